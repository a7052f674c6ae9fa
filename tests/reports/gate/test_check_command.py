"""The ``director-bench check`` command as a user runs it: what it prints, writes and returns
on stores and baseline files written by hand (a missing or new run, a verdict gone worse, a
baseline file refused or read), each expected line written here from docs/results.md ("The
CI gate"). What it prints of one comparison built by hand is test_check_output.py's."""

from __future__ import annotations

import errno
import json
import os
import xml.etree.ElementTree as ET

import pytest

from reports.gate import check as gate
from reports.store.results import frame
from tests.reports.gate.test_gate import baseline_entry, failing_row, row, write

K1 = ("dzhanibekov", "mujoco", "RK4", 0.001, None)


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
    entry = baseline_entry()
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
    entry = baseline_entry()
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
