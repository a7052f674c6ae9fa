"""Long horizons with streaming metrics: every step measured, memory bounded by the segment.

:class:`StreamingRecorder` is the recorder of a run (``references.engines.base.Recorder``) that
sees the state after every step. It buffers ``segment`` steps, evaluates the reference at
their times, folds the suite's pointwise metrics (energy and momentum drift, orthonormality,
the velocity-constraint residual, attitude, rate and position error) into running maxima, and
keeps only the states at the saved step indices. The run itself is one continuous run of the
engine: nothing is restarted, so a streamed run follows exactly the same discrete trajectory
as a run that saves every step.

Phase observables (flip interval, nutation period) are measured on the kept samples, so
``save_every`` must sample the motion finely enough for them.
"""

from __future__ import annotations

import math

import numpy as np

from references import conventions as cv
from references.engines.base import Recorder
from reports.metrics import body as M

#: pointwise metrics folded over every step: name -> (needs the reference, function)
POINTWISE = {
    "energy_drift_max": (False, lambda sc, tr, ref: M.energy_drift(sc, tr)),
    "energy_drift_rot_max": (False, lambda sc, tr, ref: M.energy_part_drift(sc, tr, "rot")),
    "energy_drift_trans_max": (False, lambda sc, tr, ref: M.energy_part_drift(sc, tr, "trans")),
    "momentum_drift_max": (False, lambda sc, tr, ref: M.momentum_drift(sc, tr)),
    "orthonormality_max": (False, lambda sc, tr, ref: M.orthonormality(tr)),
    "constraint_velocity_max": (False, lambda sc, tr, ref: M.constraint_velocity(sc, tr)),
    "attitude_error_max": (True, lambda sc, tr, ref: M.attitude_error(tr, ref)),
    "omega_error_max": (True, lambda sc, tr, ref: M.omega_error(tr, ref)),
    "position_error_max": (True, lambda sc, tr, ref: M.position_error(tr, ref)),
}


class StreamingRecorder(Recorder):
    """Running maxima of the pointwise metrics over every step (see the module docstring).

    ``reference(t)`` returns the reference trajectory at times ``t`` (None: no reference, the
    error metrics stay NaN); ``scenario`` gives the scales. After the run, :attr:`maxima`
    holds the metrics and :attr:`reference_accuracy` the largest accuracy estimate of the
    reference over the chunks.
    """

    every_step = True

    def __init__(self, saves, scenario, dt: float, segment: int, reference=None):
        super().__init__(saves)
        if segment < 1:
            raise ValueError(f"segment = {segment}: must be a whole number of steps >= 1")
        self.scenario, self.dt, self.segment = scenario, float(dt), int(segment)
        self.reference = reference
        # a metric that does not apply (no reference; an energy part of a pivoted body) is NaN
        parts = M.ENERGY_PART_METRICS.values() if scenario.pivot is not None else ()
        self.maxima = {
            k: (math.nan if (needs_ref and reference is None) or k in parts else 0.0)
            for k, (needs_ref, _) in POINTWISE.items()
        }
        self.reference_accuracy = 0.0 if reference is not None else math.nan
        self._buf_steps: list[np.ndarray] = []
        self._buf: list[cv.BodyState] = []
        self._buf_cv: list[np.ndarray] = []
        self._nbuf = 0

    def record_block(self, steps, block: cv.BodyState) -> None:
        steps = np.asarray(steps, dtype=np.int64)
        res = np.array([self.residuals.get(int(s), math.nan) for s in steps])
        super().record_block(steps, block)
        self._buf_steps.append(steps)
        self._buf.append(block)
        self._buf_cv.append(res)
        self._nbuf += len(steps)
        if self._nbuf >= self.segment:
            self.flush()

    def flush(self) -> None:
        """Fold the buffered steps into the maxima."""
        if not self._nbuf:
            return
        from references.engines.base import block_trajectory

        t = np.concatenate(self._buf_steps) * self.dt
        block = cv.BodyState(*(np.concatenate(p) for p in zip(*self._buf, strict=True)))
        tr = block_trajectory(self.scenario, t, block, np.concatenate(self._buf_cv))
        ref = None
        if self.reference is not None:
            ref = self.reference(t)
            self.reference_accuracy = max(self.reference_accuracy, float(ref.accuracy))
        for name, (needs_ref, fn) in POINTWISE.items():
            if needs_ref and ref is None:
                continue
            v = fn(self.scenario, tr, ref)
            if v is None:  # does not apply to this scenario
                continue
            worst = math.inf if not np.all(np.isfinite(v)) else float(np.max(v))
            self.maxima[name] = max(self.maxima[name], worst)
        self._buf_steps.clear()
        self._buf.clear()
        self._buf_cv.clear()
        self._nbuf = 0

    def trajectory(self, scenario, dt: float):
        self.flush()
        return super().trajectory(scenario, dt)
