"""The report of a results folder, in Markdown and self-contained HTML: a verdict first.

``report.md`` and ``report.html`` are pure functions of the folder (the results store,
``provenance.json``, the per-run series files and, if present, the ensemble store); what they
say comes from reports.report.tables (grouped by reports.report.groups, named by
reports.report.labels), the figures from reports.report.figures. In order:

1. a line of provenance and counts, and a table of contents;
2. the **scorecard**: scenario x integrator family, each cell the verdicts at the scenario's
   own dt with the max attitude error and energy drift, configurations that agree collapsed
   into one entry, linked to the scenario's details (colour-coded in HTML);
3. the **work-precision** answers: per scenario and accuracy, the cheapest configuration,
   ranked by the time spent inside the engine (``engine_time_s``), never by a wall time that
   includes the suite's own Python (configurations integrated by the suite read
   ``pinocchio + suite RKMK4``);
4. **failures and divergences** (with the time of divergence), then the runs that did not run;
5. **details** per scenario (collapsible in HTML): the table at its dt, the dt sweep, the
   work-precision table and the figures;
6. the **settings** changed from the engines' defaults, every value that ran (collapsed), and
   the full provenance.

Every table is preceded by a one-line title, so that two reports diff cleanly; Markdown
tables escape what GitHub-flavoured Markdown would otherwise read as cell borders. The
scorecard is also written to ``summary.json`` (reports.report.summary_json) and, when the
environment variable ``GITHUB_STEP_SUMMARY`` names a file, appended to it.
"""

from __future__ import annotations

import html
import os
from pathlib import Path

from reports.report.contact import contact_rows, contact_section
from reports.report.doc import CARDS, CSS, SCRIPT, Doc, anchor
from reports.report.labels import with_engine_order
from reports.report.sections import (
    details_section,
    ensemble_section,
    failures_section,
    scorecard_picture,
    scorecard_section,
    settings_section,
    verdict_section,
    work_precision_section,
)
from reports.report.summary_json import write_summary
from reports.report.tables import (
    failures,
    scenarios_of,
    scorecard,
    settings_table,
)
from reports.store.atomic import write_text
from reports.store.format import md_cell
from reports.store.provenance import read_provenance
from reports.store.runs import STATUSES


def count_line(df) -> str:
    """``276 runs: 210 ok (143 pass, 67 fail), 45 diverged, 12 error, 9 unsupported.``"""
    if df.empty:
        return "No runs in this folder."
    counts = df["status"].value_counts().to_dict()
    parts = []
    for st in (*STATUSES, *sorted(set(counts) - set(STATUSES))):
        n = counts.get(st, 0)
        if not n:
            continue
        if st == "ok":
            ok = df[df["status"] == "ok"]["verdict"].value_counts().to_dict()
            inner = ", ".join(f"{ok[v]} {v}" for v in ("pass", "fail") if ok.get(v))
            parts.append(f"{n} ok ({inner})" if inner else f"{n} ok")
        else:
            parts.append(f"{n} {st}")
    return f"{len(df)} runs: " + ", ".join(parts) + "."


def provenance_line(prov: dict) -> str:
    if not prov:
        return "No provenance.json in this folder: versions and machine unknown"
    m = prov.get("machine", {}) or {}
    commit = str(prov.get("git_commit", "?"))
    short = commit[:10] + (" (uncommitted changes)" if commit.endswith("+dirty") else "")
    return (
        f"director-bench {prov.get('suite_version', '?')}, commit {short}, "
        f"{prov.get('date', '?')}, {m.get('cpu', '?')} ({m.get('cores', '?')} cores)"
    )


def provenance_rows(prov: dict) -> list[list[str]]:
    m = prov.get("machine", {}) or {}
    rows = [
        ["suite version", str(prov.get("suite_version", "?"))],
        ["git commit", str(prov.get("git_commit", "?"))],
        ["date (UTC)", str(prov.get("date", "?"))],
        ["machine", f"{m.get('cpu', '?')}, {m.get('cores', '?')} cores"],
        ["platform", f"{m.get('platform', '?')}, Python {m.get('python', '?')}"],
    ]
    rows += [[f"engine {e}", str(v)] for e, v in (prov.get("engines", {}) or {}).items()]
    rows += [
        [f"engine {e}", f"not in the default suite here: {why} (--engines all adds it)"]
        for e, why in (prov.get("left_out", {}) or {}).items()
    ]
    if prov.get("note"):
        rows.append(["note", str(prov["note"])])
    return rows


CSS += "".join(
    CARDS.replace("WIDTH", str(w)).replace("CLS", c)
    for c, w in (("stack", 1000), ("narrow-stack", 640))
)


def _toc(df, has_settings: bool, has_ensemble: bool) -> tuple[str, str]:
    entries = []
    if len(df):
        entries.append(("Scorecard", "scorecard"))
        if len(contact_rows(df)):
            entries.append(("Contact", "contact"))
        entries.append(("Work precision", "work-precision"))
        entries.append(("Failures and divergences", "failures-and-divergences"))
        entries += [(s, anchor(s)) for s in scenarios_of(df)]
    if has_ensemble:
        entries.append(("Ensembles", "ensembles"))
    if has_settings:
        entries.append(("Settings", "settings"))
    entries.append(("Provenance", "provenance"))
    md = " · ".join(f"[{md_cell(t)}](#{a})" for t, a in entries)
    h = " ".join(f"<a href='#{a}'>{html.escape(t)}</a>" for t, a in entries)
    return f"**Contents:** {md}", f"<nav class='toc'><b>Contents:</b> {h}</nav>"


