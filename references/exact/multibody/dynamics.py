"""Recursive dynamics of a :class:`~references.exact.multibody.tree.Tree` in joint coordinates:
the composite-rigid-body algorithm (mass matrix) and the recursive Newton-Euler algorithm (bias
forces), compiled with numba.

Spatial vectors are taken in world axes at the world origin (Featherstone, *Rigid Body
Dynamics Algorithms*, 2008, section 2, "Plücker coordinates" of a single fixed frame), so no
coordinate transforms between links are needed:

- a motion vector v = (w, v_O): the angular velocity and the velocity of the body point that
  is at the origin, v_O = v_G - w x x_G;
- a force vector f = (n_O, f): the moment about the origin and the force;
- cross products v x m = (w x m_w, w x m_v + v_O x m_w) and
  v x* f = (w x n + v_O x f, w x f);
- the spatial inertia of body b about the origin,
  I_O = [[I_G + m (|c|^2 1 - c c^T), m hat(c)], [-m hat(c), m 1]] with c = x_G and
  I_G = R diag(J) R^T, so that I_O v = (L_O, m v_G) (angular momentum about the origin and
  linear momentum).

Motion subspaces S (columns in the same coordinates): a rotation about the unit axis a through
the point p is (a, p x a); a spherical joint has the three columns of the child's axes R e_k
through the joint point, a revolute one the column of its axis R n, a free root three
translations (0, e_k) (constant in world axes) and three rotations about the body axes through
its centre of mass. Every column except the free root's translations is fixed in the child,
so its time derivative is v_child x S (Featherstone, section 2.11); the velocity-product
acceleration of body b is c_b = v_b x (S_b u_b) over those columns.

Recursive Newton-Euler with the accelerations set to zero and gravity as an upward acceleration
of the ground, a_0 = (0, -g): a_b = a_parent + c_b, f_b = I_b a_b + v_b x* I_b v_b, summed from
the leaves inwards; the bias force of a column is C_k = S_k . f (composite force of its body).
Composite-rigid-body algorithm: composite inertias Ic_b = I_b + sum over children;
M_ij = S_i^T Ic_b(i) S_j for every column j of b(i) and of its ancestors (M symmetric). The
joint accelerations solve M u' = -C (no joint forces). Joint kinematics: a free root's x' = v
and q' = q (0, W)/2; a spherical joint's q' = q (0, w_rel)/2; a revolute's theta' = u.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.np import linalg as _numba_linalg

FREE, SPHERICAL, REVOLUTE = 0, 1, 2

# The matrix products and the linear solve call BLAS (dgemm, dgemv, ddot) and LAPACK (dgesv)
# through numba's own entry points (numba_xxgemm, numba_xxgemv, numba_xxdot, numba_xgesv of
# numba's helper library, the routines numba's ``@`` and np.linalg.solve call), with the
# arguments numba passes them for C-contiguous float64 operands: the results are those of
# ``@`` and np.linalg.solve, while the compiled code holds none of numba's generic wrappers
# around them (checks of shapes and layouts, copies, and their exceptions for every operand
# type), which took most of this module's compile time.
_f8p = types.CPointer(types.float64)
if np.dtype(getattr(_numba_linalg, "F_INT_nptype", np.int32)) != np.int32:
    raise ImportError(
        "references.exact.multibody.dynamics: numba's LAPACK takes 64-bit pivot indices "
        "here (ILP64); the dgesv call below passes 32-bit ones"
    )
_GEMM = types.ExternalFunction(
    "numba_xxgemm",
    types.intc(types.char, types.char, types.char, types.intp, types.intp, types.intp,
               _f8p, _f8p, types.intp, _f8p, types.intp, _f8p, _f8p, types.intp),
)  # fmt: skip
_GEMV = types.ExternalFunction(
    "numba_xxgemv",
    types.intc(types.char, types.char, types.intp, types.intp, _f8p, _f8p, types.intp,
               _f8p, _f8p, _f8p),
)  # fmt: skip
_DOT = types.ExternalFunction(
    "numba_xxdot", types.intc(types.char, types.char, types.intp, _f8p, _f8p, _f8p)
)
_GESV = types.ExternalFunction(
    "numba_xgesv",
    types.intc(types.char, types.intp, types.intp, _f8p, types.intp,
               types.CPointer(types.int32), _f8p, types.intp),
)  # fmt: skip
_D, _N, _T = ord("d"), ord("n"), ord("t")
#: alpha = 1 and beta = 0 of the BLAS calls (out = A B)
_ONE = np.ones(1)
_ZERO = np.zeros(1)
# Calls, for C-contiguous float64 operands (n, n) and (n,), with the arguments of numba's ``@``:
#   out = A @ B    _GEMM(_D, _N, _N, n, n, n, _ONE.ctypes, B.ctypes, n, A.ctypes, n,
#                        _ZERO.ctypes, out.ctypes, n)
#   out = A @ B.T  the same with _T in place of the first _N
#   out = A @ x    _GEMV(_D, _T, n, n, _ONE.ctypes, A.ctypes, n, x.ctypes, _ZERO.ctypes,
#                        out.ctypes)
#   cell[0] = a @ b  _DOT(_D, 0, n, a.ctypes, b.ctypes, cell.ctypes)
# Each returns 0 on success; the codes are or-ed together and checked once.
#
# Few compiled functions, each holding what it alone calls: every function numba compiles
# costs ~0.1-0.2 s of its own (its pipeline, wrappers, a module optimised again by each caller).


@njit(cache=True)
def _quat_R(q0, q1, q2, q3, R):
    n = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    s = 2.0 / n
    R[0, 0] = 1.0 - s * (q2 * q2 + q3 * q3)
    R[0, 1] = s * (q1 * q2 - q0 * q3)
    R[0, 2] = s * (q1 * q3 + q0 * q2)
    R[1, 0] = s * (q1 * q2 + q0 * q3)
    R[1, 1] = 1.0 - s * (q1 * q1 + q3 * q3)
    R[1, 2] = s * (q2 * q3 - q0 * q1)
    R[2, 0] = s * (q1 * q3 - q0 * q2)
    R[2, 1] = s * (q2 * q3 + q0 * q1)
    R[2, 2] = 1.0 - s * (q1 * q1 + q2 * q2)


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    """a x b as a tuple."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def _mcross(v, m, out):
    """out = v x m, the spatial motion cross product (6,)."""
    out[0], out[1], out[2] = _cross(v[0], v[1], v[2], m[0], m[1], m[2])
    s0, s1, s2 = _cross(v[0], v[1], v[2], m[3], m[4], m[5])
    t0, t1, t2 = _cross(v[3], v[4], v[5], m[0], m[1], m[2])
    out[3], out[4], out[5] = s0 + t0, s1 + t1, s2 + t2


