/* psys with MPI (docs/mpi.md): only in a library built with -DPSYS_MPI=ON.
 * Kept out of psys.h so that programs of a non-MPI build never see MPI types. */
#ifndef PSYS_MPI_H
#define PSYS_MPI_H

#include <mpi.h>

#include "psys/psys.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Spread the system's force evaluation over the ranks of comm (duplicated:
 *  the caller keeps comm). Every rank must hold the same system (load the
 *  same scene) and then make the same calls in the same order: every
 *  derivative evaluation becomes collective over comm. Each rank computes
 *  the pair forces of the particles in its slab of the box (the owner rule of
 *  docs/mpi.md) and the rows are combined with MPI_Allgatherv, so every rank
 *  ends each evaluation with the full force array, bit-identical to a serial
 *  evaluation. comm = MPI_COMM_NULL (or a communicator of one rank) returns to
 *  serial evaluation. Not thread-safe with other calls on the same system. */
psys_status psys_system_set_comm(psys_system *sys, MPI_Comm comm);

/** Ranks the system's evaluation is spread over (1 when serial). */
int psys_system_comm_size(const psys_system *sys);

/** Pair-force rows this rank computed in its last distributed evaluation
 *  (0 when serial): how the work is split, for tests and benchmarks. */
size_t psys_system_comm_owned(const psys_system *sys);

/** Spread the run's particles over the ranks of comm (domain decomposition,
 *  docs/mpi.md): every rank must have created the run from the same scene.
 *  Space is cut into a grid of R boxes (px·py·pz = R, near cubes). Each
 *  rank then integrates only the particles of its box, with
 *  ghost copies of the particles within the pair forces' range (and skin),
 *  and psys_run_step becomes collective. On ranks other than 0 the scene's
 *  system is emptied (its particles and force objects freed); rank 0's is
 *  brought up to date only by psys_run_gather. Fails with
 *  PSYS_ERR_UNSUPPORTED, leaving the run as it was, for scenes with mouse
 *  springs or user force classes (but per-particle ones with clone), or with the implicit-euler solver (springs and behaviours are computed by the rank
 *  owning their lowest-index particle, docs/mpi.md). A communicator of one rank leaves the
 *  run serial. Not combinable with psys_system_set_comm on the same system. */
psys_status psys_run_decompose(psys_run *run, MPI_Comm comm, psys_error *err);

/** Collective: every particle's state and the clock into the scene's system
 *  on rank 0 (for output); nothing when the run is not decomposed. */
psys_status psys_run_gather(psys_run *run, psys_error *err);

/** Particles this rank owns and holds as ghosts, and the redistributions so
 *  far (all 0 when the run is not decomposed). */
void psys_run_domain_counts(const psys_run *run, size_t *owned, size_t *ghosts, size_t *redistributions);

/** Bonded terms (springs, behaviours) this rank computes, and the forces on
 *  other ranks' particles it sends them at every evaluation (0 when the run
 *  is not decomposed); over all ranks the terms add up to the scene's. */
void psys_run_domain_bonds(const psys_run *run, size_t *computed, size_t *sent);

/** Ranks along each axis of the decomposition's grid (1, 1, 1 when not decomposed). */
void psys_run_domain_grid(const psys_run *run, int parts[3]);

#ifdef __cplusplus
}
#endif

#endif
