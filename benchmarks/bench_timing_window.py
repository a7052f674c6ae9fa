"""The timing pass over bounded windows of steps, against whole-run repeats, side by side.

The default suite (its engines on this machine) runs once in this process without its timing
passes: its rows. Then two measurements, each alternating, CPU time of this process:

1. **What the pass costs.** Per scenario, the timing pass as this checkout has it
   (reports.run.timing: each repeat steps a bounded window of the run's first steps) and
   the pass of ``--before REV`` (that revision's reports/run/timing.py, loaded beside it;
   default ``main``), in turns (one first, then the other, swapped each scenario), each on
   the same rows; their CPU time and repeat calls summed over the suite, and how many rows
   the two passes' costs agree on within 1.5x (``engine_ns_per_step``, ``ns_per_step``).
2. **Whether the window biases a run's cost** (``--bias``): for every run a window
   shortens, ``--repeats`` rounds of a whole-run repeat and a window repeat (their order
   swapped each round, the scenario's runs in turns), the least per-step cost of each; the
   distribution of window over whole (below 1: the window prices the run cheaper), and the
   runs furthest from 1.
3. **What a repeat adds to a run that ran clean** (``--clean``): every timed run once more
   (its window, as the pass steps it, the scenario's runs in turns), the repeat's engine time
   per step over the run's own, for the runs whose own timing ran clean
   (reports.run.timing.ran_clean: the pass does not time them again) and for the others.

Usage: ``python benchmarks/bench_timing_window.py [--before main] [--bias] [--clean]
[--repeats 3] [--scenarios a b ...] [--rows FILE]``
"""

from __future__ import annotations

import argparse
import collections
import importlib.util
import math
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def rows_without_passes(names: list[str] | None):
    """(specs, {run_id: row}) of the default suite (or the scenarios ``names``) on the
    default suite's engines, planned as ``director-bench run`` plans them, run here without
    their timing passes."""
    from reports.run import runner
    from reports.run.parallel import serial
    from reports.run.plan import plan
    from reports.suite import check_engines, check_integrators, default_engines, resolve_scenarios

    engines, _ = default_engines()
    engines = check_engines(engines)
    integrators = check_integrators(None, engines, False)
    specs = plan(resolve_scenarios(names or ()), engines, integrators)
    original = runner.with_timing_passes
    runner.with_timing_passes = lambda units: (units, {})
    try:
        with tempfile.TemporaryDirectory() as tmp:
            df, _ = runner.run_suite(specs, Path(tmp), progress=False, mapper=serial(Path(tmp)))
    finally:
        runner.with_timing_passes = original
    rows = {r["run_id"]: r for r in df.to_dict("records")}
    return [s for s in specs if s.run_id in rows], rows


def module_at(rev: str):
    """reports/run/timing.py as it is at git revision ``rev``, loaded as a module."""
    src = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{rev}:reports/run/timing.py"],
        check=True, capture_output=True, text=True,
    ).stdout  # fmt: skip
    spec = importlib.util.spec_from_loader(f"timing_at_{rev}", loader=None)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclasses look their module up
    exec(compile(src, f"{rev}:reports/run/timing.py", "exec"), mod.__dict__)  # noqa: S102
    return mod


def counted(mod):
    """``mod``'s pass, wrapped: (its columns, process CPU s, repeat calls)."""
    calls = [0]
    real = mod._run_again

    def again(*a, **k):
        calls[0] += 1
        return real(*a, **k)

    def run(unit):
        calls[0] = 0
        mod._run_again = again
        try:
            c0 = time.process_time()
            cols = mod.time_unit(unit).columns
            return cols, time.process_time() - c0, calls[0]
        finally:
            mod._run_again = real

    return run


def cost_of_passes(specs, rows, before: str) -> None:
    from reports.run import timing
    from reports.run.body import is_reference

    passes = {"window (this checkout)": counted(timing), f"before ({before})": counted(
        module_at(before))}  # fmt: skip
    by_scenario = collections.defaultdict(list)
    for s in specs:
        if not is_reference(s.engine):
            by_scenario[s.scenario.name].append(s)
    cpu = collections.Counter()
    ncalls = collections.Counter()
    cols = {name: {} for name in passes}
    for k, (name, ss) in enumerate(sorted(by_scenario.items())):
        order = list(passes) if k % 2 == 0 else list(passes)[::-1]
        for which in order:
            unit = timing.TimingUnit(name, ss, {s.run_id: dict(rows[s.run_id]) for s in ss})
            got, c, n = passes[which](unit)
            cpu[which] += c
            ncalls[which] += n
            cols[which].update(got)
    print(f"{'timing pass':<28} {'CPU s':>8} {'repeat calls':>13}")
    for which in passes:
        print(f"{which:<28} {cpu[which]:8.2f} {ncalls[which]:13d}")
    a, b = (cols[w] for w in passes)
    for col in ("engine_ns_per_step", "ns_per_step"):
        ratios = []
        for run_id, row in rows.items():
            x = a.get(run_id, {}).get(col, row.get(col))
            y = b.get(run_id, {}).get(col, row.get(col))
            if x and y and x > 0 and y > 0 and math.isfinite(x) and math.isfinite(y):
                ratios.append(x / y)
        within = sum(1 for r in ratios if 1 / 1.5 <= r <= 1.5)
        print(f"  {col}: the two passes' rows within 1.5x: {within} of {len(ratios)}; "
              f"median window/before {statistics.median(ratios):.3f}")  # fmt: skip


