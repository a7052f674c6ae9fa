"""A robot model as read from a URDF or MJCF file, and its conversion into the suite's system of
bodies (:class:`scenarios.system.SystemBody`, :class:`scenarios.system.SystemJoint`).

The reading keeps the file's own structure: one :class:`Link` per URDF link or MJCF body, with
its mass properties in its own frame, and one :class:`ModelJoint` per joint, holding the pose
of the child's frame in the parent's frame at the joint's zero, the axis and a point of it in
the child's frame (URDF: the child frame's origin; MJCF: the joint's ``pos``), and what the
file says of limits, damping, friction, armature and springs (which a clean test switches
off, and which :attr:`RobotModel.switched_off` lists).

:func:`to_system` turns a reading and an initial joint state into bodies and joints of the
suite: links joined by fixed (or locked) joints become one body (their mass properties
combined), a body's frame is its principal frame at its centre of mass, each moving joint
becomes a revolute or spherical joint between two bodies (or a body and the ground), and a
floating root has no joint. The motion of a joint of the reading: the child's frame in the
parent's is ``origin Trans(point) Rot(axis, q - ref) Trans(-point)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from scenarios.models.xml import ModelError
from scenarios.schema import body_problems, rotation_from_vector

#: joint kinds of a reading (URDF's and MJCF's names mapped to these by the readers)
MOVING_KINDS = ("revolute", "continuous", "prismatic", "planar", "ball", "free", "floating")
KINDS = ("fixed", *MOVING_KINDS)
#: kinds the suite's system and its reference treat (a free root has no joint in a system)
SUPPORTED = {"revolute": "revolute", "continuous": "revolute", "ball": "spherical"}
#: a link's inertia must be positive semi-definite and satisfy the triangle inequality to this
#: relative tolerance (the principal moments of a file's six numbers carry its rounding)
INERTIA_RTOL = 1e-9


@dataclass
class Inertial:
    """Mass properties of one link in its own frame: ``mass`` (kg), ``com`` (3,) the centre of
    mass (m), ``inertia`` (3, 3) about the centre of mass in the link's axes (kg m^2);
    ``source`` says where they came from (``<inertial>``, the geoms, or nothing)."""

    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    source: str = "none"


@dataclass
class Link:
    name: str
    inertial: Inertial
    where: str = ""
    #: geometry as read: (kind, size text) per visual/collision/geom element, for ``show``
    geometry: list = field(default_factory=list)


@dataclass
class ModelJoint:
    """One joint: the child's frame in the parent's is ``origin`` (4, 4) at q = ``ref``;
    ``axis`` (unit, child frame) and ``point`` (child frame) locate the motion. ``parent``
    None is the world. ``lower``/``upper`` (rad or m; None: unlimited), ``damping``,
    ``friction``, ``armature``, ``stiffness`` as the file gives them (0 if absent)."""

    name: str
    kind: str
    parent: str | None
    child: str
    origin: np.ndarray
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ref: float = 0.0
    lower: float | None = None
    upper: float | None = None
    damping: float = 0.0
    friction: float = 0.0
    armature: float = 0.0
    stiffness: float = 0.0
    where: str = ""
    #: URDF <mimic>: the joint this one follows (refused unless held)
    mimic: str | None = None


@dataclass
class RobotModel:
    """A URDF or MJCF file as read: ``links`` and ``joints`` in file order, ``root`` the link
    nearest the world (for MJCF the world's first moving body), ``format`` "urdf" or "mjcf",
    ``actuators`` (count of transmissions or actuators), ``contact_geoms`` (count of collision
    geometries), ``gravity`` (MJCF's option, else None), ``notes`` (what was read but does
    not enter the dynamics), ``meshes`` (file names referenced)."""

    name: str
    path: str
    format: str
    links: list
    joints: list
    root: str
    actuators: int = 0
    contact_geoms: int = 0
    gravity: np.ndarray | None = None
    notes: list = field(default_factory=list)
    meshes: list = field(default_factory=list)

    def link(self, name: str) -> Link:
        for lk in self.links:
            if lk.name == name:
                return lk
        raise KeyError(name)

    def joint(self, name: str) -> ModelJoint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(name)

    @property
    def moving_joints(self) -> list:
        return [j for j in self.joints if j.kind != "fixed"]

    @property
    def switched_off(self) -> list[str]:
        """What a clean test switches off, as the file has it: damping, friction, armature,
        springs, limits on each joint, actuators and collision geometry."""
        out = []
        for what in ("damping", "friction", "armature", "stiffness"):
            js = [j for j in self.moving_joints if getattr(j, what)]
            if js:
                vals = sorted({getattr(j, what) for j in js})
                out.append(f"{what} on {len(js)} joints ({', '.join(f'{v:g}' for v in vals)})")
        lim = [j for j in self.moving_joints if j.lower is not None or j.upper is not None]
        if lim:
            out.append(f"limits on {len(lim)} joints")
        if self.actuators:
            out.append(f"{self.actuators} actuators")
        if self.contact_geoms:
            out.append(f"contact: {self.contact_geoms} collision geometries")
        return out


# -- small frame helpers ----------------------------------------------------------------------


def pose(p=(0.0, 0.0, 0.0), R=None) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = np.asarray(p, dtype=float)
    if R is not None:
        T[:3, :3] = R
    return T


def rpy_matrix(rpy) -> np.ndarray:
    """URDF's roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll) (rotations about the fixed
    axes x, then y, then z)."""
    r, p, y = (float(v) for v in rpy)
    return (
        rotation_from_vector([0.0, 0.0, y])
        @ rotation_from_vector([0.0, p, 0.0])
        @ rotation_from_vector([r, 0.0, 0.0])
    )


def rotate_inertia(I: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The inertia tensor ``I`` given in a frame rotated by ``R`` relative to the link, in the
    link's axes: R I R^T."""
    return R @ I @ R.T


