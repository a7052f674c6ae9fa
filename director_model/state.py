"""Director-form state and the conversions to and from other attitude conventions.

All convention conversions of director_model live here (style habit 3).

Director form: x_G (3,) centre of mass, v_G (3,) its velocity, D = [d1 d2 d3] (3, 3) whose
columns are the directors (the body-to-world rotation matrix R: a body vector b has world
coordinates R b), and D' (3, 3) the director velocities. With W the angular velocity in body
axes and w = R W in world axes,

    D' = D hat(W) = hat(w) D,    d_i' = w x d_i,    W = vee(skew(D^T D')).

``hat(a)`` is the 3x3 matrix with hat(a) b = a x b; ``vee`` is its inverse on skew matrices.

Quaternions are unit quaternions in **scalar-first order (w, x, y, z)**, named ``quat_wxyz``
everywhere (scipy's default is scalar-last; MuJoCo uses scalar-first). The quaternion q and
the rotation matrix R act as R b = q b q^*. Both signs describe the same rotation; the
helpers return the one with w >= 0.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from director_model.errors import InvalidStateError

#: Largest accepted max|R^T R - I| of an initial rotation. An initial rotation is never
#: re-orthonormalised: a matrix farther from SO(3) than this is an input error.
ORTHONORMAL_TOL = 1e-12


def hat(a) -> np.ndarray:
    """Skew matrix of a, shape (..., 3) -> (..., 3, 3), with hat(a) b = a x b."""
    a = np.asarray(a, dtype=float)
    z = np.zeros(a.shape[:-1])
    return np.stack(
        [
            np.stack([z, -a[..., 2], a[..., 1]], axis=-1),
            np.stack([a[..., 2], z, -a[..., 0]], axis=-1),
            np.stack([-a[..., 1], a[..., 0], z], axis=-1),
        ],
        axis=-2,
    )


def vee(A) -> np.ndarray:
    """Vector of the skew part of A, shape (..., 3, 3) -> (..., 3): vee(hat(a)) = a.
    For a non-skew A this is vee((A - A^T)/2)."""
    A = np.asarray(A, dtype=float)
    return 0.5 * np.stack(
        [
            A[..., 2, 1] - A[..., 1, 2],
            A[..., 0, 2] - A[..., 2, 0],
            A[..., 1, 0] - A[..., 0, 1],
        ],
        axis=-1,
    )


def check_rotation(R, name: str = "rotation", tol: float = ORTHONORMAL_TOL) -> np.ndarray:
    """Return R as a float (3, 3) array if it is a rotation matrix, else raise.

    Raises :class:`InvalidStateError` naming the deviation if R has the wrong shape, has
    non-finite entries, has max|R^T R - I| > ``tol`` (1e-12), or det(R) < 0 (a reflection).
    R is never repaired (no re-orthonormalisation).
    """
    try:
        R = np.asarray(R, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidStateError(f"{name}: expected a 3x3 rotation matrix ({exc})") from None
    if R.shape != (3, 3):
        raise InvalidStateError(
            f"{name}: expected a 3x3 rotation matrix, got shape {R.shape} (for a quaternion "
            "use director_model.rotation_from_quat_wxyz)"
        )
    if not np.all(np.isfinite(R)):
        raise InvalidStateError(f"{name} = {R.tolist()}: every entry must be finite")
    dev = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if not dev <= tol:
        raise InvalidStateError(
            f"{name} is not orthonormal: max|R^T R - I| = {dev:.3e} > {tol:.0e} (rule: the "
            "initial rotation must be a rotation matrix to 1e-12; it is never "
            "re-orthonormalised silently)"
        )
    det = float(np.linalg.det(R))
    if det < 0:
        raise InvalidStateError(
            f"{name} has det = {det:.15g}: a reflection, not a rotation (rule: det(R) = +1)"
        )
    return R


def quat_wxyz_from_rotation(R) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w >= 0, of rotation matrices R, (..., 3, 3) -> (..., 4).
    R is not validated here (scipy projects onto SO(3)); use :func:`check_rotation` first."""
    R = np.asarray(R, dtype=float)
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    q = np.where(q[:, :1] < 0, -q, q)
    return q.reshape(R.shape[:-2] + (4,))


def rotation_from_quat_wxyz(q) -> np.ndarray:
    """Rotation matrices of quaternions (w, x, y, z), (..., 4) -> (..., 3, 3).

    Raises :class:`InvalidStateError` if a quaternion is non-finite or its norm differs from
    1 by more than 1e-12 (it is not normalised silently)."""
    q = np.asarray(q, dtype=float)
    if q.shape[-1:] != (4,):
        raise InvalidStateError(f"quat_wxyz: expected shape (..., 4), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise InvalidStateError("quat_wxyz: every entry must be finite")
    dev = float(np.max(np.abs(np.linalg.norm(q, axis=-1) - 1.0)))
    if not dev <= ORTHONORMAL_TOL:
        raise InvalidStateError(
            f"quat_wxyz is not a unit quaternion: max| |q| - 1 | = {dev:.3e} > 1e-12"
        )
    Rm = Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix()
    return Rm.reshape(q.shape[:-1] + (3, 3))


def director_velocity(R, omega_body) -> np.ndarray:
    """Director velocities D' = R hat(W), shapes (..., 3, 3), (..., 3) -> (..., 3, 3)."""
    return np.asarray(R, dtype=float) @ hat(omega_body)


def matmul3(A, B) -> np.ndarray:
    """A B for (..., 3, 3) arrays (broadcasting), each entry summed as
    (A_i0 B_0j + A_i1 B_1j) + A_i2 B_2j in element-wise operations: every sample rounds the
    same way whatever the shape of the stack (``@`` may go through BLAS, whose order and
    fused multiply-adds depend on the shape), so a saved state gives the same derived
    quantities in a long run and in a chunk of one sample."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    return (A[..., :, 0:1] * B[..., 0:1, :] + A[..., :, 1:2] * B[..., 1:2, :]) + A[..., :, 2:3] * B[
        ..., 2:3, :
    ]


def omega_body_from_directors(D, Dp) -> np.ndarray:
    """Body angular velocity W = vee(skew(D^T D')), (..., 3, 3) x2 -> (..., 3), rad/s.

    Only the skew part counts: a velocity that violates the hidden constraint (D^T D' not
    skew, as the energy-momentum scheme produces at O(h^2)) has its symmetric part dropped.
    """
    D = np.asarray(D, dtype=float)
    return vee(matmul3(np.swapaxes(D, -1, -2), Dp))


def omega_world_from_body(R, omega_body) -> np.ndarray:
    """World angular velocity w = R W, (..., 3, 3), (..., 3) -> (..., 3)."""
    return np.einsum("...ij,...j->...i", np.asarray(R, float), np.asarray(omega_body, float))


def omega_body_from_world(R, omega_world) -> np.ndarray:
    """Body angular velocity W = R^T w, (..., 3, 3), (..., 3) -> (..., 3)."""
    return np.einsum("...ji,...j->...i", np.asarray(R, float), np.asarray(omega_world, float))
