/* Force objects: eq. 1 springs (force law, rest lengths, parameters),
 * gravity and drag, custom force classes, and force Jacobians (analytic
 * against central finite differences). */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

/* Eq. 1 as in docs/notes-errata.md#42-eq-1-and-the-distance-behaviour-function,
 * computed independently of the library:
 * f_a = -[ks(|l| - r) + kd (l̇·l)/|l|] l/|l|, f_b = -f_a. */
static void eq1_force(int dim, const double *xa, const double *xb, const double *va, const double *vb, double ks,
                      double kd, double r, double *fa)
{
    double l[3], ld[3], len = 0, dot = 0;
    for (int k = 0; k < dim; k++) {
        l[k] = xa[k] - xb[k];
        ld[k] = va[k] - vb[k];
        len += l[k] * l[k];
    }
    len = sqrt(len);
    for (int k = 0; k < dim; k++)
        dot += ld[k] * l[k];
    double mag = ks * (len - r) + kd * dot / len;
    for (int k = 0; k < dim; k++)
        fa[k] = -mag * l[k] / len;
}

/* ------------------------------------------------------------------ */
/* Spring force law and parameters                                      */
/* ------------------------------------------------------------------ */

static void spring_force_eq1(void)
{
    const double xa[3] = {0.3, -0.2, 0.5}, xb[3] = {1.1, 0.4, -0.3};
    const double va[3] = {0.7, -1.2, 0.4}, vb[3] = {-0.5, 0.3, 0.9};
    const double ks = 25, kd = 1.5, r = 0.7;
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys = make_system(dim);
        add_particle(sys, xa, va, 1.3);
        add_particle(sys, xb, vb, 0.6);
        CHECK(psys_system_add_spring(sys, 0, 1, ks, kd, r) == PSYS_OK);
        double f[6], fa[3];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        eq1_force(dim, xa, xb, va, vb, ks, kd, r, fa);
        for (int k = 0; k < dim; k++) {
            CHECK_NEAR(f[k], fa[k], 1e-13 * (1 + fabs(fa[k])));
            CHECK(f[dim + k] == -f[k]); /* Newton's third law, exactly */
        }
        psys_system_destroy(sys);
    }

    /* Worked numbers: |l| = 5 along (3, 4)/5, rest 2, ks 10, and a relative
     * velocity of (1, 2): l̇·l/|l| = (3 + 8)/5 = 2.2, kd 0.5:
     * magnitude 10·3 + 0.5·2.2 = 31.1, f_a = -31.1 (0.6, 0.8). */
    psys_system *sys = make_system(2);
    const double a[2] = {4, 5}, b[2] = {1, 1}, v1[2] = {1, 2};
    add_particle(sys, a, v1, 1.0);
    add_particle(sys, b, NULL, 1.0);
    CHECK(psys_system_add_spring(sys, 0, 1, 10, 0.5, 2.0) == PSYS_OK);
    double f[4];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    CHECK_NEAR(f[0], -31.1 * 0.6, 1e-12);
    CHECK_NEAR(f[1], -31.1 * 0.8, 1e-12);
    CHECK_NEAR(f[2], 31.1 * 0.6, 1e-12);
    CHECK_NEAR(f[3], 31.1 * 0.8, 1e-12);
    psys_system_destroy(sys);
}

/* Chains whose springs share ks, or kd, or both, or all but one spring,
 * or ks, kd and the rest length but for one spring's rest length or a
 * muscle: the spring loops read shared parameters once per run of springs,
 * so a run taken as shared when it is not would give some springs
 * another's ks, kd or rest length. Every particle's force, by both derivative paths (the force
 * object, psys_system_compute_forces, and the ODE derivative, which takes
 * the fused one for springs with gravity or drag), against eq. 1 spring
 * by spring. */
