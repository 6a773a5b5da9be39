/* Damped Hooke springs (notes eq. 1), all of a system's springs in one
 * force object stored as arrays so the loop streams through memory:
 *   l = a - b,  f_a = -[ks(|l| - r) + kd (l̇·l)/|l|] l/|l|,  f_b = -f_a.
 * A spring of zero current length has no direction and exerts no force. */
#include "forces/springs.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

static void springs_destroy(void *data)
{
    springs *s = data;
    if (!s)
        return;
    free(s->a);
    free(s->b);
    free(s->ks);
    free(s->kd);
    free(s->rest);
    free(s->mslot);
    free(s->rest_t);
    free(s->midx);
    free(s->mamp);
    free(s->momega);
    free(s->mphase);
    psys__springs_plan_free(s);
    free(s->soa);
    free(s->ring);
    free(s->stage);
    free(s);
}

void *psys__springs_create(const psys_system *owner)
{
    springs *s = calloc(1, sizeof(springs));
    if (s)
        s->owner = owner;
    return s;
}
size_t psys__springs_count(const void *set) { return ((const springs *)set)->n; }

psys_status psys__springs_add(void *set, size_t a, size_t b, double ks, double kd, double rest)
{
    springs *s = set;
    if (a > UINT32_MAX || b > UINT32_MAX)
        return PSYS_ERR_INVALID;
    if (s->n == s->cap) {
        size_t cap = s->cap ? s->cap * 2 : 64;
        void *p;
#define GROW(field, type)                              \
    if (!(p = psys__realloc(s->field, cap, sizeof(type)))) \
        return PSYS_ERR_NOMEM;                         \
    s->field = p;
        GROW(a, uint32_t)
        GROW(b, uint32_t)
        GROW(ks, double)
        GROW(kd, double)
        GROW(rest, double)
        if (s->mslot) {
            GROW(mslot, uint32_t)
            GROW(rest_t, double)
        }
#undef GROW
        s->cap = cap;
    }
    if (s->mslot) {
        s->mslot[s->n] = NO_MUSCLE;
        s->rest_t[s->n] = rest;
    }
    s->a[s->n] = (uint32_t)a;
    s->b[s->n] = (uint32_t)b;
    s->ks[s->n] = ks;
    s->kd[s->n] = kd;
    s->rest[s->n] = rest;
    s->n++;
    s->version++;
    return PSYS_OK;
}

void psys__springs_get(const void *set, size_t k, size_t *a, size_t *b, double *ks, double *kd, double *rest)
{
    const springs *s = set;
    if (a) *a = s->a[k];
    if (b) *b = s->b[k];
    if (ks) *ks = s->ks[k];
    if (kd) *kd = s->kd[k];
    if (rest) *rest = s->rest[k];
}

/* Rest length of muscle slot m at time t (one expression, used everywhere). */
static double muscle_rest(const springs *s, size_t m, double t)
{
    return s->rest[s->midx[m]] * (1.0 + s->mamp[m] * sin(s->momega[m] * t + s->mphase[m]));
}

/* Rest lengths at time t: rest[] itself without muscles, else rest_t[] with
 * the muscle entries brought to time t (no allocation: called from apply). */
static const double *rest_at(springs *s, double t)
{
    if (!s->nm)
        return s->rest;
    for (size_t m = 0; m < s->nm; m++)
        s->rest_t[s->midx[m]] = muscle_rest(s, m, t);
    return s->rest_t;
}

