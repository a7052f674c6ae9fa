"""Scenario files of systems of rigid bodies joined by joints (chains, trees, closed loops),
read into a :class:`~scenarios.system.SystemScenario`.

A system file is a scenario file whose top level has ``[[bodies]]`` and ``[[joints]]`` arrays
of tables instead of ``[body]`` and ``[initial]`` (docs/scenarios.md, "Systems of bodies")::

    [[bodies]]
    name = "upper"
    mass = 1.0
    inertia = [0.09, 0.09, 0.02]      # principal moments about the centre of mass, kg m^2
    position = [0.0, 0.0, -0.5]       # centre of mass, world, m
    rotation_vector = [0.3, 0.0, 0.0] # or rotation = [[...]] or quaternion_wxyz = [...]
    velocity = [0.0, 0.0, 0.0]        # centre-of-mass velocity, world, m/s (default 0)
    omega_body = [0.0, 0.0, 0.0]      # body angular velocity, body axes, rad/s (default 0)

    [[joints]]
    name = "shoulder"                 # default "joint<index>"
    kind = "spherical"                # spherical, fixed_point, revolute, universal,
                                      # cylindrical, prismatic
    body_a = "upper"
    body_b = "ground"                 # a body's name, or "ground"
    anchor_a = [0.0, 0.0, 0.5]        # in a's principal frame, relative to its centre of mass
    anchor_b = [0.0, 0.0, 0.0]        # in b's principal frame; for the ground a WORLD point
    # axis_a, axis_b for revolute, universal, cylindrical, prismatic (world for the ground)

with ``[environment] gravity``, ``[run]``, ``[tolerances]`` as for one body and ``[reference] kind``
one of :data:`~scenarios.system.SYSTEM_REFERENCE_KINDS` (with the parameters of an exact motion
beside it).

A tree may instead give joint coordinates (``angle``/``rate`` of a revolute joint,
``rotation_vector``/``omega`` of a spherical one, the child relative to its parent in the
parent's axes) and no body states but a floating root's: :func:`_tree_states` places the
bodies by forward kinematics (docs/scenarios.md, "Initial state by joint coordinates").

Every problem of a file is listed in one :class:`~scenarios.schema.ScenarioError` naming the file,
the field (``bodies[1].inertia``, ``joints[0].anchor_b``), the value and the rule: the bodies'
physics (as for one body), unknown or repeated names, the joints' shape, and the joints holding at t
= 0 in position (:data:`~scenarios.system.JOINT_TOL`) and velocity. Nothing is repaired.

"""

from __future__ import annotations

import math
import types

import numpy as np

from scenarios import contact as ct
from scenarios.system import (
    AXIS_KINDS,
    CONTACT_CLOSED_FORMS,
    JOINT_KINDS,
    JOINT_TOL,
    SYSTEM_REFERENCE_KINDS,
    SystemBody,
    SystemJoint,
    SystemScenario,
    joint_residuals,
    magnitude_problems,
)
from scenarios.tree import spanning_tree

_BODY_KEYS = {
    "name": "name",
    "mass": "number",
    "inertia": "vec3",
    "position": "vec3",
    "rotation": "mat3",
    "quaternion_wxyz": "vec4",
    "rotation_vector": "vec3",
    "velocity": "vec3",
    "omega_body": "vec3",
    "shape": "table",
}


_BODY_REQUIRED = ("name", "mass", "inertia", "position")


_JOINT_KEYS = {
    "name": "name",
    "kind": "str",
    "body_a": "str",
    "body_b": "str",
    "anchor_a": "vec3",
    "anchor_b": "vec3",
    "axis_a": "vec3",
    "axis_b": "vec3",
    "angle": "number",
    "rate": "number",
    "rotation_vector": "vec3",
    "omega": "vec3",
}


_JOINT_REQUIRED = ("kind", "body_a", "body_b", "anchor_a", "anchor_b")


_TOP_KEYS = (
    "name",
    "description",
    "source",
    "tags",
    "bodies",
    "joints",
    "environment",
    "run",
    "reference",
    "tolerances",
    "engine_settings",
    "planes",
    "contacts",
    "forces",
    "torques",
    "springs",
)


