/* What the spring loop could cost at best on this machine (a program, not a
 * test; bench/README.md, "Ceiling"). Not psys: a minimal cloth written for
 * speed alone, to set psys's figures against.
 *
 *   spring_ceiling [N] [STEPS]
 *
 * Prints these JSON lines:
 * - "divider": ns per correctly rounded square root and per division, at
 *   the widest vector width the compiler uses here (each spring of psys
 *   takes one of each: |l| and 1/|l|), measured on a 1,024-element array
 *   in L1; and their sum times the spring evaluations of one rk4 step of the
 *   N×N cloth (4 per spring), per particle: the divider floor.
 * - "ideal-cloth": the N×N cloth (N = 100) of psys bench cloth-N with its
 *   six kinds of springs (offsets 1, N, N+1, N-1, 2, 2N in row-major order),
 *   the spring law of psys (eq. 1 with the same operations, shared ks, kd,
 *   a rest length per spring), gravity and drag, stepped by rk4 in
 *   structure-of-arrays form, eight particles at a time: a chunk's
 *   forces stay in registers across its six springs, only the far ends'
 *   forces go through memory; rows are not cut at the cloth's edges and no
 *   particle is pinned (work psys must do is left out, none added). ns per
 *   particle-step (STEPS steps, 1,000), split into the derivative and the
 *   stage sums.
 * - "ideal-cloth-fused" (AVX-512 hosts, N > 8 so that the long offsets' far
 *   ends lie in later chunks, N² a multiple of 8): the same cloth
 *   with each stage's sums done in the spring loop, chunk by chunk, and the
 *   short offsets' far ends kept in registers: one pass over memory per
 *   stage. Its check: every particle's height must match ideal-cloth's to
 *   1e-9 relative, or the program exits with status 1 ("check" in the
 *   lines: a middle particle's height).
 * - "ideal-cloth-fused-partner" (the same hosts and sizes): the fused loop
 *   with each particle's spring forces added in an order that does not
 *   depend on the chunk size: its lower partners in ascending index, then
 *   its upper partners in descending index (the order a sweep of any
 *   granularity can keep; bench/README.md, "What cloth-100 needs"). The
 *   same check.
 * - "ideal-cloth-fused-psys-like" (the same hosts and sizes): the partner
 *   loop with the work psys's fused derivative adds: the solver's
 *   interleaved [x | v] state copied into a structure-of-arrays window as
 *   particles enter it (the largest offset ahead of the chunk), each
 *   entering particle's force set to m·g − drag·v there, a lane mask per
 *   chunk and kind of spring loaded and applied (all lanes set, so the same
 *   cloth and the same check), f times a per-particle inverse mass, and the
 *   stage sums on the interleaved layout. What a chunk-major sweep inside
 *   psys could reach at best (bench/README.md, "What cloth-100 needs").
 *
 * CEILING_RSQRT=1 in the environment: the AVX-512 spring law takes 1/|l|
 * from the hardware's 14-bit reciprocal square root and two Newton steps
 * (|l| = |l|²·(1/|l|)) instead of a square root and a division: not
 * correctly rounded, and its bits may differ between CPUs, so nothing psys
 * could ship as it is; it measures what the loop costs without the divider
 * ("law" in the ideal-cloth lines: "sqrt-div" or "rsqrt14").
 *
 * Same compiler flags as the library (no FMA, no fast math). */
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CLONES
#endif

#define CHUNK 8
#define KINDS 6

/* CEILING_RSQRT=1: the approximate spring law (above); read once in main. */
static int approx_rsqrt;

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

CLONES static void sqrt_pass(const double *restrict x, double *restrict y, size_t n)
{
    for (size_t i = 0; i < n; i++)
        y[i] = sqrt(x[i]);
}

CLONES static void div_pass(const double *restrict x, double *restrict y, size_t n)
{
    for (size_t i = 0; i < n; i++)
        y[i] = 1.0 / x[i];
}

/* ns per element of pass over an L1-sized array, best of 5 batches. */
static double per_element(void (*pass)(const double *restrict, double *restrict, size_t), double *x, double *y,
                          size_t n)
{
    double best = 1e30;
    for (int b = 0; b < 5; b++) {
        const int reps = 20000;
        const double t0 = now();
        for (int r = 0; r < reps; r++) {
            pass(x, y, n);
            x[r % n] = y[(r * 7) % n] + 1.0; /* keeps the passes from being merged */
        }
        const double t = (now() - t0) * 1e9 / ((double)reps * (double)n);
        best = t < best ? t : best;
    }
    return best;
}

