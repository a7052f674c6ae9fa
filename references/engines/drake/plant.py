"""The Drake objects of a run: the MultibodyPlant of the body, its Simulator and integrator,
and their read-back.

The Drake body frame B is the principal centre-of-mass frame: the spatial inertia is
``SpatialInertia.MakeFromCentralInertia(m, 0, RotationalInertia(I1, I2, I3))``. The joint
connects a frame F on the world to a frame M on the body at ``p_BM = -com`` (the pivot for a
pivoted body, B itself for a free one), so the suite's body frame (origin at the joint point,
principal axes) has the centre of mass at ``com``; that is what the read-back reports. There
is no geometry, so nothing can touch; gravity is set and read back; joint damping is 0 and
the joint limits are infinite (read back).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from references.engines.drake.integrators import CONVEX_SCHEME
from references.engines.native import import_engine


def import_drake():
    return import_engine("pydrake", "Drake (pydrake)", "drake")


@dataclass
class Replaced:
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
class Handle:
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
    replaced: Replaced = field(default_factory=Replaced)


def build_plant(ctx, h: Handle, R_WF, R_BM):
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
    if h.scheme == CONVEX_SCHEME:
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


def make_integrator(ctx, h: Handle, sim, first_step: float):
    """The Simulator's integrator, replaced by the run's (None for the discrete plant)."""
    from pydrake.systems.analysis import ResetIntegratorFromFlags

    if h.mode == "fixed step":
        integ = ResetIntegratorFromFlags(sim, h.scheme, ctx.dt)
        integ.set_fixed_step_mode(True)
        return integ
    if h.mode != "error-controlled":
        return None
    # No cap on the step but the run's horizon: Drake never steps past the time it is asked
    # to reach, so the checkpoints (ctx.dt times the save interval, at most stepping.CHUNK steps
    # apart) are the only other limit. A cap at ctx.dt would pin the step there and make
    # every target accuracy the same run.
    integ = ResetIntegratorFromFlags(sim, h.scheme, h.horizon)
    integ.set_fixed_step_mode(False)
    integ.set_target_accuracy(ctx.accuracy)
    integ.request_initial_step_size_target(first_step)
    h.first_step = first_step
    return integ


def model_checks(h: Handle) -> dict:
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


def integrator_checks(ctx, h: Handle, extra: dict) -> float:
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


def update_count(sim) -> int:
    """The state updates a Simulator made (the discrete plant's step is an unrestricted one)."""
    return sim.get_num_discrete_updates() + sim.get_num_unrestricted_updates()


def default_integrator(ctx) -> None:
    """Put back the Simulator's default integrator (SimulatorConfig(): runge_kutta3,
    error-controlled, accuracy 1e-4, largest step 0.1 s)."""
    from pydrake.systems.analysis import ApplySimulatorConfig, SimulatorConfig

    h = ctx.handle
    ApplySimulatorConfig(SimulatorConfig(), h.simulator)
    h.integrator = h.simulator.get_mutable_integrator()