def validate(data: dict, path: str | None = None):
    """A scenario of one body (:func:`scenarios.schema.validate`) or, for data with
    ``[[bodies]]``, of a system (:func:`validate_system`)."""
    from scenarios import schema

    if isinstance(data, dict) and "bodies" in data:
        return validate_system(data, path)
    return schema.validate(data, path)


def load_file(path):
    """Read and validate one scenario file of one body or of a system."""
    from scenarios import schema

    return validate(schema.read_file(path), path=str(path))


def validate_system(data: dict, path: str | None = None) -> SystemScenario:
    """Validate parsed TOML ``data`` of a system file into a :class:`SystemScenario`; raise
    :class:`~scenarios.schema.ScenarioError` listing every problem."""
    from scenarios import schema as sch

    probs: list[tuple] = []
    where = path if path is not None else "<scenario data>"

    def bad(f, value, rule):
        probs.append((f, value, rule))

    for key in data:
        if key not in _TOP_KEYS:
            bad(key, data[key], f"unknown key in a system file; allowed: {', '.join(_TOP_KEYS)}")
    _typed(data, {"name": "name", "description": "str"}, ("name", "description"), "", bad)
    env = _table(data, "environment", bad)
    run = _table(data, "run", bad, required=True)
    ref = _table(data, "reference", bad)
    gravity = np.array(_typed(env, {"gravity": "vec3"}, (), "environment", bad).get(
        "gravity", [0.0, 0.0, 0.0]), dtype=float)  # fmt: skip
    spec = {k: kind for k, (kind, _) in sch._SPEC["run"].items()}
    required = [k for k, (_, req) in sch._SPEC["run"].items() if req]
    good_run = _typed(run, spec, required, "run", bad)
    sweep, save_every = sch._check_run(good_run, bad)
    kind = ref.get("kind", "auto")
    if kind not in SYSTEM_REFERENCE_KINDS:
        bad(
            "reference.kind",
            kind,
            f"must be one of {', '.join(SYSTEM_REFERENCE_KINDS)}"
            f"{sch.did_you_mean(kind, SYSTEM_REFERENCE_KINDS)}",
        )
    params = {}
    for key, value in ref.items():
        if key == "kind":
            continue
        if not sch._finite(value):
            bad(f"reference.{key}", value, "a parameter of an exact motion is a finite number")
        else:
            params[key] = float(value)
    tolerances = sch._check_tolerances(data.get("tolerances"), bad)
    engine_settings = _engine_settings(data.get("engine_settings"), bad)
    from scenarios import system_checks as chk

    by_joints = _uses_joint_coordinates(data.get("joints"))
    n_probs = len(probs)
    angles = chk.angle_problems(data.get("joints"), data.get("bodies"))
    if angles:  # the states and joints are built from these numbers: nothing more to check
        probs.extend(angles)
        raise sch.ScenarioError(sch._message(where, probs), path=path, problems=probs)
    bodies = _bodies(data.get("bodies"), bad, by_joints)
    joints = _joints(data.get("joints"), bodies, bad)
    if by_joints and len(probs) == n_probs:
        bodies = _tree_states(bodies, joints, data["bodies"], data["joints"], bad)
    if not probs and joints:
        _initial_gaps(bodies, joints, bad)
    planes, contacts, forces = ct.read_contact_parts(data, bodies, bad)
    # the pairs the file lists, valid or not: a pair refused above (mu < 0, say) is no reason
    # to report its bodies as touching nothing or the file as listing no contact
    raw = data.get("contacts") if isinstance(data.get("contacts"), list) else []
    listed = [t["pair"] for t in raw if isinstance(t, dict) and isinstance(t.get("pair"), list)]
    torques, springs = (), ()
    if not probs:
        from scenarios.force_elements import read_force_elements

        torques, springs = read_force_elements(data, bodies, joints, bad, _typed)
        if (torques or springs) and kind not in ("auto", "numerical", "none"):
            bad("reference.kind", kind, "a system with force elements ([[torques]], "
                "[[springs]]) takes the numerical reference (auto) or none: the closed forms "
                "know no force elements")  # fmt: skip
    if (
        contacts
        and kind in SYSTEM_REFERENCE_KINDS
        and kind not in (*CONTACT_CLOSED_FORMS, "none", "auto")
    ):
        bad("reference.kind", kind, "a scene with [[contacts]] takes a contact closed form ("
            f"{', '.join(CONTACT_CLOSED_FORMS)}) or none")  # fmt: skip
    elif kind in CONTACT_CLOSED_FORMS and not contacts and not listed:
        bad("reference.kind", kind, "a contact closed form needs [[contacts]] (the pairs that "
            "touch)")  # fmt: skip
    if not probs and contacts:
        ct.initial_penetrations(
            types.SimpleNamespace(bodies=bodies, planes=planes, contacts=contacts), bad
        )
    touching = {n for c in contacts for n in (c.a, c.b)}
    touching |= {n for pair in listed for n in pair if isinstance(n, str)}
    # a pair naming an unknown body is reported as such; the body it meant is not also
    # reported as joined to nothing
    if touching <= {b.name for b in bodies} | {pl.name for pl in planes}:
        probs.extend(chk.unjoined_problems(bodies, joints, touching))
    if not probs:
        probs.extend(chk.step_problems(bodies, good_run["dt"], sweep))
    if probs:
        raise sch.ScenarioError(sch._message(where, probs), path=path, problems=probs)
    sc = SystemScenario(
        name=data["name"],
        description=data["description"],
        bodies=bodies,
        joints=joints,
        gravity=gravity,
        t_end=float(good_run["t_end"]),
        dt=float(good_run["dt"]),
        dt_sweep=tuple(float(h) for h in sweep),
        save_every=int(save_every),
        accuracies=tuple(float(a) for a in good_run.get("accuracies", ())),
        reference=kind,
        reference_params=params,
        tolerances=tolerances,
        engine_settings=engine_settings,
        planes=planes,
        contacts=contacts,
        forces=forces,
        torques=torques,
        springs=springs,
        source=data.get("source", ""),
        tags=tuple(data.get("tags", ())),
        path=path,
    )
    probs = magnitude_problems(sc)
    if probs:
        raise sch.ScenarioError(sch._message(where, probs), path=path, problems=probs)
    return sc


