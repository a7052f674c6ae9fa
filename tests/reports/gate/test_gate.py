"""The regression gate on hand-written results: a clean run passes, a regression, a status
change, a verdict change, a missing run, a new run and a run whose identity differs (another
horizon, an edited scenario) each fail with a readable line, in JUnit and as an annotation; a
run failing as in the baseline is a known failure, never a JUnit failure."""

import json
import math
import xml.etree.ElementTree as ET

import pytest

from reports.cli import main
from reports.gate import check as gate
from reports.store.results import Store
from reports.store.runs import IDENTITY_COLUMNS, NUMERIC_COLUMNS, RESULT_COLUMNS, suite_version


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
        scenario_hash=f"hash-of-{scenario}",
        t_end=30.0,
        save_every=10,
        engine_version="3.3.0",
        suite_version=suite_version(),
    )
    r.update(energy_drift_max=1e-8, attitude_error_max=1e-6)
    r.update(m)
    return r


def baseline_entry() -> dict:
    """One entry of a baseline file as check reads it: a passing run with every identity
    field present and empty (the tests that refuse a baseline change one field of it)."""
    return {
        "scenario": "s",
        "engine": "e",
        "integrator": "i",
        "dt": 0.001,
        "status": "ok",
        "verdict": "pass",
        "target_accuracy": None,
        **dict.fromkeys(IDENTITY_COLUMNS),
    }


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
    assert cmp.ok and len(cmp.compared) == 2
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
    assert [(f.key[1], f.column) for f in cmp.regressions] == [("mujoco", "energy_drift_max")]
    assert cmp.regressions[0].ratio == pytest.approx(3.0)
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
    what = {(f.key[1], f.what, f.column) for f in gate.compare(cur, bl).regressions}
    assert ("mujoco", "metric", "convergence_order") in what
    assert ("pybullet", "status", "status") in what
    cur = write(
        tmp_path / "cur2",
        [
            *sweep(4, verdict="fail", verdict_detail="x > y"),
            row(engine="pybullet", integrator="multibody"),
        ],
    )
    what = {(f.key[1], f.what) for f in gate.compare(cur, bl).regressions}
    assert what == {("mujoco", "verdict")}


def test_missing_and_new_runs(tmp_path, baseline):
    cur = write(tmp_path / "cur", [row(), row(engine="dart", integrator="semi-implicit Euler")])
    cmp = gate.compare(cur, baseline)
    assert {(f.key[1], f.what) for f in cmp.regressions} == {
        ("pybullet", "missing"),
        ("dart", "new"),
    }
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


def junit_cases(folder) -> tuple[dict, dict]:
    suite = ET.parse(folder / "junit.xml").getroot()
    cases = {
        c.get("name"): (c[0].tag, c[0].get("message")) if len(c) else ("pass", "") for c in suite
    }
    return suite.attrib, cases


def test_junit_with_a_baseline_fails_exactly_the_regressed_run(tmp_path, baseline, capsys):
    cur = write(
        tmp_path / "cur",
        [
            row(energy_drift_max=1.0),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3),
        ],
    )
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 1
    attrib, cases = junit_cases(cur)
    assert attrib["tests"] == "2" and attrib["failures"] == "1"
    kind, msg = cases["mujoco/RK4/dt=0.001"]
    assert kind == "failure" and msg.startswith("regression against the baseline: energy_drift_max")
    assert cases["pybullet/multibody/dt=0.001"] == ("pass", "")
    out = capsys.readouterr().out
    # one GitHub annotation, for the regressed run only
    notes = [ln for ln in out.splitlines() if ln.startswith("::error")]
    assert len(notes) == 1
    assert notes[0].startswith(
        "::error title=director-bench regression%3A dzhanibekov mujoco/RK4/dt=0.001::"
        "energy_drift_max: baseline 1.000e-08, now 1.000e+00"
    )


def failing_row(**kw):
    detail = "attitude_error_max 0.5 > 0.1"
    return row(verdict="fail", verdict_detail=detail, attitude_error_max=0.5, **kw)


