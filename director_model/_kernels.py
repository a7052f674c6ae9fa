"""Compiled kernels: the step functions of every scheme and the time loops.

The primitives shared with the system and contact kernels (the compensated sum, the
attitude quaternion, the DMV residual and solve) are in :mod:`director_model._primitives`;
numba keys the on-disk cache (``cache=True``) of a function on its own file only, so the
caches of this module are tied to the primitives' file as well (:func:`director_model._cache.tie`,
at the end of this module): an edit there recompiles these kernels.

Debugging: run with the environment variable ``NUMBA_DISABLE_JIT=1`` to execute these same
functions as plain Python (``prange`` becomes ``range``); the numbers are the same (a test
compares short RATTLE and energy-momentum runs), only about 1e3 times slower.

Data layout (float64 arrays, so one compiled signature serves every body):

``P`` body parameters, length ``NP``:
    P[0] = m; P[1:10] = Jbar (row-major); P[10:19] = Ibar; P[19:28] = Ibar^{-1};
    P[28:31] = c (pivot in body axes rel. to the COM, zeros if none); P[31] = 1.0 if pivoted;
    P[32] = 1.0 if Ibar is diagonal (selects the cheaper solver; same equations);
    P[33:36] = (e_0/I_0, e_1/I_1, e_2/I_2) with e = (I_2 - I_1, I_0 - I_2, I_1 - I_0) for a
    diagonal Ibar = diag(I) (so that w x Ibar w = e * (w_1 w_2, w_2 w_0, w_0 w_1)), zeros
    otherwise. Ibar^{-1} is the inverse of the positive definite inertia (never of the
    singular director mass matrix): it maps body momentum to body angular velocity.
``S`` state, length ``NS``:
    S[0:3] x_G; S[3:6] v_G; S[6:15] D (row-major: D[r, i] = S[6 + 3 r + i], column i is the
    director d_i); S[15:24] D' (same layout).
    Energy-momentum: D and D' are the state; S[30:36] scaled multipliers mu = h^2/4 Lambda
    (warm start; order 11, 22, 33, 12, 13, 23).
    RATTLE family: S[6:15] holds D_0, the directors at the start of the run, and the
    directors after n steps are D_n = D_0 Q_1 ... Q_n = D_0 R(p_n), with p_n the product of
    the quaternions (1, w_k) of the rotations Q_k (Gibbs vectors w_k), unnormalised, in
    S[36:40] (scalar first); D_n is formed where it is needed (saved states; the torque of a
    pivoted body uses D_n^T g = R(p_n)^T D_0^T g). S[15:24] is only a scratch for D' at the
    start. S[24:27] Pi = Ibar W; S[27:30] the body torque of gravity (cached between
    steps); S[30:33] D_0^T g. S[40:44] and S[44:47] are the compensations of p and Pi: the
    rounding error of the last sum into each entry (Kahan's compensated summation, see
    :func:`kahan`); the value of an entry is S[k] + its compensation, S[k] being that
    value rounded to double. Zero at the start of a run.
    A free centre of mass is never stepped: every scheme integrates free flight exactly
    (RATTLE and the energy-momentum midpoint rule both give x += h v + h^2/2 g, v += h g,
    and a composition of exact flows is exact), so S[0:6] keeps x_G, v_G of the start and
    the saved states get x_G(t) = x_G + v_G t + g t^2/2, v_G(t) = v_G + g t at the absolute
    time t (:func:`_store_com`), with no round-off accumulating over steps.

The batched RATTLE loop keeps a block of up to BLOCK bodies in one flat array, row-major with
BLOCK lanes per row (the rows of S, then those of P, then work rows; see ``ROW_P``), so that
its lane loops vectorise.

The kernels never raise: they return the status codes below, and the Python layer turns a
failure into StepSizeError with the time reached and a step-size estimate.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, njit, prange

from director_model import _cache
from director_model._primitives import (
    EPS,
    FAIL_BRANCH,
    FAIL_NEWTON,
    FAIL_NONFINITE,
    FP_SMAX,
    MAXIT,
    OK,
    cramer3,
    diag_finish,
    dmv_residual,
    dmv_solve_diag,
    fp_count,
    fp_step,
    kahan,
    kahan4,
    quat_increment,
    quat_matrix,
    stagnated,
)

NP = 36
NS = 47
#: RATTLE family: the attitude quaternion p (S[36:40]), its compensation (S[40:44]) and the
#: compensation of Pi (S[44:47])
QP = 36
LO_Q = 40
LO_PI = 44
#: the attitude quaternion is rescaled by QUAT_SHRINK (exactly) when |p|^2 exceeds QUAT_BIG,
#: checked every RESCALE_EVERY steps: |p|^2 grows by less than 2 per step, so it stays below
#: 2^(128 + 64), far from overflow
QUAT_BIG = 2.0**128
QUAT_SHRINK = 2.0**-64
RESCALE_EVERY = 64

#: method codes
RATTLE_FAMILY = 0
ENERGY_MOMENTUM = 1

#: status codes: OK, FAIL_NEWTON, FAIL_BRANCH and FAIL_NONFINITE those of the DMV solve
#: (director_model._primitives), and
FAIL_SINGULAR = 3  # singular saddle-point matrix (energy-momentum Newton)

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

#: Energy-momentum residual tolerance, relative to the magnitude of the terms (9x9 products
#: with up to 6 terms each: rounding of order 10 ulps).
EM_TOL = 16.0 * EPS


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
        G0, G1, G2, conv, finite = dmv_residual(b0, b1, b2, w0, w1, w2, u0, u1, u2)
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
        det, d0, d1, d2 = cramer3(K00, K01, K02, K10, K11, K12, K20, K21, K22, G0, G1, G2)
        if not det > 0.0:
            # the branch through Q = 1 has det > 0 up to its first fold; det <= 0 means the
            # step is past the solvability limit or Newton is heading to another branch
            return FAIL_BRANCH, w0, w1, w2, 0.0, 0.0, 0.0, 1.0
        w0 -= d0
        w1 -= d1
        w2 -= d2
        if stagnated(d0, d1, d2, w0, w1, w2):
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


@njit(cache=True)
def _dmv_solve_diag(P, b0, b1, b2):
    """The Newton-loop DMV solve for a diagonal Ibar
    (:func:`director_model._primitives.dmv_solve_diag`) with the moments of P. Called when
    the straight-line solve of :func:`_rattle_substep` did not finish (a large step, a
    failure)."""
    return dmv_solve_diag(P[10], P[14], P[18], P[19], P[23], P[27], b0, b1, b2)


@njit(inline="always")
def _torque(piv, m, c, gb):
    """Body torque of gravity about the pivot, tau = m gb x c with gb = D^T g the gravity in
    body axes (zero for a free body); c, gb 3-tuples. Returns a 3-tuple.

    From V = -m g . x_G with x_G = -D c: the director forces are f_i = -dV/dd_i = -m c_i g and
    tau = vee(D^T F - F^T D) = -m c x (D^T g) (numerics.md section 2). Zero for a free body
    (gravity acts at the centre of mass)."""
    t0 = m * (gb[1] * c[2] - gb[2] * c[1]) if piv else 0.0
    t1 = m * (gb[2] * c[0] - gb[0] * c[2]) if piv else 0.0
    t2 = m * (gb[0] * c[1] - gb[1] * c[0]) if piv else 0.0
    return (t0, t1, t2)


@njit(inline="always")
def _quat_rotate_back(p, x):
    """R(p/|p|)^T x for a quaternion p (any norm > 0) and a 3-tuple x:
    ((p0^2 - |v|^2) x + 2 (v . x) v - 2 p0 v x x) / |p|^2."""
    v0 = p[1]
    v1 = p[2]
    v2 = p[3]
    vv = (v0 * v0 + v1 * v1) + v2 * v2
    r = 1.0 / (p[0] * p[0] + vv)
    s = p[0] * p[0] - vv
    vx = 2.0 * ((v0 * x[0] + v1 * x[1]) + v2 * x[2])
    c0 = v1 * x[2] - v2 * x[1]
    c1 = v2 * x[0] - v0 * x[2]
    c2 = v0 * x[1] - v1 * x[0]
    t = 2.0 * p[0]
    return (
        ((s * x[0] + vx * v0) - t * c0) * r,
        ((s * x[1] + vx * v1) - t * c1) * r,
        ((s * x[2] + vx * v2) - t * c2) * r,
    )


@njit(inline="always")
def _directors(S):
    """D = D_0 R(p/|p|) of a RATTLE state: D_0 in S[6:15], p in S[36:40]. A 9-tuple."""
    R = quat_matrix((S[QP], S[QP + 1], S[QP + 2], S[QP + 3]))
    return (
        (S[6] * R[0] + S[7] * R[3]) + S[8] * R[6],
        (S[6] * R[1] + S[7] * R[4]) + S[8] * R[7],
        (S[6] * R[2] + S[7] * R[5]) + S[8] * R[8],
        (S[9] * R[0] + S[10] * R[3]) + S[11] * R[6],
        (S[9] * R[1] + S[10] * R[4]) + S[11] * R[7],
        (S[9] * R[2] + S[10] * R[5]) + S[11] * R[8],
        (S[12] * R[0] + S[13] * R[3]) + S[14] * R[6],
        (S[12] * R[1] + S[13] * R[4]) + S[14] * R[7],
        (S[12] * R[2] + S[13] * R[5]) + S[14] * R[8],
    )


@njit(inline="always")
def _kahan3(hi, lo, d, comp):
    """:func:`kahan` on 3-tuples; returns (new values, new compensations)."""
    t0, e0 = kahan(hi[0], lo[0], d[0], comp)
    t1, e1 = kahan(hi[1], lo[1], d[1], comp)
    t2, e2 = kahan(hi[2], lo[2], d[2], comp)
    return (t0, t1, t2), (e0, e1, e2)


@njit(inline="always")
def _quat_rescale(p, pl):
    """Multiply p and its compensation by 2^-64 if |p|^2 > 2^128: exact (a power of two),
    so the rotation and the compensated value are unchanged; |p|^2 grows by the factor
    1 + |w|^2 < 2 per step and would otherwise overflow after very many steps."""
    big = ((p[0] * p[0] + p[1] * p[1]) + (p[2] * p[2] + p[3] * p[3])) > QUAT_BIG
    f = QUAT_SHRINK if big else 1.0
    return (p[0] * f, p[1] * f, p[2] * f, p[3] * f), (pl[0] * f, pl[1] * f, pl[2] * f, pl[3] * f)


@njit(cache=True)
def _rattle_init(P, g, S):
    """From a new director state (D = D_0 in S[6:15], D' in S[15:24]) set Pi = Ibar
    vee(skew(D^T D')), p = (1, 0, 0, 0), the gravity in body axes D_0^T g (S[30:33]) and
    the torque."""
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
    S[QP] = 1.0
    for j in range(1, 4):
        S[QP + j] = 0.0
    for j in range(4):
        S[LO_Q + j] = 0.0
    for j in range(3):
        S[LO_PI + j] = 0.0
        S[30 + j] = (S[6 + j] * g[0] + S[9 + j] * g[1]) + S[12 + j] * g[2]
    t = _torque(P[31] != 0.0, P[0], (P[28], P[29], P[30]), (S[30], S[31], S[32]))
    S[27] = t[0]
    S[28] = t[1]
    S[29] = t[2]


# One RATTLE step of size h (h may be negative inside a composition, never 0), in two pieces
# that take and return numbers and tuples of numbers only (array arguments of inlined
# functions would cost numba reference-count calls, atomic operations, in the hot loop):
#
#   _rattle_solve:  pi = Pi_n + h/2 tau_n, b = h pi/2; the Gibbs vector w of
#                   Q = D_n^T D_{n+1} from Q Jbar - Jbar Q^T = h hat(pi), by the
#                   straight-line solve when Ibar is diagonal (predictor, fp_count
#                   fixed-point corrections, diag_finish); otherwise, or if it does not
#                   finish, the caller runs _solve_loop.
#   _rattle_commit: D_{n+1} = D_n Q, kept as D_0 R(p) with p_{n+1} = p_n + p_n (x) (0, w);
#                   Pi_{n+1} = Q^T pi + h/2 tau_{n+1}, computed as
#                   Pi_n + (h/2 (tau_n + tau_{n+1}) - 4 c/(q h)) (Q^T pi = pi - 4 c/(q h), see
#                   _dmv_solve). Both sums are compensated (kahan) unless comp is False.
#                   (The centre of mass is not stepped: see _store_com.)
#
# The RATTLE state as tuples: p, pl (4: attitude quaternion and its compensation), Pi, Pl
# (momentum, compensation), T (torque), G (gravity in the axes of D_0) (3 each).
# The single-body loop (_rattle_loop), the array step (_rattle_substep) and the block step of
# the batched loop (_rattle_block_substep) all use these, so they compute the same numbers.
@njit(inline="always")
def _rattle_solve(diag, I0, I1, I2, a0, a1, a2, ae0, ae1, ae2, hh, Pi, T):
    """Returns (ok, b0, b1, b2, w0, w1, w2, c0, c1, c2, q): ok if the straight-line solve
    finished (then w, c = w x Ibar w and q = 1 + |w|^2 are the solution's), and b."""
    b0 = hh * (Pi[0] + hh * T[0])
    b1 = hh * (Pi[1] + hh * T[1])
    b2 = hh * (Pi[2] + hh * T[2])
    ok = False
    w0 = 0.0
    w1 = 0.0
    w2 = 0.0
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    q = 1.0
    if diag:
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
            ok, w0, w1, w2, c0, c1, c2, q = diag_finish(
                I0, I1, I2, a0, a1, a2, b0, b1, b2, w0, w1, w2
            )
    return ok, b0, b1, b2, w0, w1, w2, c0, c1, c2, q


@njit(cache=True)
def _solve_loop(P, b0, b1, b2):
    """The Newton-loop solvers (:func:`_dmv_solve_diag`, :func:`_dmv_solve`), for what the
    straight-line solve does not finish. Returns (status, w0, w1, w2, c0, c1, c2, q)."""
    if P[32] != 0.0:
        return _dmv_solve_diag(P, b0, b1, b2)
    return _dmv_solve(P, b0, b1, b2)


@njit(inline="always")
def _rattle_commit(comp, piv, m, pc, hh, rh, w, c, q, p, pl, Pi, Pl, T, G, vector, torque):
    """The new state from the solution (w, c, q) of a step of size h (hh = h/2, rh = 4/h);
    pc is the pivot, G the gravity in the axes of D_0 (3-tuples). Returns
    (finite, p, pl, Pi, Pl, T); finite is False if the new momentum is not finite.
    ``vector`` (a constant): called from the SIMD lane loop: the torque without a branch,
    zero for the free lanes (the same numbers as the scalar branch), and only if ``torque``
    (a constant: some lane of the block is pivoted)."""
    pn, pln = _commit_attitude(p, pl, w, comp)
    N = (0.0, 0.0, 0.0)
    if vector:
        if torque:
            N = _torque(piv, m, pc, _quat_rotate_back(pn, G))
    elif piv:
        # a branch in scalar code: a free body's momentum does not wait for the attitude
        N = _torque(True, m, pc, _quat_rotate_back(pn, G))
    finite, Pn, Pln = _commit_momentum(hh, rh, c, q, Pi, Pl, T, N, comp)
    return finite, pn, pln, Pn, Pln, N


@njit(inline="always")
def _commit_attitude(p, pl, w, comp):
    """p + p (x) (0, w), compensated: the attitude part of :func:`_rattle_commit`."""
    return kahan4(p, pl, quat_increment(p, w), comp)


@njit(inline="always")
def _commit_momentum(hh, rh, c, q, Pi, Pl, T, N, comp):
    """Pi + (h/2 (T + N) - 4 c/(q h)), compensated, with T and N the torques at the start
    and the end of the step: the momentum part of :func:`_rattle_commit`. Returns
    (finite, Pi, Pl)."""
    r = rh * (1.0 / q)
    dP = (
        hh * (T[0] + N[0]) - r * c[0],
        hh * (T[1] + N[1]) - r * c[1],
        hh * (T[2] + N[2]) - r * c[2],
    )
    Pn, Pln = _kahan3(Pi, Pl, dP, comp)
    return (abs(Pn[0]) + abs(Pn[1]) + abs(Pn[2])) < math.inf, Pn, Pln


@njit(cache=True)
def _get_state(S):
    """The RATTLE state tuples (p, pl, Pi, Pl, T, G) from S."""
    return (
        (S[QP], S[QP + 1], S[QP + 2], S[QP + 3]),
        (S[LO_Q], S[LO_Q + 1], S[LO_Q + 2], S[LO_Q + 3]),
        (S[24], S[25], S[26]),
        (S[LO_PI], S[LO_PI + 1], S[LO_PI + 2]),
        (S[27], S[28], S[29]),
        (S[30], S[31], S[32]),
    )


@njit(cache=True)
def _put_state(S, p, pl, Pi, Pl, T):
    """Write the RATTLE state tuples into S."""
    for j in range(4):
        S[QP + j] = p[j]
        S[LO_Q + j] = pl[j]
    for j in range(3):
        S[24 + j] = Pi[j]
        S[LO_PI + j] = Pl[j]
        S[27 + j] = T[j]


@njit(cache=True)
def _rattle_substep(P, S, hh, rh, comp):
    """One RATTLE step of size h (hh = h/2, rh = 4/h) on the array state S, written only if
    the step succeeds; returns a status code. The scalar fallback of the batched loop."""
    p, pl, Pi, Pl, T, G = _get_state(S)
    ok, b0, b1, b2, w0, w1, w2, c0, c1, c2, q = _rattle_solve(
        P[32] != 0.0, P[10], P[14], P[18], P[19], P[23], P[27], P[33], P[34], P[35], hh, Pi, T
    )
    if not ok:
        st, w0, w1, w2, c0, c1, c2, q = _solve_loop(P, b0, b1, b2)
        if st != OK:
            return st
    finite, p, pl, Pi, Pl, T = _rattle_commit(
        comp, P[31] != 0.0, P[0], (P[28], P[29], P[30]), hh, rh, (w0, w1, w2), (c0, c1, c2),
        q, p, pl, Pi, Pl, T, G, False, False,
    )  # fmt: skip
    if not finite:
        return FAIL_NONFINITE
    _put_state(S, p, pl, Pi, Pl, T)
    return OK


@njit(cache=True)
def _rescale_state(S):
    """:func:`_quat_rescale` on the quaternion in S."""
    p, pl = _quat_rescale(
        (S[QP], S[QP + 1], S[QP + 2], S[QP + 3]),
        (S[LO_Q], S[LO_Q + 1], S[LO_Q + 2], S[LO_Q + 3]),
    )
    for j in range(4):
        S[QP + j] = p[j]
        S[LO_Q + j] = pl[j]


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
    (10, 3, 3) for D0, V0, D1, mu, Jbar, F, R1, D0 + D1, D1 - D0 - h V0, R2. Not
    compensated: Newton solves for D1 itself, to a tolerance of 16 ulps, so there is no
    small increment to carry. (The centre of mass is not stepped: see _store_com.)
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
    return OK


# --------------------------------------------------------------------------------------------
# RATTLE over a block of bodies: one SIMD lane per body
# --------------------------------------------------------------------------------------------
#: Bodies per block of the batched RATTLE loop. A compile-time constant on purpose: the rows
#: of the block array are then a constant distance apart, which lets LLVM prove that the lane
#: loops of _rattle_block_substep have no loop-carried dependence and vectorise them (AVX2:
#: four bodies per instruction). 32 and 64 run equally fast on the project's 2-core AMD EPYC
#: (12.0-12.5 ns per free-body step on one thread, dt = 1e-3), 16 is 5-10 % slower; 32 keeps
#: the block array (NROW x 32 x 8 bytes = 24.3 kB) inside a 32 kB L1 data cache.
BLOCK = 32
#: Rows of the block array (row-major, BLOCK lanes per row): the state rows 0..NS-1 as in S,
#: the parameter rows ROW_P..ROW_P+NP-1 as in P, then work rows: b = h pi/2 (3 rows),
#: ab = Ibar^{-1} b (3), the iterate w (3), the number of fixed-point corrections of the
#: lane (0: not for the vector code), a live flag (0 once a body has failed) and an accepted
#: flag written by each vector substep.
ROW_P = NS
ROW_B = NS + NP
ROW_AB = ROW_B + 3
ROW_W = ROW_B + 6
ROW_K = ROW_B + 9
ROW_LIVE = ROW_B + 10
ROW_ACC = ROW_B + 11
NROW = ROW_B + 12


@njit(cache=True, error_model="numpy")
def _rattle_block_substep(B, hh, rh, nl, anypiv):
    """One RATTLE substep of size h (hh = h/2, rh = 4/h) for lanes 0..nl-1 of the block
    array B, in place; ``anypiv``: some lane is pivoted (else the torque, zero for every
    lane, is not computed). Returns the number of lanes not accepted.

    :func:`_rattle_substep` with its straight-line solve, cut into three passes over the
    lanes: the predictor, the fixed-point corrections (one pass each, as many as the lane
    that needs most; a lane stops at its own count), and the residual test, polish and
    compensated commit. Each pass is a loop without branches or loop-carried dependences,
    which LLVM vectorises; short passes let the out-of-order core overlap the dependency
    chains of many lanes, where one long pass would be latency-bound. The passes call the
    same inlined functions as the scalar step with the same expressions, and no
    ``fastmath`` is used, so vector and scalar IEEE operations round alike (no contraction
    into FMA, no reassociation) and an accepted lane gets the scalar bits.
    ``error_model="numpy"``: a division by zero gives inf instead of a Python exception,
    which would be a branch that stops vectorisation.

    A lane is accepted (B[ROW_ACC] = 1, state updated) only if it is live, its Ibar is
    diagonal, and the scalar step would take the straight-line path and succeed. Otherwise
    its state is left untouched (B[ROW_ACC] = 0) and the caller runs the scalar
    :func:`_rattle_substep` on it, which gives the scalar result, failures included.
    """
    # pass 1: predictor and the number of corrections per lane
    for l in range(nl):
        p0 = B[24 * BLOCK + l] + hh * B[27 * BLOCK + l]
        p1 = B[25 * BLOCK + l] + hh * B[28 * BLOCK + l]
        p2 = B[26 * BLOCK + l] + hh * B[29 * BLOCK + l]
        b0 = hh * p0
        b1 = hh * p1
        b2 = hh * p2
        ab0 = B[(ROW_P + 19) * BLOCK + l] * b0
        ab1 = B[(ROW_P + 23) * BLOCK + l] * b1
        ab2 = B[(ROW_P + 27) * BLOCK + l] * b2
        s = max(abs(ab0), abs(ab1), abs(ab2))
        cand = (
            (B[ROW_LIVE * BLOCK + l] != 0.0) & (B[(ROW_P + 32) * BLOCK + l] != 0.0) & (s <= FP_SMAX)
        )
        B[ROW_K * BLOCK + l] = fp_count(s) if cand else 0.0
        B[ROW_B * BLOCK + l] = b0
        B[(ROW_B + 1) * BLOCK + l] = b1
        B[(ROW_B + 2) * BLOCK + l] = b2
        B[ROW_AB * BLOCK + l] = ab0
        B[(ROW_AB + 1) * BLOCK + l] = ab1
        B[(ROW_AB + 2) * BLOCK + l] = ab2
        # the first correction here: every lane the vector code accepts takes at least 3
        w0, w1, w2 = fp_step(
            ab0, ab1, ab2, B[(ROW_P + 33) * BLOCK + l], B[(ROW_P + 34) * BLOCK + l],
            B[(ROW_P + 35) * BLOCK + l], ab0, ab1, ab2,
        )  # fmt: skip
        B[ROW_W * BLOCK + l] = w0
        B[(ROW_W + 1) * BLOCK + l] = w1
        B[(ROW_W + 2) * BLOCK + l] = w2
    # the largest count, and the smallest among the lanes the vector code may accept (the
    # others, count 0, are rejected in pass 3 whatever their w)
    kmin = math.inf
    kmax = 0.0
    for l in range(nl):
        k = B[ROW_K * BLOCK + l]
        kmax = max(kmax, k)
        if k > 0.0:
            kmin = min(kmin, k)
    kmin = min(kmin, kmax)
    # pass 2: the other fixed-point corrections, one per pass (two per pass measured
    # slower); lane l takes B[ROW_K, l] in all. Up to the smallest count every lane takes
    # the correction: no per-lane test, which would turn the loads into masked loads
    it = 1.0
    while it < kmin:
        for l in range(nl):
            w0, w1, w2 = fp_step(
                B[ROW_AB * BLOCK + l], B[(ROW_AB + 1) * BLOCK + l], B[(ROW_AB + 2) * BLOCK + l],
                B[(ROW_P + 33) * BLOCK + l], B[(ROW_P + 34) * BLOCK + l],
                B[(ROW_P + 35) * BLOCK + l], B[ROW_W * BLOCK + l], B[(ROW_W + 1) * BLOCK + l],
                B[(ROW_W + 2) * BLOCK + l],
            )  # fmt: skip
            B[ROW_W * BLOCK + l] = w0
            B[(ROW_W + 1) * BLOCK + l] = w1
            B[(ROW_W + 2) * BLOCK + l] = w2
        it += 1.0
    while it < kmax:
        for l in range(nl):
            w0 = B[ROW_W * BLOCK + l]
            w1 = B[(ROW_W + 1) * BLOCK + l]
            w2 = B[(ROW_W + 2) * BLOCK + l]
            n0, n1, n2 = fp_step(
                B[ROW_AB * BLOCK + l], B[(ROW_AB + 1) * BLOCK + l], B[(ROW_AB + 2) * BLOCK + l],
                B[(ROW_P + 33) * BLOCK + l], B[(ROW_P + 34) * BLOCK + l],
                B[(ROW_P + 35) * BLOCK + l], w0, w1, w2,
            )  # fmt: skip
            on = it < B[ROW_K * BLOCK + l]
            B[ROW_W * BLOCK + l] = n0 if on else w0
            B[(ROW_W + 1) * BLOCK + l] = n1 if on else w1
            B[(ROW_W + 2) * BLOCK + l] = n2 if on else w2
        it += 1.0
    # pass 3: residual test, polish, compensated commit; the torque only if needed
    if anypiv:
        return _block_finish(B, hh, rh, nl, True)
    return _block_finish(B, hh, rh, nl, False)


@njit(cache=True, error_model="numpy")
def _block_finish(B, hh, rh, nl, torque):
    """Pass 3 of :func:`_rattle_block_substep`: the residual test, the polish and the
    compensated commit for lanes 0..nl-1; ``torque``: some lane is pivoted, a literal
    (``numba.literally``), so the function is compiled once with and once without the
    torque. Returns the number of lanes not accepted. A called function, not an inlined
    one: numba would count references to the array argument of an inlined function at each
    call."""
    literally(torque)
    # 3a: residual, test and polish; w, c = w x Ibar w, q = 1 + |w|^2 and the outcome go to
    # the rows of w, ab and b (two short loops overlap across lanes better than one long one)
    for l in range(nl):
        ok, w0, w1, w2, c0, c1, c2, q = diag_finish(
            B[(ROW_P + 10) * BLOCK + l], B[(ROW_P + 14) * BLOCK + l],
            B[(ROW_P + 18) * BLOCK + l], B[(ROW_P + 19) * BLOCK + l],
            B[(ROW_P + 23) * BLOCK + l], B[(ROW_P + 27) * BLOCK + l],
            B[ROW_B * BLOCK + l], B[(ROW_B + 1) * BLOCK + l], B[(ROW_B + 2) * BLOCK + l],
            B[ROW_W * BLOCK + l], B[(ROW_W + 1) * BLOCK + l], B[(ROW_W + 2) * BLOCK + l],
        )  # fmt: skip
        B[ROW_W * BLOCK + l] = w0
        B[(ROW_W + 1) * BLOCK + l] = w1
        B[(ROW_W + 2) * BLOCK + l] = w2
        B[ROW_AB * BLOCK + l] = c0
        B[(ROW_AB + 1) * BLOCK + l] = c1
        B[(ROW_AB + 2) * BLOCK + l] = c2
        B[ROW_B * BLOCK + l] = q
        B[(ROW_B + 1) * BLOCK + l] = 1.0 if ok & (B[ROW_K * BLOCK + l] != 0.0) else 0.0
    # 3b: the compensated commit
    nrej = 0
    for l in range(nl):
        p = (B[QP * BLOCK + l], B[(QP + 1) * BLOCK + l], B[(QP + 2) * BLOCK + l],
             B[(QP + 3) * BLOCK + l])  # fmt: skip
        pl = (B[LO_Q * BLOCK + l], B[(LO_Q + 1) * BLOCK + l], B[(LO_Q + 2) * BLOCK + l],
              B[(LO_Q + 3) * BLOCK + l])  # fmt: skip
        Pi = (B[24 * BLOCK + l], B[25 * BLOCK + l], B[26 * BLOCK + l])
        Pl = (B[LO_PI * BLOCK + l], B[(LO_PI + 1) * BLOCK + l], B[(LO_PI + 2) * BLOCK + l])
        # without a pivoted lane every torque is zero, as stored: no torque rows to read
        T = (B[27 * BLOCK + l], B[28 * BLOCK + l], B[29 * BLOCK + l]) if torque else (0.0, 0.0, 0.0)
        finite, pn, pln, Pin, Pln, Tn = _rattle_commit(
            True, B[(ROW_P + 31) * BLOCK + l] != 0.0, B[ROW_P * BLOCK + l],
            (B[(ROW_P + 28) * BLOCK + l], B[(ROW_P + 29) * BLOCK + l],
             B[(ROW_P + 30) * BLOCK + l]),
            hh, rh,
            (B[ROW_W * BLOCK + l], B[(ROW_W + 1) * BLOCK + l], B[(ROW_W + 2) * BLOCK + l]),
            (B[ROW_AB * BLOCK + l], B[(ROW_AB + 1) * BLOCK + l], B[(ROW_AB + 2) * BLOCK + l]),
            B[ROW_B * BLOCK + l], p, pl, Pi, Pl, T,
            (B[30 * BLOCK + l], B[31 * BLOCK + l], B[32 * BLOCK + l]), True, torque,
        )  # fmt: skip
        ok = finite & (B[(ROW_B + 1) * BLOCK + l] != 0.0)
        # the new state where accepted
        B[QP * BLOCK + l] = pn[0] if ok else p[0]
        B[(QP + 1) * BLOCK + l] = pn[1] if ok else p[1]
        B[(QP + 2) * BLOCK + l] = pn[2] if ok else p[2]
        B[(QP + 3) * BLOCK + l] = pn[3] if ok else p[3]
        B[LO_Q * BLOCK + l] = pln[0] if ok else pl[0]
        B[(LO_Q + 1) * BLOCK + l] = pln[1] if ok else pl[1]
        B[(LO_Q + 2) * BLOCK + l] = pln[2] if ok else pl[2]
        B[(LO_Q + 3) * BLOCK + l] = pln[3] if ok else pl[3]
        B[24 * BLOCK + l] = Pin[0] if ok else Pi[0]
        B[25 * BLOCK + l] = Pin[1] if ok else Pi[1]
        B[26 * BLOCK + l] = Pin[2] if ok else Pi[2]
        B[LO_PI * BLOCK + l] = Pln[0] if ok else Pl[0]
        B[(LO_PI + 1) * BLOCK + l] = Pln[1] if ok else Pl[1]
        B[(LO_PI + 2) * BLOCK + l] = Pln[2] if ok else Pl[2]
        if torque:
            B[27 * BLOCK + l] = Tn[0] if ok else T[0]
            B[28 * BLOCK + l] = Tn[1] if ok else T[1]
            B[29 * BLOCK + l] = Tn[2] if ok else T[2]
        B[ROW_ACC * BLOCK + l] = 1.0 if ok else 0.0
        nrej += 0 if ok else 1
    return nrej


@njit(cache=True, error_model="numpy")
def _rattle_block_rescale(B, nl):
    """:func:`_quat_rescale` for lanes 0..nl-1 (every RESCALE_EVERY steps, as the scalar
    loop does)."""
    for l in range(nl):
        p, pl = _quat_rescale(
            (B[QP * BLOCK + l], B[(QP + 1) * BLOCK + l], B[(QP + 2) * BLOCK + l],
             B[(QP + 3) * BLOCK + l]),
            (B[LO_Q * BLOCK + l], B[(LO_Q + 1) * BLOCK + l], B[(LO_Q + 2) * BLOCK + l],
             B[(LO_Q + 3) * BLOCK + l]),
        )  # fmt: skip
        B[QP * BLOCK + l] = p[0]
        B[(QP + 1) * BLOCK + l] = p[1]
        B[(QP + 2) * BLOCK + l] = p[2]
        B[(QP + 3) * BLOCK + l] = p[3]
        B[LO_Q * BLOCK + l] = pl[0]
        B[(LO_Q + 1) * BLOCK + l] = pl[1]
        B[(LO_Q + 2) * BLOCK + l] = pl[2]
        B[(LO_Q + 3) * BLOCK + l] = pl[3]


@njit(cache=True)
def _lane_get(B, l, S):
    for j in range(NS):
        S[j] = B[j * BLOCK + l]


@njit(cache=True)
def _lane_put(B, l, S):
    for j in range(NS):
        B[j * BLOCK + l] = S[j]


@njit(cache=True)
def _substep_sizes(coef, h):
    """The substep sizes coef[c] h of a composition step, their halves and 4/(coef[c] h),
    computed once per run (the same numbers for the scalar and the vector code)."""
    n = coef.shape[0]
    hs = np.empty(n)
    hhs = np.empty(n)
    rhs = np.empty(n)
    for c in range(n):
        hc = coef[c] * h
        hs[c] = hc
        hhs[c] = 0.5 * hc
        rhs[c] = 4.0 / hc
    return hs, hhs, rhs


@njit(cache=True)
def _run_rattle_block(
    coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info, vec, i0, nl
):
    """``run_one`` of the RATTLE family for bodies i0 .. i0+nl-1 (nl <= BLOCK) together:
    each substep runs :func:`_rattle_block_substep` over the block, then the scalar
    :func:`_rattle_substep` on the lanes it did not accept. Every body gets the numbers
    ``run_one`` gives it, bit for bit, including a failure's status and info; a failed body
    stops (its lane is no longer live) and the others go on. vec[i] counts the substeps of
    body i taken by the vector code: those it attempted less those the scalar code redid
    (counted here, not in the vector pass, which they would cost a load and a store)."""
    B = np.zeros(NROW * BLOCK)
    S = np.empty(NS)
    hs, hhs, rhs = _substep_sizes(coef, h)
    nsave = saves.shape[0]
    store0 = nsave > 0 and saves[0] == 0
    for l in range(nl):
        i = i0 + l
        S[:] = S0[i]
        _rattle_init(P[i], g, S)
        if store0:
            _store_rattle(P[i], S, g, 0.0, np.int64(0), X[i], V[i], Dout[i], Dpout[i])
        _lane_put(B, l, S)
        for j in range(NP):
            B[(ROW_P + j) * BLOCK + l] = P[i, j]
        B[ROW_LIVE * BLOCK + l] = 1.0
    k = 1 if store0 else 0
    anypiv = False
    for l in range(nl):
        anypiv = anypiv or P[i0 + l, 31] != 0.0
    ncoef = coef.shape[0]
    attempted = np.full(nl, nstep * ncoef)
    scalar = np.zeros(nl, dtype=np.int64)
    for n in range(1, nstep + 1):
        for c in range(ncoef):
            if _rattle_block_substep(B, hhs[c], rhs[c], nl, anypiv) == 0:
                continue
            for l in range(nl):
                if B[ROW_ACC * BLOCK + l] != 0.0 or B[ROW_LIVE * BLOCK + l] == 0.0:
                    continue
                i = i0 + l
                _lane_get(B, l, S)
                st = _rattle_substep(P[i], S, hhs[c], rhs[c], True)
                _lane_put(B, l, S)
                scalar[l] += 1
                if st != OK:
                    attempted[l] = (n - 1) * ncoef + c + 1
                    status[i] = st
                    info[i, 0] = n - 1
                    info[i, 1] = _omega_norm_rattle(P[i], S)
                    info[i, 2] = _alpha_norm_rattle(P[i], S)
                    B[ROW_LIVE * BLOCK + l] = 0.0
        if n % RESCALE_EVERY == 0:
            _rattle_block_rescale(B, nl)
        if k < nsave and saves[k] == n:
            for l in range(nl):
                if B[ROW_LIVE * BLOCK + l] != 0.0:
                    i = i0 + l
                    _lane_get(B, l, S)
                    _store_rattle(P[i], S, g, n * h, k, X[i], V[i], Dout[i], Dpout[i])
            k += 1
    for l in range(nl):
        vec[i0 + l] = attempted[l] - scalar[l]


# --------------------------------------------------------------------------------------------
# Time loops
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def _store_rattle(P, S, g, t, k, X, V, Dout, Dpout):
    """Saved state k at the absolute time t of a RATTLE-family state: D = D_0 R(p) and
    D' = D hat(W), W = Ibar^{-1} Pi; x_G, v_G as :func:`_store_com` gives them."""
    D = _directors(S)
    W0 = P[19] * S[24] + P[20] * S[25] + P[21] * S[26]
    W1 = P[22] * S[24] + P[23] * S[25] + P[24] * S[26]
    W2 = P[25] * S[24] + P[26] * S[25] + P[27] * S[26]
    for r in range(3):
        a0 = D[3 * r]
        a1 = D[3 * r + 1]
        a2 = D[3 * r + 2]
        Dout[k, r, 0] = a0
        Dout[k, r, 1] = a1
        Dout[k, r, 2] = a2
        # row r of D hat(W); hat(W) columns: (0, W2, -W1), (-W2, 0, W0), (W1, -W0, 0)
        Dpout[k, r, 0] = a1 * W2 - a2 * W1
        Dpout[k, r, 1] = a2 * W0 - a0 * W2
        Dpout[k, r, 2] = a0 * W1 - a1 * W0
    _store_com(P, S, g, t, k, X, V, Dout, Dpout)


@njit(cache=True)
def _store_em(P, S, g, t, k, X, V, Dout, Dpout):
    """Saved state k at the absolute time t of an energy-momentum state: D, D' from S;
    x_G, v_G as :func:`_store_com` gives them."""
    for r in range(3):
        for j in range(3):
            Dout[k, r, j] = S[6 + 3 * r + j]
            Dpout[k, r, j] = S[15 + 3 * r + j]
    _store_com(P, S, g, t, k, X, V, Dout, Dpout)


@njit(cache=True)
def _store_com(P, S, g, t, k, X, V, Dout, Dpout):
    """x_G, v_G of saved state k (D, D' already in Dout[k], Dpout[k]): a free centre of mass
    from its start state S[0:6] in closed form, x_G + v_G t + (t^2/2) g and v_G + g t at the
    absolute time t; with a pivot x_G = -D c, v_G = -D' c."""
    tt = 0.5 * t * t
    for r in range(3):
        if P[31] != 0.0:
            X[k, r] = -(Dout[k, r, 0] * P[28] + Dout[k, r, 1] * P[29] + Dout[k, r, 2] * P[30])
            V[k, r] = -(Dpout[k, r, 0] * P[28] + Dpout[k, r, 1] * P[29] + Dpout[k, r, 2] * P[30])
        else:
            X[k, r] = S[r] + (S[3 + r] * t + tt * g[r])
            V[k, r] = S[3 + r] + g[r] * t


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
def _omega_norm_rattle(P, S):
    """|W| = |Ibar^{-1} Pi| of a RATTLE-family state."""
    W0 = P[19] * S[24] + P[20] * S[25] + P[21] * S[26]
    W1 = P[22] * S[24] + P[23] * S[25] + P[24] * S[26]
    W2 = P[25] * S[24] + P[26] * S[25] + P[27] * S[26]
    return _norm3(W0, W1, W2)


@njit(cache=True)
def _omega_norm_em(S):
    """|W| = |vee(skew(D^T D'))| of an energy-momentum state."""
    w0 = 0.0
    w1 = 0.0
    w2 = 0.0
    for r in range(3):
        w0 += 0.5 * (S[6 + 3 * r + 2] * S[15 + 3 * r + 1] - S[6 + 3 * r + 1] * S[15 + 3 * r + 2])
        w1 += 0.5 * (S[6 + 3 * r + 0] * S[15 + 3 * r + 2] - S[6 + 3 * r + 2] * S[15 + 3 * r + 0])
        w2 += 0.5 * (S[6 + 3 * r + 1] * S[15 + 3 * r + 0] - S[6 + 3 * r + 0] * S[15 + 3 * r + 1])
    return _norm3(w0, w1, w2)


@njit(cache=True)
def _alpha_norm_rattle(P, S):
    """|Ibar^{-1} tau|, the angular acceleration of gravity at a RATTLE-family state (the
    energy-momentum limit estimate ignores it: 0 there)."""
    a0 = P[19] * S[27] + P[20] * S[28] + P[21] * S[29]
    a1 = P[22] * S[27] + P[23] * S[28] + P[24] * S[29]
    a2 = P[25] * S[27] + P[26] * S[28] + P[27] * S[29]
    return _norm3(a0, a1, a2)


def init_state(method, P, g, S):
    """Complete a new state S (x, v, D, D' set, everything else zero) for
    ``run_one(..., init=False)``: the RATTLE momentum Pi and torque (nothing to do for
    energy-momentum)."""
    if method == RATTLE_FAMILY:
        _rattle_init(P, g, S)


def store_state(method, P, S, g, t, X, V, Dout, Dpout):
    """The state S at the absolute time t as x_G, v_G (1, 3) and D, D' (1, 3, 3) in X, V,
    Dout, Dpout."""
    store = _store_rattle if method == RATTLE_FAMILY else _store_em
    store(P, S, g, float(t), 0, X, V, Dout, Dpout)


# The solve and the commit of the single-body loop: the same Python functions compiled as
# functions of their own (everything they call inlined into them by numba), once per
# signature, and marked for LLVM to inline (``forceinline``: LLVM's alwaysinline) into the
# loop variants, so the machine code is that of numba-level inlining. Inlining them into
# each loop variant with inline="always" instead repeats numba's work per call site, and
# that work grows with the square of the inlined code's size (numba copies the callee's IR
# block by block, each block with its whole variable scope): it was most of the compile time.
# (Under NUMBA_DISABLE_JIT the decorators return the Python functions, without ``py_func``.)
_rattle_solve_c = njit(forceinline=True)(getattr(_rattle_solve, "py_func", _rattle_solve))
_rattle_commit_c = njit(forceinline=True)(getattr(_rattle_commit, "py_func", _rattle_commit))


@njit
def _rattle_loop(coef, P, g, S, h, nstep, saves, k, X, V, Dout, Dpout, info, n0, free, comp):
    """The loop of :func:`run_rattle`: the state in local variables (registers) between
    steps, written to S at the saved steps, at the end and (for a composition) at the start
    of each step. ``free`` and ``comp`` are literal constants (a version compiled for each
    pair; numba prunes the branches on them): True for a free body, whose Ibar is diagonal
    and whose torque is zero; compensated sums. A function of its own, not inlined: each
    version is compiled once, where numba-level inlining would copy its IR per call site."""
    hs, hhs, rhs = _substep_sizes(coef, h)
    ncoef = coef.shape[0]
    nsave = saves.shape[0]
    diag = free or P[32] != 0.0
    piv = not free
    m = P[0]
    pc = (P[28], P[29], P[30])
    I0 = P[10]
    I1 = P[14]
    I2 = P[18]
    a0 = P[19]
    a1 = P[23]
    a2 = P[27]
    ae0 = P[33]
    ae1 = P[34]
    ae2 = P[35]
    p, pl, Pi, Pl, T, G = _get_state(S)
    if free:
        T = (0.0, 0.0, 0.0)  # as stored: a free body has no torque
    for n in range(1, nstep + 1):
        if ncoef > 1:
            # the start of the step, left in S if a later substep fails (a failing substep
            # changes nothing, so a single-substep scheme needs no copy)
            _put_state(S, p, pl, Pi, Pl, T)
        st = OK
        for c in range(ncoef):
            hh = hhs[c]
            ok, b0, b1, b2, w0, w1, w2, c0, c1, c2, q = _rattle_solve_c(
                diag, I0, I1, I2, a0, a1, a2, ae0, ae1, ae2, hh, Pi, T
            )
            if not ok:
                st, w0, w1, w2, c0, c1, c2, q = _solve_loop(P, b0, b1, b2)
                if st != OK:
                    break
            finite, pn, pln, Pin, Pln, Tn = _rattle_commit_c(
                comp, piv, m, pc, hh, rhs[c], (w0, w1, w2), (c0, c1, c2), q, p, pl, Pi, Pl, T,
                G, False, False,
            )  # fmt: skip
            if not finite:
                st = FAIL_NONFINITE
                break
            p, pl, Pi, Pl = pn, pln, Pin, Pln
            if not free:
                T = Tn
        if st != OK:
            info[0] = n - 1
            info[1] = _norm3(
                P[19] * Pi[0] + P[20] * Pi[1] + P[21] * Pi[2],
                P[22] * Pi[0] + P[23] * Pi[1] + P[24] * Pi[2],
                P[25] * Pi[0] + P[26] * Pi[1] + P[27] * Pi[2],
            )
            info[2] = _norm3(
                P[19] * T[0] + P[20] * T[1] + P[21] * T[2],
                P[22] * T[0] + P[23] * T[1] + P[24] * T[2],
                P[25] * T[0] + P[26] * T[1] + P[27] * T[2],
            )
            if ncoef == 1:
                _put_state(S, p, pl, Pi, Pl, T)
            return st
        if (n0 + n) % RESCALE_EVERY == 0:
            p, pl = _quat_rescale(p, pl)
        if k < nsave and saves[k] == n:
            _put_state(S, p, pl, Pi, Pl, T)
            _store_rattle(P, S, g, (n0 + n) * h, k, X, V, Dout, Dpout)
            k += 1
    _put_state(S, p, pl, Pi, Pl, T)
    return OK


@njit(inline="always")
def _run_rattle(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0, comp):
    """The body of :func:`run_rattle` (``comp`` True) and :func:`run_rattle_plain`: the
    start (momentum and torque of a new state, the saved start state), then the loop
    :func:`_rattle_loop` for a free body (no torque, diagonal Ibar: those branches and the
    torque terms folded away) or a pivoted one. The same numbers as one general loop."""
    if init:
        _rattle_init(P, g, S)
    k = _save_start(saves)
    if k > 0:
        _store_rattle(P, S, g, n0 * h, np.int64(0), X, V, Dout, Dpout)
    if P[31] == 0.0:
        return _rattle_loop(coef, P, g, S, h, nstep, saves, k, X, V, Dout, Dpout, info, n0,
                            True, comp)  # fmt: skip
    return _rattle_loop(coef, P, g, S, h, nstep, saves, k, X, V, Dout, Dpout, info, n0,
                        False, comp)  # fmt: skip


@njit(inline="always")
def _save_start(saves):
    """1 if the first saved step is 0 (the start state is stored), else 0: the index of the
    next saved state."""
    return 1 if saves.shape[0] > 0 and saves[0] == 0 else 0


# The entry points of one body, a kernel per family and per summation, so that a run
# compiles (or loads from numba's cache) only the code it uses. The same arguments for all;
# see :func:`run_one`.
@njit(cache=True)
def run_rattle(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0):
    """:func:`run_one` for the RATTLE family, with compensated sums."""
    return _run_rattle(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0, True)


@njit(cache=True)
def run_rattle_plain(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0):
    """:func:`run_rattle` with plain sums (round-off studies): a kernel of its own, so that
    the compensated path, the only one of the suite's runs, compiles without it."""
    return _run_rattle(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0, False)


@njit(cache=True)
def run_em(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0):
    """:func:`run_one` for the energy-momentum scheme (``coef`` and ``init`` unused: the
    scheme has one stage and its state needs no completion)."""
    k = _save_start(saves)
    if k > 0:
        _store_em(P, S, g, n0 * h, np.int64(0), X, V, Dout, Dpout)
    nsave = saves.shape[0]
    A = np.empty((15, 16))
    M = np.empty((10, 3, 3))
    for n in range(1, nstep + 1):
        st = _em_step(P, g, S, h, A, M)
        if st != OK:
            info[0] = n - 1
            info[1] = _omega_norm_em(S)
            info[2] = 0.0
            return st
        if k < nsave and saves[k] == n:
            _store_em(P, S, g, (n0 + n) * h, k, X, V, Dout, Dpout)
            k += 1
    return OK


def run_one(method, coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0):
    """Advance one body by ``nstep`` steps of size ``h`` from the state ``S`` (length NS,
    updated in place), reached after ``n0`` earlier steps (the absolute time of step n of
    this call is (n0 + n) h), and store the states at the step indices ``saves``
    (increasing, counted from this call's start; a first 0 stores the start state) into X,
    V (nsave, 3) and Dout, Dpout (nsave, 3, 3). ``coef`` are the composition coefficients
    of the RATTLE family (one RATTLE step of size coef[k] h each). ``init``: S holds a new
    state (x, v, D, D'; compensations zero) whose RATTLE momentum and torque are to be
    computed; False continues from a state this function left. Sums into the state are
    compensated (:func:`run_one_plain`: plain sums, for round-off studies).

    Returns a status code. On failure info[0] = number of steps completed, info[1] = |W| and
    info[2] = |Ibar^{-1} tau| at the failing state, and S is the state after info[0] steps.

    A Python function that calls the compiled kernel of the method (:func:`kernel`).
    """
    return kernel(method)(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0)


def run_one_plain(method, coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0):
    """:func:`run_one` with plain sums in the RATTLE family (energy-momentum is the same)."""
    fn = kernel(method, compensated=False)
    return fn(coef, P, g, S, h, nstep, saves, X, V, Dout, Dpout, info, init, n0)


def kernel(method, compensated=True):
    """The compiled single-body kernel of ``method`` (RATTLE_FAMILY or ENERGY_MOMENTUM):
    :func:`run_rattle`, :func:`run_rattle_plain` or :func:`run_em`, all with the arguments
    of :func:`run_one` less the method."""
    if method == RATTLE_FAMILY:
        return run_rattle if compensated else run_rattle_plain
    if method == ENERGY_MOMENTUM:
        return run_em
    raise ValueError(f"method = {method!r}: expected RATTLE_FAMILY (0) or ENERGY_MOMENTUM (1)")


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
            S = S0[i].copy()
            if method == RATTLE_FAMILY:
                status[i] = run_rattle(coef, P[i], g, S, h, nstep, saves, X[i], V[i], Dout[i],
                                       Dpout[i], info[i], True, 0)  # fmt: skip
            else:
                status[i] = run_em(coef, P[i], g, S, h, nstep, saves, X[i], V[i], Dout[i],
                                   Dpout[i], info[i], True, 0)  # fmt: skip


@njit(cache=True, parallel=True)
def run_batch_parallel(method, coef, P, g, S0, h, nstep, saves, X, V, Dout, Dpout, status, info,
                       vec, nblock):  # fmt: skip
    """Integrate each body i (leading axis of P, S0, X, V, Dout, Dpout, status, info, vec) as
    ``run_one`` does from a new state (``init`` and ``comp`` True), blocks of bodies
    distributed over threads with prange. The RATTLE family runs a block of up to BLOCK
    bodies through the vector substep (:func:`_run_rattle_block`), energy-momentum one body
    after another. vec[i] counts the substeps of body i taken by the vector code. The bodies
    are cut into ``nblock`` near-equal blocks (see :func:`block_count`)."""
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


_cache.tie(globals())
