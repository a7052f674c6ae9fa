"""Each engine's own importer on a model file (issue 36): the part every engine shares.

An engine's importer lives in its home, ``references/engines/<engine>/importer.py``, and
provides ``readback(model, config, floating=False) -> Readback``: the engine's own loader on
the model file in one of the named configurations :data:`CONFIGS` (a floating URDF root
loaded floating, as the engine's user asks for it), its loaded model read back at the zero
configuration; and, for the runs, ``INTEGRATORS`` and ``load`` (:func:`simulate`). This
module holds what they share: the read-back (:class:`Readback`), our own
reading of the file as one (:func:`our_readback`), the comparison (:func:`compare`,
:class:`Difference`), the table over every engine and configuration (:func:`importer_table`)
and the loaders' common chores (a URDF copy without geometry, C-level output captured).

The configurations:

- ``as-loaded``: the file passed to the importer as a user would, with the importer's
  defaults (PyBullet's loadURDF without flags, MuJoCo's compiler defaults, ...);
- ``faithful``: the settings that make the importer take the file's mass properties as
  written: PyBullet ``URDF_USE_INERTIA_FROM_FILE``; for URDF files, geometry removed (a copy
  without ``<visual>``/``<collision>``: mesh files are not needed, and no inertia is computed
  from shapes; MuJoCo also gets ``fusestatic="false"``).

A read-back holds, at the model's zero configuration (each joint at 0, an MJCF joint at its
``ref``), per body of the loaded model (named after the URDF link or MJCF body it carries):
mass, centre of mass and inertia about the centre of mass, both in the root link's frame (so
that where an importer puts the base does not matter); per moving joint: axis and a point of
it in the root link's frame, limits, damping, friction, armature.

:func:`compare` groups the bodies of each side into the rigid groups of our reading (links
joined by fixed joints: an importer may fuse them, as MuJoCo's URDF import and Pinocchio do,
or keep them apart, as PyBullet, DART and Drake do), then reports every group and joint whose
numbers differ beyond :data:`TOL`: mass (relative), centre of mass (m), inertia (relative,
Frobenius norm of the difference over ours), axis direction (rad), the axis line's offset
(m, the distance of the importer's point from our axis line), limits, damping, friction and
armature as the importer holds them against the file's values.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenarios.models.configurations import CONFIGS, variant
from scenarios.models.model import joint_transform

#: the engines with an importer (``references/engines/<engine>/importer.py``)
ENGINES = ("mujoco", "mjx", "pinocchio", "pybullet", "drake", "dart")

#: differences below these are agreement: relative 1e-9 for masses and inertias (the files'
#: numbers pass through float parsing and a few products), 1e-9 m, 1e-9 rad
TOL = {"mass": 1e-9, "com": 1e-9, "inertia": 1e-9, "axis": 1e-9, "point": 1e-9}


@dataclass
class Readback:
    """One loaded model, read back (module docstring). ``bodies`` {name: (mass, com (3,),
    inertia (3, 3))}; ``joints`` {name: {"axis", "point", "lower", "upper", "damping",
    "friction", "armature"}} (a missing key: the importer has no such quantity); ``notes``:
    what the importer said or did (warnings, flags used); ``error``: why it failed to load;
    ``joint_body`` {joint name: the body it moves}, where the importer names bodies its own
    way (an unnamed MJCF body), so that :func:`compare` pairs them by their joint;
    ``root_joint``: "free" or "attached", where the importer's model says how its root body
    hangs from the world (compared for MJCF files, whose free joint is in the file)."""

    engine: str
    config: str
    bodies: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    error: str | None = None
    joint_body: dict = field(default_factory=dict)
    #: how the root body hangs from the world: "free" (a free joint) or "attached" (welded,
    #: or on a joint of fewer degrees of freedom); None: not read back
    root_joint: str | None = None


def to_root(T_root: np.ndarray, mass, com_world, I_world):
    """(mass, com, inertia) from world to the root frame ``T_root`` (4, 4)."""
    R = T_root[:3, :3]
    return float(mass), R.T @ (np.asarray(com_world) - T_root[:3, 3]), R.T @ I_world @ R


def combine(parts) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and inertia about it of several (mass, com, inertia) parts."""
    m = sum(p[0] for p in parts)
    if not m > 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    c = sum(p[0] * p[1] for p in parts) / m
    I = np.zeros((3, 3))
    for mi, ci, Ii in parts:
        d = ci - c
        I += Ii + mi * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return m, c, I


