"""MJX builder for trees of rigid bodies, in float64: MuJoCo's JAX implementation stepping the
model of the C builder (:mod:`references.engines.mujoco_system`).

The model is built, checked and read back exactly as for C MuJoCo (:func:`mujoco_system.build`:
the spanning tree, the initial states checked against every joint, the compiled ``MjModel``
compared with the scenario, MuJoCo's kinematics of the initial state compared with the
scenario's world states), then put on the JAX device with ``mjx.put_model(impl="jax")`` and
``mjx.put_data`` inside ``jax.enable_x64(True)`` (a thread-local setting, as in
:mod:`references.engines.mjx_engine`). Before the first step the builder checks that MJX holds
the state handed over bit for bit, in 8-byte floats: a float32 run cannot pass as float64.

Stepping: ``lax.fori_loop`` of ``mjx.step`` between two saves, jitted once per run (JAX's
persistent compilation cache, set up by :mod:`references.engines.mjx_engine`, serves later
processes); ``engine_time_s`` is the time inside those calls until their results are ready;
the compile time is recorded in the settings. The saved states are read from MJX's qpos/qvel
through the C builder's read-out (MuJoCo's kinematics on a C ``MjData``), so the conversion is
the C builder's, shared.

Integrators (MJX's JAX backend; docs/engines.md, section MJX): ``Euler`` (MuJoCo's
semi-implicit Euler), ``RK4`` (MJX's: four stages in the velocities, the positions advanced
once by the exponential map of the mean stage velocity, order 2 in the attitude) and
``implicitfast`` (with no damping the Euler step). ``implicit`` and ``discrete`` are not
implemented by MJX's JAX backend: :class:`Unsupported`. Loop closures are not built for MJX
here (trees only): :class:`Unsupported` with the joints named.
"""

from __future__ import annotations

import time

import numpy as np

from references.engines import mujoco_system as ms
from references.errors import Diverged, EngineError, Unsupported

#: the integrators MJX's JAX backend steps, and what each is
INTEGRATORS = {
    "Euler": "MJX's Euler: MuJoCo's semi-implicit Euler",
    "RK4": "MJX's RK4: four stages in the velocities, positions advanced once by the "
    "exponential map of the mean stage velocity (order 2 in the attitude)",
    "implicitfast": "MJX's implicitfast: without damping or actuators the Euler step",
}

_NOT_IN_MJX = ("implicit", "discrete")

_STEP = {}


def _base_name(integrator: str) -> str:
    """The MuJoCo integrator of one of the MJX adapter's configurations ("Euler (float64)" ->
    "Euler"); the float32 configurations are refused, since this builder runs in float64 only."""
    name, _, precision = integrator.partition(" (")
    if precision.rstrip(")") == "float32":
        raise Unsupported(
            "mjx: systems run in float64 only (a float32 tree would be checked against a "
            "float64 state it cannot hold)"
        )
    return name


def _step_fn():
    """``(model, data, k) -> data`` after k steps, jitted (one function per process)."""
    from references.engines.mjx_engine import _import

    _, jax, mjx = _import()
    if "fn" not in _STEP:
        _STEP["fn"] = jax.jit(
            lambda m, d, k: jax.lax.fori_loop(0, k, lambda _, dd: mjx.step(m, dd), d)
        )
    return jax, mjx, _STEP["fn"]


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> dict:  # fmt: skip
    """Run the tree ``scenario`` on MJX in float64 (module docstring); arguments and result
    as :func:`references.engines.mujoco_system.simulate_system` (no settings: a tree has no
    soft constraint). Raises :class:`Unsupported` for a loop, a joint the C builder does not
    build, or an integrator MJX does not implement."""
    integrator = _base_name(integrator)
    if integrator in _NOT_IN_MJX:
        raise Unsupported(
            f"mjx: MJX's JAX backend does not implement MuJoCo's {integrator} integrator"
        )
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator {integrator!r} unknown; known: {list(INTEGRATORS)}")
    if settings:
        raise ValueError(f"mjx simulate_system: unknown settings {sorted(settings)} (none taken)")
    saves = ms._saves(nstep, save_every)
    pl = ms.plan(scenario)
    if pl.loops:
        raise Unsupported(
            "mjx: loop closures are not built for MJX (trees only): "
            + "; ".join(lp.label for lp in pl.loops)
        )
    mujoco, m, d, pl, bid, rec = ms.build(scenario, integrator, dt)
    jax, mjx, step = _step_fn()
    with jax.enable_x64(True):
        mx = mjx.put_model(m, impl="jax")
        dx = mjx.put_data(m, d, impl="jax")
    qpos, qvel = np.asarray(dx.qpos), np.asarray(dx.qvel)
    widths = {qpos.dtype.itemsize, qvel.dtype.itemsize, np.asarray(mx.body_mass).dtype.itemsize}
    if widths != {8}:
        raise EngineError(f"mjx: the model and state MJX holds are not float64 (widths {widths})")
    if not (np.array_equal(qpos, d.qpos) and np.array_equal(qvel, d.qvel)):
        raise EngineError("mjx: the state MJX holds differs from the state handed over")
    t0 = time.perf_counter()
    with jax.enable_x64(True):
        compiled = step.lower(mx, dx, np.int32(1)).compile()
    compile_s = time.perf_counter() - t0
    nb = len(pl.bodies)
    n = len(saves)
    x, v, W = np.empty((n, nb, 3)), np.empty((n, nb, 3)), np.empty((n, nb, 3))
    R = np.empty((n, nb, 3, 3))
    x[0], R[0], v[0], W[0] = ms.read_states(mujoco, m, d, bid)
    engine = 0.0
    done = 0
    for k in range(1, n):
        t0 = time.perf_counter()
        with jax.enable_x64(True):
            dx = compiled(mx, dx, np.int32(saves[k] - done))
            jax.block_until_ready(dx.qvel)
        engine += time.perf_counter() - t0
        done = int(saves[k])
        d.qpos[:] = np.asarray(dx.qpos)
        d.qvel[:] = np.asarray(dx.qvel)
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            out = ms._output(saves[:k], dt, x[:k], R[:k], v[:k], W[:k], engine, rec)
            raise Diverged(
                f"mjx {integrator} at dt = {dt:g} s: a non-finite state between t = "
                f"{saves[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt)",
                done * dt,
                out,
            )
        x[k], R[k], v[k], W[k] = ms.read_states(mujoco, m, d, bid)
    from references.engines.mjx_engine import _versions

    rec = {
        **rec,
        "engine": "mjx {mujoco-mjx} (JAX backend, jax {jax}), float64".format(**_versions()),
        "integrator": f"{integrator}: {INTEGRATORS[integrator]}",
        "precision": "float64 (jax.enable_x64 for every call; widths read back)",
        "compile time s": round(compile_s, 3),
    }
    return ms._output(saves, dt, x, R, v, W, engine, rec)
