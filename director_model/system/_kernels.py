"""Compiled kernels of the system integrator: RATTLE on M q'' = f - G^T lambda, g(q) = 0.

All numba code of director_model.system is in this module, apart from the primitives it shares
with the single-body kernels (director_model/_primitives.py: the compensated sum and the
attitude quaternion's rotation) and the block solver's joint rows (_block3.py); its disk cache
is tied to those files (director_model/_cache.py).

Formulation. Body i has the director coordinates q_i = (x_i, d_1i, d_2i, d_3i) and the
constant mass matrix blockdiag(m 1, J_1 1, J_2 1, J_3 1). RATTLE on the whole system splits
exactly into (a) the six internal constraints of each body (orthonormal directors) and
(b) the joint rows g_r. For fixed joint multipliers lambda, the internal multipliers of one
body solve that body's RATTLE step under the director forces of the joints, which is the
discrete Moser-Veselov (DMV) equation with the body torque of those forces (numerics.md,
section 3): with Q = D_n^T D_{n+1} given by the Gibbs vector w (quaternion (1, w)),

    2 (I w + w x I w) = h (1 + |w|^2) pi,     pi = Pi_n + h/2 D_n^T tau(lambda)

(I = principal moments, all > 0; no convected moment J_i appears, so laminas with one
J_i = 0 are handled without dividing by it). The joint multipliers then solve
g(q_{n+1}(lambda)) = 0 by a chord Newton iteration whose matrix is the exact derivative at the
first iterate,

    dg/dlambda = -h^2 sum_i G_i(q_{n+1}) blockdiag(1/(2 m_i), Mth_i) G_i(q_n)^T,
    Mth_i = D_{n+1} (1 - hat(w)) A^{-1} D_n^T,   A = dF/dw of the DMV residual F,

assembled row pair by row pair over the rows that share a body (block tridiagonal for a
chain: solved by banded LU without pivoting, cost linear in the number of bodies; for chains
of spherical joints assembled and eliminated as 3x3 blocks in straight-line code, their rows,
forces and rates computed without the zeros of POINT rows with the same numbers, and the
velocity stage's symmetric matrix assembled and factorised as L D L^T joint by joint in one
pass from the upper triangles, director_model/system/_block3.py). Closed
loops (redundant rows) are factorised in the same band, with the joints ordered along the
loops (model.band_order), rank-revealing in the row order: the velocity stage's L D L^T drops
each row dependent on the rows before it, the Newton matrix's LU drops the same rows (a basic
solution: the joint forces are those of the minimum-norm one), and where a kept pivot is
small (near a singular configuration) the matrix goes to a dense SVD and the minimum-norm
solution. The velocity stage solves the symmetric positive semi-definite system
sum_i G_i blockdiag(1/m_i, D I^-1 D^T) G_i^T nu = G u0 for the multipliers of
G(q_{n+1}) u_{n+1} = 0, by banded L D L^T (upper band) or the same SVD.

Rows: joint constraint rows (see model.py) with, per row, the 12 numbers
(dg/dx_a, dg/dtheta_a, dg/dx_b, dg/dtheta_b), theta the world rotation increment
(delta d = delta theta x d). The joint force on a body is -G^T lambda as (force, world torque).

State per body (``S`` rows, length NS): x (0:3) and its compensation (3:6), v (6:9) and
(9:12), the unnormalised attitude quaternion p (12:16) with D = D_0 R(p/|p|) and (16:20),
Pi = I W (20:23) and (23:26). Sums into x, v, p, Pi are compensated (Kahan). ``mu`` holds
the last velocity multipliers and the position multipliers of each sub-step of the last
steps (force units; layout in :func:`_run_system`): the start values of the next position
multipliers, so a stepper restarted from (S, mu) continues bit for bit.

The step is written out inside :func:`_run_system`: a call with some thirty array arguments
per sub-step cost about 0.4 us (1 body: 540 ns per step with the call, 130 ns without).
Compile time (a cold numba cache) decides how the helpers are joined to it:

- the helpers of every sub-step and Newton iteration (rows, forces, DMV, assembly, block
  and banded solvers, the 3x3 tuple algebra, storing a state) are
  ``njit(forceinline=True)``: each is typed and compiled once and LLVM inlines it into
  run_system (numba's ``inline="always"`` inlines at the IR level and types every call site
  again: about three times the compile time of run_system, with the same per-step cost);
- the SVD and the minimum-norm solve are plain calls (the SVD's cost dwarfs a call's few
  tens of ns);
- no argument of a helper is a compile-time constant (a literal flag or index would compile
  one specialisation per value), and the SVD calls LAPACK's dgesdd through numba's wrapper
  directly, as np.linalg.svd does, without the checks and copies that make np.linalg.svd
  compile for several seconds; arrays are cleared by loops (a slice assignment ``A[:] = 0``
  lowers numba's general broadcasting store at each use).

- the banded solver is compiled into an entry of its own (:func:`run_system_banded`), apart
  from the block and minnorm solvers (:func:`run_system`): a run compiles the solvers of its
  entry only.

tests/director_model/test_director_system.py checks that every kernel compiles a single signature.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit, types
from numba.np.linalg import _LAPACK, ensure_lapack

from director_model import _cache
from director_model._primitives import kahan, quat_matrix
from director_model.system._band5 import (
    _b5_ldl_solve_rr,
    _b5_solve_rr,
    _is_band5,
    _is_revolute5,
    _r5_assemble,
    _r5_forces,
    _r5_rows,
)
from director_model.system._block3 import (  # _U: unsigned array indices, see there
    _U,
    _dot_row,
    _forces3,
    _hat_blk,
    _mm_z,
    _mmt_z,
    _rows3,
    _sym_factor,
    _sym_solve,
    _vres3,
)

ensure_lapack()
#: LAPACK's dgesdd through numba's wrapper (numba_ez_gesdd: workspace query, then the call),
#: the routine and arguments of numba's np.linalg.svd; calling it directly compiles in about
#: a tenth of the time of np.linalg.svd and its checks
_GESDD = _LAPACK().numba_ez_gesdd(types.float64)
_KIND_D = ord("d")
_JOBZ_A = ord("A")

NS = 26
EPS = 2.220446049250313e-16
MAXIT = 50
DMV_MAXIT = 40
QUAT_BIG = 2.0**128
QUAT_SHRINK = 2.0**-64

#: the minimum-norm solves drop singular values below SOLVE_TOL sigma_1 (redundant rows give
#: sigma ~ 1e-16 sigma_1; a configuration 1e-12 away from a singular one keeps its direction,
#: so Newton still closes the constraints there)
SOLVE_TOL = 1e-14
#: the loop solver's banded factorisations reveal the rank in the row order: the pivot of
#: row k over its diagonal entry before elimination is the squared sine of the angle between
#: row k of G and the rows kept before it (M^-1 metric). A redundant row's ratio is rounding:
#: each update of a_kk adds at most ~eps a_kk (the updates l_kj^2 d_j sum to at most a_kk),
#: so over the band (<= 2 bw + 1 of them) at most ~2 bw eps with bw ~ 10..50, ~1e-14; rows
#: below DROP_TOL = 1e-12 (a factor 100 over that) are dropped. A ratio between DROP_TOL and
#: PIVOT_CHECK (an angle below 1e-4 rad: near a singular configuration, where rank and null
#: space are no longer plain to see) sends the matrix to the SVD instead
DROP_TOL = 1e-10
PIVOT_CHECK = 1e-8
#: ``minnorm`` modes of the kernel: 0 block or banded, 1 banded rank-revealing with the SVD
#: where a pivot ratio drops, 2 the SVD at every solve (the ``svd`` solver, kept to compare)
MODE_PIVOTED = 1
MODE_SVD = 2
#: a step of the loop solver with a sub-step landing inside it (not at its end) where the
#: velocity stage's SVD drops a direction the joint rows have at t = 0 (sigma_rank_nominal of
#: G M^-1 G^T below SOLVE_TOL sigma_1: within rounding of a singular configuration of the
#: loop, where its branches meet) is done again from its start as m = 2, 3, ... steps of
#: dt / m (msp in the kernel), whose landings are elsewhere: at such a landing the solves
#: cannot resolve the direction in which the branches part, and rounding of the rows,
#: amplified by the inverse of that singular value, goes into the velocities and the energy
#: (iftomm_a02_n2: 1e-8 J in one step, docs/scenarios.md). Up to m = MAXSPLIT; if every split
#: has such a landing (the step's end lands near the singular configuration too, so the
#: landings just before it come nearer as m grows), the step of dt is taken as it comes and
#: counted (D_KEPT). The work of such a step is bounded by 1 + 2 + ... + MAXSPLIT + 1 steps
MAXSPLIT = 4

OK = 0
FAIL_NEWTON = 1  # the joint multipliers did not converge
FAIL_DMV = 2  # a body's rotation equation has no admissible solution (step too large)
FAIL_SINGULAR = 3  # singular multiplier matrix (banded solver)
FAIL_NONFINITE = 4
FAIL_SVD = 5  # the SVD of the multiplier matrix failed (minnorm solver)
FAIL_DAMP = 6  # the dampers' implicit half step did not converge

STATUS_TEXT = {
    FAIL_NEWTON: "the Newton iteration for the joint multipliers did not converge",
    FAIL_DMV: "a body's rotation equation (discrete Moser-Veselov) has no admissible solution "
    "(rotation of 90 degrees or more in one step, or a singular Jacobian)",
    FAIL_SINGULAR: "the multiplier matrix is singular (a singular configuration of the joints; "
    "solver='minnorm' handles it)",
    FAIL_NONFINITE: "a non-finite state",
    FAIL_SVD: "the singular value decomposition of the multiplier matrix failed (non-finite "
    "entries, or LAPACK's dgesdd did not converge)",
    FAIL_DAMP: "the dampers' implicit half step did not converge (a damping time m/c near the "
    "step or shorter)",
}

#: the smallest normal float64. The integrator state (S) and the multipliers kept in ``mu``
#: are flushed to zero below it at every sub-step (:func:`_ftz`): subnormal numbers cost
#: tens of cycles per operation, and a motion in a plane (the four-bar) tilts out of it by
#: rounding (~1e-45 rad) and then carries subnormal out-of-plane components (~1e-322) in its
#: quaternions and multipliers, which made its step 25 % dearer from t ~ 0.3 s. A state entry
#: below it is zero on every scale a body or a force can have (an absolute change under
#: 2.3e-308 in SI units).
TINY = 2.2250738585072014e-308

#: diagnostics slots
D_ITER = 0  # Newton iterations (all substeps)
D_RANKDROP = 1  # steps whose velocity-stage matrix lost rank below the nominal rank
D_SMIN = 2  # smallest sigma_{rank_nominal} / sigma_1 of that matrix (minnorm solver)
D_TSMIN = 3  # step index where it occurred
D_MAXIT = 4  # largest iteration count of one substep
D_SVD = 5  # factorisations done by SVD (loop solver: a pivot ratio below PIVOT_CHECK)
D_SPLIT = 6  # steps done again as more steps of a fraction of dt (loop solver, MAXSPLIT)
D_KEPT = 7  # steps kept as they came after MAXSPLIT splits, each with such a landing
NDIAG = 8


@njit(forceinline=True)
def _ftz(x):
    """x, or 0 if x is subnormal (|x| < TINY)."""
    return 0.0 if abs(x) < TINY else x


@njit(forceinline=True)
def _zero2(A):
    """A = 0 for a 2-d array."""
    for i in range(A.shape[0]):
        for j in range(A.shape[1]):
            A[i, j] = 0.0


@njit(forceinline=True)
def _mm(A, B):
    """A B for row-major 3x3 9-tuples."""
    return (
        A[0] * B[0] + A[1] * B[3] + A[2] * B[6],
        A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
        A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
        A[3] * B[0] + A[4] * B[3] + A[5] * B[6],
        A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
        A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[3] + A[8] * B[6],
        A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
        A[6] * B[2] + A[7] * B[5] + A[8] * B[8],
    )


@njit(forceinline=True)
def _mmt(A, B):
    """A B^T for row-major 3x3 9-tuples."""
    return (
        A[0] * B[0] + A[1] * B[1] + A[2] * B[2],
        A[0] * B[3] + A[1] * B[4] + A[2] * B[5],
        A[0] * B[6] + A[1] * B[7] + A[2] * B[8],
        A[3] * B[0] + A[4] * B[1] + A[5] * B[2],
        A[3] * B[3] + A[4] * B[4] + A[5] * B[5],
        A[3] * B[6] + A[4] * B[7] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[1] + A[8] * B[2],
        A[6] * B[3] + A[7] * B[4] + A[8] * B[5],
        A[6] * B[6] + A[7] * B[7] + A[8] * B[8],
    )


@njit(forceinline=True)
def _inv3(A):
    """(det A, A^{-1}) for a row-major 9-tuple (the inverse is garbage if det = 0)."""
    c00 = A[4] * A[8] - A[5] * A[7]
    c01 = A[5] * A[6] - A[3] * A[8]
    c02 = A[3] * A[7] - A[4] * A[6]
    det = A[0] * c00 + A[1] * c01 + A[2] * c02
    r = 1.0 / det if det != 0.0 else 0.0
    return det, (
        c00 * r, (A[2] * A[7] - A[1] * A[8]) * r, (A[1] * A[5] - A[2] * A[4]) * r,
        c01 * r, (A[0] * A[8] - A[2] * A[6]) * r, (A[2] * A[3] - A[0] * A[5]) * r,
        c02 * r, (A[1] * A[6] - A[0] * A[7]) * r, (A[0] * A[4] - A[1] * A[3]) * r,
    )  # fmt: skip


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
def _band_lu_rr(A, bw, ext, keep, out):
    """In-place LU without pivoting of the banded A (n, 2 bw + 1), A[r, bw + s - r], within
    the envelope ``ext`` (:func:`_envelope`), in the row order, over the rows with keep[k] = 1
    (the others dropped: their unknowns 0, their equations taken as consistent; the pattern
    of the velocity stage's :func:`_band_ldl_rr` at the sub-step's start). Returns 1 where a
    kept pivot |u_kk| falls below PIVOT_CHECK times the largest diagonal entry (near a
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
        if not abs(piv) >= PIVOT_CHECK * dmax:
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
def _band_ldl_rr(A, bw, ext, keep, d0, out):
    """In-place L D L^T of the symmetric positive semi-definite banded A (upper band stored,
    as :func:`_band_ldl`) within the envelope ``ext``, in the row order, rank-revealing: a
    row whose pivot d_k is at most DROP_TOL times its diagonal entry a_kk before elimination
    (d_k / a_kk: the squared sine of the angle between row k of G and the rows kept before
    it, metric M^-1) is dependent on those rows, a redundant joint row, and is dropped
    (keep[k] = 0, its L column 0; for a positive semi-definite A its whole remaining row is
    negligible too, |s_kj| <= sqrt(s_kk s_jj)); the others are kept (keep[k] = 1). Returns 1
    where a kept pivot falls below PIVOT_CHECK times the largest diagonal entry (near a
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
        if d < PIVOT_CHECK * dmax:
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
def _row9(A, i):
    u = _U(i)
    return (A[u, 0], A[u, 1], A[u, 2], A[u, 3], A[u, 4], A[u, 5], A[u, 6], A[u, 7], A[u, 8])


@njit(forceinline=True)
def _put9(A, i, T):
    u = _U(i)
    for c in range(9):
        A[u, _U(c)] = T[c]


@njit(forceinline=True)
def _tmul(D, t0, t1, t2):
    """D^T t for a row-major 9-tuple D."""
    return (
        D[0] * t0 + D[3] * t1 + D[6] * t2,
        D[1] * t0 + D[4] * t1 + D[7] * t2,
        D[2] * t0 + D[5] * t1 + D[8] * t2,
    )


@njit(forceinline=True)
def _mul(D, t0, t1, t2):
    """D t for a row-major 9-tuple D."""
    return (
        D[0] * t0 + D[1] * t1 + D[2] * t2,
        D[3] * t0 + D[4] * t1 + D[5] * t2,
        D[6] * t0 + D[7] * t1 + D[8] * t2,
    )


@njit(forceinline=True)
def _fail(info, n, h):
    """Record a failure at sub-step h of step n: info[0] = steps completed, info[1] = h."""
    info[0] = n - 1
    info[1] = h


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


@njit
def _run_system(
    B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X, V, D, W, minnorm,
    bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr, jidx, jside, fint, fvec, banded,
):  # fmt: skip
    """Advance the system nstep steps of dt (each step the composition ``coef`` of RATTLE
    sub-steps), storing the states at the step indices ``saves`` (increasing, 0 = the start)
    into X, V (nsave, nb, 3), D (nsave, nb, 3, 3), W (nsave, nb, 3). Returns a status; on
    failure info[0] = steps completed, info[1] = the failing sub-step's h.

    ``mu`` (length nr (2 + 3 ns) + 2, nr = max(nrow, 1), ns = len(coef)): the last velocity
    multipliers (0:nr), the position multipliers of each sub-step j of the last step
    (nr (1 + j) ...) and of the step before (nr (1 + ns + j) ...), the number of steps in
    that history (0 to 3) at kp0 - 1 = nr (1 + 2 ns), the loop solver's row pattern
    (kp0 ... kp0 + nr - 1: 1 kept, 0 dropped) and whether it is set (kp0 + nr), then the
    position multipliers of each sub-step j three steps back (kp0 + nr + 1 + nr j ...): the
    integrator state besides S. The block solver keeps in the three histories the position
    multipliers less the velocity multipliers at the sub-step's start instead.

    The solver of the multiplier equations: ``minnorm`` (an int) the banded rank-revealing
    factorisations with the SVD where a pivot ratio drops (:data:`MODE_PIVOTED`) or the SVD
    throughout (:data:`MODE_SVD`), else ``banded`` (a
    literal constant: numba drops the branches of the other value before typing them) the
    banded LU and L D L^T, else the 3x3 block elimination. Called by the entries
    :func:`run_system` and :func:`run_system_banded`."""
    nb = S.shape[0]
    nrow = rint.shape[0]
    nr = max(nrow, 1)
    nd = nr if minnorm else 1
    Dn = np.empty((nb, 9))
    Dnew = np.empty((nb, 9))
    VH = np.empty((nb, 3))
    PI = np.empty((nb, 3))
    WG = np.empty((nb, 3))
    XN = np.empty((nb, 3))
    F = np.zeros((nb, 3))
    T = np.zeros((nb, 3))
    Mx = np.empty(nb)
    Mth = np.empty((nb, 9))
    AI = np.empty((nb, 9))  # the inverse DMV Jacobian of each body at the fresh iterate
    # per body: 1/m (products, not quotients: divisions cost several times a product), the
    # kick h/2 (g + F/m) of the last Newton iterate and the momentum term 4 c/(q h) of the
    # velocity stage, both used again in the state update
    IM = np.empty(nb)
    for i in range(nb):
        IM[i] = 1.0 / B[i, 0]
    HK = np.empty((nb, 3))
    RC = np.empty((nb, 3))
    Jold = np.zeros((nr, 12))
    Jnew = np.zeros((nr, 12))
    gv = np.zeros(nr)
    lam = np.zeros(nr)
    dl = np.zeros(nr)
    Ab = np.zeros((nr, 2 * bw + 1))
    Ad = np.zeros((nd, nd))
    r0 = np.zeros(nr)
    U = np.zeros((nd, nd))
    sv = np.zeros(nd)
    Vt = np.zeros((nd, nd))
    psvd = False
    Fn = np.zeros((nb, 3))
    Tn = np.zeros((nb, 3))
    # force elements: their forces at the start (FE, TE) and the end (FE2, TE2) of a sub-step,
    # the world angular velocities of the start state (WD) and of the velocity stage's u0
    # (TW), u0 with the elements' second half kick (VC, TC) and the velocities the dampers are
    # evaluated at (VG, TG)
    nfe = fint.shape[0]
    damped = False
    for e in range(nfe):
        if fint[e, 0] == 0 and fvec[e, 7] != 0.0:
            damped = True
    FE = np.zeros((nb, 3))
    TE = np.zeros((nb, 3))
    FE2 = np.zeros((nb, 3))
    TE2 = np.zeros((nb, 3))
    WD = np.zeros((nb, 3))
    TW = np.zeros((nb, 3))
    VC = np.zeros((nb, 3))
    TC = np.zeros((nb, 3))
    VG = np.zeros((nb, 3))
    TG = np.zeros((nb, 3))
    nK = 1 if banded or minnorm else nrow // 3
    Dg = np.zeros((nK, 9))
    Up = np.zeros((nK, 9))
    Lo = np.zeros((nK, 9))
    # the flags of _assemble (banded storage, the upper band only) as run-time values
    # (constant arguments would compile one _assemble for each combination)
    yes = minnorm >= 0
    no = minnorm < 0
    # the loop solver's row patterns (1 kept, 0 dropped): kv of the velocity stage, kn of
    # the Newton matrix (the velocity stage's at the sub-step's start, kept in mu)
    kv = np.ones(nr, dtype=np.int64)
    kn = np.ones(nr, dtype=np.int64)
    ext = np.zeros(nr, dtype=np.int64)
    _envelope(ptr, idx, nrow, ext)
    # joints of five rows, each sharing a body with the next only: the solves in joint blocks
    # (_band5.py), and for revolute joints the rows, forces and assembly too
    b5 = minnorm == MODE_PIVOTED and _is_band5(ext, nrow)
    r5 = b5 and _is_revolute5(rint, nrow)
    d0 = np.zeros(nr)
    pb = np.zeros(2)
    ns = coef.shape[0]
    nhist = int(mu[nr * (1 + 2 * ns)])
    kp0 = nr * (1 + 2 * ns) + 1
    havepat = mu[kp0 + nr] > 0.0
    for r in range(nrow):
        kn[r] = int(mu[kp0 + r])
    ks = 0
    if saves.shape[0] > 0 and saves[0] == 0:
        _store(B, D0, S, X, V, D, W, saves[0])
        ks = 1
    # a step whose sub-steps land where the velocity stage's solve drops a direction (see
    # MAXSPLIT) is done again as m steps of dt / m from its start, restored from these
    split = minnorm > 0 and nrow > 0
    S0 = np.empty((nb if split else 0, NS))
    mu0 = np.empty(nr if split else 0)
    kn0 = np.empty(nr if split else 0, dtype=np.int64)
    hp0 = havepat
    for n in range(1, nstep + 1):
        if split:
            _copy_step_state(nb, nr, S, mu, kn, S0, mu0, kn0)
            hp0 = havepat
        msp = 1
        keep = False
        hs = dt
        js = 0
        while js < msp * ns:
            j = js % ns
            js += 1
            h = coef[j] * hs
            hh = 0.5 * h
            xmax = Lsc
            for i in range(nb):
                Ri = quat_matrix((S[i, 12], S[i, 13], S[i, 14], S[i, 15]))
                _put9(Dn, i, _mm(_row9(D0, i), Ri))
                for c in range(3):
                    xmax = max(xmax, abs(S[i, c]))
            tol = tol_rel * xmax
            if nrow > 0:
                if r5:
                    _r5_rows(rint, rvec, S, Dn, gv, Jold)
                elif banded or minnorm:
                    _rows(rint, rvec, S, Dn, gv, Jold)
                else:
                    _rows3(rint, rvec, S, Dn, gv, Jold)
            if nfe > 0:
                for i in range(nb):
                    WD[i, 0], WD[i, 1], WD[i, 2] = _mul(
                        _row9(Dn, i), S[i, 20] * B[i, 4], S[i, 21] * B[i, 5], S[i, 22] * B[i, 6]
                    )
                    for c in range(3):
                        VC[i, c] = S[i, 6 + c]
                _ext(fint, fvec, S, Dn, VC, WD, FE, TE)
            # start value: in the banded solver the position multipliers of this sub-step
            # extrapolated linearly from the same sub-step of the two previous steps; in the
            # block solver the last velocity multipliers (those at this sub-step's start)
            # plus the difference d = position - velocity multipliers of this sub-step,
            # extrapolated by the polynomial through the last three steps (history in mu,
            # see _run_system). d is O(h) smaller than the multipliers, so this start is
            # O(h^4) off where the multipliers extrapolated by the same polynomial are
            # O(h^3) off: hanging chains of 50 and 100 rods, rattle, 100000 body-steps, take
            # 1.07 and 1.29 Newton updates per sub-step against 1.27 and 1.46. The loop
            # solver starts from the last velocity multipliers (on the
            # loops these close the joints more tightly in one iteration: on the four-bar
            # through its singular configuration, residuals ~5e-16 m against ~3e-15 m from
            # the extrapolated ones, and the crank and rocker parallel to 3e-13, not 2e-12)
            ho1 = nr * (1 + j)
            ho2 = nr * (1 + ns + j)
            ho3 = kp0 + nr + 1 + nr * j
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
            if minnorm == MODE_PIVOTED and nrow > 0 and not havepat:
                # no row pattern yet (the first sub-step, or the last velocity stage went to
                # the SVD): that of the velocity stage's matrix at q_n
                for i in range(nb):
                    Mx[i] = 1.0 / B[i, 0]
                    Di = _row9(Dn, i)
                    DI = (Di[0] * B[i, 4], Di[1] * B[i, 5], Di[2] * B[i, 6],
                          Di[3] * B[i, 4], Di[4] * B[i, 5], Di[5] * B[i, 6],
                          Di[6] * B[i, 4], Di[7] * B[i, 5], Di[8] * B[i, 6])  # fmt: skip
                    _put9(Mth, i, _mmt(DI, Di))
                _assemble(ptr, idx, side, Jold, Jold, Mx, Mth, Ab, yes, bw, yes)
                st = _band_ldl_rr(Ab, bw, ext, kn, d0, pb)
                if st < 0:
                    _fail(info, n, h)
                    return FAIL_SVD
                havepat = st == 0
            rank = 0
            it = 0
            while True:
                # the chord matrix of the first iterate; from the fourth on a new one at every
                # iterate (plain Newton: linear convergence near a singular configuration)
                fresh = it == 0 or it >= 3
                if nrow > 0:
                    if r5:
                        _r5_forces(rint, Jold, lam, F, T)
                    elif banded or minnorm:
                        _forces(rint, Jold, lam, F, T)
                    else:
                        _forces3(rint, Jold, lam, F, T)
                if nfe > 0:
                    if nrow == 0:
                        _zero2(F)
                        _zero2(T)
                    for i in range(nb):
                        for c in range(3):
                            F[i, c] += FE[i, c]
                            T[i, c] += TE[i, c]
                for i in range(nb):
                    m = B[i, 0]
                    Di = _row9(Dn, i)
                    for c in range(3):
                        HK[i, c] = hh * (g[c] + F[i, c] * IM[i])
                        VH[i, c] = S[i, 6 + c] + HK[i, c]
                        XN[i, c] = S[i, c] + h * VH[i, c]  # x_{n+1}
                    t0, t1, t2 = _tmul(Di, T[i, 0], T[i, 1], T[i, 2])
                    p0 = S[i, 20] + hh * t0
                    p1 = S[i, 21] + hh * t1
                    p2 = S[i, 22] + hh * t2
                    PI[i, 0] = p0
                    PI[i, 1] = p1
                    PI[i, 2] = p2
                    if fresh:
                        ok, w0, w1, w2, Ai = _dmv(
                            B[i, 1], B[i, 2], B[i, 3], B[i, 4], B[i, 5], B[i, 6], p0, p1, p2, h
                        )
                        _put9(AI, i, Ai)
                    else:
                        Ai = _row9(AI, i)
                        ok, w0, w1, w2 = _dmv_iterate(B[i, 1], B[i, 2], B[i, 3], p0, p1, p2, h,
                                                      WG[i, 0], WG[i, 1], WG[i, 2], Ai)  # fmt: skip
                    if not ok:
                        _fail(info, n, h)
                        return FAIL_DMV
                    WG[i, 0] = w0
                    WG[i, 1] = w1
                    WG[i, 2] = w2
                    Dj = _mm(Di, quat_matrix((1.0, w0, w1, w2)))
                    _put9(Dnew, i, Dj)
                    if fresh and nrow > 0:
                        # Mth = Dnew (1 - hat(w)) A^{-1} Dn^T, the rotation's response to a torque
                        K = (
                            Ai[0] - (-w2 * Ai[3] + w1 * Ai[6]),
                            Ai[1] - (-w2 * Ai[4] + w1 * Ai[7]),
                            Ai[2] - (-w2 * Ai[5] + w1 * Ai[8]),
                            Ai[3] - (w2 * Ai[0] - w0 * Ai[6]),
                            Ai[4] - (w2 * Ai[1] - w0 * Ai[7]),
                            Ai[5] - (w2 * Ai[2] - w0 * Ai[8]),
                            Ai[6] - (-w1 * Ai[0] + w0 * Ai[3]),
                            Ai[7] - (-w1 * Ai[1] + w0 * Ai[4]),
                            Ai[8] - (-w1 * Ai[2] + w0 * Ai[5]),
                        )
                        _put9(Mth, i, _mmt(_mm(Dj, K), Di))
                        Mx[i] = 0.5 / m
                if nrow == 0:
                    break
                if r5:
                    _r5_rows(rint, rvec, XN, Dnew, gv, Jnew)
                elif banded or minnorm:
                    _rows(rint, rvec, XN, Dnew, gv, Jnew)
                else:
                    _rows3(rint, rvec, XN, Dnew, gv, Jnew)
                err = 0.0
                for r in range(nrow):
                    err = max(err, abs(gv[r]))
                if not err < math.inf:
                    _fail(info, n, h)
                    return FAIL_NONFINITE
                # at least one update: a start value already within tol would leave the joints
                # open by up to tol (free_chain_5 rattle6: 9e-15 m against 1e-15 m polished)
                if err <= tol and it > 0:
                    break
                if it >= MAXIT:
                    _fail(info, n, h)
                    return FAIL_NEWTON
                if fresh:
                    if minnorm:
                        # the rows dropped at q_n may not be redundant at q_{n+1} at a singular
                        # configuration (where branches of the loop meet): from the fourth
                        # iterate on (the matrix is fresh from then on) the SVD decides
                        psvd = minnorm == MODE_SVD or it >= 3
                        if not psvd and havepat:
                            if r5:
                                _r5_assemble(jptr, jidx, jside, Jnew, Jold, Mx, Mth, Ab, bw, no)
                            else:
                                _assemble(ptr, idx, side, Jnew, Jold, Mx, Mth, Ab, yes, bw, no)
                            st = _band_lu_rr(Ab, bw, ext, kn, pb)
                            if st < 0:
                                _fail(info, n, h)
                                return FAIL_SVD
                            psvd = st > 0
                        else:
                            psvd = True
                        if psvd:
                            diag[D_SVD] += 1
                            _assemble(ptr, idx, side, Jnew, Jold, Mx, Mth, Ad, no, bw, no)
                            rank = _svd_factor(Ad, SOLVE_TOL, U, sv, Vt)
                            if rank < 0:
                                _fail(info, n, h)
                                return FAIL_SVD
                    elif banded:
                        _assemble(ptr, idx, side, Jnew, Jold, Mx, Mth, Ab, yes, bw, no)
                        if not _band_lu(Ab, bw):
                            _fail(info, n, h)
                            return FAIL_SINGULAR
                    else:
                        _blk_assemble(jptr, jidx, jside, Jnew, Jold, Mx, Mth, Dg, Up, Lo)
                        if not _blk_lu(Dg, Up, Lo):
                            _fail(info, n, h)
                            return FAIL_SINGULAR
                if minnorm:
                    if psvd:
                        _svd_solve(U, sv, Vt, rank, gv, dl)
                    elif b5:
                        _b5_solve_rr(Ab, bw, kn, gv, dl)
                    else:
                        _band_solve_rr(Ab, bw, ext, kn, gv, dl)
                elif banded:
                    _band_solve(Ab, bw, gv, dl)
                else:
                    _blk_solve(Dg, Up, Lo, gv, dl)
                ih2 = 1.0 / (h * h)
                for r in range(nrow):
                    lam[r] += dl[r] * ih2
                it += 1
            diag[D_ITER] += it
            diag[D_MAXIT] = max(diag[D_MAXIT], it)
            # velocity stage: u0 = (v_half + h/2 g, Dnew I^{-1} Q^T pi), Q^T pi = pi - 4 c/(q h);
            # TW holds the world angular velocity of u0, VH its velocity
            for i in range(nb):
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
            if nrow > 0 or nfe > 0:
                for i in range(nb):
                    Mx[i] = 1.0 / B[i, 0]
                    Dj = _row9(Dnew, i)
                    DI = (Dj[0] * B[i, 4], Dj[1] * B[i, 5], Dj[2] * B[i, 6],
                          Dj[3] * B[i, 4], Dj[4] * B[i, 5], Dj[5] * B[i, 6],
                          Dj[6] * B[i, 4], Dj[7] * B[i, 5], Dj[8] * B[i, 6])  # fmt: skip
                    if banded or minnorm:
                        _put9(Mth, i, _mmt(DI, Dj))
                    else:
                        # the block solver's factorisation is symmetric: Mth = D I^-1 D^T
                        # from its upper triangle
                        m00 = DI[0] * Dj[0] + DI[1] * Dj[1] + DI[2] * Dj[2]
                        m01 = DI[0] * Dj[3] + DI[1] * Dj[4] + DI[2] * Dj[5]
                        m02 = DI[0] * Dj[6] + DI[1] * Dj[7] + DI[2] * Dj[8]
                        m11 = DI[3] * Dj[3] + DI[4] * Dj[4] + DI[5] * Dj[5]
                        m12 = DI[3] * Dj[6] + DI[4] * Dj[7] + DI[5] * Dj[8]
                        m22 = DI[6] * Dj[6] + DI[7] * Dj[7] + DI[8] * Dj[8]
                        _put9(Mth, i, (m00, m01, m02, m01, m11, m12, m02, m12, m22))
            # the velocity stage's matrix G M^-1 G^T at q_{n+1}, factorised once
            vsvd = False
            if nrow > 0:
                if minnorm:
                    vsvd = minnorm == MODE_SVD
                    if not vsvd:
                        if r5:
                            _r5_assemble(jptr, jidx, jside, Jnew, Jnew, Mx, Mth, Ab, bw, yes)
                        else:
                            _assemble(ptr, idx, side, Jnew, Jnew, Mx, Mth, Ab, yes, bw, yes)
                        st = _band_ldl_rr(Ab, bw, ext, kv, d0, pb)
                        if st < 0:
                            _fail(info, n, h)
                            return FAIL_SVD
                        vsvd = st > 0
                        # the pattern of the next sub-step's Newton matrix (at this q_{n+1})
                        havepat = not vsvd
                        for r in range(nrow):
                            kn[r] = kv[r]
                    if vsvd:
                        diag[D_SVD] += 1
                        _assemble(ptr, idx, side, Jnew, Jnew, Mx, Mth, Ad, no, bw, no)
                        rank = _svd_factor(Ad, SOLVE_TOL, U, sv, Vt)
                        if rank < 0:
                            _fail(info, n, h)
                            return FAIL_SVD
                        nrank = 0
                        for k in range(nd):
                            if sv[k] > rank_tol * sv[0]:
                                nrank += 1
                        rel = sv[rank_nom - 1] / sv[0] if rank_nom > 0 and sv[0] > 0.0 else 1.0
                    else:
                        # the rows kept; every kept pivot ratio is at least PIVOT_CHECK (a
                        # bound on sigma_rank / sigma_1 it is not: that one the SVD gives)
                        nrank = int(pb[1])
                        rel = pb[0]
                    if vsvd and rank < rank_nom and js < msp * ns and not keep:
                        # a landing inside the step where the solve drops a direction the
                        # rows have away from singular configurations: the step again, as
                        # msp + 1 steps of dt / (msp + 1) from its start (other landing
                        # times); after MAXSPLIT, the step of dt as it comes
                        _copy_step_state(nb, nr, S0, mu0, kn0, S, mu, kn)
                        havepat = hp0
                        js = 0
                        if msp >= MAXSPLIT:
                            diag[D_KEPT] += 1
                            keep = True
                            msp = 1
                        else:
                            diag[D_SPLIT] += 1
                            msp += 1
                        hs = dt / msp
                        continue
                    if nrank < rank_nom:
                        diag[D_RANKDROP] += 1
                    if rel < diag[D_SMIN]:
                        diag[D_SMIN] = rel
                        diag[D_TSMIN] = n
                elif banded:
                    _assemble(ptr, idx, side, Jnew, Jnew, Mx, Mth, Ab, yes, bw, yes)
                    if not _band_ldl(Ab, bw):
                        _fail(info, n, h)
                        return FAIL_SINGULAR
                elif not _sym_factor(rint, Jnew, Mx, Mth, Dg, Up):
                    _fail(info, n, h)
                    return FAIL_SINGULAR
            # the second half kick of the force elements at q_{n+1}: with dampers implicit in
            # the velocities (the trapezoidal rule on them, so the step stays symmetric), by a
            # fixed-point iteration from u0 that reuses the factorisation
            if nfe > 0:
                for i in range(nb):
                    for c in range(3):
                        VG[i, c] = VH[i, c]
                        TG[i, c] = TW[i, c]
            itd = 0
            dprev = math.inf
            while True:
                if nfe > 0:
                    _ext(fint, fvec, XN, Dnew, VG, TG, FE2, TE2)
                    for i in range(nb):
                        t0, t1, t2 = TE2[i, 0] * hh, TE2[i, 1] * hh, TE2[i, 2] * hh
                        for c in range(3):
                            VC[i, c] = VH[i, c] + hh * FE2[i, c] * Mx[i]
                            TC[i, c] = TW[i, c] + (
                                Mth[i, 3 * c] * t0 + Mth[i, 3 * c + 1] * t1 + Mth[i, 3 * c + 2] * t2
                            )
                    vel, om = VC, TC
                else:
                    vel, om = VH, TW
                if nrow > 0:
                    if banded or minnorm:
                        _vres(rint, Jnew, vel, om, r0)
                    else:
                        _vres3(rint, Jnew, vel, om, r0)
                    if minnorm:
                        if vsvd:
                            _svd_solve(U, sv, Vt, rank, r0, dl)
                        elif b5:
                            _b5_ldl_solve_rr(Ab, bw, kv, r0, dl)
                        else:
                            _band_ldl_solve_rr(Ab, bw, ext, kv, r0, dl)
                    elif banded:
                        _band_ldl_solve(Ab, bw, r0, dl)
                    else:
                        _sym_solve(Dg, Up, r0, dl)
                    if r5:
                        _r5_forces(rint, Jnew, dl, Fn, Tn)
                    elif banded or minnorm:
                        _forces(rint, Jnew, dl, Fn, Tn)
                    else:
                        _forces3(rint, Jnew, dl, Fn, Tn)
                else:
                    _zero2(Fn)
                    _zero2(Tn)
                if not damped:
                    break
                # the candidate velocities at n+1 against those the dampers were evaluated at
                dn = 0.0
                vn = 1e-300
                for i in range(nb):
                    t0, t1, t2 = Tn[i, 0], Tn[i, 1], Tn[i, 2]
                    for c in range(3):
                        v1 = vel[i, c] + Fn[i, c] * Mx[i]
                        w1 = om[i, c] + (
                            Mth[i, 3 * c] * t0 + Mth[i, 3 * c + 1] * t1 + Mth[i, 3 * c + 2] * t2
                        )
                        dn = max(dn, abs(v1 - VG[i, c]) + abs(w1 - TG[i, c]) * Lsc)
                        vn = max(vn, abs(v1) + abs(w1) * Lsc)
                        VG[i, c] = v1
                        TG[i, c] = w1
                if dn <= 4.0 * EPS * vn or (dn >= dprev and dn <= 64.0 * EPS * vn):
                    break
                dprev = dn
                itd += 1
                if itd >= MAXIT:
                    _fail(info, n, h)
                    return FAIL_DAMP
            if nfe > 0:
                # the force elements' second half kick joins the velocity impulse
                for i in range(nb):
                    for c in range(3):
                        Fn[i, c] += hh * FE2[i, c]
                        Tn[i, c] += hh * TE2[i, c]
            h2i = 2.0 / h
            for r in range(nrow):
                mu[ho3 + r] = mu[ho2 + r]
                mu[ho2 + r] = mu[ho1 + r]
                mu[ho1 + r] = _ftz(lam[r] if banded or minnorm else lam[r] - mu[r])
                mu[r] = _ftz(dl[r] * h2i)
                mu[kp0 + r] = kn[r]
            mu[kp0 + nr] = 1.0 if havepat else 0.0
            for i in range(nb):
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
                    if not abs(S[i, c]) < math.inf:
                        _fail(info, n, h)
                        return FAIL_NONFINITE
                    S[i, c] = _ftz(S[i, c])

        nhist = min(nhist + 1, 3)
        mu[nr * (1 + 2 * ns)] = nhist
        if ks < saves.shape[0] and saves[ks] == n:
            _store(B, D0, S, X, V, D, W, ks)
            ks += 1
    return OK


# The entries, one per group of solvers, so that a run compiles (or loads) only the code of
# its own: the default suite's systems use the block and minnorm solvers, and without the
# banded factorisations and solves the kernel compiles in about 0.9 of the time.
@njit(cache=True)
def run_system(
    B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X, V, D, W, minnorm,
    bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr, jidx, jside, fint, fvec,
):  # fmt: skip
    """:func:`_run_system` with the minnorm solver (``minnorm`` :data:`MODE_PIVOTED` or
    :data:`MODE_SVD`) or the block one (0; the joint rows in 3x3 blocks, ``jptr``, ``jidx``,
    ``jside``)."""
    return _run_system(B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X,
                       V, D, W, minnorm, bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr,
                       jidx, jside, fint, fvec, False)  # fmt: skip


@njit(cache=True)
def run_system_banded(
    B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X, V, D, W,
    bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr, jidx, jside, fint, fvec,
):  # fmt: skip
    """:func:`_run_system` with the banded solver (the arguments of :func:`run_system` less
    ``minnorm``)."""
    return _run_system(B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X,
                       V, D, W, 0, bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr,
                       jidx, jside, fint, fvec, True)  # fmt: skip


_cache.tie(
    globals(),
    *[
        Path(__file__).parent.parent / "_primitives.py",
        Path(__file__).with_name("_block3.py"),
        Path(__file__).with_name("_band5.py"),
    ],
)
