"""What a results folder says, as data: per scenario its step and reference, the scorecard,
the work-precision answers, the failures, the configurations that did not run and the settings
that ran; pure functions of the results table (reports.store.results), rendered by the report
(reports.report.build) and carried by summary.json (reports.report.summary_json).
"""

from __future__ import annotations

import json
import math
import re

import numpy as np

from reports.report.groups import group_rows
from reports.report.labels import (
    NOT_RUN,
    config_label,
    engine_key,
    is_failure,
)
from reports.report.precision import cost_of, measure_of, outlook
from reports.store.format import num, truthy
from reports.store.results import default_dt, records, reference_rows
from reports.store.runs import starved

#: max attitude error levels of the work-precision answers, rad
ACCURACY_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)

#: the integrator whose conserved energy is not the suite's (see ENERGY_MOMENTUM_NOTE), and
#: its family: the director formulation's energy-momentum scheme
ENERGY_MOMENTUM = "energy_momentum"
DIRECTOR_FAMILY = "structure-preserving director"

ENERGY_MOMENTUM_NOTE = (
    "The energy-momentum scheme conserves its own energy, the director-form energy written "
    "with the director velocities D', to round-off. Its D' leaves the tangent space at "
    "O(h^2) (the velocity constraint is not enforced at the nodes), and the suite's energy, "
    "computed from W, therefore shows an O(h^2) drift: that is the scheme's velocity-"
    "constraint violation (constraint_velocity_max), not a loss of its conserved quantity."
)


def scenario_dt(sub) -> float:
    """The step a scenario is shown at: its own dt (the exact reference's step)."""
    return float(default_dt(sub))


def at_scenario_dt(sub):
    """The rows of one scenario at its own dt, and, for each error-controlled integrator,
    its runs at the tightest target accuracy (they run at the scenario's dt as the interval
    of their checkpoints)."""
    h = scenario_dt(sub)
    fixed = sub[sub["target_accuracy"].isna() & np.isclose(sub["dt"], h, rtol=1e-9)]
    adaptive = sub[sub["target_accuracy"].notna()]
    if len(adaptive):
        import pandas as pd

        tight = adaptive.groupby(["engine", "integrator"])["target_accuracy"].transform("min")
        adaptive = adaptive[adaptive["target_accuracy"] == tight]
        return pd.concat([fixed, adaptive])
    return fixed


def scenarios_of(df) -> list[str]:
    return sorted(df["scenario"].unique())


def scenario_info(sub) -> dict:
    """dt, horizon and reference of one scenario's rows."""
    h = scenario_dt(sub)
    exact = sub[reference_rows(sub)]
    ref = exact.iloc[0] if len(exact) else None
    return {
        "dt": h,
        "t_end": float(sub["t_end"].max()),
        "reference_kind": "" if ref is None else str(ref["reference_kind"]),
        "reference_accuracy": math.nan if ref is None else num(ref["reference_accuracy"]),
        "dts": sorted({float(x) for x in sub.loc[sub["target_accuracy"].isna(), "dt"]}),
    }


def scorecard(df) -> list[dict]:
    """Per scenario: its dt and, per integrator family (the exact reference excluded), the
    groups of its runs at that dt (configurations that did not run are left out)."""
    out = []
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        rows = at_scenario_dt(sub)
        rows = rows[~reference_rows(rows) & ~rows["status"].isin(NOT_RUN)]
        cells = {}
        for g in group_rows(rows):
            cells.setdefault(g.first["family"], []).append(g)
        out.append({"scenario": scenario, **scenario_info(sub), "cells": cells})
    return out


