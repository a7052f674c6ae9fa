"""The verdict a reader sees first: one row per scenario, how many configurations pass, fail,
diverge, cannot be judged or did not run at the scenario's own step, and a row of totals.

Six columns of short cells, so that the table keeps one line per row where a report is read:
on GitHub (report.md in a pull request, 1012 px of page) and in report.html on an 800 px
screen. Everything else of the report (the scorecard of every configuration, the figures, the
tables) follows, collapsed in report.md.
"""

from __future__ import annotations

from reports.report.labels import NOT_RUN
from reports.report.tables import at_scenario_dt, scenarios_of
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
