"""Our RKMK4 helper, without any engine: dexp^{-1} against finite differences, and the order
of the method against the docs/numerics.md section 5 Dzhanibekov test vector."""

from __future__ import annotations

import numpy as np
import pytest

from references.conventions import rotvec_to_matrix, vee
from references.engines.liegroup import (
    rkmk4_step,
    so3_r3_dexpinv,
    so3_r3_integrate,
    so3_right_jacobian_inverse,
)

# docs/numerics.md section 5: I = (2, 3, 4), W0 = (0.01, 2, 0.01), R0 = 1, R(10) to 12 digits.
INERTIA = np.array([2.0, 3.0, 4.0])
W_DZ = np.array([0.01, 2.0, 0.01])
R10 = np.array(
    [
        [0.601069719933, -0.479226289446, 0.639575918311],
        [-0.541629680940, 0.344194223927, 0.766920872672],
        [-0.587666980955, -0.807386214720, -0.052678456472],
    ]
)


def right_jacobian_fd(theta, eps=1e-5):
    """J_r by central differences: column i = vee(exp(-theta) d exp(theta + s e_i)/ds)."""
    R = rotvec_to_matrix(theta)
    cols = []
    for i in range(3):
        e = np.zeros(3)
        e[i] = eps
        dR = (rotvec_to_matrix(theta + e) - rotvec_to_matrix(theta - e)) / (2 * eps)
        cols.append(vee(R.T @ dR))
    return np.column_stack(cols)


@pytest.mark.parametrize(
    "theta", [(0.3, -1.1, 0.7), (2.5, 0.4, -1.0), (1e-4, 3e-4, -2e-4), (0.0, 0.0, 0.0)]
)
def test_dexpinv_inverts_the_right_jacobian(theta):
    theta = np.asarray(theta, dtype=float)
    # central differences with eps = 1e-5: truncation ~eps^2 = 1e-10, round-off ~1e-16/eps
    assert np.allclose(
        so3_right_jacobian_inverse(theta) @ right_jacobian_fd(theta), np.eye(3), rtol=0, atol=1e-8
    )


def test_dexpinv_series_branch_is_continuous():
    # The series is used below |theta| = 1e-3. Either side of it (theta changes by 2e-15, so
    # the exact matrices differ by ~1e-15) the two formulas agree to round-off: the closed
    # form loses ~eps/|theta|^2 = 2e-10 relative in its last coefficient, times |K^2| = 1e-6.
    d = np.array([0.6, -0.8, 0.0]) * 1e-3
    below = so3_right_jacobian_inverse(d * (1 - 1e-12))
    above = so3_right_jacobian_inverse(d * (1 + 1e-12))
    assert np.allclose(below, above, rtol=0, atol=1e-14)


def torque_free_accel(q, W):
    """Euler's equations: W' = I^{-1} ((I W) x W)."""
    return np.cross(INERTIA * W, W) / INERTIA


def run_free_body(h, dexpinv, t_end=10.0):
    q = (np.eye(3),)
    W = W_DZ.copy()
    for _ in range(int(round(t_end / h))):
        q, W = rkmk4_step(q, W, h, torque_free_accel, so3_r3_integrate, dexpinv)
    return q[0]


def fitted_order(dts, errors):
    return np.polyfit(np.log(dts), np.log(errors), 1)[0]


def test_rkmk4_is_fourth_order_in_attitude():
    # dt chosen so that the errors (1e-6 .. 4e-9) are far above the 5e-13 rounding of R(10)
    dts = np.array([0.1, 0.05, 0.025])
    errors = [np.abs(run_free_body(h, so3_r3_dexpinv) - R10).max() for h in dts]
    # the slope of a 4th-order method over this sweep; 0.2 allows for the pre-asymptotic
    # part of the sweep (measured 3.94 and 3.97 for the two halvings)
    assert fitted_order(dts, errors) == pytest.approx(4.0, abs=0.2)


