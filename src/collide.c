/* Particle/plane collisions and contact (notes §7 with ERRATA).
 *
 * Detection: the sign of (X - P)·N after a step. Response: the normal
 * velocity is multiplied by -restitution. `rollback` rolls the whole system
 * back to the instant of contact (found by linear interpolation of the
 * signed distance, refined by regula falsi on re-integrated partial steps),
 * applies the response there and finishes the step; `displace` projects the
 * particle back onto the plane at the end of the step.
 * Contact: a particle within PSYS_CONTACT_DISTANCE of a plane whose normal
 * speed is below PSYS_CONTACT_SPEED and that is pushed into it (N·f < 0)
 * gets the contact force -(N·f)N and linear friction -k_f(-N·f)v_t; on a
 * `stick` plane the tangential force and velocity are zeroed instead. A plane
 * may grip harder against a `forward` direction (backward_friction), the
 * scales that let Miller's worms crawl. */
#include "internal.h"

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

static inline double dot_d(const double *a, const double *b, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += a[k] * b[k];
    return s;
}

static inline double plane_distance(const psys__plane *pl, const double *x, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += (x[k] - pl->p[k]) * pl->n[k];
    return s;
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

/* One step of exactly h (adaptive solvers may need several). */
static psys_status step_exact(psys_solver *solver, double h)
{
    double left = h;
    while (left > 0) {
        double taken;
        psys_status st = psys_solver_step(solver, left, &taken);
        if (st != PSYS_OK)
            return st;
        if (taken >= left)
            break;
        left -= taken;
    }
    return PSYS_OK;
}

static void save_state(const psys_system *s, double *y)
{
    size_t nd = s->n * (size_t)s->dim;
    if (!nd)
        return;
    memcpy(y, s->x, nd * sizeof(double));
    memcpy(y + nd, s->v, nd * sizeof(double));
}

static void restore_state(psys_system *s, const double *y, double t)
{
    size_t nd = s->n * (size_t)s->dim;
    if (nd) {
        memcpy(s->x, y, nd * sizeof(double));
        memcpy(s->v, y + nd, nd * sizeof(double));
    }
    s->t = t;
}

/* Does this rank move particle i (all do without hooks)? */
static inline bool moves(const psys__collide_hooks *hk, const psys_system *s, size_t i)
{
    return !(s->flags[i] & PSYS_PARTICLE_NOT_FREE) && (!hk || hk->own[i]);
}

/* Put particle i on plane pl and apply the collision response to an
 * approaching normal velocity. */
static void respond(psys_system *s, const psys__plane *pl, size_t i)
{
    int d = s->dim;
    double *x = s->x + i * d, *v = s->v + i * d;
    double dist = plane_distance(pl, x, d);
    for (int c = 0; c < d; c++)
        x[c] -= dist * pl->n[c];
    double vn = dot_d(v, pl->n, d);
    if (vn < 0) {
        double out = -pl->restitution * vn;
        if (out < PSYS_CONTACT_SPEED)
            out = 0; /* too slow to bounce: it comes to rest on the plane */
        for (int c = 0; c < d; c++)
            v[c] += (out - vn) * pl->n[c];
    }
}

/* Earliest crossing of a rollback plane: returns the fraction alpha of the
 * step, or 2 if none. A particle touching the plane at y0 and moving into it
 * collides at alpha = 0; one resting on it, or leaving it too slowly to be
 * clear by the end of the step, is left to the end-of-step pass. */
static double earliest_crossing(const psys_system *s, const psys__collide_hooks *hk, const double *y0, size_t *who,
                                size_t *plane)
{
    int d = s->dim;
    double best = 2;
    for (size_t k = 0; k < s->nplanes; k++) {
        const psys__plane *pl = &s->planes[k];
        if (pl->response != PSYS_RESPONSE_ROLLBACK)
            continue;
        for (size_t i = 0; i < s->n; i++) {
            if (!moves(hk, s, i))
                continue;
            double d1 = plane_distance(pl, s->x + i * d, d);
            if (d1 >= 0)
                continue;
            double d0 = plane_distance(pl, y0 + i * d, d);
            double a;
            if (d0 > PSYS_CONTACT_DISTANCE)
                a = d0 / (d0 - d1);
            else if (dot_d(y0 + (s->n + i) * (size_t)d, pl->n, d) < -PSYS_CONTACT_SPEED)
                a = 0;
            else
                continue;
            if (a < best) {
                best = a;
                *who = i;
                *plane = k;
            }
        }
    }
    return best;
}

/* Has particle i, behind displace plane pl at the end of a step that began
 * at y0, bounced below what the step can resolve? Displacing it back and
 * reflecting its end-of-step normal velocity v1 adds back the speed the
 * step's forces gave it behind the plane, up to dv = v0 - v1 (into the
 * plane): a bounce of restitution e at the contact speed |v_c| loses
 * (1 - e)|v_c|, and once that is less than dv the bounces no longer die out
 * but settle into a cycle of bounces up to e·dv/(1 - e) fast that never
 * falls below PSYS_CONTACT_SPEED when dv is above it (g = 9.81, dt = 1e-3,
 * e = 0.5: 0.00654 forever).
 * v_c is interpolated as rollback's contact instant would find it under
 * constant acceleration: v_c² = a v1² + (1 - a) v0², a = d0/(d0 - d1) the
 * fraction of the distance covered at the crossing. An elastic plane
 * (e = 1) loses nothing and never settles. */
static bool displace_unresolved(const psys_system *s, const psys__plane *pl, const double *y0, size_t i, double d1)
{
    const int d = s->dim;
    const double v1 = dot_d(s->v + i * d, pl->n, d), v0 = dot_d(y0 + (s->n + i) * (size_t)d, pl->n, d);
    if (!(v1 < 0) || !(pl->restitution < 1))
        return false;
    const double d0 = plane_distance(pl, y0 + i * d, d);
    const double a = d0 > 0 ? d0 / (d0 - d1) : 0.0;
    const double vc = sqrt(a * v1 * v1 + (1 - a) * v0 * v0);
    return (1 - pl->restitution) * vc < v0 - v1;
}

psys_status psys_system_advance(psys_system *s, psys_solver *solver, double h_max, double *h_taken)
{
    return psys__advance(s, solver, h_max, h_taken, NULL);
}

/* The distance of the crossing particle, from the rank that owns it. */
static double who_distance(const psys__collide_hooks *hk, const psys__plane *pl, const double *x, size_t who, bool mine,
                           int d)
{
    double dist = mine ? plane_distance(pl, x + who * d, d) : 0.0;
    return hk ? hk->share(hk->ctx, dist) : dist;
}

psys_status psys__advance(psys_system *s, psys_solver *solver, double h_max, double *h_taken,
                          const psys__collide_hooks *hk)
{
    double h = 0;
    psys_solver_set_threads(solver, psys_system_effective_threads(s));
    /* nothing can collide (and the scratch state is NULL with no particles;
     * across ranks every rank takes part in the events, however few it has) */
    if (!s->nplanes || (!s->n && !hk)) {
        /* a mesh numbered out of order: the step in the springs' order, the
         * same bits; a failure is taken again in the particles' order, whose
         * message names the first bad component as users number them */
        const bool ordered = !hk && psys__state_order_begin(s, solver);
        psys_status st = psys_solver_step(solver, h_max, &h);
        if (ordered) {
            psys__state_order_end(s);
            if (st == PSYS_ERR_NONFINITE)
                st = psys_solver_step(solver, h_max, &h);
        }
        if (st == PSYS_OK)
            psys__box_wrap(s); /* periodic axes: back into the box after each accepted step */
        if (h_taken)
            *h_taken = h;
        return st;
    }
    int d = s->dim;
    double *y0 = s->scratch;
    double t0 = s->t;
    save_state(s, y0);
    psys_status st = psys_solver_step(solver, h_max, &h);
    if (st != PSYS_OK)
        return st;
    const double t_end = t0 + h;
    double left = h;
    /* Each pass handles the earliest contact event in the rest of the step. */
    for (int pass = 0; pass < 64 && left > 0; pass++) {
        size_t who = SIZE_MAX, pk = 0;
        double alpha = earliest_crossing(s, hk, y0, &who, &pk);
        bool mine = who != SIZE_MAX; /* this rank holds the crossing particle */
        size_t who_g = mine ? (hk ? hk->gid[who] : who) : SIZE_MAX;
        if (hk) /* the earliest over all ranks; every rank the same (alpha, plane, particle) */
            mine = hk->earliest(hk->ctx, &alpha, &pk, &who_g) && mine;
        if (alpha > 1)
            break;
        const psys__plane *pl = &s->planes[pk];
        /* Regula falsi (Illinois) on the crossing particle's distance, each
         * trial re-integrating the partial step from y0. */
        double lo = 0, hi = 1, dlo = who_distance(hk, pl, y0, who, mine, d);
        double dhi = who_distance(hk, pl, s->x, who, mine, d), scale = dlo - dhi;
        int side = 0;
        double done = alpha; /* the fraction the current state was integrated to */
        for (int it = 0; it < 12; it++) {
            restore_state(s, y0, t0);
            if (alpha > 0 && (st = step_exact(solver, alpha * left)) != PSYS_OK)
                return st;
            done = alpha;
            double dc = who_distance(hk, pl, s->x, who, mine, d);
            if (alpha == 0 || fabs(dc) <= 1e-12 * scale || hi - lo <= 1e-15)
                break;
            if (dc > 0) {
                lo = alpha;
                dlo = dc;
                if (side == 1)
                    dhi *= 0.5;
                side = 1;
            } else {
                hi = alpha;
                dhi = dc;
                if (side == -1)
                    dlo *= 0.5;
                side = -1;
            }
            alpha = lo + (hi - lo) * dlo / (dlo - dhi);
        }
        /* At the contact instant: respond for every particle touching or
         * behind a rollback plane while approaching it. */
        for (size_t k = 0; k < s->nplanes; k++) {
            const psys__plane *q = &s->planes[k];
            if (q->response != PSYS_RESPONSE_ROLLBACK)
                continue;
            for (size_t i = 0; i < s->n; i++)
                if (moves(hk, s, i) && (mine && i == who && k == pk ? true : plane_distance(q, s->x + i * d, d) < 0))
                    respond(s, q, i);
        }
        t0 += done * left;
        left -= done * left;
        save_state(s, y0);
        if (left <= 1e-15 * fmax(1.0, fabs(t_end)))
            break;
        if ((st = step_exact(solver, left)) != PSYS_OK)
            return st;
    }
    /* Anything still behind a plane (displace planes, resting particles,
     * leftovers) is projected back. A particle that started the (rest of the)
     * step touching the plane and not approaching it fast, yet ends behind it,
     * bounced below what this step can resolve: it comes to rest (this ends
     * the endless series of ever smaller bounces); so does one behind a
     * displace plane whose bounce the step cannot resolve
     * (displace_unresolved). Sticky contacts lose their tangential velocity. */
    for (size_t k = 0; k < s->nplanes; k++) {
        const psys__plane *pl = &s->planes[k];
        for (size_t i = 0; i < s->n; i++) {
            if (!moves(hk, s, i))
                continue;
            double dist = plane_distance(pl, s->x + i * d, d);
            if (dist < 0) {
                bool settled = (plane_distance(pl, y0 + i * d, d) <= PSYS_CONTACT_DISTANCE
                                && dot_d(y0 + (s->n + i) * (size_t)d, pl->n, d) >= -PSYS_CONTACT_SPEED)
                               || (pl->response == PSYS_RESPONSE_DISPLACE && displace_unresolved(s, pl, y0, i, dist));
                respond(s, pl, i);
                if (settled) {
                    double *v = s->v + i * d, vn = dot_d(v, pl->n, d);
                    if (vn > 0)
                        for (int c = 0; c < d; c++)
                            v[c] -= vn * pl->n[c];
                }
            }
            if (pl->stick && dist <= PSYS_CONTACT_DISTANCE) {
                double *v = s->v + i * d, vn = dot_d(v, pl->n, d);
                if (vn <= PSYS_CONTACT_SPEED) /* not when it is leaving the surface */
                    for (int c = 0; c < d; c++)
                        v[c] = vn * pl->n[c];
            }
        }
    }
    s->t = t_end;
    /* The passes' partial steps projected controlled particles at their own
     * sums of fractions of h, which can round off t_end: put them on their
     * paths at the step's time, as a run resumed at t_end would. */
    psys_system_apply_controllers(s, t_end);
    psys__box_wrap(s);
    if (h_taken)
        *h_taken = h;
    return PSYS_OK;
}
