"""The report as a verdict: scorecard first, engines that run one algorithm collapsed, numbers
formatted one way, Markdown that a GitHub-flavoured parser renders as tables, summary.json,
the CI job summary and the README block; on a small real suite with failures in it."""

import json
import math
import re

import pytest

import scenarios
from reports.results import read_results
from reports.runner import plan, run_suite
from reports.summary import failures, fmt, scorecard, work_precision

#: cone_top at dt = 1e-3 and 2e-3: semi-implicit Euler diverges (at t = 0.22 s at 1e-3 in the
#: default suite), RK4 and RKMK4 run one algorithm on two engines; 0.5 s keeps it short
ENGINES = ("director", "exact", "mujoco", "pinocchio")
INTEGRATORS = ("rattle", "rattle4", "energy_momentum", "reference", "Euler", "RK4", "RKMK4")


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    cone = scenarios.load("cone_top").replace(t_end=0.5, dt_sweep=(2e-3,))
    free = scenarios.load("free_tumbling").replace(t_end=0.5, dt_sweep=(2e-3,))
    specs = plan([cone, free], ENGINES, INTEGRATORS)
    run_suite(specs, out, progress=False)
    from reports.report import build_report

    build_report(out)
    return out


@pytest.fixture(scope="module")
def df(folder):
    return read_results(folder)


def test_numbers_are_formatted_one_way():
    """Three significant digits; scientific notation outside [1e-3, 1e4), short exponent."""
    cases = {
        0.0037: "0.00370",
        8.5e-4: "8.50e-4",
        1e-3: "0.00100",
        0.1: "0.100",
        3.14159: "3.14",
        1234.5: "1230",
        9999.6: "1.00e4",  # rounds into the scientific range
        158000.0: "1.58e5",
        -2.5e-12: "-2.50e-12",
        0.0: "0",
        math.nan: "-",
        math.inf: "inf",
        4: "4",
    }
    assert {v: fmt(v) for v in cases} == cases


def test_engines_running_one_algorithm_collapse_into_one_entry(df):
    """MuJoCo RK4 and Pinocchio RKMK4 are the same 4th-order Lie-group method: one scorecard
    entry listing both, their largest relative difference far below the 1e-3 that groups
    them (they agree to round-off, ~1e-11); semi-implicit Euler diverges."""
    card = {s["scenario"]: s for s in scorecard(df)}
    cone = card["cone_top"]
    assert cone["dt"] == 1e-3
    (lie,) = cone["cells"]["4th-order Lie-group"]
    assert {(r["engine"], r["integrator"]) for r in lie.rows} == {
        ("mujoco", "RK4"),
        ("pinocchio", "RKMK4"),
    }
    assert lie.max_rel_diff < 1e-6
    (euler,) = cone["cells"]["semi-implicit Euler"]
    assert euler.outcome == "diverged" and 0 < euler.value("t_diverged") < 0.5
    # the director schemes are different algorithms: one entry each
    assert len(cone["cells"]["structure-preserving director"]) == 3
    fails = failures(df)
    assert any(f["group"].outcome == "diverged" and f["own_dt"] for f in fails)


def test_work_precision_ranks_by_engine_time_and_labels_suite_integration(df):
    """Costs compare the time inside the engine; Pinocchio's RKMK4 is the suite's loop around
    aba and says so; ratios are relative to the cheapest by that measure."""
    wp = work_precision(df[df["scenario"] == "free_tumbling"], levels=(1e-4,))
    ranked = wp[0]["ranked"]
    assert ranked and ranked[0]["cost_ratio"] == 1.0
    assert all(b["cost_ratio"] >= a["cost_ratio"] for a, b in zip(ranked, ranked[1:], strict=False))
    pin = [e for e in ranked if e["engine"] == "pinocchio"]
    assert pin and pin[0]["configuration"].startswith("pinocchio + suite RKMK4")
    assert all(e["attitude_error_max"] <= 1e-4 for e in ranked)


def test_report_opens_with_the_verdict(folder):
    md = (folder / "report.md").read_text()
    heads = [h for h in re.findall(r"^## (.+)$", md, flags=re.M)]
    assert heads[:5] == [
        "Scorecard",
        "Work precision",
        "Failures and divergences",
        "Details",
        "Settings",
    ]
    contents = md.split("## Scorecard")[0]
    assert "**Contents:**" in contents and "(#cone_top)" in contents
    assert "pinocchio + suite RKMK4" in md
    assert re.search(r"💥 mujoco: at t = 0\.\d+ s", md)  # the divergence, with its time
    # the energy-momentum scheme's note, where it runs
    assert "director-form energy" in md and "constraint_velocity_max" in md
    html = (folder / "report.html").read_text()
    assert "<details id='cone_top'>" in html and "class='entry v-pass'" in html
    assert "class='scroll'" in html


