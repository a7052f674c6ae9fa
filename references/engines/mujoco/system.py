"""MuJoCo builder for systems of rigid bodies: trees in reduced coordinates, loops closed by
MuJoCo's own soft ``equality connect``.

Input: a system scenario with ``name``, ``gravity`` (3,), ``bodies`` (each with ``name, mass,
inertia`` (principal moments about the COM), ``position`` (COM, world), ``rotation`` (body to
world, columns = principal axes), ``velocity`` (COM, world), ``omega_body`` (body axes)) and
``joints`` (each with ``kind, body_a, body_b`` (None = ground), ``anchor_a, anchor_b`` (in each
body's principal frame relative to its COM; a world point for the ground), ``axis_a, axis_b``
(same frames), ``name``), the fields of ``director_model.system.Body`` and ``Joint``.

Spanning tree: the plan of every reduced-coordinate builder
(:func:`references.engines.reduced.plan`, :func:`plan`): the loop closures of
:func:`scenarios.tree.spanning_tree`, the other joints a tree grown from the ground, a body joined
to nothing a floating root with a ``free`` joint.

Frames. Every MuJoCo body frame IS the body's principal frame at its centre of mass: each body
has an explicit ``<inertial pos="0 0 0" quat="1 0 0 0" mass diaginertia>`` (no inertia is
inferred from geoms; there are no geoms), so ``xipos``/``ximat`` are the COM and R, and a free
root's qpos/qvel are x_G, R, v_G (world) and W (body axes) directly. A tree joint sits at the
child's anchor Y (``jnt_pos`` = Y, child frame) and its axis is the child-frame axis
(``jnt_axis``); the body is placed in its parent's frame at ``X - R_ref Y`` (X: the parent's
anchor, in the parent's frame, or a world point) with orientation ``R_ref``:

==================  ====================  =============================================
scenario kind       MuJoCo joint          reference orientation R_ref, initial qpos/qvel
==================  ====================  =============================================
spherical,          ``ball``              identity; qpos = quaternion (w first) of
fixed_point                               R_p^T R_c, qvel = W_c - R_rel^T W_p (child axes)
revolute            ``hinge``             R_p^T R_c at t = 0; qpos = 0, qvel = n . w_rel
prismatic           ``slide``             R_p^T R_c at t = 0; qpos = the anchors' offset
                                          along the axis, qvel its rate
universal           two ``hinge``         R_p^T R_c at t = 0; the first about the
                                          parent-fixed axis, the second about the
                                          child-fixed one; qpos = 0, qvel = each axis . w_rel
cylindrical         ``hinge`` + ``slide`` R_p^T R_c at t = 0; both on the axis; as above
(floating root)     ``free``              body pos/quat = the initial x, R
==================  ====================  =============================================

Loop closures (MuJoCo documentation, "XML Reference / equality / connect"): a spherical joint
that closes a loop is one ``connect`` between two sites, one at each anchor (sites, not the
body form of ``connect``, whose second anchor MuJoCo computes from the reference configuration
qpos0, which here is not the initial configuration). A revolute closure is two connects, at the
anchors and at the anchors moved by ``ell`` (the system's length scale) along the hinge axis:
six equations for the five a hinge imposes (the one along the axis is redundant; MuJoCo's soft,
regularised constraints accept it). A universal closure is a connect at the anchors and a
spatial tendon between the points ``ell`` along each axis whose length an ``equality tendon``
holds at ``ell sqrt 2`` (the axes perpendicular: four equations for four). A prismatic or
cylindrical closure is unsupported (:data:`REFUSED_CLOSURES` says why). Connects and tendon
equalities are soft: ``solref`` (time constant, damping ratio) and ``solimp``, MuJoCo's
defaults unless given (``solref=(0.002, 1)`` for a stiffer loop); MuJoCo raises a time
constant below two time steps to two time steps (the ``refsafe`` rule, left on): the settings
record the requested and the effective value.

Checks before stepping: the initial world states must satisfy every joint (tree and loop) to
:data:`STATE_TOL` times the system's length scale (anchor gap, m) and rate scale (anchor slip,
m/s; axis misalignment, rad; relative rotation off a hinge axis), else
:class:`InconsistentSystem` names the joint and the residual (never projected). The compiled
model is read back (``body_parentid, body_mass, body_inertia, body_ipos, body_iquat, body_pos,
body_quat, jnt_type, jnt_pos, jnt_axis``, sites and ``eq_*``, every distorting default:
damping, armature, friction loss, stiffness, limits, gravity compensation, geoms, actuators,
contacts, sleep, the constraint override) and compared with the scenario; after the initial
state is set, MuJoCo's own kinematics (``xipos, ximat, xanchor, xaxis``, body velocities) must
reproduce every body's world state and every joint's anchors and axes from both sides. A
mismatch raises :class:`~references.errors.EngineError` naming the body or joint.

State read-out at the saved steps: ``mj_kinematics``, ``mj_comPos`` and ``mj_comVel`` on the current
qpos/qvel (after ``mj_step`` the derived fields describe the start of the step), then
``xipos``, ``ximat`` and ``mj_objectVelocity`` (body frame) per body. ``engine_time_s`` is the
time inside ``mj_step`` only.
"""

