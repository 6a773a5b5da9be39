/* Pair-force benchmarks (programs, not tests; bench/README.md). Each case prints
 * one JSON line per measurement.
 *
 *   pair_bench lj-melt [--cells C] [--steps S] [--threads T] [--reps R]
 *       The LAMMPS LJ melt (the peer in.lj, bench/README.md#peer-programs;
 *       $PEERS): fcc lattice at reduced
 *       density 0.8442, C×C×C unit cells (C = 20: 32,000 atoms) in a periodic
 *       box, Lennard-Jones epsilon = sigma = 1 cut at 2.5 (no shift), skin
 *       0.3, uniform random velocities for temperature 1.44 (zero momentum;
 *       LAMMPS's "velocity create" default distribution), velocity
 *       Verlet at dt = 0.005, S steps (100). Reports ns per atom-step of the
 *       stepping loop (setup excluded), neighbour-list builds, partial
 *       evaluations and the rows each recomputed on average, and the
 *       relative energy change.
 *   pair_bench lj-eval [--cells C] [--threads T] [--steps E] [--reps R]
 *       The two parts of a step, apart: lj-melt's liquid after 100 steps,
 *       then E force evaluations (200) alternating between its state and
 *       the state with every coordinate 1e-9 larger (lists kept, every
 *       force recomputed: "evaluation"), and E alternating with every
 *       coordinate 0.2 larger (a list build before each: "evaluation with a
 *       build"); ns per atom for both and their difference ("build").
 *   pair_bench lj-threads [--cells C] [--steps S] [--threads T] [--reps R]
 *       Thread scaling: lj-melt at C = 40 (256,000 atoms) by default, one
 *       thread against T (2), R rounds (5) of one run each, the order of
 *       the two swapped every round (a host that drifts slows both alike).
 *       lj-melt's lines ("lj-threads-1", "lj-threads-T"), then an
 *       "lj-threads-summary" line: each round's speed-up (time on one
 *       thread over time on T), their median, and the ratio of the two
 *       medians of ns per atom-step.
 *   pair_bench grid-scaling [--threads T] [--steps S] [--max-n N]
 *       The same liquid (lj-melt's set-up) at 6, 10, 14, 20, 30, 44 and 63
 *       cells per side: 864, 4,000, 10,976, 32,000, 108,000, 340,736 and
 *       1,000,188 atoms, S steps each (50; the same at every size, since the
 *       first steps from the lattice need fewer list builds and would make
 *       shorter runs look cheaper), sizes above N skipped. One line per
 *       run, case "grid-<n>" with lj-melt's fields (atoms = n,
 *       ns_per_atom_step = grid cost per particle-step); sizes up to 10,976
 *       atoms run 9 times, 32,000 5 times, larger ones 3 times (one run
 *       of the largest alone can move the sweep by a fifth on a busy
 *       host), and the median of a size's runs counts. Then a
 *       "grid-scaling-summary" line: min and max of those medians over the
 *       sizes, the sizes where they occur and max/min.
 *   pair_bench barnes-hut [--n N] [--threads T]
 *       Plummer-like 3-D cloud: direct vs Barnes–Hut time per evaluation and
 *       force error for theta 0.3, 0.5, 0.7, 1.0.
 *   pair_bench bh-crossover [--threads T] [--theta 0.5] [--max-n 32768]
 *       The same cloud at n = 256, 512, ..., 32768 (sizes above N skipped):
 *       time of one force evaluation with direct and with barnes-hut at
 *       theta (after one warm-up evaluation each, medians of 5 interleaved
 *       batches of at least 50 ms; a method whose warm-up took over 1 s is
 *       timed by that evaluation alone). One line per n: direct_ms, bh_ms,
 *       ratio = direct_ms / bh_ms (> 1: barnes-hut faster) and force_error
 *       (as in barnes-hut: RMS |f_bh - f_direct| / RMS |f_direct|). Then a
 *       "bh-crossover-summary" line: first_faster_n, the smallest n where
 *       barnes-hut was faster, and crossover_n, from where it stays faster at
 *       every larger size, interpolated in log n (log ratio linear in log n)
 *       between that size and the one below ("bracket"); the two differ when
 *       the ratio hovers about 1 (host noise). crossover_n is null with
 *       "crossover_below" when barnes-hut is faster at every size, with
 *       "crossover_above" when it is not faster at the largest.
 *
 * Timings depend on the host (its noise: bench/README.md#peer-programs):
 * compare only within one run. */
