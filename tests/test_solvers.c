/* Solvers: the registry, the ODE interface with custom (non-particle) ODEs,
 * measured convergence orders, rk45 error control and landing, symplectic
 * energy behaviour, and non-finite states. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include "../src/sim/sim.h" /* psys__system_ode_fast */

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

static const char *const all_solvers[] = {"euler", "midpoint", "rk4", "symplectic-euler", "verlet", "rk45"};
#define NSOLVERS (sizeof all_solvers / sizeof all_solvers[0])

/* ------------------------------------------------------------------ */
/* A custom ODE that knows nothing of particles.                        */
/* ------------------------------------------------------------------ */

enum { ODE_DECAY, ODE_HARMONIC, ODE_NAN };

typedef struct custom {
    size_t n;
    double y[4];
    double t;
    long evals;
    int kind;
    size_t nan_at; /* ODE_NAN: the component whose derivative is NaN */
} custom;

static void c_get(void *ctx, double *y) { memcpy(y, ((custom *)ctx)->y, ((custom *)ctx)->n * sizeof(double)); }
static void c_set(void *ctx, const double *y) { memcpy(((custom *)ctx)->y, y, ((custom *)ctx)->n * sizeof(double)); }
static double c_time(void *ctx) { return ((custom *)ctx)->t; }
static void c_set_time(void *ctx, double t) { ((custom *)ctx)->t = t; }

static psys_status c_deriv(void *ctx, double t, const double *y, double *yd)
{
    custom *c = ctx;
    (void)t;
    c->evals++;
    switch (c->kind) {
    case ODE_DECAY: /* y' = -y, componentwise */
        for (size_t i = 0; i < c->n; i++)
            yd[i] = -y[i];
        break;
    case ODE_HARMONIC: /* y = [q | p], q' = p, p' = -q */
        for (size_t i = 0; i < c->n / 2; i++) {
            yd[i] = y[c->n / 2 + i];
            yd[c->n / 2 + i] = -y[i];
        }
        break;
    default: /* like decay, but one component's derivative is NaN */
        for (size_t i = 0; i < c->n; i++)
            yd[i] = -y[i];
        yd[c->nan_at] = NAN;
        break;
    }
    return PSYS_OK;
}

static psys_ode custom_ode(custom *c, size_t npos)
{
    psys_ode o;
    memset(&o, 0, sizeof o);
    o.size = c->n;
    o.npos = npos;
    o.ctx = c;
    o.get_state = c_get;
    o.set_state = c_set;
    o.get_time = c_time;
    o.set_time = c_set_time;
    o.derivative = c_deriv;
    return o;
}

/* 13. Registry: six solvers in a fixed order, with their properties. */
static void registry(void)
{
    static const int orders[NSOLVERS] = {1, 2, 4, 1, 2, 5};
    /* The six explicit solvers, then implicit-euler (which needs masses and
     * Jacobians, so it is tested with particle systems in test_implicit). */
    CHECK(psys_solver_count() == 7);
    for (size_t i = 0; i < NSOLVERS; i++) {
        CHECK_STR(psys_solver_name_at(i), all_solvers[i]);
        CHECK(psys_solver_exists(all_solvers[i]));
    }
    CHECK_STR(psys_solver_name_at(6), "implicit-euler");
    CHECK(psys_solver_name_at(7) == NULL);
    CHECK(!psys_solver_exists("rk5"));
    CHECK(!psys_solver_exists(""));
    CHECK(!psys_solver_exists(NULL));

    custom c = {.n = 2, .y = {1, 0}, .kind = ODE_HARMONIC};
    psys_ode ode = custom_ode(&c, 1);
    for (size_t i = 0; i < NSOLVERS; i++) {
        psys_solver *s = make_ode_solver(all_solvers[i], &ode);
        CHECK_STR(psys_solver_name(s), all_solvers[i]);
        CHECK(psys_solver_order(s) == orders[i]);
        CHECK(psys_solver_is_adaptive(s) == (strcmp(all_solvers[i], "rk45") == 0));
        if (!psys_solver_is_adaptive(s))
            CHECK(psys_solver_next_step(s) == 0.0);
        psys_solver_destroy(s);
    }

    psys_error err;
    memset(&err, 0, sizeof err);
    CHECK(psys_solver_create("implicit-euler", &ode, &err) == NULL); /* no masses or Jacobians offered */
    CHECK(err.code == PSYS_ERR_INVALID);
    memset(&err, 0, sizeof err);
    CHECK(psys_solver_create("runge-kutta", &ode, &err) == NULL);
    CHECK(err.code == PSYS_ERR_INVALID);
    CHECK(strstr(err.message, "runge-kutta") != NULL);
    memset(&err, 0, sizeof err);
    CHECK(psys_solver_create("RK4", &ode, &err) == NULL); /* names are exact */
    CHECK(err.code == PSYS_ERR_INVALID);
    memset(&err, 0, sizeof err);
    CHECK(psys_solver_create(NULL, &ode, &err) == NULL);
    CHECK(err.code == PSYS_ERR_INVALID);
    psys_solver_destroy(NULL);
}

/* 13. Symplectic solvers need y = [q | p] with q' = p (npos = size/2). */
static void symplectic_needs_second_order(void)
{
    custom c = {.n = 2, .y = {1, 0}, .kind = ODE_DECAY};
    psys_ode first = custom_ode(&c, 0);
    psys_ode odd = custom_ode(&c, 2); /* npos must be exactly size/2 */
    const char *symp[2] = {"symplectic-euler", "verlet"};
    for (int i = 0; i < 2; i++) {
        psys_error err;
        memset(&err, 0, sizeof err);
        CHECK(psys_solver_create(symp[i], &first, &err) == NULL);
        CHECK(err.code == PSYS_ERR_INVALID);
        CHECK(err.message[0] != '\0');
        memset(&err, 0, sizeof err);
        CHECK(psys_solver_create(symp[i], &odd, &err) == NULL);
        CHECK(err.code == PSYS_ERR_INVALID);
    }
    /* The Runge–Kutta family accepts any first-order ODE. */
    const char *rk[4] = {"euler", "midpoint", "rk4", "rk45"};
    for (int i = 0; i < 4; i++) {
        psys_error err;
        psys_solver *s = psys_solver_create(rk[i], &first, &err);
        CHECK(s != NULL);
        psys_solver_destroy(s);
    }
}

/* Custom ODE y' = -y: each fixed-step RK method multiplies y by its
 * stability polynomial R(-h) per step, exactly: euler 1-h, midpoint
 * 1-h+h²/2, rk4 1-h+h²/2-h³/6+h⁴/24; one derivative evaluation per stage. */
