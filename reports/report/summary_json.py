"""``summary.json``: what a results folder says, for machines (the scorecard, the
work-precision answers and every run; the layout is documented in docs/results.md). Written
with every report and by ``python -m reports.report.summary RESULTS_DIR``.
"""

from __future__ import annotations

import json
from pathlib import Path

from reports.metrics.catalog import METRIC_COLUMNS
from reports.report.groups import Group
from reports.report.labels import energy_headline, headline
from reports.report.tables import scenarios_of, scorecard, work_precision
from reports.store.atomic import write_text
from reports.store.format import json_value, truthy
from reports.store.results import records

#: version of the layout of summary.json
SUMMARY_FORMAT = 1

#: the columns every run carries in summary.json
RUN_FIELDS = (
    "run_id",
    "scenario",
    "engine",
    "engine_version",
    "integrator",
    "family",
    "suite_integrated",
    "dt",
    "target_accuracy",
    "t_end",
    "status",
    "verdict",
    "verdict_detail",
    "message",
    "t_diverged",
    *METRIC_COLUMNS,
    "convergence_points",
    "reference_accuracy",
    "wall_time_s",
    "engine_time_s",
    "ns_per_step",
    "engine_ns_per_step",
)


def _group_json(g: Group) -> dict:
    fr = g.figure_row()
    col = headline(fr)[0]  # the error the group is summed up by (contact: position)
    return {
        "configurations": [
            {
                "engine": r["engine"],
                "integrator": r["integrator"],
                "suite_integrated": truthy(r["suite_integrated"]),
                "run_id": r["run_id"],
            }
            for r in g.rows
        ],
        "outcome": g.outcome,
        "status": g.first["status"],
        "verdict": g.first["verdict"],
        "verdict_detail": g.first["verdict_detail"],
        "error": json_value(fr[col]),
        "error_measure": col,
        "error_below_reference_accuracy": bool(fr[col] < fr["reference_accuracy"]),
        "attitude_error_max": json_value(fr["attitude_error_max"]),
        "attitude_below_reference_accuracy": bool(
            fr["attitude_error_max"] < fr["reference_accuracy"]
        ),
        "reference_accuracy": json_value(fr["reference_accuracy"]),
        "energy": json_value(fr[energy_headline(fr)]),
        "energy_measure": energy_headline(fr),
        "energy_drift_max": json_value(fr["energy_drift_max"]),
        "t_diverged": json_value(fr["t_diverged"]),
        "max_rel_diff": json_value(g.max_rel_diff),
    }


def summary(df, prov: dict | None = None, card: list | None = None) -> dict:
    """The content of summary.json (documented in docs/results.md); ``card``: the table's
    :func:`reports.report.tables.scorecard` if the caller has it already."""
    from reports import __version__

    scenarios = scorecard(df) if card is None else card
    card = []
    for s in scenarios:
        card.append(
            {
                "scenario": s["scenario"],
                "dt": s["dt"],
                "t_end": s["t_end"],
                "reference_kind": s["reference_kind"],
                "reference_accuracy": json_value(s["reference_accuracy"]),
                "families": {
                    fam: [_group_json(g) for g in groups] for fam, groups in s["cells"].items()
                },
            }
        )
    wp = {}
    for scenario in scenarios_of(df):
        wp[scenario] = [
            {
                "level": lv["level"],
                "ranked": [{k: json_value(v) for k, v in e.items()} for e in lv["ranked"]],
                "not_reached": lv["not_reached"],
            }
            for lv in work_precision(df[df["scenario"] == scenario])
        ]
    runs = [{k: json_value(r.get(k)) for k in RUN_FIELDS} for r in records(df)]
    for r in runs:
        r["suite_integrated"] = truthy(r["suite_integrated"])
    return {
        "format": SUMMARY_FORMAT,
        "suite_version": __version__,
        "provenance": prov or {},
        "counts": {
            "runs": len(df),
            "status": {k: int(v) for k, v in df["status"].value_counts().sort_index().items()},
            "verdict": {
                (k or "none"): int(v) for k, v in df["verdict"].value_counts().sort_index().items()
            },
        },
        "scorecard": card,
        "work_precision": wp,
        "runs": runs,
    }


def write_summary(root: str | Path, df, prov: dict | None = None, card: list | None = None) -> Path:
    """Write ``summary.json`` into the results folder (atomically); ``card`` as for
    :func:`summary`."""
    text = json.dumps(summary(df, prov, card), indent=1, allow_nan=False)
    return write_text(Path(root) / "summary.json", text + "\n")
