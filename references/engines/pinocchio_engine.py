"""Pinocchio adapter: a FreeFlyer joint (free body) or a Spherical joint at the world origin
(pivoted body), stepped by our own time loops around Pinocchio's ABA.

Pinocchio has no time integrator (docs/engines.md): both integrators here are ours.

- ``semi-implicit Euler``: v += h aba(q, v); q = integrate(q, h v). This is the usual
  Pinocchio time loop. For the FreeFlyer, ``pinocchio.integrate`` is the SE(3) exponential of
  the LOCAL twist, so over one step the COM moves along a screw, not a straight line; the
  difference from MuJoCo's Euler is O(h^2) per step when the body both translates and spins.
- ``RKMK4``: Runge-Kutta-Munthe-Kaas of order 4 (:mod:`references.engines.liegroup`), with
  ``pinocchio.integrate`` as the group action and ``pinocchio.dIntegrate`` (derivative with
  respect to the velocity argument, i.e. the right Jacobian of exp on SE(3) or SO(3)) for
  dexp^{-1}.

Model: the body frame is the principal COM frame for the FreeFlyer (lever 0), and the pivot
frame for the Spherical joint (lever = -pivot). ``pinocchio.Inertia(mass, lever, I)`` takes the
rotational inertia about the COM (Pinocchio documentation, class Inertia).
"""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from references.engines.base import (
    READBACK_RTOL,
    Engine,
    Integrator,
    RunOutput,
    StepFailure,
    Stopwatch,
    import_engine,
)
from references.engines.liegroup import check_stage_rotation, rkmk4_step
from references.trajectory import Trajectory


def _import():
    return import_engine("pinocchio", "Pinocchio", "pin")


