"""Phase observables on synthetic signals with known answers (error bounds from the cubic
interpolation remainder) and on exact reference trajectories."""

from __future__ import annotations

import math
import pickle
from types import SimpleNamespace

import numpy as np
import pytest

import scenarios
from references.exact import expected_observables, reference_trajectory
from references.exact._util import rot_x, rot_z
from references.trajectory import one_body
from reports.metrics import observables as ob
from tests.mp_roots import polyroots


def _cubic_bound(h, d4max, slope):
    """Error bound of an event time located by the 4-point cubic, the event in the middle
    interval of equally spaced nodes: |Pi (t - x_j)| <= (9/16) h^4 there, so the value error is
    <= (9/16) h^4 max|y''''|/4! = (3/128) h^4 max|y''''|, divided by the slope."""
    return 3.0 / 128.0 * h**4 * d4max / slope


# -- crossings ----------------------------------------------------------------------------------


def _sine_crossing_errors(h, T=1.3, phase=0.4, ncycles=6):
    w = 2 * math.pi / T
    t = np.arange(0.0, ncycles * T, h)
    tc = ob.crossings(t, np.sin(w * t + phase))
    k = np.arange(1, len(tc) + 1)
    exact = (k * math.pi - phase) / w  # zeros of sin(w t + phase) for t > 0
    return np.abs(tc - exact).max(), len(tc), w


def test_crossings_of_a_coarsely_sampled_sine_meet_the_cubic_bound():
    T = 1.3
    h = T / 20  # 20 samples per period
    err, n, w = _sine_crossing_errors(h)
    assert n == 12  # two per cycle, none lost or doubled
    bound = _cubic_bound(h, w**4, w)  # |sin''''| <= w^4, slope w at a zero
    assert err <= bound
    assert bound < 1e-3 * h  # far better than the sample spacing (linear: ~2e-2 h here)


def test_crossings_converge_at_fourth_order():
    e1, _, _ = _sine_crossing_errors(1.3 / 16)
    e2, _, _ = _sine_crossing_errors(1.3 / 32)
    # 4th order: ratio 16 asymptotically; 12 leaves room for the pre-asymptotic regime
    assert e1 / e2 > 12


def test_crossings_with_irregular_samples():
    rng = np.random.default_rng(7)
    t = np.cumsum(rng.uniform(0.03, 0.07, 400))
    w = 2.0
    tc = ob.crossings(t, np.cos(w * t))
    exact = (np.arange(len(tc)) + 0.5) * math.pi / w + math.pi / w * np.floor(t[0] * w / math.pi)
    # each factor of Pi (t - x_j) grows with the spacings, so |Pi| is largest with all
    # spacings at h_max: (9/16) h_max^4 for a centred stencil, < 1.0 h_max^4 for one shifted
    # at the ends of the record; value error |Pi| w^4/24, divided by the slope w
    assert np.abs(tc - exact).max() <= 1.0 * 0.07**4 * w**4 / 24 / w


def test_crossing_directions_and_samples_on_the_level():
    t = np.arange(5.0)
    assert ob.crossings(t, [-1.0, 0.0, 1.0, 2.0, 3.0]).tolist() == [1.0]
    assert ob.crossings(t, [1.0, 0.0, -1.0, 0.0, 1.0]).tolist() == [1.0, 3.0]
    assert ob.crossings(t, [1.0, 0.0, -1.0, 0.0, 1.0], direction=+1).tolist() == [3.0]
    assert ob.crossings(t, [1.0, 0.0, -1.0, 0.0, 1.0], direction=-1).tolist() == [1.0]
    assert ob.crossings(t, [1.0, 2.0, 3.0, 2.0, 1.0]).size == 0
    assert ob.crossings(t, [1.0, np.nan, -1.0, -1.0, -1.0]).size == 0
    # two samples: the linear interpolant
    assert ob.crossings([0.0, 1.0], [-1.0, 3.0]).tolist() == [0.25]