psys_status psys__springs_set_muscle(void *set, size_t k, double amplitude, double omega, double phase)
{
    springs *s = set;
    if (!s->mslot) {
        if (amplitude == 0)
            return PSYS_OK;
        uint32_t *slot = psys__calloc(s->cap, sizeof *slot);
        double *rt = psys__calloc(s->cap, sizeof *rt);
        if (!slot || !rt) {
            free(slot);
            free(rt);
            return PSYS_ERR_NOMEM;
        }
        for (size_t i = 0; i < s->n; i++) {
            slot[i] = NO_MUSCLE;
            rt[i] = s->rest[i];
        }
        s->mslot = slot;
        s->rest_t = rt;
    }
    uint32_t m = s->mslot[k];
    if (amplitude == 0) { /* remove: move the last muscle into slot m */
        if (m == NO_MUSCLE)
            return PSYS_OK;
        size_t last = s->nm - 1;
        s->midx[m] = s->midx[last];
        s->mamp[m] = s->mamp[last];
        s->momega[m] = s->momega[last];
        s->mphase[m] = s->mphase[last];
        s->mslot[s->midx[m]] = m;
        s->mslot[k] = NO_MUSCLE;
        s->rest_t[k] = s->rest[k];
        s->nm--;
        s->version++;
        return PSYS_OK;
    }
    if (m == NO_MUSCLE) {
        if (s->nm == s->mcap) {
            size_t cap = s->mcap ? s->mcap * 2 : 16;
            void *p;
#define GROW(field, type)                                  \
    if (!(p = psys__realloc(s->field, cap, sizeof(type)))) \
        return PSYS_ERR_NOMEM;                             \
    s->field = p;
            GROW(midx, uint32_t)
            GROW(mamp, double)
            GROW(momega, double)
            GROW(mphase, double)
#undef GROW
            s->mcap = cap;
        }
        m = (uint32_t)s->nm++;
        s->midx[m] = (uint32_t)k;
        s->mslot[k] = m;
    }
    s->mamp[m] = amplitude;
    s->momega[m] = omega;
    s->mphase[m] = phase;
    s->version++;
    return PSYS_OK;
}

bool psys__springs_muscle(const void *set, size_t k, double *amplitude, double *omega, double *phase)
{
    const springs *s = set;
    if (!s->mslot || s->mslot[k] == NO_MUSCLE)
        return false;
    uint32_t m = s->mslot[k];
    if (amplitude) *amplitude = s->mamp[m];
    if (omega) *omega = s->momega[m];
    if (phase) *phase = s->mphase[m];
    return true;
}

double psys__springs_rest_at(const void *set, size_t k, double t)
{
    const springs *s = set;
    if (!s->mslot || s->mslot[k] == NO_MUSCLE)
        return s->rest[k];
    return muscle_rest(s, s->mslot[k], t);
}

void psys__springs_truncate(void *set, size_t n)
{
    springs *s = set;
    for (size_t k = n; k < s->n; k++)
        if (s->mslot && s->mslot[k] != NO_MUSCLE)
            psys__springs_set_muscle(s, k, 0, 0, 0); /* removal never allocates */
    if (n < s->n)
        s->n = n;
    s->version++;
}

/* ---- the force loop ----
 * psys__springs_plan (forces/spring_plan.c) regroups the springs into runs:
 * springs (lo + j, lo + off + j) for j < len, with lo < lo + off, ordered by block of 256 first particles,
 * then offset, then first particle. A cloth, rope or lattice built row by row
 * falls into runs as long as its rows (one per kind of neighbour), so the
 * loop over a run reads positions and velocities of both ends and writes
 * their forces as contiguous blocks: it vectorises, and only one array of
 * parameters per quantity (ks, kd, rest in plan order) streams by.
 * Each particle's force receives its springs' contributions in plan order
 * (run by run; in a run the first ends, then the second ends), whatever the
 * thread count. A spring with a > b is the same spring seen from b: l and
 * l̇ change sign, l·l̇ and |l| do not, so its force is the same to the bit.
 * "Particles" above are slots: a set numbered out of order gets an internal
 * order first (psys__springs_plan, perm), and the SoA copies and the fused
 * window gather and scatter through it; runs shorter than SPRING_SHORT go through
 * run_short instead of the vector loops. */

#if SPRING_AVX512
bool psys__springs_avx512(const psys_system *sys)
{
    return __builtin_cpu_supports("avx512f") && !(sys && sys->sw.spring_plain);
}

/* run_forces_d on AVX-512 (F at 0..len): eight springs to a vector from
 * the line holding the first end lo, the first and last vectors masked
 * instead of a scalar head and tail; the same bits. */
