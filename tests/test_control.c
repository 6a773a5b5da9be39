/* Controlled particles (notes §5,
 * docs/notes-errata.md#5-controlled-particles-position-and-velocity-at-every-stage,
 * docs/semantics.md#controller-paths) and mouse springs,
 * pinned against closed forms:
 *   circle     x = c + R(cos(ωt+φ)u + sin(ωt+φ)w),  v = Rω(−sin(ωt+φ)u + cos(ωt+φ)w)
 *   oscillate  x = c + A sin(ωt+φ) d̂,              v = Aω cos(ωt+φ) d̂
 *   keyframes  piecewise linear, held (v = 0) outside the range
 *   mouse      f = −ks(x − p) − kd(v − ṗ),           U = ½ks|x − p|²
 * and the errata point (docs/notes-errata.md, same section) that
 * velocity-dependent forces must see the
 * controller's velocity at every stage time. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

/* ------------------------------------------------------------------ */
/* helpers                                                             */
/* ------------------------------------------------------------------ */

static void circle_at(int d, const double *c, double R, double w, double ph, const double *u, const double *wv,
                      double t, double *x, double *v)
{
    double a = w * t + ph;
    for (int k = 0; k < d; k++) {
        x[k] = c[k] + R * (cos(a) * u[k] + sin(a) * wv[k]);
        v[k] = R * w * (-sin(a) * u[k] + cos(a) * wv[k]);
    }
}

/* max over k of |a[k] - b[k]| */
static double maxdiff(const double *a, const double *b, int n)
{
    double m = 0;
    for (int k = 0; k < n; k++)
        m = fmax(m, fabs(a[k] - b[k]));
    return m;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double *a, const double *b, double *c)
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Run a scene to the end, calling check(t, sys, ctx) after every step.
 * Returns the number of steps taken. */
typedef void (*step_check)(double t, psys_system *sys, void *ctx);

static long run_scene(psys_scene *sc, step_check check, void *ctx)
{
    psys_error err;
    psys_run *run = psys_run_create(sc, &err);
    if (!run) {
        fprintf(stderr, "psys_run_create: %s\n", err.message);
        CHECK(run != NULL);
        return 0;
    }
    psys_system *sys = psys_scene_system(sc);
    long steps = 0;
    check(psys_system_time(sys), sys, ctx);
    while (!psys_run_done(run)) {
        psys_status st = psys_run_step(run, &err);
        CHECK(st == PSYS_OK);
        if (st != PSYS_OK) {
            fprintf(stderr, "psys_run_step: %s\n", err.message);
            break;
        }
        steps++;
        check(psys_system_time(sys), sys, ctx);
    }
    psys_run_destroy(run);
    return steps;
}

static const char *const run_solvers[] = {"rk4", "euler", "verlet", "rk45"};
#define NRUN (sizeof run_solvers / sizeof run_solvers[0])

/* ------------------------------------------------------------------ */
/* circle, oscillate, keyframes through psys_run                        */
/* ------------------------------------------------------------------ */

typedef struct ctl_expect {
    size_t particle;
    int dim;
    void (*at)(const struct ctl_expect *e, double t, double *x, double *v);
    double c[3], R, w, ph, u[3], wv[3], dir[3], A;
    const double *frames;
    size_t nframes;
    double worst; /* largest |error| seen */
    long checks;
} ctl_expect;

static void expect_circle(const ctl_expect *e, double t, double *x, double *v)
{
    circle_at(e->dim, e->c, e->R, e->w, e->ph, e->u, e->wv, t, x, v);
}

static void expect_oscillate(const ctl_expect *e, double t, double *x, double *v)
{
    double a = e->w * t + e->ph;
    for (int k = 0; k < e->dim; k++) {
        x[k] = e->c[k] + e->A * sin(a) * e->dir[k];
        v[k] = e->A * e->w * cos(a) * e->dir[k];
    }
}

/* Independent piecewise-linear interpolation (linear scan); each knot
 * starts the piece to its right. */
static void expect_keyframes(const ctl_expect *e, double t, double *x, double *v)
{
    int d = e->dim;
    size_t s = 1 + (size_t)d, n = e->nframes;
    const double *f = e->frames;
    if (t < f[0]) {
        for (int k = 0; k < d; k++) {
            x[k] = f[1 + k];
            v[k] = 0;
        }
        return;
    }
    if (t >= f[(n - 1) * s]) {
        for (int k = 0; k < d; k++) {
            x[k] = f[(n - 1) * s + 1 + k];
            v[k] = 0;
        }
        return;
    }
    for (size_t j = 0; j + 1 < n; j++) {
        const double *a = f + j * s, *b = f + (j + 1) * s;
        if (t >= a[0] && t < b[0]) {
            for (int k = 0; k < d; k++) {
                double slope = (b[1 + k] - a[1 + k]) / (b[0] - a[0]);
                x[k] = a[1 + k] + slope * (t - a[0]);
                v[k] = slope;
            }
            return;
        }
    }
}

static void check_ctl(double t, psys_system *sys, void *ctx)
{
    ctl_expect *e = ctx;
    int d = e->dim;
    double x[3], v[3];
    e->at(e, t, x, v);
    const double *px = psys_system_positions(sys) + e->particle * d;
    const double *pv = psys_system_velocities(sys) + e->particle * d;
    double err = fmax(maxdiff(px, x, d), maxdiff(pv, v, d));
    if (err > e->worst)
        e->worst = err;
    if (!(err <= 1e-12))
        fprintf(stderr, "  t = %.17g: controlled state off by %.3g\n", t, err);
    CHECK(err <= 1e-12);
    CHECK(psys_system_is_controlled(sys, e->particle));
    e->checks++;
}

/* Bit for bit: after every step the controlled particle holds exactly the
 * controller's state at the step's time, also in steps a plane collision cut
 * into partial steps (a resumed run puts it there; they must agree). */
typedef struct {
    size_t particle, bounces;
    double last_vy;
} on_path;

static void check_on_path(double t, psys_system *sys, void *ctx)
{
    on_path *o = ctx;
    size_t n = psys_system_count(sys) * 2;
    double *x = malloc(n * sizeof(double)), *v = malloc(n * sizeof(double));
    if (!x || !v) {
        CHECK(!"out of memory");
        free(x);
        free(v);
        return;
    }
    memcpy(x, psys_system_positions(sys), n * sizeof(double));
    memcpy(v, psys_system_velocities(sys), n * sizeof(double));
    psys_system_apply_controllers(sys, t);
    const double *px = psys_system_positions(sys) + o->particle * 2;
    const double *pv = psys_system_velocities(sys) + o->particle * 2;
    bool same = memcmp(px, x + o->particle * 2, 2 * sizeof(double)) == 0
                && memcmp(pv, v + o->particle * 2, 2 * sizeof(double)) == 0;
    if (!same)
        fprintf(stderr, "  t = %.17g: controlled x off by %.3g\n", t, maxdiff(px, x + o->particle * 2, 2));
    CHECK(same);
    double vy = v[2 * 2 + 1]; /* particle 2 falls onto the plane y = -1.5 */
    o->bounces += o->last_vy < 0 && vy > 0 && x[2 * 2 + 1] < -1.45;
    o->last_vy = vy;
    free(x);
    free(v);
}

static void test_on_path_through_bounces(void)
{
    for (size_t s = 0; s < NRUN; s++) {
        char text[1536];
        snprintf(text, sizeof text,
                 "{\"psys\":1,\"dim\":2,\"integrator\":\"%s\",\"dt\":0.001,\"duration\":6,\"output\":{\"every\":1000000},"
                 "\"particles\":[{\"id\":\"p\",\"x\":[0,0],\"fixed\":true},"
                 "{\"id\":\"b\",\"x\":[1,0],\"v\":[0,0.5],\"mass\":0.5},{\"x\":[1,1],\"mass\":2},"
                 "{\"id\":\"m\",\"x\":[2,0],\"control\":{\"type\":\"circle\",\"center\":[2,0.5],"
                 "\"radius\":0.5,\"omega\":3}}],"
                 "\"forces\":[{\"type\":\"gravity\",\"g\":[0,-9.81]},{\"type\":\"drag\",\"kd\":0.1},"
                 "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"b\",\"ks\":100,\"kd\":0.5},"
                 "{\"type\":\"spring\",\"a\":1,\"b\":2,\"ks\":50,\"rest\":0.8},"
                 "{\"type\":\"spring\",\"a\":2,\"b\":\"m\",\"ks\":10}],"
                 "\"planes\":[{\"point\":[0,-1.5],\"normal\":[0,1],\"restitution\":0.7}]}",
                 run_solvers[s]);
        psys_scene *sc = load_scene(text);
        on_path o = {3, 0, 0};
        long steps = run_scene(sc, check_on_path, &o);
        fprintf(stderr, "  %-7s %ld steps, %zu bounces\n", run_solvers[s], steps, o.bounces);
        CHECK(o.bounces >= 2); /* the steps with collisions were checked */
        psys_scene_destroy(sc);
    }
}

