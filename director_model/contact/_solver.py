"""Compiled solver of one frictional contact problem with the exact Coulomb cone.

The problem (one stage of a step): unknown impulses z (N = 3 m + nj rows: for each of the m
contacts a normal row and two tangent rows, then nj bilateral rows of joints), the rows'
velocities

    u = W z + b,

W = J M^-1 J^T the Delassus operator (symmetric positive semi-definite, singular whenever
contacts are redundant, e.g. the four corners of a resting box), b the velocities without
the impulses plus the rows' targets (a gap over the step, a restitution target). Sought:

- contact k, impulse (z_n, z_t) and velocity (u_n, u_t): Signorini z_n >= 0, u_n >= 0,
  z_n u_n = 0; Coulomb |z_t| <= mu z_n (the exact isotropic cone, no pyramid); maximum
  dissipation: u_t = 0 (stick) or z_t = -mu z_n u_t/|u_t| (slip);
- bilateral row j: u_j = 0.

Solved as the root of the Alart-Curnier function (Alart & Curnier 1991; in the form of
Christensen, Klarbring, Pang & Stroemberg 1998), with rho_k = 3 / trace(W_kk):

    F_n = z_n - max(0, sigma),   sigma = z_n - rho u_n
    F_t = z_t - P(z_t - rho u_t),   P the projection on the disk of radius mu max(0, sigma)
    F_j = rho_j u_j,

whose roots are exactly the solutions of the laws above (no regularisation: F = 0 is the
law), by a semi-smooth Newton method (its generalised Jacobian per contact case: separated,
stick, slip) with a Levenberg-Marquardt shift kappa I, kappa proportional to |F|, which keeps
the Newton matrix regular where W is singular and vanishes at the solution, and a
backtracking line search on |F|^2. Where that stalls (W singular and the targets of
redundant contacts incompatible with a rigid motion, e.g. restitution targets of a face
landing with a twist: the solution unloads a contact, a move along the null space of W that
Newton's model does not see), the proximal point method (Rockafellar 1976): a sequence of
problems with W + eps I and b - eps zbar, zbar the previous solution, each strongly
monotone in its normal part and solved by the same Newton method; their fixed point is a
solution of the original problem (eps enters only through zbar - z, zero at the fixed
point). Converged when every row's |F| of the original problem is at most RES_TOL times the
size of its terms (:func:`solve`): the certified residual returned with the solution. Every
loop has a cap (MAXIT Newton iterations per problem, PROX_MAX proximal problems); a problem
not solved to RES_TOL returns the status FAIL with its residual.
"""

from __future__ import annotations

import math

from numba import njit

EPS = 2.220446049250313e-16
#: convergence: every |F_r| <= RES_TOL x the size of its terms (see :func:`solve`)
RES_TOL = 256.0 * EPS
MAXIT = 40
#: smallest Levenberg-Marquardt shift (the Newton matrix rho W is O(1) on its range)
KAPPA_MIN = 1e-9
#: full Newton steps without a new best iterate before the Newton method gives up
WATCH = 4
#: proximal problems at most, and their shift eps relative to the mean diagonal of W
PROX_MAX = 60
PROX_REL = 1e-3
MAXLS = 30

OK = 0
FAIL = 1  # not converged within MAXIT iterations


@njit(inline="always")
def rows_velocity(N, W, b, z, u, ts, eps, zbar):
    """u = W z + b + eps (z - zbar) (first N rows) and ts = |b| + |W| |z|, the size of the
    terms summed (their rounding bounds what any solver can reach on that row)."""
    for r in range(N):
        s = b[r]
        t = abs(b[r])
        for c in range(N):
            p = W[r, c] * z[c]
            s += p
            t += abs(p)
        u[r] = s + eps * (z[r] - zbar[r]) if eps != 0.0 else s
        ts[r] = t


