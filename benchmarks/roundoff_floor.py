"""Round-off floor of director_model's RATTLE schemes: attitude error against the number of
steps, with and without compensated summation.

Case: the Dzhanibekov body of docs/numerics.md section 5 (free body, I = (2, 3, 4) kg m^2,
W0 = (0.01, 2, 0.01) rad/s, R0 = identity, no gravity) over 30 s, i.e. through two flips of
the intermediate axis. Error: the largest geodesic angle 2 arcsin(|R - R_ref|_F / (2 sqrt 2))
over the states every 0.1 s, against the exact solution of references.exact (Jacobi
elliptic functions; its own error estimate is printed, about 2e-13 here).

Each scheme runs at dt = 0.1/k (so that 0.1 s is a whole number of steps) for k on a
geometric grid, once with the shipped compensated sums and once with plain sums
(``compensated=False``). With plain sums the error stops falling and then grows as dt
shrinks (round-off of O(1) quantities every step); with compensation it falls with the
order of the scheme down to a floor set by the rounding of the O(h) increments. Optionally
MuJoCo's RK4 on the same body, for comparison.

Usage:
    python benchmarks/roundoff_floor.py [--out FIGURE.png] [--quick] [--no-mujoco]

Prints the table of the plotted numbers; writes the figure (default
/tmp/director_roundoff_floor.png).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

import director_model as dm
from references.exact.free_body import FreeBody

I = (2.0, 3.0, 4.0)
W0 = (0.01, 2.0, 0.01)
T_END = 30.0
T_SAVE = 0.1
TARGET = 1e-11

#: k values (dt = 0.1/k) per scheme: from the truncation-dominated range down to where the
#: plain sums show their floor (rattle: up to 3e7 steps, about 1.5 s per run)
GRID = {
    "rattle": [10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 50000, 100000],
    "rattle4": [2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000],
    "rattle6": [1, 2, 4, 5, 8, 10, 16, 20, 40, 50, 100, 200, 400, 1000, 2000],
}
QUICK = {
    "rattle": [10, 100, 1000, 10000],
    "rattle4": [5, 50, 500, 5000],
    "rattle6": [2, 10, 40, 200, 1000],
}


def geodesic(R, Rref) -> np.ndarray:
    """Rotation angle of R^T Rref, rad, from the Frobenius distance."""
    n = np.linalg.norm(R - Rref, axis=(-2, -1))
    return 2.0 * np.arcsin(np.minimum(n / (2.0 * math.sqrt(2.0)), 1.0))


def director_error(scheme: str, k: int, compensated: bool, Rref) -> tuple[float, float]:
    dt = T_SAVE / k
    tr = dm.simulate(1.0, I, rotation=np.eye(3), omega_body=W0, scheme=scheme, dt=dt,
                     t_end=T_END, save_every=k, compensated=compensated)  # fmt: skip
    return float(np.max(geodesic(tr.rotation, Rref))), tr.wall_time_s


def mujoco_rk4_error(k: int, Rref) -> float:
    import mujoco

    dt = T_SAVE / k
    xml = f"""<mujoco><option timestep="{dt!r}" gravity="0 0 0" integrator="RK4"/>
      <worldbody><body><freejoint/><geom type="sphere" size="0.1"/>
      <inertial pos="0 0 0" mass="1" diaginertia="2 3 4"/></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[3:6] = W0  # free joint: angular velocity in body axes
    R = np.empty((Rref.shape[0], 3, 3))
    buf = np.empty(9)
    for i in range(Rref.shape[0]):
        if i:
            mujoco.mj_step(m, d, nstep=k)
        mujoco.mju_quat2Mat(buf, d.qpos[3:7])  # MuJoCo quaternions are (w, x, y, z)
        R[i] = buf.reshape(3, 3)
    return float(np.max(geodesic(R, Rref)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/director_roundoff_floor.png", help="figure (PNG)")
    ap.add_argument("--quick", action="store_true", help="a few step counts per scheme")
    ap.add_argument("--no-mujoco", action="store_true", help="leave out MuJoCo's RK4")
    args = ap.parse_args(argv)
    grid = QUICK if args.quick else GRID

    nsave = int(round(T_END / T_SAVE)) + 1
    t = np.arange(nsave) * T_SAVE
    ref = FreeBody(I, W0, np.eye(3))
    Rref = ref.rotation(t)
    import numba

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"numba {numba.__version__}; load average {os.getloadavg()[0]:.2f}")  # fmt: skip
    print(
        f"case: free body I = {I}, W0 = {W0}, R0 = identity, {T_END:g} s; error = max "
        f"geodesic angle over {nsave} states every {T_SAVE:g} s against references.exact"
    )
    print(f"exact reference: case {ref.case}, its error estimate over the run "
          f"{ref.accuracy(t):.1e} rad")  # fmt: skip
    dm.simulate(1.0, I, rotation=np.eye(3), omega_body=W0, dt=0.01, t_end=0.01)  # compile

    rows = {}
    print()
    print(f"| {'scheme':8s} | {'dt (s)':>9s} | {'steps':>9s} | {'compensated':>11s} | "
          f"{'plain sums':>10s} | {'plain/comp':>10s} | {'run (s)':>7s} |")  # fmt: skip
    print(f"|{'-' * 10}|{'-' * 11}|{'-' * 11}|{'-' * 13}|{'-' * 12}|{'-' * 12}|{'-' * 9}|")
    for scheme, ks in grid.items():
        rows[scheme] = []
        for k in ks:
            dt = T_SAVE / k
            nstep = int(round(T_END / dt))
            e_c, wall = director_error(scheme, k, True, Rref)
            e_p, _ = director_error(scheme, k, False, Rref)
            rows[scheme].append((dt, nstep, e_c, e_p))
            print(f"| {scheme:8s} | {dt:9.3g} | {nstep:9d} | {e_c:11.2e} | {e_p:10.2e} | "
                  f"{e_p / e_c:10.2f} | {wall:7.3f} |", flush=True)  # fmt: skip
    mj = []
    if not args.no_mujoco:
        try:
            import mujoco

            print()
            print(f"MuJoCo {mujoco.__version__} RK4 (mj_step), same body:")
            for k in [10, 100, 1000] if args.quick else [5, 10, 20, 50, 100, 200, 500, 1000]:
                e = mujoco_rk4_error(k, Rref)
                mj.append((int(round(T_END * k / T_SAVE)), e))
                print(f"  dt = {T_SAVE / k:9.3g} s, {mj[-1][0]:8d} steps: {e:.2e}", flush=True)
        except ImportError:
            print("mujoco not installed: RK4 left out")

    print()
    print(f"lowest error with compensation (target {TARGET:g} rad):")
    for scheme, r in rows.items():
        i = int(np.argmin([e for _, _, e, _ in r]))
        j = int(np.argmin([e for _, _, _, e in r]))
        print(f"  {scheme:8s}: {r[i][2]:.2e} at dt = {r[i][0]:.3g} s ({r[i][1]} steps); "
              f"plain sums at best {r[j][3]:.2e} at dt = {r[j][0]:.3g} s")  # fmt: skip

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5.0), constrained_layout=True)
    colors = {"rattle": "tab:blue", "rattle4": "tab:orange", "rattle6": "tab:green"}
    for scheme, r in rows.items():
        n = [x[1] for x in r]
        ax.loglog(n, [x[2] for x in r], "o-", color=colors[scheme], label=f"{scheme}")
        ax.loglog(n, [x[3] for x in r], "x--", color=colors[scheme], alpha=0.7,
                  label=f"{scheme}, plain sums")  # fmt: skip
    if mj:
        ax.loglog([x[0] for x in mj], [x[1] for x in mj], "s:", color="0.4",
                  label="MuJoCo RK4")  # fmt: skip
    ax.axhline(TARGET, color="k", lw=0.8, ls=":")
    ax.text(1e3, TARGET * 1.3, "target 1e-11", fontsize=8)
    ax.axhline(ref.accuracy(t), color="0.5", lw=0.8, ls="-.")
    ax.text(1e3, ref.accuracy(t) * 1.3, "exact reference's error estimate", fontsize=8)
    ax.set_xlabel("number of steps over 30 s")
    ax.set_ylabel("max attitude error (rad)")
    ax.set_title("Dzhanibekov body, 30 s: compensated (solid) vs plain sums (dashed)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    print(f"\nfigure: {out}")
    print(f"load average at end: {os.getloadavg()[0]:.2f}; {time.strftime('%Y-%m-%d %H:%M')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
