/* psys bench: built-in benchmark cases printing one JSON line each
 * (bench/README.md explains the cases, the byte counts and the floor).
 *   cloth-N      the N×N sheet of the peer ref_cloth.c (bench/README.md#peer-programs;
 *                $PEERS) (2 m × 2 m, 1 kg,
 *                structural + shear + bend springs, two corners pinned,
 *                gravity, drag), N = 100, 256, 1024 (any N from 2 to 4096 by name), dt = 1/sqrt(17.6 ks N²);
 *                cloth-N-shuffled: the same with its particles numbered at random;
 *                cloth-N-floor: the same lying on a floor (a plane through it,
 *                friction 0.5): contact forces in every evaluation
 *   rope-1000000 a rope of 10⁶ particles (structural springs), top end pinned
 *   lj-melt      the LAMMPS LJ melt, 32,000 atoms, grid pair force, verlet
 *   nbody-4096   4096 bodies, softened gravity, direct pair sums, verlet
 * Every line carries the STREAM-triad bandwidth measured at start and the
 * case's floor: the bytes that must move per particle-step over it. */
#include "cli.h"

#include "sim/bench.h" /* private: psys__system_timing_settled */

#include <ctype.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* STREAM triad a = b + s·c over three arrays of 2^25 doubles (768 MiB in
 * all, about three times the last-level cache), one thread, best of 5, counted as
 * STREAM does: 24 bytes per element (write-allocate not counted). 0 when
 * the memory cannot be had. */
static double triad_gbs(void)
{
    const size_t n = (size_t)1 << 25;
    double *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b), *c = malloc(n * sizeof *c);
    double best = 0;
    if (a && b && c) {
        for (size_t i = 0; i < n; i++) {
            a[i] = 0;
            b[i] = 1.0;
            c[i] = 2.0;
        }
        for (int r = 0; r < 5; r++) {
            double t0 = now_seconds(), s = 1.0 + r * 1e-3;
            for (size_t i = 0; i < n; i++)
                a[i] = b[i] + s * c[i];
            double el = now_seconds() - t0;
            double gbs = 24.0 * (double)n / el * 1e-9;
            if (gbs > best)
                best = gbs;
        }
        volatile double sink = a[n / 2];
        (void)sink;
    }
    free(a);
    free(b);
    free(c);
    return best;
}

/* Bytes that must move per particle-step (DRAM traffic of an ideal fused
 * integrator when nothing stays in cache, write-allocate counted; d = 3):
 *   rk4:    4 stages × (read x0,v0 48 + read k 48 + write k 48 + its
 *           write-allocate 48) + 4 × springs + final combination 336
 *           (read y0 and 4 k = 240, write y1 48 + 48) = 4·192 + 336 + 4·32·S/n
 *   verlet: 2 evaluations × (read x,v 48 + write a 24 + 24) + the update
 *           passes (read x,v,a 72, write x,v 48 + 48; then read v,a 48,
 *           write v 24 + 24) + 2 × springs = 2·96 + 264 + 2·32·S/n
 *   other fixed-step solvers: (evaluations) × (96 + 32·S/n) + 96 + 96
 * A spring is 32 bytes (two 4-byte indices, ks, kd, rest). Pair forces
 * (lj-melt, nbody) count the particle state only: their floor is far below
 * what their arithmetic costs. */
static double floor_bytes(const char *integrator, double springs_per_particle)
{
    double sp = 32.0 * springs_per_particle;
    if (strcmp(integrator, "rk4") == 0)
        return 4 * 192.0 + 336.0 + 4 * sp;
    if (strcmp(integrator, "verlet") == 0)
        return 2 * 96.0 + 264.0 + 2 * sp;
    int evals = strcmp(integrator, "midpoint") == 0 ? 2 : 1;
    return evals * (96.0 + sp) + 192.0;
}

static int evals_per_step(const char *integrator)
{
    return strcmp(integrator, "rk4") == 0 ? 4 : strcmp(integrator, "verlet") == 0 || strcmp(integrator, "midpoint") == 0 ? 2 : 1;
}

/* Variants of the cloth-N sheet (cloth_size). */
enum { CLOTH_PLAIN, CLOTH_SHUFFLED, CLOTH_FLOOR };

/* The cloth-N sheet; CLOTH_SHUFFLED: its particles numbered in a random
 * order (a fixed Fisher–Yates shuffle: the same on every machine), as a
 * mesh exported by a tool that does not keep rows together comes;
 * CLOTH_FLOOR: lying on a floor, the plane y = 2 through it (friction 0.5),
 * so that every free particle rests in contact. */