# -- flips --------------------------------------------------------------------------------------


def _tumble(h, w=0.8, t_end=20.0):
    t = np.arange(0.0, t_end + h / 2, h)
    W = np.stack([0.5 * np.sin(w * t + 0.3), 2.0 * np.cos(w * t + 0.3), 0.1 + 0 * t], 1)
    return SimpleNamespace(t=t, omega_body=W, rotation=np.tile(np.eye(3), (len(t), 1, 1)))


def test_flip_interval_of_a_synthetic_tumble():
    h, w = 0.2, 0.8
    traj = _tumble(h, w)
    assert ob.flip_axis(traj) == 1  # the largest mean |W_i|
    fi = ob.flip_interval(traj)
    assert fi.reason == "" and fi.n == 5
    # (last - first)/(n - 1): two event errors, each within the cubic bound
    bound = 2 * _cubic_bound(h, 2.0 * w**4, 2.0 * w) / (fi.n - 1)
    assert abs(fi - math.pi / w) <= bound
    # a given axis is followed instead
    t1 = ob.flip_times(traj, axis=0)
    assert np.abs(np.sin(w * t1 + 0.3)).max() < 1e-5


def test_no_flip_is_nan_with_a_reason():
    traj = _tumble(0.2)
    traj.omega_body[:, 1] += 2.5  # the dominant rate never changes sign: a stable spin
    fi = ob.flip_interval(traj)
    assert math.isnan(fi) and "sign change" in fi.reason and fi.n == 0
    traj.omega_body[3, 1] = np.nan
    fi = ob.flip_interval(traj)
    assert math.isnan(fi) and "non-finite" in fi.reason


def test_measured_behaves_like_a_float():
    m = ob.Measured(2.5, n=3)
    assert m * 2 == 5.0 and isinstance(m, float) and m.n == 3
    back = pickle.loads(pickle.dumps(ob.Measured(math.nan, "why", 1)))
    assert math.isnan(back) and back.reason == "why" and back.n == 1
    assert "why" in repr(back)


# -- tops ---------------------------------------------------------------------------------------

U0, A, NU, OMEGA, B = 0.6, 0.05, 7.0, 0.9, 0.02
Z = (0.0, 0.0, 1.0)  # the synthetic tops' vertical


def _top(h, t_end=6.0, a=A, u0=U0, phase=0.0):
    """Symmetry axis d3 with cos(tilt) u = u0 + a cos(nu t + phase) and Euler angle
    phi = Omega t + b sin(nu t) (azimuth of d3 = phi - pi/2), spin psi = 30 t."""
    t = np.arange(0.0, t_end + h / 2, h)
    th = np.arccos(u0 + a * np.cos(NU * t + phase))
    phi = OMEGA * t + B * np.sin(NU * t)
    R = rot_z(phi) @ rot_x(th) @ rot_z(30.0 * t)
    return SimpleNamespace(t=t, rotation=R, omega_body=np.zeros((len(t), 3)))


def test_nutation_period_of_a_synthetic_top():
    h = 2 * math.pi / NU / 25.3  # 25.3 samples per period: event phases differ
    traj = _top(h)
    period = ob.nutation_period(traj, 2, Z)
    assert period.reason == "" and period.n >= 5
    u = traj.rotation[:, 2, 2]
    level = u.mean()
    slope = A * NU * math.sqrt(1 - ((level - U0) / A) ** 2)  # |u'| where u crosses the level
    bound = 2 * _cubic_bound(h, A * NU**4, slope) / (period.n - 1)
    assert abs(period - 2 * math.pi / NU) <= bound


