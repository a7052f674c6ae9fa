"""Systems of bodies through the suite: scenario files validated with every problem named,
references checked against a formulation that shares nothing with them, metrics that catch
planted mistakes, and one run end to end through the runner."""

from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
import pytest

import scenarios
from references.engines.exact.system import reference
from references.trajectory import Trajectory
from reports.metrics.system import compute_system_metrics
from scenarios import ScenarioError
from scenarios.system_file import validate_system

LIBRARY = ["bricard", "conical_pendulum", "conical_pendulum_fast",
           "conical_pendulum_unstable", "double_pendulum_3d", "four_bar",
           "four_bar_stiff_loop", "free_chain_5", "iftomm_a02", "iftomm_a02_n2", "iftomm_a03",
           "iftomm_a05", "planar_chain_3_rates", "planar_chain_4", "slider_crank_spatial",
           "spinning_chain"]  # fmt: skip


def _data(name: str) -> dict:
    return tomllib.loads((scenarios.systems_path() / f"{name}.toml").read_text())


def _initial_traj(sc) -> Trajectory:
    bs = sc.bodies
    return Trajectory([0.0], [[b.position for b in bs]], [[b.velocity for b in bs]],
                            [[b.rotation for b in bs]], [[b.omega_body for b in bs]],
                            sc.body_names)  # fmt: skip


# -- the library and the schema ----------------------------------------------------------------


def test_library_systems_load_with_their_structure():
    assert scenarios.list_systems() == LIBRARY
    for name in LIBRARY:
        sc = scenarios.load(name)
        assert sc.name == name and sc.kind == "system" and len(sc.source) > 40
    # the loops: the four-bar's second rocker joint and one joint of Bricard's ring
    assert scenarios.load("four_bar").loop_joints == ("B1",)
    assert len(scenarios.load("bricard").loop_joints) == 1
    assert len(scenarios.load("bricard").tree_joints) == 5
    for name in ("free_chain_5", "double_pendulum_3d", "spinning_chain", "conical_pendulum"):
        assert scenarios.load(name).is_tree
    # single-body files are unchanged objects
    assert scenarios.load("heavy_top").kind == "body"


def test_every_problem_is_listed_with_its_field():
    d = _data("free_chain_5")
    d["bodies"][1]["mass"] = -1.0
    d["bodies"][2]["inertia"] = [1.0, 0.1, 0.1]  # triangle inequality
    d["bodies"][3]["colour"] = "red"
    d["joints"][0]["body_b"] = "nobody"
    d["joints"][1]["kind"] = "weld"
    with pytest.raises(ScenarioError) as err:
        validate_system(d, "x.toml")
    fields = [p[0] for p in err.value.problems]
    assert fields == ["bodies[1].mass", "bodies[2].inertia", "bodies[3].colour",
                      "joints[0].body_b", "joints[1].kind"]  # fmt: skip
    assert "x.toml" in str(err.value)


def test_open_joints_misaligned_axes_and_bad_velocities_are_refused():
    d = _data("free_chain_5")
    d["joints"][2]["anchor_a"][2] += 1e-3  # the joint opens by 1 mm
    d["bodies"][4]["velocity"][0] += 0.1  # the last joint's anchor points separate
    with pytest.raises(ScenarioError) as err:
        validate_system(d)
    probs = {p[0]: p[2] for p in err.value.problems}
    assert "open at t = 0 by 0.001 m" in probs["joints[2].anchor_b"]
    assert "separate at 0.1 m/s" in probs["joints[3]"]
    d = _data("four_bar")
    d["joints"][2]["axis_b"] = [0.0, 0.01, 1.0]  # 0.01 rad off
    with pytest.raises(ScenarioError, match=r"axes are off by 0.01 rad"):
        validate_system(d)


