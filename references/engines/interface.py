"""The engine interface: what the runner needs of anything that produces trajectories
(:class:`EngineBase`) and what an engine adapter implements (:class:`Engine`).

Every hook is declared here, abstract or with a documented default; an adapter overrides what
differs for its engine. docs/engines.md ("The interface's hooks") lists each with its signature,
its default and the adapters that override it (a test compares that table with this module's
members, so neither can drift).

:meth:`Engine.run` owns everything else, identically for every engine (the run loop of
:mod:`references.engines.stepping`): the step plan, the read-back of the model, the
initial-state check through the engine's own quantities, the loop (saves, chunks, progress,
the stopwatch that separates time inside the engine's calls from the suite's glue), the
divergence checks and the conversion into the suite's trajectory schema
(:mod:`references.trajectory`).
Adapters never compute metrics.

Failures are exceptions of the classes below with a ``status``; the runner turns each into a
result row with that status and the message, so messages say what happened and what to do.
"""

from __future__ import annotations

import dataclasses
import importlib
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback, RunContext, RunOutput
from references.engines.integrators import Integrator, slug
from references.engines.liegroup import unpack_state
from references.engines.recording import Recorder
from references.engines.stepping import run_loop
from references.errors import EngineError, EngineUnavailable, Unsupported


@dataclass(frozen=True)
class SceneBuilder:
    """An engine's builder of systems of bodies (a scene of several bodies joined by joints),
    declared by its adapter (:attr:`EngineBase.scene_builder`).

    ``target``: ``"module:function"``, imported only when a system runs (declaring it imports
    nothing), of a function::

        simulate_system(scenario, integrator, dt, nstep, save_every, **settings) -> SystemResult

    (the contract and :class:`~references.engines.system.SystemResult` are in
    :mod:`references.engines.system`); ``settings``: the names of the settings it takes (a
    scenario file's ``[engine_settings.<engine>]``; any other name is refused before a run);
    ``force_elements``: the builder applies a scenario's force elements (``[[torques]]``,
    ``[[springs]]``, :mod:`scenarios.force_elements`); a builder that does not declare it is
    ``unsupported`` on such a scenario, never run without them."""

    target: str
    settings: tuple[str, ...] = ()
    force_elements: bool = False

    def __post_init__(self):
        module, _, func = self.target.partition(":")
        if not module or not func.isidentifier():
            raise ValueError(f"SceneBuilder target {self.target!r}: expected 'module:function'")
        object.__setattr__(self, "settings", tuple(self.settings))

    def load(self) -> Callable:
        """The builder function (imports its module)."""
        module, _, func = self.target.partition(":")
        return getattr(importlib.import_module(module), func)


def _check_slugs(owner: type, integrators) -> None:
    """Two integrators of ``owner`` with the same typed name are a ValueError."""
    slugs: dict[str, str] = {}
    for integ in integrators:
        prev = slugs.setdefault(integ.slug, integ.name)
        if prev != integ.name:
            raise ValueError(
                f"{owner.__name__}: integrators {prev!r} and {integ.name!r} have the same "
                f"typed name {integ.slug!r} (references.engines.slug); rename one"
            )


class LazyIntegrators:
    """An adapter's ``integrators`` made by ``make()`` the first time they are asked for, for
    an adapter whose list comes from a package that is slow to import (the director's, from
    director_model): a command imports every adapter before it starts its workers' fork
    server (reports.suite.run: the default engines, what the workers preload), and that
    import then costs nothing of the package's."""

    def __init__(self, make):
        self.make = make
        self.value: tuple[Integrator, ...] | None = None
        self.owner: type | None = None

    def __set_name__(self, owner: type, name: str) -> None:
        self.owner = owner

    def __get__(self, obj, cls=None) -> tuple[Integrator, ...]:
        if self.value is None:
            value = tuple(self.make())
            _check_slugs(self.owner or cls, value)
            self.value = value
        return self.value


