"""How the report names and orders what it shows: integrator families and engines in table
order, a configuration's label, a run's outcome in one word, the metrics' short names in
verdict texts, the error a run is summed up by (:func:`headline`: the attitude error, a
contact scene's position error), the attitude error and fitted order as table cells, a
figure's axis label with the value of the scale its quantity is divided by.
"""

from __future__ import annotations

import math

from reports.metrics.catalog import HEADLINE, HEADLINE_ENERGY, METRIC_SHORT, METRIC_UNITS
from reports.store.format import fmt, fmt_cost, fmt_level, fmt_step, num, truthy
from reports.store.results import is_reference_record, reference_rows

#: integrator families in the order tables and the scorecard show them; the reference's
#: family follows them, then the others, sorted
FAMILY_ORDER = (
    "structure-preserving director",
    "4th-order Lie-group",
    "implicit gyroscopic",
    "semi-implicit Euler",
)

#: the column of the report's table holding each run's engine's place in the engine order of
#: its results folder (:func:`with_engine_order`, :func:`engine_key`)
ENGINE_RANK = "engine_rank"

#: statuses that are not a result of the configuration (nothing ran, or could not)
NOT_RUN = ("unsupported", "unavailable")


def family_key(fam: str, reference: bool = False) -> tuple:
    """The sort key of an integrator family (``reference``: the reference's family)."""
    return _order_key(FAMILY_ORDER, fam, reference)


def engine_order(prov: dict, engines=()) -> list[str]:
    """The engines in the order the report lists them: as the results folder's provenance
    (``prov``, its ``engines``) lists them, which is the order of the registry of the
    installation that ran them (:mod:`references.engines`: the built-in engines, then the
    plug-ins), when it names every one of ``engines``; else this installation's registry,
    then the provenance's other names in its order."""
    listed = prov.get("engines") if isinstance(prov, dict) else None
    listed = [str(e) for e in listed] if isinstance(listed, dict) else []
    if listed and set(engines) <= set(listed):
        return listed
    from references.engines import engine_names

    registry = engine_names()
    return registry + [e for e in listed if e not in registry]


def with_engine_order(df, prov: dict):
    """The results table ``df`` with the column :data:`ENGINE_RANK`: each run's engine's place
    in :func:`engine_order` (names it does not hold: one place after the last), so that every
    table and figure drawn from the table, in this process or a worker's, orders the engines
    alike, and a figure's reuse key (its rows) changes with the order its colours follow."""
    order = engine_order(prov, set(df["engine"]))
    place = {e: k for k, e in enumerate(order)}
    return df.assign(**{ENGINE_RANK: [place.get(e, len(order)) for e in df["engine"]]})


def engine_key(df):
    """The sort key of the engines of the results table ``df``, a function of an engine's
    name: the engines under test in the order of :data:`ENGINE_RANK` (a table without that
    column: this installation's registry, :func:`engine_order`), names the order does not
    hold after them, alphabetically; then the reference engines (:func:`reference_engines`)
    in the same order. Plots give out colours in this order."""
    refs = reference_engines(df)
    if ENGINE_RANK in df:
        place = dict(zip(df["engine"], df[ENGINE_RANK], strict=True))
    else:
        order = engine_order({}, ())
        place = {e: order.index(e) for e in set(df["engine"]) if e in order}
        place.update({e: len(order) for e in set(df["engine"]) - set(place)})

    def key(eng: str) -> tuple:
        return (eng in refs, place.get(eng, math.inf), eng)

    return key


def _order_key(order: tuple, name: str, reference: bool) -> tuple:
    if reference:
        return (len(order), "")
    return (order.index(name), "") if name in order else (len(order) + 1, name)


def reference_engines(df) -> set:
    """The engines of the reference rows of ``df`` (:func:`reference_rows`)."""
    return set(df.loc[reference_rows(df), "engine"])


def families_of(df) -> list[str]:
    refs = set(df.loc[reference_rows(df), "family"])
    return sorted({f for f in df["family"] if f}, key=lambda f: family_key(f, f in refs))


def reference_label(row) -> str:
    """What a reference run is: ``exact reference`` for a closed form, ``numerical reference``
    for one integrated to its error estimate (``reference_kind`` ``numerical``: DOP853), so
    that no table or legend calls an integration exact."""
    kind = row.get("reference_kind")
    return "numerical reference" if kind == "numerical" else "exact reference"


def config_label(row, with_step: bool = False) -> str:
    """``mujoco RK4``; a configuration whose time loop is the suite's own code around the
    engine's dynamics reads ``pinocchio + suite RKMK4`` (its wall time includes our Python);
    the suite's reference run reads as :func:`reference_label` says.
    ``with_step``: the step (``dt 2e-3``) or, for an error-controlled integrator, its target
    accuracy (``tol 1e-8``)."""
    if is_reference_record(row):
        return reference_label(row)
    text = f"{row['engine']}{suite_sep(row)}{row['integrator']}"
    if on_cpu_alone(row):
        text += " (one instance, CPU)"
    acc = num(row.get("target_accuracy"))
    if not math.isnan(acc):
        text += f" tol {fmt_level(acc)}"
    elif with_step:
        text += f" dt {fmt_step(row['dt'])} s"
    return text


