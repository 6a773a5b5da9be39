/* psys — particle-system dynamics after Witkin's "Particle System Dynamics".
 *
 * Two views of one model (the notes' §3):
 *   - from outside, a psys_ode: a point in phase space whose derivative can be
 *     evaluated at will; solvers (psys_solver) see only that;
 *   - from inside, a psys_system: particles stored structure-of-arrays plus a
 *     list of heterogeneous force objects (psys_force_class).
 *
 * Rules: no global mutable state; every fallible call returns a psys_status
 * and leaves a message (psys_error, or the object's last-error text); the
 * library never prints and never exits.
 */
#ifndef PSYS_PSYS_H
#define PSYS_PSYS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Library version as "MAJOR.MINOR.PATCH". */
#define PSYS_VERSION_STRING "0.2.0"

/** Result of every fallible call. */
typedef enum psys_status {
    PSYS_OK = 0,          /**< success */
    PSYS_ERR_INVALID,     /**< bad argument or bad scene */
    PSYS_ERR_NOMEM,       /**< an allocation failed */
    PSYS_ERR_IO,          /**< a file could not be read or written */
    PSYS_ERR_NONFINITE,   /**< the state became NaN or infinite */
    PSYS_ERR_UNSUPPORTED  /**< a feature this build or object does not provide */
} psys_status;

/** An error code with its message (no "psys:" prefix, no newline). */
typedef struct psys_error {
    psys_status code;   /**< PSYS_OK when nothing failed */
    char message[512];  /**< human-readable description */
} psys_error;

/** Short name of a status code ("ok", "invalid", ...). */
const char *psys_status_name(psys_status s);

/** Flush results too small for a normal double (below 2.2e-308) to zero in
 *  the calling thread (x86-64 flush-to-zero mode), and in the threads it
 *  creates from then on, OpenMP's included: call it before the first
 *  parallel step, or worker threads that exist already keep their mode and
 *  results could depend on the thread count. Such numbers appear ahead of
 *  a cloth's disturbance front and can make a step several times slower;
 *  the psys program turns flushing on at start (docs/cli.md). The library
 *  never changes the mode by itself. False (nothing changed) where the CPU
 *  has no such mode. */
bool psys_fpu_flush_subnormals(bool on);
/** True if the calling thread flushes subnormal results to zero. */
bool psys_fpu_flushes_subnormals(void);

/* ------------------------------------------------------------------ */
/* ODE interface (notes §3): size, get state, set state, derivative,   */
/* clock. Solvers know nothing else about the system they step.        */
/* ------------------------------------------------------------------ */

struct psys_jacobian;

/** A first-order ODE y' = f(t, y) of fixed size, seen by solvers. */
typedef struct psys_ode {
    size_t size;  /**< length of the state vector */
    /** If > 0 the system is second order: y = [q | p] with q of length
     *  npos, and q' = p exactly (what symplectic solvers rely on). */
    size_t npos;
    void *ctx;    /**< passed back to every callback */
    /** Copy the current state into y (length size). */
    void (*get_state)(void *ctx, double *y);
    /** Make y (length size) the current state. */
    void (*set_state)(void *ctx, const double *y);
    /** Current time of the system's clock. */
    double (*get_time)(void *ctx);
    /** Set the system's clock. */
    void (*set_time)(void *ctx, double t);
    /** Evaluate ydot = f(t, y); must not change the current state. */
    psys_status (*derivative)(void *ctx, double t, const double *y, double *ydot);
    /** Optional (may be NULL): overwrite prescribed components of y with
     *  their values at time t (controlled particles). Solvers call it
     *  on every stage state before evaluating the derivative. */
    void (*project)(void *ctx, double t, double *y);
    /** Optional, for implicit solvers of second-order systems (NULL if not
     *  offered): the mass of each position component (npos numbers; 0 marks a
     *  prescribed component the solver must not change). */
    void (*mass)(void *ctx, double *m);
    /** Optional: emit ∂f/∂x, ∂f/∂v blocks (block × block, block = `block`) of
     *  the forces at (t, y) into J. Forces that cannot are treated explicitly. */
    psys_status (*jacobian)(void *ctx, double t, const double *y, struct psys_jacobian *J);
    int block;    /**< block size of jacobian (the dimension) */
    /** Optional (NULL when the state is held whole): for a state split over
     *  processes (MPI domain decomposition, docs/mpi.md), replace values[0..count),
     *  this piece's partial sums, by their totals over all pieces. Adaptive
     *  solvers pass {sum of squared scaled errors, components} through it. */
    void (*reduce_sum)(void *ctx, double *values, int count);
} psys_ode;

/* ------------------------------------------------------------------ */
/* Solvers                                                             */
/* ------------------------------------------------------------------ */

/** A solver instance bound to one psys_ode (owns its scratch buffers). */
typedef struct psys_solver psys_solver;

/** Number of registered solvers. */
size_t psys_solver_count(void);
/** Name of registered solver i ("euler", "midpoint", "rk4", ...), NULL past the end. */
const char *psys_solver_name_at(size_t i);
/** True if name is a registered solver. */
bool psys_solver_exists(const char *name);

/** Create a solver by name for ode (copied; ctx must outlive the solver). */
psys_solver *psys_solver_create(const char *name, const psys_ode *ode, psys_error *err);
/** Free a solver (NULL is fine). */
void psys_solver_destroy(psys_solver *s);
/** The solver's registered name. */
const char *psys_solver_name(const psys_solver *s);
/** True for solvers that choose their own step size (rk45). */
bool psys_solver_is_adaptive(const psys_solver *s);
/** Order of accuracy of the solver (1 for euler, 4 for rk4, 5 for rk45). */
int psys_solver_order(const psys_solver *s);

/** Advance the ode by one step of at most h_max and store the step taken in
 *  *h_taken (may be NULL). Fixed-step solvers take exactly h_max; adaptive
 *  ones take min(h_max, their own proposal) after error control. Nothing
 *  changes on failure; PSYS_ERR_NONFINITE means the new state would not be
 *  finite (see psys_solver_bad_component). No allocation happens here. */
psys_status psys_solver_step(psys_solver *s, double h_max, double *h_taken);
/** Index of the first non-finite state component after PSYS_ERR_NONFINITE. */
size_t psys_solver_bad_component(const psys_solver *s);
/** Last error message of this solver. */
const char *psys_solver_last_error(const psys_solver *s);

/** Local error tolerance of adaptive solvers (absolute and relative). */
psys_status psys_solver_set_tolerance(psys_solver *s, double tol);
/** Threads for the solver's elementwise passes over long state vectors
 *  (0: OpenMP's default; 1, the default, without OpenMP); results are the
 *  same bits for every count. psys_system_advance sets it to the system's
 *  psys_system_effective_threads before each step. */
