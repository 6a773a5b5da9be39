/* Structures (chain, cloth, beam, block, wheel) and muscle springs: particle
 * and spring counts against closed forms, ids and indexing, exact positions,
 * pins, springs at rest, physics (a hanging cloth settles, a free block's
 * centre of mass falls as g t²/2, a spinning wheel keeps its shape), muscle
 * rest lengths and forces against eq. 1 with r(t), scene round trips, and
 * every bad-input class with its exact message. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

#define TWO_PI 6.28318530717958647692

static psys_scene *load(const char *text)
{
    psys_error err;
    psys_scene *sc = psys_scene_load_string(text, strlen(text), &err);
    if (!sc)
        fprintf(stderr, "load failed: %s\n", err.message);
    CHECK(sc != NULL);
    return sc;
}

static size_t find(const psys_system *sys, const char *id)
{
    size_t i = (size_t)-1;
    psys_status st = psys_system_find(sys, id, &i);
    if (st != PSYS_OK)
        fprintf(stderr, "no particle \"%s\"\n", id);
    CHECK(st == PSYS_OK);
    return i;
}

/* Every spring starts at rest: |x_a - x_b| == rest exactly, energy 0. */
static void check_at_rest(const psys_system *sys)
{
    int d = psys_system_dim(sys);
    const double *x = psys_system_positions(sys);
    size_t bad = 0;
    for (size_t k = 0; k < psys_system_spring_count(sys); k++) {
        size_t a, b;
        double rest, l2 = 0;
        psys_system_spring(sys, k, &a, &b, NULL, NULL, &rest);
        for (int c = 0; c < d; c++)
            l2 += (x[a * d + c] - x[b * d + c]) * (x[a * d + c] - x[b * d + c]);
        if (sqrt(l2) != rest || rest <= 0)
            bad++;
    }
    CHECK(bad == 0);
    CHECK(psys_system_potential_energy(sys) == 0.0);
}

/* True if the spring set holds a spring between particles p and q. */
static bool has_spring(const psys_system *sys, size_t p, size_t q)
{
    for (size_t k = 0; k < psys_system_spring_count(sys); k++) {
        size_t a, b;
        psys_system_spring(sys, k, &a, &b, NULL, NULL, NULL);
        if ((a == p && b == q) || (a == q && b == p))
            return true;
    }
    return false;
}

/* No pair of particles is joined by two springs. */
static bool no_duplicate_springs(const psys_system *sys)
{
    size_t n = psys_system_spring_count(sys);
    for (size_t k = 0; k < n; k++) {
        size_t a, b;
        psys_system_spring(sys, k, &a, &b, NULL, NULL, NULL);
        for (size_t m = k + 1; m < n; m++) {
            size_t c, e;
            psys_system_spring(sys, m, &c, &e, NULL, NULL, NULL);
            if ((a == c && b == e) || (a == e && b == c))
                return false;
        }
    }
    return true;
}

/* ------------------------------------------------------------------ */

static void chain_counts_positions(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys = make_system(dim);
        double x0[3] = {9, 9, 9};
        CHECK(psys_system_add_particle(sys, x0, NULL, 1, "before", NULL) == PSYS_OK);
        psys_chain_def def = psys_chain_def_default();
        size_t pin[] = {0, 6};
        def.id = "rope";
        def.from[0] = 0.1, def.from[1] = -0.3, def.from[2] = 0.7;
        def.to[0] = 1.3, def.to[1] = 0.9, def.to[2] = -0.2;
        def.count = 7;
        def.mass = 0.25;
        def.ks = 40;
        def.kd = 0.5;
        def.pin = pin;
        def.pin_count = 2;
        size_t first = 0;
        CHECK(psys_system_add_chain(sys, &def, &first) == PSYS_OK);
        CHECK(first == 1);
        CHECK(psys_system_count(sys) == 1 + 7);
        CHECK(psys_system_spring_count(sys) == 6);
        const double *x = psys_system_positions(sys);
        for (size_t i = 0; i < 7; i++) {
            char id[32];
            snprintf(id, sizeof id, "rope[%zu]", i);
            CHECK(find(sys, id) == first + i);
            double t = (double)i / 6.0;
            for (int c = 0; c < dim; c++)
                CHECK(x[(first + i) * dim + c] == (1.0 - t) * def.from[c] + t * def.to[c]);
            CHECK(psys_system_masses(sys)[first + i] == 0.25);
            CHECK(psys_system_is_fixed(sys, first + i) == (i == 0 || i == 6));
        }
        for (int c = 0; c < dim; c++) { /* both ends exact */
            CHECK(x[first * dim + c] == def.from[c]);
            CHECK(x[(first + 6) * dim + c] == def.to[c]);
        }
        for (size_t k = 0; k < 6; k++) {
            size_t a, b;
            double ks, kd;
            psys_system_spring(sys, k, &a, &b, &ks, &kd, NULL);
            CHECK(a == first + k && b == first + k + 1 && ks == 40 && kd == 0.5);
            CHECK(!psys_system_spring_muscle(sys, k, NULL, NULL, NULL));
        }
        check_at_rest(sys);
        psys_system_destroy(sys);
    }
}

static void chain_muscle_wave(void)
{
    psys_system *sys = make_system(2);
    psys_chain_def def = psys_chain_def_default();
    def.count = 5;
    def.ks = 10;
    def.muscle_amplitude = 0.2;
    def.muscle_omega = 3;
    def.muscle_phase = 0.1;
    def.muscle_phase_step = 0.5;
    CHECK(psys_system_add_chain(sys, &def, NULL) == PSYS_OK);
    CHECK(psys_system_particle_id(sys, 0) == NULL); /* no id: no particle ids */
    for (size_t s = 0; s < 4; s++) {
        double a, w, p;
        CHECK(psys_system_spring_muscle(sys, s, &a, &w, &p));
        CHECK(a == 0.2 && w == 3 && p == 0.1 + (double)s * 0.5);
    }
    psys_system_destroy(sys);
}

/* Counts of a cloth: structural 2nxny - nx - ny, shear 2(nx-1)(ny-1), bend (nx-2)ny + nx(ny-2). */
static size_t cloth_springs(size_t nx, size_t ny, bool shear, bool bend)
{
    size_t n = 2 * nx * ny - nx - ny;
    if (shear)
        n += 2 * (nx - 1) * (ny - 1);
    if (bend)
        n += (nx - 2) * ny + nx * (ny - 2);
    return n;
}

static void cloth_counts(void)
{
    static const size_t sizes[][2] = {{2, 2}, {2, 5}, {3, 3}, {7, 4}, {20, 13}};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++)
        for (int flags = 0; flags < 4; flags++) {
            bool shear = flags & 1, bend = flags & 2;
            psys_system *sys = make_system(3);
            psys_cloth_def def = psys_cloth_def_default();
            def.id = "sheet";
            def.nx = sizes[z][0];
            def.ny = sizes[z][1];
            def.spacing = 0.05;
            def.shear = shear;
            def.bend = bend;
            size_t first = 99;
            CHECK(psys_system_add_cloth(sys, &def, &first) == PSYS_OK);
            CHECK(first == 0);
            CHECK(psys_system_count(sys) == def.nx * def.ny);
            CHECK(psys_system_spring_count(sys) == cloth_springs(def.nx, def.ny, shear, bend));
            CHECK(no_duplicate_springs(sys));
            check_at_rest(sys);
            psys_system_destroy(sys);
        }
}

