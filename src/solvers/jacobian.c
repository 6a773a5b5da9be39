/* The Jacobian sink that force classes write their blocks into: the
 * solver (or a dense check) decides where each block goes. */
#include "solvers/jacobian.h"

void psys_jacobian_add(psys_jacobian *J, size_t i, size_t j, const double *dfdx, const double *dfdv)
{
    J->add(J, i, j, dfdx, dfdv);
}

bool psys_jacobian_wants_definite(const psys_jacobian *J) { return J->definite; }

