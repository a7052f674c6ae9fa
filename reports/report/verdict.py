"""The verdict a reader sees first: one row per scenario, how many configurations pass, fail,
diverge, cannot be judged or did not run at the scenario's own step, and a row of totals;
and report.md's short verdict table of each scenario (:func:`scenario_verdicts`).

Six columns of short cells, so that the table keeps one line per row where a report is read:
on GitHub (report.md in a pull request, 1012 px of page) and in report.html on an 800 px
screen. Everything else of the report (the scorecard of every configuration, the figures, the
tables) follows, collapsed in report.md.
"""

from __future__ import annotations

from reports.report.doc import Cell, Doc, num
from reports.report.labels import (
    METRIC_SHORT,
    NOT_RUN,
    SYMBOL,
    energy_headline,
    entry_texts,
    family_key,
    fmt_headline,
    fmt_joint_angle,
    headline,
)
from reports.report.tables import at_scenario_dt, scenarios_of
from reports.store.format import fmt, fmt_step, md_cell
from reports.store.results import reference_rows

#: the columns after the scenario, each an outcome of a configuration at a scenario's own step
#: (a group's outcome, reports.report.groups; ``not judged``: an error of the suite or a
#: reference too coarse to judge; ``not run``: the engine cannot represent the scenario or is
#: not installed)
COLUMNS = ("pass", "fail", "diverged", "not judged", "not run")
OUTCOME_COLUMN = {
    "pass": "pass",
    "fail": "fail",
    "diverged": "diverged",
    "error": "not judged",
    "reference-inaccurate": "not judged",
}
#: the sentence under the table
LEGEND = (
    "Configurations (engine and integrator) per scenario at its own step: *fail* a bound "
    "exceeded, *diverged* the run blew up (it fails too), *not judged* a fault of the suite "
    "or a reference too coarse to judge, *not run* the engine cannot represent the scenario "
    "or is not installed. Each scenario's section below has every configuration's verdict, "
    "errors, cost and figures."
)


def verdict_rows(df, card) -> list[dict]:
    """Per scenario: ``scenario``, ``dt``, ``t_end`` and the count of each of :data:`COLUMNS`
    at its own step; ``card``: :func:`reports.report.tables.scorecard` of ``df``."""
    out = []
    by_name = {s["scenario"]: s for s in card}
    for scenario in scenarios_of(df):
        s = by_name[scenario]
        counts = dict.fromkeys(COLUMNS, 0)
        for groups in s["cells"].values():
            for g in groups:
                counts[OUTCOME_COLUMN.get(g.outcome, "not judged")] += len(g.rows)
        rows = at_scenario_dt(df[df["scenario"] == scenario])
        counts["not run"] = int((~reference_rows(rows) & rows["status"].isin(NOT_RUN)).sum())
        out.append({"scenario": scenario, "dt": s["dt"], "t_end": s["t_end"], **counts})
    return out


def totals(rows: list[dict]) -> dict:
    return {c: sum(r[c] for r in rows) for c in COLUMNS}


def scenario_verdicts(doc: Doc, s: dict) -> None:
    """report.md's scorecard of one scenario (``s``, an entry of
    :func:`reports.report.tables.scorecard`): a row per group of configurations that agree,
    six columns (the HTML report has the scorecard of every scenario instead), the error
    its runs are summed up by (:func:`reports.report.labels.headline`: the attitude error,
    a contact scene's position error) among them; a seventh, the joint angle error, where
    the scenario's runs measure one (a system of bodies with joints: a robot model, a
    chain)."""
    groups = [g for fam in sorted(s["cells"], key=family_key) for g in s["cells"][fam]]
    joints = any(fmt_joint_angle(g.figure_row()) is not None for g in groups)
    first = groups[0].figure_row() if groups else {}
    _, unit, short = headline(first)
    energy = METRIC_SHORT.get(energy_headline(first), "energy")
    header = ["family", "configurations", "verdict", f"{short} [{unit}]", energy,
              "engine µs/step"]  # fmt: skip
    if joints:
        header.insert(3, "joint angle [rad]")
    body = []
    for fam in sorted(s["cells"], key=family_key):
        for g in s["cells"][fam]:
            out, who, figs, failing = entry_texts(g)
            verdict = f"{SYMBOL.get(out, '')} {out}" + (f": {failing}" if failing else "")
            fr = g.figure_row()
            if out in ("pass", "fail"):
                att, energy = fmt_headline(fr), fmt(fr[energy_headline(fr)])
                q = fmt_joint_angle(fr) or "-"
            else:
                verdict += figs[0].removeprefix("diverged") if out == "diverged" else ""
                att = energy = q = "-"
            row = [
                fam,
                Cell(md="<br>".join(md_cell(n) for n, _ in who)),
                verdict,
                num(None, att),
                num(None, energy),
                Cell(md="<br>".join(md_cell(c.removesuffix(" µs")) for _, c in who), num=True),
            ]
            if joints:
                row.insert(3, num(None, q))
            body.append(row)
    where = f"dt = {fmt_step(s['dt'])} s, t_end = {fmt_step(s['t_end'])} s"
    doc.table(f"{s['scenario']}: verdicts at {where}", header, body)