def test_skipping_dexpinv_is_only_second_order():
    # The naive variant (stage tangents = stage velocities) is the trap documented in
    # docs/engines.md; this shows the test above can tell the two apart.
    dts = np.array([0.1, 0.05, 0.025])
    errors = [np.abs(run_free_body(h, lambda th, v: v) - R10).max() for h in dts]
    assert fitted_order(dts, errors) == pytest.approx(2.0, abs=0.3)


# == the compiled RKMK4 against the readable one ===========================================
def _engine_or_skip(name):
    from references.engines import get_engine

    cls = get_engine(name)
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine {name!r} is not available here: {why}")
    return cls()


@pytest.mark.parametrize("scenario", ["free_tumbling", "heavy_top", "simo_wong_top"])
@pytest.mark.parametrize("name", ["pinocchio", "dart"])
def test_compiled_glue_equals_the_readable_rkmk4(monkeypatch, name, scenario):
    """The run loop's compiled RKMK4 (quaternion state, packed engine calls) and the readable
    rkmk4_step (rotation matrices, BodyState per stage) are the same method: over 1000 steps
    their trajectories agree to round-off. 1e-13: the two parametrisations round differently
    (quaternion products against 3x3 matrix products), ~1e-16 per step, growing as a random
    walk to ~1e-14 over 1e3 steps (measured <= 1.1e-14), with the problem's own growth."""
    import scenarios
    from references.engines import liegroup, stepping

    engine = _engine_or_skip(name)
    sc = scenarios.load(scenario).replace(t_end=1.0)
    fast = engine.run(sc, "RKMK4", 1e-3, save_every=50)
    monkeypatch.setattr(stepping, "_stepper", lambda e, c: liegroup.RKMK4Stepper(e, c))
    slow = engine.run(sc, "RKMK4", 1e-3, save_every=50)
    a, b = fast.trajectory, slow.trajectory
    assert fast.evals_per_step == slow.evals_per_step == 4.0
    np.testing.assert_allclose(a.rotation, b.rotation, rtol=0, atol=1e-13)
    W = np.max(np.abs(b.omega_body))
    np.testing.assert_allclose(a.omega_body, b.omega_body, rtol=0, atol=1e-13 * W)
    np.testing.assert_allclose(a.position, b.position, rtol=0, atol=1e-13)


def test_an_engine_vector_of_another_layout_is_refused():
    """The compiled unpacking reads a C-contiguous float64 vector; anything else an engine
    might return (a strided view, float32, another length, a list) is refused by name."""
    from references.engines.liegroup import check_engine_vector
    from references.errors import EngineError

    check_engine_vector(np.arange(6.0), 6, "toy")
    for bad in (np.arange(12.0)[::2], np.arange(6, dtype=np.float32), np.arange(3.0), [0.0] * 6):
        with pytest.raises(EngineError, match="toy returned"):
            check_engine_vector(bad, 6, "toy")


