"""The roll-pitch-yaw chart of a pivoted body on Drake's BallRpyJoint.

Pivoted bodies. Drake 1.51 has no ball joint with quaternion coordinates (its own error
message says so and points to https://github.com/RobotLocomotion/drake/issues/12404); the
BallRpyJoint's roll-pitch-yaw chart is singular at pitch = +-pi/2, where Drake refuses to
step (|cos pitch| below about 1e-3). The adapter places the frames F and M (:func:`rpy_chart`)
so that the singular set is a configuration the motion stays far from (for a Lagrange top,
known from its first integrals) and, where it can, so that a top's spin is the roll angle:
the chart decides Drake's accuracy on tops (cone_top, runge_kutta5 at dt = 1e-3: attitude
error 9.6e-10 with the spin as roll, 7.2e-4 without). A body that is not a Lagrange top has
no such chart for its whole motion, so the run changes chart on the way: at the end of every
step with |cos pitch| < :data:`CHART_SWITCH_COS` a Simulator monitor ends the call there, and
the adapter reads (R, W), builds a new plant whose frames put that orientation at roll = pitch
= yaw = 0 (:func:`centred_chart`), writes the same (R, W) into it at the same time and goes on,
summing steps and evaluations over every Simulator of the run. The switches and the smallest
|cos pitch| are in the run's settings. A step that goes from above the switching level to
Drake's own singularity check within one step is a step failure (diverged) saying so.
"""

from __future__ import annotations

import math

import numpy as np

#: a pivoted run switches to a new RPY chart (:func:`centred_chart`, pitch 0) at the end of
#: every step with |cos pitch| below this, so that the chart's kinematic map (1/cos pitch)
#: never amplifies more than 2.5x; a new chart keeps |cos pitch| >= 0.5 over a whole turn
#: about the angular velocity, so a steady rotation does not switch back and forth. Measured
#: on a wobbly top (runge_kutta5, dt = 4e-3, 3 s): attitude error 6.6e-6
#: with 7 switches at 0.3, 1.3e-6 with 13 at 0.4, 2.5e-6 with 19 at 0.5, 7.1e-7 with 26 at 0.7
CHART_SWITCH_COS = 0.4


def _unit(a) -> np.ndarray | None:
    a = np.asarray(a, dtype=float)
    n = float(np.linalg.norm(a))
    return a / n if n > 0 else None


def _perpendicular(a) -> np.ndarray:
    """A unit vector perpendicular to the unit vector ``a``."""
    e = np.eye(3)[int(np.argmin(np.abs(a)))]
    return _unit(np.cross(a, e))


#: the COM axis is made the chart's roll axis only if the sine of its angle to the vertical
#: stays above this over the whole motion (|cos pitch| = sin(tilt) in that chart): the
#: switching level, so that the exact motion of a top in that chart never switches (no chart
#: with pitch 0 keeps its spin as roll and its precession as yaw)
ROLL_AXIS_MIN_SIN = CHART_SWITCH_COS


def lagrange_tilt_band(model, R0, W0) -> tuple[float, float] | None:
    """(u_min, u_max), the range of u = cos(tilt) of the COM axis from the upward vertical over
    the whole motion, if the body is a Lagrange top (two equal principal moments, the pivot on
    the third axis, gravity); None otherwise.

    From the three first integrals (energy, the momenta about the vertical and about the
    axis): u'^2 = f(u) = (alpha - beta u)(1 - u^2) - (a - b u)^2 with A, C the transverse and
    axial moments about the pivot, l the pivot distance, alpha = (2E - C w3^2)/A,
    beta = 2 m g l/A, a = L_up/A, b = C w3/A; the motion keeps f >= 0, between the two roots
    of the cubic in [-1, 1] (f(+-1) = -(a -+ b)^2 <= 0, f -> +inf as u -> +inf)."""
    com = np.asarray(model.com, dtype=float)
    g = np.asarray(model.gravity, dtype=float)
    I = np.asarray(model.inertia, dtype=float)
    l, gn = float(np.linalg.norm(com)), float(np.linalg.norm(g))
    if l == 0.0 or gn == 0.0:
        return None
    k = int(np.argmax(np.abs(com)))
    i, j = (x for x in range(3) if x != k)
    if com[i] != 0.0 or com[j] != 0.0 or abs(I[i] - I[j]) > 1e-12 * I[i]:
        return None
    c = com / l
    up = -g / gn
    W = np.asarray(W0, dtype=float)
    Ip = I + model.mass * (l * l - com * com)  # principal moments about the pivot
    A, C = float(Ip[i]), float(Ip[k])
    w3 = float(W @ c)
    u0 = float((R0 @ c) @ up)
    E = 0.5 * float(W @ (Ip * W)) + model.mass * gn * l * u0
    alpha = (2 * E - C * w3 * w3) / A
    beta = 2 * model.mass * gn * l / A
    a = float((R0 @ (Ip * W)) @ up) / A
    b = C * w3 / A
    roots = np.roots([beta, -alpha - b * b, 2 * a * b - beta, alpha - a * a])
    lo, hi = np.sort(roots.real)[:2]  # a steady precession's double root may come out complex
    return float(min(max(lo, -1.0), u0)), float(max(min(hi, 1.0), u0))


