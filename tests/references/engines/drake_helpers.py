"""What the Drake adapter's tests (test_engine_drake.py, test_engine_drake_chart.py) share:
the engine (skipped with the reason when Drake is not installed), an adapter built on a
scenario's state, and the rotation angle between two stacks of rotations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from references.engines import get_engine
from references.engines.context import BodyModel, RunContext

EPS = np.finfo(float).eps


def drake_engine():
    """The Drake adapter's class, or the test skipped with the reason it is not available."""
    cls = get_engine("drake")
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine 'drake' is not available here: {why}")
    return cls


def _built(cls, sc, integrator, dt=None, accuracy=None):
    """An adapter and its RunContext after build and set_state (the scenario's state)."""
    from references.engines.stepping import initial_state

    eng = cls()
    integ = cls.integrator(integrator)
    dt = sc.dt if dt is None else dt
    ctx = RunContext(sc, BodyModel.of(sc, dt), integ, dt, sc.t_end, accuracy=accuracy)
    eng.build(ctx)
    eng.set_state(ctx, initial_state(sc))
    return eng, ctx


def _angle(Ra, Rb) -> np.ndarray:
    """Rotation angle between stacks of rotations (the attitude error of reports.metrics.body)."""
    d = np.linalg.norm(np.asarray(Ra) - np.asarray(Rb), axis=(-2, -1)) / (2 * math.sqrt(2))
    return 2 * np.arcsin(np.minimum(d, 1.0))
