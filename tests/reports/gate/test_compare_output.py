"""What ``director-bench compare`` prints and writes (reports/gate/compare.py's text, Markdown
and JSON, and run_compare's files and exit code), on two folders written row by row (no
engine runs). Every expected line is written here from the rule (docs/results.md, "Comparing
two result folders") applied by hand to the planted values, with the numbers as the suite's
tables write them (three significant digits, reports/store/format.py):

A -> B, factor 2, free_tumbling on mujoco 1.0 -> 1.1, all at dt 0.001 but two:

- Euler: attitude error 1e-3 -> 1e-2: ``worse``, B/A 10, gates;
- RK4: 1e-3 -> 1.5e-3: ``same`` (1.5 < 2), not shown;
- implicit: 1e-3 -> 1e-4: ``better``, B/A 0.1;
- implicitfast: engine ns per step 1000 -> 3000, ranges +-1 ns: ``worse`` (2999 > 2 x 1001)
  but costs gate only with a cost factor: ``worse (not gated)``;
- discrete: the same 1000 -> 3000, but A's slowest repeat took 4000: ``not significant``;
- semi: 1000 -> 3000 with B's spread half its engine time (beyond STARVED = 0.1): ``starved``;
- Euler at dt 0.0005 only in A (ok), RK45 at tolerance 1e-8 only in B (error).

Runs in both: 6; worse 1 (Euler), better 1 (implicit), the same 6 - 1 - 1 = 4. The release
change counts the 6 pairs: 2 changed (Euler regressed, implicit better), 3 identical in every
metric (discrete, implicitfast, semi: only their costs differ)."""

from __future__ import annotations

import errno
import json
import os
import re

import pytest

import scenarios
from reports.gate.compare import (
    as_json,
    as_markdown,
    compare_folders,
    format_comparison,
    run_compare,
)
from tests.reports.gate.test_compare_rule import _folder, _row

M = "attitude_error_max"
NS = "engine_ns_per_step"


def _cost(ns, slowest=None, spread=1e-6):
    """A cost of ``ns`` ns per step over the rows' 1000 steps: engine time ns * 1e-6 s, its
    uncertainty ``spread`` s (1e-6 s: +-1 ns per step), the slowest repeat ``slowest``."""
    return {NS: ns, "engine_time_s": ns * 1e-6, "engine_time_spread_s": spread,
            "engine_time_max_s": (slowest or ns) * 1e-6}  # fmt: skip


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    sc = scenarios.load("free_tumbling")
    root = tmp_path_factory.mktemp("compare-output")
    a = _folder(root / "a", [
        _row(sc, "Euler"), _row(sc, "RK4"), _row(sc, "implicit"),
        _row(sc, "implicitfast", **_cost(1000.0)),
        _row(sc, "discrete", **_cost(1000.0, slowest=4000.0)),
        _row(sc, "semi", **_cost(1000.0)),
        _row(sc, "Euler", dt=5e-4),
    ])  # fmt: skip
    v = "1.1"
    b = _folder(root / "b", [
        _row(sc, "Euler", version=v, **{M: 1e-2}), _row(sc, "RK4", version=v, **{M: 1.5e-3}),
        _row(sc, "implicit", version=v, **{M: 1e-4}),
        _row(sc, "implicitfast", version=v, **_cost(3000.0)),
        _row(sc, "discrete", version=v, **_cost(3000.0)),
        _row(sc, "semi", version=v, **_cost(3000.0, spread=1.5e-3)),
        _row(sc, "RK45", version=v, accuracy=1e-8, status="error"),
    ])  # fmt: skip
    return a, b


