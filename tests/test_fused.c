/* The fused derivative (src/fast/fused.c) against the generic one: the
 * same bits for every system it accepts, at every thread count, through
 * every explicit solver; and the systems it must leave to the generic path. */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include "check.h"

#include "../src/sim/bench.h"
#include "../src/sim/sim.h"
#include "../src/forces/springs.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static uint64_t lcg = 12345;
static double rnd(void) /* in [0, 1), the same sequence on every machine */
{
    lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(lcg >> 11) * (1.0 / 9007199254740992.0);
}

static void add_particles(psys_system *s, int dim, size_t n, int nx)
{
    for (size_t i = 0; i < n; i++) {
        double x[3] = {0.1 * (double)(i % (size_t)nx) + 0.01 * rnd(), 0.1 * (double)(i / (size_t)nx) + 0.01 * rnd(),
                       0.01 * rnd()};
        double v[3] = {rnd() - 0.5, rnd() - 0.5, rnd() - 0.5};
        if (dim == 2)
            x[2] = v[2] = 0;
        CHECK(psys_system_add_particle(s, x, v, 0.5 + rnd(), NULL, NULL) == PSYS_OK);
    }
}

/* Where set, spring() renumbers its ends: particle i is spring_map[i]. */
static const size_t *spring_map;

static void spring(psys_system *s, size_t a, size_t b)
{
    if (spring_map)
        a = spring_map[a], b = spring_map[b];
    /* rest -1: the current distance, then stretched by the random positions */
    CHECK(psys_system_add_spring(s, a, b, 50 + 100 * rnd(), 0.5 * rnd(), 0.09 + 0.02 * rnd()) == PSYS_OK);
}

/* An nx × ny sheet with structural, shear and bend springs (offsets 1, nx,
 * nx ± 1, 2, 2 nx: the window wraps around many times when nx·ny is large). */
static void sheet_springs(psys_system *s, size_t first, int nx, int ny)
{
    for (int r = 0; r < ny; r++)
        for (int c = 0; c < nx; c++) {
            size_t i = first + (size_t)r * (size_t)nx + (size_t)c;
            if (c + 1 < nx) spring(s, i, i + 1);
            if (r + 1 < ny) spring(s, i + (size_t)nx, i); /* some springs with a > b */
            if (c + 1 < nx && r + 1 < ny) spring(s, i, i + (size_t)nx + 1);
            if (c > 0 && r + 1 < ny) spring(s, i, i + (size_t)nx - 1);
            if (c + 2 < nx) spring(s, i, i + 2);
            if (r + 2 < ny) spring(s, i, i + 2 * (size_t)nx);
        }
}

enum { SHEET, SHEET_FORCES_AFTER, CHAIN_GAPS_2D, RANDOM_FAR, BIG_SHEET, SHEET_SHUFFLED, NEAR_RUNS, NEAR_RUNS_2D, NKINDS };

/* The system a of build(SHEET) with particle i renumbered pi[i]: the same
 * particles, forces and springs (in the same order), so the same physics. */
static psys_system *relabelled(const psys_system *a, const size_t *pi)
{
    const double g3[3] = {0.3, -9.81, 0.2};
    const size_t n = psys_system_count(a);
    size_t *inv = malloc(n * sizeof *inv);
    for (size_t i = 0; i < n; i++)
        inv[pi[i]] = i;
    psys_system *b = psys_system_create(3, NULL);
    CHECK(psys_system_add_gravity(b, g3) == PSYS_OK);
    CHECK(psys_system_add_drag(b, 0.3) == PSYS_OK);
    const double *x = psys_system_positions(a), *v = psys_system_velocities(a), *m = psys_system_masses(a);
    for (size_t q = 0; q < n; q++)
        CHECK(psys_system_add_particle(b, x + 3 * inv[q], v + 3 * inv[q], m[inv[q]], NULL, NULL) == PSYS_OK);
    for (size_t i = 0; i < n; i++)
        if (psys_system_is_fixed(a, i))
            CHECK(psys_system_set_fixed(b, pi[i], true) == PSYS_OK);
    for (size_t k = 0; k < psys_system_spring_count(a); k++) {
        size_t sa, sb;
        double ks, kd, rest;
        CHECK(psys_system_spring(a, k, &sa, &sb, &ks, &kd, &rest) == PSYS_OK);
        CHECK(psys_system_add_spring(b, pi[sa], pi[sb], ks, kd, rest) == PSYS_OK);
    }
    free(inv);
    return b;
}

/* A random permutation of 0..n-1 (Fisher–Yates on rnd()). */
static size_t *shuffled(size_t n)
{
    size_t *pi = malloc(n * sizeof *pi);
    for (size_t i = 0; i < n; i++)
        pi[i] = i;
    for (size_t i = n - 1; i > 0; i--) {
        size_t j = (size_t)(rnd() * (double)(i + 1)), t = pi[i];
        pi[i] = pi[j];
        pi[j] = t;
    }
    return pi;
}

/* Runs of offsets 1 to 9, of lengths 1 to 40 at every position within a
 * cache line, half of them sharing ks and kd: the AVX-512 loops' masked
 * first and last vectors, and the near offsets' shifted second ends
 * (fast/fused.c, run_near_512_d). n = 3000 particles: the window (1,024
 * slots) wraps around within some runs. Two springs of zero length. */
static void near_runs(psys_system *s, int dim)
{
    const size_t n = 3000;
    add_particles(s, dim, n, 60);
    for (size_t i = 1000; i < 1400; i += 97) { /* a particle on its neighbour: no direction, no force */
        const double *x = psys_system_positions(s) + (i + 1) * (size_t)dim;
        double at[3] = {x[0], x[1], dim == 3 ? x[2] : 0}, v[3] = {0.1, 0.2, 0.3};
        CHECK(psys_system_set_particle(s, i, at, v) == PSYS_OK);
    }
    for (size_t o = 1; o <= 9; o++)
        for (int seg = 0; seg < 25; seg++) {
            const size_t len = 1 + (size_t)(rnd() * 40), a = (size_t)(rnd() * (double)(n - len - o));
            const bool shared = seg % 2 == 0;
            const double ks = 50 + 100 * rnd(), kd = 0.5 * rnd();
            for (size_t j = 0; j < len; j++) {
                if (shared)
                    CHECK(psys_system_add_spring(s, a + j, a + j + o, ks, kd, 0.09 + 0.02 * rnd()) == PSYS_OK);
                else
                    spring(s, a + j, a + j + o);
            }
        }
    for (size_t i = 0; i + 1 < n; i++) /* a whole rope too: runs of a block's length */
        spring(s, i + 1, i);
}

