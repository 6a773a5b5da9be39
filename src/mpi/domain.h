/* MPI domain decomposition, the internals its files share: the domain's
 * state (struct psys__domain) and the calls between mpi/domain.c (creation,
 * stepping, gathering), mpi/decompose.c (the grid of ranks, migration) and
 * mpi/halo.c (the halo exchange and the local ODE). Compiled only with
 * -DPSYS_MPI=ON; docs/mpi.md "Domain decomposition" describes it.
 *
 * The domain: the particles of a run spread over the ranks of a
 * communicator, each rank holding only the particles of its box of space
 * ("owned") and ghost copies of the particles near its box.
 *
 * Decomposition. A grid of px·py·pz = R boxes: R's prime factors go, largest
 * first, to the axis whose parts are longest (the box's extent, else the
 * particles'), so 4 ranks cut a cube 2×2×1 and 8 ranks 2×2×2. The cuts are
 * levels (one per cut axis): the space is cut along the first axis into px
 * parts holding about n/px particles each, each of those along the next axis
 * into py parts, and so on, from global histograms of 64 bins per part
 * (MPI_Allreduce), cuts at bin edges. A rank's ghosts are the other ranks'
 * particles whose every coordinate is within delta of its box (delta = the
 * longest pair-force range + skin; every particle when a law has no cutoff:
 * the all-gather exchange for direct and Barnes–Hut gravity and Coulomb).
 * Before every force evaluation each rank sends its owned particles'
 * positions and velocities to the ranks that hold them as ghosts
 * (point-to-point, halo exchange); both sides derive the lists from the same
 * positions and cuts.
 *
 * Migration. At a redistribution every rank sends each particle it owns to
 * the rank of the box it is now in, and copies to the ranks that need it as
 * a ghost (MPI_Alltoallv); the grid is re-cut first. Every evaluation
 * gathers each rank's two largest displacements since then; the ghosts hold
 * while the two largest of all add up to less than the skin (no pair can
 * have closed its gap by more). Between steps a redistribution happens when
 * the next step could break that (judged from the last step's growth); if
 * an evaluation inside a step finds it broken anyway, that step is
 * abandoned on every rank, the particles redistributed and the step taken
 * again. Ghost sets are therefore always complete: every pair closer than
 * the pair range with one owned end has its other end on the rank.
 *
 * Same answers. The local system holds its particles in increasing global
 * index and computes pair-force rows only for the owned particles (the
 * own_mark of pair/pair.h's methods), each row the serial sum over the same
 * partners in the same order (pairs beyond the cutoff add exactly nothing);
 * gravity and drag are per particle. So every owned particle's force, and
 * every explicit solver's update of it, is bit-identical to the serial run.
 * rk45's error norm is a sum over the whole state: here it is summed per rank
 * and combined with MPI_Allreduce, so rk45 trajectories equal the serial ones
 * to rounding (not bit for bit).
 *
 * The library keeps no global state: everything lives in the psys__domain
 * of one run. */
#ifndef PSYS_MPI_DOMAIN_H
#define PSYS_MPI_DOMAIN_H

#include "mpi/bonded.h"
#include "solvers/solver.h"
#include "psys/psys_mpi.h"

#define DOMAIN_BINS 64  /* histogram bins per part for the cuts */
#define HALO_TAG 7301

/* One particle on the move: global index, mass, inverse mass, charge,
 * flags, then x and v. */
#define REC_HEAD 5
#define REC_LEN(d) (REC_HEAD + 2 * (size_t)(d))

/* A received record's global index and where it lies, for sorting. */
struct rec_key {
    size_t gid, at;
};

