"""A system's force elements (:mod:`scenarios.force_elements`) on PyBullet, which has no spring
element and no constant joint torque of its own: before every ``stepSimulation`` the elements'
loads at the current state (:func:`scenarios.force_elements.body_loads`: the resultant force at
each body's centre of mass and the moment about it, world axes) are applied with
``applyExternalForce`` (at the link's centre of mass, ``WORLD_FRAME``) and
``applyExternalTorque`` (``WORLD_FRAME``). Bullet clears external forces at the end of each
step (btMultiBody::clearForcesAndTorques), so each step sees the loads of its own start: the
elements enter Bullet's semi-implicit Euler explicitly, as gravity does. A joint torque is the
couple tau u on body a and -tau u on body b, so it acts on a joint that closes a loop as on a
tree joint.

Read back: PyBullet has no getter for the external forces it holds; what is checked is the
state the loads are computed from (each link's centre of mass, orientation and velocities from
``getLinkState``, the same read-out as the run's saved states) and, by the tests, the motion:
the spatial arm with two torques and a spring-damper against the reduced-coordinate reference
(tests/references/engines/test_engine_forces.py), with planted mistakes that must show.
"""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from scenarios import force_elements as fe


def link_states(bm, bodies=None):
    """(x, R, v, W) of every body (scenario order; W in body axes), or of ``bodies`` alone
    (indices; the other rows are left unset), from PyBullet's link states: the centre of mass
    (getLinkState 0), its orientation (1), linear and angular velocity (6, 7), read with one
    ``getLinkStates`` per multibody (one pass of its forward kinematics); a multibody's base
    from getBasePositionAndOrientation/getBaseVelocity."""
    p, cid = bm.p, bm.cid
    nb = len(bm.pl.bodies)
    x, R, v, W = np.empty((nb, 3)), np.empty((nb, 3, 3)), np.empty((nb, 3)), np.empty((nb, 3))
    links: dict[int, list] = {}  # multibody -> [(body, link)]
    read = []
    for c in bm.where if bodies is None else bodies:
        mb, k = bm.where[c]
        if k < 0:
            xc, q = p.getBasePositionAndOrientation(mb, physicsClientId=cid)
            vc, wc = p.getBaseVelocity(mb, physicsClientId=cid)
            read.append((c, xc, q, vc, wc))
        else:
            links.setdefault(mb, []).append((c, k))
    for mb, ck in links.items():
        got = p.getLinkStates(mb, [k for _, k in ck], computeLinkVelocity=1,
                              computeForwardKinematics=1, physicsClientId=cid)  # fmt: skip
        read += [(c, s[0], s[1], s[6], s[7]) for (c, _), s in zip(ck, got, strict=True)]
    for c, xc, q, vc, wc in read:
        R[c] = cv.quat_xyzw_to_matrix(q)
        x[c], v[c] = xc, vc
        W[c] = R[c].T @ np.asarray(wc, float)
    return x, R, v, W


def apply(bm, scenario, bodies=None) -> tuple[np.ndarray, np.ndarray]:
    """Apply the force elements' loads at PyBullet's current state for the next step; returns
    them (F, T), world, per body. ``bodies``: the bodies they act on
    (:func:`scenarios.force_elements.loaded_bodies`, computed when not given): only their
    states are read and only they are loaded."""
    p, cid = bm.p, bm.cid
    if bodies is None:
        bodies = fe.loaded_bodies(scenario)
    x, R, v, W = link_states(bm, bodies)
    F, T = fe.body_loads(scenario, x, R, v, W)
    Fl, Tl, xl = F.tolist(), T.tolist(), x.tolist()
    for c in bodies:
        mb, k = bm.where[c]
        if any(Fl[c]):
            p.applyExternalForce(mb, k, Fl[c], xl[c], p.WORLD_FRAME, physicsClientId=cid)
        if any(Tl[c]):
            p.applyExternalTorque(mb, k, Tl[c], p.WORLD_FRAME, physicsClientId=cid)
    return F, T


def record(scenario) -> list[str]:
    """The settings record's lines: what each element became."""
    out = [f"spring {s.name!r}: applyExternalForce/applyExternalTorque (WORLD_FRAME) of its "
           f"force (k {s.stiffness:g}, c {s.damping:g}, l0 {s.rest_length:g}) before each step"
           for s in getattr(scenario, "springs", ())]  # fmt: skip
    out += [f"torque on {t.joint!r}: the couple {t.torque:g} N m about its axis on its two "
            "bodies, applyExternalTorque (WORLD_FRAME) before each step"
            for t in getattr(scenario, "torques", ())]  # fmt: skip
    return out
