"""The loop solver's banded solves and assembly in 5 x 5 joint blocks, where the joints have
five rows each (revolute and prismatic joints) and each joint's rows share a body with the
next joint's only: the multiplier matrix is block tridiagonal in joint blocks (a single loop
closed through the ground, joints listed along it by model.band_order: the four-bar,
Bricard's linkage; a chain of such joints). ``_solvers._envelope`` then gives every row of
joint k the envelope end of joint k + 1's rows, and the loops here run over the blocks with
trip counts that are constants of the block (the general solves read each row's end from the
envelope array). For revolute joints (three POINT rows, two DOT rows) the assembly of
G1 W G0^T goes joint pair by joint pair without the products by the rows' exact zeros (a
POINT row has one translation entry, +-1, and a zero rotation entry; a DOT row no
translation entries), and so are the rows, their Jacobians, the joint forces and the rows'
rates G u (the lever arms and the axis once per joint), as _block3.py does for ball joints;
the velocity stage's symmetric matrix is computed in its upper triangle only, a joint's own
block included.

Each unknown receives the same subtractions in the same order as in the general solves
(``_solvers._band_solve_rr``, ``_solvers._band_ldl_solve_rr``), each matrix entry the same
products summed in the same order as in ``_solvers._assemble`` less those with a factor 0
(x + 0 * y = x for finite x; only the sign of a zero could differ): the results are bit for
bit theirs (tests/director_model/test_director_system_band5.py). Measured on the four-bar's
20 x 20 matrices at step 1000 (thread CPU time, best of 5 x 20000 calls, /tmp scripts):
LU solve 290 -> 212 ns, L D L^T solve 300 -> 170 ns, Newton matrix assembly 467 -> 273 ns,
velocity-stage matrix (upper band) 305 -> 222 ns, rows and Jacobians 92 -> 44 ns, joint
forces 76 -> 39 ns. The kernels of _kernels.py inline these
functions; its disk cache is tied to this file.
"""

from __future__ import annotations

from numba import njit

from director_model.system._block3 import _U, _dot_row, _point3

#: rows of a joint block
JB = 5


