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

import errno
import json
import math
import os
import re
import xml.etree.ElementTree as ET

import pytest

from reports.gate import check as gate
from reports.gate.rule import Change, Comparison, VersionChange
from reports.store.results import frame
from reports.store.runs import IDENTITY_COLUMNS
from tests.reports.gate.test_gate import failing_row, row, write

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
    entry = {
        "scenario": "s",
        "engine": "e",
        "integrator": "i",
        "dt": 0.001,
        "status": "ok",
        "verdict": "pass",
        "target_accuracy": None,
        **dict.fromkeys(IDENTITY_COLUMNS),
    }
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


# -- the command: what check prints, writes and returns ------------------------------------------

OK_LINE = ("OK: the results' invariants hold (no blown-up run ok, verdicts match statuses, "
           "fitted orders within 0.3 of declared, junit.xml agrees).")  # fmt: skip
PYB = {"engine": "pybullet", "integrator": "multibody"}


@pytest.fixture
def bl(tmp_path):
    base = write(tmp_path / "base", [row(), row(**PYB, energy_drift_max=0.3)])
    return gate.write_baseline(base, tmp_path / "bl.json")


def test_check_prints_the_table_the_invariants_and_what_it_wrote(tmp_path, bl, capsys):
    """The mujoco run's drift 1e-8 -> 3e-8 (3x: a regression); the pybullet run's 0.3 -> 1.5:
    5x, and above the divergence limit (1.0) while ok: an invariant broken too."""
    cur = write(tmp_path / "cur", [row(energy_drift_max=3e-8), row(**PYB, energy_drift_max=1.5)])
    md, js = tmp_path / "out.md", tmp_path / "out.json"
    assert gate.check(cur, bl, markdown=md, json_path=js) == 1
    out = capsys.readouterr().out.split("\n")
    problem = "dzhanibekov pybullet multibody dt=0.001: status ok with energy drift 1.5"
    i = out.index("FAIL: 1 statement(s) the results must make true do not hold:")
    assert out[i + 1] == f"  {problem}"
    assert out[i + 2].startswith("::error title=director-bench regression%3A dzhanibekov ")
    assert out[i + 4] == f"::error title=director-bench invariant::{problem}"
    assert out[i + 5 :] == [f"written: {cur / 'junit.xml'}, {md}, {js}", ""]
    assert md.read_text().startswith("## director-bench check: FAIL")
    assert json.loads(js.read_text())["invariant_problems"] == [problem]
    assert not (cur / "check.md").exists() and not (cur / "check.json").exists()
    suite = ET.parse(cur / "junit.xml").getroot()
    assert (suite.get("baseline"), suite.get("failures")) == (str(bl), "2")


def test_check_passes_and_writes_beside_the_results_by_default(tmp_path, bl, capsys):
    cur = write(tmp_path / "cur", [row(), row(**PYB, energy_drift_max=0.3)])
    assert gate.check(cur, bl) == 0
    out = capsys.readouterr().out.split("\n")
    assert out[-3:] == [OK_LINE, f"written: {cur / 'junit.xml'}, {cur / 'check.md'}, "
                                 f"{cur / 'check.json'}", ""]  # fmt: skip
    # a drift 2.5x its baseline: beyond the default factor 2, within 3
    cur = write(tmp_path / "c2", [row(energy_drift_max=2.5e-8), row(**PYB, energy_drift_max=0.3)])
    assert gate.check(cur, bl) == 1 and gate.check(cur, bl, factor=3.0) == 0
    # a step 5x slower: gated only with a timing factor
    cur = write(tmp_path / "c3", [row(ns_per_step=5000.0), row(**PYB, energy_drift_max=0.3)])
    assert gate.check(cur, bl) == 0 and gate.check(cur, bl, timing_factor=3.0) == 1


def test_check_reads_the_junit_run_wrote_and_names_a_missing_run_in_it(tmp_path, bl, capsys):
    cur = write(tmp_path / "cur", [row()])  # the pybullet run is missing
    (cur / "junit.xml").write_text('<testsuite tests="7" failures="2" errors="0" skipped="0"/>')
    assert gate.check(cur, bl) == 1
    out = capsys.readouterr().out
    assert (f"FAIL: 2 statement(s) the results must make true do not hold:\n"
            f"  {cur / 'junit.xml'}: tests = 7, the results say 1\n"
            f"  {cur / 'junit.xml'}: failures = 2, the results say 0\n") in out  # fmt: skip
    suite = ET.parse(cur / "junit.xml").getroot()  # rewritten with the baseline's expectations
    (case,) = [c for c in suite if c.get("name") == "pybullet/multibody/dt=0.001"]
    assert case[0].tag == "failure" and "missing run" in case[0].get("message")


