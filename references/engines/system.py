"""Runs of systems of bodies: the suite's side of the contract with the engine builders.

An engine runs a system scenario (:class:`scenarios.SystemScenario`) through a builder module
``references/engines/<engine>/system.py`` (the engine's registry name, e.g.
``director/system.py``, ``mujoco/system.py``) that provides::

    def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                        **settings) -> dict | object

returning ``t`` (n,) s, ``x`` (n, nb, 3) centres of mass (world, m), ``R`` (n, nb, 3, 3)
body-to-world, ``v`` (n, nb, 3) m/s (world), ``W`` (n, nb, 3) rad/s (body axes), with the
bodies in the order of ``scenario.bodies`` and the frames their principal frames at the
centres of mass, saved at the steps 0, s, 2s, ..., nstep; ``engine_time_s`` (time inside the
engine's own stepping calls) and ``settings`` (every setting that shapes the result). A joint
or loop the engine cannot express raises :class:`~references.errors.Unsupported` with the
reason. The suite (:func:`run_system`) checks the shape and the times of what comes back,
stops it at a divergence (a non-finite state, or an energy error beyond DIVERGENCE_ENERGY
times the scenario's energy scale, the rule of one body) and computes every metric itself.

An engine with no builder module is ``unsupported`` for systems, with that reason.

A robot-model scenario also runs through each engine's own importer: an integrator named
for an importer configuration ("RK4 (as loaded)", "RK4 (faithful)":
:func:`references.engines.importers.variant`) loads the scenario's model file with the
engine's importer (``references/engines/<engine>/importer.py``) and returns the same result
(:func:`references.engines.importers.simulate`).
"""

from __future__ import annotations

import importlib
import math
import time
from dataclasses import dataclass, field

import numpy as np

from references.engines import importers
from references.engines.stepping import DIVERGENCE_ENERGY, step_plan
from references.errors import Diverged, EngineError, Unsupported
from references.trajectory import SystemTrajectory, system_energy

#: the keys a builder's result must have
RESULT_KEYS = ("t", "x", "R", "v", "W")


@dataclass
class SystemRunOutput:
    """A system run's states and costs (the system counterpart of ``RunOutput``)."""

    trajectory: SystemTrajectory
    nstep: int
    wall_time_s: float
    engine_time_s: float
    settings: dict
    evals_per_step: float = math.nan
    stats: dict = field(default_factory=dict)
    family: str = ""

    @property
    def glue_time_s(self) -> float:
        return max(self.wall_time_s - self.engine_time_s, 0.0)


def builder(engine: str):
    """The builder module of ``engine`` (``references.engines.<engine>.system``), or raise
    :class:`Unsupported` saying that the engine has none."""
    name = f"references.engines.{engine}.system"
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name:
            raise
        raise Unsupported(
            f"{engine}: this engine has no system builder (references/engines/"
            f"{engine}/system.py), so it runs no system of bodies yet"
        ) from None


def builder_settings(engine: str) -> tuple[str, ...] | None:
    """The names of the settings ``engine``'s system builder takes (the ``_SETTINGS`` its
    ``simulate_system`` checks the file's ``[engine_settings.<engine>]`` against), or None
    when the engine has no builder or its builder declares none."""
    try:
        mod = builder(engine)
    except Unsupported:
        return None
    known = getattr(mod, "_SETTINGS", None)
    return None if known is None else tuple(known)


