"""Drake's own importer (``Parser.AddModels``, URDF and MJCF, ``package://`` names resolved
through its package map) on a model file, read back (:mod:`references.engines.importers`):
each body's spatial inertia and world pose in the default context, revolute joints' axes,
limits and default damping."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import Readback, file_for, limit, packages, to_root


def readback(model, config: str) -> Readback:
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import RevoluteJoint

    rb = Readback("drake", config)
    path, tmp = file_for(model, config)
    try:
        plant = MultibodyPlant(time_step=0.0)
        parser = Parser(plant)
        for k, v in packages(model).items():
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
            "lower": limit(jt.position_lower_limits()[0]),
            "upper": limit(jt.position_upper_limits()[0]),
            "damping": float(jt.default_damping()),
        }
    return rb


def _bi(i):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(i)


def _ji(i):
    from pydrake.multibody.tree import JointIndex

    return JointIndex(i)
