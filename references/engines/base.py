"""The engine interface: one adapter per engine, selected by name from the registry.

An adapter turns a :class:`scenarios.model.Scenario` into the engine's own model, steps it with
one of the engine's integrators, and maps what it reads back into the suite's
:class:`references.trajectory.Trajectory` (energy and momentum recomputed by the suite). It
never computes metrics: those belong to :mod:`reports.metrics`, identical for every engine.

Failures are exceptions of the classes below; the runner turns each into a result row with a
status and the message, so messages must say what happened and what to do about it.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from references.trajectory import Trajectory

#: Integrator families used to group results in reports, so that readers see that the
#: algorithm matters more than the engine.
FAMILIES = {
    "semi-implicit Euler": "first order, gyroscopic term explicit",
    "implicit gyroscopic": "first order, gyroscopic term linearised implicitly",
    "4th-order Lie-group": "explicit Runge-Kutta-Munthe-Kaas class, order 4 on SO(3)",
    "structure-preserving director": "symplectic/energy-momentum schemes of the director model",
    "exact": "closed-form or high-accuracy reference solution",
}


class EngineError(Exception):
    """Base class; ``status`` is the value written to the results table."""

    status = "error"


class EngineUnavailable(EngineError):
    """The engine's Python package is not installed or does not import."""

    status = "unavailable"


class Unsupported(EngineError):
    """The scenario (or integrator) cannot be represented by this engine."""

    status = "unsupported"


class StepFailure(EngineError):
    """A step could not be taken (not solvable, diverged, non-finite state)."""

    status = "failed"


@dataclass(frozen=True)
class Integrator:
    """An integrator an engine offers, named for what it is."""

    name: str
    family: str
    order: int
    description: str

    def __post_init__(self):
        if self.family not in FAMILIES:
            raise ValueError(f"integrator {self.name!r}: unknown family {self.family!r}")


@dataclass
class RunOutput:
    """What one run returns: the trajectory in the suite's schema, the number of steps, the
    wall time of the stepping alone (model building excluded), and every setting the adapter
    changed from the engine's defaults (name -> value), recorded with the results."""

    trajectory: Trajectory
    nstep: int
    wall_time_s: float
    settings: dict[str, object] = field(default_factory=dict)


def step_plan(dt: float, t_end: float, save_every: int) -> tuple[int, np.ndarray]:
    """Number of steps and the step indices to save (0, s, 2s, ... and always the last).

    ``t_end`` must be a whole number of steps to within 1e-9 relative; anything else is an
    error (a ``ValueError``) rather than a silently shortened or lengthened horizon. The rule
    is director_model's (:func:`director_model.step_plan`), so that every engine, the
    reference integrator and the scenario validation share one definition.
    """
    from director_model import step_plan as _plan

    return _plan(dt, t_end, save_every)


class Engine(ABC):
    """Interface of an engine adapter.

    Subclasses set ``name`` and ``integrators`` and implement :meth:`version` and :meth:`_run`.
    The public :meth:`run` owns the bookkeeping (step plan, integrator lookup, support checks).
    """

    name: ClassVar[str]
    integrators: ClassVar[tuple[Integrator, ...]]
    description: ClassVar[str] = ""

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
    def integrator(cls, name: str) -> Integrator:
        for integ in cls.integrators:
            if integ.name == name:
                return integ
        names = ", ".join(i.name for i in cls.integrators)
        raise Unsupported(f"engine {cls.name!r} has no integrator {name!r}; it offers: {names}")

    def check_supported(self, scenario, integrator: str) -> None:  # noqa: B027 - optional hook
        """Raise :class:`Unsupported` with the reason if this scenario/integrator pair cannot
        be represented. The default accepts everything."""

    def run(
        self,
        scenario,
        integrator: str,
        dt: float,
        t_end: float | None = None,
        save_every: int | None = None,
        progress: Callable[[float], None] | None = None,
    ) -> RunOutput:
        """Run ``scenario`` with ``integrator`` at step ``dt`` up to ``t_end`` (default: the
        scenario's), saving every ``save_every`` steps (default: the scenario's).

        ``progress``, if given, is called now and then with the fraction done (0..1).
        """
        self.integrator(integrator)
        self.check_supported(scenario, integrator)
        t_end = scenario.t_end if t_end is None else t_end
        save_every = scenario.save_every if save_every is None else save_every
        nstep, saves = step_plan(dt, t_end, save_every)
        return self._run(scenario, integrator, dt, nstep, saves, progress)

    @abstractmethod
    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        """Take ``nstep`` steps of size ``dt``; save the states at step indices ``saves``."""


#: Read-back tolerance of the adapters' model checks, a few ulp: engines may store a number
#: through some arithmetic (with pin 4.1.0 and pybullet 3.2.7 an inertia of 0.9 reads back as
#: 0.8999999999999999).
READBACK_RTOL = 1e-15


def import_engine(module: str, label: str, pip_name: str):
    """Import an engine's Python package, or raise :class:`EngineUnavailable` saying how to
    install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise EngineUnavailable(
            f"{label} is not installed or does not import ({exc}); install it with "
            f"`pip install {pip_name}` (or `pip install director-bench[engines]`)"
        ) from exc


class Stopwatch:
    """Accumulates wall time of the stepping alone (``with watch: ...``)."""

    def __init__(self):
        self.elapsed = 0.0

    def __enter__(self):
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.elapsed += time.perf_counter() - self._t0
        return False
