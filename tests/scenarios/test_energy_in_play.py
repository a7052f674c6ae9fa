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


def _rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _body(sc, name, mass, X, R):
    X = np.asarray(X, float)
    return dataclasses.replace(sc.bodies[0], name=name, mass=mass, position=X, rotation=R,
                               velocity=np.zeros(3), omega_body=np.zeros(3))  # fmt: skip


@pytest.mark.parametrize("g", [9.81, 0.5])
def test_a_body_on_a_tilted_hinge_to_the_ground(g):
    """Hinged to the ground at C = (0.1, -0.2, 1) about n, 60 deg from the vertical, its
    centre of mass 0.2 m along n from C and 0.3 m off the axis (horizontally), its frame
    turned 90 deg about the vertical (so that its axis and anchor differ from the world's): it
    moves on a circle of radius 0.3 in a plane tilted 60 deg, whose lowest point is 0.3 sin 60
    below the circle's centre, the height the centre of mass starts at (hand computation; the
    offset along n does not enter): E_c = 2 x 9.81 x 0.3 sin 60 J."""
    sc = scenarios.load("planar_chain_4")
    n = np.array([math.sin(math.pi / 3), 0.0, math.cos(math.pi / 3)])
    C = np.array([0.1, -0.2, 1.0])
    X = C + 0.2 * n + 0.3 * np.array([0.0, 1.0, 0.0])
    R = _rz(math.pi / 2)
    j = dataclasses.replace(sc.joints[0], body_a="b", anchor_a=R.T @ (C - X), anchor_b=C,
                            axis_a=R.T @ n, axis_b=n)  # fmt: skip
    sc1 = sc.replace(bodies=(_body(sc, "b", 2.0, X, R),), joints=(j,),
                     gravity=np.array([0.0, 0.0, -g]))  # fmt: skip
    hand = 2.0 * g * 0.3 * math.sin(math.pi / 3)
    assert math.isclose(energy_in_play(sc1), hand, rel_tol=1e-12), (energy_in_play(sc1), hand)


@pytest.mark.parametrize("kind", ["fixed_point", "universal"])
def test_a_body_free_to_turn_about_a_point(kind):
    """A 2 kg body on a fixed point or a universal joint to the ground at C = (0, 0, 1), its
    centre of mass 0.5 m from C and 0.3 m below it: it can hang straight down, 0.2 m lower
    (hand computation): E_c = 2 x 9.81 x 0.2 J."""
    sc = scenarios.load("planar_chain_4")
    C, X = np.array([0.0, 0.0, 1.0]), np.array([0.4, 0.0, 0.7])
    R = _rz(0.3)
    axes = {"axis_a": None, "axis_b": None}
    if kind == "universal":
        axes = {"axis_a": R.T @ np.array([1.0, 0.0, 0.0]), "axis_b": np.array([0.0, 1.0, 0.0])}
    j = dataclasses.replace(sc.joints[0], kind=kind, body_a="b", anchor_a=R.T @ (C - X),
                            anchor_b=C, **axes)  # fmt: skip
    sc1 = sc.replace(bodies=(_body(sc, "b", 2.0, X, R),), joints=(j,))
    assert math.isclose(energy_in_play(sc1), 2.0 * 9.81 * 0.2, rel_tol=1e-12)


