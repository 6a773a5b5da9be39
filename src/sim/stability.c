/* Stability estimate of explicit solvers (guard rail, docs/trust.md).
 *
 * A spring of stiffness ks between particles a and b makes their relative
 * motion oscillate with ω² = ks (1/m_a + 1/m_b). A particle held by springs
 * on both sides (a chain, a lattice) oscillates faster: the highest mode of
 * a uniform chain has ω² = 4 ks/m = 2 ks (1/m + 1/m). The estimate takes
 * that chain bound for every spring,
 *
 *     ω_max² ≈ max over springs of 2 ks (1/m_a + 1/m_b),
 *
 * with 1/m = 0 for fixed and controlled particles (they do not move in
 * response). Explicit solvers are stable for an undamped oscillator only
 * when ω·dt stays below a small constant: 2 for symplectic Euler and
 * Verlet, about 2.8 for RK4 (explicit Euler and midpoint gain energy at any
 * dt). dt > 2/ω_max is therefore the point past which an explicit run of a
 * stiff scene is expected to blow up. Damping (kd), behaviour functions and
 * pair forces are not included: the estimate is for springs only. */
#include "sim/sim.h"

#include <math.h>

double psys_system_stiffest_omega(const psys_system *sys)
{
    if (!sys)
        return 0.0;
    size_t n = psys_system_count(sys), ns = psys_system_spring_count(sys);
    const double *mass = psys_system_masses(sys);
    double w2max = 0.0;
    for (size_t k = 0; k < ns; k++) {
        size_t a, b;
        double ks;
        if (psys_system_spring(sys, k, &a, &b, &ks, NULL, NULL) != PSYS_OK || a >= n || b >= n)
            continue;
        double inv = 0.0;
        if (!psys_system_is_fixed(sys, a) && !psys_system_is_controlled(sys, a))
            inv += 1.0 / mass[a];
        if (!psys_system_is_fixed(sys, b) && !psys_system_is_controlled(sys, b))
            inv += 1.0 / mass[b];
        double w2 = 2.0 * ks * inv;
        if (w2 > w2max)
            w2max = w2;
    }
    return sqrt(w2max);
}
