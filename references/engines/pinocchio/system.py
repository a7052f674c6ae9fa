"""Pinocchio builder for systems of rigid bodies: trees in Pinocchio's reduced coordinates,
loops closed by Pinocchio's ``RigidConstraintModel`` (CONTACT_3D) with ``constraintDynamics``
and a Baumgarte corrector.

Input: a system scenario with ``name``, ``gravity`` (3,), ``bodies`` and ``joints`` with the fields
of ``director_model.system.Body`` and ``Joint`` (docs of that module: anchors and axes in each
body's principal frame relative to its centre of mass, world for the ground). The spanning tree is
:func:`scenarios.tree.spanning_tree`'s: from the ground outwards; a part joined to nothing is a
floating root (its first body in the scenario's order) on a ``JointModelFreeFlyer``.

Frames (the kit's :func:`~references.engines.reduced.plan` computes them once;
:func:`engine_frames` turns them into what Pinocchio is given, the builder's boundary where the
tests plant mistakes). The frame of the Pinocchio joint
that attaches body c is parallel to c's principal frame and sits at c's anchor Y, so c's
principal frame is that joint frame moved by -Y (``appendBodyToJoint`` with placement
(1, -Y) and ``Inertia(m, 0, diag(I))``). The joint placement in the parent's joint frame is
(R_ref, X - Y_p) (X: the parent's anchor in the parent's principal frame, Y_p: the parent's own
anchor; a world point and no Y_p for the ground):

==================  ============================  ==========================================
scenario kind       Pinocchio joint               R_ref, initial q and v
==================  ============================  ==========================================
spherical,          ``JointModelSpherical``       identity; q = quaternion (x y z w) of
fixed_point         (quaternion, LOCAL rates)     R_p^T R_c, v = W_c - R_rel^T W_p
revolute            ``JointModelRevoluteUnaligned``  R_p^T R_c at t = 0; q = 0,
                    (axis = the child's axis)     v = n . (W_c - R_rel^T W_p)
prismatic           ``JointModelPrismaticUnaligned`` R_p^T R_c at t = 0; q = the anchors'
                    (axis = the child's axis)     offset along the axis, v its rate
                                                  (the kit's ``slide_state``)
universal           ``JointModelUniversal``       R_p^T R_c at t = 0; q = (0, 0), v the
                    (R_ref^T u_p, then u_c:       relative angular velocity on the two axes
                    :func:`universal_first_axis`) (least squares; the state check catches
                                                  a rate off them)
cylindrical         ``JointModelComposite`` of    R_p^T R_c at t = 0; q = (the prismatic's
                    ``JointModelPrismaticUnaligned``  slide, 0), v = (its rate,
                    and ``JointModelRevoluteUnaligned``  n . (W_c - R_rel^T W_p))
                    on the child's axis
(floating root)     ``JointModelFreeFlyer``       q = [x, quaternion of R], v = [R^T v, W]
others              -                             unsupported (not built by this adapter)
==================  ============================  ==========================================

Cylindrical joints: Pinocchio 4.1 has no cylindrical joint model; the builder writes the
composition Pinocchio offers for it, one ``JointModelComposite`` holding a slide and a turn on
the same axis (both at the composite's origin: the two commute, so this is the cylindrical
joint; no extra body). Read back: the composite's two parts, their types, axes and (identity)
placements.

Loop closures: each closing spherical joint is one ``RigidConstraintModel(CONTACT_3D)`` between
the two anchors (LOCAL frame); a closing revolute joint is two of them, at the anchors and at the
anchors moved by the system's length scale along the hinge axis: six equations for the hinge's
five (one redundant), which ``constraintDynamics``' proximal solver accepts (its ``mu`` > 0
regularises the rank-deficient system). Pinocchio's Baumgarte gains default to 0 (read back):
without them the loop drifts open; here Kp = omega^2, Kd = 2 omega (critical damping) with
omega = ``baumgarte_omega`` (rad/s; default :data:`BAUMGARTE_FACTOR` times the system's frequency
scale max(sqrt(|g| / L), V / L), L and V its length and rate scales), or ``baumgarte=(Kp, Kd)``
given. The gains do not depend on dt, so that a sweep over dt integrates one system and shows
the integrator's order. Other closures are unsupported (:data:`REFUSED_CLOSURES` says why).

Time stepping (Pinocchio has none; both loops are ours and drawn from Pinocchio's calls only):
``semi-implicit Euler``: v += h a(q, v); q = integrate(q, h v); quaternions renormalised
(``pinocchio.normalize``). ``RKMK4``: the suite's Runge-Kutta-Munthe-Kaas of order 4
(:mod:`references.engines.liegroup`) on Pinocchio's whole configuration group: stage
configurations ``integrate(q0, theta)``, theta' = J_r(theta)^{-1} v with J_r =
``dIntegrate(q0, theta, ARG1)``; a free root's group is Pinocchio's SE(3) (LOCAL twist).
a = ``aba`` for a tree, ``constraintDynamics`` with loops.

Checks before stepping: the model is read back (joint types, placements, axes, parents, masses,
inertias about the COM, gravity, damping, armature, friction, constraint placements and gains)
and Pinocchio's forward kinematics of the initial q, v must reproduce every body's world state
and every scenario joint's anchor (from both sides) and axis (from both sides), to
:data:`~references.engines.reduced.CHECK_TOL` relative to the length and rate scales; a
mismatch raises :class:`~references.errors.EngineError` naming the body or joint.
"""

