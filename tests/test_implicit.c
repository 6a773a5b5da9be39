/* implicit-euler: the linearised backward Euler of Baraff & Witkin (1998),
 *   (M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f0 + h ∂f/∂x v0),  v1 = v0 + Δv,  x1 = x0 + h v1,
 * checked against things computed independently of the solver:
 *   - every force's Jacobian against central finite differences of its force;
 *   - single steps against closed forms (linear springs, free fall) and
 *     against a dense Gaussian-elimination solve of the same linear system;
 *   - the definite approximation of compressed, moving damped springs;
 *   - filtering of fixed and controlled particles, momentum conservation;
 *   - measured first-order convergence against an rk4 reference;
 *   - stability where explicit solvers blow up (stiff spring, 20×20 cloth);
 *   - the conjugate-gradient settings, counters and scene keys. */
#include "check.h"
#include "helpers.h"

#include <psys/psys.h>

#include <math.h>
#include <string.h>

#define MAXN 64 /* state components of the small systems solved densely here */

/* Under AddressSanitizer (the Debug sanitizer build) the 400-particle cloth
 * is too slow for its whole 5-second run (bench/HISTORY.md), so that
 * build runs only its first few steps (finiteness, pins, energy); the
 * settling checks run in the normal build. */
#if defined(__SANITIZE_ADDRESS__)
#define SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SANITIZED 1
#endif
#endif
#ifndef SANITIZED
#define SANITIZED 0
#endif

/* Unlike helpers.h's add_particle, stops the test at once, as add_spring does. */
static size_t add_particle_or_exit(psys_system *sys, const double *x, const double *v, double m)
{
    size_t i = (size_t)-1;
    if (psys_system_add_particle(sys, x, v, m, NULL, &i) != PSYS_OK) {
        fprintf(stderr, "add_particle: %s\n", psys_system_last_error(sys));
        exit(1);
    }
    return i;
}

static void add_spring(psys_system *sys, size_t a, size_t b, double ks, double kd, double rest)
{
    if (psys_system_add_spring(sys, a, b, ks, kd, rest) != PSYS_OK) {
        fprintf(stderr, "add_spring: %s\n", psys_system_last_error(sys));
        exit(1);
    }
}

/* One step that must succeed (prints the solver's message otherwise). */
static int step_ok(psys_solver *s, double h)
{
    double taken = -1;
    psys_status st = psys_solver_step(s, h, &taken);
    if (st != PSYS_OK) {
        fprintf(stderr, "step failed: %s\n", psys_solver_last_error(s));
        return 0;
    }
    return taken == h;
}

static size_t ncomp(const psys_system *sys) { return psys_system_count(sys) * (size_t)psys_system_dim(sys); }

static void get_state(const psys_system *sys, double *x, double *v)
{
    size_t nd = ncomp(sys);
    memcpy(x, psys_system_positions(sys), nd * sizeof(double));
    memcpy(v, psys_system_velocities(sys), nd * sizeof(double));
}

/* Largest |a - b| over n numbers. */
static double max_diff(const double *a, const double *b, size_t n)
{
    double w = 0;
    for (size_t i = 0; i < n; i++)
        if (!(fabs(a[i] - b[i]) <= w))
            w = fabs(a[i] - b[i]);
    return w;
}

/* Euclidean norm of a - b over n numbers. */
static double norm_diff(const double *a, const double *b, size_t n)
{
    double w = 0;
    for (size_t i = 0; i < n; i++)
        w += (a[i] - b[i]) * (a[i] - b[i]);
    return sqrt(w);
}

static double max_abs(const double *a, size_t n)
{
    double w = 0;
    for (size_t i = 0; i < n; i++)
        if (!(fabs(a[i]) <= w))
            w = fabs(a[i]);
    return w;
}

/* Solve A z = b (n×n, row-major, overwritten) by Gaussian elimination with
 * partial pivoting; returns 0 if A is singular. */
static int dense_solve(double *A, double *b, double *z, size_t n)
{
    for (size_t c = 0; c < n; c++) {
        size_t piv = c;
        for (size_t r = c + 1; r < n; r++)
            if (fabs(A[r * n + c]) > fabs(A[piv * n + c]))
                piv = r;
        if (A[piv * n + c] == 0)
            return 0;
        if (piv != c) {
            for (size_t k = 0; k < n; k++) {
                double t = A[c * n + k];
                A[c * n + k] = A[piv * n + k];
                A[piv * n + k] = t;
            }
            double t = b[c];
            b[c] = b[piv];
            b[piv] = t;
        }
        for (size_t r = c + 1; r < n; r++) {
            double f = A[r * n + c] / A[c * n + c];
            for (size_t k = c; k < n; k++)
                A[r * n + k] -= f * A[c * n + k];
            b[r] -= f * b[c];
        }
    }
    for (size_t c = n; c-- > 0;) {
        double s = b[c];
        for (size_t k = c + 1; k < n; k++)
            s -= A[c * n + k] * z[k];
        z[c] = s / A[c * n + c];
    }
    return 1;
}

/* One linearised backward-Euler step of sys from its current state, solved
 * densely (independently of the library's assembly and CG):
 *   (M - h dfdv - h² dfdx) Δv = h (f0 + h dfdx v0)  on the free components,
 * Δv = 0 on fixed particles. dfdx/dfdv: the Jacobian to use (nd × nd), or
 * NULL for the system's own dense (exact) Jacobian. Writes x1, v1 (nd each);
 * fixed particles keep x0 and v0 = 0. The system is not changed. */
static void reference_step(psys_system *sys, double h, const double *dfdx_in, const double *dfdv_in, double *x1,
                           double *v1)
{
    size_t nd = ncomp(sys), n = psys_system_count(sys);
    int d = psys_system_dim(sys);
    static double dfdx[MAXN * MAXN], dfdv[MAXN * MAXN], A[MAXN * MAXN];
    double x0[MAXN], v0[MAXN], f0[MAXN], b[MAXN], z[MAXN];
    size_t map[MAXN], nf = 0;
    if (nd > MAXN) {
        fprintf(stderr, "reference_step: system too large\n");
        exit(1);
    }
    get_state(sys, x0, v0);
    CHECK(psys_system_compute_forces(sys, f0) == PSYS_OK);
    if (dfdx_in) {
        memcpy(dfdx, dfdx_in, nd * nd * sizeof(double));
        memcpy(dfdv, dfdv_in, nd * nd * sizeof(double));
    } else {
        CHECK(psys_system_dense_jacobian(sys, dfdx, dfdv) == PSYS_OK);
    }
    const double *mass = psys_system_masses(sys);
    for (size_t i = 0; i < n; i++)
        if (!psys_system_is_fixed(sys, i) && !psys_system_is_controlled(sys, i))
            for (int c = 0; c < d; c++)
                map[nf++] = i * (size_t)d + (size_t)c;
    for (size_t r = 0; r < nf; r++) {
        size_t p = map[r];
        double kv = 0;
        for (size_t q = 0; q < nd; q++)
            kv += dfdx[p * nd + q] * v0[q];
        b[r] = h * (f0[p] + h * kv);
        for (size_t c = 0; c < nf; c++) {
            size_t q = map[c];
            A[r * nf + c] = (p == q ? mass[p / (size_t)d] : 0.0) - h * dfdv[p * nd + q] - h * h * dfdx[p * nd + q];
        }
    }
    CHECK(dense_solve(A, b, z, nf));
    memcpy(x1, x0, nd * sizeof(double));
    memcpy(v1, v0, nd * sizeof(double));
    for (size_t r = 0; r < nf; r++) {
        size_t p = map[r];
        v1[p] = v0[p] + z[r];
        x1[p] = x0[p] + h * v1[p];
    }
}

/* ------------------------------------------------------------------ */
/* 1. Force Jacobians against central finite differences               */
/* ------------------------------------------------------------------ */

