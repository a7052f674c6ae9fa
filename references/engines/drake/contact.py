"""Drake's contact: a discrete ``MultibodyPlant`` (time step dt) with a discrete contact
approximation (SAP, TAMSI, Lagged) and compliant point contact or hydroelastic contact, stepped
by a ``Simulator``.

Model: each body a free body (``AddRigidBody`` with ``MakeFromCentralInertia``: the body frame
is the principal frame at the centre of mass), its shape (``Sphere``, ``Box`` of full sides,
``Capsule`` and ``Cylinder`` of full length) registered as collision geometry at the shape's
offset with ``CoulombFriction(mu, mu)``; each plane a ``HalfSpace`` on the world whose frame's
z is the plane's normal, at its point. Only the scene's pairs collide (every other pair of
geometries excluded through the collision filter manager). Drake gives a pair the friction
2 mu_1 mu_2/(mu_1 + mu_2) (:func:`references.engines.contact.pair_coefficients` solves for
per-geometry values; read back from the proximity properties and combined by the same rule).
Drake's discrete contact has no restitution coefficient (its dissipation is a velocity-
dependent law): a scene with e > 0 is unsupported, with that reason.

Point contact: stiffness from ``penetration_allowance`` (MultibodyPlantConfig, default 1e-3 m)
and Drake's default dissipation; a box on a half-space touches at one point (its deepest
vertex), which Drake documents for point contact. Hydroelastic: the bodies compliant
(``AddCompliantHydroelasticProperties``, modulus ``hydroelastic_modulus`` default 1e7 Pa,
resolution hint ``resolution`` default a quarter of the shape's size), the planes rigid.

External forces: ``ExternallyAppliedSpatialForce`` at the body point, fixed on the plant's
applied-force port (constant in world axes; the point turns with the body).

Contacts at the saved steps from the contact results port (its sampled value: the step that
ended there): point pairs (``contact_point``, ``contact_force`` on B, ``nhat_BA_W`` from B into
A, ``depth``); hydroelastic surfaces as one row each at the surface's centroid with the
resultant force on A (``F_Ac_W``) and the area-weighted mean of the surface's face normals
(a surface of no area that carries nothing is no row).
"""

from __future__ import annotations

import time

import numpy as np

from references.engines import timing
from references.engines.contact import (
    ContactLog,
    SavedStates,
    ground_joints,
    joint_anchor_world,
    joint_rate,
    pair_coefficients,
    pair_index,
)
from references.engines.integrators import Integrator
from references.errors import Unsupported

FAMILY = "convex compliant contact"

CONFIGURATIONS = (
    Integrator(
        "SAP, point contact",
        FAMILY,
        1,
        "discrete SAP (Castro et al. 2022) with compliant point contact",
        options={"approx": "sap", "model": "point"},
    ),
    Integrator(
        "TAMSI, point contact",
        FAMILY,
        1,
        "discrete TAMSI (Castro et al. 2019; deprecated in Drake 1.51) with compliant "
        "point contact",
        options={"approx": "tamsi", "model": "point"},
        default=False,  # deprecated by Drake; the default suite runs SAP
    ),
    Integrator(
        "Lagged, point contact",
        FAMILY,
        1,
        "Drake's default discrete approximation (SAP-based, lagged) with point contact",
        options={"approx": "lagged", "model": "point"},
        default=False,
    ),
    Integrator(
        "SAP, hydroelastic",
        FAMILY,
        1,
        "discrete SAP with compliant hydroelastic bodies on rigid planes",
        options={"approx": "sap", "model": "hydroelastic"},
        default=False,
    ),
)

SETTINGS = ("penetration_allowance", "stiction_tolerance", "hydroelastic_modulus", "resolution")


def _import():
    from references.engines.drake.plant import import_drake

    return import_drake()


