"""Kernel primitives shared by every compiled integrator of director_model: the
compensated sum, the attitude quaternion's increment and rotation matrix, and the discrete
Moser-Veselov (DMV) equation of a RATTLE step with its residual, Newton solve and polish.

The single body (:mod:`director_model._kernels`), systems of bodies
(:mod:`director_model.system._kernels`) and contact (:mod:`director_model.contact._kernels`)
call these, so the same state gives the same numbers in each. Every function here is inlined
into its caller (``inline="always"``, numba's IR inlining; none is cached on its own). The
callers' on-disk caches are tied to this file's content by :func:`director_model._cache.tie`:
numba keys a cached function on its own file only, so without it an edit here would leave
stale machine code in the callers' caches.

The DMV equation. A RATTLE step of a body with principal moments I (about its centre of mass,
or Ibar about a pivot) rotates its directors by Q = D_n^T D_{n+1}, the solution of
Q Jbar - Jbar Q^T = h hat(pi) (Jbar the convected moments, pi = Pi_n + h/2 tau_n the momentum
at the half step). Q is the unit quaternion (s, v), s > 0; with its Gibbs vector w = v / s
(w = tan(theta/2) e for a rotation by theta about e), Q = 1 + 2/(1 + |w|^2) (hat(w) + hat(w)^2),
and the equation divided by s^2 = 1/(1 + |w|^2) reads

    G(w) = Ibar w + w x (Ibar w) - (1 + |w|^2) b = 0,    b = h pi / 2,

a quadratic equation in three unknowns (no square root). For a spin about a principal axis it
is sin(theta) = h |W|: the branch through Q = 1 folds at theta = 90 degrees (|w| = 1), beyond
which a step is refused. At the solution, with c = w x Ibar w and q = 1 + |w|^2, the momentum
at the end of the step is Q^T pi = pi - 4 c / (q h).
"""

from __future__ import annotations

import math

from numba import njit

EPS = 2.220446049250313e-16
#: Residual tolerance of the DMV solve, relative to the sum of the magnitudes of the terms of
#: each equation (their rounding error is about 2-3 ulps of that sum).
DMV_TOL = 4.0 * EPS
#: Newton iterations of a DMV solve
MAXIT = 30

#: status codes of a DMV solve (the single-body kernels report the same codes)
OK = 0
FAIL_NEWTON = 1  # Newton did not reach the round-off tolerance within MAXIT iterations
FAIL_BRANCH = 2  # no admissible solution: det(Jacobian) <= 0, or a rotation >= 90 degrees
FAIL_NONFINITE = 4  # a non-finite number appeared


@njit(inline="always")
def qnorm(w0, w1, w2):
    """1 + |w|^2, summed as (w0^2 + w1^2) + (w2^2 + 1): two roundings at the ulp of 1 and a
    chain two additions deep."""
    return (w0 * w0 + w1 * w1) + (w2 * w2 + 1.0)


@njit(inline="always")
def kahan(hi, lo, d, comp):
    """Add the increment d to the value hi + lo (Kahan's compensated summation, Kahan 1965;
    Higham, Accuracy and Stability of Numerical Algorithms, 2nd ed., section 4.3).

    Returns (t, e): t = hi + (d + lo) rounded, the new value in double, and e the part of
    d + lo that the rounding lost (exactly, when |hi| >= |d + lo|). Over many steps the error
    of the running sum stays at a few ulps of the sum of the |d|, instead of one rounding of
    the (large) value per step. ``comp`` False gives the plain sum hi + d and e = 0 (the
    uncompensated variant, for round-off studies; lo is then always 0)."""
    y = d + lo
    t = hi + y
    return t, (y - (t - hi)) if comp else 0.0


@njit(inline="always")
def kahan4(hi, lo, d, comp):
    """:func:`kahan` on 4-tuples (a quaternion and its compensation); returns (new values,
    new compensations)."""
    t0, e0 = kahan(hi[0], lo[0], d[0], comp)
    t1, e1 = kahan(hi[1], lo[1], d[1], comp)
    t2, e2 = kahan(hi[2], lo[2], d[2], comp)
    t3, e3 = kahan(hi[3], lo[3], d[3], comp)
    return (t0, t1, t2, t3), (e0, e1, e2, e3)


@njit(inline="always")
def quat_increment(p, w):
    """p (x) (0, w), the Hamilton product: the increment of the quaternion p when it is
    multiplied by (1, w), the (unnormalised) quaternion of Q with Gibbs vector w. p a
    4-tuple (scalar first), w a 3-tuple; O(|w| |p|)."""
    return (
        -((p[1] * w[0] + p[2] * w[1]) + p[3] * w[2]),
        p[0] * w[0] + (p[2] * w[2] - p[3] * w[1]),
        p[0] * w[1] + (p[3] * w[0] - p[1] * w[2]),
        p[0] * w[2] + (p[1] * w[1] - p[2] * w[0]),
    )


