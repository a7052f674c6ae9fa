"""The system metrics' per-sample series and their window, against values computed by hand
from trajectories built for the purpose (no engine runs): each sample of a library system's
initial state moved in one way whose effect on every metric is a line of arithmetic.

The four-bar (scenarios/systems/four_bar.toml): crank and rocker hinged to the ground at
their anchors (-0.25, 0, 0) in their principal frames, the coupler (2 kg) hinged to both at
(-/+0.5, 0, 0) of its own; every hinge axis is the world's -y, perpendicular to the anchors'
arms. So turning a body by theta about its hinge axis through its centre of mass moves an
anchor at distance r by 2 r sin(theta / 2) and changes neither its kinetic nor its potential
energy; lifting the coupler by d opens its two joints by d and adds m g d.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import scenarios
from references import conventions as cv
from references.trajectory import Trajectory
from reports.metrics.system import compute_system_metrics, error_series

D = 1e-3  # the coupler's lift, m
A = 0.3  # the crank's turn, rad
B = 0.4  # the coupler's turn, rad
T = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
HORIZON = 0.75  # the sample at 0.75 s is in, the last one out


def _stack(sc, states):
    """A Trajectory at the times T of the states [(x, v, R, W) per body]."""
    x, v, R, W = (np.array([[b[k] for b in s] for s in states]) for k in range(4))
    return Trajectory(T[: len(states)], x, v, R, W, sc.body_names)


def _initial(sc):
    return [
        [np.array(b.position, float), np.array(b.velocity, float),
         np.array(b.rotation, float), np.array(b.omega_body, float)]
        for b in sc.bodies
    ]  # fmt: skip


def _turned(sc, state, name, theta):
    """``state`` with body ``name`` turned by theta about its own e3 (its hinge axis) through
    its centre of mass."""
    out = [list(b) for b in state]
    i = sc.body_names.index(name)
    R = out[i][2]
    out[i][2] = cv.rotvec_to_matrix(theta * R[:, 2]) @ R
    return out


def _four_bar_run():
    sc = scenarios.load("four_bar")
    s0 = _initial(sc)
    s1 = [list(b) for b in s0]
    c = sc.body_names.index("coupler")
    s1[c][0] = s1[c][0] + np.array([0.0, 0.0, D])
    s2 = _turned(sc, s0, "crank", A)
    s3 = _turned(sc, s0, "coupler", B)
    traj = _stack(sc, [s0, s1, s2, s3, s2])
    ref = SimpleNamespace(trajectory=_stack(sc, [s0] * 5), horizon=HORIZON)
    return sc, traj, ref


class _Model:
    """The scenario as a robot model's run sees it (a ``model``): error_series then adds the
    joint-coordinate series."""

    def __init__(self, sc):
        self._sc, self.model = sc, "stand-in"

    def __getattr__(self, name):
        return getattr(self._sc, name)


def test_the_four_bars_series_are_the_hand_values():
    sc, traj, ref = _four_bar_run()
    cols = error_series(sc, traj, ref)
    dE = 2.0 * 9.81 * D  # the coupler lifted by D
    np.testing.assert_allclose(cols["energy_change"], [0, dE, 0, 0, 0], rtol=1e-9, atol=1e-12)
    # the drift over the energy scale (the scale's rule: tests/scenarios/test_energy_in_play.py)
    drift = np.array([0, dE, 0, 0, 0]) / sc.energy_scale
    np.testing.assert_allclose(cols["energy_drift"], drift, rtol=1e-9, atol=1e-15)
    # the crank's anchors 0.25 m from its centre, the coupler's 0.5 m
    gaps = [0, D, 0.5 * math.sin(A / 2), math.sin(B / 2), 0.5 * math.sin(A / 2)]
    np.testing.assert_allclose(cols["joint_gap"], gaps, rtol=1e-9, atol=1e-15)
    # the loop closure B1 joins rocker and coupler: the crank's turn leaves it closed
    loop = [0, D, 0, math.sin(B / 2), 0]
    np.testing.assert_allclose(cols["loop_gap"], loop, rtol=1e-9, atol=1e-15)
    assert np.all(cols["orthonormality"] < 1e-14)
    assert "momentum_drift" not in cols  # a closed loop conserves no momentum
    # the attitude error within the horizon, NaN beyond it
    np.testing.assert_allclose(cols["attitude_error"][:4], [0, 0, A, B], rtol=1e-9, atol=1e-12)
    assert math.isnan(cols["attitude_error"][4])
    assert "joint_coordinate_error" not in cols  # not a robot model's run


def test_without_a_reference_there_is_no_error_series():
    sc, traj, _ = _four_bar_run()
    cols = error_series(sc, traj)
    assert "attitude_error" not in cols and "joint_gap" in cols


def test_the_horizon_includes_a_sample_at_it_to_round_off():
    """A sample at the horizon is judged (<=), also when the horizon is a rounding below it
    (1e-12 relative); the attitude error there (B) is the largest."""
    sc, traj, ref = _four_bar_run()
    # the last: the horizon whose rounding margin lands exactly on the sample's time
    h_exact = 0.7499999999992499
    assert h_exact * (1 + 1e-12) == HORIZON
    for h in (HORIZON, HORIZON * (1 - 5e-13), h_exact):
        ref.horizon = h
        assert error_series(sc, traj, ref)["attitude_error"][3] == pytest.approx(B, rel=1e-9)
        vals = compute_system_metrics(sc, traj, ref)
        assert vals["attitude_error_max"] == pytest.approx(B, rel=1e-9)
    ref.horizon = 0.5  # the coupler's turn at 0.75 s is beyond it
    assert compute_system_metrics(sc, traj, ref)["attitude_error_max"] == pytest.approx(A, rel=1e-9)
    assert np.isnan(error_series(sc, traj, ref)["attitude_error"][3])


def test_a_robot_models_run_gets_each_joints_coordinate_error():
    """Turning the crank changes the relative rotation of its two joints by A, turning the
    coupler that of its two by B (each about the joints' common axis)."""
    sc, traj, ref = _four_bar_run()
    cols = error_series(_Model(sc), traj, ref)
    want = {"A0": [0, 0, A, 0], "B0": [0, 0, 0, 0], "A1": [0, 0, A, B], "B1": [0, 0, 0, B]}
    for name, w in want.items():
        e = cols[f"joint_coordinate_error.{name}"]
        np.testing.assert_allclose(e[:4], w, rtol=1e-9, atol=1e-12)
        assert math.isnan(e[4])
    np.testing.assert_allclose(cols["joint_coordinate_error"][:4], [0, 0, A, B], rtol=1e-9,
                               atol=1e-12)  # fmt: skip
    assert math.isnan(cols["joint_coordinate_error"][4])


def test_kept_series_are_reused_as_they_are():
    """error_series takes a series compute_system_metrics kept instead of computing it
    again: the very object (a stand-in array here, never what the function would give)."""
    sc, traj, ref = _four_bar_run()
    kept = {name: np.full(5, k + 0.5) for k, name in enumerate(
        ("orthonormality_max", "energy_drift_max", "joint_gap_max"))}  # fmt: skip
    cols = error_series(sc, traj, ref, kept=kept)
    assert cols["orthonormality"] is kept["orthonormality_max"]
    assert cols["energy_drift"] is kept["energy_drift_max"]
    assert cols["joint_gap"] is kept["joint_gap_max"]
    free = scenarios.load("free_chain_5")
    ftraj = _stack(free, [_initial(free)] * 2)
    mark = np.array([7.0, 8.0])
    assert error_series(free, ftraj, kept={"momentum_drift_max": mark})["momentum_drift"] is mark


def test_compute_keeps_the_series_not_against_the_reference():
    sc, traj, ref = _four_bar_run()
    keep = {}
    compute_system_metrics(sc, traj, ref, keep=keep)
    assert "joint_gap_max" in keep and "energy_drift_max" in keep
    assert "attitude_error_max" not in keep and "position_error_max" not in keep
    np.testing.assert_allclose(keep["joint_gap_max"], error_series(sc, traj)["joint_gap"])


def test_a_floating_chains_momentum_series():
    """free_chain_5 (no gravity): a body's velocity changed by dv along its arm from the
    system's centre of mass changes p by m dv and the angular momentum about the centre of
    mass by m (x - x_G) x dv = 0: the drift is m |dv| / p_c."""
    sc = scenarios.load("free_chain_5")
    s0 = _initial(sc)
    s1 = [list(b) for b in s0]
    i = 2
    m = sc.bodies[i].mass
    arm = s1[i][0] - np.array(sc.centre_of_mass)
    dv = 0.1 * arm / np.linalg.norm(arm)
    s1[i][1] = s1[i][1] + dv
    cols = error_series(sc, _stack(sc, [s0, s1]))
    np.testing.assert_allclose(cols["momentum_drift"], [0, m * 0.1 / sc.linear_momentum_scale],
                               rtol=1e-9, atol=1e-15)  # fmt: skip
    v = np.asarray(sc.bodies[i].velocity)
    dE = 0.5 * m * ((v + dv) @ (v + dv) - v @ v)
    np.testing.assert_allclose(cols["energy_change"], [0, dE], rtol=1e-9, atol=1e-15)
    assert "loop_gap" not in cols  # a tree


def test_the_orthonormality_series_sees_a_stretched_rotation():
    """R scaled by (1 + e): ||R^T R - 1||_F = sqrt(3) ((1 + e)^2 - 1)."""
    sc = scenarios.load("four_bar")
    s0 = _initial(sc)
    s1 = [list(b) for b in s0]
    e = 1e-6
    s1[1][2] = (1 + e) * s1[1][2]
    cols = error_series(sc, _stack(sc, [s0, s1]))
    assert cols["orthonormality"][1] == pytest.approx(math.sqrt(3) * ((1 + e) ** 2 - 1), rel=1e-6)


def test_a_reference_at_other_times_is_refused():
    """The window needs the reference at the run's own times, to 1e-9 s absolute: its last
    sample (t = 1 s) 5e-9 s off, or a sample missing, and it is refused."""
    sc, traj, _ = _four_bar_run()
    for n, shift in ((5, 5e-9), (4, 0.0)):
        r = _stack(sc, [_initial(sc)] * n)
        r.t = r.t.copy()
        r.t[-1] += shift
        with pytest.raises(ValueError, match="^the system reference is sampled at other times "
                           "than the run$"):  # fmt: skip
            compute_system_metrics(sc, traj, SimpleNamespace(trajectory=r, horizon=HORIZON))


def test_energy_is_not_judged_where_a_torqued_joint_turns_too_far_between_states():
    """Andrews' squeezer (A03, a constant torque on joint 'O'): its body a turned about the
    joint's axis by 1 rad per saved state is counted; a step of 2 rad (> pi / 2) could be a
    turn the other way (its work tau theta would be miscounted), so the drift is not
    measured."""
    sc = scenarios.load("iftomm_a03")
    j = next(j for j in sc.joints if j.name == sc.torques[0].joint)
    i = sc.body_names.index(j.body_a)
    s0 = _initial(sc)
    u = s0[i][2] @ np.asarray(j.axis_a, float)

    def turned(theta):
        s = [list(b) for b in s0]
        s[i][2] = cv.rotvec_to_matrix(theta * u / np.linalg.norm(u)) @ s[i][2]
        return s

    ok = error_series(sc, _stack(sc, [s0, turned(1.0), turned(2.0)]))
    assert "energy_drift" in ok and len(ok["energy_drift"]) == 3
    far = error_series(sc, _stack(sc, [s0, turned(1.0), turned(3.0)]))
    assert "energy_drift" not in far
    vals = compute_system_metrics(sc, _stack(sc, [s0, turned(1.0), turned(3.0)]))
    assert math.isnan(vals["energy_drift_max"])
