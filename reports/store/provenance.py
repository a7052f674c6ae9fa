"""Provenance of a results folder: suite version, git commit, date, machine, engine versions.

Written once per ``run`` to ``provenance.json`` beside the results store, and shown at the top
of every report, so that two result folders can be told apart and compared."""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import subprocess
from pathlib import Path

from reports.store.atomic import write_text


def git_commit() -> str:
    """The suite's git commit (with '+dirty' if the tree has changes), or 'unknown'."""
    here = Path(__file__).resolve().parent
    try:
        commit = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(here), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        return commit + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }


def engine_versions(names=None) -> dict:
    """Each engine's version as the runner plans its runs (``planned_version``: the installed
    package's metadata where it says it, without importing the engine), or why it is not
    available; in the registry's order (the built-in engines, then the plug-ins), which the
    report lists the engines in (reports.report.labels.engine_order)."""
    from references.engines import EngineUnavailable, engine_names, get_engine

    registry = engine_names()
    names = registry if not names else sorted(names, key=lambda n: _place(registry, n))
    out = {}
    for name in names:
        try:
            out[name] = get_engine(name).planned_version()
        except EngineUnavailable as exc:
            out[name] = f"not available ({exc})"
    return out


def _place(order: list, name: str) -> tuple:
    return (order.index(name), "") if name in order else (len(order), name)


def provenance(engines=None, left_out=None) -> dict:
    """The provenance of a run of ``engines``; ``left_out``: {engine: why} of the engines
    the default suite left out on this machine (kept only when there are some)."""
    from reports import __version__

    doc = {
        "suite_version": __version__,
        "git_commit": git_commit(),
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "machine": machine(),
        "engines": engine_versions(engines),
    }
    if left_out:
        doc["left_out"] = dict(left_out)
    return doc


def write_provenance(out: Path, engines=None, left_out=None) -> Path:
    """Write ``provenance.json`` into ``out`` (atomically: a temporary file renamed)."""
    return write_text(
        Path(out) / "provenance.json",
        json.dumps(provenance(engines, left_out), indent=2) + "\n",
    )


def read_provenance(root: Path) -> dict:
    """The provenance of a results folder ({} if it has none; a note if it is unreadable)."""
    path = Path(root) / "provenance.json"
    if not path.exists():
        return {}
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        return {"note": f"{path} is unreadable ({exc})"}
    return doc if isinstance(doc, dict) else {"note": f"{path} is not a JSON object"}
