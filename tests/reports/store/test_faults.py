"""Fault injection: results survive kill -9, concurrent writers, damaged stores, read-only
folders and a full disk. Each test counts rows lost (a run finished and committed, or run to
completion after recovery, that the store does not hold) and rows wrong (a stored row whose
deterministic content differs from a clean run's): both must be 0.

The long variants (many kill points) are marked slow; the default run keeps one of each.
"""

from __future__ import annotations

import math
import os
import random
import re
import resource
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from reports.store.results import Store, StoreDamaged, read_results
from reports.store.runs import NUMERIC_COLUMNS, RESULT_COLUMNS, TIMING_COLUMNS

#: columns that may differ between two runs of the same configuration (timings, the time of
#: day); every other column is deterministic and must be equal
VOLATILE = TIMING_COLUMNS | {"convergence_order", "convergence_points"}

RUN_ARGS = [
    "run", "free_tumbling", "heavy_top", "--engines", "mujoco,pybullet,exact",
    "--t-end", "2", "--quiet", "--no-report", "--jobs", "1",
]  # fmt: skip


def cli(*args, env=None, timeout=600, **kw):
    return subprocess.run(
        [sys.executable, "-m", "reports.cli", *args],
        capture_output=True, text=True, timeout=timeout, env=env, **kw,
    )  # fmt: skip


def rows_by_id(folder) -> dict:
    with Store(folder) as st:
        return {r["run_id"]: r for r in st.rows()}


def same(a: dict, b: dict) -> bool:
    for c in RESULT_COLUMNS:
        if c in VOLATILE:
            continue
        x, y = a.get(c), b.get(c)
        if c in NUMERIC_COLUMNS:
            x, y = float(x), float(y)
            if not (x == y or (math.isnan(x) and math.isnan(y))):
                return False
        elif x != y:
            return False
    return True


def count_lost_and_wrong(got: dict, clean: dict) -> tuple[int, int]:
    lost = sum(1 for k in clean if k not in got)
    wrong = sum(1 for k, r in got.items() if k not in clean or not same(r, clean[k]))
    return lost, wrong


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The rows of an undisturbed run of RUN_ARGS."""
    out = tmp_path_factory.mktemp("clean")
    proc = cli(*RUN_ARGS, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    rows = rows_by_id(out)
    assert len(rows) >= 20
    return rows


# -- kill -9 ------------------------------------------------------------------------------------


def kill_run_at(out: Path, delay: float) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "reports.cli", *RUN_ARGS, "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    time.sleep(delay)
    proc.send_signal(signal.SIGKILL)
    proc.wait()


def check_killed_then_resumed(out: Path, clean: dict) -> None:
    if (out / "results.sqlite").exists():
        partial = rows_by_id(out)  # readable, every checksum valid: no half row
        lost, wrong = count_lost_and_wrong(partial, clean)
        assert wrong == 0, f"{wrong} wrong rows after kill -9"
    proc = cli(*RUN_ARGS, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    lost, wrong = count_lost_and_wrong(rows_by_id(out), clean)
    assert (lost, wrong) == (0, 0)


def test_kill_9_during_a_run_loses_nothing(tmp_path, clean):
    kill_run_at(tmp_path / "out", 6.0)
    check_killed_then_resumed(tmp_path / "out", clean)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_kill_9_at_random_points_of_a_run(tmp_path, clean, seed):
    kill_run_at(tmp_path / "out", random.Random(seed).uniform(2.0, 14.0))
    check_killed_then_resumed(tmp_path / "out", clean)


WRITER = """
import sys
from reports.store.results import Store
from reports.store.runs import RESULT_COLUMNS
folder, tag, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
with Store(folder, create=True) as st:
    print("open", flush=True)
    for i in range(n):
        row = dict.fromkeys(RESULT_COLUMNS, "")
        row.update(run_id=f"{tag}-{i}", scenario=tag, engine="e", integrator="i", dt=0.001,
                   status="ok", message="x" * 2000, energy_drift_max=i * 1e-3)
        st.put(row)
