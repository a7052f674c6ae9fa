"""Long horizons with streaming metrics: every step measured, memory bounded by the segment.

:class:`StreamingRecorder` is the recorder of a run (``references.engines.recording.Recorder``) that
sees the state after every step. It buffers ``segment`` steps, evaluates the reference at
their times, folds every pointwise single-body metric of the catalog
(:data:`reports.metrics.catalog.STREAMED`: energy and momentum drift, orthonormality, the
velocity-constraint residual, attitude, rate and position error, ...) into running maxima,
and keeps only the states at the saved step indices. The run itself is one continuous run of the
engine: nothing is restarted, so a streamed run follows exactly the same discrete trajectory
as a run that saves every step.

Phase observables (flip interval, nutation period) are measured on the kept samples, so
``save_every`` must sample the motion finely enough for them.
"""

from __future__ import annotations

import math

import numpy as np

from references import conventions as cv
from references.engines.recording import Recorder
from reports.metrics import body  # noqa: F401  (attaches the single-body functions)
from reports.metrics.catalog import POINTWISE, computed


def streamed() -> list:
    """(metric, function) of the metrics folded over every step: the catalog's pointwise
    single-body metrics."""
    return [(m, fn) for m, fn in computed("body") if m.kind == POINTWISE]


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
        # a metric that does not apply is NaN: without a reference the errors against it,
        # and one whose function says so (None, e.g. an energy part of a pivoted body)
        self.maxima = {
            m.name: (math.nan if m.reference and reference is None else 0.0) for m, _ in streamed()
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
        from references.engines.recording import block_trajectory
        from references.trajectory import one_body

        t = np.concatenate(self._buf_steps) * self.dt
        block = cv.BodyState(*(np.concatenate(p) for p in zip(*self._buf, strict=True)))
        tr = one_body(block_trajectory(self.scenario, t, block, np.concatenate(self._buf_cv)))
        ref = None
        if self.reference is not None:
            ref = self.reference(t)
            self.reference_accuracy = max(self.reference_accuracy, float(ref.accuracy))
            ref = one_body(ref)
        for metric, fn in streamed():
            if metric.reference and ref is None:
                continue
            v = fn(self.scenario, tr, ref)
            if v is None:  # does not apply to this scenario
                self.maxima[metric.name] = math.nan
                continue
            worst = math.inf if not np.all(np.isfinite(v)) else float(np.max(v))
            self.maxima[metric.name] = max(self.maxima[metric.name], worst)
        self._buf_steps.clear()
        self._buf.clear()
        self._buf_cv.clear()
        self._nbuf = 0

    def trajectory(self, scenario, dt: float):
        self.flush()
        return super().trajectory(scenario, dt)