typedef struct cloth {
    size_t n, np, pad;
    double *x[3], *v[3], *f[3], *base[6], *acc[6], *rest[KINDS];
    size_t off[KINDS];
} cloth;

/* f = 0 on every particle, the anchors past the sheet included. */
static void clear_forces(cloth *c)
{
    for (int q = 0; q < 3; q++)
        memset(c->f[q], 0, (c->np + c->pad) * sizeof(double));
}

/* f of every particle: springs eight first ends at a time, then gravity and
 * drag. The portable loop; derivative512 below is the same with AVX-512. */
static void derivative_c(cloth *c)
{
    const double ks = 100.0, kd = 0.5, drag = 0.01, g = -9.81;
    const size_t np = c->np;
    double *const *F = c->f;
    double *const *X = c->x, *const *V = c->v;
    clear_forces(c);
    for (size_t p = 0; p < np; p += CHUNK) {
        double a[3][CHUNK] = {{0}};
        for (int k = 0; k < KINDS; k++) {
            const size_t q = p + c->off[k];
            for (int l = 0; l < CHUNK; l++) {
                double e[3], dv[3];
                for (int d = 0; d < 3; d++) {
                    e[d] = X[d][p + l] - X[d][q + l];
                    dv[d] = V[d][p + l] - V[d][q + l];
                }
                const double len2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
                const double dot = dv[0] * e[0] + dv[1] * e[1] + dv[2] * e[2];
                const double L = sqrt(len2), inv = 1.0 / L;
                const double m = (ks * (L - c->rest[k][p + l]) + kd * dot * inv) * inv, mag = len2 == 0 ? 0.0 : m;
                for (int d = 0; d < 3; d++) {
                    a[d][l] -= mag * e[d];
                    F[d][q + l] += mag * e[d];
                }
            }
        }
        for (int d = 0; d < 3; d++)
            for (int l = 0; l < CHUNK; l++)
                F[d][p + l] = F[d][p + l] + a[d][l] + (d == 1 ? g : 0.0) - drag * V[d][p + l];
    }
}

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define HAVE512 1
/* The spring law on eight springs from chunk p's first ends (xa, va) to
 * their far ends at q (rows X, V): the differences into e, the magnitude
 * (psys's operations; zero-length springs exert no force) returned. */
__attribute__((target("avx512f"))) static inline __m512d spring8(const __m512d xa[3], const __m512d va[3],
                                                                 double *const *X, double *const *V, size_t q,
                                                                 const double *rest, __m512d e[3])
{
    const __m512d ks = _mm512_set1_pd(100.0), kd = _mm512_set1_pd(0.5), one = _mm512_set1_pd(1.0),
                  zero = _mm512_setzero_pd();
    __m512d dv[3];
    for (int d = 0; d < 3; d++) {
        e[d] = _mm512_sub_pd(xa[d], _mm512_loadu_pd(X[d] + q));
        dv[d] = _mm512_sub_pd(va[d], _mm512_loadu_pd(V[d] + q));
    }
    const __m512d len2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(e[0], e[0]), _mm512_mul_pd(e[1], e[1])),
                                       _mm512_mul_pd(e[2], e[2]));
    const __m512d dot = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dv[0], e[0]), _mm512_mul_pd(dv[1], e[1])),
                                      _mm512_mul_pd(dv[2], e[2]));
    __m512d L, inv;
    if (approx_rsqrt) {
        const __m512d h = _mm512_mul_pd(_mm512_set1_pd(0.5), len2), th = _mm512_set1_pd(1.5);
        __m512d y = _mm512_rsqrt14_pd(len2);
        y = _mm512_mul_pd(y, _mm512_sub_pd(th, _mm512_mul_pd(h, _mm512_mul_pd(y, y))));
        y = _mm512_mul_pd(y, _mm512_sub_pd(th, _mm512_mul_pd(h, _mm512_mul_pd(y, y))));
        inv = y;
        L = _mm512_mul_pd(len2, inv);
    } else {
        L = _mm512_sqrt_pd(len2);
        inv = _mm512_div_pd(one, L);
    }
    const __m512d m = _mm512_mul_pd(_mm512_add_pd(_mm512_mul_pd(ks, _mm512_sub_pd(L, _mm512_loadu_pd(rest))),
                                                  _mm512_mul_pd(_mm512_mul_pd(kd, dot), inv)),
                                    inv);
    return _mm512_maskz_mov_pd(_mm512_cmp_pd_mask(len2, zero, _CMP_NEQ_OQ), m);
}

