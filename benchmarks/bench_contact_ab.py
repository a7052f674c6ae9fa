"""Warm cost per step of two versions of director_model.contact, side by side: the one this
checkout imports (B) against another source tree (A, ``--base``: a folder holding
``director_model/`` and ``benchmarks/``, e.g. ``git archive main director_model benchmarks``
unpacked; with its numba cache already built, or it compiles first).

Two worker processes, one per version (``PYTHONPATH`` and the working folder put each tree
first; each prints the ``director_model`` it imported), each holding the four scenes of
benchmarks/bench_contact_vs_engines.py (sphere, box, stack of 3, incline) warmed up by
``--warm`` steps. The parent alternates them: per repeat and scene, A then B (the order
swapped every other repeat) each advance ``--steps`` steps, thread CPU time; the best of
``--repeats`` kept. Prints ns per step and B / A.

    python benchmarks/bench_contact_ab.py --base /tmp/contact-main
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

WORKER = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1] + "/benchmarks")
import director_model
from director_model.contact import ContactStepper
from bench_contact_vs_engines import scenes
warm, steps = int(sys.argv[2]), int(sys.argv[3])
st = {}
for name, (sc, _) in scenes().items():
    st[name] = ContactStepper(sc, dt=1e-3)
    st[name].advance(warm, save_every=warm)
print(json.dumps({"module": director_model.__file__}), flush=True)
for line in sys.stdin:
    name = line.strip()
    c = time.thread_time()
    st[name].advance(steps, save_every=steps)
    print(json.dumps({"ns": (time.thread_time() - c) / steps * 1e9}), flush=True)
"""


def _worker(root: Path, warm: int, steps: int, cache: str | None) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(root))
    env.pop("NUMBA_CACHE_DIR", None)
    if cache:
        env["NUMBA_CACHE_DIR"] = cache
    p = subprocess.Popen(
        [sys.executable, "-c", WORKER, str(root), str(warm), str(steps)], env=env,
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=str(root),
    )  # fmt: skip
    hello = p.stdout.readline()
    if not hello:
        sys.exit(f"worker for {root} failed to start (see its error above)")
    print(f"{root}: imports {json.loads(hello)['module']}")
    return p


def _ask(p: subprocess.Popen, name: str) -> float:
    p.stdin.write(name + "\n")
    p.stdin.flush()
    return json.loads(p.stdout.readline())["ns"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, type=Path, help="source tree of version A")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--warm", type=int, default=500)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--cache-b", help="NUMBA_CACHE_DIR of version B (e.g. the folder "
                    "bench_contact_compile.py --cache filled); default numba's own")  # fmt: skip
    args = ap.parse_args()
    here = Path(__file__).resolve().parents[1]
    a = _worker(args.base.resolve(), args.warm, args.steps, None)
    b = _worker(here, args.warm, args.steps, args.cache_b)
    names = ["sphere", "box", "stack", "incline"]
    best = {(v, n): float("inf") for v in "AB" for n in names}
    try:
        for rep in range(args.repeats):
            for n in names:
                order = (("A", a), ("B", b)) if rep % 2 == 0 else (("B", b), ("A", a))
                for v, p in order:
                    best[v, n] = min(best[v, n], _ask(p, n))
    finally:
        for p in (a, b):
            p.stdin.close()
            p.wait()
    print(f"load average {os.getloadavg()[0]:.2f}; thread CPU, best of {args.repeats} x "
          f"{args.steps} steps, alternated")  # fmt: skip
    print("| scene | A ns/step | B ns/step | B / A |")
    print("|---|---|---|---|")
    for n in names:
        print(f"| {n} | {best['A', n]:.0f} | {best['B', n]:.0f} | "
              f"{best['B', n] / best['A', n]:.3f} |")  # fmt: skip


if __name__ == "__main__":
    main()
