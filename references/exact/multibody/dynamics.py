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
from numba import njit

FREE, SPHERICAL, REVOLUTE = 0, 1, 2


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
def _axis_R(n, th, R):
    """Rot(n, th) for a unit n (Rodrigues)."""
    c, s = np.cos(th), np.sin(th)
    c1 = 1.0 - c
    R[0, 0] = c + c1 * n[0] * n[0]
    R[0, 1] = c1 * n[0] * n[1] - s * n[2]
    R[0, 2] = c1 * n[0] * n[2] + s * n[1]
    R[1, 0] = c1 * n[1] * n[0] + s * n[2]
    R[1, 1] = c + c1 * n[1] * n[1]
    R[1, 2] = c1 * n[1] * n[2] - s * n[0]
    R[2, 0] = c1 * n[2] * n[0] - s * n[1]
    R[2, 1] = c1 * n[2] * n[1] + s * n[0]
    R[2, 2] = c + c1 * n[2] * n[2]


@njit(cache=True)
def _cross(a, b):
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@njit(cache=True)
def _mcross(v, m):
    """Spatial motion cross product v x m (6,)."""
    out = np.empty(6)
    out[:3] = _cross(v[:3], m[:3])
    out[3:] = _cross(v[:3], m[3:]) + _cross(v[3:], m[:3])
    return out


@njit(cache=True)
def _fcross(v, f):
    """Spatial force cross product v x* f (6,)."""
    out = np.empty(6)
    out[:3] = _cross(v[:3], f[:3]) + _cross(v[3:], f[3:])
    out[3:] = _cross(v[:3], f[3:])
    return out


@njit(cache=True)
def _kinematics(q, u, kind, parent, qofs, uofs, X, Y, axis, offset, R, x, S, v, c):
    """Fill R (nb,3,3), x (nb,3), S (nu,6) (the motion subspace columns as rows), v (nb,6)
    and c (nb,6) (velocity-product terms)."""
    nb = len(kind)
    Rrel = np.empty((3, 3))
    Rax = np.empty((3, 3))
    for b in range(nb):
        qo, uo = qofs[b], uofs[b]
        k = kind[b]
        p = parent[b]
        if k == FREE:
            x[b] = q[qo : qo + 3]
            _quat_R(q[qo + 3], q[qo + 4], q[qo + 5], q[qo + 6], R[b])
            vj = np.zeros(6)
            vr = np.zeros(6)
            for i in range(3):
                S[uo + i, :] = 0.0
                S[uo + i, 3 + i] = 1.0
                a = R[b, :, i].copy()
                S[uo + 3 + i, :3] = a
                S[uo + 3 + i, 3:] = _cross(x[b], a)
                vj += S[uo + i] * u[uo + i]
                vr += S[uo + 3 + i] * u[uo + 3 + i]
            vj += vr
            v[b] = vj
            c[b] = _mcross(vj, vr)
            continue
        if p < 0:
            pj = X[b].copy()
            if k == SPHERICAL:
                _quat_R(q[qo], q[qo + 1], q[qo + 2], q[qo + 3], R[b])
            else:
                _axis_R(axis[b], q[qo], Rax)
                R[b] = offset[b] @ Rax
            vp = np.zeros(6)
        else:
            pj = x[p] + R[p] @ X[b]
            if k == SPHERICAL:
                _quat_R(q[qo], q[qo + 1], q[qo + 2], q[qo + 3], Rrel)
            else:
                _axis_R(axis[b], q[qo], Rax)
                Rrel[:, :] = offset[b] @ Rax
            R[b] = R[p] @ Rrel
            vp = v[p]
        x[b] = pj - R[b] @ Y[b]
        vj = np.zeros(6)
        if k == SPHERICAL:
            for i in range(3):
                a = R[b, :, i].copy()
                S[uo + i, :3] = a
                S[uo + i, 3:] = _cross(pj, a)
                vj += S[uo + i] * u[uo + i]
        else:
            a = R[b] @ axis[b]
            S[uo, :3] = a
            S[uo, 3:] = _cross(pj, a)
            vj += S[uo] * u[uo]
        v[b] = vp + vj
        c[b] = _mcross(v[b], vj)


