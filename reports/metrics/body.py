"""Metrics computed by the suite from trajectories, identically for every engine.

Every function takes one body's states (:class:`references.trajectory.OneBody`: (n, 3),
(n, 3, 3) arrays) and the :class:`scenarios.Scenario` they came from; the entry points
(:func:`compute_metrics`, :func:`series`, :func:`metrics_and_series`) take the run's
trajectory in the suite's schema (:class:`references.trajectory.Trajectory`, the scene's one
body on the bodies axis) and read it through :func:`references.trajectory.one_body`; none
trusts a value reported by an engine. Drifts
are measured against the scenario's own initial state (computed the suite's way), not against
the engine's first saved sample, so an engine that builds the initial state wrongly shows it.
Each has a physical scale, the scenario's (:class:`scenarios.model.Scenario`), never a
quantity that may vanish (an initial energy of 0, an initial momentum of 0).

Each metric is declared in the metric catalog (:mod:`scenarios.metric_catalog`: unit, scale,
round-off floor, default tolerance, title) and computed by the function here that names it in
``@measures``, whose docstring gives its formula; :func:`compute_metrics` computes them all
(docs/results.md tables them).

The energy-momentum scheme of the director model conserves its own energy, written with the
director velocities D', to round-off; its D' leaves the tangent space at O(h^2) (the velocity
constraint is not enforced at the nodes), and the suite's energy, computed from W (the skew
part of D^T D'), therefore shows an O(h^2) drift that ``constraint_velocity_max`` explains.
"""

from __future__ import annotations

import math

import numpy as np

from references.trajectory import angular_momentum, energy, energy_parts, one_body
from reports.metrics.catalog import (  # the tables: re-exported for the modules reading them here
    FLOORS,  # noqa: F401
    HIGHER_IS_BETTER,  # noqa: F401
    ORDER_SLACK,  # noqa: F401
    check_attached,
    computed,
    measure,
    measures,
)

#: attitude errors at or above this (rad) are saturated, not in the asymptotic range of a
#: convergence fit (an error of order 1 rad says the phase is lost, not how fast it is)
SATURATION = 0.1


def _initial(scenario):
    """(E0, L0) of the scenario's initial state, computed the suite's way."""
    x = scenario.position[None]
    v = scenario.velocity[None]
    R = scenario.rotation[None]
    W = scenario.omega_body[None]
    E0 = float(energy(scenario, x, v, R, W)[0])
    L0 = angular_momentum(scenario, x, v, R, W)[0]
    return E0, L0


@measures("energy_drift_max")
def energy_drift(scenario, traj) -> np.ndarray:
    """|E(t) - E0| / E_c with E_c = :attr:`Scenario.energy_scale`, shape (n,)."""
    E0, _ = _initial(scenario)
    return np.abs(traj.energy - E0) / scenario.energy_scale


@measures("energy_drift_rot_max", part="rot")
@measures("energy_drift_trans_max", part="trans")
def energy_part_drift(scenario, traj, part: str) -> np.ndarray | None:
    """|E_part(t) - E_part(0)| over the part's own scale (:attr:`Scenario.energy_scales`),
    shape (n,), for ``part`` "rot" or "trans" of a free body: uniform gravity exerts no torque
    about the centre of mass, so the rotational and the translational energy are conserved
    apart, and an error in one is measured against what is in play in that one (a fall of
    240 J does not hide a rotational error of 0.1 J, nor the reverse). None for a pivoted
    body, whose rotation and translation exchange energy."""
    if scenario.pivot is not None:
        return None
    x, v, R, W = (scenario.position, scenario.velocity, scenario.rotation, scenario.omega_body)
    p0 = energy_parts(scenario, x[None], v[None], R[None], W[None])[part][0]
    p = energy_parts(scenario, traj.position, traj.velocity, traj.rotation, traj.omega_body)
    return np.abs(p[part] - p0) / scenario.energy_scales[part]


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