def _engine_settings(table, bad) -> dict:
    """``[engine_settings.<engine>]``: name = a number, a string, a boolean or a list of
    numbers, handed to that engine's system builder as keyword arguments (e.g. MuJoCo's
    ``solref`` of the loop closures); the builder refuses a name it does not take."""
    from scenarios import schema as sch

    if table is None:
        return {}
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        bad("engine_settings", table, "must hold one table per engine: [engine_settings.<name>]")
        return {}
    out: dict = {}
    for engine, values in table.items():
        for k, v in values.items():
            ok = (
                isinstance(v, str | bool)
                or sch._finite(v)
                or (isinstance(v, list) and v and sch._finite_numbers(v))
            )
            if not ok:
                bad(
                    f"engine_settings.{engine}.{k}",
                    v,
                    "must be a number, a string, a boolean or a list of numbers",
                )
            else:
                out.setdefault(str(engine), {})[str(k)] = v
    return out  # fmt: skip


def _table(data, key, bad, required=False) -> dict:
    v = data.get(key)
    if v is None:
        if required:
            bad(key, "<missing>", "required: a table")
        return {}
    if not isinstance(v, dict):
        bad(key, v, "must be a table")
        return {}
    return v


def _typed(tab, keys, required, prefix, bad) -> dict:
    """The entries of ``tab`` of the right type; unknown, missing and mistyped ones are
    reported with the field ``prefix.key``."""
    from scenarios import schema as sch

    def dotted(key):
        return f"{prefix}.{key}" if prefix else key

    good = {}
    for key in tab:
        if key not in keys and prefix:
            bad(dotted(key), tab[key], f"unknown key; allowed here: {', '.join(keys)}")
    for key, kind in keys.items():
        if key not in tab:
            if key in required:
                bad(dotted(key), "<missing>", f"required: {sch._KIND_TEXT[kind]}")
        elif not sch._type_ok(kind, tab[key]):
            bad(dotted(key), tab[key], f"must be {sch._KIND_TEXT[kind]}")
        else:
            good[key] = tab[key]
    return good


