"""The run loop every adapter shares (:meth:`Engine.run <references.engines.interface.Engine.run>`
calls :func:`run_loop`): the step plan, the read-back of the model, the initial-state check
through the engine's own quantities, the loop (saves, chunks, progress, the stopwatch that
separates time inside the engine's calls from the suite's glue), the divergence checks and the
conversion into the suite's trajectory schema (:mod:`references.trajectory`).

``engine`` below is an :class:`~references.engines.interface.Engine` (an adapter); this module
does not import it, the interface imports this one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from references import conventions as cv
from references.engines.context import BodyModel, ModelReadback, RunContext, RunOutput
from references.engines.liegroup import CompiledRKMK4Stepper
from references.engines.native import NativeStderr
from references.engines.recording import Recorder, sorted_unique
from references.engines.timing import cpu_clock
from references.errors import Diverged, EngineError, StepFailure, Unsupported
from references.trajectory import energy_parts
from scenarios.schema import step_plan

#: Energy error, relative to the scenario's energy scale, beyond which a run has diverged.
DIVERGENCE_ENERGY = 1.0

#: Largest number of steps between two checks of the state (bounds how late a divergence is
#: seen, and the resolution of ``t_diverged``).
CHUNK = 1000

#: Read-back tolerance of the model checks, a few ulp: engines may store a number through some
#: arithmetic (with pin 4.1.0 and pybullet 3.2.7 an inertia of 0.9 reads back as
#: 0.8999999999999999).
READBACK_RTOL = 1e-15


def run_loop(
    engine: Any,
    scenario,
    integrator: str,
    dt: float,
    t_end: float | None = None,
    save_every: int | None = None,
    progress: Callable[[float], None] | None = None,
    recorder: Recorder | None = None,
    accuracy: float | None = None,
) -> RunOutput:
    """:meth:`Engine.run <references.engines.interface.Engine.run>` of the adapter ``engine``
    (the arguments and exceptions are documented there)."""
    integ = engine.integrator(integrator)
    if integ.adaptive != (accuracy is not None):
        raise Unsupported(
            f"{engine.name} {integ.name}: "
            + (
                "an error-controlled integrator needs a target accuracy"
                if integ.adaptive
                else "a fixed-step integrator takes no target accuracy"
            )
        )
    engine.check_supported(scenario, integ)
    t_end = scenario.t_end if t_end is None else t_end
    save_every = scenario.save_every if save_every is None else save_every
    nstep, saves = step_plan(dt, t_end, save_every)
    ctx = RunContext(scenario, BodyModel.of(scenario, dt), integ, float(dt), float(t_end))
    ctx.accuracy = None if accuracy is None else float(accuracy)
    if ctx.model.pivoted and integ.family_on_a_ball is not None:
        ctx.family = integ.family_on_a_ball
    ctx.stderr = NativeStderr()
    rec = recorder if recorder is not None else Recorder(saves)
    rec.residuals = ctx.residuals
    try:
        engine.build(ctx)
        check_readback(engine.name, engine.read_model(ctx), ctx.model)
        stepper = _stepper(engine, ctx)
        stepper.start(initial_state(scenario))
        check_initial(engine, ctx, scenario)
        wall, steps_done = _loop(engine, ctx, stepper, nstep, saves, rec, progress)
        settings = {**engine.settings(ctx), "integrator": integ.name, "timestep": float(dt)}
        if ctx.accuracy is not None:
            settings["target accuracy"] = ctx.accuracy
    finally:
        engine.close(ctx)
        ctx.stderr.close()
    out = _output(ctx, rec, steps_done, wall, settings)
    if progress is not None:
        progress(1.0)
    return out


def check_batch_members(engine: str, members: Sequence) -> None:
    """Raise :class:`EngineError` naming the field unless the scenarios ``members`` of a
    batched run (:meth:`EngineBase.run_batch <references.engines.interface.EngineBase.run_batch>`)
    are one body: the same mass, inertia, gravity and pivot (only initial states may differ)."""
    if not members:
        raise EngineError(f"{engine}: a batched run needs at least one member")
    first = members[0]
    for k, member in enumerate(members[1:], start=1):
        for field in ("mass", "inertia", "gravity", "pivot"):
            a, b = getattr(member, field), getattr(first, field)
            if (a is None) != (b is None) or (a is not None and not np.array_equal(a, b)):
                raise EngineError(
                    f"{engine}: batch member {k} ({member.name!r}) differs from member 0 in "
                    f"{field} ({a!r} against {b!r}); the members of a batch may differ only in "
                    "their initial state"
                )


def initial_state(scenario) -> cv.BodyState:
    return cv.BodyState(
        np.array(scenario.position, dtype=float),
        np.array(scenario.velocity, dtype=float),
        np.array(scenario.rotation, dtype=float),
        np.array(scenario.omega_body, dtype=float),
    )


def check_readback(engine: str, got: ModelReadback, want: BodyModel) -> None:
    """Raise :class:`EngineError` naming the quantity unless the built model holds ``want``."""
    chk = cv.check_quantity
    chk(engine, "mass", got.mass, want.mass, READBACK_RTOL)
    chk(engine, "inertia tensor about the COM", got.inertia, np.diag(want.inertia), READBACK_RTOL)
    scale = float(np.linalg.norm(want.com)) or math.sqrt(float(np.max(want.inertia)) / want.mass)
    chk(engine, "COM position in the body frame", got.com, want.com, READBACK_RTOL, 1e-15 * scale)
    if got.joint != want.joint:
        raise EngineError(
            f"{engine}: the built model has a {got.joint!r} joint, the scenario needs "
            f"{want.joint!r}; the adapter built the wrong joint"
        )
    chk(engine, "gravity", got.gravity, want.gravity, READBACK_RTOL)
    chk(engine, "time step", got.dt, want.dt, READBACK_RTOL)
    for name, (value, required, *atol) in got.extra.items():
        chk(engine, name, value, required, 0.0, atol[0] if atol else 0.0)


def check_initial(engine: Any, ctx: RunContext, scenario) -> dict:
    """Check, before the first step, that the engine holds the scenario's initial state: the
    state read back through the adapter's conversions AND the engine's own energy, angular
    momentum and rotation (:meth:`Engine.native_quantities`), which a mistake made the same
    way in both conversions (a quaternion order, a body/world frame, a unit) cannot fool."""
    native = engine.native_quantities(ctx)
    if "energy" not in native or "angular momentum" not in native or "rotation" not in native:
        raise EngineError(
            f"{engine.name}: native_quantities must give the engine's own energy, angular "
            "momentum and rotation (the only checks a consistent conversion mistake cannot pass)"
        )
    state = engine.read_state(ctx)
    return cv.check_initial_state(engine.name, scenario, state, native=native)


# -- stepping strategies ----------------------------------------------------------------------


class _NativeStepper:
    """The engine's own integrator: the state lives in the engine."""

    def __init__(self, engine: Any, ctx: RunContext):
        self.engine, self.ctx = engine, ctx

    def start(self, state: cv.BodyState) -> None:
        self.engine.set_state(self.ctx, state)

    def run(self, steps: list[int]) -> cv.BodyState:
        out = self.engine.advance_saving(self.ctx, steps)
        per = self.ctx.integrator.evals_per_step
        if per is not None:
            self.ctx.nevals += per * sum(steps)
        return out

    def state(self) -> cv.BodyState:
        return self.engine.read_state(self.ctx)