from __future__ import annotations

import math
import time

import numpy as np

from references import conventions as cv
from references.engines import reduced, timing
from references.engines.native import import_engine
from references.engines.pinocchio import forces
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError
from scenarios.force_elements import has_elements

INTEGRATORS = ("semi-implicit Euler", "RKMK4")

#: default Baumgarte frequency over the system's frequency scale (Kp = omega^2, Kd = 2 omega)
BAUMGARTE_FACTOR = 10.0

#: proximal settings of constraintDynamics: accuracy, mu (regularisation), iterations
PROX = (1e-12, 1e-8, 10)


def _import():
    return import_engine("pinocchio", "Pinocchio", "pin")


# -- Pinocchio model --------------------------------------------------------------------------


def engine_frames(pl: reduced.Plan, c: int) -> reduced.EngineFrames:
    """The builder's boundary: the frames of body c's joint (:func:`reduced.engine_frames`)."""
    return reduced.engine_frames(pl, c)


#: the tree joints this builder builds (cylindrical as a composite: module docstring)
TREE_KINDS = (*reduced.SLIDING_KINDS, "universal", "cylindrical")
#: the parts of a cylindrical joint's JointModelComposite, in order
CYLINDRICAL_PARTS = ("JointModelPrismaticUnaligned", "JointModelRevoluteUnaligned")


def universal_first_axis(tj) -> np.ndarray:
    """A universal joint's first axis in its joint frame (parallel to the child's principal
    frame at t = 0): the parent's axis u_p seen from there, R_ref^T u_p; the second is the
    child's axis. Pinocchio's JointModelUniversal turns by Rot(a1, q1) Rot(a2, q2), so that
    R_p^T R_c = Rot(u_p, q1) R_ref Rot(u_c, q2): a turn about the axis fixed in the parent,
    then about the one fixed in the child."""
    return tj.R_ref.T @ tj.axis_p


