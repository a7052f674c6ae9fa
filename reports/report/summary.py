"""What a results folder says, as data: the scorecard, the work-precision answers, the failures
and ``summary.json``; pure functions of the results table (reports.store.results).

The report (reports.report.build) renders these; ``summary.json`` carries them for machines; and

    python -m reports.report.summary RESULTS_DIR [--readme] [--level 1e-8]

writes ``summary.json`` into the folder, or with ``--readme`` prints the Markdown block of the
README's "What it shows" from the same scorecard, so that no figure there is copied by hand.

Grouping. Engines that run the same algorithm (one integrator family) give the same numbers to
round-off. Rows of one scenario, step (or target accuracy) and family whose status and verdict
match and whose every metric agrees to :data:`COLLAPSE_RTOL` (relative) are one *group*: one
row in every table, listing its configurations, with the largest relative difference between
them. Two values that are both at or below the metric's round-off floor
(:data:`reports.metrics.body.FLOORS`) agree whatever their ratio: 3e-16 against 9e-15 is round-off.

Numbers are formatted one way everywhere (:func:`fmt`): three significant digits, scientific
notation outside [1e-3, 1e4).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from reports.metrics.body import FLOORS, HIGHER_IS_BETTER
from reports.store.results import METRIC_COLUMNS, default_dt

#: version of the layout of summary.json
SUMMARY_FORMAT = 1

#: integrator families in the order tables and the scorecard show them (others follow, sorted)
FAMILY_ORDER = (
    "structure-preserving director",
    "4th-order Lie-group",
    "implicit gyroscopic",
    "semi-implicit Euler",
    "exact",
)

#: engines in the order tables list them (others follow, sorted); plots colour them likewise
ENGINE_ORDER = ("director", "mujoco", "pinocchio", "dart", "pybullet", "exact")

#: rows whose every metric agrees to this relative difference are one group: their figures
#: printed to three significant digits would differ by at most one unit in the last digit
COLLAPSE_RTOL = 1e-3

#: max attitude error levels of the work-precision answers, rad
ACCURACY_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)

#: the metrics a group's members must agree on (with the status, verdict and t_diverged)
GROUP_METRICS = tuple(m for m in METRIC_COLUMNS if m != "convergence_order")

#: the integrator whose conserved energy is not the suite's (see ENERGY_MOMENTUM_NOTE)
ENERGY_MOMENTUM = "energy_momentum"

ENERGY_MOMENTUM_NOTE = (
    "The energy-momentum scheme conserves its own energy, the director-form energy written "
    "with the director velocities D', to round-off. Its D' leaves the tangent space at "
    "O(h^2) (the velocity constraint is not enforced at the nodes), and the suite's energy, "
    "computed from W, therefore shows an O(h^2) drift: that is the scheme's velocity-"
    "constraint violation (constraint_velocity_max), not a loss of its conserved quantity."
)

#: statuses that are not a result of the configuration (nothing ran, or could not)
NOT_RUN = ("unsupported", "unavailable")


#: short names of the metrics in verdict texts
METRIC_SHORT = {
    "attitude_error_max": "attitude",
    "omega_error_max": "W",
    "position_error_max": "position",
    "flip_interval_error": "flip interval",
    "nutation_period_error": "nutation period",
    "energy_drift_max": "energy",
    "energy_drift_rot_max": "rotational energy",
    "energy_drift_trans_max": "translational energy",
    "momentum_drift_max": "momentum",
    "orthonormality_max": "orthonormality",
    "constraint_velocity_max": "velocity constraint",
}

# -- formatting ---------------------------------------------------------------------------------


def fmt(v) -> str:
    """A number for a table: three significant digits, scientific notation outside
    [1e-3, 1e4) with a short exponent (``8.50e-4``, ``1.58e5``); NaN and None are ``-``,
    integers and text as they are."""
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    v = float(v)
    if math.isnan(v):
        return "-"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == 0:
        return "0"
    r = float(f"{v:.3g}")
    if 1e-3 <= abs(r) < 1e4:
        e = math.floor(math.log10(abs(r)))
        return f"{r:.{max(0, 2 - e)}f}"
    mant, exp = f"{r:.2e}".split("e")
    return f"{mant}e{int(exp)}"


def fmt_int(v) -> str:
    """A count or a declared order: a whole number, ``-`` if missing."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return "-" if v in (None, "") else str(v)
    return "-" if math.isnan(f) else str(int(round(f)))


