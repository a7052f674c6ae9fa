"""The force elements' glue on the engines that take them from the suite at every evaluation
(Pinocchio: a generalised force at each Euler step or RKMK4 stage; PyBullet: external forces
before each step; DART: body forces before each step): this checkout's code against that of
``--before REV`` (default ``main``), side by side, thread CPU time.

The "before" side is REV's scenarios/force_elements.py and each engine's forces.py and
system.py, loaded beside this checkout's and wired to each other. Per configuration (engine,
integrator, scenario, steps), ``--rounds`` rounds of one whole run on each side (their order
swapped every round) through ``references.engines.system.run_system``; printed: the least
whole step (the stepping's CPU time per step, our glue included) and engine step (the
engine's calls alone) of each side, the glue (their difference) and after/before, and
whether the two sides' saved states are bit for bit the same (else their largest
difference).

Usage: ``python benchmarks/bench_force_glue.py [--before main] [--rounds 5]
[--engines pinocchio pybullet dart]``
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: (engine, integrator, scenario, steps): the library's systems with force elements (A05: two
#: spring-dampers on a tree; A03: a spring and a motor torque on a loop mechanism)
CONFIGS = [
    ("pinocchio", "semi-implicit Euler", "iftomm_a05", 2000),
    ("pinocchio", "RKMK4", "iftomm_a05", 1000),
    ("pinocchio", "semi-implicit Euler", "iftomm_a03", 1000),
    ("pinocchio", "RKMK4", "iftomm_a03", 500),
    ("pybullet", "multibody", "iftomm_a05", 2000),
    ("pybullet", "multibody", "iftomm_a03", 1000),
    ("dart", "semi-implicit Euler", "iftomm_a05", 2000),
]


def _load(rev: str, path: str, name: str):
    text = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout  # fmt: skip
    file = Path(tempfile.mkdtemp()) / f"{name}.py"
    file.write_text(text)
    spec = importlib.util.spec_from_file_location(name, file)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def before_builders(rev: str, engines) -> dict:
    """engine -> REV's simulate_system, its forces.py and force_elements.py its own."""
    fe = _load(rev, "scenarios/force_elements.py", "force_elements_before")
    out = {}
    for e in engines:
        forces = _load(rev, f"references/engines/{e}/forces.py", f"{e}_forces_before")
        forces.fe = fe
        system = _load(rev, f"references/engines/{e}/system.py", f"{e}_system_before")
        system.forces = forces
        out[e] = system.simulate_system
    return out


def run(engine: str, fn, sc, integrator: str, dt: float, steps: int):
    """One run of ``engine``'s builder ``fn``: (whole s, engine s, steps, states)."""
    from references.engines.system import run_system

    mod = importlib.import_module(f"references.engines.{engine}.system")
    mine = mod.simulate_system
    mod.simulate_system = fn
    try:
        out = run_system(engine, sc, integrator, dt, steps * dt, steps // 10)
    finally:
        mod.simulate_system = mine
    tr = out.trajectory
    states = (tr.position, tr.rotation, tr.velocity, tr.omega_body)
    return out.timing.cpu, out.timing.engine, out.nstep, states


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="main")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--engines", nargs="*", default=["pinocchio", "pybullet", "dart"])
    args = ap.parse_args()
    import scenarios

    engines = []
    for e in args.engines:
        try:
            importlib.import_module(f"references.engines.{e}.system")
            engines.append(e)
        except Exception as exc:  # noqa: BLE001 - an engine not installed: said, skipped
            print(f"{e}: skipped ({exc})")
    configs = [c for c in CONFIGS if c[0] in engines]
    before = before_builders(args.before, engines)
    after = {e: importlib.import_module(f"references.engines.{e}.system").simulate_system
             for e in engines}  # fmt: skip
    scs = {c[2]: scenarios.load(c[2]) for c in configs}
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"before: {args.before}; after: this checkout; thread CPU time; load {load}")
    print(f"{'configuration':44} {'whole before':>12} {'after':>8} {'after/before':>12} "
          f"{'engine':>7} {'glue before':>11} {'after':>7} {'glue a/b':>8}  states")  # fmt: skip
    for engine, integ, name, steps in configs:
        sc = scs[name]
        best = {"before": [np.inf, np.inf], "after": [np.inf, np.inf]}
        states = {}
        for k in range(args.rounds):
            for side in ("before", "after") if k % 2 == 0 else ("after", "before"):
                fn = (before if side == "before" else after)[engine]
                cpu, eng, n, st = run(engine, fn, sc, integ, sc.dt, steps)
                b = best[side]
                b[0], b[1] = min(b[0], 1e6 * cpu / n), min(b[1], 1e6 * eng / n)
                states.setdefault(side, st)
        diff = max(float(np.max(np.abs(a - b)))
                   for a, b in zip(states["before"], states["after"], strict=True))  # fmt: skip
        same = "bit-identical" if diff == 0 else f"differ by up to {diff:.3g}"
        (bw, be), (aw, ae) = best["before"], best["after"]
        label = f"{engine} {integ} {name} ({steps} steps)"
        print(f"{label:44} {bw:12.1f} {aw:8.1f} {aw / bw:12.3f} {ae:7.1f} {bw - be:11.1f} "
              f"{aw - ae:7.1f} {(aw - ae) / (bw - be):8.3f}  {same}")  # fmt: skip
    print(
        "(us per step: whole = the stepping's CPU time with our glue, engine = its calls; "
        f"least of {args.rounds} rounds)"
    )


if __name__ == "__main__":
    sys.exit(main())
