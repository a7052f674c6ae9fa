"""Our own reading of a model file as a :class:`~references.importers.readback.Readback`: every
link at the model's zero configuration (MJCF joints at their ``ref``), in the root link's
frame; each moving joint's axis and point there, and its limits, damping, friction and armature
as the file gives them."""

from __future__ import annotations

import numpy as np

from references.importers.readback import Readback, to_root
from scenarios.models.model import joint_transform


def zero_poses(model) -> dict:
    """{link: (4, 4) pose in the root link's frame} at the zero configuration."""
    by_child: dict = {}
    for j in model.joints:
        by_child.setdefault(j.child, []).append(j)
    T: dict = {}

    def pose_of(n):
        if n in T:
            return T[n]
        js = by_child.get(n, [])
        moving = [j for j in js if j.kind not in ("fixed", "free", "floating")]
        j = moving[0] if moving else (js[0] if js else None)
        if j is None or j.parent is None:
            T[n] = np.eye(4) if j is None or j.kind in ("free", "floating") else j.origin
        else:
            q = np.zeros(3) if j.kind == "ball" else j.ref
            T[n] = pose_of(j.parent) @ joint_transform(j, q)
        return T[n]

    for lk in model.links:
        pose_of(lk.name)
    root = T[model.root]
    return {n: np.linalg.solve(root, t) for n, t in T.items()}


def readback(model) -> Readback:
    rb = Readback("ours", "reader")
    T = zero_poses(model)
    eye = np.eye(4)
    for lk in model.links:
        t = T[lk.name]
        ine = lk.inertial
        R = t[:3, :3]
        rb.bodies[lk.name] = to_root(eye, ine.mass, R @ ine.com + t[:3, 3],
                                     R @ ine.inertia @ R.T)  # fmt: skip
    for j in model.moving_joints:
        if j.kind not in ("revolute", "continuous"):
            continue  # the importers are read back for revolute joints
        t = T[j.child]
        rb.joints[j.name] = {
            "axis": t[:3, :3] @ j.axis,
            "point": t[:3, :3] @ j.point + t[:3, 3],
            "lower": j.lower,
            "upper": j.upper,
            "damping": j.damping,
            "friction": j.friction,
            "armature": j.armature,
        }
    return rb
