"""PyBullet builder for systems of rigid bodies: btMultiBody trees in Bullet's reduced
(Featherstone) coordinates, loops closed by ``createConstraint(JOINT_POINT2POINT)``.

Input: a system scenario (the contract's ``name, gravity, bodies, joints``); the spanning tree,
reference orientations and frames are the kit's :func:`~references.engines.reduced.plan` and
:func:`~references.engines.reduced.engine_frames` (one definition for Pinocchio and DART too).
Every body that hangs from the ground is a link of one fixed-base multibody (massless base at the
world origin); every floating root is the base of a multibody of its own (base inertial frame = link
frame = its principal frame at its COM).

Frames: each link frame (PyBullet's joint frame) sits at the link's joint point, parallel to the
body's principal frame; the inertial frame is given explicitly (position -Y, the COM relative to
the joint point, identity orientation), so PyBullet's link world frame (getLinkState 0, 1) *is*
the principal frame at the COM. ``linkPositions``/``linkOrientations`` are (X - Y_p, R_ref) in
the parent's link frame; a revolute joint's axis is the child's axis (link frame).

==================  =====================  ==================================================
scenario kind       PyBullet joint         initial state
==================  =====================  ==================================================
spherical,          ``JOINT_SPHERICAL``    resetJointStateMultiDof: quaternion (x y z w) of
fixed_point                                R_p^T R_c, rates W_c - R_rel^T W_p (child axes)
revolute            ``JOINT_REVOLUTE``     resetJointState: 0, n . (W_c - R_rel^T W_p)
prismatic           ``JOINT_PRISMATIC``    resetJointState: the anchors' offset along the
                                           axis, its rate (reduced.slide_state)
universal           two ``JOINT_REVOLUTE``  both 0; the relative rate on the two axes (least
                    through a massless     squares; the state check catches a rate off them)
                    cross link
cylindrical         ``JOINT_PRISMATIC`` to  the slide as a prismatic joint's; the turn 0,
                    a massless sleeve       n . (W_c - R_rel^T W_p)
                    link, ``JOINT_REVOLUTE``
                    from it
(floating root)     base of a multibody    resetBasePositionAndOrientation / resetBaseVelocity
                                           (COM, world v and world w)
others              -                      unsupported (not built by this adapter)
==================  =====================  ==================================================

Universal joints: PyBullet has none (its joint types are revolute, prismatic, spherical,
planar, fixed, point-to-point, gear), so a universal joint is built as the composition it is:
a massless link, the joint's *cross* (named ``<joint>_cross`` in the settings record: mass 0,
moments 0, no collision shape), hinged to the parent at the joint point about the parent's axis
(R_ref^T u_p in the cross's frame, placed at (R_ref, X - Y_p) as any link), and the body hinged
to the cross at the same point about its own axis u_c: R_p^T R_c = Rot(u_p, q1) R_ref
Rot(u_c, q2), DART's and Pinocchio's parametrisation. Both hinges are read back (type, parent,
axis, placement, the cross's zero mass and moments). The cross adds no inertia, so the motion is
the universal joint's; its two coordinates are the engine's, the bodies' states are read as
for any link.

Cylindrical joints: PyBullet has none either; the builder writes the composition: a massless
link, the joint's *sleeve* (``<joint>_sleeve`` in the settings record: mass 0, moments 0, no
collision shape), on a ``JOINT_PRISMATIC`` from the parent at the joint's placement (R_ref,
X - Y_p) along the child's axis (the sleeve's frame is the child's at a zero turn), and the body
on a ``JOINT_REVOLUTE`` from the sleeve about the same axis at the sleeve's origin: the slide
and the turn about one line commute, so this is the cylindrical joint. Read back as the
universal's (both joints' types, parents, axes and placements, the sleeve's zero mass and
moments); the initial-state check compares the anchors from both sides (the child's moves
along the axis, as a prismatic joint's) and the hinge's world axis with both sides' axes.

Loop closures: a closing spherical joint is one ``JOINT_POINT2POINT`` constraint between the two
anchors (pivots relative to each link's COM frame, world point for the ground); a closing
revolute joint is two of them, at the anchors and at the anchors moved by the system's length
scale along the hinge (six equations for five, as Pinocchio's builder). Bullet solves them as
velocity-level impulses (its sequential-impulse multibody solver) with a position correction by
the error reduction parameter: ``erp`` (default :data:`DEFAULT_ERP`, passed to changeConstraint
and read back with getConstraintInfo) and ``max_force`` (default :data:`DEFAULT_MAX_FORCE` N,
read back); both recorded. The erp is set twice: as the solver's global ``erp``
(setPhysicsEngineParameter), the one Bullet's multibody point-to-point constraint uses (the
four-bar's largest gap over 2 s at dt 1 ms, saved every 10 steps: 2.4e-3 m at erp 0, 2.3e-6 m
at 0.2, 6.2e-7 m at 0.9, measured), and per constraint (changeConstraint, read back; no
effect on a multibody constraint, measured). The global erp cannot be read back; a run at
erp 0.2 equals one at Bullet's default bit for bit (tests).

Integrator: ``multibody``: stepSimulation, Bullet's multibody semi-implicit Euler (velocities,
then positions; gyroscopic term explicit). ``maximal coordinates``: unsupported (pybullet builds
no links with useMaximalCoordinates=True).

Defaults neutralised (docs/engines.md) and checked: joint motors (spherical: POSITION_CONTROL
force [0, 0, 0]; revolute: VELOCITY_CONTROL force 0), linear/angular damping 0.04 -> 0,
jointDamping -> 0, the 100 rad/s velocity clamp -> :data:`MAX_JOINT_VELOCITY`, sleeping
disabled, no collision shapes, gravity set, numSubSteps 0. Motors, damping and the clamp cannot
be read back from pybullet (getJointInfo reports a jointDamping set by changeDynamics as 0, and
the step uses it: measured), so :func:`probe` checks them by behaviour: a step without gravity
from the scenario's configuration with every joint coordinate turning at each of the
:data:`PROBES`' rates must keep the kinetic energy: a fast probe for the clamp, a slow one for
motors and damping (module constants). Masses, inertias, inertial
frames, parents, joint types, axes and frames are read back, and PyBullet's kinematics of the
initial state must reproduce every body and joint (anchors and axes from both sides), else
:class:`~references.errors.EngineError` names the body or joint.
"""

