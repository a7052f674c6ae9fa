"""DART's contact: ``World.step`` with its ``BoxedLcpConstraintSolver`` (a boxed LCP: two
tangent directions, each friction component bounded by mu N on its own, so the friction set is
a box, not a cone), FCL collision detection (DART's default detector).

Model: each body a skeleton on a ``FreeJoint`` (positions [rotation vector, x], velocities
[w, v] both world), or on a ``RevoluteJoint`` or ``PrismaticJoint`` for a body hinged or
slid on the ground (its frame at the anchor with the body's initial axes, q = 0 the scene's
initial pose; each joint read back: its type, and the world anchor and axis of its parent
side), whose body node
frame is the principal frame at the centre of mass, one
shape node (``SphereShape``, ``BoxShape`` of full sides, ``CapsuleShape`` (radius, length of
its cylinder), ``CylinderShape`` (radius, full height)) at the shape's offset; each plane a
static skeleton holding a 100 m x 100 m x 1 m box whose top face is the plane (FCL's
plane-box test returns one contact point, so a box resting on a ``PlaneShape`` stands on one
corner: checked when this module was written). Only the scene's pairs collide (every other
pair of body nodes is on the collision filter's black list). Deactivation (sleeping) off.

Friction and restitution are per shape: DART gives a pair min(mu_1, mu_2) and e_1 e_2
(:func:`references.engines.contact.pair_coefficients` solves for per-shape values; a scene
they cannot express is unsupported, naming the pair). Read back from the shapes' dynamics
aspects and combined by the same rules.

Configurations: the boxed LCP solved by Dantzig's pivoting method with DART's PGS as the
fallback when it fails (DART's default), by Dantzig alone (a failed solve leaves the impulses
zero), by PGS alone (DART's defaults: 30 iterations). Split impulse off (DART's default).

Contacts: ``World.getLastCollisionResult().getContacts()`` after each step: ``point``,
``normal`` (from body node 2 to body node 1), ``force`` (on body node 1, world, the impulse
of the step over dt), ``penetrationDepth``.
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
from references.errors import Unsupported

FAMILY = "boxed LCP"

CONFIGURATIONS = (
    Integrator(
        "Dantzig + PGS fallback",
        FAMILY,
        1,
        "DART's default: the boxed LCP by Dantzig's method, PGS when it fails",
        options={"primary": "Dantzig", "secondary": "PGS"},
    ),
    Integrator(
        "Dantzig",
        FAMILY,
        1,
        "the boxed LCP by Dantzig's method alone (no fallback)",
        options={"primary": "Dantzig", "secondary": None},
        default=False,
    ),
    Integrator(
        "PGS",
        FAMILY,
        1,
        "the boxed LCP by DART's projected Gauss-Seidel alone",
        options={"primary": "PGS", "secondary": None},
    ),
)

SETTINGS = ("detector", "split_impulse")
_DETECTORS = ("fcl", "bullet", "dart", "ode")
GROUND_SIZE = (100.0, 100.0, 1.0)


def _import():
    from references.engines.dart.adapter import _import as imp

    return imp()


def _shape(dart, s):
    if s.kind == "sphere":
        return dart.dynamics.SphereShape(s.radius)
    if s.kind == "box":
        return dart.dynamics.BoxShape(2.0 * np.asarray(s.half_extents))
    if s.kind == "capsule":
        return dart.dynamics.CapsuleShape(s.radius, 2.0 * s.half_length)
    return dart.dynamics.CylinderShape(s.radius, 2.0 * s.half_length)


def _iso(dart, R, p):
    T = dart.math.Isometry3()
    T.set_rotation(np.asarray(R, dtype=float))
    T.set_translation(np.asarray(p, dtype=float))
    return T


def _frame_z_to(n):
    from references.engines.pinocchio.contact import _frame

    return _frame(np.asarray(n, dtype=float))


class Scene:
    def __init__(self, dart, scenario, conf, dt, settings):
        hinges = ground_joints(scenario, "dart")
        self.dart, self.sc = dart, scenario
        mu = pair_coefficients(scenario, "mu", "min", plane_value=1e3)
        e = pair_coefficients(scenario, "e", "product", plane_value=1.0)
        self.mu_set, self.e_set = mu, e
        w = dart.simulation.World()
        w.setGravity(np.asarray(scenario.gravity, dtype=float))
        w.setTimeStep(float(dt))
        opts = w.getDeactivationOptions()
        opts.mEnabled = False
        w.setDeactivationOptions(opts)
        cs = w.getConstraintSolver()
        det = settings.get("detector", "fcl")
        if det not in _DETECTORS:
            raise Unsupported(f"dart: detector {det!r}; it takes {', '.join(_DETECTORS)}")
        if det != "fcl":
            cls = {
                "bullet": "BulletCollisionDetector",
                "dart": "DARTCollisionDetector",
                "ode": "OdeCollisionDetector",
            }[det]
            cs.setCollisionDetector(getattr(dart.collision, cls)())
        dantzig, pgs = cs.getBoxedLcpSolver(), cs.getSecondaryBoxedLcpSolver()
        opt = conf.options
        cs.setSecondaryBoxedLcpSolver(None)
        cs.setBoxedLcpSolver(dantzig if opt["primary"] == "Dantzig" else pgs)
        if opt["secondary"] == "PGS":
            cs.setSecondaryBoxedLcpSolver(pgs)
        cs.setSplitImpulseEnabled(bool(settings.get("split_impulse", False)))
        self.world, self.cs = w, cs
        self.nodes, self.joints, self.shapes = {}, {}, {}
        self.hinged = set()  # bodies on a joint to the ground
        for p in scenario.planes:
            g = dart.dynamics.Skeleton(f"plane:{p.name}")
            _, gb = g.createWeldJointAndBodyNodePair()
            gb.setName(f"plane:{p.name}")
            R = _frame_z_to(p.normal)
            sn = gb.createShapeNode(dart.dynamics.BoxShape(np.array(GROUND_SIZE)))
            sn.setName(f"plane:{p.name}")
            sn.setRelativeTransform(_iso(dart, R, p.point - 0.5 * GROUND_SIZE[2] * p.normal))
            sn.createCollisionAspect()
            sn.createDynamicsAspect()
            sn.getDynamicsAspect().setFrictionCoeff(mu[p.name])
            sn.getDynamicsAspect().setRestitutionCoeff(e[p.name])
            g.setMobile(False)
            w.addSkeleton(g)
            self.nodes[p.name], self.shapes[p.name] = gb, sn
        for b in scenario.bodies:
            skel = dart.dynamics.Skeleton(b.name)
            hinge = hinges.get(b.name)
            if hinge is None:
                j, bn = skel.createFreeJointAndBodyNodePair()
            else:  # the joint frame: at the anchor with the body's initial axes (q = 0)
                if hinge.kind == "prismatic":
                    j, bn = skel.createPrismaticJointAndBodyNodePair()
                else:
                    j, bn = skel.createRevoluteJointAndBodyNodePair()
                # the anchor on body a where it is at t = 0 (a hinge's anchor_b, a slider's
                # point on its line)
                j.setTransformFromParentBodyNode(
                    _iso(dart, b.rotation, joint_anchor_world(b, hinge))
                )
                j.setTransformFromChildBodyNode(_iso(dart, np.eye(3), hinge.anchor_a))
                j.setAxis(np.asarray(hinge.axis_a, dtype=float))
            bn.setName(b.name)
            bn.setInertia(dart.dynamics.Inertia(b.mass, np.zeros(3), np.diag(b.inertia)))
            for i in range(j.getNumDofs()):
                j.setDampingCoefficient(i, 0.0)
            if b.shape is not None:
                sn = bn.createShapeNode(_shape(dart, b.shape))
                sn.setName(f"geom:{b.name}")
                sn.setRelativeTransform(_iso(dart, b.shape.rotation, b.shape.position))
                sn.createCollisionAspect()
                sn.createDynamicsAspect()
                sn.getDynamicsAspect().setFrictionCoeff(mu[b.name])
                sn.getDynamicsAspect().setRestitutionCoeff(e[b.name])
                self.shapes[b.name] = sn
            w.addSkeleton(skel)
            if hinge is None:
                pos, vel = cv.dart_free_from_state(b.position, b.velocity, b.rotation, b.omega_body)
                j.setPositions(pos)
                j.setVelocities(vel)
            else:
                j.setPosition(0, 0.0)
                j.setVelocity(0, joint_rate(b, hinge))
                self.hinged.add(b.name)
            self.nodes[b.name], self.joints[b.name] = bn, j
        listed = {frozenset((c.a, c.b)) for c in scenario.contacts}
        filt = cs.getCollisionOption().collisionFilter
        names = list(self.nodes)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if frozenset((a, b)) not in listed:
                    filt.addBodyNodePairToBlackList(self.nodes[a], self.nodes[b])

    def readback(self) -> dict:
        shapes = {}
        kinds = {
            "SphereShape": "sphere",
            "BoxShape": "box",
            "CapsuleShape": "capsule",
            "CylinderShape": "cylinder",
        }
        for b in self.sc.bodies:
            sn = self.shapes.get(b.name)
            if sn is None:
                continue
            shp = sn.getShape()
            kind = kinds.get(shp.getType(), shp.getType())
            if kind == "box":
                size = tuple(np.asarray(shp.getSize()) / 2.0)
            elif kind == "sphere":
                size = (shp.getRadius(),)
            else:
                size = (shp.getRadius(), shp.getHeight() / 2.0)
            T = sn.getRelativeTransform()
            shapes[b.name] = {
                "kind": kind,
                "size": size,
                "offset": tuple(T.translation()),
                "rotation": np.asarray(T.rotation()),
            }
        pairs = {}
        for i, c in enumerate(self.sc.contacts):
            da, db = self.shapes[c.a].getDynamicsAspect(), self.shapes[c.b].getDynamicsAspect()
            pairs[i] = {
                "mu": min(da.getFrictionCoeff(), db.getFrictionCoeff()),
                "e": da.getRestitutionCoeff() * db.getRestitutionCoeff(),
            }
        joints = {}
        kinds = {"RevoluteJoint": "revolute", "PrismaticJoint": "prismatic"}
        for j in self.sc.joints:
            dj = self.joints[j.body_a]
            T = dj.getTransformFromParentBodyNode()  # the parent is the world
            joints[j.name] = {
                "kind": kinds.get(dj.getType(), dj.getType()),
                "anchor": np.asarray(T.translation()),
                "axis": np.asarray(T.rotation()) @ np.asarray(dj.getAxis()),
            }
        return {"pairs": pairs, "shapes": shapes, "joints": joints}


def _plant_axis(scene):
    """Tilt every joint's axis by 0.01 rad."""
    for j in scene.sc.joints:
        dj = scene.joints[j.body_a]
        a = np.asarray(dj.getAxis(), dtype=float)
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        dj.setAxis(a + 0.01 * across / np.linalg.norm(across))