@njit(cache=True)
def _dynamics(q, u, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g):
    """(M (nu,nu), C (nu,), R, x, v, Ib, S, a) at the state (q, u): M u' + C = 0; S (nu, 6)
    the motion-subspace columns as rows, a (nb, 6) each body's spatial acceleration at
    u' = 0 with gravity as the ground's upward acceleration (a_b + (0, g) is the
    velocity-product acceleration)."""
    nb = len(kind)
    nu = len(u)
    # every element of these is written by the kinematics below
    R = np.empty((nb, 3, 3))
    x = np.empty((nb, 3))
    S = np.empty((nu, 6))
    v = np.empty((nb, 6))
    c = np.empty((nb, 6))
    # kinematics: R, x, S (the motion subspace columns as rows), v, and the velocity-product
    # terms c
    Rrel = np.empty((3, 3))
    Rax = np.empty((3, 3))
    pj = np.empty(3)
    w3 = np.empty(3)
    ax = np.empty(3)
    vj = np.empty(6)
    vr = np.empty(6)
    err = 0
    for b in range(nb):
        qo, uo = qofs[b], uofs[b]
        k = kind[b]
        p = parent[b]
        if k == FREE:
            for i in range(3):
                x[b, i] = q[qo + i]
            _quat_R(q[qo + 3], q[qo + 4], q[qo + 5], q[qo + 6], R[b])
            for j in range(6):
                vj[j] = 0.0
                vr[j] = 0.0
            for i in range(3):
                for j in range(6):
                    S[uo + i, j] = 0.0
                S[uo + i, 3 + i] = 1.0
                r = uo + 3 + i
                for j in range(3):
                    S[r, j] = R[b, j, i]
                S[r, 3], S[r, 4], S[r, 5] = _cross(x[b, 0], x[b, 1], x[b, 2],
                                                   R[b, 0, i], R[b, 1, i], R[b, 2, i])  # fmt: skip
                for j in range(6):
                    vj[j] += S[uo + i, j] * u[uo + i]
                    vr[j] += S[r, j] * u[r]
            for j in range(6):
                vj[j] += vr[j]
                v[b, j] = vj[j]
            _mcross(vj, vr, c[b])
            continue
        if k == SPHERICAL:
            _quat_R(q[qo], q[qo + 1], q[qo + 2], q[qo + 3], Rrel)
        else:
            # Rrel = offset Rot(n, th), Rot(n, th) for the unit axis n by Rodrigues' formula
            n = axis[b]
            th = q[qo]
            cs, sn = np.cos(th), np.sin(th)
            c1 = 1.0 - cs
            Rax[0, 0] = cs + c1 * n[0] * n[0]
            Rax[0, 1] = c1 * n[0] * n[1] - sn * n[2]
            Rax[0, 2] = c1 * n[0] * n[2] + sn * n[1]
            Rax[1, 0] = c1 * n[1] * n[0] + sn * n[2]
            Rax[1, 1] = cs + c1 * n[1] * n[1]
            Rax[1, 2] = c1 * n[1] * n[2] - sn * n[0]
            Rax[2, 0] = c1 * n[2] * n[0] - sn * n[1]
            Rax[2, 1] = c1 * n[2] * n[1] + sn * n[0]
            Rax[2, 2] = cs + c1 * n[2] * n[2]
            err |= _GEMM(_D, _N, _N, 3, 3, 3, _ONE.ctypes, Rax.ctypes, 3, offset[b].ctypes, 3,
                         _ZERO.ctypes, Rrel.ctypes, 3)  # fmt: skip
        if p < 0:
            for i in range(3):
                pj[i] = X[b, i]
                for j in range(3):
                    R[b, i, j] = Rrel[i, j]
        else:
            err |= _GEMV(_D, _T, 3, 3, _ONE.ctypes, R[p].ctypes, 3, X[b].ctypes, _ZERO.ctypes,
                         w3.ctypes)  # fmt: skip
            for i in range(3):
                pj[i] = x[p, i] + w3[i]
            err |= _GEMM(_D, _N, _N, 3, 3, 3, _ONE.ctypes, Rrel.ctypes, 3, R[p].ctypes, 3,
                         _ZERO.ctypes, R[b].ctypes, 3)  # fmt: skip
        err |= _GEMV(_D, _T, 3, 3, _ONE.ctypes, R[b].ctypes, 3, Y[b].ctypes, _ZERO.ctypes,
                     w3.ctypes)  # fmt: skip
        for i in range(3):
            x[b, i] = pj[i] - w3[i]
        for j in range(6):
            vj[j] = 0.0
        if k == SPHERICAL:
            for i in range(3):
                r = uo + i
                for j in range(3):
                    S[r, j] = R[b, j, i]
                S[r, 3], S[r, 4], S[r, 5] = _cross(pj[0], pj[1], pj[2],
                                                   R[b, 0, i], R[b, 1, i], R[b, 2, i])  # fmt: skip
                for j in range(6):
                    vj[j] += S[r, j] * u[r]
        else:
            err |= _GEMV(_D, _T, 3, 3, _ONE.ctypes, R[b].ctypes, 3, axis[b].ctypes,
                         _ZERO.ctypes, ax.ctypes)  # fmt: skip
            for j in range(3):
                S[uo, j] = ax[j]
            S[uo, 3], S[uo, 4], S[uo, 5] = _cross(pj[0], pj[1], pj[2], ax[0], ax[1], ax[2])
            for j in range(6):
                vj[j] += S[uo, j] * u[uo]
        for j in range(6):
            v[b, j] = (0.0 if p < 0 else v[p, j]) + vj[j]
        _mcross(v[b], vj, c[b])
    # spatial inertias about the origin, world axes: IG = R diag(J) R^T in the upper left
    # block (less m (c c^T - |c|^2 1)), m hat(c) upper right, -m hat(c) lower left, m 1
    Ib = np.empty((nb, 6, 6))
    D = np.empty((3, 3))
    RD = np.empty((3, 3))
    IG = np.empty((3, 3))
    for b in range(nb):
        m = mass[b]
        xg = x[b]
        I = Ib[b]
        for i in range(3):
            for j in range(3):
                D[i, j] = J[b, i] if i == j else 0.0
        err |= _GEMM(_D, _N, _N, 3, 3, 3, _ONE.ctypes, D.ctypes, 3, R[b].ctypes, 3,
                     _ZERO.ctypes, RD.ctypes, 3)  # fmt: skip
        err |= _GEMM(_D, _T, _N, 3, 3, 3, _ONE.ctypes, R[b].ctypes, 3, RD.ctypes, 3,
                     _ZERO.ctypes, IG.ctypes, 3)  # fmt: skip
        for i in range(6):
            for j in range(6):
                I[i, j] = 0.0
        cc = xg[0] * xg[0] + xg[1] * xg[1] + xg[2] * xg[2]
        for i in range(3):
            for j in range(3):
                I[i, j] = IG[i, j] - m * xg[i] * xg[j]
            I[i, i] += m * cc
            I[3 + i, 3 + i] = m
        for i in range(3):
            I[i, 3 + i] = 0.0 * m
            I[3 + i, i] = -(0.0 * m)
        I[0, 4] = -xg[2] * m
        I[0, 5] = xg[1] * m
        I[1, 3] = xg[2] * m
        I[1, 5] = -xg[0] * m
        I[2, 3] = -xg[1] * m
        I[2, 4] = xg[0] * m
        for i in range(3):
            for j in range(3):
                if i != j:
                    I[3 + i, j] = -I[i, 3 + j]
    nus = np.empty(nb, dtype=np.int64)  # joint rates of each body
    for b in range(nb):
        nus[b] = 6 if kind[b] == FREE else (3 if kind[b] == SPHERICAL else 1)
    # recursive Newton-Euler (u' = 0), gravity as an upward acceleration of the ground:
    # f_b = I_b a_b + v_b x* (I_b v_b)
    a = np.empty((nb, 6))
    f = np.empty((nb, 6))
    h = np.empty(6)
    cell = np.empty(1)
    for b in range(nb):
        p = parent[b]
        for j in range(6):
            if p >= 0:
                a[b, j] = a[p, j] + c[b, j]
            elif j < 3:
                a[b, j] = 0.0 + c[b, j]
            else:
                a[b, j] = -g[j - 3] + c[b, j]
        err |= _GEMV(_D, _T, 6, 6, _ONE.ctypes, Ib[b].ctypes, 6, a[b].ctypes, _ZERO.ctypes,
                     f[b].ctypes)  # fmt: skip
        err |= _GEMV(_D, _T, 6, 6, _ONE.ctypes, Ib[b].ctypes, 6, v[b].ctypes, _ZERO.ctypes,
                     h.ctypes)  # fmt: skip
        vb = v[b]
        s0, s1, s2 = _cross(vb[0], vb[1], vb[2], h[0], h[1], h[2])
        t0, t1, t2 = _cross(vb[3], vb[4], vb[5], h[3], h[4], h[5])
        r0, r1, r2 = _cross(vb[0], vb[1], vb[2], h[3], h[4], h[5])
        f[b, 0] += s0 + t0
        f[b, 1] += s1 + t1
        f[b, 2] += s2 + t2
        f[b, 3] += r0
        f[b, 4] += r1
        f[b, 5] += r2
    C = np.empty(nu)
    Ic = np.empty((nb, 6, 6))
    for b in range(nb):
        for j in range(6):
            for k in range(6):
                Ic[b, j, k] = Ib[b, j, k]
    for b in range(nb - 1, -1, -1):
        uo = uofs[b]
        for i in range(nus[b]):
            err |= _DOT(_D, 0, 6, S[uo + i].ctypes, f[b].ctypes, cell.ctypes)
            C[uo + i] = cell[0]
        p = parent[b]
        if p >= 0:
            for j in range(6):
                f[p, j] += f[b, j]
                for k in range(6):
                    Ic[p, j, k] += Ic[b, j, k]
    # composite-rigid-body algorithm
    M = np.empty((nu, nu))
    for i in range(nu):
        for j in range(nu):
            M[i, j] = 0.0
    F = np.empty(6)
    for b in range(nb):
        uo = uofs[b]
        for i in range(uo, uo + nus[b]):
            err |= _GEMV(_D, _T, 6, 6, _ONE.ctypes, Ic[b].ctypes, 6, S[i].ctypes,
                         _ZERO.ctypes, F.ctypes)  # fmt: skip
            a_ = b
            while a_ >= 0:
                ua = uofs[a_]
                for j in range(ua, ua + nus[a_]):
                    err |= _DOT(_D, 0, 6, S[j].ctypes, F.ctypes, cell.ctypes)
                    M[i, j] = cell[0]
                    M[j, i] = cell[0]
                a_ = parent[a_]
    if err != 0:
        raise RuntimeError("multibody reference: a BLAS call returned an error")
    return M, C, R, x, v, Ib, S, a


