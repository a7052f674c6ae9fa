"""What the director's system builder's whole step (``ns_per_step``) counts: this checkout's
builder (references/engines/director/system.py) against that of ``--before REV`` (default
``main``), side by side, thread CPU time.

A run's whole step is the CPU time of its stepping on the run's stopwatch
(references.engines.timing: from the builder's ``timing.stepping()`` to its return), over
its steps; its engine step the compiled call's own CPU time. Three measurements, each
alternating the two builders (their order swapped every round):

1. **A process's first run** (``--first N`` rounds, each in a fresh process per builder):
   what the first director system run of a suite worker counts, its import of
   director_model.system and its kernel's loading from numba's cache included when they
   are inside the stopwatch.
2. **Whole runs** (``--rounds N``, one process): the default suite's director system
   configurations, each run whole; per configuration the least whole step and engine step
   of each builder (ns per step), the glue (whole minus engine), and after/before.
3. **Windows**: the same runs over their first :data:`WINDOW` steps (the timing pass's
   shortest window, reports.run.timing.WINDOW_MIN_STEPS), priced per step: a fixed cost per
   call inside the stopwatch shows here ten times over; window/whole per builder.

Beside each builder's runs: the thread's minor page faults, system CPU time and the garbage
collector's collections during its timed calls (the whole call, the build included), summed.

Usage: ``python benchmarks/bench_director_system_glue.py [--before main] [--rounds 5]
[--first 3] [--scenarios a b ...]``
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODULE = "references/engines/director/system.py"
#: the timing pass's shortest window (reports.run.timing.WINDOW_MIN_STEPS)
WINDOW = 100
#: the default suite's director system configurations: (scenario, scheme, dt)
CONFIGS = [
    (sc, scheme, dt)
    for sc, dts in (
        ("arm3_swing", (1e-3,)),
        ("four_bar", (2e-3,)),
        ("double_pendulum_3d", (1e-3, 2e-3)),
        ("free_chain_5", (1e-3, 2e-3)),
        ("spinning_chain", (1e-3, 2e-3)),
    )  # fmt: skip
    for scheme in ("rattle", "rattle4", "rattle6")
    for dt in dts
]


def load_before(rev: str):
    """The builder module of revision ``rev``, loaded beside this checkout's."""
    text = subprocess.run(["git", "show", f"{rev}:{MODULE}"], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout  # fmt: skip
    path = Path(tempfile.mkdtemp()) / "director_system_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("director_system_before", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class Builders:
    """Runs a configuration through ``references.engines.system.run_system`` with either
    builder in place of the director's (the adapter loads it by name at every run)."""

    def __init__(self, rev: str):
        import references.engines.director.system as after

        self.module = after
        self.fn = {"after": after.simulate_system, "before": load_before(rev).simulate_system}

    def run(self, which: str, sc, scheme: str, dt: float, nstep: int | None = None):
        """(whole-step CPU s, engine CPU s, steps, faults, system CPU s, collections)."""
        from references.engines.system import run_system

        self.module.simulate_system = self.fn[which]
        try:
            t_end = None if nstep is None else nstep * dt
            c0 = sum(s["collections"] for s in gc.get_stats())
            r0 = resource.getrusage(resource.RUSAGE_THREAD)
            out = run_system("director", sc, scheme, dt, t_end)
            r1 = resource.getrusage(resource.RUSAGE_THREAD)
            c1 = sum(s["collections"] for s in gc.get_stats())
        finally:
            self.module.simulate_system = self.fn["after"]
        t = out.timing
        self.last = out
        return (t.cpu, t.engine, out.nstep, r1.ru_minflt - r0.ru_minflt,
                r1.ru_stime - r0.ru_stime, c1 - c0)  # fmt: skip


def first_run(which: str, rev: str, name: str, scheme: str, dt: float) -> dict:
    """The first run of a fresh process with builder ``which`` (a child process)."""
    here = str(Path(__file__).parent)
    code = (
        f"import json, sys; sys.path.insert(0, {here!r}); import bench_director_system_glue "
        f"as b; import scenarios; B = b.Builders({rev!r}); sc = scenarios.load({name!r}); "
        f"r = [B.run({which!r}, sc, {scheme!r}, {dt!r}) for _ in range(2)]; "
        "print(json.dumps(r))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout  # fmt: skip
    (first, second) = json.loads(out.strip().splitlines()[-1])
    return {"first": first, "second": second}


def ns(x: float, n: int) -> float:
    return 1e9 * x / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="main")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--first", type=int, default=3)
    ap.add_argument("--scenarios", nargs="*")
    args = ap.parse_args()
    import scenarios

    configs = [c for c in CONFIGS if not args.scenarios or c[0] in args.scenarios]
    print(
        f"before: {args.before}; after: this checkout; thread CPU time; load "
        f"{' '.join(f'{x:.1f}' for x in os.getloadavg())}"
    )

    # 1. the first run of a fresh process
    if args.first:
        print(
            f"\n1. first run of a fresh process ({args.first} rounds each, alternating): "
            "whole step, engine step (us per step)"
        )
        print(
            f"{'configuration':34} {'builder':7} {'1st whole':>10} {'1st engine':>10} "
            f"{'2nd whole':>10} {'2nd engine':>10}"
        )
        for name, scheme, dt in (("arm3_swing", "rattle4", 1e-3), ("four_bar", "rattle4", 2e-3)):
            got = {"before": [], "after": []}
            for k in range(args.first):
                for which in ("before", "after") if k % 2 == 0 else ("after", "before"):
                    got[which].append(first_run(which, args.before, name, scheme, dt))
            for which in ("before", "after"):
                for r in got[which]:
                    f, s = r["first"], r["second"]
                    print(
                        f"{name + ' ' + scheme + f' dt {dt:g}':34} {which:7} "
                        f"{ns(f[0], f[2]) / 1e3:10.1f} {ns(f[1], f[2]) / 1e3:10.1f} "
                        f"{ns(s[0], s[2]) / 1e3:10.1f} {ns(s[1], s[2]) / 1e3:10.1f}"
                    )

    # 2. and 3. whole runs and windows, interleaved
    B = Builders(args.before)
    scs = {name: scenarios.load(name) for name in {c[0] for c in configs}}
    same = 0
    for c in configs:  # once each, untimed: every kernel loaded in this process
        outs = []
        for which in ("before", "after"):
            B.run(which, scs[c[0]], c[1], c[2])
            outs.append(B.last)
        a, b = (o.trajectory for o in outs)
        same += all(np.array_equal(getattr(a, f), getattr(b, f))
                    for f in ("t", "position", "velocity", "rotation", "omega_body")) and (
            repr((outs[0].settings, outs[0].stats)) == repr((outs[1].settings, outs[1].stats))
        )  # fmt: skip
    print(f"\nstates, settings and stats bit-identical before and after: {same}/{len(configs)}")
    best: dict = {}
    extra = {w: [0, 0.0, 0] for w in ("before", "after")}
    for k in range(args.rounds):
        for c in configs:
            order = ("before", "after") if (k + configs.index(c)) % 2 == 0 else ("after", "before")
            for span in ("whole", "window"):
                for which in order:
                    steps = None if span == "whole" else WINDOW
                    cpu, eng, n, flt, st, col = B.run(which, scs[c[0]], c[1], c[2], steps)
                    e = extra[which]
                    e[0], e[1], e[2] = e[0] + flt, e[1] + st, e[2] + col
                    key = (c, span, which)
                    cur = best.get(key, (float("inf"), float("inf")))
                    best[key] = (min(cur[0], ns(cpu, n)), min(cur[1], ns(eng, n)))
    print(
        f"\n2./3. whole runs and {WINDOW}-step windows, least of {args.rounds} rounds, ns per step"
    )
    print(
        f"{'configuration':34} {'whole before':>12} {'after':>9} {'after/before':>12} "
        f"{'engine':>9} {'glue before':>11} {'glue after':>10} "
        f"{'window/whole before':>19} {'after':>6}"
    )
    ratios, wb, wa = [], [], []
    for c in configs:
        b, a = best[(c, "whole", "before")], best[(c, "whole", "after")]
        bw, aw = best[(c, "window", "before")], best[(c, "window", "after")]
        ratios.append(a[0] / b[0])
        wb.append(bw[0] / b[0])
        wa.append(aw[0] / a[0])
        label = f"{c[0]} {c[1]} dt {c[2]:g}"
        print(
            f"{label:34} {b[0]:12.0f} {a[0]:9.0f} {a[0] / b[0]:12.3f} {a[1]:9.0f} "
            f"{b[0] - b[1]:11.0f} {a[0] - a[1]:10.0f} {bw[0] / b[0]:19.2f} {aw[0] / a[0]:6.2f}"
        )
    print(
        f"median after/before {statistics.median(ratios):.3f} (range {min(ratios):.3f}-"
        f"{max(ratios):.3f}); window/whole before {min(wb):.2f}-{max(wb):.2f}, "
        f"after {min(wa):.2f}-{max(wa):.2f}"
    )
    for which in ("before", "after"):
        flt, st, col = extra[which]
        print(
            f"{which}: over all its timed calls {flt} minor page faults, {st * 1e3:.1f} ms "
            f"system CPU, {col} garbage collections"
        )


if __name__ == "__main__":
    main()
