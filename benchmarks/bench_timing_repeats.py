"""What timing cheap runs more than once costs the suite, measured side by side in one run.

The runner repeats a cheap run for its timing (reports.run.runner.TIMING_BUDGET_S and
TIMING_REPEATS: repeated while the calls so far and one more stay within the budget). This
script runs the same suite (the default scenarios on ``--engines``, one process, fresh output
folders) alternately with repeats off (budget 0) and on (the runner's budget), ``--rounds``
times each, and prints the best wall time of each, their ratio, and how many runs were
repeated how often. Usage:

    python benchmarks/bench_timing_repeats.py [--engines director,mujoco] [--rounds 2]
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time
from pathlib import Path


def one_suite(engines: list[str], budget: float) -> tuple[float, collections.Counter]:
    import scenarios
    from reports.run import runner
    from reports.run.plan import plan

    runner.TIMING_BUDGET_S = budget
    suite = [scenarios.load(n) for n in scenarios.default_suite()]
    specs = plan(suite, engines)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        df, _ = runner.run_suite(specs, Path(tmp), progress=False)
        took = time.perf_counter() - t0
    return took, collections.Counter(df["timing_repeats"].fillna(0).astype(int))


def main() -> None:
    from reports.run import runner

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--engines", default="director,mujoco")
    p.add_argument("--rounds", type=int, default=2)
    args = p.parse_args()
    engines = args.engines.split(",")
    budget = runner.TIMING_BUDGET_S
    one_suite(engines, 0.0)  # warm-up: imports, numba caches, references
    best = {0.0: float("inf"), budget: float("inf")}
    counts = {}
    for _ in range(args.rounds):
        for b in (0.0, budget):
            took, counts[b] = one_suite(engines, b)
            best[b] = min(best[b], took)
    n = sum(counts[budget].values())
    print(f"default suite on {args.engines}: {n} runs, best of {args.rounds}, one process")
    print(f"  timed once:                       {best[0.0]:.2f} s")
    print(f"  cheap runs repeated (budget {budget:g} s): {best[budget]:.2f} s")
    print(f"  ratio: {best[budget] / best[0.0]:.3f}")
    hist = ", ".join(f"{k}x: {v}" for k, v in sorted(counts[budget].items()))
    print(f"  runs by number of timed runs: {hist} (0: no timing, e.g. unsupported)")


if __name__ == "__main__":
    main()
