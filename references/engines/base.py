"""The engine interface: an adapter per engine, and the run loop they all share.

An adapter (a subclass of :class:`Engine`) provides only what differs between engines:

==========================  ===============================================================
``build(ctx)``              the engine's model of ``ctx.model`` (a :class:`BodyModel`), with
                            the engine's distorting defaults switched off; stored in
                            ``ctx.handle``
``read_model(ctx)``         what the built model holds, read back from the engine
                            (:class:`ModelReadback`); the base compares it with the scenario
``settings(ctx)``           the settings changed from the engine's defaults (recorded)
``set_state(ctx, state)``   write a :class:`~references.conventions.BodyState` (the suite's
                            convention) into the engine, converting in
                            :mod:`references.conventions`
``read_state(ctx)``         the engine's current state as a ``BodyState``
``native_quantities(ctx)``  the engine's OWN energy, angular momentum, rotation (and COM
                            velocity where it has one), computed by the engine's code from its
                            own state; they check that the engine holds the state we meant
``advance(ctx, k)``         k steps with the engine's own integrator (``stepping="native"``)
``forward_dynamics``        accelerations of a state, for the suite's RKMK4
(ctx, state)                (``stepping="rkmk4"``, :mod:`references.engines.liegroup`)
``guard(ctx, state)``       optional: a reason if the engine hit one of its own limits
``close(ctx)``              optional: release the engine's resources
==========================  ===============================================================

:meth:`Engine.run` owns everything else, identically for every engine: the step plan, the
read-back of the model, the initial-state check through the engine's own quantities, the loop
(saves, chunks, progress, the stopwatch that separates time inside the engine's calls from the
suite's glue), the divergence checks and the conversion into the suite's
:class:`references.trajectory.Trajectory`. Adapters never compute metrics.

Failures are exceptions of the classes below with a ``status``; the runner turns each into a
result row with that status and the message, so messages say what happened and what to do.
"""

from __future__ import annotations

import math
import os
import re
import sys
import tempfile
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from references import conventions as cv
from references.engines.liegroup import CompiledRKMK4Stepper
from references.errors import (
    Diverged,
    EngineError,
    EngineUnavailable,
    StepFailure,
    Unsupported,
)
from references.trajectory import Trajectory, energy_parts

__all__ = [
    "CHUNK",
    "DIVERGENCE_ENERGY",
    "FAMILIES",
    "READBACK_RTOL",
    "BodyModel",
    "Clock",
    "Diverged",
    "Engine",
    "EngineBase",
    "EngineError",
    "EngineUnavailable",
    "Family",
    "Integrator",
    "ModelReadback",
    "Recorder",
    "RunContext",
    "RunOutput",
    "StepFailure",
    "Unsupported",
    "import_engine",
    "register_family",
    "slug",
    "step_plan",
]

# -- integrator families ----------------------------------------------------------------------


@dataclass(frozen=True)
class Family:
    """A class of integrators that share an algorithm (so engines running it should agree),
    with the default verdict tolerances its members are held to (metric -> bound; see
    :mod:`reports.verdicts` for the defaults every family shares)."""

    name: str
    description: str
    tolerances: Mapping[str, float] = field(default_factory=dict)


#: Integrator families, name -> :class:`Family`. Engines from other packages may add their own
#: with :func:`register_family` (families are data, not code).
FAMILIES: dict[str, Family] = {}


def register_family(family: Family) -> Family:
    """Add ``family`` to :data:`FAMILIES` (idempotent for an equal family; a different family
    under a taken name is an error)."""
    old = FAMILIES.get(family.name)
    if old is not None and old != family:
        raise ValueError(f"integrator family {family.name!r} is already registered differently")
    FAMILIES[family.name] = family
    return family


