/* The base layer: error reporting, allocation, OpenMP and CPU-dispatch
 * macros that every other layer uses. */
#ifndef PSYS_BASE_H
#define PSYS_BASE_H

#include "psys/psys.h"


#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#define PSYS_PRAGMA(x) _Pragma(#x)
#define PSYS_OMP(x) PSYS_PRAGMA(x)
#else
#define PSYS_OMP(x)
#endif

/* Elementwise passes over at least this many numbers run on the caller's
 * threads (static schedule: each element computed alone, so the same bits
 * for every thread count); shorter ones are not worth a parallel region. */
#define PSYS_PAR_MIN 65536
#define PSYS_PAR_FOR(nt, len) PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if ((nt) > 1 && (len) >= PSYS_PAR_MIN))

/* Elementwise scans also built for AVX2 and AVX-512 (x86-64, GCC on
 * Linux), the variant chosen at load time: comparisons, min/max and
 * elementwise arithmetic without FMA (-ffp-contract=off), so the same
 * results on every variant. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define PSYS_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define PSYS_CLONES
#endif

/** Fill err (may be NULL) with code and a printf-style message; returns code. */
psys_status psys__fail(psys_error *err, psys_status code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/** vprintf form of psys__fail. */
psys_status psys__vfail(psys_error *err, psys_status code, const char *fmt, va_list ap);
/** Clear err (may be NULL). */
void psys__ok(psys_error *err);

/** Overflow-checked n*size allocation (NULL on overflow or failure). */
void *psys__calloc(size_t n, size_t size);
/** psys__calloc on a 64-byte boundary (whole cache lines; free() releases it). */
void *psys__calloc_lines(size_t n, size_t size);
/** Overflow-checked realloc of n*size bytes. */
void *psys__realloc(void *p, size_t n, size_t size);
/** p (*cap elements of size bytes) grown by doubling to hold want; NULL on
 *  failure, with p and *cap as they were. */
void *psys__grow(void *p, size_t *cap, size_t want, size_t size);
/** strdup that does not depend on POSIX. */
char *psys__strdup(const char *s);

/** Bit 63 set when x is not finite: its exponent bits are all set, and
 *  only then does adding one to the exponent carry into the sign bit. OR
 *  it over many values: AND, ADD and OR vectorize, a branch per value does
 *  not (the solver's check of a step's result, and the fused sweep's). */
static inline uint64_t psys__nonfinite_bit(double x)
{
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return (u & 0x7ff0000000000000u) + 0x0010000000000000u;
}

#endif
