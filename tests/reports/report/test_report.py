"""The report as a verdict: scorecard first, engines that run one algorithm collapsed, numbers
formatted one way, Markdown that a GitHub-flavoured parser renders as tables, summary.json,
the CI job summary and the README block; on a small real suite with failures in it."""

import html
import json
import math
import re
import shutil

import pytest

import scenarios
from reports.report.tables import failures, scorecard, work_precision
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.format import fmt
from reports.store.results import read_results

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
    from reports.report.build import build_report

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


def test_steps_are_written_with_the_short_exponent_of_every_other_number():
    """A step size is written as given, with its exponent as fmt writes one (``6.25e-5``
    beside ``1.00e-12``, never ``6.25e-05``), in tables, titles and a dt axis' ticks."""
    from reports.store.format import fmt_step

    cases = {0.002: "0.002", 0.000125: "0.000125", 6.25e-5: "6.25e-5", 1e-5: "1e-5", 2.0: "2"}
    assert {v: fmt_step(v) for v in cases} == cases


def test_an_error_controlled_line_says_so_once_on_hover():
    """The hover text of an error-controlled work-precision line names it error-controlled
    once (Drake's integrator is called ``runge_kutta5 (error-controlled)`` already)."""
    from reports.report import plots

    said = plots._adaptive_gid("drake runge_kutta5 (error-controlled)")
    assert said.count("error-controlled") == 1 and "target accuracies" in said
    assert plots._adaptive_gid("x rk45").startswith("x rk45, error-controlled, ")


def test_a_note_under_a_figure_keeps_a_number_with_its_unit():
    """Wherever the wrap of a note under a figure falls, ``0.107 s`` and ``dt 0.001`` stay
    on one line (a line once ended in ``diverged at 0.107`` with ``s)`` alone below)."""
    from reports.report import canvas

    plt = canvas._plt()
    for k in range(90):
        fig, _ = canvas._new_figure(1)
        note = "x" * k + " semi_explicit_euler (dt 0.001: diverged at 0.107 s) " + "y " * 60
        canvas._fit(fig, note)
        lines = fig.texts[-1].get_text().split("\n")
        plt.close(fig)
        assert not any(ln.rstrip().endswith(("0.107", " dt")) for ln in lines), (k, lines)
        assert not any(ln.lstrip().startswith(("s)", "0.001:")) for ln in lines), (k, lines)


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
    # the divergence, with its time, and the configuration with its cost, in its scenario's
    # table of verdicts
    row = next(ln for ln in md.split("### cone_top")[1].splitlines() if "mujoco Euler" in ln)
    assert re.search(r"💥 diverged at t = 0\.\d+ s \| - \| - \| [\d.]+ \|$", row), row
    # the energy-momentum scheme's note, where it runs
    assert "director-form energy" in md and "constraint_velocity_max" in md
    html = (folder / "report.html").read_text()
    assert "<section class='scenario' id='cone_top'>" in html and "class='entry v-pass'" in html
    assert "class='scroll'" in html


def test_settings_show_every_value_that_ran(folder, df):
    """Both steps of the sweep appear for the timestep setting, not only the first seen."""
    md = (folder / "report.md").read_text()
    settings = md.split("## Settings")[1]
    rows = [ln for ln in settings.splitlines() if ln.startswith("| mujoco | Euler | timestep")]
    assert rows and all("0.001" in r and "0.002" in r for r in rows)


def test_settings_print_a_negative_zero_as_zero():
    """An engine records a centre of mass at [-0.0, -0.0, 0.1] (a negated zero coordinate):
    the report shows 0 there, keeps every other number as recorded, and the stored value is
    left as it is."""
    import pandas as pd

    from reports.report.tables import _setting, settings_table

    stored = json.dumps(
        {
            "local COM": [-0.0, -0.0, 0.1],
            "inertial frame": "diaginertia at [-0.0, -0, 0.075], tilt -0.05, -1.0e-0, x-0",
            "timestep": -0.0,
        }
    )
    df = pd.DataFrame(
        [{"engine": "mjx", "integrator": "Euler", "scenario": "heavy_top", "settings": stored}]
    )
    shown = {e["setting"]: e["values"] for e in settings_table(df)}
    assert shown == {
        "local COM": ["[0.0, 0.0, 0.1]"],
        "inertial frame": ["diaginertia at [0.0, 0, 0.075], tilt -0.05, -1.0e-0, x-0"],
        "timestep": ["0.0"],
    }
    assert (_setting(-0.0), _setting(-0.5), _setting("(-0.0, 1)")) == ("0", "-0.5", "(0.0, 1)")
    assert json.loads(df["settings"][0])["local COM"][0] == 0.0  # still stored as recorded
    assert str(json.loads(df["settings"][0])["local COM"][0]) == "-0.0"


def _cells(line: str) -> int:
    """Cells of a Markdown table row: pipes not escaped with a backslash, minus the borders."""
    return len(re.findall(r"(?<!\\)\|", line)) - 1


#: GitHub's rendering of a Markdown file (github-markdown-css): a page of 1012 px less 2 x 32 px
#: of padding, 16 px text, cells padded 13 px either side with a 1 px border
GITHUB_WIDTH_PX, CELL_PAD_PX, CHAR_PX = 1012 - 64, 2 * 13 + 1, 9.0


