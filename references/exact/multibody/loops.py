"""Closed loops, and joints the reduced-coordinate tree does not have, as constraint rows on
the tree: the reference of every system of bodies.

The bodies are joined by the suite's spanning tree (:mod:`scenarios.tree`) of the joints the
reduced tree has (spherical, fixed_point, revolute; :func:`system_from_world`); every other
joint, the loop closures and the joints of other kinds (universal, cylindrical, prismatic),
becomes a set of constraint rows phi(q) = 0 on the tree's coordinates (a body reached by no
tree joint is a free root). The motion solves the index-1 form of the constrained equations

    M(q) u' = -C(q, u) - J(q)^T lambda,     J(q) u' = -b(q, u),

J the rows' velocity Jacobian (phi' = J u) and b = J' u their velocity-product acceleration,
both from the tree's own kinematics (the motion-subspace columns S and the accelerations at
u' = 0 of :func:`references.exact.multibody.dynamics._dynamics`), never from the director
model. With M = L L^T (Cholesky) and Y = L^-1 J^T = U diag(s) V^T (thin SVD),

    u' = a0 - L^-T U_r diag(1/s_r) V_r^T (J a0 + b),     a0 = -M^-1 C,

over the r largest singular values, r the rows' rank at t = 0 (:data:`RANK_TOL`): redundant
rows (Bricard's loop closed by a revolute joint: five rows of rank four on the tree)
contribute nothing, and the motion is unique though the multipliers are not. Near a singular
configuration (a rank that drops, where two branches of the loop meet) the rows' rates lose
their hold on the motion along the other branch and errors are amplified by 1/s_min: the
reference stops there (:data:`SINGULAR_TOL`, :class:`LoopSingular`) rather than follow a
branch it cannot tell apart (the closed forms cover the four-bars that pass through one). The
test is made on the states DOP853 accepts: a trial stage that lands near a singular
configuration (on a stiff system, IFToMM A05's dampers, a rejected step's stage may land
anywhere) returns NaN, which makes DOP853 reject the step, and LoopSingular is raised when no
smaller step avoids it.
The rows, per joint (world vectors; a = body_a, b = body_b or the ground; A, B unit vectors
fixed in a and b):

=============  ==========================================================================
point          p_a - p_b = 0 (3 rows): spherical, fixed_point, revolute, universal
revolute       + A . B_k = 0, A the axis in a, B_1, B_2 perpendicular to the axis in b
universal      + A . B = 0, the two axes
cylindrical    the revolute's two axis rows, and (p_b - p_a) . T_k = 0, T_1, T_2
               perpendicular to the axis in a (b's point on a's axis line)
prismatic      the three rows A_k . B_(k+1) = 0 of a locked relative rotation (B_(k+1) the
               body-b vector at t = 0 along a's e_(k+1)), and the cylindrical's two line rows
=============  ==========================================================================

with phi' and phi'' at u' = 0 written out in :func:`_rows`. A state (q, u) must satisfy the
rows at t = 0 (the scenario layer checks it); the index-1 form then holds them up to the
integration error, which grows with time: the reference's own largest row residual over the
run (``constraint_residual``, m and rad) is reported and is a lower bound of its position
error, added to the estimate. The error estimate is that of :mod:`.integrate` (a run at
10 rtol, one with halved steps, round-off probes with joint rates perturbed within the
velocity constraints), checked against the exact motion of the parallelogram four-bar in
tests/references/exact/test_multibody_loops.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from references.exact.multibody.dynamics import _args, _dynamics, _rhs
from references.exact.multibody.forces import _force_kernel, _pack_forces
from references.exact.multibody.tree import STATE_TOL, tree_from_world

#: the joints the reduced tree has (a fixed_point is a spherical joint to the ground)
TREE_KINDS = ("spherical", "fixed_point", "revolute")
#: the joints with a point constraint
POINT_KINDS = ("spherical", "fixed_point", "revolute", "universal")
#: at t = 0 (a state on the loops to round-off) singular values of L^-1 J^T below RANK_TOL s_1
#: are redundant directions (~1e-16 s_1), dropped over the whole run (:func:`accelerations`);
#: a singular configuration stops the reference long before, at SINGULAR_TOL
RANK_TOL = 1e-11
#: the motion approaches a singular configuration when the smallest of the singular values kept at t
#: = 0 (the rank of the rows there) falls below SINGULAR_TOL s_1: there the rows' rank drops, the
#: branches of the loop meet, and a state a round-off away from the motion's branch is as near
#: another; the reference then stops (:class:`LoopSingular`) rather than follow a branch it cannot
#: tell apart (tests/references/exact/test_multibody_loops.py: through the four-bar's collinear
#: configuration it takes the crossed branch)
SINGULAR_TOL = 1e-5


class LoopSingular(ValueError):
    """The motion reaches a singular configuration of its loops (:data:`SINGULAR_TOL`)."""


def _perp(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing the unit n to a right-handed orthonormal frame."""
    k = int(np.argmin(np.abs(n)))
    e = np.zeros(3)
    e[k] = 1.0
    p1 = np.cross(n, e)
    p1 /= np.linalg.norm(p1)
    return p1, np.cross(n, p1)


