"""An engine adapter outside director-bench: scipy's solve_ivp on the Euler-Poisson equations.

The "engine" integrates y = (q (4), W (3), x (3), v (3)): a unit quaternion q = (w, x, y, z)
of the body-to-world rotation R, the body angular velocity W, and the centre of mass x_G and
its velocity (free body) with

    q' = 1/2 q (0, W),    I_p W' = tau - W x I_p W,    x' = v,    v' = g,

I_p the inertia about the centre of mass (free) or about the pivot (pivoted), tau the gravity
torque about the pivot, (-c) x (m R^T g) with c the pivot relative to the centre of mass (zero
for a free body); a pivoted body's centre of mass follows from R, x_G = R com. Fixed steps:
``solve_ivp`` with ``first_step = max_step = dt`` and tolerances so loose that no step is ever
rejected, i.e. the explicit Runge-Kutta method of its tableau at step dt.

It implements the director-bench adapter interface (``references.engines.Engine``): build and
read back the model, set and read the state in the suite's convention, its own energy,
momentum and rotation, native stepping, and a forward-dynamics call, which gives it the
suite's RKMK4 as a third integrator. Its ``scene_builder`` declares the builder that runs
systems of bodies with the two fixed-step methods (:mod:`solve_ivp_system`).
"""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from references.engines import (
    Engine,
    EngineUnavailable,
    Family,
    Integrator,
    ModelReadback,
    SceneBuilder,
    register_family,
)

FAMILY = register_family(
    Family(
        "explicit Runge-Kutta on quaternion coordinates",
        "explicit Runge-Kutta in the vector space of (quaternion, rates); the quaternion is "
        "normalised only when read",
    )
)


def _scipy():
    try:
        from scipy.integrate import solve_ivp
    except ImportError as exc:  # pragma: no cover - scipy is a dependency
        raise EngineUnavailable(f"scipy does not import ({exc}); pip install scipy") from exc
    return solve_ivp


class _Model:
    """The engine's own model of the body: what it was built with."""

    def __init__(self, mdl):
        self.mass = float(mdl.mass)
        self.inertia = np.array(mdl.inertia, dtype=float)
        self.com = np.array(mdl.com, dtype=float)
        self.pivoted = mdl.pivoted
        self.gravity = np.array(mdl.gravity, dtype=float)
        self.dt = float(mdl.dt)
        c = -self.com  # pivot relative to the centre of mass (zeros for a free body)
        self.Ip = np.diag(self.inertia) + self.mass * (c @ c * np.eye(3) - np.outer(c, c))
        self.Ip_inv = np.linalg.inv(self.Ip)
        self.y = None

    def rotation(self, q):
        w, x, y, z = q / np.linalg.norm(q)
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )

    def rates(self, q, W):
        """(dW/dt, torque-free or gravity torque) of the Euler-Poisson equations."""
        tau = -np.cross(W, self.Ip @ W)
        if self.pivoted:
            tau = tau + np.cross(self.com, self.mass * self.rotation(q).T @ self.gravity)
        return self.Ip_inv @ tau

    def rhs(self, _t, y):
        q, W, v = y[0:4], y[4:7], y[10:13]
        w0, w1, w2 = W
        qd = 0.5 * np.array(
            [
                -q[1] * w0 - q[2] * w1 - q[3] * w2,
                q[0] * w0 + q[2] * w2 - q[3] * w1,
                q[0] * w1 + q[3] * w0 - q[1] * w2,
                q[0] * w2 + q[1] * w1 - q[2] * w0,
            ]
        )
        return np.concatenate([qd, self.rates(q, W), v, self.gravity])


