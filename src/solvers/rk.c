/* Explicit Runge–Kutta solvers driven by Butcher tableaux: euler, midpoint,
 * rk4 share one stepper; rk45 is Dormand–Prince 5(4) with error control. */
#include "solvers/solver.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

enum { Y0, YTMP, Y1, K0 }; /* scratch vector slots; stage k_i is buf[K0 + i] */

static const psys__tableau euler_tab = {
    .stages = 1, .b = {1}, .c = {0},
};

static const psys__tableau midpoint_tab = {
    .stages = 2, .a = {{0}, {0.5}}, .b = {0, 1}, .c = {0, 0.5},
};

static const psys__tableau rk4_tab = {
    .stages = 4,
    .a = {{0}, {0.5}, {0, 0.5}, {0, 0, 1}},
    .b = {1.0 / 6, 1.0 / 3, 1.0 / 3, 1.0 / 6},
    .c = {0, 0.5, 0.5, 1},
};

/* Dormand & Prince (1980), the pair behind MATLAB's ode45. */
static const psys__tableau dopri5_tab = {
    .stages = 7,
    .a = {{0},
          {1.0 / 5},
          {3.0 / 40, 9.0 / 40},
          {44.0 / 45, -56.0 / 15, 32.0 / 9},
          {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729},
          {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656},
          {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}},
    .b = {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84, 0},
    .bhat = {5179.0 / 57600, 0, 7571.0 / 16695, 393.0 / 640, -92097.0 / 339200, 187.0 / 2100, 1.0 / 40},
    .c = {0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1, 1},
};

/* out = base + h * Σ w[j] k[j] over the nonzero weights only, so rk4's
 * one-term stages are a single fused pass over memory. */
static void combine(int nt, size_t n, double *out, const double *base, double h, const double *w, int count,
                    double *const *k)
{
    int idx[7], m = 0;
    for (int j = 0; j < count; j++)
        if (w[j] != 0)
            idx[m++] = j;
    if (m == 0) {
        if (out != base)
            memcpy(out, base, n * sizeof(double));
    } else if (m == 1) {
        const double w0 = w[idx[0]], *k0 = k[idx[0]];
        PSYS_PAR_FOR(nt, n)
        for (size_t i = 0; i < n; i++)
            out[i] = base[i] + h * (w0 * k0[i]);
    } else {
        PSYS_PAR_FOR(nt, n)
        for (size_t i = 0; i < n; i++) {
            double acc = 0;
            for (int j = 0; j < m; j++)
                acc += w[idx[j]] * k[idx[j]][i];
            out[i] = base[i] + h * acc;
        }
    }
}

/* All stages of tab from (t, y0); the propagated solution goes to y1. */
static psys_status rk_stages(psys_solver *s, const psys__tableau *tab, double t, double h, double *y0, double *y1)
{
    double *const *k = &s->buf[K0];
    for (int i = 0; i < tab->stages; i++) {
        double *yi = y0;
        if (i > 0) {
            yi = s->buf[YTMP];
            combine(psys__solver_threads(s), s->n, yi, y0, h, tab->a[i], i, k);
        }
        psys_status st = psys__solver_eval(s, t + tab->c[i] * h, yi, k[i]);
        if (st != PSYS_OK)
            return st;
    }
    combine(psys__solver_threads(s), s->n, y1, y0, h, tab->b, tab->stages, k);
    return PSYS_OK;
}

/* True when stage i uses only stage i-1 (a[i][j] != 0 exactly for j = i-1):
 * euler, midpoint and rk4. */
static bool rk_is_chain(const psys__tableau *tab)
{
    for (int i = 1; i < tab->stages; i++)
        for (int j = 0; j < i; j++)
            if ((tab->a[i][j] != 0) != (j == i - 1))
                return false;
    return true;
}

/* rk_stages for chain tableaux with one stage vector and one pass over
 * memory per stage: after stage i, the same pass forms the next stage's
 * state and adds b_i k_i into y1. Each element sees the same operations in
 * the same order as combine() (acc = 0 + w k, acc += w k, ..., y0 + h acc;
 * or y0 + h (w k) for a single weight), so the bits are those of rk_stages. */
/* Role of stage i's weight in a chain tableau with nw nonzero weights, the
 * last at stage `last`, after `seen` earlier nonzero ones:
 * 0 no weight, 1 the only weight, 2 first, 3 middle, 4 last. */
static int chain_role(const psys__tableau *tab, int i, int nw, int seen, int last)
{
    const double w = tab->b[i];
    return w == 0 ? 0 : nw == 1 ? 1 : seen == 0 ? 2 : i == last ? 4 : 3;
}

