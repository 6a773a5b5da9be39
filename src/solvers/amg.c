/* Aggregation multigrid for implicit-euler's block systems (src/solvers/amg.h).
 *
 * Why: with stiff springs the system M - h ∂f/∂v - h² ∂f/∂x is dominated by
 * a graph Laplacian of the springs, whose condition number grows with the
 * square of the mesh size; block-Jacobi conjugate gradient then needs
 * hundreds of iterations per step on a 100×100 cloth. A multigrid cycle
 * removes the smooth (long-wavelength) error that Jacobi and Gauss–Seidel
 * barely touch, so CG needs a few iterations instead.
 *
 * Levels: the nodes of each level are grouped into aggregates (a node and
 * its strongly coupled neighbours); each aggregate is one node of the next
 * level, with piecewise-constant prolongation P (identity blocks) and the
 * Galerkin matrix Pᵀ A P. Everything runs in a fixed order, so the result
 * does not depend on threads. */
#include "solvers/amg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_LEVELS = 16, COARSE_NODES = 16 }; /* coarsest level: a dense Cholesky of at most 48 unknowns */
#define STRONG 0.25 /* a coupling is strong at >= STRONG × the largest at either end */
#define NONE ((size_t)-1)

typedef struct level {
    size_t nb, nnz;
    const size_t *row, *col; /* level 0: the caller's; others: orow, ocol */
    const double *val;       /* level 0: the caller's; others: oval */
    size_t *orow, *ocol;
    double *oval;
    double *dinv;            /* nb × bs²: inverse diagonal blocks */
    size_t *agg;             /* nb: node of the next level (not on the coarsest) */
    unsigned char *strong;   /* nnz: the strong couplings the aggregates came from (NULL: not aggregated) */
    size_t *map;             /* nnz: block of the next level each block adds to */
    unsigned char *how;      /* nnz: 0 add B, 1 add Bᵀ, 2 add B + Bᵀ */
    /* A P (nb × next level's nb, block rows, gather only): the product of
     * the prolongated coarse correction, cheaper than A (P x_c) in full;
     * ap_map[2e], ap_map[2e+1]: where block e adds as (i, agg j), (j, agg i) */
    size_t *ap_row, *ap_col, *ap_map;
    double *ap_val;
    double *x, *b, *t;       /* nb × bs work vectors */
} level;

struct psys__amg {
    int bs, nlev;
    level lev[MAX_LEVELS];
    double *chol;            /* coarsest level: dense Cholesky factor (lower, n × n) */
    /* scratch for finding strong couplings (sized for level 0, the largest) */
    double *norm, *rowmax;   /* nnz, nb */
    unsigned char *strong;   /* nnz: psys__amg_refresh's of the current values */
    size_t *agg;             /* nb: psys__amg_refresh's aggregates of the current values */
    size_t nc;               /* its order (0: the coarsest level uses Gauss–Seidel) */
    int chol_ok;             /* the last factorisation succeeded */
};

/* ---- blocks ---- */

/* Inverse of the symmetric positive-definite b×b block a (b = 2 or 3) into
 * out; zero when a is not positive definite. */
static void block_inverse(const double *a, int b, double *out)
{
    memset(out, 0, sizeof(double) * (size_t)b * b);
    if (b == 2) {
        double det = a[0] * a[3] - a[1] * a[2];
        if (!(det > 0) || !(a[0] > 0))
            return;
        out[0] = a[3] / det;
        out[1] = -a[1] / det;
        out[2] = -a[2] / det;
        out[3] = a[0] / det;
        return;
    }
    double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8], c02 = a[3] * a[7] - a[4] * a[6];
    double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    if (!(det > 0) || !(a[0] > 0))
        return;
    out[0] = c00 / det;
    out[1] = (a[2] * a[7] - a[1] * a[8]) / det;
    out[2] = (a[1] * a[5] - a[2] * a[4]) / det;
    out[3] = c01 / det;
    out[4] = (a[0] * a[8] - a[2] * a[6]) / det;
    out[5] = (a[2] * a[3] - a[0] * a[5]) / det;
    out[6] = c02 / det;
    out[7] = (a[1] * a[6] - a[0] * a[7]) / det;
    out[8] = (a[0] * a[4] - a[1] * a[3]) / det;
}

