/* implicit-euler: linearised backward Euler of Baraff & Witkin, "Large
 * steps in cloth simulation" (SIGGRAPH 1998), for y = [x | v]:
 *
 *   (M - h ∂f/∂v - h² ∂f/∂x) Δv = h (f0 + h ∂f/∂x v0),  v1 = v0 + Δv,  x1 = x0 + h v1
 *
 * solved by conjugate gradient on a block-sparse
 * matrix (block = dimension), preconditioned with one aggregation-multigrid
 * cycle (src/solvers/amg.c). Prescribed components (mass 0: fixed and
 * controlled particles) are filtered out of the solve, as in the paper.
 * The sparsity pattern is built on the first step and reused; it is rebuilt
 * (the only allocation) only when a force reports a new pair of particles.
 * Forces without Jacobians enter through f0 only (treated explicitly). */
#include "solvers/solver.h"
#include "solvers/amg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { Y0, YDOT, Y1, M_, B_, DV, R_, Z_, P_, Q_, KV, NBUF };

/* The matrix is symmetric, so only its upper triangle (diagonal blocks
 * included) is stored: block (i, j) with j >= i; the diagonal block is the
 * first of each row. Half the bytes per product, which is memory bound. */
typedef struct bsr {
    size_t nb;         /* block rows */
    int bs;            /* block size */
    size_t *row;       /* nb + 1 */
    size_t *col;       /* nnz blocks, sorted within each row */
    double *val;       /* nnz × bs² */
    size_t nnz;
    /* pairs seen during an assembly that the pattern lacked */
    size_t *miss;      /* pairs (i, j) flattened */
    size_t nmiss, miss_cap;
    psys__amg *amg;    /* the preconditioner; NULL until built for the current pattern */
    /* The forces report their blocks in the same order every step: the block
     * position of each report is cached (slot[c] for report c, with its pair
     * in slot_pair[2c], slot_pair[2c+1]) so assembly skips the binary
     * search; a report that does not match its cached pair falls back to
     * searching. */
    size_t *slot, *slot_pair;
    size_t nslot;      /* capacity (reports of the assembly that built the pattern) */
    size_t ncall;      /* reports in the current assembly */
    bool slot_fill;    /* this assembly records slots */
    /* assembly context */
    double h;
    const double *v0;
    double *kv;
} bsr;

static void bsr_free(bsr *m)
{
    if (!m)
        return;
    free(m->row);
    free(m->col);
    free(m->val);
    free(m->miss);
    psys__amg_destroy(m->amg);
    free(m->slot);
    free(m->slot_pair);
    free(m);
}

static long bsr_find(const bsr *m, size_t i, size_t j)
{
    size_t e = psys__block_find(m->row, m->col, i, j);
    return e == (size_t)-1 ? -1 : (long)e;
}

static void note_miss(bsr *m, size_t i, size_t j)
{
    if (m->nmiss == m->miss_cap) {
        size_t cap = m->miss_cap ? 2 * m->miss_cap : 1024;
        size_t *p = psys__realloc(m->miss, cap, 2 * sizeof(size_t));
        if (!p)
            return; /* the rebuild below then fails cleanly as out of memory */
        m->miss = p;
        m->miss_cap = cap;
    }
    m->miss[2 * m->nmiss] = i;
    m->miss[2 * m->nmiss + 1] = j;
    m->nmiss++;
}

/* Sink: A += -h ∂f/∂v - h² ∂f/∂x, symmetrised (½B at (i,j), ½Bᵀ at (j,i)),
 * and kv_i += (∂f/∂x)_ij v0_j for the right-hand side. B is the block size,
 * a constant in each instantiation so the block loops unroll. */
