"""DART's own importers (``DartLoader`` for URDF, ``MjcfParser`` for MJCF) on a model file,
read back (:mod:`references.engines.importers`): each body node's mass, centre of mass and
inertia, revolute joints' axes, limits, damping and Coulomb friction, at the zero
configuration. A URDF root is loaded FIXED, or FLOATING for a floating model. The immobile
skeletons ``MjcfParser`` makes of the world's own geoms (a floor) are not part of the model.
``MjcfParser`` reads ``<joint>`` elements only (Body.cpp, ``Body::read``): a ``<freejoint>``
is skipped and its body welded to the world; the faithful configuration loads a copy with
``<joint type="free">`` in its place. ``MjcfParser`` ignores a joint's ``ref``: DART's
coordinate 0 is the pose the file gives (where MuJoCo's coordinate is ``ref``), so a
scenario's joint value q is DART's q - ref.

DART's ``MjcfParser`` (dart/utils/mjcf/MjcfParser.cpp, ``createBodyProperties``; Body.cpp,
``computeInertialFromGeoms``) gives a body node the mass and centre of mass of the body's
first geom only, or of its ``<inertial>`` when the body also has a geom, and never its
rotational inertia, which stays at DART's default (1 kg m^2 about each axis); a body
without geoms keeps DART's default 1 kg. No option changes that: the faithful configuration
sets each body node's spatial inertia after loading from MuJoCo's compiled model of the same
file (:func:`mujoco_inertias`), MJCF's own reading of it."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from references.engines.importers import (
    Readback,
    file_for,
    limit,
    mjcf_copy,
    packages,
    quiet_fd,
    to_root,
)

_INERTIA = (
    "DART's MjcfParser takes a body's mass and centre of mass from its first geom and never "
    "its rotational inertia (1 kg m^2 per axis); a body without geoms gets 1 kg: the "
    "faithful configuration sets each body's inertia from MuJoCo's compiled model"
)
#: the known cause of a difference, by configuration, quantity and format, printed beside it
HINTS = {
    **{("as-loaded", q, "mjcf"): _INERTIA for q in ("mass", "com", "inertia")},
    **{(c, q, "mjcf"): "DART's MjcfParser takes the range as written (degrees under compiler "
       "angle='degree' read as radians; an unlimited joint: [0, 0], not enforced)"
       for c in ("as-loaded", "faithful") for q in ("lower", "upper")},
    **{(c, "friction", "mjcf"): "DART's MjcfParser ignores frictionloss"
       for c in ("as-loaded", "faithful")},
    ("as-loaded", "root joint", "mjcf"): "DART's MjcfParser reads <joint> elements only: "
    "a <freejoint> is skipped and its body welded to the world; the faithful configuration "
    "loads a copy with <joint type='free'> instead",
}  # fmt: skip


def _free_joints(root) -> None:
    """Every ``<freejoint>`` of an MJCF tree written as the ``<joint type="free">`` it
    stands for (DART's parser reads the latter only)."""
    for el in root.iter("freejoint"):
        el.tag = "joint"
        el.set("type", "free")
        el.attrib.pop("align", None)  # a freejoint's own attribute


def dart_file(model, config: str):
    """(the file DART's parser loads in ``config``, a temporary folder or None): the
    importers' :func:`~references.engines.importers.file_for`, and for a faithful MJCF file
    a copy whose ``<freejoint>`` elements are ``<joint type="free">`` (:data:`HINTS`)."""
    if config == "faithful" and model.format == "mjcf":
        return mjcf_copy(model.path, _free_joints)
    return file_for(model, config)


def mobile(skels) -> list:
    """The skeletons of a loaded world that move (``MjcfParser`` adds an immobile one per
    geom of the world body, a floor: not part of the model)."""
    return [s for s in skels if s is not None and s.isMobile()]


def mujoco_inertias(skels, model) -> None:
    """Set every body node of ``skels`` (``MjcfParser``'s, in its depth-first order, which is
    MuJoCo's body order) to the mass, centre of mass and inertia of MuJoCo's compiled model
    of ``model``'s file, both at the file's pose (MuJoCo's qpos0, DART's zero), matched
    in the world frame so that where each importer puts a body's frame does not matter.
    Raises ValueError when the two trees do not pair body for body."""
    import dartpy as dp
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(Path(model.path).resolve()))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)  # qpos0: the file's pose, each hinge at its ref
    nodes = [s.getBodyNode(k) for s in skels for k in range(s.getNumBodyNodes())]
    if len(nodes) != m.nbody - 1:
        raise ValueError(f"DART's tree has {len(nodes)} bodies, MuJoCo's {m.nbody - 1}")
    for s in skels:
        for k in range(s.getNumJoints()):
            jt = s.getJoint(k)
            if jt.getNumDofs() == 1:
                jt.setPosition(0, 0.0)  # the file's pose (MjcfParser ignores ref)
    for b, bn in enumerate(nodes, start=1):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
        if name and name != bn.getName():
            raise ValueError(f"body {b}: MuJoCo's {name!r}, DART's {bn.getName()!r}")
        X = bn.getWorldTransform().matrix()
        R, p = X[:3, :3], X[:3, 3]
        Ri = d.ximat[b].reshape(3, 3)
        I_world = Ri @ np.diag(m.body_inertia[b]) @ Ri.T
        bn.setInertia(dp.dynamics.Inertia(float(m.body_mass[b]), R.T @ (d.xipos[b] - p),
                                          R.T @ I_world @ R))  # fmt: skip


