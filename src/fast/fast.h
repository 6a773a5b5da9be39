/* The fast layer: the fused one-sweep derivative of springs and
 * per-particle forces, and the springs' internal state order. */
#ifndef PSYS_FAST_H
#define PSYS_FAST_H

#include "forces/forces.h"
#include "solvers/solver_fast.h"

/** The derivative [v | f/m] of sys at (e->t, y) in one pass over memory when
 *  its forces are springs and per-particle forces only (fast/fused.c),
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

/** Whether the steps timed to choose between equivalent code paths are
 *  over: for rk4 and midpoint on springs that reach far, the first six
 *  steps after the springs, particle count or threads change time every
 *  stage in one sweep against stage by stage. The results are the same
 *  bits either way; benchmarks step until this holds. */
bool psys__system_timing_settled(const psys_system *sys);

#endif