"""


def writer(folder, tag, n):
    """A process writing ``n`` rows tagged ``tag``; its first line on stdout, "open", says the
    store is open and the rows start."""
    return subprocess.Popen(
        [sys.executable, "-c", WRITER, str(folder), tag, str(n)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip


def check_writer_rows(folder, tag, n_max) -> int:
    """Rows of one writer: a prefix 0..k-1 of what it meant to write, each row intact."""
    rows = [r for r in rows_by_id(folder).values() if r["scenario"] == tag]
    ids = sorted(int(r["run_id"].split("-")[1]) for r in rows)
    assert ids == list(range(len(ids))) and len(ids) <= n_max
    for r in rows:
        i = int(r["run_id"].split("-")[1])
        assert r["message"] == "x" * 2000 and r["energy_drift_max"] == i * 1e-3
    return len(ids)


@pytest.mark.parametrize("seed", [0])
def test_kill_9_during_store_writes_leaves_no_half_row(tmp_path, seed):
    rng = random.Random(seed)
    total = 0
    for k in range(3):
        p = writer(tmp_path, f"w{k}", 100000)
        # the kill lands 0.5-1.5 s into the writing, not into the start-up (imports take
        # seconds on a loaded machine: a kill before the store opens would test nothing)
        assert p.stdout.readline() == b"open\n", p.stderr.read().decode()
        time.sleep(rng.uniform(0.5, 1.5))
        p.send_signal(signal.SIGKILL)
        p.wait()
        total += check_writer_rows(tmp_path, f"w{k}", 100000)
    assert total > 0  # the writers did get rows in before being killed


def test_concurrent_writers_lose_nothing(tmp_path):
    procs = [writer(tmp_path, f"c{k}", 300) for k in range(3)]
    for p in procs:
        assert p.wait(timeout=300) == 0, p.stderr.read().decode()
    counts = [check_writer_rows(tmp_path, f"c{k}", 300) for k in range(3)]
    assert counts == [300, 300, 300]  # rows lost: 0


def test_two_run_commands_into_one_folder(tmp_path, clean):
    """Two `run` commands writing the same folder at once (different scenarios): the store
    holds both sets; and the rows equal a clean run's."""
    out = tmp_path / "out"
    args = [a for a in RUN_ARGS if a not in ("free_tumbling", "heavy_top")]
    a = subprocess.Popen(
        [sys.executable, "-m", "reports.cli", "run", "free_tumbling", *args[1:], "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    b = subprocess.Popen(
        [sys.executable, "-m", "reports.cli", "run", "heavy_top", *args[1:], "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    assert a.wait(timeout=600) == 0, a.stderr.read().decode()
    assert b.wait(timeout=600) == 0, b.stderr.read().decode()
    lost, wrong = count_lost_and_wrong(rows_by_id(out), clean)
    assert (lost, wrong) == (0, 0)


def test_a_lock_sqlite_answers_at_once_is_waited_out(monkeypatch):
    """SQLite answers some lock contention "database is locked" at once, without calling
    its busy handler (two connections both switching a new file to WAL: one is refused to
    avoid a deadlock). A store write waits that out within its bound and fails only once the
    bound is spent; another error is not retried."""
    import reports.store.results as results

    calls = []

    def locked_twice():
        calls.append(1)
        if len(calls) <= 2:
            raise sqlite3.OperationalError("database is locked")
        return "written"

    assert results._retry_busy(locked_twice, time.monotonic() + 5) == "written"
    assert len(calls) == 3
    calls.clear()
    with pytest.raises(sqlite3.OperationalError, match="locked"):
        results._retry_busy(lambda: locked_twice() and locked_twice(), time.monotonic() - 1)
    assert len(calls) == 1  # the bound is spent: one attempt
    calls.clear()

    def malformed():
        calls.append(1)
        raise sqlite3.OperationalError("disk I/O error")

    with pytest.raises(sqlite3.OperationalError, match="disk"):
        results._retry_busy(malformed, time.monotonic() + 5)
    assert len(calls) == 1


class _LockedOnce:
    """A connection whose first statement matching ``word`` answers "database is locked",
    as SQLite does at once (without its busy handler) to a writer that would deadlock."""

    refused: list  # one entry per refusal, shared by the connections of one test

    def __init__(self, con, word, refused):
        self.con, self.word, self.refused = con, word, refused

    def execute(self, sql, *args):
        if self.word in sql and not self.refused:
            self.refused.append(sql)
            raise sqlite3.OperationalError("database is locked")
        return self.con.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.con, name)


def test_a_store_waits_out_an_immediate_lock_on_open_and_on_write(tmp_path, monkeypatch):
    """Opening a new store and writing a row each meet one immediate "database is locked"
    (the answer two `run` commands starting into one folder got from SQLite, 1 trial in
    ~60 of three writers opening a new store at once): both wait it out and the row is
    stored."""
    import reports.store.results as results

    real_connect = sqlite3.connect
    opened, on_open, on_write = [], [], []

    def connect(*args, **kw):
        opened.append(1)
        return _LockedOnce(real_connect(*args, **kw), "journal_mode", on_open)

    monkeypatch.setattr(results.sqlite3, "connect", connect)
    with Store(tmp_path, create=True) as st:
        assert len(on_open) == 1 and len(opened) == 2  # refused once, opened at the 2nd try
        st._con = _LockedOnce(st._con, "BEGIN IMMEDIATE", on_write)
        row = dict.fromkeys(RESULT_COLUMNS, "")
        st.put({**row, "run_id": "r", "scenario": "s", "engine": "e", "integrator": "i", "dt": 0.1})
        assert len(on_write) == 1
    monkeypatch.undo()
    with Store(tmp_path) as st:
        assert [r["run_id"] for r in st.rows()] == ["r"]


# -- damaged stores -----------------------------------------------------------------------------


@pytest.fixture
def small_store(tmp_path):
    with Store(tmp_path, create=True) as st:
        for i in range(200):
            row = dict.fromkeys(RESULT_COLUMNS, "")
            row.update(run_id=f"r{i}", scenario="s", engine="e", integrator="i", dt=1e-3,
                       status="ok", message="m" * 500)  # fmt: skip
            st.put(row)
    return tmp_path


def test_truncated_store_is_reported_not_read(small_store, capsys):
    from reports.cli import main

    path = small_store / "results.sqlite"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(StoreDamaged, match="damaged"):
        read_results(small_store)
    assert main(["report", str(small_store)]) == 1
    err = capsys.readouterr().err
    assert "results.sqlite" in err and "damaged" in err and "Traceback" not in err


def test_garbled_store_is_reported_not_read(small_store):
    path = small_store / "results.sqlite"
    data = bytearray(path.read_bytes())
    rng = random.Random(1)
    # garble the content of the rows (past the header page): a value changes inside a row
    at = data.find(b"m" * 500, 4096)
    assert at > 0
    data[at + 10 : at + 14] = b"XXXX"
    path.write_bytes(bytes(data))
    with pytest.raises(StoreDamaged, match="checksum"):
        read_results(small_store)
    # random garbage over a page: malformed
    start = rng.randrange(4096, len(data) - 4096)
    data[start : start + 4096] = bytes(rng.randrange(256) for _ in range(4096))
    path.write_bytes(bytes(data))
    with pytest.raises(StoreDamaged):
        read_results(small_store)


def test_a_file_that_is_not_a_store(tmp_path):
    (tmp_path / "results.sqlite").write_text("not a database, just text " * 100)
    with pytest.raises(StoreDamaged, match="damaged"):
        read_results(tmp_path)


# -- read-only folder and a full disk -----------------------------------------------------------


def _read_only_command(folder: Path, args: list[str]) -> list[str] | None:
    """The command running ``args`` with ``folder`` read-only: permissions for a normal user;
    for root (whom permissions do not stop) a read-only bind mount in a private mount
    namespace (``unshare -rm``), or None where that is not possible here."""
    cmd = [sys.executable, "-m", "reports.cli", *args]
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return cmd
    unshare = shutil.which("unshare")
    if unshare is None:
        return None
    mount = f"mount --bind {folder} {folder} && mount -o remount,bind,ro {folder}"
    if subprocess.run([unshare, "-rm", "sh", "-c", mount], capture_output=True).returncode:
        return None
    return [unshare, "-rm", "sh", "-c", mount + ' && exec "$@"', "sh", *cmd]


def test_read_only_output_folder_is_refused_up_front(tmp_path):
    """A folder that cannot be written: exit 2 naming it, no traceback, nothing written."""
    ro = tmp_path / "ro"
    ro.mkdir()
    cmd = _read_only_command(ro, ["run", "free_tumbling", "--engines", "exact", "--out", str(ro)])
    if cmd is None:
        pytest.skip("running as root without user namespaces: no way to make a folder read-only")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    ro.chmod(0o755)
    assert proc.returncode == 2, proc.stderr
    assert str(ro) in proc.stderr and "cannot write" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert list(ro.iterdir()) == []


def _limit_file_size(nbytes):
    def pre():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))

    return pre


