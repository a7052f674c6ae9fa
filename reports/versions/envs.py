"""One isolated Python environment per engine version, made with ``uv`` and kept in a cache.

An environment holds the engine at one version, binary wheels only, and the suite's runtime
dependencies pinned to the versions of the environment running the matrix (so that a
difference between two engine versions is the engine's, not numpy's); if the engine cannot
live with those pins, the dependencies are resolved afresh and the environment's record says
so. The suite itself is not installed: a ``.pth`` file points at the checkout that made the
environment, and every command run in it puts the checkout it was started from first on
``PYTHONPATH`` (:func:`checkout_env`), so that a cached environment made from another clone
runs this one's code.

Environments live in ``$DIRECTOR_BENCH_CACHE/envs`` (default ``~/.cache/director-bench/envs``),
one folder per engine, version and Python (``mujoco-3.3.0-py311``). A folder is made under a
temporary name and renamed once complete, so an interrupted creation leaves nothing that
could be taken for an environment; a complete one is reused. Failures (no such version, no
wheel for this platform, no network to the index) are returned, never raised: they become
``unavailable`` rows of the matrix with the reason.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from reports import cache_root
from reports.versions.requirements import Target

#: the record each complete environment holds
MARKER = "director-bench-env.json"
#: longest a single ``uv`` call may take (Drake's wheels are ~200 MB)
UV_TIMEOUT_S = 1800
CHECKOUT = Path(__file__).resolve().parents[2]


def python_tag() -> str:
    return f"py{sys.version_info.major}{sys.version_info.minor}"


def env_path(target: Target, root: Path | None = None) -> Path:
    name = re.sub(r"[^A-Za-z0-9.+_-]+", "-", f"{target.engine}-{target.label}-{python_tag()}")
    return (root or cache_root()) / "envs" / name


@dataclass
class Env:
    """The outcome of making (or finding) one target's environment."""

    target: Target
    path: Path
    ok: bool
    reused: bool = False
    seconds: float = 0.0
    reason: str = ""  # why the environment could not be made (for the unavailable rows)
    installed: dict = field(default_factory=dict)  # package -> version, as installed
    engine_version: str = ""  # what the engine reports in the environment

    @property
    def python(self) -> Path:
        return self.path / "bin" / "python"


def find_uv() -> str:
    """The ``uv`` executable (beside this Python first), or a clear error saying how to get it."""
    here = Path(sys.executable).parent / "uv"
    if here.exists():
        return str(here)
    found = shutil.which("uv")
    if found:
        return found
    raise FileNotFoundError(
        "uv is not installed; install it with `pip install uv` (or "
        "`pip install -e '.[versions]'`): director-bench versions makes its environments with it"
    )


def runtime_pins() -> list[str]:
    """The suite's runtime dependencies pinned to the versions installed here."""
    from importlib import metadata

    from packaging.requirements import Requirement

    pins = []
    for text in metadata.requires("director-bench") or []:
        req = Requirement(text)
        if req.marker is not None and "extra" in str(req.marker):
            continue
        try:
            pins.append(f"{req.name}=={metadata.version(req.name)}")
        except metadata.PackageNotFoundError:
            pins.append(str(req))
    return pins


def classify_failure(stderr: str) -> str:
    """A one-line reason for a failed ``uv pip install``, uv's own words after it."""
    text = stderr.strip()
    low = text.lower()
    tail = " ".join(line.strip() for line in text.splitlines()[-6:] if line.strip())[-600:]
    if any(
        s in low
        for s in (
            "failed to fetch",
            "error sending request",
            "connection refused",
            "dns error",
            "tcp connect error",
            "operation timed out",
            "network is unreachable",
            "could not connect",
        )
    ):
        kind = "the package index could not be reached"
    elif "no usable wheels" in low or "matching platform tag" in low or "no wheels" in low:
        kind = "no binary wheel for this platform and Python"
    elif "no version of" in low or "not found in the package registry" in low:
        kind = "no such version on the package index"
    else:
        kind = "uv could not install it"
    return f"{kind} (uv: {tail})"


def _uv(args: list[str], timeout: float = UV_TIMEOUT_S) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.setdefault("UV_NO_PROGRESS", "1")
    try:
        return subprocess.run(
            args, capture_output=True, text=True, timeout=timeout, env=env, check=False
        )
    except subprocess.TimeoutExpired:
        return subprocess.CompletedProcess(args, 124, "", f"timed out after {timeout:g} s")


