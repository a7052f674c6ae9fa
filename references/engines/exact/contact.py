"""The closed form of a contact scene (:mod:`references.exact.contact_scene`) as the exact
engine's contact builder: its rows are the floor of the measurement, beside every engine's.

It reports no contact forces (the closed forms give them only in sums: the support forces of
a resting scene, the normal load of a block; how a box's weight spreads over its four corners
is statically indeterminate), so its law residuals are 0 by construction and its rows are the
reference, not a configuration under test.
"""

from __future__ import annotations

import time

from references.engines import timing
from references.engines.contact import ContactLog
from references.engines.integrators import Integrator
from references.errors import Unsupported

CONFIGURATIONS = (
    Integrator("closed form", "exact contact", 0,
               "the closed form of the scene (references.exact.contact)"),
)  # fmt: skip

SETTINGS = ()


def simulate_contact(scenario, configuration, dt, nstep, save_every, _plant=None, **settings):
    """The closed form at the saved steps; the contract of :mod:`references.engines.contact`."""
    from references.engines.stepping import step_plan
    from references.exact._util import ReferenceNotApplicable
    from references.exact.contact_scene import contact_motion

    if scenario.reference in ("none", "auto"):
        raise Unsupported(f"scene {scenario.name!r} names no closed form ([reference] kind)")
    _, saves = step_plan(dt, nstep * dt, save_every)
    t = saves * float(dt)
    timing.stepping()  # its cost is the closed form's evaluation, timed like an engine's
    t0 = time.perf_counter()
    try:
        m = contact_motion(scenario, t)
    except ReferenceNotApplicable as exc:
        raise Unsupported(str(exc)) from None
    wall = timing.lap(t0)
    log = ContactLog()
    for _ in t:
        log.save()
    pairs = {i: {"mu": c.mu, "e": c.e} for i, c in enumerate(scenario.contacts)}
    shapes = {}
    for b in scenario.bodies:
        s = b.shape
        if s is None:
            continue
        size = (
            tuple(s.half_extents)
            if s.kind == "box"
            else (s.radius,) + ((s.half_length,) if s.kind in ("capsule", "cylinder") else ())
        )
        shapes[b.name] = {"kind": s.kind, "size": size, "offset": tuple(s.position)}
    return {
        "t": m.t, "x": m.x, "R": m.R, "v": m.v, "W": m.W,
        "contacts": log.arrays(), "engine_time_s": wall,
        "settings": {"reference kind": scenario.reference, "method": m.method,
                     "accuracy": float(m.accuracy["attitude"]),
                     "accuracy position (m)": float(m.accuracy["position"])},
        "readback": {"pairs": pairs, "shapes": shapes},
    }  # fmt: skip
