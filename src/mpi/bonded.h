/* Bonded forces (springs, behaviour functions) across the ranks of a domain
 * decomposition (mpi/bonded.c, docs/mpi.md "Bonded forces"). Internal to
 * the MPI build. */
#ifndef PSYS_MPI_BONDED_H
#define PSYS_MPI_BONDED_H

#include "mpi/mpi.h"

#include <mpi.h>

typedef struct psys__bonds psys__bonds;

/** Copy every spring and behaviour force of g (their serial order of
 *  application included); *out = NULL when g has none. */
psys_status psys__bonds_create(const psys_system *g, psys__bonds **out);
/** Free (NULL is fine). */
void psys__bonds_free(psys__bonds *B);
/** Does force object k of g become a bonded force here? */
bool psys__bonds_takes(const psys_force_class *c);
/** Add to the local system, in place of g's force object k, the object that
 *  adds the bonded forces to this rank's owned particles. */
psys_status psys__bonds_add_force(psys__bonds *B, psys_system *local, size_t k);
/** The largest extent along any axis of any bonded term at the global
 *  positions x (every particle's). */
double psys__bonds_extent_all(const psys__bonds *B, const double *x);
/** The largest extent along any axis of the terms this rank computes, at
 *  the local positions x (ghosts current); 0 before the first localize. */
double psys__bonds_extent(const psys__bonds *B, const double *x);
/** The local terms after a redistribution: nloc particles in increasing
 *  global index gid, own[i] = 1 for the owned ones, owner[i] the rank owning
 *  each. 1 on success, 0 when a term with an owned particle lacks one of its
 *  particles here (the ghosts do not reach it), -1 out of memory. */
int psys__bonds_localize(psys__bonds *B, size_t nloc, const size_t *gid, const unsigned char *own, const int *owner,
                         int rank, int size);
/** Collective: the forces of the terms this rank computes at time t and
 *  state y = [x | v] (ghosts filled in), and the other ranks' contributions
 *  to its owned particles. 0 on success. */
int psys__bonds_evaluate(psys__bonds *B, MPI_Comm comm, double t, const double *y, size_t nloc);
/** Terms this rank computes, and contributions it sends per evaluation. */
size_t psys__bonds_owned_terms(const psys__bonds *B);
size_t psys__bonds_sent(const psys__bonds *B);

#endif
