/* Pair forces (spatial interaction, notes §4.3): every law against hand
 * values, Newton's third law, energy conservation, grid = direct bit for bit
 * (with and without periodic boxes), the minimum image, wrapping, thread-count
 * determinism, Barnes–Hut error against theta, Kepler and figure-eight orbits
 * with rk45, Jacobians, scene round trips and bad-input messages. */
#include "check.h"
#include "helpers.h"

#include "../src/sim/bench.h"
#include "../src/pair/pair.h"

#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static size_t add_pair(psys_system *sys, const psys_pair_def *def)
{
    size_t k = (size_t)-1;
    psys_status st = psys_system_add_pair(sys, def, &k);
    if (st != PSYS_OK)
        fprintf(stderr, "psys_system_add_pair: %s\n", psys_system_last_error(sys));
    CHECK(st == PSYS_OK);
    return k;
}

static double *forces_of(psys_system *sys)
{
    size_t nd = psys_system_count(sys) * (size_t)psys_system_dim(sys);
    double *f = calloc(nd ? nd : 1, sizeof(double));
    CHECK(f != NULL);
    psys_system_compute_forces(sys, f);
    return f;
}

/* Two particles on the x axis at distance r; force on particle 0 (x) and the energy. */
static void two_body(int dim, const psys_pair_def *def, double r, double m0, double m1, double q0, double q1,
                     double *f0x, double *f1x, double *u)
{
    psys_system *sys = make_system(dim);
    double a[3] = {0.25, -0.5, 0.125}, b[3] = {0.25 + r, -0.5, 0.125};
    add_particle(sys, a, NULL, m0);
    add_particle(sys, b, NULL, m1);
    if (q0 != 0 || q1 != 0) {
        CHECK(psys_system_set_charge(sys, 0, q0) == PSYS_OK);
        CHECK(psys_system_set_charge(sys, 1, q1) == PSYS_OK);
    }
    add_pair(sys, def);
    double *f = forces_of(sys);
    *f0x = f[0];
    *f1x = f[dim];
    for (int k = 1; k < dim; k++) {
        CHECK(f[k] == 0);
        CHECK(f[dim + k] == 0);
    }
    *u = psys_system_potential_energy(sys);
    free(f);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ laws against hand values */

static void gravity_hand_values(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_pair_def def = psys_pair_def_default();
        def.law = PSYS_PAIR_GRAVITY;
        def.G = 1.5;
        double f0, f1, u;
        /* Newtonian: |F| = G m0 m1 / r² = 1.5·2·3/4, attractive (+x on particle 0) */
        two_body(dim, &def, 2.0, 2.0, 3.0, 0, 0, &f0, &f1, &u);
        CHECK_NEAR(f0, 2.25, 1e-15);
        CHECK(f1 == -f0);
        CHECK_NEAR(u, -1.5 * 6 / 2.0, 1e-15);
        /* Plummer softening 1: F = G m m r/(r² + ε²)^{3/2}, U = -G m m/sqrt(r² + ε²) */
        def.softening = 1.0;
        two_body(dim, &def, 2.0, 2.0, 3.0, 0, 0, &f0, &f1, &u);
        CHECK_NEAR(f0, 1.5 * 6 * 2.0 / pow(5.0, 1.5), 1e-15);
        CHECK(f1 == -f0);
        CHECK_NEAR(u, -1.5 * 6 / sqrt(5.0), 1e-15);
        /* coincident particles, softened: no force, finite energy -G m m/ε */
        two_body(dim, &def, 0.0, 2.0, 3.0, 0, 0, &f0, &f1, &u);
        CHECK(f0 == 0 && f1 == 0);
        CHECK_NEAR(u, -9.0, 1e-15);
        /* coincident, Newtonian: no force and no energy rather than inf/NaN */
        def.softening = 0;
        two_body(dim, &def, 0.0, 2.0, 3.0, 0, 0, &f0, &f1, &u);
        CHECK(f0 == 0 && f1 == 0 && u == 0);
    }
}

static void coulomb_hand_values(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_pair_def def = psys_pair_def_default();
        def.law = PSYS_PAIR_COULOMB;
        def.k = 3.0;
        double f0, f1, u;
        /* opposite charges attract: |F| = k |q0 q1| / r² = 3·2/4 */
        two_body(dim, &def, 2.0, 1, 1, 2.0, -1.0, &f0, &f1, &u);
        CHECK_NEAR(f0, 1.5, 1e-15);
        CHECK(f1 == -f0);
        CHECK_NEAR(u, -3.0, 1e-15);
        /* like charges repel, energy positive */
        two_body(dim, &def, 2.0, 1, 1, -2.0, -1.0, &f0, &f1, &u);
        CHECK_NEAR(f0, -1.5, 1e-15);
        CHECK_NEAR(u, 3.0, 1e-15);
        /* masses do not matter; an uncharged particle feels nothing */
        two_body(dim, &def, 2.0, 5, 7, 2.0, 0.0, &f0, &f1, &u);
        CHECK(f0 == 0 && f1 == 0 && u == 0);
    }
}

static void lennard_jones_hand_values(void)
{
    const double eps = 0.7, sig = 0.3, rc = 2.5 * sig;
    for (int dim = 2; dim <= 3; dim++)
        for (int method = PSYS_PAIR_DIRECT; method <= PSYS_PAIR_GRID; method++) {
            psys_pair_def def = psys_pair_def_default();
            def.law = PSYS_PAIR_LENNARD_JONES;
            def.epsilon = eps;
            def.sigma = sig;
            def.cutoff = rc;
            def.method = (psys_pair_method)method;
            double f0, f1, u;
            /* minimum at 2^(1/6) σ: zero force, U = -ε */
            two_body(dim, &def, pow(2.0, 1.0 / 6) * sig, 1, 1, 0, 0, &f0, &f1, &u);
            CHECK(fabs(f0) < 1e-12 * 24 * eps / sig);
            CHECK_NEAR(u, -eps, 1e-15);
            /* at σ: U = 0, repulsive F = 24ε/σ (particle 0 pushed to -x) */
            two_body(dim, &def, sig, 1, 1, 0, 0, &f0, &f1, &u);
            CHECK_NEAR(f0, -24 * eps / sig, 1e-12);
            CHECK(f1 == -f0);
            CHECK(fabs(u) < 1e-14);
            /* at 1.5σ: attractive, F = 24ε/r [2(σ/r)¹² - (σ/r)⁶], U = 4ε[(σ/r)¹² - (σ/r)⁶] */
            double r = 1.5 * sig, s6 = pow(sig / r, 6);
            two_body(dim, &def, r, 1, 1, 0, 0, &f0, &f1, &u);
            CHECK_NEAR(f0, -24 * eps / r * (2 * s6 * s6 - s6), 1e-13);
            CHECK(f0 > 0);
            CHECK_NEAR(u, 4 * eps * (s6 * s6 - s6), 1e-15);
            /* truncated without shift: just inside the cutoff U = U_LJ(rc) ≠ 0; beyond, nothing */
            double sc6 = pow(sig / rc, 6), urc = 4 * eps * (sc6 * sc6 - sc6);
            two_body(dim, &def, rc * (1 - 1e-12), 1, 1, 0, 0, &f0, &f1, &u);
            CHECK_NEAR(u, urc, 1e-12);
            CHECK(f0 != 0);
            two_body(dim, &def, rc, 1, 1, 0, 0, &f0, &f1, &u);
            CHECK(f0 == 0 && u == 0);
            two_body(dim, &def, 1.01 * rc, 1, 1, 0, 0, &f0, &f1, &u);
            CHECK(f0 == 0 && u == 0);
            /* shift: U(rc) = 0 (continuous), U(r) = U_LJ(r) - U_LJ(rc), forces unchanged */
            def.shift = true;
            double g0;
            two_body(dim, &def, rc * (1 - 1e-12), 1, 1, 0, 0, &f0, &f1, &u);
            CHECK(fabs(u) < 1e-12);
            two_body(dim, &def, r, 1, 1, 0, 0, &g0, &f1, &u);
            CHECK_NEAR(u, 4 * eps * (s6 * s6 - s6) - urc, 1e-15);
            CHECK_NEAR(g0, -24 * eps / r * (2 * s6 * s6 - s6), 1e-13);
        }
    /* cutoff default 2.5σ */
    psys_system *sys = make_system(3);
    psys_pair_def def = psys_pair_def_default(), got;
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = 0.2;
    size_t k = add_pair(sys, &def);
    CHECK(psys_system_pair(sys, k, &got) == PSYS_OK);
    CHECK(got.cutoff == 2.5 * 0.2);
    CHECK(got.method == PSYS_PAIR_GRID);
    CHECK(got.skin == 0.1 * got.cutoff);
    psys_system_destroy(sys);
}

static void soft_repulsion_hand_values(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_pair_def def = psys_pair_def_default();
        def.law = PSYS_PAIR_SOFT_REPULSION;
        def.k = 4;
        def.radius = 1;
        double f0, f1, u;
        /* U = ½k(R - r)², F = k(R - r) repulsive */
        two_body(dim, &def, 0.5, 1, 1, 0, 0, &f0, &f1, &u);
        CHECK_NEAR(f0, -2.0, 1e-15);
        CHECK(f1 == 2.0);
        CHECK_NEAR(u, 0.5, 1e-15);
        two_body(dim, &def, 1.0, 1, 1, 0, 0, &f0, &f1, &u);
        CHECK(f0 == 0 && u == 0);
        two_body(dim, &def, 3.0, 1, 1, 0, 0, &f0, &f1, &u);
        CHECK(f0 == 0 && u == 0);
    }
}

/* User law: a spring of rest length 1 and stiffness ctx, F(r) = -k (r - 1), U = ½ k (r - 1)². */
static double spring_law(void *ctx, double r, double *u)
{
    double k = *(const double *)ctx;
    if (u)
        *u = 0.5 * k * (r - 1) * (r - 1);
    return -k * (r - 1);
}

static void user_law_hand_values(void)
{
    static double k = 3.0;
    for (int dim = 2; dim <= 3; dim++) {
        psys_pair_def def = psys_pair_def_default();
        def.law = PSYS_PAIR_USER;
        def.fn = spring_law;
        def.ctx = &k;
        double f0, f1, u;
        two_body(dim, &def, 1.5, 1, 1, 0, 0, &f0, &f1, &u); /* stretched: pulls together */
        CHECK_NEAR(f0, 1.5, 1e-15);
        CHECK(f1 == -f0);
        CHECK_NEAR(u, 0.375, 1e-15);
        def.cutoff = 1.2; /* with a cutoff: grid by default, nothing beyond it */
        two_body(dim, &def, 1.5, 1, 1, 0, 0, &f0, &f1, &u);
        CHECK(f0 == 0 && u == 0);
        two_body(dim, &def, 0.5, 1, 1, 0, 0, &f0, &f1, &u);
        CHECK_NEAR(f0, -1.5, 1e-15);
    }
    /* no scene form */
    psys_error err;
    psys_scene *s = psys_scene_load_string("{\"psys\": 1}", 11, &err);
    CHECK(s != NULL);
    if (!s)
        return;
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_USER;
    def.fn = spring_law;
    def.ctx = &k;
    add_pair(psys_scene_system(s), &def);
    char *text = psys_scene_to_string(s, NULL, &err);
    CHECK(text == NULL);
    CHECK(err.code == PSYS_ERR_UNSUPPORTED);
    CHECK_STR(err.message, "force \"user-pair\" was added through the C API and has no scene form");
    free(text);
    psys_scene_destroy(s);
}

/* ------------------------------------------------------------------ conservation */

static psys_system *random_cloud(int dim, size_t n, double size, bool masses, bool charges)
{
    psys_system *sys = make_system(dim);
    for (size_t i = 0; i < n; i++) {
        double x[3], v[3];
        for (int k = 0; k < dim; k++) {
            x[k] = urand(0, size);
            v[k] = urand(-0.1, 0.1);
        }
        add_particle(sys, x, v, masses ? urand(0.5, 2) : 1.0);
        if (charges)
            CHECK(psys_system_set_charge(sys, i, urand(-1, 1)) == PSYS_OK);
    }
    return sys;
}

