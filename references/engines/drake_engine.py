"""Drake adapter: a MultibodyPlant with one rigid body on a QuaternionFloatingJoint (free body)
or a BallRpyJoint at the world origin (pivoted body), stepped by Drake's Simulator.

Model. The Drake body frame B is the principal centre-of-mass frame: the spatial inertia is
``SpatialInertia.MakeFromCentralInertia(m, 0, RotationalInertia(I1, I2, I3))``. The joint
connects a frame F on the world to a frame M on the body at ``p_BM = -com`` (the pivot for a
pivoted body, B itself for a free one), so the suite's body frame (origin at the joint point,
principal axes) has the centre of mass at ``com``; that is what the read-back reports. There
is no geometry, so nothing can touch; gravity is set and read back; joint damping is 0 and
the joint limits are infinite (read back).

Integrators, each named for what it is (Drake's scheme names, as in ``ResetIntegratorFromFlags``
and the Drake documentation of ``systems::analysis``):

- continuous mode (``MultibodyPlant(time_step=0)``) at a FIXED step dt
  (``set_fixed_step_mode(True)``, maximum step size dt): ``explicit_euler``,
  ``semi_explicit_euler``, ``runge_kutta2``/``3``/``5``, ``bogacki_shampine3``,
  ``implicit_euler``, ``velocity_implicit_euler``, ``radau1``, ``radau3``, ``cenic``;
- continuous mode ERROR-CONTROLLED at a target accuracy (``adaptive``; dt is only the interval
  of the checkpoints; the largest step is the horizon): every scheme with an error estimate;
- discrete mode (``MultibodyPlant(time_step=dt)``, SAP): Drake's discrete update.

Every one integrates the joint's coordinates in their vector space: a quaternion is advanced
additively and never renormalised (:mod:`references.conventions` shows the norm's drift in
the orthonormality of R). The Simulator's silent default (runge_kutta3, error-controlled at
accuracy 1e-4, largest step 0.1 s) is always replaced, and the replacement read back.

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

Cut-off of error-controlled runs: a run may make at most :data:`EVAL_BUDGET` dynamics
evaluations (Drake's derivative evaluations, Jacobian ones included; steps for CENIC, which
counts none) per fixed step of the scenario over the run's horizon, i.e.
``EVAL_BUDGET * max(t_end / scenario.dt, MIN_FIXED_STEPS)``; beyond that it stops and raises
``Unsupported`` with the steps taken, the evaluations and the time reached. The count is
checked after every step (a Simulator monitor). Evaluations, not steps, because an implicit
step costs ten or more of them: measured (drake 1.51.1, this adapter) at 16 to 30 us per
evaluation, the budget bounds the longest default scenario (30000 fixed steps) to about
300000 evaluations, 5 to 10 s.

Time bookkeeping: a fixed step is dt exactly. Drake never steps past the time it is asked to
reach, and a target 1 ulp beyond its running sum of steps would cost an extra tiny step, so
each target is the running floating-point sum of the steps (the Simulator's own arithmetic),
and the number of steps Drake took is checked against the plan after every call.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback
from references.engines.integrators import Family, Integrator, register_family
from references.engines.interface import Engine
from references.engines.native import import_engine
from references.errors import EngineError, StepFailure, Unsupported

#: an error-controlled run may make at most this many dynamics evaluations per fixed step of
#: the scenario (t_end / scenario.dt, at least MIN_FIXED_STEPS) before it is cut off (see the
#: module docstring); runge_kutta5 at a fixed step makes 7
EVAL_BUDGET = 10
#: the fixed-step count the budget is scaled from is at least this, so that a run of a few
#: steps (the conformance kit's) has room for the integrator's first step-size adjustments
MIN_FIXED_STEPS = 100

#: a pivoted run switches to a new RPY chart (:func:`centred_chart`, pitch 0) at the end of
#: every step with |cos pitch| below this, so that the chart's kinematic map (1/cos pitch)
#: never amplifies more than 2.5x; a new chart keeps |cos pitch| >= 0.5 over a whole turn
#: about the angular velocity, so a steady rotation does not switch back and forth. Measured
#: on the module docstring's wobbly top (runge_kutta5, dt = 4e-3, 3 s): attitude error 6.6e-6
#: with 7 switches at 0.3, 1.3e-6 with 13 at 0.4, 2.5e-6 with 19 at 0.5, 7.1e-7 with 26 at 0.7
CHART_SWITCH_COS = 0.4

# -- families (Drake's integrators that fit none of the suite's) ------------------------------

EXPLICIT_EULER = register_family(
    Family(
        "explicit Euler",
        "first order, forward Euler on the coordinates: positions and velocities both from "
        "the derivatives at the start of the step (not semi-implicit)",
    )
)
SEMI_EXPLICIT_Q = register_family(
    Family(
        "semi-implicit Euler on quaternion coordinates",
        "first order: the velocity update of semi-implicit Euler (gyroscopic term explicit), "
        "then the quaternion advanced additively (q += h N(q) v) and never renormalised; the "
        "rates agree with MuJoCo Euler's to round-off, the attitude does not (measured: 1e-10 "
        "and 3e-2 rad on dzhanibekov over 30 s)",
    )
)
EXPLICIT_RK = register_family(
    Family(
        "explicit Runge-Kutta on coordinates",
        "explicit Runge-Kutta methods applied to (q, v) as a vector ODE: a quaternion is "
        "integrated as four numbers, not on SO(3), and not renormalised",
    )
)
IMPLICIT_RK = register_family(
    Family(
        "implicit Runge-Kutta on coordinates",
        "fully implicit methods (implicit Euler, Radau IIA) on (q, v) as a vector ODE, "
        "solved by Newton iterations with a finite-difference Jacobian",
    )
)
CONVEX = register_family(
    Family(
        "convex implicit (CENIC)",
        "Drake's CENIC: a convex, error-controlled implicit integrator built for contact",
    )
)
DISCRETE = register_family(
    Family(
        "discrete (SAP)",
        "Drake's discrete-time MultibodyPlant update with the SAP solver: velocities from the "
        "start-of-step dynamics (joint damping implicit), then positions from the new "
        "velocities",
    )
)


#: the configurations in the default suite: the first-order one every engine shares, Drake's
#: most accurate explicit scheme at a fixed step and under error control; the others cost 80 s
#: (fixed steps) and 150 s (error-controlled sweeps) on the default scenarios and run on request
_DEFAULT_SUITE = ("semi_explicit_euler", "runge_kutta5", "runge_kutta5 (error-controlled)")


def _fixed(scheme, family, order, description, evals=None):
    return Integrator(
        scheme,
        family,
        order,
        description,
        evals_per_step=evals,
        options={"mode": "fixed step", "scheme": scheme},
        default=scheme in _DEFAULT_SUITE,
    )


def _controlled(scheme, family, order, description):
    name = f"{scheme} (error-controlled)"
    return Integrator(
        name,
        family,
        order,
        description,
        evals_per_step=None,
        options={"mode": "error-controlled", "scheme": scheme},
        adaptive=True,
        default=name in _DEFAULT_SUITE,
    )


_QUAT = "the quaternion is advanced additively and never renormalised"

INTEGRATORS = (
    _fixed(
        "semi_explicit_euler",
        SEMI_EXPLICIT_Q.name,
        1,
        "Drake's SemiExplicitEulerIntegrator: v += h a(q, v) with the gyroscopic term "
        f"explicit, then q += h N(q) v with the new v; {_QUAT} (unlike MuJoCo Euler's "
        "exponential map).",
        evals=1.0,
    ),
    _fixed(
        "explicit_euler",
        EXPLICIT_EULER.name,
        1,
        f"Drake's ExplicitEulerIntegrator: x += h f(x) for x = (q, v); {_QUAT}.",
        evals=1.0,
    ),
    _fixed(
        "runge_kutta2",
        EXPLICIT_RK.name,
        2,
        f"Drake's RungeKutta2Integrator (explicit trapezoid, 2 stages); {_QUAT}.",
        evals=2.0,
    ),
    _fixed(
        "runge_kutta3",
        EXPLICIT_RK.name,
        3,
        "Drake's RungeKutta3Integrator (3 stages, the embedded 2nd-order error estimate is "
        f"computed but unused at a fixed step); {_QUAT}.",
        evals=3.0,
    ),
    _fixed(
        "bogacki_shampine3",
        EXPLICIT_RK.name,
        3,
        "Drake's BogackiShampine3Integrator (3rd order, 4 evaluations per step with the "
        f"embedded estimate); {_QUAT}.",
        evals=4.0,
    ),
    _fixed(
        "runge_kutta5",
        EXPLICIT_RK.name,
        5,
        "Drake's RungeKutta5Integrator (Dormand-Prince 5(4), 7 evaluations per step as "
        f"Drake counts them); {_QUAT}.",
        evals=7.0,
    ),
    _fixed(
        "implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's ImplicitEulerIntegrator with its default step doubling: every step of h is "
        "a full implicit Euler step plus two half steps, and the two half steps are kept "
        f"(Newton iterations, finite-difference Jacobian); {_QUAT}.",
    ),
    _fixed(
        "velocity_implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's VelocityImplicitEulerIntegrator: implicit in v, q from the new v, with step "
        f"doubling (two half steps kept); {_QUAT}.",
    ),
    _fixed(
        "radau1",
        IMPLICIT_RK.name,
        1,
        "Drake's RadauIntegrator with 1 stage (Radau IIA = implicit Euler, one step of h; "
        f"Newton iterations, finite-difference Jacobian); {_QUAT}.",
    ),
    _fixed(
        "radau3",
        IMPLICIT_RK.name,
        3,
        f"Drake's RadauIntegrator with 2 stages (Radau IIA, order 3); {_QUAT}.",
    ),
    _fixed(
        "cenic",
        CONVEX.name,
        1,
        "Drake's CenicIntegrator (convex implicit step) at a fixed step; it needs a Diagram "
        "with a SceneGraph, which the adapter builds (with no geometry).",
    ),
    Integrator(
        "discrete SAP",
        DISCRETE.name,
        1,
        "MultibodyPlant(time_step=dt) with DiscreteContactApproximation.kSap, stepped by the "
        "Simulator's periodic discrete update: v from the start-of-step dynamics, then "
        f"q += h N(q) v with the new v; {_QUAT}.",
        evals_per_step=1.0,
        options={"mode": "discrete", "scheme": "discrete SAP"},
        default=False,
    ),
    _controlled(
        "runge_kutta3",
        EXPLICIT_RK.name,
        3,
        "Drake's RungeKutta3Integrator with error control (embedded 2nd-order estimate) at "
        f"the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "bogacki_shampine3",
        EXPLICIT_RK.name,
        3,
        "Drake's BogackiShampine3Integrator with error control (embedded 2nd-order "
        f"estimate) at the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "runge_kutta5",
        EXPLICIT_RK.name,
        5,
        "Drake's RungeKutta5Integrator (Dormand-Prince 5(4)) with error control at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        "implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's ImplicitEulerIntegrator with error control by step doubling at the target "
        f"accuracy; {_QUAT}.",
    ),
    _controlled(
        "velocity_implicit_euler",
        IMPLICIT_RK.name,
        1,
        "Drake's VelocityImplicitEulerIntegrator with error control by step doubling at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        "radau1",
        IMPLICIT_RK.name,
        1,
        "Drake's 1-stage RadauIntegrator (implicit Euler) with error control (implicit "
        f"trapezoid estimate) at the target accuracy; {_QUAT}.",
    ),
    _controlled(
        "radau3",
        IMPLICIT_RK.name,
        3,
        "Drake's 2-stage RadauIntegrator (Radau IIA, order 3) with error control at the "
        f"target accuracy; {_QUAT}.",
    ),
    _controlled(
        "cenic",
        CONVEX.name,
        1,
        "Drake's CenicIntegrator with error control at the target accuracy (Diagram with an "
        "empty SceneGraph).",
    ),
)


def _import():
    return import_engine("pydrake", "Drake (pydrake)", "drake")


# -- the RPY chart of a pivoted body -----------------------------------------------------------


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


# -- the adapter --------------------------------------------------------------------------------


@dataclass
class _Replaced:
    """What the Simulators and integrators replaced at chart switches did, summed (largest
    and smallest step: the extremes; NaN where none was taken)."""

    steps: int = 0  # the integrator's steps (the Simulator's in discrete mode)
    updates: int = 0  # the Simulator's discrete and unrestricted updates (discrete mode)
    evals: int = 0
    rejected_by_error: int = 0
    rejected_by_failure: int = 0
    largest: float = math.nan
    smallest: float = math.nan


@dataclass
class _Handle:
    plant: Any
    body: Any
    joint: Any
    simulator: Any
    context: Any  # the plant's context inside the Simulator's
    integrator: Any  # None in discrete mode
    mode: str
    scheme: str
    R_WF: np.ndarray
    R_BM: np.ndarray
    p_BM: np.ndarray
    #: the Simulator's time reached so far (the running sum of the fixed steps)
    t: float = 0.0
    #: checkpoints advanced so far (units of ctx.dt)
    n: int = 0
    #: Drake's derivative evaluations already added to ctx.nevals (over every integrator)
    evals_seen: int = 0
    budget: int | None = None
    horizon: float = math.nan
    stop: str | None = None
    min_cos_pitch: float = math.inf
    chart: str = ""
    #: the initial step size target requested of the current integrator (error-controlled)
    first_step: float = math.nan
    #: error-controlled: end time and size of the last step taken (kept by the monitor)
    t_last: float = 0.0
    last_step: float = math.nan
    #: every chart used, (R_WF, R_BM) in order; a row of read_raw ends with its chart's index
    charts: list = field(default_factory=list)
    #: (time, |cos pitch| in the chart left) of every chart switch
    switches: list = field(default_factory=list)
    #: set by the monitor when a step ends below CHART_SWITCH_COS
    switch_pending: bool = False
    #: wall time of the chart switches (adapter glue, outside ctx.clock), s
    switch_s: float = 0.0
    replaced: _Replaced = field(default_factory=_Replaced)


class DrakeEngine(Engine):
    """Drake (pydrake): continuous MultibodyPlant with Drake's integrators (fixed step or
    error-controlled), or the discrete MultibodyPlant (SAP)."""

    name = "drake"
    description = (
        "Drake: QuaternionFloatingJoint or BallRpyJoint; Drake's Simulator with each of its "
        "integrators at a fixed step or error-controlled, or the discrete SAP plant"
    )
    integrators = INTEGRATORS

    #: defaults that distort the experiment, planted back by the conformance kit
    plantable = {
        "joint damping left on": (
            lambda ctx: ctx.handle.joint.SetDampingVector(
                ctx.handle.context, np.full(ctx.handle.plant.num_velocities(), 0.01)
            ),
            ("free", "pivoted"),
        ),
        "the Simulator's default integrator left on (runge_kutta3, accuracy 1e-4, step 0.1)": (
            lambda ctx: _default_integrator(ctx),
            ("free", "pivoted"),
        ),
    }

    @classmethod
    def version(cls) -> str:
        _import()
        import importlib.metadata

        try:
            return importlib.metadata.version("drake")
        except importlib.metadata.PackageNotFoundError:
            import pydrake.common

            return str(getattr(pydrake.common, "__version__", "unknown"))

    def check_supported(self, scenario, integrator) -> None:
        scheme = integrator.options["scheme"]
        if integrator.options["mode"] == "discrete":
            return
        _import()
        from pydrake.systems.analysis import GetIntegrationSchemes

        if scheme not in GetIntegrationSchemes():
            raise Unsupported(
                f"Drake {self.version()} has no integration scheme {scheme!r} "
                f"(ResetIntegratorFromFlags offers {', '.join(GetIntegrationSchemes())})"
            )

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        _import()
        mdl = ctx.model
        mode = ctx.integrator.options["mode"]
        scheme = ctx.integrator.options["scheme"]
        if mdl.pivoted:
            R_WF, R_BM, chart = rpy_chart(mdl, ctx.scenario.rotation, ctx.scenario.omega_body)
        else:
            R_WF, R_BM, chart = np.eye(3), np.eye(3), ""
        p_BM = -np.asarray(mdl.com, dtype=float)
        h = _Handle(None, None, None, None, None, None, mode, scheme, R_WF, R_BM, p_BM)
        h.horizon = ctx.t_end
        h.chart = chart
        if mode == "error-controlled":
            fixed_steps = max(h.horizon / ctx.scenario.dt, MIN_FIXED_STEPS)
            h.budget = int(math.ceil(EVAL_BUDGET * fixed_steps))
        # Drake's first error-controlled attempt would be the largest step (the horizon);
        # from such a step runge_kutta5's error control never recovers on a top (measured:
        # 258000 rejected attempts and no step in 12 s at t = 0, heavy_top, 1e-6), and no
        # step means no monitor call to cut it off. The scenario's own fixed step is a sane
        # first try.
        self._assemble(ctx, h, R_WF, R_BM, min(ctx.scenario.dt, h.horizon))
        ctx.handle = h
        if scheme == "cenic":
            ctx.nevals = math.nan  # CENIC counts no derivative evaluations (it has none)

    def _assemble(self, ctx, h: _Handle, R_WF, R_BM, first_step: float) -> None:
        """Build the plant (joint frames F and M at ``R_WF`` and ``R_BM``), its Simulator and
        integrator (error-controlled: ``first_step`` as the initial step size target) and the
        monitor, into ``h``; at t = 0 and at every chart switch (a finalised plant's joint
        frames cannot move)."""
        from pydrake.systems.analysis import Simulator

        plant, body, joint, system = _plant(ctx, h, R_WF, R_BM)
        sim = Simulator(system)
        context = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        integ = _integrator(ctx, h, sim, first_step)
        h.plant, h.body, h.joint, h.simulator, h.context, h.integrator = (
            plant, body, joint, sim, context, integ,
        )  # fmt: skip
        h.R_WF, h.R_BM = np.asarray(R_WF, dtype=float), np.asarray(R_BM, dtype=float)
        h.charts.append((h.R_WF, h.R_BM))
        if ctx.model.pivoted or h.mode == "error-controlled":
            sim.set_monitor(_monitor(h, ctx.model.pivoted))

    def read_model(self, ctx) -> ModelReadback:
        h = ctx.handle
        plant, body, joint, pc = h.plant, h.body, h.joint, h.context
        M = body.CalcSpatialInertiaInBodyFrame(pc)  # about Bo, the COM by construction
        p_BoBcm = np.asarray(M.get_com())
        about_com = M.Shift(p_BoBcm)
        X_BM = joint.frame_on_child().CalcPoseInBodyFrame(pc)
        extra = _model_checks(h)
        dt = _integrator_checks(ctx, h, extra)
        return ModelReadback(
            mass=M.get_mass(),
            inertia=about_com.CalcRotationalInertia().CopyToFullMatrix3(),
            com=p_BoBcm - X_BM.translation(),
            joint={"quaternion_floating": "free", "ball_rpy": "ball"}.get(
                joint.type_name(), joint.type_name()
            ),
            gravity=plant.gravity_field().gravity_vector(),
            dt=dt,
            extra=extra,
        )

    def settings(self, ctx) -> dict:
        h = ctx.handle
        mdl = ctx.model
        out = {
            "gravity": mdl.gravity.tolist(),
            "joint": "BallRpyJoint at the world origin"
            if mdl.pivoted
            else "QuaternionFloatingJoint",
            "body frame": "principal centre-of-mass frame; spatial inertia "
            "MakeFromCentralInertia(m, 0, diag(I))",
            "joint frame M on the body": f"origin {h.p_BM.tolist()}, rotation "
            f"{h.charts[0][1].tolist()}" + (" (at t = 0)" if mdl.pivoted else ""),
            "joint damping": 0.0,
            "joint limits": "none (infinite, read back)",
            "geometry": "none (no collision geometry)"
            + ("; an empty SceneGraph for CENIC" if h.scheme == "cenic" else ""),
        }
        if not mdl.pivoted:
            out["quaternion"] = (
                "kept at unit norm by CENIC's position update"
                if h.scheme == "cenic"
                else "never renormalised by Drake; its norm's drift shows in R (R^T R = |q|^4 1)"
            )
        if mdl.pivoted:
            out["RPY chart"] = (
                f"at t = 0: {h.chart}, frame F rotation {h.charts[0][0].tolist()}; a new chart "
                f"(roll = pitch = yaw = 0) at the end of every step with |cos pitch| < "
                f"{CHART_SWITCH_COS}"
                + (
                    ", its integrator's initial step size target the last step taken"
                    if h.mode == "error-controlled"
                    else ""
                )
            )
            out["RPY chart switches"] = len(h.switches)
            out["RPY chart smallest |cos pitch|"] = float(h.min_cos_pitch)
        if h.mode == "discrete":
            out["mode"] = f"discrete MultibodyPlant(time_step={ctx.dt!r}), SAP"
        else:
            out["mode"] = "continuous MultibodyPlant(time_step=0)"
            out["integration scheme"] = h.scheme
            out["fixed step mode"] = h.mode == "fixed step"
            out["maximum step size"] = ctx.dt if h.mode == "fixed step" else h.horizon
        if h.mode == "error-controlled":
            out["initial step size target"] = min(ctx.scenario.dt, h.horizon)
        if h.mode == "error-controlled":
            out["evaluation budget"] = (
                f"{h.budget} dynamics evaluations ({EVAL_BUDGET} x max(t_end / scenario dt "
                f"{ctx.scenario.dt!r}, {MIN_FIXED_STEPS}))"
            )
        return out

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        h = ctx.handle
        if ctx.model.pivoted:
            q, v = cv.drake_ball_rpy_from_state(state.rotation, state.omega_body, h.R_WF, h.R_BM)
        else:
            q, v = cv.drake_free_from_state(*state)
        h.plant.SetPositions(h.context, q)
        h.plant.SetVelocities(h.context, v)
        h.simulator.Initialize()
        if h.switch_pending:  # a state far from the scenario's, e.g. a planted mistake
            self._switch_chart(ctx)

    def read_state(self, ctx) -> cv.BodyState:
        h = ctx.handle
        q = h.plant.GetPositions(h.context)
        v = h.plant.GetVelocities(h.context)
        if ctx.model.pivoted:
            R, W = cv.drake_ball_rpy_to_state(q, v, h.R_WF, h.R_BM)
            return ctx.model.state_from_rotation(R, W)
        return cv.drake_free_to_state(q, v)

    def read_raw(self, ctx) -> np.ndarray:
        """[q, v] and, for a pivoted body, the index of the chart q is in (h.charts)."""
        h = ctx.handle
        q, v = h.plant.GetPositions(h.context), h.plant.GetVelocities(h.context)
        if ctx.model.pivoted:
            return np.concatenate((q, v, [len(h.charts) - 1]))
        return np.concatenate((q, v))

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        h = ctx.handle
        raw = np.asarray(raw, dtype=float)
        if not ctx.model.pivoted:
            return cv.drake_block(raw, 7, ctx.model.com, False)
        chart = raw[:, 6].astype(int)
        parts = [
            cv.drake_block(raw[chart == i, :6], 3, ctx.model.com, True, *h.charts[i])
            for i in np.unique(chart)  # ascending: the rows' order
        ]
        if len(parts) == 1:
            return parts[0]
        return cv.BodyState(*(np.concatenate(f) for f in zip(*parts, strict=True)))

    def native_quantities(self, ctx) -> dict:
        """Drake's own energy (CalcKineticEnergy + CalcPotentialEnergy, whose zero is at the
        world origin: V = -m g . x_G), angular momentum (CalcSpatialMomentumInWorldAboutPoint
        about the COM for a free body, the world origin for a pivoted one), the body pose
        (EvalBodyPoseInWorld), and its COM position and velocity."""
        h = ctx.handle
        plant, pc = h.plant, h.context
        x_G = np.asarray(plant.CalcCenterOfMassPositionInWorld(pc))
        about = np.zeros(3) if ctx.model.pivoted else x_G
        L = plant.CalcSpatialMomentumInWorldAboutPoint(pc, about).rotational()
        return {
            "energy": plant.CalcKineticEnergy(pc) + plant.CalcPotentialEnergy(pc),
            "angular momentum": np.asarray(L),
            "rotation": plant.EvalBodyPoseInWorld(pc, h.body).rotation().matrix(),
            "COM velocity": np.asarray(plant.CalcCenterOfMassTranslationalVelocityInWorld(pc)),
            "COM position": x_G,
        }

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        h = ctx.handle
        if h.mode == "fixed step":
            target = h.t
            for _ in range(k):
                target += ctx.dt
        else:
            # periodic discrete updates fall at n * time_step (Drake's event times); an
            # error-controlled run's checkpoints are the same multiples of ctx.dt
            target = (h.n + k) * ctx.dt
        while True:
            try:
                with ctx.clock:
                    h.simulator.AdvanceTo(target)
            except RuntimeError as exc:
                if h.stop is not None:
                    raise Unsupported(h.stop) from exc
                raise self._failure(ctx, exc) from exc
            if not h.switch_pending:
                break
            # the monitor ended AdvanceTo at the end of a step, in the singular set's way
            self._switch_chart(ctx)
            if h.context.get_time() >= target:  # the switch came at the end of the last step
                break
        h.t = target
        h.n += k
        if h.mode == "error-controlled":
            self._collect_stats(ctx)
        else:
            # summed over the Simulators of every chart; a discrete plant's steps must each
            # begin with its update (on the grid n * dt, also after a switch)
            old = h.replaced
            if h.integrator is None:
                taken = old.steps + h.simulator.get_num_steps_taken()
                updates = old.updates + _updates(h.simulator)
                what = f"{taken} steps and {updates} discrete updates"
            else:
                taken = updates = old.steps + h.integrator.get_num_steps_taken()
                what = f"{taken} steps"
            if taken != h.n or updates != h.n:
                raise EngineError(
                    f"drake {h.scheme}: Drake took {what} where the plan had {h.n} fixed steps "
                    f"of {ctx.dt!r} s (up to t = {target!r}, over {len(h.charts)} chart(s)); "
                    "the time bookkeeping of the adapter is wrong"
                )
            if ctx.integrator.evals_per_step is None and h.scheme != "cenic":
                self._add_evals(ctx)

    def _failure(self, ctx, exc) -> StepFailure:
        """The StepFailure of a step Drake could not take, with the time it started from."""
        h = ctx.handle
        if h.mode == "error-controlled":
            t = h.t_last
        else:  # the steps this call took, each of dt
            sim, old = h.simulator, h.replaced
            done = old.steps + (
                sim.get_num_steps_taken()
                if h.integrator is None
                else h.integrator.get_num_steps_taken()
            )
            t = h.t + (done - h.n) * ctx.dt
        msg = f"Drake: {exc}"
        if ctx.model.pivoted and "singularity" in str(exc):
            msg = (
                f"within one step of drake {h.scheme} the BallRpyJoint's roll-pitch-yaw chart "
                f"went from |cos pitch| >= {CHART_SWITCH_COS} (where every step starts: after a "
                "step that ends below it the adapter switches to a chart with pitch 0) to "
                "Drake's own singularity check (|cos pitch| about 1e-3): one step (a trial "
                "step, a stage or a Newton iterate of it) turned the body more than "
                f"{90 - math.degrees(math.acos(CHART_SWITCH_COS)):.1f} degrees in pitch; "
                f"{msg}"
            )
        return StepFailure(msg, time=t)

    def _switch_chart(self, ctx) -> None:
        """Carry a pivoted run over to a new chart (:func:`centred_chart`) at the end of the
        step after which the monitor found |cos pitch| < :data:`CHART_SWITCH_COS`: read (R, W)
        in the old chart, build a new plant, Simulator and integrator with the new frames F
        and M, write (R, W) in the new chart at the same time, and fold the old Simulator's
        counts into ``h.replaced``. The state is the same to round-off (tested); adapter
        glue, so not on ctx.clock (its time is in ``h.switch_s``)."""
        t0 = time.perf_counter()
        h = ctx.handle
        sim, integ, old = h.simulator, h.integrator, h.replaced
        t = h.context.get_time()
        q = h.plant.GetPositions(h.context)
        R, W = cv.drake_ball_rpy_to_state(q, h.plant.GetVelocities(h.context), h.R_WF, h.R_BM)
        if integ is None:
            old.steps += sim.get_num_steps_taken()
            old.updates += _updates(sim)
        else:
            old.steps += integ.get_num_steps_taken()
            old.evals += integ.get_num_derivative_evaluations()
            old.rejected_by_error += integ.get_num_step_shrinkages_from_error_control()
            old.rejected_by_failure += integ.get_num_step_shrinkages_from_substep_failures()
            old.largest = _extreme(max, old.largest, integ.get_largest_step_size_taken())
            old.smallest = _extreme(min, old.smallest, integ.get_smallest_adapted_step_size_taken())
        sim.clear_monitor()  # it holds h: a reference cycle through C++ the GC cannot see
        h.switches.append((t, abs(math.cos(q[1]))))
        R_WF, R_BM, _ = centred_chart(ctx.model, R, W)
        first = h.first_step
        if h.mode == "error-controlled" and math.isfinite(h.last_step):
            first = min(h.last_step, h.horizon)  # error control resumes from the last step
        self._assemble(ctx, h, R_WF, R_BM, first)
        q, v = cv.drake_ball_rpy_from_state(R, W, h.R_WF, h.R_BM)
        h.plant.SetPositions(h.context, q)
        h.plant.SetVelocities(h.context, v)
        h.simulator.get_mutable_context().SetTime(t)
        h.switch_pending = False
        h.t_last = t
        h.simulator.Initialize()
        h.switch_s += time.perf_counter() - t0

    def _add_evals(self, ctx) -> int:
        h = ctx.handle
        evals = h.replaced.evals + int(h.integrator.get_num_derivative_evaluations())
        if h.scheme != "cenic":
            ctx.nevals += evals - h.evals_seen
        h.evals_seen = evals
        return evals

    def _collect_stats(self, ctx) -> None:
        h = ctx.handle
        integ, old = h.integrator, h.replaced
        evals = self._add_evals(ctx)
        by_error = old.rejected_by_error + integ.get_num_step_shrinkages_from_error_control()
        by_failure = old.rejected_by_failure + integ.get_num_step_shrinkages_from_substep_failures()
        ctx.stats.update(
            {
                "steps taken": float(old.steps + integ.get_num_steps_taken()),
                "steps rejected": float(by_error + by_failure),
                "steps rejected by error control": float(by_error),
                "steps rejected by failed substeps": float(by_failure),
                "dynamics evaluations": float(evals) if h.scheme != "cenic" else math.nan,
                "largest step": _extreme(max, old.largest, integ.get_largest_step_size_taken()),
                "smallest adapted step": _extreme(
                    min, old.smallest, integ.get_smallest_adapted_step_size_taken()
                ),
            }
        )

    def close(self, ctx) -> None:
        h = ctx.handle
        if h is not None:
            h.simulator.clear_monitor()
        ctx.handle = None


def _plant(ctx, h: _Handle, R_WF, R_BM):
    """(plant, body, joint, the system to simulate): the finalised MultibodyPlant of
    ``ctx.model`` with its joint between frame F (``R_WF`` on the world) and frame M (``R_BM``
    and ``h.p_BM`` on the body), no geometry; continuous, or discrete with SAP."""
    from pydrake.math import RigidTransform, RotationMatrix
    from pydrake.multibody.plant import (
        AddMultibodyPlantSceneGraph,
        DiscreteContactApproximation,
        MultibodyPlant,
    )
    from pydrake.multibody.tree import (
        BallRpyJoint,
        FixedOffsetFrame,
        QuaternionFloatingJoint,
        RotationalInertia,
        SpatialInertia,
    )
    from pydrake.systems.framework import DiagramBuilder

    mdl = ctx.model
    builder = None
    if h.scheme == "cenic":
        # CENIC refuses a bare plant ("must be given a Diagram"): plant + empty SceneGraph
        builder = DiagramBuilder()
        plant, _ = AddMultibodyPlantSceneGraph(builder, 0.0)
    else:
        plant = MultibodyPlant(time_step=ctx.dt if h.mode == "discrete" else 0.0)
    if h.mode == "discrete":
        plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    I1, I2, I3 = (float(x) for x in mdl.inertia)
    inertia = SpatialInertia.MakeFromCentralInertia(
        mdl.mass, np.zeros(3), RotationalInertia(I1, I2, I3)
    )
    body = plant.AddRigidBody("body", inertia)
    X_WF = RigidTransform(RotationMatrix(R_WF), np.zeros(3))
    frame_F = plant.AddFrame(FixedOffsetFrame("F", plant.world_frame(), X_WF))
    X_BM = RigidTransform(RotationMatrix(R_BM), h.p_BM)
    frame_M = plant.AddFrame(FixedOffsetFrame("M", body.body_frame(), X_BM))
    if mdl.pivoted:
        joint = plant.AddJoint(BallRpyJoint("pivot", frame_F, frame_M, 0.0))
    else:
        joint = plant.AddJoint(QuaternionFloatingJoint("free", frame_F, frame_M, 0.0, 0.0))
    plant.mutable_gravity_field().set_gravity_vector(np.asarray(mdl.gravity, dtype=float))
    plant.Finalize()
    return plant, body, joint, (builder.Build() if builder is not None else plant)


def _integrator(ctx, h: _Handle, sim, first_step: float):
    """The Simulator's integrator, replaced by the run's (None for the discrete plant)."""
    from pydrake.systems.analysis import ResetIntegratorFromFlags

    if h.mode == "fixed step":
        integ = ResetIntegratorFromFlags(sim, h.scheme, ctx.dt)
        integ.set_fixed_step_mode(True)
        return integ
    if h.mode != "error-controlled":
        return None
    # No cap on the step but the run's horizon: Drake never steps past the time it is asked
    # to reach, so the checkpoints (ctx.dt times the save interval, at most base.CHUNK steps
    # apart) are the only other limit. A cap at ctx.dt would pin the step there and make
    # every target accuracy the same run.
    integ = ResetIntegratorFromFlags(sim, h.scheme, h.horizon)
    integ.set_fixed_step_mode(False)
    integ.set_target_accuracy(ctx.accuracy)
    integ.request_initial_step_size_target(first_step)
    h.first_step = first_step
    return integ


def _model_checks(h: _Handle) -> dict:
    """The read-back of everything of the plant that could distort a run but inertia, joint
    type, gravity and step: name -> (value, required[, atol])."""
    plant, body, joint, pc = h.plant, h.body, h.joint, h.context
    X_BM = joint.frame_on_child().CalcPoseInBodyFrame(pc)
    X_WF = joint.frame_on_parent().CalcPoseInWorld(pc)
    nv = plant.num_velocities()
    lows = (joint.position_lower_limits(), joint.velocity_lower_limits(),
            joint.acceleration_lower_limits())  # fmt: skip
    ups = (joint.position_upper_limits(), joint.velocity_upper_limits(),
           joint.acceleration_upper_limits())  # fmt: skip
    infinite = all(np.all(np.isneginf(a)) for a in lows) and all(
        np.all(np.isposinf(a)) for a in ups
    )
    gravity_on = plant.gravity_field().is_enabled(body.model_instance())
    return {
        "joint damping (in the context)": (joint.GetDampingVector(pc), np.zeros(nv)),
        "joint damping (default)": (joint.default_damping_vector(), np.zeros(nv)),
        "joint position, velocity and acceleration limits infinite": (float(infinite), 1.0),
        "joint locked": (float(joint.is_locked(pc)), 0.0),
        "joint frame F origin in the world": (X_WF.translation(), np.zeros(3)),
        "joint frame F rotation": (X_WF.rotation().matrix(), h.R_WF, 1e-15),
        "joint frame M rotation in the body": (X_BM.rotation().matrix(), h.R_BM, 1e-15),
        "number of bodies (world and the body)": (plant.num_bodies(), 2),
        "number of joints": (plant.num_joints(), 1),
        "number of force elements (gravity only)": (plant.num_force_elements(), 1),
        "number of actuators": (plant.num_actuators(), 0),
        "number of constraints": (plant.num_constraints(), 0),
        "number of collision geometries": (plant.num_collision_geometries(), 0),
        "gravity enabled for the body": (float(gravity_on), 1.0),
    }


def _integrator_checks(ctx, h: _Handle, extra: dict) -> float:
    """Add the read-back of the time stepping (discrete approximation, or the integrator's
    mode, accuracy and step sizes) to ``extra``; return the step to check against ctx.dt."""
    plant = h.plant
    if h.mode == "discrete":
        from pydrake.multibody.plant import DiscreteContactApproximation

        extra["discrete contact approximation (SAP)"] = (
            float(plant.get_discrete_contact_approximation().value),
            float(DiscreteContactApproximation.kSap.value),
        )
        return plant.time_step()
    integ = h.integrator
    extra["plant time step (continuous)"] = (plant.time_step(), 0.0)
    extra["fixed step mode"] = (float(integ.get_fixed_step_mode()), float(h.mode == "fixed step"))
    if h.mode != "error-controlled":
        return integ.get_maximum_step_size()
    extra["target accuracy"] = (integ.get_target_accuracy(), ctx.accuracy)
    extra["maximum step size (the horizon)"] = (integ.get_maximum_step_size(), h.horizon)
    extra["initial step size target (requested)"] = (
        integ.get_initial_step_size_target(),
        h.first_step,
    )
    # an error-controlled integrator has no step of its own to read back: ctx.dt is the
    # interval of the adapter's calls (checkpoints), not an engine setting
    return ctx.dt


def _monitor(h: _Handle, pivoted: bool):
    """The Simulator monitor (called at the end of Initialize and of every step) of the
    Simulator now in ``h``.

    Error-controlled runs: stop the run (EventStatus.Failed, so AdvanceTo raises) once it
    has made more than ``h.budget`` dynamics evaluations (steps for CENIC), counted over every
    integrator of the run; keep the last step's size (the next chart's first step).
    Pivoted bodies: keep the smallest |cos pitch| and, when a step ends below
    :data:`CHART_SWITCH_COS`, end AdvanceTo there (EventStatus.ReachedTermination, which makes
    it return at that step's end) for :meth:`DrakeEngine._switch_chart`."""
    from pydrake.systems.framework import EventStatus

    plant, old = h.plant, h.replaced
    budget = h.budget
    cenic = h.scheme == "cenic"
    what = "steps (CENIC counts no evaluations)" if cenic else "dynamics evaluations"
    if pivoted:
        # a read-only view of the plant's state [roll, pitch, yaw, w_F] (BasicVector.get_value:
        # Drake writes every step into the same storage; tested), read without a call into
        # Drake: 0.1 us instead of 1 us a step
        x = (
            h.context.get_discrete_state_vector()
            if h.mode == "discrete"
            else h.context.get_continuous_state_vector()
        ).get_value()
    cos = math.cos

    def monitor(root_context):
        if budget is not None:
            integ = h.integrator  # (not captured: the kit plants a replacement)
            steps = old.steps + integ.get_num_steps_taken()
            evals = old.evals + integ.get_num_derivative_evaluations()
            if (steps if cenic else evals) > budget:
                rejected = old.rejected_by_error
                rejected += integ.get_num_step_shrinkages_from_error_control()
                h.stop = (
                    f"drake {h.scheme} (error-controlled): cut off at t = "
                    f"{root_context.get_time():.6g} s after {steps} steps and {evals} dynamics "
                    f"evaluations, over the budget of {budget} {what} ({EVAL_BUDGET} per "
                    f"fixed step of the scenario); steps rejected so far {rejected}"
                )
                return EventStatus.Failed(plant, h.stop)
            t = root_context.get_time()
            if t > h.t_last:
                h.last_step = t - h.t_last
                h.t_last = t
        if pivoted:
            c = abs(cos(x[1]))
            if c < h.min_cos_pitch:
                h.min_cos_pitch = c
            if c < CHART_SWITCH_COS:
                h.switch_pending = True
                return EventStatus.ReachedTermination(plant, "RPY chart switch")
        return None  # success (pydrake's binding)

    return monitor


def _updates(sim) -> int:
    """The state updates a Simulator made (the discrete plant's step is an unrestricted one)."""
    return sim.get_num_discrete_updates() + sim.get_num_unrestricted_updates()


def _extreme(pick, a: float, b: float) -> float:
    """``pick`` (max or min) of two step sizes, NaN standing for none taken."""
    if math.isnan(a):
        return float(b)
    return a if math.isnan(b) else float(pick(a, b))


def _default_integrator(ctx) -> None:
    """Put back the Simulator's default integrator (SimulatorConfig(): runge_kutta3,
    error-controlled, accuracy 1e-4, largest step 0.1 s)."""
    from pydrake.systems.analysis import ApplySimulatorConfig, SimulatorConfig

    h = ctx.handle
    ApplySimulatorConfig(SimulatorConfig(), h.simulator)
    h.integrator = h.simulator.get_mutable_integrator()
