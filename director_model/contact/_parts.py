"""Compiled pieces of the contact step (director_model.contact._kernels): the state's
layout and status codes, one stage's solve, the law residuals and the candidate search; the
rows of the contacts and joints and the Delassus operator are in _stage_rows, the loop and its
cached entries in _kernels.

Compile cost (benchmarks/bench_contact_compile.py): numba compiles each ``@njit`` function
that is called (not inlined) to its own LLVM module, and when it links a callee's module into
its caller's it runs the full optimisation over the linked whole again: every level of
calls re-optimises everything below it. So the helpers called per row or per contact, and
those with one call site, are inlined in numba's IR (``inline="always"``: no module of their
own, typed at their call site); the few larger pieces called from several places
(:func:`_setup_rows`, :func:`_stage_solve`, :func:`_eval`, :func:`_laws`, :func:`_candidates`,
the solver's Newton method) are compiled once each, and the call tree is kept shallow.

Reference counting: those pieces (and the solver's, and _geometry.eval_features) take only
arrays that the time loop allocated and allocate none, so they are compiled without numba's
runtime (``_nrt=False``, numba's option for code that needs no reference counting): with it,
every array argument of a compiled call and of each helper inlined into one is an atomic
increment and decrement, 10-13 % of the step of a stack of three boxes (perf samples in
numba's NRT_incref/NRT_decref)."""

from __future__ import annotations

import math

from numba import njit

from director_model._primitives import dmv_solve, quat_matrix
from director_model.contact import _geometry as G
from director_model.contact._solver import RES_TOL, ac_residual, lu_apply, pattern, scale_of
from director_model.contact._solver import solve as ac_solve
from director_model.contact._stage_rows import _delassus

NS = 26
EPS = 2.220446049250313e-16
OUTER_MAX = 30
REDO_MAX = 3
#: chord Newton steps with a kept factorisation before the full solver
CHORD = 3
#: a kept factorisation whose smallest pivot is below SINGULAR x its largest is of redundant
#: rows (a singular Delassus operator, kept regular by the solver's shift >= 1e-9)
SINGULAR = 1e-6
#: length tolerance: max(|x|, L) x LEN_TOL (m), for gaps (a closed contact), the outer loop
#: and the penetration check
LEN_TOL = 16.0 * EPS

OK = 0
FAIL_SOLVE = 1
FAIL_OUTER = 2
FAIL_INEXACT = 3
FAIL_PENETRATION = 4
FAIL_DMV = 5
FAIL_NONFINITE = 6

STATUS_TEXT = {
    FAIL_SOLVE: "the frictional contact problem did not converge to its certified residual "
    "within the iteration cap",
    FAIL_OUTER: "the position stage's gaps did not settle (rotation curvature correction) "
    "within the iteration cap",
    FAIL_INEXACT: "a contact configuration that the scheme does not treat exactly",
    FAIL_PENETRATION: "a contact that was not a candidate would overlap after the step, even "
    "after redoing it",
    FAIL_DMV: "a body's rotation equation (discrete Moser-Veselov) has no admissible solution "
    "(a rotation of 90 degrees or more in one step)",
    FAIL_NONFINITE: "a non-finite number appeared in the state",
}

# per-save diagnostics (Q columns)
Q_PEN = 0  # largest penetration max(-gap) of a closed contact over the steps since the last save
Q_SIG = 1  # largest Signorini residual
Q_COUL = 2  # largest Coulomb (cone) residual
Q_DISS = 3  # largest maximum-dissipation residual
Q_WORK = 4  # largest work of the contact impulses in one step (J; > 0 is energy gained)
Q_ITER = 5  # largest number of Newton iterations of one stage
Q_RES = 6  # largest certified residual of a stage (relative to its impulse scale)
Q_NCON = 7  # contacts closed at the saved step
Q_OUTER = 8  # largest number of position-stage passes
NQ = 9

# info slots on failure
I_STEPS = 0
I_PAIR = 1
I_FEATURE = 2
I_RES = 3
NINFO = 4


