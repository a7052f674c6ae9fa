"""Pinocchio adapter: a FreeFlyer joint (free body) or a Spherical joint at the world origin
(pivoted body), stepped by our own time loops around Pinocchio's ABA.

Pinocchio has no time integrator (docs/engines.md): both integrators here are ours.

- ``semi-implicit Euler``: v += h aba(q, v); q = integrate(q, h v). This is the usual
  Pinocchio time loop. For the FreeFlyer, ``pinocchio.integrate`` is the SE(3) exponential of
  the LOCAL twist, so over one step the COM moves along a screw, not a straight line; the
  difference from MuJoCo's Euler is O(h^2) per step when the body both translates and spins.
- ``RKMK4``: the suite's Runge-Kutta-Munthe-Kaas of order 4
  (:mod:`references.engines.liegroup`) on SO(3) x R^3, with the accelerations from
  ``pinocchio.aba``.

Model: the body frame is the principal COM frame for the FreeFlyer (lever 0), and the pivot
frame for the Spherical joint (lever = -pivot). ``pinocchio.Inertia(mass, lever, I)`` takes the
rotational inertia about the COM (Pinocchio documentation, class Inertia).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from references import conventions as cv
from references.engines import _rkmk4
from references.engines.context import ModelReadback
from references.engines.integrators import Integrator
from references.engines.interface import Engine, SceneBuilder
from references.engines.liegroup import StagedDynamics, check_engine_vector, direct
from references.engines.native import import_engine


def _import():
    return import_engine("pinocchio", "Pinocchio", "pin")


class PinocchioEngine(Engine):
    """Pinocchio (``pin`` package): ABA forward dynamics, time stepping written here."""

    name = "pinocchio"
    description = "Pinocchio: FreeFlyer or Spherical joint, ABA, our own time loops"
    scene_builder = SceneBuilder(
        "references.engines.pinocchio.system:simulate_system",
        ("baumgarte", "baumgarte_omega", "prox"),
        force_elements=True,
    )
    integrators = (
        Integrator(
            "semi-implicit Euler",
            "semi-implicit Euler",
            1,
            "Ours (Pinocchio has no integrator): v += h aba(q, v); q = pinocchio.integrate(q, "
            "h v). Gyroscopic term explicit; same algorithm as MuJoCo Euler for rotation.",
            ours=True,
        ),
        Integrator(
            "RKMK4",
            "4th-order Lie-group",
            4,
            "The suite's Runge-Kutta-Munthe-Kaas order 4 on SO(3) x R^3 (SO(3) when pivoted), "
            "exact dexp^{-1}, accelerations from pinocchio.aba.",
            stepping="rkmk4",
            evals_per_step=4.0,
        ),
    )

    packages = ("pin",)
    saves_raw = True

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        pin = _import()
        model = pin.Model()
        joint = pin.JointModelSpherical() if ctx.model.pivoted else pin.JointModelFreeFlyer()
        jid = model.addJoint(0, joint, pin.SE3.Identity(), "body_joint")
        inertia = pin.Inertia(ctx.model.mass, ctx.model.com, np.diag(ctx.model.inertia))
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        # Gravity is on by default in Pinocchio (docs/engines.md): set it from the scenario.
        model.gravity = pin.Motion(ctx.model.gravity, np.zeros(3))
        ctx.handle = _Handle(pin, model, model.createData())

    def read_model(self, ctx) -> ModelReadback:
        h = ctx.handle
        body = h.model.inertias[1]
        kind = h.model.joints[1].shortname()
        joint = {"JointModelFreeFlyer": "free", "JointModelSpherical": "ball"}.get(kind, kind)
        return ModelReadback(
            mass=body.mass,
            inertia=body.inertia,
            com=body.lever,
            joint=joint,
            gravity=h.model.gravity.linear,
            dt=ctx.dt,  # Pinocchio has no time step: the loop is ours
            extra={
                "gravity (angular part)": (h.model.gravity.angular, np.zeros(3)),
                "joint placement": (h.model.jointPlacements[1].homogeneous, np.eye(4)),
                "joint damping": (h.model.damping, np.zeros(h.model.nv)),
                "armature": (h.model.armature, np.zeros(h.model.nv)),
                "number of joints": (h.model.njoints, 2),
            },
        )

    def settings(self, ctx) -> dict:
        return {
            "gravity": ctx.model.gravity.tolist(),
            "joint": "Spherical at the world origin" if ctx.model.pivoted else "FreeFlyer",
            "COM lever": ctx.model.com.tolist(),
            "quaternion": "normalised after every step (Pinocchio accepts unnormalised ones)",
            "damping, armature": "0 (defaults, read back; aba ignores them anyway)",
            "time stepping": "ours (Pinocchio has no integrator): "
            + (
                "v += h aba(q, v); q = integrate(q, h v)"
                if ctx.integrator.stepping == "native"
                else "the suite's RKMK4 around aba"
            ),
        }

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        if ctx.model.pivoted:
            q, v = cv.pinocchio_spherical_from_state(state.rotation, state.omega_body)
        else:
            q, v = cv.pinocchio_freeflyer_from_state(*state)
        ctx.handle.q, ctx.handle.v = q, v

    def read_state(self, ctx) -> cv.BodyState:
        q, v = ctx.handle.q, ctx.handle.v
        if ctx.model.pivoted:
            return ctx.model.state_from_rotation(*cv.pinocchio_spherical_to_state(q, v))
        return cv.pinocchio_freeflyer_to_state(q, v)

    def read_raw(self, ctx) -> np.ndarray:
        return np.concatenate((ctx.handle.q, ctx.handle.v))

    def states_from_raw(self, ctx, raw) -> cv.BodyState:
        return cv.pinocchio_block(raw, ctx.handle.model.nq, ctx.model.com, ctx.model.pivoted)

    def native_quantities(self, ctx) -> dict:
        """Pinocchio's own kinetic and potential energy, centroidal momentum (about the COM,
        world axes; shifted to the pivot when pivoted), COM position and velocity, and the
        joint frame's rotation from its forward kinematics."""
        h = ctx.handle
        pin, model, data, q, v = h.pin, h.model, h.data, h.q, h.v
        energy = pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(
            model, data, q
        )
        com = pin.centerOfMass(model, data, q).copy()
        hg = pin.computeCentroidalMomentum(model, data, q, v)
        L = hg.angular + (np.cross(com, hg.linear) if ctx.model.pivoted else 0.0)
        pin.forwardKinematics(model, data, q)
        return {
            "energy": energy,
            "angular momentum": L,
            "rotation": data.oMi[1].rotation.copy(),
            "COM velocity": hg.linear / ctx.model.mass,
            "COM position": com,
        }

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        """Semi-implicit Euler: v += h aba(q, v); q = integrate(q, h v); the quaternion (the
        last 4 entries of q for both joints) renormalised (:meth:`_euler`)."""
        self._euler(ctx, [k], None)

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """:meth:`Engine.advance_saving` with the Euler loop's bindings made once per block
        and each saved [q, v] copied into one preallocated block."""
        h = ctx.handle
        rows = np.empty((len(steps), h.model.nq + h.model.nv))
        self._euler(ctx, steps, rows)
        return self.states_from_raw(ctx, rows)

    def _euler(self, ctx, steps, rows) -> None:
        """The semi-implicit Euler steps of ``steps`` in turn, [q, v] after each count into
        ``rows`` (when given). The arithmetic between the two Pinocchio calls is compiled
        (:func:`_euler_velocity`, :func:`_normalize_tail`: the operations numpy did, bit for
        bit)."""
        h = ctx.handle
        model, data, tau, dt, clock = h.model, h.data, h.tau, ctx.dt, ctx.clock
        aba, integrate, now = h.pin.aba, h.pin.integrate, time.perf_counter
        # the compiled entries without numba's type dispatch: v and dv are ours, Pinocchio's
        # a and q checked on the run's first step (the binding fixes their layout)
        velocity, normalize = h.euler
        q, v, dv, checked = h.q, np.array(h.v, dtype=float), h.dv, h.checked
        nq = model.nq
        for j, k in enumerate(steps):
            for _ in range(k):
                t0 = now()  # the stopwatch around the two Pinocchio calls only
                a = aba(model, data, q, v, tau)
                clock.lap(t0)
                if not checked:
                    check_engine_vector(a, len(v), "Pinocchio's aba")
                velocity(v, a, dt, dv)  # v += dt a; dv = dt v
                t0 = now()
                q = integrate(model, q, dv)
                clock.lap(t0)
                if not checked:
                    check_engine_vector(q, nq, "Pinocchio's integrate")
                    h.checked = checked = True
                normalize(q)
            if rows is not None:
                rows[j, :nq] = q
                rows[j, nq:] = v
        h.q, h.v = q, v

    def forward_dynamics(self, ctx, state):
        """(dW/dt, a_G) from aba. The FreeFlyer's acceleration is the derivative of its LOCAL
        velocity (R^T v_G, W), so a_G = R (dv_local/dt + W x R^T v_G)."""
        h = ctx.handle
        self.set_state(ctx, state)
        with ctx.clock:
            a = h.pin.aba(h.model, h.data, h.q, h.v, h.tau)
        if ctx.model.pivoted:
            return a, None
        R = state.rotation
        v_local = R.T @ state.velocity
        return a[3:], R @ (a[:3] + np.cross(state.omega_body, v_local))

    def staged_dynamics(self, ctx) -> StagedDynamics:
        """The compiled RKMK4's stages packing Pinocchio's q and v (``_rkmk4.pinocchio_stage``),
        and aba with the model, data and buffers bound once: the stopwatch around the aba
        call only."""
        h = ctx.handle
        w = np.zeros(_rkmk4.STAGED_WORKSPACE)
        qbuf, vbuf = _rkmk4.pinocchio_buffers(w, bool(ctx.model.pivoted))
        aba, model, data, tau = h.pin.aba, h.model, h.data, h.tau
        clock, now = ctx.clock, time.perf_counter

        def call():
            t0 = now()
            a = aba(model, data, qbuf, vbuf, tau)
            clock.lap(t0)
            return a

        return StagedDynamics(w, _rkmk4.pinocchio_stage, _rkmk4.pinocchio_finish, call,
                              len(vbuf), "Pinocchio's aba")  # fmt: skip


