"""Two results folders of the same suite, run by run: every column of every run compared bit
for bit except the timings (``reports.store.runs.TIMING_COLUMNS``: they measure the machine,
not the code). Floats are compared by their bits (NaN equal to NaN, -0.0 not equal to 0.0),
everything else as text. For a change that must not move any result (a refactoring): run the
default suite on the code before and after, then compare.

    director-bench run --out /tmp/before --quiet --no-report     # on the code before
    director-bench run --out /tmp/after --quiet --no-report      # on the code after
    python benchmarks/compare_results.py /tmp/before /tmp/after

Prints the runs only one side has, the columns only one side has, and per column the runs
whose values differ (the first few with both values); exits 1 if any compared value differs
or a run is missing on one side, else 0.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def load(folder):
    from reports.store.results import read_results

    df = read_results(folder, all_rows=True)
    if df["run_id"].duplicated().any():
        raise SystemExit(f"{folder}: a run_id stands in more than one row")
    return df.set_index("run_id")


def differing(x, y) -> np.ndarray:
    """Which entries of two columns differ: floats by their bits (NaN = NaN), else as text."""
    import pandas as pd

    if pd.api.types.is_float_dtype(x) and pd.api.types.is_float_dtype(y):
        a, b = x.to_numpy(dtype=np.float64), y.to_numpy(dtype=np.float64)
        return (a.view(np.int64) != b.view(np.int64)) & ~(np.isnan(a) & np.isnan(b))
    return x.astype(str).to_numpy() != y.astype(str).to_numpy()


def main(argv=None) -> int:
    from reports.store.runs import TIMING_COLUMNS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--show", type=int, default=8, help="runs shown per differing column")
    args = ap.parse_args(argv)
    a, b = load(args.before), load(args.after)
    only_a, only_b = a.index.difference(b.index), b.index.difference(a.index)
    print(f"runs: before {len(a)}, after {len(b)}; "
          f"only before {len(only_a)}, only after {len(only_b)}")  # fmt: skip
    for side, ids, df in (("before", only_a, a), ("after", only_b, b)):
        for i in ids[: args.show]:
            r = df.loc[i]
            print(f"  only {side}: {r['scenario']}/{r['engine']}/{r['integrator']} dt={r['dt']}")
    if set(a.columns) != set(b.columns):
        print(f"columns only before: {sorted(set(a.columns) - set(b.columns))}; "
              f"only after: {sorted(set(b.columns) - set(a.columns))}")  # fmt: skip
    common = a.index.intersection(b.index)
    a, b = a.loc[common], b.loc[common]
    compared = [c for c in a.columns if c in b.columns and c not in TIMING_COLUMNS]
    left_out = sorted(TIMING_COLUMNS & set(a.columns))
    print(f"columns compared: {len(compared)}; timings left out: {', '.join(left_out)}")
    diffs = {c: common[bad] for c in compared if (bad := differing(a[c], b[c])).any()}
    for c, ids in diffs.items():
        print(f"\n{c}: {len(ids)} run(s) differ")
        for i in ids[: args.show]:
            row = a.loc[i]
            print(f"  {row['scenario']}/{row['engine']}/{row['integrator']} dt={row['dt']}: "
                  f"{a.loc[i, c]!r} -> {b.loc[i, c]!r}")  # fmt: skip
    if not diffs:
        print(
            f"every compared column of every one of the {len(common)} common runs is bit-identical"
        )
    return 1 if diffs or len(only_a) or len(only_b) else 0


if __name__ == "__main__":
    sys.exit(main())
