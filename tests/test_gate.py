"""The regression gate on hand-written results: a clean run passes, a regression, a status
change, a verdict change, a missing run and a new run each fail with a readable line."""

import json
import math
import xml.etree.ElementTree as ET

import pytest

from reports import gate
from reports.cli import main
from reports.results import NUMERIC_COLUMNS, RESULT_COLUMNS, Store


def row(scenario="dzhanibekov", engine="mujoco", integrator="RK4", dt=1e-3, status="ok", **m):
    r = dict.fromkeys(RESULT_COLUMNS, "")
    for c in NUMERIC_COLUMNS:
        r[c] = math.nan
    r.update(
        run_id=f"{scenario}/{engine}/{integrator}/{dt!r}",
        scenario=scenario,
        engine=engine,
        integrator=integrator,
        dt=dt,
        status=status,
        verdict="pass" if status == "ok" else "",
        ns_per_step=1000.0,
        finished_at="2026-11-22T00:00:00+00:00",
    )
    r.update(energy_drift_max=1e-8, attitude_error_max=1e-6)
    r.update(m)
    return r


def write(folder, rows):
    folder.mkdir(parents=True, exist_ok=True)
    with Store(folder, create=True) as st:
        for r in rows:
            st.put(r)
    return folder


@pytest.fixture
def baseline(tmp_path):
    base = write(
        tmp_path / "base",
        [row(), row(engine="pybullet", integrator="multibody", energy_drift_max=0.3)],
    )
    return gate.write_baseline(base, tmp_path / "baseline.json")


def test_identical_run_passes(tmp_path, baseline):
    cur = write(
        tmp_path / "cur",
        [row(), row(engine="pybullet", integrator="multibody", energy_drift_max=0.3)],
    )
    cmp = gate.compare(cur, baseline)
    assert cmp.ok and len(cmp.checked) == 2
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 0


def test_metric_regression_beyond_factor_fails(tmp_path, baseline, capsys):
    # energy drift 1e-8 -> 3e-8 is 3x worse (> factor 2); 1.5x is within the factor
    cur = write(
        tmp_path / "cur",
        [
            row(energy_drift_max=3e-8),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.45),
        ],
    )
    cmp = gate.compare(cur, baseline, factor=2.0)
    assert [(f.key[1], f.metric) for f in cmp.findings] == [("mujoco", "energy_drift_max")]
    assert cmp.findings[0].ratio == pytest.approx(3.0)
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 1
    out = capsys.readouterr().out
    assert "energy_drift_max" in out and "dzhanibekov" in out and "3" in out


def test_roundoff_floor(tmp_path):
    """3e-15 -> 9e-15 is noise at round-off level, not a regression (floor 1e-11)."""
    base = write(tmp_path / "b", [row(energy_drift_max=3e-15)])
    bl = gate.write_baseline(base, tmp_path / "bl.json")
    cur = write(tmp_path / "c", [row(energy_drift_max=9e-15)])
    assert gate.compare(cur, bl).ok
    cur = write(tmp_path / "d", [row(energy_drift_max=5e-11)])
    assert not gate.compare(cur, bl).ok


def sweep(slope, **kw):
    """RK4 rows (declared order 4) at three steps whose attitude errors fall with ``slope``."""
    return [
        row(
            dt=h, order=4.0, attitude_error_max=1e-4 * (h / 4e-3) ** slope, run_id=f"sweep{h}", **kw
        )
        for h in (4e-3, 2e-3, 1e-3)
    ]


def test_order_drop_status_and_verdict_change(tmp_path):
    base = write(tmp_path / "base", [*sweep(4), row(engine="pybullet", integrator="multibody")])
    bl = gate.write_baseline(base, tmp_path / "bl.json")
    entries = json.loads(bl.read_text())["runs"]
    assert {round(e["convergence_order"], 6) for e in entries if e["engine"] == "mujoco"} == {4.0}
    cur = write(
        tmp_path / "cur",
        [
            *sweep(2),
            row(engine="pybullet", integrator="multibody", status="diverged", message="blew up"),
        ],
    )
    what = {(f.key[1], f.what, f.metric) for f in gate.compare(cur, bl).findings}
    assert ("mujoco", "metric", "convergence_order") in what
    assert ("pybullet", "status", "status") in what
    cur = write(
        tmp_path / "cur2",
        [
            *sweep(4, verdict="fail", verdict_detail="x > y"),
            row(engine="pybullet", integrator="multibody"),
        ],
    )
    what = {(f.key[1], f.what) for f in gate.compare(cur, bl).findings}
    assert what == {("mujoco", "verdict")}