static double block_norm(const double *a, int b)
{
    double s = 0;
    for (int k = 0; k < b * b; k++)
        s += a[k] * a[k];
    return sqrt(s);
}

/* ---- products and sweeps (B is a constant in each instantiation) ---- */

static inline void sym_mul_b(const level *L, const double *restrict x, double *restrict y, const int B)
{
    const size_t *restrict row = L->row, *restrict col = L->col;
    const double *restrict val = L->val;
    size_t n = L->nb * (size_t)B;
    for (size_t k = 0; k < n; k++)
        y[k] = 0.0;
    for (size_t i = 0; i < L->nb; i++) {
        const double *xi = x + i * B, *d = val + row[i] * (size_t)(B * B);
        double acc[3] = {0, 0, 0};
        for (int r = 0; r < B; r++)
            for (int c = 0; c < B; c++)
                acc[r] += d[r * B + c] * xi[c];
        for (size_t e = row[i] + 1; e < row[i + 1]; e++) {
            const double *blk = val + e * (size_t)(B * B), *xj = x + col[e] * B;
            double *yj = y + col[e] * B;
            for (int r = 0; r < B; r++)
                for (int c = 0; c < B; c++) {
                    acc[r] += blk[r * B + c] * xj[c];
                    yj[c] += blk[r * B + c] * xi[r];
                }
        }
        for (int r = 0; r < B; r++)
            y[i * B + r] += acc[r];
    }
}

/* t_j += A_ijᵀ x_i for the stored blocks (i, j > i) of row i: the lower
 * triangle's contribution of x_i, which Gauss–Seidel sums in both directions. */
static inline void scatter_lower(const level *L, size_t i, const double *xi, double *t, const int B)
{
    for (size_t e = L->row[i] + 1; e < L->row[i + 1]; e++) {
        const double *blk = L->val + e * (size_t)(B * B);
        double *tj = t + L->col[e] * B;
        for (int r = 0; r < B; r++)
            for (int c = 0; c < B; c++)
                tj[c] += blk[r * B + c] * xi[r];
    }
}

/* out = D s for one B×B block D. */
static inline void block_apply(const double *D, const double *s, double *out, const int B)
{
    for (int r = 0; r < B; r++) {
        double v = 0;
        for (int c = 0; c < B; c++)
            v += D[r * B + c] * s[c];
        out[r] = v;
    }
}

/* Forward block Gauss–Seidel from x = 0: x_i = D_i⁻¹ (b_i - Σ_{j<i} A_ij x_j);
 * the lower sums are scattered from the upper blocks into t as rows finish. */
static inline void forward_gs_b(const level *L, const int B)
{
    const double *restrict dinv = L->dinv, *restrict b = L->b;
    double *restrict x = L->x, *restrict t = L->t;
    size_t n = L->nb * (size_t)B;
    for (size_t k = 0; k < n; k++)
        t[k] = 0.0;
    for (size_t i = 0; i < L->nb; i++) {
        double s[3], *xi = x + i * B;
        const double *di = dinv + i * (size_t)(B * B);
        for (int r = 0; r < B; r++)
            s[r] = b[i * B + r] - t[i * B + r];
        block_apply(di, s, xi, B);
        scatter_lower(L, i, xi, t, B);
    }
}

/* Backward block Gauss–Seidel on the current x: rows in descending order,
 * x_i = D_i⁻¹ (b_i - Σ_{j<i} A_ij x_j(old) - Σ_{j>i} A_ij x_j(new)); the
 * lower sums use the old x only, so they are gathered first into t. */
static inline void backward_gs_b(const level *L, const int B)
{
    const size_t *restrict row = L->row, *restrict col = L->col;
    const double *restrict val = L->val, *restrict dinv = L->dinv, *restrict b = L->b;
    double *restrict x = L->x, *restrict t = L->t;
    size_t n = L->nb * (size_t)B;
    for (size_t k = 0; k < n; k++)
        t[k] = 0.0;
    for (size_t i = 0; i < L->nb; i++) {
        const double *xi = x + i * B;
        scatter_lower(L, i, xi, t, B);
    }
    for (size_t i = L->nb; i-- > 0;) {
        double s[3];
        for (int r = 0; r < B; r++)
            s[r] = b[i * B + r] - t[i * B + r];
        for (size_t e = row[i] + 1; e < row[i + 1]; e++) {
            const double *blk = val + e * (size_t)(B * B), *xj = x + col[e] * B;
            for (int r = 0; r < B; r++)
                for (int c = 0; c < B; c++)
                    s[r] -= blk[r * B + c] * xj[c];
        }
        const double *di = dinv + i * (size_t)(B * B);
        double *xi = x + i * B;
        block_apply(di, s, xi, B);
    }
}

