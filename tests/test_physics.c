/* Physics of particle systems built through the C API, pinned against closed
 * forms: projectiles, drag decay, damped oscillators, conservation of
 * momentum and energy, fixed particles, per-particle masses
 * (docs/notes-errata.md#3-particlederivative-each-particles-own-mass). */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

static const char *const all_solvers[] = {"euler", "midpoint", "rk4", "symplectic-euler", "verlet", "rk45"};
#define NSOLVERS (sizeof all_solvers / sizeof all_solvers[0])

/* Integrate sys with solver `name` over T = n h: fixed-step solvers take n
 * steps of h; adaptive ones step with h_max = min(h, T - t) until they land
 * on T. Returns the steps taken. */
static long run_to(psys_system *sys, const char *name, double h, long nsteps, double tol)
{
    psys_ode ode = psys_system_ode(sys);
    psys_solver *s = make_ode_solver(name, &ode);
    long taken = 0;
    if (psys_solver_is_adaptive(s)) {
        CHECK(psys_solver_set_tolerance(s, tol) == PSYS_OK);
        double T = psys_system_time(sys) + h * (double)nsteps;
        while (psys_system_time(sys) < T) {
            double t = psys_system_time(sys), hmax = fmin(h, T - t), ht = 0;
            psys_status st = psys_solver_step(s, hmax, &ht);
            CHECK(st == PSYS_OK);
            if (st != PSYS_OK)
                break;
            CHECK(ht > 0 && ht <= hmax);
            taken++;
        }
    } else {
        for (long k = 0; k < nsteps; k++) {
            double ht = 0;
            psys_status st = psys_solver_step(s, h, &ht);
            CHECK(st == PSYS_OK);
            CHECK(ht == h);
            if (st != PSYS_OK)
                break;
            taken++;
        }
    }
    psys_solver_destroy(s);
    return taken;
}

/* ------------------------------------------------------------------ */
/* 1. Projectile: x(t) = x0 + v0 t + g t²/2, v(t) = v0 + g t.           */
/* ------------------------------------------------------------------ */

/* Explicit Euler under constant g: v_n = v0 + n h g exactly, and
 * x_n = x0 + n h v0 + h² g Σ_{k<n} k = x(t_n) − g h t_n / 2.
 * Symplectic Euler uses v_{k+1}: x_n = x0 + n h v0 + h² g Σ_{k<=n} k
 * = x(t_n) + g h t_n / 2. Midpoint, RK4, Verlet and DP5 integrate a
 * quadratic exactly. */
static double projectile_offset(const char *name, double g, double h, double t)
{
    if (strcmp(name, "euler") == 0)
        return -0.5 * g * h * t;
    if (strcmp(name, "symplectic-euler") == 0)
        return 0.5 * g * h * t;
    return 0.0;
}

static void projectile(int dim)
{
    const double x0[2][3] = {{1.0, 2.0, -0.5}, {-0.25, 0.75, 3.0}};
    const double v0[2][3] = {{3.0, 12.0, -1.5}, {-2.0, 5.0, 0.5}};
    const double g[3] = {0.75, -9.81, 1.25};
    const double masses[2] = {0.3, 7.0};
    const double h = 1.0 / 64;
    const long n = 128;
    const double T = h * (double)n;
    for (size_t si = 0; si < NSOLVERS; si++) {
        const char *name = all_solvers[si];
        psys_system *sys = make_system(dim);
        for (int p = 0; p < 2; p++)
            add_particle(sys, x0[p], v0[p], masses[p]);
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        run_to(sys, name, h, n, 1e-8);
        CHECK_NEAR(psys_system_time(sys), T, 1e-12);
        const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
        for (int p = 0; p < 2; p++)
            for (int k = 0; k < dim; k++) {
                double exact_x = x0[p][k] + v0[p][k] * T + 0.5 * g[k] * T * T;
                double exact_v = v0[p][k] + g[k] * T;
                double want_x = exact_x + projectile_offset(name, g[k], h, T);
                /* Rounding over n steps of values of size ~20: far below
                 * Euler's O(h) offset (~0.15 here). */
                double tol = 1e-12 * (1.0 + fabs(exact_x));
                if (!(fabs(x[p * dim + k] - want_x) <= tol))
                    fprintf(stderr, "  solver %s particle %d axis %d\n", name, p, k);
                CHECK_NEAR(x[p * dim + k], want_x, tol);
                CHECK_NEAR(v[p * dim + k], exact_v, 1e-12 * (1.0 + fabs(exact_v)));
            }
        psys_system_destroy(sys);
    }
}