__attribute__((target("avx512f"))) static void derivative512(cloth *c)
{
    const __m512d drag = _mm512_set1_pd(0.01), zero = _mm512_setzero_pd();
    const __m512d grav[3] = {zero, _mm512_set1_pd(-9.81), zero};
    const size_t np = c->np;
    double *const *F = c->f;
    double *const *X = c->x, *const *V = c->v;
    clear_forces(c);
    for (size_t p = 0; p < np; p += CHUNK) {
        __m512d xa[3], va[3], a[3];
        for (int d = 0; d < 3; d++) {
            xa[d] = _mm512_loadu_pd(X[d] + p);
            va[d] = _mm512_loadu_pd(V[d] + p);
            a[d] = zero;
        }
        for (int k = 0; k < KINDS; k++) {
            const size_t q = p + c->off[k];
            __m512d e[3];
            const __m512d mag = spring8(xa, va, X, V, q, c->rest[k] + p, e);
            for (int d = 0; d < 3; d++) {
                const __m512d gd = _mm512_mul_pd(mag, e[d]);
                a[d] = _mm512_sub_pd(a[d], gd);
                _mm512_storeu_pd(F[d] + q, _mm512_add_pd(_mm512_loadu_pd(F[d] + q), gd));
            }
        }
        for (int d = 0; d < 3; d++) {
            const __m512d f = _mm512_add_pd(_mm512_add_pd(_mm512_loadu_pd(F[d] + p), a[d]), grav[d]);
            _mm512_storeu_pd(F[d] + p, _mm512_sub_pd(f, _mm512_mul_pd(drag, va[d])));
        }
    }
}

/* a + the second ends' forces of a near kind (offset o, 1 or 2): g of
 * this chunk's springs shifted up by o lanes, the last o lanes of the
 * previous chunk's (*prev) shifted in; *prev becomes g. */
__attribute__((target("avx512f"), always_inline)) static inline __m512d near_in(__m512d a, __m512d g, __m512d *prev,
                                                                                int o)
{
    const __m512i gi = _mm512_castpd_si512(g), pi = _mm512_castpd_si512(*prev);
    const __m512i sh = o == 1 ? _mm512_alignr_epi64(gi, pi, 7) : _mm512_alignr_epi64(gi, pi, 6);
    *prev = g;
    return _mm512_add_pd(a, _mm512_castsi512_pd(sh));
}

/* The same cloth with each rk4 stage's sums fused into the spring loop:
 * a chunk's force is complete once its own springs are done (every spring
 * goes from a lower to a higher index, and the higher ends of the long
 * offsets were visited earlier), so the chunk's stage runs right there.
 * The short offsets' (1, 2) far ends stay in registers too: their forces
 * land on the chunk shifted by one or two lanes, the rest carried into the
 * next chunk. One pass over memory per stage. State buffers: in (the
 * stage's input), out (its output), base (the step's start), acc (the
 * weighted sum); the last stage writes base + h·(acc + w·k) into out. */
