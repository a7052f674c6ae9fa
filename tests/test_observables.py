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
from reports import observables as ob


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
    period = ob.nutation_period(traj, 2)
    assert period.reason == "" and period.n >= 5
    u = traj.rotation[:, 2, 2]
    level = u.mean()
    slope = A * NU * math.sqrt(1 - ((level - U0) / A) ** 2)  # |u'| where u crosses the level
    bound = 2 * _cubic_bound(h, A * NU**4, slope) / (period.n - 1)
    assert abs(period - 2 * math.pi / NU) <= bound


def test_precession_rate_of_a_synthetic_top():
    h = 2 * math.pi / NU / 25.3
    traj = _top(h)
    rate = ob.precession_rate(traj, 2)
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
    lo, hi = ob.tilt_range(_top(h, t_end=1.0, phase=0.7), 2)
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
    period = ob.nutation_period(traj, 2)
    assert math.isnan(period) and "no nutation" in period.reason
    # no nutation: (azimuth(end) - azimuth(start))/duration; phi = Omega t + b sin(nu t)
    expect = OMEGA + B * math.sin(NU * traj.t[-1]) / traj.t[-1]
    assert ob.precession_rate(traj, 2) == pytest.approx(expect, rel=1e-12)
    lo, hi = ob.tilt_range(traj, 2)
    assert lo == pytest.approx(math.acos(U0), rel=1e-14) and hi == pytest.approx(lo, rel=1e-14)


def test_top_observables_refuse_what_they_cannot_measure():
    short = _top(0.01, t_end=0.5)  # shorter than one nutation period (0.9 s)
    assert "at least 2" in ob.nutation_period(short, 2).reason
    upright = _top(0.01, t_end=2.0, a=0.0, u0=1.0)  # the axis on the vertical
    assert "azimuth undefined" in ob.precession_rate(upright, 2).reason


# -- on exact references ---------------------------------------------------------------------


@pytest.mark.parametrize("name", ["dzhanibekov", "gazebo_boxes_complex", "major_axis_spin",
                                  "free_tumbling", "gazebo_boxes_simple"])  # fmt: skip
def test_flip_interval_of_the_exact_free_bodies(name):
    # sampled as an engine run saves them (dt x save_every)
    sc = scenarios.load(name)
    h = sc.dt * sc.save_every
    t = np.arange(round(sc.t_end / h) + 1) * h
    ref = reference_trajectory(sc, t)
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
    ref = reference_trajectory(sc, t, kind="lagrange_top")
    ex = expected_observables(sc)
    # h = 9e-3 is 76 samples per nutation period: cubic event errors ~1e-11 relative (measured
    # 2e-11 for the period, 2e-9 for the precession, whose azimuth wiggles faster)
    assert ob.nutation_period(ref, 2) == pytest.approx(ex["nutation_period"], rel=1e-9)
    assert ob.precession_rate(ref, 2) == pytest.approx(ex["precession_rate"], rel=1e-8)
    lo, hi = ob.tilt_range(ref, 2)
    assert lo == pytest.approx(ex["tilt_min"], rel=1e-9)
    assert hi == pytest.approx(ex["tilt_max"], rel=1e-9)
