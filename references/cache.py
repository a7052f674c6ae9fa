"""The suite's cache folder, and the references kept in it across runs.

A reference (a system's numerical reference or closed form with its Floquet analysis, a
single body's closed form or numerical solution) depends only on its inputs and the code
that computes it, so a warm run reads the one an earlier run computed instead of computing
it again, as numba keeps its compiled code. :func:`kept` does it for a reference module:

- **key** (:func:`key`): a SHA-256 of everything the reference depends on: what it is
  (``what``: its kind of reference), the scenario's content (its ``scenario_hash``, as the
  results store computes it), the times it is asked at (their bytes: the time grid and the
  save grid, as they give the saved times), the tolerances and bounds of the code that
  computes it (their values, read when the key is made), the digest of that code
  (:func:`code_version`: every source file of :data:`CODE`, so an edit is a new key), the
  versions of numpy, scipy and numba, Python's and the machine's architecture;
- **entry**: one ``.npz`` file per key in ``$DIRECTOR_BENCH_CACHE/references`` (default
  ``~/.cache/director-bench``, :func:`cache_root`): the reference's arrays bit for bit and
  a JSON text of its other fields (floats written exactly: Python's shortest repr), its key
  and the CPU and wall time its computation took. Written to a temporary file and renamed:
  a reader sees a whole entry or none, and two processes writing one key write the same
  bytes. A computed reference is decoded from the very bytes written, so a run uses the same
  object whether it computed the reference or read it;
- **bound**: at most :data:`MAX_BYTES` in all, the least recently used entries removed
  first (a read touches its entry);
- **failure**: an entry that cannot be read, or whose key or fields are not the ones asked
  for, is computed again and written anew, with one line in :func:`drain`'s notes (the run
  prints it); a folder that cannot be written is no error (the reference is computed);
- **switch**: ``DIRECTOR_BENCH_REFERENCE_CACHE=off`` (or ``director-bench run
  --no-reference-cache``) computes every reference and keeps none.

:func:`cache_root` is the one declaration of the suite's cache folder (the figures reused
across results folders and the engine environments of ``versions`` live there too).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import io
import json
import os
import time
from pathlib import Path

import numpy as np

#: the environment variable naming the suite's cache folder
ROOT_ENV = "DIRECTOR_BENCH_CACHE"
#: the environment variable that switches the reference cache off (:data:`OFF` values)
SWITCH_ENV = "DIRECTOR_BENCH_REFERENCE_CACHE"
OFF = ("0", "off", "no", "false")
#: the entries kept at most, in bytes (a default suite's references take about 10 MB)
MAX_BYTES = 512 * 2**20
#: the entries' layout: a new one is a new key
FORMAT = 1

#: the source files of the code that computes a reference (relative to the repository): the
#: reference modules and this one (the entries' layout), the trajectory schema they fill, the
#: scenarios they read (their derived quantities: scales, inertias about the pivot, the
#: spanning tree) and the director model's body rules a scenario uses (its symmetric axis);
#: tests/references/test_reference_cache.py checks that computing every kind of reference
#: runs no suite module outside them
CODE = (
    "references/cache.py",
    "references/exact",
    "references/engines/exact",
    "references/trajectory.py",
    "references/conventions.py",
    "references/errors.py",
    "scenarios",
    "director_model/body.py",
)

_ROOT = Path(__file__).resolve().parents[1]


def cache_root() -> Path:
    """The suite's cache folder: ``$DIRECTOR_BENCH_CACHE`` or ``~/.cache/director-bench``."""
    root = os.environ.get(ROOT_ENV)
    return Path(root).expanduser() if root else Path.home() / ".cache" / "director-bench"


def folder() -> Path:
    """Where the references are kept."""
    return cache_root() / "references"


def enabled() -> bool:
    """Whether references are read from and kept in the cache (:data:`SWITCH_ENV`)."""
    return os.environ.get(SWITCH_ENV, "").strip().lower() not in OFF


def _files(code=CODE) -> list[Path]:
    out = []
    for rel in code:
        p = _ROOT / rel
        out += sorted(p.rglob("*.py")) if p.is_dir() else [p]
    return out


@functools.cache
def code_version(code: tuple = CODE) -> str:
    """The SHA-256 of the source files of ``code`` (their paths and contents), once per
    process."""
    h = hashlib.sha256()
    for p in _files(code):
        h.update(p.relative_to(_ROOT).as_posix().encode() + b"\0")
        h.update(p.read_bytes() + b"\0")
    return h.hexdigest()


