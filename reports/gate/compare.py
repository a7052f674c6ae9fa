"""Compare two result folders, run by run: ``director-bench compare A B``.

The runs of A and B are matched on their configuration (scenario, engine, integrator, dt,
target accuracy: :data:`reports.store.runs.CONFIG_KEY`) and must be the same run: a pair whose
identity differs (:data:`reports.store.runs.RUN_IDENTITY`: scenario content, horizon,
save_every, segmenting, suite version) is a ``mismatch`` naming each field (``t_end 30 vs
10``), never compared as if it were the same run. Two releases of an engine are the same run
on another release: compared as usual, each release change reported with the number of runs
it changed (``mujoco 4.0.0 -> 4.0.1: 196 runs compared, 0 changed``). To compare two suite
versions on purpose, name the field that may differ: ``--vary suite_version``
(docs/results.md has the recipe).

For each run in both, every metric and the cost get a ratio B/A and a word by the comparison
rule of :mod:`reports.gate.rule`, the one ``check`` applies against a baseline: ``worse``
when B is more than ``factor`` times A above the metric's round-off floor, ``better`` when
less than A / ``factor``, ``same`` otherwise; the fitted convergence order by difference; a
status that got worse (ok to diverged or error), a verdict that went from pass to fail or a
failing run that fails one more check (:func:`reports.gate.rule.verdict_change`) is
``worse`` whatever the numbers (``unsupported`` and ``unavailable`` are the environment, not
a result). A cost (ns per step inside the engine and of the whole step) is a range measured
with the run (reports.run.runner); a cost change is significant only beyond the factor AND
the measured spread, and only when every dt of the configuration's sweep moved the same way
(:func:`reports.gate.rule.classify_cost`, :func:`reports.gate.rule.corroborate_costs`);
otherwise it is ``not significant``, or ``starved`` where a side's engine time was measured
starved (reports.gate.rule.starved). The costs are CPU times (references.engines.timing):
the time a run waited for a CPU on a busy machine is not in them.

Exit code of the command: 1 when some run got worse in a metric, its status or its verdict,
when a pair of runs is a mismatch, or when nothing is comparable (an empty folder, no run in
both); the cost gates only with ``cost_factor`` (timings vary with the machine's load far
more than the metrics do). Runs found in only one folder are listed and do not gate.

This is not the CI gate (reports.gate.check): that compares a folder against a committed baseline
file; this compares two folders, e.g. two engine versions (docs/results.md has the recipe).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

from reports.gate.format import json_number, md_escape, md_table, text_table
from reports.gate.rule import (
    COST_COLUMNS,
    RAN,
    Change,
    Comparison,
    NothingComparable,
    classify,
    classify_cost,
    corroborate_costs,
    cost_range,
    count_version_change,
    status_change,
    verdict_change,
)
from reports.metrics.catalog import METRIC_COLUMNS
from reports.store.format import fmt, fmt_level, fmt_step, num
from reports.store.results import read_results, records
from reports.store.runs import IDENTITY_COLUMNS, config_key, identity_differences
from scenarios.schema import InputError


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
    differ between the two (e.g. ``("suite_version",)``; engine releases always may)."""
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
        cmp.compared.append(key)
        x, y = ra[key], rb[key]
        diff = identity_differences(x, y, vary)
        if diff:
            cmp.changes.append(
                Change(key, "identity", "A", "; ".join(diff), math.nan, "mismatch", gates=True)
            )
            continue
        found = _run_changes(key, x, y, factor, cost_factor)
        cmp.changes += found
        count_version_change(cmp, key, x, y, found)
    corroborate_costs(cmp.changes)
    return cmp


def _sort_key(key):
    sc, eng, integ, dt, acc = key
    return (sc, eng, integ, dt, -1.0 if acc is None else acc)


def _run_changes(key, x, y, factor, cost_factor) -> list[Change]:
    out = []
    sx, sy = x["status"], y["status"]
    if sx != sy:
        if sx not in RAN or sy not in RAN:  # unsupported / unavailable: the environment
            out.append(Change(key, "status", sx, sy, math.nan, "same"))
        else:
            out.append(Change(key, "status", sx, sy, math.nan, status_change(sx, sy), True))
        return out
    if sx != "ok":
        return out
    column, change, new = verdict_change(x, y)
    if column == "verdict":
        out.append(Change(key, "verdict", x["verdict"], y["verdict"], math.nan, change, True))
    elif column:
        out.append(Change(key, column, "", f"also fails {new}", math.nan, change, True))
    for m in METRIC_COLUMNS:
        got = classify(m, x[m], y[m], factor)
        if got is not None:
            out.append(Change(key, m, num(x[m]), num(y[m]), got[0], got[1], gates=True))
    for c in COST_COLUMNS:
        got = classify_cost(cost_range(x, c), cost_range(y, c), cost_factor or factor)
        if got is not None:
            gates = cost_factor is not None
            out.append(Change(key, c, num(x[c]), num(y[c]), got[0], got[1], gates=gates))
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
        "in_both": len(cmp.compared),
        "worse": len(worse - mismatch),
        "mismatch": len(mismatch),
        "better": len(better),
        "same": len(cmp.compared) - len(worse) - len(better),
        "cost_not_significant": sum(1 for c in cmp.changes if c.change == "not significant"),
        "cost_starved": sum(1 for c in cmp.changes if c.change == "starved"),
        "only_a": len(cmp.only_a),
        "only_b": len(cmp.only_b),
    }


_ORDER = {"mismatch": 0, "worse": 1, "better": 2, "not significant": 3, "starved": 3, "same": 4}


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
        f"factor but within the measured spread: not significant; {n['cost_starved']} beyond "
        "it where a side was timed starved (no repeat ran clean enough to know the engine's "
        f"CPU time): starved{vary}); {n['only_a']} only in A, {n['only_b']} only in B."
    )


def _change_row(c: Change) -> list[str]:
    ratio = "" if math.isnan(c.ratio) else fmt(c.ratio)
    return [_word(c), _run_name(c.key), c.column, _value(c.a), _value(c.b), ratio]


def format_comparison(cmp: Comparison, show_all: bool = False) -> str:
    """The comparison as text: a summary line, then every change that is not ``same``
    (every change with ``show_all``), mismatches and worse first, then the runs in one
    folder only."""
    lines = [f"A: {cmp.a}", f"B: {cmp.b}", *cmp.version_lines(), _summary_line(cmp)]
    shown = _shown(cmp, show_all)
    if shown:
        head = ["change", "run", "what", "A", "B", "B/A"]
        rows = [_change_row(c) for c in shown]
        lines += ["", *text_table(head, rows)]
    for title, items in (("Only in A", cmp.only_a), ("Only in B", cmp.only_b)):
        if items:
            lines += ["", f"{title} ({len(items)}):"]
            lines += [f"  {_run_name(k)} ({status})" for k, status in items]
    lines += ["", _verdict(cmp)]
    return "\n".join(lines)


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
                "a": json_number(c.a),
                "b": json_number(c.b),
                "ratio": json_number(c.ratio),
            }
            for c in _shown(cmp, False)
        ],
        "engine_releases": [dataclasses.asdict(v) for v in cmp.versions.values()],
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
        *[f"{md_escape(line)}  " for line in cmp.version_lines()],
        md_escape(_summary_line(cmp)),
    ]
    shown = _shown(cmp, False)
    if shown:
        rows = [_change_row(c) for c in shown]
        out += ["", *md_table(["change", "run", "what", "A", "B", "B/A"], rows, "lllllr")]
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

    from reports.store.atomic import write_text

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
            write_text(path, text)
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