def bias(specs, rows, repeats: int) -> None:
    from references.engines import get_engine
    from reports.run import timing

    runs = []
    for s in specs:
        row = rows[s.run_id]
        if not timing.timed(row):
            continue
        nstep = int(row["nstep"])
        steps = timing.window(s, nstep, float(row["cpu_time_s"]))
        if steps < nstep:
            runs.append((s, nstep, steps))
    by_scenario = collections.defaultdict(list)
    for r in runs:
        by_scenario[r[0].scenario.name].append(r)
    best = {r[0].run_id: {"whole": [math.inf, math.inf], "window": [math.inf, math.inf]}
            for r in runs}  # fmt: skip
    for k in range(repeats):
        for ss in by_scenario.values():
            for s, nstep, steps in ss:
                for which in ("whole", "window") if k % 2 == 0 else ("window", "whole"):
                    n = nstep if which == "whole" else steps
                    t = timing._run_again(get_engine(s.engine), s, nstep, n)
                    if t is None or t.starved:
                        continue
                    b = best[s.run_id][which]
                    b[0] = min(b[0], t.engine / n)
                    b[1] = min(b[1], t.cpu / n)
    for i, col in enumerate(("engine_ns_per_step", "ns_per_step")):
        ratios = []
        for s, nstep, steps in runs:
            w, h = best[s.run_id]["window"][i], best[s.run_id]["whole"][i]
            if math.isfinite(w) and math.isfinite(h) and h > 0:
                ratios.append((w / h, s, nstep, steps))
        ratios.sort(key=lambda r: r[0])
        q = [r[0] for r in ratios]
        print(f"\n{col}: window over whole run, per step, least of {repeats} each, "
              f"{len(q)} runs a window shortens")  # fmt: skip
        cuts = [0, 0.67, 0.8, 0.9, 1.1, 1.25, 1.5, math.inf]
        for lo, hi in zip(cuts, cuts[1:], strict=False):
            print(f"  [{lo:.2f}, {hi:.2f}): {sum(1 for x in q if lo <= x < hi)}")
        dec = statistics.quantiles(q, n=10) if len(q) > 1 else q
        print("  deciles: " + " ".join(f"{x:.3f}" for x in dec))
        print("  cheapest windows (window/whole, scenario, engine, integrator, dt, steps):")
        for r, s, nstep, steps in ratios[:8]:
            print(f"    {r:.3f} {s.scenario.name} {s.engine} {s.integrator} {s.dt:g} "
                  f"{steps}/{nstep}")  # fmt: skip
        print("  dearest windows:")
        for r, s, nstep, steps in ratios[-5:]:
            print(f"    {r:.3f} {s.scenario.name} {s.engine} {s.integrator} {s.dt:g} "
                  f"{steps}/{nstep}")  # fmt: skip


def clean(specs, rows) -> None:
    import numpy as np

    from references.engines import get_engine
    from reports.run import timing

    by_scenario = collections.defaultdict(list)
    for s in specs:
        if timing.timed(rows[s.run_id]):
            by_scenario[s.scenario.name].append(s)
    got = {True: [], False: []}  # own timing ran clean -> [(share, repeat/own per step)]
    for ss in by_scenario.values():
        for s in ss:
            row = rows[s.run_id]
            nstep = int(row["nstep"])
            steps = timing.window(s, nstep, float(row["cpu_time_s"]))
            own = timing._from_row(row)
            t = timing._run_again(get_engine(s.engine), s, nstep, steps)
            if t is None or t.starved or own.starved or own.engine <= 0:
                continue
            ratio = (t.engine / steps) / (own.engine / nstep)
            got[timing.ran_clean(own)].append((own.share, ratio))
    print("\nrepeat over the run's own timing, engine time per step (one window each):")
    for ran, what in ((True, "own timing ran clean (not timed again)"), (False, "the others")):
        q = np.array([r for _, r in got[ran]])
        if not len(q):
            print(f"  {what}: none")
            continue
        lo, med, hi = np.quantile(q, [0.05, 0.5, 0.95])
        print(f"  {what}: {len(q)} runs; 5 %, median, 95 %: {lo:.3f} {med:.3f} {hi:.3f}; "
              f"least {q.min():.3f}, most {q.max():.3f}")  # fmt: skip
    shares = np.array([sh for ran in got for sh, _ in got[ran]])
    if len(shares):
        print(f"  the runs' own CPU share: 10 %, median: "
              f"{np.quantile(shares, 0.1):.3f} {np.median(shares):.3f}; ran clean "
              f"{len(got[True])} of {len(shares)}")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--before", default="main")
    p.add_argument("--bias", action="store_true")
    p.add_argument("--no-cost", action="store_true", help="skip measurement 1")
    p.add_argument("--clean", action="store_true", help="measurement 3")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--scenarios", nargs="*")
    p.add_argument("--rows", type=Path, help="keep the rows in this file, or reuse them")
    args = p.parse_args()
    t0 = time.perf_counter()
    if args.rows and args.rows.exists():
        specs, rows = pickle.loads(args.rows.read_bytes())
    else:
        specs, rows = rows_without_passes(args.scenarios)
        if args.rows:
            args.rows.write_bytes(pickle.dumps((specs, rows)))
    print(f"{len(rows)} runs without timing passes ({time.perf_counter() - t0:.1f} s wall)",
          flush=True)  # fmt: skip
    if not args.no_cost:
        cost_of_passes(specs, rows, args.before)
    if args.bias:
        bias(specs, rows, args.repeats)
    if args.clean:
        clean(specs, rows)
    sys.stdout.flush()


if __name__ == "__main__":
    main()