def test_full_disk_stops_the_run_and_a_rerun_completes(tmp_path, clean):
    """A file-size limit (ulimit -f) makes writes fail with EFBIG as on a full disk: the run
    stops with exit 1 and a message, no traceback; the rows it committed are right, and a
    rerun without the limit completes with no row lost or wrong."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "reports.cli", *RUN_ARGS, "--out", str(out)],
        capture_output=True, text=True, timeout=600, preexec_fn=_limit_file_size(150_000),
    )  # fmt: skip
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr and "rerun" in proc.stderr
    partial = rows_by_id(out)
    assert 0 < len(partial) < len(clean)
    assert count_lost_and_wrong(partial, clean)[1] == 0
    proc = cli(*RUN_ARGS, "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert count_lost_and_wrong(rows_by_id(out), clean) == (0, 0)


# -- processes and files ------------------------------------------------------------------------


def _marked_processes(mark: str) -> list[int]:
    pids = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            if mark.encode() in (d / "environ").read_bytes():
                pids.append(int(d.name))
        except OSError:
            continue
    return pids


@pytest.mark.skipif(not Path("/proc/self/environ").exists(), reason="needs Linux /proc")
@pytest.mark.parametrize("started", [3, 5])
def test_workers_end_when_the_main_process_is_killed(tmp_path, started):
    """The main process is killed once ``started`` processes run: 3, the main process,
    multiprocessing's resource tracker and the workers' fork server, still importing what it
    preloads; 5, also the two workers. Every one of them ends."""
    mark = f"DIRECTOR_BENCH_TEST_MARK={uuid.uuid4().hex}"
    env = dict(os.environ, DIRECTOR_BENCH_TEST_MARK=mark.split("=", 1)[1])
    proc = subprocess.Popen(
        [sys.executable, "-m", "reports.cli", "run", "dzhanibekov", "--engines",
         "mujoco,pybullet", "--out", str(tmp_path / "o"), "--quiet", "--jobs", "2"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while len(_marked_processes(mark)) < started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert len(_marked_processes(mark)) >= started, "the workers did not start"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 10
    while _marked_processes(mark) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _marked_processes(mark) == []


def test_nothing_is_written_outside_the_output_folder(tmp_path):
    """heavy_top under MuJoCo Euler at dt = 4e-3 diverges, and MuJoCo writes MUJOCO_LOG.TXT
    into the current directory when it warns: the runs execute in the output folder's logs."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    out = tmp_path / "out"
    proc = cli(
        "run", "heavy_top", "--engines", "mujoco", "--integrators", "Euler", "--dt", "4e-3",
        "--out", str(out), "--quiet", "--jobs", "1", cwd=str(cwd),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert list(cwd.iterdir()) == []
    assert read_results(out)["status"].tolist() == ["diverged"]


# -- every hang bounded, every failure of the work a message ------------------------------------


def test_the_numerical_reference_stops_at_its_step_and_time_bounds(monkeypatch):
    """dzhanibekov over 30 s takes ~1 900 DOP853 steps in its main solution alone: a bound of
    500 steps (above the 360 of the estimate made before any step) stops it mid-way, and a
    time bound of 1 ns stops it at its first step; each message names the bound, its figures
    and the variable that raises it."""
    import numpy as np

    import scenarios
    from references.exact.numerical import ReferenceCostExceeded, solve

    sc = scenarios.load("dzhanibekov")
    t = np.linspace(0.0, sc.t_end, 31)
    with pytest.raises(ReferenceCostExceeded, match=r"step bound: 501 steps > 500, at t = "):
        solve(sc, t, max_steps=500)
    with pytest.raises(ReferenceCostExceeded, match="time bound: .* s > 1e-09 s") as info:
        solve(sc, t, max_seconds=1e-9)
    assert "DIRECTOR_BENCH_REFERENCE_MAX_SECONDS" in str(info.value)
    # |W| = 1e11 rad/s for 10 s: 1e12 rad cannot fit 2e6 steps; refused before any step
    fast = sc.replace(omega_body=[1e11, 0.0, 0.0], t_end=10.0)
    monkeypatch.setenv("DIRECTOR_BENCH_REFERENCE_MAX_STEPS", "2e6")
    with pytest.raises(ReferenceCostExceeded, match="before any step: .* 1e\\+12 rad"):
        solve(fast, np.linspace(0.0, 10.0, 11))
    monkeypatch.setenv("DIRECTOR_BENCH_REFERENCE_MAX_STEPS", "-1")
    with pytest.raises(ValueError, match="DIRECTOR_BENCH_REFERENCE_MAX_STEPS='-1'"):
        solve(sc, t)


def test_a_reference_over_its_bound_is_said_in_the_rows(monkeypatch):
    """The exact engine's row is `unsupported` with the bound's message; an engine's run
    keeps its metrics and is `reference-inaccurate` with the same message."""
    import math

    import scenarios
    from reports.run.body import _reference_cached
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    monkeypatch.setenv("DIRECTOR_BENCH_REFERENCE_MAX_STEPS", "50")
    _reference_cached.cache_clear()
    sc = scenarios.load("free_tumbling").replace(reference="numerical", t_end=1.0, dt_sweep=())
    exact = execute(RunSpec(sc, "exact", "reference", 1e-2))
    rattle = execute(RunSpec(sc, "director", "rattle", 1e-2))
    _reference_cached.cache_clear()
    assert exact["status"] == "unsupported", exact["message"]
    assert "step bound" in exact["message"] and "MAX_STEPS" in exact["message"]
    assert rattle["status"] == "reference-inaccurate", rattle["message"]
    assert "step bound" in rattle["message"] and rattle["verdict"] == ""
    assert math.isfinite(rattle["energy_drift_max"]) and rattle["nstep"] == 100


def test_a_write_lock_held_too_long_is_a_locked_store_not_a_damaged_one(
    tmp_path, monkeypatch, capsys
):
    """Another process holds the store's write lock past the wait: exit 1, the holder named,
    'wait', and no advice to move the store aside; the store is intact."""
    import reports.store.results as results
    from reports.cli import main

    Store(tmp_path, create=True).close()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sqlite3, sys, time\n"
         f"c = sqlite3.connect({str(tmp_path / 'results.sqlite')!r}, isolation_level=None)\n"
         "c.execute('BEGIN IMMEDIATE'); print('locked', flush=True); time.sleep(120)"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert holder.stdout.readline().strip() == "locked"
        monkeypatch.setattr(results, "BUSY_TIMEOUT_S", 0.5)
        code = main(["run", "free_tumbling", "--engines", "exact", "--no-sweep", "--t-end", "1",
                     "--out", str(tmp_path), "--quiet", "--jobs", "1", "--no-report"])  # fmt: skip
    finally:
        holder.kill()
        holder.wait()
    assert code == 1
    err = capsys.readouterr().err
    assert f"have it open: process {holder.pid}" in err and "wait" in err, err
    assert re.search(r"stayed locked for the \d+\.\d s this process waited \(at most 0.5 s", err)
    assert "damaged" not in err.replace("not damaged", "") and "mv " not in err
    assert read_results(tmp_path, all_rows=True).empty


def test_a_figure_that_cannot_be_drawn_costs_neither_report_nor_junit(tmp_path, capsys):
    """RATTLE at dt = 0.5 and 0.25 s on free_tumbling: both runs are above 0.1 rad, the
    work-precision figure has nothing a log axis can show; the run still exits 0 with its
    report and junit.xml, and says which figure was left out."""
    from reports.cli import main

    out = tmp_path / "out"
    code = main(["run", "free_tumbling", "--engines", "director", "--integrators", "rattle",
                 "--dt", "0.5,0.25", "--out", str(out), "--quiet", "--jobs", "1"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 0, err
    assert "work_precision figure of free_tumbling was not drawn" in err
    assert (out / "report.md").exists() and (out / "junit.xml").exists()
    assert len(read_results(out)) == 2


@pytest.fixture
def broken_plugin(tmp_path, monkeypatch):
    """An engine adapter whose module raises on import, registered beside the built-ins."""
    import references.engines as engines

    (tmp_path / "broken_adapter.py").write_text("raise RuntimeError('broken on purpose')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    registry = {**engines._registry(), "broken": "broken_adapter:Adapter"}
    monkeypatch.setattr(engines, "_registry", lambda: registry)
    return "broken"


def test_an_adapter_that_fails_to_import_is_unavailable_and_the_others_run(
    tmp_path, broken_plugin, capsys
):
    from reports.cli import main
    from reports.suite import catalog

    entry = next(e for e in catalog()["engines"] if e["name"] == broken_plugin)
    assert entry["available"] is False and entry["integrators"] == []
    assert "RuntimeError: broken on purpose" in entry["why"]
    assert main(["list"]) == 0
    assert "NOT AVAILABLE: engine 'broken'" in capsys.readouterr().out
    out = tmp_path / "out"
    code = main(["run", "free_tumbling", "--engines", "exact,broken", "--no-sweep", "--t-end",
                 "1", "--out", str(out), "--quiet", "--jobs", "1", "--no-report"])  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0 and "not run:      engine 'broken'" in printed
    assert read_results(out)[["engine", "status"]].values.tolist() == [["exact", "ok"]]


def test_report_needs_no_engine_registered_here(tmp_path, capsys):
    """Rows of an engine this machine does not have (a plug-in installed elsewhere, with its
    own family) are reported like any other."""
    from reports.cli import main

    out = tmp_path / "out"
    argv = ["run", "free_tumbling", "--engines", "exact", "--no-sweep", "--t-end", "1",
            "--out", str(out), "--quiet", "--jobs", "1", "--no-report"]  # fmt: skip
    assert main(argv) == 0
    with Store(out, create=True) as st:
        row = dict(st.rows()[0])
        row.update(run_id="elsewhere", engine="elsewhere", integrator="magic",
                   family="a family registered elsewhere", reference=0)  # fmt: skip
        st.put(row)
    assert main(["report", str(out)]) == 0, capsys.readouterr().err
    assert "elsewhere magic" in (out / "report.md").read_text()


def test_a_value_error_of_the_work_is_exit_1_not_bad_input(tmp_path, monkeypatch, capsys):
    import reports.report.build
    from reports.cli import main

    def fails(*args, **kwargs):
        raise ValueError("a failure deep inside the work")

    monkeypatch.setattr(reports.report.build, "build_report", fails)
    assert main(["report", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "the work failed: ValueError: a failure deep inside the work" in err
    assert "test_faults.py" in err and "not of the input" in err and "Traceback" not in err


def test_an_ensemble_writes_nothing_outside_its_folder(tmp_path, monkeypatch, capsys):
    """MuJoCo's Euler diverges on heavy_top at dt = 4e-3 and MuJoCo writes MUJOCO_LOG.TXT
    into the working directory: the ensemble's engines run in the output folder's logs."""
    from reports.cli import main

    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    out = tmp_path / "out"
    code = main(["ensemble", "heavy_top", "--n", "2", "--engines", "mujoco", "--integrators",
                 "Euler", "--dt", "4e-3", "--out", str(out), "--quiet", "--jobs", "1",
                 "--no-report"])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert list(cwd.iterdir()) == []
    assert (out / "logs" / "MUJOCO_LOG.TXT").exists()


def test_a_read_only_results_folder_can_be_compared(tmp_path):
    """A results folder that cannot be written: its store is read as it is (no -wal/-shm
    files to create), so compare works there; report, which writes into the folder, says so
    and what to do. Nothing in the folder changes."""
    from reports.cli import main

    ro = tmp_path / "ro"
    argv = ["run", "free_tumbling", "--engines", "exact", "--no-sweep", "--t-end", "1",
            "--out", str(ro), "--quiet", "--jobs", "1", "--no-report"]  # fmt: skip
    assert main(argv) == 0
    before = sorted(p.name for p in ro.iterdir())
    cmd = _read_only_command(ro, ["compare", str(ro), str(ro)])
    if cmd is None:
        pytest.skip("running as root without user namespaces: no way to make a folder read-only")
    compared = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    cmd = _read_only_command(ro, ["report", str(ro)])
    reported = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    ro.chmod(0o755)
    assert compared.returncode == 0, compared.stderr
    assert "cannot write the results store" not in compared.stderr
    assert "Traceback" not in compared.stderr + reported.stderr
    assert reported.returncode == 1
    assert "is read-only" in reported.stderr and "cp -r" in reported.stderr
    assert sorted(p.name for p in ro.iterdir()) == before


def test_report_md_escapes_what_it_inserts(tmp_path, capsys):
    """Text from provenance.json and from the store (a message) with Markdown and HTML in
    it: report.md shows it as text (no tag, no heading, no extra table cell or line)."""
    import json

    from reports.cli import main

    out = tmp_path / "out"
    argv = ["run", "free_tumbling", "--engines", "exact", "--no-sweep", "--t-end", "1",
            "--out", str(out), "--quiet", "--jobs", "1", "--no-report"]  # fmt: skip
    assert main(argv) == 0
    evil = "a | b\n# Heading `code` <script>alert(1)</script> &lt;img&gt;"
    prov = json.loads((out / "provenance.json").read_text())
    prov["machine"]["cpu"] = evil
    prov["note"] = evil
    (out / "provenance.json").write_text(json.dumps(prov))
    with Store(out, create=True) as st:
        row = dict(st.rows()[0])
        row.update(run_id="evil", integrator="evil", status="error", verdict="", message=evil)
        st.put(row)
    assert main(["report", str(out)]) == 0, capsys.readouterr().err
    md = (out / "report.md").read_text()
    assert "<script" not in md and "<img" not in md
    assert not [line for line in md.splitlines() if line.startswith("# Heading")]
    lines = [line for line in md.splitlines() if "alert(1)" in line]
    assert len(lines) >= 3  # the provenance line, its table, the failed run
    for line in lines:
        assert "a \\| b # Heading \\`code\\` &lt;script>" in line, line
        assert "&amp;lt;img&amp;gt;" in line, line