class _Model:
    """Pinocchio's model and data, joint ids, the constraints and the state."""

    def __init__(self, pin, pl: reduced.Plan, dt: float, gains, prox):
        self.pin, self.pl = pin, pl
        model = pin.Model()
        self.jid: dict[int, int] = {}
        self.frames: dict[int, reduced.EngineFrames] = {}
        for c in pl.order:
            f = engine_frames(pl, c)
            tj = pl.tree[c]
            if f.kind == "free":
                jm = pin.JointModelFreeFlyer()
            elif f.kind == "spherical":
                jm = pin.JointModelSpherical()
            elif f.kind == "prismatic":
                jm = pin.JointModelPrismaticUnaligned(*f.axis)
            elif f.kind == "universal":
                # about the parent's axis (in the joint frame, R_ref^T u_p) then the child's
                jm = pin.JointModelUniversal(universal_first_axis(tj), np.asarray(f.axis, float))
            elif f.kind == "cylindrical":
                # a slide and a turn on the child's axis (module docstring)
                jm = pin.JointModelComposite(2)
                jm.addJoint(pin.JointModelPrismaticUnaligned(*f.axis))
                jm.addJoint(pin.JointModelRevoluteUnaligned(*f.axis))
            else:
                jm = pin.JointModelRevoluteUnaligned(*f.axis)
            parent = 0 if tj.parent < 0 else self.jid[tj.parent]
            jid = model.addJoint(parent, jm, pin.SE3(f.R, f.p), f"{pl.names[c]}_joint")
            b = pl.bodies[c]
            inertia = pin.Inertia(float(b.mass), np.zeros(3), np.diag(np.asarray(b.inertia, float)))
            model.appendBodyToJoint(jid, inertia, pin.SE3(np.eye(3), f.body_offset))
            self.jid[c], self.frames[c] = jid, f
        model.gravity = pin.Motion(pl.gravity, np.zeros(3))
        self.model, self.data = model, model.createData()
        self.constraints = []
        for lp in pl.loops:
            for k, (Pa, Pb) in enumerate(lp.pairs):
                pa = Pa + self.frames[lp.a].body_offset
                pb = Pb if lp.b < 0 else Pb + self.frames[lp.b].body_offset
                cm = pin.RigidConstraintModel(
                    pin.ContactType.CONTACT_3D, model, self.jid[lp.a], pin.SE3(np.eye(3), pa),
                    0 if lp.b < 0 else self.jid[lp.b], pin.SE3(np.eye(3), pb),
                    pin.ReferenceFrame.LOCAL,
                )  # fmt: skip
                cm.name = f"{lp.label} point {k}"
                cm.setBaumgarteCorrectorParameters(pin.BaumgarteCorrectorParameters(*gains))
                self.constraints.append(cm)
        if self.constraints:
            self.cmodels = pin.StdVec_RigidConstraintModel()
            for cm in self.constraints:
                self.cmodels.append(cm)
            self.cdatas = pin.StdVec_RigidConstraintData()
            for cm in self.cmodels:
                self.cdatas.append(cm.createData())
            pin.initConstraintDynamics(model, self.data, self.cmodels, self.cdatas)
            self.prox = pin.ProximalSettings(prox[0], prox[1], int(prox[2]))
        self.tau = np.zeros(model.nv)
        self.clock = 0.0
        self.loads = None  # the scenario, when it has force elements (forces.py)
        self.loaded = []  # the bodies they act on (forces.loaded)

    # -- initial state -----------------------------------------------------------------------
    def initial(self):
        pl, model = self.pl, self.model
        q, v = np.zeros(model.nq), np.zeros(model.nv)
        for c in pl.order:
            jm = model.joints[self.jid[c]]
            qa, va = jm.idx_q, jm.idx_v
            tj = pl.tree[c]
            x, R, vG, w = reduced.world(pl, c)
            if tj.kind == "free":
                qq, vv = cv.pinocchio_freeflyer_from_state(x, vG, R, R.T @ w)
            elif tj.kind == "spherical":
                Rrel, Wrel = reduced.relative_state(pl, tj)
                qq, vv = cv.pinocchio_spherical_from_state(Rrel, Wrel)
            elif tj.kind == "prismatic":
                d0, rate = reduced.slide_state(pl, tj)
                qq, vv = [d0], [rate]
            elif tj.kind == "cylindrical":
                d0, rate = reduced.slide_state(pl, tj)
                _, Wrel = reduced.relative_state(pl, tj)
                qq, vv = [d0, 0.0], [rate, float(tj.axis_c @ Wrel)]
            elif tj.kind == "universal":
                _, Wrel = reduced.relative_state(pl, tj)
                axes = np.column_stack([universal_first_axis(tj), np.asarray(jm.extract().axis2)])
                qq, vv = [0.0, 0.0], list(np.linalg.lstsq(axes, Wrel, rcond=None)[0])
            else:
                _, Wrel = reduced.relative_state(pl, tj)
                qq, vv = [0.0], [float(tj.axis_c @ Wrel)]
            q[qa : qa + len(qq)] = qq
            v[va : va + len(vv)] = vv
        return q, v

    # -- read-out ----------------------------------------------------------------------------
    def states(self, q, v, bodies=None):
        """(x, R, v, W) per body (scenario order) from Pinocchio's forward kinematics; with
        ``bodies`` (indices), only theirs are read (the other rows are left unset)."""
        pin = self.pin
        pin.forwardKinematics(self.model, self.data, q, v)
        x, R, vv, W = reduced.state_arrays(len(self.pl.bodies))
        oMi, twists, jids = self.data.oMi, self.data.v, self.jid
        for c in jids if bodies is None else bodies:
            jid = jids[c]
            M, tw = oMi[jid], twists[jid]
            Rc, off = M.rotation, self.frames[c].body_offset
            R[c] = Rc
            x[c] = M.translation + Rc @ off
            w, lin = tw.angular, tw.linear
            W[c] = w
            # the centre's velocity in the joint frame, lin + w x off (written out: np.cross
            # costs ~10 us on 3-vectors, the same products here well under one)
            u = (
                lin[0] + (w[1] * off[2] - w[2] * off[1]),
                lin[1] + (w[2] * off[0] - w[0] * off[2]),
                lin[2] + (w[0] * off[1] - w[1] * off[0]),
            )
            vv[c] = Rc @ u
        return x, R, vv, W

    # -- dynamics ----------------------------------------------------------------------------
    def accel(self, q, v):
        pin = self.pin
        tau = self.tau
        if self.loads is not None:  # the force elements' generalised force (forces.py)
            tau = tau + forces.generalized(self, q, v)
        t0 = time.perf_counter()
        if self.constraints:
            a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.cmodels,
                                       self.cdatas, self.prox)  # fmt: skip
        else:
            a = pin.aba(self.model, self.data, q, v, tau)
        self.clock += timing.lap(t0)
        return np.array(a)

    def integrate(self, q, dv):
        t0 = time.perf_counter()
        out = self.pin.integrate(self.model, q, dv)
        self.clock += timing.lap(t0)
        return out

    def dexpinv(self, q0, theta, u):
        t0 = time.perf_counter()
        J = self.pin.dIntegrate(self.model, q0, theta, self.pin.ArgumentPosition.ARG1)
        self.clock += timing.lap(t0)
        return np.linalg.solve(J, u)

    def normalize(self, q):
        t0 = time.perf_counter()
        out = self.pin.normalize(self.model, q)
        self.clock += timing.lap(t0)
        return out

    def step_euler(self, q, v, h):
        v = v + h * self.accel(q, v)
        return self.normalize(self.integrate(q, h * v)), v

    def step_rkmk4(self, q, v, h):
        """One RKMK4 step on Pinocchio's configuration group (module docstring)."""
        k1t, k1v = v, self.accel(q, v)
        th = 0.5 * h * k1t
        v2 = v + 0.5 * h * k1v
        k2t, k2v = self.dexpinv(q, th, v2), self.accel(self.integrate(q, th), v2)
        th = 0.5 * h * k2t
        v3 = v + 0.5 * h * k2v
        k3t, k3v = self.dexpinv(q, th, v3), self.accel(self.integrate(q, th), v3)
        th = h * k3t
        v4 = v + h * k3v
        k4t, k4v = self.dexpinv(q, th, v4), self.accel(self.integrate(q, th), v4)
        theta = (h / 6.0) * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
        v_new = v + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        return self.normalize(self.integrate(q, theta)), v_new


