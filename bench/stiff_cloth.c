/* stiff_cloth: the stiff-cloth benchmark of issue 7 (bench/README.md).
 *
 * The cloth of the peer bullet_cloth.cpp (bench/README.md#peer-programs;
 * $PEERS): N×N particles, 2 m × 2 m,
 * 1 kg in all, horizontal at y = 2, hanging from the two corners of one edge,
 * gravity 9.81, simulated for 1 s. psys builds it with the scene loader's
 * `cloth` structure (structural, shear and bend springs) and steps it with the
 * named solver; the figures are the wall time of the stepping loop and the
 * strain of the structural springs at the end (|len/rest - 1|, mean and max),
 * the measure bullet_cloth prints for its links.
 *
 *   stiff_cloth SOLVER DT [ks=2000] [kd=...] [n=100] [cg_tolerance=1e-3]
 *
 * prints one JSON line; exit status 1 when the run produced a non-finite
 * state (unstable), 2 on bad arguments. */
#include <psys/psys.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double arg_or(int argc, char **argv, int i, double dflt)
{
    return argc > i ? strtod(argv[i], NULL) : dflt;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: stiff_cloth SOLVER DT [ks=2000] [kd=0.01*ks] [n=100] [cg_tolerance=1e-3] [bend_ks=0.1*ks]\n");
        return 2;
    }
    const char *solver_name = argv[1];
    const double dt = strtod(argv[2], NULL);
    const double ks = arg_or(argc, argv, 3, 2000.0);
    const double kd = arg_or(argc, argv, 4, 0.01 * ks);
    const int n = (int)arg_or(argc, argv, 5, 100);
    const double cg_tol = arg_or(argc, argv, 6, 1e-3);
    const double bend_ks = arg_or(argc, argv, 7, 0.1 * ks);
    if (!(dt > 0) || n < 3 || !(ks > 0)) {
        fprintf(stderr, "stiff_cloth: bad arguments\n");
        return 2;
    }
    const double h = 2.0 / (n - 1), m = 1.0 / ((double)n * n);
    char scene[2048];
    snprintf(scene, sizeof scene,
             "{\"psys\": 1, \"dim\": 3, \"integrator\": \"%s\", \"dt\": %.17g, \"duration\": 1,"
             " \"cg_tolerance\": %.17g,"
             " \"structures\": [{\"type\": \"cloth\", \"origin\": [-1, 2, -1], \"size\": [%d, %d],"
             " \"spacing\": %.17g, \"axes\": [[1, 0, 0], [0, 0, 1]], \"mass\": %.17g,"
             " \"ks\": %.17g, \"kd\": %.17g, \"bend_ks\": %.17g, \"bend_kd\": %.17g,"
             " \"pin\": [[0, 0], [%d, 0]]}],"
             " \"forces\": [{\"type\": \"gravity\", \"g\": [0, -9.81, 0]}]}",
             solver_name, dt, cg_tol, n, n, h, m, ks, kd, bend_ks, 0.1 * kd, n - 1);
    psys_error err;
    psys_scene *sc = psys_scene_load_string(scene, strlen(scene), &err);
    if (!sc) {
        fprintf(stderr, "stiff_cloth: %s\n", err.message);
        return 2;
    }
    psys_system *sys = psys_scene_system(sc);
    psys_settings *set = psys_scene_settings(sc);
    psys_system_set_threads(sys, 1); /* one core, as Bullet */
    psys_solver *solver = psys_system_solver_create(sys, solver_name, &err);
    if (!solver) {
        fprintf(stderr, "stiff_cloth: %s\n", err.message);
        psys_scene_destroy(sc);
        return 2;
    }
    psys_solver_set_cg(solver, set->cg_tolerance, (int)set->cg_max_iterations);
    const long long steps = (long long)llround(1.0 / dt);
    int finite = 1;
    double t0 = now_seconds();
    for (long long k = 0; k < steps && finite; k++) {
        double taken;
        if (psys_solver_step(solver, dt, &taken) != PSYS_OK)
            finite = 0;
    }
    double wall = now_seconds() - t0;
    /* Strain of the structural springs: the cloth structure lists them first. */
    const size_t nstruct = 2 * (size_t)n * n - 2 * (size_t)n;
    const double *x = psys_system_positions(sys);
    double mean = 0, max = 0;
    for (size_t k = 0; k < nstruct && finite; k++) {
        size_t a, b;
        double ks_k, kd_k, rest;
        psys_system_spring(sys, k, &a, &b, &ks_k, &kd_k, &rest);
        double d2 = 0;
        for (int c = 0; c < 3; c++) {
            double dx = x[3 * b + c] - x[3 * a + c];
            d2 += dx * dx;
        }
        double e = fabs(sqrt(d2) / rest - 1.0);
        if (!isfinite(e))
            finite = 0;
        mean += e / (double)nstruct;
        if (e > max)
            max = e;
    }
    printf("{\"case\": \"stiff-cloth\", \"solver\": \"%s\", \"n\": %d, \"dt\": %.6g, \"steps\": %lld, \"ks\": %g, "
           "\"kd\": %g, \"cg_tolerance\": %g, \"finite\": %s, \"wall_s\": %.4f, \"ms_per_step\": %.4f, "
           "\"cg_iterations\": %zu, \"cg_unconverged\": %zu, \"mean_strain\": %.5f, \"max_strain\": %.5f}\n",
           solver_name, n, dt, steps, ks, kd, set->cg_tolerance, finite ? "true" : "false", wall,
           1e3 * wall / (double)steps, psys_solver_cg_iterations(solver), psys_solver_cg_unconverged(solver),
           finite ? mean : NAN, finite ? max : NAN);
    psys_solver_destroy(solver);
    psys_scene_destroy(sc);
    return finite ? 0 : 1;
}
