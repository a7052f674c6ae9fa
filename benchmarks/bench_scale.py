"""Scale benchmarks, measured side by side in one run on this machine.

1. The default suite: wall time (runs and report) and peak memory of ``director-bench run``,
   with every engine and with the engines it had before Drake and MJX joined, the stepping
   time by engine, and the suite's RKMK4 (Pinocchio, DART) against MuJoCo's RK4 per step on
   the same runs; unless ``--skip-suite``.
2. Long horizon: 1e6 steps of the Dzhanibekov body (1000 s at dt = 1e-3), decimated storage
   (one saved state per 1000 steps), through the suite's engine interface: wall time, peak
   resident memory of the process (each run in a fresh subprocess so peaks do not mix), and
   the size the full trajectory would have had; then the same with streaming metrics over
   every step (runs in segments, memory bounded by the segment).
3. Ensemble throughput: director_model's batched path against ``mujoco.rollout`` on the same
   ensemble of free bodies (the Dzhanibekov body of docs/numerics.md with random directions of W at
   its rotational energy), both on every core, body-steps per second and the ratio.

Every timing is the best of ``--repeat`` (the machine is shared: +-30 % noise); ratios are of
figures measured in this same run. Usage:

    python benchmarks/bench_scale.py [--quick] [--skip-suite] [--repeat 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

I = (2.0, 3.0, 4.0)
W0 = np.array([0.01, 2.0, 0.01])


def ensemble(nbody: int, seed: int = 0):
    """Initial rotations (identity) and body rates of the ensemble: random directions at the
    rotational energy of W0 (same rule as reports.run.ensemble)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(nbody, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    Iv = np.array(I)
    T = 0.5 * W0 @ (Iv * W0)
    W = u * np.sqrt(2 * T / np.einsum("ni,i,ni->n", u, Iv, u))[:, None]
    return np.repeat(np.eye(3)[None], nbody, axis=0), W


def director_batch(nbody, nstep, dt, scheme, repeat):
    import director_model as dm

    R, W = ensemble(nbody)
    best = np.inf
    for _ in range(repeat + 1):  # the first call may load the compiled cache
        out = dm.simulate_batch(
            1.0,
            I,
            rotation=R,
            omega_body=W,
            scheme=scheme,
            dt=dt,
            t_end=nstep * dt,
            save_every=nstep,
        )
        best = min(best, out.wall_time_s)
    return nbody * nstep / best


def mujoco_rollout(nbody, nstep, dt, integrator, repeat):
    import mujoco
    from mujoco import rollout

    xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 0" integrator="{integrator}"/>
      <worldbody><body><freejoint/><geom type="sphere" size="0.1" contype="0" conaffinity="0"/>
      <inertial pos="0 0 0" mass="1" diaginertia="2 3 4"/></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    nthread = os.cpu_count() or 1
    datas = [mujoco.MjData(m) for _ in range(nthread)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    size = mujoco.mj_stateSize(m, spec)
    R, W = ensemble(nbody)
    init = np.empty((nbody, size))
    d = datas[0]
    for k in range(nbody):
        mujoco.mj_resetData(m, d)
        d.qpos[3:7] = (1, 0, 0, 0)
        d.qvel[3:6] = W[k]  # MuJoCo's free-joint angular velocity is in body axes
        mujoco.mj_getState(m, d, init[k], spec)
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        rollout.rollout(m, datas, init, nstep=nstep)
        best = min(best, time.perf_counter() - t0)
    return nbody * nstep / best


# Peak memory is read from /proc/self/status (VmHWM): unlike ru_maxrss, which Linux carries
# across exec from the parent, it belongs to the new address space.
LONG = """
import json, sys, time
import scenarios
from references.engines import get_engine
from references.exact import reference_trajectory
from reports.metrics.body import compute_metrics
def hwm_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
engine, integ, nstep, every = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
segment = int(sys.argv[5]) if len(sys.argv) > 5 else 0
sc = scenarios.load("dzhanibekov")
if segment:  # streaming metrics over every step, segments of `segment` steps
    from reports.run.runner import RunSpec, execute
    execute(RunSpec(sc.replace(t_end=1.0), engine, integ, 1e-3, save_every=every,
                    segment=segment))  # warm-up
    before = hwm_kb()
    t0 = time.perf_counter()
    row = execute(RunSpec(sc.replace(t_end=nstep * 1e-3), engine, integ, 1e-3,
                          save_every=every, segment=segment))
    wall = time.perf_counter() - t0
    print(json.dumps(dict(wall=wall, stepping=row["wall_time_s"], nsave=nstep // every + 1,
                          before_kb=before, peak_kb=hwm_kb(), energy=row["energy_drift_max"],
                          attitude=row["attitude_error_max"])))
    sys.exit(0)
warm = get_engine(engine)().run(sc, integ, 1e-3, t_end=1e-3 * every, save_every=every)
compute_metrics(sc, warm.trajectory, reference_trajectory(sc, warm.trajectory.t))  # warm-up
before = hwm_kb()
t0 = time.perf_counter()
out = get_engine(engine)().run(sc, integ, 1e-3, t_end=nstep * 1e-3, save_every=every)
wall = time.perf_counter() - t0
peak = hwm_kb()  # the run alone: stepping and the decimated trajectory
tr = out.trajectory
m = compute_metrics(sc, tr, reference_trajectory(sc, tr.t))
print(json.dumps(dict(wall=wall, stepping=out.wall_time_s, nsave=len(tr), before_kb=before,
                      peak_kb=peak, energy=m["energy_drift_max"],
                      attitude=m["attitude_error_max"])))
"""


def long_horizon(engine, integ, nstep, every, segment=0):
    res = subprocess.run(
        [sys.executable, "-c", LONG, engine, integ, str(nstep), str(every), str(segment)],
        capture_output=True,
        text=True,
        timeout=3600,
    )
    if res.returncode != 0:
        return {"error": res.stderr.strip().splitlines()[-1]}
    return json.loads(res.stdout.strip().splitlines()[-1])


def long_table(nlong, every, configs, segment=0):
    """Print one row per (engine, integrator) of a long-horizon run in a subprocess."""
    print(
        "| engine integrator | wall [s] | stepping [s] | saved | peak RSS [MB] | "
        "growth [MB] | energy drift | attitude err [rad] |\n|---|---|---|---|---|---|---|---|"
    )
    for engine, integ in configs:
        res = long_horizon(engine, integ, nlong, every, segment)
        if "error" in res:
            print(f"| {engine} {integ} | failed: {res['error']} |")
            continue
        print(
            f"| {engine} {integ} | {res['wall']:.2f} | {res['stepping']:.2f} | {res['nsave']} | "
            f"{res['peak_kb'] / 1024:.0f} | {(res['peak_kb'] - res['before_kb']) / 1024:.1f} | "
            f"{res['energy']:.2e} | {res['attitude']:.2e} |"
        )


#: the engines of the default suite before Drake and MJX joined it
FIRST_ENGINES = "director,exact,mujoco,pinocchio,dart,pybullet"


def default_suite(engines: str | None = None):
    """Wall time of ``director-bench run`` (runs and report) into a fresh folder, the peak
    RSS of the largest process, and the results (for the breakdown below)."""
    from reports.store.results import read_results

    with tempfile.TemporaryDirectory() as tmp:
        cmd = ["director-bench", "run", "--out", tmp, "--quiet"]
        if engines:
            cmd += ["--engines", engines]
        t0 = time.perf_counter()
        res = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        df = read_results(tmp) if res.returncode == 0 else None
    return wall, peak, res.returncode, df


def suite_breakdown(df) -> None:
    """Stepping time by engine (inside the engine's calls and with the suite's glue), and the
    suite's RKMK4 against MuJoCo's RK4 per step on the same runs."""
    g = df.groupby("engine")[["wall_time_s", "engine_time_s"]].sum().sort_values("wall_time_s")
    print("   | engine | stepping [s] | inside the engine [s] |\n   |---|---|---|")
    for eng, r in g.iterrows():
        print(f"   | {eng} | {r['wall_time_s']:.1f} | {r['engine_time_s']:.1f} |")
    key = ["scenario", "dt"]
    ok = df[df["status"] == "ok"]
    mj = ok[(ok["engine"] == "mujoco") & (ok["integrator"] == "RK4")].set_index(key)
    for eng in ("pinocchio", "dart"):
        rk = ok[(ok["engine"] == eng) & (ok["integrator"] == "RKMK4")].set_index(key)
        both = rk.merge(mj, left_index=True, right_index=True, suffixes=("", "_mj"))
        if both.empty:
            continue
        wall = (both["wall_time_s"] / both["wall_time_s_mj"]).median()
        inside = (both["engine_time_s"] / both["wall_time_s_mj"]).median()
        print(
            f"   {eng} + suite RKMK4 against mujoco RK4, same runs ({len(both)}), median ratio "
            f"of stepping wall time {wall:.2f} x (time inside {eng} alone: {inside:.2f} x)"
        )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes (a smoke run)")
    ap.add_argument("--skip-suite", action="store_true", help="skip the default-suite timing")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    import mujoco
    import numba

    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, numba {numba.__version__}, MuJoCo {mujoco.__version__}"
    )
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    if os.path.exists("/proc/self/status") is False:
        print("(no /proc: peak-memory figures are not available on this platform)")

    if not args.skip_suite:
        for label, engines in (("every engine", None), (FIRST_ENGINES, FIRST_ENGINES)):
            wall, peak, code, df = default_suite(engines)
            print(
                f"1. Default suite ({label}), runs and report: wall {wall:.0f} s, "
                f"{0 if df is None else len(df)} runs, peak RSS of the largest process "
                f"{peak / 1024:.0f} MB, exit code {code}"
            )
            if df is not None:
                suite_breakdown(df)
    nlong = 100_000 if args.quick else 1_000_000
    every = 1000
    full_mb = nlong * 23 * 8 / 2**20
    print(
        f"2. Long horizon: dzhanibekov, {nlong:.0e} steps (dt = 1e-3), one state saved per "
        f"{every} steps; the full trajectory in the suite's schema would take {full_mb:.0f} MB"
    )
    long_table(
        nlong,
        every,
        [("director", "rattle"), ("director", "rattle4"), ("mujoco", "RK4"), ("mujoco", "Euler")],
    )
    seg = 20_000
    print(
        f"\nSame horizon with streaming metrics (reports.metrics.streaming): segments of "
        f"{seg} steps, "
        "every step measured (energy, momentum, attitude... against the exact reference)"
    )
    long_table(nlong, every, [("director", "rattle"), ("mujoco", "Euler")], seg)
    print()
    nbody, nstep = (1000, 200) if args.quick else (4000, 1000)
    dt = 1e-3
    print(
        f"3. Ensemble throughput: {nbody} bodies x {nstep} steps, dt = {dt}, best of {args.repeat}"
    )
    rows = [
        (
            "director rattle (simulate_batch)",
            director_batch(nbody, nstep, dt, "rattle", args.repeat),
        ),
        (
            "director rattle4 (simulate_batch)",
            director_batch(nbody, nstep, dt, "rattle4", args.repeat),
        ),
        ("mujoco.rollout Euler", mujoco_rollout(nbody, nstep, dt, "Euler", args.repeat)),
        ("mujoco.rollout RK4", mujoco_rollout(nbody, nstep, dt, "RK4", args.repeat)),
    ]
    print("| method | body-steps/s | ns per body-step |\n|---|---|---|")
    for name, rate in rows:
        print(f"| {name} | {rate:.3e} | {1e9 / rate:.1f} |")
    r = dict(rows)
    print(
        f"ratio director rattle / mujoco.rollout Euler: "
        f"{r['director rattle (simulate_batch)'] / r['mujoco.rollout Euler']:.1f} x"
    )
    print(
        f"ratio director rattle4 / mujoco.rollout RK4: "
        f"{r['director rattle4 (simulate_batch)'] / r['mujoco.rollout RK4']:.1f} x\n"
    )

    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
