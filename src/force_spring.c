/* Damped Hooke springs (notes eq. 1), all of a system's springs in one
 * force object stored as arrays so the loop streams through memory:
 *   l = a - b,  f_a = -[ks(|l| - r) + kd (l̇·l)/|l|] l/|l|,  f_b = -f_a.
 * A spring of zero current length has no direction and exerts no force. */
#include "internal.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>

/* Muscles (Miller's snakes and worms): spring k with a muscle has rest
 * length r(t) = rest[k]·(1 + amp·sin(omega·t + phase)) at evaluation time t.
 * Muscle arrays stay NULL until the first muscle exists, so a set without
 * muscles runs the plain loop on rest[] with no extra work. */
#define NO_MUSCLE UINT32_MAX

typedef struct springs {
    size_t n, cap;
    uint32_t *a, *b;
    double *ks, *kd, *rest;
    uint32_t *mslot;  /* cap entries once a muscle exists: muscle slot of spring k or NO_MUSCLE */
    double *rest_t;   /* cap entries once a muscle exists: rest length at the latest evaluation
                         time (equal to rest[k] for springs without a muscle) */
    size_t nm, mcap;  /* muscles, compact: spring, amplitude, omega, phase */
    uint32_t *midx;
    double *mamp, *momega, *mphase;
} springs;

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
    free(s);
}

void *psys__springs_create(void) { return calloc(1, sizeof(springs)); }
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
}

/* d is a compile-time constant at each call site, so the inner loops unroll. */
static inline void springs_apply_d(const springs *s, const psys_force_eval *e, const double *restrict rest,
                                   double *restrict f, const int d)
{
    const double *restrict x = e->x, *restrict v = e->v;
    const uint32_t *restrict ia_ = s->a, *restrict ib_ = s->b;
    const double *restrict ks = s->ks, *restrict kd = s->kd;
    for (size_t k = 0; k < s->n; k++) {
        size_t ia = (size_t)ia_[k] * d, ib = (size_t)ib_[k] * d;
        double l[3], ld[3], len2 = 0, dot = 0;
        for (int c = 0; c < d; c++) {
            l[c] = x[ia + c] - x[ib + c];
            ld[c] = v[ia + c] - v[ib + c];
            len2 += l[c] * l[c];
            dot += ld[c] * l[c];
        }
        if (len2 == 0)
            continue;
        double len = sqrt(len2), inv = 1.0 / len;
        double mag = (ks[k] * (len - rest[k]) + kd[k] * dot * inv) * inv;
        for (int c = 0; c < d; c++) {
            double fc = mag * l[c];
            f[ia + c] -= fc;
            f[ib + c] += fc;
        }
    }
}

static void springs_apply(void *data, const psys_force_eval *e, double *f)
{
    const double *rest = rest_at(data, e->t);
    if (e->dim == 2)
        springs_apply_d(data, e, rest, f, 2);
    else
        springs_apply_d(data, e, rest, f, 3);
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

const psys_force_class psys_spring_class = {"spring", springs_apply, springs_energy, springs_jacobian,
                                            springs_destroy};

psys_status psys__parse_muscle(psys__parse *p, const cJSON *obj, const char *path, bool with_step,
                               bool *present, double out[4])
{
    static const char *const keys[] = {"amplitude", "omega", "phase", NULL};
    static const char *const step_keys[] = {"amplitude", "omega", "phase", "phase_step", NULL};
    char mp[256];
    const cJSON *m = cJSON_GetObjectItemCaseSensitive(obj, "muscle");
    snprintf(mp, sizeof mp, "%s.muscle", path);
    *present = m != NULL;
    out[0] = out[1] = out[2] = out[3] = 0;
    if (!m)
        return PSYS_OK;
    if (!cJSON_IsObject(m))
        return psys__parse_fail(p, mp, m, "must be an object {\"amplitude\", \"omega\", \"phase\"%s}",
                                with_step ? ", \"phase_step\"" : "");
    psys_status st = psys__parse_keys(p, m, mp, with_step ? step_keys : keys);
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "amplitude", false, 0, 0, false, &out[0]);
    if (st == PSYS_OK && out[0] > 1) {
        char ap[280];
        snprintf(ap, sizeof ap, "%s.amplitude", mp);
        st = psys__parse_fail(p, ap, cJSON_GetObjectItemCaseSensitive(m, "amplitude"), "must be from 0 to 1");
    }
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "omega", false, 0, -INFINITY, false, &out[1]);
    if (st == PSYS_OK) st = psys__parse_number(p, m, mp, "phase", true, 0, -INFINITY, false, &out[2]);
    if (st == PSYS_OK && with_step)
        st = psys__parse_number(p, m, mp, "phase_step", true, 0, -INFINITY, false, &out[3]);
    return st;
}