psys_status psys_solver_set_threads(psys_solver *s, int threads);
/** Step size the adaptive solver will try next (0 for fixed-step solvers). */
double psys_solver_next_step(const psys_solver *s);
/** Set the step size the adaptive solver will try next (restoring a checkpoint). */
psys_status psys_solver_set_next_step(psys_solver *s, double h);
/** Steps rejected by error control so far (adaptive solvers). */
size_t psys_solver_rejected_steps(const psys_solver *s);
/** Conjugate-gradient settings of implicit solvers: relative residual
 *  tolerance and iteration cap per step. */
psys_status psys_solver_set_cg(psys_solver *s, double tolerance, int max_iterations);
/** Steps whose conjugate-gradient solve stopped before reaching its tolerance. */
size_t psys_solver_cg_unconverged(const psys_solver *s);
/** Largest relative residual left by an unconverged solve (0 if none). */
double psys_solver_cg_worst_residual(const psys_solver *s);
/** Total conjugate-gradient iterations so far. */
size_t psys_solver_cg_iterations(const psys_solver *s);

/* ------------------------------------------------------------------ */
/* Particle system                                                     */
/* ------------------------------------------------------------------ */

/** A particle system: SoA particles plus force objects. */
typedef struct psys_system psys_system;

/** Particle flag: fixed in place (anchor); never moved by a solver. */
#define PSYS_PARTICLE_FIXED 1u
/** Particle flag: position and velocity prescribed by a controller (notes §5). */
#define PSYS_PARTICLE_CONTROLLED 2u
/** Flags of particles that are not integrated (excluded from kinetic and gravity energy). */
#define PSYS_PARTICLE_NOT_FREE (PSYS_PARTICLE_FIXED | PSYS_PARTICLE_CONTROLLED)

/** Read-only view passed to force callbacks at one derivative evaluation. */
typedef struct psys_force_eval {
    int dim;                     /**< 2 or 3 */
    size_t n;                    /**< number of particles */
    double t;                    /**< time of the evaluation */
    const double *x;             /**< positions, n*dim, particle-major */
    const double *v;             /**< velocities, n*dim */
    const double *mass;          /**< masses, n */
    const double *inv_mass;      /**< 1/mass, 0 for fixed particles, n */
    const unsigned char *flags;  /**< PSYS_PARTICLE_* flags, n */
    int threads;                 /**< threads the force may use (>= 1); results must not depend on it */
} psys_force_eval;

/** Sink for force Jacobian blocks (see psys_jacobian_add). */
typedef struct psys_jacobian psys_jacobian;

/** True when the sink asks for a positive-definite approximation (implicit
 *  solvers): force classes then drop stiffness terms that can make -∂f/∂x
 *  indefinite (springs under compression) or non-symmetric (damping in ∂f/∂x). */
bool psys_jacobian_wants_definite(const psys_jacobian *J);

/** Add dim×dim row-major blocks ∂f_i/∂x_j and ∂f_i/∂v_j (either may be NULL). */
void psys_jacobian_add(psys_jacobian *J, size_t i, size_t j,
                       const double *dfdx, const double *dfdv);

/* Traits of a force class (psys_force_class.traits): promises about its
 * forces that let the library take faster paths. 0 promises nothing and
 * gets the generic paths, which are always correct. */
/** No force of the class depends on the velocities (verlet then evaluates at
 *  its half-step velocities instead of writing predicted ones). */
#define PSYS_FORCE_VELOCITY_FREE 0x1u
/** The force on each particle is one function of that particle's own mass,
 *  position, velocity and the time, the same for every particle (the data
 *  names no particle). With apply_rows the fused one-sweep derivative takes
 *  the class; with clone a decomposed MPI run applies it on every rank to
 *  the particles that rank owns. */
#define PSYS_FORCE_PER_PARTICLE 0x2u
/** The forces are a sum of terms, each over a few particles the data names
 *  (springs, behaviours). A decomposed MPI run splits the terms over the
 *  ranks where the library can read them (its own spring and behaviour
 *  classes, which set terms); other bonded classes are refused there. */
#define PSYS_FORCE_BONDED 0x4u

/** Library-internal description of a bonded class's terms (for MPI ranks). */
struct psys__force_terms;

/** Behaviour of one force type (Chipmunk-style class of function pointers).
 *  Members after destroy are optional: a class initialised without them
 *  (zero) runs on the generic paths. */
typedef struct psys_force_class {
    const char *name;  /**< type name, e.g. "spring" */
    /** Add this object's forces into f (n*dim accumulators). */
    void (*apply)(void *data, const psys_force_eval *e, double *f);
    /** Potential energy, or NULL if the force is not conservative. */
    double (*energy)(void *data, const psys_force_eval *e);
    /** Add Jacobian blocks into J, or NULL if not provided. */
    void (*jacobian)(void *data, const psys_force_eval *e, psys_jacobian *J);
    /** Free data (may be NULL). */
    void (*destroy)(void *data);
    /** PSYS_FORCE_* flags: what the class's forces promise (0: nothing). */
    unsigned traits;
    /** Optional, with PSYS_FORCE_PER_PARTICLE: apply's operations for `count`
     *  consecutive particles with masses mass[j], velocities V[c][j] and
     *  forces F[c][j] in component rows (c < dim), the same bits as apply.
     *  first: F is not cleared yet and gets 0.0 + this force's term (the bits
     *  of clearing it and adding), one pass over F fewer. Only for forces of
     *  the mass and velocity alone; called from several threads at once on
     *  disjoint rows. */
    void (*apply_rows)(const void *data, int dim, size_t count, const double *mass, const double *const *V,
                       double *const *F, bool first);
    /** Optional: a copy of data (freed with destroy) for another system, or
     *  NULL when out of memory; MPI ranks apply their copies. */
    void *(*clone)(const void *data);
    /** Library-internal (its bonded classes); NULL in user classes. */
    const struct psys__force_terms *terms;
} psys_force_class;

/** Create an empty system of dimension 2 or 3. */
psys_system *psys_system_create(int dim, psys_error *err);
/** Free a system and its forces (NULL is fine). */
void psys_system_destroy(psys_system *sys);
/** Last error message of this system ("" when none). */
const char *psys_system_last_error(const psys_system *sys);

/** Spatial dimension (2 or 3). */
int psys_system_dim(const psys_system *sys);
/** Number of particles. */
size_t psys_system_count(const psys_system *sys);
/** Simulation clock. */
double psys_system_time(const psys_system *sys);
/** Set the simulation clock. */
void psys_system_set_time(psys_system *sys, double t);

/** Add a particle; v may be NULL (zero), id may be NULL; mass finite and at least DBL_MIN (1/mass finite). */
psys_status psys_system_add_particle(psys_system *sys, const double *x, const double *v,
                                     double mass, const char *id, size_t *index);