__attribute__((target("avx512f"), always_inline)) static inline void
fused_stage512_o(cloth *c, double *const *in, double *const *out, double *const *base, double *const *acc, double ha,
                 double w, int which, const bool partner)
{
    /* partner: the near kinds (2, 1), then the far ones by descending
     * offset (2N, N + 1, N, N − 1) */
    static const int order[2][KINDS] = {{0, 1, 2, 3, 4, 5}, {4, 0, 5, 2, 1, 3}};
    __m512d G[KINDS][3];
    const __m512d drag = _mm512_set1_pd(0.01), zero = _mm512_setzero_pd();
    const __m512d grav[3] = {zero, _mm512_set1_pd(-9.81), zero};
    const __m512d H = _mm512_set1_pd(ha), W = _mm512_set1_pd(w);
    const size_t np = c->np;
    double *const *F = c->f;
    __m512d prev1[3] = {zero, zero, zero}, prev2[3] = {zero, zero, zero};
    for (size_t p = 0; p < np; p += CHUNK) {
        __m512d xa[3], va[3], a[3];
        for (int d = 0; d < 3; d++) {
            xa[d] = _mm512_load_pd(in[d] + p);
            va[d] = _mm512_load_pd(in[3 + d] + p);
            a[d] = _mm512_load_pd(F[d] + p); /* the long offsets' far ends, from earlier chunks */
            _mm512_store_pd(F[d] + p, zero);
        }
        for (int i = 0; i < KINDS; i++) {
            const int k = order[partner][i];
            const size_t q = p + c->off[k];
            __m512d e[3];
            const __m512d mag = spring8(xa, va, in, in + 3, q, c->rest[k] + p, e);
            for (int d = 0; d < 3; d++) {
                const __m512d gd = _mm512_mul_pd(mag, e[d]);
                if (partner && c->off[k] <= 2)
                    G[k][d] = gd; /* its first ends after every second end */
                else
                    a[d] = _mm512_sub_pd(a[d], gd);
                if (c->off[k] <= 2) {
                    a[d] = near_in(a[d], gd, c->off[k] == 1 ? &prev1[d] : &prev2[d], (int)c->off[k]);
                } else {
                    _mm512_storeu_pd(F[d] + q, _mm512_add_pd(_mm512_loadu_pd(F[d] + q), gd));
                }
            }
        }
        for (int i = 0; partner && i < 2; i++)
            for (int d = 0; d < 3; d++)
                a[d] = _mm512_sub_pd(a[d], G[order[1][i]][d]);
        for (int d = 0; d < 3; d++) {
            const __m512d kx = va[d];
            const __m512d kv = _mm512_sub_pd(_mm512_add_pd(a[d], grav[d]), _mm512_mul_pd(drag, va[d]));
            const __m512d k2[2] = {kx, kv};
            for (int h2 = 0; h2 < 2; h2++) {
                const int r = 3 * h2 + d;
                const __m512d b = _mm512_load_pd(base[r] + p), wk = _mm512_mul_pd(W, k2[h2]);
                if (which == 3) {
                    const __m512d s = _mm512_add_pd(_mm512_load_pd(acc[r] + p), wk);
                    _mm512_store_pd(out[r] + p, _mm512_add_pd(b, _mm512_mul_pd(H, s)));
                } else {
                    _mm512_store_pd(out[r] + p, _mm512_add_pd(b, _mm512_mul_pd(H, k2[h2])));
                    _mm512_store_pd(acc[r] + p, which == 0 ? wk : _mm512_add_pd(_mm512_load_pd(acc[r] + p), wk));
                }
            }
        }
    }
}

/* fused_stage512_o in the ideal loop's own order of additions, or (partner)
 * in the partner order: each particle's second ends (lower partners) by
 * ascending partner, then its first ends by descending partner. In a chunk
 * the near kinds' forces (offsets 1, 2) wait in registers until the far
 * kinds' first ends are in; the far ends go to memory by descending offset,
 * so a later chunk reads them in ascending partner order. */
__attribute__((target("avx512f"))) static void fused_stage512(cloth *c, double *const *in, double *const *out,
                                                               double *const *base, double *const *acc, double ha,
                                                               double w, int which, bool partner)
{
    if (partner)
        fused_stage512_o(c, in, out, base, acc, ha, w, which, true);
    else
        fused_stage512_o(c, in, out, base, acc, ha, w, which, false);
}

/* Eight particles' x (or v) from the solver's interleaved layout (x0 y0 z0
 * x1 ...: three vectors from p3) into one vector per component. */
__attribute__((target("avx512f"))) static inline void deinterleave8(const double *p3, __m512d out[3])
{
    const __m512d a = _mm512_loadu_pd(p3), b = _mm512_loadu_pd(p3 + 8), c = _mm512_loadu_pd(p3 + 16);
    static const long long lo[3][8] = {{0, 3, 6, 9, 12, 15, 0, 0}, {1, 4, 7, 10, 13, 0, 0, 0}, {2, 5, 8, 11, 14, 0, 0, 0}};
    static const long long hi[3][8] = {{0, 0, 0, 0, 0, 0, 2, 5}, {0, 0, 0, 0, 0, 0, 3, 6}, {0, 0, 0, 0, 0, 1, 4, 7}};
    static const __mmask8 hm[3] = {0xC0, 0xE0, 0xE0};
    for (int d = 0; d < 3; d++) {
        const __m512d t = _mm512_permutex2var_pd(a, _mm512_loadu_si512(lo[d]), b);
        out[d] = _mm512_mask_permutexvar_pd(t, hm[d], _mm512_loadu_si512(hi[d]), c);
    }
}

/* The inverse of deinterleave8: three component vectors into the
 * interleaved layout (three vectors, in order). */