@njit(_nrt=False)
def _dmv(I0, I1, I2, a0, a1, a2, ae0, ae1, ae2, b0, b1, b2):
    """director_model._primitives.dmv_solve, compiled once (its IR-level inlining happens
    here, not at the kernel's call site: numba types an inlined body again at each site)."""
    return dmv_solve(I0, I1, I2, a0, a1, a2, ae0, ae1, ae2, b0, b1, b2)


@njit(inline="always")
def _onb(n0, n1, n2):
    """Two unit tangents completing the unit normal n (Duff et al., JCGT 6(1), 2017)."""
    s = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (s + n2)
    b = n0 * n1 * a
    return (1.0 + s * n0 * n0 * a, s * b, -s * n0), (b, s + n1 * n1 * a, -n1)


@njit(inline="always")
def _directors(D0, S, i):
    R = quat_matrix((S[i, 12], S[i, 13], S[i, 14], S[i, 15]))
    return (
        D0[i, 0] * R[0] + D0[i, 1] * R[3] + D0[i, 2] * R[6],
        D0[i, 0] * R[1] + D0[i, 1] * R[4] + D0[i, 2] * R[7],
        D0[i, 0] * R[2] + D0[i, 1] * R[5] + D0[i, 2] * R[8],
        D0[i, 3] * R[0] + D0[i, 4] * R[3] + D0[i, 5] * R[6],
        D0[i, 3] * R[1] + D0[i, 4] * R[4] + D0[i, 5] * R[7],
        D0[i, 3] * R[2] + D0[i, 4] * R[5] + D0[i, 5] * R[8],
        D0[i, 6] * R[0] + D0[i, 7] * R[3] + D0[i, 8] * R[6],
        D0[i, 6] * R[1] + D0[i, 7] * R[4] + D0[i, 8] * R[7],
        D0[i, 6] * R[2] + D0[i, 7] * R[5] + D0[i, 8] * R[8],
    )


@njit(inline="always")
def _set_directors(D0, S, Dm):
    for i in range(S.shape[0]):
        R = _directors(D0, S, i)
        for c in range(9):
            Dm[i, c] = R[c]


@njit(inline="always")
def _loads(B, fb, fv, Dm, Fs, Tb):
    """Total external force Fs (world) and body torque Tb of the constant point forces."""
    for i in range(Fs.shape[0]):
        for c in range(3):
            Fs[i, c] = 0.0
            Tb[i, c] = 0.0
    for j in range(fb.shape[0]):
        i = fb[j]
        f0, f1, f2 = fv[j, 0], fv[j, 1], fv[j, 2]
        Fs[i, 0] += f0
        Fs[i, 1] += f1
        Fs[i, 2] += f2
        y0, y1, y2 = G.to_body(Dm, i, f0, f1, f2)
        x0, x1, x2 = fv[j, 3], fv[j, 4], fv[j, 5]
        Tb[i, 0] += x1 * y2 - x2 * y1
        Tb[i, 1] += x2 * y0 - x0 * y2
        Tb[i, 2] += x0 * y1 - x1 * y0


@njit(inline="always")
def _world_omega(B, Dm, i, P0, P1, P2):
    """w = D I^-1 P (world angular velocity of body momentum P in body axes)."""
    return G.body_point(Dm, Dm, i, P0 * B[i, 4], P1 * B[i, 5], P2 * B[i, 6])


@njit(inline="always")
def _omega_half(B, Dm, PIH, i):
    """|w| of the body momentum PIH[i] (body axes): the angular speed of the step."""
    w0 = PIH[i, 0] * B[i, 4]
    w1 = PIH[i, 1] * B[i, 5]
    w2 = PIH[i, 2] * B[i, 6]
    return math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)


