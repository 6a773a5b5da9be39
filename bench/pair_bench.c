/* Pair-force benchmarks (programs, not tests; DESIGN §4). Each case prints
 * one JSON line per measurement.
 *
 *   pair_bench lj-melt [--cells C] [--steps S] [--threads T] [--reps R]
 *       The LAMMPS LJ melt (../shared/peers/in.lj): fcc lattice at reduced
 *       density 0.8442, C×C×C unit cells (C = 20: 32,000 atoms) in a periodic
 *       box, Lennard-Jones epsilon = sigma = 1 cut at 2.5 (no shift), skin
 *       0.3, uniform random velocities for temperature 1.44 (zero momentum;
 *       LAMMPS's "velocity create" default distribution), velocity
 *       Verlet at dt = 0.005, S steps (100). Reports ns per atom-step of the
 *       stepping loop (setup excluded), neighbour-list builds and the
 *       relative energy change.
 *   pair_bench grid-scaling [--threads T] [--steps S]
 *       The same liquid from 10³ to 10⁵ particles (cubic boxes of random
 *       positions relaxed by a few soft steps are not needed: a jittered
 *       lattice at the LJ-melt density): grid cost per particle-step.
 *   pair_bench barnes-hut [--n N] [--threads T]
 *       Plummer-like 3-D cloud: direct vs Barnes–Hut time per evaluation and
 *       force error for theta 0.3, 0.5, 0.7, 1.0.
 *
 * Timings depend on the host (see ../shared/peers/README.md, "Noise"):
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
    if (!v)
        return NULL;
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

static int run_lj(int cells, int steps, int threads, int reps, const char *label)
{
    for (int r = 0; r < reps; r++) {
        size_t fi = 0;
        rng = 87287;
        psys_system *sys = lj_melt(cells, 0.3, threads, &fi);
        if (!sys)
            return 1;
        psys_ode ode = psys_system_ode(sys);
        psys_error err;
        psys_solver *sol = psys_solver_create("verlet", &ode, &err);
        double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        double t0 = now();
        for (int s = 0; s < steps; s++)
            if (psys_system_advance(sys, sol, 0.005, NULL) != PSYS_OK) {
                fprintf(stderr, "pair_bench: %s\n", psys_solver_last_error(sol));
                return 1;
            }
        double el = now() - t0;
        double e1 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
        size_t n = psys_system_count(sys);
        psys_pair_stats st;
        psys_system_pair_stats(sys, fi, &st);
        printf("{\"case\":\"%s\",\"atoms\":%zu,\"steps\":%d,\"threads\":%d,\"effective_threads\":%d,\"seconds\":%.4f,"
               "\"ns_per_atom_step\":%.1f,\"force_evaluations\":%zu,\"ns_per_atom_evaluation\":%.1f,"
               "\"list_builds\":%zu,\"partial_evaluations\":%zu,\"pairs_per_atom\":%.2f,\"energy_per_atom_start\":%.6f,"
               "\"relative_energy_change\":%.3g}\n",
               label, n, steps, threads, psys_system_effective_threads(sys), el, el * 1e9 / ((double)n * steps),
               st.evaluations, el * 1e9 / ((double)n * (double)(st.evaluations - 2)), st.rebuilds, st.partial,
               (double)st.pairs / (double)n, e0 / (double)n, (e1 - e0) / fabs(e0));
        fflush(stdout);
        psys_solver_destroy(sol);
        psys_system_destroy(sys);
    }
    return 0;
}

static int grid_scaling(int threads, int steps)
{
    static const int cells[] = {6, 10, 14, 20, 30}; /* 864 .. 108,000 atoms */
    for (size_t c = 0; c < sizeof cells / sizeof cells[0]; c++) {
        char label[32];
        snprintf(label, sizeof label, "grid-%d", 4 * cells[c] * cells[c] * cells[c]);
        if (run_lj(cells[c], steps, threads, 1, label))
            return 1;
    }
    return 0;
}

static int barnes_hut(size_t n, int threads)
{
    static const double thetas[] = {0.3, 0.5, 0.7, 1.0};
    double *ref = NULL, tref = 0;
    for (int m = -1; m < 4; m++) {
        rng = 5;
        psys_system *sys = psys_system_create(3, NULL);
        for (size_t i = 0; i < n; i++) { /* Plummer sphere radii */
            double u = urand() * 0.99, r = 1.0 / sqrt(pow(u, -2.0 / 3) - 1), x[3];
            double z = 2 * urand() - 1, ph = 2 * 3.14159265358979323846 * urand(), s = sqrt(1 - z * z);
            x[0] = r * s * cos(ph);
            x[1] = r * s * sin(ph);
            x[2] = r * z;
            psys_system_add_particle(sys, x, NULL, 1.0 / (double)n, NULL, NULL);
        }
        psys_pair_def def = psys_pair_def_default();
        def.softening = 0.01;
        def.method = m < 0 ? PSYS_PAIR_DIRECT : PSYS_PAIR_BARNES_HUT;
        def.theta = m < 0 ? 0.5 : thetas[m];
        psys_system_add_pair(sys, &def, NULL);
        psys_system_set_threads(sys, threads);
        double *f = malloc(n * 3 * sizeof(double));
        int evals = 0;
        double t0 = now(), el;
        do {
            psys_system_compute_forces(sys, f);
            evals++;
            el = now() - t0;
        } while (el < 0.5);
        el /= evals;
        if (m < 0) {
            ref = f;
            tref = el;
            printf("{\"case\":\"barnes-hut\",\"n\":%zu,\"method\":\"direct\",\"ms_per_evaluation\":%.3f}\n", n, el * 1e3);
        } else {
            double e = 0, nn = 0;
            for (size_t i = 0; i < n * 3; i++) {
                e += (f[i] - ref[i]) * (f[i] - ref[i]);
                nn += ref[i] * ref[i];
            }
            printf("{\"case\":\"barnes-hut\",\"n\":%zu,\"theta\":%.2f,\"ms_per_evaluation\":%.3f,\"speedup\":%.1f,"
                   "\"force_error\":%.3g}\n",
                   n, thetas[m], el * 1e3, tref / el, sqrt(e / nn));
            free(f);
        }
        fflush(stdout);
        psys_system_destroy(sys);
    }
    free(ref);
    return 0;
}

int main(int argc, char **argv)
{
    const char *which = argc > 1 ? argv[1] : "lj-melt";
    int cells = 20, steps = 100, threads = 1, reps = 1;
    size_t n = 20000;
    for (int i = 2; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "--cells") == 0)
            cells = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--steps") == 0)
            steps = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--threads") == 0)
            threads = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--reps") == 0)
            reps = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--n") == 0)
            n = (size_t)atol(argv[i + 1]);
        else {
            fprintf(stderr, "pair_bench: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (strcmp(which, "lj-melt") == 0)
        return run_lj(cells, steps, threads, reps, "lj-melt");
    if (strcmp(which, "grid-scaling") == 0)
        return grid_scaling(threads, steps);
    if (strcmp(which, "barnes-hut") == 0)
        return barnes_hut(n, threads);
    fprintf(stderr, "pair_bench: unknown case %s (lj-melt, grid-scaling, barnes-hut)\n", which);
    return 2;
}
