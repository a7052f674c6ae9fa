"""The director model's system builder (:mod:`director_model.system`), per the contract of
:mod:`references.engines.system`: RATTLE and its compositions of order 4 and 6 on bodies in
director form with the joints as constraint rows (loops and redundant rows included)."""

from __future__ import annotations

import numpy as np

from references.engines import timing
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported

#: the director schemes that integrate systems
SCHEMES = ("rattle", "rattle4", "rattle6")


def model(scenario):
    """(bodies, joints) of ``director_model.system`` for a system scenario: the scenario's
    fields are that API's fields, one for one."""
    from director_model.system import Body, Joint

    bodies = [
        Body(b.name, b.mass, tuple(b.inertia), position=b.position, rotation=b.rotation,
             velocity=b.velocity, omega_body=b.omega_body)
        for b in scenario.bodies
    ]  # fmt: skip
    joints = [
        Joint(j.kind, j.body_a, j.body_b, anchor_a=j.anchor_a, anchor_b=j.anchor_b,
              axis_a=j.axis_a, axis_b=j.axis_b, name=j.name)
        for j in scenario.joints
    ]  # fmt: skip
    return bodies, joints


def force_elements(scenario):
    """(springs, torques) of ``director_model.system`` for a system scenario's force elements
    (the same fields)."""
    from director_model.system import Spring, Torque

    springs = [
        Spring(s.body_a, s.body_b, s.anchor_a, s.anchor_b, s.stiffness, s.damping,
               s.rest_length, name=s.name)
        for s in getattr(scenario, "springs", ())
    ]  # fmt: skip
    torques = [Torque(t.joint, t.torque) for t in getattr(scenario, "torques", ())]
    return springs, torques


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` with the director scheme ``integrator`` (module docstring)."""
    import director_model
    from director_model.system import InvalidJointError, InvalidMechanismError, SystemStepper

    if integrator not in SCHEMES:
        raise Unsupported(
            f"director {integrator}: not a scheme of director_model.system (it integrates "
            f"systems with {', '.join(SCHEMES)})"
        )
    bodies, joints = model(scenario)
    springs, torques = force_elements(scenario)
    try:
        # the stepper checks and assembles the mechanism and compiles its kernel, or loads
        # it from numba's cache, when it is built: a run's cost is its stepping
        # (timing.stepping), as every other builder's model construction is left out
        stepper = SystemStepper(bodies, joints, gravity=tuple(scenario.gravity),
                                scheme=integrator, dt=dt, springs=springs, torques=torques,
                                **settings)  # fmt: skip
        timing.stepping()
        # director_model.simulate_system's run (its steps, its saves, its start saved); the
        # run's cost ends with the compiled stepping: the invariants and residuals the
        # stepper then computes from the saved states are its own checks, which no other
        # engine's stepping does (the suite's metrics come from the states)
        tr = stepper.advance(int(nstep), int(save_every), include_start=True,
                             stepped=timing.stepped)  # fmt: skip
    except director_model.StepSizeError as exc:
        raise Diverged(f"director {integrator}: {exc}", float(exc.time)) from exc
    except (InvalidJointError, InvalidMechanismError, ValueError) as exc:
        raise EngineError(f"director_model.system refused the system: {exc}") from exc
    timing.add(float(tr.wall_time_s), float(tr.cpu_time_s))  # the compiled run's own
    if tuple(tr.body_names) != tuple(scenario.body_names):
        raise EngineError(
            f"director_model.system returned bodies {tr.body_names}, the scenario has "
            f"{scenario.body_names}"
        )
    if tuple(tr.joint_names) != tuple(j.name for j in scenario.joints):
        raise EngineError(f"director_model.system built joints {tr.joint_names}")
    settings = {
        "scheme": integrator,
        "constraint solver": tr.solver,
        "constraint rows (nominal rank)": int(tr.rank_nominal),
        "steps with a rank drop": int(tr.rank_drop_steps),
        "smallest relative singular value": float(tr.min_singular_value),
        "Newton iterations": int(tr.newton_iterations),
    }
    if tr.solver in ("minnorm", "svd"):  # the loop solvers' steps redone at singular landings
        settings["steps split at a singular landing"] = int(tr.split_steps)
        settings["singular landings kept"] = int(tr.kept_singular_steps)
    return SystemResult(
        t=tr.t,
        x=tr.position,
        R=tr.rotation,
        v=tr.velocity,
        W=tr.omega_body,
        engine_time_s=float(tr.wall_time_s),
        settings=settings,
        stats={"largest constraint row residual": float(np.max(tr.constraint_position))},
    )
