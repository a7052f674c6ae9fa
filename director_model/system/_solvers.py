"""The linear algebra of the system kernels' multiplier equations: the assembly of
G_L blockdiag(Mx, Mth) G_R^T over the rows sharing a body (:func:`_assemble`, dense or banded),
the Newton iteration's start value (:func:`_start_value`), the banded solver's LU and
L D L^T without pivoting, the loop solver's rank-revealing banded factorisations within the
matrices' envelope (:func:`_envelope`) and its SVD fallback (LAPACK's dgesdd), and the block
solver's block-tridiagonal elimination in 3x3 blocks. The 5 x 5 joint-block solves of the
loop solver are in _band5.py, the block solver's symmetric velocity stage in _block3.py.
"""

from __future__ import annotations

import math

from numba import njit, types
from numba.np.linalg import _LAPACK, ensure_lapack

from director_model.system._block3 import _U, _hat_blk, _mm_z, _mmt_z
from director_model.system._common import (
    DROP_TOL,
    _inv3,
    _mm,
    _mul,
    _put9,
    _row9,
    _zero2,
)

ensure_lapack()
#: LAPACK's dgesdd through numba's wrapper (numba_ez_gesdd: workspace query, then the call),
#: the routine and arguments of numba's np.linalg.svd; calling it directly compiles in about
#: a tenth of the time of np.linalg.svd and its checks
_GESDD = _LAPACK().numba_ez_gesdd(types.float64)
_KIND_D = ord("d")
_JOBZ_A = ord("A")


@njit(forceinline=True)
def _assemble(ptr, idx, side, JL, JR, Mx, Mth, A, band, bw, upper):
    """A = sum_i JL_i blockdiag(Mx_i 1, Mth_i) JR_i^T over the rows sharing body i; A dense
    (nrow, nrow) or banded (nrow, 2 bw + 1) with A[r, bw + s - r]; with ``upper`` only the
    entries s >= r (a symmetric A, JL = JR and Mth symmetric; the rows of a body are listed
    in increasing order, model.assemble). Indices unsigned (:data:`_U`)."""
    _zero2(A)
    nb = ptr.shape[0] - 1
    for i in range(nb):
        ui = _U(i)
        mx = Mx[ui]
        M0, M1, M2 = Mth[ui, _U(0)], Mth[ui, _U(1)], Mth[ui, _U(2)]
        M3, M4, M5 = Mth[ui, _U(3)], Mth[ui, _U(4)], Mth[ui, _U(5)]
        M6, M7, M8 = Mth[ui, _U(6)], Mth[ui, _U(7)], Mth[ui, _U(8)]
        e0 = ptr[ui]
        e9 = ptr[_U(i + 1)]
        for e1 in range(e0, e9):
            r = idx[_U(e1)]
            ur = _U(r)
            o1 = 6 * side[_U(e1)]
            l0 = JL[ur, _U(o1)] * mx
            l1 = JL[ur, _U(o1 + 1)] * mx
            l2 = JL[ur, _U(o1 + 2)] * mx
            t0, t1, t2 = JL[ur, _U(o1 + 3)], JL[ur, _U(o1 + 4)], JL[ur, _U(o1 + 5)]
            l3 = t0 * M0 + t1 * M3 + t2 * M6
            l4 = t0 * M1 + t1 * M4 + t2 * M7
            l5 = t0 * M2 + t1 * M5 + t2 * M8
            for e2 in range(e1 if upper else e0, e9):
                s = idx[_U(e2)]
                us = _U(s)
                o2 = 6 * side[_U(e2)]
                v = (
                    l0 * JR[us, _U(o2)] + l1 * JR[us, _U(o2 + 1)] + l2 * JR[us, _U(o2 + 2)]
                    + l3 * JR[us, _U(o2 + 3)] + l4 * JR[us, _U(o2 + 4)]
                    + l5 * JR[us, _U(o2 + 5)]
                )  # fmt: skip
                if band:
                    A[ur, _U(bw + s - r)] += v
                else:
                    A[ur, us] += v