static void spring_runs_shared_parameters(void)
{
    enum { CHAINS = 8, LEN = 40, N = CHAINS * LEN };
    for (int dim = 2; dim <= 3; dim++) { /* the run loops have a copy for each */
        psys_system *sys = make_system(dim);
        uint64_t seed = 99;
        double x[N][3] = {{0}}, v[N][3] = {{0}};
        for (int i = 0; i < N; i++) {
            for (int k = 0; k < dim; k++) {
                seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
                double u = (double)(seed >> 11) * (1.0 / 9007199254740992.0);
                x[i][k] = (k == 0 ? 0.1 * (i % LEN) : 0) + 0.03 * u;
                v[i][k] = u - 0.5;
            }
            add_particle(sys, x[i], v[i], 1.0);
        }
        double ks[N], kd[N], rest[N];
        int ns = 0, a[N], b[N];
        for (int c = 0; c < CHAINS; c++)
            for (int j = 0; j + 1 < LEN; j++, ns++) {
                a[ns] = c * LEN + j;
                b[ns] = a[ns] + 1;
                ks[ns] = c == 0 || c == 2 || c == 3 ? 40 : 10 + j;          /* chain 0: ks shared, kd not */
                kd[ns] = c == 1 || c == 2 || c == 3 ? 0.3 : 0.05 * (1 + j); /* chain 1: kd shared, ks not */
                rest[ns] = 0.08 + 0.001 * j;                                /* chain 2: both shared */
                if (c == 3 && j == 17)
                    ks[ns] = 41; /* chain 3: all shared but one, mid-run */
                if (c == 4 && j == 25)
                    kd[ns] = 0.3; /* chain 4: neither shared */
                if (c >= 5) { /* chains 5-7: ks, kd and the rest length shared, */
                    ks[ns] = 40;
                    kd[ns] = 0.3;
                    rest[ns] = c == 5 && j == 17 ? 0.095 : 0.09; /* but one rest length mid-run (5) */
                }
                CHECK(psys_system_add_spring(sys, (size_t)a[ns], (size_t)b[ns], ks[ns], kd[ns], rest[ns]) == PSYS_OK);
                if (c == 6 && j == 17) { /* or a muscle mid-run (6); at t = 0 its rest is r(1 + 0.2 sin 1) */
                    CHECK(psys_system_set_spring_muscle(sys, (size_t)ns, 0.2, 3.0, 1.0) == PSYS_OK);
                    rest[ns] *= 1 + 0.2 * sin(1.0);
                }
            }
        const double g[3] = {0, -1, 0};
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        double want[N][3] = {{0}};
        for (int i = 0; i < N; i++)
            want[i][1] = -1;
        for (int k = 0; k < ns; k++) {
            double fa[3];
            eq1_force(dim, x[a[k]], x[b[k]], v[a[k]], v[b[k]], ks[k], kd[k], rest[k], fa);
            for (int c = 0; c < dim; c++) {
                want[a[k]][c] += fa[c];
                want[b[k]][c] -= fa[c];
            }
        }
        static double f[3 * N], y[6 * N], ydot[6 * N];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        psys_ode o = psys_system_ode(sys);
        o.get_state(o.ctx, y);
        CHECK(o.derivative(o.ctx, 0, y, ydot) == PSYS_OK);
        for (int i = 0; i < N; i++)
            for (int c = 0; c < dim; c++) {
                const double tol = 1e-12 * (1 + fabs(want[i][c]));
                CHECK_NEAR(f[dim * i + c], want[i][c], tol);
                CHECK_NEAR(ydot[dim * N + dim * i + c], want[i][c], tol); /* mass 1 */
            }
        psys_system_destroy(sys);
    }
}

/* Eq. 1 damps only along l: at rest length, a relative velocity normal to
 * l gives no force, one along l gives -kd (l̇·l̂) l̂. */
static void spring_damping_along_l(void)
{
    psys_system *sys = make_system(3);
    const double a[3] = {1, 2, 2}, b[3] = {0, 0, 0}; /* |l| = 3, l̂ = (1,2,2)/3 */
    const double perp[3] = {2, -1, 0};              /* perp · l = 0 */
    add_particle(sys, a, perp, 1.0);
    add_particle(sys, b, NULL, 1.0);
    CHECK(psys_system_add_spring(sys, 0, 1, 100, 4.0, 3.0) == PSYS_OK);
    double f[6];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 6; k++)
        CHECK_NEAR(f[k], 0.0, 1e-13);
    const double along[3] = {0.5, 1.0, 1.0}; /* l̇·l̂ = 1.5 */
    CHECK(psys_system_set_particle(sys, 0, NULL, along) == PSYS_OK);
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    const double u[3] = {1.0 / 3, 2.0 / 3, 2.0 / 3};
    for (int k = 0; k < 3; k++) {
        CHECK_NEAR(f[k], -4.0 * 1.5 * u[k], 1e-13);
        CHECK_NEAR(f[3 + k], 4.0 * 1.5 * u[k], 1e-13);
    }
    psys_system_destroy(sys);
}

