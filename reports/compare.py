"""Compare two result folders, run by run: ``director-bench compare A B``.

The runs of A and B are matched on their configuration (scenario, engine, integrator, dt,
target accuracy: :data:`reports.results.CONFIG_KEY`), whatever the engine versions, so two
folders made with two versions of an engine compare directly. For each run in both, every
metric and the cost get a ratio B/A and a word, as airspeed velocity's ``asv compare`` does:
``worse`` when B is more than ``factor`` times A, ``better`` when less than A / ``factor``,
``same`` otherwise. An error metric is compared above its round-off floor
(:data:`reports.gate.FLOORS`: ``max(value, floor)`` on both sides), so that 3e-16 against
9e-15 is ``same``, not a regression; the fitted convergence order is compared by difference
(:data:`reports.gate.ORDER_SLACK`). A status that got worse (ok to diverged or error) or a
verdict that went from pass to fail is ``worse`` whatever the numbers.

Exit code of the command: 1 when some run got worse in a metric, its status or its verdict;
the cost (ns per step inside the engine and wall) is reported but gates only with
``cost_factor`` (timings vary with the machine's load far more than the metrics do). Runs
found in only one folder are listed and do not gate.

This is not the CI gate (reports.gate): that compares a folder against a committed baseline
file; this compares two folders, e.g. two engine versions (docs/results.md has the recipe).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from reports.gate import FLOORS, ORDER_SLACK
from reports.metrics import HIGHER_IS_BETTER
from reports.results import METRIC_COLUMNS, config_key, read_results
from reports.summary import fmt, fmt_level, fmt_step, records

#: cost columns compared (ns per step: inside the engine's calls, and wall)
COST_COLUMNS = ("engine_ns_per_step", "ns_per_step")

#: statuses in order of how bad they are for a run that should have run
STATUS_RANK = {"ok": 0, "reference-inaccurate": 1, "diverged": 2, "error": 3}


@dataclass
class Change:
    key: tuple
    column: str  # a metric, a cost column, "status" or "verdict"
    a: object
    b: object
    ratio: float
    change: str  # "better", "worse", "same"
    gates: bool = False  # a "worse" that makes the command exit 1

    @property
    def worse(self) -> bool:
        return self.change == "worse"


@dataclass
class Comparison:
    a: Path
    b: Path
    factor: float
    cost_factor: float | None
    both: list = field(default_factory=list)
    only_a: list = field(default_factory=list)  # (key, status)
    only_b: list = field(default_factory=list)
    changes: list = field(default_factory=list)

    @property
    def regressions(self) -> list[Change]:
        return [c for c in self.changes if c.worse and c.gates]

    @property
    def ok(self) -> bool:
        return not self.regressions


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def classify(column: str, a: float, b: float, factor: float) -> tuple[float, str] | None:
    """(ratio B/A, better/worse/same) of one metric or cost, or None when neither side has a
    value. A value on one side only: ``worse`` if B lost it, ``same`` if B gained it."""
    a, b = _num(a), _num(b)
    if math.isnan(a) and math.isnan(b):
        return None
    if math.isnan(b):
        return math.nan, "worse"
    if math.isnan(a):
        return math.nan, "same"
    if column in HIGHER_IS_BETTER:
        ratio = b / a if a else math.nan
        if b < a - ORDER_SLACK:
            return ratio, "worse"
        return ratio, ("better" if b > a + ORDER_SLACK else "same")
    floor = FLOORS.get(column, 0.0)
    ea, eb = max(a, floor), max(b, floor)
    if ea == eb:
        return 1.0, "same"
    if ea == 0:
        return math.inf, "worse"
    ratio = eb / ea
    if ratio > factor:
        return ratio, "worse"
    return ratio, ("better" if ratio < 1.0 / factor else "same")


def _by_key(df) -> dict:
    return {
        config_key(r["scenario"], r["engine"], r["integrator"], r["dt"], r["target_accuracy"]): r
        for r in records(df)
    }


def compare_folders(
    a: str | Path, b: str | Path, factor: float = 2.0, cost_factor: float | None = None
) -> Comparison:
    """Compare the results of folders ``a`` and ``b`` (see the module docstring); a folder
    without a results store is a FileNotFoundError naming it."""
    if not factor >= 1.0:
        raise ValueError(f"--factor {factor!r}: must be a number >= 1")
    if cost_factor is not None and not cost_factor >= 1.0:
        raise ValueError(f"--cost-factor {cost_factor!r}: must be a number >= 1")
    ra, rb = _by_key(read_results(a)), _by_key(read_results(b))
    cmp = Comparison(Path(a), Path(b), factor, cost_factor)
    cmp.only_a = [(k, ra[k]["status"]) for k in sorted(ra, key=_sort_key) if k not in rb]
    cmp.only_b = [(k, rb[k]["status"]) for k in sorted(rb, key=_sort_key) if k not in ra]
    for key in sorted(set(ra) & set(rb), key=_sort_key):
        cmp.both.append(key)
        x, y = ra[key], rb[key]
        cmp.changes += _run_changes(key, x, y, factor, cost_factor)
    return cmp


def _sort_key(key):
    sc, eng, integ, dt, acc = key
    return (sc, eng, integ, dt, -1.0 if acc is None else acc)


def _run_changes(key, x, y, factor, cost_factor) -> list[Change]:
    out = []
    sx, sy = x["status"], y["status"]
    if sx != sy:
        rx, ry = STATUS_RANK.get(sx), STATUS_RANK.get(sy)
        if rx is None or ry is None:  # unsupported / unavailable: the environment, not a result
            out.append(Change(key, "status", sx, sy, math.nan, "same"))
        else:
            change = "worse" if ry > rx else "better"
            out.append(Change(key, "status", sx, sy, math.nan, change, gates=True))
        return out
    if sx != "ok":
        return out
    if x["verdict"] != y["verdict"] and {x["verdict"], y["verdict"]} == {"pass", "fail"}:
        change = "worse" if y["verdict"] == "fail" else "better"
        out.append(Change(key, "verdict", x["verdict"], y["verdict"], math.nan, change, True))
    for m in METRIC_COLUMNS:
        got = classify(m, x[m], y[m], factor)
        if got is not None:
            out.append(Change(key, m, _num(x[m]), _num(y[m]), got[0], got[1], gates=True))
    for c in COST_COLUMNS:
        got = classify(c, x[c], y[c], cost_factor or factor)
        if got is not None:
            gates = cost_factor is not None
            out.append(Change(key, c, _num(x[c]), _num(y[c]), got[0], got[1], gates=gates))
    return out


def _run_name(key) -> str:
    sc, eng, integ, dt, acc = key
    step = f"tol {fmt_level(acc)}" if acc is not None else f"dt {fmt_step(dt)}"
    return f"{sc} {eng} {integ} {step}"


def _value(v) -> str:
    return v if isinstance(v, str) else fmt(v)


def format_comparison(cmp: Comparison, show_all: bool = False) -> str:
    """The comparison as text: a summary line, then every change that is not ``same``
    (every change with ``show_all``), worse first, then the runs in one folder only."""
    runs_worse = {c.key for c in cmp.changes if c.worse and c.gates}
    runs_better = {c.key for c in cmp.changes if c.change == "better"} - runs_worse
    cost_note = (
        f"cost gated at {cmp.cost_factor:g}x"
        if cmp.cost_factor is not None
        else "cost not gated (--cost-factor F to gate it)"
    )
    lines = [
        f"A: {cmp.a}",
        f"B: {cmp.b}",
        f"{len(cmp.both)} runs in both: {len(runs_worse)} worse, {len(runs_better)} better, "
        f"{len(cmp.both) - len(runs_worse) - len(runs_better)} the same within a factor "
        f"{cmp.factor:g} (above round-off floors; {cost_note}); {len(cmp.only_a)} only in A, "
        f"{len(cmp.only_b)} only in B.",
    ]
    order = {"worse": 0, "better": 1, "same": 2}
    shown = [c for c in cmp.changes if show_all or c.change != "same"]
    shown.sort(key=lambda c: (order[c.change], not c.gates, _sort_key(c.key), c.column))
    if shown:
        head = ["change", "run", "what", "A", "B", "B/A"]
        rows = []
        for c in shown:
            word = c.change + ("" if c.gates or c.change != "worse" else " (not gated)")
            ratio = "" if math.isnan(c.ratio) else fmt(c.ratio)
            rows.append([word, _run_name(c.key), c.column, _value(c.a), _value(c.b), ratio])
        lines += ["", *_text_table(head, rows)]
    for title, items in (("Only in A", cmp.only_a), ("Only in B", cmp.only_b)):
        if items:
            lines += ["", f"{title} ({len(items)}):"]
            lines += [f"  {_run_name(k)} ({status})" for k, status in items]
    lines.append("")
    lines.append(
        f"FAIL: {len(runs_worse)} run(s) got worse beyond a factor {cmp.factor:g}."
        if runs_worse
        else "OK: no run got worse."
    )
    return "\n".join(lines)


def _text_table(head, rows) -> list[str]:
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return out
