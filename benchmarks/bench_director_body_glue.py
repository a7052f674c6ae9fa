"""What the director's single-body runs count as their whole step (``ns_per_step``): this
checkout's adapter (references/engines/director/adapter.py) against that of ``--before REV``
(default ``main``), side by side, thread CPU time.

The adapter's stepping runs director_model's compiled chunk; after it, director_model computes
the invariants of the saved states and the adapter the velocity-constraint residual of each:
checks of the states, inside the run's stopwatch or not. For each of the default suite's
director single-body configurations (the scenario's dt), ``--rounds`` rounds of one run with
each adapter's chunk (order swapped every round); printed: the least whole step and engine step
of each (ns per step), the glue (whole minus engine) and after/before, and whether the saved
states are bit for bit the same.

Usage: ``python benchmarks/bench_director_body_glue.py [--before main] [--rounds 5]``
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MODULE = "references/engines/director/adapter.py"
SCENARIOS = ("cone_top", "dzhanibekov", "free_tumbling", "gazebo_boxes_complex", "heavy_top",
             "pendulum_through_vertical", "simo_wong_top")  # fmt: skip
SCHEMES = ("rattle", "rattle4", "rattle6", "energy_momentum")


def before_chunk(rev: str):
    """REV's ``DirectorEngine._chunk``, loaded beside this checkout's."""
    text = subprocess.run(["git", "show", f"{rev}:{MODULE}"], cwd=ROOT, check=True,
                          capture_output=True, text=True).stdout  # fmt: skip
    path = Path(tempfile.mkdtemp()) / "director_adapter_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("director_adapter_before", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.DirectorEngine._chunk


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="main")
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    import scenarios
    from references.engines.director.adapter import DirectorEngine

    chunks = {"before": before_chunk(args.before), "after": DirectorEngine._chunk}
    scs = {n: scenarios.load(n) for n in SCENARIOS}
    configs = [(n, s) for n in SCENARIOS for s in SCHEMES]
    load = " ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"before: {args.before}; after: this checkout; thread CPU time; load {load}")

    def run(side, name, scheme):
        DirectorEngine._chunk = chunks[side]
        try:
            return DirectorEngine().run(scs[name], scheme, scs[name].dt)
        finally:
            DirectorEngine._chunk = chunks["after"]

    best, same = {}, 0
    for name, scheme in configs:  # once each, untimed, its states compared
        a, b = (run(side, name, scheme).trajectory for side in ("before", "after"))
        same += all(np.array_equal(getattr(a, f), getattr(b, f))
                    for f in ("t", "position", "velocity", "rotation", "omega_body"))  # fmt: skip
    for k in range(args.rounds):
        for i, (name, scheme) in enumerate(configs):
            for side in ("before", "after") if (k + i) % 2 == 0 else ("after", "before"):
                out = run(side, name, scheme)
                t, n = out.timing, out.nstep
                key = (name, scheme, side)
                old = best.get(key, (np.inf, np.inf))
                best[key] = (min(old[0], 1e9 * t.cpu / n), min(old[1], 1e9 * t.engine / n))
    print(f"saved states bit-identical before and after: {same}/{len(configs)}")
    print(f"{'configuration':42} {'whole before':>12} {'after':>7} {'after/before':>12} "
          f"{'engine':>7} {'glue before':>11} {'after':>6}")  # fmt: skip
    ratios = []
    for name, scheme in configs:
        (bw, be), (aw, ae) = best[(name, scheme, "before")], best[(name, scheme, "after")]
        ratios.append(aw / bw)
        label = f"{name} {scheme} dt {scs[name].dt:g}"
        print(f"{label:42} {bw:12.0f} {aw:7.0f} {aw / bw:12.3f} {ae:7.0f} {bw - be:11.0f} "
              f"{aw - ae:6.0f}")  # fmt: skip
    print(
        f"median after/before {statistics.median(ratios):.3f} ({min(ratios):.3f}-"
        f"{max(ratios):.3f}); ns per step, least of {args.rounds} rounds"
    )


if __name__ == "__main__":
    main()
