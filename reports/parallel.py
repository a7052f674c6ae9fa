"""Where runs execute: here, in a local process pool, or on a Dask cluster.

Each executor is a *mapper*: ``mapper(fn, specs)`` yields ``fn(spec)`` results as they finish
(in completion order). The runner writes each row as it arrives, so an interrupted sweep keeps
every finished run wherever it ran, and a rerun skips them.

Runs are independent and deterministic (each engine adapter builds its model from the
scenario alone), so a parallel or distributed sweep gives the same rows as a serial one apart
from the timing columns. Timings measured with several runs sharing the machine are noisier:
use ``--jobs 1`` when the cost columns matter.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator


def serial(fn: Callable, specs: Iterable) -> Iterator:
    """Run each spec in this process, in order."""
    return map(fn, specs)


def process_pool(jobs: int | None = None) -> Callable:
    """A mapper over a local pool of ``jobs`` processes (default: the number of cores)."""
    jobs = jobs or os.cpu_count() or 1

    def mapper(fn, specs):
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        specs = list(specs)
        if jobs == 1 or len(specs) <= 1:
            yield from map(fn, specs)
            return
        # spawn, not fork: engines hold native state that does not survive a fork safely
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            futures = [pool.submit(fn, s) for s in specs]
            try:
                for fut in as_completed(futures):
                    yield fut.result()
            except BaseException:
                for fut in futures:
                    fut.cancel()
                raise

    return mapper


def dask_cluster(address: str, timeout: float = 20.0) -> Callable:
    """A mapper over the Dask cluster whose scheduler listens at ``address``
    (e.g. ``tcp://127.0.0.1:8786``). Needs ``pip install director-bench[dask]``; the workers
    need the suite installed and must see the output folder (same machine or shared disk).
    ``timeout``: seconds to wait for the scheduler before giving up with an error."""
    try:
        from distributed import Client, as_completed
    except ImportError as exc:
        raise ValueError(
            f"--scheduler {address}: Dask's distributed package is not installed "
            "(pip install 'director-bench[dask]')"
        ) from exc

    def mapper(fn, specs):
        specs = list(specs)
        try:
            client = Client(address, timeout=f"{timeout}s")
        except OSError as exc:
            raise ValueError(f"--scheduler {address}: cannot reach the scheduler ({exc})") from exc
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


def make_mapper(jobs: int | None = None, scheduler: str | None = None) -> Callable:
    if scheduler:
        return dask_cluster(scheduler)
    if jobs == 1:
        return serial
    return process_pool(jobs)
