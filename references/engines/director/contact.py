"""The director model's contact scheme (``director_model.contact``, issue 34): a nonsmooth
RATTLE in director coordinates with the exact Coulomb cone and Newton's impact law, the
suite's hard-contact reference integrator, run through its public API.

The scene maps one to one: each body a ``director_model.system.Body`` and each joint a
``director_model.system.Joint`` (the same fields; the system builder's ``model``), its
shape a ``Sphere``, ``Box``, ``Capsule`` or ``Cylinder`` (centred at the centre of mass with
the body's axes: a shape offset or rotation is unsupported, with that reason), each plane
``Plane.through(normal, point)``, each pair ``Pair(a, b, mu, e)``, each force
``PointForce(body, force, point)``. Pairs the scheme does not treat exactly it refuses with
the reason (``InvalidContactError``: an ``unsupported`` row), and a run that meets one stops
with ``ContactSolveError`` (an ``error`` row with the time and the pair).

Contacts: the scheme reports one resultant per pair (``pair_force``: the force on the pair's
body a in the step ending at the saved time), not per point. Each is logged as one row at the
pair's witness point: the shape's point nearest the plane for a plane pair, the midpoint of
the two centres of mass for a body pair, with the normal of the plane (from the second
body's centre towards the first's for a body pair), moved back by h v_G to where it stood
when the step began (the rows' convention, references.engines.contact). The scheme's own
law residuals (Signorini, Coulomb, maximum dissipation, each the largest since the last save)
and its solver diagnostics are recorded with the run.
"""

from __future__ import annotations

import time

import numpy as np

from references.engines import timing
from references.engines.contact import ContactLog
from references.engines.integrators import Integrator
from references.errors import EngineError, Unsupported

CONFIGURATIONS = (
    Integrator("nonsmooth RATTLE", "exact-cone hard contact", 2,
               "the director model's contact scheme: RATTLE with the exact Coulomb cone, "
               "Newton's impact law, non-penetration at the end of each step (order 2 in "
               "smooth phases, 1 through events)"),
)  # fmt: skip

SETTINGS = ()


def _api():
    try:
        import director_model.contact as dc
    except ImportError as exc:
        raise Unsupported(
            f"director_model.contact is not in this installation ({exc}): the director's "
            "contact scheme (issue 34) runs no contact scene here"
        ) from None
    return dc


def _shape(dc, b):
    s = b.shape
    if np.any(s.position != 0) or np.any(s.rotation != np.eye(3)):
        raise Unsupported(
            f"director: body {b.name!r}'s shape is offset or turned in the body; the director's "
            "shapes sit at the centre of mass with the body's axes"
        )
    if s.kind == "sphere":
        return dc.Sphere(s.radius)
    if s.kind == "box":
        return dc.Box(tuple(s.half_extents))
    if s.kind == "capsule":
        return dc.Capsule(s.radius, s.half_length)
    return dc.Cylinder(s.radius, s.half_length)


def scene_of(dc, sc):
    """The ``director_model.contact.ContactScene`` of the suite's scene ``sc``."""
    from references.engines.director.system import model

    bodies, joints = model(sc)  # the system's bodies and joints, field for field
    shapes = {b.name: _shape(dc, b) for b in sc.bodies if b.shape is not None}
    planes = {p.name: dc.Plane.through(tuple(p.normal), tuple(p.point)) for p in sc.planes}
    pairs = [dc.Pair(c.a, c.b, mu=c.mu, e=c.e) for c in sc.contacts]
    forces = [dc.PointForce(f.body, tuple(f.force), point=tuple(f.point)) for f in sc.forces]
    try:
        return dc.ContactScene(bodies, shapes=shapes, planes=planes, pairs=pairs, joints=joints,
                               forces=forces, gravity=tuple(sc.gravity))  # fmt: skip
    except dc.InvalidContactError as exc:
        raise Unsupported(f"director: {exc}") from None


#: the kernel's shape codes (``ContactScene.SH[:, 0]``)
_KINDS = {1: "sphere", 2: "box", 3: "capsule", 4: "cylinder"}


