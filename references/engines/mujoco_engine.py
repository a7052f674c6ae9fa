"""MuJoCo adapter: a free joint (free body) or a ball joint at the world origin (pivoted body).

Model: one body with an explicit ``<inertial>`` at the body origin with identity orientation
and ``diaginertia`` = the scenario's principal moments, so the body frame IS the principal COM
frame and the free-joint alignment option (``freejoint align`` / ``compiler alignfree``) has
nothing to change: qpos/qvel refer to x_G and R directly (docs/engines.md, "Free-joint
alignment"). For a pivoted body the body frame sits at the world origin with the ball joint at
its origin, and the inertial frame at ``-pivot``.

Integrators are MuJoCo's own (``mjtIntegrator``; MuJoCo documentation, "Computation /
Numerical integration"). The state is read from qpos/qvel only; derived quantities (xmat,
xipos) are used solely in the read-back after an explicit ``mj_forward``, because after
``mj_step`` they describe the start of that step.
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
    Unsupported,
    import_engine,
)
from references.trajectory import Trajectory

#: largest number of steps between two finiteness checks (bounds how late a divergence is seen)
_CHUNK = 1000

_INTEGRATOR_ENUM = {
    "Euler": "mjINT_EULER",
    "implicit": "mjINT_IMPLICIT",
    "implicitfast": "mjINT_IMPLICITFAST",
    "discrete": "mjINT_DISCRETE",
    "RK4": "mjINT_RK4",
}


def _import():
    return import_engine("mujoco", "MuJoCo", "mujoco")


def _num(a) -> str:
    """Numbers for the XML, written so that MuJoCo parses back the same doubles."""
    return " ".join(repr(float(x)) for x in np.ravel(a))


class MujocoEngine(Engine):
    """MuJoCo (mujoco Python bindings), stepped with ``mj_step``."""

    name = "mujoco"
    description = "MuJoCo: free joint or ball joint, MuJoCo's own integrators via mj_step"
    integrators = (
        Integrator(
            "Euler",
            "semi-implicit Euler",
            1,
            "MuJoCo's default: v += h a(q, v) with the gyroscopic term explicit, then "
            "q integrated with the new v (quaternion exponential map).",
        ),
        Integrator(
            "implicit",
            "implicit gyroscopic",
            1,
            "Implicit in velocity: the full derivative of the velocity-dependent forces "
            "(gyroscopic term included, asymmetric Jacobian) is linearised into the step.",
        ),
        Integrator(
            "implicitfast",
            "implicit gyroscopic",
            1,
            "Like implicit but with a symmetrised derivative. For a standalone free body "
            "the gyroscopic derivative is included (same as implicit); for a BALL joint it is "
            "dropped, so on a pivoted body this is the same algorithm as Euler "
            "(docs/engines.md).",
        ),
        Integrator(
            "discrete",
            "implicit gyroscopic",
            1,
            "MuJoCo's discrete-time integrator (constraint solve and implicit velocity "
            "update in one metric). Measured like implicitfast: gyroscopic derivative kept "
            "for a free body, dropped for a ball joint (docs/engines.md). Only in MuJoCo "
            "versions whose mjtIntegrator has mjINT_DISCRETE.",
        ),
        Integrator(
            "RK4",
            "4th-order Lie-group",
            4,
            "MuJoCo's explicit 4-stage Runge-Kutta; the stages integrate quaternions on the "
            "group, so it is 4th order including orientations (docs/engines.md).",
        ),
    )

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    def check_supported(self, scenario, integrator: str) -> None:
        mujoco = _import()
        enum = _INTEGRATOR_ENUM[integrator]
        if not hasattr(mujoco.mjtIntegrator, enum):
            raise Unsupported(
                f"MuJoCo {mujoco.__version__} has no integrator {integrator!r} "
                f"(mjtIntegrator lacks {enum})"
            )
        I = np.asarray(scenario.inertia)
        for k in range(3):
            # MuJoCo's compiler rejects inertias violating A + B >= C, strictly: one ulp over
            # is refused (docs/engines.md; checked with mujoco 4.0.0).
            if I[k] > I[(k + 1) % 3] + I[(k + 2) % 3]:
                raise Unsupported(
                    f"MuJoCo rejects the inertia {I.tolist()}: it violates the triangle "
                    "inequality A + B >= C"
                )

    # -- model -------------------------------------------------------------------------
    @staticmethod
    def model_xml(scenario, integrator: str, dt: float) -> str:
        """The MJCF of the scenario (public so that tests can inspect what is built)."""
        if scenario.pivoted:
            joint = '<joint name="pivot" type="ball" pos="0 0 0"/>'
            ipos = -np.asarray(scenario.pivot)
        else:
            joint = '<freejoint name="free"/>'
            ipos = np.zeros(3)
        return f"""