@njit(inline="always")
def _rate(Jr, rb_, r, V, Om):
    """Row r's rate J_r . (v, w) for body velocities V (nb, 3) and world omegas Om (nb, 3)."""
    s = 0.0
    for sd in range(2):
        i = rb_[r, sd]
        if i < 0:
            continue
        o = 6 * sd
        s += (Jr[r, o] * V[i, 0] + Jr[r, o + 1] * V[i, 1] + Jr[r, o + 2] * V[i, 2]
              + Jr[r, o + 3] * Om[i, 0] + Jr[r, o + 4] * Om[i, 1]
              + Jr[r, o + 5] * Om[i, 2])  # fmt: skip
    return s


@njit(inline="always")
def _impulse_response(N, nb, rb_, Y, z, BA):
    """The bodies' velocity changes of the row impulses z: BA (nb, 12) = (dv (3), dw (3),
    sum |terms of dv| (3), sum |terms of dw| (3)), world axes."""
    for i in range(nb):
        for c in range(12):
            BA[i, c] = 0.0
    for r in range(N):
        zr = z[r]
        if zr == 0.0:
            continue
        for sd in range(2):
            i = rb_[r, sd]
            if i < 0:
                continue
            o = 6 * sd
            for c in range(6):
                d = zr * Y[r, o + c]
                BA[i, c] += d
                BA[i, 6 + c] += abs(d)


@njit(inline="always")
def _angular_impulse(N, nb, Jr, rb_, z, DL):
    """World angular impulses DL (nb, 3) of the row impulses z."""
    for i in range(nb):
        for c in range(3):
            DL[i, c] = 0.0
    for r in range(N):
        zr = z[r]
        if zr == 0.0:
            continue
        for sd in range(2):
            i = rb_[r, sd]
            if i < 0:
                continue
            o = 6 * sd + 3
            DL[i, 0] += zr * Jr[r, o]
            DL[i, 1] += zr * Jr[r, o + 1]
            DL[i, 2] += zr * Jr[r, o + 2]


@njit(inline="always")
def _same_list(m, cand, lst, meta):
    """Whether the stage has the contacts of its last call (cand[0:m] == lst[0:meta[2]]);
    records them, and drops the kept factorisation if not. meta (7,): the kept
    factorisation's state (0 none, 1 LU factors, 2 inverse), its size N, the list's length,
    the solves done with the LU factors (see :func:`_stage_solve`), the rows' version and
    size of the recorded response (see :func:`_eval`), whether the factors are those of
    redundant rows."""
    same = meta[2] == m
    if same:
        for c in range(m):
            same = same and lst[c] == cand[c]
    if not same:
        meta[0] = 0
        for c in range(m):
            lst[c] = cand[c]
        meta[2] = m
    return same


@njit(inline="always")
def _response(N, nb, rb_, Jr, Y, z, BA, PZ, TZ, zc, meta, rv):
    """The bodies' response to the row impulses z: BA (see :func:`_impulse_response`), the
    rows' rates PZ = J M^-1 J^T z through the bodies and the size of their terms TZ;
    recorded (meta[4] = rv, the rows' version; meta[5] = N; zc = z) for :func:`_eval`."""
    _impulse_response(N, nb, rb_, Y, z, BA)
    for r in range(N):
        s = 0.0
        t = 0.0
        for sd in range(2):
            i = rb_[r, sd]
            if i < 0:
                continue
            o = 6 * sd
            for c in range(6):
                s += Jr[r, o + c] * BA[i, c]
                t += abs(Jr[r, o + c]) * BA[i, 6 + c]
        PZ[r] = s
        TZ[r] = t
        zc[r] = z[r]
    meta[4] = rv
    meta[5] = N