def readback(model, config: str, floating: bool = False) -> Readback:
    import dartpy as dp

    rb = Readback("dart", config)
    path, tmp = dart_file(model, config)
    try:
        with quiet_fd() as out:
            if model.format == "urdf":
                loader = dp.utils.DartLoader()
                for k, v in packages(model).items():
                    loader.addPackageDirectory(k, str(v))
                opts = dp.utils.DartLoaderOptions()
                kind = "FLOATING" if floating else "FIXED"
                opts.mDefaultRootJointType = getattr(dp.utils.DartLoaderRootJointType, kind)
                loader.setOptions(opts)
                skels = [loader.parseSkeleton(str(path))]
            else:
                world = dp.utils.MjcfParser.readWorld(str(path))
                skels = [world.getSkeleton(i) for i in range(world.getNumSkeletons())]
        if out and out[0].strip():
            rb.notes.append(out[0].strip().splitlines()[-1][:200])
        skels = mobile(skels)
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
    if config == "faithful" and model.format == "mjcf":
        try:
            mujoco_inertias(skels, model)
        except Exception as exc:
            rb.error = f"faithful inertias from MuJoCo's model: {type(exc).__name__}: {exc}"
            return rb
        rb.notes.append("inertias set from MuJoCo's compiled model")
    for s in skels:
        for k in range(s.getNumBodyNodes()):
            bn = s.getBodyNode(k)
            nodes[bn.getName()] = bn
        # the zero configuration, the pose the file gives (MJCF: each joint at its ref, which
        # is DART's 0: MjcfParser ignores ref); DART's loader starts a joint
        # whose limits exclude 0 inside them (go2's calves, panda's joint 4), not at 0
        for k in range(s.getNumJoints()):
            jt = s.getJoint(k)
            if jt.getNumDofs() == 1:
                jt.setPosition(0, 0.0)
    if model.root not in nodes:
        rb.error = f"no body node named after the root link {model.root!r}"
        return rb
    T = nodes[model.root].getWorldTransform().matrix()
    if model.format == "mjcf":
        kind = nodes[model.root].getParentJoint().getType()
        rb.root_joint = "free" if kind == "FreeJoint" else "attached"
    for name, bn in nodes.items():
        X = bn.getWorldTransform().matrix()
        R = X[:3, :3]
        I = np.asarray(bn.getInertia().getMoment())
        rb.bodies[name] = to_root(T, bn.getMass(), np.asarray(bn.getCOM()), R @ I @ R.T)
        jt = bn.getParentJoint()
        if jt is None or jt.getType() != "RevoluteJoint":
            continue
        rb.joint_body[jt.getName()] = name
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


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("semi-implicit Euler",)


