"""MuJoCo's contact: bodies on free joints with one geom each, the scene's planes as plane
geoms of the world body, and one explicit ``<pair>`` per scene pair (every geom has contype =
conaffinity = 0, so only the listed pairs collide; MuJoCo documentation, "XML Reference /
contact / pair"). A body on a revolute or prismatic joint to the ground (a system in contact)
gets a ``hinge`` or ``slide`` joint at the joint's anchor and axis in its frame instead of its
free joint, at qpos 0 (the model's pose is the scene's initial pose) and qvel the initial rate
about or along the axis; a joint between two bodies, or of another kind, is not built here
(``unsupported``, :func:`references.engines.contact.ground_joints`).

Each body's frame is its principal frame at its centre of mass (an explicit ``<inertial>``,
as in :mod:`.system`); its geom sits at the shape's offset and rotation. A pair has
``condim = 3`` (sliding friction only: the scenes have no rolling or torsional resistance),
``friction = mu mu 0 0 0``, margin 0, MuJoCo's default ``solimp`` and ``solref``
(0.02 s, damping ratio 1). MuJoCo has no restitution coefficient: a pair with e > 0 gets the
damping ratio of a linear spring-damper that rebounds at e, zeta = -ln e / sqrt(pi^2 + ln^2 e)
(an approximation: MuJoCo's impedance and its time step change the rebound), recorded as such.

Configurations: the friction cone (pyramidal, MuJoCo's default, or elliptic), ``impratio``
(1, the default, or 10, the grasping recipe of MuJoCo's documentation, "Preventing slip"),
``noslip_iterations`` (0 or 10; with the pyramidal cone it changed nothing in a check made
when this module was written), the Newton solver; the Euler integrator (MuJoCo's default).
``[engine_settings.mujoco]`` may set ``solver`` (Newton, CG, PGS), ``iterations``,
``tolerance``, ``solref``, ``solimp``, ``integrator`` for every configuration.

Contacts read after each step (they are those the step's collision found and its solver
loaded): ``d.contact[i]`` (``pos``, ``frame`` whose first row is the normal from geom1 to
geom2, ``dist`` < 0 when penetrating) and ``mj_contactForce`` (the force geom1 exerts on geom2
in that frame, normal first). Read back: ``pair_friction``, ``pair_solref``, geom types, sizes,
positions and orientations in their bodies, each joint's type, world anchor and axis at t = 0
(``xanchor``, ``xaxis``).
"""

from __future__ import annotations

import math
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
    joint_rate,
    pair_index,
)
from references.engines.integrators import Integrator
from references.errors import Unsupported

FAMILY = "soft convex contact"


def _conf(name, cone, impratio, noslip, default, text):
    return Integrator(
        name,
        FAMILY,
        1,
        text,
        default=default,
        options={"cone": cone, "impratio": impratio, "noslip_iterations": noslip},
    )


CONFIGURATIONS = (
    _conf(
        "pyramidal",
        "pyramidal",
        1.0,
        0,
        True,
        "MuJoCo's defaults: pyramidal cone, impratio 1, Newton solver, no noslip pass",
    ),
    _conf(
        "pyramidal impratio 10",
        "pyramidal",
        10.0,
        0,
        False,
        "pyramidal cone with friction 10x stiffer than the normal (impratio 10)",
    ),
    _conf("elliptic", "elliptic", 1.0, 0, False, "elliptic (Coulomb) cone, impratio 1"),
    _conf(
        "elliptic impratio 10",
        "elliptic",
        10.0,
        0,
        True,
        "elliptic cone, impratio 10: the grasping recipe of MuJoCo's documentation",
    ),
    _conf(
        "elliptic noslip 10",
        "elliptic",
        1.0,
        10,
        True,
        "elliptic cone, impratio 1, 10 noslip iterations (a post-pass removing slip)",
    ),
    _conf(
        "elliptic impratio 10 noslip 10",
        "elliptic",
        10.0,
        10,
        False,
        "elliptic cone, impratio 10, 10 noslip iterations",
    ),
)

SETTINGS = ("solver", "iterations", "tolerance", "solref", "solimp", "integrator")
_SOLVERS = ("Newton", "CG", "PGS")
_INTEGRATORS = ("Euler", "implicit", "implicitfast", "RK4")
_GEOM = {"sphere": "sphere", "box": "box", "capsule": "capsule", "cylinder": "cylinder"}
#: the MJCF joint type of each scene joint kind built here (to the ground)
_JOINT = {"revolute": "hinge", "prismatic": "slide"}
DEFAULT_SOLREF = (0.02, 1.0)