def fmt_level(v: float) -> str:
    """An accuracy level or target accuracy: ``1e-8``."""
    mant, exp = f"{float(v):.0e}".split("e")
    return f"{mant}e{int(exp)}"


def fmt_attitude(row) -> str:
    """The attitude error, or ``< acc`` (the reference's accuracy) when it is below what the
    reference can measure."""
    v = _num(row.get("attitude_error_max"))
    acc = _num(row.get("reference_accuracy"))
    if not math.isnan(v) and not math.isnan(acc) and v < acc:
        return f"< {fmt(acc)}"
    return fmt(v)


def fmt_order(row) -> str:
    """The fitted convergence order with the number of points of the fit, ``-`` if none."""
    o = _num(row.get("convergence_order"))
    if math.isnan(o):
        return "-"
    n = _num(row.get("convergence_points"))
    return fmt(o) if math.isnan(n) else f"{fmt(o)} ({int(n)} pts)"


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def truthy(v) -> bool:
    """A boolean column read back from the store (``"True"``/``"False"``/empty)."""
    return v is True or str(v).strip().lower() in ("true", "1", "yes")


# -- ordering and labels ------------------------------------------------------------------------


def family_key(fam: str) -> tuple:
    return (FAMILY_ORDER.index(fam), "") if fam in FAMILY_ORDER else (len(FAMILY_ORDER), fam)


def engine_key(eng: str) -> tuple:
    return (ENGINE_ORDER.index(eng), "") if eng in ENGINE_ORDER else (len(ENGINE_ORDER), eng)


def families_of(df) -> list[str]:
    return sorted({f for f in df["family"] if f}, key=family_key)


def config_label(row, with_step: bool = False) -> str:
    """``mujoco RK4``; a configuration whose time loop is the suite's own code around the
    engine's dynamics reads ``pinocchio + suite RKMK4`` (its wall time includes our Python).
    ``with_step``: the step (``dt 2e-3``) or, for an error-controlled integrator, its target
    accuracy (``tol 1e-8``)."""
    sep = " + suite " if truthy(row.get("suite_integrated")) else " "
    text = f"{row['engine']}{sep}{row['integrator']}"
    acc = _num(row.get("target_accuracy"))
    if not math.isnan(acc):
        text += f" tol {fmt_level(acc)}"
    elif with_step:
        text += f" dt {fmt_step(row['dt'])} s"
    return text


def fmt_step(dt: float) -> str:
    return f"{float(dt):g}"


def outcome(row) -> str:
    """One word for a row: pass, fail, diverged, error, reference-inaccurate, unsupported or
    unavailable (the verdict of an ok run, else the status)."""
    status = row.get("status", "")
    if status == "ok":
        return row.get("verdict") or "ok"
    return status or "error"


def failed_metrics(detail: str) -> list[str]:
    """The metric names of a verdict detail (``"attitude_error_max 3.14 > 0.1; ..."``)."""
    return [part.strip().split(" ")[0] for part in str(detail).split(";") if part.strip()]


# -- groups -------------------------------------------------------------------------------------


def rel_diff(a: float, b: float, floor: float = 0.0) -> float:
    """Relative difference of two metric values, 0 when both are at or below ``floor``."""
    a, b = _num(a), _num(b)
    if math.isnan(a) and math.isnan(b):
        return 0.0
    if math.isnan(a) or math.isnan(b):
        return math.inf
    if a == b or (abs(a) <= floor and abs(b) <= floor):
        return 0.0
    if math.isinf(a) or math.isinf(b):
        return math.inf
    return abs(a - b) / max(abs(a), abs(b))


def row_difference(a, b) -> float:
    """The largest relative difference between two rows' metrics (inf when their status,
    verdict or divergence time differ)."""
    if (a["status"], a["verdict"]) != (b["status"], b["verdict"]):
        return math.inf
    worst = rel_diff(a["t_diverged"], b["t_diverged"])
    for m in GROUP_METRICS:
        worst = max(worst, rel_diff(a[m], b[m], FLOORS.get(m, 0.0)))
    return worst