# -- references ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["spinning_chain", "conical_pendulum"])
def test_closed_forms_agree_with_the_reduced_coordinate_tree(name):
    """The closed form (in the file's body order) against the DOP853 tree reference of the
    same file, a formulation sharing nothing with it: equal within the tree's estimate."""
    sc = scenarios.load(name).replace(t_end=0.5)
    t = np.linspace(0.0, 0.5, 11)
    exact = reference(sc, t)
    num = reference(sc.replace(reference="numerical"), t)
    assert exact.kind == name and num.kind == "numerical"
    m = compute_system_metrics(sc, num.trajectory, exact)
    assert m["attitude_error_max"] <= num.accuracy + exact.accuracy
    assert m["position_error_max"] <= num.accuracy_position + exact.accuracy_position
    assert num.accuracy < 1e-9


def test_a_closed_form_whose_state_is_not_the_files_is_refused():
    from references.errors import Unsupported

    sc = scenarios.load("conical_pendulum")
    wrong = sc.replace(reference_params={**sc.reference_params, "rate": 2.9})
    with pytest.raises(Unsupported, match="initial"):
        reference(wrong, [0.0, 0.1])
    with pytest.raises(Unsupported, match="no independent reference"):
        reference(scenarios.load("bricard").replace(reference="none"), [0.0, 0.1])


# -- metrics -------------------------------------------------------------------------------------


def test_metrics_catch_planted_joint_and_momentum_mistakes():
    sc = scenarios.load("free_chain_5")
    tr = _initial_traj(sc)
    m0 = compute_system_metrics(sc, tr)
    assert m0["joint_gap_max"] < 1e-14 and m0["momentum_drift_max"] < 1e-14
    bad = copy.deepcopy(tr)
    bad.position[0, 2] += np.array([0.0, 3e-4, 4e-4])  # body 2 displaced by 5e-4 m
    assert compute_system_metrics(sc, bad)["joint_gap_max"] == pytest.approx(5e-4, rel=1e-9)
    bad = copy.deepcopy(tr)
    bad.velocity[0, 0] += np.array([0.01, 0.0, 0.0])  # linear momentum off by 0.01 kg m/s
    md = compute_system_metrics(sc, bad)["momentum_drift_max"]
    assert md >= 0.01 / sc.linear_momentum_scale * (1 - 1e-9)
    # a hinge's axes 1e-3 rad apart: rotate the coupler about x (perpendicular to its axis)
    fb = scenarios.load("four_bar")
    tr = _initial_traj(fb)
    c, s = math.cos(1e-3), math.sin(1e-3)
    tr.rotation[0, 2] = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ tr.rotation[0, 2]
    m = compute_system_metrics(fb, tr)
    assert m["joint_angle_gap_max"] == pytest.approx(1e-3, rel=1e-6)
    assert m["branch_error"] == pytest.approx(1e-3, rel=1e-6)


# -- end to end ------------------------------------------------------------------------------------


def test_a_system_runs_end_to_end_through_the_runner(tmp_path):
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    sc = scenarios.load("spinning_chain")
    row = execute(RunSpec(sc, "director", "rattle4", 1e-3, t_end=0.5), tmp_path)
    assert row["status"] == "ok" and row["verdict"] == "pass", row["message"]
    assert row["reference_kind"] == "spinning_chain"
    # round-off: constraints, momentum and energy of a relative equilibrium
    assert row["joint_gap_max"] < 1e-12 and row["momentum_drift_max"] < 1e-12
    assert row["attitude_error_max"] < 1e-9
    tr = Trajectory.read(tmp_path / row["trajectory"])
    assert tr.body_names == sc.body_names and len(tr) == 51
    assert np.max(np.abs(tr.position[0] - [b.position for b in sc.bodies])) == 0.0
    row = execute(RunSpec(sc, "director", "energy_momentum", 1e-3, t_end=0.5), tmp_path)
    assert row["status"] == "unsupported" and "rattle" in row["message"]
    row_exact = execute(RunSpec(sc, "exact", "reference", 1e-3, t_end=0.5), tmp_path)
    assert row_exact["status"] == "ok" and row_exact["reference_accuracy"] < 1e-12
    # the system figure is drawn from the files the runs wrote
    import pandas as pd

    from reports.report.canvas import SeriesCache, _plt, _save
    from reports.report.system_plots import system_plot

    first = execute(RunSpec(sc, "director", "rattle", 1e-3, t_end=0.5), tmp_path)
    rows = pd.DataFrame([first, row_exact])
    png = system_plot(rows, 1e-3, SeriesCache(tmp_path), tmp_path / "plots", sc.name, _plt(),
                      _save)  # fmt: skip
    assert png.exists() and png.stat().st_size > 1000


