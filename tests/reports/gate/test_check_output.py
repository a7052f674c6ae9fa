"""What ``director-bench check`` prints and writes (reports/gate/check.py: the table, the
messages, the JUnit notes, the GitHub annotations, check.md and check.json), from a comparison
written by hand, and the small rules beside them (a failure's reason, a number as the
baseline file spells it, junit.xml against the results, the closing line's count of known
failures). Every expected line is written here from docs/results.md ("The CI gate") and the
numbers' format (``%.3e`` for a value, ``%.3g`` for a ratio) applied to the planted values.

The comparison: six runs checked (factor 2), one failing as in the baseline, one passing, and
six findings in five runs: an energy drift 3x its baseline and, on the same run, a verdict
gone from pass to fail; a status gone from ok to diverged; a run missing (the store holds it
as history); a new run (with a target accuracy); a run of another identity. passed = 6
checked - 4 regressed among them (the new run is not among the checked) - 1 known = 1."""

from __future__ import annotations

import json
import math
import re

import pytest

from reports.gate import check as gate
from reports.gate.rule import Change, Comparison, VersionChange
from reports.store.results import frame
from tests.reports.gate.test_gate import baseline_entry, failing_row, row, write

K1 = ("dzhanibekov", "mujoco", "RK4", 0.001, None)
K2 = ("heavy_top", "pybullet", "multibody", 0.002, None)
K3 = ("free_tumbling", "dart", "semi-implicit Euler", 0.001, None)
K4 = ("free_tumbling", "drake", "RK3", 0.001, 1e-08)
K5 = ("tennis_racket", "mujoco", "Euler", 0.0005, None)
K6 = ("heavy_top", "mujoco", "RK4", 0.001, None)
K7 = ("dzhanibekov", "mujoco", "Euler", 0.001, None)
FAIL_DETAIL = "fail: energy_drift_max 3e-08 > 1e-08"


@pytest.fixture
def cmp():
    c = Comparison("bl.json", "results", 2.0)
    c.provenance_a = {"git_commit": "abc1234"}
    c.compared = [K1, K2, K3, K5, K6, K7]
    c.changes = [
        Change(K1, "energy_drift_max", 1e-8, 3e-8, 3.0, "worse", True),
        Change(K1, "verdict", "pass", FAIL_DETAIL, change="worse", gates=True),
        Change(K2, "status", "ok", "diverged: blew up", change="worse", gates=True),
        Change(K3, "", "ok", "history only: t_end 30 vs 10", change="missing", gates=True),
        Change(K4, "", None, "ok", change="new", gates=True),
        Change(K5, "identity", "baseline", "t_end 30 vs 10", change="mismatch", gates=True),
    ]
    c.known = {K6: ("fail: attitude_error_max 0.5 > 0.1", "fail: attitude_error_max 0.4 > 0.1")}
    c.versions = {("mujoco", "3.3.0", "3.3.1"): VersionChange("mujoco", "3.3.0", "3.3.1", 3, 1,
                                                                1, 0)}  # fmt: skip
    return c


RELEASE = ("mujoco 3.3.0 -> 3.3.1: 3 runs compared, 1 changed (1 identical in every metric, "
           "1 regressed, 0 better)")  # fmt: skip
HEAD = ("6 runs checked against the baseline (factor 2): 5 regressed, 1 known failure(s) "
        "failing as in the baseline (expected, not regressions)")  # fmt: skip
MESSAGES = [
    "energy_drift_max: baseline 1.000e-08, now 3.000e-08 (3x)",
    f"verdict: baseline pass, now {FAIL_DETAIL}",
    "status: baseline ok, now diverged: blew up",
    "missing run (in the baseline with status ok); the store holds it as history only: t_end "
    "30 vs 10",
    "new run, not in the baseline (status ok); write the baseline again if it belongs to the suite",
    "not the baseline's run: t_end 30 vs 10",
]
NAMES = [
    "dzhanibekov mujoco/RK4/dt=0.001",
    "dzhanibekov mujoco/RK4/dt=0.001",
    "heavy_top pybullet/multibody/dt=0.002",
    "free_tumbling dart/semi-implicit Euler/dt=0.001",
    "free_tumbling drake/RK3/dt=0.001/accuracy=1e-08",
    "tennis_racket mujoco/Euler/dt=0.0005",
]
PROBLEMS = ["energy_drift_max", "verdict got worse", "status got worse", "missing run",
            "new run (not in baseline)", "identity mismatch"]  # fmt: skip
