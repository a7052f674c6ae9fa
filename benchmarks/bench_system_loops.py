"""Per-step cost of the director model's RATTLE schemes on closed loops against an open chain
of as many bodies, before and after the pivoted factorisations, in one interleaved run.

Systems: the library's ``four_bar`` (3 bodies, 20 joint rows of rank 17, through its singular
configuration) and ``bricard`` (5 bodies, 30 rows of rank 29), and open chains of 3, 4 and 5
rods hanging from a ball joint (director_model.system.examples.rod_chain: ball joints, the
block solver). Solvers on the loops: ``svd`` (the SVD of both multiplier matrices at every
sub-step: the code before) and ``minnorm`` (LU with complete pivoting and L D L^T with
diagonal pivoting, the SVD only where a kept pivot falls below 1e-8 of the first). Schemes:
rattle, rattle4, rattle6 at dt = 1e-3 s.

Timing: thread CPU time (``time.thread_time``, the stepper's own figure: the compiled stepping
alone) of ``--steps`` steps, the configurations taken in turn and the round repeated
``--repeats`` times, the best kept (interleaving spreads the machine's load over all of them
alike). Printed: ns per step, the loop's ratio to the open chain of as many bodies (the goal
of issue 32: within 3x), and after/before. The first call of each configuration (compilation,
cache load) is outside the timing.

    python benchmarks/bench_system_loops.py              # 2000 steps, 5 rounds
    python benchmarks/bench_system_loops.py --quick      # 300 steps, 3 rounds
"""

from __future__ import annotations

import argparse
import os
import platform

import numpy as np

import scenarios
from director_model.system import Body, Joint, SystemStepper
from director_model.system.examples import rod_chain

SCHEMES = ("rattle", "rattle4", "rattle6")


def from_scenario(name: str):
    """(bodies, joints, gravity) of a library system as director_model.system objects."""
    sc = scenarios.load(name)
    bodies = [Body(b.name, b.mass, b.inertia, b.position, b.rotation, b.velocity,
                   b.omega_body) for b in sc.bodies]  # fmt: skip
    joints = [Joint(j.kind, j.body_a, j.body_b, j.anchor_a, j.anchor_b, j.axis_a, j.axis_b,
                    name=j.name) for j in sc.joints]  # fmt: skip
    return bodies, joints, tuple(sc.gravity)


def configs():
    """(label, nbodies, bodies, joints, gravity, solver) of every timed configuration."""
    out = []
    for name in ("four_bar", "bricard"):
        b, j, g = from_scenario(name)
        for solver in ("svd", "minnorm"):
            out.append((f"{name} {solver}", len(b), b, j, g, solver))
    for n in (3, 4, 5):
        b, j = rod_chain(n, True, seed=1)
        out.append((f"chain{n}", n, b, j, (0.0, 0.0, -9.81), "auto"))
    return out


def time_one(cfg, scheme: str, steps: int) -> float:
    """Thread CPU time per step (ns) of ``steps`` steps from the initial state."""
    _, _, bodies, joints, g, solver = cfg
    st = SystemStepper(bodies, joints, gravity=g, scheme=scheme, dt=1e-3, solver=solver)
    tr = st.advance(steps, save_every=steps)
    return tr.cpu_time_s / steps * 1e9


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    if a.quick:
        a.steps, a.repeats = 300, 3
    cfgs = configs()
    for cfg in cfgs:  # compile or load every kernel first
        for scheme in SCHEMES:
            time_one(cfg, scheme, 2)
    best = {(c[0], s): np.inf for c in cfgs for s in SCHEMES}
    for _ in range(a.repeats):
        for scheme in SCHEMES:
            for cfg in cfgs:
                best[(cfg[0], scheme)] = min(best[(cfg[0], scheme)], time_one(cfg, scheme, a.steps))
    print(f"# {platform.processor() or platform.machine()}, load {os.getloadavg()[0]:.1f}, "
          f"{a.steps} steps, best of {a.repeats} interleaved rounds, thread CPU time")  # fmt: skip
    print("| system | bodies | solver | " + " | ".join(f"{s} ns/step" for s in SCHEMES)
          + " | " + " | ".join(f"{s} / chain" for s in SCHEMES) + " |")  # fmt: skip
    print("|---" * (3 + 2 * len(SCHEMES)) + "|")
    for label, nb, *_rest in cfgs:
        chain = f"chain{nb}"
        cells = [f"{best[(label, s)]:.0f}" for s in SCHEMES]
        ratio = [f"{best[(label, s)] / best[(chain, s)]:.1f}x" for s in SCHEMES]
        name, _, solver = label.partition(" ")
        print(f"| {name} | {nb} | {solver or 'auto (block)'} | " + " | ".join(cells) + " | "
              + " | ".join(ratio) + " |")  # fmt: skip
    print()
    for name in ("four_bar", "bricard"):
        r = [best[(f"{name} svd", s)] / best[(f"{name} minnorm", s)] for s in SCHEMES]
        print(f"{name}: before / after = " + ", ".join(f"{s} {x:.1f}x" for s, x in
                                                      zip(SCHEMES, r, strict=True)))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
