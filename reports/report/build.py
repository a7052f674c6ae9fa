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

import base64
import contextlib
import html
import json
import math
import os
import re
from pathlib import Path

from reports.metrics import catalog
from reports.report.canvas import SeriesCache, figure_meta
from reports.report.contact import contact_rows, contact_section
from reports.report.groups import group_rows, sweep_groups
from reports.report.importers import importer_section
from reports.report.labels import (
    METRIC_SHORT,
    NOT_RUN,
    config_label,
    engine_key,
    failed_metrics,
    family_key,
    fmt_attitude,
    fmt_order,
)
from reports.report.plots import rates_left_out
from reports.report.summary_json import write_summary
from reports.report.tables import (
    ACCURACY_LEVELS,
    ENERGY_MOMENTUM_NOTE,
    at_scenario_dt,
    closure_settings,
    energy_momentum_rows,
    failures,
    not_run,
    scenario_info,
    scenarios_of,
    scorecard,
    settings_table,
    work_precision,
)
from reports.run.importers import read_table
from reports.store.atomic import write_text
from reports.store.format import fmt, fmt_int, fmt_level, fmt_step, md_cell
from reports.store.provenance import read_provenance
from reports.store.results import STATUSES, records, reference_rows

#: column titles of the metrics, with units (no character GitHub's tables would split on), in
#: the order shown: the metric catalog's (:data:`reports.metrics.catalog.METRIC_TITLES`)
METRIC_TITLES = catalog.METRIC_TITLES

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
        html_=f"<a href='#{a}'>{html.escape(scenario).replace('_', '_<wbr>')}</a>",
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


def order_cell(text: str) -> Cell:
    """A fitted order with its points (``2.00 (3 pts)``): a number that may wrap before its
    count, so that it does not widen a table of many columns."""
    parts = text.split(" ", 1)
    return Cell(text, html_=" ".join(f"<span>{html.escape(t)}</span>" for t in parts), cls="nums")


class Doc:
    """Markdown and HTML written side by side."""

    def __init__(self):
        self.md: list[str] = []
        self.html: list[str] = []

    def heading(self, level: int, text: str, id_: str | None = None) -> None:
        id_ = id_ or anchor(text)
        self.md.append(f"{'#' * level} {text}\n")
        self.html.append(f"<h{level} id='{html.escape(id_)}'>{html.escape(text)}</h{level}>")

    def para(self, md: str, html_: str | None = None, cls: str = "") -> None:
        self.md.append(md + "\n")
        attr = f" class='{cls}'" if cls else ""
        self.html.append(f"<p{attr}>{html_ if html_ is not None else html.escape(md)}</p>")

    def bullets(self, items: list[tuple[str, str]]) -> None:
        """Items as (Markdown, HTML)."""
        self.md.append("\n".join(f"- {m}" for m, _ in items) + "\n")
        self.html.append("<ul>" + "".join(f"<li>{h}</li>" for _, h in items) + "</ul>")

    def table(self, title: str, header: list, rows: list[list], cls: str = "") -> None:
        """A table with its one-line title; header entries and cells are text or
        :class:`Cell`. In HTML inside a container that scrolls should the table be wider than
        the page; a table of class ``stack`` turns into one card per row on a narrow screen
        (below 1000 px, :data:`CARDS`), each cell labelled with its column (``data-label``);
        so does every table of more than seven columns; one of class ``narrow-stack`` only
        below 640 px."""
        heads = [h if isinstance(h, Cell) else Cell(h) for h in header]
        if len(heads) > 7 and "stack" not in cls.split():
            cls = f"{cls} stack".strip()
        cells = [[c if isinstance(c, Cell) else Cell(c) for c in r] for r in rows]
        md = [f"**{md_cell(title)}**", ""] if title else []
        md.append("| " + " | ".join(h.to_md() for h in heads) + " |")
        # a column of numbers right-aligned, as in HTML
        right = [
            bool(cells) and all(r[k].num for r in cells if k < len(r)) for k in range(len(heads))
        ]
        md.append("|" + "|".join("--:" if a else "---" for a in right) + "|")
        md += ["| " + " | ".join(c.to_md() for c in r) + " |" for r in cells]
        self.md.append("\n".join(md) + "\n")
        head = "".join(f"<th>{h.to_html()}</th>" for h in heads)
        labels = [html.escape(h.text, quote=True) for h in heads]
        body = []
        for r in cells:
            tds = []
            for k, c in enumerate(r):
                classes = " ".join(x for x in ("num" if c.num else "", c.cls) if x)
                attr = f" class='{classes}'" if classes else ""
                if k < len(labels):
                    attr += f" data-label='{labels[k]}'"
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

    def images(
        self, paths: list[Path], root: Path, cls: str = "plots", md: bool = True, alts=None
    ) -> None:
        """Figures: in Markdown as links to the files, in HTML embedded (base64), each with
        its alt text and, where :func:`reports.report.canvas.figure_meta` has them, the lines a
        pointer over the figure names (``data-lines``, read by :data:`SCRIPT`)."""
        if not paths:
            return
        if md:
            for p in paths:
                alt = (alts or {}).get(p) or figure_meta(p).get("alt") or p.stem
                self.md.append(f"![{_md_alt(alt)}]({p.relative_to(root).as_posix()})\n")
        figs = "".join(figure_html(p, (alts or {}).get(p, "")) for p in paths)
        self.html.append(f"<div class='{cls}'>{figs}</div>")

    def raw_html(self, text: str) -> None:
        self.html.append(text)

    def md_details(self, summary: str) -> None:
        """A collapsible section of report.md only (GitHub renders ``<details>``): the
        HTML report shows the same part open, or collapses it its own way."""
        self.md.append(f"<details><summary>{html.escape(summary)}</summary>\n")

    def md_end(self) -> None:
        self.md.append("</details>\n")

    @contextlib.contextmanager
    def only(self, side: str):
        """Write what the block writes to one side only: ``md`` (report.md) or ``html``."""
        keep_md, keep_html = len(self.md), len(self.html)
        yield self
        if side == "md":
            del self.html[keep_html:]
        else:
            del self.md[keep_md:]


