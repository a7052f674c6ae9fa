"""Where runs execute: here, in a local process pool, or on a Dask cluster.

Each executor is a :class:`Mapper`: ``mapper(fn, specs)`` yields ``fn(spec)`` results as they
finish (in completion order). The runner commits each row as it arrives, so an interrupted sweep
keeps every finished run wherever it ran, and a rerun skips them.

Runs are independent and deterministic (each engine adapter builds its model from the
scenario alone), so a parallel or distributed sweep gives the same rows as a serial one apart
from the timing columns. Timings measured with several runs sharing the machine are noisier:
use ``--jobs 1`` when the cost columns matter.

Engines run with the output folder's ``logs/`` as their working directory (MuJoCo writes
MUJOCO_LOG.TXT into the current directory), so nothing is written outside the output folder.
Local worker processes end with the main process, also when it is killed (SIGKILL included):
each asks the kernel for SIGKILL on its parent's death (Linux ``PR_SET_PDEATHSIG``) and
watches its parent's process id as a fallback. On Linux a worker's parent is a fork server
(below), killed in turn by the kernel when the main process dies (reports.run.server_guard);
elsewhere it is the main process.

How local workers start: engines hold native state that does not survive a fork safely, so a
worker is never a fork of a process that has imported an engine. On Linux the workers are
forked from a fork server (multiprocessing's ``forkserver``) that imports only
:data:`PRELOAD` (the suite's own modules, numpy, scipy, numba, pandas, pyarrow) and, when
asked, JAX: modules whose import starts no thread other than OpenBLAS's pool, which OpenBLAS
itself stops before a fork, and the background thread of Arrow's allocator (jemalloc), whose
fork handlers hold its locks across the fork (the child runs without that thread: seen with
pyarrow 26), and initialises no device (JAX warns at a fork only once a backend is
initialised; its import initialises none). The server starts when the mapper is made, so its
imports overlap the main process's planning, and each worker starts with them done instead of
importing them again. Elsewhere workers are spawned (a fresh interpreter each).

Lost workers: a local worker that dies (killed, out of memory) breaks the pool, and a Dask
cluster whose scheduler goes away, or which has no worker for :data:`NO_WORKER_S` seconds
while runs are pending, is given up: :class:`ClusterLost` says how many runs did not finish
and what to do; every finished row is already in the store. A run whose Dask worker died
each time it was tried (Dask's ``KilledWorker``) is an ``error`` row; the others go on.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from scenarios.schema import InputError

#: seconds between checks of a Dask cluster while runs are pending
POLL_S = 1.0

#: a Dask cluster with no worker for this long while runs are pending is lost (s): long
#: enough for a worker to restart (its nanny restarts it within seconds)
NO_WORKER_S = 30.0


class ClusterLost(RuntimeError):
    """The workers or the scheduler running the sweep went away; the message says how many
    runs did not finish and what to do. Finished rows are kept."""


def log_dir(out: Path | None) -> Path | None:
    if out is None:
        return None
    path = Path(out) / "logs"
    path.mkdir(parents=True, exist_ok=True)
    return path


@contextlib.contextmanager
def working_directory(path: Path | None):
    """Run the block with ``path`` as the current directory (nothing if None)."""
    if path is None:
        yield
        return
    old = os.getcwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


@dataclass(frozen=True)
class Mapper:
    """Where units of work run: ``mapper(fn, units, keys, needs, provides)`` yields
    ``fn(unit)`` for each unit as it finishes, by ``run(fn, units, keys, needs, provides)``.
    ``keys(unit)``, optional, names the compilations a unit goes through the first time in a
    process: a mapper that runs units side by side uses it to keep two workers from compiling
    the same thing at once (:func:`process_pool`); the others ignore it. ``needs(unit)`` and
    ``provides(unit)``, optional: names of work a unit must wait for and names it provides
    when it finishes (a scenario's timing pass waits for its runs, reports.run.timing).
    ``in_process``: the units run here, one after another in the order given (a run can then
    show its own progress while it runs); ``waits``: the mapper honours ``needs`` (in order,
    or by holding a unit back), so units that need others may be given to it."""

    run: Callable[..., Iterator]
    in_process: bool = False
    waits: bool = False

    def __call__(self, fn, units, keys=None, needs=None, provides=None) -> Iterator:
        if needs is None and provides is None:  # a mapper that knows no needs
            return self.run(fn, units, keys)
        return self.run(fn, units, keys, needs, provides)


def serial(out: Path | None = None) -> Mapper:
    """Run each spec in this process, in order (engines' log files into ``out/logs``)."""

    def mapper(fn, specs, keys=None, needs=None, provides=None):
        # in the order given: a unit placed after the units it needs waits for them
        with working_directory(log_dir(out)):
            yield from map(fn, specs)

    return Mapper(mapper, in_process=True, waits=True)


def _parent_of(pid: int) -> int | None:
    """The parent process id of ``pid`` (Linux /proc), or None if it cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return int(f.read().rsplit(b")", 1)[1].split()[1])
    except (OSError, ValueError, IndexError):
        return None


def _die_with_parent(main: int, logs: str | None) -> None:
    """Initializer of a local worker: end when the main process ``main`` dies (the worker's
    parent is ``main`` itself, or a fork server that ``main`` started and that ends with it);
    run engines in ``logs``."""
    from reports.run.server_guard import kill_on_parent_death

    kill_on_parent_death()  # Linux only; the watcher below covers the rest
    parent = os.getppid()

    def orphaned() -> bool:
        # the parent changed (it died), or the fork server no longer has main as its parent
        return os.getppid() != parent or (parent != main and _parent_of(parent) != main)

    if orphaned():  # also when the parent died before the kernel was asked above
        os._exit(1)

    def watch():
        import time

        while True:
            time.sleep(1.0)
            if orphaned():
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
    if logs:
        os.chdir(logs)


#: what a local worker's fork server imports before it forks the workers (see the module
#: docstring): what every worker imports for its first runs, none of it an engine; every one
#: starts no thread but OpenBLAS's pool and Arrow's allocator's (pyarrow, imported by pandas)
PRELOAD = (
    "reports.run.server_guard",  # first: the server dies with the main process from then on
    "numpy",
    "scipy.linalg",
    "numba",
    "pandas",  # pyarrow's tables import it (each run's trajectory file)
    "pyarrow.parquet",
    "reports.run.runner",
    "reports.run.body",  # a single body's runs
    "references.engines",
    "references.exact",
    "references.engines.director.adapter",
    "reports.run.system",  # a system of bodies' runs
    "references.exact.multibody",
    "references.engines.director.system",
    "references.engines.exact.system",
)


def _context(preload: tuple[str, ...]):
    """The multiprocessing context of local workers: a fork server importing ``preload``
    (Linux), else spawn."""
    import multiprocessing as mp
    import sys

    if not sys.platform.startswith("linux"):
        return mp.get_context("spawn")
    ctx = mp.get_context("forkserver")
    # a server already running in this process (an earlier pool) keeps what it imported
    ctx.set_forkserver_preload(list(preload))
    from multiprocessing import forkserver

    from reports.run.server_guard import PARENT_VARIABLE

    # the server starts importing now, while the caller plans the runs; it learns this
    # process's id from its environment (reports.run.server_guard)
    os.environ[PARENT_VARIABLE] = str(os.getpid())
    try:
        forkserver.ensure_running()
    finally:
        del os.environ[PARENT_VARIABLE]
    return ctx


def process_pool(
    jobs: int | None = None, out: Path | None = None, preload: tuple[str, ...] = ()
) -> Mapper:
    """A mapper over a local pool of ``jobs`` processes (default: the number of cores).

    Making the mapper with more than one job starts the workers' fork server, which imports
    :data:`PRELOAD` and ``preload`` (modules safe to import before a fork, see the module
    docstring; e.g. ``("jax",)`` when the runs include MJX's) while the caller goes on.

    ``mapper(fn, units, keys)``: ``keys(unit)``, optional, names the compilations (numba
    kernels, JAX functions) the unit goes through the first time in a process. A unit is
    handed to a worker only when no unit in flight is compiling one of its keys not compiled
    yet: the first unit of a key compiles it (and writes the compiler's on-disk cache), the
    others wait for it and then load the cache, while the other workers take units that
    need nothing being compiled. Without this, two workers would compile the same kernels at
    once (numba has no lock between processes), each paying the whole compilation. Units
    are handed out in the order given, skipping those that must wait; at most
    :data:`IN_FLIGHT_PER_WORKER` per worker are in flight at a time."""
    jobs = jobs or os.cpu_count() or 1
    ctx = _context((*PRELOAD, *preload)) if jobs > 1 else None

    def mapper(fn, specs, keys: Callable | None = None, needs=None, provides=None):
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        specs = list(specs)
        if jobs == 1 or len(specs) <= 1:
            yield from serial(out)(fn, specs)
            return
        logs = log_dir(out)
        # never a fork of this process: engines hold native state that does not survive one
        pool = ProcessPoolExecutor(
            max_workers=jobs,
            mp_context=ctx,
            initializer=_die_with_parent,
            initargs=(os.getpid(), str(logs) if logs else None),
        )
        gate = _Gate(specs, keys, needs, provides)
        running: dict = {}  # future -> (the keys it compiles, its unit)
        try:
            n_done = 0
            while gate.pending or running:
                while len(running) < IN_FLIGHT_PER_WORKER * jobs:
                    unit, compiles = gate.next()
                    if unit is None:
                        break
                    running[pool.submit(fn, unit)] = (compiles, unit)
                if not running:  # every unit left waits for one that never ran
                    raise RuntimeError(f"{len(gate.pending)} unit(s) wait for work never given")
                finished, _ = wait(list(running), return_when=FIRST_COMPLETED)
                for fut in finished:
                    compiles, unit = running.pop(fut)
                    gate.compiled(compiles, unit)
                    try:
                        result = fut.result()
                    except BrokenProcessPool:
                        raise ClusterLost(
                            f"a local worker process died (killed, or out of memory): "
                            f"{len(specs) - n_done} of {len(specs)} units of work did not "
                            "finish; finished runs are kept in the results store: rerun the "
                            "same command to run the rest (--jobs 1 runs them in this process)"
                        ) from None
                    n_done += 1
                    yield result
        finally:
            for fut in running:
                fut.cancel()
            pool.shutdown(wait=True, cancel_futures=True)

    return Mapper(mapper, waits=True)


#: units of work in flight per local worker (running or queued): enough that a worker never
#: waits for the parent (which stores every row as it comes) to hand out its next unit; the
#: queue is first in, first out, so units still start in the order given
IN_FLIGHT_PER_WORKER = 4


class _Gate:
    """Which unit to hand out next (see :func:`process_pool`): ``next()`` gives the first
    pending unit none of whose keys is being compiled by a unit in flight and whose
    ``needs`` (names of work, e.g. run ids) have all been ``provided`` by finished units,
    with the keys it will compile (None when every pending unit must wait);
    ``compiled(keys, unit)`` marks them done when that unit finishes, and what it
    provides."""

    def __init__(self, units: list, keys: Callable | None, needs=None, provides=None):
        self.pending = [
            (u, frozenset(keys(u) if keys else ()), frozenset(needs(u) if needs else ()))
            for u in units
        ]
        self.done: set[str] = set()
        self.compiling: set[str] = set()
        self.provides = provides
        self.provided: set = set()

    def next(self) -> tuple:
        for i, (unit, keys, need) in enumerate(self.pending):
            todo = keys - self.done
            if not todo & self.compiling and need <= self.provided:
                del self.pending[i]
                self.compiling |= todo
                return unit, todo
        return None, set()

    def compiled(self, keys: set, unit=None) -> None:
        self.compiling -= keys
        self.done |= keys
        if self.provides is not None and unit is not None:
            self.provided |= set(self.provides(unit))


def dask_cluster(address: str, timeout: float = 20.0, no_worker_s: float | None = None) -> Mapper:
    """A mapper over the Dask cluster whose scheduler listens at ``address``
    (e.g. ``tcp://127.0.0.1:8786``). Needs ``pip install director-bench[dask]``; the workers
    need the suite installed and must see the output folder (same machine or shared disk).
    ``timeout``: seconds to wait for the scheduler before giving up with an error;
    ``no_worker_s``: seconds without any worker, runs pending, before the cluster counts as
    lost (default :data:`NO_WORKER_S`)."""
    try:
        from distributed import Client
    except ImportError as exc:
        raise InputError(
            f"--scheduler {address}: Dask's distributed package is not installed "
            "(pip install 'director-bench[dask]')"
        ) from exc

    def connect():
        try:
            return Client(address, timeout=f"{timeout}s")
        except (OSError, ValueError, TypeError) as exc:  # unreachable, or not an address
            raise InputError(f"--scheduler {address}: cannot reach the scheduler ({exc})") from exc

    connect().close()  # an unreachable scheduler is bad input, said before anything runs

    def mapper(fn, specs, keys=None, needs=None, provides=None):
        specs = list(specs)
        client = connect()
        try:
            futures = client.map(fn, specs, pure=False)
            try:
                yield from _watch(
                    client,
                    dict(zip(futures, specs, strict=True)),
                    address,
                    NO_WORKER_S if no_worker_s is None else no_worker_s,
                )
            except BaseException:
                with contextlib.suppress(Exception):
                    client.cancel(futures)
                raise
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=10)

    return Mapper(mapper)


def _watch(client, spec_of: dict, address: str, no_worker_s: float):
    """Yield the results of the futures in ``spec_of`` as they finish, checking the cluster
    every :data:`POLL_S` seconds (see the module docstring)."""
    import time
    from concurrent.futures import CancelledError

    from distributed import wait
    from distributed.comm.core import CommClosedError
    from distributed.scheduler import KilledWorker

    pending, total, idle_since = set(spec_of), len(spec_of), None
    finished = 0

    def went_away() -> ClusterLost:
        return _lost(
            f"the Dask scheduler at {address} went away: {total - finished} of {total} units "
            "of work did not finish; finished runs are kept in the results store. "
            "Restart the scheduler and its workers and rerun the same command (finished "
            "runs are skipped), or run without --scheduler"
        )

    while pending:
        try:
            res = wait(list(pending), timeout=POLL_S, return_when="FIRST_COMPLETED")
            done, pending = set(res.done), set(res.not_done)
        except (TimeoutError, CancelledError):
            done = set()
        for fut in done:
            try:
                result = fut.result()
            except KilledWorker as exc:
                why = f"its Dask worker died each time it ran it: {exc}"
                result = _error_rows(spec_of[fut], why)
            except CommClosedError:  # the scheduler died between the wait and the fetch
                raise went_away() from None
            finished += 1
            yield result
        if client.status != "running" or any(f.cancelled() for f in pending):
            raise went_away()
        try:
            workers = len(client.scheduler_info()["workers"])
        except Exception:  # noqa: BLE001 - the next round sees the client's status
            continue
        idle_since = None if workers else (idle_since or time.monotonic())
        if pending and idle_since is not None and time.monotonic() - idle_since > no_worker_s:
            raise _lost(
                f"the Dask cluster at {address} has had no worker for {no_worker_s:g} s "
                f"(killed or lost) with {len(pending)} of {total} units of work pending; "
                "finished runs are kept in the results store. Start workers (`dask worker "
                f"{address}`) and rerun the same command (finished runs are skipped), or run "
                "without --scheduler"
            )


def _lost(message: str) -> ClusterLost:
    """The error for a lost cluster, after silencing Dask's loggers: its client would go on
    logging reconnection attempts and their tracebacks after our message."""
    import logging

    names = [n for n in logging.root.manager.loggerDict if n.startswith(("distributed", "tornado"))]
    for name in [*names, "asyncio"]:
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    return ClusterLost(message)


def _error_rows(unit, message: str):
    """The ``error`` rows of a unit of work (a RunSpec, or a bundle of them) that could not
    run, shaped like what the mapped function returns for it."""
    from reports.store.runs import blank_row, finish_time

    def row(spec):
        r = blank_row(spec)
        r.update(status="error", message=message, finished_at=finish_time())
        return r

    return [row(s) for s in unit] if isinstance(unit, list) else row(unit)


def make_mapper(
    jobs: int | None = None,
    scheduler: str | None = None,
    out: Path | None = None,
    preload: tuple[str, ...] = (),
) -> Mapper:
    """The mapper of a command's options: a Dask cluster (``scheduler``), this process
    (``jobs`` 1) or a local pool (:func:`process_pool`, whose workers' fork server also
    imports ``preload``)."""
    if scheduler:
        return dask_cluster(scheduler)
    if jobs == 1:
        return serial(out)
    return process_pool(jobs, out, preload)