struct psys__domain {
    MPI_Comm comm;
    int rank, size, dim;
    psys_system *local;
    psys_solver *solver;
    char integrator[32];
    double tol, cg_tol, h_next; /* for creating the solver */
    int cg_maxit;
    bool charges;    /* the system has charges: ghosts carry them */
    /* the grid of ranks: levels of cuts along the axes with more than one part */
    int parts[3];    /* ranks along each axis (product: size) */
    int nlev, lev_axis[3], lev_cells[3]; /* level L cuts axis lev_axis[L] in each of lev_cells[L] cells */
    bool periodic[3];
    bool fixed_range;/* the box gives the histograms' ranges */
    double lo[3], len[3]; /* histogram range along each axis */
    double delta;    /* ghost range: < 0 none, INFINITY every particle */
    double pair_delta; /* the pair forces' part of it (< 0: none) */
    psys__bonds *bonds;/* springs and behaviours (mpi/bonded.c), NULL = none */
    double bond_ext; /* the longest bonded term along any axis at the last redistribution */
    bool all_ghosts; /* every particle a ghost from now on */
    /* controlled particles: every controller of the system (by increasing
     * particle), and room for the local system's, which are copies of those
     * of its owned particles (the keyframes stay here) */
    psys__controller *gctrl;
    size_t ngctrl, ctrl_cap;
    /* planes: the collision code's collectives (psys__advance) */
    psys__collide_hooks hooks;
    int who_rank;     /* the rank owning the particle of the current contact event */
    double skin;     /* displacements of two particles may add up to less than this */
    int *bin_part[3];      /* level L: lev_cells[L]·parts·DOMAIN_BINS, the part each bin goes to */
    uint64_t *hist;        /* size·DOMAIN_BINS (the largest level's histogram) */
    double *reg_lo, *reg_hi; /* size·3: each rank's box (lo == hi on an axis: empty; ±inf: unbounded) */
    /* local particles, in increasing global index */
    size_t cap, nloc, nown;
    size_t *gid;
    unsigned char *own;
    int *lowner;     /* the rank owning each local particle */
    double *xref;    /* cap·dim: positions at the last redistribution */
    double *ysave;   /* 2·cap·dim: the state before a step */
    /* halo plan: local indices sent to / received from each rank */
    int *scount, *rcount;     /* size: particles */
    size_t *soff, *roff;      /* size + 1 */
    size_t *sidx, *ridx;
    size_t scap;
    double *sbuf, *rbuf;
    size_t sbuf_cap, rbuf_cap;
    MPI_Request *req;         /* 2·size */
    MPI_Status *stat;         /* 2·size (MPI_STATUSES_IGNORE trips GCC's -Wstringop-overflow) */
    /* migration buffers */
    int *mcount, *mdispl, *rmcount, *rmdispl; /* size each, in doubles */
    double *msend, *mrecv;
    size_t msend_cap, mrecv_cap;
    struct rec_key *order;    /* sort of received records */
    size_t order_cap;
    /* step state */
    psys_ode inner;           /* the local system's ODE */
    double dmax;              /* the two largest displacements since the redistribution added, all ranks,
                                 at the last evaluation */
    double dmax_step;         /* dmax at the start of the last step */
    double *gath;             /* 3·size: every rank's two largest displacements and failure flag */
    bool stale;               /* an evaluation found the ghosts could be incomplete */
    size_t bad;               /* global index of the first non-finite particle of a failed step */
    size_t redistributions;
    void *grown;              /* GROW_BUF's result before it is stored */
    psys_error err;
};

/* D->field grown to hold want elements; false (and the buffer kept) on failure. */
#define GROW_BUF(field, cap, want) \
    ((D->grown = psys__grow((field), &(cap), (want), sizeof *(field))) != NULL && ((field) = D->grown, true))

/* ---- mpi/decompose.c ---- */
/** Ranks per axis for a system whose parts along each axis are len[k] long. */
void psys__domain_choose_parts(psys__domain *D, const double *len);
/** Local arrays for m particles (0 on success). */
int psys__domain_reserve_local(psys__domain *D, size_t m);
/** Room for m charges in s (0 on success). */
int psys__domain_reserve_charges(psys_system *s, size_t m);
/** Collective: move the particles to their boxes' ranks (0 on success on every rank). */
int psys__domain_redistribute(psys__domain *D);

/* ---- mpi/halo.c ---- */
/** Owners send their particles' x and v (in y) to the ranks holding them as ghosts (0 on success). */
int psys__domain_halo_exchange(psys__domain *D, double *y);
/** The solver of the local ODE, created or pointed at the new local particles (0 on success). */
int psys__domain_make_solver(psys__domain *D);

#endif
