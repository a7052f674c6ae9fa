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

import contextlib
import importlib.metadata
import math
import time

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback
from references.engines.integrators import Integrator
from references.engines.interface import Engine, SceneBuilder
from references.engines.native import import_engine
from references.errors import Unsupported

#: the raised velocity clamp (rad/s and m/s); runs whose speeds come near it are refused
MAX_JOINT_VELOCITY = 1e6


def _import():
    import sys

    if sys.modules.get("pybullet") is not None:
        return sys.modules["pybullet"]
    # pybullet's C module prints its build time on the standard error when imported, once per
    # process: in a parallel run that is one stray line per worker in the suite's output
    with _banner_silenced():
        return import_engine("pybullet", "PyBullet", "pybullet")


@contextlib.contextmanager
def _banner_silenced():
    """The process's standard error (file descriptor 2, where native code writes) goes to
    /dev/null while pybullet is imported. Nothing of the suite's is lost: a failed import is
    an ImportError whose message import_engine puts in the EngineUnavailable."""
    import os
    import sys

    try:
        fd = sys.stderr.fileno()
    except (AttributeError, ValueError, OSError):  # stderr replaced (pytest's capture)
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, fd)
        yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
        os.close(devnull)


def _plant_damping(ctx) -> None:
    """PyBullet's default damping (0.04 linear and angular) back on the body."""
    h = ctx.handle
    for link in (-1, 0) if ctx.model.pivoted else (-1,):
        h.p.changeDynamics(
            h.body, link, linearDamping=0.04, angularDamping=0.04, physicsClientId=h.cid
        )


def _plant_motor(ctx) -> None:
    """The spherical joint's default motor back on (PyBullet's default force limit)."""
    h = ctx.handle
    h.p.setJointMotorControlMultiDof(
        h.body,
        0,
        h.p.POSITION_CONTROL,
        targetPosition=[0.0, 0.0, 0.0, 1.0],
        targetVelocity=[0.0, 0.0, 0.0],
        force=[1000.0, 1000.0, 1000.0],
        physicsClientId=h.cid,
    )


def _plant_clamp(ctx) -> None:
    """PyBullet's default 100 rad/s velocity clamp back on."""
    h = ctx.handle
    for link in (-1, 0) if ctx.model.pivoted else (-1,):
        h.p.changeDynamics(h.body, link, maxJointVelocity=100.0, physicsClientId=h.cid)