static void sym_mul(const level *L, int bs, const double *x, double *y)
{
    if (bs == 3)
        sym_mul_b(L, x, y, 3);
    else
        sym_mul_b(L, x, y, 2);
}

static void forward_gs(const level *L, int bs)
{
    if (bs == 3)
        forward_gs_b(L, 3);
    else
        forward_gs_b(L, 2);
}

static void backward_gs(const level *L, int bs)
{
    if (bs == 3)
        backward_gs_b(L, 3);
    else
        backward_gs_b(L, 2);
}

/* ---- setup ---- */

/* A coupling is strong when its block is at least STRONG × the largest
 * coupling at either of its ends (weak ones, e.g. bend springs, are left to
 * the smoother): flag[e] for each block of L (0 on the diagonal); norm and
 * rowmax are scratch (nnz, nb). */
static void strong_couplings(const level *L, int bs, double *norm, double *rowmax, unsigned char *flag)
{
    size_t nb = L->nb, bb = (size_t)bs * bs;
    for (size_t i = 0; i < nb; i++)
        rowmax[i] = 0;
    for (size_t i = 0; i < nb; i++)
        for (size_t e = L->row[i] + 1; e < L->row[i + 1]; e++) {
            double s = block_norm(L->val + e * bb, bs);
            size_t j = L->col[e];
            norm[e] = s;
            rowmax[i] = fmax(rowmax[i], s);
            rowmax[j] = fmax(rowmax[j], s);
        }
    for (size_t i = 0; i < nb; i++) {
        if (L->row[i] < L->row[i + 1])
            flag[L->row[i]] = 0;
        for (size_t e = L->row[i] + 1; e < L->row[i + 1]; e++)
            flag[e] = norm[e] > 0 && norm[e] >= STRONG * fmax(rowmax[i], rowmax[L->col[e]]);
    }
}

/* Group the nodes of L into aggregates of the strong couplings flag
 * (strong_couplings): agg[i] gets the aggregate of node i; returns their
 * number, or NONE when out of memory. */
static size_t aggregate(const level *L, const unsigned char *flag, size_t *agg)
{
    size_t nb = L->nb;
    size_t *start = psys__calloc(nb + 1, sizeof(size_t)), *fill = psys__calloc(nb ? nb : 1, sizeof(size_t));
    unsigned char *joined = psys__calloc(nb ? nb : 1, 1);
    size_t *adj = NULL, nagg = NONE;
    if (!start || !fill || !joined)
        goto done;
    /* The strong graph, both directions, as adjacency lists. */
    for (size_t i = 0; i < nb; i++)
        for (size_t e = L->row[i] + 1; e < L->row[i + 1]; e++)
            if (flag[e]) {
                start[i + 1]++;
                start[L->col[e] + 1]++;
            }
    for (size_t i = 0; i < nb; i++)
        start[i + 1] += start[i];
    if (!(adj = psys__calloc(start[nb] ? start[nb] : 1, sizeof(size_t))))
        goto done;
    memcpy(fill, start, nb * sizeof(size_t));
    for (size_t i = 0; i < nb; i++)
        for (size_t e = L->row[i] + 1; e < L->row[i + 1]; e++)
            if (flag[e]) {
                adj[fill[i]++] = L->col[e];
                adj[fill[L->col[e]]++] = i;
            }
    for (size_t i = 0; i < nb; i++)
        agg[i] = NONE;
    nagg = 0;
    /* 1: a node whose strong neighbours are all free starts an aggregate with them. */
    for (size_t i = 0; i < nb; i++) {
        if (agg[i] != NONE || start[i] == start[i + 1])
            continue;
        bool free_around = true;
        for (size_t q = start[i]; q < start[i + 1] && free_around; q++)
            free_around = agg[adj[q]] == NONE;
        if (!free_around)
            continue;
        agg[i] = nagg;
        for (size_t q = start[i]; q < start[i + 1]; q++)
            agg[adj[q]] = nagg;
        nagg++;
    }
    /* 2: the rest join the aggregate of a strong neighbour placed in pass 1. */
    for (size_t i = 0; i < nb; i++) {
        if (agg[i] != NONE)
            continue;
        for (size_t q = start[i]; q < start[i + 1]; q++)
            if (agg[adj[q]] != NONE && !joined[adj[q]]) {
                agg[i] = agg[adj[q]];
                joined[i] = 1;
                break;
            }
    }
    /* 3: what is left (isolated nodes, or ones whose neighbours joined in
     * pass 2) forms aggregates with its free strong neighbours. */
    for (size_t i = 0; i < nb; i++) {
        if (agg[i] != NONE)
            continue;
        agg[i] = nagg;
        for (size_t q = start[i]; q < start[i + 1]; q++)
            if (agg[adj[q]] == NONE)
                agg[adj[q]] = nagg;
        nagg++;
    }
done:
    free(start);
    free(fill);
    free(joined);
    free(adj);
    return nagg;
}

