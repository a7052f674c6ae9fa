"""What a run costs the engine, measured so that it holds on a busy machine.

The stopwatch an adapter runs around each of its engine's calls (``with ctx.clock:``, or
``clock.lap(t0)`` in a hot loop) reads the wall clock: a read costs ~70 ns, where a
thread's CPU clock (``time.thread_time``) costs ~640 ns on this suite's 2-core VM (a
system call) and a call to an engine can take a microsecond. But the wall clock also counts
the time the thread waited for a CPU: on a machine running twice as many processes as it
has cores, a run's wall time is two to ten times its CPU time, and which calls the waits
fell into is chance.

So the :class:`Stopwatch` cuts the stepping into *slices* of about :data:`SLICE_S` (closed
at the first engine call that ends after it) and reads the thread's CPU clock once per
slice, beside the wall clock. A slice whose CPU time is at least :data:`CLEAN` of its wall
time was not preempted: its engine calls' wall time is their CPU time. The engine's share
of the thread's CPU time, measured over those clean slices, prices the CPU time of the
others (the thread's CPU time is exact however long it waited), within the bounds its wall
and CPU times allow (:func:`bounds`: a slice spent inside one engine call is its CPU time,
one with no engine call none). Where no slice ran clean, the engine calls' wall time times
the slice's CPU share (CPU over wall) is the estimate, with an *uncertainty*: the width of
those bounds (the waits could all have fallen into the engine calls or all into the glue).
A run whose uncertainty exceeds :data:`references.costs.STARVED` of its estimate was
*starved*: the runner times it again and marks it when no repeat ran clean
(reports.run.runner, reports.gate.rule).

The CPU clock is the thread's (engines compute on the calling thread), or the process's for
an engine that computes on threads of its own (``EngineBase.threaded``: MJX's XLA).
"""

from __future__ import annotations

import contextlib
import threading
import time
from dataclasses import dataclass

from references.costs import STARVED

#: a slice of the stepping is about this long (s): short enough that most slices run
#: between two preemptions on a busy machine (a scheduler's time slice is milliseconds),
#: long enough that its CPU-clock reads (~1 us) cost nothing
SLICE_S = 5e-4
#: a slice ran clean (no preemption) when its CPU time is at least this share of its wall
#: time (timer interrupts and page faults take a few per cent)
CLEAN = 0.9
#: the engine's share of the CPU time is trusted when the clean slices hold at least this
#: much CPU time (s)
SHARE_MIN_S = 2e-4


def cpu_clock(threaded: bool = False):
    """The CPU clock a run's slices are read with: the calling thread's, or (``threaded``)
    the whole process's, for an engine computing on threads of its own."""
    return time.process_time if threaded else time.thread_time