static inline void assemble_add_b(bsr *m, size_t i, size_t j, const double *dfdx, const double *dfdv, const int B)
{
    if (dfdx)
        for (int r = 0; r < B; r++)
            for (int c = 0; c < B; c++)
                m->kv[i * B + r] += dfdx[r * B + c] * m->v0[j * B + c];
    size_t call = m->ncall++;
    size_t lo = i < j ? i : j, hi = i < j ? j : i;
    long e;
    if (call < m->nslot && !m->slot_fill && m->slot_pair[2 * call] == i && m->slot_pair[2 * call + 1] == j) {
        e = (long)m->slot[call];
    } else {
        e = bsr_find(m, lo, hi);
        if (call < m->nslot && m->slot_fill && e >= 0) {
            m->slot[call] = (size_t)e;
            m->slot_pair[2 * call] = i;
            m->slot_pair[2 * call + 1] = j;
        }
    }
    if (e < 0) {
        note_miss(m, lo, hi);
        return;
    }
    /* ½B at (i, j) and ½Bᵀ at (j, i): the stored upper block (lo, hi) gets
     * ½B (i < j), ½Bᵀ (i > j) or ½(B + Bᵀ) on the diagonal. */
    double cx = -0.5 * m->h * m->h, cv = -0.5 * m->h, x[9];
    for (int k = 0; k < B * B; k++)
        x[k] = (dfdx ? cx * dfdx[k] : 0.0) + (dfdv ? cv * dfdv[k] : 0.0);
    double *a = m->val + (size_t)e * (size_t)(B * B);
    if (i <= j)
        for (int k = 0; k < B * B; k++)
            a[k] += x[k];
    if (i >= j)
        for (int r = 0; r < B; r++)
            for (int c = 0; c < B; c++)
                a[c * B + r] += x[r * B + c];
}

static void assemble_add(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv)
{
    bsr *m = J->ctx;
    if (m->bs == 3) /* 2 or 3: checked by implicit_init */
        assemble_add_b(m, i, j, dfdx, dfdv, 3);
    else
        assemble_add_b(m, i, j, dfdx, dfdv, 2);
}

/* New pattern = old pattern ∪ missed pairs ∪ diagonal. */
static psys_status bsr_rebuild(bsr *m)
{
    size_t total = m->nnz + m->nmiss + m->nb;
    size_t *pairs = psys__calloc(total, 2 * sizeof(size_t));
    if (!pairs)
        return PSYS_ERR_NOMEM;
    size_t k = 0;
    for (size_t i = 0; i < m->nb; i++) {
        pairs[2 * k] = pairs[2 * k + 1] = i;
        k++;
        for (size_t q = m->row[i]; q < m->row[i + 1]; q++) {
            pairs[2 * k] = i;
            pairs[2 * k + 1] = m->col[q];
            k++;
        }
    }
    if (m->nmiss) /* m->miss may be NULL when no pair was missing */
        memcpy(pairs + 2 * k, m->miss, m->nmiss * 2 * sizeof(size_t));
    k += m->nmiss;
    size_t u = psys__pairs_sort_unique(pairs, k);
    size_t *col = psys__calloc(u, sizeof(size_t));
    double *val = psys__calloc(u * (size_t)m->bs * m->bs, sizeof(double));
    size_t *slot = psys__calloc(m->ncall, sizeof(size_t)), *slot_pair = psys__calloc(m->ncall, 2 * sizeof(size_t));
    if (!col || !val || (m->ncall && (!slot || !slot_pair))) {
        free(pairs);
        free(col);
        free(val);
        free(slot);
        free(slot_pair);
        return PSYS_ERR_NOMEM;
    }
    free(m->slot);
    free(m->slot_pair);
    m->slot = slot;
    m->slot_pair = slot_pair;
    m->nslot = m->ncall;
    memset(m->row, 0, (m->nb + 1) * sizeof(size_t));
    for (size_t q = 0; q < u; q++) {
        m->row[pairs[2 * q] + 1]++;
        col[q] = pairs[2 * q + 1];
    }
    for (size_t i = 0; i < m->nb; i++)
        m->row[i + 1] += m->row[i];
    free(pairs);
    free(m->col);
    free(m->val);
    psys__amg_destroy(m->amg);
    m->amg = NULL;
    m->col = col;
    m->val = val;
    m->nnz = u;
    m->nmiss = 0;
    return PSYS_OK;
}