class PinocchioEngine(Engine):
    """Pinocchio (``pin`` package): ABA forward dynamics, time stepping written here."""

    name = "pinocchio"
    description = "Pinocchio: FreeFlyer or Spherical joint, ABA, our own time loops"
    integrators = (
        Integrator(
            "semi-implicit Euler",
            "semi-implicit Euler",
            1,
            "Ours (Pinocchio has no integrator): v += h aba(q, v); q = pinocchio.integrate(q, "
            "h v). Gyroscopic term explicit; same algorithm as MuJoCo Euler for rotation.",
        ),
        Integrator(
            "RKMK4",
            "4th-order Lie-group",
            4,
            "Ours: Runge-Kutta-Munthe-Kaas order 4 on the joint's Lie group, stage tangents "
            "through pinocchio.dIntegrate (dexp^{-1}), forces from pinocchio.aba.",
        ),
    )

    @classmethod
    def version(cls) -> str:
        return _import().__version__

    # -- model -------------------------------------------------------------------------
    def _build(self, scenario):
        pin = _import()
        model = pin.Model()
        if scenario.pivoted:
            joint = pin.JointModelSpherical()
            lever = -np.asarray(scenario.pivot, dtype=float)
        else:
            joint = pin.JointModelFreeFlyer()
            lever = np.zeros(3)
        jid = model.addJoint(0, joint, pin.SE3.Identity(), "body_joint")
        inertia = pin.Inertia(float(scenario.mass), lever, np.diag(scenario.inertia))
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        # Gravity is on by default in Pinocchio (docs/engines.md): set it from the scenario.
        model.gravity = pin.Motion(np.asarray(scenario.gravity, dtype=float), np.zeros(3))
        self._check_model(pin, model, scenario, lever)
        settings = {
            "gravity": np.asarray(scenario.gravity).tolist(),
            "joint": "Spherical at the world origin" if scenario.pivoted else "FreeFlyer",
            "COM lever": lever.tolist(),
            "quaternion": "normalised after every step (Pinocchio accepts unnormalised ones)",
            "damping, armature": "0 (defaults, read back; aba ignores them anyway)",
        }
        return pin, model, settings

    @staticmethod
    def _check_model(pin, model, scenario, lever):
        chk = cv.check_quantity
        e = "Pinocchio"
        body = model.inertias[1]
        chk(e, "mass", body.mass, scenario.mass, READBACK_RTOL)
        chk(
            e,
            "inertia tensor about the COM",
            body.inertia,
            np.diag(scenario.inertia),
            READBACK_RTOL,
        )
        chk(e, "COM position in the body frame (lever)", body.lever, lever, READBACK_RTOL)
        chk(e, "gravity", model.gravity.linear, scenario.gravity, READBACK_RTOL)
        chk(e, "gravity (angular part)", model.gravity.angular, np.zeros(3), 0, 0)
        chk(e, "joint placement", model.jointPlacements[1].homogeneous, np.eye(4), 0, 0)
        chk(e, "joint damping", model.damping, np.zeros(model.nv), 0, 0)
        chk(e, "armature", model.armature, np.zeros(model.nv), 0, 0)
        want = (4, 3) if scenario.pivoted else (7, 6)
        chk(e, "(nq, nv)", [model.nq, model.nv], want, 0, 0)

    # -- state -------------------------------------------------------------------------
    @staticmethod
    def state_from_scenario(scenario):
        if scenario.pivoted:
            return cv.pinocchio_spherical_from_state(scenario.rotation, scenario.omega_body)
        return cv.pinocchio_freeflyer_from_state(
            scenario.position, scenario.velocity, scenario.rotation, scenario.omega_body
        )

    @staticmethod
    def to_state(q, v, scenario) -> cv.BodyState:
        if scenario.pivoted:
            R, W = cv.pinocchio_spherical_to_state(q, v)
            return cv.BodyState(*cv.pivot_com(R, W, scenario.pivot), R, W)
        return cv.pinocchio_freeflyer_to_state(q, v)

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        pin, model, settings = self._build(scenario)
        data = model.createData()
        q, v = self.state_from_scenario(scenario)
        state0 = self.to_state(q, v, scenario)
        # Pinocchio's own energy and momentum: kinetic and potential energy, centroidal
        # momentum (about the COM, world axes), shifted to the pivot when pivoted.
        energy = pin.computeKineticEnergy(model, data, q, v) + pin.computePotentialEnergy(
            model, data, q
        )
        com = pin.centerOfMass(model, data, q).copy()
        hg = pin.computeCentroidalMomentum(model, data, q, v)
        L = hg.angular + (np.cross(com, hg.linear) if scenario.pivoted else 0.0)
        native = {
            "energy": energy,
            "angular momentum": L,
            "COM velocity": hg.linear / scenario.mass,
        }
        cv.check_initial_state("Pinocchio", scenario, state0, native=native)
        # The COM Pinocchio computes from q must be where the scenario puts it.
        cv.check_quantity("Pinocchio", "COM world position", com, state0.position, 1e-14, 1e-15)

        nv = model.nv
        tau = np.zeros(nv)
        iq = slice(model.nq - 4, model.nq)  # the quaternion, last 4 entries in both joints

        def accel(qq, vv):
            return pin.aba(model, data, qq, vv, tau).copy()

        if integrator == "semi-implicit Euler":

            def step(qq, vv):
                vv = vv + dt * accel(qq, vv)
                return pin.integrate(model, qq, dt * vv), vv
        else:
            arg1 = pin.ArgumentPosition.ARG1
            q_neutral = pin.neutral(model)

            angular = slice(nv - 3, nv)  # last 3 entries for both the FreeFlyer and Spherical

            def dexpinv(theta, vv):
                check_stage_rotation(float(theta[angular] @ theta[angular]))
                # d integrate(q, theta)/d theta is the right Jacobian of exp at theta; on a
                # Lie group it does not depend on q, so the neutral configuration serves.
                return np.linalg.solve(pin.dIntegrate(model, q_neutral, theta, arg1), vv)

            def integ(qq, theta):
                return pin.integrate(model, qq, theta)

            def step(qq, vv):
                return rkmk4_step(qq, vv, dt, accel, integ, dexpinv)

        n = len(saves)
        qs = np.empty((n, model.nq))
        vs = np.empty((n, nv))
        watch = Stopwatch()
        done = 0
        report = max(1, nstep // 100)
        for i, target in enumerate(saves):
            with watch:
                try:
                    while done < target:
                        q, v = step(q, v)
                        quat = q[iq]
                        q[iq] = quat / np.sqrt(quat @ quat)
                        done += 1
                        if progress is not None and done % report == 0:
                            progress(done / nstep)
                except (ArithmeticError, np.linalg.LinAlgError) as exc:
                    raise StepFailure(
                        f"Pinocchio {integrator}: step {done + 1} (from t = {done * dt:.6g} s, "
                        f"dt = {dt:g}) could not be taken: {exc}; reduce dt"
                    ) from exc
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
                t_prev = saves[i - 1] * dt if i else 0.0
                raise StepFailure(
                    f"Pinocchio {integrator}: the state became non-finite between "
                    f"t = {t_prev:.6g} and t = {done * dt:.6g} s (dt = {dt:g}); reduce dt"
                )
            qs[i] = q
            vs[i] = v
        states = [self.to_state(a, b, scenario) for a, b in zip(qs, vs, strict=True)]
        if progress is not None:
            progress(1.0)
        traj = Trajectory.from_states(scenario, np.asarray(saves) * dt, *cv.stack_states(states))
        settings["integrator"] = integrator
        settings["timestep"] = float(dt)
        return RunOutput(traj, nstep, watch.elapsed, settings)
