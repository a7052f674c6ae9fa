"""Cost per body-step of MJX's vmapped batch against C MuJoCo's ``mujoco.rollout``, in one run.

The body: a free body, m = 1 kg, I = (1, 2, 3) kg m^2, no gravity, W0 = (0.01, 2, 0.01) rad/s
with its direction drawn at random per body (the ensemble's rule, reports.run.ensemble.members:
same kinetic energy), dt = 1e-3 s. Both engines get the same MJCF (the adapters',
references.engines.mujoco.adapter.MujocoEngine.model_xml) and the same initial states.

- MJX: the mjx adapter's compiled stepping (references.engines.mjx), vmapped over the
  bodies, one call for ``--nstep`` steps with only the last state returned; compiled ahead of
  time before timing (the compile time is printed apart).
- C MuJoCo: ``mujoco.rollout.rollout`` over the same bodies for the same steps, with 1 and with
  2 threads (one MjData per thread). rollout returns every step's state (it has no option not
  to), so its figure includes writing nbody x nstep states.

Every figure is the best of ``--repeat`` timings (the machine is shared and noisy). Printed:
microseconds per body-step for each, and the ratios MJX / rollout.

Usage: python benchmarks/bench_mjx.py [--quick] [--n 1000] [--nstep 1000] [--repeat 3]
       [--integrators Euler,RK4] [--precision float64]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

I = (1.0, 2.0, 3.0)
W0 = (0.01, 2.0, 0.01)
DT = 1e-3


def scenario():
    from scenarios.model import Scenario

    return Scenario(
        name="bench-mjx",
        description="free body for bench_mjx",
        mass=1.0,
        inertia=list(I),
        rotation=np.eye(3),
        omega_body=list(W0),
        t_end=1.0,
        dt=DT,
    )


def initial_qpos_qvel(n: int):
    from references import conventions as cv
    from reports.run.ensemble import members

    qp, qv = [], []
    for mem in members(scenario(), n, seed=0):
        q, v = cv.mujoco_free_from_state(mem.position, mem.velocity, mem.rotation, mem.omega_body)
        qp.append(q)
        qv.append(v)
    return np.array(qp), np.array(qv)


def mjx_rate(integrator: str, precision: str, n: int, nstep: int, repeat: int):
    """(best seconds per body-step, compile seconds) of the vmapped compiled stepping."""
    from references.engines.context import BodyModel, RunContext
    from references.engines.mjx import CHECKPOINTS, MjxEngine
    from references.engines.mjx.compile import _block_fn, _compiled

    eng = MjxEngine()
    sc = scenario()
    ctx = RunContext(sc, BodyModel.of(sc, DT), eng.integrator(f"{integrator} ({precision})"), DT)
    eng._put_model(ctx)
    h = ctx.handle
    jax, jnp = h.jax, h.jax.numpy
    qpos0, qvel0 = initial_qpos_qvel(n)
    with h.x64_mode():
        dxb = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), h.dx)
        dxb = dxb.replace(qpos=jnp.asarray(qpos0), qvel=jnp.asarray(qvel0))
    ks = np.zeros(CHECKPOINTS, np.int32)
    vblock = jax.vmap(_block_fn(), in_axes=(None, 0, None, None))
    comp, compile_s, _ = _compiled(
        f"batch-step-{h.mj_name}", vblock, (h.mx, dxb), (ks, np.int32(0)), h.x64
    )
    ml, dl = comp.leaves(0, h.mx), comp.leaves(1, dxb)
    ks[0] = nstep
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        with h.x64_mode():
            out = comp(ml, dl, ks, np.int32(1))
            jax.block_until_ready(out)
        best = min(best, (time.perf_counter() - t0) / (n * nstep))
    return best, compile_s


def rollout_rate(integrator: str, n: int, nstep: int, repeat: int, nthread: int) -> float:
    """Best seconds per body-step of mujoco.rollout over the same bodies."""
    import mujoco
    from mujoco import rollout

    from references.engines.context import BodyModel
    from references.engines.mujoco.adapter import MujocoEngine

    m = mujoco.MjModel.from_xml_string(
        MujocoEngine.model_xml(BodyModel.of(scenario(), DT), integrator)
    )
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    size = mujoco.mj_stateSize(m, spec)
    qpos0, qvel0 = initial_qpos_qvel(n)
    state0 = np.empty((n, size))
    d = datas[0]
    for k in range(n):
        d.qpos[:], d.qvel[:] = qpos0[k], qvel0[k]
        mujoco.mj_getState(m, d, state0[k], spec)
    out = np.empty((n, nstep, size))
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        rollout.rollout(m, datas, state0, nstep=nstep, state=out)
        best = min(best, (time.perf_counter() - t0) / (n * nstep))
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="100 bodies x 200 steps (a smoke run)")
    ap.add_argument("--n", type=int, default=1000, help="bodies")
    ap.add_argument("--nstep", type=int, default=1000, help="steps per timing")
    ap.add_argument("--repeat", type=int, default=3, help="repeats; the best is kept")
    ap.add_argument("--integrators", default="Euler,RK4", help="MuJoCo integrator names")
    ap.add_argument("--precision", default="float64", choices=("float64", "float32"))
    args = ap.parse_args(argv)
    n, nstep = (100, 200) if args.quick else (args.n, args.nstep)
    from references.engines.mjx import MjxEngine

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    print(f"mjx {MjxEngine.version()}")
    print(f"body: I = {I}, |W0| as {W0} in random directions, no gravity; dt = {DT:g} s; "
          f"{n} bodies x {nstep} steps per timing; best of {args.repeat}")  # fmt: skip
    print("load average at start (1, 5, 15 min): " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print()
    print(f"| {'integrator':10s} | {'MJX vmap us/body-step':>21s} | {'compile s':>9s} | "
          f"{'rollout 1 thr':>13s} | {'rollout 2 thr':>13s} | {'MJX/roll 1':>10s} | "
          f"{'MJX/roll 2':>10s} |")  # fmt: skip
    print("|" + "|".join("-" * w for w in (12, 23, 11, 15, 15, 12, 12)) + "|")
    for integ in args.integrators.split(","):
        mjx_s, comp_s = mjx_rate(integ, args.precision, n, nstep, args.repeat)
        r1 = rollout_rate(integ, n, nstep, args.repeat, 1)
        r2 = rollout_rate(integ, n, nstep, args.repeat, 2)
        print(f"| {integ + ' ' + args.precision[-2:]:10s} | {mjx_s * 1e6:21.3f} | {comp_s:9.1f} | "
              f"{r1 * 1e6:13.3f} | {r2 * 1e6:13.3f} | {mjx_s / r1:10.1f} | "
              f"{mjx_s / r2:10.1f} |")  # fmt: skip
    print("load average at end: " + " ".join(f"{x:.2f}" for x in os.getloadavg()))


if __name__ == "__main__":
    main()