@pytest.mark.parametrize("pivoted", [False, True])
@pytest.mark.parametrize("engine", ["pinocchio", "dart"])
def test_a_staged_call_is_the_separate_calls_bit_for_bit(engine, pivoted):
    """The compiled stage that also unpacks the engine's accelerations and packs the next
    stage's state (``_rkmk4.<engine>_stage``, ``<engine>_finish``, on the staged workspace
    holding the slopes and the engine's buffers) computes what the separate calls compute
    (unpack, stage, pack; unpack, finish, the next stage 0 and its pack), bit for bit, on
    random states, slopes and accelerations over a whole step, the failing half turn
    included."""
    from references.engines import _rkmk4

    stage, finish = getattr(_rkmk4, f"{engine}_stage"), getattr(_rkmk4, f"{engine}_finish")
    pack, unpack = getattr(_rkmk4, f"pack_{engine}"), getattr(_rkmk4, f"unpack_{engine}")
    buffers = getattr(_rkmk4, f"{engine}_buffers")
    m = 3 if pivoted else 6
    rng = np.random.default_rng(7)
    for h in (1e-3, 0.3, 40.0):  # the last asks for rotations beyond half a turn
        w = np.zeros(_rkmk4.WORKSPACE)
        q = rng.normal(size=4)
        w[0:4] = q / np.linalg.norm(q)
        w[4:13] = rng.normal(size=9)
        staged = np.zeros(_rkmk4.STAGED_WORKSPACE)
        staged[: _rkmk4.WORKSPACE] = w
        K = np.zeros((4, 12))
        b0, b1 = (np.zeros(len(b)) for b in buffers(staged, pivoted))
        accs = [rng.normal(size=m) for _ in range(4)]
        fused, separate = [], []
        for i in range(4):
            a = accs[i - 1] if i else np.zeros(m)
            fused.append(stage(i, staged, h, pivoted, a))
            if i:
                unpack(w[_rkmk4.Z], pivoted, a, w[_rkmk4.ACC])
            separate.append(_rkmk4.stage(i, w, K, h, pivoted))
            if separate[-1] == _rkmk4.OK:
                pack(w[_rkmk4.Z], pivoted, b0, b1)
        fused.append(finish(staged, h, pivoted, accs[3]))
        unpack(w[_rkmk4.Z], pivoted, accs[3], w[_rkmk4.ACC])
        separate.append(_rkmk4.finish(w, K, h, pivoted))
        if separate[-1] == _rkmk4.OK:  # the next step's stage 0
            _rkmk4.stage(0, w, K, h, pivoted)
            pack(w[_rkmk4.Z], pivoted, b0, b1)
        assert fused == separate
        got = (staged[: _rkmk4.WORKSPACE], staged[_rkmk4.KS].reshape(4, 12),
               *buffers(staged, pivoted))  # fmt: skip
        for x, y in zip(got, (w, K, b0, b1), strict=True):
            assert np.array_equal(x, y, equal_nan=True)
        if h == 40.0:
            assert _rkmk4.TOO_LARGE in fused


