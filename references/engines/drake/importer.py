"""Drake's own importer (``Parser.AddModels``, URDF and MJCF, ``package://`` names resolved
through its package map) on a model file, read back (:mod:`references.engines.importers`):
each body's spatial inertia and world pose in the default context, revolute joints' axes,
limits, default damping and armature (the reflected rotor inertia of the actuators on the
joint: Drake holds armature nowhere else).

Drake's MJCF parser (multibody/parsing/detail_mujoco_parser.cc, where it reads a joint's
``armature``) keeps a joint's armature only as the rotor inertia of an actuator that drives
that joint; a joint without an actuator loses it (MuJoCo adds it to the mass matrix's
diagonal for every joint). On crawler.xml four of five hinges lose 0.01 kg m^2; its
knee_left is left with 2.8e-5 kg m^2 against its damping of 0.3 N m s: the damping's rate
1.1e4 1/s times a fixed step of 1e-3 s is 10.8, far outside an explicit Runge-Kutta
method's stability interval, and the as-loaded run diverges in its first steps (the
faithful configuration switches damping off)."""

from __future__ import annotations

import logging
import shutil

import numpy as np

from references.engines.importers import Readback, file_for, limit, packages, to_root

_ARMATURE = (
    "Drake's MJCF parser keeps a joint's armature only as the rotor inertia of an actuator "
    "on that joint: a joint without one loses it (an explicit fixed step then meets the "
    "joint's damping over a much smaller inertia)"
)
#: the known cause of a difference, by configuration, quantity and format, printed beside it
HINTS = {(c, "armature", "mjcf"): _ARMATURE for c in ("as-loaded", "faithful")}


def armatures(plant) -> dict:
    """{joint index: the reflected rotor inertia of the actuators on it (gear ratio squared
    times rotor inertia; 0 for a joint without an actuator)}."""
    out: dict = {}
    for i in range(plant.num_actuators()):
        a = plant.get_joint_actuator(_ai(i))
        k = int(a.joint().index())
        out[k] = out.get(k, 0.0) + float(a.default_reflected_inertia())
    return out


def readback(model, config: str, floating: bool = False) -> Readback:
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
        with _Said() as said:
            parser.AddModels(str(path))
        rb.notes += sorted({ln.split(": warning: ")[-1] for ln in said.lines})
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
    arm = armatures(plant)
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
            "armature": arm.get(int(jt.index()), 0.0),
        }
    return rb


def _bi(i):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(i)


def _ji(i):
    from pydrake.multibody.tree import JointIndex

    return JointIndex(i)


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("runge_kutta5",)


