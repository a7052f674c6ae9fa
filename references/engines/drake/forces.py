"""A system's force elements (:mod:`scenarios.force_elements`) in Drake's plant, with Drake's
own elements where it has them:

- Spring ``k``: a ``LinearSpringDamper`` between point P = ``anchor_a`` of body a and point Q =
  ``anchor_b`` of body b (the world body for the ground: ``anchor_b`` is then a world point;
  every Drake body frame is the body's principal frame at its centre of mass, so the anchors
  are P and Q as written) with free length l0, stiffness k and damping c: Drake's law
  f = -(k (l - l0) + c l') along the line is the scenario's.
- Torque on a revolute joint that Drake holds as a ``RevoluteJoint`` of the tree: the
  constant generalised force Q = (the torque on the joint's child) . (its axis in the world)
  on the joint's velocity, through the plant's ``applied_generalized_force`` input port
  (fixed in the context, as every plant of a run is built: at t = 0 and at each chart switch):
  +tau when the child is the joint's body a, -tau (u . n_c) when it is body b. A torque on a
  joint that closes a loop (Drake holds it as constraints, not a degree of freedom) is
  unsupported with that reason.

Read back (:func:`read_back`): the number of force elements (gravity and one per spring), each
spring's bodies, points, free length, stiffness and damping; the input port's value. What is
handed to Drake is made by :func:`spring_parameters` and :func:`torque_forces` (the builder's
boundary, where the tests plant mistakes).
"""

from __future__ import annotations

import numpy as np

from references.engines import reduced
from references.errors import Unsupported


def spring_parameters(scenario) -> list[tuple]:
    """[(body a, P, body b or None, Q, l0, k, c)] of the springs, as Drake is given them."""
    return [(s.body_a, np.asarray(s.anchor_a, float), s.body_b, np.asarray(s.anchor_b, float),
             s.rest_length, s.stiffness, s.damping)
            for s in getattr(scenario, "springs", ())]  # fmt: skip


def add_springs(plant, body: dict, pl: reduced.Plan, scenario) -> list:
    """Add a LinearSpringDamper per spring (before Finalize); the elements, in order."""
    from pydrake.multibody.tree import LinearSpringDamper

    idx = {n: i for i, n in enumerate(pl.names)}
    out = []
    for a, P, b, Q, l0, k, c in spring_parameters(scenario):
        B = plant.world_body() if b is None else body[idx[b]]
        out.append(plant.AddForceElement(
            LinearSpringDamper(body[idx[a]], P, B, Q, float(l0), float(k), float(c))))  # fmt: skip
    return out


def torque_forces(pl: reduced.Plan, scenario, joint: dict) -> list[tuple[int, float, str]]:
    """[(velocity index, generalised force, label)] of the joint torques (module docstring);
    :class:`Unsupported` for a torque on a loop closure."""
    tree = {tj.name: c for c, tj in pl.tree.items()}
    by = {j.name: j for j in pl.joints}
    out = []
    for tq in getattr(scenario, "torques", ()):
        if tq.joint not in tree:
            raise Unsupported(
                f"drake: the torque on joint {tq.joint!r}: that joint closes a loop (ball "
                "constraints in Drake), which has no generalised velocity for the applied "
                "generalised force to act on"
            )
        c = tree[tq.joint]
        j = by[tq.joint]
        ia = pl.names.index(j.body_a)
        _, Rc, _, _ = reduced.world(pl, c)
        _, Ra, _, _ = reduced.world(pl, ia)
        u = Ra @ reduced.unit(j.axis_a, f"joint {j.name!r}: axis_a")
        on_child = tq.torque * u if ia == c else -tq.torque * u
        jt = joint[c]
        Q = float(on_child @ (Rc @ np.asarray(jt.revolute_axis(), float)))
        iv = int(jt.velocity_start())
        out.append((iv, Q, f"torque on {tq.joint!r}: applied generalised force [{iv}] = "
                           f"{Q:.12g} N m"))  # fmt: skip
    return out


def fix_torques(plant, context, applied) -> np.ndarray:
    """Fix the applied generalised force input port to the torques' vector; returns it."""
    Q = np.zeros(plant.num_velocities())
    for iv, q, _ in applied:
        Q[iv] += q
    plant.get_applied_generalized_force_input_port().FixValue(context, Q)
    return Q


def read_back(dm, scenario, want, bad) -> None:
    """Compare Drake's force elements and applied generalised force with the scenario:
    ``want(what, got, expected, scale)`` and ``bad`` (a list) are the builder's read-back."""
    from pydrake.multibody.tree import ForceElementIndex

    plant, pl = dm.plant, dm.pl
    springs = getattr(scenario, "springs", ())
    want("number of force elements (gravity, springs)", plant.num_force_elements(),
         1 + len(springs))  # fmt: skip
    for k, s in enumerate(springs):
        what = f"spring {s.name!r}"
        if k + 1 >= plant.num_force_elements():
            break
        e = plant.get_force_element(ForceElementIndex(k + 1))
        if type(e).__name__ != "LinearSpringDamper":
            bad.append(f"{what}: Drake's force element {k + 1} is a {type(e).__name__}")
            continue
        names = [e.bodyA().name(), e.bodyB().name()]
        exp = [s.body_a, plant.world_body().name() if s.body_b is None else s.body_b]
        if names != exp:
            bad.append(f"{what}: between bodies {names}, needs {exp}")
        want(f"{what}: p_AP (anchor_a)", e.p_AP(), s.anchor_a)
        want(f"{what}: p_BQ (anchor_b)", e.p_BQ(), s.anchor_b)
        want(f"{what}: free_length", e.free_length(), s.rest_length)
        want(f"{what}: stiffness", e.stiffness(), s.stiffness)
        want(f"{what}: damping", e.damping(), s.damping)
    if getattr(scenario, "torques", ()):
        # expected from Drake's own kinematics, not from torque_forces: the couples tau u on
        # body a and -tau u on body b through each body's angular-velocity Jacobian
        from pydrake.multibody.tree import JacobianWrtVariable

        got = plant.get_applied_generalized_force_input_port().Eval(dm.context)
        exp = np.zeros(plant.num_velocities())
        idx = {n: i for i, n in enumerate(pl.names)}
        by = {j.name: j for j in pl.joints}
        W = plant.world_frame()

        def jw(name):
            frame = dm.body[idx[name]].body_frame()
            return plant.CalcJacobianAngularVelocity(dm.context, JacobianWrtVariable.kV,
                                                     frame, W, W)  # fmt: skip

        for tq in scenario.torques:
            j = by[tq.joint]
            Ra = dm.body[idx[j.body_a]].EvalPoseInWorld(dm.context).rotation().matrix()
            u = Ra @ reduced.unit(j.axis_a, f"joint {j.name!r}: axis_a")
            exp += jw(j.body_a).T @ (tq.torque * u)
            if j.body_b is not None:
                exp -= jw(j.body_b).T @ (tq.torque * u)
        want("applied generalised force (the joint torques)", got, exp)


def record(scenario, applied) -> list[str]:
    """The settings record's lines: what each element became."""
    out = [f"spring {s.name!r}: LinearSpringDamper (free_length {s.rest_length:g}, stiffness "
           f"{s.stiffness:g}, damping {s.damping:g}; read back)"
           for s in getattr(scenario, "springs", ())]  # fmt: skip
    return out + [label for _, _, label in applied]