from __future__ import annotations

import math
import time

import numpy as np

from references import conventions as cv
from references.engines import reduced, timing
from references.engines.mujoco import forces
from references.engines.mujoco.mjcf import hold_distances, loop_points, mj_type, model_xml, parts
from references.engines.native import import_engine
from references.engines.reduced import saves as _saves
from references.engines.reduced import unit as _unit
from references.engines.reduced import vec as _vec
from references.engines.system import SystemResult
from references.errors import Diverged, EngineError, Unsupported
from scenarios.force_elements import has_elements

#: MuJoCo's integrators offered (``mjtIntegrator``); "discrete" only where MuJoCo has it
INTEGRATORS = {
    "Euler": "mjINT_EULER",
    "implicit": "mjINT_IMPLICIT",
    "implicitfast": "mjINT_IMPLICITFAST",
    "discrete": "mjINT_DISCRETE",
    "RK4": "mjINT_RK4",
}

#: MuJoCo's default solref and solimp of an equality constraint (MuJoCo documentation,
#: "Modeling / Solver parameters"; read back from a compiled model in the tests)
DEFAULT_SOLREF = (0.02, 1.0)
DEFAULT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)

#: The initial world states must satisfy each joint to this tolerance, relative to the
#: system's length scale (m) or rate scale (m/s, rad/s); the rule of
#: director_model.system's joints at t = 0 (1e-10) and of the reduced reference.
STATE_TOL = 1e-10

#: Read-back tolerance, relative to each quantity's scale: the compiled model holds the
#: doubles written into the MJCF (repr round-trips) up to MuJoCo's own arithmetic (quaternion
#: normalisation, a few operations of round-off each).
READBACK_TOL = 1e-12

#: MuJoCo's kinematics of the initial state against the scenario's world states, relative to
#: the length, rate and unit scales: each body's state goes through one product of rotations
#: and cross products per joint from the root (measured at most 5.4e-15 on the seven library
#: systems; the margin covers deeper chains, and every frame mistake is O(1))
INITIAL_TOL = 1e-11


class InconsistentSystem(EngineError):
    """The scenario's initial world states do not satisfy its joints (the residual is named):
    the state is never projected onto the joints by the builder."""


def _import():
    from references.engines.mujoco import adapter

    mujoco = import_engine("mujoco", "MuJoCo", "mujoco")
    adapter._import()  # MuJoCo's warnings to its log file, as for one body
    return mujoco


# -- the plan: spanning tree, reference configuration, loops -------------------------------------

#: every joint kind MuJoCo builds in a tree
TREE_KINDS = ("spherical", "fixed_point", "revolute", "prismatic", "universal", "cylindrical")


#: why MuJoCo closes no loop of these kinds
REFUSED_CLOSURES = dict.fromkeys(
    ("prismatic", "cylindrical"),
    "MuJoCo's equality constraints hold a point (connect), a whole pose (weld), a joint's or "
    "a tendon's value (joint, tendon) or a flex; none leaves a relative translation free, and "
    "a composition through an extra body with a slide joint needs that body to have mass "
    "(MuJoCo refuses a massless moving body: 'mass and inertia of moving bodies must be "
    "larger than mjMINVAL'), which would change the motion",
)


def plan(scenario) -> reduced.Plan:
    """The spanning tree, reference configuration and loop closures of ``scenario``: the plan
    of every reduced-coordinate builder (:func:`references.engines.reduced.plan`)
    with every kind of :data:`TREE_KINDS` in the tree and a universal closure as a point and a
    distance. Raises ``ValueError`` for malformed joints, :class:`Unsupported` for a closure
    this builder cannot express."""
    return reduced.plan(scenario, "mujoco", TREE_KINDS, reduced.DISTANCE_CLOSURES,
                        REFUSED_CLOSURES)  # fmt: skip


# -- consistency of the initial world states -----------------------------------------------------


_world = reduced.world


