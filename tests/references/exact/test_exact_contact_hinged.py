"""The hinged-strike reference (references/exact/contact_hinged.py) against computations
written for this test: the impact time by quadrature of the energy integral, energy
conservation in flight, the joint's geometry, the rebound heights read from its own states,
the support force by the moment balance about the hinge; and its refusals."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad

import scenarios
from references.exact._util import ReferenceNotApplicable
from references.exact.contact_scene import contact_motion

G = 9.81
M, R_BALL, L, TH0 = 1.0, 0.05, 0.3, math.pi / 6  # the library's hinged_strike
I_H = 0.4 * M * R_BALL**2 + M * L * L  # about the hinge: the ball's own plus m L^2


def _scene(**contact):
    sc = scenarios.load("hinged_strike")
    if contact:
        sc = sc.replace(contacts=(dataclasses.replace(sc.contacts[0], **contact),))
    return sc


def _impact_time() -> float:
    """Time to fall from TH0 to the horizontal: t = int dphi / phi', phi'^2 = 2 m g L
    (sin TH0 - sin phi)/I_H, with phi = TH0 - s^2 (no singularity at the release)."""
    k = 2.0 * M * G * L / I_H

    def f(s):
        if s == 0:
            return 2.0 / math.sqrt(k * math.cos(TH0))
        return 2.0 * s / math.sqrt(k * (math.sin(TH0) - math.sin(TH0 - s * s)))

    return quad(f, 0.0, math.sqrt(TH0), epsabs=0.0, epsrel=1e-13, limit=200)[0]


def test_impact_time_is_the_energy_quadratures():
    m = contact_motion(_scene(), np.linspace(0.0, 0.6, 61))
    # DOP853 at rtol 1e-12 with its event located to the integrator's accuracy: 1e-10 s
    assert m.facts["impact_times"][0] == pytest.approx(_impact_time(), abs=1e-10)
    assert m.facts["drop_height"] == pytest.approx(L * math.sin(TH0), abs=1e-15)


def test_flight_keeps_energy_and_the_hinge():
    t = np.linspace(0.0, 0.18, 181)  # before the impact (0.1896 s)
    m = contact_motion(_scene(), t)
    x, v, W = m.x[:, 0], m.v[:, 0], m.W[:, 0]
    hinge = np.array([0.0, 0.0, R_BALL])
    assert np.max(np.abs(np.linalg.norm(x - hinge, axis=1) - L)) < 1e-14
    E = 0.5 * M * np.sum(v * v, axis=1) + 0.5 * 0.4 * M * R_BALL**2 * np.sum(W * W, axis=1)
    E += M * G * x[:, 2]
    # the integrator's rtol 1e-12 on phi' ~ 5 rad/s and phi: ~1e-11 J on E ~ 2 J
    assert np.max(np.abs(E - E[0])) < 1e-9
    # the body turns with the rod: its x axis stays along the rod, from the hinge to the ball
    ex = m.R[:, 0, :, 0]
    assert np.max(np.linalg.norm(ex - (x - hinge) / L, axis=1)) < 1e-13


def test_rebounds_of_its_own_states_follow_newtons_law():
    """e = 0.5: the ball's greatest gap between impacts, read from the states (0.1 ms
    samples), is e^2 and e^4 times the drop; then it rests on the ground."""
    e = 0.5
    t = np.arange(0.0, 1.2, 1e-4)
    m = contact_motion(_scene(e=e), t)
    gap = m.x[:, 0, 2] - R_BALL
    t1, t2, t3 = m.facts["impact_times"][:3]
    h0 = L * math.sin(TH0)
    # sampled apexes: the gap is flat there to (phi'' L dt)^2 ~ 1e-8 m at dt 1e-4 s
    assert np.max(gap[(t > t1) & (t < t2)]) == pytest.approx(e**2 * h0, abs=1e-7)
    assert np.max(gap[(t > t2) & (t < t3)]) == pytest.approx(e**4 * h0, abs=1e-7)
    assert m.facts["rebound_heights"][:2] == pytest.approx([e**2 * h0, e**4 * h0], rel=1e-12)
    assert np.all(gap >= -1e-12)
    rest = m.facts["rest_time"]
    assert np.all(gap[t > rest] == pytest.approx(0.0, abs=1e-15))


def test_support_force_is_the_moment_balance():
    """At rest the ground's force N and gravity balance about the hinge: N L = m g L (the
    hinge at the ball centre's height, the contact below the centre)."""
    m = contact_motion(_scene(), np.linspace(0.0, 0.6, 61))
    assert m.facts["support_forces"] == pytest.approx([M * G], rel=1e-14)
    assert m.accuracy["position"] < 1e-9


@pytest.mark.parametrize(
    "change, said",
    [
        ({"mu": 0.5}, "frictionless"),
        ({"e": 1.0}, "0 <= e < 1"),
    ],
)
def test_refusals(change, said):
    with pytest.raises(ReferenceNotApplicable, match=said):
        contact_motion(_scene(**change), [0.0, 0.1])


def test_other_kinds_refuse_a_scene_with_joints():
    sc = _scene().replace(reference="rolling")
    with pytest.raises(ReferenceNotApplicable, match="free bodies"):
        contact_motion(sc, [0.0, 0.1])
    # bounce takes a prismatic joint along the normal (slider_drop), not a hinge
    with pytest.raises(ReferenceNotApplicable, match="single prismatic joint"):
        contact_motion(_scene().replace(reference="bounce"), [0.0, 0.1])