/** Find a particle by id. */
psys_status psys_system_find(const psys_system *sys, const char *id, size_t *index);
/** Id of particle i, or NULL if it has none. */
const char *psys_system_particle_id(const psys_system *sys, size_t i);
/** Make particle i fixed (velocity zeroed) or free. */
psys_status psys_system_set_fixed(psys_system *sys, size_t i, bool fixed);
/** True if particle i is fixed. */
bool psys_system_is_fixed(const psys_system *sys, size_t i);
/** Set particle i's position and velocity (v may be NULL: unchanged). */
psys_status psys_system_set_particle(psys_system *sys, size_t i, const double *x, const double *v);
/** Positions, n*dim, particle-major (valid until particles are added). */
const double *psys_system_positions(const psys_system *sys);
/** Velocities, n*dim. */
const double *psys_system_velocities(const psys_system *sys);
/** Masses, n. */
const double *psys_system_masses(const psys_system *sys);

/** Add a force object; data is owned by the system from now on (destroyed
 *  with it, also when this call fails). */
psys_status psys_system_add_force(psys_system *sys, const psys_force_class *cls, void *data);
/** Number of force objects. */
size_t psys_system_force_count(const psys_system *sys);
/** Class of force object i. */
const psys_force_class *psys_system_force_class(const psys_system *sys, size_t i);
/** Data of force object i. */
void *psys_system_force_data(const psys_system *sys, size_t i);

/** Add uniform gravity f = m g (a new force object). */
psys_status psys_system_add_gravity(psys_system *sys, const double *g);
/** Add viscous drag f = -kd v on every particle (a new force object). */
psys_status psys_system_add_drag(psys_system *sys, double kd);
/** Add a damped Hooke spring (eq. 1) between a and b; rest < 0 means the
 *  current distance. All springs live in one force object of the system. */
psys_status psys_system_add_spring(psys_system *sys, size_t a, size_t b,
                                   double ks, double kd, double rest);
/** Number of springs. */
size_t psys_system_spring_count(const psys_system *sys);
/** Parameters of spring k (any out pointer may be NULL). */
psys_status psys_system_spring(const psys_system *sys, size_t k, size_t *a, size_t *b,
                               double *ks, double *kd, double *rest);
/** Stability estimate for explicit solvers: ω_max = max over springs of
 *  sqrt(2 ks (1/m_a + 1/m_b)), with 1/m = 0 for fixed and controlled
 *  particles (0 when there are no springs). Explicit solvers are expected
 *  to go unstable for dt > 2/ω_max (src/sim/stability.c, docs/trust.md). */
double psys_system_stiffest_omega(const psys_system *sys);

/** The force class of gravity objects. */
extern const psys_force_class psys_gravity_class;
/** The force class of drag objects. */
extern const psys_force_class psys_drag_class;
/** The force class of the spring set. */
extern const psys_force_class psys_spring_class;

/* ------------------------------------------------------------------ */
/* Behaviour functions ("energy" forces, notes §6 eq. 2;              */
/* docs/notes-errata.md#6-eq-2-the-transpose-of-the-jacobian)         */
/* ------------------------------------------------------------------ */
/* A behaviour function C(x_1..x_k) ∈ R^m vanishes when its particles are
 * "happy". It becomes the force f_i = -(∂C/∂x_i)ᵀ (k_s C + k_d Ċ) with
 * Ċ = Σ_i (∂C/∂x_i) v_i, and the energy ½ k_s C·C. Each behaviour added is
 * one force object; built-in functions and user callbacks go through the
 * same machinery. Its Jacobian (for implicit solvers) is the Gauss–Newton
 * approximation ∂f/∂x ≈ -k_s JᵀJ, ∂f/∂v = -k_d JᵀJ (J = ∂C/∂x): it ignores
 * the second derivatives of C, so it is exact only for affine C (coincide,
 * point-on-plane); otherwise it drops the (k_s C + k_d Ċ)·∂²C/∂x² and
 * k_d Jᵀ ∂Ċ/∂x terms. */

/** Most particles one behaviour function may depend on (k). */
#define PSYS_BEHAVIOR_MAX_PARTICLES 8
/** Most components one behaviour function may have (m). */
#define PSYS_BEHAVIOR_MAX_COMPONENTS 9

/** Which function a behaviour uses. */
typedef enum psys_behavior_function {
    PSYS_BEHAVIOR_USER = 0,        /**< user callback (eval, ctx, ncomponents) */
    PSYS_BEHAVIOR_COINCIDE,        /**< C = x1 - x2 (dim components), 2 particles */
    PSYS_BEHAVIOR_DISTANCE,        /**< C = |x1 - x2| - r, 2 particles */
    PSYS_BEHAVIOR_POINT_ON_PLANE,  /**< C = (x - point)·n̂, 1 particle */
    PSYS_BEHAVIOR_POINT_ON_SPHERE, /**< C = |x - center| - radius (circle in 2-D), 1 particle */
    PSYS_BEHAVIOR_ANGLE            /**< C = θ - angle, θ ∈ [0, π] between a-b and c-b, 3 particles a, b, c */
} psys_behavior_function;

/** A behaviour function: from x (k*dim positions, particle-major) write C (m
 *  values) and, when J is not NULL, J = ∂C/∂x (m × k*dim, row-major). J is
 *  NULL when only C is wanted (energy, finite differences). */
typedef void (*psys_behavior_eval_fn)(void *ctx, int dim, const double *x, double *C, double *J);

/** Definition of a behaviour force (Box2D style: start from
 *  psys_behavior_def_default() and set the fields that matter). Where a
 *  built-in's gradient direction is undefined (distance with coincident
 *  particles, point-on-sphere exactly at the center, angle with a zero arm or
 *  at exactly θ = 0 or π) its J is zero: no force, never NaN (the energy is
 *  still ½ k_s C·C). Near θ = 0 or π the angle's gradient keeps its size
 *  (1/arm length) but its direction is ill-conditioned. */
typedef struct psys_behavior_def {
    psys_behavior_function function; /**< built-in, or PSYS_BEHAVIOR_USER (default) */
    int nparticles;                  /**< k: 1..PSYS_BEHAVIOR_MAX_PARTICLES; built-ins need 2, 2, 1, 1, 3 */
    size_t particles[PSYS_BEHAVIOR_MAX_PARTICLES]; /**< particle indices, all different */
    double ks;                       /**< stiffness k_s >= 0 (default 1) */
    double kd;                       /**< damping k_d >= 0 (default 0) */
    int ncomponents;                 /**< user: m, 1..PSYS_BEHAVIOR_MAX_COMPONENTS (built-ins: ignored) */
    psys_behavior_eval_fn eval;      /**< user: the function (built-ins: ignored) */
    void *ctx;                       /**< user: passed to eval; must outlive the system */
    bool fd_jacobian;                /**< user: J by central differences of C (eval gets J = NULL) */
    double fd_step;                  /**< user: difference step h·max(1, |x_q|) (default 1e-6) */
    double r;                        /**< distance: target distance; < 0 (default) = the current one */
    double point[3];                 /**< point-on-plane: a point of the plane (line in 2-D) */
    double normal[3];                /**< point-on-plane: its normal, nonzero, normalised when used */
    double center[3];                /**< point-on-sphere: the center */
    double radius;                   /**< point-on-sphere: the radius >= 0 */
    double angle;                    /**< angle: target angle in [0, π]; < 0 (default) = the current one */
} psys_behavior_def;