def test_trajectory_errors_are_judged_only_inside_the_trusted_horizon():
    """A run that departs from the reference after the reference's horizon: its attitude
    error counts only up to the horizon; its invariants count over the whole run."""
    from references.engines.exact.system import SystemReference

    sc = scenarios.load("spinning_chain").replace(t_end=1.0)
    t = np.linspace(0.0, 1.0, 11)
    exact = reference(sc, t)
    tr = copy.deepcopy(exact.trajectory)
    c, s = math.cos(0.5), math.sin(0.5)
    late = t > 0.55
    tr.rotation[late] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ tr.rotation[late]
    trusted = SystemReference(exact.trajectory, "numerical", 1e-12, 1e-12, 0.5, "test")
    assert compute_system_metrics(sc, tr, trusted)["attitude_error_max"] < 1e-12
    whole = SystemReference(exact.trajectory, "numerical", 1e-12, 1e-12, 1.0, "test")
    assert compute_system_metrics(sc, tr, whole)["attitude_error_max"] == pytest.approx(0.5)


def test_a_system_without_reference_is_judged_on_its_invariants_and_joints(tmp_path):
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    sc = scenarios.load("four_bar").replace(reference="none", t_end=0.02)
    row = execute(RunSpec(sc, "director", "rattle", 2e-3), tmp_path)
    assert row["status"] == "ok" and row["verdict"] == "pass", row["message"]
    assert "no reference" in row["message"] and math.isnan(row["attitude_error_max"])
    assert row["joint_gap_max"] < 1e-12 and row["branch_error"] < 1e-12
    row = execute(RunSpec(sc, "exact", "reference", 2e-3), tmp_path)
    assert row["status"] == "unsupported" and "no independent reference" in row["message"]
    row = execute(RunSpec(sc, "drake", "semi_explicit_euler", 2e-3), tmp_path)
    assert row["status"] in ("unsupported", "unavailable")


def test_the_system_figure_titles_only_the_panels_it_draws(tmp_path):
    """The four-bar conserves no momentum: its figure has no momentum panel, and its title
    must not announce one; a floating chain has all three."""
    import pandas as pd

    from reports.report.canvas import SeriesCache, _plt
    from reports.report.system_plots import system_plot
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    titles, alts = {}, {}

    def save(fig, path, alt):
        titles[path.name] = [ax.get_title() for ax in fig.axes if ax.get_title()]
        alts[path.name] = alt
        return path

    for name, dt in (("four_bar", 2e-3), ("spinning_chain", 1e-3)):
        sc = scenarios.load(name).replace(t_end=10 * dt)
        row = execute(RunSpec(sc, "director", "rattle", dt), tmp_path)
        assert row["status"] == "ok", row["message"]
        system_plot(pd.DataFrame([row]), dt, SeriesCache(tmp_path), tmp_path, name, _plt(), save)
    assert titles["four-bar__system.png"] == [
        f"four_bar: joints and energy over time at dt = {2e-3:g} s"
    ]
    assert titles["spinning-chain__system.png"] == [
        f"spinning_chain: joints, energy and momentum over time at dt = {1e-3:g} s"
    ]
    # the alt text says the same, in words, and counts the configurations drawn
    assert alts["four-bar__system.png"] == (
        f"four_bar: per engine and integrator at dt = {2e-3:g} s, the largest loop closure gap "
        "in m and the energy drift over time, log axes, 1 line(s) of configurations"
    )
    assert "gap in m, the energy drift and the momentum drift" in alts["spinning-chain__system.png"]


