"""MJX compiled functions: MJX and JAX imported once, JAX's persistent cache, and the
stepping and own-quantities functions compiled ahead of time.

Compilation. The stepping is one jitted function per configuration and joint, compiled ahead
of time (``jax.jit(...).lower(...).compile()``) when the state is first set, after the model's
read-back and outside the stopwatch, and cached for the process: it takes the model and the
state (as leaf lists) and up to :data:`CHECKPOINTS` step counts, and returns the state after
each (a ``lax.while_loop`` over the checkpoints of a ``lax.fori_loop`` of ``mjx.step``). The
compile time is recorded (``settings``: "compile time s"). Later processes are served from
disk, in ``JAX_COMPILATION_CACHE_DIR`` when the user sets it, else in the user's cache folder
(``$XDG_CACHE_HOME/director-bench/jax``, by default ``~/.cache/director-bench/jax``): JAX's
persistent compilation cache keeps every compilation (:func:`_persistent_cache`), which skips
XLA's compilation but not the tracing of MJX's step before it; so the traced computation is
kept too, exported with ``jax.export`` in the folder's ``director-bench-exported`` and keyed by
everything that determines it (:func:`_lowered`, :func:`_export_key`), and a later process
compiles it from there without tracing MJX. Measured on the MJX part of the default suite
(serial, both caches warm): 28 s of CPU when every function is traced, 20 s with the exported
computations. MJX has no
warning counters, no velocity clamp and no automatic reset: a state that blows up stays
non-finite and the run loop reports the divergence.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import time

import numpy as np

from references import conventions as cv
from references.engines.context import BodyModel, RunContext
from references.engines.mujoco.adapter import MujocoEngine
from references.engines.native import import_engine
from references.errors import EngineError, EngineUnavailable

#: the name of every MJX model (see the module docstring: names are part of the compile key)
MODEL_NAME = "director-bench"

#: most checkpoints per call of the compiled stepping function (a call loops over the
#: checkpoints it is given only; more take several calls)
CHECKPOINTS = 128


_WARP_NOTE = ("Failed to import warp", "Failed to import mujoco_warp")


_MODULES: tuple | None = None


def cache_folder():
    """The folder of JAX's persistent cache that MJX's runs use (:func:`_persistent_cache`),
    found without importing JAX: ``JAX_COMPILATION_CACHE_DIR`` when the user sets it, else
    ``$XDG_CACHE_HOME/director-bench/jax`` (by default ``~/.cache/director-bench/jax``)."""
    import os
    from pathlib import Path

    if os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return Path(os.environ["JAX_COMPILATION_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "director-bench" / "jax"


def _persistent_cache(jax) -> None:
    """Keep every compilation in JAX's persistent cache: the folder the user chose
    (``JAX_COMPILATION_CACHE_DIR``, which JAX reads itself) or the user's cache folder; none
    when that folder cannot be created (the run then compiles, as without a cache)."""
    if not jax.config.jax_compilation_cache_dir:
        folder = cache_folder()
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            return
        jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def _import():
    """(mujoco, jax, mjx), imported once. MJX prints a line on standard output when its
    optional Warp (GPU) backend is not installed; that line is swallowed here (the JAX backend
    is used), anything else MJX prints is passed on."""
    global _MODULES
    if _MODULES is not None:
        return _MODULES
    mujoco = import_engine("mujoco", "MuJoCo", "mujoco")
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            mjx = import_engine("mujoco.mjx", "MJX", "mujoco-mjx")
    except EngineUnavailable:
        raise
    except Exception as exc:  # noqa: BLE001 - a package that fails while importing
        raise EngineUnavailable(
            f"MJX does not import ({type(exc).__name__}: {exc}); install it with "
            "`pip install mujoco-mjx` (or `pip install 'director-bench[engines]'`)"
        ) from exc
    finally:
        rest = [ln for ln in buf.getvalue().splitlines() if not ln.startswith(_WARP_NOTE)]
        if rest:
            print("\n".join(rest))
    import jax

    _persistent_cache(jax)
    # the C adapter's warning handler (MuJoCo's warnings to its log file)
    from references.engines.mujoco import adapter

    adapter._import()
    _MODULES = (mujoco, jax, mjx)
    return _MODULES


#: the 64-bit mode of the process's last JAX work for MJX (None before any)
_LAST_X64: list[bool | None] = [None]


def x64_mode(x64: bool):
    """``jax.enable_x64(x64)`` for every JAX call of MJX's adapter and system builder, after
    dropping JAX's in-memory caches (``jax.clear_caches``) when the process last worked in the
    other mode. JAX's staging caches are not all keyed by the 64-bit mode: an inner ``jit``
    traced with a numpy float64 constant keeps that constant's float64 type (jax 0.10.2,
    measured: ``jnp.tril`` of MJX's RK4 tableau, traced in float64 then in float32, is lowered
    with a float64 operand for a float32 function and refused, "Cannot lower jaxpr ...
    tensor<3x3xf32> ... tensor<3x3xf64>"). Functions compiled ahead of time (:data:`_COMPILED`)
    and JAX's persistent cache are kept. A run works in one mode from its model's upload to its
    last call, so the caches are dropped at most once per run, before its stopwatch starts."""
    _, jax, _ = _import()
    if _LAST_X64[0] is not None and _LAST_X64[0] != x64:
        jax.clear_caches()
    _LAST_X64[0] = x64
    return jax.enable_x64(x64)


_VERSIONS: dict[str, str] = {}


def _versions() -> dict[str, str]:
    """The versions of MuJoCo, JAX, MJX and jaxlib (a new dict each call), read once per
    process: the installed packages' metadata costs ~2 ms a look-up (measured), and the adapter
    asks for every run and every key of an exported computation. Imports MJX (raising
    :class:`EngineUnavailable` when it does not import) on every call."""
    mujoco, jax, _ = _import()
    if not _VERSIONS:
        from references.engines.interface import installed

        out = {"mujoco": mujoco.__version__, "jax": jax.__version__}
        out.update({pkg: installed(pkg) or "unknown" for pkg in ("mujoco-mjx", "jaxlib")})
        _VERSIONS.update(out)
    return dict(_VERSIONS)


# -- compiled functions -----------------------------------------------------------------------


class _Compiled:
    """A function of pytrees (and further array arguments), compiled ahead of time as a
    function of the trees' leaf lists. MJX flattens an mjx.Model or Data by hashing its static
    numpy fields on every call (~0.5 ms, measured); a compiled call on leaf lists skips that.
    ``leaves(i, tree)`` flattens the i-th tree argument once and checks that it has the
    structure compiled for (a changed static field, e.g. a flag, would otherwise be ignored)."""

    def __init__(self, comp, defs, seconds: float):
        self.comp, self.defs, self.seconds = comp, defs, seconds

    def leaves(self, i: int, tree) -> list:
        _, jax, _ = _import()
        leaves, tdef = jax.tree_util.tree_flatten(tree)
        if tdef != self.defs[i]:
            raise EngineError(
                "mjx: the model or data changed its static structure after compilation (a "
                "setting that MJX bakes into the compiled code); rebuild the run"
            )
        return leaves

    def __call__(self, *args):
        return self.comp(*args)


def _dtype(a) -> str:
    """The name of an array's dtype, read from the array (``np.asarray`` of a JAX array would
    copy it from the device first)."""
    dt = getattr(a, "dtype", None)
    return str(dt if dt is not None else np.asarray(a).dtype)


#: (kind, 64-bit mode, tree structures, shapes and dtypes) -> _Compiled
_COMPILED: dict[tuple, _Compiled] = {}


def _compiled(kind: str, fn, trees: tuple, extra: tuple, x64: bool):
    """``fn(*trees, *extra)`` compiled ahead of time (``jax.jit(...).lower(...).compile()``) in
    the given precision as a function of the trees' leaf lists and ``extra``, cached for the
    process. Returns (_Compiled, compile seconds, compiled now?)."""
    _, jax, _ = _import()
    flat = [jax.tree_util.tree_flatten(t) for t in trees]
    defs = tuple(d for _, d in flat)
    avals = tuple((np.shape(a), _dtype(a)) for a in [*(x for lv, _ in flat for x in lv), *extra])
    key = (kind, x64, defs, avals)
    hit = _COMPILED.get(key)
    if hit is not None:
        return hit, hit.seconds, False

    def on_leaves(*args):
        trees = args[: len(defs)]
        ts = [jax.tree_util.tree_unflatten(d, lv) for d, lv in zip(defs, trees, strict=True)]
        return fn(*ts, *args[len(defs) :])

    args = (*(lv for lv, _ in flat), *extra)
    with x64_mode(x64):
        t0 = time.perf_counter()
        comp = _lowered(kind, on_leaves, defs, avals, args, x64).compile()
        seconds = time.perf_counter() - t0
    _COMPILED[key] = _Compiled(comp, defs, seconds)
    return _COMPILED[key], seconds, True


# -- the traced computations kept on disk -----------------------------------------------------

#: the format of a file of :func:`_exported_store`; part of every key
_EXPORT_FORMAT = b"director-bench mjx exported 1\n"

#: the sources whose text is part of every key: ours that define the compiled functions
_OWN_SOURCES = ("mjx/compile.py", "mjx/adapter.py", "mjx/batch.py", "mjx/system.py")

_SOURCES_DIGEST: list[bytes] = []


def _exported_store():
    """The folder of the traced computations (:func:`_lowered`): ``director-bench-exported``
    inside JAX's persistent cache folder, None when JAX has none or the folder cannot be made."""
    from pathlib import Path

    _, jax, _ = _import()
    base = jax.config.jax_compilation_cache_dir
    if not base:
        return None
    folder = Path(base) / "director-bench-exported"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return folder