class _Sim:
    """A continuous ``MultibodyPlant`` filled by Drake's ``Parser`` (a URDF root that the
    scenario fixes welded where the scenario puts it, as a Drake user welds it; a floating one
    left free, Drake's default), its state set from the scenario's start, stepped by a
    ``Simulator`` with the fixed-step integrator (``ResetIntegratorFromFlags``):
    ``references.engines.importers.simulate``'s ``sim``. No SceneGraph: no contact. A
    continuous plant applies joint damping and reflected rotor inertia, not position limits
    (Drake enforces those in discrete plants only): the settings say so."""

    def __init__(self, scenario, config: str, integrator: str, dt: float):
        from pydrake.math import RigidTransform
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import MultibodyPlant
        from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator

        from references.engines.importers import start_of
        from references.errors import EngineError, Unsupported

        model = scenario.model
        st = start_of(scenario)
        path, tmp = file_for(model, config)
        plant = MultibodyPlant(time_step=0.0)
        said = _Said()
        try:
            parser = Parser(plant)
            for k, v in packages(model).items():
                parser.package_map().Add(k, str(v))
            with said:
                parser.AddModels(str(path))
        except Exception as exc:
            raise Unsupported(
                f"drake: its importer cannot load {scenario.model_spec['file']} ({config}): "
                f"{type(exc).__name__}: {str(exc).splitlines()[0][:300]}"
            ) from None
        finally:
            if tmp:
                shutil.rmtree(tmp, ignore_errors=True)
        rec = {"importer": "Parser.AddModels", "configuration": config,
               "integrator": f"{integrator} (fixed step)", "gravity": st.gravity.tolist(),
               "contact": "none (no SceneGraph)",
               "limits": "not enforced (a continuous plant)"}  # fmt: skip
        if said.lines:  # what the parser ignored, in its words (file name dropped)
            rec["importer warnings"] = sorted({ln.split(": warning: ")[-1] for ln in said.lines})
        root = plant.GetBodyByName(model.root)
        welded = {j.child for j in model.joints if j.parent is None and j.kind == "fixed"}
        if model.format == "urdf" and not st.floating and model.root not in welded:
            plant.WeldFrames(plant.world_frame(), root.body_frame(), RigidTransform(st.T))
            rec["root"] = "welded to the world at the scenario's base pose"
        elif model.format == "urdf" and not st.floating:
            rec["root"] = "welded by the file (a joint from its link 'world')"
        joints = [plant.get_joint(_ji(i)) for i in range(plant.num_joints())]
        if config == "faithful":
            for jt in joints:
                if hasattr(jt, "set_default_damping"):
                    jt.set_default_damping(0.0)
            for i in range(plant.num_actuators()):
                plant.get_joint_actuator(_ai(i)).set_default_rotor_inertia(0.0)
            rec["switched off"] = "joint damping 0, rotor inertia 0"
        else:
            damp = sorted({float(jt.default_damping()) for jt in joints
                           if hasattr(jt, "default_damping")})  # fmt: skip
            rec["as the file has it"] = f"damping {damp}, {plant.num_actuators()} actuators"
            arm = armatures(plant)
            lost = [j.name for j in model.joints if j.armature and plant.HasJointNamed(j.name)
                    and arm.get(int(plant.GetJointByName(j.name).index()), 0.0) == 0.0]  # fmt: skip
            if lost:
                rec["armature lost"] = (f"{lost}: no actuator on them, so Drake's MJCF parser "
                                        "drops the file's armature")  # fmt: skip
        plant.mutable_gravity_field().set_gravity_vector(st.gravity)
        plant.Finalize()
        self.plant = plant
        if plant.num_constraints():  # e.g. a URDF <mimic> joint: a coupler constraint
            raise Unsupported(
                f"drake: its importer's plant holds {plant.num_constraints()} constraint(s) (a "
                "<mimic> joint becomes a coupler), which a continuous plant does not run "
                "(Drake: 'Continuous time does not support constraints')"
            )
        sim = Simulator(plant)
        ctx = sim.get_mutable_context()
        if plant.num_actuated_dofs():
            plant.get_actuation_input_port().FixValue(ctx, np.zeros(plant.num_actuated_dofs()))
            rec["actuation"] = "0"
        self._start(ctx, st, model)
        integ = ResetIntegratorFromFlags(sim, integrator, float(dt))
        integ.set_fixed_step_mode(True)
        if not (integ.get_fixed_step_mode() and integ.get_maximum_step_size() == float(dt)):
            raise EngineError(f"drake: {integrator}: the fixed step {dt:g} s did not take")
        sim.Initialize()
        if st.held:
            rec["held joints"] = f"{st.held}: free in Drake's plant, at rest at t = 0"
        self.sim, self.ctx, self.integ, self.dt = sim, ctx, integ, float(dt)
        self.t, self.settings, self.clock = 0.0, rec, 0.0
        self._bodies: dict = {}

    def _start(self, ctx, st, model) -> None:
        """The start by joint name (an MJCF hinge's Drake angle is MuJoCo's qpos, the
        scenario's coordinate: measured so that at its ``ref`` the body sits where the file
        puts it; shown by the faithful run of crawler_float, whose wrist has a ref)."""
        from pydrake.math import RigidTransform
        from pydrake.multibody.math import SpatialVelocity

        from references.errors import Unsupported

        plant = self.plant
        for name in set(st.q) | set(st.qd):
            if not plant.HasJointNamed(name):
                continue
            jt = plant.GetJointByName(name)
            if jt.num_positions() != 1:
                if name in st.given:
                    raise Unsupported(f"drake: joint {name!r} is a {jt.type_name()} in "
                                      "Drake's plant: the scenario's start for it is not "
                                      "set here")  # fmt: skip
                continue
            if name in st.q:
                q = plant.GetPositions(ctx)
                q[jt.position_start()] = float(st.q[name])
                plant.SetPositions(ctx, q)
            if name in st.qd:
                v = plant.GetVelocities(ctx)
                v[jt.velocity_start()] = float(st.qd[name])
                plant.SetVelocities(ctx, v)
        root = plant.GetBodyByName(model.root)
        if root.is_floating_base_body():
            plant.SetFreeBodyPose(ctx, root, RigidTransform(st.T))
            plant.SetFreeBodySpatialVelocity(ctx, root, SpatialVelocity(st.w, st.v))

    def advance(self, n: int) -> None:
        import time

        from references.engines import timing

        for _ in range(n):
            self.t += self.dt  # the Simulator's own running sum of steps
        t0 = time.perf_counter()
        self.sim.AdvanceTo(self.t)
        self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices

    def links(self, names):
        plant, ctx = self.plant, self.ctx
        n = len(names)
        T = np.tile(np.eye(4), (n, 1, 1))
        v, w = np.zeros((n, 3)), np.zeros((n, 3))
        for i, (name, joint) in enumerate(names):
            if name not in self._bodies:
                if plant.HasBodyNamed(name):
                    self._bodies[name] = plant.GetBodyByName(name)
                elif joint is not None and plant.HasJointNamed(joint):
                    self._bodies[name] = plant.GetJointByName(joint).child_body()
                else:
                    raise KeyError(f"drake: link {name!r} (joint {joint!r}) is not in the plant")
            b = self._bodies[name]
            T[i] = b.EvalPoseInWorld(ctx).GetAsMatrix4()
            V = b.EvalSpatialVelocityInWorld(ctx)
            w[i], v[i] = V.rotational(), V.translational()
        return T, v, w


class _Said(logging.Handler):
    """The lines Drake's parser logs (its warnings about what it ignores), kept instead of
    printed: inside ``with``, this is the ``drake`` logger's only handler."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.lines: list = []

    def emit(self, record) -> None:
        self.lines.append(record.getMessage())

    def __enter__(self):
        log = logging.getLogger("drake")
        self._saved = (log.handlers[:], log.propagate)
        log.handlers, log.propagate = [self], False
        return self

    def __exit__(self, *exc):
        log = logging.getLogger("drake")
        log.handlers, log.propagate = self._saved


def _ai(i):
    from pydrake.multibody.tree import JointActuatorIndex

    return JointActuatorIndex(i)


def load(scenario, config: str, integrator: str, dt: float) -> _Sim:
    """The scenario's model file loaded by Drake's importer in ``config``, its state set
    (:func:`references.engines.importers.simulate`)."""
    return _Sim(scenario, config, integrator, dt)
