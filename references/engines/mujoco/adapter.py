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

import time

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback
from references.engines.integrators import Integrator
from references.engines.interface import Engine, SceneBuilder
from references.engines.native import import_engine
from references.errors import EngineError, Unsupported

_INTEGRATOR_ENUM = {
    "Euler": "mjINT_EULER",
    "implicit": "mjINT_IMPLICIT",
    "implicitfast": "mjINT_IMPLICITFAST",
    "discrete": "mjINT_DISCRETE",
    "RK4": "mjINT_RK4",
}


def _import():
    mujoco = import_engine("mujoco", "MuJoCo", "mujoco")
    if mujoco.get_mju_user_warning() is None:
        # MuJoCo's default handler prints each warning on standard output; the run loop reads
        # the warning counters itself (guard), so the text goes to MuJoCo's log file only, in
        # the current directory, which during a suite run is the output folder's logs/
        mujoco.set_mju_user_warning(_log_warning)
    return mujoco


def _log_warning(message: str) -> None:
    with open("MUJOCO_LOG.TXT", "a") as fh:
        fh.write(f"WARNING: {message}\n")


def _num(a) -> str:
    """Numbers for the XML, written so that MuJoCo parses back the same doubles."""
    return " ".join(repr(float(x)) for x in np.ravel(a))


