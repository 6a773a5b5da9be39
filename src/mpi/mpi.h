/* The MPI layer: a run's particles spread over ranks (domain
 * decomposition; only in -DPSYS_MPI=ON builds). */
#ifndef PSYS_MPI_LAYER_H
#define PSYS_MPI_LAYER_H

#include "sim/sim.h"

#ifdef PSYS_MPI
/** A run's particles spread over ranks (mpi/domain.c). */
typedef struct psys__domain psys__domain;
/** Free a domain decomposition, its local system and solver (NULL is fine). */
void psys__domain_free(psys__domain *D);
/** Collective: one step of at most h_max of the local particles (as
 *  psys_system_advance); every rank returns the same status. */
psys_status psys__domain_advance(psys__domain *D, double h_max, double *h_taken);
/** The local system (owned particles and ghosts). */
psys_system *psys__domain_local(const psys__domain *D);
/** The solver stepping the local system (the same one for the whole run). */
psys_solver *psys__domain_solver(const psys__domain *D);
/** After a failed step: the global index of the first particle that became non-finite. */
size_t psys__domain_bad_particle(const psys__domain *D);
/** Message of the domain's last failure. */
const char *psys__domain_last_error(const psys__domain *D);
/** Particles this rank owns, holds as ghosts; redistributions so far. */
size_t psys__domain_owned(const psys__domain *D);
size_t psys__domain_ghosts(const psys__domain *D);
size_t psys__domain_redistributions(const psys__domain *D);
/** Bonded terms this rank computes; forces it sends other ranks per evaluation. */
size_t psys__domain_bond_terms(const psys__domain *D);
size_t psys__domain_bond_sent(const psys__domain *D);
/** Ranks along each axis of the domain's grid. */
void psys__domain_parts(const psys__domain *D, int parts[3]);
/** Collective: rank 0's g gets every particle's state and the clock. */
psys_status psys__domain_gather(psys__domain *D, psys_system *g);

#endif

#endif