/* 12. rest < 0 means the initial distance; any rest >= 0 is honoured. */
static void spring_rest_length(void)
{
    psys_system *sys = make_system(2);
    const double a[2] = {1, 1}, b[2] = {4, 5}, c[2] = {1, 3};
    add_particle(sys, a, NULL, 1.0);
    add_particle(sys, b, NULL, 1.0);
    add_particle(sys, c, NULL, 1.0);
    CHECK(psys_system_add_spring(sys, 0, 1, 10, 0.2, -1) == PSYS_OK);   /* |ab| = 5 */
    CHECK(psys_system_add_spring(sys, 1, 2, 10, 0.2, -0.5) == PSYS_OK); /* |bc| = √13 */
    CHECK(psys_system_add_spring(sys, 0, 2, 7, 0.0, 0.5) == PSYS_OK);   /* |ac| = 2 */
    CHECK(psys_system_add_spring(sys, 2, 0, 3, 0.0, 0.0) == PSYS_OK);   /* zero rest */
    CHECK(psys_system_spring_count(sys) == 4);
    size_t ia, ib;
    double ks, kd, rest;
    CHECK(psys_system_spring(sys, 0, &ia, &ib, &ks, &kd, &rest) == PSYS_OK);
    CHECK(ia == 0 && ib == 1 && ks == 10 && kd == 0.2);
    CHECK(rest == 5.0);
    CHECK(psys_system_spring(sys, 1, NULL, NULL, NULL, NULL, &rest) == PSYS_OK);
    CHECK_NEAR(rest, sqrt(13.0), 1e-15);
    CHECK(psys_system_spring(sys, 2, NULL, NULL, NULL, NULL, &rest) == PSYS_OK);
    CHECK(rest == 0.5);
    CHECK(psys_system_spring(sys, 3, NULL, NULL, NULL, NULL, &rest) == PSYS_OK);
    CHECK(rest == 0.0);
    CHECK(psys_system_spring(sys, 4, NULL, NULL, NULL, NULL, &rest) == PSYS_ERR_INVALID);
    /* Springs 0 and 1 sit at their rest lengths: zero force on particle 1;
     * on particle 0 only the two a–c springs, along +y:
     * 7·(2 - 0.5) + 3·2 = 16.5 toward c. */
    double f[6];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    CHECK_NEAR(f[2], 0.0, 1e-13);
    CHECK_NEAR(f[3], 0.0, 1e-13);
    CHECK_NEAR(f[0], 0.0, 1e-13);
    CHECK_NEAR(f[1], 16.5, 1e-12);
    CHECK_NEAR(f[4], 0.0, 1e-13);
    CHECK_NEAR(f[5], -16.5, 1e-12);
    psys_system_destroy(sys);

    /* The same through a scene: "rest" absent means the initial distance. */
    const char *json = "{\"psys\": 1, \"dim\": 3, \"particles\": ["
                       "{\"id\": \"p\", \"x\": [0, 0, 0]}, {\"id\": \"q\", \"x\": [2, 3, 6]},"
                       "{\"id\": \"s\", \"x\": [0, 0, 1], \"fixed\": true}],"
                       "\"forces\": [{\"type\": \"spring\", \"a\": \"p\", \"b\": \"q\", \"ks\": 5},"
                       "{\"type\": \"spring\", \"a\": \"q\", \"b\": 2, \"ks\": 5, \"kd\": 0.5, \"rest\": 1.25}]}";
    psys_error err;
    psys_scene *scene = psys_scene_load_string(json, strlen(json), &err);
    CHECK(scene != NULL);
    if (!scene) {
        fprintf(stderr, "scene: %s\n", err.message);
        return;
    }
    sys = psys_scene_system(scene);
    CHECK(psys_system_spring_count(sys) == 2);
    CHECK(psys_system_spring(sys, 0, &ia, &ib, &ks, &kd, &rest) == PSYS_OK);
    CHECK(ia == 0 && ib == 1 && ks == 5 && kd == 0);
    CHECK(rest == 7.0); /* |(2, 3, 6)| = 7 */
    CHECK(psys_system_spring(sys, 1, &ia, &ib, &ks, &kd, &rest) == PSYS_OK);
    CHECK(ia == 1 && ib == 2 && kd == 0.5 && rest == 1.25);
    CHECK(psys_system_is_fixed(sys, 2));
    psys_scene_destroy(scene);
}

