"""Our own MJCF reader: the parts of a MuJoCo XML file that enter the dynamics.

Read: ``<compiler>`` (``angle`` degree (MuJoCo's default) or radian, ``eulerseq``,
``inertiafromgeom`` false/true/auto, ``inertiagrouprange``; ``coordinate`` local only),
``<option gravity>``, ``<default>`` classes (nested, inherited; an element's class is its
``class``, else its nearest body's ``childclass``, else the top class), ``<include file>``
(inlined, at most :data:`MAX_INCLUDE_DEPTH` deep), and the ``<worldbody>`` tree: ``<body>``
with ``pos`` and one of ``quat`` (w x y z), ``axisangle``, ``euler``, ``xyaxes``, ``zaxis``;
``<inertial pos, orientation, mass, diaginertia | fullinertia (ixx iyy izz ixy ixz iyz)>``;
``<joint type=hinge|slide|ball|free pos axis ref range limited damping armature frictionloss
stiffness>`` and ``<freejoint>``; ``<geom>`` of the primitive types (their mass properties
from their volume and ``density`` or ``mass``, :mod:`scenarios.models.geoms`, with ``size``
or ``fromto``), counted as contact geometry when ``contype`` or ``conaffinity`` is non-zero;
``<actuator>`` children counted. A body without a joint is welded to its parent; several
joints in one body must all be held (``lock``) but one (:func:`scenarios.models.model.to_system`).

Refused with the reason (each names the file, the element and its line): a body whose mass
properties come from a mesh (or plane, height field, SDF) geom; ``shellinertia``;
``coordinate="global"``; ``<frame>``, ``<replicate>``, ``<attach>`` (not read here);
``<equality>`` constraints (loops); ``balanceinertia``, ``settotalmass``, ``boundmass``,
``boundinertia`` (they change the file's mass properties); malformed numbers; unknown
joint types. Reference: MuJoCo's XML reference (mujoco.readthedocs.io, "XML Reference").
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from scenarios.models import geoms as G
from scenarios.models.model import Inertial, Link, ModelJoint, RobotModel, pose, rotate_inertia
from scenarios.models.xml import ModelError, Node, parse
from scenarios.schema import rotation_from_quaternion, rotation_from_vector

MAX_INCLUDE_DEPTH = 8
JOINT_TYPES = {"hinge": "revolute", "slide": "prismatic", "ball": "ball", "free": "free"}
_REFUSED_ELEMENTS = {
    "frame": "a <frame> element (MuJoCo 3) is not read here; write its pose into its bodies",
    "replicate": "a <replicate> element is not read here; expand it",
    "attach": "an <attach> element is not read here; give the assembled model",
}


class _Reader:
    def __init__(self, path: str):
        self.path = str(path)
        self.angle = "degree"
        self.eulerseq = "xyz"
        self.fromgeom = "auto"
        self.grouprange = (0, 5)
        self.classes: dict = {}

    def bad(self, node: Node | None, rule: str) -> ModelError:
        where = node.label() if node is not None else "<mujoco>"
        return ModelError(
            f"model file {self.path}: {where}: {rule}", path=self.path, problems=[(where, rule)]
        )

    # -- numbers and frames --------------------------------------------------------------
    def nums(self, node: Node, attr: str, n: int | None, default=None, attrs=None):
        text = (attrs if attrs is not None else node.attrib).get(attr)
        if text is None:
            return None if default is None else np.asarray(default, dtype=float)
        try:
            vals = np.array([float(t) for t in text.split()], dtype=float)
        except ValueError:
            raise self.bad(node, f"{attr}={text!r}: not a list of numbers") from None
        if (n is not None and len(vals) != n) or not np.all(np.isfinite(vals)):
            raise self.bad(node, f"{attr}={text!r}: expected {n} finite numbers")
        return vals

    def angle_unit(self) -> float:
        return math.pi / 180.0 if self.angle == "degree" else 1.0

    def orientation(self, node: Node, attrs: dict) -> np.ndarray:
        forms = [k for k in ("quat", "axisangle", "euler", "xyaxes", "zaxis") if k in attrs]
        if len(forms) > 1:
            raise self.bad(
                node, f"orientation given {len(forms)} ways ({', '.join(forms)}): give one"
            )
        if not forms:
            return np.eye(3)
        k = forms[0]
        if k == "quat":
            q = self.nums(node, k, 4, attrs=attrs)
            if not np.linalg.norm(q) > 0:
                raise self.bad(node, f"quat {q.tolist()}: a zero quaternion")
            return rotation_from_quaternion(q / np.linalg.norm(q))
        if k == "axisangle":
            a = self.nums(node, k, 4, attrs=attrs)
            n = np.linalg.norm(a[:3])
            if not n > 0:
                raise self.bad(node, f"axisangle {a.tolist()}: a zero axis")
            return rotation_from_vector(a[:3] / n * a[3] * self.angle_unit())
        if k == "euler":
            e = self.nums(node, k, 3, attrs=attrs) * self.angle_unit()
            return euler_matrix(e, self.eulerseq)
        if k == "xyaxes":
            a = self.nums(node, k, 6, attrs=attrs)
            x = a[:3]
            y = a[3:]
            nx = np.linalg.norm(x)
            if not nx > 0:
                raise self.bad(node, f"xyaxes {a.tolist()}: a zero x axis")
            x = x / nx
            y = y - (y @ x) * x
            ny = np.linalg.norm(y)
            if not ny > 1e-12:
                raise self.bad(node, f"xyaxes {a.tolist()}: y is parallel to x")
            y = y / ny
            return np.column_stack([x, y, np.cross(x, y)])
        z = self.nums(node, k, 3, attrs=attrs)
        return zaxis_matrix(z, lambda: self.bad(node, f"zaxis {z.tolist()}: a zero axis"))

    def frame(self, node: Node, attrs: dict) -> np.ndarray:
        return pose(
            self.nums(node, "pos", 3, (0, 0, 0), attrs=attrs), self.orientation(node, attrs)
        )

    # -- defaults ------------------------------------------------------------------------
    def read_defaults(self, node: Node, parent: str | None) -> None:
        name = node.get("class", "main" if parent is None else None)
        if name is None:
            raise self.bad(node, "a nested <default> needs a class name")
        base = {t: dict(a) for t, a in self.classes.get(parent, {}).items()} if parent else {}
        for c in node.children:
            if c.tag == "default":
                continue
            base.setdefault(c.tag, {}).update(c.attrib)
        self.classes[name] = base
        for c in node.children:
            if c.tag == "default":
                self.read_defaults(c, name)

    def attrs(self, node: Node, childclass: str | None) -> dict:
        cls = node.get("class") or childclass or "main"
        if cls not in self.classes and cls != "main":
            raise self.bad(node, f"class {cls!r} is not a <default> class of this file")
        out = dict(self.classes.get(cls, {}).get(node.tag, {}))
        out.update(node.attrib)
        return out


def euler_matrix(e, seq: str) -> np.ndarray:
    """MuJoCo's ``euler`` with ``eulerseq``: a lower-case letter rotates about the moving
    (body) axis, composed on the right; an upper-case one about the fixed axis, composed on
    the left."""
    R = np.eye(3)
    for ang, ax in zip(e, seq, strict=True):
        v = np.zeros(3)
        v["xyz".index(ax.lower())] = ang
        Ri = rotation_from_vector(v)
        R = R @ Ri if ax.islower() else Ri @ R
    return R


def zaxis_matrix(z, err) -> np.ndarray:
    """The smallest rotation taking (0, 0, 1) to the direction ``z`` (MuJoCo's ``zaxis``)."""
    n = np.linalg.norm(z)
    if not n > 0:
        raise err()
    z = np.asarray(z, dtype=float) / n
    e = np.array([0.0, 0.0, 1.0])
    ax = np.cross(e, z)
    s, c = np.linalg.norm(ax), float(e @ z)
    if s < 1e-14:
        return np.eye(3) if c > 0 else rotation_from_vector([math.pi, 0.0, 0.0])
    return rotation_from_vector(ax / s * math.atan2(s, c))


def _inline(node: Node, base: Path, rd: _Reader, depth: int) -> None:
    """Replace each ``<include file>`` below ``node`` by the children of the included file's
    root (MuJoCo's rule: the included file's top element is a wrapper)."""
    out = []
    for c in node.children:
        if c.tag == "include":
            if depth >= MAX_INCLUDE_DEPTH:
                raise rd.bad(c, f"includes nested more than {MAX_INCLUDE_DEPTH} deep")
            f = c.get("file")
            if not f:
                raise rd.bad(c, "an <include> needs a file")
            p = base / f
            if not p.is_file():
                raise rd.bad(c, f"included file {f!r} not found (looked for {p})")
            sub = parse(p)
            _inline(sub, p.parent, rd, depth + 1)
            for s in sub.children:
                s.parent = node
            out.extend(sub.children)
        else:
            _inline(c, base, rd, depth)
            out.append(c)
    node.children = out


def read(path) -> RobotModel:
    """The :class:`RobotModel` of the MJCF file ``path`` (module docstring)."""
    rd = _Reader(path)
    root = parse(path)
    if root.tag != "mujoco":
        raise rd.bad(root, f"the root element is <{root.tag}>: an MJCF file's is <mujoco>")
    _inline(root, Path(path).resolve().parent, rd, 0)
    notes = []
    for comp in root.findall("compiler"):
        a = comp.attrib
        if a.get("coordinate", "local") != "local":
            raise rd.bad(
                comp,
                "coordinate='global' is not read (MuJoCo itself no longer "
                "accepts it); give local coordinates",
            )
        for k in ("balanceinertia", "settotalmass", "boundmass", "boundinertia"):
            if k in a and a[k] not in ("false", "0"):
                raise rd.bad(
                    comp,
                    f"{k}={a[k]!r} changes the file's mass properties at "
                    "compile time; this reader takes them as written: remove it",
                )
        if "angle" in a:
            if a["angle"] not in ("degree", "radian"):
                raise rd.bad(comp, f"angle={a['angle']!r}: degree or radian")
            rd.angle = a["angle"]
        if "eulerseq" in a:
            s = a["eulerseq"]
            if len(s) != 3 or any(ch.lower() not in "xyz" for ch in s):
                raise rd.bad(comp, f"eulerseq={s!r}: three letters of xyzXYZ")
            rd.eulerseq = s
        if "inertiafromgeom" in a:
            if a["inertiafromgeom"] not in ("true", "false", "auto"):
                raise rd.bad(comp, f"inertiafromgeom={a['inertiafromgeom']!r}: true, false or auto")
            rd.fromgeom = a["inertiafromgeom"]
        if "inertiagrouprange" in a:
            g = rd.nums(comp, "inertiagrouprange", 2)
            rd.grouprange = (int(g[0]), int(g[1]))
    gravity = None
    for opt in root.findall("option"):
        if "gravity" in opt.attrib:
            gravity = rd.nums(opt, "gravity", 3)
    for d in root.findall("default"):
        rd.read_defaults(d, None)
    for tag in ("equality",):
        for el in root.findall(tag):
            if el.children:
                raise rd.bad(
                    el.children[0],
                    "equality constraints close loops or couple "
                    "joints; the reduced-coordinate reference treats trees: remove "
                    "them for this test",
                )
    for el in root.findall("tendon"):
        if el.children:
            notes.append(
                f"{len(el.children)} tendons ignored (no spring, damping or limit "
                "of theirs enters this test)"
            )
    wb = root.find("worldbody")
    if wb is None:
        raise rd.bad(root, "no <worldbody>: nothing to simulate")
    links: list = []
    joints: list = []
    meshes: list = []
    counters = {"body": 0, "contact": 0}
    _walk(rd, wb, None, None, links, joints, meshes, counters)
    if not links:
        raise rd.bad(wb, "no <body> in the <worldbody>: nothing moves")
    actuators = sum(len(a.children) for a in root.findall("actuator"))
    roots = [j.child for j in joints if j.parent is None]
    return RobotModel(
        name=root.get("model", Path(path).stem),
        path=str(path),
        format="mjcf",
        links=links,
        joints=joints,
        root=roots[0] if roots else links[0].name,
        actuators=actuators,
        contact_geoms=counters["contact"],
        gravity=gravity,
        notes=notes,
        meshes=meshes,
    )


def _walk(rd, node, parent, childclass, links, joints, meshes, counters):
    """Read the bodies below ``node`` (the worldbody or a body named ``parent``)."""
    for c in node.children:
        if c.tag in _REFUSED_ELEMENTS:
            raise rd.bad(c, _REFUSED_ELEMENTS[c.tag])
        if c.tag == "geom" and parent is None:
            a = rd.attrs(c, childclass)
            if _collides(a):
                counters["contact"] += 1
    for c in node.children:
        if c.tag != "body":
            continue
        counters["body"] += 1
        name = c.get("name") or f"body{counters['body']}"
        if any(lk.name == name for lk in links):
            raise rd.bad(c, f"body name {name!r} used twice")
        cc = c.get("childclass") or childclass
        battrs = dict(c.attrib)
        origin = rd.frame(c, battrs)
        link = Link(name, Inertial(), c.label())
        links.append(link)
        ine_el = c.find("inertial")
        gm = []
        for g in c.findall("geom"):
            a = rd.attrs(g, cc)
            if _collides(a):
                counters["contact"] += 1
            kind = a.get("type", "sphere")
            link.geometry.append(
                (
                    "geom",
                    f"{kind} size={a.get('size', '')}"
                    + (f" fromto={a['fromto']}" if "fromto" in a else ""),
                )
            )
            if kind == "mesh":
                meshes.append(a.get("mesh", ""))
            g0, g1 = rd.grouprange
            if g0 <= int(float(a.get("group", "0"))) <= g1:
                gm.append((g, a, kind))
        use_geoms = rd.fromgeom == "true" or (rd.fromgeom == "auto" and ine_el is None)
        if use_geoms and gm:
            link.inertial = _from_geoms(rd, gm, name)
        elif ine_el is not None:
            link.inertial = _inertial(rd, ine_el)
        js = []
        for j in c.children:
            if j.tag == "freejoint":
                js.append(
                    ModelJoint(
                        name=j.get("name") or f"{name}_free",
                        kind="free",
                        parent=parent,
                        child=name,
                        origin=origin,
                        where=j.label(),
                    )
                )
            elif j.tag == "joint":
                js.append(_joint(rd, j, rd.attrs(j, cc), parent, name, origin))
        if not js:
            js.append(
                ModelJoint(
                    name=f"{name}_weld",
                    kind="fixed",
                    parent=parent,
                    child=name,
                    origin=origin,
                    where=c.label(),
                )
            )
        joints.extend(js)
        _walk(rd, c, name, cc, links, joints, meshes, counters)


def _collides(a: dict) -> bool:
    return int(float(a.get("contype", "1"))) != 0 or int(float(a.get("conaffinity", "1"))) != 0


def _joint(rd, el, a, parent, child, origin) -> ModelJoint:
    t = a.get("type", "hinge")
    if t not in JOINT_TYPES:
        raise rd.bad(el, f"type={t!r}: an MJCF joint type is one of {', '.join(JOINT_TYPES)}")
    kind = JOINT_TYPES[t]
    axis = rd.nums(el, "axis", 3, (0, 0, 1), attrs=a)
    n = float(np.linalg.norm(axis))
    if kind in ("revolute", "prismatic") and not n > 0:
        raise rd.bad(el, f"axis {axis.tolist()}: a {t} joint needs a non-zero axis")
    unit = rd.angle_unit() if t == "hinge" else 1.0
    ref = float(rd.nums(el, "ref", 1, (0.0,), attrs=a)[0]) * unit
    lower = upper = None
    limited = a.get("limited", "auto")
    rng = rd.nums(el, "range", 2, attrs=a)
    if rng is not None and (limited == "true" or (limited == "auto" and "range" in a)):
        lower, upper = float(rng[0]) * unit, float(rng[1]) * unit
    return ModelJoint(
        name=el.get("name") or f"{child}_{t}",
        kind=kind,
        parent=parent,
        child=child,
        origin=origin,
        axis=axis / n if n > 0 else axis,
        point=rd.nums(el, "pos", 3, (0, 0, 0), attrs=a),
        ref=ref if kind in ("revolute", "prismatic") else 0.0,
        lower=lower,
        upper=upper,
        damping=float(rd.nums(el, "damping", 1, (0.0,), attrs=a)[0]),
        friction=float(rd.nums(el, "frictionloss", 1, (0.0,), attrs=a)[0]),
        armature=float(rd.nums(el, "armature", 1, (0.0,), attrs=a)[0]),
        stiffness=float(rd.nums(el, "stiffness", 1, (0.0,), attrs=a)[0]),
        where=el.label(),
    )


def _inertial(rd, el) -> Inertial:
    a = el.attrib
    T = rd.frame(el, dict(a))
    m = rd.nums(el, "mass", 1)
    if m is None:
        raise rd.bad(el, "an <inertial> needs a mass")
    if "diaginertia" in a and "fullinertia" in a:
        raise rd.bad(el, "give diaginertia or fullinertia, not both")
    if "fullinertia" in a:
        if any(k in a for k in ("quat", "axisangle", "euler", "xyaxes", "zaxis")):
            raise rd.bad(
                el,
                "fullinertia is given in the body frame: an orientation beside "
                "it is refused (as MuJoCo does)",
            )
        f = rd.nums(el, "fullinertia", 6)
        I = np.array([[f[0], f[3], f[4]], [f[3], f[1], f[5]], [f[4], f[5], f[2]]])
    elif "diaginertia" in a:
        I = rotate_inertia(np.diag(rd.nums(el, "diaginertia", 3)), T[:3, :3])
    else:
        raise rd.bad(el, "an <inertial> needs diaginertia or fullinertia")
    return Inertial(mass=float(m[0]), com=T[:3, 3].copy(), inertia=I, source="<inertial>")


def _from_geoms(rd, gm, body) -> Inertial:
    parts = []
    for g, a, kind in gm:
        if kind not in G.PRIMITIVES:
            why = (
                "a mesh's mass properties need its volume integrals, which this reader "
                "does not compute"
                if kind == "mesh"
                else f"a {kind} has no volume"
            )
            raise rd.bad(
                g,
                f"body {body!r} takes its mass and inertia from its geoms "
                f"(inertiafromgeom={rd.fromgeom}) and this geom is a {kind}: {why}; "
                "give the body an <inertial> (or set inertiafromgeom='false' and "
                "give one), or put the geom in a group outside inertiagrouprange",
            )
        if a.get("shellinertia", "false") == "true":
            raise rd.bad(g, "shellinertia='true' (a hollow shell) is not read; give an <inertial>")
        size = rd.nums(g, "size", None, (), attrs=a)
        if "fromto" in a:
            ft = rd.nums(g, "fromto", 6, attrs=a)
            d = ft[3:] - ft[:3]
            half = float(np.linalg.norm(d)) / 2
            if not half > 0:
                raise rd.bad(g, f"fromto {ft.tolist()}: the two points coincide")
            R = zaxis_matrix(d, None)
            p = 0.5 * (ft[:3] + ft[3:])
            if kind in ("capsule", "cylinder"):
                need = 1
                dims = [*size[:1], half]
            elif kind in ("box", "ellipsoid"):
                need = 2
                dims = [*size[:2], half]
            else:
                raise rd.bad(g, f"fromto on a {kind}: capsule, cylinder, box or ellipsoid")
        else:
            need = G.SIZE_COUNT[kind]
            dims = list(size[:need])
            T = rd.frame(g, a)
            p, R = T[:3, 3], T[:3, :3]
        if len(size) < need or np.any(np.asarray(dims) <= 0):
            raise rd.bad(g, f"size {size.tolist()}: a {kind} needs {need} positive numbers")
        vol, k = G.mass_properties(kind, dims)
        if "mass" in a:
            m = float(rd.nums(g, "mass", 1, attrs=a)[0])
        else:
            m = float(rd.nums(g, "density", 1, (1000.0,), attrs=a)[0]) * vol
        if m < 0:
            raise rd.bad(g, f"mass {m}: must be >= 0")
        parts.append((m, p, rotate_inertia(np.diag(m * k), R)))
    m = sum(x[0] for x in parts)
    if not m > 0:
        return Inertial(source="geoms (no mass)")
    c = sum(x[0] * x[1] for x in parts) / m
    I = np.zeros((3, 3))
    for mi, pi, Ii in parts:
        d = pi - c
        I += Ii + mi * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return Inertial(mass=m, com=c, inertia=I, source=f"{len(parts)} geoms")