def test_a_known_failure_is_expected_not_failed(tmp_path, capsys, monkeypatch):
    """A run failing exactly as in the baseline: JUnit <skipped> with its reason, listed in
    the Markdown summary (also appended to $GITHUB_STEP_SUMMARY) and the JSON, exit 0."""
    rows = [failing_row(), row(engine="pybullet", integrator="multibody")]
    bl = gate.write_baseline(write(tmp_path / "base", rows), tmp_path / "bl.json")
    cur = write(tmp_path / "cur", rows)
    summary = tmp_path / "step-summary.md"
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    assert main(["check", str(cur), "--baseline", str(bl)]) == 0
    out = capsys.readouterr().out
    assert "1 known failure(s) failing as in the baseline" in out and "::error" not in out
    attrib, cases = junit_cases(cur)
    assert attrib["failures"] == "0" and attrib["skipped"] == "1" and attrib["baseline"]
    assert cases["mujoco/RK4/dt=0.001"] == (
        "skipped",
        "known failure (as in baseline): fail: attitude_error_max 0.5 > 0.1",
    )
    md = (cur / "check.md").read_text()
    assert md.startswith("## director-bench check: OK")
    assert "| dzhanibekov mujoco/RK4/dt=0.001 | fail: attitude_error_max 0.5 &gt; 0.1 |" in md
    assert summary.read_text() == md
    doc = json.loads((cur / "check.json").read_text())
    assert doc["ok"] and doc["counts"]["known_failures"] == 1 and doc["counts"]["passed"] == 1
    assert doc["known_failures"][0]["reason"] == "fail: attitude_error_max 0.5 > 0.1"


def test_a_known_failure_failing_one_more_check_is_a_regression(tmp_path, capsys):
    bl = gate.write_baseline(write(tmp_path / "base", [failing_row()]), tmp_path / "bl.json")
    worse = failing_row(energy_drift_max=0.5)
    worse["verdict_detail"] += "; energy_drift_max 0.5 > 0.01"
    cur = write(tmp_path / "cur", [worse])
    assert main(["check", str(cur), "--baseline", str(bl)]) == 1
    _, cases = junit_cases(cur)
    kind, msg = cases["mujoco/RK4/dt=0.001"]
    assert kind == "failure" and "now also fails energy_drift_max" in msg


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("t_end", 10.0, "t_end 30 vs 10"),
        (
            "scenario_hash",
            "edited-file",
            "scenario content (scenario_hash) hash-of-dzha vs edited-file",
        ),
        ("save_every", 1, "save_every 10 vs 1"),
        ("segment", 1000, "segment none vs 1000"),
        ("suite_version", "99.0", f"suite_version {suite_version()} vs 99.0"),
    ],
)
def test_a_run_of_another_identity_is_a_mismatch_never_a_pass(
    tmp_path, baseline, capsys, field, value, words
):
    """Same configuration, another run (a shorter horizon, an edited scenario file, ...):
    every metric may match, yet the gate fails naming the field."""
    changed = row(**{field: value})
    cur = write(
        tmp_path / "cur",
        [
            changed,
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3, **{field: value}),
        ],
    )
    cmp = gate.compare(cur, baseline)
    assert {f.what for f in cmp.regressions} == {"mismatch"} and len(cmp.regressions) == 2
    assert words in cmp.regressions[0].b
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 1
    out = capsys.readouterr().out
    assert "identity mismatch" in out and words in out
    _, cases = junit_cases(cur)
    kind, msg = cases["mujoco/RK4/dt=0.001"]
    assert kind == "failure" and words in msg


def test_an_engine_patch_release_is_compared_and_reported_not_a_mismatch(
    tmp_path, baseline, capsys
):
    """The same runs on a newer release of MuJoCo (a patch release installed after the
    baseline was written) with every metric equal: the gate passes and says which release
    changed and that no run changed; check.md and check.json name it too."""
    cur = write(
        tmp_path / "cur",
        [
            row(engine_version="3.3.1"),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3),
        ],
    )
    cmp = gate.compare(cur, baseline)
    assert cmp.ok and not cmp.changes
    (vc,) = cmp.versions.values()
    assert (vc.engine, vc.a, vc.b, vc.compared, vc.identical, vc.changed) == (
        "mujoco", "3.3.0", "3.3.1", 1, 1, 0
    )  # fmt: skip
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 0
    out = capsys.readouterr().out
    line = (
        "engine release mujoco 3.3.0 -> 3.3.1: 1 runs compared, 0 changed (1 identical in "
        "every metric, 0 regressed, 0 better)"
    )
    assert out.splitlines()[0] == line
    assert "mujoco 3.3.0 -&gt; 3.3.1: 1 runs compared, 0 changed" in (cur / "check.md").read_text()
    doc = json.loads((cur / "check.json").read_text())
    assert doc["ok"] and doc["engine_releases"][0]["b"] == "3.3.1"


