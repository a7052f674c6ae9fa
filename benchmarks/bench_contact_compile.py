"""Compile cost of director_model.contact's kernels: cold (an empty numba cache) and from the
cache (a second process on the same cache), per kernel, and the warm cost per step after.

Each measurement is a fresh Python process whose ``NUMBA_CACHE_DIR`` points at a new empty
folder (the first process compiles and writes the cache; the second process, on the same
folder, should only load it). In it, process CPU time (``time.process_time``: numba compiles
in the calling thread, LLVM included) is read around:

- ``import``: ``import director_model.contact`` (nothing is compiled at import);
- ``features_at``: the first ``ContactScene`` built (its initial-state check calls the
  ``features_at`` kernel);
- ``run_contact``: the first ``ContactStepper(...).advance(1)`` (the time loop);
- ``second scenes``: the other scenes of the default suite's kind (sphere, stack of boxes,
  sphere on box, a hinged body: joints) built and stepped once: zero when the call sites
  pass one type signature (``run_contact.signatures`` is printed);
- ``run_contact_batch`` (``--batch`` only): the first ``simulate_contact_batch`` (the
  parallel kernel, compiled only when a batch is asked for).

Then the warm cost of a step: thread CPU time of ``advance(2000)`` on each of the four scenes
of benchmarks/bench_contact_vs_engines.py (sphere, box, stack of 3, incline), best of 3.

    python benchmarks/bench_contact_compile.py            # cold + cached, no batch
    python benchmarks/bench_contact_compile.py --batch    # the batch kernel too
    python benchmarks/bench_contact_compile.py --cache DIR  # keep the cache in DIR (new)
    python benchmarks/bench_contact_compile.py --profile    # + compile CPU per function

``--profile``: the exclusive compile time of each numba function compiled for run_contact
(thread CPU between numba's compile events, nested compiles subtracted). A function's time
includes the optimisation of what it links in from its callees: numba re-optimises a callee's
code in every module that links it, so deep call chains show up here.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

CHILD = r"""
import json, sys, time
out = {}
c = time.process_time()
import numpy as np
import director_model.contact as dc
from director_model.contact import _kernels as K
from director_model.contact import examples as ex
out["import"] = time.process_time() - c

c = time.process_time()
box_scene = ex.block_on_incline(0.0, 0.5)
out["features_at"] = time.process_time() - c

prof = None
if "--profile" in sys.argv:
    from numba.core import event

    class Prof(event.Listener):
        # exclusive CPU time of each function's compile (nested compiles subtracted) and
        # the CPU time spent holding the LLVM lock (LLVM's optimisation and code generation)
        def __init__(self):
            self.stack, self.excl, self.llvm = [], {}, 0.0
        def on_start(self, ev):
            self.stack.append([ev, time.thread_time(), 0.0])
        def on_end(self, ev):
            ev0, t0, inner = self.stack.pop()
            dt = time.thread_time() - t0
            if ev.kind == "numba:llvm_lock":
                self.llvm += dt
                return
            name = getattr(ev.data.get("dispatcher"), "py_func", None)
            name = getattr(name, "__qualname__", "?")
            self.excl[name] = self.excl.get(name, 0.0) + dt - inner
            if self.stack:
                self.stack[-1][2] += dt
    prof = Prof()
    event.register("numba:compile", prof)
c = time.process_time()
dc.ContactStepper(box_scene, dt=1e-3, _warm=False).advance(1)
out["run_contact"] = time.process_time() - c
if prof is not None:
    event.unregister("numba:compile", prof)
    out["profile"] = sorted(prof.excl.items(), key=lambda kv: -kv[1])[:25]

