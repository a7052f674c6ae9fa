"""The reference of a system of bodies, presented as the ``exact`` engine's system builder
(:mod:`references.engines.system`) and used by the suite to measure every engine's errors.

Kinds (``[reference] kind`` of the file, :data:`scenarios.system.SYSTEM_REFERENCE_KINDS`):

- ``spinning_chain``, ``conical_pendulum``, ``four_bar``, ``n_four_bar``: the closed forms of
  :mod:`references.exact.multibody.exact`, built from the file's bodies and the parameters
  of its ``[reference]`` table; the closed form's state at t = 0 must equal the file's
  initial state (:data:`INITIAL_TOL`), so a file whose state is not that motion's is refused
  rather than compared with another motion. Accuracy: the closed form's round-off estimate.
- ``numerical`` (``auto``): the reduced-coordinate tree of the spanning tree's spherical and
  revolute joints, every other joint (the loop closures; universal, cylindrical, prismatic
  joints) as constraint rows on it (:func:`references.exact.multibody.loops.system_from_world`,
  a formulation that shares nothing with the director model), integrated by DOP853 at rtol
  1e-13 with its error estimate (:func:`references.exact.multibody.solve`); a loop that
  reaches a singular configuration has none (the branches meet there: the closed forms
  cover the four-bars that pass through one), and the horizon over which it is meaningful
  (:func:`references.exact.multibody.trajectory_horizon`: perturbed runs depart by less than
  :data:`HORIZON_ATTITUDE` rad and HORIZON_POSITION times the system's size): trajectory
  errors are judged only up to that horizon, the accuracy is the estimate's over it.
- ``none``: no independent reference, asked for by the file; the exact engine's row is
  ``unsupported`` with that reason and other engines' trajectory errors are not measured
  (their invariants and joint gaps are).
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np

from references.engines.system import SystemResult
from references.engines.timing import Timing
from references.errors import EngineError, Unsupported
from references.trajectory import Trajectory

#: the closed form's initial state must equal the file's to this, relative to the system's
#: size (positions), 1 (rotations) and the rate scale (velocities): the files print 17
#: digits, so a mismatch beyond 1e-12 is a different motion, not rounding
INITIAL_TOL = 1e-12
#: the horizon of a numerical reference: perturbed runs stay within this attitude (rad), a
#: tenth of the default attitude tolerance 0.1 rad (reports.metrics.verdicts, REFERENCE_MARGIN), and
#: this fraction of the system's size in position
HORIZON_ATTITUDE = 1e-2
HORIZON_POSITION = 1e-2


@dataclass
class SystemReference:
    """A system's reference at the times ``t``: ``trajectory`` (bodies in the scenario's
    order), ``kind``, ``accuracy`` (rad, the attitude error estimate over the trusted
    horizon), ``accuracy_position`` (m), ``horizon`` (s: trajectory errors are judged on
    t <= horizon; t_end when the whole run is trusted), ``method``, ``wall_time_s`` and
    ``cpu_time_s`` (what its computation took on the thread that computed it, in this
    process or in the run that kept it in the reference cache, :mod:`references.cache`)."""

    trajectory: Trajectory
    kind: str
    accuracy: float
    accuracy_position: float
    horizon: float
    method: str
    wall_time_s: float = 0.0
    notes: dict = field(default_factory=dict)
    cpu_time_s: float = 0.0
    #: CPU s of the work this reference shares with the scenario's other time grids that its
    #: computation took from its process's memory (a closed form's Floquet analysis done for
    #: another grid): part of its cost all the same, so that the cost does not depend on
    #: which grid a process computed first
    shared_cpu_s: float = 0.0


def reference_kind(scenario) -> str:
    """The reference kind a scenario gets (``auto`` resolved)."""
    if scenario.reference != "auto":
        return scenario.reference
    return "numerical"


def _order(names_from, names_to) -> list[int]:
    idx = {n: i for i, n in enumerate(names_from)}
    return [idx[n] for n in names_to]


def _check_initial(scenario, x, R, v, W, what: str) -> None:
    """Refuse a closed form whose initial state is not the file's (module docstring)."""
    size = scenario.length_scale
    rate = max(1.0, max(float(np.linalg.norm(b.omega_body)) for b in scenario.bodies))
    for i, b in enumerate(scenario.bodies):
        gaps = {
            "centre of mass": float(np.linalg.norm(x[i] - b.position)) / size,
            "rotation": float(np.max(np.abs(R[i] - b.rotation))),
            "velocity": float(np.linalg.norm(v[i] - b.velocity)) / (rate * size),
            "angular velocity": float(np.linalg.norm(W[i] - b.omega_body)) / rate,
        }
        for k, g in gaps.items():
            if not g <= INITIAL_TOL:
                raise Unsupported(
                    f"{what}: the exact motion's initial {k} of body {b.name!r} differs from "
                    f"the scenario's by {g:.3g} (relative; at most {INITIAL_TOL:g}): the file's "
                    "state is not this motion's; fix the file or its [reference] parameters"
                )


