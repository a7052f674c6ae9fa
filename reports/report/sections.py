"""The sections of the report (:mod:`reports.report.build` puts them in order): the verdict,
the scorecard (scenario x integrator family, its legend and its picture), the work-precision
answers, failures and divergences and the runs that did not run, the details of each scenario
(its table at its dt, the dt sweep, the work-precision table and the figures), the settings
changed from the engines' defaults, and the ensemble. Each writes into a
:class:`reports.report.doc.Doc` what :mod:`reports.report.tables` says of the rows.
"""

from __future__ import annotations

import html
import math
import re
from pathlib import Path

from reports.metrics import catalog
from reports.report.canvas import SeriesCache
from reports.report.doc import Cell, Doc, anchor, num, nums, order_cell, scenario_link
from reports.report.groups import group_rows, sweep_groups
from reports.report.importers import importer_section
from reports.report.labels import (
    METRIC_SHORT,
    NOT_RUN,
    SYMBOL,
    config_label,
    engine_key,
    entry_texts,
    family_key,
    fmt_attitude,
    fmt_error,
    fmt_headline,
    fmt_order,
    headline,
)
from reports.report.plots import rates_left_out
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
from reports.store.format import fmt, fmt_int, fmt_level, fmt_step, md_cell
from reports.store.results import records, reference_rows

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


#: what the figures of a scorecard entry are (the legend above the scorecard, the tooltips)
SCORECARD_TERMS = {
    "rad": "the max attitude error over the run (< x: below the reference's accuracy x, not "
    "a measurement)",
    "m": "a contact scene's largest position error against its closed form (a block's "
    "attitude hardly changes whether it holds, creeps or slides; its position tells them "
    "apart)",
    "q": "the max joint angle error against the reference (systems of bodies with joints: "
    "robot models, chains)",
    "E": "the max energy drift relative to the scenario's energy scale (a contact scene: the "
    "energy gained, exact 0 or less)",
    "µs": "the time inside the engine's own calls per step, the cost beside the verdict "
    "(the suite's glue left out; + suite: the suite's time loop around the engine's "
    "dynamics, whose own time is this figure)",
}


def scorecard_legend(doc: Doc, contact: bool = False) -> None:
    """The key to the scorecard, above it; ``contact``: the scorecard has contact scenes,
    whose entries show their position error in m."""
    m_md = f"**m**: {SCORECARD_TERMS['m']}, " if contact else ""
    m_html = f"<b>m</b>: {html.escape(SCORECARD_TERMS['m'])}, " if contact else ""
    md = (
        "✅ pass · ❌ fail (the metrics out of bounds after *fails*) · 💥 diverged · ⚠️ error "
        "· ❔ the reference is not accurate enough to judge. Each entry: the verdict, "
        f"**rad**: {SCORECARD_TERMS['rad']}, {m_md}**q**: {SCORECARD_TERMS['q']}, "
        f"**E**: {SCORECARD_TERMS['E']}, "
        f"then each configuration with **µs**: {SCORECARD_TERMS['µs']}. Configurations in one "
        "entry agree to 1e-3 in every metric (round-off-level values aside); each scenario's "
        "details give their largest difference."
    )
    h = (
        "<span class='v-pass'>✓ pass</span> <span class='v-fail'>✗ fail</span> "
        "<span class='v-diverged'>↯ diverged</span> <span class='v-error'>⚠ error</span> "
        "<span class='v-reference-inaccurate'>? reference too coarse to judge</span>. "
        "Each entry: the verdict, <b>rad</b>: "
        f"{html.escape(SCORECARD_TERMS['rad'])}, {m_html}"
        f"<b>q</b>: {html.escape(SCORECARD_TERMS['q'])}"
        f", <b>E</b>: {html.escape(SCORECARD_TERMS['E'])}"
        "; the metrics out of bounds after <b>fails</b>; then each configuration with "
        f"<b>µs</b>: {html.escape(SCORECARD_TERMS['µs'])}. Configurations in one entry agree "
        "to 1e-3 in every metric (round-off-level values aside); each scenario's details give "
        "their largest difference."
    )
    doc.para(md, h, cls="legend")


def _entry_html(out: str, who, figs, failing: str, href: str) -> str:
    spans = []
    for f in figs:
        if f.startswith(("E ", "q ")):
            abbr = f"<abbr title='{html.escape(SCORECARD_TERMS[f[0]])}'>{f[0]}</abbr>"
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