c = time.process_time()
s = dc.Sphere(0.1)
b = dc.Box((0.2, 0.2, 0.1))
others = [
    ex.sphere_on_ground(1.0, 0.0, 0.3),
    ex.box_stack(3),
    dc.ContactScene(
        [dc.Body("box", 1.0, b.inertia(1.0), position=(0, 0, 0.1)),
         dc.Body("ball", 1.0, s.inertia(1.0), position=(0, 0, 0.3))],
        {"box": b, "ball": s}, {"ground": dc.Plane()},
        [dc.Pair("box", "ground", mu=0.5), dc.Pair("ball", "box", mu=0.5)],
        gravity=(0, 0, -9.81)),
    dc.ContactScene(
        [dc.Body("ball", 1.0, s.inertia(1.0), position=(0.5, 0.0, 0.1))], {"ball": s},
        {"ground": dc.Plane()}, [dc.Pair("ball", "ground", mu=0.5)],
        joints=[dc.Joint("revolute", "ball", None, anchor_a=(-0.5, 0.0, 0.0),
                         anchor_b=(0.0, 0.0, 0.1), axis_a=(0.0, 1.0, 0.0),
                         axis_b=(0.0, 1.0, 0.0))],
        gravity=(0, 0, -9.81)),
]
for sc in others:
    dc.ContactStepper(sc, dt=1e-3, _warm=False).advance(1)
out["second scenes"] = time.process_time() - c
out["run_contact signatures"] = len(K.run_contact.signatures)
out["features_at signatures"] = len(K.features_at.signatures)

if "--batch" in sys.argv:
    c = time.process_time()
    dc.simulate_contact_batch([ex.box_stack(3), ex.box_stack(3)], dt=1e-3, t_end=1e-3)
    out["run_contact_batch"] = time.process_time() - c

sys.path.insert(0, sys.argv[1])
from bench_contact_vs_engines import scenes
warm = {}
for name, (sc, _) in scenes().items():
    st = dc.ContactStepper(sc, dt=1e-3)
    st.advance(200)
    best = float("inf")
    for _ in range(3):
        c = time.thread_time()
        st.advance(2000, save_every=2000)
        best = min(best, time.thread_time() - c)
    warm[name] = best / 2000 * 1e9
out["warm ns/step"] = warm
print("RESULT " + json.dumps(out))
"""


def child(cache: str, batch: bool, profile: bool = False) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache)
    args = [sys.executable, "-c", CHILD, os.path.dirname(os.path.abspath(__file__))]
    if batch:
        args.append("--batch")
    if profile:
        args.append("--profile")
    t0 = time.perf_counter()
    p = subprocess.run(args, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
    if p.returncode != 0 or not lines:
        sys.exit(f"child process failed (exit {p.returncode}):\n{p.stderr[-3000:]}")
    out = json.loads(lines[-1][7:])
    out["wall"] = wall
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", action="store_true", help="also compile the parallel batch kernel")
    ap.add_argument("--profile", action="store_true",
                    help="print the compile CPU time of each function (exclusive)")  # fmt: skip
    ap.add_argument("--cache", help="numba cache folder to create and keep (default: a "
                    "temporary one, removed after)")  # fmt: skip
    args = ap.parse_args()
    if args.cache:
        os.makedirs(args.cache)  # must not exist: the first process must find it empty
        cold = child(args.cache, args.batch, args.profile)
        cached = child(args.cache, args.batch)
    else:
        with tempfile.TemporaryDirectory(prefix="contact-numba-") as cache:
            cold = child(cache, args.batch, args.profile)
            cached = child(cache, args.batch)
    print(f"load average {os.getloadavg()[0]:.2f}; process CPU time, s")
    print("| stage | cold (empty cache) | second process (cache) |")
    print("|---|---|---|")
    keys = ["import", "features_at", "run_contact", "second scenes"]
    if args.batch:
        keys.append("run_contact_batch")
    for k in keys:
        print(f"| {k} | {cold[k]:.2f} | {cached[k]:.2f} |")
    tot_c = sum(cold[k] for k in keys)
    tot_w = sum(cached[k] for k in keys)
    print(f"| total | {tot_c:.2f} | {tot_w:.2f} |")
    print(f"| process wall (incl. warm steps) | {cold['wall']:.1f} | {cached['wall']:.1f} |")
    print(f"signatures compiled: run_contact {cold['run_contact signatures']}, "
          f"features_at {cold['features_at signatures']}")  # fmt: skip
    for name, t in cold.get("profile", []):
        print(f"  compile {name}: {t:.2f} s (exclusive, thread CPU)")
    print("warm ns/step (thread CPU, best of 3 x 2000 steps):",
          ", ".join(f"{k} {v:.0f}" for k, v in cached["warm ns/step"].items()))  # fmt: skip


if __name__ == "__main__":
    main()
