"""Conservation figures of director_model (docs/numerics.md, section 3, table "Measured"):
round-off drift of the torque-free energy and |L| over random bodies, with and without
compensated sums, and the bounded O(h^2) energy error of RATTLE on the Simo-Wong top.

Run: python benchmarks/director_conservation.py (about a minute on 2 cores).
"""

import numpy as np
from scipy.spatial.transform import Rotation

import director_model as dm

#: the Simo-Wong top's energy (docs/numerics.md, section 5: E0 of its test vector)
SIMO_WONG_E0 = 1269.9750052078993249


def random_bodies(nbody, hw, h, seed):
    """Inertias (every tenth body flat), rates with h |W| = hw, random attitudes."""
    rng = np.random.default_rng(seed)
    J = rng.uniform(0.0, 1.0, size=(nbody, 3))
    J[::10, 2] = 0.0
    inertia = J.sum(axis=1, keepdims=True) - J
    W = rng.normal(size=(nbody, 3))
    W *= hw / h / np.linalg.norm(W, axis=1, keepdims=True)
    R = Rotation.random(nbody, random_state=seed + 3).as_matrix()
    return inertia, W, R


def relative_drift(values):
    """Largest |v/v0 - 1| along the last axis (v0 the first sample)."""
    return float(np.abs(values / values[..., :1] - 1).max())


def large_steps(h=0.01):
    inertia, W, R = random_bodies(200, 0.4, h, 2024)
    for n in (1_000, 10_000, 100_000):
        bt = dm.simulate_batch(
            1.0, inertia, rotation=R, omega_body=W, dt=h, t_end=n * h, save_every=n // 10
        )
        e = relative_drift(bt.energy)
        ell = relative_drift(np.linalg.norm(bt.angular_momentum, axis=-1))
        print(f"200 bodies, h|W| = 0.4, {n:>7} steps: E drift {e:.2g}, |L| drift {ell:.2g}")


def small_steps(h=0.01, n=1_000_000):
    inertia, W, R = random_bodies(10, 0.01, h, 7)
    for compensated in (True, False):
        e = ell = c = 0.0
        for k in range(len(W)):
            tr = dm.simulate(
                1.0, inertia[k], rotation=R[k], omega_body=W[k], dt=h, t_end=n * h,
                save_every=n // 100, compensated=compensated,
            )  # fmt: skip
            e = max(e, relative_drift(tr.energy))
            ell = max(ell, relative_drift(np.linalg.norm(tr.angular_momentum, axis=-1)))
            c = max(c, float(tr.constraint_position.max()))
        print(
            f"10 bodies, h|W| = 0.01, {n} steps, compensated={compensated}: E drift {e:.2g}, "
            f"|L| drift {ell:.2g}, max|D^T D - 1| {c:.2g}"
        )


def simo_wong(n=100_000):
    R0 = Rotation.from_rotvec([0.05, 0, 0]).as_matrix()
    for h in (2e-3, 1e-3):
        tr = dm.simulate(
            1.0, (4.75, 4.75, 1.0), rotation=R0, omega_body=(0, 0, 50), gravity=(0, 0, -40),
            pivot=(0, 0, -0.5), dt=h, t_end=n * h, save_every=10,
        )  # fmt: skip
        rel = np.abs(tr.energy / SIMO_WONG_E0 - 1)
        m = len(rel) // 10
        Lz = tr.angular_momentum[:, 2]
        spin = np.einsum("ij,ij->i", tr.angular_momentum, tr.rotation[:, :, 2])
        print(
            f"Simo-Wong top, h = {h:g}, {n} steps: energy error max {rel.max():.3g} (first 10 % "
            f"{rel[:m].max():.3g}, last 10 % {rel[-m:].max():.3g}); drift of L_z "
            f"{relative_drift(Lz):.2g}, of the spin {relative_drift(spin):.2g}"
        )


if __name__ == "__main__":
    large_steps()
    small_steps()
    simo_wong()