BEFORE = ["1.000e-08", "pass", "ok", "ok", "-", "baseline"]
NOW = ["3.000e-08", FAIL_DETAIL, "diverged: blew up", "history only: t_end 30 vs 10", "ok",
       "t_end 30 vs 10"]  # fmt: skip
RATIOS = ["3", "", "", "", "", ""]


def _cells(line):
    return re.split(r" {2,}", line.strip())


def test_each_finding_as_one_line(cmp):
    assert [gate.message(c) for c in cmp.changes] == MESSAGES
    # a missing run the store does not hold at all; a metric whose value is gone (no ratio)
    assert gate.message(Change(K3, "", "error", None, change="missing", gates=True)) == (
        "missing run (in the baseline with status error)")  # fmt: skip
    gone = Change(K1, "attitude_error_max", 2e-3, None, math.nan, "worse", True)
    assert gate.message(gone) == "attitude_error_max: baseline 2.000e-03, now -"
    assert gate.message(Change(K1, "x", 7, 12, 12 / 7, "worse", True)) == (
        "x: baseline 7, now 12 (1.71x)")  # fmt: skip
    # a failing run failing one more check: named by that column, not by its kind (verdict)
    more = Change(K1, "failed checks", "fail: a 1 > 0", "also fails b: fail: a 1 > 0; b 2 > 1",
                  change="worse", gates=True)  # fmt: skip
    assert gate.message(more) == (
        "failed checks: baseline fail: a 1 > 0, now also fails b: fail: a 1 > 0; b 2 > 1"
    )
    assert [gate.run_name(c.key) for c in cmp.changes] == NAMES


def test_the_table(cmp):
    lines = gate.format_comparison(cmp).split("\n")
    assert lines[:2] == [f"engine release {RELEASE}", f"FAIL: 6 finding(s) in 5 run(s); {HEAD}:"]
    assert _cells(lines[2]) == ["scenario", "engine", "integrator", "dt", "problem", "baseline",
                                "current", "ratio"]  # fmt: skip
    assert set(lines[3]) == {"-"} and len(lines) == 10
    want = []
    for key, problem, a, b, ratio in zip([c.key for c in cmp.changes], PROBLEMS, BEFORE, NOW,
                                         RATIOS, strict=True):  # fmt: skip
        sc, eng, integ, dt, acc = key
        integ = integ if acc is None else f"{integ} (accuracy 1e-08)"
        want.append([x for x in (sc, eng, integ, f"{dt:g}", problem, a, b, ratio) if x])
    assert [_cells(x) for x in lines[4:]] == want
    assert want[5][3] == "0.0005" and want[4][2] == "RK3 (accuracy 1e-08)"
    # nothing regressed: one line, the release first
    cmp.changes = []
    assert gate.format_comparison(cmp).split("\n") == [
        f"engine release {RELEASE}",
        "OK: 6 runs checked against the baseline (factor 2): 0 regressed, 1 known failure(s) "
        "failing as in the baseline (expected, not regressions).",
    ]


