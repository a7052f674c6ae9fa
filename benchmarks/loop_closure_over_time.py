"""The loop-closure gap over time of every run that closes a loop, from result folders.

Usage: ``python benchmarks/loop_closure_over_time.py FOLDER [FOLDER ...]`` (folders written by
``director-bench run``, e.g. of ``four_bar``, ``four_bar_stiff_loop`` and ``bricard``). Prints a
Markdown table, one row per run at its scenario's own dt: the closure settings the engine
recorded (``reports.report.tables.closure_settings``), the largest loop-closure gap (m,
``reports.metrics.system.loop_gap``, measured on the stored trajectory) at a quarter, half and
the whole of the horizon, and its maximum over the run.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import scenarios
from references.trajectory import Trajectory
from reports.metrics.system import loop_gap
from reports.report.tables import closure_settings
from reports.store.results import read_results, reference_rows

FRACTIONS = (0.25, 0.5, 1.0)


def rows(folder: Path):
    df = read_results(folder)
    df = df[(df["status"] == "ok") & ~reference_rows(df)]
    for _, r in df.sort_values(["scenario", "engine", "integrator", "dt"]).iterrows():
        sc = scenarios.load(r["scenario"])
        if not getattr(sc, "loop_joints", None) or r["dt"] != sc.dt:
            continue
        tr = Trajectory.read(folder / r["trajectory"])
        gap = loop_gap(sc, tr)
        at = [gap[min(np.searchsorted(tr.t, f * tr.t[-1]), len(gap) - 1)] for f in FRACTIONS]
        settings = closure_settings(r.to_dict(), short=True)[:60] or "-"
        cells = [r["scenario"], f"{tr.t[-1]:g}", r["engine"], r["integrator"], f"{r['dt']:g}"]
        cells += [settings, *(f"{v:.2g}" for v in at), f"{gap.max():.2g}"]
        yield cells


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    head = ["scenario", "t_end [s]", "engine", "integrator", "dt [s]", "closure settings"]
    head += [f"gap at {f:g} t_end [m]" for f in FRACTIONS] + ["max [m]"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for folder in argv:
        for cells in rows(Path(folder)):
            print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
