"""The kit of the reduced-coordinate system builders (Pinocchio, MuJoCo, MJX, DART, PyBullet,
Drake): what each of them does the same way before and after it talks to its engine.

- The plan (:func:`plan`): the scenario's spanning tree (:func:`scenarios.tree.spanning_tree`,
  the one walk of a system's joints: from the ground outwards, a part joined to nothing a
  floating root on its first body in the scenario's order), the bodies depth first (parents
  first, every subtree contiguous), each tree joint's anchors, axes and reference orientation
  (:class:`TreeJoint`), the loop closures as point pairs (:class:`Loop`), and the system's
  length and rate scales.
- The frames of the builders whose joint frame is parallel to the child's principal frame at
  its anchor (Pinocchio, DART, PyBullet): :func:`engine_frames`, the builders' boundary where the
  conformance kit plants its mistakes (:mod:`references.engines.system_conformance`).
- The checks every builder makes before stepping: the engine's kinematics of the initial state
  against the scenario (:func:`check_states`), its model read back (:class:`Mismatches`), the
  run's arguments and settings (:func:`check_run_args`, :func:`check_settings`).
- The run's saved steps and its result (:func:`saves`, :func:`state_arrays`, :func:`output`,
  :func:`tree_record`), in the form :mod:`references.engines.system` reads.

Anchors and axes are in each body's principal frame relative to its centre of mass (world for
the ground), as in ``director_model.system.Body`` and ``Joint``.
"""

from __future__ import annotations

import math
import types
from dataclasses import dataclass, field

import numpy as np

from references.engines.system import SystemResult
from references.engines.system import check_settings as check_settings  # for the builders
from references.errors import EngineError, Unsupported
from scenarios.tree import spanning_tree

#: Read-back and initial-state tolerance relative to each quantity's scale: the conversions are
#: exact up to a few operations of round-off per body along a chain.
CHECK_TOL = 1e-10

_TREE_KINDS = ("spherical", "fixed_point", "revolute")
#: the closures every reduced-coordinate builder makes of point constraints
POINT_CLOSURES = ("spherical", "fixed_point", "revolute")
#: a universal closure as a point and a distance: the point pair at the anchors and the points
#: one length scale L along each axis held L sqrt(2) apart (|L u_a - L u_b|^2 = 2 L^2 (1 -
#: u_a . u_b): the distance holds the axes perpendicular), for engines with a distance
#: constraint (MuJoCo: a tendon's length, Drake: AddDistanceConstraint)
DISTANCE_CLOSURES = (*POINT_CLOSURES, "universal")
#: the tree joints Pinocchio's builder (and Drake's) build
SLIDING_KINDS = (*_TREE_KINDS, "prismatic")
#: the mass (kg) and each principal moment (kg m^2) of the body a joint the engine lacks is
#: composed through (PyBullet's universal cross; DART's, PyBullet's and Drake's cylindrical
#: sleeve): none, so the composition is the joint. The builders hand this value to the engine
#: and read back 0 (the tests plant a mass here)
COMPOSED_MASS = 0.0

#: closures that leave a translation along their axis free, as a plan holds them: the point pair
#: at the anchors and the pair one length scale L along the axes (a revolute closure's form; the
#: engine's constraint frees the motion along the axis, and for a cylindrical the turn about
#: it), the engines' own constraints (DART CylindricalJointConstraint, PyBullet JOINT_PRISMATIC)
SLIDING_CLOSURES = ("cylindrical", "prismatic")


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
    """A closing joint between bodies a and b (b = -1: the ground) as point pairs that must
    coincide (point in a's principal frame, point in b's principal frame or world) and, for a
    universal closure, ``distances``: (point on a, point on b, the distance held, m)."""

    label: str
    kind: str
    a: int
    b: int
    pairs: list
    distances: list = field(default_factory=list)
    joint: str = ""  # the scenario joint's name


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


def composed_name(pl: Plan, tj: TreeJoint, part: str) -> str:
    """The name of the massless body a composed joint goes through, ``<joint>_<part>``
    (``part``: "cross", "sleeve"); ``ValueError`` naming the joint when a scenario body has
    that name (the engine would refuse or rename it)."""
    name = f"{tj.name}_{part}"
    if name in pl.names:
        raise ValueError(
            f"{tj.label}: its massless {part} is named {name!r}, the name of a body of the "
            "scenario: rename that body or the joint"
        )
    return name


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