@measures("momentum_drift_max")
def momentum_drift(scenario, traj) -> np.ndarray:
    """Drift of the conserved angular-momentum components over L_c =
    :attr:`Scenario.momentum_scale`, shape (n,): |L - L0| for "L"; for "Lg+spin" the larger of
    the drifts of the vertical component and of the spin."""
    _, L0 = _initial(scenario)
    scale = scenario.momentum_scale
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


@measures("linear_momentum_drift_max")
def linear_momentum_drift(scenario, traj) -> np.ndarray | None:
    """A free body's |m (v_G - v_G0 - g t)| / p_c, shape (n,): uniform gravity is the only
    force on it, so m v_G - m g t is conserved. p_c = sqrt(2 m E_tr,c), the momentum of the
    largest translational kinetic energy over the horizon
    (:attr:`Scenario.translational_energy_scale`, never 0). Sees what the translational
    energy cannot: a velocity turned without changing its length (e.g. reported in body
    axes). None for a pivoted body, whose pivot pushes it."""
    if scenario.pivot is not None:
        return None
    dv = traj.velocity - scenario.velocity - np.outer(traj.t, scenario.gravity)
    p_c = math.sqrt(2.0 * scenario.mass * scenario.translational_energy_scale)
    return scenario.mass * np.linalg.norm(dv, axis=1) / p_c


def gram(R) -> np.ndarray:
    """R^T R of each matrix of ``R`` (n, 3, 3), C-contiguous: entry (i, j) is
    (R_0i R_0j + R_1i R_1j) + R_2i R_2j, the products and the sum in the order in which
    ``np.einsum("nki,nkj->nij", R, R)`` forms them (bit for bit the same), as 30 operations on
    contiguous rows of n, several times faster than einsum's loop over the stack."""
    R = np.asarray(R, dtype=float)
    n = len(R)
    c = np.ascontiguousarray(R.reshape(n, 9).T)  # c[3 k + i] = R[:, k, i]
    out = np.empty((9, n))
    with np.errstate(all="ignore"):  # as quiet as einsum on a run that blew up (inf - inf)
        for i in range(3):
            for j in range(i, 3):
                out[3 * i + j] = (c[i] * c[j] + c[3 + i] * c[3 + j]) + c[6 + i] * c[6 + j]
                if j != i:
                    out[3 * j + i] = out[3 * i + j]
    return np.ascontiguousarray(out.T).reshape(n, 3, 3)


@measures("orthonormality_max")
def orthonormality(traj) -> np.ndarray:
    """||R^T R - 1|| (Frobenius) at each saved time, shape (n,)."""
    return np.linalg.norm(gram(traj.rotation) - np.eye(3), axis=(1, 2))


@measures("constraint_velocity_max")
def constraint_velocity(scenario, traj) -> np.ndarray:
    """The velocity-constraint residual ||D^T D' + D'^T D|| over the rate scale, shape (n,)."""
    return np.asarray(traj.constraint_velocity) / scenario.rate_scale


#: below this ||R^T R - 1||_F the polar factor is summed as a series (truncation error
#: 35/128 ||E||^4 < 3e-17): exactly R when R^T R = 1 in floating point, so an orthonormal R
#: is measured without the SVD's own rounding (a few ulp)
POLAR_SERIES = 1e-4


