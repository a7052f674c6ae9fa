"""Drake's side of a cylindrical tree joint (Drake has none): the read-back of the massless
sleeve body between a ``PrismaticJoint`` and a ``RevoluteJoint`` on one axis, as
:mod:`references.engines.drake.system` builds it (its docstring)."""

from __future__ import annotations

import numpy as np

from references.engines import reduced


def sleeve_read_back(dm, c: int, name: str, bad: reduced.Mismatches) -> None:
    """The massless sleeve of body c's cylindrical joint (``dm``: the builder's model): mass
    and inertia 0, its PrismaticJoint from the parent's frame F (at p_F, R_F) to the sleeve's
    body frame along the frames' axis, undamped, limits infinite."""
    want, pl, f, ctx = bad.want, dm.pl, dm.frames[c], dm.context
    tj = pl.tree[c]
    slide, sleeve = dm.sleeve[c]
    what = f"{tj.name}_sleeve"
    M = sleeve.CalcSpatialInertiaInBodyFrame(ctx)
    want(f"{what}: mass", M.get_mass(), 0.0)
    want(f"{what}: rotational inertia", M.CalcRotationalInertia().CopyToFullMatrix3(),
         np.zeros((3, 3)))  # fmt: skip
    if slide.type_name() != "prismatic":
        bad.append(f"{what}: joint {slide.type_name()}, needs prismatic")
        return
    plant = dm.plant
    got = "world" if slide.parent_body().index() == plant.world_body().index() else (
        slide.parent_body().name())  # fmt: skip
    exp = "world" if tj.parent < 0 else pl.names[tj.parent]
    if got != exp or slide.child_body().index() != sleeve.index():
        bad.append(f"{what}: slides from {got!r} (needs {exp!r}) to "
                   f"{slide.child_body().name()!r}")  # fmt: skip
    XF = slide.frame_on_parent().GetFixedPoseInBodyFrame()
    want(f"{what}: frame F position in the parent", XF.translation(), f.p_F)
    want(f"{what}: frame F rotation in the parent", XF.rotation().matrix(), f.R_F)
    want(f"{what}: its own frame", slide.frame_on_child().GetFixedPoseInBodyFrame().GetAsMatrix4(),
         np.eye(4))  # fmt: skip
    want(f"{what}: prismatic axis", slide.translation_axis(), f.axis)
    want(f"{what}: joint damping", slide.GetDampingVector(ctx), np.zeros(1))
    lim = (slide.position_lower_limits(), slide.position_upper_limits())
    if not (np.all(np.isneginf(lim[0])) and np.all(np.isposinf(lim[1]))):
        bad.append(f"{what}: joint limits not infinite")
