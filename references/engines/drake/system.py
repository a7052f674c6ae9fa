"""Drake builder for systems of rigid bodies: one MultibodyPlant in Drake's reduced coordinates
(``BallRpyJoint``, ``RevoluteJoint``, ``PrismaticJoint``, ``UniversalJoint``,
``QuaternionFloatingJoint`` for a floating root; a cylindrical joint through a massless body),
loops
closed by ``AddBallConstraint`` on discrete (SAP) plants only.

Input: a system scenario (the contract's ``name, gravity, bodies, joints``); the spanning tree
is the kit's :func:`~references.engines.reduced.plan` (one definition for every
reduced-coordinate engine).

Frames. Every Drake body frame is the body's principal frame at its COM
(``SpatialInertia.MakeFromCentralInertia(m, 0, RotationalInertia(I1, I2, I3))``), so Drake's
body poses and spatial velocities are the suite's states with no conversion. A tree joint
connects a frame F on the parent (``FixedOffsetFrame`` at the parent's anchor X, in the parent's
principal frame relative to its COM, a world point for the ground; rotation R_F = R_p^T R_c at
t = 0) to a frame M on the child (at the child's anchor Y, identity rotation), so every joint's
coordinates are zero at t = 0 but a prismatic joint's, which is the anchors' offset along
the axis (:func:`engine_frames`, the builder's boundary where the tests plant mistakes):

==================  ======================  ================================================
scenario kind       Drake joint             initial coordinates
==================  ======================  ================================================
spherical,          ``BallRpyJoint``        rpy 0; w_FM (in F) = R_F^T R_p^T (w_c - w_p)
fixed_point
revolute            ``RevoluteJoint`` (axis  angle 0; rate n . (W_c - R_rel^T W_p)
                    = the child's, in M)
prismatic           ``PrismaticJoint`` (axis translation = the anchors' offset along the
                    = the child's, in M)    axis, rate its rate
                                            (:func:`~references.engines.reduced.slide_state`)
universal           ``UniversalJoint`` (F's  angles 0; rates: w_FM in F's x and y
                    x the parent's axis, y  (:func:`universal_frames`: F and M turned so,
                    the child's)            coinciding at t = 0)
cylindrical         ``PrismaticJoint`` from  the slide as a prismatic joint's; the turn 0,
                    F to a massless sleeve  its rate n . (W_c - R_rel^T W_p)
                    body, ``RevoluteJoint``
                    from it to M (both on
                    the child's axis)
(floating root)     ``QuaternionFloatingJoint``  SetFreeBodyPose / SetFreeBodySpatialVelocity
others              -                       unsupported (not built by this adapter)
==================  ======================  ================================================

Cylindrical joints: Drake has none; the builder writes the composition: a massless body, the
joint's *sleeve* (``<joint>_sleeve``: ``SpatialInertia.Zero()``), on a ``PrismaticJoint`` from
F (its body frame the joint's M at a zero slide) and the body on a ``RevoluteJoint`` from the
sleeve's body frame to M, both along the child's axis (the slide and the turn about one line
commute). Drake accepts a massless body that is not a leaf (the body hangs from it, so the
articulated inertia stays regular; measured: the runs agree with the loop reference,
tests/references/engines/test_system_cylindrical.py). Read back: the sleeve's zero mass and
inertia, both joints' types, parents, frames and axes.

The roll-pitch-yaw chart of a ball joint is singular at pitch = +-pi/2. The builder switches
charts for the whole system at once: a Simulator monitor ends ``AdvanceTo`` at the end of a step
where any ball joint's |cos pitch| < :data:`CHART_SWITCH_COS`; the plant is then rebuilt by
:func:`assemble` (the one entry point of every plant, as at t = 0) from every body's current
world state, so every joint coordinate is 0 again, read back and checked like the first, and a
new Simulator goes on from the same time. Engine time and steps are summed over the plants
(the steps must add up to the plan's); the settings record the number of switches, their times
and the joints that triggered them.

Loops. A closing spherical joint is one ``AddBallConstraint`` between the anchors (the world
body for the ground); a closing revolute joint two, at the anchors and at the anchors moved by
the system's length scale along the hinge (six equations for five; SAP's regularised solve
accepts the redundancy); a closing universal joint one at the anchors and an
``AddDistanceConstraint`` (rigid) holding the points one length scale along each axis sqrt 2
length scales apart (the axes perpendicular). Prismatic and cylindrical closures are
unsupported (:data:`REFUSED_CLOSURES`). Drake honours these constraints only in discrete SAP
plants; a continuous-time plant with a loop is ``Unsupported`` with that reason. drake#24957
reports a constraint silently ignored in continuous mode; Drake 1.51.1 does not ignore it but
raises at the first step ("Continuous time does not support constraints", for ball and
distance constraints alike, measured), which the tests show with the refusal bypassed.

Integrators: the single-body adapter's names (``references.engines.drake_engine``): the
fixed-step continuous schemes (``ResetIntegratorFromFlags`` at dt, fixed step mode, read back)
and ``discrete SAP`` (``MultibodyPlant(time_step=dt)``, kSap). Error-controlled runs and
``cenic`` (it needs a SceneGraph diagram) are unsupported for systems.

Read back before stepping: body masses, central inertias and COMs, joint types, parents,
frames (F in the parent, M in the child), revolute axes, damping (0), limits (infinite),
gravity, the numbers of joints, actuators, geometries and constraints, the time stepping; then
Drake's kinematics of the initial state must reproduce every body and every joint's anchor and
axis (from both sides), else :class:`~references.errors.EngineError` names the body or joint.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import math
import time
from dataclasses import dataclass

import numpy as np

from references.engines import reduced, timing
from references.engines.drake import forces
from references.engines.drake.sleeve import sleeve_read_back
from references.engines.native import import_engine
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported
from scenarios.force_elements import has_elements

#: fixed-step continuous schemes (Drake's names) and the discrete plant
CONTINUOUS = (
    "semi_explicit_euler",
    "explicit_euler",
    "runge_kutta2",
    "runge_kutta3",
    "bogacki_shampine3",
    "runge_kutta5",
    "implicit_euler",
    "velocity_implicit_euler",
    "radau1",
    "radau3",
)
DISCRETE = "discrete SAP"
INTEGRATORS = (*CONTINUOUS, DISCRETE)

#: at the end of a step where a ball joint's |cos pitch| is below this, the plant is rebuilt
#: from the bodies' world states (pitch 0 again): the chart's rate map (1 / cos pitch) never
#: amplifies more than 2.5x; the single-body adapter's level (drake_engine.CHART_SWITCH_COS)
CHART_SWITCH_COS = 0.4


#: the tree joints this builder builds (cylindrical through a massless sleeve: module docstring)
TREE_KINDS = (*reduced.SLIDING_KINDS, "universal", "cylindrical")

#: why Drake closes no loop of these kinds
REFUSED_CLOSURES = dict.fromkeys(
    ("prismatic", "cylindrical"),
    "Drake's constraints hold a point (AddBallConstraint), a whole pose (AddWeldConstraint), a "
    "distance (AddDistanceConstraint) or two joints' coordinates (AddCouplerConstraint); none "
    "leaves a relative translation free, and a composition through an extra body on a "
    "PrismaticJoint needs that body's mass, which would change the motion: the body would be a "
    "leaf of the tree (tied to the other side by constraints only), and Drake refuses a "
    "massless leaf on a sliding joint ('An internal mass matrix associated with the joint ... "
    "is not positive-definite', measured on a discrete SAP plant, Drake 1.51.1)",
)


def _import():
    return import_engine("pydrake", "Drake (pydrake)", "drake")


def loops_supported(integrator: str) -> bool:
    """Whether this builder closes loops with ``integrator``: only on the discrete SAP plant
    (module docstring; the tests bypass it to show what a continuous plant does)."""
    return integrator == DISCRETE


@dataclass
class DrakeFrames:
    """What Drake is given for one tree joint: its kind, frame F on the parent (position in
    the parent's principal frame at the COM, world for the ground; rotation), frame M on the
    child (position; identity rotation) and a revolute or prismatic axis (in F and M)."""

    kind: str
    p_F: np.ndarray
    R_F: np.ndarray
    p_M: np.ndarray
    axis: np.ndarray | None
    #: a universal joint's parent axis (in the parent's frame); its F and M frames are
    #: turned from R_F by :func:`universal_frames`
    axis_p: np.ndarray | None = None


def engine_frames(pl: reduced.Plan, c: int) -> DrakeFrames:
    """The builder's boundary: the frames of body c's joint (module docstring). A universal
    joint's frames F and M coincide at t = 0 with F's x axis the parent's axis and its y axis
    the child's (Drake's UniversalJoint turns M about F's x, then about the turned y)."""
    tj = pl.tree[c]
    _, Rp, _, _ = reduced.world(pl, tj.parent)
    _, Rc, _, _ = reduced.world(pl, c)
    Rrel = Rp.T @ Rc
    if tj.kind == "universal":
        return DrakeFrames(tj.kind, tj.X, Rrel, tj.Y, tj.axis_c, axis_p=tj.axis_p)
    return DrakeFrames(tj.kind, tj.X, Rrel, tj.Y, tj.axis_c)


def universal_frames(f: DrakeFrames) -> tuple[np.ndarray, np.ndarray]:
    """(rotation of F in the parent, of M in the child) of a universal joint from its frames
    (R_F the relative rotation at t = 0, ``axis`` the child's axis, ``axis_p`` the parent's):
    F's x axis the parent's axis, its y axis the child's, M = F at t = 0."""
    ex, ey = f.axis_p, f.R_F @ f.axis
    RF = np.column_stack([ex, ey, np.cross(ex, ey)])
    return RF, f.R_F.T @ RF


class _Model:
    """Drake's plant, context, simulator; joints and bodies per scenario body."""

    def __init__(self, pl: reduced.Plan, integrator: str, dt: float, scenario=None):
        from pydrake.math import RigidTransform, RotationMatrix
        from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant
        from pydrake.multibody.tree import (
            BallRpyJoint,
            FixedOffsetFrame,
            PrismaticJoint,
            QuaternionFloatingJoint,
            RevoluteJoint,
            RotationalInertia,
            SpatialInertia,
            UniversalJoint,
        )

        self.pl = pl
        self.discrete = integrator == DISCRETE
        plant = MultibodyPlant(time_step=dt if self.discrete else 0.0)
        if self.discrete:
            plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        self.body, self.joint, self.frames = {}, {}, {}
        #: body of a cylindrical joint -> (the sleeve's PrismaticJoint, the sleeve body)
        self.sleeve: dict = {}
        for c in pl.order:
            b = pl.bodies[c]
            I1, I2, I3 = (float(v) for v in b.inertia)
            M = SpatialInertia.MakeFromCentralInertia(
                float(b.mass), np.zeros(3), RotationalInertia(I1, I2, I3)
            )
            self.body[c] = plant.AddRigidBody(b.name, M)
        for c in pl.order:
            tj = pl.tree[c]
            if tj.kind == "free":  # explicit, with zero damping (read back)
                self.joint[c] = plant.AddJoint(QuaternionFloatingJoint(
                    f"{pl.names[c]}_joint", plant.world_frame(), self.body[c].body_frame(),
                    0.0, 0.0))  # fmt: skip
                continue
            f = engine_frames(pl, c)
            parent = plant.world_body() if tj.parent < 0 else self.body[tj.parent]
            RF, RM = universal_frames(f) if tj.kind == "universal" else (f.R_F, np.eye(3))
            X_F = RigidTransform(RotationMatrix(RF), f.p_F)
            X_M = RigidTransform(RotationMatrix(RM), f.p_M)
            F = plant.AddFrame(FixedOffsetFrame(f"{pl.names[c]}_F", parent.body_frame(), X_F))
            Mf = plant.AddFrame(
                FixedOffsetFrame(f"{pl.names[c]}_M", self.body[c].body_frame(), X_M)
            )
            if tj.kind == "cylindrical":
                m = reduced.COMPOSED_MASS  # Drake's central inertia needs m > 0: Zero() for 0
                Ms = SpatialInertia.Zero()
                if m != 0:
                    Im = RotationalInertia(m, m, m)
                    Ms = SpatialInertia.MakeFromCentralInertia(m, np.zeros(3), Im)
                sleeve = plant.AddRigidBody(reduced.composed_name(pl, tj, "sleeve"), Ms)
                slide = plant.AddJoint(
                    PrismaticJoint(f"{tj.name}_slide", F, sleeve.body_frame(), f.axis, damping=0.0)
                )
                self.sleeve[c] = (slide, sleeve)
                joint = RevoluteJoint(f"{pl.names[c]}_joint", sleeve.body_frame(), Mf, f.axis,
                                      0.0)  # fmt: skip
            elif tj.kind == "spherical":
                joint = BallRpyJoint(f"{pl.names[c]}_joint", F, Mf, 0.0)
            elif tj.kind == "prismatic":
                joint = PrismaticJoint(f"{pl.names[c]}_joint", F, Mf, f.axis)
            elif tj.kind == "universal":
                joint = UniversalJoint(f"{pl.names[c]}_joint", F, Mf, 0.0)
            else:
                joint = RevoluteJoint(f"{pl.names[c]}_joint", F, Mf, f.axis, 0.0)
            self.joint[c] = plant.AddJoint(joint)
            self.frames[c] = f
        plant.mutable_gravity_field().set_gravity_vector(pl.gravity)
        self.loops, self.balls, self.distances = [], [], []
        if pl.loops and loops_supported(integrator):
            for lp in pl.loops:
                B = plant.world_body() if lp.b < 0 else self.body[lp.b]
                for Xa, Xb in lp.pairs:
                    plant.AddBallConstraint(self.body[lp.a], Xa, B, Xb)
                    self.balls.append((self.body[lp.a], Xa, B, Xb))
                for Xa, Xb, dist in lp.distances:  # rigid: infinite stiffness, no damping
                    cid = plant.AddDistanceConstraint(self.body[lp.a], Xa, B, Xb, float(dist))
                    self.distances.append(cid)
                self.loops.append(lp)
        self.springs = [] if scenario is None else forces.add_springs(plant, self.body, pl,
                                                                      scenario)  # fmt: skip
        plant.Finalize()
        self.plant = plant
        self.context = plant.CreateDefaultContext()
        self.clock = 0.0
        self.applied = [] if scenario is None else forces.torque_forces(pl, scenario, self.joint)
        if self.applied:
            forces.fix_torques(plant, self.context, self.applied)

    def set_initial(self) -> None:
        from pydrake.math import RigidTransform, RotationMatrix
        from pydrake.multibody.math import SpatialVelocity

        pl, plant, ctx = self.pl, self.plant, self.context
        for c in pl.order:
            tj = pl.tree[c]
            x, R, v, w = reduced.world(pl, c)
            if tj.kind == "free":
                plant.SetFreeBodyPose(ctx, self.body[c], RigidTransform(RotationMatrix(R), x))
                plant.SetFreeBodySpatialVelocity(ctx, self.body[c], SpatialVelocity(w, v))
                continue
            _, Rp, _, wp = reduced.world(pl, tj.parent)
            joint, f = self.joint[c], self.frames[c]
            if tj.kind == "spherical":
                joint.set_angles(ctx, np.zeros(3))
                joint.set_angular_velocity(ctx, f.R_F.T @ Rp.T @ (w - wp))
            elif tj.kind in ("prismatic", "cylindrical"):
                d0, rate = reduced.slide_state(pl, tj)
                slide = joint if tj.kind == "prismatic" else self.sleeve[c][0]
                slide.set_translation(ctx, d0)
                slide.set_translation_rate(ctx, rate)
                if tj.kind == "cylindrical":  # the body turns in its sleeve from 0
                    joint.set_angle(ctx, 0.0)
                    joint.set_angular_rate(ctx, float(tj.axis_c @ (R.T @ (w - wp))))
            elif tj.kind == "universal":
                # at angles 0 the rates are w_FM in F's x and y (its z part is off the joint:
                # the state check names it)
                joint.set_angles(ctx, np.zeros(2))
                RF = universal_frames(f)[0]
                joint.set_angular_rates(ctx, (RF.T @ Rp.T @ (w - wp))[:2])
            else:
                joint.set_angle(ctx, 0.0)
                joint.set_angular_rate(ctx, float(tj.axis_c @ (R.T @ (w - wp))))

    def states(self):
        x, R, v, W = reduced.state_arrays(len(self.pl.bodies))
        for c, body in self.body.items():
            X = body.EvalPoseInWorld(self.context)
            V = body.EvalSpatialVelocityInWorld(self.context)
            R[c] = X.rotation().matrix()
            x[c] = X.translation()
            v[c] = V.translational()
            W[c] = R[c].T @ V.rotational()
        return x, R, v, W

    def loop_world(self) -> dict:
        """Drake's loop constraints at the current state, in the form of
        :func:`~references.engines.reduced.check_loops`: the ball constraints' points as
        added, each distance constraint's points and distance as Drake holds them
        (``GetDistanceConstraintParams``), placed by Drake's body poses."""
        plant, ctx = self.plant, self.context

        def at(body, p):
            return body.EvalPoseInWorld(ctx).multiply(np.asarray(p, float))

        out, k, n = {}, 0, 0
        for lp in self.loops:
            pairs = [(at(A, pa), at(B, pb)) for A, pa, B, pb in self.balls[k : k + len(lp.pairs)]]
            dists = []
            for cid in self.distances[n : n + len(lp.distances)]:
                par = plant.GetDistanceConstraintParams(ctx, cid)
                A, B = plant.get_body(par.bodyA()), plant.get_body(par.bodyB())
                dists.append((at(A, par.p_AP()), at(B, par.p_BQ()), par.distance()))
                if not (math.isinf(par.stiffness()) and par.damping() == 0):
                    dists[-1] = (*dists[-1][:2], math.nan)  # compliant: not the joint
            out[lp.label] = (pairs, dists)
            k, n = k + len(lp.pairs), n + len(lp.distances)
        return out

    def joint_world(self):
        points, axes = {}, {}
        for c, joint in self.joint.items():
            tj = self.pl.tree[c]
            if tj.kind == "free":
                continue
            X = joint.frame_on_child().CalcPoseInWorld(self.context)
            XF = joint.frame_on_parent().CalcPoseInWorld(self.context)
            points[tj.name] = X.translation()
            if tj.kind in ("revolute", "cylindrical"):
                # a cylindrical joint's: the turn's (the slide's is read back equal to it)
                axes[tj.name] = XF.rotation().matrix() @ joint.revolute_axis()
            if tj.kind == "cylindrical":
                # the child's side (M) moves along the axis; the parent's side is the slide's F
                XF = self.sleeve[c][0].frame_on_parent().CalcPoseInWorld(self.context)
                j = next(j for j in self.pl.joints if j.name == tj.name)
                a_is_child = j.body_a == self.pl.names[c]
                points[tj.name] = {("a" if a_is_child else "b"): X.translation(),
                                   ("b" if a_is_child else "a"): XF.translation()}  # fmt: skip
            if tj.kind == "prismatic":
                # the child's side (M) moves along the axis; the parent's side is F
                j = next(j for j in self.pl.joints if j.name == tj.name)
                a_is_child = j.body_a == self.pl.names[c]
                points[tj.name] = {("a" if a_is_child else "b"): X.translation(),
                                   ("b" if a_is_child else "a"): XF.translation()}  # fmt: skip
                axes[tj.name] = XF.rotation().matrix() @ joint.translation_axis()
        return points, axes


def read_back(dm: _Model, scenario) -> None:
    """Compare Drake's model with the scenario (module docstring)."""
    pl, plant, ctx = dm.pl, dm.plant, dm.context
    bad = reduced.Mismatches()
    want = bad.want

    types = {"spherical": "ball_rpy", "revolute": "revolute", "prismatic": "prismatic",
             "universal": "universal", "free": "quaternion_floating",
             "cylindrical": "revolute"}  # fmt: skip
    for c, body in dm.body.items():
        b, tj = pl.bodies[c], pl.tree[c]
        name = f"body {b.name!r} ({tj.label})"
        M = body.CalcSpatialInertiaInBodyFrame(ctx)
        want(f"{name}: mass", M.get_mass(), b.mass)
        want(f"{name}: COM in the body frame", M.get_com(), np.zeros(3))
        want(f"{name}: central inertia", M.CalcRotationalInertia().CopyToFullMatrix3(),
             np.diag(np.asarray(b.inertia, float)))  # fmt: skip
        joint = dm.joint.get(c)
        if joint is None:
            bad.append(f"{name}: no joint found")
            continue
        if joint.type_name() != types[tj.kind]:
            bad.append(f"{name}: joint {joint.type_name()}, needs {types[tj.kind]}")
            continue
        if joint.child_body().index() != body.index():
            bad.append(f"{name}: the joint's child is {joint.child_body().name()!r}")
        exp_parent = "world" if tj.parent < 0 else pl.names[tj.parent]
        if tj.kind == "cylindrical":
            sleeve_read_back(dm, c, name, bad)
            exp_parent = f"{tj.name}_sleeve"
        got_parent = "world" if joint.parent_body().index() == plant.world_body().index() else (
            joint.parent_body().name())  # fmt: skip
        if got_parent != exp_parent:
            bad.append(f"{name}: parent {got_parent!r}, needs {exp_parent!r}")
        nv = joint.num_velocities()
        want(f"{name}: joint damping", joint.GetDampingVector(ctx), np.zeros(nv))
        lows = (joint.position_lower_limits(), joint.velocity_lower_limits(),
                joint.acceleration_lower_limits())  # fmt: skip
        ups = (joint.position_upper_limits(), joint.velocity_upper_limits(),
               joint.acceleration_upper_limits())  # fmt: skip
        if not (all(np.all(np.isneginf(a)) for a in lows)
                and all(np.all(np.isposinf(a)) for a in ups)):  # fmt: skip
            bad.append(f"{name}: joint limits not infinite")
        if tj.kind == "free":
            continue
        f = dm.frames[c]
        XF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
        XM = joint.frame_on_child().GetFixedPoseInBodyFrame()
        RF, RM = universal_frames(f) if tj.kind == "universal" else (f.R_F, np.eye(3))
        pF = f.p_F
        if tj.kind == "cylindrical":  # the turn's F is the sleeve's body frame
            pF, RF = np.zeros(3), np.eye(3)
        want(f"{name}: frame F position in the parent", XF.translation(), pF)
        want(f"{name}: frame F rotation in the parent", XF.rotation().matrix(), RF)
        want(f"{name}: frame M position in the child", XM.translation(), f.p_M)
        want(f"{name}: frame M rotation in the child", XM.rotation().matrix(), RM)
        if tj.kind in ("revolute", "cylindrical"):
            want(f"{name}: revolute axis", joint.revolute_axis(), f.axis)
        if tj.kind == "prismatic":
            want(f"{name}: prismatic axis", joint.translation_axis(), f.axis)
    want("gravity", plant.gravity_field().gravity_vector(), pl.gravity)
    want("number of joints", plant.num_joints(), len(dm.body) + len(dm.sleeve))
    want("number of actuators", plant.num_actuators(), 0)
    want("number of collision geometries", plant.num_collision_geometries(), 0)
    want("number of constraints", plant.num_constraints(),
         sum(len(lp.pairs) + len(lp.distances) for lp in dm.loops))  # fmt: skip
    forces.read_back(dm, scenario, want, bad)
    bad.raise_any("drake", scenario)


def at_state(pl: reduced.Plan, x, R, v, W) -> reduced.Plan:
    """``pl`` with every body's state replaced by (x, R, v, W) (arrays in scenario order; W in
    body axes): what a chart switch builds from. Anchors, axes and the tree are body-fixed and
    carry over."""
    bodies = [
        dataclasses.replace(b, position=x[c], rotation=R[c], velocity=v[c], omega_body=W[c])
        for c, b in enumerate(pl.bodies)
    ]
    return dataclasses.replace(pl, bodies=bodies)


def assemble(scenario, pl: reduced.Plan, integrator: str, dt: float) -> _Model:
    """The single entry point of every plant of a run: Drake's model of ``pl`` built from its
    bodies' world states (the scenario's at t = 0, the current ones at a chart switch, every
    joint coordinate 0), read back, the state set and checked against Drake's kinematics."""
    dm = _Model(pl, integrator, float(dt), scenario)
    read_back(dm, scenario)
    dm.set_initial()
    x, R, v, W = dm.states()
    points, axes = dm.joint_world()
    reduced.check_states("drake", pl, x, R, v, W, points, axes)
    reduced.check_loops("drake", pl, dm.loop_world())
    return dm


def build(scenario, integrator: str, dt: float, **settings):
    """(_Model, settings record): planned, built, read back, the initial state set and checked
    against Drake's kinematics."""
    if integrator not in INTEGRATORS and integrator.endswith("(error-controlled)"):
        raise Unsupported(
            f"drake: {integrator}: error-controlled runs are not offered for systems (the "
            "suite refuses target accuracies for systems)"
        )
    if integrator == "cenic":
        raise Unsupported(
            "drake: cenic needs a Diagram with a SceneGraph, which this builder does not build"
        )
    reduced.check_run_args(integrator, dt, INTEGRATORS)
    reduced.check_settings("drake", settings)
    _import()
    pl = reduced.plan(scenario, "drake", TREE_KINDS, reduced.DISTANCE_CLOSURES, REFUSED_CLOSURES)
    if pl.loops and not loops_supported(integrator):
        raise Unsupported(
            f"drake: {pl.loops[0].label} closes a loop; Drake's constraints (AddBallConstraint) "
            f"act only in a discrete SAP plant, and {integrator} runs a continuous-time plant "
            "(Drake 1.51 raises there at the first step; drake#24957 reports a constraint "
            "silently ignored in continuous mode): run 'discrete SAP'"
        )
    dm = assemble(scenario, pl, integrator, dt)
    rec = {
        "engine": f"drake {importlib.metadata.version('drake')}",
        "integrator": integrator,
        "plant": "discrete, DiscreteContactApproximation.kSap"
        if dm.discrete
        else "continuous; Simulator with the fixed-step integrator at dt",
        "dt": float(dt),
        "gravity": pl.gravity.tolist(),
        "tree": reduced.tree_record(pl),
        "frames": "body frames principal at the COM; joint frames F (parent, rotation R_p^T R_c "
        "at t = 0 and at every chart switch) and M (child) at the anchors: every joint "
        "coordinate 0 at t = 0 and after every switch",
        "ball joints": "BallRpyJoint; at the end of a step where one has |cos pitch| < "
        f"{CHART_SWITCH_COS:g} the plant is rebuilt from the bodies' world states (every "
        "coordinate 0 again)",
        "joint damping": 0.0,
        "collision": "none (no geometry)",
    }
    if dm.sleeve:
        rec["cylindrical joints"] = [
            f"{pl.tree[c].name}: PrismaticJoint then RevoluteJoint on one axis through the "
            f"massless body '{pl.tree[c].name}_sleeve' (SpatialInertia.Zero())"
            for c in dm.sleeve
        ]
    if has_elements(scenario):
        rec["force elements"] = forces.record(scenario, dm.applied)
    if dm.loops:
        rec["loop closures"] = [
            f"{lp.label}: "
            + (
                "two AddBallConstraint on the hinge axis (6 equations for 5)"
                if lp.kind == "revolute"
                else "AddBallConstraint at the anchors and AddDistanceConstraint (rigid) "
                f"holding the points {pl.length:.6g} m along each axis {pl.length * 2**0.5:.6g}"
                " m apart (the axes perpendicular)"
                if lp.distances
                else "AddBallConstraint"
            )  # fmt: skip
            for lp in dm.loops
        ]
    return dm, rec


@dataclass
class _Stepper:
    """The Simulator of the current plant, its integrator (None for the discrete plant) and
    the fixed steps the replaced plants took."""

    dm: _Model
    sim: object
    integ: object
    steps_before: int = 0
    #: (joint label, time, |cos pitch|) set by the monitor when a step ends below the level
    pending: tuple | None = None

    def steps(self) -> int:
        if self.integ is None:
            n = self.sim.get_num_discrete_updates() + self.sim.get_num_unrestricted_updates()
        else:
            n = self.integ.get_num_steps_taken()
        return self.steps_before + n


def _stepper(dm: _Model, integrator: str, dt: float, t: float, steps_before: int) -> _Stepper:
    """A Simulator on ``dm`` at time ``t`` (fixed step dt, read back) whose monitor ends
    AdvanceTo at the end of a step where a ball joint's |cos pitch| < :data:`CHART_SWITCH_COS`."""
    from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
    from pydrake.systems.framework import EventStatus

    plant = dm.plant
    sim = Simulator(plant, dm.context)
    ctx = sim.get_mutable_context()
    dm.context = ctx
    ctx.SetTime(t)
    integ = None
    if not dm.discrete:
        integ = ResetIntegratorFromFlags(sim, integrator, float(dt))
        integ.set_fixed_step_mode(True)
        if not (integ.get_fixed_step_mode() and integ.get_maximum_step_size() == float(dt)):
            raise EngineError(f"drake: {integrator}: the fixed step {dt:g} s did not take")
    elif not (plant.time_step() == float(dt)):
        raise EngineError(f"drake: the discrete plant's step {plant.time_step()} != {dt}")
    st = _Stepper(dm, sim, integ, steps_before)
    pl = dm.pl
    pitch = [(pl.tree[c].label, dm.joint[c].position_start() + 1)
             for c in pl.order if pl.tree[c].kind == "spherical"]  # fmt: skip

    def monitor(root):
        if pitch:
            q = plant.GetPositions(root)
            for lab, i in pitch:
                c = abs(math.cos(q[i]))
                if c < CHART_SWITCH_COS:
                    st.pending = (lab, root.get_time(), c)
                    return EventStatus.ReachedTermination(plant, "RPY chart switch")
        return EventStatus.Succeeded()

    if pitch:
        sim.set_monitor(monitor)
    sim.Initialize()
    return st


def switch(st: _Stepper, scenario, integrator: str, dt: float) -> _Stepper:
    """Carry the run over to a new plant at the end of the step the monitor stopped: built by
    :func:`assemble` from every body's current world state (ball joints at pitch 0 again), a
    new Simulator at the same time, the old one's steps carried over."""
    old = st.dm
    t = old.context.get_time()
    steps = st.steps()
    st.sim.clear_monitor()  # it holds st: a reference cycle through C++
    try:
        dm = assemble(scenario, at_state(old.pl, *old.states()), integrator, dt)
    except EngineError as exc:
        raise EngineError(f"at the chart switch at t = {t:.6g} s: {exc}") from None
    dm.clock = old.clock
    return _stepper(dm, integrator, dt, t, steps)


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` (module docstring) on Drake.

    ``integrator``: one of :data:`INTEGRATORS`; ``dt`` s; ``nstep`` steps saved at 0, s, 2s,
    ..., nstep; no settings. Returns a SystemResult with ``t, x, R, v, W`` (as
    :func:`references.engines.pinocchio.system.simulate_system`), ``engine_time_s`` (inside
    Simulator.AdvanceTo, summed over the plants of every chart) and ``settings`` (with the
    number and times of the chart switches). Raises :class:`Unsupported` (a loop on a
    continuous plant), :class:`EngineError` (read-back or state mismatch at t = 0 or at a chart
    switch, or Drake's step count off the plan) and :class:`Diverged` (a failed step or a
    non-finite state).
    """
    steps = reduced.saves(nstep, save_every)
    dm, rec = build(scenario, integrator, dt, **settings)
    st = _stepper(dm, integrator, dt, 0.0, 0)
    nb, n = len(dm.pl.bodies), len(steps)
    x, R, v, W = reduced.state_arrays(n, nb)
    x[0], R[0], v[0], W[0] = dm.states()
    switches: list = []
    t = 0.0
    timing.stepping()  # the model is built: its construction is not the cost
    for k in range(1, n):
        if dm.discrete:  # periodic updates fall at n * dt (Drake's event times)
            t = float(steps[k]) * float(dt)
        else:
            for _ in range(int(steps[k] - steps[k - 1])):
                t += float(dt)  # the Simulator's own running sum (drake_engine's docstring)
        while True:
            t0 = time.perf_counter()
            try:
                st.sim.AdvanceTo(t)
            except RuntimeError as exc:
                raise Diverged(
                    f"drake {integrator} at dt = {dt:g} s: a step failed between t = "
                    f"{steps[k - 1] * dt:.6g} and {steps[k] * dt:.6g} s: {str(exc)[:300]}",
                    steps[k - 1] * dt,
                    reduced.output(steps[:k], dt, x[:k], R[:k], v[:k], W[:k], st.dm.clock, rec),
                ) from None
            st.dm.clock += timing.lap(t0)
            if st.pending is None:
                break
            lab, th, cs = st.pending
            switches.append((th, lab, cs))
            st = switch(st, scenario, integrator, dt)
            if st.dm.context.get_time() >= t:  # the switch came at the end of the last step
                break
        x[k], R[k], v[k], W[k] = st.dm.states()
        if not (np.all(np.isfinite(x[k])) and np.all(np.isfinite(W[k]))):
            raise Diverged(
                f"drake {integrator} at dt = {dt:g} s: a non-finite state at t = "
                f"{steps[k] * dt:.6g} s",
                steps[k] * dt,
                reduced.output(steps[:k], dt, x[:k], R[:k], v[:k], W[:k], st.dm.clock, rec),
            )
    if st.steps() != int(steps[-1]):
        raise EngineError(
            f"drake {integrator}: Drake took {st.steps()} steps where the plan had "
            f"{int(steps[-1])} of {dt!r} s over {len(switches) + 1} plant(s); the time "
            "bookkeeping of the builder is wrong"
        )
    rec["RPY chart switches"] = len(switches)
    rec["RPY chart switch times s"] = [th for th, _, _ in switches]
    rec["RPY chart switch joints"] = [lab for _, lab, _ in switches]
    st.sim.clear_monitor()
    clock = st.dm.clock if math.isfinite(st.dm.clock) else 0.0
    return reduced.output(steps, dt, x, R, v, W, clock, rec)
