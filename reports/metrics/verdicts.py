"""Verdicts: whether a run tells the truth about its scenario to within tolerances.

A completed run is not a correct one. Beside its ``status`` (did it complete, and can its
numbers be trusted) every run gets a ``verdict``: ``pass`` when every bounded metric is within
its tolerance, ``fail`` otherwise (a diverged run always fails), empty when there is nothing to
judge (the run did not produce numbers: error, unsupported, unavailable, or its reference is
not accurate enough to judge by).

Tolerances come from, in increasing precedence:

1. :data:`DEFAULT_TOLERANCES` (each metric's ``tolerance`` in the metric catalog), shared by
   every integrator family: a configuration that gets the motion right to 0.1 rad of
   attitude, 1 % of the energy scales (the total, and a free body's rotational and
   translational energy each against its own) and of the momentum scale, 1 % on the flip
   interval and nutation period, and keeps R orthonormal to 1e-9;
2. the family's own (:class:`references.engines.Family` ``tolerances``: a family that
   promises more is held to it, e.g. the director schemes keep R orthonormal to round-off),
   then the integrator's own (:class:`references.engines.Integrator` ``tolerances``, e.g.
   RATTLE conserves angular momentum to round-off);
3. the scenario file's ``[tolerances]`` table (all families), then its
   ``[tolerances."<family>"]`` sub-table (docs/scenarios.md).

A reference whose accuracy estimate is not at least :data:`REFERENCE_MARGIN` times below the
attitude tolerance cannot decide a verdict: such runs get the status
``reference-inaccurate``, with the figure, instead of numbers that look like measurements.
"""

from __future__ import annotations

import math

from reports.metrics import catalog

#: Default verdict bounds, every family (metric -> largest value that passes), from the metric
#: catalog (:data:`reports.metrics.catalog.DEFAULT_TOLERANCES`; scenarios.metric_catalog says
#: where each bound comes from)
DEFAULT_TOLERANCES = catalog.DEFAULT_TOLERANCES

#: the reference must be this many times more accurate than the attitude tolerance
REFERENCE_MARGIN = 10.0


def tolerances(scenario, integrator) -> dict[str, float]:
    """The verdict bounds of a run of ``scenario`` by ``integrator`` (an
    :class:`references.engines.Integrator`)."""
    from references.engines import FAMILIES

    family = integrator.family
    out = dict(DEFAULT_TOLERANCES)
    fam = FAMILIES.get(family)
    if fam is not None:
        out.update(fam.tolerances)
    out.update(integrator.tolerances)
    file_tol = getattr(scenario, "tolerances", {}) or {}
    out.update(file_tol.get("*", {}))
    out.update(file_tol.get(family, {}))
    return out


def unknown_families(scenario) -> list[str]:
    """Families named in the scenario's ``[tolerances]`` table that no engine registers.
    An adapter registers its families when it is imported, so a name not yet registered is
    looked for again after every registered adapter is loaded (whichever engines this run
    selected: a file is valid or not on its own)."""
    from references.engines import FAMILIES, engine_names, get_engine

    named = [f for f in (getattr(scenario, "tolerances", {}) or {}) if f != "*"]
    if any(f not in FAMILIES for f in named):
        for name in engine_names():
            get_engine(name)  # importing an adapter never imports its engine
    return [f for f in named if f not in FAMILIES]


def reference_problem(reference_accuracy: float, bounds: dict[str, float]) -> str | None:
    """The reason a reference cannot judge a run, or None."""
    tol = bounds.get("attitude_error_max")
    if tol is None:
        return None
    if not (reference_accuracy <= tol / REFERENCE_MARGIN):
        return (
            f"the reference's accuracy estimate {reference_accuracy:.3g} rad is not "
            f"{REFERENCE_MARGIN:g}x below the attitude tolerance {tol:g} rad, so its errors "
            "cannot be told from the reference's"
        )
    return None


def judge(row: dict, scenario, integrator, diverged=None) -> None:
    """Set the status and the verdict of a run that produced an output, whatever its scene's
    kind: ``diverged`` (the engine's :class:`references.engines.Diverged`, or None) makes it
    ``diverged`` at its time; a reference the row names (``reference_kind``) whose accuracy
    estimate cannot decide the verdict (:func:`reference_problem`) makes it
    ``reference-inaccurate``, with that reason unless the row already says one; a row with no
    reference (``reference_kind`` "none": a system or contact scene that none applies to, its
    message says why) is ``ok`` and judged on what is measured without one (invariants, joints,
    contact laws). Then :func:`verdict` against the run's :func:`tolerances`."""
    bounds = tolerances(scenario, integrator)
    if diverged is not None:
        row["status"] = "diverged"
        row["t_diverged"] = diverged.t_diverged
        row["message"] = str(diverged)
    else:
        why = None
        if row["reference_kind"] not in ("", "none"):
            why = reference_problem(row["reference_accuracy"], bounds)
        if why is not None:
            row["status"] = "reference-inaccurate"
            row["message"] = row["message"] or f"{why} (reference: {row['reference_kind']})"
        else:
            row["status"] = "ok"
    row["verdict"], row["verdict_detail"] = verdict(row, bounds)


def verdict(row: dict, bounds: dict[str, float]) -> tuple[str, str]:
    """(verdict, detail) of a result row: "pass"/"fail" with the metrics out of bounds, or
    ("", "") when the row has nothing to judge."""
    status = row.get("status")
    if status == "diverged":
        return "fail", f"diverged at t = {row.get('t_diverged', math.nan):.6g} s"
    if status != "ok":
        return "", ""
    over = []
    for metric, bound in bounds.items():
        value = row.get(metric, math.nan)
        if value is None or (isinstance(value, float) and math.isnan(value)):
            continue
        if not value <= bound:
            over.append(f"{metric} {value:.3g} > {bound:.3g}")
    return ("fail", "; ".join(over)) if over else ("pass", "")