class Stopwatch:
    """The time inside an engine's own calls: ``elapsed`` (s, wall), accumulated by ``with
    stopwatch:`` around each call, :meth:`lap` after one, or added to directly; between
    :meth:`resume` and :meth:`pause` (the stepping), slices of the wall and CPU time from
    which :meth:`timing` prices the engine calls' CPU time (module docstring)."""

    __slots__ = (
        "elapsed", "cpu_now", "_t0", "_running", "_w0", "_c0", "_e0", "_x0",
        "wall", "cpu", "clean_cpu", "clean_engine", "dirty", "measured_engine", "_measured",
    )  # fmt: skip

    def __init__(self, cpu_now=time.thread_time):
        self.elapsed = 0.0
        self.cpu_now = cpu_now
        self._t0 = 0.0
        self._running = False
        self._w0 = self._c0 = self._e0 = 0.0
        self.wall = 0.0  # the stepping's wall time, s
        self.cpu = 0.0  # its CPU time, s
        self.clean_cpu = 0.0  # CPU time of the clean slices
        self.clean_engine = 0.0  # the engine calls' time in the clean slices
        self.dirty: list[tuple[float, float, float]] = []  # (wall, cpu, engine) of the others
        self.measured_engine = 0.0  # the CPU time of the calls read around (:meth:`measure`)
        self._measured = [0.0, 0.0, 0.0]  # their wall, CPU and engine wall time so far
        self._x0 = (0.0, 0.0, 0.0)

    # -- around the engine's calls -----------------------------------------------------------
    def __enter__(self):
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.lap(self._t0)
        return False

    def lap(self, t0: float) -> float:
        """An engine call that started at ``t0`` (``time.perf_counter``) has returned; its
        wall time (s)."""
        t1 = time.perf_counter()
        self.elapsed += t1 - t0
        if self._running and t1 - self._w0 >= SLICE_S:
            self._close(t1)
            self._open(t1)
        return t1 - t0

    def measure(self, inside: float | None = None) -> _Measured:
        """``with stopwatch.measure() as call:`` around one long engine call (a compiled run
        of many steps: the CPU-clock reads cost nothing beside it): its CPU time is read
        around it and is the engine's, exactly; ``call.inside`` (settable in the block), the
        wall time of the engine's own work within the call when the call also does some of
        the suite's (default: all of it)."""
        return _Measured(self, inside)

    def add(self, wall: float, cpu: float) -> None:
        """An engine call that has just returned took ``wall`` and ``cpu`` seconds, as the
        engine measured them itself (director_model's compiled runs)."""
        self._add_measured(wall, cpu, None)

    def _add_measured(self, wall: float, cpu: float, inside: float | None) -> None:
        wall = max(wall, 0.0)
        cpu = max(min(cpu, wall), 0.0)
        engine = wall if inside is None else max(min(inside, wall), 0.0)
        self.elapsed += engine
        self.measured_engine += cpu * (engine / wall) if wall > 0 else 0.0
        m = self._measured
        m[0] += wall
        m[1] += cpu
        m[2] += engine
        t1 = time.perf_counter()
        if self._running and t1 - self._w0 >= SLICE_S:
            self._close(t1)
            self._open(t1)

    # -- around the stepping ---------------------------------------------------------------
    def resume(self) -> None:
        """The stepping (re)starts: a slice opens."""
        self._running = True
        self._open(time.perf_counter())

    def pause(self) -> float:
        """The stepping stops (the suite's checks between blocks are not the engine's run):
        the slice closes; the wall time since :meth:`resume` (s)."""
        t1 = time.perf_counter()
        if self._running:
            self._close(t1)
            self._running = False
        return t1

    @property
    def running(self) -> bool:
        """Whether the stepping is on (between :meth:`resume` and :meth:`pause`)."""
        return self._running

    def restart(self) -> None:
        """The stepping starts now: what ran since :meth:`resume` (a system builder's model
        construction) is left out, as the building of a single body's model is."""
        if self._running:
            self._open(time.perf_counter())

    def _open(self, t: float) -> None:
        self._w0, self._c0, self._e0 = t, self.cpu_now(), self.elapsed
        self._x0 = tuple(self._measured)

    def _close(self, t: float) -> None:
        wall = t - self._w0
        cpu = max(min(self.cpu_now() - self._c0, wall), 0.0)
        self.wall += wall
        self.cpu += cpu
        # the measured calls in the slice are priced already: the rest of it
        xw, xc, xe = (a - b for a, b in zip(self._measured, self._x0, strict=True))
        engine = max(min(self.elapsed - self._e0 - xe, wall - xw), 0.0)
        wall, cpu = max(wall - xw, 0.0), max(min(cpu - xc, wall - xw), 0.0)
        if wall <= 0:
            return
        if cpu >= CLEAN * wall:  # its few waits spread over engine and glue alike
            self.clean_cpu += cpu
            self.clean_engine += engine * cpu / wall if wall > 0 else 0.0
        else:
            self.dirty.append((wall, cpu, engine))

    def timing(self) -> Timing:
        """The stepping's :class:`Timing`: the clean slices' engine time, and the others'
        priced by the engine's share of the CPU time in the clean ones (or, when they are
        too few, by their own CPU share, with its uncertainty), each within what its wall
        and CPU times allow (:func:`bounds`)."""
        engine, spread = self.clean_engine + self.measured_engine, 0.0
        share = self.clean_engine / self.clean_cpu if self.clean_cpu >= SHARE_MIN_S else None
        for wall, cpu, eng in self.dirty:
            lo, hi = bounds(wall, cpu, eng)
            if share is not None:
                engine += min(max(share * cpu, lo), hi)
            else:
                guess = eng * cpu / wall if wall > 0 else 0.0
                engine += min(max(guess, lo), hi)
                spread += hi - lo
        return Timing(engine, spread, self.cpu, self.wall, self.elapsed)