static psys_system *build(int kind)
{
    const double g3[3] = {0.3, -9.81, 0.2};
    int dim = kind == CHAIN_GAPS_2D || kind == NEAR_RUNS_2D ? 2 : 3;
    lcg = 12345 + (uint64_t)kind; /* the same system every time */
    psys_system *s = psys_system_create(dim, NULL);
    switch (kind) {
    case SHEET: /* gravity and drag before the springs */
        add_particles(s, 3, 70 * 45, 70);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        CHECK(psys_system_add_drag(s, 0.3) == PSYS_OK);
        sheet_springs(s, 0, 70, 45);
        CHECK(psys_system_set_fixed(s, 0, true) == PSYS_OK);
        CHECK(psys_system_set_fixed(s, 69, true) == PSYS_OK);
        break;
    case SHEET_FORCES_AFTER: /* drag before, two gravities after the springs */
        add_particles(s, 3, 70 * 45, 70);
        CHECK(psys_system_add_drag(s, 0.3) == PSYS_OK);
        sheet_springs(s, 0, 70, 45);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        CHECK(psys_system_set_fixed(s, 3000, true) == PSYS_OK);
        break;
    case CHAIN_GAPS_2D: { /* particles with no springs before, between and after two chains; muscles */
        const double g2[2] = {0.1, -9.81};
        add_particles(s, 2, 5000, 100);
        CHECK(psys_system_add_gravity(s, g2) == PSYS_OK);
        for (size_t i = 1000; i + 1 < 1600; i++) {
            spring(s, i, i + 1);
            if (i % 7 == 0)
                spring(s, i + 3, i);
        }
        for (size_t i = 4000; i + 1 < 4100; i++)
            spring(s, i, i + 1);
        CHECK(psys_system_add_drag(s, 0.2) == PSYS_OK);
        for (size_t k = 0; k < psys_system_spring_count(s); k += 5)
            CHECK(psys_system_set_spring_muscle(s, k, 0.3, 2.0 + (double)k, 0.1 * (double)k) == PSYS_OK);
        psys_system_set_time(s, 0.37);
        break;
    }
    case RANDOM_FAR: /* offsets up to n - 1: a window as long as the system */
        add_particles(s, 3, 700, 30);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        for (int k = 0; k < 3000; k++) {
            size_t a = (size_t)(rnd() * 700), b = (size_t)(rnd() * 700);
            if (a != b)
                spring(s, a, b);
        }
        break;
    case SHEET_SHUFFLED: { /* SHEET with its particles renumbered at random: an internal order */
        psys_system *a = build(SHEET);
        size_t *pi = shuffled(psys_system_count(a));
        psys_system_destroy(s);
        s = relabelled(a, pi);
        /* and a hub: particle 5 tied to 60 others */
        for (size_t k = 1; k <= 60; k++)
            spring(s, 5, (5 + 47 * k) % psys_system_count(s));
        free(pi);
        psys_system_destroy(a);
        break;
    }
    case NEAR_RUNS:
        CHECK(psys_system_add_drag(s, 0.2) == PSYS_OK);
        near_runs(s, 3);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        break;
    case NEAR_RUNS_2D: {
        const double g2[2] = {0.1, -9.81};
        CHECK(psys_system_add_gravity(s, g2) == PSYS_OK);
        near_runs(s, 2);
        CHECK(psys_system_set_fixed(s, 1500, true) == PSYS_OK);
        break;
    }
    case BIG_SHEET: /* over 20,000 springs: threads share the particles */
        add_particles(s, 3, 110 * 100, 110);
        CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
        CHECK(psys_system_add_drag(s, 0.1) == PSYS_OK);
        sheet_springs(s, 0, 110, 100);
        CHECK(psys_system_set_fixed(s, 5000, true) == PSYS_OK);
        break;
    }
    return s;
}

/* ydot by the generic path (PSYS_FUSED=0) through the ODE interface. */
static double *generic_derivative(psys_system *s, const double *y)
{
    psys_ode o = psys_system_ode(s);
    double *ydot = calloc(o.size, sizeof *ydot);
    const psys__switches sw = s->sw;
    s->sw.fused = '0'; /* PSYS_FUSED=0 for this evaluation */
    CHECK(o.derivative(o.ctx, psys_system_time(s), y, ydot) == PSYS_OK);
    s->sw = sw;
    return ydot;
}

/* ydot by the fused path, which must take the system. */
static double *fused_derivative(psys_system *s, const double *y, int threads)
{
    psys_ode o = psys_system_ode(s);
    double *ydot = calloc(o.size, sizeof *ydot);
    for (size_t i = 0; i < o.size; i++)
        ydot[i] = NAN; /* every entry must be written */
    CHECK(psys_system_set_threads(s, threads) == PSYS_OK);
    psys_force_eval e;
    size_t nd = o.size / 2;
    psys__sys_eval(s, psys_system_time(s), y, y + nd, &e);
    bool used = false;
    const psys__switches sw = s->sw;
    s->sw.fused = '1'; /* PSYS_FUSED=1 for this evaluation */
    CHECK(psys__fused_derivative(s, &e, y, ydot, NULL, &used) == PSYS_OK);
    s->sw = sw;
    CHECK(used);
    return ydot;
}

/* The first index at which got and want differ in their bits (size if none). */
static size_t first_difference(const double *got, const double *want, size_t size)
{
    for (size_t i = 0; i < size; i++)
        if (memcmp(&got[i], &want[i], sizeof(double)) != 0)
            return i;
    return size;
}

/* Whether got and want are the same bits; if not, says where they first
 * differ, after the label (a printf format and its arguments). */
static bool same_bits(const double *got, const double *want, size_t size, const char *fmt, ...)
{
    const size_t bad = first_difference(got, want, size);
    if (bad == size)
        return true;
    va_list ap;
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, ": [%zu] = %.17g, expected %.17g\n", bad, got[bad], want[bad]);
    return false;
}

static void derivative_same_bits(void)
{
    for (int kind = 0; kind < NKINDS; kind++) {
        psys_system *s = build(kind);
        psys_ode o = psys_system_ode(s);
        double *y = malloc(o.size * sizeof *y);
        o.get_state(o.ctx, y);
        double *want = generic_derivative(s, y);
        for (int threads = 1; threads <= 3; threads++) {
            double *got = fused_derivative(s, y, threads);
            CHECK(same_bits(got, want, o.size, "kind %d, %d threads, ydot against the generic path", kind, threads));
            free(got);
        }
        /* and the forces are not trivially zero: the comparison means something */
        double norm = 0;
        for (size_t i = o.size / 2; i < o.size; i++)
            norm += fabs(want[i]);
        CHECK(norm > 1.0);
        free(want);
        free(y);
        psys_system_destroy(s);
    }
}

/* The internal order of sys's spring set (NULL: the particles' own). */
static const uint32_t *order_of(const psys_system *sys)
{
    for (size_t k = 0; k < psys_system_force_count(sys); k++)
        if (psys_system_force_class(sys, k) == &psys_spring_class)
            return ((const springs *)psys_system_force_data(sys, k))->perm;
    return NULL;
}

/* The springs' internal order (src/forces/spring.c): a sheet whose particles
 * come shuffled gets one, the sheet in its own order keeps that; and the
 * shuffled sheet's derivative is the sheet's, relabelled, to rounding (each
 * particle's spring forces are added in another order), on both paths
 * (which agree bit for bit: derivative_same_bits, SHEET_SHUFFLED). */
static void shuffled_same_physics(void)
{
    psys_system *a = build(SHEET);
    const size_t n = psys_system_count(a);
    size_t *pi = shuffled(n);
    psys_system *b = relabelled(a, pi);
    psys_ode oa = psys_system_ode(a), ob = psys_system_ode(b);
    double *ya = malloc(oa.size * sizeof *ya), *yb = malloc(ob.size * sizeof *yb);
    oa.get_state(oa.ctx, ya);
    ob.get_state(ob.ctx, yb);
    for (int fused = 0; fused < 2; fused++) {
        double *da = fused ? fused_derivative(a, ya, 1) : generic_derivative(a, ya);
        double *db = fused ? fused_derivative(b, yb, 2) : generic_derivative(b, yb);
        CHECK(order_of(a) == NULL);
        CHECK(order_of(b) != NULL);
        if (order_of(b)) { /* a permutation of the particles */
            unsigned char *hit = calloc(n, 1);
            for (size_t i = 0; i < n; i++)
                if (order_of(b)[i] < n)
                    hit[order_of(b)[i]]++;
            for (size_t i = 0; i < n; i++)
                CHECK(hit[i] == 1);
            free(hit);
        }
        double scale = 0, worst = 0;
        for (size_t h = 0; h < 2; h++) /* x' = v, then v' = f/m */
            for (size_t i = 0; i < n; i++)
                for (size_t c = 0; c < 3; c++) {
                    const double p = da[h * 3 * n + 3 * i + c], q = db[h * 3 * n + 3 * pi[i] + c];
                    scale = fmax(scale, fabs(p));
                    worst = fmax(worst, fabs(p - q));
                }
        CHECK(scale > 1.0);
        if (!(worst <= 1e-12 * scale))
            fprintf(stderr, "fused %d: relabelled derivative off by %g (scale %g)\n", fused, worst, scale);
        CHECK(worst <= 1e-12 * scale);
        free(da);
        free(db);
    }
    /* PSYS_SPRING_ORDER=0 keeps the particles' own order */
    psys_system_destroy(b);
    setenv("PSYS_SPRING_ORDER", "0", 1);
    b = relabelled(a, pi);
    free(generic_derivative(b, yb));
    CHECK(order_of(b) == NULL);
    unsetenv("PSYS_SPRING_ORDER");
    free(ya);
    free(yb);
    free(pi);
    psys_system_destroy(a);
    psys_system_destroy(b);
    /* a strip of 300 columns in row order keeps it: its rows are long runs,
     * though the order of its 4-particle columns would bring springs closer */
    a = psys_system_create(3, NULL);
    add_particles(a, 3, 300 * 4, 300);
    sheet_springs(a, 0, 300, 4);
    CHECK(psys_system_spring_count(a) >= 4096);
    oa = psys_system_ode(a);
    ya = malloc(oa.size * sizeof *ya);
    oa.get_state(oa.ctx, ya);
    free(generic_derivative(a, ya));
    CHECK(order_of(a) == NULL);
    free(ya);
    psys_system_destroy(a);
}

