"""Contact geometry: the shapes of bodies and the fixed planes they touch.

A body's shape is given in its principal frame with the origin at its centre of mass (the
frame of :class:`director_model.system.Body`): a sphere centred there, a box whose faces are
perpendicular to the principal axes, a capsule or a cylinder whose axis is principal axis 3.
A plane is fixed in the world: the points x with n . x >= offset are outside it (n its unit
normal). Lengths in m.

Each shape also gives the principal moments of inertia of a solid of uniform density
(:meth:`inertia`), for bodies whose mass distribution is the shape itself; a body may be
given any other moments (e.g. a hollow sphere): the shape is only its surface for contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class InvalidContactError(ValueError):
    """Contact input that the integrator refuses: a degenerate shape, a friction coefficient
    below 0, a restitution coefficient outside [0, 1], an unknown body or plane in a pair, a
    pair of shapes that the scheme does not treat exactly, bodies that overlap at t = 0 (the
    message names the pair, the feature and the depth)."""


def _positive(where: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidContactError(f"{where} = {value!r}: expected a number") from None
    if not (math.isfinite(v) and v > 0.0):
        raise InvalidContactError(f"{where} = {value!r}: must be finite and > 0")
    return v


def _vec3(where: str, value) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidContactError(f"{where} = {value!r}: expected 3 real numbers") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidContactError(f"{where} = {value!r}: expected 3 finite real numbers")
    return a


@dataclass(frozen=True)
class Sphere:
    """A sphere of ``radius`` (m) centred at the body's centre of mass."""

    radius: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _positive("Sphere radius", self.radius))

    def inertia(self, mass: float) -> tuple:
        """Principal moments of a solid sphere of uniform density: 2/5 m r^2."""
        i = 0.4 * mass * self.radius**2
        return (i, i, i)

    @property
    def bound(self) -> float:
        """Radius of the smallest ball about the centre of mass containing the shape."""
        return self.radius


@dataclass(frozen=True)
class Box:
    """A box with ``half_extents`` (a1, a2, a3) (m) along the principal axes, centred at the
    centre of mass."""

    half_extents: tuple

    def __post_init__(self):
        a = _vec3("Box half_extents", self.half_extents)
        for k in range(3):
            _positive(f"Box half_extents[{k}]", a[k])
        object.__setattr__(self, "half_extents", tuple(float(x) for x in a))

    def inertia(self, mass: float) -> tuple:
        """Principal moments of a solid box: m (a_j^2 + a_k^2) / 3."""
        a1, a2, a3 = self.half_extents
        return (mass * (a2**2 + a3**2) / 3, mass * (a1**2 + a3**2) / 3, mass * (a1**2 + a2**2) / 3)

    @property
    def bound(self) -> float:
        return float(np.linalg.norm(self.half_extents))

    def vertices(self) -> np.ndarray:
        """The 8 vertices (8, 3) in the body frame, vertex k at (s1 a1, s2 a2, s3 a3) with
        s_i = -1 + 2 ((k >> (i - 1)) & 1)."""
        a = np.array(self.half_extents)
        return np.array([[(1 if (k >> i) & 1 else -1) * a[i] for i in range(3)] for k in range(8)])


@dataclass(frozen=True)
class Capsule:
    """A capsule: the points within ``radius`` of the segment from -half_length to
    +half_length along principal axis 3 (m)."""

    radius: float
    half_length: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _positive("Capsule radius", self.radius))
        object.__setattr__(self, "half_length", _positive("Capsule half_length", self.half_length))

    def inertia(self, mass: float) -> tuple:
        """Principal moments of a solid capsule of uniform density (a cylinder of length
        2 half_length and two hemispherical caps)."""
        r, L = self.radius, 2.0 * self.half_length
        vc = math.pi * r * r * L
        vs = 4.0 / 3.0 * math.pi * r**3
        mc = mass * vc / (vc + vs)
        ms = mass - mc
        axial = mc * r * r / 2 + ms * 2 * r * r / 5
        # each hemisphere: COM at 3r/8 from its base; moment about its own COM
        # 83/320 m_h r^2 (m_h = ms/2), shifted to the capsule's centre
        d = L / 2 + 3 * r / 8
        trans = mc * (3 * r * r + L * L) / 12 + 2 * (
            (ms / 2) * (83 / 320) * r * r + (ms / 2) * d * d
        )
        return (trans, trans, axial)

    @property
    def bound(self) -> float:
        return self.radius + self.half_length