static void projectile_2d(void) { projectile(2); }
static void projectile_3d(void) { projectile(3); }

/* ------------------------------------------------------------------ */
/* 2. Drag: m v' = −kd v (+ m g).                                       */
/* ------------------------------------------------------------------ */

static void drag_decay(void)
{
    const double m = 2.5, kd = 0.7, x0[3] = {0.5, -1.0, 2.0}, v0[3] = {3.0, -1.0, 2.0};
    const double h = 0.01;
    const long n = 200;
    const double T = h * (double)n, tau = m / kd;
    psys_system *sys = make_system(3);
    add_particle(sys, x0, v0, m);
    CHECK(psys_system_add_drag(sys, kd) == PSYS_OK);
    run_to(sys, "rk4", h, n, 0);
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    double decay = exp(-T / tau);
    for (int k = 0; k < 3; k++) {
        CHECK_NEAR(v[k], v0[k] * decay, 1e-10);
        CHECK_NEAR(x[k], x0[k] + v0[k] * tau * (1.0 - decay), 1e-10);
    }
    psys_system_destroy(sys);
}

/* With gravity too: v(t) = v∞ + (v0 − v∞) e^{−t/τ}, v∞ = m g / kd, τ = m/kd,
 * x(t) = x0 + v∞ t + (v0 − v∞) τ (1 − e^{−t/τ}). Two particles of different
 * mass reach different terminal velocities. */
static void drag_gravity_terminal(void)
{
    const double kd = 0.4, g[2] = {0.5, -9.81};
    const double masses[2] = {0.2, 3.0};
    const double x0[2] = {0.0, 10.0}, v0[2] = {1.0, 4.0};
    const double h = 0.005;
    const long n = 600;
    const double T = h * (double)n;
    psys_system *sys = make_system(2);
    add_particle(sys, x0, v0, masses[0]);
    add_particle(sys, x0, v0, masses[1]);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, kd) == PSYS_OK);
    run_to(sys, "rk4", h, n, 0);
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    for (int p = 0; p < 2; p++) {
        double tau = masses[p] / kd, e = exp(-T / tau);
        for (int k = 0; k < 2; k++) {
            double vinf = masses[p] * g[k] / kd;
            CHECK_NEAR(v[p * 2 + k], vinf + (v0[k] - vinf) * e, 1e-10 * (1 + fabs(vinf)));
            CHECK_NEAR(x[p * 2 + k], x0[k] + vinf * T + (v0[k] - vinf) * tau * (1 - e),
                       1e-10 * (1 + fabs(vinf) * T));
        }
    }
    /* The light particle (τ = 0.5) is near its terminal velocity, the heavy
     * one (τ = 7.5) far from it. */
    CHECK(fabs(v[1] - masses[0] * g[1] / kd) < 0.01 * fabs(v0[1] - masses[0] * g[1] / kd));
    CHECK(fabs(v[3] - masses[1] * g[1] / kd) > 0.5 * fabs(v0[1] - masses[1] * g[1] / kd));
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 3. Damped oscillator: particle on an eq. 1 spring to a fixed anchor. */
/* ------------------------------------------------------------------ */

/* m u'' + kd u' + ks u = 0 with u = |l| − r, motion along a line through
 * the anchor. Underdamped: u = e^{−ζω t}(u0 cos ωd t + (u̇0 + ζω u0)/ωd sin ωd t). */