/* A driven mechanism: the controlled particle "m" pulls a free particle "p"
 * through a damped spring under gravity, so the solver has real work. */
static psys_scene *driven_scene(const char *integrator, int dim, const char *control)
{
    char text[2048];
    if (dim == 2)
        snprintf(text, sizeof text,
                 "{\"psys\":1,\"dim\":2,\"integrator\":\"%s\",\"dt\":0.01,\"duration\":1.0,"
                 "\"particles\":[{\"id\":\"m\",\"x\":[0,0],\"control\":%s},"
                 "{\"id\":\"p\",\"x\":[4,1],\"mass\":0.5}],"
                 "\"forces\":[{\"type\":\"spring\",\"a\":\"p\",\"b\":\"m\",\"ks\":30,\"kd\":0.8,\"rest\":1.5},"
                 "{\"type\":\"gravity\",\"g\":[0,-9.81]}]}",
                 integrator, control);
    else
        snprintf(text, sizeof text,
                 "{\"psys\":1,\"dim\":3,\"integrator\":\"%s\",\"dt\":0.01,\"duration\":1.0,"
                 "\"particles\":[{\"id\":\"m\",\"x\":[0,0,0],\"control\":%s},"
                 "{\"id\":\"p\",\"x\":[4,1,0.5],\"mass\":0.5}],"
                 "\"forces\":[{\"type\":\"spring\",\"a\":\"p\",\"b\":\"m\",\"ks\":30,\"kd\":0.8,\"rest\":1.5},"
                 "{\"type\":\"gravity\",\"g\":[0,-9.81,0]}]}",
                 integrator, control);
    return load_scene(text);
}

static void run_and_check(const char *integrator, int dim, const char *control, ctl_expect *e)
{
    psys_scene *sc = driven_scene(integrator, dim, control);
    e->worst = 0;
    e->checks = 0;
    long steps = run_scene(sc, check_ctl, e);
    CHECK(steps >= 100);
    CHECK_NEAR(psys_system_time(psys_scene_system(sc)), 1.0, 1e-12);
    /* the free particle really moved (the run did something) */
    const double *p = psys_system_positions(psys_scene_system(sc)) + dim;
    CHECK(fabs(p[0] - 4) + fabs(p[1] - 1) > 1e-2);
    fprintf(stderr, "  %-7s %dD: %ld steps, worst controlled-state error %.3g\n", integrator, dim, steps, e->worst);
    psys_scene_destroy(sc);
}

static void test_circle_2d_run(void)
{
    ctl_expect e = {.particle = 0, .dim = 2, .at = expect_circle, .c = {2, 1}, .R = 1.5, .w = 3, .ph = 0.4,
                    .u = {1, 0}, .wv = {0, 1}};
    for (size_t s = 0; s < NRUN; s++)
        run_and_check(run_solvers[s], 2,
                      "{\"type\":\"circle\",\"center\":[2,1],\"radius\":1.5,\"omega\":3,\"phase\":0.4}", &e);
    /* negative omega turns clockwise */
    ctl_expect e2 = {.particle = 0, .dim = 2, .at = expect_circle, .c = {-1, 0.5}, .R = 0.75, .w = -2, .ph = 0,
                     .u = {1, 0}, .wv = {0, 1}};
    run_and_check("rk4", 2, "{\"type\":\"circle\",\"center\":[-1,0.5],\"radius\":0.75,\"omega\":-2}", &e2);
}

/* 3-D circle: axis z gives u = e_x, w = e_y; a tilted axis gives a
 * right-handed orthonormal basis of the plane normal to it. */
static void test_circle_3d_axis(void)
{
    /* default axis (z) and an explicit, unnormalised z axis, through psys_run */
    ctl_expect e = {.particle = 0, .dim = 3, .at = expect_circle, .c = {1, -2, 0.5}, .R = 2, .w = 1.7, .ph = -0.3,
                    .u = {1, 0, 0}, .wv = {0, 1, 0}};
    for (size_t s = 0; s < NRUN; s++)
        run_and_check(run_solvers[s], 3,
                      "{\"type\":\"circle\",\"center\":[1,-2,0.5],\"radius\":2,\"omega\":1.7,\"phase\":-0.3}", &e);
    run_and_check("rk4", 3,
                  "{\"type\":\"circle\",\"center\":[1,-2,0.5],\"radius\":2,\"omega\":1.7,\"phase\":-0.3,"
                  "\"axis\":[0,0,5]}",
                  &e);

    /* tilted axis through the C API and psys_system_advance */
    psys_system *sys = make_system(3);
    const double axis_in[3] = {1, 2, 2}; /* |axis| = 3 */
    const double ahat[3] = {1.0 / 3, 2.0 / 3, 2.0 / 3};
    const double c[3] = {0.5, -1, 2}, R = 1.25, w = 2.0;
    double z[3] = {0, 0, 0}, pfree[3] = {2, 0, 1};
    size_t a = add_particle(sys, z, NULL, 1);   /* phase 0: gives u and w */
    size_t b = add_particle(sys, z, NULL, 1);   /* phase 0.7, same axis */
    size_t p = add_particle(sys, pfree, NULL, 0.3);
    CHECK(psys_system_control_circle(sys, a, c, R, w, 0.0, axis_in) == PSYS_OK);
    CHECK(psys_system_control_circle(sys, b, c, R, w, 0.7, axis_in) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, p, a, 20, 0.5, 1.0) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, p, b, 20, 0.5, 1.0) == PSYS_OK);
    /* at t = 0 with phase 0: x - c = R u and v = Rω w */
    double u[3], wv[3], uxw[3];
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    for (int k = 0; k < 3; k++) {
        u[k] = (X[a * 3 + k] - c[k]) / R;
        wv[k] = V[a * 3 + k] / (R * w);
    }
    cross3(u, wv, uxw);
    CHECK_NEAR(dot3(u, u), 1, 1e-15);
    CHECK_NEAR(dot3(wv, wv), 1, 1e-15);
    CHECK_NEAR(dot3(u, wv), 0, 1e-15);
    CHECK_NEAR(dot3(u, ahat), 0, 1e-15);
    CHECK_NEAR(dot3(wv, ahat), 0, 1e-15);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(uxw[k], ahat[k], 1e-15); /* right-handed: u × w = axis */

    psys_solver *s = make_solver("rk4", sys);
    double worst = 0;
    for (int step = 1; step <= 300; step++) {
        double ht = 0;
        CHECK(psys_system_advance(sys, s, 0.005, &ht) == PSYS_OK);
        double t = psys_system_time(sys);
        X = psys_system_positions(sys);
        V = psys_system_velocities(sys);
        double xa[3], va[3], xb[3], vb[3];
        circle_at(3, c, R, w, 0.0, u, wv, t, xa, va);
        circle_at(3, c, R, w, 0.7, u, wv, t, xb, vb);
        worst = fmax(worst, fmax(maxdiff(X + a * 3, xa, 3), maxdiff(V + a * 3, va, 3)));
        worst = fmax(worst, fmax(maxdiff(X + b * 3, xb, 3), maxdiff(V + b * 3, vb, 3)));
        /* basis-free checks: in the plane normal to the axis, radius R,
         * angular momentum (x - c) × v = R²ω â */
        double r[3], L[3];
        for (int k = 0; k < 3; k++)
            r[k] = X[b * 3 + k] - c[k];
        cross3(r, V + b * 3, L);
        CHECK_NEAR(dot3(r, ahat), 0, 1e-14);
        CHECK_NEAR(sqrt(dot3(r, r)), R, 1e-14);
        for (int k = 0; k < 3; k++)
            CHECK_NEAR(L[k], R * R * w * ahat[k], 1e-13);
    }
    CHECK(worst <= 1e-12);
    fprintf(stderr, "  tilted axis: worst error %.3g\n", worst);
    CHECK_NEAR(psys_system_time(sys), 1.5, 1e-12);
    psys_solver_destroy(s);

    /* axis along x: still an orthonormal right-handed basis */
    const double ex[3] = {-4, 0, 0}, mex[3] = {-1, 0, 0};
    CHECK(psys_system_control_circle(sys, a, c, R, w, 0.0, ex) == PSYS_OK);
    psys_system_apply_controllers(sys, 0.0);
    X = psys_system_positions(sys);
    V = psys_system_velocities(sys);
    for (int k = 0; k < 3; k++) {
        u[k] = (X[a * 3 + k] - c[k]) / R;
        wv[k] = V[a * 3 + k] / (R * w);
    }
    cross3(u, wv, uxw);
    CHECK_NEAR(dot3(u, u), 1, 1e-15);
    CHECK_NEAR(dot3(u, wv), 0, 1e-15);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(uxw[k], mex[k], 1e-15);
    psys_system_destroy(sys);
}

