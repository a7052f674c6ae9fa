"""Compiled pieces of the contact step (director_model.contact._kernels), the rows of a stage:
the Jacobian rows of the closed contacts and of the joints at a state, the bodies' mobility
along them, whether the rows built last still serve (:data:`ROWS_TOL`), the gaps of the
candidates fitted for the position stage, and the Delassus operator J M^-1 J^T. The rest of
the step (state layout, status codes, a stage's solve, the laws, the candidate search) is in
_parts; compiled as _parts says (inlined where called per row, ``_nrt=False``).
"""

from __future__ import annotations

import sys

from numba import njit

from director_model.contact import _geometry as G
from director_model.system._rows import _rows


@njit(inline="always")
def _contact_rows(ncand, cb, cg, Jr, rb_):
    """Rows 3c, 3c+1, 3c+2 of candidate c: directions n, t1, t2 (cg[c, 1:10]) at the points
    ra (cg[c, 10:13]) of body a and rb (cg[c, 13:16]) of body b; Jr (rows, 12) as the
    joints': (d, ra x d) for a and -(d, rb x d) for b; rb_ (rows, 2) the bodies."""
    for c in range(ncand):
        a = cb[c, 0]
        b = cb[c, 1]
        ra0, ra1, ra2 = cg[c, 10], cg[c, 11], cg[c, 12]
        rb0, rb1, rb2 = cg[c, 13], cg[c, 14], cg[c, 15]
        for k in range(3):
            r = 3 * c + k
            d0, d1, d2 = cg[c, 1 + 3 * k], cg[c, 2 + 3 * k], cg[c, 3 + 3 * k]
            Jr[r, 0] = d0
            Jr[r, 1] = d1
            Jr[r, 2] = d2
            Jr[r, 3] = ra1 * d2 - ra2 * d1
            Jr[r, 4] = ra2 * d0 - ra0 * d2
            Jr[r, 5] = ra0 * d1 - ra1 * d0
            Jr[r, 6] = -d0
            Jr[r, 7] = -d1
            Jr[r, 8] = -d2
            Jr[r, 9] = -(rb1 * d2 - rb2 * d1)
            Jr[r, 10] = -(rb2 * d0 - rb0 * d2)
            Jr[r, 11] = -(rb0 * d1 - rb1 * d0)
            rb_[r, 0] = a
            rb_[r, 1] = b


@njit(inline="always")
def _mobility(N, B, Dm, Jr, rb_, Y):
    """Y = M^-1 J^T per row and side: (J_v / m, D I^-1 D^T J_w)."""
    for r in range(N):
        for s in range(2):
            i = rb_[r, s]
            o = 6 * s
            if i < 0:
                for c in range(6):
                    Y[r, o + c] = 0.0
                continue
            im = 1.0 / B[i, 0]
            Y[r, o] = Jr[r, o] * im
            Y[r, o + 1] = Jr[r, o + 1] * im
            Y[r, o + 2] = Jr[r, o + 2] * im
            t0, t1, t2 = G.to_body(Dm, i, Jr[r, o + 3], Jr[r, o + 4], Jr[r, o + 5])
            y0, y1, y2 = G.body_point(Dm, Dm, i, t0 * B[i, 4], t1 * B[i, 5], t2 * B[i, 6])
            Y[r, o + 3] = y0
            Y[r, o + 4] = y1
            Y[r, o + 5] = y2


@njit(_nrt=False)
def joint_rows(rint, rvec, X, D, gv, Jc):
    """director_model.system's joint rows (values gv, Jacobians Jc) at (X, D), compiled once
    here (the system's kernel inlines its own copy)."""
    _rows(rint, rvec, X, D, gv, Jc)


@njit(_nrt=False)
def _setup_rows(m, nj, cb, cg, rint, rvec, X, Dm, B, gvj, Jj, Jr, rb_, Y, rho):
    """The rows of a stage at (X, Dm): m contacts (cb, cg), then the nj joint rows (their
    values into gvj); their mobilities Y and rho (3 / trace of a contact's diagonal block,
    1 / W_jj for a joint row)."""
    N = 3 * m + nj
    _contact_rows(m, cb, cg, Jr, rb_)
    if nj > 0:
        joint_rows(rint, rvec, X, Dm, gvj, Jj)
        for r in range(nj):
            for c in range(12):
                Jr[3 * m + r, c] = Jj[r, c]
            rb_[3 * m + r, 0] = rint[r, 1]
            rb_[3 * m + r, 1] = rint[r, 2]
    _mobility(N, B, Dm, Jr, rb_, Y)
    for c in range(m):
        t = 0.0
        for r in range(3 * c, 3 * c + 3):
            for sd in range(2):
                if rb_[r, sd] >= 0:
                    o = 6 * sd
                    for q in range(6):
                        t += Jr[r, o + q] * Y[r, o + q]
        rho[c] = 3.0 / t
    for j in range(nj):
        r = 3 * m + j
        t = 0.0
        for sd in range(2):
            if rb_[r, sd] >= 0:
                o = 6 * sd
                for q in range(6):
                    t += Jr[r, o + q] * Y[r, o + q]
        rho[m + j] = 1.0 / t


#: the rows of a stage are those built last while the contacts are the same features and
#: their geometry (directions, the bodies' directors) differs from the one they were built
#: at by at most ROWS_TOL (absolute, on unit vectors; times the scene's length scale on the
#: contact points): the size of the rounding in the rows' own computation
ROWS_TOL = 8.0 * sys.float_info.epsilon