def test_the_compiled_tree_rkmk4_is_the_readable_one_on_a_product_group():
    """The compiled RKMK4 of a tree (references.engines._rkmk4_tree: quaternions, DART's
    packing) against the readable rkmk4_step on the product SO(3) x R^3 (free root, body-axes
    W), SO(3) (ball joint) and R (hinge) with rotation matrices, driven by the same smooth
    acceleration field of DART's positions and velocities: 200 steps of 1e-2 agree to 1e-12
    (the two parametrisations round differently, ~1e-16 a step, a random walk over 200 steps;
    measured <= 3.6e-15). A planted slip (the free root's accelerations left in world axes) moves
    them apart by far more."""
    from references import conventions as cv
    from references.engines import _rkmk4_tree as tree
    from references.engines.liegroup import rkmk4_step, so3_right_jacobian_inverse

    tree.warm_up()  # its cache tied to _rkmk4.py first, as the builder does
    rng = np.random.default_rng(3)
    M = rng.normal(size=(10, 20)) * 0.3

    def field(pos, vel):  # DART's (pos, vel) -> DART's accelerations (world for the root)
        return np.tanh(M @ np.concatenate([pos, vel]))

    J = np.array([[tree.FREE, 0, 0, 6, 0], [tree.BALL, 7, 6, 3, 6], [tree.VECTOR, 11, 9, 1, 9]])
    r0, r1 = rng.normal(size=3), rng.normal(size=3)
    x0, hinge = rng.normal(size=3), rng.normal()
    u0 = rng.normal(size=10)
    y = np.zeros(12)
    tree.quat_of_rotvec(r0, y[0:4])
    y[4:7] = x0
    tree.quat_of_rotvec(r1, y[7:11])
    y[11] = hinge

    def compiled(h, n, world_slip=False):
        yy, u = y.copy(), u0.copy()
        zy, zu, K = yy.copy(), u.copy(), np.zeros((4, 20))
        pos, vel, a = np.zeros(10), np.zeros(10), np.zeros(10)
        for _ in range(n):
            for i in range(4):
                assert tree.stage(i, J, yy, u, zy, zu, K, h, a, pos, vel) == tree.OK
                a = field(pos, vel)
                if world_slip:  # undo the root's R^T, so the kernel sees world axes
                    R = cv.quat_wxyz_to_matrix(zy[0:4])
                    a = np.concatenate([R @ a[:3], a[3:]])
            tree.finish(J, yy, u, zy, K, h, a)
        return cv.quat_wxyz_to_matrix(yy[0:4]), cv.quat_wxyz_to_matrix(yy[7:11]), yy, u

    def accel(q, u):
        (R0, x), (R1,), (th,) = q
        p0, v0 = cv.dart_free_from_state(x, u[3:6], R0, u[0:3])
        p1, v1 = cv.dart_ball_from_state(R1, u[6:9])
        a = field(np.concatenate([p0, p1, [th]]), np.concatenate([v0, v1, u[9:]]))
        return np.concatenate([R0.T @ a[:3], a[3:]])

    def integrate(q, t):
        (R0, x), (R1,), (th,) = q
        return ((R0 @ cv.rotvec_to_matrix(t[0:3]), x + t[3:6]),
                (R1 @ cv.rotvec_to_matrix(t[6:9]),), (th + t[9],))  # fmt: skip

    def dexpinv(t, v):
        out = np.array(v, float)
        for s in (slice(0, 3), slice(6, 9)):
            out[s] = so3_right_jacobian_inverse(t[s]) @ out[s]
        return out

    q = ((cv.rotvec_to_matrix(r0), x0), (cv.rotvec_to_matrix(r1),), (hinge,))
    u = u0.copy()
    for _ in range(200):
        q, u = rkmk4_step(q, u, 1e-2, accel, integrate, dexpinv)
    R0, R1, yy, uu = compiled(1e-2, 200)
    assert np.abs(R0 - q[0][0]).max() < 1e-12 and np.abs(R1 - q[1][0]).max() < 1e-12
    assert np.abs(yy[4:7] - q[0][1]).max() < 1e-12 and abs(yy[11] - q[2][0]) < 1e-12
    assert np.abs(uu - u).max() < 1e-12
    assert np.abs(compiled(1e-2, 200, world_slip=True)[3] - u).max() > 1e-6


def test_the_tree_kernels_cache_is_keyed_on_the_stage_arithmetic_it_compiles_in():
    """numba keys a disk cache on the function's own file; the tree RKMK4 compiles in the
    quaternion and dexp^-1 arithmetic of _rkmk4.py, so its cache is tied to that file's
    content too (director_model._cache.tie; the mechanism is tested by
    tests/director_model/test_director_cache.py): every cached tree function's stamp holds
    _rkmk4.py's digest."""
    from pathlib import Path

    from director_model import _cache
    from references.engines import _rkmk4, _rkmk4_tree

    _rkmk4_tree.warm_up()  # ties them (the first warm-up of a process)
    want = _cache.digest([Path(_rkmk4.__file__)])
    for fn in (_rkmk4_tree.stage, _rkmk4_tree.finish, _rkmk4_tree.pack, _rkmk4_tree.unpack):
        assert fn._cache._cache_file._source_stamp[1] == want
    # the functions it imports from _rkmk4 keep _rkmk4's own stamp (tied, they would be
    # stale in every process that did not build a DART tree, and compiled again there)
    for fn in (_rkmk4.rotate, _rkmk4.rotvec, _rkmk4._dexpinv, _rkmk4._qexp_mul):
        assert not isinstance(fn._cache._cache_file._source_stamp, tuple)
