"""Metrics of systems of bodies, computed by the suite from the states of a run
(:class:`references.trajectory.Trajectory`) and the scenario
(:class:`scenarios.SystemScenario`), identically for every engine. The columns are those of
one body where the meaning carries over (the largest over the bodies) and three more:

=========================  ============================================================  =====
``energy_drift_max``       max_t |E(t) - E0| / E_c, E0 of the scenario's initial state,   1
                           E_c :attr:`SystemScenario.energy_scale` (never E0); E with
                           the force elements' potential; NaN with a damper
``momentum_drift_max``     the conserved momenta's largest drift: floating, |L_G - L_G0|   1
                           / L_c (about the moving centre of mass) and |p - p0 - m g t|
                           / p_c; hanging from one point joint, the angular momentum
                           about that point along g (every component without gravity)
                           / L_c; NaN when no momentum is conserved (a closed loop, a
                           hinge not along g, a force element to the ground)
``orthonormality_max``     max over t and bodies of ||R^T R - 1||_F                       1
``attitude_error_max``     max over t <= the reference's trusted horizon and bodies of    rad
                           the geodesic angle to the reference (as for one body)
``omega_error_max``        the same of |W - W_ref|                                        rad/s
``position_error_max``     the same of |x_G - x_G,ref|                                    m
``joint_gap_max``          max over t and every joint, loop closures included, of the     m
                           distance between its two anchor points (the distance of b's
                           point from a's axis line for cylindrical and prismatic)
``joint_angle_gap_max``    max over t and joints of the angle between a hinge's (or a     rad
                           cylindrical or prismatic joint's) two axes; a universal
                           joint's departure from perpendicular axes
``joint_coordinate_error_``  max over t <= the horizon and every joint (loop closures        rad
``max``                    included) of the angle between the run's relative rotation
                           R_a^T R_b of the joint's two bodies and the reference's (a
                           slider's travel is in position_error_max); for a hinge
                           |q - q_ref|; per joint in a robot model's run file
                           (``joint_coordinate_error.<joint>``)
``branch_error``           a mechanism through a singular configuration: for a            rad
                           parallelogram four-bar (a scenario tagged ``parallelogram``
                           with a body ``coupler``), the largest rotation of the coupler
                           from its initial attitude (it translates on the parallelogram
                           branch and turns on the crossed one); NaN otherwise
=========================  ============================================================  =====

The joints' rules are those of the scenario layer (:func:`scenarios.system.joint_residuals`).
"""

from __future__ import annotations

import math

import numpy as np

from references.trajectory import system_energy, system_momenta
from reports.metrics.body import attitude_error, gram, nearest_rotation
from reports.metrics.catalog import SYSTEM_METRICS, by_name, check_attached, measure, measures
from scenarios import force_elements as fe
from scenarios.system import joint_residuals

__all__ = ["SYSTEM_METRICS", "compute_system_metrics", "error_series"]


def _initial(scenario):
    """The scenario's initial state as a one-sample trajectory."""
    from references.trajectory import Trajectory

    bs = scenario.bodies
    return Trajectory(
        [0.0], [[b.position for b in bs]], [[b.velocity for b in bs]],
        [[b.rotation for b in bs]], [[b.omega_body for b in bs]], scenario.body_names,
    )  # fmt: skip


@measures("energy_drift_max", on="system")
def energy_drift(scenario, traj) -> np.ndarray | None:
    """|E(t) - E0| / E_c, (n,); None where no energy is conserved (a damper dissipates it) or
    the saved states are too far apart to count a torqued joint's turns (its work, tau
    theta, would be miscounted)."""
    if fe.dissipative(scenario) or not _turns_counted(scenario, traj):
        return None
    E0 = float(system_energy(scenario, _initial(scenario))[0])
    return np.abs(system_energy(scenario, traj) - E0) / scenario.energy_scale


def _turns_counted(scenario, traj) -> bool:
    """Every torqued joint turns less than pi/2 between two saved states."""
    by = {j.name: j for j in scenario.joints}
    return all(
        fe.angle_steps_ok(fe.joint_angle(scenario.bodies, by[t.joint], traj.rotation))
        for t in getattr(scenario, "torques", ())
    )


def energy(scenario, traj) -> np.ndarray:
    """E(t) - E0, J, (n,) (the figure's series)."""
    E0 = float(system_energy(scenario, _initial(scenario))[0])
    return system_energy(scenario, traj) - E0