static void cloth_ids_positions_pins(void)
{
    psys_system *sys = make_system(3);
    double x0[3] = {0, 0, 0};
    CHECK(psys_system_add_particle(sys, x0, NULL, 1, "p0", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, x0, NULL, 1, NULL, NULL) == PSYS_OK);
    psys_cloth_def def = psys_cloth_def_default();
    size_t pin[] = {0, 0, 5, 0, 2, 3};
    def.id = "sheet";
    def.origin[0] = 1, def.origin[1] = 2, def.origin[2] = 3;
    def.nx = 6;
    def.ny = 4;
    def.spacing = 0.3;
    def.mass = 0.01;
    def.ks = 500;
    def.kd = 0.2;
    def.shear_ks = 250;
    def.bend_ks = 50;
    def.bend_kd = 0.01;
    /* a tilted, non-orthogonal frame: x = origin + (i h) a1 + (j h) a2 */
    double a1[3] = {0.6, 0, 0.8}, a2[3] = {0.1, -1, 0.3};
    memcpy(def.axes[0], a1, sizeof a1);
    memcpy(def.axes[1], a2, sizeof a2);
    def.pin = pin;
    def.pin_count = 3;
    size_t first = 0;
    CHECK(psys_system_add_cloth(sys, &def, &first) == PSYS_OK);
    CHECK(first == 2);
    const double *x = psys_system_positions(sys);
    for (size_t j = 0; j < 4; j++)
        for (size_t i = 0; i < 6; i++) {
            char id[32];
            snprintf(id, sizeof id, "sheet[%zu,%zu]", i, j);
            size_t p = find(sys, id);
            CHECK(p == first + i + 6 * j);
            for (int c = 0; c < 3; c++) {
                double want = def.origin[c] + ((double)i * 0.3) * a1[c] + ((double)j * 0.3) * a2[c];
                CHECK(x[p * 3 + c] == want);
            }
            bool pinned = (i == 0 && j == 0) || (i == 5 && j == 0) || (i == 2 && j == 3);
            CHECK(psys_system_is_fixed(sys, p) == pinned);
        }
    CHECK(psys_system_find(sys, "sheet[3,4]", NULL) != PSYS_OK); /* outside the grid */
    /* spring order: structural a1, structural a2, shear (both), bend a1, bend a2 */
    size_t nst = 5 * 4 + 6 * 3, nsh = 2 * 5 * 3, nb = 4 * 4 + 6 * 2;
    CHECK(psys_system_spring_count(sys) == nst + nsh + nb);
    for (size_t k = 0; k < psys_system_spring_count(sys); k++) {
        double ks, kd;
        psys_system_spring(sys, k, NULL, NULL, &ks, &kd, NULL);
        if (k < nst)
            CHECK(ks == 500 && kd == 0.2);
        else if (k < nst + nsh)
            CHECK(ks == 250 && kd == 0.2);
        else
            CHECK(ks == 50 && kd == 0.01);
    }
    size_t a, b;
    psys_system_spring(sys, 0, &a, &b, NULL, NULL, NULL);
    CHECK(a == find(sys, "sheet[0,0]") && b == find(sys, "sheet[1,0]"));
    psys_system_spring(sys, nst, &a, &b, NULL, NULL, NULL);
    CHECK(a == find(sys, "sheet[0,0]") && b == find(sys, "sheet[1,1]"));
    CHECK(has_spring(sys, find(sys, "sheet[1,0]"), find(sys, "sheet[0,1]")));
    CHECK(has_spring(sys, find(sys, "sheet[0,0]"), find(sys, "sheet[2,0]")));
    CHECK(has_spring(sys, find(sys, "sheet[5,1]"), find(sys, "sheet[5,3]")));
    CHECK(!has_spring(sys, find(sys, "sheet[0,0]"), find(sys, "sheet[2,2]")));
    check_at_rest(sys);
    psys_system_destroy(sys);

    /* a 2-D cloth (default axes e_x, e_y) */
    sys = make_system(2);
    def = psys_cloth_def_default();
    def.id = "flat";
    def.nx = 3;
    def.ny = 3;
    def.spacing = 0.5;
    CHECK(psys_system_add_cloth(sys, &def, NULL) == PSYS_OK);
    x = psys_system_positions(sys);
    size_t p = find(sys, "flat[2,1]");
    CHECK(p == 2 + 3 * 1 && x[p * 2] == 1.0 && x[p * 2 + 1] == 0.5);
    check_at_rest(sys);
    psys_system_destroy(sys);
}

static void beam_counts(void)
{
    for (size_t nx = 2; nx <= 9; nx += 7)
        for (size_t ny = 2; ny <= 4; ny++) {
            psys_system *sys = make_system(2);
            psys_beam_def def = psys_beam_def_default();
            def.id = "beam";
            def.nx = nx;
            def.ny = ny;
            def.spacing = 0.1;
            CHECK(psys_system_add_beam(sys, &def, NULL) == PSYS_OK);
            CHECK(psys_system_count(sys) == nx * ny);
            CHECK(psys_system_spring_count(sys) == cloth_springs(nx, ny, true, false));
            CHECK(has_spring(sys, find(sys, "beam[1,0]"), find(sys, "beam[0,1]")));
            CHECK(no_duplicate_springs(sys));
            check_at_rest(sys);
            psys_system_destroy(sys);
        }
}

/* A cantilevered beam (left column pinned) under gravity settles with a
 * small sag: the diagonals make it resist shear. The same lattice without
 * diagonals (a cloth with shear and bend off) folds down. */
static double cantilever_tip_drop(bool beam)
{
    psys_system *sys = make_system(2);
    size_t pin[] = {0, 0, 0, 1, 0, 2};
    size_t first = 0;
    if (beam) {
        psys_beam_def def = psys_beam_def_default();
        def.nx = 10;
        def.ny = 3;
        def.spacing = 0.1;
        def.mass = 0.01;
        def.ks = 10000;
        def.kd = 0.5;
        def.pin = pin;
        def.pin_count = 3;
        CHECK(psys_system_add_beam(sys, &def, &first) == PSYS_OK);
    } else {
        psys_cloth_def def = psys_cloth_def_default();
        def.nx = 10;
        def.ny = 3;
        def.spacing = 0.1;
        def.mass = 0.01;
        def.ks = 10000;
        def.kd = 0.5;
        def.shear = def.bend = false;
        def.pin = pin;
        def.pin_count = 3;
        CHECK(psys_system_add_cloth(sys, &def, &first) == PSYS_OK);
    }
    double g[2] = {0, -9.81};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, 0.02) == PSYS_OK);
    psys_solver *s = make_solver("rk4", sys);
    for (int k = 0; k < 4000; k++)
        CHECK(psys_solver_step(s, 5e-4, NULL) == PSYS_OK);
    double drop = -psys_system_positions(sys)[(first + 9) * 2 + 1];
    if (beam)
        CHECK(psys_system_kinetic_energy(sys) < 1e-4);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
    return drop;
}

static void beam_cantilever(void)
{
    double beam = cantilever_tip_drop(true), floppy = cantilever_tip_drop(false);
    fprintf(stderr, "  cantilever tip drop: beam %.4g m, without diagonals %.4g m\n", beam, floppy);
    CHECK(beam > 0 && beam < 0.05);  /* sags a little */
    CHECK(floppy > 0.5);              /* hangs down: tip ~0.9 below */
}

static size_t block_springs(size_t nx, size_t ny, size_t nz)
{
    size_t edges = (nx - 1) * ny * nz + nx * (ny - 1) * nz + nx * ny * (nz - 1);
    size_t faces = 2 * ((nx - 1) * (ny - 1) * nz + (nx - 1) * ny * (nz - 1) + nx * (ny - 1) * (nz - 1));
    size_t body = 4 * (nx - 1) * (ny - 1) * (nz - 1);
    return edges + faces + body;
}