@njit(forceinline=True)
def _band_lu(A, bw):
    """In-place LU without pivoting of the banded A (n, 2 bw + 1). Returns False on a pivot
    below 1e-13 times the largest diagonal entry (a singular configuration)."""
    n = A.shape[0]
    big = 0.0
    for k in range(n):
        big = max(big, abs(A[k, bw]))
    tiny = 1e-13 * big
    for k in range(n):
        piv = A[k, bw]
        if not abs(piv) > tiny:
            return False
        ip = 1.0 / piv
        for i in range(k + 1, min(k + bw + 1, n)):
            li = A[i, bw + k - i] * ip
            A[i, bw + k - i] = li
            if li != 0.0:
                for j in range(k + 1, min(k + bw + 1, n)):
                    A[i, bw + j - i] -= li * A[k, bw + j - k]
    return True


@njit(forceinline=True)
def _band_solve(A, bw, b, x):
    """Solve with the factors of :func:`_band_lu`: x = A^{-1} b."""
    n = A.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(max(0, i - bw), i):
            s -= A[i, bw + k - i] * x[k]
        x[i] = s
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, min(i + bw + 1, n)):
            s -= A[i, bw + j - i] * x[j]
        x[i] = s / A[i, bw]


@njit(forceinline=True)
def _band_ldl(A, bw):
    """In-place L D L^T of the symmetric banded A, upper band stored (A[k, bw + j - k],
    j >= k): D on the diagonal, L[i, k] in A[k, bw + i - k]. Returns False on a pivot
    below 1e-13 times the largest diagonal entry (positive definite otherwise)."""
    n = A.shape[0]
    big = 0.0
    for k in range(n):
        big = max(big, abs(A[k, bw]))
    tiny = 1e-13 * big
    for k in range(n):
        d = A[k, bw]
        if not d > tiny:
            return False
        idd = 1.0 / d
        for i in range(k + 1, min(k + bw + 1, n)):
            aki = A[k, bw + i - k]
            if aki != 0.0:
                li = aki * idd
                for j in range(i, min(k + bw + 1, n)):
                    A[i, bw + j - i] -= li * A[k, bw + j - k]
                A[k, bw + i - k] = li
    return True


@njit(forceinline=True)
def _band_ldl_solve(A, bw, b, x):
    """Solve with the factors of :func:`_band_ldl`: x = A^{-1} b."""
    n = A.shape[0]
    for i in range(n):
        x[i] = b[i]
    for k in range(n):
        xk = x[k]
        for i in range(k + 1, min(k + bw + 1, n)):
            x[i] -= A[k, bw + i - k] * xk
    for k in range(n):
        x[k] /= A[k, bw]
    for i in range(n - 1, -1, -1):
        t = x[i]
        for j in range(i + 1, min(i + bw + 1, n)):
            t -= A[i, bw + j - i] * x[j]
        x[i] = t


@njit(forceinline=True)
def _transpose(A):
    """A = A^T in place (square A)."""
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            A[i, j], A[j, i] = A[j, i], A[i, j]


@njit
def _svd_factor(A, rank_tol, U, s, Vt):
    """SVD A = U diag(s) Vt of the square C-ordered A (overwritten) by LAPACK's dgesdd with
    jobz = 'A', through numba's own wrapper of it (the call np.linalg.svd makes, with the
    same arguments, so the same numbers); returns rank = #(s > rank_tol s_0), or -1 if A is
    not finite or dgesdd failed. The transposes pass the C arrays as column-major ones."""
    n = A.shape[0]
    for i in range(n):
        for j in range(n):
            if not abs(A[i, j]) < math.inf:
                return -1
    _transpose(A)
    r = _GESDD(_KIND_D, _JOBZ_A, n, n, A.ctypes, n, s.ctypes, U.ctypes, n, Vt.ctypes, n)
    if r != 0:
        return -1
    _transpose(U)
    _transpose(Vt)
    rank = 0
    if s.shape[0] > 0 and s[0] > 0.0:
        for k in range(s.shape[0]):
            if s[k] > rank_tol * s[0]:
                rank += 1
    return rank


@njit
def _svd_solve(U, s, Vt, rank, b, x):
    """Minimum-norm x = V S^+ U^T b over the first ``rank`` singular values."""
    n = x.shape[0]
    for j in range(n):
        x[j] = 0.0
    for k in range(rank):
        c = 0.0
        for i in range(n):
            c += U[i, k] * b[i]
        c /= s[k]
        for j in range(n):
            x[j] += c * Vt[k, j]


