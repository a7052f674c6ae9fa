"""Our own URDF reader: the parts of a URDF file that enter the dynamics.

Read: ``<link>`` with ``<inertial>`` (``<origin xyz rpy>``: the centre of mass and the
orientation of the inertia's axes in the link frame; ``<mass value>``; ``<inertia ixx ixy ixz
iyy iyz izz>`` about the centre of mass in those axes), ``<joint type>`` (revolute,
continuous, prismatic, fixed, floating, planar) with ``<origin>`` (the child link's frame in
the parent's at q = 0), ``<axis xyz>`` (joint frame = child frame; default (1, 0, 0),
normalised), ``<limit lower upper>``, ``<dynamics damping friction>``; the geometry of
``<visual>`` and ``<collision>`` for ``show`` and the mesh files it names (each must exist
unless the caller says meshes do not matter); ``<transmission>`` counted as actuators.
Refused with the reason: a ``<mimic>`` joint that is not held (it couples joints), an
unknown joint type, a link with two
parents, a loop, several roots, a joint naming a link that does not exist, numbers that do
not parse. The URDF specification: wiki.ros.org/urdf/XML (link, joint).

A root link named ``world`` without an inertial is the world itself: its joints tie their
children to the ground.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from scenarios.models.model import (
    Inertial,
    Link,
    ModelJoint,
    RobotModel,
    pose,
    rotate_inertia,
    rpy_matrix,
)
from scenarios.models.xml import ModelError, Node, parse

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


def axis_in_child(axis: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """The joint axis in the child link's frame: URDF gives it in the joint frame, which is
    the child's frame, so it is taken as written (``origin`` unused; one place to change)."""
    return axis


class _Reader:
    def __init__(self, path: str, packages: dict | None):
        self.path = str(path)
        self.dir = Path(path).resolve().parent
        self.packages = {k: Path(v) for k, v in (packages or {}).items()}

    def bad(self, node: Node | None, rule: str) -> ModelError:
        where = node.label() if node is not None else "<robot>"
        return ModelError(
            f"model file {self.path}: {where}: {rule}", path=self.path, problems=[(where, rule)]
        )

    def numbers(self, node: Node, attr: str, n: int, default=None) -> np.ndarray:
        text = node.get(attr)
        if text is None:
            if default is None:
                raise self.bad(node, f"attribute {attr!r} is required ({n} numbers)")
            return np.asarray(default, dtype=float)
        try:
            vals = [float(t) for t in text.split()]
        except ValueError:
            raise self.bad(node, f"{attr}={text!r}: not {n} numbers") from None
        if len(vals) != n or not np.all(np.isfinite(vals)):
            raise self.bad(node, f"{attr}={text!r}: expected {n} finite numbers")
        return np.asarray(vals, dtype=float)

    def origin(self, node: Node | None) -> np.ndarray:
        o = node.find("origin") if node is not None else None
        if o is None:
            return np.eye(4)
        return pose(
            self.numbers(o, "xyz", 3, (0, 0, 0)), rpy_matrix(self.numbers(o, "rpy", 3, (0, 0, 0)))
        )

    def resolve(self, uri: str) -> Path:
        """A mesh file name: ``package://pkg/rest`` (a folder given for ``pkg``, else the first
        ancestor folder of this file holding ``rest`` or named ``pkg``), ``file://`` or a path
        relative to this file."""
        if uri.startswith("file://"):
            return Path(uri[len("file://") :])
        if uri.startswith("package://"):
            pkg, _, rest = uri[len("package://") :].partition("/")
            if pkg in self.packages:
                return self.packages[pkg] / rest
            for a in [self.dir, *self.dir.parents]:
                if a.name == pkg and (a / rest).exists():
                    return a / rest
                if (a / rest).exists():
                    return a / rest
            return self.dir / rest
        return self.dir / uri

    def inertial(self, link: Node) -> Inertial:
        el = link.find("inertial")
        if el is None:
            return Inertial()
        T = self.origin(el)
        m_el = el.find("mass")
        if m_el is None:
            raise self.bad(el, "an <inertial> needs a <mass value=...>")
        m = float(self.numbers(m_el, "value", 1)[0])
        i_el = el.find("inertia")
        if i_el is None:
            raise self.bad(el, "an <inertial> needs an <inertia ixx= ixy= ixz= iyy= iyz= izz=>")
        v = {
            k: float(self.numbers(i_el, k, 1, (0.0,))[0])
            for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        }
        I = np.array(
            [
                [v["ixx"], v["ixy"], v["ixz"]],
                [v["ixy"], v["iyy"], v["iyz"]],
                [v["ixz"], v["iyz"], v["izz"]],
            ]
        )
        return Inertial(
            mass=m, com=T[:3, 3].copy(), inertia=rotate_inertia(I, T[:3, :3]), source="<inertial>"
        )

    def geometry(self, link: Node, meshes: list, contact: list) -> list:
        out = []
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                g = el.find("geometry")
                if g is None or not g.children:
                    raise self.bad(el, f"a <{tag}> needs a <geometry> with a shape")
                shape = g.children[0]
                if shape.tag == "mesh":
                    fn = shape.get("filename")
                    if not fn:
                        raise self.bad(shape, "a <mesh> needs a filename")
                    meshes.append((link.get("name"), shape, fn, self.resolve(fn)))
                    out.append((tag, f"mesh {fn}"))
                else:
                    out.append(
                        (
                            tag,
                            shape.tag + " " + " ".join(f"{k}={v}" for k, v in shape.attrib.items()),
                        )
                    )
                if tag == "collision":
                    contact.append(link.get("name"))
        return out


