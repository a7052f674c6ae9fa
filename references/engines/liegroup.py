"""The suite's Runge-Kutta-Munthe-Kaas integrator of order 4 (RKMK4): a stepping strategy that
any engine with a forward-dynamics call can use (``Integrator(stepping="rkmk4")``; Pinocchio
and DART, which have no 4th-order Lie-group integrator of their own, use it).

The engine supplies only the acceleration (:meth:`Engine.forward_dynamics`). The state is
(q, v): q on a Lie group G, v in its Lie algebra, with the right-trivialised kinematics
q' = q v (body-frame velocities), and v' = a(q, v) from the engine's forward dynamics. For a
free body G = SO(3) x R^3 with q = (R, x_G), v = (W, v_G); for a pivoted one G = SO(3).

RKMK writes q(t) = q0 exp(theta(t)) and integrates the algebra-valued ODE

    theta' = dexpinv(theta, v),    v' = a(q0 exp(theta), v),    theta(0) = 0

with the classical 4-stage Runge-Kutta tableau. ``dexpinv(theta, v)`` solves
J_r(theta) theta' = v with J_r the right Jacobian of exp (the derivative of
integrate(q, theta) with respect to theta). With the exact dexpinv the method keeps the order 4
of the tableau on the group (Munthe-Kaas, BIT 38 (1998) and Appl. Numer. Math. 29 (1999)).
Skipping dexpinv (stages q_i = q0 exp(c_i h v_i)) leaves a method of order 2 in attitude, as
measured in docs/engines.md.

The code is ours; the engines contribute only the accelerations.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from references.conventions import BodyState, rotvec_to_matrix
from references.errors import EngineError, StepFailure


class StageRotationTooLarge(StepFailure):
    """A Runge-Kutta stage asked for a rotation of half a turn or more: beyond it exp is not
    one-to-one and dexp^{-1} becomes singular at a full turn, so the step size is far outside
    anything meaningful (the explicit method is unstable long before). Adapters turn this into
    a :class:`~references.errors.StepFailure`."""


def check_stage_rotation(a2: float) -> None:
    """Raise :class:`StageRotationTooLarge` unless the squared rotation angle a2 < pi^2."""
    if not a2 < math.pi**2:
        raise StageRotationTooLarge(
            f"a Runge-Kutta stage rotation of {math.sqrt(a2):.3g} rad (>= pi, or not finite)"
        )


def so3_right_jacobian_inverse(theta) -> np.ndarray:
    """J_r(theta)^{-1} for SO(3): the matrix with theta' = J_r^{-1} W when R = R0 exp(hat theta)
    and W is the body angular velocity of R.

    J_r^{-1} = 1 + hat(theta)/2 + (1/a^2 - (1 + cos a)/(2 a sin a)) hat(theta)^2, a = |theta|,
    with the series 1/12 + a^2/720 + a^4/30240 of the last coefficient for small a.
    """
    x, y, z = (float(t) for t in np.ravel(theta))
    a2 = x * x + y * y + z * z
    check_stage_rotation(a2)
    if a2 < 1e-6:
        c = 1.0 / 12.0 + a2 / 720.0 + a2 * a2 / 30240.0
    else:
        a = math.sqrt(a2)
        c = 1.0 / a2 - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    # 1 + K/2 + c K^2 with K = hat(theta) and K^2 = theta theta^T - a^2 1, in scalars.
    return np.array(
        [
            [1.0 - c * (y * y + z * z), c * x * y - 0.5 * z, c * x * z + 0.5 * y],
            [c * x * y + 0.5 * z, 1.0 - c * (x * x + z * z), c * y * z - 0.5 * x],
            [c * x * z - 0.5 * y, c * y * z + 0.5 * x, 1.0 - c * (x * x + y * y)],
        ]
    )


def so3_r3_integrate(q, theta):
    """Group operation of SO(3) x R^3 for a state q = (R, x): (R exp(hat theta_r), x + theta_x).

    Used for a free body whose translation is integrated in world axes, theta = (theta_r,
    theta_x) with 6 entries; for a pivoted body q = (R,) and theta has 3 entries."""
    R = q[0] @ rotvec_to_matrix(theta[:3])
    if len(q) == 1:
        return (R,)
    return (R, q[1] + theta[3:6])


def so3_r3_dexpinv(theta, v) -> np.ndarray:
    """dexpinv on SO(3) x R^3: the rotational part through J_r^{-1}, the translation as is."""
    out = np.array(v, dtype=float)
    out[:3] = so3_right_jacobian_inverse(theta[:3]) @ out[:3]
    return out


def rkmk4_step(
    q,
    v: np.ndarray,
    h: float,
    accel: Callable,
    integrate: Callable,
    dexpinv: Callable,
):
    """One RKMK4 step of size h from (q, v); returns (q_new, v_new).

    ``accel(q, v)`` -> dv/dt; ``integrate(q, theta)`` -> q exp(theta);
    ``dexpinv(theta, v)`` -> J_r(theta)^{-1} v. ``v`` and the outputs are arrays of the
    algebra's dimension; ``q`` is whatever ``integrate`` accepts.
    """
    k1t = v
    k1v = accel(q, v)

    th = 0.5 * h * k1t
    v2 = v + 0.5 * h * k1v
    k2t = dexpinv(th, v2)
    k2v = accel(integrate(q, th), v2)

    th = 0.5 * h * k2t
    v3 = v + 0.5 * h * k2v
    k3t = dexpinv(th, v3)
    k3v = accel(integrate(q, th), v3)

    th = h * k3t
    v4 = v + h * k3v
    k4t = dexpinv(th, v4)
    k4v = accel(integrate(q, th), v4)

    theta = (h / 6.0) * (k1t + 2.0 * k2t + 2.0 * k3t + k4t)
    v_new = v + (h / 6.0) * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
    return integrate(q, theta), v_new


class RKMK4Stepper:
    """The RKMK4 stepping strategy of :meth:`Engine.run`: the state lives here, in the suite's
    convention; the engine is asked for accelerations (four forward-dynamics calls a step)."""

    def __init__(self, engine, ctx):
        self.engine = engine
        self.ctx = ctx
        self.pivoted = ctx.model.pivoted

    def start(self, state: BodyState) -> None:
        # the engine holds the initial state too: the initial check reads it back from there
        self.engine.set_state(self.ctx, state)
        if self.pivoted:
            self.q, self.u = (np.array(state.rotation),), np.array(state.omega_body)
        else:
            self.q = (np.array(state.rotation), np.array(state.position))
            self.u = np.concatenate([state.omega_body, state.velocity])

    def _accel(self, q, u) -> np.ndarray:
        if self.pivoted:
            st = self.ctx.model.state_from_rotation(q[0], u)
            return np.asarray(self.engine.forward_dynamics(self.ctx, st)[0], dtype=float)
        st = BodyState(q[1], u[3:], q[0], u[:3])
        dW, a = self.engine.forward_dynamics(self.ctx, st)
        return np.concatenate([dW, a])

    def run(self, steps: list[int]) -> BodyState:
        from references.conventions import stack_states

        h = self.ctx.dt
        out = []
        taken = 0
        for k in steps:
            for _ in range(k):
                try:
                    self.q, self.u = rkmk4_step(
                        self.q, self.u, h, self._accel, so3_r3_integrate, so3_r3_dexpinv
                    )
                except StepFailure as exc:
                    exc.steps_taken = taken
                    exc.states = stack_states(out) if out else None
                    raise
                taken += 1
            self.ctx.nevals += 4 * k
            out.append(self.state())
        return stack_states(out)

    def state(self) -> BodyState:
        if self.pivoted:
            return self.ctx.model.state_from_rotation(self.q[0], self.u)
        return BodyState(self.q[1], self.u[3:], self.q[0], self.u[:3])


def direct(fn):
    """The compiled code of the numba function ``fn`` (compiled for exactly one signature),
    called without numba's type dispatch, which costs about half a microsecond a call: a
    tenth of a stage of the RKMK4. Only for arguments of that signature made by the suite:
    float64 arrays it allocated (C-contiguous, as the signature says; the compiled entry
    does not check contiguity) or whose layout :func:`check_engine_vector` checked, and
    Python scalars. ``fn`` itself when it has another number
    of signatures, or when it is not compiled (``NUMBA_DISABLE_JIT=1``)."""
    signatures = getattr(fn, "signatures", ())
    if len(signatures) != 1:
        return fn
    return fn.overloads[signatures[0]].entry_point


def check_engine_vector(a, n: int, what: str) -> None:
    """Raise :class:`EngineError` unless ``a`` (an array an engine returned) has the layout of
    the suite's own float64 vectors of ``n`` entries (C-contiguous), so that it may be handed
    to the compiled entry of :func:`direct`. The layout is fixed by the engine binding's return
    type, not by the values: checked on the first array a run receives."""
    if not (
        isinstance(a, np.ndarray)
        and a.dtype == np.float64
        and a.shape == (n,)
        and a.flags.c_contiguous
        and a.flags.aligned
    ):
        layout = (
            f"{a.dtype} {a.shape} strides {a.strides}" if isinstance(a, np.ndarray) else type(a)
        )
        raise EngineError(
            f"{what} returned {layout}, not a C-contiguous float64 vector of {n} entries; "
            "the compiled unpacking of the RKMK4 stages reads only that layout"
        )


#: what the first run of the suite's RKMK4 in a process compiles (numba's cache then serves
#: later processes), named by the progress display while it lasts
RKMK4_WARM_UP = "the RKMK4 stages (numba)"


def unpack_state(model, y: np.ndarray) -> BodyState:
    """The ``BodyState`` of the compiled stepper's flat state ``y`` (13,): unit quaternion
    (w, x, y, z), x_G, W (body axes), v_G; for a pivoted ``model`` (a
    :class:`~references.engines.context.BodyModel`) x_G and v_G follow from R and W."""
    from references.conventions import quat_wxyz_to_matrix

    R = quat_wxyz_to_matrix(y[0:4])
    W = y[7:10].copy()
    if model.pivoted:
        return model.state_from_rotation(R, W)
    return BodyState(y[4:7].copy(), y[10:13].copy(), R, W)


class StagedDynamics(NamedTuple):
    """An adapter's engine bound for :class:`CompiledRKMK4Stepper` with the packing of its
    stages compiled into the stage arithmetic (:meth:`Engine.staged_dynamics
    <references.engines.interface.Engine.staged_dynamics>`): per stage one compiled call and
    the engine's.

    - ``workspace``: the stepper's state, stage state, slopes and the engine's buffers in
      one array (``_rkmk4.STAGED_WORKSPACE``; the buffers are views of it bound in ``call``);
    - ``stage(i, workspace, h, pivoted, a)``: the previous stage's accelerations unpacked
      from the engine's vector ``a`` (i > 0), stage i's state computed and packed into the
      buffers; returns ``_rkmk4.OK`` or ``TOO_LARGE`` (e.g. ``_rkmk4.dart_stage``);
    - ``finish(workspace, h, pivoted, a)``: the last stage's ``a`` unpacked, the step
      finished and, when it succeeded, the next step's stage 0 packed into the buffers;
    - ``call()``: the engine's calls on the buffers (timed on the run's clock, and only
      they), returning its accelerations ``a``;
    - ``size``, ``what``: the length of ``a``, and the engine call's name, for the check
      of its layout (:func:`check_engine_vector`) on the run's first call."""

    workspace: np.ndarray
    stage: Callable
    finish: Callable
    call: Callable
    size: int
    what: str


