"""Which joint kinds each system builder builds, in a tree and as a loop closure, found by
running them: ``python -m references.engines.joint_coverage [--engines a,b] [--plants]``.

For every engine with a system builder, every joint kind of ``director_model.system`` (a fixed
point is a spherical joint to the ground, so it is not a column of its own) and both roles,
one short run (the conformance kit's integrator and step,
:data:`~references.engines.system_conformance.RUNS`; the loop integrator of
:data:`~references.engines.system_conformance.LOOP_RUNS` for a closure) of a system built for
the purpose:

- tree: :func:`tree_probe`, two links at rest, ``link0`` on a spherical joint to the ground,
  ``link1`` on a joint ``h1`` of the kind to ``link0``;
- closure: :func:`~references.engines.system_conformance.closure_loop`, two links on
  spherical joints to the ground joined to each other by ``h1`` of the kind (the loop).

A cell is ``built`` when the run completes, ``unsupported`` with the builder's own reason when
it raises :class:`~references.errors.Unsupported`, ``error`` with the message otherwise (a
fault to report). With ``--plants`` a built cell also runs the kit's planted mistakes on ``h1``
(:data:`~references.engines.system_conformance.MISTAKES` in a tree, the axis one only where the
kind has an axis; :data:`~references.engines.system_conformance.CLOSURE_MISTAKES` on a closure)
and shows how many of them the builder refused naming ``h1``.

The table is printed as Markdown, the reasons numbered below it; ``--json`` prints the cells.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from references import conventions as cv
from references.engines import system_conformance as kit
from references.errors import Unsupported

#: the columns: every joint kind of the director model but the fixed point (a spherical joint
#: to the ground)
KINDS = ("spherical", "revolute", "universal", "cylindrical", "prismatic")
ROLES = ("tree", "closure")
#: the engines with a system builder, in the table's order
ENGINES = ("director", "mujoco", "mjx", "pinocchio", "dart", "pybullet", "drake")


def tree_probe(kind: str, seed: int = 11):
    """(bodies, joints): ``link0`` on a spherical joint ``h0`` to the ground at the origin,
    ``link1`` on a joint ``h1`` of ``kind`` to ``link0`` at link0's lower end; random
    attitudes, random axes (a universal's perpendicular), link0 turning at random and link1
    moving relative to it along every freedom of ``h1`` (so that an axis in the wrong frame
    shows in the rates as well as in the attitudes)."""
    from director_model.system import Body, Joint

    rng = np.random.default_rng(seed)
    Y = np.array([0.0, 0.0, 0.5])
    R0, R1 = (cv.rotvec_to_matrix(0.7 * rng.normal(size=3)) for _ in range(2))
    x0 = -R0 @ Y
    tip = x0 - R0 @ Y
    x1 = tip - R1 @ Y
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    w = np.cross(u, rng.normal(size=3)) if kind == "universal" else u
    w /= np.linalg.norm(w)
    w0 = rng.normal(size=3)
    rel, slide = {
        "spherical": (rng.normal(size=3), 0.0),
        "revolute": (1.3 * u, 0.0),
        "universal": (1.3 * u + 0.8 * w, 0.0),
        "cylindrical": (1.3 * u, 0.4),
        "prismatic": (np.zeros(3), 0.4),
    }[kind]
    w1 = w0 + rel
    v0 = np.cross(w0, x0)
    v1 = np.cross(w0, tip) + np.cross(w1, x1 - tip) + slide * u
    bodies = [Body("link0", 1.0, (0.09, 0.1, 0.02), x0, R0, v0, R0.T @ w0),
              Body("link1", 1.3, (0.12, 0.125, 0.03), x1, R1, v1, R1.T @ w1)]  # fmt: skip
    axes = (R0.T @ u, R1.T @ w) if kind != "spherical" else (None, None)
    joints = [Joint("spherical", "link0", None, Y, (0, 0, 0), name="h0"),
              Joint(kind, "link0", "link1", -Y, Y, *axes, name="h1")]  # fmt: skip
    return bodies, joints


def probe(engine: str, kind: str, role: str, plants: bool = False) -> dict:
    """One cell: {"status": built | unsupported | error, "reason": ..., "plants": (caught,
    planted) or None}."""
    loop = role == "closure"
    parts = kit.closure_loop(kind) if loop else tree_probe(kind)
    sc = kit.scenario(f"probe-{kind}-{role}", *parts)
    try:
        kit.run(engine, sc, loop)
    except Unsupported as exc:
        return {"status": "unsupported", "reason": str(exc), "plants": None}
    except Exception as exc:  # noqa: BLE001 - a cell of the table, never raised
        return {"status": "error", "reason": f"{type(exc).__name__}: {exc}", "plants": None}
    caught = None
    if plants:
        # the director has no tree or closure: its plants are on the joint (the kit's MISTAKES)
        mistakes = kit.CLOSURE_MISTAKES if loop and engine != "director" else kit.MISTAKES
        if kind == "spherical":  # no axis to put in the wrong frame
            mistakes = mistakes[1:]
        checks = kit.check_mistakes(engine, False, sc, mistakes)
        caught = (sum(c.ok for c in checks), len(checks))
    return {"status": "built", "reason": "", "plants": caught}


def coverage(engines=ENGINES, plants: bool = False, progress=None) -> dict:
    """{(engine, role, kind): cell} for every engine, role and kind (:func:`probe`); an engine
    whose adapter is broken or not installed gets that reason in every cell."""
    from references.engines import get_engine

    cells = {}
    for engine in engines:
        broken = get_engine(engine).broken
        for role in ROLES:
            for kind in KINDS:
                if progress:
                    progress(f"{engine} {role} {kind}")
                cells[engine, role, kind] = (
                    {"status": "unsupported", "reason": f"{engine}: {broken}", "plants": None}
                    if broken
                    else probe(engine, kind, role, plants)
                )
    return cells


def table(cells: dict) -> str:
    """The Markdown table of :func:`coverage`'s cells, the reasons numbered below it."""
    engines = list(dict.fromkeys(e for e, _, _ in cells))
    reasons: dict[str, int] = {}
    lines = ["| engine | role | " + " | ".join(KINDS) + " |",
             "|---|---|" + "---|" * len(KINDS)]  # fmt: skip
    for engine in engines:
        for role in ROLES:
            row = []
            for kind in KINDS:
                c = cells[engine, role, kind]
                if c["status"] == "built":
                    p = c["plants"]
                    row.append("built" + (f" ({p[0]}/{p[1]} plants caught)" if p else ""))
                else:
                    n = reasons.setdefault(c["reason"], len(reasons) + 1)
                    row.append(f"{c['status']} [{n}]")
            lines.append(f"| {engine} | {role} | " + " | ".join(row) + " |")
    lines.append("")
    lines += [f"[{n}] {r}" for r, n in reasons.items()]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m references.engines.joint_coverage",
        description="Run every system builder on each joint kind in a tree and as a loop "
        "closure and print which are built (and, with --plants, how many of the conformance "
        "kit's planted mistakes each refuses).",
    )
    ap.add_argument("--engines", default=",".join(ENGINES),
                    help=f"comma-separated engines (default: {','.join(ENGINES)})")  # fmt: skip
    ap.add_argument("--plants", action="store_true", help="also run the kit's planted mistakes")
    ap.add_argument("--json", action="store_true", help="print the cells as JSON")
    args = ap.parse_args(argv)
    engines = [e.strip() for e in args.engines.split(",") if e.strip()]
    unknown = sorted(set(engines) - set(ENGINES))
    if unknown:
        ap.error(f"--engines: {unknown} have no system builder; known: {list(ENGINES)}")
    cells = coverage(engines, args.plants,
                     lambda s: print(f"probing {s}", file=sys.stderr, flush=True))  # fmt: skip
    if args.json:
        print(json.dumps([{"engine": e, "role": r, "kind": k, **c}
                          for (e, r, k), c in cells.items()], indent=1))  # fmt: skip
    else:
        print(table(cells))
    return 1 if any(c["status"] == "error" for c in cells.values()) else 0


if __name__ == "__main__":
    raise SystemExit(main())