def bounds(wall: float, cpu: float, engine: float) -> tuple[float, float]:
    """The least and the most CPU time a slice's engine calls can have taken, from the
    slice's ``wall`` and ``cpu`` time and the calls' ``engine`` wall time: no more than
    their wall time nor the slice's CPU time, and at least what the CPU time leaves once
    the rest of the slice (its glue, ``wall - engine``) ran without waiting."""
    return max(cpu - (wall - engine), 0.0), min(engine, cpu)


class _Measured:
    """The context of :meth:`Stopwatch.measure`."""

    __slots__ = ("watch", "inside", "_t0", "_c0")

    def __init__(self, watch: Stopwatch, inside: float | None):
        self.watch, self.inside = watch, inside

    def __enter__(self) -> _Measured:
        self._c0 = self.watch.cpu_now()
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc) -> bool:
        wall = time.perf_counter() - self._t0
        self.watch._add_measured(wall, self.watch.cpu_now() - self._c0, self.inside)
        return False


# -- the stopwatch of the run in progress, for a system builder's loop ---------------------

_local = threading.local()


@contextlib.contextmanager
def running(watch: Stopwatch):
    """The block runs a system builder with ``watch`` as the stopwatch its engine calls are
    timed on (:func:`lap`, :func:`stepping`), between ``watch.resume()`` and ``pause()``."""
    before = getattr(_local, "watch", None)
    _local.watch = watch
    watch.resume()
    try:
        yield watch
    finally:
        watch.pause()
        _local.watch = before


def lap(t0: float) -> float:
    """A system builder's engine call that started at ``t0`` has returned: timed on the
    stopwatch of the run in progress (:func:`running`); its wall time (s)."""
    watch = getattr(_local, "watch", None)
    return watch.lap(t0) if watch is not None else time.perf_counter() - t0


def add(wall: float, cpu: float) -> None:
    """A system builder's engine call timed by the engine itself (:meth:`Stopwatch.add`)."""
    watch = getattr(_local, "watch", None)
    if watch is not None:
        watch.add(wall, cpu)


def stepping() -> None:
    """A system builder starts stepping: its model's construction is not the run's cost
    (:meth:`Stopwatch.restart`)."""
    watch = getattr(_local, "watch", None)
    if watch is not None:
        watch.restart()


def stepped() -> None:
    """A system builder's stepping is over: what it does before it returns (its engine's
    own checks of the states it saved) is not the run's cost (:meth:`Stopwatch.pause`)."""
    watch = getattr(_local, "watch", None)
    if watch is not None:
        watch.pause()


@dataclass(frozen=True)
class Timing:
    """One timing of a run's stepping, s: ``engine`` (the engine calls' CPU time, priced by
    :meth:`Stopwatch.timing`), ``spread`` (its uncertainty), ``cpu`` and ``wall`` (the whole
    stepping's, the suite's glue included), ``engine_wall`` (the engine calls' wall time)."""

    engine: float
    spread: float
    cpu: float
    wall: float
    engine_wall: float

    @property
    def starved(self) -> bool:
        return self.spread > STARVED * self.engine

    @property
    def share(self) -> float:
        """The CPU time over the wall time of the stepping (1: never waited)."""
        return self.cpu / self.wall if self.wall > 0 else 1.0


def best(timings) -> tuple[Timing, bool]:
    """(the timing a run keeps among ``timings``, whether it is starved): the least engine
    time among those not starved; when every one is, the one whose uncertainty is the
    smallest fraction of its estimate (starved)."""
    timings = list(timings)
    clean = [t for t in timings if not t.starved]
    if clean:
        return min(clean, key=lambda t: t.engine), False
    return min(timings, key=lambda t: t.spread / t.engine if t.engine > 0 else 1.0), True