def _param(scenario, key: str) -> float:
    p = scenario.reference_params
    if key not in p:
        raise Unsupported(
            f"reference {scenario.reference!r} needs the parameter {key!r} in the file's "
            f"[reference] table (it has {sorted(p)})"
        )
    return p[key]


def _closed_form(scenario):
    """The closed form of the scenario's kind, in the scenario's body order: (motion(t) ->
    (x, R, v, W) in scenario order, the :class:`~references.exact.multibody.exact.ExactMotion`
    itself)."""
    from references.exact._util import ReferenceNotApplicable
    from references.exact.multibody import exact as ex
    from references.exact.multibody import tree_from_world

    kind = scenario.reference
    by = {b.name: b for b in scenario.bodies}
    try:
        if kind == "spinning_chain":
            tree, _, _ = tree_from_world(scenario.bodies, scenario.joints, scenario.gravity)
            root = by[tree.names[0]]
            m = scenario.total_mass
            vc = sum(b.mass * b.velocity for b in scenario.bodies) / m
            motion = ex.SpinningChain(tree, _param(scenario, "rate"),
                                      int(_param(scenario, "axis")), root.rotation,
                                      scenario.centre_of_mass, vc)  # fmt: skip
            names = tree.names
        elif kind == "conical_pendulum":
            g = np.asarray(scenario.gravity)
            if not (g[0] == 0 and g[1] == 0 and g[2] < 0):
                raise Unsupported("conical_pendulum: the reference needs gravity along -z")
            b1, b2 = scenario.bodies[0], scenario.bodies[1]
            motion = ex.DoubleConicalPendulum(
                (b1.mass, b2.mass), (tuple(b1.inertia), tuple(b2.inertia)),
                (_param(scenario, "l1"), _param(scenario, "l2")), _param(scenario, "L1"),
                -float(g[2]), _param(scenario, "rate"),
                int(scenario.reference_params.get("branch", 1)),
            )  # fmt: skip
            names = [b1.name, b2.name]
        elif kind == "four_bar":
            g = np.asarray(scenario.gravity)
            if not (g[0] == 0 and g[1] == 0 and g[2] < 0):
                raise Unsupported("four_bar: the reference needs gravity along -z")
            missing = {"crank", "rocker", "coupler"} - set(by)
            if missing:
                raise Unsupported(f"four_bar: the reference needs bodies named {sorted(missing)}")
            parts = [(by[n].mass, tuple(by[n].inertia)) for n in ("crank", "rocker", "coupler")]
            P = {k: _param(scenario, k) for k in
                 ("L", "D", "LA", "LB", "coupler_com", "theta0", "thetadot0")}  # fmt: skip
            motion = ex.ParallelogramFourBar(P["L"], P["D"], *parts, P["LA"], P["LB"],
                                             P["coupler_com"], -float(g[2]), P["theta0"],
                                             P["thetadot0"])  # fmt: skip
            names = motion.names
        elif kind == "n_four_bar":
            g = np.asarray(scenario.gravity)
            if not (g[0] == 0 and g[2] == 0 and g[1] < 0):
                raise Unsupported("n_four_bar: the reference needs gravity along -y")
            P = {k: _param(scenario, k) for k in ("N", "L", "m", "J", "theta0", "thetadot0")}
            motion = ex.NFourBar(P["N"], P["L"], P["m"], P["J"], -float(g[1]), P["theta0"],
                                 P["thetadot0"])  # fmt: skip
            missing = set(motion.names) - set(by)
            if missing:
                raise Unsupported(f"n_four_bar: the reference needs bodies named {sorted(missing)}")
            for n in motion.names:
                b = by[n]
                if b.mass != motion.m or b.inertia[2] != motion.J:
                    raise Unsupported(
                        f"n_four_bar: body {n!r} has mass {b.mass} and hinge moment "
                        f"{b.inertia[2]} (inertia[2]); the reference's links have m = "
                        f"{motion.m}, J = {motion.J}"
                    )
            names = motion.names
        else:  # pragma: no cover - kinds are validated by the scenario layer
            raise Unsupported(f"no closed form of kind {kind!r}")
    except (ReferenceNotApplicable, ValueError) as exc:
        raise Unsupported(f"reference {kind}: {exc}") from None
    order = _order(names, scenario.body_names)

    def at(t):
        x, R, v, W = motion.motion(np.asarray(t, dtype=float))
        return x[:, order], R[:, order], v[:, order], W[:, order]

    x0, R0, v0, W0 = (a[0] for a in at(np.zeros(1)))
    _check_initial(scenario, x0, R0, v0, W0, f"reference {kind}")
    return at, motion