static void spring_invalid_arguments(void)
{
    psys_system *sys = make_system(2);
    const double a[2] = {0, 0}, b[2] = {1, 0};
    add_particle(sys, a, NULL, 1.0);
    add_particle(sys, b, NULL, 1.0);
    CHECK(psys_system_add_spring(sys, 0, 0, 1, 0, 1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 2, 1, 0, 1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 1, -1, 0, 1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 1, 1, -0.1, 1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 1, NAN, 0, 1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 1, 1, 0, NAN) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_spring(sys, 0, 1, 1, 0, INFINITY) == PSYS_ERR_INVALID);
    CHECK(psys_system_spring_count(sys) == 0);
    CHECK(psys_system_last_error(sys)[0] != '\0');
    CHECK(psys_system_add_drag(sys, -1) == PSYS_ERR_INVALID);
    CHECK(psys_system_add_drag(sys, NAN) == PSYS_ERR_INVALID);
    CHECK(psys_system_force_count(sys) == 0);
    psys_system_destroy(sys);
}

/* A spring whose ends coincide has no direction: it must not produce NaN. */
static void spring_zero_length(void)
{
    psys_system *sys = make_system(3);
    const double a[3] = {1, 1, 1}, v[3] = {1, 0, 0};
    add_particle(sys, a, v, 1.0);
    add_particle(sys, a, NULL, 1.0);
    CHECK(psys_system_add_spring(sys, 0, 1, 10, 1, 0.5) == PSYS_OK);
    double f[6];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int k = 0; k < 6; k++)
        CHECK(isfinite(f[k]));
    CHECK(isfinite(psys_system_potential_energy(sys)));
    CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * 10 * 0.25, 1e-15);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* Gravity, drag, custom force classes                                  */
/* ------------------------------------------------------------------ */

static void gravity_and_drag(void)
{
    const double g[3] = {0.5, -9.81, 1.5}, kd = 0.35;
    const double x[3][3] = {{0, 0, 0}, {1, 2, 3}, {-1, 0.5, 2}};
    const double v[3][3] = {{1, -2, 0.5}, {0, 0, 3}, {-4, 1, 1}};
    const double m[3] = {0.5, 2.0, 7.5};
    psys_system *sys = make_system(3);
    for (int p = 0; p < 3; p++)
        add_particle(sys, x[p], v[p], m[p]);
    psys_system_set_fixed(sys, 2, true); /* zeroes its velocity */
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, kd) == PSYS_OK);
    CHECK(psys_system_force_count(sys) == 2);
    CHECK(psys_system_force_class(sys, 0) == &psys_gravity_class);
    CHECK(psys_system_force_class(sys, 1) == &psys_drag_class);
    CHECK_STR(psys_gravity_class.name, "gravity");
    CHECK_STR(psys_drag_class.name, "drag");
    CHECK_STR(psys_spring_class.name, "spring");
    CHECK(psys_drag_class.energy == NULL); /* drag is not conservative */
    double f[9];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    for (int p = 0; p < 3; p++)
        for (int k = 0; k < 3; k++) {
            double vk = p == 2 ? 0.0 : v[p][k];
            CHECK_NEAR(f[p * 3 + k], m[p] * g[k] - kd * vk, 1e-13);
        }
    psys_system_destroy(sys);
}

typedef struct pull {
    size_t particle;
    double k; /* U = ½ k |x|², f = -k x: a spring to the origin */
} pull;

static void pull_apply(void *data, const psys_force_eval *e, double *f)
{
    const pull *pl = data;
    for (int c = 0; c < e->dim; c++)
        f[pl->particle * (size_t)e->dim + (size_t)c] -= pl->k * e->x[pl->particle * (size_t)e->dim + (size_t)c];
}

static double pull_energy(void *data, const psys_force_eval *e)
{
    const pull *pl = data;
    double s = 0;
    for (int c = 0; c < e->dim; c++)
        s += e->x[pl->particle * (size_t)e->dim + (size_t)c] * e->x[pl->particle * (size_t)e->dim + (size_t)c];
    return 0.5 * pl->k * s;
}