static void custom_ode_decay(void)
{
    const double h = 0.1;
    const long n = 50;
    const char *names[3] = {"euler", "midpoint", "rk4"};
    const double R[3] = {1 - h, 1 - h + h * h / 2, 1 - h + h * h / 2 - h * h * h / 6 + h * h * h * h / 24};
    const long stages[3] = {1, 2, 4};
    for (int i = 0; i < 3; i++) {
        custom c = {.n = 3, .y = {1.0, -2.0, 0.5}, .t = 1.0, .kind = ODE_DECAY};
        psys_ode ode = custom_ode(&c, 0);
        psys_solver *s = make_ode_solver(names[i], &ode);
        for (long k = 0; k < n; k++) {
            double ht = -1;
            CHECK(psys_solver_step(s, h, &ht) == PSYS_OK);
            CHECK(ht == h);
        }
        CHECK(c.evals == stages[i] * n);
        CHECK_NEAR(c.t, 1.0 + n * h, 1e-12);
        double f = pow(R[i], (double)n);
        CHECK_NEAR(c.y[0], 1.0 * f, 1e-13);
        CHECK_NEAR(c.y[1], -2.0 * f, 2e-13);
        CHECK_NEAR(c.y[2], 0.5 * f, 1e-13);
        psys_solver_destroy(s);
    }
    /* rk45 lands on T and meets its tolerance against e^{-T}. */
    custom c = {.n = 3, .y = {1.0, -2.0, 0.5}, .kind = ODE_DECAY};
    psys_ode ode = custom_ode(&c, 0);
    psys_solver *s = make_ode_solver("rk45", &ode);
    CHECK(psys_solver_set_tolerance(s, 1e-9) == PSYS_OK);
    const double T = 5.0;
    while (c.t < T)
        CHECK(psys_solver_step(s, T - c.t, NULL) == PSYS_OK);
    CHECK(c.t == T);
    CHECK_NEAR(c.y[0], exp(-T), 1e-8);
    CHECK_NEAR(c.y[1], -2 * exp(-T), 1e-8);
    psys_solver_destroy(s);
}

/* Symplectic solvers on a custom second-order ODE q' = p, p' = -q (ω = 1).
 * One step of symplectic Euler is the map p1 = p - h q, q1 = q + h p1; of
 * velocity Verlet q1 = (1 - h²/2) q + h p, p1 = p - h (q + q1)/2.
 * Each conserves its own quadratic invariant exactly:
 * SE: q² + p² - h q p;  Verlet: p² + (1 - h²/4) q². */
static void custom_ode_symplectic(void)
{
    const double h = 0.05, q0 = 0.6, p0 = -0.3;
    for (int which = 0; which < 2; which++) {
        custom c = {.n = 2, .y = {q0, p0}, .kind = ODE_HARMONIC};
        psys_ode ode = custom_ode(&c, 1);
        psys_solver *s = make_ode_solver(which ? "verlet" : "symplectic-euler", &ode);
        CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
        double q1, p1;
        if (which == 0) {
            p1 = p0 - h * q0;
            q1 = q0 + h * p1;
        } else {
            q1 = (1 - h * h / 2) * q0 + h * p0;
            p1 = p0 - h * (q0 + q1) / 2;
        }
        CHECK_NEAR(c.y[0], q1, 1e-15);
        CHECK_NEAR(c.y[1], p1, 1e-15);
        CHECK(c.evals == (which ? 2 : 1));
        double I0 = which ? p0 * p0 + (1 - h * h / 4) * q0 * q0 : q0 * q0 + p0 * p0 - h * q0 * p0;
        for (int k = 1; k < 20000; k++)
            CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
        double q = c.y[0], p = c.y[1];
        double I = which ? p * p + (1 - h * h / 4) * q * q : q * q + p * p - h * q * p;
        CHECK_NEAR(I, I0, 1e-12);
        CHECK_NEAR(c.t, 20000 * h, 1e-9);
        psys_solver_destroy(s);
    }
}

/* ------------------------------------------------------------------ */
/* The undamped spring oscillator as a particle system.                 */
/* ------------------------------------------------------------------ */

/* Anchor (fixed) at the origin, a particle of mass m on an eq. 1 spring of
 * rest length r along the x axis: u = x - r obeys m u'' = -ks u - c u' with
 * c = kd (spring) + kdrag as long as x > 0 (|l| = x). Undamped:
 * u = u0 cos ωt + (w0/ω) sin ωt; underdamped (ζ = c / 2√(ks m) < 1):
 * u = e^{-ζωt}(u0 cos ωd t + (w0 + ζω u0)/ωd sin ωd t), ωd = ω√(1-ζ²). */
typedef struct osc {
    double m, ks, r, u0, w0;
    double kd, kdrag; /* spring damping and drag (0 for the undamped one) */
} osc;

static const osc OSC = {2.0, 8.0, 2.0, 0.5, 0.6, 0.0, 0.0};        /* ω = 2 */
static const osc OSC_DAMPED = {2.0, 8.0, 2.0, 0.5, 0.6, 1.0, 0.3}; /* ζ = 0.1625 */

static double osc_omega(const osc *o) { return sqrt(o->ks / o->m); }

static psys_system *osc_system(const osc *o)
{
    psys_error err;
    psys_system *sys = psys_system_create(2, &err);
    CHECK(sys != NULL);
    if (!sys)
        exit(1);
    const double a[2] = {0, 0}, x[2] = {o->r + o->u0, 0}, v[2] = {o->w0, 0};
    CHECK(psys_system_add_particle(sys, a, NULL, 3.0, "anchor", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x, v, o->m, "bob", NULL) == PSYS_OK);
    CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 0, 1, o->ks, o->kd, o->r) == PSYS_OK);
    if (o->kdrag > 0)
        CHECK(psys_system_add_drag(sys, o->kdrag) == PSYS_OK);
    return sys;
}

/* Phase-space error sqrt(Δu² + (Δu̇/ω)²) at the system's current time. */
static double osc_error(const osc *o, const psys_system *sys)
{
    double w = osc_omega(o), t = psys_system_time(sys);
    double zeta = (o->kd + o->kdrag) / (2 * sqrt(o->ks * o->m)), wd = w * sqrt(1 - zeta * zeta);
    double e = exp(-zeta * w * t);
    double u = e * (o->u0 * cos(wd * t) + (o->w0 + zeta * w * o->u0) / wd * sin(wd * t));
    double ud = e * (o->w0 * cos(wd * t) - (w * o->u0 + zeta * o->w0) / sqrt(1 - zeta * zeta) * sin(wd * t));
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    double du = x[2] - (o->r + u), dv = (v[2] - ud) / w;
    CHECK(x[3] == 0.0 && v[3] == 0.0); /* the motion stays on the axis */
    return sqrt(du * du + dv * dv);
}

static double osc_energy(const psys_system *sys)
{
    return psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
}

/* 4. Measured convergence orders at T = 2 (ωT = 4). */
static double osc_fixed_error_of(const osc *o, const char *name, double T, long n)
{
    psys_system *sys = osc_system(o);
    psys_ode ode = psys_system_ode(sys);
    psys_solver *s = make_ode_solver(name, &ode);
    double h = T / (double)n;
    for (long k = 0; k < n; k++)
        CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
    CHECK_NEAR(psys_system_time(sys), T, 1e-12);
    psys_system_set_time(sys, T); /* evaluate the closed form at exactly T */
    double e = osc_error(o, sys);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return e;
}

static double osc_fixed_error(const char *name, double T, long n) { return osc_fixed_error_of(&OSC, name, T, n); }

typedef struct order_case {
    const char *name;
    long n0; /* coarsest step count: asymptotic yet well above rounding */
} order_case;