def suite_sep(row) -> str:
    """What goes between a configuration's engine and its integrator: `` + suite `` where
    its time loop is the suite's own code, unless the integrator's name says so already
    (Pinocchio's contact configurations, ``ADMM + suite``), else a space."""
    integ = str(row.get("integrator", ""))
    return " + suite " if truthy(row.get("suite_integrated")) and "+ suite" not in integ else " "


def on_cpu_alone(row) -> bool:
    """Whether the run stepped one instance of a batched accelerator engine on the CPU (MJX
    records its JAX device in its settings): not how such an engine is meant to run, which
    its label says."""
    text = row.get("settings")
    return isinstance(text, str) and '"device": "cpu"' in text


def scaled_label(label: str, rows, scale_col: str | None, unit: str) -> str:
    """An axis label of a quantity divided by a scale, with that scale's value on a second
    line from the rows' ``scale_col`` (``|E − E₀| / E_c [1]`` then ``E_c = 5.41 J``); the
    label alone when there is no such column or no value in it."""
    if not scale_col or scale_col not in rows or not rows[scale_col].notna().any():
        return label
    scale = float(rows[scale_col].dropna().iloc[0])
    sym = label.split("/")[-1].split("[")[0].strip()
    return f"{label}\n{sym} = {fmt(scale)} {unit}"


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


def is_failure(row) -> bool:
    return row["verdict"] == "fail" or row["status"] in (
        "diverged",
        "error",
        "reference-inaccurate",
    )


def fmt_attitude(row) -> str:
    """The attitude error, or ``< acc`` (the reference's accuracy) when it is below what the
    reference can measure."""
    return fmt_error(row.get("attitude_error_max"), row.get("reference_accuracy"))


def fmt_error(value, accuracy) -> str:
    """An error against the reference, or ``< acc`` when it is below the reference's
    ``accuracy`` (what the reference can measure)."""
    v, acc = num(value), num(accuracy)
    if not math.isnan(v) and not math.isnan(acc) and v < acc:
        return f"< {fmt(acc)}"
    return fmt(v)


def headline(row) -> tuple[str, str, str]:
    """(column, unit, short name) of the error a run is summed up by wherever it is one
    number (the scorecard, the short verdict tables, summary.json, the work-precision
    answers): the metric catalog's for the run's scene kind
    (:data:`reports.metrics.catalog.HEADLINE`, the row's ``scene_kind``): the max attitude
    error (rad) of a body or a system, the largest position error against the closed form
    (m) of a contact scene."""
    name = HEADLINE[_kind(row)]
    return name, METRIC_UNITS[name], METRIC_SHORT.get(name, name)


def energy_headline(row) -> str:
    """The column of the energy error shown beside the :func:`headline` error, in E_c: the
    energy drift of a body or a system, the energy gained by a contact scene (exact <= 0;
    its drift is not measured: contact takes energy away)."""
    return HEADLINE_ENERGY[_kind(row)]


def _kind(row) -> str:
    """The scene kind recorded in the row (``scene_kind``), ``body`` where it holds none."""
    kind = row.get("scene_kind")
    return kind if isinstance(kind, str) and kind in HEADLINE else "body"


def fmt_headline(row) -> str:
    """The run's :func:`headline` error as a cell (``< acc`` below the reference's
    accuracy), without its unit."""
    return fmt_error(row.get(headline(row)[0]), row.get("reference_accuracy"))


def fmt_joint_angle(row) -> str | None:
    """The largest joint angle error against the reference (a system of bodies with joints:
    a robot model, a chain), ``< acc`` below the reference's accuracy as for the attitude;
    None where the run measured none (a single body, a failed run)."""
    v = num(row.get("joint_coordinate_error_max"))
    if math.isnan(v):
        return None
    acc = num(row.get("reference_accuracy"))
    if not math.isnan(acc) and v < acc:
        return f"< {fmt(acc)}"
    return fmt(v)


def fmt_order(row) -> str:
    """The fitted convergence order with the number of points of the fit, ``-`` if none."""
    o = num(row.get("convergence_order"))
    if math.isnan(o):
        return "-"
    n = num(row.get("convergence_points"))
    return fmt(o) if math.isnan(n) else f"{fmt(o)} ({int(n)} pts)"


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
    figs = [f"{fmt_headline(fr)} {headline(fr)[1]}", f"E {fmt(fr[energy_headline(fr)])}"]
    if (q := fmt_joint_angle(fr)) is not None:  # a system of bodies with joints
        figs.insert(1, f"q {q} rad")
    failing = ""
    if out == "fail":
        names = [METRIC_SHORT.get(m, m) for m in failed_metrics(g.first["verdict_detail"])]
        failing = ", ".join(names)
    return out, who, figs, failing
