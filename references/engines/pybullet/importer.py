"""PyBullet's own importer (``loadURDF``, ``loadMJCF``) on a model file, read back
(:mod:`references.engines.importers`) through ``getDynamicsInfo``, ``getLinkState`` and
``getJointInfo``. As loaded, ``loadURDF`` and ``loadMJCF`` take no flags; faithful, they take
``URDF_USE_INERTIA_FROM_FILE`` (without it PyBullet recomputes each link's inertia from its
collision shapes: :data:`HINTS`), and ``loadURDF`` a copy of the file without geometry whose
joint axes are unit vectors (PyBullet keeps an axis's length, which scales the joint's
coordinate and rate).

``loadMJCF`` (Bullet's ``BulletMJCFImporter.cpp``, bullet3 examples/Importers/ImportMJCFDemo)
reads each element's own attributes and little else: a body without ``<inertial>`` gets the
mass 1000 kg/m^3 times its geoms' volume (a constant in ``parseBody``: neither a geom's
``density`` or ``mass`` nor a ``<default>``'s is read; a mesh adds no volume), its centre of
mass at the midpoint of its last ``fromto`` capsule (else the body origin) and, without
``URDF_USE_INERTIA_FROM_FILE``, the inertia of its collision shapes; a joint's ``type`` and
``axis`` only when written on the joint itself (not from a class), the axis kept unnormalised;
``euler``, ``xyaxes``, ``zaxis``, ``<freejoint>``, ``ref``, ``damping`` and ellipsoids not at
all. The faithful configuration therefore loads a copy of the file written out from MuJoCo's
compiled model of it (:func:`flat_mjcf`): every body's ``pos`` and ``quat``, an explicit
``<inertial>`` (``inertiafromgeom="false"``), every joint's type, position and unit axis on the
joint, no geometry (the scenario is contact-free). PyBullet's coordinate 0 of an MJCF joint is
then the file's pose, where MuJoCo's is ``ref``: a scenario's joint value q is PyBullet's
q - ref."""

from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from references.engines.importers import (
    Readback,
    combine,
    file_for,
    mjcf_copy,
    quiet_fd,
    rot_inertia,
    to_root,
)

#: the known cause of a difference, by configuration and quantity, printed beside it
HINTS = {
    ("as-loaded", "inertia"): "loadURDF without URDF_USE_INERTIA_FROM_FILE "
    "recomputes the inertia from the collision shapes: pass that flag",
    ("as-loaded", "com"): "loadURDF without URDF_USE_INERTIA_FROM_FILE",
    ("as-loaded", "mass", "mjcf"): "loadMJCF gives a body without <inertial> 1000 kg/m^3 "
    "times its geoms' volume, reading no density or mass of the file (BulletMJCFImporter.cpp "
    "parseBody); the faithful configuration writes each body's <inertial> out",
    ("as-loaded", "inertia", "mjcf"): "loadMJCF without URDF_USE_INERTIA_FROM_FILE takes the "
    "inertia of the collision shapes at its own mass; the faithful configuration writes each "
    "body's <inertial> out and passes that flag",
    ("as-loaded", "com", "mjcf"): "loadMJCF puts a body's centre of mass at its last fromto "
    "capsule's midpoint, else at the body origin",
    ("as-loaded", "missing", "mjcf"): "loadMJCF reads a joint's type and axis only from the "
    "joint element (not from a default class) and skips <freejoint>, euler, xyaxes, zaxis",
    ("as-loaded", "damping", "mjcf"): "loadMJCF does not read a joint's damping",
}  # fmt: skip


_MJCF_JOINT = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}

#: attributes of a body or joint that the flat copy replaces by its own
_FRAME_KEYS = ("pos", "quat", "euler", "axisangle", "xyaxes", "zaxis", "class", "childclass")


def _num(a) -> str:
    return " ".join(repr(float(x)) for x in a)


