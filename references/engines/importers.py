"""What a model file holds, read back from a loaded model, and the differences between two
read-backs (ours and an engine importer's), by name and size.

A :class:`Readback` holds, at the model's zero configuration (each joint at 0, an MJCF joint
at its ``ref``), per body of the loaded model (named after the URDF link or MJCF body it
carries): mass, centre of mass and inertia about the centre of mass, both in the root link's
frame (so that where an importer puts the base does not matter); per moving joint: axis and a
point of it in the root link's frame, limits, damping, friction, armature.

:func:`compare` groups the bodies of each side into the rigid groups of our reading (links
joined by fixed joints: an importer may fuse them, as MuJoCo's URDF import and Pinocchio do,
or keep them apart, as PyBullet, DART and Drake do), then reports every group and joint whose
numbers differ beyond :data:`TOL`: mass (relative), centre of mass (m), inertia (relative,
Frobenius norm of the difference over ours), axis direction (rad), the axis line's offset
(m, the distance of the importer's point from our axis line), limits, damping, friction and
armature as the importer holds them against the file's values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: differences below these are agreement: relative 1e-9 for masses and inertias (the files'
#: numbers pass through float parsing and a few products), 1e-9 m, 1e-9 rad
TOL = {"mass": 1e-9, "com": 1e-9, "inertia": 1e-9, "axis": 1e-9, "point": 1e-9}


@dataclass
class Readback:
    """One loaded model, read back (module docstring). ``bodies`` {name: (mass, com (3,),
    inertia (3, 3))}; ``joints`` {name: {"axis", "point", "lower", "upper", "damping",
    "friction", "armature"}} (a missing key: the importer has no such quantity); ``notes``:
    what the importer said or did (warnings, flags used); ``error``: why it failed to load."""

    engine: str
    config: str
    bodies: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    error: str | None = None


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
    grp = rigid_groups(model)
    known = set(grp)
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