def _import():
    from references.engines.mujoco.system import _import as imp

    return imp()


def _num(a) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(a))


def damping_ratio(e: float) -> float:
    """The damping ratio of a linear spring-damper whose rebound speed is e times the impact's
    (e = exp(-zeta pi / sqrt(1 - zeta^2))); 1 (critical) for e = 0."""
    if e <= 0:
        return 1.0
    le = math.log(e)
    return -le / math.sqrt(math.pi**2 + le * le)


def _size(s) -> list:
    if s.kind == "box":
        return list(s.half_extents)
    if s.kind == "sphere":
        return [s.radius]
    return [s.radius, s.half_length]


def mjcf(scenario, conf, dt: float, settings: dict) -> str:
    """The model of the scene (module docstring)."""
    joints = ground_joints(scenario, "mujoco")
    opt = conf.options
    solver = settings.get("solver", "Newton")
    integ = settings.get("integrator", "Euler")
    if solver not in _SOLVERS:
        raise Unsupported(f"mujoco: solver {solver!r}; it takes {', '.join(_SOLVERS)}")
    if integ not in _INTEGRATORS:
        raise Unsupported(f"mujoco: integrator {integ!r}; it takes {', '.join(_INTEGRATORS)}")
    g = scenario.gravity
    parts = [
        "<mujoco>",
        f'<option timestep="{dt!r}" gravity="{_num(g)}" cone="{opt["cone"]}" '
        f'impratio="{opt["impratio"]!r}" noslip_iterations="{opt["noslip_iterations"]}" '
        f'solver="{solver}" integrator="{integ}" '
        f'iterations="{int(settings.get("iterations", 100))}" '
        f'tolerance="{float(settings.get("tolerance", 1e-8))!r}"/>',
        "<worldbody>",
    ]
    for p in scenario.planes:
        q = _quat_z_to(p.normal)
        parts.append(
            f'<geom name="plane:{p.name}" type="plane" size="0 0 1" pos="{_num(p.point)}"'
            f' quat="{_num(q)}" contype="0" conaffinity="0"/>'
        )
    for b in scenario.bodies:
        parts.append(
            f'<body name="{b.name}" pos="{_num(b.position)}" '
            f'quat="{_num(cv.matrix_to_quat_wxyz(b.rotation))}">'
        )
        j = joints.get(b.name)
        parts.append(
            f'<joint name="{j.name}" type="{_JOINT[j.kind]}" pos="{_num(j.anchor_a)}" '
            f'axis="{_num(j.axis_a)}"/>'
            if j is not None
            else "<freejoint/>"
        )
        parts.append(
            f'<inertial pos="0 0 0" quat="1 0 0 0" mass="{b.mass!r}" '
            f'diaginertia="{_num(b.inertia)}"/>'
        )
        s = b.shape
        if s is not None:
            q = cv.matrix_to_quat_wxyz(s.rotation)
            parts.append(
                f'<geom name="geom:{b.name}" type="{_GEOM[s.kind]}" size="{_num(_size(s))}"'
                f' pos="{_num(s.position)}" quat="{_num(q)}" contype="0" '
                'conaffinity="0" mass="0"/>'
            )
        parts.append("</body>")
    parts.append("</worldbody><contact>")
    solimp = settings.get("solimp")
    for c in scenario.contacts:
        g2 = f"plane:{c.b}" if c.b_is_plane else f"geom:{c.b}"
        ref = settings.get("solref") or (DEFAULT_SOLREF[0], damping_ratio(c.e))
        extra = f' solimp="{_num(solimp)}"' if solimp is not None else ""
        parts.append(
            f'<pair geom1="{g2}" geom2="geom:{c.a}" condim="3" '
            f'friction="{c.mu!r} {c.mu!r} 0 0 0" margin="0" gap="0" '
            f'solref="{_num(ref)}"{extra}/>'
        )
    parts.append("</contact></mujoco>")
    return "\n".join(parts)


def _quat_z_to(n) -> np.ndarray:
    """A quaternion (w first) turning +z onto the unit vector n."""
    n = np.asarray(n, dtype=float)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    s, c = float(np.linalg.norm(axis)), float(z @ n)
    if s < 1e-15:
        return np.array([1.0, 0.0, 0.0, 0.0]) if c > 0 else np.array([0.0, 1.0, 0.0, 0.0])
    ang = math.atan2(s, c)
    return np.concatenate([[math.cos(ang / 2)], math.sin(ang / 2) * axis / s])