#: the scenarios of the cache's keys (content hash -> scenario)
_BY_HASH: dict = {}


@functools.lru_cache(maxsize=16)
def _cached(scenario_hash: str, t_bytes: bytes) -> SystemReference:
    from references import cache

    sc, t = _BY_HASH[scenario_hash], np.frombuffer(t_bytes, dtype=float)
    ref, info = cache.kept("system", sc, t, tolerances(), lambda: _compute(sc, t),
                           _to_entry, _from_entry)  # fmt: skip
    ref.cpu_time_s, ref.wall_time_s = info["cpu_s"] + ref.shared_cpu_s, info["wall_s"]
    return ref


def tolerances() -> dict:
    """The tolerances and bounds a system's reference is computed with, for the reference
    cache's key (:mod:`references.cache`; those of the multibody modules are in their
    source, whose digest the key holds)."""
    return {"INITIAL_TOL": INITIAL_TOL, "HORIZON_ATTITUDE": HORIZON_ATTITUDE,
            "HORIZON_POSITION": HORIZON_POSITION, "REFERENCE_RUNS": REFERENCE_RUNS}  # fmt: skip


#: the fields of a SystemReference kept as the JSON text of a reference cache entry
_FIELDS = ("kind", "accuracy", "accuracy_position", "horizon", "method", "notes",
           "shared_cpu_s")  # fmt: skip


def _to_entry(ref: SystemReference) -> tuple[dict, dict]:
    tr = ref.trajectory
    arrays = {"t": tr.t, "x": tr.position, "v": tr.velocity, "R": tr.rotation,
              "W": tr.omega_body}  # fmt: skip
    fields = {f: getattr(ref, f) for f in _FIELDS} | {"body_names": list(tr.body_names)}
    return arrays, fields


def _from_entry(arrays: dict, fields: dict) -> SystemReference:
    a = arrays
    traj = Trajectory(a["t"], a["x"], a["v"], a["R"], a["W"], tuple(fields["body_names"]))
    for arr in (traj.t, traj.position, traj.velocity, traj.rotation, traj.omega_body):
        arr.setflags(write=False)  # shared by the runs on this grid: nobody may change it
    if not isinstance(fields["notes"], dict):
        raise TypeError("notes is not a table")
    return SystemReference(traj, str(fields["kind"]), float(fields["accuracy"]),
                           float(fields["accuracy_position"]), float(fields["horizon"]),
                           str(fields["method"]), notes=dict(fields["notes"]),
                           shared_cpu_s=float(fields["shared_cpu_s"]))  # fmt: skip


@functools.lru_cache(maxsize=16)
def _stability(scenario_hash: str):
    """The linear stability of a closed form's motion (its Floquet analysis, which does not
    depend on the times asked for), once per process per scenario: the runs of a dt sweep
    save on other grids and would each analyse it again (0.4 s of CPU for spinning_chain);
    with the CPU s (this thread's) it took."""
    c0 = time.thread_time()
    stab = _closed_form(_BY_HASH[scenario_hash])[1].stability()
    return stab, time.thread_time() - c0


