"""The per-body work of the system kernels' RATTLE sub-step: each body's rotation equation
(discrete Moser-Veselov, :func:`_dmv`, solved in each Newton iterate of the joint
multipliers), the directors at the sub-step's start, the bodies' responses to a force and a
torque, the velocity stage's free velocities, the state update (:func:`_advance`), and
storing or copying a state.
"""

from __future__ import annotations

import math

from numba import njit

from director_model._primitives import kahan, quat_matrix
from director_model.system._common import (
    DMV_MAXIT,
    EPS,
    NS,
    QUAT_BIG,
    QUAT_SHRINK,
    _ftz,
    _inv3,
    _mm,
    _mmt,
    _mul,
    _put9,
    _row9,
    _tmul,
)


@njit(forceinline=True)
def _dmv_jac(I0, I1, I2, w0, w1, w2, p0, p1, p2, h):
    """dF/dw of F(w) = 2 (I w + w x I w) - h (1 + |w|^2) pi: 2 (diag(I) + hat(w) diag(I) -
    hat(I w)) - 2 h pi w^T, a row-major 9-tuple."""
    Iw0 = I0 * w0
    Iw1 = I1 * w1
    Iw2 = I2 * w2
    t = 2.0 * h
    return (
        2.0 * I0 - t * p0 * w0,
        2.0 * (Iw2 - w2 * I1) - t * p0 * w1,
        2.0 * (w1 * I2 - Iw1) - t * p0 * w2,
        2.0 * (w2 * I0 - Iw2) - t * p1 * w0,
        2.0 * I1 - t * p1 * w1,
        2.0 * (Iw0 - w0 * I2) - t * p1 * w2,
        2.0 * (Iw1 - w1 * I0) - t * p2 * w0,
        2.0 * (w0 * I1 - Iw0) - t * p2 * w1,
        2.0 * I2 - t * p2 * w2,
    )


@njit(forceinline=True)
def _dmv(I0, I1, I2, iI0, iI1, iI2, p0, p1, p2, h):
    """Solve the DMV equation F(w) = 2 (I w + w x I w) - h (1 + |w|^2) pi = 0 for the Gibbs
    vector w: start w = h/2 I^{-1} pi, one fixed-point correction (iI = 1/I: products, not
    quotients), then chord Newton with the Jacobian at that start (its error is O(|w|^2), so
    each iteration gains about as many digits as h |W| has leading zeros, twice), in
    :func:`_dmv_iterate`. Returns (ok, w0, w1, w2, Ai) with Ai the
    inverse Jacobian at the start (for the multiplier matrix); ok is False without an
    admissible solution (no convergence, det <= 0, or |w| >= 1: 90 degrees or more)."""
    w0 = 0.5 * h * p0 * iI0
    w1 = 0.5 * h * p1 * iI1
    w2 = 0.5 * h * p2 * iI2
    q = 1.0 + (w0 * w0 + w1 * w1 + w2 * w2)
    c0 = w1 * (I2 * w2) - w2 * (I1 * w1)
    c1 = w2 * (I0 * w0) - w0 * (I2 * w2)
    c2 = w0 * (I1 * w1) - w1 * (I0 * w0)
    w0 = (0.5 * h * q * p0 - c0) * iI0
    w1 = (0.5 * h * q * p1 - c1) * iI1
    w2 = (0.5 * h * q * p2 - c2) * iI2
    det, Ai = _inv3(_dmv_jac(I0, I1, I2, w0, w1, w2, p0, p1, p2, h))
    if not det > 0.0:
        return False, w0, w1, w2, Ai
    ok, w0, w1, w2 = _dmv_iterate(I0, I1, I2, p0, p1, p2, h, w0, w1, w2, Ai)
    return ok, w0, w1, w2, Ai


@njit(forceinline=True)
def _dmv_iterate(I0, I1, I2, p0, p1, p2, h, w0, w1, w2, Ai):
    """The chord Newton iteration of :func:`_dmv` from the Gibbs vector w with the inverse
    Jacobian Ai. Returns (ok, w0, w1, w2), ok as :func:`_dmv`. The Newton iterations of the
    joint multipliers after the first call it from the body's w of the iterate before, with
    the Ai of the first: the momentum changes by the multipliers' correction only, and the
    iteration ends at the same test (a correction at the rounding of w), a step or two
    instead of :func:`_dmv`'s start value, its correction and the Jacobian's inverse (on
    chains 5-10 % of a step; the w found differ from :func:`_dmv`'s at rounding)."""
    ok = False
    dprev = math.inf
    for _ in range(DMV_MAXIT):
        Iw0 = I0 * w0
        Iw1 = I1 * w1
        Iw2 = I2 * w2
        q = 1.0 + (w0 * w0 + w1 * w1 + w2 * w2)
        F0 = 2.0 * (Iw0 + (w1 * Iw2 - w2 * Iw1)) - h * q * p0
        F1 = 2.0 * (Iw1 + (w2 * Iw0 - w0 * Iw2)) - h * q * p1
        F2 = 2.0 * (Iw2 + (w0 * Iw1 - w1 * Iw0)) - h * q * p2
        d0 = Ai[0] * F0 + Ai[1] * F1 + Ai[2] * F2
        d1 = Ai[3] * F0 + Ai[4] * F1 + Ai[5] * F2
        d2 = Ai[6] * F0 + Ai[7] * F1 + Ai[8] * F2
        w0 -= d0
        w1 -= d1
        w2 -= d2
        wn = abs(w0) + abs(w1) + abs(w2)
        if not wn < math.inf:
            break
        dn = abs(d0) + abs(d1) + abs(d2)
        # converged: a correction at the rounding of w, or no longer falling near it
        if dn <= 4.0 * EPS * wn or (dn >= dprev and dn <= 64.0 * EPS * wn):
            ok = True
            break
        dprev = dn
    ok = ok and (w0 * w0 + w1 * w1 + w2 * w2) < 1.0
    return ok, w0, w1, w2


