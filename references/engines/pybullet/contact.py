"""PyBullet's contact: ``stepSimulation`` with Bullet's multibody sequential-impulse solver
(projected Gauss-Seidel on velocity impulses, ERP position correction), its default friction
(two tangent directions, each bounded by mu N: a friction box) or its cone friction
(``enableConeFriction``).

Model: each body a base-only multibody (``createMultiBody``; its base frame is the inertial
frame at the centre of mass, engines.md) with one collision shape (``GEOM_SPHERE``,
``GEOM_BOX`` half extents, ``GEOM_CAPSULE`` and ``GEOM_CYLINDER`` with ``height`` the length
of the cylinder, along z) at the shape's offset, the inertia set and read back
(``localInertiaDiagonal``), damping 0 (PyBullet's default 0.04 removes energy), rolling and
spinning friction 0; each plane a static ``GEOM_PLANE`` with its normal, based at its point.
Only the scene's pairs collide (``setCollisionFilterPair`` off for every other pair).

Friction and restitution are per body and Bullet multiplies the two bodies' values
(:func:`references.engines.contact.pair_coefficients` with the product rule, planes 1; a
scene they cannot express is unsupported). Read back with ``getDynamicsInfo`` and
``getCollisionShapeData``.

A scene with restitution (some e > 0) sets every body's ``contactProcessingThreshold`` to 0:
with Bullet's default predictive contacts a ball with e = 0.5 did not rebound at all (a check
made here; bullet3 issue 3094); with 0 it rebounded to 0.135 m from 0.5 m (exact 0.125).

Contacts: ``getContactPoints`` after each step: position on A, ``contactNormalOnB`` (from B
towards A), ``contactDistance`` (< 0 penetrating), ``normalForce`` and the two lateral
friction forces along their directions, the forces Bullet applied on A over the step
(impulse/dt).
"""

from __future__ import annotations

import time

import numpy as np

from references import conventions as cv
from references.engines import timing
from references.engines.contact import (
    ContactLog,
    SavedStates,
    external_wrench,
    forced_bodies,
    ground_joints,
    joint_anchor_world,
    joint_rate,
    pair_coefficients,
    pair_index,
)
from references.engines.integrators import Integrator

FAMILY = "sequential impulses"

CONFIGURATIONS = (
    Integrator(
        "default friction",
        FAMILY,
        1,
        "Bullet's default: two friction directions, each bounded by mu N (a box)",
        options={"enableConeFriction": 0},
    ),
    Integrator(
        "cone friction",
        FAMILY,
        1,
        "Bullet's cone friction (enableConeFriction): |friction| <= mu N",
        options={"enableConeFriction": 1},
    ),
)

SETTINGS = ("numSolverIterations", "erp", "contactERP", "frictionERP", "enableSAT")


def _import():
    from references.engines.native import import_engine

    return import_engine("pybullet", "PyBullet", "pybullet")


def _shape(p, s, cid):
    kw = {
        "collisionFramePosition": list(map(float, s.position)),
        "collisionFrameOrientation": list(map(float, cv.matrix_to_quat_xyzw(s.rotation))),
        "physicsClientId": cid,
    }
    if s.kind == "sphere":
        return p.createCollisionShape(p.GEOM_SPHERE, radius=s.radius, **kw)
    if s.kind == "box":
        return p.createCollisionShape(
            p.GEOM_BOX, halfExtents=list(map(float, s.half_extents)), **kw
        )
    kind = p.GEOM_CAPSULE if s.kind == "capsule" else p.GEOM_CYLINDER
    return p.createCollisionShape(kind, radius=s.radius, height=2.0 * s.half_length, **kw)


