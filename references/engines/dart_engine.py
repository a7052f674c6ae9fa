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

import numpy as np

from references import conventions as cv
from references.engines.base import (
    READBACK_RTOL,
    Engine,
    EngineError,
    Integrator,
    RunOutput,
    StepFailure,
    Stopwatch,
    import_engine,
)
from references.engines.liegroup import rkmk4_step, so3_r3_dexpinv, so3_r3_integrate
from references.trajectory import Trajectory


def _import():
    return import_engine("dartpy", "DART (dartpy)", "dartpy")


class DartEngine(Engine):
    """DART (``dartpy``): World.step, or our RKMK4 around computeForwardDynamics."""

    name = "dart"
    description = "DART: FreeJoint or BallJoint; World.step or our RKMK4 on DART's dynamics"
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
        ),
    )

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    # -- model -------------------------------------------------------------------------
    def _build(self, scenario, dt):
        dart = _import()
        world = dart.simulation.World()
        world.setGravity(np.asarray(scenario.gravity, dtype=float))
        world.setTimeStep(float(dt))
        opts = world.getDeactivationOptions()
        opts.mEnabled = False
        world.setDeactivationOptions(opts)

        skel = dart.dynamics.Skeleton(scenario.name or "body")
        if scenario.pivoted:
            joint, body = skel.createBallJointAndBodyNodePair()
            com = -np.asarray(scenario.pivot, dtype=float)
        else:
            joint, body = skel.createFreeJointAndBodyNodePair()
            com = np.zeros(3)
        body.setInertia(dart.dynamics.Inertia(float(scenario.mass), com, np.diag(scenario.inertia)))
        for i in range(joint.getNumDofs()):
            joint.setDampingCoefficient(i, 0.0)
            joint.setSpringStiffness(i, 0.0)
            joint.setCoulombFriction(i, 0.0)
        joint.setLimitEnforcement(False)
        world.addSkeleton(skel)
        self._check_model(world, skel, joint, body, scenario, com, dt)
        settings = {
            "deactivation (sleeping)": False,
            "gravity": np.asarray(scenario.gravity).tolist(),
            "timestep": float(dt),
            "joint": "BallJoint at the world origin" if scenario.pivoted else "FreeJoint",
            "local COM": com.tolist(),
            "collision": "none (no shape nodes)",
            "joint damping, spring stiffness, Coulomb friction": 0.0,
            "joint limit enforcement": False,
        }
        return world, skel, joint, body, settings

    @staticmethod
    def _check_model(world, skel, joint, body, scenario, com, dt):
        chk = cv.check_quantity
        e = "DART"
        inertia = body.getInertia()
        chk(e, "mass", inertia.getMass(), scenario.mass, READBACK_RTOL)
        chk(
            e,
            "inertia tensor about the COM",
            inertia.getMoment(),
            np.diag(scenario.inertia),
            READBACK_RTOL,
        )
        chk(e, "COM position in the body frame", body.getLocalCOM(), com, READBACK_RTOL)
        chk(e, "gravity (world)", world.getGravity(), scenario.gravity, READBACK_RTOL)
        chk(e, "gravity (skeleton)", skel.getGravity(), scenario.gravity, READBACK_RTOL)
        chk(e, "time step (world)", world.getTimeStep(), dt, READBACK_RTOL)
        chk(e, "time step (skeleton)", skel.getTimeStep(), dt, READBACK_RTOL)
        chk(e, "body affected by gravity", float(body.getGravityMode()), 1.0, 0, 0)
        chk(
            e,
            "joint to parent transform",
            joint.getTransformFromParentBodyNode().matrix(),
            np.eye(4),
            0,
            0,
        )
        chk(
            e,
            "joint to child transform",
            joint.getTransformFromChildBodyNode().matrix(),
            np.eye(4),
            0,
            0,
        )
        n = joint.getNumDofs()
        chk(e, "joint damping", [joint.getDampingCoefficient(i) for i in range(n)], np.zeros(n), 0)
        chk(
            e,
            "joint spring stiffness",
            [joint.getSpringStiffness(i) for i in range(n)],
            np.zeros(n),
            0,
        )
        chk(
            e,
            "joint Coulomb friction",
            [joint.getCoulombFriction(i) for i in range(n)],
            np.zeros(n),
            0,
        )
        chk(e, "number of shape nodes", skel.getNumShapeNodes(), 0, 0, 0)
        if joint.areLimitsEnforced():
            raise EngineError("DART: joint limits are enforced in the built model")
        if world.getDeactivationOptions().mEnabled:
            raise EngineError("DART: deactivation (sleeping) is still enabled in the World")
        if not skel.isMobile():
            raise EngineError("DART: the skeleton is not mobile")

    # -- state -------------------------------------------------------------------------
    @staticmethod
    def joint_state_from(scenario, x, v, R, W):
        if scenario.pivoted:
            return cv.dart_ball_from_state(R, W)
        return cv.dart_free_from_state(x, v, R, W)

    @staticmethod
    def to_state(positions, velocities, scenario) -> cv.BodyState:
        if scenario.pivoted:
            R, W = cv.dart_ball_to_state(positions, velocities)
            return cv.BodyState(*cv.pivot_com(R, W, scenario.pivot), R, W)
        return cv.dart_free_to_state(positions, velocities)

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        world, skel, joint, body, settings = self._build(scenario, dt)
        pos, vel = self.joint_state_from(
            scenario,
            scenario.position,
            scenario.velocity,
            scenario.rotation,
            scenario.omega_body,
        )
        joint.setPositions(pos)
        joint.setVelocities(vel)
        state0 = self.to_state(joint.getPositions(), joint.getVelocities(), scenario)
        # DART's own energy and momentum; getAngularMomentum() is about the body origin in
        # body axes (docs/engines.md): the COM for a free body, the pivot for a pivoted one.
        native = {
            "energy": skel.computeKineticEnergy() + skel.computePotentialEnergy(),
            "angular momentum": body.getWorldTransform().rotation() @ body.getAngularMomentum(),
            "COM velocity": body.getCOMLinearVelocity(),
        }
        cv.check_initial_state("DART", scenario, state0, native=native)
        cv.check_quantity(
            "DART", "COM world position", body.getCOM(), state0.position, 1e-14, 1e-15
        )
        cv.check_quantity(
            "DART", "body rotation", body.getWorldTransform().rotation(), state0.rotation, 0, 1e-15
        )

        pivoted = scenario.pivoted
        if integrator == "semi-implicit Euler":

            def advance():
                world.step()

            def read():
                return self.to_state(joint.getPositions(), joint.getVelocities(), scenario)
        else:
            # Our RKMK4 state: q = (R,) or (R, x); u = W or (W, v_G).
            s0 = state0
            rk = {
                "q": (s0.rotation,) if pivoted else (s0.rotation, s0.position),
                "u": s0.omega_body.copy()
                if pivoted
                else np.concatenate([s0.omega_body, s0.velocity]),
            }

            def accel(q, u):
                R = q[0]
                if pivoted:
                    p, w = cv.dart_ball_from_state(R, u)
                else:
                    p, w = cv.dart_free_from_state(q[1], u[3:], R, u[:3])
                skel.setPositions(p)
                skel.setVelocities(w)
                skel.computeForwardDynamics()
                a = np.array(skel.getAccelerations())
                if pivoted:
                    return a
                return np.concatenate([R.T @ a[:3], a[3:]])

            def advance():
                rk["q"], rk["u"] = rkmk4_step(
                    rk["q"], rk["u"], dt, accel, so3_r3_integrate, so3_r3_dexpinv
                )

            def read():
                q, u = rk["q"], rk["u"]
                if pivoted:
                    return cv.BodyState(*cv.pivot_com(q[0], u, scenario.pivot), q[0], u)
                return cv.BodyState(q[1], u[3:], q[0], u[:3])

        states = []
        watch = Stopwatch()
        done = 0
        report = max(1, nstep // 100)
        for i, target in enumerate(saves):
            with watch:
                try:
                    while done < target:
                        advance()
                        done += 1
                        if progress is not None and done % report == 0:
                            progress(done / nstep)
                except (ArithmeticError, np.linalg.LinAlgError) as exc:
                    raise StepFailure(
                        f"DART {integrator}: step {done + 1} (from t = {done * dt:.6g} s, "
                        f"dt = {dt:g}) could not be taken: {exc}; reduce dt"
                    ) from exc
            state = read()
            if not all(np.all(np.isfinite(a)) for a in state):
                t_prev = saves[i - 1] * dt if i else 0.0
                raise StepFailure(
                    f"DART {integrator}: the state became non-finite between "
                    f"t = {t_prev:.6g} and t = {done * dt:.6g} s (dt = {dt:g}); reduce dt"
                )
            states.append(state)
        if progress is not None:
            progress(1.0)
        traj = Trajectory.from_states(scenario, np.asarray(saves) * dt, *cv.stack_states(states))
        settings["integrator"] = integrator
        settings["stepping"] = (
            "World.step"
            if integrator == "semi-implicit Euler"
            else "our RKMK4 around Skeleton.computeForwardDynamics (World.step not used)"
        )
        return RunOutput(traj, nstep, watch.elapsed, settings)