def check_consistent(scenario, pl: reduced.Plan | None = None) -> None:
    """Raise :class:`InconsistentSystem` naming the joint and the residual if the initial
    world states violate a joint (tree joints and loop closures alike): the anchors' gap (m)
    and slip (m/s), a revolute's or prismatic's axis misalignment (rad) and relative rotation
    rate off its axis (rad/s), a prismatic's offset and slip across its axis."""
    pl = pl or plan(scenario)
    tol_x = STATE_TOL * pl.length
    tol_v = STATE_TOL * pl.rate
    idx = {n: i for i, n in enumerate(pl.names)}
    for j in pl.joints:
        what = reduced.label(j)
        a = idx[j.body_a]
        b = -1 if j.body_b is None else idx[j.body_b]
        xa, Ra, va, wa = _world(pl, a)
        xb, Rb, vb, wb = _world(pl, b)
        pa = xa + Ra @ _vec(j.anchor_a, what)
        pb = xb + Rb @ _vec(j.anchor_b, what)
        vpa = va + np.cross(wa, pa - xa)
        vpb = vb + np.cross(wb, pb - xb)
        gap, slip = pa - pb, vpa - vpb

        def refuse(quantity, value, tol, unit, what=what):
            raise InconsistentSystem(
                f"mujoco: system {scenario.name!r}: {what}: the initial world states violate "
                f"the joint: {quantity} {value:.3g} {unit} (allowed {tol:.3g} {unit}); give "
                "states that satisfy every joint (the builder does not project them)"
            )

        if j.kind in ("spherical", "fixed_point", "revolute"):
            if np.linalg.norm(gap) > tol_x:
                refuse(f"anchor gap |p_a - p_b| (p_a {pa.tolist()}, p_b {pb.tolist()})",
                       float(np.linalg.norm(gap)), tol_x, "m")  # fmt: skip
            if np.linalg.norm(slip) > tol_v:
                refuse("anchor slip |dp_a/dt - dp_b/dt|", float(np.linalg.norm(slip)), tol_v,
                       "m/s")  # fmt: skip
        if j.kind in ("revolute", "prismatic", "universal", "cylindrical"):
            if j.axis_a is None or j.axis_b is None:
                raise ValueError(f"{what}: a {j.kind} joint needs axis_a and axis_b")
            ua = Ra @ _unit(j.axis_a, what)
            ub = Rb @ _unit(j.axis_b, what)
        if j.kind in ("revolute", "prismatic", "cylindrical"):
            mis = float(np.linalg.norm(np.cross(ua, ub)))
            if mis > STATE_TOL:
                refuse(f"axis misalignment |u_a x u_b| (u_a {ua.tolist()}, u_b {ub.tolist()})",
                       mis, STATE_TOL, "rad")  # fmt: skip
            rel = wa - wb
            off = float(np.linalg.norm(rel - (rel @ ua) * ua))
            if off > STATE_TOL * pl.rate / pl.length:
                refuse("relative angular velocity off the axis", off,
                       STATE_TOL * pl.rate / pl.length, "rad/s")  # fmt: skip
        if j.kind == "universal":
            dot = abs(float(ua @ ub))
            if dot > STATE_TOL:
                refuse("|u_a . u_b| (the axes must be perpendicular)", dot, STATE_TOL, "")
            # d/dt (u_a . u_b) = (w_b - w_a) . (u_a x u_b)
            rate = abs(float((wb - wa) @ np.cross(ua, ub)))
            if rate > STATE_TOL * pl.rate / pl.length:
                refuse("d/dt (u_a . u_b)", rate, STATE_TOL * pl.rate / pl.length, "rad/s")
        if j.kind in ("prismatic", "cylindrical"):
            across = float(np.linalg.norm(gap - (gap @ ua) * ua))
            if across > tol_x:
                refuse("anchor offset across the axis", across, tol_x, "m")
            # b's anchor relative to the point of a that coincides with it
            rel_v = vpb - va - np.cross(wa, pb - xa)
            s_across = float(np.linalg.norm(rel_v - (rel_v @ ua) * ua))
            if s_across > tol_v:
                refuse("anchor slip across the axis", s_across, tol_v, "m/s")
        if j.kind == "prismatic":
            rel = float(np.linalg.norm(wa - wb))
            if rel > STATE_TOL * pl.rate / pl.length:
                refuse("relative angular velocity", rel, STATE_TOL * pl.rate / pl.length,
                       "rad/s")  # fmt: skip


# -- read-back ---------------------------------------------------------------------------------