def test_junit_notes_and_annotations(cmp):
    notes, missing = gate.junit_notes(cmp)
    assert notes == {
        K6: ("known", "fail: attitude_error_max 0.5 > 0.1"),
        K1: ("regression", f"{MESSAGES[0]}; {MESSAGES[1]}"),
        K2: ("regression", MESSAGES[2]),
        K4: ("regression", MESSAGES[4]),
        K5: ("regression", MESSAGES[5]),
    }
    assert missing == [(K3, MESSAGES[3])]
    title = "::error title=director-bench regression%3A "
    assert gate.annotations(cmp) == [
        f"{title}dzhanibekov mujoco/RK4/dt=0.001::{MESSAGES[0]}; {MESSAGES[1]}",
        f"{title}heavy_top pybullet/multibody/dt=0.002::{MESSAGES[2]}",
        f"{title}free_tumbling dart/semi-implicit Euler/dt=0.001::{MESSAGES[3]}",
        f"{title}free_tumbling drake/RK3/dt=0.001/accuracy=1e-08::{MESSAGES[4]}",
        f"{title}tennis_racket mujoco/Euler/dt=0.0005::{MESSAGES[5]}",
    ]
    assert gate.annotation("t", "m", level="warning") == "::warning title=t::m"
    assert gate.annotation("a%\r", "b\r%") == "::error title=a%25%0D::b%0D%25"


def _run(key):
    return dict(zip(("scenario", "engine", "integrator", "dt", "target_accuracy"), key,
                    strict=True))  # fmt: skip


def test_the_json(cmp):
    doc = gate.as_json(cmp, ["x: status ok with energy drift 2"])
    assert {k: doc[k] for k in ("ok", "results", "baseline", "baseline_git_commit", "factor")} == {
        "ok": False, "results": "results", "baseline": "bl.json",
        "baseline_git_commit": "abc1234", "factor": 2.0}  # fmt: skip
    assert doc["counts"] == {"checked": 6, "regressed": 5, "known_failures": 1, "passed": 1,
                             "findings": 6, "invariant_problems": 1}  # fmt: skip
    assert doc["findings"] == [
        {"run": _run(c.key), "what": what, "metric": c.column, "baseline": a, "current": b,
         "ratio": ratio, "message": msg}
        for c, what, a, b, ratio, msg in zip(
            cmp.changes, ["metric", "verdict", "status", "missing", "new", "mismatch"],
            [1e-8, "pass", "ok", "ok", None, "baseline"],
            [3e-8, FAIL_DETAIL, "diverged: blew up", "history only: t_end 30 vs 10", "ok",
             "t_end 30 vs 10"],
            [3.0, None, None, None, None, None], MESSAGES, strict=True)
    ]  # fmt: skip
    assert doc["known_failures"] == [
        {
            "run": _run(K6),
            "reason": "fail: attitude_error_max 0.5 > 0.1",
            "baseline_reason": "fail: attitude_error_max 0.4 > 0.1",
        }
    ]
    assert doc["engine_releases"] == [{"engine": "mujoco", "a": "3.3.0", "b": "3.3.1",
                                       "compared": 3, "identical": 1, "regressed": 1,
                                       "better": 0}]  # fmt: skip
    assert doc["invariant_problems"] == ["x: status ok with energy drift 2"]
    # a metric finding without a ratio, a regression-free comparison with a problem, and one
    # without any: ok only in the last
    cmp.changes = [Change(K1, "attitude_error_max", 2e-3, math.nan, math.nan, "worse", True)]
    (f,) = gate.as_json(cmp, [])["findings"]
    assert (f["current"], f["ratio"]) == (None, None)
    cmp.changes = []
    assert not gate.as_json(cmp, ["p"])["ok"] and gate.as_json(cmp, [])["ok"]
    assert gate.as_json(cmp, [])["counts"]["passed"] == 5