@njit(forceinline=True)
def _store(B, D0, S, X, V, D, W, k):
    for i in range(S.shape[0]):
        for c in range(3):
            X[k, i, c] = S[i, c]
            V[k, i, c] = S[i, 6 + c]
            W[k, i, c] = S[i, 20 + c] * B[i, 4 + c]
        R = _mm(_row9(D0, i), quat_matrix((S[i, 12], S[i, 13], S[i, 14], S[i, 15])))
        for c in range(9):
            D[k, i, c // 3, c % 3] = R[c]


@njit(forceinline=True)
def _copy_step_state(nb, nr, S, mu, kn, S_to, mu_to, kn_to):
    """Copy a step's state (S: the nb bodies' states; mu, kn: the nr rows' last velocity
    multipliers and pattern) into S_to, mu_to, kn_to: a step split at a singular landing
    keeps its start this way and is restored from it."""
    for i in range(nb):
        for c in range(NS):
            S_to[i, c] = S[i, c]
    for r in range(nr):
        mu_to[r] = mu[r]
        kn_to[r] = kn[r]


@njit(forceinline=True)
def _directors(S, D0, Dn, Lsc):
    """The directors Dn (nb, 9) of the state S at a sub-step's start (D0 R(p)); returns the
    length scale of the joint tolerance, max(Lsc, the largest |x_i| component)."""
    x0 = x1 = x2 = Lsc  # three running maxima: independent compare chains
    for i in range(S.shape[0]):
        Ri = quat_matrix((S[i, 12], S[i, 13], S[i, 14], S[i, 15]))
        _put9(Dn, i, _mm(_row9(D0, i), Ri))
        x0 = max(x0, abs(S[i, 0]))
        x1 = max(x1, abs(S[i, 1]))
        x2 = max(x2, abs(S[i, 2]))
    return max(max(x0, x1), x2)


@njit(forceinline=True)
def _scaled(Dj, B, i):
    """D diag(1/I) of body i for the row-major 9-tuple D (B[i, 4:7] = 1/I)."""
    return (Dj[0] * B[i, 4], Dj[1] * B[i, 5], Dj[2] * B[i, 6],
            Dj[3] * B[i, 4], Dj[4] * B[i, 5], Dj[5] * B[i, 6],
            Dj[6] * B[i, 4], Dj[7] * B[i, 5], Dj[8] * B[i, 6])  # fmt: skip


@njit(forceinline=True)
def _inv_inertia(B, Dd, Mx, Mth):
    """Each body's response to a force and a world torque at the directors Dd (nb, 9):
    Mx = 1/m, Mth = D I^-1 D^T (all nine entries)."""
    for i in range(B.shape[0]):
        Mx[i] = 1.0 / B[i, 0]
        Dj = _row9(Dd, i)
        _put9(Mth, i, _mmt(_scaled(Dj, B, i), Dj))


@njit(forceinline=True)
def _inv_inertia_sym(B, Dd, Mx, Mth):
    """:func:`_inv_inertia` with Mth from its upper triangle (the block solver's symmetric
    factorisation)."""
    for i in range(B.shape[0]):
        Mx[i] = 1.0 / B[i, 0]
        Dj = _row9(Dd, i)
        DI = _scaled(Dj, B, i)
        m00 = DI[0] * Dj[0] + DI[1] * Dj[1] + DI[2] * Dj[2]
        m01 = DI[0] * Dj[3] + DI[1] * Dj[4] + DI[2] * Dj[5]
        m02 = DI[0] * Dj[6] + DI[1] * Dj[7] + DI[2] * Dj[8]
        m11 = DI[3] * Dj[3] + DI[4] * Dj[4] + DI[5] * Dj[5]
        m12 = DI[3] * Dj[6] + DI[4] * Dj[7] + DI[5] * Dj[8]
        m22 = DI[6] * Dj[6] + DI[7] * Dj[7] + DI[8] * Dj[8]
        _put9(Mth, i, (m00, m01, m02, m01, m11, m12, m02, m12, m22))


@njit(forceinline=True)
def _free_velocity(B, WG, PI, Dnew, g, h, hh, RC, TW, VH):
    """The velocity stage's u0 before the joint impulse: the momentum term
    RC = 4 c/(q h) of each body (Q^T pi = pi - RC), TW = Dnew I^{-1} Q^T pi its world angular
    velocity, and VH += h/2 g (VH then holds v_half + h/2 g)."""
    for i in range(B.shape[0]):
        w0, w1, w2 = WG[i, 0], WG[i, 1], WG[i, 2]
        I0, I1, I2 = B[i, 1], B[i, 2], B[i, 3]
        rq = 4.0 / ((1.0 + (w0 * w0 + w1 * w1 + w2 * w2)) * h)
        c0 = w1 * (I2 * w2) - w2 * (I1 * w1)
        c1 = w2 * (I0 * w0) - w0 * (I2 * w2)
        c2 = w0 * (I1 * w1) - w1 * (I0 * w0)
        RC[i, 0] = rq * c0
        RC[i, 1] = rq * c1
        RC[i, 2] = rq * c2
        W0 = (PI[i, 0] - RC[i, 0]) * B[i, 4]
        W1 = (PI[i, 1] - RC[i, 1]) * B[i, 5]
        W2 = (PI[i, 2] - RC[i, 2]) * B[i, 6]
        TW[i, 0], TW[i, 1], TW[i, 2] = _mul(_row9(Dnew, i), W0, W1, W2)
        for c in range(3):
            VH[i, c] = VH[i, c] + hh * g[c]


@njit(forceinline=True)
def _advance(S, WG, VH, HK, Fn, Tn, IM, Dn, Dnew, T, RC, g, h, hh):
    """The sub-step's state update of every body (compensated sums, NS layout of S), the
    quaternion rescaled when its norm grows large, entries flushed to zero below TINY.
    False on a non-finite state (every body updated first: the test of each entry sets a flag
    instead of leaving the loop, a branch less per entry; measured 0.5-1.5 % of a chain's
    step)."""
    bad = False
    for i in range(S.shape[0]):
        w0, w1, w2 = WG[i, 0], WG[i, 1], WG[i, 2]
        # x += h v_half; v += h/2 (g + F/m) + h/2 g + Fn/m  (VH holds v_half + h/2 g)
        for c in range(3):
            vh = VH[i, c] - hh * g[c]
            S[i, c], S[i, 3 + c] = kahan(S[i, c], S[i, 3 + c], h * vh, True)
            dv = HK[i, c] + hh * g[c] + Fn[i, c] * IM[i]
            S[i, 6 + c], S[i, 9 + c] = kahan(S[i, 6 + c], S[i, 9 + c], dv, True)
        # Pi += h/2 Dn^T T - 4 c/(q h) + Dnew^T Tn
        a0, a1, a2 = _tmul(_row9(Dn, i), T[i, 0], T[i, 1], T[i, 2])
        b0, b1, b2 = _tmul(_row9(Dnew, i), Tn[i, 0], Tn[i, 1], Tn[i, 2])
        S[i, 20], S[i, 23] = kahan(S[i, 20], S[i, 23], (hh * a0 - RC[i, 0]) + b0, True)
        S[i, 21], S[i, 24] = kahan(S[i, 21], S[i, 24], (hh * a1 - RC[i, 1]) + b1, True)
        S[i, 22], S[i, 25] = kahan(S[i, 22], S[i, 25], (hh * a2 - RC[i, 2]) + b2, True)
        # p += p (x) (0, w)
        p0, p1, p2, p3 = S[i, 12], S[i, 13], S[i, 14], S[i, 15]
        dp0 = -((p1 * w0 + p2 * w1) + p3 * w2)
        dp1 = p0 * w0 + (p2 * w2 - p3 * w1)
        dp2 = p0 * w1 + (p3 * w0 - p1 * w2)
        dp3 = p0 * w2 + (p1 * w1 - p2 * w0)
        S[i, 12], S[i, 16] = kahan(p0, S[i, 16], dp0, True)
        S[i, 13], S[i, 17] = kahan(p1, S[i, 17], dp1, True)
        S[i, 14], S[i, 18] = kahan(p2, S[i, 18], dp2, True)
        S[i, 15], S[i, 19] = kahan(p3, S[i, 19], dp3, True)
        nn = (S[i, 12] * S[i, 12] + S[i, 13] * S[i, 13]) + (
            S[i, 14] * S[i, 14] + S[i, 15] * S[i, 15]
        )
        if nn > QUAT_BIG:
            for c in range(12, 20):
                S[i, c] *= QUAT_SHRINK
        for c in range(NS):
            x = S[i, c]
            bad |= not abs(x) < math.inf
            S[i, c] = _ftz(x)
    return not bad