def _sources_digest() -> bytes:
    """SHA-256 of the text of our sources that define the compiled functions
    (:data:`_OWN_SOURCES`) and of every Python file of the installed MJX package, once per
    process."""
    import hashlib
    from pathlib import Path

    if not _SOURCES_DIGEST:
        _, _, mjx = _import()
        h = hashlib.sha256()
        engines = Path(__file__).resolve().parent.parent
        roots = [(engines, [engines / f for f in _OWN_SOURCES])]
        mroot = Path(mjx.__file__).resolve().parent
        roots.append((mroot, sorted(mroot.rglob("*.py"))))
        for root, files in roots:
            for f in files:
                h.update(str(f.relative_to(root)).encode() + b"\0")
                h.update(f.read_bytes() + b"\0")
        _SOURCES_DIGEST.append(h.digest())
    return _SOURCES_DIGEST[0]


def _export_key(kind: str, defs: tuple, avals: tuple, x64: bool) -> bytes | None:
    """SHA-256 of everything that determines the computation traced for ``kind``: the file
    format, the versions of Python, JAX, jaxlib, MuJoCo and MJX, the device, the 64-bit mode,
    :data:`CHECKPOINTS`, the text of our sources and MJX's (:func:`_sources_digest`), the
    trees' structures with every static field (their pickle: MJX keeps the model's static
    numpy arrays in the structure) and the shapes and dtypes of the arguments. The caller's
    ``kind`` names whatever else selects the function (integrator, joint, vmapped or not).
    None when a structure cannot be pickled (then nothing is kept)."""
    import hashlib
    import pickle
    import sys

    _, jax, _ = _import()
    try:
        structure = pickle.dumps(defs, protocol=5)
    except Exception:  # noqa: BLE001 - a static field pickle refuses: not kept on disk
        return None
    dev = jax.devices()[0]
    h = hashlib.sha256(_EXPORT_FORMAT)
    for part in (
        kind,
        repr(sorted(_versions().items())),
        sys.version,
        f"{dev.platform} {dev.device_kind}",
        f"x64={x64} checkpoints={CHECKPOINTS}",
        repr(avals),
    ):
        h.update(part.encode() + b"\0")
    h.update(_sources_digest())
    h.update(structure)
    return h.digest()