def test_check_with_nothing_comparable_prints_one_annotation(tmp_path, bl, capsys):
    cur = write(tmp_path / "cur", [row(scenario="heavy_top")])
    assert gate.check(cur, bl) == 1
    cap = capsys.readouterr()
    why = (f"{cur}: none of its 1 run(s) is in the baseline {bl} (2 runs): nothing was "
           "compared (another suite, or another baseline?)")  # fmt: skip
    assert cap.err == f"director-bench: error: {why}\n"
    assert cap.out == f"::error title=director-bench check%3A nothing compared::{why}\n"


def test_check_says_which_output_it_could_not_write(tmp_path, bl, capsys, monkeypatch):
    """The verdict stands when a summary cannot be written: a warning on stderr naming the
    file (when the system names one) and the reason; "written:" lists what was written."""
    cur = write(tmp_path / "cur", [row(), row(**PYB, energy_drift_max=0.3)])
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert gate.check(cur, bl, markdown=blocker / "c.md") == 0
    cap = capsys.readouterr()
    tail = "; the verdict above stands, but junit.xml and the summaries were not all written\n"
    assert cap.err.startswith(f"director-bench: warning: {blocker}") and cap.err.endswith(tail)
    assert f": {os.strerror(errno.ENOTDIR)}{tail}" in cap.err
    assert cap.out.split("\n")[-3:] == [OK_LINE, f"written: {cur / 'junit.xml'}", ""]

    def full(*args):
        raise OSError("disk full")

    monkeypatch.setattr(gate, "write_outputs", full)
    assert gate.check(cur, bl) == 0
    assert capsys.readouterr().err == f"director-bench: warning: disk full{tail}"


def test_findings_of_compare_name_what_changed(tmp_path, bl):
    """Runs of another horizon and save_every: mismatches naming both; a run gone from ok
    to diverged: its status with the message."""
    other = {"t_end": 10.0, "save_every": 1}
    cur = write(tmp_path / "cur", [row(**other), row(**PYB, energy_drift_max=0.3, **other)])
    m = {c.key[1]: c for c in gate.compare(cur, bl).regressions}["mujoco"]
    assert (m.column, m.a, m.b, m.change) == (
        "identity", "baseline", "t_end 30 vs 10; save_every 10 vs 1", "mismatch")  # fmt: skip
    cur = write(
        tmp_path / "c2",
        [row(), row(**PYB, status="diverged", verdict="fail", message="blew up at t = 1")],
    )
    (s,) = gate.compare(cur, bl).regressions
    assert (s.column, s.a, s.b, s.change) == (
        "status", "ok", "diverged: blew up at t = 1", "worse")  # fmt: skip


def test_a_run_that_no_longer_diverges_is_no_regression(tmp_path):
    """Diverged in the baseline (its attitude error 0.1 when it blew up), now run to the end
    and failing on attitude (1.0): its status improved, so nothing it measures now counts
    against it; it stays a failing run, listed with both reasons."""
    was = row(status="diverged", verdict="fail", message="blew up", attitude_error_max=0.1)
    bl = gate.write_baseline(write(tmp_path / "base", [was]), tmp_path / "bl.json")
    now = row(verdict="fail", verdict_detail="attitude_error_max 1 > 0.1", attitude_error_max=1.0)
    cmp = gate.compare(write(tmp_path / "cur", [now]), bl)
    assert cmp.ok and cmp.known == {K1: ("fail: attitude_error_max 1 > 0.1", "diverged: blew up")}


def test_the_energy_parts_are_checked_in_a_store_without_one_of_them(tmp_path):
    """A store written before the rotational part was measured still has its translational
    part checked."""
    df = frame([row(energy_drift_trans_max=2.0)]).drop(columns=["energy_drift_rot_max"])
    assert gate.invariants(df) == [
        "dzhanibekov mujoco RK4 dt=0.001: status ok with energy drift trans 2"
    ]


