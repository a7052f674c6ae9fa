"""What ``director-bench versions`` prints and writes about the changes between releases
(reports/versions/changes.py: the change and summary rows of versions.md, the upgrade gate's
text, versions.json), on changes and tables written by hand (no store, no engine). Every
expected cell is written here from the rule of docs/versions.md ("What counts as a change",
"The gate") and the numbers' format (three significant digits, ``%.3g``; a summary's ratio two,
``x%.2g``; a value longer than its cell cut with an ellipsis) applied to the planted values."""

from __future__ import annotations

import json
import math

import pytest

from reports.metrics.catalog import FLOORS, HIGHER_IS_BETTER, METRIC_COLUMNS
from reports.versions.changes import (
    CHANGE_HEAD,
    COST_COLUMN,
    SUMMARY_HEAD,
    Change,
    CheckResult,
    PairSummary,
    VersionTable,
    change_rows,
    format_check,
    summary_rows,
    to_json,
    write_json,
)

M = "attitude_error_max"
LONG = "unsupported: the adapter refused the run at its step budget of 100000 steps"


def _c(integ, kind, column, a, b, ratio, direction, dt=1e-3, acc=None, sc="top", va="1.0",
       vb="1.1"):  # fmt: skip
    return Change(sc, "mujoco", integ, dt, acc, va, vb, kind, column, a, b, ratio, direction)


CHANGES = [
    _c("Euler", "metric", M, 1e-3, 1e-2, 10.0, "worse"),
    _c("RK4", "cost", COST_COLUMN, 1000.0, 3000.0, 3.0, "worse", dt=None),
    _c("disc", "status", "status", "ok", "diverged", None, "worse"),
    _c("gone", "integrator", "status", "ok", LONG, None, "vanished"),
    _c("RK45", "metric", M, 1e-6, 1e-7, 0.1, "better", acc=1e-8),
    _c("semi", "verdict", "verdict", "pass", "fail (attitude_error_max 1 > 0.1)", None, "worse"),
    _c("sym", "behaviour", "energy error", "losing", "conserved", None, "better"),
    _c("new", "integrator", "status", "unsupported", "ok", None, "new"),
    _c("newerr", "integrator", "status", "unsupported", "error", None, "new"),
    _c("Euler", "metric", "omega_error_max", 2e-3, math.nan, None, "worse"),
]

# the ellipsis cuts at 48 characters (47 kept), 60 and 30 in the summary (59 and 29 kept)
ROWS = [
    ["1.0 -> 1.1", "top mujoco Euler dt=0.001", M, "0.001", "0.01", "10", "worse"],
    ["1.0 -> 1.1", "top mujoco RK4", COST_COLUMN, "1e+03", "3e+03", "3", "worse"],
    ["1.0 -> 1.1", "top mujoco disc dt=0.001", "status", "ok", "diverged", "", "worse"],
    ["1.0 -> 1.1", "top mujoco gone dt=0.001", "integrator", "ok",
     "unsupported: the adapter refused the run at its…", "", "vanished"],
    ["1.0 -> 1.1", "top mujoco RK45 dt=0.001 acc=1e-08", M, "1e-06", "1e-07", "0.1", "better"],
    ["1.0 -> 1.1", "top mujoco semi dt=0.001", "verdict", "pass",
     "fail (attitude_error_max 1 > 0.1)", "", "worse"],
    ["1.0 -> 1.1", "top mujoco sym dt=0.001", "behaviour", "losing", "conserved", "", "better"],
    ["1.0 -> 1.1", "top mujoco new dt=0.001", "integrator", "unsupported", "ok", "", "new"],
    ["1.0 -> 1.1", "top mujoco newerr dt=0.001", "integrator", "unsupported", "error", "",
     "new"],
    ["1.0 -> 1.1", "top mujoco Euler dt=0.001", "omega_error_max", "0.002", "-", "", "worse"],
]  # fmt: skip


