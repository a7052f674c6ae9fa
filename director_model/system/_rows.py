"""The joint rows and the forces of the system kernels, general code for every joint kind
(model.py's POINT, DOT and LINE rows, one row at a time): the rows' values and Jacobians
(:func:`_rows`), the joint forces -G^T lambda (:func:`_forces`), the rows' rates G u
(:func:`_vres`), and the force elements' forces and torques (:func:`_ext`). The block solver's
ball joints (_block3.py) and the loop solver's revolute joints (_band5.py) have their own
versions of the first three with the same numbers; the contact kernel
(director_model/contact/_stage_rows.py) calls :func:`_rows` for its joints.
"""

from __future__ import annotations

import math

from numba import njit

from director_model.system._block3 import _U, _dot_row
from director_model.system._common import _mul, _row9, _zero2


@njit(forceinline=True)
def _rows(rint, rvec, X, D, gv, Jc):
    """Row values gv (nrow,) and Jacobians Jc (nrow, 12) at positions X (nb, 3) and
    directors D (nb, 9); body index -1 is the ground (x = 0, D = 1)."""
    for r0 in range(rint.shape[0]):
        r = _U(r0)
        prim = rint[r, 0]
        a = _U(rint[r, 1])
        b = rint[r, 2]
        k = rint[r, 3]
        va0, va1, va2 = rvec[r, 0], rvec[r, 1], rvec[r, 2]
        vb0, vb1, vb2 = rvec[r, 3], rvec[r, 4], rvec[r, 5]
        ra0 = D[a, 0] * va0 + D[a, 1] * va1 + D[a, 2] * va2
        ra1 = D[a, 3] * va0 + D[a, 4] * va1 + D[a, 5] * va2
        ra2 = D[a, 6] * va0 + D[a, 7] * va1 + D[a, 8] * va2
        if b >= 0:
            ub = _U(b)
            rb0 = D[ub, 0] * vb0 + D[ub, 1] * vb1 + D[ub, 2] * vb2
            rb1 = D[ub, 3] * vb0 + D[ub, 4] * vb1 + D[ub, 5] * vb2
            rb2 = D[ub, 6] * vb0 + D[ub, 7] * vb1 + D[ub, 8] * vb2
            xb0, xb1, xb2 = X[ub, 0], X[ub, 1], X[ub, 2]
        else:
            rb0, rb1, rb2 = vb0, vb1, vb2
            xb0, xb1, xb2 = 0.0, 0.0, 0.0
        xa0, xa1, xa2 = X[a, 0], X[a, 1], X[a, 2]
        for c in range(12):
            Jc[r, c] = 0.0
        if prim == 0:  # POINT component k
            if k == 0:
                gv[r] = (xa0 + ra0) - (xb0 + rb0)
                Jc[r, 0] = 1.0
                Jc[r, 4] = ra2
                Jc[r, 5] = -ra1
                Jc[r, 6] = -1.0
                Jc[r, 10] = -rb2
                Jc[r, 11] = rb1
            elif k == 1:
                gv[r] = (xa1 + ra1) - (xb1 + rb1)
                Jc[r, 1] = 1.0
                Jc[r, 3] = -ra2
                Jc[r, 5] = ra0
                Jc[r, 7] = -1.0
                Jc[r, 9] = rb2
                Jc[r, 11] = -rb0
            else:
                gv[r] = (xa2 + ra2) - (xb2 + rb2)
                Jc[r, 2] = 1.0
                Jc[r, 3] = ra1
                Jc[r, 4] = -ra0
                Jc[r, 8] = -1.0
                Jc[r, 9] = -rb1
                Jc[r, 10] = rb0
        elif prim == 1:  # DOT
            _dot_row(r, ra0, ra1, ra2, rb0, rb1, rb2, rvec, gv, Jc)
        else:  # LINE
            p0, p1, p2 = rvec[r, 6], rvec[r, 7], rvec[r, 8]
            u0 = D[a, 0] * p0 + D[a, 1] * p1 + D[a, 2] * p2
            u1 = D[a, 3] * p0 + D[a, 4] * p1 + D[a, 5] * p2
            u2 = D[a, 6] * p0 + D[a, 7] * p1 + D[a, 8] * p2
            s0 = (xb0 + rb0) - (xa0 + ra0)
            s1 = (xb1 + rb1) - (xa1 + ra1)
            s2 = (xb2 + rb2) - (xa2 + ra2)
            gv[r] = s0 * u0 + s1 * u1 + s2 * u2
            Jc[r, 0] = -u0
            Jc[r, 1] = -u1
            Jc[r, 2] = -u2
            Jc[r, 3] = -(ra1 * u2 - ra2 * u1) + (u1 * s2 - u2 * s1)
            Jc[r, 4] = -(ra2 * u0 - ra0 * u2) + (u2 * s0 - u0 * s2)
            Jc[r, 5] = -(ra0 * u1 - ra1 * u0) + (u0 * s1 - u1 * s0)
            Jc[r, 6] = u0
            Jc[r, 7] = u1
            Jc[r, 8] = u2
            Jc[r, 9] = rb1 * u2 - rb2 * u1
            Jc[r, 10] = rb2 * u0 - rb0 * u2
            Jc[r, 11] = rb0 * u1 - rb1 * u0