@njit(_nrt=False)
def ac_residual(m, nj, mu, rho, z, u, F, gtol, ts, sc):
    """The Alart-Curnier function F (first 3 m + nj entries) at impulses z and velocities u.
    Returns the residual relative to the terms: max over the rows of |F_r| / (sc + rho
    ts_r), sc the problem's impulse scale (:func:`scale_of`) and ts_r the size of the terms
    of u_r (:func:`rows_velocity`), where a normal or bilateral row's |F| is first reduced by
    rho gtol (gtol: the uncertainty of those rows' targets, m/s; see :func:`solve`)."""
    res = 0.0
    for k in range(m):
        i = 3 * k
        sigma = z[i] - rho[k] * u[i]
        F[i] = z[i] - max(0.0, sigma)
        R = mu[k] * max(0.0, sigma)
        y1 = z[i + 1] - rho[k] * u[i + 1]
        y2 = z[i + 2] - rho[k] * u[i + 2]
        ny = math.sqrt(y1 * y1 + y2 * y2)
        if ny <= R:
            F[i + 1] = rho[k] * u[i + 1]
            F[i + 2] = rho[k] * u[i + 2]
        else:
            f = R / ny
            F[i + 1] = z[i + 1] - f * y1
            F[i + 2] = z[i + 2] - f * y2
        res = max(
            res,
            max(abs(F[i]) - rho[k] * gtol, 0.0) / (sc + rho[k] * ts[i]),
            abs(F[i + 1]) / (sc + rho[k] * ts[i + 1]),
            abs(F[i + 2]) / (sc + rho[k] * ts[i + 2]),
        )
    for j in range(nj):
        r = 3 * m + j
        F[r] = rho[m + j] * u[r]
        res = max(res, max(abs(F[r]) - rho[m + j] * gtol, 0.0) / (sc + rho[m + j] * ts[r]))
    return res


@njit(_nrt=False)
def _ac_jacobian(m, nj, mu, rho, W, z, u, A, eps):
    """The generalised Jacobian dF/dz of :func:`ac_residual` into A (N x N), for the
    velocities u = (W + eps I) z + ..."""
    N = 3 * m + nj
    for k in range(m):
        i = 3 * k
        rk = rho[k]
        sigma = z[i] - rk * u[i]
        if sigma <= 0.0:
            # separated: F = z
            for c in range(N):
                A[i, c] = 0.0
                A[i + 1, c] = 0.0
                A[i + 2, c] = 0.0
            A[i, i] = 1.0
            A[i + 1, i + 1] = 1.0
            A[i + 2, i + 2] = 1.0
            continue
        for c in range(N):
            A[i, c] = rk * W[i, c]
        A[i, i] += rk * eps
        R = mu[k] * sigma
        y1 = z[i + 1] - rk * u[i + 1]
        y2 = z[i + 2] - rk * u[i + 2]
        ny = math.sqrt(y1 * y1 + y2 * y2)
        if ny <= R:
            for c in range(N):
                A[i + 1, c] = rk * W[i + 1, c]
                A[i + 2, c] = rk * W[i + 2, c]
            A[i + 1, i + 1] += rk * eps
            A[i + 2, i + 2] += rk * eps
            continue
        # slip: F_t = z_t - R yh, yh = y/|y|; dF_t = E_t - mu yh dsigma - (R/|y|)(1 - yh yh^T) dy
        # with dsigma = e_n - rho W_n and dy = E_t - rho W_t
        h1 = y1 / ny
        h2 = y2 / ny
        f = R / ny
        p11 = f * (1.0 - h1 * h1)
        p12 = -f * h1 * h2
        p22 = f * (1.0 - h2 * h2)
        for c in range(N):
            ds = (1.0 if c == i else 0.0) - rk * (W[i, c] + (eps if c == i else 0.0))
            d1 = (1.0 if c == i + 1 else 0.0) - rk * (W[i + 1, c] + (eps if c == i + 1 else 0.0))
            d2 = (1.0 if c == i + 2 else 0.0) - rk * (W[i + 2, c] + (eps if c == i + 2 else 0.0))
            A[i + 1, c] = (1.0 if c == i + 1 else 0.0) - mu[k] * h1 * ds - (p11 * d1 + p12 * d2)
            A[i + 2, c] = (1.0 if c == i + 2 else 0.0) - mu[k] * h2 * ds - (p12 * d1 + p22 * d2)
    for j in range(nj):
        r = 3 * m + j
        for c in range(N):
            A[r, c] = rho[m + j] * W[r, c]
        A[r, r] += rho[m + j] * eps


@njit(inline="always")
def _lu_solve(A, N, x, piv):
    """Solve A y = x in place (x becomes y) by LU with partial pivoting, A (N x N)
    overwritten. Returns False on a zero pivot."""
    for k in range(N):
        p = k
        amax = abs(A[k, k])
        for r in range(k + 1, N):
            if abs(A[r, k]) > amax:
                amax = abs(A[r, k])
                p = r
        if not amax > 0.0:
            return False
        piv[k] = p
        if p != k:
            for c in range(N):
                t = A[k, c]
                A[k, c] = A[p, c]
                A[p, c] = t
            t = x[k]
            x[k] = x[p]
            x[p] = t
        inv = 1.0 / A[k, k]
        for r in range(k + 1, N):
            f = A[r, k] * inv
            if f != 0.0:
                A[r, k] = f
                for c in range(k + 1, N):
                    A[r, c] -= f * A[k, c]
                x[r] -= f * x[k]
    for k in range(N - 1, -1, -1):
        s = x[k]
        for c in range(k + 1, N):
            s -= A[k, c] * x[c]
        x[k] = s / A[k, k]
    return True


