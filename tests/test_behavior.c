/* Behaviour-function forces (notes §6 eq. 2,
 * docs/notes-errata.md#6-eq-2-the-transpose-of-the-jacobian): the built-ins against
 * closed forms and eq. 1 springs, the Gauss–Newton force Jacobian, the
 * Jacobian checker, user functions (analytic and finite-difference J, in a
 * simulation), scene round trips and bad-input messages. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static void add_behavior_ok(psys_system *sys, const psys_behavior_def *def)
{
    psys_status st = psys_system_add_behavior(sys, def);
    if (st != PSYS_OK)
        fprintf(stderr, "psys_system_add_behavior: %s\n", psys_system_last_error(sys));
    CHECK(st == PSYS_OK);
}

static psys_behavior_def builtin_def(psys_behavior_function f, int k, const size_t *idx, double ks, double kd)
{
    psys_behavior_def def = psys_behavior_def_default();
    def.function = f;
    def.nparticles = k;
    for (int i = 0; i < k; i++)
        def.particles[i] = idx[i];
    def.ks = ks;
    def.kd = kd;
    return def;
}

static double max_abs(const double *a, size_t n)
{
    double m = 0;
    for (size_t i = 0; i < n; i++)
        m = fmax(m, fabs(a[i]));
    return m;
}

/* ---- distance = eq. 1 spring
 * (docs/notes-errata.md#42-eq-1-and-the-distance-behaviour-function) ---- */

static void distance_vs_spring(int dim)
{
    enum { N = 12 };
    for (int trial = 0; trial < 50; trial++) {
        psys_system *sb = make_system(dim), *ss = make_system(dim);
        for (int i = 0; i < N; i++) {
            double x[3], v[3];
            for (int c = 0; c < dim; c++) {
                x[c] = urand(-2, 2);
                v[c] = urand(-3, 3);
            }
            add_particle(sb, x, v, 1.0);
            add_particle(ss, x, v, 1.0);
        }
        for (int s = 0; s < 20; s++) {
            size_t a = (size_t)(urand(0, N)), b = (size_t)(urand(0, N));
            if (a == b)
                continue;
            double ks = urand(0.1, 100), kd = urand(0, 5);
            double rest = s % 3 == 0 ? -1.0 : urand(0, 3); /* -1: both use the current length */
            size_t idx[2] = {a, b};
            psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_DISTANCE, 2, idx, ks, kd);
            def.r = rest;
            add_behavior_ok(sb, &def);
            CHECK(psys_system_add_spring(ss, a, b, ks, kd, rest) == PSYS_OK);
        }
        double fb[N * 3], fs[N * 3];
        CHECK(psys_system_compute_forces(sb, fb) == PSYS_OK);
        CHECK(psys_system_compute_forces(ss, fs) == PSYS_OK);
        double scale = max_abs(fs, (size_t)(N * dim));
        CHECK(scale > 1);
        for (int i = 0; i < N * dim; i++)
            CHECK_NEAR(fb[i], fs[i], 1e-13 * scale);
        CHECK_NEAR(psys_system_potential_energy(sb), psys_system_potential_energy(ss),
                   1e-13 * psys_system_potential_energy(ss));
        psys_system_destroy(sb);
        psys_system_destroy(ss);
    }
}

static void distance_equals_spring_2d(void) { distance_vs_spring(2); }
static void distance_equals_spring_3d(void) { distance_vs_spring(3); }

/* ---- coincide: f1 = -ks(x1 - x2) - kd(v1 - v2), f2 = -f1
 * (docs/notes-errata.md#6-coincide-is-not-an-eq-1-spring-of-rest-length-0) ---- */

static void coincide_closed_form(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        double x1[3] = {0.3, -1.2, 2.5}, x2[3] = {1.1, 0.4, -0.7};
        double v1[3] = {0.5, 2.0, -1.0}, v2[3] = {-1.5, 0.25, 0.75};
        double ks = 7.5, kd = 1.25;
        psys_system *sys = make_system(dim), *spr = make_system(dim);
        size_t idx[2] = {add_particle(sys, x1, v1, 1.0), add_particle(sys, x2, v2, 1.0)};
        add_particle(spr, x1, v1, 1.0);
        add_particle(spr, x2, v2, 1.0);
        psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_COINCIDE, 2, idx, ks, kd);
        add_behavior_ok(sys, &def);
        CHECK(psys_system_add_spring(spr, 0, 1, ks, kd, 0.0) == PSYS_OK);
        double f[6], fs[6];
        psys_system_compute_forces(sys, f);
        psys_system_compute_forces(spr, fs);
        double diff = 0;
        for (int c = 0; c < dim; c++) {
            double f1 = -ks * (x1[c] - x2[c]) - kd * (v1[c] - v2[c]);
            CHECK_NEAR(f[c], f1, 1e-13);
            CHECK_NEAR(f[dim + c], -f1, 1e-13);
            diff = fmax(diff, fabs(f[c] - fs[c]));
        }
        /* The relative velocity has a component across l, so the r = 0
         * eq. 1 spring (damping only along l) must differ... */
        CHECK(diff > 0.1);
        psys_system_destroy(sys);
        psys_system_destroy(spr);

        /* ...and agree when kd = 0. */
        sys = make_system(dim);
        spr = make_system(dim);
        add_particle(sys, x1, v1, 1.0);
        add_particle(sys, x2, v2, 1.0);
        add_particle(spr, x1, v1, 1.0);
        add_particle(spr, x2, v2, 1.0);
        def.kd = 0;
        add_behavior_ok(sys, &def);
        CHECK(psys_system_add_spring(spr, 0, 1, ks, 0.0, 0.0) == PSYS_OK);
        psys_system_compute_forces(sys, f);
        psys_system_compute_forces(spr, fs);
        for (int c = 0; c < 2 * dim; c++)
            CHECK_NEAR(f[c], fs[c], 1e-13);
        psys_system_destroy(sys);
        psys_system_destroy(spr);
    }
}

/* ---- one-particle built-ins against hand-computed values ---- */

static void one_particle_force(int dim, psys_behavior_def def, const double *x, const double *v, const double *want)
{
    psys_system *sys = make_system(dim);
    def.nparticles = 1;
    def.particles[0] = add_particle(sys, x, v, 1.0);
    add_behavior_ok(sys, &def);
    double f[3];
    psys_system_compute_forces(sys, f);
    for (int c = 0; c < dim; c++)
        CHECK_NEAR(f[c], want[c], 1e-12);
    psys_system_destroy(sys);
}

