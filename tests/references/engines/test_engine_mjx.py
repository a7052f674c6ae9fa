"""The MJX adapter (references.engines.mjx).

Checked against references that do not share its code: C MuJoCo running the same algorithms
(``Euler`` through ``mj_step``; MJX's RK4 redone step by step with C MuJoCo's ``mj_forward``
and ``mj_integratePos``), the exact references of references.exact, and hand computations
(the float32 unit round-off). Compiling is slow (6 to 13 s per configuration and joint; the
adapter caches compiled functions for the process), so the default run compiles two
configurations on a free body and shares them; the heavy top, every configuration, the
ensemble batch and the conformance kit are marked slow. Skipped with the reason when MJX is
not installed.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

import scenarios
from references import conventions as cv
from references.engines import FAMILIES, EngineError, Unsupported, engine_names, get_engine
from references.engines import conformance as kit
from references.engines.context import BodyModel, RunContext
from references.engines.stepping import initial_state
from references.trajectory import one_body

EPS = np.finfo(float).eps
U32 = 2.0**-24


@pytest.fixture(scope="module")
def mjx():
    cls = get_engine("mjx")
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine 'mjx' is not available here: {why}")
    return cls


def _free(**kw):
    """The kit's free body (generic rotation, rates, gravity), 0.5 s."""
    return kit.free_scenario(t_end=0.5, **kw)


def _angle(Ra, Rb) -> np.ndarray:
    """Rotation angle between stacks of rotations (the attitude error of reports.metrics.body)."""
    d = np.linalg.norm(np.asarray(Ra) - np.asarray(Rb), axis=(-2, -1)) / (2 * math.sqrt(2))
    return 2 * np.arcsin(np.minimum(d, 1.0))


def _gap(a, b) -> dict:
    """Largest differences of two trajectories: attitude (rad), W, x, v (their units)."""
    a, b = one_body(a), one_body(b)
    return {
        "R": float(_angle(a.rotation, b.rotation).max()),
        "W": float(np.abs(a.omega_body - b.omega_body).max()),
        "x": float(np.abs(a.position - b.position).max()),
        "v": float(np.abs(a.velocity - b.velocity).max()),
    }


def _built(cls, sc, integrator):
    """An adapter and its RunContext after build and set_state (the scenario's state)."""
    eng = cls()
    integ = cls.integrator(integrator)
    ctx = RunContext(sc, BodyModel.of(sc, sc.dt), integ, sc.dt)
    eng.build(ctx)
    eng.set_state(ctx, initial_state(sc))
    return eng, ctx


@pytest.fixture(scope="module")
def free_runs(mjx):
    """The free body with C MuJoCo's Euler and MJX's Euler in both precisions (compiled once
    for the module)."""
    sc = _free()
    out = {"C": get_engine("mujoco")().run(sc, "Euler", sc.dt, save_every=50)}
    for name in ("Euler (float64)", "Euler (float32)"):
        out[name] = mjx().run(sc, name, sc.dt, save_every=50)
    return sc, out


# -- registry and identity ----------------------------------------------------------------------


def test_registered_and_named(mjx):
    assert "mjx" in engine_names()
    names = [i.name for i in mjx.integrators]
    assert names == [
        "Euler (float64)",
        "RK4 (float64)",
        "implicitfast (float64)",
        "Euler (float32)",
        "RK4 (float32)",
        "implicitfast (float32)",
        "implicit",
        "discrete",
    ]
    for i in mjx.integrators:
        assert i.family in FAMILIES and len(i.description) > 20


