"""Grouping the rows of a table: engines that run the same algorithm (one integrator family)
give the same numbers to round-off. Rows of one scenario, step (or target accuracy) and family
whose status and verdict match and whose every metric agrees to :data:`COLLAPSE_RTOL`
(relative) are one *group*: one row in every table, listing its configurations, with the
largest relative difference between them. Two values that are both at or below the metric's
round-off floor (:data:`reports.metrics.body.FLOORS`) agree whatever their ratio: 3e-16 against
9e-15 is round-off. A sweep group (:func:`sweep_groups`) is the same over every dt of a
fixed-step sweep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from reports.metrics.catalog import FLOORS, HIGHER_IS_BETTER, METRIC_COLUMNS
from reports.report.labels import config_label, engine_key, family_key, outcome
from reports.store.format import num
from reports.store.results import is_reference_record, records, reference_rows

#: rows whose every metric agrees to this relative difference are one group: their figures
#: printed to three significant digits would differ by at most one unit in the last digit
COLLAPSE_RTOL = 1e-3

#: the metrics a group's members must agree on (with the status, verdict and t_diverged)
GROUP_METRICS = tuple(m for m in METRIC_COLUMNS if m != "convergence_order")


def rel_diff(a: float, b: float, floor: float = 0.0) -> float:
    """Relative difference of two metric values, 0 when both are at or below ``floor``."""
    a, b = num(a), num(b)
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
        vals = [num(r.get(metric)) for r in self.rows]
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
        return [num(r.get(column)) for r in self.rows]


def _sorted_records(df) -> list[dict]:
    recs = records(df)
    engine = engine_key(df)

    def key(r):
        ref = is_reference_record(r)
        return (family_key(r["family"], ref), engine(r["engine"]), r["integrator"])

    return sorted(recs, key=key)


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
            if is_reference_record(f) or is_reference_record(rec):
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
    x, y = num(a.get("target_accuracy")), num(b.get("target_accuracy"))
    return (math.isnan(x) and math.isnan(y)) or x == y


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
    fixed = sub[sub["target_accuracy"].isna() & ~reference_rows(sub)]
    configs = {}
    for r in records(fixed):
        configs.setdefault((r["engine"], r["integrator"]), {})[float(r["dt"])] = r
    engine = engine_key(sub)
    order = sorted(
        configs.values(),
        key=lambda c: (
            family_key(_any(c)["family"]),
            engine(_any(c)["engine"]),
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