static void point_on_plane_force(void)
{
    /* 2-D: n = (3, 4) -> n̂ = (0.6, 0.8); x - p = (1, 2): C = 2.2;
     * v = (1, -1): Ċ = -0.2; λ = 5·2.2 + 0.5·(-0.2) = 10.9; f = -λ n̂. */
    psys_behavior_def def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_PLANE;
    def.ks = 5;
    def.kd = 0.5;
    def.point[0] = 1, def.point[1] = 1;
    def.normal[0] = 3, def.normal[1] = 4;
    one_particle_force(2, def, (double[]){2, 3}, (double[]){1, -1}, (double[]){-6.54, -8.72});
    /* 3-D: n = (0, 0, 2), p = (0, 1, 0), x = (1, 2, 3): C = 3; v_z = 0.25;
     * λ = 10·3 + 2·0.25 = 30.5. */
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_PLANE;
    def.ks = 10;
    def.kd = 2;
    def.point[1] = 1;
    def.normal[2] = 2;
    one_particle_force(3, def, (double[]){1, 2, 3}, (double[]){0.5, -1, 0.25}, (double[]){0, 0, -30.5});
    /* On the plane and moving along it: no force. */
    one_particle_force(3, def, (double[]){7, -3, 0}, (double[]){0.5, -1, 0}, (double[]){0, 0, 0});
}

static void point_on_sphere_force(void)
{
    /* Circle in 2-D: c = (1, 0), R = 1, x = (4, 4): d = (3, 4), C = 4,
     * u = (0.6, 0.8); v = (1, 2): Ċ = 2.2; λ = 3·4 + 0.5·2.2 = 13.1. */
    psys_behavior_def def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_SPHERE;
    def.ks = 3;
    def.kd = 0.5;
    def.center[0] = 1;
    def.radius = 1;
    one_particle_force(2, def, (double[]){4, 4}, (double[]){1, 2}, (double[]){-7.86, -10.48});
    /* Inside the circle: pushed outwards. x = (1, 0.5): C = -0.5, u = (0, 1). */
    one_particle_force(2, def, (double[]){1, 0.5}, (double[]){0, 0}, (double[]){0, 1.5});
    /* Sphere in 3-D: c = 0, R = 2, x = (0, 3, 4): C = 3, u = (0, 0.6, 0.8);
     * v = (0, 0, 1): Ċ = 0.8; λ = 2·3 + 1·0.8 = 6.8. */
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_SPHERE;
    def.ks = 2;
    def.kd = 1;
    def.radius = 2;
    one_particle_force(3, def, (double[]){0, 3, 4}, (double[]){0, 0, 1}, (double[]){0, -4.08, -5.44});
}

/* ---- angle ---- */

static void angle_forces(int dim, const double *x, const double *v, double rest, double ks, double kd,
                         double *f /* 3*dim */)
{
    psys_system *sys = make_system(dim);
    size_t idx[3];
    for (int i = 0; i < 3; i++)
        idx[i] = add_particle(sys, x + i * dim, v ? v + i * dim : NULL, 1.0);
    psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_ANGLE, 3, idx, ks, kd);
    def.angle = rest;
    add_behavior_ok(sys, &def);
    psys_system_compute_forces(sys, f);
    psys_system_destroy(sys);
}

static double angle_at(int dim, const double *x)
{
    double C;
    psys_behavior_def def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_ANGLE;
    def.nparticles = 3;
    def.angle = 0;
    CHECK(psys_behavior_eval(&def, dim, x, &C, NULL, NULL) == PSYS_OK);
    return C;
}

static void angle_hand_values(void)
{
    /* a = e_x, b = 0, c = e_y: θ = π/2, rest π/3, ks = 2: C = π/6;
     * ∂θ/∂a = -e_y, ∂θ/∂c = -e_x, so f_a = ks C e_y, f_c = ks C e_x:
     * both arms are pulled toward each other (the angle closes). */
    double x[9] = {1, 0, 0, 0, 0, 0, 0, 1, 0}, f[9];
    angle_forces(3, x, NULL, PI / 3, 2, 0, f);
    double g = 2 * (PI / 6);
    double want[9] = {0, g, 0, -g, -g, 0, g, 0, 0};
    for (int i = 0; i < 9; i++)
        CHECK_NEAR(f[i], want[i], 1e-14);
    /* Arms of length 2: the gradient, hence the force, halves. */
    double x2[6] = {2, 0, 0, 0, 0, 2}, f2[6];
    angle_forces(2, x2, NULL, PI / 3, 2, 0, f2);
    CHECK_NEAR(f2[1], g / 2, 1e-14);
    CHECK_NEAR(f2[4], g / 2, 1e-14);
}

static void angle_rest_restores_no_net_force_or_torque(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (int trial = 0; trial < 40; trial++) {
            double x[9], v[9], f[9];
            for (int i = 0; i < 3 * dim; i++) {
                x[i] = urand(-1, 1);
                v[i] = urand(-1, 1);
            }
            double theta = angle_at(dim, x);
            /* At the rest angle, at rest: no force at all. */
            angle_forces(dim, x, NULL, -1, 10, 0.5, f);
            CHECK(max_abs(f, (size_t)(3 * dim)) <= 1e-12);
            /* Away from it, moving: no net force and no net torque. */
            double rest = urand(0, PI);
            angle_forces(dim, x, v, rest, 10, 0.5, f);
            double sum[3] = {0, 0, 0}, torque[3] = {0, 0, 0};
            for (int i = 0; i < 3; i++) {
                const double *p = x + i * dim, *fi = f + i * dim;
                for (int c = 0; c < dim; c++)
                    sum[c] += fi[c];
                if (dim == 2) {
                    torque[2] += p[0] * fi[1] - p[1] * fi[0];
                } else {
                    torque[0] += p[1] * fi[2] - p[2] * fi[1];
                    torque[1] += p[2] * fi[0] - p[0] * fi[2];
                    torque[2] += p[0] * fi[1] - p[1] * fi[0];
                }
            }
            double scale = max_abs(f, (size_t)(3 * dim));
            CHECK(scale > 0);
            for (int c = 0; c < 3; c++) {
                CHECK_NEAR(sum[c], 0, 1e-12 * scale);
                CHECK_NEAR(torque[c], 0, 1e-12 * scale);
            }
            /* Restoring: a small step along the (undamped) force moves θ
             * toward the rest angle. */
            angle_forces(dim, x, NULL, rest, 10, 0, f);
            double step = 1e-4 / fmax(1, max_abs(f, (size_t)(3 * dim))), xs[9];
            for (int i = 0; i < 3 * dim; i++)
                xs[i] = x[i] + step * f[i];
            CHECK(fabs(angle_at(dim, xs) - rest) < fabs(theta - rest));
        }
}