/* Stage i's work on its derivative (psys__stage_pass): weight into acc (y1)
 * by its role, and the next stage's state into next (NULL after the last). */
static psys__stage_pass chain_pass(const psys__tableau *tab, int i, double h, const double *y0, double *y1,
                                  double *next, int nw, int seen, int last, int *finite)
{
    const bool more = i + 1 < tab->stages;
    const int role = chain_role(tab, i, nw, seen, last);
    psys__stage_pass p = {.h = h, .base = y0, .w = tab->b[i], .acc = role == 0 ? NULL : y1};
    p.acc_op = role == 1 ? PSYS__ACC_BASE_STEP
               : more    ? (role == 2 ? PSYS__ACC_SET : PSYS__ACC_ADD)
                         : (role == 2 ? PSYS__ACC_BASE_FIRST : PSYS__ACC_BASE_SUM);
    p.next = more ? next : NULL;
    p.a = more ? tab->a[i + 1][i] : 0;
    p.finite = i == last ? finite : NULL; /* the pass that completes acc */
    return p;
}

/* rk_chain_stages through fast.derivative_chain (all stages in one call), or
 * else fast.derivative_stage: each stage's derivative is applied to acc and
 * the next stage's state as it is computed and never stored. Stage by
 * stage, the next state alternates between two vectors, since the stage's
 * own state is read while it is written. The operations per element are
 * those of rk_chain_stages (psys__stage_pass.acc_op), so the same bits.
 * y0 is the step's start only once *loaded: the chain may read the ODE's
 * state where it is (derivative_chain_current) and spare the copy; else
 * y0 is loaded here. PSYS_ERR_UNSUPPORTED, with nothing done (and y0
 * perhaps loaded), when the ODE declines. */
static psys_status rk_chain_fused(psys_solver *s, const psys__tableau *tab, double t, double h, double *y0,
                                  bool *loaded, double *y1, int nw, int last)
{
    const int ns = tab->stages;
    if (s->fast.derivative_chain && ns > 1 && s->fast.derivative_chain(s->ode.ctx, t, NULL, ns, NULL, NULL) == PSYS_OK) {
        /* All stages in one call: each stage's state in a vector of its own
         * (the ODE may still be reading stage i's state while it writes
         * stage i + 1's), slots YTMP, K0 + 1, ..., K0 + ns - 2. */
        psys__stage_pass pass[7];
        int finite = -1, in_place = -1;
        for (int i = 0, seen = 0; i < ns; i++) {
            double *next = i + 1 < ns ? s->buf[i == 0 ? YTMP : K0 + i] : NULL;
            pass[i] = chain_pass(tab, i, h, NULL, y1, next, nw, seen, last, &finite);
            if (tab->b[i] != 0)
                seen++;
        }
        psys_status st = PSYS_ERR_UNSUPPORTED;
        if (s->fast.derivative_chain_current && !*loaded) {
            /* the result straight into the state where no later stage reads the start */
            pass[last].in_place = last == ns - 1 ? &in_place : NULL;
            st = s->fast.derivative_chain_current(s->ode.ctx, t, ns, tab->c, pass);
            pass[last].in_place = NULL;
        }
        if (st == PSYS_ERR_UNSUPPORTED) {
            in_place = -1;
            if (!*loaded)
                s->ode.get_state(s->ode.ctx, y0);
            *loaded = true;
            for (int i = 0; i < ns; i++)
                pass[i].base = y0;
            st = s->fast.derivative_chain(s->ode.ctx, t, y0, ns, tab->c, pass);
        }
        if (st == PSYS_OK) {
            s->y1_finite = finite == 1;
            s->y1_in_state = in_place == 1;
            return PSYS_OK;
        }
        if (st == PSYS_ERR_UNSUPPORTED) /* it accepted the step: declining now is a fault, not a fallback */
            return psys__fail(&s->err, PSYS_ERR_INVALID, "the derivative declined a step at t = %.17g", t);
        return psys__fail(&s->err, st, "the derivative evaluation failed in the step from t = %.17g", t);
    }
    if (!s->fast.derivative_stage || s->fast.derivative_stage(s->ode.ctx, t, NULL, NULL) != PSYS_OK)
        return PSYS_ERR_UNSUPPORTED; /* asked before any projection: callbacks run once per stage */
    if (!*loaded)
        s->ode.get_state(s->ode.ctx, y0);
    *loaded = true;
    double *next[2] = {s->buf[YTMP], ns > 1 ? s->buf[K0 + 1] : NULL};
    double *yi = y0;
    int seen = 0, finite = -1;
    for (int i = 0; i < ns; i++) {
        const psys__stage_pass p =
            chain_pass(tab, i, h, y0, y1, i + 1 < ns ? next[i & 1] : NULL, nw, seen, last, &finite);
        if (tab->b[i] != 0)
            seen++;
        const double ti = t + tab->c[i] * h;
        if (s->ode.project)
            s->ode.project(s->ode.ctx, ti, yi);
        psys_status st = s->fast.derivative_stage(s->ode.ctx, ti, yi, &p);
        if (st == PSYS_ERR_UNSUPPORTED) /* it accepted the step: declining a stage now is a fault, not a fallback */
            return psys__fail(&s->err, PSYS_ERR_INVALID, "the derivative declined stage %d of a step at t = %.17g",
                              i, ti);
        if (st != PSYS_OK)
            return psys__fail(&s->err, st, "the derivative evaluation failed at t = %.17g", ti);
        yi = p.next;
    }
    s->y1_finite = finite == 1;
    return PSYS_OK;
}