def test_settings_show_every_value_that_ran(folder, df):
    """Both steps of the sweep appear for the timestep setting, not only the first seen."""
    md = (folder / "report.md").read_text()
    settings = md.split("## Settings")[1]
    rows = [ln for ln in settings.splitlines() if ln.startswith("| mujoco | Euler | timestep")]
    assert rows and all("0.001" in r and "0.002" in r for r in rows)


def _cells(line: str) -> int:
    """Cells of a Markdown table row: pipes not escaped with a backslash, minus the borders."""
    return len(re.findall(r"(?<!\\)\|", line)) - 1


def test_markdown_tables_render_as_tables(folder):
    """GitHub's own parser (cmark-gfm) turns every table of report.md into a table: as many
    <table> elements as delimiter rows, and every row with as many cells as its header (an
    unescaped | in a cell, e.g. in |R^T R - 1|, would make one more and break the table)."""
    cmarkgfm = pytest.importorskip("cmarkgfm", reason="pip install cmarkgfm (test extras)")
    md = (folder / "report.md").read_text()
    lines = md.splitlines()
    delims = [i for i, ln in enumerate(lines) if re.fullmatch(r"\|(---\|)+", ln)]
    assert len(delims) >= 8
    for i in delims:
        n = _cells(lines[i - 1])
        j = i + 1
        while j < len(lines) and lines[j].startswith("|"):
            assert _cells(lines[j]) == n, (lines[i - 1], lines[j])
            j += 1
    out = cmarkgfm.github_flavored_markdown_to_html(md)
    assert out.count("<table>") == len(delims)
    assert not re.search(r"<p>\|", out), "a table left as text"


def test_summary_json_is_strict_json_with_every_run(folder, df):
    doc = json.loads((folder / "summary.json").read_text(), parse_constant=pytest.fail)
    assert doc["format"] == 1 and doc["counts"]["runs"] == len(df) == len(doc["runs"])
    card = {s["scenario"]: s for s in doc["scorecard"]}
    (lie,) = card["cone_top"]["families"]["4th-order Lie-group"]
    assert {c["engine"] for c in lie["configurations"]} == {"mujoco", "pinocchio"}
    assert lie["outcome"] == "pass" and lie["attitude_error_max"] > 0
    run = doc["runs"][0]
    assert {"status", "verdict", "attitude_error_max", "energy_drift_max", "run_id"} <= set(run)


def test_scorecard_goes_to_the_ci_job_summary(folder, tmp_path, monkeypatch):
    from reports.report import build_report

    target = tmp_path / "step_summary.md"
    target.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(target))
    build_report(folder)
    text = target.read_text()
    assert text.startswith("earlier step\n")  # appended, not overwritten
    assert "## director-bench scorecard" in text and "| scenario |" in text


def test_figures_are_reused_when_nothing_changed(folder):
    """A report regenerated from an unchanged store draws no figure again."""
    from reports.report import build_report

    pngs = sorted((folder / "plots").glob("*.png"))
    assert len(pngs) == 8  # errors, rates, convergence, work-precision for two scenarios
    before = {p: p.stat().st_mtime_ns for p in pngs}
    build_report(folder)
    assert {p: p.stat().st_mtime_ns for p in pngs} == before


def test_readme_block_from_the_scorecard(folder, capsys):
    from reports.summary import main

    assert main([str(folder), "--readme"]) == 0
    out = capsys.readouterr().out
    assert "| scenario | integrator family | configurations |" in out
    assert "cone_top" in out and "mujoco RK4, pinocchio + suite RKMK4" in out
    assert main([str(folder / "nowhere"), "--readme"]) == 2
    # a selection for the README: one scenario, one family
    fam = "4th-order Lie-group"
    assert main([str(folder), "--readme", "--scenarios", "cone_top", "--families", fam]) == 0
    table = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("| cone_top")]
    assert len(table) == 1 and fam in table[0]
    assert main([str(folder), "--readme", "--scenarios", "no_such"]) == 2