static void test_oscillate_run(void)
{
    /* direction (3, 4) is normalised to (0.6, 0.8) */
    ctl_expect e = {.particle = 0, .dim = 2, .at = expect_oscillate, .c = {1, -1}, .A = 0.5, .w = 2.5,
                    .ph = -0.3, .dir = {0.6, 0.8}};
    for (size_t s = 0; s < NRUN; s++)
        run_and_check(run_solvers[s], 2,
                      "{\"type\":\"oscillate\",\"center\":[1,-1],\"direction\":[3,4],\"amplitude\":0.5,"
                      "\"omega\":2.5,\"phase\":-0.3}",
                      &e);
    ctl_expect e3 = {.particle = 0, .dim = 3, .at = expect_oscillate, .c = {0, 1, 2}, .A = 1.5, .w = 4,
                     .ph = 0, .dir = {2.0 / 3, -1.0 / 3, 2.0 / 3}};
    for (size_t s = 0; s < NRUN; s++)
        run_and_check(run_solvers[s], 3,
                      "{\"type\":\"oscillate\",\"center\":[0,1,2],\"direction\":[2,-1,2],\"amplitude\":1.5,"
                      "\"omega\":4}",
                      &e3);
}

static void test_keyframes_run(void)
{
    /* knots off the step grid so every printed time is strictly inside a segment */
    static const double frames[] = {0.123, 1, 2, 0.4567, 3, -1, 0.789, 0, 0.5};
    ctl_expect e = {.particle = 0, .dim = 2, .at = expect_keyframes, .frames = frames, .nframes = 3};
    for (size_t s = 0; s < NRUN; s++)
        run_and_check(run_solvers[s], 2,
                      "{\"type\":\"keyframes\",\"frames\":[[0.123,1,2],[0.4567,3,-1],[0.789,0,0.5]]}", &e);
    run_and_check("rk4", 2,
                  "{\"type\":\"keyframes\",\"linear\":true,\"frames\":[[0.123,1,2],[0.4567,3,-1],[0.789,0,0.5]]}",
                  &e);

    /* direct evaluation: held with zero velocity before and after the range,
     * exact slopes inside */
    psys_system *sys = make_system(3);
    double z[3] = {9, 9, 9};
    size_t i = add_particle(sys, z, z, 1);
    /* (-1; 0,0,0) -> (2; 2,4,-2) -> (6; 3,10,-3): slopes (2/3,4/3,-2/3), (1/4,3/2,-1/4) */
    const double f3[] = {-1, 0, 0, 0, 2, 2, 4, -2, 6, 3, 10, -3};
    CHECK(psys_system_control_keyframes(sys, i, f3, 3) == PSYS_OK);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    /* installed at the system time 0: on the first segment */
    CHECK_NEAR(X[0], 2.0 / 3, 1e-15);
    CHECK_NEAR(X[1], 4.0 / 3, 1e-15);
    CHECK_NEAR(X[2], -2.0 / 3, 1e-15);
    CHECK_NEAR(V[0], 2.0 / 3, 1e-15);
    CHECK_NEAR(V[1], 4.0 / 3, 1e-15);
    CHECK_NEAR(V[2], -2.0 / 3, 1e-15);
    struct {
        double t, x[3], v[3];
    } want[] = {
        {-50, {0, 0, 0}, {0, 0, 0}},
        {-1.0000001, {0, 0, 0}, {0, 0, 0}},
        {-0.25, {0.5, 1, -0.5}, {2.0 / 3, 4.0 / 3, -2.0 / 3}},
        {1.5, {5.0 / 3, 10.0 / 3, -5.0 / 3}, {2.0 / 3, 4.0 / 3, -2.0 / 3}},
        {2.75, {2.1875, 5.125, -2.1875}, {0.25, 1.5, -0.25}},
        {5.5, {2.875, 9.25, -2.875}, {0.25, 1.5, -0.25}},
        {6.0000001, {3, 10, -3}, {0, 0, 0}},
        {1e6, {3, 10, -3}, {0, 0, 0}},
    };
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        psys_system_apply_controllers(sys, want[k].t);
        for (int c = 0; c < 3; c++) {
            CHECK_NEAR(X[c], want[k].x[c], 1e-12);
            CHECK_NEAR(V[c], want[k].v[c], 1e-15);
        }
    }
    /* a single frame holds forever */
    const double one[] = {5, 1, 2, 3};
    CHECK(psys_system_control_keyframes(sys, i, one, 1) == PSYS_OK);
    psys_system_apply_controllers(sys, 7.0);
    CHECK(X[0] == 1 && X[1] == 2 && X[2] == 3 && V[0] == 0 && V[1] == 0 && V[2] == 0);
    /* bad frames through the C API */
    const double bad[] = {0, 0, 0, 0, 0, 1, 1, 1};
    CHECK(psys_system_control_keyframes(sys, i, bad, 2) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "keyframes: times must increase strictly (frame 1)");
    CHECK(psys_system_control_keyframes(sys, i, bad, 0) == PSYS_ERR_INVALID);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* Velocity-dependent forces see the controller's velocity             */
/* (docs/notes-errata.md#5-controlled-particles-position-and-velocity-at-every-stage) */
/* ------------------------------------------------------------------ */

typedef struct driven {
    double c[2], R, w, ph; /* the driver's circle */
    double ks, kd, rest, m;
    bool stale;            /* pretend the driver's velocity is never set (zero) */
} driven;

/* Eq. 1 force on the free particle P (spring end a = P, b = driver D). */
static void driven_force(const driven *q, double t, const double *xp, const double *vp, double *f)
{
    static const double u[2] = {1, 0}, wv[2] = {0, 1};
    double xd[2], vd[2];
    circle_at(2, q->c, q->R, q->w, q->ph, u, wv, t, xd, vd);
    if (q->stale)
        vd[0] = vd[1] = 0;
    double l[2] = {xp[0] - xd[0], xp[1] - xd[1]}, ld[2] = {vp[0] - vd[0], vp[1] - vd[1]};
    double L = sqrt(l[0] * l[0] + l[1] * l[1]);
    double s = q->ks * (L - q->rest) + q->kd * (ld[0] * l[0] + ld[1] * l[1]) / L;
    f[0] = -s * l[0] / L;
    f[1] = -s * l[1] / L;
}

/* Classical RK4 on y = (x_P, v_P) with the driver's exact motion. */
static void driven_rk4(const driven *q, double t, double h, double *y)
{
    double k[4][4], yt[4], f[2];
    static const double cs[4] = {0, 0.5, 0.5, 1};
    for (int s = 0; s < 4; s++) {
        for (int j = 0; j < 4; j++)
            yt[j] = s == 0 ? y[j] : y[j] + cs[s] * h * k[s - 1][j];
        driven_force(q, t + cs[s] * h, yt, yt + 2, f);
        k[s][0] = yt[2];
        k[s][1] = yt[3];
        k[s][2] = f[0] / q->m;
        k[s][3] = f[1] / q->m;
    }
    for (int j = 0; j < 4; j++)
        y[j] += h / 6 * (k[0][j] + 2 * k[1][j] + 2 * k[2][j] + k[3][j]);
}