@dataclass
class Group:
    """Rows of one scenario, step and family that agree (see the module docstring)."""

    rows: list = field(default_factory=list)  # dicts, the members in table order
    max_rel_diff: float = 0.0

    @property
    def first(self) -> dict:
        return self.rows[0]

    @property
    def labels(self) -> list[str]:
        return [config_label(r) for r in self.rows]

    @property
    def label(self) -> str:
        return ", ".join(self.labels)

    @property
    def engines(self) -> list[str]:
        return list(dict.fromkeys(r["engine"] for r in self.rows))

    @property
    def outcome(self) -> str:
        return outcome(self.first)

    def value(self, metric: str) -> float:
        """The group's figure: the worst member's (largest error, lowest fitted order)."""
        vals = [_num(r.get(metric)) for r in self.rows]
        vals = [v for v in vals if not math.isnan(v)]
        if not vals:
            return math.nan
        return min(vals) if metric in HIGHER_IS_BETTER else max(vals)

    def figure_row(self) -> dict:
        """A row with the group's figures, for the formatting helpers."""
        row = dict(self.first)
        for m in (*METRIC_COLUMNS, "reference_accuracy", "t_diverged"):
            row[m] = self.value(m)
        return row

    def cost(self, column: str) -> list[float]:
        return [_num(r.get(column)) for r in self.rows]


def records(df) -> list[dict]:
    """The rows of a results table as dicts (column by column: DataFrame.to_dict walks the
    rows one by one, a hundred times slower on a table of a few hundred runs)."""
    cols = list(df.columns)
    columns = [df[c].tolist() for c in cols]
    return [dict(zip(cols, vals, strict=True)) for vals in zip(*columns, strict=True)]


def _sorted_records(df) -> list[dict]:
    recs = records(df)
    return sorted(
        recs, key=lambda r: (family_key(r["family"]), engine_key(r["engine"]), r["integrator"])
    )


def group_rows(df, rtol: float = COLLAPSE_RTOL) -> list[Group]:
    """Groups of rows of one scenario and step (or target accuracy): within each family, a
    row joins the first group whose first member it agrees with (see the module docstring);
    groups in family order, members in engine order."""
    groups: list[Group] = []
    for rec in _sorted_records(df):
        for g in groups:
            f = g.first
            if f["family"] != rec["family"] or not _same_accuracy(f, rec):
                continue
            if f["engine"] == "exact" or rec["engine"] == "exact":
                continue
            d = row_difference(f, rec)
            if d <= rtol:
                g.rows.append(rec)
                g.max_rel_diff = max(g.max_rel_diff, d)
                break
        else:
            groups.append(Group([rec]))
    return groups


def _same_accuracy(a, b) -> bool:
    x, y = _num(a.get("target_accuracy")), _num(b.get("target_accuracy"))
    return (math.isnan(x) and math.isnan(y)) or x == y


# -- what the report shows ----------------------------------------------------------------------


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
    exact = sub[sub["engine"] == "exact"]
    ref = exact.iloc[0] if len(exact) else None
    return {
        "dt": h,
        "t_end": float(sub["t_end"].max()),
        "reference_kind": "" if ref is None else str(ref["reference_kind"]),
        "reference_accuracy": math.nan if ref is None else _num(ref["reference_accuracy"]),
        "dts": sorted({float(x) for x in sub.loc[sub["target_accuracy"].isna(), "dt"]}),
    }


def scorecard(df) -> list[dict]:
    """Per scenario: its dt and, per integrator family (the exact reference excluded), the
    groups of its runs at that dt (configurations that did not run are left out)."""
    out = []
    for scenario in scenarios_of(df):
        sub = df[df["scenario"] == scenario]
        rows = at_scenario_dt(sub)
        rows = rows[(rows["engine"] != "exact") & ~rows["status"].isin(NOT_RUN)]
        cells = {}
        for g in group_rows(rows):
            cells.setdefault(g.first["family"], []).append(g)
        out.append({"scenario": scenario, **scenario_info(sub), "cells": cells})
    return out


