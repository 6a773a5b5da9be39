/* The system's thread count for parallel force evaluation; results are the
 * same bits for every count. */
#include "core/core.h"

#ifdef PSYS_HAVE_OPENMP
#include <omp.h>
#endif

psys_status psys_system_set_threads(psys_system *s, int threads)
{
    if (threads < 0)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "threads must be >= 0 (got %d)", threads);
    s->threads = threads;
    return PSYS_OK;
}

int psys_system_threads(const psys_system *s) { return s->threads; }

int psys_system_effective_threads(const psys_system *s)
{
#ifdef PSYS_HAVE_OPENMP
    return s->threads > 0 ? s->threads : omp_get_max_threads();
#else
    (void)s;
    return 1;
#endif
}