def run_system(
    engine: str,
    scenario,
    integrator: str,
    dt: float,
    t_end: float | None = None,
    save_every: int | None = None,
    **settings,
) -> SystemRunOutput:
    """Run the system ``scenario`` on ``engine``'s builder with ``integrator`` at step
    ``dt`` up to ``t_end`` (default: the scenario's), saving every ``save_every`` steps,
    with the builder's ``settings`` (the file's ``[engine_settings.<engine>]``, then these).
    Raises :class:`Unsupported`, :class:`Diverged` (with the output up to the last good
    state) or :class:`EngineError` (a builder's output that breaks the contract)."""
    t_end = scenario.t_end if t_end is None else float(t_end)
    save_every = scenario.save_every if save_every is None else int(save_every)
    nstep, saves = step_plan(dt, t_end, save_every)
    base, config = importers.split_variant(integrator)
    t0 = time.perf_counter()
    try:
        if config is not None:  # through the engine's own importer (references.engines.importers)
            res = importers.simulate(engine, scenario, config, base, float(dt), int(nstep),
                                     int(save_every))  # fmt: skip
        else:
            mod = builder(engine)
            settings = {**getattr(scenario, "engine_settings", {}).get(engine, {}), **settings}
            res = mod.simulate_system(scenario, integrator, float(dt), int(nstep),
                                      int(save_every), **settings)  # fmt: skip
    except Diverged as exc:  # the builder's states up to the divergence, as an output
        if isinstance(exc.output, dict):
            exc.output = _output(engine, scenario, exc.output, integrator, dt,
                                 time.perf_counter() - t0)  # fmt: skip
        raise
    wall = time.perf_counter() - t0
    get = res.get if isinstance(res, dict) else (lambda k, d=None: getattr(res, k, d))
    missing = [k for k in RESULT_KEYS if get(k) is None]
    if missing:
        raise EngineError(f"{engine} system builder: its result lacks {missing}")
    names = scenario.body_names
    try:
        traj = SystemTrajectory(get("t"), get("x"), get("v"), get("R"), get("W"), names)
    except ValueError as exc:
        raise EngineError(f"{engine} system builder: {exc}") from None
    want = saves * float(dt)
    n = len(traj)
    if n > len(want) or not np.allclose(traj.t, want[:n], rtol=0, atol=1e-9 * max(t_end, 1)):
        raise EngineError(
            f"{engine} system builder: saved times {traj.t[:3].tolist()}... are not the "
            f"steps 0, {save_every}, ... of dt = {dt:g} s"
        )
    out = SystemRunOutput(
        trajectory=traj,
        nstep=int(saves[n - 1]) if n else 0,
        wall_time_s=wall,
        engine_time_s=float(min(get("engine_time_s", wall) or wall, wall)),
        settings={**dict(get("settings", {}) or {}), "integrator": integrator, "timestep": dt},
        evals_per_step=float(get("evals_per_step", math.nan) or math.nan),
        stats=dict(get("stats", {}) or {}),
    )
    bad = _first_divergence(scenario, traj)
    if bad is not None:
        k, why = bad
        out.trajectory = traj.head(k)
        out.nstep = int(saves[k - 1]) if k else 0
        raise Diverged(
            f"{integrator} at dt = {dt:g} s: {why} at t = {traj.t[k]:.6g} s; the run diverged",
            float(traj.t[k]),
            out,
        )
    if n < len(want):
        raise EngineError(
            f"{engine} system builder: {n} saved states, the step plan has {len(want)}"
        )
    return out


def _output(engine, scenario, res: dict, integrator, dt, wall) -> SystemRunOutput | None:
    """The output of a builder's result dict that ended at a divergence (states up to the
    last good save); None when it holds none."""
    try:
        traj = SystemTrajectory(res["t"], res["x"], res["v"], res["R"], res["W"],
                                scenario.body_names)  # fmt: skip
    except (KeyError, ValueError):
        return None
    settings = {**dict(res.get("settings", {}) or {}), "integrator": integrator, "timestep": dt}
    return SystemRunOutput(
        trajectory=traj,
        nstep=int(round(traj.t[-1] / dt)) if len(traj) else 0,
        wall_time_s=wall,
        engine_time_s=float(min(res.get("engine_time_s", wall) or wall, wall)),
        settings=settings,
    )


def _first_divergence(scenario, traj) -> tuple[int, str] | None:
    """(index of the first diverged saved state, why) or None: a non-finite state, or an
    energy error beyond DIVERGENCE_ENERGY of the scenario's energy scale."""
    arrays = (traj.position, traj.velocity, traj.omega_body)
    finite = np.all([np.isfinite(a).all(axis=(1, 2)) for a in arrays], axis=0)
    finite &= np.isfinite(traj.rotation).all(axis=(1, 2, 3))
    with np.errstate(all="ignore"):
        E = system_energy(scenario, traj)
        drift = np.abs(E - E[0]) / scenario.energy_scale
    bad = ~finite | ~(drift <= DIVERGENCE_ENERGY)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    if not finite[k]:
        return k, "the state became non-finite"
    return k, (
        f"the energy error {drift[k] * scenario.energy_scale:.4g} J exceeded "
        f"{DIVERGENCE_ENERGY:g} x the scenario's energy scale {scenario.energy_scale:.4g} J"
    )
