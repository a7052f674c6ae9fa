"""DART adapter: a FreeJoint (free body) or a BallJoint at the world origin (pivoted body).

- ``semi-implicit Euler``: DART's only built-in stepper, ``World.step`` (docs/engines.md).
- ``RKMK4``: our Runge-Kutta-Munthe-Kaas of order 4 (:mod:`references.engines.liegroup`) on
  SO(3) x R^3 (free body) or SO(3) (pivoted body), with the accelerations from DART's
  ``Skeleton.computeForwardDynamics``. DART contributes the forces only.

Frames (measured, docs/engines.md): FreeJoint positions are [rotation vector, x], velocities
[w WORLD, v WORLD]; BallJoint positions are a rotation vector and velocities are BODY rates.
For the RKMK4 stages the accelerations are mapped to body rates: with w = R W,
W' = R^T w' because R'^T w = -(W x W) = 0.

Defaults neutralised: deactivation (sleeping) is switched off in the World, gravity set
explicitly (DART's default is (0, 0, -9.81)). The skeleton has no shape nodes, so nothing can
collide. Joint damping, springs, Coulomb friction and limit enforcement are read back as off.

Observed (DART 6.20): when a state diverges DART prints warnings and replaces non-finite joint
accelerations and transforms by zero / identity ("to avoid instability"); positions and
velocities still become non-finite, which is what this adapter checks.
"""

from __future__ import annotations

import time

import numpy as np

from references import conventions as cv
from references.engines import _rkmk4
from references.engines.context import ModelReadback
from references.engines.integrators import Integrator
from references.engines.interface import Engine, SceneBuilder
from references.engines.liegroup import StagedDynamics
from references.engines.native import import_engine


def _import():
    return import_engine("dartpy", "DART (dartpy)", "dartpy")


def _plant_sleeping(ctx) -> None:
    world = ctx.handle[0]
    opts = world.getDeactivationOptions()
    opts.mEnabled = True
    world.setDeactivationOptions(opts)


def _plant_damping(ctx) -> None:
    joint = ctx.handle[2]
    for i in range(joint.getNumDofs()):
        joint.setDampingCoefficient(i, 0.01)