@njit(inline="always")
def _rows_valid(m, cand, cg, X, Dm, nj, Lsc, rm, candR, cgR, XR, DR):
    """Whether the rows built last (rm[0] contacts candR with geometry cgR, at the state XR,
    DR) are the rows of the contacts cand[0:m] with geometry cg at (X, Dm) to round-off
    (ROWS_TOL); with joint rows (nj > 0), only at the same state exactly."""
    if rm[0] != m:
        return False
    tol = 0.0 if nj > 0 else ROWS_TOL
    for i in range(DR.shape[0]):
        for k in range(9):
            if not abs(Dm[i, k] - DR[i, k]) <= tol:
                return False
        if nj > 0:
            for k in range(3):
                if X[i, k] != XR[i, k]:
                    return False
    tp = tol * Lsc
    for c in range(m):
        if cand[c] != candR[c]:
            return False
        for k in range(1, 10):
            if not abs(cg[c, k] - cgR[c, k]) <= tol:
                return False
        for k in range(10, 16):
            if not abs(cg[c, k] - cgR[c, k]) <= tp:
                return False
    return True


@njit(inline="always")
def _rows_record(m, cand, cg, X, Dm, rm, candR, cgR, XR, DR):
    """Record what the rows were just built from (see :func:`_rows_valid`)."""
    rm[0] = m
    for i in range(DR.shape[0]):
        for k in range(9):
            DR[i, k] = Dm[i, k]
        for k in range(3):
            XR[i, k] = X[i, k]
    for c in range(m):
        candR[c] = cand[c]
        for k in range(16):
            cgR[c, k] = cg[c, k]


@njit(_nrt=False)
def _fit_gaps(m, cand, cb, cg, FI, X, g0, grp):
    """Make the gaps of redundant contacts those of a rigid face: the contacts of one pair
    with one normal (a face on a plane or on a face; at least 4 points) have gaps that are
    an affine function of their points (a plane evaluated on a plane), but each is rounded
    on its own, and the four rounded gaps of a resting box are not those of any rigid
    motion (a twist of a few ulps, over h in the position stage's targets: no impulse meets
    them all, and Newton's method stalls). Replaced here by their least-squares affine fit
    over the points' coordinates in the contact plane, which differs from them by that
    rounding only. grp: (m,) scratch."""
    for c in range(m):
        grp[c] = -1
    for c in range(m):
        if grp[c] >= 0:
            continue
        p = FI[cand[c], 3]
        n0, n1, n2 = cg[c, 1], cg[c, 2], cg[c, 3]
        cnt = 0
        for d in range(c, m):
            if grp[d] < 0 and FI[cand[d], 3] == p:
                if cg[d, 1] * n0 + cg[d, 2] * n1 + cg[d, 3] * n2 > 1.0 - 1e-12:
                    grp[d] = c
                    cnt += 1
        if cnt < 4:
            continue
        # normal equations of gap = alpha + beta1 s + beta2 t over the group's points
        # (s, t: coordinates along the tangents of c, about the group's mean point)
        t10, t11, t12 = cg[c, 4], cg[c, 5], cg[c, 6]
        t20, t21, t22 = cg[c, 7], cg[c, 8], cg[c, 9]
        ms = 0.0
        mt = 0.0
        for d in range(c, m):
            if grp[d] == c:
                a = cb[d, 0]
                q0, q1, q2 = X[a, 0] + cg[d, 10], X[a, 1] + cg[d, 11], X[a, 2] + cg[d, 12]
                ms += q0 * t10 + q1 * t11 + q2 * t12
                mt += q0 * t20 + q1 * t21 + q2 * t22
        ms /= cnt
        mt /= cnt
        S11 = 0.0
        S12 = 0.0
        S22 = 0.0
        Sg = 0.0
        Sgs = 0.0
        Sgt = 0.0
        for d in range(c, m):
            if grp[d] == c:
                a = cb[d, 0]
                q0, q1, q2 = X[a, 0] + cg[d, 10], X[a, 1] + cg[d, 11], X[a, 2] + cg[d, 12]
                sd = (q0 * t10 + q1 * t11 + q2 * t12) - ms
                td = (q0 * t20 + q1 * t21 + q2 * t22) - mt
                S11 += sd * sd
                S12 += sd * td
                S22 += td * td
                Sg += g0[3 * d]
                Sgs += g0[3 * d] * sd
                Sgt += g0[3 * d] * td
        det = S11 * S22 - S12 * S12
        if not det > 1e-12 * (S11 + S22) ** 2:
            continue  # the points are (nearly) collinear: no redundancy to remove this way
        alpha = Sg / cnt
        b1 = (S22 * Sgs - S12 * Sgt) / det
        b2 = (S11 * Sgt - S12 * Sgs) / det
        for d in range(c, m):
            if grp[d] == c:
                a = cb[d, 0]
                q0, q1, q2 = X[a, 0] + cg[d, 10], X[a, 1] + cg[d, 11], X[a, 2] + cg[d, 12]
                sd = (q0 * t10 + q1 * t11 + q2 * t12) - ms
                td = (q0 * t20 + q1 * t21 + q2 * t22) - mt
                g0[3 * d] = alpha + b1 * sd + b2 * td


@njit(_nrt=False)
def _delassus(N, Jr, rb_, Y, W):
    for r in range(N):
        for s in range(r, N):
            w = 0.0
            for sr in range(2):
                i = rb_[r, sr]
                if i < 0:
                    continue
                for ss in range(2):
                    if rb_[s, ss] == i:
                        o = 6 * sr
                        p = 6 * ss
                        w += (Jr[r, o] * Y[s, p] + Jr[r, o + 1] * Y[s, p + 1]
                              + Jr[r, o + 2] * Y[s, p + 2] + Jr[r, o + 3] * Y[s, p + 3]
                              + Jr[r, o + 4] * Y[s, p + 4]
                              + Jr[r, o + 5] * Y[s, p + 5])  # fmt: skip
            W[r, s] = w
            W[s, r] = w