def figure_html(p: Path, alt: str = "") -> str:
    """A figure embedded in the page: the PNG as a data URI, its alt text (``alt``, or the
    one written beside the figure), its hover lines."""
    meta = figure_meta(p)
    alt = alt or meta.get("alt") or p.stem.replace("__", ": ").replace("_", " ")
    data = base64.b64encode(p.read_bytes()).decode()
    lines = meta.get("lines") or []
    hover = ""
    if lines:
        hover = f" data-lines='{html.escape(json.dumps(lines, separators=(',', ':')), quote=True)}'"
    kind = p.stem.rsplit("__", 1)[-1]
    return (
        f"<figure class='fig k-{html.escape(kind)}'{hover}>"
        f"<img alt='{html.escape(alt, quote=True)}' loading='eager' "
        f"src='data:image/png;base64,{data}'><span class='tip' hidden></span></figure>"
    )


def _md_alt(text: str) -> str:
    """Alt text safe inside Markdown's ``![...]``."""
    return " ".join(str(text).split()).replace("[", "(").replace("]", ")")


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
    rows += [
        [f"engine {e}", f"not in the default suite here: {why} (--engines all adds it)"]
        for e, why in (prov.get("left_out", {}) or {}).items()
    ]
    if prov.get("note"):
        rows.append(["note", str(prov["note"])])
    return rows


def fmt_cost(ns) -> str:
    """The time inside the engine per step, ``11.0 µs`` (``-`` when unknown)."""
    from reports.report.scorecard_plot import fmt_cost as _fmt_cost

    return _fmt_cost(ns)


def entry_texts(g) -> tuple[str, list[tuple[str, str]], list[str], str]:
    """(outcome, members, figures, failing) of a scorecard entry: members as (configuration,
    its time inside the engine per step), every configuration named in full (engine and
    integrator); figures: short pieces, each kept on one line; failing: the metrics out of
    bounds (empty unless the verdict is fail)."""
    who = [(config_label(r), fmt_cost(r.get("engine_ns_per_step"))) for r in g.rows]
    fr = g.figure_row()
    out = g.outcome
    if out == "diverged":
        return out, who, [f"diverged at t = {fmt(fr['t_diverged'])} s"], ""
    if out == "error":
        return out, who, ["error"], ""
    if out == "reference-inaccurate":
        return out, who, ["reference too coarse to judge"], ""
    figs = [f"{fmt_attitude(fr)} rad", f"E {fmt(fr['energy_drift_max'])}"]
    failing = ""
    if out == "fail":
        names = [METRIC_SHORT.get(m, m) for m in failed_metrics(g.first["verdict_detail"])]
        failing = ", ".join(names)
    return out, who, figs, failing


