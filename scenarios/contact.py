"""Contact in scenario files: collision shapes on bodies, static planes, the pairs that touch
(Coulomb ``mu`` and Newton ``e`` per pair) and constant external forces, with the suite's own
contact geometry (signed distances of shapes to planes and to each other).

A system file (docs/scenarios.md, "Contact") adds to its ``[[bodies]]``::

    [bodies.shape]                  # the body's collision shape (optional)
    kind = "box"                    # sphere (radius), box (half_extents),
    half_extents = [0.1, 0.1, 0.1]  # capsule and cylinder (radius, half_length along axis 3)
    position = [0.0, 0.0, 0.0]      # shape centre, body axes rel. to the centre of mass
    rotation_vector = [0.0, 0.0, 0.0]  # shape axes in body axes

and at the top level ``[[planes]]`` (name, unit outward ``normal``, a ``point`` of the
surface), ``[[contacts]]`` (``pair`` = two names, at least one a body; ``mu`` >= 0; ``e`` in
[0, 1]) and ``[[forces]]`` (``body``, ``force`` world N, ``point`` body axes rel. to the
centre of mass). Only the listed pairs touch.

Geometry (the one implementation: the file check at t = 0 and the penetration metrics):
the signed distance of a convex shape to the plane n . x = c is n . x_s - c - h(n), h the
shape's extent along -n (sphere r; box sum a_i |n . e_i|; capsule r + l |n . a|; cylinder
l |n . a| + r sqrt(1 - (n . a)^2)); between bodies: sphere-sphere exactly, sphere-box by the
closest point of the box, box-box by the separating-axis test over the 15 axes (exact when the
boxes overlap: the penetration depth; a lower bound of the distance when apart). Other
body-body pairs are refused with that reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.model import frozen
from scenarios.schema import did_you_mean

SHAPE_KINDS = ("sphere", "box", "capsule", "cylinder")
#: the body-body pairs the suite's geometry measures (unordered)
BODY_PAIRS = (("sphere", "sphere"), ("box", "sphere"), ("box", "box"))
#: a shape may penetrate a plane or another shape by at most this at t = 0 (m): the files print
#: 17 significant digits, so a box set on a 30 degree ramp is placed to ~1e-16 m
CONTACT_INIT_TOL = 1e-9
#: a plane's normal must be unit to this (never normalised silently)
NORMAL_TOL = 1e-12

_SHAPE_KEYS = {
    "kind": "str",
    "radius": "number",
    "half_extents": "vec3",
    "half_length": "number",
    "position": "vec3",
    "rotation_vector": "vec3",
}
_SIZE_KEYS = {
    "sphere": ("radius",),
    "box": ("half_extents",),
    "capsule": ("radius", "half_length"),
    "cylinder": ("radius", "half_length"),
}
_PLANE_KEYS = {"name": "name", "normal": "vec3", "point": "vec3"}
_PAIR_KEYS = {"pair": "str_list", "mu": "number", "e": "number"}
_FORCE_KEYS = {"body": "str", "force": "vec3", "point": "vec3"}


@dataclass(frozen=True, eq=False)
class Shape:
    """A convex collision shape fixed to a body: ``kind`` (:data:`SHAPE_KINDS`), ``radius``
    (m; sphere, capsule, cylinder), ``half_extents`` (3,) m (box), ``half_length`` (m, along the
    shape's axis 3; capsule, cylinder), ``position`` (3,) m and ``rotation`` (3, 3) of the
    shape's frame in the body's principal frame (relative to the centre of mass)."""

    kind: str
    radius: float = 0.0
    half_extents: np.ndarray | None = None
    half_length: float = 0.0
    position: np.ndarray = None  # type: ignore[assignment]
    rotation: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self):
        object.__setattr__(
            self, "position", frozen(np.zeros(3) if self.position is None else self.position)
        )
        object.__setattr__(
            self, "rotation", frozen(np.eye(3) if self.rotation is None else self.rotation)
        )
        if self.half_extents is not None:
            object.__setattr__(self, "half_extents", frozen(self.half_extents))
        object.__setattr__(self, "radius", float(self.radius))
        object.__setattr__(self, "half_length", float(self.half_length))

    @property
    def size(self) -> float:
        """The shape's smallest dimension (m): the length scale of its contact errors."""
        if self.kind == "box":
            return float(np.min(self.half_extents))
        return self.radius

    @property
    def extent(self) -> float:
        """The largest distance from the shape's centre to its surface (m)."""
        if self.kind == "box":
            return float(np.linalg.norm(self.half_extents))
        return self.radius + self.half_length

    def to_dict(self) -> dict:
        d = {
            "kind": self.kind,
            "position": self.position.tolist(),
            "rotation": self.rotation.tolist(),
        }
        if self.kind == "box":
            d["half_extents"] = self.half_extents.tolist()
        else:
            d["radius"] = self.radius
        if self.kind in ("capsule", "cylinder"):
            d["half_length"] = self.half_length
        return d


@dataclass(frozen=True, eq=False)
class Plane:
    """A static half-space n . x >= c: ``name``, unit outward ``normal`` (3,), ``point`` (3,)
    of its surface."""

    name: str
    normal: np.ndarray
    point: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "normal", frozen(self.normal))
        object.__setattr__(self, "point", frozen(self.point))

    @property
    def offset(self) -> float:
        """c in n . x = c (m)."""
        return float(self.normal @ self.point)

    def to_dict(self) -> dict:
        return {"name": self.name, "normal": self.normal.tolist(), "point": self.point.tolist()}