def rigid_groups(model) -> dict:
    """{link: the name of its rigid group}: links joined by fixed joints (MJCF: a body without
    a joint) share the group of the one nearest the root; links fixed to the world belong to
    the group ``"world"``."""
    parent = {}
    for j in model.joints:
        parent.setdefault(j.child, []).append(j)
    out: dict = {}

    def group(n):
        if n in out:
            return out[n]
        js = parent.get(n)
        if not js:
            out[n] = n
        elif all(j.kind == "fixed" for j in js):
            out[n] = "world" if js[0].parent is None else group(js[0].parent)
        else:
            out[n] = n
        return out[n]

    for lk in model.links:
        group(lk.name)
    return out


@dataclass
class Difference:
    engine: str
    config: str
    item: str
    quantity: str
    ours: str
    theirs: str
    size: float
    unit: str
    remark: str = ""

    def line(self) -> str:
        size = "" if math.isnan(self.size) else f"{self.size:.3g} {self.unit}".strip()
        return (
            f"{self.engine} [{self.config}]: {self.item}: {self.quantity} {size}: ours "
            f"{self.ours}, theirs {self.theirs}" + (f"; {self.remark}" if self.remark else "")
        )


def _v(a) -> str:
    return "[" + ", ".join(f"{float(x):.4g}" for x in np.ravel(a)) + "]"


def _angle(a, b) -> float:
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def compare(
    model, ours: Readback, theirs: Readback, hints: dict | None = None, fixed_base: bool = False
) -> list:
    """The :class:`Difference` rows of ``theirs`` against ``ours`` (module docstring).
    ``hints`` {quantity: remark} adds the importer's known cause to a row of that quantity.
    ``fixed_base``: the root link is fixed to the world (its mass properties do not enter the
    motion, and an importer may fuse it into the world): not compared."""
    hints = hints or {}
    rows: list = []
    e, c = theirs.engine, theirs.config

    def row(item, q, o, t, size, unit, remark=""):
        rows.append(Difference(e, c, item, q, o, t, size, unit, remark or hints.get(q, "")))

    if theirs.error:
        row("model", "load", "loads", theirs.error, math.nan, "")
        return rows
    if ours.root_joint and theirs.root_joint and ours.root_joint != theirs.root_joint:
        row(f"body {model.root!r}", "root joint", ours.root_joint, theirs.root_joint,
            math.nan, "")  # fmt: skip
    grp = rigid_groups(model)
    known = set(grp)
    # a body the importer named its own way, paired with our link by the joint that moves it
    moved = {j.name: j.child for j in model.joints if j.kind != "fixed"}
    rename = {b: moved[j] for j, b in theirs.joint_body.items()
              if j in moved and b not in known and moved[j] not in theirs.bodies}  # fmt: skip
    if rename:
        theirs = Readback(theirs.engine, theirs.config,
                          {rename.get(k, k): v for k, v in theirs.bodies.items()},
                          theirs.joints, theirs.notes, theirs.error, theirs.joint_body)  # fmt: skip
    if fixed_base:
        grp = {k: ("world" if v == model.root else v) for k, v in grp.items()}
    sides = []
    for rb in (ours, theirs):
        g: dict = {}
        for name, parts in rb.bodies.items():
            if name not in known:
                if parts[0] > 0 and rb is theirs:
                    row(f"body {name!r}", "unknown body", "-", _v([parts[0]]), parts[0], "kg",
                        "a body with mass that our reading has no link for")  # fmt: skip
                continue
            g.setdefault(grp[name], []).append(parts)
        sides.append({k: combine(v) for k, v in g.items() if k != "world"})
    go, gt = sides
    for name, (m, cm, I) in go.items():
        if name not in gt:
            row(f"body {name!r}", "missing", "present", "absent", m, "kg")
            continue
        m2, c2, I2 = gt[name]
        dm = abs(m2 - m) / m
        if dm > TOL["mass"]:
            row(f"body {name!r}", "mass", f"{m:.6g} kg", f"{m2:.6g} kg", 100 * dm, "%")
        dc = float(np.linalg.norm(c2 - cm))
        if dc > TOL["com"]:
            row(f"body {name!r}", "com", _v(cm), _v(c2), dc, "m")
        dI = float(np.linalg.norm(I2 - I) / max(np.linalg.norm(I), 1e-300))
        if dI > TOL["inertia"]:
            row(f"body {name!r}", "inertia", _v(np.linalg.eigvalsh(I)),
                _v(np.linalg.eigvalsh(I2)), 100 * dI, "%")  # fmt: skip
    for name, jo in ours.joints.items():
        jt = theirs.joints.get(name)
        if jt is None:
            row(f"joint {name!r}", "missing", "present", "absent", math.nan, "")
            continue
        if "axis" in jt:
            ln = float(np.linalg.norm(jt["axis"]))
            if abs(ln - 1.0) > 1e-9:
                row(f"joint {name!r}", "axis length", "1", f"{ln:.6g}", abs(ln - 1.0), "",
                    "the importer keeps the file's axis unnormalised")  # fmt: skip
        if "axis" in jo and "axis" in jt:
            a = _angle(jo["axis"], jt["axis"])
            if a > TOL["axis"]:
                rem = "reversed: the joint angle's sign flips" if a > math.pi - 1e-6 else ""
                row(f"joint {name!r}", "axis", _v(jo["axis"]), _v(jt["axis"]), a, "rad", rem)
        if "point" in jo and "point" in jt:
            n = np.asarray(jo["axis"], dtype=float)
            d = np.asarray(jt["point"]) - np.asarray(jo["point"])
            off = float(np.linalg.norm(d - (d @ n) * n))
            if off > TOL["point"]:
                row(f"joint {name!r}", "axis offset", _v(jo["point"]), _v(jt["point"]), off, "m")
        for q in ("lower", "upper", "damping", "friction", "armature"):
            if q not in jt:
                continue
            vo, vt = jo.get(q), jt[q]
            if vo is None and vt is None:
                continue
            if vo is None or vt is None or abs(vo - vt) > 1e-9 * max(1.0, abs(vo)):
                size = abs(vt - vo) if (vo is not None and vt is not None) else math.nan
                row(f"joint {name!r}", q, f"{vo}", f"{vt}", size, "")
    return rows