from __future__ import annotations

import importlib.metadata
import time

import numpy as np

from references import conventions as cv
from references.engines import reduced, timing
from references.engines.pybullet import forces
from references.engines.pybullet.adapter import MAX_JOINT_VELOCITY, _import
from references.engines.pybullet.loops import check_constraints, constraint_record, loop_world
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported
from scenarios.force_elements import has_elements, loaded_bodies

#: the tree joints this builder builds (universal and cylindrical as compositions through a
#: massless link: module docstring)
TREE_KINDS = (*reduced.SLIDING_KINDS, "universal", "cylindrical")
#: the massless link of a composed joint: (its name's suffix, its joint type) per kind
COMPOSED = {"universal": ("cross", "JOINT_REVOLUTE"), "cylindrical": ("sleeve", "JOINT_PRISMATIC")}

INTEGRATORS = ("multibody", "maximal coordinates")
#: why PyBullet closes no loop of these kinds (createConstraint's joint types on multibodies:
#: JOINT_POINT2POINT, JOINT_FIXED, JOINT_GEAR, JOINT_PRISMATIC)
REFUSED_CLOSURES = {
    "universal": "PyBullet's user constraints are point-to-point (3 equations), fixed (6), "
    "gear (1: two joints' rates) and prismatic (5); a universal closure holds a point and the "
    "axes' right angle (4), and PyBullet has no universal or distance constraint",
    "cylindrical": "PyBullet's user constraints are point-to-point, fixed, gear and prismatic; "
    "none leaves a rotation and a translation about one axis free",
}
#: the closures this builder makes: point-to-point constraints, and JOINT_PRISMATIC
CLOSURES = (*reduced.POINT_CLOSURES, "prismatic")

#: error reduction parameter of the loop closures: Bullet's default global erp (shown in the
#: tests by a run that leaves it unset)
DEFAULT_ERP = 0.2
#: force limit of the loop closures, N (pybullet's default for a created constraint is 500 N,
#: which a heavy mechanism can exceed; this is far above any force in the library's systems)
DEFAULT_MAX_FORCE = 1e6

#: probes (joint rate rad/s, step s, tolerance on the relative kinetic-energy change). Over one
#: step of h the semi-implicit Euler changes a conservative system's kinetic energy by
#: O((h w)^2) relative. Fast probe: above PyBullet's default 100 rad/s clamp, which removes
#: ~50 %; Euler's change at most 7e-9 on the library systems (measured, 6.8e-7 at h = 1e-6 on
#: free_chain_5). Slow probe: Euler's change at most 3e-10 (measured); damping of any kind
#: changes it by ~2 c h / I (c its coefficient, I the chain's inertia about the joint,
#: ~0.1-5 kg m^2): 2.7e-6 .. 1.8e-5 for a joint damping of 0.01 N m s on the test chains,
#: more for PyBullet's default 0.04 link damping; a motor with a force limit stops a slow
#: joint outright.
PROBES = ((150.0, 1e-7, 1e-6), (0.003, 1e-3, 1e-7))


