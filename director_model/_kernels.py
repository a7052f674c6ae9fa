"""Compiled kernels: the step functions of every scheme and the time loops.

All numba code of director_model is in this one module on purpose: numba's on-disk cache
(``cache=True``) is invalidated by the timestamp of the file that defines the cached
function, not by the files of the functions it calls, so kernels spread over several modules
could silently run stale machine code after an edit.

Debugging: run with the environment variable ``NUMBA_DISABLE_JIT=1`` to execute these same
functions as plain Python (``prange`` becomes ``range``); the numbers are the same (a test
compares short RATTLE and energy-momentum runs), only about 1e3 times slower.

Data layout (float64 arrays, so one compiled signature serves every body):

``P`` body parameters, length ``NP``:
    P[0] = m; P[1:10] = Jbar (row-major); P[10:19] = Ibar; P[19:28] = Ibar^{-1};
    P[28:31] = c (pivot in body axes rel. to the COM, zeros if none); P[31] = 1.0 if pivoted;
    P[32] = 1.0 if Ibar is diagonal (selects the cheaper Jacobian; same equations).
    Ibar^{-1} is the inverse of the positive definite inertia (never of the singular
    director mass matrix): it maps body momentum to body angular velocity.
``S`` state, length ``NS``:
    S[0:3] x_G; S[3:6] v_G; S[6:15] D (row-major: D[r, i] = S[6 + 3 r + i], column i is the
    director d_i); S[15:24] D' (same layout); S[24:27] Pi = Ibar W (RATTLE family);
    S[27:30] body torque of gravity at D (RATTLE family, cached between steps);
    S[30:36] scaled multipliers mu = h^2/4 Lambda (energy-momentum warm start; order 11, 22,
    33, 12, 13, 23).

The batched RATTLE loop keeps a block of up to BLOCK bodies in one flat array, row-major with
BLOCK lanes per row (the rows of S, then those of P, then two flags; see ``ROW_P``), so that
its lane loop vectorises.

The kernels never raise: they return the status codes below, and the Python layer turns a
failure into StepSizeError with the time reached and a step-size estimate.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

NP = 33
NS = 36

#: method codes
RATTLE_FAMILY = 0
ENERGY_MOMENTUM = 1

#: status codes
OK = 0
FAIL_NEWTON = 1  # Newton did not reach the round-off tolerance within the iteration cap
FAIL_BRANCH = 2  # no admissible solution: |v| >= 1, det(Jacobian) <= 0, or rotation >= 90 deg
FAIL_SINGULAR = 3  # singular saddle-point matrix (energy-momentum Newton)
FAIL_NONFINITE = 4  # a non-finite number appeared in the state

STATUS_TEXT = {
    FAIL_NEWTON: "Newton's method did not converge to round-off within the iteration cap",
    FAIL_BRANCH: (
        "the implicit step equation has no admissible solution on the branch through the "
        "identity (past a fold of the solution branch, or a rotation of 90 degrees or more "
        "in one step)"
    ),
    FAIL_SINGULAR: "the Newton matrix of the step is singular",
    FAIL_NONFINITE: "a non-finite number appeared in the state",
}

EPS = 2.220446049250313e-16
#: Residual tolerance of the DMV Newton solve, relative to the sum of the magnitudes of the
#: terms of each equation (their rounding error is about 2-3 ulps of that sum).
DMV_TOL = 4.0 * EPS
#: Energy-momentum residual tolerance, relative to the magnitude of the terms (9x9 products
#: with up to 6 terms each: rounding of order 10 ulps).
EM_TOL = 16.0 * EPS
MAXIT = 30


# --------------------------------------------------------------------------------------------
# RATTLE in reduced form: the discrete Moser-Veselov equation
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def _dmv_solve(P, b0, b1, b2):
    """Solve the discrete Moser-Veselov equation Q Jbar - Jbar Q^T = 2 hat(b), b = h pi / 2,
    for the rotation Q = D_n^T D_{n+1}.

    Q is the unit quaternion (s, v), s > 0. We solve for its Gibbs vector w = v / s
    (w = tan(theta/2) e for a rotation by theta about e), with
    Q = 1 + 2/(1 + |w|^2) (hat(w) + hat(w)^2). Substituting the quaternion form
    Q = (s^2 - v.v) 1 + 2 v v^T + 2 s hat(v) gives
    Q Jbar - Jbar Q^T = 2 hat(s Ibar v + v x Ibar v) (using v x Jbar v = -v x Ibar v,
    Ibar = tr(Jbar) 1 - Jbar), and dividing by s^2 = 1/(1 + |w|^2):

        G(w) = Ibar w + w x (Ibar w) - (1 + |w|^2) b = 0,

    a quadratic equation in three unknowns (no square root), solved by Newton with
    Jacobian Ibar + hat(w) Ibar - hat(Ibar w) - 2 b w^T. For a spin about a principal axis
    it reads sin(theta) = h |W|: the branch through Q = 1 folds at theta = 90 deg (|w| = 1),
    beyond which the step is refused. Returns (status, w0, w1, w2, c0, c1, c2, q) with
    c = w x Ibar w and q = 1 + |w|^2 at the solution, which give the new momentum cheaply:
    Q^T pi = vee(Jbar Q - Q^T Jbar)/h = 2 (Ibar w - c)/(q h) and pi = 2 (Ibar w + c)/(q h),
    so Q^T pi = pi - 4 c/(q h).
    """
    I00 = P[10]
    I01 = P[11]
    I02 = P[12]
    I10 = P[13]
    I11 = P[14]
    I12 = P[15]
    I20 = P[16]
    I21 = P[17]
    I22 = P[18]
    # predictor: G linearised at w = 0 is Ibar w = b; then two fixed-point corrections
    # w <- Ibar^{-1} ((1 + |w|^2) b - w x Ibar w) (contraction ~|w|, error O(|w|^4))
    w0 = P[19] * b0 + P[20] * b1 + P[21] * b2
    w1 = P[22] * b0 + P[23] * b1 + P[24] * b2
    w2 = P[25] * b0 + P[26] * b1 + P[27] * b2
    for _ in range(2):
        u0 = I00 * w0 + I01 * w1 + I02 * w2
        u1 = I10 * w0 + I11 * w1 + I12 * w2
        u2 = I20 * w0 + I21 * w1 + I22 * w2
        q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
        r0 = q * b0 - (w1 * u2 - w2 * u1)
        r1 = q * b1 - (w2 * u0 - w0 * u2)
        r2 = q * b2 - (w0 * u1 - w1 * u0)
        w0 = P[19] * r0 + P[20] * r1 + P[21] * r2
        w1 = P[22] * r0 + P[23] * r1 + P[24] * r2
        w2 = P[25] * r0 + P[26] * r1 + P[27] * r2
    for _ in range(MAXIT):
        u0 = I00 * w0 + I01 * w1 + I02 * w2
        u1 = I10 * w0 + I11 * w1 + I12 * w2
        u2 = I20 * w0 + I21 * w1 + I22 * w2
        G0, G1, G2, conv, finite = _dmv_residual(b0, b1, b2, w0, w1, w2, u0, u1, u2)
        if conv:
            # Polish: one simplified-Newton step with the leading part Ibar of the Jacobian
            # (K = Ibar (1 + O(|w|))) shrinks the accepted residual (<= 4 ulps) by a factor
            # ~|w|. The momentum update Q^T pi = pi - 4c/(qh) changes the energy by
            # 8 G . Ibar^{-1} c/(qh)^2, about 16 |w| ulps of E per step with a residual of one
            # sign; polishing removes that slow drift. c and q are then taken at the new w.
            w0 -= P[19] * G0 + P[20] * G1 + P[21] * G2
            w1 -= P[22] * G0 + P[23] * G1 + P[24] * G2
            w2 -= P[25] * G0 + P[26] * G1 + P[27] * G2
            q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
            u0 = I00 * w0 + I01 * w1 + I02 * w2
            u1 = I10 * w0 + I11 * w1 + I12 * w2
            u2 = I20 * w0 + I21 * w1 + I22 * w2
            c0 = w1 * u2 - w2 * u1
            c1 = w2 * u0 - w0 * u2
            c2 = w0 * u1 - w1 * u0
            break
        if not finite:
            return FAIL_NONFINITE, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
        # Jacobian K = Ibar + hat(w) Ibar - hat(u) - 2 b w^T
        t0 = 2.0 * b0
        t1 = 2.0 * b1
        t2 = 2.0 * b2
        K00 = I00 + (-w2 * I10 + w1 * I20) - t0 * w0
        K01 = I01 + (-w2 * I11 + w1 * I21) + u2 - t0 * w1
        K02 = I02 + (-w2 * I12 + w1 * I22) - u1 - t0 * w2
        K10 = I10 + (w2 * I00 - w0 * I20) - u2 - t1 * w0
        K11 = I11 + (w2 * I01 - w0 * I21) - t1 * w1
        K12 = I12 + (w2 * I02 - w0 * I22) + u0 - t1 * w2
        K20 = I20 + (-w1 * I00 + w0 * I10) + u1 - t2 * w0
        K21 = I21 + (-w1 * I01 + w0 * I11) - u0 - t2 * w1
        K22 = I22 + (-w1 * I02 + w0 * I12) - t2 * w2
        det, d0, d1, d2 = _cramer3(K00, K01, K02, K10, K11, K12, K20, K21, K22, G0, G1, G2)
        if not det > 0.0:
            # the branch through Q = 1 has det > 0 up to its first fold; det <= 0 means the
            # step is past the solvability limit or Newton is heading to another branch
            return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
        w0 -= d0
        w1 -= d1
        w2 -= d2
        if _stagnated(d0, d1, d2, w0, w1, w2):
            # c = w x Ibar w and q at the final w for the momentum update
            u0 = I00 * w0 + I01 * w1 + I02 * w2
            u1 = I10 * w0 + I11 * w1 + I12 * w2
            u2 = I20 * w0 + I21 * w1 + I22 * w2
            q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
            c0 = w1 * u2 - w2 * u1
            c1 = w2 * u0 - w0 * u2
            c2 = w0 * u1 - w1 * u0
            break
    else:
        return FAIL_NEWTON, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    if not (w0 * w0 + w1 * w1 + w2 * w2) < 1.0:
        # rotation angle of Q >= 90 degrees: for a principal-axis spin this is exactly the
        # second branch of sin(theta) = h|W|, theta > pi/2; refused in general (conservative)
        return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    return OK, w0, w1, w2, c0, c1, c2, q


@njit(inline="always")
def _dmv_residual(b0, b1, b2, w0, w1, w2, u0, u1, u2):
    """G(w) = u + w x u - (1 + |w|^2) b with u = Ibar w (computed by the caller, general or
    diagonal Ibar). Returns (G0, G1, G2, converged, finite): converged when every |G_i| is
    within DMV_TOL of the largest sum of term magnitudes, finite unless that sum overflowed.
    Used by both DMV solvers and the straight-line form, inlined by numba."""
    q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
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
def _cramer3(K00, K01, K02, K10, K11, K12, K20, K21, K22, G0, G1, G2):
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


# The pieces of _dmv_solve_diag, inlined by numba into it and into _dmv_diag_fast, so that the
# loop and its straight-line form compute every quantity with the same expressions.
@njit(inline="always")
def _diag_start(I0, I1, I2, a0, a1, a2, b0, b1, b2):
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
def _diag_newton(I0, I1, I2, b0, b1, b2, w0, w1, w2, G0, G1, G2):
    """det K and the Newton correction K^{-1} G, K = Ibar + hat(w) Ibar - hat(Ibar w) - 2 b w^T
    (the diagonal-Ibar entries of the Jacobian in _dmv_solve)."""
    e0 = I2 - I1
    e1 = I0 - I2
    e2 = I1 - I0
    t0 = 2.0 * b0
    t1 = 2.0 * b1
    t2 = 2.0 * b2
    return _cramer3(
        I0 - t0 * w0, w2 * e0 - t0 * w1, w1 * e0 - t0 * w2,
        w2 * e1 - t1 * w0, I1 - t1 * w1, w0 * e1 - t1 * w2,
        w1 * e2 - t2 * w0, w0 * e2 - t2 * w1, I2 - t2 * w2,
        G0, G1, G2,
    )  # fmt: skip


@njit(inline="always")
def _diag_polish(I0, I1, I2, a0, a1, a2, w0, w1, w2, G0, G1, G2):
    """Polish (see _dmv_solve): w -= Ibar^{-1} G, then c = w x Ibar w and q = 1 + |w|^2 at
    the new w; this takes the slow torque-free energy drift from ~0.6 to ~0.1 ulp per step.
    Returns (w0, w1, w2, c0, c1, c2, q)."""
    w0 -= a0 * G0
    w1 -= a1 * G1
    w2 -= a2 * G2
    q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
    u0 = I0 * w0
    u1 = I1 * w1
    u2 = I2 * w2
    return w0, w1, w2, w1 * u2 - w2 * u1, w2 * u0 - w0 * u2, w0 * u1 - w1 * u0, q


@njit(inline="always")
def _stagnated(d0, d1, d2, w0, w1, w2):
    """The Newton correction is below one ulp of w: Newton has stagnated at round-off."""
    return max(abs(d0), abs(d1), abs(d2)) <= EPS * max(abs(w0), abs(w1), abs(w2))


@njit(inline="always")
def _dmv_diag_fast(I0, I1, I2, a0, a1, a2, b0, b1, b2):
    """The outcome of :func:`_dmv_solve_diag` in almost every step, as straight-line code:
    converged after the predictor and two fixed-point corrections, or after one Newton
    update; then the polish. Built from the loop's own pieces, so when it returns ``ok`` its
    w, c, q are the loop's to the last bit; otherwise the loop decides (more Newton updates,
    stagnation, a failure). No early exit: the tests become flags, which lets the block loop
    of :func:`_rattle_block_substep` run it in SIMD lanes. Returns (ok, w0, w1, w2, c0, c1,
    c2, q)."""
    w0, w1, w2 = _diag_start(I0, I1, I2, a0, a1, a2, b0, b1, b2)
    G0, G1, G2, conv1, finite1 = _dmv_residual(b0, b1, b2, w0, w1, w2, I0 * w0, I1 * w1, I2 * w2)
    det, d0, d1, d2 = _diag_newton(I0, I1, I2, b0, b1, b2, w0, w1, w2, G0, G1, G2)
    v0 = w0 - d0
    v1 = w1 - d1
    v2 = w2 - d2
    stagnated = _stagnated(d0, d1, d2, v0, v1, v2)
    H0, H1, H2, conv2, _ = _dmv_residual(b0, b1, b2, v0, v1, v2, I0 * v0, I1 * v1, I2 * v2)
    newton1 = (not conv1) & finite1 & (det > 0.0) & (not stagnated) & conv2
    # polish from the accepted iterate
    w0, w1, w2, c0, c1, c2, q = _diag_polish(
        I0, I1, I2, a0, a1, a2,
        w0 if conv1 else v0, w1 if conv1 else v1, w2 if conv1 else v2,
        G0 if conv1 else H0, G1 if conv1 else H1, G2 if conv1 else H2,
    )  # fmt: skip
    return conv1 | newton1, w0, w1, w2, c0, c1, c2, q


@njit(cache=True)
def _dmv_solve_diag(P, b0, b1, b2):
    """:func:`_dmv_solve` for a diagonal Ibar (a free body, or a pivot on a principal
    axis): the same equations and tests with the zero products left out, which shortens the
    latency-bound chain of the step by about a fifth. The common outcome is computed by
    :func:`_dmv_diag_fast` first; the loop below gives the same numbers in that case and
    handles the others."""
    I0 = P[10]
    I1 = P[14]
    I2 = P[18]
    a0 = P[19]
    a1 = P[23]
    a2 = P[27]
    ok, w0, w1, w2, c0, c1, c2, q = _dmv_diag_fast(I0, I1, I2, a0, a1, a2, b0, b1, b2)
    if not ok:
        # the general loop: more Newton updates, stagnation or a failure
        w0, w1, w2 = _diag_start(I0, I1, I2, a0, a1, a2, b0, b1, b2)
        for _ in range(MAXIT):
            G0, G1, G2, conv, finite = _dmv_residual(
                b0, b1, b2, w0, w1, w2, I0 * w0, I1 * w1, I2 * w2
            )
            if conv:
                w0, w1, w2, c0, c1, c2, q = _diag_polish(
                    I0, I1, I2, a0, a1, a2, w0, w1, w2, G0, G1, G2
                )
                break
            if not finite:
                return FAIL_NONFINITE, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
            det, d0, d1, d2 = _diag_newton(I0, I1, I2, b0, b1, b2, w0, w1, w2, G0, G1, G2)
            if not det > 0.0:
                return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
            w0 -= d0
            w1 -= d1
            w2 -= d2
            if _stagnated(d0, d1, d2, w0, w1, w2):
                # c and q at the final w for the momentum update
                q = 1.0 + w0 * w0 + w1 * w1 + w2 * w2
                c0 = (I2 - I1) * w1 * w2
                c1 = (I0 - I2) * w2 * w0
                c2 = (I1 - I0) * w0 * w1
                break
        else:
            return FAIL_NEWTON, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    if not (w0 * w0 + w1 * w1 + w2 * w2) < 1.0:
        return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
    return OK, w0, w1, w2, c0, c1, c2, q


@njit(inline="always")
def _torque(piv, m, c0, c1, c2, g0, g1, g2, D00, D01, D02, D10, D11, D12, D20, D21, D22):
    """Body torque of gravity about the pivot, tau = m (D^T g) x c (zero for a free body).

    From V = -m g . x_G with x_G = -D c: the director forces are f_i = -dV/dd_i = -m c_i g and
    tau = vee(D^T F - F^T D) = -m c x (D^T g) (numerics.md section 2). Zero for a free body
    (gravity acts at the centre of mass)."""
    gb0 = D00 * g0 + D10 * g1 + D20 * g2
    gb1 = D01 * g0 + D11 * g1 + D21 * g2
    gb2 = D02 * g0 + D12 * g1 + D22 * g2
    t0 = m * (gb1 * c2 - gb2 * c1) if piv else 0.0
    t1 = m * (gb2 * c0 - gb0 * c2) if piv else 0.0
    t2 = m * (gb0 * c1 - gb1 * c0) if piv else 0.0
    return t0, t1, t2


@njit(cache=True)
def _gravity_torque(P, g, S):
    """:func:`_torque` at the state's D, stored in S[27:30]."""
    t0, t1, t2 = _torque(
        P[31] != 0.0, P[0], P[28], P[29], P[30], g[0], g[1], g[2],
        S[6], S[7], S[8], S[9], S[10], S[11], S[12], S[13], S[14],
    )  # fmt: skip
    S[27] = t0
    S[28] = t1
    S[29] = t2