/* n particles on a jittered square/cubic lattice of the given spacing. */
static psys_system *jittered_lattice(int dim, size_t n, double spacing, double jitter, bool charges)
{
    psys_system *sys = make_system(dim);
    size_t side = (size_t)ceil(pow((double)n, 1.0 / dim));
    for (size_t i = 0; i < n; i++) {
        double x[3], v[3];
        size_t c = i;
        for (int k = 0; k < dim; k++) {
            x[k] = spacing * (double)(c % side) + urand(-jitter, jitter);
            c /= side;
            v[k] = urand(-0.1, 0.1);
        }
        add_particle(sys, x, v, urand(0.5, 2));
        if (charges)
            CHECK(psys_system_set_charge(sys, i, urand(-1, 1)) == PSYS_OK);
    }
    return sys;
}

/* Each pair's forces cancel exactly, so the net force is rounding only, and
 * momentum is conserved along a trajectory. */
static void newton_third_law(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (int law = 0; law < 4; law++) {
            psys_system *sys = jittered_lattice(dim, 200, 0.17, 0.02, law == PSYS_PAIR_COULOMB);
            psys_pair_def def = psys_pair_def_default();
            def.law = (psys_pair_law)law;
            def.softening = 0.05;
            def.sigma = 0.1;
            def.epsilon = 1e-3;
            def.radius = 0.3;
            add_pair(sys, &def);
            double *f = forces_of(sys);
            double net[3] = {0, 0, 0}, mag = 0;
            for (size_t i = 0; i < 200; i++)
                for (int k = 0; k < dim; k++) {
                    net[k] += f[i * dim + k];
                    mag += fabs(f[i * dim + k]);
                }
            CHECK(mag > 0);
            for (int k = 0; k < dim; k++)
                CHECK(fabs(net[k]) <= 1e-13 * mag);
            free(f);
            /* momentum over 100 verlet steps */
            psys_error err;
            psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
            double p0[3] = {0, 0, 0}, p1[3] = {0, 0, 0}, pmag = 0;
            const double *v = psys_system_velocities(sys), *m = psys_system_masses(sys);
            for (size_t i = 0; i < 200; i++)
                for (int k = 0; k < dim; k++) {
                    p0[k] += m[i] * v[i * dim + k];
                    pmag += fabs(m[i] * v[i * dim + k]);
                }
            for (int s = 0; s < 20; s++)
                CHECK(psys_system_advance(sys, sol, 1e-3, NULL) == PSYS_OK);
            v = psys_system_velocities(sys);
            double pmag1 = 0;
            for (size_t i = 0; i < 200; i++)
                for (int k = 0; k < dim; k++) {
                    p1[k] += m[i] * v[i * dim + k];
                    pmag1 += fabs(m[i] * v[i * dim + k]);
                }
            pmag = fmax(pmag, pmag1);
            for (int k = 0; k < dim; k++)
                CHECK_NEAR(p1[k], p0[k], 1e-12 * pmag);
            psys_solver_destroy(sol);
            psys_system_destroy(sys);
        }
}

/* A 27-atom Lennard-Jones cluster with verlet: total energy stays within a
 * small band (no drift), grid and direct give the same trajectory bit for bit. */
static void lj_cluster_energy(void)
{
    double e_first = 0;
    double *x_by_method[2] = {NULL, NULL};
    for (int method = 0; method < 2; method++) {
        urand_seed(12345);
        psys_system *sys = make_system(3);
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                for (int c = 0; c < 3; c++) {
                    double x[3] = {1.12 * a + urand(-0.03, 0.03), 1.12 * b + urand(-0.03, 0.03),
                                   1.12 * c + urand(-0.03, 0.03)};
                    double v[3] = {urand(-0.2, 0.2), urand(-0.2, 0.2), urand(-0.2, 0.2)};
                    add_particle(sys, x, v, 1.0);
                }
        psys_pair_def def = psys_pair_def_default();
        def.law = PSYS_PAIR_LENNARD_JONES;
        def.shift = true;
        def.method = method ? PSYS_PAIR_DIRECT : PSYS_PAIR_GRID;
        def.skin = 0.3;
        size_t k = add_pair(sys, &def);
        psys_error err;
        psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
        double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys), worst = 0;
        CHECK(e0 < 0); /* bound */
        for (int s = 1; s <= 1200; s++) {
            CHECK(psys_system_advance(sys, sol, 0.003, NULL) == PSYS_OK);
            if (s % 50 == 0) {
                double e = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
                worst = fmax(worst, fabs(e - e0));
            }
        }
        /* measured: about 2e-4 of |E0| (verlet's bounded oscillation at dt = 0.002) */
        if (worst > 1e-3 * fabs(e0))
            fprintf(stderr, "LJ cluster energy error %.3g (E0 = %.6g)\n", worst, e0);
        CHECK(worst <= 1e-3 * fabs(e0));
        if (method == 0) {
            e_first = e0;
            psys_pair_stats st;
            CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK);
            CHECK(st.rebuilds >= 2);            /* the atoms moved far enough to need new lists ... */
            CHECK(st.rebuilds < st.evaluations / 4); /* ... but lists were reused */
        } else {
            CHECK(e0 == e_first);
        }
        size_t nd = 27 * 3;
        x_by_method[method] = malloc(nd * sizeof(double));
        memcpy(x_by_method[method], psys_system_positions(sys), nd * sizeof(double));
        psys_solver_destroy(sol);
        psys_system_destroy(sys);
    }
    CHECK(memcmp(x_by_method[0], x_by_method[1], 27 * 3 * sizeof(double)) == 0);
    free(x_by_method[0]);
    free(x_by_method[1]);
}

/* ------------------------------------------------------------------ list sorting */