/* ---- energies ½ ks C·C ---- */

static double energy_of(int dim, const double *x, int k, psys_behavior_def def)
{
    psys_system *sys = make_system(dim);
    def.nparticles = k;
    for (int i = 0; i < k; i++)
        def.particles[i] = add_particle(sys, x + i * dim, NULL, 1.0);
    add_behavior_ok(sys, &def);
    double u = psys_system_potential_energy(sys);
    psys_system_destroy(sys);
    return u;
}

static void energies(void)
{
    psys_behavior_def def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_COINCIDE;
    def.ks = 3;
    /* l = (1, 2, 2): ½·3·9 */
    CHECK_NEAR(energy_of(3, (double[]){1, 2, 2, 0, 0, 0}, 2, def), 13.5, 1e-14);
    def.function = PSYS_BEHAVIOR_DISTANCE;
    def.ks = 4;
    def.r = 3;
    /* |l| = 5: ½·4·2² */
    CHECK_NEAR(energy_of(2, (double[]){3, 4, 0, 0}, 2, def), 8, 1e-14);
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_PLANE;
    def.ks = 5;
    def.point[0] = 1, def.point[1] = 1;
    def.normal[0] = 3, def.normal[1] = 4;
    /* C = 2.2 */
    CHECK_NEAR(energy_of(2, (double[]){2, 3}, 1, def), 0.5 * 5 * 2.2 * 2.2, 1e-13);
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_POINT_ON_SPHERE;
    def.ks = 2;
    def.radius = 2;
    /* C = 3 */
    CHECK_NEAR(energy_of(3, (double[]){0, 3, 4}, 1, def), 9, 1e-14);
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_ANGLE;
    def.ks = 2;
    def.angle = PI / 3;
    /* C = π/6 */
    CHECK_NEAR(energy_of(3, (double[]){1, 0, 0, 0, 0, 0, 0, 1, 0}, 3, def), (PI / 6) * (PI / 6), 1e-14);
}

/* ---- Jacobians ---- */

/* C = [x0² + y1, x0·y0] on two 2-D particles; `wrong` corrupts ∂C1/∂y0. */
typedef struct poly_ctx {
    bool wrong;
    int calls_with_j, calls_without_j;
} poly_ctx;

static void poly_eval(void *ctx, int dim, const double *x, double *C, double *J)
{
    poly_ctx *pc = ctx;
    (void)dim;
    C[0] = x[0] * x[0] + x[3];
    C[1] = x[0] * x[1];
    if (!J) {
        pc->calls_without_j++;
        return;
    }
    pc->calls_with_j++;
    double Jv[8] = {2 * x[0], 0, 0, 1, x[1], x[0] + (pc->wrong ? 0.5 : 0.0), 0, 0};
    memcpy(J, Jv, sizeof Jv);
}

static void checker_catches_wrong_jacobian(void)
{
    poly_ctx pc = {true, 0, 0};
    psys_behavior_def def = psys_behavior_def_default();
    def.nparticles = 2;
    def.ncomponents = 2;
    def.eval = poly_eval;
    def.ctx = &pc;
    double x[4] = {0.7, -1.3, 2.0, 0.4}, worst = -1;
    int row = -1, col = -1;
    CHECK(psys_behavior_check_jacobian(&def, 2, x, 1e-6, &worst, &row, &col) == PSYS_OK);
    CHECK_NEAR(worst, 0.5, 1e-6);
    CHECK(row == 1);
    CHECK(col == 1);
    pc.wrong = false;
    CHECK(psys_behavior_check_jacobian(&def, 2, x, 1e-6, &worst, &row, &col) == PSYS_OK);
    CHECK(worst < 1e-8);
    /* The checker asks for the analytic J even for an fd_jacobian def. */
    pc.wrong = true;
    def.fd_jacobian = true;
    CHECK(psys_behavior_check_jacobian(&def, 2, x, 0, &worst, &row, &col) == PSYS_OK);
    CHECK(worst > 0.4);
    /* A missing eval is an error, not a crash. */
    def.eval = NULL;
    CHECK(psys_behavior_check_jacobian(&def, 2, x, 0, &worst, &row, &col) == PSYS_ERR_INVALID);
}

static void builtin_jacobians_pass_checker(void)
{
    static const psys_behavior_function fs[] = {PSYS_BEHAVIOR_COINCIDE, PSYS_BEHAVIOR_DISTANCE,
                                                PSYS_BEHAVIOR_POINT_ON_PLANE, PSYS_BEHAVIOR_POINT_ON_SPHERE,
                                                PSYS_BEHAVIOR_ANGLE};
    static const int ks[] = {2, 2, 1, 1, 3};
    for (int dim = 2; dim <= 3; dim++)
        for (int fi = 0; fi < 5; fi++)
            for (int trial = 0; trial < 20; trial++) {
                psys_behavior_def def = psys_behavior_def_default();
                def.function = fs[fi];
                def.nparticles = ks[fi];
                def.r = urand(0, 2);
                def.radius = urand(0, 2);
                def.angle = urand(0, PI);
                for (int c = 0; c < dim; c++) {
                    def.point[c] = urand(-1, 1);
                    def.normal[c] = urand(-1, 1);
                    def.center[c] = urand(-1, 1);
                }
                double x[9], worst = -1;
                int row = -1, col = -1;
                for (int i = 0; i < ks[fi] * dim; i++)
                    x[i] = urand(-2, 2);
                CHECK(psys_behavior_check_jacobian(&def, dim, x, 1e-6, &worst, &row, &col) == PSYS_OK);
                if (!(worst < 1e-7))
                    fprintf(stderr, "%s dim %d: worst %g at (%d, %d)\n", psys_behavior_function_name(fs[fi]), dim,
                            worst, row, col);
                CHECK(worst < 1e-7);
                CHECK(row >= 0 && row < psys_behavior_components(&def, dim));
                CHECK(col >= 0 && col < ks[fi] * dim);
            }
}

/* The force Jacobian is the Gauss–Newton form -ks JᵀJ, -kd JᵀJ; for an
 * affine C (coincide) it is exact, so it matches finite differences. */
