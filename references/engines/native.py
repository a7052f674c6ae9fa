"""What an adapter needs of an engine's native side: importing its Python package
(:func:`import_engine`, a clear message when it is missing) and keeping what its native code
writes to the standard error while it steps (:class:`NativeStderr`)."""

from __future__ import annotations

import os
import re
import sys
import tempfile
import threading

from references.errors import EngineUnavailable


class NativeStderr:
    """What an engine's native code writes to the standard error (file descriptor 2) while
    it steps, kept for the run's record instead of the terminal.

    A diverging state makes some engines print a warning at every step (DART 6.20: three
    lines a step once a state is non-finite, until the run loop's next checkpoint stops the
    run); a default suite would flood the terminal with thousands of lines. While a block of
    steps runs, file descriptor 2 points to a temporary file; afterwards the lines are counted
    and the first and last kept (:meth:`summary`, recorded in the run's settings). Only on the
    main thread: redirecting a process-wide descriptor from several threads at once (a Dask
    worker's task threads) could leave it pointing at a closed file, so there the writes go
    where they always went (the worker's log)."""

    def __init__(self) -> None:
        self.lines = 0
        self.first = ""
        self.last = ""
        self._file = None
        self._saved: int | None = None

    def __enter__(self) -> NativeStderr:
        if threading.current_thread() is not threading.main_thread():
            return self
        if self._file is None:
            self._file = tempfile.TemporaryFile()
        sys.stderr.flush()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is None:
            return
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._saved = None
        f = self._file
        if f.tell() or os.fstat(f.fileno()).st_size:
            f.seek(0)
            text = f.read().decode("utf-8", "replace")
            f.seek(0)
            f.truncate()
            lines = [_plain(x) for x in text.splitlines() if x.strip()]
            if lines:
                self.first = self.first or lines[0]
                self.last = lines[-1]
                self.lines += len(lines)

    def summary(self) -> str | None:
        """The record of what was written, or None if nothing was."""
        if not self.lines:
            return None
        out = f"{self.lines} line(s) while stepping; first: {self.first}"
        return out + (f"; last: {self.last}" if self.lines > 1 else "")

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def _plain(line: str) -> str:
    """A terminal line without its ANSI colour codes."""
    return re.sub(r"\x1b\[[0-9;]*m", "", line).strip()


def import_engine(module: str, label: str, pip_name: str):
    """Import an engine's Python package, or raise :class:`EngineUnavailable` saying how to
    install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except Exception as exc:  # noqa: BLE001 - a broken install raises more than ImportError
        raise EngineUnavailable(
            f"{label} is not installed or does not import ({type(exc).__name__}: {exc}); "
            "install it with "
            f"`pip install {pip_name}` (or `pip install 'director-bench[engines]'`)"
        ) from exc