def _pydrake():
    """Drake's classes a contact scene is built from, as one namespace: from the modules that
    define them (``pydrake.all`` would import every one of Drake's modules, its visualisers
    and matplotlib with them: 0.47 s more CPU per worker process, measured)."""
    import types

    from pydrake import geometry, math
    from pydrake.multibody import math as mb_math
    from pydrake.multibody import plant, tree
    from pydrake.systems import analysis, framework

    names = {
        geometry: (
            "AddCompliantHydroelasticProperties", "AddContactMaterial",
            "AddRigidHydroelasticProperties", "Box", "Capsule", "CollisionFilterDeclaration",
            "Cylinder", "GeometrySet", "HalfSpace", "ProximityProperties", "Sphere",
        ),
        math: ("RigidTransform", "RotationMatrix"),
        mb_math: ("SpatialForce", "SpatialVelocity"),
        plant: (
            "AddMultibodyPlant", "CoulombFriction", "ExternallyAppliedSpatialForce",
            "MultibodyPlantConfig",
        ),
        tree: (
            "FixedOffsetFrame", "PrismaticJoint", "RevoluteJoint", "RotationalInertia",
            "SpatialInertia",
        ),
        analysis: ("Simulator",),
        framework: ("DiagramBuilder",),
    }  # fmt: skip
    return types.SimpleNamespace(**{n: getattr(mod, n) for mod, ns in names.items() for n in ns})


def _shape(m, s):
    if s.kind == "sphere":
        return m.Sphere(s.radius)
    if s.kind == "box":
        return m.Box(*(2.0 * np.asarray(s.half_extents)))
    if s.kind == "capsule":
        return m.Capsule(s.radius, 2.0 * s.half_length)
    return m.Cylinder(s.radius, 2.0 * s.half_length)


