"""Phase observables measured from any trajectory in the suite's schema.

Pure functions of ``traj.t`` (n,), ``traj.rotation`` (n, 3, 3) and ``traj.omega_body`` (n, 3);
they never look at how the trajectory was made, so every engine is measured the same way.

Event times (sign changes, level crossings) are located by the cubic through the four samples
around the bracketing pair (two on each side, fewer at the ends of the record), solved by
bisection to round-off. For equally spaced samples h apart of a smooth signal y the error of
an event time is at most (3/128) h^4 max|y''''|/|y'| (the cubic interpolation remainder at
mid-interval divided by the slope), i.e. O(h^4): far below the sample spacing. With fewer
than four samples the linear interpolant is used.

Values that cannot be measured are NaN with a reason: each function returns a
:class:`Measured`, a ``float`` that also carries ``reason`` (empty when the value is valid)
and ``n`` (the number of events it is based on).

Symbols: W (body rates, rad/s), d_k = R e_k (the k-th director: body axis k in world axes),
up (the scenario's vertical -g/|g|, :attr:`scenarios.model.Scenario.vertical`: a required
argument, never a default axis, since a top under gravity along another axis nutates about
that one), u = d_k . up = cos(tilt), azimuth = angle of d_k about up.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "Measured",
    "crossings",
    "flip_axis",
    "flip_interval",
    "flip_times",
    "nutation_period",
    "precession_rate",
    "tilt_range",
]

#: Below this peak-to-peak variation of u the symmetry axis is taken as not nutating (a
#: steady precession, round-off only): crossings of its mean would be noise.
NUTATION_FLOOR = 1e-12


class Measured(float):
    """A measured value: a float, NaN when not measurable, with ``reason`` saying why and
    ``n`` the number of events used."""

    reason: str
    n: int

    def __new__(cls, value: float, reason: str = "", n: int = 0):
        obj = super().__new__(cls, value)
        obj.reason = reason
        obj.n = int(n)
        return obj

    def __repr__(self) -> str:
        if self.reason:
            return f"Measured(nan, reason={self.reason!r})"
        return f"Measured({float(self)!r}, n={self.n})"

    def __reduce__(self):
        return (Measured, (float(self), self.reason, self.n))


def _nan(reason: str, n: int = 0) -> Measured:
    return Measured(math.nan, reason, n)


# -- interpolation ----------------------------------------------------------------------------


def _stencils(i: np.ndarray, n: int) -> np.ndarray:
    """Indices of the 4-point stencils (i-1, i, i+1, i+2) shifted to lie inside [0, n)."""
    start = np.clip(i - 1, 0, max(n - 4, 0))
    return start[:, None] + np.arange(min(4, n))


class _Polynomials:
    """The polynomials through the nodes x (m, p) with values y (m, p), in Lagrange form:
    P(xq) = sum_j y_j prod_{k != j} (xq - x_k)/(x_j - x_k), the products taken in the order of
    k and the sum in the order of j. The node differences are formed once, for the many
    evaluations of a bisection."""

    def __init__(self, x: np.ndarray, y: np.ndarray):
        p = x.shape[1]
        self.x, self.y, self.p = x, y, p
        #: others[j]: the nodes k != j, in order
        self.others = np.array([[k for k in range(p) if k != j] for j in range(p)], dtype=int)
        self.den = x[:, :, None] - x[:, self.others] if p > 1 else None  # (m, p, p - 1)

    def __call__(self, xq: np.ndarray) -> np.ndarray:
        """P at xq (m,), one point per polynomial."""
        if self.p == 1:
            L = np.ones((len(xq), 1))
        else:
            r = (xq[:, None] - self.x)[:, self.others] / self.den  # (xq - x_k)/(x_j - x_k)
            L = r[:, :, 0]
            for c in range(1, self.p - 1):
                L = L * r[:, :, c]
        terms = self.y * L
        out = np.zeros(len(xq))
        for j in range(self.p):
            out += terms[:, j]
        return out


def _lagrange(x: np.ndarray, y: np.ndarray, xq: np.ndarray) -> np.ndarray:
    """Value at xq (m,) of the polynomial through the nodes x (m, p), values y (m, p)."""
    return _Polynomials(x, y)(xq)


def _interp(t: np.ndarray, y: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Cubic (4-point) interpolation of samples y(t) at times tq within [t0, t_end]."""
    i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
    st = _stencils(i, len(t))
    return _lagrange(t[st], y[st], tq)


