"""director_model: the reference rigid-body integrator of director-bench.

The rigid body in director form (x_G, d1, d2, d3 with six orthonormality constraints; seed
note by I. Romero), integrated by structure-preserving schemes in numba-compiled loops.
It imports nothing from the rest of the suite.

Public API
----------
simulate, simulate_batch, Trajectory, BatchTrajectory, step_plan, saved_steps
    run one body / N bodies (see their docstrings for shapes and units); the step plan and
    the saved step indices every engine of the suite follows
Stepper, StepperState
    one body advanced in chunks (``advance``), the integrator state kept between them
SCHEMES
    registry name -> scheme class ("rattle", "rattle4", "rattle6", "energy_momentum")
validate_body, Body
    body checks (convected moments J_i = (I_j + I_k - I_i)/2) and derived matrices
InvalidBodyError, InvalidStateError, InvalidRunError, StepSizeError
    errors (the first three are ValueError, the last RuntimeError)
hat, vee, check_rotation, quat_wxyz_from_rotation, rotation_from_quat_wxyz,
director_velocity, omega_body_from_directors, omega_world_from_body, omega_body_from_world
    convention conversions (quaternions scalar-first, w x y z)
invariants
    module: energy, angular momentum, spin, constraint residuals in director form
reference
    module: the readable numpy RATTLE with six multipliers (the check of the fast kernel)
system, simulate_system, SystemStepper, SystemTrajectory, SystemBody, Joint, project_velocities
    systems of bodies and joints (module ``director_model.system``; ``SystemBody`` is its
    ``Body``: name, mass, inertia and initial state)

Debugging: ``NUMBA_DISABLE_JIT=1`` runs every kernel as plain Python.
"""

from director_model import invariants, system
from director_model.body import Body, validate_body
from director_model.errors import (
    InvalidBodyError,
    InvalidRunError,
    InvalidStateError,
    StepSizeError,
)
from director_model.schemes import SCHEMES
from director_model.simulate import (
    Stepper,
    StepperState,
    saved_steps,
    simulate,
    simulate_batch,
    step_plan,
)
from director_model.state import (
    check_rotation,
    director_velocity,
    hat,
    omega_body_from_directors,
    omega_body_from_world,
    omega_world_from_body,
    quat_wxyz_from_rotation,
    rotation_from_quat_wxyz,
    vee,
)
from director_model.system import Body as SystemBody
from director_model.system import (
    Joint,
    SystemStepper,
    SystemTrajectory,
    project_velocities,
    simulate_system,
)
from director_model.trajectory import BatchTrajectory, Trajectory

__all__ = [
    "SCHEMES",
    "BatchTrajectory",
    "Body",
    "InvalidBodyError",
    "InvalidRunError",
    "InvalidStateError",
    "Joint",
    "StepSizeError",
    "Stepper",
    "StepperState",
    "SystemBody",
    "SystemStepper",
    "SystemTrajectory",
    "Trajectory",
    "check_rotation",
    "director_velocity",
    "hat",
    "invariants",
    "omega_body_from_directors",
    "omega_body_from_world",
    "omega_world_from_body",
    "project_velocities",
    "quat_wxyz_from_rotation",
    "rotation_from_quat_wxyz",
    "saved_steps",
    "simulate",
    "simulate_batch",
    "simulate_system",
    "step_plan",
    "system",
    "validate_body",
    "vee",
]