static void force_jacobian_gauss_newton(void)
{
    int dim = 3;
    psys_system *sys = make_system(dim);
    double x[9] = {0.3, -0.2, 1.0, 1.4, 0.9, -0.5, -0.8, 0.6, 0.2}, v[9] = {0.1, 0.2, -0.3, 0, 1, 0, -1, 0, 0.5};
    for (int i = 0; i < 3; i++)
        add_particle(sys, x + 3 * i, v + 3 * i, 1.0);
    psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_ANGLE, 3, (size_t[]){2, 0, 1}, 3.0, 0.7);
    def.angle = 1.0;
    add_behavior_ok(sys, &def);
    double Jdx[81], Jdv[81], C, Jc[9];
    CHECK(psys_system_dense_jacobian(sys, Jdx, Jdv) == PSYS_OK);
    double xl[9];
    memcpy(xl, x + 6, 3 * sizeof(double));
    memcpy(xl + 3, x, 3 * sizeof(double));
    memcpy(xl + 6, x + 3, 3 * sizeof(double));
    CHECK(psys_behavior_eval(&def, dim, xl, &C, Jc, NULL) == PSYS_OK);
    size_t slot_of[3] = {1, 2, 0}; /* particle -> slot */
    for (int r = 0; r < 9; r++)
        for (int c = 0; c < 9; c++) {
            double jj = Jc[slot_of[r / 3] * 3 + r % 3] * Jc[slot_of[c / 3] * 3 + c % 3];
            CHECK_NEAR(Jdx[r * 9 + c], -3.0 * jj, 1e-13);
            CHECK_NEAR(Jdv[r * 9 + c], -0.7 * jj, 1e-13);
        }
    psys_system_destroy(sys);

    sys = make_system(dim);
    for (int i = 0; i < 3; i++)
        add_particle(sys, x + 3 * i, v + 3 * i, 1.0);
    def = builtin_def(PSYS_BEHAVIOR_COINCIDE, 2, (size_t[]){0, 2}, 4.0, 1.5);
    add_behavior_ok(sys, &def);
    def = builtin_def(PSYS_BEHAVIOR_POINT_ON_PLANE, 1, (size_t[]){1}, 2.0, 0.5);
    def.normal[0] = 1, def.normal[1] = -2, def.normal[2] = 0.5;
    add_behavior_ok(sys, &def);
    double Fdx[81], Fdv[81];
    CHECK(psys_system_dense_jacobian(sys, Jdx, Jdv) == PSYS_OK);
    CHECK(psys_system_fd_jacobian(sys, 1e-6, Fdx, Fdv) == PSYS_OK);
    for (int i = 0; i < 81; i++) {
        CHECK_NEAR(Jdx[i], Fdx[i], 1e-7);
        CHECK_NEAR(Jdv[i], Fdv[i], 1e-7);
    }
    CHECK_NEAR(Jdx[0], -4.0, 1e-15);     /* ∂f_0x/∂x_0x = -ks */
    CHECK_NEAR(Jdv[0 * 9 + 6], 1.5, 1e-15); /* ∂f_0x/∂v_2x = +kd */
    psys_system_destroy(sys);
}

/* Zero-length cases: no NaN, no force. */
static void degenerate_cases_no_nan(void)
{
    double f[9];
    /* distance with coincident particles */
    psys_system *sys = make_system(3);
    double p[3] = {1, 2, 3}, v1[3] = {1, 0, 0}, v2[3] = {0, 1, 0};
    add_particle(sys, p, v1, 1.0);
    add_particle(sys, p, v2, 1.0);
    psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_DISTANCE, 2, (size_t[]){0, 1}, 5, 1);
    def.r = 0.5;
    add_behavior_ok(sys, &def);
    psys_system_compute_forces(sys, f);
    for (int i = 0; i < 6; i++)
        CHECK(f[i] == 0);
    CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * 5 * 0.25, 1e-15);
    double Jx[36], Jv[36];
    CHECK(psys_system_dense_jacobian(sys, Jx, Jv) == PSYS_OK);
    for (int i = 0; i < 36; i++)
        CHECK(Jx[i] == 0 && Jv[i] == 0);
    psys_system_destroy(sys);
    /* point-on-sphere at the center */
    sys = make_system(2);
    add_particle(sys, (double[]){1, 1}, (double[]){3, 4}, 1.0);
    def = builtin_def(PSYS_BEHAVIOR_POINT_ON_SPHERE, 1, (size_t[]){0}, 5, 1);
    def.center[0] = 1, def.center[1] = 1;
    def.radius = 2;
    add_behavior_ok(sys, &def);
    psys_system_compute_forces(sys, f);
    CHECK(f[0] == 0 && f[1] == 0);
    CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * 5 * 4, 1e-15);
    psys_system_destroy(sys);
    /* angle at θ = π, θ = 0, and with a zero arm */
    static const double cfg[3][9] = {
        {-1, 0, 0, 0, 0, 0, 2, 0, 0}, /* straight: θ = π */
        {1, 0, 0, 0, 0, 0, 2, 0, 0},  /* folded: θ = 0 */
        {0, 0, 0, 0, 0, 0, 2, 1, 0},  /* a on the vertex */
    };
    for (int k = 0; k < 3; k++) {
        for (int dim = 2; dim <= 3; dim++) {
            double x[9];
            for (int i = 0; i < 3; i++)
                for (int c = 0; c < dim; c++)
                    x[i * dim + c] = cfg[k][i * 3 + c];
            angle_forces(dim, x, (double[]){0, 1, 0, 1, 0, 0, 0, 0, 1}, 1.0, 5, 1, f);
            for (int i = 0; i < 3 * dim; i++)
                CHECK(f[i] == 0);
            double C;
            psys_behavior_def ad = psys_behavior_def_default();
            ad.function = PSYS_BEHAVIOR_ANGLE;
            ad.nparticles = 3;
            ad.angle = 1.0;
            CHECK(psys_behavior_eval(&ad, dim, x, &C, NULL, NULL) == PSYS_OK);
            CHECK(isfinite(C));
        }
    }
    CHECK_NEAR(angle_at(2, (double[]){-1, 0, 0, 0, 2, 0}), PI, 1e-15);
    CHECK_NEAR(angle_at(3, cfg[1]), 0, 1e-15);
}

/* ---- user-defined functions ---- */

/* C = y - p·x² (the parabola y = p x²) on one 2-D particle. */
static void parabola_eval(void *ctx, int dim, const double *x, double *C, double *J)
{
    double p = *(const double *)ctx;
    (void)dim;
    C[0] = x[1] - p * x[0] * x[0];
    if (J) {
        J[0] = -2 * p * x[0];
        J[1] = 1;
    }
}