def test_the_change_rows():
    assert CHANGE_HEAD == ["versions", "configuration", "what", "before", "after", "ratio",
                           "change"]  # fmt: skip
    assert change_rows(CHANGES) == ROWS
    # a missing value and a text of exactly 48 characters (not cut), of 49 (cut)
    c = _c("x", "status", "status", None, "y" * 48, None, "worse")
    assert change_rows([c])[0][3:5] == ["-", "y" * 48]
    c = _c("x", "status", "status", 7, "y" * 49, 1.23456, "worse")
    assert change_rows([c])[0][3:6] == ["7", "y" * 47 + "…", "1.23"]


def test_the_summary_rows_one_per_configuration_and_pair():
    """Worse, better, changed by the rule: a vanished integrator is worse, a new one that
    ends ok better, one that ends otherwise changed; the two Euler changes share a row."""
    assert SUMMARY_HEAD == ["versions", "configuration", "worse", "better", "changed"]
    cut = "unsupported: the adapter refused the run at its step budget…"
    assert summary_rows(CHANGES) == [
        ["1.0 -> 1.1", "top mujoco Euler dt=0.001", f"{M} x10; omega_error_max (gone)", "", ""],
        ["1.0 -> 1.1", "top mujoco RK4", f"{COST_COLUMN} x3", "", ""],
        ["1.0 -> 1.1", "top mujoco disc dt=0.001", "status ok -> diverged", "", ""],
        ["1.0 -> 1.1", "top mujoco gone dt=0.001", f"no longer runs ({cut})", "", ""],
        ["1.0 -> 1.1", "top mujoco RK45 dt=0.001 acc=1e-08", "", f"{M} x0.1", ""],
        ["1.0 -> 1.1", "top mujoco semi dt=0.001",
         "verdict pass -> fail (attitude_error_max 1 > …", "", ""],  # 33 characters cut at 30
        ["1.0 -> 1.1", "top mujoco sym dt=0.001", "", "behaviour losing -> conserved", ""],
        ["1.0 -> 1.1", "top mujoco new dt=0.001", "", "runs now (ok)", ""],
        ["1.0 -> 1.1", "top mujoco newerr dt=0.001", "", "", "runs now (error)"],
    ]  # fmt: skip
    # the 30-character cut of a status text and of what a new integrator ends with
    long_b = "error: " + "z" * 40
    rows = summary_rows(
        [
            _c("x", "status", "status", "ok", long_b, None, "worse"),
            _c("y", "integrator", "status", "unsupported", long_b, None, "new"),
        ]
    )
    assert rows[0][2] == "status ok -> error: " + "z" * 22 + "…"
    assert rows[1][4] == "runs now (error: " + "z" * 22 + "…)"
    assert summary_rows([_c("x", "metric", M, 1.0, 2.5, 2.5, "worse")])[0][2] == f"{M} x2.5"
    # the value before is cut at 30 too (31 characters: 29 kept); several items of one kind in
    # one configuration are joined with "; "
    rows = summary_rows([
        _c("x", "verdict", "verdict", "y" * 31, "pass", None, "better"),
        _c("x", "metric", M, 1.0, 0.25, 0.25, "better"),
        _c("x", "behaviour", "energy error", "gaining", "losing", None, "changed"),
        _c("x", "integrator", "status", "unsupported", "error", None, "new"),
    ])  # fmt: skip
    assert rows == [["1.0 -> 1.1", "top mujoco x dt=0.001", "",
                     "verdict " + "y" * 29 + "… -> pass; " + f"{M} x0.25",
                     "behaviour gaining -> losing; runs now (error)"]]  # fmt: skip


def _summary(**kw):
    return PairSummary("mujoco", "1.0", "1.1", **kw)


def _cells(line):
    return [x.strip() for x in line.split("  ") if x.strip()]