/* The system's derivative_stage, counting the stages it computes. */
static psys_status (*system_stage)(void *ctx, double t, const double *y, const psys__stage_pass *pass);
static long stage_calls;
static psys_status counting_stage(void *ctx, double t, const double *y, const psys__stage_pass *pass)
{
    if (y)
        stage_calls++;
    return system_stage(ctx, t, y, pass);
}

/* Whole runs through every explicit solver: the same states bit for bit;
 * euler, midpoint and rk4 take every stage through derivative_stage when
 * fused (and none otherwise), so both fused paths are compared. */
static void runs_same_bits(void)
{
    static const char *const solvers[] = {"euler", "midpoint", "rk4", "rk45", "symplectic-euler", "verlet"};
    static const int chain_stages[] = {1, 2, 4, 0, 0, 0};
    for (size_t k = 0; k < sizeof solvers / sizeof *solvers; k++)
        for (int kind = 0; kind < NKINDS; kind++) {
            double *out[2] = {NULL, NULL};
            size_t size = 0;
            for (int fused = 0; fused < 2; fused++) {
                setenv("PSYS_FUSED", fused ? "1" : "0", 1);
                psys_system *s = build(kind);
                CHECK(psys_system_set_threads(s, fused ? 2 : 1) == PSYS_OK);
                psys_ode o = psys_system_ode(s);
                psys__ode_fast f = psys__system_ode_fast(s);
                system_stage = f.derivative_stage;
                f.derivative_stage = counting_stage;
                f.derivative_chain = NULL; /* stage by stage here; chain_same_bits compares the chain */
                stage_calls = 0;
                psys_solver *sv = psys__solver_create_fast(solvers[k], &o, &f, NULL, NULL);
                CHECK(sv != NULL);
                for (int step = 0; step < 10; step++) {
                    double taken;
                    CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
                }
                CHECK(stage_calls == (fused ? 10L * chain_stages[k] : 0));
                size = o.size;
                out[fused] = malloc(size * sizeof(double));
                o.get_state(o.ctx, out[fused]);
                psys_solver_destroy(sv);
                psys_system_destroy(s);
            }
            unsetenv("PSYS_FUSED");
            if (memcmp(out[0], out[1], size * sizeof(double)) != 0)
                fprintf(stderr, "%s, kind %d: fused and generic runs differ\n", solvers[k], kind);
            CHECK(memcmp(out[0], out[1], size * sizeof(double)) == 0);
            free(out[0]);
            free(out[1]);
        }
}

/* A rope of n particles with a spring to the third neighbour every fifth
 * particle (offsets 1 and 3), gravity and drag: long enough for several
 * threads' ranges in the chain sweep. */
static psys_system *rope(size_t n, int dim)
{
    const double g3[3] = {0.3, -9.81, 0.2};
    lcg = 777;
    psys_system *s = psys_system_create(dim, NULL);
    add_particles(s, dim, n, 1000);
    CHECK(psys_system_add_drag(s, 0.2) == PSYS_OK);
    for (size_t i = 0; i + 1 < n; i++) {
        spring(s, i, i + 1);
        if (i % 5 == 0 && i + 3 < n)
            spring(s, i + 3, i);
    }
    CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
    CHECK(psys_system_set_fixed(s, n / 2, true) == PSYS_OK);
    return s;
}

/* n particles in rows of 85 with springs (i, i + off) for every i but those
 * 254 past a multiple of 256, gravity and drag: each block of 256 first
 * ends has a last run from its slot 255 on, 255 springs into the next
 * block, the farthest a run can reach past its block (chain_reach in
 * fast/fused.c). With off 512 that run reaches 1,022 past its block's
 * start, beyond the window's 1,024 slots less the block before: the
 * sweep cannot hold that block's leavings back (exitq) and leaves them
 * at once. With off 85, on one thread rk4's last stage, 3 · 597 particles
 * behind the first, sweeps up to one past a block's start (the first
 * advances 1,024 at a time), so a run there reaches within 3
 * particles of what the stage before has left, and rounding its entry up
 * to a granule of 64 would read beyond: the sweep must stop at its reach. */
static psys_system *reach_edge(size_t n, size_t off)
{
    const double g3[3] = {0.1, -9.81, 0.3};
    lcg = 4242;
    psys_system *s = psys_system_create(3, NULL);
    add_particles(s, 3, n, 85);
    CHECK(psys_system_add_drag(s, 0.2) == PSYS_OK);
    for (size_t i = 0; i + off < n; i++)
        if (i % 256 != 254)
            spring(s, i, i + off);
    CHECK(psys_system_add_gravity(s, g3) == PSYS_OK);
    return s;
}

/* The system's derivative_chain, counting the steps it takes. */
static psys_status (*system_chain)(void *ctx, double t, const double *y0, int stages, const double *c,
                                   const psys__stage_pass *pass);
static long chain_calls;
static psys_status counting_chain(void *ctx, double t, const double *y0, int stages, const double *c,
                                  const psys__stage_pass *pass)
{
    if (y0)
        chain_calls++;
    return system_chain(ctx, t, y0, stages, c, pass);
}

/* The same for derivative_chain_current (the chain from the system's state
 * where it is); chain_current_calls counts the steps it takes. */
static psys_status (*system_chain_current)(void *ctx, double t, int stages, const double *c,
                                           const psys__stage_pass *pass);
static long chain_current_calls;
static psys_status counting_chain_current(void *ctx, double t, int stages, const double *c,
                                          const psys__stage_pass *pass)
{
    psys_status st = system_chain_current(ctx, t, stages, c, pass);
    if (st == PSYS_OK) {
        chain_calls++;
        chain_current_calls++;
    }
    return st;
}

/* A solver for s with the system's fast paths, its chain callbacks
 * counted; current: derivative_chain_current kept (else NULL: the solver
 * copies the state for derivative_chain). No owner, as for any replaced
 * callback: the state stays in the particles' order. */
static psys_solver *counting_chains(const char *name, psys_system *s, bool current)
{
    const psys_ode o = psys_system_ode(s);
    psys__ode_fast f = psys__system_ode_fast(s);
    system_chain = f.derivative_chain;
    system_chain_current = f.derivative_chain_current;
    f.derivative_chain = counting_chain;
    f.derivative_chain_current = current ? counting_chain_current : NULL;
    chain_calls = chain_current_calls = 0;
    return psys__solver_create_fast(name, &o, &f, NULL, NULL);
}

/* Whether the system's derivative_chain would take a step of s of that many stages. */
static psys_status chain_asked(psys_system *s, int stages)
{
    return psys__system_ode_fast(s).derivative_chain(s, 0, NULL, stages, NULL, NULL);
}