@measures("momentum_drift_max", on="system")
def momentum_drift(scenario, traj) -> np.ndarray | None:
    """The drift of the conserved momenta over their scales, (n,), or None (module
    docstring)."""
    init = _initial(scenario)
    if fe.grounded(scenario):
        return None
    if scenario.floating:
        m = scenario.total_mass
        p0, L0 = system_momenta(scenario, init, np.zeros(3))
        p, L = system_momenta(scenario, traj, np.zeros(3))
        xc = np.einsum("b,nbi->ni", [b.mass for b in scenario.bodies], traj.position) / m
        LG = L - np.cross(xc, p)
        LG0 = L0[0] - np.cross(scenario.centre_of_mass, p0[0])
        dp = p - p0[0] - m * np.outer(traj.t, scenario.gravity)
        return np.maximum(
            np.linalg.norm(LG - LG0, axis=1) / scenario.momentum_scale,
            np.linalg.norm(dp, axis=1) / scenario.linear_momentum_scale,
        )
    point = scenario.ground_point
    ground = [j for j in scenario.joints if j.body_b is None]
    if point is None or ground[0].kind not in ("spherical", "fixed_point"):
        return None
    _, L0 = system_momenta(scenario, init, point)
    _, L = system_momenta(scenario, traj, point)
    d = L - L0[0]
    if scenario.has_gravity:
        g = np.asarray(scenario.gravity) / np.linalg.norm(scenario.gravity)
        return np.abs(d @ g) / scenario.momentum_scale
    return np.linalg.norm(d, axis=1) / scenario.momentum_scale


def joint_gaps(scenario, traj) -> dict[str, dict[str, np.ndarray]]:
    """Every joint's residuals over time, {joint name: {"gap": m, "angle": rad}}."""
    index = {b.name: i for i, b in enumerate(scenario.bodies)}
    return {
        j.name: joint_residuals(scenario.bodies, j, traj.position, traj.rotation, index=index)
        for j in scenario.joints
    }


@measures("joint_gap_max", on="system")
def joint_gap(scenario, traj) -> np.ndarray | None:
    """The largest anchor gap over the joints, loop closures included (m), (n,), or None
    without joints."""
    gaps = joint_gaps(scenario, traj)
    return np.max([g["gap"] for g in gaps.values()], axis=0) if gaps else None


@measures("joint_angle_gap_max", on="system")
def joint_angle_gap(scenario, traj) -> np.ndarray | None:
    """The largest axes gap over the joints (rad), (n,), or None without joints."""
    gaps = joint_gaps(scenario, traj)
    return np.max([g["angle"] for g in gaps.values()], axis=0) if gaps else None


def loop_gap(scenario, traj) -> np.ndarray | None:
    """The largest gap of the loop closures over time (m), (n,), or None for a tree: the
    figure's series of how far a loop drifts open."""
    if not scenario.loop_joints:
        return None
    gaps = joint_gaps(scenario, traj)
    return np.max([gaps[n]["gap"] for n in scenario.loop_joints], axis=0)


@measures("orthonormality_max", on="system")
def orthonormality(traj) -> np.ndarray:
    """max over bodies of ||R^T R - 1||_F, (n,)."""
    R = traj.rotation
    E = gram(R.reshape(-1, 3, 3)).reshape(R.shape) - np.eye(3)
    return np.max(np.linalg.norm(E, axis=(2, 3)), axis=1)


def _per_body_attitude(traj, ref) -> np.ndarray:
    n, nb = traj.rotation.shape[:2]

    class _Flat:  # the single-body metric on the bodies stacked
        def __init__(self, R):
            self.rotation = R.reshape(n * nb, 3, 3)

    return attitude_error(_Flat(traj.rotation), _Flat(ref.rotation)).reshape(n, nb)


@measures("attitude_error_max", on="system")
def attitude_errors(traj, ref) -> np.ndarray:
    """Largest attitude error over the bodies (rad), (n,)."""
    return np.max(_per_body_attitude(traj, ref), axis=1)


@measures("position_error_max", on="system")
def position_errors(traj, ref) -> np.ndarray:
    return np.max(np.linalg.norm(traj.position - ref.position, axis=2), axis=1)


@measures("omega_error_max", on="system")
def omega_errors(traj, ref) -> np.ndarray:
    return np.max(np.linalg.norm(traj.omega_body - ref.omega_body, axis=2), axis=1)


def joint_coordinate_error_by_joint(scenario, traj, ref) -> dict[str, np.ndarray]:
    """{joint name: the error of its relative rotation (rad), (n,)} for every joint. The
    ground has R = 1."""
    idx = {n: i for i, n in enumerate(scenario.body_names)}
    n = len(traj.t)
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))

    def rel(tr, j):
        Ra = tr.rotation[:, idx[j.body_a]]
        Rb = eye if j.body_b is None else tr.rotation[:, idx[j.body_b]]
        return np.einsum("nji,njk->nik", Ra, Rb)

    class _Flat:  # the single-body metric on the relative rotations
        def __init__(self, R):
            self.rotation = R

    return {
        j.name: attitude_error(_Flat(rel(traj, j)), _Flat(rel(ref, j))) for j in scenario.joints
    }


