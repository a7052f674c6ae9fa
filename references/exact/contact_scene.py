"""The contact closed forms (:mod:`references.exact.contact`) built from a contact scene (a
system scenario with ``planes``, ``contacts`` and ``forces``; :mod:`scenarios.contact`): each
kind reads what it needs from the scene itself and refuses, with the reason, a scene it does
not describe (:class:`ReferenceNotApplicable`).

=================  ===============================================================================
``sliding_block``  one box body, one pair with a plane, on which it lies flat; gravity and the
                   scene's forces on it
``tipping_block``  one box body on one plane, at rest
``rolling``        one sphere, or one cylinder lying on its side, touching one plane at its lowest
                   point; e the direction of the initial velocity (downhill when at rest), the
                   spin about n x e; k = a . I a/(m r^2) from the body's inertia
``bounce``         one body above one plane, at rest or moving along the normal; free, or on a
                   prismatic joint to the ground along the normal (it carries no force then)
``resting``        every body at rest; each body's support is the pair below it (the plane, or
                   the body whose centre is lowest among those it touches)
``hinged_strike``  one body on a revolute joint to the ground, a sphere at its centre of mass
                   above one plane, frictionless, released at rest
                   (:mod:`references.exact.contact_hinged`)
=================  ===============================================================================

Every other kind describes free bodies: a scene with joints is refused by them.
"""

from __future__ import annotations

import numpy as np

from references.exact._util import ReferenceNotApplicable
from references.exact.contact import (
    GEOMETRY_TOL,
    Bounce,
    ContactMotion,
    Resting,
    Rolling,
    SlidingBlock,
    TippingBlock,
)
from scenarios.system import CONTACT_CLOSED_FORMS

#: the contact closed forms by kind (declared with the scenario schema)
KINDS = CONTACT_CLOSED_FORMS


def _one_body_on_plane(sc, kind: str, shapes: tuple[str, ...]):
    """(body, plane, pair) of a scene of one body touching one plane."""
    if len(sc.bodies) != 1 or len(sc.contacts) != 1 or not sc.contacts[0].b_is_plane:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} describes one body touching one plane "
            f"({len(sc.bodies)} bodies, {len(sc.contacts)} pairs here)"
        )
    body = sc.bodies[0]
    if body.shape.kind not in shapes:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} describes a {' or '.join(shapes)}, not a "
            f"{body.shape.kind}"
        )
    pair = sc.contacts[0]
    plane = next(p for p in sc.planes if p.name == pair.b)
    return body, plane, pair


def _shape_at_centre(sc, body, kind):
    s = body.shape
    if np.any(s.position != 0) or np.any(s.rotation != np.eye(3)):
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} needs the shape centred at the centre of mass with "
            "the body's axes"
        )


def _slider_along_normal(sc) -> None:
    """Accept for ``bounce`` a body on one prismatic joint to the ground whose axis is the
    plane's normal, without spin: the joint then only forbids what the free motion along the
    normal never does (turning, moving across), so it carries no force and the closed form
    holds as for a free body."""
    (j,) = sc.joints if len(sc.joints) == 1 else (None,)
    if j is None or j.kind != "prismatic" or j.body_b is not None or len(sc.planes) != 1:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: bounce describes a free body, or one on a single prismatic "
            "joint to the ground above one plane"
        )
    body = next(b for b in sc.bodies if b.name == j.body_a)
    axis = body.rotation @ np.asarray(j.axis_a, dtype=float)
    axis = axis / np.linalg.norm(axis)
    n = np.asarray(sc.planes[0].normal, dtype=float)
    if float(np.linalg.norm(np.cross(axis, n))) > GEOMETRY_TOL:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: joint {j.name!r}'s axis {axis.tolist()} is not the plane's "
            f"normal {n.tolist()}: the slider would carry forces bounce does not describe"
        )
    if np.any(np.asarray(body.omega_body) != 0):
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: a body on a prismatic joint cannot spin"
        )


def _forces_on(sc, name):
    return [(f.force, f.point) for f in sc.forces if f.body == name]


def builder(sc):
    """The closed form of the scene ``sc`` (its ``reference`` kind): an object with
    ``motion(t) -> ContactMotion``."""
    kind = sc.reference
    g = np.asarray(sc.gravity, dtype=float)
    if kind not in KINDS:
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: {kind!r} is not a contact kind")
    if kind == "hinged_strike":
        return _hinged(sc, g)
    if kind == "bounce" and sc.joints:
        _slider_along_normal(sc)
    elif sc.joints:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} describes free bodies; the scene has joints"
        )
    if kind == "resting":
        return _resting(sc, g)
    shapes = {
        "sliding_block": ("box",),
        "tipping_block": ("box",),
        "rolling": ("sphere", "cylinder"),
        "bounce": ("sphere", "box", "capsule", "cylinder"),
    }[kind]
    body, plane, pair = _one_body_on_plane(sc, kind, shapes)
    if kind != "bounce":
        _shape_at_centre(sc, body, kind)
    if kind == "sliding_block":
        if np.any(body.velocity != 0) or np.any(body.omega_body != 0):
            raise ReferenceNotApplicable(f"scenario {sc.name!r}: sliding_block starts at rest")
        return SlidingBlock(
            body.mass,
            body.shape.half_extents,
            body.position,
            body.rotation,
            plane.normal,
            pair.mu,
            g,
            _forces_on(sc, body.name),
        )
    if sc.forces:
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: {kind} takes no external force")
    if kind == "tipping_block":
        if np.any(body.velocity != 0) or np.any(body.omega_body != 0):
            raise ReferenceNotApplicable(f"scenario {sc.name!r}: tipping_block starts at rest")
        return TippingBlock(
            body.mass,
            body.inertia,
            body.shape.half_extents,
            body.position,
            body.rotation,
            plane.normal,
            pair.mu,
            g,
        )
    if kind == "rolling":
        return _rolling(sc, body, plane, pair, g)
    n = plane.normal
    v = np.asarray(body.velocity, dtype=float)
    if float(np.linalg.norm(v - (v @ n) * n)) > GEOMETRY_TOL * max(1.0, float(np.linalg.norm(v))):
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: bounce moves along the normal only")
    W = np.asarray(body.omega_body, dtype=float)
    w = body.rotation @ W
    if pair.mu > 0 and float(np.linalg.norm(w - (w @ n) * n)) > 0:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: a spin across the normal meets friction at the impact"
        )
    from scenarios.contact import plane_distance

    z0 = float(plane_distance(body.shape, plane, body.position, body.rotation)[0])
    if body.shape.kind != "sphere" and float(np.linalg.norm(w)) > 0:
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: only a sphere may spin in bounce")
    return Bounce(max(z0, 0.0), body.position, body.rotation, n, pair.e, g, float(v @ n), W)