static psys_status implicit_init(psys_solver *s)
{
    const psys_ode *o = &s->ode;
    if (!o->mass || !o->jacobian || o->block < 1 || o->npos % (size_t)o->block != 0)
        return psys__fail(&s->err, PSYS_ERR_INVALID,
                          "implicit-euler needs an ODE that offers masses and force Jacobians");
    if (o->block != 2 && o->block != 3)
        return psys__fail(&s->err, PSYS_ERR_INVALID, "implicit-euler needs Jacobian blocks of size 2 or 3 (got %d)",
                          o->block);
    bsr *m = calloc(1, sizeof *m);
    if (!m || !(m->row = psys__calloc(o->npos / (size_t)o->block + 1, sizeof(size_t)))) {
        bsr_free(m);
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory creating implicit-euler");
    }
    m->bs = o->block;
    m->nb = o->npos / (size_t)o->block;
    s->impl = m;
    return PSYS_OK;
}

static void implicit_fini(psys_solver *s) { bsr_free(s->impl); }

/* Assemble A and K v0 at (t, y0); rebuild the pattern when a force reports a
 * pair it lacks (first step, or changed topology) and assemble again. */
static psys_status assemble(psys_solver *s, bsr *m, double t, const double *y0, double h, double *kv)
{
    size_t np = s->ode.npos;
    psys_jacobian J = {assemble_add, m, true};
    m->h = h;
    m->v0 = y0 + np;
    m->kv = kv;
    for (int attempt = 0; attempt < 2; attempt++) {
        if (m->nnz) /* m->val is NULL before the first pattern: memset(NULL, 0, 0) is undefined */
            memset(m->val, 0, m->nnz * (size_t)m->bs * m->bs * sizeof(double));
        memset(kv, 0, np * sizeof(double));
        m->nmiss = 0;
        m->ncall = 0;
        psys_status st = s->ode.jacobian(s->ode.ctx, t, y0, &J);
        m->slot_fill = false;
        if (st != PSYS_OK)
            return psys__fail(&s->err, st, "the force Jacobians could not be evaluated");
        if (m->nmiss == 0 && m->nnz > 0)
            return PSYS_OK;
        m->slot_fill = true; /* the assembly after a rebuild records the slots */
        if (bsr_rebuild(m) != PSYS_OK)
            return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory building the implicit-euler matrix");
    }
    return m->nmiss == 0 ? PSYS_OK
                         : psys__fail(&s->err, PSYS_ERR_NOMEM, "the implicit-euler matrix pattern did not settle");
}

/* Make the stored matrix the filtered system S (M + A) S + (I - S), S
 * zeroing prescribed components (mass 0): their rows and columns vanish and
 * their diagonal entries become 1, so the product and the multigrid see one
 * symmetric positive-definite matrix and keep those components at 0. */
static void bake(bsr *m, const double *mass)
{
    int b = m->bs;
    for (size_t i = 0; i < m->nb; i++)
        for (size_t e = m->row[i]; e < m->row[i + 1]; e++) {
            size_t j = m->col[e];
            double *blk = m->val + e * (size_t)b * b;
            for (int r = 0; r < b; r++)
                for (int c = 0; c < b; c++) {
                    bool pr = !(mass[i * b + r] > 0), pc = !(mass[j * b + c] > 0);
                    if (pr || pc)
                        blk[r * b + c] = i == j && r == c ? 1.0 : 0.0;
                    else if (i == j && r == c)
                        blk[r * b + c] += mass[i * b + r];
                }
        }
}

static void apply_matrix(const bsr *m, const double *p, double *q)
{
    psys__bsr_sym_mul(m->nb, m->bs, m->row, m->col, m->val, p, q);
}

/* Four interleaved partial sums, combined in a fixed order: a shorter
 * dependency chain than one running sum, and the same bits on every run. */
static double dot(const double *restrict a, const double *restrict b, size_t n)
{
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    size_t i = 0;
    for (; i + 4 <= n; i += 4) {
        s0 += a[i] * b[i];
        s1 += a[i + 1] * b[i + 1];
        s2 += a[i + 2] * b[i + 2];
        s3 += a[i + 3] * b[i + 3];
    }
    for (; i < n; i++)
        s0 += a[i] * b[i];
    return (s0 + s1) + (s2 + s3);
}