/* The system's dense Jacobian (what an implicit solver gets when it does not
 * ask for a definite one) against central differences of its forces:
 * |J - J_fd| <= tol·(1 + max|J_fd|) entrywise. Returns the worst error. */
static double jacobian_error(psys_system *sys, double eps)
{
    size_t nd = ncomp(sys);
    static double jx[MAXN * MAXN], jv[MAXN * MAXN], fx[MAXN * MAXN], fv[MAXN * MAXN];
    CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
    CHECK(psys_system_fd_jacobian(sys, eps, fx, fv) == PSYS_OK);
    double ex = max_diff(jx, fx, nd * nd) / (1 + max_abs(fx, nd * nd));
    double ev = max_diff(jv, fv, nd * nd) / (1 + max_abs(fv, nd * nd));
    return ex > ev ? ex : ev;
}

/* Damped springs in every state the definite approximation would change:
 * stretched and compressed, with relative velocities along and across the
 * springs (so the damping part of ∂f/∂x is large), a fixed end. */
static void spring_system(psys_system *sys)
{
    const double x[5][3] = {{0, 0, 0}, {1.1, 0.2, -0.1}, {0.3, 0.9, 0.4}, {-0.5, 0.4, 1.0}, {0.6, -0.7, 0.8}};
    const double v[5][3] = {{0, 0, 0}, {0.7, -1.2, 0.4}, {-0.5, 0.3, 0.9}, {1.1, 0.6, -0.8}, {-0.2, -0.9, 0.3}};
    for (int i = 0; i < 5; i++)
        add_particle_or_exit(sys, x[i], v[i], 0.5 + 0.25 * i);
    CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
    add_spring(sys, 0, 1, 40, 1.5, 0.7);  /* stretched */
    add_spring(sys, 1, 2, 25, 2.0, 1.6);  /* compressed */
    add_spring(sys, 2, 3, 60, 0.8, 0.5);  /* stretched */
    add_spring(sys, 0, 3, 30, 1.2, 2.0);  /* compressed */
    add_spring(sys, 3, 4, 15, 3.0, 1.9);  /* compressed */
    add_spring(sys, 1, 4, 50, 0.5, 0.2);  /* stretched */
}

static void jacobian_springs_2d(void)
{
    psys_system *sys = make_system(2);
    spring_system(sys);
    double e = jacobian_error(sys, 1e-6);
    if (!(e <= 1e-7))
        fprintf(stderr, "2-D spring Jacobian error %.3g\n", e);
    CHECK(e <= 1e-7);
    psys_system_destroy(sys);
}

static void jacobian_springs_3d(void)
{
    psys_system *sys = make_system(3);
    spring_system(sys);
    double e = jacobian_error(sys, 1e-6);
    if (!(e <= 1e-7))
        fprintf(stderr, "3-D spring Jacobian error %.3g\n", e);
    CHECK(e <= 1e-7);
    psys_system_destroy(sys);
}

static void jacobian_drag_mouse_gravity(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys = make_system(dim);
        const double x0[3] = {0.3, -0.4, 0.2}, v0[3] = {1.5, -0.7, 0.4};
        const double x1[3] = {-1.0, 0.5, 0.7}, v1[3] = {-0.3, 0.2, -1.1};
        add_particle_or_exit(sys, x0, v0, 0.7);
        add_particle_or_exit(sys, x1, v1, 2.0);
        const double g[3] = {0.5, -9.81, 1.2};
        const size_t nd = (size_t)(2 * dim);
        double jx[36], jv[36], fx[36], fv[36];
        /* gravity alone: both Jacobians are exactly zero */
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
        CHECK(psys_system_fd_jacobian(sys, 1e-6, fx, fv) == PSYS_OK);
        CHECK(max_abs(jx, nd * nd) == 0 && max_abs(jv, nd * nd) == 0);
        CHECK(max_abs(fx, nd * nd) == 0 && max_abs(fv, nd * nd) == 0);
        /* drag: ∂f/∂v = -kd I, ∂f/∂x = 0 */
        CHECK(psys_system_add_drag(sys, 0.35) == PSYS_OK);
        CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
        for (size_t r = 0; r < nd; r++)
            for (size_t c = 0; c < nd; c++) {
                CHECK(jx[r * nd + c] == 0);
                CHECK(jv[r * nd + c] == (r == c ? -0.35 : 0.0));
            }
        CHECK(jacobian_error(sys, 1e-6) <= 1e-8);
        /* mouse spring with a fixed target on particle 1: -ks I and -kd I on its block */
        const double target[3] = {0.9, 1.4, -0.6};
        size_t handle;
        CHECK(psys_system_add_mouse_spring(sys, 1, target, 12.0, 0.8, &handle) == PSYS_OK);
        CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
        for (size_t r = 0; r < nd; r++)
            for (size_t c = 0; c < nd; c++) {
                bool diag1 = r == c && r >= (size_t)dim;
                CHECK(jx[r * nd + c] == (diag1 ? -12.0 : 0.0));
                CHECK(jv[r * nd + c] == (r == c ? -0.35 : 0.0) + (diag1 ? -0.8 : 0.0));
            }
        CHECK(jacobian_error(sys, 1e-6) <= 1e-8);
        psys_system_destroy(sys);
    }
}

/* Behaviour forces: the Gauss–Newton Jacobian -ks JᵀJ, -kd JᵀJ is exact for
 * affine C (coincide, point-on-plane), also with damping and motion. For
 * distance it is exact where C = 0 and Ċ = 0; elsewhere it misses exactly the
 * second-derivative terms, -(ks C + kd Ċ) ∂²C/∂x_i∂x_j - kd J_iᵀ (∂Ċ/∂x_j),
 * which for C = |l| - r (∂²C/∂l² = P/|l|, P = I - u uᵀ) are
 * ∓[(ks C + kd Ċ) P + kd u (P l̇)ᵀ] / |l| (- on the diagonal blocks). */