def _plant_mu(scene):
    for sn in scene.shapes.values():
        sn.getDynamicsAspect().setFrictionCoeff(1.0)


def _plant_offset(scene):
    b = scene.sc.bodies[0]
    sn = scene.shapes[b.name]
    sn.setRelativeTransform(
        _iso(scene.dart, b.shape.rotation, b.shape.position + np.array([0.0, 0.0, 0.01]))
    )


PLANTABLE = {"mu not applied": _plant_mu, "shape offset": _plant_offset,
             "joint axis": _plant_axis}  # fmt: skip


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    from references.engines.contact import configuration as find

    dart = _import()
    conf = find("dart", configuration)
    sc = Scene(dart, scenario, conf, dt, settings)
    if _plant is not None:
        PLANTABLE[_plant](sc)
    w = sc.world
    names = [b.name for b in scenario.bodies]
    node_of = {}
    for name, sn in sc.shapes.items():
        node_of[sn.getName()] = name
    pidx = pair_index(scenario)
    forced = forced_bodies(scenario)
    nb = len(names)
    saved = SavedStates(nstep, save_every, nb)
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()

    def save(k, step):
        for i, n in enumerate(names):
            if n in sc.hinged:  # its body node's frame is its principal frame at the centre
                bn = sc.nodes[n]
                T = bn.getWorldTransform()
                X[k, i], R[k, i] = np.asarray(T.translation()), np.asarray(T.rotation())
                V[k, i] = np.asarray(bn.getCOMLinearVelocity())
                W[k, i] = R[k, i].T @ np.asarray(bn.getAngularVelocity())
                continue
            j = sc.joints[n]
            st = cv.dart_free_to_state(j.getPositions(), j.getVelocities())
            X[k, i], V[k, i], R[k, i], W[k, i] = (
                st.position,
                st.velocity,
                st.rotation,
                st.omega_body,
            )
        t[k] = step * dt
        if step > 0:
            for c in w.getLastCollisionResult().getContacts():
                n1 = node_of.get(c.collisionObject1.getShapeFrame().getName())
                n2 = node_of.get(c.collisionObject2.getShapeFrame().getName())
                pi = pidx.get(frozenset((n1, n2)))
                if pi is None:
                    continue
                f, nrm = np.asarray(c.force), np.asarray(c.normal)  # on 1; from 2 to 1
                if n1 != scenario.contacts[pi].a:
                    f, nrm = -f, -nrm
                log.add(pi, np.asarray(c.point), nrm, f, float(c.penetrationDepth))
        log.save()

    import tempfile

    from references.engines.dart.system import dart_warnings

    save(0, 0)
    engine = 0.0
    timing.stepping()  # the model is built: its construction is not the cost
    k = 1
    said = []  # what DART wrote to stderr (a failed LCP solve: impulses set to zero)
    capture = tempfile.TemporaryFile()
    for step in range(1, nstep + 1):
        for i in forced:
            bn = sc.nodes[names[i]]
            Rb = np.asarray(bn.getWorldTransform().rotation())
            F, tau = external_wrench(scenario, i, Rb)
            bn.setExtForce(F)
            bn.setExtTorque(tau)
        t0 = time.perf_counter()
        with dart_warnings(capture) as box:
            w.step()
        engine += timing.lap(t0)
        said += [m for m in box if m]
        if step % save_every == 0 or step == nstep:
            save(k, step)
            k += 1
            if not np.all(np.isfinite(X[k - 1])):
                break
    opt = conf.options
    record = {
        "solver": "BoxedLcpConstraintSolver",
        "boxed LCP primary": opt["primary"],
        "boxed LCP fallback": opt["secondary"] or "none",
        "collision detector": sc.cs.getCollisionDetector().getType(),
        "split impulse": bool(sc.cs.isSplitImpulseEnabled()),
        "planes": f"{GROUND_SIZE[0]:g} x {GROUND_SIZE[1]:g} x {GROUND_SIZE[2]:g} m static boxes",
        "friction per shape (pair: min)": {k: float(v) for k, v in sc.mu_set.items()},
        "restitution per shape (pair: product)": {k: float(v) for k, v in sc.e_set.items()},
        "deactivation (sleeping)": False,
        "LCP solves failed (impulses zeroed, DART's message)": sum(
            m.count("failed to find a solution") for m in said
        ),
        "stepping": "World.step (semi-implicit Euler)",
    }
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": record,
        "readback": sc.readback(),
    }