def read_back(pm: _Model, scenario, gains, prox) -> None:
    """Compare Pinocchio's model with the scenario (masses, inertias about the COM in principal
    axes, joint kinds, parents, distorting defaults, gravity, constraint gains and points)."""
    pin, pl, model = pm.pin, pm.pl, pm.model
    bad = reduced.Mismatches()
    want = bad.want

    kinds = {"free": "JointModelFreeFlyer", "spherical": "JointModelSpherical",
             "revolute": "JointModelRevoluteUnaligned",
             "prismatic": "JointModelPrismaticUnaligned",
             "universal": "JointModelUniversal", "cylindrical": "JointModelComposite"}  # fmt: skip
    want("number of joints", model.njoints, len(pl.order) + 1)
    for c, jid in pm.jid.items():
        b, tj = pl.bodies[c], pl.tree[c]
        name = f"body {b.name!r} ({tj.label})"
        if model.joints[jid].shortname() != kinds[tj.kind]:
            bad.append(f"{name}: joint {model.joints[jid].shortname()}, needs {kinds[tj.kind]}")
        want(f"{name}: parent", model.parents[jid], 0 if tj.parent < 0 else pm.jid[tj.parent])
        inr = model.inertias[jid]
        want(f"{name}: mass", inr.mass, b.mass)
        # the inertia about the COM in the joint frame = principal moments (frames parallel)
        want(f"{name}: inertia about the COM", inr.inertia, np.diag(np.asarray(b.inertia, float)))
        want(f"{name}: COM in the joint frame", inr.lever, -tj.Y)
        if tj.kind == "cylindrical" and model.joints[jid].shortname() == kinds["cylindrical"]:
            comp = model.joints[jid].extract()
            parts = [j.shortname() for j in comp.joints]
            if parts != list(CYLINDRICAL_PARTS):
                bad.append(f"{name}: composite of {parts}, needs {list(CYLINDRICAL_PARTS)}")
            else:
                for k, part in enumerate(comp.joints):
                    want(f"{name}: {parts[k]} axis", part.extract().axis, pm.frames[c].axis)
                    want(f"{name}: {parts[k]} placement in the composite",
                         comp.jointPlacements[k].homogeneous, np.eye(4))  # fmt: skip
    for jid in range(1, model.njoints):
        # crba and constraintDynamics need every subtree's velocities contiguous (depth first)
        idx = sorted(i for k in model.subtrees[jid]
                     for i in range(model.idx_vs[k], model.idx_vs[k] + model.nvs[k]))  # fmt: skip
        if idx != list(range(idx[0], idx[0] + len(idx))):
            bad.append(f"joint {model.names[jid]!r}: its subtree's velocities are not contiguous "
                       f"({idx}): joints not added depth first")  # fmt: skip
    want("gravity", model.gravity.linear, pl.gravity)
    want("gravity (angular part)", model.gravity.angular, np.zeros(3))
    for what in ("damping", "armature", "friction"):
        want(f"joint {what}", getattr(model, what), np.zeros(model.nv))
    for cm in pm.constraints:
        p = cm.m_baumgarte_parameters
        want(f"{cm.name}: Baumgarte Kp, Kd", [np.ravel(p.Kp)[0], np.ravel(p.Kd)[0]], list(gains))
        if cm.type != pin.ContactType.CONTACT_3D:
            bad.append(f"{cm.name}: type {cm.type}, needs CONTACT_3D")
    bad.raise_any("pinocchio", scenario)