@njit(cache=True)
def _inertia(m, J, R, xg):
    """Spatial inertia (6,6) about the origin, world axes."""
    IG = R @ np.diag(J) @ R.T
    I = np.zeros((6, 6))
    cc = xg[0] * xg[0] + xg[1] * xg[1] + xg[2] * xg[2]
    for i in range(3):
        for j in range(3):
            I[i, j] = IG[i, j] - m * xg[i] * xg[j]
        I[i, i] += m * cc
        I[3 + i, 3 + i] = m
    H = np.array([[0.0, -xg[2], xg[1]], [xg[2], 0.0, -xg[0]], [-xg[1], xg[0], 0.0]]) * m
    I[:3, 3:] = H
    I[3:, :3] = -H
    return I


@njit(cache=True)
def _nu_of(kind, b):
    if kind[b] == FREE:
        return 6
    if kind[b] == SPHERICAL:
        return 3
    return 1


@njit(cache=True)
def _dynamics(q, u, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g):
    """(M (nu,nu), C (nu,), R, x, v, Ib) at the state (q, u): M u' + C = 0."""
    nb = len(kind)
    nu = len(u)
    R = np.zeros((nb, 3, 3))
    x = np.zeros((nb, 3))
    S = np.zeros((nu, 6))
    v = np.zeros((nb, 6))
    c = np.zeros((nb, 6))
    _kinematics(q, u, kind, parent, qofs, uofs, X, Y, axis, offset, R, x, S, v, c)
    Ib = np.zeros((nb, 6, 6))
    for b in range(nb):
        Ib[b] = _inertia(mass[b], J[b], R[b], x[b])
    # recursive Newton-Euler (u' = 0), gravity as an upward acceleration of the ground
    a0 = np.zeros(6)
    a0[3:] = -g
    a = np.zeros((nb, 6))
    f = np.zeros((nb, 6))
    for b in range(nb):
        p = parent[b]
        a[b] = (a0 if p < 0 else a[p]) + c[b]
        f[b] = Ib[b] @ a[b] + _fcross(v[b], Ib[b] @ v[b])
    C = np.zeros(nu)
    Ic = Ib.copy()
    for b in range(nb - 1, -1, -1):
        uo = uofs[b]
        for i in range(_nu_of(kind, b)):
            C[uo + i] = S[uo + i] @ f[b]
        p = parent[b]
        if p >= 0:
            f[p] += f[b]
            Ic[p] += Ic[b]
    # composite-rigid-body algorithm
    M = np.zeros((nu, nu))
    for b in range(nb):
        uo = uofs[b]
        for i in range(uo, uo + _nu_of(kind, b)):
            F = Ic[b] @ S[i]
            a_ = b
            while a_ >= 0:
                ua = uofs[a_]
                for j in range(ua, ua + _nu_of(kind, a_)):
                    Mij = S[j] @ F
                    M[i, j] = Mij
                    M[j, i] = Mij
                a_ = parent[a_]
    return M, C, R, x, v, Ib


@njit(cache=True)
def _qdot(q, u, kind, qofs, uofs, out):
    for b in range(len(kind)):
        qo, uo = qofs[b], uofs[b]
        if kind[b] == REVOLUTE:
            out[qo] = u[uo]
            continue
        if kind[b] == FREE:
            out[qo : qo + 3] = u[uo : uo + 3]
            qo += 3
            uo += 3
        q0, q1, q2, q3 = q[qo], q[qo + 1], q[qo + 2], q[qo + 3]
        w1, w2, w3 = u[uo], u[uo + 1], u[uo + 2]
        out[qo] = 0.5 * (-q1 * w1 - q2 * w2 - q3 * w3)
        out[qo + 1] = 0.5 * (q0 * w1 + q2 * w3 - q3 * w2)
        out[qo + 2] = 0.5 * (q0 * w2 + q3 * w1 - q1 * w3)
        out[qo + 3] = 0.5 * (q0 * w3 + q1 * w2 - q2 * w1)


@njit(cache=True)
def _rhs(y, nq, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g):
    q = y[:nq]
    u = y[nq:]
    M, C, _, _, _, _ = _dynamics(q, u, kind, parent, qofs, uofs, mass, J, X, Y, axis, offset, g)
    out = np.empty(len(y))
    _qdot(q, u, kind, qofs, uofs, out)
    out[nq:] = np.linalg.solve(M, -C)
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
    _, _, R, x, vs, Ib = _dynamics(q, u, *_args(tree))
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