static int cmp_pair(const void *a, const void *b)
{
    const size_t *p = a, *q = b;
    if (p[0] != q[0])
        return p[0] < q[0] ? -1 : 1;
    return p[1] < q[1] ? -1 : p[1] > q[1];
}

/* Sorted by i with a counting sort (when the indices are at most k and the
 * scratch is there), then each i's run by j (insertion sort for short runs):
 * hierarchies are rebuilt often with pair forces, and qsort's calls to
 * cmp_pair were most of the cost. The same order as qsort's. */
static bool pairs_sort_counting(size_t *pairs, size_t k)
{
    size_t imax = 0;
    for (size_t q = 0; q < k; q++)
        imax = pairs[2 * q] > imax ? pairs[2 * q] : imax;
    if (k < 64 || imax > k)
        return false;
    size_t *start = psys__calloc(imax + 2, sizeof(size_t)), *tmp = psys__calloc(k, 2 * sizeof(size_t));
    if (!start || !tmp) {
        free(start);
        free(tmp);
        return false;
    }
    for (size_t q = 0; q < k; q++)
        start[pairs[2 * q] + 1]++;
    for (size_t i = 0; i <= imax; i++)
        start[i + 1] += start[i];
    for (size_t q = 0; q < k; q++) {
        size_t t = start[pairs[2 * q]]++;
        tmp[2 * t] = pairs[2 * q];
        tmp[2 * t + 1] = pairs[2 * q + 1];
    }
    memcpy(pairs, tmp, k * 2 * sizeof(size_t));
    free(tmp);
    for (size_t i = 0, lo = 0; i <= imax; i++) {
        size_t hi = start[i]; /* now the end of i's run */
        if (hi - lo > 32) {
            qsort(pairs + 2 * lo, hi - lo, 2 * sizeof(size_t), cmp_pair);
        } else {
            for (size_t q = lo + 1; q < hi; q++) {
                size_t j = pairs[2 * q + 1], r = q;
                for (; r > lo && pairs[2 * (r - 1) + 1] > j; r--)
                    pairs[2 * r + 1] = pairs[2 * (r - 1) + 1];
                pairs[2 * r + 1] = j;
            }
        }
        lo = hi;
    }
    free(start);
    return true;
}

size_t psys__pairs_sort_unique(size_t *pairs, size_t k)
{
    if (!pairs_sort_counting(pairs, k))
        qsort(pairs, k, 2 * sizeof(size_t), cmp_pair);
    size_t u = 0;
    for (size_t q = 0; q < k; q++)
        if (u == 0 || cmp_pair(pairs + 2 * q, pairs + 2 * (u - 1)) != 0) {
            pairs[2 * u] = pairs[2 * q];
            pairs[2 * u + 1] = pairs[2 * q + 1];
            u++;
        }
    return u;
}

size_t psys__block_find(const size_t *row, const size_t *col, size_t i, size_t j)
{
    size_t lo = row[i], hi = row[i + 1];
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (col[mid] < j)
            lo = mid + 1;
        else if (col[mid] > j)
            hi = mid;
        else
            return mid;
    }
    return NONE;
}

/* The pattern of A P: row i holds a block for the aggregate of i and of
 * each neighbour of i (either direction). */