def _det3(R) -> np.ndarray:
    """det R of each matrix of ``R`` (n, 3, 3) by the rule of Sarrus, vectorised over n
    (np.linalg.det factorises each 3x3 matrix apart, ten times slower here). Only its sign
    is used, where ||R^T R - 1|| < :data:`POLAR_SERIES`: there |det R| > 0.999, far from
    the rounding of either formula."""
    a, b, c = R[:, 0, 0], R[:, 0, 1], R[:, 0, 2]
    d, e, f = R[:, 1, 0], R[:, 1, 1], R[:, 1, 2]
    g, h, i = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def nearest_rotation(R) -> np.ndarray:
    """The rotation nearest to each matrix of ``R`` (n, 3, 3) in the Frobenius norm: the
    orthogonal factor Q = R (R^T R)^(-1/2) of its polar decomposition. With E = R^T R - 1
    small (:data:`POLAR_SERIES`) and det R > 0, Q = R (1 - E/2 + 3 E^2/8 - 5 E^3/16); else
    from the SVD R = U S V^T, Q = U diag(1, 1, det(U V^T)) V^T (the sign keeps Q a rotation).
    A non-finite matrix gives NaN."""
    # contiguous, as the selections it replaces were: matmul's arithmetic may depend on it
    R = np.ascontiguousarray(R, dtype=float)
    ok = np.isfinite(R).all(axis=(1, 2))
    if not ok.all():
        out = np.full(R.shape, np.nan)
        if ok.any():
            out[ok] = nearest_rotation(R[ok])
        return out
    E = gram(R) - np.eye(3)
    near = (np.linalg.norm(E, axis=(1, 2)) < POLAR_SERIES) & (_det3(R) > 0)
    if near.all():  # the usual case: no selection (a copy of each array) needed
        E2 = E @ E
        return R @ (np.eye(3) - 0.5 * E + 0.375 * E2 - 0.3125 * (E2 @ E))
    Q = np.empty_like(R)
    if near.any():
        En = E[near]
        E2 = En @ En
        Q[near] = R[near] @ (np.eye(3) - 0.5 * En + 0.375 * E2 - 0.3125 * (E2 @ En))
    far = ~near
    U, _, Vt = np.linalg.svd(R[far])
    U[:, :, 2] *= np.sign(np.linalg.det(U @ Vt))[:, None]
    Q[far] = U @ Vt
    return Q


def _nearest_kept(traj) -> np.ndarray:
    """:func:`nearest_rotation` of ``traj.rotation``, kept on ``traj`` when that array is
    read-only (a reference the runner shares among the runs on its grid, whose arrays it
    makes read-only): computed once per reference, not once per run."""
    R = traj.rotation
    kept = getattr(traj, "_nearest_rotation", None)
    if kept is not None and kept[0] is R:
        return kept[1]
    Q = nearest_rotation(R)
    if isinstance(R, np.ndarray) and not R.flags.writeable:
        Q.setflags(write=False)
        traj._nearest_rotation = (R, Q)
    return Q


@measures("attitude_error_max")
def attitude_error(traj, ref) -> np.ndarray:
    """Geodesic angle between the rotations nearest to R and to R_ref
    (:func:`nearest_rotation`), rad, shape (n,). An R that is not orthonormal is measured by
    the rotation it stands for; its departure from orthonormality is :func:`orthonormality`'s,
    not counted twice. (The reference is projected too, so that equal matrices give 0.)

    Uses ||Q - Q_ref||_F = 2 sqrt(2) sin(theta/2) for rotations Q, Q_ref, accurate for small
    angles, unlike the arccos of the trace (which loses half the digits near zero)."""
    Q, Q_ref = nearest_rotation(traj.rotation), _nearest_kept(ref)
    d = np.linalg.norm(Q - Q_ref, axis=(1, 2)) / (2.0 * math.sqrt(2.0))
    return 2.0 * np.arcsin(np.clip(d, 0.0, 1.0))


@measures("omega_error_max")
def omega_error(traj, ref) -> np.ndarray:
    """|W - W_ref| in body axes, rad/s, shape (n,)."""
    return np.linalg.norm(traj.omega_body - ref.omega_body, axis=1)


@measures("position_error_max")
def position_error(traj, ref) -> np.ndarray:
    """|x_G - x_G,ref|, m, shape (n,)."""
    return np.linalg.norm(traj.position - ref.position, axis=1)


def _check_same_times(traj, ref):
    if len(traj) != len(ref) or not np.allclose(traj.t, ref.t, rtol=0, atol=1e-9):
        raise ValueError(
            f"reference sampled at other times than the trajectory "
            f"({len(ref)} vs {len(traj)} samples); evaluate the reference at traj.t"
        )


