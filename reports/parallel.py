"""Where runs execute: here, in a local process pool, or on a Dask cluster.

Each executor is a *mapper*: ``mapper(fn, specs)`` yields ``fn(spec)`` results as they finish
(in completion order). The runner commits each row as it arrives, so an interrupted sweep
keeps every finished run wherever it ran, and a rerun skips them.

Runs are independent and deterministic (each engine adapter builds its model from the
scenario alone), so a parallel or distributed sweep gives the same rows as a serial one apart
from the timing columns. Timings measured with several runs sharing the machine are noisier:
use ``--jobs 1`` when the cost columns matter.

Engines run with the output folder's ``logs/`` as their working directory (MuJoCo writes
MUJOCO_LOG.TXT into the current directory), so nothing is written outside the output folder.
Local worker processes end with their parent, also when it is killed (SIGKILL included):
each asks the kernel for SIGKILL on its parent's death (Linux ``PR_SET_PDEATHSIG``) and
watches its parent's process id as a fallback.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable
from pathlib import Path

from scenarios.schema import InputError


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


def serial(out: Path | None = None) -> Callable:
    """Run each spec in this process, in order (engines' log files into ``out/logs``)."""

    def mapper(fn, specs):
        with working_directory(log_dir(out)):
            yield from map(fn, specs)

    mapper.serial = True
    return mapper


def _die_with_parent(parent: int, logs: str | None) -> None:
    """Initializer of a local worker: end when the parent dies; run engines in ``logs``."""
    with contextlib.suppress(Exception):  # Linux only; the watcher below covers the rest
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1
    if os.getppid() != parent:
        os._exit(1)

    def watch():
        import time

        while True:
            time.sleep(1.0)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
    if logs:
        os.chdir(logs)


def process_pool(jobs: int | None = None, out: Path | None = None) -> Callable:
    """A mapper over a local pool of ``jobs`` processes (default: the number of cores)."""
    jobs = jobs or os.cpu_count() or 1

    def mapper(fn, specs):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        specs = list(specs)
        if jobs == 1 or len(specs) <= 1:
            yield from serial(out)(fn, specs)
            return
        logs = log_dir(out)
        # spawn, not fork: engines hold native state that does not survive a fork safely
        ctx = mp.get_context("spawn")
        pool = ProcessPoolExecutor(
            max_workers=jobs,
            mp_context=ctx,
            initializer=_die_with_parent,
            initargs=(os.getpid(), str(logs) if logs else None),
        )
        futures = [pool.submit(fn, s) for s in specs]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            for fut in futures:
                fut.cancel()
            pool.shutdown(wait=True, cancel_futures=True)

    return mapper


def dask_cluster(address: str, timeout: float = 20.0) -> Callable:
    """A mapper over the Dask cluster whose scheduler listens at ``address``
    (e.g. ``tcp://127.0.0.1:8786``). Needs ``pip install director-bench[dask]``; the workers
    need the suite installed and must see the output folder (same machine or shared disk).
    ``timeout``: seconds to wait for the scheduler before giving up with an error."""
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise InputError(
            f"--scheduler {address}: Dask's distributed package is not installed "
            "(pip install 'director-bench[dask]')"
        ) from exc

    def connect():
        try:
            return Client(address, timeout=f"{timeout}s")
        except OSError as exc:
            raise InputError(f"--scheduler {address}: cannot reach the scheduler ({exc})") from exc

    connect().close()  # an unreachable scheduler is bad input, said before anything runs

    def mapper(fn, specs):
        specs = list(specs)
        client = connect()
        try:
            futures = client.map(fn, specs, pure=False)
            try:
                for fut in as_completed(futures):
                    yield fut.result()
            except BaseException:
                client.cancel(futures)
                raise
        finally:
            client.close()

    return mapper


def make_mapper(
    jobs: int | None = None, scheduler: str | None = None, out: Path | None = None
) -> Callable:
    if scheduler:
        return dask_cluster(scheduler)
    if jobs == 1:
        return serial(out)
    return process_pool(jobs, out)
