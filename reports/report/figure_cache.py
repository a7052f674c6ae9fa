"""Figures reused across results folders: a scenario's figure whose inputs are those of a
figure drawn before, in any folder, is copied from the user's cache instead of drawn again.

A figure's inputs are the code that draws it, its kind and scenario, the scenario's rows
without the columns no such figure shows (:data:`VOLATILE`: the timings, the time a run
finished, a compilation's time in the settings; the rows hold each engine's place in the
folder's engine order, :data:`reports.report.labels.ENGINE_RANK`, which the legends and
colours follow), the styles of its configurations and the *contents* of the runs' series
files (and of a robot model's importer table). A second run of the same code on the same
engines gives byte-identical series and metrics (the engines are deterministic; the timings
are not), so its figures are copies; a change to any input is a new key, drawn anew. The
work-precision figure shows the timings and is never reused (nor the scorecard picture).

The cache lives in ``$DIRECTOR_BENCH_CACHE/figures`` (default ``~/.cache/director-bench``,
:func:`reports.cache_root`), one folder per key holding the figure's PNG and its ``.json``;
it keeps at most :data:`MAX_ENTRIES` figures, the least recently used removed first. A cache
that cannot be read or written is no error: the figure is drawn.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
from pathlib import Path

from reports import cache_root
from reports.store.runs import TIMING_COLUMNS, error_series_path, slug

#: the figures whose inputs hold no timing, reused across folders
REUSED = ("scenario", "errors", "rates", "system", "joint_angles", "importers", "convergence")

#: columns of the results no reused figure shows: timings and clock times, and the settings
#: (compared without their compilation times)
VOLATILE = TIMING_COLUMNS | {"settings"}

#: most figures kept in the cache (a default folder has about 50 reusable ones)
MAX_ENTRIES = 2000


def folder() -> Path:
    return cache_root() / "figures"


def _settings_without_times(text) -> str:
    """A run's settings (JSON) without the entries that are times (MJX's compilation)."""
    try:
        doc = json.loads(text) if text else {}
    except (TypeError, ValueError):
        return str(text)
    if not isinstance(doc, dict):
        return str(text)
    return json.dumps({k: v for k, v in doc.items() if "time s" not in k}, sort_keys=True)


def _digest(path: Path) -> str:
    """The content hash of a file ("" when it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            return hashlib.file_digest(fh, "blake2b").hexdigest()
    except OSError:
        return ""


def inputs(scenario: str, sub, styles, root: Path) -> str:
    """The digest of what a scenario's reused figures are drawn from: ``sub`` (its rows,
    without :data:`VOLATILE`), their ``styles`` and the contents of the series files under
    ``root`` (and a robot model's importers table); computed once per scenario."""
    h = hashlib.sha256()
    h.update(f"{scenario}\0".encode())
    sub = sub.sort_values("run_id")
    cols = [c for c in sub.columns if c not in VOLATILE]
    h.update(sub[cols].to_json(orient="values", double_precision=15).encode())
    if "settings" in sub.columns:
        h.update("\0".join(map(_settings_without_times, sub["settings"])).encode())
    for r in sub[["engine", "integrator", "family", "trajectory"]].to_dict("records"):
        h.update(json.dumps(styles.of(r), default=str, sort_keys=True).encode())
        if r["trajectory"]:
            h.update(_digest(Path(root) / error_series_path(Path(r["trajectory"]))).encode())
    table = Path(root) / "importers" / f"{slug(scenario)}.json"  # a robot model's
    if table.is_file():
        h.update(_digest(table).encode())
    return h.hexdigest()


def key(kind: str, inputs_digest: str, code: str) -> str:
    """The key of the ``kind`` figure drawn from ``inputs_digest`` (:func:`inputs`) by the
    code whose digest is ``code`` (reports.report.canvas._hash_code)."""
    return hashlib.sha256(f"{code}\0{kind}\0{inputs_digest}".encode()).hexdigest()


#: the file of an entry that records a scenario without such a figure
NONE = "no-figure"


def fetch(k: str, out: Path) -> str | None:
    """Copy the cached figure of key ``k`` (its PNG and ``.json``) into ``out``; its file
    name, "" when the entry records that there is no such figure, or None when the cache
    does not hold the key."""
    entry = folder() / k
    try:
        files = list(entry.iterdir())
        if [p.name for p in files] == [NONE]:
            os.utime(entry)
            return ""
        pngs = [p for p in files if p.suffix == ".png"]
        if len(pngs) != 1 or not pngs[0].with_suffix(".json").exists():
            return None
        png = pngs[0]
        shutil.copyfile(png, out / png.name)
        shutil.copyfile(png.with_suffix(".json"), out / png.with_suffix(".json").name)
        os.utime(entry)  # used now: pruned last
    except OSError:
        return None
    return png.name


def put(k: str, png: Path | None) -> None:
    """Keep the figure ``png`` (and its ``.json``) under key ``k``, or (None) that there is
    no such figure; nothing on failure."""
    entry = folder() / k
    tmp = entry.with_name(entry.name + f".tmp{os.getpid()}")
    try:
        tmp.mkdir(parents=True, exist_ok=True)
        if png is None:
            (tmp / NONE).write_bytes(b"")
        else:
            shutil.copyfile(png, tmp / png.name)
            shutil.copyfile(png.with_suffix(".json"), tmp / png.with_suffix(".json").name)
        if entry.exists():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            os.rename(tmp, entry)  # whole or absent: a reader never sees half an entry
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)


def prune(limit: int = MAX_ENTRIES) -> None:
    """Remove the least recently used entries beyond ``limit``."""
    with contextlib.suppress(OSError):
        entries = [p for p in folder().iterdir() if p.is_dir()]
        if len(entries) <= limit:
            return
        entries.sort(key=lambda p: p.stat().st_mtime)
        for p in entries[: len(entries) - limit]:
            shutil.rmtree(p, ignore_errors=True)
