"""Ensembles on MJX: many bodies that differ only in their initial state, in one vmapped,
compiled call (:func:`run_batch`, the engine's ``run_batch`` hook)."""

from __future__ import annotations

import time

import numpy as np

from references import conventions as cv
from references.engines.context import BodyModel, RunContext, RunOutput
from references.engines.mjx.compile import (
    CHECKPOINTS,
    FLOAT32_INITIAL_RTOL,
    _as_float,
    _block_fn,
    _c_ctx,
    _compiled,
    _for_native,
    _native_fn,
    _states,
)
from references.engines.mujoco.adapter import MujocoEngine
from references.engines.stepping import CHUNK, DIVERGENCE_ENERGY, check_readback
from references.errors import Diverged, EngineError
from scenarios.schema import step_plan


def run_batch(eng, members, integrator: str, dt: float, t_end: float, save_every: int) -> list:
    """Run ``members`` (scenarios that differ only in their initial state) with one MJX
    configuration of the engine ``eng`` (an :class:`~references.engines.mjx.MjxEngine`) in one
    vmapped, compiled call per CHECKPOINTS checkpoints.

    Returns one entry per member: its :class:`RunOutput`, or a :class:`Diverged` carrying the
    output up to its last good checkpoint (checkpoints: the saves and every CHUNK steps, as
    in :meth:`Engine.run`; a member diverges on a non-finite state or an energy error beyond
    DIVERGENCE_ENERGY of its energy scale). Before stepping, the shared model is read back
    (:func:`check_readback`), and every member's initial state is checked twice: the
    conversions on the C ``MjData`` through C MuJoCo's quantities to 1e-12, and the batched
    state MJX holds through MJX's own quantities (vmapped), to 1e-12 in float64 and to
    :data:`FLOAT32_INITIAL_RTOL` in float32 (the state handed over in float64 is rounded by
    JAX as it is put on the device). The saved state at t = 0 is the state handed over. Wall
    and engine times are the batch's divided by the number of members. Raises
    :class:`EngineError` (``Unsupported`` included) for the whole batch.
    """
    integ = eng.integrator(integrator)
    base = members[0]
    _check_same_body(members)
    eng.check_supported(base, integ)
    nstep, saves = step_plan(dt, t_end, save_every)
    ctx = RunContext(base, BodyModel.of(base, dt), integ, float(dt))
    ctx.t_end = float(t_end)
    eng._put_model(ctx)
    check_readback(eng.name, eng.read_model(ctx), ctx.model)
    qpos0, qvel0, dxb = _batch_initial(eng, ctx, members)
    points = sorted(set(int(s) for s in saves if s > 0) | set(range(CHUNK, nstep, CHUNK)))
    qp, qv, wall, engine_s = _batch_step(ctx, dxb, qpos0, qvel0, points)
    settings = {**eng.settings(ctx), "integrator": integ.name, "timestep": float(dt)}
    n = len(members)
    settings["batch"] = f"{n} bodies in one vmapped call; times are the batch's / {n}"
    settings["initial state rounding errors"] = "checked per member, not recorded"
    points = np.array([0, *points])
    return [
        _batch_output(
            ctx, mem, qp[k], qv[k], points, saves, nstep, settings, wall / n, engine_s / n
        )
        for k, mem in enumerate(members)
    ]


def _check_same_body(members) -> None:
    base = members[0]
    for mem in members[1:]:
        for f in ("mass", "inertia", "gravity", "pivot"):
            a, b = getattr(mem, f), getattr(base, f)
            if (a is None) != (b is None) or (a is not None and not np.array_equal(a, b)):
                raise ValueError(f"run_batch: the members differ in {f}; only initial states may")


def _batch_initial(eng, ctx, members):
    """The members' initial states on the device as one batched ``mjx.Data``, each checked
    through C MuJoCo's quantities (the conversions) and MJX's own (the state MJX holds)."""
    h = ctx.handle
    jax, jnp = h.jax, h.jax.numpy
    n = len(members)
    cctx = _c_ctx(ctx, h)
    c_engine = MujocoEngine()
    qpos0, qvel0 = [], []
    for mem in members:
        c_engine.set_state(cctx, _initial(mem))
        cctx.scenario = mem
        cv.check_initial_state(
            eng.name, mem, c_engine.read_state(cctx), c_engine.native_quantities(cctx)
        )
        qpos0.append(h.d.qpos.copy())
        qvel0.append(h.d.qvel.copy())
    qpos0, qvel0 = np.stack(qpos0), np.stack(qvel0)

    with h.x64_mode():
        dxb = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), h.dx)
        dxb = dxb.replace(qpos=jnp.asarray(qpos0), qvel=jnp.asarray(qvel0))
    vnative = jax.vmap(_native_fn(ctx.model.pivoted), in_axes=(None, 0))
    mxn = _for_native(h.mjx, h.mx)
    comp_n, h.compile_s["batched own quantities"], now = _compiled(
        f"batch-native-{ctx.model.joint}", vnative, (mxn, dxb), (), h.x64
    )
    h.compiled_now += ["batched own quantities"] if now else []
    with h.x64_mode():
        nat = _as_float(comp_n(comp_n.leaves(0, mxn), comp_n.leaves(1, dxb)))
    held = _states(ctx.model, np.asarray(dxb.qpos, dtype=float), np.asarray(dxb.qvel, dtype=float))
    tol = 1e-12 if h.x64 else FLOAT32_INITIAL_RTOL
    for k, mem in enumerate(members):
        errors = cv.initial_state_errors(
            mem, cv.BodyState(*(a[k] for a in held)), {q: a[k] for q, a in nat.items()}
        )
        for quantity, err in errors.items():
            if not err <= tol:
                raise EngineError(
                    f"{eng.name}: member {k} ({mem.name}): before the first step, the "
                    f"{quantity} of the state MJX holds differs from the scenario's by "
                    f"{err:.3g} relative (allowed {tol:.3g}); a conversion or the model is wrong"
                )
    return qpos0, qvel0, dxb