def _stepper(engine: Any, ctx: RunContext):
    if ctx.integrator.stepping == "native":
        return _NativeStepper(engine, ctx)
    return CompiledRKMK4Stepper(engine, ctx)


# -- the loop ---------------------------------------------------------------------------------


def _blocks(nstep: int, saves: np.ndarray, every_step: bool):
    """The checkpoints (steps at which the state is read) in blocks that end at multiples of
    CHUNK: every step, or the saves and at least every CHUNK steps. Generated lazily (a long
    horizon has many), a block at a time from arrays (a Python loop over the points costs a
    microsecond each)."""
    if every_step:
        for start in range(1, nstep + 1, CHUNK):
            yield list(range(start, min(start + CHUNK, nstep + 1)))
        return
    saves = np.asarray(saves)
    points = sorted_unique(np.concatenate([saves[saves > 0], np.arange(CHUNK, nstep, CHUNK)]))
    ends = np.flatnonzero((points % CHUNK == 0) | (points == nstep)) + 1
    start = 0
    for end in (*ends.tolist(), len(points)):
        if end > start:
            yield points[start:end].tolist()
        start = end


#: the separately conserved parts of the energy, as divergence messages name them
_ENERGY_PART = {"total": "energy", "rot": "rotational energy", "trans": "translational energy"}


def _first_divergence(engine, ctx, block, energy0, scales) -> tuple[int, str] | None:
    """(index of the first diverged state of a block, why), or None: a non-finite state or
    an energy error beyond DIVERGENCE_ENERGY of its scale (vectorised over the block): of the
    total energy, and for a free body of its rotational and its translational energy apart,
    each against its own scale (:attr:`Scenario.energy_scales`), so that neither hides the
    other; or the engine's own limit (:meth:`Engine.guard`, on the block's last state).
    ``energy0``: the parts of the initial energy (:func:`energy_parts`); ``scales``: the
    scenario's :attr:`Scenario.energy_scales`, read once per run by the caller (computing
    them costs about as much as the check of a block)."""
    x, v, R, W = block
    finite = np.isfinite(x).all(1) & np.isfinite(v).all(1) & np.isfinite(W).all(1)
    finite &= np.isfinite(R).all((1, 2))
    with np.errstate(all="ignore"):
        parts = energy_parts(ctx.scenario, x, v, R, W)
        drifts = {p: np.abs(parts[p] - energy0[p]) / scales[p] for p in parts}
    over = {p: ~(d <= DIVERGENCE_ENERGY) for p, d in drifts.items()}
    bad = ~finite | np.logical_or.reduce(list(over.values()))
    if bad.any():
        i = int(np.argmax(bad))
        if not finite[i]:
            return i, "the state became non-finite"
        p = next(p for p in drifts if over[p][i])
        what = _ENERGY_PART[p]
        return i, (
            f"the {what} error |E - E0| = {drifts[p][i] * scales[p]:.4g} J exceeded "
            f"{DIVERGENCE_ENERGY:g} x the scenario's {what} scale {scales[p]:.4g} J"
        )
    why = engine.guard(ctx, cv.block_row(block, len(x) - 1))
    return (len(x) - 1, why) if why else None


