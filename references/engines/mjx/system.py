"""MJX builder for systems of rigid bodies (trees and loops), in float64: MuJoCo's JAX
implementation stepping the model of the C builder (:mod:`references.engines.mujoco.system`).

The model is built, checked and read back exactly as for C MuJoCo (:func:`mujoco_system.build`:
the spanning tree, the initial states checked against every joint, the compiled ``MjModel``
compared with the scenario, MuJoCo's kinematics of the initial state compared with the
scenario's world states), then put on the JAX device with ``mjx.put_model(impl="jax")`` and
``mjx.put_data`` inside :func:`references.engines.mjx.compile.x64_mode` (``jax.enable_x64``, a
thread-local setting, as for every JAX call of :mod:`references.engines.mjx`). Before the
first step the builder checks that MJX holds the state handed over bit for bit, in 8-byte
floats: a float32 run cannot pass as float64.

Stepping: ``lax.fori_loop`` of ``mjx.step`` between two saves, compiled ahead of time through
the single-body adapter's cache (:func:`references.engines.mjx.compile._compiled`, keyed by the
64-bit mode and the model's structure: once per model and integrator in a process; later
processes load the exported computation and JAX's persistent cache, see that module);
``engine_time_s`` is the time inside those calls until their results are ready; the compile
time, and whether this run compiled, are recorded in the settings. The saved states are read
from MJX's qpos/qvel through the C builder's read-out (MuJoCo's kinematics on a C ``MjData``),
so the conversion is the C builder's, shared.

Integrators (MJX's JAX backend; docs/engines.md, section MJX): ``Euler`` (MuJoCo's
semi-implicit Euler), ``RK4`` (MJX's: four stages in the velocities, the positions advanced
once by the exponential map of the mean stage velocity, order 2 in the attitude) and
``implicitfast`` (with no damping the Euler step). ``implicit`` and ``discrete`` are not
implemented by MJX's JAX backend: :class:`Unsupported`.

Loop closures: the C builder's site-to-site ``equality connect`` rows (one per closing
spherical joint, two per closing revolute joint), with the same ``solref``/``solimp``
(MuJoCo's defaults unless given) and the same refsafe rule. MJX's JAX backend builds connect
rows between sites (``mujoco/mjx/_src/constraint.py``, ``_efc_equality_connect``: the sites'
world points, their Jacobians, the impedance and reference acceleration of MuJoCo's
documented soft-constraint model) and solves them with the model's solver, iterations and
tolerance. Before stepping, the builder reads back from the MJX model every connect's type,
sites, solref and solimp, the solver settings and the disable flags, and compares them with
the compiled C model. Measured on the four-bar (mujoco-mjx 3.17.0, mujoco 4.0.0): MJX's
constraint rows (position error, Jacobian, D, K, B, impedance) equal C MuJoCo's, but MJX's
reference acceleration is aref = -B J v - K imp r while C MuJoCo's also subtracts the
connect's velocity-product term Jdot v (``mj_referenceConstraint`` calls ``mj_Jdotv`` for
connect and weld rows; C's aref equals MJX's minus Jdot v, Jdot v taken by central
differences of efc_J along qvel, to 1e-8): MJX's loop closure lacks that term, so on a closed
loop MJX's Euler is not C MuJoCo's Euler step for step as it is on a tree: 1.4e-3 m apart
after the singular passages with the default solref, 1.8e-6 m with solref (0.002, 1), and
its loop gaps are larger where Jdot v matters (Bricard: 1.7e-3 m against C's 5.6e-4 m)
(docs/engines.md, MJX).
"""

from __future__ import annotations

import time

import numpy as np

from references.engines import timing
from references.engines.mujoco import system as ms
from references.engines.reduced import check_settings
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported
from scenarios.force_elements import has_elements

#: what differs from C MuJoCo on a closed loop, recorded in a loop's run settings
LOOP_DIFFERENCE = (
    "connect rows, solref, solimp, solver, iterations and tolerance equal C MuJoCo's (read "
    "back), but MJX's reference acceleration aref = -B J v - K imp r omits the velocity-"
    "product term Jdot v that C MuJoCo's mj_referenceConstraint subtracts for connect rows: "
    "on a loop MJX's Euler is another constraint stabilisation than C MuJoCo's Euler"
)

