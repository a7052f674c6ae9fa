"""The Drake adapter's chart of a pivoted body (references.engines.drake): the roll-pitch-yaw
chart it picks to keep the library's pivoted bodies away from its singularity, the switches
to the other chart on the way (at the time a hand computation gives), the state continuous
across a switch, Drake's own step and evaluation counts summed over the switches, the model
read back after one. Checked against Drake's own kinematics and counters and the exact
solutions of references.exact; skipped with the reason when Drake is not installed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from references.engines import conformance as kit
from references.engines import get_engine
from references.engines.context import BodyModel
from references.errors import Diverged, Unsupported
from references.exact import reference_trajectory
from references.trajectory import one_body
from tests.references.engines.drake_helpers import EPS, _angle, _built, drake_engine


@pytest.fixture(scope="module")
def drake():
    return drake_engine()


# -- the RPY chart of pivoted bodies ------------------------------------------------------------


PIVOTED = [
    "heavy_top",
    "cone_top",
    "simo_wong_top",
    "pendulum_through_vertical",
    "near_vertical_top",
]


#: the chart each library pivoted body gets: the COM axis as the roll axis where its tilt band
#: keeps it off the vertical (sin(tilt) >= ROLL_AXIS_MIN_SIN), else a perpendicular
ROLL_IS_COM_AXIS = {
    "heavy_top": True,
    "cone_top": True,
    "simo_wong_top": False,  # tilt 0.05 rad
    "pendulum_through_vertical": False,  # swings through the downward vertical
    "near_vertical_top": False,  # comes within 1e-6 rad of the downward vertical
}


@pytest.mark.parametrize("name", PIVOTED)
def test_chart_keeps_the_library_pivoted_bodies_far_from_its_singularity(drake, name):
    """The tilt band from the first integrals equals the exact motion's (references.exact,
    20001 times over the horizon; to 1e-7: a steady precession's double root comes out of the
    cubic to about sqrt(eps), and the samples miss the pendulum's lowest point by 1.1e-8);
    over the exact motion the chart's |cos pitch| stays >= 0.45, above CHART_SWITCH_COS, so
    the exact motions of the library's pivoted bodies never switch charts (the tightest is
    heavy_top with the COM axis as roll axis: |cos pitch| = sin(tilt) >= sin(0.512) = 0.47)."""
    from references.engines.drake import CHART_SWITCH_COS, lagrange_tilt_band, rpy_chart

    sc = scenarios.load(name)
    mdl = BodyModel.of(sc, sc.dt)
    R_WF, R_BM, why = rpy_chart(mdl, sc.rotation, sc.omega_body)
    assert np.abs(R_WF.T @ R_WF - np.eye(3)).max() <= 4 * EPS
    assert np.abs(R_BM.T @ R_BM - np.eye(3)).max() <= 4 * EPS
    c = mdl.com / np.linalg.norm(mdl.com)
    assert np.allclose(R_BM[:, 0], c, atol=1e-15) == ROLL_IS_COM_AXIS[name], why
    ref = reference_trajectory(sc, np.linspace(0.0, sc.t_end, 20001))
    up = -mdl.gravity / np.linalg.norm(mdl.gravity)
    u = np.einsum("nij,j,i->n", one_body(ref).rotation, c, up)
    band = lagrange_tilt_band(mdl, sc.rotation, sc.omega_body)
    assert band[0] == pytest.approx(u.min(), abs=1e-7)
    assert band[1] == pytest.approx(u.max(), abs=1e-7)
    sin_pitch = np.einsum("i,nij,j->n", R_WF[:, 2], one_body(ref).rotation, R_BM[:, 0])
    min_cos = float(np.sqrt(1.0 - sin_pitch**2).min())
    assert min_cos >= 0.45 > CHART_SWITCH_COS


def test_chart_is_not_guessed_for_other_bodies(drake):
    """No first integrals give the tilt band of an asymmetric body or an off-axis pivot: the
    chart at t = 0 is then the perpendicular one, and chart switching takes it from there."""
    from references.engines.drake import lagrange_tilt_band, rpy_chart

    sc = kit.pivoted_scenario()
    mdl = BodyModel.of(sc, sc.dt)
    assert lagrange_tilt_band(mdl, sc.rotation, sc.omega_body) is None
    R_WF, R_BM, why = rpy_chart(mdl, sc.rotation, sc.omega_body)
    assert abs(R_BM[:, 0] @ mdl.com) <= 1e-15 and "perpendicular" in why


def test_the_chart_decides_drakes_accuracy_on_a_top(drake):
    """Why the COM axis is the roll axis where it can be: on cone_top, with the spin as roll
    and the precession as yaw, runge_kutta3 at dt = 1e-3 follows the exact steady precession
    to 1.1e-4 rad (measured) without a chart switch; with the perpendicular chart all three
    angles swing at the spin rate and the same run ends 2.2 rad off (measured, after one
    switch). Bound: 10x the measured error."""
    sc = scenarios.load("cone_top")
    out = drake().run(sc, "runge_kutta3", sc.dt)
    ref = reference_trajectory(sc, out.trajectory.t)
    assert _angle(one_body(out.trajectory).rotation, one_body(ref).rotation).max() <= 1.1e-3
    assert out.settings["RPY chart switches"] == 0


# -- chart switching ----------------------------------------------------------------------------


def _steady_rotation(w):
    """No gravity (the chart's yaw axis is e_z), the COM on body z above the pivot, R0 = 1, a
    steady rotation at w about the principal axis x. The chart at t = 0 has roll axis e_y, so
    the motion is pure pitch, pitch = -w t, and |cos pitch| = |cos w t|."""
    return kit.pivoted_scenario(
        rotation=np.eye(3), omega_body=[w, 0.0, 0.0], gravity=[0.0, 0.0, 0.0], pivot=[0, 0, -0.2]
    )


def test_a_steady_rotation_switches_chart_once(drake):
    """|cos w t| falls below CHART_SWITCH_COS at t* = acos(CHART_SWITCH_COS)/w: the run must
    switch at the end of the first step after t*, to a chart whose roll axis is the (horizontal)
    rotation axis x (centred_chart: w is horizontal), in which the rest of the motion is pure
    roll and never switches again. RK5 integrates the linear angles exactly, so the attitude
    stays on Rx(w t) to round-off (bound: 1000 steps x eps x w t = 7e-13, rounded up to
    1e-12)."""
    from references.engines.drake import CHART_SWITCH_COS
    from references.engines.stepping import initial_state

    w, dt = 3.0, 1e-3
    sc = _steady_rotation(w)
    eng, ctx = _built(drake, sc, "runge_kutta5", dt)
    assert "perpendicular" in ctx.handle.chart
    eng.advance(ctx, 1000)
    h = ctx.handle
    (t_switch, cos_at_switch), *others = h.switches
    t_star = math.acos(CHART_SWITCH_COS) / w
    assert not others
    assert t_star <= t_switch <= t_star + dt + 1e-12
    assert cos_at_switch == pytest.approx(abs(math.cos(w * t_switch)), abs=1e-12)
    assert np.allclose(h.R_BM[:, 0], [1.0, 0.0, 0.0], atol=1e-15)
    t = h.t
    Rx = np.array([[1, 0, 0], [0, math.cos(w * t), -math.sin(w * t)], [0, math.sin(w * t), 0]])
    Rx[2, 2] = math.cos(w * t)
    state = eng.read_state(ctx)
    assert np.abs(state.rotation - Rx).max() <= 1e-12
    assert np.abs(state.omega_body - initial_state(sc).omega_body).max() <= 1e-12 * w
    eng.close(ctx)


def test_a_step_into_the_singular_set_is_a_step_failure(drake):
    """The steady rotation with w dt = pi/4: runge_kutta2's first step ends at pitch -pi/4
    (|cos| = 0.71, no switch), and the second stage of its second step lies at -pi/2, the
    singular set, where Drake refuses to evaluate: one step that turns the body by more than
    the 23.6 degrees between the switching level and the singular set is a real failure of
    the step, and the run ends as diverged at the step's start, t = dt."""
    w = 3.0
    dt = math.pi / 4 / w
    with pytest.raises(Diverged) as info:
        drake().run(_steady_rotation(w), "runge_kutta2", dt, t_end=8 * dt, save_every=1)
    assert info.value.t_diverged == pytest.approx(dt, rel=1e-15)
    msg = str(info.value)
    assert "within one step of drake runge_kutta2" in msg and "singularity" in msg


def _wobbly_top():
    """An asymmetric top pivoted off every principal axis, spinning at about 30 rad/s: not a
    Lagrange top (the reference is numerical), and it falls through the horizontal (cos of
    the COM axis's tilt from 0.996 down to -0.29 over 3 s), so every fixed chart meets its
    singular set (the chart chosen at t = 0 at t = 0.085 s)."""
    return scenarios.validate(
        {
            "name": "wobbly_top",
            "description": "An asymmetric top pivoted off every principal axis.",
            "tags": ["top"],
            "body": {"mass": 0.7, "inertia": [0.0021, 0.0033, 0.0040]},
            "initial": {"rotation_vector": [0.3, -0.2, 0.1], "omega_body": [1.5, -2.0, 30.0]},
            "environment": {"gravity": [0.0, 0.0, -9.81], "pivot": [0.01, -0.02, -0.06]},
            "run": {"t_end": 3.0, "dt": 1e-3, "save_every": 10},
        }
    )


@pytest.fixture(scope="module")
def wobbly():
    """(the wobbly top, its reference at the saved times 0, 0.01, ..., 3 s)."""
    sc = _wobbly_top()
    return sc, reference_trajectory(sc, np.linspace(0.0, sc.t_end, 301))


def test_an_asymmetric_top_runs_through_chart_switches(drake, wobbly):
    """runge_kutta5 at dt = 1e-3 over 3 s runs ok, switching charts (measured 10 times), and
    follows the numerical reference (accuracy 2.6e-10) to 2.4e-10 rad (measured). Bound:
    MuJoCo's RK4 on the same body at the same step (an independent engine, one order lower:
    2.8e-8 measured): a switch that broke the state's continuity, or a chart left near its
    singular set, would cost far more than that order."""
    sc, ref = wobbly
    out = drake().run(sc, "runge_kutta5", sc.dt)
    assert out.nstep == 3000 and out.settings["RPY chart switches"] >= 1
    from references.engines.drake import CHART_SWITCH_COS

    assert 0.3 < out.settings["RPY chart smallest |cos pitch|"] < CHART_SWITCH_COS
    err = _angle(one_body(out.trajectory).rotation, one_body(ref).rotation).max()
    rk4 = one_body(get_engine("mujoco")().run(sc, "RK4", sc.dt).trajectory)
    err_rk4 = _angle(rk4.rotation, one_body(ref).rotation).max()
    assert err <= err_rk4, (err, err_rk4)


def _drake_view(h):
    """Drake's own pose and spatial velocity of the body (its kinematics of its own q, v)."""
    X = h.plant.EvalBodyPoseInWorld(h.context, h.body)
    V = h.plant.EvalBodySpatialVelocityInWorld(h.context, h.body)
    return X.rotation().matrix().copy(), V.rotational().copy(), h.context.get_time()


@pytest.mark.parametrize("name", ["runge_kutta5", "discrete SAP", "cenic"])
def test_the_state_is_continuous_across_a_switch(drake, wobbly, monkeypatch, name):
    """Just before and just after every switch of the wobbly top's run: the same time, the
    same body orientation and angular velocity (Drake's own kinematics of the old and the new
    plant; for CENIC, whose plant leaves its pose cache a step behind, the adapter's
    read-back), and the new chart's angles are all 0. Tolerance 1e-14 relative (45 eps): the
    roll and yaw angles grow to tens of radians between switches, and the sine and cosine of
    an angle x carry an error of about |x| eps (measured: up to 11 eps in R, 26 eps in W)."""
    from references.engines.drake import DrakeEngine

    pairs = []
    switch = DrakeEngine._switch_chart

    def spy(self, ctx):
        h = ctx.handle
        before = (_drake_view(h), self.read_state(ctx))
        switch(self, ctx)
        after = (_drake_view(h), self.read_state(ctx))
        pairs.append((before, after, h.plant.GetPositions(h.context)))

    monkeypatch.setattr(DrakeEngine, "_switch_chart", spy)
    sc, _ = wobbly
    out = drake().run(sc, name, sc.dt)
    assert len(pairs) == out.settings["RPY chart switches"] >= 1
    for ((R0, w0, t0), s0), ((R1, w1, t1), s1), q in pairs:
        scale = np.linalg.norm(w0)
        assert t1 == t0
        if name != "cenic":
            assert np.abs(R1 - R0).max() <= 1e-14
            assert np.abs(w1 - w0).max() <= 1e-14 * scale
        assert np.abs(s1.rotation - s0.rotation).max() <= 1e-14
        assert np.abs(s1.omega_body - s0.omega_body).max() <= 1e-14 * scale
        assert np.abs(q).max() <= 16 * EPS


def _counts(h):
    """The current Simulator's own counts, read from Drake."""
    sim, integ = h.simulator, h.integrator
    if integ is None:
        return {
            "steps": sim.get_num_steps_taken(),
            "updates": sim.get_num_discrete_updates() + sim.get_num_unrestricted_updates(),
        }
    return {
        "steps": integ.get_num_steps_taken(),
        "evals": integ.get_num_derivative_evaluations(),
        "rejected": integ.get_num_step_shrinkages_from_error_control()
        + integ.get_num_step_shrinkages_from_substep_failures(),
        "largest": integ.get_largest_step_size_taken(),
        "smallest": integ.get_smallest_adapted_step_size_taken(),
    }


def _counted_run(monkeypatch, sc, name, **kw):
    """A run and the counts of each of its Simulators (read just before a switch replaces it,
    and at the end)."""
    from references.engines.drake import DrakeEngine

    counts = []
    switch, close = DrakeEngine._switch_chart, DrakeEngine.close

    def spy_switch(self, ctx):
        counts.append(_counts(ctx.handle))
        switch(self, ctx)

    def spy_close(self, ctx):
        if ctx.handle is not None:
            counts.append(_counts(ctx.handle))
        close(self, ctx)

    monkeypatch.setattr(DrakeEngine, "_switch_chart", spy_switch)
    monkeypatch.setattr(DrakeEngine, "close", spy_close)
    return DrakeEngine().run(sc, name, sc.dt, **kw), counts


@pytest.mark.parametrize("name", ["runge_kutta5", "implicit_euler", "discrete SAP"])
def test_fixed_step_bookkeeping_across_switches(drake, wobbly, monkeypatch, name):
    """Over all the Simulators of a switching run: Drake's steps sum to the planned 3000
    (the discrete plant's updates too: each step starts with one, on the grid n dt), and the
    dynamics evaluations the run reports are the sum of Drake's counters (runge_kutta5: 7 a
    step, as declared; implicit_euler: a varying count, added up by the adapter)."""
    sc, _ = wobbly
    out, counts = _counted_run(monkeypatch, sc, name)
    assert len(counts) == out.settings["RPY chart switches"] + 1 >= 2
    assert sum(c["steps"] for c in counts) == out.nstep == 3000
    if name == "discrete SAP":
        assert sum(c["updates"] for c in counts) == 3000
        return
    evals = sum(c["evals"] for c in counts)
    assert out.evals_per_step * out.nstep == pytest.approx(evals, rel=1e-15)
    if name == "runge_kutta5":
        assert evals == 7 * 3000


def test_error_controlled_bookkeeping_across_switches(drake, wobbly, monkeypatch):
    """runge_kutta5 (error-controlled) at 1e-8 on the wobbly top runs ok through its chart
    switches; its statistics are Drake's counters summed over every integrator (the largest
    and smallest steps their extremes), and the read-back after the last switch still holds
    (the new integrator's first step: the last one taken before the switch). At 1e-10 the
    run is cut off by the evaluation budget, which only the sum over the integrators
    exceeds."""
    from references.engines.drake import EVAL_BUDGET, DrakeEngine
    from references.engines.stepping import check_readback

    sc, _ = wobbly
    name = "runge_kutta5 (error-controlled)"
    out, counts = _counted_run(monkeypatch, sc, name, accuracy=1e-8)
    assert len(counts) == out.settings["RPY chart switches"] + 1 >= 2
    st = out.stats
    assert st["steps taken"] == sum(c["steps"] for c in counts)
    assert st["steps rejected"] == sum(c["rejected"] for c in counts)
    assert st["dynamics evaluations"] == sum(c["evals"] for c in counts)
    assert st["largest step"] == max(c["largest"] for c in counts)
    assert st["smallest adapted step"] == min(c["smallest"] for c in counts)
    assert out.evals_per_step * out.nstep == pytest.approx(st["dynamics evaluations"])
    last = []
    switch = DrakeEngine._switch_chart

    def spy(self, ctx):
        last.append(ctx.handle.last_step)  # the step that ended where the switch happens
        switch(self, ctx)

    monkeypatch.setattr(DrakeEngine, "_switch_chart", spy)
    eng, ctx = _built(drake, sc, name, accuracy=1e-8)
    while not ctx.handle.switches:
        eng.advance(ctx, 10)
    h = ctx.handle
    assert h.integrator.get_initial_step_size_target() == last[-1] != sc.dt
    check_readback("drake", eng.read_model(ctx), ctx.model)
    eng.close(ctx)
    with pytest.raises(Unsupported) as info:
        drake().run(sc, name, sc.dt, accuracy=1e-10)
    budget = EVAL_BUDGET * 3000
    assert f"over the budget of {budget} dynamics evaluations" in str(info.value)


def test_the_read_back_holds_after_a_switch(drake, wobbly):
    """After a switch the model read back is the new chart's (frames F and M), and it still
    passes the run's read-back check."""
    from references.engines.stepping import check_readback

    sc, _ = wobbly
    eng, ctx = _built(drake, sc, "runge_kutta5")
    first = ctx.handle.R_WF
    while not ctx.handle.switches:
        eng.advance(ctx, 10)
    h = ctx.handle
    got = eng.read_model(ctx)
    check_readback("drake", got, ctx.model)
    assert np.array_equal(got.extra["joint frame F rotation"][1], h.R_WF)
    assert np.abs(h.R_WF - first).max() > 0.1  # a new chart
    eng.close(ctx)
    assert ctx.handle is None


def test_the_monitor_reads_drakes_state_in_place(drake):
    """The monitor reads the pitch from a view of the plant's state taken once
    (BasicVector.get_value); every configuration must write its steps into that same
    storage."""
    sc = kit.pivoted_scenario()
    for integ in drake.integrators:
        acc = 1e-8 if integ.adaptive else None
        eng, ctx = _built(drake, sc, integ.name, accuracy=acc)
        h = ctx.handle
        vec = (
            h.context.get_discrete_state_vector()
            if h.mode == "discrete"
            else h.context.get_continuous_state_vector()
        )
        x = vec.get_value()
        eng.advance(ctx, 5)
        assert np.array_equal(x[:3], h.plant.GetPositions(h.context)), integ.name
        eng.close(ctx)
