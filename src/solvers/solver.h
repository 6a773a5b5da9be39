/* Solver internals: a small vtable per solver kind (REBOUND-style registry). */
#ifndef PSYS_SOLVER_H
#define PSYS_SOLVER_H

#include "base/base.h"
#include "solvers/jacobian.h"
#include "solvers/solver_fast.h"

/** Butcher tableau of an explicit Runge–Kutta method (optionally embedded). */
typedef struct psys__tableau {
    int stages;
    double a[7][7];   /* strictly lower triangular */
    double b[7];      /* weights of the propagated solution */
    double bhat[7];   /* weights of the embedded solution (adaptive only) */
    double c[7];      /* stage times */
} psys__tableau;

typedef struct psys__solver_class psys__solver_class;

#define PSYS__MAX_BUFS 12

struct psys_solver {
    const psys__solver_class *cls;
    psys_ode ode;
    psys__ode_fast fast;  /* the ODE's fast paths (psys__solver_create_fast), all NULL for a user's ODE */
    psys_system *owner;   /* the system whose own ODE ode is (psys_system_solver_create), or NULL */
    size_t n;
    size_t cap;                  /* length the scratch vectors hold (>= n; psys__solver_rebind) */
    double *buf[PSYS__MAX_BUFS]; /* scratch vectors of length n, allocated once */
    double tol;
    int threads;      /* psys_solver_set_threads: 0 = OpenMP's default */
    double h_next;
    size_t rejected;
    size_t bad;
    /* The stages found every component of the result finite and project
     * changes none (psys__stage_pass.finite): commit need not look again.
     * Set just before a successful commit; commit clears it. */
    bool y1_finite;
    /* The ODE wrote the result into its state itself and the step's start
     * into y1 (psys__stage_pass.in_place; rk solvers: rk_commit_in_state). */
    bool y1_in_state;
    psys_error err;
    /* implicit solvers */
    void *impl;               /* solver-kind state (e.g. the sparse matrix) */
    double cg_tol;
    int cg_maxit;
    size_t cg_unconverged, cg_iterations;
    double cg_worst;
};

struct psys__solver_class {
    const char *name;
    int order;
    bool adaptive;
    bool second_order_only;      /* needs ode.npos * 2 == ode.size */
    bool elementwise;            /* a step treats each state component alone (no sums across
                                    components): any order of them gives the same bits */
    int nbuf;                    /* scratch vectors needed */
    const psys__tableau *tab;    /* for Runge–Kutta kinds */
    psys_status (*step)(psys_solver *s, double h_max, double *h_taken);
    psys_status (*init)(psys_solver *s); /* optional: allocate s->impl */
    void (*fini)(psys_solver *s);        /* optional: free s->impl */
};

extern const psys__solver_class psys__euler, psys__midpoint, psys__rk4, psys__rk45;
extern const psys__solver_class psys__symplectic_euler, psys__verlet, psys__implicit_euler;

/** Threads for the solver's elementwise passes (at least 1). */
int psys__solver_threads(const psys_solver *s);
/** Project y1 at t1, check it is finite, then set_state(y1) and set_time(t1). */
psys_status psys__solver_commit(psys_solver *s, double *y1, double t1);
/* The first non-finite of the n components of y (whatever the thread
 * count), or SIZE_MAX. */
size_t psys__solver_first_nonfinite(const psys_solver *s, const double *y);
/* PSYS_ERR_NONFINITE for state component bad (psys_solver_bad_component). */
psys_status psys__solver_nonfinite(psys_solver *s, size_t bad);
/** Point the solver at another ODE of the same kind but maybe another size
 *  (an MPI domain's local particles after a migration), keeping its
 *  settings and step-size state but no fast paths or owner (they belonged
 *  with the old ODE); the scratch vectors grow only when the new size
 *  exceeds their length. PSYS_ERR_UNSUPPORTED for solvers with state of
 *  their own (implicit), PSYS_ERR_NOMEM if they cannot grow (unchanged then). */
psys_status psys__solver_rebind(psys_solver *s, const psys_ode *ode);
/** Evaluate the derivative at (t, y) after projecting prescribed components. */
psys_status psys__solver_eval(psys_solver *s, double t, double *y, double *ydot);
/** psys__solver_eval for solvers of second-order systems: through
 *  fast.acceleration where there is one, so only ydot[npos..size) is sure
 *  to be written. */
psys_status psys__solver_eval_accel(psys_solver *s, double t, double *y, double *ydot);

#endif