static int cmp_u32(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* The builds' sort of a list (the AVX-512 network where it runs, else
 * buckets and insertion; PSYS_SCAN_PLAIN forces the latter) against qsort:
 * every length up to 600, spread and clustered values, duplicates and the
 * largest index (the network's padding value); nothing past n is touched. */
static void sort_lists(void)
{
    enum { CAP = 640 };
    uint32_t *a = malloc(CAP * sizeof *a), *b = malloc(CAP * sizeof *b);
    psys_system *sys = psys_system_create(3, NULL); /* its switches: PSYS_SCAN_PLAIN */
    uint64_t st = 12345;
    for (int kind = 0; kind < 4; kind++)
        for (size_t n = 0; n <= 600; n++) {
            for (size_t i = 0; i < CAP; i++) {
                st = st * 6364136223846793005ull + 1442695040888963407ull;
                const uint32_t r = (uint32_t)(st >> 32);
                a[i] = kind == 0 ? r : kind == 1 ? 5000 + r % 900 : kind == 2 ? r % 7 : UINT32_MAX - r % 3;
            }
            memcpy(b, a, CAP * sizeof *a);
            psys__pair_sort_list(sys, a, n);
            qsort(b, n, sizeof *b, cmp_u32);
            CHECK(memcmp(a, b, CAP * sizeof *a) == 0);
        }
    psys_system_destroy(sys);
    free(a);
    free(b);
}

/* A Lennard-Jones pair definition (the tests' usual parameters). */
static psys_pair_def lj_def(double sigma, double epsilon, double cutoff, double skin, psys_pair_method method)
{
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = sigma;
    def.epsilon = epsilon;
    def.cutoff = cutoff;
    def.skin = skin;
    def.method = method;
    return def;
}

/* ------------------------------------------------------------------ grid = direct */

static psys_system *cloud_with_pair(int dim, size_t n, double size, int law, psys_pair_method method, double skin,
                                    const double *box_len, uint64_t seed)
{
    urand_seed(seed);
    psys_system *sys = random_cloud(dim, n, size, true, false);
    if (box_len) {
        double lo[3] = {0, 0, 0}, hi[3];
        bool per[3] = {true, true, true};
        for (int k = 0; k < 3; k++)
            hi[k] = box_len[k];
        per[dim - 1] = dim == 2 ? true : false; /* 3-D: z free, to mix both kinds of axes */
        CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
    }
    psys_pair_def def = psys_pair_def_default();
    def.law = (psys_pair_law)law;
    def.sigma = 0.1;
    def.epsilon = 0.01;
    def.cutoff = 0.3;
    def.radius = 0.25;
    def.k = 2.3; /* not a power of two: a change in the order of the kernel's products shows */
    def.method = method;
    def.skin = skin;
    add_pair(sys, &def);
    return sys;
}

/* Whether the grid's forces run four or eight rows at a time here
 * (pair/group.c: AVX2, not switched off). */
/* Evaluations of pair force i whose rows ran in the vector loops (src/sim/bench.h). */
static size_t grouped_of(const psys_system *sys, size_t i)
{
    size_t g = 0;
    CHECK(psys__system_pair_grouped(sys, i, &g) == PSYS_OK);
    return g;
}

static bool group_loops_run(void)
{
#if (defined(__GNUC__) || defined(__clang__)) && defined(__x86_64__)
    return __builtin_cpu_supports("avx2") && !getenv("PSYS_GROUP_OFF");
#else
    return false;
#endif
}

/* a and b give the same forces, bit for bit, not all zero, and the same energy. */
static void check_same_forces(psys_system *a, psys_system *b)
{
    const size_t nd = psys_system_count(a) * (size_t)psys_system_dim(a);
    double *fa = forces_of(a), *fb = forces_of(b);
    CHECK(memcmp(fa, fb, nd * sizeof(double)) == 0);
    double fmax_ = 0;
    for (size_t i = 0; i < nd; i++)
        fmax_ = fmax(fmax_, fabs(fa[i]));
    CHECK(fmax_ > 0);
    CHECK(psys_system_potential_energy(a) == psys_system_potential_energy(b));
    free(fa);
    free(fb);
}

/* n particles in a cloud of the given size; the skin passes first..last of
 * 0, 0.05, 0.4 */
static void compare_grid_direct_n(int dim, const double *box_len, size_t n, double size, int first, int last)
{
    for (int law = PSYS_PAIR_LENNARD_JONES; law <= PSYS_PAIR_SOFT_REPULSION; law++)
        for (int pass = first; pass <= last; pass++) {
            double skin = pass == 0 ? 0.0 : pass == 1 ? 0.05 : 0.4;
            psys_system *a = cloud_with_pair(dim, n, size, law, PSYS_PAIR_GRID, skin, box_len, 99 + pass);
            psys_system *b = cloud_with_pair(dim, n, size, law, PSYS_PAIR_DIRECT, skin, box_len, 99 + pass);
            for (int move = 0; move < 3; move++) {
                check_same_forces(a, b);
                /* small moves (lists reused) then a large one (rebuild); across the box edge too */
                for (size_t i = 0; i < n; i++) {
                    double x[3];
                    memcpy(x, psys_system_positions(a) + i * dim, dim * sizeof(double));
                    for (int k = 0; k < dim; k++)
                        x[k] += move == 1 ? urand(-0.3, 0.3) : urand(-0.01, 0.01);
                    CHECK(psys_system_set_particle(a, i, x, NULL) == PSYS_OK);
                    CHECK(psys_system_set_particle(b, i, x, NULL) == PSYS_OK);
                }
            }
            psys_pair_stats st;
            CHECK(psys_system_pair_stats(a, 0, &st) == PSYS_OK);
            CHECK(st.rebuilds >= 2 && st.pairs > 0 && st.fallbacks == 0);
            /* the vector loops ran where they can (else this compared the row kernel twice) */
            CHECK(group_loops_run() ? grouped_of(a, 0) > 0 : grouped_of(a, 0) == 0);
            psys_system_destroy(a);
            psys_system_destroy(b);
        }
}

static void compare_grid_direct(int dim, const double *box_len) { compare_grid_direct_n(dim, box_len, 250, 2.5, 0, 2); }

static void grid_equals_direct_2d(void) { compare_grid_direct(2, NULL); }
static void grid_equals_direct_3d(void) { compare_grid_direct(3, NULL); }
static void grid_equals_direct_periodic_2d(void)
{
    double len[3] = {2.5, 2.0, 0};
    compare_grid_direct(2, len);
}
static void grid_equals_direct_periodic_3d(void)
{
    double len[3] = {2.5, 0.7, 2.0}; /* 0.7: two cells across, wrapping onto the same neighbour */
    compare_grid_direct(3, len);
}

/* A user law on the grid: swept once over half lists on one thread (each
 * pair's force added to i and its negation to j), gathered over full lists
 * on three threads, and direct: the same forces bit for bit (each
 * particle's terms fused into its sum in increasing partner order on every
 * path), with small moves (lists kept) and a large one (a rebuild). */
static void user_law_grid_equals_direct(void)
{
    static double kuser = 2.3;
    for (int dim = 2; dim <= 3; dim++)
        for (int boxed = 0; boxed < 2; boxed++) {
            const double len[3] = {2.5, 2.0, 2.0};
            psys_system *sys[3];
            for (int v = 0; v < 3; v++) {
                urand_seed(71 + (uint64_t)dim);
                sys[v] = random_cloud(dim, 300, 2.5, true, false);
                if (boxed) {
                    const double lo[3] = {0, 0, 0};
                    const bool per[3] = {true, true, dim == 3 ? false : true};
                    CHECK(psys_system_set_box(sys[v], lo, len, per) == PSYS_OK);
                }
                psys_pair_def def = psys_pair_def_default();
                def.law = PSYS_PAIR_USER;
                def.fn = spring_law;
                def.ctx = &kuser;
                def.cutoff = 0.3;
                def.skin = 0.05;
                def.method = v == 2 ? PSYS_PAIR_DIRECT : PSYS_PAIR_GRID;
                add_pair(sys[v], &def);
                CHECK(psys_system_set_threads(sys[v], v == 1 ? 3 : 1) == PSYS_OK);
            }
            const size_t n = psys_system_count(sys[0]), nd = n * (size_t)dim;
            for (int move = 0; move < 3; move++) {
                double *f[3];
                for (int v = 0; v < 3; v++)
                    f[v] = forces_of(sys[v]);
                double big = 0;
                for (size_t i = 0; i < nd; i++)
                    big = fmax(big, fabs(f[2][i]));
                CHECK(big > 0);
                CHECK(memcmp(f[0], f[2], nd * sizeof(double)) == 0);
                CHECK(memcmp(f[1], f[2], nd * sizeof(double)) == 0);
                for (int v = 0; v < 3; v++)
                    free(f[v]);
                for (size_t i = 0; i < n; i++) {
                    double x[3];
                    memcpy(x, psys_system_positions(sys[0]) + i * dim, dim * sizeof(double));
                    for (int k = 0; k < dim; k++)
                        x[k] += move == 1 ? urand(-0.3, 0.3) : urand(-0.01, 0.01);
                    for (int v = 0; v < 3; v++)
                        CHECK(psys_system_set_particle(sys[v], i, x, NULL) == PSYS_OK);
                }
            }
            psys_pair_stats st;
            CHECK(psys_system_pair_stats(sys[0], 0, &st) == PSYS_OK);
            CHECK(st.rebuilds >= 2 && st.pairs > 0 && st.fallbacks == 0);
            for (int v = 0; v < 3; v++)
                psys_system_destroy(sys[v]);
        }
}

/* Denser clouds in a box of 7 cells a side (list radius 0.35, cells 0.2;
 * x and y periodic, z free): 1,500 particles, whose candidates per home cell
 * (about 550) the AVX-512 build gathers into one sliding window, and 6,000,
 * whose candidates (about 2,200) pass the window's 2,048 in most lines,
 * which then go cell by cell and run by run, with lists of about 400. Each
 * way the same forces as direct. */
static void grid_equals_direct_dense(void)
{
    double len[3] = {1.4, 1.4, 1.4};
    compare_grid_direct_n(3, len, 1500, 1.4, 1, 1);
    compare_grid_direct_n(3, len, 6000, 1.4, 1, 1);
}

/* 10³ particles on a jittered lattice filling a box periodic on every axis
 * (spacing 0.2, box 2, every position within half a skin of it; and all
 * lengths ten times that, with Lennard-Jones σ = 1): the
 * groups of eight consecutive rows lie along x, so many are near the faces
 * of x only and take the minimum image on that axis alone (pair/group.c),
 * others on all axes. The same forces and energy as direct, before and
 * after small moves. */
static psys_system *lattice_with_pair(int law, psys_pair_method method, double scale)
{
    urand_seed(7);
    psys_system *sys = jittered_lattice(3, 1000, 0.2 * scale, 0.02 * scale, false);
    double lo[3] = {0, 0, 0}, hi[3] = {2 * scale, 2 * scale, 2 * scale};
    bool per[3] = {true, true, true};
    CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
    psys_pair_def def = psys_pair_def_default();
    def.law = (psys_pair_law)law;
    def.sigma = scale == 10 ? 1.0 : 0.1 * scale; /* σ = 1: the eight-lane loop's own variant */
    def.epsilon = 0.01;
    def.cutoff = 0.3 * scale;
    def.radius = 0.25 * scale;
    def.k = 2.3;
    def.method = method;
    def.skin = 0.05 * scale;
    add_pair(sys, &def);
    return sys;
}

/* The lists hold every pair within the list radius, however the build
 * tests the distances (the AVX-512 build in single precision, whose
 * roundings at coordinates of 100 are a hundred times the 1e-7 margin used
 * here): a box far from the origin, with 400 pairs placed at 1 − 1e-7 of
 * the radius in random directions among 1,200 particles. The lists may
 * also hold a few pairs just outside (at most 1e-3 of the radius). */
static void grid_lists_keep_radius(void)
{
    urand_seed(11);
    psys_system *sys = make_system(3);
    const double lo[3] = {100, -120, 90}, L = 3.0, rl = 0.5;
    double hi[3];
    for (int k = 0; k < 3; k++)
        hi[k] = lo[k] + L;
    bool per[3] = {true, true, true};
    CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
    for (int i = 0; i < 800; i++) {
        double x[3], u[3], r = 0;
        for (int k = 0; k < 3; k++) {
            x[k] = lo[k] + urand(0.05, L - 0.05);
            u[k] = urand(-1, 1);
            r += u[k] * u[k];
        }
        add_particle(sys, x, NULL, 1);
        if (i % 2)
            continue;
        r = sqrt(r);
        for (int k = 0; k < 3; k++) {
            x[k] += u[k] / r * rl * (1 - 1e-7);
            x[k] = x[k] < lo[k] ? x[k] + L : x[k] >= hi[k] ? x[k] - L : x[k];
        }
        add_particle(sys, x, NULL, 1);
    }
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_SOFT_REPULSION;
    def.radius = 0.4;
    def.skin = 0.1;
    add_pair(sys, &def);
    free(forces_of(sys));
    const size_t n = psys_system_count(sys);
    const double *x = psys_system_positions(sys);
    size_t within = 0, near = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t j = i + 1; j < n; j++) {
            double r2 = 0;
            for (int k = 0; k < 3; k++) {
                double e = x[i * 3 + k] - x[j * 3 + k];
                e -= L * round(e / L);
                r2 += e * e;
            }
            within += r2 < rl * rl;
            near += r2 < rl * rl * (1 + 2e-3);
        }
    psys_pair_stats st;
    CHECK(psys_system_pair_stats(sys, 0, &st) == PSYS_OK);
    CHECK(within >= 400 && st.pairs >= within && st.pairs <= near);
    psys_system_destroy(sys);
}

static void grid_equals_direct_lattice(void)
{
    const size_t n = 1000;
    for (int pass = 0; pass < 3; pass++) {
        const int law = pass == 2 ? PSYS_PAIR_SOFT_REPULSION : PSYS_PAIR_LENNARD_JONES;
        const double scale = pass == 1 ? 10 : 1;
        psys_system *a = lattice_with_pair(law, PSYS_PAIR_GRID, scale);
        psys_system *b = lattice_with_pair(law, PSYS_PAIR_DIRECT, scale);
        for (int move = 0; move < 3; move++) {
            check_same_forces(a, b);
            for (size_t i = 0; i < n; i++) {
                double x[3];
                memcpy(x, psys_system_positions(a) + i * 3, sizeof x);
                for (int k = 0; k < 3; k++)
                    x[k] += urand(-0.002, 0.002) * scale;
                CHECK(psys_system_set_particle(a, i, x, NULL) == PSYS_OK);
                CHECK(psys_system_set_particle(b, i, x, NULL) == PSYS_OK);
            }
        }
        psys_pair_stats st;
        CHECK(psys_system_pair_stats(a, 0, &st) == PSYS_OK);
        CHECK(st.pairs > 0 && st.fallbacks == 0);
        CHECK(group_loops_run() ? grouped_of(a, 0) > 0 : grouped_of(a, 0) == 0);
        psys_system_destroy(a);
        psys_system_destroy(b);
    }
}

/* A few particles moved between evaluations (lists kept): only they and
 * their partners are recomputed (a partial evaluation, whose position
 * records are updated for the moved particles only), and the forces are
 * still direct's, bit for bit; one moved particle leaves the box through a
 * face, one is put back in (as a wrap does). */
static void grid_partial_matches_direct(void)
{
    for (int pass = 0; pass < 2; pass++) {
        const int law = pass ? PSYS_PAIR_SOFT_REPULSION : PSYS_PAIR_LENNARD_JONES;
        psys_system *a = lattice_with_pair(law, PSYS_PAIR_GRID, 1);
        psys_system *b = lattice_with_pair(law, PSYS_PAIR_DIRECT, 1);
        const size_t moved[5] = {3, 250, 511, 777, 998};
        for (int round = 0; round < 6; round++) {
            check_same_forces(a, b);
            for (int q = 0; q < 5; q++) {
                double x[3];
                memcpy(x, psys_system_positions(a) + moved[q] * 3, sizeof x);
                for (int k = 0; k < 3; k++)
                    x[k] += urand(-0.004, 0.004);
                if (q == 0) /* across the face x = 0 and back: 2 is the box length */
                    x[0] += round % 2 ? 2.0 : -2.0;
                CHECK(psys_system_set_particle(a, moved[q], x, NULL) == PSYS_OK);
                CHECK(psys_system_set_particle(b, moved[q], x, NULL) == PSYS_OK);
            }
        }
        psys_pair_stats st;
        CHECK(psys_system_pair_stats(a, 0, &st) == PSYS_OK);
        CHECK(st.partial >= 4 && st.fallbacks == 0);
        CHECK(group_loops_run() ? grouped_of(a, 0) > 0 : grouped_of(a, 0) == 0);
        psys_system_destroy(a);
        psys_system_destroy(b);
    }
}

/* The sparse partial loop (pair/group.c: the marked rows eight at a time
 * wherever they lie, their lists interleaved on the fly; where most rows of
 * the touched groups are marked, the groups as they are): 4,913 particles,
 * two spans of 4,096 rows, one and two threads. Rounds alternate between
 * scattered moves in the second span (one through a face) and a block of
 * 600 consecutive particles in the first; after each, the forces equal
 * those of a system built afresh at the same positions (a full evaluation)
 * bit for bit. */
static void grid_partial_sparse_groups(void)
{
    const size_t side = 17, n = side * side * side;
    const double L = 0.2 * (double)side, lo[3] = {0, 0, 0}, hi[3] = {L, L, L};
    const bool per[3] = {true, true, true};
    const psys_pair_def def = lj_def(0.1, 0.01, 0.3, 0.05, PSYS_PAIR_GRID);
    for (int threads = 1; threads <= 2; threads++) {
        urand_seed(13);
        psys_system *a = jittered_lattice(3, n, 0.2, 0.02, false);
        CHECK(psys_system_set_box(a, lo, hi, per) == PSYS_OK);
        add_pair(a, &def);
        CHECK(psys_system_set_threads(a, threads) == PSYS_OK);
        for (int round = 0; round < 6; round++) {
            double *fa = forces_of(a);
            psys_system *b = make_system(3);
            for (size_t i = 0; i < n; i++)
                add_particle(b, psys_system_positions(a) + 3 * i, NULL, 1.0);
            CHECK(psys_system_set_box(b, lo, hi, per) == PSYS_OK);
            add_pair(b, &def);
            CHECK(psys_system_set_threads(b, threads) == PSYS_OK);
            double *fb = forces_of(b);
            CHECK(memcmp(fa, fb, 3 * n * sizeof(double)) == 0);
            free(fa);
            free(fb);
            psys_system_destroy(b);
            const size_t count = round % 2 ? 600 : 15;
            for (size_t q = 0; q < count; q++) {
                const size_t i = round % 2 ? q : 4100 + 53 * q;
                double x[3];
                memcpy(x, psys_system_positions(a) + 3 * i, sizeof x);
                for (int k = 0; k < 3; k++)
                    x[k] += urand(-0.004, 0.004);
                if (q == 0 && !(round % 2))
                    x[0] += x[0] < 0.5 * L ? L : -L;
                CHECK(psys_system_set_particle(a, i, x, NULL) == PSYS_OK);
            }
        }
        psys_pair_stats st;
        CHECK(psys_system_pair_stats(a, 0, &st) == PSYS_OK);
        CHECK(st.partial >= 3 && st.fallbacks == 0);
        CHECK(group_loops_run() ? grouped_of(a, 0) > 0 : grouped_of(a, 0) == 0);
        psys_system_destroy(a);
    }
}

