"""Compare two result folders, run by run: ``director-bench compare A B``.

The runs of A and B are matched on their configuration (scenario, engine, integrator, dt,
target accuracy: :data:`reports.store.results.CONFIG_KEY`) and must be the same run: a pair whose
identity differs (:data:`reports.store.results.IDENTITY_COLUMNS`: scenario content, horizon,
save_every, segmenting, engine and suite versions) is a ``mismatch`` naming each field
(``t_end 30 vs 10``), never compared as if it were the same run. To compare two engine
versions (or two suite versions) on purpose, name the field that may differ: ``--vary
engine_version`` (docs/results.md has the recipe).

For each run in both, every metric and the cost get a ratio B/A and a word, as airspeed
velocity's ``asv compare`` does: ``worse`` when B is more than ``factor`` times A, ``better``
when less than A / ``factor``, ``same`` otherwise. An error metric is compared above its
round-off floor (:data:`reports.metrics.body.FLOORS`: ``max(value, floor)`` on both sides), so that
3e-16 against 9e-15 is ``same``, not a regression; the fitted convergence order is compared
by difference (:data:`reports.metrics.body.ORDER_SLACK`). A status that got worse (ok to diverged or
error) or a verdict that went from pass to fail is ``worse`` whatever the numbers.

A cost (ns per step inside the engine and wall) is a range measured with the run
(reports.run.runner): from the fastest timed repeat scaled by the process's CPU time over the
wall time of its stepping (on a busy machine the process ran only that part of the wall
time) up to the slowest repeat. After asv's rule, a cost change is significant only when the
ratio of the fastest times exceeds the factor AND the ranges are that far apart (B's low end
over A's high end beyond the factor, for a slowdown); otherwise it is ``not significant``:
the noise measured with the runs could account for it. A change must also hold at every dt
of the configuration's sweep (:func:`_corroborate_costs`): the engine's own slowdown moves
every step size, a burst of load on the machine single runs.

Exit code of the command: 1 when some run got worse in a metric, its status or its verdict,
when a pair of runs is a mismatch, or when nothing is comparable (an empty folder, no run in
both); the cost gates only with ``cost_factor`` (timings vary with the machine's load far
more than the metrics do). Runs found in only one folder are listed and do not gate.

This is not the CI gate (reports.gate.check): that compares a folder against a committed baseline
file; this compares two folders, e.g. two engine versions (docs/results.md has the recipe).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from reports.gate.check import NothingComparable, md_escape
from reports.metrics.body import FLOORS, HIGHER_IS_BETTER, ORDER_SLACK
from reports.store.format import fmt, fmt_level, fmt_step
from reports.store.results import (
    IDENTITY_COLUMNS,
    METRIC_COLUMNS,
    config_key,
    identity_differences,
    read_results,
    records,
)
from scenarios.schema import InputError

#: cost columns compared (ns per step: inside the engine's calls, and wall), each with the
#: column of the slowest repeat's time that bounds its range
COST_COLUMNS = ("engine_ns_per_step", "ns_per_step")
COST_MAX = {"engine_ns_per_step": "engine_time_max_s", "ns_per_step": "wall_time_max_s"}

#: statuses in order of how bad they are for a run that should have run
STATUS_RANK = {"ok": 0, "reference-inaccurate": 1, "diverged": 2, "error": 3}


@dataclass
class Change:
    key: tuple
    column: str  # a metric, a cost column, "status", "verdict" or "identity"
    a: object
    b: object
    ratio: float
    change: str  # "better", "worse", "same", "not significant" or "mismatch"
    gates: bool = False  # a "worse" (or a mismatch) that makes the command exit 1

    @property
    def worse(self) -> bool:
        return self.change in ("worse", "mismatch")


@dataclass
class Comparison:
    a: Path
    b: Path
    factor: float
    cost_factor: float | None
    vary: tuple = ()
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


def classify_cost(a, b, factor: float) -> tuple[float, str] | None:
    """(ratio of the fastest times B/A, word) of a cost measured on each side as
    (fastest, low, high) (:func:`cost_range`; low and high NaN: the spread was not
    measured). After asv's rule (a change beyond the factor whose ranges do not overlap),
    taken at the ranges' nearest ends: ``worse`` only when the ratio of the fastest times
    exceeds ``factor`` AND so does B's low end over A's high end (``better``: B's high end
    below A's low end over the factor); ``not significant`` when the fastest times differ
    beyond the factor but the ranges allow less, or a side's spread was not measured (a
    change cannot be told from noise that was not measured); ``same`` within the factor."""
    (a_fast, a_lo, a_hi), (b_fast, b_lo, b_hi) = (tuple(_num(v) for v in side) for side in (a, b))
    if math.isnan(a_fast) and math.isnan(b_fast):
        return None
    if math.isnan(a_fast) or math.isnan(b_fast) or a_fast <= 0:
        return math.nan, "same"
    ratio = b_fast / a_fast
    if not 1.0 / factor <= ratio <= factor and any(math.isnan(v) for v in (a_lo, a_hi, b_lo, b_hi)):
        return ratio, "not significant"
    if ratio > factor:
        return ratio, ("worse" if b_lo > factor * a_hi else "not significant")
    if ratio < 1.0 / factor:
        return ratio, ("better" if factor * b_hi < a_lo else "not significant")
    return ratio, "same"


def cost_range(row, column: str) -> tuple[float, float, float]:
    """The cost of a run in ``column`` (ns per step): (fastest repeat, the range's low end,
    its high end). The high end is the slowest repeat; the low end is the fastest repeat
    scaled by the process's CPU time over its wall time during the stepping (``cpu_time_s``
    / ``wall_time_s``, at most 1): on a busy machine the process waited for a CPU part of
    the wall time, so the engine's own cost may be that much lower than the clock says.
    Without a CPU time and with a single timing (a row written before they were measured,
    a run path that does not measure them) the spread is unknown: low and high are NaN."""
    fastest = _num(row.get(column))
    n = _num(row.get("nstep"))
    wall, cpu = _num(row.get("wall_time_s")), _num(row.get("cpu_time_s"))
    repeats = _num(row.get("timing_repeats"))
    if math.isnan(cpu) and not repeats >= 2:
        return fastest, math.nan, math.nan
    hi = 1e9 * _num(row.get(COST_MAX[column])) / n if n and n > 0 else math.nan
    hi = fastest if math.isnan(hi) else max(hi, fastest)
    share = cpu / wall if wall > 0 else math.nan
    lo = fastest * share if 0.0 <= share < 1.0 else fastest
    return fastest, lo, hi


def _by_key(df) -> dict:
    return {
        config_key(r["scenario"], r["engine"], r["integrator"], r["dt"], r["target_accuracy"]): r
        for r in records(df)
    }


def compare_folders(
    a: str | Path,
    b: str | Path,
    factor: float = 2.0,
    cost_factor: float | None = None,
    vary=(),
) -> Comparison:
    """Compare the results of folders ``a`` and ``b`` (see the module docstring); a folder
    without a results store is a FileNotFoundError naming it; :class:`NothingComparable`
    when either folder holds no run or they share none. ``vary``: identity columns that may
    differ between the two (e.g. ``("engine_version",)``)."""
    if not factor >= 1.0:
        raise InputError(f"--factor {factor!r}: must be a number >= 1")
    if cost_factor is not None and not cost_factor >= 1.0:
        raise InputError(f"--cost-factor {cost_factor!r}: must be a number >= 1")
    bad = [v for v in vary if v not in IDENTITY_COLUMNS]
    if bad:
        raise InputError(
            f"--vary {bad[0]!r}: not an identity column (one of {', '.join(IDENTITY_COLUMNS)})"
        )
    ra, rb = _by_key(read_results(a)), _by_key(read_results(b))
    for folder, runs in ((a, ra), (b, rb)):
        if not runs:
            raise NothingComparable(f"{folder}: the results store holds no run: nothing to compare")
    if not set(ra) & set(rb):
        raise NothingComparable(
            f"{a} ({len(ra)} runs) and {b} ({len(rb)} runs) share no run (scenario, engine, "
            "integrator, dt, target accuracy): nothing was compared"
        )
    cmp = Comparison(Path(a), Path(b), factor, cost_factor, tuple(vary))
    cmp.only_a = [(k, ra[k]["status"]) for k in sorted(ra, key=_sort_key) if k not in rb]
    cmp.only_b = [(k, rb[k]["status"]) for k in sorted(rb, key=_sort_key) if k not in ra]
    for key in sorted(set(ra) & set(rb), key=_sort_key):
        cmp.both.append(key)
        x, y = ra[key], rb[key]
        diff = identity_differences(x, y, vary)
        if diff:
            cmp.changes.append(
                Change(key, "identity", "A", "; ".join(diff), math.nan, "mismatch", gates=True)
            )
            continue
        cmp.changes += _run_changes(key, x, y, factor, cost_factor)
    _corroborate_costs(cmp.changes)
    return cmp


def _corroborate_costs(changes: list) -> None:
    """Keep a cost change only where every step size of its sweep moved the same way.

    A change of the engine moves the cost per step at every dt of a configuration's sweep
    (scenario, engine, integrator); a burst of load on the machine hits single runs, and a
    run's measured spread cannot show load that came and went between two of its repeats.
    So a ``worse`` (``better``) cost at one dt stays so only when that cost column is
    ``worse`` (``better``) at every dt of the sweep the two folders share; otherwise it is
    ``not significant``. A configuration run at one dt only is judged on that run."""
    groups: dict = {}
    for c in changes:
        if c.column in COST_COLUMNS:
            groups.setdefault((c.key[:3], c.column), []).append(c)
    for group in groups.values():
        words = {c.change for c in group}
        if len(words) > 1:
            for c in group:
                if c.change in ("worse", "better"):
                    c.change = "not significant"


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
        got = classify_cost(cost_range(x, c), cost_range(y, c), cost_factor or factor)
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


def _counts(cmp: Comparison) -> dict:
    worse = {c.key for c in cmp.changes if c.worse and c.gates}
    mismatch = {c.key for c in cmp.changes if c.change == "mismatch"}
    better = {c.key for c in cmp.changes if c.change == "better"} - worse
    return {
        "in_both": len(cmp.both),
        "worse": len(worse - mismatch),
        "mismatch": len(mismatch),
        "better": len(better),
        "same": len(cmp.both) - len(worse) - len(better),
        "cost_not_significant": sum(1 for c in cmp.changes if c.change == "not significant"),
        "only_a": len(cmp.only_a),
        "only_b": len(cmp.only_b),
    }


_ORDER = {"mismatch": 0, "worse": 1, "better": 2, "not significant": 3, "same": 4}


def _shown(cmp: Comparison, show_all: bool) -> list[Change]:
    shown = [c for c in cmp.changes if show_all or c.change != "same"]
    shown.sort(key=lambda c: (_ORDER[c.change], not c.gates, _sort_key(c.key), c.column))
    return shown


def _word(c: Change) -> str:
    return c.change + ("" if c.gates or c.change != "worse" else " (not gated)")


def _verdict(cmp: Comparison) -> str:
    n = _counts(cmp)
    if n["mismatch"]:
        return (
            f"FAIL: {n['mismatch']} run(s) are not the same run in A and B (identity mismatch), "
            f"{n['worse']} got worse beyond a factor {cmp.factor:g}."
        )
    if n["worse"]:
        return f"FAIL: {n['worse']} run(s) got worse beyond a factor {cmp.factor:g}."
    return "OK: no run got worse."


def _summary_line(cmp: Comparison) -> str:
    n = _counts(cmp)
    cost_note = (
        f"cost gated at {cmp.cost_factor:g}x"
        if cmp.cost_factor is not None
        else "cost not gated (--cost-factor F to gate it)"
    )
    vary = f"; allowed to differ: {', '.join(cmp.vary)}" if cmp.vary else ""
    return (
        f"{n['in_both']} runs in both: {n['mismatch']} identity mismatch(es), {n['worse']} worse, "
        f"{n['better']} better, {n['same']} the same within a factor {cmp.factor:g} (above "
        f"round-off floors; {cost_note}; {n['cost_not_significant']} cost change(s) beyond the "
        f"factor but within the measured spread: not significant{vary}); {n['only_a']} only "
        f"in A, {n['only_b']} only in B."
    )


def format_comparison(cmp: Comparison, show_all: bool = False) -> str:
    """The comparison as text: a summary line, then every change that is not ``same``
    (every change with ``show_all``), mismatches and worse first, then the runs in one
    folder only."""
    lines = [f"A: {cmp.a}", f"B: {cmp.b}", _summary_line(cmp)]
    shown = _shown(cmp, show_all)
    if shown:
        head = ["change", "run", "what", "A", "B", "B/A"]
        rows = []
        for c in shown:
            ratio = "" if math.isnan(c.ratio) else fmt(c.ratio)
            rows.append([_word(c), _run_name(c.key), c.column, _value(c.a), _value(c.b), ratio])
        lines += ["", *_text_table(head, rows)]
    for title, items in (("Only in A", cmp.only_a), ("Only in B", cmp.only_b)):
        if items:
            lines += ["", f"{title} ({len(items)}):"]
            lines += [f"  {_run_name(k)} ({status})" for k, status in items]
    lines += ["", _verdict(cmp)]
    return "\n".join(lines)


def _json_num(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def as_json(cmp: Comparison) -> dict:
    """The comparison as a JSON-ready dict (every change that is not ``same``)."""

    def run(key):
        sc, eng, integ, dt, acc = key
        return {
            "scenario": sc,
            "engine": eng,
            "integrator": integ,
            "dt": dt,
            "target_accuracy": acc,
        }

    return {
        "ok": cmp.ok,
        "a": str(cmp.a),
        "b": str(cmp.b),
        "factor": cmp.factor,
        "cost_factor": cmp.cost_factor,
        "vary": list(cmp.vary),
        "counts": _counts(cmp),
        "changes": [
            {
                "run": run(c.key),
                "what": c.column,
                "change": c.change,
                "gates": c.gates,
                "a": _json_num(c.a),
                "b": _json_num(c.b),
                "ratio": _json_num(c.ratio),
            }
            for c in _shown(cmp, False)
        ],
        "only_a": [{"run": run(k), "status": st} for k, st in cmp.only_a],
        "only_b": [{"run": run(k), "status": st} for k, st in cmp.only_b],
    }


def as_markdown(cmp: Comparison) -> str:
    """The comparison as Markdown (a pull-request comment or a job summary)."""
    out = [
        f"## director-bench compare: {'OK' if cmp.ok else 'FAIL'}",
        "",
        f"A `{md_escape(cmp.a)}`, B `{md_escape(cmp.b)}`.",
        "",
        md_escape(_summary_line(cmp)),
    ]
    shown = _shown(cmp, False)
    if shown:
        out += ["", "| change | run | what | A | B | B/A |", "|---|---|---|---|---|---:|"]
        for c in shown:
            ratio = "" if math.isnan(c.ratio) else fmt(c.ratio)
            cells = (_word(c), _run_name(c.key), c.column, _value(c.a), _value(c.b), ratio)
            out.append("| " + " | ".join(md_escape(x) for x in cells) + " |")
    for title, items in (("Only in A", cmp.only_a), ("Only in B", cmp.only_b)):
        if items:
            out += ["", f"{title} ({len(items)}):", ""]
            out += [f"- {md_escape(_run_name(k))} ({md_escape(st)})" for k, st in items]
    out += ["", md_escape(_verdict(cmp))]
    return "\n".join(out) + "\n"


def run_compare(
    a,
    b,
    factor: float = 2.0,
    cost_factor: float | None = None,
    vary=(),
    show_all: bool = False,
    markdown=None,
    json_path=None,
) -> int:
    """``director-bench compare``: print the table, write the Markdown and JSON summaries
    (default ``B/compare.md`` and ``B/compare.json``; appended to ``$GITHUB_STEP_SUMMARY``
    when set) and return the exit code (0 nothing worse, 1 worse, a mismatch or nothing
    comparable)."""
    import json
    import os
    import sys

    try:
        cmp = compare_folders(a, b, factor=factor, cost_factor=cost_factor, vary=vary)
    except NothingComparable as exc:
        print(f"director-bench: error: {exc}", file=sys.stderr)
        return 1
    print(format_comparison(cmp, show_all=show_all))
    md = as_markdown(cmp)
    md_path = Path(markdown) if markdown else Path(b) / "compare.md"
    js_path = Path(json_path) if json_path else Path(b) / "compare.json"
    try:
        for path, text in ((md_path, md), (js_path, json.dumps(as_json(cmp), indent=1) + "\n")):
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            tmp.write_text(text)
            tmp.replace(path)
        print(f"written: {md_path}, {js_path}")
    except OSError as exc:
        print(
            f"director-bench: warning: cannot write {exc.filename or md_path} "
            f"({exc.strerror or exc}); give --markdown FILE and --json FILE elsewhere",
            file=sys.stderr,
        )
    summary = os.environ.get("GITHUB_STEP_SUMMARY")
    if summary:
        with open(summary, "a") as fh:
            fh.write(md)
    return 0 if cmp.ok else 1


def _text_table(head, rows) -> list[str]:
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return out
