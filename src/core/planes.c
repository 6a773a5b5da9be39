/* Planes (notes §7, docs/notes-errata.md): their definitions and the
 * contact forces they add to the derivative; the collision response at the
 * end of a step is the step loop's (sim/advance.c).
 * Contact: a particle within PSYS_CONTACT_DISTANCE of a plane whose normal
 * speed is below PSYS_CONTACT_SPEED and that is pushed into it (N·f < 0)
 * gets the contact force -(N·f)N and linear friction -k_f(-N·f)v_t; on a
 * `stick` plane the tangential force and velocity are zeroed instead. A plane
 * may grip harder against a `forward` direction (backward_friction), the
 * scales that let Miller's worms crawl. */
#include "core/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

psys_plane_def psys_plane_def_default(void)
{
    psys_plane_def d;
    memset(&d, 0, sizeof d);
    d.normal[1] = 1;
    d.restitution = 0.5;
    d.friction = 0;
    d.stick = false;
    d.response = PSYS_RESPONSE_ROLLBACK;
    return d;
}

psys_status psys__planes_reserve(psys_system *s)
{
    if (!s->nplanes || !s->cap)
        return PSYS_OK;
    /* Sized to the capacity so growth is rare; called whenever capacity grows. */
    double *p = psys__realloc(s->scratch, 2 * s->cap * (size_t)s->dim, sizeof(double));
    if (!p)
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory for collision handling");
    s->scratch = p;
    return PSYS_OK;
}

psys_status psys_system_add_plane(psys_system *s, const psys_plane_def *def)
{
    int d = s->dim;
    double len = 0;
    for (int k = 0; k < d; k++) {
        if (!isfinite(def->point[k]) || !isfinite(def->normal[k]))
            return psys__fail(&s->err, PSYS_ERR_INVALID, "plane point and normal must be finite");
        len += def->normal[k] * def->normal[k];
    }
    len = sqrt(len);
    if (!(len > 0))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "plane normal must not be zero");
    if (!(def->restitution >= 0 && def->restitution <= 1))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "plane restitution must be from 0 to 1");
    if (!(def->friction >= 0) || !isfinite(def->friction))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "plane friction must be finite and >= 0");
    if (def->response != PSYS_RESPONSE_ROLLBACK && def->response != PSYS_RESPONSE_DISPLACE)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "unknown collision response");
    if (!(def->backward_friction >= 0) || !isfinite(def->backward_friction))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "plane backward friction must be finite and >= 0");
    /* The forward direction lives in the plane: its normal component is dropped. */
    double fwd[3] = {0, 0, 0}, fn = 0, fl = 0;
    for (int k = 0; k < d; k++) {
        if (!isfinite(def->forward[k]))
            return psys__fail(&s->err, PSYS_ERR_INVALID, "plane forward direction must be finite");
        fn += def->forward[k] * def->normal[k] / len;
    }
    for (int k = 0; k < d; k++) {
        fwd[k] = def->forward[k] - fn * def->normal[k] / len;
        fl += fwd[k] * fwd[k];
    }
    fl = sqrt(fl);
    bool any_forward = false;
    for (int k = 0; k < d; k++)
        any_forward |= def->forward[k] != 0;
    if (any_forward && !(fl > 1e-12))
        return psys__fail(&s->err, PSYS_ERR_INVALID, "plane forward direction must not be along the normal");
    if (s->nplanes == s->planes_cap) {
        size_t cap = s->planes_cap ? 2 * s->planes_cap : 4;
        psys__plane *p = psys__realloc(s->planes, cap, sizeof *p);
        if (!p)
            return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory adding a plane");
        s->planes = p;
        s->planes_cap = cap;
    }
    psys__plane *pl = &s->planes[s->nplanes];
    memset(pl, 0, sizeof *pl);
    for (int k = 0; k < d; k++) {
        pl->p[k] = def->point[k];
        pl->n[k] = def->normal[k] / len;
        pl->given_n[k] = def->normal[k];
    }
    pl->restitution = def->restitution;
    pl->friction = def->friction;
    pl->stick = def->stick;
    pl->response = def->response;
    pl->backward_friction = any_forward ? def->backward_friction : def->friction;
    for (int k = 0; k < d; k++) {
        pl->forward[k] = any_forward ? fwd[k] / fl : 0.0;
        pl->given_forward[k] = def->forward[k];
    }
    s->nplanes++;
    if (psys__planes_reserve(s) != PSYS_OK) {
        s->nplanes--;
        return PSYS_ERR_NOMEM;
    }
    return PSYS_OK;
}

