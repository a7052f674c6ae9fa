"""Small numerical tools shared by the exact references: rotations about axes (vectorised),
Jacobi elliptic functions with argument reduction, and antiderivatives of smooth (periodic)
functions by composite Gauss-Legendre quadrature."""

from __future__ import annotations

import math

import numpy as np
from numpy.polynomial.legendre import leggauss
from scipy.special import ellipj, ellipkinc

EPS = float(np.finfo(float).eps)


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


def jacobi(u, m: float, m1: float, K: float):
    """sn, cn, dn of argument ``u`` (array) and parameter m = k^2, with m1 = 1 - m given
    separately (accurately) and K = K(m).

    scipy's ``ellipj`` takes only m, so near m = 1 the rounding of m shifts the quarter period
    and the phase error grows with u. Here u is reduced modulo 2K (with the accurate K) to
    |r| <= K, and for K/2 < |r| <= K the reflection sn(K - v) = cn v/dn v,
    cn(K - v) = k' sn v/dn v, dn(K - v) = k'/dn v (k' = sqrt(m1)) is used, so ``ellipj`` is only
    called with arguments <= K/2, where its sensitivity to the rounding of m is negligible.
    m1 = 0 (the separatrix) gives the hyperbolic limit sn = tanh, cn = dn = sech.
    """
    u = np.asarray(u, dtype=float)
    if m1 == 0.0:
        ch = np.cosh(u)
        return np.tanh(u), 1.0 / ch, 1.0 / ch
    n = np.round(u / (2.0 * K))
    r = u - 2.0 * K * n
    flip = np.where(np.mod(n, 2.0) == 0.0, 1.0, -1.0)  # sn, cn change sign every 2K
    ar = np.abs(r)
    sn = np.empty_like(ar)
    cn = np.empty_like(ar)
    dn = np.empty_like(ar)
    near = ar <= 0.5 * K
    s, c, d, _ = ellipj(ar[near], m)
    sn[near], cn[near], dn[near] = s, c, d
    far = ~near
    s, c, d, _ = ellipj(K - ar[far], m)
    kp = math.sqrt(m1)
    sn[far], cn[far], dn[far] = c / d, kp * s / d, kp / d
    sn *= np.sign(r) * flip
    cn *= flip
    return sn, cn, dn


def jacobi_inverse(s0: float, c0: float, m: float, m1: float, K: float) -> float:
    """The argument u in (-2K, 2K] with sn(u) ~ s0 and cn(u) ~ c0 (signs and ratio are used;
    s0^2 + c0^2 need only be 1 to round-off). Well conditioned near m = 1: the incomplete
    integral is only evaluated up to K/2, by the same reflection as :func:`jacobi`."""
    a_s, a_c = abs(s0), abs(c0)
    if m1 == 0.0:
        x = math.asinh(a_s / a_c) if a_c > 0 else math.inf
    else:
        kp = math.sqrt(m1)
        if a_s * math.sqrt(kp) <= a_c:
            x = float(ellipkinc(math.atan2(a_s, a_c), m))
        else:
            x = K - float(ellipkinc(math.atan2(a_c, kp * a_s), m))
        if c0 < 0:
            x = 2.0 * K - x
    return -x if s0 < 0 else x


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
