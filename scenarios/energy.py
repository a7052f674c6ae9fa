"""The energy in play of a system of bodies: the scale its energy drift is measured against.

Principle (docs/results.md, "Scales"; scenarios/metric_catalog.py, ``energy_drift_max``): the
scale of an energy error is the largest kinetic energy the motion can reach, never the total
energy (its zero is arbitrary) nor energy that can never change hands. For a system held by
its joints that is, exactly,

    E_c = T0 + V0 - V_low,

T0 the initial kinetic energy, V0 the initial potential energy and V_low the lowest potential
energy of any configuration the joints allow (the motion is conservative: T = T0 + V0 - V).
V_low is bounded from below body by body, walking the suite's spanning tree
(:mod:`scenarios.tree`) from the ground: each body's centre of mass is at most as low as the
lowest point its joint can carry it to. Per joint, the lowest height (along -g) of a point X
of the child, given the joint point C (its initial world position) and h_C, the lowest height
C itself can reach:

=================================  ===========================================================
spherical, universal, fixed_point  h_C - |X - C| (the child may turn any way about C)
revolute to the ground             the circle about the axis n through C:
                                   up.(C + ((X - C).n) n) - |(X - C) x n| sqrt(1 - (up.n)^2)
revolute to a body                 h_C - |X - C| (the parent turns the axis)
prismatic along a horizontal axis  up.X + (h_C - up.C): the child keeps its attitude and the
  from a body that keeps its own   height of every point relative to C (a slider on a level
  attitude (or the ground)         rail never drops)
cylindrical along a horizontal     the circle about the axis line through C, lowered by
  axis, same parent                h_C - up.C
any other slide                    unbounded: the part beyond it falls (below)
=================================  ===========================================================

Loop closures are ignored, which only lowers V_low (a conservative, larger E_c). A part the
joints do not hold up (a floating part, or one beyond a slide with a component along g) falls
freely: it adds the translational kinetic energy gravity can give its centre of mass over
the horizon, 1/2 m max(|v_c|^2, |v_c + g t_end|^2), as for a floating system. Without gravity
E_c = T0; 1 J if that is 0. Force elements (:func:`scenarios.force_elements.energy_bound`) add
their springs' initial energy and bound what the torques can give over the horizon.

tests/scenarios/test_energy_in_play.py holds E_c between the largest kinetic energy along the
reference and a small multiple of it, and shows that a heavy body on a level slider adds nothing but
its own kinetic energy.
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.force_elements import energy_bound
from scenarios.tree import spanning_tree

#: an axis is level (normal to g) when |up . n| <= LEVEL_TOL: the files give axes to 17 digits
LEVEL_TOL = 1e-12

# how a body's points can move, given its joint to its parent (module docstring)
_ANY = "any"  # turns any way about C (lowest: h_C - |X - C|)
_CIRCLE = "circle"  # turns about the axis line (C, n), whose height drops by at most h_C - up.C
_KEEP = "keep"  # keeps its attitude: every point drops as much as C
_FALL = "fall"  # not held up


def _lowest(rule, up, X):
    """The lowest height of the body point whose initial world position is X (module
    docstring), or -inf for a falling body."""
    kind, C, hC, n = rule
    if kind == _FALL:
        return -math.inf
    d = X - C
    if kind == _ANY:
        return hC - float(np.linalg.norm(d))
    if kind == _KEEP:
        return float(up @ X) + (hC - float(up @ C))
    along = float(d @ n)
    radial = float(np.linalg.norm(d - along * n))
    tilt = math.sqrt(max(0.0, 1.0 - float(up @ n) ** 2))
    return float(up @ (C + along * n)) - radial * tilt + (hC - float(up @ C))


def energy_in_play(sc) -> float:
    """E_c (J) of the system scenario ``sc`` (module docstring)."""
    e = sc.kinetic_energy0()
    gnorm = float(np.linalg.norm(sc.gravity))
    if gnorm > 0:
        up = -np.asarray(sc.gravity, dtype=float) / gnorm
        drops, falling = _drops(sc, up)
        e += gnorm * sum(drops.values())
        for part in falling:
            m = sum(b.mass for b in part)
            vc = sum(b.mass * b.velocity for b in part) / m
            v1 = vc + np.asarray(sc.gravity) * sc.t_end
            e += 0.5 * m * max(float(vc @ vc), float(v1 @ v1))
    e = energy_bound(sc, e)
    return e if e > 0 else 1.0


def _drops(sc, up):
    """({body: m times the largest drop of its centre of mass (kg m)}, [falling parts, each
    a list of bodies]) over the spanning tree (module docstring)."""
    by = {b.name: b for b in sc.bodies}
    st = spanning_tree(sc.bodies, sc.joints)
    rules: dict = {}
    drops: dict = {}
    falling: dict = {}  # the root of each falling part -> its bodies

    def point(body, anchor):
        b = by[body]
        return b.position + b.rotation @ np.asarray(anchor, dtype=float)

    for name in st.order:
        parent, k = st.parent[name]
        b = by[name]
        rule = (_FALL, None, 0.0, None)  # a floating root: its part falls
        if k is not None:
            rule = _rule(sc.joints[k], name, b, parent, rules, up, point)
        rules[name] = rule
        if rule[0] == _FALL:
            root = name
            while st.parent[root][0] is not None and rules[st.parent[root][0]][0] == _FALL:
                root = st.parent[root][0]
            falling.setdefault(root, []).append(b)
            continue
        drops[name] = b.mass * max(0.0, float(up @ b.position) - _lowest(rule, up, b.position))
    return drops, list(falling.values())


def _rule(j, name, b, parent, rules, up, point):
    """How the joint ``j`` lets body ``name`` (``b``) move, given its parent's rule."""
    child_is_a = j.body_a == name
    C = point(name, j.anchor_a if child_is_a else j.anchor_b)
    axis = j.axis_a if child_is_a else j.axis_b
    n = None if axis is None else b.rotation @ np.asarray(axis, dtype=float)
    if parent is None:
        hC, prule = float(up @ C), (_KEEP, C, float(up @ C), None)
    else:
        prule = rules[parent]
        hC = _lowest(prule, up, C)
    if prule[0] == _FALL:
        rule = (_FALL, None, 0.0, None)
    elif j.kind in ("spherical", "fixed_point", "universal"):
        rule = (_ANY, C, hC, None)
    elif j.kind == "revolute":
        rule = (_CIRCLE, C, hC, n) if prule[0] == _KEEP else (_ANY, C, hC, None)
    else:  # prismatic, cylindrical: held only on a level axis from a body that keeps
        level = abs(float(up @ n)) <= LEVEL_TOL
        if not level or prule[0] != _KEEP:
            rule = (_FALL, None, 0.0, None)
        elif j.kind == "prismatic":
            rule = (_KEEP, C, hC, None)
        else:
            rule = (_CIRCLE, C, hC, n)
    return rule


__all__ = ["LEVEL_TOL", "energy_in_play"]