def crossings(t, y, level: float = 0.0, direction: int = 0) -> np.ndarray:
    """Times at which the sampled signal y(t) crosses ``level``.

    ``direction``: +1 upward only (y - level goes from < 0 to >= 0), -1 downward only
    (from > 0 to <= 0), 0 both. A sample exactly at the level counts once. The time inside each
    bracketing interval is the root of the local cubic (see the module docstring), found by
    bisection down to round-off of the interval (at most 60 halvings; it stops early once
    a halving no longer moves the brackets). Non-finite samples are never bracketed.
    """
    t = np.asarray(t, dtype=float)
    s = np.asarray(y, dtype=float) - level
    if len(t) < 2:
        return np.empty(0)
    a, b = s[:-1], s[1:]
    up = (a < 0) & (b >= 0)
    down = (a > 0) & (b <= 0)
    mask = up if direction > 0 else down if direction < 0 else (up | down)
    i = np.flatnonzero(mask)
    if len(i) == 0:
        return np.empty(0)
    st = _stencils(i, len(t))
    x, v = t[st], s[st]
    lo, hi = t[i].copy(), t[i + 1].copy()
    slo = s[i]
    local = _Polynomials(x, v)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        smid = local(mid)
        same = np.sign(smid) == np.sign(slo)
        lo2 = np.where(same, mid, lo)
        slo2 = np.where(same, smid, slo)
        hi2 = np.where(same, hi, mid)
        # (lo, hi, slo) alone decide the next bisection: once one leaves them unchanged (the
        # brackets are adjacent floats), so would every later one of the 60
        if np.array_equal(lo2, lo) and np.array_equal(hi2, hi) and np.array_equal(slo2, slo):
            break
        lo, hi, slo = lo2, hi2, slo2
    return 0.5 * (lo + hi)


# -- the flip of a free body ------------------------------------------------------------------


def flip_axis(traj) -> int:
    """The body axis of the dominant rotation: the largest time-mean |W_i| (sample mean)."""
    W = np.asarray(traj.omega_body, dtype=float)
    return int(np.argmax(np.nanmean(np.abs(W), axis=0)))


def flip_times(traj, axis: int | None = None) -> np.ndarray:
    """Times at which the body rate about ``axis`` changes sign, interpolated (s).

    A flip (the Dzhanibekov effect) is a reversal of the dominant rotation. By default the axis
    is :func:`flip_axis`, the body axis with the largest mean |W_i|: for a body tumbling near
    its intermediate axis this is that axis, and for a stable spin the dominant rate never
    changes sign, so no flips are found (rather than the sign changes of a small wobble).
    Pass ``axis`` (0, 1 or 2) to follow a given body axis.
    """
    k = flip_axis(traj) if axis is None else int(axis)
    return crossings(traj.t, np.asarray(traj.omega_body, dtype=float)[:, k])


def flip_interval(traj, axis: int | None = None) -> Measured:
    """Mean time between successive sign changes of the dominant (or given) body rate, s:
    (last - first)/(number - 1). NaN with a reason if fewer than two are found."""
    W = np.asarray(traj.omega_body, dtype=float)
    if not np.all(np.isfinite(W)):
        return _nan("the body rates contain non-finite values")
    k = flip_axis(traj) if axis is None else int(axis)
    tf = flip_times(traj, k)
    if len(tf) < 2:
        return _nan(
            f"{len(tf)} sign change(s) of W_{k + 1} in [{traj.t[0]:g}, {traj.t[-1]:g}] s: at "
            "least 2 are needed (no flip, or a record shorter than a flip interval)",
            len(tf),
        )
    return Measured((tf[-1] - tf[0]) / (len(tf) - 1), n=len(tf))


# -- tops -------------------------------------------------------------------------------------