def _attitude(tab: dict, prefix: str, bad) -> np.ndarray:
    """The body's initial rotation: at most one of three forms (none: identity)."""
    from scenarios import schema as sch

    forms = [k for k in ("rotation", "quaternion_wxyz", "rotation_vector") if k in tab]
    if len(forms) > 1:
        bad(prefix, forms, "give the initial attitude exactly once")
        return np.eye(3)
    if not forms:
        return np.eye(3)
    k = forms[0]
    if k == "rotation":
        R = np.array(tab[k], dtype=float)
        dev = float(np.max(np.abs(R.T @ R - np.eye(3))))
        if dev > sch.ROTATION_TOL:
            bad(f"{prefix}.rotation", tab[k], f"not orthonormal: max |R^T R - 1| = {dev:.3g} > "
                f"{sch.ROTATION_TOL:g} (give 17 digits, or use rotation_vector)")  # fmt: skip
        elif float(np.linalg.det(R)) < 0:
            bad(f"{prefix}.rotation", tab[k], "det R = -1: a reflection, not a rotation")
        return R
    if k == "quaternion_wxyz":
        q = np.array(tab[k], dtype=float)
        if abs(float(np.linalg.norm(q)) - 1.0) > sch.ROTATION_TOL:
            bad(f"{prefix}.quaternion_wxyz", tab[k], "not a unit quaternion")
            return np.eye(3)
        return sch.rotation_from_quaternion(q)
    return sch.rotation_from_vector(tab[k])


def _bodies(raw, bad, by_joints: bool = False) -> list[SystemBody]:
    """The ``[[bodies]]`` tables; ``by_joints``: the initial state comes from the joint
    coordinates (:func:`_tree_states`), so ``position`` is not required here."""
    from scenarios import schema as sch

    if not isinstance(raw, list) or not raw or not all(isinstance(b, dict) for b in raw):
        bad("bodies", "<missing>" if raw is None else raw, "required: an array of [[bodies]] "
            "tables, one per body")  # fmt: skip
        return []
    out, seen = [], set()
    z = [0.0, 0.0, 0.0]
    for i, tab in enumerate(raw):
        p = f"bodies[{i}]"
        required = _BODY_REQUIRED[:3] if by_joints else _BODY_REQUIRED
        good = _typed(tab, _BODY_KEYS, required, p, bad)
        name = good.get("name", f"body{i}")
        if name == "ground":
            bad(f"{p}.name", name, "'ground' names the fixed world in joints; rename the body")
        if name in seen:
            bad(f"{p}.name", name, "body names must be unique")
        seen.add(name)
        for f, v, rule in sch.body_problems(good.get("mass"), good.get("inertia"), p):
            bad(f, v, rule)
        R = _attitude(good, p, bad)
        shape = ct.read_shape(tab["shape"], f"{p}.shape", bad) if "shape" in tab else None
        out.append(
            SystemBody(
                name=name,
                mass=float(good.get("mass", 1.0)),
                inertia=np.array(good.get("inertia", [1.0, 1.0, 1.0]), dtype=float),
                position=np.array(good.get("position", z), dtype=float),
                rotation=R,
                velocity=np.array(good.get("velocity", z), dtype=float),
                omega_body=np.array(good.get("omega_body", z), dtype=float),
                shape=shape,
            )
        )
    return out