class _Handle:
    """Pinocchio's model and data, and the state our loop advances."""

    def __init__(self, pin, model, data):
        self.pin, self.model, self.data = pin, model, data
        self.tau = np.zeros(model.nv)
        self.q = self.v = None
        # the semi-implicit Euler's compiled arithmetic (compiled or loaded from numba's
        # cache here, at the build), its h v buffer, and whether Pinocchio's vectors were
        # checked
        _euler_velocity(np.zeros(model.nv), self.tau, 0.0, np.zeros(model.nv))
        _normalize_tail(np.array([0.0, 0.0, 0.0, 1.0]))
        self.euler = (direct(_euler_velocity), direct(_normalize_tail))
        self.dv = np.zeros(model.nv)
        self.checked = False


@njit(cache=True)
def _euler_velocity(v, a, dt, dv):
    """v += dt a, then dv = dt v, in place: numpy's ``v + dt * a`` and ``dt * v``, element by
    element, the same products and sums."""
    for k in range(v.shape[0]):
        v[k] = v[k] + dt * a[k]
        dv[k] = dt * v[k]


@njit(cache=True)
def _normalize_tail(q):
    """The last four entries of q (the quaternion, x y z w) divided by their norm, in place:
    numpy's ``quat / np.sqrt(quat @ quat)``. numpy's ``@`` of two vectors and numba's
    ``np.dot`` both call BLAS's ddot (the same sum bit for bit: OpenBLAS's fused
    multiply-add chain for four entries, which plain products and sums do not reproduce in
    one case in four); sqrt and the division are correctly rounded in both."""
    t = q[q.shape[0] - 4 :]
    s = math.sqrt(np.dot(t, t))
    for k in range(4):
        t[k] = t[k] / s
