"""``director-bench compare A B`` on two real result folders: B is A with one run's attitude
error made 10 times worse, one round-off-level energy drift made 5 times larger (still
round-off: not a regression) and one more run."""

import json
import math
import shutil

import pytest

import scenarios
from reports.cli import main
from reports.gate.compare import compare_folders
from reports.gate.rule import classify, classify_cost, cost_range
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.results import Store, read_results
from reports.store.runs import RunSpec


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("compare")
    a, b = root / "a", root / "b"
    a.mkdir()
    sc = scenarios.load("free_tumbling").replace(t_end=0.5, dt_sweep=())
    run_suite(plan([sc], ["mujoco"], ["Euler", "RK4"]), a, progress=False)
    shutil.copytree(a, b)
    with Store(b) as st:
        rows = {(r["integrator"]): r for r in st.rows()}
        euler, rk4 = rows["Euler"], rows["RK4"]
        assert rk4["energy_drift_max"] < 1e-12  # round-off level at this step
        euler["attitude_error_max"] *= 10.0
        rk4["energy_drift_max"] *= 5.0
        st.put(euler)
        st.put(rk4)
    run_suite([RunSpec(sc, "mujoco", "Euler", 2.5e-4)], b, progress=False)
    return a, b


def test_a_metric_worse_beyond_the_factor_is_a_regression(folders):
    a, b = folders
    cmp = compare_folders(a, b)
    assert len(cmp.compared) == 2 and cmp.only_a == [] and len(cmp.only_b) == 1
    (reg,) = cmp.regressions
    assert reg.key[1:3] == ("mujoco", "Euler") and reg.column == "attitude_error_max"
    assert reg.ratio == pytest.approx(10.0, rel=1e-12)
    # 5x a round-off-level drift is compared above the floor (1e-11): the same
    drift = [c for c in cmp.changes if c.key[2] == "RK4" and c.column == "energy_drift_max"]
    assert drift and drift[0].change == "same"
    assert compare_folders(a, b, factor=20.0).ok


def test_cli_exit_codes_and_table(folders, capsys):
    a, b = folders
    assert main(["compare", str(a), str(b)]) == 1
    out = capsys.readouterr().out
    assert "attitude_error_max" in out and "worse" in out and "10.0" in out
    assert "Only in B (1):" in out and "dt 0.00025" in out
    assert "FAIL: 1 run(s) got worse" in out
    assert main(["compare", str(a), str(a)]) == 0
    assert "OK: no run got worse." in capsys.readouterr().out
    # the cost is reported but gates only on request
    assert main(["compare", str(a), str(b), "--factor", "20"]) == 0


def test_bad_input_exits_2_naming_the_folder(folders, tmp_path, capsys):
    a, _ = folders
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["compare", str(a), str(empty)]) == 2
    err = capsys.readouterr().err
    assert str(empty) in err and "results.sqlite" in err
    with pytest.raises(SystemExit) as exc:  # argparse refuses a factor below 1
        main(["compare", str(a), str(a), "--factor", "0.5"])
    assert exc.value.code == 2


def test_classification():
    assert classify("attitude_error_max", 1e-3, 3e-3, 2.0) == (pytest.approx(3.0), "worse")
    assert classify("attitude_error_max", 1e-3, 4e-4, 2.0) == (pytest.approx(0.4), "better")
    assert classify("attitude_error_max", 1e-13, 9e-11, 2.0)[1] == "same"  # floor 1e-10
    assert classify("convergence_order", 4.0, 3.5, 2.0)[1] == "worse"  # slack 0.3
    assert classify("convergence_order", 4.0, 3.8, 2.0)[1] == "same"
    r, word = classify("attitude_error_max", 1e-3, math.nan, 2.0)
    assert word == "worse" and math.isnan(r)  # a metric that existed is gone
    assert classify("ns_per_step", math.nan, math.nan, 2.0) is None