static psys_status implicit_step(psys_solver *s, double h, double *h_taken)
{
    bsr *m = s->impl;
    size_t np = s->ode.npos;
    int b = m->bs;
    double *y0 = s->buf[Y0], *ydot = s->buf[YDOT], *y1 = s->buf[Y1];
    double *mass = s->buf[M_], *rhs = s->buf[B_], *dv = s->buf[DV], *r = s->buf[R_];
    double *z = s->buf[Z_], *p = s->buf[P_], *q = s->buf[Q_], *kv = s->buf[KV];
    double t = s->ode.get_time(s->ode.ctx);
    s->ode.get_state(s->ode.ctx, y0);
    psys_status st = psys__solver_eval(s, t, y0, ydot); /* projects y0 at t */
    if (st != PSYS_OK)
        return st;
    s->ode.mass(s->ode.ctx, mass);
    if ((st = assemble(s, m, t, y0, h, kv)) != PSYS_OK)
        return st;
    /* rhs = S h (f0 + h K v0), with f0 = m a0. */
    for (size_t k = 0; k < np; k++) {
        rhs[k] = mass[k] > 0 ? h * (mass[k] * ydot[np + k] + h * kv[k]) : 0.0;
        dv[k] = 0;
    }
    bake(m, mass);
    /* The preconditioner's aggregates are those of this step's matrix (kept
     * while they stay the same, built anew when they change): a hierarchy
     * kept from an earlier step would make the result depend on when it was
     * built, and a run resumed from a checkpoint differ from the one-go run. */
    if (m->amg && !psys__amg_refresh(m->amg)) {
        psys__amg_destroy(m->amg);
        m->amg = NULL;
    }
    if (!m->amg && !(m->amg = psys__amg_create(m->nb, b, m->row, m->col, m->val)))
        return psys__fail(&s->err, PSYS_ERR_NOMEM, "out of memory building the implicit-euler preconditioner");
    /* Preconditioned conjugate gradient from Δv = 0 on the filtered system. */
    double bnorm = sqrt(dot(rhs, rhs, np));
    memcpy(r, rhs, np * sizeof(double));
    psys__amg_apply(m->amg, r, z);
    memcpy(p, z, np * sizeof(double));
    double rz = dot(r, z, np), res = bnorm;
    int it = 0;
    while (bnorm > 0 && res > s->cg_tol * bnorm && it < s->cg_maxit) {
        apply_matrix(m, p, q);
        double pq = dot(p, q, np);
        if (!(pq > 0))
            break; /* not positive definite along p: keep the best iterate */
        double alpha = rz / pq;
        for (size_t k = 0; k < np; k++) {
            dv[k] += alpha * p[k];
            r[k] -= alpha * q[k];
        }
        res = sqrt(dot(r, r, np));
        it++;
        psys__amg_apply(m->amg, r, z);
        double rz_new = dot(r, z, np);
        double beta = rz_new / rz;
        rz = rz_new;
        for (size_t k = 0; k < np; k++)
            p[k] = z[k] + beta * p[k];
    }
    s->cg_iterations += (size_t)it;
    if (bnorm > 0 && res > s->cg_tol * bnorm) {
        s->cg_unconverged++;
        if (res / bnorm > s->cg_worst)
            s->cg_worst = res / bnorm;
    }
    for (size_t k = 0; k < np; k++) {
        double v1 = y0[np + k] + dv[k];
        y1[np + k] = v1;
        y1[k] = y0[k] + h * v1;
    }
    *h_taken = h;
    return psys__solver_commit(s, y1, t + h);
}

const psys__solver_class psys__implicit_euler = {
    .name = "implicit-euler",
    .order = 1,
    .adaptive = false,
    .second_order_only = true,
    .nbuf = NBUF,
    .tab = NULL,
    .step = implicit_step,
    .init = implicit_init,
    .fini = implicit_fini,
};