def flat_mjcf(model) -> tuple:
    """(the path of PyBullet's faithful copy of the MJCF file, its temporary folder): the file
    with every body's ``pos`` and ``quat``, an ``<inertial>`` and every joint's type, ``pos``
    and unit ``axis`` written on the element from MuJoCo's compiled model of the file (its
    qpos0: the file's pose) and its range (radians) where the joint is limited,
    ``inertiafromgeom="false"``, every geom and ``<default>`` removed, ``<freejoint>`` written
    as ``<joint type="free">``.
    Raises ValueError when the file's bodies or joints do not pair with MuJoCo's one for one
    (a ``<frame>``, an ``<include>`` or a ``<replicate>`` that MuJoCo expands)."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(Path(model.path).resolve()))

    def edit(root):
        comp = root.find("compiler")
        comp.set("inertiafromgeom", "false")
        comp.set("angle", "radian")
        for key in ("eulerseq", "autolimits"):
            comp.attrib.pop(key, None)
        for el in root.findall("default"):
            root.remove(el)
        world = root.find("worldbody")
        if world is None or world.find(".//frame") is not None:
            raise ValueError("the file's <worldbody> has <frame> elements or none at all")
        bodies = list(world.iter("body"))
        if len(bodies) != m.nbody - 1:
            raise ValueError(f"the file has {len(bodies)} bodies, MuJoCo's model {m.nbody - 1}")
        for parent in [world, *bodies]:
            for g in parent.findall("geom"):
                parent.remove(g)
        for b, el in enumerate(bodies, start=1):
            for key in _FRAME_KEYS:
                el.attrib.pop(key, None)
            el.set("pos", _num(m.body_pos[b]))
            el.set("quat", _num(m.body_quat[b]))
            for old in el.findall("inertial"):
                el.remove(old)
            ine = ET.Element(
                "inertial",
                {
                    "pos": _num(m.body_ipos[b]),
                    "quat": _num(m.body_iquat[b]),
                    "mass": repr(float(m.body_mass[b])),
                    "diaginertia": _num(m.body_inertia[b]),
                },
            )
            el.insert(0, ine)
            joints = [j for j in el if j.tag in ("joint", "freejoint")]
            if len(joints) != m.body_jntnum[b]:
                raise ValueError(
                    f"body {b}: {len(joints)} joints in the file, "
                    f"{m.body_jntnum[b]} in MuJoCo's model"
                )
            for k, jel in enumerate(joints):
                j = m.body_jntadr[b] + k
                jel.tag = "joint"
                jel.attrib.clear()
                jel.set("name", mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f"j{j}")
                jel.set("type", _MJCF_JOINT[int(m.jnt_type[j])])
                jel.set("pos", _num(m.jnt_pos[j]))
                jel.set("axis", _num(m.jnt_axis[j] / np.linalg.norm(m.jnt_axis[j])))
                limited = bool(m.jnt_limited[j])
                jel.set("limited", "true" if limited else "false")
                if limited:
                    jel.set("range", _num(m.jnt_range[j]))

    return mjcf_copy(model.path, edit)


def _unit_axes(path) -> None:
    """Rewrite every ``<joint><axis xyz>`` of the URDF file ``path`` as a unit vector (the
    URDF's axis is a direction; ``loadURDF`` keeps its length, which scales the joint's
    coordinate and rate)."""
    tree = ET.parse(path)
    for ax in tree.getroot().iter("axis"):
        v = np.array([float(x) for x in ax.get("xyz", "1 0 0").split()])
        n = float(np.linalg.norm(v))
        if n > 0 and abs(n - 1.0) > 1e-15:
            ax.set("xyz", _num(v / n))
    tree.write(path)


def _pybullet_file(model, config: str) -> tuple:
    """(the file PyBullet loads in ``config``, a temporary folder or None): the importers'
    :func:`~references.engines.importers.file_for`; faithful, for an MJCF file
    :func:`flat_mjcf`'s copy, for a URDF file that copy (no geometry) with unit axes."""
    if config == "faithful" and model.format == "mjcf":
        return flat_mjcf(model)
    path, tmp = file_for(model, config)
    if config == "faithful" and tmp is not None:
        _unit_axes(path)
    return path, tmp


def _load(p, path, model, floating: bool, flags: int, cid) -> list:
    if model.format == "urdf":
        return [p.loadURDF(str(path), useFixedBase=not floating, flags=flags,
                           physicsClientId=cid)]  # fmt: skip
    return list(p.loadMJCF(str(path), flags=flags, physicsClientId=cid))