def test_another_engine_version_is_compared_and_its_release_change_reported(
    folders, tmp_path, capsys
):
    """Two folders made with two releases of an engine hold the same runs on another
    release: compared as usual (no mismatch), with the release change on a line of its own;
    another suite version is a mismatch unless declared to vary (--vary)."""
    a, _ = folders
    c = tmp_path / "c"
    shutil.copytree(a, c)
    with Store(c) as st:
        for r in st.rows():
            old = r["engine_version"]
            r["engine_version"] = "9.9.9"
            st.put(r)
    assert set(read_results(c)["engine_version"]) == {"9.9.9"}
    cmp = compare_folders(a, c)
    assert len(cmp.compared) == 2 and cmp.ok
    assert "mismatch" not in {ch.change for ch in cmp.changes}
    (vc,) = cmp.versions.values()
    assert (vc.a, vc.b, vc.compared, vc.identical, vc.changed) == (old, "9.9.9", 2, 2, 0)
    assert main(["compare", str(a), str(c)]) == 0
    out = capsys.readouterr().out
    assert f"{vc.engine} {old} -> 9.9.9: 2 runs compared, 0 changed" in out
    d = tmp_path / "d"
    shutil.copytree(a, d)
    with Store(d) as st:
        for r in st.rows():
            r["suite_version"] = "99.0"
            st.put(r)
    cmp = compare_folders(a, d)
    assert {ch.change for ch in cmp.changes} == {"mismatch"} and not cmp.ok
    assert all("suite_version" in ch.b and "vs 99.0" in ch.b for ch in cmp.changes)
    assert main(["compare", str(a), str(d)]) == 1
    out = capsys.readouterr().out
    assert "FAIL: 2 run(s) are not the same run in A and B (identity mismatch)" in out
    assert compare_folders(a, d, vary=("suite_version",)).ok
    assert main(["compare", str(a), str(d), "--vary", "suite_version"]) == 0
    assert main(["compare", str(a), str(d), "--vary", "colour"]) == 2
    assert "--vary 'colour': not an identity column" in capsys.readouterr().err


def test_a_shorter_horizon_is_a_mismatch_not_a_comparison(folders, tmp_path, capsys):
    a, _ = folders
    sc = scenarios.load("free_tumbling").replace(t_end=0.5, dt_sweep=())  # A's scenario
    d = tmp_path / "d"
    run_suite(plan([sc], ["mujoco"], ["Euler", "RK4"], t_end=0.25), d, progress=False)
    assert main(["compare", str(a), str(d)]) == 1
    out = capsys.readouterr().out
    assert out.count("t_end 0.5 vs 0.25") == 2 and "scenario content" not in out
    # written beside the table: Markdown for a pull-request comment, and JSON
    md = (d / "compare.md").read_text()
    assert md.startswith("## director-bench compare: FAIL") and "t_end 0.5 vs 0.25" in md
    doc = json.loads((d / "compare.json").read_text())
    assert doc["counts"]["mismatch"] == 2 and not doc["ok"]


def test_nothing_comparable_exits_1(folders, tmp_path, capsys):
    a, _ = folders
    empty = tmp_path / "empty"
    empty.mkdir()
    with Store(empty, create=True):
        pass
    assert main(["compare", str(a), str(empty)]) == 1
    assert "holds no run: nothing to compare" in capsys.readouterr().err
    other = tmp_path / "other"
    sc = scenarios.load("free_tumbling").replace(t_end=0.5, dt_sweep=())
    run_suite([RunSpec(sc, "mujoco", "Euler", 2.5e-4)], other, progress=False)
    assert main(["compare", str(a), str(other)]) == 1
    assert "share no run" in capsys.readouterr().err


def test_cost_changes_count_only_beyond_the_measured_spread():
    """asv's rule on the ranges (fastest, low, high) of the timed repeats."""
    nan = math.nan
    # 3x slower, ranges apart: worse; 3x slower on the fastest, yet A's slowest repeat
    # reaches B's range: not significant; within the factor: same
    assert classify_cost((1.0, 1.0, 1.2), (3.0, 3.0, 3.3), 2.0) == (pytest.approx(3.0), "worse")
    assert classify_cost((1.0, 1.0, 3.5), (3.0, 3.0, 3.3), 2.0)[1] == "not significant"
    assert classify_cost((1.0, 1.0, 1.1), (1.5, 1.5, 1.6), 2.0)[1] == "same"
    assert classify_cost((3.0, 3.0, 3.3), (1.0, 1.0, 1.2), 2.0) == (pytest.approx(1 / 3), "better")
    assert classify_cost((3.0, 3.0, 3.3), (1.0, 1.0, 3.1), 2.0)[1] == "not significant"
    # B ran 4x slower on the wall clock while its process had a quarter of a CPU (CPU time
    # a quarter of the wall time: low end 1.0): the load, not the engine
    assert classify_cost((1.0, 1.0, 1.1), (4.0, 1.0, 4.4), 2.0)[1] == "not significant"
    # a side whose spread was not measured (one timing, no CPU time): not significant,
    # whatever the ratio; within the factor it is the same
    assert classify_cost((1.0, nan, nan), (30.0, 30.0, 30.0), 2.0)[1] == "not significant"
    assert classify_cost((1.0, 1.0, 1.0), (0.1, nan, nan), 2.0)[1] == "not significant"
    assert classify_cost((1.0, nan, nan), (1.5, nan, nan), 2.0)[1] == "same"
    assert classify_cost((nan, nan, nan), (nan, nan, nan), 2.0) is None