def axis_rotation(axis, angle: float) -> np.ndarray:
    return rotation_from_vector(np.asarray(axis, dtype=float) * float(angle))


def joint_transform(j: ModelJoint, q) -> np.ndarray:
    """The child's frame in the parent's at the joint coordinate ``q`` (an angle for a
    revolute joint, a distance along the axis for a prismatic one, a rotation vector for a
    ball joint, ignored for fixed joints)."""
    if j.kind in ("fixed", "free", "floating"):
        return j.origin
    if j.kind == "prismatic":  # a slide along the axis (held joints only)
        return j.origin @ pose(np.asarray(j.axis, dtype=float) * (float(q) - j.ref))
    if j.kind == "ball":
        R = rotation_from_vector(q)
    else:
        R = axis_rotation(j.axis, float(q) - j.ref)
    c = j.point
    M = pose(c - R @ c, R)  # Trans(c) Rot Trans(-c)
    return j.origin @ M


# -- the conversion into a system of bodies ---------------------------------------------------


@dataclass
class Conversion:
    """The system of a reading: ``bodies`` and ``joints`` (SystemBody, SystemJoint),
    ``groups`` {body name: link names fused into it}, ``ground_links`` (links fixed to the
    world), ``link_pose`` {link: (4, 4) world pose at the initial state}, ``locked`` joint
    names, ``dofs`` {joint name: its system joint kind}."""

    bodies: list
    joints: list
    groups: dict
    ground_links: list
    link_pose: dict
    locked: list
    dofs: dict


def _bad(model: RobotModel, where: str, rule: str) -> ModelError:
    return ModelError(
        f"model file {model.path}: {where}: {rule}", path=model.path, problems=[(where, rule)]
    )


def check_inertial(model: RobotModel, link: Link) -> None:
    """A link's own mass properties: mass >= 0, inertia symmetric positive semi-definite with
    its principal moments satisfying the triangle inequality (to :data:`INERTIA_RTOL`), zero
    inertia only with zero mass... raised as :class:`ModelError` naming the link."""
    m = link.inertial.mass
    I = link.inertial.inertia
    where = f"link {link.name!r} {link.where}".strip()
    if not (math.isfinite(m) and m >= 0):
        raise _bad(model, where, f"mass {m!r}: must be a finite number >= 0 kg")
    if not np.all(np.isfinite(I)):
        raise _bad(model, where, "inertia: every entry must be finite")
    ev = np.linalg.eigvalsh(0.5 * (I + I.T))
    scale = max(float(np.max(np.abs(ev))), 0.0)
    if m == 0 and scale == 0:
        return
    if m > 0 and scale == 0:
        return  # a point mass: acceptable inside a body whose other parts have inertia
    tol = INERTIA_RTOL * scale
    if ev[0] < -tol:
        raise _bad(
            model,
            where,
            f"inertia is not positive semi-definite: principal moments "
            f"{ev.tolist()} (kg m^2); no mass distribution has a negative moment",
        )
    s = float(np.sum(ev))
    for k in range(3):
        if 2 * ev[k] > s + 2 * tol:
            raise _bad(
                model,
                where,
                f"inertia violates the triangle inequality: principal "
                f"moments {ev.tolist()} (kg m^2), {ev[k]:.6g} > the sum of the other two "
                f"{s - ev[k]:.6g}; no mass distribution has these moments",
            )