static void block_counts(void)
{
    static const size_t sizes[][3] = {{2, 2, 2}, {3, 2, 2}, {2, 5, 3}, {4, 4, 4}, {6, 3, 5}};
    for (size_t z = 0; z < sizeof sizes / sizeof sizes[0]; z++) {
        psys_system *sys = make_system(3);
        psys_block_def def = psys_block_def_default();
        def.id = "b";
        def.nx = sizes[z][0];
        def.ny = sizes[z][1];
        def.nz = sizes[z][2];
        def.spacing = 0.2;
        def.origin[2] = -1;
        size_t pin[] = {1, 1, 1};
        def.pin = pin;
        def.pin_count = 1;
        CHECK(psys_system_add_block(sys, &def, NULL) == PSYS_OK);
        size_t nx = def.nx, ny = def.ny, nz = def.nz;
        CHECK(psys_system_count(sys) == nx * ny * nz);
        CHECK(psys_system_spring_count(sys) == block_springs(nx, ny, nz));
        CHECK(no_duplicate_springs(sys));
        const double *x = psys_system_positions(sys);
        for (size_t k = 0; k < nz; k++)
            for (size_t j = 0; j < ny; j++)
                for (size_t i = 0; i < nx; i++) {
                    char id[80];
                    snprintf(id, sizeof id, "b[%zu,%zu,%zu]", i, j, k);
                    size_t p = find(sys, id);
                    CHECK(p == i + nx * (j + ny * k));
                    CHECK(x[p * 3] == (double)i * 0.2 && x[p * 3 + 1] == (double)j * 0.2
                          && x[p * 3 + 2] == -1 + (double)k * 0.2);
                    CHECK(psys_system_is_fixed(sys, p) == (i == 1 && j == 1 && k == 1));
                }
        /* the body diagonals of the first cell */
        CHECK(has_spring(sys, find(sys, "b[0,0,0]"), find(sys, "b[1,1,1]")));
        CHECK(has_spring(sys, find(sys, "b[1,0,0]"), find(sys, "b[0,1,1]")));
        CHECK(has_spring(sys, find(sys, "b[0,1,0]"), find(sys, "b[1,0,1]")));
        CHECK(has_spring(sys, find(sys, "b[1,1,0]"), find(sys, "b[0,0,1]")));
        check_at_rest(sys);
        psys_system_destroy(sys);
    }
}

/* A block with no pins under gravity, set spinning and wobbling: the
 * internal springs are busy, but the centre of mass follows x0 + v0 t + g t²/2. */
static void block_free_fall(void)
{
    psys_system *sys = make_system(3);
    psys_block_def def = psys_block_def_default();
    def.nx = 3;
    def.ny = 4;
    def.nz = 2;
    def.spacing = 0.1;
    def.mass = 0.05;
    def.ks = 300;
    def.kd = 0.3;
    def.origin[1] = 10;
    CHECK(psys_system_add_block(sys, &def, NULL) == PSYS_OK);
    size_t n = psys_system_count(sys);
    /* pseudo-random velocities (a fixed LCG) */
    uint64_t seed = 12345;
    double com0[3] = {0, 0, 0}, vcm[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        double v[3];
        for (int c = 0; c < 3; c++) {
            seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
            v[c] = (double)(seed >> 11) / 9007199254740992.0 - 0.5;
        }
        CHECK(psys_system_set_particle(sys, i, NULL, v) == PSYS_OK);
        for (int c = 0; c < 3; c++) {
            com0[c] += psys_system_positions(sys)[i * 3 + c] / (double)n;
            vcm[c] += v[c] / (double)n;
        }
    }
    double g[3] = {0, -9.81, 0};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    psys_solver *s = make_solver("rk4", sys);
    double h = 1e-3, max_err = 0, max_spring = 0;
    for (int k = 1; k <= 1000; k++) {
        CHECK(psys_solver_step(s, h, NULL) == PSYS_OK);
        double t = k * h, com[3] = {0, 0, 0};
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++)
                com[c] += psys_system_positions(sys)[i * 3 + c] / (double)n;
        for (int c = 0; c < 3; c++) {
            double want = com0[c] + vcm[c] * t + 0.5 * g[c] * t * t;
            max_err = fmax(max_err, fabs(com[c] - want));
        }
        double u = psys_system_potential_energy(sys);
        (void)u;
    }
    /* springs did work: the block is deformed (not just translating) */
    const double *x = psys_system_positions(sys);
    for (size_t k = 0; k < psys_system_spring_count(sys); k++) {
        size_t a, b;
        double rest, l2 = 0;
        psys_system_spring(sys, k, &a, &b, NULL, NULL, &rest);
        for (int c = 0; c < 3; c++)
            l2 += (x[a * 3 + c] - x[b * 3 + c]) * (x[a * 3 + c] - x[b * 3 + c]);
        max_spring = fmax(max_spring, fabs(sqrt(l2) - rest));
    }
    CHECK(max_spring > 1e-4);
    CHECK(max_err < 1e-10);
    fprintf(stderr, "  block free fall: max |com - analytic| = %.3g, max |stretch| = %.3g\n", max_err, max_spring);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

static void wheel_counts_positions(void)
{
    for (size_t n = 3; n <= 9; n++)
        for (int flags = 0; flags < 4; flags++) {
            bool hub = flags & 1, brace = flags & 2;
            psys_system *sys = make_system(2);
            psys_wheel_def def = psys_wheel_def_default();
            def.id = "w";
            def.center[0] = 1;
            def.center[1] = 2;
            def.radius = 0.5;
            def.count = n;
            def.hub = hub;
            def.brace = brace;
            size_t first = 0;
            CHECK(psys_system_add_wheel(sys, &def, &first) == PSYS_OK);
            CHECK(psys_system_count(sys) == n + hub);
            size_t nbrace = !brace ? 0 : n >= 5 ? n : n == 4 ? 2 : 0;
            CHECK(psys_system_spring_count(sys) == n + (hub ? n : 0) + nbrace);
            CHECK(no_duplicate_springs(sys));
            const double *x = psys_system_positions(sys);
            for (size_t i = 0; i < n; i++) {
                char id[32];
                snprintf(id, sizeof id, "w[%zu]", i);
                CHECK(find(sys, id) == first + i);
                double th = TWO_PI * (double)i / (double)n;
                CHECK(x[i * 2] == 1 + 0.5 * cos(th) * 1 + 0.5 * sin(th) * 0);
                CHECK(x[i * 2 + 1] == 2 + 0.5 * cos(th) * 0 + 0.5 * sin(th) * 1);
            }
            if (hub) {
                size_t h = find(sys, "w[hub]");
                CHECK(h == first + n && x[h * 2] == 1 && x[h * 2 + 1] == 2);
            } else {
                CHECK(psys_system_find(sys, "w[hub]", NULL) != PSYS_OK);
            }
            check_at_rest(sys);
            psys_system_destroy(sys);
        }

    /* 3-D: the rim lies in the plane normal to the axis, at the radius */
    psys_system *sys = make_system(3);
    psys_wheel_def def = psys_wheel_def_default();
    def.id = "w";
    def.axis[0] = 1, def.axis[1] = 1, def.axis[2] = 0;
    def.count = 12;
    def.radius = 2;
    size_t pin[] = {3};
    def.pin = pin;
    def.pin_count = 1;
    def.pin_hub = true;
    CHECK(psys_system_add_wheel(sys, &def, NULL) == PSYS_OK);
    const double *x = psys_system_positions(sys);
    for (size_t i = 0; i < 12; i++) {
        double r = sqrt(x[i * 3] * x[i * 3] + x[i * 3 + 1] * x[i * 3 + 1] + x[i * 3 + 2] * x[i * 3 + 2]);
        CHECK_NEAR(r, 2, 1e-14);
        CHECK_NEAR((x[i * 3] + x[i * 3 + 1]) / sqrt(2.0), 0, 1e-14);
        CHECK(psys_system_is_fixed(sys, i) == (i == 3));
    }
    CHECK(psys_system_is_fixed(sys, find(sys, "w[hub]")));
    check_at_rest(sys);
    psys_system_destroy(sys);
}