@njit(inline="always")
def _cayley_increment(w0, w1, w2, D00, D01, D02, D10, D11, D12, D20, D21, D22):
    """D Q for Q = 1 + f (hat(w) + hat(w)^2), f = 2/(1 + |w|^2) (the Cayley form of the
    quaternion with Gibbs vector w), computed as D + D (Q - 1): the increment form keeps the
    rounding of the update at the ulp of the small increment, instead of a biased rounding of
    1 - O(h^2) on the diagonal. Returns the 9 entries row by row."""
    x00 = w0 * w0
    x11 = w1 * w1
    x22 = w2 * w2
    f = 2.0 / (1.0 + x00 + x11 + x22)
    x01 = w0 * w1
    x02 = w0 * w2
    x12 = w1 * w2
    Q00 = -f * (x11 + x22)
    Q11 = -f * (x00 + x22)
    Q22 = -f * (x00 + x11)
    Q01 = f * (x01 - w2)
    Q10 = f * (x01 + w2)
    Q02 = f * (x02 + w1)
    Q20 = f * (x02 - w1)
    Q12 = f * (x12 - w0)
    Q21 = f * (x12 + w0)
    return (
        D00 + (D00 * Q00 + D01 * Q10 + D02 * Q20),
        D01 + (D00 * Q01 + D01 * Q11 + D02 * Q21),
        D02 + (D00 * Q02 + D01 * Q12 + D02 * Q22),
        D10 + (D10 * Q00 + D11 * Q10 + D12 * Q20),
        D11 + (D10 * Q01 + D11 * Q11 + D12 * Q21),
        D12 + (D10 * Q02 + D11 * Q12 + D12 * Q22),
        D20 + (D20 * Q00 + D21 * Q10 + D22 * Q20),
        D21 + (D20 * Q01 + D21 * Q11 + D22 * Q21),
        D22 + (D20 * Q02 + D21 * Q12 + D22 * Q22),
    )