def engine_frames(pl: reduced.Plan, c: int) -> reduced.EngineFrames:
    """The builder's boundary: what PyBullet is given for body c's link (module docstring)."""
    return reduced.engine_frames(pl, c)


def _joint_types(p) -> dict:
    """PyBullet's joint type of each tree kind's body link (a composed joint's body hangs from
    its massless link by a revolute joint)."""
    return {"spherical": p.JOINT_SPHERICAL, "revolute": p.JOINT_REVOLUTE,
            "prismatic": p.JOINT_PRISMATIC, "universal": p.JOINT_REVOLUTE,
            "cylindrical": p.JOINT_REVOLUTE}  # fmt: skip


class _Model:
    """PyBullet's client, multibodies and links (per scenario body) and loop constraints."""

    def __init__(self, p, pl: reduced.Plan, dt: float):
        self.p, self.pl = p, pl
        self.cid = p.connect(p.DIRECT)
        self.clock = 0.0
        self.where: dict[int, tuple[int, int]] = {}  # body -> (multibody id, link index)
        #: body of a universal or cylindrical joint -> (multibody id, link index of its
        #: massless cross or sleeve)
        self.cross: dict[int, tuple[int, int]] = {}
        self.frames: dict[int, reduced.EngineFrames] = {}
        self.constraints: list = []
        p.setGravity(*pl.gravity.tolist(), physicsClientId=self.cid)
        p.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, physicsClientId=self.cid)
        roots = [c for c in pl.order if pl.tree[c].parent < 0]
        grounded = [c for c in roots if pl.tree[c].kind != "free"]
        if grounded:
            self._multibody(None, self._subtree(grounded))
        for c in roots:
            if pl.tree[c].kind == "free":
                self._multibody(c, [k for k in self._subtree([c]) if k != c])

    def _subtree(self, tops) -> list:
        """Bodies under ``tops`` (included), parents first, in the plan's depth-first order."""
        keep = set(tops)
        for c in self.pl.order:
            if self.pl.tree[c].parent in keep:
                keep.add(c)
        return [c for c in self.pl.order if c in keep]

    def _multibody(self, base, links) -> None:
        p, cid, pl = self.p, self.cid, self.pl
        kinds = _joint_types(p)
        # the multibody's links: each body's, preceded by its massless cross (universal) or
        # sleeve (cylindrical) (module docstring); rows (body, is_cross, position,
        # orientation, inertial offset, axis, mass, joint type)
        rows, index, cross = [], {}, {}
        for c in links:
            fc = engine_frames(pl, c)
            self.frames[c] = fc
            tj = pl.tree[c]
            mass = float(pl.bodies[c].mass)
            if fc.kind in COMPOSED:
                reduced.composed_name(pl, tj, COMPOSED[fc.kind][0])  # not a body's name
                # the cross turns about the parent's axis; the sleeve slides along the child's
                first = tj.R_ref.T @ tj.axis_p if fc.kind == "universal" else fc.axis
                cross[c] = len(rows)
                rows.append((c, True, fc.p, fc.R, np.zeros(3), first, reduced.COMPOSED_MASS,
                             getattr(p, COMPOSED[fc.kind][1])))  # fmt: skip
                index[c] = len(rows)
                rows.append((c, False, np.zeros(3), np.eye(3), fc.body_offset, fc.axis, mass,
                             p.JOINT_REVOLUTE))  # fmt: skip
            else:
                index[c] = len(rows)
                axis = fc.axis if fc.axis is not None else np.array([0, 0, 1.0])
                rows.append((c, False, fc.p, fc.R, fc.body_offset, axis, mass, kinds[fc.kind]))

        def parent(c, is_cross):
            if c in cross and not is_cross:
                return cross[c] + 1
            tp = pl.tree[c].parent
            return 0 if tp < 0 or tp == base else index[tp] + 1

        mb = p.createMultiBody(
            baseMass=0.0 if base is None else float(pl.bodies[base].mass),
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=[0.0, 0.0, 0.0],
            baseOrientation=[0.0, 0.0, 0.0, 1.0],
            baseInertialFramePosition=[0.0, 0.0, 0.0],
            baseInertialFrameOrientation=[0.0, 0.0, 0.0, 1.0],
            linkMasses=[r[6] for r in rows],
            linkCollisionShapeIndices=[-1] * len(rows),
            linkVisualShapeIndices=[-1] * len(rows),
            linkPositions=[np.asarray(r[2]).tolist() for r in rows],
            linkOrientations=[cv.matrix_to_quat_xyzw(r[3]).tolist() for r in rows],
            linkInertialFramePositions=[np.asarray(r[4]).tolist() for r in rows],
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * len(rows),
            linkParentIndices=[parent(r[0], r[1]) for r in rows],
            linkJointTypes=[r[7] for r in rows],
            linkJointAxis=[np.asarray(r[5]).tolist() for r in rows],
            useMaximalCoordinates=False,
            physicsClientId=cid,
        )
        if base is not None:
            self.where[base] = (mb, -1)
            self.frames[base] = engine_frames(pl, base)
        for c in links:
            self.where[c] = (mb, index[c])
        for c, k in cross.items():
            self.cross[c] = (mb, k)
        # body-wide options and the inertia in SEPARATE calls, no mass on a link
        # (pybullet_engine's docstring: either distorts the link)
        for link in [-1, *range(len(links))]:
            p.changeDynamics(mb, link, linearDamping=0.0, angularDamping=0.0,
                             maxJointVelocity=MAX_JOINT_VELOCITY,
                             activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
                             physicsClientId=cid)  # fmt: skip
        if base is not None:
            p.changeDynamics(mb, -1, localInertiaDiagonal=list(map(float, pl.bodies[base].inertia)),
                             physicsClientId=cid)  # fmt: skip
        for c in links:
            k = index[c]
            p.changeDynamics(mb, k, jointDamping=0.0, physicsClientId=cid)
            p.changeDynamics(mb, k, localInertiaDiagonal=list(map(float, pl.bodies[c].inertia)),
                             physicsClientId=cid)  # fmt: skip
        for k in cross.values():
            p.changeDynamics(mb, k, jointDamping=0.0, physicsClientId=cid)
            p.changeDynamics(mb, k, localInertiaDiagonal=[reduced.COMPOSED_MASS] * 3,
                             physicsClientId=cid)  # fmt: skip
        ks = [index[c] for c in links] + list(cross.values())
        composed = ["prismatic" if pl.tree[c].kind == "cylindrical" else "revolute" for c in cross]
        self.motors_off(mb, ks, [pl.tree[c].kind for c in links] + composed)

    def motors_off(self, mb, links, kinds) -> None:
        """Every joint's default motor off: a zero force limit (zero gains alone do not)."""
        p, cid = self.p, self.cid
        for k, kind in zip(links, kinds, strict=True):
            if kind == "spherical":
                p.setJointMotorControlMultiDof(mb, k, p.POSITION_CONTROL,
                                               targetPosition=[0.0, 0.0, 0.0, 1.0],
                                               targetVelocity=[0.0, 0.0, 0.0],
                                               force=[0.0, 0.0, 0.0],
                                               physicsClientId=cid)  # fmt: skip
            else:
                p.setJointMotorControl2(mb, k, p.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0,
                                        physicsClientId=cid)  # fmt: skip

    # -- state -------------------------------------------------------------------------------
    def set_joints(self, rates=None) -> None:
        """The scenario's initial configuration; velocities the scenario's, or every joint
        coordinate (and a floating base's w) at ``rates`` rad/s with v = 0 (the probe)."""
        p, cid, pl = self.p, self.cid, self.pl
        for c, (mb, k) in self.where.items():
            tj = pl.tree[c]
            x, R, vG, w = reduced.world(pl, c)
            if tj.kind == "free":
                W = R.T @ w if rates is None else np.array([rates, -0.8 * rates, 0.6 * rates])
                X, q, v, ww = cv.pybullet_base_from_state(x, vG if rates is None else 0 * vG, R, W)
                p.resetBasePositionAndOrientation(mb, X, q, physicsClientId=cid)
                p.resetBaseVelocity(mb, v, ww, physicsClientId=cid)
                continue
            Rr, Wr = reduced.relative_state(pl, tj)
            if rates is not None:
                Wr = np.array([rates, -0.8 * rates, 0.6 * rates])
            if tj.kind == "spherical":
                q, W = cv.pybullet_spherical_from_state(Rr, Wr)
                p.resetJointStateMultiDof(mb, k, targetValue=q, targetVelocity=W,
                                          physicsClientId=cid)  # fmt: skip
            elif tj.kind == "prismatic":
                d0, rate = reduced.slide_state(pl, tj)
                u = rates if rates is not None else rate
                p.resetJointState(mb, k, d0, u, physicsClientId=cid)
            elif tj.kind == "universal":
                # at (0, 0) the relative rate (child axes) is q1' R_ref^T u_p + q2' u_c
                axes = np.column_stack([tj.R_ref.T @ tj.axis_p, tj.axis_c])
                q12 = np.linalg.lstsq(axes, Wr, rcond=None)[0]
                if rates is not None:
                    q12 = [rates, rates]
                p.resetJointState(mb, self.cross[c][1], 0.0, float(q12[0]), physicsClientId=cid)
                p.resetJointState(mb, k, 0.0, float(q12[1]), physicsClientId=cid)
            elif tj.kind == "cylindrical":
                # the sleeve slides as a prismatic joint; the body turns in it from 0
                d0, rate = reduced.slide_state(pl, tj)
                u = (rates, rates) if rates is not None else (rate, float(tj.axis_c @ Wr))
                p.resetJointState(mb, self.cross[c][1], d0, u[0], physicsClientId=cid)
                p.resetJointState(mb, k, 0.0, u[1], physicsClientId=cid)
            else:
                u = rates if rates is not None else float(tj.axis_c @ Wr)
                p.resetJointState(mb, k, 0.0, u, physicsClientId=cid)

    def states(self):
        """(x, R, v, W) per body (scenario order), and per multibody link the world link-frame
        point and orientation (joint frames), from PyBullet's kinematics."""
        p, cid = self.p, self.cid
        x, R, v, W = reduced.state_arrays(len(self.pl.bodies))
        frames = {}
        for c, (mb, k) in self.where.items():
            if k < 0:
                xc, q = p.getBasePositionAndOrientation(mb, physicsClientId=cid)
                vc, wc = p.getBaseVelocity(mb, physicsClientId=cid)
                fp, fq = xc, q
            else:
                s = p.getLinkState(mb, k, computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=cid)  # fmt: skip
                xc, q, vc, wc = s[0], s[1], s[6], s[7]
            Rc = cv.quat_xyzw_to_matrix(q)
            if k >= 0:
                # the link (joint) frame from PyBullet's COM frame and the inertial offset it
                # holds: getLinkState's own link-frame position (4) carries an error of 1e-8 m
                # relative to it (measured, pybullet 3.2.7), far above round-off
                off = np.asarray(p.getDynamicsInfo(mb, k, physicsClientId=cid)[3], float)
                fp, fq = np.asarray(xc, float) - Rc @ off, q
            x[c], R[c], v[c] = xc, Rc, vc
            W[c] = Rc.T @ np.asarray(wc, float)
            frames[c] = (np.asarray(fp, float), cv.quat_xyzw_to_matrix(fq))
        return x, R, v, W, frames

    def joint_world(self, frames):
        """World joint points and hinge axes of the tree joints (by scenario joint name)."""
        p, cid = self.p, self.cid
        points, axes = {}, {}
        for c, (mb, k) in self.where.items():
            tj = self.pl.tree[c]
            if tj.kind == "free":
                continue
            P, Rf = frames[c]
            points[tj.name] = P
            if tj.kind in ("revolute", "prismatic", "cylindrical"):
                # a cylindrical joint's: the hinge's from the sleeve (the slide's is read back
                # equal to it)
                axes[tj.name] = Rf @ np.asarray(p.getJointInfo(mb, k, physicsClientId=cid)[13])
            if tj.kind in ("prismatic", "cylindrical"):
                # the child's side moves along the axis; the parent's is the joint placement
                if tj.parent < 0:
                    fixed = self.frames[c].p
                else:
                    Pp, Rp = frames[tj.parent]
                    fixed = Pp + Rp @ self.frames[c].p
                j = next(j for j in self.pl.joints if j.name == tj.name)
                a_is_child = j.body_a == self.pl.names[c]
                points[tj.name] = {("a" if a_is_child else "b"): P,
                                   ("b" if a_is_child else "a"): fixed}  # fmt: skip
        return points, axes

    def kinetic_energy(self) -> float:
        """From PyBullet's link velocities and the inertias it reports (getDynamicsInfo)."""
        p, cid = self.p, self.cid
        x, R, v, W, _ = self.states()
        E = 0.0
        for c, (mb, k) in self.where.items():
            info = p.getDynamicsInfo(mb, k, physicsClientId=cid)
            E += 0.5 * info[0] * v[c] @ v[c] + 0.5 * W[c] @ (np.asarray(info[2]) * W[c])
        return float(E)  # a universal joint's cross has no mass (read back)

    def add_loops(self, erp: float, max_force: float) -> None:
        p, cid, pl = self.p, self.cid, self.pl
        if pl.loops:
            # the solver's global erp is the one Bullet's multibody point-to-point constraint
            # uses (measured: the per-constraint erp of changeConstraint, read back by
            # getConstraintInfo, leaves the four-bar's gap unchanged to all digits)
            p.setPhysicsEngineParameter(erp=float(erp), physicsClientId=cid)
        for lp in pl.loops:
            mba, ka = self.where[lp.a]
            mbb, kb = (-1, -1) if lp.b < 0 else self.where[lp.b]
            if lp.kind == "prismatic":
                self.constraints.append(self._slider(lp, mba, ka, mbb, kb))
                continue
            for Xa, Xb in lp.pairs:
                cons = p.createConstraint(mba, ka, mbb, kb, p.JOINT_POINT2POINT, [0, 0, 0],
                                          Xa.tolist(), Xb.tolist(),
                                          physicsClientId=cid)  # fmt: skip
                self.constraints.append((lp, cons, Xa, Xb))
        for _, cons, *_ in self.constraints:
            p.changeConstraint(cons, maxForce=float(max_force), erp=float(erp),
                               physicsClientId=cid)  # fmt: skip

    def _slider(self, lp, mba, ka, mbb, kb) -> tuple:
        """A prismatic closure as one JOINT_PRISMATIC (btMultiBodySliderConstraint: the two
        translations across the axis and the three rotations held, the axis in a's link frame):
        pivot on a at its anchor, on b at the point of b that meets a's anchor at t = 0 (the
        anchors may stand apart along the axis), frames chosen so that both are the same world
        frame at t = 0 (a's: its link frame; b's: R_b^T R_a, the ground's: R_a)."""
        p, cid, pl = self.p, self.cid, self.pl
        xa, Ra, _, _ = reduced.world(pl, lp.a)
        xb, Rb, _, _ = (np.zeros(3), np.eye(3), None, None) if lp.b < 0 else reduced.world(pl, lp.b)
        Xa = lp.pairs[0][0]
        axis = (lp.pairs[1][0] - Xa) / pl.length
        Xb = Rb.T @ (xa + Ra @ Xa - xb)
        Fb = Rb.T @ Ra
        cons = p.createConstraint(mba, ka, mbb, kb, p.JOINT_PRISMATIC, axis.tolist(), Xa.tolist(),
                                  Xb.tolist(), [0, 0, 0, 1], cv.matrix_to_quat_xyzw(Fb).tolist(),
                                  physicsClientId=cid)  # fmt: skip
        return lp, cons, Xa, Xb, axis, Fb


