"""The report of a results folder, in Markdown and self-contained HTML: a verdict first.

``report.md`` and ``report.html`` are pure functions of the folder (the results store,
``provenance.json``, the per-run series files and, if present, the ensemble store); what they
say comes from reports.summary, the figures from reports.plots. In order:

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
scorecard is also written to ``summary.json`` (reports.summary) and, when the environment
variable ``GITHUB_STEP_SUMMARY`` names a file, appended to it.
"""

from __future__ import annotations

import base64
import html
import math
import os
import re
from pathlib import Path

from reports.provenance import read_provenance
from reports.results import STATUSES
from reports.summary import (
    ACCURACY_LEVELS,
    ENERGY_MOMENTUM_NOTE,
    METRIC_SHORT,
    NOT_RUN,
    at_scenario_dt,
    config_label,
    energy_momentum_rows,
    failed_metrics,
    failures,
    family_key,
    fmt,
    fmt_attitude,
    fmt_int,
    fmt_level,
    fmt_order,
    fmt_step,
    group_rows,
    md_cell,
    not_run,
    scenario_info,
    scenarios_of,
    scorecard,
    settings_table,
    sweep_groups,
    work_precision,
    write_summary,
)

#: column titles of the metrics, with units (no character GitHub's tables would split on)
METRIC_TITLES = {
    "attitude_error_max": "attitude error [rad]",
    "omega_error_max": "W error [rad/s]",
    "position_error_max": "x_G error [m]",
    "flip_interval_error": "flip interval error [rel.]",
    "nutation_period_error": "nutation period error [rel.]",
    "energy_drift_max": "energy drift [E_c]",
    "momentum_drift_max": "momentum drift [L_c]",
    "orthonormality_max": "‖RᵀR − 1‖",
    "constraint_velocity_max": "velocity constraint [w_c]",
}

#: a mark per outcome in the HTML scorecard, beside its colour (the words are in the legend)
MARK = {
    "pass": "✓",
    "fail": "✗",
    "diverged": "↯",
    "error": "⚠",
    "reference-inaccurate": "?",
    "ok": "✓",
}

#: a symbol per outcome, so that the Markdown scorecard reads at a glance without colour
SYMBOL = {
    "pass": "✅",
    "fail": "❌",
    "diverged": "💥",
    "error": "⚠️",
    "reference-inaccurate": "❔",
    "unsupported": "➖",
    "unavailable": "➖",
    "ok": "✅",
}


# -- GitHub-compatible anchors --------------------------------------------------------------------


def anchor(text: str) -> str:
    """The id GitHub gives a heading: lower case, punctuation other than ``-`` and ``_``
    dropped, spaces as ``-``; the HTML report uses the same ids, so links work in both."""
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


# -- a document written as Markdown and HTML at once ----------------------------------------------


class Cell:
    """A table cell: plain text, or Markdown and HTML of its own; ``num``: a number (kept
    on one line, right-aligned); ``cls``: an HTML class (the verdict colours)."""

    def __init__(self, text="", md=None, html_=None, num=False, cls=""):
        self.text = str(text)
        self.md = md
        self.html = html_
        self.num = num
        self.cls = cls

    def to_md(self) -> str:
        return self.md if self.md is not None else md_cell(self.text)

    def to_html(self) -> str:
        return self.html if self.html is not None else html.escape(self.text)


def scenario_link(scenario: str) -> Cell:
    """A scenario's name linking to its details."""
    a = anchor(scenario)
    return Cell(
        md=f"[{md_cell(scenario)}](#{a})",
        html_=f"<a href='#{a}'>{html.escape(scenario)}</a>",
    )


def nums(values) -> Cell:
    """Several numbers in one cell (one per configuration of a group), each kept whole."""
    texts = [fmt(v) for v in values]
    return Cell(
        " / ".join(texts),
        html_=" / ".join(f"<span>{html.escape(t)}</span>" for t in texts),
        cls="nums",
    )


def num(v, text=None) -> Cell:
    return Cell(fmt(v) if text is None else text, num=True)