size_t psys_system_plane_count(const psys_system *s) { return s->nplanes; }

psys_status psys_system_plane(const psys_system *s, size_t k, psys_plane_def *def)
{
    if (k >= s->nplanes)
        return PSYS_ERR_INVALID;
    const psys__plane *pl = &s->planes[k];
    *def = psys_plane_def_default();
    memcpy(def->point, pl->p, sizeof pl->p);
    memcpy(def->normal, pl->n, sizeof pl->n);
    def->restitution = pl->restitution;
    def->friction = pl->friction;
    def->stick = pl->stick;
    def->response = pl->response;
    memcpy(def->forward, pl->forward, sizeof pl->forward);
    def->backward_friction = pl->backward_friction;
    return PSYS_OK;
}


/* A plane's constants for contact_law, copied out of it (so that stores
 * to forces cannot alias them). */
typedef struct contact_plane {
    double p[3], n[3], forward[3];
    double kf, kb; /* friction, and backward friction where it differs (else friction again) */
} contact_plane;

static inline contact_plane contact_plane_of(const psys__plane *pl)
{
    contact_plane q;
    for (int c = 0; c < 3; c++) {
        q.p[c] = pl->p[c];
        q.n[c] = pl->n[c];
        q.forward[c] = pl->forward[c];
    }
    q.kf = pl->friction;
    q.kb = pl->backward_friction != pl->friction ? pl->backward_friction : pl->friction;
    return q;
}

/* Plane q's contact force (notes §7.3) on a particle at x with velocity v,
 * into its total applied force f, where it is free (is_free): within
 * PSYS_CONTACT_DISTANCE of the plane, slower than PSYS_CONTACT_SPEED
 * along its normal and pushed into it (f·n < 0), the normal part of f is
 * cancelled and friction opposes the tangential velocity (stick: f = 0,
 * the tangential part held by the surface). The tests are selections, not
 * branches, so loops over particles vectorise; a NaN passes each test (as
 * it passed the branches this replaced), so it reaches f. d is a constant
 * where inlined. */
static inline __attribute__((always_inline)) void contact_law(const contact_plane *q, const double *x,
                                                               const double *v, double *f, int is_free,
                                                               const bool stick, const int d)
{
    double dist = 0, vn = 0, fn = 0, along = 0; /* along: v_t·forward = v·forward, forward in the plane */
    for (int c = 0; c < d; c++) {
        dist += (x[c] - q->p[c]) * q->n[c];
        vn += v[c] * q->n[c];
        fn += f[c] * q->n[c];
        along += v[c] * q->forward[c];
    }
    /* & rather than &&: every test made, no branch */
    const int on = is_free & !(dist > PSYS_CONTACT_DISTANCE) & !(fabs(vn) > PSYS_CONTACT_SPEED) & !(fn >= 0);
    const double kf = along < 0 ? q->kb : q->kf;
    for (int c = 0; c < d; c++) {
        const double vt = v[c] - vn * q->n[c], g = f[c] + (-fn * q->n[c] - kf * (-fn) * vt);
        f[c] = on ? (stick ? 0.0 : g) : f[c];
    }
}

/* psys__contact_forces for one plane with d and stick constants. */
static inline __attribute__((always_inline)) void contact_plane_forces(const psys_system *s, const psys__plane *pl,
                                                                        const double *x, const double *v, double *f,
                                                                        const bool stick, const int d)
{
    const contact_plane q = contact_plane_of(pl);
    for (size_t i = 0; i < s->n; i++)
        contact_law(&q, x + i * d, v + i * d, f + i * d, !(s->flags[i] & PSYS_PARTICLE_NOT_FREE), stick, d);
}