static void damped_oscillator_case(int dim, const double *dir, bool anchor_first)
{
    const double m = 1.5, ks = 60.0, kd = 1.2, r = 2.0, u0 = 0.4, w0 = -0.9;
    const double h = 1e-3;
    const long n = 3000;
    const double T = h * (double)n;
    const double omega = sqrt(ks / m), zeta = kd / (2 * sqrt(ks * m));
    const double wd = omega * sqrt(1 - zeta * zeta);
    CHECK(zeta > 0.05 && zeta < 1);
    const double c[3] = {0.3, -0.2, 0.1}; /* anchor position */
    double xp[3], vp[3];
    for (int k = 0; k < dim; k++) {
        xp[k] = c[k] + (r + u0) * dir[k];
        vp[k] = w0 * dir[k];
    }
    psys_system *sys = make_system(dim);
    size_t ia, ip;
    if (anchor_first) {
        ia = add_particle(sys, c, NULL, 5.0);
        ip = add_particle(sys, xp, vp, m);
    } else {
        ip = add_particle(sys, xp, vp, m);
        ia = add_particle(sys, c, NULL, 5.0);
    }
    CHECK(psys_system_set_fixed(sys, ia, true) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, ia, ip, ks, kd, r) == PSYS_OK);
    run_to(sys, "rk4", h, n, 0);
    double e = exp(-zeta * omega * T);
    double u = e * (u0 * cos(wd * T) + (w0 + zeta * omega * u0) / wd * sin(wd * T));
    double ud = e * (w0 * cos(wd * T) - (omega * u0 + zeta * w0) / sqrt(1 - zeta * zeta) * sin(wd * T));
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    for (int k = 0; k < dim; k++) {
        CHECK_NEAR(x[ip * dim + k], c[k] + (r + u) * dir[k], 1e-9);
        CHECK_NEAR(v[ip * dim + k], ud * dir[k], 1e-9);
        CHECK(x[ia * dim + k] == c[k]);
    }
    /* Not vacuous: the amplitude decayed but the particle still moves. */
    CHECK(fabs(u) < 0.5 * sqrt(u0 * u0 + (w0 / omega) * (w0 / omega)));
    psys_system_destroy(sys);
}

static void damped_oscillator_2d(void)
{
    const double ex[2] = {1.0, 0.0};
    damped_oscillator_case(2, ex, true);
    damped_oscillator_case(2, ex, false);
}

static void damped_oscillator_3d(void)
{
    const double dir[3] = {2.0 / 3, -1.0 / 3, 2.0 / 3};
    damped_oscillator_case(3, dir, true);
    damped_oscillator_case(3, dir, false);
}

