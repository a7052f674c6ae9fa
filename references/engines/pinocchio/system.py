"""Pinocchio builder for systems of rigid bodies: trees in Pinocchio's reduced coordinates,
loops closed by Pinocchio's ``RigidConstraintModel`` (CONTACT_3D) with ``constraintDynamics``
and a Baumgarte corrector.

Input: a system scenario with ``name``, ``gravity`` (3,), ``bodies`` and ``joints`` with the
fields of ``director_model.system.Body`` and ``Joint`` (docs of that module: anchors and axes in
each body's principal frame relative to its centre of mass, world for the ground). The spanning
tree is the scenario's (``scenario.loop_joints`` when present, else
``scenarios.system.spanning_tree``): from the ground outwards; a part joined to nothing is a
floating root (its first body in the scenario's order) on a ``JointModelFreeFlyer``.

Frames (:func:`plan` computes them once; :func:`engine_frames` turns them into what Pinocchio is
given, the builder's boundary where the tests plant mistakes). The frame of the Pinocchio joint
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
                                                  (:func:`slide_state`)
(floating root)     ``JointModelFreeFlyer``       q = [x, quaternion of R], v = [R^T v, W]
others              -                             unsupported (not built by this adapter)
==================  ============================  ==========================================

Loop closures: each closing spherical joint is one ``RigidConstraintModel(CONTACT_3D)`` between
the two anchors (LOCAL frame); a closing revolute joint is two of them, at the anchors and at the
anchors moved by the system's length scale along the hinge axis: six equations for the hinge's
five (one redundant), which ``constraintDynamics``' proximal solver accepts (its ``mu`` > 0
regularises the rank-deficient system). Pinocchio's Baumgarte gains default to 0 (read back):
without them the loop drifts open; here Kp = omega^2, Kd = 2 omega (critical damping) with
omega = ``baumgarte_omega`` (rad/s; default :data:`BAUMGARTE_FACTOR` times the system's frequency
scale max(sqrt(|g| / L), V / L), L and V its length and rate scales), or ``baumgarte=(Kp, Kd)``
given. The gains do not depend on dt, so that a sweep over dt integrates one system and shows
the integrator's order. Other closures are unsupported.

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
:data:`CHECK_TOL` relative to the length and rate scales; a mismatch raises
:class:`~references.errors.EngineError` naming the body or joint.
"""

from __future__ import annotations

import math
import time
import types
from dataclasses import dataclass, field

import numpy as np

from references import conventions as cv
from references.engines.native import import_engine
from references.errors import Diverged, EngineError, Unsupported

INTEGRATORS = ("semi-implicit Euler", "RKMK4")

#: Read-back and initial-state tolerance relative to each quantity's scale: the conversions are
#: exact up to a few operations of round-off per body along a chain.
CHECK_TOL = 1e-10

#: default Baumgarte frequency over the system's frequency scale (Kp = omega^2, Kd = 2 omega)
BAUMGARTE_FACTOR = 10.0

#: proximal settings of constraintDynamics: accuracy, mu (regularisation), iterations
PROX = (1e-12, 1e-8, 10)

_SETTINGS = ("baumgarte", "baumgarte_omega", "prox")
_TREE_KINDS = ("spherical", "fixed_point", "revolute")
#: the tree joints Pinocchio's builder (and Drake's) build
SLIDING_KINDS = (*_TREE_KINDS, "prismatic")


def _import():
    return import_engine("pinocchio", "Pinocchio", "pin")


# -- the plan: spanning tree and frames (engine-neutral: every builder of systems but the
# director's uses it) ----------------------------------------------------------------------------


@dataclass
class TreeJoint:
    """The joint that attaches body ``child`` (index) to ``parent`` (index, -1 = ground)."""

    label: str
    name: str  # the scenario joint's name ("" for a free root)
    kind: str  # "spherical" (fixed_point too), "revolute", "prismatic", "universal",
    # "cylindrical" or "free"
    child: int
    parent: int
    X: np.ndarray = field(default_factory=lambda: np.zeros(3))  # parent anchor (world: ground)
    Y: np.ndarray = field(default_factory=lambda: np.zeros(3))  # child anchor (child frame)
    axis_c: np.ndarray | None = None  # hinge or slide axis, child frame, unit
    axis_p: np.ndarray | None = None  # the same joint's axis, parent frame (world: ground), unit
    R_ref: np.ndarray = field(default_factory=lambda: np.eye(3))  # child in parent at q = 0