static psys_status build_ap(level *L, int bs)
{
    size_t *pairs = psys__calloc(2 * L->nnz, 2 * sizeof(size_t)), k = 0;
    if (!pairs)
        return PSYS_ERR_NOMEM;
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++) {
            size_t j = L->col[e];
            pairs[2 * k] = i;
            pairs[2 * k + 1] = L->agg[j];
            k++;
            if (j != i) {
                pairs[2 * k] = j;
                pairs[2 * k + 1] = L->agg[i];
                k++;
            }
        }
    size_t u = psys__pairs_sort_unique(pairs, k);
    L->ap_row = psys__calloc(L->nb + 1, sizeof(size_t));
    L->ap_col = psys__calloc(u ? u : 1, sizeof(size_t));
    L->ap_val = psys__calloc(u ? u * (size_t)bs * bs : 1, sizeof(double));
    L->ap_map = psys__calloc(2 * L->nnz, sizeof(size_t));
    if (!L->ap_row || !L->ap_col || !L->ap_val || !L->ap_map) {
        free(pairs);
        return PSYS_ERR_NOMEM;
    }
    for (size_t q = 0; q < u; q++) {
        L->ap_row[pairs[2 * q] + 1]++;
        L->ap_col[q] = pairs[2 * q + 1];
    }
    for (size_t i = 0; i < L->nb; i++)
        L->ap_row[i + 1] += L->ap_row[i];
    free(pairs);
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++) {
            size_t j = L->col[e];
            L->ap_map[2 * e] = psys__block_find(L->ap_row, L->ap_col, i, L->agg[j]);
            L->ap_map[2 * e + 1] = j != i ? psys__block_find(L->ap_row, L->ap_col, j, L->agg[i]) : NONE;
        }
    return PSYS_OK;
}

/* The pattern of the next level C from L's aggregates, and L's map/how. */
static psys_status build_coarse(level *L, level *C, int bs, size_t nc)
{
    size_t total = L->nnz + nc;
    size_t *pairs = psys__calloc(total, 2 * sizeof(size_t));
    if (!pairs)
        return PSYS_ERR_NOMEM;
    size_t k = 0;
    for (size_t I = 0; I < nc; I++, k++)
        pairs[2 * k] = pairs[2 * k + 1] = I;
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++, k++) {
            size_t I = L->agg[i], J = L->agg[L->col[e]];
            pairs[2 * k] = I < J ? I : J;
            pairs[2 * k + 1] = I < J ? J : I;
        }
    size_t u = psys__pairs_sort_unique(pairs, k);
    size_t n = nc * (size_t)bs;
    C->nb = nc;
    C->nnz = u;
    C->orow = psys__calloc(nc + 1, sizeof(size_t));
    C->ocol = psys__calloc(u, sizeof(size_t));
    C->oval = psys__calloc(u * (size_t)bs * bs, sizeof(double));
    C->dinv = psys__calloc(nc * (size_t)bs * bs, sizeof(double));
    C->x = psys__calloc(n, sizeof(double));
    C->b = psys__calloc(n, sizeof(double));
    C->t = psys__calloc(n, sizeof(double));
    L->map = psys__calloc(L->nnz, sizeof(size_t));
    L->how = psys__calloc(L->nnz, 1);
    if (!C->orow || !C->ocol || !C->oval || !C->dinv || !C->x || !C->b || !C->t || !L->map || !L->how) {
        free(pairs);
        return PSYS_ERR_NOMEM;
    }
    for (size_t q = 0; q < u; q++) {
        C->orow[pairs[2 * q] + 1]++;
        C->ocol[q] = pairs[2 * q + 1];
    }
    for (size_t I = 0; I < nc; I++)
        C->orow[I + 1] += C->orow[I];
    free(pairs);
    C->row = C->orow;
    C->col = C->ocol;
    C->val = C->oval;
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++) {
            size_t j = L->col[e], I = L->agg[i], J = L->agg[j];
            L->map[e] = psys__block_find(C->row, C->col, I < J ? I : J, I < J ? J : I);
            L->how[e] = i == j ? 0 : I < J ? 0 : I > J ? 1 : 2;
        }
    return build_ap(L, bs);
}

/* Galerkin product: C = Pᵀ L P, summed in L's block order. */
static void galerkin(const level *L, level *C, int bs)
{
    size_t bb = (size_t)bs * bs;
    memset(C->oval, 0, C->nnz * bb * sizeof(double));
    for (size_t e = 0; e < L->nnz; e++) {
        const double *a = L->val + e * bb;
        double *c = C->oval + L->map[e] * bb;
        for (int r = 0; r < bs; r++)
            for (int q = 0; q < bs; q++) {
                double v = a[r * bs + q];
                if (L->how[e] != 1)
                    c[r * bs + q] += v;
                if (L->how[e] != 0)
                    c[q * bs + r] += v;
            }
    }
}

