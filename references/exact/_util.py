"""Small numerical tools shared by the exact references: the "not applicable" exception, rotations
about axes (vectorised), Jacobi elliptic functions with argument reduction, Carlson's symmetric
integral R_J and the elliptic integral of the third kind built on it, and antiderivatives of
smooth (periodic) functions by composite Gauss-Legendre quadrature."""

from __future__ import annotations

import math

import numpy as np
from numpy.polynomial.legendre import leggauss

EPS = float(np.finfo(float).eps)


class ReferenceNotApplicable(ValueError):
    """A reference solution does not apply to a scenario, or cannot be trusted for it; the
    message says why. The only exception a closed form's constructor raises for a valid
    scenario (``references.exact`` then hands over to the numerical reference when the kind
    was chosen automatically)."""


def rot_axis(axis: np.ndarray, angle) -> np.ndarray:
    """Rotations by ``angle`` (shape (n,)) about the unit vector ``axis`` (3,): shape (n, 3, 3)."""
    a = np.asarray(angle, dtype=float).reshape(-1)
    k = np.asarray(axis, dtype=float)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    s = np.sin(a)[:, None, None]
    c1 = (2.0 * np.sin(0.5 * a) ** 2)[:, None, None]  # 1 - cos a without cancellation
    return np.eye(3) + s * K + c1 * (K @ K)


