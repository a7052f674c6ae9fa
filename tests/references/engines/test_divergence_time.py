"""``t_diverged`` of a step that cannot be taken is the time that step starts from, not the end
of the block of checkpoints it was in; the checkpoints completed before it are kept.

The independent check: a run whose horizon ends exactly at the reported time completes, and
one step more fails (the same engine, the same step, no knowledge of the run loop's blocks)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from references.engines import get_engine
from references.errors import Diverged
from scenarios.model import Scenario

# An asymmetric tumble whose |W| swings between 3.05 and 3.51 rad/s: at h = 0.9 s the RKMK4
# stage rotation h |W| first reaches pi some steps in, at h = 0.04 s with |W| = 96 rad/s at the
# first step (h |W| = 3.8 > pi).
TUMBLE = Scenario(
    name="tumble",
    description="",
    mass=1.0,
    inertia=[1.0, 2.0, 3.0],
    rotation=np.eye(3),
    omega_body=[0.3, 3.0, 0.5],
    t_end=54.0,
    dt=0.9,
)
FAST = TUMBLE.replace(omega_body=[60.0, 50.0, 58.0], t_end=2.0, dt=0.04)


def _engine_or_skip(name):
    cls = get_engine(name)
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine {name!r} is not available here: {why}")
    return cls()


@pytest.fixture(params=["compiled", "readable"])
def stepper(request, monkeypatch):
    """Both RKMK4 steppers of the run loop must say where they failed."""
    if request.param == "readable":
        from references.engines import liegroup, stepping

        monkeypatch.setattr(stepping, "_stepper", lambda e, c: liegroup.RKMK4Stepper(e, c))
    return request.param


def test_a_failing_step_inside_a_block_is_dated_by_its_start(stepper):
    engine = _engine_or_skip("pinocchio")
    h = TUMBLE.dt
    with pytest.raises(Diverged) as info:
        engine.run(TUMBLE, "RKMK4", h, save_every=5)  # one block: checkpoints 5, 10, ..., 60
    t_div = info.value.t_diverged
    k = round(t_div / h)
    assert 0 < t_div < TUMBLE.t_end and t_div == pytest.approx(k * h, rel=1e-15)
    assert f"the step from t = {t_div:.6g} to t = {t_div + h:.6g} s" in str(info.value)
    # the checkpoints completed before the failing step are kept, none after it
    out = info.value.output
    assert out.trajectory.t[-1] == pytest.approx(5 * h * (k // 5)) and out.nstep == 5 * (k // 5)
    # independent of the run loop's blocks: up to t_div every step can be taken, one more fails
    full = engine.run(TUMBLE, "RKMK4", h, t_end=k * h, save_every=1)
    assert full.nstep == k and np.all(np.isfinite(full.trajectory.omega_body))
    with pytest.raises(Diverged) as again:
        engine.run(TUMBLE, "RKMK4", h, t_end=(k + 1) * h, save_every=1)
    assert again.value.t_diverged == pytest.approx(t_div, rel=1e-15)


@pytest.mark.parametrize("name", ["pinocchio", "dart"])
def test_a_first_step_that_fails_is_dated_zero(name, stepper):
    """h |W| = 3.8 > pi on the first step: t_diverged = 0 (it was the block's end, t_end)."""
    engine = _engine_or_skip(name)
    assert FAST.dt * float(np.linalg.norm(FAST.omega_body)) > math.pi
    with pytest.raises(Diverged) as info:
        engine.run(FAST, "RKMK4", FAST.dt)
    assert info.value.t_diverged == 0.0 and info.value.output.nstep == 0
    assert "the step from t = 0 to t = 0.04 s could not be taken" in str(info.value)