/* The stages of a chain tableau into y1; y0 gets the step's start (get_state)
 * unless the ODE's chain reads it where it is (rk_chain_fused). */
static psys_status rk_chain_stages(psys_solver *s, const psys__tableau *tab, double t, double h, double *y0,
                                   double *y1)
{
    const size_t n = s->n;
    const int nt = psys__solver_threads(s);
    double *restrict k = s->buf[K0], *restrict yt = s->buf[YTMP], *restrict acc = y1;
    const double *restrict base = y0;
    int nw = 0, last = -1;
    for (int j = 0; j < tab->stages; j++)
        if (tab->b[j] != 0) {
            nw++;
            last = j;
        }
    bool loaded = false;
    if ((s->fast.derivative_stage || s->fast.derivative_chain) && nw > 0) {
        psys_status st = rk_chain_fused(s, tab, t, h, y0, &loaded, y1, nw, last);
        if (st != PSYS_ERR_UNSUPPORTED)
            return st;
    }
    if (!loaded)
        s->ode.get_state(s->ode.ctx, y0);
    int seen = 0;
    for (int i = 0; i < tab->stages; i++) {
        psys_status st = psys__solver_eval(s, t + tab->c[i] * h, i == 0 ? y0 : yt, k);
        if (st != PSYS_OK)
            return st;
        const bool next = i + 1 < tab->stages;
        const double an = next ? tab->a[i + 1][i] : 0, w = tab->b[i];
        const int role = chain_role(tab, i, nw, seen, last);
        if (w != 0)
            seen++;
        /* role 0: no weight; 1: the only weight; 2: first; 3: middle; 4: last */
        if (next) {
            switch (role) {
            case 0:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++)
                    yt[j] = base[j] + h * (an * k[j]);
                break;
            case 1:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++) {
                    acc[j] = base[j] + h * (w * k[j]);
                    yt[j] = base[j] + h * (an * k[j]);
                }
                break;
            case 2:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++) {
                    acc[j] = 0.0 + w * k[j];
                    yt[j] = base[j] + h * (an * k[j]);
                }
                break;
            default:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++) {
                    acc[j] = acc[j] + w * k[j];
                    yt[j] = base[j] + h * (an * k[j]);
                }
                break;
            }
        } else {
            switch (role) {
            case 0:
                if (nw == 0)
                    memcpy(acc, base, n * sizeof(double));
                break;
            case 1:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++)
                    acc[j] = base[j] + h * (w * k[j]);
                break;
            case 2:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++)
                    acc[j] = base[j] + h * (0.0 + w * k[j]);
                break;
            default:
                PSYS_PAR_FOR(nt, n)
                for (size_t j = 0; j < n; j++)
                    acc[j] = base[j] + h * (acc[j] + w * k[j]);
                break;
            }
        }
    }
    return PSYS_OK;
}

/* psys__solver_commit where the ODE wrote the step's result into its state
 * itself and the start into y1 (psys__stage_pass.in_place, where project
 * changes none of the result): the state kept, or y1 put back when the
 * result is not finite, scanned through y0 unless the stages looked. */
static psys_status rk_commit_in_state(psys_solver *s, double *y0, const double *y1, double t1)
{
    const bool known = s->y1_finite;
    s->y1_finite = s->y1_in_state = false;
    size_t bad = SIZE_MAX;
    if (!known) {
        s->ode.get_state(s->ode.ctx, y0);
        bad = psys__solver_first_nonfinite(s, y0);
    }
    if (bad != SIZE_MAX) {
        s->ode.set_state(s->ode.ctx, y1); /* nothing of the refused step kept */
        return psys__solver_nonfinite(s, bad);
    }
    s->ode.set_time(s->ode.ctx, t1);
    return PSYS_OK;
}