def test_a_pendulum_on_a_cart_on_a_level_rail():
    """A 3 kg cart on a level rail (prismatic along x to the ground: it keeps its height and
    attitude) and a 2 kg pendulum hinged to it about x (the cart is the joint's body_a, the
    pendulum body_b, its frame turned 90 deg about the vertical so that the two sides'
    axis components differ), its centre of mass 0.2 m along the axis and 0.3 m from it,
    horizontally: it can swing 0.3 m below the axis (hand computation); the cart adds
    nothing (at rest, it never drops): E_c = 2 x 9.81 x 0.3 J."""
    sc = scenarios.load("planar_chain_4")
    x = np.array([1.0, 0.0, 0.0])
    cart = _body(sc, "cart", 3.0, [0.0, 0.0, 0.5], np.eye(3))
    R = _rz(math.pi / 2)
    C = np.array([0.0, 0.0, 0.5])  # the hinge at the cart's centre of mass
    X = C + 0.2 * x + np.array([0.0, 0.3, 0.0])
    pend = _body(sc, "pend", 2.0, X, R)
    # the rail 0.2 m below the cart's centre of mass (were the cart free to turn about it, it
    # could drop 0.4 m)
    rail = dataclasses.replace(sc.joints[0], kind="prismatic", body_a="cart", body_b=None,
                               anchor_a=np.array([0.0, 0.0, -0.2]), anchor_b=C - [0, 0, 0.2],
                               axis_a=x, axis_b=x)  # fmt: skip
    hinge = dataclasses.replace(sc.joints[1], kind="revolute", body_a="cart", body_b="pend",
                                anchor_a=np.zeros(3), anchor_b=R.T @ (C - X), axis_a=x,
                                axis_b=R.T @ x)  # fmt: skip
    sc1 = sc.replace(bodies=(cart, pend), joints=(rail, hinge))
    assert math.isclose(energy_in_play(sc1), 2.0 * 9.81 * 0.3, rel_tol=1e-12)


def test_a_body_on_a_level_cylindrical_joint():
    """On a level cylindrical joint to the ground (axis x through C = (0, 0, 1)), its centre
    of mass 0.2 m along the axis and 0.3 m from it, level with it: it may slide and turn about
    the axis line, at most 0.3 m below it (hand computation): E_c = 2 x 9.81 x 0.3 J."""
    sc = scenarios.load("planar_chain_4")
    x, C = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    X = C + np.array([0.2, 0.3, 0.0])
    j = dataclasses.replace(sc.joints[0], kind="cylindrical", body_a="b", anchor_a=C - X,
                            anchor_b=C, axis_a=x, axis_b=x)  # fmt: skip
    sc1 = sc.replace(bodies=(_body(sc, "b", 2.0, X, np.eye(3)),), joints=(j,))
    assert math.isclose(energy_in_play(sc1), 2.0 * 9.81 * 0.3, rel_tol=1e-12)


def test_a_second_link_offset_along_its_hinge():
    """Link 1 hangs from a level hinge (x) at the origin, its centre of mass 0.25 m below
    (already its lowest); link 2 hangs from link 1's hinge point C2 = (0, 0, -0.5) about x,
    its centre of mass at C2 + (0.2, 0, -0.3). Link 1 turns C2's hinge axis with it, so link 2
    may end up anywhere |d| = sqrt(0.13) m from C2, whose own lowest point is -0.5 m (hand
    computation): E_c = 2 x 9.81 x (sqrt(0.13) - 0.3) J."""
    sc = scenarios.load("planar_chain_4")
    x = np.array([1.0, 0.0, 0.0])
    X1, C2 = np.array([0.0, 0.0, -0.25]), np.array([0.0, 0.0, -0.5])
    X2 = C2 + np.array([0.2, 0.0, -0.3])
    b1, b2 = _body(sc, "l1", 1.0, X1, np.eye(3)), _body(sc, "l2", 2.0, X2, _rz(0.4))
    h1 = dataclasses.replace(sc.joints[0], body_a="l1", anchor_a=-X1, anchor_b=np.zeros(3),
                             axis_a=x, axis_b=x)  # fmt: skip
    h2 = dataclasses.replace(sc.joints[1], kind="revolute", body_a="l1", body_b="l2",
                             anchor_a=C2 - X1, anchor_b=_rz(0.4).T @ (C2 - X2), axis_a=x,
                             axis_b=_rz(0.4).T @ x)  # fmt: skip
    sc1 = sc.replace(bodies=(b1, b2), joints=(h1, h2))
    hand = 2.0 * 9.81 * (math.sqrt(0.13) - 0.3)
    assert math.isclose(energy_in_play(sc1), hand, rel_tol=1e-12), (energy_in_play(sc1), hand)