def work_precision(sub, levels=ACCURACY_LEVELS) -> list[dict]:
    """For each level of error (the max attitude error; a contact scene's position error,
    :func:`reports.report.precision.measure_of`): every configuration (engine, integrator) that
    reaches it with its cheapest such run (fixed steps and error-controlled points alike),
    cheapest first by the cost a user pays (:func:`reports.report.precision.cost_of`: the
    engine's CPU time; for a ``+ suite`` configuration the whole step's), with the cost
    ratio to the cheapest; and every other configuration that ran, with why not
    (``not tried``: still converging at the smallest step run; ``does not reach``:
    :func:`reports.report.precision.outlook`). An error below the reference's accuracy does
    not reach a level below that accuracy: it is not a measurement."""
    rows = records(sub[~reference_rows(sub) & ~sub["status"].isin(NOT_RUN)])
    configs: dict[tuple, list] = {}
    for r in rows:
        configs.setdefault((r["engine"], r["integrator"]), []).append(r)
    out = []
    for level in levels:
        reached, missed = [], []
        for (eng, integ), runs in configs.items():
            word, what = outlook(runs, level)
            if word == "reached":
                reached.append(what)
            else:
                label = config_label(runs[0])
                missed.append(
                    {
                        "configuration": label,
                        "engine": eng,
                        "integrator": integ,
                        "answer": word,
                        "why": what,
                    }  # fmt: skip
                )
        ranked = sorted(reached, key=cost_of)
        entries = [
            {
                "configuration": config_label(r, with_step=True),
                "engine": r["engine"],
                "integrator": r["integrator"],
                "suite_integrated": truthy(r["suite_integrated"]),
                "dt": float(r["dt"]),
                "target_accuracy": num(r["target_accuracy"]),
                "attitude_error_max": num(r["attitude_error_max"]),
                "error": num(r[measure_of(r)[0]]),
                "error_measure": measure_of(r)[0],
                "reference_accuracy": num(r["reference_accuracy"]),
                "cost_s": cost_of(r),
                "engine_time_s": num(r["engine_time_s"]),
                "cpu_time_s": num(r.get("cpu_time_s")),
                "wall_time_s": num(r["wall_time_s"]),
                "starved": starved(r),
                "cost_ratio": cost_of(r) / cost_of(ranked[0]),
            }
            for r in ranked
        ]
        out.append({"level": level, "ranked": entries, "not_reached": missed})
    return out


def failures(df) -> list[dict]:
    """Runs that failed their verdict, diverged, errored or could not be judged, grouped
    (identical engines collapse), each with whether it is at the scenario's own dt."""
    out = []
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        h = scenario_dt(sub)
        bad = sub[[is_failure(r) for r in records(sub)]]
        for (dt, acc), g in bad.groupby(["dt", "target_accuracy"], dropna=False, sort=True):
            for grp in group_rows(g):
                out.append(
                    {
                        "scenario": scenario,
                        "dt": float(dt),
                        "target_accuracy": num(acc),
                        "own_dt": bool(np.isclose(dt, h, rtol=1e-9)),
                        "group": grp,
                    }
                )
    return out


def not_run(df) -> list[dict]:
    """Configurations that did not run (unsupported, unavailable), one entry per
    configuration and message (the whole message: its reason and what to do), with the
    scenarios concerned."""
    rows = df[df["status"].isin(NOT_RUN)]
    engine = engine_key(df)
    out = {}
    for r in records(rows):
        key = (r["engine"], r["integrator"], r["status"], " ".join(str(r["message"]).split()))
        out.setdefault(key, set()).add(r["scenario"])
    return [
        {
            "engine": e,
            "integrator": i,
            "status": s,
            "message": m,
            "scenarios": sorted(scs),
        }
        for (e, i, s, m), scs in sorted(out.items(), key=lambda kv: engine(kv[0][0]))
    ]


def settings_table(df) -> list[dict]:
    """Every setting changed from an engine's defaults with all the values that ran: per
    engine, integrator and setting, the distinct values per scenario; scenarios with the same
    values share an entry."""
    per = {}
    for r in records(df[df["settings"] != ""]):
        try:
            s = json.loads(r["settings"])
        except ValueError:
            continue
        if not isinstance(s, dict):
            continue
        for k, v in s.items():
            text = unsigned_zeros(v if isinstance(v, str) else json.dumps(v))
            key = (r["engine"], r["integrator"], k)
            per.setdefault(key, {}).setdefault(r["scenario"], set()).add(text)
    out = []
    for (eng, integ, k), by_scen in per.items():
        merged = {}
        for scen, vals in by_scen.items():
            merged.setdefault(tuple(sorted(vals, key=_value_key)), []).append(scen)
        for vals, scens in sorted(merged.items(), key=lambda kv: sorted(kv[1])):
            out.append(
                {
                    "engine": eng,
                    "integrator": integ,
                    "setting": k,
                    "values": list(vals),
                    "scenarios": sorted(scens),
                }
            )
    engine = engine_key(df)
    out.sort(key=lambda e: (engine(e["engine"]), e["integrator"], e["setting"]))
    return out


