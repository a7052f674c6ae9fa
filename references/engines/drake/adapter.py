"""The Drake adapter: a MultibodyPlant with one rigid body on a QuaternionFloatingJoint (free
body) or a BallRpyJoint at the world origin (pivoted body), stepped by Drake's Simulator
(:mod:`.plant`), with the integrators of :mod:`.integrators` and, for a pivoted body, the
charts of :mod:`.charts`.

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

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback
from references.engines.drake.charts import CHART_SWITCH_COS, centred_chart, rpy_chart
from references.engines.drake.integrators import CONVEX_SCHEME, INTEGRATORS
from references.engines.drake.plant import (
    Handle,
    build_plant,
    default_integrator,
    import_drake,
    integrator_checks,
    make_integrator,
    model_checks,
    update_count,
)
from references.engines.interface import Engine, SceneBuilder
from references.errors import EngineError, StepFailure, Unsupported

#: an error-controlled run may make at most this many dynamics evaluations per fixed step of
#: the scenario (t_end / scenario.dt, at least MIN_FIXED_STEPS) before it is cut off (see the
#: module docstring); runge_kutta5 at a fixed step makes 7
EVAL_BUDGET = 10
#: the fixed-step count the budget is scaled from is at least this, so that a run of a few
#: steps (the conformance kit's) has room for the integrator's first step-size adjustments
MIN_FIXED_STEPS = 100


class DrakeEngine(Engine):
    """Drake (pydrake): continuous MultibodyPlant with Drake's integrators (fixed step or
    error-controlled), or the discrete MultibodyPlant (SAP)."""

    name = "drake"
    description = (
        "Drake: QuaternionFloatingJoint or BallRpyJoint; Drake's Simulator with each of its "
        "integrators at a fixed step or error-controlled, or the discrete SAP plant"
    )
    scene_builder = SceneBuilder(
        "references.engines.drake.system:simulate_system", force_elements=True
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
            lambda ctx: default_integrator(ctx),
            ("free", "pivoted"),
        ),
    }

    packages = ("drake",)
    saves_raw = True

    @classmethod
    def version(cls) -> str:
        import_drake()
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
        import_drake()
        from pydrake.systems.analysis import GetIntegrationSchemes

        if scheme not in GetIntegrationSchemes():
            raise Unsupported(
                f"Drake {self.version()} has no integration scheme {scheme!r} "
                f"(ResetIntegratorFromFlags offers {', '.join(GetIntegrationSchemes())})"
            )

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        import_drake()
        mdl = ctx.model
        mode = ctx.integrator.options["mode"]
        scheme = ctx.integrator.options["scheme"]
        if mdl.pivoted:
            R_WF, R_BM, chart = rpy_chart(mdl, ctx.scenario.rotation, ctx.scenario.omega_body)
        else:
            R_WF, R_BM, chart = np.eye(3), np.eye(3), ""
        p_BM = -np.asarray(mdl.com, dtype=float)
        h = Handle(None, None, None, None, None, None, mode, scheme, R_WF, R_BM, p_BM)
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
        if scheme == CONVEX_SCHEME:
            ctx.nevals = math.nan  # CENIC counts no derivative evaluations (it has none)

    def _assemble(self, ctx, h: Handle, R_WF, R_BM, first_step: float) -> None:
        """Build the plant (joint frames F and M at ``R_WF`` and ``R_BM``), its Simulator and
        integrator (error-controlled: ``first_step`` as the initial step size target) and the
        monitor, into ``h``; at t = 0 and at every chart switch (a finalised plant's joint
        frames cannot move)."""
        from pydrake.systems.analysis import Simulator

        plant, body, joint, system = build_plant(ctx, h, R_WF, R_BM)
        sim = Simulator(system)
        context = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        integ = make_integrator(ctx, h, sim, first_step)
        h.plant, h.body, h.joint, h.simulator, h.context, h.integrator = (
            plant, body, joint, sim, context, integ,
        )  # fmt: skip
        h.R_WF, h.R_BM = np.asarray(R_WF, dtype=float), np.asarray(R_BM, dtype=float)
        h.charts.append((h.R_WF, h.R_BM))
        # read_raw's last entry for a pivoted body: the chart's index; None for a free one
        h.chart_entry = np.array([len(h.charts) - 1.0]) if ctx.model.pivoted else None
        if ctx.model.pivoted or h.mode == "error-controlled":
            sim.set_monitor(_monitor(h, ctx.model.pivoted))

    def read_model(self, ctx) -> ModelReadback:
        h = ctx.handle
        plant, body, joint, pc = h.plant, h.body, h.joint, h.context
        M = body.CalcSpatialInertiaInBodyFrame(pc)  # about Bo, the COM by construction
        p_BoBcm = np.asarray(M.get_com())
        about_com = M.Shift(p_BoBcm)
        X_BM = joint.frame_on_child().CalcPoseInBodyFrame(pc)
        extra = model_checks(h)
        dt = integrator_checks(ctx, h, extra)
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
            + ("; an empty SceneGraph for CENIC" if h.scheme == CONVEX_SCHEME else ""),
        }
        if not mdl.pivoted:
            out["quaternion"] = (
                "kept at unit norm by CENIC's position update"
                if h.scheme == CONVEX_SCHEME
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
        x = h.plant.GetPositionsAndVelocities(h.context)  # a copy, [q, v]
        if h.chart_entry is not None:
            return np.concatenate((x, h.chart_entry))
        return x

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
                t0 = time.perf_counter()
                h.simulator.AdvanceTo(target)
                ctx.clock.lap(t0)
            except RuntimeError as exc:
                ctx.clock.lap(t0)
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
                updates = old.updates + update_count(h.simulator)
            else:
                taken = updates = old.steps + h.integrator.get_num_steps_taken()
            if taken != h.n or updates != h.n:
                what = f"{taken} steps" + (
                    f" and {updates} discrete updates" if h.integrator is None else ""
                )
                raise EngineError(
                    f"drake {h.scheme}: Drake took {what} where the plan had {h.n} fixed steps "
                    f"of {ctx.dt!r} s (up to t = {target!r}, over {len(h.charts)} chart(s)); "
                    "the time bookkeeping of the adapter is wrong"
                )
            if ctx.integrator.evals_per_step is None and h.scheme != CONVEX_SCHEME:
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
            old.updates += update_count(sim)
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
        if h.scheme != CONVEX_SCHEME:
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
                "dynamics evaluations": float(evals) if h.scheme != CONVEX_SCHEME else math.nan,
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


def _monitor(h: Handle, pivoted: bool):
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
    cenic = h.scheme == CONVEX_SCHEME
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


def _extreme(pick, a: float, b: float) -> float:
    """``pick`` (max or min) of two step sizes, NaN standing for none taken."""
    if math.isnan(a):
        return float(b)
    return a if math.isnan(b) else float(pick(a, b))
