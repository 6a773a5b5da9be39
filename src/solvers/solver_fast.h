/* The solver layer's private fast paths: callbacks that only the particle
 * system's own ODE offers (psys_system_solver_create), never a user's
 * psys_ode, so a wrapped ODE cannot carry hooks of the ODE it wraps. */
#ifndef PSYS_SOLVER_FAST_H
#define PSYS_SOLVER_FAST_H

#include "psys/psys.h"

/** What a stage pass does with acc[j] for the stage's derivative k[j]. The
 *  values and expressions are those of rk_chain_stages, element by element
 *  (the same bits either way). */
typedef enum psys__acc_op {
    PSYS__ACC_SET = 0,        /**< acc[j] = 0 + w k: first of several weights, more stages to come */
    PSYS__ACC_ADD = 1,        /**< acc[j] = acc[j] + w k: a later weight, more stages to come */
    PSYS__ACC_BASE_STEP = 2,  /**< acc[j] = base[j] + h (w k): the only weight */
    PSYS__ACC_BASE_FIRST = 3, /**< acc[j] = base[j] + h (0 + w k): first weight, last stage */
    PSYS__ACC_BASE_SUM = 4    /**< acc[j] = base[j] + h (acc[j] + w k): last of several weights */
} psys__acc_op;

/** Per-component work that an explicit Runge–Kutta solver whose stage i uses
 *  only stage i−1 (euler, midpoint, rk4) does with the derivative k of a
 *  stage: derivative_stage applies it to each component j of k as it
 *  computes it, instead of storing k (one sweep over memory, not two).
 *  acc and next never overlap each other, base or the stage's state y. */
typedef struct psys__stage_pass {
    double h;            /**< step */
    const double *base;  /**< y0, the state at the start of the step */
    double *acc;         /**< weighted sum of the stages, NULL when this stage has weight 0 */
    double w;            /**< this stage's weight */
    psys__acc_op acc_op; /**< what to do with acc (the PSYS__ACC_BASE_* ones complete the step) */
    double *next;        /**< next stage's state base[j] + h (a k), NULL after the last stage */
    double a;            /**< the next stage's coefficient of this one */
    /** Optional (NULL: not asked), on the pass that completes acc: the ODE
     *  may set *finite to 1 when every component it wrote to acc is finite
     *  and project would change none of them (the solver then skips its own
     *  pass over the result), or to 0; left as it was when it does not look. */
    int *finite;
    /** Optional (NULL: not offered), only with derivative_chain_current, on
     *  its last pass: the ODE may write the step's result into its current
     *  state itself and the step's start into acc instead (the two swapped),
     *  setting *in_place to 1, and only when project would change none of
     *  the result. The solver then keeps the state as the step's result, or
     *  puts acc back (set_state) when it refuses the result. */
    int *in_place;
} psys__stage_pass;

/** The fast paths of one ODE, each optional (NULL), each taking that
 *  ODE's ctx and giving the bits of its plain callbacks. */
typedef struct psys__ode_fast {
    /** Evaluate the derivative at (t, y) and apply pass to it without
     *  storing it. PSYS_ERR_UNSUPPORTED when it cannot (the solver then does
     *  the two itself); with y and pass NULL it only answers whether it can. */
    psys_status (*derivative_stage)(void *ctx, double t, const double *y, const psys__stage_pass *pass);
    /** For second-order systems: derivative with only the accelerations
     *  ydot[npos..size) required (symplectic-euler and verlet). */
    psys_status (*acceleration)(void *ctx, double t, const double *y, double *ydot);
    /** True when the accelerations do not depend on the velocities (asked
     *  every step): verlet then evaluates its second stage at [x1 | v½]. */
    bool (*velocity_free)(void *ctx);
    /** Every stage of a chain Runge–Kutta step at once: stage i at time
     *  t + c[i]·pass[i].h on y_i (y_0 = y0, y_{i+1} = pass[i].next) with
     *  pass[i] applied; the bits of project and derivative_stage stage after
     *  stage. PSYS_ERR_UNSUPPORTED when it cannot; y0 NULL only asks. */
    psys_status (*derivative_chain)(void *ctx, double t, const double *y0, int stages, const double *c,
                                    const psys__stage_pass *pass);
    /** derivative_chain from the current state where it is (every pass's
     *  base NULL stands for it), so the solver need not copy it; called only
     *  after derivative_chain accepted the step. PSYS_ERR_UNSUPPORTED, with
     *  nothing done, sends the solver to derivative_chain with a copy. */
    psys_status (*derivative_chain_current)(void *ctx, double t, int stages, const double *c,
                                            const psys__stage_pass *pass);
} psys__ode_fast;

/** psys_solver_create with fast paths for ode (fast may be NULL), for the
 *  system `owner` (NULL: none) whose own ODE ode is. */
psys_solver *psys__solver_create_fast(const char *name, const psys_ode *ode, const psys__ode_fast *fast,
                                      psys_system *owner, psys_error *err);
/** The system the solver was created for by psys_system_solver_create
 *  (NULL for every other solver). */
psys_system *psys__solver_owner(const psys_solver *s);
/** Length of the state vector the solver steps. */
size_t psys__solver_size(const psys_solver *s);
/** True when a step treats each state component alone (no sums across
 *  components), so any order of them gives the same bits. */
bool psys__solver_elementwise(const psys_solver *s);

#endif
