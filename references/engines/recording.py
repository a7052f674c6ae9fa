"""Recording a run's states: the :class:`Recorder` keeps the saved steps block by block and
turns them into the suite's :class:`~references.trajectory.Trajectory` (the scene's one body on
the bodies axis)."""

from __future__ import annotations

import math

import numpy as np

from references import conventions as cv
from references.trajectory import Trajectory


def sorted_unique(a) -> np.ndarray:
    """The distinct values of the integers ``a`` in increasing order, as int64 (what
    ``np.unique`` returns for them), by a sort and a comparison of neighbours: numpy 2's
    ``np.unique`` hashes the values first, ~1 ms for the 4000 sorted steps of a run's saves
    against ~15 us here (measured, numpy 2.4)."""
    a = np.sort(np.asarray(a, dtype=np.int64), axis=None)
    if a.size > 1:
        keep = np.empty(a.size, dtype=bool)
        keep[0] = True
        np.not_equal(a[1:], a[:-1], out=keep[1:])
        if not keep.all():
            a = a[keep]
    return a


class Recorder:
    """Receives the states of a run, block by block (:func:`conventions.block_row`: stacked
    arrays), and keeps those at the saved step indices. A subclass with ``every_step = True``
    sees every step (streaming metrics over long horizons keep O(1) memory that way, see
    :mod:`reports.metrics.streaming`)."""

    every_step = False

    def __init__(self, saves: np.ndarray):
        #: sorted and unique, so that a block's saved steps are found by bisection
        self.saves = sorted_unique(saves)
        self.steps: list[np.ndarray] = []
        self.blocks: list[cv.BodyState] = []
        self.cv: list[np.ndarray] = []
        #: the run's residuals by step (RunContext.residuals), consumed as states arrive
        self.residuals: dict = {}

    def _residuals(self, steps) -> np.ndarray:
        if not self.residuals:
            return np.full(len(steps), math.nan)
        # Python ints from tolist(): int() of each numpy integer costs several times the pop
        return np.array([self.residuals.pop(s, math.nan) for s in steps.tolist()])

    def record_block(self, steps, block: cv.BodyState) -> None:
        steps = np.asarray(steps, dtype=np.int64)
        res = self._residuals(steps)
        # np.isin would sort or hash all the saves at every block
        i = np.minimum(np.searchsorted(self.saves, steps), len(self.saves) - 1)
        keep = self.saves[i] == steps if len(self.saves) else np.zeros(len(steps), bool)
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
    """The trajectory of a block of states of the scenario's one body, energy and momentum
    computed the suite's way (:meth:`Trajectory.from_states`); ``residuals`` the engine's own
    velocity-constraint residuals (NaN where it has none: then computed from R and W)."""
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