@njit(_nrt=False)
def _eval(N, m, nj, nb, mu, rho, Jr, rb_, Y, b, z, u, F, ts, BA, PZ, TZ, zc, meta, rv):
    """u = b + J M^-1 J^T z through the bodies (no W; the size of its terms into ts), the
    Alart-Curnier function F and the residual. Returns (residual, impulse scale).

    J M^-1 J^T z depends on z and the rows only: it is computed (:func:`_response`) unless
    this stage's last one was at the same z and the same rows (version rv), as when a step
    starts from the impulses its stage ended with at the last step and the rows are reused
    (a resting or sticking configuration): then only b changes, and u = b + PZ is the same
    arithmetic either way."""
    hit = meta[4] == rv and meta[5] == N
    if hit:
        for r in range(N):
            if z[r] != zc[r]:
                hit = False
                break
    if not hit:
        _response(N, nb, rb_, Jr, Y, z, BA, PZ, TZ, zc, meta, rv)
    for r in range(N):
        u[r] = b[r] + PZ[r]
        ts[r] = abs(b[r]) + TZ[r]
    sc = scale_of(N, m, nj, rho, b, z)
    if sc == 0.0:
        return 0.0, sc
    return ac_residual(m, nj, mu, rho, z, u, F, 0.0, ts, sc), sc


@njit(inline="always")
def _invert_kept(LUc, N, pivc, A):
    """Replace the kept LU factors (LUc, pivc) of a matrix K by its inverse, transposed:
    LUc[c, r] = (K^-1)[r, c], so that a chord step K^-1 F is a sum of contiguous rows of LUc
    (vectorised) instead of two triangular solves (each a chain of dependent operations).
    A: N x N scratch."""
    for j in range(N):
        for r in range(N):
            A[j, r] = 0.0
        A[j, j] = 1.0
        lu_apply(LUc, N, pivc, A[j])
    for j in range(N):
        for r in range(N):
            LUc[j, r] = A[j, r]