class Scene:
    def __init__(self, scenario, conf, dt, settings, mu_override=None):
        _import()
        m = _pydrake()
        hinges = ground_joints(scenario, "drake")
        bad = [f"{c.a}-{c.b}" for c in scenario.contacts if c.e > 0]
        if bad:
            raise Unsupported(
                "drake: its discrete contact has no restitution coefficient (the dissipation is "
                f"a velocity-dependent law): pairs {bad} ask for e > 0"
            )
        self.m, self.sc = m, scenario
        opt = conf.options
        self.mu_set = pair_coefficients(scenario, "mu", "harmonic")
        if mu_override is not None:
            self.mu_set = {k: mu_override for k in self.mu_set}
        model = "hydroelastic_with_fallback" if opt["model"] == "hydroelastic" else "point"
        cfg = m.MultibodyPlantConfig(
            time_step=float(dt),
            discrete_contact_approximation=opt["approx"],
            contact_model=model,
            penetration_allowance=float(settings.get("penetration_allowance", 1e-3)),
            stiction_tolerance=float(settings.get("stiction_tolerance", 1e-4)),
        )
        builder = m.DiagramBuilder()
        plant, sg = m.AddMultibodyPlant(cfg, builder)
        self.plant, self.sg, self.cfg = plant, sg, cfg
        plant.mutable_gravity_field().set_gravity_vector(np.asarray(scenario.gravity, float))
        hydro = opt["model"] == "hydroelastic"
        modulus = float(settings.get("hydroelastic_modulus", 1e7))
        self.gid, self.body = {}, {}
        for p in scenario.planes:
            props = m.ProximityProperties()
            m.AddContactMaterial(
                friction=m.CoulombFriction(self.mu_set[p.name], self.mu_set[p.name]),
                properties=props,
            )
            if hydro:
                m.AddRigidHydroelasticProperties(properties=props)
            from references.engines.pinocchio.contact import _frame

            X = m.RigidTransform(
                m.RotationMatrix(_frame(np.asarray(p.normal, float))), np.asarray(p.point, float)
            )
            self.gid[p.name] = plant.RegisterCollisionGeometry(
                plant.world_body(), X, m.HalfSpace(), f"plane:{p.name}", props
            )
        for b in scenario.bodies:
            body = plant.AddRigidBody(
                b.name,
                m.SpatialInertia.MakeFromCentralInertia(
                    b.mass, np.zeros(3), m.RotationalInertia(*map(float, b.inertia))
                ),
            )
            self.body[b.name] = body
            s = b.shape
            if s is None:
                continue
            props = m.ProximityProperties()
            mu = self.mu_set[b.name]
            m.AddContactMaterial(friction=m.CoulombFriction(mu, mu), properties=props)
            if hydro:
                hint = float(settings.get("resolution", s.size / 4.0))
                m.AddCompliantHydroelasticProperties(
                    resolution_hint=hint, hydroelastic_modulus=modulus, properties=props
                )
            X = m.RigidTransform(m.RotationMatrix(s.rotation), np.asarray(s.position, float))
            self.gid[b.name] = plant.RegisterCollisionGeometry(
                body, X, _shape(m, s), f"geom:{b.name}", props
            )
        self.hinges = {}  # body name -> (its RevoluteJoint or PrismaticJoint, its initial rate)
        for b in scenario.bodies:
            j = hinges.get(b.name)
            if j is None:
                continue
            # F on the world at the anchor with the body's initial axes, M on the body at its
            # anchor: they coincide at q = 0, the scene's initial pose
            F = plant.AddFrame(
                m.FixedOffsetFrame(
                    f"{j.name}_F",
                    plant.world_frame(),
                    m.RigidTransform(m.RotationMatrix(b.rotation), joint_anchor_world(b, j)),
                )
            )
            M = plant.AddFrame(m.FixedOffsetFrame(
                f"{j.name}_M", self.body[b.name].body_frame(),
                m.RigidTransform(np.asarray(j.anchor_a, float))))  # fmt: skip
            kind = m.PrismaticJoint if j.kind == "prismatic" else m.RevoluteJoint
            joint = plant.AddJoint(kind(j.name, F, M, np.asarray(j.axis_a, float)))
            self.hinges[b.name] = (joint, joint_rate(b, j))
        plant.Finalize()
        listed = {frozenset((c.a, c.b)) for c in scenario.contacts}
        names = list(self.gid)
        mgr = sg.collision_filter_manager()
        for i, a in enumerate(names):
            for bname in names[i + 1 :]:
                if frozenset((a, bname)) not in listed:
                    mgr.Apply(
                        m.CollisionFilterDeclaration().ExcludeBetween(
                            m.GeometrySet(self.gid[a]), m.GeometrySet(self.gid[bname])
                        )
                    )
        forces = []
        for f in scenario.forces:
            ext = m.ExternallyAppliedSpatialForce()
            ext.body_index = self.body[f.body].index()
            ext.p_BoBq_B = np.asarray(f.point, float)
            ext.F_Bq_W = m.SpatialForce(np.zeros(3), np.asarray(f.force, float))
            forces.append(ext)
        self.diagram = builder.Build()
        self.sim = m.Simulator(self.diagram)
        ctx = self.sim.get_mutable_context()
        self.pc = plant.GetMyMutableContextFromRoot(ctx)
        if forces:
            plant.get_applied_spatial_force_input_port().FixValue(self.pc, forces)
        for b in scenario.bodies:
            body = self.body[b.name]
            if b.name in self.hinges:
                joint, rate = self.hinges[b.name]
                if type(joint).__name__.startswith("PrismaticJoint"):
                    joint.set_translation(self.pc, 0.0)
                    joint.set_translation_rate(self.pc, rate)
                else:
                    joint.set_angle(self.pc, 0.0)
                    joint.set_angular_rate(self.pc, rate)
                continue
            plant.SetFreeBodyPose(
                self.pc,
                body,
                m.RigidTransform(m.RotationMatrix(b.rotation), np.asarray(b.position, float)),
            )
            plant.SetFreeBodySpatialVelocity(
                self.pc,
                body,
                m.SpatialVelocity(b.rotation @ b.omega_body, np.asarray(b.velocity, float)),
            )
        self.sim.Initialize()

    def readback(self) -> dict:
        insp = self.sg.model_inspector()
        shapes, mus = {}, {}
        for name, gid in self.gid.items():
            props = insp.GetProximityProperties(gid)
            mus[name] = props.GetProperty("material", "coulomb_friction").static_friction()
        for b in self.sc.bodies:
            if b.name not in self.gid:
                continue
            gid = self.gid[b.name]
            shp = insp.GetShape(gid)
            kind = type(shp).__name__.lower()
            if kind == "box":
                size = (shp.width() / 2, shp.depth() / 2, shp.height() / 2)
            elif kind == "sphere":
                size = (shp.radius(),)
            else:
                size = (shp.radius(), shp.length() / 2)
            X = insp.GetPoseInFrame(gid)
            shapes[b.name] = {
                "kind": kind,
                "size": size,
                "offset": tuple(X.translation()),
                "rotation": X.rotation().matrix(),
            }
        pairs = {}
        for i, c in enumerate(self.sc.contacts):
            a, bb = mus[c.a], mus[c.b]
            pairs[i] = {"mu": 2 * a * bb / (a + bb) if a + bb > 0 else 0.0}
        joints = {}
        for j in self.sc.joints:
            joint, _ = self.hinges[j.body_a]
            X = joint.frame_on_parent().CalcPoseInWorld(self.pc)
            prismatic = type(joint).__name__.startswith("PrismaticJoint")
            axis = joint.translation_axis() if prismatic else joint.revolute_axis()
            joints[j.name] = {
                "kind": "prismatic" if prismatic else "revolute",
                "anchor": np.asarray(X.translation()),
                "axis": X.rotation().matrix() @ np.asarray(axis),
            }
        return {"pairs": pairs, "shapes": shapes, "joints": joints}


