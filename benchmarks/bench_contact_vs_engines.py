"""Cost per step of director_model.contact against MuJoCo's mj_step and PyBullet's
stepSimulation on the same contact scenes, and MuJoCo's creep where the director holds still.

Scenes (SI, dt = 1e-3 s, gravity 9.81 m/s^2, solid shapes of uniform density, the same masses,
moments, sizes, friction and initial states in both):

- ``sphere``: a sphere (r 0.1 m, 1 kg, mu 0.3) on a plane, launched at 1 m/s: it slides, then
  rolls (one contact);
- ``box``: a box (half extents 0.1 m, 1 kg, mu 0.5) resting on a plane (four contacts);
- ``stack``: three boxes (half extents 0.2/0.16/0.12 x same x 0.05 m, 1 kg each, mu 0.5) stacked
  on a plane (twelve contacts);
- ``incline``: a box (half extents 0.1 x 0.1 x 0.05 m, 2 kg, mu 0.4) released at rest on a plane
  inclined by 15 degrees, below the friction angle (atan 0.4 = 21.8 degrees): the exact motion
  is none (four contacts).

MuJoCo (the installed release): the same bodies with a ``freejoint``, geoms of the same shape
and mass, ``friction="mu 0 0"`` (condim 3), its default contact parameters, solver Newton,
once with ``cone="elliptic"`` and once with its default ``cone="pyramidal"``; the C loop
``mujoco.mj_step(m, d, nstep)``. PyBullet (the installed release): the same shapes and masses
in a DIRECT client, its default solver, ``stepSimulation`` called from a Python loop (the
loop's own cost is in PyBullet's figure). Director:
``ContactStepper.advance(nstep, save_every=nstep)``.
Each figure: thread CPU time of ``--steps`` steps after ``--warm`` steps of warm-up (both
engines in their steady state), the four configurations alternated ``--repeats`` times in
one run and the best kept; ns per step and the ratio MuJoCo / director from that run.

Creep: the displacement of the incline box's centre of mass after 10 s in each, and its speed
over the last second (the exact values are 0).

    python benchmarks/bench_contact_vs_engines.py            # table
    python benchmarks/bench_contact_vs_engines.py --quick    # smoke run
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np

from director_model.contact import (
    Body,
    Box,
    ContactScene,
    ContactStepper,
    Pair,
    Plane,
    Sphere,
    incline_frame,
)

G = 9.81
THETA = math.radians(15.0)


def scenes():
    """name -> (ContactScene, list of (kind, size, mass, friction, pos, quat wxyz, vel))."""
    out = {}
    s = Sphere(0.1)
    out["sphere"] = (
        ContactScene(
            [Body("s", 1.0, s.inertia(1.0), position=(0, 0, 0.1), velocity=(1, 0, 0))],
            {"s": s},
            {"ground": Plane()},
            [Pair("s", "ground", mu=0.3)],
            gravity=(0, 0, -G),
        ),  # fmt: skip
        [("sphere", (0.1,), 1.0, 0.3, (0, 0, 0.1), (1, 0, 0, 0), (1, 0, 0))],
    )
    b = Box((0.1, 0.1, 0.1))
    out["box"] = (
        ContactScene([Body("b", 1.0, b.inertia(1.0), position=(0, 0, 0.1))], {"b": b},
                     {"ground": Plane()}, [Pair("b", "ground", mu=0.5)], gravity=(0, 0, -G)),
        [("box", (0.1, 0.1, 0.1), 1.0, 0.5, (0, 0, 0.1), (1, 0, 0, 0), (0, 0, 0))],
    )  # fmt: skip
    bodies, shapes, pairs, mj = [], {}, [], []
    z = 0.0
    for k in range(3):
        hx = 0.2 - 0.04 * k
        bx = Box((hx, hx, 0.05))
        name = f"b{k}"
        bodies.append(Body(name, 1.0, bx.inertia(1.0), position=(0, 0, z + 0.05)))
        shapes[name] = bx
        pairs.append(Pair(name, "ground" if k == 0 else f"b{k - 1}", mu=0.5))
        mj.append(("box", (hx, hx, 0.05), 1.0, 0.5, (0, 0, z + 0.05), (1, 0, 0, 0), (0, 0, 0)))
        z += 0.1
    out["stack"] = (ContactScene(bodies, shapes, {"ground": Plane()}, pairs, gravity=(0, 0, -G)),
                    mj)  # fmt: skip
    down, nrm = incline_frame(THETA)
    R = np.column_stack([down, np.cross(nrm, down), nrm])
    bi = Box((0.1, 0.1, 0.05))
    x0 = 0.05 * nrm
    out["incline"] = (
        ContactScene([Body("b", 2.0, bi.inertia(2.0), position=x0, rotation=R)], {"b": bi},
                     {"slope": Plane.incline(THETA)}, [Pair("b", "slope", mu=0.4)],
                     gravity=(0, 0, -G)),
        [("box", (0.1, 0.1, 0.05), 2.0, 0.4, tuple(x0), _quat(R), (0, 0, 0))],
    )  # fmt: skip
    return out


def _quat(R) -> tuple:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return (w, x, y, z)


def mujoco_model(name, geoms, cone):
    import mujoco

    plane = '<geom type="plane" size="5 5 0.1" friction="1 0 0"/>'
    if name == "incline":
        q = _quat(np.array([[math.cos(THETA), 0, math.sin(THETA)], [0, 1, 0],
                            [-math.sin(THETA), 0, math.cos(THETA)]]))  # fmt: skip
        plane = f'<geom type="plane" size="5 5 0.1" friction="1 0 0" quat="{_f(q)}"/>'
    bodies = ""
    for kind, size, mass, mu, pos, quat, _vel in geoms:
        bodies += (
            f'<body pos="{_f(pos)}" quat="{_f(quat)}"><freejoint/>'
            f'<geom type="{kind}" size="{_f(size)}" mass="{mass!r}" friction="{mu!r} 0 0"/>'
            "</body>"
        )
    xml = (
        f'<mujoco><option timestep="0.001" cone="{cone}" solver="Newton" '
        f'gravity="0 0 {-G}"/><default><geom condim="3"/></default>'
        f"<worldbody>{plane}{bodies}</worldbody></mujoco>"
    )
    m = mujoco.MjModel.from_xml_string(xml)
    # MuJoCo takes the larger of two geoms' friction for their contact: the plane gets the
    # smallest body coefficient, so that every pair has the bodies' own
    m.geom_friction[0, 0] = min(g[3] for g in geoms)
    d = mujoco.MjData(m)
    for k, (_, _, _, _, _, _, vel) in enumerate(geoms):
        d.qvel[6 * k : 6 * k + 3] = vel
    mujoco.mj_forward(m, d)
    return m, d


def pybullet_world(name, geoms):
    """The same scene in PyBullet (DIRECT, its default solver settings; restitution 0; the
    plane's friction 1 so that each body-plane pair's combined coefficient, the product, is
    the body's; box-on-box pairs of the stack get 0.5 x 0.5 = 0.25, which a resting stack
    without tangential load does not feel). Returns (client, step function)."""
    import pybullet as pb

    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -G, physicsClientId=cid)
    pb.setTimeStep(1e-3, physicsClientId=cid)
    q = (0.0, 0.0, 0.0, 1.0)
    if name == "incline":
        q = (0.0, math.sin(THETA / 2), 0.0, math.cos(THETA / 2))  # xyzw, about y
    plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
    ground = pb.createMultiBody(0, plane, baseOrientation=q, physicsClientId=cid)
    pb.changeDynamics(ground, -1, lateralFriction=1.0, restitution=0.0, physicsClientId=cid)
    for kind, size, mass, mu, pos, quat, vel in geoms:
        if kind == "sphere":
            shp = pb.createCollisionShape(pb.GEOM_SPHERE, radius=size[0], physicsClientId=cid)
        else:
            shp = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=size, physicsClientId=cid)
        w, x, y, z = quat
        b = pb.createMultiBody(mass, shp, basePosition=pos, baseOrientation=(x, y, z, w),
                               physicsClientId=cid)  # fmt: skip
        pb.changeDynamics(b, -1, lateralFriction=mu, restitution=0.0, linearDamping=0.0,
                          angularDamping=0.0, physicsClientId=cid)  # fmt: skip
        pb.resetBaseVelocity(b, vel, (0, 0, 0), physicsClientId=cid)

    def step(n):
        for _ in range(n):
            pb.stepSimulation(physicsClientId=cid)

    return cid, step


def _f(a) -> str:
    return " ".join(repr(float(x)) for x in a)


def timed(fn, nstep) -> float:
    t0 = time.thread_time()
    fn(nstep)
    return (time.thread_time() - t0) / nstep * 1e9


def bench(args):
    import mujoco

    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"mujoco {mujoco.__version__}, load {os.getloadavg()[0]:.2f}")  # fmt: skip
    rows = []
    for name, (scene, geoms) in scenes().items():
        st = ContactStepper(scene, dt=1e-3)
        st.advance(args.warm, save_every=args.warm)
        mjs = {}
        for cone in ("elliptic", "pyramidal"):
            m, d = mujoco_model(name, geoms, cone)
            mujoco.mj_step(m, d, nstep=args.warm)
            mjs[cone] = (m, d)
        cid, pstep = pybullet_world(name, geoms)
        pstep(args.warm)
        best = {"director": math.inf, "elliptic": math.inf, "pyramidal": math.inf,
                "pybullet": math.inf}  # fmt: skip
        for _ in range(args.repeats):
            best["director"] = min(best["director"], timed(
                lambda n, st=st: st.advance(n, save_every=n), args.steps))  # fmt: skip
            for cone, (m, d) in mjs.items():
                best[cone] = min(best[cone], timed(
                    lambda n, m=m, d=d: mujoco.mj_step(m, d, nstep=n), args.steps))  # fmt: skip
            best["pybullet"] = min(best["pybullet"], timed(pstep, args.steps))
        import pybullet as pb

        pb.disconnect(cid)
        rows.append((name, best, int(mjs["elliptic"][1].ncon)))
    print(f"\n# load at the end {os.getloadavg()[0]:.2f}")
    print(
        "\n| scene | contacts (MuJoCo) | director ns/step | MuJoCo elliptic+Newton | "
        "MuJoCo pyramidal+Newton | PyBullet | elliptic/director | pyramidal/director | "
        "PyBullet/director |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, b, ncon in rows:
        print(f"| {name} | {ncon} | {b['director']:.0f} | {b['elliptic']:.0f} | "
              f"{b['pyramidal']:.0f} | {b['pybullet']:.0f} | "
              f"{b['elliptic'] / b['director']:.2f} | {b['pyramidal'] / b['director']:.2f} | "
              f"{b['pybullet'] / b['director']:.2f} |")  # fmt: skip


def creep(args):
    import mujoco

    scene, geoms = scenes()["incline"]
    T = 1.0 if args.quick else 10.0
    n = int(round(T / 1e-3))
    st = ContactStepper(scene, dt=1e-3)
    tr = st.advance(n, save_every=n // 10, include_start=True)
    x = tr.position[:, 0]
    dir_disp = float(np.linalg.norm(x[-1] - x[0]))
    dir_speed = float(np.linalg.norm(x[-1] - x[-2]) / (tr.t[-1] - tr.t[-2]))
    print(f"\n# creep of the incline box (exact: 0), {T:g} s")
    print("\n| engine | displacement after T (m) | mean speed over the last tenth (m/s) |")
    print("|---|---|---|")
    print(f"| director | {dir_disp:.3g} | {dir_speed:.3g} |")
    for cone in ("elliptic", "pyramidal"):
        m, d = mujoco_model("incline", geoms, cone)
        x0 = d.qpos[0:3].copy()
        mujoco.mj_step(m, d, nstep=n - n // 10)
        x9 = d.qpos[0:3].copy()
        mujoco.mj_step(m, d, nstep=n // 10)
        x1 = d.qpos[0:3].copy()
        print(f"| MuJoCo {cone}+Newton | {np.linalg.norm(x1 - x0):.3g} | "
              f"{np.linalg.norm(x1 - x9) / (T / 10):.3g} |")  # fmt: skip


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--warm", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    if args.quick:
        args.steps, args.warm, args.repeats = 200, 100, 2
    bench(args)
    creep(args)


if __name__ == "__main__":
    main()