class Doc:
    """Markdown and HTML written side by side."""

    def __init__(self):
        self.md: list[str] = []
        self.html: list[str] = []

    def heading(self, level: int, text: str, id_: str | None = None) -> None:
        id_ = id_ or anchor(text)
        self.md.append(f"{'#' * level} {text}\n")
        self.html.append(f"<h{level} id='{html.escape(id_)}'>{html.escape(text)}</h{level}>")

    def para(self, md: str, html_: str | None = None) -> None:
        self.md.append(md + "\n")
        self.html.append(f"<p>{html_ if html_ is not None else html.escape(md)}</p>")

    def bullets(self, items: list[tuple[str, str]]) -> None:
        """Items as (Markdown, HTML)."""
        self.md.append("\n".join(f"- {m}" for m, _ in items) + "\n")
        self.html.append("<ul>" + "".join(f"<li>{h}</li>" for _, h in items) + "</ul>")

    def table(self, title: str, header: list, rows: list[list], cls: str = "") -> None:
        """A table with its one-line title; in HTML inside a container that scrolls when the
        table is wider than the page."""
        cells = [[c if isinstance(c, Cell) else Cell(c) for c in r] for r in rows]
        md = [f"**{md_cell(title)}**", ""] if title else []
        md.append("| " + " | ".join(md_cell(h) for h in header) + " |")
        md.append("|" + "|".join("---" for _ in header) + "|")
        md += ["| " + " | ".join(c.to_md() for c in r) + " |" for r in cells]
        self.md.append("\n".join(md) + "\n")
        head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
        body = []
        for r in cells:
            tds = []
            for c in r:
                classes = " ".join(x for x in ("num" if c.num else "", c.cls) if x)
                attr = f" class='{classes}'" if classes else ""
                tds.append(f"<td{attr}>{c.to_html()}</td>")
            body.append("<tr>" + "".join(tds) + "</tr>")
        caption = f"<div class='title'>{html.escape(title)}</div>" if title else ""
        self.html.append(
            f"{caption}<div class='scroll'><table class='{cls}'><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table></div>"
        )

    def open_details(self, summary: str, id_: str = "", md: bool = True, open_=False) -> None:
        """A collapsible section (HTML); with ``md`` also in Markdown (GitHub renders it)."""
        attr = (f" id='{html.escape(id_)}'" if id_ else "") + (" open" if open_ else "")
        self.html.append(f"<details{attr}><summary>{summary}</summary>")
        if md:
            self.md.append(f"<details><summary>{html.escape(_strip_tags(summary))}</summary>\n")

    def close_details(self, md: bool = True) -> None:
        self.html.append("</details>")
        if md:
            self.md.append("</details>\n")

    def images(self, paths: list[Path], root: Path) -> None:
        if not paths:
            return
        for p in paths:
            self.md.append(f"![{p.stem}]({p.relative_to(root).as_posix()})\n")
        figs = []
        for p in paths:
            data = base64.b64encode(p.read_bytes()).decode()
            figs.append(
                f"<img alt='{html.escape(p.stem)}' loading='eager' "
                f"src='data:image/png;base64,{data}'>"
            )
        self.html.append("<div class='plots'>" + "".join(figs) + "</div>")

    def raw_html(self, text: str) -> None:
        self.html.append(text)