def _children(joints):
    out: dict = {}
    for j in joints:
        out.setdefault(j.parent, []).append(j)
    return out


def to_system(
    model: RobotModel,
    q0=None,
    qd0=None,
    *,
    floating: bool | None = None,
    base_position=None,
    base_rotation=None,
    base_velocity=None,
    base_omega=None,
    lock=(),
) -> Conversion:
    """The bodies and joints of ``model`` at the joint state ``q0`` (name -> angle in rad, or
    a rotation vector for a ball joint; missing: 0, MJCF: the joint's ``ref``) and rates
    ``qd0`` (name -> rad/s, or an angular velocity in the child's axes for a ball joint).

    ``floating``: the root moves freely (None: as the file says: an MJCF free joint, a URDF
    ``floating`` joint to the world); else it is fixed to the world. ``base_position``,
    ``base_rotation`` (3, 3): the root frame's world pose (default: the file's for MJCF, the
    origin for URDF); ``base_velocity`` (of the root frame's origin) and ``base_omega``, world
    axes, for a floating root. ``lock``: joint names held fixed at their ``q0``.

    Raises :class:`ModelError` naming the joint or link for a kind the suite does not treat
    (prismatic, planar: lock them), a moving body without mass or with a singular inertia,
    unknown joint names in ``q0``/``qd0``/``lock``.
    """
    q0 = dict(q0 or {})
    qd0 = dict(qd0 or {})
    lock = list(lock)
    names = {j.name for j in model.joints}
    for what, d in (
        ("initial joint angle", q0),
        ("initial joint rate", qd0),
        ("locked joint", lock),
    ):
        for n in d:
            if n not in names:
                moving = ", ".join(j.name for j in model.moving_joints) or "none"
                raise _bad(
                    model, f"{what} {n!r}", f"no joint of that name; moving joints: {moving}"
                )
    for lk in model.links:
        check_inertial(model, lk)
    joints_all = _effective_joints(model, lock, q0)
    root_joint = [j for j in joints_all if j.parent is None and j.kind in ("free", "floating")]
    if floating is None:
        floating = bool(root_joint)
    kinds = {}
    for j in joints_all:
        k = j.kind
        if j.name in lock or k == "fixed":
            kinds[j.name] = "fixed"
            continue
        if k in ("free", "floating"):
            if j.parent is not None:
                raise _bad(
                    model,
                    f"joint {j.name!r} {j.where}",
                    "a free joint must join a body to the world (a root)",
                )
            kinds[j.name] = "free" if floating else "fixed"
            continue
        if j.mimic is not None:
            raise _bad(
                model,
                f"joint {j.name!r} {j.where}",
                f"a mimic joint (it follows "
                f"{j.mimic!r}): the suite's joints move independently; hold it with "
                f"lock = [{j.name!r}]",
            )
        if k not in SUPPORTED:
            raise _bad(
                model,
                f"joint {j.name!r} {j.where}",
                f"a {k} joint: the suite's "
                "systems and its reduced-coordinate reference treat revolute, "
                "continuous, ball and free joints; hold it with lock = "
                f"[{j.name!r}] in the scenario's [model] table",
            )
        kinds[j.name] = k
        if j.name in qd0 and k == "ball" and np.shape(qd0[j.name]) != (3,):
            raise _bad(
                model,
                f"initial joint rate {j.name!r}",
                "a ball joint's rate is an angular velocity: 3 numbers",
            )
    parent_joint = {j.child: j for j in joints_all}
    children = _children(joints_all)
    # world poses and velocities of every link frame, from the roots outwards
    Tw: dict = {}
    vw: dict = {}
    base_R = None if base_rotation is None else np.asarray(base_rotation, dtype=float)
    roots = [j for j in joints_all if j.parent is None]
    queue = []
    for lk in model.links:
        if lk.name not in parent_joint:  # URDF root without a joint to the world
            T = pose(np.zeros(3) if base_position is None else base_position, base_R)
            Tw[lk.name] = T
            vw[lk.name] = _base_twist(floating, base_velocity, base_omega)
            queue.append(lk.name)
    for j in roots:
        T = j.origin.copy()
        if base_position is not None:
            T[:3, 3] = base_position
        if base_R is not None:
            T[:3, :3] = base_R
        if j.kind in ("free", "floating"):
            Tw[j.child] = T
            vw[j.child] = _base_twist(kinds[j.name] == "free", base_velocity, base_omega)
        else:
            Tw[j.child] = joint_transform(j, _q(j, q0))
            vw[j.child] = _rel_twist(j, Tw[j.child], None, None, kinds, qd0)
        queue.append(j.child)
    while queue:
        p = queue.pop(0)
        for j in children.get(p, []):
            Tw[j.child] = Tw[p] @ joint_transform(j, _q(j, q0))
            vw[j.child] = _rel_twist(j, Tw[j.child], Tw[p], vw[p], kinds, qd0)
            queue.append(j.child)
    # groups: links joined by fixed joints; the ground: links fixed to the world
    group_of = {}
    for lk in model.links:
        j = parent_joint.get(lk.name)
        if j is None:
            group_of[lk.name] = lk.name if floating else None
    order = [lk.name for lk in model.links]
    pending = [n for n in order if n not in group_of]
    while pending:
        rest = []
        for n in pending:
            j = parent_joint[n]
            if j.parent is not None and j.parent not in group_of:
                rest.append(n)
                continue
            if kinds[j.name] == "fixed":
                group_of[n] = None if j.parent is None else group_of[j.parent]
            else:
                group_of[n] = n
        if len(rest) == len(pending):
            raise _bad(
                model,
                f"links {rest}",
                "not connected to the root (a loop, or a parent that is never placed)",
            )
        pending = rest
    groups: dict = {}
    for n in order:
        if group_of[n] is not None:
            groups.setdefault(group_of[n], []).append(n)
    ground_links = [n for n in order if group_of[n] is None]
    bodies, frames = _bodies(model, groups, Tw, vw)
    joints, dofs = _joints(joints_all, kinds, group_of, frames, Tw)
    return Conversion(
        bodies,
        joints,
        groups,
        ground_links,
        Tw,
        [j.name for j in model.joints if j.name in lock],
        dofs,
    )