def test_the_findings_of_a_verdict(tmp_path):
    """pass -> fail: the verdict, with the run's reason; a failing run failing one more
    check: that check, with the baseline's reason; fail -> pass: nothing; a run the
    baseline could not run (unsupported) that now diverges: a verdict from pass to its
    status and message."""
    bl = gate.write_baseline(write(tmp_path / "b", [
        row(), failing_row(**PYB), row(integrator="Euler"),
        row(integrator="implicit", status="unsupported", message="not here")]),
        tmp_path / "bl.json")  # fmt: skip
    more = failing_row(**PYB, energy_drift_max=0.5)
    more["verdict_detail"] += "; energy_drift_max 0.5 > 0.01"
    cur = write(
        tmp_path / "c",
        [
            failing_row(),
            more,
            row(integrator="Euler"),
            row(integrator="implicit", status="diverged", verdict="fail", message="blew up"),
        ],
    )
    got = [(c.key[1], c.key[2], c.column, c.a, c.b, c.change)
           for c in gate.compare(cur, bl).regressions]  # fmt: skip
    assert got == [
        ("mujoco", "RK4", "verdict", "pass", "fail: attitude_error_max 0.5 > 0.1", "worse"),
        ("mujoco", "RK4", "attitude_error_max", 1e-06, 0.5, "worse"),
        ("mujoco", "implicit", "verdict", "pass", "diverged: blew up", "worse"),
        ("pybullet", "multibody", "failed checks", "fail: attitude_error_max 0.5 > 0.1",
         "also fails energy_drift_max: fail: attitude_error_max 0.5 > 0.1; energy_drift_max "
         "0.5 > 0.01", "worse"),
        ("pybullet", "multibody", "energy_drift_max", 1e-08, 0.5, "worse"),
    ]  # fmt: skip
    # the other way round: every run better or the same, none a regression
    back = gate.write_baseline(cur, tmp_path / "back.json")
    assert [c.key[2] for c in gate.compare(write(tmp_path / "d", [
        row(), failing_row(**PYB), row(integrator="Euler"),
        row(integrator="implicit", status="diverged", verdict="fail", message="blew up")]),
        back).regressions] == []  # fmt: skip


def test_compare_options_and_what_it_records(tmp_path, bl):
    # a factor of 1 is allowed (any worsening counts), below 1 is refused naming the option
    cur = write(tmp_path / "c", [row(energy_drift_max=1.5e-8), row(**PYB, energy_drift_max=0.3)])
    assert [c.column for c in gate.compare(cur, bl, factor=1.0).regressions] == ["energy_drift_max"]
    with pytest.raises(ValueError, match=r"^--factor 0\.5: must be a number >= 1$"):
        gate.compare(cur, bl, factor=0.5)
    cmp = gate.compare(cur, bl)
    assert (cmp.a, cmp.b) == (str(bl), str(cur))
    # the baseline's provenance is the comparison's (check.md names its commit)
    doc = json.loads(bl.read_text())
    doc["provenance"] = {"git_commit": "0123abc"}
    bl.write_text(json.dumps(doc))
    assert gate.compare(cur, bl).provenance_a == {"git_commit": "0123abc"}
    # only the runs present: a missing first run does not end the comparison
    cur = write(tmp_path / "d", [row(**PYB, energy_drift_max=1.5)])
    (reg,) = gate.compare(cur, bl, only_present=True).regressions
    assert (reg.key[1], reg.column) == ("pybullet", "energy_drift_max")


def test_runs_with_a_target_accuracy_are_matched_on_it(tmp_path):
    """Two error-controlled runs that differ only in their target accuracy are two runs."""
    runs = [row(integrator="RK45", target_accuracy=a, run_id=f"rk45-{a}") for a in (1e-6, 1e-8)]
    bl = gate.write_baseline(write(tmp_path / "b", runs), tmp_path / "bl.json")
    cmp = gate.compare(write(tmp_path / "c", runs), bl)
    assert cmp.ok and sorted(k[4] for k in cmp.compared) == [1e-8, 1e-6]


