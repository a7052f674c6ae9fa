"""Runs of systems of bodies: the suite's side of the contract with the engine builders.

An engine runs a system scenario (:class:`scenarios.SystemScenario`) through the builder its
adapter declares (:attr:`~references.engines.interface.EngineBase.scene_builder`, a
:class:`~references.engines.interface.SceneBuilder`: where the function is and the settings
it takes), a function::

    def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                        **settings) -> SystemResult

returning a :class:`SystemResult`: ``t`` (n,) s, ``x`` (n, nb, 3) centres of mass (world, m),
``R`` (n, nb, 3, 3) body-to-world, ``v`` (n, nb, 3) m/s (world), ``W`` (n, nb, 3) rad/s (body
axes), with the bodies in the order of ``scenario.bodies`` and the frames their principal
frames at the centres of mass, saved at the steps 0, s, 2s, ..., nstep; ``engine_time_s``
(time inside the engine's own stepping calls) and ``settings`` (every setting that shapes the
result). A joint or loop the engine cannot express raises
:class:`~references.errors.Unsupported` with the reason; a run that diverges raises
:class:`~references.errors.Diverged` whose ``output`` is the :class:`SystemResult` up to the
last good state. The suite (:func:`run_system`) checks the settings asked for against those
declared, the shape and the times of what comes back, stops it at a divergence (a non-finite
state, or an energy error beyond DIVERGENCE_ENERGY times the scenario's energy scale, the rule
of one body; with a damper, an energy rise) and computes every metric itself.

An engine that declares no builder is ``unsupported`` for systems, with that reason. The
builders of the built-in engines are ``references/engines/<engine>/system.py``; a plug-in's
adapter declares its own (docs/extending.md).

A robot-model scenario also runs through each engine's own importer: an integrator named
for an importer configuration ("RK4 (as loaded)", "RK4 (faithful)":
:func:`references.engines.importers.variant`) loads the scenario's model file with the
engine's importer (``references/engines/<engine>/importer.py``) and returns the same result
(:func:`references.engines.importers.simulate`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from references.engines import importers, timing
from references.engines.context import SystemResult
from references.engines.stepping import DIVERGENCE_ENERGY, step_plan
from references.errors import Diverged, EngineError, Unsupported
from references.trajectory import Trajectory, system_energy
from scenarios.force_elements import dissipative, has_elements
from scenarios.models.configurations import split_variant


@dataclass
class SystemRunOutput:
    """A system run's states and costs (the system counterpart of ``RunOutput``)."""

    trajectory: Trajectory
    nstep: int
    wall_time_s: float
    engine_time_s: float
    settings: dict
    evals_per_step: float = math.nan
    stats: dict = field(default_factory=dict)
    family: str = ""
    #: the stepping's timing (references.engines.timing), when the builder timed its engine
    #: calls on the run's stopwatch; None: its wall time stands
    timing: object = None

    @property
    def glue_time_s(self) -> float:
        return max(self.wall_time_s - self.engine_time_s, 0.0)


def builder(engine: str):
    """The system builder function of ``engine`` (its adapter's
    :attr:`~references.engines.interface.EngineBase.scene_builder`), or raise
    :class:`Unsupported` saying that the engine has none."""
    return _declared(engine).load()


def builder_settings(engine: str) -> tuple[str, ...] | None:
    """The names of the settings ``engine``'s system builder takes (a file's
    ``[engine_settings.<engine>]``), or None when the engine has no builder."""
    from references.engines import get_engine

    declared = get_engine(engine).scene_builder
    return None if declared is None else declared.settings


def check_settings(engine: str, settings) -> None:
    """Refuse a setting the builder of ``engine`` does not take (those its adapter declares):
    ValueError naming the unknown ones and the known ones."""
    known = _declared(engine).settings
    unknown = sorted(set(settings) - set(known))
    if unknown:
        raise ValueError(f"{engine} simulate_system: unknown settings {unknown}; known: "
                         f"{list(known) or 'none'}")  # fmt: skip


def _declared(engine: str):
    from references.engines import get_engine

    declared = get_engine(engine).scene_builder
    if declared is None:
        raise Unsupported(
            f"{engine}: this engine's adapter declares no system builder (scene_builder), so "
            "it runs no system of bodies"
        )
    return declared


#: how each engine whose builder does not apply force elements could (what it lacks, or what
#: would express them and is not written): the reason its refusal gives
FORCE_ELEMENT_ROUTES: dict[str, str] = {}  # every built-in builder applies them


