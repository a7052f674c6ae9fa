"""The rigid body of the director model: mass, principal moments, optional pivot.

Conventions (SI): ``inertia`` are the principal moments of inertia I = (I_1, I_2, I_3) about
the centre of mass, kg m^2, in body axes (the principal axes). ``pivot`` c, if given, is the
fixed point in body axes relative to the centre of mass, m; the fixed point is the world
origin, so x_G = -R c.

The director model uses the *convected* second moments J_i = int rho xi_i^2 dV instead of
the moments of inertia (seed note eq. 9-11)::

    J_i = (I_j + I_k - I_i) / 2,        I_i = J_j + J_k         (i, j, k distinct)

J_i >= 0 for all i is the triangle inequality I_i <= I_j + I_k, the condition for a real
mass distribution. One J_i = 0 is a flat body (a lamina): the director mass matrix is then
singular, which every scheme here tolerates (none divides by J_i). Two J_i = 0 is a thin rod:
the spin about the rod has no inertia and the dynamics is singular; it is rejected.

For a pivoted body the centre of mass is eliminated (x_G = -D c is linear in the directors),
which replaces J by the 3x3 matrix Jbar = diag(J) + m c c^T (numerics.md section 2) and the
inertia by the pivot inertia Ibar = tr(Jbar) 1 - Jbar = diag(I) + m (|c|^2 1 - c c^T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from director_model.errors import InvalidBodyError

#: Relative size below which a convected moment is taken as exactly zero (a flat direction):
#: J_i = (I_j + I_k - I_i)/2 is a difference of O(I) numbers, so its rounding error is a few
#: ulps of max(I). 16 eps covers it; a J_i of -1e-17 from I = (0.3, 0.1, 0.2) is a lamina,
#: not a triangle violation.
FLAT_TOL = 16 * np.finfo(float).eps


def _fmt(a) -> str:
    return np.array2string(np.asarray(a, dtype=float), separator=", ", precision=17)


def _as_float_vector(name: str, value, err=InvalidBodyError) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise err(f"{name} = {value!r}: expected 3 real numbers ({exc})") from None
    if arr.shape != (3,):
        raise err(f"{name} = {value!r}: expected 3 real numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise err(f"{name} = {_fmt(arr)}: every entry must be finite")
    return arr


def validate_body(mass, inertia, pivot=None) -> np.ndarray:
    """Check a body and return its convected moments J = (J_1, J_2, J_3), kg m^2.

    Parameters
    ----------
    mass : float
        Total mass m > 0, kg.
    inertia : array_like, shape (3,)
        Principal moments (I_1, I_2, I_3) about the centre of mass, kg m^2, each > 0.
    pivot : array_like, shape (3,), optional
        Fixed point in body axes relative to the centre of mass, m (finite).

    Returns
    -------
    J : ndarray, shape (3,)
        J_i = (I_j + I_k - I_i)/2 >= 0; an entry within ``FLAT_TOL * max(I)`` of zero is
        returned as exactly 0.0 (a flat direction, rounding of the difference).

    Raises
    ------
    InvalidBodyError
        With a message ``"<argument> = <value>: <rule>"`` for: non-finite or non-positive
        mass; non-finite or negative moments; triangle inequality violated (J_i < 0); a thin
        rod (two J_i = 0, e.g. I = (0, 1, 1)); a zero moment otherwise; a non-finite pivot.
        The message has no file or field prefix: the scenario loader adds its own.
    """
    try:
        m = float(mass)
    except (TypeError, ValueError):
        raise InvalidBodyError(f"mass = {mass!r}: must be a real number") from None
    if not (math.isfinite(m) and m > 0.0):
        raise InvalidBodyError(f"mass = {m!r}: must be positive and finite")
    I = _as_float_vector("inertia", inertia)
    if np.any(I < 0.0):
        raise InvalidBodyError(
            f"inertia = {_fmt(I)}: principal moments of inertia must be positive"
        )
    J = 0.5 * (I.sum() - 2.0 * I)
    tol = FLAT_TOL * float(I.max())
    if np.any(J < -tol):
        i = int(np.argmin(J))
        j, k = [a for a in range(3) if a != i]
        raise InvalidBodyError(
            f"inertia = {_fmt(I)}: violates the triangle inequality I_{i + 1} <= "
            f"I_{j + 1} + I_{k + 1} ({I[i]!r} > {I[j] + I[k]!r}), so the convected moment "
            f"J_{i + 1} = (I_{j + 1} + I_{k + 1} - I_{i + 1})/2 = {J[i]!r} is negative: "
            "no mass distribution has these moments (not a physical rigid body)"
        )
    J = np.where(np.abs(J) <= tol, 0.0, J)
    if np.count_nonzero(J == 0.0) >= 2:
        raise InvalidBodyError(
            f"inertia = {_fmt(I)}: a thin rod (convected moments J = {_fmt(J)} have two "
            "zeros): the spin about the rod axis has no inertia and the dynamics is "
            "singular; give the rod a finite thickness"
        )
    if np.any(I <= 0.0):  # unreachable after the checks above; kept as a guard
        raise InvalidBodyError(f"inertia = {_fmt(I)}: moments must be positive")
    if pivot is not None:
        _as_float_vector("pivot", pivot)
    return J


@dataclass(frozen=True, eq=False)
class Body:
    """A validated body (build it with :meth:`Body.make`).

    Attributes: ``mass`` (kg), ``inertia`` (3,) principal moments about the COM, ``pivot``
    (3,) or None, ``J`` (3,) convected moments about the COM, ``Jbar`` (3, 3) the director
    mass matrix of the rotation (diag(J) for a free body, diag(J) + m c c^T about a pivot),
    ``Ibar`` (3, 3) the inertia tensor the rotation sees (diag(I) or the pivot inertia).
    """

    mass: float
    inertia: np.ndarray
    pivot: np.ndarray | None
    J: np.ndarray
    Jbar: np.ndarray
    Ibar: np.ndarray

    @classmethod
    def make(cls, mass, inertia, pivot=None) -> Body:
        J = validate_body(mass, inertia, pivot)
        m = float(mass)
        I = np.asarray(inertia, dtype=float).copy()
        c = None if pivot is None else np.asarray(pivot, dtype=float).copy()
        Jbar = np.diag(J)
        if c is not None:
            Jbar = Jbar + m * np.outer(c, c)
        Ibar = np.trace(Jbar) * np.eye(3) - Jbar
        return cls(mass=m, inertia=I, pivot=c, J=J, Jbar=Jbar, Ibar=Ibar)

    @property
    def pivoted(self) -> bool:
        return self.pivot is not None

    @property
    def symmetric_axis(self) -> int | None:
        """Index of the axis of symmetry (:func:`symmetric_axis` of the principal moments)."""
        return symmetric_axis(self.inertia)


def symmetric_axis(inertia) -> int | None:
    """Index of the body axis of symmetry of principal moments ``inertia`` (3,): the moment
    that differs from two equal ones; None for an asymmetric or spherical body. Equality is
    exact: scenario files state symmetric bodies with equal numbers."""
    I = inertia
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        if I[i] == I[j] and I[k] != I[i]:
            return k
    return None