def _strip_tags(text: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", text))


# -- pieces -------------------------------------------------------------------------------------


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
    if prov.get("note"):
        rows.append(["note", str(prov["note"])])
    return rows


def short_labels(df) -> dict:
    """Scorecard labels: the integrator alone in a family only one engine runs (the director
    schemes), the engine alone where it has one integrator in the family, else both."""
    out = {}
    for _, fam in df.groupby("family"):
        single_engine = fam["engine"].nunique() == 1
        for eng, g in fam.groupby("engine"):
            integs = set(g["integrator"])
            for i in integs:
                if single_engine and len(integs) > 1:
                    out[(eng, i)] = i
                else:
                    out[(eng, i)] = eng if len(integs) == 1 else f"{eng} {i}"
    return out


def entry_texts(g, labels: dict) -> tuple[str, str, list[str]]:
    """(outcome, who, figures) of a scorecard entry; figures: short pieces, each kept on
    one line."""
    who = ", ".join(labels.get((r["engine"], r["integrator"]), config_label(r)) for r in g.rows)
    acc = g.first.get("target_accuracy")
    if isinstance(acc, float) and not math.isnan(acc):
        who += f" (tol {fmt_level(acc)})"
    fr = g.figure_row()
    out = g.outcome
    if out == "diverged":
        return out, who, [f"at t = {fmt(fr['t_diverged'])} s"]
    if out == "error":
        return out, who, ["error"]
    if out == "reference-inaccurate":
        return out, who, ["reference too coarse to judge"]
    figs = [f"{fmt_attitude(fr)} rad", f"E {fmt(fr['energy_drift_max'])}"]
    if out == "fail":
        names = [METRIC_SHORT.get(m, m) for m in failed_metrics(g.first["verdict_detail"])]
        figs.append(f"fails: {', '.join(names)}")
    return out, who, figs


def scorecard_section(doc: Doc, df, card, links: bool = True) -> None:
    fams = sorted({f for s in card for f in s["cells"]}, key=family_key)
    labels = short_labels(df)
    header = ["scenario", *fams]
    rows = []
    for s in card:
        sid = anchor(s["scenario"])
        where = f"dt {fmt_step(s['dt'])} s, {fmt_step(s['t_end'])} s"
        name_md = f"[{md_cell(s['scenario'])}](#{sid})" if links else md_cell(s["scenario"])
        row = [
            Cell(
                md=f"{name_md}<br>{where}",
                html_=f"<a href='#{sid}'>{html.escape(s['scenario'])}</a>"
                f"<br><small>{html.escape(where)}</small>",
            )
        ]
        for fam in fams:
            md_parts, html_parts = [], []
            for g in s["cells"].get(fam, []):
                out, who, figs = entry_texts(g, labels)
                md_parts.append(
                    f"{SYMBOL.get(out, '')} {md_cell(who)}: {md_cell(' · '.join(figs))}"
                )
                href = f" href='#{sid}'" if links else ""
                why = [f for f in figs if f.startswith("fails")]
                title = f" title='{html.escape(out)}: {html.escape(why[0])}'" if why else ""
                spans = " · ".join(
                    f"<span class='fig'>{html.escape(f)}</span>"
                    for f in figs
                    if not f.startswith("fails")
                )
                html_parts.append(
                    f"<a class='entry v-{out}'{href}{title}><b>{MARK.get(out, '')}</b> "
                    f"<span class='who'>{html.escape(who)}</span> {spans}</a>"
                )
            row.append(Cell(md="<br>".join(md_parts) or "-", html_="".join(html_parts) or "-"))
        rows.append(row)
    doc.table("Verdicts at each scenario's own dt", header, rows, cls="scorecard")
    doc.para(
        "✅ pass · ❌ fail (the metrics out of bounds in brackets) · 💥 diverged · ⚠️ error · ❔ "
        "the reference is not accurate enough to judge. Figures: max attitude error [rad] "
        "(`< x`: below the reference's accuracy x, not a measurement) and E, the max energy "
        "drift relative to the scenario's energy scale. Configurations in one entry agree to "
        "1e-3 in every metric (round-off-level values aside); the details give their largest "
        "difference.",
        "<span class='v-pass'>✓ pass</span> <span class='v-fail'>✗ fail</span> "
        "<span class='v-diverged'>↯ diverged</span> <span class='v-error'>⚠ error</span> "
        "<span class='v-reference-inaccurate'>? reference too coarse to judge</span>. "
        "Figures: max attitude error [rad] (<code>&lt; x</code>: below the reference's "
        "accuracy x, not a measurement) and E, the max energy drift relative to the "
        "scenario's energy scale; hovering over a failing entry names the metrics out of "
        "bounds (the failures section lists them). "
        "Configurations in one entry agree to 1e-3 in every metric (round-off-level values "
        "aside); each scenario's details give their largest difference.",
    )
    if len(energy_momentum_rows(df)):
        doc.para("**energy_momentum:** " + ENERGY_MOMENTUM_NOTE, html.escape(ENERGY_MOMENTUM_NOTE))


def wp_cell(entry) -> tuple[str, str]:
    """(Markdown, HTML) of a work-precision answer: configuration, engine and wall time."""
    if entry is None:
        return "none", "none"
    cost = f"{fmt(entry['engine_time_s'])} s engine, {fmt(entry['wall_time_s'])} s wall"
    return (
        f"{md_cell(entry['configuration'])}<br>{cost}",
        f"{html.escape(entry['configuration'])}<br><small>{html.escape(cost)}</small>",
    )


def work_precision_section(doc: Doc, df) -> None:
    levels = ACCURACY_LEVELS
    header = ["scenario", *(f"≤ {fmt_level(lv)} rad" for lv in levels)]
    rows = []
    for scenario in scenarios_of(df):
        wp = work_precision(df[df["scenario"] == scenario], levels)
        row = [scenario_link(scenario)]
        for lv in wp:
            m, h = wp_cell(lv["ranked"][0] if lv["ranked"] else None)
            row.append(Cell(md=m, html_=h))
        rows.append(row)
    text = (
        "The cheapest configuration reaching each max attitude error (fixed steps and "
        "error-controlled runs alike), ranked by the time spent inside the engine's own calls "
        "(`engine_time_s`); the wall time, which includes the suite's glue, is given beside "
        "it. `+ suite` marks a configuration whose time loop is the suite's own Python around "
        "the engine's dynamics: its wall time measures our code, so no ratio here uses it. "
        "An error below the reference's accuracy reaches no level below that accuracy."
        + _finer_sweep_note(df)
    )
    doc.para(text, re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text)))
    doc.table("Cheapest configuration per accuracy", header, rows, cls="wp")


