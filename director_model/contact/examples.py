"""Ready-made contact scenes (the classical set-ups whose motion is known in closed form).

Each function returns a :class:`ContactScene`; the expected motions are not here (the tests
and ``benchmarks/contact_closed_forms.py`` state them). Conventions: gravity (0, 0, -g);
inclines are ``Plane.incline(angle)`` (descending towards +x, downhill unit vector and normal
from :func:`incline_frame`); a body resting on a plane touches it exactly (gap 0 up to the
rounding of its coordinates).
"""

from __future__ import annotations

import math

import numpy as np

from director_model.contact.scene import ContactScene, Pair, PointForce
from director_model.contact.shapes import Box, Cylinder, Plane, Sphere, incline_frame
from director_model.system.model import Body

G = 9.81


def rot_y(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the world y axis: it carries the ground's normal z
    onto the normal of ``Plane.incline(angle)``."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: a cylinder lying on its side with its axis (body axis 3) along world y, across the slope
CYLINDER_ACROSS = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def block_on_incline(angle, mu, half=(0.1, 0.1, 0.05), mass=1.0, e=0.0):
    """A box (half extents ``half``, half-height half[2]) released at rest flat on an incline
    of ``angle`` rad, its base's sides along the slope and across it."""
    box = Box(half)
    _, n = incline_frame(angle)
    body = Body("block", mass, box.inertia(mass), position=tuple(half[2] * n),
                rotation=rot_y(angle))  # fmt: skip
    return ContactScene(
        bodies=[body], shapes={"block": box}, planes={"incline": Plane.incline(angle)},
        pairs=[Pair("block", "incline", mu=mu, e=e)], gravity=(0.0, 0.0, -G),
    )  # fmt: skip


def pushed_box(force, direction, mu, half=(0.1, 0.1, 0.05), mass=1.0):
    """A box at rest on the ground z = 0 pushed at its centre of mass by a horizontal force
    of size ``force`` (N) at ``direction`` rad from its body axis 1 (0: along an axis,
    pi/4: along the diagonal of its friction box)."""
    box = Box(half)
    body = Body("box", mass, box.inertia(mass), position=(0.0, 0.0, half[2]))
    f = (force * math.cos(direction), force * math.sin(direction), 0.0)
    return ContactScene(
        bodies=[body], shapes={"box": box}, planes={"ground": Plane((0.0, 0.0, 1.0), 0.0)},
        pairs=[Pair("box", "ground", mu=mu)], forces=[PointForce("box", f)],
        gravity=(0.0, 0.0, -G),
    )  # fmt: skip


def sphere_on_ground(v0, w0, mu, radius=0.1, mass=1.0):
    """A solid sphere touching the ground, centre velocity v0 along x, spin w0 about y (the
    axis for which rolling forward is positive: the contact point slips at v0 - r w0)."""
    sph = Sphere(radius)
    body = Body("ball", mass, sph.inertia(mass), position=(0.0, 0.0, radius),
                velocity=(v0, 0.0, 0.0), omega_body=(0.0, w0, 0.0))  # fmt: skip
    return ContactScene(
        bodies=[body], shapes={"ball": sph}, planes={"ground": Plane((0.0, 0.0, 1.0), 0.0)},
        pairs=[Pair("ball", "ground", mu=mu)], gravity=(0.0, 0.0, -G),
    )  # fmt: skip


def roller_on_incline(kind, angle, mu, radius=0.1, half_length=0.1, mass=1.0):
    """A solid sphere (``kind`` "sphere") or a cylinder lying on its side ("cylinder", axis
    across the slope) released at rest on an incline of ``angle`` rad."""
    _, n = incline_frame(angle)
    if kind == "sphere":
        shape, R = Sphere(radius), np.eye(3)
    elif kind == "cylinder":
        shape, R = Cylinder(radius, half_length), CYLINDER_ACROSS
    else:
        raise ValueError(f"kind = {kind!r}: expected 'sphere' or 'cylinder'")
    body = Body("roller", mass, shape.inertia(mass), position=tuple(radius * n), rotation=R)
    return ContactScene(
        bodies=[body], shapes={"roller": shape}, planes={"incline": Plane.incline(angle)},
        pairs=[Pair("roller", "incline", mu=mu)], gravity=(0.0, 0.0, -G),
    )  # fmt: skip


def box_stack(n_boxes=3, mu=0.5, half=(0.1, 0.1, 0.05), mass=1.0):
    """``n_boxes`` equal boxes stacked face on face on the ground, at rest (n_boxes = 1: a
    resting box). Pairs: the bottom box with the ground, each box with the one below."""
    box = Box(half)
    names = [f"box{k}" for k in range(n_boxes)]
    bodies = [
        Body(nm, mass, box.inertia(mass), position=(0.0, 0.0, (2 * k + 1) * half[2]))
        for k, nm in enumerate(names)
    ]
    pairs = [Pair(names[0], "ground", mu=mu)]
    pairs += [Pair(names[k], names[k - 1], mu=mu) for k in range(1, n_boxes)]
    return ContactScene(
        bodies=bodies, shapes=dict.fromkeys(names, box),
        planes={"ground": Plane((0.0, 0.0, 1.0), 0.0)}, pairs=pairs, gravity=(0.0, 0.0, -G),
    )  # fmt: skip


def dropped_sphere(height, e, mu=0.0, radius=0.1, mass=1.0, spin=(0.0, 0.0, 0.0)):
    """A solid sphere released at rest with its lowest point ``height`` above the ground."""
    sph = Sphere(radius)
    body = Body("ball", mass, sph.inertia(mass), position=(0.0, 0.0, radius + height),
                omega_body=spin)  # fmt: skip
    return ContactScene(
        bodies=[body], shapes={"ball": sph}, planes={"ground": Plane((0.0, 0.0, 1.0), 0.0)},
        pairs=[Pair("ball", "ground", mu=mu, e=e)], gravity=(0.0, 0.0, -G),
    )  # fmt: skip