# -- our own reading as a read-back ----------------------------------------------------------


def zero_poses(model) -> dict:
    """{link: (4, 4) pose in the root link's frame} at the zero configuration."""
    by_child: dict = {}
    for j in model.joints:
        by_child.setdefault(j.child, []).append(j)
    T: dict = {}

    def pose_of(n):
        if n in T:
            return T[n]
        js = by_child.get(n, [])
        moving = [j for j in js if j.kind not in ("fixed", "free", "floating")]
        j = moving[0] if moving else (js[0] if js else None)
        if j is None or j.parent is None:
            T[n] = np.eye(4) if j is None or j.kind in ("free", "floating") else j.origin
        else:
            q = np.zeros(3) if j.kind == "ball" else j.ref
            T[n] = pose_of(j.parent) @ joint_transform(j, q)
        return T[n]

    for lk in model.links:
        pose_of(lk.name)
    root = T[model.root]
    return {n: np.linalg.solve(root, t) for n, t in T.items()}


def our_readback(model) -> Readback:
    """Our own reading of ``model`` as a read-back: every link at the zero configuration (MJCF
    joints at their ``ref``), in the root link's frame; each revolute joint's axis and point
    there, and its limits, damping, friction and armature as the file gives them."""
    rb = Readback("ours", "reader")
    if model.format == "mjcf":  # the file says whether its root is free
        free = any(j.kind == "free" and j.child == model.root for j in model.joints)
        rb.root_joint = "free" if free else "attached"
    T = zero_poses(model)
    eye = np.eye(4)
    for lk in model.links:
        t = T[lk.name]
        ine = lk.inertial
        R = t[:3, :3]
        rb.bodies[lk.name] = to_root(eye, ine.mass, R @ ine.com + t[:3, 3],
                                     R @ ine.inertia @ R.T)  # fmt: skip
    for j in model.moving_joints:
        if j.kind not in ("revolute", "continuous"):
            continue  # the importers are read back for revolute joints
        t = T[j.child]
        rb.joints[j.name] = {
            "axis": t[:3, :3] @ j.axis,
            "point": t[:3, :3] @ j.point + t[:3, 3],
            "lower": j.lower,
            "upper": j.upper,
            "damping": j.damping,
            "friction": j.friction,
            "armature": j.armature,
        }
    return rb


