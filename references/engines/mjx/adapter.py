"""The MJX engine (see :mod:`references.engines.mjx`): its configurations, the model on the
device, the read-back, the state handed over and read, and the compiled stepping."""

from __future__ import annotations

import dataclasses

import numpy as np

from references import conventions as cv
from references.engines.context import BodyModel, ModelReadback
from references.engines.integrators import Family, Integrator, register_family
from references.engines.interface import Engine, SceneBuilder
from references.engines.mjx.batch import run_batch
from references.engines.mjx.compile import (
    CHECKPOINTS,
    FLOAT32_INITIAL_RTOL,
    MODEL_NAME,
    _as_float,
    _block_fn,
    _c_ctx,
    _Compiled,
    _compiled,
    _for_native,
    _import,
    _native_fn,
    _states,
    _versions,
    cache_folder,
    x64_mode,
)
from references.engines.mujoco.adapter import MujocoEngine
from references.errors import EngineError, Unsupported

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


# -- the handle -------------------------------------------------------------------------------


#: the Python distributions through which JAX reaches an accelerator (its GPU and TPU plugins)
ACCELERATOR_PLUGINS = (
    "jax-cuda12-plugin",
    "jax-cuda13-plugin",
    "jax-rocm60-plugin",
    "jax-rocm7-plugin",
    "libtpu",
    "libtpu-nightly",
    "jax-metal",
)


def accelerator() -> str | None:
    """The accelerator platform JAX runs on here ("gpu", "tpu", ...), or None when it sees
    none. Without an accelerator plugin installed (:data:`ACCELERATOR_PLUGINS`, read from
    the packages' metadata) or with ``JAX_PLATFORMS`` naming only the CPU, None without
    importing JAX; else JAX is asked (its import and a device query, about a second)."""
    import os
    from importlib.metadata import PackageNotFoundError, version

    platforms = os.environ.get("JAX_PLATFORMS", "").strip().lower()
    if platforms and set(platforms.replace(" ", "").split(",")) <= {"cpu"}:
        return None
    plugins = []
    for name in ACCELERATOR_PLUGINS:
        try:
            version(name)
            plugins.append(name)
        except PackageNotFoundError:
            pass
    if not plugins:
        return None
    try:
        import jax

        backend = jax.default_backend()
    except Exception:  # noqa: BLE001 - a plugin that cannot start: no accelerator
        return None
    return None if backend == "cpu" else backend


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
        return x64_mode(self.x64)

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


#: CPU seconds of one compilation of MJX's step loop (``mjx.step`` in a ``lax.fori_loop``,
#: float64) for a system of bodies or a robot model where JAX's persistent cache does not hold
#: it yet, rounded up from the library's robot models: the CPU time of a command that compiles
#: less the same command with the cache filled, per compilation (mujoco-mjx 3.17.0, jax
#: 0.10.2, AMD EPYC; /work/wt/reports/robots4.md): contact-free (the system builder, an
#: importer's faithful configuration) 5.2 to 16 s on 3 to 13 bodies, not growing with them;
#: with the file's contacts (an importer's as-loaded configuration of a file with collision
#: geometry, whose collision functions MJX compiles too) about 30 s (pusher as loaded: 114 s
#: of wall at a quarter of a core). A compilation the cache
#: holds loads in about a second. Not counted: the steps themselves, which are cheap on most
#: models (arm3: 0.14 ms each) but not all (pusher through its importer: 0.51 s of CPU each).
COMPILE_CPU_S = {"contact-free": 20.0, "with contacts": 60.0}


class MjxEngine(Engine):
    """MJX (mujoco-mjx, JAX backend), stepped with a compiled ``mjx.step`` loop."""

    name = "mjx"
    description = (
        "MJX, MuJoCo in JAX: free joint or ball joint, MJX's integrators in float64 and float32"
    )
    scene_builder = SceneBuilder(
        "references.engines.mjx.system:simulate_system",
        MujocoEngine.scene_builder.settings,
        force_elements=True,
    )
    integrators = _configurations()
    bundle_runs = True  # compiled functions are cached per process: compile once per worker
    preload = ("jax",)  # safe before a fork: no thread, no device (reports.run.parallel)
    warm_up = "MJX's step (JAX)"
    batched = True  # run_batch: the members in one vmapped, compiled call
    threaded = True  # XLA computes on its own threads

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

    @classmethod
    def first_run_cost(cls, scenario, integrator: str) -> tuple[str, float, str] | None:
        """(what, CPU seconds, where it is kept) of the compilation of MJX's step loop that
        the first run of ``integrator`` on the system of bodies or robot model ``scenario``
        pays before its first step when JAX's persistent cache does not hold it
        (:data:`COMPILE_CPU_S`); None for a single body (seconds, announced by the default
        suite's exclusion) and a contact scene (not measured)."""
        if scenario.kind != "system":
            return None
        from scenarios.models.configurations import split_variant

        _, config = split_variant(integrator)
        model = getattr(scenario, "model", None)
        contact = config == "as-loaded" and model is not None and model.contact_geoms > 0
        what = "mjx.step with the file's contacts" if contact else "mjx.step"
        return (
            what,
            COMPILE_CPU_S["with contacts" if contact else "contact-free"],
            str(cache_folder()),
        )

    def run_batch(self, members, integrator, dt, t_end, save_every) -> list:
        """The members in one vmapped, compiled call
        (:func:`references.engines.mjx.batch.run_batch`)."""
        return run_batch(self, members, integrator, dt, t_end, save_every)

    @classmethod
    def version(cls) -> str:
        return _version_text(_versions())

    packages = ("mujoco-mjx", "mujoco", "jax", "jaxlib")

    @classmethod
    def default_suite_exclusion(cls) -> str | None:
        """Left out where JAX sees no accelerator (:func:`accelerator`): on a CPU, MJX steps
        one instance at a time at hundreds of times MuJoCo's cost per step and compiles for
        tens of seconds first, which is not how it is meant to run (batched, on a GPU or
        TPU); in the default suite where an accelerator is present."""
        if accelerator() is not None:
            return None
        return (
            "JAX sees no accelerator here (no GPU or TPU), and MJX on the CPU runs one "
            "instance at a time at hundreds of times MuJoCo's cost per step, after tens of "
            "seconds of compilation; it is meant to run batched on an accelerator"
        )

    @classmethod
    def version_of(cls, versions) -> str | None:
        return (
            None if any(versions.get(p) is None for p in cls.packages) else _version_text(versions)
        )

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
        with x64_mode(x64):
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
            with ctx.clock.measure(), h.x64_mode():  # a compiled call: its CPU time read
                d_leaves, qpos, qvel = h.block(m_leaves, d_leaves, ks, np.int32(len(part)))
                h.jax.block_until_ready((d_leaves, qpos, qvel))
            h.stepped(d_leaves)
            qp.append(np.asarray(qpos)[: len(part)])
            qv.append(np.asarray(qvel)[: len(part)])
        h.handed = False
        return _states(ctx.model, np.concatenate(qp), np.concatenate(qv))


def _version_text(v: dict[str, str]) -> str:
    """MJX's version as the runs record it, of the versions of its packages."""
    return f"{v['mujoco-mjx']} (mujoco {v['mujoco']}, jax {v['jax']}, jaxlib {v['jaxlib']})"


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
        with x64_mode(True):
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
            "yet; add its float64 and float32 configurations to references/engines/mjx/adapter.py"
        )
    _PROBED[key] = why
    return why
