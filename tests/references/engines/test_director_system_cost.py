"""What the director's system builder (references.engines.director.system) counts as a run's
cost: its stepping, as every other builder's, not the construction of its mechanism (which
loads the compiled kernel from numba's cache in a process's first run: ~0.2 s, measured by
benchmarks/bench_director_system_glue.py) nor director_model's own checks of the saved states
(energy, constraint residuals), which no other engine's stepping computes. Planted mistake:
the builder running ``director_model.system.simulate_system`` inside its stopwatch (as it did)
fails the first test by the CPU time it burns on purpose in both."""

from __future__ import annotations

import time

import numpy as np
import pytest

import scenarios
from director_model.system import simulate as dsim
from references.engines.director.system import model
from references.engines.system import run_system

#: CPU time (s) spent on purpose in the stepper's construction and in its checks: a 20-step
#: run of the four-bar steps in well under a millisecond of CPU (at load too: a thread's CPU
#: time does not grow with the machine's load, bench_director_system_glue.py)
BURN_S = 0.3


def burn(s: float) -> None:
    c0 = time.thread_time()
    while time.thread_time() - c0 < s:
        pass


def test_the_whole_step_leaves_out_the_build_and_the_steppers_checks(monkeypatch):
    init, checks = dsim.SystemStepper.__init__, dsim.SystemStepper._trajectory

    def slow_init(self, *a, **k):
        init(self, *a, **k)
        burn(BURN_S)

    def slow_checks(self, *a, **k):
        burn(BURN_S)
        return checks(self, *a, **k)

    monkeypatch.setattr(dsim.SystemStepper, "__init__", slow_init)
    monkeypatch.setattr(dsim.SystemStepper, "_trajectory", slow_checks)
    sc = scenarios.load("four_bar")
    c0 = time.thread_time()
    out = run_system("director", sc, "rattle", 2e-3, 20 * 2e-3, 5)
    assert time.thread_time() - c0 >= 2 * BURN_S  # both burned, inside the builder
    t = out.timing
    assert 0 < t.engine <= t.cpu < BURN_S, (t.engine, t.cpu)


def test_the_builder_runs_director_model_simulate_system_bit_for_bit():
    """The builder's stepper and its chunk are director_model's public simulate_system."""
    sc = scenarios.load("four_bar")
    out = run_system("director", sc, "rattle4", 2e-3, 40 * 2e-3, 5)
    bodies, joints = model(sc)
    tr = dsim.simulate_system(bodies, joints, gravity=tuple(sc.gravity), scheme="rattle4",
                              dt=2e-3, t_end=40 * 2e-3, save_every=5)  # fmt: skip
    traj = out.trajectory
    assert len(traj) == len(tr) == 9
    pairs = ((traj.position, tr.position), (traj.rotation, tr.rotation),
             (traj.velocity, tr.velocity), (traj.omega_body, tr.omega_body))  # fmt: skip
    for ours, theirs in pairs:
        np.testing.assert_array_equal(ours, theirs)
    assert out.stats["largest constraint row residual"] == pytest.approx(
        float(np.max(tr.constraint_position)), rel=0, abs=0
    )


def test_a_single_bodys_whole_step_leaves_out_director_models_checks(monkeypatch):
    """The same for a single body (references.engines.director.adapter): director_model's
    invariants of the saved states (simulate._finish) are not the step's cost. The run's last
    chunk is shorter than the others (10 steps saved every 3), so one block is stepped chunk
    by chunk: every chunk's compiled call stays on the stopwatch (its CPU time at least the
    kernel's). Planted: the adapter's chunk as it was (no ``stepped``) counts the burns."""
    import importlib

    from references.engines.director.adapter import DirectorEngine

    body_sim = importlib.import_module("director_model.simulate")  # the module, not its function

    finish = body_sim._finish
    burned = []

    def slow_finish(*a, **k):
        burn(BURN_S / 10)
        burned.append(1)
        return finish(*a, **k)

    monkeypatch.setattr(body_sim, "_finish", slow_finish)
    sc = scenarios.load("cone_top")
    out = DirectorEngine().run(sc, "rattle", 1e-3, 10e-3, 3)
    t = out.timing
    assert out.nstep == 10 and len(burned) >= 2
    assert 0 < t.engine <= t.cpu < BURN_S / 10, (t.engine, t.cpu, len(burned))