def readback(mujoco, m, scenario) -> dict:
    """The model as MuJoCo compiled it: each pair's mu (pair_friction; e is not modelled) and
    solref, each body's geom type, size, position and axes in the body."""
    pairs = {}
    idx = pair_index(scenario)
    for k in range(m.npair):
        g1, g2 = int(m.pair_geom1[k]), int(m.pair_geom2[k])
        names = [
            mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g).split(":", 1)[1] for g in (g1, g2)
        ]
        i = idx.get(frozenset(names))
        if i is None:
            continue
        fr = m.pair_friction[k]
        pairs[i] = {"mu": float(fr[0]), "mu2": float(fr[1]), "solref": m.pair_solref[k].tolist()}
        if fr[0] != fr[1]:
            pairs[i]["mu"] = math.nan  # anisotropic: not the scene's
    kinds = {int(getattr(mujoco.mjtGeom, f"mjGEOM_{k.upper()}")): k for k in _GEOM}
    shapes = {}
    for b in scenario.bodies:
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"geom:{b.name}")
        if gid < 0:
            continue
        kind = kinds.get(int(m.geom_type[gid]), "other")
        size = m.geom_size[gid]
        size = tuple(size) if kind == "box" else (size[0],) if kind == "sphere" else tuple(size[:2])
        shapes[b.name] = {
            "kind": kind,
            "size": size,
            "offset": tuple(m.geom_pos[gid]),
            "rotation": cv.quat_wxyz_to_matrix(m.geom_quat[gid]),
        }
    return {"pairs": pairs, "shapes": shapes, "joints": read_joints(mujoco, m, scenario)}


def read_joints(mujoco, m, scenario) -> dict:
    """Each scene joint as the model holds it at qpos0 (the scene's initial pose): its kind,
    world anchor and axis (``xanchor``, ``xaxis`` after ``mj_kinematics``)."""
    if not scenario.joints:
        return {}
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    kinds = {int(mujoco.mjtJoint.mjJNT_HINGE): "revolute", int(mujoco.mjtJoint.mjJNT_SLIDE):
             "prismatic"}  # fmt: skip
    out = {}
    for j in scenario.joints:
        jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j.name)
        if jid < 0:
            continue
        out[j.name] = {
            "kind": kinds.get(int(m.jnt_type[jid]), "other"),
            "anchor": d.xanchor[jid].copy(),
            "axis": d.xaxis[jid].copy(),
        }
    return out


def _plant_mu(mujoco, m):
    m.pair_friction[:, :2] = 1.0


def _plant_offset(mujoco, m):
    m.geom_pos[m.ngeom - 1] += np.array([0.0, 0.0, 0.01])


def _plant_axis(mujoco, m):
    """Tilt every joint's axis by 0.01 rad (about an axis across it)."""
    for k in range(m.njnt):
        a = np.array(m.jnt_axis[k], float)
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        a = a + 0.01 * across / np.linalg.norm(across)
        m.jnt_axis[k] = a / np.linalg.norm(a)


#: mistakes the conformance kit plants after the model is compiled; the read-back must see them
PLANTABLE = {"mu not applied": _plant_mu, "shape offset": _plant_offset,
             "joint axis": _plant_axis}  # fmt: skip


def set_initial_state(mujoco, m, d, scenario, bid) -> None:
    """The scene's initial state in ``d``: a free body's position, attitude and velocities,
    a body on a ground joint its rate about or along the joint (qpos 0: the model's pose is
    the scene's); ``bid``: the scene bodies' MuJoCo body ids."""
    joints = ground_joints(scenario, "mujoco")
    for i, b in enumerate(scenario.bodies):
        jadr = m.body_jntadr[bid[i]]
        qa, va = m.jnt_qposadr[jadr], m.jnt_dofadr[jadr]
        if b.name in joints:
            d.qpos[qa], d.qvel[va] = 0.0, joint_rate(b, joints[b.name])
            continue
        qpos, qvel = cv.mujoco_free_from_state(b.position, b.velocity, b.rotation, b.omega_body)
        d.qpos[qa : qa + 7] = qpos
        d.qvel[va : va + 6] = qvel


def read_bodies(mujoco, m, d, scenario, bid, X, R, V, W) -> None:
    """The scene bodies' centres, attitudes, velocities (world) and body rates (body axes)
    from ``d`` into the arrays of one saved step (each (nb, ...)); a free body's from its
    qvel, a body on a ground joint's from ``mj_objectVelocity`` at its centre of mass."""
    mujoco.mj_kinematics(m, d)
    if scenario.joints:  # the velocities of the state saved (mj_objectVelocity reads cvel)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
    vel6 = np.zeros(6)
    for i in range(len(scenario.bodies)):
        j = bid[i]
        X[i] = d.xipos[j]
        R[i] = d.ximat[j].reshape(3, 3)
        jadr = m.body_jntadr[j]
        if int(m.jnt_type[jadr]) != int(mujoco.mjtJoint.mjJNT_FREE):  # (rotation, translation)
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, j, vel6, 0)
            V[i] = vel6[3:]
            W[i] = R[i].T @ vel6[:3]
            continue
        va = m.jnt_dofadr[jadr]
        V[i] = d.qvel[va : va + 3]
        W[i] = d.qvel[va + 3 : va + 6]


