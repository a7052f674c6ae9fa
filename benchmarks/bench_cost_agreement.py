"""Do two runs of identical code agree on cost, one alone and one beside a second suite run?

Issue 31's target: the default suite run once on a machine as quiet as it gets ("alone") and
once beside a second default-suite run (the machine's load at least 4 on 2 cores: two suites
of two workers each); the rows' costs agree within 1.5x on at least 95 % of the rows, and
``director-bench compare`` of the two folders finds no significant cost change.

Runs ``director-bench run`` (the README's command, this checkout's code) into ``DIR/alone``,
then into ``DIR/loaded`` while a second one runs into ``DIR/beside`` (started first, and
restarted if it ends before the measured one), then compares. Printed: the machine's load
(1-minute average, before and after each run, and sampled every second during it), the
yardstick (bench_first_run.yardstick: CPU seconds of a fixed pure-Python loop, before and
after), per cost column the rows both ran ok and the share within 1.5x (both directions),
the starved rows on each side, and compare's counts of cost changes (worse / better:
significant; not significant; starved). ``--markdown FILE`` writes the table.

``--beside N`` runs N suites beside the loaded one (each restarted when it ends), started
``--lead`` seconds before it, for a load of at least 4 where one is not enough.

Usage: python benchmarks/bench_cost_agreement.py DIR [--engines A,B] [--scenarios X Y]
       [--markdown FILE] [--compare-only] [--beside N] [--lead S]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_first_run import yardstick  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RUN = [sys.executable, "-m", "reports.cli", "run", "--quiet", "--no-report"]
COLUMNS = ("engine_ns_per_step", "ns_per_step")
AGREE = 1.5


class LoadSampler:
    """The 1-minute load average sampled every second while the block runs."""

    def __init__(self):
        self.samples: list[float] = []
        self._stop = threading.Event()

    def __enter__(self):
        def run():
            while not self._stop.wait(1.0):
                self.samples.append(os.getloadavg()[0])

        self._t = threading.Thread(target=run, daemon=True)
        self._t.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._t.join()

    def text(self) -> str:
        s = self.samples or [os.getloadavg()[0]]
        return f"load {min(s):.1f}-{max(s):.1f} (median {statistics.median(s):.1f})"


def run(out: Path, extra: list[str], log: Path) -> float:
    t0 = time.perf_counter()
    with log.open("w") as fh:
        proc = subprocess.run([*RUN, "--out", str(out), *extra], cwd=REPO, stdout=fh,
                              stderr=subprocess.STDOUT)  # fmt: skip
    if proc.returncode not in (0, 1):
        sys.exit(f"director-bench run --out {out} exited {proc.returncode}; see {log}")
    return time.perf_counter() - t0


def measured(
    out: Path, extra: list[str], log: Path, beside: Path | None, n_beside: int = 1,
    lead_s: float = 5.0,
) -> dict:  # fmt: skip
    """Run into ``out`` (with ``n_beside`` other suites beside it into ``beside``, started
    ``lead_s`` seconds before it, when given)."""
    stick0, load0 = yardstick(), os.getloadavg()[0]
    seconds = []
    stop = threading.Event()
    current: dict[int, subprocess.Popen] = {}
    if beside is not None:

        def keep_running(j):
            k = 0
            while not stop.is_set():
                k += 1
                with beside.with_suffix(f".{j}.{k}.log").open("w") as fh:
                    cmd = [*RUN, "--out", str(beside / f"{j}.{k}"), *extra]
                    proc = subprocess.Popen(cmd, cwd=REPO, stdout=fh, stderr=subprocess.STDOUT)
                    current[j] = proc
                    proc.wait()

        beside.mkdir(parents=True, exist_ok=True)
        for j in range(n_beside):
            seconds.append(threading.Thread(target=keep_running, args=(j,), daemon=True))
            seconds[-1].start()
        time.sleep(lead_s)  # the other suites' workers are up and stepping
    with LoadSampler() as load:
        wall = run(out, extra, out.with_suffix(".log"))
    stop.set()
    for proc in list(current.values()):
        proc.terminate()  # its workers end with it (reports.run.parallel)
    for t in seconds:
        t.join()
    return {
        "wall_s": wall,
        "load": load.text(),
        "load_before": load0,
        "load_after": os.getloadavg()[0],
        "yardstick_s": (stick0 + yardstick()) / 2,
    }


def agreement(a: Path, b: Path) -> dict:
    import pandas as pd

    sys.path.insert(0, str(REPO))
    from reports.gate.rule import starved

    ra, rb = (pd.read_parquet(p / "results.parquet") for p in (a, b))
    ok = ["ok", "reference-inaccurate"]
    both = ra[ra["status"].isin(ok)].merge(
        rb[rb["status"].isin(ok)], on="run_id", suffixes=("_a", "_b")
    )
    both = both[both["reference_a"] != 1.0]
    out = {"rows": len(both)}
    for col in COLUMNS:
        x, y = both[f"{col}_a"].astype(float), both[f"{col}_b"].astype(float)
        r = (y / x).where((x > 0) & (y > 0))
        within = ((r <= AGREE) & (r >= 1 / AGREE)).sum()
        out[col] = {
            "within": int(within),
            "share": float(within / len(both)) if len(both) else float("nan"),
            "worst": float(max(r.max(), 1 / r.min())) if r.notna().any() else float("nan"),
        }
    out["starved_a"] = int(sum(starved(r) for r in ra.to_dict("records")))
    out["starved_b"] = int(sum(starved(r) for r in rb.to_dict("records")))
    return out


def compare_counts(a: Path, b: Path) -> dict:
    js = b / "compare-agreement.json"
    subprocess.run([sys.executable, "-m", "reports.cli", "compare", str(a), str(b), "--json",
                    str(js), "--markdown", str(b / "compare-agreement.md")], cwd=REPO,
                   capture_output=True)  # fmt: skip
    doc = json.loads(js.read_text())
    counts = {"worse": 0, "better": 0, "not significant": 0, "starved": 0}
    for c in doc["changes"]:
        if c["what"] in COLUMNS and c["change"] in counts:
            counts[c["change"]] += 1
    return counts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("--engines", help="passed to run (default: the default suite's)")
    ap.add_argument("--scenarios", nargs="*", default=[], help="passed to run")
    ap.add_argument("--markdown", type=Path, help="write the agreement table here")
    ap.add_argument("--compare-only", action="store_true", help="the folders exist: compare")
    ap.add_argument("--beside", type=int, default=1, help="suites run beside the loaded one")
    ap.add_argument("--lead", type=float, default=5.0,
                    help="seconds the suites beside start before the loaded one")  # fmt: skip
    args = ap.parse_args(argv)
    extra = [*args.scenarios] + (["--engines", args.engines] if args.engines else [])
    d = args.dir.resolve()
    alone, loaded = d / "alone", d / "loaded"
    info = {}
    if not args.compare_only:
        d.mkdir(parents=True, exist_ok=True)
        info["alone"] = measured(alone, extra, None, None)
        print(f"alone:  {json.dumps(info['alone'])}", flush=True)
        info["loaded"] = measured(loaded, extra, None, d / "beside", args.beside, args.lead)
        print(f"loaded: {json.dumps(info['loaded'])}", flush=True)
        (d / "runs.json").write_text(json.dumps(info, indent=1))
    elif (d / "runs.json").exists():
        info = json.loads((d / "runs.json").read_text())
    agree = agreement(alone, loaded)
    counts = compare_counts(alone, loaded)
    lines = [
        f"| | alone | beside {args.beside} other suite run(s) |",
        "|---|---|---|",
    ]
    for k in ("wall_s", "load", "yardstick_s"):
        a, b = info.get("alone", {}).get(k, "?"), info.get("loaded", {}).get(k, "?")
        fmt = lambda v: f"{v:.2f}" if isinstance(v, float) else str(v)  # noqa: E731
        lines.append(f"| {k} | {fmt(a)} | {fmt(b)} |")
    lines.append(f"| rows timed starved | {agree['starved_a']} | {agree['starved_b']} |")
    lines += ["", "| cost column | rows ok in both | within 1.5x | share | worst ratio |",
              "|---|---|---|---|---|"]  # fmt: skip
    for col in COLUMNS:
        c = agree[col]
        lines.append(f"| `{col}` | {agree['rows']} | {c['within']} | {100 * c['share']:.1f} % "
                     f"| {c['worst']:.2f} |")  # fmt: skip
    lines += [
        "",
        "compare alone -> loaded, cost changes beyond its factor 2: "
        f"{counts['worse']} worse, {counts['better']} better (significant), "
        f"{counts['not significant']} not significant, {counts['starved']} starved",
    ]
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
