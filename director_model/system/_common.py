"""Constants and small algebra of the system kernels (director_model/system/_kernels.py and
the modules it compiles in): the integrator's tolerances and iteration bounds, the status codes
and their messages, the diagnostics slots, and the row-major 3x3 tuple algebra.

Every function here is ``njit(forceinline=True)``: typed and compiled once, inlined by LLVM
into the kernels that call it (_kernels.py explains why).
"""

from __future__ import annotations

from numba import njit

from director_model.system._block3 import _U

#: the integrator state per body (``S`` rows): x (0:3) and its compensation (3:6), v (6:9)
#: and (9:12), the unnormalised attitude quaternion p (12:16) with D = D_0 R(p/|p|) and
#: (16:20), Pi = I W (20:23) and (23:26). Sums into x, v, p, Pi are compensated (Kahan)
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
#: space are no longer plain to see) sends the matrix to the SVD instead, except where the
#: envelope is block tridiagonal in 5-row joints (_band5.py: a single loop, the four-bar,
#: Bricard's linkage): there the velocity stage's symmetric matrix keeps its L D L^T where its
#: singular values (_sigma.py, without the vectors) show the nominal rank, the rank the
#: factorisation kept (the minimum-norm SVD solve would keep every direction it keeps: the
#: same joint forces), and sigma_rank_nominal / sigma_1 >= SIGMA_LDL, and the Newton
#: matrix's LU, which needs no rank decision beyond its row pattern (the velocity stage's),
#: is used as it is; a kept pivot below PIVOT_FLOOR of the largest diagonal entry (two
#: orders above the SVD's SOLVE_TOL: the four-bar's smallest relative singular value is about
#: 1/16 of its smallest pivot ratio) sends either matrix to the SVD. Below SIGMA_LDL rounding,
#: amplified by the inverse singular value, reaches the energy (IFToMM A02, two four-bars at
#: dt 1e-3: landings within 1e-13 .. 1e-12 of sigma_1 jump by up to 1.8e-11 J, within
#: 1e-12 .. 1e-11 by at most 2.8e-13 J). On A02 (two loops, not block tridiagonal) the
#: singular values' check moved the energy jumps of its landings within 1e-13 of sigma_1 to
#: 1.1e-11 .. 1.8e-11 J (three variants) against 6.1e-12 J with the SVD, across the bound of
#: tests/director_model/test_director_system_singular_passage.py: rounding either way, but
#: not shown to be no worse there, so it keeps the SVD. On the four-bar (rattle, 2000 steps
#: through three collinear passages) the pivot ratios below PIVOT_CHECK were 1e-11 .. 9e-9,
#: the singular values 1.2e-11 .. 2e-9 of sigma_1: 14 SVDs (about 60 us each in the step)
#: became 5 eigenvalue computations
DROP_TOL = 1e-10
PIVOT_CHECK = 1e-8
PIVOT_FLOOR = 1e-12
SIGMA_LDL = 1e-12
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
D_SVD = 5  # factorisations done by SVD (loop solver: see PIVOT_CHECK)
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
def _absmax(v, n):
    """max(0, |v[0]|, ..., |v[n - 1]|) over the entries that are not NaN (a NaN never wins
    numba's max, as in Python), as four running maxima over every fourth entry: the same value
    as one running maximum (max is exact), in four independent compare chains instead of one
    (one chain costs a compare and a select of latency per entry: ~1 % of a chain's step)."""
    m0 = m1 = m2 = m3 = 0.0
    n4 = n - n % 4
    for r in range(0, n4, 4):
        m0 = max(m0, abs(v[r]))
        m1 = max(m1, abs(v[r + 1]))
        m2 = max(m2, abs(v[r + 2]))
        m3 = max(m3, abs(v[r + 3]))
    for r in range(n4, n):
        m0 = max(m0, abs(v[r]))
    return max(max(m0, m1), max(m2, m3))


@njit(forceinline=True)
def _fail(info, n, h):
    """Record a failure at sub-step h of step n: info[0] = steps completed, info[1] = h."""
    info[0] = n - 1
    info[1] = h