def test_a_metric_regression_on_a_new_engine_release_stays_red(tmp_path, baseline, capsys):
    """A release change does not hide a regression: the metric that got worse on the new
    release is the one finding, and the release line counts it."""
    cur = write(
        tmp_path / "cur",
        [
            row(engine_version="3.3.1", attitude_error_max=1e-3),
            row(engine="pybullet", integrator="multibody", energy_drift_max=0.3),
        ],
    )
    cmp = gate.compare(cur, baseline)
    assert [(f.key[1], f.column) for f in cmp.regressions] == [("mujoco", "attitude_error_max")]
    (vc,) = cmp.versions.values()
    assert (vc.compared, vc.identical, vc.regressed) == (1, 0, 1)
    assert main(["check", str(cur), "--baseline", str(baseline)]) == 1
    out = capsys.readouterr().out
    assert "mujoco 3.3.0 -> 3.3.1: 1 runs compared, 1 changed" in out
    assert "FAIL: 1 finding(s) in 1 run(s)" in out


def test_history_rows_are_missing_runs_with_the_reason(tmp_path, baseline):
    """A folder where one scenario was run again with an edited file: the new run is a
    mismatch, and the baseline's other runs of that scenario, stored only with the old
    content, are missing (history), named so."""
    edited = row(scenario_hash="edited", finished_at="2026-11-23T00:00:00+00:00", run_id="new")
    cur = write(
        tmp_path / "cur",
        [row(), row(engine="pybullet", integrator="multibody", energy_drift_max=0.3), edited],
    )
    cmp = gate.compare(cur, baseline)
    what = {(f.key[1], f.what) for f in cmp.regressions}
    assert what == {("mujoco", "mismatch"), ("pybullet", "missing")}
    (missing,) = [f for f in cmp.regressions if f.what == "missing"]
    text = gate.message(missing)
    assert "history" in text and "newest runs have another identity" in text


def test_nothing_comparable_exits_1(tmp_path, baseline, capsys):
    empty = write(tmp_path / "empty", [])
    assert main(["check", str(empty), "--baseline", str(baseline)]) == 1
    assert "holds no run" in capsys.readouterr().err
    other = write(tmp_path / "other", [row(scenario="heavy_top")])
    assert main(["check", str(other), "--baseline", str(baseline)]) == 1
    err = capsys.readouterr().err
    assert "none of its 1 run(s) is in the baseline" in err and "nothing was compared" in err


def test_annotation_escapes_what_github_requires():
    line = gate.annotation("a: b, c", "50% done\nnext")
    assert line == "::error title=a%3A b%2C c::50%25 done%0Anext"


def test_bad_baseline_file_is_a_clear_error(tmp_path, capsys):
    cur = write(tmp_path / "cur", [row()])
    entry = json.loads(gate.write_baseline(cur, tmp_path / "good.json").read_text())["runs"][0]
    cases = {
        "{not json": "invalid JSON",
        "[1, 2]": "expected an object with a 'runs' list",
        '{"format": 3, "runs": [{"scenario": "x"}]}': "runs[0] lacks engine",
        '{"format": 2, "runs": []}': "baseline format 2, this suite reads format 3",
        json.dumps({"format": 3, "runs": [{**entry, "attitude_error_max": "1e-3"}]}): (
            "runs[0].attitude_error_max = '1e-3' is not a number"
        ),
        "[" * 100000: "nested too deeply",
        # NaN compares as nothing: a baseline of NaN metrics would pass any results
        json.dumps({"format": 3, "runs": [{**entry, "attitude_error_max": math.nan}]}): (
            "runs[0].attitude_error_max = NaN: not a number (a value that was not measured is null)"
        ),
        json.dumps({"format": 3, "runs": [{**entry, "energy_drift_max": -1.0}]}): (
            "runs[0].energy_drift_max = -1.0: must be >= 0"
        ),
        json.dumps({"format": 3, "runs": [{**entry, "dt": math.inf}]}): (
            "runs[0].dt = Infinity: a step must be finite and > 0"
        ),
        json.dumps({"format": 3, "runs": [{**entry, "target_accuracy": 5.0}]}): (
            "runs[0].target_accuracy = 5.0: a target accuracy is in (0, 1)"
        ),
        json.dumps({"format": 3, "runs": [{**entry, "status": "bogus"}]}): (
            "runs[0].status = 'bogus': must be one of 'ok', 'reference-inaccurate'"
        ),
        json.dumps({"format": 3, "runs": [{**entry, "verdict": "maybe"}]}): (
            "runs[0].verdict = 'maybe': must be one of 'pass', 'fail', ''"
        ),
        json.dumps({"format": 3, "runs": [entry, {**entry, "attitude_error_max": 1e-30}]}): (
            "runs[1] repeats the configuration of runs[0] (dzhanibekov mujoco/RK4/dt=0.001)"
        ),
    }
    failed = []  # every case is tried: each must fail on its own without its check
    for text, words in cases.items():
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        code = main(["check", str(cur), "--baseline", str(bad)])
        err = capsys.readouterr().err
        if code != 2 or "bad.json:" not in err or words not in err or "Traceback" in err:
            failed.append(f"exit {code}, {words!r} not in {err.strip()[:200]!r}")
    assert not failed, "\n".join(failed)


