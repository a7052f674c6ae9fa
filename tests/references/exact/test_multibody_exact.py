"""The exact multibody motions (references/exact/multibody/exact.py) against the independent
reduced-coordinate dynamics of the same package and against equations written out here: the
straight chain spinning rigidly while falling, the double conical pendulum in steady rotation,
and the parallelogram four-bar as a planar pendulum."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from references.exact._util import rot_axis, rotation_angle
from references.exact.multibody import rhs, solve
from references.exact.multibody.exact import (
    DoubleConicalPendulum,
    ParallelogramFourBar,
    SpinningChain,
    straight_chain,
)

G = (0.0, 0.0, -9.81)


def chain(joint):
    return straight_chain(
        masses=(1.0, 0.6, 1.4, 0.8),
        inertias=((0.01, 0.05, 0.06), (0.004, 0.02, 0.022), (0.02, 0.1, 0.11), (0.006, 0.03, 0.03)),
        anchors=((0.2, 0.25), (0.15, 0.15), (0.3, 0.2), (0.1, 0.3)),
        joint=joint,
        gravity=G,
    )


def _compare(exact, sol, t):
    x, R, v, W = exact.motion(t)
    att = float(np.max(rotation_angle(R.reshape(-1, 3, 3), sol.R.reshape(-1, 3, 3))))
    pos = float(np.max(np.linalg.norm(x - sol.x, axis=2)))
    vel = float(np.max(np.linalg.norm(v - sol.v, axis=2)))
    om = float(np.max(np.linalg.norm(W - sol.W, axis=2)))
    return att, pos, vel, om


@pytest.mark.parametrize(
    "joint, axis", [("spherical", 2), ("spherical", 1), ("revolute", 2), ("spherical", 0)]
)
def test_straight_chain_spins_rigidly_while_falling(joint, axis):
    tree = chain(joint)
    R0 = rot_axis(np.array([0.2, 0.4, 0.8]) / math.sqrt(0.84), 0.9)[0]
    exact = SpinningChain(tree, rate=5.0, axis=axis, R0=R0, x_c=(0.1, -0.2, 1.0), v_c=(0.5, 0, 2))
    q0, u0 = tree.to_joint(*exact.initial)
    t = np.linspace(0.0, 1.0, 21)
    sol = solve(tree, q0, u0, t)
    att, pos, vel, om = _compare(exact, sol, t)
    acc = exact.accuracy(t)
    # the closed form's error is round-off (acc); the reference's is its own estimate
    assert att <= sol.accuracy["attitude"] + acc["attitude"]
    assert pos <= sol.accuracy["position"] + acc["position"]
    assert vel <= sol.accuracy["velocity"] + 1e-13
    assert om <= sol.accuracy["omega"] + 1e-13
    assert att < 1e-10 and pos < 1e-10  # measured 8e-14 .. 1.5e-12 (rad and m)


def test_spinning_chain_refuses_a_bent_chain():
    tree = straight_chain((1, 1), ((1, 1, 1), (1, 1, 1)), ((0.1, 0.1), (0.1, 0.1)))
    tree.Y[1, 1] = 0.05  # anchor off the line
    from references.exact._util import ReferenceNotApplicable

    with pytest.raises(ReferenceNotApplicable, match="e1 axes"):
        SpinningChain(tree, 1.0)


def conical(rate, **kw):
    return DoubleConicalPendulum(
        m=(1.0, 0.7),
        J=((0.002, 0.03, 0.031), (0.001, 0.02, 0.02)),
        l=(0.3, 0.25),
        L1=0.6,
        g=9.81,
        rate=rate,
        **kw,
    )


def test_double_conical_pendulum_is_held_with_zero_acceleration():
    cp = conical(6.0)
    assert 0 < cp.phi[0] < cp.phi[1] < math.pi / 2
    y0 = np.concatenate([cp.q0, cp.u0])
    ydot = rhs(cp.tree, y0)
    # joint accelerations vanish to round-off of terms of size Omega^2 (36 rad/s^2)
    assert np.max(np.abs(ydot[cp.tree.nq :])) < 1e-12 * cp.rate**2
    # the balance is not trivially met: the angles of a 1 % faster rotation are not held
    other = conical(6.06)
    y1 = np.concatenate([other.q0, cp.u0])
    assert np.max(np.abs(rhs(cp.tree, y1)[cp.tree.nq :])) > 1e-2
    # and the reduced dynamics follows the closed form over 4 turns
    t = np.linspace(0.0, 4 * 2 * math.pi / cp.rate, 41)
    sol = solve(cp.tree, cp.q0, cp.u0, t)
    att, pos, vel, om = _compare(cp, sol, t)
    acc = cp.accuracy(t)
    assert att <= sol.accuracy["attitude"] + acc["attitude"]
    assert pos <= sol.accuracy["position"] + acc["position"]
    # the error grows in the twist of each link about its own axis (axial moment 15 to 20 times
    # below the transverse ones): measured 9e-8 rad over 4 turns, estimated 5e-7; the centres
    # of mass agree to 1.5e-10 m
    assert pos < 1e-9 and att < 1e-6


FOURBAR = dict(
    L=0.4,
    D=0.7,
    crank=(1.0, (0.001, 0.013, 0.0135)),
    rocker=(0.6, (0.0008, 0.009, 0.0095)),
    coupler=(1.5, (0.002, 0.06, 0.061)),
    LA=0.2,
    LB=0.25,
    coupler_com=0.35,
    g=9.81,
)


@pytest.mark.parametrize(
    "theta0, thetadot0, case",
    [(0.9, 1.0, "oscillating"), (-0.3, -12.0, "rotating"), (2.5, 0.0, "oscillating")],
)
def test_parallelogram_four_bar_against_the_pendulum_equation(theta0, thetadot0, case):
    fb = ParallelogramFourBar(theta0=theta0, thetadot0=thetadot0, **FOURBAR)
    assert fb.case == case
    t = np.linspace(0.0, 5.0, 201)
    y = solve_ivp(
        lambda _t, y: [y[1], -fb.wp2 * math.sin(y[0])],
        (0, 5),
        [theta0, thetadot0],
        "DOP853",
        t_eval=t,
        rtol=1e-13,
        atol=1e-13,
    ).y
    th, thd = fb.theta(t)
    # DOP853 at rtol 1e-13 on a pendulum over ~5 periods: measured 1e-12 apart
    assert np.max(np.abs(th - y[0])) < 1e-10
    assert np.max(np.abs(thd - y[1])) < 1e-9
    if case == "rotating":
        assert abs(th[-1] - th[0]) > 4 * math.pi  # through the vertical, turn after turn


def test_parallelogram_four_bar_bodies_close_the_loop_and_keep_energy():
    fb = ParallelogramFourBar(theta0=-0.3, thetadot0=-12.0, **FOURBAR)
    t = np.linspace(0.0, 3.0, 301)
    x, R, v, W = fb.motion(t)
    # joint points: crank tip (L along its e1) = coupler's first joint; rocker tip = second
    tipA = x[:, 0] + (fb.L - fb.LA) * R[:, 0, :, 0]
    tipB = x[:, 1] + (fb.L - fb.LB) * R[:, 1, :, 0]
    c1 = x[:, 2] - fb.coupler_com * R[:, 2, :, 0]
    c2 = c1 + fb.D * R[:, 2, :, 0]
    for a, b in ((tipA, c1), (tipB, c2)):
        assert np.max(np.linalg.norm(a - b, axis=1)) < 1e-14
    # ground pivots stay put
    assert np.max(np.abs(x[:, 0] - fb.LA * R[:, 0, :, 0])) < 1e-15
    # total energy of the three bodies, from their world states (not from the pendulum's T, V)
    E = np.zeros(len(t))
    for b, (m, J) in enumerate(fb.bodies):
        E += 0.5 * m * np.sum(v[:, b] ** 2, 1) + 0.5 * np.sum(np.asarray(J) * W[:, b] ** 2, 1)
        E += m * 9.81 * x[:, b, 2]
    scale = 9.81 * (1.0 + 0.6 + 1.5) * fb.L
    assert np.ptp(E) < 1e-13 * scale + 1e-13 * np.max(np.abs(E))
    # velocities are the time derivative of the positions (central differences, h = 1e-5 s:
    # truncation h^2 |d3x/dt3|/6 ~ 1e-7 m/s, rounding eps |x|/h ~ 1e-11)
    h = 1e-5
    dx = (fb.motion(t + h)[0] - fb.motion(t - h)[0]) / (2 * h)
    assert np.max(np.abs(dx - v)) < 1e-6 * np.max(np.abs(v))