def readback(model, config: str, floating: bool = False) -> Readback:
    from references.engines.pybullet.adapter import _import

    p = _import()  # its build-time banner silenced, as the adapter's runs have it

    rb = Readback("pybullet", config)
    cid = p.connect(p.DIRECT)
    tmp = None
    try:
        path, tmp = _pybullet_file(model, config)
        flags = p.URDF_USE_INERTIA_FROM_FILE if config == "faithful" else 0
        rb.notes.append(f"flags {flags}")
        with quiet_fd() as out:
            ids = _load(p, path, model, floating, flags, cid)
        if out and out[0].strip():
            rb.notes.append(out[0].strip().splitlines()[-1][:200])
        frames = {b: _frames(p, cid, b) for b in ids}
        # the root link's frame, in whichever loaded body holds it (loadMJCF returns one body
        # per tree of the world body: pusher's object and goal are bodies of their own)
        T = next((f[0][model.root] for f in frames.values() if model.root in f[0]), None)
        for b in ids:
            _pybullet_body(p, cid, b, model, rb, frames[b], T)
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {exc}".strip()
    finally:
        p.disconnect(cid)
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    return rb


def _frames(p, cid, b) -> tuple:
    """({link name: its link frame (4, 4) in the world}, the base's inertial frame, the list
    of (link index, name), -1 the base) of PyBullet body ``b``."""
    base = p.getBodyInfo(b, physicsClientId=cid)[0].decode()
    links = [(-1, base)]
    for j in range(p.getNumJoints(b, physicsClientId=cid)):
        links.append((j, p.getJointInfo(b, j, physicsClientId=cid)[12].decode()))
    # the base's link frame: the base pose is its inertial frame; getDynamicsInfo gives the
    # inertial frame's pose in the link frame
    dyn = p.getDynamicsInfo(b, -1, physicsClientId=cid)
    pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
    Tin = _T(pos, orn, p)
    frames = {base: Tin @ np.linalg.inv(_T(dyn[3], dyn[4], p))}
    for j, name in links[1:]:
        st = p.getLinkState(b, j, computeForwardKinematics=True, physicsClientId=cid)
        frames[name] = _T(st[4], st[5], p)
    return frames, Tin, links


def _pybullet_body(p, cid, b, model, rb, fr, T):
    """Read body ``b`` into ``rb``, in the root link's frame ``T`` (None: this body's base
    frame); ``fr``: :func:`_frames` of ``b``."""
    frames, Tin, links = fr
    base = links[0][1]
    if T is None:
        T = frames[base]
    # loadMJCF makes a jointed body two links: one on the joint, without mass, and the body's
    # own, fixed to it (named after the body, or "link..." when the body has no name); a link
    # our reading does not know that hangs by a fixed joint is counted with its parent's
    ours = {lk.name for lk in model.links}
    owner: dict = {base: base}
    parts: dict = {}
    for j, name in links:
        dyn = p.getDynamicsInfo(b, j, physicsClientId=cid)
        if j < 0:
            Tc = Tin
        else:
            st = p.getLinkState(b, j, computeForwardKinematics=True, physicsClientId=cid)
            Tc = _T(st[0], st[1], p)
            info = p.getJointInfo(b, j, physicsClientId=cid)
            up = links[info[16] + 1][1]
            fold = name not in ours and info[2] == p.JOINT_FIXED
            owner[name] = owner[up] if fold else name
        part = to_root(T, dyn[0], Tc[:3, 3], rot_inertia(Tc[:3, :3], dyn[2]))
        parts.setdefault(owner[name], []).append(part)
        rb.bodies[owner[name]] = combine(parts[owner[name]])
        if j < 0:
            continue
        if info[2] != p.JOINT_REVOLUTE:
            continue
        rb.joint_body[info[1].decode()] = name
        Tl = frames[name]
        lo, hi = float(info[8]), float(info[9])
        rb.joints[info[1].decode()] = {
            # PyBullet holds the axis in the child's inertial (centre-of-mass) frame
            "axis": T[:3, :3].T @ (Tc[:3, :3] @ np.asarray(info[13])),
            "point": T[:3, :3].T @ (Tl[:3, 3] - T[:3, 3]),
            "lower": None if lo > hi else lo,
            "upper": None if lo > hi else hi,
            "damping": float(info[6]),
            "friction": float(info[7]),
        }


