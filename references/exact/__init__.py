"""Exact and high-accuracy reference solutions of scenarios.

:func:`reference_trajectory` returns a :class:`ReferenceTrajectory` (the suite's
:class:`references.trajectory.Trajectory` plus ``kind``, ``accuracy``, ``omega_accuracy`` and
``method``); :func:`expected_observables` gives exact values of phase observables.

Reference kinds (``scenario.reference``, or the ``kind`` argument):

=====================  =====================================================================
``free_body``          torque-free body: Jacobi elliptic functions + Euler angles about L
                       (:mod:`references.exact.free_body`); centre of mass on the exact
                       parabola. Applies to every free body, with or without gravity (uniform
                       gravity does not torque about the centre of mass), and to a pivoted body
                       without gravity torque whose pivot lies on a principal axis.
``steady_precession``  closed-form steady precession of a Lagrange top,
                       R(t) = Rot(up, w_p t) R_0 Rot(e_k, w_s t) (:mod:`.lagrange_top`); the
                       state is verified to be a steady precession, an error otherwise.
``numerical``          DOP853 at rtol 1e-13 with an error estimate from four runs (10 rtol,
                       step halving, a round-off probe)
                       (:mod:`references.exact.numerical`); any scenario.
``lagrange_top``       (argument only, not a scenario-file value) the quadrature solution of a
                       symmetric heavy top pivoted on its axis (:mod:`.lagrange_top`).
``auto``               free_body if there is no gravity torque and the above applies,
                       numerical otherwise.
=====================  =====================================================================

``accuracy`` is the estimated maximum error of the attitude over the returned times, in rad
(the angle of R_ref^T R_true); ``omega_accuracy`` that of the body rates, rad/s. For the
closed forms they are round-off and quadrature estimates; for the numerical reference, twice
the spread of four solutions (see :mod:`references.exact.numerical`). Energy and angular
momentum are computed by :meth:`Trajectory.from_states`, exactly as for every engine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from references.exact import numerical
from references.exact.free_body import FreeBody, free_flight
from references.exact.lagrange_top import LagrangeTop, NotALagrangeTop
from references.trajectory import Trajectory

__all__ = [
    "KINDS",
    "FreeBody",
    "LagrangeTop",
    "ReferenceError",
    "ReferenceTrajectory",
    "expected_observables",
    "free_body_of",
    "reference_trajectory",
    "resolve_kind",
]

KINDS = ("free_body", "steady_precession", "numerical", "lagrange_top")


class ReferenceError(ValueError):
    """The requested reference does not apply to the scenario (the message says why)."""


@dataclass
class ReferenceTrajectory(Trajectory):
    """A reference solution in the suite's trajectory schema, with what it is and how good."""

    kind: str = ""
    accuracy: float = math.nan
    method: str = ""
    omega_accuracy: float = math.nan


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
        raise ReferenceError(f"scenario {scenario.name!r}: free_body does not apply: {reason}")
    I = np.diag(scenario.pivot_inertia).copy()
    return FreeBody(I, scenario.omega_body, scenario.rotation)


def resolve_kind(scenario, kind: str | None = None) -> str:
    """The reference kind used for ``scenario``: ``kind`` if given, else the scenario's own,
    with "auto" resolved: free_body when torque-free, lagrange_top for a symmetric top on a
    pivot on its axis (closed form, about 1e-12 rad and ~100x cheaper than the numerical
    reference), numerical otherwise."""
    kind = scenario.reference if kind is None else kind
    if kind == "auto":
        if _torque_free_reason(scenario) is None:
            return "free_body"
        try:
            LagrangeTop(scenario)
        except NotALagrangeTop:
            return "numerical"
        return "lagrange_top"
    if kind not in KINDS:
        raise ReferenceError(f"unknown reference kind {kind!r}; known: auto, {', '.join(KINDS)}")
    return kind