def _text_width(cell_html: str) -> float:
    """An upper bound on the width of a rendered cell's text, 9 px per character (16 px
    Helvetica/Arial averages about 7.5 px for lower case and digits, 10-11 px for capitals)."""
    text = html.unescape(re.sub(r"<[^>]+>", "", cell_html))
    return CHAR_PX * len(text)


def test_report_md_opens_with_a_verdict_that_fits_on_github(folder, df):
    """report.md as GitHub renders it (cmark-gfm): the first table is the verdict, before any
    figure or collapsed part, at most six columns whose widest cells fit GitHub's page without
    a line wrapping; everything after it but the section headings is collapsed (<details>)."""
    cmarkgfm = pytest.importorskip("cmarkgfm", reason="pip install cmarkgfm (test extras)")
    from cmarkgfm.cmark import Options

    md = (folder / "report.md").read_text()
    page = cmarkgfm.github_flavored_markdown_to_html(md, options=Options.CMARK_OPT_UNSAFE)
    first = page.index("<table>")
    assert "<img" not in page[:first] and "<details>" not in page[:first]
    table = page[first : page.index("</table>") + 8]
    rows = re.findall(r"<tr>(.*?)</tr>", table, flags=re.S)
    cells = [re.findall(r"<t[hd][^>]*>(.*?)</t[hd]>", r, flags=re.S) for r in rows]
    assert cells[0] == ["scenario", "pass", "fail", "diverged", "not judged", "not run"]
    assert len(rows) == 1 + df["scenario"].nunique() + 1  # a row per scenario, the totals
    widths = [max(_text_width(r[k]) for r in cells) + CELL_PAD_PX for k in range(len(cells[0]))]
    assert sum(widths) <= GITHUB_WIDTH_PX, widths
    # the counts add up: every configuration at each scenario's own step, reference aside
    total = cells[-1][1:]
    own = [
        r
        for _, r in df.iterrows()
        if r["engine"] != "exact"
        and r["dt"] == {"cone_top": 1e-3, "free_tumbling": 1e-3}[r["scenario"]]
    ]
    assert sum(int(re.sub(r"\D", "", c) or 0) for c in total) == len(own)
    # after the verdict: headings, and collapsed parts
    rest = re.sub(r"<details>.*?</details>", "", page[first + len(table) :], flags=re.S)
    rest = re.sub(r"<h[23][^>]*>.*?</h[23]>", "", rest, flags=re.S)
    assert "<table>" not in rest and "<img" not in rest, rest[:500]


def test_markdown_tables_render_as_tables(folder):
    """GitHub's own parser (cmark-gfm) turns every table of report.md into a table: as many
    <table> elements as delimiter rows, and every row with as many cells as its header (an
    unescaped | in a cell, e.g. in |R^T R - 1|, would make one more and break the table)."""
    cmarkgfm = pytest.importorskip("cmarkgfm", reason="pip install cmarkgfm (test extras)")
    md = (folder / "report.md").read_text()
    lines = md.splitlines()
    delims = [i for i, ln in enumerate(lines) if re.fullmatch(r"\|((---|--:)\|)+", ln)]
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
    from reports.report.build import build_report

    target = tmp_path / "step_summary.md"
    target.write_text("earlier step\n")
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", str(target))
    build_report(folder)
    text = target.read_text()
    assert text.startswith("earlier step\n")  # appended, not overwritten
    assert "## director-bench verdicts" in text and "| scenario | pass | fail |" in text


def test_figures_are_reused_when_nothing_changed(folder):
    """A report regenerated from an unchanged store draws no figure again."""
    from reports.report.build import build_report

    pngs = sorted((folder / "plots").glob("*.png"))
    # the scenario picture, errors, rates, convergence, work-precision for two scenarios, but
    # no rates figure for free_tumbling (every configuration within 1 %: a sentence instead)
    assert len(pngs) == 9
    pngs += [folder / "scorecard.png", folder / "scorecard.svg"]
    before = {p: p.stat().st_mtime_ns for p in pngs}
    build_report(folder)
    assert {p: p.stat().st_mtime_ns for p in pngs} == before


