"""RATTLE on the director system, in the reduced discrete Moser-Veselov form."""

from __future__ import annotations

from director_model import _kernels
from director_model.schemes.base import Scheme


class Rattle(Scheme):
    """RATTLE (Andersen 1983: SHAKE position step + velocity projection) on the 12-coordinate
    director system with its six orthonormality constraints, computed in reduced form.

    Reduced form (McLachlan & Zanna 2005 show RATTLE on the directors *is* the discrete
    Moser-Veselov algorithm, Moser & Veselov 1991): with Q = D_n^T D_{n+1},

        Q Jbar - Jbar Q^T = h hat(pi),   pi = Pi_n + h/2 tau_n,
        D_{n+1} = D_n Q,                 Pi_{n+1} = Q^T pi + h/2 tau_{n+1},

    Pi = Ibar W the body angular momentum, tau the body torque (gravity about the pivot),
    Jbar the convected-moment matrix (diag(J), or diag(J) + m c c^T about a pivot). Q is a
    unit quaternion (s, v), s > 0, found by a 3-unknown Newton solve to round-off. The free
    centre of mass moves exactly under uniform gravity. The readable 12-coordinate version
    with the six multipliers is :mod:`director_model.reference`; a test checks that both agree
    to round-off, which is the independent check of the equivalence.

    Properties: second order, symplectic, time-reversible. Conserves the angular momentum
    about the origin exactly (torque-free) or its vertical component (heavy top), the
    position and velocity constraints to round-off (the compiled loop accumulates the
    product of the Q as a compensated quaternion and forms D_n = D_0 R(p_n) from it at the
    saved states, so max|D^T D - I| stays at a few ulps whatever the step count). For
    the torque-free body the energy is conserved to round-off too (the DMV map is
    integrable; numerics.md section 3); with gravity the energy error is O(h^2), bounded and
    without drift (backward error analysis of symplectic maps).

    Step-size limit: for a spin about a principal axis the equation reads
    sin(theta) = h |W| with theta the rotation angle of Q, so no solution exists for
    h |W| >= 1. A step beyond it, a step whose Newton solve does not converge, or one that
    would rotate by 90 degrees or more (the second branch) raises StepSizeError.
    """

    name = "rattle"
    order = 2
    description = "RATTLE / discrete Moser-Veselov, symplectic, order 2"
    method = _kernels.RATTLE_FAMILY
    coefficients = (1.0,)
    limit_factor = 1.0
    limit_rule = "h |W| < 1 for a spin about a principal axis"
