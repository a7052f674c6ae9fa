"""Trees of rigid bodies in reduced (joint) coordinates: the description, its validation, and
the conversion between joint coordinates and per-body world states.

A :class:`Tree` is a list of :class:`Body` (mass, principal moments about the centre of mass)
and one :class:`Joint` per body connecting it to its parent (another body, or the ground when
``parent`` is None). Each body's frame is its principal frame centred at its centre of mass;
anchors and axes are given in those frames (for the ground, in world axes from the origin).

Joint kinds and their coordinates (q: positions, u: velocities; offsets into the state vector
are ``Tree.qofs`` and ``Tree.uofs``):

=============  ===============================================  ===========================
kind           q                                                u
=============  ===============================================  ===========================
``free``       x_G (3, world) and the unit quaternion (w, x, y,  v_G (3, world) and W (3,
               z) of R (body to world); only for a root          body axes)
``spherical``  unit quaternion (w, x, y, z) of the relative      w_rel (3): the child's
               rotation R_rel = R_parent^T R_child               angular velocity relative
                                                                  to the parent, child axes
``revolute``   angle theta: R_rel = offset Rot(axis, theta)      theta' (1)
               (axis in the child's frame)
=============  ===============================================  ===========================

Positions follow from the joint coordinates from the root outwards: the joint point is
p = x_parent + R_parent X (X = ``parent_anchor``), R_child = R_parent R_rel and
x_child = p - R_child Y (Y = ``child_anchor``). Quaternions are normalised wherever they are
turned into rotations, so the joint coordinates need not have unit norm exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from references.conventions import matrix_to_quat_wxyz, quat_wxyz_to_matrix
from scenarios.tree import spanning_tree

KINDS = {"free": 0, "spherical": 1, "revolute": 2}
NQ = {"free": 7, "spherical": 4, "revolute": 1}
NU = {"free": 6, "spherical": 3, "revolute": 1}

#: A world state converted to joint coordinates must satisfy the joints to this tolerance
#: (relative to the tree's length scale for anchor gaps, absolute in rad for axes): a state
#: that violates a joint is refused, never projected silently.
STATE_TOL = 1e-10


@dataclass(frozen=True)
class Body:
    """A rigid body: ``mass`` (kg, > 0) and ``inertia`` (3,), the principal moments about the
    centre of mass (kg m^2, > 0, satisfying the triangle inequality)."""

    name: str
    mass: float
    inertia: tuple


@dataclass(frozen=True)
class Joint:
    """A joint connecting ``child`` to ``parent`` (a body name, or None for the ground).

    ``parent_anchor`` X: the joint point in the parent's principal frame relative to its centre
    of mass (m), or a world point if the parent is the ground; ``child_anchor`` Y: the same
    point in the child's frame. ``axis``: revolute axis in the child's frame (normalised here).
    ``offset``: the relative rotation R_parent^T R_child at theta = 0 (revolute only).
    A ``free`` joint has no parent and ignores the anchors.
    """

    kind: str
    child: str
    parent: str | None = None
    parent_anchor: tuple = (0.0, 0.0, 0.0)
    child_anchor: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    offset: np.ndarray = field(default_factory=lambda: np.eye(3))


class Tree:
    """A validated tree of bodies (see the module docstring), ordered parents first.

    Attributes (arrays indexed by body in tree order): ``names``, ``nb``, ``nq``, ``nu``,
    ``kind`` (int codes, :data:`KINDS`), ``parent`` (index, -1 for the ground), ``qofs``,
    ``uofs``, ``mass`` (nb,), ``inertia`` (nb, 3), ``X``, ``Y``, ``axis`` (nb, 3), ``offset``
    (nb, 3, 3), ``gravity`` (3,), ``length`` (the largest anchor distance, m: the length
    scale of tolerances). Raises ``ValueError`` naming the body or joint, the value and the
    rule for any invalid input.
    """

    def __init__(self, bodies, joints, gravity=(0.0, 0.0, 0.0)):
        bodies = list(bodies)
        joints = list(joints)
        byname = {}
        for b in bodies:
            if b.name in byname:
                raise ValueError(f"body {b.name!r}: the name is used twice; names are unique")
            _check_body(b)
            byname[b.name] = b
        joint_of = {}
        for j in joints:
            if j.kind not in KINDS:
                raise ValueError(
                    f"joint of body {j.child!r}: kind {j.kind!r} unknown; known: {', '.join(KINDS)}"
                )
            if j.child not in byname:
                raise ValueError(f"joint of body {j.child!r}: no body of that name")
            if j.parent is not None and j.parent not in byname:
                raise ValueError(
                    f"joint of body {j.child!r}: parent {j.parent!r} is not a body (None "
                    "is the ground)"
                )
            if j.child in joint_of:
                raise ValueError(f"body {j.child!r} has two joints to a parent; a tree has one")
            if j.kind == "free" and j.parent is not None:
                raise ValueError(
                    f"joint of body {j.child!r}: a free joint connects a root to the "
                    f"ground, parent must be None (got {j.parent!r})"
                )
            joint_of[j.child] = j
        for b in bodies:
            if b.name not in joint_of:
                raise ValueError(
                    f"body {b.name!r} has no joint; give it one (a free joint for a floating root)"
                )
        order = []
        placed = set()
        while len(order) < len(bodies):
            ready = [
                b.name
                for b in bodies
                if b.name not in placed
                and (joint_of[b.name].parent is None or joint_of[b.name].parent in placed)
            ]
            if not ready:
                rest = sorted(set(byname) - placed)
                raise ValueError(f"bodies {rest}: their joints form a loop; a tree has none")
            for n in ready:
                order.append(n)
                placed.add(n)
        self.names = order
        self.nb = nb = len(order)
        idx = {n: i for i, n in enumerate(order)}
        self.kind = np.zeros(nb, dtype=np.int64)
        self.parent = np.zeros(nb, dtype=np.int64)
        self.qofs = np.zeros(nb, dtype=np.int64)
        self.uofs = np.zeros(nb, dtype=np.int64)
        self.mass = np.zeros(nb)
        self.inertia = np.zeros((nb, 3))
        self.X = np.zeros((nb, 3))
        self.Y = np.zeros((nb, 3))
        self.axis = np.zeros((nb, 3))
        self.offset = np.zeros((nb, 3, 3))
        self.kinds = []
        nq = nu = 0
        for i, n in enumerate(order):
            j = joint_of[n]
            self.kinds.append(j.kind)
            self.kind[i] = KINDS[j.kind]
            self.parent[i] = -1 if j.parent is None else idx[j.parent]
            self.qofs[i], self.uofs[i] = nq, nu
            nq += NQ[j.kind]
            nu += NU[j.kind]
            self.mass[i] = byname[n].mass
            self.inertia[i] = byname[n].inertia
            self.X[i] = _vec3(j.parent_anchor, f"joint of body {n!r}: parent_anchor")
            self.Y[i] = _vec3(j.child_anchor, f"joint of body {n!r}: child_anchor")
            a = _vec3(j.axis, f"joint of body {n!r}: axis")
            if j.kind == "revolute":
                na = float(np.linalg.norm(a))
                if not na > 0:
                    raise ValueError(f"joint of body {n!r}: axis {a.tolist()} has zero length")
                a = a / na
            self.axis[i] = a
            off = np.asarray(j.offset, dtype=float)
            if off.shape != (3, 3) or not np.allclose(off.T @ off, np.eye(3), atol=1e-12):
                raise ValueError(
                    f"joint of body {n!r}: offset must be a 3x3 rotation matrix (orthonormal "
                    f"to 1e-12), got {off.tolist()}"
                )
            if np.linalg.det(off) < 0:
                raise ValueError(f"joint of body {n!r}: offset has determinant -1 (a reflection)")
            self.offset[i] = off
        self.nq, self.nu = nq, nu
        # a writable copy: a scenario's frozen gravity would be a second compiled signature
        # of the numba dynamics (readonly arrays are a type of their own), ~20 s to compile
        self.gravity = _vec3(gravity, "gravity").copy()
        self.length = max(
            float(np.max(np.linalg.norm(np.concatenate([self.X, self.Y]), axis=1))), 1e-3
        )
        self.index = idx

    # -- world states <-> joint coordinates ----------------------------------------------
    def to_joint(self, x, R, v, W) -> tuple[np.ndarray, np.ndarray]:
        """Joint coordinates (q (nq,), u (nu,)) of the world state of every body: ``x`` (nb,
        3) centres of mass, ``R`` (nb, 3, 3) body-to-world, ``v`` (nb, 3) centre-of-mass
        velocities, ``W`` (nb, 3) body angular velocities, in tree order (``names``).

        Raises ``ValueError`` naming the joint when the state violates it beyond
        :data:`STATE_TOL` (the anchor gap in m, the relative velocity of the anchor points
        in m/s, a revolute's axis misalignment): a state must satisfy the joints, it is never
        projected onto them here.
        """
        x, R, v, W = (np.asarray(a, dtype=float) for a in (x, R, v, W))
        q = np.zeros(self.nq)
        u = np.zeros(self.nu)
        tol = STATE_TOL * self.length
        for b in range(self.nb):
            name, kind = self.names[b], self.kinds[b]
            qo, uo = self.qofs[b], self.uofs[b]
            if kind == "free":
                q[qo : qo + 3] = x[b]
                q[qo + 3 : qo + 7] = matrix_to_quat_wxyz(R[b])
                u[uo : uo + 3] = v[b]
                u[uo + 3 : uo + 6] = W[b]
                continue
            p = self.parent[b]
            Rp = np.eye(3) if p < 0 else R[p]
            xp = np.zeros(3) if p < 0 else x[p]
            vp = np.zeros(3) if p < 0 else v[p]
            Wp = np.zeros(3) if p < 0 else W[p]
            wp = Rp @ Wp
            wc = R[b] @ W[b]
            anchor_p = xp + Rp @ self.X[b]
            anchor_c = x[b] + R[b] @ self.Y[b]
            gap = float(np.linalg.norm(anchor_p - anchor_c))
            if gap > tol:
                raise ValueError(
                    f"joint of body {name!r}: the anchors are {gap:.3g} m apart (parent "
                    f"{anchor_p.tolist()}, child {anchor_c.tolist()}); they must coincide "
                    f"within {tol:.3g} m"
                )
            vel_p = vp + np.cross(wp, anchor_p - xp)
            vel_c = v[b] + np.cross(wc, anchor_c - x[b])
            slip = float(np.linalg.norm(vel_p - vel_c))
            vscale = max(1.0, float(np.max(np.abs(W))) * self.length, float(np.max(np.abs(v))))
            if slip > STATE_TOL * vscale:
                raise ValueError(
                    f"joint of body {name!r}: the anchor points move apart at {slip:.3g} m/s; "
                    "the velocities must satisfy the joint"
                )
            Rrel = Rp.T @ R[b]
            wrel = W[b] - Rrel.T @ Wp
            if kind == "spherical":
                q[qo : qo + 4] = matrix_to_quat_wxyz(Rrel)
                u[uo : uo + 3] = wrel
            else:
                n = self.axis[b]
                M = self.offset[b].T @ Rrel  # = Rot(n, theta)
                # M = Rot(n, theta): its skew part is sin(theta) n, its trace 1 + 2 cos(theta)
                skew = 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
                theta = math.atan2(float(n @ skew), 0.5 * (float(np.trace(M)) - 1.0))
                misalign = float(np.linalg.norm(M @ n - n))
                if misalign > STATE_TOL:
                    raise ValueError(
                        f"joint of body {name!r}: the revolute axis is misaligned by "
                        f"{misalign:.3g} rad; the relative rotation must be about the axis"
                    )
                off_axis = float(np.linalg.norm(wrel - (n @ wrel) * n))
                if off_axis > STATE_TOL * max(1.0, float(np.max(np.abs(W)))):
                    raise ValueError(
                        f"joint of body {name!r}: the relative angular velocity has "
                        f"{off_axis:.3g} rad/s off the revolute axis"
                    )
                q[qo] = theta
                u[uo] = float(n @ wrel)
        return q, u

    def initial_from_joint(self, q, u) -> tuple[np.ndarray, np.ndarray]:
        """Checked copies of joint coordinates: shapes (nq,), (nu,), finite, non-zero
        quaternions (normalised; a quaternion off unit norm by more than 1e-12 is refused)."""
        q = np.array(q, dtype=float).reshape(-1)
        u = np.array(u, dtype=float).reshape(-1)
        if q.shape != (self.nq,) or u.shape != (self.nu,):
            raise ValueError(
                f"joint coordinates: expected q of shape ({self.nq},) and u of shape "
                f"({self.nu},), got {q.shape} and {u.shape}"
            )
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(u))):
            raise ValueError("joint coordinates: q and u must be finite")
        for b in range(self.nb):
            if self.kinds[b] == "revolute":
                continue
            o = self.qofs[b] + (3 if self.kinds[b] == "free" else 0)
            nrm = float(np.linalg.norm(q[o : o + 4]))
            if abs(nrm - 1.0) > 1e-12:
                raise ValueError(
                    f"joint of body {self.names[b]!r}: quaternion norm {nrm!r}; must be 1 "
                    "within 1e-12"
                )
            q[o : o + 4] /= nrm
        return q, u


def _vec3(a, what: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected 3 finite numbers, got {np.asarray(a).tolist()}")
    return a


def _check_body(b: Body) -> None:
    if not (isinstance(b.mass, (int, float)) and math.isfinite(b.mass) and b.mass > 0):
        raise ValueError(f"body {b.name!r}: mass {b.mass!r} must be a finite number > 0")
    J = np.asarray(b.inertia, dtype=float)
    if J.shape != (3,) or not np.all(np.isfinite(J)) or np.any(J <= 0):
        raise ValueError(
            f"body {b.name!r}: inertia {np.asarray(b.inertia).tolist()} must be three finite "
            "principal moments > 0"
        )
    s = float(np.sum(J))
    if np.any(2.0 * J > s * (1.0 + 1e-12)):
        raise ValueError(
            f"body {b.name!r}: inertia {J.tolist()} violates the triangle inequality "
            "(each moment at most the sum of the other two)"
        )


def quat_to_R(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a (not necessarily unit) quaternion (w, x, y, z)."""
    q = np.asarray(q, dtype=float)
    return quat_wxyz_to_matrix(q / np.linalg.norm(q))


def tree_from_world(bodies, joints, gravity=(0.0, 0.0, 0.0)):
    """A :class:`Tree` and its joint state (q, u) from bodies given by their world state and
    joints given between two bodies or a body and the ground, the form a director-form
    system or a scenario file uses.

    ``bodies``: objects with ``name``, ``mass``, ``inertia`` (principal moments), ``position``
    (x_G, world), ``rotation`` (R, body to world), ``velocity`` (v_G, world) and
    ``omega_body`` (W, body axes). ``joints``: objects with ``kind`` ("spherical" or
    "revolute"; "fixed_point" is a spherical joint to the ground), ``body_a``, ``body_b`` (a
    body name, or None for the ground), ``anchor_a``, ``anchor_b`` (the joint point in each
    body's principal frame relative to its centre of mass; a world point for the ground) and,
    for a revolute, ``axis_a``, ``axis_b`` (the hinge axis in each frame; world for the
    ground). Each body joined to nothing becomes a free root. The parent of each joint is the
    side nearer the ground (or the first body listed, for a floating system); a revolute's
    angle is measured from the initial configuration (offset = R_parent^T R_child at t = 0).

    Returns (tree, q0, u0). Raises ``ValueError`` naming the joint for a closed loop (a tree
    has none), an unknown body, a kind this reference does not treat, axes that are not
    aligned at t = 0, and whatever :meth:`Tree.to_joint` refuses (anchor gaps, velocities
    that violate a joint).
    """
    bodies = list(bodies)
    joints = list(joints)
    names = [b.name for b in bodies]
    known = set(names)
    whats = []
    for k, j in enumerate(joints):
        what = f"joint {getattr(j, 'name', None) or k} ({j.kind} {j.body_a!r}-{j.body_b!r})"
        whats.append(what)
        if j.kind not in ("spherical", "fixed_point", "revolute"):
            raise ValueError(
                f"{what}: kind {j.kind!r} is not treated by the reduced reference "
                "(spherical, fixed_point, revolute)"
            )
        for side in (j.body_a, j.body_b):
            if side is not None and side not in known:
                raise ValueError(f"{what}: body {side!r} unknown; bodies: {names}")
        if j.body_a is None:
            raise ValueError(f"{what}: body_a must be a body (body_b None is the ground)")
    st = spanning_tree(bodies, joints)
    if st.loops:
        raise ValueError(
            f"{whats[st.loops[0]]}: closes a loop; the reduced reference treats trees only"
        )
    parent_joint = {}
    for n, (parent, k) in st.parent.items():
        parent_joint[n] = (
            (parent, None, "free root") if k is None else (parent, joints[k], whats[k])
        )
    # the bodies on the ground, then depth first from each (a body's children when it is
    # taken from the stack), then each floating root and its part: the order in which the
    # tree lists the bodies of one generation
    ground = [r for r in st.children[None] if st.parent[r][1] is not None]
    order = list(ground)

    def grow(root):
        stack = [root]
        while stack:
            kids = st.children[stack.pop()]
            order.extend(kids)
            stack.extend(kids)

    for r in ground:
        grow(r)
    for r in st.floating_roots:
        order.append(r)
        grow(r)
    by = dict(zip(names, bodies, strict=True))
    tb, tj = [], []
    for n in order:
        b = by[n]
        tb.append(Body(n, float(b.mass), tuple(float(v) for v in b.inertia)))
        parent, j, what = parent_joint[n]
        if j is None:
            tj.append(Joint("free", n))
            continue
        child_is_a = j.body_a == n
        ca, pa = (j.anchor_a, j.anchor_b) if child_is_a else (j.anchor_b, j.anchor_a)
        if j.kind != "revolute":
            tj.append(Joint("spherical", n, parent, tuple(pa), tuple(ca)))
            continue
        cax, pax = (j.axis_a, j.axis_b) if child_is_a else (j.axis_b, j.axis_a)
        cax = np.asarray(cax, dtype=float) / np.linalg.norm(cax)
        pax = np.asarray(pax, dtype=float) / np.linalg.norm(pax)
        Rc = np.asarray(b.rotation, dtype=float)
        Rp = np.eye(3) if parent is None else np.asarray(by[parent].rotation, dtype=float)
        mis = float(np.linalg.norm(Rc @ cax - Rp @ pax))
        if mis > STATE_TOL:
            raise ValueError(
                f"{what}: the axes differ by {mis:.3g} rad at t = 0 (world "
                f"{(Rc @ cax).tolist()} and {(Rp @ pax).tolist()}); they must "
                "coincide"
            )
        tj.append(Joint("revolute", n, parent, tuple(pa), tuple(ca), tuple(cax), Rp.T @ Rc))
    tree = Tree(tb, tj, gravity)
    st = [by[n] for n in tree.names]
    q0, u0 = tree.to_joint(
        [b.position for b in st],
        [b.rotation for b in st],
        [b.velocity for b in st],
        [b.omega_body for b in st],
    )
    return tree, q0, u0
