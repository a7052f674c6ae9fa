"""The assembled system evaluated at states, in NumPy: constraint rows and their rates, the
constraint Jacobian, the checks of an initial state, the projection of initial velocities
onto the joints, energy and momenta, the force elements' potential.

These serve the checks of the initial state and of saved states and the invariants written
with a run; the compiled kernel has its own copy of the row formulas (``_rows.py``,
``_block3.py``, ``_band5.py``). The rows, their primitives and the conventions are those of
:mod:`director_model.system.model`.
"""

from __future__ import annotations

import numpy as np

from director_model.errors import InvalidStateError
from director_model.system.model import (
    DOT,
    INIT_TOL,
    LINE,
    POINT,
    Assembly,
    Body,
    InvalidJointError,
    InvalidMechanismError,
    _perp_pair,
    assemble,
)


def rows_numpy(asm: Assembly, X, R, V=None, Wb=None):
    """Values of the constraint rows, and with velocities their time derivatives, for states
    X (..., nb, 3), R (..., nb, 3, 3), V (..., nb, 3), Wb (..., nb, 3) (body axes).
    Returns g (..., nrow) and, if V is given, gdot (..., nrow)."""
    X = np.asarray(X)
    R = np.asarray(R)
    lead = X.shape[:-2]
    nrow = asm.rint.shape[0]
    g = np.zeros(lead + (nrow,))
    gd = np.zeros(lead + (nrow,)) if V is not None else None
    if V is not None:
        W = np.einsum("...ij,...j->...i", R, Wb)  # world angular velocity
    zero = np.zeros(lead + (3,))
    eye = np.broadcast_to(np.eye(3), lead + (3, 3))
    for r in range(nrow):
        prim, a, b, k = asm.rint[r]
        va, vb, vc, c = asm.rvec[r, 0:3], asm.rvec[r, 3:6], asm.rvec[r, 6:9], asm.rvec[r, 9]
        xa, Ra = X[..., a, :], R[..., a, :, :]
        xb, Rb = (zero, eye) if b < 0 else (X[..., b, :], R[..., b, :, :])
        ra = Ra @ va
        rb = Rb @ vb
        if V is not None:
            vA, wA = V[..., a, :], W[..., a, :]
            vB, wB = (zero, zero) if b < 0 else (V[..., b, :], W[..., b, :])
        if prim == POINT:
            g[..., r] = (xa + ra - xb - rb)[..., k]
            if V is not None:
                gd[..., r] = (vA + np.cross(wA, ra) - vB - np.cross(wB, rb))[..., k]
        elif prim == DOT:
            g[..., r] = np.sum(ra * rb, axis=-1) - c
            if V is not None:
                gd[..., r] = np.sum(np.cross(wA, ra) * rb + ra * np.cross(wB, rb), axis=-1)
        else:
            u = Ra @ vc
            s = xb + rb - xa - ra
            g[..., r] = np.sum(s * u, axis=-1)
            if V is not None:
                sd = vB + np.cross(wB, rb) - vA - np.cross(wA, ra)
                gd[..., r] = np.sum(sd * u + s * np.cross(wA, u), axis=-1)
    return g, gd


def jacobian_numpy(asm: Assembly, X, R) -> np.ndarray:
    """The constraint Jacobian (nrow, 6 nb) at one state: row r, columns 6 i .. 6 i + 5 are
    (dg_r/dx_i, dg_r/dtheta_i) with theta_i the world rotation increment of body i
    (delta d = delta theta x d), so that gdot = G (v_1, w_1, v_2, w_2, ...)."""
    nb = X.shape[0]
    nrow = asm.rint.shape[0]
    G = np.zeros((nrow, 6 * nb))
    for r in range(nrow):
        prim, a, b, k = asm.rint[r]
        va, vb, vc = asm.rvec[r, 0:3], asm.rvec[r, 3:6], asm.rvec[r, 6:9]
        Ra = R[a]
        xa = X[a]
        xb, Rb = (np.zeros(3), np.eye(3)) if b < 0 else (X[b], R[b])
        ra, rb = Ra @ va, Rb @ vb
        if prim == POINT:
            e = np.eye(3)[k]
            Ja = np.r_[e, np.cross(ra, e)]
            Jb = np.r_[-e, -np.cross(rb, e)]
        elif prim == DOT:
            Ja = np.r_[np.zeros(3), np.cross(ra, rb)]
            Jb = np.r_[np.zeros(3), np.cross(rb, ra)]
        else:
            u = Ra @ vc
            s = xb + rb - xa - ra
            Ja = np.r_[-u, -np.cross(ra, u) + np.cross(u, s)]
            Jb = np.r_[u, np.cross(rb, u)]
        G[r, 6 * a : 6 * a + 6] += Ja
        if b >= 0:
            G[r, 6 * b : 6 * b + 6] += Jb
    return G