/* Overdamped (ζ > 1): u = A e^{s1 t} + B e^{s2 t}, s = ω(−ζ ± √(ζ²−1)). */
static void overdamped_oscillator(void)
{
    const double m = 0.5, ks = 8.0, kd = 10.0, r = 1.0, u0 = 0.3, w0 = 0.5;
    const double h = 1e-3;
    const long n = 2000;
    const double T = h * (double)n;
    const double omega = sqrt(ks / m), zeta = kd / (2 * sqrt(ks * m));
    CHECK(zeta > 1);
    const double s1 = omega * (-zeta + sqrt(zeta * zeta - 1)), s2 = omega * (-zeta - sqrt(zeta * zeta - 1));
    const double B = (w0 - s1 * u0) / (s2 - s1), A = u0 - B;
    const double anchor[2] = {0, 0}, xp[2] = {0, -(r + u0)}, vp[2] = {0, -w0};
    psys_system *sys = make_system(2);
    add_particle(sys, anchor, NULL, 1.0);
    add_particle(sys, xp, vp, m);
    psys_system_set_fixed(sys, 0, true);
    CHECK(psys_system_add_spring(sys, 0, 1, ks, kd, r) == PSYS_OK);
    run_to(sys, "rk4", h, n, 0);
    double u = A * exp(s1 * T) + B * exp(s2 * T), ud = A * s1 * exp(s1 * T) + B * s2 * exp(s2 * T);
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    CHECK_NEAR(x[2], 0.0, 0.0);
    CHECK_NEAR(x[3], -(r + u), 1e-12);
    CHECK_NEAR(v[3], -ud, 1e-12);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 6. Momentum of a free damped spring pair.                            */
/* ------------------------------------------------------------------ */

static void momentum_spring_pair(void)
{
    const double m[2] = {1.5, 0.4};
    const double x0[2][3] = {{0.0, 0.0, 0.0}, {1.2, 0.3, -0.4}};
    const double v0[2][3] = {{0.2, -0.1, 0.3}, {-0.7, 0.9, 0.25}};
    const double h = 0.005;
    const long n = 400;
    const double T = h * (double)n;
    double P[3], X[3], M = m[0] + m[1];
    for (int k = 0; k < 3; k++) {
        P[k] = m[0] * v0[0][k] + m[1] * v0[1][k];
        X[k] = (m[0] * x0[0][k] + m[1] * x0[1][k]) / M;
    }
    for (size_t si = 0; si < NSOLVERS; si++) {
        const char *name = all_solvers[si];
        psys_system *sys = make_system(3);
        add_particle(sys, x0[0], v0[0], m[0]);
        add_particle(sys, x0[1], v0[1], m[1]);
        CHECK(psys_system_add_spring(sys, 0, 1, 40.0, 0.8, 1.0) == PSYS_OK);
        run_to(sys, name, h, n, 1e-9);
        const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
        double rel_speed0 = 0, rel_speed = 0;
        for (int k = 0; k < 3; k++) {
            double p = m[0] * v[k] + m[1] * v[3 + k];
            double xc = (m[0] * x[k] + m[1] * x[3 + k]) / M;
            if (!(fabs(p - P[k]) <= 1e-13))
                fprintf(stderr, "  solver %s axis %d\n", name, k);
            CHECK_NEAR(p, P[k], 1e-13);
            CHECK_NEAR(xc, X[k] + P[k] / M * T, 1e-13);
            rel_speed0 += (v0[0][k] - v0[1][k]) * (v0[0][k] - v0[1][k]);
            rel_speed += (v[k] - v[3 + k]) * (v[k] - v[3 + k]);
        }
        /* Not vacuous: the spring did exchange momentum between the two. */
        CHECK(fabs(sqrt(rel_speed) - sqrt(rel_speed0)) > 0.05);
        psys_system_destroy(sys);
    }
}

/* ------------------------------------------------------------------ */
/* 8. Fixed particles never move.                                       */
/* ------------------------------------------------------------------ */

static void fixed_particles_stay(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (size_t si = 0; si < NSOLVERS; si++) {
            const char *name = all_solvers[si];
            psys_system *sys = make_system(dim);
            const double pts[5][3] = {
                {0, 0, 0}, {1, 0.2, 0.1}, {2, -0.3, 0.4}, {3, 0.1, -0.2}, {1.5, 1.0, 0.3}};
            const double vel[5][3] = {
                {0.5, 0.5, 0.5}, {0, 1, 0}, {0.3, 0, -1}, {-0.2, 0.4, 0}, {1, 1, 1}};
            for (int p = 0; p < 5; p++)
                add_particle(sys, pts[p], vel[p], 0.5 + 0.25 * p);
            const size_t fixed[2] = {0, 3};
            for (int q = 0; q < 2; q++) {
                CHECK(psys_system_set_fixed(sys, fixed[q], true) == PSYS_OK);
                CHECK(psys_system_is_fixed(sys, fixed[q]));
            }
            const double g[3] = {0.1, -9.81, 0.3};
            CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
            CHECK(psys_system_add_drag(sys, 0.05) == PSYS_OK);
            CHECK(psys_system_add_spring(sys, 0, 1, 50, 0.5, 0.8) == PSYS_OK);
            CHECK(psys_system_add_spring(sys, 1, 2, 50, 0.5, -1) == PSYS_OK);
            CHECK(psys_system_add_spring(sys, 2, 3, 80, 0.2, 1.5) == PSYS_OK);
            CHECK(psys_system_add_spring(sys, 0, 3, 80, 0.2, 1.0) == PSYS_OK); /* fixed–fixed */
            CHECK(psys_system_add_spring(sys, 4, 0, 30, 0.1, -1) == PSYS_OK);
            double keep[2][3];
            const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
            for (int q = 0; q < 2; q++) {
                memcpy(keep[q], x + fixed[q] * dim, sizeof(double) * (size_t)dim);
                for (int k = 0; k < dim; k++)
                    CHECK(v[fixed[q] * dim + k] == 0.0); /* set_fixed zeroes velocity */
            }
            double free0 = x[1 * dim + 1];
            run_to(sys, name, 0.002, 250, 1e-7);
            x = psys_system_positions(sys);
            v = psys_system_velocities(sys);
            for (int q = 0; q < 2; q++) {
                bool same = memcmp(keep[q], x + fixed[q] * dim, sizeof(double) * (size_t)dim) == 0;
                if (!same)
                    fprintf(stderr, "  solver %s dim %d: fixed particle %zu moved\n", name, dim, fixed[q]);
                CHECK(same);
                for (int k = 0; k < dim; k++)
                    CHECK(v[fixed[q] * dim + k] == 0.0);
            }
            /* Free particles did move (the forces were really applied). */
            CHECK(fabs(x[1 * dim + 1] - free0) > 1e-3);
            /* Setting a fixed particle's velocity is ignored. */
            const double kick[3] = {1, 2, 3};
            CHECK(psys_system_set_particle(sys, 0, NULL, kick) == PSYS_OK);
            for (int k = 0; k < dim; k++)
                CHECK(psys_system_velocities(sys)[k] == 0.0);
            psys_system_destroy(sys);
        }
}

/* ------------------------------------------------------------------ */
/* 9. Each particle's own mass (f[k]/p[i]->m,                          */
/* docs/notes-errata.md#3-particlederivative-each-particles-own-mass)  */
/* ------------------------------------------------------------------ */

typedef struct const_force {
    double f[3];
} const_force;

static void const_force_apply(void *data, const psys_force_eval *e, double *f)
{
    const const_force *cf = data;
    for (size_t i = 0; i < e->n; i++)
        for (int k = 0; k < e->dim; k++)
            f[i * (size_t)e->dim + (size_t)k] += cf->f[k];
}

static const psys_force_class const_force_class = {.name = "constant", .apply = const_force_apply, .destroy = free};

static void own_mass_acceleration(void)
{
    const double masses[3] = {0.5, 4.0, 1.0};
    const double F[3] = {2.0, -3.0, 0.75};
    psys_system *sys = make_system(3);
    const double x[3][3] = {{0, 0, 0}, {5, 0, 0}, {0, 5, 0}};
    for (int p = 0; p < 3; p++)
        add_particle(sys, x[p], NULL, masses[p]);
    const_force *cf = malloc(sizeof *cf);
    CHECK(cf != NULL);
    memcpy(cf->f, F, sizeof F);
    CHECK(psys_system_add_force(sys, &const_force_class, cf) == PSYS_OK);
    psys_ode ode = psys_system_ode(sys);
    CHECK(ode.size == 18 && ode.npos == 9);
    double y[18], yd[18];
    ode.get_state(ode.ctx, y);
    CHECK(ode.derivative(ode.ctx, 0.0, y, yd) == PSYS_OK);
    for (int p = 0; p < 3; p++)
        for (int k = 0; k < 3; k++) {
            CHECK_NEAR(yd[p * 3 + k], 0.0, 0.0); /* x' = v = 0 */
            CHECK_NEAR(yd[9 + p * 3 + k], F[k] / masses[p], 1e-15);
        }
    /* One step of Euler: v = h F/m_i for each particle. */
    psys_solver *s = make_ode_solver("euler", &ode);
    CHECK(psys_solver_step(s, 0.125, NULL) == PSYS_OK);
    const double *v = psys_system_velocities(sys);
    for (int p = 0; p < 3; p++)
        for (int k = 0; k < 3; k++)
            CHECK_NEAR(v[p * 3 + k], 0.125 * F[k] / masses[p], 1e-15);
    psys_solver_destroy(s);
    psys_system_destroy(sys);

    /* A spring between unequal masses: a_a = f/m_a, a_b = −f/m_b, so
     * m_a a_a + m_b a_b = 0 while the accelerations differ. */
    sys = make_system(2);
    const double xa[2] = {0, 0}, xb[2] = {3, 4};
    add_particle(sys, xa, NULL, 0.25);
    add_particle(sys, xb, NULL, 2.0);
    CHECK(psys_system_add_spring(sys, 0, 1, 10.0, 0.0, 2.0) == PSYS_OK);
    ode = psys_system_ode(sys);
    double y2[8], yd2[8];
    ode.get_state(ode.ctx, y2);
    CHECK(ode.derivative(ode.ctx, 0.0, y2, yd2) == PSYS_OK);
    /* |l| = 5, stretch 3: force on a toward b is 30 along (3,4)/5. */
    CHECK_NEAR(yd2[4], 30.0 * 0.6 / 0.25, 1e-12);
    CHECK_NEAR(yd2[5], 30.0 * 0.8 / 0.25, 1e-12);
    CHECK_NEAR(yd2[6], -30.0 * 0.6 / 2.0, 1e-12);
    CHECK_NEAR(yd2[7], -30.0 * 0.8 / 2.0, 1e-12);
    psys_system_destroy(sys);

    /* Gravity f = m g gives every particle the same acceleration g. */
    sys = make_system(2);
    add_particle(sys, xa, NULL, 0.1);
    add_particle(sys, xb, NULL, 30.0);
    const double g[2] = {1.5, -9.81};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    ode = psys_system_ode(sys);
    ode.get_state(ode.ctx, y2);
    CHECK(ode.derivative(ode.ctx, 0.0, y2, yd2) == PSYS_OK);
    for (int p = 0; p < 2; p++)
        for (int k = 0; k < 2; k++)
            CHECK_NEAR(yd2[4 + p * 2 + k], g[k], 1e-14);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 10. Energy accounting and conservation.                              */
/* ------------------------------------------------------------------ */

static double dist(const double *a, const double *b, int dim)
{
    double s = 0;
    for (int k = 0; k < dim; k++)
        s += (a[k] - b[k]) * (a[k] - b[k]);
    return sqrt(s);
}

static void energy_accounting(void)
{
    const double g[3] = {0.3, -9.81, 0.5};
    const double pts[4][3] = {{0, 1, 0}, {1, 0.5, 0.2}, {2.5, -1, 0.1}, {0.5, 3, -1}};
    const double vel[4][3] = {{0, 0, 0}, {1, -2, 0.5}, {0.3, 0.1, -1}, {2, 0, 0}};
    const double mass[4] = {5.0, 0.7, 1.3, 2.2};
    const struct { int a, b; double ks, r; } spr[3] = {{0, 1, 20, 0.5}, {1, 2, 35, 2.0}, {2, 3, 12, 1.0}};
    psys_system *sys = make_system(3);
    for (int p = 0; p < 4; p++)
        add_particle(sys, pts[p], vel[p], mass[p]);
    CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, 0.3) == PSYS_OK); /* non-conservative: no energy */
    for (int s = 0; s < 3; s++)
        CHECK(psys_system_add_spring(sys, (size_t)spr[s].a, (size_t)spr[s].b, spr[s].ks, 0.7, spr[s].r) == PSYS_OK);
    double ke = 0, ug = 0, us = 0;
    for (int p = 1; p < 4; p++) { /* particle 0 is fixed: neither kinetic nor gravity energy */
        ke += 0.5 * mass[p] * (vel[p][0] * vel[p][0] + vel[p][1] * vel[p][1] + vel[p][2] * vel[p][2]);
        ug -= mass[p] * (g[0] * pts[p][0] + g[1] * pts[p][1] + g[2] * pts[p][2]);
    }
    for (int s = 0; s < 3; s++) { /* springs count even when attached to the fixed particle */
        double stretch = dist(pts[spr[s].a], pts[spr[s].b], 3) - spr[s].r;
        us += 0.5 * spr[s].ks * stretch * stretch;
    }
    CHECK_NEAR(psys_system_kinetic_energy(sys), ke, 1e-12 * ke);
    CHECK_NEAR(psys_system_potential_energy(sys), ug + us, 1e-12 * (fabs(ug) + us));

    /* Gravity alone, 2-D: U = m·9.81·y for g = (0, −9.81)
     * (docs/semantics.md#energy). */
    psys_system *s2 = make_system(2);
    const double p2[2] = {4.0, 2.5}, q2[2] = {1.0, 7.0}, g2[2] = {0, -9.81};
    add_particle(s2, p2, NULL, 3.0);
    add_particle(s2, q2, NULL, 1.0);
    psys_system_set_fixed(s2, 1, true);
    CHECK(psys_system_add_gravity(s2, g2) == PSYS_OK);
    CHECK_NEAR(psys_system_potential_energy(s2), 3.0 * 9.81 * 2.5, 1e-12);
    CHECK_NEAR(psys_system_kinetic_energy(s2), 0.0, 0.0);
    psys_system_destroy(s2);
    psys_system_destroy(sys);
}

