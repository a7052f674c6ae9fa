"""The Drake adapter (references.engines.drake).

Checked against references that do not share its code: Drake's own kinematics for every
layout conversion (and pydrake.math.RollPitchYaw for the angles) and across chart switches,
Drake's own step and evaluation counters, hand computations (the quaternion norm under an
additive update, the time a steady rotation reaches the chart's switching level), the exact
solutions of references.exact, and MuJoCo running the same algorithms. Skipped with the
reason when Drake is not installed.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from references import conventions as cv
from references.engines import conformance as kit
from references.engines import engine_names, get_engine
from references.errors import Diverged, Unsupported
from references.exact import reference_trajectory
from references.trajectory import one_body
from tests.references.engines.drake_helpers import EPS, _angle, _built, drake_engine


@pytest.fixture(scope="module")
def drake():
    return drake_engine()


# -- registry and identity ----------------------------------------------------------------------


def test_registered_and_named(drake):
    assert "drake" in engine_names()
    assert drake.version().startswith("1.")
    names = [i.name for i in drake.integrators]
    assert len(names) == len(set(names))
    adaptive = {i.name for i in drake.integrators if i.adaptive}
    assert adaptive == {
        f"{s} (error-controlled)"
        for s in (
            "runge_kutta3",
            "bogacki_shampine3",
            "runge_kutta5",
            "implicit_euler",
            "velocity_implicit_euler",
            "radau1",
            "radau3",
            "cenic",
        )
    }


# -- layouts, checked against Drake's own kinematics --------------------------------------------


def test_free_joint_layout_against_drake_kinematics(drake):
    """q = [wxyz, x], v = [w WORLD, v WORLD]: Drake's body pose and spatial velocity of the
    state the adapter wrote equal the suite's state (to round-off of the quaternion)."""
    sc = kit.free_scenario()
    eng, ctx = _built(drake, sc, "runge_kutta3")
    h = ctx.handle
    X = h.plant.EvalBodyPoseInWorld(h.context, h.body)
    V = h.plant.EvalBodySpatialVelocityInWorld(h.context, h.body)
    R, W = sc.rotation, sc.omega_body
    assert np.abs(X.rotation().matrix() - R).max() <= 4 * EPS
    assert np.abs(X.translation() - sc.position).max() <= 4 * EPS
    assert np.abs(V.rotational() - R @ W).max() <= 8 * EPS * np.linalg.norm(W)
    assert np.array_equal(V.translational(), sc.velocity)
    q = h.plant.GetPositions(h.context)
    assert np.array_equal(q[:4], h.joint.get_quaternion(h.context).wxyz())
    assert np.array_equal(q[4:], h.joint.get_translation(h.context))
    back = eng.read_state(ctx)
    for got, want in zip(back, (sc.position, sc.velocity, R, W), strict=True):
        assert np.abs(got - want).max() <= 8 * EPS * max(1.0, np.abs(want).max())


def test_unnormalised_quaternion_shows_in_R_not_in_the_rates(drake):
    """Drake leaves |q| alone; the adapter's R keeps |q|^2 (R^T R = |q|^4 1) while W stays
    Drake's own body rate (orthonormal pose from EvalBodyPoseInWorld), so the suite's kinetic
    energy is Drake's."""
    sc = kit.free_scenario(gravity=[0.0, 0.0, 0.0])
    eng, ctx = _built(drake, sc, "runge_kutta3")
    h = ctx.handle
    q = h.plant.GetPositions(h.context)
    s = 1.01
    h.plant.SetPositions(h.context, np.concatenate([s * q[:4], q[4:]]))
    st = eng.read_state(ctx)
    assert np.abs(st.rotation.T @ st.rotation - s**4 * np.eye(3)).max() <= 16 * EPS
    R_drake = h.plant.EvalBodyPoseInWorld(h.context, h.body).rotation().matrix()
    assert np.abs(R_drake.T @ R_drake - np.eye(3)).max() <= 4 * EPS
    w = h.plant.GetVelocities(h.context)[:3]
    assert np.abs(st.omega_body - R_drake.T @ w).max() <= 16 * EPS * np.linalg.norm(w)
    T = 0.5 * sc.mass * st.velocity @ st.velocity + 0.5 * st.omega_body @ (
        sc.inertia * st.omega_body
    )
    assert T == pytest.approx(h.plant.CalcKineticEnergy(h.context), rel=1e-14)


