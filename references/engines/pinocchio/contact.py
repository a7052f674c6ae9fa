"""Pinocchio's contact (4.x): its ``ADMMConstraintSolver`` and ``PGSConstraintSolver`` on its
Delassus operator, in the suite's time-stepping loop ("+ suite": Pinocchio has no contact time
stepper of its own in the installed release).

Model: one ``JointModelFreeFlyer`` per body (q = [x, quaternion xyzw], v = [R^T v, W] in the
LOCAL frame), the body's principal frame at the joint (``Inertia(m, 0, diag(I))``), or for a
body on a revolute or prismatic joint to the ground a ``JointModelRevoluteUnaligned`` or
``JointModelPrismaticUnaligned`` placed at the anchor with the body's initial axes (q = 0 the
scene's initial pose, the centre of mass at -anchor_a in the joint frame, q += h q' in the
step; read back: the joint's kind, world anchor and axis); one coal
shape per body (``Sphere``, ``Box`` of full sides, ``Capsule`` and ``Cylinder`` of full
length) at the shape's offset, the scene's planes as coal ``Halfspace`` on the universe, one
collision pair per scene pair.

One step from (q, v), h (a Moreau-Jean step, written here from Pinocchio's calls):

1. v_free = v + h a(q, v), a = aba(q, v, 0, f_ext) made classical (:func:`classical`; the
   scene's forces as LOCAL joint forces);
2. contacts: ``computeCollisions`` with a security margin (``margin``, default 1 cm) and
   ``computeContactPatches`` (coal's patches: up to 4 points per patch by default); each
   point a ``PointContactConstraintModel`` between the pair's b (joint 1) and a (joint 2) with
   its frame's z along the normal from b into a, ``setFriction(mu)`` (Coulomb's cone);
3. the Delassus operator G of ``ConstraintCholeskyDecomposition`` (regularised by
   ``compliance`` 1e-10), the drift g = J v_free, and on each normal row (v_n the normal
   velocity before the step): where the contact touches or closes within the step,
   gap + h v_n <= 0, Newton's impact law e min(v_n, 0) plus min(gap, 0)/h (a penetration
   pushed out in one step); else gap/h (a contact ahead may close its gap, not cross it);
4. impulses lambda from ``ADMMConstraintSolver.solve`` or ``PGSConstraintSolver.solve``
   (``solve_ncp`` on: De Saxce's correction, the maximum-dissipation law, not the convex
   relaxation), tolerances ``tolerance`` (default 1e-10) absolute and relative on feasibility
   and complementarity, at most ``max_iterations`` (1000 ADMM, 1000 PGS);
5. v+ = v_free + M^-1 J^T lambda (``computeMinverse``); q+ on SO(3) x R^3
   (:func:`step_positions`: not Pinocchio's SE(3) ``integrate``, whose coupling of
   translation and rotation pushes a spinning body into the ground).

Forces reported: lambda/h per point (the mean force over the step) in world axes on the pair's
body a. Engine time: the Pinocchio and coal calls; the loop and the constraint set-up are ours.
"""

from __future__ import annotations

import functools
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
)
from references.engines.integrators import Integrator
from references.errors import EngineError

FAMILY = "Delassus NCP + suite"

CONFIGURATIONS = (
    Integrator(
        "ADMM + suite",
        FAMILY,
        1,
        "Pinocchio's ADMMConstraintSolver (NCP, De Saxce) on its Delassus operator in "
        "the suite's Moreau-Jean loop",
        ours=True,
        options={"solver": "ADMM"},
    ),
    Integrator(
        "PGS + suite",
        FAMILY,
        1,
        "Pinocchio's PGSConstraintSolver (NCP) on its Delassus operator in the suite's "
        "Moreau-Jean loop",
        ours=True,
        options={"solver": "PGS"},
        default=False,  # the default suite runs ADMM: a second Python loop costs ~20 s there
    ),
)

SETTINGS = ("tolerance", "max_iterations", "margin", "compliance", "solve_ncp", "patch_points")
DEFAULTS = {
    "tolerance": 1e-10,
    "max_iterations": 1000,
    "margin": 1e-2,
    "compliance": 1e-10,
    "solve_ncp": True,
    "patch_points": 4,
}