def test_the_markdown(cmp):
    md = gate.as_markdown(cmp, ["x: status ok with energy drift 2 > 1"])
    assert md.endswith("</details>\n")
    rows = [
        f"| {n} | {p} | {a} | {b} | {r} |".replace(">", "&gt;")
        for n, p, a, b, r in zip(NAMES, PROBLEMS, BEFORE, NOW, RATIOS, strict=True)
    ]
    assert md.split("\n")[:-1] == [
        "## director-bench check: FAIL", "",
        "Results `results` against the baseline `bl.json` (abc1234), factor 2.", "",
        "| runs checked | passed | known failures (as in the baseline) | regressed | "
        "invariant problems |",
        "|---:|---:|---:|---:|---:|",
        "| 6 | 1 | 1 | 5 | 1 |", "",
        "Engine releases other than the baseline's (the same runs, compared as usual):", "",
        "- " + RELEASE.replace(">", "&gt;"), "",
        "### Regressions", "",
        "| run | problem | baseline | now | ratio |", "|---|---|---|---|---:|", *rows, "",
        "### Invariants that do not hold", "",
        "- x: status ok with energy drift 2 &gt; 1", "",
        "<details><summary>1 known failure(s), failing as in the baseline</summary>", "",
        "| run | reason |", "|---|---|",
        "| heavy_top mujoco/RK4/dt=0.001 | fail: attitude_error_max 0.5 &gt; 0.1 |", "",
        "</details>",
    ]  # fmt: skip
    # nothing to report but the counts: no section, the commit unknown
    clean = Comparison("bl.json", "results", 3.0)
    clean.compared = [K7]
    assert gate.as_markdown(clean, []) == "\n".join([
        "## director-bench check: OK", "",
        "Results `results` against the baseline `bl.json` (unknown commit), factor 3.", "",
        "| runs checked | passed | known failures (as in the baseline) | regressed | "
        "invariant problems |",
        "|---:|---:|---:|---:|---:|",
        "| 1 | 1 | 0 | 0 | 0 |"]) + "\n"  # fmt: skip


def test_write_outputs_writes_both_and_appends_the_job_summary(cmp, tmp_path, monkeypatch):
    summary = tmp_path / "summary.md"
    summary.write_text("earlier\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    md, js = tmp_path / "c.md", tmp_path / "c.json"
    gate.write_outputs(cmp, [], md, js)
    assert md.read_text() == gate.as_markdown(cmp, [])
    text = js.read_text()
    assert text.startswith('{\n "ok": false,\n "results": "results",') and text.endswith("}\n")
    assert json.loads(text) == json.loads(json.dumps(gate.as_json(cmp, [])))
    assert summary.read_text() == "earlier\n" + md.read_text()
    monkeypatch.delenv("GITHUB_STEP_SUMMARY")
    gate.write_outputs(cmp, [], md, js)
    assert summary.read_text() == "earlier\n" + md.read_text()  # not appended without it


def test_a_failure_reason():
    """Its verdict detail when the run ran to the end, else its status and message (or the
    detail without one), cut to 400 characters ending in "..."."""
    r = gate._reason
    assert r({"status": "ok", "verdict_detail": "x 1 > 0.1"}) == "fail: x 1 > 0.1"
    assert r({"status": "ok", "verdict_detail": None}) == "fail: "
    assert r({"status": "ok"}) == "fail: "
    assert r({"status": "diverged", "message": "blew up", "verdict_detail": "d"}) == (
        "diverged: blew up")  # fmt: skip
    assert r({"status": "error", "message": "", "verdict_detail": "d"}) == "error: d"
    assert r({"status": "error", "message": None, "verdict_detail": "d"}) == "error: d"
    assert r({"status": "error"}) == "error: "
    assert r({}) == ": "
    assert r({"status": "ok", "verdict_detail": "y" * 394}) == "fail: " + "y" * 394  # 400
    assert r({"status": "ok", "verdict_detail": "y" * 395}) == "fail: " + "y" * 391 + "..."
    assert len(r({"status": "error", "message": "z" * 1000})) == 400


def test_a_number_as_the_baseline_file_spells_it():
    assert [gate._json_text(v) for v in (math.nan, math.inf, -math.inf, 1.5, 3, True)] == [
        "NaN", "Infinity", "-Infinity", "1.5", "3", "True"]  # fmt: skip


def test_a_baseline_number_below_its_rule_names_it(tmp_path):
    entry = baseline_entry()
    cases = {
        ("energy_drift_max", -math.inf): "runs[0].energy_drift_max = -Infinity: must be >= 0",
        ("dt", 0.0): "runs[0].dt = 0.0: a step must be finite and > 0",
        ("dt", None): "runs[0].dt = None is not a number",
        ("target_accuracy", 1.0): "runs[0].target_accuracy = 1.0: a target accuracy is in (0, 1)",
        ("convergence_order", math.inf): "runs[0].convergence_order = Infinity: a fitted order "
                                         "must be finite",
        ("energy_drift_max", True): "runs[0].energy_drift_max = True is not a number",
    }  # fmt: skip
    for (field, value), words in cases.items():
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps({"format": 3, "runs": [{**entry, field: value}]}))
        with pytest.raises(ValueError) as exc:
            gate.read_baseline(bad)
        assert str(exc.value).startswith(f"{bad}: {words}"), field
    # the edges that are allowed: a metric of 0, an accuracy just inside (0, 1), a null one
    for field, value in (("energy_drift_max", 0.0), ("target_accuracy", 0.999),
                         ("target_accuracy", None), ("convergence_order", -3.0)):  # fmt: skip
        bad.write_text(json.dumps({"format": 3, "runs": [{**entry, field: value}]}))
        assert gate.read_baseline(bad)["runs"][0][field] == value