class PybulletEngine(Engine):
    """PyBullet in DIRECT mode, one physics client per run."""

    name = "pybullet"
    description = "PyBullet: multibody base/spherical link or a maximal-coordinates rigid body"
    scene_builder = SceneBuilder(
        "references.engines.pybullet.system:simulate_system",
        ("erp", "max_force"),
        force_elements=True,
    )
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

    #: defaults that distort the experiment, planted back by the conformance kit
    plantable = {
        "PyBullet's default damping back on": (_plant_damping, ("free", "pivoted")),
        "the spherical joint's default motor back on": (_plant_motor, ("pivoted",)),
        "PyBullet's 100 rad/s velocity clamp back on": (_plant_clamp, ("free", "pivoted")),
    }

    packages = ("pybullet",)
    saves_raw = True

    @classmethod
    def version(cls) -> str:
        _import()
        return importlib.metadata.version("pybullet")

    def check_supported(self, scenario, integrator) -> None:
        if integrator.name == "maximal coordinates" and scenario.pivot is not None:
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
    def build(self, ctx) -> None:
        p = _import()
        cid = p.connect(p.DIRECT)
        ctx.handle = _Handle(p, cid)
        h = ctx.handle
        mdl = ctx.model
        maximal = ctx.integrator.name == "maximal coordinates"
        p.setGravity(*mdl.gravity.tolist(), physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=ctx.dt, numSubSteps=0, physicsClientId=cid)
        if mdl.pivoted:
            h.body = self._pivoted_body(p, cid, mdl)
            h.link = 0
        else:
            h.body = self._free_body(p, cid, mdl, maximal)
            h.link = -1

    def _body_wide(self, p, cid) -> dict:
        return dict(
            linearDamping=0.0,
            angularDamping=0.0,
            maxJointVelocity=MAX_JOINT_VELOCITY,
            activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
            physicsClientId=cid,
        )

    def _free_body(self, p, cid, mdl, maximal: bool) -> int:
        body = p.createMultiBody(
            baseMass=mdl.mass,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=[0.0, 0.0, 0.0],
            baseOrientation=[0.0, 0.0, 0.0, 1.0],
            baseInertialFramePosition=mdl.com.tolist(),
            baseInertialFrameOrientation=[0.0, 0.0, 0.0, 1.0],
            useMaximalCoordinates=maximal,
            physicsClientId=cid,
        )
        # Body-wide options and the inertia go in SEPARATE changeDynamics calls (see the
        # module docstring); with maximal coordinates the mass is passed again.
        p.changeDynamics(body, -1, **self._body_wide(p, cid))
        extra = {"mass": mdl.mass} if maximal else {}
        p.changeDynamics(
            body, -1, localInertiaDiagonal=mdl.inertia.tolist(), physicsClientId=cid, **extra
        )
        return body

    def _pivoted_body(self, p, cid, mdl) -> int:
        body = p.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=[0.0, 0.0, 0.0],
            baseOrientation=[0.0, 0.0, 0.0, 1.0],
            linkMasses=[mdl.mass],
            linkCollisionShapeIndices=[-1],
            linkVisualShapeIndices=[-1],
            linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
            linkInertialFramePositions=[mdl.com.tolist()],
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]],
            linkParentIndices=[0],
            linkJointTypes=[p.JOINT_SPHERICAL],
            linkJointAxis=[[0.0, 0.0, 1.0]],
            useMaximalCoordinates=False,
            physicsClientId=cid,
        )
        for link in (-1, 0):
            p.changeDynamics(body, link, **self._body_wide(p, cid))
        p.changeDynamics(body, 0, jointDamping=0.0, physicsClientId=cid)
        p.changeDynamics(body, 0, localInertiaDiagonal=mdl.inertia.tolist(), physicsClientId=cid)
        # The default spherical-joint motor drives the joint to identity; only a zero force
        # limit switches it off (zero gains alone do not; docs/engines.md).
        p.setJointMotorControlMultiDof(
            body,
            0,
            p.POSITION_CONTROL,
            targetPosition=[0.0, 0.0, 0.0, 1.0],
            targetVelocity=[0.0, 0.0, 0.0],
            force=[0.0, 0.0, 0.0],
            physicsClientId=cid,
        )
        return body

    def read_model(self, ctx) -> ModelReadback:
        h = ctx.handle
        p, cid, body, link = h.p, h.cid, h.body, h.link
        info = p.getDynamicsInfo(body, link, physicsClientId=cid)
        params = p.getPhysicsEngineParameters(physicsClientId=cid)
        extra = {"number of substeps": (params["numSubSteps"], 0)}
        maximal = ctx.integrator.name == "maximal coordinates"
        if not maximal:
            # For btRigidBody pybullet 3.2.7 returns uninitialised numbers here (read as
            # (0, 1, 6.9e-310, 1)); the rigid body is created with the identity inertial frame.
            extra["inertial frame orientation"] = (info[4], [0, 0, 0, 1])
        if ctx.model.pivoted:
            j = p.getJointInfo(body, 0, physicsClientId=cid)
            extra.update(
                {
                    "joint damping": (j[6], 0.0),
                    "joint friction": (j[7], 0.0),
                    "joint frame position in the parent": (j[14], np.zeros(3)),
                    "joint frame orientation in the parent": (j[15], [0, 0, 0, 1]),
                    "fixed base mass": (p.getDynamicsInfo(body, -1, physicsClientId=cid)[0], 0),
                }
            )
            joint = "ball" if j[2] == p.JOINT_SPHERICAL else f"joint type {j[2]}"
        else:
            njoint = p.getNumJoints(body, physicsClientId=cid)
            joint = "free" if njoint == 0 else f"base with {njoint} joints"
        extra.update(_probe(p, cid, body, link, ctx))
        return ModelReadback(
            mass=info[0],
            inertia=np.diag(info[2]),
            com=info[3],
            joint=joint,
            gravity=[params[f"gravityAcceleration{a}"] for a in "XYZ"],
            dt=params["fixedTimeStep"],
            extra=extra,
        )

    def settings(self, ctx) -> dict:
        out = {
            "useMaximalCoordinates": ctx.integrator.name == "maximal coordinates",
            "fixedTimeStep": ctx.dt,
            "numSubSteps": 0,
            "gravity": ctx.model.gravity.tolist(),
            "linearDamping": 0.0,
            "angularDamping": 0.0,
            "maxJointVelocity": MAX_JOINT_VELOCITY,
            "activationState": "ACTIVATION_STATE_DISABLE_SLEEPING",
            "localInertiaDiagonal": ctx.model.inertia.tolist(),
            "collision shapes": "none",
            "checked by a probe step": "no damping, no velocity clamp"
            + (", no joint motor" if ctx.model.pivoted else ""),
        }
        if ctx.model.pivoted:
            out["jointDamping"] = 0.0
            out["spherical joint motor"] = "disabled (POSITION_CONTROL, force [0, 0, 0])"
            out["link inertial frame position"] = ctx.model.com.tolist()
        if ctx.integrator.name == "maximal coordinates":
            out["mass"] = "passed again with localInertiaDiagonal (else pybullet sets 0)"
        return out

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        h = ctx.handle
        p, cid, body = h.p, h.cid, h.body
        if ctx.model.pivoted:
            q, W = cv.pybullet_spherical_from_state(state.rotation, state.omega_body)
            p.resetJointStateMultiDof(body, 0, targetValue=q, targetVelocity=W, physicsClientId=cid)
        else:
            x, q, v, w = cv.pybullet_base_from_state(*state)
            p.resetBasePositionAndOrientation(body, x, q, physicsClientId=cid)
            p.resetBaseVelocity(body, v, w, physicsClientId=cid)

    def read_state(self, ctx) -> cv.BodyState:
        h = ctx.handle
        p, cid, body = h.p, h.cid, h.body
        if ctx.model.pivoted:
            js = p.getJointStateMultiDof(body, 0, physicsClientId=cid)
            return ctx.model.state_from_rotation(*cv.pybullet_spherical_to_state(js[0], js[1]))
        x, q = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        v, w = p.getBaseVelocity(body, physicsClientId=cid)
        return cv.pybullet_base_to_state(x, q, v, w)

    def read_raw(self, ctx) -> np.ndarray:
        h = ctx.handle
        p, cid, body = h.p, h.cid, h.body
        if ctx.model.pivoted:
            q, W = p.getJointStateMultiDof(body, 0, physicsClientId=cid)[:2]
            return np.array([*q, *W])
        x, q = p.getBasePositionAndOrientation(body, physicsClientId=cid)
        v, w = p.getBaseVelocity(body, physicsClientId=cid)
        return np.array([*x, *q, *v, *w])

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        return cv.pybullet_block(raw, ctx.model.com, ctx.model.pivoted)

    def native_quantities(self, ctx) -> dict:
        """PyBullet has no energy or momentum API (docs/engines.md). These come from its own
        kinematics, never from the suite's conversions: the rotation from PyBullet's
        getMatrixFromQuaternion of the orientation it holds, its world angular and COM
        velocities (getBaseVelocity for the base; getLinkState with forward kinematics for
        the link) and the inertia it reports (getDynamicsInfo), with
        E = 1/2 m v.v + 1/2 w.(R I R^T w) - m g.x and L = R I R^T w (+ x x m v about the
        pivot)."""
        h = ctx.handle
        p, cid, body = h.p, h.cid, h.body
        if ctx.model.pivoted:
            ls = p.getLinkState(
                body, 0, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=cid
            )
            x, orn, v, w = ls[0], ls[1], ls[6], ls[7]
        else:
            x, orn = p.getBasePositionAndOrientation(body, physicsClientId=cid)
            v, w = p.getBaseVelocity(body, physicsClientId=cid)
        x, v, w = (np.asarray(a, dtype=float) for a in (x, v, w))
        R = np.asarray(p.getMatrixFromQuaternion(orn), dtype=float).reshape(3, 3)
        info = p.getDynamicsInfo(body, h.link, physicsClientId=cid)
        I_world = R @ np.diag(info[2]) @ R.T
        m = info[0]
        L = I_world @ w + (m * np.cross(x, v) if ctx.model.pivoted else 0.0)
        g = np.asarray(ctx.model.gravity)
        return {
            "energy": 0.5 * m * v @ v + 0.5 * w @ I_world @ w - m * x @ g,
            "angular momentum": L,
            "rotation": R,
            "COM velocity": v,
            "COM position": x,
        }

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        h = ctx.handle
        step, cid = h.p.stepSimulation, h.cid
        with ctx.clock:
            for _ in range(k):
                step(physicsClientId=cid)

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """:meth:`Engine.advance_saving` with stepSimulation, the state getters and the
        stopwatch bound once; each saved state (:meth:`read_raw`'s row) kept as PyBullet's
        floats and made one array per block (a run saving every step reads a state per
        stepSimulation)."""
        h = ctx.handle
        p, cid, body = h.p, h.cid, h.body
        step, clock, now = p.stepSimulation, ctx.clock, time.perf_counter
        joint, pose = p.getJointStateMultiDof, p.getBasePositionAndOrientation
        velocity = p.getBaseVelocity
        pivoted = ctx.model.pivoted
        rows = []
        for k in steps:
            t0 = now()
            for _ in range(k):
                step(physicsClientId=cid)
            clock.lap(t0)
            if pivoted:
                q, W = joint(body, 0, physicsClientId=cid)[:2]
                rows.append((*q, *W))
            else:
                x, q = pose(body, physicsClientId=cid)
                v, w = velocity(body, physicsClientId=cid)
                rows.append((*x, *q, *v, *w))
        return self.states_from_raw(ctx, np.array(rows, dtype=float))

    def guard(self, ctx, state) -> str | None:
        speed = max(np.linalg.norm(state.omega_body), np.linalg.norm(state.velocity))
        if speed > 0.1 * MAX_JOINT_VELOCITY:
            return (
                f"a speed of {speed:g} came near PyBullet's velocity clamp "
                f"{MAX_JOINT_VELOCITY:g} (results beyond it would be clamped)"
            )
        return None

    def close(self, ctx) -> None:
        if ctx.handle is not None:
            ctx.handle.p.disconnect(physicsClientId=ctx.handle.cid)


