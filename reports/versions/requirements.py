"""Engine requirements of a version matrix: ``ENGINE==V1,V2,...`` or ``ENGINE@WHEEL``.

Grammar (one requirement per command-line argument)::

    mujoco==3.3.0,3.6.0,4.0.0          released versions, each installed from the package index
    mujoco@/path/to/mujoco-4.1.0.dev0-cp311-cp311-linux_x86_64.whl   a wheel file
    mujoco@https://example.org/wheels/mujoco-4.1.0-cp311-...whl      a wheel by URL (http, https,
                                                                      file)

Every version is an exact PEP 440 version (no ``>=``, no ``*``): a matrix compares releases, and
a range would let the index choose. A wheel is the engine developer's own build: the wheel
their build produced (``python -m build``, ``pip wheel .``), given by path or URL; only binary
wheels are installed, never a source tree that would have to be built. Every problem is a
InputError naming the requirement, the part at fault and the rule.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

from scenarios.schema import InputError


def engine_package(engine: str) -> str | None:
    """The package on the index that provides ``engine``: the first of its adapter's
    ``packages`` (its own distribution; the others are what it runs on), or None for an
    engine that is part of the suite (the director model, the exact references)."""
    from references.engines import get_engine

    packages = get_engine(engine).packages
    return packages[0] if packages else None


_ENGINE = re.compile(r"[A-Za-z][A-Za-z0-9_.-]*")
_WHEEL_NAME = re.compile(r"^(?P<dist>[^-]+)-(?P<version>[^-]+)(-\d[^-]*)?-[^-]+-[^-]+-[^-]+\.whl$")


@dataclass(frozen=True)
class Target:
    """One environment of the matrix: an engine at one version or one wheel.

    ``requirement`` is what ``uv pip install`` receives; ``label`` names the environment and,
    for a released version, is the version itself (for a wheel, the version in the wheel's
    file name followed by a digest of its content or URL, so that a rebuilt wheel gets an
    environment of its own)."""

    engine: str
    package: str
    requirement: str
    label: str
    source: str  # the requirement as the user wrote it
    wheel: bool = False

    @property
    def version(self) -> str:
        """The version the target asks for (for a wheel, the one in its file name)."""
        return self.label.split("+", 1)[0]


def parse_requirements(texts, known_engines=None) -> list[Target]:
    """Targets of requirements like ``mujoco==3.3.0,4.0.0`` or ``mujoco@./dist/x.whl``.

    ``known_engines``: the engine names registered in the suite (default: the registry's).
    InputError naming the requirement for: an empty list, an unknown engine, an engine that is
    part of the suite, a missing or malformed version, a range instead of a version, a version
    given twice, a path that is not a wheel file or does not exist, a URL that is not a
    wheel's."""
    from packaging.version import InvalidVersion, Version

    if known_engines is None:
        from references.engines import engine_names

        known_engines = engine_names()
    texts = list(texts or [])
    if not texts:
        raise InputError(
            "--engines: no requirement; give e.g. --engines mujoco==3.3.0,4.0.0 drake==1.40.0"
        )
    out: list[Target] = []
    for text in texts:
        text = str(text).strip()
        m = re.match(r"^\s*([^=@<>!~\s]+)\s*(==|@|[<>!~]=?|=)?\s*(.*)$", text)
        if not m or not m.group(1):
            raise InputError(f"requirement {text!r}: expected ENGINE==VERSION[,VERSION...]")
        engine, op, rest = m.group(1), m.group(2), m.group(3).strip()
        where = f"requirement {text!r}"
        if not _ENGINE.fullmatch(engine):
            raise InputError(f"{where}: {engine!r} is not an engine name")
        if engine not in known_engines:
            raise InputError(
                f"{where}: unknown engine {engine!r}; known engines: {', '.join(known_engines)}"
            )
        package = engine_package(engine)
        if package is None:
            versioned = [e for e in known_engines if engine_package(e) is not None]
            raise InputError(
                f"{where}: {engine!r} is part of director-bench and has no releases of its own; "
                f"engines with versions: {', '.join(versioned)}"
            )
        if op is None:
            raise InputError(
                f"{where}: no version; write {engine}==V1,V2 (released versions) or "
                f"{engine}@PATH_OR_URL (a wheel)"
            )
        if op == "@":
            out.append(_wheel_target(engine, package, rest, where))
            continue
        if op == "=":
            raise InputError(
                f"{where}: '=' is not an operator; write {engine}=={rest or 'VERSION'}"
            )
        if op != "==":
            raise InputError(
                f"{where}: {op!r} is a range; a version matrix needs exact versions: "
                f"{engine}==V1,V2,..."
            )
        parts = [p.strip() for p in rest.split(",")]
        if not rest or any(not p for p in parts):
            raise InputError(f"{where}: an empty version in {rest!r}; e.g. {engine}==3.3.0,4.0.0")
        seen = set()
        for p in parts:
            try:
                v = Version(p)
            except InvalidVersion:
                raise InputError(
                    f"{where}: {p!r} is not a version (PEP 440, e.g. 3.3.0 or 4.0.0rc1)"
                ) from None
            if v in seen:
                raise InputError(f"{where}: version {p} is given twice")
            seen.add(v)
            out.append(Target(engine, package, f"{package}=={p}", str(p), text))
    labels = [(t.engine, t.label) for t in out]
    dup = {x for x in labels if labels.count(x) > 1}
    if dup:
        e, lab = sorted(dup)[0]
        raise InputError(f"--engines: {e} {lab} is asked for by two requirements")
    return out


def _wheel_target(engine: str, package: str, loc: str, where: str) -> Target:
    if not loc:
        raise InputError(f"{where}: nothing after '@'; give the path or URL of a wheel")
    url = urlparse(loc)
    if url.scheme in ("http", "https", "file"):
        name = Path(url.path).name
        digest = hashlib.sha256(loc.encode()).hexdigest()[:8]
        req_loc = loc
    elif url.scheme and len(url.scheme) > 1:
        raise InputError(
            f"{where}: URL scheme {url.scheme!r} not supported; give an http(s) or file URL "
            "of a wheel, or a path"
        )
    else:
        path = Path(loc).expanduser().resolve()
        if not path.exists():
            raise InputError(f"{where}: {path} does not exist")
        if path.is_dir():
            raise InputError(
                f"{where}: {path} is a folder; give the wheel your build produced "
                "(e.g. `python -m build --wheel` writes dist/*.whl): only binary wheels are "
                "installed"
            )
        name = path.name
        digest = _file_digest(path)
        req_loc = path.as_uri()
    m = _WHEEL_NAME.match(name)
    if not m:
        raise InputError(
            f"{where}: {name!r} is not a wheel file name (NAME-VERSION-PY-ABI-PLATFORM.whl): "
            "only binary wheels are installed"
        )
    dist = m.group("dist").lower().replace("_", "-").replace(".", "-")
    if dist != package:
        raise InputError(
            f"{where}: the wheel is of {m.group('dist')!r}, engine {engine!r} comes from "
            f"{package!r}"
        )
    version = m.group("version").split("+", 1)[0]
    return Target(engine, package, f"{package} @ {req_loc}", f"{version}+w{digest}", loc, True)


def _file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:8]
