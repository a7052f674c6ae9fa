"""The engine's CPU time on a busy machine (references.engines.timing), on simulated clocks:
a loop of engine calls and glue, preempted for milliseconds at a time (the wall clock runs,
the thread's CPU clock does not), priced back to the engine calls' CPU time that the loop
really spent; and the same loop on the real clocks."""

from __future__ import annotations

import random

import pytest

from references.engines import timing
from references.engines.timing import Stopwatch, Timing, best


class Clocks:
    """A wall clock and a thread CPU clock the test advances: ``run(s)`` spends ``s`` on
    the CPU (both advance), ``wait(s)`` is preempted (only the wall clock advances)."""

    def __init__(self):
        self.wall = 0.0
        self.cpu = 0.0

    def run(self, s: float) -> None:
        self.wall += s
        self.cpu += s

    def wait(self, s: float) -> None:
        self.wall += s


@pytest.fixture
def clocks(monkeypatch):
    c = Clocks()
    monkeypatch.setattr(timing.time, "perf_counter", lambda: c.wall)
    return c


def loop(c: Clocks, watch: Stopwatch, n: int, engine_s: float, glue_s: float, preempt, rng):
    """``n`` engine calls of ``engine_s`` each with ``glue_s`` of glue after each, between
    resume and pause; ``preempt(rng)``: seconds of preemption at a point (0: none)."""
    watch.resume()
    for _ in range(n):
        t0 = timing.time.perf_counter()
        c.run(engine_s / 2)
        c.wait(preempt(rng))
        c.run(engine_s / 2)
        watch.lap(t0)
        c.run(glue_s / 2)
        c.wait(preempt(rng))
        c.run(glue_s / 2)
    watch.pause()


def test_preemptions_fall_out_of_the_engine_time(clocks):
    rng = random.Random(1)

    def busy(rng):  # about as long preempted as running, a few milliseconds at a time
        return 3e-3 if rng.random() < 1 / 3000 else 0.0

    watch = Stopwatch(cpu_now=lambda: clocks.cpu)
    n, engine_s, glue_s = 20000, 1e-6, 1e-6
    loop(clocks, watch, n, engine_s, glue_s, busy, rng)
    t = watch.timing()
    true = n * engine_s
    assert watch.wall > 1.5 * (n * (engine_s + glue_s))  # the loop was starved
    assert abs(watch.elapsed - true) > 0.2 * true  # the wall clock inside the calls is off
    assert t.engine == pytest.approx(true, rel=0.03)  # the priced CPU time is not
    assert not t.starved and t.cpu == pytest.approx(n * (engine_s + glue_s), rel=1e-9)


def test_without_clean_slices_the_estimate_is_marked_starved(clocks, monkeypatch):
    """Every slice preempted: no share of the engine can be measured; the estimate comes
    with an uncertainty and the run is starved (the planted failure of the share: the same
    loop as above with the share disabled is starved too)."""
    rng = random.Random(2)
    watch = Stopwatch(cpu_now=lambda: clocks.cpu)
    loop(clocks, watch, 2000, 1e-6, 1e-6, lambda rng: 2e-6, rng)  # a wait at every point
    t = watch.timing()
    assert t.starved and t.spread > 0
    monkeypatch.setattr(timing, "SHARE_MIN_S", 1e9)
    rng = random.Random(1)
    watch = Stopwatch(cpu_now=lambda: clocks.cpu)
    loop(clocks, watch, 20000, 1e-6, 1e-6, lambda r: 3e-3 if r.random() < 1 / 3000 else 0, rng)
    assert watch.timing().starved


def test_a_long_call_read_around_is_its_cpu_time(clocks):
    watch = Stopwatch(cpu_now=lambda: clocks.cpu)
    watch.resume()
    clocks.run(1e-4)  # glue
    with watch.measure():
        clocks.run(2e-3)
        clocks.wait(5e-3)
        clocks.run(2e-3)
    watch.add(1e-2, 3e-3)  # a call the engine timed itself: 3 ms of CPU in 10 ms
    watch.pause()
    t = watch.timing()
    assert t.engine == pytest.approx(4e-3 + 3e-3, rel=1e-9)
    assert watch.elapsed == pytest.approx(9e-3 + 1e-2, rel=1e-9)