def read_back(bm: _Model, scenario, dt: float) -> None:
    """Compare PyBullet's model with the scenario (module docstring)."""
    p, cid, pl = bm.p, bm.cid, bm.pl
    bad = reduced.Mismatches()
    want = bad.want

    kinds = _joint_types(p)
    inv = {v: c for c, v in bm.where.items()}
    for c, (mb, k) in bm.where.items():
        b, tj, f = pl.bodies[c], pl.tree[c], bm.frames[c]
        name = f"body {b.name!r} ({tj.label})"
        info = p.getDynamicsInfo(mb, k, physicsClientId=cid)
        want(f"{name}: mass", info[0], b.mass)
        want(f"{name}: principal moments", info[2], b.inertia)
        if k < 0:
            want(f"{name}: base inertial frame position", info[3], np.zeros(3))
            want(f"{name}: base inertial frame orientation", info[4], [0, 0, 0, 1])
            continue
        want(f"{name}: inertial frame position (COM from the joint point)", info[3], -tj.Y)
        want(f"{name}: inertial frame orientation", info[4], [0, 0, 0, 1])
        j = p.getJointInfo(mb, k, physicsClientId=cid)
        if j[2] != kinds[tj.kind]:
            bad.append(f"{name}: joint type {j[2]}, needs {tj.kind}")
        want(f"{name}: joint damping", j[6], 0.0)
        want(f"{name}: joint friction", j[7], 0.0)
        parent = j[16]
        exp_parent = "ground" if tj.parent < 0 else pl.names[tj.parent]
        place = f.p
        if tj.kind in COMPOSED:
            # the body hangs from its cross (universal) or sleeve (cylindrical) at the joint
            # point, about its own axis; the cross turns from the parent about the parent's
            # axis, the sleeve slides along the child's (module docstring)
            what, jtype = COMPOSED[tj.kind]
            kc = bm.cross[c][1]
            if parent != kc:
                bad.append(f"{name}: parent link {parent}, needs its {what} (link {kc})")
            want(f"{name}: joint position in its {what}", j[14], np.zeros(3))
            want(f"{name}: joint frame orientation in its {what}", j[15], [0, 0, 0, 1])
            want(f"{name}: joint axis (child frame)", j[13], f.axis)
            name = f"{tj.name}_{what}"
            ci = p.getDynamicsInfo(mb, kc, physicsClientId=cid)
            want(f"{name}: mass", ci[0], 0.0)
            want(f"{name}: moments", ci[2], np.zeros(3))
            j = p.getJointInfo(mb, kc, physicsClientId=cid)
            if j[2] != getattr(p, jtype):
                bad.append(f"{name}: joint type {j[2]}, needs {jtype}")
            want(f"{name}: joint damping", j[6], 0.0)
            want(f"{name}: joint friction", j[7], 0.0)
            first = tj.R_ref.T @ tj.axis_p if tj.kind == "universal" else f.axis
            want(f"{name}: joint axis (its frame)", j[13], first)
            parent = j[16]
        got_parent = inv.get((mb, parent))
        got_parent = "ground" if got_parent is None else pl.names[got_parent]
        if got_parent != exp_parent:
            bad.append(f"{name}: parent {got_parent!r}, needs {exp_parent!r}")
        # joint frame in the parent's link frame, as stored (pybullet reports it relative to
        # the parent's inertial frame: back to the link frame by the parent's inertial offset)
        off = np.zeros(3) if parent < 0 else np.asarray(
            p.getDynamicsInfo(mb, parent, physicsClientId=cid)[3])  # fmt: skip
        want(f"{name}: joint position in the parent", np.asarray(j[14]) + off, place)
        if tj.kind in ("revolute", "prismatic"):
            want(f"{name}: joint axis (child frame)", j[13], f.axis)
    params = p.getPhysicsEngineParameters(physicsClientId=cid)
    want("gravity", [params[f"gravityAcceleration{a}"] for a in "XYZ"], pl.gravity)
    want("time step", params["fixedTimeStep"], dt)
    want("number of substeps", params["numSubSteps"], 0)
    bad.raise_any("pybullet", scenario)


