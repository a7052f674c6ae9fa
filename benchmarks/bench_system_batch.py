"""Body-steps per second of a batch of chains: director_model.system.simulate_system_batch
against MuJoCo's batched C rollout (``mujoco.rollout.rollout``), side by side in one run.

A batch of ``--batch`` hanging chains of 5 and 10 rods (1 m, 1 kg, the rods and ball joints of
:func:`director_model.system.examples.rod_chain`, member k with seed k: its own tilts and
initial velocities, projected on the joints), gravity 9.81 m/s^2, dt = 1e-3 s, ``--steps``
steps. Director: RATTLE (order 2), one saved state per member besides the start (memory
O(saved states)), numba threads 1 and 2. MuJoCo: one model of the same chain (nested bodies,
ball joints at the rod tops, the first at the world origin, the same masses and principal
moments, contacts off, Euler), each member's pose and velocities as its qpos (ball-joint
quaternions relative to the parent) and qvel (angular velocity relative to the parent, in
the child's axes), checked against the director's body positions before timing; rolled out
by ``rollout.rollout`` with 1 and 2 MjData (threads), which writes the full physics state of
every step (memory O(steps), preallocated once, outside the timing).

Each figure is the best of ``--repeats`` runs in wall time (the threads run in parallel; the
load printed beside), as body-steps per second = batch x steps x bodies / time; the ratio is
the director's rate over MuJoCo's on the same number of threads, from the same run. The
last column is the largest distance between the two engines' body positions of member 0 at
the end (RATTLE and Euler differ by O(dt) at these steps: the two simulate the same motion).

    python benchmarks/bench_system_batch.py                # 1000 chains, 200 steps
    python benchmarks/bench_system_batch.py --quick        # 50 chains, 50 steps
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numba
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_system_vs_mujoco import _quat, mujoco_xml  # noqa: E402

from director_model.system import simulate_system_batch  # noqa: E402
from director_model.system.examples import rod_chain  # noqa: E402

G = (0.0, 0.0, -9.81)


def mujoco_batch_states(mujoco, m, d, members) -> np.ndarray:
    """(nbatch, nstate) full-physics initial states of the members in the model ``m`` whose
    reference pose is the straight chain (all body quaternions identity)."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.empty((len(members), mujoco.mj_stateSize(m, spec)))
    for k, bodies in enumerate(members):
        mujoco.mj_resetData(m, d)
        qpos, qvel = [], []
        for i, b in enumerate(bodies):
            if i == 0:
                qpos += list(_quat(b.rotation))
                qvel += list(b.omega_body)
            else:
                p = bodies[i - 1]
                qpos += list(_quat(p.rotation.T @ b.rotation))
                qvel += list(b.omega_body - b.rotation.T @ p.rotation @ p.omega_body)
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        mujoco.mj_forward(m, d)
        X = np.array([b.position for b in bodies])
        gap = np.abs(d.xipos[1:] - X).max()
        if gap > 1e-12:  # the glue is wrong, not the engine: stop rather than time it
            raise RuntimeError(f"member {k}: MuJoCo body positions off by {gap:.3g} m")
        mujoco.mj_getState(m, d, out[k], spec)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="50 chains, 50 steps, 2 repeats")
    args = ap.parse_args()
    nbatch, nstep, rep = (50, 50, 2) if args.quick else (args.batch, args.steps, args.repeats)
    try:
        import mujoco
        import mujoco.rollout
    except ImportError:  # an engine not installed is skipped with a message
        mujoco = None
        print("MuJoCo not installed: its columns are skipped")
    threads = [t for t in (1, 2) if t <= numba.config.NUMBA_NUM_THREADS]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}; MuJoCo {getattr(mujoco, '__version__', '-')}; "
          f"numba {numba.__version__}; "
          f"{nbatch} chains x {nstep} steps, dt = 1e-3 s, best of {rep}, wall time")  # fmt: skip
    head = ["chain"]
    for t in threads:
        head += [f"director rattle, {t} thr [body-steps/s]", f"MuJoCo rollout Euler, {t} thr",
                 f"ratio {t} thr"]  # fmt: skip
    head += ["max dx member 0 [m]"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    t_end = nstep * 1e-3
    setup = {}
    for n in (5, 10):
        members = [rod_chain(n, True, seed=k)[0] for k in range(nbatch)]
        joints = rod_chain(n, True, seed=0)[1]
        work = nbatch * nstep * n
        row = [f"{n} bodies, hanging"]
        last = None
        for t in threads:
            best = np.inf
            for _ in range(rep + 1):  # the first run compiles or loads the kernels
                c = time.perf_counter()
                tr = simulate_system_batch(members, joints, gravity=G, scheme="rattle",
                                           dt=1e-3, t_end=t_end, save_every=nstep,
                                           threads=t)  # fmt: skip
                best = min(best, tr.wall_time_s)
                setup[n] = time.perf_counter() - c - tr.wall_time_s
            assert tr.ok.all(), tr.messages
            last = tr.position[0, -1]
            rate_d = work / best
            rate_m = np.nan
            dx = np.nan
            if mujoco is not None:
                straight = rod_chain(n, True, tilt=0.0, spin=False)[0]
                m = mujoco.MjModel.from_xml_string(mujoco_xml(straight, True, "Euler"))
                datas = [mujoco.MjData(m) for _ in range(t)]
                x0 = mujoco_batch_states(mujoco, m, datas[0], members)
                out = np.empty((nbatch, nstep, x0.shape[1]))
                best_m = np.inf
                for _ in range(rep + 1):
                    c = time.perf_counter()
                    mujoco.rollout.rollout(m, datas, x0, nstep=nstep, state=out,
                                           persistent_pool=t > 1)  # fmt: skip
                    best_m = min(best_m, time.perf_counter() - c)
                rate_m = work / best_m
                d = datas[0]
                mujoco.mj_setState(m, d, out[0, -1], mujoco.mjtState.mjSTATE_FULLPHYSICS)
                mujoco.mj_kinematics(m, d)
                dx = np.abs(d.xipos[1:] - last).max()
            row += [f"{rate_d:.3g}", f"{rate_m:.3g}", f"{rate_d / rate_m:.2f}"]
        row.append(f"{dx:.1e}")
        print("| " + " | ".join(row) + " |")
    print(
        "director set-up outside the timed stepping (checks and assembly of every member, "
        + ", ".join(f"{n} bodies {v:.2f} s" for n, v in setup.items())
        + ")"
    )
    print(f"load at the end {os.getloadavg()[0]:.2f}; numba threading layer "
          f"{numba.threading_layer()}")  # fmt: skip


if __name__ == "__main__":
    main()