def _state_arrays(bodies):
    X = np.array([b.position for b in bodies])
    R = np.array([b.rotation for b in bodies])
    V = np.array([b.velocity for b in bodies])
    W = np.array([b.omega_body for b in bodies])
    return X, R, V, W


def _mobility(bodies, R) -> np.ndarray:
    """Inverse of the 6 nb x 6 nb kinetic metric blockdiag(m 1, R I R^T) (all I_k > 0)."""
    nb = len(bodies)
    Minv = np.zeros((6 * nb, 6 * nb))
    for i, b in enumerate(bodies):
        Minv[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = np.eye(3) / b.mass
        Minv[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = R[i] @ np.diag(1 / b.inertia) @ R[i].T
    return Minv


def check_initial(asm: Assembly, bodies, tol: float = INIT_TOL) -> tuple[int, int]:
    """Check that every joint holds at t = 0 (positions and velocities) and that the
    mechanism keeps a degree of freedom. Returns (rank of G, degrees of freedom).

    Raises InvalidJointError naming the joint, its largest gap (m, or the dot product of
    axes) and the rule; InvalidStateError for velocities violating a joint (the residual,
    and the pointer to :func:`project_velocities`); InvalidMechanismError for a locked
    mechanism (no degree of freedom left)."""
    X, R, V, W = _state_arrays(bodies)
    nrow = asm.rint.shape[0]
    if nrow == 0:
        return 0, 6 * len(bodies)
    g, gd = rows_numpy(asm, X, R, V, W)
    for j, jn in enumerate(asm.joint_names):
        rows = np.flatnonzero(asm.row_joint == j)
        if rows.size == 0:
            continue
        gap = g[rows]
        worst = int(rows[np.argmax(np.abs(gap))])
        if np.max(np.abs(gap)) > tol:
            prim = asm.rint[worst, 0]
            if prim in (POINT, LINE):  # the distance: the norm of the joint's rows of that kind
                d = float(np.linalg.norm(g[rows[asm.rint[rows, 0] == prim]]))
                what = (
                    f"the anchors do not coincide at t = 0: gap |x_a + R_a anchor_a - x_b - "
                    f"R_b anchor_b| = {d:.6g} m (tolerance {tol:g} m)"
                    if prim == POINT
                    else f"anchor_b is not on the axis line through anchor_a at t = 0: distance "
                    f"{d:.6g} m (tolerance {tol:g} m)"
                )
            else:
                what = (
                    f"the axes violate the joint at t = 0: a dot product of the joint's unit "
                    f"axes is {float(g[worst]):.6g} where it must be 0 (tolerance {tol:g}); "
                    "revolute/cylindrical/prismatic need R_a axis_a parallel to R_b axis_b, "
                    "universal needs them perpendicular"
                )
            raise InvalidJointError(f"joint {jn!r}: {what}")
    G = jacobian_numpy(asm, X, R)
    s = np.linalg.svd(G, compute_uv=False)
    rank = int(np.sum(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
    dof = 6 * len(bodies) - rank
    if dof == 0:
        raise InvalidMechanismError(
            f"the joints leave no degree of freedom (rank of the constraint Jacobian {rank} = "
            f"6 x {len(bodies)} bodies): the mechanism is locked, a rigid structure with "
            "nothing to integrate"
        )
    vscale = max(1.0, float(np.abs(V).max()), float(np.abs(W).max()) * asm.length_scale)
    for j, jn in enumerate(asm.joint_names):
        rows = np.flatnonzero(asm.row_joint == j)
        if rows.size and np.max(np.abs(gd[rows])) > tol * vscale:
            raise InvalidStateError(
                f"joint {jn!r}: the initial velocities violate the joint: the rate of its "
                f"constraints is {np.abs(gd[rows]).max():.6g} (m/s, or 1/s for axes; "
                f"tolerance {tol * vscale:g}); give consistent velocity/omega_body or call "
                "director_model.system.project_velocities(bodies, joints) explicitly"
            )
    return rank, dof


def project_velocities(bodies, joints) -> list[Body]:
    """Return copies of ``bodies`` whose velocities satisfy every joint: the projection of
    (v, w) onto the null space of the constraint Jacobian G in the kinetic-energy metric
    (the consistent velocities closest to the given ones in kinetic energy; the minimum-norm
    multiplier solve handles redundant joints). Positions are not changed (they must
    satisfy the joints already). Never called implicitly by the integrators."""
    bodies = list(bodies)
    asm = assemble(bodies, joints)
    X, R, V, W = _state_arrays(bodies)
    if asm.rint.shape[0] == 0:
        return bodies
    G = jacobian_numpy(asm, X, R)
    Minv = _mobility(bodies, R)
    u = np.concatenate([np.r_[V[i], R[i] @ W[i]] for i in range(len(bodies))])
    S = G @ Minv @ G.T
    mu = np.linalg.lstsq(S, G @ u, rcond=1e-12)[0]
    u = u - Minv @ (G.T @ mu)
    out = []
    for i, b in enumerate(bodies):
        out.append(
            Body(
                b.name, b.mass, b.inertia, b.position, b.rotation, u[6 * i : 6 * i + 3],
                R[i].T @ u[6 * i + 3 : 6 * i + 6],
            )
        )  # fmt: skip
    return out


def energy_momentum(bodies_B: np.ndarray, gravity, X, V, R, W):
    """Energy (...,), linear momentum (..., 3), angular momentum about the world origin
    (..., 3) of states X, V (..., nb, 3), R (..., nb, 3, 3), W (..., nb, 3) body axes;
    ``bodies_B`` the (nb, 7) body table of :class:`Assembly`. E = sum 1/2 m |v|^2 +
    1/2 W . I W - m g . x."""
    m = bodies_B[:, 0]
    I = bodies_B[:, 1:4]
    g = np.asarray(gravity, dtype=float)
    E = (
        0.5 * np.sum(m[:, None] * V * V, axis=(-2, -1))
        + 0.5 * np.sum(I * W * W, axis=(-2, -1))
        - np.sum(m[:, None] * (X @ g)[..., None], axis=(-2, -1))
    )
    p = np.sum(m[:, None] * V, axis=-2)
    L = np.sum(np.cross(X, m[:, None] * V) + np.einsum("...ij,...j->...i", R, I * W), axis=-2)
    return E, p, L


def force_potential(fint, fvec, X, R, R0, theta_prev=None):
    """(V (n,) J, theta (ne,)): the force elements' potential at states X (n, nb, 3),
    R (n, nb, 3, 3) of one run in time order, sum 1/2 k (l - l0)^2 less sum tau theta, theta
    the rotation of a torqued joint's body a relative to its body b about the axis since the
    attitudes R0 (nb, 3, 3) of t = 0, unwrapped along the states from ``theta_prev`` (the
    elements' angles at the state before these, 0 by default); and the angles of the last
    state (to continue from)."""
    X = np.asarray(X)
    R = np.asarray(R)
    V = np.zeros(X.shape[0])
    last = np.zeros(len(fint))
    for e, ((kind, a, b), f) in enumerate(zip(fint, fvec, strict=True)):
        Ra = R[:, a]
        Rb = np.broadcast_to(np.eye(3), Ra.shape) if b < 0 else R[:, b]
        if kind == 0:
            pa = X[:, a] + Ra @ f[0:3]
            pb = np.broadcast_to(f[3:6], pa.shape) if b < 0 else X[:, b] + Rb @ f[3:6]
            V += 0.5 * f[6] * (np.linalg.norm(pa - pb, axis=1) - f[8]) ** 2
            continue
        u = Ra @ f[0:3]
        m1, _ = _perp_pair(f[0:3])
        Rb0 = np.eye(3) if b < 0 else R0[b]
        pb = Rb @ (Rb0.T @ (R0[a] @ m1))  # the b vector that coincided with m1 at t = 0
        pa = Ra @ m1
        th = np.arctan2(np.einsum("ni,ni->n", u, np.cross(pb, pa)), np.einsum("ni,ni->n", pb, pa))
        prev = 0.0 if theta_prev is None else float(theta_prev[e])
        th = np.unwrap(np.concatenate([[prev], th]))[1:]
        if th.size:
            last[e] = th[-1]
        V -= f[6] * th
    return V, last