def _composed_record(pl: reduced.Plan, composed) -> dict:
    """The settings record's entries for the joints built as compositions (module docstring):
    each names its massless link."""
    out: dict = {}
    for c in composed:
        tj = pl.tree[c]
        what = COMPOSED[tj.kind][0]
        joints = ("two JOINT_REVOLUTE" if tj.kind == "universal"
                  else "JOINT_PRISMATIC then JOINT_REVOLUTE on one axis")  # fmt: skip
        out.setdefault(f"{tj.kind} joints", []).append(
            f"{tj.name}: {joints} through the massless link '{tj.name}_{what}' (mass 0, moments 0)"
        )
    return out


def probe(bm: _Model, dt: float) -> list:
    """The PROBES: one step each without gravity from the scenario's configuration, every joint
    coordinate at the probe's rate; the relative kinetic-energy changes (module docstring).
    Raises EngineError beyond a probe's tolerance. Gravity and the time step are restored; the
    state is reset by the caller."""
    p, cid, pl = bm.p, bm.cid, bm.pl
    out = []
    p.setGravity(0.0, 0.0, 0.0, physicsClientId=cid)
    for rate, h, tol in PROBES:
        bm.set_joints(rates=rate)
        p.setPhysicsEngineParameter(fixedTimeStep=h, physicsClientId=cid)
        E0 = bm.kinetic_energy()
        p.stepSimulation(physicsClientId=cid)
        rel = abs(bm.kinetic_energy() - E0) / E0
        out.append(rel)
        if not rel <= tol:
            raise EngineError(
                f"pybullet: system {pl.name!r}: a probe step of {h:g} s (no gravity, joints at "
                f"{rate:g} rad/s) changed the kinetic energy by {rel:.3g} relative (> {tol:g}): "
                "a joint motor, damping or the velocity clamp is still acting"
            )
    p.setGravity(*pl.gravity.tolist(), physicsClientId=cid)
    p.setPhysicsEngineParameter(fixedTimeStep=dt, physicsClientId=cid)
    return out