/* A copy of o's state (*size components). */
static double *ode_state(const psys_ode *o, size_t *size)
{
    *size = o->size;
    double *y = malloc(*size * sizeof(double));
    CHECK(y != NULL);
    o->get_state(o->ctx, y);
    return y;
}

/* A 2-D sheet of nx × ny particles with gravity and drag. */
static psys_system *sheet_2d(int nx, int ny)
{
    const double g2[2] = {0.2, -9.81};
    lcg = 4242;
    psys_system *s = psys_system_create(2, NULL);
    add_particles(s, 2, (size_t)nx * (size_t)ny, nx);
    CHECK(psys_system_add_gravity(s, g2) == PSYS_OK);
    sheet_springs(s, 0, nx, ny);
    CHECK(psys_system_add_drag(s, 0.1) == PSYS_OK);
    CHECK(psys_system_set_fixed(s, 0, true) == PSYS_OK);
    return s;
}

/* rk4 and midpoint steps with every stage swept together (derivative_chain)
 * against stage by stage (PSYS_CHAIN=0) and against the generic path
 * (PSYS_FUSED=0; with AVX-512, 3-D systems' stage work is held back into
 * the run loops on the fused paths): the same bits, for 1 to 4
 * threads (the rope's ranges at 3 and 4 threads, trapezoids and the
 * patches between them) and for a system with muscles or controlled
 * particles, which the chain leaves to the stages. The ropes (3-D, 2-D) and
 * the 2-D sheet are long enough for the stage states to go through rings
 * (fast/fused.c, stage_rings): on 1 to 3 threads for the ropes, 1 for
 * the sheet; reach_edge has runs that reach as far as a sweep may read
 * (with offset 512, too far to hold a block's leavings back). The chain
 * reads the step's start from the system's own x and v
 * (derivative_chain_current), or from the solver's copy where that
 * callback is dropped (where it declines, the state in the springs' order:
 * state_order_same_bits). */
static void chain_same_bits(void)
{
    static const char *const solvers[] = {"midpoint", "rk4"};
    for (size_t k = 0; k < 2; k++)
        for (int kind = 0; kind <= NKINDS + 4; kind++) {
            double *want = NULL;
            size_t size = 0;
            /* 0: stage by stage; 1..4: the chain on 1..4 threads; 5, 6: the
             * chain from the solver's copy of the state on 1 and 3 threads;
             * 7: the generic path */
            for (int run = 0; run < 8; run++) {
                setenv("PSYS_FUSED", run == 7 ? "0" : "1", 1);
                setenv("PSYS_CHAIN", run == 0 ? "0" : "1", 1);
                psys_system *s = kind == NKINDS       ? rope(30000, 3)
                                 : kind == NKINDS + 1 ? rope(30000, 2)
                                 : kind == NKINDS + 2 ? sheet_2d(100, 160)
                                 : kind == NKINDS + 3 ? reach_edge(30000, 85)
                                 : kind == NKINDS + 4 ? reach_edge(30000, 512)
                                                      : build(kind);
                const int threads = run == 0 || run == 7 ? 1 : run <= 4 ? run : run == 5 ? 1 : 3;
                CHECK(psys_system_set_threads(s, threads) == PSYS_OK);
                psys_ode o = psys_system_ode(s);
                psys_solver *sv = counting_chains(solvers[k], s, run <= 4);
                CHECK(sv != NULL);
                for (int step = 0; step < 6; step++) {
                    double taken;
                    CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
                }
                /* muscles (CHAIN_GAPS_2D) depend on the stage time: never chained */
                const bool chained = run > 0 && run < 7 && kind != CHAIN_GAPS_2D;
                CHECK(chain_calls == (chained ? 6 : 0));
                CHECK(chain_current_calls == (chained && run <= 4 ? 6 : 0));
                double *got = ode_state(&o, &size);
                if (run == 0) {
                    want = got;
                } else {
                    CHECK(same_bits(got, want, size, "%s, kind %d, run %d, y against run 0 (stage by stage, fused)",
                                    solvers[k], kind, run));
                    free(got);
                }
                psys_solver_destroy(sv);
                psys_system_destroy(s);
            }
            unsetenv("PSYS_FUSED");
            unsetenv("PSYS_CHAIN");
            free(want);
        }
    /* By default the chain for springs reaching at most 600 particles: the
     * rope (offset 3 + 512); a sheet of 300 columns (600 + 512) gets it by
     * timing (chain_timed): the first step asked about is the chain's, the
     * second stage by stage's; PSYS_CHAIN=1 always takes it. */
    psys_system *s = rope(3000, 3);
    CHECK(chain_asked(s, 4) == PSYS_OK);
    psys_system_destroy(s);
    s = psys_system_create(3, NULL);
    add_particles(s, 3, 300 * 4, 300);
    sheet_springs(s, 0, 300, 4);
    CHECK(chain_asked(s, 4) == PSYS_OK);
    CHECK(chain_asked(s, 4) == PSYS_ERR_UNSUPPORTED);
    setenv("PSYS_CHAIN", "1", 1);
    CHECK(chain_asked(s, 4) == PSYS_OK);
    unsetenv("PSYS_CHAIN");
    psys_system_destroy(s);
    /* controlled particles: left to the stages (the projection) */
    setenv("PSYS_CHAIN", "1", 1);
    s = build(SHEET);
    CHECK(chain_asked(s, 4) == PSYS_OK);
    const double centre[3] = {0, 0, 0}, dir[3] = {1, 0, 0};
    CHECK(psys_system_control_oscillate(s, 7, centre, dir, 0.1, 3.0, 0) == PSYS_OK);
    CHECK(chain_asked(s, 4) == PSYS_ERR_UNSUPPORTED);
    unsetenv("PSYS_CHAIN");
    psys_system_destroy(s);
}

/* Springs reaching beyond 600 particles: the first six rk4 steps time the
 * chain (odd steps) against stage by stage (even ones), and the one whose
 * fastest step was faster takes every later step; psys__system_timing_settled
 * turns true with the choice and false again when the particle count,
 * the springs or the thread count change. The same bits as stage by stage throughout. PSYS_CHAIN=0 or 1
 * times nothing. A step's time runs to the next step, so 50 ms spent by
 * the caller after every chain step (or every other) must make the other
 * mode win. */
static void chain_timed(void)
{
    double *want = NULL;
    size_t size = 0;
    /* 0: PSYS_CHAIN=0; 1: timed; 2: PSYS_CHAIN=1; 3, 4: timed, the caller
     * slow after the chain's steps (3) or the stages' (4) */
    for (int run = 0; run < 5; run++) {
        const bool timed = run == 1 || run >= 3;
        if (!timed)
            setenv("PSYS_CHAIN", run == 0 ? "0" : "1", 1);
        psys_system *s = rope(3000, 3);
        spring(s, 0, 700); /* reach 700 + 512 */
        psys_ode o = psys_system_ode(s);
        psys_solver *sv = counting_chains("rk4", s, true);
        CHECK(sv != NULL);
        CHECK(psys__fused_chain_pick(s) == -1);
        long calls_before_choice = 0;
        for (int step = 1; step <= 12; step++) {
            double taken;
            CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
            /* asked at step 7 after six timed steps, the choice is made */
            CHECK(psys__system_timing_settled(s) == (!timed || step >= 7));
            CHECK((psys__fused_chain_pick(s) >= 0) == (timed && step >= 7));
            if (step == 6)
                calls_before_choice = chain_calls;
            if (run >= 3 && step <= 6 && step % 2 == (run == 3 ? 1 : 0)) {
                const struct timespec pause = {0, 50000000};
                nanosleep(&pause, NULL);
            }
        }
        if (timed) {
            const int pick = psys__fused_chain_pick(s);
            CHECK(calls_before_choice == 3);
            CHECK(chain_calls == 3 + 6 * pick);
            if (run >= 3)
                CHECK(pick == (run == 3 ? 0 : 1));
        } else {
            CHECK(chain_calls == (run == 2 ? 12 : 0));
        }
        double *got = ode_state(&o, &size);
        if (run == 0) {
            want = got;
        } else {
            CHECK(memcmp(got, want, size * sizeof(double)) == 0);
            free(got);
        }
        if (run == 1) { /* a new particle, a new spring, another thread count: timed again */
            for (int change = 0; change < 3; change++) {
                for (int step = 0; step < 7; step++) { /* settled again first */
                    double taken;
                    CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
                }
                CHECK(psys__system_timing_settled(s));
                if (change == 0) {
                    const double p[3] = {0, 0, 0}, v[3] = {0, 0, 0};
                    CHECK(psys_system_add_particle(s, p, v, 1.0, NULL, NULL) == PSYS_OK);
                } else if (change == 1) {
                    spring(s, 1, 702);
                } else {
                    CHECK(psys_system_set_threads(s, psys_system_effective_threads(s) == 1 ? 2 : 1) == PSYS_OK);
                }
                psys_solver_destroy(sv);
                o = psys_system_ode(s);
                sv = psys_system_solver_create(s, "rk4", NULL);
                double taken;
                CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
                CHECK(!psys__system_timing_settled(s));
                CHECK(psys__fused_chain_pick(s) == -1);
            }
        }
        unsetenv("PSYS_CHAIN");
        psys_solver_destroy(sv);
        psys_system_destroy(s);
    }
    free(want);
}