def _finer_sweep_note(df) -> str:
    """The sentence naming the configurations that ran steps below the shared dt sweep."""
    from references.engines import EngineError, get_engine

    finer = []
    for (engine, name), _ in df.groupby(["engine", "integrator"]):
        try:
            n = get_engine(engine).integrator(name).sweep_halvings
        except EngineError:  # no longer registered or offered: its rows still show
            continue
        if n:
            finer.append(f"{engine} {name} ({n} halvings)")
    if not finer:
        return ""
    return (
        " Every configuration ran each scenario's dt sweep; " + ", ".join(finer) + " also "
        "ran halvings of the smallest step (milliseconds of stepping, so that their "
        "curves reach the round-off floor); the others were not run there, where each would "
        "cost more than at its smallest swept step."
    )


def failures_section(doc: Doc, df) -> None:
    fails = failures(df)
    header = [
        "scenario",
        "dt [s]",
        "family",
        "configurations",
        "outcome",
        "t diverged [s]",
        "what failed",
        "engines agree to",
    ]

    def rows_of(items):
        out = []
        for f in items:
            g = f["group"]
            r = g.first
            what = r["verdict_detail"] if r["status"] == "ok" else r["message"]
            if r["status"] == "diverged":
                what = r["message"]
            step = fmt_step(f["dt"])
            if not math.isnan(f["target_accuracy"]):
                step += f" (tol {fmt_level(f['target_accuracy'])})"
            out.append(
                [
                    scenario_link(f["scenario"]),
                    num(None, step),
                    r["family"],
                    g.label,
                    Cell(g.outcome, cls=f"v-{g.outcome}"),
                    num(g.value("t_diverged")),
                    _readable_detail(what),
                    num(None, _agree(g)),
                ]
            )
        return out

    own = [f for f in fails if f["own_dt"]]
    other = [f for f in fails if not f["own_dt"]]
    if not fails:
        doc.para("No run failed its verdict, diverged or errored.")
    if own:
        doc.table("Failures at each scenario's own dt", header, rows_of(own), cls="failures")
    if other:
        doc.open_details(f"Failures at the other steps of the dt sweeps ({len(other)} groups)")
        doc.table("Failures at the other steps of the dt sweeps", header, rows_of(other))
        doc.close_details()
    nr = not_run(df)
    if nr:
        doc.para(
            "Did not run:",
            "Did not run:",
        )
        doc.bullets(
            [
                (
                    f"{md_cell(e['engine'])} {md_cell(e['integrator'])}, {e['status']} on "
                    f"{md_cell(', '.join(e['scenarios']))}: {md_cell(e['message'])}",
                    f"{html.escape(e['engine'])} {html.escape(e['integrator'])}, "
                    f"{html.escape(e['status'])} on {html.escape(', '.join(e['scenarios']))}: "
                    f"{html.escape(e['message'])}",
                )
                for e in nr
            ]
        )


def _readable_detail(text: str) -> str:
    for m, short in METRIC_SHORT.items():
        text = text.replace(m, short)
    return text


def _agree(g) -> str:
    if len(g.rows) < 2:
        return "-"
    return "identical" if g.max_rel_diff == 0 else fmt(g.max_rel_diff)


def metric_columns(rows) -> list[str]:
    """The metrics a scenario's table shows: those with a value in some row; the velocity
    constraint only where the energy-momentum scheme runs (elsewhere it is orthonormality
    times |W|, nothing new)."""
    cols = []
    for m in METRIC_TITLES:
        if m == "constraint_velocity_max" and not len(energy_momentum_rows(rows)):
            continue
        if rows[m].notna().any():
            cols.append(m)
    return cols