__attribute__((target("avx512f"))) static inline void interleave8(const __m512d in[3], __m512d out[3])
{
    /* from x, y (indices 0-7, 8-15), then z into the remaining lanes */
    static const long long xy[3][8] = {
        {0, 8, 0, 1, 9, 0, 2, 10}, {0, 3, 11, 0, 4, 12, 0, 5}, {13, 0, 6, 14, 0, 7, 15, 0}};
    static const long long zz[3][8] = {{0, 0, 0, 0, 0, 1, 0, 0}, {2, 0, 0, 3, 0, 0, 4, 0}, {0, 5, 0, 0, 6, 0, 0, 7}};
    static const __mmask8 zm[3] = {0x24, 0x49, 0x92};
    for (int r = 0; r < 3; r++) {
        const __m512d t = _mm512_permutex2var_pd(in[0], _mm512_loadu_si512(xy[r]), in[1]);
        out[r] = _mm512_mask_permutexvar_pd(t, zm[r], _mm512_loadu_si512(zz[r]), in[2]);
    }
}

/* The partner-order fused loop with the work psys adds (the "psys-like"
 * line): the solver's interleaved state ([x | v], x0 y0 z0 x1 ...) read as
 * particles enter a structure-of-arrays window max_off ahead of the chunk,
 * each entering particle's f set to m·g − drag·v there (psys's forces
 * listed before the springs), a mask per chunk and kind of spring loaded
 * and applied (all lanes set: the same cloth as the other loops, so the
 * same check), f times a per-particle inverse mass, and the stage sums on
 * the interleaved layout. in, out, base, acc: [x | v] of cap particles. */
__attribute__((target("avx512f"))) static void fused_stage512_aos(cloth *c, const double *in, double *out,
                                                                   const double *base, double *acc, double ha,
                                                                   double w, int which, const double *mass,
                                                                   const double *im, const uint8_t *mask)
{
    static const int order[KINDS] = {4, 0, 5, 2, 1, 3};
    __m512d G[KINDS][3];
    const __m512d drag = _mm512_set1_pd(0.01), zero = _mm512_setzero_pd(), gy = _mm512_set1_pd(-9.81);
    const __m512d H = _mm512_set1_pd(ha), W = _mm512_set1_pd(w);
    const size_t np = c->np, cap = c->np + c->pad, half = 3 * cap;
    double *const *F = c->f, *const *X = c->x, *const *V = c->v;
    size_t reach = 0;
    for (int k = 0; k < KINDS; k++)
        reach = c->off[k] > reach ? c->off[k] : reach;
    size_t entered = 0;
    __m512d prev1[3] = {zero, zero, zero}, prev2[3] = {zero, zero, zero};
    for (size_t p = 0; p < np; p += CHUNK) {
        for (; entered <= p + CHUNK - 1 + reach && entered + CHUNK <= cap; entered += CHUNK) {
            __m512d xe[3], ve[3];
            deinterleave8(in + 3 * entered, xe);
            deinterleave8(in + half + 3 * entered, ve);
            const __m512d m = _mm512_loadu_pd(mass + entered);
            for (int d = 0; d < 3; d++) {
                _mm512_store_pd(X[d] + entered, xe[d]);
                _mm512_store_pd(V[d] + entered, ve[d]);
                const __m512d g = d == 1 ? _mm512_mul_pd(m, gy) : zero;
                _mm512_store_pd(F[d] + entered, _mm512_sub_pd(_mm512_add_pd(zero, g), _mm512_mul_pd(drag, ve[d])));
            }
        }
        __m512d xa[3], va[3], a[3];
        for (int d = 0; d < 3; d++) {
            xa[d] = _mm512_load_pd(X[d] + p);
            va[d] = _mm512_load_pd(V[d] + p);
            a[d] = _mm512_load_pd(F[d] + p);
        }
        const uint8_t *mk = mask + (p / CHUNK) * KINDS;
        for (int i = 0; i < KINDS; i++) {
            const int k = order[i];
            const size_t o = c->off[k], q = p + o;
            const __mmask8 lanes = mk[k];
            __m512d e[3];
            const __m512d mag = _mm512_maskz_mov_pd(lanes, spring8(xa, va, X, V, q, c->rest[k] + p, e));
            for (int d = 0; d < 3; d++) {
                const __m512d gd = _mm512_mul_pd(mag, e[d]);
                if (o <= 2)
                    G[k][d] = gd;
                else
                    a[d] = _mm512_mask_sub_pd(a[d], lanes, a[d], gd);
                if (o <= 2) {
                    a[d] = near_in(a[d], gd, o == 1 ? &prev1[d] : &prev2[d], (int)o);
                } else {
                    _mm512_mask_storeu_pd(F[d] + q, lanes, _mm512_add_pd(_mm512_loadu_pd(F[d] + q), gd));
                }
            }
        }
        for (int i = 0; i < 2; i++)
            for (int d = 0; d < 3; d++)
                a[d] = _mm512_mask_sub_pd(a[d], mk[order[i]], a[d], G[order[i]][d]);
        const __m512d imv = _mm512_loadu_pd(im + p);
        __m512d acc_soa[3], kv[3], kx[3];
        for (int d = 0; d < 3; d++)
            acc_soa[d] = _mm512_mul_pd(a[d], imv);
        interleave8(acc_soa, kv);
        for (int r = 0; r < 3; r++)
            kx[r] = _mm512_loadu_pd(in + half + 3 * p + 8 * r);
        for (int h2 = 0; h2 < 2; h2++) {
            const size_t o0 = (h2 ? half : 0) + 3 * p;
            for (int r = 0; r < 3; r++) {
                const size_t o = o0 + 8 * (size_t)r;
                const __m512d k = h2 ? kv[r] : kx[r];
                const __m512d b = _mm512_loadu_pd(base + o), wk = _mm512_mul_pd(W, k);
                if (which == 3) {
                    const __m512d s = _mm512_add_pd(_mm512_loadu_pd(acc + o), wk);
                    _mm512_storeu_pd(out + o, _mm512_add_pd(b, _mm512_mul_pd(H, s)));
                } else {
                    _mm512_storeu_pd(out + o, _mm512_add_pd(b, _mm512_mul_pd(H, k)));
                    _mm512_storeu_pd(acc + o, which == 0 ? wk : _mm512_add_pd(_mm512_loadu_pd(acc + o), wk));
                }
            }
        }
    }
}
#endif

