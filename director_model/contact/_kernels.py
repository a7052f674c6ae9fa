"""Compiled time loop of the contact integrator: RATTLE with frictional contact impulses.

The state of each body (``S`` rows, as in director_model.system): x (0:3) and its Kahan
compensation (3:6), v (6:9) and (9:12), the unnormalised attitude quaternion p (12:16) with
D = D_0 R(p/|p|) and (16:20), the body momentum Pi = I W (20:23) and (23:26).

One step of size h (hh = h/2) from (q_n, v_n), a nonsmooth RATTLE in two stages, each a
frictional contact problem (director_model.contact._solver) on the contacts and joint rows:

1. position stage, at q_n. The half-step velocities
       v_half = v_n + hh (g + F/m) + (impulses)/m,  pi = Pi_n + hh tau_n + D_n^T (angular impulses)
   give x_{n+1} = x_n + h v_half and D_{n+1} = D_n Q, Q from the discrete Moser-Veselov
   equation with pi (director_model._primitives.dmv_solve). The rows' rates are those of
   the linear velocities (v_half, w_half = D_n I^-1 pi); their targets make the step exact
   at position level: a contact's normal row asks gap(q_{n+1}) >= 0 complementary to its
   impulse, a joint row g(q_{n+1}) = 0, where gap(q_{n+1}) = gap_n + h u_n + c and c, the
   part of the gap's change that the rotation's curvature adds (O(h^2)), is taken from the
   last iterate of this stage until it no longer changes (the outer loop, at most
   OUTER_MAX passes; one pass when no row depends on a rotation). Tangent rows: Coulomb's
   law with the slip velocity of the contact point.
2. velocity stage, at q_{n+1}. v_{n+1} = v_half + hh (g + F/m) + impulses/m, Pi_{n+1} = Q^T pi
   + hh tau_{n+1} + angular impulses, on the contacts closed at q_{n+1} (an impulse in the
   position stage, or a gap below the length tolerance): Newton's impact law
   u_n >= -e min(u_n^-, 0) complementary to the normal impulse (u_n^- the normal velocity of
   the contact point at the start of the step: 0 for a resting contact, the approach speed at
   an impact), Coulomb on the tangent rows, joint rows at velocity level.

Without contacts and joints both stages are empty and the step is the single-body RATTLE step
(the same primitives and the same sums, director_model._kernels), so the attitude and the
angular velocity of a body that touches nothing are bit for bit those of
director_model.simulate; its centre of mass is stepped (that path evaluates free flight in
closed form), equal to round-off.

Candidates: the features of a pair whose bounding spheres come within a margin of the motion
over the step (2 h x the speeds of the shapes' points, plus h^2 |g| and the length
tolerance), and whose own distance is below it. After the position stage every feature of a
near pair is checked at q_{n+1}: one that would overlap without being a candidate is added
and the step redone (at most REDO_MAX times).

Rows: a stage's rows (their directions, mobilities M^-1 J^T and Delassus operator) are those
built last while the contacts are the same features and their geometry is the same to
round-off (_stage_rows._rows_valid: directions and directors within 8 eps, contact points within
8 eps of the scene's length; joint rows only at the same state exactly): a resting or
sticking configuration builds them once for many steps. Each stage keeps the factors of its
last full solve for chord steps at the next steps (_parts._stage_solve), and the bodies'
response to its last impulses: a step that starts from them with the same rows evaluates its
residual without going through the bodies again (_parts._eval).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from director_model import _cache
from director_model._primitives import OK as DMV_OK
from director_model._primitives import kahan, kahan4, quat_increment, quat_matrix
from director_model.contact import _geometry as G
from director_model.contact._parts import (
    FAIL_DMV,
    FAIL_INEXACT,
    FAIL_NONFINITE,
    FAIL_OUTER,
    FAIL_PENETRATION,
    I_FEATURE,
    I_PAIR,
    I_RES,
    I_STEPS,
    LEN_TOL,
    NQ,
    NS,
    OK,
    OUTER_MAX,
    Q_ITER,
    Q_NCON,
    Q_OUTER,
    Q_PEN,
    Q_RES,
    Q_SIG,
    Q_WORK,
    REDO_MAX,
    _candidates,
    _dmv,
    _laws,
    _loads,
    _omega_half,
    _onb,
    _rate,
    _same_list,
    _set_directors,
    _stage_solve,
    _store,
    _world_omega,
)  # fmt: skip
from director_model.contact._stage_rows import (
    _fit_gaps,
    _rows_record,
    _rows_valid,
    _setup_rows,
    joint_rows,
)


@njit(cache=True)
def run_contact(B, SH, D0, S, WS, WJ, FI, FV, PI, PV, rint, rvec, fb, fv, g, dt, nstep, saves,
                X, V, D, W, Q, PF, info):  # fmt: skip
    """Advance nstep steps of dt; store the states at the step indices ``saves`` (0 = the
    start) into X, V (nsave, nb, 3), D (nsave, nb, 3, 3), W (nsave, nb, 3) (body axes), the
    diagnostics since the previous save into Q (nsave, NQ) and the contact force on body a of
    each pair in the saved step into PF (nsave, npair, 3). WS (nfeat, 6) and WJ (nrow, 2)
    hold the last impulses of each feature and joint row (position stage, velocity stage):
    the start values of the next step, part of the integrator state. Returns a status; on a
    failure S, WS, WJ keep the last completed step and info says where it failed."""
    nb = S.shape[0]
    nf = FI.shape[0]
    nj = rint.shape[0]
    npair = PI.shape[0]
    Nmax = 3 * nf + nj
    Nm = max(Nmax, 1)
    h = dt
    hh = 0.5 * h
    rh = 4.0 / h
    # work arrays
    Dm = np.empty((nb, 9))
    DN = np.empty((nb, 9))
    Fs = np.zeros((nb, 3))
    Tb = np.zeros((nb, 3))
    Tb1 = np.zeros((nb, 3))
    VF = np.empty((nb, 3))
    PIF = np.empty((nb, 3))
    OF = np.empty((nb, 3))
    ON = np.empty((nb, 3))
    VH = np.empty((nb, 3))
    PIH = np.empty((nb, 3))
    XN = np.empty((nb, 3))
    XL = np.empty((nb, 3))
    PN = np.empty((nb, 4))
    PL = np.empty((nb, 4))
    WQ = np.empty((nb, 5))  # w (3), q, 4/(q h)
    CQ = np.empty((nb, 3))  # c = w x I w
    DV = np.zeros((nb, 3))
    BA = np.zeros((nb, 12))
    DW = np.zeros((nb, 3))
    DL = np.zeros((nb, 3))
    DV1 = np.zeros((nb, 3))
    DL1 = np.zeros((nb, 3))
    VF1 = np.empty((nb, 3))
    OF1 = np.empty((nb, 3))
    marg = np.zeros(npair)
    cand = np.zeros(max(nf, 1), dtype=np.int64)
    cb = np.zeros((max(nf, 1), 2), dtype=np.int64)
    cg = np.zeros((max(nf, 1), 16))
    cand2 = np.zeros(max(nf, 1), dtype=np.int64)
    cb2 = np.zeros((max(nf, 1), 2), dtype=np.int64)
    cg2 = np.zeros((max(nf, 1), 16))
    cgN = np.zeros((max(nf, 1), 16))
    inexN = np.zeros(max(nf, 1), dtype=np.bool_)
    isc = np.zeros(max(nf, 1), dtype=np.bool_)
    fidx = np.zeros(max(nf, 1), dtype=np.int64)
    FO = np.zeros((max(nf, 1), 13))
    grp = np.zeros(max(nf, 1), dtype=np.int64)
    # the kept factorisations of the two stages (see _stage_solve)
    LUP = np.zeros((Nm, Nm))
    LUV = np.zeros((Nm, Nm))
    pivP = np.zeros(Nm, dtype=np.int64)
    pivV = np.zeros(Nm, dtype=np.int64)
    patP = np.zeros(max(nf, 1), dtype=np.int64)
    patV = np.zeros(max(nf, 1), dtype=np.int64)
    pat = np.zeros(max(nf, 1), dtype=np.int64)
    listP = np.full(max(nf, 1), -1, dtype=np.int64)
    listV = np.full(max(nf, 1), -1, dtype=np.int64)
    metaP = np.zeros(7, dtype=np.int64)
    metaV = np.zeros(7, dtype=np.int64)
    metaP[4] = -1
    metaV[4] = -1
    # each stage's record of the bodies' response to its last impulses (_parts._eval)
    BAV = np.zeros((nb, 12))
    PZP = np.zeros(Nm)
    TZP = np.zeros(Nm)
    zcP = np.zeros(Nm)
    PZV = np.zeros(Nm)
    TZV = np.zeros(Nm)
    zcV = np.zeros(Nm)
    rver = 0  # the rows' version: + 1 whenever they are rebuilt
    luflag = np.zeros(1, dtype=np.int64)
    Jr = np.zeros((Nm, 12))
    rb_ = np.zeros((Nm, 2), dtype=np.int64)
    Y = np.zeros((Nm, 12))
    Wd = np.zeros((Nm, Nm))
    # what the rows (Jr, rb_, Y, rho, Wd) were built from (see _rows_valid); wflag[0] = 1
    # once Wd is built from them
    rm = np.full(1, -1, dtype=np.int64)
    candR = np.zeros(max(nf, 1), dtype=np.int64)
    cgR = np.zeros((max(nf, 1), 16))
    XR = np.zeros((nb, 3))
    DR = np.zeros((nb, 9))
    wflag = np.zeros(1, dtype=np.int64)
    m2 = 0
    P8 = np.zeros((8, 4))
    A = np.zeros((Nm, Nm))
    b = np.zeros(Nm)
    u0 = np.zeros(Nm)
    off = np.zeros(Nm)
    corr = np.zeros(Nm)
    g0 = np.zeros(Nm)
    z = np.zeros(Nm)
    z1 = np.zeros(Nm)
    u = np.zeros(Nm)
    F = np.zeros(Nm)
    dz = np.zeros(Nm)
    zt = np.zeros(Nm)
    ut = np.zeros(Nm)
    Ft = np.zeros(Nm)
    ts = np.zeros(Nm)
    tst = np.zeros(Nm)
    zb = np.zeros(Nm)
    zbar = np.zeros(Nm)
    piv = np.zeros(Nm, dtype=np.int64)
    mu = np.zeros(max(nf, 1))
    rho = np.zeros(Nm)
    gvj = np.zeros(max(nj, 1))
    Jj = np.zeros((max(nj, 1), 12))
    Qs = np.zeros(NQ)
    Ls = np.zeros(3)
    PFs = np.zeros((npair, 3))
    gn = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    Lsc = 1.0
    for p in range(npair):
        Lsc = max(Lsc, PV[p, 2], PV[p, 3])
    ks = 0
    if saves.shape[0] > 0 and saves[0] == 0:
        _store(B, D0, S, X, V, D, W, 0)
        ks = 1
    for n in range(1, nstep + 1):
        _set_directors(D0, S, Dm)
        _loads(B, fb, fv, Dm, Fs, Tb)
        xmax = Lsc
        for i in range(nb):
            im = 1.0 / B[i, 0]
            for c in range(3):
                VF[i, c] = S[i, 6 + c] + hh * (g[c] + Fs[i, c] * im)
                PIF[i, c] = S[i, 20 + c] + hh * Tb[i, c]
                xmax = max(xmax, abs(S[i, c]))
            o = _world_omega(B, Dm, i, PIF[i, 0], PIF[i, 1], PIF[i, 2])
            OF[i, 0], OF[i, 1], OF[i, 2] = o
            o = _world_omega(B, Dm, i, S[i, 20], S[i, 21], S[i, 22])
            ON[i, 0], ON[i, 1], ON[i, 2] = o
        ltol = LEN_TOL * xmax
        mfac = 1.0
        st = OK
        for redo in range(REDO_MAX + 1):  # noqa: B007
            # candidates and their margins
            for p in range(npair):
                a = PI[p, 1]
                bb = PI[p, 2]
                sa = math.sqrt(VF[a, 0] ** 2 + VF[a, 1] ** 2 + VF[a, 2] ** 2) + PV[
                    p, 2
                ] * math.sqrt(OF[a, 0] ** 2 + OF[a, 1] ** 2 + OF[a, 2] ** 2)
                sb = 0.0
                if PI[p, 0] != 0:
                    sb = math.sqrt(VF[bb, 0] ** 2 + VF[bb, 1] ** 2 + VF[bb, 2] ** 2) + PV[
                        p, 3
                    ] * math.sqrt(OF[bb, 0] ** 2 + OF[bb, 1] ** 2 + OF[bb, 2] ** 2)
                marg[p] = mfac * (2.0 * h * (sa + sb) + 2.0 * h * h * gn) + ltol
            st, nc, fp, ff = _candidates(
                FI, FV, PI, PV, SH, S, Dm, marg, cand, cb, cg, P8, fidx, FO
            )
            if st != OK:
                info[I_PAIR] = fp
                info[I_FEATURE] = ff
                break
            for f in range(nf):
                isc[f] = False
            for c in range(nc):
                isc[cand[c]] = True
            m = nc
            N = 3 * m + nj
            # the rows at q_n: those built last (by the last velocity stage, at this state,
            # or earlier) if they are these contacts' to round-off, else computed
            if _rows_valid(m, cand, cg, S, Dm, nj, Lsc, rm, candR, cgR, XR, DR):
                if nj > 0:
                    joint_rows(rint, rvec, S, Dm, gvj, Jj)
            else:
                _setup_rows(m, nj, cb, cg, rint, rvec, S, Dm, B, gvj, Jj, Jr, rb_, Y, rho)
                _rows_record(m, cand, cg, S, Dm, rm, candR, cgR, XR, DR)
                wflag[0] = 0
                rver += 1
            for c in range(m):
                f = cand[c]
                mu[c] = PV[FI[f, 3], 0]
                g0[3 * c] = cg[c, 0]
                g0[3 * c + 1] = 0.0
                g0[3 * c + 2] = 0.0
            for r in range(N):
                u0[r] = _rate(Jr, rb_, r, VF, OF)
                corr[r] = 0.0
            for r in range(nj):
                g0[3 * m + r] = gvj[r]
            _fit_gaps(m, cand, cb, cg, FI, S, g0, grp)
            # start values
            for c in range(m):
                f = cand[c]
                z[3 * c] = WS[f, 0]
                z[3 * c + 1] = WS[f, 1]
                z[3 * c + 2] = WS[f, 2]
            for r in range(nj):
                z[3 * m + r] = WJ[r, 0]
            passes = 0
            converged = False
            for _ in range(OUTER_MAX):
                passes += 1
                for r in range(N):
                    off[r] = 0.0
                for c in range(m):
                    off[3 * c] = (g0[3 * c] + corr[3 * c]) / h
                    off[3 * c + 1] = corr[3 * c + 1] / h
                    off[3 * c + 2] = corr[3 * c + 2] / h
                for r in range(nj):
                    off[3 * m + r] = (g0[3 * m + r] + corr[3 * m + r]) / h
                for r in range(N):
                    b[r] = u0[r] + off[r]
                same = _same_list(m, cand, listP, metaP)
                st, it, rr = _stage_solve(
                    m, nj, mu, rho, Jr, rb_, Y, Wd, b, z, u, F, A, dz, zt, ut, Ft, piv, nb, DV,
                    DW, DL, wflag, ts, tst, zb, zbar, BA, LUP, pivP, patP, pat, metaP, same,
                    luflag, PZP, TZP, zcP, rver,
                )  # fmt: skip
                Qs[Q_ITER] = max(Qs[Q_ITER], it)
                Qs[Q_RES] = max(Qs[Q_RES], rr)
                if st != OK:
                    info[I_RES] = rr
                    break
                # the step's positions for these impulses
                dmv_fail = False
                for i in range(nb):
                    I0, I1, I2 = B[i, 1], B[i, 2], B[i, 3]
                    a0, a1, a2 = B[i, 4], B[i, 5], B[i, 6]
                    lb0, lb1, lb2 = G.to_body(Dm, i, DL[i, 0], DL[i, 1], DL[i, 2])
                    PIH[i, 0] = PIF[i, 0] + lb0
                    PIH[i, 1] = PIF[i, 1] + lb1
                    PIH[i, 2] = PIF[i, 2] + lb2
                    sd_, w0, w1, w2, c0, c1, c2, q = _dmv(
                        I0, I1, I2, a0, a1, a2,
                        (I2 - I1) * a0, (I0 - I2) * a1, (I1 - I0) * a2,
                        hh * PIH[i, 0], hh * PIH[i, 1], hh * PIH[i, 2],
                    )  # fmt: skip
                    if sd_ != DMV_OK:
                        dmv_fail = True
                        break
                    WQ[i, 0], WQ[i, 1], WQ[i, 2], WQ[i, 3] = w0, w1, w2, q
                    CQ[i, 0], CQ[i, 1], CQ[i, 2] = c0, c1, c2
                    for c in range(3):
                        VH[i, c] = VF[i, c] + DV[i, c]
                        XN[i, c], XL[i, c] = kahan(S[i, c], S[i, 3 + c], h * VH[i, c], True)
                    pp = (S[i, 12], S[i, 13], S[i, 14], S[i, 15])
                    pn, pln = kahan4(pp, (S[i, 16], S[i, 17], S[i, 18], S[i, 19]),
                                     quat_increment(pp, (w0, w1, w2)), True)  # fmt: skip
                    for c in range(4):
                        PN[i, c] = pn[c]
                        PL[i, c] = pln[c]
                    R = quat_matrix(pn)
                    for c in range(9):
                        rr3 = c // 3
                        cc3 = c % 3
                        DN[i, c] = (D0[i, 3 * rr3] * R[cc3] + D0[i, 3 * rr3 + 1] * R[3 + cc3]) + D0[
                            i, 3 * rr3 + 2
                        ] * R[6 + cc3]
                if dmv_fail:
                    st = FAIL_DMV
                    break
                # actual gaps and joint rows at q_{n+1} against the linear prediction h u
                dmax = 0.0
                G.eval_features(FI, FV, cand, m, XN, DN, FO)
                for c in range(m):
                    gap = FO[c, 2]
                    d = gap - h * u[3 * c]
                    corr[3 * c] += d
                    if z[3 * c] > 0.0 or gap < 0.0:
                        dmax = max(dmax, abs(d))
                    # the geometry at q_{n+1}, for the velocity stage
                    t_, s_ = _onb(FO[c, 3], FO[c, 4], FO[c, 5])
                    cgN[c, 0] = gap
                    cgN[c, 1], cgN[c, 2], cgN[c, 3] = FO[c, 3], FO[c, 4], FO[c, 5]
                    cgN[c, 4], cgN[c, 5], cgN[c, 6] = t_[0], t_[1], t_[2]
                    cgN[c, 7], cgN[c, 8], cgN[c, 9] = s_[0], s_[1], s_[2]
                    for k in range(6):
                        cgN[c, 10 + k] = FO[c, 6 + k]
                    inexN[c] = FO[c, 1] != 0.0
                    if FI[cand[c], 0] == G.K_PLANE_VERTEX or FI[cand[c], 0] == G.K_BOX_VERTEX:
                        # a vertex is a material point: its tangential displacement over the
                        # step against the linear prediction h u_t (the rotation's curvature,
                        # O(h^2)), so that a sticking vertex stays exactly in place
                        s1, s2 = _vertex_slip(c, cb, cg, Dm, DN, VH, h)
                        for q in range(1, 3):
                            d = (s1 if q == 1 else s2) - h * u[3 * c + q]
                            corr[3 * c + q] += d
                            if z[3 * c] > 0.0:
                                dmax = max(dmax, abs(d))
                if nj > 0:
                    joint_rows(rint, rvec, XN, DN, gvj, Jj)
                    for r in range(nj):
                        d = gvj[r] - h * u[3 * m + r]
                        corr[3 * m + r] += d
                        dmax = max(dmax, abs(d))
                if not dmax <= ltol:
                    if not dmax < math.inf:
                        st = FAIL_NONFINITE
                        break
                    continue
                converged = True
                break
            if st != OK:
                break
            if not converged:
                st = FAIL_OUTER
                break
            Qs[Q_OUTER] = max(Qs[Q_OUTER], passes)
            # a feature that is not a candidate must not overlap at q_{n+1}
            missed = False
            nq = 0
            for p in range(npair):
                a = PI[p, 1]
                bb = PI[p, 2]
                # the motion of the pair's points over the step: if below the margin, no
                # feature that was farther than the margin can have closed
                mv = h * (math.sqrt(VH[a, 0] ** 2 + VH[a, 1] ** 2 + VH[a, 2] ** 2)
                          + PV[p, 2] * _omega_half(B, Dm, PIH, a))  # fmt: skip
                if PI[p, 0] != 0:
                    mv += h * (math.sqrt(VH[bb, 0] ** 2 + VH[bb, 1] ** 2 + VH[bb, 2] ** 2)
                               + PV[p, 3] * _omega_half(B, Dm, PIH, bb))  # fmt: skip
                if 2.0 * mv < marg[p] - ltol:
                    continue
                if PI[p, 0] != 0:
                    d0, d1, d2 = XN[a, 0] - XN[bb, 0], XN[a, 1] - XN[bb, 1], XN[a, 2] - XN[bb, 2]
                    if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) > PV[p, 2] + PV[p, 3]:
                        continue  # the bounding spheres do not overlap at q_{n+1}
                for f in range(PI[p, 3], PI[p, 3] + PI[p, 4]):
                    if not isc[f]:
                        fidx[nq] = f
                        nq += 1
            G.eval_features(FI, FV, fidx, nq, XN, DN, FO)
            for q in range(nq):
                if FO[q, 0] != 0.0 and FO[q, 2] < -ltol:
                    missed = True
                    info[I_PAIR] = FI[fidx[q], 3]
                    info[I_FEATURE] = fidx[q]
            if not missed:
                break
            mfac *= 8.0
            st = FAIL_PENETRATION
        if st != OK:
            info[I_STEPS] = n - 1
            return st
        # work of the position stage's contact impulses
        work = 0.0
        for r in range(3 * m):
            work += z[r] * (u0[r] + 0.5 * (u[r] - off[r] - u0[r]))
        _laws(m, mu, rho, z, u, Lsc / h, Ls)
        for k in range(3):
            Qs[Q_SIG + k] = max(Qs[Q_SIG + k], Ls[k])
            Ls[k] = 0.0
        for p in range(npair):
            PFs[p, 0] = 0.0
            PFs[p, 1] = 0.0
            PFs[p, 2] = 0.0
        for c in range(m):
            p = FI[cand[c], 3]
            for k in range(3):
                PFs[p, k] += (z[3 * c] * cg[c, 1 + k] + z[3 * c + 1] * cg[c, 4 + k]
                              + z[3 * c + 2] * cg[c, 7 + k]) / h  # fmt: skip
        # -------------------------------------------------------------- velocity stage
        _loads(B, fb, fv, DN, Fs, Tb1)
        m2 = 0
        for c in range(m):
            if z[3 * c] > 0.0 or cgN[c, 0] <= ltol:
                if inexN[c]:
                    info[I_STEPS] = n - 1
                    info[I_FEATURE] = cand[c]
                    return FAIL_INEXACT
                cand2[m2] = cand[c]
                cb2[m2, 0] = cb[c, 0]
                cb2[m2, 1] = cb[c, 1]
                for k in range(16):
                    cg2[m2, k] = cgN[c, k]
                m2 += 1
        pen = 0.0
        for c in range(m2):
            pen = max(pen, -cg2[c, 0])
        Qs[Q_PEN] = max(Qs[Q_PEN], pen)
        N2 = 3 * m2 + nj
        # the rows at q_{n+1}: the position stage's if they are these contacts' to round-off
        if not _rows_valid(m2, cand2, cg2, XN, DN, nj, Lsc, rm, candR, cgR, XR, DR):
            _setup_rows(m2, nj, cb2, cg2, rint, rvec, XN, DN, B, gvj, Jj, Jr, rb_, Y, rho)
            _rows_record(m2, cand2, cg2, XN, DN, rm, candR, cgR, XR, DR)
            wflag[0] = 0
            rver += 1
        for i in range(nb):
            im = 1.0 / B[i, 0]
            rq = rh * (1.0 / WQ[i, 3])
            P0 = PIH[i, 0] - rq * CQ[i, 0] + hh * Tb1[i, 0]
            P1 = PIH[i, 1] - rq * CQ[i, 1] + hh * Tb1[i, 1]
            P2 = PIH[i, 2] - rq * CQ[i, 2] + hh * Tb1[i, 2]
            o = _world_omega(B, DN, i, P0, P1, P2)
            OF1[i, 0], OF1[i, 1], OF1[i, 2] = o
            for c in range(3):
                VF1[i, c] = VH[i, c] + hh * (g[c] + Fs[i, c] * im)
        Vn = S[:, 6:9]
        for c in range(m2):
            f = cand2[c]
            mu[c] = PV[FI[f, 3], 0]
            upre = _rate(Jr, rb_, 3 * c, Vn, ON)
            off[3 * c] = PV[FI[f, 3], 1] * min(upre, 0.0)
            off[3 * c + 1] = 0.0
            off[3 * c + 2] = 0.0
            z1[3 * c] = WS[f, 3]
            z1[3 * c + 1] = WS[f, 4]
            z1[3 * c + 2] = WS[f, 5]
        for r in range(nj):
            off[3 * m2 + r] = 0.0
            z1[3 * m2 + r] = WJ[r, 1]
        for r in range(N2):
            u0[r] = _rate(Jr, rb_, r, VF1, OF1)
            b[r] = u0[r] + off[r]
        same = _same_list(m2, cand2, listV, metaV)
        st, it, rr = _stage_solve(
            m2, nj, mu, rho, Jr, rb_, Y, Wd, b, z1, u, F, A, dz, zt, ut, Ft, piv, nb, DV1, DW,
            DL1, wflag, ts, tst, zb, zbar, BAV, LUV, pivV, patV, pat, metaV, same, luflag,
            PZV, TZV, zcV, rver,
        )  # fmt: skip
        Qs[Q_ITER] = max(Qs[Q_ITER], it)
        Qs[Q_RES] = max(Qs[Q_RES], rr)
        if st != OK:
            info[I_STEPS] = n - 1
            info[I_RES] = rr
            return st
        for r in range(3 * m2):
            work += z1[r] * (u0[r] + 0.5 * (u[r] - off[r] - u0[r]))
        Qs[Q_WORK] = max(Qs[Q_WORK], work) if n > 1 or ks > 0 else work
        vs = gn * h
        for r in range(N2):
            vs = max(vs, abs(u0[r]))
        _laws(m2, mu, rho, z1, u, vs if vs > 0.0 else 1.0, Ls)
        for k in range(3):
            Qs[Q_SIG + k] = max(Qs[Q_SIG + k], Ls[k])
            Ls[k] = 0.0
        for c in range(m2):
            p = FI[cand2[c], 3]
            for k in range(3):
                PFs[p, k] += (z1[3 * c] * cg2[c, 1 + k] + z1[3 * c + 1] * cg2[c, 4 + k]
                              + z1[3 * c + 2] * cg2[c, 7 + k]) / h  # fmt: skip
        # -------------------------------------------------------------- commit
        for i in range(nb):
            im = 1.0 / B[i, 0]
            rq = rh * (1.0 / WQ[i, 3])
            lp0, lp1, lp2 = G.to_body(Dm, i, DL[i, 0], DL[i, 1], DL[i, 2])
            lv0, lv1, lv2 = G.to_body(DN, i, DL1[i, 0], DL1[i, 1], DL1[i, 2])
            dP0 = ((hh * (Tb[i, 0] + Tb1[i, 0]) - rq * CQ[i, 0]) + lp0) + lv0
            dP1 = ((hh * (Tb[i, 1] + Tb1[i, 1]) - rq * CQ[i, 1]) + lp1) + lv1
            dP2 = ((hh * (Tb[i, 2] + Tb1[i, 2]) - rq * CQ[i, 2]) + lp2) + lv2
            S[i, 20], S[i, 23] = kahan(S[i, 20], S[i, 23], dP0, True)
            S[i, 21], S[i, 24] = kahan(S[i, 21], S[i, 24], dP1, True)
            S[i, 22], S[i, 25] = kahan(S[i, 22], S[i, 25], dP2, True)
            for c in range(3):
                a_ = hh * (g[c] + Fs[i, c] * im)
                dv = (a_ + DV[i, c]) + (a_ + DV1[i, c])
                S[i, 6 + c], S[i, 9 + c] = kahan(S[i, 6 + c], S[i, 9 + c], dv, True)
                S[i, c] = XN[i, c]
                S[i, 3 + c] = XL[i, c]
            for c in range(4):
                S[i, 12 + c] = PN[i, c]
                S[i, 16 + c] = PL[i, c]
            nn = (S[i, 12] ** 2 + S[i, 13] ** 2) + (S[i, 14] ** 2 + S[i, 15] ** 2)
            if nn > 2.0**128:
                for c in range(12, 20):
                    S[i, c] *= 2.0**-64
            for c in range(NS):
                if not abs(S[i, c]) < math.inf:
                    info[I_STEPS] = n - 1
                    return FAIL_NONFINITE
        for f in range(nf):
            for k in range(6):
                WS[f, k] = 0.0
        for c in range(m):
            f = cand[c]
            WS[f, 0] = z[3 * c]
            WS[f, 1] = z[3 * c + 1]
            WS[f, 2] = z[3 * c + 2]
        for c in range(m2):
            f = cand2[c]
            WS[f, 3] = z1[3 * c]
            WS[f, 4] = z1[3 * c + 1]
            WS[f, 5] = z1[3 * c + 2]
        for r in range(nj):
            WJ[r, 0] = z[3 * m + r]
            WJ[r, 1] = z1[3 * m2 + r]
        if ks < saves.shape[0] and saves[ks] == n:
            _store(B, D0, S, X, V, D, W, ks)
            Qs[Q_NCON] = m2
            for k in range(NQ):
                Q[ks, k] = Qs[k]
                Qs[k] = 0.0
            for p in range(npair):
                for k in range(3):
                    PF[ks, p, k] = PFs[p, k]
            ks += 1
    return OK


@njit(inline="always")
def _vertex_slip(c, cb, cg, Dm, DN, VH, h):
    """Displacement over the step, along the tangents t1 and t2 of contact c, of the material
    point of body a at the contact relative to that of body b (none for a plane): h v_half
    plus the directors' change applied to the point's body-frame offset."""
    s1 = 0.0
    s2 = 0.0
    for side in range(2):
        i = cb[c, side]
        if i < 0:
            continue
        r0, r1, r2 = cg[c, 10 + 3 * side], cg[c, 11 + 3 * side], cg[c, 12 + 3 * side]
        x0, x1, x2 = G.to_body(Dm, i, r0, r1, r2)
        p0, p1, p2 = G.body_point(VH, DN, i, x0, x1, x2)
        e0 = h * VH[i, 0] + p0 - r0
        e1 = h * VH[i, 1] + p1 - r1
        e2 = h * VH[i, 2] + p2 - r2
        d1 = cg[c, 4] * e0 + cg[c, 5] * e1 + cg[c, 6] * e2
        d2 = cg[c, 7] * e0 + cg[c, 8] * e1 + cg[c, 9] * e2
        s1 += d1 if side == 0 else -d1
        s2 += d2 if side == 0 else -d2
    return s1, s2


@njit(cache=True, parallel=True)
def run_contact_batch(B, SH, D0, S, WS, WJ, FI, FV, PI, PV, rint, rvec, fb, fv, g, dt, nstep,
                      saves, X, V, D, W, Q, PF, info, status):  # fmt: skip
    """N scenes of one structure (arrays with a leading batch axis: D0, S, WS, WJ, X, V, D,
    W, Q, PF, info), each its own :func:`run_contact`, in parallel over numba's threads."""
    for k in prange(S.shape[0]):
        status[k] = run_contact(B, SH, D0[k], S[k], WS[k], WJ[k], FI, FV, PI, PV, rint, rvec,
                                 fb, fv, g, dt, nstep, saves, X[k], V[k], D[k], W[k], Q[k], PF[k],
                                 info[k])  # fmt: skip