def _close(got, want, scale: float = 1.0) -> float:
    """Largest difference of got and want relative to max(scale, |want|)."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    return float(np.max(np.abs(got - want), initial=0.0)) / max(
        scale, float(np.max(np.abs(want), initial=0.0))
    )


def _quat_close(got, want) -> float:
    got, want = np.asarray(got, float), np.asarray(want, float)
    return min(_close(got, want), _close(got, -want))


def read_back(mujoco, m, scenario, pl: reduced.Plan, integrator: str, dt, solref, solimp) -> dict:
    """Compare the compiled model with the scenario (module docstring); raise
    :class:`EngineError` naming the body, joint or setting on a mismatch. Returns the
    read-back values recorded in the settings."""
    bad = reduced.Mismatches()

    def want(what, got, expect, scale=1.0, quat=False):
        err = _quat_close(got, expect) if quat else _close(got, expect, scale)
        if not err <= READBACK_TOL:
            bad.append(
                f"{what}: the model holds {np.round(np.asarray(got, float), 15).tolist()}, "
                f"the scenario needs {np.round(np.asarray(expect, float), 15).tolist()}"
            )

    L = pl.length
    njnt = sum(len(parts(tj)) for tj in pl.tree.values())
    if m.nbody != len(pl.bodies) + 1 or m.njnt != njnt:
        raise EngineError(
            f"mujoco: the model has {m.nbody - 1} bodies and {m.njnt} joints; the scenario "
            f"{len(pl.bodies)} and {njnt}"
        )
    jtypes = {
        "free": mujoco.mjtJoint.mjJNT_FREE,
        "ball": mujoco.mjtJoint.mjJNT_BALL,
        "hinge": mujoco.mjtJoint.mjJNT_HINGE,
        "slide": mujoco.mjtJoint.mjJNT_SLIDE,
    }
    bid = {}
    for c, b in enumerate(pl.bodies):
        i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, str(b.name))
        if i < 0:
            raise EngineError(f"mujoco: body {b.name!r} is missing from the compiled model")
        bid[c] = i
    for c, b in enumerate(pl.bodies):
        i, tj = bid[c], pl.tree[c]
        nm = f"body {b.name!r}"
        parent = 0 if tj.parent < 0 else bid[tj.parent]
        if m.body_parentid[i] != parent:
            bad.append(f"{nm}: parent body id {m.body_parentid[i]}, the tree needs {parent}")
        want(f"{nm}: body_mass", m.body_mass[i], b.mass)
        want(f"{nm}: body_inertia (principal moments)", m.body_inertia[i], b.inertia)
        want(f"{nm}: body_ipos (COM in the body frame)", m.body_ipos[i], np.zeros(3), L)
        want(f"{nm}: body_iquat (principal axes)", m.body_iquat[i], [1, 0, 0, 0], quat=True)
        want(f"{nm}: body_gravcomp", m.body_gravcomp[i], 0.0)
        if m.body_jntnum[i] != len(parts(tj)):
            bad.append(f"{nm}: {m.body_jntnum[i]} joints, the tree needs {len(parts(tj))}")
            continue
        jn = f"{tj.label} (MuJoCo {mj_type(tj)} of {b.name!r})"
        for part, (typ, ax) in enumerate(parts(tj)):
            jid = m.body_jntadr[i] + part
            if m.jnt_type[jid] != jtypes[typ]:
                bad.append(f"{jn}: jnt_type {int(m.jnt_type[jid])}, needs {int(jtypes[typ])}")
            if typ == "free":
                continue
            want(f"{jn}: jnt_pos (the child's anchor, child frame)", m.jnt_pos[jid], tj.Y, L)
            if ax is not None:
                want(f"{jn}: jnt_axis (the child's axis, child frame)", m.jnt_axis[jid], ax)
            if m.jnt_limited[jid]:
                bad.append(f"{jn}: jnt_limited is on; a joint of the scenario has no limits")
        if tj.kind == "free":
            want(f"{nm}: body_pos (root at the initial COM)", m.body_pos[i], b.position, L)
            want(f"{nm}: body_quat (root)", m.body_quat[i], cv.matrix_to_quat_wxyz(b.rotation),
                 quat=True)  # fmt: skip
            continue
        want(f"{jn}: body_pos (X - R_ref Y)", m.body_pos[i], tj.X - tj.R_ref @ tj.Y, L)
        want(f"{jn}: body_quat (R_ref)", m.body_quat[i], cv.matrix_to_quat_wxyz(tj.R_ref),
             quat=True)  # fmt: skip
    for name in ("dof_damping", "dof_armature", "dof_frictionloss"):
        if np.any(getattr(m, name) != 0):
            bad.append(f"{name} {getattr(m, name).tolist()}: must be 0 (it distorts the motion)")
    if np.any(m.jnt_stiffness != 0):
        bad.append(f"jnt_stiffness {m.jnt_stiffness.tolist()}: must be 0")
    ndist = sum(len(lp.distances) for lp in pl.loops)
    nspring = len(getattr(scenario, "springs", ()))
    if m.ngeom or m.nu or m.ntendon != ndist + nspring:
        bad.append(f"geoms {m.ngeom}, actuators {m.nu}, tendons {m.ntendon}: must be 0, 0, "
                   f"{ndist + nspring} (the loops' held distances, the springs)")  # fmt: skip
    else:
        forces.read_back_springs(mujoco, m, scenario, pl, bid, ndist, want, bad)
    npairs = sum(len(lp.pairs) for lp in pl.loops)
    if m.neq != npairs + ndist:
        bad.append(f"{m.neq} equality constraints, the loops need {npairs + ndist}")
    elif m.ntendon == ndist + nspring:
        e = t = 0
        for lp in pl.loops:
            b1, b2 = bid[lp.a], 0 if lp.b < 0 else bid[lp.b]
            for di, (pa, pb, dist) in enumerate(lp.distances):
                what = f"{lp.label}: distance {di}"
                if m.eq_type[e + len(lp.pairs) + di] != mujoco.mjtEq.mjEQ_TENDON:
                    bad.append(f"{what}: not a tendon equality")
                ee = e + len(lp.pairs) + di
                if m.eq_obj1id[ee] != t + di or m.eq_obj2id[ee] != -1:
                    bad.append(f"{what}: the equality holds tendons {m.eq_obj1id[ee]}, "
                               f"{m.eq_obj2id[ee]}, needs {t + di} alone")  # fmt: skip
                want(f"{what}: held length (eq_data[0] + tendon_length0)",
                     m.eq_data[ee, 0] + m.tendon_length0[t + di], dist, L)  # fmt: skip
                want(f"{what}: polycoef 1..4", m.eq_data[ee, 1:5], np.zeros(4))
                want(f"{what}: eq_solref", m.eq_solref[ee], solref)
                want(f"{what}: eq_solimp", m.eq_solimp[ee], solimp)
                k = t + di
                sites = forces.site_pair(mujoco, m, k)
                if sites is None:
                    bad.append(f"{what}: the tendon is not a straight line between two sites")
                    continue
                s1, s2 = sites
                if m.site_bodyid[s1] != b1 or m.site_bodyid[s2] != b2:
                    bad.append(f"{what}: its sites are on bodies {m.site_bodyid[[s1, s2]]}")
                want(f"{what}: site on a", m.site_pos[s1], pa, L)
                want(f"{what}: site on b", m.site_pos[s2], pb, L)
                for f in ("tendon_stiffness", "tendon_damping", "tendon_frictionloss",
                          "tendon_armature", "tendon_limited"):  # fmt: skip
                    if np.any(np.asarray(getattr(m, f)[k]) != 0):
                        bad.append(f"{what}: {f} {getattr(m, f)[k]}: must be 0")
            t += len(lp.distances)
            for pi, (pa, pb) in enumerate(lp.pairs):
                what = f"{lp.label}: connect {pi}"
                if m.eq_type[e] != mujoco.mjtEq.mjEQ_CONNECT or m.eq_objtype[e] != int(
                    mujoco.mjtObj.mjOBJ_SITE
                ):
                    bad.append(f"{what}: not a site-to-site connect")
                s1, s2 = m.eq_obj1id[e], m.eq_obj2id[e]
                b1 = bid[lp.a]
                b2 = 0 if lp.b < 0 else bid[lp.b]
                if m.site_bodyid[s1] != b1 or m.site_bodyid[s2] != b2:
                    bad.append(f"{what}: its sites are on bodies {m.site_bodyid[[s1, s2]]}")
                want(f"{what}: site on a (its anchor)", m.site_pos[s1], pa, L)
                want(f"{what}: site on b (its anchor)", m.site_pos[s2], pb, L)
                want(f"{what}: site orientation", m.site_quat[s1], [1, 0, 0, 0], quat=True)
                want(f"{what}: eq_solref", m.eq_solref[e], solref)
                want(f"{what}: eq_solimp", m.eq_solimp[e], solimp)
                if not m.eq_active0[e]:
                    bad.append(f"{what}: inactive (eq_active0 false)")
                e += 1
            for di in range(len(lp.distances)):
                if not m.eq_active0[e]:
                    bad.append(f"{lp.label}: distance {di}: inactive (eq_active0 false)")
                e += 1
    want("gravity", m.opt.gravity, pl.gravity)
    want("timestep", m.opt.timestep, dt)
    if m.opt.integrator != int(getattr(mujoco.mjtIntegrator, INTEGRATORS[integrator])):
        bad.append(f"integrator {int(m.opt.integrator)}, needs {integrator}")
    want("density, viscosity", [m.opt.density, m.opt.viscosity], [0.0, 0.0])
    want("wind", m.opt.wind, np.zeros(3))
    dis, ena = int(m.opt.disableflags), int(m.opt.enableflags)
    D, E = mujoco.mjtDisableBit, mujoco.mjtEnableBit
    for flag, on in (("mjDSBL_CONTACT", True), ("mjDSBL_AUTORESET", True),
                     ("mjDSBL_EQUALITY", False), ("mjDSBL_CONSTRAINT", False),
                     ("mjDSBL_GRAVITY", False), ("mjDSBL_REFSAFE", False)):  # fmt: skip
        if bool(dis & int(getattr(D, flag))) != on:
            bad.append(f"disable flag {flag} must be {'set' if on else 'clear'}")
    for flag in ("mjENBL_SLEEP", "mjENBL_OVERRIDE"):
        bit = getattr(E, flag, None)
        if bit is not None and ena & int(bit):
            bad.append(f"enable flag {flag} must be clear (sleeping / overridden solref)")
    bad.raise_any("mujoco", scenario, "compiled model")
    return bid


# -- state ---------------------------------------------------------------------------------


def initial_qpos_qvel(m, pl: reduced.Plan, bid: dict) -> tuple[np.ndarray, np.ndarray]:
    """qpos, qvel of the scenario's initial world states (module docstring's table);
    ``bid``: MuJoCo's body id of each body (scenario order)."""
    qpos = np.zeros(m.nq)
    qvel = np.zeros(m.nv)
    for c in pl.order:
        tj = pl.tree[c]
        x, R, v, w = _world(pl, c)
        xp, Rp, vp, wp = _world(pl, tj.parent)
        w_rel = R.T @ (w - wp)  # child axes
        for part, (typ, ax) in enumerate(parts(tj)):
            jid = m.body_jntadr[bid[c]] + part
            qa, va = m.jnt_qposadr[jid], m.jnt_dofadr[jid]
            if typ == "free":
                q, u = cv.mujoco_free_from_state(x, v, R, R.T @ w)
            elif typ == "ball":
                q, u = cv.matrix_to_quat_wxyz(Rp.T @ R), w_rel
            elif typ == "hinge":
                # at the reference (initial) configuration the hinge axes are the child's
                # axes ax; a universal's two are perpendicular, a cylindrical's hinge is alone
                q, u = [0.0], [float(ax @ w_rel)]
            else:  # slide: the anchors' offset along the axis and its rate
                u_w = R @ ax
                d0 = float((x + R @ tj.Y - xp - Rp @ tj.X) @ u_w)
                rate = float((v - vp - np.cross(wp, x - xp)) @ u_w)
                q, u = [d0], [rate]
            qpos[qa : qa + len(q)] = q
            qvel[va : va + len(u)] = u
    return qpos, qvel


