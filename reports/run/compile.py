"""Compiling ahead (``director-bench compile``): the numba kernels the runs of a suite go
through, compiled into numba's on-disk cache before the first run.

The director's kernels (single body, systems, contact), the multibody reference's and the
suite's RKMK4 are numba functions with ``cache=True``: the first process that calls one
compiles it for the argument types it gets and writes the machine code to ``__pycache__``
beside the source (director_model._cache keys it on every source file it is built from, so
an edit to any of them recompiles it); every later process loads it in milliseconds. Which
kernels and which argument types a suite needs is decided by its runs, so this module compiles
them the one way that cannot miss one: it executes, for every configuration that goes
through a numba warm-up (reports.run.runner.warm_ups), one short run of each scenario at
the configuration's first step (:data:`SHORT_SAVES` saved samples), through the runner's own
code (engine, reference, metrics), and throws the rows away. Configurations whose engine
bundles its runs (MJX: JAX's compilation, in JAX's own persistent cache at its first run)
and those that compile nothing are left out.

The short runs go to a local process pool (reports.run.parallel.process_pool) in units of the
same warm-ups, so that two workers never compile the same kernel (the pool's gate) and the
longest compilations start first: the contact kernels (about 90 s of CPU from nothing on the
2-core machine), then the systems' (about 40 s), then the single bodies' (firstrun's
measurements, reports in the repository's history). Each worker prints a line when a kernel
starts compiling and when it is done, with its CPU time (numba's ``numba:compile`` event;
a kernel loaded from the cache fires none), and the command a line every
:data:`HEARTBEAT_S` seconds while it waits; run again with the cache current, it compiles
nothing and says so.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
import time

from reports.store.runs import RunSpec

#: a short run keeps this many saved samples (the first step's horizon: enough for every
#: metric of a run to be computed, so that every kernel a run calls is called)
SHORT_SAVES = 4

#: seconds between the command's "still compiling" lines while nothing else is printed
HEARTBEAT_S = 15.0

#: the order in which units start, by scene kind: the longest compilations first (see the
#: module docstring)
KIND_ORDER = {"contact": 0, "system": 1, "body": 2}

PREFIX = "director-bench compile:"


def _say(text: str) -> None:
    print(f"{PREFIX} {text}", file=sys.stderr, flush=True)


def short_spec(spec: RunSpec) -> RunSpec:
    """``spec`` cut to :data:`SHORT_SAVES` saved samples, keeping nothing on disk."""
    return dataclasses.replace(
        spec, t_end=spec.dt * spec.saving * SHORT_SAVES, segment=None, keep="none"
    )


def units(specs) -> list[list[RunSpec]]:
    """The short runs of ``specs`` that compile something with numba, one per scenario,
    engine and integrator (at its first step), in units of the same warm-ups, the longest
    compilations first."""
    from reports.run.runner import _bundled, warm_ups

    seen, groups = set(), {}
    for s in specs:
        ident = (s.scenario.name, s.engine, s.integrator)
        if ident in seen or s.accuracy is not None or _bundled(s.engine):
            continue
        keys = frozenset(warm_ups(s))
        if not keys:
            continue
        seen.add(ident)
        groups.setdefault(keys, []).append(short_spec(s))
    order = sorted(
        groups.items(),
        key=lambda kv: (min(KIND_ORDER.get(s.scenario.kind, 3) for s in kv[1]), sorted(kv[0])),
    )
    return [g for _, g in order]


def unit_keys(unit) -> set[str]:
    """Every warm-up key of a unit (the pool's gate: one unit compiles each)."""
    from reports.run.runner import warm_ups

    return {k for s in unit for k in warm_ups(s)}


# -- in each process: what numba compiles ----------------------------------------------------

_compiled: list[tuple[str, float]] = []
_listener = None


def listen() -> None:
    """Print a line when numba starts and ends a top-level compilation in this process, and
    record (name, CPU s of this thread) of each, until :func:`stop`; once per process."""
    global _listener
    if _listener is not None:
        return
    import numba.core.event as ev

    depth = []

    class Listener(ev.Listener):
        def on_start(self, event):
            disp = (event.data or {}).get("dispatcher")
            fn = getattr(disp, "py_func", None)
            name = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', disp)}"
            depth.append((name, time.thread_time()))
            if len(depth) == 1:
                _say(f"compiling {name} ...")

        def on_end(self, event):
            if not depth:
                return
            name, c0 = depth.pop()
            if not depth:  # a top-level compilation (its callees are part of it)
                cpu = time.thread_time() - c0
                _compiled.append((name, cpu))
                _say(f"compiled {name} ({cpu:.1f} s CPU)")

    _listener = Listener()
    ev.register("numba:compile", _listener)


def stop() -> None:
    """No more lines nor records of numba's compilations in this process."""
    global _listener
    if _listener is not None:
        import numba.core.event as ev

        ev.unregister("numba:compile", _listener)
        _listener = None


def drain() -> list[tuple[str, float]]:
    """The compilations recorded since the last call."""
    out = _compiled[:]
    _compiled.clear()
    return out


def compile_unit(unit: list[RunSpec]) -> tuple[list, list]:
    """Execute a unit's short runs here: (the compilations they went through, (label,
    message) of each run that errored)."""
    from reports.run.runner import execute

    listen()
    errors = []
    for s in unit:
        row = execute(s)
        if row["status"] == "error":
            errors.append((f"{s.scenario.name}/{s.engine}/{s.integrator}", row["message"]))
    return drain(), errors


# -- the command -------------------------------------------------------------------------------


def compile_specs(specs, jobs: int | None = None, preload: tuple[str, ...] = ()) -> dict:
    """Compile what ``specs`` go through (see the module docstring); returns {"kernels":
    [(name, CPU s)], "errors": [(run, message)], "units": n, "runs": n, "seconds": wall}."""
    import tempfile

    from reports.run.parallel import make_mapper

    t0 = time.perf_counter()
    work = units(specs)
    n_runs = sum(len(u) for u in work)
    jobs = jobs or os.cpu_count() or 1
    kernels, errors = drain(), []  # what planning compiled here (the loops' check)
    if not work:
        return dict(kernels=kernels, errors=errors, units=0, runs=0, seconds=0.0)
    _say(f"{n_runs} short runs in {len(work)} units, on {min(jobs, len(work))} process(es)")
    done = threading.Event()

    def heartbeat():
        while not done.wait(HEARTBEAT_S):
            t = time.perf_counter() - t0
            _say(f"still compiling ({int(t) // 60}:{int(t) % 60:02d} so far)")

    threading.Thread(target=heartbeat, daemon=True).start()
    try:
        with tempfile.TemporaryDirectory(prefix="director-bench-compile-") as logs:
            mapper = make_mapper(min(jobs, len(work)), None, logs, preload)
            for k, (got, errs) in enumerate(mapper(compile_unit, work, keys=unit_keys), 1):
                kernels += got
                errors += errs
                _say(f"[{k}/{len(work)}] units done, {len(kernels)} kernel(s) compiled so far")
    finally:
        done.set()
    return dict(
        kernels=kernels,
        errors=errors,
        units=len(work),
        runs=n_runs,
        seconds=time.perf_counter() - t0,
    )