/* A P from L's values: block (i, J) = Σ_{j in J} A_ij. */
static void ap_update(level *L, int bs)
{
    size_t bb = (size_t)bs * bs;
    memset(L->ap_val, 0, L->ap_row[L->nb] * bb * sizeof(double));
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++) {
            const double *a = L->val + e * bb;
            double *p = L->ap_val + L->ap_map[2 * e] * bb;
            for (size_t k = 0; k < bb; k++)
                p[k] += a[k];
            if (L->ap_map[2 * e + 1] != NONE) {
                double *q = L->ap_val + L->ap_map[2 * e + 1] * bb;
                for (int r = 0; r < bs; r++)
                    for (int c = 0; c < bs; c++)
                        q[c * bs + r] += a[r * bs + c];
            }
        }
}

/* t += (A P) xc. */
static inline void ap_mul_add_b(const level *L, const double *restrict xc, double *restrict t, const int B)
{
    const size_t *restrict row = L->ap_row, *restrict col = L->ap_col;
    const double *restrict val = L->ap_val;
    for (size_t i = 0; i < L->nb; i++) {
        double acc[3] = {0, 0, 0};
        for (size_t q = row[i]; q < row[i + 1]; q++) {
            const double *blk = val + q * (size_t)(B * B), *xj = xc + col[q] * B;
            for (int r = 0; r < B; r++)
                for (int c = 0; c < B; c++)
                    acc[r] += blk[r * B + c] * xj[c];
        }
        for (int r = 0; r < B; r++)
            t[i * B + r] += acc[r];
    }
}

static void ap_mul_add(const level *L, int bs, const double *xc, double *t)
{
    if (bs == 3)
        ap_mul_add_b(L, xc, t, 3);
    else
        ap_mul_add_b(L, xc, t, 2);
}

static void inverse_diagonals(level *L, int bs)
{
    size_t bb = (size_t)bs * bs;
    for (size_t i = 0; i < L->nb; i++)
        block_inverse(L->val + L->row[i] * bb, bs, L->dinv + i * bb);
}

/* Dense Cholesky of the coarsest level; 0 if it is not positive definite. */
static int factor_coarsest(psys__amg *a)
{
    level *L = &a->lev[a->nlev - 1];
    size_t n = a->nc, bs = (size_t)a->bs;
    double *A = a->chol;
    memset(A, 0, n * n * sizeof(double));
    for (size_t i = 0; i < L->nb; i++)
        for (size_t e = L->row[i]; e < L->row[i + 1]; e++) {
            size_t j = L->col[e];
            const double *blk = L->val + e * bs * bs;
            for (size_t r = 0; r < bs; r++)
                for (size_t c = 0; c < bs; c++) {
                    A[(i * bs + r) * n + j * bs + c] = blk[r * bs + c];
                    A[(j * bs + c) * n + i * bs + r] = blk[r * bs + c];
                }
        }
    for (size_t j = 0; j < n; j++) {
        double d = A[j * n + j];
        for (size_t k = 0; k < j; k++)
            d -= A[j * n + k] * A[j * n + k];
        if (!(d > 0))
            return 0;
        d = sqrt(d);
        A[j * n + j] = d;
        for (size_t i = j + 1; i < n; i++) {
            double s = A[i * n + j];
            for (size_t k = 0; k < j; k++)
                s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / d;
        }
    }
    return 1;
}

static void solve_coarsest(const psys__amg *a, level *L)
{
    size_t n = a->nc;
    const double *A = a->chol;
    double *x = L->x;
    for (size_t i = 0; i < n; i++) {
        double s = L->b[i];
        for (size_t k = 0; k < i; k++)
            s -= A[i * n + k] * x[k];
        x[i] = s / A[i * n + i];
    }
    for (size_t i = n; i-- > 0;) {
        double s = x[i];
        for (size_t k = i + 1; k < n; k++)
            s -= A[k * n + i] * x[k];
        x[i] = s / A[i * n + i];
    }
}