def test_rpy_angles_are_drakes():
    pytest.importorskip("pydrake")
    from pydrake.math import RollPitchYaw, RotationMatrix

    rng = np.random.default_rng(3)
    for _ in range(20):
        rpy = rng.uniform(-3, 3, 3) * np.array([1.0, 0.5, 1.0])
        R = cv.rpy_to_matrix(rpy)
        assert np.abs(R - RotationMatrix(RollPitchYaw(rpy)).matrix()).max() <= 4 * EPS
        got = cv.matrix_to_rpy(R)
        assert np.abs(got - RollPitchYaw(RotationMatrix(R)).vector()).max() <= 1e-14
        assert np.abs(cv.rpy_to_matrix(got) - R).max() <= 8 * EPS


def test_ball_rpy_layout_against_drake_kinematics(drake):
    """The BallRpyJoint with the adapter's frames F and M: Drake's body pose, COM and angular
    velocity of the written state equal the suite's; the generalized velocity is w_FM in F."""
    sc = kit.pivoted_scenario()
    eng, ctx = _built(drake, sc, "runge_kutta3")
    h = ctx.handle
    R, W = sc.rotation, sc.omega_body
    X = h.plant.EvalBodyPoseInWorld(h.context, h.body)
    V = h.plant.EvalBodySpatialVelocityInWorld(h.context, h.body)
    assert np.abs(X.rotation().matrix() - R).max() <= 8 * EPS
    assert np.abs(X.translation() - sc.position).max() <= 8 * EPS  # B is the COM frame
    assert np.abs(V.rotational() - R @ W).max() <= 16 * EPS * np.linalg.norm(W)
    assert np.abs(V.translational() - sc.velocity).max() <= 16 * EPS * np.linalg.norm(W)
    w_F = h.joint.get_angular_velocity(h.context)
    assert np.abs(w_F - h.R_WF.T @ R @ W).max() <= 16 * EPS * np.linalg.norm(W)
    back = eng.read_state(ctx)
    assert np.abs(back.rotation - R).max() <= 8 * EPS
    assert np.abs(back.omega_body - W).max() <= 16 * EPS * np.linalg.norm(W)


# -- the conformance kit ------------------------------------------------------------------------


def test_passes_the_conformance_kit(drake):
    """The kit (references/engines/conformance.py) on every integrator, the error-controlled
    ones at its target accuracy; every planted mistake, the kit's and Drake's own defaults
    (joint damping, the Simulator's default integrator), is caught on free and pivoted
    bodies."""
    kit.assert_conforms(drake)
    names = {c.name for c in kit.check_adapter(drake, orders=False)}
    for mistake in (*kit.STATE_MISTAKES, *kit.MODEL_MISTAKES, *drake.plantable):
        assert f"catches {mistake} (free)" in names
        assert f"catches {mistake} (pivoted)" in names


# -- what each configuration computes -----------------------------------------------------------