static int pull_destroyed = 0;
static void pull_destroy(void *data)
{
    pull_destroyed++;
    free(data);
}

static const psys_force_class pull_class = {.name = "pull", .apply = pull_apply, .energy = pull_energy, .destroy = pull_destroy};

/* A new force type is one class: it adds into the accumulators, its energy
 * counts, and the system owns (and destroys) its data. */
static void custom_force_class(void)
{
    pull_destroyed = 0;
    psys_system *sys = make_system(2);
    const double x[2] = {3, -4}, y[2] = {1, 1};
    add_particle(sys, x, NULL, 2.0);
    add_particle(sys, y, NULL, 1.0);
    pull *pl = malloc(sizeof *pl);
    CHECK(pl != NULL);
    pl->particle = 0;
    pl->k = 1.5;
    CHECK(psys_system_add_force(sys, &pull_class, pl) == PSYS_OK);
    CHECK(psys_system_force_data(sys, 0) == pl);
    double f[4];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    CHECK_NEAR(f[0], -4.5, 1e-15);
    CHECK_NEAR(f[1], 6.0, 1e-15);
    CHECK(f[2] == 0.0 && f[3] == 0.0);
    CHECK_NEAR(psys_system_potential_energy(sys), 0.5 * 1.5 * 25, 1e-14);
    /* No Jacobian in the class: the dense Jacobian is unsupported. */
    double J[16], Jv[16];
    CHECK(psys_system_dense_jacobian(sys, J, Jv) == PSYS_ERR_UNSUPPORTED);
    /* A class without apply is refused, and its data destroyed at once. */
    static const psys_force_class broken = {.name = "broken", .destroy = pull_destroy};
    pull *other = malloc(sizeof *other);
    CHECK(psys_system_add_force(sys, &broken, other) == PSYS_ERR_INVALID);
    CHECK(pull_destroyed == 1);
    CHECK(psys_system_force_count(sys) == 1);
    psys_system_destroy(sys);
    CHECK(pull_destroyed == 2);
}

/* ------------------------------------------------------------------ */
/* 11. Jacobians: analytic vs central finite differences.               */
/* ------------------------------------------------------------------ */

