/* The core layer: the particle system's storage (particles, force
 * objects, controllers, planes, box) and what the layers above need of it. */
#ifndef PSYS_CORE_H
#define PSYS_CORE_H

#include "base/base.h"
#include "solvers/jacobian.h"

/** One force object of a system. */
typedef struct psys__force {
    const psys_force_class *cls;
    void *data;
} psys__force;

/** Controller kinds. */
typedef enum psys__control_kind {
    PSYS__CONTROL_CIRCLE,
    PSYS__CONTROL_OSCILLATE,
    PSYS__CONTROL_KEYFRAMES,
    PSYS__CONTROL_CALLBACK
} psys__control_kind;

/** One controlled particle. */
typedef struct psys__controller {
    size_t particle;
    psys__control_kind kind;
    double center[3], u[3], w[3]; /* circle: basis u, w; oscillate: u = unit direction */
    double given[3];              /* axis or direction as given (saved as is: re-normalising is not exact) */
    double radius, amplitude, omega, phase;
    double *frames;       /* keyframes: count × (1 + dim) */
    size_t nframes;
    psys_controller_fn fn;
    void *ctx;
} psys__controller;

/** One plane (normal unit length). */
typedef struct psys__plane {
    double p[3], n[3];
    double given_n[3]; /* normal as given, saved as is so a reload normalises identically */
    double restitution, friction;
    bool stick;
    psys_response response;
    double forward[3];       /* unit, or zero when friction is the same in every direction */
    double given_forward[3]; /* as given, for saving */
    double backward_friction;
} psys__plane;

/** Simulation box (docs/scene-format.md#periodic-box): periodic axes wrap positions and pair
 *  forces use the minimum image there. */
typedef struct psys__box {
    bool on;              /* a box is set */
    bool any_periodic;    /* some axis is periodic */
    bool periodic[3];
    double lo[3], hi[3];
    double len[3];        /* hi - lo */
} psys__box;

/** The environment switches (docs/api.md#environment-switches), read once
 *  when a system is created (settings.c). Each only picks between code
 *  paths that give the same bits. */
typedef struct psys__switches {
    char fused;            /* PSYS_FUSED's first character: '0' never the fused path, '1' wherever it applies */
    char chain;            /* PSYS_CHAIN's: '0' stage by stage, '1' the chain sweep without timing */
    bool spring_plain;     /* PSYS_SPRING_PLAIN=1: no AVX-512 spring loops */
    bool spring_order_off; /* PSYS_SPRING_ORDER=0: springs keep the particles' numbering */
    bool state_order_off;  /* PSYS_STATE_ORDER=0: the solver's state stays in particle order */
    bool scan_plain;       /* PSYS_SCAN_PLAIN set: the portable neighbour scan and sort */
    bool window_double;    /* PSYS_WINDOW_DOUBLE set: double candidate windows */
    bool group_off;        /* PSYS_GROUP_OFF set: the pair row kernel only */
    bool group8_off;       /* PSYS_GROUP8_OFF set: no eight-row pair groups */
} psys__switches;

/** The switches as the environment sets them now. */
psys__switches psys__switches_from_env(void);

struct psys_system {
    int dim;
    size_t n, cap;
    double *x, *v;         /* positions and velocities, n*dim each (SoA by quantity) */
    double *f;             /* force accumulator, n*dim */
    double *mass, *inv_mass;
    unsigned char *flags;
    char **ids;
    size_t *id_index;      /* hash of ids (core/system.c): slot -> particle index + 1, 0 = empty */
    size_t id_index_cap;   /* slots (a power of 2, at least twice the ids), 0 = no index yet */
    size_t nids;           /* particles with an id (entries in id_index) */
    double t;
    psys__force *forces;
    size_t nforces, forces_cap;
    void *springs;         /* the system's spring set (also in forces), or NULL */
    psys__controller *ctrl;
    size_t nctrl, ctrl_cap;
    psys__plane *planes;
    size_t nplanes, planes_cap;
    double *scratch;       /* 2·cap·dim doubles for collision rollback, allocated with planes */
    double *charge;        /* per-particle charges (forces/box.c), NULL until one is set; ncharge of them, 0 beyond */
    size_t ncharge, charge_cap;
    psys__box box;         /* simulation box (forces/box.c) */
    int threads;           /* threads for parallel force evaluation, 0 = OpenMP default */
    psys__switches sw;     /* the environment switches, read at creation */
    struct psys__dist *dist; /* MPI decomposition (core/comm_mpi.c, PSYS_MPI builds), NULL = serial */
    const unsigned char *own_mark; /* MPI domain decomposition (mpi/domain.c): 1 for the particles this
                                      rank owns (pair rows to compute), 0 for ghosts; NULL = all */
    /* During a step of psys__advance in the springs' internal order
     * (psys__state_order_begin): slot i of the ODE's state holds particle
     * ode_perm[i] (i < ode_perm_n; beyond, particle i), ode_mass and
     * ode_inv_mass (ode_cap entries) the masses in slot order, and
     * ode_slot[p] the slot of particle p (filled only with controlled
     * particles, for the projection). NULL: the particles' own order, as
     * always outside such a step. */
    const uint32_t *ode_perm;
    size_t ode_perm_n, ode_cap;
    double *ode_mass, *ode_inv_mass;
    uint32_t *ode_slot;
    /* What ode_mass, ode_inv_mass and ode_slot were last filled for, so a
     * step does not gather them again (O(n) reads all over memory) while
     * nothing they depend on changed: the springs' plan, and `epoch`,
     * which every new particle or force (a new spring set comes as one),
     * every change of fixedness and every controller taken or released
     * advances (particles removed from the end leave the others' slots as
     * they were). */
    unsigned long epoch, ode_epoch;
    unsigned ode_plan;
    psys_error err;
};