def _check_force_elements(engine: str, scenario) -> None:
    """:class:`Unsupported` when ``scenario`` has force elements and ``engine``'s builder does
    not declare that it applies them (a run without them would be another motion), with the
    reason (:data:`FORCE_ELEMENT_ROUTES`)."""
    if not has_elements(scenario) or _declared(engine).force_elements:
        return
    what = [f"torque on {t.joint!r}" for t in getattr(scenario, "torques", ())]
    what += [f"spring {s.name!r}" for s in getattr(scenario, "springs", ())]
    why = FORCE_ELEMENT_ROUTES.get(engine, "its builder does not declare force_elements")
    raise Unsupported(
        f"{engine}: force elements ({', '.join(what)}) are not built in this engine's system "
        f"builder: {why}; the builders that apply them: {', '.join(_applying())}"
    )


def _applying() -> list[str]:
    """The engines whose builder declares that it applies force elements."""
    from references.engines import engine_names, get_engine

    out = []
    for name in engine_names():
        try:
            declared = get_engine(name).scene_builder
        except Exception:  # an engine that cannot load declares nothing here
            continue
        if declared is not None and declared.force_elements:
            out.append(name)
    return out


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
    base, config = split_variant(integrator)
    if config is not None:  # through the engine's own importer (references.engines.importers)

        def simulate(scenario, integrator, dt, nstep, save_every):
            return importers.simulate(engine, scenario, config, base, dt, nstep, save_every)

        settings = {}  # an importer configuration takes the model file as it is
    else:
        _check_force_elements(engine, scenario)
        simulate = builder(engine)
        settings = {**getattr(scenario, "engine_settings", {}).get(engine, {}), **settings}
        check_settings(engine, settings)
    watch = timing.Stopwatch(timing.cpu_clock(_threaded(engine)))
    t0 = time.perf_counter()
    try:
        with timing.running(watch):  # the builder times its engine calls on it
            res = simulate(scenario, integrator, float(dt), int(nstep), int(save_every), **settings)
    except Diverged as exc:
        # the builder's own divergence: its states up to the last good save, in the form of
        # a run's output
        if isinstance(exc.output, SystemResult):
            wall = time.perf_counter() - t0
            part = _output(engine, scenario, integrator, dt, t_end, saves, exc.output, wall)
            part.timing = _timing(watch)
            raise Diverged(str(exc), exc.t_diverged, part) from exc
        raise
    wall = time.perf_counter() - t0
    out = _output(engine, scenario, integrator, dt, t_end, saves, res, wall)
    out.timing = res.timing if res.timing is not None else _timing(watch)
    traj, n, want = out.trajectory, len(out.trajectory), saves * float(dt)
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


def _timing(watch: timing.Stopwatch) -> timing.Timing | None:
    """The run's timing, when its builder timed its engine calls on ``watch``
    (:func:`references.engines.timing.lap`); else None (its wall time stands)."""
    return watch.timing() if watch.elapsed > 0 else None


def _threaded(engine: str) -> bool:
    from references.engines import EngineError, get_engine

    try:
        return bool(get_engine(engine).threaded)
    except EngineError:
        return False


def _output(engine, scenario, integrator, dt, t_end, saves, res, wall) -> SystemRunOutput:
    """The run's output from a builder's result: its states checked against the contract
    (shapes, the saved times of the step plan ``saves``)."""
    if not isinstance(res, SystemResult):
        raise EngineError(
            f"{engine} system builder: it returned a {type(res).__name__}, not a SystemResult"
        )
    try:
        traj = Trajectory(res.t, res.x, res.v, res.R, res.W, scenario.body_names)
    except ValueError as exc:
        raise EngineError(f"{engine} system builder: {exc}") from None
    want = saves * float(dt)
    n = len(traj)
    if n > len(want) or not np.allclose(traj.t, want[:n], rtol=0, atol=1e-9 * max(t_end, 1)):
        raise EngineError(
            f"{engine} system builder: saved times {traj.t[:3].tolist()}... are not the "
            f"steps {', '.join(str(int(k)) for k in saves[:3])}, ... of dt = {dt:g} s"
        )
    # 0 or NaN: not measured, the run's wall time stands for it
    engine_time = min(res.engine_time_s, wall) if res.engine_time_s > 0 else wall
    return SystemRunOutput(
        trajectory=traj,
        nstep=int(saves[n - 1]) if n else 0,
        wall_time_s=wall,
        engine_time_s=float(engine_time),
        settings={**res.settings, "integrator": integrator, "timestep": dt},
        evals_per_step=float(res.evals_per_step or math.nan),
        stats=dict(res.stats),
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
        if dissipative(scenario):  # a damper takes energy out: only a rise is divergence
            drift = np.maximum(E - E[0], 0.0) / scenario.energy_scale
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
