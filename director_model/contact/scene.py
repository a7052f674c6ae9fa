"""A contact scene: bodies with shapes, fixed planes, the pairs that touch, joints, loads.

:class:`ContactScene` checks everything before any step and builds the arrays of the compiled
kernel (director_model.contact._kernels): the bodies and joints through
director_model.system (the same Body, Joint and checks), the contact features of each pair
(director_model.contact._geometry), the point forces. Every refusal names the body, plane or
pair, the value and the rule (:class:`InvalidContactError`, or the system's errors for
bodies and joints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from director_model.contact import _geometry as G
from director_model.contact.shapes import (
    Box,
    Capsule,
    Cylinder,
    InvalidContactError,
    Plane,
    Sphere,
)
from director_model.system.model import Body, assemble
from director_model.system.states import check_initial

#: a feature overlapping by more than this (m) times the scene's length scale at t = 0 is
#: refused (bodies placed in contact have gaps of a few ulps of their coordinates)
INIT_PEN_TOL = 1e-12

# pair kinds of the kernel's pair table
PK_PLANE = 0
PK_BODY = 1
PK_BOXBOX = 2

_SHAPE_KIND = {Sphere: 1, Box: 2, Capsule: 3, Cylinder: 4}

#: pairs of shapes the scheme refuses, with the reason
_REFUSED = {
    ("capsule", "capsule"): "two capsules touch along a segment when their axes are parallel; "
    "the scheme's point features do not represent that contact exactly",
    ("box", "capsule"): "the box-capsule distance (segment against box) is not implemented",
    ("capsule", "cylinder"): "cylinder-capsule contact is not implemented",
    ("cylinder", "sphere"): "cylinder-sphere contact is not implemented",
    ("box", "cylinder"): "cylinder-box contact is not implemented",
    ("cylinder", "cylinder"): "cylinder-cylinder contact is not implemented",
}


@dataclass(frozen=True)
class Pair:
    """Two bodies, or a body and a plane (names), that may touch, with their isotropic
    Coulomb friction coefficient ``mu`` >= 0 and Newton restitution coefficient ``e`` in
    [0, 1] (normal rebound speed = e x approach speed). Pairs not listed never touch."""

    a: str
    b: str
    mu: float = 0.0
    e: float = 0.0


@dataclass(frozen=True)
class PointForce:
    """A constant force (N, world axes) applied at a point of a body (m, its principal frame
    relative to its centre of mass; default the centre of mass)."""

    body: str
    force: tuple
    point: tuple = (0.0, 0.0, 0.0)


def _kind_name(shape) -> str:
    return type(shape).__name__.lower()


def _number(where: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidContactError(f"{where} = {value!r}: expected a number") from None
    if not math.isfinite(v):
        raise InvalidContactError(f"{where} = {value!r}: must be finite")
    return v


class ContactScene:
    """Bodies (director_model.system.Body: name, mass, principal moments, initial state),
    their ``shapes`` (dict body name -> Sphere, Box, Capsule or Cylinder; a body without a
    shape touches nothing), fixed ``planes`` (dict name -> Plane), the contact ``pairs``
    (Pair, by name), ``joints`` (director_model.system.Joint), constant point ``forces``
    (PointForce) and uniform ``gravity`` (m/s^2). Raises InvalidContactError (shapes,
    planes, pairs, forces, overlap at t = 0) or the system's errors (bodies, joints)."""

    def __init__(self, bodies, shapes, planes=None, pairs=(), joints=(), forces=(),
                 gravity=(0.0, 0.0, -9.81)):  # fmt: skip
        self.bodies = list(bodies)
        self.joints = list(joints)
        self.asm = assemble(self.bodies, self.joints)
        if self.joints:
            check_initial(self.asm, self.bodies)
        names = self.asm.names
        index = {n: i for i, n in enumerate(names)}
        self.shapes = dict(shapes or {})
        self.planes = dict(planes or {})
        for bn, sh in self.shapes.items():
            if bn not in index:
                raise InvalidContactError(
                    f"shapes[{bn!r}]: unknown body; the bodies are {list(names)}"
                )
            if type(sh) not in _SHAPE_KIND:
                raise InvalidContactError(
                    f"shapes[{bn!r}] = {sh!r}: expected a Sphere, Box, Capsule or Cylinder"
                )
        for pn, pl in self.planes.items():
            if not isinstance(pl, Plane):
                raise InvalidContactError(f"planes[{pn!r}] = {pl!r}: expected a Plane")
            if pn in index:
                raise InvalidContactError(
                    f"planes[{pn!r}]: the name is also a body's; names must be unique"
                )
        self.gravity = np.array([_number(f"gravity[{k}]", v) for k, v in enumerate(gravity)])
        if self.gravity.shape != (3,):
            raise InvalidContactError(f"gravity = {gravity!r}: expected 3 numbers")
        nb = len(self.bodies)
        SH = np.zeros((nb, 4))
        for bn, sh in self.shapes.items():
            i = index[bn]
            SH[i, 0] = _SHAPE_KIND[type(sh)]
            if isinstance(sh, Box):
                SH[i, 1:4] = sh.half_extents
            elif isinstance(sh, Sphere):
                SH[i, 1] = sh.radius
            else:
                SH[i, 1:3] = (sh.radius, sh.half_length)
        self.SH = SH
        # pairs and their features
        FI, FV, PI, PV, self.feature_text, self.pair_names = [], [], [], [], [], []
        self.pair_sign = []
        seen = set()
        for k, pr in enumerate(pairs):
            if not isinstance(pr, Pair):
                raise InvalidContactError(f"pairs[{k}] = {pr!r}: expected a Pair")
            where = f"pair {pr.a!r}-{pr.b!r}"
            mu = _number(where + ": mu", pr.mu)
            e = _number(where + ": e", pr.e)
            if mu < 0.0:
                raise InvalidContactError(f"{where}: mu = {pr.mu!r}: must be >= 0")
            if not 0.0 <= e <= 1.0:
                raise InvalidContactError(f"{where}: e = {pr.e!r}: must be in [0, 1]")
            key = frozenset((pr.a, pr.b))
            if key in seen or pr.a == pr.b:
                raise InvalidContactError(f"{where}: listed twice, or a body paired with itself")
            seen.add(key)
            for nm in (pr.a, pr.b):
                if nm not in index and nm not in self.planes:
                    raise InvalidContactError(
                        f"{where}: {nm!r} is neither a body nor a plane; bodies "
                        f"{list(names)}, planes {list(self.planes)}"
                    )
                if nm in index and nm not in self.shapes:
                    raise InvalidContactError(f"{where}: body {nm!r} has no shape in shapes")
            f0 = len(FI)
            p = len(PI)
            self.pair_sign.append(1.0)
            a_name, b_name = pr.a, pr.b
            if a_name in self.planes and b_name in self.planes:
                raise InvalidContactError(f"{where}: two planes never move; pair a body")
            if a_name in self.planes:
                a_name, b_name = b_name, a_name
            if b_name in self.planes:
                pk = PK_PLANE
                self._plane_features(p, index[a_name], a_name, b_name, FI, FV)
                a, b = index[a_name], -1
            else:
                ka, kb = _kind_name(self.shapes[a_name]), _kind_name(self.shapes[b_name])
                order = {"capsule": 0, "sphere": 1, "box": 2, "cylinder": 3}
                if order[ka] > order[kb]:
                    # the kernel's body a is the pair's b: its force on a comes out
                    # negated (pair_force is on the pair's first body)
                    a_name, b_name, ka, kb = b_name, a_name, kb, ka
                    self.pair_sign[p] = -1.0
                refuse = _REFUSED.get(tuple(sorted((ka, kb))))
                if refuse:
                    raise InvalidContactError(f"{where}: a {ka}-{kb} pair is refused: {refuse}")
                a, b = index[a_name], index[b_name]
                pk = PK_BOXBOX if ka == kb == "box" else PK_BODY
                self._body_features(p, a, b, a_name, b_name, ka, kb, FI, FV)
            bnd_a = self.shapes[a_name].bound
            bnd_b = self.shapes[b_name].bound if b >= 0 else 0.0
            PI.append((pk, a, b, f0, len(FI) - f0))
            PV.append((mu, e, bnd_a, bnd_b))
            self.pair_names.append((pr.a, pr.b))
        self.FI = np.array(FI, dtype=np.int64).reshape(-1, 4)
        self.FV = np.array(FV, dtype=float).reshape(-1, 10)
        self.PI = np.array(PI, dtype=np.int64).reshape(-1, 5)
        self.PV = np.array(PV, dtype=float).reshape(-1, 4)
        fb, fv = [], []
        for k, pf in enumerate(forces):
            if not isinstance(pf, PointForce):
                raise InvalidContactError(f"forces[{k}] = {pf!r}: expected a PointForce")
            if pf.body not in index:
                raise InvalidContactError(
                    f"forces[{k}]: body {pf.body!r} unknown; the bodies are {list(names)}"
                )
            fvec = [_number(f"forces[{k}].force[{j}]", v) for j, v in enumerate(pf.force)]
            pvec = [_number(f"forces[{k}].point[{j}]", v) for j, v in enumerate(pf.point)]
            if len(fvec) != 3 or len(pvec) != 3:
                raise InvalidContactError(f"forces[{k}]: force and point need 3 numbers each")
            fb.append(index[pf.body])
            fv.append(fvec + pvec)
        self.fb = np.array(fb, dtype=np.int64)
        self.fv = np.array(fv, dtype=float).reshape(-1, 6)
        self.length_scale = max(
            [1.0] + [float(np.abs(b.position).max()) for b in self.bodies]
            + [s.bound for s in self.shapes.values()]
        )  # fmt: skip
        self._check_initial()

    # ------------------------------------------------------------------ features
    def _plane_features(self, p, a, a_name, plane_name, FI, FV):
        sh = self.shapes[a_name]
        pl = self.planes[plane_name]
        n = list(pl.normal)
        c = pl.offset
        tag = f"{type(sh).__name__.lower()} {a_name!r} against plane {plane_name!r}"
        if isinstance(sh, Sphere):
            FI.append((G.K_PLANE_SPHERE, a, -1, p))
            FV.append(n + [c, sh.radius] + [0.0] * 5)
            self.feature_text.append(tag)
        elif isinstance(sh, Box):
            for k, v in enumerate(sh.vertices()):
                FI.append((G.K_PLANE_VERTEX, a, -1, p))
                FV.append(n + [c] + list(v) + [0.0] * 3)
                self.feature_text.append(f"vertex {k} {tuple(v.tolist())} of {tag}")
        else:
            kind = G.K_PLANE_CAPSULE if isinstance(sh, Capsule) else G.K_PLANE_RIM
            part = "end sphere" if isinstance(sh, Capsule) else "rim"
            for s in (-sh.half_length, sh.half_length):
                FI.append((kind, a, -1, p))
                FV.append(n + [c, sh.radius, s] + [0.0] * 4)
                self.feature_text.append(f"{part} at {s:+g} e3 of {tag}")

    def _body_features(self, p, a, b, a_name, b_name, ka, kb, FI, FV):
        sa, sb = self.shapes[a_name], self.shapes[b_name]
        tag = f"{ka} {a_name!r} against {kb} {b_name!r}"
        if ka == kb == "sphere":
            FI.append((G.K_SPHERE_SPHERE, a, b, p))
            FV.append([sa.radius, sb.radius] + [0.0] * 8)
            self.feature_text.append(tag)
        elif (ka, kb) == ("sphere", "box"):
            FI.append((G.K_SPHERE_BOX, a, b, p))
            FV.append([sa.radius, *sb.half_extents] + [0.0] * 6)
            self.feature_text.append(tag)
        elif (ka, kb) == ("capsule", "sphere"):
            FI.append((G.K_CAPSULE_SPHERE, a, b, p))
            FV.append([sa.radius, sa.half_length, sb.radius] + [0.0] * 7)
            self.feature_text.append(tag)
        else:  # box-box: the vertices of each against the faces of the other
            for (i, j, si, sj, ni, nj, rev) in ((a, b, sa, sb, a_name, b_name, 0.0),
                                               (b, a, sb, sa, b_name, a_name, 1.0)):  # fmt: skip
                for k, v in enumerate(si.vertices()):
                    FI.append((G.K_BOX_VERTEX, i, j, p))
                    FV.append(list(v) + list(sj.half_extents) + [rev] + [0.0] * 3)
                    self.feature_text.append(
                        f"vertex {k} {tuple(v.tolist())} of box {ni!r} against box {nj!r}"
                    )

    # ------------------------------------------------------------------ checks
    def state_arrays(self):
        """Positions (nb, 3) and directors (nb, 9, row-major) of the initial state."""
        X = np.array([b.position for b in self.bodies], dtype=float)
        Dm = np.array([b.rotation.ravel() for b in self.bodies], dtype=float)
        return X, Dm

    def features_at(self, X, Dm, margin=0.0):
        """(valid, inexact, gap, distance) of every feature (nfeat, 4) and the box-box pairs
        within ``margin`` not treated exactly (npair,) at positions X, directors Dm."""
        from director_model.contact._kernels import features_at

        out = np.zeros((self.FI.shape[0], 4))
        status = np.zeros(self.PI.shape[0], dtype=np.int64)
        features_at(self.FI, self.FV, self.PI, self.PV, self.SH, np.ascontiguousarray(X),
                    np.ascontiguousarray(Dm), float(margin), out, status)  # fmt: skip
        return out, status

    def _check_initial(self):
        if self.FI.shape[0] == 0:
            return
        X, Dm = self.state_arrays()
        tol = INIT_PEN_TOL * self.length_scale
        out, status = self.features_at(X, Dm, tol)
        for p in np.flatnonzero(status):
            a, b = self.pair_names[p]
            raise InvalidContactError(
                f"pair {a!r}-{b!r}: the boxes touch at t = 0 along an edge or with crossing "
                "faces, a contact whose corners are not vertices of the boxes: not treated "
                "exactly (refused)"
            )
        for f in range(out.shape[0]):
            valid, inexact, gap = out[f, 0] > 0, out[f, 1] > 0, out[f, 2]
            if not valid:
                continue
            a, b = self.pair_names[self.FI[f, 3]]
            if inexact and out[f, 3] <= tol:
                raise InvalidContactError(
                    f"pair {a!r}-{b!r}: {self.feature_text[f]}: a contact the scheme does not "
                    "treat exactly at t = 0 (a cylinder on its flat face: a disk; a sphere's "
                    "centre inside a box)"
                )
            if gap < -tol:
                raise InvalidContactError(
                    f"pair {a!r}-{b!r}: the bodies overlap at t = 0: {self.feature_text[f]} "
                    f"penetrates by {-gap:.6g} m (tolerance {tol:.3g} m); place them apart "
                    "or touching"
                )


__all__ = ["Body", "ContactScene", "Pair", "PointForce"]
