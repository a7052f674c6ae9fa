"""Pinocchio's own importer (``buildModelFromUrdf``, ``buildModelFromMJCF``) on a model file,
read back (:mod:`references.engines.importers`): each joint's body (named after the link of
the first BODY frame on it) with its inertia placed by ``oMi``, revolute joints' motion
subspace axes, position limits, damping, friction and armature, at ``pinocchio.neutral``."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, limit, to_root


def readback(model, config: str) -> Readback:
    import pinocchio as pin

    rb = Readback("pinocchio", config)
    path, tmp = file_for(model, config)
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
            "lower": None if unbounded else limit(pm.lowerPositionLimit[idx]),
            "upper": None if unbounded else limit(pm.upperPositionLimit[idx]),
            "damping": float(pm.damping[jm.idx_v]),
            "friction": float(pm.friction[jm.idx_v]),
            "armature": float(pm.armature[jm.idx_v]),
        }
    return rb