@dataclass
class Loop:
    """A closing joint between bodies a and b (b = -1: the ground) as point pairs (point in
    a's principal frame, point in b's principal frame or world)."""

    label: str
    kind: str
    a: int
    b: int
    pairs: list


@dataclass
class Plan:
    name: str  # the scenario's
    names: list
    bodies: list
    joints: list  # the scenario's joints with names filled in
    order: list  # body indices, depth first (parents first, every subtree contiguous)
    tree: dict  # child index -> TreeJoint
    loops: list
    gravity: np.ndarray
    length: float
    rate: float


def label(j) -> str:
    return f"joint {j.name!r} ({j.kind} {j.body_a!r}-{j.body_b!r})"


def vec(a, what: str) -> np.ndarray:
    v = np.asarray(a, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what}: expected 3 finite numbers, got {np.asarray(a).tolist()}")
    return v


def unit(a, what: str) -> np.ndarray:
    v = vec(a, what)
    n = float(np.linalg.norm(v))
    if not n > 0:
        raise ValueError(f"{what}: the axis {v.tolist()} has zero length")
    return v / n


def _named(joints) -> list:
    out = []
    for k, j in enumerate(joints):
        d = {f: getattr(j, f, None) for f in ("kind", "body_a", "body_b", "anchor_a",
                                               "anchor_b", "axis_a", "axis_b")}  # fmt: skip
        out.append(types.SimpleNamespace(name=getattr(j, "name", None) or f"joint{k}", **d))
    return out