__attribute__((target("avx512f"))) static void run_forces_512(const double *X, size_t cap, size_t lo, size_t hi,
                                                              const double *ks, const double *kd,
                                                              const double *rest, size_t len, double *F, bool uni,
                                                              int d)
{
    const size_t h0 = lo & 7, end = h0 + len;
    const ptrdiff_t o = (ptrdiff_t)hi - (ptrdiff_t)lo;
    const double *r = __builtin_assume_aligned((const double *)psys__lanes_at(X + lo, -(ptrdiff_t)h0), 64);
    double *pf = (double *)psys__lanes_at(F, -(ptrdiff_t)h0);
    const spring_par8 p = psys__spring_par8(ks, kd, rest, h0);
    cap &= ~(size_t)7;
    for (size_t i = 0; i < end; i += 8) {
        __mmask8 m = (__mmask8)(0xffu << (i == 0 ? h0 : 0));
        if (end - i < 8)
            m &= (__mmask8)((1u << (end - i)) - 1);
        __m512d g[3];
        if (m == 0xff) {
            if (d == 3)
                psys__spring_g8(r + i, o, cap, &p, i, m, true, uni, 3, g);
            else
                psys__spring_g8(r + i, o, cap, &p, i, m, true, uni, 2, g);
            for (int c = 0; c < d; c++)
                _mm512_storeu_pd(pf + (size_t)c * SPRING_BLOCK + i, g[c]);
        } else {
            if (d == 3)
                psys__spring_g8(r + i, o, cap, &p, i, m, false, uni, 3, g);
            else
                psys__spring_g8(r + i, o, cap, &p, i, m, false, uni, 2, g);
            for (int c = 0; c < d; c++)
                _mm512_mask_storeu_pd(pf + (size_t)c * SPRING_BLOCK + i, m, g[c]);
        }
    }
}
#endif

/* run_forces_d for a whole run (F at 0..len), ks and kd read once where the
 * run's springs share them, split where the first ends reach a cache line:
 * the same operations on each spring. */
#if defined(__GNUC__)
__attribute__((always_inline)) /* into each clone of springs_runs below */
#endif
static inline void run_forces(const double *X, const double *V, size_t cap, size_t lo, size_t hi, const double *ks,
                              const double *kd, const double *rest, size_t len, double *F, bool uni, const int d)
{
    const size_t h = psys__springs_to_line(lo, len);
    if (h)
        run_forces_d(X, V, cap, lo, hi, ks, kd, rest, h, F, uni, d, false);
    if (len > h && uni)
        run_forces_d(X, V, cap, lo + h, hi + h, ks + h, kd + h, rest + h, len - h, F + h, true, d, true);
    else if (len > h)
        run_forces_d(X, V, cap, lo + h, hi + h, ks + h, kd + h, rest + h, len - h, F + h, false, d, true);
}

/* Runs r0..r1-1 into the SoA forces Fs; with `owned`, only the ends in
 * particles [P, Q). Per particle and component the contributions arrive in
 * plan order: run by run, in a run the first end before the second. */
#if defined(__GNUC__)
__attribute__((always_inline)) /* into each clone of springs_runs below */
#endif
static inline void springs_runs_d(const springs *s, double *restrict Fs, size_t r0, size_t r1, size_t P, size_t Q,
                                  const int d, const bool owned, bool k512)
{
    double F[3 * SPRING_BLOCK];
    const size_t cap = s->soa_cap;
    const double *X = s->soa, *V = s->soa + (size_t)d * cap;
    for (size_t r = r0; r < r1; r++) {
        const size_t lo = s->run_lo[r], hi = lo + s->run_off[r], len = s->run_len[r], k = s->run_k[r];
        size_t a0 = 0, a1 = len, b0 = 0, b1 = len; /* j ranges written at the lo and hi ends */
        if (owned) {
            a0 = P > lo ? P - lo : 0;
            a1 = Q < lo ? 0 : Q - lo < len ? Q - lo : len;
            b0 = P > hi ? P - hi : 0;
            b1 = Q < hi ? 0 : Q - hi < len ? Q - hi : len;
            if (a0 >= a1 && b0 >= b1)
                continue;
        }
        if (len < SPRING_SHORT) {
            run_short(X, V, Fs, cap, SIZE_MAX, lo, hi, s->pks + k, s->pkd + k, s->prest + k, len, a0, a1, b0, b1, d);
            continue;
        }
        const bool uni = s->run_uni[r];
#if SPRING_AVX512
        if (k512)
            run_forces_512(X, cap, lo, hi, s->pks + k, s->pkd + k, s->prest + k, len, F, uni, d);
        else
#else
        (void)k512;
#endif
            run_forces(X, V, cap, lo, hi, s->pks + k, s->pkd + k, s->prest + k, len, F, uni, d);
        for (int c = 0; c < d; c++) {
            double *restrict fa = Fs + c * cap + lo, *restrict fb = Fs + c * cap + hi;
            const double *restrict Fc = F + c * SPRING_BLOCK;
            for (size_t j = a0; j < a1; j++)
                fa[j] -= Fc[j];
            for (size_t j = b0; j < b1; j++)
                fb[j] += Fc[j];
        }
    }
}