def _batch_step(ctx, dxb, qpos0, qvel0, points):
    """Step the batch to every checkpoint in ``points`` (step counts), one compiled, vmapped
    call per CHECKPOINTS of them; the (qpos, qvel) of each member at 0 and every checkpoint,
    and the wall and engine seconds of the stepping."""
    h = ctx.handle
    jax = h.jax
    ks = np.zeros(CHECKPOINTS, np.int32)
    vblock = jax.vmap(_block_fn(), in_axes=(None, 0, None, None))
    comp, h.compile_s["batched step"], now = _compiled(
        f"batch-step-{h.mj_name}", vblock, (h.mx, dxb), (ks, np.int32(0)), h.x64
    )
    h.compiled_now += ["batched step"] if now else []
    steps = np.diff([0, *points]).astype(np.int32)
    qp, qv = [qpos0[:, None]], [qvel0[:, None]]
    m_leaves, d_leaves = comp.leaves(0, h.mx), comp.leaves(1, dxb)
    engine_s = 0.0
    t0 = time.perf_counter()
    for i in range(0, len(steps), CHECKPOINTS):
        part = steps[i : i + CHECKPOINTS]
        ks = np.zeros(CHECKPOINTS, np.int32)
        ks[: len(part)] = part
        c0 = time.perf_counter()
        with h.x64_mode():
            d_leaves, qpos, qvel = comp(m_leaves, d_leaves, ks, np.int32(len(part)))
            jax.block_until_ready((d_leaves, qpos, qvel))
        engine_s += time.perf_counter() - c0
        qp.append(np.asarray(qpos, dtype=float)[:, : len(part)])
        qv.append(np.asarray(qvel, dtype=float)[:, : len(part)])
    wall = time.perf_counter() - t0
    return np.concatenate(qp, axis=1), np.concatenate(qv, axis=1), wall, engine_s


def _batch_output(ctx, mem, qp, qv, points, saves, nstep, settings, wall, engine_s):
    """One member's RunOutput from its states at the checkpoints ``points``, or a Diverged
    carrying the output up to its last good checkpoint."""
    from references.trajectory import Trajectory, energy

    dt, integ = ctx.dt, ctx.integrator
    saved = np.isin(points, saves)
    x, v, R, W = _states(ctx.model, qp, qv)
    e0 = float(energy(mem, *(np.asarray(a)[None] for a in _initial(mem)))[0])
    with np.errstate(all="ignore"):
        drift = np.abs(energy(mem, x, v, R, W) - e0) / mem.energy_scale
    finite = np.isfinite(qp).all(1) & np.isfinite(qv).all(1)
    bad = ~finite | ~(drift <= DIVERGENCE_ENERGY)
    good = int(np.argmax(bad)) if bad.any() else len(points)
    keep = np.flatnonzero(saved & (np.arange(len(points)) < good))
    traj = Trajectory.from_states(mem, points[keep] * dt, x[keep], v[keep], R[keep], W[keep])
    done = int(points[good - 1]) if good < len(points) else nstep
    output = RunOutput(traj, done, wall, engine_s, float(integ.evals_per_step or 0.0), settings)
    if good == len(points):
        return output
    what = (
        "the state became non-finite"
        if not finite[good]
        else f"the energy error exceeded {DIVERGENCE_ENERGY:g} x the scenario's energy "
        f"scale {mem.energy_scale:.4g} J"
    )
    span = f"between t = {done * dt:.6g} and t = {points[good] * dt:.6g} s"
    msg = f"{integ.name} at dt = {dt:g} s: {what} {span}; the run diverged (reduce dt)"
    return Diverged(msg, float(points[good] * dt), output)


def _initial(scenario) -> cv.BodyState:
    from references.engines.stepping import initial_state

    return initial_state(scenario)