RUN = "free_tumbling mujoco {} dt 0.001"
# (change, run, what, A, B, B/A): mismatches and worse first, gating before not gating, then
# better, then the costs that are not changes; within a word by run
ROWS = [
    ["worse", RUN.format("Euler"), M, "0.00100", "0.0100", "10.0"],
    ["worse (not gated)", RUN.format("implicitfast"), NS, "1000", "3000", "3.00"],
    ["better", RUN.format("implicit"), M, "0.00100", "1.00e-4", "0.100"],
    ["not significant", RUN.format("discrete"), NS, "1000", "3000", "3.00"],
    ["starved", RUN.format("semi"), NS, "1000", "3000", "3.00"],
]
RELEASE = "mujoco 1.0 -> 1.1: 6 runs compared, 2 changed (3 identical in every metric, " \
          "1 regressed, 1 better)"  # fmt: skip
SUMMARY = (
    "6 runs in both: 0 identity mismatch(es), 1 worse, 1 better, 4 the same within a factor 2 "
    "(above round-off floors; cost not gated (--cost-factor F to gate it); 1 cost change(s) "
    "beyond the factor but within the measured spread: not significant; 1 beyond it where a "
    "side was timed starved (no repeat ran clean enough to know the engine's CPU time): "
    "starved); 1 only in A, 1 only in B."
)
ONLY_A = "free_tumbling mujoco Euler dt 0.0005 (ok)"
ONLY_B = "free_tumbling mujoco RK45 tol 1e-8 (error)"
VERDICT = "FAIL: 1 run(s) got worse beyond a factor 2."


def _cells(line):
    return re.split(r" {2,}", line.strip())


def test_the_text_names_every_change_in_order(folders):
    a, b = folders
    lines = format_comparison(compare_folders(a, b)).split("\n")
    assert lines[:5] == [f"A: {a}", f"B: {b}", RELEASE, SUMMARY, ""]
    assert _cells(lines[5]) == ["change", "run", "what", "A", "B", "B/A"]
    assert set(lines[6]) == {"-"}
    assert [_cells(x) for x in lines[7:12]] == ROWS
    assert lines[12:] == ["", "Only in A (1):", f"  {ONLY_A}", "", "Only in B (1):",
                          f"  {ONLY_B}", "", VERDICT]  # fmt: skip


def test_every_change_with_show_all(folders):
    """--all: the 15 changes (attitude error and energy drift of each of the 6 runs, and the
    3 costs), the 10 that are the same after the 5 above."""
    a, b = folders
    lines = format_comparison(compare_folders(a, b), show_all=True).split("\n")
    rows = [_cells(x) for x in lines[7:22]]
    assert rows[:5] == ROWS
    assert [r[0] for r in rows[5:]] == ["same"] * 10
    assert {(r[1].split()[2], r[2]) for r in rows[5:]} == {
        (i, m) for i in ("Euler", "RK4", "discrete", "implicit", "implicitfast", "semi")
        for m in (M, "energy_drift_max") if (i, m) not in {("Euler", M), ("implicit", M)}
    }  # fmt: skip
    assert lines[22] == ""


def test_a_gated_cost_and_a_varied_column_in_the_summary(folders):
    a, b = folders
    cmp = compare_folders(a, b, cost_factor=2.0, vary=("t_end",))
    lines = format_comparison(cmp).split("\n")
    assert lines[2] == (
        "mujoco 1.0 -> 1.1: 6 runs compared, 3 changed (3 identical in every metric, "
        "2 regressed, 1 better)"
    )
    assert lines[3] == (
        "6 runs in both: 0 identity mismatch(es), 2 worse, 1 better, 3 the same within a "
        "factor 2 (above round-off floors; cost gated at 2x; 1 cost change(s) beyond the "
        "factor but within the measured spread: not significant; 1 beyond it where a side was "
        "timed starved (no repeat ran clean enough to know the engine's CPU time): starved; "
        "allowed to differ: t_end); 1 only in A, 1 only in B."
    )
    assert _cells(lines[8])[0] == "worse"  # the cost gates now: no "(not gated)"
    assert lines[-1] == "FAIL: 2 run(s) got worse beyond a factor 2."