static void jacobian_behaviors_affine(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        const double xs[3][3] = {{0.2, -0.3, 0.5}, {1.0, 0.4, -0.2}, {-0.6, 0.8, 0.1}};
        const double vs[3][3] = {{0.4, 1.1, -0.3}, {-0.9, 0.2, 0.6}, {0.3, -0.5, 0.8}};
        psys_system *sys = make_system(dim);
        for (int i = 0; i < 3; i++)
            add_particle_or_exit(sys, xs[i], vs[i], 1.0 + i);
        psys_behavior_def c = psys_behavior_def_default();
        c.function = PSYS_BEHAVIOR_COINCIDE;
        c.nparticles = 2;
        c.particles[0] = 0;
        c.particles[1] = 1;
        c.ks = 30;
        c.kd = 1.7;
        CHECK(psys_system_add_behavior(sys, &c) == PSYS_OK);
        psys_behavior_def p = psys_behavior_def_default();
        p.function = PSYS_BEHAVIOR_POINT_ON_PLANE;
        p.nparticles = 1;
        p.particles[0] = 2;
        p.ks = 45;
        p.kd = 2.5;
        p.point[0] = 0.1;
        p.point[1] = -0.2;
        p.point[2] = 0.3;
        p.normal[0] = 1; /* not unit length: normalised when used */
        p.normal[1] = 2;
        p.normal[2] = 2;
        CHECK(psys_system_add_behavior(sys, &p) == PSYS_OK);
        double e = jacobian_error(sys, 1e-6);
        if (!(e <= 1e-8))
            fprintf(stderr, "dim %d: coincide/point-on-plane Jacobian error %.3g\n", dim, e);
        CHECK(e <= 1e-8);
        psys_system_destroy(sys);

        /* distance at its target length with no relative motion: exact */
        sys = make_system(dim);
        add_particle_or_exit(sys, xs[0], vs[0], 1.0);
        add_particle_or_exit(sys, xs[1], vs[0], 2.0); /* same velocity: Ċ = 0 */
        psys_behavior_def q = psys_behavior_def_default();
        q.function = PSYS_BEHAVIOR_DISTANCE;
        q.nparticles = 2;
        q.particles[0] = 0;
        q.particles[1] = 1;
        q.ks = 80;
        q.kd = 3;
        CHECK(psys_system_add_behavior(sys, &q) == PSYS_OK); /* r = the current distance */
        e = jacobian_error(sys, 1e-6);
        CHECK(e <= 1e-8);
        psys_system_destroy(sys);

        /* distance stretched and moving: dense + missing term = finite differences */
        sys = make_system(dim);
        add_particle_or_exit(sys, xs[0], vs[0], 1.0);
        add_particle_or_exit(sys, xs[1], vs[1], 2.0);
        q.r = 0.6;
        CHECK(psys_system_add_behavior(sys, &q) == PSYS_OK);
        size_t nd = (size_t)(2 * dim);
        double jx[36], jv[36], fx[36], fv[36], l[3], ld[3], len = 0, cdot = 0;
        CHECK(psys_system_dense_jacobian(sys, jx, jv) == PSYS_OK);
        CHECK(psys_system_fd_jacobian(sys, 1e-6, fx, fv) == PSYS_OK);
        for (int k = 0; k < dim; k++) {
            l[k] = xs[0][k] - xs[1][k];
            ld[k] = vs[0][k] - vs[1][k];
            len += l[k] * l[k];
        }
        len = sqrt(len);
        for (int k = 0; k < dim; k++)
            cdot += ld[k] * l[k] / len;
        double lam = q.ks * (len - q.r) + q.kd * cdot, worst = 0, missing = 0, pld[3];
        for (int k = 0; k < dim; k++)
            pld[k] = ld[k] - cdot * l[k] / len; /* P l̇ */
        for (size_t r = 0; r < nd; r++)
            for (size_t cc = 0; cc < nd; cc++) {
                int a = (int)(r % (size_t)dim), bb = (int)(cc % (size_t)dim);
                double sign = (r < (size_t)dim) == (cc < (size_t)dim) ? 1.0 : -1.0;
                double P = (a == bb ? 1.0 : 0.0) - l[a] * l[bb] / (len * len);
                double term = -sign * (lam * P + q.kd * (l[a] / len) * pld[bb]) / len;
                double err = fabs(jx[r * nd + cc] + term - fx[r * nd + cc]);
                if (err > worst)
                    worst = err;
                if (fabs(term) > missing)
                    missing = fabs(term);
            }
        CHECK(missing > 1);      /* the Gauss–Newton approximation really differs here */
        CHECK(worst <= 1e-6);    /* ... by exactly the documented term */
        CHECK(max_diff(jv, fv, nd * nd) <= 1e-7); /* ∂f/∂v = -kd JᵀJ is exact */
        psys_system_destroy(sys);
    }
}

/* A force class that offers no Jacobian: f = -k (x - c) per particle. */
static void nojac_apply(void *data, const psys_force_eval *e, double *f)
{
    double k = *(const double *)data;
    for (size_t i = 0; i < e->n * (size_t)e->dim; i++)
        f[i] += -k * (e->x[i] - 0.25);
}
static const psys_force_class nojac_class = {.name = "no-jacobian", .apply = nojac_apply, .destroy = free};

/* Forces without Jacobians are treated explicitly: with only such forces the
 * matrix is M, so implicit-euler's step is v1 = v0 + h f(x0)/m, x1 = x0 + h v1
 * — the symplectic Euler step. */
static void jacobian_missing_is_explicit(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys[2];
        const double x0[3] = {0.3, -0.4, 0.2}, v0[3] = {1.5, -0.7, 0.4};
        const double x1[3] = {-1.0, 0.5, 0.7}, v1[3] = {-0.3, 0.2, -1.1};
        const double g[3] = {0.5, -9.81, 1.2};
        for (int k = 0; k < 2; k++) {
            sys[k] = make_system(dim);
            add_particle_or_exit(sys[k], x0, v0, 0.7);
            add_particle_or_exit(sys[k], x1, v1, 2.0);
            double *kk = malloc(sizeof *kk);
            *kk = 900; /* stiff: ω h = 0.36 at h = 0.01 */
            CHECK(psys_system_add_force(sys[k], &nojac_class, kk) == PSYS_OK);
            CHECK(psys_system_add_gravity(sys[k], g) == PSYS_OK);
        }
        double jx[36], jv[36];
        CHECK(psys_system_dense_jacobian(sys[0], jx, jv) == PSYS_ERR_UNSUPPORTED);
        psys_solver *imp = make_solver("implicit-euler", sys[0]);
        psys_solver *sym = make_solver("symplectic-euler", sys[1]);
        size_t nd = ncomp(sys[0]);
        double worst = 0, scale = 0;
        for (int s = 0; s < 20; s++) {
            CHECK(step_ok(imp, 0.01));
            CHECK(step_ok(sym, 0.01));
            double a = max_diff(psys_system_positions(sys[0]), psys_system_positions(sys[1]), nd);
            double b = max_diff(psys_system_velocities(sys[0]), psys_system_velocities(sys[1]), nd);
            worst = fmax(worst, fmax(a, b));
            scale = fmax(scale, max_abs(psys_system_velocities(sys[1]), nd));
        }
        CHECK(worst <= 1e-13 * scale);
        psys_solver_destroy(imp);
        psys_solver_destroy(sym);
        psys_system_destroy(sys[0]);
        psys_system_destroy(sys[1]);
    }
}

/* ------------------------------------------------------------------ */
/* 4. Exactness: steps against closed forms and a dense solve           */
/* ------------------------------------------------------------------ */

/* A 1-D spring to a fixed anchor, kept stretched by a constant pull g along
 * it, with drag: the force f = -ks (x - r) - c v + m g is linear, so the
 * linearised step is the exact backward-Euler step, the 2×2 system
 *     x1 - h v1 = x0,   h ks x1 + (m + h c) v1 = m v0 + h (ks r + m g),
 * solved by Cramer's rule. Motion stays on the x axis (y stays exactly 0). */
