"""The horizon over which a trajectory reference of a (possibly chaotic) system means something.

A numerical reference errs by what its integrator commits at each step (DOP853 keeps the local
error near rtol times each component's scale) and by round-off; the flow then carries those
errors forward, and on a chaotic motion it amplifies them exponentially, until no digit of
the trajectory is left. The reference's own error therefore behaves like the divergence of
runs started from states perturbed by the same amount. :func:`trajectory_horizon` runs the
reference and ``probes`` perturbed copies (initial joint state moved in a random direction,
fixed seed, by ``delta`` times each component's scale, default 10 rtol: the local error the
integrator leaves at a step, with a margin of 10), and returns the first time at which any
copy departs from the reference by more than the tolerance (attitude in rad, or centre-of-mass
position in m, the largest over bodies). Trajectory errors of an engine are to be judged only
inside that horizon; invariants (energy, momenta, joint residuals) over the whole run.

The result also carries the divergence curve and the growth rate fitted to its logarithm over
the part between 1e3 delta and the tolerance (a finite-time Lyapunov exponent, 1/s; nan when
the divergence does not grow that much).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from references.exact.multibody.dynamics import rhs_function
from references.exact.multibody.integrate import (
    MAX_WALL,
    RTOL,
    MultibodySolution,
    _differences,
    _run,
    _scales,
    _world,
    solve,
)


@dataclass
class Horizon:
    """``horizon`` (s): the first saved time at which a perturbed run departs by more than the
    tolerance (``t[-1]`` and ``within`` True when none does); ``divergence`` {"attitude",
    "position"}: (n,) the largest departure over the probes per saved time; ``delta`` the
    relative perturbation; ``growth_rate`` (1/s) fitted as the module docstring says;
    ``reference`` the unperturbed :class:`MultibodySolution` (without an error estimate)."""

    horizon: float
    within: bool
    t: np.ndarray
    divergence: dict
    delta: float
    growth_rate: float
    tol_attitude: float
    tol_position: float
    reference: MultibodySolution


def trajectory_horizon(
    tree,
    q0,
    u0,
    t,
    tol_attitude: float,
    tol_position: float = math.inf,
    delta: float | None = None,
    probes: int = 3,
    rtol: float = RTOL,
    seed: int = 1,
    max_wall: float = MAX_WALL,
    system=None,
) -> Horizon:
    """Horizon of the reference of ``tree`` from (``q0``, ``u0``) over the times ``t``
    (module docstring). ``tol_attitude`` rad, ``tol_position`` m (inf: attitude only)."""
    if not tol_attitude > 0 or not tol_position > 0:
        raise ValueError(
            f"tolerances must be > 0, got attitude {tol_attitude!r}, position {tol_position!r}"
        )
    delta = 10.0 * rtol if delta is None else float(delta)
    ref = solve(tree, q0, u0, t, rtol=rtol, estimate=False, max_wall=max_wall, system=system)
    main = (ref.x, ref.R, ref.v, ref.W)
    q0, u0 = tree.initial_from_joint(q0, u0)
    y0 = np.concatenate([q0, u0])
    scale, wscale = _scales(tree, q0, u0, system)
    loop = system is not None and system.active
    if loop:
        from references.exact.multibody import loops

        f = loops.rhs_function(system, alpha=wscale)
    else:
        f = rhs_function(tree)
    rng = np.random.default_rng(seed)
    div = {"attitude": np.zeros(len(ref.t)), "position": np.zeros(len(ref.t))}
    deadline = time.perf_counter() + max_wall
    for i in range(probes):
        d = rng.standard_normal(len(y0))
        if loop:
            # the positions stay on the loops: the rates are perturbed within the velocity
            # constraints (by delta times their scale)
            d[: tree.nq] = 0.0
            d[tree.nq :] = loops.project_rates(system, q0, d[tree.nq :])
        yp = y0 + delta * scale * d / np.linalg.norm(d)
        Yp, _, _ = _run(f, yp, ref.t, rtol, scale, np.inf, 10**7, deadline, f"horizon probe {i}")
        dd = _differences(main, _world(tree, Yp))
        for k in div:
            div[k] = np.maximum(div[k], dd[k])
    out = (div["attitude"] > tol_attitude) | (div["position"] > tol_position)
    within = not bool(np.any(out))
    horizon = float(ref.t[-1]) if within else float(ref.t[int(np.argmax(out))])
    # growth rate of the attitude divergence between 1e3 delta and the tolerance
    a = div["attitude"]
    sel = (a > 1e3 * delta) & (a < tol_attitude) & (ref.t <= horizon)
    if np.count_nonzero(sel) >= 5:
        growth = float(np.polyfit(ref.t[sel], np.log(a[sel]), 1)[0])
    else:
        growth = math.nan
    return Horizon(
        horizon=horizon,
        within=within,
        t=ref.t,
        divergence=div,
        delta=delta,
        growth_rate=growth,
        tol_attitude=tol_attitude,
        tol_position=tol_position,
        reference=ref,
    )