/* ---- the system's MPI communicator (comm_mpi.c, only in -DPSYS_MPI=ON builds; docs/mpi.md) ---- */
typedef struct psys__dist psys__dist;
#ifdef PSYS_MPI
/** Free a decomposition (NULL is fine). */
void psys__dist_free(psys__dist *d);
/** Collective: split the rows of the evaluation at positions x among the
 *  ranks; false when every rank evaluates every row this time. */
bool psys__dist_begin(const psys_system *s, const double *x);
/** Collective: give every rank the owners' rows of f. */
psys_status psys__dist_finish(const psys_system *s, double *f);
/** During a split evaluation (or always, in a domain's local system), 1 for
 *  the rows this rank computes; NULL otherwise. */
const unsigned char *psys__dist_mark(const psys_system *s);
#else
static inline const unsigned char *psys__dist_mark(const psys_system *s)
{
    (void)s;
    return NULL;
}
#endif


/* ---- particles ---- */
/** Add a particle without searching for a duplicate id: the caller has made
 *  sure id (may be NULL) is unique. Otherwise as psys_system_add_particle. */
psys_status psys__system_add_particle_unique(psys_system *s, const double *x, const double *v, double mass,
                                             const char *id, size_t *index);
/** Grow the particle arrays to hold at least want particles. */
psys_status psys__system_reserve(psys_system *s, size_t want);
/** Free every particle and force object of s, leaving an empty system (MPI
 *  ranks other than 0 after decomposing a run). */
void psys__system_release(psys_system *s);
/** Remove particles n.. (undoing a partly built structure); they must not be
 *  referred to by forces, controllers or anything else yet. */
void psys__system_truncate(psys_system *s, size_t n);


/* ---- controllers and planes ---- */
/** a·b over d components. */
static inline double psys__dot(const double *a, const double *b, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += a[k] * b[k];
    return s;
}

/** Signed distance of x from plane pl (positive on the allowed side). */
static inline double psys__plane_distance(const psys__plane *pl, const double *x, int d)
{
    double s = 0;
    for (int k = 0; k < d; k++)
        s += (x[k] - pl->p[k]) * pl->n[k];
    return s;
}

/** Controller state at time t into x and v (dim numbers each). */
void psys__controller_eval(const psys__controller *c, int dim, double t, double *x, double *v);
/** Free a controller's owned memory. */
void psys__controller_free(psys__controller *c);
/** Index of particle i's controller in sys->ctrl, or sys->nctrl if none. */
size_t psys__controller_find(const psys_system *sys, size_t i);
/** Contact forces and friction of planes into f at state (x, v). */
void psys__contact_forces(const psys_system *sys, const double *x, const double *v, double *f);
/** The same contact forces on particles perm[a + j] (perm NULL: a + j),
 *  j < cnt, whose components sit in rows X, V, F at j (the fused
 *  derivative's window): per particle the same operations in the same
 *  order, so the same bits. */
void psys__contact_rows(const psys_system *sys, const uint32_t *perm, size_t a, size_t cnt, const double *const *X,
                        const double *const *V, double *const *F);
/** Make sure collision scratch space fits the particles (called when growing). */
psys_status psys__planes_reserve(psys_system *sys);

/** Fill a force evaluation view of the system from explicit x and v. */
void psys__sys_eval(const psys_system *s, double t, const double *x, const double *v, psys_force_eval *e);


#endif