/* The grid's groups of rows (pair/group.c) follow the particles' numbering
 * where it is local (a lattice numbered row by row) and the cell order
 * where it is not (the same lattice numbered at random): both give
 * direct's forces bit for bit, through full evaluations, partial ones (15
 * particles moved, one across a face, or 600) and rebuilds, on one and two
 * threads. */
static void grid_groups_any_numbering(void)
{
    const size_t side = 17, n = side * side * side;
    const double L = 0.2 * (double)side, lo[3] = {0, 0, 0}, hi[3] = {L, L, L};
    const bool per[3] = {true, true, true};
    const psys_pair_def grid = lj_def(0.1, 0.01, 0.3, 0.05, PSYS_PAIR_GRID);
    const psys_pair_def direct = lj_def(0.1, 0.01, 0.3, 0.05, PSYS_PAIR_DIRECT);
    urand_seed(29);
    psys_system *lat = jittered_lattice(3, n, 0.2, 0.02, false);
    size_t *pi = malloc(n * sizeof *pi);
    for (size_t i = 0; i < n; i++)
        pi[i] = i;
    for (size_t i = n - 1; i > 0; i--) {
        size_t j = (size_t)urand(0, (double)(i + 1));
        j = j > i ? i : j;
        const size_t t = pi[i];
        pi[i] = pi[j];
        pi[j] = t;
    }
    for (int shuffled = 0; shuffled < 2; shuffled++)
        for (int threads = 1; threads <= 2; threads++) {
            psys_system *a = make_system(3);
            for (size_t q = 0; q < n; q++)
                add_particle(a, psys_system_positions(lat) + 3 * (shuffled ? pi[q] : q), NULL, 1.0);
            CHECK(psys_system_set_box(a, lo, hi, per) == PSYS_OK);
            const size_t k = add_pair(a, &grid);
            CHECK(psys_system_set_threads(a, threads) == PSYS_OK);
            for (int round = 0; round < 6; round++) {
                double *fa = forces_of(a);
                if (group_loops_run()) /* the grouping this numbering takes */
                    CHECK(((const pair_force *)psys_system_force_data(a, k))->grid.gl_cells == (shuffled == 1));
                psys_system *b = make_system(3);
                for (size_t i = 0; i < n; i++)
                    add_particle(b, psys_system_positions(a) + 3 * i, NULL, 1.0);
                CHECK(psys_system_set_box(b, lo, hi, per) == PSYS_OK);
                add_pair(b, &direct);
                double *fb = forces_of(b);
                CHECK(memcmp(fa, fb, 3 * n * sizeof(double)) == 0);
                free(fa);
                free(fb);
                psys_system_destroy(b);
                const size_t count = round == 4 ? n : round % 2 ? 600 : 15;
                for (size_t q = 0; q < count; q++) {
                    const size_t i = round % 2 || round == 4 ? q : 4100 + 53 * q;
                    double x[3];
                    memcpy(x, psys_system_positions(a) + 3 * i, sizeof x);
                    for (int c = 0; c < 3; c++)
                        x[c] += round == 4 ? urand(-0.03, 0.03) : urand(-0.004, 0.004);
                    if (q == 0 && !(round % 2))
                        x[0] += x[0] < 0.5 * L ? L : -L;
                    CHECK(psys_system_set_particle(a, i, x, NULL) == PSYS_OK);
                }
            }
            psys_pair_stats st;
            CHECK(psys_system_pair_stats(a, k, &st) == PSYS_OK);
            CHECK(st.partial >= 3 && st.rebuilds >= 2 && st.fallbacks == 0);
            CHECK(group_loops_run() ? grouped_of(a, k) > 0 : grouped_of(a, k) == 0);
            psys_system_destroy(a);
        }
    free(pi);
    psys_system_destroy(lat);
}

/* A pair at exactly the cutoff adds nothing in the vector loops (the
 * eight-lane loop tests 0 < r² < rc² on the bits): 16 particles on a line,
 * 0 and 1 at r = rc = 0.5 (r² = rc² exactly), 2 and 3 at 0.49, the others
 * far apart. Grid equals direct bit for bit; particles 0 and 1 feel no
 * force, 2 and 3 opposite ones. */
static void cutoff_boundary_groups(void)
{
    psys_system *sys[2];
    for (int q = 0; q < 2; q++) {
        sys[q] = make_system(3);
        for (int i = 0; i < 16; i++) {
            double x[3] = {2.0 * i, 0, 0};
            if (i == 1)
                x[0] = 0.5;
            if (i == 3)
                x[0] = 4.0 + 0.49;
            add_particle(sys[q], x, NULL, 1.0);
        }
        const psys_pair_def def = lj_def(0.45, 0.01, 0.5, 0.1, q ? PSYS_PAIR_DIRECT : PSYS_PAIR_GRID);
        add_pair(sys[q], &def);
    }
    check_same_forces(sys[0], sys[1]);
    double *f = forces_of(sys[0]);
    for (int k = 0; k < 3; k++)
        CHECK(f[k] == 0 && f[3 + k] == 0);
    CHECK(f[6] != 0 && f[9] == -f[6]);
    free(f);
    psys_pair_stats st;
    CHECK(psys_system_pair_stats(sys[0], 0, &st) == PSYS_OK);
    CHECK(group_loops_run() ? grouped_of(sys[0], 0) > 0 : grouped_of(sys[0], 0) == 0);
    psys_system_destroy(sys[0]);
    psys_system_destroy(sys[1]);
}

/* A particle taken through a face by exactly one box length, as the wrap
 * after a step does: in the box [0, 2) its differences to the partners it
 * leaves behind the face keep their bits (their coordinates lie in [1, 2),
 * its own at 2.003 and 2.003 − 2 on the grid of 2⁻⁵¹, so both differences
 * are exact), so a partial evaluation recomputes it and its partners across
 * the face but not those: fewer rows than its neighbourhood, and still
 * direct's forces bit for bit. */
static void grid_partial_keeps_unchanged_rows(void)
{
    psys_system *a = lattice_with_pair(PSYS_PAIR_LENNARD_JONES, PSYS_PAIR_GRID, 1);
    psys_system *b = lattice_with_pair(PSYS_PAIR_LENNARD_JONES, PSYS_PAIR_DIRECT, 1);
    const size_t c = 9 + 10 * 5 + 100 * 5, n = psys_system_count(a); /* x ≈ 1.8, y and z ≈ 1 */
    double x[3];
    memcpy(x, psys_system_positions(a) + 3 * c, sizeof x);
    x[0] = 2.003; /* just past the face */
    CHECK(psys_system_set_particle(a, c, x, NULL) == PSYS_OK && psys_system_set_particle(b, c, x, NULL) == PSYS_OK);
    check_same_forces(a, b);
    psys_pair_stats s0, s1;
    CHECK(psys_system_pair_stats(a, 0, &s0) == PSYS_OK);
    x[0] = 2.003 - 2.0; /* wrapped, exactly */
    CHECK(x[0] + 2.0 == 2.003);
    CHECK(psys_system_set_particle(a, c, x, NULL) == PSYS_OK && psys_system_set_particle(b, c, x, NULL) == PSYS_OK);
    check_same_forces(a, b);
    CHECK(psys_system_pair_stats(a, 0, &s1) == PSYS_OK);
    CHECK(s1.partial == s0.partial + 1 && s1.rebuilds == s0.rebuilds);
    /* its neighbourhood (within the list radius 0.35, minimum image) on
     * either side of the face */
    size_t behind = 0, across = 0;
    const double *p = psys_system_positions(a);
    for (size_t j = 0; j < n; j++) {
        double r2 = 0;
        for (int k = 0; k < 3; k++) {
            double dx = p[3 * j + k] - p[3 * c + k];
            dx -= 2.0 * nearbyint(dx / 2.0);
            r2 += dx * dx;
        }
        if (j != c && r2 < 0.35 * 0.35)
            *(p[3 * j] > 1.0 ? &behind : &across) += 1;
    }
    const size_t rows = s1.partial_rows - s0.partial_rows;
    CHECK(behind > 0 && across > 0);
    CHECK(rows == across + 1);
    psys_system_destroy(a);
    psys_system_destroy(b);
}

/* The rebuild tests' system: a 10 × 10 lattice of spacing 0.5 with a
 * soft repulsion of radius 0.6 and skin 0.2 (*def, force index *k). */
static psys_system *rebuild_lattice(psys_pair_def *def, size_t *k)
{
    psys_system *sys = make_system(2);
    for (int i = 0; i < 10; i++)
        for (int j = 0; j < 10; j++) {
            double x[2] = {0.5 * i, 0.5 * j};
            add_particle(sys, x, NULL, 1);
        }
    *def = psys_pair_def_default();
    def->law = PSYS_PAIR_SOFT_REPULSION;
    def->radius = 0.6;
    def->skin = 0.2;
    *k = add_pair(sys, def);
    return sys;
}

/* The forces of a fresh rebuild_lattice system (pair def) with sys's positions. */
static double *fresh_forces(const psys_system *sys, const psys_pair_def *def)
{
    psys_system *fresh = make_system(2);
    for (size_t i = 0; i < 100; i++)
        add_particle(fresh, psys_system_positions(sys) + 2 * i, NULL, 1);
    add_pair(fresh, def);
    double *f = forces_of(fresh);
    psys_system_destroy(fresh);
    return f;
}

/* Lists are rebuilt only when the two largest displacements since the last
 * build add up to the skin or more. */
static void grid_rebuild_criterion(void)
{
    psys_pair_def def;
    size_t k;
    psys_system *sys = rebuild_lattice(&def, &k);
    psys_pair_stats st;
    double *f0 = forces_of(sys);
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1 && st.pairs == 90 + 90 + 162);
    free(forces_of(sys)); /* nothing moved */
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1);
    double x[2] = {0.5 * 3 + 0.15, 0.5 * 4}; /* one particle moved 0.15 < skin */
    psys_system_set_particle(sys, 34, x, NULL);
    free(forces_of(sys));
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1);
    double y[2] = {0.5 * 7, 0.5 * 7 + 0.04}; /* a second one 0.04: 0.19 < skin */
    psys_system_set_particle(sys, 77, y, NULL);
    free(forces_of(sys));
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1);
    y[1] = 0.5 * 7 + 0.06; /* 0.15 + 0.06 >= skin: they could now be closer than listed */
    psys_system_set_particle(sys, 77, y, NULL);
    free(forces_of(sys));
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 2);
    CHECK(st.evaluations == 5);
    /* particle 77 back (0.06 from the last build): no rebuild, and the forces
     * of a fresh system in the same state, bit for bit */
    double y0[2] = {3.5, 3.5};
    psys_system_set_particle(sys, 77, y0, NULL);
    double *f1 = forces_of(sys);
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 2);
    double *f2 = fresh_forces(sys, &def);
    CHECK(memcmp(f1, f2, 100 * 2 * sizeof(double)) == 0);
    CHECK(memcmp(f0, f2, 100 * 2 * sizeof(double)) != 0);
    free(f0);
    free(f1);
    free(f2);
    psys_system_destroy(sys);
}

/* The same rule when most particles moved, so the check passes over all of
 * them (in lanes of eight, each keeping its own two largest): every
 * particle moved 0.001, particle 34 0.15 more, then particle 42, in the
 * same lane, 0.06: the second pair of moves must rebuild. */