@dataclass
class Closure:
    """One joint as constraint rows on the tree (module docstring). ``a``, ``b``: body
    indices in tree order (``b`` -1: the ground); ``pa``, ``pb``: anchors in each body's
    frame (a world point for the ground); ``dots``: (A in a's frame, B in b's frame) pairs
    with A . B = 0; ``lines``: vectors T in a's frame with (p_b - p_a) . T = 0; ``point``:
    whether p_a = p_b is imposed."""

    name: str
    kind: str
    a: int
    b: int
    pa: np.ndarray
    pb: np.ndarray
    point: bool
    dots: list = field(default_factory=list)
    lines: list = field(default_factory=list)

    @property
    def nrows(self) -> int:
        return 3 * self.point + len(self.dots) + len(self.lines)


@dataclass
class LoopSystem:
    """A tree with constraint rows: ``tree`` (:class:`~.tree.Tree`), ``closures``
    (:class:`Closure` list), ``tree_joints`` and ``closure_joints`` (the joint names of
    each), ``nc`` (rows), ``chains`` (per body, the indices into u of its joint and its
    ancestors')."""

    tree: object
    closures: list
    tree_joints: list
    closure_joints: list
    chains: list
    #: force elements packed for :func:`.forces._force_kernel` (:func:`.forces._pack_forces`)
    forces: tuple = ()

    def __post_init__(self):
        self.packed = _pack(self.closures)
        if not self.forces:
            self.forces = _pack_forces([], [], {}, {})
        lens = [len(c) for c in self.chains]
        self.cptr = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
        self.cidx = (np.concatenate(self.chains) if self.chains else np.zeros(0)).astype(np.int64)
        #: the rows' rank at t = 0 (set by system_from_world)
        self.rank0 = 0

    @property
    def nc(self) -> int:
        return sum(c.nrows for c in self.closures)

    @property
    def has_forces(self) -> bool:
        """Force elements act (springs, joint torques)."""
        return bool(len(self.forces[0]) or len(self.forces[7]))

    @property
    def active(self) -> bool:
        """The tree alone does not give the motion: constraint rows or force elements."""
        return self.nc > 0 or self.has_forces


def _spanning(bodies, joints):
    """(tree joints, the rest): the suite's spanning tree (:func:`scenarios.tree.spanning_tree`)
    of the joints the reduced tree has; every other joint, and those of the tree kinds that
    close a loop, are closures."""
    from scenarios.tree import spanning_tree

    treeable = [j for j in joints if j.kind in TREE_KINDS]
    st = spanning_tree(bodies, treeable)
    tree = [treeable[k] for k in sorted(st.tree)]
    chosen = {id(j) for j in tree}
    return tree, [j for j in joints if id(j) not in chosen]