def _effective_joints(model: RobotModel, lock, q0) -> list:
    """One joint per child link: an MJCF body with several joints keeps the one not held
    (``lock``); the held ones must stay at their ``ref`` (where they are the identity)."""
    by: dict = {}
    for j in model.joints:
        by.setdefault(j.child, []).append(j)
    out = []
    for child, js in by.items():
        if len(js) == 1:
            out.append(js[0])
            continue
        free = [j for j in js if j.name not in lock]
        for j in js:
            if j.name in lock and j.name in q0 and np.any(np.asarray(q0[j.name]) != j.ref):
                raise _bad(
                    model,
                    f"joint {j.name!r} {j.where}",
                    f"held at {q0[j.name]}: a "
                    f"held joint of a body with {len(js)} joints stays at its ref "
                    f"({j.ref:g})",
                )
        if len(free) > 1:
            raise _bad(
                model,
                f"link {child!r}",
                f"{len(js)} joints ({', '.join(j.name for j in js)})"
                " move this one body; the suite's joints move one body each (a body "
                "between them would be massless): hold all but one with lock = [...]",
            )
        out.append(free[0] if free else js[0])
    return out


def _q(j: ModelJoint, q0: dict):
    if j.kind == "ball":
        return np.asarray(q0.get(j.name, (0.0, 0.0, 0.0)), dtype=float)
    return float(q0.get(j.name, j.ref))


def _base_twist(floating, v, w):
    z = np.zeros(3)
    if not floating:
        return z, z
    return (
        z if v is None else np.asarray(v, dtype=float),
        z if w is None else np.asarray(w, dtype=float),
    )


def _rel_twist(j, T_child, T_parent, tw_parent, kinds, qd0):
    """(velocity of the child frame's origin, angular velocity), world axes."""
    if T_parent is None:
        vp, wp, pp = np.zeros(3), np.zeros(3), np.zeros(3)
    else:
        vp, wp = tw_parent
        pp = T_parent[:3, 3]
    pc = T_child[:3, 3]
    v = vp + np.cross(wp, pc - pp)
    w = wp.copy()
    if kinds[j.name] in ("revolute", "continuous", "ball"):
        Rc = T_child[:3, :3]
        if kinds[j.name] == "ball":
            wr = Rc @ np.asarray(qd0.get(j.name, (0.0, 0.0, 0.0)), dtype=float)
        else:
            wr = Rc @ j.axis * float(qd0.get(j.name, 0.0))
        pj = T_child[:3, :3] @ j.point + pc
        w = w + wr
        v = v + np.cross(wr, pc - pj)
    return v, w