void psys__amg_destroy(psys__amg *a)
{
    if (!a)
        return;
    for (int l = 0; l < MAX_LEVELS; l++) {
        level *L = &a->lev[l];
        free(L->orow);
        free(L->ocol);
        free(L->oval);
        free(L->dinv);
        free(L->agg);
        free(L->strong);
        free(L->map);
        free(L->how);
        free(L->ap_row);
        free(L->ap_col);
        free(L->ap_map);
        free(L->ap_val);
        free(L->x);
        free(L->b);
        free(L->t);
    }
    free(a->chol);
    free(a->norm);
    free(a->rowmax);
    free(a->strong);
    free(a->agg);
    free(a);
}

psys__amg *psys__amg_create(size_t nb, int bs, const size_t *row, const size_t *col, const double *val)
{
    psys__amg *a = psys__calloc(1, sizeof *a);
    if (!a)
        return NULL;
    a->bs = bs;
    a->nlev = 1;
    level *L0 = &a->lev[0];
    size_t n = nb * (size_t)bs;
    L0->nb = nb;
    L0->nnz = row[nb];
    L0->row = row;
    L0->col = col;
    L0->val = val;
    L0->dinv = psys__calloc(nb ? nb * (size_t)bs * bs : 1, sizeof(double));
    L0->x = psys__calloc(n ? n : 1, sizeof(double));
    L0->b = psys__calloc(n ? n : 1, sizeof(double));
    L0->t = psys__calloc(n ? n : 1, sizeof(double));
    a->norm = psys__calloc(L0->nnz ? L0->nnz : 1, sizeof(double));
    a->rowmax = psys__calloc(nb ? nb : 1, sizeof(double));
    a->strong = psys__calloc(L0->nnz ? L0->nnz : 1, 1);
    a->agg = psys__calloc(nb ? nb : 1, sizeof(size_t));
    if (!L0->dinv || !L0->x || !L0->b || !L0->t || !a->norm || !a->rowmax || !a->strong || !a->agg)
        goto fail;
    while (a->nlev < MAX_LEVELS && a->lev[a->nlev - 1].nb > COARSE_NODES) {
        level *L = &a->lev[a->nlev - 1], *C = &a->lev[a->nlev];
        if (!(L->agg = psys__calloc(L->nb, sizeof(size_t))) || !(L->strong = psys__calloc(L->nnz ? L->nnz : 1, 1)))
            goto fail;
        strong_couplings(L, bs, a->norm, a->rowmax, L->strong); /* coarse levels are smaller than level 0 */
        size_t nc = aggregate(L, L->strong, L->agg);
        if (nc == NONE)
            goto fail;
        if (nc == 0 || (double)nc > 0.8 * (double)L->nb) { /* coarsening stalled: L is the coarsest */
            free(L->agg);
            L->agg = NULL;
            break;
        }
        if (build_coarse(L, C, bs, nc) != PSYS_OK)
            goto fail;
        galerkin(L, C, bs);
        a->nlev++;
    }
    level *Lc = &a->lev[a->nlev - 1];
    if (Lc->nb <= COARSE_NODES && Lc->nb > 0) {
        a->nc = Lc->nb * (size_t)bs;
        if (!(a->chol = psys__calloc(a->nc * a->nc, sizeof(double))))
            goto fail;
    }
    psys__amg_update(a);
    return a;
fail:
    psys__amg_destroy(a);
    return NULL;
}

/* The rest of an update, the coarse matrices (Galerkin products) done or not. */
static void update(psys__amg *a, bool coarse_done)
{
    for (int l = 0; l + 1 < a->nlev; l++) {
        if (!coarse_done)
            galerkin(&a->lev[l], &a->lev[l + 1], a->bs);
        ap_update(&a->lev[l], a->bs);
    }
    for (int l = 0; l < a->nlev; l++)
        inverse_diagonals(&a->lev[l], a->bs);
    a->chol_ok = a->nc ? factor_coarsest(a) : 0;
}

void psys__amg_update(psys__amg *a) { update(a, false); }

/* Level by level from the finest: the strong couplings of the current values
 * (the coarse ones from the Galerkin product of the level above); when they
 * differ from those the level was aggregated from, the aggregates they give,
 * compared with the level's (a level create left unaggregated, the coarsest
 * at or below COARSE_NODES nodes or MAX_LEVELS deep, has none to compare;
 * one where coarsening stalled must stall again: no next level). */