def test_junit_xml_against_the_results(tmp_path):
    """tests = rows; failures = failed verdicts of runs that are not errors; errors = error
    rows (a verdict of theirs is not a failure); skipped = unsupported, unavailable,
    reference-inaccurate."""
    df = frame([row(), row(integrator="Euler", verdict="fail"),
                row(integrator="implicit", status="error", verdict="fail"),
                row(integrator="x", status="unsupported", verdict=""),
                row(integrator="y", status="diverged", verdict="fail")])  # fmt: skip
    path = tmp_path / "junit.xml"
    path.write_text('<testsuite tests="5" failures="2" errors="1" skipped="1"/>')
    assert gate._junit_agrees(df, path) == []
    path.write_text('<testsuite tests="4" failures="3" errors="0" skipped="2"/>')
    assert gate._junit_agrees(df, path) == [
        f"{path}: tests = 4, the results say 5",
        f"{path}: failures = 3, the results say 2",
        f"{path}: errors = 0, the results say 1",
        f"{path}: skipped = 2, the results say 1",
    ]
    path.write_text('<testsuite baseline="bl.json" tests="0"/>')  # written by check: its own
    assert gate._junit_agrees(df, path) == []
    path.write_text("<testsuite")
    (msg,) = gate._junit_agrees(df, path)
    assert msg.startswith(f"{path}: not readable JUnit XML (")
    (msg,) = gate._junit_agrees(df, tmp_path / "none.xml")
    assert msg.startswith(f"{tmp_path / 'none.xml'}: not readable JUnit XML (")
    assert gate.invariants(df, tmp_path / "none.xml") == [*gate.invariants(df), msg]


def test_the_closing_line_counts_known_other_and_absent_failures(tmp_path):
    """failures_in_baseline: (failing as in the baseline, failing otherwise, not in it)."""
    base = write(tmp_path / "base", [failing_row(), row(engine="pybullet", integrator="multibody")])
    bl = gate.write_baseline(base, tmp_path / "bl.json")
    other = row(engine="pybullet", integrator="multibody", verdict="fail",
                verdict_detail="energy_drift_max 1 > 0.01")  # fmt: skip
    absent = row(engine="dart", integrator="x", status="error", verdict="", message="boom")
    df = frame([failing_row(), other, absent])
    assert gate.failures_in_baseline(tmp_path / "r", df, bl) == (1, 1, 1)
    assert gate.failures_in_baseline(tmp_path / "r", frame([failing_row(), row(
        engine="pybullet", integrator="multibody")]), bl) == (1, 0, 0)  # fmt: skip
    assert gate.failures_in_baseline(tmp_path / "r", frame([row()]), bl) == (0, 0, 0)
    # none of the failing runs in the baseline, nor any other: nothing comparable
    assert gate.failures_in_baseline(tmp_path / "r", frame([absent]), bl) == (0, 0, 1)
