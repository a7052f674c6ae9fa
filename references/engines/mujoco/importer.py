"""Each engine's own importer loads the model file, and its model is read back
(:class:`~references.importers.readback.Readback`) at the zero configuration, in two named
configurations:

- ``as-loaded``: the file passed to the importer as a user would, with the importer's
  defaults (PyBullet's loadURDF without flags, MuJoCo's compiler defaults, ...);
- ``faithful``: the settings that make the importer take the file's mass properties as
  written: PyBullet ``URDF_USE_INERTIA_FROM_FILE``; for URDF files, geometry removed (a copy
  without ``<visual>``/``<collision>``: mesh files are not needed, and no inertia is computed
  from shapes; MuJoCo also gets ``fusestatic="false"``).

Each function returns a Readback whose ``error`` says why the importer refused the file (that
is a finding, not a failure of the comparison). An engine not installed raises ImportError.
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
from pathlib import Path

import numpy as np

from references.importers.geometry import strip_urdf
from references.importers.readback import Readback, to_root

CONFIGS = ("as-loaded", "faithful")
ENGINES = ("mujoco", "mjx", "pinocchio", "pybullet", "drake", "dart")


def _file_for(model, config: str, extra: str | None = None) -> tuple[Path, Path | None]:
    """(file to load, temporary folder to remove afterwards)."""
    if config == "faithful" and model.format == "urdf":
        p = strip_urdf(model.path, extra)
        return p, p.parent
    return Path(model.path).resolve(), None


@contextlib.contextmanager
def _quiet_fd():
    """Capture C-level stdout/stderr (PyBullet and DART print from C++)."""
    saved = [os.dup(1), os.dup(2)]
    import tempfile

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
            out.append(tmp.read().decode("utf-8", "replace"))


def _rot_inertia(R, diag):
    return R @ np.diag(diag) @ R.T


# -- MuJoCo and MJX ------------------------------------------------------------------------------


def mujoco_model(model, config: str):
    import mujoco

    extra = '<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>'
    path, tmp = _file_for(model, config, extra)
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)


def _mujoco_names(m, model):
    import mujoco

    names = []
    for b in range(m.nbody):
        n = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if not n and model.format == "mjcf":
            n = f"body{b}"  # our MJCF reader names unnamed bodies by MuJoCo's body id
        names.append(n)
    return names


def _mujoco_readback(m, model, engine, config, fields=None) -> Readback:
    import mujoco

    rb = Readback(engine, config)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    f = fields or m
    names = _mujoco_names(m, model)
    root = model.root
    T = np.eye(4)
    if root in names:
        ir = names.index(root)
        T[:3, :3] = d.xmat[ir].reshape(3, 3)
        T[:3, 3] = d.xpos[ir]
    elif model.format == "urdf":
        rb.notes.append(f"root link {root!r} fused into the world body (fusestatic)")
    else:
        rb.error = f"no body named after the root link {root!r}"
        return rb
    mass = np.asarray(f.body_mass)
    inertia = np.asarray(f.body_inertia)
    for b in range(1, m.nbody):
        R = d.ximat[b].reshape(3, 3)
        rb.bodies[names[b]] = to_root(T, mass[b], d.xipos[b], _rot_inertia(R, inertia[b]))
    for j in range(m.njnt):
        if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
            continue
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        dof = m.jnt_dofadr[j]
        lim = bool(m.jnt_limited[j])
        rb.joints[name] = {
            "axis": T[:3, :3].T @ d.xaxis[j],
            "point": T[:3, :3].T @ (d.xanchor[j] - T[:3, 3]),
            "lower": float(m.jnt_range[j, 0]) if lim else None,
            "upper": float(m.jnt_range[j, 1]) if lim else None,
            "damping": float(np.asarray(f.dof_damping)[dof]),
            "friction": float(np.asarray(f.dof_frictionloss)[dof]),
            "armature": float(np.asarray(f.dof_armature)[dof]),
        }
    return rb


def mujoco(model, config: str) -> Readback:
    try:
        m = mujoco_model(model, config)
    except Exception as exc:  # the importer's refusal is the finding
        return Readback("mujoco", config, error=f"{type(exc).__name__}: {exc}".strip())
    return _mujoco_readback(m, model, "mujoco", config)


def mjx(model, config: str) -> Readback:
    """MuJoCo's model put on the device by ``mjx.put_model``, read from the MJX model's own
    arrays (float64)."""
    try:
        m = mujoco_model(model, config)
    except Exception as exc:
        return Readback("mjx", config, error=f"{type(exc).__name__}: {exc}".strip())
    import jax

    jax.config.update("jax_enable_x64", True)
    from mujoco import mjx as _mjx

    if config == "faithful":
        import mujoco as _mj

        # a contact-free test: MJX lacks some geom-pair collisions and refuses the model
        m.geom_contype[:] = 0
        m.geom_conaffinity[:] = 0
        m.opt.disableflags |= int(_mj.mjtDisableBit.mjDSBL_CONTACT)
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            mx = _mjx.put_model(m)
    except Exception as exc:
        return Readback("mjx", config, error=f"put_model: {type(exc).__name__}: {exc}".strip())
    return _mujoco_readback(m, model, "mjx", config, fields=mx)


# -- Pinocchio -----------------------------------------------------------------------------------


def pinocchio(model, config: str) -> Readback:
    import pinocchio as pin

    rb = Readback("pinocchio", config)
    path, tmp = _file_for(model, config)
    try:
        if model.format == "urdf":
            pm = pin.buildModelFromUrdf(str(path))
        else:
            pm = pin.buildModelFromMJCF(str(path))
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {exc}".strip()
        return rb
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    data = pm.createData()
    q = pin.neutral(pm)
    pin.forwardKinematics(pm, data, q)
    pin.updateFramePlacements(pm, data)
    # the root link's frame
    fid = pm.getFrameId(model.root) if pm.existFrame(model.root) else None
    if fid is None:
        rb.error = f"no frame named after the root link {model.root!r}"
        return rb
    T = data.oMf[fid].homogeneous
    # each joint's body is named after the link of its BODY frame right after the joint
    body_of = {}
    for f in pm.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint not in body_of:
            body_of[f.parentJoint] = f.name
    for i in range(1, pm.njoints):
        name = body_of.get(i, pm.names[i])
        I = pm.inertias[i]
        oM = data.oMi[i]
        R = oM.rotation
        com = oM.act(I.lever)
        rb.bodies[name] = to_root(T, I.mass, com, R @ I.inertia @ R.T)
        jm = pm.joints[i]
        sname = jm.shortname()
        if not sname.startswith("JointModelR"):
            continue
        ax = np.asarray(data.joints[i].S).reshape(6, -1)[3:6, 0]
        idx = jm.idx_q
        unbounded = "Unbounded" in sname or sname.startswith("JointModelRUB")
        rb.joints[pm.names[i]] = {
            "axis": T[:3, :3].T @ (R @ ax),
            "point": T[:3, :3].T @ (oM.translation - T[:3, 3]),
            "lower": None if unbounded else _lim(pm.lowerPositionLimit[idx]),
            "upper": None if unbounded else _lim(pm.upperPositionLimit[idx]),
            "damping": float(pm.damping[jm.idx_v]),
            "friction": float(pm.friction[jm.idx_v]),
            "armature": float(pm.armature[jm.idx_v]),
        }
    return rb


def _lim(v):
    v = float(v)
    return None if not np.isfinite(v) or abs(v) >= 1e300 else v


# -- PyBullet ------------------------------------------------------------------------------------


def pybullet(model, config: str) -> Readback:
    import pybullet as p

    rb = Readback("pybullet", config)
    path, tmp = _file_for(model, config)
    cid = p.connect(p.DIRECT)
    try:
        flags = p.URDF_USE_INERTIA_FROM_FILE if config == "faithful" else 0
        rb.notes.append(f"flags {flags}")
        with _quiet_fd() as out:
            if model.format == "urdf":
                ids = [p.loadURDF(str(path), useFixedBase=True, flags=flags,
                                  physicsClientId=cid)]  # fmt: skip
            else:
                ids = list(p.loadMJCF(str(path), physicsClientId=cid))
        if out and out[0].strip():
            rb.notes.append(out[0].strip().splitlines()[-1][:200])
        for b in ids:
            _pybullet_body(p, cid, b, model, rb)
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {exc}".strip()
    finally:
        p.disconnect(cid)
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    return rb


def _pybullet_body(p, cid, b, model, rb):
    base = p.getBodyInfo(b, physicsClientId=cid)[0].decode()
    links = [(-1, base)]
    for j in range(p.getNumJoints(b, physicsClientId=cid)):
        links.append((j, p.getJointInfo(b, j, physicsClientId=cid)[12].decode()))
    # the base's link frame: the base pose is its inertial frame; getDynamicsInfo gives the
    # inertial frame's pose in the link frame
    dyn = p.getDynamicsInfo(b, -1, physicsClientId=cid)
    pos, orn = p.getBasePositionAndOrientation(b, physicsClientId=cid)
    Tin = _T(pos, orn, p)
    Tloc = _T(dyn[3], dyn[4], p)
    Tb = Tin @ np.linalg.inv(Tloc)
    frames = {base: Tb}
    for j, name in links[1:]:
        st = p.getLinkState(b, j, computeForwardKinematics=True, physicsClientId=cid)
        frames[name] = _T(st[4], st[5], p)
    T = frames.get(model.root, Tb)
    for j, name in links:
        dyn = p.getDynamicsInfo(b, j, physicsClientId=cid)
        if j < 0:
            Tc = Tin
        else:
            st = p.getLinkState(b, j, computeForwardKinematics=True, physicsClientId=cid)
            Tc = _T(st[0], st[1], p)
        rb.bodies[name] = to_root(T, dyn[0], Tc[:3, 3], _rot_inertia(Tc[:3, :3], dyn[2]))
        if j < 0:
            continue
        info = p.getJointInfo(b, j, physicsClientId=cid)
        if info[2] != p.JOINT_REVOLUTE:
            continue
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


# -- Drake ---------------------------------------------------------------------------------------


def drake(model, config: str) -> Readback:
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint

    rb = Readback("drake", config)
    path, tmp = _file_for(model, config)
    try:
        plant = MultibodyPlant(time_step=0.0)
        parser = Parser(plant)
        for k, v in _packages(model).items():
            parser.package_map().Add(k, str(v))
        parser.AddModels(str(path))
        plant.Finalize()
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {str(exc).splitlines()[0][:300]}"
        return rb
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    ctx = plant.CreateDefaultContext()
    try:
        T = plant.GetBodyByName(model.root).EvalPoseInWorld(ctx).GetAsMatrix4()
    except Exception:
        rb.error = f"no body named after the root link {model.root!r}"
        return rb
    for i in range(1, plant.num_bodies()):
        body = plant.get_body(_bi(i))
        X = body.EvalPoseInWorld(ctx)
        M = body.CalcSpatialInertiaInBodyFrame(ctx)
        m = M.get_mass()
        com_b = M.get_com()
        Ic = M.Shift(com_b).CalcRotationalInertia().CopyToFullMatrix3() if m > 0 else np.zeros(
            (3, 3))  # fmt: skip
        R = X.rotation().matrix()
        rb.bodies[body.name()] = to_root(T, m, X.multiply(com_b), R @ Ic @ R.T)
    for i in range(plant.num_joints()):
        jt = plant.get_joint(_ji(i))
        if not isinstance(jt, RevoluteJoint):
            continue
        XF = jt.frame_on_parent().CalcPoseInWorld(ctx)
        rb.joints[jt.name()] = {
            "axis": T[:3, :3].T @ (XF.rotation().matrix() @ jt.revolute_axis()),
            "point": T[:3, :3].T @ (XF.translation() - T[:3, 3]),
            "lower": _lim(jt.position_lower_limits()[0]),
            "upper": _lim(jt.position_upper_limits()[0]),
            "damping": float(jt.default_damping()),
        }
    return rb


def _bi(i):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(i)


def _ji(i):
    from pydrake.multibody.tree import JointIndex

    return JointIndex(i)


def _packages(model) -> dict:
    """Package folders for ``package://`` names, guessed as our URDF reader does."""
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