static void test_errata_controller_velocity(void)
{
    /* (a) acceleration at the start of a step. Driver on a circle of radius 1,
     * ω = 2 about the origin; at t0 = 0.3 the free particle P sits at rest at
     * distance 3 straight "above" the driver. A pure damper (ks = 0, kd = 5)
     * pulls P along l with magnitude kd (v_D·l̂). */
    driven q = {.c = {0, 0}, .R = 1, .w = 2, .ph = 0, .ks = 0, .kd = 5, .rest = 1, .m = 2};
    const double t0 = 0.3, h = 1e-7;
    const double u[2] = {1, 0}, wv[2] = {0, 1};
    double xd[2], vd[2];
    circle_at(2, q.c, q.R, q.w, q.ph, u, wv, t0, xd, vd);
    double xp[2] = {xd[0], xd[1] + 3}, zero[2] = {0, 0};
    /* closed form: l = (0, 3), l̇ = -v_D, f_P = -kd (l̇·l̂) l̂ = kd v_Dy ŷ */
    const double a_true[2] = {0, q.kd * vd[1] / q.m};
    double f_chk[2];
    driven_force(&q, t0, xp, zero, f_chk);
    CHECK_NEAR(f_chk[0] / q.m, a_true[0], 1e-15);
    CHECK_NEAR(f_chk[1] / q.m, a_true[1], 1e-15);
    CHECK(fabs(a_true[1]) > 1); /* v_Dy = 2 cos(0.6) = 1.65: a = 4.13 */

    double a_ctl[2], a_fixed[2];
    for (int variant = 0; variant < 2; variant++) {
        psys_system *sys = make_system(2);
        size_t d = add_particle(sys, zero, NULL, 1);
        size_t p = add_particle(sys, xp, zero, q.m);
        psys_system_set_time(sys, t0);
        if (variant == 0) {
            CHECK(psys_system_control_circle(sys, d, q.c, q.R, q.w, q.ph, NULL) == PSYS_OK);
            /* make the stored velocity stale: the solver must set it at the stage */
            CHECK(psys_system_set_particle(sys, d, xd, zero) == PSYS_OK);
        } else {
            CHECK(psys_system_set_particle(sys, d, xd, zero) == PSYS_OK);
            CHECK(psys_system_set_fixed(sys, d, true) == PSYS_OK);
        }
        CHECK(psys_system_add_spring(sys, p, d, q.ks, q.kd, q.rest) == PSYS_OK);
        psys_solver *s = make_solver("euler", sys);
        CHECK(psys_system_advance(sys, s, h, NULL) == PSYS_OK);
        const double *V = psys_system_velocities(sys);
        double *a = variant == 0 ? a_ctl : a_fixed;
        a[0] = V[p * 2] / h; /* Euler: v1 = v0 + h a(t0, y0) with v0 = 0 */
        a[1] = V[p * 2 + 1] / h;
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
    CHECK_NEAR(a_ctl[0], a_true[0], 1e-8);
    CHECK_NEAR(a_ctl[1], a_true[1], 1e-8);
    /* a driver that is merely fixed there (zero velocity) exerts no force at
     * all: the check above would fail by |a_true| if velocities were stale */
    CHECK_NEAR(a_fixed[0], 0, 1e-12);
    CHECK_NEAR(a_fixed[1], 0, 1e-12);
    CHECK(fabs(a_ctl[1] - a_fixed[1]) > 4);

    /* (b) whole trajectories: rk4 through psys_system_advance equals a
     * hand-written RK4 that uses the driver's exact x(t), v(t) at the stage
     * times t, t+h/2, t+h/2, t+h; the same RK4 with a stale (zero) driver
     * velocity is far off. */
    driven q2 = {.c = {0.5, -0.5}, .R = 0.8, .w = 3, .ph = 0.2, .ks = 4, .kd = 5, .rest = 1.5, .m = 0.7};
    psys_system *sys = make_system(2);
    double x0p[2] = {2.5, 0.5}, v0p[2] = {0.3, -0.2};
    size_t d = add_particle(sys, zero, NULL, 1);
    size_t p = add_particle(sys, x0p, v0p, q2.m);
    CHECK(psys_system_control_circle(sys, d, q2.c, q2.R, q2.w, q2.ph, NULL) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, p, d, q2.ks, q2.kd, q2.rest) == PSYS_OK);
    psys_solver *s = make_solver("rk4", sys);
    double y[4] = {x0p[0], x0p[1], v0p[0], v0p[1]}, ys[4];
    memcpy(ys, y, sizeof y);
    driven q2s = q2;
    q2s.stale = true;
    const double hh = 0.005;
    double worst = 0;
    for (int step = 0; step < 200; step++) {
        double t = psys_system_time(sys);
        driven_rk4(&q2, t, hh, y);
        driven_rk4(&q2s, t, hh, ys);
        CHECK(psys_system_advance(sys, s, hh, NULL) == PSYS_OK);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        worst = fmax(worst, fmax(maxdiff(X + p * 2, y, 2), maxdiff(V + p * 2, y + 2, 2)));
    }
    CHECK(worst <= 1e-11);
    const double *X = psys_system_positions(sys);
    double stale_gap = maxdiff(y, ys, 2);
    fprintf(stderr, "  rk4 vs exact-driver RK4: %.3g; stale-velocity RK4 differs by %.3g\n", worst, stale_gap);
    CHECK(stale_gap > 1e-2);
    CHECK(maxdiff(X + p * 2, ys, 2) > 1e-2);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* energy, release, fixed vs controlled                                 */
/* ------------------------------------------------------------------ */

static void test_energy_excludes_controlled(void)
{
    psys_system *sys = make_system(2);
    const double g[2] = {0, -9.81};
    double xp[2] = {0, 3}, vp[2] = {1, 0.5}, xf[2] = {0, 10}, z[2] = {0, 0};
    size_t p = add_particle(sys, xp, vp, 2);
    size_t d = add_particle(sys, z, NULL, 5);
    size_t f = add_particle(sys, xf, NULL, 3);
    const double c[2] = {0, 1};
    CHECK(psys_system_control_circle(sys, d, c, 1, 2, 0, NULL) == PSYS_OK); /* at (1, 1), speed 2 */
    CHECK(psys_system_set_fixed(sys, f, true) == PSYS_OK);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    /* kinetic: only P, ½·2·(1 + 0.25) */
    CHECK_NEAR(psys_system_kinetic_energy(sys), 1.25, 1e-15);
    /* gravity: only P, m g y = 2·9.81·3 */
    CHECK_NEAR(psys_system_potential_energy(sys), 2 * 9.81 * 3, 1e-12);
    /* a spring's energy counts whatever it is attached to: |l| = |(0,3)-(1,1)| = √5 */
    CHECK(psys_system_add_spring(sys, p, d, 10, 0, 1) == PSYS_OK);
    CHECK_NEAR(psys_system_potential_energy(sys), 2 * 9.81 * 3 + 5 * (sqrt(5.0) - 1) * (sqrt(5.0) - 1), 1e-12);
    /* released, D counts again: ½·5·4 kinetic, 5·9.81·1 gravity */
    CHECK(psys_system_release(sys, d) == PSYS_OK);
    CHECK_NEAR(psys_system_kinetic_energy(sys), 1.25 + 10, 1e-14);
    CHECK_NEAR(psys_system_potential_energy(sys),
               2 * 9.81 * 3 + 5 * 9.81 * 1 + 5 * (sqrt(5.0) - 1) * (sqrt(5.0) - 1), 1e-12);
    psys_system_destroy(sys);
}

static void test_release_makes_free(void)
{
    psys_system *sys = make_system(2);
    const double g[2] = {0, -9.81}, c[2] = {1, 2};
    double z[2] = {0, 0};
    size_t d = add_particle(sys, z, NULL, 1.5);
    CHECK(psys_system_control_circle(sys, d, c, 0.5, 4, 0.1, NULL) == PSYS_OK);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_release(sys, d) == PSYS_OK);
    CHECK(!psys_system_is_controlled(sys, d));
    CHECK(psys_system_release(sys, d) == PSYS_ERR_INVALID); /* nothing left to release */
    CHECK_STR(psys_system_last_error(sys), "particle 0 has no controller");
    CHECK(psys_system_control_circle(sys, d, c, 0.5, 4, 0.1, NULL) == PSYS_OK);
    CHECK(psys_system_is_controlled(sys, d));
    psys_solver *s = make_solver("rk4", sys);
    for (int k = 0; k < 37; k++)
        CHECK(psys_system_advance(sys, s, 0.01, NULL) == PSYS_OK);
    /* controlled: gravity did nothing, it is on its circle */
    double t_rel = psys_system_time(sys), xr[2], vr[2];
    const double u[2] = {1, 0}, wv[2] = {0, 1};
    circle_at(2, c, 0.5, 4, 0.1, u, wv, t_rel, xr, vr);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    CHECK(maxdiff(X, xr, 2) <= 1e-12 && maxdiff(V, vr, 2) <= 1e-12);
    CHECK(psys_system_release(sys, d) == PSYS_OK);
    CHECK(!psys_system_is_controlled(sys, d));
    /* releasing keeps the current state */
    CHECK(maxdiff(X, xr, 2) <= 1e-12 && maxdiff(V, vr, 2) <= 1e-12);
    /* from now on a projectile: x = x_r + v_r τ + ½ g τ² (rk4 is exact here) */
    for (int k = 0; k < 50; k++)
        CHECK(psys_system_advance(sys, s, 0.01, NULL) == PSYS_OK);
    double tau = psys_system_time(sys) - t_rel;
    CHECK_NEAR(tau, 0.5, 1e-12);
    for (int k = 0; k < 2; k++) {
        CHECK_NEAR(X[k], xr[k] + vr[k] * tau + 0.5 * g[k] * tau * tau, 1e-12);
        CHECK_NEAR(V[k], vr[k] + g[k] * tau, 1e-12);
    }
    CHECK_NEAR(psys_system_kinetic_energy(sys), 0.5 * 1.5 * (V[0] * V[0] + V[1] * V[1]), 1e-14);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

static void cb_circle(void *ctx, double t, double *x, double *v);

static void test_fixed_cannot_be_controlled(void)
{
    psys_system *sys = make_system(2);
    double x0[2] = {3, 4}, z[2] = {0, 0}, dir[2] = {1, 0};
    const double frames[] = {0, 1, 1, 1, 2, 2};
    size_t i = add_particle(sys, x0, NULL, 1);
    CHECK(psys_system_set_fixed(sys, i, true) == PSYS_OK);
    CHECK(psys_system_control_circle(sys, i, z, 1, 1, 0, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "particle 0 is fixed and cannot also be controlled");
    CHECK(psys_system_control_oscillate(sys, i, z, dir, 1, 1, 0) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "particle 0 is fixed and cannot also be controlled");
    CHECK(psys_system_control_keyframes(sys, i, frames, 2) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "particle 0 is fixed and cannot also be controlled");
    CHECK(psys_system_control_callback(sys, i, cb_circle, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "particle 0 is fixed and cannot also be controlled");
    /* nothing changed */
    CHECK(psys_system_is_fixed(sys, i));
    CHECK(!psys_system_is_controlled(sys, i));
    CHECK(psys_system_positions(sys)[0] == 3 && psys_system_positions(sys)[1] == 4);
    /* and the other way round */
    size_t j = add_particle(sys, x0, NULL, 1);
    CHECK(psys_system_control_circle(sys, j, z, 1, 1, 0, NULL) == PSYS_OK);
    CHECK(psys_system_set_fixed(sys, j, true) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "particle 1 is controlled; release it before fixing it");
    CHECK(psys_system_is_controlled(sys, j) && !psys_system_is_fixed(sys, j));
    /* no such particle */
    CHECK(psys_system_control_circle(sys, 7, z, 1, 1, 0, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "no particle 7");
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* callback controllers                                                 */
/* ------------------------------------------------------------------ */

typedef struct cb_rec {
    double c[2], R, w, ph;
    double times[64];
    int n;
} cb_rec;

static void cb_circle(void *ctx, double t, double *x, double *v)
{
    cb_rec *r = ctx;
    if (r->n < 64)
        r->times[r->n] = t;
    r->n++;
    double a = r->w * t + r->ph;
    x[0] = r->c[0] + r->R * cos(a);
    x[1] = r->c[1] + r->R * sin(a);
    v[0] = -r->R * r->w * sin(a);
    v[1] = r->R * r->w * cos(a);
}

/* Two identical mechanisms, one driven by the callback, one by the
 * built-in circle; returns the system with the callback. */
static psys_system *cb_system(cb_rec *rec, bool builtin)
{
    psys_system *sys = make_system(2);
    double z[2] = {0, 0}, xp[2] = {2, 1};
    size_t d = add_particle(sys, z, NULL, 1);
    size_t p = add_particle(sys, xp, NULL, 0.4);
    if (builtin)
        CHECK(psys_system_control_circle(sys, d, rec->c, rec->R, rec->w, rec->ph, NULL) == PSYS_OK);
    else
        CHECK(psys_system_control_callback(sys, d, cb_circle, rec) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, p, d, 25, 2, 1.2) == PSYS_OK);
    return sys;
}

static void test_callback_stage_times(void)
{
    cb_rec rec = {.c = {0.5, 0}, .R = 1, .w = 2.5, .ph = 0.3};
    psys_system *sys = cb_system(&rec, false);
    CHECK(psys_system_is_controlled(sys, 0));
    CHECK(rec.n >= 1); /* installing puts it on its path at once */
    const double t0 = 0.25, h = 0.1;
    psys_system_set_time(sys, t0);
    psys_system_apply_controllers(sys, t0);

    static const char *const names[] = {"rk4", "midpoint", "euler"};
    const double stage_c[3][4] = {{0, 0.5, 0.5, 1}, {0, 0.5, 0, 0}, {0, 0, 0, 0}};
    const int nst[3] = {4, 2, 1};
    for (int m = 0; m < 3; m++) {
        psys_system_set_time(sys, t0);
        psys_solver *s = make_solver(names[m], sys);
        rec.n = 0;
        CHECK(psys_system_advance(sys, s, h, NULL) == PSYS_OK);
        CHECK(rec.n >= nst[m] && rec.n <= 64);
        /* the stages, in order, at t + c_i h */
        for (int k = 0; k < nst[m] && k < rec.n; k++)
            CHECK_NEAR(rec.times[k], t0 + stage_c[m][k] * h, 1e-15);
        /* anything after the stages only puts the particle at the step's end */
        for (int k = nst[m]; k < rec.n && k < 64; k++)
            CHECK_NEAR(rec.times[k], t0 + h, 1e-15);
        fprintf(stderr, "  %s: %d calls, first at %.17g\n", names[m], rec.n, rec.times[0]);
        psys_solver_destroy(s);
    }
    psys_system_destroy(sys);

    /* the callback's x and v are used exactly like a built-in circle's */
    cb_rec r1 = rec, r2 = rec;
    psys_system *a = cb_system(&r1, false), *b = cb_system(&r2, true);
    psys_solver *sa = make_solver("rk4", a), *sb = make_solver("rk4", b);
    for (int k = 0; k < 100; k++) {
        CHECK(psys_system_advance(a, sa, 0.01, NULL) == PSYS_OK);
        CHECK(psys_system_advance(b, sb, 0.01, NULL) == PSYS_OK);
    }
    CHECK(maxdiff(psys_system_positions(a), psys_system_positions(b), 4) <= 1e-14);
    CHECK(maxdiff(psys_system_velocities(a), psys_system_velocities(b), 4) <= 1e-14);
    CHECK(fabs(psys_system_positions(a)[2] - 2) > 1e-2); /* it moved */
    psys_solver_destroy(sa);
    psys_solver_destroy(sb);
    psys_system_destroy(a);
    psys_system_destroy(b);
}

static void test_callback_scene_unsaveable(void)
{
    psys_scene *sc = load_scene("{\"psys\":1,\"dim\":2,\"particles\":[{\"id\":\"a\",\"x\":[1,0]},{\"x\":[0,0]}]}");
    cb_rec rec = {.c = {0, 0}, .R = 1, .w = 1, .ph = 0};
    psys_system *sys = psys_scene_system(sc);
    CHECK(psys_system_control_callback(sys, 1, NULL, NULL) == PSYS_ERR_INVALID);
    CHECK(psys_system_control_callback(sys, 1, cb_circle, &rec) == PSYS_OK);
    psys_error err;
    memset(&err, 0, sizeof err);
    char *text = psys_scene_to_string(sc, NULL, &err);
    CHECK(text == NULL);
    free(text);
    CHECK(err.code == PSYS_ERR_UNSUPPORTED);
    if (err.code != PSYS_ERR_UNSUPPORTED)
        fprintf(stderr, "  got code %d (%s): %s\n", (int)err.code, psys_status_name(err.code), err.message);
    CHECK(strstr(err.message, "callback") != NULL);
    /* once released it can be saved again */
    CHECK(psys_system_release(sys, 1) == PSYS_OK);
    text = psys_scene_to_string(sc, NULL, &err);
    CHECK(text != NULL);
    CHECK(err.code == PSYS_OK);
    free(text);
    psys_scene_destroy(sc);
}

/* ------------------------------------------------------------------ */
/* mouse springs                                                        */
/* ------------------------------------------------------------------ */

static void test_mouse_force_target(void)
{
    psys_system *sys = make_system(3);
    const double g[3] = {0, -9.81, 0};
    double x[3] = {1, 2, -0.5}, v[3] = {0.3, -0.1, 0.7};
    size_t i = add_particle(sys, x, v, 2);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    const double ks = 40, kd = 1.5, p[3] = {0.5, 2.5, 0};
    size_t h = 99;
    CHECK(psys_system_add_mouse_spring(sys, i, p, ks, kd, &h) == PSYS_OK);
    CHECK(h == 1);
    CHECK(psys_system_force_class(sys, h) == &psys_mouse_spring_class);
    double f[3];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(f[k], 2 * g[k] - ks * (x[k] - p[k]) - kd * v[k], 1e-12);
    /* energy: gravity + ½ks|x - p|² = 2·9.81·2 + 20·(0.25+0.25+0.25) */
    CHECK_NEAR(psys_system_potential_energy(sys), 2 * 9.81 * 2 + 0.5 * ks * 0.75, 1e-12);

    /* moving the target, with a target velocity */
    const double p2[3] = {-1, 0, 3}, pd[3] = {2, -1, 0.5};
    CHECK(psys_system_mouse_set_target(sys, h, p2, pd) == PSYS_OK);
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(f[k], 2 * g[k] - ks * (x[k] - p2[k]) - kd * (v[k] - pd[k]), 1e-12);
    double l2 = 0;
    for (int k = 0; k < 3; k++)
        l2 += (x[k] - p2[k]) * (x[k] - p2[k]);
    CHECK_NEAR(psys_system_potential_energy(sys), 2 * 9.81 * 2 + 0.5 * ks * l2, 1e-12);
    /* NULL velocity: target at rest */
    CHECK(psys_system_mouse_set_target(sys, h, p2, NULL) == PSYS_OK);
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(f[k], 2 * g[k] - ks * (x[k] - p2[k]) - kd * v[k], 1e-12);

    /* not a mouse spring */
    CHECK(psys_system_mouse_set_target(sys, 0, p2, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "force 0 is not a mouse spring");
    CHECK(psys_system_mouse_set_target(sys, 5, p2, NULL) == PSYS_ERR_INVALID);
    /* bad arguments */
    CHECK(psys_system_add_mouse_spring(sys, i, p, -1, kd, NULL) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_mouse_spring(sys, 3, p, ks, kd, NULL) == PSYS_ERR_INVALID);
    CHECK(psys_system_force_count(sys) == 2);

    /* releasing: only gravity is left */
    CHECK(psys_system_remove_force(sys, h) == PSYS_OK);
    CHECK(psys_system_force_count(sys) == 1);
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(f[k], 2 * g[k], 1e-15);
    CHECK_NEAR(psys_system_potential_energy(sys), 2 * 9.81 * 2, 1e-12);
    CHECK(psys_system_remove_force(sys, 1) == PSYS_ERR_INVALID);
    psys_system_destroy(sys);
}

static void test_mouse_force_path(void)
{
    psys_system *sys = make_system(2);
    double x[2] = {0.2, -0.3}, v[2] = {1, 2};
    size_t i = add_particle(sys, x, v, 1);
    const double ks = 12, kd = 0.75, p0[2] = {9, 9};
    size_t h;
    CHECK(psys_system_add_mouse_spring(sys, i, p0, ks, kd, &h) == PSYS_OK);
    /* target: (0,0) at t=0, (2,1) at t=1, (2,-3) at t=3 */
    const double path[] = {0, 0, 0, 1, 2, 1, 3, 2, -3};
    CHECK(psys_system_mouse_set_path(sys, h, path, 3) == PSYS_OK);
    struct {
        double t, p[2], pd[2];
    } want[] = {
        {-1, {0, 0}, {0, 0}},   {0.25, {0.5, 0.25}, {2, 1}}, {0.75, {1.5, 0.75}, {2, 1}},
        {1.5, {2, 0}, {0, -2}}, {2.9, {2, -2.8}, {0, -2}},   {3.5, {2, -3}, {0, 0}},
        {100, {2, -3}, {0, 0}},
    };
    for (size_t k = 0; k < sizeof want / sizeof want[0]; k++) {
        psys_system_set_time(sys, want[k].t);
        double f[2];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        double l2 = 0;
        for (int c = 0; c < 2; c++) {
            CHECK_NEAR(f[c], -ks * (x[c] - want[k].p[c]) - kd * (v[c] - want[k].pd[c]), 1e-12);
            l2 += (x[c] - want[k].p[c]) * (x[c] - want[k].p[c]);
        }
        CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * ks * l2, 1e-12);
    }
    /* bad paths */
    const double bad[] = {0, 0, 0, 0, 1, 1};
    CHECK(psys_system_mouse_set_path(sys, h, bad, 2) == PSYS_ERR_INVALID);
    CHECK(psys_system_mouse_set_path(sys, h, bad, 0) == PSYS_ERR_INVALID);
    psys_system_destroy(sys);
}

/* A particle dragged by a mouse spring whose target moves at constant
 * velocity u: with e = x - p, m ë = -ks e - kd ė (the damping acts on the
 * velocity relative to the target), so from rest at p(0) (e = 0, ė = -u)
 *   e(t) = -u e^{-γt} sin(ω_d t)/ω_d,  γ = kd/2m, ω_d = √(ks/m - γ²):
 * it catches up with no steady lag (a spring damped against the absolute
 * velocity would lag by kd u/ks). The target path p(t) = u t is keyframed
 * from t_start (≤ 0) to 10. Returns the worst deviation over 0 < t ≤ 3. */
static const double drag_m = 1, drag_ks = 100, drag_kd = 4, drag_u[2] = {1, 0.5};

static double drag_worst(double t_start, bool check_energy, double *lag)
{
    const double *u = drag_u;
    const double gam = drag_kd / (2 * drag_m), wd = sqrt(drag_ks / drag_m - gam * gam);
    psys_system *sys = make_system(2);
    double z[2] = {0, 0};
    size_t i = add_particle(sys, z, NULL, drag_m), h;
    CHECK(psys_system_add_mouse_spring(sys, i, z, drag_ks, drag_kd, &h) == PSYS_OK);
    const double path[] = {t_start, t_start * u[0], t_start * u[1], 10, 10 * u[0], 10 * u[1]};
    CHECK(psys_system_mouse_set_path(sys, h, path, 2) == PSYS_OK);
    psys_solver *s = make_solver("rk4", sys);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    double worst = 0;
    for (int step = 1; step <= 3000; step++) {
        CHECK(psys_system_advance(sys, s, 1e-3, NULL) == PSYS_OK);
        if (step % 100)
            continue;
        double t = psys_system_time(sys), E = exp(-gam * t);
        for (int c = 0; c < 2; c++) {
            double e = -u[c] * E * sin(wd * t) / wd;
            double ed = -u[c] * E * (cos(wd * t) - gam / wd * sin(wd * t));
            worst = fmax(worst, fabs(X[c] - (u[c] * t + e)));
            worst = fmax(worst, fabs(V[c] - (u[c] + ed)));
        }
        if (check_energy) { /* energy is ½ks|x - p(t)|² */
            double l2 = 0;
            for (int c = 0; c < 2; c++)
                l2 += (X[c] - u[c] * t) * (X[c] - u[c] * t);
            CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * drag_ks * l2, 1e-12);
        }
    }
    if (lag) /* at t = 3 */
        *lag = hypot(X[0] - 3 * u[0], X[1] - 3 * u[1]);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return worst;
}

static void test_mouse_drag_follows(void)
{
    const double *u = drag_u;
    double lag = 1;
    double worst = drag_worst(-1.0, true, &lag);
    fprintf(stderr, "  moving target: worst deviation from closed form %.3g, lag at t=3 %.3g\n", worst, lag);
    CHECK(worst <= 1e-8);
    /* at t = 3 the lag is e^{-6}/ω_d-small, far below kd|u|/ks */
    CHECK(lag < 1e-3);
    CHECK(lag < 0.05 * drag_kd * hypot(u[0], u[1]) / drag_ks);

    /* the path stops at t = 1: the particle settles on its last point */
    psys_system *sys = make_system(2);
    double z[2] = {0, 0};
    size_t i = add_particle(sys, z, NULL, drag_m), h;
    CHECK(psys_system_add_mouse_spring(sys, i, z, drag_ks, drag_kd, &h) == PSYS_OK);
    const double short_path[] = {-1, -u[0], -u[1], 1, u[0], u[1]};
    CHECK(psys_system_mouse_set_path(sys, h, short_path, 2) == PSYS_OK);
    psys_solver *s = make_solver("rk4", sys);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    for (int step = 0; step < 8000; step++)
        CHECK(psys_system_advance(sys, s, 1e-3, NULL) == PSYS_OK);
    CHECK_NEAR(X[0], u[0], 1e-5);
    CHECK_NEAR(X[1], u[1], 1e-5);
    CHECK_NEAR(V[0], 0, 1e-5);
    CHECK_NEAR(V[1], 0, 1e-5);
    CHECK_NEAR(psys_system_potential_energy(sys), 0, 1e-9);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* Keyframed paths are stepped forward in time, so the velocity at a knot is
 * the one going forward from it (right-continuous): at an interior knot the
 * next segment's slope, at the last knot 0 (held) — and at the FIRST knot
 * the first segment's slope, not the hold value 0. Otherwise the first
 * stage of a step starting on the first knot (a scene whose scripted path
 * starts at t = 0, the usual case) sees a target or controller at rest, and
 * rk4 loses its order for that step. */
static void test_path_first_frame_velocity(void)
{
    psys_system *sys = make_system(2);
    double z[2] = {0, 0};
    size_t i = add_particle(sys, z, NULL, 1);
    const double fr[] = {0, 0, 0, 1, 2, 1, 3, 2, -3};
    CHECK(psys_system_control_keyframes(sys, i, fr, 3) == PSYS_OK);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    const struct {
        double t, x[2], v[2];
    } want[] = {{0, {0, 0}, {2, 1}}, {1, {2, 1}, {0, -2}}, {3, {2, -3}, {0, 0}}};
    for (int k = 0; k < 3; k++) {
        psys_system_apply_controllers(sys, want[k].t);
        for (int c = 0; c < 2; c++) {
            CHECK_NEAR(X[c], want[k].x[c], 1e-15);
            CHECK_NEAR(V[c], want[k].v[c], 1e-15);
        }
    }
    /* the same for a mouse-spring path: f = -ks(x - p) - kd(v - ṗ) at t = 0 */
    size_t j = add_particle(sys, z, NULL, 1), h;
    CHECK(psys_system_add_mouse_spring(sys, j, z, 10, 3, &h) == PSYS_OK);
    CHECK(psys_system_mouse_set_path(sys, h, fr, 3) == PSYS_OK);
    psys_system_set_time(sys, 0);
    psys_system_apply_controllers(sys, 0);
    double f[4];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    CHECK_NEAR(f[2], 3 * 2, 1e-15);
    CHECK_NEAR(f[3], 3 * 1, 1e-15);
    psys_system_destroy(sys);

    /* end to end: the drag of test mouse_drag_follows with the path starting
     * exactly at t = 0 must be as accurate as with a path starting earlier */
    double worst = drag_worst(0.0, false, NULL);
    fprintf(stderr, "  path from t = 0: worst deviation from closed form %.3g\n", worst);
    CHECK(worst <= 1e-8);
}

/* ------------------------------------------------------------------ */
/* scenes                                                               */
/* ------------------------------------------------------------------ */

static const char scene2d[] =
    "{\"psys\":1,\"dim\":2,\"integrator\":\"rk4\",\"dt\":0.01,\"steps\":25,"
    "\"particles\":["
    "{\"id\":\"c\",\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[1,2],\"radius\":0.5,\"omega\":2,"
    "\"phase\":0.25}},"
    "{\"id\":\"o\",\"x\":[0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,1],\"direction\":[0,2],"
    "\"amplitude\":0.3,\"omega\":5,\"phase\":0.1}},"
    "{\"id\":\"k\",\"x\":[0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0,0,0],[0.1,1,0.25],"
    "[0.3,-1,2]]}},"
    "{\"id\":\"anchor\",\"x\":[0,3],\"fixed\":true},"
    "{\"id\":\"p\",\"x\":[0.5,0.5],\"v\":[0.1,0],\"mass\":0.7},"
    "{\"id\":\"q\",\"x\":[-0.5,0.5],\"mass\":1.3},"
    "{\"x\":[0.1,0.2],\"mass\":0.9}],"
    "\"forces\":["
    "{\"type\":\"gravity\",\"g\":[0,-9.81]},"
    "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"c\",\"ks\":40,\"kd\":0.5,\"rest\":1},"
    "{\"type\":\"spring\",\"a\":\"q\",\"b\":\"o\",\"ks\":40,\"kd\":0.5},"
    "{\"type\":\"spring\",\"a\":6,\"b\":\"k\",\"ks\":30,\"kd\":0.2},"
    "{\"type\":\"spring\",\"a\":\"q\",\"b\":\"anchor\",\"ks\":5,\"kd\":0.1},"
    "{\"type\":\"mouse-spring\",\"particle\":\"p\",\"ks\":20,\"kd\":1,\"target\":[0.3,0.7]},"
    "{\"type\":\"mouse-spring\",\"particle\":6,\"ks\":15,\"path\":[[0,-0.5,0.5],[0.1,0.5,1.5],[0.2,0.7,0.2]]}]}";

static const char scene3d[] =
    "{\"psys\":1,\"dim\":3,\"integrator\":\"verlet\",\"dt\":0.01,\"duration\":0.2,"
    "\"particles\":["
    "{\"id\":\"c\",\"x\":[0,0,0],\"control\":{\"type\":\"circle\",\"center\":[1,2,3],\"radius\":0.5,"
    "\"omega\":2,\"axis\":[1,1,1]}},"
    "{\"id\":\"c2\",\"x\":[0,0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0,0],\"radius\":1,"
    "\"omega\":-1,\"phase\":3}},"
    "{\"id\":\"o\",\"x\":[0,0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,1,0],\"direction\":[1,2,2],"
    "\"amplitude\":0.3,\"omega\":5}},"
    "{\"id\":\"k\",\"x\":[0,0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0.05,0,0,0],[0.15,1,0.25,-1]]}},"
    "{\"id\":\"p\",\"x\":[0.5,0.5,0.5],\"mass\":0.7}],"
    "\"forces\":["
    "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"c\",\"ks\":40,\"kd\":0.5},"
    "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"o\",\"ks\":40,\"kd\":0.5},"
    "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"k\",\"ks\":40,\"kd\":0.5},"
    "{\"type\":\"mouse-spring\",\"particle\":\"p\",\"ks\":20,\"kd\":1,\"target\":[0.3,0.7,0.1]},"
    "{\"type\":\"mouse-spring\",\"particle\":\"p\",\"ks\":15,\"kd\":2,\"path\":[[0,0,0,0],[0.1,0.5,1.5,1]]}]}";

static void run_to_end(psys_scene *sc)
{
    psys_error err;
    psys_run *r = psys_run_create(sc, &err);
    CHECK(r != NULL);
    while (r && !psys_run_done(r))
        if (psys_run_step(r, &err) != PSYS_OK) {
            CHECK(!"run step failed");
            break;
        }
    psys_run_destroy(r);
}

static void round_trip(const char *text, size_t want_mice)
{
    psys_scene *a = load_scene(text);
    char *s1 = save_scene(a);
    if (!s1) {
        psys_scene_destroy(a);
        return;
    }
    psys_scene *b = load_scene(s1);
    char *s2 = save_scene(b);
    CHECK_STR(s2, s1);
    if (s2 && strcmp(s1, s2) != 0) {
        /* show the first differing line */
        const char *x = s1, *y = s2;
        while (*x && *x == *y) {
            x++;
            y++;
        }
        while (x > s1 && x[-1] != '\n') {
            x--;
            y--;
        }
        fprintf(stderr, "  first difference:\n  saved once:  %.80s\n  saved twice: %.80s\n", x, y);
    }
    /* every controller and mouse spring came back */
    psys_system *sa = psys_scene_system(a), *sb = psys_scene_system(b);
    CHECK(psys_system_count(sa) == psys_system_count(sb));
    CHECK(psys_system_force_count(sa) == psys_system_force_count(sb));
    for (size_t i = 0; i < psys_system_count(sa) && i < psys_system_count(sb); i++) {
        CHECK(psys_system_is_controlled(sa, i) == psys_system_is_controlled(sb, i));
        CHECK(psys_system_is_fixed(sa, i) == psys_system_is_fixed(sb, i));
    }
    size_t mice = 0;
    for (size_t k = 0; k < psys_system_force_count(sb); k++)
        mice += psys_system_force_class(sb, k) == &psys_mouse_spring_class;
    CHECK(mice == want_mice);
    /* the reloaded scene is the same system: same run to the last bit */
    run_to_end(a);
    run_to_end(b);
    size_t nd = psys_system_count(sa) * (size_t)psys_system_dim(sa);
    if (psys_system_count(sa) == psys_system_count(sb)) {
        CHECK(memcmp(psys_system_positions(sa), psys_system_positions(sb), nd * sizeof(double)) == 0);
        CHECK(memcmp(psys_system_velocities(sa), psys_system_velocities(sb), nd * sizeof(double)) == 0);
    }
    free(s1);
    free(s2);
    psys_scene_destroy(a);
    psys_scene_destroy(b);
}

static void test_scene_round_trip(void)
{
    round_trip(scene2d, 2);
    round_trip(scene3d, 2);
}

/* Oscillation directions and circle axes are normalised on load; saving the
 * normalised vector and loading it again must not change the system (a
 * renormalised unit vector can differ in its last bit, which would make the
 * reloaded run differ from the original). */
static void test_scene_round_trip_tilted(void)
{
    round_trip("{\"psys\":1,\"dim\":2,\"steps\":10,\"dt\":0.01,\"particles\":["
               "{\"id\":\"o\",\"x\":[0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,1],"
               "\"direction\":[1,1],\"amplitude\":0.3,\"omega\":5}},"
               "{\"id\":\"o2\",\"x\":[0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,1],"
               "\"direction\":[1,3],\"amplitude\":0.3,\"omega\":5}},"
               "{\"id\":\"p\",\"x\":[1,1]}],"
               "\"forces\":[{\"type\":\"spring\",\"a\":\"p\",\"b\":\"o\",\"ks\":40,\"kd\":0.5},"
               "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"o2\",\"ks\":40,\"kd\":0.5}]}",
               0);
    round_trip("{\"psys\":1,\"dim\":3,\"steps\":10,\"dt\":0.01,\"particles\":["
               "{\"id\":\"c\",\"x\":[0,0,0],\"control\":{\"type\":\"circle\",\"center\":[1,2,3],"
               "\"radius\":0.5,\"omega\":2,\"axis\":[1,1,0]}},"
               "{\"id\":\"c2\",\"x\":[0,0,0],\"control\":{\"type\":\"circle\",\"center\":[1,2,3],"
               "\"radius\":0.5,\"omega\":2,\"axis\":[1,5,7]}},"
               "{\"id\":\"p\",\"x\":[1,1,1]}],"
               "\"forces\":[{\"type\":\"spring\",\"a\":\"p\",\"b\":\"c\",\"ks\":40,\"kd\":0.5},"
               "{\"type\":\"spring\",\"a\":\"p\",\"b\":\"c2\",\"ks\":40,\"kd\":0.5}]}",
               0);
}

/* The scene's controllers are the ones of docs/semantics.md#controller-paths
 * (loaded values). */
static void test_scene_control_values(void)
{
    psys_scene *sc = load_scene(scene2d);
    psys_system *sys = psys_scene_system(sc);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    const double t = 0.0625;
    psys_system_apply_controllers(sys, t);
    const double u[2] = {1, 0}, wv[2] = {0, 1}, c[2] = {1, 2};
    double x[2], v[2];
    circle_at(2, c, 0.5, 2, 0.25, u, wv, t, x, v);
    CHECK(maxdiff(X, x, 2) <= 1e-15 && maxdiff(V, v, 2) <= 1e-15);
    const double a = 5 * t + 0.1; /* direction [0, 2] -> (0, 1) */
    CHECK_NEAR(X[2], 0, 1e-15);
    CHECK_NEAR(X[3], 1 + 0.3 * sin(a), 1e-15);
    CHECK_NEAR(V[2], 0, 1e-15);
    CHECK_NEAR(V[3], 0.3 * 5 * cos(a), 1e-15);
    CHECK_NEAR(X[4], 0.625, 1e-15);
    CHECK_NEAR(X[5], 0.15625, 1e-15);
    CHECK_NEAR(V[4], 10, 1e-13);
    CHECK_NEAR(V[5], 2.5, 1e-13);
    CHECK(psys_system_is_fixed(sys, 3) && !psys_system_is_controlled(sys, 3));
    psys_scene_destroy(sc);
}

#define P2 "{\"psys\":1,\"dim\":2,\"particles\":["
#define P3 "{\"psys\":1,\"dim\":3,\"particles\":["

static void test_scene_bad_inputs(void)
{
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"spiral\"}}]}"),
              "particles[0].control.type: unknown control type (known: circle, oscillate, keyframes) "
              "(got \"spiral\")");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"radius\":1}}]}"),
              "particles[0].control.type: required key missing");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"radius\":1,\"omega\":1}}]}"),
              "particles[0].control.center: required key missing");
    CHECK_STR(load_error(P2 "{\"x\":[0,0]},{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0],"
                            "\"omega\":1}}]}"),
              "particles[1].control.radius: required key missing");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0],\"radius\":1}}]}"),
              "particles[0].control.omega: required key missing");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0],\"radius\":-1,"
                            "\"omega\":1}}]}"),
              "particles[0].control.radius: must be >= 0 (got -1)");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0],\"radius\":1,"
                            "\"omega\":1,\"speed\":2}}]}"),
              "particles[0].control.speed: unknown key");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,0],"
                            "\"direction\":[0,0],\"amplitude\":1,\"omega\":1}}]}"),
              "particles[0].control.direction: must be a nonzero vector (got [0,0])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"oscillate\",\"center\":[0,0],"
                            "\"amplitude\":1,\"omega\":1}}]}"),
              "particles[0].control.direction: required key missing");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"fixed\":true,\"control\":{\"type\":\"circle\",\"center\":[0,0],"
                            "\"radius\":1,\"omega\":1}}]}"),
              "particles[0].control: a particle cannot be both fixed and controlled");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0.5,0,0],[0.5,1,1]]}}]}"),
              "particles[0].control.frames[1]: frame times must increase strictly (got [0.5,1,1])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0,0,0],[1,1,1],"
                            "[0.5,2,2]]}}]}"),
              "particles[0].control.frames[2]: frame times must increase strictly (got [0.5,2,2])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0,1]]}}]}"),
              "particles[0].control.frames[0]: must be [t, x, y] (3 numbers) (got [0,1])");
    CHECK_STR(load_error(P3 "{\"x\":[0,0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[[0,1,2,3],"
                            "[1,1,2]]}}]}"),
              "particles[0].control.frames[1]: must be [t, x, y, z] (4 numbers) (got [1,1,2])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"keyframes\",\"frames\":[]}}]}"),
              "particles[0].control.frames: must be a non-empty array of frames [t, x...] (got [])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0],\"control\":{\"type\":\"circle\",\"center\":[0,0],\"radius\":1,"
                            "\"omega\":1,\"axis\":[0,0,1]}}]}"),
              "particles[0].control.axis: is only used in 3-D scenes (dim is 2) (got [0,0,1])");
    /* mouse springs: exactly one of target and path */
    CHECK_STR(load_error(P2 "{\"x\":[0,0]}],\"forces\":[{\"type\":\"mouse-spring\",\"particle\":0,\"ks\":1,"
                            "\"target\":[0,0],\"path\":[[0,0,0]]}]}"),
              "forces[0]: give exactly one of target or path");
    CHECK_STR(load_error(P2 "{\"x\":[0,0]}],\"forces\":[{\"type\":\"gravity\"},{\"type\":\"mouse-spring\","
                            "\"particle\":0,\"ks\":1}]}"),
              "forces[1]: give exactly one of target or path");
    CHECK_STR(load_error(P2 "{\"x\":[0,0]}],\"forces\":[{\"type\":\"mouse-spring\",\"particle\":0,\"ks\":1,"
                            "\"path\":[[1,0,0],[0,1,1]]}]}"),
              "forces[0].path[1]: frame times must increase strictly (got [0,1,1])");
    CHECK_STR(load_error(P2 "{\"x\":[0,0]}],\"forces\":[{\"type\":\"mouse-spring\",\"particle\":0,"
                            "\"target\":[0,0]}]}"),
              "forces[0].ks: required key missing");
}

static const check_case cases[] = {
    {"circle_2d_run", test_circle_2d_run},
    {"circle_3d_axis", test_circle_3d_axis},
    {"oscillate_run", test_oscillate_run},
    {"keyframes_run", test_keyframes_run},
    {"on_path_through_bounces", test_on_path_through_bounces},
    {"errata_controller_velocity", test_errata_controller_velocity},
    {"energy_excludes_controlled", test_energy_excludes_controlled},
    {"release_makes_free", test_release_makes_free},
    {"fixed_cannot_be_controlled", test_fixed_cannot_be_controlled},
    {"callback_stage_times", test_callback_stage_times},
    {"callback_scene_unsaveable", test_callback_scene_unsaveable},
    {"mouse_force_target", test_mouse_force_target},
    {"mouse_force_path", test_mouse_force_path},
    {"mouse_drag_follows", test_mouse_drag_follows},
    {"path_first_frame_velocity", test_path_first_frame_velocity},
    {"scene_round_trip", test_scene_round_trip},
    {"scene_round_trip_tilted", test_scene_round_trip_tilted},
    {"scene_control_values", test_scene_control_values},
    {"scene_bad_inputs", test_scene_bad_inputs},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