def test_precession_rate_of_a_synthetic_top():
    h = 2 * math.pi / NU / 25.3
    traj = _top(h)
    rate = ob.precession_rate(traj, 2, Z)
    # over whole nutation periods the mean of phi' is Omega exactly; errors: the azimuth
    # interpolated at two event times (cubic bound with |phi''''| <= b nu^4) and those times'
    # own errors times |phi'| <= Omega + b nu, over the span (n - 1) periods
    u = traj.rotation[:, 2, 2]
    slope = A * NU * math.sqrt(1 - ((u.mean() - U0) / A) ** 2)
    dt_event = _cubic_bound(h, A * NU**4, slope)
    span = (rate.n - 1) * 2 * math.pi / NU
    bound = 2 * (_cubic_bound(h, B * NU**4, 1.0) + dt_event * (OMEGA + B * NU)) / span
    assert abs(rate - OMEGA) <= bound


def test_tilt_range_of_a_synthetic_top():
    h = 2 * math.pi / NU / 25.3
    # about one period, so that each extreme is seen once, between samples (the best of many
    # sampled extrema would hide a missing interpolation)
    lo, hi = ob.tilt_range(_top(h, t_end=1.0, phase=0.7), 2, Z)
    # parabola through three samples: |p - f| <= max|f'''| h^3/(9 sqrt 3) on the stencil;
    # f''' of the tilt from the analytic signal on a fine grid (independent of the code)
    tf = np.linspace(0.0, 1.0, 100_001)
    th = np.arccos(U0 + A * np.cos(NU * tf + 0.7))
    d3 = np.gradient(np.gradient(np.gradient(th, tf), tf), tf)[10:-10]  # one-sided ends cut
    bound = np.abs(d3).max() * h**3 / (9 * math.sqrt(3))
    assert bound < 1e-4  # 7e-5; the nearest samples alone are off by up to 5e-4 here
    assert abs(lo - math.acos(U0 + A)) <= bound
    assert abs(hi - math.acos(U0 - A)) <= bound


def test_steady_precession_has_no_nutation():
    traj = _top(0.01, t_end=2.0, a=0.0)
    period = ob.nutation_period(traj, 2, Z)
    assert math.isnan(period) and "no nutation" in period.reason
    # no nutation: (azimuth(end) - azimuth(start))/duration; phi = Omega t + b sin(nu t)
    expect = OMEGA + B * math.sin(NU * traj.t[-1]) / traj.t[-1]
    assert ob.precession_rate(traj, 2, Z) == pytest.approx(expect, rel=1e-12)
    lo, hi = ob.tilt_range(traj, 2, Z)
    assert lo == pytest.approx(math.acos(U0), rel=1e-14) and hi == pytest.approx(lo, rel=1e-14)


def test_top_observables_refuse_what_they_cannot_measure():
    short = _top(0.01, t_end=0.5)  # shorter than one nutation period (0.9 s)
    assert "at least 2" in ob.nutation_period(short, 2, Z).reason
    upright = _top(0.01, t_end=2.0, a=0.0, u0=1.0)  # the axis on the vertical
    assert "azimuth undefined" in ob.precession_rate(upright, 2, Z).reason


# -- on exact references ---------------------------------------------------------------------


@pytest.mark.parametrize("name", ["dzhanibekov", "gazebo_boxes_complex", "major_axis_spin",
                                  "free_tumbling", "gazebo_boxes_simple"])  # fmt: skip
def test_flip_interval_of_the_exact_free_bodies(name):
    # sampled as an engine run saves them (dt x save_every)
    sc = scenarios.load(name)
    h = sc.dt * sc.save_every
    t = np.arange(round(sc.t_end / h) + 1) * h
    ref = one_body(reference_trajectory(sc, t))
    expected = expected_observables(sc)
    fi = ob.flip_interval(ref)
    if "flip_interval" in expected:
        # cubic event error at h = 0.01 s: measured 1e-14 (dzhanibekov), 3e-10 (gazebo)
        assert fi == pytest.approx(expected["flip_interval"], rel=1e-9)
    else:
        assert math.isnan(fi) and fi.reason


