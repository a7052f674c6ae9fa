"""``director-bench compare A B`` on two real result folders: B is A with one run's attitude
error made 10 times worse, one round-off-level energy drift made 5 times larger (still
round-off: not a regression) and one more run."""

import math
import shutil

import pytest

import scenarios
from reports.cli import main
from reports.compare import classify, compare_folders
from reports.results import RunSpec, Store, read_results
from reports.runner import plan, run_suite


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
    assert len(cmp.both) == 2 and cmp.only_a == [] and len(cmp.only_b) == 1
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


def test_runs_match_across_engine_versions(folders, tmp_path):
    """Two folders made with two versions of an engine: the version is not part of the
    match, so every run compares."""
    a, _ = folders
    c = tmp_path / "c"
    shutil.copytree(a, c)
    with Store(c) as st:
        for r in st.rows():
            r["engine_version"] = "9.9.9"
            st.put(r)
    assert set(read_results(c)["engine_version"]) == {"9.9.9"}
    cmp = compare_folders(a, c)
    assert len(cmp.both) == 2 and not cmp.only_a and not cmp.only_b and cmp.ok