@measures("joint_coordinate_error_max", on="system")
def joint_coordinate_errors(scenario, traj, ref) -> np.ndarray | None:
    """Largest error of a joint's relative rotation over the joints (rad), (n,), or None
    without joints."""
    if not scenario.joints:
        return None
    return np.max(list(joint_coordinate_error_by_joint(scenario, traj, ref).values()), axis=0)


@measures("branch_error", on="system")
def branch_error(scenario, traj) -> np.ndarray | None:
    """The four-bar's branch check (module docstring), rad, (n,), or None."""
    if "parallelogram" not in scenario.tags or "coupler" not in scenario.body_names:
        return None
    i = scenario.body_names.index("coupler")
    Q = nearest_rotation(traj.rotation[:, i])
    R0 = scenario.bodies[i].rotation
    d = np.linalg.norm(Q - R0[None], axis=(1, 2)) / (2.0 * math.sqrt(2.0))
    return 2.0 * np.arcsin(np.clip(d, 0.0, 1.0))


def _inside(traj, ref):
    """The samples of ``traj`` and ``ref.trajectory`` up to the reference's trusted horizon
    (the reference must be sampled at the run's times)."""
    rt = ref.trajectory
    if len(rt) != len(traj) or not np.allclose(rt.t, traj.t, rtol=0, atol=1e-9):
        raise ValueError("the system reference is sampled at other times than the run")
    k = int(np.searchsorted(traj.t, ref.horizon * (1 + 1e-12), side="right"))
    return traj.head(k), rt.head(k)


def compute_system_metrics(scenario, traj, ref=None, keep: dict | None = None) -> dict[str, float]:
    """Every metric of one system run: each system metric of the catalog
    (:mod:`reports.metrics.catalog`; the module docstring) as its largest value over the
    samples, those against the reference over the samples up to its trusted horizon, NaN
    where it does not apply. ``ref``: the
    :class:`references.engines.exact.system.SystemReference` at the same times, or None
    (error metrics NaN). ``keep``: a dict that receives the per-sample series of the metrics
    not against the reference (metric name: series, None where one does not apply), for
    :func:`error_series` to reuse."""
    values, series = measure(scenario, traj, ref, window=_inside)
    if keep is not None:
        keep.update({m: v for m, v in series.items() if not by_name(m).reference})
    return values


def error_series(scenario, traj, ref=None, kept: dict | None = None) -> dict[str, np.ndarray]:
    """Per-sample series of one system run, written beside its trajectory so that figures
    are pure functions of files: energy (E - E0, J) and its drift, momentum drift, joint and
    loop gaps (m), and, with a reference, the attitude error (NaN beyond its horizon).
    ``kept``: the series :func:`compute_system_metrics` kept for the same run (its ``keep``),
    reused instead of computed again; the same functions give the same arrays."""
    kept = kept or {}

    def series(name, fn, *args):
        return kept[name] if name in kept else fn(*args)

    cols = {
        "energy_change": energy(scenario, traj),
        "orthonormality": series("orthonormality_max", orthonormality, traj),
    }
    ed = series("energy_drift_max", energy_drift, scenario, traj)
    if ed is not None:  # none where no energy is conserved (a damper)
        cols["energy_drift"] = ed
    md = series("momentum_drift_max", momentum_drift, scenario, traj)
    if md is not None:
        cols["momentum_drift"] = md
    gap = series("joint_gap_max", joint_gap, scenario, traj)
    if gap is not None:
        cols["joint_gap"] = gap
    lg = loop_gap(scenario, traj)
    if lg is not None:
        cols["loop_gap"] = lg
    if ref is not None:
        inside = traj.t <= ref.horizon * (1 + 1e-12)
        err = attitude_errors(traj, ref.trajectory)
        cols["attitude_error"] = np.where(inside, err, np.nan)
        # a robot model's figure reads them (reports.report.model_plots): its runs only
        model = getattr(scenario, "model", None) is not None
        per = joint_coordinate_error_by_joint(scenario, traj, ref.trajectory) if model else {}
        if per:
            cols["joint_coordinate_error"] = np.where(
                inside, np.max(list(per.values()), axis=0), np.nan
            )
            for name, e in per.items():
                cols[f"joint_coordinate_error.{name}"] = np.where(inside, e, np.nan)
    return cols


check_attached("system")
