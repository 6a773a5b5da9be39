/* The multigrid preconditioner of implicit-euler (src/solvers/amg.c): the V-cycle is
 * a symmetric positive-definite operator (conjugate gradient needs that),
 * exact on systems no larger than its coarsest level, and it cuts the
 * conjugate-gradient iterations of a stiff spring grid several-fold against
 * block Jacobi. The matrices are built here by hand: a grid of particles
 * joined by stiff springs (blocks k n nᵀ, the definite spring Jacobian) plus
 * a small mass on the diagonal, stored as the upper triangle. */
#include "check.h"

#include "../src/solvers/amg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct mat {
    size_t nb;
    int bs;
    size_t *row, *col;
    double *val;
} mat;

/* Upper-triangle block matrix of an nx×ny grid in bs (2 or 3) dimensions:
 * mass m per particle, springs of stiffness k to the right, up and both
 * diagonals (a cloth without bend springs); the grid lies in the x-y plane,
 * so in 3-D the z blocks hold only the mass (as a flat cloth's normal
 * direction does). */
static mat grid(int nx, int ny, int bs, double m, double k)
{
    mat A = {(size_t)nx * ny, bs, NULL, NULL, NULL};
    const int off[4][2] = {{1, 0}, {0, 1}, {1, 1}, {-1, 1}};
    size_t cap = A.nb * 5, bb = (size_t)bs * bs;
    A.row = calloc(A.nb + 1, sizeof(size_t));
    A.col = calloc(cap, sizeof(size_t));
    A.val = calloc(cap * bb, sizeof(double));
    /* diagonal blocks first: mass, then each spring adds k n nᵀ to both ends */
    double *diag = calloc(A.nb * bb, sizeof(double));
    for (size_t i = 0; i < A.nb; i++)
        for (int r = 0; r < bs; r++)
            diag[i * bb + r * bs + r] = m;
    size_t e = 0;
    for (int y = 0; y < ny; y++)
        for (int x = 0; x < nx; x++) {
            size_t i = (size_t)y * nx + x;
            A.row[i] = e;
            e++; /* the diagonal block, filled below */
            /* neighbours with a larger index, in ascending order */
            int cand[4] = {-1, -1, -1, -1};
            for (int q = 0; q < 4; q++) {
                int x2 = x + off[q][0], y2 = y + off[q][1];
                if (x2 < 0 || x2 >= nx || y2 >= ny)
                    continue;
                cand[q] = y2 * nx + x2;
            }
            /* order: (1,0) < (-1,1) < (0,1) < (1,1) by index */
            const int order[4] = {0, 3, 1, 2};
            for (int o = 0; o < 4; o++) {
                int q = order[o];
                if (cand[q] < 0)
                    continue;
                double n[3] = {off[q][0], off[q][1], 0}, len = sqrt(n[0] * n[0] + n[1] * n[1]);
                n[0] /= len;
                n[1] /= len;
                A.col[e] = (size_t)cand[q];
                for (int r = 0; r < bs; r++)
                    for (int c = 0; c < bs; c++) {
                        double v = k * n[r] * n[c];
                        A.val[e * bb + r * bs + c] = -v;
                        diag[i * bb + r * bs + c] += v;
                        diag[(size_t)cand[q] * bb + r * bs + c] += v;
                    }
                e++;
            }
        }
    A.row[A.nb] = e;
    for (size_t i = 0; i < A.nb; i++) {
        A.col[A.row[i]] = i;
        memcpy(A.val + A.row[i] * bb, diag + i * bb, bb * sizeof(double));
    }
    free(diag);
    return A;
}

static void mat_free(mat *A)
{
    free(A->row);
    free(A->col);
    free(A->val);
}

