"""How ``director-bench versions`` reads a folder (reports/versions/changes.py: the release
order, the energy behaviour of a run, its signed energy error from the trajectory file, the
newest row of each configuration in each release), on series and stores written here. Every
expected value is worked by hand in its test: the energy series are a line plus a wobble
orthogonal to it, so that the least-squares line and the wobble are known exactly."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import scenarios
from reports.store.results import Store
from reports.versions.changes import (
    energy_behaviour,
    load_table,
    signed_energy_error,
    sort_versions,
    version_key,
)
from scenarios.schema import InputError
from tests.reports.versions.test_versions import _row

# five samples at t = 2 .. 6: S sums to 0 and is orthogonal to t (2 - 3 + 0 - 5 + 6 = 0), so
# the least-squares line through a t + b S is a t exactly and the largest deviation is |b|
T5 = np.array([2.0, 3.0, 4.0, 5.0, 6.0])
S5 = np.array([1.0, -1.0, 0.0, -1.0, 1.0])


def test_releases_in_pep440_order_then_the_unparsable_by_text():
    got = sort_versions(["2.0", "1.10", "nightly", "1.9", "1.10", "abc", "1.0rc1"])
    assert got == ["1.0rc1", "1.9", "1.10", "2.0", "abc", "nightly"]
    assert sort_versions([]) == []
    assert version_key("build-7") == (1, None, "build-7")
    assert version_key("1.2")[0] == 0 and version_key("1.2")[2] == ""


@pytest.mark.parametrize(
    "slope, cls",
    [
        # trend = slope x (6 - 2) = 4 slope; wobble 1e-3
        (0.525e-3, "gaining"),  # trend 2.1e-3 > 2 x wobble
        (0.475e-3, "mixed"),  # 1.9e-3: between half and twice the wobble
        (-0.525e-3, "losing"),
        (-0.475e-3, "mixed"),
        (0.1275e-3, "mixed"),  # 0.51e-3: just above half the wobble
        (0.1225e-3, "conserved"),  # 0.49e-3: below half of it
        (-0.1225e-3, "conserved"),
    ],
)
def test_energy_behaviour_at_the_edges_of_its_bands(slope, cls):
    e = 0.7e-3 + slope * T5 + 1e-3 * S5  # the offset is the line's intercept: no wobble
    got = energy_behaviour(T5, e)
    assert got["class"] == cls
    assert got["trend"] == pytest.approx(4 * slope, rel=1e-9)
    assert got["wobble"] == pytest.approx(1e-3, rel=1e-9)
    assert got["max"] == pytest.approx(np.max(np.abs(e)), rel=1e-15)
    assert "round_off" not in got


def test_energy_behaviour_of_short_empty_and_blown_up_series():
    # fewer than three samples, or no time elapsed: no line to fit, conserved at its size
    for t, e in (([0.0, 1.0], [0.0, 2e-3]), ([1.0, 1.0, 1.0], [0.0, 1e-3, -2e-3])):
        got = energy_behaviour(t, e)
        assert got == {"class": "conserved", "max": 2e-3, "trend": 0.0, "wobble": 2e-3,
                       "round_off": True}  # fmt: skip
    three = energy_behaviour([0.0, 1.0, 2.0], [0.0, 1e-3, 2e-3])  # a line: no wobble
    assert three["class"] == "gaining" and three["trend"] == pytest.approx(2e-3)
    # two samples at one time (first or last) still leave time elapsed: a line is fitted
    for t in ([0.0, 0.0, 1.0], [0.0, 1.0, 1.0]):
        got = energy_behaviour(t, [0.0, 1e-3, 2e-3])
        assert "round_off" not in got and got["class"] != "conserved", t
    assert energy_behaviour([], [])["class"] == "diverged"
    got = energy_behaviour([0.0, 1.0, 2.0], [0.0, np.nan, 1.0])
    assert got["class"] == "diverged" and got["max"] == np.inf
    assert np.isnan(got["trend"]) and np.isnan(got["wobble"])
    # at the floor (1e-11) exactly: round-off; a little above it: a real series
    assert energy_behaviour(T5, 1e-11 * S5)["class"] == "conserved"
    assert "round_off" not in energy_behaviour(T5, 1.01e-11 * S5)


def _parquet(path, **columns):
    pq.write_table(pa.table({k: np.asarray(v, dtype=float) for k, v in columns.items()}), path)
    return path.name


def test_the_signed_energy_error_of_a_run(tmp_path):
    """(E(t) - E(0)) / E_c: energies 5, 5.5, 4 on a scale of 0.5 are 0, 1, -2."""
    name = _parquet(tmp_path / "run.parquet", t=[0.0, 0.5, 1.0], energy=[5.0, 5.5, 4.0])
    t, e = signed_energy_error(tmp_path, {"trajectory": name, "energy_scale": 0.5})
    assert t.tolist() == [0.0, 0.5, 1.0] and e.tolist() == [0.0, 1.0, -2.0]
    # no series to read: no trajectory, another kind of file, a file gone, no energy column,
    # no energy sample, no scale (missing, zero, negative, not a number)
    (tmp_path / "run.csv").write_text("t,energy\n0,1\n")
    no_energy = _parquet(tmp_path / "q.parquet", t=[0.0, 1.0], x=[1.0, 2.0])
    empty = _parquet(tmp_path / "e.parquet", t=[], energy=[])
    for row in ({}, {"trajectory": None}, {"trajectory": ""},
                {"trajectory": "run.csv", "energy_scale": 2.0},
                {"trajectory": "gone.parquet", "energy_scale": 2.0},
                {"trajectory": no_energy, "energy_scale": 2.0},
                {"trajectory": empty, "energy_scale": 2.0},
                {"trajectory": name}, {"trajectory": name, "energy_scale": None},
                {"trajectory": name, "energy_scale": 0.0},
                {"trajectory": name, "energy_scale": -1.0},
                {"trajectory": name, "energy_scale": float("nan")}):  # fmt: skip
        assert signed_energy_error(tmp_path, row) is None, row


def test_the_newest_row_of_each_configuration_in_each_release(tmp_path):
    """A store holding, for release 1.0, the Euler run twice (the later one, by its finish
    time, holds 3e-2) and an RK4 sweep at three steps whose attitude errors fall as dt^2 (a
    fitted order 2; an older run at one step is not part of it); release 0.9 once; and
    another engine under label 1.0."""
    free = scenarios.load("free_tumbling")
    rows = [
        _row(free, "1.0", "Euler", attitude_error_max=3e-2, finished_at="2026-12-02T00:00:00"),
        _row(free, "1.0", "Euler", attitude_error_max=1e-2, finished_at="2026-12-01T00:00:00",
             run_id="an-earlier-run"),
        *[_row(free, "1.0", "RK4", dt=h, attitude_error_max=1e-2 * (h / 1e-3) ** 2)
          for h in (1e-3, 5e-4, 2.5e-4)],
        # an older run of the sweep's middle step: not in the fit
        _row(free, "1.0", "RK4", dt=5e-4, attitude_error_max=5e-2,
             finished_at="2026-11-30T00:00:00", run_id="an-older-rk4-run"),
        _row(free, "0.9", "Euler", attitude_error_max=1e-2),
        {**_row(free, "1.0", "Euler", attitude_error_max=5e-2), "engine": "drake",
         "run_id": "drake-run"},
    ]  # fmt: skip
    with Store(tmp_path, create=True) as st:
        for r in rows:
            st.put(r)
    tab = load_table(tmp_path, factor=1.0, behaviour=False)
    # the engines in the order the store holds them (the order the matrix ran them)
    assert list(tab.versions.items()) == [("mujoco", ["0.9", "1.0"]), ("drake", ["1.0"])]
    assert tab.factor == 1.0 and tab.behaviour == {} and tab.folder == tmp_path
    euler = ("free_tumbling", "mujoco", "Euler", 0.001, None)
    assert tab.row(euler, "1.0")["attitude_error_max"] == 3e-2
    assert tab.row(euler, "0.9")["attitude_error_max"] == 1e-2
    assert tab.row(("free_tumbling", "drake", "Euler", 0.001, None), "1.0")[
        "attitude_error_max"] == 5e-2  # fmt: skip
    assert tab.row(euler, "1.0")["target_accuracy"] is None  # NaN read as None
    for h in (1e-3, 5e-4, 2.5e-4):
        r = tab.row(("free_tumbling", "mujoco", "RK4", h, None), "1.0")
        assert r["convergence_order"] == pytest.approx(2.0, abs=1e-9)
    assert len(tab.rows) == 6
    assert tab.configs("drake") == [("free_tumbling", "drake", "Euler", 0.001, None)]
    assert [k[2:4] for k in tab.configs("mujoco")] == [("Euler", 0.001), ("RK4", 0.00025),
                                                      ("RK4", 0.0005), ("RK4", 0.001)]  # fmt: skip
    assert len(tab.configs()) == 5
    # the only pair, 0.9 -> 1.0 of mujoco: Euler 1e-2 -> 3e-2 is beyond a factor 1
    (pair,) = tab.pairs
    assert (pair.engine, pair.from_version, pair.to_version, pair.compared) == (
        "mujoco", "0.9", "1.0", 1)  # fmt: skip
    assert [(c.integrator, c.direction) for c in tab.changes] == [("Euler", "worse")]
    with pytest.raises(InputError, match=r"^--factor 0\.99: must be a number >= 1$"):
        load_table(tmp_path, factor=0.99)


def test_the_energy_behaviour_is_read_only_for_runs_that_ran(tmp_path):
    """ok and diverged runs: their trajectories are read; an error row's is not (its
    series stops where the run failed)."""
    free = scenarios.load("free_tumbling")
    ec = free.energy_scale
    traj = {}
    for name, e in (("up", 1e-3 * (T5 - 2.0)), ("flat", 1e-3 * S5)):
        traj[name] = _parquet(tmp_path / f"{name}.parquet", t=T5, energy=5.0 + ec * e)
    rows = [
        {**_row(free, "1.0", "Euler"), "trajectory": traj["up"]},
        {**_row(free, "1.0", "RK4", status="diverged"), "trajectory": traj["flat"],
         "energy_scale": ec},
        {**_row(free, "1.0", "implicit", status="error"), "trajectory": traj["up"],
         "energy_scale": ec},
    ]  # fmt: skip
    rows[0]["energy_scale"] = ec
    with Store(tmp_path, create=True) as st:
        for r in rows:
            st.put(r)
    tab = load_table(tmp_path)
    assert tab.factor == 2.0  # the default factor
    got = {k[2]: b["class"] for (k, v), b in tab.behaviour.items()}
    assert got == {"Euler": "gaining", "RK4": "conserved"}
    assert load_table(tmp_path, behaviour=False).behaviour == {}


def test_a_metric_gone_in_the_newer_release_is_worse_without_a_ratio():
    """attitude error 1e-3 in 1.0, not measured in 1.1: worse (a value that existed is gone),
    its ratio None (no number); 1e-3 -> 0 compares above the floor 1e-10: 1e-7, better."""
    from reports.versions.changes import VersionTable, compare_versions

    def row(v, **m):
        return {"status": "ok", "verdict": "pass", "verdict_detail": "", "message": "",
                "engine_version": v, **m}  # fmt: skip

    k1, k2 = (("top", "mujoco", i, 0.001, None) for i in ("Euler", "RK4"))
    rows = {(k1, "1.0"): row("1.0", attitude_error_max=1e-3), (k1, "1.1"): row("1.1"),
            (k2, "1.0"): row("1.0", attitude_error_max=1e-3),
            (k2, "1.1"): row("1.1", attitude_error_max=0.0)}  # fmt: skip
    tab = VersionTable("f", 2.0, {"mujoco": ["1.0", "1.1"]}, rows)
    _, changes = compare_versions(tab, "mujoco", "1.0", "1.1")
    got = {c.integrator: (c.column, c.direction, c.ratio) for c in changes}
    assert got["Euler"] == ("attitude_error_max", "worse", None)
    assert got["RK4"][:2] == ("attitude_error_max", "better")
    assert got["RK4"][2] == pytest.approx(1e-7) and type(got["RK4"][2]) is float


def test_configurations_sort_by_step_then_target_accuracy():
    """A fixed-step configuration (no target) before the error-controlled ones of the same
    step, those by their target."""
    from reports.versions.changes import VersionTable

    keys = [("top", "mujoco", "RK45", 0.001, a) for a in (1e-6, None, 1e-8)]
    keys.append(("top", "mujoco", "RK45", 0.0005, 1e-6))
    tab = VersionTable("f", 2.0, {"mujoco": ["1.0"]}, {(k, "1.0"): {} for k in keys})
    assert [(k[3], k[4]) for k in tab.configs()] == [(0.0005, 1e-6), (0.001, None),
                                                     (0.001, 1e-8), (0.001, 1e-6)]  # fmt: skip
