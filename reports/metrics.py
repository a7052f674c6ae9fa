"""Metrics computed by the suite from trajectories, identically for every engine.

Every function takes trajectories in the suite's schema (:class:`references.Trajectory`) and the
:class:`scenarios.Scenario` they came from; none trusts a value reported by an engine. Drifts
are measured against the scenario's own initial state (computed the suite's way), not against
the engine's first saved sample, so an engine that builds the initial state wrongly shows it.

Column names of :func:`compute_metrics` (all "lower is better" except ``convergence_order``):

==========================  ===============================================================
``energy_drift_max``        max_t |E(t) - E0| / max(|E0|, T0)              (relative)
``momentum_drift_max``      max_t of the drift of the conserved angular-momentum components,
                            divided by |L0| (see :func:`conserved_momentum`)  (relative)
``orthonormality_max``      max_t ||R^T R - 1||_F
``attitude_error_max``      max_t geodesic angle between R and R_ref, rad
``omega_error_max``         max_t |W - W_ref|, rad/s
``position_error_max``      max_t |x_G - x_G,ref|, m
``flip_interval_error``     |flip interval - exact| / exact (free asymmetric bodies that flip)
``nutation_period_error``   |nutation period - exact| / exact (Lagrange tops)
``convergence_order``       slope of log(attitude_error_max) against log(dt) over a dt sweep
==========================  ===============================================================
"""

from __future__ import annotations

import math

import numpy as np

from references.trajectory import angular_momentum, energy

METRIC_COLUMNS = (
    "energy_drift_max",
    "momentum_drift_max",
    "orthonormality_max",
    "attitude_error_max",
    "omega_error_max",
    "position_error_max",
    "flip_interval_error",
    "nutation_period_error",
    "convergence_order",
)

#: Metrics where a larger value is better; every other metric is an error (lower is better).
HIGHER_IS_BETTER = frozenset({"convergence_order"})


def _initial(scenario):
    """(E0, T0, L0) of the scenario's initial state, computed the suite's way."""
    x = scenario.position[None]
    v = scenario.velocity[None]
    R = scenario.rotation[None]
    W = scenario.omega_body[None]
    E0 = float(energy(scenario, x, v, R, W)[0])
    T0 = 0.5 * scenario.mass * float(v[0] @ v[0]) + 0.5 * float(W[0] @ (scenario.inertia * W[0]))
    L0 = angular_momentum(scenario, x, v, R, W)[0]
    return E0, T0, L0


def energy_drift(scenario, traj) -> np.ndarray:
    """|E(t) - E0| / max(|E0|, T0), shape (n,). The kinetic energy T0 guards the scale when the
    potential's zero makes E0 small."""
    E0, T0, _ = _initial(scenario)
    scale = max(abs(E0), T0)
    if scale == 0.0:
        scale = 1.0
    return np.abs(traj.energy - E0) / scale


def conserved_momentum(scenario) -> str:
    """Which angular-momentum components the scenario conserves.

    - a free body (no pivot): all of L about the centre of mass (uniform gravity exerts no
      torque about it): ``"L"``;
    - a pivoted body without gravity: all of L about the pivot: ``"L"``;
    - a pivoted body with gravity: the component along gravity, ``"Lg"``, and, for a body
      symmetric about the axis through the pivot and the centre of mass
      (:attr:`Scenario.top_axis`), also the spin L . d_k: ``"Lg+spin"``.
    """
    if scenario.pivot is None or not scenario.has_gravity:
        return "L"
    return "Lg" if scenario.top_axis is None else "Lg+spin"


def momentum_drift(scenario, traj) -> np.ndarray:
    """Drift of the conserved angular-momentum components relative to |L0|, shape (n,)."""
    _, _, L0 = _initial(scenario)
    scale = float(np.linalg.norm(L0)) or 1.0
    which = conserved_momentum(scenario)
    L = traj.angular_momentum
    if which == "L":
        return np.linalg.norm(L - L0, axis=1) / scale
    g = scenario.gravity / np.linalg.norm(scenario.gravity)
    drift = np.abs(L @ g - L0 @ g)
    if which == "Lg+spin":
        k = scenario.top_axis
        spin = np.einsum("ni,ni->n", L, traj.rotation[:, :, k])
        spin0 = L0 @ scenario.rotation[:, k]
        drift = np.maximum(drift, np.abs(spin - spin0))
    return drift / scale


def orthonormality(traj) -> np.ndarray:
    """||R^T R - 1|| (Frobenius) at each saved time, shape (n,)."""
    RtR = np.einsum("nki,nkj->nij", traj.rotation, traj.rotation)
    return np.linalg.norm(RtR - np.eye(3), axis=(1, 2))