def test_missing_and_new_runs(tmp_path, baseline):
    cur = write(tmp_path / "cur", [row(), row(engine="dart", integrator="semi-implicit Euler")])
    cmp = gate.compare(cur, baseline)
    assert {(f.key[1], f.what) for f in cmp.findings} == {("pybullet", "missing"), ("dart", "new")}
    assert gate.compare(cur, baseline, only_present=True).ok


def test_timing_is_gated_only_on_request(tmp_path, baseline):
    cur = write(
        tmp_path / "cur",
        [
            row(ns_per_step=5000.0),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3),
        ],
    )
    assert gate.compare(cur, baseline).ok
    assert not gate.compare(cur, baseline, timing_factor=3.0).ok


def test_junit_has_one_case_per_checked_run(tmp_path, baseline):
    cur = write(
        tmp_path / "cur",
        [
            row(energy_drift_max=1.0),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3),
        ],
    )
    path = gate.write_junit(gate.compare(cur, baseline), tmp_path / "check-junit.xml")
    suite = ET.parse(path).getroot()
    assert suite.get("tests") == "2" and suite.get("failures") == "1"
    failed = [c for c in suite if c.find("failure") is not None]
    assert failed[0].get("name") == "mujoco/RK4/dt=0.001"


def test_bad_baseline_file_is_a_clear_error(tmp_path, capsys):
    cur = write(tmp_path / "cur", [row()])
    for text in ("{not json", "[1, 2]", '{"format": 2, "runs": [{"scenario": "x"}]}'):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        assert main(["check", str(cur), "--baseline", str(bad)]) == 2
        err = capsys.readouterr().err
        assert "bad.json:" in err and "Traceback" not in err


# -- invariants ---------------------------------------------------------------------------------
def _frame(rows):
    from reports.results import frame

    return frame(rows)


def test_invariants_hold_on_consistent_rows(tmp_path):
    from reports import junit

    rows = [
        *sweep(4, convergence_order=4.0, convergence_points=3.0),
        row(engine="pybullet", integrator="multibody", status="diverged", verdict="fail"),
        row(engine="dart", integrator="x", status="unsupported", verdict=""),
    ]
    df = _frame(rows)
    path = junit.write(df, tmp_path / "junit.xml")
    assert gate.invariants(df, path) == []


def test_each_invariant_can_fail(tmp_path):
    from reports import junit

    good = _frame([row(order=4.0), row(engine="pybullet", integrator="multibody")])
    path = junit.write(good, tmp_path / "junit.xml")
    cases = {
        "energy drift": row(energy_drift_max=1.5),  # blew up, yet ok
        "energy drift rot 2": row(energy_drift_rot_max=2.0),  # a free body's rotation blew up
        "energy drift trans 3": row(energy_drift_trans_max=3.0),  # ... or its translation
        "with verdict ''": row(verdict=""),  # ok without a verdict
        "verdict 'pass'": row(status="diverged", verdict="pass"),  # diverged cannot pass
        "fitted order 2.9": row(order=4.0, convergence_order=2.9, convergence_points=2.0),
    }
    for words, bad in cases.items():
        problems = gate.invariants(_frame([bad]))
        assert len(problems) == 1 and words in problems[0], (words, problems)
    # a junit.xml that counts differently from the results
    worse = _frame([row(order=4.0, verdict="fail"), row(engine="pybullet", integrator="multibody")])
    problems = gate.invariants(worse, path)
    assert any("failures = 0, the results say 1" in p for p in problems)