/* An undamped system (gravity + springs, one anchor) conserves
 * E = KE + U; RK4's energy error is O(h⁴): halving h shrinks it ~16×. */
static double rk4_energy_drift(double h, long n)
{
    const double g[2] = {0.0, -9.81};
    const double pts[4][2] = {{0, 0}, {1, -0.2}, {1.8, -0.9}, {0.6, -1.5}};
    const double vel[4][2] = {{0, 0}, {0.5, 1.0}, {-1, 0.3}, {0.2, -0.4}};
    const double mass[4] = {1, 0.8, 1.2, 0.5};
    psys_system *sys = make_system(2);
    for (int p = 0; p < 4; p++)
        add_particle(sys, pts[p], vel[p], mass[p]);
    psys_system_set_fixed(sys, 0, true);
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 0, 1, 60, 0, 0.9) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 1, 2, 40, 0, -1) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 2, 3, 50, 0, 1.1) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 3, 1, 30, 0, 1.0) == PSYS_OK);
    double E0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
    double ke0 = psys_system_kinetic_energy(sys);
    psys_ode ode = psys_system_ode(sys);
    psys_solver *s = make_ode_solver("rk4", &ode);
    double worst = 0, ke_change = 0;
    for (long k = 0; k < n; k++) {
        CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
        double E = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        worst = fmax(worst, fabs(E - E0));
        ke_change = fmax(ke_change, fabs(psys_system_kinetic_energy(sys) - ke0));
    }
    /* Not vacuous: energy really moved between kinetic and potential. */
    CHECK(ke_change > 0.1 * fabs(E0));
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return worst / fabs(E0);
}