@njit(_nrt=False)
def _stage_solve(m, nj, mu, rho, Jr, rb_, Y, W, b, z, u, F, A, dz, zt, ut, Ft, piv, nb, DV, DW,
                 DL, wflag, ts, tst, zb, zbar, BA, LUc, pivc, patc, pat, meta, same,
                 luflag, PZ, TZ, zc, rv):  # fmt: skip
    """Solve one stage from the start value z. First its residual through the bodies (no
    W); if not converged, chord Newton steps with the Jacobian this stage factorised at an
    earlier step (valid if ``same``, the same rows as then, and the contacts in the same
    cases ``patc``; at most CHORD steps, each at least halving the residual): with its
    factors ``LUc``, ``pivc`` as the full solver left them (meta[0] = 1; meta[3] counts
    their solves), until they have served N solves; then they are turned into the inverse
    (meta[0] = 2; :func:`_invert_kept`, the cost of about N solves, paid only where the
    factors have already served as many: at most twice the cheaper of the two ways), a
    matrix-vector product per step. Only then W (built unless wflag[0] = 1) and the full
    solver (director_model.contact._solver.solve), whose last factors are kept. Returns
    (status, iterations, residual); the bodies' velocity changes DV, DW and angular
    impulses DL of the solution. BA, PZ, TZ, zc, meta[4:6]: this stage's record of the
    bodies' response (:func:`_eval`); rv: the rows' version (changed whenever they are
    rebuilt).

    No chord steps where a contact slides and the kept factors are those of redundant rows
    (meta[6]: a pivot below SINGULAR times the largest, e.g. the four corners of a face):
    the slip law's Jacobian changes from step to step, and along the rows' null space the
    factors are kept regular only by the solver's small shift, which turns the rounding in
    F into large moves there; such chord steps mostly fail to contract (a box sliding on a
    face, diagonal push: 300 of 1000 stages paid a failed chord step before the full solve)
    where a Newton step from the same start converges at once (38 full solves in all)."""
    N = 3 * m + nj
    st = OK
    it = 0
    rr = 0.0
    fresh = False  # BA holds the bodies' response to z (from the last _eval)
    if N > 0:
        res, sc = _eval(N, m, nj, nb, mu, rho, Jr, rb_, Y, b, z, u, F, ts, BA, PZ, TZ, zc, meta, rv)
        fresh = True
        rr = res
        done = res <= RES_TOL
        if not done and same and meta[0] >= 1 and meta[1] == N:
            pattern(m, mu, rho, z, u, pat)
            ok = True
            for k in range(m):
                # a sliding contact among redundant rows (meta[6]): no chord steps
                ok = ok and pat[k] == patc[k] and (patc[k] != 2 or meta[6] == 0)
            while ok and it < CHORD:
                it += 1
                for r in range(N):
                    zt[r] = z[r]
                if meta[0] == 1 and meta[3] >= N:
                    _invert_kept(LUc, N, pivc, A)
                    meta[0] = 2
                if meta[0] == 2:
                    for r in range(N):
                        dz[r] = 0.0
                    for c in range(N):
                        f = F[c]
                        if f != 0.0:
                            for r in range(N):
                                dz[r] += LUc[c, r] * f
                else:
                    for r in range(N):
                        dz[r] = F[r]
                    lu_apply(LUc, N, pivc, dz)
                    meta[3] += 1
                for r in range(N):
                    z[r] -= dz[r]
                rn, sc = _eval(
                    N, m, nj, nb, mu, rho, Jr, rb_, Y, b, z, u, F, ts, BA, PZ, TZ, zc, meta, rv
                )
                if rn <= RES_TOL:
                    rr = rn
                    done = True
                    break
                if not rn <= 0.5 * res:
                    # not contracting: back to the start value, the full solver from there
                    # (it evaluates its rows itself)
                    for r in range(N):
                        z[r] = zt[r]
                    fresh = False
                    break
                res = rn
        if not done:
            if wflag[0] == 0:
                _delassus(N, Jr, rb_, Y, W)
                wflag[0] = 1
            st, k, rr = ac_solve(
                m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, 0.0, ts, tst, zb, zbar,
                luflag,
            )  # fmt: skip
            fresh = False
            it += k
            meta[0] = 0
            if st == 0 and luflag[0] == 1:
                # keep the last factors (of the Jacobian at the last Newton iterate) for the
                # next steps
                for r in range(N):
                    pivc[r] = piv[r]
                    for c in range(N):
                        LUc[r, c] = A[r, c]
                for r in range(N):
                    zt[r] = z[r]
                pattern(m, mu, rho, z, u, patc)
                meta[0] = 1
                meta[1] = N
                meta[3] = 0
                # redundant rows: a pivot of the factors at the size of the solver's shift
                pmin = math.inf
                pmax = 0.0
                for r in range(N):
                    pmin = min(pmin, abs(LUc[r, r]))
                    pmax = max(pmax, abs(LUc[r, r]))
                meta[6] = 1 if pmin <= SINGULAR * pmax else 0
            st = OK if st == 0 else FAIL_SOLVE
    if not fresh:
        _response(N, nb, rb_, Jr, Y, z, BA, PZ, TZ, zc, meta, rv)
    for i in range(nb):
        for c in range(3):
            DV[i, c] = BA[i, c]
            DW[i, c] = BA[i, 3 + c]
    _angular_impulse(N, nb, Jr, rb_, z, DL)
    return st, it, rr


@njit(_nrt=False)
def _laws(m, mu, rho, z, u, vs, Qs):
    """Dimensionless law residuals of a solved stage into Qs[0:3] (max with what is there),
    with Z the stage's largest contact impulse and u the rows' rates including their targets
    (the gap at the end of the step over h in the position stage): Signorini
    |min(z_n / Z, u_n / vs)| (vs: L/h in the position stage, so that u_n / vs is the end gap
    over the scene's length scale L; the largest free rate in the velocity stage); Coulomb
    (|z_t| - mu z_n)+ / (mu z_n) (over Z if mu z_n = 0); maximum dissipation
    rho |z_t . u_t + mu z_n |u_t|| / Z^2, zero for stick and for z_t opposite to u_t on the
    cone's edge."""
    Z = 0.0
    for r in range(3 * m):
        Z = max(Z, abs(z[r]))
    if Z == 0.0:
        return
    rZ = 1.0 / Z
    rvs = 1.0 / vs
    rZ2 = rZ * rZ
    for k in range(m):
        i = 3 * k
        zn = z[i]
        Qs[0] = max(Qs[0], abs(min(zn * rZ, u[i] * rvs)))
        zt = math.sqrt(z[i + 1] ** 2 + z[i + 2] ** 2)
        cap = mu[k] * zn
        if zt > cap:
            Qs[1] = max(Qs[1], (zt - cap) / (cap if cap > 0.0 else Z))
        ut = math.sqrt(u[i + 1] ** 2 + u[i + 2] ** 2)
        md = abs(z[i + 1] * u[i + 1] + z[i + 2] * u[i + 2] + cap * ut)
        Qs[2] = max(Qs[2], rho[k] * md * rZ2)