def _loop(engine, ctx, stepper, nstep, saves, rec, progress) -> tuple[float, int]:
    """Step from 0 to nstep block by block; returns (wall time of the stepping, steps done).
    Raises Diverged with the output up to the last good state."""
    sc = ctx.scenario
    energy0 = {
        p: float(e[0])
        for p, e in energy_parts(sc, *(np.asarray(a)[None] for a in initial_state(sc))).items()
    }
    check = (energy0, sc.energy_scales)
    first = stepper.state()
    rec.record_block([0], cv.BodyState(*(np.asarray(a)[None] for a in first)))
    wall = 0.0
    done = 0
    dt = ctx.dt
    watch = ctx.clock
    watch.cpu_now = cpu_clock(engine.threaded)
    for block in _blocks(nstep, saves, rec.every_step):
        steps = np.diff([done, *block]).tolist()
        try:
            with ctx.stderr:  # set by Engine.run, the only caller
                watch.resume()  # after the redirection is in place
                states = stepper.run(steps)
        except StepFailure as exc:
            watch.pause()
            wall = watch.wall
            t_div, span = _failed_step(exc, done, block[-1], dt)
            kept = exc.states  # the checkpoints completed before it
            if kept is not None and len(kept[0]):
                _record_checked(engine, ctx, rec, block, kept, done, wall, check)
                done = block[len(kept[0]) - 1]
            raise _diverged(
                engine, ctx, rec, done, wall, t_div, f"{span} could not be taken: {exc}"
            ) from exc
        watch.pause()
        wall = watch.wall
        _record_checked(engine, ctx, rec, block, states, done, wall, check)
        done = block[-1]
        if progress is not None:
            progress(done / nstep)
    return wall, done


def _record_checked(engine, ctx, rec, block, states, done, wall, check) -> None:
    """Record the states of the checkpoints ``block[:len(states)]`` up to the first diverged
    one, and raise :class:`Diverged` at that one if there is one. ``check``: the parts of the
    initial energy and the scenario's energy scales (:func:`_first_divergence`)."""
    dt = ctx.dt
    found = _first_divergence(engine, ctx, states, *check)
    good = len(states[0]) if found is None else found[0]
    if good:
        rec.record_block(block[:good], cv.BodyState(*(a[:good] for a in states)))
    if found is not None:
        before = block[good - 1] if good else done
        span = f"between t = {before * dt:.6g} and t = {block[good] * dt:.6g} s"
        raise _diverged(engine, ctx, rec, before, wall, block[good] * dt, f"{found[1]} {span}")


def _failed_step(exc: StepFailure, done: int, last: int, dt: float) -> tuple[float, str]:
    """(t_diverged, what failed) of a :class:`StepFailure` raised while stepping from step
    ``done`` to ``last``: the time the failing step starts from, as the raiser gives it
    (``time``, or ``steps_taken`` in this call); without either, only the block is known and
    its end is the latest the failure can be."""
    t_fail, taken = exc.time, exc.steps_taken
    if t_fail is None and taken is not None:
        t_fail = (done + int(taken)) * dt
    if t_fail is not None:
        t_fail = float(t_fail)
        return t_fail, f"the step from t = {t_fail:.6g} to t = {t_fail + dt:.6g} s"
    return last * dt, f"a step between t = {done * dt:.6g} and t = {last * dt:.6g} s"


def _diverged(engine, ctx, rec, done, wall, t_div, what) -> Diverged:
    integ = ctx.integrator
    msg = f"{integ.name} at dt = {ctx.dt:g} s: {what}; the run diverged (reduce dt)"
    settings = {**engine.settings(ctx), "integrator": integ.name, "timestep": ctx.dt}
    out = _output(ctx, rec, done, wall, settings)
    return Diverged(msg, t_div, out)


def _output(ctx, rec, steps_done, wall, settings) -> RunOutput:
    per = ctx.nevals / steps_done if steps_done else float(ctx.integrator.evals_per_step or 0)
    if ctx.family is not None:
        settings = {**settings, "family of the algorithm run": ctx.family}
    said = ctx.stderr.summary() if ctx.stderr is not None else None
    if said is not None:
        settings = {**settings, "engine's standard error": said}
    return RunOutput(
        trajectory=rec.trajectory(ctx.scenario, ctx.dt),
        nstep=int(steps_done),
        wall_time_s=float(wall),
        engine_time_s=float(min(ctx.clock.elapsed, wall)),
        cpu_time_s=float(ctx.clock.cpu),
        timing=ctx.clock.timing(),
        evals_per_step=float(per),
        settings=settings,
        stats=dict(ctx.stats),
        family=ctx.family or ctx.integrator.family,
    )
