"""Mass properties of MJCF's primitive geoms (sphere, capsule, cylinder, box, ellipsoid) of
uniform density, for bodies whose inertia the file leaves to its geoms
(``inertiafromgeom``).

Each function returns (volume m^3, principal moments per unit mass (3,) about the centre,
in the geom's own axes, the third along a capsule's or cylinder's axis). Closed forms of
solid bodies (e.g. Hibbeler, *Engineering Mechanics: Dynamics*, table of mass moments); the
capsule is a cylinder of length h plus two hemispheres of radius r, each hemisphere's centre
of mass 3r/8 from its flat face, moved by the parallel-axis theorem:
I_perp = m_c (3 r^2 + h^2)/12 + m_s (2 r^2/5 + 3 r h/8 + h^2/4), I_axis = m_c r^2/2 +
2 m_s r^2/5, with m_c the cylinder's mass and m_s the two hemispheres'. Meshes, planes, height
fields and signed-distance shapes have no closed form here: a body that needs their mass
properties is refused by the MJCF reader with that reason.
"""

from __future__ import annotations

import math

import numpy as np

PRIMITIVES = ("sphere", "capsule", "cylinder", "box", "ellipsoid")


def sphere(r: float):
    return 4.0 / 3.0 * math.pi * r**3, np.full(3, 0.4 * r * r)


def ellipsoid(a: float, b: float, c: float):
    return 4.0 / 3.0 * math.pi * a * b * c, np.array(
        [b * b + c * c, a * a + c * c, a * a + b * b]
    ) / 5.0


def box(a: float, b: float, c: float):
    """Half-sizes a, b, c."""
    return 8.0 * a * b * c, np.array([b * b + c * c, a * a + c * c, a * a + b * b]) / 3.0


def cylinder(r: float, half: float):
    h = 2.0 * half
    return math.pi * r * r * h, np.array([(3 * r * r + h * h) / 12.0] * 2 + [0.5 * r * r])


def capsule(r: float, half: float):
    h = 2.0 * half
    vc = math.pi * r * r * h
    vs = 4.0 / 3.0 * math.pi * r**3
    v = vc + vs
    perp = vc * (3 * r * r + h * h) / 12.0 + vs * (0.4 * r * r + 0.375 * r * h + 0.25 * h * h)
    ax = vc * 0.5 * r * r + vs * 0.4 * r * r
    return v, np.array([perp, perp, ax]) / v


def mass_properties(kind: str, size) -> tuple[float, np.ndarray]:
    """(volume, principal moments per unit mass) of a primitive geom of MJCF ``size``
    (sphere: r; capsule and cylinder: r, half-length; box: half-sizes; ellipsoid: radii)."""
    s = [float(x) for x in size]
    if kind == "sphere":
        return sphere(s[0])
    if kind == "capsule":
        return capsule(s[0], s[1])
    if kind == "cylinder":
        return cylinder(s[0], s[1])
    if kind == "box":
        return box(s[0], s[1], s[2])
    if kind == "ellipsoid":
        return ellipsoid(s[0], s[1], s[2])
    raise ValueError(f"no closed-form mass properties for a {kind} geom")


#: how many size numbers each primitive needs
SIZE_COUNT = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3, "ellipsoid": 3}
