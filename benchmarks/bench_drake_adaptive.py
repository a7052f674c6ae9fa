"""Drake's error-controlled integrators: achieved attitude error against the target accuracy.

For every error-controlled integrator of the Drake adapter (references/engines/drake/)
and every target accuracy of the sweep, one run of a library scenario through the adapter
(``DrakeEngine.run``), with ``--checkpoints`` evenly spaced checkpoints (the integrator's steps
end at each one, so few checkpoints let it choose its own steps). Printed per run: target,
achieved attitude error (the largest angle of R_ref^T R over the checkpoints, against the
scenario's exact reference, references.exact), steps taken, steps rejected, dynamics
(derivative) evaluations, wall time of the stepping; a run over the adapter's step budget is
reported as cut off, with the figures of its message. The figure (``--png``) plots achieved
against target, one line per integrator, with the diagonal achieved = target.

Drake's target accuracy bounds a weighted norm of each step's local error estimate, not the
global attitude error, so achieved/target is what this measures, not what it assumes.

Usage: python benchmarks/bench_drake_adaptive.py [--scenario free_tumbling] [--t-end 20]
           [--accuracies 1e-4,1e-6,1e-8,1e-10] [--checkpoints 10] [--png drake_adaptive.png]
"""

from __future__ import annotations

import argparse
import math
import platform

import numpy as np

import scenarios
from references.engines import get_engine
from references.errors import Diverged, EngineError
from references.exact import reference_trajectory
from references.trajectory import one_body


def attitude_error(R, R_ref) -> float:
    d = np.linalg.norm(np.asarray(R) - np.asarray(R_ref), axis=(-2, -1)) / (2 * math.sqrt(2))
    return float(np.max(2 * np.arcsin(np.minimum(d, 1.0))))


def run_one(cls, sc, integrator: str, accuracy: float, t_end: float, checkpoints: int) -> dict:
    dt = t_end / checkpoints
    row = {"integrator": integrator, "target": accuracy}
    try:
        out = cls().run(sc, integrator, dt, t_end=t_end, save_every=1, accuracy=accuracy)
        row["status"] = "ok"
    except Diverged as exc:
        out = exc.output
        row["status"] = f"diverged at t = {exc.t_diverged:g} s"
    except EngineError as exc:
        row.update(status=exc.status, message=str(exc))
        return row
    tr = one_body(out.trajectory)
    ref = one_body(reference_trajectory(sc, tr.t))
    row.update(
        achieved=attitude_error(tr.rotation, ref.rotation),
        reference_accuracy=float(ref.accuracy),
        steps=out.stats.get("steps taken", math.nan),
        rejected=out.stats.get("steps rejected", math.nan),
        evaluations=out.stats.get("dynamics evaluations", math.nan),
        wall_s=out.wall_time_s,
    )
    return row


HEADER = (
    f"{'integrator':40s} {'target':>8s} {'achieved':>10s} {'steps':>8s} {'rejected':>8s} "
    f"{'evals':>9s} {'wall s':>8s}  status"
)


def format_row(r) -> str:
    if "achieved" not in r:
        return f"{r['integrator']:40s} {r['target']:8.0e}  {r['status']}: {r.get('message', '')}"
    return (
        f"{r['integrator']:40s} {r['target']:8.0e} {r['achieved']:10.3e} {r['steps']:8.0f} "
        f"{r['rejected']:8.0f} {r['evaluations']:9.0f} {r['wall_s']:8.3f}  {r['status']}"
    )


def plot(rows, path: str, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    targets = sorted({r["target"] for r in rows})
    ax.plot(targets, targets, color="0.6", lw=1, ls="--", label="achieved = target")
    for name in dict.fromkeys(r["integrator"] for r in rows):
        pts = [
            (r["target"], r["achieved"])
            for r in rows
            if r["integrator"] == name and "achieved" in r
        ]
        if pts:
            x, y = zip(*pts, strict=True)
            ax.plot(
                x, np.maximum(y, 1e-17), marker="o", label=name.replace(" (error-controlled)", "")
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.invert_xaxis()
    ax.set_xlabel("target accuracy (Drake's set_target_accuracy)")
    ax.set_ylabel("achieved attitude error, rad (max over checkpoints)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="free_tumbling")
    ap.add_argument("--t-end", type=float, default=None, help="horizon, s (default: scenario's)")
    ap.add_argument("--accuracies", default="1e-4,1e-6,1e-8,1e-10")
    ap.add_argument("--checkpoints", type=int, default=10)
    ap.add_argument("--integrators", default=None, help="comma-separated (default: every one)")
    ap.add_argument("--png", default=None, help="write the figure here")
    args = ap.parse_args()

    cls = get_engine("drake")
    why = cls.availability()
    if why is not None:
        raise SystemExit(f"Drake is not available: {why}")
    sc = scenarios.load(args.scenario)
    t_end = sc.t_end if args.t_end is None else args.t_end
    accs = [float(a) for a in args.accuracies.split(",")]
    names = [i.name for i in cls.integrators if i.adaptive]
    if args.integrators:
        names = [n for n in names if n in args.integrators.split(",")]
    print(f"drake {cls.version()}, python {platform.python_version()}, {platform.machine()}")
    print(f"scenario {sc.name}, t_end {t_end:g} s, {args.checkpoints} checkpoints")
    print(HEADER)
    rows = []
    for name in names:
        for a in accs:
            rows.append(run_one(cls, sc, name, a, t_end, args.checkpoints))
            print(format_row(rows[-1]), flush=True)
    if args.png:
        plot(rows, args.png, f"Drake error-controlled integrators, {sc.name}, {t_end:g} s")


if __name__ == "__main__":
    main()
