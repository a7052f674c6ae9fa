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
error 9.6e-10 with the spin as roll, 7.2e-4 without). A run in which |cos pitch| falls below
:data:`CHART_MIN_COS` at a checkpoint (or Drake's own singularity check fires) ends as diverged
at that time: for the library's pivoted bodies, only a numerical motion far off the exact one
gets there.

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
from dataclasses import dataclass
from typing import Any

import numpy as np

from references import conventions as cv
from references.engines.base import (
    Engine,
    EngineError,
    Family,
    Integrator,
    ModelReadback,
    StepFailure,
    Unsupported,
    import_engine,
    register_family,
)

#: an error-controlled run may make at most this many dynamics evaluations per fixed step of
#: the scenario (t_end / scenario.dt, at least MIN_FIXED_STEPS) before it is cut off (see the
#: module docstring); runge_kutta5 at a fixed step makes 7
EVAL_BUDGET = 10
#: the fixed-step count the budget is scaled from is at least this, so that a run of a few
#: steps (the conformance kit's) has room for the integrator's first step-size adjustments
MIN_FIXED_STEPS = 100

#: a pivoted run ends (diverged) when |cos pitch| of the RPY chart falls below this at a
#: checkpoint: the chart's kinematic map (1/cos pitch) would amplify errors more than 5x
CHART_MIN_COS = 0.2

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
#: stays above this over the whole motion (|cos pitch| = sin(tilt) in that chart)
ROLL_AXIS_MIN_SIN = 0.3


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
    a_world = R0 @ a
    fx = _unit(a_world - (a_world @ b) * b)
    R_WF = np.column_stack([fx, np.cross(b, fx), b])
    u = R0.T @ R_WF[:, 1]
    R_BM = np.column_stack([a, u, np.cross(a, u)])
    return R_WF, R_BM, why


# -- the adapter --------------------------------------------------------------------------------


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
    #: Drake's derivative evaluations already added to ctx.nevals
    evals_seen: int = 0
    budget: int | None = None
    horizon: float = math.nan
    stop: str | None = None
    min_cos_pitch: float = math.inf
    chart: str = ""


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
        from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
        from pydrake.systems.framework import DiagramBuilder

        mdl = ctx.model
        mode = ctx.integrator.options["mode"]
        scheme = ctx.integrator.options["scheme"]
        builder = None
        if scheme == "cenic":
            # CENIC refuses a bare plant ("must be given a Diagram"): plant + empty SceneGraph
            builder = DiagramBuilder()
            plant, _ = AddMultibodyPlantSceneGraph(builder, 0.0)
        else:
            plant = MultibodyPlant(time_step=ctx.dt if mode == "discrete" else 0.0)
        if mode == "discrete":
            plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        I1, I2, I3 = (float(x) for x in mdl.inertia)
        body = plant.AddRigidBody(
            "body",
            SpatialInertia.MakeFromCentralInertia(
                mdl.mass, np.zeros(3), RotationalInertia(I1, I2, I3)
            ),
        )
        if mdl.pivoted:
            R_WF, R_BM, chart = rpy_chart(mdl, ctx.scenario.rotation, ctx.scenario.omega_body)
        else:
            R_WF, R_BM, chart = np.eye(3), np.eye(3), ""
        p_BM = -np.asarray(mdl.com, dtype=float)
        frame_F = plant.AddFrame(
            FixedOffsetFrame(
                "F", plant.world_frame(), RigidTransform(RotationMatrix(R_WF), np.zeros(3))
            )
        )
        frame_M = plant.AddFrame(
            FixedOffsetFrame("M", body.body_frame(), RigidTransform(RotationMatrix(R_BM), p_BM))
        )
        if mdl.pivoted:
            joint = plant.AddJoint(BallRpyJoint("pivot", frame_F, frame_M, 0.0))
        else:
            joint = plant.AddJoint(QuaternionFloatingJoint("free", frame_F, frame_M, 0.0, 0.0))
        plant.mutable_gravity_field().set_gravity_vector(np.asarray(mdl.gravity, dtype=float))
        plant.Finalize()
        system = builder.Build() if builder is not None else plant
        sim = Simulator(system)
        context = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        integ = None
        horizon = ctx.t_end
        if mode == "fixed step":
            integ = ResetIntegratorFromFlags(sim, scheme, ctx.dt)
            integ.set_fixed_step_mode(True)
        elif mode == "error-controlled":
            # No cap on the step but the run's horizon: Drake never steps past the time it is
            # asked to reach, so the checkpoints (ctx.dt times the save interval, at most
            # base.CHUNK steps apart) are the only other limit. A cap at ctx.dt would pin the
            # step there and make every target accuracy the same run.
            integ = ResetIntegratorFromFlags(sim, scheme, horizon)
            integ.set_fixed_step_mode(False)
            integ.set_target_accuracy(ctx.accuracy)
            # Drake's first attempt would be the largest step (the horizon); from such a step
            # runge_kutta5's error control never recovers on a top (measured: 258000 rejected
            # attempts and no step in 12 s at t = 0, heavy_top, 1e-6), and no step means no
            # monitor call to cut it off. The scenario's own fixed step is a sane first try.
            integ.request_initial_step_size_target(min(ctx.scenario.dt, horizon))
        h = _Handle(plant, body, joint, sim, context, integ, mode, scheme, R_WF, R_BM, p_BM)
        h.horizon = horizon
        h.chart = chart
        if mode == "error-controlled":
            fixed_steps = max(horizon / ctx.scenario.dt, MIN_FIXED_STEPS)
            h.budget = int(math.ceil(EVAL_BUDGET * fixed_steps))
            sim.set_monitor(_budget_monitor(h, plant))
        ctx.handle = h
        if scheme == "cenic":
            ctx.nevals = math.nan  # CENIC counts no derivative evaluations (it has none)

    def read_model(self, ctx) -> ModelReadback:
        h = ctx.handle
        plant, body, joint, pc = h.plant, h.body, h.joint, h.context
        M = body.CalcSpatialInertiaInBodyFrame(pc)  # about Bo, the COM by construction
        p_BoBcm = np.asarray(M.get_com())
        about_com = M.Shift(p_BoBcm)
        X_BM = joint.frame_on_child().CalcPoseInBodyFrame(pc)
        X_WF = joint.frame_on_parent().CalcPoseInWorld(pc)
        nv = plant.num_velocities()
        lims = [
            joint.position_lower_limits(),
            joint.velocity_lower_limits(),
            joint.acceleration_lower_limits(),
        ]
        ups = [
            joint.position_upper_limits(),
            joint.velocity_upper_limits(),
            joint.acceleration_upper_limits(),
        ]
        infinite = all(np.all(np.isneginf(a)) for a in lims) and all(
            np.all(np.isposinf(a)) for a in ups
        )
        extra = {
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
            "gravity enabled for the body": (
                float(plant.gravity_field().is_enabled(body.model_instance())),
                1.0,
            ),
        }
        if h.mode == "discrete":
            from pydrake.multibody.plant import DiscreteContactApproximation

            extra["discrete contact approximation (SAP)"] = (
                float(plant.get_discrete_contact_approximation().value),
                float(DiscreteContactApproximation.kSap.value),
            )
            dt = plant.time_step()
        else:
            integ = h.integrator
            extra["plant time step (continuous)"] = (plant.time_step(), 0.0)
            extra["fixed step mode"] = (
                float(integ.get_fixed_step_mode()),
                float(h.mode == "fixed step"),
            )
            if h.mode == "error-controlled":
                extra["target accuracy"] = (integ.get_target_accuracy(), ctx.accuracy)
                extra["maximum step size (the horizon)"] = (
                    integ.get_maximum_step_size(),
                    h.horizon,
                )
                extra["initial step size target (the scenario's dt)"] = (
                    integ.get_initial_step_size_target(),
                    min(ctx.scenario.dt, h.horizon),
                )
                # an error-controlled integrator has no step of its own to read back: ctx.dt is
                # the interval of the adapter's calls (checkpoints), not an engine setting
                dt = ctx.dt
            else:
                dt = integ.get_maximum_step_size()
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
            "joint frame M on the body": f"origin {h.p_BM.tolist()}, rotation {h.R_BM.tolist()}",
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
                f"{h.chart}; frame F rotation {h.R_WF.tolist()}; the run ends below "
                f"|cos pitch| {CHART_MIN_COS} (smallest seen {h.min_cos_pitch:.4g})"
            )
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

    def read_state(self, ctx) -> cv.BodyState:
        h = ctx.handle
        q = h.plant.GetPositions(h.context)
        v = h.plant.GetVelocities(h.context)
        if ctx.model.pivoted:
            R, W = cv.drake_ball_rpy_to_state(q, v, h.R_WF, h.R_BM)
            return ctx.model.state_from_rotation(R, W)
        return cv.drake_free_to_state(q, v)

    def read_raw(self, ctx) -> np.ndarray:
        h = ctx.handle
        return np.concatenate((h.plant.GetPositions(h.context), h.plant.GetVelocities(h.context)))

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        h = ctx.handle
        nq = 3 if ctx.model.pivoted else 7
        return cv.drake_block(
            raw, nq, ctx.model.com, ctx.model.pivoted, getattr(h, "R_WF", None),
            getattr(h, "R_BM", None),
        )  # fmt: skip

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
        try:
            with ctx.clock:
                h.simulator.AdvanceTo(target)
        except RuntimeError as exc:
            if h.stop is not None:
                raise Unsupported(h.stop) from exc
            raise StepFailure(f"Drake: {exc}") from exc
        h.t = target
        if ctx.model.pivoted:
            self._check_chart(ctx)
        h.n += k
        if h.mode == "error-controlled":
            self._collect_stats(ctx)
        else:
            taken = (
                h.simulator.get_num_steps_taken()
                if h.integrator is None
                else h.integrator.get_num_steps_taken()
            )
            if taken != h.n:
                raise EngineError(
                    f"drake {h.scheme}: Drake took {taken} steps where the plan had {h.n} "
                    f"fixed steps of {ctx.dt!r} s (up to t = {target!r}); the time bookkeeping "
                    "of the adapter is wrong"
                )
            if ctx.integrator.evals_per_step is None and h.scheme != "cenic":
                self._add_evals(ctx)

    def _add_evals(self, ctx) -> int:
        h = ctx.handle
        evals = int(h.integrator.get_num_derivative_evaluations())
        if h.scheme != "cenic":
            ctx.nevals += evals - h.evals_seen
        h.evals_seen = evals
        return evals

    def _collect_stats(self, ctx) -> None:
        h = ctx.handle
        integ = h.integrator
        evals = self._add_evals(ctx)
        by_error = integ.get_num_step_shrinkages_from_error_control()
        by_failure = integ.get_num_step_shrinkages_from_substep_failures()
        ctx.stats.update(
            {
                "steps taken": float(integ.get_num_steps_taken()),
                "steps rejected": float(by_error + by_failure),
                "steps rejected by error control": float(by_error),
                "steps rejected by failed substeps": float(by_failure),
                "dynamics evaluations": float(evals) if h.scheme != "cenic" else math.nan,
                "largest step": float(integ.get_largest_step_size_taken()),
                "smallest adapted step": float(integ.get_smallest_adapted_step_size_taken()),
            }
        )

    def _check_chart(self, ctx) -> None:
        """End a pivoted run whose RPY chart came near its singularity (|cos pitch| below
        :data:`CHART_MIN_COS` at a checkpoint): a StepFailure at that time, so the run counts
        as diverged there. With the frames of :func:`rpy_chart` the exact motions of the
        library's pivoted bodies stay far from the singular set (|cos pitch| >= 0.47,
        tests/test_engine_drake.py), so reaching it means the numerical motion has left the
        exact one far behind: the integrator has failed, and beyond that point the chart, not
        the integrator, would shape the result."""
        h = ctx.handle
        pitch = float(h.plant.GetPositions(h.context)[1])
        c = abs(math.cos(pitch))
        h.min_cos_pitch = min(h.min_cos_pitch, c)
        if c < CHART_MIN_COS:
            exc = StepFailure(
                f"the BallRpyJoint's roll-pitch-yaw chart reached pitch = {pitch:.6g} rad "
                f"(|cos pitch| = {c:.3g} < {CHART_MIN_COS}) at t = {h.t:.6g} s, where the exact "
                "motion of a top or pendulum never goes with this chart; Drake 1.51 has no ball "
                "joint with quaternion coordinates (drake issue 12404), so the run stops here"
            )
            exc.time = h.t
            raise exc

    def close(self, ctx) -> None:
        h = ctx.handle
        if h is not None:
            h.simulator.clear_monitor()
        ctx.handle = None