SPRING_CLONES
static void springs_runs(const springs *s, int dim, double *Fs, size_t r0, size_t r1, size_t P, size_t Q, bool owned,
                         bool k512)
{
    if (dim == 2) {
        if (owned)
            springs_runs_d(s, Fs, r0, r1, P, Q, 2, true, k512);
        else
            springs_runs_d(s, Fs, r0, r1, 0, 0, 2, false, k512);
    } else {
        if (owned)
            springs_runs_d(s, Fs, r0, r1, P, Q, 3, true, k512);
        else
            springs_runs_d(s, Fs, r0, r1, 0, 0, 3, false, k512);
    }
}

/* Particles [P, Q) of x, v and f into the SoA scratch (component-major). */
SPRING_CLONES
static void soa_gather(springs *s, const psys_force_eval *e, const double *f, size_t P, size_t Q)
{
    const int d = e->dim;
    const size_t cap = s->soa_cap;
    const double *src[3] = {e->x, e->v, f};
    for (int q = 0; q < 3; q++) {
        const double *restrict a = src[q];
        double *restrict c0 = s->soa + (size_t)(q * d) * cap, *restrict c1 = c0 + cap, *restrict c2 = c1 + cap;
        if (s->perm) {
            for (size_t i = P; i < Q; i++) {
                const size_t p = (size_t)s->perm[i] * (size_t)d;
                c0[i] = a[p];
                c1[i] = a[p + 1];
                if (d == 3)
                    c2[i] = a[p + 2];
            }
        } else if (d == 2) {
            for (size_t i = P; i < Q; i++) {
                c0[i] = a[2 * i];
                c1[i] = a[2 * i + 1];
            }
        } else {
            for (size_t i = P; i < Q; i++) {
                c0[i] = a[3 * i];
                c1[i] = a[3 * i + 1];
                c2[i] = a[3 * i + 2];
            }
        }
    }
}

/* Particles [P, Q) of the SoA forces back into f (particle-major). */
SPRING_CLONES
static void soa_scatter(const springs *s, int d, double *f, size_t P, size_t Q)
{
    const size_t cap = s->soa_cap;
    const double *restrict c0 = s->soa + (size_t)(2 * d) * cap, *restrict c1 = c0 + cap, *restrict c2 = c1 + cap;
    double *restrict a = f;
    if (s->perm) {
        for (size_t i = P; i < Q; i++) {
            const size_t p = (size_t)s->perm[i] * (size_t)d;
            a[p] = c0[i];
            a[p + 1] = c1[i];
            if (d == 3)
                a[p + 2] = c2[i];
        }
    } else if (d == 2) {
        for (size_t i = P; i < Q; i++) {
            a[2 * i] = c0[i];
            a[2 * i + 1] = c1[i];
        }
    } else {
        for (size_t i = P; i < Q; i++) {
            a[3 * i] = c0[i];
            a[3 * i + 1] = c1[i];
            a[3 * i + 2] = c2[i];
        }
    }
}

/* The plain loop in spring order: only when the plan could not be built
 * (out of memory) in a call that cannot report it. */
static void springs_plain(const springs *s, const psys_force_eval *e, const double *rest, double *f)
{
    const int d = e->dim;
    for (size_t k = 0; k < s->n; k++) {
        size_t ia = (size_t)s->a[k] * d, ib = (size_t)s->b[k] * d;
        double l[3], ld[3], len2 = 0, dot = 0;
        for (int c = 0; c < d; c++) {
            l[c] = e->x[ia + c] - e->x[ib + c];
            ld[c] = e->v[ia + c] - e->v[ib + c];
            len2 += l[c] * l[c];
            dot += ld[c] * l[c];
        }
        if (len2 == 0)
            continue;
        double len = sqrt(len2), inv = 1.0 / len;
        double mag = (s->ks[k] * (len - rest[k]) + s->kd[k] * dot * inv) * inv;
        for (int c = 0; c < d; c++) {
            double fc = mag * l[c];
            f[ia + c] -= fc;
            f[ib + c] += fc;
        }
    }
}