static const order_case order_cases[] = {
    {"euler", 400}, {"midpoint", 100}, {"rk4", 20}, {"symplectic-euler", 400}, {"verlet", 100},
};

/* Error at T with n0, 2 n0, 4 n0, 8 n0 steps; each successive log2 ratio
 * and the least-squares slope must be the solver's declared order ± 0.15. */
static void measure_orders(const osc *o, const char *label)
{
    const double T = 2.0;
    for (size_t i = 0; i < sizeof order_cases / sizeof order_cases[0]; i++) {
        const char *name = order_cases[i].name;
        custom dummy = {.n = 2, .kind = ODE_HARMONIC};
        psys_ode dode = custom_ode(&dummy, 1);
        psys_solver *s = make_ode_solver(name, &dode);
        int order = psys_solver_order(s);
        psys_solver_destroy(s);
        double e[4], sx = 0, sy = 0, sxx = 0, sxy = 0;
        for (int j = 0; j < 4; j++) {
            e[j] = osc_fixed_error_of(o, name, T, order_cases[i].n0 << j);
            double xj = -j, yj = log2(e[j]); /* log2 h relative to h0 */
            sx += xj;
            sy += yj;
            sxx += xj * xj;
            sxy += xj * yj;
        }
        double slope = (4 * sxy - sx * sy) / (4 * sxx - sx * sx);
        fprintf(stderr, "  %s %-16s errors %.3e %.3e %.3e %.3e  ratios", label, name, e[0], e[1], e[2], e[3]);
        for (int j = 0; j < 3; j++)
            fprintf(stderr, " %.3f", log2(e[j] / e[j + 1]));
        fprintf(stderr, "  fitted order %.3f (declared %d)\n", slope, order);
        CHECK(fabs(slope - order) < 0.15);
        for (int j = 0; j < 3; j++)
            CHECK(fabs(log2(e[j] / e[j + 1]) - order) < 0.15);
        CHECK(e[3] > 1e-12); /* far above rounding, so the orders are real */
    }
}

/* Undamped oscillator: euler 1, midpoint 2, rk4 4, symplectic-euler 1,
 * verlet 2. */
static void convergence_orders(void)
{
    static const int expected[] = {1, 2, 4, 1, 2};
    custom dummy = {.n = 2, .kind = ODE_HARMONIC};
    psys_ode dode = custom_ode(&dummy, 1);
    for (size_t i = 0; i < sizeof order_cases / sizeof order_cases[0]; i++) {
        psys_solver *s = make_ode_solver(order_cases[i].name, &dode);
        CHECK(psys_solver_order(s) == expected[i]);
        psys_solver_destroy(s);
    }
    measure_orders(&OSC, "undamped");
}

/* The same with velocity-dependent forces (damped spring + drag): every
 * solver must keep its declared order, since psys scenes are usually
 * damped. */
static void convergence_orders_damped(void) { measure_orders(&OSC_DAMPED, "damped"); }

/* ------------------------------------------------------------------ */
/* 5. rk45 (Dormand–Prince) error control.                              */
/* ------------------------------------------------------------------ */

/* Counts derivative evaluations of a wrapped ODE. */
typedef struct counted {
    psys_ode inner;
    long evals;
} counted;

static void w_get(void *ctx, double *y) { counted *c = ctx; c->inner.get_state(c->inner.ctx, y); }
static void w_set(void *ctx, const double *y) { counted *c = ctx; c->inner.set_state(c->inner.ctx, y); }
static double w_time(void *ctx) { counted *c = ctx; return c->inner.get_time(c->inner.ctx); }
static void w_set_time(void *ctx, double t) { counted *c = ctx; c->inner.set_time(c->inner.ctx, t); }
static psys_status w_deriv(void *ctx, double t, const double *y, double *yd)
{
    counted *c = ctx;
    c->evals++;
    return c->inner.derivative(c->inner.ctx, t, y, yd);
}
static void w_project(void *ctx, double t, double *y)
{
    counted *c = ctx;
    c->inner.project(c->inner.ctx, t, y);
}

static psys_ode counted_ode(counted *c, psys_system *sys)
{
    c->inner = psys_system_ode(sys);
    c->evals = 0;
    psys_ode o = c->inner;
    o.ctx = c;
    o.get_state = w_get;
    o.set_state = w_set;
    o.get_time = w_time;
    o.set_time = w_set_time;
    o.derivative = w_deriv;
    o.project = c->inner.project ? w_project : NULL;
    return o; /* a user's ODE has no fast paths that could bypass w_deriv's count */
}

typedef struct rk45_result {
    double err;
    long steps, evals;
    size_t rejected;
} rk45_result;

static rk45_result rk45_run(double tol, double T)
{
    psys_system *sys = osc_system(&OSC);
    counted cnt;
    psys_ode ode = counted_ode(&cnt, sys);
    psys_solver *s = make_ode_solver("rk45", &ode);
    CHECK(psys_solver_set_tolerance(s, tol) == PSYS_OK);
    rk45_result r = {0, 0, 0, 0};
    while (psys_system_time(sys) < T && r.steps < 100000) {
        double t = psys_system_time(sys), ht = 0;
        CHECK(psys_solver_step(s, T - t, &ht) == PSYS_OK);
        CHECK(ht > 0 && ht <= T - t);
        CHECK(psys_system_time(sys) == t + ht);
        r.steps++;
    }
    CHECK(psys_system_time(sys) == T); /* landed exactly */
    r.err = osc_error(&OSC, sys);
    r.evals = cnt.evals;
    r.rejected = psys_solver_rejected_steps(s);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return r;
}

static void rk45_tolerance(void)
{
    const double T = 10.0, tols[3] = {1e-6, 1e-8, 1e-10};
    const double amp = sqrt(OSC.u0 * OSC.u0 + OSC.w0 * OSC.w0 / 4); /* |u|max */
    rk45_result r[3];
    for (int i = 0; i < 3; i++) {
        r[i] = rk45_run(tols[i], T);
        fprintf(stderr, "  tol %.0e: error %.3e (%.2f tol), %ld steps, %zu rejected, %ld evals\n", tols[i],
                r[i].err, r[i].err / tols[i], r[i].steps, r[i].rejected, r[i].evals);
        /* The tolerance bounds each step's error estimate, scaled by
         * tol·(1 + |y|) (|y| ≤ r + |u| ≈ 2.6) in an RMS over all 8 state
         * components, of which only 2 move: one step may err by about
         * √8 · 3.6 ≈ 10 tol. After 60–400 steps the global error must still
         * be within 10 × (1 + |y|) tol, i.e. of the order of one step's
         * allowance, not growing with the number of steps. */
        CHECK(r[i].err < 10 * tols[i] * (1 + OSC.r + amp));
        CHECK(r[i].err > 0);
    }
    for (int i = 0; i < 2; i++) {
        /* Error shrinks roughly in proportion to tol: 100× tighter gives
         * between 20× and 500× smaller error. */
        double ratio = r[i].err / r[i + 1].err;
        CHECK(ratio > 20 && ratio < 500);
        /* Steps grow like tol^(-1/5): 100^(1/5) ≈ 2.5. */
        double sr = (double)r[i + 1].steps / (double)r[i].steps;
        CHECK(sr > 1.8 && sr < 3.5);
    }
}