# -- the loaders' common chores ------------------------------------------------------------


def strip_urdf(path, extra: str | None = None) -> Path:
    """The path of a copy of the URDF ``path`` with every link's visual and collision removed
    (and ``extra``, an XML element's text, appended to the robot element)."""
    tree = ET.parse(path)
    root = tree.getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    if extra:
        root.append(ET.fromstring(extra))
    folder = Path(tempfile.mkdtemp(prefix="director-bench-urdf-"))
    out = folder / Path(path).name
    tree.write(out)
    return out


def file_for(model, config: str, extra: str | None = None) -> tuple[Path, Path | None]:
    """(the file an importer loads in ``config``, a temporary folder to remove afterwards):
    the user's file, or for a faithful URDF a copy without geometry (:func:`strip_urdf`)."""
    if config == "faithful" and model.format == "urdf":
        p = strip_urdf(model.path, extra)
        return p, p.parent
    return Path(model.path).resolve(), None


def mjcf_copy(path, edit) -> tuple[Path, Path]:
    """(the path of a copy of the MJCF file ``path`` after ``edit(root element)``, its
    temporary folder to remove afterwards). The copy lives elsewhere, so the compiler's asset
    folders and every ``<include>`` are made absolute against the original file's folder."""
    src = Path(path).resolve()
    tree = ET.parse(src)
    root = tree.getroot()
    comp = root.find("compiler")
    if comp is None:
        comp = ET.Element("compiler")
        root.insert(0, comp)
    for key in ("meshdir", "texturedir", "assetdir"):
        if comp.get(key) is not None:
            comp.set(key, str((src.parent / comp.get(key)).resolve()) + os.sep)
    for key in ("meshdir", "texturedir"):  # unset: the file's own folder
        if comp.get(key) is None and comp.get("assetdir") is None:
            comp.set(key, str(src.parent) + os.sep)
    for inc in root.iter("include"):
        if inc.get("file"):
            inc.set("file", str((src.parent / inc.get("file")).resolve()))
    edit(root)
    folder = Path(tempfile.mkdtemp(prefix="director-bench-mjcf-"))
    out = folder / src.name
    tree.write(out)
    return out, folder


@contextlib.contextmanager
def quiet_fd():
    """Capture C-level stdout and stderr (PyBullet and DART print from C++); the text is the
    one item of the list yielded, once the block ends."""
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        out: list = []
        try:
            yield out
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace")
            out.append(re.sub(r"\x1b\[[0-9;]*m", "", text))  # terminal colours dropped


def rot_inertia(R, diag):
    """R diag(diag) R^T."""
    return R @ np.diag(diag) @ R.T


def limit(v):
    """A joint limit as a float, or None for an unbounded side (inf, or +-1e300 and beyond)."""
    v = float(v)
    return None if not np.isfinite(v) or abs(v) >= 1e300 else v


def packages(model) -> dict:
    """Package folders for ``package://`` file names, guessed as our URDF reader does: the
    first folder above the file holding ``robots/`` is example-robot-data's."""
    from scenarios.models.urdf import _Reader

    if model.format != "urdf" or not model.meshes:
        return {}
    out = {}
    rd = _Reader(model.path, None)
    for a in [rd.dir, *rd.dir.parents]:
        if (a / "robots").is_dir():
            out["example-robot-data"] = a
            break
    return out


# -- the table -----------------------------------------------------------------------------------


def importer(engine: str):
    """The importer module of ``engine`` (``references.engines.<engine>.importer``)."""
    return importlib.import_module(f"references.engines.{engine}.importer")