def _times(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1 or len(t) == 0:
        raise ReferenceError(f"times must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) < 0):
        raise ReferenceError("times must be finite, >= 0 and sorted (non-decreasing)")
    return t


def reference_trajectory(scenario, t, kind: str | None = None) -> ReferenceTrajectory:
    """The reference solution of ``scenario`` at the times ``t`` (s, sorted, >= 0).

    ``kind`` overrides the scenario's ``reference`` (see the module docstring). Raises
    :class:`ReferenceError` if the requested kind does not apply.
    """
    t = _times(t)
    kind = resolve_kind(scenario, kind)
    if kind == "free_body":
        fb = free_body_of(scenario)
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
    elif kind in ("steady_precession", "lagrange_top"):
        try:
            top = LagrangeTop(scenario)
        except NotALagrangeTop as exc:
            raise ReferenceError(
                f"scenario {scenario.name!r}: {kind} does not apply: {exc}"
            ) from None
        if kind == "steady_precession" and not top.steady:
            raise ReferenceError(
                f"scenario {scenario.name!r}: the initial state is not a steady precession "
                f"(relative residual of the torque balance {top.residual:.3g}, nutation between "
                f"tilts {top.tilt_range[0]:.12g} and {top.tilt_range[1]:.12g} rad); use "
                "reference kind 'numerical' or fix the initial rates"
            )
        R, W = top.rotation_and_omega(t)
        x = v = None
        acc = top.accuracy(t)
        if top.steady:
            method = (
                f"closed-form steady precession R = Rot(up, w_p t) R0 Rot(e_k, w_s t), "
                f"w_p = {top.w_p:.15g}, w_s = {top.w_s:.15g} rad/s"
            )
        else:
            method = (
                "Lagrange top: nutation by Jacobi functions from the polished cubic, "
                "precession and spin angles by periodic Gauss-Legendre quadrature"
            )
    else:
        sol = numerical.solve(scenario, t)
        R, W = sol.rotation, sol.omega_body
        if scenario.pivot is None:
            x, v = free_flight(scenario.position, scenario.velocity, scenario.gravity, t)
        else:
            x = v = None
        acc = sol.accuracy
        method = (
            f"DOP853 (solve_ivp) at rtol {numerical.RTOL:g} on Euler's equations + quaternion "
            f"kinematics; error estimate: 2 x spread of runs at 10 rtol, halved steps and "
            f"perturbed by the round-off; "
            f"{sol.nfev} evaluations"
        )
        base = Trajectory.from_states(scenario, t, x, v, R, W)
        return _wrap(base, kind, acc, method, sol.omega_accuracy)
    base = Trajectory.from_states(scenario, t, x, v, R, W)
    wmax = float(np.max(np.linalg.norm(W, axis=1)))
    return _wrap(base, kind, acc, method, acc * max(wmax, 1.0))


def _wrap(base: Trajectory, kind, acc, method, wacc) -> ReferenceTrajectory:
    data = {f.name: getattr(base, f.name) for f in fields(Trajectory)}
    return ReferenceTrajectory(
        **data, kind=kind, accuracy=float(acc), method=method, omega_accuracy=float(wacc)
    )


def expected_observables(scenario) -> dict[str, float]:
    """Exact values of phase observables where a closed form applies (else an empty dict).

    Keys (all in s, rad or rad/s):

    - ``period``: period of the body rates W of a torque-free asymmetric body (4K/lambda), or
      of a symmetric one (2 pi/|psi'|).
    - ``flip_interval``: T/2, the time between sign changes of the intermediate-axis rate,
      given only when the body tumbles about its intermediate axis (that axis has the largest
      mean |W_i|, which is what :func:`reports.observables.flip_times` follows by default);
      absent for a stable spin.
    - ``nutation_period``: Lagrange top, from the cubic (absent for a steady precession).
    - ``precession_rate``: Lagrange top, mean rate of the azimuth of the symmetry axis about
      the vertical (dphi per nutation / nutation period; w_p for a steady precession).
    - ``tilt_min``, ``tilt_max``: Lagrange top, range of the tilt of the symmetry axis from
      the vertical.
    """
    out: dict[str, float] = {}
    if _torque_free_reason(scenario) is None:
        fb = free_body_of(scenario)
        if math.isfinite(fb.period):
            out["period"] = fb.period
        if (
            fb.flip_interval is not None
            and fb.intermediate_axis is not None
            and fb.dominant_axis == fb.intermediate_axis
        ):
            out["flip_interval"] = fb.flip_interval
        return out
    try:
        top = LagrangeTop(scenario)
    except NotALagrangeTop:
        return out
    if not top.steady:
        out["nutation_period"] = top.nutation_period
    out["precession_rate"] = top.precession_rate
    out["tilt_min"], out["tilt_max"] = top.tilt_range
    return out