class MujocoEngine(Engine):
    """MuJoCo (mujoco Python bindings), stepped with ``mj_step``."""

    name = "mujoco"
    description = "MuJoCo: free joint or ball joint, MuJoCo's own integrators via mj_step"
    scene_builder = SceneBuilder(
        "references.engines.mujoco.system:simulate_system",
        ("solref", "solimp"),
        force_elements=True,
    )
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
            # on a ball joint MuJoCo drops the gyroscopic derivative, which leaves its Euler
            # step (measured: bit-identical trajectories on heavy_top)
            family_on_a_ball="semi-implicit Euler",
        ),
        Integrator(
            "discrete",
            "implicit gyroscopic",
            1,
            "MuJoCo's discrete-time integrator (constraint solve and implicit velocity "
            "update in one metric). Measured like implicitfast: gyroscopic derivative kept "
            "for a free body, dropped for a ball joint (docs/engines.md). Only in MuJoCo "
            "versions whose mjtIntegrator has mjINT_DISCRETE.",
            family_on_a_ball="semi-implicit Euler",  # as implicitfast's
        ),
        Integrator(
            "RK4",
            "4th-order Lie-group",
            4,
            "MuJoCo's explicit 4-stage Runge-Kutta; the stages integrate quaternions on the "
            "group, so it is 4th order including orientations (docs/engines.md).",
            evals_per_step=4.0,
        ),
    )

    #: defaults that distort the experiment, planted back by the conformance kit
    plantable = {
        "joint damping left on": (
            lambda ctx: ctx.handle[1].dof_damping.__setitem__(slice(None), 0.01),
            ("free", "pivoted"),
        ),
        "contacts left on": (
            lambda ctx: setattr(
                ctx.handle[1].opt,
                "disableflags",
                ctx.handle[1].opt.disableflags & ~int(_import().mjtDisableBit.mjDSBL_CONTACT),
            ),
            ("free", "pivoted"),
        ),
    }

    packages = ("mujoco",)
    saves_raw = True

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    def check_supported(self, scenario, integrator) -> None:
        mujoco = _import()
        enum = _INTEGRATOR_ENUM[integrator.name]
        if not hasattr(mujoco.mjtIntegrator, enum):
            raise Unsupported(
                f"MuJoCo {mujoco.__version__} has no integrator {integrator.name!r} "
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
    def model_xml(model, integrator: str) -> str:
        """The MJCF of a :class:`BodyModel` (public so that tests can inspect what is built):
        the body frame at the world origin; the inertial frame at ``model.com`` with identity
        orientation, so qpos/qvel of a free joint are x_G and the principal frame."""
        joint = (
            '<joint name="pivot" type="ball" pos="0 0 0"/>'
            if model.pivoted
            else '<freejoint name="free"/>'
        )
        return f"""
<mujoco model="{model.name}">
  <option timestep="{model.dt!r}" gravity="{_num(model.gravity)}" integrator="{integrator}">
    <flag contact="disable" autoreset="disable"/>
  </option>
  <worldbody>
    <body name="body" pos="0 0 0" quat="1 0 0 0">
      {joint}
      <inertial pos="{_num(model.com)}" quat="1 0 0 0" mass="{model.mass!r}"
                diaginertia="{_num(model.inertia)}"/>
    </body>
  </worldbody>
</mujoco>"""

    def build(self, ctx) -> None:
        mujoco = _import()
        try:
            m = mujoco.MjModel.from_xml_string(self.model_xml(ctx.model, ctx.integrator.name))
        except ValueError as exc:
            if "inertia must satisfy" in str(exc):
                raise Unsupported(f"MuJoCo rejects the scenario's inertia: {exc}") from exc
            raise EngineError(f"MuJoCo could not compile the scenario's model: {exc}") from exc
        ctx.handle = (mujoco, m, mujoco.MjData(m))

    def read_model(self, ctx) -> ModelReadback:
        mujoco, m, _ = ctx.handle
        enum = getattr(mujoco.mjtIntegrator, _INTEGRATOR_ENUM[ctx.integrator.name])
        joint = {int(mujoco.mjtJoint.mjJNT_BALL): "ball", int(mujoco.mjtJoint.mjJNT_FREE): "free"}
        flags = m.opt.disableflags
        extra = {
            "integrator": (m.opt.integrator, int(enum)),
            "inertial frame orientation (body_iquat)": (m.body_iquat[1], [1, 0, 0, 0]),
            "body frame position (body_pos)": (m.body_pos[1], np.zeros(3)),
            "body frame orientation (body_quat)": (m.body_quat[1], [1, 0, 0, 0]),
            "joint position": (m.jnt_pos[0], np.zeros(3)),
            "number of joints": (m.njnt, 1),
            "number of geoms": (m.ngeom, 0),
            "gravity compensation": (m.body_gravcomp[1], 0.0),
            "medium density, viscosity": ([m.opt.density, m.opt.viscosity], [0, 0]),
            "wind": (m.opt.wind, np.zeros(3)),
            "contacts disabled": (bool(flags & mujoco.mjtDisableBit.mjDSBL_CONTACT), True),
            "autoreset disabled": (bool(flags & mujoco.mjtDisableBit.mjDSBL_AUTORESET), True),
        }
        sleep = getattr(mujoco.mjtEnableBit, "mjENBL_SLEEP", None)  # absent in e.g. 3.3.0
        if sleep is not None:
            extra["sleeping enabled"] = (bool(m.opt.enableflags & sleep), False)
        for name in ("dof_damping", "dof_armature", "dof_frictionloss"):
            extra[name] = (getattr(m, name), np.zeros(m.nv))
        return ModelReadback(
            mass=m.body_mass[1],
            inertia=np.diag(m.body_inertia[1]),
            com=m.body_ipos[1],
            joint=joint.get(int(m.jnt_type[0]), f"type {int(m.jnt_type[0])}"),
            gravity=m.opt.gravity,
            dt=m.opt.timestep,
            extra=extra,
        )

    def settings(self, ctx) -> dict:
        return {
            "gravity": ctx.model.gravity.tolist(),
            "contact": "disabled (flag contact=disable); the model has no geoms",
            "autoreset": "disabled (flag autoreset=disable): a diverged state is reported "
            "as a failure instead of being silently reset to qpos0",
            "joint": "ball at the world origin" if ctx.model.pivoted else "free",
            "inertial frame": f"diaginertia at {ctx.model.com.tolist()} in the body frame, "
            "identity orientation (qpos/qvel are the principal COM frame)",
            "damping, armature, frictionloss": "0 (defaults, read back)",
            "sleep": "off (mjENBL_SLEEP not set, read back)"
            if hasattr(_import().mjtEnableBit, "mjENBL_SLEEP")
            else "none in this MuJoCo version",
        }

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        mujoco, m, d = ctx.handle
        if ctx.model.pivoted:
            qpos, qvel = cv.mujoco_ball_from_state(state.rotation, state.omega_body)
        else:
            qpos, qvel = cv.mujoco_free_from_state(*state)
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        mujoco.mj_forward(m, d)

    def read_state(self, ctx) -> cv.BodyState:
        """The suite state from qpos/qvel only (never from derived, possibly stale, fields)."""
        _, _, d = ctx.handle
        if ctx.model.pivoted:
            return ctx.model.state_from_rotation(*cv.mujoco_ball_to_state(d.qpos, d.qvel))
        return cv.mujoco_free_to_state(d.qpos, d.qvel)

    def read_raw(self, ctx) -> np.ndarray:
        _, m, d = ctx.handle
        return np.concatenate((d.qpos, d.qvel))

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        return cv.mujoco_block(raw, ctx.handle[1].nq, ctx.model.com, ctx.model.pivoted)

    def native_quantities(self, ctx) -> dict:
        """MuJoCo's own energy, momentum and frames of the current state, after mj_forward:
        T = 1/2 qvel . M qvel (mj_mulM), V = -m g . xipos, L from mj_subtreeVel about the
        subtree COM (plus x_G x m v_G when pivoted: about the world origin), v_G from
        mj_subtreeVel, R = ximat (the inertial frame, which must be the body's principal
        frame), and xipos, the COM MuJoCo places in the world."""
        mujoco, m, d = ctx.handle
        mujoco.mj_forward(m, d)
        Mv = np.zeros(m.nv)
        mujoco.mj_mulM(m, d, Mv, d.qvel)
        mass = m.body_mass[1]
        energy = 0.5 * d.qvel @ Mv - mass * d.xipos[1] @ m.opt.gravity
        mujoco.mj_subtreeVel(m, d)
        L = d.subtree_angmom[1].copy()
        if ctx.model.pivoted:
            L += mass * np.cross(d.subtree_com[1], d.subtree_linvel[1])
        return {
            "energy": energy,
            "angular momentum": L,
            "rotation": d.ximat[1].reshape(3, 3).copy(),
            "COM velocity": d.subtree_linvel[1].copy(),
            "COM position": d.xipos[1].copy(),
        }

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        mujoco, m, d = ctx.handle
        with ctx.clock:
            mujoco.mj_step(m, d, k)

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """:meth:`Engine.advance_saving` with mj_step and the stopwatch bound once and the
        states copied into one preallocated block (runs that save every step read a state
        per mj_step call: this loop is then the whole of the glue)."""
        mujoco, m, d = ctx.handle
        step, clock, now = mujoco.mj_step, ctx.clock, time.perf_counter
        qpos, qvel, nq = d.qpos, d.qvel, m.nq
        rows = np.empty((len(steps), nq + m.nv))
        for j, k in enumerate(steps):
            t0 = now()
            step(m, d, k)
            clock.lap(t0)
            rows[j, :nq] = qpos
            rows[j, nq:] = qvel
        return self.states_from_raw(ctx, rows)

    def guard(self, ctx, state) -> str | None:
        mujoco, _, d = ctx.handle
        bad = [
            w
            for w in ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS")
            if d.warning[int(getattr(mujoco.mjtWarning, w))].number
        ]
        if bad:
            return f"MuJoCo flagged {', '.join(bad)} (the simulation is unstable)"
        return None
