"""Conservation over 1e6 steps: director_model.system RATTLE on two chains.

1. A free-floating chain of 5 rods on ball joints (rod_chain(5, hang=False), random tumbling
   velocities, no gravity): the joint residuals at position and velocity level, the
   orthonormality of the directors, the drift of the total linear and angular momentum
   (both momentum maps of the free system), and the energy error.
2. A double pendulum of rigid rods hanging from a ball joint at the origin under gravity
   (rod_chain(2, hang=True), tilted by ~1 rad and tumbling: chaotic): the drift of the
   vertical angular momentum about the pivot (the momentum map of the rotation about the
   vertical) and the energy error, whose largest value over the first and over the last
   tenth of the run shows whether it drifts.

Momentum drifts are given absolutely and relative to a scale of the momentum (for L: sum over
bodies of |x_i x m_i v_i| + |I_i W_i| at t = 0; for p: sum m_i |v_i|), never to |L0| or |p0|.

    python benchmarks/system_conservation.py               # 1e6 steps each (about 10 s each)
    python benchmarks/system_conservation.py --steps 100000
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from director_model.system import SystemStepper
from director_model.system.examples import rod_chain


def run(bodies, joints, gravity, nstep: int, dt: float, scheme: str):
    st = SystemStepper(bodies, joints, gravity=gravity, scheme=scheme, dt=dt)
    t0 = time.perf_counter()
    tr = st.advance(nstep, save_every=max(nstep // 1000, 1), include_start=True)
    return tr, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1_000_000)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--scheme", default="rattle")
    args = ap.parse_args()
    n, dt = args.steps, args.dt

    b, j = rod_chain(5, False, seed=11)
    tr, wall = run(b, j, (0.0, 0.0, 0.0), n, dt, args.scheme)
    m = np.array([x.mass for x in b])
    Lscale = sum(
        np.linalg.norm(np.cross(x.position, x.mass * x.velocity))
        + np.linalg.norm(x.inertia * x.omega_body)
        for x in b
    )
    pscale = float(np.sum(m * np.linalg.norm([x.velocity for x in b], axis=1)))
    dL = np.abs(tr.angular_momentum - tr.angular_momentum[0]).max()
    dp = np.abs(tr.linear_momentum - tr.linear_momentum[0]).max()
    dE = np.abs(tr.energy - tr.energy[0])
    k = max(len(tr) // 10, 1)
    print(f"free chain of 5 rods, {args.scheme}, dt = {dt:g} s, {n} steps ({n * dt:g} s), "
          f"{wall:.1f} s wall, {len(tr)} saved states")  # fmt: skip
    xend = float(np.abs(tr.position[-1]).max())
    print(f"  joint residual, position: max {tr.constraint_position.max():.2e} m (the chain "
          f"has drifted to |x| = {xend:.3g} m: {tr.constraint_position.max() / xend:.1e} "
          "of it)")  # fmt: skip
    print(f"  joint residual, velocity: max {tr.constraint_velocity.max():.2e} m/s")
    print(f"  orthonormality max |R^T R - 1|: {tr.orthonormality.max():.2e}")
    print(f"  linear momentum drift: {dp:.2e} kg m/s ({dp / pscale:.2e} of sum m|v| = "
          f"{pscale:.3g})")  # fmt: skip
    print(f"  angular momentum drift: {dL:.2e} kg m^2/s ({dL / Lscale:.2e} of the scale "
          f"{Lscale:.3g})")  # fmt: skip
    print(f"  energy error: max {dE.max():.2e} J of E = {tr.energy[0]:.4g} J; first tenth "
          f"{dE[:k].max():.2e}, last tenth {dE[-k:].max():.2e}")  # fmt: skip

    b, j = rod_chain(2, True, seed=5, tilt=1.0)
    g = (0.0, 0.0, -9.81)
    tr, wall = run(b, j, g, n, dt, args.scheme)
    Lz = tr.angular_momentum[:, 2]
    Lscale = sum(
        np.linalg.norm(np.cross(x.position, x.mass * x.velocity))
        + np.linalg.norm(x.inertia * x.omega_body)
        for x in b
    )
    dE = np.abs(tr.energy - tr.energy[0])
    Escale = sum(x.mass * 9.81 * 2.0 for x in b)  # m |g| x the largest distance (2 m)
    print(f"hanging double pendulum (chaotic), {args.scheme}, dt = {dt:g} s, {n} steps, "
          f"{wall:.1f} s wall")  # fmt: skip
    print(f"  joint residuals: position {tr.constraint_position.max():.2e} m, velocity "
          f"{tr.constraint_velocity.max():.2e} m/s")  # fmt: skip
    print(f"  vertical angular momentum drift: {np.abs(Lz - Lz[0]).max():.2e} kg m^2/s "
          f"({np.abs(Lz - Lz[0]).max() / Lscale:.2e} of the scale {Lscale:.3g})")  # fmt: skip
    print(f"  energy error: max {dE.max():.2e} J ({dE.max() / Escale:.2e} of m|g|l = "
          f"{Escale:.3g} J); first tenth {dE[:k].max():.2e}, "
          f"last tenth {dE[-k:].max():.2e}")  # fmt: skip


if __name__ == "__main__":
    main()