def _budget_monitor(h: _Handle, plant):
    """A Simulator monitor (called after every step) that stops an error-controlled run once
    it has made more than ``h.budget`` dynamics evaluations (steps for CENIC)."""
    from pydrake.systems.framework import EventStatus

    integ = h.integrator
    cenic = h.scheme == "cenic"
    what = "steps (CENIC counts no evaluations)" if cenic else "dynamics evaluations"

    def monitor(root_context):
        steps = integ.get_num_steps_taken()
        evals = integ.get_num_derivative_evaluations()
        if (steps if cenic else evals) > h.budget:
            h.stop = (
                f"drake {h.scheme} (error-controlled): cut off at t = "
                f"{root_context.get_time():.6g} s after {steps} steps and {evals} dynamics "
                f"evaluations, over the budget of {h.budget} {what} ({EVAL_BUDGET} per fixed "
                f"step of the scenario); steps rejected so far "
                f"{integ.get_num_step_shrinkages_from_error_control()}"
            )
            return EventStatus.Failed(plant, h.stop)
        return EventStatus.Succeeded()

    return monitor


def _default_integrator(ctx) -> None:
    """Put back the Simulator's default integrator (SimulatorConfig(): runge_kutta3,
    error-controlled, accuracy 1e-4, largest step 0.1 s)."""
    from pydrake.systems.analysis import ApplySimulatorConfig, SimulatorConfig

    h = ctx.handle
    ApplySimulatorConfig(SimulatorConfig(), h.simulator)
    h.integrator = h.simulator.get_mutable_integrator()