/* The state of s (positions, then velocities), copied. */
static double *state_of(const psys_system *s)
{
    const size_t nd = 3 * psys_system_count(s);
    double *y = malloc(2 * nd * sizeof *y);
    memcpy(y, psys_system_positions(s), nd * sizeof *y);
    memcpy(y + nd, psys_system_velocities(s), nd * sizeof *y);
    return y;
}

/* A step of psys_system_advance on a mesh numbered out of order holds the
 * solver's state in the springs' order (psys__state_order_begin): the same
 * bits as in the particles' order (PSYS_STATE_ORDER=0) for every
 * elementwise solver, stage by stage, chained (variant 1) and with
 * controlled particles (variant 2: the projection finds their slots), on 1
 * to 3 threads; rk45 (its error norm sums over the state), a mesh in its
 * own order, a solver of the caller's on the system's ODE and a solver made
 * for another system keep the particles' order; and a step that blows up
 * names the same component either way. */
static void state_order_same_bits(void)
{
    static const char *const solvers[] = {"euler", "midpoint", "rk4", "symplectic-euler", "verlet", "rk45"};
    const size_t nsolvers = sizeof solvers / sizeof *solvers;
    const double centre[3] = {0, 0, 0}, dir[3] = {1, 0, 0}, centre2[3] = {1, 0.5, 0}, dir2[3] = {0, 1, 1};
    for (size_t k = 0; k < nsolvers; k++)
        for (int variant = 0; variant < 3; variant++) {
            const int chain = variant == 1;
            if (chain && strcmp(solvers[k], "midpoint") != 0 && strcmp(solvers[k], "rk4") != 0)
                continue;
            double *want = NULL;
            for (int run = 0; run < 4; run++) { /* 0: the particles' order; 1..3: the springs', 1..3 threads */
                setenv("PSYS_FUSED", "1", 1);  /* small sets threaded too */
                setenv("PSYS_CHAIN", chain ? "1" : "0", 1);
                setenv("PSYS_STATE_ORDER", run == 0 ? "0" : "1", 1);
                psys_system *s = build(SHEET_SHUFFLED);
                CHECK(psys_system_set_threads(s, run == 0 ? 1 : run) == PSYS_OK);
                if (variant == 2) {
                    CHECK(psys_system_control_oscillate(s, 7, centre, dir, 0.1, 3.0, 0) == PSYS_OK);
                    CHECK(psys_system_control_oscillate(s, 2000, centre2, dir2, 0.2, 5.0, 1) == PSYS_OK);
                }
                psys_solver *sv = psys_system_solver_create(s, solvers[k], NULL);
                CHECK(sv != NULL);
                CHECK(psys__state_order_begin(s, sv) == (run > 0 && k + 1 < nsolvers));
                psys__state_order_end(s);
                for (int step = 0; step < 8; step++)
                    CHECK(psys_system_advance(s, sv, 1e-4, NULL) == PSYS_OK);
                CHECK(s->ode_perm == NULL); /* back in the particles' order after each step */
                double *got = state_of(s);
                const size_t size = 6 * psys_system_count(s);
                if (run == 0) {
                    want = got;
                } else {
                    CHECK(same_bits(got, want, size, "%s, variant %d, %d threads, y against the particles' order",
                                    solvers[k], variant, run));
                    free(got);
                }
                psys_solver_destroy(sv);
                psys_system_destroy(s);
            }
            free(want);
        }
    unsetenv("PSYS_FUSED");
    unsetenv("PSYS_CHAIN");
    unsetenv("PSYS_STATE_ORDER");

    /* where it stays in the particles' order */
    psys_system *s = build(SHEET); /* numbered in rows: no internal order */
    psys_solver *sv = psys_system_solver_create(s, "rk4", NULL);
    CHECK(!psys__state_order_begin(s, sv));
    psys_solver_destroy(sv);
    psys_system_destroy(s);
    s = build(SHEET_SHUFFLED);
    sv = psys_system_solver_create(s, "rk4", NULL);
    CHECK(psys__state_order_begin(s, sv));
    psys__state_order_end(s);
    psys_solver_destroy(sv);
    psys_ode o = psys_system_ode(s);
    sv = psys_solver_create("rk4", &o, NULL); /* the caller's solver: no fast paths, no owner */
    CHECK(!psys__state_order_begin(s, sv));
    psys_solver_destroy(sv);
    psys_system *other = build(SHEET_SHUFFLED);
    sv = psys_system_solver_create(other, "rk4", NULL); /* made for another system of the same size */
    CHECK(!psys__state_order_begin(s, sv));
    CHECK(psys__state_order_begin(other, sv));
    psys__state_order_end(other);
    psys_solver_destroy(sv);
    psys_system_destroy(other);
    psys_system_destroy(s);

    /* a blow-up (steps far beyond the springs' stability limit): the same
     * step and the same first non-finite component, as users number them */
    size_t bad_at[2] = {0, 0}, bad_step[2] = {0, 0};
    for (int run = 0; run < 2; run++) {
        setenv("PSYS_STATE_ORDER", run == 0 ? "0" : "1", 1);
        s = build(SHEET_SHUFFLED);
        sv = psys_system_solver_create(s, "rk4", NULL);
        psys_status st = PSYS_OK;
        size_t step = 0;
        while (st == PSYS_OK && step < 2000) {
            st = psys_system_advance(s, sv, 2.0, NULL);
            step++;
        }
        CHECK(st == PSYS_ERR_NONFINITE);
        bad_at[run] = psys_solver_bad_component(sv);
        bad_step[run] = step;
        psys_solver_destroy(sv);
        psys_system_destroy(s);
    }
    unsetenv("PSYS_STATE_ORDER");
    CHECK(bad_step[0] == bad_step[1]);
    CHECK(bad_at[0] == bad_at[1]);
    CHECK(bad_at[0] < 6 * 70 * 45);
}

/* One run of state_order_cache: steps of rk4 between changes to what the
 * state order keeps from step to step (masses and fixedness in slot order,
 * the controlled particles' slots), on a shuffled sheet; the final state. */
