"""DART (dartpy) builder for systems of rigid bodies: one Skeleton in DART's reduced coordinates,
loops closed by DART's own joint constraints inside ``World.step``.

Input: a system scenario (the contract's ``name, gravity, bodies, joints``); the spanning tree,
the reference orientations and the frames are the kit's :func:`~references.engines.reduced.plan`
and :func:`~references.engines.reduced.engine_frames` (one definition for Pinocchio too):
every DART body frame sits at its joint point, parallel to the body's principal frame, with the
local COM at -Y (``setLocalCOM``) and ``Inertia(m, -Y, diag(I))`` (moments about the COM); the
joint's transform from the parent body node is (R_ref, X - Y_p) and from the child body node the
identity.

==================  ========================  ===========================================
scenario kind       DART joint                positions and velocities at t = 0
==================  ========================  ===========================================
spherical,          ``BallJoint``             rotation vector of R_p^T R_c; velocities
fixed_point                                   W_c - R_rel^T W_p (child axes)
revolute            ``RevoluteJoint`` (axis   0; n . (W_c - R_rel^T W_p)
                    = the child's axis)
prismatic           ``PrismaticJoint`` (axis  the anchors' offset along the axis; its rate
                    = the child's axis)       (:func:`~references.engines.reduced.slide_state`)
universal           ``UniversalJoint`` (axis1 (0, 0); the relative rate on the two axes
                    R_ref^T u_p, axis2 u_c)
cylindrical         ``PrismaticJoint`` to a   the slide as a prismatic joint's; the turn 0,
                    massless sleeve body      n . (W_c - R_rel^T W_p)
                    node, ``RevoluteJoint``
                    from it (both on u_c)
(floating root)     ``FreeJoint``             [rotation vector, x]; [w WORLD, v WORLD]
others              -                         unsupported (not built by this adapter)
==================  ========================  ===========================================

Cylindrical joints: DART has none; the builder writes the composition: a massless body node,
the joint's *sleeve* (named ``<joint>_sleeve``: mass 0, moments 0, no shape), on a
``PrismaticJoint`` from the parent at the joint's placement along the child's axis, and the
body on a ``RevoluteJoint`` from the sleeve about the same axis at the sleeve's origin (the
slide and the turn about one line commute). DART accepts the zero mass and moments with
warnings (a zero mass "can cause invalid physical behavior or segfault", an "invalid moment
of inertia matrix", each zero moment "should be positive"); a sleeve is never a leaf (the body
hangs from it), so its articulated inertia is the body's and DART's dynamics stay regular:
the runs agree with the loop reference (tests/references/engines/test_system_cylindrical.py).
The builder captures those warnings (:data:`SLEEVE_WARNINGS`), refuses any other, and records
them. Read back: the sleeve's mass, moments, joint type, parent, axis and transforms, and the
body's joint from the sleeve.

Loop closures (``World.step`` only; DART's constraint solver is not part of
``computeForwardDynamics``): a closing spherical joint is a ``BallJointConstraint``, a closing
revolute joint a ``RevoluteJointConstraint``, a closing cylindrical joint a
``CylindricalJointConstraint`` (each created at the initial configuration from one world point,
body a's anchor, which DART ties to both bodies, and the world axes; a cylindrical's anchors
may stand apart along the axis, so b is tied at the point of its line that meets a's anchor).
DART solves them as velocity-level impulses (a boxed LCP) with a position correction set by its
global error reduction parameter (ERP), error allowance, maximum error-reduction velocity and
constraint force mixing: read back and recorded, DART's defaults unless ``erp`` is given.
*Measured*: DART's cylindrical constraint does not hold its line once the joint slides (its
velocity rows tie the bodies at the initial anchor point; the kit's loop drifts 0.30 m off the
line over a 0.67 m slide, tests/references/engines/test_system_closures.py): its runs fail on
the joint gap, a verdict on DART's constraint. A closure under RKMK4 is unsupported (the
constraint would be ignored by ``computeForwardDynamics``), as is any other closing kind.

Integrators: ``semi-implicit Euler`` is ``World.step`` (DART's only stepper); ``RKMK4`` is the
suite's Runge-Kutta-Munthe-Kaas of order 4 (:mod:`references.engines.liegroup`) on the product
of each joint's group (SO(3) for a ball joint, R for a hinge, SO(3) x R^3 for a free root with
body-axes W and world v_G), accelerations from ``Skeleton.computeForwardDynamics``; its stages
compiled (:mod:`references.engines._rkmk4_tree`, rotations as quaternions), the skeleton's
positions and velocities set in one call each.

Neutralised and read back: deactivation (sleeping) off, joint damping, spring stiffness, Coulomb
friction 0, limit enforcement off, no shape nodes (nothing collides), gravity set (DART's default
is (0, 0, -9.81)), every body subject to gravity. The initial world state must come back from
DART's kinematics for every body and every joint (anchors and axes from both sides), else
:class:`~references.errors.EngineError` names the body or joint.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
import time
from contextlib import contextmanager

import numpy as np

from references import conventions as cv
from references.engines import _rkmk4, reduced, timing
from references.engines import _rkmk4_tree as _tree
from references.engines.dart import forces
from references.engines.dart.sleeve import Cylinder, sleeve_read_back
from references.engines.liegroup import StageRotationTooLarge, check_engine_vector, direct
from references.engines.native import import_engine
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported
from scenarios.force_elements import has_elements

INTEGRATORS = ("semi-implicit Euler", "RKMK4")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: how a closing revolute joint is expressed: DART's RevoluteJointConstraint (5 equations), or
#: a BallJointConstraint at the anchor ("ball": 3 of the hinge's 5 equations; enough for a
#: planar loop whose tree hinges are parallel, recorded as such, never chosen silently)
REVOLUTE_CLOSURES = ("revolute", "ball")

#: the tree joints this builder builds (cylindrical through a massless sleeve: module
#: docstring)
TREE_KINDS = (*reduced.SLIDING_KINDS, "universal", "cylindrical")
#: DART's default error reduction parameter of its dynamic joint constraints (DART 6.20
#: DynamicJointConstraint; read back in the tests from a fresh World)
#: why DART closes no loop of these kinds (dartpy 6.20's joint constraints:
#: BallJointConstraint, RevoluteJointConstraint, WeldJointConstraint,
#: CylindricalJointConstraint)
REFUSED_CLOSURES = {
    "universal": "DART's joint constraints are ball (3 equations), revolute (5), cylindrical "
    "(4: two rotations and two translations) and weld (6); a universal closure holds a point "
    "and the axes' right angle (4), and DART has no universal, distance or axis constraint",
    "prismatic": "DART's joint constraints are ball, revolute, cylindrical and weld; a "
    "prismatic closure (the rotation held, one translation free) is none of them, and a "
    "cylindrical constraint leaves the rotation about the axis free",
}
#: the closures this builder makes (DART's ball, revolute and cylindrical joint constraints)
CLOSURES = (*reduced.POINT_CLOSURES, "cylindrical")

DEFAULT_ERP = 0.01


def _import():
    return import_engine("dartpy", "DART (dartpy)", "dartpy")


@contextmanager
def dart_warnings(tmp=None):
    """Collect what DART writes to the process's stderr (file descriptor 2) inside the block
    into the yielded list (one string): DART reports a non-finite state there and replaces it
    by zeros or identities ("to avoid instability"), so positions can stay finite and wrong.
    ``tmp``: a binary temporary file to capture into, emptied after it is read (one file for
    a run's blocks instead of one created per block); by default one of its own."""
    if tmp is None:
        with tempfile.TemporaryFile() as own, dart_warnings(own) as box:
            yield box
        return
    box: list[str] = []
    saved = os.dup(2)
    os.dup2(tmp.fileno(), 2)
    try:
        yield box
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        tmp.seek(0)
        box.append(tmp.read().decode(errors="replace"))
        tmp.seek(0)
        tmp.truncate()


def engine_frames(pl: reduced.Plan, c: int) -> reduced.EngineFrames:
    """The builder's boundary: what DART is given for body c's joint (module docstring)."""
    return reduced.engine_frames(pl, c)


def _iso(dart, R, p):
    T = dart.math.Isometry3()
    T.set_rotation(np.asarray(R, float))
    T.set_translation(np.asarray(p, float))
    return T


class _Model:
    """DART's world, skeleton, joints and bodies (scenario order), and the loop constraints."""

    def __init__(self, dart, pl: reduced.Plan, dt: float):
        self.dart, self.pl = dart, pl
        world = dart.simulation.World()
        world.setGravity(pl.gravity)
        world.setTimeStep(dt)
        opts = world.getDeactivationOptions()
        opts.mEnabled = False
        world.setDeactivationOptions(opts)
        skel = dart.dynamics.Skeleton(str(pl.name))
        self.joint, self.body, self.frames = {}, {}, {}
        #: body of a cylindrical joint -> (the sleeve's PrismaticJoint, the sleeve body node)
        self.sleeve: dict = {}
        #: what DART printed while the model was built (module docstring: SLEEVE_WARNINGS)
        self.build_warnings: list[str] = []
        create = {
            "free": skel.createFreeJointAndBodyNodePair,
            "spherical": skel.createBallJointAndBodyNodePair,
            "revolute": skel.createRevoluteJointAndBodyNodePair,
            "prismatic": skel.createPrismaticJointAndBodyNodePair,
            "universal": skel.createUniversalJointAndBodyNodePair,
        }
        for c in pl.order:
            f = engine_frames(pl, c)
            tj = pl.tree[c]
            parent = () if tj.parent < 0 else (self.body[tj.parent],)
            if f.kind == "cylindrical":
                sj, sleeve = skel.createPrismaticJointAndBodyNodePair(*parent)
                sj.setName(f"{tj.name}_slide")
                sleeve.setName(reduced.composed_name(pl, tj, "sleeve"))
                sj.setTransformFromParentBodyNode(_iso(dart, f.R, f.p))
                sj.setTransformFromChildBodyNode(_iso(dart, np.eye(3), np.zeros(3)))
                sj.setAxis(f.axis)
                with dart_warnings() as said:
                    m = reduced.COMPOSED_MASS
                    sleeve.setInertia(dart.dynamics.Inertia(m, np.zeros(3), m * np.eye(3)))
                self.build_warnings += [_ANSI.sub("", ln).strip() for ln in said[0].splitlines()
                                        if ln.strip()]  # fmt: skip
                self._neutral(sj)
                self.sleeve[c] = (sj, sleeve)
                joint, body = create["revolute"](sleeve)
                place = (np.eye(3), np.zeros(3))  # the body turns in its sleeve
            else:
                joint, body = create[f.kind](*parent)
                place = (f.R, f.p)
            joint.setName(f"{pl.names[c]}_joint")
            body.setName(pl.names[c])
            joint.setTransformFromParentBodyNode(_iso(dart, *place))
            joint.setTransformFromChildBodyNode(_iso(dart, np.eye(3), np.zeros(3)))
            if f.kind in ("revolute", "prismatic", "cylindrical"):
                joint.setAxis(f.axis)
            elif f.kind == "universal":
                # about the parent's axis (R_ref^T u_p in the joint frame), then the child's:
                # R_p^T R_c = Rot(u_p, q1) R_ref Rot(u_c, q2), as Pinocchio's
                joint.setAxis1(tj.R_ref.T @ tj.axis_p)
                joint.setAxis2(f.axis)
            b = pl.bodies[c]
            moments = np.diag(np.asarray(b.inertia, float))
            body.setInertia(dart.dynamics.Inertia(float(b.mass), f.body_offset, moments))
            self._neutral(joint)
            self.joint[c], self.body[c], self.frames[c] = joint, body, f
        world.addSkeleton(skel)
        self.world, self.skel = world, skel
        self.constraints = []
        self.handed: dict = {}  # closure label -> what DART is handed (add_loops)
        self.clock = 0.0
        self.loads = None  # the scenario, when it has force elements (forces.py)
        # per tree joint (tree order), for the RKMK4: (body index, kind, its slice of u, the
        # DART joint, the index of its first degree of freedom in the skeleton); a cylindrical
        # joint's two (slide, turn) as one, the sleeve's degree of freedom first (read back)
        self.blocks, k = [], 0
        sizes = {"free": 6, "spherical": 3, "revolute": 1, "prismatic": 1, "universal": 2,
                 "cylindrical": 2}  # fmt: skip
        for c in pl.order:
            kind = pl.tree[c].kind
            n = sizes[kind]
            joint = self.joint[c]
            if c in self.sleeve:
                joint = Cylinder(self.sleeve[c][0], joint)
            first = joint.slide if kind == "cylindrical" else joint
            self.blocks.append((c, kind, slice(k, k + n), joint, first.getIndexInSkeleton(0)))
            k += n
        # the rotational slices of u (ball joints and free roots), where dexpinv acts
        self.rot_slices = [
            slice(b[2].start, b[2].start + 3) for b in self.blocks if b[1] in ("free", "spherical")
        ]

    @staticmethod
    def _neutral(joint) -> None:
        """No damping, spring, friction or limits on ``joint`` (read back)."""
        for i in range(joint.getNumDofs()):
            joint.setDampingCoefficient(i, 0.0)
            joint.setSpringStiffness(i, 0.0)
            joint.setCoulombFriction(i, 0.0)
        joint.setLimitEnforcement(False)

    # -- initial state -----------------------------------------------------------------------
    def set_initial(self) -> None:
        pl = self.pl
        for c in pl.order:
            tj, joint = pl.tree[c], self.joint[c]
            x, R, vG, w = reduced.world(pl, c)
            if tj.kind == "free":
                pos, vel = cv.dart_free_from_state(x, vG, R, R.T @ w)
            elif tj.kind == "spherical":
                pos, vel = cv.dart_ball_from_state(*reduced.relative_state(pl, tj))
            elif tj.kind == "prismatic":
                d0, rate = reduced.slide_state(pl, tj)
                pos, vel = [d0], [rate]
            elif tj.kind == "cylindrical":
                # the sleeve slides as a prismatic joint; the body turns in it from 0
                d0, rate = reduced.slide_state(pl, tj)
                self.sleeve[c][0].setPositions(np.array([d0]))
                self.sleeve[c][0].setVelocities(np.array([rate]))
                pos, vel = [0.0], [float(tj.axis_c @ reduced.relative_state(pl, tj)[1])]
            elif tj.kind == "universal":
                # at (0, 0) the relative rate is q1' a1 + q2' a2 (least squares: the state
                # check catches a rate off the two axes)
                axes = np.column_stack([joint.getAxis1(), joint.getAxis2()])
                Wrel = reduced.relative_state(pl, tj)[1]
                pos, vel = [0.0, 0.0], list(np.linalg.lstsq(axes, Wrel, rcond=None)[0])
            else:
                pos, vel = [0.0], [float(tj.axis_c @ reduced.relative_state(pl, tj)[1])]
            joint.setPositions(np.asarray(pos, float))
            joint.setVelocities(np.asarray(vel, float))

    def add_loops(self, erp, revolute_closure: str) -> None:
        """DART's joint constraints for the closures, at the initial configuration."""
        dart, pl = self.dart, self.pl
        C = dart.constraint
        # a global of DART's process: set on every build (DART's default unless given)
        C.DynamicJointConstraint.setErrorReductionParameter(float(erp))
        for lp in pl.loops:
            xa, Ra, _, _ = reduced.world(pl, lp.a)
            Xa = lp.pairs[0][0]
            point = xa + Ra @ Xa
            ba = self.body[lp.a]
            # what DART is handed, in the world (it ties the one point to both bodies): the
            # form of reduced.check_loops; a ball-only revolute closure leaves its axis out
            handed = [(point, point)]
            if lp.kind in ("revolute", "cylindrical"):
                handed.append(None)
            hinge = lp.kind == "revolute" and revolute_closure == "revolute"
            if lp.kind == "cylindrical" or hinge:
                Con = (C.CylindricalJointConstraint if lp.kind == "cylindrical"
                       else C.RevoluteJointConstraint)  # fmt: skip
                na = Ra @ (lp.pairs[1][0] - Xa) / pl.length
                if lp.b < 0:
                    nb = lp.pairs[1][1] - lp.pairs[0][1]
                    con = Con(ba, point, na)
                else:
                    _, Rb, _, _ = reduced.world(pl, lp.b)
                    nb = Rb @ (lp.pairs[1][1] - lp.pairs[0][1]) / pl.length
                    con = Con(ba, self.body[lp.b], point, na, nb)
                L = pl.length
                handed[1] = (point + L * na, point + L * nb / np.linalg.norm(nb))
            elif lp.b < 0:
                con = C.BallJointConstraint(ba, point)
            else:
                con = C.BallJointConstraint(ba, self.body[lp.b], point)
            self.world.getConstraintSolver().addConstraint(con)
            self.constraints.append((lp, con))
            self.handed[lp.label] = (handed, [])

    # -- read-out ----------------------------------------------------------------------------
    def states(self):
        """(x, R, v, W) per body (scenario order) from DART's kinematics."""
        x, R, v, W = reduced.state_arrays(len(self.pl.bodies))
        for c, body in self.body.items():
            Rc = body.getWorldTransform().rotation()
            R[c] = Rc
            x[c] = body.getCOM()
            v[c] = body.getCOMLinearVelocity()
            W[c] = Rc.T @ body.getAngularVelocity()
        return x, R, v, W

    def joint_world(self):
        """World joint points and hinge axes of the tree joints (by scenario joint name)."""
        points, axes = {}, {}
        for c, joint in self.joint.items():
            tj = self.pl.tree[c]
            if tj.kind == "free":
                continue
            T = self.body[c].getWorldTransform().multiply(joint.getTransformFromChildBodyNode())
            points[tj.name] = T.translation()
            if tj.kind in ("revolute", "cylindrical"):
                # a cylindrical joint's: the turn's (the slide's is read back equal to it)
                axes[tj.name] = T.rotation() @ joint.getAxis()
            if tj.kind in ("prismatic", "cylindrical"):
                # the child's side moves along the axis; the parent's is the joint placement
                # (a cylindrical joint's: the sleeve's slide)
                placed = joint if tj.kind == "prismatic" else self.sleeve[c][0]
                parent = placed.getParentBodyNode()
                P = placed.getTransformFromParentBodyNode()
                fixed = P if parent is None else parent.getWorldTransform().multiply(P)
                j = next(j for j in self.pl.joints if j.name == tj.name)
                a_is_child = j.body_a == self.pl.names[c]
                points[tj.name] = {("a" if a_is_child else "b"): T.translation(),
                                   ("b" if a_is_child else "a"): fixed.translation()}  # fmt: skip
                axes[tj.name] = T.rotation() @ joint.getAxis()
        return points, axes

    # -- RKMK4 on the product of the joints' groups (trees) ------------------------------------
    def staged(self) -> _Staged:
        """The compiled RKMK4 (:mod:`references.engines._rkmk4_tree`) on this tree, from
        DART's state now."""
        return _Staged(self)


class _Staged:
    """The suite's RKMK4 on a tree's product group, its stages compiled
    (:mod:`references.engines._rkmk4_tree`): per stage one compiled call (the previous
    stage's accelerations unpacked, this stage's state packed into DART's positions and
    velocities) and DART's calls, timed alone (the skeleton's setters, computeForwardDynamics,
    getAccelerations); the force elements, when there are any, applied between the setters
    and the dynamics (forces.py), not timed."""

    def __init__(self, dm: _Model):
        _tree.warm_up()
        kinds = {"free": _tree.FREE, "spherical": _tree.BALL}
        rows, y, u, yo = [], [], [], 0
        for _, kind, s, j, idx in dm.blocks:
            p, v = np.asarray(j.getPositions(), float), np.asarray(j.getVelocities(), float)
            code = kinds.get(kind, _tree.VECTOR)
            rows.append((code, yo, s.start, s.stop - s.start, idx))
            if code == _tree.VECTOR:
                y.append(p)
                u.append(v)
            else:
                q = np.zeros(4)
                _tree.quat_of_rotvec(p[:3], q)
                y.append(q if code == _tree.BALL else np.concatenate([q, p[3:]]))
                if code == _tree.FREE:  # DART's world angular velocity -> body axes
                    W = np.zeros(3)
                    _rkmk4.rotate(q, v[:3], W, _rkmk4.INVERSE)
                    v = np.concatenate([W, v[3:]])
                u.append(v)
            yo += len(y[-1])
        self.J = np.array(rows, dtype=np.int64)
        self.y, self.u = np.concatenate(y), np.concatenate(u)
        nu = len(self.u)
        if dm.skel.getNumDofs() != nu:
            raise EngineError(f"dart: the RKMK4's blocks hold {nu} degrees of freedom, the "
                              f"skeleton {dm.skel.getNumDofs()}")  # fmt: skip
        self.zy, self.zu, self.K = self.y.copy(), self.u.copy(), np.zeros((4, 2 * nu))
        self.pos, self.vel = np.zeros(nu), np.zeros(nu)
        self.dm = dm
        self.call, self.checked = self.engine_call(), False

    def engine_call(self):
        """``call()``: DART's accelerations at the state packed in (pos, vel)."""
        dm, pos, vel = self.dm, self.pos, self.vel
        skel, now, lap = dm.skel, time.perf_counter, timing.lap
        set_pos, set_vel = skel.setPositions, skel.setVelocities
        compute, accelerations = skel.computeForwardDynamics, skel.getAccelerations

        def call():
            t0 = now()
            set_pos(pos)
            set_vel(vel)
            if dm.loads is not None:  # the force elements at this stage (forces.py), not timed
                dm.clock += lap(t0)
                forces.apply(dm, dm.loads)
                t0 = now()
            compute()
            a = accelerations()
            dm.clock += lap(t0)
            return a

        return call

    def steps(self, m: int, h: float) -> None:
        """m steps of size h; then DART holds the state reached."""
        # the compiled entries without numba's type dispatch: every array is ours but DART's
        # accelerations, checked on the first (dartpy's binding fixes their layout)
        stage, finish = direct(_tree.stage), direct(_tree.finish)
        J, y, u, zy, zu, K, pos, vel = (self.J, self.y, self.u, self.zy, self.zu, self.K,
                                        self.pos, self.vel)  # fmt: skip
        call = self.call
        for _ in range(m):
            stage(0, J, y, u, zy, zu, K, h, pos, pos, vel)  # stage 0 unpacks nothing
            a = call()
            if not self.checked:
                check_engine_vector(a, len(u), "DART's getAccelerations")
                self.checked = True
            for i in (1, 2, 3):
                if stage(i, J, y, u, zy, zu, K, h, a, pos, vel):
                    raise StageRotationTooLarge(
                        "a Runge-Kutta stage rotation of half a turn or more (>= pi, or not finite)"
                    )
                a = call()
            finish(J, y, u, zy, K, h, a)
        _tree.pack(J, y, u, pos, vel)
        self.dm.skel.setPositions(pos)
        self.dm.skel.setVelocities(vel)


def read_back(dm: _Model, scenario, dt: float) -> None:
    """Compare DART's model with the scenario (module docstring)."""
    pl, world, skel = dm.pl, dm.world, dm.skel
    bad = reduced.Mismatches()
    want = bad.want

    kinds = {"free": "FreeJoint", "spherical": "BallJoint", "revolute": "RevoluteJoint",
             "prismatic": "PrismaticJoint", "universal": "UniversalJoint",
             "cylindrical": "RevoluteJoint"}  # fmt: skip
    want("number of bodies", skel.getNumBodyNodes(), len(pl.bodies) + len(dm.sleeve))
    for c, body in dm.body.items():
        b, tj, joint = pl.bodies[c], pl.tree[c], dm.joint[c]
        name = f"body {b.name!r} ({tj.label})"
        if joint.getType() != kinds[tj.kind]:
            bad.append(f"{name}: joint {joint.getType()}, needs {kinds[tj.kind]}")
        parent = body.getParentBodyNode()
        got_parent = "ground" if parent is None else parent.getName()
        exp_parent = "ground" if tj.parent < 0 else pl.names[tj.parent]
        if tj.kind == "cylindrical":
            sleeve_read_back(dm, c, name, bad)
            exp_parent = f"{tj.name}_sleeve"
        if got_parent != exp_parent:
            bad.append(f"{name}: parent {got_parent!r}, needs {exp_parent!r}")
        inr = body.getInertia()
        want(f"{name}: mass", inr.getMass(), b.mass)
        want(f"{name}: moments about the COM", inr.getMoment(), np.diag(np.asarray(b.inertia)))
        want(f"{name}: local COM", body.getLocalCOM(), -tj.Y)
        want(f"{name}: transform to the child body", joint.getTransformFromChildBodyNode().matrix(),
             np.eye(4))  # fmt: skip
        n = joint.getNumDofs()
        for what, get in (("damping", joint.getDampingCoefficient),
                          ("spring stiffness", joint.getSpringStiffness),
                          ("Coulomb friction", joint.getCoulombFriction)):  # fmt: skip
            want(f"{name}: joint {what}", [get(i) for i in range(n)], [0.0] * n)
        if joint.areLimitsEnforced():
            bad.append(f"{name}: joint limits enforced")
        if not body.getGravityMode():
            bad.append(f"{name}: not subject to gravity")
    want("gravity (world)", world.getGravity(), pl.gravity)
    want("gravity (skeleton)", skel.getGravity(), pl.gravity)
    want("time step", world.getTimeStep(), dt)
    want("number of shape nodes", skel.getNumShapeNodes(), 0)
    if world.getDeactivationOptions().mEnabled:
        bad.append("deactivation (sleeping) enabled")
    if not skel.isMobile():
        bad.append("skeleton not mobile")
    bad.raise_any("dart", scenario)


def _constraint_record(dm: _Model) -> dict:
    C = dm.dart.constraint.DynamicJointConstraint
    return {
        "error reduction parameter (ERP)": float(C.getErrorReductionParameter()),
        "error allowance (m)": float(C.getErrorAllowance()),
        "max error reduction velocity (m/s)": float(C.getMaxErrorReductionVelocity()),
        "constraint force mixing": float(C.getConstraintForceMixing()),
        "LCP solver": type(dm.world.getConstraintSolver().getBoxedLcpSolver()).__name__,
        "split impulse": bool(dm.world.getConstraintSolver().isSplitImpulseEnabled()),
    }


def build(scenario, integrator: str, dt: float, **settings):
    """(_Model, settings record) of ``scenario``: planned, built, read back, the initial state
    set and checked against DART's kinematics, the loops closed."""
    reduced.check_run_args(integrator, dt, INTEGRATORS)
    reduced.check_settings("dart", settings)
    erp = settings.get("erp")
    if erp is not None and not (isinstance(erp, (int, float)) and 0 <= erp <= 1):
        raise ValueError(f"erp {erp!r}: DART's error reduction parameter, a number in [0, 1]")
    closure = settings.get("revolute_closure", "revolute")
    if closure not in REVOLUTE_CLOSURES:
        raise ValueError(f"revolute_closure {closure!r}: one of {list(REVOLUTE_CLOSURES)}")
    dart = _import()
    pl = reduced.plan(scenario, "dart", TREE_KINDS, CLOSURES, refused=REFUSED_CLOSURES)
    if pl.loops and integrator == "RKMK4":
        raise Unsupported(
            f"dart: {pl.loops[0].label} closes a loop; DART closes loops only inside "
            "World.step (its constraint solver), which the suite's RKMK4 around "
            "computeForwardDynamics does not call"
        )
    dm = _Model(dart, pl, float(dt))
    read_back(dm, scenario, float(dt))
    dm.set_initial()
    x, R, v, W = dm.states()
    points, axes = dm.joint_world()
    reduced.check_states("dart", pl, x, R, v, W, points, axes)
    dm.add_loops(DEFAULT_ERP if erp is None else erp, closure)
    reduced.check_loops("dart", pl, dm.handed)
    if has_elements(scenario):
        forces.check(dm, scenario)
        dm.loads = scenario
    rec = {
        "engine": f"dart {dart.__version__}",
        "integrator": integrator,
        "stepping": "World.step"
        if integrator != "RKMK4"
        else "the suite's RKMK4 around Skeleton.computeForwardDynamics (World.step not used)",
        "dt": float(dt),
        "gravity": pl.gravity.tolist(),
        "tree": reduced.tree_record(pl),
        "frames": "each body frame at its joint point, parallel to its principal frame "
        "(local COM -Y)",
        **(
            {
                "cylindrical joints": [
                    f"{pl.tree[c].name}: PrismaticJoint then RevoluteJoint on one axis through the "
                    f"massless body node '{pl.tree[c].name}_sleeve' (mass 0, moments 0; DART's "
                    "warnings about them captured)"
                    for c in dm.sleeve
                ]
            }
            if dm.sleeve
            else {}
        ),  # fmt: skip
        "deactivation (sleeping)": False,
        "joint damping, spring stiffness, Coulomb friction": 0.0,
        "joint limit enforcement": False,
        "collision": "none (no shape nodes)",
    }
    if dm.loads is not None:
        rec["force elements"] = forces.record(scenario, integrator)
    if dm.constraints:
        rec["loop closures"] = [
            f"{lp.label}: "
            + (
                "CylindricalJointConstraint"
                if lp.kind == "cylindrical"
                else "RevoluteJointConstraint"
                if lp.kind == "revolute" and closure == "revolute"
                else "BallJointConstraint"
                + (" at the anchor (3 of the hinge's 5 equations)" if lp.kind == "revolute" else "")
            )
            for lp, _ in dm.constraints
        ]
        rec["constraint solver"] = _constraint_record(dm)
        rec["ERP"] = "given" if erp is not None else "DART's default"
    return dm, rec


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` (module docstring) on DART.

    ``integrator``: "semi-implicit Euler" (World.step) or "RKMK4" (trees only); ``dt`` s;
    ``nstep`` steps saved at 0, s, 2s, ..., nstep; ``settings``: ``erp`` (DART's error reduction
    parameter of its joint constraints, a global of DART; default: DART's own).

    Returns a :class:`~references.engines.system.SystemResult` with ``t, x, R, v, W`` (as
    :func:`references.engines.pinocchio.system.simulate_system`), ``engine_time_s`` (inside
    World.step, or, for RKMK4, inside the skeleton's state setters, computeForwardDynamics and
    getAccelerations, not the conversions to and from DART's coordinates) and ``settings``.
    Raises :class:`Unsupported`, :class:`EngineError` (read-back or initial-state mismatch) and
    :class:`Diverged` (non-finite state, or one DART replaced)."""
    steps = reduced.saves(nstep, save_every)
    dm, rec = build(scenario, integrator, dt, **settings)
    nb, n = len(dm.pl.bodies), len(steps)
    x, R, v, W = reduced.state_arrays(n, nb)
    x[0], R[0], v[0], W[0] = dm.states()
    rk = dm.staged() if integrator == "RKMK4" else None
    world, skel = dm.world, dm.skel
    done = 0
    h = float(dt)
    with tempfile.TemporaryFile() as capture:
        timing.stepping()  # the model is built: its construction is not the cost
        for k in range(1, n):
            m = int(steps[k] - done)
            with dart_warnings(capture) as said:
                if rk is not None:
                    rk.steps(m, h)
                elif dm.loads is not None:  # set before each step (forces.py), not timed
                    for _ in range(m):
                        forces.apply(dm, dm.loads)
                        t0 = time.perf_counter()
                        world.step()
                        dm.clock += timing.lap(t0)
                else:
                    t0 = time.perf_counter()
                    for _ in range(m):
                        world.step()
                    dm.clock += timing.lap(t0)
            done = int(steps[k])
            pos, vel = skel.getPositions(), skel.getVelocities()
            patched = [
                _ANSI.sub("", ln).strip() for ln in said[0].splitlines() if "Non-finite" in ln
            ]
            if patched or not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
                why = f"DART replaced a non-finite quantity ({patched[0]})" if patched else (
                    "a non-finite state")  # fmt: skip
                raise Diverged(
                    f"dart {integrator} at dt = {dt:g} s: {why} between t = "
                    f"{steps[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt"
                    + (", or the constraints' ERP)" if dm.constraints else ")"),
                    done * dt,
                    reduced.output(steps[:k], dt, x[:k], R[:k], v[:k], W[:k], dm.clock, rec),
                )
            x[k], R[k], v[k], W[k] = dm.states()
    if not math.isfinite(dm.clock):
        dm.clock = 0.0
    return reduced.output(steps, dt, x, R, v, W, dm.clock, rec)
