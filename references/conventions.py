"""Every convention conversion of the suite, in one place.

The suite describes a rigid body by the state ``(x, v, R, W)``:

- ``x``: centre of mass x_G, world axes (3,), m
- ``v``: centre-of-mass velocity v_G, world axes (3,), m/s
- ``R``: body-to-world rotation matrix (3, 3); its columns are the directors d1, d2, d3
- ``W``: angular velocity in body axes (3,), rad/s; the world angular velocity is w = R W

Quaternions are unit quaternions of the rotation R. Two storage orders occur in the engines:
``wxyz`` (scalar first: MuJoCo) and ``xyzw`` (scalar last: Pinocchio, PyBullet, scipy). A
rotation vector ``theta`` (axis times angle) is the exponential coordinate R = exp(hat(theta))
(DART's ball and free joints).

Engine state layouts (measured, see docs/engines.md; each one is tested with a non-identity
rotation and a generic angular velocity in tests/references/test_conventions.py):

=========================  ===============================  =============================
engine, joint              positions                        velocities
=========================  ===============================  =============================
MuJoCo free joint          qpos = [x (3), q wxyz (4)]       qvel = [v world (3), W body (3)]
MuJoCo ball joint          qpos = q wxyz (4)                qvel = W body (3)
Pinocchio FreeFlyer        q = [x (3), q xyzw (4)]          v = [R^T v (3), W (3)] (LOCAL)
Pinocchio Spherical        q = q xyzw (4)                   v = W (3) (LOCAL)
DART FreeJoint             [theta (3), x (3)]               [w world (3), v world (3)]
DART BallJoint             theta (3)                        W body (3)
PyBullet base              pos x, orn xyzw                  v world, w world
PyBullet spherical joint   q xyzw                           W body (child frame)
=========================  ===============================  =============================

For the free joints above the body frame is placed at the centre of mass with principal axes,
so the joint's translation is x_G itself. For the ball joints the body frame sits at the pivot
(the world origin) and the centre of mass is at ``-pivot`` in body axes; :func:`pivot_com`
gives x_G and v_G from (R, W).

All functions accept a single state; the ``*_batch`` helpers act on stacks of shape (n, ...).
They are written out by hand (no scipy) so that the tests against scipy.spatial.transform are
an independent check.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from references.errors import EngineError
from scenarios.schema import rotation_from_vector


class BodyState(NamedTuple):
    """One rigid-body state in the suite's convention (see the module docstring)."""

    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray


def stack_states(states) -> BodyState:
    """Stack a sequence of :class:`BodyState` into one with arrays (n, 3), (n, 3), (n, 3, 3),
    (n, 3): the argument order of :meth:`references.trajectory.Trajectory.from_states`. A
    BodyState whose fields are such stacks is a *block* of states (the run loop's unit)."""
    return BodyState(*(np.array([s[k] for s in states]) for k in range(4)))


def block_row(block: BodyState, i: int) -> BodyState:
    """State ``i`` of a block."""
    return BodyState(*(a[i] for a in block))


# -- skew matrices --------------------------------------------------------------------------
def hat(w) -> np.ndarray:
    """The skew matrix of a 3-vector: hat(a) b = a x b."""
    x, y, z = (float(c) for c in w)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def vee(S) -> np.ndarray:
    """The 3-vector of a skew matrix (the inverse of :func:`hat`, using the skew part)."""
    S = np.asarray(S, dtype=float)
    return 0.5 * np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]])


# -- quaternions ----------------------------------------------------------------------------
def _unit(q, name: str) -> np.ndarray:
    q = np.asarray(q, dtype=float).reshape(4)
    n = math.sqrt(float(q @ q))
    if not math.isfinite(n):
        # a diverged engine state: keep it non-finite, the run loop reports the divergence
        return np.full(4, math.nan)
    if not n > 0.0:
        raise ValueError(f"{name} quaternion {q.tolist()} has no direction (norm {n})")
    return q / n


def quat_wxyz_to_xyzw(q) -> np.ndarray:
    """Reorder a quaternion from scalar-first (MuJoCo) to scalar-last (Pinocchio, PyBullet)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 1:4], q[..., :1]], axis=-1)


def quat_xyzw_to_wxyz(q) -> np.ndarray:
    """Reorder a quaternion from scalar-last to scalar-first."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 3:4], q[..., :3]], axis=-1)