#: mistakes the conformance kit plants (Drake's model is fixed at Finalize, so the builder
#: builds it with the mistake): every geometry's friction 1, the first body's shape moved 1 cm,
#: every joint's axis tilted by 0.01 rad
PLANTABLE = {"mu not applied": "mu", "shape offset": "offset", "joint axis": "axis"}


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    import dataclasses

    from references.engines.contact import configuration as find

    conf = find("drake", configuration)
    built = scenario
    if _plant == "shape offset":
        b = scenario.bodies[0]
        moved = dataclasses.replace(b.shape, position=b.shape.position + np.array([0, 0, 0.01]))
        built = scenario.replace(bodies=(dataclasses.replace(b, shape=moved), *scenario.bodies[1:]))
    if _plant == "joint axis":  # every joint's axis tilted by 0.01 rad
        from references.engines.contact import tilted_joints

        built = tilted_joints(scenario)
    import logging

    # Drake's log lines (TAMSI's deprecation) go into the run's settings, not the user's
    # terminal, but for those Drake gives once per process (:data:`ONCE_PER_PROCESS`)
    log = logging.getLogger("drake")
    said = _Said()
    saved = (log.handlers[:], log.propagate)
    log.handlers, log.propagate = [said], False
    try:
        mu = 1.0 if _plant == "mu not applied" else None
        sc = Scene(built, conf, dt, settings, mu_override=mu)
        sc.sc = scenario  # the read-back compares with the scene asked for
        out = _run(sc, scenario, conf, dt, nstep, save_every)
    finally:
        log.handlers, log.propagate = saved
    kept = {line for line in said.lines if not line.startswith(ONCE_PER_PROCESS)}
    out["settings"]["Drake's log"] = sorted(kept)
    return out


#: what Drake logs once per process, at the first scene that gives it cause: which run's log
#: would hold it depends only on which worker process built a Drake scene first (run to run
#: the settings of block_incline_stick and sphere_backspin differed by it, and the figures
#: drawn from them were drawn again); left out of every run's log. The half-space note
#: concerns deformable contact, which no scene here uses.
ONCE_PER_PROCESS = (
    "Rigid (non-deformable) half spaces are not currently supported for deformable contact",
)


def _surface_normal(surf, force, moment, pair):
    """The area-weighted mean of a hydroelastic surface's face normals (from N into M), or
    None for a surface of no area that carries nothing (Drake reports such degenerate
    surfaces, e.g. a sphere's first touch: four faces of area 0, zero normals, zero force).
    A surface of no area carrying a force has no normal to log: refused, naming the pair."""
    areas = np.array([surf.area(q) for q in range(surf.num_faces())])
    normals = np.array([surf.face_normal(q) for q in range(surf.num_faces())]).reshape(-1, 3)
    summed = areas @ normals if len(areas) else np.zeros(3)
    size = float(np.linalg.norm(summed))
    if size > 0.0 and np.isfinite(size):
        return summed / size
    if not (np.any(force) or np.any(moment)):
        return None
    raise RuntimeError(
        f"drake: hydroelastic surface of pair {pair[0]!r}-{pair[1]!r} has {surf.num_faces()} "
        f"faces, total area {surf.total_area():.3g} m^2 and no normal, but carries a force "
        f"{force.tolist()} N: no contact row can be logged for it"
    )