@dataclass(frozen=True)
class Cylinder:
    """A solid right circular cylinder of ``radius`` and ``half_length`` along principal
    axis 3 (m). Its contact with a plane is a point of a rim (tilted), a segment of the side
    (lying, both rims touching: two contacts, exact for a rigid body) or its flat face
    (standing: a disk, which the scheme does not treat exactly and refuses)."""

    radius: float
    half_length: float

    def __post_init__(self):
        object.__setattr__(self, "radius", _positive("Cylinder radius", self.radius))
        object.__setattr__(self, "half_length", _positive("Cylinder half_length", self.half_length))

    def inertia(self, mass: float) -> tuple:
        """Principal moments of a solid cylinder: m (3 r^2 + L^2)/12 across, m r^2/2 along."""
        r, L = self.radius, 2.0 * self.half_length
        t = mass * (3 * r * r + L * L) / 12
        return (t, t, mass * r * r / 2)

    @property
    def bound(self) -> float:
        return math.hypot(self.radius, self.half_length)


@dataclass(frozen=True)
class Plane:
    """A fixed plane {x : n . x = offset} with unit normal n = normal/|normal|; the outside
    (where bodies are) is n . x > offset. :meth:`through` gives the plane through a point,
    :meth:`incline` the ground tilted about the world y axis."""

    normal: tuple = (0.0, 0.0, 1.0)
    offset: float = 0.0

    def __post_init__(self):
        n = _vec3("Plane normal", self.normal)
        nn = float(np.linalg.norm(n))
        if not nn > 0.0:
            raise InvalidContactError(f"Plane normal = {list(self.normal)}: must be nonzero")
        try:
            c = float(self.offset)
        except (TypeError, ValueError):
            raise InvalidContactError(
                f"Plane offset = {self.offset!r}: expected a number"
            ) from None
        if not math.isfinite(c):
            raise InvalidContactError(f"Plane offset = {self.offset!r}: must be finite")
        object.__setattr__(self, "normal", tuple(float(x) for x in n / nn))
        object.__setattr__(self, "offset", c)

    @classmethod
    def through(cls, normal, point) -> Plane:
        """The plane with this normal through this point."""
        n = _vec3("Plane normal", normal)
        nn = float(np.linalg.norm(n))
        if not nn > 0.0:
            raise InvalidContactError(f"Plane normal = {list(normal)}: must be nonzero")
        return cls(tuple(n / nn), float(n / nn @ _vec3("Plane point", point)))

    @classmethod
    def incline(cls, angle: float, offset: float = 0.0) -> Plane:
        """The ground z = 0 rotated by ``angle`` (rad) about the world y axis, shifted by
        ``offset`` along its normal: normal (sin a, 0, cos a), descending towards +x for
        a > 0; :func:`incline_frame` gives its downhill and normal unit vectors."""
        return cls((math.sin(angle), 0.0, math.cos(angle)), offset)


def incline_frame(angle: float) -> tuple[np.ndarray, np.ndarray]:
    """(downhill, normal) unit vectors of ``Plane.incline(angle)``: n = (sin a, 0, cos a)
    and the steepest descent s = (cos a, 0, -sin a) (s . n = 0; gravity -z has the
    component g sin a along s and -g cos a along n)."""
    return (
        np.array([math.cos(angle), 0.0, -math.sin(angle)]),
        np.array([math.sin(angle), 0.0, math.cos(angle)]),
    )


SHAPES = (Sphere, Box, Capsule, Cylinder)
