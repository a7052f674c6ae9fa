"""PyBullet adapter: the base of a multibody (free body) or one link on a spherical joint at
the world origin under a fixed base (pivoted body).

Integrators are the two body representations of Bullet (docs/engines.md):

- ``multibody``: btMultiBody (Featherstone), semi-implicit Euler with the gyroscopic term
  explicit in the articulated-body dynamics.
- ``maximal coordinates``: ``useMaximalCoordinates=True``, a btRigidBody whose gyroscopic term
  is integrated implicitly in body coordinates (Bullet's default rigid-body flag
  BT_ENABLE_GYROSCOPIC_FORCE_IMPLICIT_BODY; pybullet exposes no switch for it, nor for
  btMultiBody's gyroscopic term, so both are verified by behaviour in the tests). Only free
  bodies: pybullet's createMultiBody with useMaximalCoordinates=True does not create the
  spherical-joint link (getNumJoints returns 0).

Defaults neutralised, every one recorded in the run's settings (docs/engines.md):
damping 0.04 on base and links (law w' = -0.04 (1 + |w|) w) -> 0; the spherical joint's default
motor -> force [0, 0, 0]; the 100 rad/s velocity clamp -> raised; inertia -> set with
localInertiaDiagonal and read back; time step 1/240 -> dt with numSubSteps = 0; gravity set;
sleeping disabled. Found while writing this adapter (pybullet 3.2.7): with maximal
coordinates, changeDynamics(localInertiaDiagonal=...) without ``mass`` sets the mass to 0 (the
body becomes static), so the mass is passed again in the same call; on a btMultiBody LINK,
passing ``mass`` to changeDynamics made the first step NaN, so it is not passed there; and on a
link, body-wide options passed in the same call as localInertiaDiagonal zeroed the inertia.
(The rigid body of maximal coordinates showed no default damping; it is set to 0 all the same.)
"""

from __future__ import annotations

import importlib.metadata

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
    Unsupported,
    import_engine,
)
from references.trajectory import Trajectory

#: the raised velocity clamp (rad/s and m/s); runs whose speeds come near it are refused
MAX_JOINT_VELOCITY = 1e6


def _import():
    return import_engine("pybullet", "PyBullet", "pybullet")