def read_states(mujoco, m, d, bid: dict, out=None):
    """(x, R, v, W) of every body (scenario order) from qpos/qvel: MuJoCo's kinematics and
    body velocities recomputed on the current state."""
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_comVel(m, d)
    x, R, v, W = reduced.state_arrays(len(bid))
    res = np.zeros(6)
    for c, i in bid.items():
        x[c] = d.xipos[i]
        R[c] = d.ximat[i].reshape(3, 3)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, i, res, 1)
        W[c] = res[:3]
        v[c] = R[c] @ res[3:]
    return x, R, v, W


def check_initial(mujoco, m, d, scenario, pl: reduced.Plan, bid: dict) -> None:
    """MuJoCo's own kinematics of the initial qpos/qvel against the scenario: every body's
    x, R, v, W, and every tree joint's anchor (xanchor) and axis (xaxis) against both the
    parent's and the child's side (:data:`INITIAL_TOL` relative to the length and rate
    scales; the conversions are exact up to round-off)."""
    x, R, v, W = read_states(mujoco, m, d, bid)
    tol = INITIAL_TOL
    bad = []
    for c, b in enumerate(pl.bodies):
        for what, got, exp, sc in (
            ("COM position", x[c], b.position, pl.length),
            ("rotation", R[c], b.rotation, 1.0),
            ("COM velocity", v[c], b.velocity, pl.rate),
            ("body angular velocity", W[c], b.omega_body, pl.rate / pl.length),
        ):
            err = _close(got, exp, sc)
            if not err <= tol:
                bad.append(f"body {b.name!r}: {what} {err:.3g} relative")
    for c in pl.order:
        tj = pl.tree[c]
        if tj.kind == "free":
            continue
        xc, Rc, _, _ = _world(pl, c)
        xp, Rp, _, _ = _world(pl, tj.parent)
        # MuJoCo's xanchor of every joint of a body is taken before any slide's translation:
        # the child's anchor moved back by the slide's qpos along the axis
        d0 = 0.0
        for part, (typ, _) in enumerate(parts(tj)):
            if typ == "slide":
                d0 = float(d.qpos[m.jnt_qposadr[m.body_jntadr[bid[c]] + part]])
        shift = d0 * (Rc @ tj.axis_c) if d0 else np.zeros(3)
        sides = [("child", xc + Rc @ tj.Y - shift)]
        sides.append(("parent", xp + Rp @ tj.X))
        for part, (_, ax) in enumerate(parts(tj)):
            jid = m.body_jntadr[bid[c]] + part
            for side, p in sides:
                err = _close(d.xanchor[jid], p, pl.length)
                if not err <= tol:
                    bad.append(f"{tj.label}: anchor (xanchor) vs the {side}'s {err:.3g} relative")
            if ax is None:
                continue
            axes = [("child", Rc @ ax)]
            if part == 0:  # the first axis is also the parent's (fixed in the parent)
                axes.append(("parent", Rp @ tj.axis_p))
            for side, u in axes:
                # a hinge's two axes may be given antiparallel (checked at t = 0)
                err = min(_close(d.xaxis[jid], u), _close(d.xaxis[jid], -u))
                if not err <= tol:
                    bad.append(f"{tj.label}: axis (xaxis) vs the {side}'s {err:.3g}")
    if bad:
        raise EngineError(
            f"mujoco: system {scenario.name!r}: MuJoCo's kinematics of the initial state differ "
            "from the scenario's world states (a frame, anchor or axis is wrong): " + "; ".join(bad)
        )
    reduced.check_loops("mujoco", pl, loop_points(m, d, pl))