class Scene:
    def __init__(self, p, scenario, conf, dt, settings):
        hinges = ground_joints(scenario, "pybullet")
        self.p, self.sc = p, scenario
        self.cid = cid = p.connect(p.DIRECT)
        self.mu_set = pair_coefficients(scenario, "mu", "product", plane_value=1.0)
        self.e_set = pair_coefficients(scenario, "e", "product", plane_value=1.0)
        p.setGravity(*map(float, scenario.gravity), physicsClientId=cid)
        p.setTimeStep(float(dt), physicsClientId=cid)
        params = {"enableConeFriction": int(conf.options["enableConeFriction"])}
        for k in SETTINGS:
            if k in settings:
                params[k] = settings[k]
        p.setPhysicsEngineParameter(**params, physicsClientId=cid)
        self.ids = {}
        self.link = {}  # name -> the link carrying it: -1 the base, 0 a hinged body's link
        for pl in scenario.planes:
            s = p.createCollisionShape(
                p.GEOM_PLANE, planeNormal=list(map(float, pl.normal)), physicsClientId=cid
            )
            self.ids[pl.name] = p.createMultiBody(
                0, s, basePosition=list(map(float, pl.point)), physicsClientId=cid
            )
            self.link[pl.name] = -1
        for b in scenario.bodies:
            if b.name in hinges:
                self._hinged(b, hinges[b.name])
                continue
            s = _shape(p, b.shape, cid) if b.shape is not None else -1
            self.link[b.name] = -1
            bid = p.createMultiBody(
                b.mass,
                s,
                basePosition=list(map(float, b.position)),
                baseOrientation=list(map(float, cv.matrix_to_quat_xyzw(b.rotation))),
                physicsClientId=cid,
            )
            self.ids[b.name] = bid
            p.changeDynamics(
                bid,
                -1,
                localInertiaDiagonal=list(map(float, b.inertia)),
                linearDamping=0.0,
                angularDamping=0.0,
                physicsClientId=cid,
            )
            p.resetBaseVelocity(
                bid,
                list(map(float, b.velocity)),
                list(map(float, b.rotation @ b.omega_body)),
                physicsClientId=cid,
            )
        # Bullet's predictive contacts (its contact processing threshold) swallow restitution:
        # a ball with e = 0.5 did not rebound at all until it was 0 (bullet3 issue 3094)
        self.bouncy = any(c.e > 0 for c in scenario.contacts)
        extra = {"contactProcessingThreshold": 0.0} if self.bouncy else {}
        for name, bid in self.ids.items():
            p.changeDynamics(
                bid,
                self.link[name],
                lateralFriction=float(self.mu_set[name]),
                restitution=float(self.e_set[name]),
                rollingFriction=0.0,
                spinningFriction=0.0,
                physicsClientId=cid,
                **extra,
            )
        listed = {frozenset((c.a, c.b)) for c in scenario.contacts}
        names = list(self.ids)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if frozenset((a, b)) not in listed:
                    p.setCollisionFilterPair(
                        self.ids[a],
                        self.ids[b],
                        self.link[a],
                        self.link[b],
                        0,
                        physicsClientId=cid,
                    )

    def _hinged(self, b, j):
        """Body ``b`` on a revolute or prismatic joint ``j`` to the ground: a multibody whose
        fixed base (mass 0, no shape) stands at the anchor (where body a's is at t = 0) with
        the body's initial axes, and whose one link turns about or slides along the axis
        there, its centre of mass at -anchor_a in the link frame
        (q = 0: the scene's initial pose), its shape placed in the link frame (PyBullet
        places a link's collision shape there, not in its inertial frame: a sphere given
        at the centre of mass was found at the hinge); the joint's default velocity motor
        is switched off (PyBullet motorises every revolute joint of a multibody)."""
        import dataclasses

        p, cid = self.p, self.cid
        shape = -1
        if b.shape is not None:
            at_link = dataclasses.replace(b.shape, position=b.shape.position - j.anchor_a)
            shape = _shape(p, at_link, cid)
        zero = [0.0, 0.0, 0.0, 1.0]
        bid = p.createMultiBody(
            0.0,
            -1,
            basePosition=list(map(float, joint_anchor_world(b, j))),
            baseOrientation=list(map(float, cv.matrix_to_quat_xyzw(b.rotation))),
            linkMasses=[float(b.mass)],
            linkCollisionShapeIndices=[shape],
            linkVisualShapeIndices=[-1],
            linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[zero],
            linkInertialFramePositions=[list(map(float, -np.asarray(j.anchor_a)))],
            linkInertialFrameOrientations=[zero],
            linkParentIndices=[0],
            linkJointTypes=[p.JOINT_PRISMATIC if j.kind == "prismatic" else p.JOINT_REVOLUTE],
            linkJointAxis=[list(map(float, j.axis_a))],
            physicsClientId=cid,
        )
        self.ids[b.name], self.link[b.name] = bid, 0
        p.changeDynamics(bid, 0, localInertiaDiagonal=list(map(float, b.inertia)),
                         linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                         physicsClientId=cid)  # fmt: skip
        p.setJointMotorControl2(bid, 0, p.VELOCITY_CONTROL, force=0.0, physicsClientId=cid)
        p.resetJointState(bid, 0, 0.0, joint_rate(b, j), physicsClientId=cid)

    def state(self, name):
        """(centre of mass, rotation, velocity, angular velocity (world)) of body ``name``."""
        p, cid, bid = self.p, self.cid, self.ids[name]
        if self.link[name] == -1:
            pos, orn = p.getBasePositionAndOrientation(bid, physicsClientId=cid)
            lin, ang = p.getBaseVelocity(bid, physicsClientId=cid)
        else:
            st = p.getLinkState(bid, self.link[name], computeLinkVelocity=1,
                                computeForwardKinematics=1, physicsClientId=cid)  # fmt: skip
            pos, orn, lin, ang = st[0], st[1], st[6], st[7]
        return np.asarray(pos), cv.quat_xyzw_to_matrix(orn), np.asarray(lin), np.asarray(ang)

    def readback(self) -> dict:
        p, cid = self.p, self.cid
        info = {
            n: p.getDynamicsInfo(i, self.link[n], physicsClientId=cid) for n, i in self.ids.items()
        }
        for b in self.sc.bodies:
            got = np.array(info[b.name][2])
            if not np.allclose(got, b.inertia, rtol=1e-9, atol=0.0):
                from references.errors import EngineError

                raise EngineError(
                    f"pybullet: body {b.name!r} has inertia {got.tolist()}, the "
                    f"scene {b.inertia.tolist()}"
                )
        pairs = {
            i: {"mu": info[c.a][1] * info[c.b][1], "e": info[c.a][5] * info[c.b][5]}
            for i, c in enumerate(self.sc.contacts)
        }
        kinds = {
            p.GEOM_SPHERE: "sphere",
            p.GEOM_BOX: "box",
            p.GEOM_CAPSULE: "capsule",
            p.GEOM_CYLINDER: "cylinder",
        }
        shapes = {}
        for b in self.sc.bodies:
            data = p.getCollisionShapeData(self.ids[b.name], self.link[b.name], physicsClientId=cid)
            if not data:
                continue
            d = data[0]
            kind = kinds.get(d[2], str(d[2]))
            dims = d[3]
            if kind == "box":
                size = tuple(0.5 * np.asarray(dims))
            elif kind == "sphere":
                size = (dims[0],)
            else:
                size = (dims[1], 0.5 * dims[0])
            # the collision frame relative to the inertial (COM) frame of the base
            shapes[b.name] = {
                "kind": kind,
                "size": size,
                "offset": tuple(d[5]),
                "rotation": cv.quat_xyzw_to_matrix(d[6]),
            }
        joints = {}
        kinds = {p.JOINT_REVOLUTE: "revolute", p.JOINT_PRISMATIC: "prismatic"}
        for j in self.sc.joints:
            bid = self.ids[j.body_a]
            info = p.getJointInfo(bid, 0, physicsClientId=cid)
            base, orn = p.getBasePositionAndOrientation(bid, physicsClientId=cid)
            Rb = cv.quat_xyzw_to_matrix(orn)  # the fixed base: the joint's parent frame
            Rj = Rb @ cv.quat_xyzw_to_matrix(info[15])
            joints[j.name] = {
                "kind": kinds.get(info[2], str(info[2])),
                "anchor": np.asarray(base) + Rb @ np.asarray(info[14]),
                "axis": Rj @ np.asarray(info[13]),
            }
        return {"pairs": pairs, "shapes": shapes, "joints": joints}

    def close(self):
        self.p.disconnect(physicsClientId=self.cid)


