"""Sweeps on a real Dask cluster: a scheduler and two worker processes started here on
loopback, through the running interpreter (``python -m distributed.cli...``, so no `dask`
command needs to be on PATH). The rows equal a serial run's (runs are deterministic), and an
interrupted distributed sweep resumes without redoing finished runs."""

import contextlib
import socket
import subprocess
import sys
import threading
import time

import pandas as pd
import pytest

import scenarios
from reports.run.parallel import ClusterLost, Mapper, dask_cluster
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.results import read_results
from reports.store.runs import RunSpec

pytest.importorskip(
    "distributed", reason="Dask's distributed is not installed (pip install 'director-bench[dask]')"
)
SCHEDULER = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def cluster():
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [
        subprocess.Popen(
            [*SCHEDULER, "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    for _ in range(2):
        procs.append(
            subprocess.Popen(
                [
                    *WORKER,
                    address,
                    "--nworkers",
                    "1",
                    "--nthreads",
                    "1",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
    from distributed import Client

    deadline = time.monotonic() + 90
    try:
        while True:
            try:
                with Client(address, timeout="5s") as c:
                    if len(c.scheduler_info()["workers"]) == 2:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail("the Dask scheduler and two workers did not come up in 90 s")
            time.sleep(0.5)
        yield address
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope="module")
def specs():
    sc = scenarios.load("dzhanibekov").replace(t_end=1.0, dt_sweep=(4e-3, 2e-3))
    return plan(
        [sc], ["director", "mujoco", "exact"], ["rattle", "rattle4", "Euler", "RK4", "reference"]
    )


COLS = [
    "scenario",
    "engine",
    "integrator",
    "dt",
    "status",
    "nstep",
    "energy_drift_max",
    "momentum_drift_max",
    "attitude_error_max",
    "omega_error_max",
    "convergence_order",
]


def test_distributed_sweep_equals_serial(tmp_path, cluster, specs):
    serial, _ = run_suite(specs, tmp_path / "serial", progress=False)
    dist, n = run_suite(specs, tmp_path / "dask", progress=False, mapper=dask_cluster(cluster))
    assert n == len(specs)
    pd.testing.assert_frame_equal(serial[COLS], dist[COLS])
    # the workers wrote the trajectories into the shared output folder
    assert all((tmp_path / "dask" / p).exists() for p in dist["trajectory"])


def test_interrupted_distributed_sweep_resumes(tmp_path, cluster, specs):
    mapper = dask_cluster(cluster)

    def interrupted(fn, todo, keys=None):
        for i, row in enumerate(mapper(fn, todo)):
            if i == 4:
                raise KeyboardInterrupt
            yield row

    with pytest.raises(KeyboardInterrupt):
        run_suite(specs, tmp_path, progress=False, mapper=Mapper(interrupted))
    assert len(read_results(tmp_path)) == 4
    df, n = run_suite(specs, tmp_path, progress=False, mapper=mapper)
    assert n == len(specs) - 4 and len(df) == len(specs)


def test_unreachable_scheduler_is_a_clear_error(tmp_path, specs):
    port = free_port()  # nothing listens there
    with pytest.raises(ValueError, match="cannot reach the scheduler"):
        run_suite(
            specs[:1],
            tmp_path,
            progress=False,
            mapper=dask_cluster(f"tcp://127.0.0.1:{port}", timeout=2),
        )


def test_cli_accepts_scheduler(tmp_path, cluster):
    out = tmp_path / "o"
    code = subprocess.run(
        [
            sys.executable,
            "-m",
            "reports.cli",
            "run",
            "major_axis_spin",
            "--engines",
            "director",
            "--integrators",
            "rattle",
            "--t-end",
            "1",
            "--no-sweep",
            "--out",
            str(out),
            "--scheduler",
            cluster,
            "--quiet",
            "--no-report",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert code.returncode == 0, code.stderr
    assert list(read_results(out)["status"]) == ["ok"]


# -- a cluster that loses its workers or its scheduler -------------------------------------------


def start_cluster(n_workers: int):
    """A scheduler and ``n_workers`` workers of one thread, each in a session of its own (so
    that a worker and its nanny can be killed together); returns (address, scheduler, workers)."""
    from distributed import Client

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    scheduler = subprocess.Popen(
        [*SCHEDULER, "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], **quiet
    )
    args = ["--nworkers", "1", "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"]
    workers = [subprocess.Popen([*WORKER, address, *args], **quiet) for _ in range(n_workers)]
    deadline = time.monotonic() + 90
    while True:
        try:
            with Client(address, timeout="5s") as c:
                if len(c.scheduler_info()["workers"]) == n_workers:
                    return address, scheduler, workers
        except OSError:
            pass
        if time.monotonic() > deadline:
            pytest.fail("the Dask scheduler and its workers did not come up in 90 s")
        time.sleep(0.5)


def kill(proc) -> None:
    import os
    import signal

    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def kill_after_first_row(folder, proc) -> threading.Thread:
    """Kill ``proc`` (its whole session) once the store in ``folder`` holds a row."""

    def watch():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            with contextlib.suppress(Exception):
                if len(read_results(folder, all_rows=True)):
                    break
            time.sleep(0.2)
        kill(proc)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


@pytest.fixture
def short_and_long():
    """A run of a second, then one of ~1e7 steps (far longer than the test waits)."""
    sc = scenarios.load("major_axis_spin").replace(dt_sweep=())
    return [
        RunSpec(sc, "director", "rattle", 1e-3, t_end=1.0),
        RunSpec(sc, "director", "rattle", 1e-5, t_end=100.0, save_every=10_000),
    ]


def test_a_killed_worker_is_detected_and_finished_rows_kept(tmp_path, short_and_long):
    address, scheduler, (worker,) = start_cluster(1)
    try:
        watcher = kill_after_first_row(tmp_path, worker)
        mapper = dask_cluster(address, no_worker_s=3.0)
        with pytest.raises(ClusterLost, match="no worker for 3 s .* 1 of 2 units") as info:
            run_suite(short_and_long, tmp_path, progress=False, mapper=mapper)
        watcher.join()
    finally:
        kill(scheduler)
    assert "dask worker" in str(info.value) and "rerun the same command" in str(info.value)
    df = read_results(tmp_path)
    assert df[["dt", "status"]].values.tolist() == [[1e-3, "ok"]]


def test_a_killed_scheduler_is_a_message_not_a_traceback(tmp_path, short_and_long, capsys):
    """`run --scheduler` whose scheduler is killed mid-run: exit 1, what happened and what to
    do, the finished row kept."""
    from reports.cli import main

    address, scheduler, (worker,) = start_cluster(1)
    try:
        watcher = kill_after_first_row(tmp_path / "out", scheduler)
        # as short_and_long: 1e5 steps at dt 1e-3, then 1e7 at 1e-5 (far longer than the
        # kill takes; at --t-end 1 the second unit's 1e5 steps could finish before it)
        code = main(["run", "major_axis_spin", "--engines", "director", "--integrators",
                     "rattle", "--dt", "1e-3,1e-5", "--t-end", "100", "--save-every", "10000",
                     "--out", str(tmp_path / "out"), "--scheduler", address, "--quiet",
                     "--no-report"])  # fmt: skip
        watcher.join()
    finally:
        kill(worker)
    err = capsys.readouterr().err
    assert code == 1, err
    assert f"the Dask scheduler at {address} went away" in err and "Traceback" not in err
    assert "1 of 2 units of work did not finish" in err
    assert read_results(tmp_path / "out")["dt"].tolist() == [1e-3]


def test_a_scheduler_lost_while_a_result_is_fetched_is_the_same_message(monkeypatch):
    """The scheduler may die between the wait that sees a unit finished and the fetch of its
    result (Dask then raises CommClosedError from the fetch): the same "went away" message as
    when the watcher sees the client stop, counting the units not received."""
    import distributed
    from distributed.comm.core import CommClosedError

    from reports.run.parallel import _watch

    class Unit:
        def __init__(self, value, lost=False):
            self.value, self.lost = value, lost

        def result(self):
            if self.lost:
                raise CommClosedError("in <TCP (closed) ConnectionPool.gather>: Stream is closed")
            return self.value

        def cancelled(self):
            return False

    first, second = Unit(["row 1"]), Unit(None, lost=True)
    rounds = iter([[first], [second]])

    def wait(futures, timeout, return_when):
        done = next(rounds)
        return type("Res", (), {"done": done, "not_done": [f for f in futures if f not in done]})

    monkeypatch.setattr(distributed, "wait", wait)
    client = type("Client", (), {"status": "running", "scheduler_info": lambda self: {
        "workers": {"w": None}}})()  # fmt: skip
    got = []
    with pytest.raises(ClusterLost, match=r"tcp://x:1 went away: 1 of 2 units"):
        for rows in _watch(client, {first: "a", second: "b"}, "tcp://x:1", 30.0):
            got.append(rows)
    assert got == [["row 1"]]
