/* Internal declarations shared by the library's source files. */
#ifndef PSYS_INTERNAL_H
#define PSYS_INTERNAL_H

#include "psys/psys.h"
#include "solver_fast.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#define PSYS_PRAGMA(x) _Pragma(#x)
#define PSYS_OMP(x) PSYS_PRAGMA(x)
#else
#define PSYS_OMP(x)
#endif

/* Elementwise passes over at least this many numbers run on the caller's
 * threads (static schedule: each element computed alone, so the same bits
 * for every thread count); shorter ones are not worth a parallel region. */
#define PSYS_PAR_MIN 65536
#define PSYS_PAR_FOR(nt, len) PSYS_OMP(omp parallel for schedule(static) num_threads(nt) if ((nt) > 1 && (len) >= PSYS_PAR_MIN))

/* Elementwise scans also built for AVX2 and AVX-512 (x86-64, GCC on
 * Linux), the variant chosen at load time: comparisons, min/max and
 * elementwise arithmetic without FMA (-ffp-contract=off), so the same
 * results on every variant. */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define PSYS_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define PSYS_CLONES
#endif

/** Fill err (may be NULL) with code and a printf-style message; returns code. */
psys_status psys__fail(psys_error *err, psys_status code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
/** vprintf form of psys__fail. */
psys_status psys__vfail(psys_error *err, psys_status code, const char *fmt, va_list ap);
/** Clear err (may be NULL). */
void psys__ok(psys_error *err);

/** Overflow-checked n*size allocation (NULL on overflow or failure). */
void *psys__calloc(size_t n, size_t size);
/** psys__calloc on a 64-byte boundary (whole cache lines; free() releases it). */
void *psys__calloc_lines(size_t n, size_t size);
/** Overflow-checked realloc of n*size bytes. */
void *psys__realloc(void *p, size_t n, size_t size);
/** p (*cap elements of size bytes) grown by doubling to hold want; NULL on
 *  failure, with p and *cap as they were. */
void *psys__grow(void *p, size_t *cap, size_t want, size_t size);
/** strdup that does not depend on POSIX. */
char *psys__strdup(const char *s);

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

/** Simulation box (DESIGN §2 `box`): periodic axes wrap positions and pair
 *  forces use the minimum image there. */
typedef struct psys__box {
    bool on;              /* a box is set */
    bool any_periodic;    /* some axis is periodic */
    bool periodic[3];
    double lo[3], hi[3];
    double len[3];        /* hi - lo */
} psys__box;

struct psys_system {
    int dim;
    size_t n, cap;
    double *x, *v;         /* positions and velocities, n*dim each (SoA by quantity) */
    double *f;             /* force accumulator, n*dim */
    double *mass, *inv_mass;
    unsigned char *flags;
    char **ids;
    size_t *id_index;      /* hash of ids (system.c): slot -> particle index + 1, 0 = empty */
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
    double *charge;        /* per-particle charges (box.c), NULL until one is set; ncharge of them, 0 beyond */
    size_t ncharge, charge_cap;
    psys__box box;         /* simulation box (box.c) */
    int threads;           /* threads for parallel force evaluation, 0 = OpenMP default */
    struct psys__dist *dist; /* MPI decomposition (mpi.c, PSYS_MPI builds), NULL = serial */
    const unsigned char *own_mark; /* MPI domain decomposition (mpi_domain.c): 1 for the particles this
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

/* ---- MPI (mpi.c, only in -DPSYS_MPI=ON builds; docs/mpi.md) ---- */
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
/** A run's particles spread over ranks (mpi_domain.c). */
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

#else
static inline const unsigned char *psys__dist_mark(const psys_system *s)
{
    (void)s;
    return NULL;
}
#endif

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

/** Jacobian sink: callback form used by dense and (later) sparse assembly. */
struct psys_jacobian {
    void (*add)(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv);
    void *ctx;
    bool definite; /* see psys_jacobian_wants_definite */
};

/** Gravity object's acceleration (force_gravity.c). */
const double *psys__gravity_g(const void *data);
/** Drag object's coefficient (force_drag.c). */
double psys__drag_kd(const void *data);
/** A mouse spring's particle, constants, fixed target (dim numbers) and
 *  scripted path (*nframes frames of 1 + dim numbers; 0: none) (force_mouse.c). */
void psys__mouse_get(const void *data, size_t *particle, double *ks, double *kd, const double **target,
                     const double **frames, size_t *nframes);
/** A pair force's definition, defaults resolved (force_pair.c). */
const psys_pair_def *psys__pair_def(const void *data);
/** A behaviour's definition as added, defaults resolved (force_behavior.c). */
const psys_behavior_def *psys__behavior_def(const void *data);
/** Built-in behaviour function i in table order (false past the end): its
 *  function, name, particle count and the NULL-terminated keys of its
 *  parameters in scenes (any out pointer may be NULL; force_behavior.c). */
bool psys__behavior_builtin(size_t i, psys_behavior_function *f, const char **name, int *nparticles,
                            const char *const **keys);
/** A pair force's particles were replaced (not just moved): rebuild its lists
 *  and forget its cached forces at the next evaluation (force_pair.c). */
void psys__pair_invalidate(void *data);

/** Bit 63 set when x is not finite: its exponent bits are all set, and
 *  only then does adding one to the exponent carry into the sign bit. OR
 *  it over many values: AND, ADD and OR vectorize, a branch per value does
 *  not (the solver's check of a step's result, and the fused sweep's). */
static inline uint64_t psys__nonfinite_bit(double x)
{
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return (u & 0x7ff0000000000000u) + 0x0010000000000000u;
}

/* ---- spring set internals (force_spring.c) ---- */
/** The damped spring law's magnitude over |l|: with len2 = |l|², dot = l̇·l,
 *  [ks(|l| - r) + kd dot/|l|] / |l|, and 0 for a spring of zero length (no
 *  direction, no force); the force on the first end is -mag·l. The one
 *  expression of every spring loop (serial and across MPI ranks), so they
 *  give the same bits. */
static inline double psys__spring_mag(double ks, double kd, double rest, double len2, double dot)
{
    double L = sqrt(len2), inv = 1.0 / L;
    double mag = (ks * (L - rest) + kd * dot * inv) * inv;
    return len2 == 0 ? 0.0 : mag;
}

/** Create an empty spring set of the system owner (whose thread count it uses). */
void *psys__springs_create(const psys_system *owner);
/** Append one spring. */
psys_status psys__springs_add(void *set, size_t a, size_t b, double ks, double kd, double rest);
/** Number of springs. */
size_t psys__springs_count(const void *set);
/** Read spring k. */
void psys__springs_get(const void *set, size_t k, size_t *a, size_t *b, double *ks, double *kd, double *rest);
/** Give spring k a muscle (amplitude 0 removes it); arguments already validated. */
psys_status psys__springs_set_muscle(void *set, size_t k, double amplitude, double omega, double phase);
/** True if spring k has a muscle; its parameters into the out pointers (may be NULL). */
bool psys__springs_muscle(const void *set, size_t k, double *amplitude, double *omega, double *phase);
/** Rest length of spring k at time t (muscles included). */
double psys__springs_rest_at(const void *set, size_t k, double t);
/** Drop springs n.. (and their muscles); never allocates. */
void psys__springs_truncate(void *set, size_t n);
/** Build the spring set's evaluation plan if the set changed (allocates;
 *  PSYS_ERR_NOMEM on failure). Called before evaluating forces. */
psys_status psys__springs_prepare(void *set);
/** The derivative [v | f/m] of sys at (e->t, y) in one pass over memory when
 *  its forces are springs and per-particle forces only (spring_fused.c),
 *  into ydot, or with pass (not NULL) applied to it instead of storing it:
 *  *used tells whether it did; the same bits as the generic path. */
psys_status psys__fused_derivative(psys_system *sys, const psys_force_eval *e, const double *y, double *ydot,
                                   const psys__stage_pass *pass, bool *used);
/** Whether psys__fused_derivative takes sys as it is now. */
bool psys__fused_eligible(const psys_system *sys);
/** Whether psys__fused_chain takes sys for a step of `stages` stages: asked
 *  once before each step (a timed choice advances with it). */
bool psys__fused_chain_eligible(psys_system *sys, int stages);
/** Where the chain sweep and stage by stage were timed against each other
 *  (springs reaching beyond 600 particles): 1 the chain was kept, 0 stage
 *  by stage, -1 not chosen (yet, or never needed). */
int psys__fused_chain_pick(const psys_system *sys);
/** Blocks whose leavings the fused sweeps have held back into the AVX-512
 *  run loops so far (3-D systems of at least 32,768 particles, or any with
 *  PSYS_FUSED=1, stepped by an explicit Runge–Kutta solver): 0 where that
 *  path was never taken. */
size_t psys__fused_held(const psys_system *sys);
/** All stages of a chain Runge–Kutta step (psys__ode_fast.derivative_chain) in
 *  one sweep: stage i on y_i (y0, then pass[i-1].next) with pass[i] applied;
 *  the bits of psys__fused_derivative stage after stage. y0 NULL: the
 *  system's own x and v, also standing for the passes' base (NULL there);
 *  only with the state in the particles' order. *used false (and nothing
 *  done) when the system is not eligible. */
psys_status psys__fused_chain(psys_system *sys, const psys_force_eval *e, const double *y0, int stages,
                              const psys__stage_pass *pass, bool *used);
/** The springs' internal order (slot -> particle, covering *perm_n
 *  particles) when the fused derivative takes sys and the springs have one
 *  (builds the plan), with the plan's version in *plan; NULL otherwise. */
const uint32_t *psys__fused_order(psys_system *sys, size_t *perm_n, unsigned *plan);
/** Rows of `width` doubles between particle order and slot order: with
 *  to_particles false dst[i] = src[perm[i]] (i < perm_n; beyond, src[i]),
 *  else dst[perm[i]] = src[i]; n rows, on nt threads. */
void psys__order_copy(const uint32_t *perm, size_t perm_n, size_t n, int width, const double *src, double *dst,
                      bool to_particles, int nt);
/** Before a step of psys__advance: hold the solver's state in the springs'
 *  internal order for this step where that gives the same bits (an
 *  elementwise solver created for s by psys_system_solver_create, the
 *  fused derivative) and the springs have such an order; true if so, until
 *  psys__state_order_end. PSYS_STATE_ORDER=0 in the environment
 *  keeps the particles' order. */
bool psys__state_order_begin(psys_system *s, const psys_solver *solver);
/** Back to the particles' own order (after the step). */
void psys__state_order_end(psys_system *s);
/** The fast paths of psys_system_ode(s) (psys_system_solver_create). */
psys__ode_fast psys__system_ode_fast(psys_system *s);

/** The order in which each particle's force receives its spring forces
 *  (builds the plan): row i of rowptr (np + 1) and ent (2·count) lists
 *  particle i's contributions, 2k for spring k's lower-index end (-F) and
 *  2k + 1 for its higher one (+F); seq[e] (2·count) is entry e's place in
 *  the loop's whole sequence of additions. */
psys_status psys__springs_order(void *set, size_t np, size_t *rowptr, uint32_t *ent, uint64_t *seq);
/** How MPI ranks read a bonded class's terms (psys_force_class.terms,
 *  mpi_bonded.c): a spring set's springs, or one behaviour. */
typedef enum psys__terms_kind { PSYS__TERMS_SPRINGS, PSYS__TERMS_BEHAVIOR } psys__terms_kind;
struct psys__force_terms {
    psys__terms_kind kind;
};
/** Copy of behaviour force data (force_behavior.c; free() frees it). */
void *psys__behavior_clone(const void *data);
/** A behaviour's particles (count, then each index). */
int psys__behavior_count(const void *data);
size_t psys__behavior_particle(const void *data, int i);
/** The force a behaviour adds to each of its particles, out[i·d + c], from
 *  their positions and velocities gathered in its order (x, v: count·d). */
void psys__behavior_forces(const void *data, const double *x, const double *v, double *out);

/* ---- structures (structures.c) ---- */
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

/* ---- plane collisions across MPI ranks (collide.c, mpi_domain.c) ---- */
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

/* ---- periodic box and pair forces (box.c, force_pair.c) ---- */
/** Wrap free particles into the box on periodic axes (after accepted steps). */
void psys__box_wrap(psys_system *s);
/** Check pair force data (of class psys_pair_class or psys_pair_user_class)
 *  against box; on failure write a message into msg. */
psys_status psys__pair_check_box(const void *pair, const psys__box *box, char *msg, size_t cap);

#endif
