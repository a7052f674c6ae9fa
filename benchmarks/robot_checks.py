"""Two checks of the robot-model path (issue 36), printed: the reference's own accuracy on a
model with an exact answer, and planted reader mistakes caught by the importer table.

1. A URDF compound pendulum (one link on a hinge, from rest at 2.5 rad) must come back to its
   start after its exact period T = 4 K(k) sqrt(I_p / (m g l)), k = sin(theta0 / 2) (Landau &
   Lifshitz, Mechanics, section 11). The file is read by the suite's URDF reader, integrated
   by the reduced-coordinate reference (references.exact.multibody, DOP853); printed: the
   distance of the centre of mass from its start after T, the reference's own error estimate
   there, and the half-period mirror error.
2. The suite's shipped arm (scenarios/robots/models/arm3.urdf, every origin rotated by an rpy)
   read with a planted mistake, then compared with MuJoCo's importer (faithful): an inertial
   rotated by its rpy twice, and joint axes taken in the parent's frame. Printed: the rows
   of the importer table that catch each (none without the mistake).

Run: python benchmarks/robot_checks.py (needs scipy; part 2 needs MuJoCo)."""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np

import scenarios
from scenarios.models import read_model, to_system
from scenarios.models import urdf as U

ARM3 = Path(scenarios.__file__).parent / "robots" / "models" / "arm3.urdf"

PENDULUM = """<robot name="pendulum">
  <link name="base"><inertial><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="arm"><inertial><origin xyz="0 0 -{l}"/><mass value="{m}"/>
    <inertia ixx="{Ic}" ixy="0" ixz="0" iyy="{Ic}" iyz="0" izz="0.005"/></inertial></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 1 0"/></joint>
</robot>
"""


def pendulum() -> None:
    from scipy.special import ellipk

    from references.exact.multibody import solve, tree_from_world

    m, l, Ic, th0 = 1.3, 0.4, 0.02, 2.5
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "p.urdf"
        p.write_text(PENDULUM.format(m=m, l=l, Ic=Ic))
        conv = to_system(read_model(p), {"j": th0})
    tree, q0, u0 = tree_from_world(conv.bodies, conv.joints, (0.0, 0.0, -9.81))
    T = 4 * ellipk(math.sin(th0 / 2) ** 2) * math.sqrt((Ic + m * l * l) / (m * 9.81 * l))
    sol = solve(tree, q0, u0, [0.5 * T, T])
    start = conv.bodies[0].position
    err = float(np.linalg.norm(sol.x[-1, 0] - start))
    mirror = abs(float(sol.x[0, 0, 0] + start[0]))
    print(f"compound pendulum, URDF, from rest at {th0} rad, exact period T = {T:.12f} s")
    print(f"  centre of mass after T, distance from its start: {err:.3g} m ({err / l:.3g} l)")
    print(f"  the reference's own position error estimate:      {sol.accuracy['position']:.3g} m")
    print(f"  after T/2, x mirrored about the vertical, error:  {mirror:.3g} m")


def planted() -> None:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("planted mistakes: MuJoCo is not installed (its importer is the comparison)")
        return
    from references.engines.importers import importer_table

    def table(label):
        rows = importer_table(read_model(ARM3), engines=["mujoco"], configs=["faithful"])
        caught = [r for r in rows if r.quantity not in ("agree",)]
        print(f"{label}: {len(caught)} row(s)")
        for r in caught:
            print(f"    {r.line()}")

    table("arm3.urdf as read, against MuJoCo's importer (faithful)")
    saved = U.rotate_inertia, U.axis_in_child
    try:
        U.rotate_inertia = lambda I, R: (R @ R) @ I @ (R @ R).T
        table("planted: each inertial rotated by its rpy twice")
        U.rotate_inertia = saved[0]
        U.axis_in_child = lambda a, T: T[:3, :3].T @ a
        table("planted: each joint axis taken in the parent's frame")
    finally:
        U.rotate_inertia, U.axis_in_child = saved


def main() -> int:
    pendulum()
    print()
    planted()
    return 0


if __name__ == "__main__":
    sys.exit(main())