@pytest.mark.parametrize("name", ["semi_explicit_euler", "explicit_euler", "discrete SAP"])
def test_quaternion_norm_drift_is_the_hand_computed_one(drake, name):
    """Spin w about principal axis 3: the gyroscopic term vanishes, so w stays exact and the
    additive quaternion update q += h/2 (0, w) q multiplies |q|^2 by 1 + h^2 w^2 / 4 each
    step ((0, w) q is orthogonal to q, of norm |w| |q|). After n steps R^T R = |q|^4 1 with
    |q|^4 = (1 + h^2 w^2/4)^(2n): the suite's orthonormality metric must show exactly that."""
    w, h, n = 10.0, 1e-2, 100
    sc = kit.free_scenario(omega_body=[0.0, 0.0, w], gravity=[0.0, 0.0, 0.0])
    tr = one_body(drake().run(sc, name, h, t_end=n * h, save_every=n).trajectory)
    R = tr.rotation[-1]
    want = (1.0 + (h * w) ** 2 / 4) ** (2 * n)
    assert np.abs(R.T @ R - want * np.eye(3)).max() <= 1e-13 * want
    assert np.abs(tr.omega_body[-1] - [0.0, 0.0, w]).max() <= 1e-13 * w


def test_cenic_keeps_the_quaternion_normalised(drake):
    """Unlike every other configuration, CENIC's position update keeps |q| = 1 (the same run
    as above leaves R orthonormal to round-off)."""
    w, h, n = 10.0, 1e-2, 100
    sc = kit.free_scenario(omega_body=[0.0, 0.0, w], gravity=[0.0, 0.0, 0.0])
    R = one_body(drake().run(sc, "cenic", h, t_end=n * h, save_every=n).trajectory).rotation[-1]
    assert np.abs(R.T @ R - np.eye(3)).max() <= 100 * EPS


def test_first_order_lands_where_mujoco_euler_lands(drake):
    """Drake's semi_explicit_euler updates w in WORLD axes and then q with the new w; back in
    body axes that is MuJoCo Euler's W update (R_{n+1}^T R_n rotates W_{n+1} about itself),
    so the body rates, and with them the energy drift, are MuJoCo Euler's to round-off, while
    the attitude differs at O(h) (additive quaternion vs exponential map). Discrete SAP and
    CENIC have the same velocity update. Round-off bound: 2000 steps x eps, x 100 for the
    condition of the flip (dzhanibekov, W near the unstable axis)."""
    sc = scenarios.load("dzhanibekov")
    runs = {
        (e, i): one_body(get_engine(e)().run(sc, i, sc.dt, t_end=2.0).trajectory)
        for e, i in (
            ("mujoco", "Euler"),
            ("drake", "semi_explicit_euler"),
            ("drake", "discrete SAP"),
            ("drake", "cenic"),
        )
    }
    ref = runs["mujoco", "Euler"]
    W0 = np.linalg.norm(sc.omega_body)
    bound = 100 * 2000 * EPS
    for key, tr in runs.items():
        assert np.abs(tr.omega_body - one_body(ref).omega_body).max() <= bound * W0, key
        drift = np.abs(tr.energy - tr.energy[0]).max()
        ref_drift = np.abs(ref.energy - ref.energy[0]).max()
        assert drift == pytest.approx(ref_drift, rel=1e-9), key
    att = _angle(runs["drake", "semi_explicit_euler"].rotation, one_body(ref).rotation).max()
    assert att > 1e-6  # a different attitude update, not the same code
    sap = runs["drake", "discrete SAP"]
    assert np.abs(sap.rotation - runs["drake", "semi_explicit_euler"].rotation).max() <= bound


def test_runge_kutta5_at_round_off(drake):
    """free_tumbling, 10 s at dt = 1e-3: RK5's truncation error there is below 1e-15 (the
    order sweep above: 3e-12 at h = 6.25e-3 over 2 s, times (0.16)^5), so what remains is
    round-off: energy within 1e-12 of the scale (1e4 steps x eps x 10), attitude within 1e-10
    of the exact solution (the same count times |W| t)."""
    sc = scenarios.load("free_tumbling")
    tr = one_body(drake().run(sc, "runge_kutta5", sc.dt).trajectory)
    e = tr.energy
    assert np.abs(e - e[0]).max() <= 1e-12 * sc.energy_scale
    ref = reference_trajectory(sc, tr.t)
    assert _angle(tr.rotation, one_body(ref).rotation).max() <= 1e-10 + ref.accuracy


