"""Per-step cost of director_model's schemes against MuJoCo's own C loop, side by side.

The body is the Dzhanibekov body of docs/numerics.md: m = 1 kg, principal moments
I = (2, 3, 4) kg m^2, no gravity, W0 = (0.01, 2, 0.01) rad/s in body axes, R0 = identity.
MuJoCo gets it as a free body with an ellipsoid geom and an explicit ``<inertial>``
(diaginertia = I), and is stepped with ``mujoco.mj_step(m, d, nstep=N)`` (the loop runs in C).
director_model runs its compiled loop with only the first and last states saved.

Every figure is the best of ``--repeat`` runs (the machine is shared and noisy, +-30 %).
Compilation is excluded (director_model compiles, or loads its on-disk cache, before timing;
``Trajectory.wall_time_s`` is the stepping alone). Also printed: each method's error in R at
t = 10 s against the numerics.md test vector, so that cost is read next to accuracy.

Single-body timings are taken twice in each repeat: wall clock (the figure of record) and
the CPU time of the calling thread (``time.thread_time``; every single-body loop, MuJoCo's
and director_model's, runs in that thread), which leaves out the time other processes hold
the core and so varies less on a shared machine. The batched path runs on several threads
and is timed by the wall clock only; its line also gives the CPU time of the process over
the wall time of the threads (100 % when they had the cores to themselves).

Targets (issue on speed): single-body rattle >= 30x faster per step than MuJoCo Euler's
``mj_step(m, d, nstep)``; batched rattle >= 1e8 body-steps/s on 2 threads; both with the
shipped compensated sums.

Usage: python benchmarks/bench_director_vs_mujoco.py [--quick] [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

import director_model as dm

I = (2.0, 3.0, 4.0)
W0 = (0.01, 2.0, 0.01)
R10 = np.array(
    [
        [0.601069719933, -0.479226289446, 0.639575918311],
        [-0.541629680940, 0.344194223927, 0.766920872672],
        [-0.587666980955, -0.807386214720, -0.052678456472],
    ]
)

MJCF = """
<mujoco model="dzhanibekov">
  <option timestep="{dt}" gravity="0 0 0" integrator="{integrator}"/>
  <worldbody>
    <body name="body">
      <freejoint/>
      <geom type="ellipsoid" size="0.1 0.2 0.3"/>
      <inertial pos="0 0 0" mass="1" diaginertia="2 3 4"/>
    </body>
  </worldbody>