def _load_exported(path, key: bytes):
    """The ``jax.export.Exported`` kept in ``path`` for ``key``; None when there is none, or
    the file is not whole, not of this format or of another key (it is then rewritten)."""
    import hashlib
    import pickle

    from jax import export

    try:
        data = path.read_bytes()
    except OSError:
        return None
    n = len(_EXPORT_FORMAT)
    if data[:n] != _EXPORT_FORMAT or data[n : n + 32] != key:
        return None
    digest, payload = data[n + 32 : n + 64], data[n + 64 :]
    if hashlib.sha256(payload).digest() != digest:
        return None
    try:
        exp = pickle.loads(payload)
    except Exception:  # noqa: BLE001 - an unreadable file is ignored and rewritten
        return None
    return exp if isinstance(exp, export.Exported) else None


def _save_exported(path, key: bytes, exp) -> None:
    """Write ``exp`` for ``key`` atomically (a temporary file in the folder, then renamed);
    nothing is written when it cannot be pickled or the folder refuses the file."""
    import dataclasses
    import hashlib
    import os
    import pickle
    import tempfile

    try:
        payload = pickle.dumps(dataclasses.replace(exp, _get_vjp=None), protocol=5)
    except Exception:  # noqa: BLE001 - not kept on disk; the run compiles as without a store
        return
    data = _EXPORT_FORMAT + key + hashlib.sha256(payload).digest() + payload
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError:
        return


