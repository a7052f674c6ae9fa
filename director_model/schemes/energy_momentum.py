"""Energy-momentum conserving midpoint scheme in director form."""

from __future__ import annotations

from director_model import _kernels
from director_model.schemes.base import Scheme


class EnergyMomentum(Scheme):
    """Energy-momentum midpoint scheme for the constrained director system (Gonzalez 1996,
    J. Nonlinear Sci. 6, discrete gradients; Betsch & Steinmann 2001, CMAME 191, for the
    director formulation of rigid bodies).

        q_{n+1} - q_n = h/2 (v_n + v_{n+1})
        M (v_{n+1} - v_n) = h (f - G(q_{n+1/2})^T lambda)
        g(q_{n+1}) = 0

    The positions move with the mean velocity, the constraint gradient is taken at the
    midpoint, the constraints are enforced at the new point. Because the constraints are
    quadratic, G(q_{n+1/2}) (q_{n+1} - q_n) = g(q_{n+1}) - g(q_n) = 0 exactly, so the
    constraint forces do no work and the energy is conserved exactly (to the Newton tolerance
    and round-off). Gravity is linear in q, so f is its own discrete gradient. The angular
    momentum is conserved exactly as well (the midpoint rule preserves quadratic invariants
    of the symmetric constraint forces). Newton on the 15 unknowns (D_{n+1}, 6 multipliers)
    with the saddle-point matrix; the director mass matrix is never inverted, so flat bodies
    integrate.

    Known defects (numerics.md section 3): second order but not symplectic; the velocity
    constraint D^T D' skew is violated at the nodes at O(h^2) (reported in
    ``constraint_velocity``); for a symmetric top the spin L . d_3 drifts at O(h^2).

    Step-size limit: for a principal-axis spin the step rotates by theta with
    tan(theta/2) = h |W| / 2; steps rotating by 90 degrees or more (h |W| >= 2) are refused.
    """

    name = "energy_momentum"
    order = 2
    description = "energy-momentum midpoint (Gonzalez/Betsch-Steinmann), order 2"
    method = _kernels.ENERGY_MOMENTUM
    coefficients = (1.0,)
    limit_factor = 2.0
    limit_rule = "h |W| < 2 (a step may not rotate the body by 90 degrees or more)"