#include <psys/psys.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static uint64_t rng = 87287;
static double urand(void)
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return (double)((rng * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

/* fcc liquid start of in.lj with cells^3 unit cells; lattice jitter 0 like LAMMPS. */
static psys_system *lj_melt(int cells, double skin, int threads, size_t *force_index)
{
    const double rho = 0.8442, a = cbrt(4.0 / rho), L = a * cells, T = 1.44;
    psys_system *sys = psys_system_create(3, NULL);
    if (!sys)
        return NULL;
    static const double basis[4][3] = {{0, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
    size_t n = 4 * (size_t)cells * cells * cells;
    double *v = malloc(n * 3 * sizeof(double)), p[3] = {0, 0, 0};
    if (!v) {
        psys_system_destroy(sys);
        return NULL;
    }
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            v[i * 3 + k] = urand() - 0.5; /* uniform, like LAMMPS's "velocity create" default */
            p[k] += v[i * 3 + k];
        }
    double ke = 0;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            v[i * 3 + k] -= p[k] / (double)n;
            ke += 0.5 * v[i * 3 + k] * v[i * 3 + k];
        }
    double scale = sqrt(T * 1.5 * (double)(n - 1) / ke); /* 3N - 3 degrees of freedom */
    size_t i = 0;
    for (int cz = 0; cz < cells; cz++)
        for (int cy = 0; cy < cells; cy++)
            for (int cx = 0; cx < cells; cx++)
                for (int b = 0; b < 4; b++, i++) {
                    double x[3] = {a * (cx + basis[b][0]), a * (cy + basis[b][1]), a * (cz + basis[b][2])};
                    double vi[3] = {v[i * 3] * scale, v[i * 3 + 1] * scale, v[i * 3 + 2] * scale};
                    psys_system_add_particle(sys, x, vi, 1.0, NULL, NULL);
                }
    free(v);
    double lo[3] = {0, 0, 0}, hi[3] = {L, L, L};
    bool per[3] = {true, true, true};
    psys_pair_def def = psys_pair_def_default();
    def.law = PSYS_PAIR_LENNARD_JONES;
    def.epsilon = 1;
    def.sigma = 1;
    def.cutoff = 2.5;
    def.skin = skin;
    def.method = PSYS_PAIR_GRID;
    if (psys_system_set_box(sys, lo, hi, per) != PSYS_OK || psys_system_add_pair(sys, &def, force_index) != PSYS_OK
        || psys_system_set_threads(sys, threads) != PSYS_OK) {
        fprintf(stderr, "pair_bench: %s\n", psys_system_last_error(sys));
        psys_system_destroy(sys);
        return NULL;
    }
    return sys;
}

/* Runs the melt reps times (at most 64); *ns_per_step (may be NULL) gets
 * the median of the runs' ns per atom-step. */
static int run_lj(int cells, int steps, int threads, int reps, const char *label, double *ns_per_step)
{
    double runs[64];
    if (reps > 64)
        reps = 64;
    for (int r = 0; r < reps; r++) {
        size_t fi = 0;
        rng = 87287;
        psys_system *sys = lj_melt(cells, 0.3, threads, &fi);
        if (!sys)
            return 1;
        psys_error err;
        psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
        if (!sol) {
            fprintf(stderr, "pair_bench: cannot create the verlet solver\n");
            psys_system_destroy(sys);
            return 1;
        }
        double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        double t0 = now();
        for (int s = 0; s < steps; s++)
            if (psys_system_advance(sys, sol, 0.005, NULL) != PSYS_OK) {
                fprintf(stderr, "pair_bench: %s\n", psys_solver_last_error(sol));
                psys_solver_destroy(sol);
                psys_system_destroy(sys);
                return 1;
            }
        double el = now() - t0;
        double e1 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        size_t n = psys_system_count(sys);
        psys_pair_stats st;
        psys_system_pair_stats(sys, fi, &st);
        printf("{\"case\":\"%s\",\"atoms\":%zu,\"steps\":%d,\"threads\":%d,\"effective_threads\":%d,\"seconds\":%.4f,"
               "\"ns_per_atom_step\":%.1f,\"force_evaluations\":%zu,\"ns_per_atom_evaluation\":%.1f,"
               "\"list_builds\":%zu,\"partial_evaluations\":%zu,\"rows_per_partial\":%.1f,\"pairs_per_atom\":%.2f,\"energy_per_atom_start\":%.6f,"
               "\"relative_energy_change\":%.3g}\n",
               label, n, steps, threads, psys_system_effective_threads(sys), el, el * 1e9 / ((double)n * steps),
               st.evaluations, el * 1e9 / ((double)n * (double)(st.evaluations - 2)), st.rebuilds, st.partial,
               st.partial ? (double)st.partial_rows / (double)st.partial : 0.0,
               (double)st.pairs / (double)n, e0 / (double)n, (e1 - e0) / fabs(e0));
        fflush(stdout);
        runs[r] = el * 1e9 / ((double)n * steps);
        psys_solver_destroy(sol);
        psys_system_destroy(sys);
    }
    if (ns_per_step && reps > 0) {
        for (int a = 1; a < reps; a++) /* insertion sort: a handful of runs */
            for (int b = a; b > 0 && runs[b] < runs[b - 1]; b--) {
                const double t = runs[b];
                runs[b] = runs[b - 1];
                runs[b - 1] = t;
            }
        *ns_per_step = runs[reps / 2];
    }
    return 0;
}

static int cmp_double(const void *a, const void *b);
static double median(double *v, int n);

/* lj-threads: one thread against `threads`, rounds interleaved. */
static int lj_threads(int cells, int steps, int threads, int reps)
{
    if (reps > 64)
        reps = 64;
    if (reps < 1)
        reps = 1;
    double one[64], many[64], up[64];
    char label[32];
    snprintf(label, sizeof label, "lj-threads-%d", threads);
    for (int r = 0; r < reps; r++) {
        for (int k = 0; k < 2; k++) {
            const bool single = (k == 0) == (r % 2 == 0);
            if (run_lj(cells, steps, single ? 1 : threads, 1, single ? "lj-threads-1" : label,
                       single ? &one[r] : &many[r]))
                return 1;
        }
        up[r] = one[r] / many[r];
    }
    printf("{\"case\":\"lj-threads-summary\",\"atoms\":%d,\"threads\":%d,\"rounds\":%d,\"speedups\":[",
           4 * cells * cells * cells, threads, reps);
    for (int r = 0; r < reps; r++)
        printf("%s%.3f", r ? "," : "", up[r]);
    const double m1 = median(one, reps), mt = median(many, reps);
    printf("],\"median_speedup\":%.3f,\"ns_per_atom_step_1\":%.1f,\"ns_per_atom_step_t\":%.1f,"
           "\"speedup_of_medians\":%.3f}\n",
           median(up, reps), m1, mt, m1 / mt);
    return 0;
}

/* One derivative evaluation from y into ydot, failing loudly. */
static int derive(const psys_ode *ode, const double *y, double *ydot)
{
    if (ode->derivative(ode->ctx, 0.0, y, ydot) != PSYS_OK) {
        fprintf(stderr, "pair_bench: a force evaluation failed\n");
        return 1;
    }
    return 0;
}

static int lj_eval(int cells, int evals, int threads, int reps)
{
    for (int r = 0; r < reps; r++) {
        size_t fi = 0;
        rng = 87287;
        psys_system *sys = lj_melt(cells, 0.3, threads, &fi);
        if (!sys)
            return 1;
        psys_ode ode = psys_system_ode(sys);
        psys_error err;
        psys_solver *sol = psys_system_solver_create(sys, "verlet", &err);
        double *y = malloc(3 * ode.size * sizeof(double));
        int bad = !sol || !y;
        for (int s = 0; s < 100 && !bad; s++)
            bad = psys_system_advance(sys, sol, 0.005, NULL) != PSYS_OK;
        double ns[2] = {0, 0};
        size_t builds[2] = {0, 0}, n = psys_system_count(sys);
        for (int kind = 0; kind < 2 && !bad; kind++) {
            double *y2 = y + ode.size, *ydot = y2 + ode.size;
            ode.get_state(ode.ctx, y);
            memcpy(y2, y, ode.size * sizeof(double));
            for (size_t i = 0; i < ode.npos; i++)
                y2[i] = y[i] + (kind ? 0.2 : 1e-9);
            psys_pair_stats a, b;
            bad = derive(&ode, y2, ydot) || psys_system_pair_stats(sys, fi, &a) != PSYS_OK;
            double t0 = now();
            for (int e = 0; e < evals && !bad; e++)
                bad = derive(&ode, e & 1 ? y2 : y, ydot);
            ns[kind] = (now() - t0) * 1e9 / ((double)n * evals);
            bad = bad || psys_system_pair_stats(sys, fi, &b) != PSYS_OK;
            builds[kind] = b.rebuilds - a.rebuilds;
        }
        if (!bad)
            printf("{\"case\":\"lj-eval\",\"atoms\":%zu,\"threads\":%d,\"evaluations\":%d,"
                   "\"ns_per_atom_evaluation\":%.1f,\"ns_per_atom_evaluation_with_build\":%.1f,"
                   "\"ns_per_atom_build\":%.1f,\"builds\":[%zu,%zu]}\n",
                   n, threads, evals, ns[0], ns[1], ns[1] - ns[0], builds[0], builds[1]);
        else
            fprintf(stderr, "pair_bench: lj-eval: %s\n", sol ? psys_solver_last_error(sol) : "no solver or memory");
        fflush(stdout);
        free(y);
        psys_solver_destroy(sol);
        psys_system_destroy(sys);
        if (bad)
            return 1;
    }
    return 0;
}

static int grid_scaling(int threads, int steps, size_t max_n)
{
    /* 864 .. 1,000,188 atoms */
    static const int cells[] = {6, 10, 14, 20, 30, 44, 63};
    double lo = 0, hi = 0;
    size_t n_lo = 0, n_hi = 0;
    int sizes = 0;
    for (size_t c = 0; c < sizeof cells / sizeof cells[0]; c++) {
        size_t n = 4 * (size_t)cells[c] * cells[c] * cells[c];
        if (n > max_n)
            break;
        char label[32];
        double ns = 0;
        snprintf(label, sizeof label, "grid-%zu", n);
        /* small systems run a few times (a run of 864 atoms lasts about 10 ms,
         * within reach of the host's hiccups): the median counts */
        const int reps = n <= 11000 ? 9 : n <= 32000 ? 5 : 3;
        if (run_lj(cells[c], steps, threads, reps, label, &ns))
            return 1;
        if (sizes == 0 || ns < lo) {
            lo = ns;
            n_lo = n;
        }
        if (sizes == 0 || ns > hi) {
            hi = ns;
            n_hi = n;
        }
        sizes++;
    }
    if (sizes == 0) {
        fprintf(stderr, "pair_bench: no size up to --max-n %zu (the smallest is 864)\n", max_n);
        return 2;
    }
    printf("{\"case\":\"grid-scaling-summary\",\"sizes\":%d,\"steps\":%d,\"threads\":%d,"
           "\"min_ns_per_atom_step\":%.1f,\"n_at_min\":%zu,\"max_ns_per_atom_step\":%.1f,\"n_at_max\":%zu,"
           "\"max_over_min\":%.3f}\n",
           sizes, steps, threads, lo, n_lo, hi, n_hi, hi / lo);
    return 0;
}

/* Plummer-like 3-D cloud of n particles of mass 1/n (radii from the
 * Plummer profile, cut at 99 % of the mass), softened gravity (0.01) by
 * method at opening angle theta. The same positions for every call. */
static psys_system *plummer(size_t n, psys_pair_method method, double theta, int threads)
{
    rng = 5;
    psys_system *sys = psys_system_create(3, NULL);
    if (!sys)
        return NULL;
    for (size_t i = 0; i < n; i++) {
        double u = urand() * 0.99, r = 1.0 / sqrt(pow(u, -2.0 / 3) - 1), x[3];
        double z = 2 * urand() - 1, ph = 2 * 3.14159265358979323846 * urand(), s = sqrt(1 - z * z);
        x[0] = r * s * cos(ph);
        x[1] = r * s * sin(ph);
        x[2] = r * z;
        psys_system_add_particle(sys, x, NULL, 1.0 / (double)n, NULL, NULL);
    }
    psys_pair_def def = psys_pair_def_default();
    def.softening = 0.01;
    def.method = method;
    def.theta = theta;
    if (psys_system_count(sys) != n || psys_system_add_pair(sys, &def, NULL) != PSYS_OK
        || psys_system_set_threads(sys, threads) != PSYS_OK) {
        fprintf(stderr, "pair_bench: %s\n", psys_system_last_error(sys));
        psys_system_destroy(sys);
        return NULL;
    }
    return sys;
}

/* Seconds per force evaluation of sys (forces into f), over back-to-back
 * evaluations lasting at least min_seconds (at least one); negative when an
 * evaluation fails. */
static double batch_seconds(psys_system *sys, double *f, double min_seconds)
{
    int evals = 0;
    double t0 = now(), el;
    do {
        if (psys_system_compute_forces(sys, f) != PSYS_OK) {
            fprintf(stderr, "pair_bench: %s\n", psys_system_last_error(sys));
            return -1;
        }
        evals++;
        el = now() - t0;
    } while (el < min_seconds);
    return el / evals;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof v[0], cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* RMS |f - ref| / RMS |ref| over n 3-D forces. */
static double force_error(const double *f, const double *ref, size_t n)
{
    double e = 0, nn = 0;
    for (size_t i = 0; i < n * 3; i++) {
        e += (f[i] - ref[i]) * (f[i] - ref[i]);
        nn += ref[i] * ref[i];
    }
    return sqrt(e / nn);
}

/* Warns when barnes-hut or a grid fell back to direct sums (storage could not grow). */
static void check_fallbacks(const psys_system *sys, size_t n, psys_pair_method method)
{
    psys_pair_stats st;
    if (psys_system_pair_stats(sys, 0, &st) == PSYS_OK && st.fallbacks)
        fprintf(stderr, "pair_bench: n = %zu, %s: %zu evaluations fell back to direct sums\n", n,
                psys_pair_method_name(method), st.fallbacks);
}

/* Builds plummer(n, method, theta, threads) and times its force evaluation
 * over at least min_seconds (forces into f, n·3 doubles); negative on failure. */
static double time_plummer(size_t n, psys_pair_method method, double theta, int threads, double min_seconds,
                           double *f)
{
    psys_system *sys = plummer(n, method, theta, threads);
    if (!sys)
        return -1;
    double el = batch_seconds(sys, f, min_seconds);
    check_fallbacks(sys, n, method);
    psys_system_destroy(sys);
    return el;
}

static int barnes_hut(size_t n, int threads)
{
    static const double thetas[] = {0.3, 0.5, 0.7, 1.0};
    double *ref = malloc(n * 3 * sizeof(double)), *f = malloc(n * 3 * sizeof(double));
    double tref = ref && f ? time_plummer(n, PSYS_PAIR_DIRECT, 0.5, threads, 0.5, ref) : -1;
    if (!ref || !f)
        fprintf(stderr, "pair_bench: out of memory\n");
    else if (tref >= 0)
        printf("{\"case\":\"barnes-hut\",\"n\":%zu,\"method\":\"direct\",\"ms_per_evaluation\":%.3f}\n", n, tref * 1e3);
    fflush(stdout);
    int rc = tref < 0;
    for (int m = 0; m < 4 && !rc; m++) {
        double el = time_plummer(n, PSYS_PAIR_BARNES_HUT, thetas[m], threads, 0.5, f);
        if (el < 0) {
            rc = 1;
            break;
        }
        printf("{\"case\":\"barnes-hut\",\"n\":%zu,\"theta\":%.2f,\"ms_per_evaluation\":%.3f,\"speedup\":%.1f,"
               "\"force_error\":%.3g}\n",
               n, thetas[m], el * 1e3, tref / el, force_error(f, ref, n));
        fflush(stdout);
    }
    free(ref);
    free(f);
    return rc;
}

/* One size of bh-crossover: direct and barnes-hut on the same cloud, each
 * evaluated once first (storage warm-up; where that took over 1 s it is the
 * figure), then, interleaved, 5 batches of at least 50 ms of each, medians.
 * Prints the size's line and stores log(direct/bh) in *log_ratio; nonzero
 * on failure. */
static int crossover_size(size_t n, int threads, double theta, double *log_ratio)
{
    enum { REPS = 5 };
    psys_system *sd = plummer(n, PSYS_PAIR_DIRECT, theta, threads);
    psys_system *sb = sd ? plummer(n, PSYS_PAIR_BARNES_HUT, theta, threads) : NULL;
    double *ref = malloc(n * 3 * sizeof(double)), *f = malloc(n * 3 * sizeof(double));
    double td = -1, tb = -1, tds[REPS], tbs[REPS];
    if (!ref || !f)
        fprintf(stderr, "pair_bench: out of memory\n");
    else if (sb && (td = batch_seconds(sd, ref, 0)) >= 0 && (tb = batch_seconds(sb, f, 0)) >= 0) {
        const bool rd = td <= 1, rb = tb <= 1;
        for (int r = 0; r < REPS && (rd || rb) && td >= 0 && tb >= 0; r++) {
            if (rd)
                td = tds[r] = batch_seconds(sd, ref, 0.05);
            if (rb && td >= 0)
                tb = tbs[r] = batch_seconds(sb, f, 0.05);
        }
        if (td >= 0 && tb >= 0) {
            if (rd)
                td = median(tds, REPS);
            if (rb)
                tb = median(tbs, REPS);
            check_fallbacks(sb, n, PSYS_PAIR_BARNES_HUT);
            printf("{\"case\":\"bh-crossover\",\"n\":%zu,\"theta\":%.2f,\"threads\":%d,\"direct_ms\":%.4f,"
                   "\"bh_ms\":%.4f,\"ratio\":%.3f,\"force_error\":%.3g}\n",
                   n, theta, threads, td * 1e3, tb * 1e3, td / tb, force_error(f, ref, n));
            fflush(stdout);
            *log_ratio = log(td / tb);
        }
    }
    free(ref);
    free(f);
    psys_system_destroy(sb);
    psys_system_destroy(sd);
    return td < 0 || tb < 0;
}

static int bh_crossover(int threads, double theta, size_t max_n)
{
    enum { SIZES = 8 }; /* 256 .. 32768 */
    double lr[SIZES];   /* log(direct / bh) */
    size_t ns[SIZES];
    int sizes = 0;
    for (size_t n = 256; sizes < SIZES && n <= max_n; n *= 2) {
        if (crossover_size(n, threads, theta, &lr[sizes]))
            return 1;
        ns[sizes++] = n;
    }
    if (sizes == 0) {
        fprintf(stderr, "pair_bench: no size up to --max-n %zu (the smallest is 256)\n", max_n);
        return 2;
    }
    int first = 0, k = sizes; /* the first size where barnes-hut is faster; the first from which it stays so */
    while (first < sizes && lr[first] <= 0)
        first++;
    while (k > 0 && lr[k - 1] > 0)
        k--;
    printf("{\"case\":\"bh-crossover-summary\",\"theta\":%.2f,\"threads\":%d,\"sizes\":%d,", theta, threads, sizes);
    if (first < sizes)
        printf("\"first_faster_n\":%zu,", ns[first]);
    else
        printf("\"first_faster_n\":null,");
    if (k == sizes)
        printf("\"crossover_n\":null,\"crossover_above\":%zu}\n", ns[sizes - 1]);
    else if (k == 0)
        printf("\"crossover_n\":null,\"crossover_below\":%zu}\n", ns[0]);
    else {
        double a = log((double)ns[k - 1]), b = log((double)ns[k]);
        double x = a + (b - a) * (0 - lr[k - 1]) / (lr[k] - lr[k - 1]);
        printf("\"crossover_n\":%.0f,\"bracket\":[%zu,%zu]}\n", exp(x), ns[k - 1], ns[k]);
    }
    return 0;
}

int main(int argc, char **argv)
{
    const char *which = argc > 1 ? argv[1] : "lj-melt";
    int cells = 20, steps = -1, threads = 1, reps = 1;
    size_t n = 20000, max_n = 0;
    double theta = 0.5;
    bool cells_set = false, reps_set = false;
    for (int i = 2; i < argc; i += 2) {
        if (i + 1 >= argc) {
            fprintf(stderr, "pair_bench: option %s needs a value\n", argv[i]);
            return 2;
        }
        if (strcmp(argv[i], "--cells") == 0) {
            cells = atoi(argv[i + 1]);
            cells_set = true;
        }
        else if (strcmp(argv[i], "--steps") == 0)
            steps = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--threads") == 0)
            threads = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--reps") == 0) {
            reps = atoi(argv[i + 1]);
            reps_set = true;
        }
        else if (strcmp(argv[i], "--n") == 0)
            n = (size_t)atol(argv[i + 1]);
        else if (strcmp(argv[i], "--max-n") == 0)
            max_n = (size_t)atol(argv[i + 1]);
        else if (strcmp(argv[i], "--theta") == 0)
            theta = atof(argv[i + 1]);
        else {
            fprintf(stderr, "pair_bench: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (strcmp(which, "lj-melt") == 0)
        return run_lj(cells, steps > 0 ? steps : 100, threads, reps, "lj-melt", NULL);
    if (strcmp(which, "lj-threads") == 0)
        return lj_threads(cells_set ? cells : 40, steps > 0 ? steps : 100, threads > 1 ? threads : 2,
                          reps_set ? reps : 5);
    if (strcmp(which, "lj-eval") == 0)
        return lj_eval(cells, steps > 0 ? steps : 200, threads, reps);
    if (strcmp(which, "grid-scaling") == 0)
        return grid_scaling(threads, steps > 0 ? steps : 50, max_n ? max_n : SIZE_MAX);
    if (strcmp(which, "barnes-hut") == 0)
        return barnes_hut(n, threads);
    if (strcmp(which, "bh-crossover") == 0)
        return bh_crossover(threads, theta, max_n ? max_n : 32768);
    fprintf(stderr, "pair_bench: unknown case %s (lj-melt, lj-threads, lj-eval, grid-scaling, barnes-hut, bh-crossover)\n", which);
    return 2;
}
