"""DART's side of a cylindrical tree joint (DART has none): the massless sleeve body node
between a ``PrismaticJoint`` and a ``RevoluteJoint`` on one axis, as
:mod:`references.engines.dart.system` builds it (its docstring): the warnings DART prints for
the sleeve's zero mass and moments, the two joints as one for the RKMK4, the sleeve's read-back.
"""

from __future__ import annotations

import numpy as np

from references.engines import reduced

#: what DART says when handed a sleeve's zero mass and moments (DART 6.20, Inertia.cpp and
#: BodyNode.cpp; ANSI colours stripped): the only warnings a build may print
SLEEVE_WARNINGS = (
    "[Inertia::verifyMoment] Invalid entry for",  # once per diagonal entry: "(k,k): 0"
    "[Inertia::setMoment] Passing in an invalid moment of inertia matrix",
    "A negative or zero mass [0] is set to BodyNode",
)


class Cylinder:
    """A cylindrical joint's two DART joints (the sleeve's prismatic, the body's revolute) as
    one joint of two coordinates (slide, turn), for the RKMK4's blocks."""

    def __init__(self, slide, turn):
        self.slide, self.turn = slide, turn

    def getPositions(self):
        return np.concatenate([self.slide.getPositions(), self.turn.getPositions()])

    def getVelocities(self):
        return np.concatenate([self.slide.getVelocities(), self.turn.getVelocities()])

    def setPositions(self, q):
        self.slide.setPositions(np.asarray(q[:1], float))
        self.turn.setPositions(np.asarray(q[1:], float))

    def setVelocities(self, u):
        self.slide.setVelocities(np.asarray(u[:1], float))
        self.turn.setVelocities(np.asarray(u[1:], float))


def sleeve_read_back(dm, c: int, name: str, bad: reduced.Mismatches) -> None:
    """The massless sleeve of body c's cylindrical joint (module docstring): its mass and
    moments 0, its PrismaticJoint from the parent at the joint's placement along the frames'
    axis, neutral, its degree of freedom just before the body's; the body's RevoluteJoint at
    the sleeve's origin about the same axis."""
    want, pl, f = bad.want, dm.pl, dm.frames[c]
    tj, joint = pl.tree[c], dm.joint[c]
    sj, sleeve = dm.sleeve[c]
    what = f"{tj.name}_sleeve"
    inr = sleeve.getInertia()
    want(f"{what}: mass", inr.getMass(), 0.0)
    want(f"{what}: moments", inr.getMoment(), np.zeros((3, 3)))
    if sj.getType() != "PrismaticJoint":
        bad.append(f"{what}: joint {sj.getType()}, needs PrismaticJoint")
    parent = sleeve.getParentBodyNode()
    got = "ground" if parent is None else parent.getName()
    exp = "ground" if tj.parent < 0 else pl.names[tj.parent]
    if got != exp:
        bad.append(f"{what}: parent {got!r}, needs {exp!r}")
    place = np.eye(4)
    place[:3, :3], place[:3, 3] = f.R, f.p
    want(f"{what}: transform from the parent", sj.getTransformFromParentBodyNode().matrix(),
         place)  # fmt: skip
    want(f"{what}: transform to the sleeve", sj.getTransformFromChildBodyNode().matrix(),
         np.eye(4))  # fmt: skip
    want(f"{what}: slide axis", sj.getAxis(), f.axis)
    for label, get in (("damping", sj.getDampingCoefficient),
                       ("spring stiffness", sj.getSpringStiffness),
                       ("Coulomb friction", sj.getCoulombFriction)):  # fmt: skip
        want(f"{what}: joint {label}", get(0), 0.0)
    if sj.areLimitsEnforced():
        bad.append(f"{what}: joint limits enforced")
    want(f"{name}: turn's degree of freedom after the slide's", joint.getIndexInSkeleton(0),
         sj.getIndexInSkeleton(0) + 1)  # fmt: skip
    want(f"{name}: transform from its sleeve", joint.getTransformFromParentBodyNode().matrix(),
         np.eye(4))  # fmt: skip
    want(f"{name}: turn axis", joint.getAxis(), f.axis)
    other = [w for w in dm.build_warnings if not any(k in w for k in SLEEVE_WARNINGS)]
    if other:
        bad.append(f"{what}: DART warned {other}")
