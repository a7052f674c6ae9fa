"""What one run works on and returns: the body an adapter builds (:class:`BodyModel`), what
the built model holds read back (:class:`ModelReadback`), the run's working state passed to
every adapter method (:class:`RunContext`, with the
:class:`~references.engines.timing.Stopwatch` of the time inside the engine's calls) and the
result (:class:`RunOutput`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from references import conventions as cv
from references.engines.integrators import Integrator
from references.engines.timing import Stopwatch, Timing
from references.trajectory import Trajectory

if TYPE_CHECKING:
    from references.engines.native import NativeStderr


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
    #: the time inside the engine's calls, and per block of the loop its wall and CPU time
    clock: Stopwatch = field(default_factory=Stopwatch)
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


@dataclass
class RunOutput:
    """What one run returns: the trajectory in the suite's schema (the scene's one body on the
    bodies axis; the single-body metrics read it through references.trajectory.one_body), the
    number of steps taken, the wall time of the stepping (model building excluded) split into
    the time inside the engine's own calls and the suite's glue around them, the dynamics
    evaluations per step, and every setting changed from the engine's defaults (recorded with
    the results)."""

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
    #: the CPU time of the stepping (the running thread's; the process's for a threaded
    #: engine): on a busy machine less than the wall time, by the time it waited for a CPU
    cpu_time_s: float = math.nan
    #: the stepping's timing (references.engines.timing): the engine calls' CPU time and its
    #: uncertainty; None where it was not measured
    timing: Timing | None = None

    @property
    def glue_time_s(self) -> float:
        return max(self.wall_time_s - self.engine_time_s, 0.0)


@dataclass
class SystemResult:
    """What a system builder returns (module docstring): the saved states ``t`` (n,), ``x``
    (n, nb, 3), ``R`` (n, nb, 3, 3), ``v`` (n, nb, 3), ``W`` (n, nb, 3); ``engine_time_s``,
    the time inside the engine's own calls (NaN: not measured, the run's wall time is used);
    ``settings``, every setting that shapes the result; ``evals_per_step``, the dynamics
    evaluations per step (NaN: not said); ``stats``, counts and figures the builder reports."""

    t: np.ndarray
    x: np.ndarray
    R: np.ndarray
    v: np.ndarray
    W: np.ndarray
    engine_time_s: float = math.nan
    settings: dict = field(default_factory=dict)
    evals_per_step: float = math.nan
    stats: dict = field(default_factory=dict)
    #: the run's timing (references.engines.timing.Timing) when the builder knows it better
    #: than the run's stopwatch does (the exact reference: what its computation took, kept
    #: with it in the reference cache); None: the stopwatch's, or the wall time
    timing: object = None