static void closed_form_linear_spring(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        const double ks = 50, c = 0.6, r = 1.0, m = 0.8, h = 0.02, gx = 30;
        psys_system *sys = make_system(dim);
        const double xa[3] = {0, 0, 0}, xb[3] = {1.6, 0, 0}, vb[3] = {-0.9, 0, 0}, g[3] = {gx, 0, 0};
        add_particle_or_exit(sys, xa, NULL, 1);
        add_particle_or_exit(sys, xb, vb, m);
        CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
        add_spring(sys, 0, 1, ks, 0, r);
        CHECK(psys_system_add_drag(sys, c) == PSYS_OK);
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        psys_solver *s = make_solver("implicit-euler", sys);
        double x = xb[0], v = vb[0], worst = 0;
        for (int n = 0; n < 50; n++) {
            double det = (m + h * c) + h * h * ks; /* | 1  -h ; h ks  m + h c | */
            double rhs2 = m * v + h * (ks * r + m * gx);
            double x1 = (x * (m + h * c) + h * rhs2) / det;
            double v1 = (rhs2 - h * ks * x) / det;
            x = x1;
            v = v1;
            CHECK(step_ok(s, h));
            CHECK(x > r); /* stayed stretched: the force really is linear */
            const double *px = psys_system_positions(sys), *pv = psys_system_velocities(sys);
            worst = fmax(worst, fmax(fabs(px[dim] - x), fabs(pv[dim] - v)));
            for (int k = 1; k < dim; k++)
                CHECK(px[dim + k] == 0 && pv[dim + k] == 0);
        }
        if (!(worst <= 1e-12))
            fprintf(stderr, "dim %d: linear spring vs closed form: %.3g\n", dim, worst);
        CHECK(worst <= 1e-12);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A zero-length mouse spring f = -ks (x - p) - kd v is linear in every
 * direction: backward Euler in closed form, v1 = (m v0 - h ks (x0 - p)) /
 * (m + h kd + h² ks), x1 = x0 + h v1, for any direction of motion. */
static void closed_form_mouse_spring(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        const double ks = 250, kd = 1.5, m = 0.3, h = 0.01;
        const double p[3] = {0.5, -1.0, 2.0}, x0[3] = {1.3, 0.4, -0.6}, v0[3] = {-2.0, 1.1, 0.7};
        psys_system *sys = make_system(dim);
        add_particle_or_exit(sys, x0, v0, m);
        CHECK(psys_system_add_mouse_spring(sys, 0, p, ks, kd, NULL) == PSYS_OK);
        psys_solver *s = make_solver("implicit-euler", sys);
        double x[3], v[3], worst = 0;
        memcpy(x, x0, sizeof x);
        memcpy(v, v0, sizeof v);
        for (int n = 0; n < 30; n++) {
            for (int k = 0; k < dim; k++) {
                v[k] = (m * v[k] - h * ks * (x[k] - p[k])) / (m + h * kd + h * h * ks);
                x[k] += h * v[k];
            }
            CHECK(step_ok(s, h));
            worst = fmax(worst, max_diff(psys_system_positions(sys), x, (size_t)dim));
            worst = fmax(worst, max_diff(psys_system_velocities(sys), v, (size_t)dim));
        }
        CHECK(worst <= 1e-12);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* Free fall: with gravity alone the matrix is M and the step is
 * v1 = v0 + h g, x1 = x0 + h v1 (to rounding; x1 from v1 exactly). */
static void free_fall(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        const double g[3] = {0.3, -9.81, 1.7}, h = 0.01;
        const double x0[3] = {0.2, 5.0, -1.0}, v0[3] = {1.0, 2.0, -0.5};
        psys_system *sys = make_system(dim);
        add_particle_or_exit(sys, x0, v0, 0.37);
        add_particle_or_exit(sys, x0, NULL, 12.5);
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        psys_solver *s = make_solver("implicit-euler", sys);
        for (int n = 1; n <= 100; n++) {
            double xp[6], vp[6];
            get_state(sys, xp, vp);
            CHECK(step_ok(s, h));
            const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
            for (int i = 0; i < 2; i++)
                for (int k = 0; k < dim; k++) {
                    size_t q = (size_t)(i * dim + k);
                    CHECK_NEAR(v[q], vp[q] + h * g[k], 4e-15 * (fabs(vp[q]) + 1));
                    CHECK(x[q] == xp[q] + h * v[q]); /* bit for bit */
                    /* closed form after n steps: v0 + n h g, x0 + n h v0 + h² g n(n+1)/2 */
                    double vi = i == 0 ? v0[k] : 0.0;
                    CHECK_NEAR(v[q], vi + n * h * g[k], 1e-12);
                    CHECK_NEAR(x[q], x0[k] + n * h * vi + h * h * g[k] * n * (n + 1) / 2.0, 1e-12);
                }
        }
        CHECK(psys_solver_cg_unconverged(s) == 0);
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* Springs (stretched, undamped or at rest), drag, a mouse spring, a fixed
 * anchor, a coincide and an angle behaviour, where the definite
 * approximation equals the system's own (exact for springs, Gauss–Newton for
 * behaviours) Jacobian: each implicit step equals the dense solve of the same
 * linear system (CG run to 1e-14). The damped variant takes one step from
 * rest (no damping part in ∂f/∂x); the undamped one takes ten steps. */
static void step_matches_dense_solve(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        for (int damped = 0; damped <= 1; damped++) {
            psys_system *sys = make_system(dim);
            const double x[5][3] = {{0, 0, 0}, {1.1, 0.2, -0.1}, {2.3, 0.9, 0.4}, {1.5, 1.6, 1.0}, {0.6, 1.2, 0.8}};
            const double v[5][3] = {{0, 0, 0}, {0.7, -1.2, 0.4}, {-0.5, 0.3, 0.9}, {1.1, 0.6, -0.8}, {-0.2, -0.9, 0.3}};
            for (int i = 0; i < 5; i++)
                add_particle_or_exit(sys, x[i], damped ? NULL : v[i], 0.5 + 0.25 * i);
            CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
            const double kd = damped ? 2.0 : 0.0;
            add_spring(sys, 0, 1, 40, kd, 0.7);
            add_spring(sys, 1, 2, 25, kd, 0.9);
            add_spring(sys, 2, 3, 60, kd, 0.5);
            add_spring(sys, 1, 3, 30, kd, 0.4);
            const double g[3] = {0, -9.81, 0}, target[3] = {0.2, 1.5, 0.3};
            CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
            CHECK(psys_system_add_drag(sys, 0.3) == PSYS_OK);
            CHECK(psys_system_add_mouse_spring(sys, 4, target, 90, 0.7, NULL) == PSYS_OK);
            psys_behavior_def c = psys_behavior_def_default();
            c.function = PSYS_BEHAVIOR_COINCIDE;
            c.nparticles = 2;
            c.particles[0] = 4;
            c.particles[1] = 3;
            c.ks = 70;
            c.kd = 0.9;
            CHECK(psys_system_add_behavior(sys, &c) == PSYS_OK);
            /* an angle behaviour: its Gauss–Newton blocks J_iᵀ J_j (i ≠ j) are
             * not symmetric, so this checks the assembly's transposes */
            psys_behavior_def an = psys_behavior_def_default();
            an.function = PSYS_BEHAVIOR_ANGLE;
            an.nparticles = 3;
            an.particles[0] = 1;
            an.particles[1] = 2;
            an.particles[2] = 4;
            an.ks = 5;
            an.kd = 0.4;
            an.angle = 1.0;
            CHECK(psys_system_add_behavior(sys, &an) == PSYS_OK);
            psys_solver *s = make_solver("implicit-euler", sys);
            CHECK(psys_solver_set_cg(s, 1e-14, 1000) == PSYS_OK);
            size_t nd = ncomp(sys);
            int steps = damped ? 1 : 10;
            for (int n = 0; n < steps; n++) {
                double rx[MAXN], rv[MAXN];
                reference_step(sys, 0.01, NULL, NULL, rx, rv);
                CHECK(step_ok(s, 0.01));
                double ex = max_diff(psys_system_positions(sys), rx, nd);
                double ev = max_diff(psys_system_velocities(sys), rv, nd) / (1 + max_abs(rv, nd));
                if (!(ex <= 1e-12 && ev <= 1e-12))
                    fprintf(stderr, "dim %d damped %d step %d: |x - ref| %.3g, |v - ref| %.3g\n", dim, damped, n,
                            ex, ev);
                CHECK(ex <= 1e-12 && ev <= 1e-12);
                /* the springs really are stretched (so exact = definite) */
                const double *px = psys_system_positions(sys);
                for (size_t k = 0; k < psys_system_spring_count(sys); k++) {
                    size_t a, b;
                    double rest, len = 0;
                    psys_system_spring(sys, k, &a, &b, NULL, NULL, &rest);
                    for (int q = 0; q < dim; q++)
                        len += (px[a * dim + q] - px[b * dim + q]) * (px[a * dim + q] - px[b * dim + q]);
                    CHECK(sqrt(len) > rest);
                }
            }
            CHECK(psys_solver_cg_unconverged(s) == 0);
            psys_solver_destroy(s);
            psys_system_destroy(sys);
        }
    }
}

/* The definite approximation (psys_jacobian_wants_definite): for the solve, a
 * compressed spring's transverse stiffness ks(1 - r/|l|)P is dropped and the
 * damping part of ∂f/∂x is dropped, keeping ∂f/∂x = -ks u uᵀ - ks max(0, 1 -
 * r/|l|) P and ∂f/∂v = -kd u uᵀ. Built here by hand, the dense solve with it
 * equals the implicit step; the exact Jacobian gives a different step. */
static void definite_approximation(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys = make_system(dim);
        spring_system(sys); /* stretched and compressed damped springs, moving */
        size_t nd = ncomp(sys), ns = psys_system_spring_count(sys);
        static double dx[MAXN * MAXN], dv[MAXN * MAXN];
        memset(dx, 0, sizeof dx);
        memset(dv, 0, sizeof dv);
        const double *x = psys_system_positions(sys);
        for (size_t k = 0; k < ns; k++) {
            size_t a, b;
            double ks, kd, r, l[3], len = 0;
            psys_system_spring(sys, k, &a, &b, &ks, &kd, &r);
            for (int q = 0; q < dim; q++) {
                l[q] = x[a * dim + q] - x[b * dim + q];
                len += l[q] * l[q];
            }
            len = sqrt(len);
            double fr = fmax(0.0, 1 - r / len);
            for (int rr = 0; rr < dim; rr++)
                for (int cc = 0; cc < dim; cc++) {
                    double uu = l[rr] * l[cc] / (len * len), P = (rr == cc) - uu;
                    double kx = -ks * (uu + fr * P), kv = -kd * uu;
                    size_t ends[2] = {a, b};
                    for (int i = 0; i < 2; i++)
                        for (int j = 0; j < 2; j++) {
                            double sgn = i == j ? 1 : -1;
                            size_t at = (ends[i] * dim + rr) * nd + ends[j] * dim + cc;
                            dx[at] += sgn * kx;
                            dv[at] += sgn * kv;
                        }
                }
        }
        double rx[MAXN], rv[MAXN], ex_x[MAXN], ex_v[MAXN];
        reference_step(sys, 0.05, dx, dv, rx, rv);
        reference_step(sys, 0.05, NULL, NULL, ex_x, ex_v); /* exact Jacobian */
        psys_solver *s = make_solver("implicit-euler", sys);
        CHECK(psys_solver_set_cg(s, 1e-14, 1000) == PSYS_OK);
        CHECK(step_ok(s, 0.05));
        double e = max_diff(psys_system_velocities(sys), rv, nd) / (1 + max_abs(rv, nd));
        if (!(e <= 1e-12))
            fprintf(stderr, "dim %d: step vs definite reference %.3g\n", dim, e);
        CHECK(e <= 1e-12);
        CHECK(max_diff(psys_system_positions(sys), rx, nd) <= 1e-12);
        CHECK(max_diff(rv, ex_v, nd) > 1e-3); /* the approximation matters here */
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* The sparsity pattern is built on the first step and rebuilt when a force
 * reports a new pair: a spring added between unconnected particles after
 * some steps enters the next solve. */
static void pattern_rebuild(void)
{
    psys_system *sys = make_system(3);
    const double x[4][3] = {{0, 0, 0}, {1.2, 0, 0}, {0, 1.3, 0}, {1.4, 1.5, 0.2}};
    for (int i = 0; i < 4; i++)
        add_particle_or_exit(sys, x[i], NULL, 1.0);
    add_spring(sys, 0, 1, 300, 0, 1.0);
    add_spring(sys, 2, 3, 300, 0, 1.0);
    psys_solver *s = make_solver("implicit-euler", sys);
    CHECK(psys_solver_set_cg(s, 1e-14, 1000) == PSYS_OK);
    for (int n = 0; n < 3; n++)
        CHECK(step_ok(s, 0.01));
    add_spring(sys, 1, 3, 500, 0, 1.0); /* new pairs (1,3), (3,1) */
    add_spring(sys, 0, 2, 500, 0, 0.5);
    size_t nd = ncomp(sys);
    for (int n = 0; n < 3; n++) {
        double rx[MAXN], rv[MAXN];
        reference_step(sys, 0.01, NULL, NULL, rx, rv);
        CHECK(step_ok(s, 0.01));
        double e = max_diff(psys_system_velocities(sys), rv, nd) / (1 + max_abs(rv, nd));
        if (!(e <= 1e-12))
            fprintf(stderr, "after the new springs, step %d: %.3g\n", n, e);
        CHECK(e <= 1e-12);
    }
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 5. Filtering and conservation                                       */
/* ------------------------------------------------------------------ */

/* Fixed particles are filtered out of the solve: bit-identical positions and
 * exactly zero velocities, while stiff springs pull on them. */
static void fixed_particles_bit_identical(void)
{
    for (int dim = 2; dim <= 3; dim++) {
        psys_system *sys = make_system(dim);
        psys_chain_def c = psys_chain_def_default();
        c.from[0] = 0.1;
        c.from[1] = 0.7;
        c.to[0] = 2.3;
        c.to[1] = 0.3;
        c.to[2] = 0.2;
        c.count = 8;
        c.mass = 0.05;
        c.ks = 5e4;
        c.kd = 2;
        const size_t pin[2] = {0, 7};
        c.pin = pin;
        c.pin_count = 2;
        CHECK(psys_system_add_chain(sys, &c, NULL) == PSYS_OK);
        const double g[3] = {0, -9.81, 0};
        CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
        size_t handle;
        CHECK(psys_system_add_mouse_spring(sys, 7, g, 1e3, 1, &handle) == PSYS_OK); /* pulls on a pin */
        double x0[MAXN], v0[MAXN];
        get_state(sys, x0, v0);
        psys_solver *s = make_solver("implicit-euler", sys);
        for (int n = 0; n < 100; n++) {
            CHECK(step_ok(s, 0.02));
            const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
            for (int k = 0; k < dim; k++) {
                CHECK(memcmp(&x[k], &x0[k], sizeof(double)) == 0);
                CHECK(memcmp(&x[7 * dim + k], &x0[7 * dim + k], sizeof(double)) == 0);
                CHECK(v[k] == 0 && v[7 * dim + k] == 0);
            }
        }
        CHECK(psys_system_positions(sys)[3 * dim + 1] < x0[3 * dim + 1] - 0.001); /* the chain sagged */
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* A circle-controlled particle follows its path exactly (position and
 * velocity from the controller at every step's end), and a particle it drags
 * through a damped spring converges at first order to the rk4 solution. */
static void driven_run(const char *solver, double h, double T, double *x_out, double *v_out, int check_path)
{
    psys_system *sys = make_system(2);
    const double c[2] = {0.2, -0.1}, R = 0.5, w = 3.0, ph = 0.4;
    const double xf[2] = {0.2 + 1.4, -0.1};
    add_particle_or_exit(sys, c, NULL, 1.0);
    add_particle_or_exit(sys, xf, NULL, 1.0);
    CHECK(psys_system_control_circle(sys, 0, c, R, w, ph, NULL) == PSYS_OK);
    add_spring(sys, 0, 1, 20, 0.5, 1.0);
    CHECK(psys_system_add_drag(sys, 0.1) == PSYS_OK);
    psys_solver *s = make_solver(solver, sys);
    int n = (int)lround(T / h);
    for (int k = 0; k < n; k++) {
        CHECK(step_ok(s, h));
        if (check_path) {
            double t = psys_system_time(sys), a = w * t + ph;
            const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
            CHECK_NEAR(x[0], c[0] + R * cos(a), 1e-15);
            CHECK_NEAR(x[1], c[1] + R * sin(a), 1e-15);
            CHECK_NEAR(v[0], -R * w * sin(a), 1e-14);
            CHECK_NEAR(v[1], R * w * cos(a), 1e-14);
        }
    }
    memcpy(x_out, psys_system_positions(sys), 4 * sizeof(double));
    memcpy(v_out, psys_system_velocities(sys), 4 * sizeof(double));
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

static void controlled_circle_exact(void)
{
    double rx[4], rv[4], x[4], v[4], err[4];
    driven_run("rk4", 1e-4, 0.5, rx, rv, 0);
    for (int k = 0; k < 4; k++) {
        double h = 0.01 / (1 << k);
        driven_run("implicit-euler", h, 0.5, x, v, 1);
        err[k] = hypot(norm_diff(x + 2, rx + 2, 2), norm_diff(v + 2, rv + 2, 2));
    }
    for (int k = 0; k < 3; k++) {
        double p = log2(err[k] / err[k + 1]);
        if (!(fabs(p - 1) <= 0.15))
            fprintf(stderr, "driven particle: order %.3f (errors %.3g, %.3g)\n", p, err[k], err[k + 1]);
        CHECK(fabs(p - 1) <= 0.15);
    }
}

/* Internal forces only (a damped spring pair, no gravity): the solve keeps
 * Σ m v fixed to rounding (CG run to 1e-14; the block rows of ∂f/∂x and
 * ∂f/∂v sum to zero). */
static void momentum_conserved(void)
{
    psys_system *sys = make_system(3);
    const double xa[3] = {0, 0, 0}, xb[3] = {1.3, 0.2, -0.4};
    const double va[3] = {0.3, -1.0, 0.2}, vb[3] = {-0.5, 0.4, 1.0};
    const double ma = 1.0, mb = 2.5;
    add_particle_or_exit(sys, xa, va, ma);
    add_particle_or_exit(sys, xb, vb, mb);
    add_spring(sys, 0, 1, 5e3, 3.0, 1.0);
    psys_solver *s = make_solver("implicit-euler", sys);
    CHECK(psys_solver_set_cg(s, 1e-14, 1000) == PSYS_OK);
    double p0[3], worst = 0;
    for (int k = 0; k < 3; k++)
        p0[k] = ma * va[k] + mb * vb[k];
    for (int n = 0; n < 300; n++) {
        CHECK(step_ok(s, 0.01));
        const double *v = psys_system_velocities(sys);
        for (int k = 0; k < 3; k++)
            worst = fmax(worst, fabs(ma * v[k] + mb * v[3 + k] - p0[k]));
    }
    if (!(worst <= 1e-13))
        fprintf(stderr, "momentum drift %.3g\n", worst);
    CHECK(worst <= 1e-13);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 3. Convergence: first order against an rk4 reference                */
/* ------------------------------------------------------------------ */

/* A 2-D spring pendulum that stays stretched, without spring damping (drag
 * only): the definite Jacobian is the exact one. */
static psys_system *pendulum(void)
{
    psys_system *sys = make_system(2);
    const double a[2] = {0, 0}, b[2] = {1.3, 0};
    add_particle_or_exit(sys, a, NULL, 1);
    add_particle_or_exit(sys, b, NULL, 1);
    CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
    add_spring(sys, 0, 1, 30, 0, 1.0);
    const double g[2] = {0, -9.81};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    CHECK(psys_system_add_drag(sys, 0.2) == PSYS_OK);
    return sys;
}

/* A 3-D 3×3 cloth patch with damped springs, falling from the horizontal
 * while pinned at two corners (springs compress and move: the definite
 * approximation differs from the exact Jacobian). */
static psys_system *patch(void)
{
    psys_system *sys = make_system(3);
    psys_cloth_def c = psys_cloth_def_default();
    c.nx = c.ny = 3;
    c.spacing = 0.1;
    c.mass = 0.05;
    c.ks = 20;
    c.kd = 1;
    c.axes[1][1] = 0;
    c.axes[1][2] = 1;
    const size_t pin[4] = {0, 0, 2, 0};
    c.pin = pin;
    c.pin_count = 2;
    CHECK(psys_system_add_cloth(sys, &c, NULL) == PSYS_OK);
    const double g[3] = {0, -9.81, 0};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    return sys;
}

/* Run make() for T with solver at step h; state into y (x then v). The
 * smallest spring stretch |l| - r seen goes to *min_stretch. */
static void run_to(psys_system *(*make)(void), const char *solver, double h, double T, double *y,
                   double *min_stretch)
{
    psys_system *sys = make();
    psys_solver *s = make_solver(solver, sys);
    int n = (int)lround(T / h);
    double ms = INFINITY;
    int dim = psys_system_dim(sys);
    for (int k = 0; k < n; k++) {
        CHECK(step_ok(s, h));
        const double *x = psys_system_positions(sys);
        for (size_t q = 0; q < psys_system_spring_count(sys); q++) {
            size_t a, b;
            double r, len = 0;
            psys_system_spring(sys, q, &a, &b, NULL, NULL, &r);
            for (int c = 0; c < dim; c++)
                len += (x[a * dim + c] - x[b * dim + c]) * (x[a * dim + c] - x[b * dim + c]);
            ms = fmin(ms, sqrt(len) - r);
        }
    }
    get_state(sys, y, y + ncomp(sys));
    if (min_stretch)
        *min_stretch = ms;
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* Errors (Euclidean norm of the state error) at T = 0.5 against rk4 at
 * h = 5e-4, for h = h0 / 2^k, k = 0..3: three measured orders, each 1 ± 0.15. */
static void check_first_order(psys_system *(*make)(void), const char *what, double h0, double *min_stretch)
{
    double ref[MAXN], y[MAXN], err[4];
    run_to(make, "rk4", 5e-4, 0.5, ref, NULL);
    psys_system *tmp = make();
    size_t n = 2 * ncomp(tmp);
    psys_system_destroy(tmp);
    double ms = INFINITY;
    for (int k = 0; k < 4; k++) {
        double m;
        run_to(make, "implicit-euler", h0 / (1 << k), 0.5, y, &m);
        ms = fmin(ms, m);
        err[k] = norm_diff(y, ref, n);
    }
    for (int k = 0; k < 3; k++) {
        double p = log2(err[k] / err[k + 1]);
        fprintf(stderr, "%s: h = %g -> %g: error %.4g -> %.4g, order %.3f\n", what, h0 / (1 << k),
                h0 / (2 << k), err[k], err[k + 1], p);
        CHECK(fabs(p - 1) <= 0.15);
    }
    if (min_stretch)
        *min_stretch = ms;
}

static void convergence_first_order(void)
{
    double ms;
    check_first_order(pendulum, "undamped spring pendulum", 0.01, &ms);
    CHECK(ms > 0); /* always stretched: the exact Jacobian was used */
}

static void convergence_first_order_damped(void)
{
    double ms;
    check_first_order(patch, "damped 3x3 cloth", 0.005, &ms);
    CHECK(ms < 0); /* some springs were compressed: the approximation was in use */
}

/* ------------------------------------------------------------------ */
/* 7. and 2. Stability where explicit solvers fail                      */
/* ------------------------------------------------------------------ */

/* One very stiff spring, ω h = 10 (ks 1e6, m 1, h 0.01): backward Euler's
 * energy E = ½ m v² + ½ ks (|l| - r)² falls at every step (the oscillation
 * is linear along the spring), so the amplitude never grows; rk4 (stable for
 * ω h < 2.8) overflows and names the free particle. */
static void stiff_spring(void)
{
    for (int implicit = 1; implicit >= 0; implicit--) {
        psys_system *sys = make_system(2);
        const double a[2] = {0, 0}, b[2] = {1.1, 0}, vb[2] = {3.0, 0};
        add_particle_or_exit(sys, a, NULL, 1);
        add_particle_or_exit(sys, b, vb, 1);
        CHECK(psys_system_set_fixed(sys, 0, true) == PSYS_OK);
        add_spring(sys, 0, 1, 1e6, 0, 1.0);
        psys_solver *s = make_solver(implicit ? "implicit-euler" : "rk4", sys);
        double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys), e = e0;
        if (implicit) {
            for (int n = 0; n < 300; n++) {
                CHECK(step_ok(s, 0.01));
                double en = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
                CHECK(en <= e * (1 + 1e-14));
                CHECK(fabs(psys_system_positions(sys)[2] - 1.0) <= sqrt(2 * e0 / 1e6) * (1 + 1e-12));
                e = en;
            }
            CHECK(e <= 1e-20 * e0); /* (1 + ω²h²)^-n: decayed */
        } else {
            psys_status st = PSYS_OK;
            int n = 0;
            double xp[4], vp[4];
            while (n < 1000 && st == PSYS_OK) {
                get_state(sys, xp, vp);
                st = psys_solver_step(s, 0.01, NULL);
                n++;
            }
            CHECK(st == PSYS_ERR_NONFINITE);
            CHECK(n < 300);
            CHECK(psys_system_particle_of_component(sys, psys_solver_bad_component(s)) == 1);
            double x[4], v[4];
            get_state(sys, x, v);
            CHECK(memcmp(x, xp, sizeof x) == 0 && memcmp(v, vp, sizeof v) == 0); /* unchanged on failure */
        }
        psys_solver_destroy(s);
        psys_system_destroy(sys);
    }
}

/* An n×n cloth (the stability scene at n = 20): structural, shear and bend
 * springs with ks 1e5, kd 10, mass 0.01, spacing 0.05, laid flat in the x–z
 * plane and pinned at the corners (0,0) and (n-1,0), under gravity: it falls
 * and swings. */
static psys_system *cloth_n(size_t n)
{
    psys_system *sys = make_system(3);
    psys_cloth_def c = psys_cloth_def_default();
    c.nx = c.ny = n;
    c.spacing = 0.05;
    c.mass = 0.01;
    c.ks = 1e5;
    c.kd = 10;
    c.axes[1][1] = 0;
    c.axes[1][2] = 1;
    const size_t pin[4] = {0, 0, n - 1, 0};
    c.pin = pin;
    c.pin_count = 2;
    CHECK(psys_system_add_cloth(sys, &c, NULL) == PSYS_OK);
    const double g[3] = {0, -9.81, 0};
    CHECK(psys_system_add_gravity(sys, g) == PSYS_OK);
    return sys;
}

static psys_system *big_cloth(void) { return cloth_n(20); }

/* Largest relative strain |l - r| / r of the structural springs (the first
 * 2·nx·ny - nx - ny springs of a cloth). */
static double structural_strain(const psys_system *sys, size_t nstruct)
{
    const double *x = psys_system_positions(sys);
    double w = 0;
    for (size_t q = 0; q < nstruct; q++) {
        size_t a, b;
        double r, len = 0;
        psys_system_spring(sys, q, &a, &b, NULL, NULL, &r);
        for (int c = 0; c < 3; c++)
            len += (x[a * 3 + c] - x[b * 3 + c]) * (x[a * 3 + c] - x[b * 3 + c]);
        w = fmax(w, fabs(sqrt(len) - r) / r);
    }
    return w;
}

/* implicit-euler at dt = 1/60 for 5 s (300 steps; 10 s adds nothing but
 * time — the kinetic energy over the last second is already ~1.5 % of its
 * peak): every step succeeds (so every value is finite), the pins never move
 * (bit for bit), the total energy never rises above its start, the kinetic
 * energy over the last second is far below its peak, the cloth hangs below
 * its pins and its structural springs are barely strained. Sanitizer builds
 * stop after a few steps and skip the checks that need the whole run. */
#define CLOTH_STEPS (SANITIZED ? 2 : 300)
static void cloth_hangs_and_settles(void)
{
    psys_system *sys = big_cloth();
    const size_t n = psys_system_count(sys), nstruct = 2 * 20 * 20 - 20 - 20;
    CHECK(n == 400);
    const double h = 1.0 / 60;
    double pins[6];
    memcpy(pins, psys_system_positions(sys), 3 * sizeof(double));
    memcpy(pins + 3, psys_system_positions(sys) + 19 * 3, 3 * sizeof(double));
    double e0 = psys_system_kinetic_energy(sys) + psys_system_potential_energy(sys);
    psys_solver *s = make_solver("implicit-euler", sys);
    double peak = 0, last_second = 0, emax = -INFINITY;
    const int steps = CLOTH_STEPS;
    for (int k = 0; k < steps; k++) {
        if (!step_ok(s, h)) {
            CHECK(!"cloth step failed");
            break;
        }
        const double *x = psys_system_positions(sys);
        if (memcmp(x, pins, 3 * sizeof(double)) != 0 || memcmp(x + 19 * 3, pins + 3, 3 * sizeof(double)) != 0) {
            CHECK(!"a pinned corner moved");
            break;
        }
        double ke = psys_system_kinetic_energy(sys);
        emax = fmax(emax, ke + psys_system_potential_energy(sys));
        peak = fmax(peak, ke);
        if (k >= steps - 60)
            last_second = fmax(last_second, ke);
    }
    const double *x = psys_system_positions(sys), *v = psys_system_velocities(sys);
    for (size_t i = 0; i < 3 * n; i++)
        CHECK(isfinite(x[i]) && isfinite(v[i]));
    double ycm = 0, zcm = 0;
    for (size_t i = 0; i < n; i++) {
        ycm += x[3 * i + 1] / (double)n;
        zcm += x[3 * i + 2] / (double)n;
    }
    double strain = structural_strain(sys, nstruct);
    fprintf(stderr, "cloth: peak KE %.4g J, last-second max KE %.4g J, max energy %.4g J (start %.4g), "
                    "centre of mass y %.4f z %.4f, structural strain %.4g, CG iterations %zu\n",
            peak, last_second, emax, e0, ycm, zcm, strain, psys_solver_cg_iterations(s));
    CHECK(emax <= e0 + 1e-9); /* never gained energy */
    CHECK(psys_solver_cg_unconverged(s) == 0);
    if (!SANITIZED) {
        CHECK(peak > 2);                      /* it fell: 400 × 0.01 kg dropping ~0.5 m */
        CHECK(last_second < 0.05 * peak);     /* ... and settled */
        CHECK(ycm < -0.4 && fabs(zcm) < 0.1); /* hangs straight down below the pins */
        CHECK(strain < 0.01);
    }
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* The same cloth with rk4 at dt = 1/60 overflows within the first second,
 * fails cleanly (PSYS_ERR_NONFINITE, state unchanged) and names a free
 * particle. */
static void cloth_rk4_fails(void)
{
    psys_system *sys = big_cloth();
    psys_solver *s = make_solver("rk4", sys);
    psys_status st = PSYS_OK;
    int k = 0;
    while (k < 60 && (st = psys_solver_step(s, 1.0 / 60, NULL)) == PSYS_OK)
        k++;
    CHECK(st == PSYS_ERR_NONFINITE);
    size_t p = psys_system_particle_of_component(sys, psys_solver_bad_component(s));
    CHECK(p < 400 && p != 0 && p != 19);
    const double *x = psys_system_positions(sys);
    for (size_t i = 0; i < 3 * 400; i++)
        CHECK(isfinite(x[i]));
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* ------------------------------------------------------------------ */
/* 6. Conjugate gradient settings                                      */
/* ------------------------------------------------------------------ */

static void cg_settings(void)
{
    psys_system *sys = pendulum();
    psys_solver *s = make_solver("implicit-euler", sys);
    const char *msg = "CG tolerance must be > 0 and the iteration cap >= 1";
    CHECK(psys_solver_set_cg(s, 0, 10) == PSYS_ERR_INVALID);
    CHECK_STR(psys_solver_last_error(s), msg);
    CHECK(psys_solver_set_cg(s, -1e-6, 10) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_cg(s, NAN, 10) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_cg(s, INFINITY, 10) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_cg(s, 1e-6, 0) == PSYS_ERR_INVALID);
    CHECK(psys_solver_set_cg(s, 1e-6, -3) == PSYS_ERR_INVALID);
    CHECK_STR(psys_solver_last_error(s), msg);
    /* rejected settings changed nothing: the defaults (1e-6, 1000) still converge */
    CHECK(psys_solver_cg_iterations(s) == 0 && psys_solver_cg_unconverged(s) == 0);
    CHECK(psys_solver_cg_worst_residual(s) == 0);
    for (int n = 0; n < 10; n++)
        CHECK(step_ok(s, 0.01));
    CHECK(psys_solver_cg_unconverged(s) == 0);
    CHECK(psys_solver_cg_worst_residual(s) == 0);
    CHECK(psys_solver_cg_iterations(s) >= 10);
    CHECK(psys_solver_set_cg(s, 1e-3, 1) == PSYS_OK);
    psys_solver_destroy(s);
    /* explicit solvers accept the call and never count iterations */
    s = make_solver("rk4", sys);
    CHECK(step_ok(s, 0.01));
    CHECK(psys_solver_cg_iterations(s) == 0 && psys_solver_cg_unconverged(s) == 0);
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* A stiff cloth with the iteration cap at 1: each step stops after exactly
 * one iteration, and every step but the first stops short of the tolerance
 * (on the first, the cloth is flat, at rest and unstrained, so gravity,
 * normal to it, meets only M: one iteration solves it); the run completes. */
static void cg_cap_unconverged(void)
{
    psys_system *sys = cloth_n(10);
    psys_solver *s = make_solver("implicit-euler", sys);
    CHECK(psys_solver_set_cg(s, 1e-6, 1) == PSYS_OK);
    const int steps = 20;
    for (int k = 0; k < steps; k++)
        CHECK(step_ok(s, 1.0 / 60));
    CHECK(psys_solver_cg_unconverged(s) == (size_t)steps - 1);
    CHECK(psys_solver_cg_iterations(s) == (size_t)steps);
    double w = psys_solver_cg_worst_residual(s);
    CHECK(w > 1e-6 && isfinite(w));
    psys_solver_destroy(s);
    psys_system_destroy(sys);
}

/* Scene keys cg_tolerance and cg_max_iterations: defaults, loading,
 * validation messages, and the saved form (written only when not default). */
static psys_scene *load(const char *text, psys_error *err)
{
    return psys_scene_load_string(text, strlen(text), err);
}

static void scene_cg_keys(void)
{
    psys_error err;
    psys_settings d = psys_settings_default();
    CHECK(d.cg_tolerance == 1e-6 && d.cg_max_iterations == 1000);

    psys_scene *sc = load("{\"psys\": 1, \"integrator\": \"implicit-euler\", \"particles\": [{\"x\": [0, 0, 0]}]}",
                          &err);
    CHECK(sc != NULL);
    if (sc) {
        CHECK(psys_scene_settings(sc)->cg_tolerance == 1e-6);
        CHECK(psys_scene_settings(sc)->cg_max_iterations == 1000);
        char *text = psys_scene_to_string(sc, NULL, &err);
        CHECK(text && !strstr(text, "cg_tolerance") && !strstr(text, "cg_max_iterations"));
        free(text);
        psys_scene_destroy(sc);
    }

    const char *with = "{\"psys\": 1, \"integrator\": \"implicit-euler\", \"cg_tolerance\": 2.5e-9, "
                       "\"cg_max_iterations\": 37, \"particles\": [{\"x\": [0, 0, 0]}]}";
    sc = load(with, &err);
    CHECK(sc != NULL);
    if (sc) {
        CHECK(psys_scene_settings(sc)->cg_tolerance == 2.5e-9);
        CHECK(psys_scene_settings(sc)->cg_max_iterations == 37);
        char *text = psys_scene_to_string(sc, NULL, &err);
        CHECK(text != NULL);
        if (text) {
            psys_scene *again = load(text, &err);
            CHECK(again != NULL);
            if (again) {
                CHECK(psys_scene_settings(again)->cg_tolerance == 2.5e-9);
                CHECK(psys_scene_settings(again)->cg_max_iterations == 37);
                char *text2 = psys_scene_to_string(again, NULL, &err);
                CHECK(text2 && strcmp(text, text2) == 0);
                free(text2);
                psys_scene_destroy(again);
            }
            free(text);
        }
        psys_scene_destroy(sc);
    }
    /* one non-default key makes both explicit */
    sc = load("{\"psys\": 1, \"cg_max_iterations\": 5, \"particles\": [{\"x\": [0, 0, 0]}]}", &err);
    CHECK(sc != NULL);
    if (sc) {
        char *text = psys_scene_to_string(sc, NULL, &err);
        CHECK(text && strstr(text, "\"cg_tolerance\"") && strstr(text, "\"cg_max_iterations\""));
        free(text);
        psys_scene_destroy(sc);
    }

    static const struct {
        const char *json, *message;
    } bad[] = {
        {"{\"psys\": 1, \"cg_max_iterations\": 0}", "cg_max_iterations: must be an integer from 1 to 1e15 (got 0)"},
        {"{\"psys\": 1, \"cg_max_iterations\": -1}", "cg_max_iterations: must be an integer from 1 to 1e15 (got -1)"},
        {"{\"psys\": 1, \"cg_max_iterations\": 1.5}", "cg_max_iterations: must be an integer (got 1.5)"},
        {"{\"psys\": 1, \"cg_max_iterations\": \"10\"}", "cg_max_iterations: must be an integer (got \"10\")"},
        {"{\"psys\": 1, \"cg_tolerance\": 0}", "cg_tolerance: must be > 0 (got 0)"},
        {"{\"psys\": 1, \"cg_tolerance\": -1e-6}", "cg_tolerance: must be > 0 (got -1e-06)"},
        {"{\"psys\": 1, \"cg_tolerance\": \"tight\"}", "cg_tolerance: must be a number (got \"tight\")"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        sc = load(bad[k].json, &err);
        CHECK(sc == NULL);
        psys_scene_destroy(sc);
        CHECK(err.code == PSYS_ERR_INVALID);
        CHECK_STR(err.message, bad[k].message);
    }

    /* the run uses them: a cap of 1 leaves the stiff cloth's solves short (20×20: more
     * nodes than the multigrid's coarsest level, whose solve is exact) */
    const char *capped = "{\"psys\": 1, \"integrator\": \"implicit-euler\", \"dt\": 0.0166, \"steps\": 5, "
                         "\"cg_max_iterations\": 1, \"structures\": [{\"type\": \"cloth\", \"size\": [20, 20], "
                         "\"spacing\": 0.05, \"mass\": 0.01, \"ks\": 1e5, \"kd\": 10, \"axes\": [[1, 0, 0], "
                         "[0, 0, 1]], \"pin\": [[0, 0], [19, 0]]}], \"forces\": [{\"type\": \"gravity\"}]}";
    sc = load(capped, &err);
    CHECK(sc != NULL);
    if (sc) {
        psys_run *run = psys_run_create(sc, &err);
        CHECK(run != NULL);
        while (run && !psys_run_done(run))
            if (psys_run_step(run, &err) != PSYS_OK) {
                CHECK(!"run step failed");
                break;
            }
        if (run) {
            CHECK(psys_solver_cg_unconverged(psys_run_solver(run)) == 4); /* all but the first (see above) */
            CHECK(psys_solver_cg_iterations(psys_run_solver(run)) == 5);
        }
        psys_run_destroy(run);
        psys_scene_destroy(sc);
    }
}

static const check_case cases[] = {
    {"jacobian_springs_2d", jacobian_springs_2d},
    {"jacobian_springs_3d", jacobian_springs_3d},
    {"jacobian_drag_mouse_gravity", jacobian_drag_mouse_gravity},
    {"jacobian_behaviors_affine", jacobian_behaviors_affine},
    {"jacobian_missing_is_explicit", jacobian_missing_is_explicit},
    {"closed_form_linear_spring", closed_form_linear_spring},
    {"closed_form_mouse_spring", closed_form_mouse_spring},
    {"free_fall", free_fall},
    {"step_matches_dense_solve", step_matches_dense_solve},
    {"definite_approximation", definite_approximation},
    {"pattern_rebuild", pattern_rebuild},
    {"fixed_particles_bit_identical", fixed_particles_bit_identical},
    {"controlled_circle_exact", controlled_circle_exact},
    {"momentum_conserved", momentum_conserved},
    {"convergence_first_order", convergence_first_order},
    {"convergence_first_order_damped", convergence_first_order_damped},
    {"stiff_spring", stiff_spring},
    {"cloth_hangs_and_settles", cloth_hangs_and_settles},
    {"cloth_rk4_fails", cloth_rk4_fails},
    {"cg_settings", cg_settings},
    {"cg_cap_unconverged", cg_cap_unconverged},
    {"scene_cg_keys", scene_cg_keys},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
