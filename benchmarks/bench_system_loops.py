"""Per-step cost of the director model's RATTLE schemes on closed loops against open chains of
as many bodies, this checkout against another one (``--before``, e.g. a git worktree of main),
in one interleaved run.

Systems: the library's ``four_bar`` (3 bodies, 20 joint rows of rank 17, through its singular
configuration) and ``bricard`` (5 bodies, 30 rows of rank 29) with the loop solver
("minnorm"), and open chains of 3, 4 and 5 rods hanging from a ball joint
(director_model.system.examples.rod_chain: ball joints, the block solver). With ``--svd``
the loops also with the SVD at every solve ("svd"). Schemes: rattle, rattle4, rattle6 at
dt = 1e-3 s, from the initial state.

Each checkout runs in a worker process of its own (this script with ``--worker``, the
checkout first on PYTHONPATH), so that two versions of the same package can be timed side by
side. Timing: thread CPU time (``time.thread_time`` inside the stepper, the compiled stepping
alone) of ``--steps`` steps; the workers are asked in turn, configuration by configuration,
and the round repeated ``--repeats`` times, the best kept (interleaving spreads the machine's
load over all of them alike). The first call of each configuration (compilation, cache load)
is outside the timing. Printed: ns per step, the loop's ratio to the open chain of as many
bodies of the same checkout (the goal of issue 32: within 3x), and before / after.

    python benchmarks/bench_system_loops.py                          # this checkout only
    python benchmarks/bench_system_loops.py --before /tmp/main-wt    # against another
    python benchmarks/bench_system_loops.py --quick                  # 300 steps, 3 rounds
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

from _checkout import CheckoutWorker

SCHEMES = ("rattle", "rattle4", "rattle6")
ROOT = Path(__file__).resolve().parent.parent


def configs(svd: bool):
    """(label, number of bodies) of every timed configuration."""
    out = []
    for name, nb in (("four_bar", 3), ("bricard", 5)):
        for solver in ("minnorm", "svd") if svd else ("minnorm",):
            out.append((f"{name} {solver}", nb))
    out += [(f"chain{n}", n) for n in (3, 4, 5)]
    return out


def _build(label: str):
    """(bodies, joints, gravity, solver) of a configuration, with the importing checkout's
    own code (in the worker)."""
    import scenarios
    from director_model.system import Body, Joint
    from director_model.system.examples import rod_chain

    if label.startswith("chain"):
        b, j = rod_chain(int(label[5:]), True, seed=1)
        return b, j, (0.0, 0.0, -9.81), "auto"
    name, solver = label.split()
    sc = scenarios.load(name)
    bodies = [Body(b.name, b.mass, b.inertia, b.position, b.rotation, b.velocity,
                   b.omega_body) for b in sc.bodies]  # fmt: skip
    joints = [Joint(j.kind, j.body_a, j.body_b, j.anchor_a, j.anchor_b, j.axis_a, j.axis_b,
                    name=j.name) for j in sc.joints]  # fmt: skip
    return bodies, joints, tuple(sc.gravity), solver


def worker() -> int:
    """Answer one JSON request a line on stdin ({"label", "scheme", "steps"}) with the thread
    CPU time per step in ns ({"ns"}) on stdout."""
    from director_model.system import SystemStepper

    built = {}
    for line in sys.stdin:
        req = json.loads(line)
        if req["label"] not in built:
            built[req["label"]] = _build(req["label"])
        bodies, joints, g, solver = built[req["label"]]
        st = SystemStepper(bodies, joints, gravity=g, scheme=req["scheme"], dt=1e-3,
                           solver=solver)  # fmt: skip
        tr = st.advance(req["steps"], save_every=req["steps"])
        print(json.dumps({"ns": tr.cpu_time_s / req["steps"] * 1e9}), flush=True)
    return 0


class Worker(CheckoutWorker):
    """A worker process importing the checkout at ``root``."""

    def __init__(self, root: Path):
        super().__init__(root, __file__)

    def time(self, label: str, scheme: str, steps: int) -> float:
        req = {"label": label, "scheme": scheme, "steps": steps}
        return self.ask(req, f"{label} {scheme}")["ns"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--before", type=Path, help="another checkout to time alongside this one")
    ap.add_argument("--svd", action="store_true", help="also the loops with solver='svd'")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        return worker()
    if a.quick:
        a.steps, a.repeats = 300, 3
    cfgs = configs(a.svd)
    versions = {"after": Worker(ROOT)}
    if a.before is not None:
        versions = {"before": Worker(a.before.resolve()), **versions}
    try:
        for w in versions.values():  # compile or load every kernel first
            for label, _ in cfgs:
                for scheme in SCHEMES:
                    w.time(label, scheme, 2)
        best = {}
        for _ in range(a.repeats):
            for scheme in SCHEMES:
                for label, _ in cfgs:
                    for v, w in versions.items():
                        t = w.time(label, scheme, a.steps)
                        best[(v, label, scheme)] = min(best.get((v, label, scheme), t), t)
    finally:
        for w in versions.values():
            w.close()
    print(f"# {platform.processor() or platform.machine()}, load {os.getloadavg()[0]:.1f}, "
          f"{a.steps} steps, best of {a.repeats} interleaved rounds, thread CPU time; "
          f"before = {a.before}, after = {ROOT}")  # fmt: skip
    print("| system | bodies | solver | code | " + " | ".join(f"{s} ns/step" for s in SCHEMES)
          + " | " + " | ".join(f"{s} / chain" for s in SCHEMES) + " |")  # fmt: skip
    print("|---" * (4 + 2 * len(SCHEMES)) + "|")
    for label, nb in cfgs:
        name, _, solver = label.partition(" ")
        for v in versions:
            cells = [f"{best[(v, label, s)]:.0f}" for s in SCHEMES]
            ratio = [f"{best[(v, label, s)] / best[(v, f'chain{nb}', s)]:.1f}x" for s in SCHEMES]
            print(f"| {name} | {nb} | {solver or 'auto (block)'} | {v} | " + " | ".join(cells)
                  + " | " + " | ".join(ratio) + " |")  # fmt: skip
    if "before" in versions:
        print()
        for label, _ in cfgs:
            r = [best[("before", label, s)] / best[("after", label, s)] for s in SCHEMES]
            print(f"{label}: before / after = " + ", ".join(
                f"{s} {x:.2f}x" for s, x in zip(SCHEMES, r, strict=True)))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