def test_the_baseline_file_as_written(tmp_path):
    """Strict JSON (no NaN), one line per key, keys sorted, a final newline, into folders
    made for it; per run its target accuracy (null for a fixed step), its failure reason (a
    failed verdict's detail, or a status and its message; empty for a pass) and failed checks,
    the folder's provenance."""
    folder = write(
        tmp_path / "r",
        [
            row(),
            row(
                integrator="Euler",
                verdict="fail",
                verdict_detail="attitude_error_max 0.5 > 0.1; energy_drift_max 1 > 0.1",
            ),
            row(integrator="RK45", target_accuracy=1e-8, run_id="rk45"),
            row(integrator="implicit", status="unsupported", verdict="", message="not in 3.3"),
        ],
    )
    (folder / "provenance.json").write_text('{"git_commit": "0123abc"}')
    path = gate.write_baseline(folder, tmp_path / "a" / "b" / "bl.json")
    text = path.read_text()
    assert path == tmp_path / "a" / "b" / "bl.json"
    assert text.startswith('{\n "format": 3,\n "provenance": {\n  "git_commit": "0123abc"\n },')
    assert text.endswith("}\n") and "NaN" not in text
    doc = json.loads(text)
    assert list(doc) == ["format", "provenance", "runs"]
    runs = doc["runs"]
    assert [list(r) == sorted(r) for r in runs] == [True] * 4
    got = [(r["integrator"], r["status"], r["verdict"], r["target_accuracy"], r["reason"],
            r["failed_checks"], r["segment"], r["t_end"]) for r in runs]  # fmt: skip
    assert got == [
        ("Euler", "ok", "fail", None,
         "fail: attitude_error_max 0.5 > 0.1; energy_drift_max 1 > 0.1",
         ["attitude_error_max", "energy_drift_max"], None, 30.0),
        ("RK4", "ok", "pass", None, "", [], None, 30.0),
        ("RK45", "ok", "pass", 1e-8, "", [], None, 30.0),
        ("implicit", "unsupported", "", None, "unsupported: not in 3.3", [], None, 30.0),
    ]  # fmt: skip


def test_more_ways_a_baseline_file_is_refused_or_read(tmp_path, monkeypatch):
    entry = {
        "scenario": "s",
        "engine": "e",
        "integrator": "i",
        "dt": 0.001,
        "status": "ok",
        "verdict": "pass",
        "target_accuracy": None,
        **dict.fromkeys(IDENTITY_COLUMNS),
    }
    path = tmp_path / "bl.json"

    def refused(doc):
        path.write_text(json.dumps(doc))
        with pytest.raises((ValueError, FileNotFoundError)) as exc:
            gate.read_baseline(path)
        return str(exc.value)

    assert refused({"format": 2, "runs": []}) == (
        f"{path}: baseline format 2, this suite reads format 3 (with each run's identity: "
        "scenario content, horizon, save_every, segmenting, engine and suite versions); write "
        "it again with `director-bench baseline DIR --write FILE`"
    )
    assert refused({"format": 3, "runs": [entry, {**entry, "verdict": "fail"}]}) == (
        f"{path}: runs[1] repeats the configuration of runs[0] (s e/i/dt=0.001): each run is "
        "in a baseline once (which of the two would count is not for the order of the file "
        "to decide); remove one, or write the baseline again with `director-bench baseline "
        "DIR --write FILE`"
    )
    # an entry without a verdict is a run with nothing to judge
    no_verdict = {k: v for k, v in entry.items() if k != "verdict"}
    path.write_text(json.dumps({"format": 3, "runs": [no_verdict]}))
    assert gate.read_baseline(path)["runs"] == [no_verdict]
    path.unlink()
    with pytest.raises(FileNotFoundError) as exc:
        gate.read_baseline(path)
    assert str(exc.value) == f"{path}: baseline file not found"
    # the size limit (64 MiB; 100 bytes here): one byte more is refused before it is parsed
    monkeypatch.setattr(gate, "MAX_BASELINE_BYTES", 100)
    path.write_text(" " * 101)
    with pytest.raises(ValueError) as exc:
        gate.read_baseline(path)
    assert str(exc.value) == f"{path}: not a baseline file (larger than 100 bytes)"
    path.write_text('{"format": 3, "runs": []}'.ljust(100))
    assert gate.read_baseline(path) == {"format": 3, "runs": []}


def test_the_fitted_order_of_every_configuration_is_checked(tmp_path):
    """A configuration above its order on a steady motion is let through; the next one,
    off its order on a generic motion, is still checked."""
    above = dict(order=1.0, convergence_order=2.0, convergence_points=2.0)
    steady = row(integrator="Euler", **above, reference_kind="spinning_chain")
    off = row(integrator="RK4", order=4.0, convergence_order=2.9, convergence_points=2.0,
              reference_kind="free_body")  # fmt: skip
    assert gate.invariants(frame([steady, off])) == [
        "dzhanibekov mujoco RK4: fitted order 2.900 from 2 points, declared 4"
    ]


