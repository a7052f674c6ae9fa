"""MJX adapter: MuJoCo's JAX implementation (``mujoco-mjx``), free joint or ball joint.

Model: the MJCF of the C MuJoCo adapter (:meth:`MujocoEngine.model_xml`), compiled by MuJoCo
and put on the JAX device with ``mjx.put_model(impl="jax")``, so the layout is MuJoCo's
(docs/engines.md, section 2) and the conversions are :mod:`references.conventions`' MuJoCo
ones. The only change to the MJCF is its model name, always :data:`MODEL_NAME`: MJX keeps the
names in the static part of ``mjx.Model``, which is part of JAX's compilation key, so a
scenario's name would otherwise force a new compilation per scenario. The model's numbers
(mass, inertia, centre of mass, gravity, step) are array leaves and do not: one compilation
serves every scenario with the same joint, integrator and precision.

Precision. JAX computes in float32 unless 64-bit mode is on (JAX documentation, "The Sharp
Bits: double (64-bit) precision"). Every integrator is offered twice, as named configurations
"... (float64)" and "... (float32)"; every JAX call of a run (putting the model and data on
the device, compiling, stepping, the engine's own quantities) runs inside
``jax.enable_x64(True)`` or ``jax.enable_x64(False)``, a thread-local setting that overrides
the process's ``jax_enable_x64`` for that call only. JAX compiles a function separately for
each setting, so the two precisions coexist in one process whatever the user's global
setting. The read-back checks the width of the model's and the state's floats (8 or 4 bytes):
a float32 run labelled float64 cannot pass.

The initial state of a float32 run. The suite checks the state an engine holds before its
first step against the scenario to 1e-12 (:func:`references.engines.stepping.check_initial`),
which a float32 state cannot meet (its rounding alone is ~6e-8 relative). The float32
configurations therefore hand the scenario's state over in float64: before the first step the
state read back, and the engine's own quantities (C MuJoCo's, as in the C adapter, on the
``MjData`` from which MJX takes the state), are those of the float64 state handed over, which
checks the conversions to 1e-12 like every adapter. ``mjx.put_data`` in float32 mode then
rounds it; that rounded state, which MJX steps from, is checked at once through MJX's own
float32 quantities against the state handed over, to :data:`FLOAT32_INITIAL_RTOL`, and the
errors are recorded in the settings. From the first step on, everything read is MJX's float32
state.

Integrators (MJX's JAX backend, ``mujoco.mjx._src.forward.step``; MuJoCo documentation, "MJX:
Feature Parity"):

- ``Euler``: MuJoCo's semi-implicit Euler; reproduces C MuJoCo's ``Euler`` (float64: to
  round-off, tests/test_engine_mjx.py).
- ``RK4``: the classical four stages in the velocities, but the positions are advanced once,
  by the exponential map of the stage-weighted mean velocity, without the dexp correction: order
  2 in the attitude (*measured*). That is C MuJoCo 3.17.0's RK4 (*measured*: equal to 1e-15
  after 160 steps), not 4.0.0's, whose RK4 is order 4 in the attitude; the family
  :data:`RK4_MEAN_EXP` says so.
- ``implicitfast``: MJX's implicit-in-velocity step without the derivative of the bias
  (Coriolis, centripetal, gyroscopic) forces; with no damping and no actuators it is the Euler
  step (*measured*: bit-identical to MJX ``Euler`` on free and ball joints), unlike C MuJoCo's
  ``implicitfast``, which keeps the gyroscopic derivative of a free body.
- ``implicit`` and ``discrete``: not implemented by MJX's JAX backend; declared so that the
  results show the gap. The adapter asks MJX (``put_model`` and a trace of ``step``) and
  reports MJX's own ``NotImplementedError`` as the reason of an ``unsupported`` row.

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
from references.engines.context import BodyModel, ModelReadback, RunContext, RunOutput
from references.engines.integrators import Family, Integrator, register_family
from references.engines.interface import Engine
from references.engines.mujoco_engine import MujocoEngine
from references.engines.native import import_engine
from references.engines.stepping import CHUNK, DIVERGENCE_ENERGY, check_readback
from references.errors import Diverged, EngineError, EngineUnavailable, Unsupported
from scenarios.schema import step_plan

#: the name of every MJX model (see the module docstring: names are part of the compile key)
MODEL_NAME = "director-bench"

#: most checkpoints per call of the compiled stepping function (a call loops over the
#: checkpoints it is given only; more take several calls)
CHECKPOINTS = 128

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

#: MJX's RK4 (see the module docstring); registered like Drake's families
RK4_MEAN_EXP = register_family(
    Family(
        "RK4 stages with an uncorrected exponential update",
        "the classical four Runge-Kutta stages in the velocities, the positions advanced once "
        "by the exponential map of the stage-weighted mean velocity without the dexp "
        "correction: order 4 in the velocities of a torque-free body, order 2 in the attitude "
        "(MJX's RK4 and C MuJoCo 3.17.0's)",
    )
)

_PRECISIONS = ("float64", "float32")

_MJ_ENUM = {
    "Euler": "mjINT_EULER",
    "RK4": "mjINT_RK4",
    "implicitfast": "mjINT_IMPLICITFAST",
    "implicit": "mjINT_IMPLICIT",
    "discrete": "mjINT_DISCRETE",
}

#: the integrators MJX's JAX backend does not implement (asked at run time, see _probe)
_UNIMPLEMENTED = ("implicit", "discrete")


def _configurations() -> tuple[Integrator, ...]:
    """Every configuration. Compiling costs 6 to 13 s per joint type (14 to 29 s per
    configuration on the default scenarios, free and pivoted bodies), so the default suite
    keeps two: Euler in float64 (it reproduces C MuJoCo's Euler) and RK4 in float32 (what
    MJX's users run: it shows float32's limit and MJX's order-2 RK4); the others run with
    ``director-bench run --full`` or ``--integrators``."""
    out = []
    for prec in _PRECISIONS:
        arith = (
            "float64 (JAX 64-bit mode on for every call of the run)"
            if prec == "float64"
            else "float32, JAX's default and what MJX users run; the initial state is handed "
            "over in float64 and rounded by mjx.put_data (module docstring)"
        )
        out += [
            Integrator(
                f"Euler ({prec})",
                "semi-implicit Euler",
                1,
                "MJX's Euler: v += h a(q, v) with the gyroscopic (bias) force explicit, then "
                f"q advanced with the new v on the group; MuJoCo's algorithm. Arithmetic: {arith}.",
                options={"mjtIntegrator": "mjINT_EULER", "precision": prec},
                default=prec == "float64",
            ),
            Integrator(
                f"RK4 ({prec})",
                RK4_MEAN_EXP.name,
                2,
                "MJX's RK4: classical 4 stages in the velocities; positions advanced once by "
                "exp(h * weighted mean of the stage velocities), no dexp correction, so order 2 "
                "in the attitude (C MuJoCo 3.17.0's RK4, not 4.0.0's, which is order 4). "
                f"Arithmetic: {arith}.",
                evals_per_step=4.0,
                options={"mjtIntegrator": "mjINT_RK4", "precision": prec},
                default=prec == "float32",
            ),
            Integrator(
                f"implicitfast ({prec})",
                "semi-implicit Euler",
                1,
                "MJX's implicitfast: implicit in velocity without the derivative of the bias "
                "forces (MJX does not implement it), so with no damping it is the Euler step "
                "(measured bit-identical to MJX Euler); unlike C MuJoCo's implicitfast, it "
                f"keeps no gyroscopic derivative for a free body. Arithmetic: {arith}.",
                options={"mjtIntegrator": "mjINT_IMPLICITFAST", "precision": prec},
                default=False,
            ),
        ]
    for name in _UNIMPLEMENTED:
        out.append(
            Integrator(
                name,
                "implicit gyroscopic",
                1,
                f"C MuJoCo's {name} integrator; MJX's JAX backend does not implement it, so its "
                "runs are unsupported rows carrying MJX's NotImplementedError (declared so "
                "that the gap shows in the results).",
                options={"mjtIntegrator": _MJ_ENUM[name]},
                default=False,
            )
        )
    return tuple(out)


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

    with jax.enable_x64(x64):
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


# -- the handle -------------------------------------------------------------------------------


class _Handle:
    """A run's MuJoCo and MJX objects. The state MJX holds is ``dx`` (an mjx.Data), kept
    between compiled calls as its leaf list and rebuilt only when read."""

    def __init__(self, mujoco, jax, mjx, m, d, mx, dx, x64: bool, mj_name: str):
        self.mujoco, self.jax, self.mjx = mujoco, jax, mjx
        self.m, self.d = m, d  # the compiled MjModel and the MjData of the state handed over
        self.mx = mx  # the mjx.Model in the run's precision (planted mistakes replace it)
        self.x64, self.mj_name = x64, mj_name
        self._dx, self._d_leaves = dx, None
        self._m_leaves = (None, None)
        #: seconds it took to compile each function this run uses (in this run or an earlier
        #: one of the process: compilations are cached)
        self.compile_s: dict[str, float] = {}
        #: the functions compiled for this run (the others were in the process's cache)
        self.compiled_now: list[str] = []
        self.block: _Compiled | None = None
        self.native: _Compiled | None = None
        #: float32: the state read is still the float64 one handed over (no step taken yet)
        self.handed = False
        #: float32: errors of the rounded initial state, by quantity
        self.rounding: dict[str, float] = {}

    def x64_mode(self):
        return self.jax.enable_x64(self.x64)

    @property
    def dx(self):
        if self._dx is None:
            self._dx = self.jax.tree_util.tree_unflatten(self.block.defs[1], self._d_leaves)
        return self._dx

    @dx.setter
    def dx(self, value) -> None:
        self._dx, self._d_leaves = value, None

    def step_args(self) -> tuple[list, list]:
        """The model's and the state's leaf lists for the compiled stepping."""
        if self._m_leaves[0] is not self.mx:
            self._m_leaves = (self.mx, self.block.leaves(0, self.mx))
        if self._d_leaves is None:
            self._d_leaves = self.block.leaves(1, self._dx)
        return self._m_leaves[1], self._d_leaves

    def stepped(self, d_leaves: list) -> None:
        self._dx, self._d_leaves = None, d_leaves


def _c_ctx(ctx: RunContext, h: _Handle) -> RunContext:
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


class MjxEngine(Engine):
    """MJX (mujoco-mjx, JAX backend), stepped with a compiled ``mjx.step`` loop."""

    name = "mjx"
    description = (
        "MJX, MuJoCo in JAX: free joint or ball joint, MJX's integrators in float64 and float32"
    )
    integrators = _configurations()
    bundle_runs = True  # compiled functions are cached per process: compile once per worker
    warm_up = "MJX's step (JAX)"
    batched = True  # run_batch: the members in one vmapped, compiled call

    #: defaults that distort the experiment, planted back on the mjx.Model by the kit
    plantable = {
        "joint damping left on": (
            lambda ctx: _plant(ctx, lambda mx: mx.replace(dof_damping=mx.dof_damping + 0.01)),
            ("free", "pivoted"),
        ),
        "contacts left on": (
            lambda ctx: _plant(
                ctx,
                lambda mx: mx.replace(
                    opt=mx.opt.replace(
                        disableflags=mx.opt.disableflags & ~ctx.handle.mjx.DisableBit.CONTACT
                    )
                ),
            ),
            ("free", "pivoted"),
        ),
    }

    def run_batch(self, members, integrator, dt, t_end, save_every) -> list:
        """The members in one vmapped, compiled call (:func:`run_batch`)."""
        return run_batch(members, integrator, dt, t_end, save_every)

    @classmethod
    def version(cls) -> str:
        v = _versions()
        return f"{v['mujoco-mjx']} (mujoco {v['mujoco']}, jax {v['jax']}, jaxlib {v['jaxlib']})"

    def check_supported(self, scenario, integrator) -> None:
        MujocoEngine().check_supported(scenario, MujocoEngine.integrator(_mj_name(integrator)))
        if integrator.name in _UNIMPLEMENTED:
            raise Unsupported(_probe(integrator.name, scenario.pivot is not None))

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        """The model on the device; the functions are compiled when the state is first set
        (after the read-back, so a model the read-back refuses is never compiled)."""
        self._put_model(ctx)

    def _compile(self, ctx) -> None:
        """The compiled stepping and own-quantities functions (outside the stopwatch; from
        the process's cache when compiled before)."""
        h = ctx.handle
        if h.block is not None:
            return
        ks = np.zeros(CHECKPOINTS, np.int32)
        h.block, h.compile_s["step"], now = _compiled(
            f"step-{h.mj_name}", _block_fn(), (h.mx, h.dx), (ks, np.int32(0)), h.x64
        )
        h.compiled_now += ["step"] if now else []
        h.native, h.compile_s["own quantities"], now = _compiled(
            f"native-{ctx.model.joint}",
            _native_fn(ctx.model.pivoted),
            (_for_native(h.mjx, h.mx), h.dx),
            (),
            h.x64,
        )
        h.compiled_now += ["own quantities"] if now else []

    def _put_model(self, ctx) -> None:
        """Compile the MJCF with MuJoCo and put model and data on the device (ctx.handle)."""
        mujoco, jax, mjx = _import()
        mj_name = _mj_name(ctx.integrator)
        x64 = ctx.integrator.options["precision"] == "float64"
        named = dataclasses.replace(ctx.model, name=MODEL_NAME)
        try:
            m = mujoco.MjModel.from_xml_string(MujocoEngine.model_xml(named, mj_name))
        except ValueError as exc:
            if "inertia must satisfy" in str(exc):
                raise Unsupported(f"MuJoCo rejects the scenario's inertia: {exc}") from exc
            raise EngineError(f"MuJoCo could not compile the scenario's model: {exc}") from exc
        d = mujoco.MjData(m)
        with jax.enable_x64(x64):
            try:
                mx = mjx.put_model(m, impl="jax")
            except NotImplementedError as exc:
                raise Unsupported(f"MJX cannot take the model: NotImplementedError: {exc}") from exc
            dx = mjx.put_data(m, d, impl="jax")
        ctx.handle = _Handle(mujoco, jax, mjx, m, d, mx, dx, x64, mj_name)

    def read_model(self, ctx) -> ModelReadback:
        """C MuJoCo's read-back of the compiled MjModel (the C adapter's, with all its extra
        checks), then the mjx.Model against it: every number MJX holds must be the MjModel's
        in the run's precision exactly, in floats of the run's width. For float64 the main
        quantities are read from the mjx.Model itself."""
        h = ctx.handle
        mjx, mx, m = h.mjx, h.mx, h.m
        rb = MujocoEngine.read_model(MujocoEngine(), _c_ctx(ctx, h))
        width = 8 if h.x64 else 4
        dtype = np.float64 if h.x64 else np.float32
        extra = dict(rb.extra)
        pairs = {
            "body_mass": (mx.body_mass, m.body_mass),
            "body_inertia": (mx.body_inertia, m.body_inertia),
            "body_ipos": (mx.body_ipos, m.body_ipos),
            "body_iquat": (mx.body_iquat, m.body_iquat),
            "body_pos": (mx.body_pos, m.body_pos),
            "body_quat": (mx.body_quat, m.body_quat),
            "opt.gravity": (mx.opt.gravity, m.opt.gravity),
            "opt.timestep": (mx.opt.timestep, m.opt.timestep),
            "dof_damping": (mx.dof_damping, m.dof_damping),
            "dof_armature": (mx.dof_armature, m.dof_armature),
            "dof_frictionloss": (mx.dof_frictionloss, m.dof_frictionloss),
        }
        for name, (got, want) in pairs.items():
            extra[f"mjx.Model {name} = the MjModel's in {dtype.__name__}"] = (
                np.asarray(got, dtype=float),
                np.asarray(want).astype(dtype).astype(float),
            )
            extra[f"mjx.Model {name}: bytes per float"] = (np.asarray(got).dtype.itemsize, width)
        for name in ("qpos", "qvel", "qacc", "time"):
            extra[f"mjx.Data {name}: bytes per float"] = (
                np.asarray(getattr(h.dx, name)).dtype.itemsize,
                width,
            )
        enum = getattr(h.mujoco.mjtIntegrator, _MJ_ENUM[h.mj_name])
        extra["mjx.Model integrator"] = (int(mx.opt.integrator), int(enum))
        contact = mjx.DisableBit.CONTACT
        extra["mjx.Model contacts disabled"] = (bool(mx.opt.disableflags & contact), True)
        extra["mjx.Model backend is JAX"] = (mx.impl == mjx.Impl.JAX, True)
        if h.x64:
            return ModelReadback(
                mass=float(np.asarray(mx.body_mass)[1]),
                inertia=np.diag(np.asarray(mx.body_inertia)[1]),
                com=np.asarray(mx.body_ipos)[1],
                joint=rb.joint,
                gravity=np.asarray(mx.opt.gravity),
                dt=float(np.asarray(mx.opt.timestep)),
                extra=extra,
            )
        return dataclasses.replace(rb, extra=extra)

    def settings(self, ctx) -> dict:
        h = ctx.handle
        out = MujocoEngine.settings(MujocoEngine(), _c_ctx(ctx, h)) if h is not None else {}
        if h is None:
            return out
        v = _versions()
        prec = ctx.integrator.options["precision"]
        out.update(
            {
                "model name": f"{MODEL_NAME!r} (one compilation for every scenario)",
                "MJX backend": "JAX (mjx.put_model impl='jax'; the Warp backend is not used)",
                "precision": prec,
                "JAX 64-bit mode": f"jax.enable_x64({h.x64}) around every JAX call of the run",
                "versions": v,
                "device": str(h.jax.devices()[0].platform),
                "checkpoints per compiled call": CHECKPOINTS,
                "compile time s": float(sum(h.compile_s.values())),
                "compile time s, by function": dict(h.compile_s),
                "compiled for this run": list(h.compiled_now) or "none (cached in the process)",
                "JAX persistent compilation cache": h.jax.config.jax_compilation_cache_dir
                or "off (JAX_COMPILATION_CACHE_DIR unset)",
            }
        )
        if not h.x64:
            out["initial state"] = (
                "handed over in float64 (checked to 1e-12 with C MuJoCo's quantities), rounded "
                "to float32 by mjx.put_data; the rounded state checked through MJX's float32 "
                f"quantities to {FLOAT32_INITIAL_RTOL:.3g}"
            )
            out["initial state rounding errors"] = dict(h.rounding)
        return out

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        """Write ``state`` into the MjData (float64) and put it on the device in the run's
        precision with ``mjx.put_data`` (which rounds it for float32; that rounding is checked
        here, see the module docstring)."""
        self._compile(ctx)
        h = ctx.handle
        if ctx.model.pivoted:
            qpos, qvel = cv.mujoco_ball_from_state(state.rotation, state.omega_body)
        else:
            qpos, qvel = cv.mujoco_free_from_state(*state)
        h.d.qpos[:] = qpos
        h.d.qvel[:] = qvel
        h.mujoco.mj_forward(h.m, h.d)
        with h.x64_mode():
            h.dx = h.mjx.put_data(h.m, h.d, impl="jax")
        h.handed = not h.x64
        if not h.x64:
            self._check_rounding(ctx, state)

    def _check_rounding(self, ctx, state) -> None:
        h = ctx.handle
        given = ctx.scenario.replace(
            position=state.position,
            velocity=state.velocity,
            rotation=state.rotation,
            omega_body=state.omega_body,
        )
        rounded = self._mjx_state(ctx)
        errors = cv.initial_state_errors(given, rounded, self._mjx_native(ctx))
        h.rounding = {k: float(v) for k, v in errors.items()}
        for quantity, err in errors.items():
            if not err <= FLOAT32_INITIAL_RTOL:
                raise EngineError(
                    f"{self.name}: the float32 state MJX holds after mjx.put_data differs from "
                    f"the state handed over in its {quantity} by {err:.3g} relative (allowed "
                    f"{FLOAT32_INITIAL_RTOL:.3g}, 64 float32 round-offs); a conversion or the "
                    "model is wrong"
                )

    def _mjx_state(self, ctx) -> cv.BodyState:
        h = ctx.handle
        qpos = np.asarray(h.dx.qpos, dtype=float)
        qvel = np.asarray(h.dx.qvel, dtype=float)
        return cv.BodyState(*(a[0] for a in _states(ctx.model, qpos[None], qvel[None])))

    def _mjx_native(self, ctx) -> dict:
        h = ctx.handle
        mxn = _for_native(h.mjx, h.mx)
        args = (h.native.leaves(0, mxn), h.native.leaves(1, h.dx))
        with h.x64_mode():
            out = h.native(*args)
        return _as_float(out)

    def read_state(self, ctx) -> cv.BodyState:
        """MJX's state from qpos/qvel; for float32 before the first step, the float64 state
        handed over (module docstring)."""
        h = ctx.handle
        if h.handed:
            d = h.d
            if ctx.model.pivoted:
                return ctx.model.state_from_rotation(*cv.mujoco_ball_to_state(d.qpos, d.qvel))
            return cv.mujoco_free_to_state(d.qpos, d.qvel)
        qpos = np.asarray(h.dx.qpos, dtype=float)
        qvel = np.asarray(h.dx.qvel, dtype=float)
        if ctx.model.pivoted:
            return ctx.model.state_from_rotation(*cv.mujoco_ball_to_state(qpos, qvel))
        return cv.mujoco_free_to_state(qpos, qvel)

    def native_quantities(self, ctx) -> dict:
        """MJX's own energy, momentum and frames (:func:`_native_fn`), computed by MJX on the
        state it holds in the run's precision; for float32 before the first step, C MuJoCo's
        (the C adapter's) on the float64 state handed over."""
        h = ctx.handle
        if h.handed:
            return MujocoEngine.native_quantities(MujocoEngine(), _c_ctx(ctx, h))
        out = self._mjx_native(ctx)
        out["energy"] = float(out["energy"])
        return out

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        self.advance_saving(ctx, [k])

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """The checkpoints of a block in calls of the compiled stepping, CHECKPOINTS at a
        time; the engine's clock runs around each call until its results are ready."""
        h = ctx.handle
        qp, qv = [], []
        for i in range(0, len(steps), CHECKPOINTS):
            part = steps[i : i + CHECKPOINTS]
            ks = np.zeros(CHECKPOINTS, np.int32)
            ks[: len(part)] = part
            m_leaves, d_leaves = h.step_args()
            with ctx.clock, h.x64_mode():
                d_leaves, qpos, qvel = h.block(m_leaves, d_leaves, ks, np.int32(len(part)))
                h.jax.block_until_ready((d_leaves, qpos, qvel))
            h.stepped(d_leaves)
            qp.append(np.asarray(qpos)[: len(part)])
            qv.append(np.asarray(qvel)[: len(part)])
        h.handed = False
        return _states(ctx.model, np.concatenate(qp), np.concatenate(qv))


def _mj_name(integrator: Integrator) -> str:
    return integrator.name.split(" (")[0]


def _plant(ctx, change) -> None:
    """Apply a planted mistake to the mjx.Model, in the run's precision."""
    h = ctx.handle
    with h.x64_mode():
        h.mx = change(h.mx)


#: (integrator, pivoted) -> MJX's reason (asked once per process)
_PROBED: dict[tuple[str, bool], str] = {}


def _probe(mj_name: str, pivoted: bool) -> str:
    """Ask MJX whether it steps ``mj_name``: put a model with that integrator on the device
    and trace ``mjx.step`` (no compilation). Returns the reason it cannot."""
    key = (mj_name, pivoted)
    if key in _PROBED:
        return _PROBED[key]
    mujoco, jax, mjx = _import()
    bm = BodyModel(MODEL_NAME, 1.0, np.ones(3), np.zeros(3), "ball" if pivoted else "free",
                   np.zeros(3), 1e-3)  # fmt: skip
    m = mujoco.MjModel.from_xml_string(MujocoEngine.model_xml(bm, mj_name))
    v = _versions()["mujoco-mjx"]
    try:
        with jax.enable_x64(True):
            mx = mjx.put_model(m, impl="jax")
            dx = mjx.put_data(m, mujoco.MjData(m), impl="jax")
            jax.eval_shape(mjx.step, mx, dx)
    except NotImplementedError as exc:
        why = (
            f"MJX {v} (JAX backend) does not implement the {mj_name} integrator: "
            f"NotImplementedError: {exc}"
        )
    else:
        why = (
            f"MJX {v} now steps the {mj_name} integrator, but this adapter does not offer it "
            "yet; add its float64 and float32 configurations to references/engines/mjx_engine.py"
        )
    _PROBED[key] = why
    return why


# -- ensembles: many bodies in one vmapped call --------------------------------------------------


def run_batch(members, integrator: str, dt: float, t_end: float, save_every: int) -> list:
    """Run ``members`` (scenarios that differ only in their initial state) with one MJX
    configuration in one vmapped, compiled call per CHECKPOINTS checkpoints.

    Returns one entry per member: its :class:`RunOutput`, or a :class:`Diverged` carrying the
    output up to its last good checkpoint (checkpoints: the saves and every CHUNK steps, as
    in :meth:`Engine.run`; a member diverges on a non-finite state or an energy error beyond
    DIVERGENCE_ENERGY of its energy scale). Before stepping, the shared model is read back
    (:func:`check_readback`), and every member's initial state is checked twice: the
    conversions on the C ``MjData`` through C MuJoCo's quantities to 1e-12, and the batched
    state MJX holds through MJX's own quantities (vmapped), to 1e-12 in float64 and to
    :data:`FLOAT32_INITIAL_RTOL` in float32 (the state handed over in float64 is rounded by
    JAX as it is put on the device). The saved state at t = 0 is the state handed over. Wall
    and engine times are the batch's divided by the number of members. Raises
    :class:`EngineError` (``Unsupported`` included) for the whole batch.
    """
    eng = MjxEngine()
    integ = eng.integrator(integrator)
    base = members[0]
    _check_same_body(members)
    eng.check_supported(base, integ)
    nstep, saves = step_plan(dt, t_end, save_every)
    ctx = RunContext(base, BodyModel.of(base, dt), integ, float(dt))
    ctx.t_end = float(t_end)
    eng._put_model(ctx)
    check_readback(eng.name, eng.read_model(ctx), ctx.model)
    qpos0, qvel0, dxb = _batch_initial(eng, ctx, members)
    points = sorted(set(int(s) for s in saves if s > 0) | set(range(CHUNK, nstep, CHUNK)))
    qp, qv, wall, engine_s = _batch_step(ctx, dxb, qpos0, qvel0, points)
    settings = {**eng.settings(ctx), "integrator": integ.name, "timestep": float(dt)}
    n = len(members)
    settings["batch"] = f"{n} bodies in one vmapped call; times are the batch's / {n}"
    settings["initial state rounding errors"] = "checked per member, not recorded"
    points = np.array([0, *points])
    return [
        _batch_output(
            ctx, mem, qp[k], qv[k], points, saves, nstep, settings, wall / n, engine_s / n
        )
        for k, mem in enumerate(members)
    ]


def _check_same_body(members) -> None:
    base = members[0]
    for mem in members[1:]:
        for f in ("mass", "inertia", "gravity", "pivot"):
            a, b = getattr(mem, f), getattr(base, f)
            if (a is None) != (b is None) or (a is not None and not np.array_equal(a, b)):
                raise ValueError(f"run_batch: the members differ in {f}; only initial states may")


def _batch_initial(eng, ctx, members):
    """The members' initial states on the device as one batched ``mjx.Data``, each checked
    through C MuJoCo's quantities (the conversions) and MJX's own (the state MJX holds)."""
    h = ctx.handle
    jax, jnp = h.jax, h.jax.numpy
    n = len(members)
    cctx = _c_ctx(ctx, h)
    c_engine = MujocoEngine()
    qpos0, qvel0 = [], []
    for mem in members:
        c_engine.set_state(cctx, _initial(mem))
        cctx.scenario = mem
        cv.check_initial_state(
            eng.name, mem, c_engine.read_state(cctx), c_engine.native_quantities(cctx)
        )
        qpos0.append(h.d.qpos.copy())
        qvel0.append(h.d.qvel.copy())
    qpos0, qvel0 = np.stack(qpos0), np.stack(qvel0)

    with h.x64_mode():
        dxb = jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (n, *a.shape)), h.dx)
        dxb = dxb.replace(qpos=jnp.asarray(qpos0), qvel=jnp.asarray(qvel0))
    vnative = jax.vmap(_native_fn(ctx.model.pivoted), in_axes=(None, 0))
    mxn = _for_native(h.mjx, h.mx)
    comp_n, h.compile_s["batched own quantities"], now = _compiled(
        f"batch-native-{ctx.model.joint}", vnative, (mxn, dxb), (), h.x64
    )
    h.compiled_now += ["batched own quantities"] if now else []
    with h.x64_mode():
        nat = _as_float(comp_n(comp_n.leaves(0, mxn), comp_n.leaves(1, dxb)))
    held = _states(ctx.model, np.asarray(dxb.qpos, dtype=float), np.asarray(dxb.qvel, dtype=float))
    tol = 1e-12 if h.x64 else FLOAT32_INITIAL_RTOL
    for k, mem in enumerate(members):
        errors = cv.initial_state_errors(
            mem, cv.BodyState(*(a[k] for a in held)), {q: a[k] for q, a in nat.items()}
        )
        for quantity, err in errors.items():
            if not err <= tol:
                raise EngineError(
                    f"{eng.name}: member {k} ({mem.name}): before the first step, the "
                    f"{quantity} of the state MJX holds differs from the scenario's by "
                    f"{err:.3g} relative (allowed {tol:.3g}); a conversion or the model is wrong"
                )
    return qpos0, qvel0, dxb