def _joint_world(pm: _Model):
    """The world joint points and axes (by scenario joint name) of the tree joints, and of the
    loop closures' first points from both sides, from Pinocchio's placements (data.oMi)."""
    points, axes, loops = {}, {}, {}
    for c, jid in pm.jid.items():
        tj = pm.pl.tree[c]
        if tj.kind == "free":
            continue
        name = tj.name
        M = pm.data.oMi[jid]
        points[name] = M.translation.copy()
        if tj.kind in ("prismatic", "cylindrical"):
            # the child's side moves along the axis; the parent's is the joint placement
            parent = pm.model.parents[jid]
            fixed = pm.data.oMi[parent].act(pm.model.jointPlacements[jid]).translation
            a_is_child = next(j for j in pm.pl.joints if j.name == name).body_a == pm.pl.names[c]
            child_side, parent_side = ("a", "b") if a_is_child else ("b", "a")
            points[name] = {child_side: M.translation.copy(), parent_side: fixed.copy()}
        if tj.kind in ("revolute", "prismatic"):
            axes[name] = M.rotation @ np.asarray(pm.model.joints[jid].extract().axis)
        if tj.kind == "cylindrical":  # the turn's axis (read back equal to the slide's)
            turn = pm.model.joints[jid].extract().joints[1].extract()
            axes[name] = M.rotation @ np.asarray(turn.axis)
    return points, axes, loops


def _loop_gaps(pm: _Model) -> list:
    """(name, gap m) of every closing point from Pinocchio's placements: joint1 and joint2
    placements mapped to the world."""
    out = []
    for cm in pm.constraints:
        p1 = pm.data.oMi[cm.joint1_id].act(cm.joint1_placement).translation
        p2 = pm.data.oMi[cm.joint2_id].act(cm.joint2_placement).translation
        out.append((cm.name, float(np.linalg.norm(p1 - p2))))
    return out