def test_declared_evaluations_per_step_are_drakes(drake):
    """For the explicit schemes the declared evals_per_step equals Drake's own counter."""
    sc = kit.free_scenario()
    for integ in drake.integrators:
        if integ.adaptive or integ.evals_per_step is None or integ.options["mode"] == "discrete":
            continue
        eng, ctx = _built(drake, sc, integ.name)
        eng.advance(ctx, 10)
        evals = ctx.handle.integrator.get_num_derivative_evaluations()
        assert evals == 10 * integ.evals_per_step, integ.name


def _short_runs(cls, sc, t_end, accuracy):
    out = {}
    for integ in cls.integrators:
        acc = accuracy if integ.adaptive else None
        try:
            out[integ.name] = cls().run(sc, integ.name, sc.dt, t_end=t_end, accuracy=acc)
        except Unsupported as exc:
            out[integ.name] = exc
    return out


@pytest.mark.parametrize(
    "name,t_end,accuracy", [("dzhanibekov", 0.5, 1e-8), ("heavy_top", 0.1, 1e-6)]
)
def test_every_configuration_runs(drake, name, t_end, accuracy):
    """Every Drake configuration on the free body and the heavy top, for a short horizon: a
    fixed step runs every planned step; an error-controlled one either runs and
    records its statistics or is cut off by the budget, saying so. The energy bounds are
    regression bounds (a few times the largest drift measured at these horizons with drake
    1.51.1: first order 7.1e-3, runge_kutta2 1.8e-5, on the heavy top at 0.2 s); accuracy against
    independent references is tested above."""
    sc = scenarios.load(name)
    for integ_name, res in _short_runs(drake, sc, t_end, accuracy).items():
        integ = drake.integrator(integ_name)
        if isinstance(res, Unsupported):
            assert integ.adaptive and "cut off at" in str(res), (integ_name, str(res))
            continue
        tr = res.trajectory
        assert res.nstep == round(t_end / sc.dt), integ_name
        drift = np.abs(tr.energy - tr.energy[0]).max() / sc.energy_scale
        assert drift <= (2e-2 if integ.order == 1 else 1e-4), (integ_name, drift)
        if integ.adaptive:
            for key in ("steps taken", "steps rejected", "dynamics evaluations"):
                assert key in res.stats, (integ_name, key)
            assert res.settings["maximum step size"] == t_end
        elif integ.options["mode"] == "fixed step":
            assert res.settings["fixed step mode"] is True
            assert res.settings["maximum step size"] == sc.dt


def test_error_control_follows_the_target(drake):
    """runge_kutta5 (error-controlled) on free_tumbling over 2 s (checkpoints every 0.5 s):
    a tighter target takes more steps and lands closer to the exact solution."""
    sc = scenarios.load("free_tumbling")
    res = {
        a: drake().run(sc, "runge_kutta5 (error-controlled)", 0.5, t_end=2.0, accuracy=a)
        for a in (1e-6, 1e-10)
    }
    ref = reference_trajectory(sc, res[1e-6].trajectory.t)
    err = {
        a: _angle(one_body(r.trajectory).rotation, one_body(ref).rotation).max()
        for a, r in res.items()
    }
    assert res[1e-10].stats["steps taken"] > res[1e-6].stats["steps taken"]
    assert err[1e-10] < err[1e-6]
    for r in res.values():
        assert r.stats["dynamics evaluations"] >= 6 * r.stats["steps taken"]
        assert r.evals_per_step == pytest.approx(r.stats["dynamics evaluations"] / r.nstep)


