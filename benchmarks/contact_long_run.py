"""Law residuals and energy over a long contact-rich run: a box thrown onto the ground slides,
tumbles, bounces and comes to rest on a face; 1e5 steps of 1e-3 s (100 s).

Box 0.1 x 0.08 x 0.05 m (half extents), 1 kg, mu 0.5, e 0.3, released 0.3 m above the ground
at (2, 0.5, 0) m/s spinning at (3, 5, 1) rad/s (body axes); the scene of
tests/director_model/test_contact.py::test_tumbling_box_1e5_steps_within_the_laws.
Prints, over the whole run (each a maximum over the saves, which hold the largest value
since the previous save): the energy's largest rise above its start (J; kinetic + gravity),
the largest work of the contact impulses in one step (J; > 0 would be energy gained), the
largest penetration of a closed contact (m), the dimensionless law residuals (Signorini,
Coulomb, maximum dissipation; definitions in ContactTrajectory), the certified residual of
the contact problems, the most Newton iterations of one problem and position-stage passes of
one step; when the box comes to rest (speed below 1e-9 m/s from then on) and how far it moves
afterwards; the CPU time of the run.

    python benchmarks/contact_long_run.py              # 1e5 steps
    python benchmarks/contact_long_run.py --steps 2000 # shorter
"""

from __future__ import annotations

import argparse

import numpy as np

from director_model.contact import Body, Box, ContactScene, Pair, Plane, simulate_contact

G = 9.81


def scene() -> ContactScene:
    b = Box((0.1, 0.08, 0.05))
    body = Body("box", 1.0, b.inertia(1.0), position=(0.0, 0.0, 0.3), velocity=(2.0, 0.5, 0.0),
                omega_body=(3.0, 5.0, 1.0))  # fmt: skip
    return ContactScene([body], {"box": b}, {"ground": Plane()},
                        [Pair("box", "ground", mu=0.5, e=0.3)], gravity=(0.0, 0.0, -G))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100_000)
    ap.add_argument("--save-every", type=int, default=100)
    args = ap.parse_args()
    dt = 1e-3
    tr = simulate_contact(scene(), dt=dt, t_end=args.steps * dt, save_every=args.save_every)
    speed = np.linalg.norm(tr.velocity[:, 0], axis=1)
    moving = np.nonzero(speed > 1e-9)[0]
    k_rest = moving[-1] + 1 if moving.size else 0
    rows = [
        ("steps", f"{tr.nstep}"),
        ("energy at start (J)", f"{tr.energy[0]:.6g}"),
        ("largest energy rise above the start (J)", f"{tr.energy.max() - tr.energy[0]:.3g}"),
        ("largest contact work in one step (J)", f"{tr.contact_work.max():.3g}"),
        ("largest penetration (m)", f"{tr.penetration.max():.3g}"),
        ("Signorini residual", f"{tr.signorini.max():.3g}"),
        ("Coulomb residual", f"{tr.coulomb.max():.3g}"),
        ("maximum-dissipation residual", f"{tr.dissipation.max():.3g}"),
        ("certified residual of a contact problem", f"{tr.residual.max():.3g}"),
        ("most Newton iterations of one problem", f"{tr.iterations.max()}"),
        ("most position-stage passes of one step", f"{tr.passes.max()}"),
    ]
    if k_rest < len(tr.t):
        drift = np.abs(tr.position[-1, 0] - tr.position[k_rest, 0]).max()
        rows.append(("at rest from (s; speed < 1e-9 m/s after)", f"{tr.t[k_rest]:.3g}"))
        rows.append(("largest displacement after coming to rest (m)", f"{drift:.3g}"))
    else:
        rows.append(("at rest", "not within the run"))
    rows.append(("CPU time of the run (s)", f"{tr.cpu_time_s:.2f}"))
    print("| quantity | value |")
    print("|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")


if __name__ == "__main__":
    main()