/* One rk4 stage's sums (unit masses): next state base + h·a·k, acc += w·k
 * (acc = w·k at the first stage). */
CLONES static void stage(cloth *c, double ha, double w, int first)
{
    const size_t np = c->np;
    for (int q = 0; q < 3; q++) {
        double *restrict x = c->x[q], *restrict v = c->v[q];
        const double *restrict f = c->f[q], *restrict bx = c->base[q], *restrict bv = c->base[3 + q];
        double *restrict ax = c->acc[q], *restrict av = c->acc[3 + q];
        for (size_t i = 0; i < np; i++) {
            const double kx = v[i], kv = f[i];
            ax[i] = (first ? 0.0 : ax[i]) + w * kx;
            av[i] = (first ? 0.0 : av[i]) + w * kv;
            x[i] = bx[i] + ha * kx;
            v[i] = bv[i] + ha * kv;
        }
    }
}

/* Every array the program allocates, freed at its end. */
static double *columns[64];
static int ncolumns;

static double *column(size_t m)
{
    double *p = ncolumns < 64 ? aligned_alloc(64, ((m * sizeof(double) + 63) / 64) * 64) : NULL;
    if (!p) {
        fprintf(stderr, "spring_ceiling: out of memory\n");
        exit(1);
    }
    memset(p, 0, m * sizeof(double));
    columns[ncolumns++] = p;
    return p;
}