/* A 2-D wheel set spinning about its hub keeps its shape (rim particles stay
 * at the radius) and its angular momentum. */
static void wheel_spins_rigidly(void)
{
    psys_system *sys = make_system(2);
    psys_wheel_def def = psys_wheel_def_default();
    def.count = 16;
    def.radius = 1;
    def.mass = 0.1;
    def.ks = 5000;
    def.kd = 1;
    CHECK(psys_system_add_wheel(sys, &def, NULL) == PSYS_OK);
    double omega = 3;
    const double *x = psys_system_positions(sys);
    for (size_t i = 0; i < 16; i++) {
        double v[2] = {-omega * x[i * 2 + 1], omega * x[i * 2]};
        CHECK(psys_system_set_particle(sys, i, NULL, v) == PSYS_OK);
    }
    psys_solver *s = make_solver("rk4", sys);
    double L0 = 0, L = 0, worst = 0;
    for (size_t i = 0; i < 17; i++)
        L0 += 0.1 * (x[i * 2] * psys_system_velocities(sys)[i * 2 + 1]
                     - x[i * 2 + 1] * psys_system_velocities(sys)[i * 2]);
    for (int k = 0; k < 4000; k++) {
        CHECK(psys_solver_step(s, 5e-4, NULL) == PSYS_OK);
        x = psys_system_positions(sys);
        for (size_t i = 0; i < 16; i++) {
            double dx = x[i * 2] - x[32], dy = x[i * 2 + 1] - x[33];
            worst = fmax(worst, fabs(sqrt(dx * dx + dy * dy) - 1));
        }
    }
    const double *v = psys_system_velocities(sys);
    for (size_t i = 0; i < 17; i++)
        L += 0.1 * (x[i * 2] * v[i * 2 + 1] - x[i * 2 + 1] * v[i * 2]);
    fprintf(stderr, "  spinning wheel: max |r - R| = %.3g, L %.17g -> %.17g\n", worst, L0, L);
    CHECK(worst < 0.01); /* centrifugal stretch ω²R m/ks-scale, no collapse */
    CHECK_NEAR(L, L0, 1e-9 * fabs(L0));
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* A cloth pinned at two corners hangs under gravity with drag: kinetic
 * energy decays below a bound and the pinned corners never move. */
static void cloth_hanging_settles(void)
{
    psys_system *sys = make_system(3);
    psys_cloth_def def = psys_cloth_def_default();
    size_t pin[] = {0, 0, 9, 0};
    def.id = "sheet";
    def.nx = 10;
    def.ny = 10;
    def.spacing = 0.1;
    def.mass = 0.01;
    def.ks = 200;
    def.kd = 0.05;
    def.bend_ks = 20;
    def.axes[1][1] = 0; /* lying flat in the x-z plane */
    def.axes[1][2] = 1;
    def.pin = pin;
    def.pin_count = 2;
    CHECK(psys_system_add_cloth(sys, &def, NULL) == PSYS_OK);
    double g[3] = {0, -9.81, 0};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, 0.05) == PSYS_OK);
    size_t c0 = find(sys, "sheet[0,0]"), c1 = find(sys, "sheet[9,0]");
    double p0[3], p1[3];
    memcpy(p0, psys_system_positions(sys) + c0 * 3, sizeof p0);
    memcpy(p1, psys_system_positions(sys) + c1 * 3, sizeof p1);
    psys_solver *s = make_solver("rk4", sys);
    double ke_max = 0;
    bool moved = false;
    for (int k = 0; k < 12000; k++) {
        CHECK(psys_solver_step(s, 5e-4, NULL) == PSYS_OK);
        const double *x = psys_system_positions(sys);
        moved = moved || memcmp(x + c0 * 3, p0, sizeof p0) != 0 || memcmp(x + c1 * 3, p1, sizeof p1) != 0;
        ke_max = fmax(ke_max, psys_system_kinetic_energy(sys));
    }
    double ke = psys_system_kinetic_energy(sys);
    fprintf(stderr, "  hanging cloth: peak KE %.3g J, final KE %.3g J\n", ke_max, ke);
    CHECK(!moved);
    CHECK(ke_max > 0.1);
    CHECK(ke < 1e-6 * ke_max);
    /* it hangs: the free corner is well below the pins */
    CHECK(psys_system_positions(sys)[find(sys, "sheet[0,9]") * 3 + 1] < -0.7);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ---- muscles ---- */

/* Eq. 1 force on a with rest length r. */
static void eq1(const double *xa, const double *xb, const double *va, const double *vb, double ks, double kd,
                double r, double *fa)
{
    double l[3], ld[3], len = 0, dot = 0;
    for (int c = 0; c < 3; c++) {
        l[c] = xa[c] - xb[c];
        ld[c] = va[c] - vb[c];
        len += l[c] * l[c];
        dot += ld[c] * l[c];
    }
    len = sqrt(len);
    for (int c = 0; c < 3; c++)
        fa[c] = -(ks * (len - r) + kd * dot / len) * l[c] / len;
}

static void muscle_rest_and_force(void)
{
    psys_system *sys = make_system(3);
    double xa[3] = {0.3, -0.2, 0.1}, xb[3] = {1.4, 0.5, -0.6}, va[3] = {0.2, 0.1, -0.3}, vb[3] = {-0.1, 0.4, 0.2};
    CHECK(psys_system_add_particle(sys, xa, va, 1, "a", NULL) == PSYS_OK);
    CHECK(psys_system_add_particle(sys, xb, vb, 2, "b", NULL) == PSYS_OK);
    double ks = 50, kd = 0.7, rest = 1.1, A = 0.3, w = 2.5, ph = 0.4;
    CHECK(psys_system_add_spring(sys, 0, 1, ks, kd, rest) == PSYS_OK);
    CHECK(psys_system_set_spring_muscle(sys, 0, A, w, ph) == PSYS_OK);
    double a, om, p;
    CHECK(psys_system_spring_muscle(sys, 0, &a, &om, &p) && a == A && om == w && p == ph);
    static const double times[] = {0, 0.1, 0.37, 1.0, 2.2, 10.5};
    for (size_t q = 0; q < sizeof times / sizeof times[0]; q++) {
        double t = times[q], r = rest * (1 + A * sin(w * t + ph));
        CHECK(psys_system_spring_rest_length(sys, 0, t) == r);
        psys_system_set_time(sys, t);
        double f[6], fa[3];
        CHECK(psys_system_compute_forces(sys, f) == PSYS_OK);
        eq1(xa, xb, va, vb, ks, kd, r, fa);
        for (int c = 0; c < 3; c++) {
            CHECK_NEAR(f[c], fa[c], 1e-12 * (1 + fabs(fa[c])));
            CHECK(f[3 + c] == -f[c]);
        }
        double l2 = 0;
        for (int c = 0; c < 3; c++)
            l2 += (xa[c] - xb[c]) * (xa[c] - xb[c]);
        double u = 0.5 * ks * (sqrt(l2) - r) * (sqrt(l2) - r);
        CHECK_NEAR(psys_system_potential_energy(sys), u, 1e-12 * (1 + u));
    }
    /* the Jacobian uses r(t) too: analytic against finite differences */
    psys_system_set_time(sys, 0.37);
    double dfdx[36], dfdv[36], fdx[36], fdv[36];
    CHECK(psys_system_dense_jacobian(sys, dfdx, dfdv) == PSYS_OK);
    CHECK(psys_system_fd_jacobian(sys, 1e-6, fdx, fdv) == PSYS_OK);
    for (int k = 0; k < 36; k++) {
        CHECK_NEAR(dfdx[k], fdx[k], 1e-6);
        CHECK_NEAR(dfdv[k], fdv[k], 1e-6);
    }
    /* springs added after a muscle exists keep their fixed rest length */
    CHECK(psys_system_add_particle(sys, xa, NULL, 1, NULL, NULL) == PSYS_OK);
    CHECK(psys_system_add_spring(sys, 1, 2, 10, 0, 0.75) == PSYS_OK);
    CHECK(psys_system_spring_rest_length(sys, 1, 3.0) == 0.75);
    CHECK(!psys_system_spring_muscle(sys, 1, NULL, NULL, NULL));
    /* amplitude 0 removes the muscle */
    CHECK(psys_system_set_spring_muscle(sys, 0, 0, 1, 0) == PSYS_OK);
    CHECK(!psys_system_spring_muscle(sys, 0, NULL, NULL, NULL));
    CHECK(psys_system_spring_rest_length(sys, 0, 0.37) == rest);
    /* bad arguments */
    CHECK(psys_system_set_spring_muscle(sys, 2, 0.1, 1, 0) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "no spring 2 (there are 2 springs)");
    CHECK(psys_system_set_spring_muscle(sys, 0, 1.5, 1, 0) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "muscle amplitude must be from 0 to 1 (got 1.5)");
    CHECK(psys_system_set_spring_muscle(sys, 0, 0.5, NAN, 0) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "muscle omega and phase must be finite");
    CHECK(isnan(psys_system_spring_rest_length(sys, 7, 0)));
    psys_system_destroy(sys);
}

