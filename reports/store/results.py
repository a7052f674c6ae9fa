"""The results store: the transactional store the rows of an output folder live in, and its
reading views.

Every run is one row (:data:`reports.store.runs.RESULT_COLUMNS`, documented column by column
in ``docs/results.md``). The source of truth is ``results.sqlite`` in the output folder, an
SQLite database in WAL mode written one row per transaction: any number of processes (the
local pool's parent, several ``director-bench run`` commands, a Dask client) may write into
one folder at once without losing a row, a killed process never leaves half a row, and every
row carries a checksum of its content, verified on every read, so a damaged file is reported
(:class:`StoreDamaged`), never read as a result. ``results.csv`` and ``results.parquet`` are
exports written from the store (reports.store.exports); ``report``, ``check`` and
``compare`` read the store.

A rerun skips a run whose identity (:attr:`reports.store.runs.RunSpec.run_id`) is in the
store; a changed input runs again. Rows of older identities stay in the store as history:
:func:`current` keeps, per scenario, only the rows of its newest identity
(:data:`~reports.store.runs.IDENTITY_COLUMNS`: scenario content, horizon, segmenting, suite
version; per engine its newest version, per integrator its newest save_every), then the
newest row per configuration (:data:`~reports.store.runs.CONFIG_KEY`); tables, reports and
convergence fits read that view.

The store is refused, never converted, when the file is an SQLite database of another
application (:data:`APPLICATION_ID`, the tables it holds). A store of an older format of ours
is read: its rows are completed as they are read (:func:`upgrade_rows`), and rewritten in the
current format when the store is opened for writing (:meth:`Store._migrate`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import sqlite3
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from reports.store.atomic import replacing
from reports.store.runs import (
    CONFIG_KEY,
    NUMERIC_COLUMNS,
    RESULT_COLUMNS,
    RETRY_STATUSES,
    SCENARIO_IDENTITY,
    _ident_value,
)

STORE_NAME = "results.sqlite"
#: version of the store's layout, checked on open. 2: every row holds its scene's kind
#: (``scene_kind``); 1: rows without it (read, and migrated: :func:`upgrade_rows`)
STORE_FORMAT = 2
#: the formats this code reads
READABLE_FORMATS = frozenset({"1", str(STORE_FORMAT)})
#: SQLite ``application_id`` of a results store ("DBR1" in ASCII); a database with another
#: non-zero id, or with tables of its own, is not ours and is refused
APPLICATION_ID = 0x44425231
#: the tables of a results store
STORE_TABLES = frozenset({"runs", "meta"})


class StoreDamaged(RuntimeError):
    """The results store cannot be read as results (not a database, malformed, a row whose
    checksum does not match); the message names the file and what to do."""


class StoreForeign(StoreDamaged):
    """The file named like a results store is another application's SQLite database; it is
    refused, never read and never converted."""


class StoreUnwritable(RuntimeError):
    """The results store cannot be written (read-only folder, disk full, file-size limit)."""


class StoreLocked(StoreUnwritable):
    """Another process held the store's write lock for longer than :data:`BUSY_TIMEOUT_S`:
    the store is fine, the message names the holder and says to wait."""


#: how long a writer waits for another process's write lock on the store (s)
BUSY_TIMEOUT_S = 60.0


def _is_busy(exc: sqlite3.Error) -> bool:
    text = str(exc)
    return "locked" in text or "busy" in text


def _transaction(con: sqlite3.Connection, statements: Callable[[sqlite3.Connection], None]):
    """``statements(con)`` in one write transaction (BEGIN IMMEDIATE .. COMMIT), rolled back
    if any of them fails."""
    con.execute("BEGIN IMMEDIATE")
    try:
        statements(con)
        con.execute("COMMIT")
    except sqlite3.Error:
        with contextlib.suppress(sqlite3.Error):
            con.execute("ROLLBACK")
        raise


def _retry_busy(attempt: Callable, deadline: float):
    """``attempt()``, tried again while SQLite answers "database is locked" and ``deadline``
    (time.monotonic) is ahead. SQLite's busy handler (``busy_timeout``) waits for most
    locks, but not all: switching a new database file to WAL while another process opens
    it, or the last connection's cleanup of the WAL, answer busy at once. Those locks last
    milliseconds; this waits them out (at most until the deadline) instead of failing."""
    pause = 0.01
    while True:
        try:
            return attempt()
        except sqlite3.OperationalError as exc:
            if not _is_busy(exc) or time.monotonic() + pause > deadline:
                raise
        time.sleep(pause)
        pause = min(2 * pause, 0.5)


def lock_holders(path: Path) -> list[str]:
    """The processes holding a POSIX lock on the database ``path`` or its -wal/-shm files, as
    ``pid (command line)`` (Linux ``/proc/locks``; empty where that is not available)."""
    inodes = set()
    for suffix in ("", "-wal", "-shm"):
        with contextlib.suppress(OSError):
            inodes.add(os.stat(f"{path}{suffix}").st_ino)
    holders = []
    with contextlib.suppress(OSError):
        for line in Path("/proc/locks").read_text().splitlines():
            parts = line.split()
            if len(parts) < 6 or parts[1] != "POSIX" or parts[4] == str(os.getpid()):
                continue
            if int(parts[5].rsplit(":", 1)[-1]) in inodes and parts[4] not in holders:
                holders.append(parts[4])
    out = []
    for pid in holders:
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            cmd = "?"
        out.append(f"process {pid} ({' '.join(cmd.split())[:120]})")
    return out


# -- canonical form and checksum ----------------------------------------------------------------


def _clean(v):
    if isinstance(v, float) or hasattr(v, "dtype"):
        f = float(v)
        return f
    if isinstance(v, bool):
        return v
    if isinstance(v, int):
        return int(v)
    return "" if v is None else str(v)


def canonical(row: dict) -> str:
    """The row as canonical JSON (sorted keys, every column, floats exactly), the text the
    checksum is taken of."""
    data = {c: _clean(row.get(c, "")) for c in RESULT_COLUMNS}
    return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)


def checksum(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# -- older formats ------------------------------------------------------------------------------


def _legacy_kind(rows: list[dict]) -> str:
    """The scene kind of a scenario's rows written before the store recorded it (format 1),
    from what its runs measured: ``contact`` when a run has a metric only contact scenes have,
    ``system`` when one has a metric of systems that single bodies do not have, else ``body``
    (the metrics' scene kinds are the catalog's, :data:`scenarios.metric_catalog.METRICS`)."""
    from scenarios.metric_catalog import METRICS

    def measured(names) -> bool:
        for r in rows:
            for n in names:
                try:
                    if math.isfinite(float(r.get(n))):
                        return True
                except (TypeError, ValueError):
                    continue
        return False

    if measured([m.name for m in METRICS if m.contact and not (m.body or m.system)]):
        return "contact"
    if measured([m.name for m in METRICS if m.system and not m.body]):
        return "system"
    return "body"


def upgrade_rows(rows: list[dict]) -> list[dict]:
    """``rows`` (store order) with the columns of the current format filled in where a row of
    an older format lacks them: ``scene_kind``, per scenario by :func:`_legacy_kind`. Rows that
    have every column are returned as they are."""
    old = [r for r in rows if "scene_kind" not in r]
    if not old:
        return rows
    by_scenario: dict[str, list[dict]] = {}
    for r in old:
        by_scenario.setdefault(r.get("scenario", ""), []).append(r)
    kinds = {name: _legacy_kind(rs) for name, rs in by_scenario.items()}
    return [r if "scene_kind" in r else {**r, "scene_kind": kinds[r.get("scenario", "")]}
            for r in rows]  # fmt: skip


# -- the store ----------------------------------------------------------------------------------


def store_path(folder: str | Path, name: str = STORE_NAME) -> Path:
    return Path(folder) / name


class Store:
    """The results store of one output folder (see the module docstring).

    ``Store(folder)`` opens an existing store (read); ``Store(folder, create=True)`` creates
    it if needed (write). ``name`` is the file's name in the folder (the ensemble has its
    own store). Every method raises :class:`StoreDamaged` or
    :class:`StoreUnwritable` with the file named, never an sqlite3 traceback.
    """

    def __init__(self, folder: str | Path, create: bool = False, name: str = STORE_NAME):
        self.path = store_path(folder, name)
        if not create and not self.path.exists():
            raise FileNotFoundError(
                f"{Path(folder)}: no results store here ({name} is missing); run "
                "`director-bench run --out FOLDER` first"
            )
        self._con = self._open(create)

    def _open(self, create: bool) -> sqlite3.Connection:
        since = time.monotonic()
        try:
            writable = os.access(self.path.parent, os.W_OK) and os.access(self.path, os.W_OK)
            if not create and not writable:
                # a store nobody can write here (a read-only folder or file): read it as it
                # is, without the -shm and -wal files a writable WAL database needs
                uri = f"{self.path.resolve().as_uri()}?immutable=1"
                con = sqlite3.connect(uri, uri=True, isolation_level=None)
                self._refuse_foreign(con)
                self._check(con)
                return con
            return _retry_busy(lambda: self._connect(create), since + BUSY_TIMEOUT_S)
        except sqlite3.DatabaseError as exc:
            raise self._damaged(exc, since) from None
        except sqlite3.Error as exc:  # pragma: no cover - other sqlite failures
            raise StoreUnwritable(f"{self.path}: cannot open the results store: {exc}") from None

    def _connect(self, create: bool) -> sqlite3.Connection:
        """A writable connection to the store, set up (one attempt; closed if it fails)."""
        con = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT_S, isolation_level=None)
        try:
            con.execute(f"PRAGMA busy_timeout = {int(1000 * BUSY_TIMEOUT_S)}")
            self._refuse_foreign(con)
            if create:
                con.execute("PRAGMA journal_mode = WAL")
                # WAL with synchronous NORMAL: a commit is atomic and survives a killed
                # process; it reaches the disk at the next checkpoint, not at every commit
                # (an fsync per row cost ~10 ms of wall time each). An OS crash or power cut
                # may roll back the last rows (their runs are redone), never damage the store.
                con.execute("PRAGMA synchronous = NORMAL")
                self._create_schema(con)
            self._check(con)
            if create and self._format != str(STORE_FORMAT):
                self._migrate(con)
        except BaseException:
            con.close()
            raise
        return con

    def _refuse_foreign(self, con) -> None:
        """Raise :class:`StoreForeign` when the file is another application's database (an
        application_id not ours, or tables other than a store's), before anything is
        written to it: a database that is not ours is never converted."""
        app = con.execute("PRAGMA application_id").fetchone()[0]
        tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if app not in (0, APPLICATION_ID) or not tables <= STORE_TABLES:
            other = ", ".join(sorted(tables - STORE_TABLES)) or "none"
            raise StoreForeign(
                f"{self.path} is not a director-bench results store (SQLite application_id "
                f"{app:#x}, ours is {APPLICATION_ID:#x}; tables not ours: {other}). Nothing was "
                "read or changed. Give another output folder (--out), or move that file "
                "elsewhere if it does not belong there"
            )
        if tables and app == 0:  # a store written before the application_id was set
            try:
                fmt = con.execute("SELECT value FROM meta WHERE key = 'format'").fetchone()
            except sqlite3.Error:
                fmt = None
            if fmt is None:
                raise StoreForeign(
                    f"{self.path} is not a director-bench results store (tables "
                    f"{', '.join(sorted(tables))} without the store's format record). Nothing "
                    "was read or changed. Give another output folder (--out), or move that "
                    "file elsewhere if it does not belong there"
                )

    @staticmethod
    def _create_schema(con) -> None:
        """The store's id, tables and format record, in one transaction: a process killed
        while it creates them leaves an empty database (read as a store of no rows), never a
        table without the other."""

        def statements(con):
            con.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            con.execute(
                "CREATE TABLE IF NOT EXISTS runs (run_id TEXT PRIMARY KEY, scenario TEXT, "
                "engine TEXT, integrator TEXT, dt REAL, status TEXT, finished_at TEXT, "
                "row_json TEXT NOT NULL, checksum TEXT NOT NULL)"
            )
            con.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
            con.execute("INSERT OR IGNORE INTO meta VALUES ('format', ?)", (str(STORE_FORMAT),))

        _transaction(con, statements)

    #: an empty database: a store whose creation was cut short, read as holding no rows
    _empty = False

    def _check(self, con) -> None:
        ok = con.execute("PRAGMA quick_check").fetchone()[0]
        if ok != "ok":
            raise StoreDamaged(self._advice(f"the database is malformed ({ok})"))
        tables = con.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table'")
        if tables.fetchone()[0] == 0:
            self._empty = True
            return
        fmt = con.execute("SELECT value FROM meta WHERE key = 'format'").fetchone()
        if fmt is None or fmt[0] not in READABLE_FORMATS:
            raise StoreDamaged(self._advice(f"not a director-bench results store (format {fmt})"))
        self._format = fmt[0]

    #: the format of the store as opened (:data:`READABLE_FORMATS`)
    _format = str(STORE_FORMAT)

    def _migrate(self, con) -> None:
        """Rewrite a store of an older format in the current one, in one transaction: every
        row, its checksum verified first, completed by :func:`upgrade_rows` and given its new
        checksum, then the format record. A damaged row stops it before anything is written
        (:class:`StoreDamaged`); a process killed during it leaves the old store whole."""
        rows = self._verified(con)
        new = upgrade_rows(rows)

        def statements(con):
            for row in new:
                text = canonical(row)
                con.execute(
                    "UPDATE runs SET row_json = ?, checksum = ? WHERE run_id = ?",
                    (text, checksum(text), row["run_id"]),
                )
            con.execute("UPDATE meta SET value = ? WHERE key = 'format'", (str(STORE_FORMAT),))

        _transaction(con, statements)
        self._format = str(STORE_FORMAT)

    def _advice(self, what: str) -> str:
        return (
            f"results store {self.path} is damaged: {what}. Nothing was read from it. Move it "
            f"aside (e.g. `mv {self.path} {self.path}.damaged`) and run again: the runs it held "
            "are redone"
        )

    def _damaged(self, exc, since: float | None = None) -> Exception:
        """The store error for the sqlite3 error ``exc``; ``since`` (time.monotonic) is when
        the failed attempt began waiting, for a locked store (without it, the wait was
        SQLite's busy handler's, :data:`BUSY_TIMEOUT_S`)."""
        text = str(exc)
        if _is_busy(exc):
            who = ", ".join(lock_holders(self.path)) or "another process"
            waited = BUSY_TIMEOUT_S if since is None else time.monotonic() - since
            return StoreLocked(
                f"results store {self.path} stayed locked for the {waited:.1f} s this process "
                f"waited (at most {BUSY_TIMEOUT_S:g} s; SQLite: {text}); processes that have "
                f"it open: {who}. The store is not damaged: wait for the other process to "
                "finish (or stop it) and run the same command again; finished runs are kept"
            )
        if "readonly" in text or "unable to open" in text:
            return StoreUnwritable(f"{self.path}: cannot write the results store: {text}")
        if "full" in text or "disk I/O" in text:
            return StoreUnwritable(
                f"{self.path}: cannot write the results store: {text} (disk full or a file "
                "size limit?); finished runs are kept, rerun to continue"
            )
        return StoreDamaged(self._advice(text))

    def close(self) -> None:
        with contextlib.suppress(sqlite3.Error):
            self._con.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- writing --------------------------------------------------------------------------
    def _write(self, statements: Callable[[sqlite3.Connection], None]) -> None:
        """``statements(con)`` in one write transaction, waiting out a busy store (at most
        :data:`BUSY_TIMEOUT_S`); any failure rolls it back and raises a store error."""
        since = time.monotonic()
        try:
            _retry_busy(lambda: _transaction(self._con, statements), since + BUSY_TIMEOUT_S)
        except sqlite3.Error as exc:
            raise self._damaged(exc, since) from None

    def put(self, row: dict) -> None:
        """Insert (or replace) one row in its own transaction."""
        text = canonical(row)
        vals = (
            row["run_id"],
            row["scenario"],
            row["engine"],
            row["integrator"],
            float(row["dt"]),
            row["status"],
            row.get("finished_at", ""),
            text,
            checksum(text),
        )
        self._write(
            lambda con: con.execute("INSERT OR REPLACE INTO runs VALUES (?,?,?,?,?,?,?,?,?)", vals)
        )

    def touch(self, run_ids: Iterable[str]) -> None:
        """Make the stored rows ``run_ids`` the newest, in this order, unchanged: a rerun that
        skips runs the store holds asks for them again, so they are what :func:`current`
        shows, whatever another invocation wrote since (one transaction)."""
        ids = list(run_ids)

        def statements(con):
            for i in ids:
                con.execute(
                    "UPDATE runs SET rowid = (SELECT MAX(rowid) + 1 FROM runs) WHERE run_id = ?",
                    (i,),
                )

        self._write(statements)

    def get_meta(self, key: str) -> str | None:
        if self._empty:
            return None
        try:
            got = self._con.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        except sqlite3.DatabaseError as exc:
            raise self._damaged(exc) from None
        return None if got is None else got[0]

    def set_meta(self, key: str, value: str) -> None:
        self._write(
            lambda con: con.execute("INSERT OR REPLACE INTO meta VALUES (?, ?)", (key, value))
        )

    def delete(self, run_ids: Iterable[str]) -> None:
        ids = list(run_ids)
        self._write(
            lambda con: con.executemany("DELETE FROM runs WHERE run_id = ?", [(i,) for i in ids])
        )

    # -- reading --------------------------------------------------------------------------
    def done_ids(self) -> set[str]:
        """Identities of the runs a rerun skips (every status but :data:`RETRY_STATUSES`),
        read from the checksummed rows (:meth:`rows`), so a status changed outside the
        store cannot make a rerun skip or retry a run."""
        return {r["run_id"] for r in self.rows() if r.get("status") not in RETRY_STATUSES}

    def rows(self) -> list[dict]:
        """Every row, checksums verified (:class:`StoreDamaged` on a mismatch), in the current
        format (a store of an older one: :func:`upgrade_rows`)."""
        if self._empty:
            return []
        try:
            return upgrade_rows(self._verified(self._con))
        except sqlite3.DatabaseError as exc:
            raise self._damaged(exc) from None

    def _verified(self, con) -> list[dict]:
        """Every row as stored, checksums verified (:class:`StoreDamaged` on a mismatch)."""
        data = con.execute(
            "SELECT run_id, status, row_json, checksum FROM runs ORDER BY rowid"
        ).fetchall()
        out, bad = [], []
        for run_id, status, text, chk in data:
            try:
                row = json.loads(text)
            except ValueError:
                row = None
            if (
                not isinstance(row, dict)
                or checksum(text) != chk
                or row.get("run_id") != run_id
                or row.get("status") != status
            ):
                bad.append(run_id)
                continue
            out.append(row)
        if bad:
            raise StoreDamaged(
                self._advice(f"{len(bad)} row(s) fail their checksum (first: {bad[0]})")
            )
        return out


# -- tables -------------------------------------------------------------------------------------


def frame(rows: list[dict]):
    """The rows as a pandas DataFrame with every column of :data:`RESULT_COLUMNS`."""
    import pandas as pd

    df = pd.DataFrame(rows, columns=list(RESULT_COLUMNS))
    for col in RESULT_COLUMNS:
        if col in NUMERIC_COLUMNS:
            df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
        else:
            df[col] = df[col].astype(object).where(df[col].notna(), "").astype(str)
    return df


def records(df) -> list[dict]:
    """The rows of a results table as dicts, their values Python objects as
    ``Series.tolist`` gives them (DataFrame.to_dict walks the rows one by one, a hundred
    times slower on a table of a few hundred runs; selecting each column costs the report's
    hundreds of calls on a scenario's rows 4x this one conversion of the table's blocks)."""
    cols = list(df.columns)
    return [dict(zip(cols, vals, strict=True)) for vals in df.to_numpy(dtype=object).tolist()]


def current(df):
    """The current view of the stored rows, sorted by :data:`CONFIG_KEY`, with the
    convergence orders of the dt sweeps filled in (reports.metrics.body).

    Per scenario, only the rows of its newest identity count (:data:`SCENARIO_IDENTITY`:
    the scenario's content, horizon, segmenting and suite version of its newest row; per
    engine, the version of that engine's newest row; per integrator, the save_every of its
    newest row); older rows are history, never current and never in a fit. Of the rest, the
    newest row of each configuration.

    Newest is last in ``df``'s order, the store's (:meth:`Store.rows`): the order the rows
    were written in, a rerun's skipped runs moved last (:meth:`Store.touch`), so that the
    runs of the last invocation are what every table shows. Never the rows' ``finished_at``:
    a clock set ahead, on this machine or another that wrote into the folder, would make
    another invocation's rows win."""
    from reports.metrics.body import add_convergence_orders

    if df.empty:
        return df
    df = df.reset_index(drop=True)
    df = df[_newest_identity(df)]
    df = df.drop_duplicates(subset=list(CONFIG_KEY), keep="last")  # NaN accuracies match
    df = df.sort_values(list(CONFIG_KEY), ignore_index=True)
    return add_convergence_orders(df)