class EngineBase(ABC):
    """What the runner needs of anything that produces trajectories: a name, integrators, a
    version, and :meth:`run`. :class:`Engine` (an engine adapter) implements :meth:`run` with
    the shared loop; the exact reference (:mod:`references.engines.exact.adapter`) implements
    it by evaluating closed forms."""

    name: ClassVar[str]
    integrators: ClassVar[tuple[Integrator, ...]]
    description: ClassVar[str] = ""
    #: the runs of one integrator share an expensive warm-up in a process (MJX compiles its
    #: step): a runner executes them one after another in one worker instead of spreading them
    bundle_runs: ClassVar[bool] = False
    #: what the first run in a process compiles before it steps ("" if nothing), shown by the
    #: progress display while it lasts (per integrator when ``bundle_runs``)
    warm_up: ClassVar[str] = ""
    #: what the first run of a system of bodies in a process compiles ("" if nothing), when
    #: it is not the single body's ``warm_up``; a runner never compiles one warm-up in two
    #: workers at once (reports.run.parallel)
    system_warm_up: ClassVar[str] = ""
    #: what the first run of a contact scene in a process compiles ("" if nothing), when it
    #: is neither of the above (the same rule)
    contact_warm_up: ClassVar[str] = ""
    #: this engine's rows are the reference the others are measured against (the scenario's
    #: exact or high-accuracy solution), not a configuration under test: tables and figures
    #: show it as the floor of the measurement and comparisons between engines leave it out
    is_reference: ClassVar[bool] = False
    #: the engine computes on threads of its own (XLA's), not only on the calling thread: a
    #: run's CPU time is read from the process's clock rather than the thread's
    #: (references.engines.timing)
    threaded: ClassVar[bool] = False
    #: :meth:`run_batch` steps its members together in one call (an ensemble of one
    #: configuration is then one task), rather than the default's loop over :meth:`run`
    batched: ClassVar[bool] = False
    #: the builder that runs this engine's systems of bodies, or None: the engine runs single
    #: bodies only, and a system's runs on it are ``unsupported`` with that reason
    scene_builder: ClassVar[SceneBuilder | None] = None
    #: modules a runner's local workers may import before they fork (their import starts no
    #: thread and initialises no device), so that each worker starts with them imported
    #: (reports.run.parallel); e.g. JAX for MJX
    preload: ClassVar[tuple[str, ...]] = ()
    #: why this engine cannot be used at all, "" when it can: the reason of the stand-in that
    #: replaces an adapter whose import failed (:func:`references.engines.get_engine`)
    broken: ClassVar[str] = ""

    @classmethod
    @abstractmethod
    def version(cls) -> str:
        """The engine's version string; raises :class:`EngineUnavailable` if not installed."""

    @classmethod
    def availability(cls) -> str | None:
        """None if the engine can run here, else a message saying why not and how to fix it."""
        try:
            cls.version()
        except EngineUnavailable as exc:
            return str(exc)
        return None

    @classmethod
    def default_suite_exclusion(cls) -> str | None:
        """None when the engine belongs in the default suite on this machine, else why it is
        left out (a sentence: the runner lists it with the flag that adds it). Asked without
        running the engine; the default: None."""
        return None

    #: the Python distributions (pip names) whose versions make up the engine's version
    #: (:meth:`version_of`), e.g. ("mujoco",); empty for an engine that ships with the suite
    #: or that does not say. The CI pins them (reports/baselines/engines.txt).
    packages: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def version_of(cls, versions: Mapping[str, str | None]) -> str | None:
        """The engine's version string given the versions of its :attr:`packages` (None when
        one is missing). The default: the version of its one package."""
        if len(cls.packages) != 1:
            return None
        return versions.get(cls.packages[0])

    @classmethod
    def installed_version(cls) -> str | None:
        """What :meth:`version` returns, read from the installed packages' metadata
        (:func:`installed`) without importing the engine, or None when the metadata does not
        say it (a package installed without it, or not installed). The default: the
        :meth:`version_of` the installed :attr:`packages`."""
        if not cls.packages:
            return None
        versions = {p: installed(p) for p in cls.packages}
        return None if None in versions.values() else cls.version_of(versions)

    @classmethod
    def planned_version(cls) -> str:
        """The version under which a process that plans runs of this engine files them,
        without importing the engine where its packages' metadata says it
        (:meth:`installed_version`; an engine import costs up to seconds, paid again by each
        worker that runs the engine), else :meth:`version`. Raises :class:`EngineUnavailable`
        with :meth:`availability`'s message when the metadata says nothing and the engine
        does not import. The process that runs them compares it with :meth:`version`
        (reports.run.runner): a package whose import reports another version than its
        metadata, or that does not import, fails its runs there with the reason."""
        known = cls.installed_version()
        if known is not None:
            return known
        why = cls.availability()
        if why is not None:
            raise EngineUnavailable(why)
        return cls.version()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        own = cls.__dict__.get("integrators", ())
        if not isinstance(own, LazyIntegrators):  # a lazy list is checked when it is made
            _check_slugs(cls, own)

    @classmethod
    def integrator(cls, name: str) -> Integrator:
        """The integrator called ``name``, by its display name or its slug, in any case; an
        importer configuration of one ("RK4 (as loaded)",
        :func:`references.engines.importers.variant`) is that integrator under that name."""
        for integ in cls.integrators:
            if integ.slug == slug(name):
                return integ
        from references.engines import importers

        for integ in cls.integrators:
            for v in importers.variants(cls.name, [integ.name]):
                if slug(v) == slug(name):
                    return dataclasses.replace(integ, name=v, default=False)
        names = ", ".join(i.slug for i in cls.integrators)
        raise Unsupported(f"engine {cls.name!r} has no integrator {name!r}; it offers: {names}")

    def check_supported(self, scenario, integrator: Integrator) -> None:  # noqa: B027
        """Raise :class:`Unsupported` with the reason if this scenario/integrator pair cannot
        be represented. The default accepts everything."""

    @abstractmethod
    def run(
        self,
        scenario,
        integrator: str,
        dt: float,
        t_end: float | None = None,
        save_every: int | None = None,
        progress: Callable[[float], None] | None = None,
        recorder: Recorder | None = None,
        accuracy: float | None = None,
    ) -> RunOutput:
        """Run ``scenario`` with ``integrator`` at step ``dt`` (see :meth:`Engine.run`)."""

    def run_batch(
        self,
        members: Sequence,
        integrator: str,
        dt: float,
        t_end: float,
        save_every: int,
    ) -> list[RunOutput | EngineError]:
        """Run ``members`` (scenarios that differ only in their initial state) with one
        configuration, each from t = 0 to ``t_end`` at step ``dt``, saving every
        ``save_every`` steps.

        Returns one entry per member, in order: its :class:`RunOutput`, or the
        :class:`EngineError` that stopped it (a :class:`Diverged` carries the output up to
        its last good state), so that one failed member never loses the others. Raises
        :class:`EngineError` when the whole batch is refused before any member runs (an
        unknown integrator, a model the engine refuses). The default runs the members one
        after another through :meth:`run`; an engine that steps many bodies in one call
        (``batched``) overrides it."""
        self.integrator(integrator)  # an unknown integrator refuses the whole batch
        out: list[RunOutput | EngineError] = []
        for member in members:
            try:
                out.append(self.run(member, integrator, dt, t_end, save_every))
            except EngineError as exc:
                out.append(exc)
        return out