static double *changes_run(bool ordered)
{
    setenv("PSYS_STATE_ORDER", ordered ? "1" : "0", 1);
    psys_system *s = build(SHEET_SHUFFLED);
    psys_ode o = psys_system_ode(s);
    psys_solver *sv = NULL;
    const double centre[3] = {0.2, 0.1, 0}, dir[3] = {0, 0, 1}, target[3] = {1, 1, 1};
    const double x[3] = {0.5, 0.5, 0.3}, v[3] = {0, 0, 0};
    const size_t n = psys_system_count(s);
    for (int phase = 0; phase < 11; phase++) {
        switch (phase) {
        case 1: /* inv_mass 0 at one particle */
            CHECK(psys_system_set_fixed(s, 100, true) == PSYS_OK);
            break;
        case 2: /* a controlled particle: its inv_mass and the projection's slot map */
            CHECK(psys_system_control_oscillate(s, 7, centre, dir, 0.1, 3.0, 0) == PSYS_OK);
            break;
        case 3:
            CHECK(psys_system_release(s, 7) == PSYS_OK);
            break;
        case 4:
            CHECK(psys_system_set_fixed(s, 100, false) == PSYS_OK);
            break;
        case 5: /* a new spring: a new plan and order */
            spring(s, 11, 2222);
            break;
        case 6: /* a particle with no springs (a slot past the order's) */
            CHECK(psys_system_add_particle(s, x, v, 3.5, NULL, NULL) == PSYS_OK);
            break;
        case 7: /* removed from the end, and another at its index, the arrays long enough */
            psys__system_truncate(s, n);
            break;
        case 8:
            CHECK(psys_system_add_particle(s, x, v, 0.7, NULL, NULL) == PSYS_OK);
            break;
        case 9: /* a mouse spring (the generic path while it is there), then gone */
            CHECK(psys_system_add_mouse_spring(s, 300, target, 20, 1, NULL) == PSYS_OK);
            CHECK(psys_system_remove_force(s, psys_system_force_count(s) - 1) == PSYS_OK);
            break;
        case 10: { /* the spring set replaced by one as long (the same plan version) with other ends */
            const size_t ns = psys_system_spring_count(s);
            CHECK(psys_system_remove_force(s, 2) == PSYS_OK);
            for (size_t k = 0; k < ns; k++)
                spring(s, (k * 37) % n, (k * 37 + 1 + k % 5) % n);
            break;
        }
        }
        if (phase == 0 || psys_system_count(s) != o.size / 6) { /* a new system size, a new solver */
            psys_solver_destroy(sv);
            o = psys_system_ode(s);
            sv = psys_system_solver_create(s, "rk4", NULL);
            CHECK(sv != NULL);
        }
        for (int step = 0; step < 3; step++)
            CHECK(psys_system_advance(s, sv, 1e-4, NULL) == PSYS_OK);
    }
    double *y = state_of(s);
    psys_solver_destroy(sv);
    psys_system_destroy(s);
    unsetenv("PSYS_STATE_ORDER");
    return y;
}

/* The masses and slots in the springs' order are kept from step to step
 * and gathered again after any change to them: the same bits as the
 * particles' order through changes of every kind, and no gather while
 * nothing changed. */
static void state_order_cache(void)
{
    double *want = changes_run(false), *got = changes_run(true);
    CHECK(same_bits(got, want, 6 * (70 * 45 + 1), "after changes, y against the particles' order"));
    free(want);
    free(got);

    psys_system *s = build(SHEET_SHUFFLED);
    psys_solver *sv = psys_system_solver_create(s, "rk4", NULL);
    CHECK(psys__state_order_begin(s, sv));
    psys__state_order_end(s);
    const double m0 = s->ode_mass[0];
    s->ode_mass[0] = -1; /* kept: nothing changed */
    CHECK(psys__state_order_begin(s, sv));
    psys__state_order_end(s);
    CHECK(s->ode_mass[0] == -1);
    CHECK(psys_system_set_fixed(s, 3, false) == PSYS_OK); /* a change, even one that changes nothing */
    CHECK(psys__state_order_begin(s, sv));
    psys__state_order_end(s);
    CHECK(s->ode_mass[0] == m0);
    psys_solver_destroy(sv);
    psys_system_destroy(s);
}

static bool takes(psys_system *s)
{
    psys_ode o = psys_system_ode(s);
    double *y = malloc(o.size * sizeof *y), *ydot = malloc(o.size * sizeof *ydot);
    o.get_state(o.ctx, y);
    psys_force_eval e;
    psys__sys_eval(s, psys_system_time(s), y, y + o.size / 2, &e);
    bool used = true;
    CHECK(psys__fused_derivative(s, &e, y, ydot, NULL, &used) == PSYS_OK);
    free(y);
    free(ydot);
    return used;
}

/* A 60 × 50 sheet on planes (notes §7.3 contact forces), drag after the
 * springs. 3-D: the ground z = 0 under every particle (z = 0, v_z = 0,
 * gravity pressing it down), a sticky wall x = 0 at the first column and a
 * wall y = 0 with directional friction at the first row, which meets the
 * ground; row 10 starts just above the ground falling onto it (collisions
 * within the first step). 2-D: the sheet stands on the ground y = 0 by its
 * first row, beside the sticky wall. One particle fixed; sliding
 * velocities, so friction acts. */
static psys_system *on_planes(int dim, bool shuffle, size_t *probe)
{
    lcg = 777;
    psys_system *s = psys_system_create(dim, NULL);
    const size_t nx = 60, ny = 50, n = nx * ny;
    double (*x)[3] = calloc(n, sizeof *x), (*v)[3] = calloc(n, sizeof *v), *m = calloc(n, sizeof *m);
    for (size_t i = 0; i < n; i++) {
        const size_t r = i / nx, c = i % nx;
        x[i][0] = c == 0 ? 0.0 : 0.1 * (double)c + 0.01 * rnd();
        x[i][1] = r == 0 ? 0.0 : 0.1 * (double)r + 0.01 * rnd();
        v[i][0] = c == 0 ? 0.0 : rnd() - 0.5;
        v[i][1] = r == 0 ? 0.0 : rnd() - 0.5;
        if (dim == 3 && r == 10) {
            x[i][2] = 2e-4;
            v[i][2] = -1.0;
        }
        m[i] = 0.5 + rnd();
    }
    /* shuffle: grid point i is particle pi[i] (the springs then get an
     * internal order: the fused path's gathering window, leave_perm) */
    size_t *pi = shuffled(n), *inv = malloc(n * sizeof *inv);
    for (size_t i = 0; i < n; i++) {
        if (!shuffle)
            pi[i] = i;
        inv[pi[i]] = i;
    }
    for (size_t q = 0; q < n; q++)
        CHECK(psys_system_add_particle(s, x[inv[q]], v[inv[q]], m[inv[q]], NULL, NULL) == PSYS_OK);
    *probe = pi[10 * nx + 5]; /* in the falling row */
    /* 2-D: gravity strong enough to hold the first row down against the springs */
    const double g[3] = {0.2, 0.1, -9.81}, g2[2] = {0.2, -300};
    CHECK(psys_system_add_gravity(s, dim == 3 ? g : g2) == PSYS_OK);
    spring_map = pi;
    sheet_springs(s, 0, (int)nx, (int)ny);
    spring_map = NULL;
    CHECK(psys_system_add_drag(s, 0.2) == PSYS_OK);
    CHECK(psys_system_set_fixed(s, pi[1234], true) == PSYS_OK);
    free(x), free(v), free(m), free(pi), free(inv);
    psys_plane_def ground = psys_plane_def_default(), wall = psys_plane_def_default(),
                   scales = psys_plane_def_default();
    ground.normal[0] = 0, ground.normal[1] = dim == 3 ? 0 : 1, ground.normal[2] = dim == 3 ? 1 : 0;
    ground.friction = 0.4;
    wall.normal[0] = 1, wall.normal[1] = 0, wall.normal[2] = 0;
    wall.stick = true;
    scales.normal[0] = 0, scales.normal[1] = 1, scales.normal[2] = 0;
    scales.friction = 0.1;
    scales.backward_friction = 0.9;
    scales.forward[0] = 1;
    CHECK(psys_system_add_plane(s, &ground) == PSYS_OK);
    CHECK(psys_system_add_plane(s, &wall) == PSYS_OK);
    if (dim == 3)
        CHECK(psys_system_add_plane(s, &scales) == PSYS_OK);
    return s;
}