def _plant_mu(scene):
    for name, bid in scene.ids.items():
        scene.p.changeDynamics(
            bid, scene.link[name], lateralFriction=1.0, physicsClientId=scene.cid
        )


def _plant_offset(scene):
    b = scene.sc.bodies[0]
    p, cid = scene.p, scene.cid
    s = b.shape
    moved = type(s)(
        s.kind,
        s.radius,
        s.half_extents,
        s.half_length,
        s.position + np.array([0.0, 0.0, 0.01]),
        s.rotation,
    )
    bid = p.createMultiBody(
        b.mass,
        _shape(p, moved, cid),
        basePosition=list(b.position),
        baseOrientation=list(cv.matrix_to_quat_xyzw(b.rotation)),
        physicsClientId=cid,
    )
    p.removeBody(scene.ids[b.name], physicsClientId=cid)
    scene.ids[b.name] = bid


def _plant_axis(scene):
    """Rebuild every jointed body with its joint's axis tilted by 0.01 rad."""
    import dataclasses

    bodies = {b.name: b for b in scene.sc.bodies}
    for j in scene.sc.joints:
        a = np.asarray(j.axis_a, dtype=float)
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        tilted = dataclasses.replace(j, axis_a=a + 0.01 * np.linalg.norm(a) * across
                                     / np.linalg.norm(across))  # fmt: skip
        scene.p.removeBody(scene.ids[j.body_a], physicsClientId=scene.cid)
        scene._hinged(bodies[j.body_a], tilted)


