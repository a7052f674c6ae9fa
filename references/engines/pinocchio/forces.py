"""A system's force elements (:mod:`scenarios.force_elements`) on Pinocchio, which has no force
element (it computes dynamics; the time stepping is the suite's): the elements enter its
forward dynamics as a generalised force. At every evaluation of the accelerations (each
semi-implicit Euler step, each RKMK4 stage) the bodies' states come from Pinocchio's forward
kinematics of (q, v), the elements' loads from :func:`scenarios.force_elements.body_loads`
(the resultant force at each body's centre of mass and the moment about it, world axes), and

    Q = sum over bodies of J_c^T (F_c, T_c + x_c x F_c)

with J_c the body's joint Jacobian in Pinocchio's WORLD frame (``computeJointJacobians``,
``getJointJacobian``: linear rows the velocity of the point at the world origin, angular
rows the angular velocity) and the load's moment taken about the world origin. Q is added to
the joint torques handed to ``aba`` (a tree) or ``constraintDynamics`` (loops). A joint torque is
the couple tau u on body a and -tau u on body b: on a joint that closes a loop as on a tree
joint.

Read back (:func:`check`, at t = 0): Q must equal what Pinocchio's own external-force input
makes of the same loads, ``rnea(q, v, 0) - rnea(q, v, 0, fext)`` with ``fext`` each body's load
as a ``pinocchio.Force`` in its joint's LOCAL frame about the joint's origin, to 1e-12
of the elements' load scale (:func:`scenarios.force_elements.load_scale`: a spring at its
rest length gives loads of rounding size); else :class:`~references.errors.EngineError`
names the difference.
"""

from __future__ import annotations

import numpy as np

from references.errors import EngineError
from scenarios import force_elements as fe


def generalized(pm, q, v) -> np.ndarray:
    """Q (nv,): the force elements' generalised force at (q, v) (module docstring). One pass
    of forward kinematics (q, v) gives the loaded bodies' states and, after it, their joint
    Jacobians (``computeJointJacobians`` on the placements it computed)."""
    pin, model, data = pm.pin, pm.model, pm.data
    x, R, vv, W = pm.states(q, v, pm.loaded)  # forwardKinematics(q, v)
    F, T = fe.body_loads(pm.loads, x, R, vv, W)
    pin.computeJointJacobians(model, data)
    Q = np.zeros(model.nv)
    F, T, x = F.tolist(), T.tolist(), x.tolist()
    for c in pm.loaded:
        f, t, p = F[c], T[c], x[c]
        if any(f) or any(t):
            J = pin.getJointJacobian(model, data, pm.jid[c], pin.ReferenceFrame.WORLD)
            # the load's moment about the world origin, t + p x f (written out: np.cross
            # costs ~15 us on 3-vectors)
            w = (
                f[0],
                f[1],
                f[2],
                t[0] + (p[1] * f[2] - p[2] * f[1]),
                t[1] + (p[2] * f[0] - p[0] * f[2]),
                t[2] + (p[0] * f[1] - p[1] * f[0]),
            )
            Q += J.T @ np.array(w)
    return Q


def loaded(pm) -> list[int]:
    """The bodies the force elements act on (:func:`scenarios.force_elements.loaded_bodies`),
    in the order of the model's joints (``pm.jid``: the order :func:`generalized` sums in)."""
    which = set(fe.loaded_bodies(pm.loads))
    return [c for c in pm.jid if c in which]


def check(pm, q, v) -> None:
    """Compare :func:`generalized` at (q, v) with Pinocchio's rnea with ``fext`` (module
    docstring)."""
    pin = pm.pin
    Q = generalized(pm, q, v)
    x, R, vv, W = pm.states(q, v)
    F, T = fe.body_loads(pm.loads, x, R, vv, W)
    fext = pin.StdVec_Force()
    for _ in range(pm.model.njoints):
        fext.append(pin.Force.Zero())
    for c, jid in pm.jid.items():
        M = pm.data.oMi[jid]
        Rj, o = M.rotation, M.translation
        fext[jid] = pin.Force(Rj.T @ F[c], Rj.T @ (T[c] + np.cross(x[c] - o, F[c])))
    a0 = np.zeros(pm.model.nv)
    want = np.array(pin.rnea(pm.model, pm.data, q, v, a0)) - np.array(
        pin.rnea(pm.model, pm.data, q, v, a0, fext)
    )
    # generalised forces: N m on hinges, N on slides (the length scale makes them one size)
    scale = max(float(np.abs(want).max()),
                fe.load_scale(pm.loads, pm.pl.length, pm.pl.rate) * pm.pl.length)  # fmt: skip
    if not np.abs(Q - want).max() <= 1e-12 * scale:
        raise EngineError(
            f"pinocchio: the force elements' generalised force {np.round(Q, 12).tolist()} "
            f"differs from Pinocchio's rnea with fext {np.round(want, 12).tolist()}"
        )


def record(scenario, integrator: str) -> list[str]:
    """The settings record's lines: what each element became."""
    when = "each Euler step" if integrator != "RKMK4" else "each RKMK4 stage"
    out = [f"spring {s.name!r}: J^T of its force (k {s.stiffness:g}, c {s.damping:g}, l0 "
           f"{s.rest_length:g}) added to the joint torques at {when}; checked against rnea "
           "with fext" for s in getattr(scenario, "springs", ())]  # fmt: skip
    out += [f"torque on {t.joint!r}: J^T of the couple {t.torque:g} N m about its axis on its "
            f"two bodies, added to the joint torques at {when}; checked against rnea with fext"
            for t in getattr(scenario, "torques", ())]  # fmt: skip
    return out