def importer_table(model, engines=None, configs=None, fixed_base=None) -> list:
    """Difference rows (:class:`Difference`) of every engine and configuration against our
    reading, and one row per engine not installed; an importer that refuses the file is one
    row with its message. An engine module's ``HINTS`` {(config, quantity): remark} names the
    known cause of a difference beside it ((config, quantity, format): for one file format,
    "urdf" or "mjcf", only)."""
    ours = our_readback(model)
    if fixed_base is None:
        fixed_base = model.format == "urdf"
    rows = []
    for e in engines or ENGINES:
        mod = importer(e)
        for c in configs or CONFIGS:
            try:
                rb = mod.readback(model, c, floating=not fixed_base)
            except ImportError as exc:
                rows.append(Difference(e, c, "engine", "not installed", "-", str(exc),
                                       float("nan"), ""))  # fmt: skip
                break
            hints = {k[1]: h for k, h in getattr(mod, "HINTS", {}).items()
                     if k[0] == c and (len(k) == 2 or k[2] == model.format)}  # fmt: skip
            diff = compare(model, ours, rb, hints, fixed_base)
            if not diff:
                diff = [Difference(e, c, "all", "agree", "-", "-", float("nan"), "",
                                   f"{len(rb.bodies)} bodies, {len(rb.joints)} revolute "
                                   "joints read back")]  # fmt: skip
            rows.extend(diff)
    return rows


# -- runs through an importer ---------------------------------------------------------------------


def variants(engine: str, selected) -> list[str]:
    """The importer configurations of ``engine`` planned beside its ``selected`` integrators
    for a robot-model scenario: every configuration of each selected integrator that the
    engine's importer runs (its module's ``INTEGRATORS``); none for an engine without one."""
    if engine not in ENGINES:
        return []
    runs = getattr(importer(engine), "INTEGRATORS", ())
    return [variant(i, c) for i in selected if i in runs for c in CONFIGS]


@dataclass
class Start:
    """The initial state of a model scenario as an importer run sets it: joint coordinates
    ``q`` and rates ``qd`` by joint name, every joint of one coordinate (radians; a joint the
    scenario does not name: its zero, MJCF: its ``ref``; rate 0), ``floating``, the root
    link's world pose ``T`` (4, 4), its origin's velocity ``v`` and angular velocity ``w``
    (world axes), ``gravity``, ``held`` (the joints the scenario holds), ``given`` (the joints
    the scenario names a value or rate for: an importer run that cannot set one of them
    refuses; one the scenario leaves at rest is left at the importer's zero)."""

    q: dict
    qd: dict
    floating: bool
    T: np.ndarray
    v: np.ndarray
    w: np.ndarray
    gravity: np.ndarray
    held: list
    given: frozenset = frozenset()


def start_of(scenario) -> Start:
    """The :class:`Start` of a model scenario (its ``[model.initial]`` table and the pose and
    twist of its root link that our conversion placed)."""
    spec = scenario.model_spec
    init = spec.get("initial", {})
    model, conv = scenario.model, scenario.conversion
    # every joint of one coordinate at the scenario's value, else at its zero (MJCF: its
    # ref, as our reading places it): an importer's own initial value (DART clamps a joint
    # into its limits) never sets the start
    one = ("revolute", "continuous", "prismatic", "hinge", "slide")
    q = {j.name: float(j.ref) for j in model.joints if j.kind in one}
    qd = {j.name: 0.0 for j in model.joints if j.kind in one}
    given = {k.split(".", 1)[1] for k in init if k.startswith(("joints.", "rates."))}
    q.update({k[7:]: v for k, v in init.items() if k.startswith("joints.")})
    qd.update({k[6:]: v for k, v in init.items() if k.startswith("rates.")})
    root = model.root
    T = np.asarray(conv.link_pose[root], dtype=float)
    v = w = np.zeros(3)
    floating = bool(spec.get("floating"))
    if floating:
        b = scenario.bodies[[x.name for x in scenario.bodies].index(root)]
        w = np.asarray(b.rotation, float) @ np.asarray(b.omega_body, float)
        v = np.asarray(b.velocity, float) + np.cross(w, T[:3, 3] - np.asarray(b.position, float))
    return Start(q, qd, floating, T, v, w, np.asarray(scenario.gravity, float),
                 list(spec.get("lock", ())), frozenset(given))  # fmt: skip