def _newest_identity(df):
    """Mask of the rows (in store order, oldest first) that share their scenario's newest identity
    and their engine's newest version."""
    import pandas as pd

    keep = pd.Series(True, index=df.index)
    for group, cols in (
        (["scenario"], SCENARIO_IDENTITY),
        (["scenario", "engine"], ("engine_version",)),
        (["scenario", "engine", "integrator"], ("save_every",)),
    ):
        ident = pd.Series(
            [tuple(_ident_value(c, v) for c, v in zip(cols, vals, strict=True))
             for vals in df[list(cols)].itertuples(index=False)],
            index=df.index,
            dtype=object,
        )  # fmt: skip
        newest = ident.groupby([df[g] for g in group], sort=False).transform("last")
        keep &= ident == newest
    return keep


def read_results(folder: str | Path, all_rows: bool = False):
    """The results of an output folder as a DataFrame: the current view (one row per
    configuration, with convergence orders) or, with ``all_rows``, every stored row."""
    folder = Path(folder)
    if folder.is_file() and folder.name == STORE_NAME:
        folder = folder.parent
    elif folder.exists() and not folder.is_dir():
        raise FileNotFoundError(
            f"{folder}: not a results folder (give the folder that holds {STORE_NAME})"
        )
    with Store(folder) as st:
        df = frame(st.rows())
    return df if all_rows else current(df)