@njit(inline="always")
def scale_of(N, m, nj, rho, b, z):
    """Impulse scale of the problem: max(|z|, rho |b|) over the rows (> 0 unless both are 0)."""
    s = 0.0
    for k in range(m):
        for i in range(3 * k, 3 * k + 3):
            s = max(s, abs(z[i]), rho[k] * abs(b[i]))
    for j in range(nj):
        r = 3 * m + j
        s = max(s, abs(z[r]), rho[m + j] * abs(b[r]))
    return s


@njit(_nrt=False)
def _newton(m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, gtol, ts, tst, zb, eps, zbar,
            luflag):  # fmt: skip
    """Semi-smooth Newton on the problem with W + eps I and b - eps zbar, from z. Returns
    (converged, iterations); z the best iterate, u, F, ts at z. luflag[0] is set to 1 when
    A holds the LU factors of a Jacobian of the plain problem (eps = 0), 0 for eps > 0."""
    N = 3 * m + nj
    rows_velocity(N, W, b, z, u, ts, eps, zbar)
    sc = scale_of(N, m, nj, rho, b, z)
    res = ac_residual(m, nj, mu, rho, z, u, F, gtol, ts, sc)
    it = 0
    best = res
    watch = 0
    for r in range(N):
        zb[r] = z[r]
    while it < MAXIT and res > RES_TOL:
        it += 1
        _ac_jacobian(m, nj, mu, rho, W, z, u, A, eps)
        fn = 0.0
        for r in range(N):
            fn = max(fn, abs(F[r]))
        # the shift: |F| / scale (vanishing at the solution) bounded below by KAPPA_MIN, so
        # that round-off in F along the null space of a singular W (redundant contacts)
        # does not become a large step along that null space
        kappa = min(1e-2, max(fn / sc, KAPPA_MIN))
        for r in range(N):
            dz[r] = -F[r]
        for k in range(m):
            i = 3 * k
            if z[i] - rho[k] * u[i] > 0.0:  # not separated (a separated contact's rows are
                A[i, i] += kappa  # the identity: its step sets z to 0 exactly)
                A[i + 1, i + 1] += kappa
                A[i + 2, i + 2] += kappa
        for r in range(3 * m, N):
            A[r, r] += kappa
        luflag[0] = 1 if eps == 0.0 else 0
        if not _lu_solve(A, N, dz, piv):
            luflag[0] = 0
            break
        # backtracking on |F|^2 (Armijo with the Newton model's decrease); where it finds
        # no decrease (a contact on the cone's edge, where the generalised Jacobian jumps,
        # with W singular) the full step is taken anyway, at most WATCH times in a row
        # without a new best iterate, which is kept (a watchdog, Chamberlain, Powell,
        # Lemarechal & Pedersen 1982)
        f0 = 0.0
        for r in range(N):
            f0 += F[r] * F[r]
        t = 1.0
        accepted = False
        for _ in range(MAXLS):
            for r in range(N):
                zt[r] = z[r] + t * dz[r]
            rows_velocity(N, W, b, zt, ut, tst, eps, zbar)
            sct = scale_of(N, m, nj, rho, b, zt)
            rn = ac_residual(m, nj, mu, rho, zt, ut, Ft, gtol, tst, sct)
            f1 = 0.0
            for r in range(N):
                f1 += Ft[r] * Ft[r]
            if f1 <= (1.0 - 1e-4 * t) * f0 or rn <= RES_TOL:
                accepted = True
                break
            t *= 0.5
        if not accepted:
            watch += 1
            if watch > WATCH:
                break
            for r in range(N):
                zt[r] = z[r] + dz[r]
            rows_velocity(N, W, b, zt, ut, tst, eps, zbar)
            sct = scale_of(N, m, nj, rho, b, zt)
            rn = ac_residual(m, nj, mu, rho, zt, ut, Ft, gtol, tst, sct)
        for r in range(N):
            z[r] = zt[r]
            u[r] = ut[r]
            F[r] = Ft[r]
            ts[r] = tst[r]
        sc = sct
        res = rn
        if res < best:
            best = res
            watch = 0
            for r in range(N):
                zb[r] = z[r]
    if res > best:
        for r in range(N):
            z[r] = zb[r]
        rows_velocity(N, W, b, z, u, ts, eps, zbar)
        sc = scale_of(N, m, nj, rho, b, z)
        res = ac_residual(m, nj, mu, rho, z, u, F, gtol, ts, sc)
    return res <= RES_TOL, it