</mujoco>
"""


def mujoco_runs(integrator: str, dt: float, nstep: int, repeat: int):
    """Best time per step of mj_step(m, d, nstep) (wall clock, thread CPU time) and the
    error in R(10)."""
    import mujoco

    m = mujoco.MjModel.from_xml_string(MJCF.format(dt=dt, integrator=integrator))
    d = mujoco.MjData(m)
    best = np.inf
    best_cpu = np.inf
    for _ in range(repeat):
        mujoco.mj_resetData(m, d)
        d.qvel[3:6] = W0  # free joint: angular velocity in the body (local) frame
        c0 = time.thread_time()
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=nstep)
        best = min(best, (time.perf_counter() - t0) / nstep)
        best_cpu = min(best_cpu, (time.thread_time() - c0) / nstep)
    # accuracy at t = 10 s with the same dt
    mujoco.mj_resetData(m, d)
    d.qvel[3:6] = W0
    mujoco.mj_step(m, d, nstep=int(round(10.0 / dt)))
    R = np.empty(9)
    mujoco.mju_quat2Mat(R, d.qpos[3:7])  # MuJoCo quaternions are (w, x, y, z)
    err = float(np.max(np.abs(R.reshape(3, 3) - R10)))
    return best, best_cpu, err, mujoco.__version__


def director_runs(scheme: str, dt: float, nstep: int, repeat: int):
    """Best time per step of one compensated simulate run (wall clock and thread CPU time
    of the compiled loop) and the error in R(10)."""
    best = np.inf
    best_cpu = np.inf
    for _ in range(repeat):
        tr = dm.simulate(1.0, I, rotation=np.eye(3), omega_body=W0, scheme=scheme, dt=dt,
                         t_end=nstep * dt, save_every=10**12)  # fmt: skip
        best_cpu = min(best_cpu, tr.cpu_time_s / tr.nstep)
        best = min(best, tr.wall_time_s / tr.nstep)
    tr = dm.simulate(1.0, I, rotation=np.eye(3), omega_body=W0, scheme=scheme, dt=dt,
                     t_end=10.0, save_every=10**12)  # fmt: skip
    err = float(np.max(np.abs(tr.rotation[-1] - R10)))
    return best, best_cpu, err


def batch_rate(scheme: str, nbody: int, nstep: int, dt: float, repeat: int, parallel: bool):
    """Best body-steps per second of simulate_batch over nbody different initial states
    (wall clock), the share of the RATTLE substeps the vector code took, and for the best
    run the process CPU time over (wall time x threads)."""
    import numba
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    R = Rotation.random(nbody, random_state=1).as_matrix()
    W = np.asarray(W0) + 0.1 * rng.normal(size=(nbody, 3))
    nthread = numba.get_num_threads() if parallel else 1
    best = 0.0
    share = 0.0
    for _ in range(repeat):
        bt = dm.simulate_batch(1.0, I, rotation=R, omega_body=W, scheme=scheme, dt=dt,
                               t_end=nstep * dt, save_every=10**12, parallel=parallel)  # fmt: skip
        cpu = bt.cpu_time_s / (bt.wall_time_s * nthread)
        rate = nbody * nstep / bt.wall_time_s
        if rate > best:
            best, share = rate, cpu
    # share of the RATTLE substeps done by the vector (SIMD) code of the batched loop
    ncoef = dm.SCHEMES[scheme].coefficient_array().size
    return best, bt.vector_substeps.sum() / (nbody * nstep * ncoef), share


def clock_estimate(n: int = 100_000_000) -> float:
    """Core clock in GHz from a chain of n dependent double additions (each waits for the
    previous one: 3 cycles of latency on AMD Zen 2/3 and Intel since Skylake), best of 3
    in thread CPU time. Used to turn times into cycles in the README's speed analysis."""
    from numba import njit

    @njit
    def chain(n, x):
        for _ in range(n):
            x = x + 1e-300  # no fastmath: kept, and each add depends on the last
        return x

    chain(10, 1.0)
    best = np.inf
    for _ in range(3):
        c0 = time.thread_time()
        chain(n, 1.0)
        best = min(best, (time.thread_time() - c0) / n)
    return 3.0 / best / 1e9


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps (a smoke run)")
    ap.add_argument("--repeat", type=int, default=7, help="repeats; the best is kept")
    ap.add_argument("--dt", type=float, default=1e-3, help="time step, s")
    args = ap.parse_args(argv)
    dt = args.dt
    nstep = 20_000 if args.quick else 200_000
    nbody, nstep_batch = (2_000, 200) if args.quick else (10_000, 1_000)
    import numba

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"numba {numba.__version__} ({numba.config.NUMBA_NUM_THREADS} threads)")  # fmt: skip
    print(f"body: I = {I}, W0 = {W0}, no gravity; dt = {dt:g} s; {nstep} steps per timing; "
          f"best of {args.repeat}")  # fmt: skip
    # other jobs on the machine inflate every timing: report the load with the figures
    print("load average at start (1, 5, 15 min): " + _load())
    print(f"core clock estimate: {clock_estimate():.2f} GHz (dependent add chain, 3 cycles "
          f"per add)")  # fmt: skip
    dm.simulate(1.0, I, rotation=np.eye(3), omega_body=W0, dt=dt, t_end=dt)  # compile/load

    rows = []
    for integ in ("Euler", "implicitfast", "RK4"):
        try:
            cost, cpu, err, ver = mujoco_runs(integ, dt, nstep, args.repeat)
        except ImportError:
            print("mujoco not installed: MuJoCo rows skipped")
            break
        rows.append((f"MuJoCo {ver} {integ} (mj_step nstep=N)", cost, cpu, err))
    for scheme in dm.SCHEMES:
        n = nstep if scheme != "energy_momentum" else max(nstep // 20, 1000)
        cost, cpu, err = director_runs(scheme, dt, n, args.repeat)
        rows.append((f"director_model {scheme}", cost, cpu, err))

    print()
    print("Per-step cost, one free body (loop in compiled code; director_model compensated)")
    print(f"| {'method':44s} | {'us/step':>9s} | {'CPU us/step':>11s} | {'err R(10)':>9s} |")
    print(f"|{'-' * 46}|{'-' * 11}|{'-' * 13}|{'-' * 11}|")
    for name, cost, cpu, err in rows:
        print(f"| {name:44s} | {cost * 1e6:9.4f} | {cpu * 1e6:11.4f} | {err:9.2e} |")
    cost = {name: c for name, c, _, _ in rows}
    cpu = {name: c for name, _, c, _ in rows}
    r = cost.get("director_model rattle")
    rc = cpu.get("director_model rattle")
    print()
    print("Ratios (MuJoCo time per step / rattle time per step), wall clock and thread CPU time")
    for name in cost:
        if name.startswith("MuJoCo"):
            print(f"  {name:44s} {cost[name] / r:6.1f} x   (CPU time {cpu[name] / rc:6.1f} x)")
    euler = next((n for n in cost if n.startswith("MuJoCo") and " Euler " in n), None)
    if euler:
        ratio = cost[euler] / r
        print(f"  rattle vs MuJoCo Euler / target 30x: {ratio / 30:.2f} "
              f"({'met' if ratio >= 30 else 'NOT met'})")  # fmt: skip

    print()
    print(f"Batched path: {nbody} bodies x {nstep_batch} steps (simulate_batch, compensated)")
    rates = {}
    for scheme in ("rattle", "rattle4"):
        for par in (True, False):
            rate, vec, share = batch_rate(scheme, nbody, nstep_batch, dt, args.repeat, par)
            label = "parallel" if par else "1 thread"
            rates[scheme, par] = rate
            print(f"  {scheme:8s} {label:8s}: {rate:10.3e} body-steps/s "
                  f"({1e9 / rate:6.1f} ns per body-step; vector code took "
                  f"{100 * vec:.1f} % of the substeps; CPU {100 * share:.0f} %)")  # fmt: skip
    rate = rates["rattle", True]
    print(f"  batched rattle / target 1e8 body-steps/s: {rate / 1e8:.2f} "
          f"({'met' if rate >= 1e8 else 'NOT met'})")  # fmt: skip
    print(f"  batched rattle, parallel / 1 thread (same run): "
          f"{rate / rates['rattle', False]:.2f} x")  # fmt: skip
    print(f"  batched rattle / single-body rattle (same run): {rate * r:.2f} x")
    if euler:
        print(f"  batched rattle / MuJoCo Euler mj_step (body-steps per second): "
              f"{rate * cost[euler]:.1f} x")  # fmt: skip
    print("load average at end (1, 5, 15 min): " + _load())


if __name__ == "__main__":
    main()