static double dot(const double *a, const double *b, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static void random_vec(double *v, size_t n, unsigned *seed)
{
    for (size_t i = 0; i < n; i++) {
        *seed = *seed * 1103515245u + 12345u;
        v[i] = (double)((*seed >> 8) & 0xffff) / 32768.0 - 1.0;
    }
}

/* Conjugate gradient on A x = b to relative residual tol; the preconditioner
 * is the V-cycle (amg) or block Jacobi (amg NULL). Returns the iterations. */
static int pcg(const mat *A, psys__amg *amg, const double *b, double tol)
{
    size_t n = A->nb * (size_t)A->bs, bb = (size_t)A->bs * A->bs;
    double *x = calloc(n, sizeof(double)), *r = malloc(n * sizeof(double)), *z = malloc(n * sizeof(double));
    double *p = malloc(n * sizeof(double)), *q = malloc(n * sizeof(double));
    double *dinv = calloc(A->nb * bb, sizeof(double));
    for (size_t i = 0; i < A->nb; i++) { /* exact inverses of the diagonal blocks for Jacobi (2-D only here) */
        const double *a = A->val + A->row[i] * bb;
        double det = a[0] * a[3] - a[1] * a[2];
        dinv[i * bb] = a[3] / det;
        dinv[i * bb + 1] = -a[1] / det;
        dinv[i * bb + 2] = -a[2] / det;
        dinv[i * bb + 3] = a[0] / det;
    }
#define PRECOND(rr, zz)                                                                          \
    do {                                                                                         \
        if (amg)                                                                                 \
            psys__amg_apply(amg, rr, zz);                                                        \
        else                                                                                     \
            for (size_t i_ = 0; i_ < A->nb; i_++)                                                \
                for (int r_ = 0; r_ < 2; r_++)                                                   \
                    zz[i_ * 2 + r_] = dinv[i_ * bb + r_ * 2] * rr[i_ * 2] + dinv[i_ * bb + r_ * 2 + 1] * rr[i_ * 2 + 1]; \
    } while (0)
    memcpy(r, b, n * sizeof(double));
    PRECOND(r, z);
    memcpy(p, z, n * sizeof(double));
    double rz = dot(r, z, n), bnorm = sqrt(dot(b, b, n));
    int it = 0;
    while (sqrt(dot(r, r, n)) > tol * bnorm && it < 10000) {
        psys__bsr_sym_mul(A->nb, A->bs, A->row, A->col, A->val, p, q);
        double alpha = rz / dot(p, q, n);
        for (size_t i = 0; i < n; i++) {
            x[i] += alpha * p[i];
            r[i] -= alpha * q[i];
        }
        PRECOND(r, z);
        double rz2 = dot(r, z, n);
        for (size_t i = 0; i < n; i++)
            p[i] = z[i] + rz2 / rz * p[i];
        rz = rz2;
        it++;
    }
#undef PRECOND
    free(x);
    free(r);
    free(z);
    free(p);
    free(q);
    free(dinv);
    return it;
}

/* ⟨V a, b⟩ = ⟨a, V b⟩ and ⟨V a, a⟩ > 0 for random vectors, in 2-D and 3-D. */
static void vcycle_is_spd(void)
{
    for (int bs = 2; bs <= 3; bs++) {
        mat A = grid(30, 30, bs, 1e-4, 1.0);
        psys__amg *amg = psys__amg_create(A.nb, bs, A.row, A.col, A.val);
        CHECK(amg != NULL);
        if (!amg) {
            mat_free(&A);
            continue;
        }
        CHECK(psys__amg_levels(amg) >= 3); /* 900 nodes, about 9 per aggregate, down to <= 16 */
        size_t n = A.nb * (size_t)bs;
        double *a = malloc(n * sizeof(double)), *b = malloc(n * sizeof(double));
        double *va = malloc(n * sizeof(double)), *vb = malloc(n * sizeof(double));
        unsigned seed = 7;
        for (int trial = 0; trial < 5; trial++) {
            random_vec(a, n, &seed);
            random_vec(b, n, &seed);
            psys__amg_apply(amg, a, va);
            psys__amg_apply(amg, b, vb);
            double ab = dot(va, b, n), ba = dot(a, vb, n);
            CHECK(fabs(ab - ba) <= 1e-10 * (fabs(ab) + fabs(ba)));
            CHECK(dot(va, a, n) > 0);
        }
        free(a);
        free(b);
        free(va);
        free(vb);
        psys__amg_destroy(amg);
        mat_free(&A);
    }
}

/* A system no larger than the coarsest level is solved exactly by one cycle. */
static void small_system_exact(void)
{
    mat A = grid(4, 4, 3, 1e-3, 50.0);
    psys__amg *amg = psys__amg_create(A.nb, 3, A.row, A.col, A.val);
    CHECK(amg != NULL && psys__amg_levels(amg) == 1);
    size_t n = A.nb * 3;
    double *x = malloc(n * sizeof(double)), *b = malloc(n * sizeof(double)), *ax = malloc(n * sizeof(double));
    unsigned seed = 3;
    random_vec(b, n, &seed);
    if (amg)
        psys__amg_apply(amg, b, x);
    psys__bsr_sym_mul(A.nb, 3, A.row, A.col, A.val, x, ax);
    double err = 0;
    for (size_t i = 0; i < n; i++)
        err = fmax(err, fabs(ax[i] - b[i]));
    CHECK(err < 1e-9 * sqrt(dot(b, b, n)));
    free(x);
    free(b);
    free(ax);
    psys__amg_destroy(amg);
    mat_free(&A);
}

/* A stiff 64×64 spring grid (k/m = 10⁴, the cloth of issue 7 at dt 1/60 has
 * h²k/m ≈ 300): block-Jacobi CG needs hundreds of iterations for 1e-6, the
 * V-cycle a few tens; and the updated hierarchy follows new values. */
static void fewer_iterations(void)
{
    mat A = grid(64, 64, 2, 1e-4, 1.0);
    size_t n = A.nb * 2;
    double *b = malloc(n * sizeof(double));
    unsigned seed = 11;
    random_vec(b, n, &seed);
    psys__amg *amg = psys__amg_create(A.nb, 2, A.row, A.col, A.val);
    CHECK(amg != NULL);
    int jac = pcg(&A, NULL, b, 1e-6), mg = amg ? pcg(&A, amg, b, 1e-6) : 0;
    fprintf(stderr, "64x64 grid, tolerance 1e-6: block Jacobi %d iterations, multigrid %d (%d levels)\n", jac, mg,
            amg ? psys__amg_levels(amg) : 0);
    CHECK(jac > 200);
    CHECK(mg > 0 && mg * 5 < jac);
    /* new values in the same pattern: update() must rebuild the coarse matrices */
    size_t nnz = A.row[A.nb];
    for (size_t k = 0; k < nnz * 4; k++)
        A.val[k] *= 2.0;
    if (amg) {
        psys__amg_update(amg);
        int mg2 = pcg(&A, amg, b, 1e-6);
        CHECK(mg2 > 0 && mg2 <= mg + 2); /* a scaled matrix: the same convergence */
    }
    free(b);
    psys__amg_destroy(amg);
    mat_free(&A);
}

/* Particles joined by nothing: aggregation stalls (every aggregate a single
 * particle), so the finest level is the coarsest and, above 16 particles,
 * is smoothed by Gauss–Seidel instead of Cholesky; for a block-diagonal
 * matrix one forward-backward pair solves exactly: z = D⁻¹ r. */
static void stalled_coarsening_gauss_seidel(void)
{
    const size_t nb = 40;
    mat A = {nb, 2, calloc(nb + 1, sizeof(size_t)), calloc(nb, sizeof(size_t)), calloc(nb * 4, sizeof(double))};
    for (size_t i = 0; i < nb; i++) {
        A.row[i + 1] = i + 1;
        A.col[i] = i;
        double *d = A.val + 4 * i;
        d[0] = 2.0 + (double)i;
        d[1] = d[2] = 0.5;
        d[3] = 1.0 + 0.25 * (double)i;
    }
    psys__amg *amg = psys__amg_create(nb, 2, A.row, A.col, A.val);
    CHECK(amg != NULL && psys__amg_levels(amg) == 1);
    double r[80], z[80], az[80];
    unsigned seed = 5;
    random_vec(r, 80, &seed);
    if (amg) {
        psys__amg_apply(amg, r, z);
        psys__bsr_sym_mul(nb, 2, A.row, A.col, A.val, z, az);
        for (size_t k = 0; k < 80; k++)
            CHECK(fabs(az[k] - r[k]) <= 1e-14 * (1 + fabs(r[k])));
    }
    psys__amg_destroy(amg);
    mat_free(&A);
}

static const check_case cases[] = {
    {"stalled_coarsening_gauss_seidel", stalled_coarsening_gauss_seidel},
    {"vcycle_is_spd", vcycle_is_spd},
    {"small_system_exact", small_system_exact},
    {"fewer_iterations", fewer_iterations},
    {NULL, NULL},
};

int main(int argc, char **argv) { return check_main(argc, argv, cases); }
