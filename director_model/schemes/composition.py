"""Symmetric compositions of RATTLE: orders 4 and 6."""

from __future__ import annotations

from director_model import _kernels
from director_model.schemes.base import Scheme

_CBRT2 = 2.0 ** (1.0 / 3.0)
_Y1 = 1.0 / (2.0 - _CBRT2)
_Y2 = -_CBRT2 / (2.0 - _CBRT2)

# Kahan & Li (1997), method s9odr6a (also Hairer, Lubich & Wanner, Geometric Numerical
# Integration, 2nd ed., section V.3.2): gamma_1..gamma_5, symmetric.
_KL = (
    0.39216144400731413928,
    0.33259913678935943860,
    -0.70624617255763935981,
    0.082213596293550800230,
    0.79854399093482996340,
)


class Rattle4(Scheme):
    """Yoshida's triple jump of RATTLE (Yoshida 1990; also Suzuki 1990, Creutz & Gocksch
    1989): RATTLE(g1 h) o RATTLE(g2 h) o RATTLE(g1 h) with g1 = 1/(2 - 2^(1/3)),
    g2 = -2^(1/3)/(2 - 2^(1/3)).

    A symmetric composition of a symmetric (time-reversible) second-order method is of order
    4. Being a composition of RATTLE steps it inherits everything that holds step by step:
    symplecticity, time reversibility, exact conservation of the angular momentum (or its
    vertical component under gravity), constraints to round-off, and for the torque-free
    body the energy to round-off. The middle step runs backwards in time (g2 < 0).

    Cost: 3 RATTLE steps. Step-size limit: the largest sub-step is |g2| h = 1.702 h, so a
    principal-axis spin needs 1.702 h |W| < 1 (numerics.md section 3).
    """

    name = "rattle4"
    order = 4
    description = "Yoshida triple-jump composition of RATTLE, symplectic, order 4"
    method = _kernels.RATTLE_FAMILY
    coefficients = (_Y1, _Y2, _Y1)
    limit_factor = 1.0 / abs(_Y2)
    limit_rule = "1.702 h |W| < 1 for a spin about a principal axis (largest sub-step)"


class Rattle6(Scheme):
    """Kahan & Li's 9-stage symmetric composition of RATTLE, order 6 (Kahan & Li, Math.
    Comp. 66 (1997) 1089-1099, method s9odr6a; coefficients as tabulated in Hairer, Lubich &
    Wanner, Geometric Numerical Integration, section V.3.2).

    Chosen over Yoshida's 7-stage order-6 solution A (largest coefficient 1.318) because its
    error constant is much smaller and its largest sub-step is only 0.799 h, so its
    step-size limit (0.799 h |W| < 1) is even looser than that of a single RATTLE step.
    Inherits the structure of RATTLE as :class:`Rattle4` does: symplectic, time-reversible,
    conserves the angular momentum (its vertical component under gravity) and the
    constraints to round-off, and the energy of the torque-free body to round-off; with
    gravity the energy error is bounded, O(h^6). Cost: 9 RATTLE steps.
    """

    name = "rattle6"
    order = 6
    description = "Kahan-Li 9-stage composition of RATTLE, symplectic, order 6"
    method = _kernels.RATTLE_FAMILY
    coefficients = _KL + _KL[-2::-1]
    limit_factor = 1.0 / max(abs(c) for c in _KL)
    limit_rule = "0.799 h |W| < 1 for a spin about a principal axis (largest sub-step)"
