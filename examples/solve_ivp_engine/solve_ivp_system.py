"""The example plug-in's builder of systems of bodies: scipy's solve_ivp on the Newton-Euler
equations of every body with the joints' constraint forces (maximal coordinates).

Each body carries y_b = (q (4), W (3), x (3), v (3)): a unit quaternion q = (w, x, y, z) of its
body-to-world rotation R, its body angular velocity W, its centre of mass x and its velocity
v. With M = diag(m I, I_p) (I_p the principal moments) the accelerations a = (v', W') of all
bodies solve

    M a = f + J^T lambda,    J a = gamma,

f = (m g, -W x I_p W) per body, J the joints' velocity Jacobian and gamma the
velocity-product terms of their second derivatives (minus ``baumgarte`` terms, below);
lambda = (J M^-1 J^T)^+ (gamma - J M^-1 f) (a least-squares solve, so that the redundant rows
of a closed loop do no harm). The joints (each a pair of anchors in the bodies' principal
frames, a world point for the ground):

- ``spherical`` and ``fixed_point``: the anchors coincide, x_a + R_a s_a = x_b + R_b s_b
  (3 rows);
- ``revolute``: the same, and the hinge axes stay parallel, (R_a p_i) . (R_b n_b) = 0 for the
  two unit vectors p_1, p_2 of body a normal to its axis (2 rows);
- other kinds raise :class:`~references.errors.Unsupported`.

Nothing holds the joints but these equations: they drift at the integrator's error, which the
suite measures (joint gaps). The setting ``baumgarte`` = omega (rad/s, default 0: none) adds
-2 omega J u - omega^2 phi to gamma (phi the joints' position residuals), a critically damped
pull back. Fixed steps as for one body (``solve_ivp_engine``): ``first_step = max_step = dt``,
tolerances so loose that no step is rejected.
"""

from __future__ import annotations

import time

import numpy as np

from references import conventions as cv
from references.engines import step_plan
from references.engines.system import SystemResult
from references.errors import Diverged, Unsupported

#: the integrators this builder runs (the adapter's fixed-step scipy methods)
METHODS = {"RK45 fixed step": "RK45", "RK23 fixed step": "RK23"}
#: the joint kinds this builder holds
KINDS = ("spherical", "fixed_point", "revolute")


def _rotations(q):
    """Rotation matrices (nb, 3, 3) of quaternions (nb, 4) (w, x, y, z), normalised first."""
    w, x, y, z = (q / np.linalg.norm(q, axis=1)[:, None]).T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )


def _cross(a, b):
    """a x b of two 3-vectors (np.cross costs ten times more on vectors this small)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


class _System:
    """The bodies' masses and the joints as (kind, a, b, s_a, s_b, p_1, p_2, n_b) with b = -1
    for the ground (s_b and n_b then world)."""

    def __init__(self, scenario, omega: float):
        names = [b.name for b in scenario.bodies]
        idx = {n: i for i, n in enumerate(names)}
        self.nb = len(names)
        self.mass = np.array([float(b.mass) for b in scenario.bodies])
        self.inertia = np.array([np.asarray(b.inertia, float) for b in scenario.bodies])
        self.gravity = np.asarray(scenario.gravity, float)
        self.omega = float(omega)
        self.joints = []
        for j in scenario.joints:
            if j.kind not in KINDS:
                raise Unsupported(
                    f"solve_ivp: joint {j.name!r} is a {j.kind} joint; this builder holds "
                    f"{', '.join(KINDS)} joints"
                )
            a = idx[j.body_a]
            b = -1 if j.body_b is None else idx[j.body_b]
            sa, sb = np.asarray(j.anchor_a, float), np.asarray(j.anchor_b, float)
            p1 = p2 = nb_ = None
            if j.kind == "revolute":
                na = np.asarray(j.axis_a, float) / np.linalg.norm(j.axis_a)
                nb_ = np.asarray(j.axis_b, float) / np.linalg.norm(j.axis_b)
                helper = np.eye(3)[int(np.argmin(np.abs(na)))]
                p1 = np.cross(na, helper)
                p1 /= np.linalg.norm(p1)
                p2 = np.cross(na, p1)
            self.joints.append((j.kind, a, b, sa, sb, p1, p2, nb_))
        self.rows = sum(5 if k == "revolute" else 3 for k, *_ in self.joints)
        # per body: (m g, 1/m) for v' and (gyroscopic term, 1/I_p) for W'
        self.minv = np.concatenate([np.repeat(1.0 / self.mass, 3).reshape(-1, 3),
                                    1.0 / self.inertia], axis=1).reshape(-1)  # fmt: skip
        self.weight = self.mass[:, None] * self.gravity

    def unpack(self, y):
        Y = y.reshape(self.nb, 13)
        return Y[:, 0:4], Y[:, 4:7], Y[:, 7:10], Y[:, 10:13], _rotations(Y[:, 0:4])

    def constraints(self, W, x, v, R):
        """(J (rows, 6 nb), gamma (rows,)) with each body's columns (v', W')."""
        J = np.zeros((self.rows, 6 * self.nb))
        gamma = np.zeros(self.rows)
        r = 0
        w = np.einsum("bij,bj->bi", R, W)  # world angular velocities
        for kind, a, b, sa, sb, p1, p2, nb_ in self.joints:
            sides = [(a, sa, 1.0)] + ([] if b < 0 else [(b, sb, -1.0)])
            phi = -sb.copy() if b < 0 else np.zeros(3)
            dphi = np.zeros(3)
            for body, s, sign in sides:
                c = 6 * body
                J[r : r + 3, c : c + 3] = sign * np.eye(3)
                J[r : r + 3, c + 3 : c + 6] = -sign * R[body] @ _hat(s)
                gamma[r : r + 3] -= sign * R[body] @ _cross(W[body], _cross(W[body], s))
                phi += sign * (x[body] + R[body] @ s)
                dphi += sign * (v[body] + R[body] @ _cross(W[body], s))
            gamma[r : r + 3] -= 2 * self.omega * dphi + self.omega**2 * phi
            r += 3
            if kind != "revolute":
                continue
            N = nb_ if b < 0 else R[b] @ nb_
            wb = np.zeros(3) if b < 0 else w[b]
            for p in (p1, p2):
                P = R[a] @ p
                PxN = _cross(P, N)
                J[r, 6 * a + 3 : 6 * a + 6] = R[a].T @ PxN
                if b >= 0:
                    J[r, 6 * b + 3 : 6 * b + 6] = -R[b].T @ PxN
                rel = w[a] - wb
                gamma[r] = -rel @ (_cross(_cross(w[a], P), N) + _cross(P, _cross(wb, N)))
                gamma[r] -= 2 * self.omega * (rel @ PxN) + self.omega**2 * (P @ N)
                r += 1
        return J, gamma

    def rhs(self, _t, y):
        q, W, x, v, R = self.unpack(y)
        f = np.concatenate([self.weight, -np.cross(W, self.inertia * W)], axis=1).reshape(-1)
        minv = self.minv
        acc = minv * f
        if self.rows:
            J, gamma = self.constraints(W, x, v, R)
            A = (J * minv) @ J.T
            lam = np.linalg.lstsq(A, gamma - J @ acc, rcond=None)[0]
            acc = minv * (f + J.T @ lam)
        acc = acc.reshape(self.nb, 6)
        w0, w1, w2 = W.T
        q0, q1, q2, q3 = q.T
        qd = 0.5 * np.stack(
            [
                -q1 * w0 - q2 * w1 - q3 * w2,
                q0 * w0 + q2 * w2 - q3 * w1,
                q0 * w1 + q3 * w0 - q1 * w2,
                q0 * w2 + q1 * w1 - q2 * w0,
            ],
            1,
        )
        return np.concatenate([qd, acc[:, 3:6], v, acc[:, 0:3]], axis=1).reshape(-1)


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run the system ``scenario`` with ``integrator`` ("RK45 fixed step" or "RK23 fixed
    step") at step ``dt`` for ``nstep`` steps, saving the steps 0, ``save_every``, ...,
    ``nstep``; ``settings``: ``baumgarte`` (rad/s, module docstring)."""
    from scipy.integrate import solve_ivp

    if integrator not in METHODS:
        raise Unsupported(
            f"solve_ivp {integrator}: systems of bodies run with {', '.join(METHODS)} only"
        )
    system = _System(scenario, settings.get("baumgarte", 0.0))
    _, saves = step_plan(dt, nstep * dt, save_every)
    y = np.concatenate(
        [
            np.concatenate(
                [
                    cv.matrix_to_quat_wxyz(np.asarray(b.rotation, float)),
                    b.omega_body,
                    b.position,
                    b.velocity,
                ]
            )  # fmt: skip
            for b in scenario.bodies
        ]
    )
    out = np.empty((len(saves), system.nb, 13))
    out[0] = y.reshape(system.nb, 13)
    clock = 0.0
    for k in range(1, len(saves)):
        steps = int(saves[k] - saves[k - 1])
        t0 = time.perf_counter()
        sol = solve_ivp(
            system.rhs, (0.0, steps * dt), y, method=METHODS[integrator], first_step=dt,
            max_step=dt, rtol=1e10, atol=1e10,
        )  # fmt: skip
        clock += time.perf_counter() - t0
        y = sol.y[:, -1].copy()
        if not np.all(np.isfinite(y)):
            raise Diverged(
                f"solve_ivp {integrator} at dt = {dt:g} s: a non-finite state between t = "
                f"{saves[k - 1] * dt:.6g} and {saves[k] * dt:.6g} s",
                saves[k] * dt,
                _result(saves[:k], dt, out[:k], clock, integrator, system),
            )
        out[k] = y.reshape(system.nb, 13)
    return _result(saves, dt, out, clock, integrator, system)


def _result(saves, dt, out, clock, integrator, system) -> SystemResult:
    """The run's result at the saved steps ``saves`` (``out``: the saved states)."""
    R = _rotations(out[:, :, 0:4].reshape(-1, 4))
    return SystemResult(
        t=saves * float(dt),
        x=out[:, :, 7:10],
        R=R.reshape(len(saves), system.nb, 3, 3),
        v=out[:, :, 10:13],
        W=out[:, :, 4:7],
        engine_time_s=clock,
        settings={
            "solve_ivp": "first_step = max_step = dt, rtol = atol = 1e10 (fixed step)",
            "constraint forces": "least squares of J M^-1 J^T lambda = gamma - J M^-1 f",
            "baumgarte omega (rad/s)": system.omega,
        },
        evals_per_step={"RK45 fixed step": 6.0, "RK23 fixed step": 3.0}[integrator],
    )