class _Sim:
    """The skeleton of ``DartLoader`` (the root joint FLOATING when the scenario's root floats,
    as a DART user asks for it, else FIXED and placed where the scenario puts it) or the world
    of ``MjcfParser.readWorld``, its state set from the scenario's start, stepped by
    ``World.step`` (DART's semi-implicit Euler): ``references.engines.importers.simulate``'s
    ``sim``. As loaded, the loader's joint damping, friction, springs and limits stay;
    faithful, they are switched off per degree of freedom."""

    def __init__(self, scenario, config: str, integrator: str, dt: float):
        import dartpy as dp

        from references.engines.importers import start_of
        from references.errors import Unsupported

        model = scenario.model
        st = start_of(scenario)
        path, tmp = dart_file(model, config)
        said = ""
        try:
            with quiet_fd() as out:
                if model.format == "urdf":
                    loader = dp.utils.DartLoader()
                    for k, v in packages(model).items():
                        loader.addPackageDirectory(k, str(v))
                    opts = dp.utils.DartLoaderOptions()
                    kind = "FLOATING" if st.floating else "FIXED"
                    opts.mDefaultRootJointType = getattr(dp.utils.DartLoaderRootJointType, kind)
                    loader.setOptions(opts)
                    skel = loader.parseSkeleton(str(path))
                    world = dp.simulation.World()
                    if skel is not None:
                        world.addSkeleton(skel)
                else:
                    world = dp.utils.MjcfParser.readWorld(str(path))
            said = out[0].strip().splitlines()[-1][:200] if out and out[0].strip() else ""
        except Exception as exc:
            raise Unsupported(
                f"dart: its importer cannot load {scenario.model_spec['file']} ({config}): "
                f"{type(exc).__name__}: {exc}"
            ) from None
        finally:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
        skels = mobile([world.getSkeleton(i) for i in range(world.getNumSkeletons())])
        if not skels:
            raise Unsupported(
                f"dart: its importer returned no skeleton for {scenario.model_spec['file']} "
                f"({config})" + (f": {said}" if said else "")
            )
        world.setGravity(np.asarray(st.gravity, float))
        world.setTimeStep(float(dt))
        rec = {"importer": ("DartLoader (root " + ("FLOATING" if st.floating else "FIXED") + ")")
               if model.format == "urdf" else "MjcfParser.readWorld", "configuration": config,
               "integrator": "World.step (semi-implicit Euler)",
               "gravity": st.gravity.tolist()}  # fmt: skip
        if said:
            rec["importer said"] = said
        self.nodes, self.joints = {}, {}
        for s in skels:
            for k in range(s.getNumBodyNodes()):
                bn = s.getBodyNode(k)
                self.nodes[bn.getName()] = bn
            for k in range(s.getNumJoints()):
                jt = s.getJoint(k)
                self.joints[jt.getName()] = jt
        if config == "faithful" and model.format == "mjcf":
            try:
                mujoco_inertias(skels, model)
            except ImportError:
                raise Unsupported("dart: the faithful configuration of an MJCF file takes "
                                  "its inertias from MuJoCo's compiled model, and MuJoCo "
                                  "is not installed") from None  # fmt: skip
            except ValueError as exc:
                raise Unsupported(f"dart: faithful inertias from MuJoCo's model: {exc}") from None
            rec["inertias"] = ("every body's mass, centre of mass and inertia from "
                               "MuJoCo's compiled model (MjcfParser keeps no rotational "
                               "inertia)")  # fmt: skip
            rec["free joints"] = "a copy of the file with <joint type='free'> for <freejoint>"
        if config == "faithful":
            for jt in self.joints.values():
                for i in range(jt.getNumDofs()):
                    jt.setDampingCoefficient(i, 0.0)
                    jt.setCoulombFriction(i, 0.0)
                    jt.setSpringStiffness(i, 0.0)
                jt.setLimitEnforcement(False)
            # contact-free, as the scenario is: no shape in the constraint solver's
            # collision group (the parser's shapes collide with each other and a floor)
            world.getConstraintSolver().getCollisionGroup().removeAllShapeFrames()
            rec["switched off"] = (
                "damping, Coulomb friction, springs, limit enforcement, "
                "collision (no shape in the solver's collision group)"
            )
        else:
            damp = sorted({float(jt.getDampingCoefficient(i)) for jt in self.joints.values()
                           for i in range(jt.getNumDofs())})  # fmt: skip
            lim = sum(bool(jt.areLimitsEnforced()) for jt in self.joints.values())
            rec["as the file has it"] = f"damping {damp}, limits enforced on {lim} joints"
        if st.held:
            rec["held joints"] = f"{st.held}: free in DART's skeleton, at rest at t = 0"
        self._start(st, model)
        self.world, self.settings, self.clock = world, rec, 0.0

    def _start(self, st, model) -> None:
        import dartpy as dp

        from references.errors import Unsupported

        # the scenario's coordinate is MuJoCo's (the file's pose at ref); DART's is 0 there
        ref = {j.name: float(j.ref) for j in model.joints} if model.format == "mjcf" else {}
        for name in set(st.q) | set(st.qd):
            jt = self.joints.get(name)
            if jt is None:
                continue
            if jt.getNumDofs() != 1:
                if name in st.given:
                    raise Unsupported(f"dart: joint {name!r} is a {jt.getType()} in "
                                      "DART's model: the scenario's start for it is not "
                                      "set here")  # fmt: skip
                continue
            if name in st.q:
                jt.setPosition(0, float(st.q[name]) - ref.get(name, 0.0))
            if name in st.qd:
                jt.setVelocity(0, float(st.qd[name]))
        root = self.nodes.get(model.root)
        if root is None:
            raise KeyError(f"dart: the root link {model.root!r} is not a body node")
        jt = root.getParentJoint()
        X = dp.math.Isometry3()
        X.set_matrix(st.T)
        if jt.getType() == "FreeJoint":
            jt.setTransform(X)
            jt.setLinearVelocity(st.v)
            jt.setAngularVelocity(st.w)
        elif model.format == "urdf" and jt.getType() == "WeldJoint":
            jt.setTransformFromParentBodyNode(X)

    def advance(self, n: int) -> None:
        import time

        from references.engines import timing

        t0 = time.perf_counter()
        for _ in range(n):
            self.world.step()
        self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices

    def links(self, names):
        n = len(names)
        T = np.tile(np.eye(4), (n, 1, 1))
        v, w = np.zeros((n, 3)), np.zeros((n, 3))
        for i, (name, joint) in enumerate(names):
            bn = self.nodes.get(name)
            if bn is None and joint in self.joints:
                bn = self.joints[joint].getChildBodyNode()
            if bn is None:
                raise KeyError(f"dart: link {name!r} (joint {joint!r}) is not a body node")
            T[i] = bn.getWorldTransform().matrix()
            v[i] = np.asarray(bn.getLinearVelocity())
            w[i] = np.asarray(bn.getAngularVelocity())
        return T, v, w


def load(scenario, config: str, integrator: str, dt: float) -> _Sim:
    """The scenario's model file loaded by DART's importer in ``config``, its state set
    (:func:`references.engines.importers.simulate`)."""
    return _Sim(scenario, config, integrator, dt)
