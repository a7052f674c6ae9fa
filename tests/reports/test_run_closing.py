"""What ``run`` says when it ends: how many of its failures the committed baseline expects, and
which verdict files of an earlier check it removed (a check of the results before the run,
saying FAIL, must not outlive them)."""

import json

import pytest

import reports.suite
from reports.cli import main
from reports.gate.check import write_baseline

#: free_tumbling for 0.01 s with an energy bound no integrator meets: both MuJoCo runs fail
STRICT = """
[tolerances]
energy_drift_max = 1e-300
"""


@pytest.fixture
def strict(tmp_path):
    from pathlib import Path

    import scenarios

    text = Path(scenarios.library_path() / "free_tumbling.toml").read_text()
    path = tmp_path / "strict_tumbling.toml"
    path.write_text(text.replace('name = "free_tumbling"', 'name = "strict_tumbling"') + STRICT)
    return path


def _run(strict, out, capsys, *extra):
    argv = ["run", str(strict), "--engines", "mujoco", "--integrators", "euler,rk4", "--dt",
            "1e-3", "--t-end", "0.01", "--no-sweep", "--quiet", "--jobs", "1", "--no-report",
            "--out", str(out), *extra]  # fmt: skip
    assert main(argv) == 0
    return capsys.readouterr().out.strip().splitlines()


def test_the_closing_line_counts_the_failures_the_committed_baseline_expects(
    tmp_path, strict, capsys, monkeypatch
):
    out = tmp_path / "res"
    other = tmp_path / "other.json"  # a baseline of other runs: none of these is in it
    other.write_text(json.dumps({"format": 3, "runs": []}))
    monkeypatch.setattr(reports.suite, "DEFAULT_BASELINE", other)
    line = _run(strict, out, capsys)[-1]
    assert line == (
        f"2 run(s) failed their verdict or errored: none of them is in the committed "
        f"baseline ({other}); see the report's failures."
    )
    committed = write_baseline(out, tmp_path / "committed.json")
    monkeypatch.setattr(reports.suite, "DEFAULT_BASELINE", committed)
    line = _run(strict, out, capsys)[-1]
    assert line == (
        f"2 run(s) failed their verdict or errored: all 2 fail as in the committed baseline "
        f"({committed}), known failures, not regressions; see the report's failures."
    )
    doc = json.loads(committed.read_text())  # the baseline says RK4 passed: it fails anew
    rk4 = next(r for r in doc["runs"] if r["integrator"] == "RK4")
    rk4.update(verdict="pass", failed_checks=[], reason="")
    committed.write_text(json.dumps(doc))
    line = _run(strict, out, capsys)[-1]
    assert line.startswith(
        f"2 run(s) failed their verdict or errored: 1 fail as in the committed baseline "
        f"({committed}), 1 do not (`director-bench check {out} --baseline {committed}` "
    )
    doc["runs"] = [r for r in doc["runs"] if r["integrator"] != "RK4"]  # RK4 not in it
    committed.write_text(json.dumps(doc))
    line = _run(strict, out, capsys)[-1]
    assert line == (
        f"2 run(s) failed their verdict or errored: 1 fail as in the committed baseline "
        f"({committed}), 1 not in it; see the report's failures."
    )


def test_a_run_removes_the_verdict_of_an_earlier_check(tmp_path, strict, capsys):
    out = tmp_path / "res"
    assert not any("removed:" in line for line in _run(strict, out, capsys))
    base = write_baseline(out, tmp_path / "base.json")
    doc = json.loads(base.read_text())
    for r in doc["runs"]:  # planted: the baseline says every run passed
        r.update(verdict="pass", failed_checks=[], reason="")
    base.write_text(json.dumps(doc))
    assert main(["check", str(out), "--baseline", str(base)]) == 1
    capsys.readouterr()
    assert (out / "check.md").read_text().startswith("## director-bench check: FAIL")
    lines = _run(strict, out, capsys, "--redo")
    assert not (out / "check.md").exists() and not (out / "check.json").exists()
    removed = [line for line in lines if line.startswith("removed:")]
    assert removed == [
        "removed:      check.md, check.json (the verdict of an earlier `check` or `compare` "
        "on the results before this run; run it again)"
    ]
