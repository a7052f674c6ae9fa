"""director_model.system: systems of rigid bodies connected by joints, in director form.

Every body keeps its twelve director coordinates and its constant mass matrix; every joint
(spherical, fixed point, revolute, universal, cylindrical, prismatic) is a set of linear or
quadratic constraint rows; open chains and closed loops (redundant ones included) are the
same problem. Integrated by RATTLE and its compositions of order 4 and 6 in compiled code.

Public API
----------
Body, Joint, JOINT_KINDS
    a body (name, mass, principal moments, initial pose and velocity) and a joint
Spring, Torque
    force elements: a linear spring-damper between body points, a constant joint torque
simulate_system, SystemStepper, SystemTrajectory, SYSTEM_SCHEMES
    one run / a run in chunks with bitwise restart / the saved states
simulate_system_batch, SystemBatchTrajectory
    N systems of one topology in parallel (numba threads), each bit for bit its own run
project_velocities
    the explicit projection of initial velocities onto the joints' velocity constraints
InvalidJointError, InvalidMechanismError
    errors (ValueError); bodies and runs raise director_model's InvalidBodyError,
    InvalidStateError, InvalidRunError and StepSizeError
"""

from director_model.system.batch import SystemBatchTrajectory, simulate_system_batch
from director_model.system.model import (
    JOINT_KINDS,
    Body,
    InvalidJointError,
    InvalidMechanismError,
    Joint,
    Spring,
    Torque,
)
from director_model.system.simulate import (
    SYSTEM_SCHEMES,
    SystemStepper,
    SystemTrajectory,
    simulate_system,
)
from director_model.system.states import project_velocities

__all__ = [
    "JOINT_KINDS",
    "SYSTEM_SCHEMES",
    "Body",
    "SystemBatchTrajectory",
    "InvalidJointError",
    "InvalidMechanismError",
    "Joint",
    "SystemStepper",
    "SystemTrajectory",
    "Spring",
    "Torque",
    "project_velocities",
    "simulate_system",
    "simulate_system_batch",
]
