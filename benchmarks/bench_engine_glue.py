"""Our per-step Python around the engines (the glue of an adapter's stepping): this checkout
against ``--before DIR`` (another checkout of director-bench, e.g. ``git archive main | tar -x
-C DIR``), side by side, thread CPU time.

Each checkout runs in a worker process of its own (this script with ``--worker``, the
checkout first on PYTHONPATH). Per configuration (engine, integrator, scenario at its dt, over
the scenario's horizon or ``--t-end``), one warm-up run on each side, then ``--rounds`` rounds
of one run on each side, their order swapped every round; printed: the least whole step (the
stepping's CPU time per step, our glue included: the row's ``ns_per_step``), the least engine
step (its engine calls alone: ``engine_ns_per_step``), the glue (their difference) and
after/before, and whether the two sides' saved states are bit for bit the same (else their
largest difference). Single bodies run through ``Engine.run``, systems through
``references.engines.system.run_system``, contact scenes through
``references.engines.contact.run_contact``, as the suite runs them.

Usage: ``python benchmarks/bench_engine_glue.py --before DIR [--rounds 3]
[--configs dart:RKMK4:free_tumbling ...]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _checkout import CheckoutWorker  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BODIES = ("free_tumbling", "heavy_top", "cone_top")
#: (engine, integrator, scenario): the default suite's configurations with the most glue
CONFIGS = [
    *[("dart", "RKMK4", s) for s in BODIES],
    *[("pinocchio", "RKMK4", s) for s in BODIES],
    *[("pinocchio", "semi-implicit Euler", s) for s in BODIES],
    *[("drake", "runge_kutta5", s) for s in BODIES],
    *[("drake", "semi_explicit_euler", s) for s in BODIES],
    ("dart", "RKMK4", "double_pendulum_3d"),
    ("dart", "RKMK4", "free_chain_5"),
    ("dart", "RKMK4", "spinning_chain"),
    ("pinocchio", "RKMK4", "free_chain_5"),
]


def worker() -> int:
    """Answer requests {engine, integrator, scenario, t_end, out} with one run's whole and
    engine CPU time per step (us); its saved states written to ``out`` (npz)."""
    import scenarios
    from references.engines import get_engine
    from references.engines.contact import run_contact
    from references.engines.system import run_system
    from references.errors import Diverged

    engines: dict = {}
    for line in sys.stdin:
        rq = json.loads(line)
        sc = scenarios.load(rq["scenario"])
        t_end = rq["t_end"]
        try:
            if sc.kind == "system":
                out = run_system(rq["engine"], sc, rq["integrator"], sc.dt, t_end)
            elif sc.kind == "contact":
                out = run_contact(rq["engine"], sc, rq["integrator"], sc.dt, t_end)
            else:
                eng = engines.setdefault(rq["engine"], get_engine(rq["engine"])())
                out = eng.run(sc, rq["integrator"], sc.dt, t_end)
        except Diverged as exc:  # a run the suite records as diverged: its steps up to there
            out = exc.output
        tr = out.trajectory
        np.savez(rq["out"], x=tr.position, R=tr.rotation, v=tr.velocity, W=tr.omega_body)
        t, n = out.timing, out.nstep
        print(json.dumps({"whole": 1e6 * t.cpu / n, "engine": 1e6 * t.engine / n, "n": n}),
              flush=True)  # fmt: skip
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, help="another checkout (required)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=None, help="default: the scenario's")
    ap.add_argument("--configs", nargs="*", help="engine:integrator:scenario")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker()
    if args.before is None:
        ap.error("--before DIR (another checkout of director-bench) is required")
    configs = [tuple(c.split(":")) for c in args.configs] if args.configs else CONFIGS
    sides = {"before": CheckoutWorker(args.before.resolve(), __file__),
             "after": CheckoutWorker(ROOT, __file__)}  # fmt: skip
    tmp = Path(tempfile.mkdtemp())
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"before: {args.before}; after: {ROOT}; thread CPU time, least of {args.rounds} "
          f"rounds; load {load}")  # fmt: skip
    print(f"{'configuration':48} {'steps':>6} {'whole before':>12} {'after':>7} {'a/b':>6} "
          f"{'engine':>7} {'glue before':>11} {'after':>6} {'a/b':>6}  states")  # fmt: skip
    for engine, integ, name in configs:
        best = {s: [np.inf, np.inf] for s in sides}
        n = 0
        for k in range(args.rounds + 1):
            order = list(sides) if k % 2 == 0 else list(sides)[::-1]
            for side in order:
                rq = {"engine": engine, "integrator": integ, "scenario": name,
                      "t_end": args.t_end, "out": str(tmp / f"{side}.npz")}  # fmt: skip
                r = sides[side].ask(rq, f"{engine} {integ} {name}")
                n = r["n"]
                if k:  # round 0 warms both sides up (imports, numba's cache)
                    b = best[side]
                    b[0], b[1] = min(b[0], r["whole"]), min(b[1], r["engine"])
        a, b = np.load(tmp / "before.npz"), np.load(tmp / "after.npz")
        diff = max(float(np.max(np.abs(a[f] - b[f]))) if a[f].shape == b[f].shape else np.inf
                   for f in ("x", "R", "v", "W"))  # fmt: skip
        same = "bit-identical" if diff == 0 else f"differ by up to {diff:.3g}"
        (bw, be), (aw, ae) = best["before"], best["after"]
        label = f"{engine} {integ} {name}"
        print(f"{label:48} {n:6d} {bw:12.2f} {aw:7.2f} {aw / bw:6.3f} {ae:7.2f} "
              f"{bw - be:11.2f} {aw - ae:6.2f} {(aw - ae) / (bw - be):6.3f}  {same}",
              flush=True)  # fmt: skip
    for s in sides.values():
        s.close()
    print("(us per step; whole: the stepping's CPU time, engine: its engine calls' CPU time "
          "(as priced by the stopwatch), glue: whole - engine)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