@njit(forceinline=True)
def _forces(rint, Jc, lam, F, T):
    """Joint forces -G^T lam per body: F (nb, 3) force, T (nb, 3) world torque."""
    _zero2(F)
    _zero2(T)
    for r0 in range(rint.shape[0]):
        r = _U(r0)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        lr = lam[r]
        for c0 in range(3):
            c = _U(c0)
            F[a, c] -= Jc[r, c] * lr
            T[a, c] -= Jc[r, _U(3 + c0)] * lr
        if b >= 0:
            ub = _U(b)
            for c0 in range(3):
                c = _U(c0)
                F[ub, c] -= Jc[r, _U(6 + c0)] * lr
                T[ub, c] -= Jc[r, _U(9 + c0)] * lr


@njit(forceinline=True)
def _vres(rint, Jc, vel, om, out):
    """G u: the rows' rates at the velocities vel (nb, 3) and world angular velocities om
    (nb, 3)."""
    for rr in range(rint.shape[0]):
        ur = _U(rr)
        ua = _U(rint[ur, 1])
        b = rint[ur, 2]
        s = (Jc[ur, 0] * vel[ua, 0] + Jc[ur, 1] * vel[ua, 1]
             + Jc[ur, 2] * vel[ua, 2])  # fmt: skip
        s += (Jc[ur, 3] * om[ua, 0] + Jc[ur, 4] * om[ua, 1]
              + Jc[ur, 5] * om[ua, 2])  # fmt: skip
        if b >= 0:
            ub = _U(b)
            s += (Jc[ur, 6] * vel[ub, 0] + Jc[ur, 7] * vel[ub, 1]
                  + Jc[ur, 8] * vel[ub, 2])  # fmt: skip
            s += (Jc[ur, 9] * om[ub, 0] + Jc[ur, 10] * om[ub, 1]
                  + Jc[ur, 11] * om[ub, 2])  # fmt: skip
        out[ur] = s


@njit(forceinline=True)
def _ext(fint, fvec, X, D, V, Wd, FE, TE):
    """The force elements' forces FE (nb, 3) and world torques TE (nb, 3) at positions X
    (nb, 3), directors D (nb, 9), centre-of-mass velocities V and world angular velocities Wd
    (nb, 3) (model.py, "Force elements"). Row e of ``fint`` (kind, body a, body b (-1: the
    ground)), of ``fvec``: a spring (kind 0) anchor_a (0:3), anchor_b (3:6; world for the
    ground), k, c, l0 (6:9), pulling point a by -(k (l - l0) + c l') e, e = (p_a - p_b) / l,
    and b by the opposite; a torque (kind 1) the unit axis in a (0:3) and tau (6): tau u on
    a, u = D_a axis, and -tau u on b."""
    _zero2(FE)
    _zero2(TE)
    for e in range(fint.shape[0]):
        a = fint[e, 1]
        b = fint[e, 2]
        if fint[e, 0] == 1:
            u0, u1, u2 = _mul(_row9(D, a), fvec[e, 0], fvec[e, 1], fvec[e, 2])
            tau = fvec[e, 6]
            TE[a, 0] += tau * u0
            TE[a, 1] += tau * u1
            TE[a, 2] += tau * u2
            if b >= 0:
                TE[b, 0] -= tau * u0
                TE[b, 1] -= tau * u1
                TE[b, 2] -= tau * u2
            continue
        ra0, ra1, ra2 = _mul(_row9(D, a), fvec[e, 0], fvec[e, 1], fvec[e, 2])
        va0 = V[a, 0] + (Wd[a, 1] * ra2 - Wd[a, 2] * ra1)
        va1 = V[a, 1] + (Wd[a, 2] * ra0 - Wd[a, 0] * ra2)
        va2 = V[a, 2] + (Wd[a, 0] * ra1 - Wd[a, 1] * ra0)
        if b >= 0:
            rb0, rb1, rb2 = _mul(_row9(D, b), fvec[e, 3], fvec[e, 4], fvec[e, 5])
            d0 = (X[a, 0] + ra0) - (X[b, 0] + rb0)
            d1 = (X[a, 1] + ra1) - (X[b, 1] + rb1)
            d2 = (X[a, 2] + ra2) - (X[b, 2] + rb2)
            vb0 = V[b, 0] + (Wd[b, 1] * rb2 - Wd[b, 2] * rb1)
            vb1 = V[b, 1] + (Wd[b, 2] * rb0 - Wd[b, 0] * rb2)
            vb2 = V[b, 2] + (Wd[b, 0] * rb1 - Wd[b, 1] * rb0)
        else:
            rb0, rb1, rb2 = 0.0, 0.0, 0.0
            d0 = (X[a, 0] + ra0) - fvec[e, 3]
            d1 = (X[a, 1] + ra1) - fvec[e, 4]
            d2 = (X[a, 2] + ra2) - fvec[e, 5]
            vb0, vb1, vb2 = 0.0, 0.0, 0.0
        ln = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        e0, e1, e2 = d0 / ln, d1 / ln, d2 / ln
        rate = e0 * (va0 - vb0) + e1 * (va1 - vb1) + e2 * (va2 - vb2)
        f = -(fvec[e, 6] * (ln - fvec[e, 8]) + fvec[e, 7] * rate)
        f0, f1, f2 = f * e0, f * e1, f * e2
        FE[a, 0] += f0
        FE[a, 1] += f1
        FE[a, 2] += f2
        TE[a, 0] += ra1 * f2 - ra2 * f1
        TE[a, 1] += ra2 * f0 - ra0 * f2
        TE[a, 2] += ra0 * f1 - ra1 * f0
        if b >= 0:
            FE[b, 0] -= f0
            FE[b, 1] -= f1
            FE[b, 2] -= f2
            TE[b, 0] -= rb1 * f2 - rb2 * f1
            TE[b, 1] -= rb2 * f0 - rb0 * f2
            TE[b, 2] -= rb0 * f1 - rb1 * f0
