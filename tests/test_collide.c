/* Particle/plane collisions and contact (notes §7,
 * docs/notes-errata.md#73-contact-force, docs/semantics.md#planes),
 * pinned against closed forms:
 *   - a ball dropped from h onto a plane with restitution r rebounds to
 *     r²h, r⁴h, ... with impacts at t₁ = √(2h/g), t₁(1 + 2r), ...;
 *   - resting contact: the contact force -(N·f)N cancels the push into the
 *     plane, so a particle at rest on it stays there;
 *   - linear friction f = -k_f(-N·f)v_t: with gravity g and unit normal N,
 *     a particle in contact has a = g_t - λ v, g_t = g - (g·N)N,
 *     λ = k_f|g·N|, so from rest v(t) = g_t(1 - e^{-λt})/λ and on a
 *     horizontal plane v_t(t) = v_t(0) e^{-k_f g t};
 *   - elastic billiards in a box follow the unfolded straight line.
 * Between collisions only gravity acts, which rk4 integrates exactly, so the
 * only errors left are the collision handling's. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <string.h>

static const double G = 9.81;

/* ------------------------------------------------------------------ */
/* helpers                                                             */
/* ------------------------------------------------------------------ */

static void add_plane(psys_system *sys, const double *point, const double *normal, double r, double kf, bool stick,
                      psys_response resp)
{
    psys_plane_def def = psys_plane_def_default();
    int d = psys_system_dim(sys);
    for (int k = 0; k < d; k++) {
        def.point[k] = point[k];
        def.normal[k] = normal[k];
    }
    def.restitution = r;
    def.friction = kf;
    def.stick = stick;
    def.response = resp;
    psys_status st = psys_system_add_plane(sys, &def);
    if (st != PSYS_OK)
        fprintf(stderr, "add_plane: %s\n", psys_system_last_error(sys));
    CHECK(st == PSYS_OK);
}

static void add_gravity(psys_system *sys)
{
    const double g[3] = {0, -G, 0};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
}

/* One step of at most h_max; adaptive solvers land on t_end. */
static void advance(psys_system *sys, psys_solver *s, double h_max)
{
    double ht = 0;
    psys_status st = psys_system_advance(sys, s, h_max, &ht);
    CHECK(st == PSYS_OK);
    if (st != PSYS_OK)
        fprintf(stderr, "psys_system_advance: %s\n", psys_solver_last_error(s));
    CHECK(ht > 0 && ht <= h_max);
}

static double dotv(const double *a, const double *b, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += a[k] * b[k];
    return s;
}

/* ------------------------------------------------------------------ */
/* dropped ball                                                         */
/* ------------------------------------------------------------------ */

typedef struct drop_stats {
    int bounces;
    double H[4];      /* apex after bounce k (1..3), from the first state after it */
    double t_imp[4];  /* impact time k, from the same state */
    double H_dev[4];  /* largest |y + v²/2g - H_expected| over the flight after bounce k */
    double min_y;     /* lowest y seen after any step */
    double t_end, y_end, v_end;
} drop_stats;

/* Drop a particle from height h onto y = 0 and follow it to time T.
 * In flight after bounce k, every state gives the apex H = y + v²/2g and,
 * with the apex time t + v/g, the impact time t + v/g - √(2H/g). */
static drop_stats drop(const char *solver, double h, double r, psys_response resp, double dt, double T)
{
    drop_stats st;
    memset(&st, 0, sizeof st);
    st.min_y = h;
    psys_system *sys = make_system(2);
    double x0[2] = {0.25, h};
    add_particle(sys, x0, NULL, 1.0);
    add_gravity(sys);
    const double p[2] = {0, 0}, n[2] = {0, 1};
    add_plane(sys, p, n, r, 0, false, resp);
    psys_solver *s = make_solver(solver, sys);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    double prev_v = 0;
    while (psys_system_time(sys) < T - 1e-12) {
        double t = psys_system_time(sys);
        advance(sys, s, fmin(dt, T - t));
        t = psys_system_time(sys);
        double y = X[1], v = V[1];
        st.min_y = fmin(st.min_y, y);
        CHECK(X[0] == 0.25 && V[0] == 0); /* frictionless, no tangential motion */
        if (prev_v < 0 && v > 0)
            st.bounces++;
        int k = st.bounces;
        if (k >= 1 && k <= 3) {
            double H = y + v * v / (2 * G);
            if (prev_v < 0 && v > 0) {
                st.H[k] = H;
                st.t_imp[k] = t + v / G - sqrt(2 * H / G);
            }
            st.H_dev[k] = fmax(st.H_dev[k], fabs(H - pow(r, 2 * k) * h));
        }
        prev_v = v;
    }
    st.t_end = psys_system_time(sys);
    st.y_end = X[1];
    st.v_end = V[1];
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return st;
}