def _joints(raw, bodies, bad) -> list[SystemJoint]:
    if raw is None:
        raw = []
    if not isinstance(raw, list) or not all(isinstance(j, dict) for j in raw):
        bad("joints", raw, "must be an array of [[joints]] tables")
        return []
    names = {b.name for b in bodies}
    known = ", ".join(sorted(names)[:20]) + (" ..." if len(names) > 20 else "")
    out, seen = [], set()
    for i, tab in enumerate(raw):
        p = f"joints[{i}]"
        good = _typed(tab, _JOINT_KEYS, _JOINT_REQUIRED, p, bad)
        name = good.get("name", f"joint{i}")
        if name in seen:
            bad(f"{p}.name", name, "joint names must be unique")
        seen.add(name)
        kind = good.get("kind", "spherical")
        if kind not in JOINT_KINDS:
            bad(f"{p}.kind", kind, f"must be one of {', '.join(JOINT_KINDS)}")
        a, b = good.get("body_a"), good.get("body_b")
        if a == "ground":
            bad(
                f"{p}.body_a",
                a,
                "the ground is always body_b (its anchor_b and axis_b in world axes): swap "
                "the sides, anchors and axes included",
            )
        elif a is not None and a not in names:
            bad(f"{p}.body_a", a, f"not a body of this file; bodies: {known}")
        if b is not None and b != "ground" and b not in names:
            bad(f"{p}.body_b", b, f"not a body of this file nor 'ground'; bodies: {known}")
        if a is not None and a == b:
            bad(f"{p}.body_b", b, "a joint joins two different bodies")
        if kind == "fixed_point" and b != "ground":
            bad(f"{p}.body_b", b, "a fixed_point joint ties a body to the ground: 'ground'")
        axes = {}
        for k in ("axis_a", "axis_b"):
            v = good.get(k)
            if kind in AXIS_KINDS and k not in tab:
                bad(f"{p}.{k}", "<missing>", f"required for a {kind} joint: 3 numbers")
            elif v is not None and kind not in AXIS_KINDS:
                bad(f"{p}.{k}", v, f"a {kind} joint takes no axis")
            elif v is not None and not float(np.linalg.norm(v)) > 0:
                bad(f"{p}.{k}", v, "an axis must be non-zero")
            elif v is not None:
                axes[k] = np.asarray(v, dtype=float) / float(np.linalg.norm(v))
        out.append(
            SystemJoint(
                name=name,
                kind=kind,
                body_a=a if a in names else "",
                body_b=None if b == "ground" or b not in names else b,
                anchor_a=np.array(good.get("anchor_a", [0.0, 0.0, 0.0]), dtype=float),
                anchor_b=np.array(good.get("anchor_b", [0.0, 0.0, 0.0]), dtype=float),
                axis_a=axes.get("axis_a"),
                axis_b=axes.get("axis_b"),
            )
        )
    return out


#: the joint coordinates of each kind that has them: (angle, rate) of a revolute joint,
#: (rotation_vector, omega) of a spherical or fixed_point joint
COORDINATE_KEYS = {
    "revolute": ("angle", "rate"),
    "spherical": ("rotation_vector", "omega"),
    "fixed_point": ("rotation_vector", "omega"),
}


_ALL_COORDINATES = ("angle", "rate", "rotation_vector", "omega")


#: a body's initial-state fields (per-body form)
_STATE_KEYS = ("position", "rotation", "quaternion_wxyz", "rotation_vector", "velocity",
               "omega_body")  # fmt: skip


def _uses_joint_coordinates(raw_joints) -> bool:
    """True when some ``[[joints]]`` table gives a joint coordinate."""
    return isinstance(raw_joints, list) and any(
        isinstance(t, dict) and any(k in t for k in _ALL_COORDINATES) for t in raw_joints
    )


def _hinge_zero(u_child: np.ndarray, u_parent: np.ndarray) -> np.ndarray | None:
    """Q0, the smallest rotation with Q0 u_child = u_parent (a revolute joint at angle 0);
    None when the axes are (nearly) opposite and Q0 is not unique."""
    from scenarios import schema as sch

    axis = np.cross(u_child, u_parent)
    s, c = float(np.linalg.norm(axis)), float(u_child @ u_parent)
    if s == 0.0 and c > 0.0:
        return np.eye(3)
    if c < 0.0 and s < 1e-8:
        return None
    return sch.rotation_from_vector(axis / s * math.atan2(s, c))


