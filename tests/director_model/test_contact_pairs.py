"""director_model.contact's body-body pairs (sphere-sphere, sphere-box, capsule-sphere, box-box)
against closed forms written out here, and the pairs it refuses.

Closed forms (rigid bodies, Coulomb friction mu, Newton restitution e):

- head-on impact of two spheres (masses m1, m2, approach along the line of centres): momentum
  m1 v1 + m2 v2 is kept and the relative normal velocity reverses scaled by e, so
  v1' = (m1 v1 + m2 v2 - m2 e (v1 - v2)) / (m1 + m2), v2' = (m1 v1 + m2 v2 + m1 e (v1 - v2))
  / (m1 + m2); the kinetic energy lost is (1 - e^2) m1 m2 (v1 - v2)^2 / (2 (m1 + m2)). The
  impact happens inside a step, but without gravity the velocities are constant before and
  after it and the scheme's impact law uses the approach speed at the start of the step: the
  velocities after the impact are exact to round-off (1e-12 m/s on speeds of 1 m/s); the
  positions err by the event's timing (at most |v| dt).
- bodies resting on each other (sphere on a box on the ground; a sphere on a capsule lying on
  the ground): no motion; each support carries the weight of everything above it. The contact
  impulses are the solver's solution to its certified residual (RES_TOL = 256 eps of the
  impulse scale): 1e-11 relative on forces; positions to 1e-12 m as the stack of boxes in
  test_contact.py.
- a sphere launched sliding on top of a box that rests on the ground (mu_ground large enough
  that the box sticks): the sphere slides into rolling exactly as on the ground, v* = 5/7 v0 at
  t* = 2 v0 / (7 mu g) (solid sphere, no initial spin); the box never moves. v* is reached
  in a step at constant deceleration: exact to round-off; t* to the step.
"""

from __future__ import annotations

import numpy as np
import pytest

from director_model.contact import (
    Body,
    Box,
    Capsule,
    ContactScene,
    Cylinder,
    InvalidContactError,
    Pair,
    Plane,
    Sphere,
    simulate_contact,
)

G = 9.81


def _two_spheres(v1, v2, e, m1=1.0, m2=2.0, r1=0.1, r2=0.15, mu=0.3):
    s1, s2 = Sphere(r1), Sphere(r2)
    return ContactScene(
        [Body("one", m1, s1.inertia(m1), position=(0.0, 0.0, 0.0), velocity=(v1, 0.0, 0.0)),
         Body("two", m2, s2.inertia(m2), position=(0.5, 0.0, 0.0), velocity=(v2, 0.0, 0.0))],
        {"one": s1, "two": s2}, pairs=[Pair("one", "two", mu=mu, e=e)], gravity=(0, 0, 0),
    )  # fmt: skip


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_head_on_spheres_leave_with_momentum_kept_and_relative_speed_times_e(e):
    m1, m2, v1, v2, dt = 1.0, 2.0, 2.0, -1.0, 1e-3
    tr = simulate_contact(_two_spheres(v1, v2, e, m1, m2), dt=dt, t_end=0.3)
    p = m1 * v1 + m2 * v2
    w1 = (p - m2 * e * (v1 - v2)) / (m1 + m2)
    w2 = (p + m1 * e * (v1 - v2)) / (m1 + m2)
    vx = tr.velocity[:, :, 0]
    after = np.flatnonzero(vx[:, 0] != v1)
    assert after.size > 0  # they met: the gap 0.25 m closes at 3 m/s in 0.083 s
    k = after[0]
    # meeting time: gap / closing speed, inside the step that ends at t[k]
    assert tr.t[k] - dt <= 0.25 / (v1 - v2) <= tr.t[k] + 1e-12
    np.testing.assert_allclose(vx[k:, 0], w1, rtol=0, atol=1e-12)
    np.testing.assert_allclose(vx[k:, 1], w2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m1 * vx[:, 0] + m2 * vx[:, 1], p, rtol=0, atol=1e-12)
    assert np.abs(tr.velocity[:, :, 1:]).max() <= 1e-12  # head on: nothing sideways
    assert np.abs(tr.omega_body).max() <= 1e-12  # and no spin from friction
    lost = (1 - e * e) * m1 * m2 * (v1 - v2) ** 2 / (2 * (m1 + m2))
    assert abs((tr.energy[0] - tr.energy[-1]) - lost) <= 1e-12 * tr.energy[0]
    assert tr.penetration.max() <= 1e-12
    # the spheres never overlap: centre distance >= r1 + r2 (to the length tolerance)
    d = tr.position[:, 1, 0] - tr.position[:, 0, 0]
    assert d.min() >= 0.25 - 1e-12


def _sphere_on_box_on_ground(v0=0.0, mu_top=0.5, mu_ground=2.0, ms=1.0, mb=3.0, ball_first=True):
    top = Pair("ball", "box", mu=mu_top) if ball_first else Pair("box", "ball", mu=mu_top)
    s, b = Sphere(0.1), Box((0.5, 0.5, 0.05))
    return ContactScene(
        [Body("box", mb, b.inertia(mb), position=(0.0, 0.0, 0.05)),
         Body("ball", ms, s.inertia(ms), position=(-0.3, 0.0, 0.2), velocity=(v0, 0.0, 0.0))],
        {"box": b, "ball": s}, {"ground": Plane((0.0, 0.0, 1.0), 0.0)},
        [Pair("box", "ground", mu=mu_ground), top],
        gravity=(0.0, 0.0, -G),
    )  # fmt: skip