@njit(cache=True)
def _rhs(y, nq, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g):
    q = y[:nq]
    u = y[nq:]
    M, C, _, _, _, _, _, _ = _dynamics(
        q, u, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g
    )
    out = np.empty(len(y))
    # joint kinematics q'
    for b in range(len(kind)):
        qo, uo = qofs[b], uofs[b]
        if kind[b] == REVOLUTE:
            out[qo] = u[uo]
            continue
        if kind[b] == FREE:
            for i in range(3):
                out[qo + i] = u[uo + i]
            qo += 3
            uo += 3
        q0, q1, q2, q3 = q[qo], q[qo + 1], q[qo + 2], q[qo + 3]
        w1, w2, w3 = u[uo], u[uo + 1], u[uo + 2]
        out[qo] = 0.5 * (-q1 * w1 - q2 * w2 - q3 * w3)
        out[qo + 1] = 0.5 * (q0 * w1 + q2 * w3 - q3 * w2)
        out[qo + 2] = 0.5 * (q0 * w2 + q3 * w1 - q1 * w3)
        out[qo + 3] = 0.5 * (q0 * w3 + q1 * w2 - q2 * w1)
    # u' = M^-1 (-C) by LU with partial pivoting (LAPACK dgesv, as np.linalg.solve); M is
    # symmetric, so its C layout is its Fortran one; M and C are this call's own, and dgesv
    # overwrites them (the factors, the solution)
    n = len(C)
    for i in range(n):
        C[i] = -C[i]
        if not np.isfinite(C[i]):
            raise FloatingPointError("multibody reference: non-finite bias forces")
        for j in range(n):
            if not np.isfinite(M[i, j]):
                raise FloatingPointError("multibody reference: non-finite mass matrix")
    ipiv = np.empty(n, dtype=np.int32)
    r = _GESV(_D, n, 1, M.ctypes, n, ipiv.ctypes, C.ctypes, n)
    if r < 0:
        raise RuntimeError("multibody reference: dgesv refused its arguments")
    if r > 0:
        raise FloatingPointError("multibody reference: the mass matrix is singular")
    for i in range(n):
        out[nq + i] = C[i]
    return out