def _tree_states(bodies, joints, raw_bodies, raw_joints, bad) -> list[SystemBody]:
    """The bodies' initial world states from joint coordinates, by forward kinematics along
    the spanning tree (:func:`spanning_tree`: from the ground outwards; a floating part
    from its first body in file order, its root, whose world state its ``[[bodies]]``
    table gives).

    For a tree joint with parent p (the side nearer the ground or the root; the ground has
    x = 0, R = 1) and child c, anchors s_p, s_c and axes u_p, u_c on either side (for
    the ground, world coordinates), the child's attitude relative to the parent is
    Q = R_p^T R_c: ``rotation_vector`` phi (rad, parent's axes) of a spherical or fixed_point
    joint gives Q = exp(phi); ``angle`` theta (rad) of a revolute joint gives
    Q = exp(theta u_p) Q0, Q0 the smallest rotation with Q0 u_c = u_p (the axes aligned;
    theta positive turns the child about u_p by the right-hand rule). ``omega`` (rad/s,
    parent's axes), or ``rate`` times u_p, is the child's angular velocity relative to the
    parent. Then R_c = R_p Q, x_c = x_p + R_p s_p - R_c s_c (the anchors coincide),
    w_c = w_p + R_p omega, v_c = v_p + w_p x (R_p s_p) - w_c x (R_c s_c) (the anchor points
    move together). Missing coordinates are 0. Refused (every problem through ``bad``): a
    loop closure, a tree joint of another kind, a coordinate of the wrong kind, opposite
    revolute axes, a body state beside the coordinates (the root of a floating part
    excepted, whose ``position`` is required)."""
    from scenarios import schema as sch

    st = spanning_tree(bodies, joints)
    jidx = {j.name: i for i, j in enumerate(joints)}
    ok = True
    for i in st.loops:
        name = joints[i].name
        given = [k for k in _ALL_COORDINATES if k in raw_joints[i]]
        field_ = f"joints[{i}].{given[0]}" if given else f"joints[{i}]"
        bad(field_, raw_joints[i][given[0]] if given else name, f"joint {name!r} closes a "
            "loop: joint coordinates give the initial state of a tree only (the closure "
            "is not solved); give per-body states")  # fmt: skip
        ok = False
    zero = {}
    for i in st.tree:
        j = joints[i]
        keys = COORDINATE_KEYS.get(j.kind)
        if keys is None:
            bad(f"joints[{i}].kind", j.kind, "joint coordinates are defined for revolute, "
                "spherical and fixed_point joints only; give per-body states")  # fmt: skip
            ok = False
            continue
        for k in _ALL_COORDINATES:
            if k in raw_joints[i] and k not in keys:
                bad(f"joints[{i}].{k}", raw_joints[i][k], f"a {j.kind} joint's coordinates "
                    f"are {' and '.join(keys)}")  # fmt: skip
                ok = False
    # the tree joints, parents before children (the walk's order), as (joint, parent, child);
    # the parent of a joint to the ground is "ground"
    order = []
    for c in st.order:
        p, k = st.parent[c]
        if k is not None:
            order.append((joints[k], p or "ground", c))
    roots = st.floating_roots
    placed_by = {c: j.name for j, _, c in order}
    for i, b in enumerate(bodies):
        tab = raw_bodies[i]
        if b.name in roots:
            if "position" not in tab:
                bad(f"bodies[{i}].position", "<missing>", f"required: body {b.name!r} is the "
                    "root of a floating tree given by joint coordinates (its world position; "
                    "its attitude and velocities default to 1 and 0)")  # fmt: skip
                ok = False
            continue
        for k in _STATE_KEYS:
            if k in tab:
                bad(f"bodies[{i}].{k}", tab[k], f"body {b.name!r} is placed by joint "
                    f"{placed_by[b.name]!r}'s coordinates: give either per-body states or "
                    "joint coordinates, never both")  # fmt: skip
                ok = False
    for j, _p, c in order:
        if j.kind != "revolute":
            continue
        u_c, u_p = (j.axis_a, j.axis_b) if j.body_a == c else (j.axis_b, j.axis_a)
        zero[j.name] = _hinge_zero(u_c, u_p)
        if zero[j.name] is None:
            i = jidx[j.name]
            bad(f"joints[{i}].axis_b", j.axis_b.tolist(), f"joint {j.name!r}: axis_a and "
                "axis_b point opposite ways, so its angle 0 (the axes aligned) is not "
                "defined; reverse one of them")  # fmt: skip
            ok = False
    if not ok:
        return bodies
    by = {b.name: b for b in bodies}
    z = np.zeros(3)
    state = {"ground": (z, np.eye(3), z, z)}  # x, R, v, w (world)
    for r in roots:
        b = by[r]
        state[r] = (b.position, b.rotation, b.velocity, b.rotation @ b.omega_body)
    for j, p, c in order:
        tab = raw_joints[jidx[j.name]]
        if j.body_a == c:
            s_c, s_p, u_p = j.anchor_a, j.anchor_b, j.axis_b
        else:
            s_c, s_p, u_p = j.anchor_b, j.anchor_a, j.axis_a
        if j.kind == "revolute":
            Q = sch.rotation_from_vector(float(tab.get("angle", 0.0)) * u_p) @ zero[j.name]
            w_rel = float(tab.get("rate", 0.0)) * u_p
        else:
            Q = sch.rotation_from_vector(tab.get("rotation_vector", [0.0, 0.0, 0.0]))
            w_rel = np.asarray(tab.get("omega", [0.0, 0.0, 0.0]), dtype=float)
        x_p, R_p, v_p, w_p = state[p]
        R_c = R_p @ Q
        w_c = w_p + R_p @ w_rel
        r_p, r_c = R_p @ s_p, R_c @ s_c
        state[c] = (x_p + r_p - r_c, R_c, v_p + np.cross(w_p, r_p) - np.cross(w_c, r_c), w_c)
    out = []
    for b in bodies:
        x, R, v, w = state[b.name]
        out.append(SystemBody(name=b.name, mass=b.mass, inertia=b.inertia, position=x,
                              rotation=R, velocity=v, omega_body=R.T @ w,
                              shape=b.shape))  # fmt: skip
    return out