/* Two components over three 3-D particles, nonlinear. */
static void twist_eval(void *ctx, int dim, const double *x, double *C, double *J)
{
    (void)ctx;
    (void)dim;
    const double *a = x, *b = x + 3, *c = x + 6;
    C[0] = a[0] * b[1] - a[1] * b[0] + sin(c[2]);
    C[1] = (a[2] - c[0]) * (a[2] - c[0]) + exp(0.1 * b[2]) - 1.5;
    if (!J)
        return;
    memset(J, 0, 2 * 9 * sizeof(double));
    J[0] = b[1];
    J[1] = -b[0];
    J[3] = -a[1];
    J[4] = a[0];
    J[8] = cos(c[2]);
    J[9 + 2] = 2 * (a[2] - c[0]);
    J[9 + 5] = 0.1 * exp(0.1 * b[2]);
    J[9 + 6] = -2 * (a[2] - c[0]);
}

static void fd_jacobian_matches_analytic(void)
{
    double x[9] = {0.4, -1.1, 0.8, 1.3, 0.2, -0.6, 0.9, 0.35, 2.2};
    double v[9] = {0.5, 0.1, -0.2, -0.7, 1.0, 0.3, 0.2, -0.4, 0.9};
    double f[2][9];
    for (int w = 0; w < 2; w++) {
        psys_system *sys = make_system(3);
        for (int i = 0; i < 3; i++)
            add_particle(sys, x + 3 * i, v + 3 * i, 1.0);
        psys_behavior_def def = psys_behavior_def_default();
        def.nparticles = 3;
        def.particles[0] = 0, def.particles[1] = 1, def.particles[2] = 2;
        def.ncomponents = 2;
        def.eval = twist_eval;
        def.ks = 20;
        def.kd = 3;
        def.fd_jacobian = w == 1;
        add_behavior_ok(sys, &def);
        CHECK(psys_system_force_class(sys, 0) == &psys_behavior_user_class);
        psys_system_compute_forces(sys, f[w]);
        psys_system_destroy(sys);
    }
    double scale = max_abs(f[0], 9);
    CHECK(scale > 1);
    for (int i = 0; i < 9; i++)
        CHECK_NEAR(f[1][i], f[0][i], 1e-7 * scale);
    /* The analytic J of twist_eval is right. */
    psys_behavior_def def = psys_behavior_def_default();
    def.nparticles = 3;
    def.ncomponents = 2;
    def.eval = twist_eval;
    double worst;
    CHECK(psys_behavior_check_jacobian(&def, 3, x, 1e-6, &worst, NULL, NULL) == PSYS_OK);
    CHECK(worst < 1e-8);
}

/* A bead on the parabola y = x² under gravity, held by a user behaviour:
 * it slides down, through the bottom and up the other side, staying on the
 * curve; analytic and finite-difference J give the same motion. */
static void user_parabola_simulation(void)
{
    double p = 1.0, track[2][2];
    for (int w = 0; w < 2; w++) {
        psys_system *sys = make_system(2);
        add_particle(sys, (double[]){0.5, 0.25}, NULL, 1.0);
        CHECK(psys_system_add_gravity(sys, (double[]){0, -9.81}) == PSYS_OK);
        psys_behavior_def def = psys_behavior_def_default();
        def.nparticles = 1;
        def.particles[0] = 0;
        def.eval = parabola_eval;
        def.ctx = &p;
        def.ks = 1e4;
        def.kd = 20;
        def.fd_jacobian = w == 1;
        add_behavior_ok(sys, &def);
        psys_error err;
        psys_solver *s = psys_system_solver_create(sys, "rk4", &err);
        CHECK(s != NULL);
        if (!s)
            return;
        double worst_c = 0, min_x = 1, max_y_after = 0;
        for (int step = 0; step < 1500; step++) {
            CHECK(psys_solver_step(s, 1e-3, NULL) == PSYS_OK);
            const double *x = psys_system_positions(sys);
            worst_c = fmax(worst_c, fabs(x[1] - p * x[0] * x[0]));
            min_x = fmin(min_x, x[0]);
            if (x[0] < 0)
                max_y_after = fmax(max_y_after, x[1]);
        }
        /* On the curve within the sag of a stiff penalty spring... */
        CHECK(worst_c < 5e-3);
        /* ...it went across and climbed most of the way back up (energy
         * is nearly conserved: damping acts only across the curve). */
        CHECK(min_x < -0.45);
        CHECK(max_y_after > 0.2);
        CHECK(max_y_after < 0.2501);
        memcpy(track[w], psys_system_positions(sys), 2 * sizeof(double));
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
    CHECK_NEAR(track[1][0], track[0][0], 1e-5);
    CHECK_NEAR(track[1][1], track[0][1], 1e-5);
}

/* ---- C API validation ---- */

static void expect_add_error(psys_system *sys, const psys_behavior_def *def, const char *msg)
{
    size_t before = psys_system_force_count(sys);
    CHECK(psys_system_add_behavior(sys, def) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), msg);
    CHECK(psys_system_force_count(sys) == before);
}