static void test_rebound_apex(void)
{
    const double h = 1, r = 0.8, t1 = sqrt(2 * h / G);
    const double dts[2] = {1e-3, 0.05};
    double err_roll_coarse = 1, err_disp_coarse = 0;
    static const char *const solvers[] = {"rk4", "rk45"};
    for (int si = 0; si < 2; si++)
        for (int k = 0; k < 2; k++) {
            /* three bounces: impacts at t1, t1(1+2r), t1(1+2r+2r²) */
            drop_stats st = drop(solvers[si], h, r, PSYS_RESPONSE_ROLLBACK, dts[k], 3.0);
            fprintf(stderr, "  rollback %s dt=%g: H1 = %.15g (want %.15g), t1 = %.15g (want %.15g)\n", solvers[si],
                    dts[k], st.H[1], r * r * h, st.t_imp[1], t1);
            CHECK(st.bounces >= 3);
            CHECK_NEAR(st.H[1], r * r * h, 1e-10);
            CHECK_NEAR(st.H[2], pow(r, 4) * h, 1e-10);
            CHECK_NEAR(st.H[3], pow(r, 6) * h, 1e-10);
            for (int b = 1; b <= 3; b++)
                CHECK(st.H_dev[b] <= 1e-10); /* the whole flight, not just one state */
            CHECK_NEAR(st.t_imp[1], t1, 1e-10);
            CHECK_NEAR(st.t_imp[2], t1 * (1 + 2 * r), 1e-10);
            CHECK_NEAR(st.t_imp[3], t1 * (1 + 2 * r + 2 * r * r), 1e-10);
            /* just after the bounce: ½v² = r² g h */
            CHECK(st.min_y >= -1e-12);
            if (k == 1 && si == 0)
                err_roll_coarse = fabs(st.H[1] - r * r * h);
        }
    /* displace: the particle is pushed back to the plane at the end of the
     * step with the speed it had reached below it, and the bounce happens at
     * the wrong time */
    for (int k = 0; k < 2; k++) {
        drop_stats st = drop("rk4", h, r, PSYS_RESPONSE_DISPLACE, dts[k], 1.0);
        fprintf(stderr, "  displace dt=%g: H1 = %.15g (want %.15g)\n", dts[k], st.H[1], r * r * h);
        CHECK(st.bounces == 1);
        CHECK(st.min_y >= -1e-12); /* never left behind the plane */
        if (k == 1)
            err_disp_coarse = fabs(st.H[1] - r * r * h);
    }
    /* coarse dt: impact at 0.4515 handled at t = 0.5, y = -0.226: the apex
     * becomes r²(h + 0.226) */
    CHECK(err_disp_coarse > 0.1);
    CHECK(err_roll_coarse < 1e-10);
    CHECK(err_disp_coarse > 1e6 * err_roll_coarse);
}

/* r = 1: total energy ½mv² + mgy is conserved through the bounces, and the
 * tangential momentum is untouched. */