@njit(cache=True)
def features_at(FI, FV, PI, PV, SH, X, Dm, margin, out, status):
    """Every feature at the state (X, Dm) (for the checks of the initial state): out (nfeat,
    4) = valid, inexact, gap, distance; status (npair,) 1 where a box-box pair within
    ``margin`` is not treated exactly."""
    P8 = np.zeros((8, 4))
    for p in range(PI.shape[0]):
        status[p] = 0
        if PI[p, 0] == 2:
            a = PI[p, 1]
            b = PI[p, 2]
            near, exact = G.box_pair_check(X, Dm, a, b, (SH[a, 1], SH[a, 2], SH[a, 3]),
                                           (SH[b, 1], SH[b, 2], SH[b, 3]), margin, P8)  # fmt: skip
            if near and not exact:
                status[p] = 1
    nf = FI.shape[0]
    idx = np.arange(nf)
    FO = np.zeros((nf, 13))
    G.eval_features(FI, FV, idx, nf, X, Dm, FO)
    for f in range(nf):
        out[f, 0] = FO[f, 0]
        out[f, 1] = FO[f, 1]
        out[f, 2] = FO[f, 2]
        out[f, 3] = FO[f, 12]


_cache.tie(
    globals(),
    *[
        __import__("pathlib").Path(__file__).parent.parent / rel
        for rel in (
            "_primitives.py",
            "system/_rows.py",
            "system/_common.py",
            "system/_block3.py",
            "contact/_geometry.py",
            "contact/_parts.py",
            "contact/_stage_rows.py",
            "contact/_solver.py",
        )
    ],
)