def checkout_env() -> dict:
    """The process environment every command in an engine environment runs with: this
    checkout first on ``PYTHONPATH``. The ``.pth`` file of a cached environment names the
    checkout that made it, which may be another one (a second clone or worktree sharing the
    cache) with other code; ``PYTHONPATH`` comes before it on ``sys.path``, so the suite
    imported is always the one the command was started from."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(CHECKOUT), env.get("PYTHONPATH")) if p)
    return env


def _site_packages(env: Path) -> Path:
    v = sys.version_info
    return env / "lib" / f"python{v.major}.{v.minor}" / "site-packages"


_PROBE = """
import json, sys
from importlib import metadata
from references.engines import get_engine
cls = get_engine(sys.argv[1])
why = cls.availability()
pk = {d.metadata["Name"].lower(): d.version for d in metadata.distributions()}
print(json.dumps({"why": why, "version": None if why else cls.version(), "installed": pk}))
"""


def make_env(target: Target, root: Path | None = None, uv: str | None = None) -> Env:
    """The environment of ``target``: reused if complete, else made (see the module docstring).
    Never raises for a failure of the install: the returned Env says why (``ok`` False)."""
    path = env_path(target, root)
    t0 = time.perf_counter()
    marker = path / MARKER
    if marker.exists():
        try:
            rec = json.loads(marker.read_text())
            if rec.get("requirement") == target.requirement:
                return Env(target, path, True, True, 0.0, "", rec["installed"], rec["version"])
        except (OSError, ValueError, KeyError):
            pass
        shutil.rmtree(path, ignore_errors=True)  # incomplete or foreign: made again
    uv = uv or find_uv()
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.parent.mkdir(parents=True, exist_ok=True)

    def fail(reason: str) -> Env:
        shutil.rmtree(tmp, ignore_errors=True)
        return Env(target, path, False, False, time.perf_counter() - t0, reason)

    r = _uv([uv, "venv", "--quiet", "--relocatable", "--python", sys.executable, str(tmp)])
    if r.returncode:
        return fail(f"uv venv failed: {r.stderr.strip()[-400:]}")
    py = str(tmp / "bin" / "python")
    base = [uv, "pip", "install", "--quiet", "--python", py, "--only-binary", ":all:"]
    pinned = True
    r = _uv([*base, target.requirement, *runtime_pins()])
    if r.returncode and "unsatisfiable" in r.stderr.lower() and _resolves_alone(base, target):
        # the engine needs other versions of the suite's dependencies than those pinned
        pinned = False
        r = _uv([*base, target.requirement, *_unpinned()])
    if r.returncode:
        return fail(classify_failure(r.stderr))
    (_site_packages(tmp) / "director_bench_checkout.pth").write_text(f"{CHECKOUT}\n")
    probe = subprocess.run(
        [py, "-c", _PROBE, target.engine],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        cwd=tmp,
        env=checkout_env(),
    )
    if probe.returncode:
        return fail(f"the suite does not start in the environment: {probe.stderr[-600:]}")
    info = json.loads(probe.stdout.strip().splitlines()[-1])
    if info["why"]:
        return fail(f"{target.engine} installed but does not load: {info['why']}")
    seconds = time.perf_counter() - t0
    rec = {
        "requirement": target.requirement,
        "source": target.source,
        "label": target.label,
        "version": info["version"],
        "installed": info["installed"],
        "dependencies_pinned": pinned,
        "python": sys.version.split()[0],
        "seconds": round(seconds, 2),
        "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    (tmp / MARKER).write_text(json.dumps(rec, indent=1, sort_keys=True) + "\n")
    try:
        tmp.rename(path)
    except OSError:  # another process finished the same environment first
        shutil.rmtree(tmp, ignore_errors=True)
        if not (path / MARKER).exists():
            return fail(f"could not move the environment into {path}")
    return Env(target, path, True, False, seconds, "", info["installed"], info["version"])


def _resolves_alone(base: list[str], target: Target) -> bool:
    r = _uv([*base, "--dry-run", target.requirement])
    return r.returncode == 0


def _unpinned() -> list[str]:
    from importlib import metadata

    from packaging.requirements import Requirement

    reqs = [Requirement(t) for t in metadata.requires("director-bench") or []]
    return [str(r) for r in reqs if r.marker is None or "extra" not in str(r.marker)]


def make_envs(
    targets: list[Target], parallel: int = 2, root: Path | None = None, log=print
) -> list[Env]:
    """Every target's environment, ``parallel`` at a time, one progress line each as it ends
    (in the order of ``targets`` in the result)."""
    uv = find_uv()
    out: dict[int, Env] = {}
    n = len(targets)
    with ThreadPoolExecutor(max_workers=max(1, parallel)) as pool:
        futs = {pool.submit(make_env, t, root, uv): i for i, t in enumerate(targets)}
        for k, fut in enumerate(as_completed(futs), 1):
            e = fut.result()
            out[futs[fut]] = e
            t = e.target
            if e.ok:
                how = "reused" if e.reused else f"created in {e.seconds:.1f} s"
                log(f"[{k}/{n}] env {t.engine} {t.label}: {how} ({e.path})")
            else:
                log(f"[{k}/{n}] env {t.engine} {t.label}: UNAVAILABLE: {e.reason}")
    return [out[i] for i in range(n)]
