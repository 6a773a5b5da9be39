/* The simulation layer: the system as an ODE, the step loop with plane
 * collisions, structures, drawing. */
#ifndef PSYS_SIM_H
#define PSYS_SIM_H

#include "fast/fast.h"

/** A structure builder's validation problem, for callers that report it
 *  in their own terms (the scene loader names the JSON path and value). */
typedef struct psys__problem {
    const char *key; /* field at fault (JSON key); NULL = out of memory */
    long index;      /* element of key (pin[index], axes[index], size[index]) or -1 */
    char what[200];  /* "must be ..." */
    char got[120];   /* the offending value as C sees it */
} psys__problem;
/** Build a chain (first index not returned), the problem into *pb on failure. */
psys_status psys__chain_build(psys_system *sys, const psys_chain_def *def, psys__problem *pb);
/** Build a cloth (a beam is a cloth without bend springs), as psys__chain_build. */
psys_status psys__cloth_build(psys_system *sys, const psys_cloth_def *def, psys__problem *pb);
/** Build a block, as psys__chain_build. */
psys_status psys__block_build(psys_system *sys, const psys_block_def *def, psys__problem *pb);
/** Build a wheel, as psys__chain_build. */
psys_status psys__wheel_build(psys_system *sys, const psys_wheel_def *def, psys__problem *pb);

/* ---- plane collisions across MPI ranks (sim/advance.c, mpi/domain.c) ---- */
/** What psys__advance needs when the system is one rank's part of a larger
 *  one: the particles it moves, their global indices, and two collectives. */
typedef struct psys__collide_hooks {
    const unsigned char *own; /* 1: this rank moves particle i */
    const size_t *gid;        /* global index of each particle */
    void *ctx;
    /** Combine each rank's earliest contact event (fraction of the step,
     *  plane, global particle; SIZE_MAX particle: none) into the earliest of
     *  all (ties: lower plane, then lower particle); true on the rank that
     *  owns its particle. */
    bool (*earliest)(void *ctx, double *alpha, size_t *plane, size_t *gid);
    /** The value of the rank owning the last earliest event's particle, on every rank. */
    double (*share)(void *ctx, double value);
} psys__collide_hooks;
/** psys_system_advance, with hooks for a rank's part of a system (NULL: the whole system). */
psys_status psys__advance(psys_system *s, psys_solver *solver, double h_max, double *h_taken,
                          const psys__collide_hooks *hk);

#endif