const double *psys__springs_rest_now(springs *s, double t) { return rest_at(s, t); }

/* Threads for the spring loop: the evaluation's, for sets large enough. */
static int springs_threads(const springs *s, const psys_force_eval *e)
{
    if (s->n < SPRING_PARALLEL_MIN)
        return 1;
    int T = e->threads;
    return T < 1 ? 1 : T > SPRING_MAX_THREADS ? SPRING_MAX_THREADS : T;
}

static void springs_apply(void *data, const psys_force_eval *e, double *f)
{
    springs *s = data;
    const double *rest = rest_at(s, e->t);
    if (psys__springs_plan(s) != PSYS_OK || e->n > s->soa_cap || (s->perm && s->perm_n < e->n)) {
        springs_plain(s, e, rest, f);
        return;
    }
    for (size_t m = 0; m < s->nm; m++)
        s->prest[s->pos[s->midx[m]]] = rest[s->midx[m]];
    int T = springs_threads(s, e);
    if (T > 1 && e->n > 0) {
        psys__springs_partition(s, e->n, T);
        if (!s->part_ok)
            T = 1;
    }
    double *Fs = s->soa + (size_t)(2 * e->dim) * s->soa_cap;
    const bool k512 = psys__springs_avx512(s->owner);
    if (T <= 1) {
        soa_gather(s, e, f, 0, e->n);
        springs_runs(s, e->dim, Fs, 0, s->nruns, 0, 0, false, k512);
        soa_scatter(s, e->dim, f, 0, e->n);
        return;
    }
#ifdef _OPENMP
    /* Thread t gathers and scatters its own particles; every thread reads
     * all positions and velocities, hence the barrier after the gather. */
#pragma omp parallel num_threads(T)
    {
        int nth = omp_get_num_threads(), me = omp_get_thread_num();
        for (int t = me; t < T; t += nth)
            soa_gather(s, e, f, psys__part_first(e->n, T, t), psys__part_first(e->n, T, t + 1));
#pragma omp barrier
        for (int t = me; t < T; t += nth) {
            size_t P = psys__part_first(e->n, T, t), Q = psys__part_first(e->n, T, t + 1);
            springs_runs(s, e->dim, Fs, s->rlo[t], s->rhi[t], P, Q, true, k512);
            soa_scatter(s, e->dim, f, P, Q);
        }
    }
#endif
}

static double springs_energy(void *data, const psys_force_eval *e)
{
    const springs *s = data;
    const double *rest = rest_at(data, e->t);
    int d = e->dim;
    double u = 0;
    for (size_t k = 0; k < s->n; k++) {
        size_t ia = (size_t)s->a[k] * d, ib = (size_t)s->b[k] * d;
        double len2 = 0;
        for (int c = 0; c < d; c++) {
            double lc = e->x[ia + c] - e->x[ib + c];
            len2 += lc * lc;
        }
        double stretch = sqrt(len2) - rest[k];
        u += 0.5 * s->ks[k] * stretch * stretch;
    }
    return u;
}

/* With u = l/|l|, P = I - u uᵀ:
 *   ∂f_a/∂l = -ks [u uᵀ + (1 - r/|l|) P] - (kd/|l|) [u (P l̇)ᵀ + (l̇·u) P]
 *   ∂f_a/∂l̇ = -kd u uᵀ
 * and ∂/∂x_a = ∂/∂l = -∂/∂x_b, f_b = -f_a. */
