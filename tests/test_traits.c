/* Force traits (psys_force_class.traits): a force type written outside the
 * library (tests/my_gravity.h, public API only) gets the paths its traits
 * promise, verlet's velocity-free shortcut and the fused derivative, and
 * the same bits as the built-in gravity; with no traits it runs the generic
 * paths and still gives the same bits. */
#include "check.h"
#include "my_gravity.h"

/* psys__fused_eligible: whether the fused derivative takes a system (the
 * fused path has no public observable). */
#include "../src/sim/sim.h"

static const double G3[3] = {0.3, -9.81, 0.2};

/* One free particle at rest under g = (0, -1) and the force of class cls
 * (g = 0, recording), one verlet step of h = 0.1: the velocity of particle
 * 0 the step's second evaluation saw. */
static double verlet_second_v(const psys_force_class *cls, bool with_drag)
{
    psys_system *s = psys_system_create(2, NULL);
    const double x[2] = {0, 0}, g[2] = {0, -1};
    double seen[24] = {0};
    int nseen = 0;
    CHECK(psys_system_add_particle(s, x, NULL, 1.0, NULL, NULL) == PSYS_OK);
    CHECK(psys_system_add_gravity(s, g) == PSYS_OK);
    my_gravity *gr = calloc(1, sizeof *gr);
    gr->seen_v = seen;
    gr->seen_n = &nseen;
    CHECK(psys_system_add_force(s, cls, gr) == PSYS_OK);
    if (with_drag)
        CHECK(psys_system_add_drag(s, 0.0) == PSYS_OK);
    psys_solver *sv = psys_system_solver_create(s, "verlet", NULL);
    double h = 0;
    CHECK(psys_system_advance(s, sv, 0.1, &h) == PSYS_OK);
    CHECK(h == 0.1);
    CHECK(nseen == 2);
    CHECK(seen[0] == 0 && seen[1] == 0);
    psys_solver_destroy(sv);
    psys_system_destroy(s);
    return seen[3 + 1];
}

/* (a) Verlet's second evaluation takes the half-step velocity v½ = -0.05
 * where every force is velocity-free, else the predicted one ṽ1 = -0.1. */
static void verlet_shortcut(void)
{
    CHECK(verlet_second_v(&my_gravity_class, false) == -0.05);
    CHECK(verlet_second_v(&my_plain_class, false) == -0.1);
    CHECK(verlet_second_v(&my_gravity_class, true) == -0.1); /* drag reads v */
}

/* An nx × ny cloth (3-D, structural, shear and bend springs, two corners
 * fixed) with gravity of class cls (NULL: the built-in) before the springs
 * and drag after them. */
static psys_system *cloth(const psys_force_class *cls, int nx, int ny)
{
    psys_system *s = psys_system_create(3, NULL);
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < nx; c++) {
            const double x[3] = {0.1 * c, 0, 0.1 * r + 0.003 * ((c * 7 + r * 3) % 5)};
            const double v[3] = {0.01 * ((r + c) % 3), 0, -0.02 * (c % 2)};
            CHECK(psys_system_add_particle(s, x, v, 0.5 + 0.1 * ((r * nx + c) % 4), NULL, NULL) == PSYS_OK);
        }
    CHECK(psys_system_set_fixed(s, 0, true) == PSYS_OK);
    CHECK(psys_system_set_fixed(s, (size_t)nx - 1, true) == PSYS_OK);
    CHECK((cls ? my_gravity_add(s, cls, G3) : psys_system_add_gravity(s, G3)) == PSYS_OK);
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < nx; c++) {
            const size_t i = (size_t)(r * nx + c), w = (size_t)nx;
            if (c + 1 < nx) CHECK(psys_system_add_spring(s, i, i + 1, 80, 0.3, -1) == PSYS_OK);
            if (r + 1 < ny) CHECK(psys_system_add_spring(s, i, i + w, 80, 0.3, -1) == PSYS_OK);
            if (c + 1 < nx && r + 1 < ny) CHECK(psys_system_add_spring(s, i, i + w + 1, 40, 0.2, -1) == PSYS_OK);
            if (c > 0 && r + 1 < ny) CHECK(psys_system_add_spring(s, i, i + w - 1, 40, 0.2, -1) == PSYS_OK);
            if (c + 2 < nx) CHECK(psys_system_add_spring(s, i, i + 2, 10, 0.1, -1) == PSYS_OK);
        }
    CHECK(psys_system_add_drag(s, 0.05) == PSYS_OK);
    return s;
}