def test_a_quiet_loop_on_the_real_clocks_prices_its_calls_at_their_wall_time():
    import time

    watch = Stopwatch()
    watch.resume()
    for _ in range(2000):
        t0 = time.perf_counter()
        sum(range(200))
        watch.lap(t0)
    watch.pause()
    t = watch.timing()
    assert 0 < t.engine <= t.cpu <= t.wall
    if t.share > 0.95:  # nothing preempted it: the wall and the CPU time are one
        assert t.engine == pytest.approx(watch.elapsed, rel=0.1)


def test_the_best_timing_is_the_fastest_clean_one():
    clean = Timing(1.0, 0.0, 2.0, 2.0, 1.0)
    faster_starved = Timing(0.5, 0.4, 2.0, 9.0, 3.0)
    slower = Timing(1.2, 0.01, 2.0, 2.0, 1.2)
    assert best([faster_starved, slower, clean]) == (clean, False)
    # all starved: the one whose uncertainty is the smallest part of it (0.8 against 1.0)
    assert best([faster_starved, Timing(0.9, 0.9, 2.0, 9.0, 3.0)]) == (faster_starved, True)


def test_a_slices_bounds():
    from references.engines.timing import bounds

    # 10 ms of wall, 4 ms of CPU, 6 ms of it inside engine calls: the glue's 4 ms of wall
    # could hold all the CPU (engine 0) or none of it (engine 4 ms)
    assert bounds(10e-3, 4e-3, 6e-3) == (0.0, 4e-3)
    # all of it inside one call: its CPU time, however long it waited
    assert bounds(10e-3, 4e-3, 10e-3) == (4e-3, 4e-3)
    # no engine call in it: none
    assert bounds(10e-3, 4e-3, 0.0) == (0.0, 0.0)
    # glue of 1 ms: at least 3 ms of the CPU time was the engine's
    assert bounds(10e-3, 4e-3, 9e-3) == (pytest.approx(3e-3), 4e-3)


def test_a_builders_stepping_ends_where_it_says_so(clocks):
    """Between ``stepping()`` and ``stepped()`` (a system builder's stepping) the CPU time
    counts; its model's construction before and its own checks of the saved states after do
    not (the planted mistake, ``stepped`` not called: the checks count and the test fails)."""
    watch = Stopwatch(cpu_now=lambda: clocks.cpu)
    with timing.running(watch):
        clocks.run(5e-3)  # the model's construction
        timing.stepping()
        clocks.run(1e-4)  # the stepping's glue
        clocks.run(2e-3)  # a compiled run of many steps ...
        timing.stepped()
        timing.add(2e-3, 2e-3)  # ... timed by the engine itself
        clocks.run(3e-3)  # the builder's checks of what it saved
    t = watch.timing()
    assert t.engine == pytest.approx(2e-3, rel=1e-9)
    assert t.cpu == pytest.approx(2.1e-3, rel=1e-9)
    assert t.wall == pytest.approx(2.1e-3, rel=1e-9)


def test_the_exact_references_cost_is_its_own_threads_cpu_time(monkeypatch):
    """The reference (engine "exact") is timed on the calling thread's CPU clock, as every
    engine: CPU time another thread of the process spends meanwhile (here NumPy's loops,
    which run without the GIL) is not its cost. Planted: the process's clock (as it was)
    counts the other thread and fails the first assertion whenever that thread ran. (The
    reference cache is off: a reference read from it costs what its computation took then,
    tests/references/test_reference_cache.py.)"""
    import threading
    import time

    import numpy as np

    import scenarios
    from references import cache
    from references.engines.exact.adapter import ExactEngine

    monkeypatch.setenv(cache.SWITCH_ENV, "off")

    sc = scenarios.load("dzhanibekov")
    ExactEngine().run(sc, "reference", sc.dt)  # its imports done: the call below is its run
    stop, started = threading.Event(), threading.Event()
    a = np.random.default_rng(0).random(2_000_000)

    def busy():
        while not stop.is_set():
            np.sin(a)
            started.set()

    other = threading.Thread(target=busy, daemon=True)
    other.start()
    try:
        started.wait(10.0)
        c0, p0 = time.thread_time(), time.process_time()
        out = ExactEngine().run(sc, "reference", sc.dt)
        mine, process = time.thread_time() - c0, time.process_time() - p0
    finally:
        stop.set()
        other.join()
    assert 0 < out.cpu_time_s <= mine + 1e-6, (out.cpu_time_s, mine, process)
    assert out.timing.cpu == out.cpu_time_s and out.timing.spread == 0.0