static void springs_jacobian(void *data, const psys_force_eval *e, psys_jacobian *J)
{
    const springs *s = data;
    const double *rest = rest_at(data, e->t);
    const bool definite = psys_jacobian_wants_definite(J);
    int d = e->dim;
    for (size_t k = 0; k < s->n; k++) {
        size_t a = s->a[k], b = s->b[k];
        double l[3], ld[3], len2 = 0;
        for (int c = 0; c < d; c++) {
            l[c] = e->x[a * d + c] - e->x[b * d + c];
            ld[c] = e->v[a * d + c] - e->v[b * d + c];
            len2 += l[c] * l[c];
        }
        if (len2 == 0)
            continue;
        double len = sqrt(len2), u[3], udot = 0, pld[3];
        for (int c = 0; c < d; c++) {
            u[c] = l[c] / len;
            udot += ld[c] * u[c];
        }
        for (int c = 0; c < d; c++)
            pld[c] = ld[c] - udot * u[c];
        double kx[9], kv[9], nkx[9], nkv[9];
        double ks = s->ks[k], kd = s->kd[k], fr = 1.0 - rest[k] / len, kdl = kd / len;
        if (definite) {
            /* Implicit solvers need -∂f/∂x symmetric positive semi-definite:
             * a compressed spring's transverse term and the damping part of
             * ∂f/∂x are dropped (Baraff & Witkin 1998; Choi & Ko 2002). */
            if (fr < 0)
                fr = 0;
            kdl = 0;
        }
        for (int r = 0; r < d; r++)
            for (int c = 0; c < d; c++) {
                double uu = u[r] * u[c], p = (r == c ? 1.0 : 0.0) - uu;
                kx[r * d + c] = -ks * (uu + fr * p) - kdl * (u[r] * pld[c] + udot * p);
                kv[r * d + c] = -kd * uu;
                nkx[r * d + c] = -kx[r * d + c];
                nkv[r * d + c] = -kv[r * d + c];
            }
        psys_jacobian_add(J, a, a, kx, kv);
        psys_jacobian_add(J, a, b, nkx, nkv);
        psys_jacobian_add(J, b, a, nkx, nkv);
        psys_jacobian_add(J, b, b, kx, kv);
    }
}

psys_status psys_system_set_spring_muscle(psys_system *sys, size_t k, double amplitude, double omega,
                                          double phase)
{
    if (k >= psys_system_spring_count(sys))
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "no spring %zu (there are %zu springs)", k,
                          psys_system_spring_count(sys));
    if (!isfinite(amplitude) || amplitude < 0 || amplitude > 1)
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "muscle amplitude must be from 0 to 1 (got %g)", amplitude);
    if (!isfinite(omega) || !isfinite(phase))
        return psys__fail(&sys->err, PSYS_ERR_INVALID, "muscle omega and phase must be finite");
    if (psys__springs_set_muscle(sys->springs, k, amplitude, omega, phase) != PSYS_OK)
        return psys__fail(&sys->err, PSYS_ERR_NOMEM, "out of memory adding a muscle");
    return PSYS_OK;
}

bool psys_system_spring_muscle(const psys_system *sys, size_t k, double *amplitude, double *omega, double *phase)
{
    return k < psys_system_spring_count(sys) && psys__springs_muscle(sys->springs, k, amplitude, omega, phase);
}

double psys_system_spring_rest_length(const psys_system *sys, size_t k, double t)
{
    return k < psys_system_spring_count(sys) ? psys__springs_rest_at(sys->springs, k, t) : NAN;
}

/* A copy of spring set src (muscles included), without its plan. */
static void *springs_clone(const void *src)
{
    void *c = psys__springs_create(NULL);
    if (!c)
        return NULL;
    for (size_t k = 0; k < psys__springs_count(src); k++) {
        size_t a, b;
        double ks, kd, rest, amp, om, ph;
        psys__springs_get(src, k, &a, &b, &ks, &kd, &rest);
        if (psys__springs_add(c, a, b, ks, kd, rest) != PSYS_OK
            || (psys__springs_muscle(src, k, &amp, &om, &ph) && psys__springs_set_muscle(c, k, amp, om, ph) != PSYS_OK)) {
            springs_destroy(c);
            return NULL;
        }
    }
    return c;
}

static const struct psys__force_terms spring_terms = {PSYS__TERMS_SPRINGS};
/* Two-particle terms (damped: not velocity-free). */
const psys_force_class psys_spring_class = {.name = "spring",
                                            .apply = springs_apply,
                                            .energy = springs_energy,
                                            .jacobian = springs_jacobian,
                                            .destroy = springs_destroy,
                                            .traits = PSYS_FORCE_BONDED,
                                            .clone = springs_clone,
                                            .terms = &spring_terms};