def _import():
    from references.engines.native import import_engine

    pin = import_engine("pinocchio", "Pinocchio", "pin")
    import coal

    return pin, coal


def _coal_shape(coal, s):
    if s.kind == "sphere":
        return coal.Sphere(s.radius)
    if s.kind == "box":
        return coal.Box(*(2.0 * np.asarray(s.half_extents)))
    if s.kind == "capsule":
        return coal.Capsule(s.radius, 2.0 * s.half_length)
    return coal.Cylinder(s.radius, 2.0 * s.half_length)


def _frame(nz) -> np.ndarray:
    """An orthonormal frame whose third column is the unit vector nz."""
    t = np.array([1.0, 0.0, 0.0]) if abs(nz[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = t - nz * (t @ nz)
    ex /= np.linalg.norm(ex)
    R = np.empty((3, 3))
    R[:, 0], R[:, 1], R[:, 2] = ex, _cross(nz, ex), nz
    return R


def _cross(a, b) -> list[float]:
    """a x b of two 3-vectors, written out: the products and differences ``np.cross``
    computes, in its order (bit for bit), without its ~5 us of array handling."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return [a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0]


class Scene:
    """The Pinocchio and coal objects of a scene."""

    def __init__(self, pin, coal, scenario, settings):
        self.pin, self.coal, self.sc = pin, coal, scenario
        self.model = pin.Model()
        self.model.gravity.linear = np.asarray(scenario.gravity, dtype=float)
        self.jid = {}
        # a body on a revolute or prismatic joint to the ground: its joint frame at the anchor
        # with the body's initial axes (q = 0: the scene's initial pose), its centre of mass
        # at -anchor_a in it; name -> (anchor_a, unit axis in the body, initial rate)
        self.hinge = {}
        self.sliding = set()  # the bodies on a prismatic joint
        for name, j in ground_joints(scenario, "pinocchio").items():
            b = next(b for b in scenario.bodies if b.name == name)
            axis = np.asarray(j.axis_a, dtype=float) / np.linalg.norm(j.axis_a)
            self.hinge[name] = (np.asarray(j.anchor_a, dtype=float), axis, joint_rate(b, j))
            if j.kind == "prismatic":
                self.sliding.add(name)
        for b in scenario.bodies:
            if b.name in self.hinge:
                lever, axis, _ = self.hinge[b.name]
                hj = next(j for j in scenario.joints if j.body_a == b.name)
                kind = (pin.JointModelPrismaticUnaligned if b.name in self.sliding
                        else pin.JointModelRevoluteUnaligned)  # fmt: skip
                j = self.model.addJoint(0, kind(axis),
                                        pin.SE3(b.rotation, joint_anchor_world(b, hj)),
                                        b.name)  # fmt: skip
                com = -lever
            else:
                j = self.model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), b.name)
                com = np.zeros(3)
            self.model.appendBodyToJoint(
                j, pin.Inertia(b.mass, com, np.diag(b.inertia)), pin.SE3.Identity()
            )
            self.jid[b.name] = j
        self.iq = [self.model.joints[self.jid[b.name]].idx_q for b in scenario.bodies]
        self.iv = [self.model.joints[self.jid[b.name]].idx_v for b in scenario.bodies]
        self.gm = pin.GeometryModel()
        self.gid = {}
        for b in scenario.bodies:
            if b.shape is None:
                continue
            s = b.shape
            obj = pin.GeometryObject(
                f"geom:{b.name}",
                self.jid[b.name],
                self.jid[b.name],
                pin.SE3(s.rotation, s.position - self._com_offset(b.name)),
                _coal_shape(coal, s),
            )
            self.gid[b.name] = self.gm.addGeometryObject(obj)
        for p in scenario.planes:
            hs = coal.Halfspace(np.asarray(p.normal, dtype=float), p.offset)
            obj = pin.GeometryObject(f"plane:{p.name}", 0, 0, pin.SE3.Identity(), hs)
            self.gid[p.name] = self.gm.addGeometryObject(obj)
        self.pairs = []
        for i, c in enumerate(scenario.contacts):
            self.gm.addCollisionPair(pin.CollisionPair(self.gid[c.a], self.gid[c.b]))
            self.pairs.append(i)
        self.data = self.model.createData()
        self.gd = self.gm.createData()
        for req in self.gd.collisionRequests:
            req.security_margin = float(settings["margin"])
            # Pinocchio's requests leave it off; then coal gave NaN normals for two boxes
            # touching face to face (the stack) in a check made when this was written
            req.enable_contact = True
        for req in self.gd.contactPatchRequests:
            req.max_num_patch = 1
        self.npatch = int(settings["patch_points"])

    def _com_offset(self, name) -> np.ndarray:
        """The body's centre of mass in its joint's frame, times -1 (a free flyer's frame
        is at the centre of mass; a hinged body's at its hinge, anchor_a from it)."""
        return self.hinge[name][0] if name in self.hinge else np.zeros(3)

    def free(self) -> list[int]:
        """The indices of the bodies on free flyers."""
        return [i for i, b in enumerate(self.sc.bodies) if b.name not in self.hinge]

    def q_v(self):
        q, v = [], []
        for b in self.sc.bodies:
            if b.name in self.hinge:
                q.append(0.0)
                v.append(self.hinge[b.name][2])
                continue
            q += [*b.position, *cv.matrix_to_quat_xyzw(b.rotation)]
            v += [*(b.rotation.T @ b.velocity), *b.omega_body]
        return np.array(q), np.array(v)

    def states(self, q, v):
        nb = len(self.sc.bodies)
        x, R, vv, W = np.zeros((nb, 3)), np.zeros((nb, 3, 3)), np.zeros((nb, 3)), np.zeros((nb, 3))
        for i, b in enumerate(self.sc.bodies):
            if b.name in self.sliding:  # x = H + R0 (q axis - anchor_a), R = R0
                lever, axis, _ = self.hinge[b.name]
                oMj = self.model.jointPlacements[self.jid[b.name]]
                R[i] = oMj.rotation
                x[i] = oMj.translation + R[i] @ (axis * q[self.iq[i]] - lever)
                vv[i] = R[i] @ axis * v[self.iv[i]]
                continue
            if b.name in self.hinge:  # x = H + R (-anchor_a), R = R0 exp(q axis)
                lever, axis, _ = self.hinge[b.name]
                oMj = self.model.jointPlacements[self.jid[b.name]]
                R[i] = oMj.rotation @ self.pin.exp3(axis * q[self.iq[i]])
                x[i] = oMj.translation - R[i] @ lever
                W[i] = axis * v[self.iv[i]]
                vv[i] = np.cross(R[i] @ W[i], x[i] - oMj.translation)
                continue
            qi, vi = q[self.iq[i] : self.iq[i] + 7], v[self.iv[i] : self.iv[i] + 6]
            x[i] = qi[:3]
            R[i] = cv.quat_xyzw_to_matrix(qi[3:])
            vv[i] = R[i] @ vi[:3]
            W[i] = vi[3:]
        return x, R, vv, W

    def readback(self) -> dict:
        pin = self.pin
        shapes = {}
        for b in self.sc.bodies:
            if b.name not in self.gid:
                continue
            obj = self.gm.geometryObjects[self.gid[b.name]]
            g = obj.geometry
            name = type(g).__name__.lower()
            if name == "box":
                size = tuple(np.asarray(g.halfSide))
            elif name == "sphere":
                size = (g.radius,)
            else:
                size = (g.radius, g.halfLength)
            if obj.parentJoint != self.jid[b.name]:
                raise EngineError(f"pinocchio: {b.name!r}'s shape hangs on another joint")
            shapes[b.name] = {
                "kind": name,
                "size": size,
                "offset": tuple(obj.placement.translation + self._com_offset(b.name)),
                "rotation": np.asarray(obj.placement.rotation),
            }
        pairs = {i: {"mu": self.mu[i], "e": self.e[i]} for i in self.pairs}
        joints = {}
        for j in self.sc.joints:
            jid = self.jid[j.body_a]
            jm, oMj = self.model.joints[jid], self.model.jointPlacements[jid]
            name = jm.shortname()
            joints[j.name] = {
                "kind": "prismatic"
                if "Prismatic" in name
                else "revolute"
                if "Revolute" in name
                else name,
                "anchor": np.asarray(oMj.translation),
                "axis": np.asarray(oMj.rotation) @ np.asarray(jm.extract().axis),
            }
        del pin
        return {"pairs": pairs, "shapes": shapes, "joints": joints}


def _plant_mu(scene):
    scene.mu = {i: 0.0 for i in scene.mu}


def _plant_offset(scene):
    obj = scene.gm.geometryObjects[0]
    obj.placement = scene.pin.SE3(
        obj.placement.rotation, obj.placement.translation + np.array([0.0, 0.0, 0.01])
    )


def _plant_axis(scene):
    """Every ground joint's axis tilted by 0.01 rad, in the model (and its data)."""
    pin = scene.pin
    for j in scene.sc.joints:
        jid = scene.jid[j.body_a]
        a = np.asarray(scene.model.joints[jid].extract().axis, dtype=float)
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        a = a + 0.01 * across / np.linalg.norm(across)
        kind = (pin.JointModelPrismaticUnaligned if j.body_a in scene.sliding
                else pin.JointModelRevoluteUnaligned)  # fmt: skip
        jm = kind(a / np.linalg.norm(a))
        jm.setIndexes(jid, scene.model.joints[jid].idx_q, scene.model.joints[jid].idx_v)
        scene.model.joints[jid] = jm
    scene.data = scene.model.createData()


PLANTABLE = {"mu not applied": _plant_mu, "shape offset": _plant_offset,
             "joint axis": _plant_axis}  # fmt: skip


def classical(a, v, starts):
    """Pinocchio's free-flyer acceleration (the derivative of the LOCAL twist, whose linear
    part turns with the body: a_lin = R^T a_G - W x v_lin) as the centre of mass's classical
    acceleration in body axes, R^T a_G = a_lin + W x v_lin, so that the step below keeps
    the world velocity of a body in free flight whatever its spin; ``starts``: the free
    flyers' first velocity index (a hinge's rate needs no correction)."""
    a = np.array(a, dtype=float)
    for s in starts:
        vi, ai = v[s : s + 6], a[s : s + 6]
        ai[:3] += _cross(vi[3:], vi[:3])
    return a


def _symmetric(M) -> np.ndarray:
    """The symmetric matrix of M's upper triangle (computeMinverse fills only that one):
    ``np.triu(M) + np.triu(M, 1).T`` bit for bit (every entry x + 0.0, which turns a -0.0
    into 0.0), without the two triu's ~10 us."""
    S = np.array(M, dtype=float)
    il = _lower(len(S))
    S[il] = S.T[il]
    S += 0.0
    return S


@functools.cache
def _lower(n: int):
    """The indices of the strict lower triangle of an n x n matrix (np.tril_indices builds
    them from a mask: ~10 us a call)."""
    return np.tril_indices(n, -1)


def step_positions(pin, q, v, h, free, hinges=()):
    """q+ from v+ on SO(3) x R^3 (each body: x += h R v_lin, R <- R exp(h W)), keeping the
    world velocity (v_lin <- R+^T R v_lin). Pinocchio's ``integrate`` on a free flyer is the
    SE(3) exponential, which moves a spinning body's centre along a screw during the step
    (a ball rolling at 1.6 m/s and 16 rad/s dips 1.3e-5 m per step at h = 1e-3, which the
    contact pushes back, feeding energy in: 7 % speed gained in 0.4 s in a check made here);
    the suite's loop uses the decoupled update of the engines."""
    q = q.copy()
    v = v.copy()
    for iq, iv in hinges:  # a hinge's angle: q += h q'
        q[iq] += h * v[iv]
    for iq, iv in free:
        qi, vi = q[iq : iq + 7], v[iv : iv + 6]
        R = cv.quat_xyzw_to_matrix(qi[3:])
        vw = R @ vi[:3]
        Rn = R @ pin.exp3(h * vi[3:])
        qi[:3] = qi[:3] + h * vw
        quat = cv.matrix_to_quat_xyzw(Rn)
        qi[3:] = quat / np.linalg.norm(quat)
        vi[:3] = cv.quat_xyzw_to_matrix(qi[3:]).T @ vw
    return q, v


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    from references.engines.contact import configuration as find

    pin, coal = _import()
    conf = find("pinocchio", configuration)
    st = {**DEFAULTS, **settings}
    sc = Scene(pin, coal, scenario, st)
    sc.mu = {i: float(c.mu) for i, c in enumerate(scenario.contacts)}
    sc.e = {i: float(c.e) for i, c in enumerate(scenario.contacts)}
    if _plant is not None:
        PLANTABLE[_plant](sc)
    model, data, gm, gd = sc.model, sc.data, sc.gm, sc.gd
    q, v = sc.q_v()
    h = float(dt)
    nb = len(scenario.bodies)
    free = [(sc.iq[i], sc.iv[i]) for i in sc.free()]
    hinged = [(sc.iq[i], sc.iv[i]) for i in range(nb) if i not in sc.free()]
    names = [b.name for b in scenario.bodies]
    forced = forced_bodies(scenario)
    admm = conf.options["solver"] == "ADMM"
    if admm:
        settings_obj = pin.ADMMSolverSettings()
    else:
        settings_obj = pin.PGSSolverSettings()
    tol = float(st["tolerance"])
    for k in (
        "absolute_feasibility_tol",
        "relative_feasibility_tol",
        "absolute_complementarity_tol",
        "relative_complementarity_tol",
    ):
        setattr(settings_obj, k, tol)
    settings_obj.max_iterations = int(st["max_iterations"])
    settings_obj.solve_ncp = bool(st["solve_ncp"])
    saved = SavedStates(nstep, save_every, nb)
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()
    stats = {"solves": 0, "not converged": 0, "iterations max": 0, "contacts max": 0}
    engine = 0.0
    timing.stepping()  # the model is built: its construction is not the cost

    def save(k, step):
        X[k], R[k], V[k], W[k] = sc.states(q, v)
        t[k] = step * h
        log.save()

    save(0, 0)
    k = 1
    zero = [pin.Force.Zero() for _ in range(model.njoints)]
    for step in range(1, nstep + 1):
        fext = list(zero)
        if forced:
            xs, Rs, _, _ = sc.states(q, v)
            for i in forced:
                F, tau = external_wrench(scenario, i, Rs[i])
                # about the joint frame's origin (a hinged body's is at the hinge)
                c = -sc._com_offset(names[i])
                Fb, tb = Rs[i].T @ F, Rs[i].T @ tau
                fext[sc.jid[names[i]]] = pin.Force(Fb, tb + _cross(c, Fb))
        fext = pin.StdVec_Force(fext)
        tau0 = np.zeros(model.nv)
        # the stopwatch around Pinocchio's and coal's calls only, not the suite's arithmetic
        # between them (classical, the symmetric M^-1, the velocity update)
        t0 = time.perf_counter()
        a = pin.aba(model, data, q, v, tau0, fext)
        engine += timing.lap(t0)
        vfree = v + h * classical(a, v, [s for _, s in free])
        t0 = time.perf_counter()
        pin.forwardKinematics(model, data, q, v)
        pin.updateGeometryPlacements(model, data, gm, gd)
        pin.computeCollisions(gm, gd, False)
        pin.computeContactPatches(gm, gd)
        engine += timing.lap(t0)
        cms = pin.StdVec_ConstraintModel()
        rows = []  # (pair, point, frame, gap)
        for cp, pi in enumerate(sc.pairs):
            res, pr = gd.collisionResults[cp], gd.contactPatchResults[cp]
            if not res.isCollision() or pr.numContactPatches() == 0:
                continue
            patch = pr.getContactPatch(0)
            c = scenario.contacts[pi]
            nz = -np.asarray(patch.getNormal())  # coal: from a (shape 1) to b; ours: b into a
            if not np.all(np.isfinite(nz)):
                raise EngineError(
                    f"pinocchio: coal gave the pair {c.a!r}-{c.b!r} a non-finite "
                    f"contact normal at t = {(step - 1) * h:.6g} s"
                )
            Rc = _frame(nz)
            gap = float(patch.penetration_depth)  # coal: the signed distance (< 0 overlapping)
            npts = patch.size()
            pts = [np.asarray(patch.getPoint(j)) for j in range(npts)]
            if npts > sc.npatch:  # keep npatch points spread over the patch
                sel = np.linspace(0, npts, sc.npatch, endpoint=False).astype(int)
                pts = [pts[j] for j in sel]
            ja = sc.jid[c.a]
            jb = 0 if c.b_is_plane else sc.jid[c.b]
            for p in pts:
                oMa = data.oMi[ja]
                pa = pin.SE3(oMa.rotation.T @ Rc, oMa.rotation.T @ (p - oMa.translation))
                if jb == 0:
                    pb = pin.SE3(Rc, p.copy())
                else:
                    oMb = data.oMi[jb]
                    pb = pin.SE3(oMb.rotation.T @ Rc, oMb.rotation.T @ (p - oMb.translation))
                cm = pin.PointContactConstraintModel(model, jb, pb, ja, pa)
                cm.setFriction(sc.mu[pi])
                cms.append(pin.ConstraintModel(cm))
                rows.append((pi, p, Rc, gap))
        if rows:
            t0 = time.perf_counter()
            cds = pin.StdVec_ConstraintData()
            for cm in cms:
                cds.append(cm.createData())
            for cm, cd in zip(cms, cds, strict=True):
                cm.calc(model, data, cd)
            pin.crba(model, data, q, pin.Convention.WORLD)
            chol = pin.ConstraintCholeskyDecomposition(model, data, cms, cds)
            chol.compute(model, data, cms, cds, float(st["compliance"]))
            G = chol.getDelassusOperatorCholeskyExpression().matrix()
            J = pin.getConstraintsJacobian(model, data, cms, cds)
            engine += timing.lap(t0)
            # eigenpy returns a one-column matrix (a hinge alone: nv = 1) as a vector
            J = np.asarray(J).reshape(-1, model.nv)
            g = J @ vfree
            vn = (J @ v)[2::3]
            for r, (pi, _p, _Rc, gap) in enumerate(rows):
                if gap + h * vn[r] <= 0.0:  # touching, or closing within the step: Newton
                    g[3 * r + 2] += sc.e[pi] * min(vn[r], 0.0) + min(gap, 0.0) / h
                else:  # ahead: it may close its gap, not cross it
                    g[3 * r + 2] += gap / h
            t0 = time.perf_counter()
            solver = (pin.ADMMConstraintSolver if admm else pin.PGSConstraintSolver)(len(g))
            result = pin.ADMMSolverResult() if admm else pin.PGSSolverResult()
            ok = solver.solve(pin.DelassusOperatorDense(G), g, cms, cds, settings_obj, result)
            lam = np.asarray(result.retrieveConstraintImpulses())
            Minv = np.asarray(pin.computeMinverse(model, data, q)).reshape(model.nv, model.nv)
            engine += timing.lap(t0)
            Minv = _symmetric(Minv)
            v = vfree + Minv @ (J.T @ lam)
            stats["solves"] += 1
            stats["not converged"] += 0 if ok else 1
            stats["iterations max"] = max(stats["iterations max"], int(result.iterations))
            stats["contacts max"] = max(stats["contacts max"], len(rows))
        else:
            lam = np.zeros(0)
            v = vfree
        q, v = step_positions(pin, q, v, h, free, hinged)
        if step % save_every == 0 or step == nstep:
            for r, (pi, p, Rc, gap) in enumerate(rows):
                log.add(pi, p, Rc[:, 2], Rc @ lam[3 * r : 3 * r + 3] / h, -gap)
            save(k, step)
            k += 1
            if not np.all(np.isfinite(q)):
                break
    record = {
        "solver": conf.options["solver"] + "ConstraintSolver (Pinocchio), NCP"
        if st["solve_ncp"]
        else conf.options["solver"] + " (CCP: solve_ncp off)",
        "time stepping": "the suite's Moreau-Jean loop (Pinocchio has none for contact)",
        "tolerance": tol,
        "max_iterations": int(st["max_iterations"]),
        "security margin": float(st["margin"]),
        "Delassus compliance": float(st["compliance"]),
        "points per patch": sc.npatch,
        "normal rows": "gap + h v_n <= 0: e min(v_n, 0) + min(gap, 0)/h (Newton's impact law, "
        "penetration projected out); else gap/h",
        "collision": "coal computeCollisions (enable_contact on) + computeContactPatches",
        "solves not converged": stats["not converged"],
        "most iterations": stats["iterations max"],
    }
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": record,
        "readback": sc.readback(),
        "stats": stats,
    }