/* Several muscles, removed out of order, keep the others intact. */
static void muscle_many(void)
{
    psys_system *sys = make_system(2);
    psys_chain_def def = psys_chain_def_default();
    def.count = 6;
    CHECK(psys_system_add_chain(sys, &def, NULL) == PSYS_OK);
    for (size_t k = 0; k < 5; k++)
        CHECK(psys_system_set_spring_muscle(sys, k, 0.1 * (double)(k + 1), (double)k, 0) == PSYS_OK);
    CHECK(psys_system_set_spring_muscle(sys, 1, 0, 0, 0) == PSYS_OK);
    CHECK(psys_system_set_spring_muscle(sys, 3, 0.9, 9, 1) == PSYS_OK); /* overwrite */
    CHECK(psys_system_set_spring_muscle(sys, 0, 0, 0, 0) == PSYS_OK);
    double want_amp[5] = {0, 0, 0.1 * 3, 0.9, 0.1 * 5};
    for (size_t k = 0; k < 5; k++) {
        double a = -1, w = -1;
        bool has = psys_system_spring_muscle(sys, k, &a, &w, NULL);
        CHECK(has == (want_amp[k] > 0));
        if (has)
            CHECK(a == want_amp[k] && w == (k == 3 ? 9 : (double)k));
        double r = psys_system_spring_rest_length(sys, k, 0.3);
        double want = want_amp[k] > 0 ? 1.0 / 5 * (1 + a * sin(w * 0.3 + (k == 3 ? 1 : 0))) : 1.0 / 5;
        CHECK_NEAR(r, want, 1e-15);
    }
    psys_system_destroy(sys);
}

/* ---- scenes ---- */

static const char *scene_all =
    "{\"psys\": 1, \"dim\": 3, \"integrator\": \"rk4\", \"dt\": 0.001, \"steps\": 50,\n"
    " \"particles\": [{\"id\": \"anchor\", \"x\": [0, 3, 0], \"fixed\": true}, {\"x\": [0.3, 3.1, 0.2]}],\n"
    " \"structures\": [\n"
    "  {\"type\": \"cloth\", \"id\": \"sheet\", \"origin\": [0, 0, 0], \"size\": [5, 4], \"spacing\": 0.1,\n"
    "   \"mass\": 0.01, \"ks\": 500, \"kd\": 0.2, \"bend_ks\": 50, \"pin\": [[0, 0], [4, 0]],\n"
    "   \"axes\": [[1, 0, 0], [0, 0, 1]]},\n"
    "  {\"type\": \"chain\", \"id\": \"rope\", \"from\": [0, 2, 0], \"to\": [1, 2, 0.3], \"count\": 6, \"ks\": 80,\n"
    "   \"kd\": 0.1, \"pin\": [0], \"muscle\": {\"amplitude\": 0.1, \"omega\": 4, \"phase\": 0.2, \"phase_step\": 0.7}},\n"
    "  {\"type\": \"beam\", \"id\": \"beam\", \"origin\": [2, 0, 0], \"size\": [4, 2], \"spacing\": 0.25, \"ks\": 300},\n"
    "  {\"type\": \"block\", \"id\": \"blk\", \"origin\": [-2, 1, 0], \"size\": [2, 3, 2], \"spacing\": 0.3,\n"
    "   \"mass\": 0.2, \"ks\": 400, \"kd\": 0.5},\n"
    "  {\"type\": \"wheel\", \"id\": \"w\", \"center\": [0, 5, 0], \"radius\": 0.4, \"count\": 7, \"ks\": 600,\n"
    "   \"axis\": [0, 1, 1], \"pin\": [\"hub\"]},\n"
    "  {\"type\": \"chain\", \"from\": [5, 5, 5], \"to\": [5, 6, 5], \"count\": 3, \"ks\": 9}\n"
    " ],\n"
    " \"forces\": [\n"
    "  {\"type\": \"gravity\", \"g\": [0, -9.81, 0]},\n"
    "  {\"type\": \"spring\", \"a\": \"anchor\", \"b\": \"sheet[2,3]\", \"ks\": 30, \"kd\": 0.1,\n"
    "   \"muscle\": {\"amplitude\": 0.25, \"omega\": 6.5}},\n"
    "  {\"type\": \"spring\", \"a\": \"rope[5]\", \"b\": \"w[hub]\", \"ks\": 20},\n"
    "  {\"type\": \"spring\", \"a\": 1, \"b\": 2, \"ks\": 20}\n"
    " ]}\n";

static void scene_ids_and_order(void)
{
    psys_scene *sc = load(scene_all);
    if (!sc)
        return;
    psys_system *sys = psys_scene_system(sc);
    /* explicit particles first, then each structure's in order */
    size_t cloth = 2, rope = cloth + 20, beam = rope + 6, blk = beam + 8, wheel = blk + 12, tail = wheel + 8;
    CHECK(psys_system_count(sys) == tail + 3);
    CHECK(find(sys, "sheet[0,0]") == cloth);
    CHECK(find(sys, "sheet[3,2]") == cloth + 3 + 5 * 2);
    CHECK(find(sys, "rope[4]") == rope + 4);
    CHECK(find(sys, "beam[3,1]") == beam + 3 + 4 * 1);
    CHECK(find(sys, "blk[1,2,1]") == blk + 1 + 2 * (2 + 3 * 1));
    CHECK(find(sys, "w[6]") == wheel + 6);
    CHECK(find(sys, "w[hub]") == wheel + 7);
    CHECK(psys_system_particle_id(sys, tail) == NULL);
    CHECK(psys_system_is_fixed(sys, find(sys, "sheet[4,0]")));
    CHECK(psys_system_is_fixed(sys, find(sys, "rope[0]")));
    CHECK(!psys_system_is_fixed(sys, find(sys, "rope[1]")));
    CHECK(psys_system_is_fixed(sys, find(sys, "w[hub]")));
    CHECK(psys_system_masses(sys)[find(sys, "blk[0,0,0]")] == 0.2);
    CHECK(psys_system_masses(sys)[find(sys, "beam[0,0]")] == 1.0);
    /* springs: structures in order, then the forces' springs */
    size_t ns = cloth_springs(5, 4, true, true) + 5 + cloth_springs(4, 2, true, false) + block_springs(2, 3, 2)
                + (7 + 7 + 7) + 2;
    CHECK(psys_system_spring_count(sys) == ns + 3);
    size_t a, b;
    psys_system_spring(sys, ns, &a, &b, NULL, NULL, NULL);
    CHECK(a == 0 && b == find(sys, "sheet[2,3]"));
    CHECK(psys_system_spring_muscle(sys, ns, NULL, NULL, NULL));
    psys_system_spring(sys, ns + 1, &a, &b, NULL, NULL, NULL);
    CHECK(a == find(sys, "rope[5]") && b == find(sys, "w[hub]"));
    /* the chain's muscles: phase 0.2 + s·0.7 */
    size_t rope_s0 = cloth_springs(5, 4, true, true);
    for (size_t s = 0; s < 5; s++) {
        double amp, w, p;
        CHECK(psys_system_spring_muscle(sys, rope_s0 + s, &amp, &w, &p));
        CHECK(amp == 0.1 && w == 4 && p == 0.2 + (double)s * 0.7);
    }
    psys_scene_destroy(sc);
}