for _fam in (
    Family("semi-implicit Euler", "first order, gyroscopic term explicit"),
    Family("implicit gyroscopic", "first order, gyroscopic term linearised implicitly"),
    Family("4th-order Lie-group", "explicit Runge-Kutta(-Munthe-Kaas) class, order 4 on SO(3)"),
    Family(
        "structure-preserving director",
        "symplectic / energy-momentum schemes of the director model; they keep the directors "
        "orthonormal to round-off",
        # every scheme of the family enforces the position constraints at the nodes (docs
        # docs/numerics.md section 3): 1e-10 is round-off accumulated over ~1e5 steps with margin
        {"orthonormality_max": 1e-10},
    ),
    Family(
        "exact",
        "closed-form or high-accuracy reference solution",
        {"energy_drift_max": 1e-9, "momentum_drift_max": 1e-9, "orthonormality_max": 1e-12},
    ),
):
    register_family(_fam)


#: Energy error, relative to the scenario's energy scale, beyond which a run has diverged.
DIVERGENCE_ENERGY = 1.0

#: Largest number of steps between two checks of the state (bounds how late a divergence is
#: seen, and the resolution of ``t_diverged``).
CHUNK = 1000

#: Read-back tolerance of the model checks, a few ulp: engines may store a number through some
#: arithmetic (with pin 4.1.0 and pybullet 3.2.7 an inertia of 0.9 reads back as
#: 0.8999999999999999).
READBACK_RTOL = 1e-15


# -- what is built ----------------------------------------------------------------------------


def slug(name: str) -> str:
    """The form of an integrator's name a shell can type, the one rule for every engine: lower
    case, and every run of characters other than letters, digits, ``_`` and ``.`` one ``-``,
    none at either end ("semi-implicit Euler" -> ``semi-implicit-euler``, "runge_kutta5
    (error-controlled)" -> ``runge_kutta5-error-controlled``, "RK4 (float32)" ->
    ``rk4-float32``). The command line matches a name given in either form through it, so
    matching ignores case; an engine's integrators have distinct slugs (checked when the
    adapter class is defined)."""
    return re.sub(r"[^a-z0-9_.]+", "-", name.lower()).strip("-")


@dataclass(frozen=True)
class Integrator:
    """An integrator an engine offers, named for what it is.

    ``stepping``: "native" (the engine's own time stepping, :meth:`Engine.advance`) or "rkmk4"
    (the suite's Runge-Kutta-Munthe-Kaas around :meth:`Engine.forward_dynamics`).
    ``evals_per_step``: dynamics evaluations per step (forward dynamics, or torque evaluations
    of the director schemes), None if it varies (error-controlled integrators report theirs).
    ``options``: engine-specific settings of this integrator (recorded with the run).
    ``ours``: the time loop is the suite's code around the engine's dynamics even though the
    adapter runs it (Pinocchio has no integrator of its own); cost tables label such
    configurations, since their cost includes our Python.
    ``tolerances``: verdict bounds this integrator promises beyond its family's (metric ->
    bound), e.g. RATTLE's conservation of angular momentum to round-off.
    ``adaptive``: an error-controlled integrator, run at target accuracies (``accuracy`` of
    :meth:`Engine.run`); ``dt`` is then the interval of the checkpoints, not a step, and the
    adapter reports the steps it took (``ctx.stats``, ``ctx.nevals``).
    ``default``: part of the default suite; an engine with many configurations keeps the
    ones that answer the suite's questions at a cost that fits, the rest run on request
    (``director-bench run --full`` or ``--integrators``).
    ``sweep_halvings``: halvings of the smallest step of a scenario's dt sweep run beyond the
    sweep in a suite (not with explicit steps or without the sweep): for an integrator cheap
    enough to follow its error down to the round-off floor (the director model's high-order
    compositions), whose work-precision curve would otherwise stop above it.
    """

    name: str
    family: str
    order: int
    description: str
    stepping: str = "native"
    evals_per_step: float | None = 1.0
    options: Mapping[str, Any] = field(default_factory=dict)
    ours: bool = False
    tolerances: Mapping[str, float] = field(default_factory=dict)
    adaptive: bool = False
    default: bool = True
    sweep_halvings: int = 0

    def __post_init__(self):
        if self.family not in FAMILIES:
            raise ValueError(
                f"integrator {self.name!r}: unknown family {self.family!r}; register it with "
                "references.engines.register_family"
            )
        if self.stepping not in ("native", "rkmk4"):
            raise ValueError(f"integrator {self.name!r}: stepping must be 'native' or 'rkmk4'")

    @property
    def suite_integrated(self) -> bool:
        """True when the time integration is the suite's code around the engine's dynamics."""
        return self.ours or self.stepping != "native"

    @property
    def slug(self) -> str:
        """The name as a shell types it (:func:`slug`); ``name`` is the display name."""
        return slug(self.name)