def test_the_markdown(folders):
    a, b = folders
    md = as_markdown(compare_folders(a, b))
    assert md.endswith("\n") and not md.endswith("\n\n")
    rows = [f"| {' | '.join(r)} |" for r in ROWS]
    assert md.split("\n")[:-1] == [
        "## director-bench compare: FAIL", "",
        f"A `{a}`, B `{b}`.", "",
        RELEASE.replace("->", "-&gt;") + "  ",
        SUMMARY, "",
        "| change | run | what | A | B | B/A |", "|---|---|---|---|---|---:|", *rows, "",
        "Only in A (1):", "", f"- {ONLY_A}", "",
        "Only in B (1):", "", f"- {ONLY_B}", "",
        VERDICT,
    ]  # fmt: skip
    assert as_markdown(compare_folders(a, a)).split("\n")[:3] == [
        "## director-bench compare: OK", "", f"A `{a}`, B `{a}`."]  # fmt: skip


def _run(integ, dt=1e-3, acc=None):
    return {"scenario": "free_tumbling", "engine": "mujoco", "integrator": integ, "dt": dt,
            "target_accuracy": acc}  # fmt: skip


def test_the_json(folders):
    a, b = folders
    doc = as_json(compare_folders(a, b))
    head = {"ok": False, "a": str(a), "b": str(b), "factor": 2.0, "cost_factor": None,
            "vary": []}  # fmt: skip
    assert {k: doc[k] for k in head} == head
    assert doc["counts"] == {"in_both": 6, "worse": 1, "mismatch": 0, "better": 1, "same": 4,
                             "cost_not_significant": 1, "cost_starved": 1, "only_a": 1,
                             "only_b": 1}  # fmt: skip
    want = [
        ("Euler", M, "worse", True, 1e-3, 1e-2, 10.0),
        ("implicitfast", NS, "worse", False, 1000.0, 3000.0, 3.0),
        ("implicit", M, "better", True, 1e-3, 1e-4, 0.1),
        ("discrete", NS, "not significant", False, 1000.0, 3000.0, 3.0),
        ("semi", NS, "starved", False, 1000.0, 3000.0, 3.0),
    ]
    got = doc["changes"]
    assert [set(c) for c in got] == [{"run", "what", "change", "gates", "a", "b", "ratio"}] * 5
    assert [c["run"] for c in got] == [_run(w[0]) for w in want]
    assert [(c["what"], c["change"], c["gates"], c["a"], c["b"]) for c in got] == [
        w[1:6] for w in want]  # fmt: skip
    assert [c["ratio"] for c in got] == [pytest.approx(w[6], rel=1e-12) for w in want]
    assert doc["engine_releases"] == [{"engine": "mujoco", "a": "1.0", "b": "1.1", "compared": 6,
                                       "identical": 3, "regressed": 1, "better": 1}]  # fmt: skip
    assert doc["only_a"] == [{"run": _run("Euler", 5e-4), "status": "ok"}]
    assert doc["only_b"] == [{"run": _run("RK45", 1e-3, 1e-8), "status": "error"}]
    json.dumps(doc, allow_nan=False)  # JSON as the standard has it: no NaN


def test_a_ratio_that_means_nothing_is_null_in_json_and_blank_in_the_table(tmp_path):
    """A status change has no ratio: JSON null, an empty B/A cell."""
    sc = scenarios.load("free_tumbling")
    a = _folder(tmp_path / "a", [_row(sc, "Euler")])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", status="diverged", verdict="fail")])
    cmp = compare_folders(a, b)
    (c,) = as_json(cmp)["changes"]
    assert (c["what"], c["change"], c["a"], c["b"], c["ratio"]) == (
        "status", "worse", "ok", "diverged", None)  # fmt: skip
    lines = format_comparison(cmp).split("\n")
    assert lines[2] == (  # one engine release: no release line
        "1 runs in both: 0 identity mismatch(es), 1 worse, 0 better, 0 the same within a "
        "factor 2 (above round-off floors; cost not gated (--cost-factor F to gate it); 0 cost "
        "change(s) beyond the factor but within the measured spread: not significant; 0 beyond "
        "it where a side was timed starved (no repeat ran clean enough to know the engine's "
        "CPU time): starved); 0 only in A, 0 only in B."
    )
    # B/A empty
    assert _cells(lines[6]) == ["worse", RUN.format("Euler"), "status", "ok", "diverged"]
    assert "Only in" not in "\n".join(lines)


