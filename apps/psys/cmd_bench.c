/* psys bench: built-in benchmark cases printing one JSON line each.
 * cloth-N: the N×N sheet of ../shared/peers/ref_cloth.c (2 m × 2 m, 1 kg,
 * structural + shear + bend springs, two corners pinned, gravity, drag),
 * stepped with rk4 at dt = 1/sqrt(17.6 ks N²). */
#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static psys_system *build_cloth(int n)
{
    psys_system *sys = psys_system_create(3, NULL);
    if (!sys)
        return NULL;
    const double h = 2.0 / (n - 1), m = 1.0 / ((double)n * n), ks = 100.0, kd = 0.01 * sqrt(ks * m);
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            double x[3] = {-1.0 + ix * h, 2.0, -1.0 + iy * h};
            if (psys_system_add_particle(sys, x, NULL, m, NULL, NULL) != PSYS_OK)
                goto fail;
        }
    for (int iy = 0; iy < n; iy++)
        for (int ix = 0; ix < n; ix++) {
            size_t i = (size_t)iy * n + ix;
            psys_status st = PSYS_OK;
            if (ix + 1 < n) st |= psys_system_add_spring(sys, i, i + 1, ks, kd, -1);
            if (iy + 1 < n) st |= psys_system_add_spring(sys, i, i + n, ks, kd, -1);
            if (ix + 1 < n && iy + 1 < n) st |= psys_system_add_spring(sys, i, i + n + 1, ks, kd, -1);
            if (ix > 0 && iy + 1 < n) st |= psys_system_add_spring(sys, i, i + n - 1, ks, kd, -1);
            if (ix + 2 < n) st |= psys_system_add_spring(sys, i, i + 2, 0.2 * ks, 0.2 * kd, -1);
            if (iy + 2 < n) st |= psys_system_add_spring(sys, i, i + 2 * (size_t)n, 0.2 * ks, 0.2 * kd, -1);
            if (st != PSYS_OK)
                goto fail;
        }
    double g[3] = {0, -9.81, 0};
    if (psys_system_set_fixed(sys, 0, true) != PSYS_OK || psys_system_set_fixed(sys, (size_t)n - 1, true) != PSYS_OK
        || psys_system_add_gravity(sys, g) != PSYS_OK || psys_system_add_drag(sys, 0.05 * m) != PSYS_OK)
        goto fail;
    return sys;
fail:
    psys_system_destroy(sys);
    return NULL;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int bench_cloth(int n, const char *integrator, int reps, double seconds)
{
    psys_system *sys = build_cloth(n);
    if (!sys) {
        cli_error("bench: out of memory building a %dx%d cloth", n, n);
        return EXIT_RUN_FAILED;
    }
    psys_ode ode = psys_system_ode(sys);
    psys_error err;
    psys_solver *solver = psys_solver_create(integrator, &ode, &err);
    if (!solver) {
        cli_error("bench: %s", err.message);
        psys_system_destroy(sys);
        return EXIT_RUN_FAILED;
    }
    const double dt = 1.0 / sqrt(17.6 * 100.0 * (double)n * n);
    /* Calibrate the batch so one repetition takes about `seconds`. */
    long long batch = 1;
    for (;;) {
        double t0 = now_seconds();
        for (long long k = 0; k < batch; k++)
            psys_solver_step(solver, dt, NULL);
        double el = now_seconds() - t0;
        if (el > 0.05 || batch > (1LL << 40)) {
            batch = (long long)fmax(1.0, batch * seconds / el);
            break;
        }
        batch *= 2;
    }
    double per[64];
    if (reps > 64)
        reps = 64;
    for (int r = 0; r < reps; r++) {
        double t0 = now_seconds();
        for (long long k = 0; k < batch; k++)
            if (psys_solver_step(solver, dt, NULL) != PSYS_OK) {
                cli_error("bench: cloth-%d: %s", n, psys_solver_last_error(solver));
                psys_solver_destroy(solver);
                psys_system_destroy(sys);
                return EXIT_RUN_FAILED;
            }
        per[r] = (now_seconds() - t0) / (double)batch;
    }
    qsort(per, (size_t)reps, sizeof per[0], cmp_double);
    double med = per[reps / 2];
    size_t np = psys_system_count(sys), ns = psys_system_spring_count(sys);
    int evals = strcmp(integrator, "rk4") == 0 ? 4 : strcmp(integrator, "verlet") == 0 ? 2 : 1;
    printf("{\"case\":\"cloth-%d\",\"integrator\":\"%s\",\"particles\":%zu,\"springs\":%zu,\"steps_per_rep\":%lld,"
           "\"reps\":%d,\"threads\":1,\"ns_per_particle_step\":%.2f,\"ns_per_spring_eval\":%.3f,"
           "\"min_ns_per_particle_step\":%.2f,\"max_ns_per_particle_step\":%.2f}\n",
           n, integrator, np, ns, batch, reps, med * 1e9 / np, med * 1e9 / ((double)ns * evals),
           per[0] * 1e9 / np, per[reps - 1] * 1e9 / np);
    fflush(stdout);
    psys_solver_destroy(solver);
    psys_system_destroy(sys);
    return EXIT_OK;
}

int cmd_bench(int argc, char **argv)
{
    const char *which = NULL, *integrator = "rk4";
    long long reps = 5;
    double seconds = 0.4;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
            if (parse_int(argv[++i], 1, 64, &reps) != 0) {
                cli_error("--reps: must be an integer from 1 to 64 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(argv[i], "--seconds") == 0 && i + 1 < argc) {
            if (parse_positive(argv[++i], &seconds) != 0) {
                cli_error("--seconds: must be a number > 0 (got %s)", argv[i]);
                return EXIT_BAD_INPUT;
            }
        } else if (strcmp(argv[i], "--integrator") == 0 && i + 1 < argc) {
            integrator = argv[++i];
            if (!psys_solver_exists(integrator) || strcmp(integrator, "rk45") == 0) {
                cli_error("--integrator: must be a fixed-step solver (got %s)", integrator);
                return EXIT_BAD_INPUT;
            }
        } else if (argv[i][0] == '-' && (strcmp(argv[i], "--reps") == 0 || strcmp(argv[i], "--seconds") == 0
                                         || strcmp(argv[i], "--integrator") == 0)) {
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
    static const int sizes[] = {100, 256};
    int rc = EXIT_OK, matched = 0;
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        char name[32];
        snprintf(name, sizeof name, "cloth-%d", sizes[k]);
        if (which && strcmp(which, name) != 0)
            continue;
        matched = 1;
        rc |= bench_cloth(sizes[k], integrator, (int)reps, seconds);
    }
    if (!matched) {
        cli_error("bench: unknown case \"%s\" (cases: cloth-100, cloth-256)", which);
        return EXIT_BAD_INPUT;
    }
    return rc;
}