def plan(scenario, engine: str, tree_kinds=_TREE_KINDS) -> Plan:
    """The spanning tree, reference orientations and loop closures of ``scenario`` (module
    docstring): the scenario's loop closures (``scenario.loop_joints``, else
    ``scenarios.system.spanning_tree``), bodies added depth first from the ground, a body
    joined to nothing a floating root. A joint with an axis has R_ref = R_p^T R_c at t = 0 and
    its axis on both sides (``axis_c``, ``axis_p``). ``ValueError`` for malformed joints,
    :class:`Unsupported` (naming ``engine``) for a kind outside ``tree_kinds`` in the tree, or
    a closure other than spherical/revolute."""
    bodies = list(scenario.bodies)
    names = [b.name for b in bodies]
    if len(set(names)) != len(names):
        raise ValueError(f"system {scenario.name!r}: body names repeat: {names}")
    idx = {n: i for i, n in enumerate(names)}
    joints = _named(scenario.joints)
    for j in joints:
        if j.body_a not in idx or (j.body_b is not None and j.body_b not in idx):
            raise ValueError(f"{label(j)}: a body is not one of {names} (None is the ground)")
        if j.body_a == j.body_b:
            raise ValueError(f"{label(j)}: joins body {j.body_a!r} to itself")
    loop_names = getattr(scenario, "loop_joints", None)
    if loop_names is None:
        from scenarios.system import spanning_tree

        loop_names = spanning_tree(bodies, joints)[1]
    loop_names = set(loop_names)
    tree_js = [j for j in joints if j.name not in loop_names]
    parent_of: dict[int, tuple] = {}
    order: list[int] = []

    def grow(start):
        queue = [start]
        while queue:
            p = queue.pop(0)
            for j in tree_js:
                if j.body_b is None:
                    continue
                a, b = idx[j.body_a], idx[j.body_b]
                if p in (a, b):
                    c = b if a == p else a
                    if c not in parent_of:
                        parent_of[c] = (p, j)
                        order.append(c)
                        queue.append(c)

    for j in tree_js:
        if j.body_b is None:
            a = idx[j.body_a]
            parent_of[a] = (-1, j)
            order.append(a)
    for c in list(order):
        grow(c)
    for i in range(len(bodies)):
        if i not in parent_of:
            parent_of[i] = (-1, None)
            order.append(i)
            grow(i)
    # depth first, parents first, children in the order reached: every subtree is contiguous
    # (Pinocchio's crba and constraintDynamics need it; aba does not, docs/engines.md)
    children: dict[int, list] = {i: [] for i in range(-1, len(bodies))}
    for c in order:
        children[parent_of[c][0]].append(c)
    order = []
    stack = list(reversed(children[-1]))
    while stack:
        c = stack.pop()
        order.append(c)
        stack.extend(reversed(children[c]))

    R = [np.asarray(b.rotation, dtype=float) for b in bodies]
    anchors = [np.zeros(3)]
    for j in joints:
        anchors.append(vec(j.anchor_a, f"{label(j)}: anchor_a"))
        if j.body_b is not None:
            anchors.append(vec(j.anchor_b, f"{label(j)}: anchor_b"))
    length = max(float(np.max(np.linalg.norm(anchors, axis=1))), 1e-3)
    rate = max(
        1.0,
        max(float(np.max(np.abs(b.omega_body))) for b in bodies) * length,
        max(float(np.max(np.abs(b.velocity))) for b in bodies),
    )
    tree = {}
    for c in order:
        p, j = parent_of[c]
        if j is None:
            tree[c] = TreeJoint(f"free root {names[c]!r}", "", "free", c, -1, R_ref=R[c])
            continue
        what = label(j)
        if j.kind not in tree_kinds:
            raise Unsupported(
                f"{engine}: {what}: a {j.kind} joint in a tree is not built by this adapter "
                f"(built: {', '.join(tree_kinds)})"
            )
        child_is_a = idx[j.body_a] == c
        Y, X = (j.anchor_a, j.anchor_b) if child_is_a else (j.anchor_b, j.anchor_a)
        kind = "spherical" if j.kind == "fixed_point" else j.kind
        tj = TreeJoint(what, j.name, kind, c, p, vec(X, what), vec(Y, what))
        if kind != "spherical":
            ax, axp = (j.axis_a, j.axis_b) if child_is_a else (j.axis_b, j.axis_a)
            if ax is None or axp is None:
                raise ValueError(f"{what}: a {kind} joint needs axis_a and axis_b")
            tj.axis_c = unit(ax, f"{what}: the child's axis")
            tj.axis_p = unit(axp, f"{what}: the parent's axis")
            tj.R_ref = (np.eye(3) if p < 0 else R[p]).T @ R[c]
        tree[c] = tj
    loops = []
    for j in joints:
        if j.name not in loop_names:
            continue
        what = label(j)
        a = idx[j.body_a]
        b = -1 if j.body_b is None else idx[j.body_b]
        Xa, Xb = vec(j.anchor_a, what), vec(j.anchor_b, what)
        if j.kind in ("spherical", "fixed_point"):
            loops.append(Loop(what, j.kind, a, b, [(Xa, Xb)]))
        elif j.kind == "revolute":
            if j.axis_a is None or j.axis_b is None:
                raise ValueError(f"{what}: a revolute joint needs axis_a and axis_b")
            na, nb = unit(j.axis_a, what), unit(j.axis_b, what)
            Rb = np.eye(3) if b < 0 else R[b]
            if float((R[a] @ na) @ (Rb @ nb)) < 0:
                nb = -nb  # antiparallel axes describe the same hinge
            loops.append(Loop(what, j.kind, a, b, [(Xa, Xb), (Xa + length * na, Xb + length * nb)]))
        else:
            raise Unsupported(
                f"{engine}: {what} closes a loop; this adapter closes spherical and revolute "
                f"loops with point constraints, a {j.kind} closure is not built"
            )
    return Plan(
        str(scenario.name),
        names,
        bodies,
        joints,
        order,
        tree,
        loops,
        vec(scenario.gravity, "gravity"),
        length,
        rate,
    )


def world(pl: Plan, i: int):
    """(x, R, v, w_world) of body i at t = 0, or the ground's for i = -1."""
    if i < 0:
        return np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3)
    b = pl.bodies[i]
    R = np.asarray(b.rotation, dtype=float)
    return (np.asarray(b.position, float), R, np.asarray(b.velocity, float),
            R @ np.asarray(b.omega_body, float))  # fmt: skip