def _T(pos, orn, p):
    T = np.eye(4)
    T[:3, :3] = np.asarray(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
    T[:3, 3] = pos
    return T


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("multibody",)

#: faithful: PyBullet's velocity clamp raised (the builder's value, rad/s and m/s)
MAX_JOINT_VELOCITY = 1e6
#: faithful: the joint limits moved this far (rad, m); a limit whose lower end exceeds its
#: upper end stays in force in PyBullet (measured: arm3_swing hit one at t = 0.35 s)
FAR = 1e6


class _Sim:
    """The model loaded by ``loadURDF`` (``useFixedBase`` as the scenario says: a floating
    root honestly floating) or ``loadMJCF``, its state set from the scenario's start, stepped by
    ``stepSimulation`` (Bullet's multibody semi-implicit Euler):
    ``references.engines.importers.simulate``'s ``sim``. As loaded, PyBullet's defaults stay:
    inertias from collision shapes (no flag), a velocity motor on every joint, linear and
    angular damping 0.04 on every link, the file's joint damping and limits, the 100 rad/s
    clamp. Faithful: ``URDF_USE_INERTIA_FROM_FILE``, the motors off (zero force), every
    damping 0, the limits moved to :data:`FAR`, the clamp raised."""

    def __init__(self, scenario, config: str, integrator: str, dt: float):
        from references.engines.pybullet.adapter import _import

        p = _import()  # its build-time banner silenced

        from references.engines.importers import start_of
        from references.errors import Unsupported

        self.p = p
        model = scenario.model
        st = start_of(scenario)
        cid = p.connect(p.DIRECT)
        self.cid = cid
        flags = p.URDF_USE_INERTIA_FROM_FILE if config == "faithful" else 0
        tmp, out = None, []
        try:
            path, tmp = _pybullet_file(model, config)
            with quiet_fd() as out:
                ids = _load(p, path, model, st.floating, flags, cid)
        except Exception as exc:
            p.disconnect(cid)
            said = out[0].strip().splitlines()[-1][:200] if out and out[0].strip() else ""
            raise Unsupported(
                f"pybullet: its importer cannot load {scenario.model_spec['file']} ({config}): "
                f"{type(exc).__name__}: {exc}" + (f" ({said})" if said else "")
            ) from None
        finally:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
        rec = {"importer": "loadURDF" + f" (flags {flags}, useFixedBase {not st.floating})"
               if model.format == "urdf" else f"loadMJCF (flags {flags})",
               "configuration": config,
               "integrator": "stepSimulation (multibody)",
               "gravity": st.gravity.tolist()}  # fmt: skip
        p.setGravity(*st.gravity.tolist(), physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=float(dt), numSubSteps=0, physicsClientId=cid)
        self.where: dict = {}  # link name -> (body, link index); joint name -> same
        self.joint_of: dict = {}
        for b in ids:
            self.where[p.getBodyInfo(b, physicsClientId=cid)[0].decode()] = (b, -1)
            for j in range(p.getNumJoints(b, physicsClientId=cid)):
                info = p.getJointInfo(b, j, physicsClientId=cid)
                self.where[info[12].decode()] = (b, j)
                self.joint_of[info[1].decode()] = (b, j, info[2])
        if config == "faithful":
            for b in ids:
                for j in range(-1, p.getNumJoints(b, physicsClientId=cid)):
                    p.changeDynamics(b, j, linearDamping=0.0, angularDamping=0.0,
                                     maxJointVelocity=MAX_JOINT_VELOCITY,
                                     activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
                                     physicsClientId=cid)  # fmt: skip
                    if j >= 0:
                        p.changeDynamics(b, j, jointDamping=0.0, jointLowerLimit=-FAR,
                                         jointUpperLimit=FAR, physicsClientId=cid)  # fmt: skip
                        p.setJointMotorControl2(b, j, p.VELOCITY_CONTROL, targetVelocity=0.0,
                                                force=0.0, physicsClientId=cid)  # fmt: skip
            rec["switched off"] = "joint motors (force 0), linear/angular damping, joint "
            rec["switched off"] += f"damping, limits (moved to +-{FAR:g}); velocity clamp 1e6"
        else:
            rec["as the file has it"] = ("PyBullet's defaults: velocity motors on, damping "
                                         "0.04, the file's joint damping and limits")  # fmt: skip
        if config == "faithful" and model.format == "mjcf":
            rec["file"] = (
                "a copy written from MuJoCo's compiled model: each body's pose and "
                "<inertial>, each joint's type, pos and unit axis, no geometry"
            )
        if st.held:
            rec["held joints"] = f"{st.held}: free in PyBullet's model, at rest at t = 0"
        self._start(st, model, ids)
        self.settings, self.clock = rec, 0.0

    def _start(self, st, model, ids) -> None:
        p, cid = self.p, self.cid
        # the scenario's coordinate is MuJoCo's (the file's pose at ref); PyBullet's is 0 there
        ref = {j.name: float(j.ref) for j in model.joints} if model.format == "mjcf" else {}
        for name, (b, j, kind) in self.joint_of.items():
            if kind not in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                if name in st.given:
                    raise ValueError(f"pybullet: joint {name!r} (type {kind}): start not set here")
                continue
            if name in st.q or name in st.qd:
                p.resetJointState(b, j, float(st.q.get(name, 0.0)) - ref.get(name, 0.0),
                                  float(st.qd.get(name, 0.0)), physicsClientId=cid)  # fmt: skip
        T = st.T
        if model.root not in self.where or self.where[model.root][1] != -1:
            if model.format != "urdf":
                return  # an MJCF root below a base: placed by the file
            # a URDF whose root hangs from a link named 'world' by a fixed joint: PyBullet's
            # base is that link, placed so that the root lands where the scenario puts it
            fixed = [j for j in model.joints if j.child == model.root and j.parent is None]
            if st.floating or not fixed or len(ids) != 1:
                raise ValueError(f"pybullet: the root link {model.root!r} is not a base")
            b, T = ids[0], st.T @ np.linalg.inv(fixed[0].origin)
        else:
            b = self.where[model.root][0]
        dyn = p.getDynamicsInfo(b, -1, physicsClientId=cid)
        Tc = T @ _T(dyn[3], dyn[4], p)  # the base's inertial frame
        p.resetBasePositionAndOrientation(b, Tc[:3, 3].tolist(), _quat(Tc[:3, :3]),
                                          physicsClientId=cid)  # fmt: skip
        if st.floating:
            vc = st.v + np.cross(st.w, Tc[:3, 3] - st.T[:3, 3])
            p.resetBaseVelocity(b, vc.tolist(), st.w.tolist(), physicsClientId=cid)

    def advance(self, n: int) -> None:
        import time

        from references.engines import timing

        p, cid = self.p, self.cid
        t0 = time.perf_counter()
        for _ in range(n):
            p.stepSimulation(physicsClientId=cid)
        self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices

    def links(self, names):
        p, cid = self.p, self.cid
        n = len(names)
        T = np.tile(np.eye(4), (n, 1, 1))
        v, w = np.zeros((n, 3)), np.zeros((n, 3))
        for i, (name, joint) in enumerate(names):
            if name in self.where:
                b, j = self.where[name]
            elif joint in self.joint_of:
                b, j, _ = self.joint_of[joint]
            else:
                raise KeyError(f"pybullet: link {name!r} (joint {joint!r}) is not in the model")
            if j < 0:
                pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
                vc, w[i] = p.getBaseVelocity(b, physicsClientId=cid)
                dyn = p.getDynamicsInfo(b, -1, physicsClientId=cid)
                Tc = _T(pos, orn, p)
                T[i] = Tc @ np.linalg.inv(_T(dyn[3], dyn[4], p))
            else:
                s = p.getLinkState(b, j, computeLinkVelocity=1, computeForwardKinematics=1,
                                   physicsClientId=cid)  # fmt: skip
                T[i] = _T(s[4], s[5], p)
                Tc = _T(s[0], s[1], p)
                vc, w[i] = s[6], s[7]
            # the link origin's velocity from the centre of mass's (PyBullet reports that one)
            v[i] = np.asarray(vc) + np.cross(w[i], T[i, :3, 3] - Tc[:3, 3])
        return T, v, w

    def __del__(self):
        try:
            self.p.disconnect(self.cid)
        except Exception:  # noqa: BLE001 - already disconnected
            pass


def _quat(R) -> list:
    from references import conventions as cv

    return list(map(float, cv.matrix_to_quat_xyzw(R)))


def load(scenario, config: str, integrator: str, dt: float) -> _Sim:
    """The scenario's model file loaded by PyBullet's importer in ``config``, its state set
    (:func:`references.engines.importers.simulate`)."""
    return _Sim(scenario, config, integrator, dt)
