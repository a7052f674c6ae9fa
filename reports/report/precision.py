"""What the work-precision answers say about a configuration that did not reach a level:
whether it was *not tried* there (its error was still falling with the step at the smallest
step the suite ran it at, so a smaller one would reach the level) or it *does not reach* it
(no run finished, or its error stopped falling: a floor), and the cost each answer is
ranked by (:func:`cost_of`).

Every configuration of a scenario runs the same steps (the scenario's sweep), so "not tried"
says where the sweep ended, never that one configuration was given fewer steps than another.
"""

from __future__ import annotations

import math

from reports.report.labels import headline
from reports.store.format import num, truthy

#: the error must have fallen by at least this factor over the last halving of the step for
#: the configuration to count as still converging (an order of at least 0.5)
STILL_FALLING = 2**0.5


def cost_of(row) -> float:
    """The cost a configuration's run is ranked by: the CPU time inside the engine's calls
    (``engine_time_s``), so that no ratio measures the suite's glue; for a configuration
    whose time loop is the suite's own code around the engine (``+ suite``), the CPU time of
    the whole step (``cpu_time_s``): what its user pays. The wall time where a row has
    neither (a folder written before)."""
    whole = num(row.get("cpu_time_s"))
    if truthy(row.get("suite_integrated")) and whole > 0:
        return whole
    t = num(row.get("engine_time_s"))
    return t if t > 0 else num(row.get("wall_time_s"))


def measure_of(row) -> tuple[str, str]:
    """(column, unit) of the error a run is ranked by: the error it is summed up by
    everywhere (:func:`reports.report.labels.headline`, by the row's recorded scene kind):
    for a contact scene the largest position error against its closed form (m: a block's
    attitude hardly changes whether it holds, creeps or slides, its position tells them
    apart), else the max attitude error (rad)."""
    return headline(row)[:2]


def error_of(row) -> float:
    """The error (:func:`measure_of`) a run can be credited with: not below the reference's
    accuracy (an error below it is not a measurement; a contact closed form's row records
    its attitude accuracy, of the size of its position accuracy: 16 eps times the scene's
    positions, or a DOP853 estimate times a reach under 1 m)."""
    err, acc = num(row.get(measure_of(row)[0])), num(row.get("reference_accuracy"))
    return max(err, 0.0 if math.isnan(acc) else acc)


def outlook(rows: list[dict], level: float) -> tuple[str, object]:
    """The answer of one configuration (its ``rows``: the runs of one engine and integrator
    on one scenario) at one ``level`` of its error (:func:`measure_of`, in its unit):

    - ``("reached", row)``: its cheapest run within the level;
    - ``("not tried", text)``: no run within it, but its error was still falling at its
      smallest step (by :data:`STILL_FALLING` or more over the last halving; an
      error-controlled integrator: at its tightest target); ``text`` says where it stood and,
      from the order over that halving, about what step would reach the level;
    - ``("does not reach", text)``: no run finished, or its error stopped falling (``text``
      says which and the best error).
    """
    ok = [r for r in rows if r.get("status") == "ok" and math.isfinite(error_of(r))]
    unit = measure_of(rows[0])[1] if rows else "rad"
    within = [r for r in ok if error_of(r) <= level]
    if within:
        return "reached", min(within, key=cost_of)
    if not ok:
        return "does not reach", "no run finished"
    adaptive = any(not math.isnan(num(r.get("target_accuracy"))) for r in ok)
    by = "target_accuracy" if adaptive else "dt"
    ok.sort(key=lambda r: num(r.get(by)), reverse=True)  # coarsest first
    last = ok[-1]
    best = min(error_of(r) for r in ok)
    finest = min(num(r.get(by)) for r in rows)  # the finest the configuration ran at all
    where = (
        f"tol {_short(num(last['target_accuracy']))}"
        if adaptive
        else f"dt {_short(num(last['dt']))}"
    )
    if num(last.get(by)) > finest:  # its finest run did not finish
        return "does not reach", f"best {_short(best)} {unit}; diverged below {where}"
    if len(ok) < 2:
        return "not tried", f"{_short(error_of(last))} {unit} at {where}, its only finished run"
    prev = ok[-2]
    fall = error_of(prev) / error_of(last) if error_of(last) > 0 else math.inf
    if fall >= STILL_FALLING:
        if adaptive:
            return "not tried", f"{_short(error_of(last))} {unit} at {where}, still falling"
        ratio = num(prev["dt"]) / num(last["dt"])
        order = math.log(fall) / math.log(ratio) if ratio > 1 else math.nan
        need = num(last["dt"]) * (level / error_of(last)) ** (1.0 / order) if order > 0 else 0
        about = f"; about dt {_short(need)} would" if need > 0 else ""
        return "not tried", f"{_short(error_of(last))} {unit} at {where}{about}"
    return "does not reach", f"stalls at {_short(best)} {unit}"


def _short(v: float) -> str:
    """A value in two significant digits (``2.5e-4``, ``0.012``)."""
    if not math.isfinite(v) or v == 0:
        return str(v)
    if 1e-3 <= abs(v) < 1e3:
        return f"{v:.2g}"
    mant, exp = f"{v:.1e}".split("e")
    return f"{mant.rstrip('0').rstrip('.')}e{int(exp)}"