@njit(forceinline=True)
def _envelope(ptr, idx, n, ext):
    """ext[r] = the last row s >= r sharing a body with row r or with a row before it (non-
    decreasing, so that the eliminations below fill nothing beyond it): the envelope of the
    multiplier matrices, whose entry (r, s) is nonzero only for rows sharing a body. For a
    loop of joints listed along it (blocks of rows, each sharing a body with the next) ext[r]
    is the end of the next joint's rows: about 2/3 of the band of a block tridiagonal matrix."""
    for r in range(n):
        ext[r] = r
    for i in range(ptr.shape[0] - 1):
        hi = -1
        for e in range(ptr[i], ptr[i + 1]):
            hi = max(hi, idx[e])
        for e in range(ptr[i], ptr[i + 1]):
            ext[idx[e]] = max(ext[idx[e]], hi)
    for r in range(1, n):
        ext[r] = max(ext[r], ext[r - 1])


@njit(forceinline=True)
def _band_lu_rr(A, bw, ext, keep, out, pchk):
    """In-place LU without pivoting of the banded A (n, 2 bw + 1), A[r, bw + s - r], within
    the envelope ``ext`` (:func:`_envelope`), in the row order, over the rows with keep[k] = 1
    (the others dropped: their unknowns 0, their equations taken as consistent; the pattern
    of the velocity stage's :func:`_band_ldl_rr` at the sub-step's start). Returns 1 where a
    kept pivot |u_kk| falls below ``pchk`` times the largest diagonal entry (near a
    singular configuration: the caller decomposes by SVD instead), -1 on a non-finite entry,
    else 0; out[0] = the smallest kept pivot over that entry, out[1] = the rows kept.
    Indices unsigned (:data:`_U`)."""
    n = A.shape[0]
    w = A.shape[1]
    dmax = 0.0
    bad = False
    for k in range(n):
        uk = _U(k)
        for j in range(w):
            bad |= not abs(A[uk, _U(j)]) < math.inf
        dmax = max(dmax, abs(A[uk, _U(bw)]))
    if bad:
        return -1
    rmin = 1.0
    nk = 0
    for k in range(n):
        uk = _U(k)
        e = ext[uk] + 1
        if keep[uk] == 0:
            for i in range(k + 1, e):
                A[_U(i), _U(bw + k - i)] = 0.0
            continue
        piv = A[uk, _U(bw)]
        if not abs(piv) >= pchk * dmax:
            return 1
        rmin = min(rmin, abs(piv) / dmax)
        nk += 1
        ip = 1.0 / piv
        for i in range(k + 1, e):
            ui = _U(i)
            li = A[ui, _U(bw + k - i)] * ip
            A[ui, _U(bw + k - i)] = li
            if li != 0.0:
                for j in range(k + 1, e):
                    A[ui, _U(bw + j - i)] -= li * A[uk, _U(bw + j - k)]
    out[0] = rmin
    out[1] = nk
    return 0


@njit(forceinline=True)
def _band_solve_rr(A, bw, ext, keep, b, x):
    """The basic solution x of A x = b from :func:`_band_lu_rr` (x_k = 0 for a dropped k)."""
    n = A.shape[0]
    for i in range(n):
        x[_U(i)] = b[_U(i)]
    for k in range(n):
        uk = _U(k)
        xk = x[uk]
        for i in range(k + 1, ext[uk] + 1):
            x[_U(i)] -= A[_U(i), _U(bw + k - i)] * xk
    for i in range(n - 1, -1, -1):
        ui = _U(i)
        if keep[ui] == 0:
            x[ui] = 0.0
            continue
        t = x[ui]
        for j in range(i + 1, ext[ui] + 1):
            t -= A[ui, _U(bw + j - i)] * x[_U(j)]
        x[ui] = t / A[ui, _U(bw)]