@njit(cache=True)
def _rattle_init(P, g, S):
    """From the director state (D, D') set Pi = Ibar vee(skew(D^T D')) and the torque."""
    W0 = 0.0
    W1 = 0.0
    W2 = 0.0
    # A = D^T D'; W = vee(skew(A)) = ((A21 - A12)/2, (A02 - A20)/2, (A10 - A01)/2)
    A = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for r in range(3):
                acc += S[6 + 3 * r + i] * S[15 + 3 * r + j]
            A[i, j] = acc
    W0 = 0.5 * (A[2, 1] - A[1, 2])
    W1 = 0.5 * (A[0, 2] - A[2, 0])
    W2 = 0.5 * (A[1, 0] - A[0, 1])
    S[24] = P[10] * W0 + P[11] * W1 + P[12] * W2
    S[25] = P[13] * W0 + P[14] * W1 + P[15] * W2
    S[26] = P[16] * W0 + P[17] * W1 + P[18] * W2
    _gravity_torque(P, g, S)


@njit(cache=True)
def _rattle_substep(P, g, S, h):
    """One RATTLE step of size h (h may be negative inside a composition, never 0).

    pi = Pi_n + h/2 tau_n; solve Q Jbar - Jbar Q^T = h hat(pi); D_{n+1} = D_n Q;
    Pi_{n+1} = Q^T pi + h/2 tau_{n+1}; free centre of mass x += h v + h^2/2 g, v += h g.
    """
    hh = 0.5 * h
    p0 = S[24] + hh * S[27]
    p1 = S[25] + hh * S[28]
    p2 = S[26] + hh * S[29]
    if P[32] != 0.0:
        st, w0, w1, w2, c0, c1, c2, q = _dmv_solve_diag(P, hh * p0, hh * p1, hh * p2)
    else:
        st, w0, w1, w2, c0, c1, c2, q = _dmv_solve(P, hh * p0, hh * p1, hh * p2)
    if st != OK:
        return st
    # D <- D Q
    (
        S[6], S[7], S[8], S[9], S[10], S[11], S[12], S[13], S[14]
    ) = _cayley_increment(
        w0, w1, w2, S[6], S[7], S[8], S[9], S[10], S[11], S[12], S[13], S[14]
    )  # fmt: skip
    _gravity_torque(P, g, S)
    # Q^T pi = pi - 4 c/(q h) (see _dmv_solve): the same quantity as the matrix product, with
    # the small change of the momentum computed directly, off the latency chain of Q
    r = 4.0 / (q * h)
    n0 = p0 - r * c0 + hh * S[27]
    n1 = p1 - r * c1 + hh * S[28]
    n2 = p2 - r * c2 + hh * S[29]
    if not (abs(n0) + abs(n1) + abs(n2)) < math.inf:
        return FAIL_NONFINITE
    S[24] = n0
    S[25] = n1
    S[26] = n2
    if P[31] == 0.0:
        for k in range(3):
            S[k] += h * S[3 + k] + h * hh * g[k]
            S[3 + k] += h * g[k]
    return OK