def test_a_body_on_an_inclined_slide_falls():
    """A slide with a component along g does not hold the body up: it is counted as falling
    freely, 1/2 m (|g| t_end)^2 from rest (the module's rule, written out here)."""
    sc = scenarios.load("planar_chain_4")
    n = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0)
    X = np.array([0.2, 0.0, 0.2])
    j = dataclasses.replace(sc.joints[0], kind="prismatic", body_a="b", anchor_a=np.zeros(3),
                            anchor_b=X, axis_a=n, axis_b=n)  # fmt: skip
    sc1 = sc.replace(bodies=(_body(sc, "b", 2.0, X, np.eye(3)),), joints=(j,))
    hand = 0.5 * 2.0 * (9.81 * sc.t_end) ** 2
    assert math.isclose(energy_in_play(sc1), hand, rel_tol=1e-12), (energy_in_play(sc1), hand)


def test_without_gravity_the_scale_is_the_kinetic_energy_or_1_J():
    """No gravity: E_c = T0 (0.25 J for 2 kg at 0.5 m/s, below 1 J), and 1 J at rest."""
    sc = scenarios.load("planar_chain_4").replace(gravity=np.zeros(3))
    X = np.array([0.0, 0.0, -0.5])
    j = dataclasses.replace(
        sc.joints[0],
        body_a="b",
        anchor_a=-X,
        anchor_b=np.zeros(3),
        axis_a=np.array([1.0, 0.0, 0.0]),
        axis_b=np.array([1.0, 0.0, 0.0]),
    )
    moving = dataclasses.replace(_body(sc, "b", 2.0, X, np.eye(3)),
                                 velocity=np.array([0.0, 0.5, 0.0]),
                                 omega_body=np.array([1.0, 0.0, 0.0]))  # fmt: skip
    I = float(moving.inertia[0])
    T0 = 0.5 * 2.0 * 0.25 + 0.5 * I * 1.0
    assert T0 < 1.0
    assert math.isclose(energy_in_play(sc.replace(bodies=(moving,), joints=(j,))), T0,
                        rel_tol=1e-12)  # fmt: skip
    still = _body(sc, "b", 2.0, X, np.eye(3))
    assert energy_in_play(sc.replace(bodies=(still,), joints=(j,))) == 1.0


def _falling(parts, g, t_end):
    """1/2 M max(|v_c|^2, |v_c + g t|^2) summed over the falling parts (hand formula)."""
    e = 0.0
    for bodies in parts:
        m = sum(b.mass for b in bodies)
        vc = sum(b.mass * np.asarray(b.velocity) for b in bodies) / m
        v1 = vc + g * t_end
        e += 0.5 * m * max(float(vc @ vc), float(v1 @ v1))
    return e


def test_a_floating_chain_in_free_fall():
    """spinning_chain floats under gravity: E_c = T0 + 1/2 M max(|v_c|^2, |v_c + g t_end|^2)
    of the whole chain, one part; cut at its second joint it is two falling parts, each
    counted with its own centre of mass (written out here)."""
    sc = scenarios.load("spinning_chain")
    g = np.asarray(sc.gravity)
    T0 = sc.kinetic_energy0()
    hand = T0 + _falling([sc.bodies], g, sc.t_end)
    assert math.isclose(energy_in_play(sc), hand, rel_tol=1e-12), (energy_in_play(sc), hand)
    cut = sc.replace(joints=sc.joints[:1])
    parts = [sc.bodies[:2], sc.bodies[2:]]
    assert math.isclose(energy_in_play(cut), T0 + _falling(parts, g, sc.t_end), rel_tol=1e-12)