def quat_wxyz_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z). The quaternion is normalised first, so a
    slightly unnormalised engine quaternion maps to the rotation it stands for."""
    w, x, y, z = _unit(q, "wxyz")
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_xyzw_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion stored (x, y, z, w)."""
    return quat_wxyz_to_matrix(quat_xyzw_to_wxyz(q))


def matrix_to_quat_wxyz(R) -> np.ndarray:
    """Unit quaternion (w, x, y, z) with w >= 0 of a rotation matrix.

    Uses the largest of the four candidate pivots (Shepperd's method), which keeps full
    accuracy for every rotation angle, including angles near pi.
    """
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"rotation matrix must have shape (3, 3), got {R.shape}")
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
    tr = r00 + r11 + r22
    k = max(range(4), key=(tr, r00, r11, r22).__getitem__)
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = (0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + r00 - r11 - r22)
        q = ((r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + r11 - r00 - r22)
        q = ((r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + r22 - r00 - r11)
        q = ((r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s)
    n = math.sqrt(sum(c * c for c in q))
    sign = -1.0 if q[0] < 0 else 1.0
    return np.array([sign * c / n for c in q])


def matrix_to_quat_xyzw(R) -> np.ndarray:
    """Unit quaternion stored (x, y, z, w), w >= 0, of a rotation matrix."""
    return quat_wxyz_to_xyzw(matrix_to_quat_wxyz(R))


# -- rotation vectors (exponential coordinates) --------------------------------------------
#: R = exp(hat(theta)) for a rotation vector theta (3,): Rodrigues' formula with Taylor
#: series for small angles, defined once in the lowest layer that needs it (the scenario files'
#: rotation vectors); :func:`rotvecs_to_matrices` is its array form
rotvec_to_matrix = rotation_from_vector


def matrix_to_rotvec(R) -> np.ndarray:
    """The rotation vector theta (|theta| <= pi) with exp(hat(theta)) = R.

    Goes through the quaternion, theta = 2 atan2(|u|, w) u/|u| with q = (w, u), w >= 0, which
    is accurate for all angles (no division by sin near 0 or pi).
    """
    w, x, y, z = matrix_to_quat_wxyz(R).tolist()
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-8:
        # theta = 2 u (1 + |u|^2/6 + ...)/w to double precision for angles below 2e-8.
        f = 2.0 / w
    else:
        f = 2.0 * math.atan2(n, w) / n
    return np.array([f * x, f * y, f * z])


# -- angular velocity frames ----------------------------------------------------------------
def body_to_world_omega(R, W) -> np.ndarray:
    """World angular velocity w = R W. Works on single states and stacks (n, 3, 3), (n, 3)."""
    return np.einsum("...ij,...j->...i", np.asarray(R, float), np.asarray(W, float))


def world_to_body_omega(R, w) -> np.ndarray:
    """Body angular velocity W = R^T w. Works on single states and stacks."""
    return np.einsum("...ji,...j->...i", np.asarray(R, float), np.asarray(w, float))


# -- pivoted bodies -------------------------------------------------------------------------
def pivot_com(R, W, pivot) -> tuple[np.ndarray, np.ndarray]:
    """Centre-of-mass position and velocity of a body pivoted at the world origin.

    ``pivot`` is the fixed point in body axes relative to the centre of mass c, so the centre
    of mass sits at -c in body axes: x_G = -R c, v_G = w x x_G = -R (W x c).
    """
    R = np.asarray(R, dtype=float)
    c = np.asarray(pivot, dtype=float)
    return -R @ c, -R @ np.cross(np.asarray(W, dtype=float), c)


# -- engine layouts -------------------------------------------------------------------------
def _vec(a, n: int, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} entries, got {a.shape[0]}")
    return a


def mujoco_free_from_state(x, v, R, W) -> tuple[np.ndarray, np.ndarray]:
    """(qpos (7,), qvel (6,)) of a MuJoCo free joint whose body frame is the COM frame."""
    qpos = np.concatenate([_vec(x, 3, "x"), matrix_to_quat_wxyz(R)])
    qvel = np.concatenate([_vec(v, 3, "v"), _vec(W, 3, "W")])
    return qpos, qvel


def mujoco_free_to_state(qpos, qvel) -> BodyState:
    """Suite state of a MuJoCo free joint: qvel[0:3] is world, qvel[3:6] is body frame."""
    qpos = _vec(qpos, 7, "MuJoCo free-joint qpos")
    qvel = _vec(qvel, 6, "MuJoCo free-joint qvel")
    return BodyState(
        qpos[:3].copy(), qvel[:3].copy(), quat_wxyz_to_matrix(qpos[3:]), qvel[3:].copy()
    )


def mujoco_ball_from_state(R, W) -> tuple[np.ndarray, np.ndarray]:
    """(qpos (4,), qvel (3,)) of a MuJoCo ball joint: quaternion wxyz and body rates."""
    return matrix_to_quat_wxyz(R), _vec(W, 3, "W").copy()


def mujoco_ball_to_state(qpos, qvel) -> tuple[np.ndarray, np.ndarray]:
    """(R, W) of a MuJoCo ball joint."""
    return quat_wxyz_to_matrix(_vec(qpos, 4, "MuJoCo ball qpos")), _vec(qvel, 3, "qvel").copy()


def pinocchio_freeflyer_from_state(x, v, R, W) -> tuple[np.ndarray, np.ndarray]:
    """(q (7,), v (6,)) of a Pinocchio FreeFlyer whose body frame is the COM frame.

    The FreeFlyer velocity is LOCAL for both parts: the linear part is R^T v_G.
    """
    R = np.asarray(R, dtype=float)
    q = np.concatenate([_vec(x, 3, "x"), matrix_to_quat_xyzw(R)])
    vel = np.concatenate([R.T @ _vec(v, 3, "v"), _vec(W, 3, "W")])
    return q, vel


def pinocchio_freeflyer_to_state(q, v) -> BodyState:
    """Suite state of a Pinocchio FreeFlyer (LOCAL velocity, quaternion xyzw)."""
    q = _vec(q, 7, "Pinocchio FreeFlyer q")
    v = _vec(v, 6, "Pinocchio FreeFlyer v")
    R = quat_xyzw_to_matrix(q[3:])
    return BodyState(q[:3].copy(), R @ v[:3], R, v[3:].copy())


def pinocchio_spherical_from_state(R, W) -> tuple[np.ndarray, np.ndarray]:
    """(q (4,) xyzw, v (3,) LOCAL) of a Pinocchio spherical joint."""
    return matrix_to_quat_xyzw(R), _vec(W, 3, "W").copy()


def pinocchio_spherical_to_state(q, v) -> tuple[np.ndarray, np.ndarray]:
    """(R, W) of a Pinocchio spherical joint."""
    return quat_xyzw_to_matrix(_vec(q, 4, "Pinocchio spherical q")), _vec(v, 3, "v").copy()


def dart_free_from_state(x, v, R, W) -> tuple[np.ndarray, np.ndarray]:
    """(positions (6,), velocities (6,)) of a DART FreeJoint whose body frame is the COM frame:
    positions = [rotation vector, x], velocities = [w WORLD, v WORLD]."""
    R = np.asarray(R, dtype=float)
    pos = np.concatenate([matrix_to_rotvec(R), _vec(x, 3, "x")])
    vel = np.concatenate([R @ _vec(W, 3, "W"), _vec(v, 3, "v")])
    return pos, vel


def dart_free_to_state(positions, velocities) -> BodyState:
    """Suite state of a DART FreeJoint (angular velocity in WORLD axes)."""
    p = _vec(positions, 6, "DART FreeJoint positions")
    u = _vec(velocities, 6, "DART FreeJoint velocities")
    R = rotvec_to_matrix(p[:3])
    return BodyState(p[3:].copy(), u[3:].copy(), R, R.T @ u[:3])


def dart_ball_from_state(R, W) -> tuple[np.ndarray, np.ndarray]:
    """(positions (3,) rotation vector, velocities (3,) BODY) of a DART BallJoint."""
    return matrix_to_rotvec(R), _vec(W, 3, "W").copy()


def dart_ball_to_state(positions, velocities) -> tuple[np.ndarray, np.ndarray]:
    """(R, W) of a DART BallJoint (body-frame velocity, unlike the FreeJoint)."""
    R = rotvec_to_matrix(_vec(positions, 3, "DART BallJoint positions"))
    return R, _vec(velocities, 3, "DART BallJoint velocities").copy()


def pybullet_base_from_state(x, v, R, W):
    """(position, orientation xyzw, linear velocity, angular velocity WORLD) of a PyBullet
    base whose inertial frame is the COM frame, as lists for the PyBullet API."""
    R = np.asarray(R, dtype=float)
    return (
        _vec(x, 3, "x").tolist(),
        matrix_to_quat_xyzw(R).tolist(),
        _vec(v, 3, "v").tolist(),
        (R @ _vec(W, 3, "W")).tolist(),
    )


def pybullet_base_to_state(position, orientation_xyzw, linear, angular_world) -> BodyState:
    """Suite state of a PyBullet base (getBasePositionAndOrientation, getBaseVelocity)."""
    R = quat_xyzw_to_matrix(_vec(orientation_xyzw, 4, "PyBullet base orientation"))
    return BodyState(
        _vec(position, 3, "PyBullet base position").copy(),
        _vec(linear, 3, "PyBullet base linear velocity").copy(),
        R,
        R.T @ _vec(angular_world, 3, "PyBullet base angular velocity"),
    )


def pybullet_spherical_from_state(R, W):
    """(quaternion xyzw, body rates) of a PyBullet spherical joint, as lists."""
    return matrix_to_quat_xyzw(R).tolist(), _vec(W, 3, "W").tolist()


def pybullet_spherical_to_state(q_xyzw, W) -> tuple[np.ndarray, np.ndarray]:
    """(R, W) of a PyBullet spherical joint (getJointStateMultiDof: xyzw, child frame)."""
    R = quat_xyzw_to_matrix(_vec(q_xyzw, 4, "PyBullet spherical joint quaternion"))
    return R, _vec(W, 3, "PyBullet spherical joint velocity").copy()


# -- blocks of states (stacks of shape (k, ...)), for the run loop's checkpoints ------------
def quats_wxyz_to_matrices(q) -> np.ndarray:
    """Rotation matrices (k, 3, 3) of quaternions (k, 4) stored (w, x, y, z), each normalised
    first (a row that is not finite gives a non-finite matrix: a diverged state)."""
    q = np.asarray(q, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def rotvecs_to_matrices(theta) -> np.ndarray:
    """R = exp(hat(theta)) for rotation vectors (k, 3): (k, 3, 3), Rodrigues' formula with the
    series of :func:`rotvec_to_matrix` for small angles."""
    th = np.asarray(theta, dtype=float)
    a2 = np.einsum("ki,ki->k", th, th)
    small = a2 < 1e-8
    a = np.sqrt(np.where(small, 1.0, a2))
    s = np.where(small, 1.0 - a2 / 6.0 + a2 * a2 / 120.0, np.sin(a) / a)
    c = np.where(
        small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - np.cos(a)) / np.where(small, 1.0, a2)
    )
    x, y, z = th.T
    return np.stack(
        [
            np.stack([1 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y], -1),
            np.stack([c * x * y + s * z, 1 - c * (x * x + z * z), c * y * z - s * x], -1),
            np.stack([c * x * z - s * y, c * y * z + s * x, 1 - c * (x * x + y * y)], -1),
        ],
        axis=1,
    )


def pivot_block(R, W, com) -> BodyState:
    """The block of states (x_G = R com, v_G = R (W x com)) of a body on a ball joint at the
    world origin, from stacks R (k, 3, 3), W (k, 3); ``com`` is the centre of mass in the
    body frame."""
    R = np.asarray(R, dtype=float)
    W = np.asarray(W, dtype=float)
    c = np.asarray(com, dtype=float)
    u = np.stack(
        [W[:, 1] * c[2] - W[:, 2] * c[1], W[:, 2] * c[0] - W[:, 0] * c[2],
         W[:, 0] * c[1] - W[:, 1] * c[0]], axis=-1,
    )  # fmt: skip
    return BodyState(R @ c, np.einsum("kij,kj->ki", R, u), R, W)


def mujoco_block(raw, nq: int, com, pivoted: bool) -> BodyState:
    """States of rows ``[qpos, qvel]`` of a MuJoCo free joint (qpos [x, q wxyz], qvel [v world,
    W body]) or ball joint (qpos q wxyz, qvel W body)."""
    raw = np.asarray(raw, dtype=float)
    if pivoted:
        return pivot_block(quats_wxyz_to_matrices(raw[:, 0:4]), raw[:, nq : nq + 3], com)
    R = quats_wxyz_to_matrices(raw[:, 3:7])
    return BodyState(raw[:, 0:3], raw[:, nq : nq + 3], R, raw[:, nq + 3 : nq + 6])


def pinocchio_block(raw, nq: int, com, pivoted: bool) -> BodyState:
    """States of rows ``[q, v]`` of a Pinocchio FreeFlyer (q [x, q xyzw], v LOCAL [R^T v_G, W])
    or Spherical joint (q xyzw, v = W)."""
    raw = np.asarray(raw, dtype=float)
    if pivoted:
        R = quats_wxyz_to_matrices(quat_xyzw_to_wxyz(raw[:, 0:4]))
        return pivot_block(R, raw[:, nq : nq + 3], com)
    R = quats_wxyz_to_matrices(quat_xyzw_to_wxyz(raw[:, 3:7]))
    v = np.einsum("kij,kj->ki", R, raw[:, nq : nq + 3])
    return BodyState(raw[:, 0:3], v, R, raw[:, nq + 3 : nq + 6])


def dart_block(raw, ndof: int, com, pivoted: bool) -> BodyState:
    """States of rows ``[positions, velocities]`` of a DART FreeJoint ([rotation vector, x],
    [w WORLD, v WORLD]) or BallJoint (rotation vector, W BODY)."""
    raw = np.asarray(raw, dtype=float)
    R = rotvecs_to_matrices(raw[:, 0:3])
    if pivoted:
        return pivot_block(R, raw[:, ndof : ndof + 3], com)
    W = np.einsum("kji,kj->ki", R, raw[:, ndof : ndof + 3])
    return BodyState(raw[:, 3:6], raw[:, ndof + 3 : ndof + 6], R, W)


def pybullet_block(raw, com, pivoted: bool) -> BodyState:
    """States of rows ``[x, q xyzw, v, w world]`` of a PyBullet base, or ``[q xyzw, W body]``
    of a spherical joint."""
    raw = np.asarray(raw, dtype=float)
    if pivoted:
        R = quats_wxyz_to_matrices(quat_xyzw_to_wxyz(raw[:, 0:4]))
        return pivot_block(R, raw[:, 4:7], com)
    R = quats_wxyz_to_matrices(quat_xyzw_to_wxyz(raw[:, 3:7]))
    W = np.einsum("kji,kj->ki", R, raw[:, 10:13])
    return BodyState(raw[:, 0:3], raw[:, 7:10], R, W)


# -- checks that an engine holds what the scenario says ------------------------------------
def check_quantity(engine: str, quantity: str, got, expected, rtol: float, atol: float = 0.0):
    """Raise :class:`~references.errors.EngineError` naming ``quantity`` unless
    |got - expected| <= atol + rtol |expected| elementwise (read-back of a built model)."""
    got = np.asarray(got, dtype=float)
    expected = np.asarray(expected, dtype=float)
    if got.shape != expected.shape or not np.all(
        np.abs(got - expected) <= atol + rtol * np.abs(expected)
    ):
        raise EngineError(
            f"{engine}: the built model holds {quantity} = {got.tolist()}, but the scenario "
            f"says {expected.tolist()} (rtol {rtol:g}, atol {atol:g}); the adapter did not "
            f"transfer {quantity} correctly"
        )


def _scaled(diff, scale) -> float:
    diff = float(np.max(np.abs(diff)))
    if scale > 0:
        return diff / scale
    return 0.0 if diff == 0 else math.inf


def initial_state_errors(scenario, state: BodyState, native: dict | None = None) -> dict:
    """Relative differences between a state read back from an engine and the scenario's own
    initial state: energy and angular momentum computed the suite's way
    (:meth:`references.trajectory.Trajectory.from_states`), the state itself, and, if the
    engine computes them (``native = {"energy": E, "angular momentum": L, "rotation": R,
    "COM velocity": v}``, L in world axes about the COM for a free body and about the pivot
    for a pivoted one, v in world axes; rotation and COM velocity optional), the engine's own
    energy, momentum, rotation and COM velocity.

    Each difference is scaled by a characteristic size of the quantity rather than by its
    value, so that a total that happens to be near zero (an energy with a negative potential
    part, the COM velocity of a body spinning about its pivot axis) does not make the
    comparison meaningless: with l the pivot distance (free body: the largest radius of
    gyration) and u = |v0| + |W0| l, energy by 1/2 m u^2 + 1/2 W.IW + m |g| (|x0| + l),
    momentum by |I W| + m (|x0| + l) u, position by |x0| + l, velocity by u, W by |W0|,
    R by 1.

    The round trip scenario -> engine -> suite checks that the two conversions are inverse to
    each other; only the engine's own energy and momentum (or its own kinematics) check that
    the engine understood the state the way we meant it.
    """
    from references.trajectory import OneBody

    def one(x, v, R, W):
        return OneBody.from_states(scenario, [0.0], [x], [v], [R], [W])

    ref = one(scenario.position, scenario.velocity, scenario.rotation, scenario.omega_body)
    got = one(*state)
    m = scenario.mass
    I = np.asarray(scenario.inertia)
    W0 = np.asarray(scenario.omega_body)
    x0 = np.asarray(scenario.position)
    v0 = np.asarray(scenario.velocity)
    # Characteristic length and speed of the body, so that a quantity that is zero in the
    # scenario (v_G of a body spinning about its pivot axis) is compared on a sensible scale.
    ell = (
        float(np.linalg.norm(scenario.pivot))
        if scenario.pivot is not None
        else math.sqrt(float(I.max()) / m)
    )
    speed = float(np.linalg.norm(v0)) + float(np.linalg.norm(W0)) * ell
    reach = float(np.linalg.norm(x0)) + ell
    e_scale = (
        0.5 * m * speed**2
        + 0.5 * W0 @ (I * W0)
        + m * float(np.linalg.norm(scenario.gravity)) * reach
    )
    l_scale = float(np.linalg.norm(I * W0)) + m * reach * speed

    errors = {
        "energy": _scaled(got.energy - ref.energy, e_scale),
        "angular momentum": _scaled(got.angular_momentum - ref.angular_momentum, l_scale),
        "COM position": _scaled(state.position - x0, reach),
        "COM velocity": _scaled(state.velocity - v0, speed),
        "rotation": _scaled(state.rotation - scenario.rotation, 1.0),
        "body angular velocity": _scaled(state.omega_body - W0, np.linalg.norm(W0)),
    }
    if native:
        if "rotation" in native:
            errors["engine's own rotation"] = _scaled(
                np.asarray(native["rotation"], dtype=float) - scenario.rotation, 1.0
            )
        errors["engine's own energy"] = _scaled(native["energy"] - ref.energy[0], e_scale)
        errors["engine's own angular momentum"] = _scaled(
            np.asarray(native["angular momentum"]) - ref.angular_momentum[0], l_scale
        )
        if "COM position" in native:
            errors["engine's own COM position"] = _scaled(
                np.asarray(native["COM position"]) - x0, reach
            )
        if "COM velocity" in native:
            errors["engine's own COM velocity"] = _scaled(
                np.asarray(native["COM velocity"]) - v0, speed
            )
    return errors


def check_initial_state(
    engine: str, scenario, state: BodyState, native: dict | None = None, rtol: float = 1e-12
) -> dict:
    """Raise :class:`~references.errors.EngineError` naming the quantity if the state
    read back from ``engine`` before the first step does not reproduce the scenario (energy,
    angular momentum, state; the engine's own energy and momentum if given in ``native``) to
    ``rtol`` relative (see :func:`initial_state_errors`); returns the relative errors."""
    errors = initial_state_errors(scenario, state, native)
    for quantity, err in errors.items():
        if not err <= rtol:
            raise EngineError(
                f"{engine}: before the first step, the {quantity} read back from the engine "
                f"differs from the scenario's by {err:.3g} relative (allowed {rtol:g}); a "
                "convention conversion or the model's mass properties are wrong"
            )
    return errors


# -- Drake (pydrake): layouts and frames ---------------------------------------------------
#
# Measured with drake 1.51.1 (tests/references/engines/test_engine_drake.py checks each against
# Drake itself):
#
# ===========================  =================================  ===========================
# joint                        positions                          velocities
# ===========================  =================================  ===========================
# QuaternionFloatingJoint      q = [q_FM wxyz (4), p_FM (3)]      v = [w_FM (3), v_FM (3)],
#                                                                 both in F (= WORLD here)
# BallRpyJoint                 q = [roll, pitch, yaw] of R_FM      v = w_FM expressed in F
#                              (R_FM = Rz(yaw) Ry(pitch) Rx(roll))
# ===========================  =================================  ===========================
#
# Drake never renormalises a QuaternionFloatingJoint's quaternion: its kinematics use
# q/|q| (the body pose is orthonormal whatever |q|), its kinematic map is qdot = 1/2 (0, w) q
# with the raw q (which keeps |q| in the exact flow), and an integrator's error changes |q|.
# :func:`drake_free_to_state` shows that change instead of hiding it: R is the homogeneous
# quadratic form of the raw q, so R^T R = |q|^4 1 and the suite's orthonormality metric sees
# it; W is Drake's own body angular velocity R(q/|q|)^T w, so the kinetic energy is Drake's.
#
# The RPY ball joint is a chart of SO(3) with a singularity at pitch = +-pi/2; the adapter
# places its frames F (on the world) and M (on the body) so that the run stays away from it
# (references/engines/drake_engine.py), and the conversions below take those frames.


def quat_wxyz_to_matrix_unnormalised(q) -> np.ndarray:
    """R(q) = the homogeneous quadratic form of the quaternion (w, x, y, z), NOT normalised:
    R(c q) = c^2 R(q) and R^T R = |q|^4 1, so a quaternion whose norm drifted gives a matrix
    whose orthonormality error shows the drift (|q|^4 - 1)."""
    w, x, y, z = _vec(q, 4, "wxyz quaternion").tolist()
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    return np.array(
        [
            [ww + xx - yy - zz, 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), ww - xx + yy - zz, 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), ww - xx - yy + zz],
        ]
    )


def drake_free_from_state(x, v, R, W) -> tuple[np.ndarray, np.ndarray]:
    """(q (7,), v (6,)) of a Drake QuaternionFloatingJoint between the world frame and the
    body's principal COM frame: q = [q wxyz, x], v = [w WORLD, v WORLD]."""
    R = np.asarray(R, dtype=float)
    q = np.concatenate([matrix_to_quat_wxyz(R), _vec(x, 3, "x")])
    vel = np.concatenate([R @ _vec(W, 3, "W"), _vec(v, 3, "v")])
    return q, vel


def drake_free_to_state(q, v) -> BodyState:
    """Suite state of a Drake QuaternionFloatingJoint (angular velocity in WORLD axes).

    R is built from the raw quaternion without normalising it
    (:func:`quat_wxyz_to_matrix_unnormalised`); W = R^T w / |q|^2 = R(q/|q|)^T w, the body
    angular velocity in Drake's own kinematics."""
    q = _vec(q, 7, "Drake QuaternionFloatingJoint positions")
    u = _vec(v, 6, "Drake QuaternionFloatingJoint velocities")
    quat = q[:4]
    n2 = float(quat @ quat)
    if not (n2 > 0.0 and math.isfinite(n2)):
        raise ValueError(f"Drake quaternion {quat.tolist()} has no direction (|q|^2 = {n2})")
    R = quat_wxyz_to_matrix_unnormalised(quat)
    return BodyState(q[4:].copy(), u[3:].copy(), R, R.T @ u[:3] / n2)


def rpy_to_matrix(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) of rpy = (roll, pitch, yaw): Drake's RollPitchYaw
    (space-fixed x-y-z angles)."""
    r, p, y = _vec(rpy, 3, "rpy").tolist()
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_rpy(R) -> np.ndarray:
    """(roll, pitch, yaw) with |pitch| <= pi/2 of a rotation R = Rz(yaw) Ry(pitch) Rx(roll).

    Accurate while cos(pitch) is not small (atan2 throughout, pitch from atan2(-R20,
    hypot(R00, R10))); at pitch = +-pi/2 the roll and yaw are not separately defined."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"rotation matrix must have shape (3, 3), got {R.shape}")
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    return np.array([math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])])