static void api_validation(void)
{
    psys_system *sys = make_system(2);
    add_particle(sys, (double[]){0, 0}, NULL, 1.0);
    add_particle(sys, (double[]){1, 0}, NULL, 1.0);
    add_particle(sys, (double[]){2, 1}, NULL, 1.0);
    psys_behavior_def def = builtin_def(PSYS_BEHAVIOR_DISTANCE, 2, (size_t[]){0, 0}, 1, 0);
    expect_add_error(sys, &def, "a behaviour's particles must be different (particle 0 is listed twice)");
    def.particles[1] = 3;
    expect_add_error(sys, &def, "behaviour refers to particle 3, which does not exist");
    def.particles[1] = 1;
    def.nparticles = 3;
    def.particles[2] = 2;
    expect_add_error(sys, &def, "behaviour \"distance\" needs exactly 2 particles (got 3)");
    def.nparticles = 9;
    expect_add_error(sys, &def, "behaviour nparticles must be 1 to 8 (got 9)");
    def.nparticles = 2;
    def.ks = -1;
    expect_add_error(sys, &def, "behaviour ks and kd must be finite and >= 0");
    def.ks = 1;
    def.kd = NAN;
    expect_add_error(sys, &def, "behaviour ks and kd must be finite and >= 0");
    def = builtin_def(PSYS_BEHAVIOR_POINT_ON_PLANE, 1, (size_t[]){0}, 1, 0);
    expect_add_error(sys, &def, "point-on-plane normal must be a nonzero vector");
    def = builtin_def(PSYS_BEHAVIOR_POINT_ON_SPHERE, 1, (size_t[]){0}, 1, 0);
    def.radius = -1;
    expect_add_error(sys, &def, "point-on-sphere radius must be finite and >= 0");
    def = builtin_def(PSYS_BEHAVIOR_ANGLE, 3, (size_t[]){0, 1, 2}, 1, 0);
    def.angle = 4;
    expect_add_error(sys, &def, "angle must be finite and at most pi");
    def = builtin_def(PSYS_BEHAVIOR_USER, 1, (size_t[]){0}, 1, 0);
    expect_add_error(sys, &def, "a user-defined behaviour needs an eval function");
    def.eval = parabola_eval;
    def.ncomponents = 10;
    expect_add_error(sys, &def, "behaviour ncomponents must be 1 to 9 (got 10)");
    def.ncomponents = 1;
    def.fd_jacobian = true;
    def.fd_step = 0;
    expect_add_error(sys, &def, "behaviour fd_step must be finite and > 0");
    CHECK(psys_system_add_behavior(sys, NULL) == PSYS_ERR_INVALID);

    /* Defaults resolved at add time and read back. */
    def = builtin_def(PSYS_BEHAVIOR_DISTANCE, 2, (size_t[]){0, 2}, 1, 0);
    add_behavior_ok(sys, &def);
    def = builtin_def(PSYS_BEHAVIOR_ANGLE, 3, (size_t[]){1, 0, 2}, 1, 0);
    add_behavior_ok(sys, &def);
    psys_behavior_def got;
    CHECK(psys_system_behavior(sys, 0, &got) == PSYS_OK);
    CHECK(got.function == PSYS_BEHAVIOR_DISTANCE);
    CHECK(got.r == sqrt(5.0)); /* (0,0)-(2,1) */
    CHECK(psys_system_behavior(sys, 1, &got) == PSYS_OK);
    CHECK_NEAR(got.angle, atan2(1, 2), 1e-15); /* vertex (0,0), arms (1,0) and (2,1) */
    CHECK(psys_system_behavior(sys, 5, &got) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_drag(sys, 0.1) == PSYS_OK);
    CHECK(psys_system_behavior(sys, 2, &got) == PSYS_ERR_INVALID);

    /* Names. */
    psys_behavior_function fn = PSYS_BEHAVIOR_USER;
    CHECK(psys_behavior_function_from_name("point-on-sphere", &fn) == PSYS_OK);
    CHECK(fn == PSYS_BEHAVIOR_POINT_ON_SPHERE);
    CHECK(psys_behavior_function_from_name("glue", &fn) == PSYS_ERR_INVALID);
    CHECK_STR(psys_behavior_function_name(PSYS_BEHAVIOR_ANGLE), "angle");
    CHECK(psys_behavior_function_name(PSYS_BEHAVIOR_USER) == NULL);
    def = psys_behavior_def_default();
    def.function = PSYS_BEHAVIOR_COINCIDE;
    CHECK(psys_behavior_components(&def, 3) == 3);
    CHECK(psys_behavior_components(&def, 2) == 2);
    psys_system_destroy(sys);
}

/* ---- scenes ---- */

static psys_scene *load(const char *text, psys_error *err)
{
    return psys_scene_load_string(text, strlen(text), err);
}

static const char *const scene3 =
    "{\"psys\": 1, \"dim\": 3, \"particles\": ["
    " {\"id\": \"a\", \"x\": [0.1, 0.2, 0.3], \"v\": [0.7, -0.1, 0.05]},"
    " {\"id\": \"b\", \"x\": [1.0, 0.33, -0.7], \"v\": [-0.3, 0.2, 0.1], \"mass\": 0.3},"
    " {\"id\": \"c\", \"x\": [0.45, 1.7, 0.9]},"
    " {\"x\": [-0.6, 0.25, 1.1], \"v\": [0.1, 0.1, 0.1]}],"
    " \"forces\": ["
    "  {\"type\": \"behavior\", \"function\": \"coincide\", \"particles\": [\"a\", 3], \"ks\": 0.7, \"kd\": 0.1},"
    "  {\"type\": \"spring\", \"a\": \"a\", \"b\": \"c\", \"ks\": 10},"
    "  {\"type\": \"behavior\", \"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"ks\": 50},"
    "  {\"type\": \"behavior\", \"function\": \"distance\", \"particles\": [\"b\", \"c\"], \"r\": 0.3, \"ks\": 5, \"kd\": 0.3},"
    "  {\"type\": \"behavior\", \"function\": \"point-on-plane\", \"particles\": [\"c\"],"
    "   \"point\": [0.1, 0.2, 0.3], \"normal\": [1, 2, 2], \"ks\": 3.3, \"kd\": 0.01},"
    "  {\"type\": \"behavior\", \"function\": \"point-on-sphere\", \"particles\": [3],"
    "   \"center\": [0.3, 0.1, -0.2], \"radius\": 0.9, \"ks\": 1e3},"
    "  {\"type\": \"behavior\", \"function\": \"angle\", \"particles\": [\"a\", \"b\", \"c\"], \"ks\": 2.5, \"kd\": 0.2},"
    "  {\"type\": \"behavior\", \"function\": \"angle\", \"particles\": [\"c\", \"a\", 3], \"angle\": 1.1, \"ks\": 1}]}";

static const char *const scene2 =
    "{\"psys\": 1, \"dim\": 2, \"particles\": ["
    " {\"id\": \"a\", \"x\": [0.1, 0.2]}, {\"id\": \"b\", \"x\": [1.3, -0.7], \"v\": [0.1, 0.3]},"
    " {\"id\": \"c\", \"x\": [0.45, 1.7]}],"
    " \"forces\": ["
    "  {\"type\": \"behavior\", \"function\": \"coincide\", \"particles\": [\"a\", \"b\"], \"ks\": 1},"
    "  {\"type\": \"behavior\", \"function\": \"distance\", \"particles\": [\"a\", \"c\"], \"ks\": 2, \"kd\": 0.1},"
    "  {\"type\": \"behavior\", \"function\": \"point-on-plane\", \"particles\": [\"a\"],"
    "   \"point\": [0, 0], \"normal\": [0.1, 0.3], \"ks\": 3},"
    "  {\"type\": \"behavior\", \"function\": \"point-on-sphere\", \"particles\": [\"b\"],"
    "   \"center\": [0.3, 0.1], \"radius\": 0, \"ks\": 4},"
    "  {\"type\": \"behavior\", \"function\": \"angle\", \"particles\": [\"a\", \"b\", \"c\"], \"ks\": 5}]}";