def _family_tip(family: str, contact: bool = False) -> str:
    """The tooltip of a scorecard column: what its entries show (``contact``: the
    scorecard has contact scenes)."""
    m = f"m: {SCORECARD_TERMS['m']}; " if contact else ""
    return (
        f"integrator family {family}. Each entry: the verdict; rad: "
        f"{SCORECARD_TERMS['rad']}; {m}q: {SCORECARD_TERMS['q']}; E: {SCORECARD_TERMS['E']}; "
        "then each configuration "
        f"with µs: {SCORECARD_TERMS['µs']}"
    )


def scorecard_section(doc: Doc, df, card, links: bool = True) -> None:
    fams = sorted({f for s in card for f in s["cells"]}, key=family_key)
    contact = any(
        headline(g.figure_row())[1] == "m"
        for s in card
        for groups in s["cells"].values()
        for g in groups
    )
    header = [
        Cell(
            "scenario",
            html_="<span title='each scenario at its own dt and horizon'>scenario</span>",
        ),
        *(
            Cell(f, html_=f"<span title='{html.escape(_family_tip(f, contact), quote=True)}'>"
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
    scorecard_legend(doc, contact)
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
        "error (a contact scene's: its position error against the closed form), the time "
        "inside the engine per step and the failing metrics."
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


def wp_cost(entry) -> str:
    """The cost of a work-precision answer: the engine's CPU time, or for a ``+ suite``
    configuration the whole step's with the engine's beside it; "starved" where no timing of
    the run ran clean (reports.store.runs.starved: an estimate, not a measurement)."""
    mark = " (starved)" if entry.get("starved") else ""
    if entry["suite_integrated"]:
        whole = f"{fmt(entry['cost_s'])} s whole step ({fmt(entry['engine_time_s'])} s engine)"
        return whole + mark
    return f"{fmt(entry['cost_s'])} s{mark}"


def wp_cell(entry, winner: bool, missed=None) -> tuple[str, str]:
    """(Markdown, HTML) of one engine's answer at one accuracy: its cheapest configuration
    (the engine named in the row), its cost (:func:`wp_cost`) and the ratio to the cheapest
    of all engines (the overall winner in bold); without one, ``missed`` ({answer, why} of
    the engine's configurations that did not reach it): *not tried* (still converging at
    the smallest step run, with where it stood) or *does not reach*."""
    if entry is None:
        if not missed:
            return "-", "<span class='none'>-</span>"
        tried = [m for m in missed if m["answer"] == "not tried"]
        pick = tried[0] if tried else missed[0]
        conf = pick["configuration"][len(pick["engine"]) :].strip()
        word = "not tried" if tried else "does not reach"
        # the word in the cell (the table fits 800 px), where it stood in its title and in
        # the scenario's own table
        title = html.escape(f"{conf}: {pick['why']}", quote=True)
        return f"*{word}*", f"<span class='none' title='{title}'>{word}</span>"
    conf = entry["configuration"][len(entry["engine"]) :].strip()
    # semi_explicit_euler may break at its underscores, "dt 0.002 s" nowhere
    conf_html = re.sub(r"dt (\S+) s$", "dt&nbsp;\\1&nbsp;s", html.escape(conf)).replace(
        "_", "_<wbr>"
    )
    ratio = "cheapest" if winner else f"x{fmt(entry['cost_ratio'])}"
    cost = f"{wp_cost(entry)}, {ratio}"
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
    of error (max attitude error; for a contact scene its position error against the closed
    form, in its own table), with its cost and its ratio to the cheapest of all engines;
    where none reaches it, whether the engine was not tried there or does not reach it."""
    from reports.report.precision import measure_of

    levels, tables = ACCURACY_LEVELS, {"rad": [], "m": []}
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        wp = work_precision(sub, levels)
        unit = measure_of(sub.iloc[0])[1]
        engines = sorted(
            set(sub.loc[(sub["status"] == "ok") & ~reference_rows(sub), "engine"]),
            key=engine_key(sub),
        )
        for k, eng in enumerate(engines):
            row = [scenario_link(scenario) if k == 0 else Cell(""), Cell(eng)]
            for lv in wp:
                mine = [e for e in lv["ranked"] if e["engine"] == eng]
                winner = bool(mine) and lv["ranked"][0] is mine[0]
                missed = [m for m in lv["not_reached"] if m["engine"] == eng]
                m, h = wp_cell(mine[0] if mine else None, winner, missed)
                row.append(Cell(md=m, html_=h, cls="win" if winner else ""))
            tables[unit].append(row)
    text = (
        "For each engine, its cheapest configuration reaching each max attitude error (fixed "
        "steps and error-controlled runs alike) and its cost: the CPU time spent inside the "
        "engine's own calls (`engine_time_s`: the time the run waited for a CPU on a busy "
        "machine is not in it), and its ratio to the cheapest of all engines (in bold, "
        "`cheapest`). `+ suite` marks a configuration whose time loop is the suite's own "
        "Python around the engine's dynamics: it is ranked by the CPU time of the whole step "
        "(`cpu_time_s`), what its user pays, with the engine's beside it. Every "
        "configuration of a scenario ran the same steps (the scenario's sweep) or targets; "
        "where none of an engine's reaches a level, *not tried* says that its error was still "
        "falling at the smallest step (and about what step would reach it) or that it "
        "finished at one step only (no sweep), *does not reach* that no run finished or its "
        "error stopped falling. An error below the reference's "
        "accuracy reaches no level below that accuracy. For a system of bodies the attitude "
        "error is the largest over its bodies; a contact scene is ranked by its largest "
        "position error against the closed form, in metres (a block's attitude hardly "
        "changes whether it holds, creeps or slides), in a table of its own. `(starved)`: no "
        "timing of that run ran clean (the machine was too busy to measure the engine's CPU "
        "time within 10 %): its cost is an estimate, and `compare` never counts a change of "
        "it as significant."
    )
    doc.para(text, re.sub(r"`([^`]+)`", r"<code>\1</code>", html.escape(text)))
    # seven columns of configurations and times (names break at underscores) fit 800 px;
    # cards on a narrower screen
    for unit, rows in tables.items():
        if rows or (unit == "rad" and not tables["m"]):
            title = "per accuracy" if unit == "rad" else "per position error (contact scenes)"
            header = ["scenario", "engine", *(f"≤ {fmt_level(lv)} {unit}" for lv in levels)]
            doc.table(f"Cheapest configuration of each engine {title}", header, rows,
                      cls="wp narrow-stack")  # fmt: skip


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
    """The scenario's headline error (:func:`reports.report.labels.headline`: the attitude
    error, a contact scene's position error) at every dt of the sweep, with the fitted and
    declared orders."""
    shown = sub[~sub["status"].isin(NOT_RUN)]
    groups = [g for g in sweep_groups(shown) if len(g.dts) >= 2]
    if not groups:
        return
    dts = sorted({h for g in groups for h in g.dts}, reverse=True)
    column, unit, short = headline(groups[0].first)
    fitted = any(fmt_order(g.first) != "-" for g in groups)
    header = [
        "family",
        "configurations",
        *(f"dt {fmt_step(h)}" for h in dts),
        # the order is fitted to the attitude errors (reports.metrics.body); where the table
        # shows another error (a contact scene's position error) and an order was fitted,
        # the header says so
        "fitted order (attitude error)"
        if column != "attitude_error_max" and fitted
        else "fitted order",
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
                cells.append(num(None, fmt_headline(at.figure_row())))
            elif out == "diverged":
                cells.append(Cell(f"diverged {fmt(at.value('t_diverged'))} s", cls="v-diverged"))
            else:
                cells.append(Cell(out, cls=f"v-{out}"))
        cells.append(order_cell(fmt_order(g.first)))
        cells.append(num(None, fmt_int(g.first["order"])))
        body.append(cells)
    doc.table(f"{scenario}: max {short} error [{unit}] over the dt sweep", header, body)


def wp_table(doc: Doc, scenario: str, sub) -> None:
    wp = work_precision(sub)
    if not any(lv["ranked"] for lv in wp):
        return
    _, unit, short = headline(sub.iloc[0])
    header = [
        f"{short} error ≤",
        "cheapest",
        f"its error [{unit}]",
        "cost [s]",
        "wall time [s]",
        "next cheapest (cost ratio)",
    ]
    body = []
    for lv in wp:
        r = lv["ranked"]
        if not r:
            tried = [m for m in lv["not_reached"] if m["answer"] == "not tried"]
            why = (
                "none reaches it; not tried: "
                + ", ".join(f"{m['configuration']} ({m['why']})" for m in tried[:3])
                if tried
                else "none of the runs"
            )
            body.append([num(None, fmt_level(lv["level"])), why, "", "", "", ""])
            continue
        first = r[0]
        nxt = ", ".join(f"{e['configuration']} x{fmt(e['cost_ratio'])}" for e in r[1:5])
        body.append(
            [
                num(None, fmt_level(lv["level"])),
                first["configuration"],
                num(None, fmt_error(first["error"], first["reference_accuracy"])),
                num(None, wp_cost(first)),
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
    its heading, its verdicts first (:func:`reports.report.verdict.scenario_verdicts`)."""
    doc.heading(2, "Details")
    cache = SeriesCache(root)
    from reports.report.verdict import COLUMNS, scenario_verdicts, verdict_rows

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