/* The scene builds exactly what the C API builds. */
static void scene_matches_c_api(void)
{
    psys_scene *sc = load("{\"psys\": 1, \"dim\": 3, \"structures\": [{\"type\": \"cloth\", \"id\": \"s\","
                          " \"origin\": [0.5, 1, -2], \"size\": [7, 5], \"spacing\": 0.033, \"mass\": 0.02,"
                          " \"ks\": 123.5, \"kd\": 0.25, \"shear_kd\": 0.5, \"pin\": [[6, 4]],"
                          " \"axes\": [[0.6, 0.8, 0], [0, 0, 1]]}]}");
    if (!sc)
        return;
    psys_system *a = psys_scene_system(sc), *b = make_system(3);
    psys_cloth_def def = psys_cloth_def_default();
    size_t pin[] = {6, 4};
    def.id = "s";
    def.origin[0] = 0.5, def.origin[1] = 1, def.origin[2] = -2;
    def.nx = 7;
    def.ny = 5;
    def.spacing = 0.033;
    def.mass = 0.02;
    def.ks = 123.5;
    def.kd = 0.25;
    def.shear_kd = 0.5;
    def.axes[0][0] = 0.6, def.axes[0][1] = 0.8, def.axes[0][2] = 0;
    def.axes[1][0] = 0, def.axes[1][1] = 0, def.axes[1][2] = 1;
    def.pin = pin;
    def.pin_count = 1;
    CHECK(psys_system_add_cloth(b, &def, NULL) == PSYS_OK);
    CHECK(psys_system_count(a) == psys_system_count(b));
    CHECK(memcmp(psys_system_positions(a), psys_system_positions(b), 35 * 3 * sizeof(double)) == 0);
    for (size_t i = 0; i < 35; i++) {
        CHECK_STR(psys_system_particle_id(a, i), psys_system_particle_id(b, i));
        CHECK(psys_system_is_fixed(a, i) == psys_system_is_fixed(b, i));
    }
    CHECK(psys_system_spring_count(a) == psys_system_spring_count(b));
    for (size_t k = 0; k < psys_system_spring_count(a); k++) {
        size_t a1, b1, a2, b2;
        double ks1, kd1, r1, ks2, kd2, r2;
        psys_system_spring(a, k, &a1, &b1, &ks1, &kd1, &r1);
        psys_system_spring(b, k, &a2, &b2, &ks2, &kd2, &r2);
        CHECK(a1 == a2 && b1 == b2 && ks1 == ks2 && kd1 == kd2 && r1 == r2);
    }
    psys_system_destroy(b);
    psys_scene_destroy(sc);
}