def _args(tree):
    return (
        tree.kind,
        tree.parent,
        tree.qofs,
        tree.uofs,
        tree.mass,
        tree.inertia,
        tree.X,
        tree.Y,
        tree.axis,
        tree.offset,
        tree.gravity,
    )


def mass_matrix_and_bias(tree, q, u) -> tuple[np.ndarray, np.ndarray]:
    """(M, C) at the state (q, u): the joint-space mass matrix (nu, nu) by the composite-rigid-
    body algorithm and the bias forces (nu,) (velocity products and gravity) by recursive
    Newton-Euler, so that M u' + C = 0. Units: u's own (rad/s, m/s), M in kg m^2 / kg / kg m."""
    q = np.ascontiguousarray(q, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    M, C, *_ = _dynamics(q, u, *_args(tree))
    return M, C


def rhs(tree, y: np.ndarray) -> np.ndarray:
    """d/dt of the state y = (q, u) (nq + nu,)."""
    a = _args(tree)
    return _rhs(np.ascontiguousarray(y, dtype=float), tree.nq, *a)


def rhs_function(tree):
    """f(t, y) for an ODE solver: the compiled right-hand side bound to ``tree``."""
    a = _args(tree)
    nq = tree.nq

    def f(_t, y):
        return _rhs(y, nq, *a)

    return f


def body_states(tree, q, u):
    """World state of every body at the joint state (q, u): x (nb,3) centres of mass,
    R (nb,3,3) body to world, v (nb,3) centre-of-mass velocities, W (nb,3) body angular
    velocities, and the spatial velocities and inertias (nb,6) and (nb,6,6) about the origin."""
    q = np.ascontiguousarray(q, dtype=float)
    u = np.ascontiguousarray(u, dtype=float)
    _, _, R, x, vs, Ib, _, _ = _dynamics(q, u, *_args(tree))
    w = vs[:, :3]
    vG = vs[:, 3:] + np.cross(w, x)  # v_G = v_O + w x x_G
    W = np.einsum("bji,bj->bi", R, w)
    return x, R, vG, W, vs, Ib


def invariants(tree, q, u) -> dict:
    """Energy (J: kinetic + potential -sum m g.x), linear momentum (3,) and angular momentum
    about the world origin (3,) of the state (q, u)."""
    x, _, _, _, vs, Ib = body_states(tree, q, u)
    h = np.einsum("bij,bj->i", Ib, vs)  # (L_O, p)
    T = 0.5 * float(np.einsum("bi,bij,bj->", vs, Ib, vs))
    V = -float(np.sum(tree.mass * (x @ tree.gravity)))
    return {"energy": T + V, "kinetic": T, "linear_momentum": h[3:], "angular_momentum": h[:3]}