def test_figures_drawn_beside_a_worker_process_are_the_serial_ones(folder, tmp_path, monkeypatch):
    """With a worker process (two cores), this process draws the scorecard picture and takes
    scenarios as well: every figure is drawn once, into the same files, byte for byte, as
    when one process draws them all."""
    from reports.report import figures

    made = {}
    for name, cores in (("serial", 1), ("pooled", 2)):
        dst = tmp_path / name
        shutil.copytree(folder, dst, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
        monkeypatch.setenv("DIRECTOR_BENCH_CACHE", str(tmp_path / f"cache-{name}"))  # drawn
        monkeypatch.setattr(figures, "_cpus", lambda cores=cores: cores)
        monkeypatch.setattr(figures, "PARALLEL_FROM", 2)  # the folder has two scenarios
        made[name] = figures.report_figures(read_results(dst), dst)
    (serial, card), (pooled, pooled_card) = made["serial"], made["pooled"]
    names = {sc: [p.name for p in ps] for sc, ps in serial.items()}
    assert names == {sc: [p.name for p in ps] for sc, ps in pooled.items()}
    assert sorted(names) == ["cone_top", "free_tumbling"] and all(names.values())
    for sc, ps in serial.items():
        for p, q in zip(ps, pooled[sc], strict=True):
            assert p.read_bytes() == q.read_bytes(), p.name
            assert p.with_suffix(".json").read_bytes() == q.with_suffix(".json").read_bytes()
    assert (
        [p.name for p in card]
        == [p.name for p in pooled_card]
        == ["scorecard.png", "scorecard.svg"]
    )
    assert card[0].read_bytes() == pooled_card[0].read_bytes()


def test_figures_without_timings_are_reused_from_another_folder(folder, tmp_path, monkeypatch):
    """A second folder with the same results (another run of the same code: timings and
    clock times differ) copies every figure but the work-precision one from the user's
    cache, byte for byte; a series file that differs (a planted change) is drawn anew."""
    import pandas as pd
    import pyarrow.parquet as pq

    from reports.report import figures

    monkeypatch.setenv("DIRECTOR_BENCH_CACHE", str(tmp_path / "cache"))
    first = tmp_path / "first"
    shutil.copytree(folder, first, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    made = figures.all_plots(read_results(first), first)
    drawn = []
    real = figures.scenario_plot

    def counting(kind, df, cache, out, scenario, styles, failed=None):
        drawn.append((scenario, kind))
        return real(kind, df, cache, out, scenario, styles, failed)

    monkeypatch.setattr(figures, "scenario_plot", counting)
    second = tmp_path / "second"
    shutil.copytree(folder, second, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    df = read_results(second)
    df["engine_time_s"] *= 3.0  # another run's timings
    df["finished_at"] = "2030-01-01T00:00:00+00:00"
    again = figures.all_plots(df, second)
    assert sorted(drawn) == [("cone_top", "work_precision"), ("free_tumbling", "work_precision")]
    for sc, paths in made.items():
        assert [p.name for p in paths] == [p.name for p in again[sc]]
        for p, q in zip(paths, again[sc], strict=True):
            if "work_precision" not in p.name:
                assert p.read_bytes() == q.read_bytes(), p.name
    # a planted change in one run's series: that scenario's figures are drawn again
    row = df[(df["scenario"] == "cone_top") & (df["trajectory"] != "")].iloc[0]
    path = second / row["trajectory"]
    table = pq.read_table(path)
    series = table.to_pandas()
    series["t"] = series["t"] * 1.0 + 1e-9
    pq.write_table(pa_table(series, table.schema.metadata), path)
    drawn.clear()
    third = tmp_path / "third"
    shutil.copytree(second, third, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    figures.all_plots(df, third)
    assert ("cone_top", "errors") in drawn and ("free_tumbling", "errors") not in drawn
    assert isinstance(df, pd.DataFrame)


def pa_table(frame, metadata):
    import pyarrow as pa

    return pa.Table.from_pandas(frame, preserve_index=False).replace_schema_metadata(metadata)


def test_figures_are_reused_when_the_folder_is_named_relative_or_absolute(folder, monkeypatch):
    """The same folder named once relative to the working directory and once absolute is
    the same folder: nothing is drawn again."""
    from reports.report.build import build_report

    pngs = sorted((folder / "plots").glob("*.png"))
    before = {p: p.stat().st_mtime_ns for p in pngs}
    monkeypatch.chdir(folder.parent)
    build_report(folder.name)
    build_report(folder.resolve())
    assert {p: p.stat().st_mtime_ns for p in pngs} == before


def test_readme_block_from_the_scorecard(folder, capsys):
    from reports.report.summary import main

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


def test_scorecard_names_every_configuration_with_its_cost(folder, df):
    """Every configuration of a scorecard entry is named with its engine and its integrator
    and its time inside the engine per step (µs); the key to the figures (E among them) is
    above the table and in a tooltip; failing metrics are visible text, not only a title."""
    md = (folder / "report.md").read_text()
    cone = md.split("### cone_top")[1].split("### ")[0]
    table = [ln for ln in cone.splitlines() if ln.startswith("| ")]
    assert table[0] == (
        "| family | configurations | verdict | attitude [rad] | energy | engine µs/step |"
    )
    lie = next(ln for ln in table if ln.startswith("| 4th-order Lie-group |"))
    names, costs = lie.split(" | ")[1], lie.split(" | ")[-1].rstrip(" |")
    assert names.split("<br>") == ["mujoco RK4", "pinocchio + suite RKMK4"]
    assert all(re.fullmatch(r"[\d.e-]+", c) for c in costs.split("<br>")), costs
    for name in ("director rattle4", "mujoco Euler"):
        assert any(name in ln for ln in table), name
    html = (folder / "report.html").read_text()
    top = html.split("id='scorecard'")[1].split("id='work-precision'")[0]
    assert top.index("class='legend'") < top.index("<table class='scorecard")
    assert "<abbr title='the max energy drift relative to the scenario" in top
    fails = re.findall(r"<span class='fails'>fails: ([^<]+)</span>", top)
    failed = df[(df["verdict"] == "fail") & (df["dt"] == 1e-3) & (df["engine"] != "exact")]
    assert len(failed) == 0 or fails, "a failing verdict without its metrics in view"


def test_cheapest_per_accuracy_names_the_best_of_each_engine(folder, df):
    """The work-precision table has a row per engine and scenario, each engine's cheapest
    configuration per level with its ratio to the cheapest of all engines."""
    md = (folder / "report.md").read_text()
    wp = md.split("## Work precision")[1].split("## Failures")[0]
    rows = [ln for ln in wp.splitlines() if ln.startswith("| ") and "engine |" not in ln]
    shown, scen = {}, None
    for ln in rows:
        first, engine = ln.split(" | ")[:2]
        scen = re.search(r"\[(\w+)\]", first).group(1) if "[" in first else scen
        shown.setdefault(scen, []).append(engine)
    ran = df[(df["status"] == "ok") & (df["engine"] != "exact")]
    expected = {s: sorted(set(g["engine"])) for s, g in ran.groupby("scenario")}
    assert {s: sorted(e) for s, e in shown.items()} == expected
    assert all(len(e) == len(set(e)) for e in shown.values())  # one row per engine
    assert "cheapest" in wp and re.search(r"\bx\d", wp)  # the winner and the others' ratios


def test_did_not_run_reasons_are_whole():
    """A long reason is given in full (it ends with what to do), never cut."""
    import pandas as pd

    from reports.report.tables import not_run

    reason = "PyBullet cannot hold this body: " + "a long explanation, " * 20 + "use X instead"
    df = pd.DataFrame(
        [
            {"engine": "pybullet", "integrator": "multibody", "status": "unsupported",
             "message": reason, "scenario": s}
            for s in ("a", "b")
        ]
    )  # fmt: skip
    (entry,) = not_run(df)
    assert entry["message"] == " ".join(reason.split()) and entry["scenarios"] == ["a", "b"]


def _capture_figures(monkeypatch):
    """Keep each figure the plot functions save (instead of closing it) for inspection: in
    every figure module that writes or closes figures."""
    from reports.report import canvas, pictures, scorecard_plot

    kept = []
    real = canvas._write_png

    def keep(fig, path, **kw):
        real(fig, path, **kw)
        kept.append((path, fig))

    for mod in (canvas, pictures, scorecard_plot):
        monkeypatch.setattr(mod, "_write_png", keep)
        monkeypatch.setattr(mod, "_plt", _no_close(canvas._plt))
    return kept


def _no_close(real_plt):
    def wrapped():
        plt = real_plt()

        class NoClose:
            def __getattr__(self, name):
                return getattr(plt, name)

            def close(self, fig=None):
                pass

        return NoClose()

    return wrapped


def _outside(fig, path) -> list:
    """The legends, titles, axis labels and drawn tick labels of a figure that reach beyond
    the image saved from it (1 px of slack), by matplotlib's own extents."""
    r = fig.canvas.get_renderer()
    box = fig.bbox
    if path.name == "scorecard.png":  # saved with its tight box: compare with that
        box = fig.get_tightbbox(r).padded(0.1).transformed(fig.dpi_scale_trans)
    texts = [("figure legend", leg.get_window_extent(r)) for leg in fig.legends]
    for ax in fig.axes:
        if ax.get_legend() is not None:
            texts.append(("legend", ax.get_legend().get_window_extent(r)))
        if ax.name == "3d":
            continue
        lo, hi = sorted(ax.get_ylim())
        drawn = [  # the tick labels drawn: those of ticks within the axes' range
            tk.label1 for tk in ax.yaxis.get_major_ticks() if lo <= tk.get_loc() <= hi
        ]
        for t in (ax.title, ax.xaxis.label, ax.yaxis.label, *drawn):
            if t.get_text() and t.get_visible():
                texts.append((t.get_text(), t.get_window_extent(r)))
    return [
        (path.name, what, ext)
        for what, ext in texts
        if not (ext.x0 >= box.x0 - 1 and ext.x1 <= box.x1 + 1 and ext.y0 >= box.y0 - 1
                and ext.y1 <= box.y1 + 1)
    ]  # fmt: skip


LONG = "RK4 with a long display name (error-controlled, for this test)"


def test_every_legend_and_label_lies_inside_its_figure(folder, df, tmp_path, monkeypatch):
    """Every figure of a scenario, with one configuration given a long display name: the
    legend, the tick labels, the axis labels and the titles lie inside the saved figure
    (matplotlib's own extents), whatever the label lengths; the figure's hover file names
    the long configuration."""
    import json

    from reports.report import canvas, figures, scorecard_plot

    df = df.copy()
    df.loc[(df["engine"] == "mujoco") & (df["integrator"] == "RK4"), "integrator"] = LONG
    kept = _capture_figures(monkeypatch)
    styles, cache = canvas.Styles(df), canvas.SeriesCache(folder)
    for kind in figures.KINDS:
        figures.scenario_plot(kind, df, cache, tmp_path, "cone_top", styles)
    scorecard_plot.scorecard_figure(df, tmp_path)
    assert len(kept) == 6
    for path, fig in kept:
        assert _outside(fig, path) == []
    errors = json.loads((tmp_path / "cone-top__errors.json").read_text())
    labels = {ln["label"] for ln in errors["lines"]}
    assert any(LONG in lab for lab in labels), labels
    for ln in errors["lines"]:
        for path in ln["paths"]:
            assert all(0 <= x <= 1 and 0 <= y <= 1 for x, y in path)
    assert "cone_top" in errors["alt"] and "diverged" in errors["alt"]


def test_the_legend_check_catches_a_cut_legend(folder, df, tmp_path, monkeypatch):
    """The check above fails on a figure that is not fitted around its legend (the figure
    left at its first size): the long label reaches beyond the image."""
    from reports.report import canvas, plots

    df = df.copy()
    df.loc[(df["engine"] == "mujoco") & (df["integrator"] == "RK4"), "integrator"] = LONG
    kept = _capture_figures(monkeypatch)
    monkeypatch.setattr(plots, "_new_figure", _narrow(canvas._new_figure))
    monkeypatch.setattr(canvas, "_fit", lambda fig, notes="": None)
    plots.work_precision_plot(df, tmp_path, "cone_top", canvas.Styles(df))
    ((path, fig),) = kept
    assert any(what == "legend" for _, what, _ in _outside(fig, path))


def _narrow(real):
    """``_new_figure`` with the figure only 1.5 in wider than its axes."""

    def new(*args, **kw):
        fig, axes = real(*args, **kw)
        w, h = fig.get_size_inches()
        fig.set_size_inches(1.0 + 5.6 + 1.5, h)
        for ax in axes:
            p = ax.get_position()
            ax.set_position([1.0 / 8.1, p.y0, 5.6 / 8.1, p.height])
        return fig, axes

    return new


def _overlapping_texts(fig) -> list:
    """The pairs of visible texts drawn on a figure's axes (annotations, ax.text) whose boxes
    overlap, by matplotlib's own extents."""
    r = fig.canvas.get_renderer()
    boxes = [
        (t.get_text(), t.get_window_extent(r))
        for ax in fig.axes
        for t in ax.texts
        if t.get_visible() and t.get_text()
    ]
    return [
        (a, b) for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1 :] if ba.overlaps(bb)
    ]


def test_each_diverged_configuration_is_told_apart_on_the_errors_figure(tmp_path, monkeypatch):
    """heavy_top at dt = 1e-3 s, where MuJoCo's Euler diverges at 2.58 s and Drake's
    semi-explicit Euler at 1.64 s (the default suite's numbers): the figure's texts do not
    overlap, and each configuration's legend entry carries its own divergence time."""
    from reports.report import canvas, plots

    sc = scenarios.load("heavy_top").replace(dt_sweep=(1e-3,))
    specs = plan([sc], ("exact", "mujoco", "drake"), ("reference", "Euler", "semi_explicit_euler"))
    run_suite(specs, tmp_path, progress=False)
    df = read_results(tmp_path)
    diverged = df[df["status"] == "diverged"]
    assert len(diverged) == 2 and diverged["t_diverged"].nunique() == 2
    kept = _capture_figures(monkeypatch)
    plots.errors_plot(df, canvas.SeriesCache(tmp_path), tmp_path, "heavy_top", canvas.Styles(df))
    ((path, fig),) = kept
    assert _overlapping_texts(fig) == []
    assert _outside(fig, path) == []
    legend = [" ".join(t.get_text().split()) for t in fig.axes[0].get_legend().get_texts()]
    for r in diverged.to_dict("records"):
        (entry,) = [lab for lab in legend if lab.startswith(f"{r['engine']} {r['integrator']}")]
        assert f"diverged at {fmt(r['t_diverged'])} s" in entry, (entry, r["t_diverged"])


def test_figures_name_what_they_leave_out(folder, df, tmp_path):
    """A configuration not drawn (never within 0.1 rad, no run finished) or cut off at a
    panel's top is named under the figure, not counted."""
    from reports.report import canvas, plots

    plots.work_precision_plot(df, tmp_path, "cone_top", canvas.Styles(df))
    meta = canvas.figure_meta(tmp_path / "cone-top__work_precision.png")
    # semi-implicit Euler diverges on cone_top at both steps: no finished run to draw
    euler = df[(df["scenario"] == "cone_top") & (df["integrator"] == "Euler")]
    assert set(euler["status"]) == {"diverged"}
    assert "not drawn" in meta["alt"] and "mujoco Euler" in meta["alt"]


def test_a_rates_figure_of_the_reference_alone_is_a_sentence_instead(folder, df, tmp_path):
    """free_tumbling here: every configuration's W error stays within 1 % of max |W| of the
    reference (checked on the stored metric and the reference's own series), so no rates
    figure is drawn and the report says why in one sentence; cone_top, where mujoco Euler
    diverges, keeps its figure and no such sentence."""
    import html as htmlmod

    import numpy as np

    from reports.report import canvas, plots
    from reports.store.results import reference_rows

    cache = canvas.SeriesCache(folder)
    free = df[df["scenario"] == "free_tumbling"]
    ref = cache.get(free[reference_rows(free)].iloc[0])
    wmax = float(np.max(np.abs(np.column_stack([ref["wx"], ref["wy"], ref["wz"]]))))
    runs = free[~reference_rows(free)]
    assert len(runs) >= 3 and (runs["omega_error_max"] <= 0.01 * wmax).all()
    styles = canvas.Styles(df)
    assert plots.rates_plot(df, cache, tmp_path, "free_tumbling", styles) is None
    assert plots.rates_plot(df, cache, tmp_path, "cone_top", styles) is not None
    assert not (folder / "plots" / "free-tumbling__rates.png").exists()
    note = plots.rates_left_out(df, cache, "free_tumbling")
    assert (
        note.startswith("No rates figure: the W error of all ") and f"({fmt(wmax)} rad/s)" in note
    )
    assert plots.rates_left_out(df, cache, "cone_top") == ""
    md = (folder / "report.md").read_text()
    free_md = md.split("### free_tumbling")[1]
    assert note in free_md and note not in md.split("### free_tumbling")[0]
    assert htmlmod.escape(note) in (folder / "report.html").read_text()


def test_report_html_shows_key_figures_with_hover_and_alt_text(folder):
    """Without a click: per scenario, its picture, errors and work-precision figures
    (outside any <details>); the scorecard picture, whose text a narrow screen shrinks
    beyond reading, one click away (the verdict table and the scorecard table are in view);
    every embedded image has an alt text that describes it (not a file name) and the line
    figures carry their hover data."""
    import html as htmlmod

    page = (folder / "report.html").read_text()
    visible = re.sub(r"<details.*?</details>", "", page, flags=re.S)
    for kind in ("scenario", "errors", "work_precision"):
        assert f"class='fig k-{kind}'" in visible, kind
    assert "class='fig k-scorecard'" not in visible and "class='fig k-scorecard'" in page
    alts = [htmlmod.unescape(a) for a in re.findall(r"<img alt='([^']*)'", page)]
    # the scorecard and 9 figures (free_tumbling's rates figure is a sentence instead)
    assert len(alts) == page.count("<img ") >= 10
    assert all(len(a) > 40 and "__" not in a and not a.endswith(".png") for a in alts), alts
    assert page.count("data-lines=") >= 6
    md = (folder / "report.md").read_text()
    assert "![cone_top: running maximum of the attitude error" in md


#: added to a copy of report.html: opens every collapsed section and writes into the page, for
#: each table wider than its container, its section, class and widths (--dump-dom prints it)
TABLE_WIDTHS = """<script>
window.addEventListener('load', function () {
  document.querySelectorAll('details').forEach(function (d) { d.open = true; });
  var wide = [];
  document.querySelectorAll('table').forEach(function (t) {
    var box = t.parentElement.clientWidth, sec = t.closest('section');
    if (t.scrollWidth > box + 1)
      wide.push((sec ? sec.id : '') + ' ' + t.className + ': ' + t.scrollWidth + ' in ' + box);
  });
  var cards = [];
  document.querySelectorAll('table').forEach(function (t) {
    if (getComputedStyle(t).display !== 'table') cards.push(t.className);
  });
  var pre = document.createElement('pre');
  pre.id = 'table-widths';
  pre.textContent = JSON.stringify({width: document.documentElement.clientWidth, wide: wide,
    tables: document.querySelectorAll('table').length, cards: cards});
  document.body.appendChild(pre);
});
</script>"""


@pytest.mark.skipif(
    shutil.which("chromium") is None, reason="Debian's chromium is not installed: not rendered"
)
def test_every_table_fits_its_container_at_1400_800_and_600_px(folder, tmp_path):
    """In headless Chromium at 1400 px (a laptop), 800 px and 600 px, with every section
    open: no table is wider than its container, so nothing scrolls sideways (free_tumbling's
    table of every metric was 1326 px in 1320). Tables of many columns turn into cards below
    1000 px; the cheapest configuration per accuracy and the settings stay tables at 800 px
    (as cards they were 5 and 3 times as tall on the default suite) and turn into cards at
    600 px."""
    import html as htmlmod
    import subprocess

    probe = tmp_path / "probe.html"
    page = (folder / "report.html").read_text()
    probe.write_text(page.replace("</body>", TABLE_WIDTHS + "</body>"))
    for width in (1400, 800, 600):
        dom = subprocess.run(
            [
                shutil.which("chromium"),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--hide-scrollbars",
                f"--user-data-dir={tmp_path / 'profile'}",
                f"--window-size={width},1600",
                "--dump-dom",
                probe.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        ).stdout
        found = re.search(r'<pre id="table-widths">(.*?)</pre>', dom, flags=re.S)
        assert found, f"no result in the DOM at {width} px: {dom[-500:]}"
        check = json.loads(htmlmod.unescape(found.group(1)))
        assert check["width"] == width and check["tables"] >= 5, check
        assert check["wide"] == [], check
        cards = {c.split()[0] for c in check["cards"]}  # the first class names the table
        stay = {"wp", "settings"}
        if width == 1400:
            assert cards == set(), check
        elif width == 800:
            assert "scorecard" in cards and not stay & cards, check
        else:
            assert {"scorecard", *stay} <= cards, check


def test_scenario_box_has_the_scenario_s_moments():
    """The box drawn for a body has its mass and principal moments: its inertia, integrated
    by the midpoint rule on a 40^3 grid (an independent quadrature, relative error of order
    1/40^2 = 6e-4), matches the scenario's moments to 1e-3."""
    import numpy as np

    from reports.report.pictures import body_box

    for name in ("dzhanibekov", "heavy_top", "gazebo_boxes_complex", "pendulum_through_vertical"):
        sc = scenarios.load(name)
        half = body_box(sc)
        n = 40
        grids = [(np.arange(n) + 0.5) / n * 2 * h - h for h in half]
        x, y, z = np.meshgrid(*grids, indexing="ij")
        dm = sc.mass / x.size
        moments = [
            float(np.sum(y**2 + z**2) * dm),
            float(np.sum(x**2 + z**2) * dm),
            float(np.sum(x**2 + y**2) * dm),
        ]
        assert np.allclose(moments, sc.inertia, rtol=1e-3), (name, moments, sc.inertia)


def test_scenario_figures_for_the_docs(tmp_path):
    """``python -m reports.report.pictures --scenario-figures DIR NAME`` writes a small PNG per
    scenario; an unknown name is an error naming it."""
    from reports.report.pictures import main

    assert main(["--scenario-figures", str(tmp_path), "cone_top"]) == 0
    png = tmp_path / "scenario_cone_top.png"
    assert png.exists() and png.stat().st_size < 60_000
    assert main(["--scenario-figures", str(tmp_path), "no_such_scenario"]) == 2


def test_every_configuration_has_a_colour_of_its_own(df):
    """No two configurations of a folder share a colour (the director's four schemes were
    once all one blue)."""
    from reports.report import canvas

    styles = canvas.Styles(df)
    configs = {(e, i) for e, i in zip(df["engine"], df["integrator"], strict=True)} - {
        ("exact", "reference")
    }
    colours = [styles.of({"engine": e, "integrator": i, "family": ""})["color"] for e, i in configs]
    assert len(configs) >= 6 and len(set(colours)) == len(configs)


def test_configurations_whose_colours_look_alike_have_different_markers():
    """The palette's second ten colours repeat the hues of the first ten (#2ca02c and #31a354
    are both green): configuration k and k + 10 must not also share a marker, or a figure
    whose runs show as markers only (a one-step work-precision point) cannot tell them apart.
    No two of 40 configurations share both colour and marker."""
    import pandas as pd

    from reports.report import canvas

    df = pd.DataFrame(
        {"engine": [f"e{k:02d}" for k in range(40)], "integrator": "x", "family": "f"}
    )
    styles = canvas.Styles(df)
    looks = [
        (s["color"], s["marker"])
        for s in (styles.of(r, always_marker=True) for r in df.to_dict("records"))
    ]
    assert len(set(looks)) == 40
    assert all(looks[k][1] != looks[k + 10][1] for k in range(30))


def test_scorecard_picture_is_written_as_png_and_svg_with_text(folder):
    """The scorecard picture for a README: a PNG and an SVG whose words are text (found by
    search, small), naming every scenario and configuration."""
    svg = (folder / "scorecard.svg").read_text()
    assert (folder / "scorecard.png").stat().st_size > 10_000
    for word in ("cone_top", "free_tumbling", "director rattle4", "pinocchio + suite RKMK4"):
        assert word in svg, word


def test_energy_momentum_note_only_where_the_scheme_ran(df):
    """The scorecard's paragraph on the energy-momentum scheme is printed when the scheme ran
    and not when every one of its runs is unsupported (it then explains nothing shown)."""
    from reports.report.doc import Doc
    from reports.report.sections import scorecard_section
    from reports.report.tables import scorecard

    def note(rows) -> bool:
        doc = Doc()
        scorecard_section(doc, rows, scorecard(rows))
        return any("**energy_momentum:**" in line for line in doc.md)

    em = (df["integrator"] == "energy_momentum") & (df["engine"] == "director")
    assert (df.loc[em, "status"] == "ok").any() and note(df)
    none_ran = df.copy()
    none_ran.loc[em, "status"] = "unsupported"
    none_ran.loc[em, "verdict"] = ""
    assert not note(none_ran)


def test_building_a_report_asks_no_engine_and_no_reference(folder):
    """The report is a function of the results folder: building it imports nothing of the
    engine adapters (references.engines) or the exact references (references.exact), so a
    folder of engines not installed here is reported all the same."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from reports.report.build import build_report\n"
        f"build_report({str(folder)!r})\n"
        "print(sorted(m for m in sys.modules if m.startswith(('references.engines', "
        "'references.exact'))))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout


def test_scorecard_figure_is_as_wide_as_its_content(df, tmp_path):
    """One scenario makes a narrow scorecard picture (its title and legend wrap to the label
    column and one column of cells, 2.5 + 1.3 in), not one as wide as a one-line title
    (8.8 in before); more scenarios make it wider."""
    from PIL import Image

    from reports.report.canvas import DPI
    from reports.report.scorecard_plot import scorecard_figure

    widths = {}
    for n, names in ((1, ["free_tumbling"]), (2, ["free_tumbling", "cone_top"])):
        (tmp_path / str(n)).mkdir()
        png, _ = scorecard_figure(df[df["scenario"].isin(names)], tmp_path / str(n))
        widths[n] = Image.open(png).size[0] / DPI
    # 1.5 in for configuration labels longer than the label column (they are never cut)
    assert widths[1] < 2.5 + 1.3 + 1.5, widths
    assert widths[2] > widths[1] + 1.0, widths


def test_scenario_picture_draws_the_body_stored_in_the_folder(folder, df, tmp_path, monkeypatch):
    """The scenario picture takes the body from the folder (stored beside the exact run's
    trajectory), not from the scenario library: with the library out of reach it is drawn
    all the same, and the stored body is the scenario file's."""
    import numpy as np

    from reports.report import canvas, pictures

    sc = scenarios.load("cone_top")
    monkeypatch.setattr(pictures, "library_scenario", lambda row: None)
    cache = canvas.SeriesCache(folder)
    exact = df[(df["scenario"] == "cone_top") & (df["engine"] == "exact")]
    row = exact.to_dict("records")[0]
    body = cache.body(row)
    assert body.name == sc.name and body.mass == sc.mass
    assert np.array_equal(body.inertia, sc.inertia) and np.array_equal(body.pivot, sc.pivot)
    assert np.array_equal(body.omega_body, sc.omega_body)
    path = pictures.scenario_plot_from_results(df, cache, tmp_path, "cone_top")
    assert path is not None and path.exists()


def test_the_reference_rows_are_told_by_the_recorded_flag_not_the_engine_name():
    import pandas as pd

    from reports.store.results import is_reference_record, reference_rows

    df = pd.DataFrame(
        {
            "engine": ["exact", "mujoco", "my_reference"],
            "family": ["exact", "RK4", "exact-ish"],
            "reference": [1.0, 0.0, 1.0],
        }
    )
    assert reference_rows(df).tolist() == [True, False, True]
    assert [is_reference_record(r) for r in df.to_dict("records")] == [True, False, True]
    # a folder written before the flag was recorded: the reference family of that time
    old = df.assign(reference=float("nan"))
    assert reference_rows(old).tolist() == [True, False, False]
    assert [is_reference_record(r) for r in old.to_dict("records")] == [True, False, False]


def test_the_text_caching_backend_draws_the_pixels_agg_draws(tmp_path):
    """reports.report.agg_text caches string layouts and glyph bitmaps across figures: a figure
    of texts at fractional positions, sizes, weights, a rotated label, mathtext, non-ASCII
    (superscripts, marks) must come out pixel for pixel as matplotlib's own Agg draws it,
    the first time (caches filling) and the second (caches hit)."""
    import matplotlib
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from reports.report import agg_text

    def draw(canvas_class):
        fig = Figure(figsize=(4.3, 2.7), dpi=100)
        canvas = canvas_class(fig)
        ax = fig.add_axes([0.17, 0.2, 0.5, 0.6])
        ax.plot(
            [1e-9, 1.0], [3e-12, 2.0], label="director rattle, mujoco RK4\n(diverged at 1.64 s)"
        )
        ax.set_yscale("log")
        ax.set_ylabel("attitude error [rad]")
        ax.set_title("cone_top: errors 10⁻⁵ ✓ ✗ ↯", fontsize=10.5)
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
        for k in range(7):
            fig.text(0.013 + 0.0371 * k, 0.0137 * k + 0.003, f"t = {k}.37 s", fontsize=7 + 0.7 * k,
                     weight="bold" if k % 2 else "normal")  # fmt: skip
        fig.text(0.5, 0.9, r"$\omega_3 = 10^{-5}$ dt")
        canvas.draw()
        return np.asarray(canvas.buffer_rgba()).copy()

    assert agg_text.SUPPORTED, f"matplotlib {matplotlib.__version__}: plain Agg is drawn"
    agg_text._GLYPHS.clear(), agg_text._LAYOUTS.clear(), agg_text._METRICS.clear()
    want = draw(FigureCanvasAgg)
    first = draw(agg_text.FigureCanvasCachedText)
    assert agg_text._GLYPHS and agg_text._LAYOUTS and agg_text._METRICS  # it did cache
    second = draw(agg_text.FigureCanvasCachedText)
    assert want.shape == first.shape == second.shape
    assert (want != first).any(axis=-1).sum() == 0
    assert (want != second).any(axis=-1).sum() == 0


def test_cheapest_per_accuracy_table_does_not_print_digits_the_reference_lacks(df):
    """The "its error" column of a scenario's cheapest-per-accuracy table says "< a" for an
    error below the reference's accuracy a, as every other table does: the error of a run
    better than its reference is not measured."""
    from reports.report.doc import Doc
    from reports.report.sections import wp_table

    sub = df[df["scenario"] == "free_tumbling"].copy()
    # the cheapest run within the loosest level; a reference accuracy twice its error, still
    # within that level, leaves it the cheapest there with its error unmeasured
    lv = work_precision(sub)[0]
    first = lv["ranked"][0]
    err = first["attitude_error_max"]
    acc = 2 * err
    assert 0 < acc <= lv["level"]
    sub["reference_accuracy"] = acc
    doc = Doc()
    wp_table(doc, "free_tumbling", sub)
    row = next(r for r in doc.md[0].splitlines() if first["configuration"] in r)
    row = html.unescape(row)  # Markdown cells carry "<" as "&lt;"
    assert f"| < {fmt(acc)} |" in row
    assert f"| {fmt(err)} |" not in row
