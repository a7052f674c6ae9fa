"""Kernels of the block solver's joints: three POINT rows each (spherical and fixed-point
joints; model.assemble's ``block3``), rows 3k .. 3k + 2 the components 0, 1, 2 of joint k.

The general code of director_model/system/_rows.py reads each row's 12 Jacobian entries,
of which a POINT row has 6 exact zeros and two entries +-1, and computes the lever arms
once per row. The functions here compute the lever arms once per joint and leave out the
terms with a factor 0 and the factors 1 (a 3x3 rotation block of a joint is a cross-product
matrix: zero diagonal), keeping every other operation and the order of every sum: the
results are bit for bit those of the general code (x + 0 * y = x and x - 0 * y = x for every
finite nonzero x; only the sign of a zero result could differ, and a zero compares equal to
zero in every later use). Measured side by side with a copy of the kernel without them
(thread CPU time, rattle): 11-18 % of a chain's step at 1 to 100 bodies.

The velocity stage's matrix G M^-1 G^T is symmetric: :func:`_sym_factor` forms only the upper
triangles of its diagonal blocks and the blocks above them, joint by joint, and eliminates
each joint as soon as its blocks are known (L D L^T; no pass over stored blocks), and
:func:`_sym_solve` solves with it. These are not the general LU's numbers (other products,
other order): the results move at round-off. The kernels of _kernels.py inline these
functions; its disk cache is tied to this file.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: array indices cast to unsigned at the access, ``A[_U(i), _U(j)]`` (every index there is
#: >= 0; the ground's -1 is tested before): numba then skips its negative-index wraparound (a
#: sign test and a select per index), which also keeps LLVM from unrolling short loops. The
#: index arithmetic stays signed (numba computes uint64 with int64 in float64). Measured on
#: the four-bar's 20 x 20 Newton matrix: its LU 1.4 -> 0.5 us
_U = np.uint64


@njit(forceinline=True)
def _point3(r, r1, r2, X, a, ra0, ra1, ra2, xb0, xb1, xb2, rb0, rb1, rb2, gv, Jc):
    """One joint's three POINT rows r, r1, r2: the gap between a's anchor (centre X[a] plus
    lever arm ra) and b's (xb plus rb; the ground's: xb 0), and the nonzero entries of Jc,
    each with the operations of ``_rows._rows`` (shared by :func:`_rows3` and the revolute
    joint blocks of ``_band5``)."""
    gv[r] = (X[a, 0] + ra0) - (xb0 + rb0)
    gv[r1] = (X[a, 1] + ra1) - (xb1 + rb1)
    gv[r2] = (X[a, 2] + ra2) - (xb2 + rb2)
    Jc[r, 0] = 1.0
    Jc[r, 4] = ra2
    Jc[r, 5] = -ra1
    Jc[r, 6] = -1.0
    Jc[r, 10] = -rb2
    Jc[r, 11] = rb1
    Jc[r1, 1] = 1.0
    Jc[r1, 3] = -ra2
    Jc[r1, 5] = ra0
    Jc[r1, 7] = -1.0
    Jc[r1, 9] = rb2
    Jc[r1, 11] = -rb0
    Jc[r2, 2] = 1.0
    Jc[r2, 3] = ra1
    Jc[r2, 4] = -ra0
    Jc[r2, 8] = -1.0
    Jc[r2, 9] = -rb1
    Jc[r2, 10] = rb0


@njit(forceinline=True)
def _dot_row(r, sa0, sa1, sa2, p0, p1, p2, rvec, gv, Jc):
    """One DOT row r: a's vector sa (world) against b's p (world), its target rvec[r, 9],
    and the nonzero entries of Jc, with the operations of ``_rows._rows`` (shared by the
    general rows and the revolute joint blocks of ``_band5``)."""
    gv[r] = (sa0 * p0 + sa1 * p1 + sa2 * p2) - rvec[r, 9]
    c0 = sa1 * p2 - sa2 * p1
    c1 = sa2 * p0 - sa0 * p2
    c2 = sa0 * p1 - sa1 * p0
    Jc[r, 3] = c0
    Jc[r, 4] = c1
    Jc[r, 5] = c2
    Jc[r, 9] = -c0
    Jc[r, 10] = -c1
    Jc[r, 11] = -c2


@njit(forceinline=True)
def _rows3(rint, rvec, X, D, gv, Jc):
    """The row values gv and Jacobians Jc of ``_rows._rows`` for joints of three POINT rows
    (components 0, 1, 2 in rows 3k .. 3k + 2): the lever arms once per joint, only the
    nonzero entries of Jc written (the others stay 0: in the block solver nothing else
    writes Jc), each with the operations of ``_rows._rows``."""
    for k0 in range(rint.shape[0] // 3):
        r = _U(3 * k0)
        r1 = _U(3 * k0 + 1)
        r2 = _U(3 * k0 + 2)
        a = _U(rint[r, 1])
        b = rint[r, 2]
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
        _point3(r, r1, r2, X, a, ra0, ra1, ra2, xb0, xb1, xb2, rb0, rb1, rb2, gv, Jc)


@njit(forceinline=True)
def _forces3(rint, Jc, lam, F, T):
    """The joint forces -G^T lam of ``_rows._forces`` (F force, T world torque per body)
    for the rows of :func:`_rows3`: each sum over the rows in the same order, without its
    terms 0 * lam (x - 0 = x) and with 1 * lam as lam."""
    for i in range(F.shape[0]):
        for c in range(3):
            F[i, c] = 0.0
            T[i, c] = 0.0
    for k0 in range(rint.shape[0] // 3):
        r = _U(3 * k0)
        r1 = _U(3 * k0 + 1)
        r2 = _U(3 * k0 + 2)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        l0, l1, l2 = lam[r], lam[r1], lam[r2]
        F[a, 0] -= l0
        F[a, 1] -= l1
        F[a, 2] -= l2
        T[a, 0] = (T[a, 0] - Jc[r1, 3] * l1) - Jc[r2, 3] * l2
        T[a, 1] = (T[a, 1] - Jc[r, 4] * l0) - Jc[r2, 4] * l2
        T[a, 2] = (T[a, 2] - Jc[r, 5] * l0) - Jc[r1, 5] * l1
        if b >= 0:
            ub = _U(b)
            F[ub, 0] += l0
            F[ub, 1] += l1
            F[ub, 2] += l2
            T[ub, 0] = (T[ub, 0] - Jc[r1, 9] * l1) - Jc[r2, 9] * l2
            T[ub, 1] = (T[ub, 1] - Jc[r, 10] * l0) - Jc[r2, 10] * l2
            T[ub, 2] = (T[ub, 2] - Jc[r, 11] * l0) - Jc[r1, 11] * l1


@njit(forceinline=True)
def _vres3(rint, Jc, vel, om, out):
    """G u for the rows of :func:`_rows3` (u = (vel, om) per body): the sums of
    ``_rows._vres`` in the same order, without their terms 0 * u and with 1 * u as u."""
    for k0 in range(rint.shape[0] // 3):
        r = _U(3 * k0)
        r1 = _U(3 * k0 + 1)
        r2 = _U(3 * k0 + 2)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        o0, o1, o2 = om[a, 0], om[a, 1], om[a, 2]
        s0 = vel[a, 0] + (Jc[r, 4] * o1 + Jc[r, 5] * o2)
        s1 = vel[a, 1] + (Jc[r1, 3] * o0 + Jc[r1, 5] * o2)
        s2 = vel[a, 2] + (Jc[r2, 3] * o0 + Jc[r2, 4] * o1)
        if b >= 0:
            ub = _U(b)
            o0, o1, o2 = om[ub, 0], om[ub, 1], om[ub, 2]
            s0 = (s0 - vel[ub, 0]) + (Jc[r, 10] * o1 + Jc[r, 11] * o2)
            s1 = (s1 - vel[ub, 1]) + (Jc[r1, 9] * o0 + Jc[r1, 11] * o2)
            s2 = (s2 - vel[ub, 2]) + (Jc[r2, 9] * o0 + Jc[r2, 10] * o1)
        out[r] = s0
        out[r1] = s1
        out[r2] = s2


@njit(forceinline=True)
def _mm_z(A, B):
    """A B for row-major 3x3 9-tuples, A with a zero diagonal: the sums of ``_common._mm``
    without their terms 0 * b."""
    return (
        A[1] * B[3] + A[2] * B[6],
        A[1] * B[4] + A[2] * B[7],
        A[1] * B[5] + A[2] * B[8],
        A[3] * B[0] + A[5] * B[6],
        A[3] * B[1] + A[5] * B[7],
        A[3] * B[2] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[3],
        A[6] * B[1] + A[7] * B[4],
        A[6] * B[2] + A[7] * B[5],
    )


@njit(forceinline=True)
def _mmt_z(A, B):
    """A B^T for row-major 3x3 9-tuples, B with a zero diagonal: the sums of ``_common._mmt``
    without their terms a * 0."""
    return (
        A[1] * B[1] + A[2] * B[2],
        A[0] * B[3] + A[2] * B[5],
        A[0] * B[6] + A[1] * B[7],
        A[4] * B[1] + A[5] * B[2],
        A[3] * B[3] + A[5] * B[5],
        A[3] * B[6] + A[4] * B[7],
        A[7] * B[1] + A[8] * B[2],
        A[6] * B[3] + A[8] * B[5],
        A[6] * B[6] + A[7] * B[7],
    )


@njit(forceinline=True)
def _hat_blk(J, r, o):
    """The rotation block J[r:r + 3, o:o + 3] of a joint's three POINT rows (zero diagonal)
    as a row-major 9-tuple."""
    r0, r1, r2 = _U(r), _U(r + 1), _U(r + 2)
    o0, o1, o2 = _U(o), _U(o + 1), _U(o + 2)
    return (
        0.0, J[r0, o1], J[r0, o2],
        J[r1, o0], 0.0, J[r1, o2],
        J[r2, o0], J[r2, o1], 0.0,
    )  # fmt: skip


@njit(forceinline=True)
def _sym_inv3(p00, p01, p02, p11, p12, p22):
    """(det P, P^{-1}) of the symmetric 3x3 P from its upper triangle; the inverse as a
    row-major 9-tuple (garbage if det = 0)."""
    c00 = p11 * p22 - p12 * p12
    c01 = p02 * p12 - p01 * p22
    c02 = p01 * p12 - p02 * p11
    det = p00 * c00 + p01 * c01 + p02 * c02
    r = 1.0 / det if det != 0.0 else 0.0
    c00 *= r
    c01 *= r
    c02 *= r
    c11 = (p00 * p22 - p02 * p02) * r
    c12 = (p01 * p02 - p00 * p12) * r
    c22 = (p00 * p11 - p01 * p01) * r
    return det, (c00, c01, c02, c01, c11, c12, c02, c12, c22)


@njit(forceinline=True)
def _sym_factor(rint, J, Mx, Mth, Pi, Y):
    """The velocity stage's matrix A = G blockdiag(Mx 1, Mth) G^T (J = G; Mth symmetric) of
    joints of three POINT rows listed along a chain, assembled joint by joint and factorised
    as A = L D L^T in the same pass: the pivot P_k = A_kk - A_{k-1,k}^T Y_{k-1} (its upper
    triangle; A is symmetric, so only the diagonal blocks' upper triangles and the blocks
    above them are formed), Pi[k] = P_k^{-1}, Y[k] = P_k^{-1} A_{k,k+1}, each a row-major
    9-vector; L_{k+1,k} = Y_k^T. The blocks of joint k: for each body i of it, sigma^2 Mx_i 1
    + C Mth_i C^T on the diagonal and, if body i is in joint k + 1 as well,
    sigma sigma' Mx_i 1 + C Mth_i C'^T above it (C, C' the joints' rotation blocks on body i,
    sigma, sigma' = +-1 their translation parts). False on a singular pivot (the test of
    ``_solvers._blk_lu``)."""
    K = rint.shape[0] // 3
    u0 = u1 = u2 = u3 = u4 = u5 = u6 = u7 = u8 = 0.0  # A_{k-1,k}
    y0 = y1 = y2 = y3 = y4 = y5 = y6 = y7 = y8 = 0.0  # Y_{k-1}
    for k in range(K):
        r = 3 * k
        p00 = p01 = p02 = p11 = p12 = p22 = 0.0
        if k > 0:  # - A_{k-1,k}^T Y_{k-1}, upper triangle
            p00 = -(u0 * y0 + u3 * y3 + u6 * y6)
            p01 = -(u0 * y1 + u3 * y4 + u6 * y7)
            p02 = -(u0 * y2 + u3 * y5 + u6 * y8)
            p11 = -(u1 * y1 + u4 * y4 + u7 * y7)
            p12 = -(u1 * y2 + u4 * y5 + u7 * y8)
            p22 = -(u2 * y2 + u5 * y5 + u8 * y8)
        u0 = u1 = u2 = u3 = u4 = u5 = u6 = u7 = u8 = 0.0
        for s in range(2):
            i = rint[_U(r), _U(1 + s)]
            if i < 0:
                continue
            ui = _U(i)
            M = (Mth[ui, 0], Mth[ui, 1], Mth[ui, 2], Mth[ui, 3], Mth[ui, 4], Mth[ui, 5],
                 Mth[ui, 6], Mth[ui, 7], Mth[ui, 8])  # fmt: skip
            mx = Mx[ui]
            C = _hat_blk(J, r, 6 * s + 3)
            X = _mm_z(C, M)
            p00 += (X[1] * C[1] + X[2] * C[2]) + mx
            p01 += X[0] * C[3] + X[2] * C[5]
            p02 += X[0] * C[6] + X[1] * C[7]
            p11 += (X[3] * C[3] + X[5] * C[5]) + mx
            p12 += X[3] * C[6] + X[4] * C[7]
            p22 += (X[6] * C[6] + X[7] * C[7]) + mx
            if k + 1 < K:
                for s2 in range(2):
                    if rint[_U(r + 3), _U(1 + s2)] == i:
                        B = _mmt_z(X, _hat_blk(J, r + 3, 6 * s2 + 3))
                        d = (J[_U(r), _U(6 * s)] * J[_U(r + 3), _U(6 * s2)]) * mx
                        u0 += B[0] + d
                        u1 += B[1]
                        u2 += B[2]
                        u3 += B[3]
                        u4 += B[4] + d
                        u5 += B[5]
                        u6 += B[6]
                        u7 += B[7]
                        u8 += B[8] + d
        nrm = max(abs(p00), abs(p01), abs(p02), abs(p11), abs(p12), abs(p22))
        det, P = _sym_inv3(p00, p01, p02, p11, p12, p22)
        if not abs(det) > 1e-36 * nrm * nrm * nrm:
            return False
        uk = _U(k)
        for c in range(9):
            Pi[uk, _U(c)] = P[c]
        if k + 1 < K:
            y0 = P[0] * u0 + P[1] * u3 + P[2] * u6
            y1 = P[0] * u1 + P[1] * u4 + P[2] * u7
            y2 = P[0] * u2 + P[1] * u5 + P[2] * u8
            y3 = P[3] * u0 + P[4] * u3 + P[5] * u6
            y4 = P[3] * u1 + P[4] * u4 + P[5] * u7
            y5 = P[3] * u2 + P[4] * u5 + P[5] * u8
            y6 = P[6] * u0 + P[7] * u3 + P[8] * u6
            y7 = P[6] * u1 + P[7] * u4 + P[8] * u7
            y8 = P[6] * u2 + P[7] * u5 + P[8] * u8
            Y[uk, 0], Y[uk, 1], Y[uk, 2] = y0, y1, y2
            Y[uk, 3], Y[uk, 4], Y[uk, 5] = y3, y4, y5
            Y[uk, 6], Y[uk, 7], Y[uk, 8] = y6, y7, y8
    return True


@njit(forceinline=True)
def _sym_solve(Pi, Y, b, x):
    """x = A^{-1} b with the factors of :func:`_sym_factor`: L y = b (y_k = b_k -
    Y_{k-1}^T y_{k-1}), then x_k = P_k^{-1} y_k - Y_k x_{k+1} from the last joint back."""
    K = Pi.shape[0]
    t0 = t1 = t2 = 0.0
    for k in range(K):
        uk = _U(3 * k)
        y0, y1, y2 = b[uk], b[uk + 1], b[uk + 2]
        if k > 0:
            q = _U(k - 1)
            y0 -= Y[q, 0] * t0 + Y[q, 3] * t1 + Y[q, 6] * t2
            y1 -= Y[q, 1] * t0 + Y[q, 4] * t1 + Y[q, 7] * t2
            y2 -= Y[q, 2] * t0 + Y[q, 5] * t1 + Y[q, 8] * t2
        x[uk], x[uk + 1], x[uk + 2] = y0, y1, y2
        t0, t1, t2 = y0, y1, y2
    for k in range(K - 1, -1, -1):
        uk = _U(3 * k)
        q = _U(k)
        y0, y1, y2 = x[uk], x[uk + 1], x[uk + 2]
        z0 = Pi[q, 0] * y0 + Pi[q, 1] * y1 + Pi[q, 2] * y2
        z1 = Pi[q, 3] * y0 + Pi[q, 4] * y1 + Pi[q, 5] * y2
        z2 = Pi[q, 6] * y0 + Pi[q, 7] * y1 + Pi[q, 8] * y2
        if k < K - 1:
            z0 -= Y[q, 0] * t0 + Y[q, 1] * t1 + Y[q, 2] * t2
            z1 -= Y[q, 3] * t0 + Y[q, 4] * t1 + Y[q, 5] * t2
            z2 -= Y[q, 6] * t0 + Y[q, 7] * t1 + Y[q, 8] * t2
        x[uk], x[uk + 1], x[uk + 2] = z0, z1, z2
        t0, t1, t2 = z0, z1, z2