/** A definition with the defaults documented on psys_behavior_def. */
psys_behavior_def psys_behavior_def_default(void);
/** Add a behaviour force (one force object); defaults (r, angle) are resolved
 *  from the particles' current positions. */
psys_status psys_system_add_behavior(psys_system *sys, const psys_behavior_def *def);
/** Definition of force object i if it is a behaviour (defaults resolved, the
 *  normal as given); PSYS_ERR_INVALID otherwise. */
psys_status psys_system_behavior(const psys_system *sys, size_t i, psys_behavior_def *def);
/** Scene name of a built-in function ("distance", ...); NULL for PSYS_BEHAVIOR_USER. */
const char *psys_behavior_function_name(psys_behavior_function f);
/** The built-in function named name (PSYS_ERR_INVALID if there is none). */
psys_status psys_behavior_function_from_name(const char *name, psys_behavior_function *f);
/** Number of components m of def in dimension dim (0 if def is invalid). */
int psys_behavior_components(const psys_behavior_def *def, int dim);
/** Evaluate def at positions x (nparticles*dim) into C (m) and, if J is not
 *  NULL, J (m × nparticles*dim; by differences when fd_jacobian). Defaults
 *  (r, angle) are resolved from x. PSYS_ERR_INVALID (err says why) for a bad def. */
psys_status psys_behavior_eval(const psys_behavior_def *def, int dim, const double *x, double *C,
                               double *J, psys_error *err);
/** Compare def's J at x (eval is asked for J even when fd_jacobian is set)
 *  with central differences of C (step eps, absolute; <= 0 means 1e-6):
 *  *worst_abs_error gets the largest |J - J_fd| (infinity if not finite),
 *  *row (component) and *col (particle slot*dim + axis) where it occurs; out
 *  pointers may be NULL. PSYS_ERR_INVALID for a bad def. */
psys_status psys_behavior_check_jacobian(const psys_behavior_def *def, int dim, const double *x, double eps,
                                         double *worst_abs_error, int *row, int *col);

/** The force class of behaviours with built-in functions (scenes can hold them). */
extern const psys_force_class psys_behavior_class;
/** The force class of behaviours with user callbacks (no scene form). */
extern const psys_force_class psys_behavior_user_class;
/* ---- end of behaviour functions ---- */

/* ---- Controlled particles (notes §5,
 * docs/notes-errata.md#5-controlled-particles-position-and-velocity-at-every-stage,
 * docs/semantics.md#projection-at-every-stage) ----
 * Not integrated: at every derivative evaluation their position AND velocity
 * are set from the controller at the stage time, so damped springs and drag
 * attached to them see the right velocity. */

/** A controller callback: write the position x and velocity v at time t. */
typedef void (*psys_controller_fn)(void *ctx, double t, double *x, double *v);

/** Move particle i on a circle: x = c + R(cos(ωt+φ)u + sin(ωt+φ)w); axis
 *  (3-D, NULL = z) is the circle's normal; u, w a right-handed basis of its plane. */
psys_status psys_system_control_circle(psys_system *sys, size_t i, const double *center, double radius,
                                       double omega, double phase, const double *axis);
/** Oscillate particle i: x = c + A·sin(ωt+φ)·d̂ (direction normalised). */
psys_status psys_system_control_oscillate(psys_system *sys, size_t i, const double *center,
                                          const double *direction, double amplitude, double omega, double phase);
/** Keyframed path: count frames of (1 + dim) numbers [t, x...], t strictly
 *  increasing; piecewise linear, held constant outside the range. */
psys_status psys_system_control_keyframes(psys_system *sys, size_t i, const double *frames, size_t count);
/** Drive particle i from a C callback (such particles cannot be saved to a scene). */
psys_status psys_system_control_callback(psys_system *sys, size_t i, psys_controller_fn fn, void *ctx);
/** Remove particle i's controller: it becomes a free particle with its current state. */
psys_status psys_system_release(psys_system *sys, size_t i);
/** True if particle i has a controller. */
bool psys_system_is_controlled(const psys_system *sys, size_t i);
/** Set every controlled particle's position and velocity for time t (done by
 *  solvers at each stage; call it after changing the clock by hand). */
void psys_system_apply_controllers(psys_system *sys, double t);

/* ---- Mouse springs (notes §5) ---- */

/** Add a damped zero-length spring pulling particle i toward a movable target:
 *  f = -ks (x - p) - kd (v - ṗ). Its force index goes to *handle. */
psys_status psys_system_add_mouse_spring(psys_system *sys, size_t i, const double *target, double ks,
                                         double kd, size_t *handle);
/** Move a mouse spring's target, replacing any scripted path (velocity NULL = at rest). */
psys_status psys_system_mouse_set_target(psys_system *sys, size_t handle, const double *target,
                                         const double *target_velocity);
/** Scripted drag: the target follows count frames [t, x...] piecewise linearly. */
psys_status psys_system_mouse_set_path(psys_system *sys, size_t handle, const double *frames, size_t count);
/** Remove force object i (e.g. release a mouse spring); later indices shift down by one. */
psys_status psys_system_remove_force(psys_system *sys, size_t i);
/** The force class of mouse springs. */
extern const psys_force_class psys_mouse_spring_class;

/* ---- Planes: collisions and contact (notes §7,
 * docs/notes-errata.md#73-contact-force) ---- */

/** How a particle found behind a plane after a step is handled. */
typedef enum psys_response {
    PSYS_RESPONSE_ROLLBACK = 0, /**< roll the whole system back to the instant of contact */
    PSYS_RESPONSE_DISPLACE      /**< project the particle back onto the plane */
} psys_response;

/** Definition of a plane (a line in 2-D); start from psys_plane_def_default(). */
typedef struct psys_plane_def {
    double point[3];      /**< a point on the plane */
    double normal[3];     /**< points to the legal side; normalised when added */
    double restitution;   /**< normal velocity times -restitution at a collision, 0..1 */
    double friction;      /**< linear friction k_f >= 0: f = -k_f (-f·N) v_t in contact */
    bool stick;           /**< non-slip surface: tangential velocity zeroed in contact */
    psys_response response; /**< collision response */
    /** Directional friction (scales, as under Miller's worms): when nonzero,
     *  sliding against `forward` uses backward_friction instead of friction. */
    double forward[3];
    double backward_friction; /**< k_f for tangential velocity with v_t·forward < 0 */
} psys_plane_def;