def relative_state(pl: Plan, tj: TreeJoint):
    """The tree joint's initial coordinates: (R_rel = R_p^T R_c, W_rel in child axes)."""
    _, Rc, _, wc = world(pl, tj.child)
    _, Rp, _, wp = world(pl, tj.parent)
    return Rp.T @ Rc, Rc.T @ (wc - wp)


def slide_state(pl: Plan, tj: TreeJoint) -> tuple[float, float]:
    """A prismatic tree joint's initial coordinate and rate: the offset (m) of the child's
    anchor from the parent's along the axis u (world), and its rate (m/s) seen from the
    parent, (v_c - v_p - w_p x (x_c - x_p)) . u (the child turns with the parent)."""
    xc, Rc, vc, _ = world(pl, tj.child)
    xp, Rp, vp, wp = world(pl, tj.parent)
    u = Rc @ tj.axis_c
    d0 = float((xc + Rc @ tj.Y - xp - Rp @ tj.X) @ u)
    return d0, float((vc - vp - np.cross(wp, xc - xp)) @ u)


def check_states(engine: str, pl: Plan, x, R, v, W, joint_points, joint_axes) -> None:
    """Compare an engine's kinematics of the initial state with the scenario: every body's
    (x, R, v, W) (arrays in scenario order), and for every scenario joint the engine's joint
    point ``joint_points[name]`` against the anchor from both sides (or, for a joint whose
    two sides may part along an axis, a dict {"a": point, "b": point} of the engine's point
    on each side), and ``joint_axes[name]`` (world) against both sides' axes. Raises
    :class:`EngineError` naming what differs."""
    bad = []
    L, V = pl.length, pl.rate
    for c, b in enumerate(pl.bodies):
        for what, got, exp, sc in (
            ("COM position", x[c], b.position, L),
            ("rotation", R[c], b.rotation, 1.0),
            ("COM velocity", v[c], b.velocity, V),
            ("body angular velocity", W[c], b.omega_body, V / L),
        ):
            err = float(np.max(np.abs(np.asarray(got) - np.asarray(exp, float)))) / sc
            if not err <= CHECK_TOL:
                bad.append(f"body {b.name!r}: {what} off by {err:.3g} (relative)")
    idx = {n: i for i, n in enumerate(pl.names)}
    for j in pl.joints:
        xa, Ra, _, _ = world(pl, idx[j.body_a])
        xb, Rb, _, _ = world(pl, -1 if j.body_b is None else idx[j.body_b])
        if j.name in joint_points:
            got = joint_points[j.name]
            for side, exp in (("a", xa + Ra @ vec(j.anchor_a, "anchor_a")),
                              ("b", xb + Rb @ vec(j.anchor_b, "anchor_b"))):  # fmt: skip
                p = np.asarray(got[side] if isinstance(got, dict) else got)
                err = float(np.max(np.abs(p - exp))) / L
                if not err <= CHECK_TOL:
                    bad.append(f"{label(j)}: the engine's joint point vs anchor_{side} off by "
                               f"{err:.3g} (relative to {L:.3g} m)")  # fmt: skip
        if j.name in joint_axes:
            u = np.asarray(joint_axes[j.name])
            for side, exp in (("a", Ra @ unit(j.axis_a, "axis_a")),
                              ("b", Rb @ unit(j.axis_b, "axis_b"))):  # fmt: skip
                err = float(np.linalg.norm(np.cross(u, exp)))
                if not err <= CHECK_TOL:
                    bad.append(f"{label(j)}: the engine's axis vs axis_{side} off by {err:.3g} rad")
    if bad:
        raise EngineError(
            f"{engine}: system {pl.name!r}: the engine's kinematics of the initial state differ "
            "from the scenario (a frame, anchor, axis or parent/child is wrong): " + "; ".join(bad)
        )


class Mismatches(list):
    """The messages of a builder's read-back: each difference between the engine's model and
    the scenario (a list; :meth:`want` compares values, anything else is appended)."""

    def want(self, what: str, got, exp, tol: float = CHECK_TOL) -> None:
        """Record ``what`` when ``got`` (read from the engine) and ``exp`` (the scenario's
        value) differ in shape or by more than ``tol`` relative to max(1, max |exp|)."""
        got, exp = np.asarray(got, float), np.asarray(exp, float)
        scale = max(1.0, float(np.max(np.abs(exp))) if exp.size else 1.0)
        if got.shape != exp.shape or not np.all(np.abs(got - exp) <= tol * scale):
            self.append(f"{what}: {np.round(got, 12).tolist()}, expected "
                        f"{np.round(exp, 12).tolist()}")  # fmt: skip

    def raise_any(self, engine: str, scenario, model: str = "model") -> None:
        """Raise :class:`EngineError` listing every mismatch, if there is one."""
        if self:
            raise EngineError(
                f"{engine}: system {scenario.name!r}: the {model} differs from the scenario: "
                + "; ".join(self)
            )