bool psys__amg_refresh(psys__amg *a)
{
    int bs = a->bs;
    for (int l = 0; l < a->nlev; l++) {
        level *L = &a->lev[l];
        if (!L->strong)
            break;
        strong_couplings(L, bs, a->norm, a->rowmax, a->strong);
        if (memcmp(a->strong, L->strong, L->nnz) != 0) {
            size_t nc = aggregate(L, a->strong, a->agg);
            bool stalled = nc == 0 || (double)nc > 0.8 * (double)L->nb;
            if (nc == NONE || (l + 1 == a->nlev) != stalled)
                return false;
            if (!stalled && (nc != a->lev[l + 1].nb || memcmp(a->agg, L->agg, L->nb * sizeof(size_t)) != 0))
                return false;
            memcpy(L->strong, a->strong, L->nnz); /* the same aggregates: compare with these from now */
        }
        if (l + 1 < a->nlev)
            galerkin(L, &a->lev[l + 1], bs);
    }
    update(a, true);
    return true;
}

/* Damped block Jacobi, the smoother: x = ω D⁻¹ b (from zero, before the
 * coarse correction) or x += ω D⁻¹ (b - A x) (after it; t holds A x). The
 * same ω both times keeps the cycle symmetric. It needs somewhat more cycles
 * than Gauss–Seidel (bench/HISTORY.md) but one pass over the matrix
 * instead of three, which is what costs: the sweeps are memory bound. */
static void jacobi(const level *L, int bs, bool from_zero)
{
    const double w = 0.7;
    size_t bb = (size_t)bs * bs;
    for (size_t i = 0; i < L->nb; i++) {
        const double *di = L->dinv + i * bb;
        double s[3];
        for (int r = 0; r < bs; r++)
            s[r] = L->b[i * bs + r] - (from_zero ? 0.0 : L->t[i * bs + r]);
        for (int r = 0; r < bs; r++) {
            double v = 0;
            for (int c = 0; c < bs; c++)
                v += di[r * bs + c] * s[c];
            L->x[i * bs + r] = (from_zero ? 0.0 : L->x[i * bs + r]) + w * v;
        }
    }
}

static void cycle(psys__amg *a, int l)
{
    level *L = &a->lev[l];
    int bs = a->bs;
    if (l == a->nlev - 1) {
        if (a->chol_ok)
            solve_coarsest(a, L);
        else {
            forward_gs(L, bs);
            backward_gs(L, bs);
        }
        return;
    }
    level *C = &a->lev[l + 1];
    size_t nc = C->nb * (size_t)bs;
    jacobi(L, bs, true);
    /* Below the finest level the cycle is a W: two coarse corrections, which
     * cost little there (each level has about a ninth of the nodes of the one
     * above) and save about an eighth of the CG iterations on the stiff cloth. */
    int corrections = l >= 1 ? 2 : 1;
    sym_mul(L, bs, L->x, L->t); /* t = A x from here on */
    for (int g = 0; g < corrections; g++) {
        /* the residual, restricted into the next level's right-hand side */
        for (size_t k = 0; k < nc; k++)
            C->b[k] = 0.0;
        for (size_t i = 0; i < L->nb; i++)
            for (int r = 0; r < bs; r++)
                C->b[L->agg[i] * bs + r] += L->b[i * bs + r] - L->t[i * bs + r];
        cycle(a, l + 1);
        for (size_t i = 0; i < L->nb; i++)
            for (int r = 0; r < bs; r++)
                L->x[i * bs + r] += C->x[L->agg[i] * bs + r];
        ap_mul_add(L, bs, C->x, L->t); /* A (x + P x_c) = A x + (A P) x_c */
    }
    jacobi(L, bs, false);
}

void psys__amg_apply(psys__amg *a, const double *r, double *z)
{
    level *L0 = &a->lev[0];
    size_t n = L0->nb * (size_t)a->bs;
    memcpy(L0->b, r, n * sizeof(double));
    cycle(a, 0);
    memcpy(z, L0->x, n * sizeof(double));
}

int psys__amg_levels(const psys__amg *a) { return a->nlev; }

void psys__bsr_sym_mul(size_t nb, int bs, const size_t *row, const size_t *col, const double *val, const double *x,
                       double *y)
{
    level L = {.nb = nb, .row = row, .col = col, .val = val};
    sym_mul(&L, bs, x, y);
}
