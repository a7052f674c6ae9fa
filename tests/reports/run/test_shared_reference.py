"""A system's reference computed once per run and time grid, not once per worker process: the
pool's gate lets one unit of a grid compute it (the others of that grid wait, the workers
take other units meanwhile), and that process leaves it in the results folder's
``.references`` for the others, which read it instead of computing it again; the runner
removes the folder when the run starts and ends."""

import numpy as np
import pytest

import scenarios
from references.engines.exact import system as exact_system
from reports.run import system as run_system
from reports.run.parallel import _Gate
from reports.run.runner import run_suite, unit_keys, unit_warm_ups
from reports.store.runs import RunSpec

T_END = 0.2  # s: a short run of the four-bar linkage (a closed form: cheap)


@pytest.fixture(scope="module")
def four_bar():
    return scenarios.load("four_bar").replace(t_end=T_END)


@pytest.fixture
def fresh(monkeypatch):
    """No reference seen by this process yet (its per-process memory of shared ones)."""
    monkeypatch.setattr(run_system, "_SEEN", {})


def test_runs_on_one_grid_share_a_key_and_other_grids_or_runs_do_not(four_bar):
    a = RunSpec(four_bar, "mujoco", "RK4", 1e-3)
    b = RunSpec(four_bar, "dart", "RKMK4", 1e-3)
    other_dt = RunSpec(four_bar, "mujoco", "RK4", 2e-3)
    exact = RunSpec(four_bar, "exact", "reference", 1e-3)  # its rows are the reference
    body = RunSpec(scenarios.load("dzhanibekov"), "mujoco", "RK4", 1e-3)
    key = run_system.shared_key(a)
    assert key is not None and key == run_system.shared_key(b)
    assert run_system.shared_key(other_dt) not in (None, key)
    assert run_system.shared_key(exact) is None and run_system.shared_key(body) is None
    assert key in unit_keys([a]) and key in unit_keys([b])


def test_the_gate_holds_back_a_grid_until_its_first_unit_is_back(four_bar):
    """The second unit of a grid is not handed out while the first computes its reference;
    a unit of another grid is; once the first is back, the second goes (and reads it)."""
    first = [RunSpec(four_bar, "mujoco", "RK4", 1e-3)]
    second = [RunSpec(four_bar, "dart", "RKMK4", 1e-3)]
    other = [RunSpec(four_bar, "mujoco", "RK4", 2e-3)]
    gate = _Gate([first, second, other], unit_keys)
    gate.done |= unit_warm_ups(first) | unit_warm_ups(other)  # the kernels: compiled before
    unit, keys = gate.next()
    assert unit is first
    assert gate.next()[0] is other  # second waits for first's reference
    assert gate.next()[0] is None
    gate.compiled(keys, first)
    assert gate.next()[0] is second


def test_a_reference_left_by_one_process_is_read_by_another(tmp_path, four_bar, fresh, monkeypatch):
    t = np.linspace(0.0, T_END, 21)
    ref = run_system.shared_reference(four_bar, t, tmp_path)
    (left,) = (tmp_path / run_system.SHARED).iterdir()
    assert left.name.startswith(four_bar.scenario_hash)

    def computed_again(*_):
        raise AssertionError("computed again instead of read")

    monkeypatch.setattr(run_system, "_SEEN", {})  # another process: nothing seen yet
    monkeypatch.setattr(exact_system, "reference", computed_again)
    got = run_system.shared_reference(four_bar, t, tmp_path)
    for name in ("t", "position", "velocity", "rotation", "omega_body"):  # bit for bit
        a, b = getattr(ref.trajectory, name), getattr(got.trajectory, name)
        assert a.tobytes() == b.tobytes()
    assert (got.kind, got.accuracy, got.horizon, got.method) == (
        ref.kind, ref.accuracy, ref.horizon, ref.method,
    )  # fmt: skip


def test_a_file_left_for_other_times_is_not_used(tmp_path, four_bar, fresh):
    t = np.linspace(0.0, T_END, 21)
    ref = run_system.shared_reference(four_bar, t, tmp_path)
    (left,) = (tmp_path / run_system.SHARED).iterdir()
    coarse = np.linspace(0.0, T_END, 11)
    # the coarse grid's file name, holding the fine grid's reference (a file name's clash)
    run_system.shared_reference(four_bar, coarse, tmp_path)
    coarse_file = next(p for p in (tmp_path / run_system.SHARED).iterdir() if p != left)
    coarse_file.write_bytes(left.read_bytes())
    run_system._SEEN.clear()
    got = run_system.shared_reference(four_bar, coarse, tmp_path)
    assert len(got.trajectory.t) == 11 and len(ref.trajectory.t) == 21


def test_the_run_removes_the_shared_folder(tmp_path, four_bar):
    stale = tmp_path / run_system.SHARED
    stale.mkdir()
    (stale / "left-by-an-interrupted-run.pickle").write_bytes(b"not a reference")
    specs = [RunSpec(four_bar, "mujoco", "RK4", 1e-3), RunSpec(four_bar, "mujoco", "Euler", 1e-3)]
    df, n = run_suite(specs, tmp_path, progress=False)
    assert n == 2 and list(df["reference_kind"]) == ["four_bar", "four_bar"]
    assert not stale.exists()


def test_the_runs_log_counts_the_references_and_names_a_damaged_entry(
    tmp_path, four_bar, monkeypatch, capsys
):
    """A run says how many references it read from the reference cache and computed
    (references.cache), and gives one line for an entry it could not read and computed
    again; the rows are the same either way."""
    from references import cache

    monkeypatch.setenv(cache.ROOT_ENV, str(tmp_path / "cache"))
    specs = [
        RunSpec(four_bar, "mujoco", "RK4", 1e-3),
        RunSpec(four_bar, "exact", "reference", 1e-3),
    ]

    def run(out):
        exact_system._cached.cache_clear()  # a new run's worker: nothing in its memory
        run_system._SEEN.clear()
        df, _ = run_suite(specs, tmp_path / out, progress=True)
        return df.sort_values("run_id").reset_index(drop=True), capsys.readouterr().err

    cold, said = run("cold")
    assert "references: 0 read from the reference cache" in said and "1 computed" in said
    warm, said = run("warm")
    assert "references: 1 read from the reference cache" in said and "0 computed" in said
    (entry,) = cache.folder().iterdir()
    entry.write_bytes(b"damaged")
    again, said = run("again")
    damaged = [line for line in said.splitlines() if str(entry) in line]
    assert len(damaged) == 1 and "computed again" in damaged[0], said
    for df in (warm, again):  # every column but the timings and the clock
        for c in ("reference_kind", "reference_accuracy", "attitude_error_max", "settings"):
            assert df[c].equals(cold[c]), c
    # the exact row costs what computing the reference took, read or computed
    exact = [df.loc[df["engine"] == "exact", "engine_time_s"].item() for df in (cold, warm)]
    assert exact[0] == exact[1] > 0