@pytest.mark.parametrize("h", [1e-3, 9e-3])
def test_simo_wong_observables_from_the_exact_motion(h):
    sc = scenarios.load("simo_wong_top")
    t = np.arange(round(sc.t_end / h) + 1) * h
    ref = one_body(reference_trajectory(sc, t, kind="lagrange_top"))
    ex = expected_observables(sc)
    # h = 9e-3 is 76 samples per nutation period: cubic event errors ~1e-11 relative (measured
    # 2e-11 for the period, 2e-9 for the precession, whose azimuth wiggles faster)
    assert ob.nutation_period(ref, 2, sc.vertical) == pytest.approx(ex["nutation_period"], rel=1e-9)
    assert ob.precession_rate(ref, 2, sc.vertical) == pytest.approx(ex["precession_rate"], rel=1e-8)
    lo, hi = ob.tilt_range(ref, 2, sc.vertical)
    assert lo == pytest.approx(ex["tilt_min"], rel=1e-9)
    assert hi == pytest.approx(ex["tilt_max"], rel=1e-9)


# -- a top under gravity along another axis: the vertical is -g/|g| -----------------------------


def _rotation(axis, angle):
    from scipy.spatial.transform import Rotation

    a = np.asarray(axis, dtype=float)
    return Rotation.from_rotvec(angle * a / np.linalg.norm(a)).as_matrix()


#: gravity turned away from -z: by 0.4 rad about y, and by 2.0 rad about an oblique axis
TURNS = [((0.0, 1.0, 0.0), 0.4), ((1.0, -2.0, 0.5), 2.0)]


def _turned(sc, G):
    """The same top in a world turned by G: gravity G g, initial attitude G R0; its motion is
    G R(t) with the same body rates."""
    return sc.replace(name=sc.name + "_turned", gravity=G @ sc.gravity, rotation=G @ sc.rotation)


def _quadrature_period(sc) -> float:
    """The nutation period of a Lagrange top by mpmath at 30 digits, from the scenario's own
    numbers and nothing of the suite: T = 2 int_{u1}^{u2} du / sqrt(f(u)), f(u) = (1 - u^2)
    (alpha - beta u) - (a - b u)^2 (Goldstein, Classical Mechanics, section 5.7), u the cosine
    of the tilt of the symmetry axis e_3 from up = -g/|g|, moments about the pivot A, C, l
    the pivot -> centre-of-mass distance along e_3."""
    import mpmath as mp

    mp.mp.dps = 30
    F = mp.mpf
    m = F(sc.mass)
    g = [F(x) for x in sc.gravity]
    gn = mp.sqrt(sum(x * x for x in g))
    up = [-x / gn for x in g]
    R = [[F(sc.rotation[i][j]) for j in range(3)] for i in range(3)]
    W = [F(x) for x in sc.omega_body]
    l = -F(sc.pivot[2])  # the centre of mass relative to the pivot is -pivot = l e_3
    A, C = F(sc.inertia[0]) + m * l * l, F(sc.inertia[2])
    n = [sum(R[i][j] * up[i] for i in range(3)) for j in range(3)]  # up in body axes
    u0 = n[2]
    Lb = [A * W[0], A * W[1], C * W[2]]  # angular momentum about the pivot, body axes
    E = (A * (W[0] ** 2 + W[1] ** 2) + C * W[2] ** 2) / 2 + m * gn * l * u0
    a, b = sum(Lb[j] * n[j] for j in range(3)) / A, C * W[2] / A
    alpha, beta = (2 * E - C * W[2] ** 2) / A, 2 * m * gn * l / A

    # f = beta u^3 - (alpha + b^2) u^2 + (2 a b - beta) u + alpha - a^2, three real roots
    coeffs = [beta, -(alpha + b * b), 2 * a * b - beta, alpha - a * a]
    u1, u2, u3 = sorted(mp.re(r) for r in polyroots(coeffs, maxsteps=200, extraprec=60))
    if beta < 0:  # the centre of mass below the pivot: the two turning points are the upper
        u1, u2, u3 = u2, u3, u1
    assert -1 <= u1 <= u0 <= u2 <= 1

    # u = u1 + (u2 - u1) sin^2 s takes the square-root singularities out of the endpoints:
    # du / sqrt(f) = 2 ds / sqrt(|beta| |u3 - u|)
    def integrand(s):
        return 2 / mp.sqrt(abs(beta * (u3 - u1 - (u2 - u1) * mp.sin(s) ** 2)))

    return float(2 * mp.quad(integrand, [0, mp.pi / 2]))