@dataclass(frozen=True, eq=False)
class ContactPair:
    """A pair that may touch: body ``a``, and ``b`` a body or a plane (``b_is_plane``);
    Coulomb ``mu``, Newton ``e``."""

    a: str
    b: str
    b_is_plane: bool
    mu: float
    e: float

    def to_dict(self) -> dict:
        return {"pair": [self.a, self.b], "mu": self.mu, "e": self.e}


@dataclass(frozen=True, eq=False)
class Force:
    """A constant force ``force`` (3,) N, world axes, on ``body`` at ``point`` (3,) m (body
    axes, relative to the centre of mass)."""

    body: str
    force: np.ndarray
    point: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "force", frozen(self.force))
        object.__setattr__(self, "point", frozen(self.point))

    def to_dict(self) -> dict:
        return {"body": self.body, "force": self.force.tolist(), "point": self.point.tolist()}


# -- geometry ------------------------------------------------------------------------------------


def shape_pose(shape: Shape, x, R) -> tuple[np.ndarray, np.ndarray]:
    """World centre (n, 3) and axes (n, 3, 3) of ``shape`` on a body at x (n, 3), R (n, 3, 3)."""
    x = np.asarray(x, dtype=float).reshape(-1, 3)
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    return x + R @ shape.position, R @ shape.rotation


def plane_distance(shape: Shape, plane: Plane, x, R) -> np.ndarray:
    """Signed distance (n,) m of ``shape`` (on a body at x (n, 3), R (n, 3, 3)) to ``plane``:
    > 0 apart, < 0 the depth of penetration."""
    c, A = shape_pose(shape, x, R)
    n = plane.normal
    dn = A.transpose(0, 2, 1) @ n  # the normal in the shape's axes, (n, 3)
    if shape.kind == "sphere":
        h = np.full(len(c), shape.radius)
    elif shape.kind == "box":
        h = np.abs(dn) @ shape.half_extents
    elif shape.kind == "capsule":
        h = shape.radius + shape.half_length * np.abs(dn[:, 2])
    else:  # cylinder
        ca = np.abs(dn[:, 2])
        h = shape.half_length * ca + shape.radius * np.sqrt(np.maximum(1.0 - ca * ca, 0.0))
    return c @ n - plane.offset - h


def lowest_point(shape: Shape, plane: Plane, x, R) -> np.ndarray:
    """The shape's point nearest the plane (n, 3), world (for a flat face or an edge: its
    centre)."""
    c, A = shape_pose(shape, x, R)
    n = plane.normal
    dn = A.transpose(0, 2, 1) @ n
    if shape.kind == "sphere":
        return c - shape.radius * n
    if shape.kind == "box":
        s = -np.sign(np.where(np.abs(dn) < 1e-12, 0.0, dn)) * shape.half_extents
        return c + np.einsum("nij,nj->ni", A, s)
    axis = A[:, :, 2]
    s = -np.sign(np.where(np.abs(dn[:, 2]) < 1e-12, 0.0, dn[:, 2]))
    end = c + (shape.half_length * s)[:, None] * axis
    if shape.kind == "capsule":
        return end - shape.radius * n
    rad = -(n - dn[:, 2:3] * axis)
    nr = np.linalg.norm(rad, axis=1, keepdims=True)
    rad = np.where(nr > 1e-12, rad / np.maximum(nr, 1e-300), 0.0)
    return end + shape.radius * rad


