/* The MPI library API (docs/mpi.md), run under mpiexec by tests/mpi.cmake:
 * psys_system_set_comm splits the pair-force rows among the ranks (every
 * particle owned by exactly one rank) and the forces equal the serial ones
 * bit for bit, for the direct, grid and Barnes–Hut methods, with springs.
 * With a scene (argv[1], the 2,048-atom melt): psys_run_decompose spreads the
 * particles over a grid of boxes (each owned once, balanced, fewer than all
 * held per rank; 4 ranks cut the cube 2×2×1), the
 * state gathered on rank 0 equals the serial run's bit for bit (verlet) or
 * to rounding (rk45), after particles have migrated. A force type written
 * outside the library (tests/my_gravity.h) is decomposed when its traits
 * say per-particle, and refused without them. */
#include "psys/psys_mpi.h"

#include "my_gravity.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int check_failures = 0;
#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (!(cond)) {                                                               \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
            check_failures++;                                                        \
        }                                                                            \
    } while (0)

static unsigned long long lcg = 12345;
static double rnd(void)
{
    lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(lcg >> 11) / 9007199254740992.0;
}

/* 300 particles in a periodic 3-D box (grid and direct) or free (Barnes–Hut). */
static psys_system *make(psys_pair_method method)
{
    psys_system *s = psys_system_create(3, NULL);
    lcg = 12345;
    double L = 8;
    for (int i = 0; i < 300; i++) {
        double x[3] = {L * rnd(), L * rnd(), L * rnd()}, v[3] = {rnd() - 0.5, rnd() - 0.5, rnd() - 0.5};
        psys_system_add_particle(s, x, v, 0.5 + rnd(), NULL, NULL);
    }
    psys_pair_def d = psys_pair_def_default();
    d.method = method;
    if (method == PSYS_PAIR_BARNES_HUT) {
        d.law = PSYS_PAIR_GRAVITY;
        d.softening = 0.1;
    } else {
        double lo[3] = {0, 0, 0}, hi[3] = {L, L, L};
        bool per[3] = {true, true, true};
        psys_system_set_box(s, lo, hi, per);
        d.law = PSYS_PAIR_LENNARD_JONES;
        d.sigma = 0.5;
        d.cutoff = 1.25;
    }
    psys_system_add_pair(s, &d, NULL);
    for (size_t i = 0; i + 1 < 300; i += 7)
        psys_system_add_spring(s, i, i + 1, 3, 0.1, -1);
    return s;
}

/* The scene at path loaded twice (the serial and the decomposed run's),
 * with the integrator and one thread each; false (checked) on failure. */
static bool load_pair(const char *path, const char *integrator, psys_scene **ss, psys_scene **ds)
{
    psys_error err;
    *ss = psys_scene_load_file(path, &err);
    *ds = psys_scene_load_file(path, &err);
    CHECK(*ss && *ds);
    if (!*ss || !*ds) {
        psys_scene_destroy(*ss);
        psys_scene_destroy(*ds);
        return false;
    }
    for (int k = 0; k < 2; k++) {
        psys_scene *sc = k ? *ds : *ss;
        snprintf(psys_scene_settings(sc)->integrator, sizeof psys_scene_settings(sc)->integrator, "%s", integrator);
        psys_system_set_threads(psys_scene_system(sc), 1); /* a rank per core: OpenMP's default would oversubscribe */
    }
    return true;
}

/* Steps of the scene's run at path, serial on every rank and decomposed over
 * MPI_COMM_WORLD, compared on rank 0 at two gathers. tol 0: bit for bit. */