@measures("flip_interval_error")
def flip_interval_error(traj, expected) -> float:
    """|flip interval - exact| / exact, NaN without an exact flip interval."""
    if "flip_interval" not in expected:
        return math.nan
    from reports.metrics.observables import flip_interval

    exp = expected["flip_interval"]
    return abs(flip_interval(traj) - exp) / exp


@measures("nutation_period_error")
def nutation_period_error(scenario, traj, expected) -> float:
    """|nutation period - exact| / exact of a top (tilt from the scenario's vertical), NaN
    without an exact nutation period or a top axis."""
    if "nutation_period" not in expected or scenario.top_axis is None:
        return math.nan
    from reports.metrics.observables import nutation_period

    exp = expected["nutation_period"]
    return abs(nutation_period(traj, scenario.top_axis, scenario.vertical) - exp) / exp


def compute_metrics(scenario, traj, ref=None, expected=None) -> dict[str, float]:
    """All per-run metrics of one trajectory: every single-body metric of the catalog
    (:mod:`reports.metrics.catalog`; the module docstring), a pointwise one as its largest
    value over the samples (inf if one is not finite), NaN where it does not apply.

    ``ref`` is the reference trajectory at the same times (None: error metrics are NaN);
    ``expected`` maps observable names ("flip_interval", "nutation_period") to exact values,
    as given by :func:`references.exact.expected_observables`.
    """
    return metrics_and_series(scenario, traj, ref, expected)[0]


def series(scenario, traj, ref=None) -> dict[str, np.ndarray]:
    """The per-sample series of one run written beside its trajectory, so that figures are
    pure functions of files: {series name: values (n,)} of every catalog metric that
    declares a ``series`` and applies here (those against the reference only with one)."""
    traj, ref = one_body(traj), one_body(ref)
    out = {}
    for metric, fn in computed("body"):
        if metric.series is None or (metric.reference and ref is None):
            continue
        v = fn(scenario, traj, ref)
        if v is not None:
            out[metric.series] = v
    return out


def metrics_and_series(scenario, traj, ref=None, expected=None) -> tuple[dict, dict]:
    """(:func:`compute_metrics`, :func:`series`) of one run, each pointwise metric computed
    once for both: a metric's value is the largest of the very series written."""
    traj, ref = one_body(traj), one_body(ref)
    values, by_name = measure(scenario, traj, ref, expected or {}, window=_same_times)
    series = {}
    for metric, _ in computed("body"):
        v = by_name.get(metric.name)
        if v is not None and metric.series is not None:
            series[metric.series] = v
    return values, series


def _same_times(traj, ref):
    """The run and its reference, which must be sampled at the same times."""
    _check_same_times(traj, ref)
    return traj, ref


def roundoff_floor(scenario, nstep: int) -> float:
    """An estimate of the attitude error (rad) that round-off alone accumulates over ``nstep``
    steps: eps sqrt(nstep) (1 + w_c t_end), the rounding of a rotation of w_c t_end rad at
    every step added up as a random walk (what engines that renormalise show: e.g. 4e-13 rad
    for MuJoCo RK4 on free_tumbling after 1e4 steps)."""
    eps = float(np.finfo(float).eps)
    return eps * math.sqrt(float(nstep)) * (1.0 + scenario.rate_scale * scenario.t_end)


#: consecutive points whose error falls more slowly than this power of dt are not in the
#: asymptotic range (every consistent method has order >= 1)
MIN_LOCAL_SLOPE = 0.5
#: a local slope this much below the previous one means the smaller step met a floor: in the
#: asymptotic range successive local slopes agree (they differ by the next order's share)
MAX_SLOPE_DROP = 0.5