def _box_box(c1, A1, h1, c2, A2, h2) -> np.ndarray:
    """Separating-axis signed distance of two boxes (module docstring), (n,)."""
    axes = [A1[:, :, i] for i in range(3)] + [A2[:, :, i] for i in range(3)]
    for i in range(3):
        for j in range(3):
            axes.append(np.cross(A1[:, :, i], A2[:, :, j]))
    d = c2 - c1
    best = np.full(len(c1), -np.inf)
    for ax in axes:
        nrm = np.linalg.norm(ax, axis=1)
        ok = nrm > 1e-9
        u = ax / np.maximum(nrm, 1e-300)[:, None]
        r1 = np.abs(np.einsum("nji,nj->ni", A1, u)) @ h1
        r2 = np.abs(np.einsum("nji,nj->ni", A2, u)) @ h2
        sep = np.abs(np.einsum("ni,ni->n", d, u)) - r1 - r2
        best = np.where(ok, np.maximum(best, sep), best)
    return best


def body_distance(s1: Shape, x1, R1, s2: Shape, x2, R2) -> np.ndarray:
    """Signed distance (n,) m between two shapes on bodies (pairs of :data:`BODY_PAIRS`)."""
    c1, A1 = shape_pose(s1, x1, R1)
    c2, A2 = shape_pose(s2, x2, R2)
    kinds = (s1.kind, s2.kind)
    if kinds == ("sphere", "sphere"):
        return np.linalg.norm(c2 - c1, axis=1) - s1.radius - s2.radius
    if kinds == ("box", "box"):
        return _box_box(c1, A1, s1.half_extents, c2, A2, s2.half_extents)
    if kinds == ("sphere", "box"):
        return body_distance(s2, x2, R2, s1, x1, R1)
    if kinds == ("box", "sphere"):
        p = np.einsum("nji,nj->ni", A1, c2 - c1)  # the centre in the box's axes
        q = np.clip(p, -s1.half_extents, s1.half_extents)
        out = np.linalg.norm(p - q, axis=1)
        inside = np.all(np.abs(p) <= s1.half_extents, axis=1)
        depth = np.min(s1.half_extents - np.abs(p), axis=1)
        return np.where(inside, -depth, out) - s2.radius
    raise ValueError(f"no contact geometry for a {s1.kind}-{s2.kind} pair")


def pair_distance(scene, pair: ContactPair, x, R) -> np.ndarray:
    """Signed distance (n,) of ``pair`` of the scene with the bodies at x (n, nb, 3), R (n, nb,
    3, 3) in the order of ``scene.bodies``."""
    idx = {b.name: i for i, b in enumerate(scene.bodies)}
    x = np.asarray(x, dtype=float)
    R = np.asarray(R, dtype=float)
    ia = idx[pair.a]
    sa = scene.bodies[ia].shape
    if pair.b_is_plane:
        plane = next(p for p in scene.planes if p.name == pair.b)
        return plane_distance(sa, plane, x[:, ia], R[:, ia])
    ib = idx[pair.b]
    return body_distance(sa, x[:, ia], R[:, ia], scene.bodies[ib].shape, x[:, ib], R[:, ib])


# -- reading the file ----------------------------------------------------------------------------


def _typed(tab, keys, required, prefix, bad) -> dict:
    """The entries of ``tab`` of the right type; unknown, missing and mistyped ones reported
    with the field ``prefix.key`` (the rule of every table of a system file)."""
    from scenarios import schema as sch

    good = {}
    for key in tab:
        if key not in keys:
            bad(f"{prefix}.{key}", tab[key], f"unknown key; allowed here: {', '.join(keys)}")
    for key, kind in keys.items():
        if key not in tab:
            if key in required:
                bad(f"{prefix}.{key}", "<missing>", f"required: {sch._KIND_TEXT[kind]}")
        elif not sch._type_ok(kind, tab[key]):
            bad(f"{prefix}.{key}", tab[key], f"must be {sch._KIND_TEXT[kind]}")
        else:
            good[key] = tab[key]
    return good


