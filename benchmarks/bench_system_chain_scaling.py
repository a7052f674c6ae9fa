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

With ``--before PATH`` (another checkout, e.g. a git worktree of main) the director's chains
are also timed with that checkout's code: each checkout then runs in a worker process of its
own (this script with ``--worker``, the checkout first on PYTHONPATH; both alike, so that
neither shares a process with Pinocchio's runs), asked in turn: a before and an after column
measured side by side.

    python benchmarks/bench_system_chain_scaling.py            # N = 1, 2, 5, 10, 20, 50, 100
    python benchmarks/bench_system_chain_scaling.py --quick    # N = 2, 20; fewer steps
    python benchmarks/bench_system_chain_scaling.py --before /tmp/main-wt
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from _checkout import CheckoutWorker

from director_model.system import SystemStepper
from director_model.system.examples import rod_chain

GOAL_NS = 350.0  # issue 32: director RATTLE per body-step, every N <= 100
ROOT = Path(__file__).resolve().parent.parent


def director_ns(n: int, hang: bool, steps: int) -> float:
    """Thread CPU ns per body-step of ``steps`` RATTLE steps of the chain."""
    b, j = rod_chain(n, hang, seed=1)
    g = (0.0, 0.0, -9.81) if hang else (0.0, 0.0, 0.0)
    st = SystemStepper(b, j, gravity=g, scheme="rattle", dt=1e-3)
    tr = st.advance(steps, save_every=steps)
    return tr.cpu_time_s / steps / n * 1e9


def worker() -> int:
    """Answer one JSON request a line on stdin ({"n", "hang", "steps"}) with
    :func:`director_ns` ({"ns"}) on stdout."""
    for line in sys.stdin:
        req = json.loads(line)
        ns = director_ns(req["n"], req["hang"], req["steps"])
        print(json.dumps({"ns": ns}), flush=True)
    return 0


class Checkout(CheckoutWorker):
    """A worker process timing the director's chains with the checkout at ``root``."""

    def __init__(self, root: Path):
        super().__init__(root, __file__)

    def __call__(self, n: int, hang: bool, steps: int) -> float:
        return self.ask({"n": n, "hang": hang, "steps": steps}, f"N = {n}")["ns"]


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
    ap.add_argument("--before", type=Path, help="another checkout whose director to time too")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        return worker()
    sizes = (2, 20) if a.quick else (1, 2, 5, 10, 20, 50, 100)
    body_steps = 20000 if a.quick else 100000
    try:
        import pinocchio  # noqa: F401

        have_pin = True
    except ImportError:
        have_pin = False
        print("# pinocchio is not installed: its column is left out")
    cfgs = [(n, hang) for hang in (False, True) for n in sizes]
    who_fn = [("director", director_ns)]
    before = Checkout(a.before.resolve()) if a.before is not None else None
    if before is not None:
        who_fn = [("before", before), ("director", Checkout(ROOT))]
    if have_pin:
        who_fn.append(("pinocchio", pinocchio_ns))
    best = {}
    try:
        for n, hang in cfgs:  # compile or load the kernels first
            for who, fn in who_fn[:2]:
                if who != "pinocchio":
                    fn(n, hang, 2)
        for _ in range(a.repeats):
            for n, hang in cfgs:
                steps = max(100, body_steps // n)
                for who, fn in who_fn:
                    key = (who, n, hang)
                    best[key] = min(best.get(key, np.inf), fn(n, hang, steps))
    finally:
        for _, fn in who_fn:
            if isinstance(fn, Checkout):
                fn.close()
    print(f"# {platform.processor() or platform.machine()}, load {os.getloadavg()[0]:.1f}, "
          f"best of {a.repeats} interleaved rounds, thread CPU time, ns per body-step")  # fmt: skip
    if before is not None:
        print(f"# before = {a.before}")
    head = "| chain | N | " + ("director before | before / after | " if before else "")
    print(head + "director rattle | goal 350 ns | director / goal | Pinocchio ABA + Euler "
          "(Python loop) | director / Pinocchio |")  # fmt: skip
    print("|---|--:|" + ("--:|--:|" if before else "") + "--:|--:|--:|--:|--:|")
    for n, hang in cfgs:
        d = best[("director", n, hang)]
        p = best.get(("pinocchio", n, hang), np.nan)
        cells = ""
        if before is not None:
            b = best[("before", n, hang)]
            cells = f"{b:.0f} | {b / d:.2f} | "
        print(f"| {'hanging' if hang else 'free'} | {n} | {cells}{d:.0f} | {GOAL_NS:.0f} | "
              f"{d / GOAL_NS:.2f} | {p:.0f} | {d / p:.2f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