def test_an_integrator_over_its_budget_is_cut_off(drake):
    """implicit_euler (error-controlled) at 1e-10 on the heavy top (spin 120 rad/s) needs steps
    of about 1e-7 s, far more than the budget allows: over a 0.1 s horizon (100 fixed steps)
    the run stops as soon as it has made more than EVAL_BUDGET x 100 dynamics evaluations
    (by less than one step's worth: an implicit step makes at most a few tens), and says so."""
    import re

    from references.engines.drake import EVAL_BUDGET

    sc = scenarios.load("heavy_top")
    with pytest.raises(Unsupported) as info:
        drake().run(sc, "implicit_euler (error-controlled)", sc.dt, t_end=0.1, accuracy=1e-10)
    budget = EVAL_BUDGET * 100
    msg = str(info.value)
    assert f"over the budget of {budget} dynamics evaluations" in msg
    steps, evals = (
        int(x) for x in re.search(r"after (\d+) steps and (\d+) dynamics", msg).groups()
    )
    assert budget < evals <= budget + 50 and 0 < steps < evals


def test_error_control_from_a_sane_first_step_on_a_top(drake):
    """Drake's first error-controlled attempt would be the largest step (the horizon); on the
    heavy top runge_kutta5 then rejected 258000 attempts in 12 s without taking a step (a loop
    no step budget can see: the monitor runs after steps). The adapter asks for the scenario's
    dt as the first step; the run must finish, in a subprocess with a timeout so that a
    regression fails instead of hanging the suite (measured 0.7 s, import included)."""
    import subprocess
    import sys

    code = (
        "import scenarios\n"
        "from references.engines import get_engine\n"
        "sc = scenarios.load('heavy_top')\n"
        "out = get_engine('drake')().run(sc, 'runge_kutta5 (error-controlled)', 0.05, "
        "t_end=0.1, save_every=1, accuracy=1e-6)\n"
        "print(int(out.stats['steps taken']))\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr[-2000:]
    assert int(res.stdout.split()[-1]) > 0


# -- long runs ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_first_order_phases_of_the_flip(drake):
    """dzhanibekov over 30 s at dt = 1e-3: semi_explicit_euler lands on the right flip phase
    (attitude error < 0.1 rad, like MuJoCo Euler's 0.029), explicit_euler, implicit_euler and
    radau1 on the wrong one (> 2 rad), runge_kutta5 at round-off."""
    sc = scenarios.load("dzhanibekov")
    errs = {}
    for name in (
        "semi_explicit_euler",
        "explicit_euler",
        "implicit_euler",
        "radau1",
        "runge_kutta5",
    ):
        tr = one_body(drake().run(sc, name, sc.dt).trajectory)
        ref = reference_trajectory(sc, tr.t)
        errs[name] = _angle(tr.rotation, one_body(ref).rotation).max()
    assert errs["semi_explicit_euler"] < 0.1
    assert min(errs["explicit_euler"], errs["implicit_euler"], errs["radau1"]) > 2.0
    assert errs["runge_kutta5"] < 1e-9


@pytest.mark.slow
def test_every_fixed_configuration_on_the_whole_heavy_top(drake):
    """The heavy top over its 4 s: the first-order explicit and semi-implicit steppers fail,
    semi_explicit_euler, CENIC and discrete SAP by diverging (energy error beyond the scale at
    1.64 s, as MuJoCo Euler diverges at 2.6 s), explicit_euler by ending a half turn off the
    exact motion (measured: attitude error 3.1 rad, energy drift 0.14 of the scale); the
    higher orders and the implicit ones run, with small energy drifts."""
    sc = scenarios.load("heavy_top")
    implicit = "implicit Runge-Kutta on coordinates"
    for integ in drake.integrators:
        if integ.adaptive:
            continue
        try:
            tr = one_body(drake().run(sc, integ.name, sc.dt).trajectory)
        except Diverged as exc:
            assert integ.order == 1 and integ.family != implicit, (integ.name, str(exc))
            continue
        drift = np.abs(tr.energy - tr.energy[0]).max() / sc.energy_scale
        if integ.order == 1 and integ.family != implicit:
            ref = reference_trajectory(sc, tr.t)
            assert _angle(tr.rotation, one_body(ref).rotation).max() > 1.0, integ.name
            continue
        assert drift <= (0.05 if integ.order == 1 else 2e-4), (integ.name, drift)