#: what the figures of a scorecard entry are (the legend above the scorecard, the tooltips)
SCORECARD_TERMS = {
    "rad": "the max attitude error over the run (< x: below the reference's accuracy x, not "
    "a measurement)",
    "E": "the max energy drift relative to the scenario's energy scale",
    "µs": "the time inside the engine's own calls per step, the cost beside the verdict "
    "(the suite's glue left out; + suite: the suite's time loop around the engine's "
    "dynamics, whose own time is this figure)",
}


def scorecard_legend(doc: Doc) -> None:
    """The key to the scorecard, above it."""
    md = (
        "✅ pass · ❌ fail (the metrics out of bounds after *fails*) · 💥 diverged · ⚠️ error "
        "· ❔ the reference is not accurate enough to judge. Each entry: the verdict, "
        f"**rad**: {SCORECARD_TERMS['rad']}, **E**: {SCORECARD_TERMS['E']}, "
        f"then each configuration with **µs**: {SCORECARD_TERMS['µs']}. Configurations in one "
        "entry agree to 1e-3 in every metric (round-off-level values aside); each scenario's "
        "details give their largest difference."
    )
    h = (
        "<span class='v-pass'>✓ pass</span> <span class='v-fail'>✗ fail</span> "
        "<span class='v-diverged'>↯ diverged</span> <span class='v-error'>⚠ error</span> "
        "<span class='v-reference-inaccurate'>? reference too coarse to judge</span>. "
        "Each entry: the verdict, <b>rad</b>: "
        f"{html.escape(SCORECARD_TERMS['rad'])}, <b>E</b>: {html.escape(SCORECARD_TERMS['E'])}"
        "; the metrics out of bounds after <b>fails</b>; then each configuration with "
        f"<b>µs</b>: {html.escape(SCORECARD_TERMS['µs'])}. Configurations in one entry agree "
        "to 1e-3 in every metric (round-off-level values aside); each scenario's details give "
        "their largest difference."
    )
    doc.para(md, h, cls="legend")


def _entry_html(out: str, who, figs, failing: str, href: str) -> str:
    spans = []
    for f in figs:
        if f.startswith("E "):
            abbr = f"<abbr title='{html.escape(SCORECARD_TERMS['E'])}'>E</abbr>"
            spans.append(f"<span class='fig'>{abbr} {html.escape(f[2:])}</span>")
        else:
            wrap = " wrap" if f.startswith(("diverged", "reference")) else ""
            spans.append(f"<span class='fig{wrap}'>{html.escape(f)}</span>")
    fails = f"<span class='fails'>fails: {html.escape(failing)}</span>" if failing else ""
    members = "".join(
        f"<li>{html.escape(name)} <span class='cost' title='time inside the engine per step'>"
        f"{html.escape(cost)}</span></li>"
        for name, cost in who
    )
    return (
        f"<a class='entry v-{out}'{href}><span class='head'><b>{MARK.get(out, '')}</b> "
        f"{' · '.join(spans)}</span>{fails}<ul class='who'>{members}</ul></a>"
    )


def _family_tip(family: str) -> str:
    """The tooltip of a scorecard column: what its entries show."""
    return (
        f"integrator family {family}. Each entry: the verdict; rad: "
        f"{SCORECARD_TERMS['rad']}; E: {SCORECARD_TERMS['E']}; then each configuration "
        f"with µs: {SCORECARD_TERMS['µs']}"
    )


