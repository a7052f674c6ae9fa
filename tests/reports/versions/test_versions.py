"""director-bench versions: the requirement syntax, the change detection on synthetic rows, the
upgrade gate, bad input at the command line, and an unreachable package index (no network
needed: the index is a closed local port). Matrices that install real engine versions are
marked slow."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import scenarios
from reports.metrics.body import FLOORS
from reports.store.results import Store
from reports.store.runs import RunSpec, blank_row, finish_time
from reports.versions.changes import check, energy_behaviour, load_table, sort_versions
from reports.versions.requirements import parse_requirements

ENGINES = ["director", "exact", "mujoco", "drake", "pinocchio"]


# -- requirements -------------------------------------------------------------------------------


def test_requirements_versions_and_engines():
    ts = parse_requirements(["mujoco==3.3.0,3.6.0", "drake==1.40.0"], ENGINES)
    assert [(t.engine, t.label, t.requirement) for t in ts] == [
        ("mujoco", "3.3.0", "mujoco==3.3.0"),
        ("mujoco", "3.6.0", "mujoco==3.6.0"),
        ("drake", "1.40.0", "drake==1.40.0"),
    ]
    (t,) = parse_requirements(["pinocchio==3.4.0"], ENGINES)
    assert t.requirement == "pin==3.4.0"  # the engine's package on the index


@pytest.mark.parametrize(
    "req, words",
    [
        ("mujocoo==3.3.0", ["'mujocoo==3.3.0'", "unknown engine 'mujocoo'", "known engines"]),
        ("mujoco", ["'mujoco'", "no version", "mujoco==V1,V2"]),
        ("mujoco>=3.3", ["'mujoco>=3.3'", "range", "exact versions"]),
        ("mujoco==3.3.0,,4.0.0", ["empty version"]),
        ("mujoco==", ["empty version"]),
        ("mujoco==three", ["'three' is not a version", "PEP 440"]),
        ("mujoco==3.3.0,3.3.0", ["3.3.0 is given twice"]),
        ("director==1.0", ["part of director-bench", "no releases"]),
        ("mujoco@", ["nothing after '@'"]),
        ("mujoco@/no/such/file.whl", ["/no/such/file.whl does not exist"]),
        ("mujoco@ftp://x/mujoco-4.0.0-cp311-cp311-linux_x86_64.whl", ["scheme 'ftp'"]),
        ("mujoco@https://x/mujoco-4.0.0.tar.gz", ["not a wheel file name", "binary wheels"]),
        ("mujoco@https://x/drake-1.0.0-cp311-cp311-linux_x86_64.whl", ["wheel is of 'drake'"]),
    ],
)
def test_requirements_refused_with_the_requirement_named(req, words):
    with pytest.raises(ValueError) as exc:
        parse_requirements([req], ENGINES)
    for w in words:
        assert w in str(exc.value), (w, str(exc.value))


def test_requirements_wheel_by_path_and_url(tmp_path):
    whl = tmp_path / "mujoco-4.1.0.dev0-cp311-cp311-manylinux_2_28_x86_64.whl"
    whl.write_bytes(b"first build")
    (t,) = parse_requirements([f"mujoco@{whl}"], ENGINES)
    assert t.wheel and t.version == "4.1.0.dev0"
    assert t.requirement == f"mujoco @ {whl.as_uri()}"
    whl.write_bytes(b"second build")  # a rebuilt wheel gets its own environment
    (t2,) = parse_requirements([f"mujoco@{whl}"], ENGINES)
    assert t2.label != t.label and t2.version == t.version
    (u,) = parse_requirements(["mujoco@https://h/mujoco-4.0.0-cp311-cp311-any.whl"], ENGINES)
    assert u.requirement.startswith("mujoco @ https://") and u.version == "4.0.0"
    with pytest.raises(ValueError, match="is a folder"):
        parse_requirements([f"mujoco@{tmp_path}"], ENGINES)


def test_versions_sort_in_release_order():
    assert sort_versions(["4.0.0", "3.11.0", "3.3.0", "3.8.1", "4.1.0.dev0+wab12"]) == [
        "3.3.0",
        "3.8.1",
        "3.11.0",
        "4.0.0",
        "4.1.0.dev0+wab12",
    ]


# -- energy behaviour ---------------------------------------------------------------------------

T = np.linspace(0.0, 10.0, 1001)


@pytest.mark.parametrize(
    "e, cls",
    [
        # a bounded oscillation without trend (a symplectic method's error)
        (1e-4 * np.sin(3.0 * T), "conserved"),
        # a secular gain 10x the wobble around it (an explicit method)
        (1e-4 * T / 10 + 1e-6 * np.sin(3.0 * T), "gaining"),
        (-1e-3 * T / 10 + 1e-5 * np.sin(3.0 * T), "losing"),
        # staircase losses at two flips, each step 1e-3: the net change dominates
        (-1e-3 * ((T > 3).astype(float) + (T > 7)), "losing"),
        # round-off: below the gate's floor whatever its shape
        (1e-13 * T, "conserved"),
        # a trend comparable to the wobble: not decisive
        (1e-4 * np.sin(T) + 1e-4 * T / 10, "mixed"),
    ],
)
def test_energy_behaviour_classes(e, cls):
    assert energy_behaviour(T, e)["class"] == cls


def test_energy_behaviour_diverged_and_floor():
    e = np.full_like(T, 1e-3)
    e[-1] = np.inf
    assert energy_behaviour(T, e)["class"] == "diverged"
    assert energy_behaviour(T, np.full_like(T, FLOORS["energy_drift_max"]))["round_off"]


# -- change detection on synthetic rows ----------------------------------------------------------


@pytest.fixture(scope="module")
def free():
    return scenarios.load("free_tumbling")


def _row(sc, version, integ, dt=1e-3, status="ok", verdict="pass", **metrics):
    spec = RunSpec(sc, "mujoco", integ, dt, engine_version=version)
    row = blank_row(spec)
    row.update(status=status, verdict=verdict if status in ("ok", "diverged") else "")
    if status == "diverged":
        row["verdict"] = "fail"
    row.update(finished_at=finish_time(), nstep=10000)
    base = dict(energy_drift_max=1e-3, momentum_drift_max=1e-3, attitude_error_max=1e-2,
                orthonormality_max=1e-15, engine_ns_per_step=2000.0)  # fmt: skip
    if status == "ok":
        row.update(base)
    row.update(metrics)
    if status != "ok":
        row["message"] = f"{status} in {version}"
    return row


def _trajectory(folder: Path, row: dict, energy: np.ndarray) -> dict:
    import pyarrow as pa
    import pyarrow.parquet as pq

    rel = Path("trajectories") / f"{row['engine_version']}-{row['integrator']}.parquet"
    (folder / rel).parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table({"t": T, "energy": energy}), folder / rel)
    return {**row, "trajectory": str(rel)}


@pytest.fixture(scope="module")
def matrix(tmp_path_factory, free):
    """Three versions of one engine with planted changes (and their absence)."""
    folder = tmp_path_factory.mktemp("versions")
    E0, Ec = 5.0, free.energy_scale
    rows = []
    for v in ("1.0", "1.1", "1.2"):
        # unchanged everywhere: identical rows
        rows.append(_row(free, v, "Euler"))
        # 1.5x: within the factor of 2, never flagged
        rows.append(
            _row(
                free, v, "implicit", energy_drift_max={"1.0": 1e-3, "1.1": 1.5e-3, "1.2": 1.5e-3}[v]
            )
        )
        # round-off noise: 1e-15 -> 8e-15 is below the floor (1e-11), not a change
        rows.append(
            _row(free, v, "RK4", energy_drift_max={"1.0": 1e-15, "1.1": 8e-15, "1.2": 8e-15}[v])
        )
    # attitude error x3 from 1.0 to 1.1 (worse), back /3 in 1.2 (better)
    att = {"1.0": 1e-2, "1.1": 3e-2, "1.2": 1e-2}
    rows += [_row(free, v, "implicitfast", attitude_error_max=att[v]) for v in att]
    # verdict pass -> fail from 1.1 to 1.2
    rows += [_row(free, v, "semi", verdict="pass" if v != "1.2" else "fail") for v in att]
    rows[-1]["verdict_detail"] = "attitude"
    # status ok -> diverged from 1.0 to 1.1, then back
    rows += [_row(free, v, "midpoint", status="diverged" if v == "1.1" else "ok") for v in att]
    # a new integrator in 1.1, vanished again in 1.2
    rows += [_row(free, v, "discrete", status="ok" if v == "1.1" else "unsupported")
             for v in att]  # fmt: skip
    # energy behaviour: losing in 1.0, conserved (same size, bounded) in 1.1 and 1.2
    for v in att:
        e = -1e-3 * T / 10 if v == "1.0" else 1e-3 * np.sin(2 * T)
        r = _row(free, v, "behaviour", energy_drift_max=1e-3)
        rows.append(_trajectory(folder, r, E0 + Ec * e))
    # unavailable in 1.2: not compared
    rows += [_row(free, v, "gone", status="unavailable" if v == "1.2" else "ok") for v in att]
    # cost: a dt sweep with a 1.2x spread; 1.1 costs 3x (a change), 1.2 1.3x of 1.1 (not)
    for v, c in (("1.0", 1000.0), ("1.1", 3000.0), ("1.2", 3900.0)):
        for k, dt in enumerate((1e-3, 5e-4)):
            rows.append(_row(free, v, "costly", dt=dt, engine_ns_per_step=c * (1.0, 1.2)[k]))
    # cost noise: the median moves 2.5x beyond both spreads, but one step size did not move
    # beyond the factor: the machine's load, not the engine (never flagged)
    for v, costs in (("1.0", (1000.0, 1000.0, 1000.0)), ("1.1", (2500.0, 2500.0, 1500.0))):
        for dt, c in zip((1e-3, 5e-4, 2.5e-4), costs, strict=True):
            rows.append(_row(free, v, "noisy", dt=dt, engine_ns_per_step=c))
    with Store(folder, create=True) as st:
        for r in rows:
            st.put(r)
    return folder


def _changes(tab, **where):
    return [c for c in tab.changes if all(getattr(c, k) == v for k, v in where.items())]


def test_changes_found_and_nothing_else(matrix):
    tab = load_table(matrix, factor=2.0)
    assert tab.versions == {"mujoco": ["1.0", "1.1", "1.2"]}
    got = sorted(
        (c.integrator, c.from_version, c.to_version, c.kind, c.column, c.direction)
        for c in tab.changes
    )
    assert got == sorted(
        [
            ("implicitfast", "1.0", "1.1", "metric", "attitude_error_max", "worse"),
            ("implicitfast", "1.1", "1.2", "metric", "attitude_error_max", "better"),
            ("semi", "1.1", "1.2", "verdict", "verdict", "worse"),
            ("midpoint", "1.0", "1.1", "status", "status", "worse"),
            ("midpoint", "1.1", "1.2", "status", "status", "better"),
            ("discrete", "1.0", "1.1", "integrator", "status", "new"),
            ("discrete", "1.1", "1.2", "integrator", "status", "vanished"),
            ("behaviour", "1.0", "1.1", "behaviour", "energy error", "better"),
            ("costly", "1.0", "1.1", "cost", "engine_ns_per_step", "worse"),
        ]
    )
    (b,) = _changes(tab, integrator="behaviour")
    assert (b.a, b.b) == ("losing", "conserved")
    p10, p11 = tab.pairs
    # Euler identical; implicit (1.5x) and RK4 (below floor) within; "gone" compared in 1.0-1.1
    assert p10.identical >= 1 and p10.within == 2
    assert p11.not_compared and "gone" in p11.not_compared[0][0]
    assert "unavailable in 1.2" in p11.not_compared[0][1]


def test_upgrade_gate(matrix):
    tab = load_table(matrix, factor=2.0)
    res = check(tab, "mujoco==1.0", "1.1")
    worse = sorted((c.integrator, c.kind) for c in res.failures)
    assert worse == [("implicitfast", "metric"), ("midpoint", "status")]
    assert not res.ok
    # 1.0 -> 1.2 directly: the verdict fails, the integrator 'discrete' never ran in either
    res = check(tab, "oldest", "newest")
    assert sorted((c.integrator, c.kind) for c in res.failures) == [("semi", "verdict")]
    # a cost change gates only with a cost factor
    res = check(tab, "1.0", "1.1", cost_factor=2.0)
    assert ("costly", "cost") in [(c.integrator, c.kind) for c in res.failures]
    with pytest.raises(ValueError, match="is not held"):
        check(tab, "1.0", "9.9")


def test_two_checks_of_one_store_give_one_verdict_and_leave_the_report(
    matrix, tmp_path, monkeypatch
):
    """The 3x cost change of 'costly' is a candidate confirmed by timing the two versions side
    by side. The probes give other times at every call (here: a 3x slowdown the first time,
    none after, as a loaded machine can): the times are taken once per folder, recorded and
    reused, so that two checks of one store agree, and a check rewrites no versions.md."""
    import hashlib

    from reports.versions import cost, run_versions

    folder = tmp_path / "v"
    shutil.copytree(matrix, folder)
    calls = []

    def probe(python, change, dt):  # 3x slower in 1.1 for the first 6 probes, then the same
        calls.append(python)
        slow = len(calls) <= 6 and python.name == "1.1"
        return 3000.0 + len(calls) if slow else 1000.0 + len(calls)

    monkeypatch.setattr(cost, "_python", lambda engine, version, root: Path(version))
    monkeypatch.setattr(cost, "_probe", probe)
    run_versions(out=folder, figures=False, log=lambda line: None)
    assert len(calls) == 6  # the report's candidate, timed once
    md = hashlib.sha256((folder / "versions.md").read_bytes()).hexdigest()
    assert "engine_ns_per_step" in (folder / "versions.md").read_text()
    verdicts = []
    for _ in range(2):
        s = run_versions(out=folder, check=("1.0", "1.1"), cost_factor=2.0, log=lambda x: None)
        verdicts.append(sorted((c.integrator, c.kind) for c in s.check.failures))
        assert s.paths == {}
    assert len(calls) == 6  # recorded: never timed again
    assert verdicts[0] == verdicts[1] and ("costly", "cost") in verdicts[0]
    assert hashlib.sha256((folder / "versions.md").read_bytes()).hexdigest() == md
    # --retime: timed again (now no slowdown), recorded for the next call
    s = run_versions(out=folder, check=("1.0", "1.1"), cost_factor=2.0, retime=True,
                     log=lambda x: None)  # fmt: skip
    assert len(calls) == 12 and ("costly", "cost") not in [
        (c.integrator, c.kind) for c in s.check.failures
    ]


def test_a_factor_of_four_hides_the_threefold_change(matrix):
    tab = load_table(matrix, factor=4.0)
    assert not _changes(tab, integrator="implicitfast")


# -- the command line ----------------------------------------------------------------------------


def _cli(*args, env=None, timeout=120):
    import os

    full = dict(os.environ, **(env or {}))
    return subprocess.run(
        [sys.executable, "-m", "reports.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=full,
        check=False,
    )


@pytest.mark.parametrize(
    "req, words",
    [
        ("bullet==3.2.7", ["requirement 'bullet==3.2.7'", "unknown engine"]),
        ("mujoco=3.3.0", ["requirement 'mujoco=3.3.0'", "write mujoco==3.3.0"]),
        ("mujoco==3..3", ["'3..3' is not a version"]),
    ],
)
def test_cli_bad_requirement_exit_2(tmp_path, req, words):
    p = _cli("versions", "free_tumbling", "--engines", req, "--out", str(tmp_path / "o"))
    assert p.returncode == 2, p.stderr
    for w in words:
        assert w in p.stderr
    assert "Traceback" not in p.stderr
    assert not (tmp_path / "o").exists()  # nothing written before the input is checked


@pytest.mark.skipif(shutil.which("uv") is None, reason="uv is not installed (pip install uv)")
def test_unreachable_index_is_an_unavailable_row_naming_the_requirement(tmp_path):
    """No network to the index (a closed local port): every configuration of that version is an
    ``unavailable`` row with the reason; the command exits 1 and says which requirement."""
    env = {
        "UV_INDEX_URL": "http://127.0.0.1:9/simple",
        "UV_DEFAULT_INDEX": "http://127.0.0.1:9/simple",
        "UV_HTTP_TIMEOUT": "5",
        "UV_HTTP_RETRIES": "0",
        "UV_NO_CACHE": "1",
        "DIRECTOR_BENCH_CACHE": str(tmp_path / "cache"),
    }
    out = tmp_path / "o"
    p = _cli(
        "versions", "free_tumbling", "--engines", "mujoco==3.3.0", "--integrators", "Euler",
        "--no-sweep", "--out", str(out), "--no-figures", env=env,
    )  # fmt: skip
    assert p.returncode == 1, p.stdout + p.stderr
    assert "mujoco==3.3.0" in p.stdout and "package index could not be reached" in p.stdout
    from reports.store.results import read_results

    df = read_results(out, all_rows=True)
    assert list(df["status"]) == ["unavailable"]
    assert df["engine_version"].iloc[0] == "3.3.0"
    assert "mujoco==3.3.0" in df["message"].iloc[0]
    assert not any((tmp_path / "cache" / "envs").glob("mujoco-*"))  # no half environment


# -- real environments (network, minutes) -------------------------------------------------------


@pytest.mark.slow
def test_partial_matrix_keeps_every_finished_row(tmp_path):
    """One version that exists, one that does not: the rows of the first are all kept, the
    second is one unavailable row per configuration naming it; a rerun skips the finished
    rows and reuses the environment."""
    out = tmp_path / "o"
    args = ["versions", "free_tumbling", "--engines", "mujoco==4.0.0,3.99.0", "--integrators",
            "Euler,RK4", "--no-sweep", "--out", str(out), "--no-figures"]  # fmt: skip
    p = _cli(*args, timeout=1800)
    assert p.returncode == 1, p.stdout + p.stderr
    assert "no such version" in p.stdout and "3.99.0" in p.stdout
    from reports.store.results import read_results

    df = read_results(out, all_rows=True)
    by = df.groupby("engine_version")["status"].apply(sorted).to_dict()
    assert by == {"4.0.0": ["ok", "ok"], "3.99.0": ["unavailable", "unavailable"]}
    p = _cli(*args, timeout=1800)
    assert "4.0.0: reused" in p.stdout
    assert "mujoco 4.0.0: 2 rows" in p.stdout and "every run already in the store" in p.stdout
    assert "3.99.0: UNAVAILABLE" in p.stdout  # tried again: unavailable rows are retried
    assert len(read_results(out, all_rows=True)) == 4


# -- an engine that takes its process down ------------------------------------------------------


def test_a_crashing_run_costs_one_row_not_the_rest(tmp_path, free, monkeypatch):
    """The matrix's recovery after an environment's run process died: a stand-in for the
    process runs its batch in order and dies at a planted culprit (as an abort in native code
    does), losing the run in flight. Every other run gets its row, each culprit one error row,
    and the number of processes stays bounded."""
    from reports.versions import matrix
    from reports.versions.envs import Env
    from reports.versions.requirements import Target

    specs = [RunSpec(free, "mujoco", integ, dt, engine_version="9.9")
             for integ in ("a", "b", "c") for dt in (1e-3, 2e-3, 4e-3)]  # fmt: skip
    culprits = {specs[1].run_id, specs[6].run_id}
    target = Target("mujoco", "mujoco", "mujoco==9.9", "9.9", "mujoco==9.9")
    env = Env(target, tmp_path / "env", True, engine_version="9.9")
    folder = matrix.sub_folder(tmp_path, target)
    folder.mkdir(parents=True)
    launches = []

    def fake_launch(env_, batch, folder_, opts, log):
        launches.append(len(batch))
        log.write_text(
            log.read_text() + "\nFailure at solver.cc:297: condition failed\n"
            if log.exists()
            else "Failure at solver.cc:297: condition failed\n"
        )
        with Store(folder_, create=True) as st:
            for s in batch:
                if s.run_id in culprits:
                    return -6  # SIGABRT: the process and the run in flight are gone
                row = blank_row(s)
                row.update(status="ok", verdict="pass", finished_at=finish_time())
                st.put(row)
        return 0

    monkeypatch.setattr(matrix, "_specs", lambda *a, **k: list(specs))
    monkeypatch.setattr(matrix, "_launch", fake_launch)
    run = matrix.EnvRun(env, folder, returncode=-6)
    assert matrix._isolate(env, [free], {}, run) == 2
    with Store(folder) as st:
        rows = {r["run_id"]: r for r in st.rows()}
    assert set(rows) == {s.run_id for s in specs}
    assert {i for i, r in rows.items() if r["status"] == "error"} == culprits
    assert all("Failure at solver.cc:297" in rows[i]["message"] for i in culprits)
    # run 0 alone (ok), run 1 alone (the first culprit), runs 2-8 together (die at run 6, after
    # recording 2-5), run 6 alone (the second culprit), runs 7-8 together: 5 processes
    assert launches == [1, 1, 7, 1, 2]


def test_worker_records_the_planned_identity(tmp_path, free):
    """The runs the matrix hands to reports.versions.worker come back under the identity it
    planned them with (horizon, decimation and all): otherwise it would wait for rows that
    never come."""
    from reports.versions import matrix
    from reports.versions.envs import Env
    from reports.versions.requirements import Target

    try:
        import mujoco  # noqa: F401
    except ImportError:
        pytest.skip("mujoco is not installed")
    env = Env(Target("mujoco", "mujoco", "x", "x", "x"), Path(sys.executable).parents[1], True)
    spec = RunSpec(free, "mujoco", "Euler", 1e-3, t_end=0.05, save_every=7,
                   engine_version=mujoco.__version__)  # fmt: skip
    code = matrix._launch(env, [spec], tmp_path, {}, tmp_path / "log")
    assert code == 0, (tmp_path / "log").read_text()
    with Store(tmp_path) as st:
        assert {r["run_id"] for r in st.rows()} == {spec.run_id}


def test_a_reused_environment_runs_this_checkouts_code(tmp_path):
    """A cached environment's .pth names the checkout that made it, which may be another
    clone sharing the cache: every command in it runs with this checkout first on
    PYTHONPATH (envs.checkout_env), so it imports this checkout's suite. Found when a
    `versions` run in one worktree reported the law residuals of another's older code."""
    import subprocess
    import sys

    from reports.versions.envs import CHECKOUT, _site_packages, checkout_env

    env = tmp_path / "env"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], check=True)
    other = tmp_path / "other-checkout"
    (other / "reports").mkdir(parents=True)
    (other / "reports" / "__init__.py").write_text("")
    (_site_packages(env) / "director_bench_checkout.pth").write_text(f"{other}\n")
    probe = [str(env / "bin" / "python"), "-c", "import reports; print(reports.__file__)"]

    def imported(**kw):
        out = subprocess.run(probe, capture_output=True, text=True, cwd=tmp_path, check=True, **kw)
        return Path(out.stdout.strip()).resolve()

    assert imported().is_relative_to(other.resolve())  # the .pth alone: the other's code
    assert imported(env=checkout_env()) == (CHECKOUT / "reports" / "__init__.py").resolve()