static uint64_t rng_state;
static double rnd(double lo, double hi)
{
    rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

enum { JN = 6 };

static void jacobian_case(int dim, uint64_t seed)
{
    rng_state = seed;
    psys_system *sys = make_system(dim);
    for (int p = 0; p < JN; p++) {
        double x[3], v[3];
        for (int k = 0; k < dim; k++) {
            x[k] = rnd(-1.5, 1.5);
            v[k] = rnd(-1, 1);
        }
        add_particle(sys, x, v, rnd(0.5, 2));
    }
    CHECK(psys_system_set_fixed(sys, 5, true) == PSYS_OK);
    static const int pairs[][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 4}, {4, 0}, {0, 2}, {1, 3}, {2, 5}, {5, 4}, {3, 0}};
    const size_t ns = sizeof pairs / sizeof pairs[0];
    const double *X = psys_system_positions(sys), *V = psys_system_velocities(sys);
    double sp_ks[16], sp_kd[16], sp_r[16];
    for (size_t s = 0; s < ns; s++) {
        int a = pairs[s][0], b = pairs[s][1];
        double len = 0;
        for (int k = 0; k < dim; k++)
            len += (X[a * dim + k] - X[b * dim + k]) * (X[a * dim + k] - X[b * dim + k]);
        len = sqrt(len);
        sp_ks[s] = rnd(10, 100);
        sp_kd[s] = rnd(0.2, 2);
        sp_r[s] = len * rnd(0.5, 1.5); /* stretched and compressed springs */
        CHECK(psys_system_add_spring(sys, (size_t)a, (size_t)b, sp_ks[s], sp_kd[s], sp_r[s]) == PSYS_OK);
    }
    const double g[3] = {0.2, -9.81, 0.4}, kdrag = 0.3;
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, kdrag) == PSYS_OK);

    /* The forces themselves are eq. 1 + m g - kd v (so the finite
     * differences below differentiate the right thing). */
    const size_t nd = JN * (size_t)dim;
    double f[JN * 3], want[JN * 3];
    CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
    const double *M = psys_system_masses(sys);
    for (size_t p = 0; p < JN; p++)
        for (int k = 0; k < dim; k++)
            want[p * dim + k] = M[p] * g[k] - kdrag * V[p * dim + k];
    for (size_t s = 0; s < ns; s++) {
        int a = pairs[s][0], b = pairs[s][1];
        double fa[3];
        eq1_force(dim, X + a * dim, X + b * dim, V + a * dim, V + b * dim, sp_ks[s], sp_kd[s], sp_r[s], fa);
        for (int k = 0; k < dim; k++) {
            want[a * dim + k] += fa[k];
            want[b * dim + k] -= fa[k];
        }
    }
    for (size_t i = 0; i < nd; i++)
        CHECK_NEAR(f[i], want[i], 1e-12 * (1 + fabs(want[i])));

    double *J = calloc(nd * nd, sizeof(double)), *Jv = calloc(nd * nd, sizeof(double));
    double *F = calloc(nd * nd, sizeof(double)), *Fv = calloc(nd * nd, sizeof(double));
    CHECK(J && Jv && F && Fv);
    double xkeep[JN * 3], vkeep[JN * 3];
    memcpy(xkeep, X, nd * sizeof(double));
    memcpy(vkeep, V, nd * sizeof(double));
    CHECK(psys_system_dense_jacobian(sys, J, Jv) == PSYS_OK);
    CHECK(psys_system_fd_jacobian(sys, 1e-6, F, Fv) == PSYS_OK);
    /* Finite differences leave the state exactly as it was. */
    CHECK(memcmp(xkeep, psys_system_positions(sys), nd * sizeof(double)) == 0);
    CHECK(memcmp(vkeep, psys_system_velocities(sys), nd * sizeof(double)) == 0);
    double worst = 0, worst_v = 0, norm = 0, offdiag_v = 0;
    for (size_t i = 0; i < nd * nd; i++) {
        worst = fmax(worst, fabs(J[i] - F[i]) / (1 + fabs(F[i])));
        worst_v = fmax(worst_v, fabs(Jv[i] - Fv[i]) / (1 + fabs(Fv[i])));
        norm = fmax(norm, fabs(J[i]));
        if (i / nd != i % nd)
            offdiag_v = fmax(offdiag_v, fabs(Jv[i]));
    }
    fprintf(stderr, "  dim %d: max |J - FD|/(1+|FD|): dfdx %.2e, dfdv %.2e (max |dfdx| %.1f)\n", dim, worst,
            worst_v, norm);
    CHECK(worst < 1e-6);
    CHECK(worst_v < 1e-6);
    CHECK(norm > 10);        /* the Jacobian is really there */
    CHECK(offdiag_v > 0.1);  /* and the spring damping couples velocities */
    /* Each row of dfdx sums to zero over the particles (translation
     * invariance: springs depend only on differences, gravity and drag
     * not on x); each row of dfdv sums to -kdrag. */
    for (size_t i = 0; i < nd; i++)
        for (int c = 0; c < dim; c++) {
            double sx = 0, sv = 0;
            for (size_t p = 0; p < JN; p++) {
                sx += J[i * nd + p * dim + c];
                sv += Jv[i * nd + p * dim + c];
            }
            CHECK_NEAR(sx, 0.0, 1e-10 * norm);
            CHECK_NEAR(sv, (int)(i % dim) == c ? -kdrag : 0.0, 1e-12);
        }
    free(J);
    free(Jv);
    free(F);
    free(Fv);
    psys_system_destroy(sys);
}

static void jacobian_2d(void)
{
    jacobian_case(2, 12345);
    jacobian_case(2, 987654321);
}

static void jacobian_3d(void)
{
    jacobian_case(3, 4242);
    jacobian_case(3, 77777);
}

static const check_case cases[] = {
    {"spring_force_eq1", spring_force_eq1},
    {"spring_runs_shared_parameters", spring_runs_shared_parameters},
    {"spring_damping_along_l", spring_damping_along_l},
    {"spring_rest_length", spring_rest_length},
    {"spring_invalid_arguments", spring_invalid_arguments},
    {"spring_zero_length", spring_zero_length},
    {"gravity_and_drag", gravity_and_drag},
    {"custom_force_class", custom_force_class},
    {"jacobian_2d", jacobian_2d},
    {"jacobian_3d", jacobian_3d},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