def rot_z(a) -> np.ndarray:
    a = np.asarray(a, dtype=float).reshape(-1)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((len(a), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = 1.0
    return out


def rot_x(a) -> np.ndarray:
    a = np.asarray(a, dtype=float).reshape(-1)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((len(a), 3, 3))
    out[:, 1, 1], out[:, 1, 2], out[:, 2, 1], out[:, 2, 2] = c, -s, s, c
    out[:, 0, 0] = 1.0
    return out


def rotation_angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Angle (rad) of Ra^T Rb for stacks (n, 3, 3), accurate for small angles (uses the
    skew part rather than the trace)."""
    M = np.einsum("nji,njk->nik", Ra, Rb)
    skew = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], 1)
    s = 0.5 * np.linalg.norm(skew, axis=1)
    c = 0.5 * (np.trace(M, axis1=1, axis2=2) - 1.0)
    return np.arctan2(s, c)


# -- Jacobi elliptic functions ----------------------------------------------------------------


def _landen(v: np.ndarray, m: float, m1: float, K: float):
    """sn, cn, dn of v (best for |v| <= K/2) and parameter m = 1 - m1, by descending Landen
    transformations (DLMF 22.7.1-2) fed with the complementary modulus k' = sqrt(m1) itself.

    k_{n+1} = (1 - k'_n)/(1 + k'_n) (= k_n^2/(1 + k'_n)^2 once k'_n > 1/2, to keep it accurate),
    k'_{n+1} = 2 sqrt(k'_n)/(1 + k'_n), until k_N < 1e-9 (k_N^2 below the rounding), where sn = sin,
    cn = cos of w = v pi/(2K) (the product of the (1 + k_n) is 2K/pi); back up, sn_n = (1 + k_{n+1})
    s/(1 + k_{n+1} s^2), cn_n = c d/(1 + k_{n+1} s^2), and dn_n = sqrt(k'_n^2 + k_n^2 cn_n^2), all
    products and sums of positive terms. Unlike scipy's ellipj, which takes m alone and so loses
    ~eps/sqrt(m1) near m = 1 (1e-12 relative at m1 = 3e-9), this keeps sn, cn, dn within 3.8e-15
    relative and sn^2 + cn^2 = 1 within 3.1e-15 for m1 from 0.5 to 1e-20 (measured against mpmath,
    tests/references/exact/test_exact_accuracy.py)."""
    k, kp = math.sqrt(m), math.sqrt(m1)
    levels = [(k, kp)]
    while k > 1e-9:
        k = (1.0 - kp) / (1.0 + kp) if kp < 0.5 else k * k / (1.0 + kp) ** 2
        kp = 2.0 * math.sqrt(kp) / (1.0 + kp)
        levels.append((k, kp))
    w = v * (0.5 * math.pi / K)
    s, c = np.sin(w), np.cos(w)
    kn, kpn = levels[-1]
    d = np.sqrt(kpn * kpn + kn * kn * c * c)
    for n in range(len(levels) - 2, -1, -1):
        k1 = levels[n + 1][0]
        kn, kpn = levels[n]
        den = 1.0 + k1 * s * s
        s, c = (1.0 + k1) * s / den, c * d / den
        d = np.sqrt(kpn * kpn + kn * kn * c * c) if n > 0 else np.sqrt(m1 + m * c * c)
    return s, c, d


def jacobi(u, m: float, m1: float, K: float):
    """sn, cn, dn of argument ``u`` (array) and parameter m = k^2, with m1 = 1 - m given
    separately (accurately) and K = K(m).

    u is reduced modulo 2K (with the accurate K) to |r| <= K, and for K/2 < |r| <= K the
    reflection sn(K - v) = cn v/dn v, cn(K - v) = k' sn v/dn v, dn(K - v) = k'/dn v
    (k' = sqrt(m1)) is used, so that the functions are only computed (by :func:`_landen`) for
    arguments <= K/2, where cn and dn are not small. m1 = 0 (the separatrix) gives the
    hyperbolic limit sn = tanh, cn = dn = sech.
    """
    u = np.asarray(u, dtype=float)
    if m1 == 0.0:
        ch = np.cosh(u)
        return np.tanh(u), 1.0 / ch, 1.0 / ch
    n = np.round(u / (2.0 * K))
    r = u - 2.0 * K * n
    flip = np.where(np.mod(n, 2.0) == 0.0, 1.0, -1.0)  # sn, cn change sign every 2K
    ar = np.abs(r)
    near = ar <= 0.5 * K
    s, c, d = _landen(np.where(near, ar, K - ar), m, m1, K)
    kp = math.sqrt(m1)
    sn = np.where(near, s, c / d)
    cn = np.where(near, c, kp * s / d)
    dn = np.where(near, d, kp / d)
    sn = sn * np.sign(r) * flip
    cn = cn * flip
    return sn, cn, dn


def carlson_rf(x, y, z) -> np.ndarray:
    """Carlson's symmetric elliptic integral of the first kind,
    R_F(x, y, z) = 1/2 int_0^inf dt / sqrt((t + x)(t + y)(t + z)), x, y, z >= 0 (at most one
    zero); duplication algorithm of Carlson, Numer. Algorithms 10 (1995), section 2."""
    x, y, z = (a.astype(float) for a in np.broadcast_arrays(*map(np.asarray, (x, y, z))))
    a0 = (x + y + z) / 3.0
    big = (3.0 * EPS) ** (-1.0 / 6.0) * np.maximum.reduce(
        [np.abs(a0 - x), np.abs(a0 - y), np.abs(a0 - z)]
    )
    x0, y0 = x, y
    a = a0
    f = 1.0
    for _ in range(100):
        sx, sy, sz = np.sqrt(x), np.sqrt(y), np.sqrt(z)
        lam = sx * sy + sy * sz + sz * sx
        x, y, z, a = (x + lam) / 4.0, (y + lam) / 4.0, (z + lam) / 4.0, (a + lam) / 4.0
        f /= 4.0
        if np.all(f * big < np.abs(a)):
            break
    X = (a0 - x0) * f / a
    Y = (a0 - y0) * f / a
    Z = -(X + Y)
    e2 = X * Y - Z * Z
    e3 = X * Y * Z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / np.sqrt(a)


def _ellipf(s: float, c: float, m1: float) -> float:
    """F(phi | m) for 0 <= phi <= pi/2 from s = sin phi, c = cos phi (s^2 + c^2 = 1):
    s R_F(c^2, c^2 + m1 s^2, 1), with 1 - m s^2 formed as c^2 + m1 s^2 (no loss near m = 1)."""
    return float(s * carlson_rf(c * c, c * c + m1 * s * s, 1.0))


def jacobi_inverse(s0: float, c0: float, m: float, m1: float, K: float) -> float:
    """The argument u in (-2K, 2K] with sn(u) ~ s0 and cn(u) ~ c0 (signs and ratio are used;
    s0^2 + c0^2 need only be 1 to round-off). Well conditioned near m = 1: the incomplete
    integral is only evaluated up to K/2, by the same reflection as :func:`jacobi`, and takes
    m1 itself (:func:`_ellipf`)."""
    a_s, a_c = abs(s0), abs(c0)
    if m1 == 0.0:
        x = math.asinh(a_s / a_c) if a_c > 0 else math.inf
    else:
        kp = math.sqrt(m1)
        if a_s * math.sqrt(kp) <= a_c:
            h = math.hypot(a_s, a_c)
            x = _ellipf(a_s / h, a_c / h, m1)
        else:
            h = math.hypot(a_c, kp * a_s)
            x = K - _ellipf(a_c / h, kp * a_s / h, m1)
        if c0 < 0:
            x = 2.0 * K - x
    return -x if s0 < 0 else x


# -- elliptic integrals of the third kind --------------------------------------------------


def _rc1(e: np.ndarray, w: np.ndarray) -> np.ndarray:
    """R_C(1, w) for w = 1 + e > 0, with e and w both given accurately (so that w near 0, where
    R_C has its logarithmic singularity, loses nothing)."""
    out = np.empty_like(e)
    small = np.abs(e) < 1e-3
    es = e[small]
    # R_C(1, 1 + e) = sum_k (-e)^k/(2k + 1): the first neglected term is < 1e-21/15
    out[small] = 1 - es * (1 / 3 - es * (1 / 5 - es * (1 / 7 - es * (1 / 9 - es * (1 / 11)))))
    pos = ~small & (e > 0)
    r = np.sqrt(e[pos])
    out[pos] = np.arctan(r) / r
    neg = ~small & (e < 0)
    r = np.sqrt(-e[neg])
    # atanh(r) = log((1 + r)/(1 - r))/2 with 1 - r^2 = w: log1p(2 r (1 + r)/w)/2
    out[neg] = 0.5 * np.log1p(2.0 * r * (1.0 + r) / w[neg]) / r
    return out


def carlson_rj(x, y, z, p) -> np.ndarray:
    """Carlson's symmetric elliptic integral of the third kind,
    R_J(x, y, z, p) = 3/2 int_0^inf dt / ((t + p) sqrt((t + x)(t + y)(t + z))), for x, y, z >= 0
    (at most one zero) and p > 0; vectorised.

    Duplication algorithm of B. C. Carlson, Numer. Algorithms 10 (1995) 13-26, section 2, with 1 +
    e_m = 2 sqrt(p_m)(p_m + lambda_m)/d_m formed without cancellation, so that p << x, y, z (where
    R_J ~ p^(-1/2) and e_m -> -1) keeps full relative accuracy, and R_C(1, 1 + e) for e < 0 is
    formed with log1p. Measured against mpmath (40 digits) on random arguments with p from 1e-30 to
    1e2 and x, y down to 1e-113 (tests/references/exact/test_exact_accuracy.py): relative error <=
    7.8e-16; scipy.special.elliprj reached 1.2e-13 on the same kind of arguments.
    """
    x, y, z, p = (a.astype(float) for a in np.broadcast_arrays(*map(np.asarray, (x, y, z, p))))
    a0 = (x + y + z + 2.0 * p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    # (r/4)^(-1/6) max|A0 - x_i| with r = eps: the series below is then accurate to ~eps
    big = (EPS / 4.0) ** (-1.0 / 6.0) * np.maximum.reduce(
        [np.abs(a0 - x), np.abs(a0 - y), np.abs(a0 - z), np.abs(a0 - p)]
    )
    x0, y0, z0 = x, y, z
    a = a0
    total = np.zeros_like(a0)
    f, fe = 1.0, 1.0
    for _ in range(100):
        sx, sy, sz, sp = np.sqrt(x), np.sqrt(y), np.sqrt(z), np.sqrt(p)
        lam = sx * sy + sy * sz + sz * sx
        d = (sp + sx) * (sp + sy) * (sp + sz)
        total = total + f * _rc1(fe * delta / (d * d), 2.0 * sp * (p + lam) / d) / d
        x, y, z, p = (x + lam) / 4.0, (y + lam) / 4.0, (z + lam) / 4.0, (p + lam) / 4.0
        a = (a + lam) / 4.0
        f /= 4.0
        fe /= 64.0
        if np.all(f * big < np.abs(a)):
            break
    X, Y, Z = ((a0 - v) * f / a for v in (x0, y0, z0))
    P = -(X + Y + Z) / 2.0
    e2 = X * Y + X * Z + Y * Z - 3.0 * P * P
    e3 = X * Y * Z + 2.0 * e2 * P + 4.0 * P**3
    e4 = (2.0 * X * Y * Z + e2 * P + 3.0 * P**3) * P
    e5 = X * Y * Z * P * P
    series = (
        1.0
        - 3.0 * e2 / 14.0
        + e3 / 6.0
        + 9.0 * e2 * e2 / 88.0
        - 3.0 * e4 / 22.0
        - 9.0 * e2 * e3 / 52.0
        + 3.0 * e5 / 26.0
    )
    return f * a**-1.5 * series + 6.0 * total


def complete_pi(n: float, one_minus_n: float, m1: float, K: float) -> float:
    """Pi(n | m) = int_0^K dv/(1 - n sn^2 v), for 0 <= n < 1 with 1 - n given accurately:
    K + (n/3) R_J(0, 1 - m, 1, 1 - n) (DLMF 19.25.2 with Carlson's form of Pi)."""
    rj = carlson_rj(0.0, m1, 1.0, one_minus_n)
    return float(K + n / 3.0 * rj)


def incomplete_pi(n: float, r, sn, cn2, dn2, p) -> np.ndarray:
    """int_0^r dv/(1 - n sn^2 v) for |r| <= K, 0 <= n < 1, from sn, cn^2, dn^2 of r and
    p = 1 - n sn^2 r (given accurately by the caller): r + (n/3) sn^3 R_J(cn^2, dn^2, 1, p)
    (the R_F part of Carlson's formula for Pi is F(am r) = r itself). All terms have the sign of
    r: no cancellation, relative accuracy ~eps even where p is tiny (the integrand's peak)."""
    return r + (n / 3.0) * sn**3 * carlson_rj(cn2, dn2, 1.0, p)


# -- antiderivatives by quadrature ------------------------------------------------------------

_GL_X, _GL_W = leggauss(16)


def _gl(g, a, b):
    """16-point Gauss-Legendre of g over [a, b] (arrays of equal shape)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    half = 0.5 * (b - a)
    x = (0.5 * (a + b))[..., None] + half[..., None] * _GL_X
    return half * (g(x.reshape(-1)).reshape(x.shape) @ _GL_W)


class Antiderivative:
    """G(x) = integral_0^x g(s) ds for a smooth vectorised g, optionally periodic.

    Periodic case (period P): the integral over one period is computed by the trapezoidal rule,
    which converges geometrically for smooth periodic integrands (the number of points is
    doubled until two successive values agree to 1e-15 of P max|g|). G is then
    n * (integral over a period) + the integral over the remainder, by composite 16-point
    Gauss-Legendre on panels whose number is doubled until every panel agrees with its two
    halves to 1e-16 of P max|g| per panel. ``error`` is the sum of those panel differences plus
    the trapezoid difference: an estimate of the quadrature error of G over one period.
    Non-periodic case: the same panels, of width ``scale``/8 refined likewise, laid from 0.
    """

    def __init__(self, g, period: float | None, scale: float):
        self.g = g
        self.period = period
        if period is not None:
            P = float(period)
            gmax = float(np.max(np.abs(g(np.linspace(0.0, P, 257)))))
            tol = 1e-15 * P * max(gmax, 1e-300)
            n, prev = 32, None
            while True:
                total = float(np.sum(g(np.arange(n) * (P / n)))) * (P / n)
                if prev is not None and abs(total - prev) <= tol:
                    break
                prev, n = total, 2 * n
                if n > 2**22:
                    raise RuntimeError("trapezoidal rule did not converge: integrand not smooth")
            self.total = total
            trap_err = abs(total - prev)
            npan = 8
            while True:
                edges = np.linspace(0.0, P, npan + 1)
                whole = _gl(g, edges[:-1], edges[1:])
                mid = 0.5 * (edges[:-1] + edges[1:])
                halves = _gl(g, edges[:-1], mid) + _gl(g, mid, edges[1:])
                err = float(np.sum(np.abs(whole - halves)))
                if err <= 0.1 * tol or npan >= 2**16:
                    break
                npan *= 2
            self.h = P / npan
            self.cum = np.concatenate([[0.0], np.cumsum(halves)])
            # the panels must add up to the spectrally accurate total
            self.error = err + trap_err + abs(self.cum[-1] - total)
            self.npan = npan
        else:
            self.h = float(scale) / 8.0
            self.error = 0.0

    def __call__(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if self.period is not None:
            P = self.period
            n = np.floor(x / P)
            r = x - n * P
            k = np.clip(np.floor(r / self.h).astype(int), 0, self.npan - 1)
            a = k * self.h
            return n * self.total + self.cum[k] + _gl(self.g, a, r)
        # non-periodic: panels [k h, (k+1) h] from 0, refined until converged over the range
        lo, hi = min(0.0, float(np.min(x))), max(0.0, float(np.max(x)))
        h = self.h
        while True:
            k0, k1 = math.floor(lo / h), math.ceil(hi / h)
            edges = np.arange(k0, k1 + 1) * h
            mid = 0.5 * (edges[:-1] + edges[1:])
            whole = _gl(self.g, edges[:-1], edges[1:])
            halves = _gl(self.g, edges[:-1], mid) + _gl(self.g, mid, edges[1:])
            gmax = float(np.max(np.abs(self.g(edges))))
            err = float(np.sum(np.abs(whole - halves)))
            if err <= 1e-16 * (hi - lo + h) * max(gmax, 1e-300) or h < 1e-6 * (hi - lo + 1):
                break
            h *= 0.5
        self.error = err
        cum = np.concatenate([[0.0], np.cumsum(halves)])
        cum -= cum[-k0]  # G(0) = 0: edges[-k0] is 0 (k0 <= 0)
        k = np.clip(np.floor(x / h).astype(int) - k0, 0, len(edges) - 2)
        return cum[k] + _gl(self.g, edges[k], x)