<mujoco model="{scenario.name}">
  <option timestep="{float(dt)!r}" gravity="{_num(scenario.gravity)}" integrator="{integrator}">
    <flag contact="disable" autoreset="disable"/>
  </option>
  <worldbody>
    <body name="body" pos="0 0 0" quat="1 0 0 0">
      {joint}
      <inertial pos="{_num(ipos)}" quat="1 0 0 0" mass="{float(scenario.mass)!r}"
                diaginertia="{_num(scenario.inertia)}"/>
    </body>
  </worldbody>
</mujoco>"""

    def _build(self, scenario, integrator, dt):
        mujoco = _import()
        try:
            m = mujoco.MjModel.from_xml_string(self.model_xml(scenario, integrator, dt))
        except ValueError as exc:
            if "inertia must satisfy" in str(exc):
                raise Unsupported(f"MuJoCo rejects the scenario's inertia: {exc}") from exc
            raise EngineError(f"MuJoCo could not compile the scenario's model: {exc}") from exc
        self._check_model(mujoco, m, scenario, integrator, dt)
        settings = {
            "integrator": integrator,
            "timestep": float(dt),
            "gravity": np.asarray(scenario.gravity).tolist(),
            "contact": "disabled (flag contact=disable); the model has no geoms",
            "autoreset": "disabled (flag autoreset=disable): a diverged state is reported "
            "as a failure instead of being silently reset to qpos0",
            "joint": "ball at the world origin" if scenario.pivoted else "free",
            "inertial frame": "diaginertia at "
            + ("-pivot" if scenario.pivoted else "the body origin")
            + ", identity orientation (qpos/qvel are the principal COM frame)",
            "damping, armature, frictionloss": "0 (defaults, read back)",
            "sleep": "off (mjENBL_SLEEP not set, read back)",
        }
        return mujoco, m, settings

    @staticmethod
    def _check_model(mujoco, m, scenario, integrator, dt):
        """Read the compiled model back and compare it with the scenario."""
        chk = cv.check_quantity
        e = "MuJoCo"
        chk(e, "mass", m.body_mass[1], scenario.mass, READBACK_RTOL)
        chk(e, "inertia diagonal", m.body_inertia[1], scenario.inertia, READBACK_RTOL)
        ipos = -np.asarray(scenario.pivot) if scenario.pivoted else np.zeros(3)
        chk(e, "COM position in the body frame (body_ipos)", m.body_ipos[1], ipos, READBACK_RTOL)
        chk(e, "inertial frame orientation (body_iquat)", m.body_iquat[1], [1, 0, 0, 0], 0, 0)
        chk(e, "body frame position (body_pos)", m.body_pos[1], np.zeros(3), 0, 0)
        chk(e, "body frame orientation (body_quat)", m.body_quat[1], [1, 0, 0, 0], 0, 0)
        chk(e, "gravity", m.opt.gravity, scenario.gravity, READBACK_RTOL)
        chk(e, "time step", m.opt.timestep, dt, READBACK_RTOL)
        enum = getattr(mujoco.mjtIntegrator, _INTEGRATOR_ENUM[integrator])
        chk(e, "integrator", m.opt.integrator, int(enum), 0, 0)
        want_type = mujoco.mjtJoint.mjJNT_BALL if scenario.pivoted else mujoco.mjtJoint.mjJNT_FREE
        chk(e, "joint type", m.jnt_type, [int(want_type)], 0, 0)
        chk(e, "joint position", m.jnt_pos[0], np.zeros(3), 0, 0)
        for name in ("dof_damping", "dof_armature", "dof_frictionloss"):
            chk(e, name, getattr(m, name), np.zeros(m.nv), 0, 0)
        chk(e, "number of geoms", m.ngeom, 0, 0, 0)
        chk(e, "gravity compensation", m.body_gravcomp[1], 0.0, 0, 0)
        chk(e, "medium density, viscosity", [m.opt.density, m.opt.viscosity], [0, 0], 0, 0)
        chk(e, "wind", m.opt.wind, np.zeros(3), 0, 0)
        if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT:
            raise EngineError("MuJoCo: contacts are not disabled in the compiled model")
        if not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_AUTORESET:
            raise EngineError("MuJoCo: autoreset is not disabled in the compiled model")
        if m.opt.enableflags & mujoco.mjtEnableBit.mjENBL_SLEEP:
            raise EngineError("MuJoCo: sleeping is enabled in the compiled model")

    # -- state -------------------------------------------------------------------------
    @staticmethod
    def _set_state(d, scenario):
        if scenario.pivoted:
            qpos, qvel = cv.mujoco_ball_from_state(scenario.rotation, scenario.omega_body)
        else:
            qpos, qvel = cv.mujoco_free_from_state(
                scenario.position, scenario.velocity, scenario.rotation, scenario.omega_body
            )
        d.qpos[:] = qpos
        d.qvel[:] = qvel

    @staticmethod
    def _state_from(qpos, qvel, scenario) -> cv.BodyState:
        if scenario.pivoted:
            R, W = cv.mujoco_ball_to_state(qpos, qvel)
            return cv.BodyState(*cv.pivot_com(R, W, scenario.pivot), R, W)
        return cv.mujoco_free_to_state(qpos, qvel)

    @classmethod
    def read_state(cls, d, scenario) -> cv.BodyState:
        """The suite state from qpos/qvel only (never from derived, possibly stale, fields)."""
        return cls._state_from(d.qpos, d.qvel, scenario)

    @staticmethod
    def native_quantities(m, d) -> dict:
        """MuJoCo's own energy and angular momentum of the current state (after mj_forward):
        T = 1/2 qvel . M qvel (mj_mulM), V = -m g . xipos, L from mj_subtreeVel about the
        subtree COM, plus x_G x m v_G when pivoted (about the world origin); v_G from
        mj_subtreeVel."""
        mujoco = _import()
        Mv = np.zeros(m.nv)
        mujoco.mj_mulM(m, d, Mv, d.qvel)
        mass = m.body_mass[1]
        energy = 0.5 * d.qvel @ Mv - mass * d.xipos[1] @ m.opt.gravity
        mujoco.mj_subtreeVel(m, d)
        L = d.subtree_angmom[1].copy()
        if m.jnt_type[0] == mujoco.mjtJoint.mjJNT_BALL:
            L += mass * np.cross(d.subtree_com[1], d.subtree_linvel[1])
        return {"energy": energy, "angular momentum": L, "COM velocity": d.subtree_linvel[1].copy()}

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        mujoco, m, settings = self._build(scenario, integrator, dt)
        d = mujoco.MjData(m)
        self._set_state(d, scenario)
        mujoco.mj_forward(m, d)
        state0 = self.read_state(d, scenario)
        cv.check_initial_state("MuJoCo", scenario, state0, native=self.native_quantities(m, d))
        # Derived frames after mj_forward must agree with the state: this catches a COM or
        # inertial frame that differs from the body frame (the free-joint alignment trap).
        cv.check_quantity(
            "MuJoCo", "COM world position (xipos)", d.xipos[1], state0.position, 1e-14, 1e-15
        )
        cv.check_quantity(
            "MuJoCo",
            "inertial frame rotation (ximat)",
            d.ximat[1].reshape(3, 3),
            state0.rotation,
            0,
            1e-15,
        )

        n = len(saves)
        nq = m.nq
        out = np.empty((n, m.nq + m.nv))
        watch = Stopwatch()
        done = 0
        for i, target in enumerate(saves):
            while done < target:
                k = min(int(target) - done, _CHUNK)
                with watch:
                    mujoco.mj_step(m, d, k)
                done += k
                if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
                    raise StepFailure(
                        f"MuJoCo {integrator}: the state became non-finite between "
                        f"t = {(done - k) * dt:.6g} and t = {done * dt:.6g} s (dt = {dt:g}); "
                        "reduce dt"
                    )
                if progress is not None:
                    progress(done / nstep)
            out[i, :nq] = d.qpos
            out[i, nq:] = d.qvel
        bad = [
            w
            for w in ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS")
            if d.warning[int(getattr(mujoco.mjtWarning, w))].number
        ]
        if bad:
            raise StepFailure(
                f"MuJoCo {integrator}: MuJoCo flagged {', '.join(bad)} during the run "
                f"(dt = {dt:g}); the simulation is unstable, reduce dt"
            )
        states = [self._state_from(row[:nq], row[nq:], scenario) for row in out]
        traj = Trajectory.from_states(scenario, np.asarray(saves) * dt, *cv.stack_states(states))
        return RunOutput(traj, nstep, watch.elapsed, settings)