def _bodies(model, groups, Tw, vw):
    """SystemBody per group (named after its root link) and each group's frame data:
    {body: (T_root (4,4) world, c (3,) centre of mass in the root frame, V principal axes)}."""
    from scenarios.system import SystemBody

    by = {lk.name: lk for lk in model.links}
    bodies, frames = [], {}
    for gname, links in groups.items():
        T0 = Tw[gname]
        R0 = T0[:3, :3]
        m = 0.0
        mc = np.zeros(3)
        parts = []
        for n in links:
            rel = np.linalg.solve(T0, Tw[n])
            ine = by[n].inertial
            c = rel[:3, :3] @ ine.com + rel[:3, 3]
            Ir = rotate_inertia(ine.inertia, rel[:3, :3])
            parts.append((ine.mass, c, Ir))
            m += ine.mass
            mc += ine.mass * c
        where = (
            f"body {gname!r} (links {', '.join(links)})"
            if len(links) > 1
            else (f"link {gname!r} {by[gname].where}")
        )
        if not m > 0:
            raise _bad(
                model,
                where,
                "a moving body needs a mass > 0 (URDF: an <inertial> with "
                "<mass>; MJCF: an <inertial>, or geoms with volume)",
            )
        c = mc / m
        I = np.zeros((3, 3))
        for mi, ci, Ii in parts:
            d = ci - c
            I += Ii + mi * (float(d @ d) * np.eye(3) - np.outer(d, d))
        J, V = np.linalg.eigh(0.5 * (I + I.T))
        if np.linalg.det(V) < 0:
            V[:, 2] = -V[:, 2]
        probs = body_problems(m, J, where)
        if probs:
            _, val, rule = probs[0]
            raise _bad(
                model,
                where,
                f"principal moments {np.asarray(val).tolist()} kg m^2: "
                f"{rule}; a moving body needs an inertia that is positive definite",
            )
        v0, w0 = vw[gname]
        R = R0 @ V
        r = R0 @ c
        bodies.append(
            SystemBody(
                name=gname,
                mass=m,
                inertia=J,
                position=T0[:3, 3] + r,
                rotation=R,
                velocity=v0 + np.cross(w0, r),
                omega_body=R.T @ w0,
            )
        )
        frames[gname] = (T0, c, V)
    return bodies, frames


def _joints(joints, kinds, group_of, frames, Tw):
    from scenarios.system import SystemJoint

    out, dofs = [], {}
    for j in joints:
        k = kinds[j.name]
        if k in ("fixed", "free"):
            continue
        kind = SUPPORTED[k]
        child = group_of[j.child]
        T0c, cc, Vc = frames[child]
        assert child == j.child  # a moving joint's child roots its body
        anchor_a = Vc.T @ (j.point - cc)
        axis_a = Vc.T @ j.axis
        # the joint's point and axis in the parent link frame (fixed there: the motion turns
        # about the axis through the point)
        p_par = j.origin[:3, :3] @ j.point + j.origin[:3, 3]
        a_par = j.origin[:3, :3] @ j.axis
        if j.parent is None or group_of[j.parent] is None:
            Tp = np.eye(4) if j.parent is None else Tw[j.parent]
            anchor_b = Tp[:3, :3] @ p_par + Tp[:3, 3]
            axis_b = Tp[:3, :3] @ a_par
            parent = None
        else:
            parent = group_of[j.parent]
            T0p, cp, Vp = frames[parent]
            rel = np.linalg.solve(T0p, Tw[j.parent])
            anchor_b = Vp.T @ (rel[:3, :3] @ p_par + rel[:3, 3] - cp)
            axis_b = Vp.T @ rel[:3, :3] @ a_par
        if kind == "spherical":
            axis_a = axis_b = None
        out.append(
            SystemJoint(
                name=j.name,
                kind=kind,
                body_a=child,
                body_b=parent,
                anchor_a=anchor_a,
                anchor_b=anchor_b,
                axis_a=axis_a,
                axis_b=axis_b,
            )
        )
        dofs[j.name] = kind
    return out, dofs