def test_the_findings_for_runs_missing_or_new(tmp_path, bl):
    """Missing and new runs carry no column; a missing run's baseline status, and where the
    store holds it only as history, why: its identity differs from the baseline's (named),
    or its scenario's newest runs have another identity."""
    cur = write(tmp_path / "c", [row(), row(engine="dart", integrator="x")])
    got = {c.key[1]: c for c in gate.compare(cur, bl).regressions}
    assert [(k, c.column, c.a, c.b, c.change) for k, c in sorted(got.items())] == [
        ("dart", "", None, "ok", "new"), ("pybullet", "", "ok", None, "missing")]  # fmt: skip
    # the pybullet run stored with another horizon (20) and save_every (5), then the scenario
    # run again at 10
    old = row(**PYB, energy_drift_max=0.3, t_end=20.0, save_every=5,
              finished_at="2026-11-21T00:00:00")  # fmt: skip
    cur = write(tmp_path / "d", [old, row(t_end=10.0, run_id="new")])
    (miss,) = [c for c in gate.compare(cur, bl).regressions if c.change == "missing"]
    assert (miss.key[1], miss.a, miss.b) == (
        "pybullet", "ok", "history only: t_end 30 vs 20; save_every 10 vs 5")  # fmt: skip
    # the same run as the baseline's, superseded by an edited scenario's newer runs
    same = row(**PYB, energy_drift_max=0.3, finished_at="2026-11-21T00:00:00")
    cur = write(tmp_path / "e", [same, row(scenario_hash="edited", run_id="new")])
    (miss,) = [c for c in gate.compare(cur, bl).regressions if c.change == "missing"]
    assert miss.b == "history only: its scenario's newest runs have another identity"
    # a missing first run does not end the comparison of the others
    cur = write(tmp_path / "f", [row(**PYB, energy_drift_max=1.5)])
    assert sorted((c.key[1], c.change) for c in gate.compare(cur, bl).regressions) == [
        ("mujoco", "missing"),
        ("pybullet", "worse"),
    ]
    # the default factor is 2: a drift 2.5x its baseline is a regression
    cur = write(tmp_path / "g", [row(energy_drift_max=2.5e-8), row(**PYB, energy_drift_max=0.3)])
    assert [c.column for c in gate.compare(cur, bl).regressions] == ["energy_drift_max"]


def test_a_baseline_entry_without_its_reason_has_none(tmp_path):
    """The reader does not require an entry's reason (the writer always writes one): without
    it, a known failure's baseline reason and a failed-checks finding's baseline value are
    empty."""
    bl = gate.write_baseline(write(tmp_path / "b", [failing_row(), failing_row(**PYB)]),
                             tmp_path / "bl.json")  # fmt: skip
    doc = json.loads(bl.read_text())
    for entry in doc["runs"]:
        del entry["reason"]
    bl.write_text(json.dumps(doc))
    more = failing_row(**PYB, energy_drift_max=0.5)
    more["verdict_detail"] += "; energy_drift_max 0.5 > 0.01"
    cmp = gate.compare(write(tmp_path / "c", [failing_row(), more]), bl)
    assert cmp.known == {K1: ("fail: attitude_error_max 0.5 > 0.1", "")}
    (f,) = [c for c in cmp.regressions if c.column == "failed checks"]
    assert f.a == ""


def test_a_baseline_file_that_is_no_file_or_no_text(tmp_path):
    entry = {
        "scenario": "s",
        "engine": "e",
        "integrator": "i",
        "dt": 0.001,
        "status": "ok",
        "verdict": "pass",
        "target_accuracy": None,
        **dict.fromkeys(IDENTITY_COLUMNS),
    }
    cases = {
        "dir": (None, "not a baseline file (not a regular file)"),
        "latin1.json": (b'{"runs": ["\xe9"]}', "cannot read the baseline file ("),
        "lacks.json": (json.dumps({"format": 3, "runs": [{"scenario": "s"}]}).encode(),
                       "runs[0] lacks engine, integrator, dt, status, scenario_hash, t_end, "
                       "save_every, segment, engine_version, suite_version"),
        "zero.json": (json.dumps({"format": 3, "runs": [{**entry, "target_accuracy": 0.0}]})
                      .encode(), "runs[0].target_accuracy = 0.0: a target accuracy is in (0, "
                      "1), or null for a fixed step"),
        "neg.json": (json.dumps({"format": 3, "runs": [{**entry, "attitude_error_max": -1}]})
                     .encode(), "runs[0].attitude_error_max = -1: must be >= 0 (an error, a "
                     "drift or a cost; Infinity for a blow-up)"),
    }  # fmt: skip
    for name, (data, words) in cases.items():
        path = tmp_path / name
        if data is None:
            path.mkdir()
        else:
            path.write_bytes(data)
        with pytest.raises(ValueError) as exc:
            gate.read_baseline(path)
        assert str(exc.value).startswith(f"{path}: {words}"), name