def rpy_chart(model, R0, W0) -> tuple[np.ndarray, np.ndarray, str]:
    """(R_WF, R_BM, why): the rotations of the BallRpyJoint's frames F (on the world) and M (on
    the body) for the pivoted ``model`` (a :class:`BodyModel`) starting at ``R0`` with body
    rates ``W0``, and a sentence saying why.

    R_FM = Rz(yaw) Ry(pitch) Rx(roll): roll turns about a = R_BM e_x, yaw about the vertical
    b = R_WF e_z (gravity's direction; e_z without gravity), and the chart is singular where
    R a = +-b. Two choices of a, both with F and M aligned at t = 0 up to the initial pitch:

    - a = c, the COM axis: for a top, spin is roll and precession is yaw, so the coordinates
      move smoothly (measured on cone_top with runge_kutta5 at dt = 1e-3: attitude error
      9.6e-10 against 7.2e-4 with the other choice). Singular where c is vertical; taken when
      the tilt band of a Lagrange top (:func:`lagrange_tilt_band`) keeps sin(tilt) >=
      ROLL_AXIS_MIN_SIN, which is then the bound on |cos pitch|.
    - a perpendicular to c and horizontal at t = 0 (a = c x R0^T b): singular only where c is
      horizontal; a pendulum swinging in the vertical plane of c keeps pitch 0, a top whose
      tilt stays off 90 degrees keeps |cos pitch| >= |cos tilt|. Every other body."""
    R0 = np.asarray(R0, dtype=float)
    b = _unit(model.gravity)
    if b is None:
        b = np.array([0.0, 0.0, 1.0])
    b_body = R0.T @ b
    c = _unit(model.com)
    if c is None:  # pivot at the centre of mass: no COM axis, any horizontal direction
        c = _perpendicular(b_body)
    band = lagrange_tilt_band(model, R0, W0)
    sin_min = None if band is None else math.sqrt(max(0.0, 1.0 - max(u * u for u in band)))
    if sin_min is not None and sin_min >= ROLL_AXIS_MIN_SIN:
        a = c
        why = (
            f"roll axis = the COM axis (Lagrange top, cos(tilt) in [{band[0]:.4g}, "
            f"{band[1]:.4g}]: |cos pitch| >= {sin_min:.3g})"
        )
    else:
        a = _unit(np.cross(c, b_body))
        if a is None:  # c starts vertical: every direction perpendicular to it is horizontal
            a = _perpendicular(c)
        why = "roll axis perpendicular to the COM axis, horizontal at t = 0"
        if band is not None:
            cos_min = 0.0 if band[0] <= 0.0 <= band[1] else min(abs(band[0]), abs(band[1]))
            why += (
                f" (Lagrange top, cos(tilt) in [{band[0]:.4g}, {band[1]:.4g}]: "
                f"|cos pitch| >= {cos_min:.3g})"
            )
    R_WF, R_BM = _frames(R0, a, b)
    return R_WF, R_BM, why


def _frames(R, a, b) -> tuple[np.ndarray, np.ndarray]:
    """(R_WF, R_BM) of the chart with roll axis ``a`` (unit, body axes) and yaw axis ``b``
    (unit, world axes) for the orientation ``R``: F's z axis is b and its x axis the part of
    R a perpendicular to b; M's x axis is a and its y axis F's, so that R_FM = Ry(pitch) with
    sin(pitch) = b . R a (R_FM = 1, all three angles 0, when R a is perpendicular to b)."""
    a_world = R @ a
    fx = _unit(a_world - (a_world @ b) * b)
    R_WF = np.column_stack([fx, np.cross(b, fx), b])
    u = R.T @ R_WF[:, 1]
    R_BM = np.column_stack([a, u, np.cross(a, u)])
    return R_WF, R_BM


def centred_chart(model, R, W) -> tuple[np.ndarray, np.ndarray, str]:
    """(R_WF, R_BM, why): the chart a pivoted run switches to (:data:`CHART_SWITCH_COS`) at
    orientation ``R`` with body rates ``W``: one in which R sits at roll = pitch = yaw = 0, a
    quarter turn from the singular set.

    The yaw axis is the vertical b, as in :func:`rpy_chart`, and the roll axis a is horizontal
    now (pitch = 0), chosen from the angular velocity w = R W so that the chart stays good over
    a whole turn about w. Such a turn carries R a around a cone about w; with e the angle of w
    above the horizontal plane, the largest |pitch| on the cone is 2 e for a along the
    horizontal part of w and 90 deg - e for a horizontal and perpendicular to w. The first is
    taken for e < 30 deg, the second above, so |pitch| <= 60 deg (|cos pitch| >= 0.5) over the
    whole turn. A fast top lying flat gets its spin as roll, one standing up its spin as
    (mostly) yaw. Without a rotation to go by (w = 0, or w vertical for the second choice):
    the perpendicular to the COM axis of :func:`rpy_chart`."""
    R = np.asarray(R, dtype=float)
    b = _unit(model.gravity)
    if b is None:
        b = np.array([0.0, 0.0, 1.0])
    w = R @ np.asarray(W, dtype=float)
    w_max = float(np.max(np.abs(w)))
    w = w / w_max if 0.0 < w_max < math.inf else np.zeros(3)  # no overflow in |w|^2
    w_h = w - (w @ b) * b
    w_n = float(np.linalg.norm(w))
    a_world = None
    if w_n > 0.0 and abs(w @ b) < 0.5 * w_n:  # e < 30 deg (sin e < 1/2)
        a_world = _unit(w_h)
        why = "roll axis along the horizontal part of the angular velocity"
    elif w_n > 0.0:
        a_world = _unit(np.cross(b, w))  # None if w is vertical
        why = "roll axis horizontal, perpendicular to the angular velocity"
    if a_world is not None:
        a = R.T @ a_world
    else:
        b_body = R.T @ b
        c = _unit(model.com)
        if c is None:
            c = _perpendicular(b_body)
        a = _unit(np.cross(c, b_body))
        if a is None:
            a = _perpendicular(c)
        why = "roll axis horizontal, perpendicular to the COM axis (no rotation to go by)"
    R_WF, R_BM = _frames(R, a, b)
    return R_WF, R_BM, why