@njit(forceinline=True)
def _band_ldl_rr(A, bw, ext, keep, d0, out, pchk):
    """In-place L D L^T of the symmetric positive semi-definite banded A (upper band stored,
    as :func:`_band_ldl`) within the envelope ``ext``, in the row order, rank-revealing: a
    row whose pivot d_k is at most DROP_TOL times its diagonal entry a_kk before elimination
    (d_k / a_kk: the squared sine of the angle between row k of G and the rows kept before
    it, metric M^-1) is dependent on those rows, a redundant joint row, and is dropped
    (keep[k] = 0, its L column 0; for a positive semi-definite A its whole remaining row is
    negligible too, |s_kj| <= sqrt(s_kk s_jj)); the others are kept (keep[k] = 1). Returns 1
    where a kept pivot falls below ``pchk`` times the largest diagonal entry (near a
    singular configuration: the caller decomposes by SVD instead), -1 on a non-finite entry,
    else 0; out as :func:`_band_lu_rr`. ``d0`` (n,) is work space. Indices unsigned
    (:data:`_U`)."""
    n = A.shape[0]
    dmax = 0.0
    bad = False
    for k in range(n):
        uk = _U(k)
        for j in range(bw, 2 * bw + 1):
            bad |= not abs(A[uk, _U(j)]) < math.inf
        d0[uk] = A[uk, _U(bw)]
        dmax = max(dmax, A[uk, _U(bw)])
    if bad:
        return -1
    rmin = 1.0
    nk = 0
    for k in range(n):
        uk = _U(k)
        e = ext[uk] + 1
        d = A[uk, _U(bw)]
        if not d > DROP_TOL * d0[uk]:
            keep[uk] = 0
            for i in range(k + 1, e):
                A[uk, _U(bw + i - k)] = 0.0
            continue
        if d < pchk * dmax:
            return 1
        rmin = min(rmin, d / dmax)
        keep[uk] = 1
        nk += 1
        idd = 1.0 / d
        for i in range(k + 1, e):
            aki = A[uk, _U(bw + i - k)]
            if aki != 0.0:
                ui = _U(i)
                li = aki * idd
                for j in range(i, e):
                    A[ui, _U(bw + j - i)] -= li * A[uk, _U(bw + j - k)]
                A[uk, _U(bw + i - k)] = li
    out[0] = rmin
    out[1] = nk
    return 0


@njit(forceinline=True)
def _band_ldl_solve_rr(A, bw, ext, keep, b, x):
    """The basic solution x of A x = b from :func:`_band_ldl_rr` (x_k = 0 for a dropped k)."""
    n = A.shape[0]
    for i in range(n):
        x[_U(i)] = b[_U(i)]
    for k in range(n):
        uk = _U(k)
        xk = x[uk]
        for i in range(k + 1, ext[uk] + 1):
            x[_U(i)] -= A[uk, _U(bw + i - k)] * xk
    for k in range(n):
        uk = _U(k)
        x[uk] = x[uk] / A[uk, _U(bw)] if keep[uk] else 0.0
    for i in range(n - 1, -1, -1):
        ui = _U(i)
        t = x[ui]
        for j in range(i + 1, ext[ui] + 1):
            t -= A[ui, _U(bw + j - i)] * x[_U(j)]
        x[ui] = t if keep[ui] else 0.0


@njit(forceinline=True)
def _blk_assemble(jptr, jidx, jside, JL, JR, Mx, Mth, Dg, Up, Lo):
    """Block-tridiagonal assembly for joints of three point rows listed along a chain (joint
    k has the rows 3k .. 3k + 2; joints sharing a body are adjacent): the blocks
    sum_i (sigma sigma' Mx_i 1 + C_k Mth_i C_l^T), C the rotation part of a joint's rows on
    body i (a cross-product matrix: zero diagonal, products without its zeros, _block3.py)
    and sigma = +-1 its translation part (+-identity). Dg[k] = block (k, k),
    Up[k] = (k, k + 1), Lo[k] = (k + 1, k), each a row-major 9-vector."""
    _zero2(Dg)
    _zero2(Up)
    _zero2(Lo)
    for i in range(jptr.shape[0] - 1):
        M = _row9(Mth, i)
        mx = Mx[i]
        for e1 in range(jptr[i], jptr[i + 1]):
            k = jidx[e1]
            o1 = 6 * jside[e1]
            CLM = _mm_z(_hat_blk(JL, 3 * k, o1 + 3), M)
            sl = JL[3 * k, o1] * mx
            for e2 in range(jptr[i], jptr[i + 1]):
                m = jidx[e2]
                o2 = 6 * jside[e2]
                Bk = _mmt_z(CLM, _hat_blk(JR, 3 * m, o2 + 3))
                d = sl * JR[3 * m, o2]
                if m == k:
                    for c in range(9):
                        Dg[k, c] += Bk[c]
                    Dg[k, 0] += d
                    Dg[k, 4] += d
                    Dg[k, 8] += d
                elif m == k + 1:
                    for c in range(9):
                        Up[k, c] += Bk[c]
                    Up[k, 0] += d
                    Up[k, 4] += d
                    Up[k, 8] += d
                else:
                    for c in range(9):
                        Lo[m, c] += Bk[c]
                    Lo[m, 0] += d
                    Lo[m, 4] += d
                    Lo[m, 8] += d


