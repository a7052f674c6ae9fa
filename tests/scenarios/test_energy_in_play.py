"""The energy scale of a system is the energy in play (scenarios/energy.py): the largest
kinetic energy the motion can reach, T0 + V0 - V_low.

Checked against values it does not compute: the kinetic energy along each system's reference
(closed forms and the reduced-coordinate reference, which conserve energy) never exceeds the
scale, and the scale is no more than a small multiple of it; a heavy body on a level slider
adds its own kinetic energy and nothing else (hand computation); hand-computed cases of each
joint rule.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import scenarios
from references.engines.exact.system import reference
from scenarios.energy import energy_in_play


def kinetic(sc, tr) -> np.ndarray:
    """Kinetic energy along a system trajectory (J), written out here."""
    T = np.zeros(len(tr.t))
    for k, b in enumerate(sc.bodies):
        v, W = tr.velocity[:, k], tr.omega_body[:, k]
        T += 0.5 * b.mass * np.sum(v * v, axis=1) + 0.5 * np.sum(W * W * b.inertia, axis=1)
    return T


#: (system, the largest E_c / max T along its reference): each a hand-checked figure, e.g. the
#: four-bar's loop is not used by the bound (the coupler may "fall" 0.5 m): 27.26 / 17.45
CASES = [
    ("four_bar", 1.6),
    ("conical_pendulum", 2.0),
    ("iftomm_a02_n2", 1.2),
    ("double_pendulum_3d", 2.0),
    ("slider_crank_spatial", 2.0),
]


@pytest.mark.parametrize("name, ratio", CASES)
def test_the_scale_bounds_the_kinetic_energy_along_the_reference(name, ratio):
    sc = scenarios.load(name)
    t = np.linspace(0.0, min(sc.t_end, 3.0), 301)
    if sc.reference == "numerical":
        from references.exact.multibody import solve
        from references.exact.multibody.loops import system_from_world

        system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity)
        sol = solve(system.tree, q0, u0, t, estimate=False, system=system)
        order = [sol.names.index(n) for n in sc.body_names]

        class Tr:
            velocity, omega_body = sol.v[:, order], sol.W[:, order]

        Tr.t = t
        tr = Tr
    else:
        tr = reference(sc, t).trajectory
    tmax = float(np.max(kinetic(sc, tr)))
    assert tmax <= sc.energy_scale * (1 + 1e-12)
    assert sc.energy_scale <= ratio * tmax, (sc.energy_scale, tmax)


def test_a_heavy_body_on_a_level_slider_adds_only_its_kinetic_energy():
    """The spatial slider-crank's 5 kg slider runs on a level rail: made 100 times heavier, the
    scale grows by its kinetic energy 1/2 (99 m) v^2 and nothing else (the former scale,
    T0 + m_tot |g| size, grew by 99 x 5 x 9.81 x 1.5 m, 7.3 kJ)."""
    sc = scenarios.load("slider_crank_spatial")
    i = sc.body_names.index("slider")
    s = sc.bodies[i]
    heavy = dataclasses.replace(s, mass=100 * s.mass, inertia=100 * s.inertia)
    sc2 = sc.replace(bodies=sc.bodies[:i] + (heavy,) + sc.bodies[i + 1 :])
    extra = 0.5 * 99 * s.mass * float(s.velocity @ s.velocity)
    assert math.isclose(sc2.energy_scale - sc.energy_scale, extra, rel_tol=1e-12)
    # the slider's potential energy is not counted at all: with it at rest the scale is that
    # of the rest of the mechanism whatever its mass
    assert sc.energy_scale < 10.0  # J; T0 = 3.8 J, the crank and rod can fall 0.06 and 0.6 m


def test_hand_computed_chain():
    """planar_chain_4: four 0.5 m links hanging from the origin on level hinges, from rest:
    link k's centre of mass can drop to -(0.5 (k - 1) + 0.25) m (the chain hanging straight),
    so E_c = |g| sum_k m_k (z_k + 0.5 (k - 1) + 0.25)."""
    sc = scenarios.load("planar_chain_4")
    g = float(np.linalg.norm(sc.gravity))
    hand = sum(b.mass * (float(b.position[2]) + 0.5 * k + 0.25) for k, b in enumerate(sc.bodies))
    assert sc.kinetic_energy0() == 0.0
    assert math.isclose(sc.energy_scale, g * hand, rel_tol=1e-12), (sc.energy_scale, g * hand)
    assert sc.energy_scale == energy_in_play(sc)


def test_a_floating_system_without_gravity_has_its_kinetic_energy():
    sc = scenarios.load("free_chain_5")
    assert not sc.has_gravity and sc.energy_scale == sc.kinetic_energy0() > 0