static psys_system *build_cloth(int n, int variant)
{
    const bool shuffled = variant == CLOTH_SHUFFLED;
    const size_t np = (size_t)n * (size_t)n;
    psys_system *sys = psys_system_create(3, NULL);
    size_t *id = malloc(np * sizeof *id), *cell = malloc(np * sizeof *cell); /* cell -> particle -> cell */
    if (!sys || !id || !cell)
        goto fail;
    for (size_t c = 0; c < np; c++)
        id[c] = c;
    uint64_t lcg = 12345;
    for (size_t c = np - 1; shuffled && c > 0; c--) {
        lcg = lcg * 6364136223846793005ULL + 1442695040888963407ULL;
        size_t j = (size_t)((lcg >> 33) % (c + 1)), t = id[c];
        id[c] = id[j];
        id[j] = t;
    }
    for (size_t c = 0; c < np; c++)
        cell[id[c]] = c;
    const double h = 2.0 / (n - 1), m = 1.0 / ((double)n * n), ks = 100.0, kd = 0.01 * sqrt(ks * m);
    for (size_t q = 0; q < np; q++) {
        const int ix = (int)(cell[q] % (size_t)n), iy = (int)(cell[q] / (size_t)n);
        double x[3] = {-1.0 + ix * h, 2.0, -1.0 + iy * h};
        if (psys_system_add_particle(sys, x, NULL, m, NULL, NULL) != PSYS_OK)
            goto fail;
    }
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            size_t i = (size_t)iy * n + ix;
            psys_status st = PSYS_OK;
            if (ix + 1 < n) st |= psys_system_add_spring(sys, id[i], id[i + 1], ks, kd, -1);
            if (iy + 1 < n) st |= psys_system_add_spring(sys, id[i], id[i + n], ks, kd, -1);
            if (ix + 1 < n && iy + 1 < n) st |= psys_system_add_spring(sys, id[i], id[i + n + 1], ks, kd, -1);
            if (ix > 0 && iy + 1 < n) st |= psys_system_add_spring(sys, id[i], id[i + n - 1], ks, kd, -1);
            if (ix + 2 < n) st |= psys_system_add_spring(sys, id[i], id[i + 2], 0.2 * ks, 0.2 * kd, -1);
            if (iy + 2 < n) st |= psys_system_add_spring(sys, id[i], id[i + 2 * (size_t)n], 0.2 * ks, 0.2 * kd, -1);
            if (st != PSYS_OK)
                goto fail;
        }
    double g[3] = {0, -9.81, 0};
    if (psys_system_set_fixed(sys, id[0], true) != PSYS_OK
        || psys_system_set_fixed(sys, id[(size_t)n - 1], true) != PSYS_OK || psys_system_add_gravity(sys, g) != PSYS_OK
        || psys_system_add_drag(sys, 0.05 * m) != PSYS_OK)
        goto fail;
    if (variant == CLOTH_FLOOR) {
        psys_plane_def floor = psys_plane_def_default(); /* normal +y */
        floor.point[1] = 2.0;
        floor.friction = 0.5;
        if (psys_system_add_plane(sys, &floor) != PSYS_OK)
            goto fail;
    }
    free(id);
    free(cell);
    return sys;
fail:
    free(id);
    free(cell);
    psys_system_destroy(sys);
    return NULL;
}

/* A rope of n particles, 10 m long, 1 kg, hanging from particle 0 and
 * released horizontally; ks = 100 N/m per segment. dt = 1/sqrt(4 ks/m). */
static psys_system *build_rope(size_t n, double *dt)
{
    psys_system *sys = psys_system_create(3, NULL);
    if (!sys)
        return NULL;
    const double len = 10.0, m = 1.0 / (double)n, ks = 100.0 * (double)n / 1000.0, kd = 0.01 * sqrt(ks * m);
    for (size_t i = 0; i < n; i++) {
        double x[3] = {len * (double)i / (double)(n - 1), 0, 0};
        if (psys_system_add_particle(sys, x, NULL, m, NULL, NULL) != PSYS_OK)
            goto fail;
    }
    for (size_t i = 0; i + 1 < n; i++)
        if (psys_system_add_spring(sys, i, i + 1, ks, kd, -1) != PSYS_OK)
            goto fail;
    double g[3] = {0, -9.81, 0};
    if (psys_system_set_fixed(sys, 0, true) != PSYS_OK || psys_system_add_gravity(sys, g) != PSYS_OK)
        goto fail;
    *dt = 1.0 / sqrt(4.0 * ks / m);
    return sys;
fail:
    psys_system_destroy(sys);
    return NULL;
}