def readback(scene, sc) -> dict:
    """What the director's kernel steps with, from its own tables: each pair's mu and e
    (``PV``), each shape's kind and sizes (``SH``), and where each shape sits in its body,
    from the plane features the kernel tests (a box's eight vertices: their mean is the
    box's centre, their half range its half extents; a capsule's end spheres or a cylinder's
    rims at s e3: their mean s is the shift along e3; a sphere's feature is its centre, the
    centre of mass by the kernel's construction)."""
    from director_model.contact import _geometry as G

    pairs = {}
    for i, c in enumerate(sc.contacts):
        for j, names in enumerate(scene.pair_names):
            if set(_names(names)) == {c.a, c.b}:
                pairs[i] = {"mu": float(scene.PV[j, 0]), "e": float(scene.PV[j, 1])}
    names = [b.name for b in scene.bodies]
    FI, FV = np.asarray(scene.FI), np.asarray(scene.FV)
    shapes = {}
    for i, name in enumerate(names):
        code = int(scene.SH[i, 0])
        if code == 0:
            continue
        kind = _KINDS[code]
        size = {"box": scene.SH[i, 1:4], "sphere": scene.SH[i, 1:2]}.get(kind, scene.SH[i, 1:3])
        offset = np.zeros(3)
        mine = FI[:, 1] == i if len(FI) else np.zeros(0, bool)
        verts = FV[mine & (FI[:, 0] == G.K_PLANE_VERTEX), 4:7] if len(FI) else np.zeros((0, 3))
        ends = (
            FV[mine & np.isin(FI[:, 0], (G.K_PLANE_CAPSULE, G.K_PLANE_RIM)), 6] if len(FI) else ()
        )
        if kind == "box" and len(verts):
            offset = verts.mean(axis=0)
            size = 0.5 * (verts.max(axis=0) - verts.min(axis=0))
        elif kind in ("capsule", "cylinder") and len(ends):
            offset = np.array([0.0, 0.0, float(np.mean(ends))])
        shapes[name] = {"kind": kind, "size": tuple(float(x) for x in size),
                        "offset": tuple(float(x) for x in offset)}  # fmt: skip
    bodies = {b.name: b for b in sc.bodies}
    joints = {}
    for j in scene.joints:  # the joints the scheme holds, at the scene's initial pose
        b = bodies[j.body_a]
        axis = np.asarray(j.axis_a, dtype=float)
        joints[j.name] = {
            "kind": j.kind,
            "anchor": b.position + b.rotation @ np.asarray(j.anchor_a, dtype=float),
            "axis": b.rotation @ (axis / np.linalg.norm(axis)),
        }
    return {"pairs": pairs, "shapes": shapes, "joints": joints}


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene on the director's scheme; the contract of
    :mod:`references.engines.contact`."""
    from scenarios.contact import lowest_point

    dc = _api()
    if _plant == "joint axis":  # a mapping mistake: the scheme given tilted joint axes
        from references.engines.contact import tilted_joints

        scene = scene_of(dc, tilted_joints(scenario))
    else:
        scene = scene_of(dc, scenario)
    if _plant in PLANTABLE and callable(PLANTABLE[_plant]):
        PLANTABLE[_plant](scene)
    # the stepper compiles its kernel, or loads it from numba's cache, when it is built: a
    # run's cost is its stepping (timing.stepping), as a model's construction is not
    stepper = dc.ContactStepper(scene, dt=float(dt))
    timing.stepping()
    t0 = time.perf_counter()
    try:
        tr = stepper.advance(int(nstep), int(save_every), include_start=True)
    except dc.ContactSolveError as exc:
        raise EngineError(f"director: {exc}") from None
    wall = time.perf_counter() - t0
    timing.add(float(tr.wall_time_s), float(tr.cpu_time_s))  # the compiled run's own
    idx = {b.name: i for i, b in enumerate(scenario.bodies)}
    planes = {p.name: p for p in scenario.planes}
    log = ContactLog()
    F = np.asarray(tr.pair_force)
    order = [next(j for j, n in enumerate(tr.pair_names) if set(_names(n)) == {c.a, c.b})
             for c in scenario.contacts]  # fmt: skip
    for k in range(len(tr.t)):
        for i, c in enumerate(scenario.contacts):
            f = F[k, order[i]]
            if k == 0 or not np.any(f):
                continue
            a = idx[c.a]
            x, R = tr.position[k, a][None], tr.rotation[k, a][None]
            if c.b_is_plane:
                n = planes[c.b].normal
                p = lowest_point(scenario.bodies[a].shape, planes[c.b], x, R)[0]
            else:
                xb = tr.position[k, idx[c.b]]
                n = (x[0] - xb) / np.linalg.norm(x[0] - xb)
                p = 0.5 * (x[0] + xb)
            # rows stand where the contact was when the step began (the contract): the
            # witness point at the saved state, moved back by the step's h v_G
            log.add(i, p - float(dt) * tr.velocity[k, a], n, f, float(tr.penetration[k]))
        log.save()
    record = {
        "scheme": "nonsmooth RATTLE (director_model.contact)",
        "friction": "exact Coulomb cone, semi-smooth Newton to a certified residual",
        "largest law residuals": {k: float(np.max(getattr(tr, k)))
                                  for k in ("signorini", "coulomb", "dissipation")},
        "largest contact work in a step (J)": float(np.max(tr.contact_work)),
        "most solver iterations": int(np.max(tr.iterations)),
        "contact rows": "one resultant per pair at a witness point",
    }  # fmt: skip
    return {
        "t": tr.t, "x": tr.position, "R": tr.rotation, "v": tr.velocity, "W": tr.omega_body,
        "contacts": log.arrays(), "engine_time_s": min(float(tr.wall_time_s), wall),
        "settings": record, "readback": readback(scene, scenario),
    }  # fmt: skip


def _names(pair_name) -> tuple:
    """The two names of one of the scheme's ``pair_names`` entries (a pair or "a-b")."""
    if isinstance(pair_name, tuple | list):
        return tuple(pair_name)
    return tuple(str(pair_name).split("-", 1))


def _plant_mu(scene):
    """The pair table's friction coefficients set to 0 after the scene is built."""
    scene.PV[:, 0] = 0.0


def _plant_offset(scene):
    """The first body's plane features (a box's vertices, a capsule's or cylinder's ends)
    moved 0.01 m along its axis 3 after the scene is built: the kernel then steps a shape
    that is not where the scene puts it."""
    from director_model.contact import _geometry as G

    rows = np.asarray(scene.FI)[:, 1] == 0
    kinds = np.asarray(scene.FI)[:, 0]
    scene.FV[rows & (kinds == G.K_PLANE_VERTEX), 6] += 0.01
    scene.FV[rows & np.isin(kinds, (G.K_PLANE_CAPSULE, G.K_PLANE_RIM)), 6] += 0.01


#: the mistakes the conformance kit plants: in the kernel's tables after the scene is built,
#: or ('joint axis', None here) in the scene handed to the scheme
PLANTABLE = {"mu not applied": _plant_mu, "shape offset": _plant_offset, "joint axis": None}