@njit(forceinline=True)
def _blk_lu(Dg, Up, Lo):
    """In-place block LU of the block-tridiagonal matrix: Dg[k] becomes the inverse of the
    k-th pivot block, Lo[k] the multiplier block L_{k+1,k}. False on a singular pivot."""
    K = Dg.shape[0]
    for k in range(K):
        P = _row9(Dg, k)
        if k > 0:
            LU = _mm(_row9(Lo, k - 1), _row9(Up, k - 1))
            P = (P[0] - LU[0], P[1] - LU[1], P[2] - LU[2], P[3] - LU[3], P[4] - LU[4],
                 P[5] - LU[5], P[6] - LU[6], P[7] - LU[7], P[8] - LU[8])  # fmt: skip
        nrm = 0.0
        for c in range(9):
            nrm = max(nrm, abs(P[c]))
        det, Pi = _inv3(P)
        if not abs(det) > 1e-36 * nrm * nrm * nrm:
            return False
        _put9(Dg, k, Pi)
        if k < K - 1:
            _put9(Lo, k, _mm(_row9(Lo, k), Pi))
    return True


@njit(forceinline=True)
def _blk_solve(Dg, Up, Lo, b, x):
    """Solve with the factors of :func:`_blk_lu`: x = A^{-1} b."""
    K = Dg.shape[0]
    for k in range(K):
        y0, y1, y2 = b[3 * k], b[3 * k + 1], b[3 * k + 2]
        if k > 0:
            l0, l1, l2 = _mul(_row9(Lo, k - 1), x[3 * k - 3], x[3 * k - 2], x[3 * k - 1])
            y0 -= l0
            y1 -= l1
            y2 -= l2
        x[3 * k], x[3 * k + 1], x[3 * k + 2] = y0, y1, y2
    for k in range(K - 1, -1, -1):
        y0, y1, y2 = x[3 * k], x[3 * k + 1], x[3 * k + 2]
        if k < K - 1:
            u0, u1, u2 = _mul(_row9(Up, k), x[3 * k + 3], x[3 * k + 4], x[3 * k + 5])
            y0 -= u0
            y1 -= u1
            y2 -= u2
        x[3 * k], x[3 * k + 1], x[3 * k + 2] = _mul(_row9(Dg, k), y0, y1, y2)


@njit(forceinline=True)
def _start_value(mu, nrow, nhist, ho1, ho2, ho3, minnorm, banded, lam):
    """The Newton iteration's start value lam of a sub-step's position multipliers, from the
    integrator's multipliers ``mu`` (layout in ``_kernels._run_system``; nhist steps of
    history, 0 to 3; this sub-step's entries at ho1, ho2, ho3 for 1, 2, 3 steps back). The
    banded solver: the position multipliers extrapolated linearly from the two previous
    steps. The block solver: the last velocity multipliers (those at this sub-step's start)
    plus the difference d = position - velocity multipliers, extrapolated by the polynomial
    through the last three steps: d is O(h) smaller than the multipliers, so this start is
    O(h^4) off where the multipliers extrapolated by the same polynomial are O(h^3) off
    (hanging chains of 50 and 100 rods, rattle, 100000 body-steps, take 1.07 and 1.29 Newton
    updates per sub-step against 1.27 and 1.46). The loop solver (``minnorm``): the last
    velocity multipliers (on the loops these close the joints more tightly in one iteration:
    on the four-bar through its singular configuration, residuals ~5e-16 m against ~3e-15 m
    from the extrapolated ones, and the crank and rocker parallel to 3e-13, not 2e-12)."""
    for r in range(nrow):
        if minnorm or nhist == 0:
            lam[r] = mu[r]
        elif banded:
            lam[r] = mu[ho1 + r] if nhist == 1 else 2.0 * mu[ho1 + r] - mu[ho2 + r]
        elif nhist == 1:
            lam[r] = mu[r] + mu[ho1 + r]
        elif nhist == 2:
            lam[r] = mu[r] + (2.0 * mu[ho1 + r] - mu[ho2 + r])
        else:
            lam[r] = mu[r] + (3.0 * (mu[ho1 + r] - mu[ho2 + r]) + mu[ho3 + r])