/** Defaults (docs/semantics.md#planes): restitution 0.5, friction 0,
 * rollback, normal +y. */
psys_plane_def psys_plane_def_default(void);
/** Add a plane. */
psys_status psys_system_add_plane(psys_system *sys, const psys_plane_def *def);
/** Number of planes. */
size_t psys_system_plane_count(const psys_system *sys);
/** Definition of plane k (normal normalised). */
psys_status psys_system_plane(const psys_system *sys, size_t k, psys_plane_def *def);

/** Resting contact: a particle within this distance of a plane ... */
#define PSYS_CONTACT_DISTANCE 1e-9
/** ... whose normal speed is below this is in contact (contact force, friction). */
#define PSYS_CONTACT_SPEED 1e-3

/** Advance the system by one solver step of at most h_max with collision
 *  handling against the planes; *h_taken gets the step length. The solver
 *  must step this system's ODE (psys_system_solver_create, or
 *  psys_solver_create on psys_system_ode(sys)); its thread count is set to
 *  the system's (psys_solver_set_threads). */
psys_status psys_system_advance(psys_system *sys, psys_solver *solver, double h_max, double *h_taken);

/** The ODE view of the system: y = [x (n*dim) | v (n*dim)]. The psys_ode
 *  refers to sys, which must outlive it; adding particles invalidates it. */
psys_ode psys_system_ode(psys_system *sys);
/** A solver by name for sys's ODE with the system's fast paths (the same
 *  bits as psys_solver_create on psys_system_ode(sys), often faster);
 *  create it after the last particle is added. */
psys_solver *psys_system_solver_create(psys_system *sys, const char *name, psys_error *err);
/** Sum of all forces at the current state into f (n*dim, overwritten). */
psys_status psys_system_compute_forces(psys_system *sys, double *f);
/** Kinetic energy of free particles. */
double psys_system_kinetic_energy(const psys_system *sys);
/** Potential energy of all conservative force objects. */
double psys_system_potential_energy(const psys_system *sys);
/** Particle index of ODE state component k. */
size_t psys_system_particle_of_component(const psys_system *sys, size_t k);

/** Dense Jacobians ∂f/∂x and ∂f/∂v ((n*dim)² each, row-major, overwritten)
 *  from the force objects that provide them; for checks on small systems. */
psys_status psys_system_dense_jacobian(psys_system *sys, double *dfdx, double *dfdv);
/** Same from central finite differences of the forces, step eps. */
psys_status psys_system_fd_jacobian(psys_system *sys, double eps, double *dfdx, double *dfdv);

/* ------------------------------------------------------------------ */
/* Structures (notes §5, docs/scene-format.md#structures) and muscle  */
/* springs                                                            */
/* Builders add particles and springs (into the system's spring set)   */
/* in a documented order (docs/scene-format.md, "Structures"): grid    */
/* particle (i,j,k) is first + i + nx·(j + ny·k); with an id, particles */
/* are named "id[i]", "id[i,j]", "id[i,j,k]" (wheel hub "id[hub]").    */
/* Every spring starts at rest (rest = initial distance). Start each   */
/* definition from its _default() so new fields never break callers.   */
/* ------------------------------------------------------------------ */

/** Most particles a system may hold after adding a structure (50 million); larger requests are refused before allocating. */
#define PSYS_MAX_PARTICLES 50000000u

/** Chain / rope: count particles evenly from `from` to `to` (both exact), a spring between neighbours. */
typedef struct psys_chain_def {
    const char *id;            /**< structure id: particle i is "id[i]"; NULL = no ids */
    double from[3];            /**< position of particle 0 (dim numbers used) */
    double to[3];              /**< position of particle count-1; must differ from `from` */
    size_t count;              /**< number of particles, >= 2 */
    double mass;               /**< mass of each particle, > 0 */
    double ks;                 /**< spring stiffness, >= 0 */
    double kd;                 /**< spring damping, >= 0 */
    const size_t *pin;         /**< indices of particles made fixed (pin_count of them) */
    size_t pin_count;          /**< length of pin */
    double muscle_amplitude;   /**< > 0: segment s is a muscle with phase muscle_phase + s·muscle_phase_step */
    double muscle_omega;       /**< muscle angular frequency (rad/s) */
    double muscle_phase;       /**< muscle phase of segment 0 (rad) */
    double muscle_phase_step;  /**< phase added per segment: a travelling wave (rad) */
} psys_chain_def;

/** Cloth sheet: nx×ny particles at origin + (i·spacing)·a1 + (j·spacing)·a2. */
typedef struct psys_cloth_def {
    const char *id;            /**< structure id: particle (i,j) is "id[i,j]"; NULL = no ids */
    double origin[3];          /**< position of particle (0,0) */
    size_t nx, ny;             /**< grid size, each >= 2 */
    double spacing;            /**< grid spacing, > 0 */
    double mass;               /**< mass of each particle, > 0 */
    double ks, kd;             /**< stiffness and damping of structural springs, >= 0 */
    bool shear;                /**< both diagonals of every cell (default true) */
    bool bend;                 /**< springs (i,j)-(i+2,j) and (i,j)-(i,j+2) (default true) */
    double shear_ks, shear_kd; /**< shear spring constants; < 0 (default) = ks, kd */
    double bend_ks, bend_kd;   /**< bend spring constants; < 0 (default) = ks, kd */
    double axes[2][3];         /**< a1, a2: non-zero, not parallel (default e_x, e_y) */
    const size_t *pin;         /**< pin_count grid coordinates made fixed, flattened: i0, j0, i1, j1, ... */
    size_t pin_count;          /**< number of pinned particles */
} psys_cloth_def;

/** Beam: a planar nx×ny lattice with structural springs and both diagonals of every cell (rigid in its plane). */
typedef struct psys_beam_def {
    const char *id;            /**< structure id: particle (i,j) is "id[i,j]"; NULL = no ids */
    double origin[3];          /**< position of particle (0,0) */
    size_t nx, ny;             /**< grid size, each >= 2 */
    double spacing;            /**< grid spacing, > 0 */
    double mass;               /**< mass of each particle, > 0 */
    double ks, kd;             /**< stiffness and damping of every spring, >= 0 */
    double axes[2][3];         /**< a1, a2: non-zero, not parallel (default e_x, e_y) */
    const size_t *pin;         /**< pin_count grid coordinates made fixed, flattened: i0, j0, ... */
    size_t pin_count;          /**< number of pinned particles */
} psys_beam_def;