#: the settings that shape a loop closure, per engine: (label, path of keys in the settings)
CLOSURE_KNOBS = (
    ("solref", ("solref effective",)),  # what ran (an override applied), else what was set
    ("solref", ("solref",)),
    ("solimp", ("solimp",)),
    ("Baumgarte (Kp, Kd)", ("Baumgarte (Kp, Kd)",)),
    ("ERP", ("constraint solver", "error reduction parameter (ERP)")),
    ("CFM", ("constraint solver", "constraint force mixing")),
    ("erp", ("constraints", "erp")),
)


def closure_settings(row, short: bool = False) -> str:
    """The settings that shape a run's loop closures, read from its ``settings`` (MuJoCo's
    ``solref``/``solimp``, Pinocchio's Baumgarte gains, DART's ERP and CFM, PyBullet's
    constraint ``erp``), or, for an engine with none of those, its closure mechanism as it
    recorded it; '' for a run without loop closures. ``short``: the stiffness alone (no
    ``solimp``, no CFM), for a legend."""
    try:
        s = json.loads(row.get("settings") or "{}")
    except ValueError:
        return ""
    if not isinstance(s, dict) or not s.get("loop closures"):
        return ""
    parts = []
    for label, path in CLOSURE_KNOBS:
        v = s.get(path[0])
        if len(path) == 2 and isinstance(v, dict):
            v = v.get(path[1])
        elif len(path) == 2 and isinstance(v, list):  # one entry per constraint
            vals = {json.dumps(c.get(path[1])) for c in v if isinstance(c, dict)}
            v = json.loads(vals.pop()) if len(vals) == 1 else sorted(vals) if vals else None
        if v is None or any(p.startswith(f"{label} ") for p in parts):
            continue
        if short and label in ("solimp", "CFM"):
            continue
        if isinstance(v, list):
            v = "(" + ", ".join(_setting(x) for x in v) + ")"
        parts.append(f"{label} {_setting(v)}")
    if parts:
        return ", ".join(parts)
    first = str(s["loop closures"][0])
    return unsigned_zeros(first.split(": ", 1)[-1])


def _setting(v) -> str:
    """A setting's value as it was given (``0.02``, ``1e-09``), not rounded like a metric;
    a negative zero as 0."""
    text = f"{v:g}" if isinstance(v, float | int) and not isinstance(v, bool) else str(v)
    return unsigned_zeros(text)


#: a number in a text that is a negative zero (``-0``, ``-0.0``, ``-0e+00``): a minus sign not
#: inside a word or number, a zero mantissa, and no digit, letter or point after it
_NEGATIVE_ZERO = re.compile(r"(?<![\w.])-(0(?:\.0*)?(?:[eE][+-]?\d+)?)(?![\w.])")


def unsigned_zeros(text: str) -> str:
    """``text`` with every negative zero written without its sign (an engine that negates a
    zero coordinate records ``[-0.0, -0.0, 0.1]``; the report shows ``[0.0, 0.0, 0.1]``).
    For display only: the stored value is not changed."""
    return _NEGATIVE_ZERO.sub(r"\1", text)


def _value_key(text: str):
    try:
        return (0, float(text), "")
    except ValueError:
        return (1, 0.0, text)


def energy_momentum_rows(df):
    """The runs of the director's energy-momentum scheme that ran (not unsupported or
    unavailable): what the report says of the scheme is said only where these exist."""
    em = (df["integrator"] == ENERGY_MOMENTUM) & (df["family"] == DIRECTOR_FAMILY)
    return df[em & ~df["status"].isin(NOT_RUN)]