def test_switching_the_64_bit_mode_keeps_both_precisions_traceable(mjx):
    """JAX's staging caches ignore the 64-bit mode for an inner ``jit`` of a numpy float64
    constant (MJX's RK4 tableau goes through ``jnp.tril``): traced in float64 then in float32,
    the float32 function is lowered with a float64 operand and refused. ``x64_mode`` drops
    those caches when the mode changes; both functions then compute in their own precision,
    and the one compiled before the switch still runs. The expected sums are exact (sums of
    0.5 and 1)."""
    from references.engines.mjx.compile import _import, x64_mode

    _, jax, _ = _import()
    A = np.array([[0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [1.0, 0.5, 1.0]])

    def f(x):
        return jax.numpy.tril(A).sum(axis=0) * x

    out = {}
    for x64, arg in ((True, np.float64(2.0)), (False, np.float32(2.0)), (True, np.float64(1.0))):
        with x64_mode(x64):
            comp = jax.jit(f).lower(arg).compile()
            out[x64, float(arg)] = np.asarray(comp(arg))
    assert out[False, 2.0].dtype == np.float32 and out[True, 2.0].dtype == np.float64
    for key, got in out.items():
        np.testing.assert_array_equal(got, key[1] * np.array([2.0, 1.0, 1.0]))
    rk4 = mjx.integrator("RK4 (float64)")
    assert rk4.order == 2 and "order 2 in the attitude" in FAMILIES[rk4.family].description
    # the version names the C MuJoCo and JAX it runs with (part of a run's identity)
    v = mjx.version()
    assert "(mujoco " in v and ", jax " in v and ", jaxlib " in v


def test_missing_mjx_names_the_pip_command(monkeypatch):
    """An MJX that does not import makes the engine unavailable with the install command."""
    from references.engines.mjx import MjxEngine
    from references.engines.mjx import compile as mjx_compile

    monkeypatch.setattr(mjx_compile, "_MODULES", None)
    monkeypatch.setitem(sys.modules, "mujoco.mjx", None)  # import raises ImportError
    why = MjxEngine.availability()
    assert why is not None and "pip install mujoco-mjx" in why


def test_unimplemented_integrators_are_unsupported_with_mjxs_reason(mjx):
    for name, text in (
        ("implicit", "mjINT_IMPLICIT"),
        ("discrete", "not implemented"),
    ):
        for sc in (kit.free_scenario(), kit.pivoted_scenario()):
            with pytest.raises(Unsupported, match="NotImplementedError") as exc:
                mjx().run(sc, name, sc.dt, t_end=2 * sc.dt)
            assert text in str(exc.value)


# -- float64: MJX's Euler is C MuJoCo's -----------------------------------------------------------


def test_float64_euler_reproduces_c_mujoco(free_runs):
    """500 steps of the same algorithm in another implementation: the gap is round-off, a few
    ulp per step accumulated (bound 500 x 10 eps of each quantity's size; measured ~1e-15)."""
    sc, runs = free_runs
    ref, got = one_body(runs["C"].trajectory), one_body(runs["Euler (float64)"].trajectory)
    gap = _gap(ref, got)
    bound = 500 * 10 * EPS
    assert gap["R"] <= bound
    assert gap["W"] <= bound * np.abs(ref.omega_body).max()
    assert gap["x"] <= bound * np.abs(ref.position).max()
    assert gap["v"] <= bound * np.abs(ref.velocity).max()
    assert runs["Euler (float64)"].settings["precision"] == "float64"


def test_float64_is_float64_and_float32_is_float32(mjx):
    """The model and the state MJX holds, before and after stepping, in floats of the width
    the configuration is named for, whatever the process's jax_enable_x64."""
    import jax

    sc = _free()
    for name, width in (("Euler (float64)", 8), ("Euler (float32)", 4)):
        eng, ctx = _built(mjx, sc, name)
        h = ctx.handle
        eng.advance(ctx, 3)
        for a in (h.dx.qpos, h.dx.qvel, h.mx.body_mass, h.mx.body_inertia, h.mx.opt.timestep):
            assert np.asarray(a).dtype.itemsize == width, (name, np.asarray(a).dtype)
        rb = eng.read_model(ctx)
        assert rb.extra["mjx.Data qpos: bytes per float"] == (width, width)
    assert not jax.config.jax_enable_x64  # the adapter never switched the process's mode


# -- float32 --------------------------------------------------------------------------------------


def test_float32_rounds_the_handed_state_by_a_few_unit_roundoffs(mjx):
    """The float32 state MJX steps from is the state handed over rounded: through MJX's own
    float32 quantities it differs by a few u32 (u32 = 2^-24 = 6e-8; each number is rounded
    once, then MJX's quantities add a dozen roundings), far inside the adapter's check
    (64 u32) and far outside float64 (1e-12 would fail)."""
    from references.engines.mjx import FLOAT32_INITIAL_RTOL

    assert FLOAT32_INITIAL_RTOL == 64 * U32
    for sc in (_free(), scenarios.load("dzhanibekov"), scenarios.load("gazebo_boxes_complex")):
        eng, ctx = _built(mjx, sc, "Euler (float32)")
        err = ctx.handle.rounding
        worst = max(err.values())
        assert worst <= 8 * U32, err
        assert worst > 1e-12  # really rounded: not a float64 state


def test_float32_run_differs_from_float64_by_float32_roundoff(free_runs):
    """The same algorithm in float32 and float64: the trajectories differ by float32 round-off
    (u32 per operation, ~100 steps' worth over 500 steps), not by float64's (a float32 run
    silently computed in float64 would agree to ~1e-15)."""
    sc, runs = free_runs
    gap = _gap(runs["Euler (float64)"].trajectory, runs["Euler (float32)"].trajectory)
    assert 10 * U32 * 1e-2 < gap["W"] / 2.1 < 500 * U32  # |W| ~ 2.1 rad/s
    assert gap["R"] < 500 * U32
    st = runs["Euler (float32)"].settings
    assert st["precision"] == "float32" and "rounded to float32" in st["initial state"]


def test_what_the_kit_says_of_the_rounded_float32_state(mjx):
    """Read back before the first step, the rounded float32 state fails the suite's 1e-12
    initial check by a few u32: the hand-over in float64 is what lets float32 runs through;
    the adapter's own check of the rounding (64 u32) is the tolerance a per-integrator
    initial-state tolerance of the base class would take."""
    from references.engines.mjx import FLOAT32_INITIAL_RTOL

    class Rounded(mjx):
        def set_state(self, ctx, state):
            super().set_state(ctx, state)
            ctx.handle.handed = False  # report the state MJX holds, rounded

    sc = _free()
    with pytest.raises(EngineError, match=r"allowed 1e-12") as exc:
        Rounded().run(sc, "Euler (float32)", sc.dt, t_end=2 * sc.dt)
    rel = float(str(exc.value).split("differs from the scenario's by ")[1].split()[0])
    assert 1e-9 < rel < FLOAT32_INITIAL_RTOL


# -- planted mistakes on a free body (the kit does both bodies, slow) -----------------------------


def test_planted_mistakes_are_caught_on_a_free_body(mjx):
    sc = kit.free_scenario()
    plants = {n: kit._planted(mjx, n, m) for n, m in kit.STATE_MISTAKES.items()}
    plants |= {n: kit._planted(mjx, n, m) for n, m in kit.MODEL_MISTAKES.items()}
    for n, (plant, _) in mjx.plantable.items():
        plants[n] = kit._engine_mistake(mjx, n, plant)
    for name, bad in plants.items():
        with pytest.raises(EngineError) as exc:
            bad().run(sc, "Euler (float64)", sc.dt, t_end=2 * sc.dt)
        assert exc.value.status == "error", name


# -- slow: every configuration, the heavy top, RK4, ensembles, the kit -----------------------

CONFIGS = [f"{a} ({p})" for p in ("float64", "float32") for a in ("Euler", "RK4", "implicitfast")]


def _rk4_mjx_algorithm(sc, dt, nstep):
    """MJX's RK4 (mujoco.mjx._src.forward.rungekutta4) redone with C MuJoCo's dynamics: the
    stage velocities v0 + a h a_{i-1}, stage positions q0 (+) a h v_{i-1} (mj_integratePos),
    then v1 = v0 + h sum b_i a_i and q1 = q0 (+) h sum b_i v_i. Returns qpos, qvel at the end."""
    import mujoco

    from references.engines.mujoco.adapter import MujocoEngine

    bm = BodyModel.of(sc, dt)
    m = mujoco.MjModel.from_xml_string(MujocoEngine.model_xml(bm, "Euler"))
    d = mujoco.MjData(m)
    if bm.pivoted:
        qpos, qvel = cv.mujoco_ball_from_state(sc.rotation, sc.omega_body)
    else:
        qpos, qvel = cv.mujoco_free_from_state(*initial_state(sc))
    b = (1 / 6, 1 / 3, 1 / 3, 1 / 6)
    for _ in range(nstep):
        q0, v0 = qpos.copy(), qvel.copy()
        d.qpos[:], d.qvel[:] = q0, v0
        mujoco.mj_forward(m, d)
        vs, accs = [v0], [d.qacc.copy()]
        for a in (0.5, 0.5, 1.0):
            qi = q0.copy()
            mujoco.mj_integratePos(m, qi, a * vs[-1], dt)
            vi = v0 + a * dt * accs[-1]
            d.qpos[:], d.qvel[:] = qi, vi
            mujoco.mj_forward(m, d)
            vs.append(vi)
            accs.append(d.qacc.copy())
        vbar = sum(bi * v for bi, v in zip(b, vs, strict=True))
        abar = sum(bi * a for bi, a in zip(b, accs, strict=True))
        qpos = q0.copy()
        mujoco.mj_integratePos(m, qpos, vbar, dt)
        qvel = v0 + dt * abar
    return qpos, qvel


@pytest.fixture(scope="module")
def every_config(mjx):
    """Every runnable configuration on the free body and on the heavy top (1 s), with C
    MuJoCo's Euler and RK4 alongside."""
    top = scenarios.load("heavy_top").replace(t_end=1.0)
    out = {}
    for sc in (_free(), top):
        for name in CONFIGS:
            out[sc.name, name] = mjx().run(sc, name, sc.dt, save_every=50)
        for name in ("Euler", "RK4"):
            out[sc.name, "C " + name] = get_engine("mujoco")().run(sc, name, sc.dt, save_every=50)
    return _free(), top, out


@pytest.mark.slow
def test_every_configuration_runs_the_free_body_and_the_heavy_top(every_config):
    free, top, out = every_config
    for sc in (free, top):
        c_euler = out[sc.name, "C Euler"].trajectory
        for name in CONFIGS:
            res = out[sc.name, name]
            assert res.nstep == round(sc.t_end / sc.dt)
            tr = res.trajectory
            if name.startswith(("Euler", "implicitfast")):
                # MJX's implicitfast is its Euler step here (no damping, no bias derivative)
                gap = _gap(c_euler, tr)
                # float64: round-off over 1000 steps (measured <= 1e-12 on the spinning top,
                # whose fast spin amplifies it); float32: u32 per operation, with margin
                tol = 1e-10 if "float64" in name else 1e-3
                assert gap["R"] <= tol and gap["W"] <= tol * 120, (sc.name, name, gap)


@pytest.mark.slow
def test_implicitfast_is_bitwise_euler_in_mjx(every_config):
    free, top, out = every_config
    for sc in (free, top):
        for p in ("float64", "float32"):
            a = one_body(out[sc.name, f"Euler ({p})"].trajectory)
            b = one_body(out[sc.name, f"implicitfast ({p})"].trajectory)
            assert np.array_equal(a.rotation, b.rotation) and np.array_equal(
                a.omega_body, b.omega_body
            )


@pytest.mark.slow
def test_float64_rk4_is_mjxs_algorithm_on_c_mujocos_dynamics(every_config):
    """Against the same algorithm with C MuJoCo's forward dynamics: round-off (measured
    ~1e-14 after 1000 steps; bound 1e-11 on the spinning top)."""
    free, top, out = every_config
    for sc in (free, top):
        qpos, qvel = _rk4_mjx_algorithm(sc, sc.dt, round(sc.t_end / sc.dt))
        tr = one_body(out[sc.name, "RK4 (float64)"].trajectory)
        if sc.pivot is not None:
            R, W = cv.mujoco_ball_to_state(qpos, qvel)
        else:
            _, _, R, W = cv.mujoco_free_to_state(qpos, qvel)
        assert _angle(R, tr.rotation[-1]) <= 1e-11
        assert np.abs(W - tr.omega_body[-1]).max() <= 1e-11 * np.abs(W).max()


@pytest.mark.slow
def test_mjx_rk4_is_not_c_mujoco_4_rk4(every_config):
    """C MuJoCo 4.0.0's RK4 is order 4 in the attitude, MJX 3.17.0's order 2: on the free body
    their attitudes part by the latter's O(h^2) error, while the torque-free body rates (which
    do not depend on the attitude) agree to round-off."""
    free, top, out = every_config
    c = one_body(out[free.name, "C RK4"].trajectory)
    m = one_body(out[free.name, "RK4 (float64)"].trajectory)
    if not get_engine("mujoco").version().startswith("4."):
        pytest.skip("measured against C MuJoCo 4")
    assert _angle(c.rotation, m.rotation).max() > 1e-9


@pytest.mark.slow
def test_float32_rk4_energy_drift_is_the_precision_limit(mjx):
    """The free body I = (1, 2, 3), W0 = (0.01, 2, 0.01), 20 s: RK4's truncation error in the
    energy is below float64 round-off at h = 1e-3, so the energy drift is round-off: ~1e-14 in
    float64, in float32 u32 per step accumulated (measured 1e-6..1e-5)."""
    from reports.metrics.body import energy_drift

    sc = kit.free_scenario(
        inertia=[1.0, 2.0, 3.0], omega_body=[0.01, 2.0, 0.01], gravity=[0, 0, 0], t_end=20.0
    )
    drift = {}
    for p in ("float64", "float32"):
        tr = mjx().run(sc, f"RK4 ({p})", sc.dt, save_every=100).trajectory
        drift[p] = float(np.max(np.abs(energy_drift(sc, tr))))
    assert drift["float64"] < 1e-12
    assert 10 * U32 < drift["float32"] < 1e-4, drift


@pytest.mark.slow
def test_ensemble_batch_equals_member_runs(mjx):
    """run_batch: every member in one vmapped call gives each member's single run (the same
    compiled step under vmap; measured equal to ~1e-15) and the rows of the ensemble."""
    from reports.run.ensemble import members

    sc = scenarios.load("dzhanibekov").replace(t_end=0.5)
    mems = members(sc, 4, seed=1)
    batch = mjx().run_batch(mems, "Euler (float64)", sc.dt, sc.t_end, 50)
    for mem, out in zip(mems, batch, strict=True):
        one = mjx().run(mem, "Euler (float64)", sc.dt, save_every=50).trajectory
        gap = _gap(one, out.trajectory)
        assert gap["R"] <= 1e-13 and gap["W"] <= 1e-13
        assert out.trajectory.t[-1] == pytest.approx(0.5)


@pytest.fixture(scope="module")
def kit_checks(mjx):
    return kit.check_adapter(mjx)


@pytest.mark.slow
def test_the_kit_passes_and_skips_the_order_of_the_integrators_mjx_refuses(kit_checks):
    # MJX's JAX backend has no implicit or discrete integrator: the adapter refuses them with
    # its reason (Unsupported), so the kit measures no order for them instead of failing it
    failed = {c.name: c.message for c in kit_checks if not c.ok}
    assert failed == {}
    names = {c.name for c in kit_checks}
    assert not {"declared order of 'implicit'", "declared order of 'discrete'"} & names
    for mistake in (*kit.STATE_MISTAKES, *kit.MODEL_MISTAKES, "joint damping left on"):
        assert f"catches {mistake} (free)" in names and f"catches {mistake} (pivoted)" in names


@pytest.mark.slow
def test_assert_conforms(mjx, kit_checks):
    kit.assert_conforms(mjx)


# -- the traced computations kept on disk (compile._lowered) ----------------------------------


def _traced_twice(mjx, tmp_path, monkeypatch, kind="test-affine"):
    """compile._lowered on a small function, with the store in tmp_path: (the compiled
    function, how often the function was traced, the store's files)."""
    from references.engines.mjx import compile as C

    monkeypatch.setattr(C, "_exported_store", lambda: tmp_path)
    _, jax, _ = C._import()
    traced = []

    def fn(a, b):
        traced.append(1)
        return {"y": 3.0 * a + b[0]}

    args = (np.arange(4.0), [np.float64(0.5)])
    avals = tuple((np.shape(a), str(np.asarray(a).dtype)) for a in (args[0], args[1][0]))
    defs = (jax.tree_util.tree_structure(args),)
    with C.x64_mode(True):
        comp = C._lowered(kind, fn, defs, avals, args, True).compile()
        out = np.asarray(comp(*args)["y"])
    return out, len(traced), sorted(tmp_path.glob("*.exported"))


def test_an_exported_computation_is_loaded_instead_of_traced(mjx, tmp_path, monkeypatch):
    out, n, files = _traced_twice(mjx, tmp_path, monkeypatch)
    assert n == 1 and len(files) == 1
    np.testing.assert_array_equal(out, 3.0 * np.arange(4.0) + 0.5)
    out2, n2, files2 = _traced_twice(mjx, tmp_path, monkeypatch)
    assert n2 == 0 and files2 == files  # loaded: not traced again
    np.testing.assert_array_equal(out2, out)
    # another kind is another key: traced and kept beside
    _, n3, files3 = _traced_twice(mjx, tmp_path, monkeypatch, kind="test-other")
    assert n3 == 1 and len(files3) == 2


def test_a_corrupt_or_foreign_exported_file_is_ignored_and_rewritten(mjx, tmp_path, monkeypatch):
    from references.engines.mjx import compile as C

    _, _, (path,) = _traced_twice(mjx, tmp_path, monkeypatch)
    good = path.read_bytes()
    n = len(C._EXPORT_FORMAT)
    flipped = bytearray(good)
    flipped[-10] ^= 0xFF  # a payload byte: its checksum no longer matches
    other_key = bytearray(good)
    other_key[n] ^= 0xFF  # the file holds another key than its name's
    for bad in (bytes(flipped), bytes(other_key), good[: len(good) // 2], b"junk"):
        path.write_bytes(bad)
        out, traced, files = _traced_twice(mjx, tmp_path, monkeypatch)
        assert traced == 1 and files == [path]
        np.testing.assert_array_equal(out, 3.0 * np.arange(4.0) + 0.5)
        assert path.read_bytes()[: n + 32] == good[: n + 32]  # rewritten whole
        assert not list(tmp_path.glob("*.tmp"))