/** Block (3-D only): nx×ny×nz lattice with edges, face diagonals and body diagonals (holds its shape). */
typedef struct psys_block_def {
    const char *id;            /**< structure id: particle (i,j,k) is "id[i,j,k]"; NULL = no ids */
    double origin[3];          /**< position of particle (0,0,0) */
    size_t nx, ny, nz;         /**< grid size, each >= 2 */
    double spacing;            /**< grid spacing, > 0 */
    double mass;               /**< mass of each particle, > 0 */
    double ks, kd;             /**< stiffness and damping of every spring, >= 0 */
    double axes[3][3];         /**< a1, a2, a3: linearly independent (default e_x, e_y, e_z) */
    const size_t *pin;         /**< pin_count grid coordinates made fixed, flattened: i0, j0, k0, ... */
    size_t pin_count;          /**< number of pinned particles */
} psys_block_def;

/** Wheel: count rim particles on a circle, rim springs, spokes to a hub particle, and cross-bracing. */
typedef struct psys_wheel_def {
    const char *id;            /**< structure id: rim particle i is "id[i]", the hub "id[hub]"; NULL = no ids */
    double center[3];          /**< centre of the rim (and the hub's position) */
    double radius;             /**< rim radius, > 0 */
    size_t count;              /**< number of rim particles, >= 3 */
    double mass;               /**< mass of each particle (rim and hub), > 0 */
    double ks, kd;             /**< stiffness and damping of every spring, >= 0 */
    double axis[3];            /**< 3-D: normal of the wheel's plane (default e_z); ignored in 2-D */
    bool hub;                  /**< add the hub particle and spokes (default true) */
    bool brace;                /**< cross-bracing springs (i, i+2) along the rim (default true) */
    const size_t *pin;         /**< rim indices made fixed (pin_count of them) */
    size_t pin_count;          /**< length of pin */
    bool pin_hub;              /**< make the hub fixed (an axle) */
} psys_wheel_def;

/** Chain defaults: from 0 to e_x, count 2, mass 1, ks 1, kd 0, no pins, no muscle. */
psys_chain_def psys_chain_def_default(void);
/** Cloth defaults: 2×2, spacing 1, mass 1, ks 1, kd 0, shear and bend on (same constants), axes e_x, e_y. */
psys_cloth_def psys_cloth_def_default(void);
/** Beam defaults: 2×2, spacing 1, mass 1, ks 1, kd 0, axes e_x, e_y. */
psys_beam_def psys_beam_def_default(void);
/** Block defaults: 2×2×2, spacing 1, mass 1, ks 1, kd 0, axes e_x, e_y, e_z. */
psys_block_def psys_block_def_default(void);
/** Wheel defaults: radius 1, count 8, mass 1, ks 1, kd 0, axis e_z, hub and brace on. */
psys_wheel_def psys_wheel_def_default(void);

/** Add a chain; its first particle's index goes to *first_index (may be NULL). Nothing is added on failure. */
psys_status psys_system_add_chain(psys_system *sys, const psys_chain_def *def, size_t *first_index);
/** Add a cloth sheet (see psys_cloth_def); nothing is added on failure. */
psys_status psys_system_add_cloth(psys_system *sys, const psys_cloth_def *def, size_t *first_index);
/** Add a beam (see psys_beam_def); nothing is added on failure. */
psys_status psys_system_add_beam(psys_system *sys, const psys_beam_def *def, size_t *first_index);
/** Add a block (3-D systems only); nothing is added on failure. */
psys_status psys_system_add_block(psys_system *sys, const psys_block_def *def, size_t *first_index);
/** Add a wheel (rim particles first, then the hub); nothing is added on failure. */
psys_status psys_system_add_wheel(psys_system *sys, const psys_wheel_def *def, size_t *first_index);

/** Make spring k a muscle: rest length r(t) = rest·(1 + amplitude·sin(omega·t + phase)), amplitude 0..1 (0 removes it). */
psys_status psys_system_set_spring_muscle(psys_system *sys, size_t k, double amplitude, double omega, double phase);
/** True if spring k is a muscle; its parameters go to the out pointers (each may be NULL). */
bool psys_system_spring_muscle(const psys_system *sys, size_t k, double *amplitude, double *omega, double *phase);
/** Rest length of spring k at time t (the muscle's r(t), else its fixed rest length; NaN if no spring k). */
double psys_system_spring_rest_length(const psys_system *sys, size_t k, double t);

/* ------------------------------------------------------------------ */
/* Spatial interaction (notes §4.3): pair forces, charges, periodic    */
/* boxes, threads. docs/scene-format.md "Pair forces" has the laws.    */
/* ------------------------------------------------------------------ */

/** Pair law: the force between every two particles as a function of their distance r. */
typedef enum psys_pair_law {
    PSYS_PAIR_GRAVITY = 0,     /**< U = -G m_i m_j / sqrt(r² + softening²) */
    PSYS_PAIR_COULOMB,         /**< U = k q_i q_j / r (charges: psys_system_set_charge) */
    PSYS_PAIR_LENNARD_JONES,   /**< U = 4ε[(σ/r)¹² - (σ/r)⁶] for r < cutoff (minus U(cutoff) with shift), else 0 */
    PSYS_PAIR_SOFT_REPULSION,  /**< U = ½ k (radius - r)² for r < radius, else 0 */
    PSYS_PAIR_USER             /**< force and potential from a callback (no scene form) */
} psys_pair_law;

/** How pairs are found. */
typedef enum psys_pair_method {
    PSYS_PAIR_AUTO = 0,        /**< grid when the law has a cutoff, else direct */
    PSYS_PAIR_DIRECT,          /**< all pairs, O(n²), blocked for cache */
    PSYS_PAIR_GRID,            /**< cell lists + Verlet neighbour lists with a skin, O(n); laws with a cutoff */
    PSYS_PAIR_BARNES_HUT       /**< quadtree (2-D) / octree (3-D), opening angle theta; gravity and coulomb */
} psys_pair_method;

/** A user pair law: return F(r) = -dU/dr (> 0 repels) at distance r > 0 and,
 *  when u is not NULL, store U(r) there. Called concurrently from several
 *  threads: it must not modify shared state. */
typedef double (*psys_pair_fn)(void *ctx, double r, double *u);

/** Definition of a pair force (start from psys_pair_def_default()). The
 *  force acts between every two different particles of the system, fixed
 *  and controlled ones included; coincident particles (r = 0) exert no force
 *  on each other (and no energy, except softened gravity's -G m m/softening). */