#: the integrators MJX's JAX backend steps, and what each is
INTEGRATORS = {
    "Euler": "MJX's Euler: MuJoCo's semi-implicit Euler",
    "RK4": "MJX's RK4: four stages in the velocities, positions advanced once by the "
    "exponential map of the mean stage velocity (order 2 in the attitude)",
    "implicitfast": "MJX's implicitfast: without damping or actuators the Euler step",
}

_NOT_IN_MJX = ("implicit", "discrete")


def _base_name(integrator: str) -> str:
    """The MuJoCo integrator of one of the MJX adapter's configurations ("Euler (float64)" ->
    "Euler"); the float32 configurations are refused, since this builder runs in float64 only."""
    name, _, precision = integrator.partition(" (")
    if precision.rstrip(")") == "float32":
        raise Unsupported(
            "mjx: systems run in float64 only (a float32 model would be checked against a "
            "float64 state it cannot hold)"
        )
    return name


def _step_fn():
    """(jax, mjx, ``(model, data, k) -> the leaves of the data`` after k steps), to be compiled
    by :func:`references.engines.mjx.compile._compiled`. The data stays a leaf list between
    calls, so no call rebuilds an ``mjx.Data`` or flattens one (MJX's flattening compares its
    static fields, ~1 ms a call)."""
    from references.engines.mjx.compile import _import

    _, jax, mjx = _import()

    def step(m, d, k):
        return jax.tree_util.tree_leaves(jax.lax.fori_loop(0, k, lambda _, dd: mjx.step(m, dd), d))

    return jax, mjx, step


def read_back(m, mx, scenario) -> None:
    """Compare the MJX model ``mx`` with the compiled C model ``m`` (already read back against
    the scenario): the equality constraints (type, objects, solref, solimp, active), the
    solver settings and the flags. Raises :class:`EngineError` naming what differs."""
    bad = []
    for what in ("eq_type", "eq_objtype", "eq_obj1id", "eq_obj2id", "eq_solref", "eq_solimp",
                 "site_bodyid", "site_pos"):  # fmt: skip
        got, exp = np.asarray(getattr(mx, what)), np.asarray(getattr(m, what))
        if got.shape != exp.shape or not np.array_equal(got.astype(float), exp.astype(float)):
            bad.append(f"{what}: MJX holds {got.tolist()}, the C model {exp.tolist()}")
    if not np.array_equal(np.asarray(mx.eq_active0, bool), np.asarray(m.eq_active0, bool)):
        bad.append("eq_active0 differs from the C model's")
    for what in ("solver", "iterations", "tolerance", "ls_iterations", "disableflags",
                 "enableflags", "timestep", "integrator"):  # fmt: skip
        got, exp = float(getattr(mx.opt, what)), float(getattr(m.opt, what))
        if got != exp:
            bad.append(f"opt.{what}: MJX holds {got:g}, the C model {exp:g}")
    if bad:
        raise EngineError(
            f"mjx: system {scenario.name!r}: the MJX model differs from the C model: "
            + "; ".join(bad)
        )


