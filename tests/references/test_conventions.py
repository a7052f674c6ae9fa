"""Convention conversions against scipy.spatial.transform and hand computations.

Every check uses non-identity rotations and generic angular velocities: an identity start
hides frame mistakes (docs/engines.md). Tolerances are a few ulp of the quantities involved
(entries of order 1), unless stated otherwise.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from references import conventions as cv
from references.errors import EngineError
from scenarios.model import Scenario

#: a few ulp for O(1) numbers that go through a handful of flops
ULP_TOL = 1e-14

# Rotations of every kind: generic, near identity, exactly pi, near pi, quarter turns.
ROTVECS = [
    (0.3, -1.1, 0.7),
    (2.0, 1.0, -0.5),
    (1e-9, -2e-9, 3e-9),
    (1e-5, 2e-5, -1e-5),
    (math.pi, 0.0, 0.0),
    (0.0, math.pi / math.sqrt(2), math.pi / math.sqrt(2)),
    (0.0, 0.0, math.pi - 1e-7),
    (0.0, 0.0, math.pi / 2),
]


def random_rotations(n=50, seed=7):
    return Rotation.random(n, random_state=np.random.default_rng(seed))


def test_hat_vee_by_hand():
    a = np.array([0.3, -1.2, 2.5])
    b = np.array([-0.7, 0.4, 1.1])
    assert np.allclose(cv.hat(a) @ b, np.cross(a, b), rtol=0, atol=ULP_TOL)
    assert np.array_equal(cv.vee(cv.hat(a)), a)
    assert np.array_equal(cv.hat(a), -cv.hat(a).T)


def test_quaternion_order_swaps():
    q = np.array([0.1, 0.2, 0.3, 0.4])  # not unit: reordering must not touch the values
    assert np.array_equal(cv.quat_wxyz_to_xyzw(q), [0.2, 0.3, 0.4, 0.1])
    assert np.array_equal(cv.quat_xyzw_to_wxyz(cv.quat_wxyz_to_xyzw(q)), q)


def test_quaternion_to_matrix_against_scipy():
    rots = random_rotations()
    for rot in rots:
        xyzw = rot.as_quat()
        R = rot.as_matrix()
        assert np.allclose(cv.quat_xyzw_to_matrix(xyzw), R, rtol=0, atol=ULP_TOL)
        assert np.allclose(cv.quat_wxyz_to_matrix(np.roll(xyzw, 1)), R, rtol=0, atol=ULP_TOL)
        # q and -q are the same rotation
        assert np.allclose(cv.quat_xyzw_to_matrix(-xyzw), R, rtol=0, atol=ULP_TOL)


def test_quaternion_to_matrix_by_hand():
    # a quarter turn about z: q = (cos 45deg, 0, 0, sin 45deg) maps x to y
    h = math.sqrt(0.5)
    R = cv.quat_wxyz_to_matrix([h, 0, 0, h])
    assert np.allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], rtol=0, atol=ULP_TOL)
    # unnormalised input stands for the same rotation (engines may hand back |q| != 1)
    assert np.allclose(cv.quat_wxyz_to_matrix([2 * h, 0, 0, 2 * h]), R, rtol=0, atol=ULP_TOL)
    with pytest.raises(ValueError, match="no direction"):
        cv.quat_wxyz_to_matrix([0, 0, 0, 0])


def test_matrix_to_quaternion_against_scipy():
    rots = random_rotations()
    for rv in ROTVECS:
        rots = Rotation.concatenate([rots, Rotation.from_rotvec(rv)])
    for rot in rots:
        R = rot.as_matrix()
        q = cv.matrix_to_quat_wxyz(R)
        ref = rot.as_quat()
        ref = np.roll(ref, 1) * (1 if ref[3] >= 0 else -1)
        assert q[0] >= 0
        # at w = 0 (a half turn) q and -q both have w >= 0: compare as rotations
        if abs(ref[0]) > 1e-12:
            assert np.allclose(q, ref, rtol=0, atol=ULP_TOL)
        assert np.allclose(cv.quat_wxyz_to_matrix(q), R, rtol=0, atol=ULP_TOL)
        assert np.allclose(cv.matrix_to_quat_xyzw(R), cv.quat_wxyz_to_xyzw(q), rtol=0, atol=0)


@pytest.mark.parametrize("rv", ROTVECS)
def test_rotation_vector_against_scipy(rv):
    rot = Rotation.from_rotvec(rv)
    assert np.allclose(cv.rotvec_to_matrix(rv), rot.as_matrix(), rtol=0, atol=ULP_TOL)
    back = cv.matrix_to_rotvec(rot.as_matrix())
    # |theta| <= pi; at exactly pi, theta and -theta are the same rotation
    assert np.linalg.norm(back) <= math.pi + 1e-15
    assert np.allclose(cv.rotvec_to_matrix(back), rot.as_matrix(), rtol=0, atol=ULP_TOL)
    if np.linalg.norm(rv) < math.pi - 1e-6:
        # 1e-8 relative near pi - 1e-7 would be needed; away from pi the log is well
        # conditioned and round-off is a few ulp of |theta| (relative for tiny angles).
        assert np.allclose(back, rv, rtol=1e-12, atol=ULP_TOL * np.linalg.norm(rv))


def test_rotation_vector_random_round_trip():
    for rot in random_rotations():
        rv = rot.as_rotvec()
        assert np.allclose(cv.matrix_to_rotvec(rot.as_matrix()), rv, rtol=0, atol=1e-13)


def test_angular_velocity_frames_by_hand_and_batched():
    Rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    # body x axis points along world y after a quarter turn about z
    assert np.array_equal(cv.body_to_world_omega(Rz, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])
    assert np.array_equal(cv.world_to_body_omega(Rz, [0.0, 1.0, 0.0]), [1.0, 0.0, 0.0])
    rots = random_rotations(5)
    W = np.random.default_rng(3).normal(size=(5, 3))
    w = cv.body_to_world_omega(rots.as_matrix(), W)
    assert np.allclose(w, rots.apply(W), rtol=0, atol=ULP_TOL)
    assert np.allclose(cv.world_to_body_omega(rots.as_matrix(), w), W, rtol=0, atol=ULP_TOL)


def test_pivot_com_by_hand():
    # pivot 0.5 below the COM along body z, body axes = world axes: COM at +0.5 z;
    # spinning about x at 1 rad/s: v_G = w x x_G = (1, 0, 0) x (0, 0, 0.5) = (0, -0.5, 0)
    x, v = cv.pivot_com(np.eye(3), [1.0, 0.0, 0.0], [0.0, 0.0, -0.5])
    assert np.array_equal(x, [0.0, 0.0, 0.5])
    assert np.array_equal(v, [0.0, -0.5, 0.0])


# -- engine layouts -------------------------------------------------------------------------
R0 = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
W0 = np.array([0.4, -1.3, 2.1])
X0 = np.array([0.1, 0.2, -0.3])
V0 = np.array([1.0, -2.0, 0.5])


def _assert_state(state, x, v, R, W):
    assert np.allclose(state.position, x, rtol=0, atol=ULP_TOL)
    assert np.allclose(state.velocity, v, rtol=0, atol=ULP_TOL)
    assert np.allclose(state.rotation, R, rtol=0, atol=ULP_TOL)
    assert np.allclose(state.omega_body, W, rtol=0, atol=ULP_TOL)


def test_mujoco_layouts():
    qpos, qvel = cv.mujoco_free_from_state(X0, V0, R0, W0)
    xyzw = Rotation.from_matrix(R0).as_quat()
    assert np.allclose(qpos[3:], np.roll(xyzw, 1) * np.sign(xyzw[3]), rtol=0, atol=ULP_TOL)
    assert np.array_equal(qpos[:3], X0)
    assert np.array_equal(qvel, np.concatenate([V0, W0]))  # linear world, angular body
    _assert_state(cv.mujoco_free_to_state(qpos, qvel), X0, V0, R0, W0)
    qb, vb = cv.mujoco_ball_from_state(R0, W0)
    assert np.array_equal(qb, qpos[3:]) and np.array_equal(vb, W0)
    R, W = cv.mujoco_ball_to_state(qb, vb)
    assert np.allclose(R, R0, rtol=0, atol=ULP_TOL) and np.array_equal(W, W0)


def test_pinocchio_layouts():
    q, v = cv.pinocchio_freeflyer_from_state(X0, V0, R0, W0)
    xyzw = Rotation.from_matrix(R0).as_quat()
    assert np.allclose(q[3:], xyzw * np.sign(xyzw[3]), rtol=0, atol=ULP_TOL)
    # LOCAL linear velocity: R^T v_G (hand: R0.T @ V0, written with scipy's inverse)
    assert np.allclose(v[:3], Rotation.from_matrix(R0).inv().apply(V0), rtol=0, atol=ULP_TOL)
    assert np.array_equal(v[3:], W0)
    _assert_state(cv.pinocchio_freeflyer_to_state(q, v), X0, V0, R0, W0)
    qs, vs = cv.pinocchio_spherical_from_state(R0, W0)
    assert np.array_equal(qs, q[3:]) and np.array_equal(vs, W0)
    R, W = cv.pinocchio_spherical_to_state(qs, vs)
    assert np.allclose(R, R0, rtol=0, atol=ULP_TOL) and np.array_equal(W, W0)


def test_dart_layouts():
    pos, vel = cv.dart_free_from_state(X0, V0, R0, W0)
    assert np.allclose(pos[:3], [0.3, -1.1, 0.7], rtol=0, atol=ULP_TOL)
    assert np.array_equal(pos[3:], X0)
    # FreeJoint angular velocity is WORLD: R W
    assert np.allclose(vel[:3], Rotation.from_matrix(R0).apply(W0), rtol=0, atol=ULP_TOL)
    assert np.array_equal(vel[3:], V0)
    _assert_state(cv.dart_free_to_state(pos, vel), X0, V0, R0, W0)
    # BallJoint angular velocity is BODY (differs from the FreeJoint!)
    pb, vb = cv.dart_ball_from_state(R0, W0)
    assert np.allclose(pb, [0.3, -1.1, 0.7], rtol=0, atol=ULP_TOL) and np.array_equal(vb, W0)
    R, W = cv.dart_ball_to_state(pb, vb)
    assert np.allclose(R, R0, rtol=0, atol=ULP_TOL) and np.array_equal(W, W0)


def test_pybullet_layouts():
    x, q, v, w = cv.pybullet_base_from_state(X0, V0, R0, W0)
    xyzw = Rotation.from_matrix(R0).as_quat()
    assert np.allclose(q, xyzw * np.sign(xyzw[3]), rtol=0, atol=ULP_TOL)
    assert np.allclose(w, Rotation.from_matrix(R0).apply(W0), rtol=0, atol=ULP_TOL)  # WORLD
    assert x == X0.tolist() and v == V0.tolist()
    _assert_state(cv.pybullet_base_to_state(x, q, v, w), X0, V0, R0, W0)
    qs, Ws = cv.pybullet_spherical_from_state(R0, W0)
    assert qs == q and Ws == W0.tolist()  # spherical joint velocity is BODY (child frame)
    R, W = cv.pybullet_spherical_to_state(qs, Ws)
    assert np.allclose(R, R0, rtol=0, atol=ULP_TOL) and np.array_equal(W, W0)


def test_layouts_reject_wrong_sizes():
    with pytest.raises(ValueError, match="7 entries"):
        cv.mujoco_free_to_state(np.zeros(6), np.zeros(6))
    with pytest.raises(ValueError, match="6 entries"):
        cv.dart_free_to_state(np.zeros(6), np.zeros(5))


# -- read-back checks -----------------------------------------------------------------------
def _scenario(**kw):
    base = dict(
        name="conv",
        description="",
        mass=1.5,
        inertia=[2.0, 3.0, 4.0],
        rotation=R0,
        omega_body=W0,
        t_end=1.0,
        dt=0.01,
        position=X0,
        velocity=V0,
        gravity=[0.0, 0.0, -9.81],
    )
    base.update(kw)
    return Scenario(**base)


def test_check_initial_state_accepts_exact_and_names_the_wrong_quantity():
    sc = _scenario()
    exact = cv.BodyState(X0, V0, R0, W0)
    errs = cv.check_initial_state("test", sc, exact)
    assert set(errs) >= {"energy", "angular momentum", "rotation", "body angular velocity"}
    assert all(e == 0.0 for e in errs.values())
    # world rates passed as body rates: |W| is kept but W . I W and R I W change
    wrong = cv.BodyState(X0, V0, R0, R0 @ W0)
    with pytest.raises(EngineError, match="energy"):
        cv.check_initial_state("test", sc, wrong)
    # a sign flip of W_1 keeps the energy but not the momentum
    flipped = cv.BodyState(X0, V0, R0, W0 * [-1, 1, 1])
    with pytest.raises(EngineError, match="angular momentum"):
        cv.check_initial_state("test", sc, flipped)
    # a consistent round trip can still hide an engine that read the state differently:
    # the engine's own energy and momentum are compared when given
    T = 0.5 * 1.5 * V0 @ V0 + 0.5 * W0 @ (np.array([2.0, 3.0, 4.0]) * W0)
    E = T - 1.5 * X0 @ np.array([0.0, 0.0, -9.81])
    L = R0 @ (np.array([2.0, 3.0, 4.0]) * W0)
    good = {"energy": E, "angular momentum": L}
    errs = cv.check_initial_state("test", sc, exact, native=good)
    assert errs["engine's own energy"] < 1e-15 and errs["engine's own angular momentum"] < 1e-15
    with pytest.raises(EngineError, match="engine's own energy"):
        cv.check_initial_state("test", sc, exact, native={**good, "energy": E * (1 + 1e-9)})
    with pytest.raises(EngineError, match="engine's own angular momentum"):
        cv.check_initial_state("test", sc, exact, native={**good, "angular momentum": -L})


def test_check_quantity_names_the_quantity():
    cv.check_quantity("E", "mass", 1.0, 1.0, 0.0)
    with pytest.raises(EngineError, match="inertia diagonal"):
        cv.check_quantity("E", "inertia diagonal", [1.0, 1.0, 1.0], [2.0, 3.0, 4.0], 1e-15)


# == blocks of states: the vectorised conversions equal the per-state ones ====================
def _random_states(n=40, seed=3):
    rng = np.random.default_rng(seed)
    R = Rotation.random(n, random_state=seed).as_matrix()
    return (
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 3)),
        R,
        rng.normal(size=(n, 3)) * 3.0,
    )


COM = np.array([0.05, -0.1, 0.3])


@pytest.mark.parametrize("pivoted", [False, True])
def test_block_conversions_equal_the_per_state_ones(pivoted):
    """Each engine layout: rows written by the per-state `*_from_state` conversion, read back
    by the vectorised `*_block`, give the states back (to a few ulp); for a pivoted body the
    centre of mass follows from R (x_G = R com, v_G = R (W x com))."""
    x, v, R, W = _random_states()
    if pivoted:
        x = np.einsum("kij,j->ki", R, COM)
        v = np.einsum("kij,kj->ki", R, np.cross(W, COM))
    rows = {"mujoco": [], "pinocchio": [], "dart": [], "pybullet": [], "drake": []}
    for i in range(len(R)):
        if pivoted:
            rows["mujoco"].append(np.concatenate(cv.mujoco_ball_from_state(R[i], W[i])))
            rows["pinocchio"].append(np.concatenate(cv.pinocchio_spherical_from_state(R[i], W[i])))
            rows["dart"].append(np.concatenate(cv.dart_ball_from_state(R[i], W[i])))
            q, Wb = cv.pybullet_spherical_from_state(R[i], W[i])
            rows["pybullet"].append(np.array([*q, *Wb]))
        else:
            rows["mujoco"].append(np.concatenate(cv.mujoco_free_from_state(x[i], v[i], R[i], W[i])))
            rows["pinocchio"].append(
                np.concatenate(cv.pinocchio_freeflyer_from_state(x[i], v[i], R[i], W[i]))
            )
            rows["dart"].append(np.concatenate(cv.dart_free_from_state(x[i], v[i], R[i], W[i])))
            xp, q, vp, w = cv.pybullet_base_from_state(x[i], v[i], R[i], W[i])
            rows["pybullet"].append(np.array([*xp, *q, *vp, *w]))
            rows["drake"].append(np.concatenate(cv.drake_free_from_state(x[i], v[i], R[i], W[i])))
    blocks = {
        "mujoco": cv.mujoco_block(np.array(rows["mujoco"]), 4 if pivoted else 7, COM, pivoted),
        "pinocchio": cv.pinocchio_block(
            np.array(rows["pinocchio"]), 4 if pivoted else 7, COM, pivoted
        ),
        "dart": cv.dart_block(np.array(rows["dart"]), 3 if pivoted else 6, COM, pivoted),
        "pybullet": cv.pybullet_block(np.array(rows["pybullet"]), COM, pivoted),
    }
    if not pivoted:
        blocks["drake"] = cv.drake_block(np.array(rows["drake"]), 7, COM, False)
    for name, (bx, bv, bR, bW) in blocks.items():
        # 1e-14: a quaternion or rotation-vector round trip of O(1) numbers (a few ulp) times
        # the rates' size (|W| ~ 5)
        np.testing.assert_allclose(bR, R, rtol=0, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(bW, W, rtol=0, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(bx, x, rtol=0, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(bv, v, rtol=0, atol=1e-13, err_msg=name)


def test_drake_ball_block_equals_the_per_state_conversion():
    _, _, R, W = _random_states()
    rng = np.random.default_rng(5)
    R_WF = Rotation.random(random_state=1).as_matrix()
    R_BM = Rotation.random(random_state=2).as_matrix()
    rows = [
        np.concatenate(cv.drake_ball_rpy_from_state(R[i], W[i], R_WF, R_BM)) for i in range(len(R))
    ]
    del rng
    bx, bv, bR, bW = cv.drake_block(np.array(rows), 3, COM, True, R_WF, R_BM)
    for i in range(len(R)):
        Ri, Wi = cv.drake_ball_rpy_to_state(rows[i][:3], rows[i][3:], R_WF, R_BM)
        np.testing.assert_allclose(bR[i], Ri, rtol=0, atol=1e-14)
        np.testing.assert_allclose(bW[i], Wi, rtol=0, atol=1e-14)


def test_a_non_finite_row_stays_non_finite():
    """A diverged engine state converts to NaN (the run loop reports it as diverged) instead
    of raising in the conversion."""
    raw = np.full((1, 13), np.nan)
    block = cv.mujoco_block(raw, 7, COM, False)
    assert np.isnan(block.rotation).all()
