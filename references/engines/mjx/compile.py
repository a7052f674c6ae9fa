"""MJX compiled functions: MJX and JAX imported once, JAX's persistent cache, and the
stepping and own-quantities functions compiled ahead of time.

Compilation. The stepping is one jitted function per configuration and joint, compiled ahead
of time (``jax.jit(...).lower(...).compile()``) when the state is first set, after the model's
read-back and outside the stopwatch, and cached for the process: it takes the model and the
state (as leaf lists) and up to :data:`CHECKPOINTS` step counts, and returns the state after
each (a ``lax.while_loop`` over the checkpoints of a ``lax.fori_loop`` of ``mjx.step``). The
compile time is recorded (``settings``: "compile time s"). JAX's persistent compilation cache
serves later processes (:func:`_persistent_cache`): in ``JAX_COMPILATION_CACHE_DIR`` when the
user sets it, else in the user's cache folder (``$XDG_CACHE_HOME/director-bench/jax``, by
default ``~/.cache/director-bench/jax``), every compilation kept; a later process then traces
the step again but skips XLA's compilation (measured on the default suite's four
configurations: 33 s of CPU the first time, 6 s with the cache). MJX has no
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
from references.engines.mujoco_engine import MujocoEngine
from references.engines.native import import_engine
from references.errors import EngineError, EngineUnavailable

#: the name of every MJX model (see the module docstring: names are part of the compile key)
MODEL_NAME = "director-bench"

#: most checkpoints per call of the compiled stepping function (a call loops over the
#: checkpoints it is given only; more take several calls)
CHECKPOINTS = 128


_WARP_NOTE = ("Failed to import warp", "Failed to import mujoco_warp")


_MODULES: tuple | None = None


def _persistent_cache(jax) -> None:
    """Keep every compilation in JAX's persistent cache: the folder the user chose
    (``JAX_COMPILATION_CACHE_DIR``, which JAX reads itself) or the user's cache folder; none
    when that folder cannot be created (the run then compiles, as without a cache)."""
    import os
    from pathlib import Path

    if not jax.config.jax_compilation_cache_dir:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        folder = Path(base) / "director-bench" / "jax"
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
    from references.engines import mujoco_engine

    mujoco_engine._import()
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


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    mujoco, jax, _ = _import()
    out = {"mujoco": mujoco.__version__, "jax": jax.__version__}
    for pkg in ("mujoco-mjx", "jaxlib"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = "unknown"
    return out


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


#: (kind, 64-bit mode, tree structures, shapes and dtypes) -> _Compiled
_COMPILED: dict[tuple, _Compiled] = {}


def _compiled(kind: str, fn, trees: tuple, extra: tuple, x64: bool):
    """``fn(*trees, *extra)`` compiled ahead of time (``jax.jit(...).lower(...).compile()``) in
    the given precision as a function of the trees' leaf lists and ``extra``, cached for the
    process. Returns (_Compiled, compile seconds, compiled now?)."""
    _, jax, _ = _import()
    flat = [jax.tree_util.tree_flatten(t) for t in trees]
    defs = tuple(d for _, d in flat)
    avals = tuple(
        (np.shape(a), str(np.asarray(a).dtype))
        for a in [*(x for lv, _ in flat for x in lv), *extra]
    )
    key = (kind, x64, defs, avals)
    hit = _COMPILED.get(key)
    if hit is not None:
        return hit, hit.seconds, False

    def on_leaves(*args):
        trees = args[: len(defs)]
        ts = [jax.tree_util.tree_unflatten(d, lv) for d, lv in zip(defs, trees, strict=True)]
        return fn(*ts, *args[len(defs) :])

    with x64_mode(x64):
        t0 = time.perf_counter()
        comp = jax.jit(on_leaves).lower(*(lv for lv, _ in flat), *extra).compile()
        seconds = time.perf_counter() - t0
    _COMPILED[key] = _Compiled(comp, defs, seconds)
    return _COMPILED[key], seconds, True


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
#: :func:`references.conventions.initial_state_errors`). Rounding each of the state's numbers
#: to float32 moves it by at most U32 relative, and MJX's float32 evaluation of its energy,
#: momentum and frames (forward kinematics, the mass matrix, the subtree sums) chains about a
#: dozen roundings each of at most U32 of a term no larger than the scale: 64 U32 (3.8e-6)
#: bounds that with margin (measured: at most 1.2 U32 on the conformance kit's bodies;
#: tests/test_engine_mjx.py asserts 8 U32 on three scenarios). Every mistake the check exists
#: for moves a quantity by more than 1e-3 of its scale (the kit's planted mistakes).
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