def read_back_forces(mujoco, m, mx, dx, scenario, pl, bid) -> None:
    """The force elements as MJX holds them, against the scenario (not only the C model):
    each spring's tendon in the MJX model (:func:`references.engines.mujoco.forces.
    read_back_springs` on the MJX model's arrays: sites, bodies, k, c, l0) and the joint
    torques in the MJX data's ``qfrc_applied`` (the C builder's generalised forces of the
    scenario's torques). Raises :class:`EngineError` naming what differs."""
    from references.engines.mujoco import forces

    bad = []

    def want(what, got, expect, scale=1.0):  # the C builder's rule (ms.READBACK_TOL)
        if not ms._close(np.asarray(got), expect, scale) <= ms.READBACK_TOL:
            g, e = np.asarray(got, float), np.asarray(expect, float)
            bad.append(f"{what}: MJX holds {np.round(g, 15).tolist()}, the scenario needs "
                       f"{np.round(e, 15).tolist()}")  # fmt: skip

    ndist = sum(len(lp.distances) for lp in pl.loops)
    forces.read_back_springs(mujoco, mx, scenario, pl, bid, ndist, want, bad)
    applied = np.zeros(m.nv)
    for dof, Q, _ in forces.torque_forces(m, scenario, pl, bid):
        applied[dof] += Q
    want("qfrc_applied (the joint torques) in MJX's data", dx.qfrc_applied, applied)
    if bad:
        raise EngineError(f"mjx: system {scenario.name!r}: the force elements MJX holds differ "
                          "from the scenario: " + "; ".join(bad))  # fmt: skip


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` on MJX in float64 (module docstring); arguments, settings (``solref``
    and ``solimp`` of the loop-closing connects) and result as
    :func:`references.engines.mujoco.system.simulate_system`. Raises :class:`Unsupported` for
    a joint or loop the C builder does not build, or an integrator MJX does not implement."""
    check_settings("mjx", settings)
    integrator = _base_name(integrator)
    if integrator in _NOT_IN_MJX:
        raise Unsupported(
            f"mjx: MJX's JAX backend does not implement MuJoCo's {integrator} integrator"
        )
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator {integrator!r} unknown; known: {list(INTEGRATORS)}")
    saves = ms._saves(nstep, save_every)
    mujoco, m, d, pl, bid, rec = ms.build(scenario, integrator, dt, **settings)
    from references.engines.mjx.compile import _compiled, x64_mode

    jax, mjx, step = _step_fn()
    with x64_mode(True):
        mx = mjx.put_model(m, impl="jax")
        dx = mjx.put_data(m, d, impl="jax")
        # put_data's integer fields (a tendon's wrap addresses) are int32, step's int64 under
        # x64: the loop's carry keeps the types step gives (a universal closure's tendon)
        shapes = jax.eval_shape(mjx.step, mx, dx)
        dx = jax.tree_util.tree_map(lambda a, s: a.astype(s.dtype), dx, shapes)
    read_back(m, mx, scenario)
    if has_elements(scenario):
        read_back_forces(mujoco, m, mx, dx, scenario, pl, bid)
    qpos, qvel = np.asarray(dx.qpos), np.asarray(dx.qvel)
    widths = {qpos.dtype.itemsize, qvel.dtype.itemsize, np.asarray(mx.body_mass).dtype.itemsize}
    if widths != {8}:
        raise EngineError(f"mjx: the model and state MJX holds are not float64 (widths {widths})")
    if not (np.array_equal(qpos, d.qpos) and np.array_equal(qvel, d.qvel)):
        raise EngineError("mjx: the state MJX holds differs from the state handed over")
    compiled, compile_s, now = _compiled(f"system-step-{integrator}", step, (mx, dx),
                                       (np.int32(1),), True)  # fmt: skip
    mxl, dxl = compiled.leaves(0, mx), compiled.leaves(1, dx)
    # where qpos and qvel are in the data's leaf list
    at = jax.tree_util.tree_unflatten(compiled.defs[1], list(range(len(dxl))))
    nb = len(pl.bodies)
    n = len(saves)
    x, v, W = np.empty((n, nb, 3)), np.empty((n, nb, 3)), np.empty((n, nb, 3))
    R = np.empty((n, nb, 3, 3))
    x[0], R[0], v[0], W[0] = ms.read_states(mujoco, m, d, bid)
    engine = 0.0
    done = 0
    timing.stepping()  # the model is built: its construction is not the cost
    for k in range(1, n):
        t0 = time.perf_counter()
        with x64_mode(True):
            dxl = compiled(mxl, dxl, np.int32(saves[k] - done))
            jax.block_until_ready(dxl[at.qvel])
        engine += timing.lap(t0)
        done = int(saves[k])
        d.qpos[:] = np.asarray(dxl[at.qpos])
        d.qvel[:] = np.asarray(dxl[at.qvel])
        if not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            out = ms._output(saves[:k], dt, x[:k], R[:k], v[:k], W[:k], engine, rec)
            raise Diverged(
                f"mjx {integrator} at dt = {dt:g} s: a non-finite state between t = "
                f"{saves[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt)",
                done * dt,
                out,
            )
        x[k], R[k], v[k], W[k] = ms.read_states(mujoco, m, d, bid)
    from references.engines.mjx.compile import _versions

    rec = {
        **rec,
        "engine": "mjx {mujoco-mjx} (JAX backend, jax {jax}), float64".format(**_versions()),
        "integrator": f"{integrator}: {INTEGRATORS[integrator]}",
        "precision": "float64 (jax.enable_x64 for every call; widths read back)",
        "compile time s": round(compile_s, 3),
        "compiled for this run": now,  # else the compile time is the first run's in the process
    }
    if pl.loops:
        # the one difference from C MuJoCo on a loop (module docstring), named in the run's
        # configuration: the same rows, solref, solimp, solver, iterations and tolerance (read
        # back above), another reference acceleration
        rec["loop closure"] = LOOP_DIFFERENCE
    return ms._output(saves, dt, x, R, v, W, engine, rec)