static void grid_rebuild_criterion_all_moved(void)
{
    psys_pair_def def;
    size_t k;
    psys_system *sys = rebuild_lattice(&def, &k);
    psys_pair_stats st;
    free(forces_of(sys));
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1);
    for (size_t i = 0; i < 100; i++) {
        const double *p = psys_system_positions(sys) + 2 * i;
        double x[2] = {p[0] + 0.001 + (i == 34 ? 0.15 : 0.0), p[1]};
        psys_system_set_particle(sys, i, x, NULL);
    }
    free(forces_of(sys));
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 1); /* 0.151 + 0.001 < skin */
    for (size_t i = 0; i < 100; i++) {
        const double *p = psys_system_positions(sys) + 2 * i;
        double x[2] = {p[0], p[1] + (i == 42 ? 0.06 : 1e-9)};
        psys_system_set_particle(sys, i, x, NULL);
    }
    double *f1 = forces_of(sys);
    CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK && st.rebuilds == 2); /* 0.151 + 0.060 >= skin */
    double *f2 = fresh_forces(sys, &def);
    CHECK(memcmp(f1, f2, 100 * 2 * sizeof(double)) == 0);
    free(f1);
    free(f2);
    psys_system_destroy(sys);
}

/* The grid method reuses the forces of particles whose neighbourhood did not
 * move (verlet's two evaluations at the same positions, up to particles
 * wrapped into the box): a periodic verlet run equals the direct method's bit
 * for bit, with partial evaluations taking place. */
static void grid_cache_matches_direct(void)
{
    double *xs[2];
    for (int method = 0; method < 2; method++) {
        urand_seed(99);
        psys_system *sys = make_system(3);
        double lo[3] = {0, 0, 0}, hi[3] = {4, 4, 4};
        bool per[3] = {true, true, true};
        CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
        for (int i = 0; i < 216; i++) {
            double x[3] = {(i % 6) * 0.66 + urand(0, 0.05), (i / 6 % 6) * 0.66 + urand(0, 0.05), (i / 36) * 0.66 + 0.01};
            double v[3] = {urand(-3, 3), urand(-3, 3), urand(-3, 3)};
            add_particle(sys, x, v, 1);
        }
        const psys_pair_def def = lj_def(0.6, 1, 1.5, 0.4, method ? PSYS_PAIR_DIRECT : PSYS_PAIR_GRID);
        size_t k = add_pair(sys, &def);
        psys_error err;
        psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
        for (int s = 0; s < 30; s++)
            CHECK(psys_system_advance(sys, sol, 0.004, NULL) == PSYS_OK);
        if (method == 0) {
            psys_pair_stats st;
            CHECK(psys_system_pair_stats(sys, k, &st) == PSYS_OK);
            CHECK(st.partial > 5);                 /* some particles wrapped: partial recomputation */
            CHECK(st.rebuilds > 1 && st.rebuilds < 15);
        }
        xs[method] = malloc(216 * 3 * sizeof(double));
        memcpy(xs[method], psys_system_positions(sys), 216 * 3 * sizeof(double));
        psys_solver_destroy(sol);
        psys_system_destroy(sys);
    }
    CHECK(memcmp(xs[0], xs[1], 216 * 3 * sizeof(double)) == 0);
    free(xs[0]);
    free(xs[1]);
}

/* ------------------------------------------------------------------ periodic box */

/* Two particles near opposite faces interact as if adjacent. */
/* The minimum-image tests' law: LJ with sigma 0.5, cut at 1.25. */
static psys_pair_def image_lj(int method)
{
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = 0.5;
    def.cutoff = 1.25;
    def.method = (psys_pair_method)method;
    return def;
}

/* An empty system in the periodic box [0, 10)^dim. */
static psys_system *boxed_10(int dim)
{
    psys_system *a = make_system(dim);
    double lo[3] = {0, 0, 0}, hi[3] = {10, 10, 10};
    bool per[3] = {true, true, true};
    CHECK(psys_system_set_box(a, lo, hi, per) == PSYS_OK);
    return a;
}

/* Partners more than 1.5 boxes apart (positions not wrapped into the box,
 * as a solver's stage states may be): the vectorised loops then take the
 * general image formula; the forces equal the pair's in open space. */
static void minimum_image_far(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (int method = PSYS_PAIR_DIRECT; method <= PSYS_PAIR_GRID; method++)
            for (int shift = -3; shift <= 3; shift += 6) {
                psys_pair_def def = image_lj(method);
                psys_system *a = boxed_10(dim);
                /* 0.6 apart through the x faces, the second particle 3 boxes off */
                double p0[3] = {0.2, 5, 5}, p1[3] = {9.6 + 10.0 * shift, 5, 5};
                add_particle(a, p0, NULL, 1);
                add_particle(a, p1, NULL, 1);
                add_pair(a, &def);
                psys_system *b = make_system(dim);
                double q0[3] = {5.2, 5, 5}, q1[3] = {4.6, 5, 5};
                add_particle(b, q0, NULL, 1);
                add_particle(b, q1, NULL, 1);
                add_pair(b, &def);
                double *fa = forces_of(a), *fb = forces_of(b);
                CHECK(fa[0] < 0); /* attracted toward the image at -0.4 */
                CHECK_NEAR(fa[0], fb[0], 1e-9 * fabs(fb[0]));
                CHECK(fa[dim] == -fa[0]);
                free(fa);
                free(fb);
                psys_system_destroy(a);
                psys_system_destroy(b);
            }
}

/* The same with many particles, so the grid's four-rows-at-a-time kernel
 * (pair/group.c) meets a partner one or several boxes off inside full
 * groups, both in a cluster across the faces (groups with the image) and in
 * one in the middle of the box (groups first without it, flagged, then again
 * with it): grid still equals direct bit for bit, and the forces are the
 * wrapped configuration's to rounding. */
static void minimum_image_far_groups(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (int v = 0; v < 8; v++) {
            const int shifts[4] = {-3, -1, 1, 3};
            const double centre = v < 4 ? 5.0 : 10.0;
            const int shift = shifts[v % 4];
            psys_system *s[3];
            for (int c = 0; c < 3; c++) {
                s[c] = boxed_10(dim);
                urand_seed(17);
                for (int i = 0; i < 24; i++) {
                    double x[3] = {urand(centre - 1.0, centre + 1.0), urand(4.0, 6.0), urand(4.0, 6.0)};
                    x[0] -= x[0] >= 10 ? 10 : 0; /* wrapped into [0, 10) */
                    if (c < 2 && i == 9)
                        x[0] += 10.0 * shift; /* particle 9 one or three boxes off */
                    add_particle(s[c], x, NULL, 1);
                }
                psys_pair_def def = image_lj(c == 1 ? PSYS_PAIR_DIRECT : PSYS_PAIR_GRID);
                add_pair(s[c], &def);
            }
            double *fg = forces_of(s[0]), *fd = forces_of(s[1]), *fw = forces_of(s[2]);
            CHECK(memcmp(fg, fd, 24 * (size_t)dim * sizeof(double)) == 0);
            double fmax_ = 0;
            for (size_t k = 0; k < 24 * (size_t)dim; k++)
                fmax_ = fmax(fmax_, fabs(fw[k]));
            CHECK(fmax_ > 0);
            for (size_t k = 0; k < 24 * (size_t)dim; k++)
                CHECK_NEAR(fg[k], fw[k], 1e-9 * fmax_);
            free(fg);
            free(fd);
            free(fw);
            for (int c = 0; c < 3; c++)
                psys_system_destroy(s[c]);
        }
}

static void minimum_image(void)
{
    for (int dim = 2; dim <= 3; dim++)
        for (int method = PSYS_PAIR_DIRECT; method <= PSYS_PAIR_GRID; method++)
            for (int sep = 0; sep < 2; sep++) {
                double gap = sep ? 0.6 : 0.45; /* σ = 0.5: 0.6 attracts (past 0.561), 0.45 repels */
                psys_pair_def def = image_lj(method);
                /* across the x faces of a box [0, 10)^dim */
                psys_system *a = boxed_10(dim);
                double p0[3] = {0.2, 5, 5}, p1[3] = {10.2 - gap, 5, 5};
                add_particle(a, p0, NULL, 1);
                add_particle(a, p1, NULL, 1);
                add_pair(a, &def);
                /* the same pair side by side in open space */
                psys_system *b = make_system(dim);
                double q0[3] = {5.2, 5, 5}, q1[3] = {5.2 - gap, 5, 5};
                add_particle(b, q0, NULL, 1);
                add_particle(b, q1, NULL, 1);
                add_pair(b, &def);
                double *fa = forces_of(a), *fb = forces_of(b);
                CHECK(fa[0] != 0);
                CHECK_NEAR(fa[0], fb[0], 1e-12 * fabs(fb[0]));
                CHECK(sep ? fa[0] < 0 : fa[0] > 0); /* attract toward the image at 0.2 - gap, or repel */
                CHECK(fa[dim] == -fa[0]);
                CHECK_NEAR(psys_system_potential_energy(a), psys_system_potential_energy(b), 1e-12);
                CHECK(psys_system_potential_energy(a) != 0);
                /* without the box they are 9.4 apart: nothing */
                psys_system *c = make_system(dim);
                add_particle(c, p0, NULL, 1);
                add_particle(c, p1, NULL, 1);
                add_pair(c, &def);
                double *fc = forces_of(c);
                CHECK(fc[0] == 0);
                free(fa);
                free(fb);
                free(fc);
                psys_system_destroy(a);
                psys_system_destroy(b);
                psys_system_destroy(c);
            }
}

/* Positions wrap on periodic axes after each step; velocities are unchanged;
 * free axes, fixed particles and particles inside the box are left alone. */
static void wrapping(void)
{
    psys_system *sys = make_system(2);
    double lo[2] = {-1, 0}, hi[2] = {1, 4};
    bool per[2] = {true, false};
    CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_OK);
    double x0[2] = {0.95, 3.95}, v0[2] = {1.0, 1.0};
    double x1[2] = {-0.95, 0.5}, v1[2] = {-1.0, 0.0};
    double x2[2] = {5.0, 2.0}; /* fixed, outside: stays */
    add_particle(sys, x0, v0, 1);
    add_particle(sys, x1, v1, 1);
    add_particle(sys, x2, NULL, 1);
    psys_system_set_fixed(sys, 2, true);
    psys_error err;
    psys_solver *sol = psys_system_solver_create(sys, "symplectic-euler", &err);
    for (int s = 0; s < 10; s++)
        CHECK(psys_system_advance(sys, sol, 0.01, NULL) == PSYS_OK);
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    CHECK_NEAR(x[0], 1.05 - 2.0, 1e-12); /* wrapped from 1.05 */
    CHECK_NEAR(x[1], 4.05, 1e-12);       /* free axis: not wrapped */
    CHECK_NEAR(x[2], -1.05 + 2.0, 1e-12);
    CHECK(x[3] == 0.5);
    CHECK(x[4] == 5.0 && x[5] == 2.0);
    CHECK(v[0] == 1.0 && v[1] == 1.0 && v[2] == -1.0);
    for (int s = 0; s < 1000; s++)
        CHECK(psys_system_advance(sys, sol, 0.01, NULL) == PSYS_OK);
    x = psys_system_positions(sys);
    CHECK(x[0] >= -1 && x[0] < 1);
    CHECK(x[2] >= -1 && x[2] < 1);
    psys_solver_destroy(sol);
    /* far outside: wrapped in one go */
    double far[2] = {1001.5, 1};
    psys_system_set_particle(sys, 0, far, NULL);
    psys_system_wrap_positions(sys);
    CHECK_NEAR(psys_system_positions(sys)[0], -0.5, 1e-12);
    bool got_per[2];
    double glo[2], ghi[2];
    CHECK(psys_system_box(sys, glo, ghi, got_per));
    CHECK(glo[0] == -1 && ghi[1] == 4 && got_per[0] && !got_per[1]);
    CHECK(psys_system_set_box(sys, NULL, NULL, NULL) == PSYS_OK);
    CHECK(!psys_system_box(sys, NULL, NULL, NULL));
    psys_system_destroy(sys);
}