PLANTABLE = {"mu not applied": _plant_mu, "shape offset": _plant_offset,
             "joint axis": _plant_axis}  # fmt: skip


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    from references.engines.contact import configuration as find

    p = _import()
    conf = find("pybullet", configuration)
    sc = Scene(p, scenario, conf, dt, settings)
    try:
        if _plant is not None:
            PLANTABLE[_plant](sc)
        return _run(p, sc, scenario, conf, dt, nstep, save_every)
    finally:
        sc.close()


def _run(p, sc, scenario, conf, dt, nstep, save_every):
    cid = sc.cid
    names = [b.name for b in scenario.bodies]
    byid = {i: n for n, i in sc.ids.items()}
    pidx = pair_index(scenario)
    forced = forced_bodies(scenario)
    nb = len(names)
    saved = SavedStates(nstep, save_every, nb)
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()

    def save(k, step):
        for i, n in enumerate(names):
            pos, Rb, lin, ang = sc.state(n)
            X[k, i], R[k, i], V[k, i], W[k, i] = pos, Rb, lin, Rb.T @ ang
        t[k] = step * dt
        if step > 0:
            for c in p.getContactPoints(physicsClientId=cid):
                na, nb_ = byid.get(c[1]), byid.get(c[2])
                pi = pidx.get(frozenset((na, nb_)))
                if pi is None:
                    continue
                nrm = np.asarray(c[7])  # on B, pointing towards A
                f = c[9] * nrm + c[10] * np.asarray(c[11]) + c[12] * np.asarray(c[13])  # on A
                point = np.asarray(c[5])
                if na != scenario.contacts[pi].a:
                    f, nrm, point = -f, -nrm, np.asarray(c[6])
                log.add(pi, point, nrm, f, -float(c[8]))
        log.save()

    save(0, 0)
    engine = 0.0
    timing.stepping()  # the model is built: its construction is not the cost
    k = 1
    for step in range(1, nstep + 1):
        for i in forced:
            bid, link = sc.ids[names[i]], sc.link[names[i]]
            pos, Rb, _, _ = sc.state(names[i])
            F, tau = external_wrench(scenario, i, Rb)
            p.applyExternalForce(bid, link, list(F), list(pos), p.WORLD_FRAME, physicsClientId=cid)
            if np.any(tau):
                p.applyExternalTorque(bid, link, list(tau), p.WORLD_FRAME, physicsClientId=cid)
        t0 = time.perf_counter()
        p.stepSimulation(physicsClientId=cid)
        engine += timing.lap(t0)
        if step % save_every == 0 or step == nstep:
            save(k, step)
            k += 1
            if not np.all(np.isfinite(X[k - 1])):
                break
    params = p.getPhysicsEngineParameters(physicsClientId=cid)
    record = {
        "solver": "Bullet multibody sequential impulses (stepSimulation)",
        "enableConeFriction": int(conf.options["enableConeFriction"]),
        "numSolverIterations": params.get("numSolverIterations"),
        "fixedTimeStep": params.get("fixedTimeStep"),
        "numSubSteps": params.get("numSubSteps"),
        "friction per body (pair: product)": {k: float(v) for k, v in sc.mu_set.items()},
        "restitution per body (pair: product)": {k: float(v) for k, v in sc.e_set.items()},
        "damping": 0.0,
        "contactProcessingThreshold": "0 (restitution in the scene; bullet3 issue 3094)"
        if sc.bouncy
        else "PyBullet's default",
        "rolling and spinning friction": 0.0,
        "other parameters": "PyBullet's defaults (ERP, contact ERP, split impulse, "
        "restitution velocity threshold) unless set in [engine_settings.pybullet]",
    }
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": record,
        "readback": sc.readback(),
    }