def scorecard_section(doc: Doc, df, card, links: bool = True) -> None:
    fams = sorted({f for s in card for f in s["cells"]}, key=family_key)
    header = [
        Cell(
            "scenario",
            html_="<span title='each scenario at its own dt and horizon'>scenario</span>",
        ),
        *(
            Cell(f, html_=f"<span title='{html.escape(_family_tip(f), quote=True)}'>"
                 f"{html.escape(f)}</span>")
            for f in fams
        ),
    ]  # fmt: skip
    rows = []
    for s in card:
        sid = anchor(s["scenario"])
        where = f"dt {fmt_step(s['dt'])} s, {fmt_step(s['t_end'])} s"
        name_md = f"[{md_cell(s['scenario'])}](#{sid})" if links else md_cell(s["scenario"])
        row = [
            Cell(
                md=f"{name_md}<br>{where}",
                html_=f"<a href='#{sid}'>{html.escape(s['scenario']).replace('_', '_<wbr>')}"
                f"</a><br><small>{html.escape(where)}</small>",
            )
        ]
        for fam in fams:
            md_parts, html_parts = [], []
            for g in s["cells"].get(fam, []):
                out, who, figs, failing = entry_texts(g)
                text = " · ".join(figs) + (f" · fails: {failing}" if failing else "")
                members = ", ".join(f"{name} ({cost})" for name, cost in who)
                md_parts.append(f"{SYMBOL.get(out, '')} {md_cell(text)} — {md_cell(members)}")
                href = f" href='#{sid}'" if links else ""
                html_parts.append(_entry_html(out, who, figs, failing, href))
            row.append(Cell(md="<br>".join(md_parts) or "-", html_="".join(html_parts) or "-"))
        rows.append(row)
    scorecard_legend(doc)
    doc.table("Verdicts at each scenario's own dt", header, rows, cls="scorecard stack")
    if len(energy_momentum_rows(df)):
        doc.para("**energy_momentum:** " + ENERGY_MOMENTUM_NOTE, html.escape(ENERGY_MOMENTUM_NOTE))


def verdict_section(doc: Doc, df, card, links: bool = True) -> None:
    """The verdict first (reports.report.verdict): per scenario, its configurations by
    outcome at its own step, and the totals; six columns of short cells."""
    from reports.report.verdict import COLUMNS, LEGEND, totals, verdict_rows

    rows = verdict_rows(df, card)
    body = []
    for r in rows:
        name = scenario_link(r["scenario"]) if links else Cell(r["scenario"])
        cells = [name]
        for c in COLUMNS:
            cls = {"pass": "v-pass", "fail": "v-fail", "diverged": "v-diverged"}.get(c, "")
            cells.append(Cell(str(r[c]) if r[c] else "·", num=True, cls=cls if r[c] else ""))
        body.append(cells)
    tot = totals(rows)
    body.append(
        [Cell(f"all {len(rows)}", md=f"**all {len(rows)}**", html_=f"<b>all {len(rows)}</b>")]
        + [Cell(str(tot[c]), md=f"**{tot[c]}**", num=True) for c in COLUMNS]
    )
    doc.table(
        "Configurations by verdict at each scenario's own step (the other steps of each dt "
        "sweep: in its section)", ["scenario", *COLUMNS], body, cls="verdict",
    )  # fmt: skip
    doc.para(LEGEND, re.sub(r"\*([^*]+)\*", r"<i>\1</i>", html.escape(LEGEND)), cls="hint")


def scenario_verdicts(doc: Doc, s: dict) -> None:
    """report.md's scorecard of one scenario (``s``, an entry of
    :func:`reports.report.tables.scorecard`): a row per group of configurations that agree,
    six columns (the HTML report has the scorecard of every scenario instead)."""
    header = ["family", "configurations", "verdict", "attitude [rad]", "energy", "engine µs/step"]
    body = []
    for fam in sorted(s["cells"], key=family_key):
        for g in s["cells"][fam]:
            out, who, figs, failing = entry_texts(g)
            verdict = f"{SYMBOL.get(out, '')} {out}" + (f": {failing}" if failing else "")
            if out in ("pass", "fail"):
                fr = g.figure_row()
                att, energy = fmt_attitude(fr), fmt(fr["energy_drift_max"])
            else:
                verdict += figs[0].removeprefix("diverged") if out == "diverged" else ""
                att = energy = "-"
            body.append(
                [
                    fam,
                    Cell(md="<br>".join(md_cell(n) for n, _ in who)),
                    verdict,
                    num(None, att),
                    num(None, energy),
                    Cell(md="<br>".join(md_cell(c.removesuffix(" µs")) for _, c in who), num=True),
                ]
            )
    where = f"dt = {fmt_step(s['dt'])} s, t_end = {fmt_step(s['t_end'])} s"
    doc.table(f"{s['scenario']}: verdicts at {where}", header, body)