def system_from_world(bodies, joints, gravity=(0.0, 0.0, 0.0), springs=(), torques=()):
    """(:class:`LoopSystem`, q0, u0) of bodies in their world state joined by ``joints``
    (objects with the fields of :class:`scenarios.system.SystemJoint`), with the force
    elements ``springs`` and ``torques`` (the fields of :class:`scenarios.force_elements.Spring`
    and :class:`~scenarios.force_elements.JointTorque`); the state must satisfy every joint
    (the tree's joints to :data:`~.tree.STATE_TOL`, the closures are checked by the caller).
    Raises ``ValueError`` naming the joint for a joint of an unknown kind or body."""
    bodies = list(bodies)
    names = [b.name for b in bodies]
    for j in joints:
        if j.kind not in POINT_KINDS + ("cylindrical", "prismatic"):
            raise ValueError(f"joint {j.name!r}: kind {j.kind!r} unknown")
        for side in (j.body_a, j.body_b):
            if side is not None and side not in names:
                raise ValueError(f"joint {j.name!r}: body {side!r} unknown; bodies: {names}")
    tj, rest = _spanning(bodies, joints)
    tree, q0, u0 = tree_from_world(bodies, tj, gravity)
    idx = tree.index
    by = {b.name: b for b in bodies}
    closures = []
    for j in rest:
        a = idx[j.body_a]
        b = -1 if j.body_b is None else idx[j.body_b]
        Ra = np.asarray(by[j.body_a].rotation, dtype=float)
        Rb = np.eye(3) if j.body_b is None else np.asarray(by[j.body_b].rotation, dtype=float)
        c = Closure(j.name, j.kind, a, b, np.array(j.anchor_a, dtype=float),
                    np.array(j.anchor_b, dtype=float), j.kind in POINT_KINDS)  # fmt: skip
        if j.kind != "spherical" and j.kind != "fixed_point":
            na = np.asarray(j.axis_a, dtype=float)
            na = na / np.linalg.norm(na)
            nb = np.asarray(j.axis_b, dtype=float)
            nb = nb / np.linalg.norm(nb)
            if j.kind == "universal":
                c.dots.append((na, nb))
            elif j.kind == "prismatic":
                # B_(k+1): the body-b vector along a's e_(k+1) at t = 0
                Rrel = Ra.T @ Rb  # b's frame in a's axes
                for k in range(3):
                    e_k = np.eye(3)[k]
                    e_k1 = np.eye(3)[(k + 1) % 3]
                    c.dots.append((e_k, Rrel.T @ e_k1))
            else:  # revolute, cylindrical: the axes aligned
                for m in _perp(nb):
                    c.dots.append((na, m))
            if j.kind in ("cylindrical", "prismatic"):
                c.lines.extend(_perp(na))
        closures.append(c)
    chains = []
    for b in range(tree.nb):
        dofs = []
        k = b
        while k >= 0:
            n = {"free": 6, "spherical": 3, "revolute": 1}[tree.kinds[k]]
            dofs.extend(range(tree.uofs[k], tree.uofs[k] + n))
            k = tree.parent[k]
        chains.append(np.array(sorted(dofs), dtype=np.int64))
    forces = _pack_forces(springs, torques, idx, {j.name: j for j in joints})
    system = LoopSystem(tree, closures, [j.name for j in tj], [j.name for j in rest], chains,
                        forces)  # fmt: skip
    if system.nc:
        s = accelerations(system, q0, u0)[1]
        system.rank0 = int(np.count_nonzero(s > RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
    res = residuals(system, q0)
    scale = max(tree.length, 1.0)
    if res.size and float(np.max(np.abs(res))) > 10 * STATE_TOL * scale:
        k = int(np.argmax(np.abs(res)))
        raise ValueError(
            f"joint {_row_owner(system, k)!r}: violated by {abs(res[k]):.3g} at t = 0 (a "
            f"loop closure must hold within {10 * STATE_TOL * scale:.3g})"
        )
    return system, q0, u0


def _row_owner(system: LoopSystem, k: int) -> str:
    for c in system.closures:
        if k < c.nrows:
            return c.name
        k -= c.nrows
    return "?"


def _kin(system: LoopSystem, q, u):
    """The tree's M, C and the per-body kinematics at (q, u)."""
    M, C, R, x, v, _Ib, S, a = _dynamics(q, u, *_args(system.tree))
    return M, C, R, x, v, S, a


#: row types of the packed rows (:func:`_pack`)
_POINT, _DOT, _LINE = 0, 1, 2


def _pack(closures):
    """The rows as arrays for :func:`_rows_kernel`: type, body a, body b (-1: ground), the
    point component (point rows), and three vectors: (p_a, p_b, -) for point rows, (A, B, -)
    for dot rows, (p_a, p_b, T) for line rows (in each body's frame, world for the ground)."""
    rows = []
    for c in closures:
        if c.point:
            for k in range(3):
                rows.append((_POINT, c.a, c.b, k, c.pa, c.pb, np.zeros(3)))
        for A, B in c.dots:
            rows.append((_DOT, c.a, c.b, 0, A, B, np.zeros(3)))
        for T in c.lines:
            rows.append((_LINE, c.a, c.b, 0, c.pa, c.pb, T))
    n = len(rows)
    typ = np.array([r[0] for r in rows], dtype=np.int64).reshape(n)
    ra = np.array([r[1] for r in rows], dtype=np.int64).reshape(n)
    rb = np.array([r[2] for r in rows], dtype=np.int64).reshape(n)
    comp = np.array([r[3] for r in rows], dtype=np.int64).reshape(n)
    V = np.array([[r[4], r[5], r[6]] for r in rows], dtype=float).reshape(n, 3, 3)
    return typ, ra, rb, comp, V


@njit(cache=True)
def _side(body, anchor, R, x, v, avp, out):
    """World point p, its velocity and acceleration at u' = 0, angular velocity and
    acceleration of ``body`` (-1: the ground, ``anchor`` a world point) into out (5, 3)."""
    if body < 0:
        for i in range(3):
            out[0, i] = anchor[i]
            for k in range(1, 5):
                out[k, i] = 0.0
        return
    for i in range(3):
        out[0, i] = (
            x[body, i]
            + R[body, i, 0] * anchor[0]
            + R[body, i, 1] * anchor[1]
            + R[body, i, 2] * anchor[2]
        )
    w = v[body, :3]
    vo = v[body, 3:]
    al = avp[body, :3]
    ao = avp[body, 3:]
    p = out[0]
    wxp = np.cross(w, p)
    for i in range(3):
        out[1, i] = vo[i] + wxp[i]
    alxp = np.cross(al, p)
    wxpd = np.cross(w, out[1])
    for i in range(3):
        out[2, i] = ao[i] + alxp[i] + wxpd[i]
        out[3, i] = w[i]
        out[4, i] = al[i]


@njit(cache=True)
def _rows_kernel(typ, ra, rb, comp, V, cptr, cidx, R, x, v, S, a, g, want_jac):
    """(phi, J, bias) of the packed rows (:func:`_rows`)."""
    nc = len(typ)
    nu = S.shape[0]
    phi = np.empty(nc)
    bias = np.empty(nc)
    J = np.zeros((nc, nu) if want_jac else (0, nu))
    avp = a.copy()
    for b in range(avp.shape[0]):
        for i in range(3):
            avp[b, 3 + i] += g[i]
    A = np.empty((5, 3))
    B = np.empty((5, 3))
    Ra = np.empty((3, 3))
    Rb = np.empty((3, 3))
    for r in range(nc):
        ia, ib = ra[r], rb[r]
        t = typ[r]
        for i in range(3):
            for j in range(3):
                Ra[i, j] = R[ia, i, j]
                Rb[i, j] = R[ib, i, j] if ib >= 0 else (1.0 if i == j else 0.0)
        if t == _POINT:
            _side(ia, V[r, 0], R, x, v, avp, A)
            _side(ib, V[r, 1], R, x, v, avp, B)
            k = comp[r]
            phi[r] = A[0, k] - B[0, k]
            bias[r] = A[2, k] - B[2, k]
            if want_jac:
                for side in range(2):
                    body = ia if side == 0 else ib
                    if body < 0:
                        continue
                    p = A[0] if side == 0 else B[0]
                    sgn = 1.0 if side == 0 else -1.0
                    for kk in range(cptr[body], cptr[body + 1]):
                        c = cidx[kk]
                        wxp = np.cross(S[c, :3], p)
                        J[r, c] += sgn * (S[c, 3 + k] + wxp[k])
        elif t == _DOT:
            _side(ia, np.zeros(3), R, x, v, avp, A)
            _side(ib, np.zeros(3), R, x, v, avp, B)
            Aw = Ra @ V[r, 0]
            Bw = Rb @ V[r, 1]
            AxB = np.cross(Aw, Bw)
            phi[r] = Aw @ Bw
            dw = A[3] - B[3]
            dAxB = np.cross(np.cross(A[3], Aw), Bw) + np.cross(Aw, np.cross(B[3], Bw))
            bias[r] = dAxB @ dw + AxB @ (A[4] - B[4])
            if want_jac:
                for kk in range(cptr[ia], cptr[ia + 1]):
                    c = cidx[kk]
                    J[r, c] += AxB @ S[c, :3]
                if ib >= 0:
                    for kk in range(cptr[ib], cptr[ib + 1]):
                        c = cidx[kk]
                        J[r, c] -= AxB @ S[c, :3]
        else:
            _side(ia, V[r, 0], R, x, v, avp, A)
            _side(ib, V[r, 1], R, x, v, avp, B)
            T = Ra @ V[r, 2]
            Td = np.cross(A[3], T)
            d = B[0] - A[0]
            dd = B[1] - A[1]
            ddd = B[2] - A[2]
            phi[r] = d @ T
            bias[r] = T @ ddd + 2.0 * (dd @ Td) + d @ (np.cross(A[4], T) + np.cross(A[3], Td))
            if want_jac:
                Txd = np.cross(T, d)
                for kk in range(cptr[ia], cptr[ia + 1]):
                    c = cidx[kk]
                    wxp = np.cross(S[c, :3], A[0])
                    J[r, c] += -(T @ (S[c, 3:] + wxp)) + Txd @ S[c, :3]
                if ib >= 0:
                    for kk in range(cptr[ib], cptr[ib + 1]):
                        c = cidx[kk]
                        wxp = np.cross(S[c, :3], B[0])
                        J[r, c] += T @ (S[c, 3:] + wxp)
    return phi, J, bias


def _rows(system, R, x, v, S, a, g, want_jac=True):
    """(phi (nc,), J (nc, nu), b (nc,)): the rows' residuals, velocity Jacobian and velocity-
    product acceleration (phi'' at u' = 0 is J u' + b). ``a`` is the tree's acceleration at
    u' = 0 including gravity as the ground's upward acceleration, removed here."""
    typ, ra, rb, comp, V = system.packed
    phi, J, bias = _rows_kernel(typ, ra, rb, comp, V, system.cptr, system.cidx, R, x, v, S, a,
                                np.asarray(g, dtype=float), want_jac)  # fmt: skip
    return phi, (J if want_jac else None), bias


def residuals(system: LoopSystem, q) -> np.ndarray:
    """The rows' residuals phi(q) (m for point and line rows, the cosine of an angle for the
    axis rows)."""
    q = np.ascontiguousarray(q, dtype=float)
    _, _, R, x, v, S, a = _kin(system, q, np.zeros(system.tree.nu))
    return _rows(system, R, x, v, S, a, system.tree.gravity, want_jac=False)[0]


def velocity_residuals(system: LoopSystem, q, u) -> np.ndarray:
    """J(q) u, the rows' rates."""
    q = np.ascontiguousarray(q, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    _, _, R, x, v, S, a = _kin(system, q, u)
    return _rows(system, R, x, v, S, a, system.tree.gravity)[1] @ u


@njit(cache=True)
def _cholesky(M):
    """Lower Cholesky factor of the symmetric positive definite M (plain loops: the
    matrices are small, and a LAPACK call per evaluation costs more than the work)."""
    n = M.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            raise FloatingPointError("loop reference: the mass matrix is not positive definite")
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    return L


@njit(cache=True)
def _lsolve(L, B):
    """L^-1 B for the lower triangular L and B (n, m)."""
    n, m = B.shape
    X = B.copy()
    for c in range(m):
        for i in range(n):
            s = X[i, c]
            for k in range(i):
                s -= L[i, k] * X[k, c]
            X[i, c] = s / L[i, i]
    return X


@njit(cache=True)
def _ltsolve(L, b):
    """L^-T b for the lower triangular L."""
    n = len(b)
    x = b.copy()
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]
    return x


@njit(cache=True)
def _finish(L, a0, U, s, Vt, r, rank):
    """a0 - L^-T U_r diag(1/s_r) V_r^T r over the ``rank`` largest singular values."""
    k = len(s)
    c = np.zeros(k)
    for i in range(min(rank, k)):
        t = 0.0
        for j in range(Vt.shape[1]):
            t += Vt[i, j] * r[j]
        c[i] = t / s[i]
    z = np.zeros(U.shape[0])
    for j in range(U.shape[0]):
        t = 0.0
        for i in range(k):
            t += U[j, i] * c[i]
        z[j] = t
    return a0 - _ltsolve(L, z)


def accelerations(system: LoopSystem, q, u, alpha: float = 0.0, rank: int | None = None):
    """(u', sigma): the constrained joint accelerations at (q, u) (module docstring, with
    the drift of the rows damped at the rate ``alpha``, 1/s: J u' = -b - 2 alpha J u -
    alpha^2 phi) and the singular values of L^-1 J^T. ``rank``: the number of singular values
    kept (default: the rows' rank at t = 0, ``system.rank0``; those above RANK_TOL s_1 when
    that is not known yet). The redundant directions are the rows' structure, not a value:
    once the state is a round-off off the loops their singular values are that round-off
    over s_1 (2e-11 on Bricard's loop after 0.01 s), and a threshold on the value would
    keep them and divide by it."""
    tree = system.tree
    q = np.ascontiguousarray(q, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    M, C, R, x, v, S, a = _kin(system, q, u)
    L = _cholesky(M)
    rhs = -C
    if system.has_forces:
        rhs = rhs + generalized_forces(system, R, x, v, S)
    a0 = _ltsolve(L, _lsolve(L, rhs.reshape(-1, 1))[:, 0])
    if not system.nc:
        return a0, np.zeros(0)
    phi, J, bias = _rows(system, R, x, v, S, a, tree.gravity)
    Y = _lsolve(L, np.ascontiguousarray(J.T))
    U, s, Vt = np.linalg.svd(Y, full_matrices=False)
    if not s.size or not s[0] > 0:
        return a0, s
    r = J @ a0 + bias + 2.0 * alpha * (J @ u) + alpha * alpha * phi
    if rank is None:
        rank = system.rank0 or int(np.count_nonzero(s > RANK_TOL * s[0]))
    return _finish(L, a0, U, s, np.ascontiguousarray(Vt), r, rank), s


def rhs_function(system: LoopSystem, alpha: float = 0.0):
    """f(t, y) for an ODE solver, y = (q, u): the tree's joint kinematics and the
    constrained accelerations (drift damped at ``alpha``, 1/s)."""
    tree = system.tree
    nq = tree.nq
    args = _args(tree)
    if not system.active:

        def f_tree(_t, y):
            return _rhs(y, nq, *args)

        return f_tree

    rank0 = system.rank0

    def f(t, y):
        if not np.all(np.isfinite(y)):  # a stage after a rejected one (below): rejected too
            return np.full(len(y), np.nan)
        out = _rhs(y, nq, *args)  # q' (and the unconstrained u', replaced)
        out[nq:], s = accelerations(system, y[:nq], y[nq:], alpha)
        if rank0 and not s[rank0 - 1] >= SINGULAR_TOL * s[0]:
            # a state near a singular configuration: NaN makes DOP853 reject the step (a
            # trial stage of a stiff system may land anywhere), and the driver raises
            # LoopSingular with this message when no smaller step avoids it (every accepted
            # state passes here: DOP853 evaluates f at each step's end)
            f.singular = (
                f"the loops reach a singular configuration near t = {t:.6g} s (the rows' "
                f"smallest singular value {s[rank0 - 1] / s[0]:.3g} of the largest, below "
                f"{SINGULAR_TOL:g}: their rank drops from {rank0}, and the loop's branches "
                "meet); the numerical reference does not follow a branch through it"
            )
            out[:] = np.nan
        return out

    f.singular = None
    return f


def generalized_forces(system: LoopSystem, R, x, v, S) -> np.ndarray:
    """Q (nu,) of the system's force elements at the tree's kinematics (R, x, spatial
    velocities v, motion subspace S of :func:`_kin`)."""
    return _force_kernel(R, x, v, S, system.cptr, system.cidx, *system.forces)


def project_rates(system: LoopSystem, q, du) -> np.ndarray:
    """``du`` with its part violating the velocity constraints removed (the least-squares
    projection onto the null space of J(q)): a perturbation of the joint rates that keeps
    the joints."""
    if not system.nc:
        return du
    q = np.ascontiguousarray(q, dtype=float)
    _, _, R, x, v, S, a = _kin(system, q, np.zeros(system.tree.nu))
    _, J, _ = _rows(system, R, x, v, S, a, system.tree.gravity)
    return du - np.linalg.pinv(J, rcond=RANK_TOL) @ (J @ du)


#: a configuration is singular when some direction the rows' rates allow violates their
#: second-order condition (w . b(q, delta) for w in the left null space of J) by more than this
#: relative to the rows' velocity-product accelerations along the allowed directions
SECOND_ORDER_TOL = 1e-8


def singular_at(system: LoopSystem, q, samples: int = 8, seed: int = 0) -> float:
    """0 at a regular configuration of the loops, else the largest relative violation of the
    rows' second-order condition over ``samples`` random directions of the null space of
    J(q) (the rows' rates allow them): where the rows lose rank at a point of a smooth
    family of configurations (redundant rows, Bricard's loop), every allowed direction keeps
    w . b(q, delta) = 0 for w with w^T J = 0; where two branches meet (the four-bar with all
    links on one line), most allowed directions do not, since only the branches' tangents
    lead anywhere."""
    if not system.nc:
        return 0.0
    tree = system.tree
    q = np.ascontiguousarray(q, dtype=float)
    _, _, R, x, v, S, a = _kin(system, q, np.zeros(tree.nu))
    _, J, _ = _rows(system, R, x, v, S, a, tree.gravity)
    U, s, Vt = np.linalg.svd(J)
    if not s.size or not s[0] > 0:
        return 0.0
    rank = int(np.count_nonzero(s > RANK_TOL * s[0]))
    left = U[:, rank:]  # w with w^T J = 0
    null = Vt[rank:].T  # delta with J delta = 0
    if not left.shape[1] or not null.shape[1]:
        return 0.0
    rng = np.random.default_rng(seed)
    worst, size = 0.0, 0.0
    for _ in range(samples):
        d = null @ rng.standard_normal(null.shape[1])
        d /= np.linalg.norm(d)
        _, _, R, x, v, S, a = _kin(system, q, d)
        _, _, b = _rows(system, R, x, v, S, a, tree.gravity, want_jac=False)
        size = max(size, float(np.max(np.abs(b))))
        worst = max(worst, float(np.max(np.abs(left.T @ b))))
    if not size > 0:
        return 0.0
    rel = worst / size
    return rel if rel > SECOND_ORDER_TOL else 0.0


def constraint_residual_max(system: LoopSystem, Q) -> float:
    """The largest row residual over the joint states Q (n, nq) (m for point and line rows,
    the cosine of the axes' angle error for the others)."""
    if not system.nc:
        return 0.0
    return float(max(np.max(np.abs(residuals(system, q))) for q in Q))


__all__ = [
    "RANK_TOL",
    "Closure",
    "LoopSingular",
    "LoopSystem",
    "accelerations",
    "constraint_residual_max",
    "project_rates",
    "residuals",
    "rhs_function",
    "singular_at",
    "system_from_world",
    "velocity_residuals",
]