static void box_validation(void)
{
    psys_system *sys = make_system(2);
    double lo[2] = {0, 0}, hi[2] = {1, 0}, hi2[2] = {1, 1};
    bool per[2] = {true, true};
    CHECK(psys_system_set_box(sys, lo, hi, per) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "box hi must be greater than lo on every axis (axis 1: lo 0, hi 0)");
    psys_pair_def def = psys_pair_def_default(); /* gravity: no cutoff */
    add_pair(sys, &def);
    CHECK(psys_system_set_box(sys, lo, hi2, per) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "pair force 0: the gravity law has no cutoff, so it cannot be used with a "
                                           "periodic box (no Ewald sums)");
    bool open[2] = {false, false};
    CHECK(psys_system_set_box(sys, lo, hi2, open) == PSYS_OK); /* no periodic axis: fine */
    psys_system_destroy(sys);

    sys = make_system(2);
    CHECK(psys_system_set_box(sys, lo, hi2, per) == PSYS_OK);
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = 0.2; /* cutoff 0.5 = half the box */
    CHECK(psys_system_add_pair(sys, &def, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys),
              "the cutoff (0.5) must be less than half the periodic box (box length 1 on axis 0)");
    def.cutoff = 0.49;
    add_pair(sys, &def);
    double hi3[2] = {0.9, 1};
    CHECK(psys_system_set_box(sys, lo, hi3, per) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "pair force 0: the cutoff (0.48999999999999999) must be less than half "
                                           "the periodic box (box length 0.90000000000000002 on axis 0)");
    psys_system_destroy(sys);

    /* API validation of definitions */
    sys = make_system(3);
    psys_pair_def bad = psys_pair_def_default();
    bad.method = PSYS_PAIR_GRID;
    CHECK(psys_system_add_pair(sys, &bad, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "method grid needs a law with a cutoff (lennard-jones, soft-repulsion, or "
                                           "a user law with cutoff > 0)");
    bad = psys_pair_def_default();
    bad.law = PSYS_PAIR_LENNARD_JONES;
    bad.method = PSYS_PAIR_BARNES_HUT;
    CHECK(psys_system_add_pair(sys, &bad, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "method barnes-hut is only for the long-range laws gravity and coulomb");
    bad = psys_pair_def_default();
    bad.softening = -1;
    CHECK(psys_system_add_pair(sys, &bad, NULL) == PSYS_ERR_INVALID);
    bad = psys_pair_def_default();
    bad.law = PSYS_PAIR_USER;
    CHECK(psys_system_add_pair(sys, &bad, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "a user pair law needs a function (fn)");
    CHECK(psys_system_force_count(sys) == 0);
    CHECK(psys_system_set_charge(sys, 0, 1) == PSYS_ERR_INVALID);
    double x[3] = {0, 0, 0};
    add_particle(sys, x, NULL, 1);
    CHECK(psys_system_set_charge(sys, 0, NAN) == PSYS_ERR_INVALID);
    CHECK(psys_system_charge(sys, 0) == 0);
    CHECK(psys_system_set_threads(sys, -1) == PSYS_ERR_INVALID);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ threads */

static psys_system *thread_case(int which)
{
    urand_seed(777 + (uint64_t)which);
    if (which == 0) { /* LJ in a periodic 3-D box, grid; 4,096 particles, so list builds run in parallel */
        double len[3] = {12, 12, 12};
        psys_system *sys = make_system(3);
        double lo[3] = {0, 0, 0};
        bool per[3] = {true, true, true};
        CHECK(psys_system_set_box(sys, lo, len, per) == PSYS_OK);
        for (int a = 0; a < 16; a++)
            for (int b = 0; b < 16; b++)
                for (int c = 0; c < 16; c++) {
                    double x[3] = {0.75 * a + urand(-0.05, 0.05), 0.75 * b + urand(-0.05, 0.05),
                                   0.75 * c + urand(-0.05, 0.05)};
                    double v[3] = {urand(-1, 1), urand(-1, 1), urand(-1, 1)};
                    add_particle(sys, x, v, 1);
                }
        const psys_pair_def def = lj_def(0.7, 1, 1.75, 0.2, PSYS_PAIR_AUTO);
        add_pair(sys, &def);
        return sys;
    }
    psys_system *sys = random_cloud(which == 3 ? 2 : 3, 200, 1.0, true, false);
    psys_pair_def def = psys_pair_def_default();
    def.softening = 0.01;
    def.G = 1e-3;
    def.method = which == 1 ? PSYS_PAIR_DIRECT : PSYS_PAIR_BARNES_HUT;
    add_pair(sys, &def);
    return sys;
}

/* Forces, energies and a short trajectory are identical for 1, 2 and 4 threads. */
static void thread_determinism(int first, int last)
{
    for (int which = first; which <= last; which++) {
        double *ref_f = NULL, *ref_x = NULL, ref_u = 0;
        size_t nd = 0;
        for (int t = 1; t <= 4; t *= 2) {
            psys_system *sys = thread_case(which);
            CHECK(psys_system_set_threads(sys, t) == PSYS_OK);
            CHECK(psys_system_threads(sys) == t);
            nd = psys_system_count(sys) * (size_t)psys_system_dim(sys);
            double *f = forces_of(sys);
            double u = psys_system_potential_energy(sys);
            psys_error err;
            psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
            for (int s = 0; s < 5; s++)
                CHECK(psys_system_advance(sys, sol, 0.002, NULL) == PSYS_OK);
            psys_solver_destroy(sol);
            if (t == 1) {
                ref_f = f;
                ref_u = u;
                ref_x = malloc(nd * sizeof(double));
                memcpy(ref_x, psys_system_positions(sys), nd * sizeof(double));
            } else {
                CHECK(memcmp(f, ref_f, nd * sizeof(double)) == 0);
                CHECK(u == ref_u);
                CHECK(memcmp(psys_system_positions(sys), ref_x, nd * sizeof(double)) == 0);
                free(f);
            }
            psys_system_destroy(sys);
        }
        free(ref_f);
        free(ref_x);
    }
}

static void thread_determinism_grid(void) { thread_determinism(0, 0); }
static void thread_determinism_direct_bh(void) { thread_determinism(1, 3); }

/* ------------------------------------------------------------------ Barnes–Hut */

/* A centrally condensed cloud (radius ~ u³) for Barnes–Hut, with a pair force of the given method. */
static psys_system *bh_cloud(int dim, size_t n, int law, psys_pair_method method, double theta)
{
    urand_seed(4242);
    psys_system *sys = make_system(dim);
    for (size_t i = 0; i < n; i++) {
        double x[3], r2 = 0;
        do {
            r2 = 0;
            for (int k = 0; k < dim; k++) {
                x[k] = urand(-1, 1);
                r2 += x[k] * x[k];
            }
        } while (r2 > 1);
        for (int k = 0; k < dim; k++)
            x[k] *= r2;
        add_particle(sys, x, NULL, urand(0.5, 1.5));
        if (law == PSYS_PAIR_COULOMB) /* mostly positive: 20% negative charges */
            CHECK(psys_system_set_charge(sys, i, urand(0.2, 1.0) * (urand(0, 1) < 0.8 ? 1 : -1)) == PSYS_OK);
    }
    psys_pair_def def = psys_pair_def_default();
    def.law = (psys_pair_law)law;
    def.softening = 1e-3;
    def.method = method;
    def.theta = theta;
    add_pair(sys, &def);
    return sys;
}

/* Relative RMS force error sqrt(Σ|f_bh - f|²/Σ|f|²) and relative energy
 * error of Barnes–Hut against direct, for increasing theta: it grows with
 * theta, vanishes (to rounding) at 0 and stays below the documented bounds
 * at 0.5 (docs/scene-format.md, "Pair forces"). */
static void barnes_hut_error(int dim)
{
    static const double thetas[] = {0.0, 0.25, 0.5, 0.75, 1.0};
    const size_t n = 600;
    for (int law = PSYS_PAIR_GRAVITY; law <= PSYS_PAIR_COULOMB; law++) {
        psys_system *ref = bh_cloud(dim, n, law, PSYS_PAIR_DIRECT, 0);
        double *f0 = forces_of(ref), u0 = psys_system_potential_energy(ref);
        psys_system_destroy(ref);
        double prev = -1, err[5], uerr[5];
        for (int t = 0; t < 5; t++) {
            psys_system *sys = bh_cloud(dim, n, law, PSYS_PAIR_BARNES_HUT, thetas[t]);
            double *f = forces_of(sys), fe = 0, fn = 0;
            for (size_t i = 0; i < n * dim; i++) {
                fe += (f[i] - f0[i]) * (f[i] - f0[i]);
                fn += f0[i] * f0[i];
            }
            err[t] = sqrt(fe / fn);
            uerr[t] = fabs(psys_system_potential_energy(sys) - u0) / fabs(u0);
            fprintf(stderr, "barnes-hut %dD %s theta %.2f: force error %.3g, energy error %.3g\n", dim,
                    psys_pair_law_name((psys_pair_law)law), thetas[t], err[t], uerr[t]);
            CHECK(err[t] > prev); /* strictly increases with theta */
            prev = err[t];
            free(f);
            psys_system_destroy(sys);
        }
        free(f0);
        CHECK(err[0] < 1e-13); /* theta 0: the exact sum, in another order */
        CHECK(uerr[0] < 1e-13);
        CHECK(err[2] < 5e-3);  /* theta 0.5 */
        CHECK(uerr[2] < 5e-3);
        CHECK(err[4] < 0.1);
    }
}

static void barnes_hut_error_2d(void) { barnes_hut_error(2); }
static void barnes_hut_error_3d(void) { barnes_hut_error(3); }

/* ------------------------------------------------------------------ orbits with rk45 */

/* Integrate with rk45 to exactly t_end. */
static void run_rk45(psys_system *sys, double t_end, double tol)
{
    psys_error err;
    psys_solver *sol = psys_system_solver_create(sys, "rk45", &err);
    CHECK(sol != NULL);
    if (!sol)
        return;
    psys_solver_set_tolerance(sol, tol);
    psys_solver_set_next_step(sol, 1e-3);
    int guard = 0;
    while (t_end - psys_system_time(sys) > 1e-13 * t_end && guard++ < 1000000) {
        double h;
        psys_status st = psys_system_advance(sys, sol, t_end - psys_system_time(sys), &h);
        CHECK(st == PSYS_OK);
        if (st != PSYS_OK)
            break;
    }
    psys_solver_destroy(sol);
}

/* Two bodies on an eccentric (e = 0.6) Kepler orbit return to their start after one period. */
static void kepler_orbit_closes(void)
{
    for (int method = PSYS_PAIR_DIRECT; method <= PSYS_PAIR_BARNES_HUT; method += 2) {
        const double G = 1, m1 = 1.0, m2 = 0.25, M = m1 + m2, a = 1.0, e = 0.6;
        double rp = a * (1 - e), vp = sqrt(G * M * (1 + e) / (a * (1 - e)));
        double T = 2 * PI * sqrt(a * a * a / (G * M));
        psys_system *sys = make_system(2);
        double x1[2] = {-m2 / M * rp, 0}, v1[2] = {0, -m2 / M * vp};
        double x2[2] = {m1 / M * rp, 0}, v2[2] = {0, m1 / M * vp};
        add_particle(sys, x1, v1, m1);
        add_particle(sys, x2, v2, m2);
        psys_pair_def def = psys_pair_def_default();
        def.G = G;
        def.method = (psys_pair_method)method;
        add_pair(sys, &def);
        double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        CHECK_NEAR(e0, -G * m1 * m2 / (2 * a), 1e-12);
        run_rk45(sys, T, 1e-10);
        const double *x = psys_system_positions(sys);
        double err = hypot(x[0] - x1[0], x[1] - x1[1]) + hypot(x[2] - x2[0], x[3] - x2[1]);
        fprintf(stderr, "kepler (%s): position error after one period %.3g (relative to a)\n",
                psys_pair_method_name((psys_pair_method)method), err / a);
        CHECK(err / a < 1e-6); /* documented tolerance; measured about 1e-8 */
        double e1 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        CHECK_NEAR(e1, e0, 1e-8 * fabs(e0));
        /* halfway, the bodies are at apoapsis: separation a(1 + e) */
        psys_system_destroy(sys);
    }
}

/* Chenciner–Montgomery figure-eight: three equal masses return to their start after T. */
static void figure_eight_returns(void)
{
    const double T = 6.32591398;
    double x[3][2] = {{0.97000436, -0.24308753}, {-0.97000436, 0.24308753}, {0, 0}};
    double v3[2] = {-0.93240737, -0.86473146};
    double v[3][2] = {{-v3[0] / 2, -v3[1] / 2}, {-v3[0] / 2, -v3[1] / 2}, {v3[0], v3[1]}};
    psys_system *sys = make_system(2);
    for (int i = 0; i < 3; i++)
        add_particle(sys, x[i], v[i], 1.0);
    psys_pair_def def = psys_pair_def_default();
    add_pair(sys, &def);
    double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
    run_rk45(sys, T, 1e-11);
    const double *y = psys_system_positions(sys), *vy = psys_system_velocities(sys);
    double err = 0, verr = 0;
    for (int i = 0; i < 3; i++) {
        err = fmax(err, hypot(y[2 * i] - x[i][0], y[2 * i + 1] - x[i][1]));
        verr = fmax(verr, hypot(vy[2 * i] - v[i][0], vy[2 * i + 1] - v[i][1]));
    }
    fprintf(stderr, "figure-eight: return error %.3g (position), %.3g (velocity)\n", err, verr);
    CHECK(err < 1e-6); /* documented tolerance: the initial conditions have 8 digits */
    CHECK(verr < 1e-6);
    /* and it really moved: a quarter period in, body 3 is far from the origin */
    double e1 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
    CHECK_NEAR(e1, e0, 1e-9 * fabs(e0));
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ Jacobians */

static void jacobians_match_differences(void)
{
    static double kuser = 2.5;
    for (int dim = 2; dim <= 3; dim++)
        for (int law = 0; law <= PSYS_PAIR_USER; law++) {
            urand_seed(31 + (uint64_t)law);
            psys_system *sys = random_cloud(dim, 6, 1.0, true, law == PSYS_PAIR_COULOMB);
            psys_pair_def def = psys_pair_def_default();
            def.law = (psys_pair_law)law;
            def.softening = 0.1;
            def.sigma = 0.4;
            def.cutoff = 1.2;
            def.radius = 0.9;
            def.fn = spring_law;
            def.ctx = &kuser;
            add_pair(sys, &def);
            size_t nd = 6 * (size_t)dim;
            double *jx = calloc(nd * nd, sizeof(double)), *jv = calloc(nd * nd, sizeof(double));
            double *fx = calloc(nd * nd, sizeof(double)), *fv = calloc(nd * nd, sizeof(double));
            CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
            CHECK(psys_system_fd_jacobian(sys, 1e-6, fx, fv) == PSYS_OK);
            double worst = 0, scale = 0;
            for (size_t i = 0; i < nd * nd; i++) {
                worst = fmax(worst, fabs(jx[i] - fx[i]));
                scale = fmax(scale, fabs(fx[i]));
                CHECK(jv[i] == 0);
            }
            CHECK(scale > 0);
            if (!(worst <= 1e-5 * scale))
                fprintf(stderr, "jacobian %dD law %d: worst %.3g, scale %.3g\n", dim, law, worst, scale);
            CHECK(worst <= 1e-5 * scale);
            free(jx);
            free(jv);
            free(fx);
            free(fv);
            psys_system_destroy(sys);
        }
}

/* Particles added after the force: storage grows at the next evaluation. */
static void particles_added_later(void)
{
    psys_system *a = make_system(3), *b = make_system(3);
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.sigma = 0.1;
    add_pair(a, &def);
    urand_seed(5);
    for (int i = 0; i < 400; i++) {
        double x[3] = {urand(0, 1), urand(0, 1), urand(0, 1)};
        add_particle(a, x, NULL, 1);
        add_particle(b, x, NULL, 1);
        if (i == 1 || i == 100)
            free(forces_of(a));
    }
    def.method = PSYS_PAIR_DIRECT;
    add_pair(b, &def);
    double *fa = forces_of(a), *fb = forces_of(b);
    CHECK(memcmp(fa, fb, 400 * 3 * sizeof(double)) == 0);
    free(fa);
    free(fb);
    psys_system_destroy(a);
    psys_system_destroy(b);
}

/* ------------------------------------------------------------------ scenes */

static psys_scene *load(const char *text, psys_error *err)
{
    psys_scene *s = psys_scene_load_string(text, strlen(text), err);
    if (!s)
        fprintf(stderr, "load: %s\n", err->message);
    return s;
}

static const char *scene_box =
    "{\"psys\": 1, \"dim\": 3, \"integrator\": \"verlet\", \"dt\": 0.005, \"steps\": 10,"
    " \"box\": {\"lo\": [0, 0, -1], \"hi\": [3.3, 3.1, 2.2], \"periodic\": [true, true, false]},"
    " \"particles\": ["
    "  {\"id\": \"a\", \"x\": [0.1, 0.2, 0.3], \"v\": [1, 0, 0], \"charge\": 0.5},"
    "  {\"x\": [3.2, 0.3, 0.2], \"charge\": -0.1},"
    "  {\"x\": [1.1, 1.0, 0.7], \"mass\": 2},"
    "  {\"x\": [1.6, 1.3, 0.9], \"v\": [0, 0.3, 0], \"charge\": -0}],"
    " \"forces\": ["
    "  {\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 0.3, \"sigma\": 0.33, \"cutoff\": 1.1,"
    "   \"shift\": true, \"skin\": 0.3},"
    "  {\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 0.1, \"sigma\": 0.2, \"method\": \"direct\"},"
    "  {\"type\": \"pair\", \"law\": \"soft-repulsion\", \"k\": 10, \"radius\": 0.7, \"method\": \"grid\"}]}";

static const char *scene_open =
    "{\"psys\": 1, \"dim\": 2, \"integrator\": \"rk45\", \"duration\": 1,"
    " \"particles\": [{\"x\": [0, 0], \"charge\": 1e-3}, {\"x\": [1, 0.1], \"v\": [0, 1]},"
    "  {\"x\": [0.3, -0.7], \"charge\": -2.5}],"
    " \"forces\": ["
    "  {\"type\": \"pair\", \"law\": \"gravity\", \"G\": 0.1, \"softening\": 0.01},"
    "  {\"type\": \"pair\", \"law\": \"gravity\", \"method\": \"barnes-hut\", \"theta\": 0.3},"
    "  {\"type\": \"pair\", \"law\": \"coulomb\", \"k\": 2, \"method\": \"barnes-hut\"},"
    "  {\"type\": \"pair\", \"law\": \"coulomb\"}]}";

static void round_trip(const char *text, size_t nforces)
{
    psys_error err;
    psys_scene *s1 = load(text, &err);
    CHECK(s1 != NULL);
    if (!s1)
        return;
    char *t1 = psys_scene_to_string(s1, NULL, &err);
    CHECK(t1 != NULL);
    psys_scene *s2 = t1 ? load(t1, &err) : NULL;
    CHECK(s2 != NULL);
    if (s2) {
        char *t2 = psys_scene_to_string(s2, NULL, &err);
        CHECK(t2 && strcmp(t1, t2) == 0);
        free(t2);
        psys_system *a = psys_scene_system(s1), *b = psys_scene_system(s2);
        CHECK(psys_system_force_count(a) == nforces && psys_system_force_count(b) == nforces);
        for (size_t i = 0; i < nforces; i++) {
            psys_pair_def da, db;
            CHECK(psys_system_pair(a, i, &da) == PSYS_OK && psys_system_pair(b, i, &db) == PSYS_OK);
            CHECK(da.law == db.law && da.method == db.method && da.cutoff == db.cutoff && da.skin == db.skin
                  && da.theta == db.theta && da.shift == db.shift && da.G == db.G && da.k == db.k);
        }
        for (size_t i = 0; i < psys_system_count(a); i++) {
            CHECK(psys_system_charge(a, i) == psys_system_charge(b, i));
            CHECK(signbit(psys_system_charge(a, i)) == signbit(psys_system_charge(b, i)));
        }
        double lo1[3], hi1[3], lo2[3], hi2[3];
        bool p1[3], p2[3];
        CHECK(psys_system_box(a, lo1, hi1, p1) == psys_system_box(b, lo2, hi2, p2));
        double *fa = forces_of(a), *fb = forces_of(b);
        size_t nd = psys_system_count(a) * (size_t)psys_system_dim(a);
        CHECK(memcmp(fa, fb, nd * sizeof(double)) == 0);
        CHECK(psys_system_potential_energy(a) == psys_system_potential_energy(b));
        free(fa);
        free(fb);
        psys_scene_destroy(s2);
    }
    free(t1);
    psys_scene_destroy(s1);
}

static void scene_round_trip(void)
{
    round_trip(scene_box, 3);
    round_trip(scene_open, 4);
    /* resolved values */
    psys_error err;
    psys_scene *s = load(scene_box, &err);
    if (!s)
        return;
    psys_system *sys = psys_scene_system(s);
    psys_pair_def d;
    CHECK(psys_system_pair(sys, 0, &d) == PSYS_OK);
    CHECK(d.law == PSYS_PAIR_LENNARD_JONES && d.method == PSYS_PAIR_GRID && d.skin == 0.3 && d.shift);
    CHECK(psys_system_pair(sys, 1, &d) == PSYS_OK);
    CHECK(d.cutoff == 2.5 * 0.2 && d.method == PSYS_PAIR_DIRECT && !d.shift);
    CHECK(psys_system_pair(sys, 2, &d) == PSYS_OK);
    CHECK(d.skin == 0.1 * 0.7 && d.cutoff == 0.7);
    CHECK(psys_system_charge(sys, 0) == 0.5 && psys_system_charge(sys, 2) == 0);
    double lo[3], hi[3];
    bool per[3];
    CHECK(psys_system_box(sys, lo, hi, per));
    CHECK(lo[2] == -1 && hi[0] == 3.3 && per[0] && per[1] && !per[2]);
    /* a run wraps particle 0 (moving -x... +x from 0.1) and particle 1 stays in the box */
    psys_run *run = psys_run_create(s, &err);
    CHECK(run != NULL);
    while (run && !psys_run_done(run))
        CHECK(psys_run_step(run, &err) == PSYS_OK);
    const double *x = psys_system_positions(sys);
    for (size_t i = 0; i < 4; i++)
        for (int k = 0; k < 2; k++)
            CHECK(x[i * 3 + k] >= lo[k] && x[i * 3 + k] < hi[k]);
    psys_run_destroy(run);
    psys_scene_destroy(s);
    s = load(scene_open, &err);
    if (!s)
        return;
    CHECK(psys_system_pair(psys_scene_system(s), 0, &d) == PSYS_OK);
    CHECK(d.method == PSYS_PAIR_DIRECT && d.softening == 0.01 && d.G == 0.1);
    CHECK(psys_system_pair(psys_scene_system(s), 2, &d) == PSYS_OK);
    CHECK(d.method == PSYS_PAIR_BARNES_HUT && d.theta == 0.5 && d.k == 2);
    CHECK(psys_system_pair(psys_scene_system(s), 3, &d) == PSYS_OK);
    CHECK(d.k == 1 && d.method == PSYS_PAIR_DIRECT);
    psys_scene_destroy(s);
}

/* docs/semantics.md#resuming: A + B steps in one run equal A steps, a checkpoint, and B
 * resumed steps, bit for bit. Pair forces do not depend on when neighbour
 * lists were built, and positions wrapped into the box are saved exactly. */
static void checkpoint_resume_bit_exact(void)
{
    char text[20000];
    size_t len = (size_t)snprintf(text, sizeof text,
                                  "{\"psys\": 1, \"dim\": 3, \"integrator\": \"verlet\", \"dt\": 0.01, \"steps\": 30,"
                                  " \"box\": {\"lo\": [0, 0, 0], \"hi\": [6, 6, 6]}, \"particles\": [");
    urand_seed(2024);
    for (int i = 0; i < 125; i++)
        len += (size_t)snprintf(text + len, sizeof text - len, "%s{\"x\": [%.17g, %.17g, %.17g], \"v\": [%.17g, %.17g, %.17g]}",
                                i ? ", " : "", 1.2 * (i % 5) + 0.1, 1.2 * (i / 5 % 5) + 0.1, 1.2 * (i / 25) + 0.1,
                                urand(-2, 2), urand(-2, 2), urand(-2, 2));
    snprintf(text + len, sizeof text - len,
             "], \"forces\": [{\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 0.6,"
             " \"cutoff\": 1.6, \"skin\": 0.2}]}");
    psys_error err;
    psys_scene *full = load(text, &err), *half = load(text, &err);
    CHECK(full && half);
    if (!full || !half)
        return;
    psys_run *r = psys_run_create(full, &err);
    while (!psys_run_done(r))
        CHECK(psys_run_step(r, &err) == PSYS_OK);
    psys_run_destroy(r);
    psys_scene_settings(half)->steps = 13;
    r = psys_run_create(half, &err);
    while (!psys_run_done(r))
        CHECK(psys_run_step(r, &err) == PSYS_OK);
    psys_resume_state rs = psys_run_resume_state(r);
    psys_run_destroy(r);
    char *ck = psys_scene_to_string(half, &rs, &err);
    CHECK(ck != NULL);
    psys_scene *resumed = ck ? load(ck, &err) : NULL;
    CHECK(resumed != NULL);
    if (resumed) {
        psys_scene_settings(resumed)->steps = 17;
        r = psys_run_create(resumed, &err);
        while (!psys_run_done(r))
            CHECK(psys_run_step(r, &err) == PSYS_OK);
        psys_run_destroy(r);
        psys_system *a = psys_scene_system(full), *b = psys_scene_system(resumed);
        CHECK(psys_system_time(a) == psys_system_time(b));
        CHECK(memcmp(psys_system_positions(a), psys_system_positions(b), 125 * 3 * sizeof(double)) == 0);
        CHECK(memcmp(psys_system_velocities(a), psys_system_velocities(b), 125 * 3 * sizeof(double)) == 0);
        const double *x = psys_system_positions(a);
        for (int i = 0; i < 125 * 3; i++)
            CHECK(x[i] >= 0 && x[i] < 6);
        psys_scene_destroy(resumed);
    }
    free(ck);
    psys_scene_destroy(full);
    psys_scene_destroy(half);
}

static void scene_bad_input(void)
{
#define P2 "{\"psys\": 1, \"dim\": 2, \"particles\": [{\"x\": [0, 0]}, {\"x\": [1, 0]}], "
#define F(body) P2 "\"forces\": [{\"type\": \"gravity\"}, {\"type\": \"pair\", " body "}]}"
    expect_error(F("\"G\": 1"), "forces[1].law: required key missing");
    expect_error(F("\"law\": 3"), "forces[1].law: must be a string (got 3)");
    expect_error(F("\"law\": \"yukawa\""),
                 "forces[1].law: unknown pair law (known: gravity, coulomb, lennard-jones, soft-repulsion) "
                 "(got \"yukawa\")");
    expect_error(F("\"law\": \"gravity\", \"method\": \"tree\""),
                 "forces[1].method: unknown method (known: direct, grid, barnes-hut) (got \"tree\")");
    expect_error(F("\"law\": \"gravity\", \"method\": 1"), "forces[1].method: must be a string (got 1)");
    expect_error(F("\"law\": \"gravity\", \"method\": \"grid\""),
                 "forces[1].method: grid needs a law with a cutoff (lennard-jones, soft-repulsion) (got \"grid\")");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1, \"method\": \"barnes-hut\""),
                 "forces[1].method: barnes-hut is only for the long-range laws gravity and coulomb "
                 "(got \"barnes-hut\")");
    expect_error(F("\"law\": \"gravity\", \"skin\": 0.1"), "forces[1].skin: only used by method \"grid\" (got 0.1)");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1, \"theta\": 0.5"),
                 "forces[1].theta: only used by method \"barnes-hut\" (got 0.5)");
    expect_error(F("\"law\": \"gravity\", \"G\": 1, \"epsilon\": 1"), "forces[1].epsilon: unknown key");
    expect_error(F("\"law\": \"coulomb\", \"G\": 1"), "forces[1].G: unknown key");
    expect_error(F("\"law\": \"gravity\", \"G\": -1"), "forces[1].G: must be >= 0 (got -1)");
    expect_error(F("\"law\": \"gravity\", \"softening\": -0.1"), "forces[1].softening: must be >= 0 (got -0.1)");
    expect_error(F("\"law\": \"gravity\", \"G\": \"big\""), "forces[1].G: must be a number (got \"big\")");
    expect_error(F("\"law\": \"coulomb\", \"k\": -2"), "forces[1].k: must be >= 0 (got -2)");
    expect_error(F("\"law\": \"lennard-jones\", \"sigma\": 1"), "forces[1].epsilon: required key missing");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1"), "forces[1].sigma: required key missing");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 0"), "forces[1].sigma: must be > 0 (got 0)");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": -1, \"sigma\": 1"),
                 "forces[1].epsilon: must be >= 0 (got -1)");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1, \"cutoff\": 0"),
                 "forces[1].cutoff: must be > 0 (got 0)");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1, \"shift\": 1"),
                 "forces[1].shift: must be true or false (got 1)");
    expect_error(F("\"law\": \"lennard-jones\", \"epsilon\": 1, \"sigma\": 1, \"skin\": -1"),
                 "forces[1].skin: must be >= 0 (got -1)");
    expect_error(F("\"law\": \"gravity\", \"method\": \"barnes-hut\", \"theta\": -0.5"),
                 "forces[1].theta: must be >= 0 (got -0.5)");
    expect_error(F("\"law\": \"soft-repulsion\", \"k\": 1"), "forces[1].radius: required key missing");
    expect_error(F("\"law\": \"soft-repulsion\", \"radius\": 1"), "forces[1].k: required key missing");
    expect_error(F("\"law\": \"soft-repulsion\", \"k\": 1, \"radius\": 1, \"cutoff\": 2"),
                 "forces[1].cutoff: unknown key");
