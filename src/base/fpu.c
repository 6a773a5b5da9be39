/* The floating-point mode for subnormal results (psys_fpu_flush_subnormals). */
#include "base/base.h"

#if defined(__x86_64__) || (defined(__SSE2__) && defined(__i386__))
#include <xmmintrin.h>
#define PSYS_HAVE_FTZ 1
#endif

bool psys_fpu_flush_subnormals(bool on)
{
#ifdef PSYS_HAVE_FTZ
    /* FTZ only, not DAZ: subnormal inputs (a scene's 1e-310) keep their
     * value, so comparisons such as "dt > 0" still see them; no result
     * becomes subnormal, so none is fed back */
    _MM_SET_FLUSH_ZERO_MODE(on ? _MM_FLUSH_ZERO_ON : _MM_FLUSH_ZERO_OFF);
    return true;
#else
    (void)on;
    return false;
#endif
}

bool psys_fpu_flushes_subnormals(void)
{
#ifdef PSYS_HAVE_FTZ
    return _MM_GET_FLUSH_ZERO_MODE() == _MM_FLUSH_ZERO_ON;
#else
    return false;
#endif
}