typedef struct psys_pair_def {
    psys_pair_law law;         /**< the law (default gravity) */
    psys_pair_method method;   /**< default PSYS_PAIR_AUTO */
    double G;                  /**< gravity: constant (default 1) */
    double softening;          /**< gravity: Plummer softening >= 0 (default 0 = Newtonian) */
    double k;                  /**< coulomb: constant; soft-repulsion: stiffness >= 0 (default 1) */
    double epsilon, sigma;     /**< lennard-jones: well depth >= 0, size > 0 (default 1, 1) */
    double cutoff;             /**< lennard-jones: > 0, default (<= 0) 2.5·sigma; user: 0 = none */
    bool shift;                /**< lennard-jones: subtract U(cutoff) so U is 0 there (default false) */
    double radius;             /**< soft-repulsion: interaction radius > 0 (default 1) */
    double skin;               /**< grid: Verlet skin >= 0; < 0 (default) = 0.1·cutoff */
    double theta;              /**< barnes-hut: opening angle >= 0 (default 0.5; 0 = exact) */
    psys_pair_fn fn;           /**< user: the law */
    void *ctx;                 /**< user: passed to fn; must outlive the system */
} psys_pair_def;

/** Defaults as documented on psys_pair_def. */
psys_pair_def psys_pair_def_default(void);
/** Add a pair force (one force object; its index goes to *force_index, may
 *  be NULL). Neighbour/cell/tree storage is allocated here for the current
 *  particles and grows only when a rebuild needs more. */
psys_status psys_system_add_pair(psys_system *sys, const psys_pair_def *def, size_t *force_index);
/** Definition of force object i if it is a pair force (defaults and method
 *  resolved); PSYS_ERR_INVALID otherwise. */
psys_status psys_system_pair(const psys_system *sys, size_t i, psys_pair_def *def);
/** Scene name of a law ("lennard-jones", ...), NULL for PSYS_PAIR_USER. */
const char *psys_pair_law_name(psys_pair_law law);
/** Scene name of a method ("direct", "grid", "barnes-hut"; "auto"). */
const char *psys_pair_method_name(psys_pair_method method);

/** Counters of a pair force, for tests and benchmarks. */
typedef struct psys_pair_stats {
    size_t evaluations;  /**< force/energy/Jacobian evaluations so far */
    size_t rebuilds;     /**< grid: neighbour-list builds; barnes-hut: tree builds */
    size_t pairs;        /**< grid: pairs closer than cutoff + skin at the last build (each counted once) */
    size_t cells;        /**< grid: cells at the last build */
    size_t nodes;        /**< barnes-hut: tree nodes at the last build */
    size_t fallbacks;    /**< evaluations done by the direct method because storage could not grow */
    size_t partial;      /**< grid: force evaluations that recomputed only the particles near moved ones */
    size_t partial_rows; /**< grid: particles' forces recomputed by the partial evaluations, in all */
} psys_pair_stats;
/** Counters of pair force object i. */
psys_status psys_system_pair_stats(const psys_system *sys, size_t i, psys_pair_stats *stats);

/** The force class of pair forces with built-in laws (scenes can hold them). */
extern const psys_force_class psys_pair_class;
/** The force class of pair forces with user laws (no scene form). */
extern const psys_force_class psys_pair_user_class;

/** Charge of particle i for coulomb pair forces (default 0). */
psys_status psys_system_set_charge(psys_system *sys, size_t i, double q);
/** Charge of particle i (0 if never set or no such particle). */
double psys_system_charge(const psys_system *sys, size_t i);

/** Set the simulation box: lo < hi on every axis; periodic[k] makes axis k
 *  periodic (positions wrap into [lo, hi) after every step taken by
 *  psys_system_advance, velocities unchanged; pair forces use the minimum
 *  image). Fails if a pair force has no cutoff or a cutoff >= half the box
 *  on a periodic axis. lo == NULL removes the box. */
psys_status psys_system_set_box(psys_system *sys, const double *lo, const double *hi, const bool *periodic);
/** True if the system has a box; its corners and flags go to the out pointers (each may be NULL). */
bool psys_system_box(const psys_system *sys, double *lo, double *hi, bool *periodic);
/** Wrap free particles' positions into the box on periodic axes (done by psys_system_advance). */
void psys_system_wrap_positions(psys_system *sys);

/** Threads for parallel force evaluation (0 = the OpenMP default). Results
 *  are bit-identical for every thread count. Loops too small to gain run on
 *  one thread (with an explicit count: below about a thousand pair
 *  evaluations; by default: below about 65,000). */
psys_status psys_system_set_threads(psys_system *sys, int threads);
/** Threads the system asks for (0 = the OpenMP default). */
int psys_system_threads(const psys_system *sys);
/** Threads large evaluations use (1 in a build without OpenMP). */
int psys_system_effective_threads(const psys_system *sys);

/* ------------------------------------------------------------------ */
/* Scenes (JSON, docs/scene-format.md)                                 */
/* ------------------------------------------------------------------ */

/** Run settings that come with a scene. */
typedef struct psys_settings {
    char integrator[32];   /**< solver name */
    double dt;             /**< step (first step for rk45) */
    bool use_steps;        /**< true: run `steps` steps; false: run `duration` */
    long long steps;       /**< number of steps when use_steps */
    double duration;       /**< simulated time when !use_steps */
    double tolerance;      /**< rk45 local error tolerance */
    long long every;       /**< steps between output frames (>= 1) */
    char trajectory[1024]; /**< output.trajectory ("" for none) */
    char energy[1024];     /**< output.energy ("" for none) */
    char render[1024];     /**< output.render ("" for none) */
    double cg_tolerance;   /**< implicit-euler: relative CG residual per step */
    long long cg_max_iterations; /**< implicit-euler: CG iteration cap per step */
    double render_radius;  /**< output.radius: particle radius for pictures (scene units; 0 = automatic) */
} psys_settings;

/** Clock and solver state saved in a checkpoint. */
typedef struct psys_resume_state {
    bool present;        /**< true if the scene carried a checkpoint */
    long long step;      /**< steps taken so far */
    double t;            /**< time reached */
    long long base_step; /**< t = base_t + (step - base_step) * dt for fixed steps */
    double base_t;       /**< see base_step */
    double next_h;       /**< adaptive solver's next step (0 if none) */
} psys_resume_state;

/** A loaded scene: the system and its run settings. */
typedef struct psys_scene psys_scene;

/** Settings with the defaults of docs/scene-format.md#top-level-keys
 * (rk4, dt 0.001, duration 1, ...). */
psys_settings psys_settings_default(void);

/** Parse a scene from memory; name is used in messages. On failure returns
 *  NULL and err holds "JSON.PATH: problem (got VALUE)". */
psys_scene *psys_scene_load_string(const char *text, size_t len, psys_error *err);
/** Parse a scene file ("-" reads standard input). */
psys_scene *psys_scene_load_file(const char *path, psys_error *err);
/** Free a scene and its system. */
void psys_scene_destroy(psys_scene *scene);
/** The scene's system (owned by the scene). */
psys_system *psys_scene_system(psys_scene *scene);
/** The scene's run settings (modifiable, e.g. by command-line flags). */
psys_settings *psys_scene_settings(psys_scene *scene);
/** Checkpoint state carried by the scene, if any. */
const psys_resume_state *psys_scene_resume_state(const psys_scene *scene);
/** Serialise the scene (structures expanded) as JSON text; free() the result.
 *  With resume != NULL a "checkpoint" object is written too. */