static void test_elastic_energy(void)
{
    const double dts[2] = {1e-3, 0.01};
    for (int k = 0; k < 2; k++) {
        psys_system *sys = make_system(2);
        double x0[2] = {0, 1}, v0[2] = {0.7, 0};
        add_particle(sys, x0, v0, 2.0);
        add_gravity(sys);
        const double p[2] = {0, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, 1.0, 0, false, PSYS_RESPONSE_ROLLBACK);
        psys_solver *s = make_solver("rk4", sys);
        const double E0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        CHECK_NEAR(E0, 0.5 * 2 * 0.49 + 2 * G * 1, 1e-13);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        double worst = 0, prev_v = 0;
        int bounces = 0;
        long n_steps = (long)(5.0 / dts[k] + 0.5);
        for (long i = 0; i < n_steps; i++) {
            advance(sys, s, dts[k]);
            double E = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
            worst = fmax(worst, fabs(E - E0));
            CHECK(X[1] >= -1e-12);
            CHECK(V[0] == 0.7);
            if (prev_v < 0 && V[1] > 0)
                bounces++;
            prev_v = V[1];
        }
        fprintf(stderr, "  dt=%g: %d bounces, worst energy error %.3g (E0 = %g)\n", dts[k], bounces, worst, E0);
        CHECK(bounces == 6); /* impacts at 0.4515 + 0.903k s, k = 0..5 */
        CHECK(worst <= 1e-10 * E0);
        CHECK_NEAR(X[0], 0.7 * 5.0, 1e-11);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* ------------------------------------------------------------------ */
/* resting contact                                                      */
/* ------------------------------------------------------------------ */

static void test_resting_contact(void)
{
    static const char *const solvers[] = {"rk4", "euler", "midpoint", "verlet", "symplectic-euler", "rk45"};
    for (size_t si = 0; si < sizeof solvers / sizeof solvers[0]; si++) {
        psys_system *sys = make_system(2);
        double x0[2] = {0.3, 0};
        add_particle(sys, x0, NULL, 1.5);
        add_gravity(sys);
        const double p[2] = {-4, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, 0.5, 0, false, PSYS_RESPONSE_ROLLBACK);
        /* the contact force cancels gravity */
        double f[2];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        CHECK_NEAR(f[0], 0, 1e-15);
        CHECK_NEAR(f[1], 0, 1e-15);
        psys_solver *s = make_solver(solvers[si], sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        double worst = 0;
        for (int i = 0; i < 10000; i++) {
            advance(sys, s, 1e-3);
            worst = fmax(worst, fmax(fabs(X[1]), fmax(fabs(V[0]), fabs(V[1]))));
            if (X[1] < -1e-12) {
                fprintf(stderr, "  %s: below the plane at step %d: y = %g\n", solvers[si], i, X[1]);
                CHECK(X[1] >= -1e-12);
                break;
            }
        }
        CHECK(worst <= 1e-12);
        CHECK_NEAR(X[0], 0.3, 1e-12);
        CHECK_NEAR(psys_system_time(sys), 10.0, 1e-9);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* r = 0: the ball stops dead at the impact and stays. */
static void test_restitution_zero_rests(void)
{
    psys_system *sys = make_system(2);
    double x0[2] = {0, 1};
    add_particle(sys, x0, NULL, 1);
    add_gravity(sys);
    const double p[2] = {0, 0}, n[2] = {0, 1};
    add_plane(sys, p, n, 0.0, 0, false, PSYS_RESPONSE_ROLLBACK);
    psys_solver *s = make_solver("rk4", sys);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    const double t1 = sqrt(2 / G);
    for (int i = 0; i < 3000; i++) {
        advance(sys, s, 1e-3);
        double t = psys_system_time(sys);
        if (t < t1 - 1e-9) { /* free fall, exact under rk4 */
            CHECK_NEAR(X[1], 1 - 0.5 * G * t * t, 1e-12);
            CHECK_NEAR(V[1], -G * t, 1e-12);
        } else {
            CHECK(fabs(X[1]) <= 1e-12);
            CHECK(fabs(V[1]) <= 1e-12);
        }
    }
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* r = 0.5: bounce heights 0.25^k; the bounces die out in finite time
 * t₁(1 + 2r/(1 - r)) = 3t₁ = 1.355 s; the ball never goes through. Once it
 * rests, it is in contact and friction (k_f = 0.5) stops its sliding:
 * v_x = e^{-k_f g (t - t_rest)}, below 1e-5 by t = 4 (it would stay 1 if the
 * ball never came to rest). */
static void test_restitution_half_dies_out(void)
{
    drop_stats st = drop("rk4", 1.0, 0.5, PSYS_RESPONSE_ROLLBACK, 1e-3, 1.2);
    CHECK_NEAR(st.H[1], 0.25, 1e-10);
    CHECK_NEAR(st.H[2], 0.0625, 1e-10);
    CHECK_NEAR(st.H[3], 0.015625, 1e-10);
    CHECK(st.min_y >= -1e-12);

    const double dts[2] = {1e-3, 1e-4};
    for (int k = 0; k < 2; k++) {
        psys_system *sys = make_system(2);
        double x0[2] = {0, 1}, v0[2] = {1, 0};
        add_particle(sys, x0, v0, 1);
        add_gravity(sys);
        const double p[2] = {0, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, 0.5, 0.5, false, PSYS_RESPONSE_ROLLBACK);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        const double t_rest = 3 * sqrt(2 / G);
        double last_moving = 0, min_y = 1;
        int bounces = 0;
        double prev_v = 0;
        long n_steps = (long)(4.0 / dts[k] + 0.5);
        for (long i = 0; i < n_steps; i++) {
            advance(sys, s, dts[k]);
            min_y = fmin(min_y, X[1]);
            if (fabs(X[1]) > 1e-12 || fabs(V[1]) > 1e-12)
                last_moving = psys_system_time(sys);
            if (prev_v < 0 && V[1] > 0)
                bounces++;
            prev_v = V[1];
        }
        fprintf(stderr, "  dt=%g: %d bounces, last moving at t = %.6g (Zeno limit %.6g), lowest y %.3g; "
                "at t = 4: y = %.3g, v = (%.3g, %.3g)\n",
                dts[k], bounces, last_moving, t_rest, min_y, X[1], V[0], V[1]);
        CHECK(min_y >= -1e-12);
        CHECK(bounces >= 8);
        CHECK(last_moving <= t_rest + 0.01);
        CHECK(fabs(X[1]) <= 1e-12 && fabs(V[1]) <= 1e-12);
        CHECK(V[0] >= 0 && V[0] <= 1e-5);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* The same on a displace plane (2 kg ball from (1, 0.5) with v = (1, 0),
 * r = 0.5, k_f = 0.5, dt = 10⁻³, 5 s), for the explicit solvers that do not
 * gain energy in flight. Displacing the ball back and reflecting its
 * end-of-step normal velocity gives back the speed gravity added behind the
 * plane (up to g·dt = 0.0098), so bounces from rest never fell below
 * PSYS_CONTACT_SPEED: the ball cycled between y = 0, vy = +0.00654 and
 * y = 1.6e-6, vy = -0.00327 forever, vx = 1 untouched. It must settle near
 * the Zeno limit t₁(1 + r)/(1 - r) = 0.958 s (its last bounces last a few
 * steps, so within 20 steps of it), then stay on the plane and slide as
 * v_t(t) = v_t(t_r) e^{-k_f g (t - t_r)} from the settling time t_r (before
 * it vx is exactly 1: no friction in flight). The friction law is integrated
 * to O(dt⁴) by rk4 and rk45 (as in friction_horizontal, 1e-8), to O(dt²) by
 * verlet and midpoint: (k_f g dt)² ≈ 2.4e-5 a unit time, so 1e-4. */
static void test_displace_comes_to_rest(void)
{
    static const char *const solvers[] = {"rk4", "verlet", "midpoint", "rk45"};
    static const double tols[] = {1e-8, 1e-4, 1e-4, 1e-8};
    const double r = 0.5, kf = 0.5, dt = 1e-3, lam = kf * G;
    const double t_zeno = sqrt(2 * 0.5 / G) * (1 + r) / (1 - r);
    for (size_t si = 0; si < sizeof solvers / sizeof solvers[0]; si++) {
        psys_system *sys = make_system(2);
        double x0[2] = {1, 0.5}, v0[2] = {1, 0};
        add_particle(sys, x0, v0, 2);
        add_gravity(sys);
        const double p[2] = {0, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, r, kf, false, PSYS_RESPONSE_DISPLACE);
        psys_solver *s = make_solver(solvers[si], sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        enum { N = 5000 };
        static double T[N], Y[N], VX[N], VY[N];
        double min_y = 1;
        for (int i = 0; i < N; i++) {
            advance(sys, s, dt);
            T[i] = psys_system_time(sys);
            Y[i] = X[1];
            VX[i] = V[0];
            VY[i] = V[1];
            min_y = fmin(min_y, X[1]);
        }
        int rest = N; /* first step from which it stays on the plane, at rest */
        while (rest > 0 && fabs(Y[rest - 1]) <= 1e-12 && fabs(VY[rest - 1]) <= 1e-12)
            rest--;
        const double t_r = rest < N ? T[rest] : INFINITY;
        double worst = 0, vx_before = 1;
        for (int i = 0; i < N; i++) {
            if (i <= rest) {
                vx_before = fmax(vx_before, fabs(VX[i] - 1) + 1);
                continue;
            }
            const double want = VX[rest] * exp(-lam * (T[i] - t_r));
            if (T[i] - t_r <= 2) /* further on, vx < 1e-4 of its start */
                worst = fmax(worst, fabs(VX[i] - want) / want);
        }
        fprintf(stderr, "  %s: at rest from t = %.4g (Zeno limit %.4g), lowest y %.3g; at t = 5: y = %.3g, "
                "v = (%.3g, %.3g); friction: worst relative error %.3g\n",
                solvers[si], t_r, t_zeno, min_y, Y[N - 1], VX[N - 1], VY[N - 1], worst);
        CHECK(min_y >= -1e-12);
        CHECK(t_r <= t_zeno + 20 * dt);
        CHECK(vx_before == 1);
        CHECK(rest < N && VX[rest] == 1);
        CHECK(worst <= tols[si]);
        CHECK(fabs(VX[N - 1]) <= 1e-8);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A particle that reaches a rollback plane exactly at the end of a step
 * (here y = 1 - 10·0.1 = 0 up to rounding) is at the instant of contact: it
 * must bounce there, not spend the next step behind the plane and be
 * displaced at its end (which delays the rebound by a whole step). No
 * gravity: y(t) = 10 r (t - 0.1) after the impact at t = 0.1. */
static void test_touching_at_step_end(void)
{
    const double rs[2] = {1.0, 0.5};
    for (int k = 0; k < 2; k++) {
        const double r = rs[k];
        psys_system *sys = make_system(2);
        double x0[2] = {0, 1}, v0[2] = {0, -10};
        add_particle(sys, x0, v0, 1);
        const double p[2] = {0, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, r, 0, false, PSYS_RESPONSE_ROLLBACK);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        for (int i = 1; i <= 5; i++) {
            advance(sys, s, 0.1);
            double t = psys_system_time(sys);
            double ye = i == 1 ? 0 : 10 * r * (t - 0.1), ve = i == 1 ? -10 : 10 * r;
            if (fabs(X[1] - ye) > 1e-12 || (i > 1 && fabs(V[1] - ve) > 1e-12))
                fprintf(stderr, "  r = %g, t = %.2f: y = %.17g (want %.17g), v = %.17g (want %.17g)\n", r, t, X[1], ye,
                        V[1], ve);
            CHECK_NEAR(X[1], ye, 1e-12);
            if (i > 1)
                CHECK_NEAR(V[1], ve, 1e-12);
        }
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* ------------------------------------------------------------------ */
/* friction                                                             */
/* ------------------------------------------------------------------ */

/* Horizontal plane: v_t(t) = v0 e^{-k_f g t}, x = x0 + v0 (1 - e^{-λt})/λ. */
static void test_friction_horizontal(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        const double kf = 0.3, lam = kf * G;
        psys_system *sys = make_system(dim);
        double x0[3] = {1, 0, -1}, v0[3] = {2, 0, -1.5};
        add_particle(sys, x0, v0, 0.8);
        add_gravity(sys);
        const double p[3] = {0, 0, 0}, n[3] = {0, 1, 0};
        add_plane(sys, p, n, 0.5, kf, false, PSYS_RESPONSE_ROLLBACK);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        double worst = 0;
        for (int i = 1; i <= 2000; i++) {
            advance(sys, s, 1e-3);
            double t = psys_system_time(sys), E = exp(-lam * t);
            for (int k = 0; k < dim; k += 2) { /* the tangential components x (and z) */
                worst = fmax(worst, fabs(V[k] - v0[k] * E) / fabs(v0[k] * E));
                worst = fmax(worst, fabs(X[k] - (x0[k] + v0[k] * (1 - E) / lam)) / fabs(v0[k] / lam));
            }
            CHECK(X[1] == 0 && V[1] == 0);
        }
        fprintf(stderr, "  %dD: worst relative error %.3g\n", dim, worst);
        CHECK(worst <= 1e-8);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A particle starting at rest on a tilted plane (unit normal N) under
 * gravity g: the contact force removes the normal part of m g, friction
 * adds -k_f m|g·N| v, so a = g_t - λv with g_t = g - (g·N)N, λ = k_f|g·N|:
 *   v(t) = g_t (1 - e^{-λt})/λ,  x(t) = P + g_t (t - (1 - e^{-λt})/λ)/λ,
 * and without friction x(t) = P + ½ g_t t². */
static double slope_run(int dim, const double *normal_in, double kf, double T, double dt)
{
    double N[3] = {0, 0, 0}, len = sqrt(dotv(normal_in, normal_in, dim));
    for (int k = 0; k < dim; k++)
        N[k] = normal_in[k] / len;
    const double P[3] = {1, 2, 3}, g[3] = {0, -G, 0};
    double gn = dotv(g, N, dim), gt[3];
    for (int k = 0; k < 3; k++)
        gt[k] = g[k] - gn * N[k];
    const double lam = kf * fabs(gn);
    psys_system *sys = make_system(dim);
    add_particle(sys, P, NULL, 1.3);
    add_gravity(sys);
    add_plane(sys, P, normal_in, 0.5, kf, false, PSYS_RESPONSE_ROLLBACK);
    /* the force at rest is m g_t: the contact force took the normal part */
    double f[3];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < dim; k++)
        CHECK_NEAR(f[k], 1.3 * gt[k], 1e-14);
    psys_solver *s = make_solver("rk4", sys);
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    double worst = 0, scale = sqrt(dotv(gt, gt, dim));
    long n = (long)(T / dt + 0.5);
    for (long i = 1; i <= n; i++) {
        advance(sys, s, dt);
        double t = psys_system_time(sys), d[3];
        for (int k = 0; k < dim; k++)
            d[k] = X[k] - P[k];
        CHECK(fabs(dotv(d, N, dim)) <= 1e-12); /* stays on the plane */
        for (int k = 0; k < dim; k++) {
            double xe, ve;
            if (lam > 0) {
                double E = exp(-lam * t);
                ve = gt[k] * (1 - E) / lam;
                xe = P[k] + gt[k] * (t - (1 - E) / lam) / lam;
            } else {
                ve = gt[k] * t;
                xe = P[k] + 0.5 * gt[k] * t * t;
            }
            worst = fmax(worst, fabs(V[k] - ve) / (scale * t));
            worst = fmax(worst, fabs(X[k] - xe) / (scale * t * t));
        }
    }
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return worst;
}

static void test_friction_slope(void)
{
    const double th = 0.3;
    const double n2[2] = {-sin(th), cos(th)}, n3[3] = {0.3, 1, -0.2};
    const double kfs[3] = {0.5, 0.1, 0};
    for (int k = 0; k < 3; k++) {
        double w2 = slope_run(2, n2, kfs[k], 2.0, 1e-3);
        double w3 = slope_run(3, n3, kfs[k], 2.0, 1e-3);
        fprintf(stderr, "  k_f = %g: worst relative error 2D %.3g, 3D %.3g\n", kfs[k], w2, w3);
        CHECK(w2 <= 1e-8);
        CHECK(w3 <= 1e-8);
    }
    /* the acceleration along the slope at the start is g sin θ, and the
     * terminal speed is tan θ / k_f: one tiny Euler step and a long run */
    psys_system *sys = make_system(2);
    const double P[2] = {0, 0};
    add_particle(sys, P, NULL, 1);
    add_gravity(sys);
    add_plane(sys, P, n2, 0.5, 0.5, false, PSYS_RESPONSE_ROLLBACK);
    psys_solver *s = make_solver("euler", sys);
    advance(sys, s, 1e-6);
    const double *V = psys_system_velocities(sys);
    CHECK_NEAR(hypot(V[0], V[1]) / 1e-6, G * sin(th), 1e-8);
    CHECK(V[0] < 0 && V[1] < 0); /* downhill */
    psys_solver_destroy(s);
    s = make_solver("rk4", sys);
    for (int i = 0; i < 3000; i++)
        advance(sys, s, 0.01);
    CHECK_NEAR(hypot(V[0], V[1]), tan(th) / 0.5, 1e-9);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* "friction": "stick" holds a particle on a slope it would slide down. */
static void test_stick_slope(void)
{
    static const char *const fmt =
        "{\"psys\":1,\"dim\":2,\"dt\":0.001,\"steps\":1000,"
        "\"particles\":[{\"x\":[0,0],\"v\":[%s]}],"
        "\"forces\":[{\"type\":\"gravity\",\"g\":[0,-9.81]}],"
        "\"planes\":[{\"point\":[0,0],\"normal\":[-0.29552020666133955,0.95533648912560598],\"friction\":%s}]}";
    const double th = 0.3;
    for (int variant = 0; variant < 3; variant++) {
        char text[1024];
        /* 0: stick at rest, 1: frictionless at rest, 2: stick, launched along the slope */
        snprintf(text, sizeof text, fmt, variant == 2 ? "0.95533648912560598,0.29552020666133955" : "0,0",
                 variant == 1 ? "0" : "\"stick\"");
        psys_scene *sc = load_scene(text);
        psys_system *sys = psys_scene_system(sc);
        psys_plane_def def;
        CHECK(psys_system_plane(sys, 0, &def) == PSYS_OK);
        CHECK(def.stick == (variant != 1));
        psys_error err;
        psys_run *run = psys_run_create(sc, &err);
        CHECK(run != NULL);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        double x_first[2] = {0, 0};
        while (run && !psys_run_done(run)) {
            CHECK(psys_run_step(run, &err) == PSYS_OK);
            if (psys_run_step_index(run) == 1) {
                x_first[0] = X[0];
                x_first[1] = X[1];
            }
            if (variant != 1) {
                /* held: no velocity after the first step, and it stays put */
                CHECK(fabs(V[0]) <= 1e-12 && fabs(V[1]) <= 1e-12);
                CHECK(fabs(X[0] - x_first[0]) <= 1e-12 && fabs(X[1] - x_first[1]) <= 1e-12);
            }
        }
        double t = psys_system_time(sys);
        CHECK_NEAR(t, 1.0, 1e-12);
        if (variant == 0) {
            CHECK(fabs(X[0]) <= 1e-12 && fabs(X[1]) <= 1e-12);
        } else if (variant == 1) { /* slid ½ g sin θ t² down the slope */
            double s_exp = 0.5 * G * sin(th) * t * t;
            CHECK_NEAR(hypot(X[0], X[1]), s_exp, 1e-10);
            CHECK_NEAR(hypot(V[0], V[1]), G * sin(th) * t, 1e-10);
        } else { /* stopped within the first step */
            CHECK(hypot(X[0], X[1]) <= 1e-3 + 1e-12);
        }
        psys_run_destroy(run);
        psys_scene_destroy(sc);
    }
}

/* ------------------------------------------------------------------ */
/* fast particles, breaking contact, several planes                     */
/* ------------------------------------------------------------------ */

/* v = -1000 from y = 1 with a step of 0.1: it would end at y ≈ -99. */
static void test_no_tunnelling(void)
{
    const double r = 0.8, h = 0.1;
    /* rollback: impact at 1 - 1000t - ½gt² = 0, then free flight up */
    const double ti = 2.0 / (1000 + sqrt(1e6 + 2 * G));
    const double vup = r * (1000 + G * ti), tau = h - ti;
    for (int resp = 0; resp < 2; resp++) {
        psys_system *sys = make_system(2);
        double x0[2] = {0, 1}, v0[2] = {3, -1000};
        add_particle(sys, x0, v0, 1);
        add_gravity(sys);
        const double p[2] = {0, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, r, 0, false, resp == 0 ? PSYS_RESPONSE_ROLLBACK : PSYS_RESPONSE_DISPLACE);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        advance(sys, s, h);
        fprintf(stderr, "  %s: after one step y = %.15g, vy = %.15g\n", resp == 0 ? "rollback" : "displace", X[1],
                V[1]);
        CHECK(X[1] >= 0);
        CHECK(V[1] > 0);
        CHECK_NEAR(X[0], 0.3, 1e-12);
        CHECK_NEAR(V[0], 3, 1e-12);
        if (resp == 0) {
            CHECK_NEAR(X[1], vup * tau - 0.5 * G * tau * tau, 1e-9);
            CHECK_NEAR(V[1], vup - G * tau, 1e-9);
        } else {
            /* displace: put back on the plane, the end-of-step normal velocity reflected */
            CHECK_NEAR(X[1], 0, 1e-12);
            CHECK_NEAR(V[1], r * (1000 + G * h), 1e-9);
        }
        for (int i = 0; i < 200; i++) {
            advance(sys, s, h);
            CHECK(X[1] >= -1e-9);
        }
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A particle resting on the floor and pulled up by a spring to an anchor
 * above it leaves the plane when the pull beats gravity (ks·1 > mg) and
 * then moves as y(t) = A(1 - cos ωt), A = (ks - g)/ks, ω = √ks (m = 1,
 * rest length 0, anchor at height 1); a weaker pull leaves it resting. */
static void test_contact_breaks(void)
{
    for (int strong = 0; strong < 2; strong++) {
        const double ks = strong ? 20 : 5;
        psys_system *sys = make_system(2);
        double x0[2] = {0, 0}, xa[2] = {0, 1};
        size_t i = add_particle(sys, x0, NULL, 1);
        size_t a = add_particle(sys, xa, NULL, 1);
        CHECK(psys_system_set_fixed(sys, a, true) == PSYS_OK);
        add_gravity(sys);
        CHECK(psys_system_add_spring(sys, i, a, ks, 0, 0) == PSYS_OK);
        const double p[2] = {-1, 0}, n[2] = {0, 1};
        add_plane(sys, p, n, 0.5, 0.3, false, PSYS_RESPONSE_ROLLBACK);
        double f[4];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        CHECK_NEAR(f[1], strong ? ks - G : 0, 1e-12); /* contact force only when pushed in */
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        const double A = (ks - G) / ks, w = sqrt(ks);
        for (int k = 0; k < 500; k++) {
            advance(sys, s, 1e-3);
            double t = psys_system_time(sys);
            if (strong) {
                CHECK_NEAR(X[1], A * (1 - cos(w * t)), 1e-10);
                CHECK_NEAR(V[1], A * w * sin(w * t), 1e-10);
            } else {
                CHECK(fabs(X[1]) <= 1e-12 && fabs(V[1]) <= 1e-12);
            }
            CHECK(X[0] == 0 && V[0] == 0);
        }
        if (strong)
            CHECK(X[1] > 0.3);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* Position in [-1, 1] of the unfolded coordinate u (a billiard between
 * walls at ±1), and the sign its velocity has there. */
static double fold(double u, double *sign)
{
    double s = fmod(u + 1, 4);
    if (s < 0)
        s += 4;
    *sign = 1;
    if (s > 2) {
        s = 4 - s;
        *sign = -1;
    }
    return s - 1;
}

/* A 2-D box of four lines [-1, 1]²: elastic billiards follow the folded
 * straight line exactly; an inelastic ball under gravity stays inside. */
static void test_box_2d(void)
{
    const double pts[4][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}};
    const double nrm[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (int variant = 0; variant < 2; variant++) {
        psys_system *sys = make_system(2);
        double x0[2] = {0.3, 0.2}, v0[2] = {7.3, 5.13}; /* no wall is hit at a step's end */
        add_particle(sys, x0, v0, 1);
        if (variant == 1)
            add_gravity(sys);
        for (int k = 0; k < 4; k++)
            add_plane(sys, pts[k], nrm[k], variant == 0 ? 1.0 : 0.9, 0, false, PSYS_RESPONSE_ROLLBACK);
        CHECK(psys_system_plane_count(sys) == 4);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        double worst = 0;
        int outside = 0;
        for (int i = 1; i <= 10000; i++) {
            advance(sys, s, 1e-3);
            if (fabs(X[0]) > 1 + 1e-12 || fabs(X[1]) > 1 + 1e-12)
                outside++;
            if (variant == 0 && i % 10 == 0) {
                double t = psys_system_time(sys), sx, sy;
                double fx = fold(x0[0] + v0[0] * t, &sx), fy = fold(x0[1] + v0[1] * t, &sy);
                worst = fmax(worst, fmax(fabs(X[0] - fx), fabs(X[1] - fy)));
                worst = fmax(worst, fmax(fabs(V[0] - sx * v0[0]), fabs(V[1] - sy * v0[1])));
            }
        }
        CHECK(outside == 0);
        if (variant == 0) {
            fprintf(stderr, "  elastic box: worst deviation from the folded line %.3g over 10 s (~60 bounces)\n",
                    worst);
            CHECK(worst <= 1e-9);
        } else {
            CHECK(hypot(V[0], V[1]) < hypot(v0[0], v0[1])); /* lost energy at the walls */
        }
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* 3-D plane with normal (1,2,2)/3: the normal velocity is scaled by -r at
 * impact, the tangential one kept; also with a huge step. */
static void test_plane_3d_tilted(void)
{
    const double N[3] = {1.0 / 3, 2.0 / 3, 2.0 / 3}, nin[3] = {1, 2, 2}, P[3] = {0.5, 0, 0};
    const double T1[3] = {2 / sqrt(5.0), -1 / sqrt(5.0), 0};
    double T2[3] = {N[1] * T1[2] - N[2] * T1[1], N[2] * T1[0] - N[0] * T1[2], N[0] * T1[1] - N[1] * T1[0]};
    const double r = 0.7;
    for (int fast = 0; fast < 2; fast++) {
        const double speed = fast ? 3000 : 3, h = fast ? 0.1 : 0.01, T = fast ? 0.1 : 1.5;
        psys_system *sys = make_system(3);
        double x0[3], v0[3], v1[3];
        for (int k = 0; k < 3; k++) {
            x0[k] = P[k] + 2 * N[k] + 0.3 * T1[k];
            v0[k] = -speed * N[k] + 0.4 * T2[k];
            v1[k] = r * speed * N[k] + 0.4 * T2[k];
        }
        add_particle(sys, x0, v0, 1);
        add_plane(sys, P, nin, r, 0, false, PSYS_RESPONSE_ROLLBACK);
        psys_plane_def def;
        CHECK(psys_system_plane(sys, 0, &def) == PSYS_OK);
        for (int k = 0; k < 3; k++)
            CHECK_NEAR(def.normal[k], N[k], 1e-16);
        psys_solver *s = make_solver("rk4", sys);
        const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
        const double ti = 2 / speed;
        long n = (long)(T / h + 0.5);
        for (long i = 0; i < n; i++) {
            advance(sys, s, h);
            double d[3];
            for (int k = 0; k < 3; k++)
                d[k] = X[k] - P[k];
            CHECK(dotv(d, N, 3) >= -1e-12);
        }
        double t = psys_system_time(sys);
        CHECK_NEAR(t, T, 1e-12);
        for (int k = 0; k < 3; k++) {
            double xe = x0[k] + v0[k] * ti + v1[k] * (t - ti);
            CHECK_NEAR(X[k], xe, 1e-12 * speed);
            CHECK_NEAR(V[k], v1[k], 1e-12 * speed);
        }
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* ------------------------------------------------------------------ */
/* scenes                                                               */
/* ------------------------------------------------------------------ */

static void test_scene_plane_defaults(void)
{
    psys_plane_def d = psys_plane_def_default();
    CHECK(d.restitution == 0.5 && d.friction == 0 && !d.stick && d.response == PSYS_RESPONSE_ROLLBACK);
    CHECK(d.normal[0] == 0 && d.normal[1] == 1 && d.normal[2] == 0);

    psys_scene *sc = load_scene("{\"psys\":1,\"dim\":2,\"particles\":[{\"x\":[0,1]}],\"planes\":["
                                "{\"point\":[0,-2],\"normal\":[0,2]},"
                                "{\"point\":[1,1],\"normal\":[-3,-4],\"restitution\":1,\"friction\":0.25,"
                                "\"response\":\"displace\"},"
                                "{\"point\":[0,0],\"normal\":[5,0],\"restitution\":0,\"friction\":\"stick\"}]}");
    psys_system *sys = psys_scene_system(sc);
    CHECK(psys_system_plane_count(sys) == 3);
    psys_plane_def p;
    CHECK(psys_system_plane(sys, 0, &p) == PSYS_OK);
    CHECK(p.point[0] == 0 && p.point[1] == -2);
    CHECK(p.normal[0] == 0 && p.normal[1] == 1);
    CHECK(p.restitution == 0.5 && p.friction == 0 && !p.stick && p.response == PSYS_RESPONSE_ROLLBACK);
    CHECK(psys_system_plane(sys, 1, &p) == PSYS_OK);
    CHECK_NEAR(p.normal[0], -0.6, 1e-16);
    CHECK_NEAR(p.normal[1], -0.8, 1e-16);
    CHECK(p.restitution == 1 && p.friction == 0.25 && !p.stick && p.response == PSYS_RESPONSE_DISPLACE);
    CHECK(psys_system_plane(sys, 2, &p) == PSYS_OK);
    CHECK(p.normal[0] == 1 && p.normal[1] == 0);
    CHECK(p.restitution == 0 && p.stick && p.response == PSYS_RESPONSE_ROLLBACK);
    CHECK(psys_system_plane(sys, 3, &p) == PSYS_ERR_INVALID);
    psys_scene_destroy(sc);

    sc = load_scene("{\"psys\":1,\"particles\":[{\"x\":[0,1,0]}],\"planes\":[{\"point\":[0,0,0],\"normal\":[1,2,2]}]}");
    CHECK(psys_system_plane(psys_scene_system(sc), 0, &p) == PSYS_OK);
    CHECK_NEAR(p.normal[0], 1.0 / 3, 1e-16);
    CHECK_NEAR(p.normal[1], 2.0 / 3, 1e-16);
    CHECK_NEAR(p.normal[2], 2.0 / 3, 1e-16);
    psys_scene_destroy(sc);

    /* the C API validates the same things */
    psys_system *s2 = make_system(2);
    psys_plane_def b = psys_plane_def_default();
    b.normal[1] = 0;
    CHECK(psys_system_add_plane(s2, &b) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(s2), "plane normal must not be zero");
    b = psys_plane_def_default();
    b.restitution = 1.5;
    CHECK(psys_system_add_plane(s2, &b) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(s2), "plane restitution must be from 0 to 1");
    b = psys_plane_def_default();
    b.friction = -1;
    CHECK(psys_system_add_plane(s2, &b) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(s2), "plane friction must be finite and >= 0");
    b = psys_plane_def_default();
    b.response = (psys_response)7;
    CHECK(psys_system_add_plane(s2, &b) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(s2), "unknown collision response");
    CHECK(psys_system_plane_count(s2) == 0);
    psys_system_destroy(s2);
}

#define PL "{\"psys\":1,\"dim\":2,\"particles\":[{\"x\":[0,1]}],\"planes\":["

static void test_scene_plane_bad_inputs(void)
{
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,0]}]}"), "planes[0].normal: must not be zero (got [0,0])");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1]},{\"point\":[0,0],\"normal\":[0,1],"
                            "\"restitution\":1.5}]}"),
              "planes[1].restitution: must be from 0 to 1 (got 1.5)");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"restitution\":-0.1}]}"),
              "planes[0].restitution: must be >= 0 (got -0.1)");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"friction\":-0.1}]}"),
              "planes[0].friction: must be >= 0 (got -0.1)");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"friction\":\"slippery\"}]}"),
              "planes[0].friction: must be a number >= 0 or \"stick\" (got \"slippery\")");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"response\":\"bounce\"}]}"),
              "planes[0].response: must be \"rollback\" or \"displace\" (got \"bounce\")");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"response\":1}]}"),
              "planes[0].response: must be \"rollback\" or \"displace\" (got 1)");
    CHECK_STR(load_error(PL "{\"normal\":[0,1]}]}"), "planes[0].point: required key missing");
    CHECK_STR(load_error(PL "{\"point\":[0,0]}]}"), "planes[0].normal: required key missing");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1,0]}]}"),
              "planes[0].normal: must be an array of 2 numbers (dim is 2) (got [0,1,0])");
    CHECK_STR(load_error(PL "{\"point\":[0,0],\"normal\":[0,1],\"bounce\":1}]}"), "planes[0].bounce: unknown key");
    CHECK_STR(load_error(PL "7]}"), "planes[0]: a plane must be an object (got 7)");
}

static void plane_round_trip(const char *text)
{
    psys_scene *a = load_scene(text);
    char *s1 = save_scene(a);
    psys_scene *b = load_scene(s1);
    char *s2 = save_scene(b);
    CHECK_STR(s2, s1);
    psys_system *sa = psys_scene_system(a), *sb = psys_scene_system(b);
    CHECK(psys_system_plane_count(sa) == psys_system_plane_count(sb));
    for (size_t k = 0; k < psys_system_plane_count(sa) && k < psys_system_plane_count(sb); k++) {
        psys_plane_def pa, pb;
        CHECK(psys_system_plane(sa, k, &pa) == PSYS_OK);
        CHECK(psys_system_plane(sb, k, &pb) == PSYS_OK);
        CHECK(memcmp(pa.point, pb.point, sizeof pa.point) == 0);
        if (memcmp(pa.normal, pb.normal, sizeof pa.normal) != 0)
            fprintf(stderr, "  plane %zu normal: loaded (%.17g, %.17g, %.17g), reloaded (%.17g, %.17g, %.17g)\n", k,
                    pa.normal[0], pa.normal[1], pa.normal[2], pb.normal[0], pb.normal[1], pb.normal[2]);
        CHECK(memcmp(pa.normal, pb.normal, sizeof pa.normal) == 0);
        CHECK(pa.restitution == pb.restitution && pa.friction == pb.friction && pa.stick == pb.stick
              && pa.response == pb.response);
    }
    free(s1);
    free(s2);
    psys_scene_destroy(a);
    psys_scene_destroy(b);
}

static void test_scene_plane_round_trip(void)
{
    plane_round_trip("{\"psys\":1,\"dim\":2,\"particles\":[{\"x\":[0,1]}],\"planes\":["
                     "{\"point\":[0,-2],\"normal\":[0,2]},"
                     "{\"point\":[1,1],\"normal\":[-1,0],\"restitution\":1,\"friction\":0.25,"
                     "\"response\":\"displace\"},"
                     "{\"point\":[0.1,-0.3],\"normal\":[0,-7],\"restitution\":0,\"friction\":\"stick\"},"
                     "{\"point\":[3,3],\"normal\":[3,4],\"friction\":\"stick\",\"response\":\"displace\"}]}");
    plane_round_trip("{\"psys\":1,\"particles\":[{\"x\":[0,1,0]}],\"planes\":["
                     "{\"point\":[0,0,0],\"normal\":[1,2,2],\"friction\":\"stick\"},"
                     "{\"point\":[0,5,0],\"normal\":[0,-1,0],\"restitution\":0.9,\"response\":\"displace\"}]}");
}

/* Normals are normalised on load: saving the normalised normal and loading
 * it again must give the same plane to the last bit
 * (docs/scene-format.md#saving-a-scene-back: a scene loaded and saved again
 * must load to the same system). */
static void test_scene_plane_round_trip_tilted(void)
{
    plane_round_trip("{\"psys\":1,\"dim\":2,\"particles\":[{\"x\":[0,1]}],\"planes\":["
                     "{\"point\":[0,0],\"normal\":[1,1]},{\"point\":[0,0],\"normal\":[1,3]}]}");
    plane_round_trip("{\"psys\":1,\"particles\":[{\"x\":[0,1,0]}],\"planes\":["
                     "{\"point\":[0,0,0],\"normal\":[1,1,1]},{\"point\":[0,0,0],\"normal\":[0,1,1]}]}");
}

static const check_case cases[] = {
    {"rebound_apex", test_rebound_apex},
    {"elastic_energy", test_elastic_energy},
    {"resting_contact", test_resting_contact},
    {"restitution_zero_rests", test_restitution_zero_rests},
    {"restitution_half_dies_out", test_restitution_half_dies_out},
    {"displace_comes_to_rest", test_displace_comes_to_rest},
    {"touching_at_step_end", test_touching_at_step_end},
    {"friction_horizontal", test_friction_horizontal},
    {"friction_slope", test_friction_slope},
    {"stick_slope", test_stick_slope},
    {"no_tunnelling", test_no_tunnelling},
    {"contact_breaks", test_contact_breaks},
    {"box_2d", test_box_2d},
    {"plane_3d_tilted", test_plane_3d_tilted},
    {"scene_plane_defaults", test_scene_plane_defaults},
    {"scene_plane_bad_inputs", test_scene_plane_bad_inputs},
    {"scene_plane_round_trip", test_scene_plane_round_trip},
    {"scene_plane_round_trip_tilted", test_scene_plane_round_trip_tilted},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
