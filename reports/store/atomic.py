"""Writing a file so that a reader never sees half of it: the content goes to a temporary file
in the same folder (so the rename stays on one file system), which is then renamed over the
target in one step (``os.replace``, atomic on POSIX and on Windows). A failed write leaves the
old file as it was and removes the temporary one.

Every file of a results folder written after the store itself (the exports, summary.json, the
report, junit.xml, the gate's outputs, the figure cache's index, provenance.json, trajectories)
is written through :func:`replacing` or :func:`write_text`.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path


def temporary_for(path: Path) -> Path:
    """The temporary file :func:`replacing` writes ``path`` through: hidden, beside it, named
    after it and this process (two processes writing one folder never share it)."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextlib.contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write ``path``'s new content into; when the block ends without
    an exception, rename it over ``path``; otherwise remove it and leave ``path`` untouched."""
    path = Path(path)
    tmp = temporary_for(path)
    try:
        yield tmp
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (see the module docstring); returns ``path``."""
    path = Path(path)
    with replacing(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return path
