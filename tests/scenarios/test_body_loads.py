"""scenarios.force_elements.body_loads: the loads an engine without force elements of its own
applies, against the spatial arm's numbers worked by hand and against the power balance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.force_elements import body_loads
from scenarios.system_file import validate_system
from tests.references.exact.test_multibody_forces import arm_file


def _state(sc):
    x = np.array([b.position for b in sc.bodies])
    R = np.array([b.rotation for b in sc.bodies])
    v = np.array([b.velocity for b in sc.bodies])
    W = np.array([b.omega_body for b in sc.bodies])
    return x, R, v, W


@pytest.mark.parametrize("c", [0.0, 0.4])
def test_the_arm_at_t0_by_hand(c):
    """Rod (index 1) at (0.8, 0, -0.3), unturned, spring point p_a = (0.8, 0, -0.6), world
    point p_b = (1, 0.5, -1): d = (-0.2, -0.5, 0.4), l = sqrt(0.45); the rod's point moves at
    v + w x r = (0, 1.75, 0) + (0.5, 0, 2.5) x (0, 0, -0.3) = (0, 1.9, 0), so l' = -0.5 * 1.9 / l.
    Torques: 0.2 about z on the arm (hinge h to the ground), -0.1 about u = (1, 0, 1)/sqrt 2 on
    the rod and +0.1 u on the arm (hinge k)."""
    sc = validate_system(arm_file(c))
    F, T = body_loads(sc, *_state(sc))
    d = np.array([-0.2, -0.5, 0.4])
    length = math.sqrt(0.45)
    e = d / length
    rate = -0.5 * 1.9 / length
    Fa = -(30.0 * (length - 0.5) + c * rate) * e
    u = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    np.testing.assert_allclose(F[0], 0.0, atol=1e-15)
    np.testing.assert_allclose(F[1], Fa, rtol=1e-14)
    np.testing.assert_allclose(T[1], np.cross([0.0, 0.0, -0.3], Fa) - 0.1 * u, rtol=1e-14,
                               atol=1e-15)  # fmt: skip
    np.testing.assert_allclose(T[0], [0.0, 0.0, 0.2] + 0.1 * u, rtol=1e-14)


def test_the_loads_do_the_elements_power():
    """sum F . v + T . w = -(k (l - l0) + c l') l' + sum tau (w_a - w_b) . u at a turned, moving
    state: the loads are the elements' (their points, arms and signs) whatever the state."""
    sc = validate_system(arm_file(0.4))
    rng = np.random.default_rng(3)
    x, R, v, W = _state(sc)
    x = x + rng.normal(size=x.shape) * 0.1
    v = rng.normal(size=v.shape)
    W = rng.normal(size=W.shape)
    R = np.array([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2)])
    R *= np.sign(np.linalg.det(R))[:, None, None]
    F, T = body_loads(sc, x, R, v, W)
    w = np.einsum("nij,nj->ni", R, W)
    power = float(np.sum(F * v) + np.sum(T * w))
    pa = x[1] + R[1] @ np.array([0.0, 0.0, -0.3])
    va = v[1] + np.cross(w[1], R[1] @ np.array([0.0, 0.0, -0.3]))
    d = pa - np.array([1.0, 0.5, -1.0])
    length = np.linalg.norm(d)
    rate = d @ va / length
    want = -(30.0 * (length - 0.5) + 0.4 * rate) * rate
    u_h = R[0] @ np.array([0.0, 0.0, 1.0])
    u_k = R[1] @ (np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0))
    want += 0.2 * w[0] @ u_h - 0.1 * (w[1] - w[0]) @ u_k
    assert power == pytest.approx(want, rel=1e-13, abs=1e-13)


def test_only_the_loaded_bodies_states_are_read():
    """IFToMM A03 (a spring from the triangle to a ground point, the motor torque between the
    crank and the ground): loaded_bodies names the triangle and the crank alone (read from
    the file, not from the code), body_loads gives every other body no load, and NaN in the
    other bodies' states changes nothing (the planted mistake, reading every body, fails)."""
    import scenarios
    from scenarios.force_elements import loaded_bodies

    sc = scenarios.load("iftomm_a03")
    names = [b.name for b in sc.bodies]
    loaded = loaded_bodies(sc)
    assert [names[i] for i in loaded] == ["crank", "triangle"]  # the file's order
    x, R, v, W = _state(sc)
    F, T = body_loads(sc, x, R, v, W)
    others = [i for i in range(len(names)) if i not in loaded]
    assert not F[others].any() and not T[others].any()
    for a in (x, R, v, W):
        a[others] = np.nan
    F2, T2 = body_loads(sc, x, R, v, W)
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_array_equal(T2, T)
