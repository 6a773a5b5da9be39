/* The Jacobian sink (psys_jacobian): a callback and a flag, so implicit
 * solvers and dense checks assemble blocks their own way. */
#ifndef PSYS_SOLVERS_JACOBIAN_H
#define PSYS_SOLVERS_JACOBIAN_H

#include "base/base.h"

/** Jacobian sink: callback form used by dense and sparse assembly. */
struct psys_jacobian {
    void (*add)(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv);
    void *ctx;
    bool definite; /* see psys_jacobian_wants_definite */
};

#endif
