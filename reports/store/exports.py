"""The exports of a results store, ``results.csv`` and ``results.parquet``, and noticing when
one was changed by hand.

The store (``results.sqlite``) is what every command reads; the exports are copies of its
current view for spreadsheets and scripts. A user who edits ``results.csv`` (a verdict turned
to pass, a value corrected) changes nothing the suite reads, and the next ``run`` writes the
file again. So that neither happens unnoticed, :func:`record` keeps each export's SHA-256 in
the store's ``meta`` table when it is written, and :func:`edited` compares the files with it:
every command that reads a folder says which export was changed and, for the CSV, the first
cell that differs from the store; ``run`` moves an edited export aside
(:func:`keep_edited`) before writing it again.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
from pathlib import Path

from reports.store.atomic import replacing
from reports.store.results import Store, read_results
from reports.store.runs import RESULT_COLUMNS

#: the exports, written by reports.store.results.export
EXPORTS = ("results.csv", "results.parquet")
#: the store's meta key holding {export name: SHA-256 of the file as written}
META_KEY = "exports_sha256"


def _digest(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def export(folder: str | Path, df=None) -> list[Path]:
    """Write ``results.csv`` and ``results.parquet`` (the current view) from the store, each
    by writing a temporary file and renaming it over the old one, and record their digests
    (:func:`record`)."""
    folder = Path(folder)
    if df is None:
        df = read_results(folder)
    paths = []
    csv_path = folder / "results.csv"
    with replacing(csv_path) as tmp, tmp.open("w", newline="") as fh:
        fh.write(csv_text(df))
    paths.append(csv_path)
    pq = folder / "results.parquet"
    with replacing(pq) as tmp:
        df[list(RESULT_COLUMNS)].to_parquet(tmp, index=False)
    paths.append(pq)
    record(folder, paths)
    return paths


def csv_text(df) -> str:
    """The results table ``df`` as results.csv holds it (NaN as an empty cell, floats
    exactly)."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(RESULT_COLUMNS)
    for rec in df[list(RESULT_COLUMNS)].itertuples(index=False):
        w.writerow(_csv_value(v) for v in rec)
    return buf.getvalue()


def _csv_value(v) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return str(v)


def record(folder: Path, paths) -> None:
    """Keep the digests of the exports just written in the store (read by :func:`edited`)."""
    digests = {Path(p).name: _digest(Path(p)) for p in paths}
    with Store(folder) as st:
        st.set_meta(META_KEY, json.dumps(digests, sort_keys=True))


def edited(folder: str | Path) -> dict[str, str]:
    """{export name: a sentence saying so} for each export of ``folder`` that differs from
    what the suite wrote (nothing for a folder whose store recorded no digests, or an export
    that is absent)."""
    folder = Path(folder)
    try:
        with Store(folder) as st:
            recorded = json.loads(st.get_meta(META_KEY) or "{}")
    except (FileNotFoundError, ValueError):
        return {}
    out = {}
    for name, want in recorded.items():
        path = folder / name
        got = _digest(path) if path.is_file() else None
        if want is None or got is None or got == want:
            continue
        where = _first_difference(folder, path) if name.endswith(".csv") else ""
        out[name] = (
            f"{path} was changed after director-bench wrote it{where}. Every command reads "
            f"the results store ({folder / 'results.sqlite'}), never {name}: the change has no "
            f"effect, and the next `director-bench run` into this folder moves the file aside "
            f"to {name}.edited and writes it again from the store"
        )
    return out


def _first_difference(folder: Path, path: Path) -> str:
    """`` (line N, run R, column C: 'x', the store says 'y')``: the first cell of the CSV
    ``path`` that differs from the CSV the store's current view gives now, or "" when the
    rows cannot be matched cell by cell."""
    try:
        mine = list(csv.reader(io.StringIO(csv_text(read_results(folder)))))
        theirs = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8", errors="replace"))))
    except (OSError, csv.Error):
        return ""
    head = mine[0] if mine else []
    for n, (a, b) in enumerate(zip(mine, theirs, strict=False), start=1):
        if a == b:
            continue
        if len(a) != len(b):
            return f" (line {n} has {len(b)} cells, the store's {len(a)})"
        k = next(i for i, (x, y) in enumerate(zip(a, b, strict=True)) if x != y)
        run = f", run {a[0]}" if n > 1 and a else ""
        return f" (line {n}{run}, column {head[k]}: {b[k]!r}, the store says {a[k]!r})"
    if len(mine) != len(theirs):
        return f" ({len(theirs)} lines, the store's view has {len(mine)})"
    return ""


def keep_edited(folder: str | Path) -> list[Path]:
    """Move each edited export of ``folder`` (:func:`edited`) aside to ``<name>.edited``
    (replacing an older one) before a run writes the exports again; returns the new paths."""
    folder = Path(folder)
    moved = []
    for name in edited(folder):
        target = folder / f"{name}.edited"
        (folder / name).replace(target)
        moved.append(target)
    return moved