def plan(scenario, engine: str, tree_kinds=_TREE_KINDS, closures=POINT_CLOSURES,
         refused=None, tree_refused=None) -> Plan:  # fmt: skip
    """The spanning tree, reference orientations and loop closures of ``scenario`` (module
    docstring): the spanning tree and loop closures of :func:`scenarios.tree.spanning_tree`,
    bodies added depth first from the ground, a body joined to nothing a floating root. A joint
    with an axis has R_ref = R_p^T R_c at t = 0 and its axis on both sides (``axis_c``,
    ``axis_p``). ``ValueError`` for malformed joints, :class:`Unsupported` (naming ``engine``)
    for a kind outside ``tree_kinds`` in the tree, or a closure outside ``closures``
    (:data:`POINT_CLOSURES`, :data:`DISTANCE_CLOSURES`), with the engine's reason
    ``refused[kind]`` (a closure) or ``tree_refused[kind]`` (a tree joint) where it gives one."""
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
    st = spanning_tree(bodies, joints)
    loop_names = {joints[k].name for k in st.loops}
    # depth first, parents first, children in the order reached: every subtree is contiguous
    # (Pinocchio's crba and constraintDynamics need it; aba does not, docs/engines.md)
    parent_of: dict[int, tuple] = {}
    for c in st.order:
        p, k = st.parent[c]
        parent_of[idx[c]] = (-1 if p is None else idx[p], None if k is None else joints[k])
    order = []
    stack = list(reversed(st.children[None]))
    while stack:
        c = stack.pop()
        order.append(idx[c])
        stack.extend(reversed(st.children[c]))

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
            why = (tree_refused or {}).get(j.kind, "not built by this adapter")
            raise Unsupported(
                f"{engine}: {what}: a {j.kind} joint in a tree: {why} "
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
            loops.append(Loop(what, j.kind, a, b, [(Xa, Xb)], joint=j.name))
        elif j.kind not in closures:
            why = (refused or {}).get(j.kind, "not built by this adapter")
            raise Unsupported(f"{engine}: {what} closes a loop: a {j.kind} closure: {why}")
        elif j.kind == "universal":
            if j.axis_a is None or j.axis_b is None:
                raise ValueError(f"{what}: a universal joint needs axis_a and axis_b")
            na, nb = unit(j.axis_a, what), unit(j.axis_b, what)
            loops.append(Loop(what, j.kind, a, b, [(Xa, Xb)],
                              [(Xa + length * na, Xb + length * nb, length * math.sqrt(2.0))],
                              joint=j.name))  # fmt: skip
        elif j.kind in ("revolute", *SLIDING_CLOSURES):
            if j.axis_a is None or j.axis_b is None:
                raise ValueError(f"{what}: a {j.kind} joint needs axis_a and axis_b")
            na, nb = unit(j.axis_a, what), unit(j.axis_b, what)
            Rb = np.eye(3) if b < 0 else R[b]
            if float((R[a] @ na) @ (Rb @ nb)) < 0:
                nb = -nb  # antiparallel axes describe the same hinge
            loops.append(Loop(what, j.kind, a, b, [(Xa, Xb), (Xa + length * na, Xb + length * nb)],
                              joint=j.name))  # fmt: skip
        else:
            raise Unsupported(f"{engine}: {what} closes a loop: a {j.kind} closure is not built")
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


def closure_points(pl: Plan, lp: Loop) -> tuple[list, list]:
    """Where the engine's constraints of closure ``lp`` must hold the bodies at t = 0, from the
    scenario's joint in world coordinates (a second derivation of the plan's body-frame
    points): (pairs [(point on a, point on b)], distances [(point on a, point on b, m)]) in the
    order of ``lp.pairs`` and ``lp.distances``."""
    j = next(j for j in pl.joints if j.name == lp.joint)
    idx = {n: i for i, n in enumerate(pl.names)}
    xa, Ra, _, _ = world(pl, idx[j.body_a])
    xb, Rb, _, _ = world(pl, -1 if j.body_b is None else idx[j.body_b])
    pa, pb = xa + Ra @ vec(j.anchor_a, "anchor_a"), xb + Rb @ vec(j.anchor_b, "anchor_b")
    if lp.kind in SLIDING_CLOSURES:
        # the anchors may stand apart along the axis: b holds a's anchor where it meets b's line
        ub = Rb @ unit(j.axis_b, "axis_b")
        pb = pb + ((pa - pb) @ ub) * ub
    pairs, distances = [(pa, pb)], []
    if lp.kind in ("revolute", "universal", *SLIDING_CLOSURES):
        ua, ub = Ra @ unit(j.axis_a, "axis_a"), Rb @ unit(j.axis_b, "axis_b")
        if lp.kind != "universal":
            ub = ub if ua @ ub >= 0 else -ub
            pairs.append((pa + pl.length * ua, pb + pl.length * ub))
        else:
            distances.append((pa + pl.length * ua, pb + pl.length * ub,
                              pl.length * math.sqrt(2.0)))  # fmt: skip
        if lp.kind == "prismatic":
            # the turn about the axis is held too: a direction across it, the same on both
            # sides at t = 0 (the engine's pair shows where its b side takes it)
            e = across(ua)
            pairs.append((pa + pl.length * e, pb + pl.length * e))
    return pairs, distances


def across(u) -> np.ndarray:
    """A unit vector perpendicular to the unit vector ``u`` (the one nearest the world axis
    least along ``u``): the direction a prismatic closure's third pair of points follows."""
    u = np.asarray(u, float)
    e = np.cross(u, np.eye(3)[int(np.argmin(np.abs(u)))])
    return e / np.linalg.norm(e)


def check_loops(engine: str, pl: Plan, got: dict) -> None:
    """Compare the engine's loop constraints at t = 0 with the scenario's closures
    (:func:`closure_points`): ``got[lp.label]`` = (pairs, distances) as the engine holds them,
    each attachment point in world coordinates from the engine's own kinematics, each distance
    the engine's. Raises :class:`EngineError` naming the closure."""
    bad = []
    L = pl.length
    for lp in pl.loops:
        pairs, distances = got.get(lp.label, ([], []))
        exp_pairs, exp_dist = closure_points(pl, lp)
        if len(pairs) != len(exp_pairs) or len(distances) != len(exp_dist):
            bad.append(
                f"{lp.label}: {len(pairs)} point and {len(distances)} distance "
                f"constraints, the closure needs {len(exp_pairs)} and {len(exp_dist)}"
            )
            continue  # fmt: skip
        for k, (g, e) in enumerate(zip([*pairs, *distances], [*exp_pairs, *exp_dist], strict=True)):
            if g is None:  # a constraint the engine's form leaves out (recorded by the builder)
                continue
            what = f"point constraint {k}" if k < len(pairs) else f"distance {k - len(pairs)}"
            for side in (0, 1):
                err = float(np.max(np.abs(np.asarray(g[side]) - e[side]))) / L
                if not err <= CHECK_TOL:
                    bad.append(f"{lp.label}: {what}: the point on side {'ab'[side]} off by "
                               f"{err:.3g} (relative to {L:.3g} m)")  # fmt: skip
            if len(e) == 3 and not abs(float(g[2]) - e[2]) <= CHECK_TOL * L:
                bad.append(f"{lp.label}: {what} held at {float(g[2]):.12g} m, the joint needs "
                           f"{e[2]:.12g} m (axes perpendicular)")  # fmt: skip
    if bad:
        raise EngineError(
            f"{engine}: system {pl.name!r}: the engine's loop constraints at t = 0 differ from "
            "the scenario's closures (an anchor, axis or side is wrong): " + "; ".join(bad)
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
    """Saved step indices 0, s, 2s, ..., nstep (always the last): the director model's
    :func:`~director_model.saved_steps`, for arguments checked here."""
    from director_model import saved_steps

    if not (isinstance(nstep, (int, np.integer)) and nstep >= 0):
        raise ValueError(f"nstep {nstep!r}: must be an integer >= 0")
    if not (isinstance(save_every, (int, np.integer)) and save_every >= 1):
        raise ValueError(f"save_every {save_every!r}: must be an integer >= 1")
    return saved_steps(int(nstep), int(save_every))


def output(steps, dt, x, R, v, W, engine_time, rec) -> SystemResult:
    """The builder's result at the saved ``steps`` (``rec``: its settings record)."""
    return SystemResult(
        t=np.asarray(steps, float) * float(dt),
        x=x,
        R=R,
        v=v,
        W=W,
        engine_time_s=float(engine_time),
        settings=rec,
        evals_per_step=4.0 if rec.get("integrator") == "RKMK4" else 1.0,
    )


def tree_record(pl: Plan, kind=lambda tj: tj.kind) -> dict:
    """The settings record's ``tree``: each body's name -> "<kind> to ground" or "<kind> to
    'parent'", in the plan's order (``kind``: the name the engine gives a tree joint)."""
    return {
        pl.names[c]: f"{kind(pl.tree[c])} to "
        + ("ground" if pl.tree[c].parent < 0 else repr(pl.names[pl.tree[c].parent]))
        for c in pl.order
    }


def check_run_args(integrator: str, dt, integrators) -> None:
    """Refuse an integrator not in ``integrators`` and a step that is not a finite number > 0."""
    if integrator not in integrators:
        raise ValueError(f"integrator {integrator!r} unknown; known: {list(integrators)}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt {dt!r}: must be a finite number > 0 (s)")


@dataclass
class EngineFrames:
    """What an engine whose joint frame is parallel to the child's principal frame, at its
    anchor, is given for one tree joint (Pinocchio, DART, PyBullet): its kind, the joint
    placement in the parent's joint frame (R, p), the hinge or slide axis in the joint frame,
    and the body's principal frame in the joint frame (a translation: the frames are
    parallel)."""

    kind: str
    R: np.ndarray
    p: np.ndarray
    axis: np.ndarray | None
    body_offset: np.ndarray


def engine_frames(pl: Plan, c: int) -> EngineFrames:
    """The frames of body c's joint from the plan: the joint placement (R_ref, X - Y_p) in the
    parent's joint frame (X: the parent's anchor in its principal frame, Y_p its own anchor; a
    world point and no Y_p for the ground), the child's principal frame at -Y in its joint
    frame."""
    tj = pl.tree[c]
    if tj.kind == "free":
        return EngineFrames("free", np.eye(3), np.zeros(3), None, np.zeros(3))
    Yp = np.zeros(3) if tj.parent < 0 else pl.tree[tj.parent].Y
    return EngineFrames(tj.kind, tj.R_ref, tj.X - Yp, tj.axis_c, -tj.Y)