@dataclass(frozen=True)
class BodyModel:
    """The one rigid body an adapter builds, in the engine-neutral terms every engine has.

    ``joint``: "free" (a free body whose body frame is its principal centre-of-mass frame) or
    "ball" (a ball joint at the world origin, at the body frame's origin). ``com``: the centre
    of mass in the body frame, m (zeros for a free body, ``-pivot`` for a pivoted one).
    ``inertia``: principal moments about the centre of mass, body axes, kg m^2. ``gravity``
    (m/s^2, world axes), ``dt`` (s).
    """

    name: str
    mass: float
    inertia: np.ndarray
    com: np.ndarray
    joint: str
    gravity: np.ndarray
    dt: float

    @classmethod
    def of(cls, scenario, dt: float) -> BodyModel:
        pivoted = scenario.pivot is not None
        return cls(
            name=scenario.name or "body",
            mass=float(scenario.mass),
            inertia=np.array(scenario.inertia, dtype=float),
            com=-np.asarray(scenario.pivot, dtype=float) if pivoted else np.zeros(3),
            joint="ball" if pivoted else "free",
            gravity=np.array(scenario.gravity, dtype=float),
            dt=float(dt),
        )

    @property
    def pivoted(self) -> bool:
        return self.joint == "ball"

    def state_from_rotation(self, R, W) -> cv.BodyState:
        """The full state of a pivoted body from its rotation and body rates:
        x_G = R com, v_G = R (W x com)."""
        R = np.asarray(R, dtype=float)
        W = np.asarray(W, dtype=float)
        c0, c1, c2 = self.com
        w0, w1, w2 = W
        # W x com written out: numpy's cross costs tens of microseconds on 3-vectors, and this
        # runs at every saved state of a pivoted body
        u = np.array([w1 * c2 - w2 * c1, w2 * c0 - w0 * c2, w0 * c1 - w1 * c0])
        return cv.BodyState(R @ self.com, R @ u, R, W)


@dataclass
class ModelReadback:
    """What a built model holds, read back from the engine (SI units, body axes):
    ``mass``, ``inertia`` (3x3 tensor about the centre of mass), ``com`` (body frame),
    ``joint`` ("free" or "ball"), ``gravity``, ``dt``; ``extra`` maps the names of the
    engine's own settings to (value read back, value required[, absolute tolerance]), e.g.
    joint damping (0, 0)."""

    mass: float
    inertia: np.ndarray
    com: np.ndarray
    joint: str
    gravity: np.ndarray
    dt: float
    extra: dict[str, tuple] = field(default_factory=dict)


class Clock:
    """Accumulates the wall time spent inside an engine's own calls (``with ctx.clock:``)."""

    __slots__ = ("elapsed", "_t0")

    def __init__(self):
        self.elapsed = 0.0
        self._t0 = 0.0

    def __enter__(self):
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.elapsed += time.perf_counter() - self._t0
        return False


