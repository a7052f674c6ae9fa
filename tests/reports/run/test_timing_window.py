"""The timing pass repeats a run over a bounded window of its first steps (reports.run.timing):
how long a window is, that a repeat steps exactly the run's first steps through the engine's
own builder, and that a window's timing is priced per step over the whole run."""

import math

import pytest

import scenarios
from references.engines.timing import Timing
from reports.run import runner, timing
from reports.store.runs import RunSpec


def spec_of(name="free_tumbling", engine="director", integ="rattle", dt=1e-3, **kw):
    return RunSpec(scenarios.load(name).replace(dt_sweep=()), engine, integ, dt, **kw)


def test_a_window_is_what_the_run_stepped_in_window_s_of_cpu(monkeypatch):
    s = spec_of()
    # 10,000 steps in 0.1 s of CPU: 10 us a step, so WINDOW_S (5 ms) is 500 of them
    assert timing.window(s, 10_000, 0.1) == math.ceil(timing.WINDOW_S / 1e-5)
    # at least WINDOW_MIN_STEPS, at most the run
    assert timing.window(s, 10_000, 100.0) == timing.WINDOW_MIN_STEPS
    assert timing.window(s, 1000, 0.001) == 1000
    assert timing.window(s, 50, 100.0) == 50
    monkeypatch.setattr(timing, "WINDOW_S", math.inf)  # whole runs
    assert timing.window(s, 10_000, 0.1) == 10_000
    monkeypatch.undo()
    # no CPU time measured, or an error-controlled run: the whole run
    assert timing.window(s, 10_000, math.nan) == 10_000
    assert timing.window(s, 10_000, 0.0) == 10_000
    adaptive = spec_of(engine="drake", integ="runge_kutta5", accuracy=1e-8)
    assert timing.window(adaptive, 10_000, 0.1) == 10_000
    # bodies in contact: a step's cost follows the contacts, the whole run is repeated
    contact = spec_of("block_incline_stick", "mujoco", "pyramidal")
    assert timing.window(contact, 10_000, 0.1) == 10_000


@pytest.mark.parametrize(
    ("name", "engine", "integ", "builder"),
    [
        ("free_tumbling", "mujoco", "Euler", None),
        ("spinning_chain", "mujoco", "Euler", "references.engines.system.run_system"),
        ("block_incline_stick", "mujoco", "pyramidal", "references.engines.contact.run_contact"),
    ],
)
def test_a_window_steps_the_runs_first_steps(name, engine, integ, builder, monkeypatch):
    """A repeat over a window runs the scene through the same builder as the run, over the
    window's horizon, and is a timing only if it stepped exactly the window's steps."""
    import importlib

    from references.engines import get_engine

    s = spec_of(name, engine, integ, dt=1e-3)
    nstep = round(s.horizon / s.dt)
    horizons = []
    if builder is not None:
        mod, fn = builder.rsplit(".", 1)
        mod = importlib.import_module(mod)
        real = getattr(mod, fn)

        def spy(eng, sc, integ_, dt, horizon, saving):
            horizons.append((sc.t_end, horizon))
            return real(eng, sc, integ_, dt, horizon, saving)

        monkeypatch.setattr(mod, fn, spy)
    got = timing._run_again(get_engine(engine), s, nstep, 120)
    assert got is not None and got.engine > 0 and got.cpu > 0
    if builder is not None:
        assert horizons == [(pytest.approx(0.12), pytest.approx(0.12))]


def test_a_window_is_no_timing_when_the_engine_steps_another_number_of_steps(monkeypatch):
    from references.engines import get_engine

    s = spec_of(engine="mujoco", integ="Euler")
    cls = get_engine("mujoco")

    class Short(cls):
        def run(self, sc, integ, dt, horizon, saving, *a, **k):
            return super().run(sc, integ, dt, horizon - dt, saving, *a, **k)

    assert timing._run_again(cls, s, 1000, 120) is not None
    assert timing._run_again(Short, s, 1000, 120) is None