/* Same particles (bits), springs and muscles. */
static void check_same_system(psys_system *a, psys_system *b)
{
    size_t n = psys_system_count(a);
    int d = psys_system_dim(a);
    CHECK(psys_system_dim(b) == d && psys_system_count(b) == n);
    if (psys_system_count(b) != n)
        return;
    CHECK(memcmp(psys_system_positions(a), psys_system_positions(b), n * (size_t)d * sizeof(double)) == 0);
    CHECK(memcmp(psys_system_velocities(a), psys_system_velocities(b), n * (size_t)d * sizeof(double)) == 0);
    CHECK(memcmp(psys_system_masses(a), psys_system_masses(b), n * sizeof(double)) == 0);
    for (size_t i = 0; i < n; i++) {
        const char *ia = psys_system_particle_id(a, i), *ib = psys_system_particle_id(b, i);
        CHECK((ia == NULL) == (ib == NULL));
        if (ia && ib)
            CHECK(strcmp(ia, ib) == 0);
        CHECK(psys_system_is_fixed(a, i) == psys_system_is_fixed(b, i));
    }
    CHECK(psys_system_force_count(a) == psys_system_force_count(b));
    CHECK(psys_system_spring_count(a) == psys_system_spring_count(b));
    for (size_t k = 0; k < psys_system_spring_count(a) && k < psys_system_spring_count(b); k++) {
        size_t a1, b1, a2, b2;
        double ks1, kd1, r1, ks2, kd2, r2, m1[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
        psys_system_spring(a, k, &a1, &b1, &ks1, &kd1, &r1);
        psys_system_spring(b, k, &a2, &b2, &ks2, &kd2, &r2);
        CHECK(a1 == a2 && b1 == b2);
        CHECK(memcmp(&ks1, &ks2, sizeof ks1) == 0 && memcmp(&kd1, &kd2, sizeof kd1) == 0
              && memcmp(&r1, &r2, sizeof r1) == 0);
        bool h1 = psys_system_spring_muscle(a, k, &m1[0], &m1[1], &m1[2]);
        bool h2 = psys_system_spring_muscle(b, k, &m2[0], &m2[1], &m2[2]);
        CHECK(h1 == h2 && memcmp(m1, m2, sizeof m1) == 0);
    }
}

static void scene_round_trip(void)
{
    psys_error err;
    psys_scene *s1 = load(scene_all);
    if (!s1)
        return;
    char *t1 = psys_scene_to_string(s1, NULL, &err);
    CHECK(t1 != NULL);
    if (!t1) {
        fprintf(stderr, "save: %s\n", err.message);
        psys_scene_destroy(s1);
        return;
    }
    CHECK(strstr(t1, "\"structures\"") == NULL); /* expanded */
    CHECK(strstr(t1, "\"sheet[3,2]\"") != NULL);
    CHECK(strstr(t1, "\"muscle\"") != NULL);
    psys_scene *s2 = load(t1);
    if (!s2) {
        free(t1);
        psys_scene_destroy(s1);
        return;
    }
    check_same_system(psys_scene_system(s1), psys_scene_system(s2));
    char *t2 = psys_scene_to_string(s2, NULL, &err);
    CHECK(t2 && strcmp(t1, t2) == 0);
    /* and they evolve identically, muscles included */
    psys_system *a = psys_scene_system(s1), *b = psys_scene_system(s2);
    psys_solver *sa = make_solver("rk4", a), *sb = make_solver("rk4", b);
    for (int k = 0; k < 200; k++) {
        CHECK(psys_solver_step(sa, 1e-3, NULL) == PSYS_OK);
        CHECK(psys_solver_step(sb, 1e-3, NULL) == PSYS_OK);
    }
    check_same_system(a, b);
    double ua = psys_system_potential_energy(a), ub = psys_system_potential_energy(b);
    CHECK(memcmp(&ua, &ub, sizeof ua) == 0);
    psys_solver_destroy(sa);
    psys_solver_destroy(sb);
    free(t1);
    free(t2);
    psys_scene_destroy(s1);
    psys_scene_destroy(s2);
}

/* ---- bad input ---- */

#define HEAD3 "{\"psys\": 1, \"dim\": 3, "
#define HEAD2 "{\"psys\": 1, \"dim\": 2, "

static void bad_structures(void)
{
    static const struct {
        const char *scene, *message;
    } cases[] = {
        {HEAD3 "\"structures\": {}}", "structures: must be an array (got {})"},
        {HEAD3 "\"structures\": [3]}", "structures[0]: a structure must be an object (got 3)"},
        {HEAD3 "\"structures\": [{\"id\": \"x\"}]}", "structures[0].type: required key missing"},
        {HEAD3 "\"structures\": [{\"type\": \"sheet\"}]}",
         "structures[0].type: unknown structure type (known: chain, cloth, beam, block, wheel) (got \"sheet\")"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, \"colour\": 1}]}",
         "structures[0].colour: unknown key"},
        {HEAD3 "\"structures\": [{\"type\": \"beam\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, \"shear\": true}]}",
         "structures[0].shear: unknown key"},
        /* sizes */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [1, 5], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: must be an array of 2 integers >= 2 (got [1,5])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 2.5], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: must be an array of 2 integers >= 2 (got [3,2.5])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3, 3], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: must be an array of 2 integers >= 2 (got [3,3,3])"},
        {HEAD3 "\"structures\": [{\"type\": \"block\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: must be an array of 3 integers >= 2 (got [3,3])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: required key missing"},
        /* hostile sizes: refused before allocating */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [100000, 10000], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: would exceed the limit of 50000000 particles per scene (got [100000,10000])"},
        {HEAD3 "\"structures\": [{\"type\": \"block\", \"size\": [4294967296, 4294967296, 4294967296], "
               "\"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: would exceed the limit of 50000000 particles per scene "
         "(got [4294967296,4294967296,4294967296])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [1e300, 2], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: would exceed the limit of 50000000 particles per scene (got [1e+300,2])"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], \"count\": 1e9, "
               "\"ks\": 1}]}",
         "structures[0].count: would exceed the limit of 50000000 particles per scene (got 1000000000)"},
        {HEAD3 "\"particles\": [{\"x\": [0, 0, 0]}], \"structures\": [{\"type\": \"cloth\", \"size\": [10000, 5000], "
               "\"spacing\": 1, \"ks\": 1}]}",
         "structures[0].size: would exceed the limit of 50000000 particles per scene (got [10000,5000])"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 50000000, \"ks\": 1}]}",
         "structures[0].count: would exceed the limit of 50000000 particles per scene (got 50000000)"},
        /* counts */
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], \"count\": 1, "
               "\"ks\": 1}]}",
         "structures[0].count: must be an integer >= 2 (got 1)"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 2, \"ks\": 1}]}",
         "structures[0].count: must be an integer >= 3 (got 2)"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": \"8\", \"ks\": 1}]}",
         "structures[0].count: must be an integer >= 3 (got \"8\")"},
        /* numbers */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 0, \"ks\": 1}]}",
         "structures[0].spacing: must be > 0 (got 0)"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, \"mass\": -1}]}",
         "structures[0].mass: must be > 0 (got -1)"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1}]}",
         "structures[0].ks: required key missing"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"bend_ks\": -2}]}",
         "structures[0].bend_ks: must be >= 0 (got -2)"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": -1, \"count\": 5, \"ks\": 1}]}",
         "structures[0].radius: must be > 0 (got -1)"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"shear\": 1}]}",
         "structures[0].shear: must be true or false (got 1)"},
        /* vectors */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"origin\": [0, 0]}]}",
         "structures[0].origin: must be an array of 3 numbers (dim is 3) (got [0,0])"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [0, 0, 0], \"count\": 3, "
               "\"ks\": 1}]}",
         "structures[0].to: must differ from \"from\" (got [0,0,0])"},
        /* axes */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"axes\": [[1, 0, 0], [2, 0, 0]]}]}",
         "structures[0].axes: must be two non-zero, non-parallel vectors (got [[1,0,0],[2,0,0]])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"axes\": [[0, 0, 0], [0, 1, 0]]}]}",
         "structures[0].axes: must be two non-zero, non-parallel vectors (got [[0,0,0],[0,1,0]])"},
        {HEAD3 "\"structures\": [{\"type\": \"block\", \"size\": [2, 2, 2], \"spacing\": 1, \"ks\": 1, "
               "\"axes\": [[1, 0, 0], [0, 1, 0], [1, 1, 0]]}]}",
         "structures[0].axes: must be three linearly independent vectors (got [[1,0,0],[0,1,0],[1,1,0]])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"axes\": [[1, 0, 0]]}]}",
         "structures[0].axes: must be an array of 2 vectors (got [[1,0,0]])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1, "
               "\"axes\": [[1, 0, 0], [0, 1]]}]}",
         "structures[0].axes[1]: must be an array of 3 numbers (dim is 3) (got [0,1])"},
        /* pins */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [4, 3], \"spacing\": 1, \"ks\": 1, "
               "\"pin\": [[0, 0], [4, 0]]}]}",
         "structures[0].pin[1]: must be grid coordinates [i, j] with 0 <= i < 4, 0 <= j < 3 (got [4,0])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [4, 3], \"spacing\": 1, \"ks\": 1, "
               "\"pin\": [[-1, 0]]}]}",
         "structures[0].pin[0]: must be grid coordinates [i, j] with 0 <= i < 4, 0 <= j < 3 (got [-1,0])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [4, 3], \"spacing\": 1, \"ks\": 1, "
               "\"pin\": [[0, 0.5]]}]}",
         "structures[0].pin[0]: must be grid coordinates [i, j] (integers) (got [0,0.5])"},
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"size\": [4, 3], \"spacing\": 1, \"ks\": 1, "
               "\"pin\": [0, 0]}]}",
         "structures[0].pin[0]: must be grid coordinates [i, j] (integers) (got 0)"},
        {HEAD3 "\"structures\": [{\"type\": \"block\", \"size\": [2, 2, 2], \"spacing\": 1, \"ks\": 1, "
               "\"pin\": [[1, 1, 2]]}]}",
         "structures[0].pin[0]: must be grid coordinates [i, j, k] with 0 <= i < 2, 0 <= j < 2, 0 <= k < 2 "
         "(got [1,1,2])"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], \"count\": 4, "
               "\"ks\": 1, \"pin\": [0, 4]}]}",
         "structures[0].pin[1]: must be a particle index from 0 to 3 (got 4)"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], \"count\": 4, "
               "\"ks\": 1, \"pin\": \"all\"}]}",
         "structures[0].pin: must be an array of particle indices (got \"all\")"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 5, \"ks\": 1, "
               "\"pin\": [\"hub\", 5]}]}",
         "structures[0].pin[1]: must be a rim index from 0 to 4 or \"hub\" (got 5)"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 5, \"ks\": 1, \"hub\": false, "
               "\"pin\": [1, \"hub\"]}]}",
         "structures[0].pin[1]: there is no hub (hub is false) (got \"hub\")"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 5, \"ks\": 1, "
               "\"pin\": [\"rim\"]}]}",
         "structures[0].pin[0]: must be a rim index (integer) or \"hub\" (got \"rim\")"},
        /* dimensions */
        {HEAD2 "\"structures\": [{\"type\": \"block\", \"size\": [2, 2, 2], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].type: needs dim 3 (a block is a 3-D lattice; use a beam in 2-D) (got \"block\")"},
        {HEAD2 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 5, \"ks\": 1, "
               "\"axis\": [0, 0, 1]}]}",
         "structures[0].axis: is only used in 3-D scenes (dim is 2) (got [0,0,1])"},
        {HEAD3 "\"structures\": [{\"type\": \"wheel\", \"radius\": 1, \"count\": 5, \"ks\": 1, "
               "\"axis\": [0, 0, 0]}]}",
         "structures[0].axis: must be a non-zero vector (got [0,0,0])"},
        /* ids */
        {HEAD3 "\"structures\": [{\"type\": \"cloth\", \"id\": \"\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].id: must be a non-empty string (got \"\")"},
        {HEAD3 "\"particles\": [{\"id\": \"sheet[0,0]\", \"x\": [0, 0, 0]}], "
               "\"structures\": [{\"type\": \"cloth\", \"id\": \"sheet\", \"size\": [3, 3], \"spacing\": 1, \"ks\": 1}]}",
         "structures[0].id: already in use by particle \"sheet[0,0]\" (got \"sheet\")"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"id\": \"r\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], "
               "\"count\": 3, \"ks\": 1}, {\"type\": \"wheel\", \"id\": \"r\", \"radius\": 1, \"count\": 5, \"ks\": 1}]}",
         "structures[1].id: already in use by particle \"r[0]\" (got \"r\")"},
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"id\": \"r\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], "
               "\"count\": 3, \"ks\": 1}], \"forces\": [{\"type\": \"spring\", \"a\": \"r[0]\", \"b\": \"r[3]\", "
               "\"ks\": 1}]}",
         "forces[0].b: unknown particle id (got \"r[3]\")"},
        /* muscles */
        {HEAD3 "\"structures\": [{\"type\": \"chain\", \"from\": [0, 0, 0], \"to\": [1, 0, 0], \"count\": 3, "
               "\"ks\": 1, \"muscle\": {\"amplitude\": 2, \"omega\": 1}}]}",
         "structures[0].muscle.amplitude: must be from 0 to 1 (got 2)"},
        {HEAD3 "\"particles\": [{\"x\": [0, 0, 0]}, {\"x\": [1, 0, 0]}], \"forces\": [{\"type\": \"spring\", "
               "\"a\": 0, \"b\": 1, \"ks\": 1, \"muscle\": {\"amplitude\": 0.5}}]}",
         "forces[0].muscle.omega: required key missing"},
        {HEAD3 "\"particles\": [{\"x\": [0, 0, 0]}, {\"x\": [1, 0, 0]}], \"forces\": [{\"type\": \"spring\", "
               "\"a\": 0, \"b\": 1, \"ks\": 1, \"muscle\": {\"amplitude\": 0.5, \"omega\": 1, \"phase_step\": 1}}]}",
         "forces[0].muscle.phase_step: unknown key"},
        {HEAD3 "\"particles\": [{\"x\": [0, 0, 0]}, {\"x\": [1, 0, 0]}], \"forces\": [{\"type\": \"spring\", "
               "\"a\": 0, \"b\": 1, \"ks\": 1, \"muscle\": {\"amplitude\": -0.5, \"omega\": 1}}]}",
         "forces[0].muscle.amplitude: must be >= 0 (got -0.5)"},
        {HEAD3 "\"particles\": [{\"x\": [0, 0, 0]}, {\"x\": [1, 0, 0]}], \"forces\": [{\"type\": \"spring\", "
               "\"a\": 0, \"b\": 1, \"ks\": 1, \"muscle\": 0.5}]}",
         "forces[0].muscle: must be an object {\"amplitude\", \"omega\", \"phase\"} (got 0.5)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        expect_error(cases[i].scene, cases[i].message);
}