#undef F
    /* charges */
    expect_error("{\"psys\": 1, \"dim\": 2, \"particles\": [{\"x\": [0, 0], \"charge\": \"+\"}]}",
                 "particles[0].charge: must be a number (got \"+\")");
    expect_error("{\"psys\": 1, \"dim\": 2, \"particles\": [{\"x\": [0, 0], \"charge\": 1e999}]}",
                 "particles[0].charge: must be finite (got inf)");
    /* box */
#define B(body) "{\"psys\": 1, \"dim\": 2, \"box\": " body "}"
    expect_error(B("[0, 1]"), "box: must be an object {\"lo\", \"hi\", \"periodic\"} (got [0,1])");
    expect_error(B("{\"lo\": [0, 0]}"), "box.hi: required key missing");
    expect_error(B("{\"hi\": [1, 1]}"), "box.lo: required key missing");
    expect_error(B("{\"lo\": [0, 0, 0], \"hi\": [1, 1]}"),
                 "box.lo: must be an array of 2 numbers (dim is 2) (got [0,0,0])");
    expect_error(B("{\"lo\": [0, 0], \"hi\": [1, 0]}"), "box.hi[1]: must be greater than box.lo[1] (0) (got 0)");
    expect_error(B("{\"lo\": [0, 0], \"hi\": [1, 1], \"periodic\": true}"),
                 "box.periodic: must be an array of 2 true/false values (dim is 2) (got true)");
    expect_error(B("{\"lo\": [0, 0], \"hi\": [1, 1], \"periodic\": [true, 1]}"),
                 "box.periodic[1]: must be true or false (got 1)");
    expect_error(B("{\"lo\": [0, 0], \"hi\": [1, 1], \"wrap\": true}"), "box.wrap: unknown key");