def state_arrays(*lead: int) -> tuple:
    """Empty (x, R, v, W) of shapes (*lead, 3), (*lead, 3, 3), (*lead, 3), (*lead, 3): one
    state per body (``lead`` = (nb,)) or a run's saved states (``lead`` = (n, nb))."""
    return np.empty((*lead, 3)), np.empty((*lead, 3, 3)), np.empty((*lead, 3)), np.empty((*lead, 3))


def saves(nstep: int, save_every: int) -> np.ndarray:
    """Saved step indices 0, s, 2s, ..., nstep (always the last)."""
    if not (isinstance(nstep, (int, np.integer)) and nstep >= 0):
        raise ValueError(f"nstep {nstep!r}: must be an integer >= 0")
    if not (isinstance(save_every, (int, np.integer)) and save_every >= 1):
        raise ValueError(f"save_every {save_every!r}: must be an integer >= 1")
    s = list(range(0, nstep + 1, save_every))
    if s[-1] != nstep:
        s.append(nstep)
    return np.array(s)


def output(steps, dt, x, R, v, W, engine_time, rec) -> dict:
    return {
        "t": np.asarray(steps, float) * float(dt),
        "x": x,
        "R": R,
        "v": v,
        "W": W,
        "engine_time_s": float(engine_time),
        "evals_per_step": 4.0 if rec.get("integrator") == "RKMK4" else 1.0,
        "settings": rec,
    }


def tree_record(pl: Plan, kind=lambda tj: tj.kind) -> dict:
    """The settings record's ``tree``: each body's name -> "<kind> to ground" or "<kind> to
    'parent'", in the plan's order (``kind``: the name the engine gives a tree joint)."""
    return {
        pl.names[c]: f"{kind(pl.tree[c])} to "
        + ("ground" if pl.tree[c].parent < 0 else repr(pl.names[pl.tree[c].parent]))
        for c in pl.order
    }


def check_settings(engine: str, settings, known) -> None:
    """Refuse a setting the builder of ``engine`` does not know: ValueError naming the unknown
    ones and the ``known`` ones."""
    unknown = sorted(set(settings) - set(known))
    if unknown:
        raise ValueError(f"{engine} simulate_system: unknown settings {unknown}; known: "
                         f"{list(known) or 'none'}")  # fmt: skip


def check_run_args(integrator: str, dt, integrators=INTEGRATORS) -> None:
    if integrator not in integrators:
        raise ValueError(f"integrator {integrator!r} unknown; known: {list(integrators)}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt {dt!r}: must be a finite number > 0 (s)")


# -- Pinocchio model --------------------------------------------------------------------------


@dataclass
class EngineFrames:
    """What Pinocchio is given for one tree joint: its kind, the joint placement in the
    parent's joint frame (R, p), the hinge or slide axis in the joint frame, and the body's
    principal frame in the joint frame (a translation: the frames are parallel)."""

    kind: str
    R: np.ndarray
    p: np.ndarray
    axis: np.ndarray | None
    body_offset: np.ndarray


def engine_frames(pl: Plan, c: int) -> EngineFrames:
    """The builder's boundary: the frames of body c's joint from the plan (module docstring)."""
    tj = pl.tree[c]
    if tj.kind == "free":
        return EngineFrames("free", np.eye(3), np.zeros(3), None, np.zeros(3))
    Yp = np.zeros(3) if tj.parent < 0 else pl.tree[tj.parent].Y
    return EngineFrames(tj.kind, tj.R_ref, tj.X - Yp, tj.axis_c, -tj.Y)