/* C API: messages, hostile sizes refused without allocating, and a failed
 * builder leaves the system as it was. */
static void c_api_errors(void)
{
    psys_system *sys = make_system(3);
    psys_chain_def chain = psys_chain_def_default();
    chain.id = "rope";
    CHECK(psys_system_add_chain(sys, &chain, NULL) == PSYS_OK);
    size_t n = psys_system_count(sys), ns = psys_system_spring_count(sys);

    psys_cloth_def cloth = psys_cloth_def_default();
    cloth.id = "sheet";
    cloth.nx = 1;
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "cloth \"sheet\": size: must be an array of 2 integers >= 2 (got [1, 2])");
    cloth.nx = SIZE_MAX / 2;
    cloth.ny = 4;
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK(strstr(psys_system_last_error(sys), "would exceed the limit of 50000000 particles per scene") != NULL);
    cloth.nx = 10000;
    cloth.ny = 5000; /* exactly 50M, but the system already holds 2 particles */
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys),
              "cloth \"sheet\": size: would exceed the limit of 50000000 particles per scene (got [10000, 5000])");
    cloth.nx = cloth.ny = 3;
    size_t pin[] = {1, 3};
    cloth.pin = pin;
    cloth.pin_count = 1;
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys),
              "cloth \"sheet\": pin[0]: must be grid coordinates [i, j] with 0 <= i < 3, 0 <= j < 3 (got [1, 3])");
    cloth.pin_count = 0;
    cloth.spacing = -1;
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "cloth \"sheet\": spacing: must be > 0 (got -1)");
    cloth.spacing = 1;
    cloth.mass = 0;
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "cloth \"sheet\": mass: must be > 0 (got 0)");
    cloth.mass = 1;
    cloth.id = "rope";
    CHECK(psys_system_add_cloth(sys, &cloth, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "cloth \"rope\": id: already in use by particle \"rope[0]\" (got \"rope\")");

    psys_block_def block = psys_block_def_default();
    block.nx = block.ny = block.nz = SIZE_MAX; /* nx·ny·nz overflows: caught before multiplying */
    CHECK(psys_system_add_block(sys, &block, NULL) == PSYS_ERR_INVALID);
    CHECK(strstr(psys_system_last_error(sys), "block: size: would exceed the limit") != NULL);
    block.nx = block.ny = block.nz = 400; /* 64 million */
    CHECK(psys_system_add_block(sys, &block, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys),
              "block: size: would exceed the limit of 50000000 particles per scene (got [400, 400, 400])");

    psys_wheel_def wheel = psys_wheel_def_default();
    wheel.hub = false;
    wheel.pin_hub = true;
    CHECK(psys_system_add_wheel(sys, &wheel, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "wheel: pin_hub: needs a hub (hub is false) (got true)");

    chain.id = NULL;
    chain.muscle_amplitude = 3;
    CHECK(psys_system_add_chain(sys, &chain, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(sys), "chain: muscle: amplitude must be from 0 to 1 (got 3)");

    CHECK(psys_system_count(sys) == n);
    CHECK(psys_system_spring_count(sys) == ns);

    psys_system *flat = make_system(2);
    block = psys_block_def_default();
    CHECK(psys_system_add_block(flat, &block, NULL) == PSYS_ERR_INVALID);
    CHECK_STR(psys_system_last_error(flat), "block: needs a 3-D system (dim is 2)");
    CHECK(psys_system_count(flat) == 0);
    psys_system_destroy(flat);

    /* after all the failures, building still works and ids continue */
    cloth = psys_cloth_def_default();
    cloth.id = "sheet";
    size_t first = 0;
    CHECK(psys_system_add_cloth(sys, &cloth, &first) == PSYS_OK);
    CHECK(first == n && find(sys, "sheet[1,1]") == n + 3);
    psys_system_destroy(sys);
}

static const check_case cases[] = {
    {"chain_counts_positions", chain_counts_positions},
    {"chain_muscle_wave", chain_muscle_wave},
    {"cloth_counts", cloth_counts},
    {"cloth_ids_positions_pins", cloth_ids_positions_pins},
    {"cloth_hanging_settles", cloth_hanging_settles},
    {"beam_counts", beam_counts},
    {"beam_cantilever", beam_cantilever},
    {"block_counts", block_counts},
    {"block_free_fall", block_free_fall},
    {"wheel_counts_positions", wheel_counts_positions},
    {"wheel_spins_rigidly", wheel_spins_rigidly},
    {"muscle_rest_and_force", muscle_rest_and_force},
    {"muscle_many", muscle_many},
    {"scene_ids_and_order", scene_ids_and_order},
    {"scene_matches_c_api", scene_matches_c_api},
    {"scene_round_trip", scene_round_trip},
    {"bad_structures", bad_structures},
    {"c_api_errors", c_api_errors},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