def frequency_scale(pl: reduced.Plan) -> float:
    """max(sqrt(|g| / L), V / L), rad/s: the fastest rate gravity or the initial motion sets."""
    return max(math.sqrt(float(np.linalg.norm(pl.gravity)) / pl.length), pl.rate / pl.length)


def _settings(kw: dict, pl: reduced.Plan):
    reduced.check_settings("pinocchio", kw)
    fs = frequency_scale(pl)
    omega = float(kw.get("baumgarte_omega", BAUMGARTE_FACTOR * fs))
    if not (math.isfinite(omega) and omega >= 0):
        raise ValueError(f"baumgarte_omega {omega!r}: a finite number >= 0 (rad/s)")
    gains = tuple(float(g) for g in kw.get("baumgarte", (omega**2, 2.0 * omega)))
    if len(gains) != 2 or not all(math.isfinite(g) and g >= 0 for g in gains):
        raise ValueError(f"baumgarte {gains}: (Kp 1/s^2, Kd 1/s), finite and >= 0")
    prox = tuple(kw.get("prox", PROX))
    if len(prox) != 3 or not (prox[0] > 0 and prox[1] >= 0 and int(prox[2]) >= 1):
        raise ValueError(f"prox {prox}: (accuracy > 0, mu >= 0, max_iter >= 1)")
    rule = (
        "given"
        if "baumgarte" in kw
        else f"critical, omega = {omega:.6g} rad/s"
        + ("" if "baumgarte_omega" in kw else f" ({BAUMGARTE_FACTOR:g} x {fs:.6g} rad/s)")
    )
    return gains, prox, rule


#: why Pinocchio closes no loop of these kinds (its constraint models, pinocchio 4.1:
#: RigidConstraintModel CONTACT_3D / CONTACT_6D, PointAnchorConstraintModel,
#: FrameAnchorConstraintModel, JointLimitConstraintModel, JointFrictionConstraintModel)
REFUSED_CLOSURES = {
    "universal": "Pinocchio's constraint models hold a point (CONTACT_3D, "
    "PointAnchorConstraintModel: 3 equations), a whole placement (CONTACT_6D, "
    "FrameAnchorConstraintModel: 6) or one joint's coordinate (limits, friction); a universal "
    "closure holds 4 (a point and the axes' right angle): one point holds 3, two points 5 (a "
    "hinge), and Pinocchio has no distance or axis constraint",
    **dict.fromkeys(
        ("prismatic", "cylindrical"),
        "Pinocchio's constraint models hold a point (CONTACT_3D, PointAnchorConstraintModel), "
        "a whole placement (CONTACT_6D, FrameAnchorConstraintModel) or one joint's coordinate "
        "(limits, friction); every one of them holds the relative translation at its point, "
        "and a sliding closure leaves one free",
    ),
}