def scorecard_picture(doc: Doc, paths: list[Path], root: Path, df) -> None:
    """The scorecard as one picture, with where its files are (to paste into a README or a
    pull request)."""
    png = [p for p in paths if p.suffix == ".png" and p.exists()]
    if not png:
        return
    runs = df[~reference_rows(df)]
    card_alt = (
        f"Scorecard: {runs.groupby(['engine', 'integrator']).ngroups} configurations (rows) "
        f"on {runs['scenario'].nunique()} scenarios (columns), each cell coloured by its "
        "verdict (green pass, pink fail, red diverged, grey not run) with the max attitude "
        "error, the time inside the engine per step and the failing metrics."
    )
    names = " and ".join(f"`{p.relative_to(root).as_posix()}`" for p in paths)
    doc.open_details("The scorecard as one picture, for a README or a pull request")
    text = (
        f"{names} in this folder; the table below has every configuration's figures, each "
        "scenario's section below its tables and figures."
    )
    doc.para(text, re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text)), cls="hint")
    doc.images(png, root, cls="plots card", alts={png[0]: card_alt})
    doc.close_details()


def wp_cell(entry, winner: bool) -> tuple[str, str]:
    """(Markdown, HTML) of one engine's answer at one accuracy: its cheapest configuration
    (the engine named in the row), the time inside the engine and the ratio to the cheapest
    of all engines (the overall winner in bold)."""
    if entry is None:
        return "-", "<span class='none'>-</span>"
    conf = entry["configuration"][len(entry["engine"]) :].strip()
    # semi_explicit_euler may break at its underscores, "dt 0.002 s" nowhere
    conf_html = re.sub(r"dt (\S+) s$", "dt&nbsp;\\1&nbsp;s", html.escape(conf)).replace(
        "_", "_<wbr>"
    )
    ratio = "cheapest" if winner else f"x{fmt(entry['cost_ratio'])}"
    cost = f"{fmt(entry['engine_time_s'])} s, {ratio}"
    if winner:
        return (
            f"**{md_cell(conf)}**<br>{cost}",
            f"<b>{conf_html}</b><br><small class='win'>{html.escape(cost)}</small>",
        )
    return (
        f"{md_cell(conf)}<br>{cost}",
        f"{conf_html}<br><small>{html.escape(cost)}</small>",
    )


def work_precision_section(doc: Doc, df) -> None:
    """Per scenario and engine, the cheapest configuration of that engine reaching each level
    of max attitude error, with its time inside the engine and its ratio to the cheapest of
    all engines."""
    levels = ACCURACY_LEVELS
    header = ["scenario", "engine", *(f"≤ {fmt_level(lv)} rad" for lv in levels)]
    rows = []
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        wp = work_precision(sub, levels)
        engines = sorted(
            set(sub.loc[(sub["status"] == "ok") & ~reference_rows(sub), "engine"]),
            key=engine_key,
        )
        for k, eng in enumerate(engines):
            row = [scenario_link(scenario) if k == 0 else Cell(""), Cell(eng)]
            for lv in wp:
                mine = [e for e in lv["ranked"] if e["engine"] == eng]
                winner = bool(mine) and lv["ranked"][0] is mine[0]
                m, h = wp_cell(mine[0] if mine else None, winner)
                row.append(Cell(md=m, html_=h, cls="win" if winner else ""))
            rows.append(row)
    text = (
        "For each engine, its cheapest configuration reaching each max attitude error (fixed "
        "steps and error-controlled runs alike), with the time spent inside the engine's own "
        "calls (`engine_time_s`) and its ratio to the cheapest of all engines (in bold, "
        "`cheapest`); `-`: no configuration of that engine reaches the level. `+ suite` "
        "marks a configuration whose time loop is the suite's own Python around the engine's "
        "dynamics: its wall time measures our code, so no ratio here uses it. An error below "
        "the reference's accuracy reaches no level below that accuracy. For a system of "
        "bodies the attitude error is the largest over its bodies." + _finer_sweep_note(df)
    )
    doc.para(text, re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text)))
    # seven columns of configurations and times (names break at underscores) fit 800 px;
    # cards on a narrower screen
    doc.table(
        "Cheapest configuration of each engine per accuracy", header, rows, cls="wp narrow-stack"
    )


