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

#ifdef __cplusplus
}
#endif

#endif