@pytest.mark.parametrize("ball_first", [True, False])
def test_sphere_resting_on_a_box_resting_on_the_ground(ball_first):
    ms, mb = 1.0, 3.0
    sc = _sphere_on_box_on_ground(ms=ms, mb=mb, ball_first=ball_first)
    tr = simulate_contact(sc, dt=1e-3, t_end=2.0, save_every=50)
    assert np.abs(tr.position - tr.position[0]).max() <= 1e-12
    # pair_force is on the pair's first body: the box from the ground; the ball from the box
    # for Pair("ball", "box"), the box from the ball for Pair("box", "ball")
    f = tr.pair_force[1:]
    np.testing.assert_allclose(f[:, 0, 2], (ms + mb) * G, rtol=1e-11)
    np.testing.assert_allclose(f[:, 1, 2], (1 if ball_first else -1) * ms * G, rtol=1e-11)
    assert np.abs(f[:, :, :2]).max() <= 1e-11 * G
    assert tr.penetration.max() <= 1e-12


def test_sphere_slides_into_rolling_on_top_of_a_box_that_sticks():
    v0, mu, dt = 1.5, 0.3, 1e-3
    tr = simulate_contact(_sphere_on_box_on_ground(v0=v0, mu_top=mu), dt=dt, t_end=0.4)
    t_star = 2 * v0 / (7 * mu * G)  # 0.1456 s: the ball is 0.21 m on, still on the box
    vx = tr.velocity[:, 1, 0]
    roll = np.flatnonzero(np.abs(vx - 5 * v0 / 7) <= 1e-12)
    assert roll.size > 0 and tr.t[roll[0]] - dt <= t_star <= tr.t[roll[0]]
    np.testing.assert_allclose(vx[roll[0] :], 5 * v0 / 7, rtol=0, atol=1e-12)
    # before t*: decelerating at mu g exactly (a constant acceleration: no truncation error)
    pre = tr.t < t_star - dt
    np.testing.assert_allclose(vx[pre], v0 - mu * G * tr.t[pre], rtol=0, atol=1e-12)
    # the box sticks: mu m_s g = 2.9 N on it, below mu_ground (m_s + m_b) g = 78 N
    assert np.abs(tr.position[:, 0] - tr.position[0, 0]).max() <= 1e-12
    assert tr.penetration.max() <= 1e-12


def test_sphere_resting_on_a_capsule_lying_on_the_ground():
    # a capsule (r 0.05, half length 0.2, axis along x) on the ground: its two end spheres'
    # lowest points touch it; a sphere on top at its middle: the ground carries both weights,
    # shared equally between the ends (symmetry), the capsule carries the sphere's
    ms, mc = 0.5, 2.0
    cap, s = Capsule(0.05, 0.2), Sphere(0.08)
    along_x = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    sc = ContactScene(
        [Body("cap", mc, cap.inertia(mc), position=(0.0, 0.0, 0.05), rotation=along_x),
         Body("ball", ms, s.inertia(ms), position=(0.0, 0.0, 0.18))],
        {"cap": cap, "ball": s}, {"ground": Plane((0.0, 0.0, 1.0), 0.0)},
        [Pair("cap", "ground", mu=0.5), Pair("ball", "cap", mu=0.5)], gravity=(0.0, 0.0, -G),
    )  # fmt: skip
    tr = simulate_contact(sc, dt=1e-3, t_end=1.0, save_every=50)
    assert np.abs(tr.position - tr.position[0]).max() <= 1e-12
    f = tr.pair_force[1:]
    np.testing.assert_allclose(f[:, 0, 2], (ms + mc) * G, rtol=1e-11)
    np.testing.assert_allclose(f[:, 1, 2], ms * G, rtol=1e-11)
    assert np.abs(f[:, :, :2]).max() <= 1e-11 * G


@pytest.mark.parametrize(
    ("a", "b", "words"),
    [
        (Capsule(0.05, 0.2), Capsule(0.05, 0.2), "segment"),
        (Capsule(0.05, 0.2), Box((0.1, 0.1, 0.1)), "not implemented"),
        (Cylinder(0.1, 0.1), Sphere(0.1), "not implemented"),
        (Cylinder(0.1, 0.1), Box((0.1, 0.1, 0.1)), "not implemented"),
    ],
)
def test_body_pairs_not_treated_exactly_are_refused_with_the_reason(a, b, words):
    with pytest.raises(InvalidContactError, match=words) as err:
        ContactScene(
            [Body("a", 1.0, a.inertia(1.0), position=(0.0, 0.0, 0.0)),
             Body("b", 1.0, b.inertia(1.0), position=(1.0, 0.0, 0.0))],
            {"a": a, "b": b}, pairs=[Pair("a", "b", mu=0.5)],
        )  # fmt: skip
    assert "'a'" in str(err.value) and "'b'" in str(err.value)