class DartEngine(Engine):
    """DART (``dartpy``): World.step, or our RKMK4 around computeForwardDynamics."""

    name = "dart"
    description = "DART: FreeJoint or BallJoint; World.step or our RKMK4 on DART's dynamics"
    scene_builder = SceneBuilder(
        "references.engines.dart.system:simulate_system",
        ("erp", "revolute_closure"),
        force_elements=True,
    )
    integrators = (
        Integrator(
            "semi-implicit Euler",
            "semi-implicit Euler",
            1,
            "DART's World.step, its only built-in stepper: velocities updated with the "
            "forward-dynamics accelerations, then positions integrated with the new velocities.",
        ),
        Integrator(
            "RKMK4",
            "4th-order Lie-group",
            4,
            "Ours: Runge-Kutta-Munthe-Kaas order 4 on SO(3) x R^3 (SO(3) when pivoted) with "
            "exact dexp^{-1}, accelerations from DART's computeForwardDynamics.",
            stepping="rkmk4",
            evals_per_step=4.0,
        ),
    )

    #: defaults that distort the experiment, planted back by the conformance kit
    plantable = {
        "deactivation (sleeping) left on": (_plant_sleeping, ("free", "pivoted")),
        "joint damping left on": (_plant_damping, ("free", "pivoted")),
    }

    packages = ("dartpy",)
    saves_raw = True

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        dart = _import()
        mdl = ctx.model
        world = dart.simulation.World()
        world.setGravity(mdl.gravity)
        world.setTimeStep(ctx.dt)
        opts = world.getDeactivationOptions()
        opts.mEnabled = False
        world.setDeactivationOptions(opts)
        skel = dart.dynamics.Skeleton(mdl.name)
        if mdl.pivoted:
            joint, body = skel.createBallJointAndBodyNodePair()
        else:
            joint, body = skel.createFreeJointAndBodyNodePair()
        body.setInertia(dart.dynamics.Inertia(mdl.mass, mdl.com, np.diag(mdl.inertia)))
        for i in range(joint.getNumDofs()):
            joint.setDampingCoefficient(i, 0.0)
            joint.setSpringStiffness(i, 0.0)
            joint.setCoulombFriction(i, 0.0)
        joint.setLimitEnforcement(False)
        world.addSkeleton(skel)
        ctx.handle = (world, skel, joint, body)

    def read_model(self, ctx) -> ModelReadback:
        world, skel, joint, body = ctx.handle
        inertia = body.getInertia()
        n = joint.getNumDofs()
        kinds = {"FreeJoint": "free", "BallJoint": "ball"}
        return ModelReadback(
            mass=inertia.getMass(),
            inertia=inertia.getMoment(),
            com=body.getLocalCOM(),
            joint=kinds.get(joint.getType(), joint.getType()),
            gravity=world.getGravity(),
            dt=world.getTimeStep(),
            extra={
                "gravity (skeleton)": (skel.getGravity(), ctx.model.gravity),
                "time step (skeleton)": (skel.getTimeStep(), ctx.dt),
                "body affected by gravity": (float(body.getGravityMode()), 1.0),
                "joint to parent transform": (
                    joint.getTransformFromParentBodyNode().matrix(),
                    np.eye(4),
                ),
                "joint to child transform": (
                    joint.getTransformFromChildBodyNode().matrix(),
                    np.eye(4),
                ),
                "joint damping": ([joint.getDampingCoefficient(i) for i in range(n)], [0.0] * n),
                "joint spring stiffness": (
                    [joint.getSpringStiffness(i) for i in range(n)],
                    [0.0] * n,
                ),
                "joint Coulomb friction": (
                    [joint.getCoulombFriction(i) for i in range(n)],
                    [0.0] * n,
                ),
                "number of shape nodes": (skel.getNumShapeNodes(), 0),
                "joint limits enforced": (float(joint.areLimitsEnforced()), 0.0),
                "deactivation enabled": (float(world.getDeactivationOptions().mEnabled), 0.0),
                "skeleton mobile": (float(skel.isMobile()), 1.0),
            },
        )

    def settings(self, ctx) -> dict:
        return {
            "deactivation (sleeping)": False,
            "gravity": ctx.model.gravity.tolist(),
            "joint": "BallJoint at the world origin" if ctx.model.pivoted else "FreeJoint",
            "local COM": ctx.model.com.tolist(),
            "collision": "none (no shape nodes)",
            "joint damping, spring stiffness, Coulomb friction": 0.0,
            "joint limit enforcement": False,
            "stepping": "World.step"
            if ctx.integrator.stepping == "native"
            else "the suite's RKMK4 around Skeleton.computeForwardDynamics (World.step not used)",
        }

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        _, _, joint, _ = ctx.handle
        if ctx.model.pivoted:
            pos, vel = cv.dart_ball_from_state(state.rotation, state.omega_body)
        else:
            pos, vel = cv.dart_free_from_state(*state)
        joint.setPositions(pos)
        joint.setVelocities(vel)

    def read_state(self, ctx) -> cv.BodyState:
        _, _, joint, _ = ctx.handle
        if ctx.model.pivoted:
            R, W = cv.dart_ball_to_state(joint.getPositions(), joint.getVelocities())
            return ctx.model.state_from_rotation(R, W)
        return cv.dart_free_to_state(joint.getPositions(), joint.getVelocities())

    def read_raw(self, ctx) -> np.ndarray:
        joint = ctx.handle[2]
        return np.concatenate((joint.getPositions(), joint.getVelocities()))

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        ndof = ctx.handle[2].getNumDofs()
        return cv.dart_block(raw, ndof, ctx.model.com, ctx.model.pivoted)

    def native_quantities(self, ctx) -> dict:
        """DART's own energy and momentum; getAngularMomentum() is about the body origin in
        body axes (docs/engines.md): the COM for a free body, the pivot for a pivoted one."""
        _, skel, _, body = ctx.handle
        R = body.getWorldTransform().rotation()
        return {
            "energy": skel.computeKineticEnergy() + skel.computePotentialEnergy(),
            "angular momentum": R @ body.getAngularMomentum(),
            "rotation": np.array(R),
            "COM velocity": body.getCOMLinearVelocity(),
            "COM position": body.getCOM(),
        }

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        world = ctx.handle[0]
        with ctx.clock:
            for _ in range(k):
                world.step()

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """:meth:`Engine.advance_saving` with World.step, the joint's getters and the
        stopwatch bound once and each saved [positions, velocities] copied into one
        preallocated block (a run saving every step reads a state per World.step)."""
        world, _, joint, _ = ctx.handle
        step, clock, now = world.step, ctx.clock, time.perf_counter
        positions, velocities = joint.getPositions, joint.getVelocities
        n = joint.getNumDofs()
        rows = np.empty((len(steps), 2 * n))
        for j, k in enumerate(steps):
            t0 = now()
            for _ in range(k):
                step()
            clock.lap(t0)
            rows[j, :n] = positions()
            rows[j, n:] = velocities()
        return self.states_from_raw(ctx, rows)

    def forward_dynamics(self, ctx, state):
        """(dW/dt, a_G) from computeForwardDynamics. A FreeJoint's accelerations are world
        angular and linear; with w = R W, dW/dt = R^T dw/dt because R'^T w = -(W x W) = 0."""
        _, skel, _, _ = ctx.handle
        if ctx.model.pivoted:
            p, w = cv.dart_ball_from_state(state.rotation, state.omega_body)
        else:
            p, w = cv.dart_free_from_state(*state)
        with ctx.clock:
            skel.setPositions(p)
            skel.setVelocities(w)
            skel.computeForwardDynamics()
            a = np.array(skel.getAccelerations())
        if ctx.model.pivoted:
            return a, None
        return state.rotation.T @ a[:3], a[3:]

    def staged_dynamics(self, ctx) -> StagedDynamics:
        """The compiled RKMK4's stages packing DART's positions and velocities
        (``_rkmk4.dart_stage``), and the engine's calls on them bound once: the stopwatch
        around the four DART calls only."""
        skel = ctx.handle[1]
        w = np.zeros(_rkmk4.STAGED_WORKSPACE)
        pos, vel = _rkmk4.dart_buffers(w, bool(ctx.model.pivoted))
        clock, now = ctx.clock, time.perf_counter
        set_pos, set_vel = skel.setPositions, skel.setVelocities
        compute, accelerations = skel.computeForwardDynamics, skel.getAccelerations

        def call():
            t0 = now()
            set_pos(pos)
            set_vel(vel)
            compute()
            a = accelerations()
            clock.lap(t0)
            return a

        return StagedDynamics(w, _rkmk4.dart_stage, _rkmk4.dart_finish, call, len(pos),
                              "DART's getAccelerations")  # fmt: skip