def installed(distribution: str) -> str | None:
    """The version of the installed ``distribution`` (its package metadata, read without
    importing it: ~2 ms), or None if it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return None


class Engine(EngineBase):
    """Interface of an engine adapter (see the module docstring for what to implement)."""

    #: mistakes specific to this engine that the conformance kit plants to show that the run
    #: refuses them (:func:`references.engines.conformance.check_mistakes`): name ->
    #: (plant(ctx), applied right after :meth:`build`; the kinds of body it applies to,
    #: "free" and/or "pivoted"), e.g. a default that distorts the experiment left on
    plantable: ClassVar[Mapping[str, tuple[Callable[[RunContext], None], tuple[str, ...]]]] = {}
    #: the adapter implements :meth:`read_raw` and :meth:`states_from_raw`, with which the
    #: default :meth:`advance_saving` copies state vectors and converts them once per block
    saves_raw: ClassVar[bool] = False

    # -- what adapters implement -----------------------------------------------------------
    @abstractmethod
    def build(self, ctx: RunContext) -> None:
        """Build the engine's model of ``ctx.model`` for ``ctx.integrator`` and step
        ``ctx.dt``; store what the other methods need in ``ctx.handle``."""

    @abstractmethod
    def read_model(self, ctx: RunContext) -> ModelReadback:
        """What the built model holds, read back from the engine."""

    def settings(self, ctx: RunContext) -> dict:
        """Every setting changed from the engine's defaults, name -> value (recorded)."""
        return {}

    @abstractmethod
    def set_state(self, ctx: RunContext, state: cv.BodyState) -> None:
        """Write ``state`` (the suite's convention) into the engine."""

    @abstractmethod
    def read_state(self, ctx: RunContext) -> cv.BodyState:
        """The engine's current state in the suite's convention."""

    @abstractmethod
    def native_quantities(self, ctx: RunContext) -> dict:
        """The engine's own view of its current state, computed by the engine:
        ``{"energy": E, "angular momentum": L (3,), "rotation": R (3, 3)}`` and, where the
        engine computes it, ``"COM velocity": v (3,)``. L in world axes about the centre of
        mass (free body) or the pivot; E = T + V with V = -m g . x_G."""

    def advance(self, ctx: RunContext, k: int) -> None:
        """Take ``k`` steps with the engine's own integrator (``stepping="native"``)."""
        raise NotImplementedError(f"{self.name}: no native stepping")

    def advance_saving(self, ctx: RunContext, steps: list[int]) -> cv.BodyState:
        """Advance by each count in ``steps`` in turn and return the block of states after
        each (a BodyState of stacked arrays, (k, 3), (k, 3), (k, 3, 3), (k, 3)). The default
        calls :meth:`advance`, copies the engine's state with :meth:`read_raw` and converts
        the block at once with :meth:`states_from_raw` where the adapter has them
        (:attr:`saves_raw`; a copy of a state vector costs a microsecond, its conversion tens:
        done once per block, vectorised), else reads each state with :meth:`read_state`. An
        engine whose loop runs in compiled code may save them all in one call (the director
        model does)."""
        if not self.saves_raw:
            states = []
            for k in steps:
                self.advance(ctx, k)
                states.append(self.read_state(ctx))
            return cv.stack_states(states)
        rows = []
        for k in steps:
            self.advance(ctx, k)
            rows.append(self.read_raw(ctx))
        return self.states_from_raw(ctx, np.array(rows))

    def read_raw(self, ctx: RunContext) -> np.ndarray:
        """Optional (with :meth:`states_from_raw` and :attr:`saves_raw`): a copy of the
        engine's state vector (any layout the adapter's :meth:`states_from_raw` reads)."""
        raise NotImplementedError

    def states_from_raw(self, ctx: RunContext, raw: np.ndarray) -> cv.BodyState:
        """Optional: the block of states of rows of :meth:`read_raw` (vectorised)."""
        raise NotImplementedError

    def forward_dynamics(self, ctx: RunContext, state: cv.BodyState):
        """(dW/dt (3,) body axes, dv_G/dt (3,) world axes) of ``state``, from the engine's
        forward dynamics (``stepping="rkmk4"``); for a ball joint the second entry is
        ignored."""
        raise NotImplementedError(f"{self.name}: no forward-dynamics call")

    def packed_dynamics(self, ctx: RunContext) -> Callable[[np.ndarray, np.ndarray], None]:
        """The function ``fd(z, acc)`` the compiled RKMK4
        (:class:`~references.engines.liegroup.CompiledRKMK4Stepper`) calls at every stage of
        the run ``ctx``, made once per run: ``z`` the flat stage state (13,) = (unit quaternion
        w, x, y, z; x_G (3,) world; W (3,) body axes; v_G (3,) world), ``acc`` (6,) filled in
        place with (dW/dt, dv_G/dt), zeros for dv_G/dt of a pivoted body. The default's
        ``fd`` builds a ``BodyState`` from ``z`` and calls :meth:`forward_dynamics`. An
        adapter may return one that hands ``z`` to its engine directly, with its engine's
        calls and buffers bound here; it must time only the engine's calls on ``ctx.clock``,
        as :meth:`forward_dynamics` does. Not called when :meth:`staged_dynamics` gives the
        stages (Pinocchio, DART)."""
        model, forward_dynamics = ctx.model, self.forward_dynamics
        pivoted = model.pivoted

        def fd(z: np.ndarray, acc: np.ndarray) -> None:
            dW, a = forward_dynamics(ctx, unpack_state(model, z))
            acc[0:3] = dW
            acc[3:6] = 0.0 if pivoted else a

        return fd

    def staged_dynamics(self, ctx: RunContext):
        """None, or the engine bound for the compiled RKMK4 with its packing compiled into
        the stages (a :class:`~references.engines.liegroup.StagedDynamics`, made once per
        run), which the stepper then uses instead of :meth:`packed_dynamics`: per stage one
        compiled call and the engine's, for engines whose calls take a microsecond or two
        (Pinocchio, DART). Its ``call`` must time only the engine's calls on ``ctx.clock``."""
        return None

    def guard(self, ctx: RunContext, state: cv.BodyState) -> str | None:
        """A reason if the engine reached one of its own limits (e.g. a velocity clamp): the
        run then counts as diverged. Checked at every checkpoint."""
        return None

    def close(self, ctx: RunContext) -> None:  # noqa: B027 - optional hook
        """Release the engine's resources (called once, also after a failure)."""

    # -- the run ---------------------------------------------------------------------------
    def run(
        self,
        scenario,
        integrator: str,
        dt: float,
        t_end: float | None = None,
        save_every: int | None = None,
        progress: Callable[[float], None] | None = None,
        recorder: Recorder | None = None,
        accuracy: float | None = None,
    ) -> RunOutput:
        """Run ``scenario`` with ``integrator`` at step ``dt`` up to ``t_end`` (default: the
        scenario's), saving every ``save_every`` steps (default: the scenario's).

        ``progress``, if given, is called now and then with the fraction done (0..1).
        ``recorder`` (default: a :class:`Recorder` of the saved steps) receives the states.
        ``accuracy``: the target accuracy of an error-controlled (``adaptive``) integrator,
        required for those and refused for the others.
        Raises :class:`Diverged`, :class:`Unsupported`, :class:`EngineUnavailable` or
        :class:`EngineError`.
        """
        return run_loop(
            self, scenario, integrator, dt, t_end, save_every, progress, recorder, accuracy
        )