@dataclass
class RunContext:
    """One run's working state, passed to every adapter method. Adapters keep whatever their
    engine needs in ``handle`` (and may add attributes)."""

    scenario: Any
    model: BodyModel
    integrator: Integrator
    dt: float
    #: the run's horizon, s
    t_end: float = 0.0
    clock: Clock = field(default_factory=Clock)
    #: the process's CPU time over the stepping so far, s (beside the wall time the loop sums)
    cpu_time: float = 0.0
    handle: Any = None
    #: dynamics evaluations so far (adapters with a varying count add to it)
    nevals: float = 0.0
    #: target accuracy of an error-controlled integrator (None for a fixed step)
    accuracy: float | None = None
    #: what an adaptive integrator reports: "steps taken", "steps rejected", ...
    stats: dict = field(default_factory=dict)
    #: step -> velocity-constraint residual ||D^T D' + D'^T D||_F of the engine's own
    #: director velocities, for adapters that have them (the director model); other states
    #: get the residual of D' = R hat(W)
    residuals: dict = field(default_factory=dict)
    #: the family of the algorithm actually run, where it differs from the integrator's
    #: declared one for this model (MuJoCo's implicitfast on a ball joint is its Euler)
    family: str | None = None
    #: what the engine's native code wrote to the standard error while stepping
    stderr: NativeStderr | None = None


class NativeStderr:
    """What an engine's native code writes to the standard error (file descriptor 2) while
    it steps, kept for the run's record instead of the terminal.

    A diverging state makes some engines print a warning at every step (DART 6.20: three
    lines a step once a state is non-finite, until the run loop's next checkpoint stops the
    run); a default suite would flood the terminal with thousands of lines. While a block of
    steps runs, file descriptor 2 points to a temporary file; afterwards the lines are counted
    and the first and last kept (:meth:`summary`, recorded in the run's settings). Only on the
    main thread: redirecting a process-wide descriptor from several threads at once (a Dask
    worker's task threads) could leave it pointing at a closed file, so there the writes go
    where they always went (the worker's log)."""

    def __init__(self) -> None:
        self.lines = 0
        self.first = ""
        self.last = ""
        self._file = None
        self._saved: int | None = None

    def __enter__(self) -> NativeStderr:
        if threading.current_thread() is not threading.main_thread():
            return self
        if self._file is None:
            self._file = tempfile.TemporaryFile()
        sys.stderr.flush()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is None:
            return
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._saved = None
        f = self._file
        if f.tell() or os.fstat(f.fileno()).st_size:
            f.seek(0)
            text = f.read().decode("utf-8", "replace")
            f.seek(0)
            f.truncate()
            lines = [_plain(x) for x in text.splitlines() if x.strip()]
            if lines:
                self.first = self.first or lines[0]
                self.last = lines[-1]
                self.lines += len(lines)

    def summary(self) -> str | None:
        """The record of what was written, or None if nothing was."""
        if not self.lines:
            return None
        out = f"{self.lines} line(s) while stepping; first: {self.first}"
        return out + (f"; last: {self.last}" if self.lines > 1 else "")

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _plain(line: str) -> str:
    """A terminal line without its ANSI colour codes."""
    return re.sub(r"\x1b\[[0-9;]*m", "", line).strip()


@dataclass
class RunOutput:
    """What one run returns: the trajectory in the suite's schema, the number of steps taken,
    the wall time of the stepping (model building excluded) split into the time inside the
    engine's own calls and the suite's glue around them, the dynamics evaluations per step,
    and every setting changed from the engine's defaults (recorded with the results)."""

    trajectory: Trajectory
    nstep: int
    wall_time_s: float
    engine_time_s: float
    evals_per_step: float
    settings: dict[str, object] = field(default_factory=dict)
    #: an adaptive integrator's statistics ("steps taken", "steps rejected")
    stats: dict[str, float] = field(default_factory=dict)
    #: the integrator family of the algorithm that ran (see RunContext.family)
    family: str = ""
    #: the process's CPU time over the stepping (all its threads): on a busy machine less than
    #: the wall time, by the time the process waited for a CPU
    cpu_time_s: float = math.nan

    @property
    def glue_time_s(self) -> float:
        return max(self.wall_time_s - self.engine_time_s, 0.0)


def step_plan(dt: float, t_end: float, save_every: int) -> tuple[int, np.ndarray]:
    """Number of steps and the step indices to save (0, s, 2s, ... and always the last).

    ``t_end`` must be a whole number of steps to within 1e-9 relative; anything else is a
    ``ValueError`` rather than a silently shortened or lengthened horizon. The rule is
    director_model's (:func:`director_model.step_plan`): every engine, the reference
    integrator and the scenario validation share one definition.
    """
    from director_model import step_plan as _plan

    return _plan(dt, t_end, save_every)