#: the reference rows of a folder written before the ``reference`` column was recorded: those
#: of this integrator family, the family of the suite's one reference then (its engine was
#: named alike); a fact of that store, not of the engine (:func:`reference_rows`)
LEGACY_REFERENCE_FAMILY = "exact"


def reference_rows(df):
    """Boolean Series: the rows of a reference engine (the exact or numerical reference every
    configuration is measured against, not a configuration under test), as the runner recorded
    it from the engine's ``is_reference`` flag in the ``reference`` column. A folder written
    before that column existed has it empty throughout; its reference rows are those of the
    family ``exact``, the family of the suite's one reference engine then."""
    flag = df["reference"].astype(float) if "reference" in df else None
    if flag is None or flag.isna().all():
        old = LEGACY_REFERENCE_FAMILY
        return df["family"] == old if "family" in df else df["engine"] == old
    return flag == 1.0


def is_reference_record(row) -> bool:
    """:func:`reference_rows` for one row (a dict)."""
    try:
        flag = float(row.get("reference", math.nan))
    except (TypeError, ValueError):
        flag = math.nan
    if math.isnan(flag):
        return row.get("family", row.get("engine")) == LEGACY_REFERENCE_FAMILY
    return flag == 1.0


def default_dt(rows) -> float:
    """The step shown in per-dt tables and time plots: the scenario's own ``dt``, the step of
    the exact reference's run; without such a row, the dt with the most runs, ties broken by
    the smaller step."""
    exact = rows[reference_rows(rows)]
    if len(exact):
        return float(exact["dt"].iloc[0])
    counts = rows.groupby("dt").size()
    return max(counts.index, key=lambda h: (counts[h], -h))


def write_parquet_table(table, path: Path, metadata: dict) -> None:
    """Write the Arrow ``table`` to ``path`` as Parquet, atomically (a temporary file in the
    same folder, then a rename), with ``metadata`` (JSON values) added to its schema."""
    import pyarrow.parquet as pq

    if metadata:
        meta = dict(table.schema.metadata or {})
        meta.update({k.encode(): json.dumps(v).encode() for k, v in metadata.items()})
        table = table.replace_schema_metadata(meta)
    with replacing(path) as tmp:
        # no dictionary encoding: trajectories are floats that hardly repeat, so the writer's
        # attempt at a dictionary only costs time (4x the write measured) and bytes. Each
        # float's bytes split into streams and zstd: lossless, a trajectory of 9001 states
        # 1.43 MB against snappy's 1.88 MB, and written faster (13 ms against 137 ms)
        pq.write_table(
            table, tmp, use_dictionary=False, compression="zstd", use_byte_stream_split=True
        )