#undef B
#define PB(periodic, force)                                                                                  \
    "{\"psys\": 1, \"dim\": 2, \"box\": {\"lo\": [0, 0], \"hi\": [2, 1], \"periodic\": " periodic "}, "     \
    "\"forces\": [" force "]}"
    expect_error(PB("[true, true]", "{\"type\": \"pair\", \"law\": \"gravity\"}"),
                 "forces[0].law: gravity has no cutoff, so it cannot be used with a periodic box (no Ewald sums) "
                 "(got \"gravity\")");
    expect_error(PB("[false, true]", "{\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 1, "
                                     "\"sigma\": 0.1, \"cutoff\": 0.5}"),
                 "forces[0].cutoff: must be less than half the periodic box (box length 1 on axis 1) (got 0.5)");
    expect_error(PB("[true, false]", "{\"type\": \"pair\", \"law\": \"soft-repulsion\", \"k\": 1, \"radius\": 1.5}"),
                 "forces[0].radius: must be less than half the periodic box (box length 2 on axis 0) (got 1.5)");
    /* a free axis has no limit; the default periodic is all true */
    psys_error err;
    const char *ok = PB("[true, false]", "{\"type\": \"pair\", \"law\": \"lennard-jones\", \"epsilon\": 1, "
                                         "\"sigma\": 0.1, \"cutoff\": 0.9}");
    psys_scene *s = load(ok, &err);
    CHECK(s != NULL);
    psys_scene_destroy(s);
    expect_error("{\"psys\": 1, \"dim\": 2, \"box\": {\"lo\": [0, 0], \"hi\": [2, 1]}, \"forces\": [{\"type\": \"pair\","
                 " \"law\": \"coulomb\"}]}",
                 "forces[0].law: coulomb has no cutoff, so it cannot be used with a periodic box (no Ewald sums) "
                 "(got \"coulomb\")");
#undef PB
#undef P2
}

static const check_case cases[] = {
    {"gravity_hand_values", gravity_hand_values},
    {"coulomb_hand_values", coulomb_hand_values},
    {"lennard_jones_hand_values", lennard_jones_hand_values},
    {"soft_repulsion_hand_values", soft_repulsion_hand_values},
    {"user_law_hand_values", user_law_hand_values},
    {"user_law_grid_equals_direct", user_law_grid_equals_direct},
    {"newton_third_law", newton_third_law},
    {"lj_cluster_energy", lj_cluster_energy},
    {"sort_lists", sort_lists},
    {"grid_equals_direct_2d", grid_equals_direct_2d},
    {"grid_equals_direct_3d", grid_equals_direct_3d},
    {"grid_equals_direct_periodic_2d", grid_equals_direct_periodic_2d},
    {"grid_equals_direct_periodic_3d", grid_equals_direct_periodic_3d},
    {"grid_equals_direct_dense", grid_equals_direct_dense},
    {"grid_equals_direct_lattice", grid_equals_direct_lattice},
    {"grid_lists_keep_radius", grid_lists_keep_radius},
    {"grid_rebuild_criterion", grid_rebuild_criterion},
    {"grid_rebuild_criterion_all_moved", grid_rebuild_criterion_all_moved},
    {"grid_cache_matches_direct", grid_cache_matches_direct},
    {"grid_partial_matches_direct", grid_partial_matches_direct},
    {"grid_partial_keeps_unchanged_rows", grid_partial_keeps_unchanged_rows},
    {"grid_partial_sparse_groups", grid_partial_sparse_groups},
    {"grid_groups_any_numbering", grid_groups_any_numbering},
    {"cutoff_boundary_groups", cutoff_boundary_groups},
    {"minimum_image", minimum_image},
    {"minimum_image_far", minimum_image_far},
    {"minimum_image_far_groups", minimum_image_far_groups},
    {"wrapping", wrapping},
    {"box_validation", box_validation},
    {"thread_determinism_grid", thread_determinism_grid},
    {"thread_determinism_direct_bh", thread_determinism_direct_bh},
    {"barnes_hut_error_2d", barnes_hut_error_2d},
    {"barnes_hut_error_3d", barnes_hut_error_3d},
    {"kepler_orbit_closes", kepler_orbit_closes},
    {"figure_eight_returns", figure_eight_returns},
    {"jacobians_match_differences", jacobians_match_differences},
    {"particles_added_later", particles_added_later},
    {"scene_round_trip", scene_round_trip},
    {"checkpoint_resume_bit_exact", checkpoint_resume_bit_exact},
    {"scene_bad_input", scene_bad_input},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
