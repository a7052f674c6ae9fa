"""Invariants in director form (seed note eq. 11), computed from saved director states.

Arguments are arrays with any leading shape ``...``: ``x``, ``v`` (..., 3) centre of mass and
its velocity (world, m, m/s), ``D``, ``Dp`` (..., 3, 3) directors and director velocities.
``mass`` (kg) is a scalar or broadcasts against ``...``; ``Jbar`` (kg m^2) is the (3, 3)
director mass matrix of the rotation (diag(J) for a free body, diag(J) + m c c^T for a pivoted
one, see :class:`director_model.body.Body`) or an array (..., 3, 3) broadcasting against the
states. ``pivoted`` says whether the centre of mass is eliminated (then its motion is inside
Jbar and ``v`` must not be counted again).

    T = 1/2 m |v_G|^2 + sum_ij 1/2 Jbar_ij d_i' . d_j'     (free: Jbar = diag(J))
    V = -m g . x_G
    L = x_G x m v_G + sum_ij Jbar_ij d_i x d_j'          (about the world origin; for a
                                                          pivoted body the first term is
                                                          inside Jbar: L about the pivot)

On exact states (D orthonormal, D' = D hat(W)) these equal the textbook forms
T_rot = 1/2 W . Ibar W and L = x_G x m v_G + R Ibar W (tests check this).

Every product and sum is written element-wise in a fixed order (:func:`matmul3`, explicit
sums of 3 or 9 terms), not with ``@`` or reductions whose rounding depends on the shape of
the stack: a saved state gives the same bits whether it is evaluated alone or in a long
array (the chunks of :class:`director_model.Stepper` rely on it).
"""

from __future__ import annotations

import numpy as np

from director_model.state import matmul3


def _sum3(X) -> np.ndarray:
    """X[..., 0] + X[..., 1] + X[..., 2], left to right."""
    return (X[..., 0] + X[..., 1]) + X[..., 2]


def _sum9(X) -> np.ndarray:
    """Sum over the last two axes (3, 3), row by row, left to right."""
    return (_sum3(X[..., 0, :]) + _sum3(X[..., 1, :])) + _sum3(X[..., 2, :])


def _rot_kinetic(Jbar, Dp):
    return 0.5 * _sum9(matmul3(Dp, Jbar) * Dp)


def kinetic_energy(mass, Jbar, pivoted: bool, v, Dp) -> np.ndarray:
    """T in J, shape (...)."""
    T = _rot_kinetic(np.asarray(Jbar, float), np.asarray(Dp, float))
    if not pivoted:
        v = np.asarray(v, float)
        T = T + 0.5 * np.asarray(mass, float) * _sum3(v * v)
    return T


def potential_energy(mass, gravity, x) -> np.ndarray:
    """V = -m g . x_G in J, shape (...); measured from the world origin (the pivot)."""
    return -np.asarray(mass, float) * _sum3(np.asarray(x, float) * np.asarray(gravity, float))


def energy(mass, Jbar, pivoted: bool, gravity, x, v, Dp) -> np.ndarray:
    """E = T + V in J, shape (...)."""
    return kinetic_energy(mass, Jbar, pivoted, v, Dp) + potential_energy(mass, gravity, x)


def rotational_angular_momentum(Jbar, D, Dp) -> np.ndarray:
    """sum_ij Jbar_ij d_i x d_j', shape (..., 3): the spin about the centre of mass for a free
    body (Jbar = diag(J)), the whole angular momentum about the pivot for a pivoted one."""
    A = matmul3(D, Jbar)
    return _sum3(np.cross(A, np.asarray(Dp, float), axis=-2))


def angular_momentum(mass, Jbar, pivoted: bool, x, v, D, Dp) -> np.ndarray:
    """L about the world origin (the pivot, for a pivoted body), kg m^2/s, shape (..., 3)."""
    L = rotational_angular_momentum(Jbar, D, Dp)
    if not pivoted:
        m = np.asarray(mass, float)[..., None]
        L = L + m * np.cross(np.asarray(x, float), np.asarray(v, float))
    return L


def linear_momentum(mass, v) -> np.ndarray:
    """m v_G, kg m/s, shape (..., 3)."""
    return np.asarray(mass, float)[..., None] * np.asarray(v, float)


def spin(Jbar, D, Dp, axis: int) -> np.ndarray:
    """Component of the rotational angular momentum along director ``axis`` (0, 1, 2),
    shape (...). For a symmetric body with symmetry axis ``axis`` this is I_k W_k, conserved
    by the torque-free body and by the symmetric heavy top (the Lagrange top, L . d_3)."""
    Lr = rotational_angular_momentum(Jbar, D, Dp)
    return _sum3(Lr * np.asarray(D, float)[..., :, axis])


def constraint_position(D) -> np.ndarray:
    """max|D^T D - I| over the 9 entries, shape (...)."""
    D = np.asarray(D, float)
    return np.max(np.abs(matmul3(np.swapaxes(D, -1, -2), D) - np.eye(3)), axis=(-2, -1))


def constraint_velocity(D, Dp) -> np.ndarray:
    """max|D^T D' + D'^T D| over the 9 entries, shape (...): the hidden constraint (D^T D'
    skew)."""
    A = matmul3(np.swapaxes(np.asarray(D, float), -1, -2), Dp)
    return np.max(np.abs(A + np.swapaxes(A, -1, -2)), axis=(-2, -1))