def _batch_step(ctx, dxb, qpos0, qvel0, points):
    """Step the batch to every checkpoint in ``points`` (step counts), one compiled, vmapped
    call per CHECKPOINTS of them; the (qpos, qvel) of each member at 0 and every checkpoint,
    and the wall and engine seconds of the stepping."""
    h = ctx.handle
    jax = h.jax
    ks = np.zeros(CHECKPOINTS, np.int32)
    vblock = jax.vmap(_block_fn(), in_axes=(None, 0, None, None))
    comp, h.compile_s["batched step"], now = _compiled(
        f"batch-step-{h.mj_name}", vblock, (h.mx, dxb), (ks, np.int32(0)), h.x64
    )
    h.compiled_now += ["batched step"] if now else []
    steps = np.diff([0, *points]).astype(np.int32)
    qp, qv = [qpos0[:, None]], [qvel0[:, None]]
    m_leaves, d_leaves = comp.leaves(0, h.mx), comp.leaves(1, dxb)
    engine_s = 0.0
    t0 = time.perf_counter()
    for i in range(0, len(steps), CHECKPOINTS):
        part = steps[i : i + CHECKPOINTS]
        ks = np.zeros(CHECKPOINTS, np.int32)
        ks[: len(part)] = part
        c0 = time.perf_counter()
        with h.x64_mode():
            d_leaves, qpos, qvel = comp(m_leaves, d_leaves, ks, np.int32(len(part)))
            jax.block_until_ready((d_leaves, qpos, qvel))
        engine_s += time.perf_counter() - c0
        qp.append(np.asarray(qpos, dtype=float)[:, : len(part)])
        qv.append(np.asarray(qvel, dtype=float)[:, : len(part)])
    wall = time.perf_counter() - t0
    return np.concatenate(qp, axis=1), np.concatenate(qv, axis=1), wall, engine_s