def scenario_table(doc: Doc, scenario: str, rows, info) -> None:
    """The groups of a scenario at its own dt with every metric, orders and costs."""
    shown = rows[~rows["status"].isin(NOT_RUN)]
    groups = group_rows(shown)
    mcols = metric_columns(shown)
    header = [
        "family",
        "configurations",
        "verdict",
        *(METRIC_TITLES[m] for m in mcols),
        "fitted order",
        "declared order",
        "engine ns/step",
        "wall ns/step",
        "engines agree to",
    ]
    body = []
    for g in groups:
        fr = g.figure_row()
        cells = [
            g.first["family"],
            ", ".join(config_label(r) for r in g.rows),
            Cell(g.outcome, cls=f"v-{g.outcome}"),
        ]
        for m in mcols:
            cells.append(num(None, fmt_attitude(fr)) if m == "attitude_error_max" else num(fr[m]))
        cells.append(num(None, fmt_order(fr)))
        cells.append(num(None, fmt_int(fr["order"])))
        cells.append(nums(g.cost("engine_ns_per_step")))
        cells.append(nums(g.cost("ns_per_step")))
        cells.append(num(None, _agree(g)))
        body.append(cells)
    doc.table(f"{scenario} at dt = {fmt_step(info['dt'])} s", header, body, cls="details")


def sweep_table(doc: Doc, scenario: str, sub) -> None:
    """Attitude error at every dt of the sweep, with the fitted and declared orders."""
    shown = sub[~sub["status"].isin(NOT_RUN)]
    groups = [g for g in sweep_groups(shown) if len(g.dts) >= 2]
    if not groups:
        return
    dts = sorted({h for g in groups for h in g.dts}, reverse=True)
    header = [
        "family",
        "configurations",
        *(f"dt {fmt_step(h)}" for h in dts),
        "fitted order",
        "declared order",
    ]
    body = []
    for g in groups:
        cells = [g.first["family"], ", ".join(config_label(r) for r in g.members)]
        for h in dts:
            if h not in g.dts:
                cells.append(num(None, "-"))
                continue
            at = g.at(h)
            out = at.outcome
            if out in ("pass", "fail", "ok"):
                cells.append(num(None, fmt_attitude(at.figure_row())))
            elif out == "diverged":
                cells.append(Cell(f"diverged {fmt(at.value('t_diverged'))} s", cls="v-diverged"))
            else:
                cells.append(Cell(out, cls=f"v-{out}"))
        cells.append(num(None, fmt_order(g.first)))
        cells.append(num(None, fmt_int(g.first["order"])))
        body.append(cells)
    doc.table(f"{scenario}: max attitude error [rad] over the dt sweep", header, body)


def wp_table(doc: Doc, scenario: str, sub) -> None:
    wp = work_precision(sub)
    if not any(lv["ranked"] for lv in wp):
        return
    header = [
        "attitude error ≤",
        "cheapest",
        "its error [rad]",
        "engine time [s]",
        "wall time [s]",
        "next cheapest (engine-time ratio)",
    ]
    body = []
    for lv in wp:
        r = lv["ranked"]
        if not r:
            body.append([num(None, fmt_level(lv["level"])), "none of the runs", "", "", "", ""])
            continue
        first = r[0]
        nxt = ", ".join(f"{e['configuration']} x{fmt(e['cost_ratio'])}" for e in r[1:5])
        body.append(
            [
                num(None, fmt_level(lv["level"])),
                first["configuration"],
                num(first["attitude_error_max"]),
                num(first["engine_time_s"]),
                num(first["wall_time_s"]),
                nxt or "-",
            ]
        )
    doc.table(f"{scenario}: cheapest configuration per accuracy", header, body)