def reference(scenario, t) -> SystemReference:
    """The reference of a system scenario at the times ``t`` (s), cached per process by the
    scenario's content (the engines of one scenario share a grid, and a worker process
    receives a new copy of the scenario with each run) and kept across runs in the
    reference cache (:mod:`references.cache`). Raises :class:`Unsupported` when there is
    none (a refusal is not kept)."""
    _BY_HASH.setdefault(scenario.scenario_hash, scenario)
    return _cached(scenario.scenario_hash, np.ascontiguousarray(t, dtype=float).tobytes())


def _compute(scenario, t) -> SystemReference:
    kind = reference_kind(scenario)
    start = time.perf_counter()
    if kind == "none":
        raise Unsupported(
            f"{scenario.name}: no independent reference (the file asks for none); its rows "
            "judge invariants and joint gaps, not trajectory errors"
        )
    if kind != "numerical":
        return _exact(scenario, kind, t, start)
    return _numerical(scenario, t, start)


def _exact(scenario, kind, t, start) -> SystemReference:
    """A closed form with its linear stability (module docstring): on a linearly unstable
    motion the engines' initial state, delta0 from the closed form's, departs from it at the
    growth rate, so trajectory errors are judged only while delta0 exp(lambda t) stays within
    :data:`HORIZON_ATTITUDE` (the tolerance / 10), and the accuracy claimed is that
    distance at the horizon (or the closed form's round-off, whichever is larger)."""
    from references.exact.multibody.stability import trusted_horizon

    at, motion = _closed_form(scenario)
    x, R, v, W = at(t)
    acc = motion.accuracy(t)
    traj = Trajectory(t, x, v, R, W, scenario.body_names)
    horizon, notes = float(t[-1]), {}
    method = f"closed form ({kind}), references.exact.multibody"
    c0 = time.thread_time()
    stab, stab_cpu = _stability(scenario.scenario_hash)
    shared = max(stab_cpu - (time.thread_time() - c0), 0.0)  # done for another grid: its cost
    if stab is None:
        method += "; one degree of freedom: errors of the initial state grow linearly"
    else:
        top = float(abs(stab.multipliers[0]))
        notes = {"growth rate 1/s": stab.growth_rate, "largest Floquet multiplier": top,
                 "period (s)": stab.period}  # fmt: skip
        if stab.unstable:
            th = trusted_horizon(stab.growth_rate, motion.delta0, HORIZON_ATTITUDE, t[-1])
            k = int(np.searchsorted(t, th * (1 + 1e-12), side="right")) - 1
            horizon = float(t[max(k, 0)])
            grown = motion.delta0 * float(np.exp(stab.growth_rate * horizon))
            acc = {"attitude": max(acc["attitude"], grown),
                   "position": max(acc["position"], grown * scenario.length_scale)}  # fmt: skip
            method += (
                f"; linearly unstable: Floquet multiplier {top:.4g} over {stab.period:.4g} s, "
                f"growth rate {stab.growth_rate:.4g} 1/s; the engines' start, "
                f"{motion.delta0:.2g} rad from the closed form's, grows to "
                f"{HORIZON_ATTITUDE:g} rad at t = {th:.4g} s: trusted horizon {horizon:.4g} s "
                f"of {t[-1]:.4g} s"
            )
        else:
            method += f"; linearly stable (Floquet multipliers |mu| <= {top:.6g} over " + (
                f"{stab.period:.4g} s)"
            )
    notes["horizon reason"] = "linearly unstable" if horizon < t[-1] else ""
    return SystemReference(traj, kind, float(acc["attitude"]), float(acc["position"]), horizon,
                           method, time.perf_counter() - start, notes,
                           shared_cpu_s=shared)  # fmt: skip


def _system(scenario):
    """(:class:`~references.exact.multibody.loops.LoopSystem`, q0, u0) of a scenario: its
    bodies, joints, gravity and force elements."""
    from references.exact.multibody.loops import system_from_world

    return system_from_world(scenario.bodies, scenario.joints, scenario.gravity,
                             springs=getattr(scenario, "springs", ()),
                             torques=getattr(scenario, "torques", ()))  # fmt: skip


