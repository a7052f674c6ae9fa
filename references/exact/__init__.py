"""Exact and high-accuracy reference solutions of scenarios.

:func:`reference_trajectory` returns a :class:`ReferenceTrajectory` (the suite's
:class:`references.trajectory.Trajectory` of the scene's one body, plus ``kind``, ``accuracy``,
``omega_accuracy``, ``method`` and ``reason``); :func:`expected_observables` gives exact
values of phase observables.

Reference kinds (``scenario.reference``, or the ``kind`` argument):

=====================  =====================================================================
``free_body``          torque-free body: Jacobi elliptic functions + Euler angles about L
                       (:mod:`references.exact.free_body`); centre of mass on the exact
                       parabola. Applies to every free body, with or without gravity (uniform
                       gravity does not torque about the centre of mass), and to a pivoted body
                       without gravity torque whose pivot lies on a principal axis.
``steady_precession``  closed-form steady precession of a Lagrange top,
                       R(t) = Rot(up, w_p t) R_0 Rot(e_k, w_s t) (:mod:`.lagrange_top`); the
                       state is verified to be a steady precession, not applicable otherwise.
``lagrange_top``       the closed form of a symmetric heavy top pivoted on its axis
                       (:mod:`.lagrange_top`): nutation by Jacobi functions, the attitude by
                       elliptic integrals of the third kind, regular through and near the
                       vertical; the planar physical pendulum; the steady precession.
``numerical``          DOP853 at rtol 1e-13 with an error estimate from six runs (10 rtol,
                       step halving, three round-off probes)
                       (:mod:`references.exact.numerical`); any scenario.
``auto``               free_body if there is no gravity torque and the above applies,
                       lagrange_top for a symmetric top pivoted on its axis, numerical
                       otherwise, and numerical whenever the closed form declines (a
                       measure-zero motion it does not treat, such as an axis starting exactly
                       vertical with transverse rates) or its evaluation is not finite.
=====================  =====================================================================

A kind that does not apply raises :class:`ReferenceNotApplicable` (a ``ValueError``) with the
reason when it was asked for explicitly (argument or file); ``auto`` never raises it, it
hands over to ``numerical``. Invalid input (times, unknown kind names) raises ``ValueError``.
``ReferenceTrajectory.reason`` says which kind was used and why, including any hand-over.

``accuracy`` is the estimated maximum error of the attitude over the returned times, in rad (the
angle of R_ref^T R_true); ``omega_accuracy`` that of the body rates, rad/s. Both are finite. For the
closed forms they are round-off estimates (16 eps per radian turned, see :meth:`FreeBody.accuracy`;
for an asymmetric free body also what the rounding of its modulus costs over the horizon,
:meth:`FreeBody.modulus_error`, which near the separatrix is where the digits go, and pi when it
cannot be told: ``auto`` then hands over); for the numerical reference twice the largest difference
between its runs (see :mod:`references.exact.numerical`).
tests/references/exact/test_exact_accuracy.py and tests/references/exact/test_exact_separatrix.py
check each estimate against independent solutions, from both sides: it covers the actual error and
exceeds it by at most a stated factor. Energy and angular momentum are computed by
:meth:`Trajectory.from_states`, exactly as for every engine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from references.exact import numerical
from references.exact._util import ReferenceNotApplicable
from references.exact.free_body import FreeBody, free_flight
from references.exact.lagrange_top import LagrangeTop, NotALagrangeTop
from references.trajectory import Trajectory

__all__ = [
    "CLOSED_FORMS",
    "KINDS",
    "FreeBody",
    "LagrangeTop",
    "NotALagrangeTop",
    "ReferenceNotApplicable",
    "ReferenceTrajectory",
    "expected_observables",
    "free_body_of",
    "reference_kept",
    "reference_trajectory",
    "resolve_kind",
]

KINDS = ("free_body", "steady_precession", "numerical", "lagrange_top")
CLOSED_FORMS = ("free_body", "steady_precession", "lagrange_top")

#: A closed form whose own accuracy estimate exceeds this (rad) is not trusted: ``auto`` hands
#: over to the numerical reference (whose estimate on the library is 4e-12 .. 3e-9).
ACCURACY_LIMIT = 1e-8

#: ``precession_rate`` is not given when the axis passes the vertical closer than this (rad):
#: the azimuth then turns by about +-pi within a short time at each passage, on the side
#: decided by errors of this size, so a measured mean rate is not comparable.
NEAR_VERTICAL = 1e-3


@dataclass
class ReferenceTrajectory(Trajectory):
    """A reference solution in the suite's trajectory schema (the scenario's one body on the
    bodies axis, its energy and momentum computed by :meth:`Trajectory.from_states`), with what
    it is, how good, and why that kind was used (``reason``, including any hand-over to the
    numerical reference). The single-body metrics read it through
    :func:`references.trajectory.one_body`."""

    kind: str = ""
    accuracy: float = math.nan
    method: str = ""
    omega_accuracy: float = math.nan
    reason: str = ""


def _torque_free_reason(scenario) -> str | None:
    """None if the rotation of ``scenario`` is torque-free with diagonal inertia (so the
    free-body solution applies), else the reason why not."""
    if scenario.pivot is None:
        return None
    c = np.asarray(scenario.pivot)
    if scenario.has_gravity and np.any(c != 0):
        return "gravity torques the body about its pivot"
    if np.count_nonzero(c) > 1:
        return "the pivot is not on a principal axis (the pivot inertia is not diagonal)"
    return None


def free_body_of(scenario) -> FreeBody:
    """The :class:`FreeBody` of a torque-free scenario (moments about the pivot if pivoted)."""
    reason = _torque_free_reason(scenario)
    if reason is not None:
        raise ReferenceNotApplicable(
            f"scenario {scenario.name!r}: free_body does not apply: {reason}"
        )
    I = np.diag(scenario.pivot_inertia).copy()
    try:
        return FreeBody(I, scenario.omega_body, scenario.rotation)
    except (ArithmeticError, ValueError) as exc:
        raise ReferenceNotApplicable(
            f"scenario {scenario.name!r}: the free-body closed form failed to set up ({exc})"
        ) from exc


def _lagrange_top_of(scenario, kind: str) -> LagrangeTop:
    try:
        top = LagrangeTop(scenario)
    except NotALagrangeTop as exc:
        raise ReferenceNotApplicable(
            f"scenario {scenario.name!r}: {kind} does not apply: {exc}"
        ) from None
    if kind == "steady_precession" and not top.steady:
        lo, hi = top.tilt_range
        raise ReferenceNotApplicable(
            f"scenario {scenario.name!r}: the initial state is not a steady precession "
            f"(relative residual of the torque balance {top.residual:.3g}, nutation between "
            f"tilts {lo:.12g} and {hi:.12g} rad); use reference kind 'lagrange_top' or "
            "'numerical', or fix the initial rates"
        )
    return top


def _choose(scenario, kind: str | None):
    """(kind, reason, closed-form object or None) for ``scenario``; see :func:`resolve_kind`."""
    if kind is None:
        requested, who = scenario.reference, "the scenario's reference.kind"
    else:
        requested, who = kind, "the caller"
    if requested not in ("auto", *KINDS):
        raise ValueError(f"unknown reference kind {requested!r}; known: auto, {', '.join(KINDS)}")
    if requested == "numerical":
        return "numerical", f"numerical: requested by {who}", None
    if requested == "free_body":
        return "free_body", f"free_body: requested by {who}", free_body_of(scenario)
    if requested in ("lagrange_top", "steady_precession"):
        top = _lagrange_top_of(scenario, requested)
        return requested, f"{requested}: requested by {who}", top
    # auto
    why = _torque_free_reason(scenario)
    if why is None:
        try:
            fb = free_body_of(scenario)
        except ReferenceNotApplicable as exc:
            return "numerical", f"numerical: auto, handed over by free_body ({exc})", None
        return "free_body", "free_body: auto, the rotation is torque-free", fb
    try:
        top = LagrangeTop(scenario)
    except NotALagrangeTop as exc:
        return "numerical", f"numerical: auto, {why} and no closed form applies ({exc})", None
    what = {"steady": "a steady precession", "pendulum": "a planar physical pendulum"}.get(
        top.case, "a symmetric top pivoted on its axis"
    )
    return "lagrange_top", f"lagrange_top: auto, {what}", top


def resolve_kind(scenario, kind: str | None = None) -> str:
    """The reference kind used for ``scenario``: ``kind`` if given, else the scenario's own,
    with "auto" resolved: free_body when torque-free, lagrange_top for a symmetric top on a
    pivot on its axis (closed form, ~1e-13 rad and ~100x cheaper than the numerical
    reference) unless it declines the motion, numerical otherwise. Raises
    :class:`ReferenceNotApplicable` when an explicitly requested kind does not apply.
    (:func:`reference_trajectory` may still hand an ``auto`` closed form over to the
    numerical reference if its evaluation is not finite; its result says so.)"""
    return _choose(scenario, kind)[0]


def _times(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1 or len(t) == 0:
        raise ValueError(f"times must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) < 0):
        raise ValueError("times must be finite, >= 0 and sorted (non-decreasing)")
    return t


def _closed_form(scenario, t, kind, obj):
    """(x, v, R, W, accuracy, omega accuracy, method) of a closed form."""
    if kind == "free_body":
        fb = obj
        R, W = fb.rotation(t), fb.omega(t)
        if scenario.pivot is None:
            x, v = free_flight(scenario.position, scenario.velocity, scenario.gravity, t)
        else:
            x = v = None
        acc = fb.accuracy(t)
        detail = f"case {fb.case}" + (f", k^2 = {fb.k2:.6g}" if fb.case in ("A", "B") else "")
        method = (
            f"exact torque-free body ({detail}): Jacobi elliptic functions, Euler angles about L, "
            "precession angle by periodic Gauss-Legendre quadrature; "
            + ("centre of mass on the exact parabola" if x is not None else "x_G = -R pivot")
        )
    else:
        top = obj
        R, W = top.rotation_and_omega(t)
        x = v = None
        acc = top.accuracy(t)
        if top.case == "steady":
            method = (
                f"closed-form steady precession R = Rot(up, w_p t) R0 Rot(e_k, w_s t), "
                f"w_p = {top.w_p:.15g}, w_s = {top.w_s:.15g} rad/s"
            )
        elif top.case == "pendulum":
            p = top.pendulum
            method = (
                f"planar physical pendulum ({p.case}, k^2 = {p.k2:.6g}): R = Rot(n, theta - "
                "theta0) R0, theta by Jacobi functions"
            )
        else:
            method = (
                "Lagrange top: nutation by Jacobi functions from the polished cubic, attitude "
                "by elliptic integrals of the third kind (Carlson R_J) of 1/(1 +- u); closest "
                f"approach to the vertical {math.sqrt(2.0 * top.pole_distance):.3g} rad"
            )
    wmax = float(np.max(np.linalg.norm(W, axis=1))) if len(W) else 0.0
    return x, v, R, W, acc, acc * max(wmax, 1.0), method


def reference_trajectory(scenario, t, kind: str | None = None) -> ReferenceTrajectory:
    """The reference solution of ``scenario`` at the times ``t`` (s, sorted, >= 0).

    ``kind`` overrides the scenario's ``reference`` (see the module docstring). Raises
    :class:`ReferenceNotApplicable` if an explicitly requested kind does not apply (``auto``
    hands over to the numerical reference instead and records why in ``reason``), and
    ``ValueError`` for invalid times or kind names.
    """
    t = _times(t)
    explicit = (kind if kind is not None else scenario.reference) != "auto"
    kind, reason, obj = _choose(scenario, kind)
    if kind != "numerical":
        x, v, R, W, acc, wacc, method = _closed_form(scenario, t, kind, obj)
        finite = bool(np.all(np.isfinite(R)) and np.all(np.isfinite(W)))
        if finite and math.isfinite(acc) and acc <= ACCURACY_LIMIT:
            base = Trajectory.from_states(scenario, t, x, v, R, W)
            return _wrap(base, kind, acc, method, wacc, reason)
        problem = (
            "its evaluation is not finite"
            if not finite
            else f"its estimated accuracy {acc:.3g} rad exceeds {ACCURACY_LIMIT:g}"
        )
        if explicit:
            raise ReferenceNotApplicable(f"scenario {scenario.name!r}: {kind}: {problem}")
        reason = f"numerical: auto, handed over by {kind} ({problem})"
    sol = numerical.solve(scenario, t)
    R, W = sol.rotation, sol.omega_body
    if scenario.pivot is None:
        x, v = free_flight(scenario.position, scenario.velocity, scenario.gravity, t)
    else:
        x = v = None
    method = (
        f"DOP853 (solve_ivp) at rtol {numerical.RTOL:g} on Euler's equations + quaternion "
        "kinematics; error estimate: 2 x the largest difference from runs at 10 rtol, with "
        f"halved steps and with W0 perturbed by the round-off along each axis; {sol.nfev} "
        "evaluations"
    )
    base = Trajectory.from_states(scenario, t, x, v, R, W)
    return _wrap(base, "numerical", sol.accuracy, method, sol.omega_accuracy, reason)


def reference_kept(scenario, t) -> tuple[ReferenceTrajectory, dict]:
    """(:func:`reference_trajectory` of ``scenario`` at ``t``, the reference cache's word on
    it: {"key", "source", "cpu_s", "wall_s"}): read from the reference cache
    (:mod:`references.cache`) when an earlier run kept it, else computed and kept; its
    arrays are read-only."""
    from references import cache

    t = _times(t)

    def compute():
        return reference_trajectory(scenario, t)

    return cache.kept("body", scenario, t, tolerances(), compute, _to_entry, _from_entry)


def tolerances() -> dict:
    """The tolerances and bounds a single body's reference is computed with, for the
    reference cache's key (those of the closed forms are in their source, whose digest the
    key holds)."""
    n = numerical
    return {"ACCURACY_LIMIT": ACCURACY_LIMIT, "RTOL": n.RTOL, "SAFETY": n.SAFETY,
            "MAX_STEPS": n.MAX_STEPS, "MAX_SECONDS": n.MAX_SECONDS,
            "SOLUTIONS": n.SOLUTIONS}  # fmt: skip


def _to_entry(ref: ReferenceTrajectory) -> tuple[dict, dict]:
    arrays, rest = {}, {}
    for f in fields(ReferenceTrajectory):
        value = getattr(ref, f.name)
        if isinstance(value, np.ndarray):
            arrays[f.name] = value
        else:
            rest[f.name] = list(value) if isinstance(value, tuple) else value
    return arrays, rest


def _from_entry(arrays: dict, rest: dict) -> ReferenceTrajectory:
    names = {f.name for f in fields(ReferenceTrajectory)}
    if set(arrays) | set(rest) != names:
        raise KeyError(f"fields {sorted(set(arrays) | set(rest))}, not {sorted(names)}")
    ref = ReferenceTrajectory(**arrays, **{k: tuple(v) if isinstance(v, list) else v
                                           for k, v in rest.items()})  # fmt: skip
    for f in fields(ref):  # shared by the runs on this grid: nobody may change it
        value = getattr(ref, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return ref


def _wrap(base: Trajectory, kind, acc, method, wacc, reason) -> ReferenceTrajectory:
    data = {f.name: getattr(base, f.name) for f in fields(Trajectory)}
    return ReferenceTrajectory(
        **data,
        kind=kind,
        accuracy=float(acc),
        method=method,
        omega_accuracy=float(wacc),
        reason=reason,
    )


def expected_observables(scenario) -> dict[str, float]:
    """Exact values of phase observables where a closed form applies (else an empty dict).

    Closed forms are only consulted for the kind :func:`resolve_kind` picks (so with
    ``kind = "numerical"`` no :class:`LagrangeTop` is built), except that a torque-free
    body's period is always taken from :class:`FreeBody`, which applies to every such body.
    Never raises for a valid scenario: a kind that does not apply gives an empty dict.

    Keys (all in s, rad or rad/s):

    - ``period``: period of the body rates W of a torque-free asymmetric body (4K/lambda), or
      of a symmetric one (2 pi/|psi'|).
    - ``flip_interval``: T/2, the time between sign changes of the intermediate-axis rate,
      given only when the body tumbles about its intermediate axis (that axis has the largest
      mean |W_i|, which is what :func:`reports.metrics.observables.flip_times` follows by default);
      absent for a stable spin.
    - ``nutation_period``: Lagrange top, period of u = cos(tilt) (absent for a steady
      precession); for the planar pendulum the period of cos(theta) (half the swing period).
    - ``precession_rate``: Lagrange top, mean rate of the azimuth of the symmetry axis about
      the vertical (dphi per nutation / nutation period; w_p for a steady precession); absent
      for the pendulum and when the axis passes the vertical within ``NEAR_VERTICAL`` rad.
    - ``tilt_min``, ``tilt_max``: Lagrange top, range of the tilt of the symmetry axis from
      the vertical.
    """
    out: dict[str, float] = {}
    try:
        kind, _, obj = _choose(scenario, None)
        if kind == "numerical" and _torque_free_reason(scenario) is None:
            kind, obj = "free_body", free_body_of(scenario)
        if kind == "free_body":
            fb = obj
            if math.isfinite(fb.period):
                out["period"] = fb.period
            if (
                fb.flip_interval is not None
                and fb.intermediate_axis is not None
                and fb.dominant_axis == fb.intermediate_axis
            ):
                out["flip_interval"] = fb.flip_interval
            return out
        if kind not in ("lagrange_top", "steady_precession"):
            return out
        top = obj
        if not top.steady and math.isfinite(top.nutation_period or math.nan):
            out["nutation_period"] = top.nutation_period
        passes_vertical = (
            top.case == "nutating" and math.sqrt(2.0 * top.pole_distance) < NEAR_VERTICAL
        )
        if math.isfinite(top.precession_rate) and not passes_vertical:
            out["precession_rate"] = top.precession_rate
        out["tilt_min"], out["tilt_max"] = top.tilt_range
    except (ValueError, ArithmeticError):  # ReferenceNotApplicable is a ValueError
        return {}
    return {k: float(v) for k, v in out.items() if math.isfinite(v)}