def details_section(doc: Doc, df, plots: dict, root: Path) -> None:
    doc.heading(2, "Details")
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        info = scenario_info(sub)
        rows = at_scenario_dt(sub)
        counts = rows[~rows["status"].isin(NOT_RUN)]
        n_pass = int((counts["verdict"] == "pass").sum())
        n_bad = int(((counts["verdict"] == "fail") | (counts["status"] == "error")).sum())
        sid = anchor(scenario)
        summary = (
            f"<h3>{html.escape(scenario)}</h3> <span class='counts'>{n_pass} pass, {n_bad} "
            f"fail or error at dt {fmt_step(info['dt'])} s</span>"
        )
        doc.open_details(summary, id_=sid, md=False)
        doc.md.append(f"### {scenario}\n")
        ref = (
            f"reference: {info['reference_kind']} (accuracy {fmt(info['reference_accuracy'])} rad)"
            if info["reference_kind"]
            else "no exact reference run"
        )
        sweep = ", ".join(fmt_step(h) for h in info["dts"])
        doc.para(
            f"dt = {fmt_step(info['dt'])} s (sweep: {sweep} s), t_end = "
            f"{fmt_step(info['t_end'])} s; {ref}."
        )
        em = energy_momentum_rows(rows)
        if len(em):
            v = em["constraint_velocity_max"].max()
            doc.para(
                f"energy_momentum: its velocity-constraint violation here is "
                f"constraint_velocity_max = {fmt(v)} (the suite's energy drift of this scheme "
                f"is that O(h^2) violation; its own director-form energy is conserved)."
            )
        scenario_table(doc, scenario, rows, info)
        sweep_table(doc, scenario, sub)
        wp_table(doc, scenario, sub)
        doc.images(plots.get(scenario, []), root)
        doc.close_details(md=False)


def settings_section(doc: Doc, df) -> None:
    entries = settings_table(df)
    if not entries:
        return
    all_scen = set(scenarios_of(df))
    rows = []
    for e in entries:
        scen = "all" if set(e["scenarios"]) == all_scen else ", ".join(e["scenarios"])
        rows.append([e["engine"], e["integrator"], e["setting"], "; ".join(e["values"]), scen])
    doc.heading(2, "Settings")
    doc.open_details(f"Settings changed from the engines' defaults ({len(rows)} rows)")
    doc.table(
        "Settings changed from the engines' defaults, every value that ran",
        ["engine", "integrator", "setting", "values", "scenarios"],
        rows,
        cls="settings",
    )
    doc.close_details()


def ensemble_section(doc: Doc, edf, root: Path) -> None:
    from reports.ensemble import summary as ens_summary
    from reports.plots import ensemble_plot

    doc.heading(2, "Ensembles")
    for scenario, g in edf.groupby("scenario"):
        rows = ens_summary(g)
        cols = [c for c in rows[0] if c != "scenario"]
        title = (
            f"{scenario}: ensemble of {g['member'].nunique()} initial conditions "
            "(median, 90th percentile, max)"
        )
        doc.table(title, cols, [[num(r[c]) for c in cols] for r in rows])
        paths = [
            ensemble_plot(g, root / "plots", m) for m in ("attitude_error_max", "energy_drift_max")
        ]
        doc.images([p for p in paths if p], root)


CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;font-size:15px;
 line-height:1.4;margin:0 auto;max-width:1320px;padding:0 16px 48px;color:#1b1b1b}
