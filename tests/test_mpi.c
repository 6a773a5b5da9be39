/* The MPI library API (docs/mpi.md), run under mpiexec by tests/mpi.cmake:
 * psys_system_set_comm splits the pair-force rows among the ranks (every
 * particle owned by exactly one rank) and the forces equal the serial ones
 * bit for bit, for the direct, grid and Barnes–Hut methods, with springs. */
#include "psys/psys_mpi.h"

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

int main(void)
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
    int fails = check_failures, all = 0;
    MPI_Allreduce(&fails, &all, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
    if (rank == 0)
        printf("test_mpi on %d ranks: %s\n", size, all ? "FAILED" : "ok");
    MPI_Finalize();
    return all ? 1 : 0;
}