char *psys_scene_to_string(const psys_scene *scene, const psys_resume_state *resume, psys_error *err);

/* ------------------------------------------------------------------ */
/* Runs (docs/semantics.md#steps-and-frames, #checkpoints): steps,     */
/* duration, frames, checkpoints                                       */
/* ------------------------------------------------------------------ */

/** Steps a scene's system according to its settings. */
typedef struct psys_run psys_run;

/** Prepare a run of scene (not owned) with its current settings; when the
 *  scene carries a checkpoint, the run continues from it. */
psys_run *psys_run_create(psys_scene *scene, psys_error *err);
/** Free a run. */
void psys_run_destroy(psys_run *run);
/** Steps taken so far (counting from the start of the simulation). */
long long psys_run_step_index(const psys_run *run);
/** Step index at which this run ends. */
long long psys_run_final_step(const psys_run *run);
/** True once the run has reached its end. */
bool psys_run_done(const psys_run *run);
/** True if the current state is an output frame (every-th step or the end). */
bool psys_run_is_frame(const psys_run *run);
/** Advance by one step (rk45: one accepted step). On PSYS_ERR_NONFINITE the
 *  state stays the last good one and err names step, time and particle. */
psys_status psys_run_step(psys_run *run, psys_error *err);
/** Fraction of the run done, 0..1. */
double psys_run_progress(const psys_run *run);
/** Clock and solver state to store in a checkpoint. */
psys_resume_state psys_run_resume_state(const psys_run *run);
/** The solver in use. */
const psys_solver *psys_run_solver(const psys_run *run);

/* ------------------------------------------------------------------ */
/* Output files (docs/cli.md#output-files)                             */
/* ------------------------------------------------------------------ */

/** Write the trajectory CSV header (step,t,i,x,y[,z],vx,vy[,vz]). */
int psys_csv_write_trajectory_header(FILE *fp, int dim);
/** Write one trajectory frame: a row per particle, %.17g numbers. */
int psys_csv_write_trajectory_frame(FILE *fp, const psys_system *sys, long long step);
/** Write the energy CSV header (step,t,kinetic,potential,total). */
int psys_csv_write_energy_header(FILE *fp);
/** Write one energy row. */
int psys_csv_write_energy_frame(FILE *fp, const psys_system *sys, long long step);

/* ---- Trajectory formats for ParaView, OVITO and ASE (docs/cli.md) ----
 * One call writes one frame; the caller owns the files (the CLI writes each
 * under a temporary name and renames it when complete). Numbers are %.17g;
 * 2-D systems are written with z = 0. All return 0, or -1 on a write error. */

/** VTK XML PolyData (ASCII inline data), one whole file per frame: particles
 *  as points (and vertex cells) with point data `velocity` (3 components),
 *  `mass`, `flags` (PSYS_PARTICLE_* bits) and `index`; springs as lines; field
 *  data `TimeValue` and `step`. */
int psys_vtp_write_frame(FILE *fp, const psys_system *sys, long long step);
/** The same frame in the legacy VTK format (ASCII POLYDATA, version 3.0). */
int psys_vtk_write_frame(FILE *fp, const psys_system *sys, long long step);
/** ParaView data series (.pvd): the opening lines. */
int psys_pvd_write_header(FILE *fp);
/** One .pvd entry: frame file `file` (relative to the .pvd, XML-escaped here) at time t. */
int psys_pvd_write_entry(FILE *fp, double t, const char *file);
/** The closing lines of a .pvd file. */
int psys_pvd_write_footer(FILE *fp);
/** One frame of extended XYZ: the particle count, then a comment line
 *  `Properties=species:S:1:pos:R:3:velo:R:3:mass:R:1:id:I:1:flags:I:1 Time=t
 *  step=k pbc="F F F"`, then a row per particle (species is always X). */
int psys_xyz_write_frame(FILE *fp, const psys_system *sys, long long step);

/* ---- Drawing (Box2D b2DebugDraw style) ----
 * The library never draws: psys_system_draw walks the system and calls the
 * callbacks of a psys_draw that a renderer implements (the CLI's headless
 * cairo renderer; an OpenGL viewer). Points are dim numbers in scene units.
 * Initialise with psys_draw d = {0} (or memset) and set what you draw: NULL
 * callbacks are skipped, and members added in later versions stay NULL. */

/** A renderer seen by psys_system_draw. Calls come in this order: begin,
 *  every plane, every guide, every spring, every link, every particle (in
 *  index order), end. */
typedef struct psys_draw {
    void *ctx;      /**< passed back to every callback */
    /** Radius, in scene units, of a particle of the system's typical
     *  (geometric-mean) mass; particle i gets radius·(m_i/m_typical)^(1/3),
     *  clamped to [radius/2, 2·radius] (equal masses: exactly radius). */
    double radius;
    /** Called first: dimension (2 or 3) and the system's time. */
    void (*begin)(void *ctx, int dim, double t);
    /** A plane (a line in 2-D) through point with unit normal (pointing to the allowed side). */
    void (*plane)(void *ctx, const double *point, const double *normal);
    /** A spring from a to b. strain = (|b - a| - r)/r with r its current rest
     *  length (a muscle's r(t)); 0 when r is 0. */
    void (*spring)(void *ctx, const double *a, const double *b, double strain);
    /** Particle i at x with its radius; flags are PSYS_PARTICLE_FIXED / PSYS_PARTICLE_CONTROLLED. */
    void (*particle)(void *ctx, size_t i, const double *x, double radius, unsigned flags);
    /** Called last. */
    void (*end)(void *ctx);
    /** A behaviour function (soft constraint) joining two particles:
     *  `distance`, `coincide`, each arm of an `angle` (a-b, b-c), and
     *  consecutive particles of a user function. */
    void (*link)(void *ctx, const double *a, const double *b);
    /** What a one-particle behaviour holds its particle to: a plane (line in
     *  2-D) through point with unit normal for `point-on-plane` (radius < 0),
     *  or a sphere (circle) of radius about point for `point-on-sphere` (normal NULL). */
    void (*guide)(void *ctx, const double *point, const double *normal, double radius);
} psys_draw;

/** Draw the current state of sys through draw (see psys_draw). */
psys_status psys_system_draw(const psys_system *sys, const psys_draw *draw);
/** Axis-aligned bounds of the particle positions into lo and hi (dim numbers
 *  each); PSYS_ERR_INVALID (lo = hi = 0) when the system has no particles. */
psys_status psys_system_bounds(const psys_system *sys, double *lo, double *hi);
/* ---- end of drawing ---- */

#ifdef __cplusplus
}
#endif
#endif