h1{font-size:1.6em;margin:.6em 0 .2em} h2{margin-top:1.6em;border-bottom:1px solid #ddd}
h3{display:inline;font-size:1.1em;margin:0}
.meta{color:#555;font-size:.92em} nav.toc{background:#f6f8fa;padding:6px 10px;margin:10px 0;
 border-radius:6px;font-size:.95em} nav.toc a{margin-right:.6em;white-space:nowrap}
.scroll{overflow-x:auto;max-width:100%;margin:4px 0 14px}
.title{font-weight:600;margin-top:12px}
table{border-collapse:collapse;font-size:13px}
th{background:#f3f3f3;text-align:left;vertical-align:bottom}
td,th{border:1px solid #d0d7de;padding:3px 7px;vertical-align:top}
td.num{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}
table.scorecard{font-size:12.5px} table.scorecard td{min-width:8em}
table.scorecard td:first-child{min-width:6em}
a.entry{display:block;margin:2px 0;padding:2px 6px;border-left:4px solid #999;
 border-radius:3px;color:inherit;text-decoration:none}
a.entry .who{font-size:.92em} a.entry .fig{white-space:nowrap;font-variant-numeric:tabular-nums}
.v-pass{background:#e6f4ea} a.v-pass{border-left-color:#1e8e3e}
.v-fail{background:#fce8e6} a.v-fail{border-left-color:#d93025}
.v-diverged{background:#f9d6d2} a.v-diverged{border-left-color:#8c1d18}
.v-error{background:#fef7e0} a.v-error{border-left-color:#b06000}
.v-reference-inaccurate{background:#eceff1} a.v-reference-inaccurate{border-left-color:#607d8b}
td.nums{text-align:right;font-variant-numeric:tabular-nums} td.nums span{white-space:nowrap}
span[class^=v-]{padding:0 4px;border-radius:3px}
details{margin:6px 0} details>summary{cursor:pointer;padding:4px 0}
details>summary .counts{color:#555;font-size:.9em;margin-left:.5em}
.plots{display:grid;grid-template-columns:minmax(0,1fr);gap:10px;max-width:900px}
.plots img{width:100%;height:auto;border:1px solid #eee}
"""

#: opens the collapsed section a link points into (the scorecard links to the details)
SCRIPT = """
function openTarget(){var id=decodeURIComponent(location.hash.slice(1));if(!id)return;
var el=document.getElementById(id);var t=el;while(el){if(el.tagName==='DETAILS')el.open=true;
el=el.parentElement;}if(t)t.scrollIntoView();}
window.addEventListener('hashchange',openTarget);
document.addEventListener('DOMContentLoaded',openTarget);
"""


def _toc(df, has_settings: bool, has_ensemble: bool) -> tuple[str, str]:
    entries = []
    if len(df):
        entries += [("Scorecard", "scorecard"), ("Work precision", "work-precision")]
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


def document(df, prov: dict, plots: dict, root: Path, edf=None) -> tuple[str, str]:
    """(report.md, report.html) of a results table."""
    doc = Doc()
    doc.md.append("# director-bench report\n")
    doc.html.append("<h1 id='director-bench-report'>director-bench report</h1>")
    doc.para(
        f"{provenance_line(prov)}. {count_line(df)}",
        f"<span class='meta'>{html.escape(provenance_line(prov))}.</span> "
        f"<b>{html.escape(count_line(df))}</b>",
    )
    has_settings = bool(len(df)) and bool(settings_table(df))
    toc_md, toc_html = _toc(df if len(df) else df, has_settings, edf is not None)
    doc.md.append(toc_md + "\n")
    doc.html.append(toc_html)
    if len(df):
        card = scorecard(df)
        doc.heading(2, "Scorecard")
        scorecard_section(doc, df, card)
        doc.heading(2, "Work precision")
        work_precision_section(doc, df)
        doc.heading(2, "Failures and divergences")
        failures_section(doc, df)
        details_section(doc, df, plots, root)
    if edf is not None:
        ensemble_section(doc, edf, root)
    if has_settings:
        settings_section(doc, df)
    doc.heading(2, "Provenance")
    if prov:
        doc.table("Provenance of the runs", ["item", "value"], provenance_rows(prov))
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


def step_summary(df) -> str:
    """The scorecard as Markdown for a CI job summary (no links: the details are elsewhere)."""
    doc = Doc()
    doc.md.append("## director-bench scorecard\n")
    doc.para(count_line(df))
    if len(df):
        scorecard_section(doc, df, scorecard(df), links=False)
    return "\n".join(doc.md)


def build_report(root: str | Path, progress: bool = False) -> dict[str, Path]:
    """Write the figures, report.md, report.html and summary.json for the results folder
    ``root``; with ``GITHUB_STEP_SUMMARY`` set, append the scorecard to that file.
    ``progress``: a progress bar while figures are drawn (figures whose inputs did not
    change since the last report are reused, reports.plots)."""
    from reports.ensemble import read_ensemble
    from reports.plots import all_plots
    from reports.results import STORE_NAME, frame, read_results

    root = Path(root)
    edf = read_ensemble(root)
    if (root / STORE_NAME).exists() or edf is None:
        df = read_results(root)
    else:  # a folder holding only an ensemble
        df = frame([])
    prov = read_provenance(root)
    plots = all_plots(df, root, progress=progress)
    md, page = document(df, prov, plots, root, edf)
    _write(root / "report.md", md)
    _write(root / "report.html", page)
    summary_path = write_summary(root, df, prov)
    target = os.environ.get("GITHUB_STEP_SUMMARY")
    if target:
        with open(target, "a", encoding="utf-8") as fh:
            fh.write(step_summary(df) + "\n")
    return {
        "markdown": root / "report.md",
        "html": root / "report.html",
        "plots": root / "plots",
        "summary": summary_path,
    }


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