def body_offsets(scenario) -> tuple[list, np.ndarray]:
    """(the link that carries each body of the scenario, in order: (the root link of its rigid
    group, the name of the joint that moves that link, None for a floating root), so that an
    importer that names a body otherwise (an unnamed MJCF body) finds it by its joint; each
    body's principal frame in that link's frame, (nb, 4, 4))."""
    conv = scenario.conversion
    held = set(conv.locked)
    moves = {}
    for j in scenario.model.joints:
        if j.kind != "fixed" and j.name not in held and j.parent is not None:
            moves.setdefault(j.child, j.name)
    links, off = [], []
    for b in scenario.bodies:
        T_link = np.asarray(conv.link_pose[b.name], dtype=float)
        T_body = np.eye(4)
        T_body[:3, :3] = b.rotation
        T_body[:3, 3] = b.position
        links.append((b.name, moves.get(b.name)))
        off.append(np.linalg.solve(T_link, T_body))
    return links, np.asarray(off)


def simulate(engine: str, scenario, config: str, integrator: str, dt: float, nstep: int,
             save_every: int):  # fmt: skip
    """Run a robot-model ``scenario`` through ``engine``'s own importer in ``config`` (the
    system builders' contract, :mod:`references.engines.system`): the engine's importer
    module loads the file (``load(scenario, config, integrator, dt) -> sim``), sets the
    initial state by joint name, steps (``sim.advance(n)``) and reports each body's link
    (``sim.links([(link, joint), ...]) -> (T (nl, 4, 4), v (nl, 3) of the link origins,
    w (nl, 3))``, world: :func:`body_offsets`);
    each body's principal frame moves with its link (:func:`body_offsets`), so an importer's
    change of the model shows in the motion of the links, never in our reading of the
    frames. Raises :class:`~references.errors.Unsupported` with the reason when the
    importer cannot load the file as a user would (the run's row says so)."""
    from director_model import saved_steps
    from references.engines import timing
    from references.engines.context import SystemResult
    from references.errors import Diverged, Unsupported

    if getattr(scenario, "model", None) is None:
        raise Unsupported(
            f"{engine}: an importer configuration runs a robot-model scenario (a [model] file); "
            f"{scenario.name!r} is a system of the suite's own"
        )
    mod = importer(engine)
    if integrator not in getattr(mod, "INTEGRATORS", ()):
        raise Unsupported(
            f"{engine}: the importer runs {list(getattr(mod, 'INTEGRATORS', ()))}, not "
            f"{integrator!r}"
        )
    sim = mod.load(scenario, config, integrator, float(dt))
    timing.stepping()  # the importer's loading of the file is not the run's cost
    links, off = body_offsets(scenario)
    steps = saved_steps(int(nstep), int(save_every))
    n, nb = len(steps), len(links)
    x, R = np.zeros((n, nb, 3)), np.zeros((n, nb, 3, 3))
    v, W = np.zeros((n, nb, 3)), np.zeros((n, nb, 3))

    def read(k):
        T, vo, w = sim.links(links)
        Tb = T @ off
        R[k] = Tb[:, :3, :3]
        x[k] = Tb[:, :3, 3]
        r = x[k] - T[:, :3, 3]
        v[k] = vo + np.cross(w, r)
        W[k] = np.einsum("bji,bj->bi", R[k], w)

    def output(m):
        return SystemResult(steps[:m] * float(dt), x[:m], R[:m], v[:m], W[:m],
                            float(sim.clock), dict(sim.settings))  # fmt: skip

    try:
        read(0)
    except KeyError as exc:  # the importer's model lacks a body the scenario moves
        raise Unsupported(f"{exc.args[0]}: the importer dropped it ({config})") from None
    for k in range(1, n):
        sim.advance(int(steps[k] - steps[k - 1]))
        read(k)
        if not all(np.all(np.isfinite(a[k])) for a in (x, R, v, W)):
            raise Diverged(
                f"{engine} {variant(integrator, config)} at dt = {dt:g} s: a non-finite state "
                f"between t = {steps[k - 1] * dt:.6g} and {steps[k] * dt:.6g} s",
                float(steps[k - 1] * dt),
                output(k),
            )
    return output(n)