def test_cost_range_of_a_row():
    # a row written before the costs were CPU times: ns_per_step is the wall's
    r = {"ns_per_step": 100.0, "nstep": 1000, "wall_time_s": 1e-4, "wall_time_max_s": 2e-4}
    r["cpu_time_s"] = 0.5e-4  # the process ran half of the stepping's wall time
    assert cost_range(r, "ns_per_step") == (100.0, 50.0, pytest.approx(200.0), False)
    r["cpu_time_s"] = 1.2e-4  # other threads of the process: no lower than the fastest
    assert cost_range(r, "ns_per_step")[1] == 100.0
    del r["cpu_time_s"]  # timed once, no CPU time: the spread is unknown
    assert cost_range(r, "ns_per_step")[0] == 100.0
    assert all(math.isnan(v) for v in cost_range(r, "ns_per_step")[1:3])
    # CPU times (references.engines.timing): the engine's range is its uncertainty up to the
    # slowest repeat; the whole step's CPU time is exact, up to its slowest repeat
    r = {"nstep": 1000, "engine_ns_per_step": 40.0, "engine_time_s": 4e-5,
         "engine_time_spread_s": 2e-6, "engine_time_max_s": 5e-5, "ns_per_step": 100.0,
         "cpu_time_s": 1e-4, "cpu_time_max_s": 1.5e-4}  # fmt: skip
    assert cost_range(r, "engine_ns_per_step") == (40.0, 38.0, pytest.approx(50.0), False)
    assert cost_range(r, "ns_per_step") == (100.0, 100.0, pytest.approx(150.0), False)
    r["engine_time_spread_s"] = 1e-5  # a quarter of it: starved
    assert cost_range(r, "engine_ns_per_step") == (40.0, 30.0, pytest.approx(50.0), True)


def test_a_cost_change_where_a_side_was_starved_is_called_starved():
    # 3x apart with no overlap, but A's engine time was measured starved: not a change
    assert classify_cost((1.0, 0.9, 1.1, True), (3.0, 3.0, 3.3, False), 2.0)[1] == "starved"
    assert classify_cost((1.0, 0.9, 1.1, False), (3.0, 3.0, 3.3, True), 2.0)[1] == "starved"
    assert classify_cost((1.0, 0.9, 1.1, False), (3.0, 3.0, 3.3, False), 2.0)[1] == "worse"
    assert classify_cost((1.0, 0.9, 1.1, True), (1.5, 1.5, 1.6, True), 2.0)[1] == "same"


def _scale_wall(src, dst, lo: float, hi: float) -> None:
    """Copy folder ``src`` to ``dst`` with the RK4 run's whole-step CPU time range set to
    ``lo`` and ``hi`` times its fastest stepping in ``src``."""
    shutil.copytree(src, dst)
    with Store(dst) as st:
        for r in st.rows():
            if r["integrator"] == "RK4":
                cpu = r["cpu_time_s"]
                r.update(cpu_time_s=lo * cpu, cpu_time_max_s=hi * cpu)
                r["ns_per_step"] = 1e9 * r["cpu_time_s"] / r["nstep"]
                st.put(r)