def convergence_order(dts, errors, floors=0.0, saturation: float = SATURATION):
    """Least-squares slope of log(error) against log(dt) over the asymptotic range, and the
    number of points it used: ``(slope, n)``; slope NaN when fewer than two points remain.

    A point is in range when its error is below ``saturation`` (larger errors say the phase
    is lost, not how fast it converges) and above 10 times its ``floors`` entry (the larger of
    the reference's accuracy and the round-off floor of that run): closer to the floor the
    error is part floor and its slope is flattened. Among those, the fit takes the points
    from the largest dt down while each local slope is at least :data:`MIN_LOCAL_SLOPE` and
    not :data:`MAX_SLOPE_DROP` below the previous one: an error that stops falling, or
    suddenly falls more slowly, has met a floor or a saturation the thresholds did not catch
    (round-off amplified near a separatrix, a nutation damped away whatever the step); a
    point within 10x of that floor counts as part floor.
    """
    dts = np.asarray(dts, dtype=float)
    errors = np.asarray(errors, dtype=float)
    floors = np.broadcast_to(np.asarray(floors, dtype=float), dts.shape)
    ok = np.isfinite(errors) & (dts > 0) & (errors > 0) & (errors < saturation)
    order = np.argsort(-dts[ok], kind="stable")
    h, e, f = dts[ok][order], errors[ok][order], floors[ok][order]
    # the walk sees every point, also those below the floor thresholds: a point that stops
    # falling marks a floor even where the estimate of the floor was too low
    keep = min(h.size, 1)
    previous = None
    while keep < h.size and h[keep] < h[keep - 1]:
        local = np.log(e[keep - 1] / e[keep]) / np.log(h[keep - 1] / h[keep])
        dropped = previous is not None and local < previous - MAX_SLOPE_DROP
        if local < MIN_LOCAL_SLOPE or dropped:
            break
        previous = local
        keep += 1
    if keep < h.size:
        # the error stopped falling at h[keep]: that is a floor, and a kept point within 10x
        # of it is already part floor (its slope exaggerated), so it does not count either
        while keep > 0 and e[keep - 1] < 10.0 * e[keep]:
            keep -= 1
    h, e = h[:keep][e[:keep] > 10.0 * f[:keep]], e[:keep][e[:keep] > 10.0 * f[:keep]]
    keep = h.size
    if keep < 2:
        return math.nan, int(keep)
    slope, _ = np.polyfit(np.log(h[:keep]), np.log(e[:keep]), 1)
    return float(slope), int(keep)


def add_convergence_orders(df):
    """Fill ``convergence_order`` and ``convergence_points`` per (scenario, engine,
    integrator) from the attitude errors of its ok runs over the dt values present. A contact
    scene whose exact motion is rest (a stick case: its runs have a ``creep_speed``) gets no
    order: its errors are the configuration's artefacts (creep, settling into a soft contact),
    not a discretisation error that shrinks with dt."""
    df = df.copy()
    orders = np.full(len(df), math.nan)
    points = np.full(len(df), math.nan)
    ok = (df["status"] == "ok").to_numpy()
    if "creep_speed" in df:
        ok = ok & df["creep_speed"].isna().to_numpy()
    at = np.flatnonzero(ok)  # positions in df of the ok rows
    dt = df["dt"].to_numpy(dtype=float)
    error = df["attitude_error_max"].to_numpy(dtype=float)
    floor = np.fmax(df["reference_accuracy"].to_numpy(dtype=float),
                    df["roundoff_floor"].to_numpy(dtype=float))  # fmt: skip
    floor[np.isnan(floor)] = 0.0
    # the groups' rows as positions, in table order (plain arrays: pandas' per-group
    # indexing and assignment cost ~30x the fits themselves)
    for pos in df[ok].groupby(["scenario", "engine", "integrator"]).indices.values():
        rows = at[pos]
        steps = dt[rows]
        if np.unique(steps[~np.isnan(steps)]).size < 2:
            continue
        orders[rows], points[rows] = convergence_order(steps, error[rows], floor[rows])
    df["convergence_order"] = orders
    df["convergence_points"] = points
    return df


check_attached("body")
