"""DART's own importers (``DartLoader`` for URDF, ``MjcfParser`` for MJCF) on a model file,
read back (:mod:`references.engines.importers`): each body node's mass, centre of mass and
inertia, revolute joints' axes, limits, damping and Coulomb friction, at the zero
configuration. A URDF root is loaded FIXED, or FLOATING for a floating model."""

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


def readback(model, config: str, floating: bool = False) -> Readback:
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
                kind = "FLOATING" if floating else "FIXED"
                opts.mDefaultRootJointType = getattr(dp.utils.DartLoaderRootJointType, kind)
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
    refs = {j.name: float(j.ref) for j in model.joints}
    for s in skels:
        for k in range(s.getNumBodyNodes()):
            bn = s.getBodyNode(k)
            nodes[bn.getName()] = bn
        # the zero configuration (MJCF: each joint at its ref): DART's loader starts a joint
        # whose limits exclude 0 inside them (go2's calves, panda's joint 4), not at 0
        for k in range(s.getNumJoints()):
            jt = s.getJoint(k)
            if jt.getNumDofs() == 1:
                jt.setPosition(0, refs.get(jt.getName(), 0.0))
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
        path, tmp = file_for(model, config)
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
        skels = [world.getSkeleton(i) for i in range(world.getNumSkeletons())]
        skels = [s for s in skels if s is not None]
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
        if config == "faithful":
            for jt in self.joints.values():
                for i in range(jt.getNumDofs()):
                    jt.setDampingCoefficient(i, 0.0)
                    jt.setCoulombFriction(i, 0.0)
                    jt.setSpringStiffness(i, 0.0)
                jt.setLimitEnforcement(False)
            rec["switched off"] = "damping, Coulomb friction, springs, limit enforcement"
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
                jt.setPosition(0, float(st.q[name]))
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

        t0 = time.perf_counter()
        for _ in range(n):
            self.world.step()
        self.clock += time.perf_counter() - t0

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