def _batch_output(ctx, mem, qp, qv, points, saves, nstep, settings, wall, engine_s):
    """One member's RunOutput from its states at the checkpoints ``points``, or a Diverged
    carrying the output up to its last good checkpoint."""
    from references.trajectory import Trajectory, energy

    dt, integ = ctx.dt, ctx.integrator
    saved = np.isin(points, saves)
    x, v, R, W = _states(ctx.model, qp, qv)
    e0 = float(energy(mem, *(np.asarray(a)[None] for a in _initial(mem)))[0])
    with np.errstate(all="ignore"):
        drift = np.abs(energy(mem, x, v, R, W) - e0) / mem.energy_scale
    finite = np.isfinite(qp).all(1) & np.isfinite(qv).all(1)
    bad = ~finite | ~(drift <= DIVERGENCE_ENERGY)
    good = int(np.argmax(bad)) if bad.any() else len(points)
    keep = np.flatnonzero(saved & (np.arange(len(points)) < good))
    traj = Trajectory.from_states(mem, points[keep] * dt, x[keep], v[keep], R[keep], W[keep])
    done = int(points[good - 1]) if good < len(points) else nstep
    output = RunOutput(traj, done, wall, engine_s, float(integ.evals_per_step or 0.0), settings)
    if good == len(points):
        return output
    what = (
        "the state became non-finite"
        if not finite[good]
        else f"the energy error exceeded {DIVERGENCE_ENERGY:g} x the scenario's energy "
        f"scale {mem.energy_scale:.4g} J"
    )
    span = f"between t = {done * dt:.6g} and t = {points[good] * dt:.6g} s"
    msg = f"{integ.name} at dt = {dt:g} s: {what} {span}; the run diverged (reduce dt)"
    return Diverged(msg, float(points[good] * dt), output)


def _initial(scenario) -> cv.BodyState:
    from references.engines.stepping import initial_state

    return initial_state(scenario)