def cost_of(row) -> float:
    """The cost ranked by: the time spent inside the engine's own calls (engine_time_s), so
    that no ratio measures the suite's glue; the wall time where an engine reports none."""
    t = _num(row.get("engine_time_s"))
    return t if t > 0 else _num(row.get("wall_time_s"))


def work_precision(sub, levels=ACCURACY_LEVELS) -> list[dict]:
    """For each level of max attitude error: every configuration (engine, integrator) that
    reaches it with its cheapest such run (fixed steps and error-controlled points alike),
    cheapest first, with the cost ratio to the cheapest (by engine time; wall times given as
    figures). An error below the reference's accuracy does not reach a level below that
    accuracy: it is not a measurement."""
    ok = sub[(sub["status"] == "ok") & (sub["engine"] != "exact")]
    out = []
    for level in levels:
        best = {}
        for r in records(ok):
            err = _num(r["attitude_error_max"])
            acc = _num(r["reference_accuracy"])
            reached = max(err, 0.0 if math.isnan(acc) else acc)
            cost = cost_of(r)
            if not (reached <= level) or not (cost > 0):
                continue
            key = (r["engine"], r["integrator"])
            if key not in best or cost < cost_of(best[key]):
                best[key] = r
        ranked = sorted(best.values(), key=cost_of)
        entries = []
        for r in ranked:
            entries.append(
                {
                    "configuration": config_label(r, with_step=True),
                    "engine": r["engine"],
                    "integrator": r["integrator"],
                    "suite_integrated": truthy(r["suite_integrated"]),
                    "dt": float(r["dt"]),
                    "target_accuracy": _num(r["target_accuracy"]),
                    "attitude_error_max": _num(r["attitude_error_max"]),
                    "engine_time_s": _num(r["engine_time_s"]),
                    "wall_time_s": _num(r["wall_time_s"]),
                    "cost_ratio": cost_of(r) / cost_of(ranked[0]),
                }
            )
        out.append({"level": level, "ranked": entries})
    return out


@dataclass
class SweepGroup:
    """Configurations (engine, integrator) of one scenario and family whose outcome and
    attitude error agree at every dt of their sweep (:func:`sweep_groups`)."""

    configs: list = field(default_factory=list)  # one {dt: row} per configuration
    max_rel_diff: float = 0.0

    @property
    def dts(self) -> list[float]:
        return sorted(self.configs[0])

    @property
    def members(self) -> list[dict]:
        """One row per configuration (at its smallest dt)."""
        return [c[min(c)] for c in self.configs]

    @property
    def first(self) -> dict:
        return self.members[0]

    def at(self, dt: float) -> Group:
        return Group([c[dt] for c in self.configs], self.max_rel_diff)


def sweep_groups(sub, rtol: float = COLLAPSE_RTOL) -> list[SweepGroup]:
    """The fixed-step configurations of one scenario, grouped within each family when their
    status, verdict, attitude error and divergence time agree at every dt (the error to
    ``rtol``, or both below its round-off floor); in family and engine order."""
    fixed = sub[sub["target_accuracy"].isna() & (sub["engine"] != "exact")]
    configs = {}
    for r in records(fixed):
        configs.setdefault((r["engine"], r["integrator"]), {})[float(r["dt"])] = r
    order = sorted(
        configs.values(),
        key=lambda c: (
            family_key(_any(c)["family"]),
            engine_key(_any(c)["engine"]),
            _any(c)["integrator"],
        ),
    )
    out: list[SweepGroup] = []
    for by_dt in order:
        for g in out:
            head = g.configs[0]
            if _any(head)["family"] != _any(by_dt)["family"] or set(head) != set(by_dt):
                continue
            diffs = [_point_difference(head[h], by_dt[h]) for h in by_dt]
            if max(diffs) <= rtol:
                g.configs.append(by_dt)
                g.max_rel_diff = max(g.max_rel_diff, max(diffs))
                break
        else:
            out.append(SweepGroup([by_dt]))
    return out


def _any(by_dt: dict) -> dict:
    return next(iter(by_dt.values()))