def _initial_gaps(bodies, joints, bad) -> None:
    """Each joint must hold at t = 0: position and axes to :data:`JOINT_TOL`, the relative
    velocity of the anchor points to JOINT_TOL times the bodies' speed scale (m/s)."""
    x = np.array([b.position for b in bodies])[None]
    R = np.array([b.rotation for b in bodies])[None]
    v = np.array([b.velocity for b in bodies])[None]
    W = np.array([b.omega_body for b in bodies])[None]
    size = max([1.0] + [float(np.linalg.norm(a)) for j in joints for a in (j.anchor_a,)])
    speed = max(
        [1.0]
        + [float(np.linalg.norm(b.velocity)) for b in bodies]
        + [float(np.linalg.norm(b.omega_body)) * size for b in bodies]
    )
    index = {b.name: i for i, b in enumerate(bodies)}
    for i, j in enumerate(joints):
        r = joint_residuals(bodies, j, x, R, v, W, index=index)
        if r["gap"][0] > JOINT_TOL:
            bad(f"joints[{i}].anchor_b", j.anchor_b.tolist(), f"joint {j.name!r} is open at "
                f"t = 0 by {r['gap'][0]:.3g} m (the anchors must coincide to {JOINT_TOL:g} m; "
                "anchors are in each body's principal frame relative to its centre of mass, "
                "a ground anchor in world axes)")  # fmt: skip
        elif r["angle"][0] > JOINT_TOL:
            rule = "perpendicular" if j.kind == "universal" else "aligned"
            bad(
                f"joints[{i}].axis_b",
                j.axis_b.tolist(),
                f"joint {j.name!r}: the axes are off "
                f"by {r['angle'][0]:.3g} rad at t = 0 (must be {rule} to {JOINT_TOL:g})",
            )
            # fmt: skip
        elif r["gap_rate"][0] > JOINT_TOL * speed:
            bad(
                f"joints[{i}]",
                j.name,
                f"the initial velocities violate joint {j.name!r}: the "
                f"anchor points separate at {r['gap_rate'][0]:.3g} m/s (at most "
                f"{JOINT_TOL * speed:.3g}); give velocities consistent with the joints",
            )