class _Handle:
    def __init__(self, p, cid):
        self.p, self.cid = p, cid
        self.body = self.link = None


#: Probe spin, rad/s: above PyBullet's default velocity clamp (100 rad/s), so a clamp that was
#: not raised shows, and large enough that the default damping law w' = -0.04 (1 + |w|) w
#: changes it by 0.04 (1 + 150) dt ~ 6e-3 relative per millisecond step.
PROBE_RATE = 150.0

#: Relative change of a steady principal spin over one probe step that counts as a distortion.
#: A torque-free spin about a principal axis has no gyroscopic torque; the step leaves it
#: unchanged up to round-off (measured: below 1e-15 with pybullet 3.2.7), so 1e-9 is far above
#: round-off and far below the smallest distortion (damping: ~1e-4 at dt = 1e-4).
PROBE_RTOL = 1e-9


def _probe(p, cid, body, link, ctx) -> dict:
    """Check by one step of a steady spin that nothing damps, clamps or drives the body:
    with gravity off, a spin of PROBE_RATE about a principal axis of the inertia about the
    joint (the COM for a free body, the pivot for a pivoted one) must stay unchanged. It
    catches PyBullet's default damping (base, link or joint), the default 100 rad/s velocity
    clamp and the spherical joint's default motor, none of which PyBullet lets us read back.
    Gravity is restored; the state is overwritten by the run's initial state afterwards."""
    mdl = ctx.model
    c = mdl.com
    Ip = np.diag(mdl.inertia) + mdl.mass * (c @ c * np.eye(3) - np.outer(c, c))
    axis = np.linalg.eigh(Ip)[1][:, 0]
    W = PROBE_RATE * axis
    p.setGravity(0.0, 0.0, 0.0, physicsClientId=cid)
    try:
        if mdl.pivoted:
            p.resetJointStateMultiDof(
                body, 0, targetValue=[0, 0, 0, 1], targetVelocity=W.tolist(), physicsClientId=cid
            )
            p.stepSimulation(physicsClientId=cid)
            W1 = np.asarray(p.getJointStateMultiDof(body, 0, physicsClientId=cid)[1])
            v1 = np.zeros(3)
        else:
            p.resetBasePositionAndOrientation(body, [0, 0, 0], [0, 0, 0, 1], physicsClientId=cid)
            p.resetBaseVelocity(body, [1.0, 0.0, 0.0], W.tolist(), physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
            v1, W1 = (np.asarray(a) for a in p.getBaseVelocity(body, physicsClientId=cid))
            v1 = v1 - np.array([1.0, 0.0, 0.0])
    finally:
        p.setGravity(*mdl.gravity.tolist(), physicsClientId=cid)
    spin = float(np.linalg.norm(W1 - W) / PROBE_RATE) if np.all(np.isfinite(W1)) else math.inf
    lin = float(np.linalg.norm(v1)) if np.all(np.isfinite(v1)) else math.inf
    return {
        "relative change of a steady spin over one probe step (damping, velocity clamp or "
        "joint motor left on)": (spin, 0.0, PROBE_RTOL),
        "change of a uniform translation over one probe step, m/s (linear damping left on)": (
            lin,
            0.0,
            PROBE_RTOL,
        ),
    }