static void energy_conservation_rk4(void)
{
    double e1 = rk4_energy_drift(2e-3, 1000);
    double e2 = rk4_energy_drift(1e-3, 2000);
    fprintf(stderr, "  rk4 max relative energy error over t = 2: h=2e-3 %.3g, h=1e-3 %.3g\n", e1, e2);
    /* Estimate (ωh)⁴ ωT / 120 with ω ≈ 15: ~1e-9 at h = 1e-3. */
    CHECK(e2 < 1e-9);
    /* Fourth order: log2(e1/e2) = 4 ± 0.5 (rounding is ~1e-14, far below e2). */
    CHECK(fabs(log2(e1 / e2) - 4.0) < 0.5);
}

static const check_case cases[] = {
    {"projectile_2d", projectile_2d},
    {"projectile_3d", projectile_3d},
    {"drag_decay", drag_decay},
    {"drag_gravity_terminal", drag_gravity_terminal},
    {"damped_oscillator_2d", damped_oscillator_2d},
    {"damped_oscillator_3d", damped_oscillator_3d},
    {"overdamped_oscillator", overdamped_oscillator},
    {"momentum_spring_pair", momentum_spring_pair},
    {"fixed_particles_stay", fixed_particles_stay},
    {"own_mass_acceleration", own_mass_acceleration},
    {"energy_accounting", energy_accounting},
    {"energy_conservation_rk4", energy_conservation_rk4},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