void psys__contact_forces(const psys_system *s, const double *x, const double *v, double *f)
{
    for (size_t k = 0; k < s->nplanes; k++) {
        const psys__plane *pl = &s->planes[k];
        if (s->dim == 3)
            pl->stick ? contact_plane_forces(s, pl, x, v, f, true, 3) : contact_plane_forces(s, pl, x, v, f, false, 3);
        else
            pl->stick ? contact_plane_forces(s, pl, x, v, f, true, 2) : contact_plane_forces(s, pl, x, v, f, false, 2);
    }
}

/* contact_law of plane pl on rows X, V, F at j0 + j, j < cnt, free_[j]
 * saying which particles are free; d and stick constants. */
static inline __attribute__((always_inline)) void contact_plane_rows(const psys__plane *pl,
                                                                      const long long *restrict free_, size_t j0,
                                                                      size_t cnt, const double *const *X,
                                                                      const double *const *V, double *const *F,
                                                                      const bool stick, const int d)
{
    const contact_plane q = contact_plane_of(pl);
    /* the third rows only in 3-D: restrict pointers must not share a row */
    const double *restrict x0 = X[0] + j0, *restrict x1 = X[1] + j0, *restrict x2 = d == 3 ? X[2] + j0 : NULL;
    const double *restrict v0 = V[0] + j0, *restrict v1 = V[1] + j0, *restrict v2 = d == 3 ? V[2] + j0 : NULL;
    double *restrict f0 = F[0] + j0, *restrict f1 = F[1] + j0, *restrict f2 = d == 3 ? F[2] + j0 : NULL;
    /* the rows are distinct and each j stands alone; GCC honours restrict
     * only on parameters, so it is told directly */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC ivdep
#endif
    for (size_t j = 0; j < cnt; j++) {
        const double x[3] = {x0[j], x1[j], d == 3 ? x2[j] : 0.0}, v[3] = {v0[j], v1[j], d == 3 ? v2[j] : 0.0};
        double f[3] = {f0[j], f1[j], d == 3 ? f2[j] : 0.0};
        contact_law(&q, x, v, f, free_[j] != 0, stick, d);
        f0[j] = f[0];
        f1[j] = f[1];
        if (d == 3)
            f2[j] = f[2];
    }
}

/* Every plane in turn, as psys__contact_forces takes them. */
PSYS_CLONES
static void contact_rows_clones(const psys_system *s, const uint32_t *perm, size_t a, size_t cnt,
                                const double *const *X, const double *const *V, double *const *F)
{
    /* in pieces of 256: which particles are free, as 64-bit numbers the
     * vector loop reads beside the doubles (a byte gather does not
     * vectorise) */
    long long free_[256];
    for (size_t j0 = 0; j0 < cnt; j0 += 256) {
        const size_t c = cnt - j0 < 256 ? cnt - j0 : 256;
        for (size_t j = 0; j < c; j++) {
            const size_t i = perm ? perm[a + j0 + j] : a + j0 + j;
            free_[j] = !(s->flags[i] & PSYS_PARTICLE_NOT_FREE);
        }
        for (size_t k = 0; k < s->nplanes; k++) {
            const psys__plane *pl = &s->planes[k];
            /* d and stick as constants: a loop each */
            if (s->dim == 3) {
                if (pl->stick)
                    contact_plane_rows(pl, free_, j0, c, X, V, F, true, 3);
                else
                    contact_plane_rows(pl, free_, j0, c, X, V, F, false, 3);
            } else if (pl->stick) {
                contact_plane_rows(pl, free_, j0, c, X, V, F, true, 2);
            } else {
                contact_plane_rows(pl, free_, j0, c, X, V, F, false, 2);
            }
        }
    }
}

/* The clones stay static, as elsewhere in the library: the exported name
 * is a plain call into them. */
void psys__contact_rows(const psys_system *s, const uint32_t *perm, size_t a, size_t cnt, const double *const *X,
                        const double *const *V, double *const *F)
{
    contact_rows_clones(s, perm, a, cnt, X, V, F);
}