@pytest.mark.parametrize("turn", TURNS)
@pytest.mark.parametrize("name", ["heavy_top", "simo_wong_top"])
def test_nutation_period_under_turned_gravity_against_quadrature(name, turn):
    """The exact reference under gravity along another axis: its nutation period agrees with
    an mpmath quadrature of the period integral (1e-10: the closed form's K(m)/tau' has ~1e-14;
    the quadrature 30 digits), and the period measured from its trajectory about the
    scenario's vertical does too, to the cubic's event-time bound. Measured about world z
    instead, it is off by percents."""
    sc = _turned(scenarios.load(name), _rotation(*turn))
    T = _quadrature_period(sc)
    ex = expected_observables(sc)
    assert ex["nutation_period"] == pytest.approx(T, rel=1e-10)
    h = 1e-3 if name == "heavy_top" else 9e-3
    t = np.arange(round(min(sc.t_end, 12 * T) / h) + 1) * h
    ref = reference_trajectory(sc, t)
    assert ref.kind == "lagrange_top"
    got = ob.nutation_period(one_body(ref), 2, sc.vertical)
    # event times by the cubic: (3/128) h^4 |u''''|/|u'| <= (3/128) h^4 w^3 for a nearly
    # sinusoidal u of angular frequency w = 2 pi/T, two events over (n - 1) periods
    w = 2 * math.pi / T
    assert got == pytest.approx(T, rel=2 * 3 / 128 * h**4 * w**3 / ((got.n - 1) * T))
    from reports.metrics.body import compute_metrics

    err = compute_metrics(sc, ref, ref, ex)["nutation_period_error"]
    assert err == pytest.approx(abs(got - ex["nutation_period"]) / ex["nutation_period"])
    wrong = ob.nutation_period(one_body(ref), 2, (0.0, 0.0, 1.0))
    assert math.isnan(wrong) or abs(wrong / T - 1) > 1e-3


@pytest.mark.parametrize("turn", TURNS)
@pytest.mark.parametrize(
    "name", ["heavy_top", "simo_wong_top", "pendulum_through_vertical", "cone_top"]
)
def test_the_exact_top_turns_with_its_gravity(name, turn):
    """Frame covariance: turning gravity and the initial attitude by G turns the exact motion
    by G, R'(t) = G R(t), W'(t) = W(t) (nutating top, planar pendulum, steady precession),
    and leaves every observable unchanged. 1e-11: the two closed forms are evaluated from
    inputs that differ by the rounding of G R0 and G g (~1e-16), grown over the horizon."""
    sc = scenarios.load(name)
    G = _rotation(*turn)
    turned = _turned(sc, G)
    t = np.linspace(0.0, sc.t_end, 401)
    a, b = reference_trajectory(sc, t), reference_trajectory(turned, t)
    assert a.kind == b.kind != "numerical"
    np.testing.assert_allclose(b.rotation, G @ a.rotation, rtol=0, atol=1e-11)
    W = np.abs(a.omega_body).max()
    np.testing.assert_allclose(b.omega_body, a.omega_body, rtol=0, atol=1e-11 * W)
    ea, eb = expected_observables(sc), expected_observables(turned)
    assert ea.keys() == eb.keys()
    for key in ea:
        assert eb[key] == pytest.approx(ea[key], rel=1e-11, abs=1e-13), key