def build(scenario, integrator: str, dt: float, **settings):
    """(_Model, q0, v0, settings record) of ``scenario``: planned, built, read back, with the
    initial state checked against Pinocchio's kinematics."""
    reduced.check_run_args(integrator, dt, INTEGRATORS)
    pin = _import()
    pl = reduced.plan(scenario, "pinocchio", TREE_KINDS, refused=REFUSED_CLOSURES)
    gains, prox, gain_rule = _settings(settings, pl)
    pm = _Model(pin, pl, float(dt), gains, prox)
    read_back(pm, scenario, gains, prox)
    q, v = pm.initial()
    x, R, vv, W = pm.states(q, v)
    points, axes, _ = _joint_world(pm)
    reduced.check_states("pinocchio", pl, x, R, vv, W, points, axes)
    pin.forwardKinematics(pm.model, pm.data, q)
    gaps = [(n, g) for n, g in _loop_gaps(pm) if not g <= reduced.CHECK_TOL * pl.length]
    if gaps:
        raise EngineError(f"pinocchio: system {scenario.name!r}: loop-closure points apart at "
                          f"t = 0 (a wrong placement): {gaps}")  # fmt: skip
    if has_elements(scenario):
        pm.loads = scenario
        pm.loaded = forces.loaded(pm)
        forces.check(pm, q, v)
    rec = {
        "engine": f"pinocchio {pin.__version__}",
        "integrator": integrator,
        "time stepping": "ours (Pinocchio has none): "
        + (
            "v += h a; q = integrate(q, h v); normalize(q)"
            if integrator != "RKMK4"
            else "the suite's RKMK4 on Pinocchio's configuration group (integrate, dIntegrate)"
        ),
        "dt": float(dt),
        "gravity": pl.gravity.tolist(),
        "tree": reduced.tree_record(pl),
        "frames": "each joint frame parallel to its body's principal frame, at its anchor",
        "damping, armature, friction": "0 (defaults, read back)",
        "forward dynamics": "constraintDynamics" if pm.constraints else "aba",
    }
    cylinders = [pl.tree[c].name for c in pl.order if pl.tree[c].kind == "cylindrical"]
    if cylinders:
        rec["cylindrical joints"] = [
            f"{name}: JointModelComposite (PrismaticUnaligned, then RevoluteUnaligned on the "
            "same axis)"
            for name in cylinders
        ]
    if pm.loads is not None:
        rec["force elements"] = forces.record(scenario, integrator)
    if pm.constraints:
        rec["loop closures"] = [f"{lp.label}: " + (
            "one CONTACT_3D at the anchors" if len(lp.pairs) == 1 else
            f"two CONTACT_3D, at the anchors and {pl.length:.6g} m along the hinge axis "
            "(6 equations for the hinge's 5)") for lp in pl.loops]  # fmt: skip
        rec["Baumgarte (Kp, Kd)"] = list(gains)
        rec["Baumgarte rule"] = gain_rule
        rec["proximal (accuracy, mu, max_iter)"] = [float(prox[0]), float(prox[1]), int(prox[2])]
        rec["constraint frame"] = "LOCAL"
    return pm, q, v, rec


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` (module docstring) on Pinocchio.

    ``integrator``: "semi-implicit Euler" or "RKMK4"; ``dt`` s; ``nstep`` steps saved at 0, s,
    2s, ..., nstep; ``settings``: ``baumgarte`` (Kp 1/s^2, Kd 1/s) or ``baumgarte_omega``
    (rad/s, Kp = omega^2, Kd = 2 omega; default: module docstring), ``prox`` (accuracy, mu,
    max_iter) of constraintDynamics; used only when the scenario closes a loop.

    Returns a :class:`~references.engines.system.SystemResult`: ``t`` (n,) s; ``x`` (n, nb, 3) COM
    world m; ``R`` (n, nb, 3, 3) body to world; ``v`` (n, nb, 3) COM velocity world m/s; ``W`` (n,
    nb, 3) body angular velocity, body axes rad/s (scenario order); ``engine_time_s`` (inside
    Pinocchio's calls: aba/constraintDynamics, integrate, dIntegrate, normalize); ``settings``.

    Raises :class:`Unsupported` for joints or loops not built here, :class:`EngineError` for a
    read-back or initial-state mismatch, :class:`Diverged` (states up to the last good save in
    ``output``) for a non-finite state.
    """
    steps = reduced.saves(nstep, save_every)
    pm, q, v, rec = build(scenario, integrator, dt, **settings)
    step = pm.step_rkmk4 if integrator == "RKMK4" else pm.step_euler
    nb, n = len(pm.pl.bodies), len(steps)
    x, R, vv, W = reduced.state_arrays(n, nb)
    x[0], R[0], vv[0], W[0] = pm.states(q, v)
    pm.clock = 0.0
    done = 0
    h = float(dt)
    timing.stepping()  # the model is built: its construction is not the cost
    for k in range(1, n):
        for _ in range(int(steps[k] - done)):
            q, v = step(q, v, h)
        done = int(steps[k])
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise Diverged(
                f"pinocchio {integrator} at dt = {dt:g} s: a non-finite state between t = "
                f"{steps[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt)",
                done * dt,
                reduced.output(steps[:k], dt, x[:k], R[:k], vv[:k], W[:k], pm.clock, rec),
            )
        x[k], R[k], vv[k], W[k] = pm.states(q, v)
    return reduced.output(steps, dt, x, R, vv, W, pm.clock, rec)
