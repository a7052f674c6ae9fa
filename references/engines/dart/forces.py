"""A system's force elements (:mod:`scenarios.force_elements`) on DART. DART's own spring
elements are joint springs (a stiffness on a joint coordinate): no spring between two body
points and no constant joint torque a scenario's elements would map to one for one. So the
elements' loads at the current state (:func:`scenarios.force_elements.body_loads`: the resultant
force at each body's centre of mass and the moment about it, world axes) are given to DART as
its body nodes' external forces: ``BodyNode.addExtForce(F, local COM, isForceLocal=False,
isOffsetLocal=True)`` and ``addExtTorque(T, isLocal=False)``, after ``clearExternalForces``.

- ``semi-implicit Euler`` (World.step): set before every step; World.step clears them at its
  end (resetCommand), so each step sees the loads of its own start, applied explicitly as
  gravity is.
- ``RKMK4``: set at every stage's state before ``computeForwardDynamics``, which includes
  them (so the elements are evaluated four times a step, as the reference's).

A joint torque is the couple tau u on body a and -tau u on body b: it acts on a joint that
closes a loop as on a tree joint.

Read back (:func:`check`): after the first application DART's external wrench of every body
(``getExternalForceGlobal``: world axes, its moment about the world origin (measured),
DART's [moment, force]) must be the loads moved to that origin, (T + x_com x F, F), to
1e-12 of the elements' load scale (:func:`scenarios.force_elements.load_scale`); else
:class:`~references.errors.EngineError` names the body.
"""

from __future__ import annotations

import numpy as np

from references.errors import EngineError
from scenarios import force_elements as fe


def apply(dm, scenario, states=None) -> tuple[np.ndarray, np.ndarray]:
    """Set DART's external forces to the elements' loads at its current state (or at
    ``states`` = (x, R, v, W), DART's, already read); returns them (F, T)."""
    x, R, v, W = dm.states() if states is None else states
    F, T = fe.body_loads(scenario, x, R, v, W)
    dm.skel.clearExternalForces()
    for c, body in dm.body.items():
        if F[c].any():
            body.addExtForce(F[c], body.getLocalCOM(), False, True)
        if T[c].any():
            body.addExtTorque(T[c], False)
    return F, T


def check(dm, scenario) -> None:
    """Apply the loads at the current state and compare DART's external wrenches with them
    (module docstring); DART's external forces are cleared again."""
    x, R, v, W = dm.states()
    F, T = apply(dm, scenario, (x, R, v, W))
    bad = []
    scale = max(float(np.abs(F).max()), float(np.abs(T).max()) / dm.pl.length,
                fe.load_scale(scenario, dm.pl.length, dm.pl.rate))  # fmt: skip
    for c, body in dm.body.items():
        want = np.concatenate([T[c] + np.cross(x[c], F[c]), F[c]])
        got = np.asarray(body.getExternalForceGlobal(), float)
        err = np.abs(got - want) / np.array([dm.pl.length] * 3 + [1.0] * 3)
        if not err.max() <= 1e-12 * scale:
            bad.append(f"body {dm.pl.names[c]!r}: DART holds {np.round(got, 12).tolist()}, "
                       f"the elements give {np.round(want, 12).tolist()}")  # fmt: skip
    dm.skel.clearExternalForces()
    if bad:
        raise EngineError("dart: the force elements' external forces differ: " + "; ".join(bad))


def record(scenario, integrator: str) -> list[str]:
    """The settings record's lines: what each element became."""
    when = "before each World.step" if integrator != "RKMK4" else "at each RKMK4 stage"
    out = [f"spring {s.name!r}: BodyNode.addExtForce/addExtTorque (world) of its force (k "
           f"{s.stiffness:g}, c {s.damping:g}, l0 {s.rest_length:g}) {when}; read back"
           for s in getattr(scenario, "springs", ())]  # fmt: skip
    out += [f"torque on {t.joint!r}: the couple {t.torque:g} N m about its axis on its two "
            f"bodies, BodyNode.addExtTorque (world) {when}; read back"
            for t in getattr(scenario, "torques", ())]  # fmt: skip
    return out
