"""What the timing pass costs the suite, measured side by side in one run.

Once every run of a scenario is back, the runner times its configurations again in one
process, alternating, and keeps each run's best timing (reports.run.timing: at most
``BUDGET_FACTOR`` times the scenario's stepping CPU plus a floor). This script runs the same
suite (the default single-body scenarios on ``--engines``, in this process, fresh output
folders) alternately without the timing passes and with them, ``--rounds`` times each, and
prints the CPU time (this process: everything runs here) and wall time of each, the
medians, their ratio, and how many runs were timed how often. A first suite, not counted,
warms the caches (imports, numba's kernels, the references). Usage:

    python benchmarks/bench_timing_repeats.py [--engines director,mujoco] [--rounds 3]
"""

from __future__ import annotations

import argparse
import collections
import statistics
import tempfile
import time
from pathlib import Path


def one_suite(engines: list[str], passes: bool) -> tuple[float, float, collections.Counter]:
    """(CPU s, wall s, runs by number of timings) of the suite, with or without its passes."""
    import scenarios
    from reports.run import runner
    from reports.run.parallel import serial
    from reports.run.plan import plan

    suite = [scenarios.load(n) for n in scenarios.default_suite()]
    specs = plan(suite, engines)
    original = runner.with_timing_passes
    if not passes:
        runner.with_timing_passes = lambda units: (units, {})
    try:
        with tempfile.TemporaryDirectory() as tmp:
            c0, t0 = time.process_time(), time.perf_counter()
            df, _ = runner.run_suite(specs, Path(tmp), progress=False, mapper=serial(Path(tmp)))
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    finally:
        runner.with_timing_passes = original
    return cpu, wall, collections.Counter(df["timing_repeats"].fillna(0).astype(int))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--engines", default="director,mujoco")
    p.add_argument("--rounds", type=int, default=3)
    args = p.parse_args()
    engines = args.engines.split(",")
    one_suite(engines, False)  # warm-up: imports, numba caches, references
    got: dict[bool, list] = {False: [], True: []}
    counts = collections.Counter()
    print(f"{'round':>5} {'timing pass':>12} {'CPU s':>8} {'wall s':>8}")
    for k in range(args.rounds):
        for passes in (False, True) if k % 2 == 0 else (True, False):
            cpu, wall, c = one_suite(engines, passes)
            got[passes].append((cpu, wall))
            if passes:
                counts = c
            print(f"{k + 1:>5} {'on' if passes else 'off':>12} {cpu:8.2f} {wall:8.2f}", flush=True)
    med = {p: [statistics.median(r[i] for r in got[p]) for i in (0, 1)] for p in got}
    n = sum(counts.values())
    print(f"default single-body suite on {args.engines}: {n} runs, median of {args.rounds}, "
          "one process")  # fmt: skip
    print(f"  without timing passes: CPU {med[False][0]:.2f} s, wall {med[False][1]:.2f} s")
    print(f"  with timing passes:    CPU {med[True][0]:.2f} s, wall {med[True][1]:.2f} s")
    print(f"  ratio (CPU): {med[True][0] / med[False][0]:.3f}")
    hist = ", ".join(f"{k}x: {v}" for k, v in sorted(counts.items()))
    print(f"  runs by number of timings: {hist} (0: not timed, e.g. failed or the reference)")


if __name__ == "__main__":
    main()