static psys_status rk_fixed_step(psys_solver *s, double h, double *h_taken)
{
    double *y0 = s->buf[Y0], *y1 = s->buf[Y1];
    double t = s->ode.get_time(s->ode.ctx);
    psys_status st;
    if (rk_is_chain(s->cls->tab)) {
        st = rk_chain_stages(s, s->cls->tab, t, h, y0, y1); /* loads y0 where it needs it */
    } else {
        s->ode.get_state(s->ode.ctx, y0);
        st = rk_stages(s, s->cls->tab, t, h, y0, y1);
    }
    if (st == PSYS_OK)
        st = s->y1_in_state ? rk_commit_in_state(s, y0, y1, t + h) : psys__solver_commit(s, y1, t + h);
    *h_taken = h;
    return st;
}

/* RMS of the embedded error scaled by tol·(1 + max(|y0|, |y1|)); inf if any
 * component is not finite. */
static double error_norm(const psys_solver *s, const psys__tableau *tab, double h, const double *y0,
                         const double *y1)
{
    double *const *k = &s->buf[K0];
    double e[7], sum = 0;
    for (int j = 0; j < tab->stages; j++)
        e[j] = tab->b[j] - tab->bhat[j];
    for (size_t i = 0; i < s->n; i++) {
        double err = 0;
        for (int j = 0; j < tab->stages; j++)
            err += e[j] * k[j][i];
        err *= h;
        double scale = s->tol * (1.0 + fmax(fabs(y0[i]), fabs(y1[i])));
        double r = err / scale;
        sum += r * r;
    }
    double count = (double)s->n;
    if (s->ode.reduce_sum) { /* a split state: the whole state's sum and count */
        double v[2] = {sum, count};
        s->ode.reduce_sum(s->ode.ctx, v, 2);
        sum = v[0];
        count = v[1];
    }
    double norm = sqrt(sum / (count > 0 ? count : 1.0));
    return isfinite(norm) ? norm : INFINITY;
}

static psys_status rk_adaptive_step(psys_solver *s, double h_max, double *h_taken)
{
    const psys__tableau *tab = s->cls->tab;
    double *y0 = s->buf[Y0], *y1 = s->buf[Y1];
    double t = s->ode.get_time(s->ode.ctx);
    double h_prop = s->h_next > 0 ? s->h_next : h_max;
    s->ode.get_state(s->ode.ctx, y0);
    for (;;) {
        bool clamped = h_prop >= h_max;
        double h = clamped ? h_max : h_prop;
        psys_status st = rk_stages(s, tab, t, h, y0, y1);
        if (st != PSYS_OK)
            return st;
        double err = error_norm(s, tab, h, y0, y1);
        /* Standard controller: safety 0.9, growth within [0.2, 5]. */
        double factor = err == 0 ? 5.0 : fmin(5.0, fmax(0.2, 0.9 * pow(err, -1.0 / 5)));
        if (err <= 1.0) {
            double next = h * factor;
            /* A step cut short to land on an output time says nothing
             * against the longer step that was proposed. */
            s->h_next = clamped && h_prop > next ? h_prop : next;
            *h_taken = h;
            return psys__solver_commit(s, y1, t + h);
        }
        s->rejected++;
        h_prop = h * (isfinite(err) ? factor : 0.1);
        if (h_prop <= 1e-14 * fmax(1.0, fabs(t))) {
            const size_t bad = psys__solver_first_nonfinite(s, y1);
            if (bad != SIZE_MAX)
                return psys__solver_nonfinite(s, bad);
            return psys__fail(&s->err, PSYS_ERR_INVALID,
                              "rk45 step size fell to %g at t = %.17g without meeting the tolerance", h_prop, t);
        }
    }
}

const psys__solver_class psys__euler = {.name = "euler", .order = 1, .adaptive = false, .second_order_only = false, .elementwise = true, .nbuf = K0 + 1, .tab = &euler_tab, .step = rk_fixed_step};
const psys__solver_class psys__midpoint = {.name = "midpoint", .order = 2, .adaptive = false, .second_order_only = false, .elementwise = true, .nbuf = K0 + 2, .tab = &midpoint_tab, .step = rk_fixed_step};
const psys__solver_class psys__rk4 = {.name = "rk4", .order = 4, .adaptive = false, .second_order_only = false, .elementwise = true, .nbuf = K0 + 4, .tab = &rk4_tab, .step = rk_fixed_step};
const psys__solver_class psys__rk45 = {.name = "rk45", .order = 5, .adaptive = true, .second_order_only = false, .nbuf = K0 + 7, .tab = &dopri5_tab, .step = rk_adaptive_step};
