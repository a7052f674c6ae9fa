"""The contact closed forms (references/exact/contact.py) against independent computations:
textbook formulas written out here, event-driven integrations of the Newton-Euler equations
with the Coulomb and Newton laws (scipy, written for this test), and an energy quadrature.
Each tolerance says where it comes from."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp

from references.exact._util import ReferenceNotApplicable, rot_axis
from references.exact.contact import Bounce, Resting, Rolling, SlidingBlock, TippingBlock

G = 9.81
#: closed forms evaluated in double precision: a few ulps of O(1) quantities
TIGHT = 1e-12
#: event-driven integrations at rtol 1e-12: their own error, ~1e-10 over these horizons
ODE = 1e-8


def _Ry(th):
    return rot_axis(np.array([0.0, 1.0, 0.0]), th)[0]


def _incline(th):
    """The unit normal (sin th, 0, cos th) of a plane tilted by th about +y: it falls towards
    +x, downhill (cos th, 0, -sin th)."""
    return np.array([math.sin(th), 0.0, math.cos(th)])


# -- sliding block -------------------------------------------------------------------------


@pytest.mark.parametrize("deg, mu", [(15.0, 0.4), (30.0, 0.4), (21.0, 0.3839)])
def test_block_on_incline_textbook(deg, mu):
    th = math.radians(deg)
    n = _incline(th)
    R = _Ry(th)
    half = [0.1, 0.1, 0.1]
    blk = SlidingBlock(1.5, half, 0.1 * n, R, n, mu, [0.0, 0.0, -G])
    t = np.linspace(0.0, 1.0, 11)
    m = blk.motion(t)
    sticks = math.tan(th) <= mu
    assert m.facts["sticks"] == sticks
    a = 0.0 if sticks else G * (math.sin(th) - mu * math.cos(th))  # textbook
    assert m.facts["acceleration"] == pytest.approx(a, rel=TIGHT, abs=TIGHT)
    assert m.facts["normal_force"] == pytest.approx(1.5 * G * math.cos(th), rel=TIGHT)
    s = np.linalg.norm(m.x[:, 0] - 0.1 * n, axis=1)
    assert np.allclose(s, 0.5 * a * t * t, rtol=TIGHT, atol=TIGHT)
    if not sticks:  # downhill: along the slope, descending
        d = m.facts["direction"]
        assert abs(d @ n) < TIGHT and d[2] < 0


def test_contact_md_example():
    """docs (background) example: mu = 0.4, th = 30 deg: a = 1.5067 m/s^2 (5 digits given)."""
    th = math.radians(30.0)
    n = _incline(th)
    blk = SlidingBlock(1.0, [0.1] * 3, 0.1 * n, _Ry(th), n, 0.4, [0, 0, -G])
    assert blk.facts["acceleration"] == pytest.approx(1.5067, abs=5e-5)


@pytest.mark.parametrize("frac", [0.8, 1.2])
@pytest.mark.parametrize("angle", [0.0, 45.0, 113.0])
def test_push_isotropic(frac, angle):
    """A push F at any direction: sticks iff F <= mu m g; else a = F/m - mu g along F."""
    mu, m = 0.5, 2.0
    F = frac * mu * m * G
    A = math.radians(angle)
    f = [F * math.cos(A), F * math.sin(A), 0.0]
    blk = SlidingBlock(
        m,
        [0.1, 0.1, 0.1],
        [0, 0, 0.1],
        np.eye(3),
        [0, 0, 1],
        mu,
        [0, 0, -G],
        [(f, [0.0, 0.0, 0.0])],
    )
    assert blk.facts["sticks"] == (frac <= 1.0)
    a = max(F / m - mu * G, 0.0)
    assert blk.facts["acceleration"] == pytest.approx(a, abs=TIGHT)
    if a > 0:
        assert np.allclose(blk.facts["direction"], [math.cos(A), math.sin(A), 0.0], atol=TIGHT)
    # the friction balances exactly in the stick case
    if frac <= 1.0:
        assert np.allclose(blk.facts["friction_force"], -np.array(f), atol=TIGHT)


def test_block_that_would_tip_is_refused():
    """A tall block pushed at its top tips: no sliding closed form."""
    half = [0.05, 0.05, 0.3]
    with pytest.raises(ReferenceNotApplicable, match="tips"):
        SlidingBlock(
            1.0,
            half,
            [0, 0, 0.3],
            np.eye(3),
            [0, 0, 1],
            0.8,
            [0, 0, -G],
            [([0.7 * G, 0, 0], [0.0, 0.0, 0.3])],
        )
    # the same push at the centre of mass of a cube slides without tipping
    SlidingBlock(
        1.0,
        [0.1] * 3,
        [0, 0, 0.1],
        np.eye(3),
        [0, 0, 1],
        0.5,
        [0, 0, -G],
        [([0.7 * G, 0, 0], [0.0, 0.0, 0.0])],
    )


def test_block_not_flat_is_refused():
    with pytest.raises(ReferenceNotApplicable, match="flat"):
        SlidingBlock(1.0, [0.1] * 3, [0, 0, 0.2], _Ry(0.3), [0, 0, 1], 0.5, [0, 0, -G])


# -- rolling ---------------------------------------------------------------------------------


def _sphere_ode(m, r, k, mu, n, g, x0, v0, w0, t_end, t_eval, slide_first=False):
    """Independent: Newton-Euler for a round body on a plane through its centre's height,
    written in 3D vectors. Sliding: f = -mu N u/|u| (u the contact point's velocity);
    rolling: the contact force from the no-slip constraint solved as a linear system. An event
    ends sliding when |u| falls below 1e-12 and rolling when the required friction exceeds
    mu N. Returns x (n, 3), v (n, 3), w (n, 3) world."""
    I = k * m * r * r
    c = -r * n  # contact point from the centre

    def slip(y):
        v, w = y[3:6], y[6:9]
        return v + np.cross(w, c)

    def sliding(t, y):
        u = slip(y)
        N = -m * float(g @ n)
        f = -mu * N * u / np.linalg.norm(u)
        a = g + (N * n + f) / m
        alpha = np.cross(c, f) / I
        return np.concatenate([y[3:6], a, alpha])

    def rolling_force(y):
        # unknown tangential f (2 in-plane components): a = g + (N n + f)/m,
        # alpha = c x f / I, and d/dt u = a + alpha x c = 0 (in-plane)
        N = -m * float(g @ n)
        A = np.zeros((3, 3))
        for i in range(3):
            e = np.eye(3)[i]
            A[:, i] = e / m + np.cross(np.cross(c, e) / I, c)
        rhs = -(g + N * n / m)
        f, *_ = np.linalg.lstsq(A, rhs, rcond=None)
        f = f - (f @ n) * n
        return f, N

    def rolling(t, y):
        f, N = rolling_force(y)
        a = g + (N * n + f) / m
        a = a - (a @ n) * n
        alpha = np.cross(c, f) / I
        return np.concatenate([y[3:6], a, alpha])

    def stop_slip(t, y):
        return np.linalg.norm(slip(y)) - 1e-10

    stop_slip.terminal, stop_slip.direction = True, -1

    y = np.concatenate([x0, v0, w0])
    ts, ys = [], []
    t0 = 0.0
    while t0 < t_end:
        if np.linalg.norm(slip(y)) > 1e-9 or (slide_first and t0 == 0.0):
            sol = solve_ivp(
                sliding,
                (t0, t_end),
                y,
                method="DOP853",
                rtol=1e-12,
                atol=1e-14,
                events=stop_slip,
                dense_output=True,
            )
        else:
            f, N = rolling_force(y)
            assert np.linalg.norm(f) <= mu * N * (1 + 1e-12), "test set-up: it cannot roll"
            sol = solve_ivp(
                rolling, (t0, t_end), y, method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True
            )
        t1 = sol.t[-1]
        sel = (t_eval >= t0) & (t_eval <= t1)
        if sel.any():
            ts.append(t_eval[sel])
            ys.append(sol.sol(t_eval[sel]).T)
        y = sol.y[:, -1].copy()
        t0 = t1
    Y = np.concatenate(ys)
    return Y[:, 0:3], Y[:, 3:6], Y[:, 6:9], np.concatenate(ts)


@pytest.mark.parametrize(
    "v0, rw0, label",
    [(2.0, 0.0, "plain"), (1.0, 3.0, "topspin"), (2.0, -2.0, "backspin"), (1.0, -3.0, "returns")],
)
def test_sphere_sliding_into_rolling(v0, rw0, label):
    m, r, k, mu = 1.0, 0.1, 0.4, 0.3
    n = np.array([0.0, 0.0, 1.0])
    e = np.array([1.0, 0.0, 0.0])
    roll = Rolling(m, r, k, [0, 0, r], np.eye(3), n, e, v0, rw0 / r, mu, [0, 0, -G])
    # contact.md / textbook: t* = 2 |v0 - r w0| / (7 mu g), v* = (5 v0 + 2 r w0) / 7
    t_star = 2.0 * abs(v0 - rw0) / (7.0 * mu * G)
    v_star = (5.0 * v0 + 2.0 * rw0) / 7.0
    assert roll.t_roll == pytest.approx(t_star, rel=TIGHT)
    assert roll.v_roll == pytest.approx(v_star, rel=TIGHT, abs=TIGHT)
    t = np.linspace(0.0, 1.0, 41)
    mo = roll.motion(t)
    I = k * m * r * r
    lost = 0.5 * m * v0**2 + 0.5 * I * (rw0 / r) ** 2 - 0.5 * (1 + k) * m * v_star**2
    assert mo.facts["energy_lost"] == pytest.approx(lost, rel=1e-12)
    # the 3-D event-driven integration, independent of the closed form
    a = np.cross(n, e)
    x, v, w, tt = _sphere_ode(
        m, r, k, mu, n, np.array([0, 0, -G]), np.array([0, 0, r]), v0 * e, rw0 / r * a, 1.0, t
    )
    assert np.allclose(tt, t)
    assert np.max(np.abs(x - mo.x[:, 0])) < ODE
    assert np.max(np.abs(v - mo.v[:, 0])) < ODE
    w_cf = np.einsum("nij,nj->ni", mo.R[:, 0], mo.W[:, 0])
    assert np.max(np.abs(w - w_cf)) < ODE / r


@pytest.mark.parametrize("k, name", [(0.4, "sphere"), (0.5, "cylinder")])
@pytest.mark.parametrize("mu", [0.3, 0.1])
def test_round_body_on_incline(k, name, mu):
    th = math.radians(30.0)
    r, m = 0.1, 2.0
    n = np.array([math.sin(th), 0.0, math.cos(th)])
    down = np.array([math.cos(th), 0.0, -math.sin(th)])
    roll = Rolling(m, r, k, r * n, np.eye(3), n, down, 0.0, 0.0, mu, [0, 0, -G])
    threshold = k * math.tan(th) / (1 + k)  # contact.md
    rolls = mu >= threshold
    assert roll.can_roll == rolls
    t = np.linspace(0.0, 0.8, 17)
    mo = roll.motion(t)
    s = (mo.x[:, 0] - r * n) @ down
    a = G * math.sin(th) / (1 + k) if rolls else G * (math.sin(th) - mu * math.cos(th))
    assert np.allclose(s, 0.5 * a * t * t, rtol=TIGHT, atol=TIGHT)
    spin = np.einsum("nij,nj->ni", mo.R[:, 0], mo.W[:, 0]) @ np.cross(n, down)
    wdot = a / r if rolls else mu * G * math.cos(th) / (k * r)
    assert np.allclose(spin, wdot * t, rtol=TIGHT, atol=TIGHT)
    if not rolls:  # the integration needs a slip direction: 1e-12 m/s downhill
        x, *_ = _sphere_ode(
            m,
            r,
            k,
            mu,
            n,
            np.array([0, 0, -G]),
            r * n,
            1e-12 * down,
            np.zeros(3),
            0.8,
            t,
            slide_first=True,
        )
        assert np.max(np.abs(x - mo.x[:, 0])) < ODE


def test_rolling_attitude_turns_with_the_distance():
    """Rolling without slip: the angle turned is the distance over r (a rolled ball's marker)."""
    r = 0.05
    roll = Rolling(
        1.0, r, 0.4, [0, 0, r], np.eye(3), [0, 0, 1], [1, 0, 0], 1.0, 20.0, 0.5, [0, 0, -G]
    )
    t = np.linspace(0, 0.5, 6)
    mo = roll.motion(t)
    ang = np.arctan2(mo.R[:, 0, 0, 2], mo.R[:, 0, 0, 0])  # rotation about +y
    dist = mo.x[:, 0, 0]
    wrapped = np.angle(np.exp(1j * (ang - dist / r)))
    assert np.max(np.abs(wrapped)) < 1e-12


# -- bounce ----------------------------------------------------------------------------------


def _bounce_ode(z0, e, t_end, t_eval):
    """Independent: event-driven free flight with Newton's impact law (rebound -e v)."""
    out = np.full(len(t_eval), np.nan)
    y, t0, impacts = np.array([z0, 0.0]), 0.0, []

    def hit(t, y):
        return y[0]

    hit.terminal, hit.direction = True, -1
    while t0 < t_end and len(impacts) < 30:
        sol = solve_ivp(
            lambda t, y: [y[1], -G],
            (t0, t_end),
            y,
            events=hit,
            rtol=1e-13,
            atol=1e-15,
            dense_output=True,
        )
        sel = (t_eval >= t0) & (t_eval <= sol.t[-1])
        if sel.any():
            out[sel] = sol.sol(t_eval[sel])[0]
        if sol.status != 1:
            break
        impacts.append(sol.t[-1])
        vz = -e * sol.y[1, -1]
        if vz < 1e-9:
            out[t_eval > sol.t[-1]] = 0.0
            break
        y, t0 = np.array([0.0, vz]), sol.t[-1]
    return out, impacts


@pytest.mark.parametrize("e", [0.0, 0.5])
def test_bounce(e):
    z0, r = 0.5, 0.1
    b = Bounce(z0, [0, 0, z0 + r], np.eye(3), [0, 0, 1], e, [0, 0, -G])
    t = np.linspace(0.0, 1.6, 801)
    mo = b.motion(t)
    z = mo.x[:, 0, 2] - r
    ref, impacts = _bounce_ode(z0, e, 1.6, t)
    ok = np.isfinite(ref)
    assert np.max(np.abs(z[ok] - ref[ok])) < ODE
    n = min(len(impacts), 4)
    assert np.allclose(mo.facts["impact_times"][:n], impacts[:n], atol=1e-9)
    h = mo.facts["rebound_heights"]
    if e == 0:
        assert h == [0.0] and mo.facts["rest_time"] == pytest.approx(math.sqrt(2 * z0 / G))
        assert np.all(np.abs(z[t > math.sqrt(2 * z0 / G)]) < 1e-15)
    else:  # contact.md: h_n = e^(2n) h0
        assert np.allclose(h[:3], [z0 * e**2, z0 * e**4, z0 * e**6], rtol=TIGHT)
        # Zeno time: the sum of the flights
        assert mo.facts["rest_time"] == pytest.approx(
            math.sqrt(2 * z0 / G) * (1 + e) / (1 - e), rel=TIGHT
        )


def test_bounce_spin_kept():
    W0 = np.array([0.0, 0.0, 7.0])
    b = Bounce(0.2, [0, 0, 0.3], np.eye(3), [0, 0, 1], 0.5, [0, 0, -G], W0=W0)
    t = np.array([0.0, 0.3, 0.9])
    mo = b.motion(t)
    assert np.allclose(mo.W[:, 0], W0)
    assert np.allclose(mo.R[2, 0], rot_axis(np.array([0, 0, 1.0]), 7.0 * 0.9)[0], atol=1e-14)


# -- tipping ---------------------------------------------------------------------------------


def test_tipping_block_against_energy_quadrature():
    """phi(t) from the ODE against t(phi) from the energy integral, written independently in
    2-D: the centre of mass at distance d from the edge, at angle psi0 = atan(w/h) from the
    slope's normal, gravity at angle th from the normal: the height of the centre of mass above
    the edge along the vertical is d cos(psi0 - th - phi) ... its potential drop
    dV(phi) = m g d (cos(psi0 - th) - cos(psi0 - th - phi))."""
    th = math.radians(20.0)
    w, h, m, mu = 0.05, 0.2, 1.0, 0.8
    I = m / 3.0 * np.array([w * w + h * h, w * w + h * h, 2 * w * w])  # a box's moments
    n = np.array([math.sin(th), 0.0, math.cos(th)])
    # the slope falls towards +x' with n tilted towards +x: downhill is (cos th, 0, -sin th)
    blk = TippingBlock(m, I, [w, w, h], h * n, _Ry(th), n, mu, [0, 0, -G])
    d = math.hypot(w, h)
    psi0 = math.atan2(w, h)
    Ip = I[0] + m * d * d  # the box's axis through the edge is along y (a body axis)
    assert blk.Ip == pytest.approx(Ip, rel=TIGHT)

    def dV(phi):
        return m * G * d * (math.cos(psi0 - th) - math.cos(psi0 - th - phi))

    def t_of(phi):
        # t = int_0^phi dphi / sqrt(2 dV / Ip); phi = s^2 removes the 1/sqrt singularity
        def f(s):
            if s > 0:
                return 2 * s / math.sqrt(2 * dV(s * s) / Ip)
            return 2 / math.sqrt(2 * m * G * d * math.sin(th - psi0) / Ip)

        return quad(f, 0.0, math.sqrt(phi), epsabs=1e-13, epsrel=1e-11)[0]

    t = np.linspace(0.0, 0.35, 36)
    mo = blk.motion(t)
    Q = mo.R[:, 0] @ _Ry(th).T  # the rotation since t = 0, about +y
    ang = np.arctan2(Q[:, 0, 2], Q[:, 0, 0])
    for k in (10, 20, 35):
        assert t_of(ang[k]) == pytest.approx(t[k], abs=1e-9)
    assert mo.accuracy["attitude"] < 1e-9
    assert mo.facts["max_friction_ratio"] < 1.0 and mo.facts["min_normal"] > 0


def test_tipping_refused_when_it_would_not_tip_or_slips():
    th = math.radians(10.0)
    n = np.array([math.sin(th), 0.0, math.cos(th)])
    I = [0.01, 0.01, 0.01]
    with pytest.raises(ReferenceNotApplicable, match="does not tip"):
        TippingBlock(1.0, I, [0.1, 0.1, 0.1], 0.1 * n, _Ry(th), n, 0.8, [0, 0, -G])
    th = math.radians(20.0)
    n = np.array([math.sin(th), 0.0, math.cos(th)])
    blk = TippingBlock(1.0, I, [0.05, 0.05, 0.2], 0.2 * n, _Ry(th), n, 0.25, [0, 0, -G])
    with pytest.raises(ReferenceNotApplicable, match="slips"):
        blk.motion(np.linspace(0, 0.3, 4))


# -- resting -------------------------------------------------------------------------------


def test_stack_support_forces():
    m = [1.0, 2.0, 3.0]  # bottom, middle, top
    x0 = [[0, 0, 0.1], [0, 0, 0.3], [0, 0, 0.5]]
    rest = Resting(m, x0, [np.eye(3)] * 3, [-1, 0, 1], [0, 0, -G])
    mo = rest.motion(np.array([0.0, 1.0]))
    assert np.allclose(mo.facts["support_forces"], [6 * G, 5 * G, 3 * G], rtol=TIGHT)
    assert np.all(mo.v == 0) and np.allclose(mo.x[1], x0)
    with pytest.raises(ReferenceNotApplicable, match="cycle"):
        Resting(m, x0, [np.eye(3)] * 3, [2, 0, 1], [0, 0, -G])


def test_bounce_on_a_slider_along_the_normal_only():
    """slider_drop (the ball of drop_e05 on a vertical prismatic joint): the bounce closed
    form takes it and gives drop_e05's motion (the slider carries nothing); a slider whose
    axis is not the plane's normal, or a hinge, is refused with the reason."""
    import dataclasses

    import scenarios
    from references.exact.contact_scene import builder

    sc = scenarios.load("slider_drop")
    t = np.linspace(0.0, 1.0, 101)
    got = builder(sc).motion(t)
    want = builder(scenarios.load("drop_e05")).motion(t)
    assert np.array_equal(got.x, want.x)
    (j,) = sc.joints
    tilted = dataclasses.replace(
        j, axis_a=np.array([0.0, 0.1, 1.0]), axis_b=np.array([0.0, 0.1, 1.0])
    )
    with pytest.raises(ReferenceNotApplicable, match="is not the plane's normal"):
        builder(sc.replace(joints=(tilted,)))
    hinge = dataclasses.replace(j, kind="revolute")
    with pytest.raises(ReferenceNotApplicable, match="single prismatic joint"):
        builder(sc.replace(joints=(hinge,)))