@functools.cache
def versions() -> dict:
    """The versions of the libraries whose arithmetic a reference's bits depend on."""
    import platform
    import sys
    from importlib import metadata

    out = {"python": sys.version.split()[0], "machine": platform.machine()}
    for lib in ("numpy", "scipy", "numba", "llvmlite"):
        try:
            out[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:
            out[lib] = ""
    return out


def key(what: str, scenario_hash: str, t, tolerances: dict) -> str:
    """The key of the reference ``what`` of the scenario of content ``scenario_hash`` at the
    times ``t``, computed with ``tolerances`` (module docstring)."""
    t = np.ascontiguousarray(t, dtype=float)
    doc = {
        "format": FORMAT,
        "what": what,
        "scenario": scenario_hash,
        "times": hashlib.sha256(t.tobytes()).hexdigest(),
        "n": len(t),
        "tolerances": {k: repr(v) for k, v in sorted(tolerances.items())},
        "code": code_version(),
        "versions": versions(),
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:32]


# -- notes for the run's log -------------------------------------------------------------------

#: what this process did since the last :func:`drain`: keys read, keys computed and kept,
#: and lines for the run's log (an entry that could not be read)
_NOTES: dict = {"read": [], "computed": [], "lines": []}


def drain() -> dict:
    """What the cache did in this process since the last call ({"read": [keys],
    "computed": [keys], "lines": [text]}), emptied; {} when it did nothing."""
    got = {k: list(v) for k, v in _NOTES.items() if v}
    for v in _NOTES.values():
        v.clear()
    return got


# -- entries -----------------------------------------------------------------------------------


class Unreadable(Exception):
    """An entry that cannot be trusted (its text says why)."""


def encode(k: str, arrays: dict, fields: dict, cpu_s: float, wall_s: float) -> bytes:
    """The bytes of an entry: ``arrays`` (name -> array) bit for bit, ``fields`` (JSON) and
    the key and the computation's CPU and wall time."""
    meta = {"key": k, "fields": fields, "cpu_s": cpu_s, "wall_s": wall_s}
    buf = io.BytesIO()
    payload = {f"a_{n}": np.ascontiguousarray(a) for n, a in arrays.items()}
    np.savez(buf, meta=np.array(json.dumps(meta, allow_nan=True)), **payload)
    return buf.getvalue()


def decode(k: str, data: bytes) -> tuple[dict, dict, float, float]:
    """(arrays, fields, CPU s, wall s) of an entry's bytes; :class:`Unreadable` when they are
    not an entry of key ``k``."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"][()]))
            arrays = {n[2:]: z[n] for n in z.files if n.startswith("a_")}
    except Exception as exc:  # noqa: BLE001 - whatever the file holds, it is not trusted
        raise Unreadable(f"not an entry ({type(exc).__name__}: {exc})") from None
    if not isinstance(meta, dict) or meta.get("key") != k:
        held = meta.get("key") if isinstance(meta, dict) else meta
        raise Unreadable(f"it holds the key {held!r}")
    try:
        return arrays, meta["fields"], float(meta["cpu_s"]), float(meta["wall_s"])
    except (KeyError, TypeError, ValueError) as exc:
        raise Unreadable(f"its fields are incomplete ({exc})") from None


def _path(k: str) -> Path:
    return folder() / f"{k}.npz"


def _read(k: str) -> bytes | None:
    """The bytes of entry ``k``, or None when there is none (touched: used now)."""
    p = _path(k)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise Unreadable(f"cannot be read ({exc.strerror or exc})") from None
    with contextlib.suppress(OSError):
        os.utime(p)  # used now: removed last
    return data


def _write(k: str, data: bytes) -> None:
    """Keep ``data`` as entry ``k`` (a temporary file renamed), then keep the folder within
    :data:`MAX_BYTES`; nothing when the folder cannot be written."""
    p = _path(k)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        os.replace(tmp, p)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()
        return
    prune()


def prune(limit: int | None = None) -> None:
    """Remove the least recently used entries until the rest take at most ``limit`` bytes
    (default :data:`MAX_BYTES`)."""
    limit = MAX_BYTES if limit is None else limit
    with contextlib.suppress(OSError):
        entries = []
        for p in folder().glob("*.npz"):
            with contextlib.suppress(OSError):
                st = p.stat()
                entries.append((st.st_mtime, st.st_size, p))
        total = sum(e[1] for e in entries)
        for _, size, p in sorted(entries, key=lambda e: e[0]):
            if total <= limit:
                break
            with contextlib.suppress(OSError):
                p.unlink()
            total -= size


def kept(what: str, scenario, t, tolerances: dict, compute, to_entry, from_entry):
    """(the reference, {"key", "source": "cache" | "computed", "cpu_s", "wall_s"}): read
    from the cache under :func:`key` when an earlier run kept it, else ``compute()``d (its
    thread CPU and wall time measured), kept, and decoded from the bytes written.
    ``to_entry(ref)`` -> (arrays, fields); ``from_entry(arrays, fields)`` -> the reference,
    raising (KeyError, TypeError, ValueError) for fields that are not its own. A refusal
    raised by ``compute`` is not kept. With the cache switched off: computed, not kept."""
    k = key(what, scenario.scenario_hash, t, tolerances)
    if enabled():
        try:
            data = _read(k)
            if data is not None:
                arrays, fields, cpu, wall = decode(k, data)
                try:
                    ref = from_entry(arrays, fields)
                except (KeyError, TypeError, ValueError) as exc:
                    raise Unreadable(f"its fields do not make a reference ({exc})") from None
                _NOTES["read"].append(k)
                return ref, {"key": k, "source": "cache", "cpu_s": cpu, "wall_s": wall}
        except Unreadable as why:
            _NOTES["lines"].append(
                f"reference cache: {_path(k)}: {why}; the reference of {scenario.name} "
                f"({what}) is computed again and the entry written anew"
            )
    c0, w0 = time.thread_time(), time.perf_counter()
    ref = compute()
    cpu, wall = time.thread_time() - c0, time.perf_counter() - w0
    arrays, fields = to_entry(ref)
    data = encode(k, arrays, fields, cpu, wall)
    if enabled():
        _write(k, data)
        _NOTES["computed"].append(k)
    arrays, fields, cpu, wall = decode(k, data)  # the same object as a later run reads
    return from_entry(arrays, fields), {"key": k, "source": "computed", "cpu_s": cpu,
                                        "wall_s": wall}  # fmt: skip