def _point_difference(a, b) -> float:
    if (a["status"], a["verdict"]) != (b["status"], b["verdict"]):
        return math.inf
    floor = FLOORS["attitude_error_max"]
    return max(
        rel_diff(a["attitude_error_max"], b["attitude_error_max"], floor),
        rel_diff(a["t_diverged"], b["t_diverged"]),
    )


def is_failure(row) -> bool:
    return row["verdict"] == "fail" or row["status"] in (
        "diverged",
        "error",
        "reference-inaccurate",
    )


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
                        "target_accuracy": _num(acc),
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
        for (e, i, s, m), scs in sorted(out.items(), key=lambda kv: engine_key(kv[0][0]))
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
            text = v if isinstance(v, str) else json.dumps(v)
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
    out.sort(key=lambda e: (engine_key(e["engine"]), e["integrator"], e["setting"]))
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
    return first.split(": ", 1)[-1]


def _setting(v) -> str:
    """A setting's value as it was given (``0.02``, ``1e-09``), not rounded like a metric."""
    return f"{v:g}" if isinstance(v, float | int) and not isinstance(v, bool) else str(v)


def _value_key(text: str):
    try:
        return (0, float(text), "")
    except ValueError:
        return (1, 0.0, text)


def energy_momentum_rows(df):
    return df[(df["integrator"] == ENERGY_MOMENTUM) & (df["engine"] == "director")]


# -- summary.json -------------------------------------------------------------------------------

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


def _json_value(v):
    """NaN and None -> null, +-inf -> "inf"/"-inf" (JSON has no infinities), numpy -> Python."""
    if isinstance(v, bool | np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        f = float(v)
        if math.isnan(f):
            return None
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return f
    if v is None:
        return None
    return v


def _group_json(g: Group) -> dict:
    fr = g.figure_row()
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
        "attitude_error_max": _json_value(fr["attitude_error_max"]),
        "attitude_below_reference_accuracy": bool(
            fr["attitude_error_max"] < fr["reference_accuracy"]
        ),
        "reference_accuracy": _json_value(fr["reference_accuracy"]),
        "energy_drift_max": _json_value(fr["energy_drift_max"]),
        "t_diverged": _json_value(fr["t_diverged"]),
        "max_rel_diff": _json_value(g.max_rel_diff),
    }


def summary(df, prov: dict | None = None) -> dict:
    """The content of summary.json (documented in docs/results.md)."""
    from reports import __version__

    card = []
    for s in scorecard(df):
        card.append(
            {
                "scenario": s["scenario"],
                "dt": s["dt"],
                "t_end": s["t_end"],
                "reference_kind": s["reference_kind"],
                "reference_accuracy": _json_value(s["reference_accuracy"]),
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
                "ranked": [{k: _json_value(v) for k, v in e.items()} for e in lv["ranked"]],
            }
            for lv in work_precision(df[df["scenario"] == scenario])
        ]
    runs = [{k: _json_value(r.get(k)) for k in RUN_FIELDS} for r in records(df)]
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


def write_summary(root: str | Path, df, prov: dict | None = None) -> Path:
    """Write ``summary.json`` into the results folder (atomically)."""
    import os

    root = Path(root)
    path = root / "summary.json"
    tmp = path.with_name(f".summary.json.{os.getpid()}.tmp")
    text = json.dumps(summary(df, prov), indent=1, allow_nan=False)
    tmp.write_text(text + "\n")
    tmp.replace(path)
    return path


# -- the README block ---------------------------------------------------------------------------


def md_cell(text) -> str:
    """Text safe in a GitHub-flavoured Markdown table cell or paragraph, shown as it is:
    backslashes, pipes and backticks escaped, ``&`` and ``<`` as entities (so ``<1e-12`` is
    not read as a tag, nor ``&lt;`` as a character), one line (newlines would end the row)."""
    text = " ".join(str(text).split())
    text = text.replace("\\", "\\\\").replace("|", "\\|").replace("`", "\\`")
    return text.replace("&", "&amp;").replace("<", "&lt;")