def test_the_upgrade_gate_text_lists_the_failures_first():
    status, cost, better = CHANGES[2], CHANGES[1], CHANGES[4]
    res = CheckResult(
        "mujoco",
        "1.0",
        "1.1",
        _summary(compared=5, identical=2, within=1, changed=2),
        [better, cost, status],
    )
    lines = format_check(res).split("\n")
    assert lines[0] == ("mujoco 1.0 -> 1.1: 5 configurations compared: 2 identical, 1 within "
                        "a factor 2 above their floors, 2 changed.")  # fmt: skip
    assert lines[1] == ""
    assert _cells(lines[2]) == CHANGE_HEAD and set(lines[3]) == {"-"}
    # the one failure first (the status; the cost gates only with a cost factor), though
    # "disc" sorts after "RK4" and "RK45"; then the rest by configuration (RK4 without a dt
    # sorts as dt -1, before RK45 at 0.001)
    assert [_cells(x) for x in lines[4:7]] == [_cells("  ".join(ROWS[i])) for i in (2, 1, 4)]
    assert lines[7:] == ["", "FAIL: upgrading mujoco 1.0 -> 1.1 makes 1 thing(s) worse."]
    # with a cost factor below the ratio 3, the cost fails too, and sorts among the failures
    res = CheckResult("mujoco", "1.0", "1.1", _summary(compared=5), [better, cost, status],
                      factor=4.0, cost_factor=2.5)  # fmt: skip
    lines = format_check(res).split("\n")
    assert "within a factor 4 above their floors" in lines[0]
    assert [line.split()[5] for line in lines[4:7]] == ["RK4", "disc", "RK45"]
    assert lines[-1] == "FAIL: upgrading mujoco 1.0 -> 1.1 makes 2 thing(s) worse."
    assert [c.kind for c in res.failures] == ["status", "cost"]
    # one configuration's changes by dt, the sweep's cost (no dt) before them
    at = [_c("RK4", "metric", M, 1e-3, 1e-4, 0.1, "better", dt=h) for h in (1e-3, 5e-4)]
    res = CheckResult("mujoco", "1.0", "1.1", _summary(), [*at, cost])
    lines = format_check(res).split("\n")
    assert [_cells(x)[1] for x in lines[4:7]] == ["top mujoco RK4", "top mujoco RK4 dt=0.0005",
                                                  "top mujoco RK4 dt=0.001"]  # fmt: skip
    # error-controlled changes at one step by target accuracy, the fixed-step one first
    acc = [_c("RK45", "metric", M, 1e-3, 1e-4, 0.1, "better", acc=a) for a in (1e-6, None, 1e-8)]
    lines = format_check(CheckResult("mujoco", "1.0", "1.1", _summary(), acc)).split("\n")
    assert [_cells(x)[1] for x in lines[4:7]] == [
        "top mujoco RK45 dt=0.001", "top mujoco RK45 dt=0.001 acc=1e-08",
        "top mujoco RK45 dt=0.001 acc=1e-06"]  # fmt: skip
    # a cost ratio of exactly the cost factor is not beyond it
    assert CheckResult("mujoco", "1.0", "1.1", _summary(), [cost], cost_factor=3.0).ok


def test_the_upgrade_gate_text_without_failures():
    res = CheckResult("mujoco", "1.0", "1.1", _summary(compared=3, identical=3), [])
    assert format_check(res).split("\n") == [
        "mujoco 1.0 -> 1.1: 3 configurations compared: 3 identical, 0 within a factor 2 above "
        "their floors, 0 changed.",
        "",
        "OK: upgrading mujoco 1.0 -> 1.1 makes nothing worse.",
    ]
    # 21 configurations not compared: the count, the first 20 named, and a failing verdict
    gone = [(f"top mujoco I{i:02d} dt=0.001", f"1.1: no wheel {i}") for i in range(21)]
    res = CheckResult("mujoco", "1.0", "1.1", _summary(not_compared=gone), [])
    lines = format_check(res).split("\n")
    assert lines[1:3] == ["", "Not compared (21): one side unavailable"]
    assert lines[3:23] == [f"  top mujoco I{i:02d} dt=0.001: 1.1: no wheel {i}" for i in range(20)]
    assert lines[23:] == ["", "FAIL: some configurations could not be compared (see above)."]
    assert not res.ok