def test_a_cost_change_within_the_spread_is_not_significant(folders, tmp_path, capsys):
    """B's fastest stepping 3x A's, but A's own repeats spread to 4x: not significant, and
    it does not gate even with --cost-factor; 10x (beyond twice A's slowest) gates."""
    a, _ = folders
    noisy_a, slower, much_slower = tmp_path / "na", tmp_path / "s", tmp_path / "m"
    _scale_wall(a, noisy_a, 1.0, 4.0)
    _scale_wall(a, slower, 3.0, 3.2)
    _scale_wall(a, much_slower, 10.0, 11.0)
    cmp = compare_folders(noisy_a, slower, cost_factor=2.0)
    (wall,) = [c for c in cmp.changes if c.key[2] == "RK4" and c.column == "ns_per_step"]
    assert wall.ratio == pytest.approx(3.0) and wall.change == "not significant" and cmp.ok
    assert main(["compare", str(noisy_a), str(slower), "--cost-factor", "2"]) == 0
    assert "1 cost change(s) beyond the factor but within the measured spread" in (
        capsys.readouterr().out
    )
    assert main(["compare", str(noisy_a), str(much_slower), "--cost-factor", "2"]) == 1
    assert "worse" in capsys.readouterr().out


def test_a_cost_change_counts_only_when_every_dt_of_its_sweep_moved():
    """A burst of load on the machine slows single runs; the engine's own slowdown moves every
    step size (on an identical rerun beside a second suite, 2 of 1164 cost comparisons were
    called worse, each at one dt of a three-step sweep)."""
    from reports.gate.rule import Change, corroborate_costs

    def sweep(words, integ="RK4"):
        return [
            Change(("s", "mujoco", integ, dt, None), "ns_per_step", 1.0, 3.0, 3.0, w)
            for dt, w in zip((1e-3, 2e-3, 4e-3), words, strict=False)
        ]

    burst = sweep(["same", "worse", "not significant"])
    corroborate_costs(burst)
    assert [c.change for c in burst] == ["same", "not significant", "not significant"]
    slower = sweep(["worse", "worse", "worse"])
    corroborate_costs(slower)
    assert [c.change for c in slower] == ["worse"] * 3
    single = sweep(["better"], integ="Euler")
    metric = [Change(("s", "mujoco", "RK4", 1e-3, None), "attitude_error_max", 1, 9, 9, "worse")]
    corroborate_costs(single + metric + sweep(["same", "same", "same"]))
    assert single[0].change == "better" and metric[0].change == "worse"


def test_a_failing_run_failing_one_more_check_is_worse_in_check_and_compare():
    # one rule for both commands (reports.gate.rule.verdict_change): a run already failing
    # on attitude that now also fails on energy got worse, whether the other side is a
    # baseline entry (failed checks kept as a list) or a row of a second folder
    from reports.gate.rule import verdict_change

    before = {"verdict": "fail", "verdict_detail": "attitude_error_max 0.5 > 0.1"}
    after = {
        "verdict": "fail",
        "verdict_detail": "attitude_error_max 0.5 > 0.1; energy_drift_max 0.2 > 0.01",
        "status": "ok",
    }
    before["status"] = "ok"
    assert verdict_change(before, after) == ("failed checks", "worse", "energy_drift_max")
    entry = {"verdict": "fail", "failed_checks": ["attitude_error_max"]}
    assert verdict_change(entry, after) == ("failed checks", "worse", "energy_drift_max")
    assert verdict_change(after, before) == ("", "same", "")  # one check fewer: not a regression
    assert verdict_change({"verdict": "pass"}, after)[:2] == ("verdict", "worse")
    assert verdict_change(after, {"verdict": "pass"})[:2] == ("verdict", "better")


def test_compare_flags_a_run_that_fails_one_more_check(folders, tmp_path):
    a0, _ = folders
    details = {"a": "attitude_error_max 0.5 > 0.1", "b": "attitude_error_max 0.5 > 0.1; "
               "nutation_period_error 1 > 0.01"}  # fmt: skip
    for side, detail in details.items():
        shutil.copytree(a0, tmp_path / side)
        with Store(tmp_path / side) as st:
            euler = {r["integrator"]: r for r in st.rows()}["Euler"]
            st.put({**euler, "verdict": "fail", "verdict_detail": detail})
    cmp = compare_folders(tmp_path / "a", tmp_path / "b")
    (reg,) = cmp.regressions
    assert reg.column == "failed checks" and "nutation_period_error" in reg.b
    assert compare_folders(tmp_path / "b", tmp_path / "a").ok  # one check fewer