def test_a_numerical_reference_is_not_called_exact(tmp_path):
    """The reference of a tree without a closed form is integrated (DOP853 to its error
    estimate): tables and legends call it the numerical reference; a closed form stays the
    exact reference."""
    import pandas as pd

    from reports.report.canvas import SeriesCache, _plt
    from reports.report.labels import config_label
    from reports.report.system_plots import system_plot
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    legends = {}

    def save(fig, path, alt):
        legends[path.name] = [t.get_text() for lg in fig.legends for t in lg.get_texts()] + [
            t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()
        ]
        return path

    sc = scenarios.load("double_pendulum_3d").replace(t_end=0.01, save_every=1)
    ref = execute(RunSpec(sc, "exact", "reference", 1e-3), tmp_path)
    assert ref["status"] == "ok" and ref["reference_kind"] == "numerical", ref["message"]
    assert config_label(ref) == "numerical reference"
    assert config_label({**ref, "reference_kind": "spinning_chain"}) == "exact reference"
    # a row under test: not flagged as a reference (the runner's reference column)
    assert config_label({**ref, "engine": "mujoco", "integrator": "RK4", "reference": 0}) == (
        "mujoco RK4"
    )
    system_plot(pd.DataFrame([ref]), 1e-3, SeriesCache(tmp_path), tmp_path, sc.name, _plt(), save)
    assert "numerical reference" in legends["double-pendulum-3d__system.png"]


def test_system_fields_are_the_director_models():
    """The scenario's bodies and joints carry exactly the fields of director_model.system's
    Body and Joint (the contract with the engine builders), a body's collision ``shape`` aside
    (read by the contact builders only, references.engines.contact)."""
    import dataclasses

    from director_model.system import Body, Joint
    from scenarios import SystemBody, SystemJoint

    def names(cls):
        return {f.name for f in dataclasses.fields(cls)}

    assert names(SystemBody) - {"shape"} == names(Body)
    assert names(SystemJoint) == names(Joint)


def test_engine_settings_reach_the_builder_and_bad_ones_are_named():
    from references.engines.system import run_system
    from references.errors import EngineError

    d = _data("four_bar")
    d["engine_settings"] = {"mujoco": {"solref": [0.004, 1.0], "solimp": {"a": 1}}}
    with pytest.raises(ScenarioError) as err:
        validate_system(d)
    assert [p[0] for p in err.value.problems] == ["engine_settings.mujoco.solimp"]
    sc = scenarios.load("spinning_chain").replace(
        t_end=0.01, engine_settings={"director": {"solver": "no-such-solver"}}
    )
    with pytest.raises(EngineError, match="no-such-solver"):
        run_system("director", sc, "rattle", 1e-3)
    assert run_system("director", sc.replace(engine_settings={}), "rattle", 1e-3).nstep == 10


def test_a_builders_divergence_is_a_diverged_row_with_its_states(tmp_path, monkeypatch):
    """A builder that stops at a divergence raises Diverged with its result up to the last good
    save: the run is a ``diverged`` row at that time, its metrics over the states before it
    and its trajectory file written (a planted divergence halfway through a real run)."""
    from references.engines.director import system as director_system
    from references.engines.system import SystemResult
    from references.errors import Diverged
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    real = director_system.simulate_system

    def diverging(scenario, integrator, dt, nstep, save_every, **settings):
        full = real(scenario, integrator, dt, nstep, save_every, **settings)
        k = len(full.t) // 2
        part = SystemResult(full.t[:k], full.x[:k], full.R[:k], full.v[:k], full.W[:k],
                            full.engine_time_s, full.settings)  # fmt: skip
        raise Diverged("planted: a non-finite state", float(full.t[k]), part)

    monkeypatch.setattr(director_system, "simulate_system", diverging)
    sc = scenarios.load("spinning_chain")
    row = execute(RunSpec(sc, "director", "rattle", 1e-3, t_end=0.1, save_every=10), tmp_path)
    assert row["status"] == "diverged" and "planted" in row["message"], row["message"]
    # 11 saves (0, 10, ..., 100 steps): the first 5 kept, the divergence seen at the 6th
    assert row["t_diverged"] == pytest.approx(0.05) and row["nstep"] == 40
    assert row["joint_gap_max"] < 1e-12  # measured on the states before the divergence
    tr = Trajectory.read(tmp_path / row["trajectory"])
    assert len(tr) == 5