def drake_ball_rpy_from_state(R, W, R_WF, R_BM) -> tuple[np.ndarray, np.ndarray]:
    """(rpy (3,), w_FM in F (3,)) of a Drake BallRpyJoint whose frame F on the world has
    rotation ``R_WF`` and whose frame M on the body (principal axes B) has rotation ``R_BM``:
    R_FM = R_WF^T R R_BM, w_F = R_WF^T R W."""
    R = np.asarray(R, dtype=float)
    R_WF = np.asarray(R_WF, dtype=float)
    R_FM = R_WF.T @ R @ np.asarray(R_BM, dtype=float)
    return matrix_to_rpy(R_FM), R_WF.T @ (R @ _vec(W, 3, "W"))


def drake_ball_rpy_to_state(rpy, w_F, R_WF, R_BM) -> tuple[np.ndarray, np.ndarray]:
    """(R, W) of a Drake BallRpyJoint (see :func:`drake_ball_rpy_from_state`):
    R = R_WF R_FM(rpy) R_BM^T, W = R^T R_WF w_F."""
    R_WF = np.asarray(R_WF, dtype=float)
    R = R_WF @ rpy_to_matrix(rpy) @ np.asarray(R_BM, dtype=float).T
    return R, R.T @ (R_WF @ _vec(w_F, 3, "BallRpyJoint angular velocity"))