static uint64_t rng_state;
static double urand(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(rng_state >> 11) * 0x1.0p-53;
}

/* The LAMMPS LJ melt (the peer in.lj, bench/README.md#peer-programs;
 * bench/pair_bench.c): fcc at
 * density 0.8442, cells³ unit cells, T = 1.44, LJ cut at 2.5, skin 0.3. */
static psys_system *build_lj(int cells)
{
    const double rho = 0.8442, a = cbrt(4.0 / rho), L = a * cells, T = 1.44;
    static const double basis[4][3] = {{0, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
    size_t n = 4 * (size_t)cells * cells * cells;
    psys_system *sys = psys_system_create(3, NULL);
    double *v = malloc(n * 3 * sizeof(double)), p[3] = {0, 0, 0}, ke = 0;
    if (!sys || !v)
        goto fail;
    rng_state = 87287;
    for (size_t i = 0; i < n * 3; i++) {
        v[i] = urand() - 0.5;
        p[i % 3] += v[i];
    }
    for (size_t i = 0; i < n * 3; i++) {
        v[i] -= p[i % 3] / (double)n;
        ke += 0.5 * v[i] * v[i];
    }
    double scale = sqrt(T * 1.5 * (double)(n - 1) / ke);
    size_t i = 0;
    for (int cz = 0; cz < cells; cz++)
        for (int cy = 0; cy < cells; cy++)
            for (int cx = 0; cx < cells; cx++)
                for (int b = 0; b < 4; b++, i++) {
                    double x[3] = {a * (cx + basis[b][0]), a * (cy + basis[b][1]), a * (cz + basis[b][2])};
                    double vi[3] = {v[i * 3] * scale, v[i * 3 + 1] * scale, v[i * 3 + 2] * scale};
                    if (psys_system_add_particle(sys, x, vi, 1.0, NULL, NULL) != PSYS_OK)
                        goto fail;
                }
    free(v);
    v = NULL;
    double lo[3] = {0, 0, 0}, hi[3] = {L, L, L};
    bool per[3] = {true, true, true};
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.epsilon = 1;
    def.sigma = 1;
    def.cutoff = 2.5;
    def.skin = 0.3;
    def.method = PSYS_PAIR_GRID;
    if (psys_system_set_box(sys, lo, hi, per) != PSYS_OK || psys_system_add_pair(sys, &def, NULL) != PSYS_OK)
        goto fail;
    return sys;
fail:
    free(v);
    psys_system_destroy(sys);
    return NULL;
}

/* n bodies of total mass 1 uniformly in a unit ball, G = 1, softening 0.01. */
static psys_system *build_nbody(size_t n)
{
    psys_system *sys = psys_system_create(3, NULL);
    if (!sys)
        return NULL;
    rng_state = 12345;
    for (size_t i = 0; i < n;) {
        double x[3] = {2 * urand() - 1, 2 * urand() - 1, 2 * urand() - 1};
        if (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > 1)
            continue;
        if (psys_system_add_particle(sys, x, NULL, 1.0 / (double)n, NULL, NULL) != PSYS_OK)
            goto fail;
        i++;
    }
    psys_pair_def def = psys_pair_def_default();
    def.softening = 0.01;
    def.method = PSYS_PAIR_DIRECT;
    if (psys_system_add_pair(sys, &def, NULL) != PSYS_OK)
        goto fail;
    return sys;
fail:
    psys_system_destroy(sys);
    return NULL;
}

typedef struct bench_opts {
    const char *integrator; /* NULL: the case's own */
    int reps, threads;
    long long steps; /* > 0: steps per repetition, no calibration */
    double seconds, gbs;
} bench_opts;

/* Time steps of sys with integrator at dt; print one JSON line. */
static int bench_system(const char *name, psys_system *sys, const char *integrator, double dt, const bench_opts *o)
{
    if (!sys) {
        cli_error("bench: %s: out of memory building the system", name);
        return EXIT_RUN_FAILED;
    }
    psys_error err;
    psys_solver *solver = NULL;
    int rc = EXIT_OK;
    if (psys_system_set_threads(sys, o->threads) != PSYS_OK ||
        !(solver = psys_system_solver_create(sys, integrator, &err))) {
        cli_error("bench: %s: %s", name, solver ? psys_system_last_error(sys) : err.message);
        psys_system_destroy(sys);
        return EXIT_RUN_FAILED;
    }
    /* One untimed step builds the spring plan and the pair lists, and
     * more until the library's timed choices are made (src/sim/bench.h:
     * psys__system_timing_settled); then calibrate the batch so one
     * repetition takes about `seconds`. */
    do {
        if (psys_system_advance(sys, solver, dt, NULL) != PSYS_OK)
            goto failed;
    } while (!psys__system_timing_settled(sys));
    long long batch = o->steps > 0 ? o->steps : 1;
    while (o->steps <= 0) {
        double t0 = now_seconds();
        for (long long k = 0; k < batch; k++)
            if (psys_system_advance(sys, solver, dt, NULL) != PSYS_OK)
                goto failed;
        double el = now_seconds() - t0;
        if (el > 0.05 || batch > (1LL << 40)) {
            batch = (long long)fmax(1.0, batch * o->seconds / el);
            break;
        }
        batch *= 2;
    }
    double per[64];
    int reps = o->reps > 64 ? 64 : o->reps;
    for (int r = 0; r < reps; r++) {
        double t0 = now_seconds();
        for (long long k = 0; k < batch; k++)
            if (psys_system_advance(sys, solver, dt, NULL) != PSYS_OK)
                goto failed;
        per[r] = (now_seconds() - t0) / (double)batch;
    }
    qsort(per, (size_t)reps, sizeof per[0], cmp_double);
    {
        double med = per[reps / 2];
        size_t np = psys_system_count(sys), ns = psys_system_spring_count(sys);
        double nsp = med * 1e9 / (double)np, fb = floor_bytes(integrator, (double)ns / (double)np);
        printf("{\"case\":\"%s\",\"integrator\":\"%s\",\"n\":%zu,\"particles\":%zu,\"springs\":%zu,\"planes\":%zu,"
               "\"steps\":%lld,\"steps_per_rep\":%lld,\"reps\":%d,\"threads\":%d,\"ns_per_particle_step\":%.2f,",
               name, integrator, np, np, ns, psys_system_plane_count(sys), batch * reps, batch, reps, o->threads, nsp);
        if (ns)
            printf("\"ns_per_spring_eval\":%.3f,", med * 1e9 / ((double)ns * evals_per_step(integrator)));
        else
            printf("\"ns_per_spring_eval\":null,");
        printf("\"min_ns_per_particle_step\":%.2f,\"max_ns_per_particle_step\":%.2f,\"bandwidth_gbs\":%.2f,"
               "\"floor_bytes_per_particle_step\":%.1f,",
               per[0] * 1e9 / (double)np, per[reps - 1] * 1e9 / (double)np, o->gbs, fb);
        if (o->gbs > 0)
            printf("\"floor_ns_per_particle_step\":%.2f,\"times_floor\":%.3f,", fb / o->gbs, nsp / (fb / o->gbs));
        else
            printf("\"floor_ns_per_particle_step\":null,\"times_floor\":null,");
        printf("\"flush_subnormals\":%s,", psys_fpu_flushes_subnormals() ? "true" : "false");
        /* how scattered the users' numbering is: a row-ordered sheet's
         * springs join particles about a row apart, a shuffled one's about
         * a third of the particles apart (the solver reorders internally) */
        if (ns) {
            double gap = 0;
            for (size_t k = 0; k < ns; k++) {
                size_t a = 0, b = 0;
                psys_system_spring(sys, k, &a, &b, NULL, NULL, NULL);
                gap += (double)(a > b ? a - b : b - a);
            }
            printf("\"mean_spring_index_gap\":%.1f}\n", gap / (double)ns);
        } else {
            printf("\"mean_spring_index_gap\":null}\n");
        }
    }
    fflush(stdout);
    goto done;
failed:
    cli_error("bench: %s: %s", name, psys_solver_last_error(solver));
    rc = EXIT_RUN_FAILED;
done:
    psys_solver_destroy(solver);
    psys_system_destroy(sys);
    return rc;
}

/* N of a case named cloth-N, cloth-N-shuffled or cloth-N-floor, 2 ≤ N ≤
 * 4096 (the suite's sizes are 100, 256 and 1024; others find where paths
 * cross over), else 0; *variant tells which. */
static int cloth_size(const char *name, int *variant)
{
    if (strncmp(name, "cloth-", 6) != 0 || !isdigit((unsigned char)name[6]))
        return 0;
    char *end;
    long n = strtol(name + 6, &end, 10);
    *variant = *end == '\0' ? CLOTH_PLAIN
               : strcmp(end, "-shuffled") == 0 ? CLOTH_SHUFFLED
               : strcmp(end, "-floor") == 0    ? CLOTH_FLOOR
                                               : -1;
    return *variant >= 0 && n >= 2 && n <= 4096 ? (int)n : 0;
}

static int run_case(const char *name, const bench_opts *o)
{
    const char *integ = o->integrator;
    int variant;
    const int n = cloth_size(name, &variant);
    if (n > 0)
        return bench_system(name, build_cloth(n, variant), integ ? integ : "rk4",
                            1.0 / sqrt(17.6 * 100.0 * (double)n * n), o);
    if (strcmp(name, "rope-1000000") == 0) {
        double dt = 0;
        psys_system *sys = build_rope(1000000, &dt);
        return bench_system(name, sys, integ ? integ : "rk4", dt, o);
    }
    if (strcmp(name, "lj-melt") == 0)
        return bench_system(name, build_lj(20), integ ? integ : "verlet", 0.005, o);
    /* nbody-4096 */
    return bench_system(name, build_nbody(4096), integ ? integ : "verlet", 1e-3, o);
}

static const char *const case_names[] = {"cloth-100", "cloth-256", "cloth-1024", "rope-1000000", "lj-melt",
                                         "nbody-4096", NULL};

int cmd_bench(int argc, char **argv)
{
    const char *which = NULL;
    bench_opts o = {NULL, 5, 1, 0, 0.4, -1};
    long long v;
    for (int i = 1; i < argc; i++) {
        const bool has = i + 1 < argc;
        if (strcmp(argv[i], "--reps") == 0 && has) {
            if (parse_int(argv[++i], 1, 64, &v) != 0) {
                cli_error("--reps: must be an integer from 1 to 64 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
            o.reps = (int)v;
        } else if (strcmp(argv[i], "--threads") == 0 && has) {
            if (parse_int(argv[++i], 1, 4096, &v) != 0) {
                cli_error("--threads: must be an integer from 1 to 4096 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
            o.threads = (int)v;
        } else if (strcmp(argv[i], "--steps") == 0 && has) {
            if (parse_int(argv[++i], 1, 1000000000, &o.steps) != 0) {
                cli_error("--steps: must be an integer from 1 to 1000000000 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(argv[i], "--seconds") == 0 && has) {
            if (parse_positive(argv[++i], &o.seconds) != 0) {
                cli_error("--seconds: must be a number > 0 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(argv[i], "--bandwidth") == 0 && has) {
            if (parse_positive(argv[++i], &o.gbs) != 0) {
                cli_error("--bandwidth: must be a number > 0 (GB/s; got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(argv[i], "--integrator") == 0 && has) {
            o.integrator = argv[++i];
            if (!psys_solver_exists(o.integrator) || strcmp(o.integrator, "rk45") == 0) {
                cli_error("--integrator: must be a fixed-step solver (got %s)", o.integrator);
                return EXIT_BAD_INPUT;
            }
        } else if (argv[i][0] == '-' && (strcmp(argv[i], "--reps") == 0 || strcmp(argv[i], "--seconds") == 0
                                         || strcmp(argv[i], "--integrator") == 0 || strcmp(argv[i], "--threads") == 0
                                         || strcmp(argv[i], "--bandwidth") == 0 || strcmp(argv[i], "--steps") == 0)) {
            cli_error("%s needs a value (see psys --help)", argv[i]);
            return EXIT_BAD_INPUT;
        } else if (argv[i][0] == '-') {
            cli_error("bench: unknown option %s (see psys --help)", argv[i]);
            return EXIT_BAD_INPUT;
        } else if (!which) {
            which = argv[i];
        } else {
            cli_error("bench: more than one case given");
            return EXIT_BAD_INPUT;
        }
    }
    int variant;
    bool known = !which || cloth_size(which, &variant) > 0;
    for (int k = 0; which && case_names[k]; k++)
        known |= strcmp(which, case_names[k]) == 0;
    if (!known) {
        cli_error("bench: unknown case \"%s\" (cases: cloth-100, cloth-256, cloth-1024, rope-1000000, lj-melt, "
                  "nbody-4096; cloth-N, cloth-N-shuffled and cloth-N-floor for N in 2..4096)",
                  which);
        return EXIT_BAD_INPUT;
    }
    if (o.gbs < 0)
        o.gbs = triad_gbs();
    int rc = EXIT_OK;
    if (which && cloth_size(which, &variant) > 0)
        return run_case(which, &o);
    for (int k = 0; case_names[k]; k++) {
        if (which && strcmp(which, case_names[k]) != 0)
            continue;
        if (!which && !o.integrator && strncmp(case_names[k], "cloth-", 6) == 0) {
            /* the whole suite: every cloth with rk4 and verlet */
            bench_opts ov = o;
            ov.integrator = "rk4";
            rc |= run_case(case_names[k], &ov);
            ov.integrator = "verlet";
            rc |= run_case(case_names[k], &ov);
        } else {
            rc |= run_case(case_names[k], &o);
        }
    }
    return rc;
}