def md_table(header, rows) -> str:
    lines = ["| " + " | ".join(md_cell(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(md_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def readme_block(df, level: float = 1e-8, scenarios=None, families=None, command: str = "") -> str:
    """The README's "What it shows" as Markdown: the scorecard of ``df`` as one table (one
    row per group of configurations at each scenario's dt) and, per scenario, the cheapest
    configuration reaching ``level`` rad with the next ones' cost ratios; ``scenarios`` and
    ``families`` (lists of names, None: all) select what the README shows."""
    if scenarios:
        unknown = sorted(set(scenarios) - set(df["scenario"]))
        if unknown:
            raise ValueError(f"--scenarios: {', '.join(unknown)} not in the results")
        df = df[df["scenario"].isin(scenarios)]
    rows = []
    for s in scorecard(df):
        for fam in sorted(s["cells"], key=family_key):
            if families and fam not in families:
                continue
            for g in s["cells"][fam]:
                fr = g.figure_row()
                figure, energy = fmt_attitude(fr), fmt(fr["energy_drift_max"])
                verdict = g.outcome
                if verdict == "diverged":  # its figures are those of the part before
                    verdict = f"diverged at t = {fmt(fr['t_diverged'])} s"
                    figure = energy = "-"
                elif verdict == "fail":
                    names = failed_metrics(g.first["verdict_detail"])
                    verdict = f"fail ({', '.join(METRIC_SHORT.get(m, m) for m in names)})"
                rows.append(
                    [
                        f"{s['scenario']} (dt {fmt_step(s['dt'])} s, {fmt_step(s['t_end'])} s)",
                        fam,
                        g.label,
                        verdict,
                        energy,
                        figure,
                    ]
                )
    header = [
        "scenario",
        "integrator family",
        "configurations",
        "verdict",
        "energy drift",
        "attitude error [rad]",
    ]
    out = [
        "From the default suite (`results/report.md`; each scenario at its own dt; generated by "
        f"`{command or 'python -m reports.report.summary results --readme'}`):",
        "",
        md_table(header, rows),
        f"Work precision: the cheapest configuration reaching a max attitude error of "
        f"{fmt_level(level)} rad, ranked by the time inside the engine (the cost ratios of the "
        "next ones by the same measure; `+ suite`: the time loop is the suite's Python around "
        "the engine's dynamics):",
        "",
    ]
    for scenario in scenarios_of(df):
        (lv,) = work_precision(df[df["scenario"] == scenario], levels=(level,))
        ranked = lv["ranked"]
        if not ranked:
            out.append(f"- {scenario}: none of the runs")
            continue
        first = ranked[0]
        nxt = ", ".join(f"{e['configuration']} x{fmt(e['cost_ratio'])}" for e in ranked[1:4])
        out.append(
            f"- {scenario}: {first['configuration']} "
            f"({fmt(first['engine_time_s'])} s in the engine, {fmt(first['wall_time_s'])} s wall)"
            + (f"; then {nxt}" if nxt else "")
        )
    return "\n".join(out) + "\n"


def main(argv=None) -> int:
    import argparse
    import sys

    from reports.store.provenance import read_provenance
    from reports.store.results import read_results

    p = argparse.ArgumentParser(
        prog="python -m reports.report.summary",
        description="Write summary.json of a results folder, or print the README block.",
    )
    p.add_argument("dir")
    p.add_argument("--readme", action="store_true", help="print the README's Markdown block")
    p.add_argument(
        "--level", type=float, default=1e-8, help="work-precision level of the README block"
    )
    p.add_argument("--scenarios", help="README block: comma-separated scenarios (default all)")
    p.add_argument("--families", help="README block: comma-separated families (default all)")
    args = p.parse_args(argv)

    def names(text):
        return [t.strip() for t in text.split(",") if t.strip()] if text else None

    try:
        df = read_results(args.dir)
        if args.readme:
            cmd = "python -m reports.report.summary results --readme" + "".join(
                f' --{k} "{v}"'
                for k, v in (("scenarios", args.scenarios), ("families", args.families))
                if v
            )
            block = readme_block(
                df, args.level, names(args.scenarios), names(args.families), command=cmd
            )
    except (FileNotFoundError, ValueError) as exc:
        print(f"python -m reports.report.summary: error: {exc}", file=sys.stderr)
        return 2
    if args.readme:
        sys.stdout.write(block)
    else:
        print(write_summary(args.dir, df, read_provenance(Path(args.dir))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