@njit(_nrt=False)
def solve(m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, gtol, ts, tst, zb, zbar,
          luflag):  # fmt: skip
    """Solve the problem from the start value z (overwritten by the solution; u its
    velocities). Returns (status, Newton iterations, certified residual).

    Converged when every row's |F| is at most RES_TOL times the size of what it is made of
    (the impulse scale plus rho times the terms of its velocity: the rounding of u = W z + b
    is a few ulps of those terms, and no iteration gets below it). ``gtol`` (m/s): the
    normal and bilateral rows' targets are known to gtol only (in the position stage, a gap
    over the step: the gaps of a resting box's four corners, each rounded, are not exactly
    those of a rigid motion, and no impulse satisfies all four exactly); their residual
    counts beyond rho gtol. Tangent rows (stick, slip) have no such allowance.
    Newton first; if it stalls, proximal problems (see the module docstring), each started
    from the last, until the original problem's residual is below RES_TOL.

    A warm start (the last step's impulses) can leave Newton and the proximal sequence
    stalled where the contacts' forces are indeterminate (a face resting between stick and
    slip: a box coming to rest with four corners); the problem is then solved again from
    z = 0 (measured: a tumbling box's velocity stage, 2575 iterations to 4.3e-8 from the warm
    start, 23 iterations to 8e-17 from 0). One function, not a helper called twice: each
    level of compiled calls costs numba a re-optimisation of everything below it."""
    N = 3 * m + nj
    if N == 0:
        return OK, 0, 0.0
    it = 0
    res = 0.0
    for attempt in range(2):
        if attempt == 1:
            for r in range(N):
                z[r] = 0.0
        luflag[0] = 0
        ok, k = _newton(m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, gtol, ts, tst,
                        zb, 0.0, zbar, luflag)  # fmt: skip
        it += k
        sc = scale_of(N, m, nj, rho, b, z)
        if ok or sc == 0.0:
            res = ac_residual(m, nj, mu, rho, z, u, F, gtol, ts, sc) if sc > 0.0 else 0.0
            return OK, it, res
        wd = 0.0
        for r in range(N):
            wd += W[r, r]
        eps = PROX_REL * wd / N
        for _ in range(PROX_MAX):
            for r in range(N):
                zbar[r] = z[r]
            _, k = _newton(m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, gtol, ts,
                           tst, zb, eps, zbar, luflag)  # fmt: skip
            it += k
            # the original problem at the proximal solution, then Newton from there
            ok, k = _newton(m, nj, mu, rho, W, b, z, u, F, A, dz, zt, ut, Ft, piv, gtol, ts,
                            tst, zb, 0.0, zbar, luflag)  # fmt: skip
            it += k
            if ok:
                break
        sc = scale_of(N, m, nj, rho, b, z)
        res = ac_residual(m, nj, mu, rho, z, u, F, gtol, ts, sc)
        if res <= RES_TOL:
            return OK, it, res
    return FAIL, it, res


@njit(inline="always")
def pattern(m, mu, rho, z, u, pat):
    """Each contact's case at (z, u): 0 separated, 1 stick, 2 slip (the branch of the
    Alart-Curnier function, which fixes the form of its Jacobian)."""
    for k in range(m):
        i = 3 * k
        sigma = z[i] - rho[k] * u[i]
        if sigma <= 0.0:
            pat[k] = 0
            continue
        y1 = z[i + 1] - rho[k] * u[i + 1]
        y2 = z[i + 2] - rho[k] * u[i + 2]
        pat[k] = 1 if math.sqrt(y1 * y1 + y2 * y2) <= mu[k] * sigma else 2


@njit(inline="always")
def lu_apply(LU, N, piv, x):
    """Solve with the factors of :func:`_lu_solve` (LU and piv), x in place."""
    for k in range(N):
        p = piv[k]
        if p != k:
            t = x[k]
            x[k] = x[p]
            x[p] = t
        for r in range(k + 1, N):
            x[r] -= LU[r, k] * x[k]
    for k in range(N - 1, -1, -1):
        s = x[k]
        for c in range(k + 1, N):
            s -= LU[k, c] * x[c]
        x[k] = s / LU[k, k]