static void domain_case(const char *path, const char *integrator, double tol)
{
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    psys_error err;
    psys_scene *ss, *ds;
    if (!load_pair(path, integrator, &ss, &ds))
        return;
    psys_system *ssys = psys_scene_system(ss), *dsys = psys_scene_system(ds);
    const size_t n = psys_system_count(ssys), nd = 3 * n;
    psys_run *sr = psys_run_create(ss, &err), *dr = psys_run_create(ds, &err);
    CHECK(sr && dr);
    CHECK(psys_run_decompose(dr, MPI_COMM_WORLD, &err) == PSYS_OK);
    size_t owned = 0, ghosts = 0, redis = 0;
    psys_run_domain_counts(dr, &owned, &ghosts, &redis);
    if (size > 1) {
        unsigned long long own = owned, total = 0, held = owned + ghosts, most = 0;
        MPI_Allreduce(&own, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
        MPI_Allreduce(&held, &most, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
        CHECK(total == n);                                   /* each particle owned by one rank */
        CHECK((double)owned < 1.25 * (double)n / size);      /* balanced boxes */
        (void)most;
        if (rank != 0)
            CHECK(psys_system_count(dsys) == 0);             /* the scene's copy was released */
        int parts[3];
        psys_run_domain_grid(dr, parts);
        CHECK(parts[0] * parts[1] * parts[2] == size);
        if (size == 4) /* a cube: 2×2×1, not four slabs */
            CHECK(parts[0] == 2 && parts[1] == 2 && parts[2] == 1);
    }
    for (int half = 0; half < 2; half++) {
        for (int k = 0; k < 30; k++) {
            CHECK(psys_run_step(sr, &err) == PSYS_OK);
            CHECK(psys_run_step(dr, &err) == PSYS_OK);
        }
        CHECK(psys_run_gather(dr, &err) == PSYS_OK);
        if (rank == 0) {
            const double *xs = psys_system_positions(ssys), *xd = psys_system_positions(dsys);
            const double *vs = psys_system_velocities(ssys), *vd = psys_system_velocities(dsys);
            if (tol == 0) {
                CHECK(memcmp(xs, xd, nd * sizeof(double)) == 0);
                CHECK(memcmp(vs, vd, nd * sizeof(double)) == 0);
                CHECK(psys_system_time(ssys) == psys_system_time(dsys));
            } else {
                double worst = 0;
                for (size_t i = 0; i < nd; i++)
                    worst = fmax(worst, fmax(fabs(xs[i] - xd[i]), fabs(vs[i] - vd[i])));
                CHECK(worst <= tol);
                CHECK(fabs(psys_system_time(ssys) - psys_system_time(dsys)) <= tol);
            }
        }
    }
    psys_run_domain_counts(dr, &owned, &ghosts, &redis);
    if (size > 1) {
        CHECK(redis >= 3); /* the first cut and at least two migrations */
        /* Memory is distributed: on 4 ranks (boxes of 6.7σ, ghosts within
         * 3.1σ) no rank holds every particle once the lattice has melted
         * (at the start a lattice plane may miss the narrow gap). */
        unsigned long long held = owned + ghosts, most = 0;
        MPI_Allreduce(&held, &most, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
        if (rank == 0 && getenv("PSYS_TEST_VERBOSE"))
            printf("%s on %d ranks: most held %llu of %zu, %zu redistributions\n", integrator, size, most, n, redis);
        if (size >= 4)
            CHECK(most < n);
    }
    psys_run_destroy(sr);
    psys_run_destroy(dr);
    psys_scene_destroy(ss);
    psys_scene_destroy(ds);
}

/* Bonded forces across ranks (springs, behaviours): each term computed by
 * exactly one rank, some forces sent between ranks, and the trajectory the
 * serial run's to the bit, on a scene where nothing migrates (cloth), one
 * with migrations (polymer: bead-spring chains in a Lennard-Jones droplet),
 * one of behaviour functions (arm), one of ropes hanging from controlled
 * particles, migrating (crank), and grains and a chain thrown onto a floor
 * between walls (hail: contact events across ranks). */
static void bonded_case(const char *path, const char *integrator, size_t min_redis)
{
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    psys_error err;
    psys_scene *ss, *ds;
    if (!load_pair(path, integrator, &ss, &ds))
        return;
    psys_system *ssys = psys_scene_system(ss), *dsys = psys_scene_system(ds);
    const size_t n = psys_system_count(ssys), nd = (size_t)psys_system_dim(ssys) * n;
    unsigned long long terms = psys_system_spring_count(ssys);
    for (size_t k = 0; k < psys_system_force_count(ssys); k++)
        terms += psys_system_force_class(ssys, k) == &psys_behavior_class;
    psys_run *sr = psys_run_create(ss, &err), *dr = psys_run_create(ds, &err);
    CHECK(sr && dr);
    CHECK(psys_run_decompose(dr, MPI_COMM_WORLD, &err) == PSYS_OK);
    for (int k = 0; k < 40 && !psys_run_done(sr); k++) { /* 40 steps, or the scene's */
        CHECK(psys_run_step(sr, &err) == PSYS_OK);
        CHECK(psys_run_step(dr, &err) == PSYS_OK);
    }
    CHECK(psys_run_gather(dr, &err) == PSYS_OK);
    if (rank == 0) {
        CHECK(memcmp(psys_system_positions(ssys), psys_system_positions(dsys), nd * sizeof(double)) == 0);
        CHECK(memcmp(psys_system_velocities(ssys), psys_system_velocities(dsys), nd * sizeof(double)) == 0);
        CHECK(psys_system_time(ssys) == psys_system_time(dsys));
    }
    if (size > 1) {
        size_t computed = 0, sent = 0, owned = 0, ghosts = 0, redis = 0;
        psys_run_domain_bonds(dr, &computed, &sent);
        psys_run_domain_counts(dr, &owned, &ghosts, &redis);
        unsigned long long in[2] = {computed, sent}, sum[2] = {0, 0}, held = owned + ghosts, most = 0;
        MPI_Allreduce(in, sum, 2, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
        MPI_Allreduce(&held, &most, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, MPI_COMM_WORLD);
        CHECK(sum[0] == terms); /* each term computed once */
        CHECK(sum[1] > 0);      /* some terms cross ranks */
        CHECK(most < n);        /* no rank holds everything */
        CHECK(redis >= min_redis);
        if (rank == 0 && getenv("PSYS_TEST_VERBOSE"))
            printf("%s %s on %d ranks: %llu terms, %llu forces sent, most held %llu of %zu, %zu redistributions\n",
                   path, integrator, size, sum[0], sum[1], most, n, redis);
    }
    psys_run_destroy(sr);
    psys_run_destroy(dr);
    psys_scene_destroy(ss);
    psys_scene_destroy(ds);
}

/* The cloth (path) with a user force of class cls added: with
 * PSYS_FORCE_PER_PARTICLE and clone every rank applies its copy to its own
 * particles, the same bits as the serial run; without traits the
 * decomposition refuses the run and leaves it serial. */
static void user_force_case(const char *path, const psys_force_class *cls)
{
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    psys_error err;
    psys_scene *ss, *ds;
    if (!load_pair(path, "verlet", &ss, &ds))
        return;
    psys_system *ssys = psys_scene_system(ss), *dsys = psys_scene_system(ds);
    const double g[3] = {0.25, -2.0, 0.125};
    CHECK(my_gravity_add(ssys, cls, g) == PSYS_OK);
    CHECK(my_gravity_add(dsys, cls, g) == PSYS_OK);
    const size_t nd = (size_t)psys_system_dim(ssys) * psys_system_count(ssys);
    psys_run *sr = psys_run_create(ss, &err), *dr = psys_run_create(ds, &err);
    CHECK(sr && dr);
    const bool takes = (cls->traits & PSYS_FORCE_PER_PARTICLE) && cls->clone;
    psys_status st = psys_run_decompose(dr, MPI_COMM_WORLD, &err);
    CHECK(st == (takes || size == 1 ? PSYS_OK : PSYS_ERR_UNSUPPORTED));
    if (st != PSYS_OK)
        CHECK(strstr(err.message, "force type") != NULL);
    for (int k = 0; k < (st == PSYS_OK ? 20 : 3) && !psys_run_done(sr); k++) { /* refused: still runs */
        CHECK(psys_run_step(sr, &err) == PSYS_OK);
        CHECK(psys_run_step(dr, &err) == PSYS_OK);
    }
    CHECK(psys_run_gather(dr, &err) == PSYS_OK);
    if (rank == 0 || st != PSYS_OK) {
        CHECK(memcmp(psys_system_positions(ssys), psys_system_positions(dsys), nd * sizeof(double)) == 0);
        CHECK(memcmp(psys_system_velocities(ssys), psys_system_velocities(dsys), nd * sizeof(double)) == 0);
    }
    if (takes && size > 1) {
        size_t owned = 0;
        psys_run_domain_counts(dr, &owned, NULL, NULL);
        CHECK(owned < psys_system_count(ssys)); /* decomposed indeed */
    }
    psys_run_destroy(sr);
    psys_run_destroy(dr);
    psys_scene_destroy(ss);
    psys_scene_destroy(ds);
}

/* A run the decomposition cannot split is refused and left alone. */
static void domain_refused(void)
{
    const char *text = "{\"psys\":1,\"dim\":2,\"dt\":0.01,\"steps\":3,\"integrator\":\"implicit-euler\","
                       "\"particles\":[{\"id\":\"a\",\"x\":[0,1]},{\"id\":\"b\",\"x\":[1,1]}],"
                       "\"forces\":[{\"type\":\"spring\",\"a\":\"a\",\"b\":\"b\",\"ks\":1}]}";
    psys_error err;
    psys_scene *sc = psys_scene_load_string(text, strlen(text), &err);
    CHECK(sc != NULL);
    if (!sc)
        return;
    psys_run *r = psys_run_create(sc, &err);
    int size;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    psys_status st = psys_run_decompose(r, MPI_COMM_WORLD, &err);
    CHECK(st == (size > 1 ? PSYS_ERR_UNSUPPORTED : PSYS_OK));
    if (size > 1)
        CHECK(strstr(err.message, "implicit-euler") != NULL);
    CHECK(psys_system_count(psys_scene_system(sc)) == 2);
    CHECK(psys_run_step(r, &err) == PSYS_OK); /* still the serial run */
    psys_run_destroy(r);
    psys_scene_destroy(sc);
}

int main(int argc, char **argv)
{
    MPI_Init(NULL, NULL);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    psys_pair_method methods[3] = {PSYS_PAIR_DIRECT, PSYS_PAIR_GRID, PSYS_PAIR_BARNES_HUT};
    for (int m = 0; m < 3; m++) {
        psys_system *s = make(methods[m]);
        size_t n = psys_system_count(s), nd = 3 * n;
        double *serial = calloc(nd, sizeof(double)), *dist = calloc(nd, sizeof(double));
        CHECK(psys_system_compute_forces(s, serial) == PSYS_OK);
        CHECK(psys_system_comm_size(s) == 1);
        CHECK(psys_system_set_comm(s, MPI_COMM_WORLD) == PSYS_OK);
        CHECK(psys_system_comm_size(s) == size);
        CHECK(psys_system_compute_forces(s, dist) == PSYS_OK);
        CHECK(memcmp(serial, dist, nd * sizeof(double)) == 0);
        if (size > 1) {
            /* Every particle is computed by exactly one rank, and the split is even. */
            unsigned long long own = psys_system_comm_owned(s), total = 0;
            MPI_Allreduce(&own, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
            CHECK(total == n);
            CHECK(own > 0 && own < n);
            CHECK((double)own < 1.5 * (double)n / size);
        }
        /* Back to serial with MPI_COMM_NULL: the same forces again. */
        CHECK(psys_system_set_comm(s, MPI_COMM_NULL) == PSYS_OK);
        CHECK(psys_system_comm_size(s) == 1);
        memset(dist, 0, nd * sizeof(double));
        CHECK(psys_system_compute_forces(s, dist) == PSYS_OK);
        CHECK(memcmp(serial, dist, nd * sizeof(double)) == 0);
        free(serial);
        free(dist);
        psys_system_destroy(s);
    }
    if (argc > 1) {
        domain_case(argv[1], "verlet", 0);
        domain_case(argv[1], "rk4", 0);
        domain_case(argv[1], "rk45", 1e-9);
    }
    if (argc > 6) { /* cloth, polymer, arm, crank, hail */
        bonded_case(argv[2], "rk4", 0);
        bonded_case(argv[3], "verlet", 2);
        bonded_case(argv[4], "midpoint", 0);
        bonded_case(argv[5], "rk4", 2);
        bonded_case(argv[6], "rk4", 2);
        bonded_case(argv[6], "verlet", 2);
        user_force_case(argv[2], &my_gravity_class);
        user_force_case(argv[2], &my_plain_class);
    }
    domain_refused();
    int fails = check_failures, all = 0;
    MPI_Allreduce(&fails, &all, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    if (rank == 0)
        printf("test_mpi on %d ranks: %s\n", size, all ? "FAILED" : "ok");
    MPI_Finalize();
    return all ? 1 : 0;
}