class _Said:
    """A logging handler keeping the messages (duck-typed: ``handle`` is what loggers call)."""

    level = 0

    def __init__(self):
        self.lines: list = []

    def handle(self, record) -> None:
        self.lines.append(record.getMessage())


def _run(sc, scenario, conf, dt, nstep, save_every):
    plant, pc = sc.plant, sc.pc
    names = [b.name for b in scenario.bodies]
    by_index = {sc.body[n].index(): n for n in names}
    pidx = pair_index(scenario)
    nb = len(names)
    saved = SavedStates(nstep, save_every, nb)
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()
    world = plant.world_body().index()

    def other_name(bidx, point):
        if bidx != world:
            return by_index.get(bidx)
        planes = [p for p in scenario.planes]
        return min(planes, key=lambda p: abs(float(p.normal @ (point - p.point)))).name

    def save(k, step):
        for i, n in enumerate(names):
            X_WB = plant.EvalBodyPoseInWorld(pc, sc.body[n])
            V_WB = plant.EvalBodySpatialVelocityInWorld(pc, sc.body[n])
            Rb = X_WB.rotation().matrix()
            X[k, i], R[k, i] = X_WB.translation(), Rb
            V[k, i], W[k, i] = V_WB.translational(), Rb.T @ V_WB.rotational()
        t[k] = step * dt
        if step > 0:
            res = plant.get_contact_results_output_port().Eval(pc)
            for j in range(res.num_point_pair_contacts()):
                info = res.point_pair_contact_info(j)
                p = np.asarray(info.contact_point())
                na, nb_ = other_name(info.bodyA_index(), p), other_name(info.bodyB_index(), p)
                pi = pidx.get(frozenset((na, nb_)))
                if pi is None:
                    continue
                f = np.asarray(info.contact_force())  # on B
                nrm = -np.asarray(info.point_pair().nhat_BA_W)  # from A into B
                if nb_ != scenario.contacts[pi].a:
                    f, nrm = -f, -nrm
                log.add(pi, p, nrm, f, float(info.point_pair().depth))
            for j in range(res.num_hydroelastic_contacts()):
                info = res.hydroelastic_contact_info(j)
                surf = info.contact_surface()
                ga, gb = surf.id_M(), surf.id_N()
                inv = {v: k for k, v in sc.gid.items()}
                na, nb_ = inv.get(ga), inv.get(gb)
                pi = pidx.get(frozenset((na, nb_)))
                if pi is None:
                    continue
                F = info.F_Ac_W()
                f = np.asarray(F.translational())  # on A: the body of geometry M
                nrm = _surface_normal(surf, f, np.asarray(F.rotational()), (na, nb_))
                if nrm is None:
                    continue
                if na != scenario.contacts[pi].a:
                    f, nrm = -f, -nrm
                log.add(pi, np.asarray(surf.centroid()), nrm, f)
        log.save()

    save(0, 0)
    engine = 0.0
    timing.stepping()  # the model is built: its construction is not the cost
    k = 1
    for step in range(save_every, nstep + save_every, save_every):
        step = min(step, nstep)
        t0 = time.perf_counter()
        sc.sim.AdvanceTo(step * dt)
        engine += timing.lap(t0)
        save(k, step)
        k += 1
        if not np.all(np.isfinite(X[k - 1])):
            break
        if step == nstep:
            break
    opt = conf.options
    record = {
        "discrete contact approximation": str(plant.get_discrete_contact_approximation()),
        "contact model": str(plant.get_contact_model()),
        "penetration allowance": float(sc.cfg.penetration_allowance),
        "stiction tolerance": float(sc.cfg.stiction_tolerance),
        "time step": float(plant.time_step()),
        "friction per geometry (pair: 2ab/(a+b))": {k: float(v) for k, v in sc.mu_set.items()},
        "restitution": "none (Drake's discrete contact has no coefficient)",
        "hydroelastic": "compliant bodies, rigid planes"
        if opt["model"] == "hydroelastic"
        else "off",
    }
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": record,
        "readback": sc.readback(),
    }