def attitude_error(traj, ref) -> np.ndarray:
    """Geodesic angle between R and R_ref, rad, shape (n,).

    Uses ||R - R_ref||_F = 2 sqrt(2) sin(theta/2), accurate for small angles, unlike the
    arccos of the trace (which loses half the digits near zero)."""
    d = np.linalg.norm(traj.rotation - ref.rotation, axis=(1, 2)) / (2.0 * math.sqrt(2.0))
    return 2.0 * np.arcsin(np.clip(d, 0.0, 1.0))


def omega_error(traj, ref) -> np.ndarray:
    """|W - W_ref| in body axes, rad/s, shape (n,)."""
    return np.linalg.norm(traj.omega_body - ref.omega_body, axis=1)


def position_error(traj, ref) -> np.ndarray:
    """|x_G - x_G,ref|, m, shape (n,)."""
    return np.linalg.norm(traj.position - ref.position, axis=1)


def _max(a) -> float:
    a = np.asarray(a)
    if a.size == 0:
        return math.nan
    # A non-finite sample means the run blew up: say so with inf rather than hide it.
    if not np.all(np.isfinite(a)):
        return math.inf
    return float(np.max(a))


def _check_same_times(traj, ref):
    if len(traj) != len(ref) or not np.allclose(traj.t, ref.t, rtol=0, atol=1e-9):
        raise ValueError(
            f"reference sampled at other times than the trajectory "
            f"({len(ref)} vs {len(traj)} samples); evaluate the reference at traj.t"
        )


def compute_metrics(scenario, traj, ref=None, expected=None) -> dict[str, float]:
    """All per-run metrics of one trajectory (see the module docstring).

    ``ref`` is the reference trajectory at the same times (None: error metrics are NaN);
    ``expected`` maps observable names ("flip_interval", "nutation_period") to exact values,
    as given by :func:`references.exact.expected_observables`.
    """
    m = {
        "energy_drift_max": _max(energy_drift(scenario, traj)),
        "momentum_drift_max": _max(momentum_drift(scenario, traj)),
        "orthonormality_max": _max(orthonormality(traj)),
        "attitude_error_max": math.nan,
        "omega_error_max": math.nan,
        "position_error_max": math.nan,
        "flip_interval_error": math.nan,
        "nutation_period_error": math.nan,
    }
    if ref is not None:
        _check_same_times(traj, ref)
        m["attitude_error_max"] = _max(attitude_error(traj, ref))
        m["omega_error_max"] = _max(omega_error(traj, ref))
        m["position_error_max"] = _max(position_error(traj, ref))
    expected = expected or {}
    if "flip_interval" in expected:
        from reports.observables import flip_interval

        got = flip_interval(traj)
        m["flip_interval_error"] = abs(got - expected["flip_interval"]) / expected["flip_interval"]
    if "nutation_period" in expected and scenario.top_axis is not None:
        from reports.observables import nutation_period

        got = nutation_period(traj, scenario.top_axis)
        exp = expected["nutation_period"]
        m["nutation_period_error"] = abs(got - exp) / exp
    return m


def convergence_order(dts, errors, floor: float = 1e-13, min_local_slope: float = 0.5) -> float:
    """Least-squares slope of log(error) against log(dt) over the asymptotic range.

    Points are taken from the largest dt downwards while the error keeps falling with a local
    slope of at least ``min_local_slope``; the first point that does not is where round-off
    (amplified by the conditioning of the problem: near the Dzhanibekov separatrix a solver
    saturates around 1e-11..1e-9 rad, numerics.md section 4) dominates the truncation error,
    and it and all smaller steps are dropped, as is any point within 10x of that floor.
    Points below ``floor`` or not finite are
    dropped too. NaN if fewer than two points remain.
    """
    dts = np.asarray(dts, dtype=float)
    errors = np.asarray(errors, dtype=float)
    ok = np.isfinite(errors) & (errors > floor) & (dts > 0)
    order = np.argsort(-dts[ok])
    h, e = dts[ok][order], errors[ok][order]
    keep = 1 if h.size else 0
    while keep < h.size:
        if h[keep] == h[keep - 1]:
            break
        local = np.log(e[keep - 1] / e[keep]) / np.log(h[keep - 1] / h[keep])
        if local < min_local_slope:
            break
        keep += 1
    if keep < h.size:
        # A floor was met at h[keep]: a point within 10x of it may already be half floor (its
        # apparent slope exaggerated), so it does not count either.
        while keep > 0 and e[keep - 1] < 10.0 * e[keep]:
            keep -= 1
    if keep < 2:
        return math.nan
    slope, _ = np.polyfit(np.log(h[:keep]), np.log(e[:keep]), 1)
    return float(slope)