def read(path, packages: dict | None = None, meshes: str = "require") -> RobotModel:
    """The :class:`RobotModel` of the URDF file ``path``. ``packages``: {package name: folder}
    for ``package://`` file names. ``meshes``: "require" (every mesh file named must exist:
    engines' importers load them, and PyBullet computes inertias from collision meshes unless
    told otherwise) or "ignore" (not checked; the dynamics read here never use them)."""
    rd = _Reader(path, packages)
    root = parse(path)
    if root.tag != "robot":
        raise rd.bad(root, f"the root element is <{root.tag}>: a URDF file's is <robot>")
    links, by = [], {}
    mesh_list: list = []
    contact: list = []
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise rd.bad(el, "a <link> needs a name")
        if name in by:
            raise rd.bad(el, f"link name {name!r} used twice; names are unique")
        lk = Link(name, rd.inertial(el), el.label(), rd.geometry(el, mesh_list, contact))
        links.append(lk)
        by[name] = el
    if not links:
        raise rd.bad(root, "no <link>: nothing to simulate")
    joints, child_of, jnames = [], {}, set()
    for el in root.findall("joint"):
        name = el.get("name")
        if not name:
            raise rd.bad(el, "a <joint> needs a name")
        if name in jnames:
            raise rd.bad(el, f"joint name {name!r} used twice; names are unique")
        jnames.add(name)
        kind = el.get("type")
        if kind not in JOINT_TYPES:
            raise rd.bad(el, f"type={kind!r}: a URDF joint type is one of {', '.join(JOINT_TYPES)}")
        mimic = el.find("mimic")
        ends = {}
        for side in ("parent", "child"):
            s = el.find(side)
            if s is None or not s.get("link"):
                raise rd.bad(el, f"a <joint> needs <{side} link=...>")
            if s.get("link") not in by:
                raise rd.bad(s, f"link {s.get('link')!r} is not a <link> of this file")
            ends[side] = s.get("link")
        if ends["child"] in child_of:
            raise rd.bad(
                el,
                f"link {ends['child']!r} is the child of two joints "
                f"({child_of[ends['child']]!r} and {name!r}); a URDF is a tree",
            )
        child_of[ends["child"]] = name
        ax_el = el.find("axis")
        axis = (
            rd.numbers(ax_el, "xyz", 3, (1, 0, 0))
            if ax_el is not None
            else np.array([1.0, 0.0, 0.0])
        )
        n = float(np.linalg.norm(axis))
        if kind in ("revolute", "continuous", "prismatic", "planar") and not n > 0:
            raise rd.bad(ax_el, f"axis {axis.tolist()}: a {kind} joint needs a non-zero axis")
        lim = el.find("limit")
        lower = upper = None
        if lim is not None and kind in ("revolute", "prismatic"):
            lower = float(rd.numbers(lim, "lower", 1, (0.0,))[0])
            upper = float(rd.numbers(lim, "upper", 1, (0.0,))[0])
        dyn = el.find("dynamics")
        damping = friction = 0.0
        if dyn is not None:
            damping = float(rd.numbers(dyn, "damping", 1, (0.0,))[0])
            friction = float(rd.numbers(dyn, "friction", 1, (0.0,))[0])
        joints.append(
            ModelJoint(
                name=name,
                kind=kind,
                parent=ends["parent"],
                child=ends["child"],
                origin=(T := rd.origin(el)),
                axis=axis_in_child(axis / n if n > 0 else axis, T),
                lower=lower,
                upper=upper,
                damping=damping,
                friction=friction,
                where=el.label(),
                mimic=None if mimic is None else mimic.get("joint", "?"),
            )
        )
    roots = [lk.name for lk in links if lk.name not in child_of]
    if len(roots) != 1:
        if not roots:
            raise rd.bad(root, "every link is a child: the joints form a loop")
        raise rd.bad(
            root, f"{len(roots)} root links {roots}: a URDF has one (join the others by joints)"
        )
    # reached from the root (a loop among the other links leaves them unreached)
    kids: dict = {}
    for j in joints:
        kids.setdefault(j.parent, []).append(j.child)
    seen, stack = set(), [roots[0]]
    while stack:
        n = stack.pop()
        seen.add(n)
        stack.extend(kids.get(n, []))
    lost = [lk.name for lk in links if lk.name not in seen]
    if lost:
        raise rd.bad(
            root,
            f"links {lost} are not reached from the root {roots[0]!r}: their joints form a loop",
        )
    root_name = roots[0]
    if root_name == "world" and by["world"].find("inertial") is None:
        links = [lk for lk in links if lk.name != "world"]
        for j in joints:
            if j.parent == "world":
                j.parent = None
        root_name = next(j.child for j in joints if j.parent is None)
    if meshes == "require":
        missing = [(lk, el, fn, p) for lk, el, fn, p in mesh_list if not p.is_file()]
        if missing:
            lk, el, fn, p = missing[0]
            more = f" ({len(missing) - 1} more missing)" if len(missing) > 1 else ""
            raise rd.bad(
                el,
                f"link {lk!r}: mesh file {fn!r} not found (looked for {p}){more}. "
                "The engines' importers load it (PyBullet computes the link's inertia "
                "from its collision mesh unless URDF_USE_INERTIA_FROM_FILE is set): "
                "give the file, a package folder (packages = {...} in [model]), or "
                'meshes = "ignore" to run without geometry',
            )
    notes = []
    if root.findall("gazebo"):
        notes.append("<gazebo> elements ignored (simulator plug-ins and materials)")
    return RobotModel(
        name=root.get("name", Path(path).stem),
        path=str(path),
        format="urdf",
        links=links,
        joints=joints,
        root=root_name,
        actuators=len(root.findall("transmission")),
        contact_geoms=len(contact),
        notes=notes,
        meshes=[str(p) for _, _, _, p in mesh_list],
    )