def _lowered(kind: str, on_leaves, defs: tuple, avals: tuple, args: tuple, x64: bool):
    """``jax.jit(on_leaves)`` lowered for ``args``, by way of the computation kept on disk.

    Tracing MJX's step costs seconds of CPU per function, and JAX's persistent cache only
    skips XLA's compilation that follows it. The traced computation is therefore exported
    (``jax.export``: StableHLO with its argument and result types) and kept in
    :func:`_exported_store` under :func:`_export_key`; a later process loads it and lowers a
    call of it, which compiles to the same executable (a hit in JAX's persistent cache) without
    tracing MJX. The process that traces lowers the loaded form too, so both compile the same
    module. Without a store, or when MJX's computation cannot be exported or a structure
    pickled, ``on_leaves`` is lowered directly."""
    _, jax, _ = _import()
    from jax import export

    store = _exported_store()
    key = _export_key(kind, defs, avals, x64) if store is not None else None
    if key is None:
        return jax.jit(on_leaves).lower(*args)
    path = store / f"{key.hex()}.exported"
    exp = _load_exported(path, key)
    if exp is None:
        try:
            exp = export.export(jax.jit(on_leaves), platforms=[jax.default_backend()])(*args)
        except Exception:  # noqa: BLE001 - not exportable (e.g. a custom call): lower directly
            return jax.jit(on_leaves).lower(*args)
        _save_exported(path, key, exp)
    return jax.jit(exp.call).lower(*args)


def _block_fn():
    """(model, data, ks, n) -> (the data's leaves after sum(ks[:n]) steps, qpos and qvel
    (CHECKPOINTS, nq | nv) after each of the first n counts ks[i]; the rest zero). A
    ``lax.while_loop`` over the n checkpoints of ``lax.fori_loop`` of ``mjx.step``."""
    _, jax, mjx = _import()
    jnp = jax.numpy

    def block(m, d, ks, n):
        qp = jnp.zeros((CHECKPOINTS, d.qpos.shape[0]), d.qpos.dtype)
        qv = jnp.zeros((CHECKPOINTS, d.qvel.shape[0]), d.qvel.dtype)

        def checkpoint(c):
            i, d, qp, qv = c
            d = jax.lax.fori_loop(0, ks[i], lambda _, d: mjx.step(m, d), d)
            return i + 1, d, qp.at[i].set(d.qpos), qv.at[i].set(d.qvel)

        _, d, qp, qv = jax.lax.while_loop(lambda c: c[0] < n, checkpoint, (0, d, qp, qv))
        return jax.tree_util.tree_leaves(d), qp, qv

    return block