def unit_with(spec, row_engine_s: float, nstep: int, cpu_s: float, wall_s: float | None = None):
    """A timing unit of ``spec`` whose run's own timing is the one given; by default its
    stepping waited half its wall time for a CPU (it did not run clean: it is timed again)."""
    row = runner.execute(spec)
    assert row["status"] == "ok", row["message"]
    row.update(nstep=nstep, engine_time_s=row_engine_s, engine_time_spread_s=0.0,
               cpu_time_s=cpu_s, wall_time_s=2 * cpu_s if wall_s is None else wall_s)  # fmt: skip
    return timing.TimingUnit(spec.scenario.name, [spec], {spec.run_id: row})


def test_a_run_whose_own_timing_ran_clean_is_not_timed_again(monkeypatch):
    """Not starved and its CPU time at least CLEAN of its wall time: its own timing stands;
    one that waited longer for a CPU, or whose timing starved, is timed again."""
    from references.engines.timing import CLEAN

    s = spec_of()
    asked = []

    def again(cls, spec, nstep, steps):
        asked.append(steps)
        return Timing(1e-4, 0.0, 4e-4, 4e-4, 1e-4)

    monkeypatch.setattr(timing, "_run_again", again)
    clean = unit_with(s, 3e-3, 10_000, 0.1, wall_s=0.1 / CLEAN)
    assert timing.time_unit(clean).columns == {} and not asked
    waited = unit_with(s, 3e-3, 10_000, 0.1, wall_s=0.1 / CLEAN * 1.01)
    assert timing.time_unit(waited).columns[s.run_id]["timing_repeats"] == 2
    assert len(asked) == 1
    starved = unit_with(s, 3e-3, 10_000, 0.1, wall_s=0.1)
    starved.rows[s.run_id]["engine_time_spread_s"] = 3e-3  # its uncertainty its estimate
    assert timing.time_unit(starved).columns[s.run_id]["timing_repeats"] == 2
    assert len(asked) == 2
    assert timing.ran_clean(Timing(1e-3, 0.0, 0.1, 0.1, 1e-3))
    assert not timing.ran_clean(Timing(1e-3, 1e-3, 0.1, 0.1, 1e-3))  # starved
    assert not timing.ran_clean(Timing(1e-3, 0.0, 0.1, 0.2, 1e-3))  # waited half its time


def test_a_windows_timing_is_priced_over_the_whole_run(monkeypatch):
    """A window of 500 of 10,000 steps that took 0.1 ms of engine time prices the run at
    2 ms (20 x), kept when cheaper than the run's own 3 ms; its per-step cost is the
    window's."""
    s = spec_of()
    unit = unit_with(s, 3e-3, 10_000, 0.1)
    steps = timing.window(s, 10_000, 0.1)
    assert steps == 500
    asked = []

    def again(cls, spec, nstep, steps):
        asked.append((nstep, steps))
        return Timing(1e-4, 0.0, 4e-4, 4e-4, 1e-4)

    monkeypatch.setattr(timing, "_run_again", again)
    cols = timing.time_unit(unit).columns[s.run_id]
    assert asked and set(asked) == {(10_000, 500)}
    assert cols["engine_time_s"] == pytest.approx(1e-4 * 20)
    assert cols["engine_ns_per_step"] == pytest.approx(1e9 * 1e-4 / 500)
    assert cols["ns_per_step"] == pytest.approx(1e9 * 4e-4 / 500)
    assert cols["timing_repeats"] == 1 + len(asked) <= timing.TIMINGS


def test_a_dearer_window_does_not_replace_the_runs_own_timing(monkeypatch):
    s = spec_of()
    unit = unit_with(s, 1e-3, 10_000, 0.1)
    # per step the window (2e-4 s over 500 steps) is 4x the run's own (1e-3 over 10,000)
    monkeypatch.setattr(
        timing, "_run_again", lambda cls, spec, nstep, steps: Timing(2e-4, 0.0, 4e-4, 4e-4, 2e-4)
    )
    cols = timing.time_unit(unit).columns[s.run_id]
    assert cols["engine_time_s"] == pytest.approx(1e-3)
    assert cols["engine_time_max_s"] == pytest.approx(2e-4 * 20)