@njit(inline="always")
def quat_matrix(p):
    """R(p/|p|), the rotation of the quaternion p (any norm > 0), as a 9-tuple row-major:
    ((p0^2 - |v|^2) 1 + 2 v v^T + 2 p0 hat(v)) / |p|^2."""
    a = p[0] * p[0]
    b = p[1] * p[1]
    c = p[2] * p[2]
    d = p[3] * p[3]
    r = 1.0 / ((a + b) + (c + d))
    r2 = 2.0 * r
    xy = p[1] * p[2]
    xz = p[1] * p[3]
    yz = p[2] * p[3]
    sx = p[0] * p[1]
    sy = p[0] * p[2]
    sz = p[0] * p[3]
    return (
        ((a + b) - (c + d)) * r, (xy - sz) * r2, (xz + sy) * r2,
        (xy + sz) * r2, ((a + c) - (b + d)) * r, (yz - sx) * r2,
        (xz - sy) * r2, (yz + sx) * r2, ((a + d) - (b + c)) * r,
    )  # fmt: skip


@njit(inline="always")
def dmv_residual(b0, b1, b2, w0, w1, w2, u0, u1, u2):
    """G(w) = u + w x u - (1 + |w|^2) b with u = Ibar w (computed by the caller, general or
    diagonal Ibar). Returns (G0, G1, G2, converged, finite): converged when every |G_i| is
    within DMV_TOL of the largest sum of term magnitudes, finite unless that sum overflowed.
    Used by both DMV solvers and the straight-line form, inlined by numba."""
    q = qnorm(w0, w1, w2)
    c0 = w1 * u2 - w2 * u1
    c1 = w2 * u0 - w0 * u2
    c2 = w0 * u1 - w1 * u0
    G0 = u0 + c0 - q * b0
    G1 = u1 + c1 - q * b1
    G2 = u2 + c2 - q * b2
    sc = max(
        abs(u0) + abs(c0) + abs(q * b0),
        abs(u1) + abs(c1) + abs(q * b1),
        abs(u2) + abs(c2) + abs(q * b2),
    )
    return G0, G1, G2, max(abs(G0), abs(G1), abs(G2)) <= DMV_TOL * sc, sc < math.inf


@njit(inline="always")
def cramer3(K00, K01, K02, K10, K11, K12, K20, K21, K22, G0, G1, G2):
    """det K and K^{-1} G by cofactors (Cramer's rule). With det == 0 the correction is inf,
    never a ZeroDivisionError (callers test det first; the guard keeps plain Python, under
    NUMBA_DISABLE_JIT=1, and the branch-free vector code alike)."""
    C00 = K11 * K22 - K12 * K21
    C01 = K12 * K20 - K10 * K22
    C02 = K10 * K21 - K11 * K20
    det = K00 * C00 + K01 * C01 + K02 * C02
    C10 = K02 * K21 - K01 * K22
    C11 = K00 * K22 - K02 * K20
    C12 = K01 * K20 - K00 * K21
    C20 = K01 * K12 - K02 * K11
    C21 = K02 * K10 - K00 * K12
    C22 = K00 * K11 - K01 * K10
    rd = 1.0 / det if det != 0.0 else math.inf
    d0 = (C00 * G0 + C10 * G1 + C20 * G2) * rd
    d1 = (C01 * G0 + C11 * G1 + C21 * G2) * rd
    d2 = (C02 * G0 + C12 * G1 + C22 * G2) * rd
    return det, d0, d1, d2


@njit(inline="always")
def stagnated(d0, d1, d2, w0, w1, w2):
    """The Newton correction is below one ulp of w: Newton has stagnated at round-off."""
    return max(abs(d0), abs(d1), abs(d2)) <= EPS * max(abs(w0), abs(w1), abs(w2))


@njit(inline="always")
def diag_start(I0, I1, I2, a0, a1, a2, b0, b1, b2):
    """Predictor Ibar w = b, then two fixed-point corrections
    w <- Ibar^{-1} ((1 + |w|^2) b - w x Ibar w) (contraction ~|w|, error O(|w|^4))."""
    e0 = I2 - I1
    e1 = I0 - I2
    e2 = I1 - I0
    w0 = a0 * b0
    w1 = a1 * b1
    w2 = a2 * b2
    for _ in range(2):
        q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
        # w x (Ibar w) = (e0 w1 w2, e1 w2 w0, e2 w0 w1)
        w0n = a0 * (q * b0 - e0 * w1 * w2)
        w1n = a1 * (q * b1 - e1 * w2 * w0)
        w2n = a2 * (q * b2 - e2 * w0 * w1)
        w0 = w0n
        w1 = w1n
        w2 = w2n
    return w0, w1, w2


