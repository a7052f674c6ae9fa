"""Compiled kernels of the system integrator: RATTLE on M q'' = f - G^T lambda, g(q) = 0.

This module holds the step (:func:`_run_system`) and its compiled entries. The numba code it
compiles in is in modules each importing only from those listed before it: ``_block3.py``
(the block solver's joints of three POINT rows), ``_band5.py`` (the loop solver in 5 x 5
joint blocks), ``_common.py`` (constants, status codes, diagnostics slots, 3x3 algebra),
``_rows.py`` (the joint rows, forces and rates of every joint kind; force elements),
``_solvers.py`` (the multiplier matrices: start value, assembly, factorisations) and
``_bodies.py`` (the per-body work: DMV, responses, state update), ``_sigma.py`` (the
velocity stage's singular values without vectors, near singular configurations); and in
director_model/_primitives.py (the compensated sum, the attitude quaternion's rotation),
shared with the single-body kernels. Its disk cache is tied to those files (:data:`SOURCES`,
director_model/_cache.py).

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

State per body: ``S`` rows of length NS (layout in _common.py). ``mu`` holds
the last velocity multipliers and the position multipliers of each sub-step of the last
steps (force units; layout in :func:`_run_system`): the start values of the next position
multipliers, so a stepper restarted from (S, mu) continues bit for bit.

The step is written out inside :func:`_run_system`: a call with some thirty array arguments
per sub-step cost about 0.4 us (1 body: 540 ns per step with the call, 130 ns without).
Compile time (a cold numba cache) decides how the helpers are joined to it:

- the helpers of every sub-step and Newton iteration (rows, forces, the per-body stages,
  assembly, block and banded solvers, the 3x3 tuple algebra, storing a state) are
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
from numba import njit

from director_model import _cache
from director_model._primitives import quat_matrix
from director_model.system._band5 import (
    _b5_ldl_solve_rr,
    _b5_solve_rr,
    _is_band5,
    _is_revolute5,
    _r5_assemble,
    _r5_forces,
    _r5_rows,
    _r5_vres,
)
from director_model.system._block3 import _forces3, _rows3, _sym_factor, _sym_solve, _vres3
from director_model.system._bodies import (
    _advance,
    _copy_step_state,
    _directors,
    _dmv,
    _dmv_iterate,
    _free_velocity,
    _inv_inertia,
    _inv_inertia_sym,
    _store,
)
from director_model.system._common import (
    D_ITER,
    D_KEPT,
    D_MAXIT,
    D_RANKDROP,
    D_SMIN,
    D_SPLIT,
    D_SVD,
    D_TSMIN,
    EPS,
    FAIL_DAMP,
    FAIL_DMV,
    FAIL_NEWTON,
    FAIL_NONFINITE,
    FAIL_SINGULAR,
    FAIL_SVD,
    MAXIT,
    MAXSPLIT,
    MODE_PIVOTED,
    MODE_SVD,
    NDIAG,
    NS,
    OK,
    PIVOT_CHECK,
    PIVOT_FLOOR,
    SIGMA_LDL,
    SOLVE_TOL,
    STATUS_TEXT,
    _absmax,
    _fail,
    _ftz,
    _mm,
    _mmt,
    _mul,
    _put9,
    _row9,
    _tmul,
    _zero2,
)
from director_model.system._rows import _ext, _forces, _rows, _vres
from director_model.system._sigma import _sym_sigma
from director_model.system._solvers import (
    _assemble,
    _band_ldl,
    _band_ldl_rr,
    _band_ldl_solve,
    _band_ldl_solve_rr,
    _band_lu,
    _band_lu_rr,
    _band_solve,
    _band_solve_rr,
    _blk_assemble,
    _blk_lu,
    _blk_solve,
    _envelope,
    _start_value,
    _svd_factor,
    _svd_solve,
)

#: what director_model.system reads from here (simulate.py, batch.py): the entries, the state
#: width, the tolerances' unit, the status codes and texts, the solver modes, the diagnostics
__all__ = [
    "D_ITER",
    "D_KEPT",
    "D_MAXIT",
    "D_RANKDROP",
    "D_SMIN",
    "D_SPLIT",
    "D_SVD",
    "D_TSMIN",
    "EPS",
    "MODE_PIVOTED",
    "MODE_SVD",
    "NDIAG",
    "NS",
    "OK",
    "SOURCES",
    "STATUS_TEXT",
    "run_system",
    "run_system_banded",
]

_HERE = Path(__file__).parent
#: the files the entries below compile from: their disk cache (and that of the batch kernels,
#: batch.py, which compile them in) is tied to these besides the module's own file
SOURCES = (
    _HERE.parent / "_primitives.py",
    _HERE / "_block3.py",
    _HERE / "_band5.py",
    _HERE / "_common.py",
    _HERE / "_rows.py",
    _HERE / "_solvers.py",
    _HERE / "_bodies.py",
    _HERE / "_sigma.py",
)


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
    # the factorisations' pivot floor: PIVOT_FLOOR with the singular values' check on such a
    # loop, PIVOT_CHECK (the SVD below it) on the others (see PIVOT_CHECK)
    pfl = PIVOT_FLOOR if b5 else PIVOT_CHECK
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
            tol = tol_rel * _directors(S, D0, Dn, Lsc)
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
            ho1 = nr * (1 + j)
            ho2 = nr * (1 + ns + j)
            ho3 = kp0 + nr + 1 + nr * j
            _start_value(mu, nrow, nhist, ho1, ho2, ho3, minnorm, banded, lam)
            if minnorm == MODE_PIVOTED and nrow > 0 and not havepat:
                # no row pattern yet (the first sub-step, or the last velocity stage went to
                # the SVD): that of the velocity stage's matrix at q_n
                _inv_inertia(B, Dn, Mx, Mth)
                _assemble(ptr, idx, side, Jold, Jold, Mx, Mth, Ab, yes, bw, yes)
                st = _band_ldl_rr(Ab, bw, ext, kn, d0, pb, pfl)
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
                err = _absmax(gv, nrow)
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
                            st = _band_lu_rr(Ab, bw, ext, kn, pb, pfl)
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
            _free_velocity(B, WG, PI, Dnew, g, h, hh, RC, TW, VH)
            if nrow > 0 or nfe > 0:
                if banded or minnorm:
                    _inv_inertia(B, Dnew, Mx, Mth)
                else:
                    # the block solver's factorisation is symmetric: Mth from its upper triangle
                    _inv_inertia_sym(B, Dnew, Mx, Mth)
            # the velocity stage's matrix G M^-1 G^T at q_{n+1}, factorised once
            vsvd = False
            if nrow > 0:
                if minnorm:
                    vsvd = minnorm == MODE_SVD
                    vsig = False
                    if not vsvd:
                        if r5:
                            _r5_assemble(jptr, jidx, jside, Jnew, Jnew, Mx, Mth, Ab, bw, yes)
                        else:
                            _assemble(ptr, idx, side, Jnew, Jnew, Mx, Mth, Ab, yes, bw, yes)
                        st = _band_ldl_rr(Ab, bw, ext, kv, d0, pb, pfl)
                        if st < 0:
                            _fail(info, n, h)
                            return FAIL_SVD
                        vsvd = st > 0
                        if not vsvd and b5 and pb[0] < PIVOT_CHECK:
                            # near a singular configuration: the factorisation stands where the
                            # singular values show the rank it kept, the nominal one (see
                            # PIVOT_CHECK)
                            _assemble(ptr, idx, side, Jnew, Jnew, Mx, Mth, Ad, no, bw, no)
                            if _sym_sigma(Ad, sv) < 0:
                                _fail(info, n, h)
                                return FAIL_SVD
                            srank = 0
                            for k in range(nd):
                                if sv[k] > SOLVE_TOL * sv[0]:
                                    srank += 1
                            vsvd = (
                                srank != rank_nom
                                or srank != int(pb[1])
                                or not sv[rank_nom - 1] >= SIGMA_LDL * sv[0]
                            )
                            vsig = True
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
                    elif vsig:
                        # the singular values, from _sym_sigma
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
                    if r5:
                        _r5_vres(rint, Jnew, vel, om, r0)
                    elif banded or minnorm:
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
            if not _advance(S, WG, VH, HK, Fn, Tn, IM, Dn, Dnew, T, RC, g, h, hh):
                _fail(info, n, h)
                return FAIL_NONFINITE

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


_cache.tie(globals(), *SOURCES)