@njit(forceinline=True)
def _is_band5(ext, n):
    """Whether the envelope ``ext`` (``_solvers._envelope``) of an n-row matrix is block
    tridiagonal in blocks of JB rows (row r's end: the last row of the next block)."""
    if n == 0 or n % JB != 0:
        return False
    for r in range(n):
        if ext[r] != min(JB * (r // JB) + 2 * JB - 1, n - 1):
            return False
    return True


@njit(forceinline=True)
def _b5_solve_rr(A, bw, keep, b, x):
    """``_solvers._band_solve_rr`` (the basic solution from ``_band_lu_rr``'s factors) on a
    block tridiagonal envelope (:func:`_is_band5`)."""
    n = A.shape[0]
    nbk = n // JB
    for i in range(n):
        x[_U(i)] = b[_U(i)]
    for bb in range(nbk):
        r0 = JB * bb
        nxt = bb < nbk - 1
        for p in range(JB):
            xk = x[_U(r0 + p)]
            for i in range(p + 1, JB):
                x[_U(r0 + i)] -= A[_U(r0 + i), _U(bw + p - i)] * xk
            if nxt:
                for i in range(JB):
                    x[_U(r0 + JB + i)] -= A[_U(r0 + JB + i), _U(bw + p - JB - i)] * xk
    for bb in range(nbk - 1, -1, -1):
        r0 = JB * bb
        nxt = bb < nbk - 1
        for p in range(JB - 1, -1, -1):
            ui = _U(r0 + p)
            if keep[ui] == 0:
                x[ui] = 0.0
                continue
            t = x[ui]
            for j in range(p + 1, JB):
                t -= A[ui, _U(bw + j - p)] * x[_U(r0 + j)]
            if nxt:
                for j in range(JB):
                    t -= A[ui, _U(bw + JB + j - p)] * x[_U(r0 + JB + j)]
            x[ui] = t / A[ui, _U(bw)]


@njit(forceinline=True)
def _b5_ldl_solve_rr(A, bw, keep, b, x):
    """``_solvers._band_ldl_solve_rr`` (the basic solution from ``_band_ldl_rr``'s factors,
    upper band stored) on a block tridiagonal envelope (:func:`_is_band5`)."""
    n = A.shape[0]
    nbk = n // JB
    for i in range(n):
        x[_U(i)] = b[_U(i)]
    for bb in range(nbk):
        r0 = JB * bb
        nxt = bb < nbk - 1
        for p in range(JB):
            uk = _U(r0 + p)
            xk = x[uk]
            for i in range(p + 1, JB):
                x[_U(r0 + i)] -= A[uk, _U(bw + i - p)] * xk
            if nxt:
                for i in range(JB):
                    x[_U(r0 + JB + i)] -= A[uk, _U(bw + JB + i - p)] * xk
    for k in range(n):
        uk = _U(k)
        x[uk] = x[uk] / A[uk, _U(bw)] if keep[uk] else 0.0
    for bb in range(nbk - 1, -1, -1):
        r0 = JB * bb
        nxt = bb < nbk - 1
        for p in range(JB - 1, -1, -1):
            ui = _U(r0 + p)
            t = x[ui]
            for j in range(p + 1, JB):
                t -= A[ui, _U(bw + j - p)] * x[_U(r0 + j)]
            if nxt:
                for j in range(JB):
                    t -= A[ui, _U(bw + JB + j - p)] * x[_U(r0 + JB + j)]
            x[ui] = t if keep[ui] else 0.0


@njit(forceinline=True)
def _is_revolute5(rint, n):
    """Whether every joint block of an n-row matrix (:func:`_is_band5`) has the rows of a
    revolute joint: POINT components 0, 1, 2, then two DOT rows (model.py)."""
    for r in range(n):
        p = r % JB
        if rint[r, 0] != (0 if p < 3 else 1) or (p < 3 and rint[r, 3] != p):
            return False
    return True


@njit(forceinline=True)
def _r5_l(JL, r, o, mx, M, p):
    """Row r (component p of a revolute joint) of JL blockdiag(mx 1, M) on the side at column
    o: (its translation entry, at column p if p < 3, else 0; its rotation entries) as
    ``_solvers._assemble`` computes them, without the terms with a factor 0 (the
    translation entries off p, a POINT row's rotation entry p)."""
    if p < 3:
        lin = JL[_U(r), _U(o + p)] * mx
    else:
        lin = 0.0
    t0 = JL[_U(r), _U(o + 3)]
    t1 = JL[_U(r), _U(o + 4)]
    t2 = JL[_U(r), _U(o + 5)]
    if p == 0:
        return lin, t1 * M[3] + t2 * M[6], t1 * M[4] + t2 * M[7], t1 * M[5] + t2 * M[8]
    if p == 1:
        return lin, t0 * M[0] + t2 * M[6], t0 * M[1] + t2 * M[7], t0 * M[2] + t2 * M[8]
    if p == 2:
        return lin, t0 * M[0] + t1 * M[3], t0 * M[1] + t1 * M[4], t0 * M[2] + t1 * M[5]
    return (
        lin,
        t0 * M[0] + t1 * M[3] + t2 * M[6],
        t0 * M[1] + t1 * M[4] + t2 * M[7],
        t0 * M[2] + t1 * M[5] + t2 * M[8],
    )


@njit(forceinline=True)
def _r5_add(A, bw, r, R2, upper, p, lv, S, U):
    """A[r, s] += the products of the row lv (:func:`_r5_l`, component p) with the rows
    s = R2 .. R2 + 4 of a revolute joint (translation entries S (3,), rotation entries U
    (15,)), each summed in the order of ``_solvers._assemble`` without its zero terms (only
    s >= r, and only those computed, if ``upper``: a joint's own block is symmetric)."""
    lin, l3, l4, l5 = lv
    ur = _U(r)
    if not upper or R2 >= r:
        if p == 0:
            v0 = (lin * S[0] + l4 * U[1]) + l5 * U[2]
        else:
            v0 = l4 * U[1] + l5 * U[2]
        A[ur, _U(bw + R2 - r)] += v0
    if not upper or R2 + 1 >= r:
        if p == 1:
            v1 = (lin * S[1] + l3 * U[3]) + l5 * U[5]
        else:
            v1 = l3 * U[3] + l5 * U[5]
        A[ur, _U(bw + R2 + 1 - r)] += v1
    if not upper or R2 + 2 >= r:
        if p == 2:
            v2 = (lin * S[2] + l3 * U[6]) + l4 * U[7]
        else:
            v2 = l3 * U[6] + l4 * U[7]
        A[ur, _U(bw + R2 + 2 - r)] += v2
    if not upper or R2 + 3 >= r:
        A[ur, _U(bw + R2 + 3 - r)] += l3 * U[9] + l4 * U[10] + l5 * U[11]
    if not upper or R2 + 4 >= r:
        A[ur, _U(bw + R2 + 4 - r)] += l3 * U[12] + l4 * U[13] + l5 * U[14]


@njit(forceinline=True)
def _r5_assemble(jptr, jidx, jside, JL, JR, Mx, Mth, A, bw, upper):
    """``_solvers._assemble`` (banded) for revolute joints (:func:`_is_revolute5`; joint k
    has the rows 5k .. 5k + 4, ``jptr``, ``jidx``, ``jside`` the joints touching each body):
    joint pair by joint pair, without the products by the exact zeros of POINT and DOT rows
    (a POINT row's translation entries off its component and its rotation entry at it, a
    DOT row's translation entries), the other products summed in the same order, the bodies
    in the same order: the same floats. With ``upper`` the columns below the diagonal
    (A[r, c], c < bw) are neither cleared nor written: the L D L^T and its solves do not read
    them."""
    c0 = bw if upper else 0
    for r in range(A.shape[0]):
        for c in range(c0, A.shape[1]):
            A[_U(r), _U(c)] = 0.0
    for i in range(jptr.shape[0] - 1):
        ui = _U(i)
        mx = Mx[ui]
        M = (Mth[ui, _U(0)], Mth[ui, _U(1)], Mth[ui, _U(2)], Mth[ui, _U(3)], Mth[ui, _U(4)],
             Mth[ui, _U(5)], Mth[ui, _U(6)], Mth[ui, _U(7)], Mth[ui, _U(8)])  # fmt: skip
        for e1 in range(jptr[ui], jptr[_U(i + 1)]):
            k1 = jidx[_U(e1)]
            o1 = 6 * jside[_U(e1)]
            R1 = JB * k1
            L0 = _r5_l(JL, R1, o1, mx, M, 0)
            L1 = _r5_l(JL, R1 + 1, o1, mx, M, 1)
            L2 = _r5_l(JL, R1 + 2, o1, mx, M, 2)
            L3 = _r5_l(JL, R1 + 3, o1, mx, M, 3)
            L4 = _r5_l(JL, R1 + 4, o1, mx, M, 4)
            for e2 in range(jptr[ui], jptr[_U(i + 1)]):
                k2 = jidx[_U(e2)]
                if upper and k2 < k1:
                    continue
                o2 = 6 * jside[_U(e2)]
                R2 = JB * k2
                u0 = _U(R2)
                u1 = _U(R2 + 1)
                u2 = _U(R2 + 2)
                u3 = _U(R2 + 3)
                u4 = _U(R2 + 4)
                c3 = _U(o2 + 3)
                c4 = _U(o2 + 4)
                c5 = _U(o2 + 5)
                S = (JR[u0, _U(o2)], JR[u1, _U(o2 + 1)], JR[u2, _U(o2 + 2)])
                U = (0.0, JR[u0, c4], JR[u0, c5],
                     JR[u1, c3], 0.0, JR[u1, c5],
                     JR[u2, c3], JR[u2, c4], 0.0,
                     JR[u3, c3], JR[u3, c4], JR[u3, c5],
                     JR[u4, c3], JR[u4, c4], JR[u4, c5])  # fmt: skip
                _r5_add(A, bw, R1, R2, upper, 0, L0, S, U)
                _r5_add(A, bw, R1 + 1, R2, upper, 1, L1, S, U)
                _r5_add(A, bw, R1 + 2, R2, upper, 2, L2, S, U)
                _r5_add(A, bw, R1 + 3, R2, upper, 3, L3, S, U)
                _r5_add(A, bw, R1 + 4, R2, upper, 4, L4, S, U)


@njit(forceinline=True)
def _r5_rows(rint, rvec, X, D, gv, Jc):
    """The row values gv and Jacobians Jc of ``_rows._rows`` for revolute joints
    (:func:`_is_revolute5`, joint k in rows 5k .. 5k + 4): the lever arms and the axis once per
    joint (the three POINT rows share their anchors, the two DOT rows their axis in a), only
    the nonzero entries of Jc written (the others stay 0: where the kernel uses this, nothing
    else writes Jc), each with the operations of ``_rows._rows``."""
    for k0 in range(rint.shape[0] // JB):
        r = _U(JB * k0)
        r1 = _U(JB * k0 + 1)
        r2 = _U(JB * k0 + 2)
        r3 = _U(JB * k0 + 3)
        r4 = _U(JB * k0 + 4)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        va0, va1, va2 = rvec[r, 0], rvec[r, 1], rvec[r, 2]
        vb0, vb1, vb2 = rvec[r, 3], rvec[r, 4], rvec[r, 5]
        ra0 = D[a, 0] * va0 + D[a, 1] * va1 + D[a, 2] * va2
        ra1 = D[a, 3] * va0 + D[a, 4] * va1 + D[a, 5] * va2
        ra2 = D[a, 6] * va0 + D[a, 7] * va1 + D[a, 8] * va2
        ua0, ua1, ua2 = rvec[r3, 0], rvec[r3, 1], rvec[r3, 2]
        sa0 = D[a, 0] * ua0 + D[a, 1] * ua1 + D[a, 2] * ua2
        sa1 = D[a, 3] * ua0 + D[a, 4] * ua1 + D[a, 5] * ua2
        sa2 = D[a, 6] * ua0 + D[a, 7] * ua1 + D[a, 8] * ua2
        m0, m1, m2 = rvec[r3, 3], rvec[r3, 4], rvec[r3, 5]
        n0, n1, n2 = rvec[r4, 3], rvec[r4, 4], rvec[r4, 5]
        if b >= 0:
            ub = _U(b)
            rb0 = D[ub, 0] * vb0 + D[ub, 1] * vb1 + D[ub, 2] * vb2
            rb1 = D[ub, 3] * vb0 + D[ub, 4] * vb1 + D[ub, 5] * vb2
            rb2 = D[ub, 6] * vb0 + D[ub, 7] * vb1 + D[ub, 8] * vb2
            xb0, xb1, xb2 = X[ub, 0], X[ub, 1], X[ub, 2]
            p0 = D[ub, 0] * m0 + D[ub, 1] * m1 + D[ub, 2] * m2
            p1 = D[ub, 3] * m0 + D[ub, 4] * m1 + D[ub, 5] * m2
            p2 = D[ub, 6] * m0 + D[ub, 7] * m1 + D[ub, 8] * m2
            q0 = D[ub, 0] * n0 + D[ub, 1] * n1 + D[ub, 2] * n2
            q1 = D[ub, 3] * n0 + D[ub, 4] * n1 + D[ub, 5] * n2
            q2 = D[ub, 6] * n0 + D[ub, 7] * n1 + D[ub, 8] * n2
        else:
            rb0, rb1, rb2 = vb0, vb1, vb2
            xb0, xb1, xb2 = 0.0, 0.0, 0.0
            p0, p1, p2 = m0, m1, m2
            q0, q1, q2 = n0, n1, n2
        _point3(r, r1, r2, X, a, ra0, ra1, ra2, xb0, xb1, xb2, rb0, rb1, rb2, gv, Jc)
        _dot_row(r3, sa0, sa1, sa2, p0, p1, p2, rvec, gv, Jc)
        _dot_row(r4, sa0, sa1, sa2, q0, q1, q2, rvec, gv, Jc)


@njit(forceinline=True)
def _r5_forces(rint, Jc, lam, F, T):
    """``_rows._forces`` (the joint forces -G^T lam: F force, T world torque per body) for
    revolute joints (:func:`_is_revolute5`), without the products by the exact zeros of the
    rows; each entry's terms in the same order."""
    for i in range(F.shape[0]):
        for c in range(3):
            F[_U(i), _U(c)] = 0.0
            T[_U(i), _U(c)] = 0.0
    for k0 in range(rint.shape[0] // JB):
        r = _U(JB * k0)
        r1 = _U(JB * k0 + 1)
        r2 = _U(JB * k0 + 2)
        r3 = _U(JB * k0 + 3)
        r4 = _U(JB * k0 + 4)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        l0, l1, l2, l3, l4 = lam[r], lam[r1], lam[r2], lam[r3], lam[r4]
        # row by row, as the general code (each entry's terms in row order)
        F[a, 0] -= Jc[r, 0] * l0
        T[a, 1] -= Jc[r, 4] * l0
        T[a, 2] -= Jc[r, 5] * l0
        F[a, 1] -= Jc[r1, 1] * l1
        T[a, 0] -= Jc[r1, 3] * l1
        T[a, 2] -= Jc[r1, 5] * l1
        F[a, 2] -= Jc[r2, 2] * l2
        T[a, 0] -= Jc[r2, 3] * l2
        T[a, 1] -= Jc[r2, 4] * l2
        T[a, 0] -= Jc[r3, 3] * l3
        T[a, 1] -= Jc[r3, 4] * l3
        T[a, 2] -= Jc[r3, 5] * l3
        T[a, 0] -= Jc[r4, 3] * l4
        T[a, 1] -= Jc[r4, 4] * l4
        T[a, 2] -= Jc[r4, 5] * l4
        if b >= 0:
            ub = _U(b)
            F[ub, 0] -= Jc[r, 6] * l0
            T[ub, 1] -= Jc[r, 10] * l0
            T[ub, 2] -= Jc[r, 11] * l0
            F[ub, 1] -= Jc[r1, 7] * l1
            T[ub, 0] -= Jc[r1, 9] * l1
            T[ub, 2] -= Jc[r1, 11] * l1
            F[ub, 2] -= Jc[r2, 8] * l2
            T[ub, 0] -= Jc[r2, 9] * l2
            T[ub, 1] -= Jc[r2, 10] * l2
            T[ub, 0] -= Jc[r3, 9] * l3
            T[ub, 1] -= Jc[r3, 10] * l3
            T[ub, 2] -= Jc[r3, 11] * l3
            T[ub, 0] -= Jc[r4, 9] * l4
            T[ub, 1] -= Jc[r4, 10] * l4
            T[ub, 2] -= Jc[r4, 11] * l4


@njit(forceinline=True)
def _r5_vres(rint, Jc, vel, om, out):
    """``_rows._vres`` (G u: the rows' rates at the velocities vel and world angular
    velocities om, per body) for revolute joints (:func:`_is_revolute5`), without the
    products by the exact zeros of the rows (a POINT row's translation entries off its
    component and rotation entry at it, a DOT row's translation entries); the other terms
    summed in the same order."""
    for k0 in range(rint.shape[0] // JB):
        r = _U(JB * k0)
        r1 = _U(JB * k0 + 1)
        r2 = _U(JB * k0 + 2)
        r3 = _U(JB * k0 + 3)
        r4 = _U(JB * k0 + 4)
        a = _U(rint[r, 1])
        b = rint[r, 2]
        v0, v1, v2 = vel[a, 0], vel[a, 1], vel[a, 2]
        w0, w1, w2 = om[a, 0], om[a, 1], om[a, 2]
        s0 = Jc[r, 0] * v0
        s0 += Jc[r, 4] * w1 + Jc[r, 5] * w2
        s1 = Jc[r1, 1] * v1
        s1 += Jc[r1, 3] * w0 + Jc[r1, 5] * w2
        s2 = Jc[r2, 2] * v2
        s2 += Jc[r2, 3] * w0 + Jc[r2, 4] * w1
        s3 = Jc[r3, 3] * w0 + Jc[r3, 4] * w1 + Jc[r3, 5] * w2
        s4 = Jc[r4, 3] * w0 + Jc[r4, 4] * w1 + Jc[r4, 5] * w2
        if b >= 0:
            ub = _U(b)
            v0, v1, v2 = vel[ub, 0], vel[ub, 1], vel[ub, 2]
            w0, w1, w2 = om[ub, 0], om[ub, 1], om[ub, 2]
            s0 += Jc[r, 6] * v0
            s0 += Jc[r, 10] * w1 + Jc[r, 11] * w2
            s1 += Jc[r1, 7] * v1
            s1 += Jc[r1, 9] * w0 + Jc[r1, 11] * w2
            s2 += Jc[r2, 8] * v2
            s2 += Jc[r2, 9] * w0 + Jc[r2, 10] * w1
            s3 += Jc[r3, 9] * w0 + Jc[r3, 10] * w1 + Jc[r3, 11] * w2
            s4 += Jc[r4, 9] * w0 + Jc[r4, 10] * w1 + Jc[r4, 11] * w2
        out[r] = s0
        out[r1] = s1
        out[r2] = s2
        out[r3] = s3
        out[r4] = s4