def _array(data, key, bad) -> list:
    raw = data.get(key)
    if raw is None:
        return []
    if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
        bad(key, raw, f"must be an array of [[{key}]] tables")
        return []
    return raw


def read_shape(tab, prefix: str, bad) -> Shape | None:
    """The ``[bodies.shape]`` table of a body (``prefix`` = "bodies[i].shape"), or None."""
    from scenarios import schema as sch

    if not isinstance(tab, dict):
        bad(prefix, tab, "must be a table: kind and its sizes")
        return None
    good = _typed(tab, _SHAPE_KEYS, ("kind",), prefix, bad)
    kind = good.get("kind")
    if kind is None:
        return None
    if kind not in SHAPE_KINDS:
        bad(f"{prefix}.kind", kind, f"must be one of {', '.join(SHAPE_KINDS)}")
        return None
    ok = True
    for key in _SHAPE_KEYS:
        if key in ("kind", "position", "rotation_vector"):
            continue
        if key in _SIZE_KEYS[kind] and key not in tab:
            bad(f"{prefix}.{key}", "<missing>", f"required for a {kind}")
            ok = False
        elif key in tab and key not in _SIZE_KEYS[kind]:
            bad(f"{prefix}.{key}", tab[key], f"a {kind} takes only {', '.join(_SIZE_KEYS[kind])}")
            ok = False
    for key in _SIZE_KEYS[kind]:
        v = good.get(key)
        if v is None:
            ok = False
            continue
        vals = v if isinstance(v, list) else [v]
        least = 0.0 if key == "half_length" else None
        if least is None and not all(x > 0 for x in vals):
            bad(f"{prefix}.{key}", v, "a size must be > 0 m")
            ok = False
        elif least is not None and not all(x >= 0 for x in vals):
            bad(f"{prefix}.{key}", v, "a half length must be >= 0 m")
            ok = False
    if not ok:
        return None
    rot = sch.rotation_from_vector(good.get("rotation_vector", [0.0, 0.0, 0.0]))
    return Shape(
        kind=kind,
        radius=float(good.get("radius", 0.0)),
        half_extents=None if kind != "box" else np.array(good["half_extents"], dtype=float),
        half_length=float(good.get("half_length", 0.0)),
        position=np.array(good.get("position", [0.0, 0.0, 0.0]), dtype=float),
        rotation=rot,
    )