def _frame(up) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    e3 = np.asarray(up, dtype=float) if up is not None else np.zeros(0)
    norm = float(np.linalg.norm(e3)) if e3.shape == (3,) else 0.0
    if not (math.isfinite(norm) and norm > 0.0):
        raise ValueError(f"up = {up!r}: the vertical must be a finite non-zero 3-vector")
    e3 = e3 / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(e3[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ e3) * e3
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(e3, e1), e3


def _axis_signals(traj, axis: int, up):
    """u = d_k . up, sin(tilt) = |d_k x up|, and the azimuth of d_k about up (unwrapped)."""
    e1, e2, e3 = _frame(up)
    d = np.asarray(traj.rotation, dtype=float)[:, :, int(axis)]
    u = d @ e3
    x, y = d @ e1, d @ e2
    s = np.hypot(x, y)
    return u, s, np.unwrap(np.arctan2(y, x))


def _axis_cos(traj, axis: int, up) -> np.ndarray:
    """u = d_k . up alone (:func:`_axis_signals`' first signal, computed the same way),
    without the tilt and the azimuth that cost most of that function."""
    _, _, e3 = _frame(up)
    return np.asarray(traj.rotation, dtype=float)[:, :, int(axis)] @ e3


def _nutation_crossings(t, u):
    """Upward crossings of the mean of u, or a reason why there are none to use."""
    if not np.all(np.isfinite(u)):
        return None, "the rotations contain non-finite values"
    if np.ptp(u) < NUTATION_FLOOR:
        return None, (
            f"cos(tilt) varies by {np.ptp(u):.2g} < {NUTATION_FLOOR:g}: no nutation "
            "(steady precession or sleeping top)"
        )
    tc = crossings(t, u, level=float(np.mean(u)), direction=+1)
    if len(tc) < 2:
        return None, (
            f"{len(tc)} upward crossing(s) of the mean of cos(tilt): at least 2 are needed "
            "(a record shorter than one nutation period)"
        )
    return tc, ""


def nutation_period(traj, axis: int, up) -> Measured:
    """Nutation period, s: the mean spacing of the upward crossings of the mean of
    u = d_axis . up (cos of the tilt of body axis ``axis`` from the vertical ``up``). Any level
    strictly between the extremes recurs once per period; the mean is used because it lies
    where the slope is large, which makes the interpolated times accurate."""
    u = _axis_cos(traj, axis, up)
    tc, why = _nutation_crossings(np.asarray(traj.t, dtype=float), u)
    if tc is None:
        return _nan(why)
    return Measured((tc[-1] - tc[0]) / (len(tc) - 1), n=len(tc))


def tilt_range(traj, axis: int, up) -> tuple[Measured, Measured]:
    """(min, max) tilt of body axis ``axis`` from ``up``, rad, tilt = atan2(|d x up|, d . up).

    Each interior local extremum of the sampled tilt is refined by the vertex of the parabola
    through it and its two neighbours (error O(h^3) times the third derivative at worst); the
    record's end points count as sampled.
    """
    u, s, _ = _axis_signals(traj, axis, up)
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(s))):
        nan = _nan("the rotations contain non-finite values")
        return nan, nan
    th = np.arctan2(s, u)
    t = np.asarray(traj.t, dtype=float)
    cands_min, cands_max = [th[0], th[-1]], [th[0], th[-1]]
    if len(th) >= 3:
        a, b, c = th[:-2], th[1:-1], th[2:]
        for sel, store in (((b <= a) & (b <= c), cands_min), ((b >= a) & (b >= c), cands_max)):
            j = np.flatnonzero(sel) + 1
            if len(j):
                store.extend(_vertex(t[j - 1], t[j], t[j + 1], th[j - 1], th[j], th[j + 1]))
    n = len(th)
    return Measured(min(cands_min), n=n), Measured(max(cands_max), n=n)


def _vertex(t0, t1, t2, y0, y1, y2) -> np.ndarray:
    """Extreme value of the parabola through three points (arrays of equal shape); the middle
    value where the parabola is degenerate or its vertex lies outside [t0, t2]."""
    d0, d1 = (y1 - y0) / (t1 - t0), (y2 - y1) / (t2 - t1)
    a = (d1 - d0) / (t2 - t0)  # p(t) = y0 + d0 (t - t0) + a (t - t0)(t - t1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = 0.5 * (t0 + t1) - d0 / (2.0 * a)
        yv = y0 + (tv - t0) * (d0 + a * (tv - t1))
    inside = (a != 0) & np.isfinite(tv) & (tv >= t0) & (tv <= t2)
    return np.where(inside, yv, y1)


def precession_rate(traj, axis: int, up) -> Measured:
    """Mean rate of the azimuth of body axis ``axis`` about ``up``, rad/s (unwrapped).

    If the axis nutates, the mean is taken over whole nutation periods (between the first and
    the last upward crossing of the mean of cos(tilt), the azimuth interpolated there), so that
    it equals (precession per nutation)/(nutation period) without bias from a partial period.
    Otherwise (steady precession) it is (azimuth(end) - azimuth(start))/duration. NaN if the
    axis comes within 1e-8 rad of the vertical, where the azimuth is undefined.
    """
    u, s, az = _axis_signals(traj, axis, up)
    t = np.asarray(traj.t, dtype=float)
    if not np.all(np.isfinite(az)):
        return _nan("the rotations contain non-finite values")
    if np.min(s) < 1e-8:
        return _nan("the axis passes within 1e-8 rad of the vertical: azimuth undefined")
    tc, _ = _nutation_crossings(t, u)
    if tc is not None:
        a0, a1 = _interp(t, az, np.array([tc[0], tc[-1]]))
        return Measured((a1 - a0) / (tc[-1] - tc[0]), n=len(tc))
    if t[-1] <= t[0]:
        return _nan("the record has no duration")
    return Measured((az[-1] - az[0]) / (t[-1] - t[0]), n=len(t))
