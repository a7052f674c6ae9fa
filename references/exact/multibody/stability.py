"""Linear stability of a periodic exact motion and the horizon over which it is a reference.

An exact motion is exact for its own initial state; an engine starts from that state rounded
to doubles (the file's 17 digits) and from the closed form's own residual, a distance delta0
of a few eps. On a linearly unstable motion that distance grows like delta0 exp(lambda t),
and every engine that integrates accurately follows the physics of the rounded state away
from the closed form at exactly that rate: the closed form is then the reference only while
delta0 exp(lambda t) stays below the metric's tolerance / 10 (the margin at which a reference
judges a run, reports.metrics.verdicts).

:func:`floquet` computes the Floquet multipliers mu of a motion that is periodic with period T
in the reduced coordinates of :mod:`.tree` (a relative equilibrium rotating at Omega is
periodic with T = 2 pi/|Omega| in the inertial frame): the eigenvalues of the monodromy
matrix, the derivative of the flow over one period with respect to the initial state, by
central differences of DOP853 runs (each column a run from the state moved by +-h times the
component's scale; truncation O(h^2), the integrator's error rtol/h). The growth rate is
lambda = ln max|mu| / T (1/s); a motion whose multipliers all have |mu| <= 1 + NEUTRAL_TOL
is linearly stable or neutral (lambda = 0: a relative equilibrium always has multipliers 1,
its symmetry and its energy), and errors then grow at most linearly.

:func:`trusted_horizon` is the time at which delta0 exp(lambda t) reaches the tolerance.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from references.exact.multibody.dynamics import rhs_function
from references.exact.multibody.integrate import _run, _scales

#: |mu| - 1 below this is neutral: the differences' own error on the monodromy matrix
#: (rtol / h = 1e-13 / 1e-6 relative, and the square root of that at a double multiplier 1)
NEUTRAL_TOL = 1e-3
#: the central differences' step, relative to each component's scale
STEP = 1e-6


@dataclass
class Floquet:
    """``multipliers`` (complex, sorted by decreasing modulus), ``period`` (s),
    ``growth_rate`` (1/s, 0 when neutral or stable), ``unstable`` (bool), ``wall_time`` (s)."""

    multipliers: np.ndarray
    period: float
    growth_rate: float
    unstable: bool
    wall_time: float


def floquet(tree, q0, u0, period: float, rtol: float = 1e-13, max_wall: float = 120.0) -> Floquet:
    """The Floquet multipliers of the reduced motion of ``tree`` from (q0, u0), periodic with
    ``period`` (module docstring)."""
    if not period > 0 or not math.isfinite(period):
        raise ValueError(f"floquet: the period {period!r} must be a finite number > 0")
    start = time.perf_counter()
    q0, u0 = tree.initial_from_joint(q0, u0)
    y0 = np.concatenate([q0, u0])
    scale, _ = _scales(tree, q0, u0)
    f = rhs_function(tree)
    t = np.array([0.0, float(period)])
    deadline = start + max_wall
    n = len(y0)
    M = np.empty((n, n))
    for i in range(n):
        h = STEP * scale[i]
        ends = []
        for sgn in (1.0, -1.0):
            y = y0.copy()
            y[i] += sgn * h
            Y, _, _ = _run(f, y, t, rtol, scale, np.inf, 10**6, deadline, f"floquet column {i}")
            ends.append(Y[-1])
        # the monodromy matrix in the scaled coordinates y / scale
        M[:, i] = (ends[0] - ends[1]) / (2.0 * h) * scale[i] / scale
    mu = np.linalg.eigvals(M)
    mu = mu[np.argsort(-np.abs(mu))]
    top = float(np.abs(mu[0]))
    unstable = top > 1.0 + NEUTRAL_TOL
    growth = math.log(top) / period if unstable else 0.0
    return Floquet(mu, float(period), growth, unstable, time.perf_counter() - start)


def trusted_horizon(growth_rate: float, delta0: float, tol: float, t_end: float) -> float:
    """The time (s, at most ``t_end``) at which delta0 exp(growth_rate t) reaches ``tol``."""
    if not growth_rate > 0 or delta0 >= tol:
        return float(t_end) if growth_rate <= 0 else 0.0
    return min(float(t_end), math.log(tol / delta0) / growth_rate)


__all__ = ["NEUTRAL_TOL", "Floquet", "floquet", "trusted_horizon"]
