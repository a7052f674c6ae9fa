"""The force elements of a system (:mod:`scenarios.force_elements`: linear spring-dampers
between two bodies or a body and the ground, constant torques about a joint's axis) as
generalized forces on the reduced-coordinate tree of :mod:`references.exact.multibody.loops`:
packed once into arrays (:func:`_pack_forces`), then summed at each evaluation by a compiled
kernel (:func:`_force_kernel`)."""

from __future__ import annotations

import numpy as np
from numba import njit


def _pack_forces(springs, torques, idx, joints_by_name):
    """The force elements as arrays for :func:`_force_kernel`: springs (body a, body b (-1:
    ground), anchor a, anchor b (a world point for the ground), k, c, l0) and torques
    (body a, body b, the axis in a's frame, tau), bodies in tree order."""
    sa = np.array([idx[s.body_a] for s in springs], dtype=np.int64)
    sb = np.array([-1 if s.body_b is None else idx[s.body_b] for s in springs], dtype=np.int64)
    spa = np.array([s.anchor_a for s in springs], dtype=float).reshape(-1, 3)
    spb = np.array([s.anchor_b for s in springs], dtype=float).reshape(-1, 3)
    k = np.array([s.stiffness for s in springs], dtype=float)
    c = np.array([s.damping for s in springs], dtype=float)
    l0 = np.array([s.rest_length for s in springs], dtype=float)
    js = [joints_by_name[t.joint] for t in torques]
    ta = np.array([idx[j.body_a] for j in js], dtype=np.int64)
    tb = np.array([-1 if j.body_b is None else idx[j.body_b] for j in js], dtype=np.int64)
    tax = np.array([np.asarray(j.axis_a, float) / np.linalg.norm(j.axis_a) for j in js],
                   dtype=float).reshape(-1, 3)  # fmt: skip
    tau = np.array([t.torque for t in torques], dtype=float)
    return sa, sb, spa, spb, k, c, l0, ta, tb, tax, tau


@njit(cache=True)
def _force_kernel(R, x, v, S, cptr, cidx, sa, sb, spa, spb, k, c, l0, ta, tb, tax, tau):
    """Q (nu,): the generalized forces of the force elements, sum over bodies of S_c . f_b
    for the columns c of each body's chain, f_b = (moment about the origin, force) of the
    elements on body b (module :mod:`scenarios.force_elements`: a spring pulls point a by
    -(k (l - l0) + c l') e, e = (p_a - p_b)/l, point b by the opposite; a torque is tau u on
    a, u = R_a axis_a, and -tau u on b)."""
    nb = x.shape[0]
    f = np.zeros((nb, 6))
    pa = np.empty(3)
    pb = np.empty(3)
    va = np.empty(3)
    vb = np.empty(3)
    for i in range(len(sa)):
        a, b = sa[i], sb[i]
        for r in range(3):
            pa[r] = (x[a, r] + R[a, r, 0] * spa[i, 0] + R[a, r, 1] * spa[i, 1]
                     + R[a, r, 2] * spa[i, 2])  # fmt: skip
        wxp = np.cross(v[a, :3], pa)
        for r in range(3):
            va[r] = v[a, 3 + r] + wxp[r]
        if b >= 0:
            for r in range(3):
                pb[r] = (x[b, r] + R[b, r, 0] * spb[i, 0] + R[b, r, 1] * spb[i, 1]
                         + R[b, r, 2] * spb[i, 2])  # fmt: skip
            wxp = np.cross(v[b, :3], pb)
            for r in range(3):
                vb[r] = v[b, 3 + r] + wxp[r]
        else:
            for r in range(3):
                pb[r] = spb[i, r]
                vb[r] = 0.0
        d = pa - pb
        length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        e = d / length
        rate = e[0] * (va[0] - vb[0]) + e[1] * (va[1] - vb[1]) + e[2] * (va[2] - vb[2])
        F = -(k[i] * (length - l0[i]) + c[i] * rate) * e
        m = np.cross(pa, F)
        for r in range(3):
            f[a, r] += m[r]
            f[a, 3 + r] += F[r]
        if b >= 0:
            m = np.cross(pb, F)
            for r in range(3):
                f[b, r] -= m[r]
                f[b, 3 + r] -= F[r]
    for i in range(len(ta)):
        a, b = ta[i], tb[i]
        for r in range(3):
            u = R[a, r, 0] * tax[i, 0] + R[a, r, 1] * tax[i, 1] + R[a, r, 2] * tax[i, 2]
            f[a, r] += tau[i] * u
            if b >= 0:
                f[b, r] -= tau[i] * u
    Q = np.zeros(S.shape[0])
    for bb in range(nb):
        for kk in range(cptr[bb], cptr[bb + 1]):
            col = cidx[kk]
            s = 0.0
            for r in range(6):
                s += S[col, r] * f[bb, r]
            Q[col] += s
    return Q
