/* The step loop (psys_system_advance): one solver step, then collisions
 * with the planes (notes §7). Detection: the sign of (X - P)·N after a
 * step. Response: the normal velocity is multiplied by -restitution.
 * `rollback` rolls the whole system back to the instant of contact (found
 * by linear interpolation of the signed distance, refined by regula falsi
 * on re-integrated partial steps), applies the response there and finishes
 * the step; `displace` projects the particle back onto the plane at the
 * end of the step. Then periodic axes wrap. */
#include "sim/sim.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    double dist = psys__plane_distance(pl, x, d);
    for (int c = 0; c < d; c++)
        x[c] -= dist * pl->n[c];
    double vn = psys__dot(v, pl->n, d);
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
            double d1 = psys__plane_distance(pl, s->x + i * d, d);
            if (d1 >= 0)
                continue;
            double d0 = psys__plane_distance(pl, y0 + i * d, d);
            double a;
            if (d0 > PSYS_CONTACT_DISTANCE)
                a = d0 / (d0 - d1);
            else if (psys__dot(y0 + (s->n + i) * (size_t)d, pl->n, d) < -PSYS_CONTACT_SPEED)
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
    const double v1 = psys__dot(s->v + i * d, pl->n, d), v0 = psys__dot(y0 + (s->n + i) * (size_t)d, pl->n, d);
    if (!(v1 < 0) || !(pl->restitution < 1))
        return false;
    const double d0 = psys__plane_distance(pl, y0 + i * d, d);
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
    double dist = mine ? psys__plane_distance(pl, x + who * d, d) : 0.0;
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
                if (moves(hk, s, i) && (mine && i == who && k == pk ? true : psys__plane_distance(q, s->x + i * d, d) < 0))
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
            double dist = psys__plane_distance(pl, s->x + i * d, d);
            if (dist < 0) {
                bool settled = (psys__plane_distance(pl, y0 + i * d, d) <= PSYS_CONTACT_DISTANCE
                                && psys__dot(y0 + (s->n + i) * (size_t)d, pl->n, d) >= -PSYS_CONTACT_SPEED)
                               || (pl->response == PSYS_RESPONSE_DISPLACE && displace_unresolved(s, pl, y0, i, dist));
                respond(s, pl, i);
                if (settled) {
                    double *v = s->v + i * d, vn = psys__dot(v, pl->n, d);
                    if (vn > 0)
                        for (int c = 0; c < d; c++)
                            v[c] -= vn * pl->n[c];
                }
            }
            if (pl->stick && dist <= PSYS_CONTACT_DISTANCE) {
                double *v = s->v + i * d, vn = psys__dot(v, pl->n, d);
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