def drake_block(raw, nq: int, com, pivoted: bool, R_WF=None, R_BM=None) -> BodyState:
    """States of rows ``[q, v]`` of a Drake QuaternionFloatingJoint (q [q wxyz, x], v [w world,
    v world]; R from the raw quaternion, unnormalised, as :func:`drake_free_to_state`) or of a
    BallRpyJoint (q rpy, v w_F; as :func:`drake_ball_rpy_to_state`), vectorised."""
    raw = np.asarray(raw, dtype=float)
    if pivoted:
        r, p, y = raw[:, 0], raw[:, 1], raw[:, 2]
        cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        R_FM = np.stack(
            [
                np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
                np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
                np.stack([-sp, cp * sr, cp * cr], -1),
            ],
            axis=1,
        )
        R = np.asarray(R_WF, dtype=float) @ R_FM @ np.asarray(R_BM, dtype=float).T
        w = raw[:, nq : nq + 3] @ np.asarray(R_WF, dtype=float).T
        return pivot_block(R, np.einsum("kji,kj->ki", R, w), com)
    w_, x_, y_, z_ = raw[:, 0], raw[:, 1], raw[:, 2], raw[:, 3]
    ww, xx, yy, zz = w_ * w_, x_ * x_, y_ * y_, z_ * z_
    R = np.stack(
        [
            np.stack([ww + xx - yy - zz, 2 * (x_ * y_ - w_ * z_), 2 * (x_ * z_ + w_ * y_)], -1),
            np.stack([2 * (x_ * y_ + w_ * z_), ww - xx + yy - zz, 2 * (y_ * z_ - w_ * x_)], -1),
            np.stack([2 * (x_ * z_ - w_ * y_), 2 * (y_ * z_ + w_ * x_), ww - xx - yy + zz], -1),
        ],
        axis=1,
    )
    n2 = ww + xx + yy + zz
    with np.errstate(invalid="ignore", divide="ignore"):
        W = np.einsum("kji,kj->ki", R, raw[:, nq : nq + 3]) / n2[:, None]
    return BodyState(raw[:, 4:7], raw[:, nq + 3 : nq + 6], R, W)