@njit(cache=True)
def _rattle_director_velocity(P, S):
    """D' = D hat(W) with W = Ibar^{-1} Pi, written to S[15:24]."""
    W0 = P[19] * S[24] + P[20] * S[25] + P[21] * S[26]
    W1 = P[22] * S[24] + P[23] * S[25] + P[24] * S[26]
    W2 = P[25] * S[24] + P[26] * S[25] + P[27] * S[26]
    for r in range(3):
        a0 = S[6 + 3 * r]
        a1 = S[7 + 3 * r]
        a2 = S[8 + 3 * r]
        # row r of D hat(W); hat(W) columns: (0, W2, -W1), (-W2, 0, W0), (W1, -W0, 0)
        S[15 + 3 * r] = a1 * W2 - a2 * W1
        S[16 + 3 * r] = a2 * W0 - a0 * W2
        S[17 + 3 * r] = a0 * W1 - a1 * W0


# --------------------------------------------------------------------------------------------
# Energy-momentum midpoint scheme in director form
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def _solve_dense(A, n):
    """Gaussian elimination with partial pivoting on the augmented n x (n+1) matrix A, in
    place; the solution is left in A[:, n]. Returns False if a pivot is zero."""
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                p = i
        if not big > 0.0:
            return False
        if p != k:
            for j in range(k, n + 1):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
        rp = 1.0 / A[k, k]
        for i in range(k + 1, n):
            f = A[i, k] * rp
            if f != 0.0:
                for j in range(k + 1, n + 1):
                    A[i, j] -= f * A[k, j]
    for k in range(n - 1, -1, -1):
        acc = A[k, n]
        for j in range(k + 1, n):
            acc -= A[k, j] * A[j, n]
        A[k, n] = acc / A[k, k]
    return True


