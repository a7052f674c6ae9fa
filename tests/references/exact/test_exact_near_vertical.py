"""The Lagrange-top reference near and away from the vertical against an independent
integration, and the hand-over rules: a kind that does not apply is refused when asked for
and handed over to the numerical reference (with the reason recorded) under "auto"; a file
asking for "numerical" never builds a LagrangeTop; expected_observables never raises.

The independent integration (:func:`rigid_body_dop853`) is written here: DOP853 at rtol 1e-13
on the nine entries of R and the body rates, R' = R hat(W), I_p W' = tau - W x I_p W, a
different state from the numerical reference's quaternion (references/exact/numerical.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import references.exact as exact
import scenarios
from references.exact import (
    ReferenceNotApplicable,
    expected_observables,
    reference_trajectory,
    resolve_kind,
)
from references.exact._util import rotation_angle
from references.trajectory import one_body
from scenarios.model import Scenario


def rigid_body_dop853(sc, t, rtol=1e-13):
    """R (n, 3, 3) and W (n, 3) of scenario ``sc`` at times ``t`` by DOP853 on (R, W)."""
    m = sc.mass
    c = np.zeros(3) if sc.pivot is None else np.asarray(sc.pivot, dtype=float)
    Ip = np.diag(sc.inertia) + m * (c @ c * np.eye(3) - np.outer(c, c))
    Ip_inv = np.linalg.inv(Ip)
    mg = m * np.asarray(sc.gravity, dtype=float)

    def rhs(_t, y):
        R = y[:9].reshape(3, 3)
        W = y[9:]
        Wx = np.array([[0.0, -W[2], W[1]], [W[2], 0.0, -W[0]], [-W[1], W[0], 0.0]])
        torque = np.cross(-c, R.T @ mg) if sc.pivot is not None else np.zeros(3)
        return np.concatenate([(R @ Wx).ravel(), Ip_inv @ (torque - np.cross(W, Ip @ W))])

    W0 = np.asarray(sc.omega_body, dtype=float)
    wscale = np.linalg.norm(W0) + math.sqrt(
        np.linalg.norm(mg) * np.linalg.norm(c) / np.linalg.eigvalsh(Ip)[0]
    )
    y0 = np.concatenate([np.asarray(sc.rotation, dtype=float).ravel(), W0])
    atol = rtol * np.concatenate([np.ones(9), np.full(3, wscale)])
    sol = solve_ivp(rhs, (0.0, float(t[-1])), y0, method="DOP853", t_eval=t, rtol=rtol, atol=atol)
    assert sol.status == 0
    return sol.y[:9].T.reshape(-1, 3, 3), sol.y[9:].T


def _passage_times(sc, count):
    """Times at which the axis is closest to the downward vertical, located on the independent
    solution (a fine grid, then the parabola through the three samples around each minimum
    of 1 + u)."""
    t = np.linspace(0.0, 0.04 * count, 4000 * count + 1)
    R, _ = rigid_body_dop853(sc, t)
    up = -sc.gravity / np.linalg.norm(sc.gravity)
    s = 1.0 + R[:, :, 2] @ up  # 1 + u
    i = np.flatnonzero((s[1:-1] < s[:-2]) & (s[1:-1] <= s[2:])) + 1
    i = i[s[i] < 1e-3][:count]
    d0, d1 = s[i] - s[i - 1], s[i + 1] - s[i]
    h = t[1] - t[0]
    return t[i] + 0.5 * h * (d0 + d1) / (d0 - d1)


def test_near_vertical_scenario_passes_within_1e6_rad_of_the_vertical():
    # the file's claim, checked on the independent solution: sample densely around the first
    # passage; the closest approach of the axis to the downward vertical is 1e-6 rad
    sc = scenarios.load("near_vertical_top")
    tp = _passage_times(sc, 1)[0]
    t = np.sort(
        np.concatenate([np.linspace(0.0, tp - 1e-4, 50), tp + np.linspace(-2e-6, 2e-6, 4001)])
    )
    R, _ = rigid_body_dop853(sc, t)
    down = sc.gravity / np.linalg.norm(sc.gravity)
    angle = np.arctan2(np.linalg.norm(np.cross(R[:, :, 2], down), axis=1), R[:, :, 2] @ down)
    # grid step 1e-9 s at an axis speed of ~27 rad/s: the sampled minimum is within 1e-15 rad
    # (quadratic in the step) of the true one; DOP853's error is ~1e-12
    assert angle.min() == pytest.approx(1e-6, rel=1e-4)


def test_near_vertical_top_against_an_independent_integration():
    # regression for "trapezoidal rule did not converge": the attitude and rates through the
    # passages, sampled at the passages themselves, 40 ns after them and on a grid
    sc = scenarios.load("near_vertical_top")
    tp = _passage_times(sc, 3)
    t = np.sort(np.concatenate([np.linspace(0.0, 0.5, 101), tp, tp + 4e-8, tp - 1e-7]))
    ref = reference_trajectory(sc, t)
    assert (
        ref.kind == "lagrange_top"
        and ref.reason == "lagrange_top: auto, a symmetric top pivoted on its axis"
    )
    R, W = rigid_body_dop853(sc, t)
    err = rotation_angle(one_body(ref).rotation, R).max()
    werr = np.abs(one_body(ref).omega_body - W).max()
    # required: 1e-9; measured 1.9e-12 rad and 5.4e-13 rad/s (|W| = 123 rad/s): the independent
    # solution's error
    assert err < 1e-9 and werr < 1e-9 * 123
    assert err <= ref.accuracy + 1e-11  # 1e-11: the independent solution's own error


def test_a_top_released_at_its_closest_approach():
    # the same top started 1e-6 rad from the downward vertical at a turning point (the tilt
    # rate zero): the initial Euler frame is then set from a tiny transverse part of up
    R0 = Rotation.from_rotvec([math.pi - 1e-6, 0.0, 0.0]).as_matrix()
    sc = Scenario(name="t", description="", mass=1.0, inertia=[0.011, 0.011, 0.02],
                  rotation=R0, omega_body=[20.0, 0.0, 120.0], gravity=[0.0, 0.0, -9.81],
                  pivot=[0.0, 0.0, -0.05], t_end=0.2, dt=1e-3)  # fmt: skip
    t = np.linspace(0.0, 0.2, 201)
    ref = reference_trajectory(sc, t)
    R, W = rigid_body_dop853(sc, t)
    assert ref.kind == "lagrange_top"
    # measured 7.3e-13 rad, 1.6e-13 rad/s
    assert rotation_angle(one_body(ref).rotation, R).max() < 1e-9
    assert np.abs(one_body(ref).omega_body - W).max() < 1e-9 * 123


@pytest.mark.parametrize("name, t_end", [("heavy_top", 1.0), ("simo_wong_top", 3.0)])
def test_lagrange_tops_away_from_the_vertical_against_an_independent_integration(name, t_end):
    sc = scenarios.load(name)
    t = np.linspace(0.0, t_end, 101)
    ref = reference_trajectory(sc, t)
    R, W = rigid_body_dop853(sc, t)
    # required: 1e-9; measured 3.3e-12 (heavy_top), 4.3e-12 (simo_wong) rad
    assert rotation_angle(one_body(ref).rotation, R).max() < 1e-9
    assert np.abs(one_body(ref).omega_body - W).max() < 1e-9 * np.abs(W).max()


def _with_kind(tmp_path, name, kind):
    """A copy of a library file with ``[reference] kind`` set."""
    text = (scenarios.library_path() / f"{name}.toml").read_text()
    assert "[reference]" not in text
    path = tmp_path / f"{name}.toml"
    path.write_text(text + f'\n[reference]\nkind = "{kind}"\n')
    return scenarios.load(str(path))


def test_a_file_asking_for_numerical_builds_no_lagrange_top(tmp_path, monkeypatch):
    sc = _with_kind(tmp_path, "near_vertical_top", "numerical")

    def forbidden(*args, **kwargs):
        raise AssertionError("a LagrangeTop was built for a file asking for numerical")

    monkeypatch.setattr(exact, "LagrangeTop", forbidden)
    assert resolve_kind(sc) == "numerical"
    assert expected_observables(sc) == {}
    ref = reference_trajectory(sc, np.linspace(0.0, 0.05, 6))
    assert ref.kind == "numerical"
    assert ref.reason == "numerical: requested by the scenario's reference.kind"
    assert 0 < ref.accuracy < 1e-9


def test_expected_observables_never_raise():
    # every library file under every kind, applicable or not
    for name in scenarios.list_scenarios():
        sc = scenarios.load(name)
        for kind in ("auto", "free_body", "lagrange_top", "steady_precession", "numerical"):
            out = expected_observables(sc.replace(reference=kind))
            assert all(math.isfinite(v) for v in out.values()), (name, kind, out)


def _vertical_start(**kw):
    base = dict(name="v", description="", mass=1.0, inertia=[0.011, 0.011, 0.02],
                rotation=np.eye(3), omega_body=[2.0, 1.0, 50.0], gravity=[0.0, 0.0, -9.81],
                pivot=[0.0, 0.0, -0.05], t_end=0.5, dt=1e-3)  # fmt: skip
    base.update(kw)
    return Scenario(**base)


def test_auto_hands_over_to_numerical_with_the_reason():
    # a spinning top started exactly upright with a transverse rate: the Euler angles about
    # the vertical are undefined at t = 0, a case the closed form does not treat
    sc = _vertical_start()
    with pytest.raises(ReferenceNotApplicable, match="starts exactly vertical"):
        reference_trajectory(sc, [0.0, 0.1], kind="lagrange_top")
    assert resolve_kind(sc) == "numerical"
    t = np.linspace(0.0, 0.5, 51)
    ref = reference_trajectory(sc, t)
    assert ref.kind == "numerical"
    assert ref.reason.startswith("numerical: auto, gravity torques the body about its pivot")
    assert "starts exactly vertical" in ref.reason
    R, _ = rigid_body_dop853(sc, t)
    assert rotation_angle(one_body(ref).rotation, R).max() <= ref.accuracy + 1e-11
    assert expected_observables(sc) == {}


def test_states_the_closed_form_treats_at_the_vertical():
    # spinning exactly upright without transverse rate: R = R0 Rot(e3, W3 t), exactly
    sc = _vertical_start(omega_body=[0.0, 0.0, 50.0])
    ref = reference_trajectory(sc, [0.0, 0.3])
    expect = Rotation.from_rotvec([0.0, 0.0, 15.0]).as_matrix()
    assert ref.kind == "lagrange_top" and "steady precession" in ref.reason
    assert rotation_angle(one_body(ref).rotation[1:], expect[None])[0] < 1e-14  # 15 rad turned
    # no spin, a kick from upright: a planar pendulum swinging over the top
    sc = _vertical_start(omega_body=[2.0, 1.0, 0.0])
    t = np.linspace(0.0, 0.5, 51)
    ref = reference_trajectory(sc, t)
    assert ref.kind == "lagrange_top" and "pendulum" in ref.reason
    R, _ = rigid_body_dop853(sc, t)
    assert rotation_angle(one_body(ref).rotation, R).max() < 1e-9  # measured 6.2e-13