def test_a_blown_up_run_and_a_negative_fitted_order_are_valid_baseline_values(tmp_path):
    """The writer writes an infinite metric (a run that blew up) as Infinity, and a fitted
    order may be negative (an error growing as dt falls): both are read, and compared."""
    blown = row(status="diverged", verdict="fail", energy_drift_max=math.inf, t_diverged=0.5)
    cur = write(tmp_path / "cur", [blown])
    path = gate.write_baseline(cur, tmp_path / "inf.json")
    assert "Infinity" in path.read_text()
    assert gate.read_baseline(path)["runs"][0]["energy_drift_max"] == math.inf
    assert main(["check", str(cur), "--baseline", str(path)]) == 0
    doc = json.loads(path.read_text())
    doc["runs"][0]["convergence_order"] = -0.5
    path.write_text(json.dumps(doc))
    assert gate.read_baseline(path)["runs"][0]["convergence_order"] == -0.5


def test_a_baseline_with_a_byte_order_mark_is_read(tmp_path, baseline):
    """A baseline saved by an editor that writes a UTF-8 byte-order mark is the same baseline
    (json refuses it: "Unexpected UTF-8 BOM")."""
    marked = tmp_path / "marked.json"
    marked.write_bytes(b"\xef\xbb\xbf" + baseline.read_bytes())
    cur = write(
        tmp_path / "cur",
        [row(), row(engine="pybullet", integrator="multibody", energy_drift_max=0.3)],
    )
    assert main(["check", str(cur), "--baseline", str(marked)]) == 0


# -- invariants ---------------------------------------------------------------------------------
def _frame(rows):
    from reports.store.results import frame

    return frame(rows)


def test_invariants_hold_on_consistent_rows(tmp_path):
    from reports.report import junit

    rows = [
        *sweep(4, convergence_order=4.0, convergence_points=3.0),
        row(engine="pybullet", integrator="multibody", status="diverged", verdict="fail"),
        row(engine="dart", integrator="x", status="unsupported", verdict=""),
    ]
    df = _frame(rows)
    path = junit.write(df, tmp_path / "junit.xml")
    assert gate.invariants(df, path) == []


def test_each_invariant_can_fail(tmp_path):
    from reports.report import junit

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


def test_an_order_above_the_generic_one_is_allowed_only_on_a_relative_equilibrium():
    # On a steady rotation the leading error term may vanish (Drake's semi-explicit Euler
    # fits order 2 on the spinning chain: the quaternion's normalised linear update is its
    # only error); on a generic motion the same fit means a mislabelled scheme.
    above = dict(order=1.0, convergence_order=2.0, convergence_points=2.0)
    steady = row(**above, reference_kind="spinning_chain")
    assert gate.invariants(_frame([steady])) == []
    generic = row(**above, reference_kind="free_body")
    assert len(gate.invariants(_frame([generic]))) == 1
    below = row(order=4.0, convergence_order=2.9, convergence_points=2.0)
    below["reference_kind"] = "steady_precession"  # below the order is wrong everywhere
    assert "fitted order 2.9" in gate.invariants(_frame([below]))[0]
