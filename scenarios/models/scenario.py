"""A robot model as a scenario: a TOML file whose ``[model]`` table names a URDF or MJCF file
(or a model by name, :mod:`scenarios.models.library`), validated into a system scenario whose
bodies and joints are our own reading of that file (docs/scenarios.md, "Robot models")::

    name = "arm3_swing"
    description = "..."
    [model]
    file = "models/arm3.urdf"        # relative to this file; or name = "gymnasium:ant"
    floating = false                 # URDF: fixed base unless true; MJCF: as the file says
    lock = []                        # joints held at their initial value
    meshes = "require"               # or "ignore" (mesh files not checked)
    packages = {}                    # package name -> folder, for package:// file names
    [model.initial]
    joints = {shoulder = 0.6, elbow = -0.9}   # rad (a ball joint: a rotation vector)
    rates = {shoulder = 0.0}                  # rad/s
    base_position = [0, 0, 0]        # the root frame's world pose (floating or fixed base)
    base_rotation_vector = [0, 0, 0]
    base_velocity = [0, 0, 0]        # the root frame origin's velocity, world, m/s (floating)
    base_omega = [0, 0, 0]           # the root's angular velocity, world, rad/s (floating)
    [environment]
    gravity = [0, 0, -9.81]
    [run] / [reference] / [tolerances] / [engine_settings]   as for any system

A clean test switches off what the file has of damping, friction, armature, springs, joint
limits, actuators and contact: the system holds none of them, and the scenario records what
was switched off (:attr:`ModelScenario.switched_off`), which ``show`` prints with the links,
masses, inertias, joints and axes it read.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from scenarios.models.xml import ModelError
from scenarios.system import SystemScenario

_MODEL_KEYS = {
    "file": "str",
    "name": "str",
    "floating": "bool",
    "lock": "str_list",
    "meshes": "str",
    "packages": "table",
    "initial": "table",
}
_INITIAL_KEYS = {
    "joints": "table",
    "rates": "table",
    "base_position": "vec3",
    "base_rotation_vector": "vec3",
    "base_velocity": "vec3",
    "base_omega": "vec3",
}
_TOP_KEYS = (
    "name",
    "description",
    "source",
    "tags",
    "model",
    "environment",
    "run",
    "reference",
    "tolerances",
    "engine_settings",
)


@dataclass(frozen=True, eq=False)
class ModelScenario(SystemScenario):
    """A system scenario read from a robot model: the system's fields, and ``model`` (the
    :class:`~scenarios.models.model.RobotModel` as read), ``conversion`` (its
    :class:`~scenarios.models.model.Conversion`: which links each body holds), ``model_spec``
    (the ``[model]`` table as resolved: file, its SHA-256, floating, locked joints, initial
    state, what was switched off)."""

    model: object = None
    conversion: object = None
    model_spec: dict = field(default_factory=dict)

    @property
    def switched_off(self) -> list[str]:
        return list(self.model_spec.get("switched_off", []))

    def to_dict(self) -> dict:
        d = super().to_dict()
        d["model"] = dict(self.model_spec)
        return d


def _typed(tab, keys, prefix, bad) -> dict:
    from scenarios import schema as sch

    out = {}
    for k, v in tab.items():
        kind = keys.get(k)
        if kind is None:
            bad(f"{prefix}.{k}", v, f"unknown key; allowed here: {', '.join(keys)}")
        elif kind == "bool":
            if isinstance(v, bool):
                out[k] = v
            else:
                bad(f"{prefix}.{k}", v, "must be true or false")
        elif kind == "table":
            if isinstance(v, dict):
                out[k] = v
            else:
                bad(f"{prefix}.{k}", v, "must be a table")
        elif sch._type_ok(kind, v):
            out[k] = v
        else:
            bad(f"{prefix}.{k}", v, f"must be {sch._KIND_TEXT[kind]}")
    return out


def _coords(tab, prefix, bad) -> dict:
    from scenarios import schema as sch

    out = {}
    for k, v in tab.items():
        if sch._finite(v) or (isinstance(v, list) and len(v) == 3 and sch._finite_numbers(v)):
            out[str(k)] = v if not isinstance(v, list) else np.asarray(v, dtype=float)
        else:
            bad(
                f"{prefix}.{k}",
                v,
                "a joint coordinate is a finite number (rad, rad/s), or 3 numbers for a ball joint",
            )
    return out


def model_file(spec: dict, path: str | None, bad) -> tuple[Path | None, dict]:
    """(file, package folders) named by the ``[model]`` table."""
    from scenarios.models import library

    have = [k for k in ("file", "name") if k in spec]
    if len(have) != 1:
        bad(
            "model",
            sorted(spec),
            "give exactly one of model.file (a path) and model.name (e.g. 'gymnasium:ant')",
        )
        return None, {}
    packages = {}
    base = Path(path).resolve().parent if path else Path.cwd()
    for k, v in spec.get("packages", {}).items():
        if not isinstance(v, str):
            bad(f"model.packages.{k}", v, "a folder (string)")
        else:
            packages[k] = base / Path(v).expanduser()
    if "file" in spec:
        return base / Path(spec["file"]).expanduser(), packages
    try:
        f, pk = library.resolve(spec["name"])
    except ModelError as exc:
        bad("model.name", spec["name"], str(exc))
        return None, {}
    pk.update(packages)
    return f, pk


def validate_model(data: dict, path: str | None = None) -> ModelScenario:
    """Validate the parsed TOML of a ``[model]`` scenario file (module docstring); raise
    :class:`~scenarios.schema.ScenarioError` listing every problem, a problem of the model
    file naming that file, its element and the rule."""
    from scenarios import schema as sch
    from scenarios import system_file as sy
    from scenarios.models import read_model
    from scenarios.models.model import to_system

    probs: list[tuple] = []
    where = path if path is not None else "<scenario data>"

    def bad(f, value, rule):
        probs.append((f, value, rule))

    def fail():
        raise sch.ScenarioError(sch._message(where, probs), path=path, problems=probs)

    for key in data:
        if key not in _TOP_KEYS:
            bad(key, data[key], f"unknown key in a model scenario; allowed: {', '.join(_TOP_KEYS)}")
    sy._typed(data, {"name": "name", "description": "str"}, ("name", "description"), "", bad)
    spec = _typed(sy._table(data, "model", bad, required=True), _MODEL_KEYS, "model", bad)
    init = _typed(spec.get("initial", {}), _INITIAL_KEYS, "model.initial", bad)
    q0 = _coords(init.get("joints", {}), "model.initial.joints", bad)
    qd0 = _coords(init.get("rates", {}), "model.initial.rates", bad)
    meshes = spec.get("meshes", "require")
    if meshes not in ("require", "ignore"):
        bad("model.meshes", meshes, "'require' or 'ignore'")
    env = sy._table(data, "environment", bad)
    gravity = np.array(
        sy._typed(env, {"gravity": "vec3"}, (), "environment", bad).get("gravity", [0.0, 0.0, 0.0]),
        dtype=float,
    )
    run = sy._table(data, "run", bad, required=True)
    runspec = {k: kind for k, (kind, _) in sch._SPEC["run"].items()}
    required = [k for k, (_, req) in sch._SPEC["run"].items() if req]
    good_run = sy._typed(run, runspec, required, "run", bad)
    sweep, save_every = sch._check_run(good_run, bad)
    ref = sy._table(data, "reference", bad)
    kind = ref.get("kind", "numerical")
    if kind not in ("auto", "numerical", "none"):
        bad(
            "reference.kind",
            kind,
            "a robot model's reference is numerical (the reduced-"
            "coordinate reference), auto or none",
        )
    for k in ref:
        if k != "kind":
            bad(f"reference.{k}", ref[k], "a robot model's reference takes no parameters")
    tolerances = sch._check_tolerances(data.get("tolerances"), bad)
    engine_settings = sy._engine_settings(data.get("engine_settings"), bad)
    f, packages = model_file(spec, path, bad)
    if probs or f is None:
        fail()
    try:
        model = read_model(f, packages=packages, meshes=meshes)
        br = init.get("base_rotation_vector")
        conv = to_system(
            model,
            q0,
            qd0,
            floating=spec.get("floating"),
            base_position=init.get("base_position"),
            base_rotation=None if br is None else sch.rotation_from_vector(br),
            base_velocity=init.get("base_velocity"),
            base_omega=init.get("base_omega"),
            lock=spec.get("lock", ()),
        )
    except ModelError as exc:
        bad(
            "model." + ("file" if "file" in spec else "name"),
            spec.get("file", spec.get("name")),
            str(exc),
        )
        fail()
    sy._initial_gaps(conv.bodies, conv.joints, bad)
    if probs:
        fail()
    digest = hashlib.sha256(Path(f).read_bytes()).hexdigest()
    floating = not any(j.body_b is None for j in conv.joints)
    mspec = {
        "file": str(f),
        "name": spec.get("name", ""),
        "format": model.format,
        "sha256": digest,
        "floating": floating,
        "lock": list(conv.locked),
        "initial": {
            k: (v.tolist() if isinstance(v, np.ndarray) else v)
            for k, v in {
                **{f"joints.{a}": b for a, b in q0.items()},
                **{f"rates.{a}": b for a, b in qd0.items()},
                **{k: init[k] for k in init if k.startswith("base_")},
            }.items()
        },
        "switched_off": model.switched_off,
    }
    sc = ModelScenario(
        name=data["name"],
        description=data["description"],
        bodies=conv.bodies,
        joints=conv.joints,
        gravity=gravity,
        t_end=float(good_run["t_end"]),
        dt=float(good_run["dt"]),
        dt_sweep=tuple(float(h) for h in sweep),
        save_every=int(save_every),
        accuracies=tuple(float(a) for a in good_run.get("accuracies", ())),
        reference=kind,
        tolerances=tolerances,
        engine_settings=engine_settings,
        source=data.get("source", ""),
        tags=tuple(data.get("tags", ())),
        path=path,
        model=model,
        conversion=conv,
        model_spec=mspec,
    )
    probs = sy.magnitude_problems(sc)
    if probs:
        fail()
    return sc


def describe(sc: ModelScenario) -> list[str]:
    """``show``'s lines for a model scenario: the file, then per link its mass, centre of mass
    and inertia as read (link frame), per joint its kind, parent, child, axis and origin, the
    bodies the links were fused into, and what the clean test switches off."""

    def vec(a) -> str:
        return "[" + ", ".join(f"{float(x):.6g}" for x in np.ravel(a)) + "]"

    m = sc.model
    conv = sc.conversion
    spec = sc.model_spec
    out = [f"  model {spec['file']} ({m.format}, {m.name!r}; sha256 {spec['sha256'][:12]})"]
    out.append(
        f"  {len(m.links)} links, {len(m.joints)} joints ({len(m.moving_joints)} moving)"
        f"; {'floating base' if spec['floating'] else 'fixed base'}"
    )
    for lk in m.links:
        ine = lk.inertial
        I = ine.inertia
        out.append(
            f"    link {lk.name}: mass {ine.mass:.6g} kg, com {vec(ine.com)} m, inertia "
            f"[xx {I[0, 0]:.6g}, yy {I[1, 1]:.6g}, zz {I[2, 2]:.6g}, xy {I[0, 1]:.6g}, "
            f"xz {I[0, 2]:.6g}, yz {I[1, 2]:.6g}] kg m^2 ({ine.source})"
        )
    for j in m.joints:
        lim = "" if j.lower is None else f", limits [{j.lower:.6g}, {j.upper:.6g}]"
        held = " (held)" if j.name in conv.locked else ""
        out.append(
            f"    joint {j.name}: {j.kind}{held} {j.parent or 'world'} -> {j.child}, "
            f"origin {vec(j.origin[:3, 3])} m, axis {vec(j.axis)} (child frame)"
            + (f", point {vec(j.point)}" if np.any(j.point) else "")
            + lim
        )
    for b, links in conv.groups.items():
        if len(links) > 1:
            out.append(f"    body {b} holds links {', '.join(links)} (fixed joints)")
    if conv.ground_links:
        out.append(f"    fixed to the world: {', '.join(conv.ground_links)}")
    off = spec["switched_off"]
    out.append("  switched off: " + ("; ".join(off) if off else "nothing (the file has none)"))
    for n in m.notes:
        out.append(f"  note: {n}")
    return out