def document(
    df, prov: dict, plots: dict, root: Path, edf=None, card_figures=(), card=None
) -> tuple[str, str]:
    """(report.md, report.html) of a results table; ``card_figures``: the scorecard picture
    (reports.report.scorecard_plot.scorecard_figure: its PNG is shown, its SVG linked);
    ``card``: the table's :func:`reports.report.tables.scorecard` if the caller has it
    already."""
    doc = Doc()
    doc.md.append("# director-bench report\n")
    doc.html.append("<h1 id='director-bench-report'>director-bench report</h1>")
    doc.para(
        md_cell(f"{provenance_line(prov)}. {count_line(df)}"),  # provenance.json is text
        f"<span class='meta'>{html.escape(provenance_line(prov))}.</span> "
        f"<b>{html.escape(count_line(df))}</b>",
    )
    has_settings = bool(len(df)) and bool(settings_table(df))
    toc_md, toc_html = _toc(df if len(df) else df, has_settings, edf is not None)
    doc.md.append(toc_md + "\n")
    doc.html.append(toc_html)
    if len(df):
        card = scorecard(df) if card is None else card
        verdict_section(doc, df, card)  # the first screen, in both reports
        doc.heading(2, "Scorecard")
        scorecard_picture(doc, [Path(p) for p in card_figures], root, df)
        with doc.only("html"):  # report.md: each scenario's verdicts, in its section
            scorecard_section(doc, df, card)
        contact_section(doc, df)
        doc.heading(2, "Work precision")
        doc.md_details("The cheapest configuration of each engine per accuracy, per scenario")
        work_precision_section(doc, df)
        doc.md_end()
        doc.heading(2, "Failures and divergences")
        doc.md_details(_failures_summary(df))
        failures_section(doc, df)
        doc.md_end()
        details_section(doc, df, plots, root, card)
    if edf is not None:
        ensemble_section(doc, edf, root)
    if has_settings:
        settings_section(doc, df)
    doc.heading(2, "Provenance")
    if prov:
        doc.md_details("Versions, commit, date and machine of the runs")
        doc.table("Provenance of the runs", ["item", "value"], provenance_rows(prov))
        doc.md_end()
    else:
        doc.para("This folder has no provenance.json (written by `director-bench run`).")
    md = "\n".join(doc.md)
    page = (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width,initial-scale=1'>"
        f"<title>director-bench report</title><style>{CSS}</style>"
        f"<script>{SCRIPT}</script></head><body>\n" + "\n".join(doc.html) + "\n</body></html>\n"
    )
    return md, page


def _failures_summary(df) -> str:
    fails = failures(df)
    own = sum(1 for f in fails if f["own_dt"])
    return (
        f"{own} group(s) of configurations failing, diverging or in error at each "
        f"scenario's own step, {len(fails) - own} at the other steps of the dt sweeps; the "
        "runs that did not run"
    )


def step_summary(df, card=None) -> str:
    """The verdicts as Markdown for a CI job summary (no links: the details are elsewhere);
    ``card`` as for :func:`document`."""
    doc = Doc()
    doc.md.append("## director-bench verdicts\n")
    doc.para(count_line(df))
    if len(df):
        verdict_section(doc, df, scorecard(df) if card is None else card, links=False)
    return "\n".join(doc.md)


def python_strings(df):
    """The results table with its text columns as Python strings (object dtype) in place of
    pandas' Arrow-backed strings, copied into one block of columns per type: the report
    selects rows of it hundreds of times, and a selection copies every Arrow column, and
    every block, with a call of its own (the store's table has a block per column: a
    selection of its rows is about six times as fast from two blocks). The values, and what
    comparing or sorting them gives, are the same."""
    import pandas as pd

    text = {c: object for c in df.columns if isinstance(df[c].dtype, pd.StringDtype)}
    return df.astype(text).copy()  # the copy consolidates the blocks


def build_report(root: str | Path, progress: bool = False, results=None) -> dict[str, Path]:
    """Write the figures, report.md, report.html and summary.json for the results folder
    ``root``; with ``GITHUB_STEP_SUMMARY`` set, append the scorecard to that file.
    ``progress``: a progress bar while figures are drawn (figures whose inputs did not
    change since the last report are reused, reports.report.figures). ``results``: the
    folder's current results as the caller just read them (reports.store.results.
    read_results), not read again."""
    from reports.report.figures import report_figures
    from reports.store.ensemble import read_ensemble
    from reports.store.results import STORE_NAME, frame, read_results

    root = Path(root)
    edf = read_ensemble(root)
    if results is not None:
        df = results
    elif (root / STORE_NAME).exists() or edf is None:
        df = read_results(root)
    else:  # a folder holding only an ensemble
        df = frame([])
    prov = read_provenance(root)
    df = with_engine_order(python_strings(df), prov)  # the folder's engine order, everywhere
    plots, card_figures = report_figures(df, root, progress=progress)
    card = scorecard(df)  # shown in the report, summary.json and the CI job summary
    md, page = document(df, prov, plots, root, edf, card_figures, card)
    _write(root / "report.md", md)
    _write(root / "report.html", page)
    summary_path = write_summary(root, df, prov, card)
    target = os.environ.get("GITHUB_STEP_SUMMARY")
    if target:
        with open(target, "a", encoding="utf-8") as fh:
            fh.write(step_summary(df, card) + "\n")
    return {
        "markdown": root / "report.md",
        "html": root / "report.html",
        "plots": root / "plots",
        "summary": summary_path,
    }


def _write(path: Path, text: str) -> None:
    write_text(path, text, encoding="utf-8")