/* At the accuracy rk45 reaches with tol = 1e-10, rk4 needs many more steps
 * and more derivative evaluations. */
static void rk45_efficiency(void)
{
    const double T = 10.0;
    rk45_result r = rk45_run(1e-10, T);
    long n = 16;
    double e = 0;
    for (; n < (1L << 16); n *= 2) {
        e = osc_fixed_error("rk4", T, n);
        if (e <= r.err)
            break;
    }
    fprintf(stderr, "  rk45: %ld steps, %ld evals, error %.3e; rk4: %ld steps (%ld evals), error %.3e\n", r.steps,
            r.evals, r.err, n, 4 * n, e);
    CHECK(e <= r.err);
    CHECK(r.steps * 4 < n);  /* far fewer steps */
    CHECK(r.evals < 4 * n);  /* and less work, even at 7 stages a step */
}

/* Landing: psys_solver_step never takes more than h_max, even when its own
 * proposal is longer, and the clock advances by exactly the step taken. */
static void rk45_landing(void)
{
    psys_system *sys = osc_system(&OSC);
    psys_ode ode = psys_system_ode(sys);
    psys_solver *s = make_ode_solver("rk45", &ode);
    CHECK(psys_solver_set_tolerance(s, 1e-6) == PSYS_OK);
    CHECK(psys_solver_set_next_step(s, 1.0) == PSYS_OK);
    CHECK(psys_solver_next_step(s) == 1.0);
    const double hmax[] = {1e-3, 0.25, 1e-5, 0.05, 2.0, 0.3, 1e-4, 0.125, 0.5, 0.01};
    for (int rep = 0; rep < 30; rep++)
        for (size_t i = 0; i < sizeof hmax / sizeof hmax[0]; i++) {
            double t0 = psys_system_time(sys), ht = -1;
            CHECK(psys_solver_step(s, hmax[i], &ht) == PSYS_OK);
            CHECK(ht > 0 && ht <= hmax[i]);
            CHECK(psys_system_time(sys) == t0 + ht);
            CHECK(psys_solver_next_step(s) > 0);
        }
    /* A tiny h_max on a smooth problem is taken in full. */
    double ht = 0;
    CHECK(psys_solver_step(s, 1e-6, &ht) == PSYS_OK);
    CHECK(ht == 1e-6);
    /* The trajectory is still accurate after all those forced landings. */
    CHECK(osc_error(&OSC, sys) < 1e-4);
    psys_solver_destroy(s);

    /* From a far too long first step: rejections, then within tolerance. */
    psys_system_destroy(sys);
    sys = osc_system(&OSC);
    ode = psys_system_ode(sys);
    s = make_ode_solver("rk45", &ode);
    CHECK(psys_solver_set_tolerance(s, 1e-8) == PSYS_OK);
    CHECK(psys_solver_step(s, 50.0, &ht) == PSYS_OK);
    CHECK(psys_solver_rejected_steps(s) > 0);
    CHECK(ht < 1.0);
    CHECK(osc_error(&OSC, sys) < 1e-7);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

static void rk45_bad_arguments(void)
{
    custom c = {.n = 1, .y = {1}, .kind = ODE_DECAY};
    psys_ode ode = custom_ode(&c, 0);
    psys_solver *s = make_ode_solver("rk45", &ode);
    CHECK(psys_solver_set_tolerance(s, 0.0) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_tolerance(s, -1e-6) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_tolerance(s, NAN) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_tolerance(s, INFINITY) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_next_step(s, 0.0) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_next_step(s, NAN) == PSYS_ERR_INVALID);
    psys_solver_destroy(s);
    /* Every solver refuses a step that is not a finite number > 0, and
     * changes nothing. */
    const double bad[4] = {0.0, -0.1, NAN, INFINITY};
    for (size_t i = 0; i < NSOLVERS; i++) {
        custom h = {.n = 2, .y = {0.25, 0.5}, .t = 3.0, .kind = ODE_HARMONIC};
        psys_ode o2 = custom_ode(&h, 1);
        s = make_ode_solver(all_solvers[i], &o2);
        for (int k = 0; k < 4; k++) {
            CHECK(psys_solver_step(s, bad[k], NULL) == PSYS_ERR_INVALID);
            CHECK(psys_solver_last_error(s)[0] != '\0');
        }
        CHECK(h.y[0] == 0.25 && h.y[1] == 0.5 && h.t == 3.0);
        psys_solver_destroy(s);
    }
}

/* No step taken, so *h_taken is 0 on every failure: the stepper failures
 * (PSYS_ERR_NONFINITE, see below) already do this; a refused h_max must too,
 * or a caller doing t += h_taken reads whatever was in its variable. */
static void failed_step_zeroes_h_taken(void)
{
    const double bad[4] = {0.0, -0.1, NAN, INFINITY};
    for (size_t i = 0; i < NSOLVERS; i++) {
        custom h = {.n = 2, .y = {0.25, 0.5}, .t = 3.0, .kind = ODE_HARMONIC};
        psys_ode ode = custom_ode(&h, 1);
        psys_solver *s = make_ode_solver(all_solvers[i], &ode);
        for (int k = 0; k < 4; k++) {
            double ht = 7;
            CHECK(psys_solver_step(s, bad[k], &ht) == PSYS_ERR_INVALID);
            if (ht != 0.0)
                fprintf(stderr, "  solver %s, h_max %g: *h_taken = %g after failure\n", all_solvers[i], bad[k], ht);
            CHECK(ht == 0.0);
        }
        psys_solver_destroy(s);
    }
}

/* ------------------------------------------------------------------ */
/* 7. Energy of symplectic solvers over 1e5 steps; Euler's growth.      */
/* ------------------------------------------------------------------ */

/* For u'' = -ω² u (u = x - r, w = u̇), with e = 2E/m = w² + ω² u²:
 *   symplectic Euler conserves I = w² + ω²u² - hω² u w exactly, and
 *     |u w| ≤ e/(2ω), so e ∈ [I/(1 + hω/2), I/(1 - hω/2)]: the relative
 *     energy error stays below hω/(1 - hω/2);
 *   velocity Verlet conserves I = w² + ω²(1 - h²ω²/4) u², so the relative
 *     energy error stays below b/(1 - b), b = (hω)²/4. */
static void symplectic_energy_bounded(void)
{
    const double h = 0.01;
    const long n = 100000;
    const double w = osc_omega(&OSC), w2 = w * w;
    for (int which = 0; which < 2; which++) {
        psys_system *sys = osc_system(&OSC);
        psys_ode ode = psys_system_ode(sys);
        psys_solver *s = make_ode_solver(which ? "verlet" : "symplectic-euler", &ode);
        const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
        double E0 = osc_energy(sys);
        CHECK_NEAR(E0, 0.5 * OSC.m * OSC.w0 * OSC.w0 + 0.5 * OSC.ks * OSC.u0 * OSC.u0, 1e-14);
        double u = x[2] - OSC.r, ud = v[2];
        double I0 = which ? ud * ud + w2 * (1 - h * h * w2 / 4) * u * u : ud * ud + w2 * u * u - h * w2 * u * ud;
        double bound = which ? (h * h * w2 / 4) / (1 - h * h * w2 / 4) : h * w / (1 - h * w / 2);
        double max_first = 0, max_last = 0, max_all = 0, inv_err = 0;
        for (long k = 1; k <= n; k++) {
            CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
            double rel = fabs(osc_energy(sys) - E0) / E0;
            max_all = fmax(max_all, rel);
            if (k <= n / 10)
                max_first = fmax(max_first, rel);
            if (k > n - n / 10)
                max_last = fmax(max_last, rel);
            if (k % 1000 == 0) {
                u = x[2] - OSC.r;
                ud = v[2];
                double I = which ? ud * ud + w2 * (1 - h * h * w2 / 4) * u * u : ud * ud + w2 * u * u - h * w2 * u * ud;
                inv_err = fmax(inv_err, fabs(I - I0) / I0);
            }
        }
        fprintf(stderr, "  %s: max relative energy error %.3e (bound %.3e), first 10%% %.3e, last 10%% %.3e, "
                "invariant drift %.2e\n", which ? "verlet" : "symplectic-euler", max_all, bound, max_first,
                max_last, inv_err);
        CHECK(max_all <= bound);
        /* No drift: the invariant holds to rounding over 1e5 steps, and the
         * energy oscillation is the same size at the end as at the start. */
        CHECK(inv_err < 1e-11);
        CHECK(max_last < 1.05 * max_first && max_last > 0.95 * max_first);
        /* The bound is sharp (within a factor of a few), so the check is real. */
        CHECK(max_all > 0.25 * bound);
        CHECK_NEAR(psys_system_time(sys), n * h, 1e-8);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* Explicit Euler on the oscillator: e_{k+1} = (1 + h²ω²) e_k exactly, so
 * the energy grows geometrically and never comes back. */
static void euler_energy_grows(void)
{
    const double h = 0.01;
    const long n = 1000;
    const double w2 = OSC.ks / OSC.m, growth = 1 + h * h * w2;
    psys_system *sys = osc_system(&OSC);
    psys_ode ode = psys_system_ode(sys);
    psys_solver *s = make_ode_solver("euler", &ode);
    double E0 = osc_energy(sys), prev = E0;
    for (long k = 1; k <= n; k++) {
        CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
        double E = osc_energy(sys);
        CHECK(E > prev);
        prev = E;
        if (k % 100 == 0)
            CHECK_NEAR(E / E0, pow(growth, (double)k), 1e-11 * pow(growth, (double)k));
    }
    CHECK(prev > 1.4 * E0); /* (1.0004)^1000 ≈ 1.49 */
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 14. Non-finite states.                                               */
/* ------------------------------------------------------------------ */

/* A NaN derivative: every solver returns PSYS_ERR_NONFINITE, names the
 * first bad component, and leaves state and clock unchanged. */
static void nonfinite_custom_ode(void)
{
    for (size_t i = 0; i < NSOLVERS; i++) {
        const char *name = all_solvers[i];
        bool symp = strcmp(name, "symplectic-euler") == 0 || strcmp(name, "verlet") == 0;
        /* y = [q0 q1 | p0 p1] for the symplectic ones: NaN acceleration of
         * q1 (component 3) makes q1 = component 1 the first bad one. For
         * the RK family, component 1's own derivative is NaN. */
        custom c = {.n = 4, .y = {0.5, -0.25, 1.0, 2.0}, .t = 2.0, .kind = ODE_NAN, .nan_at = symp ? 3 : 1};
        psys_ode ode = custom_ode(&c, symp ? 2 : 0);
        psys_solver *s = make_ode_solver(name, &ode);
        double ht = 9;
        psys_status st = psys_solver_step(s, 0.1, &ht);
        if (st != PSYS_ERR_NONFINITE)
            fprintf(stderr, "  solver %s returned %s\n", name, psys_status_name(st));
        CHECK(st == PSYS_ERR_NONFINITE);
        CHECK(psys_solver_bad_component(s) == 1);
        CHECK(ht == 0.0);
        CHECK(c.y[0] == 0.5 && c.y[1] == -0.25 && c.y[2] == 1.0 && c.y[3] == 2.0);
        CHECK(c.t == 2.0);
        CHECK(strstr(psys_solver_last_error(s), "1") != NULL);
        CHECK_STR(psys_status_name(PSYS_ERR_NONFINITE), psys_status_name(st));
        psys_solver_destroy(s);
    }
}

/* A force object that writes NaN into one particle's force. */
typedef struct nan_force {
    size_t particle;
    int axis;
} nan_force;

static void nan_force_apply(void *data, const psys_force_eval *e, double *f)
{
    const nan_force *nf = data;
    f[nf->particle * (size_t)e->dim + (size_t)nf->axis] = NAN;
}

static const psys_force_class nan_force_class = {.name = "nan", .apply = nan_force_apply, .destroy = free};

static void nonfinite_particle_force(void)
{
    for (size_t i = 0; i < NSOLVERS; i++) {
        const char *name = all_solvers[i];
        psys_error err;
        psys_system *sys = psys_system_create(2, &err);
        const double xs[3][2] = {{0, 0}, {1, 0.5}, {2, -1}}, vs[3][2] = {{1, 0}, {0, 1}, {-1, 0.5}};
        for (int p = 0; p < 3; p++)
            CHECK(psys_system_add_particle(sys, xs[p], vs[p], 1.0 + p, NULL, NULL) == PSYS_OK);
        const double g[2] = {0, -9.81};
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        CHECK(psys_system_add_spring(sys, 0, 2, 10, 0.1, -1) == PSYS_OK);
        nan_force *nf = malloc(sizeof *nf);
        CHECK(nf != NULL);
        nf->particle = 1;
        nf->axis = 1;
        CHECK(psys_system_add_force(sys, &nan_force_class, nf) == PSYS_OK);
        psys_system_set_time(sys, 0.75);
        double x0[6], v0[6];
        memcpy(x0, psys_system_positions(sys), sizeof x0);
        memcpy(v0, psys_system_velocities(sys), sizeof v0);
        psys_ode ode = psys_system_ode(sys);
        psys_solver *s = make_ode_solver(name, &ode);
        psys_status st = psys_solver_step(s, 0.01, NULL);
        CHECK(st == PSYS_ERR_NONFINITE);
        /* Euler: x1 = x0 + h v0 stays finite, v1 is the first bad one
         * (component nd + 1·2 + 1 = 9). Every other solver feeds the NaN
         * acceleration into the position first (component 3). */
        size_t want = strcmp(name, "euler") == 0 ? 9 : 3;
        if (psys_solver_bad_component(s) != want)
            fprintf(stderr, "  solver %s: bad component %zu, expected %zu\n", name, psys_solver_bad_component(s),
                    want);
        CHECK(psys_solver_bad_component(s) == want);
        /* every solver's report, rk45's give-up included (psys__solver_nonfinite) */
        char msg[64];
        snprintf(msg, sizeof msg, "state component %zu became non-finite", want);
        if (strcmp(psys_solver_last_error(s), msg) != 0)
            fprintf(stderr, "  solver %s: \"%s\"\n", name, psys_solver_last_error(s));
        CHECK(strcmp(psys_solver_last_error(s), msg) == 0);
        CHECK(psys_system_particle_of_component(sys, psys_solver_bad_component(s)) == 1);
        CHECK(memcmp(x0, psys_system_positions(sys), sizeof x0) == 0);
        CHECK(memcmp(v0, psys_system_velocities(sys), sizeof v0) == 0);
        CHECK(psys_system_time(sys) == 0.75);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A force object that writes NaN into one force component from its second
 * evaluation on: a solver's first evaluation is finite. */
typedef struct late_nan_force {
    size_t component, calls;
} late_nan_force;

static void late_nan_force_apply(void *data, const psys_force_eval *e, double *f)
{
    late_nan_force *nf = data;
    (void)e;
    if (nf->calls++ > 0)
        f[nf->component] = NAN;
}

static const psys_force_class late_nan_force_class = {.name = "late-nan", .apply = late_nan_force_apply, .destroy = free};

/* A NaN that first appears at the last evaluation of a step (velocity
 * Verlet's second one reaches only the velocities; symplectic Euler has
 * one evaluation, so its NaN comes at the next step): the step fails,
 * names the first bad component, and leaves the state as it was, on one
 * thread and on two (the system is long enough for the parallel loops). */
static void nonfinite_last_evaluation(void)
{
    const char *names[] = {"verlet", "symplectic-euler"};
    for (int threads = 1; threads <= 2; threads++)
        for (int k = 0; k < 2; k++) {
            psys_error err;
            psys_system *sys = psys_system_create(3, &err);
            const size_t np = 30000;
            for (size_t p = 0; p < np; p++) {
                const double x[3] = {(double)p, 0.5, -1}, v[3] = {0, 1, 0};
                CHECK(psys_system_add_particle(sys, x, v, 1.0, NULL, NULL) == PSYS_OK);
            }
            const double g[3] = {0, -9.81, 0};
            CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
            late_nan_force *nf = malloc(sizeof *nf);
            CHECK(nf != NULL);
            nf->component = 3 * 20000 + 2;
            nf->calls = 0;
            CHECK(psys_system_add_force(sys, &late_nan_force_class, nf) == PSYS_OK);
            psys_system_set_threads(sys, threads);
            psys_ode ode = psys_system_ode(sys);
            psys_solver *s = make_ode_solver(names[k], &ode);
            psys_solver_set_threads(s, threads);
            psys_status st = PSYS_OK;
            int steps = 0;
            while (st == PSYS_OK && steps < 3) {
                st = psys_solver_step(s, 0.01, NULL);
                steps++;
            }
            CHECK(st == PSYS_ERR_NONFINITE);
            CHECK(steps == (k == 0 ? 1 : 2));
            /* verlet: particle 20000's z velocity; symplectic Euler: its
             * position, x1 = x0 + h v1 taking the bad v1 along */
            const size_t want = (k == 0 ? 3 * np : 0) + 3 * 20000 + 2;
            if (psys_solver_bad_component(s) != want)
                fprintf(stderr, "  solver %s: bad component %zu, expected %zu\n", names[k],
                        psys_solver_bad_component(s), want);
            CHECK(psys_solver_bad_component(s) == want);
            const double *v = psys_system_velocities(sys);
            CHECK(isfinite(v[3 * 20000 + 2]));
            psys_solver_destroy(s);
            psys_system_destroy(sys);
        }
}

/* A long nonlinear ODE (y_i' = -sin(y_{i+1}) + 0.1 i/n, cyclic), past the
 * length from which the solvers' vector passes run in parallel. */
typedef struct longode {
    size_t n;
    double t, *y;
} longode;
static void lo_get(void *ctx, double *y) { memcpy(y, ((longode *)ctx)->y, ((longode *)ctx)->n * sizeof(double)); }
static void lo_set(void *ctx, const double *y) { memcpy(((longode *)ctx)->y, y, ((longode *)ctx)->n * sizeof(double)); }
static double lo_time(void *ctx) { return ((longode *)ctx)->t; }
static void lo_set_time(void *ctx, double t) { ((longode *)ctx)->t = t; }
static psys_status lo_deriv(void *ctx, double t, const double *y, double *yd)
{
    (void)t;
    const longode *o = ctx;
    for (size_t i = 0; i < o->n; i++)
        yd[i] = -sin(y[(i + 1) % o->n]) + 0.1 * (double)i / (double)o->n;
    return PSYS_OK;
}

/* psys_solver_set_threads: 1 and 3 threads give the same bits for every
 * solver that takes a general ODE; a negative count is refused. */
static void solver_threads_same_bits(void)
{
    const char *names[] = {"euler", "midpoint", "rk4", "rk45"};
    const size_t n = 100000;
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++) {
        double *out[2] = {NULL, NULL};
        for (int r = 0; r < 2; r++) {
            longode o = {n, 0, calloc(n, sizeof(double))};
            CHECK(o.y != NULL);
            if (!o.y)
                return;
            for (size_t i = 0; i < n; i++)
                o.y[i] = sin(0.001 * (double)i);
            psys_ode ode = {.size = n, .ctx = &o, .get_state = lo_get, .set_state = lo_set, .get_time = lo_time,
                            .set_time = lo_set_time, .derivative = lo_deriv};
            psys_solver *s = make_ode_solver(names[k], &ode);
            CHECK(psys_solver_set_threads(s, -1) == PSYS_ERR_INVALID);
            CHECK(psys_solver_set_threads(s, r == 0 ? 1 : 3) == PSYS_OK);
            for (int step = 0; step < 5; step++)
                CHECK(psys_solver_step(s, 0.05, NULL) == PSYS_OK);
            psys_solver_destroy(s);
            out[r] = o.y;
        }
        if (memcmp(out[0], out[1], n * sizeof(double)) != 0)
            fprintf(stderr, "%s: 3 threads differ from 1\n", names[k]);
        CHECK(memcmp(out[0], out[1], n * sizeof(double)) == 0);
        CHECK(out[0][12345] != sin(0.001 * 12345)); /* it moved */
        free(out[0]);
        free(out[1]);
    }
}

/* lo_deriv, but NaN at components 70,000 and 90,000. */
static psys_status lo_deriv_nan(void *ctx, double t, const double *y, double *yd)
{
    psys_status st = lo_deriv(ctx, t, y, yd);
    yd[90000] = NAN;
    yd[70000] = NAN;
    return st;
}

/* The failed step names the first non-finite component on any thread count
 * (the finite check is split among threads). */
static void nonfinite_index_threads(void)
{
    const size_t n = 100000;
    for (int threads = 1; threads <= 3; threads += 2) {
        longode o = {n, 0, calloc(n, sizeof(double))};
        CHECK(o.y != NULL);
        if (!o.y)
            return;
        psys_ode ode = {.size = n, .ctx = &o, .get_state = lo_get, .set_state = lo_set, .get_time = lo_time,
                        .set_time = lo_set_time, .derivative = lo_deriv_nan};
        psys_solver *s = make_ode_solver("euler", &ode);
        CHECK(psys_solver_set_threads(s, threads) == PSYS_OK);
        CHECK(psys_solver_step(s, 0.05, NULL) == PSYS_ERR_NONFINITE);
        CHECK(psys_solver_bad_component(s) == 70000);
        CHECK(o.t == 0 && o.y[70000] == 0); /* the state is unchanged */
        psys_solver_destroy(s);
        free(o.y);
    }
}

/* The finite check at the end of a step (a bit test on the exponent) takes
 * the extremes of the finite range and refuses both infinities and NaNs of
 * either sign and any payload, wherever they stand; on 3 threads each
 * thread checks its own part (the state is long enough to be split), and
 * the first bad index is still reported. A zero derivative keeps y0. */
static psys_status zero_deriv(void *ctx, double t, const double *y, double *yd)
{
    (void)t;
    (void)y;
    memset(yd, 0, ((const longode *)ctx)->n * sizeof(double));
    return PSYS_OK;
}

static double bits_to_double(uint64_t u)
{
    double v;
    memcpy(&v, &u, sizeof v);
    return v;
}

/* System k of verlet_fast_paths: 27 particles in a periodic box with a
 * Lennard-Jones grid, plus per kind: 0 nothing, 1 gravity (both velocity
 * free), 2 drag, 3 damped springs, 4 a plane, 5 a controlled particle,
 * 6 undamped springs (all read or set velocities, or may). */
static psys_system *fast_path_system(int kind)
{
    psys_system *sys = make_system(3);
    const double lo[3] = {0, 0, 0}, hi[3] = {3.3, 3.3, 3.3};
    const bool per[3] = {true, true, true};
    CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
    urand_seed(7);
    for (int i = 0; i < 27; i++) {
        double x[3] = {(i % 3) * 1.1 + urand(0, 0.1), (i / 3 % 3) * 1.1 + urand(0, 0.1), (i / 9) * 1.1 + 0.02};
        double v[3] = {urand(-2, 2), urand(-2, 2), urand(-2, 2)};
        add_particle(sys, x, v, 1.0 + 0.01 * i);
    }
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = 0.9;
    def.cutoff = 1.6;
    def.skin = 0.2;
    def.method = PSYS_PAIR_GRID;
    CHECK(psys_system_add_pair(sys, &def, NULL) == PSYS_OK);
    const double g[3] = {0, -0.5, 0};
    if (kind == 1)
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    if (kind == 2)
        CHECK(psys_system_add_drag(sys, 0.3) == PSYS_OK);
    if (kind == 3 || kind == 6)
        for (size_t i = 0; i + 1 < 27; i += 2)
            CHECK(psys_system_add_spring(sys, i, i + 1, 20.0, kind == 3 ? 0.5 : 0.0, -1) == PSYS_OK);
    if (kind == 4) {
        psys_plane_def pl = psys_plane_def_default();
        pl.point[1] = 0.01;
        pl.friction = 0.4;
        CHECK(psys_system_add_plane(sys, &pl) == PSYS_OK);
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    }
    if (kind == 5) {
        const double c[3] = {1.6, 1.6, 1.6};
        CHECK(psys_system_control_circle(sys, 13, c, 0.3, 2.0, 0.0, NULL) == PSYS_OK);
    }
    return sys;
}

/* The system's acceleration and velocity_free fast paths
 * (psys_system_solver_create): symplectic-euler and verlet give the same
 * bits with them as through derivative alone (psys_solver_create on
 * psys_system_ode), and velocity_free holds exactly for systems whose
 * forces ignore the velocities; a velocity_free that held with drag,
 * damping, planes or controlled particles would make verlet's second
 * evaluation see v½ instead of the predicted velocity, and differ. */
static void verlet_fast_paths(void)
{
    for (int kind = 0; kind <= 6; kind++)
        for (int which = 0; which < 2; which++) {
            const char *name = which ? "symplectic-euler" : "verlet";
            psys_system *a = fast_path_system(kind), *b = fast_path_system(kind);
            psys_ode oa = psys_system_ode(a), ob = psys_system_ode(b);
            const psys__ode_fast fa = psys__system_ode_fast(a);
            CHECK(fa.acceleration != NULL && fa.velocity_free != NULL);
            CHECK(fa.velocity_free(a) == (kind <= 1));
            psys_solver *sa = make_solver(name, a), *sb = make_ode_solver(name, &ob);
            for (int step = 0; step < 60; step++) {
                CHECK(psys_system_advance(a, sa, 0.004, NULL) == PSYS_OK);
                CHECK(psys_system_advance(b, sb, 0.004, NULL) == PSYS_OK);
            }
            CHECK(memcmp(psys_system_positions(a), psys_system_positions(b), 27 * 3 * sizeof(double)) == 0);
            CHECK(memcmp(psys_system_velocities(a), psys_system_velocities(b), 27 * 3 * sizeof(double)) == 0);
            /* the accelerations themselves: derivative's second half */
            double y[162], d1[162], d2[162];
            oa.get_state(oa.ctx, y);
            CHECK(oa.derivative(oa.ctx, 0.24, y, d1) == PSYS_OK);
            CHECK(fa.acceleration(a, 0.24, y, d2) == PSYS_OK);
            CHECK(memcmp(d1 + 81, d2 + 81, 81 * sizeof(double)) == 0);
            psys_solver_destroy(sa);
            psys_solver_destroy(sb);
            psys_system_destroy(a);
            psys_system_destroy(b);
        }
}

/* A cloth of nx × ny particles (3-D) numbered at random when shuffled,
 * with structural and shear springs, gravity and drag, two corners pinned;
 * with planes, a floor it partly lies on (friction) and a sticky wall. */
static psys_system *cloth(int nx, int ny, bool shuffled, bool planes)
{
    const size_t n = (size_t)nx * (size_t)ny;
    size_t *at = malloc(n * sizeof *at); /* grid point -> particle */
    CHECK(at != NULL);
    for (size_t i = 0; i < n; i++)
        at[i] = i;
    urand_seed(11);
    for (size_t i = n - 1; shuffled && i > 0; i--) {
        size_t j = (size_t)urand(0, (double)(i + 1));
        j = j > i ? i : j;
        const size_t t = at[i];
        at[i] = at[j];
        at[j] = t;
    }
    size_t *inv = malloc(n * sizeof *inv);
    CHECK(inv != NULL);
    for (size_t i = 0; i < n; i++)
        inv[at[i]] = i;
    psys_system *sys = make_system(3);
    for (size_t q = 0; q < n; q++) {
        const size_t g = inv[q], r = g / (size_t)nx, c = g % (size_t)nx;
        double x[3] = {0.05 * (double)c, 0.05 * (double)r, planes && r < 5 ? 0.0 : 0.2 + urand(-0.01, 0.01)};
        double v[3] = {urand(-0.1, 0.1), urand(-0.1, 0.1), planes && r < 5 ? 0.0 : urand(-0.5, 0.1)};
        add_particle(sys, x, v, 0.01 + urand(0, 0.002));
    }
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < nx; c++) {
            const size_t g = (size_t)r * (size_t)nx + (size_t)c;
            if (c + 1 < nx)
                CHECK(psys_system_add_spring(sys, at[g], at[g + 1], 400.0, 0.02, -1) == PSYS_OK);
            if (r + 1 < ny)
                CHECK(psys_system_add_spring(sys, at[g], at[g + (size_t)nx], 400.0, 0.02, -1) == PSYS_OK);
            if (c + 1 < nx && r + 1 < ny)
                CHECK(psys_system_add_spring(sys, at[g], at[g + (size_t)nx + 1], 200.0, 0.01, -1) == PSYS_OK);
        }
    const double g3[3] = {0, 0, -9.81};
    CHECK(psys_system_add_gravity(sys, g3) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, 0.02) == PSYS_OK);
    CHECK(psys_system_set_fixed(sys, at[n - 1], true) == PSYS_OK);
    CHECK(psys_system_set_fixed(sys, at[n - (size_t)nx], true) == PSYS_OK);
    if (planes) {
        psys_plane_def floor = psys_plane_def_default(), wall = psys_plane_def_default();
        floor.normal[0] = 0, floor.normal[1] = 0, floor.normal[2] = 1;
        floor.friction = 0.5;
        wall.normal[0] = 1, wall.normal[1] = 0, wall.normal[2] = 0;
        wall.point[0] = -0.01;
        wall.stick = true;
        CHECK(psys_system_add_plane(sys, &floor) == PSYS_OK);
        CHECK(psys_system_add_plane(sys, &wall) == PSYS_OK);
    }
    free(at);
    free(inv);
    return sys;
}

/* psys_system_solver_create (the system's fast paths: fused stages, the
 * chain, accelerations only, the state in the springs' order) against
 * psys_solver_create on psys_system_ode (the plain ODE interface), both
 * stepped by psys_system_advance: the same bits for every solver whose
 * fast paths there are, on a cloth in rows and shuffled, with and without
 * planes (collisions and contact in the steps). Over 4,096 springs, so the
 * shuffled one gets an internal order. */
static void system_solver_same_bits(void)
{
    static const char *const names[] = {"euler", "midpoint", "rk4", "symplectic-euler", "verlet"};
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
        for (int kind = 0; kind < 4; kind++) {
            const bool shuffled = kind & 1, planes = kind >= 2;
            psys_system *a = cloth(48, 36, shuffled, planes), *b = cloth(48, 36, shuffled, planes);
            psys_solver *sa = make_solver(names[k], a);
            psys_ode ob = psys_system_ode(b);
            psys_solver *sb = make_ode_solver(names[k], &ob);
            /* the fast side holds its state in the springs' order where shuffled, the plain side never */
            CHECK(psys__state_order_begin(a, sa) == (shuffled && !planes));
            psys__state_order_end(a);
            CHECK(!psys__state_order_begin(b, sb));
            psys__state_order_end(b);
            for (int step = 0; step < 40; step++) {
                double ha = 0, hb = 0;
                CHECK(psys_system_advance(a, sa, 2e-4, &ha) == PSYS_OK);
                CHECK(psys_system_advance(b, sb, 2e-4, &hb) == PSYS_OK);
                CHECK(ha == hb);
            }
            const size_t nd = 3 * psys_system_count(a);
            const bool same = memcmp(psys_system_positions(a), psys_system_positions(b), nd * sizeof(double)) == 0 &&
                              memcmp(psys_system_velocities(a), psys_system_velocities(b), nd * sizeof(double)) == 0;
            if (!same)
                fprintf(stderr, "%s, cloth kind %d: the system's solver and the plain one differ\n", names[k], kind);
            CHECK(same);
            CHECK(psys_system_time(a) == psys_system_time(b));
            /* the run did something: the cloth moved */
            CHECK(psys_system_velocities(a)[3 * 600 + 2] != 0.0);
            psys_solver_destroy(sa);
            psys_solver_destroy(sb);
            psys_system_destroy(a);
            psys_system_destroy(b);
        }
}

static void nonfinite_kinds(void)
{
    const size_t n = 100000;
    const double finite[] = {DBL_MAX, -DBL_MAX, DBL_MIN, -DBL_MIN, DBL_TRUE_MIN, -0.0, 1e300};
    const double bad[] = {INFINITY, -INFINITY, NAN, -NAN, bits_to_double(0x7ff0000000000001u),
                          bits_to_double(0xfff0000000000001u), bits_to_double(0x7ff8000000000123u)};
    const size_t nbad = sizeof bad / sizeof bad[0];
    const size_t at[] = {0, 50001, 99999}; /* first, in the second or third thread's part, last */
    for (int threads = 1; threads <= 3; threads += 2)
        for (size_t b = 0; b <= nbad; b++)
            for (size_t p = 0; p < (b < nbad ? sizeof at / sizeof at[0] : 1); p++) {
                longode o = {n, 0, calloc(n, sizeof(double))};
                CHECK(o.y != NULL);
                if (!o.y)
                    return;
                for (size_t i = 0; i < n; i++)
                    o.y[i] = finite[i % (sizeof finite / sizeof finite[0])];
                const bool expect_bad = b < nbad;
                if (expect_bad) {
                    o.y[at[p]] = bad[b];
                    if (p == 0)
                        o.y[at[2]] = bad[b]; /* a later one too: the first is named */
                }
                psys_ode ode = {.size = n, .ctx = &o, .get_state = lo_get, .set_state = lo_set, .get_time = lo_time,
                                .set_time = lo_set_time, .derivative = zero_deriv};
                psys_solver *s = make_ode_solver("euler", &ode);
                CHECK(psys_solver_set_threads(s, threads) == PSYS_OK);
                psys_status st = psys_solver_step(s, 0.05, NULL);
                if (expect_bad) {
                    CHECK(st == PSYS_ERR_NONFINITE);
                    CHECK(psys_solver_bad_component(s) == at[p]);
                    CHECK(o.t == 0);
                } else {
                    CHECK(st == PSYS_OK);
                    CHECK(o.t == 0.05 && o.y[0] == DBL_MAX && o.y[1] == -DBL_MAX && o.y[4] == DBL_TRUE_MIN);
                }
                psys_solver_destroy(s);
                free(o.y);
            }
}

static const check_case cases[] = {
    {"registry", registry},
    {"solver_threads_same_bits", solver_threads_same_bits},
    {"nonfinite_index_threads", nonfinite_index_threads},
    {"nonfinite_kinds", nonfinite_kinds},
    {"verlet_fast_paths", verlet_fast_paths},
    {"system_solver_same_bits", system_solver_same_bits},
    {"symplectic_needs_second_order", symplectic_needs_second_order},
    {"custom_ode_decay", custom_ode_decay},
    {"custom_ode_symplectic", custom_ode_symplectic},
    {"convergence_orders", convergence_orders},
    {"convergence_orders_damped", convergence_orders_damped},
    {"rk45_tolerance", rk45_tolerance},
    {"rk45_efficiency", rk45_efficiency},
    {"rk45_landing", rk45_landing},
    {"rk45_bad_arguments", rk45_bad_arguments},
    {"failed_step_zeroes_h_taken", failed_step_zeroes_h_taken},
    {"symplectic_energy_bounded", symplectic_energy_bounded},
    {"euler_energy_grows", euler_energy_grows},
    {"nonfinite_custom_ode", nonfinite_custom_ode},
    {"nonfinite_particle_force", nonfinite_particle_force},
    {"nonfinite_last_evaluation", nonfinite_last_evaluation},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
