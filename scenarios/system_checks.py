"""Checks of a system file beyond the shape of its fields: the inputs that no integrator and no
reference can run (docs/scenarios.md, "Systems of bodies"), each refused with the field, the
value and the rule before anything is computed from it.

- :func:`angle_problems`: a joint coordinate's angle or rotation vector beyond
  :data:`MAX_ANGLE` rad (a body's ``rotation_vector`` likewise). The rotation of an angle a is
  known only to its rounding, a eps/2 rad: beyond 1e3 rad (159 turns) that is 1e-13 rad, the
  joints' own tolerance is 1e-10, and at 1e300 the sine is undefined;
- :func:`unjoined_problems`: a body that no joint names: a system's bodies are joined (a body
  of its own is a single-body scenario);
- :func:`step_problems`: a body turning more than :data:`MAX_TURN_PER_STEP` rad in one step of
  ``run.dt`` (or of the largest step of ``run.dt_sweep``): no fixed-step integrator resolves
  a rotation of half a turn per step, and the reference's work grows with the rate (a joint
  rate of 1e8 rad/s ran it to its 600 s wall-time bound).
"""

from __future__ import annotations

import math

import numpy as np

#: the largest joint angle, or rotation-vector length, accepted (rad; module docstring)
MAX_ANGLE = 1e3
#: a step may turn a body by at most this (rad): half a turn
MAX_TURN_PER_STEP = math.pi


def angle_problems(raw_joints, raw_bodies) -> list[tuple]:
    """(field, value, rule) of every angle or rotation vector beyond :data:`MAX_ANGLE`."""
    probs = []

    def check(field, value):
        try:
            v = np.abs(np.asarray(value, dtype=float))
            top = float(np.max(v)) if v.size else 0.0
            a = top * float(np.linalg.norm(v / top)) if 0.0 < top < math.inf else top
        except (TypeError, ValueError):
            return  # the field's type is checked elsewhere
        if not a <= MAX_ANGLE:
            probs.append((field, value, f"an angle is at most {MAX_ANGLE:g} rad ({MAX_ANGLE / (2 * math.pi):.0f} turns): beyond it its rounding alone, a eps/2, exceeds 1e-13 rad, and at {a:.3g} rad the rotation is not defined by the number; reduce it modulo 2 pi"))  # noqa: E501  # fmt: skip

    for i, tab in enumerate(raw_joints if isinstance(raw_joints, list) else []):
        if not isinstance(tab, dict):
            continue
        for key in ("angle", "rotation_vector"):
            if key in tab:
                check(f"joints[{i}].{key}", tab[key])
    for i, tab in enumerate(raw_bodies if isinstance(raw_bodies, list) else []):
        if isinstance(tab, dict) and "rotation_vector" in tab:
            check(f"bodies[{i}].rotation_vector", tab["rotation_vector"])
    return probs


def unjoined_problems(bodies, joints, touching=()) -> list[tuple]:
    """(field, value, rule) of each body that no joint names and that is in no contact pair
    (``touching``: the names of the bodies of the contact pairs)."""
    named = {j.body_a for j in joints} | {j.body_b for j in joints} | set(touching)
    return [
        (f"bodies[{i}].name", b.name, "this body is joined to nothing: a system's bodies are "
         "joined to each other or to the ground (a body of its own is a single-body "
         "scenario: give it a [body] file); add its joint or remove it")
        for i, b in enumerate(bodies)
        if b.name not in named
    ]  # fmt: skip


def step_problems(bodies, dt: float, sweep) -> list[tuple]:
    """(field, value, rule) when a body turns more than :data:`MAX_TURN_PER_STEP` rad in one
    step of the largest step run (``dt`` or the largest of ``sweep``)."""
    h = max([float(dt), *(float(s) for s in sweep)])
    w = [float(np.linalg.norm(b.omega_body)) for b in bodies]
    k = int(np.argmax(w)) if w else 0
    if not w or w[k] * h <= MAX_TURN_PER_STEP:
        return []
    field = "run.dt" if h == dt else "run.dt_sweep"
    return [(field, h, f"body {bodies[k].name!r} turns at {w[k]:.4g} rad/s at t = 0 (from its "
             f"state or its joints' rates), {w[k] * h:.4g} rad in one step of {h:g} s: a step "
             f"may turn a body by at most pi (half a turn); choose dt below "
             f"{MAX_TURN_PER_STEP / w[k]:.3g} s or check the rates")]  # fmt: skip


__all__ = [
    "MAX_ANGLE",
    "MAX_TURN_PER_STEP",
    "angle_problems",
    "step_problems",
    "unjoined_problems",
]