int main(int argc, char **argv)
{
    const size_t n = argc > 1 ? (size_t)atol(argv[1]) : 100;
    const int steps = argc > 2 ? atoi(argv[2]) : 1000;
    if (n < 3 || steps < 1) {
        fprintf(stderr, "usage: spring_ceiling [N ≥ 3] [STEPS ≥ 1]\n");
        return 2;
    }
    const char *rs = getenv("CEILING_RSQRT");
    approx_rsqrt = rs && rs[0] == '1';
    const char *law = approx_rsqrt ? "rsqrt14" : "sqrt-div";
    /* the divider */
    const size_t m = 1024;
    double *dx = column(m), *dy = column(m);
    for (size_t i = 0; i < m; i++)
        dx[i] = 0.5 + (double)i / (double)m;
    const double t_sqrt = per_element(sqrt_pass, dx, dy, m), t_div = per_element(div_pass, dx, dy, m);
    const double springs = 2.0 * (double)n * (double)(n - 1) + 2.0 * (double)(n - 1) * (double)(n - 1)
                           + 2.0 * (double)n * (double)(n - 2);
    const double per_particle = springs / ((double)n * (double)n);
    printf("{\"case\":\"divider\",\"ns_per_sqrt\":%.3f,\"ns_per_division\":%.3f,\"cloth\":%zu,"
           "\"springs_per_particle\":%.3f,\"floor_ns_per_particle_step\":%.2f}\n",
           t_sqrt, t_div, n, per_particle, 4.0 * per_particle * (t_sqrt + t_div));
    /* the cloth */
    cloth c = {.n = n, .np = n * n, .pad = 2 * n + 2 * CHUNK};
    const size_t cap = c.np + c.pad;
    const size_t off[KINDS] = {1, n, n + 1, n - 1, 2, 2 * n};
    const double h = 1e-4, s = 2.0 / (double)(n - 1);
    for (int q = 0; q < 3; q++) {
        c.x[q] = column(cap);
        c.v[q] = column(cap);
        c.f[q] = column(cap);
    }
    for (int q = 0; q < 6; q++) {
        c.base[q] = column(cap);
        c.acc[q] = column(cap);
    }
    for (size_t i = 0; i < cap; i++) {
        c.x[0][i] = s * (double)(i % n);
        c.x[2][i] = s * (double)(i / n);
    }
    for (int k = 0; k < KINDS; k++) {
        c.off[k] = off[k];
        c.rest[k] = column(cap);
        for (size_t i = 0; i < cap; i++) {
            const double e0 = c.x[0][i] - c.x[0][(i + off[k]) % cap], e2 = c.x[2][i] - c.x[2][(i + off[k]) % cap];
            c.rest[k][i] = sqrt(e0 * e0 + e2 * e2);
        }
    }
    const double a[4] = {0.5, 0.5, 1.0, 0.0}, w[4] = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6};
    int status = 0;
    void (*derivative)(cloth *) = derivative_c;
    const char *width = "portable";
#ifdef HAVE512
    if (__builtin_cpu_supports("avx512f") && !getenv("CEILING_PORTABLE")) {
        derivative = derivative512;
        width = "avx512f";
    }
#endif
    double t_der = 0, t_stage = 0;
    for (int st = 0; st < steps; st++) {
        for (int q = 0; q < 3; q++) {
            memcpy(c.base[q], c.x[q], c.np * sizeof(double));
            memcpy(c.base[3 + q], c.v[q], c.np * sizeof(double));
        }
        for (int k = 0; k < 4; k++) {
            const double t0 = now();
            derivative(&c);
            const double t1 = now();
            stage(&c, h * a[k], w[k], k == 0);
            t_stage += now() - t1;
            t_der += t1 - t0;
        }
        const double t2 = now();
        for (int q = 0; q < 6; q++) {
            double *restrict y = q < 3 ? c.x[q] : c.v[q - 3];
            const double *restrict b = c.base[q], *restrict ac = c.acc[q];
            for (size_t i = 0; i < c.np; i++)
                y[i] = b[i] + h * ac[i];
        }
        t_stage += now() - t2;
    }
    const double per = 1e9 / ((double)steps * (double)c.np);
    printf("{\"case\":\"ideal-cloth\",\"n\":%zu,\"particles\":%zu,\"steps\":%d,\"derivative\":\"%s\","
           "\"law\":\"%s\",\"ns_per_particle_step\":%.2f,\"derivative_ns\":%.2f,\"stage_ns\":%.2f,"
           "\"check\":%.9g}\n",
           n, c.np, steps, width, strcmp(width, "avx512f") == 0 ? law : "sqrt-div", (t_der + t_stage) * per,
           t_der * per, t_stage * per, c.x[1][c.np / 2]);