def _native_fn(pivoted: bool):
    """MJX's own energy, momentum and frames of a state (after ``mjx.forward``):
    T = 1/2 qvel . M qvel (``mjx.mul_m``), V = -m g . xipos, L and v_G from
    ``mjx.subtree_vel`` (L about the subtree COM, plus x_G x m v_G when pivoted), R = ximat,
    x_G = xipos; all in MJX's arithmetic and precision."""
    _, jax, mjx = _import()
    jnp = jax.numpy

    def native(m, d):
        d = mjx.forward(m, d)
        mv = mjx.mul_m(m, d, d.qvel)
        mass = m.body_mass[1]
        energy = 0.5 * jnp.dot(d.qvel, mv) - mass * jnp.dot(d.xipos[1], m.opt.gravity)
        d = mjx.subtree_vel(m, d)
        # mjx.subtree_vel leaves its results in the JAX backend's part of Data
        L = d._impl.subtree_angmom[1]
        v = d._impl.subtree_linvel[1]
        if pivoted:
            L = L + mass * jnp.cross(d.subtree_com[1], v)
        return {
            "energy": energy,
            "angular momentum": L,
            "rotation": d.ximat[1],
            "COM velocity": v,
            "COM position": d.xipos[1],
        }

    return native


def _for_native(mjx, mx):
    """The model with its integrator set to Euler: forward dynamics do not depend on it, and
    the integrator is static in mjx.Model, so this shares one compilation among them."""
    return mx.replace(opt=mx.opt.replace(integrator=mjx.IntegratorType.EULER))


def _as_float(tree) -> dict:
    return {k: np.asarray(v, dtype=float) for k, v in tree.items()}


# -- shared by the adapter and the batch ------------------------------------------------------

#: unit round-off of float32
U32 = 2.0**-24

#: Tolerance of the check of a float32 run's rounded initial state (relative, on the scales of
#: :func:`references.conventions.initial_state_errors`). Rounding each of the state's numbers to
#: float32 moves it by at most U32 relative, and MJX's float32 evaluation of its energy, momentum
#: and frames (forward kinematics, the mass matrix, the subtree sums) chains about a dozen roundings
#: each of at most U32 of a term no larger than the scale: 64 U32 (3.8e-6) bounds that with margin
#: (measured: at most 1.2 U32 on the conformance kit's bodies;
#: tests/references/engines/test_engine_mjx.py asserts 8 U32 on three scenarios). Every mistake the
#: check exists for moves a quantity by more than 1e-3 of its scale (the kit's planted mistakes).
FLOAT32_INITIAL_RTOL = 64 * U32


def _c_ctx(ctx: RunContext, h) -> RunContext:
    """A RunContext for the C adapter's methods on the compiled MjModel/MjData."""
    return dataclasses.replace(
        ctx, handle=(h.mujoco, h.m, h.d), integrator=MujocoEngine.integrator(h.mj_name)
    )


def _states(model: BodyModel, qpos: np.ndarray, qvel: np.ndarray) -> cv.BodyState:
    """The block of suite states of MuJoCo qpos (n, nq), qvel (n, nv)
    (:func:`references.conventions.mujoco_block`)."""
    qpos = np.asarray(qpos, dtype=float)
    raw = np.concatenate([qpos, np.asarray(qvel, dtype=float)], axis=1)
    return cv.mujoco_block(raw, qpos.shape[1], model.com, model.pivoted)
