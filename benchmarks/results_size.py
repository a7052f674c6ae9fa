"""The size of a default results folder, and proof that what a run keeps on disk changes no
result.

Runs the default suite twice into two new folders, once as ``run`` does by default (each run
keeps the series the report draws, reports.run.files) and once with ``--trajectories full``
(every run's whole trajectory), then prints:

- each folder's size on disk, in total and per part (trajectories, report, store, ...);
- that every column of every run that is not a timing is bit for bit the same in both
  folders (status, verdict, every metric, fitted order, reference accuracy, scales: the
  metrics are computed from the full run before anything is kept), and how many runs and
  columns were compared;
- how many figures of the two reports are the same PNG byte for byte, and the largest
  difference of the others in pixel values (the report draws from the single-precision
  series of the default folder).

Given two existing folders (``--compare A B``), only the comparisons. Target (issue 31):
the default folder <= 30 MB with no metric lost.

Usage: python benchmarks/results_size.py [--out /tmp/size] [--compare A B]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
from pathlib import Path

#: columns that measure time or record when and where: they differ from run to run
TIMING = {
    "wall_time_s", "engine_time_s", "glue_time_s", "wall_time_max_s", "engine_time_max_s",
    "timing_repeats", "cpu_time_s", "ns_per_step", "engine_ns_per_step", "finished_at",
    "trajectory",
}  # fmt: skip


def size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def sizes(folder: Path) -> None:
    total = size(folder)
    print(f"{folder}: {total / 1e6:.1f} MB")
    parts = sorted(folder.iterdir(), key=size, reverse=True)
    for p in parts[:8]:
        print(f"  {p.name:<18} {size(p) / 1e6:8.2f} MB")


def same_results(a: Path, b: Path) -> bool:
    from reports.store.results import read_results
    from reports.store.runs import RESULT_COLUMNS

    da, db = read_results(a), read_results(b)
    key = ["scenario", "engine", "integrator", "dt", "target_accuracy"]
    da = da.sort_values(key, ignore_index=True)
    db = db.sort_values(key, ignore_index=True)
    keys_a = [tuple(map(repr, k)) for k in da[key].itertuples(index=False)]
    keys_b = [tuple(map(repr, k)) for k in db[key].itertuples(index=False)]
    if keys_a != keys_b:
        print(f"different runs: {len(da)} vs {len(db)}")
        return False
    cols = [c for c in RESULT_COLUMNS if c not in TIMING]
    bad = []
    for c in cols:
        for x, y in zip(da[c], db[c], strict=True):
            same = x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y))
            if not same:
                bad.append((c, x, y))
    print(
        f"{len(da)} runs x {len(cols)} columns (every column but timings and the file path) "
        f"compared bit for bit: {len(bad)} differ"
    )
    for c, x, y in bad[:10]:
        print(f"  {c}: {x!r} vs {y!r}")
    return not bad


def same_figures(a: Path, b: Path) -> None:
    import numpy as np
    from PIL import Image

    # the figures drawn from the runs' samples and metrics; work-precision figures and the
    # scorecard also show the costs, which differ from one run to the next
    names = sorted(
        p.name
        for p in (a / "plots").glob("*.png")
        if not p.stem.endswith(("work_precision", "scorecard")) and p.name != "scorecard.png"
    )
    same, worst = 0, (0, "")
    for n in names:
        pa, pb = a / "plots" / n, b / "plots" / n
        if not pb.exists():
            print(f"  {n}: only in {a}")
            continue
        if pa.read_bytes() == pb.read_bytes():
            same += 1
            continue
        x = np.asarray(Image.open(pa).convert("RGB"), dtype=int)
        y = np.asarray(Image.open(pb).convert("RGB"), dtype=int)
        if x.shape != y.shape:
            print(f"  {n}: {x.shape} vs {y.shape}")
            continue
        d = np.abs(x - y).max(axis=2)
        changed = int((d > 0).sum())
        worst = max(worst, (changed, n))
    print(f"figures: {same} of {len(names)} byte for byte the same; the most pixels changed in "
          f"one figure: {worst[0]} ({worst[1] or '-'})")  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="/tmp/results-size")
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = ap.parse_args()
    if args.compare:
        a, b = (Path(p) for p in args.compare)
    else:
        a, b = Path(args.out) / "default", Path(args.out) / "full"
        for folder, extra in ((a, []), (b, ["--trajectories", "full"])):
            cmd = [sys.executable, "-m", "reports.cli", "run", "--out", str(folder), "--quiet",
                   *extra]  # fmt: skip
            print("$", " ".join(cmd[2:]), flush=True)
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    sizes(a)
    sizes(b)
    ok = same_results(a, b)
    same_figures(a, b)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