def test_run_compare_prints_writes_and_exits(folders, tmp_path, capsys, monkeypatch):
    a, b = folders
    summary = tmp_path / "summary.md"
    summary.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(summary))
    md, js = tmp_path / "out" / "c.md", tmp_path / "out" / "c.json"
    md.parent.mkdir()
    assert run_compare(a, b, markdown=md, json_path=js) == 1
    out = capsys.readouterr().out.split("\n")
    assert out[:4] == [f"A: {a}", f"B: {b}", RELEASE, SUMMARY]
    assert out[-3:] == [VERDICT, f"written: {md}, {js}", ""]
    assert [_cells(x) for x in out[7:12]] == ROWS and out[12] == ""  # not --all: no "same"
    cmp = compare_folders(a, b)
    assert md.read_text() == as_markdown(cmp)
    assert json.loads(js.read_text()) == json.loads(json.dumps(as_json(cmp)))
    assert js.read_text().endswith("}\n") and js.read_text().startswith('{\n "ok": false')
    assert summary.read_text() == "earlier step\n" + as_markdown(cmp)
    # defaults: into B; --all prints the same changes too; A against itself is OK (exit 0)
    monkeypatch.delenv("GITHUB_STEP_SUMMARY")
    assert run_compare(a, a, show_all=True) == 0
    out = capsys.readouterr().out
    assert "OK: no run got worse." in out and f"written: {a / 'compare.md'}, " in out
    assert re.search(r"^same  +free_tumbling mujoco RK4 dt 0.001 ", out, re.M)
    assert (a / "compare.md").read_text().startswith("## director-bench compare: OK\n")
    assert json.loads((a / "compare.json").read_text())["ok"] is True
    assert summary.read_text() == "earlier step\n" + as_markdown(cmp)  # not appended again
    # the factor and the cost factor reach the comparison
    assert run_compare(a, b, factor=20.0) == 0  # 10x within 20
    assert run_compare(a, b, factor=20.0, cost_factor=2.0) == 1  # the 3x cost gates
    out = capsys.readouterr().out
    assert "cost gated at 2x" in out


def test_run_compare_with_unwritable_summaries_still_gives_its_verdict(folders, tmp_path,
                                                                      capsys):  # fmt: skip
    """The Markdown written, the JSON's folder a file: the warning names the JSON's path and
    the system's reason."""
    a, b = folders
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert run_compare(a, b, markdown=tmp_path / "ok.md", json_path=blocker / "c.json") == 1
    cap = capsys.readouterr()
    assert cap.out.rstrip().endswith(VERDICT) and "written:" not in cap.out
    assert cap.err.startswith(f"director-bench: warning: cannot write {blocker}")
    assert f"({os.strerror(errno.ENOTDIR)}); " in cap.err and "ok.md" not in cap.err
    assert cap.err.rstrip().endswith("; give --markdown FILE and --json FILE elsewhere")


def test_run_compare_passes_the_columns_allowed_to_differ(tmp_path, capsys):
    sc = scenarios.load("free_tumbling")
    a = _folder(tmp_path / "a", [_row(sc, "Euler")])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", t_end=2.0)])
    assert run_compare(a, b) == 1  # another horizon: not the same run
    assert run_compare(a, b, vary=("t_end", "save_every")) == 0
    assert "; allowed to differ: t_end, save_every); " in capsys.readouterr().out


def test_run_compare_with_nothing_comparable_exits_1_naming_why(folders, tmp_path, capsys):
    a, _ = folders
    sc = scenarios.load("free_tumbling")
    other = _folder(tmp_path / "other", [_row(sc, "Euler", dt=0.25)])
    assert run_compare(a, other) == 1
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err.startswith("director-bench: error: ")
    assert "share no run" in cap.err and not (other / "compare.md").exists()