/* Field by field (bit-exact numbers): memcmp would see struct padding. */
static bool def_equal(const psys_behavior_def *a, const psys_behavior_def *b)
{
#define SAME(v) (memcmp(&a->v, &b->v, sizeof a->v) == 0)
    return a->function == b->function && a->nparticles == b->nparticles && SAME(particles) && SAME(ks)
           && SAME(kd) && a->ncomponents == b->ncomponents && SAME(r) && SAME(point) && SAME(normal)
           && SAME(center) && SAME(radius) && SAME(angle);
#undef SAME
}

static void round_trip(const char *text, size_t nforces)
{
    psys_error err;
    psys_scene *s1 = load(text, &err);
    if (!s1)
        fprintf(stderr, "load: %s\n", err.message);
    CHECK(s1 != NULL);
    if (!s1)
        return;
    psys_system *sys1 = psys_scene_system(s1);
    CHECK(psys_system_force_count(sys1) == nforces);
    char *t1 = psys_scene_to_string(s1, NULL, &err);
    CHECK(t1 != NULL);
    psys_scene *s2 = t1 ? load(t1, &err) : NULL;
    if (t1 && !s2)
        fprintf(stderr, "reload: %s\n%s\n", err.message, t1);
    CHECK(s2 != NULL);
    if (!s2) {
        free(t1);
        psys_scene_destroy(s1);
        return;
    }
    char *t2 = psys_scene_to_string(s2, NULL, &err);
    CHECK_STR(t2, t1);
    /* Defaults were written explicitly. */
    CHECK(strstr(t1, "\"r\":") != NULL);
    CHECK(strstr(t1, "\"angle\":") != NULL);
    /* Same system: same definitions, forces and energy to the last bit. */
    psys_system *sys2 = psys_scene_system(s2);
    CHECK(psys_system_force_count(sys2) == nforces);
    for (size_t i = 0; i < nforces; i++) {
        psys_behavior_def d1, d2;
        bool b1 = psys_system_behavior(sys1, i, &d1) == PSYS_OK, b2 = psys_system_behavior(sys2, i, &d2) == PSYS_OK;
        CHECK(b1 == b2);
        if (b1 && b2)
            CHECK(def_equal(&d1, &d2));
    }
    size_t nd = psys_system_count(sys1) * (size_t)psys_system_dim(sys1);
    double f1[12], f2[12];
    psys_system_compute_forces(sys1, f1);
    psys_system_compute_forces(sys2, f2);
    CHECK(memcmp(f1, f2, nd * sizeof(double)) == 0);
    CHECK(max_abs(f1, nd) > 0);
    double u1 = psys_system_potential_energy(sys1), u2 = psys_system_potential_energy(sys2);
    CHECK(memcmp(&u1, &u2, sizeof u1) == 0);
    free(t1);
    free(t2);
    psys_scene_destroy(s1);
    psys_scene_destroy(s2);
}

static void scene_round_trip_3d(void) { round_trip(scene3, 8); }
static void scene_round_trip_2d(void) { round_trip(scene2, 5); }

/* Values the loader resolves and keeps. */
static void scene_resolved_values(void)
{
    psys_error err;
    psys_scene *s = load(scene3, &err);
    CHECK(s != NULL);
    if (!s)
        return;
    psys_system *sys = psys_scene_system(s);
    psys_behavior_def d;
    CHECK(psys_system_behavior(sys, 2, &d) == PSYS_OK); /* distance a-b, r defaulted */
    double dx = 0.1 - 1.0, dy = 0.2 - 0.33, dz = 0.3 + 0.7;
    CHECK_NEAR(d.r, sqrt(dx * dx + dy * dy + dz * dz), 1e-15);
    CHECK(d.kd == 0);
    CHECK(psys_system_behavior(sys, 4, &d) == PSYS_OK); /* plane: normal kept as given */
    CHECK(d.normal[0] == 1 && d.normal[1] == 2 && d.normal[2] == 2);
    CHECK(psys_system_behavior(sys, 7, &d) == PSYS_OK);
    CHECK(d.angle == 1.1);
    CHECK(d.particles[0] == 2 && d.particles[1] == 0 && d.particles[2] == 3);
    /* The plane force uses the unit normal (1, 2, 2)/3. */
    psys_scene_destroy(s);
    s = load("{\"psys\": 1, \"particles\": [{\"x\": [0, 0, 3]}], \"forces\": [{\"type\": \"behavior\","
             " \"function\": \"point-on-plane\", \"particles\": [0], \"point\": [0, 0, 0], \"normal\": [1, 2, 2],"
             " \"ks\": 1}]}",
             &err);
    CHECK(s != NULL);
    if (!s)
        return;
    double f[3];
    psys_system_compute_forces(psys_scene_system(s), f);
    CHECK_NEAR(f[0], -2.0 / 3, 1e-15);
    CHECK_NEAR(f[1], -4.0 / 3, 1e-15);
    CHECK_NEAR(f[2], -4.0 / 3, 1e-15);
    psys_scene_destroy(s);
}

static void scene_user_behavior_not_saved(void)
{
    psys_error err;
    psys_scene *s = load(scene2, &err);
    CHECK(s != NULL);
    if (!s)
        return;
    double p = 1;
    psys_behavior_def def = psys_behavior_def_default();
    def.nparticles = 1;
    def.eval = parabola_eval;
    def.ctx = &p;
    add_behavior_ok(psys_scene_system(s), &def);
    char *t = psys_scene_to_string(s, NULL, &err);
    CHECK(t == NULL);
    CHECK(err.code == PSYS_ERR_UNSUPPORTED);
    CHECK_STR(err.message, "force \"user-behavior\" was added through the C API and has no scene form");
    free(t);
    psys_scene_destroy(s);
}

static void expect_scene_error(const char *force, const char *msg)
{
    char text[1024];
    snprintf(text, sizeof text,
             "{\"psys\": 1, \"dim\": 2, \"particles\": [{\"id\": \"a\", \"x\": [0, 0]}, {\"id\": \"b\", \"x\": [1, 0]},"
             " {\"id\": \"c\", \"x\": [0, 1]}], \"forces\": [{\"type\": \"gravity\"}, %s]}",
             force);
    psys_error err;
    psys_scene *s = load(text, &err);
    CHECK(s == NULL);
    CHECK(err.code == PSYS_ERR_INVALID);
    CHECK_STR(err.message, msg);
    psys_scene_destroy(s);
}