/* Planes' contact forces on the fused path (psys__contact_rows, as each
 * particle leaves the window, in the particles' order or gathered in the
 * springs' internal one): the generic path's derivative bit for bit on 1 to
 * 3 threads, with the ground holding particles up (their vertical
 * acceleration exactly 0); and steps through psys_system_advance (contact
 * forces in every stage, collisions re-integrating part steps): the
 * generic path's states stage by stage and by the chain, on 1 and 2
 * threads, bit for bit. */
static void planes_same_bits(void)
{
    for (int k = 0; k < 4; k++) {
        const int dim = k % 2 ? 3 : 2;
        const bool shuffle = k >= 2;
        size_t probe;
        psys_system *s = on_planes(dim, shuffle, &probe);
        psys_ode o = psys_system_ode(s);
        double *y = malloc(o.size * sizeof *y);
        o.get_state(o.ctx, y);
        double *want = generic_derivative(s, y);
        CHECK((order_of(s) != NULL) == shuffle); /* the gathering window where shuffled */
        const size_t n = psys_system_count(s), up = (size_t)dim - 1;
        size_t held = 0;
        for (size_t i = 0; i < n; i++)
            held += want[o.size / 2 + i * (size_t)dim + up] == 0.0;
        /* 3-D: all but the falling row (the fixed particle's ydot is 0
         * anyway); 2-D: the first row, standing on the ground, and the
         * fixed particle */
        CHECK(held == (dim == 3 ? n - 60 : 60 + 1));
        for (int threads = 1; threads <= 3; threads++) {
            double *got = fused_derivative(s, y, threads);
            CHECK(same_bits(got, want, o.size, "%d-D%s, %d threads, ydot against the generic path", dim,
                            shuffle ? " shuffled" : "", threads));
            free(got);
        }
        free(want);
        free(y);
        psys_system_destroy(s);

        double *first = NULL;
        size_t size = 0;
        for (int run = 0; run < 4; run++) {
            setenv("PSYS_FUSED", run == 0 ? "0" : "1", 1);
            setenv("PSYS_CHAIN", run <= 1 ? "0" : "1", 1);
            s = on_planes(dim, shuffle, &probe);
            CHECK(psys_system_set_threads(s, run == 3 ? 2 : 1) == PSYS_OK);
            psys_ode so = psys_system_ode(s);
            psys_solver *sv = psys_system_solver_create(s, "rk4", NULL);
            CHECK(sv != NULL);
            for (int step = 0; step < 8; step++) {
                double taken;
                CHECK(psys_system_advance(s, sv, 1e-3, &taken) == PSYS_OK);
            }
            double *got = ode_state(&so, &size);
            if (run == 0) {
                first = got;
                /* the falling row hit the ground and bounced (restitution 0.5) */
                CHECK(dim == 2 || got[size / 2 + probe * 3 + 2] > 0.3);
            } else {
                CHECK(same_bits(got, first, size, "%d-D%s, run %d, y against the generic path", dim,
                                shuffle ? " shuffled" : "", run));
                free(got);
            }
            psys_solver_destroy(sv);
            psys_system_destroy(s);
        }
        unsetenv("PSYS_FUSED");
        unsetenv("PSYS_CHAIN");
        free(first);
    }
}

/* Pair forces and forces without row kernels go the generic way;
 * without PSYS_FUSED, small systems too (their state stays in cache). */
static void chooses_path(void)
{
    unsetenv("PSYS_FUSED");
    psys_system *s = build(SHEET);
    CHECK(takes(s)); /* 3,150 particles: fused by default at every size */
    setenv("PSYS_FUSED", "1", 1);
    CHECK(takes(s));
    const double target[3] = {1, 2, 3};
    CHECK(psys_system_add_mouse_spring(s, 5, target, 10, 1, NULL) == PSYS_OK);
    CHECK(!takes(s));
    psys_system_destroy(s);

    s = build(SHEET); /* planes: their contact forces as particles leave (planes_same_bits) */
    psys_plane_def pd = psys_plane_def_default();
    CHECK(psys_system_add_plane(s, &pd) == PSYS_OK);
    CHECK(takes(s));
    psys_system_destroy(s);

    s = build(SHEET);
    psys_pair_def pair = psys_pair_def_default();
    CHECK(psys_system_add_pair(s, &pair, NULL) == PSYS_OK);
    CHECK(!takes(s));
    psys_system_destroy(s);

    setenv("PSYS_FUSED", "0", 1);
    s = build(BIG_SHEET);
    CHECK(!takes(s));
    psys_system_destroy(s);

    unsetenv("PSYS_FUSED"); /* a large system: fused by default */
    s = psys_system_create(3, NULL);
    add_particles(s, 3, 40000, 1000);
    for (size_t i = 0; i + 1 < 40000; i++)
        CHECK(psys_system_add_spring(s, i, i + 1, 10, 0, 0.1) == PSYS_OK);
    CHECK(takes(s));
    psys_system_destroy(s);
}

/* The AVX-512 run loops run exactly where the CPU has AVX-512F, unless
 * PSYS_SPRING_PLAIN=1 asks for the compiler's loops (which the suite's
 * PSYS_SPRING_PLAIN variants rely on to test both). */
static void avx512_switch(void)
{
    const char *was = getenv("PSYS_SPRING_PLAIN");
    char *keep = was ? strdup(was) : NULL;
    unsetenv("PSYS_SPRING_PLAIN");
#if SPRING_AVX512
    const bool cpu = __builtin_cpu_supports("avx512f") != 0;
#else
    const bool cpu = false;
#endif
    /* read when a system is created, and kept by it */
    psys_system *unset = psys_system_create(3, NULL);
    CHECK(psys__springs_avx512(unset) == cpu);
    setenv("PSYS_SPRING_PLAIN", "0", 1);
    psys_system *zero = psys_system_create(3, NULL);
    CHECK(psys__springs_avx512(zero) == cpu);
    setenv("PSYS_SPRING_PLAIN", "1", 1);
    psys_system *plain = psys_system_create(3, NULL);
    CHECK(!psys__springs_avx512(plain));
    CHECK(psys__springs_avx512(unset) == cpu);
    psys_system_destroy(unset);
    psys_system_destroy(zero);
    psys_system_destroy(plain);
    if (keep)
        setenv("PSYS_SPRING_PLAIN", keep, 1);
    else
        unsetenv("PSYS_SPRING_PLAIN");
    free(keep);
}

/* Blocks held back (psys__fused_held) after two rk4 steps of s, stage by
 * stage or by the chain; s destroyed. */
static size_t held_after_steps(psys_system *s, bool chain)
{
    setenv("PSYS_CHAIN", chain ? "1" : "0", 1);
    psys_solver *sv = psys_system_solver_create(s, "rk4", NULL);
    CHECK(sv != NULL);
    for (int step = 0; step < 2; step++) {
        double taken;
        CHECK(psys_solver_step(sv, 1e-4, &taken) == PSYS_OK);
    }
    const size_t held = psys__fused_held(s);
    psys_solver_destroy(sv);
    psys_system_destroy(s);
    unsetenv("PSYS_CHAIN");
    return held;
}

/* Which systems hold a block's leavings back into the AVX-512 run loops
 * (fast/fused.c, holds_back): 3-D ones of at least 32,768 particles by
 * default, any size with PSYS_FUSED=1; never 2-D ones, ones with planes,
 * blocks whose runs reach too far (reach_edge with offset 512), or the
 * compiler's loops (PSYS_SPRING_PLAIN=1). A speed choice only (the same
 * bits either way, chain_same_bits), so only counted here. */