# -- recording --------------------------------------------------------------------------------


class Recorder:
    """Receives the states of a run, block by block (:func:`conventions.block_row`: stacked
    arrays), and keeps those at the saved step indices. A subclass with ``every_step = True``
    sees every step (streaming metrics over long horizons keep O(1) memory that way, see
    :mod:`reports.streaming`)."""

    every_step = False

    def __init__(self, saves: np.ndarray):
        self.saves = np.asarray(saves, dtype=np.int64)
        self.steps: list[np.ndarray] = []
        self.blocks: list[cv.BodyState] = []
        self.cv: list[np.ndarray] = []
        #: the run's residuals by step (RunContext.residuals), consumed as states arrive
        self.residuals: dict = {}

    def _residuals(self, steps) -> np.ndarray:
        if not self.residuals:
            return np.full(len(steps), math.nan)
        return np.array([self.residuals.pop(int(s), math.nan) for s in steps])

    def record_block(self, steps, block: cv.BodyState) -> None:
        steps = np.asarray(steps, dtype=np.int64)
        res = self._residuals(steps)
        keep = np.isin(steps, self.saves)
        if keep.all():
            self.steps.append(steps)
            self.blocks.append(block)
            self.cv.append(res)
        elif keep.any():
            self.steps.append(steps[keep])
            self.blocks.append(cv.BodyState(*(a[keep] for a in block)))
            self.cv.append(res[keep])

    def trajectory(self, scenario, dt: float) -> Trajectory:
        if not self.blocks:
            return block_trajectory(scenario, np.zeros(0), None, np.zeros(0))
        steps = np.concatenate(self.steps)
        block = cv.BodyState(*(np.concatenate(parts) for parts in zip(*self.blocks, strict=True)))
        return block_trajectory(scenario, steps * dt, block, np.concatenate(self.cv))


def block_trajectory(scenario, t, block, residuals) -> Trajectory:
    """The trajectory of a block of states; ``residuals`` the engine's own velocity-constraint
    residuals (NaN where it has none: then computed from R and W)."""
    t = np.asarray(t, dtype=float)
    if block is None or not len(t):
        z = np.zeros((0, 3))
        return Trajectory.from_states(scenario, t, z, z, np.zeros((0, 3, 3)), z)
    x, v, R, W = block
    res = np.asarray(residuals, dtype=float)
    own = None
    if np.any(np.isfinite(res)):
        from references.trajectory import velocity_constraint

        own = np.where(np.isfinite(res), res, velocity_constraint(R, W))
    return Trajectory.from_states(scenario, t, x, v, R, W, own)


# -- the interface ----------------------------------------------------------------------------


class EngineBase(ABC):
    """What the runner needs of anything that produces trajectories: a name, integrators, a
    version, and :meth:`run`. :class:`Engine` (an engine adapter) implements :meth:`run` with
    the shared loop; the exact reference (:mod:`references.engines.exact`) implements it by
    evaluating closed forms."""

    name: ClassVar[str]
    integrators: ClassVar[tuple[Integrator, ...]]
    description: ClassVar[str] = ""
    #: the runs of one integrator share an expensive warm-up in a process (MJX compiles its
    #: step): a runner executes them one after another in one worker instead of spreading them
    bundle_runs: ClassVar[bool] = False
    #: what the first run in a process compiles before it steps ("" if nothing), shown by the
    #: progress display while it lasts (per integrator when ``bundle_runs``)
    warm_up: ClassVar[str] = ""

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

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        slugs: dict[str, str] = {}
        for integ in cls.__dict__.get("integrators", ()):
            prev = slugs.setdefault(integ.slug, integ.name)
            if prev != integ.name:
                raise ValueError(
                    f"{cls.__name__}: integrators {prev!r} and {integ.name!r} have the same "
                    f"typed name {integ.slug!r} (references.engines.base.slug); rename one"
                )

    @classmethod
    def integrator(cls, name: str) -> Integrator:
        """The integrator called ``name``, by its display name or its slug, in any case."""
        for integ in cls.integrators:
            if integ.slug == slug(name):
                return integ
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