static psys_status spring_parse(psys__parse *p, const cJSON *obj, const char *path)
{
    static const char *const keys[] = {"type", "a", "b", "ks", "kd", "rest", "muscle", NULL};
    psys_system *sys = psys__parse_system(p);
    size_t a, b;
    double ks, kd, rest, muscle[4];
    bool has_muscle = false;
    psys_status st = psys__parse_keys(p, obj, path, keys);
    if (st == PSYS_OK) st = psys__parse_ref(p, obj, path, "a", &a);
    if (st == PSYS_OK) st = psys__parse_ref(p, obj, path, "b", &b);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "ks", false, 0, 0, false, &ks);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "kd", true, 0, 0, false, &kd);
    if (st == PSYS_OK) st = psys__parse_number(p, obj, path, "rest", true, -1, 0, false, &rest);
    if (st == PSYS_OK) st = psys__parse_muscle(p, obj, path, false, &has_muscle, muscle);
    if (st == PSYS_OK && a == b) {
        char bpath[256];
        snprintf(bpath, sizeof bpath, "%s.b", path);
        st = psys__parse_fail(p, bpath, cJSON_GetObjectItemCaseSensitive(obj, "b"),
                              "a spring needs two different particles");
    }
    if (st == PSYS_OK && psys_system_add_spring(sys, a, b, ks, kd, rest) != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    if (st == PSYS_OK && has_muscle
        && psys_system_set_spring_muscle(sys, psys_system_spring_count(sys) - 1, muscle[0], muscle[1], muscle[2])
               != PSYS_OK)
        st = psys__parse_fail(p, path, NULL, "%s", psys_system_last_error(sys));
    return st;
}

static psys_status spring_save(const psys_system *sys, const void *data, cJSON *arr)
{
    const springs *s = data;
    for (size_t k = 0; k < s->n; k++) {
        cJSON *o = cJSON_CreateObject();
        if (!o || !cJSON_AddStringToObject(o, "type", "spring")
            || !cJSON_AddItemToObjectCS(o, "a", psys__ref_json(sys, s->a[k]))
            || !cJSON_AddItemToObjectCS(o, "b", psys__ref_json(sys, s->b[k]))
            || !psys__add_num(o, "ks", s->ks[k]) || !psys__add_num(o, "kd", s->kd[k])
            || !psys__add_num(o, "rest", s->rest[k])) {
            cJSON_Delete(o);
            return PSYS_ERR_NOMEM;
        }
        if (s->mslot && s->mslot[k] != NO_MUSCLE) {
            uint32_t m = s->mslot[k];
            cJSON *mo = cJSON_AddObjectToObject(o, "muscle");
            if (!mo || !psys__add_num(mo, "amplitude", s->mamp[m]) || !psys__add_num(mo, "omega", s->momega[m])
                || !psys__add_num(mo, "phase", s->mphase[m])) {
                cJSON_Delete(o);
                return PSYS_ERR_NOMEM;
            }
        }
        cJSON_AddItemToArray(arr, o);
    }
    return PSYS_OK;
}

const psys__force_io psys__spring_io = {"spring", &psys_spring_class, spring_parse, spring_save};