@njit(inline="always")
def _store(B, D0, S, X, V, D, W, k):
    for i in range(S.shape[0]):
        for c in range(3):
            X[k, i, c] = S[i, c]
            V[k, i, c] = S[i, 6 + c]
            W[k, i, c] = S[i, 20 + c] * B[i, 4 + c]
        R = _directors(D0, S, i)
        for c in range(9):
            D[k, i, c // 3, c % 3] = R[c]


@njit(_nrt=False)
def _candidates(FI, FV, PI, PV, SH, X, Dm, marg, cand, cb, cg, P8, fidx, FO):
    """Candidate features at (X, Dm): near pairs (bounding spheres within the pair's margin
    marg[p]), box-box pairs checked for exactness, each valid feature with distance <= margin
    added (cand: feature index; cb: bodies; cg: gap, n, t1, t2, ra, rb). Returns (status,
    count, failing pair, failing feature). fidx, FO: scratch."""
    nq = 0
    for p in range(PI.shape[0]):
        kind = PI[p, 0]
        a = PI[p, 1]
        b = PI[p, 2]
        mg = marg[p]
        if b >= 0 and kind != 0:
            d0, d1, d2 = X[a, 0] - X[b, 0], X[a, 1] - X[b, 1], X[a, 2] - X[b, 2]
            if math.sqrt(d0 * d0 + d1 * d1 + d2 * d2) - PV[p, 2] - PV[p, 3] > mg:
                continue
        if kind == 2:  # box-box
            ha = (SH[a, 1], SH[a, 2], SH[a, 3])
            hb = (SH[b, 1], SH[b, 2], SH[b, 3])
            near, exact = G.box_pair_check(X, Dm, a, b, ha, hb, mg, P8)
            if not near:
                continue
            if not exact:
                return FAIL_INEXACT, 0, p, -1
        for f in range(PI[p, 3], PI[p, 3] + PI[p, 4]):
            fidx[nq] = f
            nq += 1
    G.eval_features(FI, FV, fidx, nq, X, Dm, FO)
    nc = 0
    for q in range(nq):
        f = fidx[q]
        if FO[q, 0] == 0.0 or FO[q, 12] > marg[FI[f, 3]]:
            continue
        if FO[q, 1] != 0.0:
            return FAIL_INEXACT, nc, FI[f, 3], f
        t, s = _onb(FO[q, 3], FO[q, 4], FO[q, 5])
        cand[nc] = f
        cb[nc, 0] = FI[f, 1]
        cb[nc, 1] = FI[f, 2] if PI[FI[f, 3], 0] != 0 else -1
        cg[nc, 0] = FO[q, 2]
        cg[nc, 1], cg[nc, 2], cg[nc, 3] = FO[q, 3], FO[q, 4], FO[q, 5]
        cg[nc, 4], cg[nc, 5], cg[nc, 6] = t[0], t[1], t[2]
        cg[nc, 7], cg[nc, 8], cg[nc, 9] = s[0], s[1], s[2]
        for k in range(6):
            cg[nc, 10 + k] = FO[q, 6 + k]
        nc += 1
    return OK, nc, -1, -1