def _rolling(sc, body, plane, pair, g):
    n = plane.normal
    v = np.asarray(body.velocity, dtype=float)
    if float(abs(v @ n)) > GEOMETRY_TOL * max(1.0, float(np.linalg.norm(v))):
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: rolling starts on the plane")
    if float(np.linalg.norm(v)) > 0:
        e = v / float(np.linalg.norm(v))
    else:
        gt = g - (g @ n) * n
        if not float(np.linalg.norm(gt)) > 0:
            raise ReferenceNotApplicable(f"scenario {sc.name!r}: at rest on level ground")
        e = gt / float(np.linalg.norm(gt))
    a = np.cross(n, e)
    w = body.rotation @ body.omega_body
    if float(np.linalg.norm(w - (w @ a) * a)) > GEOMETRY_TOL * max(1.0, float(np.linalg.norm(w))):
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: rolling spins about n x e (n the normal, e the direction of "
            "motion) only"
        )
    s = body.shape
    if s.kind == "cylinder":
        axis = body.rotation[:, 2]
        if abs(abs(float(axis @ a)) - 1.0) > GEOMETRY_TOL:
            raise ReferenceNotApplicable(
                f"scenario {sc.name!r}: the cylinder's axis must lie across the motion (n x e)"
            )
    Iw = body.rotation @ np.diag(body.inertia) @ body.rotation.T
    k = float(a @ Iw @ a) / (body.mass * s.radius**2)
    return Rolling(
        body.mass,
        s.radius,
        k,
        body.position,
        body.rotation,
        n,
        e,
        float(v @ e),
        float(w @ a),
        pair.mu,
        g,
    )


def _resting(sc, g):
    for b in sc.bodies:
        if np.any(b.velocity != 0) or np.any(b.omega_body != 0):
            raise ReferenceNotApplicable(f"scenario {sc.name!r}: resting starts at rest")
    if sc.forces:
        raise ReferenceNotApplicable(f"scenario {sc.name!r}: resting takes no external force")
    idx = {b.name: i for i, b in enumerate(sc.bodies)}
    up = -g / float(np.linalg.norm(g))
    height = [float(b.position @ up) for b in sc.bodies]
    supports = []
    for i, b in enumerate(sc.bodies):
        below = []
        for c in sc.contacts:
            if b.name not in (c.a, c.b):
                continue
            other = c.b if c.a == b.name else c.a
            if c.b_is_plane and c.a == b.name:
                below.append((-np.inf, -1))
            elif not c.b_is_plane and height[idx[other]] < height[i]:
                below.append((height[idx[other]], idx[other]))
        if not below:
            raise ReferenceNotApplicable(
                f"scenario {sc.name!r}: body {b.name!r} rests on nothing listed in [[contacts]]"
            )
        supports.append(max(below)[1] if all(h > -np.inf for h, _ in below) else -1)
    return Resting(
        [b.mass for b in sc.bodies],
        [b.position for b in sc.bodies],
        [b.rotation for b in sc.bodies],
        supports,
        g,
    )


def _hinged(sc, g):
    from references.exact.contact_hinged import HingedStrike

    kind = "hinged_strike"
    body, plane, pair = _one_body_on_plane(sc, kind, ("sphere",))
    _shape_at_centre(sc, body, kind)
    (j,) = sc.joints if len(sc.joints) == 1 else (None,)
    if j is None or j.kind != "revolute" or j.body_b is not None:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} describes one revolute joint to the ground"
        )
    if pair.mu != 0:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} is frictionless (mu = {pair.mu:g} here): friction "
            "at the impact has no closed form here"
        )
    if np.any(body.velocity != 0) or np.any(body.omega_body != 0) or sc.forces:
        raise ReferenceNotApplicable(
            f"scenario {sc.name!r}: {kind} starts at rest, with no external force"
        )
    return HingedStrike(
        body.mass, body.inertia, body.position, body.rotation, j.anchor_b, j.axis_b,
        body.shape.radius, plane.normal, plane.point, pair.e, g,
    )  # fmt: skip


def contact_motion(sc, t) -> ContactMotion:
    """The closed-form motion of the scene ``sc`` at the times ``t``."""
    return builder(sc).motion(t)