class SolveIvpEngine(Engine):
    """scipy's solve_ivp, fixed step, on the Euler-Poisson equations (an example adapter)."""

    name = "solve_ivp"
    description = "example plug-in: scipy solve_ivp on the Euler-Poisson equations, fixed step"
    #: its systems of bodies: solve_ivp_system.simulate_system, imported when a system runs
    scene_builder = SceneBuilder("solve_ivp_system:simulate_system", ("baumgarte",))
    integrators = (
        Integrator(
            "RK45 fixed step",
            FAMILY.name,
            5,
            "scipy's RK45 (Dormand-Prince 5(4), advancing with the 5th-order solution) with "
            "every step forced to dt, on (quaternion, W, x, v) in the vector space.",
            evals_per_step=6.0,
        ),
        Integrator(
            "RK23 fixed step",
            FAMILY.name,
            3,
            "scipy's RK23 (Bogacki-Shampine 3(2), advancing with the 3rd-order solution) with "
            "every step forced to dt, on (quaternion, W, x, v) in the vector space.",
            evals_per_step=3.0,
        ),
        Integrator(
            "RKMK4",
            "4th-order Lie-group",
            4,
            "director-bench's Runge-Kutta-Munthe-Kaas order 4 around this engine's forward "
            "dynamics (the Euler-Poisson right-hand side).",
            stepping="rkmk4",
            evals_per_step=4.0,
        ),
    )

    @classmethod
    def version(cls) -> str:
        _scipy()
        import scipy

        return f"scipy {scipy.__version__}"

    def build(self, ctx) -> None:
        ctx.handle = _Model(ctx.model)

    def read_model(self, ctx) -> ModelReadback:
        m = ctx.handle
        return ModelReadback(
            mass=m.mass,
            inertia=np.diag(m.inertia),
            com=m.com,
            joint="ball" if m.pivoted else "free",
            gravity=m.gravity,
            dt=m.dt,
        )

    def settings(self, ctx) -> dict:
        return {"solve_ivp": "first_step = max_step = dt, rtol = atol = 1e10 (fixed step)"}

    def set_state(self, ctx, state) -> None:
        q = cv.matrix_to_quat_wxyz(state.rotation)
        ctx.handle.y = np.concatenate([q, state.omega_body, state.position, state.velocity])

    def read_state(self, ctx) -> cv.BodyState:
        m = ctx.handle
        q, W = m.y[0:4], m.y[4:7]
        R = cv.quat_wxyz_to_matrix(q)
        if m.pivoted:
            return cv.BodyState(R @ m.com, R @ np.cross(W, m.com), R, W.copy())
        return cv.BodyState(m.y[7:10].copy(), m.y[10:13].copy(), R, W.copy())

    def native_quantities(self, ctx) -> dict:
        """The engine's own energy, momentum and rotation from its own state (its quaternion
        read with its own formula): E = 1/2 W.I_p W (+ 1/2 m v.v free) - m g.x_G,
        L = R I_p W (+ nothing: about the COM for a free body, the pivot when pivoted)."""
        m = ctx.handle
        q, W = m.y[0:4], m.y[4:7]
        R = m.rotation(q)
        if m.pivoted:
            x, v = R @ m.com, np.zeros(3)
        else:
            x, v = m.y[7:10], m.y[10:13]
        return {
            "energy": 0.5 * W @ m.Ip @ W + 0.5 * m.mass * v @ v - m.mass * m.gravity @ x,
            "angular momentum": R @ (m.Ip @ W),
            "rotation": R,
        }

    def advance(self, ctx, k: int) -> None:
        solve_ivp = _scipy()
        m = ctx.handle
        method = ctx.integrator.name.split()[0]
        with ctx.clock:
            sol = solve_ivp(
                m.rhs,
                (0.0, k * ctx.dt),
                m.y,
                method=method,
                first_step=ctx.dt,
                max_step=ctx.dt,
                rtol=1e10,
                atol=1e10,
            )
        m.y = sol.y[:, -1].copy()

    def forward_dynamics(self, ctx, state):
        m = ctx.handle
        q = cv.matrix_to_quat_wxyz(state.rotation)
        with ctx.clock:
            dW = m.rates(q, np.asarray(state.omega_body, dtype=float))
        return dW, m.gravity
