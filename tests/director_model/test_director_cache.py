"""numba's disk cache and the primitives shared by the kernels (director_model/_cache.py).

numba keys a cached function on its own file; the kernels inline the primitives of
director_model/_primitives.py, so an edit there must still recompile them. These tests plant
such an edit: a cached kernel calling a primitive of another module, compiled and cached in
one process, the primitive edited, the kernel called again in a new process."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from director_model import _cache

#: the files the system kernel (director_model/system/_kernels.py) compiles in
_SYSTEM = (
    "_primitives.py",
    "system/_block3.py",
    "system/_band5.py",
    "system/_common.py",
    "system/_rows.py",
    "system/_solvers.py",
    "system/_bodies.py",
    "system/_sigma.py",
)
#: each kernel module and the files (in director_model/) its cache is tied to besides its own:
#: the primitives, and the kernel modules whose code it compiles in (the system kernel's
#: block-solver rows; the batch of systems: the system kernel)
KERNEL_MODULES = {
    "director_model._kernels": ("_primitives.py",),
    "director_model.system._kernels": _SYSTEM,
    "director_model.system.batch": ("system/_kernels.py", *_SYSTEM),
}


def _run(tmp_path: Path, tie: bool) -> tuple[float, float]:
    """The kernel's value before and after the primitive is edited (x + 1 -> x + 2), each
    in a fresh interpreter sharing one cache directory."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    prim = pkg / "prim.py"
    prim.write_text(
        "from numba import njit\n\n\n@njit(inline='always')\ndef f(x):\n    return x + 1.0\n"
    )
    (pkg / "kern.py").write_text(
        textwrap.dedent(
            f"""
            from pathlib import Path
            from numba import njit
            from director_model import _cache
            from pkg.prim import f

            @njit(cache=True)
            def g(x):
                return f(x)

            if {tie}:
                _cache.tie(globals(), Path(__file__).with_name("prim.py"))
            """
        )
    )
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    env.pop("NUMBA_DISABLE_JIT", None)
    code = "from pkg.kern import g; print(g(1.0), sum(g.stats.cache_hits.values()))"

    def once() -> tuple[float, int]:
        out = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
        ).stdout.split()
        return float(out[0]), int(out[1])

    first, hits = once()
    assert hits == 0
    again, hits = once()
    assert (again, hits) == (first, 1), "the second start did not load the cached kernel"
    prim.write_text(prim.read_text().replace("x + 1.0", "x + 2.0"))
    return first, once()[0]


def test_an_edited_primitive_recompiles_a_tied_kernel(tmp_path):
    assert _run(tmp_path, tie=True) == (2.0, 3.0)


def test_without_the_tie_numba_runs_the_stale_code(tmp_path):
    """The premise of _cache.tie on the installed numba: an untied kernel keeps the old
    primitive (if this fails, numba tracks the files of called functions itself)."""
    assert _run(tmp_path, tie=False) == (2.0, 2.0)


@pytest.mark.parametrize("module", KERNEL_MODULES)
def test_every_cached_kernel_is_tied_to_the_primitives(module):
    import importlib

    mod = importlib.import_module(module)
    root = Path(_cache.__file__).parent
    want = _cache.digest([root / rel for rel in KERNEL_MODULES[module]])
    cached = tied = 0
    for obj in vars(mod).values():
        if not hasattr(obj, "py_func"):
            continue  # not a numba dispatcher (e.g. an imported kernel module)
        cache = getattr(obj, "_cache", None)
        if cache is None or type(cache).__name__ == "NullCache":
            continue
        cached += 1
        stamp = cache._cache_file._source_stamp
        tied += isinstance(stamp, tuple) and stamp[-1] == want
    assert cached > 0 and tied == cached