# -- DART ----------------------------------------------------------------------------------------


def dart(model, config: str) -> Readback:
    import dartpy as dp

    rb = Readback("dart", config)
    path, tmp = _file_for(model, config)
    try:
        with _quiet_fd() as out:
            if model.format == "urdf":
                loader = dp.utils.DartLoader()
                for k, v in _packages(model).items():
                    loader.addPackageDirectory(k, str(v))
                opts = dp.utils.DartLoaderOptions()
                opts.mDefaultRootJointType = dp.utils.DartLoaderRootJointType.FIXED
                loader.setOptions(opts)
                skels = [loader.parseSkeleton(str(path))]
            else:
                world = dp.utils.MjcfParser.readWorld(str(path))
                skels = [world.getSkeleton(i) for i in range(world.getNumSkeletons())]
        if out and out[0].strip():
            rb.notes.append(out[0].strip().splitlines()[-1][:200])
        skels = [s for s in skels if s is not None]
        if not skels:
            rb.error = "the loader returned no skeleton" + (
                f" ({out[0].strip().splitlines()[-1][:200]})" if out and out[0].strip() else ""
            )
            return rb
    except Exception as exc:
        rb.error = f"{type(exc).__name__}: {exc}".strip()
        return rb
    finally:
        if tmp:
            shutil.rmtree(tmp, ignore_errors=True)
    nodes = {}
    for s in skels:
        for k in range(s.getNumBodyNodes()):
            bn = s.getBodyNode(k)
            nodes[bn.getName()] = bn
    if model.root not in nodes:
        rb.error = f"no body node named after the root link {model.root!r}"
        return rb
    T = nodes[model.root].getWorldTransform().matrix()
    for name, bn in nodes.items():
        X = bn.getWorldTransform().matrix()
        R = X[:3, :3]
        I = np.asarray(bn.getInertia().getMoment())
        rb.bodies[name] = to_root(T, bn.getMass(), np.asarray(bn.getCOM()), R @ I @ R.T)
        jt = bn.getParentJoint()
        if jt is None or jt.getType() != "RevoluteJoint":
            continue
        Xj = X @ jt.getTransformFromChildBodyNode().matrix()
        ax = np.asarray(jt.getAxis())
        rb.joints[jt.getName()] = {
            "axis": T[:3, :3].T @ (Xj[:3, :3] @ ax),
            "point": T[:3, :3].T @ (Xj[:3, 3] - T[:3, 3]),
            "lower": _lim(jt.getPositionLowerLimit(0)),
            "upper": _lim(jt.getPositionUpperLimit(0)),
            "damping": float(jt.getDampingCoefficient(0)),
            "friction": float(jt.getCoulombFriction(0)),
        }
        if not jt.areLimitsEnforced() and "limits not enforced" not in rb.notes:
            rb.notes.append("limits not enforced")
    return rb


READERS = {"mujoco": mujoco, "mjx": mjx, "pinocchio": pinocchio, "pybullet": pybullet,
           "drake": drake, "dart": dart}  # fmt: skip
