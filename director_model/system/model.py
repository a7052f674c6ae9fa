"""Bodies, joints and their assembly into constraint rows (the system's Python layer).

Conventions (SI): each body's frame is its principal frame with the origin at its centre of
mass; ``rotation`` R is body-to-world (columns are the directors d_1, d_2, d_3), ``omega_body``
W is the angular velocity in body axes (w = R W). Joint anchors and axes are given in the
principal frame of each body, relative to its centre of mass; for the ground (``body_b=None``)
``anchor_b`` and ``axis_b`` are world coordinates.

Each joint is a set of *constraint rows* g_r(q) = 0, each one of three primitives, all at
most quadratic in the director coordinates q = (x, d_1, d_2, d_3) of the two bodies:

``POINT`` (component k)  (x_a + R_a X - x_b - R_b Y)_k
``DOT``                  (R_a u) . (R_b v) - c
``LINE``                 (x_b + R_b Y - x_a - R_a X) . (R_a p)

with the ground's x = 0, R = 1. Force elements (:class:`Spring`, :class:`Torque`) add their
forces to both half kicks of a RATTLE sub-step, at the start and at the end state; a
damper's force at the end depends on the end velocities, solved with them by a fixed-point
iteration (the trapezoidal rule on the damping, which keeps the step symmetric, so the
compositions keep their order). Joints (u_a = R_a axis_a, u_b = R_b axis_b):

==============  ====  ==================================================================
kind            rows  rows
==============  ====  ==================================================================
spherical       3     POINT x3 (anchor_a, anchor_b)
fixed_point     3     as spherical, body_b must be None (the ground)
revolute        5     POINT x3, DOT (u_a . R_b m_k = 0, k = 1, 2; m_1, m_2 perpendicular to
                      axis_b)
universal       4     POINT x3, DOT u_a . u_b = 0 (axes perpendicular at t = 0)
cylindrical     4     the two DOT rows of a revolute, LINE x2 (R_a p_k, p_k perpendicular to
                      axis_a)
prismatic       5     cylindrical and DOT (R_a p_1) . (R_b m_k) = c, the rotation about the
                      axis locked at its initial value
==============  ====  ==================================================================

The same rows evaluated at states in NumPy (initial checks, saved states, the velocity
projection, energy and the force elements' potential): :mod:`director_model.system.states`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from director_model.body import validate_body
from director_model.errors import InvalidBodyError, InvalidStateError
from director_model.state import check_rotation

POINT = 0
DOT = 1
LINE = 2

JOINT_KINDS = ("spherical", "fixed_point", "revolute", "universal", "cylindrical", "prismatic")
_ROWS = {"spherical": 3, "fixed_point": 3, "revolute": 5, "universal": 4, "cylindrical": 4,
         "prismatic": 5}  # fmt: skip
_NEEDS_AXES = ("revolute", "universal", "cylindrical", "prismatic")

#: a joint must hold at t = 0 to this absolute tolerance (m for points, for the dot products
#: of unit axes), and the initial velocities to this tolerance times the largest body speed
#: scale (m/s); larger gaps are errors, smaller ones are closed by the first step
INIT_TOL = 1e-10


@dataclass(frozen=True, eq=False)
class Spring:
    """A linear spring-damper between the point ``anchor_a`` of body ``body_a`` and the point
    ``anchor_b`` of body ``body_b`` (None: the ground, ``anchor_b`` a world point): stiffness
    k (N/m), damping c (N s/m), rest length l0 (m). It pulls point a by
    -(k (l - l0) + c l') e, e = (p_a - p_b) / l, and point b by the opposite; it stores
    1/2 k (l - l0)^2 (module docstring, "Force elements")."""

    body_a: str
    body_b: str | None
    anchor_a: tuple
    anchor_b: tuple
    stiffness: float
    damping: float = 0.0
    rest_length: float = 0.0
    name: str | None = None


@dataclass(frozen=True, eq=False)
class Torque:
    """A constant torque ``torque`` (N m) about the axis of the revolute joint named
    ``joint``: tau R_a axis_a on its body a, the opposite on its body b (module docstring,
    "Force elements")."""

    joint: str
    torque: float


class InvalidJointError(ValueError):
    """A joint is malformed (unknown kind or body, missing or zero axis) or does not hold at
    t = 0 (the message names the joint, the gap and the rule)."""


class InvalidMechanismError(ValueError):
    """The system as a whole cannot be integrated: no degree of freedom is left (a locked
    structure), or a body is a thin rod (two convected moments zero)."""


def _vec3(what: str, value, err=InvalidStateError) -> np.ndarray:
    """``value`` as a new writable float 3-vector (always a copy: numba compiles a read-only
    array, such as a scenario's frozen one, as another type, a second compilation of every
    kernel it reaches)."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise err(f"{what} = {value!r}: expected 3 real numbers ({exc})") from None
    if a.shape != (3,):
        raise err(f"{what} = {value!r}: expected 3 real numbers, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise err(f"{what} = {a.tolist()}: every entry must be finite")
    return a


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body of a system and its initial state (SI units).

    ``name`` unique in the system; ``mass`` m > 0 (kg); ``inertia`` principal moments
    (I_1, I_2, I_3) about the centre of mass (kg m^2), triangle inequality, a lamina
    (I_i = I_j + I_k) allowed, a thin rod refused; ``position`` x of the centre of mass (m,
    world); ``rotation`` R (3, 3) body-to-world, orthonormal to 1e-12, det +1; ``velocity``
    v (m/s, world); ``omega_body`` W (rad/s, body axes). Checked at construction
    (InvalidBodyError / InvalidStateError naming the body)."""

    name: str
    mass: float
    inertia: tuple = (1.0, 1.0, 1.0)
    position: tuple = (0.0, 0.0, 0.0)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    velocity: tuple = (0.0, 0.0, 0.0)
    omega_body: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise InvalidBodyError(f"body name = {self.name!r}: must be a non-empty string")
        where = f"body {self.name!r}: "
        try:
            J = validate_body(self.mass, self.inertia)
        except InvalidBodyError as exc:
            raise InvalidBodyError(where + str(exc)) from None
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "inertia", _vec3(where + "inertia", self.inertia))
        object.__setattr__(self, "J", J)
        for f in ("position", "velocity", "omega_body"):
            object.__setattr__(self, f, _vec3(where + f, getattr(self, f)))
        R = check_rotation(self.rotation, where + "rotation")
        object.__setattr__(self, "rotation", R)


@dataclass(frozen=True, eq=False)
class Joint:
    """A joint between body ``body_a`` and body ``body_b`` (names), or the ground if
    ``body_b`` is None. ``kind``: one of :data:`JOINT_KINDS`. ``anchor_a`` (m) in the
    principal frame of a relative to its centre of mass, ``anchor_b`` likewise in b (world
    coordinates for the ground); ``axis_a``, ``axis_b`` (any length > 0, normalised) for
    revolute, universal, cylindrical and prismatic joints, in the same frames. ``name``
    defaults to "joint<index>" in the system. The equations are in the module docstring."""

    kind: str
    body_a: str
    body_b: str | None = None
    anchor_a: tuple = (0.0, 0.0, 0.0)
    anchor_b: tuple = (0.0, 0.0, 0.0)
    axis_a: tuple | None = None
    axis_b: tuple | None = None
    name: str | None = None


def _perp_pair(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit vector n to a right-handed orthonormal basis."""
    k = int(np.argmin(np.abs(n)))
    e = np.zeros(3)
    e[k] = 1.0
    m1 = np.cross(n, e)
    m1 /= np.linalg.norm(m1)
    return m1, np.cross(n, m1)


@dataclass(frozen=True)
class Assembly:
    """The system as arrays for the compiled kernel.

    ``rint`` (nrow, 4) int64: primitive (POINT, DOT, LINE), body a, body b (-1 = ground),
    component k (POINT rows). ``rvec`` (nrow, 10): vector in a (anchor X or axis u), vector
    in b (anchor Y or axis v; world for the ground), vector p in a (LINE rows), constant c
    (DOT rows). ``row_joint`` (nrow,) the joint index of each row. ``bodies`` (nb, 7): m,
    I_1, I_2, I_3, 1/I_1, 1/I_2, 1/I_3. ``brow_ptr``, ``brow_idx``, ``brow_side``: the rows
    touching each body (CSR; side 0 = the row's body a, 1 = body b). ``bandwidth``: the
    largest |r - s| over rows r, s sharing a body. ``block3``: every joint is three point
    rows (spherical, fixed point) and joints sharing a body are adjacent in the list (a chain
    listed along itself), so the multiplier matrices are block tridiagonal with 3x3 blocks;
    ``jptr``, ``jidx``, ``jside``: the joints touching each body (CSR, side as above)."""

    names: tuple
    joint_names: tuple
    rint: np.ndarray
    rvec: np.ndarray
    row_joint: np.ndarray
    bodies: np.ndarray
    brow_ptr: np.ndarray
    brow_idx: np.ndarray
    brow_side: np.ndarray
    bandwidth: int
    length_scale: float
    block3: bool
    jptr: np.ndarray
    jidx: np.ndarray
    jside: np.ndarray


def assemble(bodies, joints) -> Assembly:
    """Check the bodies' names and the joints' kinds, bodies and axes, and build the
    constraint rows. Raises InvalidJointError / InvalidBodyError naming the joint or body."""
    bodies = list(bodies)
    joints = list(joints)
    if not bodies:
        raise InvalidBodyError("bodies: the system needs at least one body")
    for i, b in enumerate(bodies):
        if not isinstance(b, Body):
            raise InvalidBodyError(f"bodies[{i}] = {b!r}: expected a director_model.system.Body")
    names = tuple(b.name for b in bodies)
    seen = set()
    for n in names:
        if n in seen:
            raise InvalidBodyError(f"body name {n!r}: used twice; body names must be unique")
        seen.add(n)
    index = {n: i for i, n in enumerate(names)}
    rint, rvec, row_joint, jnames = [], [], [], []
    for j, jt in enumerate(joints):
        if not isinstance(jt, Joint):
            raise InvalidJointError(f"joints[{j}] = {jt!r}: expected a director_model.system.Joint")
        jn = jt.name if jt.name is not None else f"joint{j}"
        jnames.append(jn)
        where = f"joint {jn!r} ({jt.kind}, {jt.body_a!r}-{jt.body_b!r})"
        if jt.kind not in _ROWS:
            raise InvalidJointError(
                f"joint {jn!r}: kind = {jt.kind!r}: unknown; available: {', '.join(JOINT_KINDS)}"
            )
        for side, bn in (("body_a", jt.body_a), ("body_b", jt.body_b)):
            if side == "body_b" and bn is None:
                continue
            if bn not in index:
                raise InvalidJointError(
                    f"{where}: {side} = {bn!r}: unknown body; the bodies are {list(names)}"
                )
        if jt.body_b is not None and jt.body_a == jt.body_b:
            raise InvalidJointError(f"{where}: a joint must connect two different bodies")
        if jt.kind == "fixed_point" and jt.body_b is not None:
            raise InvalidJointError(
                f"{where}: body_b = {jt.body_b!r}: a fixed_point joint ties body_a to the "
                "ground (body_b=None, anchor_b a world point)"
            )
        a = index[jt.body_a]
        b = -1 if jt.body_b is None else index[jt.body_b]
        X = _vec3(where + ": anchor_a", jt.anchor_a, InvalidJointError)
        Y = _vec3(where + ": anchor_b", jt.anchor_b, InvalidJointError)
        ua = ub = None
        if jt.kind in _NEEDS_AXES:
            if jt.axis_a is None or jt.axis_b is None:
                raise InvalidJointError(f"{where}: a {jt.kind} joint needs axis_a and axis_b")
            ua = _vec3(where + ": axis_a", jt.axis_a, InvalidJointError)
            ub = _vec3(where + ": axis_b", jt.axis_b, InvalidJointError)
            for nm, ax in (("axis_a", ua), ("axis_b", ub)):
                if not np.linalg.norm(ax) > 0:
                    raise InvalidJointError(f"{where}: {nm} = {ax.tolist()}: must be nonzero")
            ua = ua / np.linalg.norm(ua)
            ub = ub / np.linalg.norm(ub)
        rows = []
        z = np.zeros(3)
        if jt.kind in ("spherical", "fixed_point", "revolute", "universal"):
            rows += [(POINT, k, X, Y, z, 0.0) for k in range(3)]
        if jt.kind in ("revolute", "cylindrical", "prismatic"):
            m1, m2 = _perp_pair(ub)
            rows += [(DOT, 0, ua, m1, z, 0.0), (DOT, 0, ua, m2, z, 0.0)]
        if jt.kind == "universal":
            rows += [(DOT, 0, ua, ub, z, 0.0)]
        if jt.kind in ("cylindrical", "prismatic"):
            p1, p2 = _perp_pair(ua)
            rows += [(LINE, 0, X, Y, p1, 0.0), (LINE, 0, X, Y, p2, 0.0)]
        if jt.kind == "prismatic":
            # lock the rotation about the axis: (R_a p1) . (R_b m) = c, with m the one of
            # m1, m2 most perpendicular to R_a p1 at t = 0 (largest gradient), c its value
            Ra = bodies[a].rotation
            Rb = np.eye(3) if b < 0 else bodies[b].rotation
            P1 = Ra @ p1
            m = m1 if abs(P1 @ (Rb @ m1)) < abs(P1 @ (Rb @ m2)) else m2
            rows += [(DOT, 0, p1, m, z, float(P1 @ (Rb @ m)))]
        for prim, k, va, vb, vc, c in rows:
            rint.append((prim, a, b, k))
            rvec.append(np.concatenate([va, vb, vc, [c]]))
            row_joint.append(j)
    nb = len(bodies)
    B = np.array([[b.mass, *b.inertia, *(1.0 / b.inertia)] for b in bodies])
    rint = np.array(rint, dtype=np.int64).reshape(-1, 4)
    rvec = np.array(rvec, dtype=float).reshape(-1, 10)
    ptr = [0]
    idx, side = [], []
    for i in range(nb):
        for r in range(rint.shape[0]):
            for s_, col in ((0, 1), (1, 2)):
                if rint[r, col] == i:
                    idx.append(r)
                    side.append(s_)
        ptr.append(len(idx))
    bw = 0
    for i in range(nb):
        rs = idx[ptr[i] : ptr[i + 1]]
        if rs:
            bw = max(bw, max(rs) - min(rs))
    L = 1.0
    if rvec.size:
        L = max(1.0, float(np.abs(rvec[:, 0:6]).max()))
    jptr, jidx, jside = [0], [], []
    for i in range(nb):
        for k, jt in enumerate(joints):
            bi = index[jt.body_a], (-1 if jt.body_b is None else index[jt.body_b])
            for s_ in (0, 1):
                if bi[s_] == i:
                    jidx.append(k)
                    jside.append(s_)
        jptr.append(len(jidx))
    block3 = bool(rint.shape[0]) and bool(np.all(rint[:, 0] == POINT))
    block3 = block3 and rint.shape[0] == 3 * len(joints)
    for i in range(nb):
        ks = jidx[jptr[i] : jptr[i + 1]]
        if len(ks) > 2 or (len(ks) == 2 and abs(ks[0] - ks[1]) != 1):
            block3 = False
    return Assembly(
        names=names,
        joint_names=tuple(jnames),
        rint=rint,
        rvec=rvec,
        row_joint=np.array(row_joint, dtype=np.int64),
        bodies=B,
        brow_ptr=np.array(ptr, dtype=np.int64),
        brow_idx=np.array(idx, dtype=np.int64),
        brow_side=np.array(side, dtype=np.int64),
        bandwidth=int(bw),
        length_scale=L,
        block3=block3,
        jptr=np.array(jptr, dtype=np.int64),
        jidx=np.array(jidx, dtype=np.int64),
        jside=np.array(jside, dtype=np.int64),
    )


def band_order(joints, index) -> list[int]:
    """An order of the joints (a permutation of their indices) that keeps the rows sharing a
    body close, for the banded factorisations of the loop solver: Cuthill-McKee over the
    graph whose nodes are the joints and whose edges join joints sharing a body (the ground
    joins nothing), from each joint of least degree in turn, the order of smallest largest
    index distance kept (the given order on a tie). A single loop through the ground (a
    four-bar listed A0, B0, A1, B1) becomes a path (A0, A1, B1, B0): the multiplier matrices
    block tridiagonal. ``index`` maps body names to indices (the ground: None)."""
    nj = len(joints)
    ends = [{index[j.body_a]} | ({index[j.body_b]} if j.body_b is not None else set())
            for j in joints]  # fmt: skip
    nbr = [[k for k in range(nj) if k != i and ends[i] & ends[k]] for i in range(nj)]

    def width(order):
        pos = {j: p for p, j in enumerate(order)}
        return max((abs(pos[i] - pos[k]) for i in range(nj) for k in nbr[i]), default=0)

    best, bw = list(range(nj)), width(range(nj))
    dmin = min((len(n) for n in nbr), default=0)
    for start in [i for i in range(nj) if len(nbr[i]) == dmin][:32]:
        order, seen = [], [False] * nj
        for root in [start, *range(nj)]:  # every component
            if seen[root]:
                continue
            seen[root] = True
            queue = [root]
            while queue:
                i = queue.pop(0)
                order.append(i)
                for k in sorted(nbr[i], key=lambda k: len(nbr[k])):
                    if not seen[k]:
                        seen[k] = True
                        queue.append(k)
        w = width(order)
        if w < bw:
            best, bw = order, w
    return best


def assemble_forces(bodies, joints, springs=(), torques=()) -> tuple[np.ndarray, np.ndarray]:
    """(fint (ne, 3) int64, fvec (ne, 10)): the force elements for the kernel (row e: kind 0
    spring / 1 torque, body a, body b (-1 the ground); a spring's anchor_a, anchor_b, k, c,
    l0, a torque's unit axis in a and tau at 6). Raises InvalidJointError naming the element
    for an unknown body or joint, a torque on a joint that is not revolute, a negative or
    non-finite k, c, a rest length <= 0, a spring from a body to itself, or a spring of length
    0 at t = 0."""
    index = {b.name: i for i, b in enumerate(bodies)}
    jby = {}
    for k, jt in enumerate(joints):
        jby[jt.name if jt.name is not None else f"joint{k}"] = jt
    fint, fvec = [], []
    for e, sp in enumerate(springs):
        nm = sp.name if sp.name is not None else f"spring{e}"
        where = f"spring {nm!r}"
        if not isinstance(sp, Spring):
            raise InvalidJointError(
                f"springs[{e}] = {sp!r}: expected a director_model.system.Spring"
            )
        for side, bn in (("body_a", sp.body_a), ("body_b", sp.body_b)):
            if side == "body_b" and bn is None:
                continue
            if bn not in index:
                raise InvalidJointError(f"{where}: {side} = {bn!r}: unknown body")
        if sp.body_a == sp.body_b:
            raise InvalidJointError(f"{where}: a spring joins two different bodies")
        X = _vec3(where + ": anchor_a", sp.anchor_a, InvalidJointError)
        Y = _vec3(where + ": anchor_b", sp.anchor_b, InvalidJointError)
        k, c, l0 = float(sp.stiffness), float(sp.damping), float(sp.rest_length)
        if not (k >= 0 and c >= 0 and math.isfinite(k) and math.isfinite(c)):
            raise InvalidJointError(f"{where}: stiffness {k!r}, damping {c!r}: finite and >= 0")
        if not (l0 > 0 and math.isfinite(l0)):
            raise InvalidJointError(f"{where}: rest_length = {l0!r}: must be > 0")
        a = bodies[index[sp.body_a]]
        pa = a.position + a.rotation @ X
        if sp.body_b is None:
            pb = Y
        else:
            b = bodies[index[sp.body_b]]
            pb = b.position + b.rotation @ Y
        if not np.linalg.norm(pa - pb) > 0:
            raise InvalidJointError(f"{where}: length 0 at t = 0 (its direction is undefined)")
        fint.append((0, index[sp.body_a], -1 if sp.body_b is None else index[sp.body_b]))
        fvec.append([*X, *Y, k, c, l0, 0.0])
    for e, tq in enumerate(torques):
        if not isinstance(tq, Torque):
            raise InvalidJointError(
                f"torques[{e}] = {tq!r}: expected a director_model.system.Torque"
            )
        jt = jby.get(tq.joint)
        if jt is None or jt.kind != "revolute":
            raise InvalidJointError(
                f"torques[{e}]: joint = {tq.joint!r}: "
                + ("unknown joint" if jt is None else f"a {jt.kind} joint; a torque acts about "
                   "a revolute joint's axis")
            )  # fmt: skip
        tau = float(tq.torque)
        if not math.isfinite(tau):
            raise InvalidJointError(f"torques[{e}]: torque = {tau!r}: must be finite")
        ax = _vec3(f"torques[{e}]: axis_a", jt.axis_a, InvalidJointError)
        ax = ax / np.linalg.norm(ax)
        fint.append((1, index[jt.body_a], -1 if jt.body_b is None else index[jt.body_b]))
        fvec.append([*ax, 0.0, 0.0, 0.0, tau, 0.0, 0.0, 0.0])
    return (np.array(fint, dtype=np.int64).reshape(-1, 3),
            np.array(fvec, dtype=float).reshape(-1, 10))  # fmt: skip