static void holds_back_where_large(void)
{
    const char *was = getenv("PSYS_SPRING_PLAIN");
    char *keep = was ? strdup(was) : NULL;
    unsetenv("PSYS_SPRING_PLAIN");
    unsetenv("PSYS_FUSED");
    psys_system *probe = psys_system_create(3, NULL);
    const bool k512 = psys__springs_avx512(probe);
    psys_system_destroy(probe);
    for (int chain = 0; chain < 2; chain++) {
        CHECK((held_after_steps(rope(40000, 3), chain) > 0) == k512);
        CHECK(held_after_steps(rope(30000, 3), chain) == 0);
        CHECK(held_after_steps(rope(40000, 2), chain) == 0);
        CHECK(held_after_steps(reach_edge(40000, 512), chain) == 0);
        psys_system *s = rope(40000, 3);
        psys_plane_def ground = psys_plane_def_default();
        ground.point[1] = -100; /* far below: the plane is there, no contact */
        CHECK(psys_system_add_plane(s, &ground) == PSYS_OK);
        CHECK(held_after_steps(s, chain) == 0);
        setenv("PSYS_FUSED", "1", 1);
        CHECK((held_after_steps(rope(30000, 3), chain) > 0) == k512);
        CHECK((held_after_steps(rope(300, 3), chain) > 0) == k512);
        unsetenv("PSYS_FUSED");
        setenv("PSYS_SPRING_PLAIN", "1", 1);
        CHECK(held_after_steps(rope(40000, 3), chain) == 0);
        unsetenv("PSYS_SPRING_PLAIN");
    }
    if (keep)
        setenv("PSYS_SPRING_PLAIN", keep, 1);
    free(keep);
}

/* The answers of the system's sweeps to psys__stage_pass.finite, counted by
 * wrappers of derivative_chain and derivative_stage: [0] "not finite", [1]
 * "finite", [2] none given on a pass that asked; and the steps whose
 * result went straight into the state (psys__stage_pass.in_place). */
static long finite_answers[3], in_place_steps;
static void count_answer(const psys__stage_pass *pass, int stages)
{
    for (int i = 0; i < stages; i++) {
        if (pass[i].finite)
            finite_answers[*pass[i].finite == -1 ? 2 : *pass[i].finite == 1]++;
        if (pass[i].in_place && *pass[i].in_place == 1)
            in_place_steps++;
    }
}
static psys_status answering_chain(void *ctx, double t, const double *y0, int stages, const double *c,
                                   const psys__stage_pass *pass)
{
    psys_status st = system_chain(ctx, t, y0, stages, c, pass);
    if (y0 && st == PSYS_OK)
        count_answer(pass, stages);
    return st;
}
static psys_status answering_chain_current(void *ctx, double t, int stages, const double *c,
                                           const psys__stage_pass *pass)
{
    psys_status st = system_chain_current(ctx, t, stages, c, pass);
    if (st == PSYS_OK)
        count_answer(pass, stages);
    return st;
}
static psys_status answering_stage(void *ctx, double t, const double *y, const psys__stage_pass *pass)
{
    psys_status st = system_stage(ctx, t, y, pass);
    if (y && st == PSYS_OK)
        count_answer(pass, 1);
    return st;
}

/* A blow-up (rk4 steps far beyond the springs' stability limit) found by
 * the sweeps' own look at the result as they write it (psys__stage_pass.finite,
 * which spares the solver a pass over the state) exactly where the
 * solver's look finds it: the same step, the same first non-finite
 * component, the state of the step before kept, on every path (the plain
 * derivative, stage by stage, the chain on 1 to 4 threads, stage states in
 * rings, the springs' internal order). The sweeps must answer "finite" on
 * every step before and "not finite" on the last; with a controlled
 * particle (whose projection could change the result) they must not
 * answer. The chain writes every step's result straight into the state
 * (psys__stage_pass.in_place), the failed one too, which the solver then
 * undoes. */
static void sweeps_find_nonfinite(void)
{
    for (int kind = 0; kind < 4; kind++) {
        size_t want_step = 0, want_bad = 0, size = 0;
        double *want = NULL;
        for (int run = 0; run < 6; run++) { /* 0: plain; 1: stage by stage; 2..5: chain on 1..4 threads */
            setenv("PSYS_FUSED", run == 0 ? "0" : "1", 1);
            setenv("PSYS_CHAIN", run <= 1 ? "0" : "1", 1);
            psys_system *s = kind == 0 ? build(SHEET) : kind == 1 ? build(SHEET_SHUFFLED) : rope(30000, 3);
            if (kind == 3) /* a controlled particle: no chain, and no answer */
                CHECK(psys_system_control_oscillate(s, 7, (const double[3]){0, 0, 0}, (const double[3]){0, 0, 1},
                                                    0.1, 3.0, 0) == PSYS_OK);
            CHECK(psys_system_set_threads(s, run < 2 ? 1 : run - 1) == PSYS_OK);
            psys_ode o = psys_system_ode(s);
            psys__ode_fast f = psys__system_ode_fast(s);
            system_chain = f.derivative_chain;
            system_chain_current = f.derivative_chain_current;
            system_stage = f.derivative_stage;
            f.derivative_chain = answering_chain;
            f.derivative_chain_current = answering_chain_current;
            f.derivative_stage = answering_stage;
            psys_solver *sv = psys__solver_create_fast("rk4", &o, &f, NULL, NULL);
            CHECK(sv != NULL);
            memset(finite_answers, 0, sizeof finite_answers);
            in_place_steps = 0;
            psys_status st = PSYS_OK;
            size_t step = 0;
            double *before = NULL;
            while (st == PSYS_OK && step < 3000) {
                free(before);
                before = ode_state(&o, &size);
                double taken;
                st = psys_solver_step(sv, kind == 2 ? 0.5 : 2.0, &taken);
                step++;
            }
            CHECK(st == PSYS_ERR_NONFINITE);
            double *after = ode_state(&o, &size);
            CHECK(first_difference(after, before, size) == size); /* nothing of the failed step kept */
            free(after);
            const size_t bad = psys_solver_bad_component(sv);
            char msg[64]; /* the same report from the sweep's check as from the solver's */
            snprintf(msg, sizeof msg, "state component %zu became non-finite", bad);
            CHECK(strcmp(psys_solver_last_error(sv), msg) == 0);
            if (run == 0) {
                want_step = step;
                want_bad = bad;
                want = before;
                CHECK(finite_answers[0] + finite_answers[1] + finite_answers[2] == 0);
            } else {
                CHECK(step == want_step);
                CHECK(bad == want_bad);
                CHECK(first_difference(before, want, size) == size);
                free(before);
                CHECK(in_place_steps == (run >= 2 && kind != 3 ? (long)step : 0));
                if (kind == 3) {
                    CHECK(finite_answers[0] + finite_answers[1] == 0);
                    CHECK(finite_answers[2] == (long)step);
                } else {
                    CHECK(finite_answers[1] == (long)step - 1);
                    CHECK(finite_answers[0] == 1);
                    CHECK(finite_answers[2] == 0);
                }
            }
            psys_solver_destroy(sv);
            psys_system_destroy(s);
        }
        CHECK(want_step > 2);
        free(want);
    }
    unsetenv("PSYS_FUSED");
    unsetenv("PSYS_CHAIN");
}

static const check_case cases[] = {
    {"derivative_same_bits", derivative_same_bits},
    {"runs_same_bits", runs_same_bits},
    {"chooses_path", chooses_path},
    {"planes_same_bits", planes_same_bits},
    {"chain_same_bits", chain_same_bits},
    {"chain_timed", chain_timed},
    {"shuffled_same_physics", shuffled_same_physics},
    {"state_order_same_bits", state_order_same_bits},
    {"state_order_cache", state_order_cache},
    {"avx512_switch", avx512_switch},
    {"holds_back_where_large", holds_back_where_large},
    {"sweeps_find_nonfinite", sweeps_find_nonfinite},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
