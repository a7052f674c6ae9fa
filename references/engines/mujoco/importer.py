"""MuJoCo's own importer (``MjModel.from_xml_path``, URDF and MJCF) on a model file, read back
(:mod:`references.engines.importers`): body masses, centres of mass and inertias
(``body_mass``, ``xipos``, ``ximat``, ``body_inertia``), hinge axes and anchors (``xaxis``,
``xanchor``), limits, damping, friction loss and armature, at the zero configuration
(``qpos0``: MJCF joints at their ``ref``). The faithful URDF adds
``<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>``."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, rot_inertia, to_root


def mujoco_model(model, config: str):
    import mujoco

    extra = '<mujoco><compiler fusestatic="false" discardvisual="true"/></mujoco>'
    path, tmp = file_for(model, config, extra)
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


def mujoco_readback(m, model, engine, config, fields=None) -> Readback:
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
        rb.bodies[names[b]] = to_root(T, mass[b], d.xipos[b], rot_inertia(R, inertia[b]))
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


def readback(model, config: str) -> Readback:
    try:
        m = mujoco_model(model, config)
    except Exception as exc:  # the importer's refusal is the finding
        return Readback("mujoco", config, error=f"{type(exc).__name__}: {exc}".strip())
    return mujoco_readback(m, model, "mujoco", config)