class _Model:
    """Pinocchio's model and data, joint ids, the constraints and the state."""

    def __init__(self, pin, pl: Plan, dt: float, gains, prox):
        self.pin, self.pl = pin, pl
        model = pin.Model()
        self.jid: dict[int, int] = {}
        self.frames: dict[int, EngineFrames] = {}
        for c in pl.order:
            f = engine_frames(pl, c)
            tj = pl.tree[c]
            if f.kind == "free":
                jm = pin.JointModelFreeFlyer()
            elif f.kind == "spherical":
                jm = pin.JointModelSpherical()
            elif f.kind == "prismatic":
                jm = pin.JointModelPrismaticUnaligned(*f.axis)
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

    # -- initial state -----------------------------------------------------------------------
    def initial(self):
        pl, model = self.pl, self.model
        q, v = np.zeros(model.nq), np.zeros(model.nv)
        for c in pl.order:
            jm = model.joints[self.jid[c]]
            qa, va = jm.idx_q, jm.idx_v
            tj = pl.tree[c]
            x, R, vG, w = world(pl, c)
            if tj.kind == "free":
                qq, vv = cv.pinocchio_freeflyer_from_state(x, vG, R, R.T @ w)
            elif tj.kind == "spherical":
                Rrel, Wrel = relative_state(pl, tj)
                qq, vv = cv.pinocchio_spherical_from_state(Rrel, Wrel)
            elif tj.kind == "prismatic":
                d0, rate = slide_state(pl, tj)
                qq, vv = [d0], [rate]
            else:
                _, Wrel = relative_state(pl, tj)
                qq, vv = [0.0], [float(tj.axis_c @ Wrel)]
            q[qa : qa + len(qq)] = qq
            v[va : va + len(vv)] = vv
        return q, v

    # -- read-out ----------------------------------------------------------------------------
    def states(self, q, v):
        """(x, R, v, W) per body (scenario order) from Pinocchio's forward kinematics."""
        pin = self.pin
        pin.forwardKinematics(self.model, self.data, q, v)
        x, R, vv, W = state_arrays(len(self.pl.bodies))
        for c, jid in self.jid.items():
            M, tw = self.data.oMi[jid], self.data.v[jid]
            Rc, off = M.rotation, self.frames[c].body_offset
            R[c] = Rc
            x[c] = M.translation + Rc @ off
            W[c] = tw.angular
            vv[c] = Rc @ (tw.linear + np.cross(tw.angular, off))
        return x, R, vv, W

    # -- dynamics ----------------------------------------------------------------------------
    def accel(self, q, v):
        pin = self.pin
        t0 = time.perf_counter()
        if self.constraints:
            a = pin.constraintDynamics(self.model, self.data, q, v, self.tau, self.cmodels,
                                       self.cdatas, self.prox)  # fmt: skip
        else:
            a = pin.aba(self.model, self.data, q, v, self.tau)
        self.clock += time.perf_counter() - t0
        return np.array(a)

    def integrate(self, q, dv):
        t0 = time.perf_counter()
        out = self.pin.integrate(self.model, q, dv)
        self.clock += time.perf_counter() - t0
        return out

    def dexpinv(self, q0, theta, u):
        t0 = time.perf_counter()
        J = self.pin.dIntegrate(self.model, q0, theta, self.pin.ArgumentPosition.ARG1)
        self.clock += time.perf_counter() - t0
        return np.linalg.solve(J, u)

    def normalize(self, q):
        t0 = time.perf_counter()
        out = self.pin.normalize(self.model, q)
        self.clock += time.perf_counter() - t0
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
    bad = Mismatches()
    want = bad.want

    kinds = {"free": "JointModelFreeFlyer", "spherical": "JointModelSpherical",
             "revolute": "JointModelRevoluteUnaligned",
             "prismatic": "JointModelPrismaticUnaligned"}  # fmt: skip
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
        if tj.kind == "prismatic":
            # the child's side moves along the axis; the parent's is the joint placement
            parent = pm.model.parents[jid]
            fixed = pm.data.oMi[parent].act(pm.model.jointPlacements[jid]).translation
            a_is_child = next(j for j in pm.pl.joints if j.name == name).body_a == pm.pl.names[c]
            child_side, parent_side = ("a", "b") if a_is_child else ("b", "a")
            points[name] = {child_side: M.translation.copy(), parent_side: fixed.copy()}
        if tj.kind in ("revolute", "prismatic"):
            axes[name] = M.rotation @ np.asarray(pm.model.joints[jid].extract().axis)
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