def read_contact_parts(data: dict, bodies, bad) -> tuple[tuple, tuple, tuple]:
    """``(planes, pairs, forces)`` of a system file's ``[[planes]]``, ``[[contacts]]`` and
    ``[[forces]]``; every problem through ``bad(field, value, rule)``. ``bodies`` are the
    file's bodies (their ``shape`` read already)."""
    names = {b.name: b for b in bodies}
    # what the file declares though it was refused (reported where it stands): a pair naming
    # a refused plane, or a body whose shape was refused, is not reported again
    refused = set()
    shaped = {
        t.get("name") for t in data.get("bodies") or [] if isinstance(t, dict) and "shape" in t
    }
    planes = []
    for i, tab in enumerate(_array(data, "planes", bad)):
        p = f"planes[{i}]"
        good = _typed(tab, _PLANE_KEYS, ("name", "normal"), p, bad)
        name = good.get("name", f"plane{i}")
        refused.add(name)
        if name in names:
            bad(f"{p}.name", name, "a plane's name must differ from every body's")
        if any(q.name == name for q in planes):
            bad(f"{p}.name", name, "plane names must be unique")
        n = good.get("normal")
        if n is None:
            continue
        norm = math.sqrt(sum(float(c) * float(c) for c in n))
        if abs(norm - 1.0) > NORMAL_TOL:
            bad(
                f"{p}.normal",
                n,
                f"must be a unit vector to {NORMAL_TOL:g} (|n| = {norm!r}); "
                "it is never normalised for you",
            )
            continue
        planes.append(
            Plane(
                name,
                np.array(n, dtype=float),
                np.array(good.get("point", [0.0, 0.0, 0.0]), dtype=float),
            )
        )
    plane_names = {q.name for q in planes}
    refused -= plane_names
    pairs = []
    seen = set()
    for i, tab in enumerate(_array(data, "contacts", bad)):
        p = f"contacts[{i}]"
        good = _typed(tab, _PAIR_KEYS, ("pair", "mu"), p, bad)
        mu, e = good.get("mu"), good.get("e", 0.0)
        if mu is not None and not mu >= 0:
            bad(f"{p}.mu", mu, "the friction coefficient must be >= 0")
            mu = None
        if "e" in good and not 0 <= e <= 1:
            bad(f"{p}.e", e, "the restitution coefficient must be in [0, 1]")
            e = None
        pair = good.get("pair")
        if pair is None:
            continue
        if len(pair) != 2:
            bad(f"{p}.pair", pair, "must name two things that touch: [body, body or plane]")
            continue
        a, b = pair
        known = ", ".join(sorted(names) + sorted(plane_names))
        problem = False
        for nm in pair:
            if nm in refused:
                problem = True
            elif nm not in names and nm not in plane_names:
                bad(
                    f"{p}.pair",
                    pair,
                    f"{nm!r} is neither a body nor a plane of this file"
                    f"{did_you_mean(nm, [*names, *plane_names])}; known: {known}",
                )
                problem = True
        if problem:
            continue
        if a in plane_names and b in plane_names:
            bad(f"{p}.pair", pair, "two planes never touch: a pair has at least one body")
            continue
        if a in plane_names:
            a, b = b, a
        if a == b:
            bad(f"{p}.pair", pair, "a body does not touch itself")
            continue
        key = frozenset((a, b))
        if key in seen:
            bad(f"{p}.pair", pair, "this pair is listed twice")
            continue
        seen.add(key)
        for nm in (a, b):
            if nm in names and names[nm].shape is None:
                if nm not in shaped:  # (a shape given but refused is reported as such)
                    bad(f"{p}.pair", pair, f"body {nm!r} has no [bodies.shape]: it cannot touch")
                problem = True
        if problem:
            continue
        if b in names:
            kinds = tuple(sorted((names[a].shape.kind, names[b].shape.kind)))
            if kinds not in BODY_PAIRS:
                bad(
                    f"{p}.pair",
                    pair,
                    f"a {kinds[0]}-{kinds[1]} pair is not measured by the "
                    "suite's contact geometry (it measures sphere-sphere, box-sphere, box-box "
                    "and every shape against a plane)",
                )
                continue
        if mu is None or e is None:
            continue
        pairs.append(ContactPair(a, b, b in plane_names, float(mu), float(e)))
    forces = []
    for i, tab in enumerate(_array(data, "forces", bad)):
        p = f"forces[{i}]"
        good = _typed(tab, _FORCE_KEYS, ("body", "force"), p, bad)
        body = good.get("body")
        if body is not None and body not in names:
            bad(f"{p}.body", body, f"not a body of this file; bodies: {', '.join(sorted(names))}")
            continue
        if body is None or "force" not in good:
            continue
        forces.append(
            Force(
                body,
                np.array(good["force"], dtype=float),
                np.array(good.get("point", [0.0, 0.0, 0.0]), dtype=float),
            )
        )
    return tuple(planes), tuple(pairs), tuple(forces)


def initial_penetrations(scene, bad) -> None:
    """Refuse (through ``bad``) every listed pair that penetrates at t = 0 by more than
    :data:`CONTACT_INIT_TOL`, naming the pair and the depth."""
    x = np.array([b.position for b in scene.bodies])[None]
    R = np.array([b.rotation for b in scene.bodies])[None]
    for i, pair in enumerate(scene.contacts):
        gap = float(pair_distance(scene, pair, x, R)[0])
        if gap < -CONTACT_INIT_TOL:
            what = "plane" if pair.b_is_plane else "body"
            rule = (
                f"body {pair.a!r} penetrates {what} {pair.b!r} by {-gap:.6g} m at t = 0 (rule: "
                f"shapes may not overlap at the start by more than {CONTACT_INIT_TOL:g} m; move "
                "the body out by that much)"
            )
            bad(f"contacts[{i}].pair", [pair.a, pair.b], rule)
