"""The results store's identity rules: a database that is not ours is refused untouched, the
status a rerun reads is inside the row checksum, rows of an older identity are history (never
current, never in a convergence fit), and runs are timed more than once."""

import hashlib
import math
import sqlite3

import numpy as np
import pytest

import scenarios
from reports.cli import main
from reports.run import runner, timing
from reports.store.results import (
    APPLICATION_ID,
    Store,
    StoreDamaged,
    StoreForeign,
    current,
    frame,
    read_results,
)
from reports.store.runs import NUMERIC_COLUMNS, RESULT_COLUMNS, RunSpec


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _other_app_id(con):
    con.execute("PRAGMA application_id = 1234")
    con.execute("CREATE TABLE runs (run_id TEXT)")


def _other_tables(con):
    con.execute("CREATE TABLE customers (name TEXT, balance REAL)")
    con.execute("INSERT INTO customers VALUES ('ada', 1.5)")


def _no_format_record(con):
    con.execute("CREATE TABLE runs (run_id TEXT, x TEXT)")
    con.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")


@pytest.mark.parametrize("make", [_other_app_id, _other_tables, _no_format_record])
def test_a_database_that_is_not_ours_is_refused_not_converted(tmp_path, capsys, make):
    path = tmp_path / "results.sqlite"
    con = sqlite3.connect(path)
    make(con)
    con.commit()
    con.close()
    before = digest(path)
    for create in (False, True):
        with pytest.raises(StoreForeign, match="is not a director-bench results store"):
            Store(tmp_path, create=create)
    assert digest(path) == before
    assert not (tmp_path / "results.sqlite-wal").exists()
    # the command line: exit 1, the file named, what to do; still untouched
    assert main(["report", str(tmp_path)]) == 1
    argv = ["run", "free_tumbling", "--engines", "director", "--integrators", "rattle"]
    assert main([*argv, "--dt", "1e-3", "--t-end", "0.01", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert str(path) in err and "Nothing was read or changed" in err and "--out" in err
    assert "Traceback" not in err
    assert digest(path) == before


def test_a_store_whose_creation_was_cut_short_holds_no_rows(tmp_path):
    """A run killed while its store was being created leaves a database with no tables (the
    schema is made in one transaction): it reads as a store of no rows, and the next run
    completes it; it was reported damaged ("no such table: meta") for good."""
    con = sqlite3.connect(tmp_path / "results.sqlite")
    con.execute("PRAGMA journal_mode = WAL")
    con.close()
    with Store(tmp_path) as st:
        assert st.rows() == [] and st.done_ids() == set()
    with Store(tmp_path, create=True) as st:
        st.put(row("r1"))
    assert [r["run_id"] for r in Store(tmp_path).rows()] == ["r1"]


def test_our_store_carries_our_application_id(tmp_path):
    with Store(tmp_path, create=True):
        pass
    con = sqlite3.connect(tmp_path / "results.sqlite")
    assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    con.close()
    with Store(tmp_path) as st:  # and opens again
        assert st.rows() == []


def row(run_id, status="ok", **kw):
    r = dict.fromkeys(RESULT_COLUMNS, "")
    for c in NUMERIC_COLUMNS:
        r[c] = math.nan
    r.update(
        run_id=run_id,
        scenario="free_tumbling",
        scenario_hash="h1",
        engine="mujoco",
        engine_version="3.3.0",
        integrator="RK4",
        dt=1e-3,
        t_end=10.0,
        save_every=10,
        status=status,
        verdict="pass" if status == "ok" else "",
        suite_version="0.1.0",
        finished_at="2026-11-22T00:00:00+00:00",
    )
    r.update(kw)
    return r


@pytest.mark.parametrize(("stored", "tampered"), [("error", "ok"), ("ok", "error")])
def test_the_status_a_rerun_reads_is_inside_the_checksum(tmp_path, stored, tampered):
    """A status changed in the store's status column (outside the row's JSON) would make a
    rerun skip a failed run (error -> ok) or redo a finished one (ok -> error): the store is
    reported damaged instead, by rows() and by done_ids()."""
    with Store(tmp_path, create=True) as st:
        st.put(row("r1", status=stored))
        assert st.done_ids() == ({"r1"} if stored == "ok" else set())
    con = sqlite3.connect(tmp_path / "results.sqlite")
    con.execute("UPDATE runs SET status = ? WHERE run_id = 'r1'", (tampered,))
    con.commit()
    con.close()
    with Store(tmp_path) as st:
        with pytest.raises(StoreDamaged, match="1 row"):
            st.rows()
        with pytest.raises(StoreDamaged, match="checksum"):
            st.done_ids()


def sweep(hash_, order, dts, day, **kw):
    """Rows of an RK4 dt sweep whose attitude errors fall as dt**order exactly."""
    return [
        row(
            f"{hash_}-{h}",
            scenario_hash=hash_,
            dt=h,
            order=4.0,
            attitude_error_max=1e-2 * (h / 4e-3) ** order,
            reference_accuracy=1e-15,
            roundoff_floor=1e-15,
            finished_at=f"2026-11-{day}T00:00:00+00:00",
            **kw,
        )
        for h in dts
    ]


def test_rows_of_an_older_scenario_content_are_history(tmp_path):
    """The scenario file was edited and the sweep run again on two of its three steps: only
    the new content's rows are current, and the fitted order is theirs (4: errors built as
    dt**4), not a slope across two bodies (the old rows fall as dt**2)."""
    old = sweep("old", 2.0, (4e-3, 2e-3, 1e-3), 22)
    new = sweep("new", 4.0, (4e-3, 2e-3), 23)
    df = current(frame(old + new))
    assert set(df["scenario_hash"]) == {"new"} and sorted(df["dt"]) == [2e-3, 4e-3]
    assert np.allclose(df["convergence_order"], 4.0, rtol=1e-9)
    assert (df["convergence_points"] == 2).all()
    # stored as written: read_results gives the same view, all_rows every row
    with Store(tmp_path, create=True) as st:
        for r in old + new:
            st.put(r)
    assert len(read_results(tmp_path)) == 2 and len(read_results(tmp_path, all_rows=True)) == 5


@pytest.mark.parametrize(
    ("field", "old", "new"),
    [("t_end", 30.0, 10.0), ("save_every", 10, 1), ("segment", math.nan, 1000.0)],
)
def test_rows_of_another_horizon_are_history(field, old, new):
    rows = sweep("h", 2.0, (4e-3, 2e-3, 1e-3), 22, **{field: old})
    rows += sweep("h", 4.0, (2e-3,), 23, **{field: new})
    df = current(frame(rows))
    assert len(df) == 1 and df["attitude_error_max"].iloc[0] == rows[-1]["attitude_error_max"]
    assert math.isnan(df["convergence_order"].iloc[0])  # one point: no fit


def test_rows_of_an_older_engine_version_are_history():
    rows = sweep("h", 2.0, (4e-3, 2e-3, 1e-3), 22)
    rows += sweep("h", 4.0, (4e-3, 2e-3), 23, engine_version="3.4.0")
    other = row("other", scenario_hash="h", engine="director", integrator="rattle")
    rows += [{**other, "finished_at": "2026-11-20T00:00:00+00:00"}]
    df = current(frame(rows))
    mj = df[df["engine"] == "mujoco"]
    assert set(mj["engine_version"]) == {"3.4.0"} and len(mj) == 2
    assert len(df[df["engine"] == "director"]) == 1  # another engine's rows stay current


def _as_other_version(r: dict, version: str, finished_at: str) -> dict:
    """Row ``r`` as another suite version would have stored it: another identity."""
    new_id = hashlib.sha256(f"{r['run_id']}{version}".encode()).hexdigest()[:20]
    return {**r, "run_id": new_id, "suite_version": version, "finished_at": finished_at,
            "attitude_error_max": 9.99}  # fmt: skip


def test_the_run_just_made_is_shown_whatever_the_clocks_say(tmp_path):
    """A store holding rows of another suite version stamped a day ahead (a clock set ahead,
    on the machine that wrote them): a run of this version into the folder, made or found
    already done, is what the tables show, not the other rows because of their later
    finished_at."""
    from reports.run.runner import run_suite

    sc = scenarios.load("free_tumbling").replace(t_end=0.01, dt_sweep=())
    spec = RunSpec(sc, "director", "rattle", 1e-3)
    run_suite([spec], tmp_path, progress=False)
    with Store(tmp_path) as st:
        (ours,) = st.rows()
    ahead = _as_other_version(ours, "0.2.0", "2999-01-01T00:00:00+00:00")
    # the other version wrote last: its rows are the newest
    with Store(tmp_path, create=True) as st:
        st.put(ahead)
    assert list(read_results(tmp_path)["suite_version"]) == ["0.2.0"]
    # this version's run asked for again (found done, not run again): it is shown
    df, n_run = run_suite([spec], tmp_path, progress=False)
    assert n_run == 0 and list(df["suite_version"]) == [ours["suite_version"]]
    assert list(df["attitude_error_max"]) == [ours["attitude_error_max"]]
    # made fresh after the other version's rows (stamped a day ahead): shown too
    with Store(tmp_path, create=True) as st:
        st.delete([ours["run_id"]])
        st.touch([ahead["run_id"]])
    df, n_run = run_suite([spec], tmp_path, progress=False)
    assert n_run == 1 and list(df["suite_version"]) == [ours["suite_version"]]
    # the other version's row is history, kept
    assert len(read_results(tmp_path, all_rows=True)) == 2


# -- timings ------------------------------------------------------------------------------------
@pytest.fixture
def cheap():
    sc = scenarios.load("free_tumbling").replace(t_end=0.05, dt_sweep=())
    return RunSpec(sc, "director", "rattle", 1e-3)


def test_a_run_is_timed_once_and_its_scenario_again_in_alternation(cheap, tmp_path):
    """execute() times a run once; run_suite's timing pass runs the scenario's
    configurations again (those whose own timing did not run clean), alternating, and each
    row keeps the best of its timings."""
    r = runner.execute(cheap)
    assert r["status"] == "ok" and r["timing_repeats"] == 1
    # per step: the whole step's CPU time; the engine's share of it
    assert r["ns_per_step"] == pytest.approx(1e9 * r["cpu_time_s"] / r["nstep"], rel=1e-12)
    assert 0 < r["engine_time_s"] <= r["cpu_time_s"] <= r["cpu_time_max_s"]
    assert r["cpu_time_s"] <= r["wall_time_s"] and 0 < r["cpu_share"] <= 1
    other = RunSpec(cheap.scenario, "mujoco", "Euler", 1e-3)
    df, n = runner.run_suite([cheap, other], tmp_path, progress=False)
    assert n == 2
    for row in df.to_dict("records"):
        # up to timing.TIMINGS timings in all, their slowest kept beside; a run whose own
        # timing ran clean is not timed again (reports.run.timing.wanted)
        assert 1 <= row["timing_repeats"] <= timing.TIMINGS, row
        if row["timing_repeats"] == 1:
            assert timing.ran_clean(timing._from_row(row)), row
        assert row["engine_time_s"] <= row["engine_time_max_s"]
        assert row["cpu_time_s"] <= row["cpu_time_max_s"]


def test_the_timing_pass_keeps_the_fastest_clean_timing_and_respects_its_budget(cheap, monkeypatch):
    from references.engines.timing import Timing

    row = runner.execute(cheap)
    # the run's own timing starved (its spread half its estimate): timed until one runs clean
    row["engine_time_spread_s"] = 0.5 * row["engine_time_s"]
    unit = timing.TimingUnit(cheap.scenario.name, [cheap], {cheap.run_id: row})
    got = [Timing(5e-5, 1e-5, 2e-4, 9e-4, 1e-4), Timing(1e-4, 0.0, 2e-4, 2e-4, 1e-4)]
    monkeypatch.setattr(timing, "_run_again", lambda cls, spec, nstep, steps: got.pop(0))
    res = timing.time_unit(unit)
    cols = res.columns[cheap.run_id]
    # 5e-5 is starved (its spread is 20 %), the run's own too: 1e-4, the one clean timing
    assert cols["engine_time_s"] == pytest.approx(1e-4)
    assert cols["timing_repeats"] == 3 and not got
    monkeypatch.setattr(timing, "BUDGET_FACTOR", 0.0)
    monkeypatch.setattr(timing, "BUDGET_FLOOR_S", 0.0)
    assert timing.time_unit(unit).columns == {}  # no budget: nothing timed again


def test_the_reference_records_its_cpu_time():
    # compare's cost range needs the process's CPU time over the run: without it a slowdown
    # under load cannot be told from a slower engine (the exact reference was called 2.6x
    # slower on an identical rerun beside a second suite before it recorded one)
    sc = scenarios.load("free_tumbling").replace(t_end=0.05, dt_sweep=())
    r = runner.execute(RunSpec(sc, "exact", "reference", 1e-3))
    assert r["status"] == "ok" and 0 < r["cpu_time_s"] < 60, r["message"]


def test_a_system_run_is_timed_in_cpu_time_by_its_builder():
    # a system's builder times its engine calls on the run's stopwatch
    # (references.engines.timing.lap): its row has the engine's CPU time and its spread
    chain = scenarios.load("spinning_chain").replace(t_end=0.05, dt_sweep=())
    for engine, integ in (("director", "rattle"), ("mujoco", "Euler")):
        r = runner.execute(RunSpec(chain, engine, integ, 1e-3))
        assert r["status"] == "ok", r["message"]
        assert 0 < r["engine_time_s"] <= r["cpu_time_s"] <= r["wall_time_s"] + 1e-9, r
        assert r["engine_time_spread_s"] >= 0 and 0 < r["cpu_share"] <= 1