class CompiledRKMK4Stepper:
    """The same RKMK4 with the state in one flat array (rotation as a unit quaternion) and the
    stage arithmetic compiled (:mod:`references.engines._rkmk4`): per step four calls of the
    engine and five small compiled calls, so that the cost is the engine's, not the suite's
    Python. With the adapter's :class:`StagedDynamics` (``staged_dynamics(ctx)``), each
    compiled stage also packs the engine's input and unpacks its accelerations; otherwise
    it calls the function ``fd(z, acc)`` of the adapter's ``packed_dynamics(ctx)`` (z the
    flat stage state, acc the 6 accelerations to fill), whose default builds a BodyState
    per stage for ``forward_dynamics``. The run loop uses this stepper; RKMK4Stepper is the
    readable reference it is tested against."""

    def __init__(self, engine, ctx):
        from references.engines import _rkmk4

        _rkmk4.warm_up()
        self.engine, self.ctx, self.k = engine, ctx, _rkmk4
        self.pivoted = bool(ctx.model.pivoted)
        # y (the state), z (a stage's state) and acc (its accelerations): views of one array
        self.staged = engine.staged_dynamics(ctx)
        if self.staged is None:
            self.w, self.K = np.zeros(_rkmk4.WORKSPACE), np.zeros((4, 12))
            self.fd = engine.packed_dynamics(ctx)
        else:  # the slopes and the engine's buffers in the same array
            self.w = self.staged.workspace
            self.K, self.fd = self.w[_rkmk4.KS].reshape(4, 12), None
        self.y, self.z, self.acc = self.w[_rkmk4.Y], self.w[_rkmk4.Z], self.w[_rkmk4.ACC]
        self.checked = False

    def start(self, state: BodyState) -> None:
        from references.conventions import matrix_to_quat_wxyz

        self.engine.set_state(self.ctx, state)
        self.y[0:4] = matrix_to_quat_wxyz(state.rotation)
        self.y[7:10] = state.omega_body
        if not self.pivoted:
            self.y[4:7] = state.position
            self.y[10:13] = state.velocity

    def _as_state(self, y) -> BodyState:
        return unpack_state(self.ctx.model, y)

    def run(self, steps: list[int]) -> BodyState:
        if self.staged is not None:
            return self._run_staged(steps)
        stage, finish = direct(self.k.stage), direct(self.k.finish)  # w and K are ours
        w, y, z, K, acc = self.w, self.y, self.z, self.K, self.acc
        h, piv = self.ctx.dt, self.pivoted
        fd, ctx = self.fd, self.ctx
        rows = np.empty((len(steps), 13))
        taken = 0
        for j, n in enumerate(steps):
            for _ in range(n):
                # the four stages written out (stage 0 never fails: it only copies y)
                stage(0, w, K, h, piv)
                fd(z, acc)
                if stage(1, w, K, h, piv):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                fd(z, acc)
                if stage(2, w, K, h, piv):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                fd(z, acc)
                if stage(3, w, K, h, piv):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                fd(z, acc)
                if finish(w, K, h, piv):
                    raise self._failure("a Runge-Kutta step rotation >= pi", taken, rows[:j])
                taken += 1
            ctx.nevals += 4 * n
            rows[j] = y
        return self._as_block(rows)

    def _run_staged(self, steps: list[int]) -> BodyState:
        """:meth:`run` with the adapter's :class:`StagedDynamics`: the same stages, the
        packing done inside the compiled stage call."""
        sd = self.staged
        # the compiled entries: the workspace is ours, ``a`` is checked on the first call of
        # the run (the engine binding fixes its layout)
        stage, finish, call = direct(sd.stage), direct(sd.finish), sd.call
        w, y = self.w, self.y
        h, piv, ctx = self.ctx.dt, self.pivoted, self.ctx
        rows = np.empty((len(steps), 13))
        taken = 0
        # stage 0 (it never fails: it only copies y) of the first step; finish does the next's
        stage(0, w, h, piv, np.zeros(sd.size))
        for j, n in enumerate(steps):
            for _ in range(n):
                a = call()
                if not self.checked:
                    check_engine_vector(a, sd.size, sd.what)
                    self.checked = True
                if stage(1, w, h, piv, a):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                a = call()
                if stage(2, w, h, piv, a):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                a = call()
                if stage(3, w, h, piv, a):
                    raise self._failure("a Runge-Kutta stage rotation >= pi", taken, rows[:j])
                a = call()
                if finish(w, h, piv, a):
                    raise self._failure("a Runge-Kutta step rotation >= pi", taken, rows[:j])
                taken += 1
            ctx.nevals += 4 * n
            rows[j] = y
        return self._as_block(rows)

    def _failure(self, what: str, taken: int, done_rows) -> StageRotationTooLarge:
        """The failure of the step after ``taken`` completed steps of this call, with the
        states of the checkpoints completed before it."""
        states = self._as_block(done_rows) if len(done_rows) else None
        return StageRotationTooLarge(what, steps_taken=taken, states=states)

    def _as_block(self, rows) -> BodyState:
        from references.conventions import pivot_block, quats_wxyz_to_matrices

        R = quats_wxyz_to_matrices(rows[:, 0:4])
        if self.pivoted:
            return pivot_block(R, rows[:, 7:10], self.ctx.model.com)
        return BodyState(rows[:, 4:7], rows[:, 10:13], R, rows[:, 7:10])

    def state(self) -> BodyState:
        return self._as_state(self.y)