# -- the run -------------------------------------------------------------------------------------


def _settings(kw: dict) -> tuple[tuple, tuple]:
    reduced.check_settings("mujoco", kw)
    solref = tuple(float(s) for s in kw.get("solref", DEFAULT_SOLREF))
    solimp = tuple(float(s) for s in kw.get("solimp", DEFAULT_SOLIMP))
    if len(solref) != 2 or not all(math.isfinite(s) for s in solref) or solref[0] <= 0:
        raise ValueError(f"solref {solref}: two finite numbers, the time constant > 0 (s)")
    if len(solimp) != 5 or not all(math.isfinite(s) for s in solimp):
        raise ValueError(f"solimp {solimp}: five finite numbers (MuJoCo's solimp)")
    return solref, solimp


def build(scenario, integrator: str, dt: float, **settings):
    """(mujoco, MjModel, MjData, plan, body ids, settings dict) of ``scenario``: planned,
    checked for consistency, compiled, read back, with the initial state set and checked."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator {integrator!r} unknown; known: {list(INTEGRATORS)}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt {dt!r}: must be a finite number > 0 (s)")
    solref, solimp = _settings(settings)
    mujoco = _import()
    if not hasattr(mujoco.mjtIntegrator, INTEGRATORS[integrator]):
        raise Unsupported(f"MuJoCo {mujoco.__version__} has no integrator {integrator!r}")
    for b in scenario.bodies:
        I = np.asarray(b.inertia, float)
        if any(I[k] > I[(k + 1) % 3] + I[(k + 2) % 3] for k in range(3)):
            raise Unsupported(
                f"mujoco: body {b.name!r}: MuJoCo rejects the inertia {I.tolist()} (A + B >= C)"
            )
    pl = plan(scenario)
    check_consistent(scenario, pl)
    xml = model_xml(scenario, pl, integrator, float(dt), solref, solimp)
    try:
        m = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:
        raise EngineError(f"mujoco: system {scenario.name!r} does not compile: {exc}") from exc
    hold_distances(m, pl)
    bid = read_back(mujoco, m, scenario, pl, integrator, float(dt), solref, solimp)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = initial_qpos_qvel(m, pl, bid)
    check_initial(mujoco, m, d, scenario, pl, bid)
    applied = forces.torque_forces(m, scenario, pl, bid)
    forces.apply_torques(d, applied)
    mujoco.mj_forward(m, d)
    refsafe = max(solref[0], 2.0 * float(dt))
    rec = {
        "engine": f"mujoco {mujoco.__version__}",
        "integrator": integrator,
        "timestep": float(dt),
        "gravity": pl.gravity.tolist(),
        "tree": reduced.tree_record(pl, mj_type),
        "frames": "each body frame is its principal frame at its COM (explicit inertial, "
        "pos 0, identity quat); no geoms, inertia never inferred",
        "damping, armature, frictionloss, stiffness": "0 (set and read back)",
        "joint limits": "none (limited=false, read back)",
        "contacts": "disabled (flag); no geoms",
        "autoreset": "disabled",
        "sleep, solref override": "off (read back)",
        "gravity compensation": "0 (read back)",
    }
    if has_elements(scenario):
        rec["force elements"] = [
            f"spring {s.name!r}: spatial tendon 'spring{k}' (stiffness {s.stiffness:g}, damping "
            f"{s.damping:g}, springlength {s.rest_length:g}; read back)"
            for k, s in enumerate(getattr(scenario, "springs", ()))
        ] + [label for _, _, label in applied]
    if pl.loops:
        rec["loop closures"] = [
            f"{lp.label}: "
            + (
                "one site-to-site connect at the anchors"
                + (
                    f", and a site-to-site spatial tendon between the points {pl.length:.6g} m "
                    f"along each axis held at {pl.length * math.sqrt(2):.6g} m (equality "
                    "tendon: the axes perpendicular)"
                    if lp.distances
                    else ""
                )
                if len(lp.pairs) == 1
                else "two site-to-site connects, at the anchors and "
                f"{pl.length:.6g} m along the hinge axis (6 equations for the hinge's 5; "
                "the one along the axis is redundant)"
            )
            for lp in pl.loops
        ]
        rec["solref"] = list(solref)
        rec["solref effective"] = [refsafe, solref[1]]
        rec["solref note"] = (
            "MuJoCo's default (0.02, 1)" if solref == DEFAULT_SOLREF else "given"
        ) + ("; time constant raised to 2 dt by MuJoCo (refsafe)" if refsafe > solref[0] else "")
        rec["solimp"] = list(solimp)
        rec["solver"] = {
            "solver": mujoco.mjtSolver(int(m.opt.solver)).name,
            "iterations": int(m.opt.iterations),
            "tolerance": float(m.opt.tolerance),
            "jacobian": mujoco.mjtJacobian(int(m.opt.jacobian)).name,
        }
    return mujoco, m, d, pl, bid, rec


def simulate_system(scenario, integrator: str, dt: float, nstep: int, save_every: int,
                    **settings) -> SystemResult:  # fmt: skip
    """Run ``scenario`` (a system scenario, module docstring) on MuJoCo.

    ``integrator``: one of :data:`INTEGRATORS`; ``dt`` s; ``nstep`` steps, saved at steps 0,
    s, 2s, ..., nstep (always the last); ``settings``: ``solref`` (2,) and ``solimp`` (5,) of
    the loop-closing connects (MuJoCo's defaults otherwise).

    Returns a :class:`~references.engines.system.SystemResult`: ``t`` (n,) s; ``x`` (n, nb, 3) COM
    world m; ``R`` (n, nb, 3, 3) body to world; ``v`` (n, nb, 3) COM velocity world m/s; ``W`` (n,
    nb, 3) body angular velocity, body axes rad/s (bodies in the order of ``scenario.bodies``);
    ``engine_time_s`` (time inside ``mj_step``); ``settings`` (every setting that shapes the
    result).

    Raises :class:`Unsupported` for a joint or loop MuJoCo is not built for here,
    :class:`InconsistentSystem` for initial states that violate a joint,
    :class:`EngineError` for a read-back mismatch, :class:`Diverged` (with the states up to
    the last good save in ``output``) for a non-finite state or MuJoCo's instability warnings.
    """
    saves = _saves(nstep, save_every)
    mujoco, m, d, pl, bid, rec = build(scenario, integrator, dt, **settings)
    nb = len(pl.bodies)
    n = len(saves)
    x, R, v, W = reduced.state_arrays(n, nb)
    x[0], R[0], v[0], W[0] = read_states(mujoco, m, d, bid)
    engine = 0.0
    warns = [int(getattr(mujoco.mjtWarning, w)) for w in
             ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS")]  # fmt: skip
    done = 0
    timing.stepping()  # the model is built: its construction is not the cost
    for k in range(1, n):
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, int(saves[k] - done))
        engine += timing.lap(t0)
        done = int(saves[k])
        flagged = [w for w in warns if d.warning[w].number]
        if flagged or not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))):
            out = _output(saves[:k], dt, x[:k], R[:k], v[:k], W[:k], engine, rec)
            why = "MuJoCo flagged an unstable state" if flagged else "a non-finite state"
            raise Diverged(
                f"mujoco {integrator} at dt = {dt:g} s: {why} between t = "
                f"{saves[k - 1] * dt:.6g} and {done * dt:.6g} s (reduce dt)",
                done * dt,
                out,
            )
        x[k], R[k], v[k], W[k] = read_states(mujoco, m, d, bid)
    return _output(saves, dt, x, R, v, W, engine, rec)


def _output(saves, dt, x, R, v, W, engine, rec) -> SystemResult:
    return SystemResult(
        t=np.asarray(saves, float) * float(dt),
        x=x,
        R=R,
        v=v,
        W=W,
        engine_time_s=float(engine),
        settings=rec,
    )