def build(scenario, integrator: str, dt: float, **settings):
    """(_Model, settings record): planned, built, read back, probed, the initial state set and
    checked against PyBullet's kinematics, the loops closed and read back."""
    reduced.check_run_args(integrator, dt, INTEGRATORS)
    reduced.check_settings("pybullet", settings)
    erp = float(settings.get("erp", DEFAULT_ERP))
    if not 0 <= erp <= 1:
        raise ValueError(f"erp {erp!r}: Bullet's error reduction parameter, a number in [0, 1]")
    max_force = float(settings.get("max_force", DEFAULT_MAX_FORCE))
    if not max_force > 0:
        raise ValueError(f"max_force {max_force!r}: the closures' force limit, a number > 0 (N)")
    if integrator == "maximal coordinates":
        raise Unsupported(
            "pybullet: maximal coordinates hold no joints (createMultiBody with "
            "useMaximalCoordinates=True builds no links; getNumJoints returns 0), so a system "
            "of jointed bodies is not built there"
        )
    p = _import()
    pl = reduced.plan(scenario, "pybullet", TREE_KINDS, CLOSURES, refused=REFUSED_CLOSURES)
    bm = _Model(p, pl, float(dt))
    try:
        read_back(bm, scenario, float(dt))
        rel = probe(bm, float(dt))
        bm.set_joints()
        x, R, v, W, frames = bm.states()
        points, axes = bm.joint_world(frames)
        reduced.check_states("pybullet", pl, x, R, v, W, points, axes)
        bm.add_loops(erp, max_force)
        check_constraints(bm, erp, max_force)
        reduced.check_loops("pybullet", pl, loop_world(bm, x, R))
    except Exception:
        p.disconnect(physicsClientId=bm.cid)
        raise
    rec = {
        "engine": f"pybullet {importlib.metadata.version('pybullet')}",
        "integrator": integrator,
        "stepping": "stepSimulation (btMultiBody, semi-implicit Euler)",
        "dt": float(dt),
        "numSubSteps": 0,
        "gravity": pl.gravity.tolist(),
        "tree": reduced.tree_record(pl),
        "frames": "link frame at the joint point, parallel to the principal frame; inertial "
        "frame explicit (-Y, identity)",
        "joint motors": "off (spherical: POSITION_CONTROL force 0; revolute: VELOCITY_CONTROL "
        "force 0)",
        "linearDamping, angularDamping, jointDamping": 0.0,
        "maxJointVelocity": MAX_JOINT_VELOCITY,
        "activationState": "ACTIVATION_STATE_DISABLE_SLEEPING",
        "collision": "none (no collision shapes)",
        **_composed_record(pl, bm.cross),
        "probes (rate rad/s, step s, relative kinetic-energy change)": [
            (r, h, e) for (r, h, _), e in zip(PROBES, rel, strict=True)
        ],
    }
    if has_elements(scenario):
        rec["force elements"] = forces.record(scenario)
    if bm.constraints:
        rec["loop closures"] = [
            f"{lp.label}: "
            + (
                "two JOINT_POINT2POINT on the hinge axis (6 equations for 5)"
                if lp.kind == "revolute"
                else "JOINT_PRISMATIC (btMultiBodySliderConstraint: two translations, three "
                "rotations)"
                if lp.kind == "prismatic"
                else "JOINT_POINT2POINT"
            )  # fmt: skip
            for lp in pl.loops
        ]
        rec["constraints"] = constraint_record(bm)
    return bm, rec


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` (module docstring) on PyBullet.

    ``integrator``: "multibody" (stepSimulation); ``dt`` s; ``nstep`` steps saved at 0, s, 2s,
    ..., nstep; ``settings``: ``erp`` (the loop closures' error reduction parameter, default
    :data:`DEFAULT_ERP`), ``max_force`` (their force limit, N, default
    :data:`DEFAULT_MAX_FORCE`).

    Returns a :class:`~references.engines.system.SystemResult` with ``t, x, R, v, W`` (as
    :func:`references.engines.pinocchio.system.simulate_system`), ``engine_time_s`` (inside
    stepSimulation) and ``settings``. Raises :class:`Unsupported`, :class:`EngineError`
    (read-back, probe or initial-state mismatch) and :class:`Diverged` (non-finite state, or a
    speed near the raised velocity clamp)."""
    steps = reduced.saves(nstep, save_every)
    bm, rec = build(scenario, integrator, dt, **settings)
    p, cid = bm.p, bm.cid
    try:
        nb, n = len(bm.pl.bodies), len(steps)
        x, R, v, W = reduced.state_arrays(n, nb)
        x[0], R[0], v[0], W[0], _ = bm.states()
        done = 0
        timing.stepping()  # the model is built: its construction is not the cost
        loads = has_elements(scenario)
        loaded = loaded_bodies(scenario) if loads else ()
        for k in range(1, n):
            m = int(steps[k] - done)
            if loads:  # applied before each step (forces.py); only the step is timed
                for _ in range(m):
                    forces.apply(bm, scenario, loaded)
                    t0 = time.perf_counter()
                    p.stepSimulation(physicsClientId=cid)
                    bm.clock += timing.lap(t0)
            else:
                t0 = time.perf_counter()
                for _ in range(m):
                    p.stepSimulation(physicsClientId=cid)
                bm.clock += timing.lap(t0)
            done = int(steps[k])
            x[k], R[k], v[k], W[k], _ = bm.states()
            speed = float(np.max(np.abs(W[k])))
            finite = bool(np.all(np.isfinite(x[k])) and np.all(np.isfinite(W[k])))
            if not finite or speed > 0.1 * MAX_JOINT_VELOCITY:
                why = "a non-finite state" if not finite else (
                    f"a rate of {speed:g} rad/s near the raised velocity clamp")  # fmt: skip
                raise Diverged(
                    f"pybullet {integrator} at dt = {dt:g} s: {why} between t = "
                    f"{steps[k - 1] * dt:.6g} and {done * dt:.6g} s",
                    done * dt,
                    reduced.output(steps[:k], dt, x[:k], R[:k], v[:k], W[:k], bm.clock, rec),
                )
        return reduced.output(steps, dt, x, R, v, W, bm.clock, rec)
    finally:
        p.disconnect(physicsClientId=cid)
