"""DART's own importers (``DartLoader`` for URDF, ``MjcfParser`` for MJCF) on a model file,
read back (:mod:`references.engines.importers`): each body node's mass, centre of mass and
inertia, revolute joints' axes, limits, damping and Coulomb friction, at the zero
configuration. URDF roots are loaded fixed (``DartLoaderRootJointType.FIXED``)."""

from __future__ import annotations

import shutil

import numpy as np

from references.engines.importers import (
    Readback,
    file_for,
    limit,
    packages,
    quiet_fd,
    to_root,
)


def readback(model, config: str) -> Readback:
    import dartpy as dp

    rb = Readback("dart", config)
    path, tmp = file_for(model, config)
    try:
        with quiet_fd() as out:
            if model.format == "urdf":
                loader = dp.utils.DartLoader()
                for k, v in packages(model).items():
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
            "lower": limit(jt.getPositionLowerLimit(0)),
            "upper": limit(jt.getPositionUpperLimit(0)),
            "damping": float(jt.getDampingCoefficient(0)),
            "friction": float(jt.getCoulombFriction(0)),
        }
        if not jt.areLimitsEnforced() and "limits not enforced" not in rb.notes:
            rb.notes.append("limits not enforced")
    return rb