#ifdef HAVE512
    if (__builtin_cpu_supports("avx512f") && c.np % CHUNK == 0 && n > 8) {
        /* the fused variants from the same start: 3 state buffers of 6 rows */
        double *buf[3][6];
        for (int b = 0; b < 3; b++)
            for (int q = 0; q < 6; q++)
                buf[b][q] = column(cap);
        for (int partner = 0; partner < 2; partner++) {
            for (int b = 0; b < 3; b++)
                for (int q = 0; q < 6; q++)
                    for (size_t i = 0; i < cap; i++)
                        buf[b][q][i] = q == 0 ? s * (double)(i % n) : q == 2 ? s * (double)(i / n) : 0.0;
            for (int q = 0; q < 3; q++)
                memset(c.f[q], 0, cap * sizeof(double));
            double **st = buf[0], **s1 = buf[1], **s2 = buf[2];
            const double t0 = now();
            for (int t = 0; t < steps; t++) {
                fused_stage512(&c, st, s1, st, c.acc, h * a[0], w[0], 0, partner);
                fused_stage512(&c, s1, s2, st, c.acc, h * a[1], w[1], 1, partner);
                fused_stage512(&c, s2, s1, st, c.acc, h * a[2], w[2], 2, partner);
                fused_stage512(&c, s1, s2, st, c.acc, h, w[3], 3, partner);
                double **tmp = st;
                st = s2;
                s2 = tmp;
            }
            const double t = now() - t0;
            /* the loops sum each force in other orders: every particle's
             * height agrees to rounding, or one of them is wrong (the
             * program then fails); the springs act within reach of the
             * fixed anchors past the sheet, so only all heights see them */
            for (size_t i = 0; i < c.np; i++) {
                const double h1 = c.x[1][i], h2 = st[1][i];
                if (!(fabs(h2 - h1) <= 1e-9 * fabs(h1) + 1e-15)) {
                    fprintf(stderr, "spring_ceiling: %s: particle %zu's height %.17g differs from %.17g\n",
                            partner ? "partner" : "fused", i, h2, h1);
                    status = 1;
                    break;
                }
            }
            printf("{\"case\":\"%s\",\"n\":%zu,\"particles\":%zu,\"steps\":%d,\"law\":\"%s\","
                   "\"ns_per_particle_step\":%.2f,\"check\":%.9g}\n",
                   partner ? "ideal-cloth-fused-partner" : "ideal-cloth-fused", n, c.np, steps, law, t * per,
                   st[1][c.np / 2]);
        }
        /* the psys-like loop: interleaved state buffers of cap particles */
        {
            double *ab[3], *aacc = column(6 * cap), *mass = column(cap), *im = column(cap);
            uint8_t *mask = malloc((cap / CHUNK + 1) * KINDS);
            if (!mask) {
                fprintf(stderr, "spring_ceiling: out of memory\n");
                return 1;
            }
            memset(mask, 0xFF, (cap / CHUNK + 1) * KINDS);
            cloth cw = c;
            for (int q = 0; q < 3; q++) {
                cw.x[q] = column(cap);
                cw.v[q] = column(cap);
                cw.f[q] = column(cap);
            }
            for (size_t i = 0; i < cap; i++)
                mass[i] = im[i] = 1.0;
            for (int b = 0; b < 3; b++) {
                ab[b] = column(6 * cap);
                for (size_t i = 0; i < cap; i++) {
                    ab[b][3 * i] = s * (double)(i % n);
                    ab[b][3 * i + 2] = s * (double)(i / n);
                }
            }
            double *st = ab[0], *s1 = ab[1], *s2 = ab[2];
            const double t0 = now();
            for (int t = 0; t < steps; t++) {
                fused_stage512_aos(&cw, st, s1, st, aacc, h * a[0], w[0], 0, mass, im, mask);
                fused_stage512_aos(&cw, s1, s2, st, aacc, h * a[1], w[1], 1, mass, im, mask);
                fused_stage512_aos(&cw, s2, s1, st, aacc, h * a[2], w[2], 2, mass, im, mask);
                fused_stage512_aos(&cw, s1, s2, st, aacc, h, w[3], 3, mass, im, mask);
                double *tmp = st;
                st = s2;
                s2 = tmp;
            }
            const double t = now() - t0;
            free(mask);
            for (size_t i = 0; i < c.np; i++) {
                const double h1 = c.x[1][i], h2 = st[3 * i + 1];
                if (!(fabs(h2 - h1) <= 1e-9 * fabs(h1) + 1e-15)) {
                    fprintf(stderr, "spring_ceiling: psys-like: particle %zu's height %.17g differs from %.17g\n",
                            i, h2, h1);
                    status = 1;
                    break;
                }
            }
            printf("{\"case\":\"ideal-cloth-fused-psys-like\",\"n\":%zu,\"particles\":%zu,\"steps\":%d,"
                   "\"law\":\"%s\",\"ns_per_particle_step\":%.2f,\"check\":%.9g}\n",
                   n, c.np, steps, law, t * per, st[3 * (c.np / 2) + 1]);
        }
    }
#endif
    for (int i = 0; i < ncolumns; i++)
        free(columns[i]);
    return status;
}
