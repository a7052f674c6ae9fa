"""Per body-step cost of the director's RATTLE on chains of N bodies, free and hanging, against
Pinocchio's articulated-body algorithm on the same chains, and against the goal of issue 32
(at most 350 ns per body-step at every N up to 100), in one interleaved run.

Chains: :func:`director_model.system.examples.rod_chain` (N rods of 1 m and 1 kg joined end
to end by ball joints, random tilts and joint-consistent velocities), floating in zero gravity
or hanging from a ball joint at the origin under gravity; dt = 1e-3 s.

Director: ``SystemStepper(..., scheme="rattle").advance(steps, save_every=steps)``, the
stepper's own thread CPU time of its compiled loop (one saved state). Pinocchio: the same
chain as a model of one free-flyer root (floating) or a spherical root joint (hanging) and
N - 1 spherical joints; a step is ``aba`` then ``v += h a``, ``q = integrate(q, h v)``
(semi-implicit Euler), called from Python: thread CPU time of the loop, so the figure
includes pinocchio's Python binding (a few microseconds a call, which dominates at small N:
the per body-step figure of Pinocchio is fair from N ~ 20). Each figure is the best of
``--repeats`` rounds, the configurations taken in turn within a round.

    python benchmarks/bench_system_chain_scaling.py            # N = 1, 2, 5, 10, 20, 50, 100
    python benchmarks/bench_system_chain_scaling.py --quick    # N = 2, 20; fewer steps
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from director_model.system import SystemStepper
from director_model.system.examples import rod_chain

GOAL_NS = 350.0  # issue 32: director RATTLE per body-step, every N <= 100


def director_ns(n: int, hang: bool, steps: int) -> float:
    """Thread CPU ns per body-step of ``steps`` RATTLE steps of the chain."""
    b, j = rod_chain(n, hang, seed=1)
    g = (0.0, 0.0, -9.81) if hang else (0.0, 0.0, 0.0)
    st = SystemStepper(b, j, gravity=g, scheme="rattle", dt=1e-3)
    tr = st.advance(steps, save_every=steps)
    return tr.cpu_time_s / steps / n * 1e9


def pinocchio_model(n: int, hang: bool):
    """(model, data, q, v, gravity on) of the chain in Pinocchio: the rods' masses and
    principal moments at their centres (rod axis z), each joint at the top of its rod, the
    rods hanging straight down at q = neutral (the timing does not depend on the pose)."""
    import pinocchio as pin

    model = pin.Model()
    L, m = 1.0, 1.0
    inertia = pin.Inertia(m, np.array([0.0, 0.0, -L / 2]),
                          np.diag([m * L**2 / 12 + 0.01, m * L**2 / 12 + 0.01, 0.02]))  # fmt: skip
    parent = 0
    for i in range(n):
        place = pin.SE3.Identity() if i == 0 else pin.SE3(np.eye(3), np.array([0.0, 0.0, -L]))
        if i == 0 and not hang:
            jm = pin.JointModelFreeFlyer()
        else:
            jm = pin.JointModelSpherical()
        parent = model.addJoint(parent, jm, place, f"j{i}")
        model.appendBodyToJoint(parent, inertia, pin.SE3.Identity())
    model.gravity.linear = np.array([0.0, 0.0, -9.81 if hang else 0.0])
    data = model.createData()
    rng = np.random.default_rng(1)
    q = pin.neutral(model)
    v = rng.normal(size=model.nv)
    return pin, model, data, q, v


def pinocchio_ns(n: int, hang: bool, steps: int) -> float:
    pin, model, data, q, v = pinocchio_model(n, hang)
    tau = np.zeros(model.nv)
    h = 1e-3
    t0 = time.thread_time()
    for _ in range(steps):
        a = pin.aba(model, data, q, v, tau)
        v = v + h * a
        q = pin.integrate(model, q, h * v)
    return (time.thread_time() - t0) / steps / n * 1e9


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    sizes = (2, 20) if a.quick else (1, 2, 5, 10, 20, 50, 100)
    body_steps = 20000 if a.quick else 100000
    try:
        import pinocchio  # noqa: F401

        have_pin = True
    except ImportError:
        have_pin = False
        print("# pinocchio is not installed: its column is left out")
    cfgs = [(n, hang) for hang in (False, True) for n in sizes]
    for n, hang in cfgs:  # compile or load the kernels first
        director_ns(n, hang, 2)
    best = {}
    for _ in range(a.repeats):
        for n, hang in cfgs:
            steps = max(100, body_steps // n)
            for who, fn in (("director", director_ns), ("pinocchio", pinocchio_ns)):
                if who == "pinocchio" and not have_pin:
                    continue
                key = (who, n, hang)
                best[key] = min(best.get(key, np.inf), fn(n, hang, steps))
    print(f"# {platform.processor() or platform.machine()}, load {os.getloadavg()[0]:.1f}, "
          f"best of {a.repeats} interleaved rounds, thread CPU time, ns per body-step")  # fmt: skip
    print("| chain | N | director rattle | goal 350 ns | director / goal | Pinocchio ABA + "
          "Euler (Python loop) | director / Pinocchio |")  # fmt: skip
    print("|---|--:|--:|--:|--:|--:|--:|")
    for n, hang in cfgs:
        d = best[("director", n, hang)]
        p = best.get(("pinocchio", n, hang), np.nan)
        print(f"| {'hanging' if hang else 'free'} | {n} | {d:.0f} | {GOAL_NS:.0f} | "
              f"{d / GOAL_NS:.2f} | {p:.0f} | {d / p:.2f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
