"""The reduced-coordinate reference: DOP853 on the joint-space equations of motion of a tree,
with an error estimate, a cost bound, and the result in world axes per body.

Integration: scipy's DOP853 (Dormand-Prince 8(5,3), Hairer, Nørsett & Wanner 1993) stepped by
hand (so that the number of steps and the wall time are bounded) at rtol = 1e-13, with
atol = rtol times the scale of each component (1 for quaternion components and angles, the
tree's length for positions, the rate scale for joint rates, see :func:`_scales`), and its
dense output at the requested times. Quaternions are integrated as they are: the kinematic
equation q' = q (0, w)/2 keeps |q| constant, so their norm drifts only by the integration
error; they are normalised wherever they are turned into rotations (in the right-hand side and
for output), never fed back into the state.

Error estimate (the same construction as the single-body reference, references/exact/ numerical.py):
the problem is solved at rtol (the solution returned), at 10 rtol, at rtol with every step at most
half the first run's mean step (its dense output is ~2^8 times more accurate), and ``probes`` more
times at rtol from joint rates perturbed in a random direction (fixed seed) by sqrt(nstep) eps times
the rate scale, the round-off accumulated over the run, which near an unstable or chaotic motion is
what the error is made of. Each quantity's estimate is ``SAFETY`` (2) times the largest difference
between the first run and the others (and between the 10 rtol and halved runs), per saved time
(``accuracy_t``) and over all times (``accuracy``): position (m, the largest |x_G| difference over
bodies), attitude (rad, the largest angle of R_a^T R_b over bodies), velocity (m/s), omega (rad/s).
It is an estimate, not a bound; tests/references/exact/test_multibody_reference.py checks it from
both sides (it covers the error of a looser run measured against this one and exceeds it by a
bounded factor).

Cost bound: ``max_steps`` accepted steps per run and ``max_wall`` seconds over all runs; beyond
either, :class:`ReferenceCostExceeded` says which bound, at which time of which run.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import DOP853

from references.exact._util import EPS, rotation_angle
from references.exact.multibody.dynamics import body_states, invariants, rhs_function
from references.exact.multibody.tree import Tree

RTOL = 1e-13

#: Margin on the spread of the runs (module docstring).
SAFETY = 2.0

#: Default cost bounds: accepted DOP853 steps per run, and wall seconds over all runs.
MAX_STEPS = 1_000_000
MAX_WALL = 600.0


class ReferenceCostExceeded(RuntimeError):
    """The reference needed more steps or wall time than its bound (the message says which)."""


@dataclass
class MultibodySolution:
    """The reference at the times ``t`` (n,), per body in tree order (``names``, nb):

    ``x`` (n, nb, 3) centres of mass (m, world), ``R`` (n, nb, 3, 3) body to world (columns
    = principal axes), ``v`` (n, nb, 3) centre-of-mass velocities (m/s, world), ``W``
    (n, nb, 3) body angular velocities (rad/s, body axes); the joint state ``q`` (n, nq)
    (quaternions normalised) and ``u`` (n, nu); ``energy`` (n,) J, ``linear_momentum`` and
    ``angular_momentum`` (about the world origin) (n, 3); ``accuracy`` {quantity: estimated
    largest error over all times} and ``accuracy_t`` {quantity: (n,) per time} for
    "position" (m), "attitude" (rad), "velocity" (m/s), "omega" (rad/s) (module docstring;
    empty when solved without an estimate); ``nstep`` accepted steps and ``nfev``
    evaluations of the main run, ``nfev_total`` over all runs, ``wall_time`` s, ``method``.
    """

    t: np.ndarray
    names: list
    x: np.ndarray
    R: np.ndarray
    v: np.ndarray
    W: np.ndarray
    q: np.ndarray
    u: np.ndarray
    energy: np.ndarray
    linear_momentum: np.ndarray
    angular_momentum: np.ndarray
    accuracy: dict = field(default_factory=dict)
    accuracy_t: dict = field(default_factory=dict)
    nstep: int = 0
    nfev: int = 0
    nfev_total: int = 0
    wall_time: float = 0.0
    method: str = ""
    constraint_residual: float = 0.0


def _scales(tree: Tree, q0, u0, system=None) -> tuple[np.ndarray, float]:
    """Per-component scales of y = (q, u) for atol, and the rate scale (rad/s): the largest
    initial joint rate plus sqrt(|g|/length), the rate gravity can build up, and with the
    force elements of ``system`` (a :class:`~.loops.LoopSystem`) their own rates: a spring's
    sqrt(k / m) on the lighter of its bodies, a torque's sqrt(|tau| / I) on its body's
    smallest principal moment (a system started at rest without gravity has no other)."""
    L = tree.length
    wscale = math.sqrt(float(np.linalg.norm(tree.gravity)) / L)
    if system is not None and system.has_forces:
        sa, sb, _, _, k, _, _, ta, _, _, tau = system.forces
        for a, b, ki in zip(sa, sb, k, strict=True):
            m = tree.mass[a] if b < 0 else min(tree.mass[a], tree.mass[b])
            wscale = max(wscale, math.sqrt(ki / m))
        for a, ti in zip(ta, tau, strict=True):
            wscale = max(wscale, math.sqrt(abs(ti) / float(np.min(tree.inertia[a]))))
    vmax = 0.0
    for b in range(tree.nb):
        uo = tree.uofs[b]
        if tree.kinds[b] == "free":
            vmax = max(vmax, float(np.linalg.norm(u0[uo : uo + 3])))
            wscale = max(wscale, float(np.linalg.norm(u0[uo + 3 : uo + 6])))
        elif tree.kinds[b] == "spherical":
            wscale = max(wscale, float(np.linalg.norm(u0[uo : uo + 3])))
        else:
            wscale = max(wscale, abs(float(u0[uo])))
    wscale = max(wscale, 1e-12)
    sq = np.ones(tree.nq)
    su = np.full(tree.nu, wscale)
    for b in range(tree.nb):
        if tree.kinds[b] == "free":
            sq[tree.qofs[b] : tree.qofs[b] + 3] = L + float(np.linalg.norm(q0[tree.qofs[b] :][:3]))
            su[tree.uofs[b] : tree.uofs[b] + 3] = wscale * L + vmax
    return np.concatenate([sq, su]), wscale


def _run(f, y0, t, rtol, scale, max_step, max_steps, deadline, label):
    """DOP853 from t = 0 to t[-1]; the states at the times t (n, ny), steps, evaluations."""
    out = np.empty((len(t), len(y0)))
    k = 0
    while k < len(t) and t[k] == 0.0:
        out[k] = y0
        k += 1
    if k == len(t):
        return out, 0, 0
    solver = DOP853(f, 0.0, y0, float(t[-1]), rtol=rtol, atol=rtol * scale, max_step=max_step)
    nstep = 0
    while k < len(t):
        msg = solver.step()
        if solver.status == "failed" and getattr(f, "singular", None):
            from references.exact.multibody.loops import LoopSingular

            raise LoopSingular(f.singular)
        if solver.status == "failed":
            raise RuntimeError(
                f"multibody reference ({label}): DOP853 failed at t = {solver.t:.6g} s: {msg}"
            )
        nstep += 1
        if solver.t >= t[k] or solver.status == "finished":
            dense = solver.dense_output()
            while k < len(t) and (t[k] <= solver.t or solver.status == "finished"):
                out[k] = dense(t[k])
                k += 1
        if k < len(t):
            if nstep >= max_steps:
                raise ReferenceCostExceeded(
                    f"multibody reference ({label}): {max_steps} steps reached at t = "
                    f"{solver.t:.6g} s of {t[-1]:.6g} s (bound max_steps)"
                )
            if time.perf_counter() > deadline:
                raise ReferenceCostExceeded(
                    f"multibody reference ({label}): wall-time bound reached at t = "
                    f"{solver.t:.6g} s of {t[-1]:.6g} s (bound max_wall)"
                )
    return out, nstep, solver.nfev


#: the pilot that estimates a run's cost: at most this many steps and this wall time (s)
PILOT_STEPS = 40
PILOT_WALL = 3.0
#: the fewest steps any run takes (a pilot that cannot finish one step assumes this many)
MIN_STEPS = 100


def estimate_cost(f, y0, t_end, rtol, scale, runs: int) -> tuple[float, str]:
    """(seconds, how): the wall time of ``runs`` DOP853 runs of ``f`` from ``y0`` to
    ``t_end``, extrapolated from a pilot run (at most :data:`PILOT_STEPS` steps or
    :data:`PILOT_WALL` s): its wall time per unit of simulated time, times ``t_end``; a
    pilot that cannot take one step in its wall time gives the cost of :data:`MIN_STEPS`
    steps of 12 evaluations at the time of one."""
    f(0.0, y0)  # compiled code is loaded (or compiled) by the first call
    t1 = time.perf_counter()
    f(0.0, y0)
    t_eval = time.perf_counter() - t1
    if t_eval * 12 > PILOT_WALL:
        est = runs * MIN_STEPS * 12 * t_eval
        return est, (f"{t_eval:.3g} s per evaluation of the equations of motion, at least "
                     f"{MIN_STEPS} steps of 12 evaluations per run, {runs} runs")  # fmt: skip
    solver = DOP853(f, 0.0, y0, float(t_end), rtol=rtol, atol=rtol * scale)
    n = 0
    start = time.perf_counter()
    while solver.status == "running" and n < PILOT_STEPS:
        solver.step()
        n += 1
        if time.perf_counter() - start > PILOT_WALL:
            break
    wall = time.perf_counter() - start
    done = max(float(solver.t), 1e-300)
    est = runs * wall * float(t_end) / done
    return est, (f"a pilot of {n} steps reached t = {done:.3g} s in {wall:.3g} s; "
                 f"{runs} runs to t = {float(t_end):.6g} s")  # fmt: skip


def _world(tree, Y):
    """Per-body world states of the joint states Y (n, ny)."""
    n = len(Y)
    x = np.empty((n, tree.nb, 3))
    R = np.empty((n, tree.nb, 3, 3))
    v = np.empty((n, tree.nb, 3))
    W = np.empty((n, tree.nb, 3))
    for i in range(n):
        x[i], R[i], v[i], W[i], _, _ = body_states(tree, Y[i, : tree.nq], Y[i, tree.nq :])
    return x, R, v, W


def _differences(a, b) -> dict:
    """Per-time largest differences over bodies between two world-state tuples."""
    n, nb = a[0].shape[:2]
    ang = rotation_angle(a[1].reshape(-1, 3, 3), b[1].reshape(-1, 3, 3)).reshape(n, nb)
    return {
        "position": np.max(np.linalg.norm(a[0] - b[0], axis=2), axis=1),
        "attitude": np.max(ang, axis=1),
        "velocity": np.max(np.linalg.norm(a[2] - b[2], axis=2), axis=1),
        "omega": np.max(np.linalg.norm(a[3] - b[3], axis=2), axis=1),
    }


def _times(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1 or len(t) == 0 or not np.all(np.isfinite(t)):
        raise ValueError(f"times: expected a non-empty 1-D array of finite values, got {t!r}")
    if t[0] < 0 or np.any(np.diff(t) <= 0):
        raise ValueError("times must be >= 0 and strictly increasing")
    return t


def solve(
    tree: Tree,
    q0,
    u0,
    t,
    rtol: float = RTOL,
    estimate: bool = True,
    probes: int = 2,
    max_steps: int = MAX_STEPS,
    max_wall: float = MAX_WALL,
    seed: int = 0,
    system=None,
) -> MultibodySolution:
    """The motion of ``tree`` from the joint state (``q0`` (nq,), ``u0`` (nu,)) at the times
    ``t`` (s, >= 0, increasing), with the error estimate of the module docstring (``estimate``
    False: one run, no estimate). ``system``: a :class:`~.loops.LoopSystem` on ``tree`` whose
    constraint rows (loop closures) the motion keeps (:mod:`.loops`): the round-off probes
    then perturb the rates within the velocity constraints, and the reference's own largest
    row residual over the run (``constraint_residual``) is added to its position and
    attitude estimates. Raises ``ValueError`` for invalid input (:class:`~.loops.LoopSingular`
    when the loops reach a singular configuration) and :class:`ReferenceCostExceeded` beyond
    ``max_steps`` (per run) or ``max_wall`` (s, all runs).
    """
    q0, u0 = tree.initial_from_joint(q0, u0)
    t = _times(t)
    if not (100 * EPS <= rtol <= 1e-3):
        raise ValueError(
            f"rtol {rtol!r} must be in [{100 * EPS:.3g}, 1e-3] (DOP853 takes no tighter one)"
        )
    start = time.perf_counter()
    deadline = start + max_wall
    y0 = np.concatenate([q0, u0])
    scale, wscale = _scales(tree, q0, u0, system)
    loop = system is not None and system.active
    if loop:
        from references.exact.multibody import loops

        # the rows' drift damped at the system's rate scale (loops module docstring)
        f = loops.rhs_function(system, alpha=wscale)
    else:
        f = rhs_function(tree)
    if math.isfinite(max_wall) and t[-1] > 0:
        runs = 1 + (3 + probes if estimate else 0)
        est, how = estimate_cost(f, y0, float(t[-1]), rtol, scale, runs)
        if est > max_wall:
            raise ReferenceCostExceeded(
                f"multibody reference: estimated {est:.3g} s ({how}), beyond its bound "
                f"max_wall = {max_wall:g} s: refused before running (shorten t_end, or a "
                "system this large has no reference here)"
            )
    Y, nstep, nfev = _run(f, y0, t, rtol, scale, np.inf, max_steps, deadline, "rtol")
    main = _world(tree, Y)
    acc_t: dict = {}
    nfev_total = nfev
    if estimate and t[-1] > 0:
        others = []
        Y10, _, nf = _run(f, y0, t, 10 * rtol, scale, np.inf, max_steps, deadline, "10 rtol")
        nfev_total += nf
        others.append(_world(tree, Y10))
        hmax = 0.5 * float(t[-1]) / max(nstep, 1)
        Yh, _, nf = _run(f, y0, t, rtol, scale, hmax, 4 * max_steps, deadline, "halved steps")
        nfev_total += nf
        others.append(_world(tree, Yh))
        diffs = [_differences(main, o) for o in others] + [_differences(others[0], others[1])]
        rng = np.random.default_rng(seed)
        delta = math.sqrt(max(nstep, 1)) * EPS * wscale
        for i in range(probes):
            d = rng.standard_normal(tree.nu)
            if loop:
                d = loops.project_rates(system, q0, d)
            yp = y0.copy()
            yp[tree.nq :] += delta * d / np.linalg.norm(d)
            Yp, _, nf = _run(f, yp, t, rtol, scale, np.inf, max_steps, deadline, f"probe {i}")
            nfev_total += nf
            diffs.append(_differences(main, _world(tree, Yp)))
        acc_t = {k: SAFETY * np.max([d[k] for d in diffs], axis=0) for k in diffs[0]}
    residual = 0.0
    if loop:
        residual = loops.constraint_residual_max(system, Y[:, : tree.nq])
        if acc_t:
            acc_t["position"] = acc_t["position"] + residual
            acc_t["attitude"] = acc_t["attitude"] + residual / tree.length
    accuracy = {k: float(np.max(a)) for k, a in acc_t.items()}
    inv = [invariants(tree, y[: tree.nq], y[tree.nq :]) for y in Y]
    q = Y[:, : tree.nq].copy()
    for b in range(tree.nb):
        if tree.kinds[b] != "revolute":
            o = tree.qofs[b] + (3 if tree.kinds[b] == "free" else 0)
            q[:, o : o + 4] /= np.linalg.norm(q[:, o : o + 4], axis=1, keepdims=True)
    method = (
        "reduced coordinates (composite-rigid-body + recursive Newton-Euler)"
        + (
            f" with {system.nc} constraint rows (joints {', '.join(system.closure_joints)}; "
            f"index-1, drift damped at {wscale:.3g} 1/s; largest row residual {residual:.3g})"
            if loop
            else ""
        )
        + f", DOP853 at rtol {rtol:g}; {nstep} steps, {nfev} evaluations"
        + (
            f"; error estimate: {SAFETY:g} x the largest difference from runs at 10 rtol, "
            f"with halved steps and {probes} round-off probes"
            if acc_t
            else "; no error estimate"
        )
    )
    return MultibodySolution(
        t=t,
        names=list(tree.names),
        x=main[0],
        R=main[1],
        v=main[2],
        W=main[3],
        q=q,
        u=Y[:, tree.nq :].copy(),
        energy=np.array([d["energy"] for d in inv]),
        linear_momentum=np.array([d["linear_momentum"] for d in inv]),
        angular_momentum=np.array([d["angular_momentum"] for d in inv]),
        accuracy=accuracy,
        accuracy_t=acc_t,
        nstep=nstep,
        nfev=nfev,
        nfev_total=nfev_total,
        wall_time=time.perf_counter() - start,
        method=method,
        constraint_residual=residual,
    )


def solve_from_states(tree: Tree, x, R, v, W, t, **kw) -> MultibodySolution:
    """:func:`solve` from a world state per body (``x``, ``R``, ``v``, ``W`` in tree order, as
    :meth:`Tree.to_joint` takes them); the state must satisfy the joints."""
    q0, u0 = tree.to_joint(x, R, v, W)
    return solve(tree, q0, u0, t, **kw)