def _finer_sweep_note(df) -> str:
    """The sentence naming the configurations that ran steps below the shared dt sweep, read
    from the rows: a scenario's sweep ends at the smallest step most of its configurations
    ran, and a configuration's halvings are its distinct steps below that."""
    finer = []
    halvings: dict[tuple[str, str], int] = {}
    for _, sc in df.groupby("scenario"):
        smallest = sc.groupby(["engine", "integrator"])["dt"].min()
        if smallest.empty:
            continue
        sweep_end = smallest.mode().max()
        for key, g in sc.groupby(["engine", "integrator"]):
            n = int((g["dt"].drop_duplicates() < sweep_end * (1 - 1e-9)).sum())
            halvings[key] = max(halvings.get(key, 0), n)
    for (engine, name), n in sorted(halvings.items()):
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
    # five columns (the step under the scenario, the time of divergence in the outcome), so
    # that the table reads on GitHub and on a narrow screen
    header = ["scenario, step [s]", "configurations", "outcome", "what failed", "engines agree to"]

    def rows_of(items):
        out = []
        for f in items:
            g = f["group"]
            r = g.first
            what = r["verdict_detail"] if r["status"] == "ok" else r["message"]
            step = fmt_step(f["dt"])
            if not math.isnan(f["target_accuracy"]):
                step += f" (tol {fmt_level(f['target_accuracy'])})"
            a = anchor(f["scenario"])
            name = html.escape(f["scenario"]).replace("_", "_<wbr>")
            outcome = g.outcome
            if outcome == "diverged":
                outcome += f" at t = {fmt(g.value('t_diverged'))} s"
            out.append(
                [
                    Cell(
                        md=f"[{md_cell(f['scenario'])}](#{a})<br>dt {step}",
                        html_=f"<a href='#{a}'>{name}</a><br><small>dt {html.escape(step)}</small>",
                    ),
                    g.label,
                    Cell(outcome, cls=f"v-{g.outcome}"),
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
    """A verdict detail with the metrics' short names (whole names only: a metric whose name
    ends with another's, e.g. ``x_momentum_drift_max``, keeps its own)."""
    names = "|".join(re.escape(m) for m in METRIC_SHORT)
    return re.sub(rf"\b({names})\b", lambda k: METRIC_SHORT[k.group(1)], text)


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
    knobs = any(closure_settings(r) for r in records(shown))
    header = [
        "family",
        "configurations",
        "verdict",
        *(["loop closure settings"] if knobs else []),
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
        if knobs:  # the settings that shaped the loop closure, per member when they differ
            vals = list(dict.fromkeys(closure_settings(r) for r in g.rows))
            cells.append("; ".join(v or "-" for v in vals) if any(vals) else "-")
        for m in mcols:
            cells.append(num(None, fmt_attitude(fr)) if m == "attitude_error_max" else num(fr[m]))
        cells.append(order_cell(fmt_order(fr)))
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
        cells.append(order_cell(fmt_order(g.first)))
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
                num(None, fmt_attitude(first)),
                num(first["engine_time_s"]),
                num(first["wall_time_s"]),
                nxt or "-",
            ]
        )
    doc.table(f"{scenario}: cheapest configuration per accuracy", header, body)


#: the figures of a scenario shown without a click (the others are in its collapsed part)
KEY_FIGURES = ("scenario", "system", "joint_angles", "importers", "errors", "work_precision")


def _kind(p: Path) -> str:
    return p.stem.rsplit("__", 1)[-1]


def details_section(doc: Doc, df, plots: dict, root: Path, card=None) -> None:
    """Per scenario: its facts and key figures in view (:data:`KEY_FIGURES`), then, collapsed
    in HTML, its tables and the other figures; in report.md the whole of it collapsed under
    its heading, its verdicts first (:func:`scenario_verdicts`)."""
    doc.heading(2, "Details")
    cache = SeriesCache(root)
    from reports.report.verdict import COLUMNS, verdict_rows

    card = card or scorecard(df)
    by_name = {s["scenario"]: s for s in card}
    verdicts = {r["scenario"]: {c: r[c] for c in COLUMNS} for r in verdict_rows(df, card)}
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        info = scenario_info(sub)
        rows = at_scenario_dt(sub)
        counts = ", ".join(f"{n} {c}" for c, n in verdicts[scenario].items() if n)
        where = f"dt {fmt_step(info['dt'])} s, t_end {fmt_step(info['t_end'])} s"
        sid = anchor(scenario)
        doc.raw_html(
            f"<section class='scenario' id='{html.escape(sid)}'><h3>{html.escape(scenario)}</h3>"
            f" <span class='counts'>{html.escape(counts)} at {where}</span>"
        )
        doc.md.append(f"### {scenario}\n")
        doc.md_details(
            f"{counts} at {where}: the verdict of each configuration, figures, the dt sweep, "
            "the cheapest configuration per accuracy"
        )
        with doc.only("md"):
            scenario_verdicts(doc, by_name[scenario])
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
        figs = plots.get(scenario, [])
        key = [p for k in KEY_FIGURES for p in figs if _kind(p) == k]
        rest = [p for p in figs if p not in key]
        doc.images(key, root, cls="plots key")
        if key:
            doc.raw_html(
                "<p class='hint'>Point at a line in a figure to see which configuration it is.</p>"
            )
        table = read_table(root, scenario)  # a robot model: each engine's importer
        if table is not None:
            importer_section(doc, table, Cell)
        doc.open_details(
            f"Tables and more figures of {html.escape(scenario)}: the verdicts at its dt, the "
            "dt sweep, the cheapest configuration per accuracy"
            + (", " + ", ".join(_kind(p).replace("_", " ") for p in rest) if rest else ""),
            md=False,
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
        if not any(_kind(p) == "rates" for p in figs):  # said instead of an empty figure
            note = rates_left_out(df, cache, scenario)
            if note:
                doc.para(note)
        doc.images(rest, root)
        doc.close_details(md=False)
        doc.md_end()
        doc.raw_html("</section>")


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
        cls="settings narrow-stack",  # values wrap anywhere: a table down to 640 px
    )
    doc.close_details()


def ensemble_section(doc: Doc, edf, root: Path) -> None:
    from reports.report.scorecard_plot import ensemble_plot
    from reports.store.ensemble import summary as ens_summary

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
h3{display:inline;font-size:1.15em;margin:0}
section.scenario{margin:18px 0 10px;padding-top:6px;border-top:1px solid #eee}
section.scenario .counts{color:#555;font-size:.9em;margin-left:.5em}
.meta{color:#555;font-size:.92em} nav.toc{background:#f6f8fa;padding:6px 10px;margin:10px 0;
 border-radius:6px;font-size:.95em} nav.toc a{margin-right:.6em;white-space:nowrap}
.scroll{overflow-x:auto;max-width:100%;margin:4px 0 14px}
.title{font-weight:600;margin-top:12px}
p.legend,p.hint{font-size:.9em;color:#333} p.legend{background:#f6f8fa;padding:6px 10px;
 border-radius:6px} p.hint{color:#666;margin:2px 0}
table{border-collapse:collapse;font-size:13px}
th{background:#f3f3f3;text-align:left;vertical-align:bottom}
td,th{border:1px solid #d0d7de;padding:3px 7px;vertical-align:top}
td.num{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}
table.settings td{overflow-wrap:anywhere}
table.details{font-size:12.5px} table.details td,table.details th{padding:3px 5px}
table.scorecard{font-size:12.5px;width:100%;table-layout:fixed}
table.scorecard th:first-child{width:9.5em}
table.scorecard td{overflow-wrap:break-word} a.entry .fig.wrap{white-space:normal}
a.entry{display:block;margin:2px 0 4px;padding:2px 6px;border-left:4px solid #999;
 border-radius:3px;color:inherit;text-decoration:none}
a.entry .head{display:block} a.entry .fig{white-space:nowrap;font-variant-numeric:tabular-nums}
a.entry .fails{display:block;color:#a50e0e;font-weight:600;font-size:.92em}
a.entry ul.who{list-style:none;margin:1px 0 0;padding:0;font-size:.9em}
a.entry .cost{color:#444;white-space:nowrap;font-variant-numeric:tabular-nums}
abbr{text-decoration:underline dotted;cursor:help}
.v-pass{background:#e6f4ea} a.v-pass{border-left-color:#1e8e3e}
.v-fail{background:#fce8e6} a.v-fail{border-left-color:#d93025}
.v-diverged{background:#f9d6d2} a.v-diverged{border-left-color:#8c1d18}
.v-error{background:#fef7e0} a.v-error{border-left-color:#b06000}
.v-reference-inaccurate{background:#eceff1} a.v-reference-inaccurate{border-left-color:#607d8b}
td.win{background:#eef6ee} small.win{font-weight:600}
table.verdict{font-size:14px} table.verdict td.num{min-width:3.2em}
table.verdict tr:last-child td{border-top:2px solid #8c959f}
td.nums{text-align:right;font-variant-numeric:tabular-nums} td.nums span{white-space:nowrap}
span[class^=v-]{padding:0 4px;border-radius:3px}
details{margin:6px 0} details>summary{cursor:pointer;padding:4px 0;color:#0b57d0}
.plots{display:flex;flex-wrap:wrap;gap:10px;align-items:flex-start;margin:6px 0}
figure.fig{margin:0;position:relative;flex:1 1 520px;max-width:100%}
figure.fig.k-scenario,figure.fig.k-scorecard{flex-basis:100%}
figure.fig img{display:block;max-width:100%;height:auto;border:1px solid #eee}
figure.fig .tip{position:absolute;pointer-events:none;background:#1b1b1b;color:#fff;
 font-size:12px;padding:2px 6px;border-radius:3px;white-space:nowrap;z-index:5}
figure.fig figcaption{font-size:.88em;color:#555}
"""

#: a table of class ``stack`` becomes one card per row, each cell labelled with its column,
#: below 1000 px; one of class ``narrow-stack`` (few columns that wrap) only below 640 px
CARDS = """@media (max-width:WIDTHpx){
 table.CLS,table.CLS tbody,table.CLS tr,table.CLS td{display:block;width:auto}
 table.CLS{border:none} table.CLS thead{display:none}
 table.CLS tr{border:1px solid #d0d7de;border-radius:4px;margin:0 0 8px}
 table.CLS td{border:none;border-bottom:1px solid #eee;text-align:left;white-space:normal;
  min-width:0}
 table.CLS td:empty{display:none}
 table.CLS td::before{content:attr(data-label);display:block;font-size:11px;color:#555;
  font-weight:600}
}
"""
CSS += "".join(
    CARDS.replace("WIDTH", str(w)).replace("CLS", c)
    for c, w in (("stack", 1000), ("narrow-stack", 640))
)

#: opens the collapsed section a link points into (the scorecard links to the details), and
#: names the line under the pointer in a figure (its polylines are the figure's data-lines)
SCRIPT = """
function openTarget(){var id=decodeURIComponent(location.hash.slice(1));if(!id)return;
var el=document.getElementById(id);var t=el;while(el){if(el.tagName==='DETAILS')el.open=true;
el=el.parentElement;}if(t)t.scrollIntoView();}
function segDist(px,py,ax,ay,bx,by){var dx=bx-ax,dy=by-ay,l=dx*dx+dy*dy,u=0;
if(l>0){u=((px-ax)*dx+(py-ay)*dy)/l;u=Math.max(0,Math.min(1,u));}
var x=ax+u*dx-px,y=ay+u*dy-py;return Math.sqrt(x*x+y*y);}
function hover(fig){var lines=JSON.parse(fig.getAttribute('data-lines'));
var img=fig.querySelector('img'),tip=fig.querySelector('.tip');
img.addEventListener('mousemove',function(e){var r=img.getBoundingClientRect();
var px=e.clientX-r.left,py=e.clientY-r.top,best='',bd=1e9;
lines.forEach(function(l){l.paths.forEach(function(p){for(var i=0;i<p.length;i++){
var a=p[i],b=p[Math.min(i+1,p.length-1)];var d=segDist(px,py,a[0]*r.width,a[1]*r.height,
b[0]*r.width,b[1]*r.height);if(d<bd){bd=d;best=l.label;}}});});
if(best&&bd<7){tip.textContent=best;tip.hidden=false;var left=px+14;
if(left+tip.offsetWidth>r.width)left=Math.max(0,px-14-tip.offsetWidth);
tip.style.left=left+'px';tip.style.top=(py+12)+'px';}else{tip.hidden=true;}});
img.addEventListener('mouseleave',function(){tip.hidden=true;});}
window.addEventListener('hashchange',openTarget);
document.addEventListener('DOMContentLoaded',function(){
document.querySelectorAll('figure[data-lines]').forEach(hover);openTarget();});
"""


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


def build_report(root: str | Path, progress: bool = False) -> dict[str, Path]:
    """Write the figures, report.md, report.html and summary.json for the results folder
    ``root``; with ``GITHUB_STEP_SUMMARY`` set, append the scorecard to that file.
    ``progress``: a progress bar while figures are drawn (figures whose inputs did not
    change since the last report are reused, reports.report.figures)."""
    from reports.report.figures import report_figures
    from reports.store.ensemble import read_ensemble
    from reports.store.results import STORE_NAME, frame, read_results

    root = Path(root)
    edf = read_ensemble(root)
    if (root / STORE_NAME).exists() or edf is None:
        df = read_results(root)
    else:  # a folder holding only an ensemble
        df = frame([])
    df = python_strings(df)
    prov = read_provenance(root)
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
