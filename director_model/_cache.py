"""numba's on-disk cache, keyed on every source file a kernel module compiles from.

numba (0.59 .. 0.68 at least) keys the cache of an ``njit(cache=True)`` function on the file
that defines it: the index of the cached machine code stores a stamp of that file (its
content hash since 0.60, its mtime and size before) and is discarded when the stamp differs;
the index key adds the function's own bytecode and closure, the signature and the target. A
function it calls from another module is compiled into the cached code but is not part of
the key, so an edit to ``director_model/_primitives.py`` alone would leave every kernel that
inlines it running the old machine code from the cache, silently.

:func:`tie` closes that gap: called at the end of a kernel module, it extends the stamp of each
cached function of the module with a hash of the files it depends on (by default ``_primitives.py``;
the system and contact kernels also name the single-body kernels they import from). An edit to any
of them changes the stamp, so numba discards the index and recompiles. The stamp is an attribute of
numba's cache object, not a public API: if a numba release renames it, :func:`tie` turns the disk
cache of that function off (it compiles at every start; never stale) and warns once.
tests/director_model/test_director_cache.py edits a primitive in a copy of a kernel module and
checks that the next process computes with the edit.
"""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

#: the files every kernel module compiles from, besides its own
_PRIMITIVES = Path(__file__).with_name("_primitives.py")
_warned = False


def digest(paths) -> bytes:
    """SHA-256 of the contents of the files, in the order given."""
    h = hashlib.sha256()
    for p in paths:
        data = Path(p).read_bytes()
        h.update(len(data).to_bytes(8, "little"))
        h.update(data)
    return h.digest()


def tie(namespace: dict, *depends: str | Path) -> int:
    """Key the disk cache of every cached numba function in ``namespace`` (a module's
    ``globals()``) on the files ``depends`` as well (default: ``_primitives.py``; given
    explicitly, the list replaces the default). Returns the number of functions tied.

    Call it once, at the end of the module, before any of its functions is called (numba
    reads the stamp when it first loads or saves the cache). Without numba's JIT
    (``NUMBA_DISABLE_JIT=1``) there is nothing to tie."""
    files = [Path(p) for p in depends] if depends else [_PRIMITIVES]
    stamp = digest(files)
    tied = 0
    for name, obj in list(namespace.items()):
        cache = getattr(obj, "_cache", None)
        if cache is None or type(cache).__name__ == "NullCache":
            continue  # not a dispatcher, or a dispatcher without a disk cache
        cache_file = getattr(cache, "_cache_file", None)
        if cache_file is None or not hasattr(cache_file, "_source_stamp"):
            _disable(obj, name, namespace.get("__name__", "?"))
            continue
        cache_file._source_stamp = (cache_file._source_stamp, stamp)
        tied += 1
    return tied


def _disable(dispatcher, name: str, module: str) -> None:
    """Turn a dispatcher's disk cache off (numba's internals changed: never risk staleness)."""
    from numba.core.caching import NullCache

    global _warned
    dispatcher._cache = NullCache()
    if not _warned:
        _warned = True
        warnings.warn(
            f"director_model: this numba release ({_numba_version()}) keeps its cache stamp "
            f"elsewhere; the disk cache of {module}.{name} and of any other kernel that "
            "cannot be tied to its dependencies is off (compiled at every start)",
            RuntimeWarning,
            stacklevel=3,
        )


def _numba_version() -> str:
    import numba

    return numba.__version__