class Engine(EngineBase):
    """Interface of an engine adapter (see the module docstring for what to implement)."""

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
        the block at once with :meth:`states_from_raw` where the adapter has them (a copy of
        a state vector costs a microsecond, its conversion tens: done once per block,
        vectorised), else reads each state with :meth:`read_state`. An engine whose loop runs
        in compiled code may save them all in one call (the director model does)."""
        if type(self).states_from_raw is Engine.states_from_raw:
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
        """Optional: a copy of the engine's state vector (any layout the adapter's
        :meth:`states_from_raw` reads)."""
        raise NotImplementedError

    def states_from_raw(self, ctx: RunContext, raw: np.ndarray) -> cv.BodyState:
        """Optional: the block of states of rows of :meth:`read_raw` (vectorised)."""
        raise NotImplementedError

    def forward_dynamics(self, ctx: RunContext, state: cv.BodyState):
        """(dW/dt (3,) body axes, dv_G/dt (3,) world axes) of ``state``, from the engine's
        forward dynamics (``stepping="rkmk4"``); for a ball joint the second entry is
        ignored."""
        raise NotImplementedError(f"{self.name}: no forward-dynamics call")

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
        integ = self.integrator(integrator)
        if integ.adaptive != (accuracy is not None):
            raise Unsupported(
                f"{self.name} {integ.name}: "
                + (
                    "an error-controlled integrator needs a target accuracy"
                    if integ.adaptive
                    else "a fixed-step integrator takes no target accuracy"
                )
            )
        self.check_supported(scenario, integ)
        t_end = scenario.t_end if t_end is None else t_end
        save_every = scenario.save_every if save_every is None else save_every
        nstep, saves = step_plan(dt, t_end, save_every)
        ctx = RunContext(scenario, BodyModel.of(scenario, dt), integ, float(dt), float(t_end))
        ctx.accuracy = None if accuracy is None else float(accuracy)
        ctx.stderr = NativeStderr()
        rec = recorder if recorder is not None else Recorder(saves)
        rec.residuals = ctx.residuals
        try:
            self.build(ctx)
            check_readback(self.name, self.read_model(ctx), ctx.model)
            stepper = _stepper(self, ctx)
            stepper.start(initial_state(scenario))
            check_initial(self, ctx, scenario)
            wall, steps_done = _loop(self, ctx, stepper, nstep, saves, rec, progress)
            settings = {**self.settings(ctx), "integrator": integ.name, "timestep": float(dt)}
            if ctx.accuracy is not None:
                settings["target accuracy"] = ctx.accuracy
        finally:
            self.close(ctx)
            ctx.stderr.close()
        out = _output(ctx, rec, steps_done, wall, settings)
        if progress is not None:
            progress(1.0)
        return out


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


def check_initial(engine: Engine, ctx: RunContext, scenario) -> dict:
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

    def __init__(self, engine: Engine, ctx: RunContext):
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


def _stepper(engine: Engine, ctx: RunContext):
    if ctx.integrator.stepping == "native":
        return _NativeStepper(engine, ctx)
    return CompiledRKMK4Stepper(engine, ctx)


# -- the loop ---------------------------------------------------------------------------------


def _blocks(nstep: int, saves: np.ndarray, every_step: bool):
    """The checkpoints (steps at which the state is read) in blocks that end at multiples of
    CHUNK: every step, or the saves and at least every CHUNK steps. Generated lazily (a long
    horizon has many)."""
    block: list[int] = []
    if every_step:
        points = range(1, nstep + 1)
    else:
        points = sorted(set(int(s) for s in saves if s > 0) | set(range(CHUNK, nstep, CHUNK)))
    for p in points:
        block.append(p)
        if p % CHUNK == 0 or p == nstep:
            yield block
            block = []
    if block:
        yield block


#: the separately conserved parts of the energy, as divergence messages name them
_ENERGY_PART = {"total": "energy", "rot": "rotational energy", "trans": "translational energy"}


def _first_divergence(engine, ctx, block, energy0) -> tuple[int, str] | None:
    """(index of the first diverged state of a block, why), or None: a non-finite state or
    an energy error beyond DIVERGENCE_ENERGY of its scale (vectorised over the block): of the
    total energy, and for a free body of its rotational and its translational energy apart,
    each against its own scale (:attr:`Scenario.energy_scales`), so that neither hides the
    other; or the engine's own limit (:meth:`Engine.guard`, on the block's last state).
    ``energy0``: the parts of the initial energy (:func:`energy_parts`)."""
    x, v, R, W = block
    finite = np.isfinite(x).all(1) & np.isfinite(v).all(1) & np.isfinite(W).all(1)
    finite &= np.isfinite(R).all((1, 2))
    scales = ctx.scenario.energy_scales
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
    first = stepper.state()
    rec.record_block([0], cv.BodyState(*(np.asarray(a)[None] for a in first)))
    wall = 0.0
    done = 0
    dt = ctx.dt
    for block in _blocks(nstep, saves, rec.every_step):
        steps = np.diff([done, *block]).tolist()
        try:
            with ctx.stderr:  # set by Engine.run, the only caller
                t0 = time.perf_counter()  # after the redirection is in place
                c0 = time.process_time()
                states = stepper.run(steps)
        except StepFailure as exc:
            wall += time.perf_counter() - t0
            ctx.cpu_time += time.process_time() - c0
            t_div, span = _failed_step(exc, done, block[-1], dt)
            kept = getattr(exc, "states", None)  # the checkpoints completed before it
            if kept is not None and len(kept[0]):
                _record_checked(engine, ctx, rec, block, kept, done, wall, energy0)
                done = block[len(kept[0]) - 1]
            raise _diverged(
                engine, ctx, rec, done, wall, t_div, f"{span} could not be taken: {exc}"
            ) from exc
        wall += time.perf_counter() - t0
        ctx.cpu_time += time.process_time() - c0
        _record_checked(engine, ctx, rec, block, states, done, wall, energy0)
        done = block[-1]
        if progress is not None:
            progress(done / nstep)
    return wall, done


def _record_checked(engine, ctx, rec, block, states, done, wall, energy0) -> None:
    """Record the states of the checkpoints ``block[:len(states)]`` up to the first diverged
    one, and raise :class:`Diverged` at that one if there is one."""
    dt = ctx.dt
    found = _first_divergence(engine, ctx, states, energy0)
    good = len(states[0]) if found is None else found[0]
    if good:
        rec.record_block(block[:good], cv.BodyState(*(a[:good] for a in states)))
    if found is not None:
        before = block[good - 1] if good else done
        span = f"between t = {before * dt:.6g} and t = {block[good] * dt:.6g} s"
        raise _diverged(engine, ctx, rec, before, wall, block[good] * dt, f"{found[1]} {span}")


def _failed_step(exc, done: int, last: int, dt: float) -> tuple[float, str]:
    """(t_diverged, what failed) of a :class:`StepFailure` raised while stepping from step
    ``done`` to ``last``: the time the failing step starts from, as the raiser gives it
    (``time``, or ``steps_taken`` in this call); without either, only the block is known and
    its end is the latest the failure can be."""
    t_fail = getattr(exc, "time", None)
    taken = getattr(exc, "steps_taken", None)
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
        cpu_time_s=float(ctx.cpu_time),
        evals_per_step=float(per),
        settings=settings,
        stats=dict(ctx.stats),
        family=ctx.family or ctx.integrator.family,
    )


# -- helpers for adapters ---------------------------------------------------------------------


def import_engine(module: str, label: str, pip_name: str):
    """Import an engine's Python package, or raise :class:`EngineUnavailable` saying how to
    install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - a broken install raises more than ImportError
        raise EngineUnavailable(
            f"{label} is not installed or does not import ({type(exc).__name__}: {exc}); "
            "install it with "
            f"`pip install {pip_name}` (or `pip install 'director-bench[engines]'`)"
        ) from exc
