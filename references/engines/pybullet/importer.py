"""PyBullet's own importer (``loadURDF``, ``loadMJCF``) on a model file, read back
(:mod:`references.engines.importers`) through ``getDynamicsInfo``, ``getLinkState`` and
``getJointInfo``. As loaded, ``loadURDF`` takes no flags; faithful, it takes
``URDF_USE_INERTIA_FROM_FILE`` (without it PyBullet recomputes each link's inertia from its
collision shapes: :data:`HINTS`)."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, quiet_fd, rot_inertia, to_root

#: the known cause of a difference, by configuration and quantity, printed beside it
HINTS = {
    ("as-loaded", "inertia"): "loadURDF without URDF_USE_INERTIA_FROM_FILE "
    "recomputes the inertia from the collision shapes: pass that flag",
    ("as-loaded", "com"): "loadURDF without URDF_USE_INERTIA_FROM_FILE",
}


def readback(model, config: str) -> Readback:
    import pybullet as p

    rb = Readback("pybullet", config)
    path, tmp = file_for(model, config)
    cid = p.connect(p.DIRECT)
    try:
        flags = p.URDF_USE_INERTIA_FROM_FILE if config == "faithful" else 0
        rb.notes.append(f"flags {flags}")
        with quiet_fd() as out:
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
        rb.bodies[name] = to_root(T, dyn[0], Tc[:3, 3], rot_inertia(Tc[:3, :3], dyn[2]))
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