@pytest.fixture
def table():
    k1 = ("top", "mujoco", "Euler", 0.001, None)
    k2 = ("top", "mujoco", "RK45", 0.001, 1e-08)
    rows = {
        (k1, "1.0"): {"status": "ok", "verdict": "pass", "message": "kept", M: 1e-3,
                      "energy_drift_max": math.inf, COST_COLUMN: 2000.0},
        (k1, "1.1"): {"status": "ok", "verdict": "pass", "message": "", M: 1e-2,
                      "energy_drift_max": math.nan},
        (k2, "1.1"): {"status": "error", "verdict": "", "message": "boom", M: None},
    }  # fmt: skip
    tab = VersionTable("folder", 2.0, {"mujoco": ["1.0", "1.1"]}, rows,
                       {(k1, "1.0"): {"class": "losing"}})  # fmt: skip
    tab.pairs = [_summary(compared=1, changed=1, not_compared=[("x", "1.1: gone")])]
    tab.changes = [CHANGES[0], _c("Euler", "metric", "omega_error_max", 2e-3, math.nan,
                                  math.inf, "worse")]  # fmt: skip
    tab.cost_candidates = [(CHANGES[1], "not confirmed: 1.4x side by side")]
    return tab


def test_the_json_document(table, tmp_path):
    doc = to_json(table, environments=[{"engine": "mujoco", "version": "1.0"}])
    assert (doc["format"], doc["factor"], doc["engines"]) == (1, 2.0, {"mujoco": ["1.0", "1.1"]})
    assert doc["floors"] == FLOORS and doc["higher_is_better"] == sorted(HIGHER_IS_BETTER)
    assert doc["environments"] == [{"engine": "mujoco", "version": "1.0"}]
    assert to_json(table)["environments"] == []
    assert doc["pairs"] == [{"engine": "mujoco", "from_version": "1.0", "to_version": "1.1",
                             "compared": 1, "identical": 0, "within": 0, "changed": 1,
                             "not_compared": [("x", "1.1: gone")]}]  # fmt: skip
    fields = ["scenario", "engine", "integrator", "dt", "target_accuracy", "from_version",
              "to_version", "kind", "column", "a", "b", "ratio", "direction"]  # fmt: skip
    assert [list(c) for c in doc["changes"]] == [fields, fields]
    # NaN is null, an infinity "inf" (JSON has neither)
    assert [(c["column"], c["a"], c["b"], c["ratio"]) for c in doc["changes"]] == [
        (M, 1e-3, 1e-2, 10.0), ("omega_error_max", 2e-3, None, "inf")]  # fmt: skip
    (cand,) = doc["cost_candidates"]
    assert cand["reason"] == "not confirmed: 1.4x side by side"
    assert (cand["integrator"], cand["dt"], cand["ratio"]) == ("RK4", None, 3.0)
    s = doc["series"]
    assert list(s) == ["top mujoco Euler dt=0.001", "top mujoco RK45 dt=0.001 accuracy 1e-08"]
    euler = s["top mujoco Euler dt=0.001"]
    assert euler["configuration"] == {"scenario": "top", "engine": "mujoco", "integrator": "Euler",
                                      "dt": 0.001, "target_accuracy": None}  # fmt: skip
    v0, v1 = euler["versions"]["1.0"], euler["versions"]["1.1"]
    assert set(v0) == {*METRIC_COLUMNS, COST_COLUMN, "status", "verdict", "message",
                       "energy_behaviour"}  # fmt: skip
    assert (v0[M], v0["energy_drift_max"], v0[COST_COLUMN], v0["omega_error_max"]) == (
        1e-3, "inf", 2000.0, None)  # fmt: skip
    # an ok run's message is not carried; the energy behaviour where it was read
    assert (v0["status"], v0["verdict"], v0["message"], v0["energy_behaviour"]) == (
        "ok", "pass", "", "losing")  # fmt: skip
    assert (v1[M], v1["energy_drift_max"], v1["energy_behaviour"]) == (1e-2, None, None)
    err = s["top mujoco RK45 dt=0.001 accuracy 1e-08"]["versions"]
    assert list(err) == ["1.1"] and (err["1.1"]["message"], err["1.1"][M]) == ("boom", None)
    path = write_json(table, tmp_path / "versions.json", environments=[{"x": 1}])
    assert path == tmp_path / "versions.json"
    text = path.read_text()
    assert text.endswith("}\n") and text.startswith('{\n "format": 1,\n "factor": 2.0,')
    assert json.loads(text)["environments"] == [{"x": 1}]
    assert json.loads(text)["series"] == json.loads(json.dumps(doc["series"]))