def frequency_scale(pl: Plan) -> float:
    """max(sqrt(|g| / L), V / L), rad/s: the fastest rate gravity or the initial motion sets."""
    return max(math.sqrt(float(np.linalg.norm(pl.gravity)) / pl.length), pl.rate / pl.length)


def _settings(kw: dict, pl: Plan):
    check_settings("pinocchio", kw, _SETTINGS)
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


def build(scenario, integrator: str, dt: float, **settings):
    """(_Model, q0, v0, settings record) of ``scenario``: planned, built, read back, with the
    initial state checked against Pinocchio's kinematics."""
    check_run_args(integrator, dt)
    pin = _import()
    pl = plan(scenario, "pinocchio", SLIDING_KINDS)
    gains, prox, gain_rule = _settings(settings, pl)
    pm = _Model(pin, pl, float(dt), gains, prox)
    read_back(pm, scenario, gains, prox)
    q, v = pm.initial()
    x, R, vv, W = pm.states(q, v)
    points, axes, _ = _joint_world(pm)
    check_states("pinocchio", pl, x, R, vv, W, points, axes)
    pin.forwardKinematics(pm.model, pm.data, q)
    gaps = [(n, g) for n, g in _loop_gaps(pm) if not g <= CHECK_TOL * pl.length]
    if gaps:
        raise EngineError(f"pinocchio: system {scenario.name!r}: loop-closure points apart at "
                          f"t = 0 (a wrong placement): {gaps}")  # fmt: skip
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
        "tree": tree_record(pl),
        "frames": "each joint frame parallel to its body's principal frame, at its anchor",
        "damping, armature, friction": "0 (defaults, read back)",
        "forward dynamics": "constraintDynamics" if pm.constraints else "aba",
    }
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
                    **settings) -> dict:  # fmt: skip
    """Run ``scenario`` (module docstring) on Pinocchio.

    ``integrator``: "semi-implicit Euler" or "RKMK4"; ``dt`` s; ``nstep`` steps saved at 0, s,
    2s, ..., nstep; ``settings``: ``baumgarte`` (Kp 1/s^2, Kd 1/s) or ``baumgarte_omega``
    (rad/s, Kp = omega^2, Kd = 2 omega; default: module docstring), ``prox`` (accuracy, mu,
    max_iter) of constraintDynamics; used only when the scenario closes a loop.

    Returns a dict: ``t`` (n,) s; ``x`` (n, nb, 3) COM world m; ``R`` (n, nb, 3, 3) body to
    world; ``v`` (n, nb, 3) COM velocity world m/s; ``W`` (n, nb, 3) body angular velocity,
    body axes rad/s (scenario order); ``engine_time_s`` (inside Pinocchio's calls:
    aba/constraintDynamics, integrate, dIntegrate, normalize); ``settings``.

    Raises :class:`Unsupported` for joints or loops not built here, :class:`EngineError` for a
    read-back or initial-state mismatch, :class:`Diverged` (states up to the last good save in
    ``output``) for a non-finite state.
    """
    steps = saves(nstep, save_every)
    pm, q, v, rec = build(scenario, integrator, dt, **settings)
    step = pm.step_rkmk4 if integrator == "RKMK4" else pm.step_euler
    nb, n = len(pm.pl.bodies), len(steps)
    x, R, vv, W = state_arrays(n, nb)
    x[0], R[0], vv[0], W[0] = pm.states(q, v)
    pm.clock = 0.0
    done = 0
    h = float(dt)
    for k in range(1, n):
        for _ in range(int(steps[k] - done)):
            q, v = step(q, v, h)
        done = int(steps[k])
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise Diverged(
                f"pinocchio {integrator} at dt = {dt:g} s: a non-finite state between t = "
                f"{steps[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt)",
                done * dt,
                output(steps[:k], dt, x[:k], R[:k], vv[:k], W[:k], pm.clock, rec),
            )
        x[k], R[k], vv[k], W[k] = pm.states(q, v)
    return output(steps, dt, x, R, vv, W, pm.clock, rec)