static void scene_bad_input(void)
{
#define B "{\"type\": \"behavior\", "
    expect_scene_error(B "\"particles\": [\"a\", \"b\"], \"ks\": 1}", "forces[1].function: required key missing");
    expect_scene_error(B "\"function\": 3, \"particles\": [\"a\", \"b\"], \"ks\": 1}",
                       "forces[1].function: must be a string (got 3)");
    expect_scene_error(B "\"function\": \"glue\", \"particles\": [\"a\", \"b\"], \"ks\": 1}",
                       "forces[1].function: unknown function (known: coincide, distance, point-on-plane, "
                       "point-on-sphere, angle) (got \"glue\")");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\"], \"ks\": 1}",
                       "forces[1].particles: must list exactly 2 particles (got [\"a\"])");
    expect_scene_error(B "\"function\": \"coincide\", \"particles\": \"a\", \"ks\": 1}",
                       "forces[1].particles: must list exactly 2 particles (got \"a\")");
    expect_scene_error(B "\"function\": \"point-on-sphere\", \"particles\": [\"a\", \"b\"], \"center\": [0, 0],"
                         " \"radius\": 1, \"ks\": 1}",
                       "forces[1].particles: must list exactly 1 particle (got [\"a\",\"b\"])");
    expect_scene_error(B "\"function\": \"angle\", \"particles\": [\"a\", \"b\"], \"ks\": 1}",
                       "forces[1].particles: must list exactly 3 particles (got [\"a\",\"b\"])");
    expect_scene_error(B "\"function\": \"coincide\", \"ks\": 1}", "forces[1].particles: required key missing");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"zz\"], \"ks\": 1}",
                       "forces[1].particles[1]: unknown particle id (got \"zz\")");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [7, \"a\"], \"ks\": 1}",
                       "forces[1].particles[0]: particle index out of range (particles are numbered 0 to 2) (got 7)");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", true], \"ks\": 1}",
                       "forces[1].particles[1]: must be a particle id (string) or index (integer) (got true)");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"b\", \"b\"], \"ks\": 1}",
                       "forces[1].particles[1]: the same particle is listed twice (got \"b\")");
    expect_scene_error(B "\"function\": \"angle\", \"particles\": [\"a\", \"b\", 0], \"ks\": 1}",
                       "forces[1].particles[2]: the same particle is listed twice (got 0)");
    expect_scene_error(B "\"function\": \"coincide\", \"particles\": [\"a\", \"b\"], \"r\": 1, \"ks\": 1}",
                       "forces[1].r: unknown key");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"radius\": 1, \"ks\": 1}",
                       "forces[1].radius: unknown key");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"kS\": 1}",
                       "forces[1].kS: unknown key");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"]}",
                       "forces[1].ks: required key missing");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"ks\": -2}",
                       "forces[1].ks: must be >= 0 (got -2)");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"ks\": 1, \"kd\": -0.5}",
                       "forces[1].kd: must be >= 0 (got -0.5)");
    expect_scene_error(B "\"function\": \"distance\", \"particles\": [\"a\", \"b\"], \"ks\": 1, \"r\": -1}",
                       "forces[1].r: must be >= 0 (got -1)");
    expect_scene_error(B "\"function\": \"point-on-sphere\", \"particles\": [\"a\"], \"center\": [0, 0],"
                         " \"radius\": -1, \"ks\": 1}",
                       "forces[1].radius: must be >= 0 (got -1)");
    expect_scene_error(B "\"function\": \"point-on-sphere\", \"particles\": [\"a\"], \"center\": [0, 0], \"ks\": 1}",
                       "forces[1].radius: required key missing");
    expect_scene_error(B "\"function\": \"point-on-plane\", \"particles\": [\"a\"], \"point\": [0, 0],"
                         " \"normal\": [0, 0], \"ks\": 1}",
                       "forces[1].normal: must not be zero (got [0,0])");
    expect_scene_error(B "\"function\": \"point-on-plane\", \"particles\": [\"a\"], \"point\": [0, 0],"
                         " \"normal\": [0, 0, 1], \"ks\": 1}",
                       "forces[1].normal: must be an array of 2 numbers (dim is 2) (got [0,0,1])");
    expect_scene_error(B "\"function\": \"point-on-plane\", \"particles\": [\"a\"], \"normal\": [0, 1], \"ks\": 1}",
                       "forces[1].point: required key missing");
    expect_scene_error(B "\"function\": \"angle\", \"particles\": [\"a\", \"b\", \"c\"], \"angle\": 4, \"ks\": 1}",
                       "forces[1].angle: must be at most pi (radians) (got 4)");
    expect_scene_error(B "\"function\": \"angle\", \"particles\": [\"a\", \"b\", \"c\"], \"angle\": -0.1, \"ks\": 1}",
                       "forces[1].angle: must be >= 0 (got -0.1)");
#undef B
}

static const check_case cases[] = {
    {"distance_equals_spring_2d", distance_equals_spring_2d},
    {"distance_equals_spring_3d", distance_equals_spring_3d},
    {"coincide_closed_form", coincide_closed_form},
    {"point_on_plane_force", point_on_plane_force},
    {"point_on_sphere_force", point_on_sphere_force},
    {"angle_hand_values", angle_hand_values},
    {"angle_rest_restores_no_net_force_or_torque", angle_rest_restores_no_net_force_or_torque},
    {"energies", energies},
    {"checker_catches_wrong_jacobian", checker_catches_wrong_jacobian},
    {"builtin_jacobians_pass_checker", builtin_jacobians_pass_checker},
    {"force_jacobian_gauss_newton", force_jacobian_gauss_newton},
    {"degenerate_cases_no_nan", degenerate_cases_no_nan},
    {"fd_jacobian_matches_analytic", fd_jacobian_matches_analytic},
    {"user_parabola_simulation", user_parabola_simulation},
    {"api_validation", api_validation},
    {"scene_round_trip_3d", scene_round_trip_3d},
    {"scene_round_trip_2d", scene_round_trip_2d},
    {"scene_resolved_values", scene_resolved_values},
    {"scene_user_behavior_not_saved", scene_user_behavior_not_saved},
    {"scene_bad_input", scene_bad_input},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