/* (b) The fused derivative takes a per-particle class with a row kernel,
 * as it takes the built-in gravity, and not the same force without traits
 * or without its kernel. */
static void fused_path(void)
{
    psys_system *a = cloth(NULL, 6, 5), *b = cloth(&my_gravity_class, 6, 5), *c = cloth(&my_plain_class, 6, 5);
    CHECK(psys__fused_eligible(a));
    CHECK(psys__fused_eligible(b));
    CHECK(!psys__fused_eligible(c));
    psys_force_class no_rows = my_gravity_class;
    no_rows.apply_rows = NULL;
    psys_system *d = cloth(&no_rows, 6, 5);
    CHECK(!psys__fused_eligible(d));
    psys_force_class rows_only = my_gravity_class; /* a kernel without the trait is not used */
    rows_only.traits = PSYS_FORCE_VELOCITY_FREE;
    psys_system *e = cloth(&rows_only, 6, 5);
    CHECK(!psys__fused_eligible(e));
    psys_system_destroy(a);
    psys_system_destroy(b);
    psys_system_destroy(c);
    psys_system_destroy(d);
    psys_system_destroy(e);
}

/* (d) 300 steps of a 16 × 12 cloth with each solver: the new type, with
 * its traits (fused path) and without (generic path), the same bits as the
 * built-in gravity, on one thread and on four. */
static void same_bits(void)
{
    const char *solvers[] = {"rk4", "verlet", "midpoint"};
    const int nx = 16, ny = 12;
    const size_t nd = 3 * (size_t)(nx * ny);
    for (int k = 0; k < 3; k++)
        for (int threads = 1; threads <= 4; threads += 3) {
            psys_system *sys[3] = {cloth(NULL, nx, ny), cloth(&my_gravity_class, nx, ny),
                                   cloth(&my_plain_class, nx, ny)};
            CHECK(psys__fused_eligible(sys[1]) && !psys__fused_eligible(sys[2]));
            for (int v = 0; v < 3; v++) {
                CHECK(psys_system_set_threads(sys[v], threads) == PSYS_OK);
                psys_solver *sv = psys_system_solver_create(sys[v], solvers[k], NULL);
                CHECK(sv != NULL);
                double h = 0;
                for (int step = 0; step < 300 && sv; step++)
                    CHECK(psys_system_advance(sys[v], sv, 0.002, &h) == PSYS_OK);
                psys_solver_destroy(sv);
            }
            for (int v = 1; v < 3; v++) {
                CHECK(memcmp(psys_system_positions(sys[0]), psys_system_positions(sys[v]), nd * sizeof(double)) == 0);
                CHECK(memcmp(psys_system_velocities(sys[0]), psys_system_velocities(sys[v]), nd * sizeof(double))
                      == 0);
                CHECK(psys_system_time(sys[0]) == psys_system_time(sys[v]));
            }
            /* it moved: a fall of about ½ g t² at t = 0.6 */
            CHECK(psys_system_positions(sys[0])[nd - 2] < -0.5);
            for (int v = 0; v < 3; v++)
                psys_system_destroy(sys[v]);
        }
}

static const check_case cases[] = {
    {"verlet_shortcut", verlet_shortcut},
    {"fused_path", fused_path},
    {"same_bits", same_bits},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
