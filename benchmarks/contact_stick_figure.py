"""The exact-stick figure: a box below its friction angle on a 15 degree incline, the distance
its centre of mass has moved over 10 s, director_model.contact against MuJoCo (elliptic and
pyramidal cones, Newton solver) and PyBullet, on a log axis (the exact motion is none).

The scene and the engines' models are those of ``benchmarks/bench_contact_vs_engines.py``
(box 0.1 x 0.1 x 0.05 m, 2 kg, mu 0.4, tan 15 deg = 0.27 < 0.4; dt = 1e-3 s). A distance below
1e-20 m (0 included) is drawn at 1e-20 m, the axis' floor, and the legend says so.

Usage: python benchmarks/contact_stick_figure.py [--out docs/figures/contact_stick.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from bench_contact_vs_engines import mujoco_model, pybullet_world, scenes  # noqa: E402

from director_model.contact import ContactStepper  # noqa: E402

FLOOR = 1e-20
T, DT, EVERY = 10.0, 1e-3, 10


def director(scene):
    n = int(round(T / DT))
    tr = ContactStepper(scene, dt=DT).advance(n, save_every=EVERY, include_start=True)
    x = tr.position[:, 0]
    return tr.t, np.linalg.norm(x - x[0], axis=1)


def mujoco_run(geoms, cone):
    import mujoco

    m, d = mujoco_model("incline", geoms, cone)
    x0 = d.qpos[0:3].copy()
    t, dist = [0.0], [0.0]
    for k in range(int(round(T / DT)) // EVERY):
        mujoco.mj_step(m, d, nstep=EVERY)
        t.append((k + 1) * EVERY * DT)
        dist.append(float(np.linalg.norm(d.qpos[0:3] - x0)))
    return np.array(t), np.array(dist)


def pybullet_run(geoms):
    import pybullet as pb

    cid, step = pybullet_world("incline", geoms)
    body = 1  # the plane is body 0
    x0 = np.array(pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0])
    t, dist = [0.0], [0.0]
    for k in range(int(round(T / DT)) // EVERY):
        step(EVERY)
        x = np.array(pb.getBasePositionAndOrientation(body, physicsClientId=cid)[0])
        t.append((k + 1) * EVERY * DT)
        dist.append(float(np.linalg.norm(x - x0)))
    pb.disconnect(cid)
    return np.array(t), np.array(dist)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="docs/figures/contact_stick.png")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scene, geoms = scenes()["incline"]
    curves = {"director (nonsmooth RATTLE)": director(scene)}
    for cone in ("elliptic", "pyramidal"):
        curves[f"MuJoCo {cone} + Newton"] = mujoco_run(geoms, cone)
    curves["PyBullet (default)"] = pybullet_run(geoms)
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, (t, d) in curves.items():
        zero = d[1:] < FLOOR
        label = f"{name}: {d[-1]:.2g} m at {T:g} s"
        if zero.any():
            label += f" (below {FLOOR:g} drawn at {FLOOR:g})"
        ax.plot(t[1:], np.maximum(d[1:], FLOOR), label=label)
        print(f"{name}: distance moved after {T:g} s {d[-1]:.3g} m, largest {d.max():.3g} m")
    ax.set_yscale("log")
    ax.set_ylim(FLOOR / 2, 1.0)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("distance moved by the centre of mass (m)")
    ax.set_title("Box at rest on a 15 deg incline, mu = 0.4 (exact motion: none), dt = 1e-3 s")
    ax.legend(fontsize=8, loc="center right")
    ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"written: {args.out}")


if __name__ == "__main__":
    main()