def settings_record(m, conf, settings) -> dict:
    """Every option that changes the contact physics, read from the compiled model."""
    opt = m.opt
    return {
        "cone": "elliptic" if int(opt.cone) == 1 else "pyramidal",
        "impratio": float(opt.impratio),
        "noslip_iterations": int(opt.noslip_iterations),
        "noslip_tolerance": float(opt.noslip_tolerance),
        "solver": ("PGS", "CG", "Newton")[int(opt.solver)],
        "iterations": int(opt.iterations),
        "tolerance": float(opt.tolerance),
        "integrator": ("Euler", "RK4", "implicit", "implicitfast")[int(opt.integrator)],
        "pair condim": sorted({int(c) for c in m.pair_dim}),
        "pair solref": [list(map(float, r)) for r in m.pair_solref],
        "pair solimp": [list(map(float, r)) for r in m.pair_solimp],
        "pair margin": sorted({float(x) for x in m.pair_margin}),
        "restitution": "not modelled: e > 0 mapped to solref's damping ratio "
        "-ln e/sqrt(pi^2 + ln^2 e) (linear spring-damper), e = 0 to 1",
        "disableflags": int(opt.disableflags),
        "enableflags": int(opt.enableflags),
    }


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """Run the scene (module docstring); the contract of :mod:`references.engines.contact`."""
    from references.engines.contact import configuration as find

    mujoco = _import()
    conf = find("mujoco", configuration)
    m = mujoco.MjModel.from_xml_string(mjcf(scenario, conf, dt, settings))
    if _plant is not None:
        PLANTABLE[_plant](mujoco, m)
    d = mujoco.MjData(m)
    bid = {
        i: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b.name)
        for i, b in enumerate(scenario.bodies)
    }
    set_initial_state(mujoco, m, d, scenario, bid)
    mujoco.mj_forward(m, d)
    geom_body = {}
    for b in scenario.bodies:
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"geom:{b.name}")
        geom_body[gid] = b.name
    pidx = pair_index(scenario)
    names = {
        g: (geom_body.get(g) or mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g).split(":", 1)[1])
        for g in range(m.ngeom)
    }
    forced = forced_bodies(scenario)
    saved = SavedStates(nstep, save_every, len(scenario.bodies))
    t, X, R, V, W = saved.t, saved.x, saved.R, saved.v, saved.W
    log = ContactLog()
    f6 = np.zeros(6)

    def save(k, step):
        read_bodies(mujoco, m, d, scenario, bid, X[k], R[k], V[k], W[k])
        t[k] = step * dt
        for c in range(d.ncon):
            con = d.contact[c]
            if con.efc_address < 0:  # found but not in the constraint problem: no force
                continue
            g1, g2 = int(con.geom1), int(con.geom2)
            pi = pidx.get(frozenset((names[g1], names[g2])))
            if pi is None:
                continue
            mujoco.mj_contactForce(m, d, c, f6)
            fr = np.asarray(con.frame).reshape(3, 3)
            f = fr.T @ f6[:3]  # on geom2, world
            n = fr[0]
            if names[g2] != scenario.contacts[pi].a:
                f, n = -f, -n
            log.add(pi, con.pos.copy(), n, f, -float(con.dist))
        log.save()

    save(0, 0)
    engine = 0.0
    timing.stepping()  # the model is built: its construction is not the cost
    k = 1
    for step in range(1, nstep + 1):
        for i in forced:
            F, tau = external_wrench(scenario, i, d.xmat[bid[i]].reshape(3, 3))
            d.xfrc_applied[bid[i], :3] = F
            d.xfrc_applied[bid[i], 3:] = tau
        t0 = time.perf_counter()
        mujoco.mj_step(m, d)
        engine += timing.lap(t0)
        if step % save_every == 0 or step == nstep:
            save(k, step)
            k += 1
            if not np.all(np.isfinite(d.qpos)):
                break
    return {
        **saved.fields(k),
        "contacts": log.arrays(),
        "engine_time_s": engine,
        "settings": settings_record(m, conf, settings),
        "readback": readback(mujoco, m, scenario),
    }
