"""Cost per step of director_model.system against MuJoCo's mj_step on the same chains.

Chains of 2, 5, 10 and 20 rods (1 m, 1 kg, principal moments (1/12 + 0.01, same, 0.02)
kg m^2, body axis 3 along the rod) joined end to end by ball joints, free floating (no
gravity) or hanging from a ball joint at the origin (gravity 9.81 m/s^2), with the same
tilted initial configuration and the same initial velocities (random, projected on the
joints) in both: :func:`director_model.system.examples.rod_chain`. dt = 1e-3 s; no contacts.

MuJoCo: nested bodies with ``ball`` joints at the rod tops (the first hanging one at the
origin; a ``freejoint`` on the first of a floating chain), an ``inertial`` element with the
same mass and moments, contacts disabled; the C loop ``mujoco.mj_step(m, d, nstep)``.
Director: ``SystemStepper.advance(nstep, save_every=nstep)`` (compiled loop, one saved
state). Each figure is the best of ``--repeats`` runs of ``--steps`` steps in thread CPU
time (the time other processes hold the core left out), printed in ns per step; the ratios
are MuJoCo Euler's time over the director's, from the same run.

    python benchmarks/bench_system_vs_mujoco.py            # full table
    python benchmarks/bench_system_vs_mujoco.py --quick    # smoke run
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from director_model.system import SystemStepper
from director_model.system.examples import rod_chain


def mujoco_xml(bodies, hang: bool, integrator: str) -> str:
    """The chain as MJCF: body i's frame at its centre of mass, axes = principal axes (the
    director body frame), so the inertial element is diagonal at the origin."""
    g = -9.81 if hang else 0.0
    xml = ""
    for i, b in enumerate(bodies):
        if i == 0:
            pos, R = b.position, b.rotation
        else:
            Rp = bodies[i - 1].rotation
            pos = Rp.T @ (b.position - bodies[i - 1].position)
            R = Rp.T @ b.rotation
        q = _quat(R)
        joint = '<joint type="ball" pos="0 0 0.5"/>' if (i > 0 or hang) else "<freejoint/>"
        I = b.inertia
        xml += (
            f'<body pos="{_f(pos)}" quat="{_f(q)}">{joint}'
            f'<inertial pos="0 0 0" mass="{b.mass!r}" diaginertia="{_f(I)}"/>'
        )
    xml += "</body>" * len(bodies)
    return (
        f'<mujoco><option timestep="0.001" integrator="{integrator}" gravity="0 0 {g}">'
        f'<flag contact="disable"/></option><worldbody>{xml}</worldbody></mujoco>'
    )


def _f(a) -> str:
    return " ".join(repr(float(v)) for v in a)


def _quat(R: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


def mujoco_state(m, d, bodies, hang: bool) -> None:
    """The director chain's initial velocities in MuJoCo's coordinates (the positions are
    the model's reference pose): ball joints take the child's angular velocity relative to
    its parent in the child's axes; a free joint the COM velocity (world) and the body
    angular velocity (local)."""
    import mujoco

    mujoco.mj_resetData(m, d)
    qv = []
    for i, b in enumerate(bodies):
        if i == 0 and not hang:
            qv += list(b.velocity) + list(b.omega_body)
        elif i == 0:
            qv += list(b.omega_body)
        else:
            p = bodies[i - 1]
            rel = b.omega_body - b.rotation.T @ p.rotation @ p.omega_body
            qv += list(rel)
    d.qvel[:] = qv
    mujoco.mj_forward(m, d)


def best_ns(fn, nstep: int, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        c0 = time.thread_time()
        fn(nstep)
        best = min(best, time.thread_time() - c0)
    return best / nstep * 1e9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="2000 steps, 2 repeats")
    args = ap.parse_args()
    nstep, rep = (2000, 2) if args.quick else (args.steps, args.repeats)
    try:
        import mujoco
    except ImportError:  # an engine not installed is skipped with a message
        mujoco = None
        print("MuJoCo not installed: its columns are skipped")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}; MuJoCo {getattr(mujoco, '__version__', '-')}; "
          f"{nstep} steps x best of {rep}, dt = 1e-3 s, thread CPU time")  # fmt: skip
    head = ("chain", "director rattle", "rattle4", "rattle6", "MuJoCo Euler", "MuJoCo RK4",
            "Euler/rattle", "RK4/rattle4", "max dx RK4 vs rattle6, 0.5 s [m]")  # fmt: skip
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for n in (2, 5, 10, 20):
        for hang in (False, True):
            bodies, joints = rod_chain(n, hang, seed=n)
            g = (0.0, 0.0, -9.81) if hang else (0.0, 0.0, 0.0)
            ns = {}
            for scheme in ("rattle", "rattle4", "rattle6"):
                st = SystemStepper(bodies, joints, gravity=g, scheme=scheme, dt=1e-3)
                st.advance(10)
                k = max(nstep // {"rattle": 1, "rattle4": 3, "rattle6": 9}[scheme], 200)
                ns[scheme] = best_ns(lambda s, st=st: st.advance(s, save_every=s), k, rep)
            dx = np.nan
            for integ in ("Euler", "RK4"):
                if mujoco is None:
                    ns[integ] = np.nan
                    continue
                m = mujoco.MjModel.from_xml_string(mujoco_xml(bodies, hang, integ))
                d = mujoco.MjData(m)
                mujoco_state(m, d, bodies, hang)
                if integ == "RK4":
                    mujoco.mj_step(m, d, 500)
                    mujoco.mj_forward(m, d)
                    st = SystemStepper(bodies, joints, gravity=g, scheme="rattle6", dt=1e-3)
                    dx = np.abs(d.xipos[1:] - st.advance(500, save_every=500).position[-1]).max()
                mujoco.mj_step(m, d, 10)
                ns[integ] = best_ns(lambda s, m=m, d=d: mujoco.mj_step(m, d, s), nstep, rep)
            label = f"{n} bodies, {'hanging' if hang else 'free'}"
            print(
                f"| {label} | {ns['rattle']:.0f} | {ns['rattle4']:.0f} | {ns['rattle6']:.0f} | "
                f"{ns['Euler']:.0f} | {ns['RK4']:.0f} | {ns['Euler'] / ns['rattle']:.2f} | "
                f"{ns['RK4'] / ns['rattle4']:.2f} | {dx:.1e} |"
            )
    print(f"load at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