@njit(inline="always")
def diag_newton(I0, I1, I2, b0, b1, b2, w0, w1, w2, G0, G1, G2):
    """det K and the Newton correction K^{-1} G, K = Ibar + hat(w) Ibar - hat(Ibar w) - 2 b w^T
    (the diagonal-Ibar entries of the Jacobian in _dmv_solve)."""
    e0 = I2 - I1
    e1 = I0 - I2
    e2 = I1 - I0
    t0 = 2.0 * b0
    t1 = 2.0 * b1
    t2 = 2.0 * b2
    return cramer3(
        I0 - t0 * w0, w2 * e0 - t0 * w1, w1 * e0 - t0 * w2,
        w2 * e1 - t1 * w0, I1 - t1 * w1, w0 * e1 - t1 * w2,
        w1 * e2 - t2 * w0, w0 * e2 - t2 * w1, I2 - t2 * w2,
        G0, G1, G2,
    )  # fmt: skip


@njit(inline="always")
def diag_polish(I0, I1, I2, a0, a1, a2, w0, w1, w2, G0, G1, G2):
    """Polish (see _dmv_solve): w -= Ibar^{-1} G, then c = w x Ibar w and q = 1 + |w|^2 at
    the new w; this takes the slow torque-free energy drift from ~0.6 to ~0.1 ulp per step.
    Returns (w0, w1, w2, c0, c1, c2, q)."""
    w0 -= a0 * G0
    w1 -= a1 * G1
    w2 -= a2 * G2
    q = qnorm(w0, w1, w2)
    u0 = I0 * w0
    u1 = I1 * w1
    u2 = I2 * w2
    return w0, w1, w2, w1 * u2 - w2 * u1, w2 * u0 - w0 * u2, w0 * u1 - w1 * u0, q


#: Largest predictor size s = max_i |(Ibar^{-1} b)_i| (about h|W|/2, the half rotation angle)
#: for which the straight-line solve is tried; larger steps go to the Newton loop at once.
FP_SMAX = 2.5e-2


@njit(inline="always")
def fp_count(s):
    """Number of fixed-point corrections after which the predictor w = Ibar^{-1} b of size s
    is within 0.1 ulp of the solution, as a float: 3 for s <= 6.5e-5, 4 up to 3.7e-4, 5 up
    to 1.45e-3 (h|W| ~ 3e-3), 7 up to 6.5e-3, 10 up to FP_SMAX.

    Each correction (:func:`fp_step`) shrinks the error by about 0.7 s (its Jacobian is
    Ibar^{-1} (2 b w^T - w x Ibar - ...) = O(|w|)) and the predictor's relative error is about
    0.7 s. The least k that leaves a worst-case relative error of 0.1 ulp, measured in
    80-bit arithmetic over 400 random bodies (a quarter of them flat) and directions, is 3
    up to s = 8e-5, 4 up to 4.6e-4, 5 up to 1.8e-3, 7 up to 8e-3, 10 up to 3.2e-2; the
    thresholds here are 20 % lower. The acceptance test that follows decides; the count
    only makes it pass. Four comparisons, no branch."""
    return (
        3.0
        + (1.0 if s > 6.5e-5 else 0.0)
        + (1.0 if s > 3.7e-4 else 0.0)
        + (2.0 if s > 1.45e-3 else 0.0)
        + (3.0 if s > 6.5e-3 else 0.0)
    )


@njit(inline="always")
def fp_step(ab0, ab1, ab2, ae0, ae1, ae2, w0, w1, w2):
    """One fixed-point correction of the diagonal DMV equation,
    w <- Ibar^{-1} ((1 + |w|^2) b - w x Ibar w) = (1 + |w|^2) ab - ae * (w1 w2, w2 w0, w0 w1)
    with ab = Ibar^{-1} b and ae = Ibar^{-1} e (P[33:36]). Latency: a product, two additions
    (the norm), a product and a subtraction, no division."""
    q = qnorm(w0, w1, w2)
    return q * ab0 - ae0 * (w1 * w2), q * ab1 - ae1 * (w2 * w0), q * ab2 - ae2 * (w0 * w1)