# (k, l) pairs of the six symmetric multipliers / constraints
_PK = (0, 1, 2, 0, 0, 1)
_PL = (0, 1, 2, 1, 2, 2)


@njit(cache=True)
def _em_step(P, g, S, h, A, M):
    """One energy-momentum midpoint step (Gonzalez 1996; Betsch & Steinmann 2001).

    Unknowns D1 = D_{n+1} (9) and mu = h^2/4 Lambda (6, symmetric):
        (D1 - D0 - h V0) Jbar + (D0 + D1) mu - h^2/2 F = 0     (momentum balance x h/2)
        d_k . d_l - delta_kl = 0 at D1                            (constraints, new point)
    then V1 = 2 (D1 - D0)/h - V0. F = -m g c^T is the exact (constant) director force of
    gravity for a pivoted body, zero for a free one. Newton on all 15 unknowns with the
    saddle-point matrix; M = Jbar (x) 1 is never inverted, so flat bodies are fine.
    Work arrays (no allocation per step): ``A`` (15, 16) for the Newton matrix, ``M``
    (10, 3, 3) for D0, V0, D1, mu, Jbar, F, R1, D0 + D1, D1 - D0 - h V0, R2.
    """
    # M[0] = D0, M[1] = V0, M[2] = D1, M[3] = mu, M[4] = Jbar, M[5] = F
    m = P[0]
    piv = P[31] != 0.0
    for r in range(3):
        for j in range(3):
            M[0, r, j] = S[6 + 3 * r + j]
            M[1, r, j] = S[15 + 3 * r + j]
            M[4, r, j] = P[1 + 3 * r + j]
            # constant director force of gravity (pivoted body): F[r, j] = -m g_r c_j
            M[5, r, j] = -m * g[r] * P[28 + j] if piv else 0.0
    for q in range(6):
        M[3, _PK[q], _PL[q]] = S[30 + q]
        M[3, _PL[q], _PK[q]] = S[30 + q]
    # predictor: D1 = D0 cay(h W), W = vee(skew(D0^T V0)); exact for a principal-axis spin
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for r in range(3):
        a0 += M[0, r, 2] * M[1, r, 1] - M[0, r, 1] * M[1, r, 2]
        a1 += M[0, r, 0] * M[1, r, 2] - M[0, r, 2] * M[1, r, 0]
        a2 += M[0, r, 1] * M[1, r, 0] - M[0, r, 0] * M[1, r, 1]
    a0 *= 0.5 * h
    a1 *= 0.5 * h
    a2 *= 0.5 * h
    f = 4.0 / (4.0 + a0 * a0 + a1 * a1 + a2 * a2)
    # cay(a) = 1 + f (hat(a) + hat(a)^2 / 2), hat(a)^2 = a a^T - |a|^2 1
    aa = a0 * a0 + a1 * a1 + a2 * a2
    C00 = 1.0 + 0.5 * f * (a0 * a0 - aa)
    C11 = 1.0 + 0.5 * f * (a1 * a1 - aa)
    C22 = 1.0 + 0.5 * f * (a2 * a2 - aa)
    C01 = f * (-a2 + 0.5 * a0 * a1)
    C10 = f * (a2 + 0.5 * a0 * a1)
    C02 = f * (a1 + 0.5 * a0 * a2)
    C20 = f * (-a1 + 0.5 * a0 * a2)
    C12 = f * (-a0 + 0.5 * a1 * a2)
    C21 = f * (a0 + 0.5 * a1 * a2)
    for r in range(3):
        x0 = M[0, r, 0]
        x1 = M[0, r, 1]
        x2 = M[0, r, 2]
        M[2, r, 0] = x0 * C00 + x1 * C10 + x2 * C20
        M[2, r, 1] = x0 * C01 + x1 * C11 + x2 * C21
        M[2, r, 2] = x0 * C02 + x1 * C12 + x2 * C22
    hF = 0.5 * h * h
    scale1 = 0.0
    fs = 0.0
    for i in range(3):
        scale1 = max(scale1, abs(M[4, i, 0]) + abs(M[4, i, 1]) + abs(M[4, i, 2]))
        for j in range(3):
            fs = max(fs, abs(hF * M[5, i, j]))
    converged = False
    for _ in range(MAXIT):
        # residuals R1 = (D1 - D0 - h V0) Jbar + (D0 + D1) mu - h^2/2 F, R2 = constraints
        for r in range(3):
            for j in range(3):
                M[8, r, j] = M[2, r, j] - M[0, r, j] - h * M[1, r, j]
                M[7, r, j] = M[0, r, j] + M[2, r, j]
        res1 = 0.0
        mus = 0.0
        for r in range(3):
            mus = max(mus, abs(M[3, r, 0]) + abs(M[3, r, 1]) + abs(M[3, r, 2]))
            for j in range(3):
                acc = -hF * M[5, r, j]
                for i in range(3):
                    acc += M[8, r, i] * M[4, i, j] + M[7, r, i] * M[3, i, j]
                M[6, r, j] = acc
                res1 = max(res1, abs(acc))
        tol1 = EM_TOL * (3.0 * scale1 + 2.0 * mus + fs)
        res2 = 0.0
        for q in range(6):
            k = _PK[q]
            ll = _PL[q]
            acc = M[2, 0, k] * M[2, 0, ll] + M[2, 1, k] * M[2, 1, ll] + M[2, 2, k] * M[2, 2, ll]
            if k == ll:
                acc = 0.5 * (acc - 1.0)
            M[9, q // 3, q % 3] = acc
            res2 = max(res2, abs(acc))
        if res1 <= tol1 and res2 <= EM_TOL:
            converged = True
            break
        # Newton matrix; unknown index 3 j + r for D1[r, j], 9 + q for mu_q
        for i in range(15):
            for j in range(16):
                A[i, j] = 0.0
        for j in range(3):
            for r in range(3):
                row = 3 * j + r
                for i in range(3):
                    A[row, 3 * i + r] = M[4, i, j] + M[3, i, j]
                A[row, 15] = M[6, r, j]
            for q in range(6):
                k = _PK[q]
                ll = _PL[q]
                if ll == j:
                    for r in range(3):
                        A[3 * j + r, 9 + q] += M[7, r, k]
                if k == j and k != ll:
                    for r in range(3):
                        A[3 * j + r, 9 + q] += M[7, r, ll]
        for q in range(6):
            k = _PK[q]
            ll = _PL[q]
            row = 9 + q
            if k == ll:
                for r in range(3):
                    A[row, 3 * k + r] = M[2, r, k]
            else:
                for r in range(3):
                    A[row, 3 * k + r] = M[2, r, ll]
                    A[row, 3 * ll + r] = M[2, r, k]
            A[row, 15] = M[9, q // 3, q % 3]
        if not _solve_dense(A, 15):
            return FAIL_SINGULAR
        dmax = 0.0
        for j in range(3):
            for r in range(3):
                d = A[3 * j + r, 15]
                M[2, r, j] -= d
                dmax = max(dmax, abs(d))
        for q in range(6):
            d = A[9 + q, 15]
            M[3, _PK[q], _PL[q]] -= d
            if _PK[q] != _PL[q]:
                M[3, _PL[q], _PK[q]] -= d
        if not dmax < math.inf:
            return FAIL_NONFINITE
        if dmax <= 2.0 * EPS:
            # corrections below the ulp of the O(1) director entries: round-off reached
            converged = True
            break
    if not converged:
        return FAIL_NEWTON
    # branch rule: refuse a step rotating by 90 degrees or more (tr(D0^T D1) <= 1)
    tr = 0.0
    for r in range(3):
        for j in range(3):
            tr += M[0, r, j] * M[2, r, j]
    if not tr > 1.0:
        return FAIL_BRANCH
    r2h = 2.0 / h
    for r in range(3):
        for j in range(3):
            S[6 + 3 * r + j] = M[2, r, j]
            S[15 + 3 * r + j] = r2h * (M[2, r, j] - M[0, r, j]) - M[1, r, j]
    for q in range(6):
        S[30 + q] = M[3, _PK[q], _PL[q]]
    if not piv:
        hh = 0.5 * h
        for k in range(3):
            S[k] += h * S[3 + k] + h * hh * g[k]
            S[3 + k] += h * g[k]
    return OK


# --------------------------------------------------------------------------------------------
# RATTLE over a block of bodies: one SIMD lane per body
# --------------------------------------------------------------------------------------------
#: Bodies per block of the batched RATTLE loop. A compile-time constant on purpose: the rows
#: of the block array are then a constant distance apart, which lets LLVM prove that the lane
#: loop of _rattle_block_substep has no loop-carried dependence and vectorise it (AVX2: four
#: bodies per instruction). 32 was the fastest of 8, 16, 32 and 64 on a 2-core AMD EPYC
#: (batched free bodies, dt = 1e-3).
BLOCK = 32
#: Rows of the block array (row-major, BLOCK lanes per row): the state rows 0..NS-1 as in S,
#: the parameter rows NS..NS+NP-1 as in P, a live flag (0 once a body has failed) and an
#: accepted flag written by each vector substep.
ROW_P = NS
ROW_LIVE = NS + NP
ROW_ACC = NS + NP + 1
NROW = NS + NP + 2


@njit(cache=True, error_model="numpy")
def _rattle_block_substep(B, g0, g1, g2, h, nl):
    """One RATTLE substep of size h for lanes 0..nl-1 of the block array B, in place.

    :func:`_rattle_substep` for the outcome :func:`_dmv_diag_fast` covers, with its tests
    turned into a per-lane flag: the lane loop has no branch and LLVM vectorises it. It calls
    the same inlined functions as the scalar step, and no ``fastmath`` is used, so vector and
    scalar IEEE operations round alike (no contraction into FMA, no reassociation) and an
    accepted lane gets the scalar bits. ``error_model="numpy"``: a division by zero gives inf
    instead of a Python exception, which would be a branch that stops vectorisation.

    A lane is accepted (B[ROW_ACC] = 1, state updated) only if it is live, its Ibar is
    diagonal and every test of the scalar step came out the way the straight-line code
    assumes. Otherwise its state is left untouched (B[ROW_ACC] = 0) and the caller runs the
    scalar :func:`_rattle_substep` on it, which gives the scalar result, failures included.
    """
    hh = 0.5 * h
    for l in range(nl):
        piv = B[(ROW_P + 31) * BLOCK + l] != 0.0
        X0 = B[0 * BLOCK + l]
        X1 = B[1 * BLOCK + l]
        X2 = B[2 * BLOCK + l]
        U0 = B[3 * BLOCK + l]
        U1 = B[4 * BLOCK + l]
        U2 = B[5 * BLOCK + l]
        D00 = B[6 * BLOCK + l]
        D01 = B[7 * BLOCK + l]
        D02 = B[8 * BLOCK + l]
        D10 = B[9 * BLOCK + l]
        D11 = B[10 * BLOCK + l]
        D12 = B[11 * BLOCK + l]
        D20 = B[12 * BLOCK + l]
        D21 = B[13 * BLOCK + l]
        D22 = B[14 * BLOCK + l]
        Pi0 = B[24 * BLOCK + l]
        Pi1 = B[25 * BLOCK + l]
        Pi2 = B[26 * BLOCK + l]
        T0 = B[27 * BLOCK + l]
        T1 = B[28 * BLOCK + l]
        T2 = B[29 * BLOCK + l]
        p0 = Pi0 + hh * T0
        p1 = Pi1 + hh * T1
        p2 = Pi2 + hh * T2
        ok, w0, w1, w2, c0, c1, c2, q = _dmv_diag_fast(
            B[(ROW_P + 10) * BLOCK + l], B[(ROW_P + 14) * BLOCK + l],
            B[(ROW_P + 18) * BLOCK + l], B[(ROW_P + 19) * BLOCK + l],
            B[(ROW_P + 23) * BLOCK + l], B[(ROW_P + 27) * BLOCK + l],
            hh * p0, hh * p1, hh * p2,
        )  # fmt: skip
        ok = (
            ok
            & (B[ROW_LIVE * BLOCK + l] != 0.0)
            & (B[(ROW_P + 32) * BLOCK + l] != 0.0)
            & ((w0 * w0 + w1 * w1 + w2 * w2) < 1.0)
        )
        n00, n01, n02, n10, n11, n12, n20, n21, n22 = _cayley_increment(
            w0, w1, w2, D00, D01, D02, D10, D11, D12, D20, D21, D22
        )
        N0, N1, N2 = _torque(
            piv, B[ROW_P * BLOCK + l], B[(ROW_P + 28) * BLOCK + l],
            B[(ROW_P + 29) * BLOCK + l], B[(ROW_P + 30) * BLOCK + l], g0, g1, g2,
            n00, n01, n02, n10, n11, n12, n20, n21, n22,
        )  # fmt: skip
        r = 4.0 / (q * h)
        Pn0 = p0 - r * c0 + hh * N0
        Pn1 = p1 - r * c1 + hh * N1
        Pn2 = p2 - r * c2 + hh * N2
        ok = ok & ((abs(Pn0) + abs(Pn1) + abs(Pn2)) < math.inf)
        free = ok & (not piv)
        B[0 * BLOCK + l] = X0 + (h * U0 + h * hh * g0) if free else X0
        B[1 * BLOCK + l] = X1 + (h * U1 + h * hh * g1) if free else X1
        B[2 * BLOCK + l] = X2 + (h * U2 + h * hh * g2) if free else X2
        B[3 * BLOCK + l] = U0 + h * g0 if free else U0
        B[4 * BLOCK + l] = U1 + h * g1 if free else U1
        B[5 * BLOCK + l] = U2 + h * g2 if free else U2
        B[6 * BLOCK + l] = n00 if ok else D00
        B[7 * BLOCK + l] = n01 if ok else D01
        B[8 * BLOCK + l] = n02 if ok else D02
        B[9 * BLOCK + l] = n10 if ok else D10
        B[10 * BLOCK + l] = n11 if ok else D11
        B[11 * BLOCK + l] = n12 if ok else D12
        B[12 * BLOCK + l] = n20 if ok else D20
        B[13 * BLOCK + l] = n21 if ok else D21
        B[14 * BLOCK + l] = n22 if ok else D22
        B[24 * BLOCK + l] = Pn0 if ok else Pi0
        B[25 * BLOCK + l] = Pn1 if ok else Pi1
        B[26 * BLOCK + l] = Pn2 if ok else Pi2
        B[27 * BLOCK + l] = N0 if ok else T0
        B[28 * BLOCK + l] = N1 if ok else T1
        B[29 * BLOCK + l] = N2 if ok else T2
        B[ROW_ACC * BLOCK + l] = 1.0 if ok else 0.0


@njit(cache=True)
def _lane_get(B, l, S):
    for j in range(NS):
        S[j] = B[j * BLOCK + l]


@njit(cache=True)
def _lane_put(B, l, S):
    for j in range(NS):
        B[j * BLOCK + l] = S[j]


@njit(cache=True)
def _run_rattle_block(
    coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info, vec, i0, nl
):
    """``run_one`` of the RATTLE family for bodies i0 .. i0+nl-1 (nl <= BLOCK) together:
    each substep runs :func:`_rattle_block_substep` over the block, then the scalar
    :func:`_rattle_substep` on the lanes it did not accept. Every body gets the numbers
    ``run_one`` gives it, bit for bit, including a failure's status and info; a failed body
    stops (its lane is no longer live) and the others go on. vec[i] counts the substeps of
    body i taken by the vector code."""
    B = np.zeros(NROW * BLOCK)
    S = np.empty(NS)
    nsave = saves.shape[0]
    store0 = nsave > 0 and saves[0] == 0
    for l in range(nl):
        i = i0 + l
        S[:] = S0[i]
        _rattle_init(P[i], g, S)
        if store0:
            _store(RATTLE_FAMILY, P[i], S, 0, X[i], V[i], Dout[i], Dpout[i])
        _lane_put(B, l, S)
        for j in range(NP):
            B[(ROW_P + j) * BLOCK + l] = P[i, j]
        B[ROW_LIVE * BLOCK + l] = 1.0
    k = 1 if store0 else 0
    g0 = g[0]
    g1 = g[1]
    g2 = g[2]
    ncoef = coef.shape[0]
    for n in range(1, nstep + 1):
        for c in range(ncoef):
            hc = coef[c] * h
            _rattle_block_substep(B, g0, g1, g2, hc, nl)
            for l in range(nl):
                if B[ROW_LIVE * BLOCK + l] == 0.0:
                    continue
                i = i0 + l
                if B[ROW_ACC * BLOCK + l] != 0.0:
                    vec[i] += 1
                    continue
                _lane_get(B, l, S)
                st = _rattle_substep(P[i], g, S, hc)
                _lane_put(B, l, S)
                if st != OK:
                    status[i] = st
                    info[i, 0] = n - 1
                    info[i, 1] = _omega_norm(RATTLE_FAMILY, P[i], S)
                    info[i, 2] = _alpha_norm(RATTLE_FAMILY, P[i], S)
                    B[ROW_LIVE * BLOCK + l] = 0.0
        if k < nsave and saves[k] == n:
            for l in range(nl):
                if B[ROW_LIVE * BLOCK + l] != 0.0:
                    i = i0 + l
                    _lane_get(B, l, S)
                    _store(RATTLE_FAMILY, P[i], S, k, X[i], V[i], Dout[i], Dpout[i])
                    _lane_put(B, l, S)
            k += 1


# --------------------------------------------------------------------------------------------
# Time loops
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def _store(method, P, S, k, X, V, Dout, Dpout):
    if method == RATTLE_FAMILY:
        _rattle_director_velocity(P, S)
    piv = P[31] != 0.0
    for r in range(3):
        for j in range(3):
            Dout[k, r, j] = S[6 + 3 * r + j]
            Dpout[k, r, j] = S[15 + 3 * r + j]
    for r in range(3):
        if piv:
            # x_G = -D c, v_G = -D' c
            X[k, r] = -(S[6 + 3 * r] * P[28] + S[7 + 3 * r] * P[29] + S[8 + 3 * r] * P[30])
            V[k, r] = -(S[15 + 3 * r] * P[28] + S[16 + 3 * r] * P[29] + S[17 + 3 * r] * P[30])
        else:
            X[k, r] = S[r]
            V[k, r] = S[3 + r]


@njit(cache=True)
def _norm3(a, b, c):
    """|(a, b, c)| without overflow for huge components."""
    m = max(abs(a), abs(b), abs(c))
    if m == 0.0 or not m < math.inf:
        return m
    a /= m
    b /= m
    c /= m
    return m * math.sqrt(a * a + b * b + c * c)


@njit(cache=True)
def _omega_norm(method, P, S):
    if method == RATTLE_FAMILY:
        W0 = P[19] * S[24] + P[20] * S[25] + P[21] * S[26]
        W1 = P[22] * S[24] + P[23] * S[25] + P[24] * S[26]
        W2 = P[25] * S[24] + P[26] * S[25] + P[27] * S[26]
        return _norm3(W0, W1, W2)
    # |W| = |vee(skew(D^T D'))|
    w = np.zeros(3)
    for r in range(3):
        w[0] += 0.5 * (S[6 + 3 * r + 2] * S[15 + 3 * r + 1] - S[6 + 3 * r + 1] * S[15 + 3 * r + 2])
        w[1] += 0.5 * (S[6 + 3 * r + 0] * S[15 + 3 * r + 2] - S[6 + 3 * r + 2] * S[15 + 3 * r + 0])
        w[2] += 0.5 * (S[6 + 3 * r + 1] * S[15 + 3 * r + 0] - S[6 + 3 * r + 0] * S[15 + 3 * r + 1])
    return _norm3(w[0], w[1], w[2])


@njit(cache=True)
def _alpha_norm(method, P, S):
    """|Ibar^{-1} tau|, the angular acceleration of gravity at the state (RATTLE family;
    0 for energy-momentum, whose limit estimate ignores it)."""
    if method != RATTLE_FAMILY:
        return 0.0
    a0 = P[19] * S[27] + P[20] * S[28] + P[21] * S[29]
    a1 = P[22] * S[27] + P[23] * S[28] + P[24] * S[29]
    a2 = P[25] * S[27] + P[26] * S[28] + P[27] * S[29]
    return _norm3(a0, a1, a2)


@njit(cache=True)
def run_one(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, info):
    """Integrate one body for ``nstep`` steps of size ``h`` and store the states at the step
    indices ``saves`` (increasing, first 0 if the initial state is saved) into X, V
    (nsave, 3) and Dout, Dpout (nsave, 3, 3). ``coef`` are the composition coefficients of
    the RATTLE family (one RATTLE step of size coef[k] h each). Returns a status code; on
    failure info[0] = number of steps completed, info[1] = |W| and info[2] = |Ibar^{-1} tau|
    at the failing state."""
    S = S0.copy()
    A = np.empty((15, 16))
    M = np.empty((10, 3, 3))
    if method == RATTLE_FAMILY:
        _rattle_init(P, g, S)
    k = 0
    nsave = saves.shape[0]
    if nsave > 0 and saves[0] == 0:
        _store(method, P, S, 0, X, V, Dout, Dpout)
        k = 1
    ncoef = coef.shape[0]
    for n in range(1, nstep + 1):
        st = OK
        if method == RATTLE_FAMILY:
            for c in range(ncoef):
                st = _rattle_substep(P, g, S, coef[c] * h)
                if st != OK:
                    break
        else:
            st = _em_step(P, g, S, h, A, M)
        if st != OK:
            info[0] = n - 1
            info[1] = _omega_norm(method, P, S)
            info[2] = _alpha_norm(method, P, S)
            return st
        if k < nsave and saves[k] == n:
            _store(method, P, S, k, X, V, Dout, Dpout)
            k += 1
    return OK


def block_count(n: int, nthread: int) -> int:
    """Blocks for n bodies: of at most BLOCK bodies each, and at least one per thread while
    bodies last (so that a small batch still uses every thread)."""
    return max((n + BLOCK - 1) // BLOCK, min(n, nthread))


@njit(cache=True)
def _block_bounds(n, nblock, b):
    """Bodies [lo, hi) of block b when n bodies are cut into nblock near-equal blocks."""
    return (b * n) // nblock, ((b + 1) * n) // nblock


@njit(cache=True)
def _run_body_range(
    method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info, vec, lo, hi
):
    any_diag = False
    for i in range(lo, hi):
        any_diag = any_diag or P[i, 32] != 0.0
    if method == RATTLE_FAMILY and any_diag:
        _run_rattle_block(coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info, vec,
                          lo, hi - lo)  # fmt: skip
    else:
        # energy-momentum, or no body with a diagonal Ibar (the vector code would reject
        # every lane): the scalar loop body by body
        for i in range(lo, hi):
            status[i] = run_one(method, coef, P[i], g, S0[i], h, nstep, saves, X[i], V[i],
                                Dout[i], Dpout[i], info[i])  # fmt: skip


@njit(cache=True, parallel=True)
def run_batch_parallel(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info,
                       vec, nblock):  # fmt: skip
    """Integrate each body i (leading axis of P, S0, X, V, Dout, Dpout, status, info, vec) as
    ``run_one`` does, blocks of bodies distributed over threads with prange. The RATTLE
    family runs a block of up to BLOCK bodies through the vector substep
    (:func:`_run_rattle_block`), energy-momentum one body after another. vec[i] (zeroed by the
    caller) counts the substeps of body i taken by the vector code. The bodies are cut into
    ``nblock`` near-equal blocks (see :func:`block_count`)."""
    n = P.shape[0]
    for b in prange(nblock):
        lo, hi = _block_bounds(n, nblock, b)
        _run_body_range(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info,
                        vec, lo, hi)  # fmt: skip


@njit(cache=True)
def run_batch_serial(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info,
                     vec, nblock):  # fmt: skip
    """Same as ``run_batch_parallel`` on one thread."""
    n = P.shape[0]
    for b in range(nblock):
        lo, hi = _block_bounds(n, nblock, b)
        _run_body_range(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info,
                        vec, lo, hi)  # fmt: skip