class PybulletEngine(Engine):
    """PyBullet in DIRECT mode, one physics client per run."""

    name = "pybullet"
    description = "PyBullet: multibody base/spherical link or a maximal-coordinates rigid body"
    integrators = (
        Integrator(
            "multibody",
            "semi-implicit Euler",
            1,
            "btMultiBody (Featherstone articulated body): velocities then positions, "
            "gyroscopic term explicit; the same algorithm as MuJoCo Euler (docs/engines.md).",
        ),
        Integrator(
            "maximal coordinates",
            "implicit gyroscopic",
            1,
            "btRigidBody (useMaximalCoordinates=True) with Bullet's default implicit "
            "body-frame gyroscopic term; like MuJoCo implicitfast on a free body "
            "(docs/engines.md). Free bodies only.",
        ),
    )

    @classmethod
    def version(cls) -> str:
        _import()
        return importlib.metadata.version("pybullet")

    def check_supported(self, scenario, integrator: str) -> None:
        if integrator == "maximal coordinates" and scenario.pivoted:
            raise Unsupported(
                "PyBullet maximal coordinates cannot hold a pivoted body: createMultiBody with "
                "useMaximalCoordinates=True does not create the spherical-joint link "
                "(getNumJoints returns 0); a point-to-point constraint would be a different "
                "(iterative, ERP-stabilised) algorithm"
            )
        speed = max(np.linalg.norm(scenario.omega_body), np.linalg.norm(scenario.velocity))
        if speed > 1e-3 * MAX_JOINT_VELOCITY:
            raise Unsupported(
                f"initial speed {speed:g} is too close to the raised PyBullet velocity clamp "
                f"{MAX_JOINT_VELOCITY:g}"
            )

    # -- model -------------------------------------------------------------------------
    def _build(self, p, cid, scenario, integrator, dt):
        maximal = integrator == "maximal coordinates"
        m = float(scenario.mass)
        I = [float(a) for a in scenario.inertia]
        p.setGravity(*[float(a) for a in scenario.gravity], physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=float(dt), numSubSteps=0, physicsClientId=cid)
        # Body-wide options and the inertia go in SEPARATE changeDynamics calls: on a link,
        # passing linearDamping, maxJointVelocity or activationState together with
        # localInertiaDiagonal left the inertia at 0 (pybullet 3.2.7, caught by the read-back).
        body_wide = dict(
            linearDamping=0.0,
            angularDamping=0.0,
            maxJointVelocity=MAX_JOINT_VELOCITY,
            activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
            physicsClientId=cid,
        )
        if scenario.pivoted:
            c = np.asarray(scenario.pivot, dtype=float)
            body = p.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=-1,
                baseVisualShapeIndex=-1,
                basePosition=[0.0, 0.0, 0.0],
                baseOrientation=[0.0, 0.0, 0.0, 1.0],
                linkMasses=[m],
                linkCollisionShapeIndices=[-1],
                linkVisualShapeIndices=[-1],
                linkPositions=[[0.0, 0.0, 0.0]],
                linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
                linkInertialFramePositions=[(-c).tolist()],
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]],
                linkParentIndices=[0],
                linkJointTypes=[p.JOINT_SPHERICAL],
                linkJointAxis=[[0.0, 0.0, 1.0]],
                useMaximalCoordinates=False,
                physicsClientId=cid,
            )
            p.changeDynamics(body, -1, **body_wide)
            p.changeDynamics(body, 0, **body_wide)
            p.changeDynamics(body, 0, jointDamping=0.0, physicsClientId=cid)
            p.changeDynamics(body, 0, localInertiaDiagonal=I, physicsClientId=cid)
            # The default spherical-joint motor drives the joint to identity; only a zero
            # force limit switches it off (zero gains alone do not; docs/engines.md).
            p.setJointMotorControlMultiDof(
                body,
                0,
                p.POSITION_CONTROL,
                targetPosition=[0.0, 0.0, 0.0, 1.0],
                targetVelocity=[0.0, 0.0, 0.0],
                force=[0.0, 0.0, 0.0],
                physicsClientId=cid,
            )
            link = 0
        else:
            body = p.createMultiBody(
                baseMass=m,
                baseCollisionShapeIndex=-1,
                baseVisualShapeIndex=-1,
                basePosition=[0.0, 0.0, 0.0],
                baseOrientation=[0.0, 0.0, 0.0, 1.0],
                baseInertialFramePosition=[0.0, 0.0, 0.0],
                baseInertialFrameOrientation=[0.0, 0.0, 0.0, 1.0],
                useMaximalCoordinates=maximal,
                physicsClientId=cid,
            )
            p.changeDynamics(body, -1, **body_wide)
            extra = {"mass": m} if maximal else {}
            p.changeDynamics(body, -1, localInertiaDiagonal=I, physicsClientId=cid, **extra)
            link = -1
        self._check_model(p, cid, body, link, scenario, maximal, dt)
        settings = {
            "integrator": integrator,
            "useMaximalCoordinates": maximal,
            "timestep": float(dt),
            "fixedTimeStep": float(dt),
            "numSubSteps": 0,
            "gravity": np.asarray(scenario.gravity).tolist(),
            "linearDamping": 0.0,
            "angularDamping": 0.0,
            "maxJointVelocity": MAX_JOINT_VELOCITY,
            "activationState": "ACTIVATION_STATE_DISABLE_SLEEPING",
            "localInertiaDiagonal": I,
            "collision shapes": "none",
        }
        if scenario.pivoted:
            settings["jointDamping"] = 0.0
            settings["spherical joint motor"] = "disabled (POSITION_CONTROL, force [0, 0, 0])"
            settings["link inertial frame position"] = (-np.asarray(scenario.pivot)).tolist()
        if maximal:
            settings["mass"] = "passed again with localInertiaDiagonal (else pybullet sets 0)"
        return body, link, settings

    @staticmethod
    def _check_model(p, cid, body, link, scenario, maximal, dt):
        # Damping, the velocity clamp, sleeping and the joint motor cannot be read back through
        # pybullet's API: tests/test_engines.py checks them by their effect on the motion.
        chk = cv.check_quantity
        e = "PyBullet"
        info = p.getDynamicsInfo(body, link, physicsClientId=cid)
        chk(e, "mass", info[0], scenario.mass, READBACK_RTOL)
        chk(e, "inertia diagonal", info[2], scenario.inertia, READBACK_RTOL)
        com = -np.asarray(scenario.pivot) if scenario.pivoted else np.zeros(3)
        chk(
            e,
            "COM position in the link frame (inertial frame position)",
            info[3],
            com,
            READBACK_RTOL,
        )
        if not maximal:
            # For btRigidBody pybullet 3.2.7 returns uninitialised numbers here (read as
            # (0, 1, 6.9e-310, 1)); the rigid body is created with the identity inertial frame.
            chk(e, "inertial frame orientation", info[4], [0, 0, 0, 1], 0, 0)
        params = p.getPhysicsEngineParameters(physicsClientId=cid)
        chk(e, "time step", params["fixedTimeStep"], dt, READBACK_RTOL)
        chk(e, "number of substeps", params["numSubSteps"], 0, 0, 0)
        chk(
            e,
            "gravity",
            [params[f"gravityAcceleration{a}"] for a in "XYZ"],
            scenario.gravity,
            READBACK_RTOL,
        )
        if scenario.pivoted:
            j = p.getJointInfo(body, 0, physicsClientId=cid)
            chk(e, "joint type (JOINT_SPHERICAL)", j[2], p.JOINT_SPHERICAL, 0, 0)
            chk(e, "joint damping", j[6], 0.0, 0, 0)
            chk(e, "joint friction", j[7], 0.0, 0, 0)
            chk(e, "joint frame position in the parent", j[14], np.zeros(3), 0, 0)
            chk(e, "joint frame orientation in the parent", j[15], [0, 0, 0, 1], 0, 0)
            base = p.getDynamicsInfo(body, -1, physicsClientId=cid)
            chk(e, "fixed base mass", base[0], 0.0, 0, 0)
        elif p.getNumJoints(body, physicsClientId=cid) != 0:
            raise EngineError("PyBullet: the free body has joints")

    # -- state -------------------------------------------------------------------------
    @staticmethod
    def _set_state(p, cid, body, scenario):
        if scenario.pivoted:
            q, W = cv.pybullet_spherical_from_state(scenario.rotation, scenario.omega_body)
            p.resetJointStateMultiDof(body, 0, targetValue=q, targetVelocity=W, physicsClientId=cid)
        else:
            x, q, v, w = cv.pybullet_base_from_state(
                scenario.position, scenario.velocity, scenario.rotation, scenario.omega_body
            )
            p.resetBasePositionAndOrientation(body, x, q, physicsClientId=cid)
            p.resetBaseVelocity(body, v, w, physicsClientId=cid)

    @staticmethod
    def read_state(p, cid, body, scenario) -> cv.BodyState:
        if scenario.pivoted:
            js = p.getJointStateMultiDof(body, 0, physicsClientId=cid)
            R, W = cv.pybullet_spherical_to_state(js[0], js[1])
            return cv.BodyState(*cv.pivot_com(R, W, scenario.pivot), R, W)
        x, q = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        v, w = p.getBaseVelocity(body, physicsClientId=cid)
        return cv.pybullet_base_to_state(x, q, v, w)

    @staticmethod
    def link_quantities(p, cid, body, scenario) -> dict:
        """Energy and momentum (about the pivot) from PyBullet's own forward kinematics of the
        link (getLinkState: COM position, COM frame orientation, world COM velocity and world
        angular velocity), independent of how the joint state is converted. PyBullet has no
        energy or momentum API (docs/engines.md)."""
        ls = p.getLinkState(
            body, 0, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid
        )
        x, v, w = (np.asarray(ls[k], dtype=float) for k in (0, 6, 7))
        R = cv.quat_xyzw_to_matrix(ls[1])
        W = R.T @ w
        I = np.asarray(scenario.inertia)
        m = scenario.mass
        energy = 0.5 * m * v @ v + 0.5 * W @ (I * W) - m * x @ np.asarray(scenario.gravity)
        return {
            "energy": energy,
            "angular momentum": R @ (I * W) + m * np.cross(x, v),
            "COM velocity": v,
        }

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        p = _import()
        cid = p.connect(p.DIRECT)
        try:
            return self._run_connected(p, cid, scenario, integrator, dt, nstep, saves, progress)
        finally:
            p.disconnect(physicsClientId=cid)

    def _run_connected(self, p, cid, scenario, integrator, dt, nstep, saves, progress):
        body, link, settings = self._build(p, cid, scenario, integrator, dt)
        self._set_state(p, cid, body, scenario)
        state0 = self.read_state(p, cid, body, scenario)
        native = self.link_quantities(p, cid, body, scenario) if scenario.pivoted else None
        cv.check_initial_state("PyBullet", scenario, state0, native=native)

        states = []
        watch = Stopwatch()
        done = 0
        report = max(1, nstep // 100)
        step = p.stepSimulation
        for i, target in enumerate(saves):
            with watch:
                while done < target:
                    step(physicsClientId=cid)
                    done += 1
                    if progress is not None and done % report == 0:
                        progress(done / nstep)
            state = self.read_state(p, cid, body, scenario)
            if not all(np.all(np.isfinite(a)) for a in state):
                t_prev = saves[i - 1] * dt if i else 0.0
                raise StepFailure(
                    f"PyBullet {integrator}: the state became non-finite between "
                    f"t = {t_prev:.6g} and t = {done * dt:.6g} s (dt = {dt:g}); reduce dt"
                )
            speed = max(np.linalg.norm(state.omega_body), np.linalg.norm(state.velocity))
            if speed > 0.1 * MAX_JOINT_VELOCITY:
                raise StepFailure(
                    f"PyBullet {integrator}: speed {speed:g} at t = {done * dt:.6g} s is near "
                    f"the velocity clamp {MAX_JOINT_VELOCITY:g}; results would be clamped"
                )
            states.append(state)
        if progress is not None:
            progress(1.0)
        traj = Trajectory.from_states(scenario, np.asarray(saves) * dt, *cv.stack_states(states))
        return RunOutput(traj, nstep, watch.elapsed, settings)
