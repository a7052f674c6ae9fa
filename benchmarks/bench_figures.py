"""Draw every figure of a results folder serially and beside a pool of worker processes,
side by side in one run: which is faster, in wall and in CPU time, on this machine.

The report draws a scenario's figures in this process and, from
reports.report.figures.PARALLEL_FROM scenarios on, in a pool of one worker process fewer
than the cores (forked where that is safe). This script copies the folder's results (store,
series, provenance) into a scratch folder once per measurement, and draws all its figures
(reports.report.figures.report_figures: every scenario's and the scorecard picture) in a
fresh interpreter, nothing reused (an empty figure cache, no plots folder), alternately
``serial`` (one core: no pool) and ``pool`` (the report's default), ``--rounds`` times each.
Printed per measurement: wall time and CPU time of the whole process tree (the interpreter
and its drawing workers: user + sys of the waited-for children), and the 1-minute load
average; then the median of each mode and their ratio.

Usage: python benchmarks/bench_figures.py RESULTS_DIR [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: what a measurement runs in its fresh interpreter: the report's figures of the folder,
#: with the number of cores the drawing sees set by the mode
DRAW = """
import sys, time
from pathlib import Path
from reports.report import figures
from reports.store.results import read_results
root = Path(sys.argv[1])
if sys.argv[2] == "serial":
    figures._cpus = lambda: 1
df = read_results(root)
plots, card = figures.report_figures(df, root)
print(sum(len(v) for v in plots.values()) + len(card))
"""

#: what a results folder holds that the figures are drawn from
INPUTS = ("results.sqlite", "provenance.json", "trajectories", "importers")


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def measure(src: Path, mode: str, scratch: Path) -> tuple[float, float, float, int]:
    """(wall s, CPU s, load, figures) of drawing ``src``'s figures in ``mode``."""
    work = scratch / f"{mode}-{time.monotonic_ns()}"
    work.mkdir()
    for name in INPUTS:
        p = src / name
        if p.is_dir():
            shutil.copytree(p, work / name)
        elif p.is_file():
            shutil.copy2(p, work / name)
    env = dict(os.environ, DIRECTOR_BENCH_CACHE=str(work / "cache"), MPLBACKEND="Agg")
    load = os.getloadavg()[0]
    cpu0, t0 = _children_cpu(), time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", DRAW, str(work), mode],
        env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    shutil.rmtree(work, ignore_errors=True)
    return wall, cpu, load, int(out.stdout.split()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path, help="a results folder (director-bench run --out)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    if not (args.results / "results.sqlite").is_file():
        sys.exit(f"{args.results}: no results.sqlite (not a results folder)")
    print(f"{args.results}: {os.cpu_count()} cores")
    print(f"{'round':>5} {'mode':>6} {'wall s':>8} {'CPU s':>8} {'load':>6} {'figures':>8}")
    rows: dict[str, list] = {"serial": [], "pool": []}
    with tempfile.TemporaryDirectory(prefix="bench-figures-") as tmp:
        for k in range(1, args.rounds + 1):
            order = ("serial", "pool") if k % 2 else ("pool", "serial")
            for mode in order:
                wall, cpu, load, n = measure(args.results, mode, Path(tmp))
                rows[mode].append((wall, cpu))
                print(f"{k:>5} {mode:>6} {wall:8.2f} {cpu:8.2f} {load:6.2f} {n:8d}", flush=True)
    med = {m: tuple(statistics.median(r[i] for r in rows[m]) for i in (0, 1)) for m in rows}
    for m in rows:
        print(f"median {m}: wall {med[m][0]:.2f} s, CPU {med[m][1]:.2f} s")
    print(f"pool / serial: wall x{med['pool'][0] / med['serial'][0]:.2f}, "
          f"CPU x{med['pool'][1] / med['serial'][1]:.2f}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
