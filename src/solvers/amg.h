/* Aggregation multigrid preconditioner for the symmetric positive-definite
 * block-sparse systems of implicit-euler (src/solvers/implicit.c).
 *
 * Matrices are stored as their upper triangle in block rows: row i holds
 * blocks (i, j) with j >= i, the diagonal block first, columns ascending
 * (bs×bs row-major blocks, bs = 2 or 3). */
#ifndef PSYS_AMG_H
#define PSYS_AMG_H

#include "base/base.h"

#include <stddef.h>

typedef struct psys__amg psys__amg;

/* Build the hierarchy for the pattern and values of the fine matrix (row,
 * col, val are borrowed: they must stay valid and keep this pattern until the
 * next setup). Aggregates come from the strong couplings of val. Allocates;
 * NULL when out of memory. */
psys__amg *psys__amg_create(size_t nb, int bs, const size_t *row, const size_t *col, const double *val);
void psys__amg_destroy(psys__amg *a);
/* Recompute the coarse matrices and smoother data from the fine values
 * (same pattern as at creation). No allocation. */
void psys__amg_update(psys__amg *a);
/* psys__amg_update, provided that the aggregates of the current fine values
 * (and of the coarse values they give, level by level) are the hierarchy's:
 * then the result is what psys__amg_create would build now, and true is
 * returned. Otherwise (or out of memory) false, and the caller creates the
 * hierarchy anew. The preconditioner is then a function of the current
 * matrix alone, not of when it was built: a run resumed from a checkpoint
 * finds the same one (docs/semantics.md#what-a-checkpoint-holds). Allocates
 * only scratch. */
bool psys__amg_refresh(psys__amg *a);
/* z = one symmetric multigrid cycle (V at the finest level, W below) applied
 * to r (an SPD approximation of A⁻¹ r):
 * damped block Jacobi before and after the coarse correction, a dense
 * Cholesky solve on the coarsest level (block Gauss–Seidel there when
 * coarsening stalled above its size). No allocation. */
void psys__amg_apply(psys__amg *a, const double *r, double *z);
/* Sort k pairs (i, j) (2k numbers) by i, then j, and drop repeats; returns
 * how many are left. */
size_t psys__pairs_sort_unique(size_t *pairs, size_t k);
/* Position of block (i, j) among block rows (row, col; columns ascending in
 * each row), or (size_t)-1 when absent. */
size_t psys__block_find(const size_t *row, const size_t *col, size_t i, size_t j);
/* y = A x for the upper-triangle block matrix (nb, bs, row, col, val). */
void psys__bsr_sym_mul(size_t nb, int bs, const size_t *row, const size_t *col, const double *val, const double *x,
                       double *y);
/* Number of levels (1: no coarsening, a symmetric Gauss–Seidel sweep pair). */
int psys__amg_levels(const psys__amg *a);

#endif
