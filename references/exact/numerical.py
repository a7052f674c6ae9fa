"""High-accuracy numerical reference for any scenario (free or pivoted, any body), with its
own error estimate.

Equations (body axes): I_p W' = tau - W x (I_p W), with I_p the inertia about the centre of mass
(free body) or about the pivot, I + m(|c|^2 1 - c c^T) (pivoted body, c = pivot in body axes
relative to the centre of mass), and tau the gravity torque about the pivot,
tau = (-c) x (m R^T g) (zero for a free body: uniform gravity does not torque about the centre
of mass). Attitude by the unit quaternion q (w, x, y, z), q' = 1/2 q (0, W). The quaternion is
integrated as it is (its norm drifts only by the integration error) and normalised when
converted to R for the torque and for output: this re-normalisation happens only inside the
reference. A free body's centre of mass follows the exact parabola x0 + v0 t + g t^2/2; a
pivoted body's follows from the rotation, x_G = -R c.

Integrator: DOP853 (scipy.integrate.solve_ivp, Dormand-Prince 8(5,3)) with dense output at the
requested times, rtol = 1e-13 and atol = rtol times the scale of each component.

Error estimate: the problem is solved six times, at rtol (the solution returned), at 10 rtol, at
rtol with every step at most half the first run's mean step (step halving), and three times at rtol
from initial rates perturbed along each body axis by delta = sqrt(nstep) eps |W| (the size of the
round-off accumulated over nstep steps). ``accuracy`` is twice the largest difference between the
first run and the others (and between the 10 rtol and halved runs), as the angle of R_a^T R_b in rad
over the saved times; ``omega_accuracy`` likewise for the body rates. Why each run: where truncation
dominates, the error scales about linearly with rtol and the 10 rtol run bounds the others. On slow
motions taken in a few long steps the dense output (the interpolant between steps) is less accurate
than the steps themselves and all tolerances share that error; the halved run's interpolant is ~2^7
times better, so its difference is the first run's error. Near an unstable motion (the Dzhanibekov
separatrix) every run's error is amplified round-off, of a size and direction that differ from run
to run and are nearly independent of rtol (measured: 4e-11 rad in the rtol, 10 rtol and halved runs
alike, while their mutual differences were 2e-11); the perturbed runs are three more such
realisations (a single perturbation along (1, -1, 1) was measured to be nearly normal to the growing
direction there and to give half the error: hence three axes, and the factor 2). Measured
estimate/error: 2.8 .. 35 (attitude and rates) on the library and 60 random bodies and tops;
tests/references/exact/test_exact_accuracy.py checks it from both sides against the closed forms. It
is an estimate, not a bound.

Cost bound: the six solutions together take at most ``max_steps`` steps and ``max_seconds`` of
wall time (defaults :data:`MAX_STEPS` and :data:`MAX_SECONDS`, or the environment variables
``DIRECTOR_BENCH_REFERENCE_MAX_STEPS`` and ``DIRECTOR_BENCH_REFERENCE_MAX_SECONDS``). A
motion that needs more is refused before any work when even a lower estimate of its steps
(one step per radian turned, in each solution; the library's motions take 1 to 6) exceeds
the bound, else stopped when a bound is reached: :class:`ReferenceCostExceeded` (an
``Unsupported``) names the bound, the figures and how to raise it.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from references.conventions import matrix_to_quat_wxyz, quats_wxyz_to_matrices
from references.errors import Unsupported
from references.exact._util import EPS, rotation_angle

RTOL = 1e-13

#: Margin applied to the spread of the runs (see the module docstring).
SAFETY = 2.0

#: Default bound on the steps of the six solutions together: 165 times the costliest in the
#: library (heavy_top: 12 100 steps), about 10 minutes of a 2026 core at 12 evaluations of a
#: ~25 us right-hand side per step.
MAX_STEPS = 2_000_000

#: Default bound on the wall time of the six solutions together (s).
MAX_SECONDS = 900.0

#: DOP853 evaluates the right-hand side 12 times per step.
EVALS_PER_STEP = 12

#: Solutions computed per reference (the main one and the five of the error estimate).
SOLUTIONS = 6


class ReferenceCostExceeded(Unsupported):
    """The numerical reference needs more steps or time than its bound allows; the message
    says which bound, the figures, and how to raise it."""


def _bound(env: str, default: float, given: float | None) -> float:
    if given is not None:
        return float(given)
    text = os.environ.get(env)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not value > 0:
        raise ValueError(f"{env}={text!r}: must be a number > 0")
    return value


class _Budget:
    """The steps and seconds left to the solutions of one reference (checked every 12
    right-hand-side evaluations: once per step)."""

    def __init__(self, name: str, t_end: float, max_steps: float, max_seconds: float):
        self.name, self.t_end = name, t_end
        self.max_steps, self.max_seconds = max_steps, max_seconds
        self.start = time.monotonic()
        self.nfev = 0
        self.solution = 1

    def charge(self, t: float) -> None:
        self.nfev += 1
        if self.nfev % EVALS_PER_STEP:
            return
        steps = self.nfev / EVALS_PER_STEP
        elapsed = time.monotonic() - self.start
        where = f"at t = {t:.3g} s of {self.t_end:.3g} s in solution {self.solution}"
        if steps > self.max_steps:
            self.stop(f"step bound: {steps:.3g} steps > {self.max_steps:.3g}, {where}", "STEPS")
        if elapsed > self.max_seconds:
            what = f"time bound: {elapsed:.3g} s > {self.max_seconds:.3g} s, {where}"
            self.stop(what, "SECONDS")

    def stop(self, what: str, env: str) -> None:
        raise ReferenceCostExceeded(
            f"scenario {self.name!r}: the numerical reference (DOP853 at rtol {RTOL:g}, "
            f"{SOLUTIONS} solutions) reached its {what}; the run cannot be judged against it: "
            "shorten the horizon (--t-end), or raise the bound with the environment variable "
            f"DIRECTOR_BENCH_REFERENCE_MAX_{env}"
        )


@dataclass
class NumericalSolution:
    t: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    accuracy: float
    omega_accuracy: float
    nfev: int


def _solve(Ip, Ip_inv, torque_arm_mg, y0, t_eval, rtol, scale, budget, max_step=np.inf):
    Ip = np.asarray(Ip)
    a = torque_arm_mg  # tau = (-c) x (m R^T g) = cross(-c, R^T (m g)) : a = (-c, m g)
    c_neg, mg = a
    has_torque = c_neg is not None and bool(np.any(c_neg != 0)) and bool(np.any(mg != 0))
    I00, I01, I02, I10, I11, I12, I20, I21, I22 = Ip.ravel()
    J00, J01, J02, J10, J11, J12, J20, J21, J22 = Ip_inv.ravel()
    if has_torque:
        cx, cy, cz = c_neg
        gx, gy, gz = mg

    def rhs(_t, y):
        budget.charge(_t)
        w1, w2, w3, qw, qx, qy, qz = y
        # angular momentum about the pivot / centre of mass, and gyroscopic torque -W x (Ip W)
        p1 = I00 * w1 + I01 * w2 + I02 * w3
        p2 = I10 * w1 + I11 * w2 + I12 * w3
        p3 = I20 * w1 + I21 * w2 + I22 * w3
        t1 = -(w2 * p3 - w3 * p2)
        t2 = -(w3 * p1 - w1 * p3)
        t3 = -(w1 * p2 - w2 * p1)
        if has_torque:
            n = qw * qw + qx * qx + qy * qy + qz * qz
            s = 2.0 / n
            # R^T (m g): rows of R^T are the columns of R
            b1 = (1 - s * (qy * qy + qz * qz)) * gx + s * (qx * qy + qw * qz) * gy
            b1 += s * (qx * qz - qw * qy) * gz
            b2 = s * (qx * qy - qw * qz) * gx + (1 - s * (qx * qx + qz * qz)) * gy
            b2 += s * (qy * qz + qw * qx) * gz
            b3 = s * (qx * qz + qw * qy) * gx + s * (qy * qz - qw * qx) * gy
            b3 += (1 - s * (qx * qx + qy * qy)) * gz
            t1 += cy * b3 - cz * b2
            t2 += cz * b1 - cx * b3
            t3 += cx * b2 - cy * b1
        return [
            J00 * t1 + J01 * t2 + J02 * t3,
            J10 * t1 + J11 * t2 + J12 * t3,
            J20 * t1 + J21 * t2 + J22 * t3,
            0.5 * (-qx * w1 - qy * w2 - qz * w3),
            0.5 * (qw * w1 + qy * w3 - qz * w2),
            0.5 * (qw * w2 + qz * w1 - qx * w3),
            0.5 * (qw * w3 + qx * w2 - qy * w1),
        ]

    tmax = float(t_eval[-1])
    if tmax == 0.0:
        return np.array(y0)[:, None] * np.ones((1, len(t_eval))), 0
    sol = solve_ivp(
        rhs,
        (0.0, tmax),
        y0,
        method="DOP853",
        t_eval=t_eval,
        rtol=rtol,
        atol=rtol * scale,
        max_step=max_step,
    )
    if sol.status != 0:
        raise RuntimeError(f"numerical reference failed: {sol.message}")
    budget.solution += 1
    return sol.y, sol.nfev


def solve(
    scenario,
    t,
    rtol: float = RTOL,
    max_steps: float | None = None,
    max_seconds: float | None = None,
) -> NumericalSolution:
    """Rotation and body rates of ``scenario`` at the sorted, non-negative times ``t``, with the
    error estimate described in the module docstring, within the cost bound ``max_steps`` and
    ``max_seconds`` (None: the environment's or the defaults; :class:`ReferenceCostExceeded`
    beyond them)."""
    t_all = np.asarray(t, dtype=float)
    if t_all.ndim != 1 or len(t_all) == 0 or np.any(np.diff(t_all) < 0) or t_all[0] < 0:
        raise ValueError("times must be a non-empty, sorted 1-D array of values >= 0")
    t, inverse = np.unique(t_all, return_inverse=True)  # solve_ivp wants distinct times
    Ip = scenario.pivot_inertia
    Ip_inv = np.linalg.inv(Ip)
    if scenario.pivot is not None:
        arm = (-np.asarray(scenario.pivot), scenario.mass * np.asarray(scenario.gravity))
    else:
        arm = (None, None)
    W0 = np.asarray(scenario.omega_body)
    y0 = np.concatenate([W0, matrix_to_quat_wxyz(scenario.rotation)])
    # scale of W: the initial rate plus the rate a gravity torque can build up, sqrt(m g l/I)
    wscale = float(np.linalg.norm(W0))
    if arm[0] is not None:
        tq = float(np.linalg.norm(arm[0]) * np.linalg.norm(arm[1]))
        wscale += math.sqrt(tq / float(np.min(np.linalg.eigvalsh(Ip))))
    wscale = max(wscale, 1e-12)
    scale = np.array([wscale] * 3 + [1.0] * 4)
    budget = _Budget(
        scenario.name,
        float(t[-1]),
        _bound("DIRECTOR_BENCH_REFERENCE_MAX_STEPS", MAX_STEPS, max_steps),
        _bound("DIRECTOR_BENCH_REFERENCE_MAX_SECONDS", MAX_SECONDS, max_seconds),
    )
    least = SOLUTIONS * float(np.linalg.norm(W0)) * float(t[-1])  # one step per radian
    if not least <= budget.max_steps:
        budget.stop(
            f"step bound before any step: |W0| t_end = {least / SOLUTIONS:.3g} rad needs at "
            f"least {least:.3g} steps (one per radian turned, in each of the {SOLUTIONS} "
            f"solutions) > {budget.max_steps:.3g}",
            "STEPS",
        )
    runs = [_solve(Ip, Ip_inv, arm, y0, t, f * rtol, scale, budget) for f in (1.0, 10.0)]
    nstep = max(runs[0][1] / 12.0, 1.0)  # DOP853: 12 evaluations per step
    # step halving: the same rtol with every step at most half the main run's mean step, so
    # that its dense output (interpolation between steps, less accurate than the steps) is
    # far better than the main run's
    half = 0.5 * float(t[-1]) / nstep
    runs.append(_solve(Ip, Ip_inv, arm, y0, t, rtol, scale, budget, max_step=half))
    Rs = [quats_wxyz_to_matrices(y[3:].T) for y, _ in runs]
    Ws = [y[:3].T for y, _ in runs]
    acc = wacc = 0.0
    for i, j in ((0, 1), (0, 2), (1, 2)):
        acc = max(acc, float(np.max(rotation_angle(Rs[i], Rs[j]))))
        wacc = max(wacc, float(np.max(np.abs(Ws[i] - Ws[j]))))
    # round-off probes: W0 perturbed along each body axis by the accumulated round-off,
    # delta = sqrt(nstep) eps |W|. Where the motion amplifies small errors (the Dzhanibekov
    # separatrix) every run's error is such an amplified round-off, of a size and direction
    # that differ from run to run; the probes are three more such realisations
    delta = math.sqrt(nstep) * EPS * wscale
    nfev_probe = 0
    for axis in range(3):
        y0p = y0.copy()
        y0p[axis] += delta
        yp, nfp = _solve(Ip, Ip_inv, arm, y0p, t, rtol, scale, budget)
        nfev_probe += nfp
        acc = max(acc, float(np.max(rotation_angle(Rs[0], quats_wxyz_to_matrices(yp[3:].T)))))
        wacc = max(wacc, float(np.max(np.abs(Ws[0] - yp[:3].T))))
    acc *= SAFETY
    wacc *= SAFETY
    nfev = sum(nf for _, nf in runs) + nfev_probe
    return NumericalSolution(t_all, Rs[0][inverse], Ws[0][inverse], acc, wacc, nfev)