@njit(inline="always")
def diag_finish(I0, I1, I2, a0, a1, a2, b0, b1, b2, w0, w1, w2):
    """The end of the straight-line solve: the residual G of w (:func:`dmv_residual`), the
    polish w -= Ibar^{-1} G (:func:`diag_polish`), and whether the solve is done: the
    polish moved w by at most DMV_TOL max|w_i| (then the error left after it is a fraction
    ~|w| of that, below an ulp) and the rotation is below 90 degrees (q = 1 + |w|^2 < 2).
    Returns (ok, w0, w1, w2, c0, c1, c2, q) with c = w x Ibar w and q at the polished w."""
    G0, G1, G2, _, _ = dmv_residual(b0, b1, b2, w0, w1, w2, I0 * w0, I1 * w1, I2 * w2)
    d = max(abs(a0 * G0), abs(a1 * G1), abs(a2 * G2))
    conv = d <= DMV_TOL * max(abs(w0), abs(w1), abs(w2))
    w0, w1, w2, c0, c1, c2, q = diag_polish(I0, I1, I2, a0, a1, a2, w0, w1, w2, G0, G1, G2)
    return conv & (q < 2.0), w0, w1, w2, c0, c1, c2, q


@njit(inline="always")
def dmv_solve_diag(I0, I1, I2, a0, a1, a2, b0, b1, b2):
    """Solve the DMV equation G(w) = 0 for a diagonal Ibar = diag(I) (a = 1/I): predictor,
    two fixed-point corrections (:func:`diag_start`), Newton (:func:`diag_newton`) until the
    residual is at round-off (:func:`dmv_residual`), then the polish (:func:`diag_polish`).
    Returns (status, w0, w1, w2, c0, c1, c2, q) with c = w x Ibar w and q = 1 + |w|^2 at the
    solution; status OK, FAIL_NEWTON (no convergence within MAXIT), FAIL_BRANCH (det <= 0 or a
    rotation of 90 degrees or more: past the step-size limit) or FAIL_NONFINITE."""
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    q = 1.0
    w0, w1, w2 = diag_start(I0, I1, I2, a0, a1, a2, b0, b1, b2)
    for _ in range(MAXIT):
        G0, G1, G2, conv, finite = dmv_residual(b0, b1, b2, w0, w1, w2, I0 * w0, I1 * w1, I2 * w2)
        if conv:
            w0, w1, w2, c0, c1, c2, q = diag_polish(I0, I1, I2, a0, a1, a2, w0, w1, w2, G0, G1, G2)
            break
        if not finite:
            return FAIL_NONFINITE, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
        det, d0, d1, d2 = diag_newton(I0, I1, I2, b0, b1, b2, w0, w1, w2, G0, G1, G2)
        if not det > 0.0:
            return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
        w0 -= d0
        w1 -= d1
        w2 -= d2
        if stagnated(d0, d1, d2, w0, w1, w2):
            # c = w x Ibar w and q at the final w for the momentum update
            q = qnorm(w0, w1, w2)
            c0 = w1 * (I2 * w2) - w2 * (I1 * w1)
            c1 = w2 * (I0 * w0) - w0 * (I2 * w2)
            c2 = w0 * (I1 * w1) - w1 * (I0 * w0)
            break
    else:
        return FAIL_NEWTON, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    if not (w0 * w0 + w1 * w1 + w2 * w2) < 1.0:
        return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    return OK, w0, w1, w2, c0, c1, c2, q


@njit(inline="always")
def dmv_solve(I0, I1, I2, a0, a1, a2, ae0, ae1, ae2, b0, b1, b2):
    """Solve the DMV equation for a diagonal Ibar = diag(I), a = 1/I, ae = e/I with
    e = (I2 - I1, I0 - I2, I1 - I0): the straight-line solve (predictor Ibar^{-1} b,
    :func:`fp_count` fixed-point corrections, :func:`diag_finish`) when the predictor is at
    most FP_SMAX, else or if it does not finish the Newton loop :func:`dmv_solve_diag`.
    Returns (status, w0, w1, w2, c0, c1, c2, q) as :func:`dmv_solve_diag`. The single-body
    step (:func:`director_model._kernels._rattle_solve`) is this same sequence, split so that
    the batched loop can vectorise its straight-line part."""
    ab0 = a0 * b0
    ab1 = a1 * b1
    ab2 = a2 * b2
    s = max(abs(ab0), abs(ab1), abs(ab2))
    if s <= FP_SMAX:
        w0 = ab0
        w1 = ab1
        w2 = ab2
        for _ in range(int(fp_count(s))):
            w0, w1, w2 = fp_step(ab0, ab1, ab2, ae0, ae1, ae2, w0, w1, w2)
        ok, w0, w1, w2, c0, c1, c2, q = diag_finish(I0, I1, I2, a0, a1, a2, b0, b1, b2, w0, w1, w2)
        if ok:
            return OK, w0, w1, w2, c0, c1, c2, q
    return dmv_solve_diag(I0, I1, I2, a0, a1, a2, b0, b1, b2)
