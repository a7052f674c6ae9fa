"""The report of systems of bodies: on a small real results folder (the four-bar loop on the
director model, MuJoCo and Pinocchio, its exact reference, and one single body), a system
scenario gets its own figure (loop-closure gap, energy and momentum over time) in view and
never a single body's figure or an error on the standard error; its table shows the settings
that shaped each loop closure; the cheapest configuration per accuracy includes it; every
line of the system figure is named in its legend (and a planted unnamed line is caught)."""

from __future__ import annotations

import json

import pytest

import scenarios
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.results import read_results
from tests.reports.report.test_report_figures import _capture_figures

#: 0.1 s of the four-bar at its own dt (2 ms): 50 steps per run, a second or so in all
ENGINES = ("director", "exact", "mujoco", "pinocchio")
INTEGRATORS = ("rattle", "reference", "RK4", "RKMK4")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The results folder of the four-bar and free_tumbling, with its report."""
    out = tmp_path_factory.mktemp("system-report")
    bar = scenarios.load("four_bar").replace(t_end=0.1)
    free = scenarios.load("free_tumbling").replace(t_end=0.1, dt_sweep=(2e-3,))
    run_suite(plan([bar, free], ENGINES, INTEGRATORS), out, progress=False)
    from reports.report.build import build_report

    build_report(out)
    return out


@pytest.fixture(scope="module")
def df(built):
    return read_results(built)


def test_a_system_gets_its_own_figure_in_view_and_no_error(built, capfd):
    from reports.report.build import build_report

    (built / "plots" / ".made-from.json").unlink(missing_ok=True)  # draw every figure again
    build_report(built)
    err = capfd.readouterr().err
    assert "not drawn" not in err and "Error" not in err, err
    names = {p.name for p in (built / "plots").glob("*.png")}
    assert "four-bar__system.png" in names
    # a single body's figures are not drawn for a system, nor the system figure for one body
    assert not {"four-bar__rates.png", "four-bar__scenario.png"} & names
    # (free_tumbling's rates figure is left out: every configuration is within 1 % of W)
    assert "free-tumbling__scenario.png" in names and "free-tumbling__system.png" not in names
    html = (built / "report.html").read_text()
    section = html[html.index("id='four_bar'") :]
    section = section[: section.index("</section>")]
    # in view: before the collapsed part of the section
    assert section.index("k-system") < section.index("<details")


def test_the_system_figure_names_every_line_with_its_closure_settings(built, df, tmp_path):
    from reports.report import canvas, figures

    styles, cache = canvas.Styles(df), canvas.SeriesCache(built)
    png = figures.scenario_plot("system", df, cache, tmp_path, "four_bar", styles)
    meta = canvas.figure_meta(png)
    labels = [ln["label"] for ln in meta["lines"]]
    # MuJoCo's default solref is (0.02, 1) (MuJoCo documentation, "solref"); the row ran it
    assert any(lab.startswith("mujoco RK4") and "solref (0.02, 1)" in lab for lab in labels)
    assert any(lab.startswith("pinocchio") and "Baumgarte" in lab for lab in labels)
    assert any(lab.startswith("director rattle") for lab in labels)
    assert "loop closure" in meta["alt"] and "four_bar" in meta["alt"]


def _unnamed_lines(fig) -> list[str]:
    """The data lines of a figure (more than two points) that its legend does not name (or
    names by their settings alone, with no configuration)."""
    named = set()
    for ax in fig.axes:
        if ax.get_legend() is not None:
            named |= {t.get_text() for t in ax.get_legend().get_texts()}
    return [
        repr(ln.get_label())
        for ax in fig.axes
        for ln in ax.get_lines()
        if len(ln.get_xdata()) > 2
        and (ln.get_label() not in named or not ln.get_label().split("\n")[0].strip())
    ]


def test_an_unnamed_line_in_a_system_figure_is_caught(built, df, tmp_path, monkeypatch):
    from reports.report import canvas, figures

    kept = _capture_figures(monkeypatch)  # (path, figure) of each saved figure
    styles, cache = canvas.Styles(df), canvas.SeriesCache(built)
    figures.scenario_plot("system", df, cache, tmp_path, "four_bar", styles)
    ((_, fig),) = kept
    assert _unnamed_lines(fig) == []
    # planted: one configuration's name lost, or hidden from the legend (matplotlib leaves
    # out a label starting with "_"): each is caught
    import reports.report.labels as labels

    real_label = labels.config_label
    for planted in ("", "_hidden"):
        monkeypatch.setattr(
            labels, "config_label", lambda row, planted=planted, **kw: planted
            if row["engine"] == "mujoco" else real_label(row, **kw),
        )  # fmt: skip
        figures.scenario_plot("system", df, cache, tmp_path, "four_bar", styles)
        # the one MuJoCo line of each panel
        fig = kept[-1][1]
        assert len(_unnamed_lines(fig)) == len(fig.axes), planted


def test_system_rows_show_their_closure_settings_and_rank_by_cost(built, df):
    from reports.report.tables import closure_settings, work_precision

    bar = df[df["scenario"] == "four_bar"]
    by = {(r["engine"], r["integrator"]): r for r in bar.to_dict("records")}
    assert closure_settings(by[("mujoco", "RK4")]).startswith("solref (0.02, 1), solimp (")
    assert closure_settings(by[("pinocchio", "RKMK4")]).startswith("Baumgarte (Kp, Kd) (")
    assert closure_settings(by[("director", "rattle")]) == ""  # no settings: held exactly
    md = (built / "report.md").read_text()
    assert "loop closure settings" in md and "solref (0.02, 1)" in md
    # the cheapest configuration per accuracy includes the system (attitude error: the
    # largest over bodies), ranked by time inside the engine
    wp = work_precision(bar)
    ranked = [e for lv in wp for e in lv["ranked"]]
    assert ranked and all(e["attitude_error_max"] <= lv["level"] for lv in wp
                          for e in lv["ranked"])  # fmt: skip
    assert "four_bar: cheapest configuration per accuracy" in md
    summary = json.loads((built / "summary.json").read_text())
    assert "four_bar" in json.dumps(summary["scorecard"] if "scorecard" in summary else summary)


def test_a_system_without_series_files_gets_no_single_body_figure(built, df, tmp_path, capfd):
    """A system whose runs left no series file (rows only): no figure of a single body is
    attempted (nothing on the standard error), and no system figure either."""
    from reports.report import canvas, figures

    rows = df.copy()
    rows.loc[rows["scenario"] == "four_bar", "trajectory"] = ""
    styles, cache = canvas.Styles(rows), canvas.SeriesCache(built)
    assert canvas.scene_kind(rows, "four_bar") == "system"
    assert canvas.scene_kind(rows, "free_tumbling") == "body"
    made = [
        figures.scenario_plot(k, rows, cache, tmp_path, "four_bar", styles) for k in figures.KINDS
    ]
    assert all(p is None or p.stem.endswith(("work_precision", "convergence")) for p in made)
    assert capfd.readouterr().err == ""


def _lines_by_name(fig) -> dict:
    """The configuration lines of a figure (those with a hover name) by configuration: the
    name up to its closure settings or divergence time, on one line."""
    return {
        " ".join(ln.get_label().split("\n(")[0].split()): ln
        for ax in fig.axes
        for ln in ax.get_lines()
        if ln.get_gid()
    }


def test_the_system_figure_draws_each_configuration_as_the_errors_figure_does(
    built, df, tmp_path, monkeypatch
):
    """A configuration looks the same in the system figure as in the errors figure beside it:
    colour, line style and marker (the marker is what tells apart two colours that look
    alike, mujoco Euler's and mjx Euler's purples; the system figure once drew no marker)."""
    from reports.report import canvas, figures

    kept = _capture_figures(monkeypatch)
    styles, cache = canvas.Styles(df), canvas.SeriesCache(built)
    figures.scenario_plot("errors", df, cache, tmp_path, "four_bar", styles)
    figures.scenario_plot("system", df, cache, tmp_path, "four_bar", styles)
    (errors, system) = (_lines_by_name(fig) for _, fig in kept)
    names = set(system) - {"exact reference"}
    assert {"director rattle", "mujoco RK4", "pinocchio + suite RKMK4"} <= names <= set(errors)
    for name in names:
        a, b = errors[name], system[name]
        assert b.get_marker() not in ("None", "", None), name
        looks = (b.get_color(), b.get_linestyle(), b.get_marker())
        assert looks == (a.get_color(), a.get_linestyle(), a.get_marker()), name


def test_the_system_figure_s_drift_axes_name_their_scale(built, df, tmp_path, monkeypatch):
    """The energy drift's axis says what E_c is, as the errors figure's does: the scenario's
    energy scale in J (loaded from the scenario, not from the results)."""
    from reports.report import canvas, figures
    from reports.store.format import fmt

    kept = _capture_figures(monkeypatch)
    styles, cache = canvas.Styles(df), canvas.SeriesCache(built)
    figures.scenario_plot("system", df, cache, tmp_path, "four_bar", styles)
    ((_, fig),) = kept
    labels = [ax.get_ylabel() for ax in fig.axes]
    e_c = scenarios.load("four_bar").energy_scale
    assert labels[1] == f"|E − E₀| / E_c [1]\nE_c = {fmt(e_c)} J", labels


def test_figures_are_drawn_again_when_the_system_figure_s_code_changes(
    built, df, tmp_path, monkeypatch
):
    """The key that lets a report reuse its figures covers the system figure's code: a
    change there draws them again (it once covered plots.py and the tables only)."""
    import importlib.machinery
    import importlib.util
    from pathlib import Path

    import reports.report.system_plots as system_plots
    from reports.report import canvas, figures

    styles = canvas.Styles(df)
    before = figures._scenario_key(df, "four_bar", styles, built)
    changed = tmp_path / "system_plots.py"
    changed.write_text(Path(system_plots.__file__).read_text() + "\n# another line\n")
    real = importlib.util.find_spec

    def find_spec(name, *args, **kw):
        if name == "reports.report.system_plots":
            return importlib.machinery.ModuleSpec(name, None, origin=str(changed))
        return real(name, *args, **kw)

    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    assert figures._scenario_key(df, "four_bar", styles, built) != before
    monkeypatch.setattr(importlib.util, "find_spec", real)
    assert figures._scenario_key(df, "four_bar", styles, built) == before