def _numerical(scenario, t, start) -> SystemReference:
    from references.exact.multibody import ReferenceCostExceeded, solve, trajectory_horizon

    try:
        system, q0, u0 = _system(scenario)
        tree = system.tree
        sol = solve(tree, q0, u0, t, system=system)
        size = scenario.length_scale
        hz = trajectory_horizon(tree, q0, u0, t, HORIZON_ATTITUDE, HORIZON_POSITION * size,
                                system=system)  # fmt: skip
    except ReferenceCostExceeded as exc:
        raise Unsupported(
            f"{scenario.name}: the numerical reference is too costly: {exc}"
        ) from None
    except ValueError as exc:
        raise Unsupported(f"{scenario.name}: the numerical reference refuses: {exc}") from None
    order = _order(sol.names, scenario.body_names)
    traj = Trajectory(t, sol.x[:, order], sol.v[:, order], sol.R[:, order],
                            sol.W[:, order], scenario.body_names)  # fmt: skip
    inside = t <= hz.horizon
    # a run that diverged in its first save has only t = 0: the start, exact (no estimate)
    zero = np.zeros(len(t))
    acc = float(np.max(sol.accuracy_t.get("attitude", zero)[inside]))
    acc_x = float(np.max(sol.accuracy_t.get("position", zero)[inside]))
    method = sol.method + (
        f"; trusted horizon {hz.horizon:.6g} s of {t[-1]:.6g} s (perturbed runs stay within "
        f"{HORIZON_ATTITUDE:g} rad and {HORIZON_POSITION:g} of the size"
        + (")" if hz.within else f"; growth rate {hz.growth_rate:.3g} 1/s)")
    )
    return SystemReference(traj, "numerical", acc, acc_x, float(hz.horizon), method,
                           time.perf_counter() - start,
                           {"growth rate 1/s": hz.growth_rate,
                            "horizon reason": "chaotic motion"})  # fmt: skip


#: the runs of a numerical reference: the solution, its error estimate (10 rtol, halved steps
#: counted twice, two probes) and the horizon's (one run, three probes)
REFERENCE_RUNS = 10


def estimate(scenario) -> tuple[float, str] | None:
    """(seconds, how) the scenario's numerical reference would take (a pilot run,
    :func:`references.exact.multibody.integrate.estimate_cost`), or None for a closed form
    or no reference."""
    if reference_kind(scenario) != "numerical":
        return None
    from references.exact.multibody.integrate import RTOL, _scales, estimate_cost
    from references.exact.multibody.loops import rhs_function

    system, q0, u0 = _system(scenario)
    scale, wscale = _scales(system.tree, q0, u0, system)
    f = rhs_function(system, alpha=wscale)
    return estimate_cost(f, np.concatenate([q0, u0]), scenario.t_end, RTOL, scale,
                         REFERENCE_RUNS)  # fmt: skip


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """The reference at the saved steps, as the ``exact`` engine's system run."""
    from scenarios.schema import step_plan

    if integrator != "reference":
        raise EngineError(f"exact: no integrator {integrator!r} (it has 'reference')")
    _, saves = step_plan(dt, nstep * dt, save_every)
    ref = reference(scenario, saves * dt)
    tr = ref.trajectory
    # its cost: what computing the reference took (its thread's CPU time), whether this
    # process computed it or read it from the reference cache (references.cache)
    cpu, wall = ref.cpu_time_s, ref.wall_time_s
    return SystemResult(
        t=tr.t, x=tr.position, R=tr.rotation, v=tr.velocity, W=tr.omega_body,
        engine_time_s=cpu, timing=Timing(cpu, 0.0, cpu, wall, wall),
        settings={"reference kind": ref.kind, "accuracy": ref.accuracy,
                  "accuracy (position, m)": ref.accuracy_position,
                  "trusted horizon (s)": ref.horizon, "method": ref.method},
    )  # fmt: skip


__all__ = ["SystemReference", "reference", "reference_kind", "simulate_system"]
