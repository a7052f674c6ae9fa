"""The report's documents as a verdict: scorecard first, engines that run one algorithm
collapsed, Markdown that a GitHub-flavoured parser renders as tables, the HTML page and its
tables, summary.json, the CI job summary and the README block; on a small real suite with
failures in it (conftest.py)."""

import html
import json
import re
import shutil

import pytest

from reports.report.tables import failures, scorecard, work_precision
from reports.store.format import fmt
from reports.store.results import read_results


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


def test_building_a_report_asks_no_engine_and_no_reference(folder, tmp_path):
    """The report is a function of the results folder: building it imports nothing of the
    engine adapters or the exact references (references.exact), so a folder of engines not
    installed here is reported all the same. A folder whose provenance.json names its engines
    (every ``director-bench run`` writes one) imports nothing of references.engines at all;
    one without (the folder of this session, written by run_suite) reads the engine order
    from the registry, references.engines, and still no adapter."""
    import ast
    import subprocess
    import sys

    from references.engines import BUILTIN

    def imported(root):
        code = (
            "import sys\n"
            "from reports.report.build import build_report\n"
            f"build_report({str(root)!r})\n"
            "print(sorted(m for m in sys.modules if m.startswith(('references.engines', "
            "'references.exact'))))\n"
        )
        run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        return ast.literal_eval(run.stdout.strip().splitlines()[-1])

    dst = tmp_path / "folder"
    shutil.copytree(folder, dst)
    engines = sorted(read_results(dst)["engine"].unique())
    (dst / "provenance.json").write_text(json.dumps({"engines": dict.fromkeys(engines, "1")}))
    assert imported(dst) == []
    without = imported(folder)
    assert "references.engines" in without  # the registry: the check above can fail
    adapters = tuple(f"references.engines.{e}" for e in BUILTIN) + ("references.exact",)
    assert [m for m in without if m.startswith(adapters)] == []


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
