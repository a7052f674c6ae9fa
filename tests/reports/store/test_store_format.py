"""The store records each run's scene kind (``scene_kind``, store format 2) and reads a store of
format 1, written before that column: its rows are completed as they are read, and rewritten
in format 2 when the store is opened for writing. The kinds a format-1 store is given are
checked against the kinds the scenario files declare (``sc.kind``), on rows of real runs."""

from __future__ import annotations

import hashlib
import json
import sqlite3

import pytest

import scenarios
from reports.run.runner import execute
from reports.store.results import STORE_FORMAT, Store, StoreDamaged, checksum, read_results
from reports.store.runs import RunSpec

#: (scenario, engine, integrator): a single body, a system of bodies, a contact scene
RUNS = (
    ("free_tumbling", "director", "rattle"),
    ("four_bar", "director", "rattle"),
    ("block_incline_stick", "mujoco", "pyramidal"),
)


@pytest.fixture(scope="module")
def rows():
    """Rows of real runs (a short horizon), one of each scene kind, and a run of the system
    that does not run (an unknown integrator: no metric at all)."""
    out = []
    for name, engine, integ in (*RUNS, ("four_bar", "director", "no-such-integrator")):
        sc = scenarios.load(name)
        row = execute(RunSpec(sc, engine, integ, sc.dt, t_end=20 * sc.dt, keep="none"))
        row.pop("_run_seconds", None)
        row.pop("_references", None)
        out.append(row)
    statuses = [r["status"] for r in out]
    assert statuses == ["ok", "ok", "ok", "unsupported"], [r["message"] for r in out]
    return out


def _format_1_store(folder, rows) -> None:
    """A store as the format-1 code wrote it: the same tables, format record 1, each row's
    JSON without ``scene_kind`` and its checksum taken of that JSON."""
    with Store(folder, create=True):
        pass
    con = sqlite3.connect(folder / "results.sqlite", isolation_level=None)
    for r in rows:
        old = {k: v for k, v in r.items() if k != "scene_kind"}
        text = json.dumps(old, sort_keys=True, separators=(",", ":"), allow_nan=True)
        con.execute(
            "INSERT INTO runs VALUES (?,?,?,?,?,?,?,?,?)",
            (r["run_id"], r["scenario"], r["engine"], r["integrator"], r["dt"], r["status"],
             r["finished_at"], text, checksum(text)),
        )  # fmt: skip
    con.execute("UPDATE meta SET value = '1' WHERE key = 'format'")
    con.close()


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _content(folder):
    """The rows and the meta records of a store, as stored."""
    con = sqlite3.connect(folder / "results.sqlite")
    try:
        return (
            con.execute("SELECT * FROM runs ORDER BY rowid").fetchall(),
            con.execute("SELECT * FROM meta ORDER BY key").fetchall(),
        )
    finally:
        con.close()


def _declared(name: str) -> str:
    return scenarios.load(name).kind


def test_the_runner_records_each_scene_kind_as_the_scenario_declares_it(rows, tmp_path):
    assert [r["scene_kind"] for r in rows] == ["body", "system", "contact", "system"]
    with Store(tmp_path, create=True) as st:
        for r in rows:
            st.put(r)
    df = read_results(tmp_path, all_rows=True)
    assert dict(zip(df["run_id"], df["scene_kind"], strict=True)) == {
        r["run_id"]: _declared(r["scenario"]) for r in rows
    }


def test_a_format_1_store_is_read_with_each_scene_kind_and_left_as_it_is(rows, tmp_path):
    _format_1_store(tmp_path, rows)
    path = tmp_path / "results.sqlite"
    before = _digest(path)
    with Store(tmp_path) as st:
        got = st.rows()
    # the failed run of the system has no metric: it takes its scenario's kind
    assert {r["run_id"]: r["scene_kind"] for r in got} == {
        r["run_id"]: _declared(r["scenario"]) for r in rows
    }
    df = read_results(tmp_path)
    assert sorted(df["scene_kind"]) == ["body", "contact", "system", "system"]
    assert _digest(path) == before  # reading does not migrate


def test_a_format_1_store_opened_for_writing_is_migrated_whole(rows, tmp_path):
    _format_1_store(tmp_path, rows[:2])
    with Store(tmp_path, create=True) as st:
        st.put(rows[2])  # a new run into the migrated store
        assert st.get_meta("format") == str(STORE_FORMAT)
    con = sqlite3.connect(tmp_path / "results.sqlite")
    stored = {
        rid: json.loads(text) for rid, text in con.execute("SELECT run_id, row_json FROM runs")
    }
    con.close()
    assert {rid: r["scene_kind"] for rid, r in stored.items()} == {
        r["run_id"]: _declared(r["scenario"]) for r in rows[:3]
    }
    # every other value as the format-1 row held it; checksums verified on this read
    with Store(tmp_path) as st:
        again = {r["run_id"]: r for r in st.rows()}
    for r in rows[:2]:
        assert json.dumps(again[r["run_id"]], sort_keys=True) == json.dumps(r, sort_keys=True)


def test_a_damaged_format_1_store_is_refused_not_migrated(rows, tmp_path):
    _format_1_store(tmp_path, rows[:2])
    con = sqlite3.connect(tmp_path / "results.sqlite", isolation_level=None)
    con.execute("UPDATE runs SET checksum = '0000000000000000' WHERE scenario = 'four_bar'")
    con.close()
    before = _content(tmp_path)
    with pytest.raises(StoreDamaged, match="fail their checksum"):
        Store(tmp_path, create=True)
    assert _content(tmp_path) == before  # no row rewritten, still format 1
    assert before[1] == [("format", "1")]


def test_a_store_of_an_unknown_format_is_refused(tmp_path):
    with Store(tmp_path, create=True):
        pass
    con = sqlite3.connect(tmp_path / "results.sqlite", isolation_level=None)
    con.execute(f"UPDATE meta SET value = '{STORE_FORMAT + 1}' WHERE key = 'format'")
    con.close()
    with pytest.raises(StoreDamaged, match="format"):
        Store(tmp_path)
