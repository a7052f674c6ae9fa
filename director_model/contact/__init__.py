"""director_model.contact: rigid bodies with hard frictional contact, in director form.

Bodies (director_model.system.Body) carry contact shapes (sphere, box, capsule, cylinder)
and touch fixed planes and each other through declared pairs, each with an isotropic
Coulomb friction coefficient and a Newton restitution coefficient; joints
(director_model.system.Joint) and constant point forces may be added. Integrated by a
nonsmooth RATTLE: per step a position stage (non-penetration at the end of the step, the
exact Coulomb cone) and a velocity stage (Newton's impact law), each contact problem solved
by a semi-smooth Newton method to a certified residual; away from contacts the step is the
single-body RATTLE step.

Public API
----------
Body, Joint
    director_model.system's body (name, mass, principal moments, initial state) and joint
Sphere, Box, Capsule, Cylinder, Plane, incline_frame
    shapes in a body's principal frame; fixed planes
Pair, PointForce, ContactScene
    a contact pair (names, mu, e); a constant force at a body point; the checked scene
simulate_contact, ContactStepper, ContactTrajectory, simulate_contact_batch
    one run / a run in chunks / the saved states and law residuals / N runs in parallel
InvalidContactError, ContactSolveError
    refused input (ValueError); a failed step (RuntimeError)
"""

from director_model.contact.batch import ContactBatchTrajectory, simulate_contact_batch
from director_model.contact.scene import ContactScene, Pair, PointForce
from director_model.contact.shapes import (
    Box,
    Capsule,
    Cylinder,
    InvalidContactError,
    Plane,
    Sphere,
    incline_frame,
)
from director_model.contact.simulate import (
    ContactSolveError,
    ContactStepper,
    ContactTrajectory,
    simulate_contact,
)
from director_model.system.model import Body, Joint

__all__ = [
    "Body",
    "Box",
    "Capsule",
    "ContactBatchTrajectory",
    "ContactScene",
    "ContactSolveError",
    "ContactStepper",
    "ContactTrajectory",
    "Cylinder",
    "InvalidContactError",
    "Joint",
    "Pair",
    "Plane",
    "PointForce",
    "Sphere",
    "incline_frame",
    "simulate_contact",
    "simulate_contact_batch",
]
