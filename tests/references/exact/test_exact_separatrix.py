"""The closed-form free body near the separatrix, against mpmath.

The separatrix distance L^2 - 2 E I_mid is a difference of two terms of size L^2; formed in
floating point near the separatrix, their rounding (a few ulp of L^2) is the whole result.
A body a few ulp off the separatrix was then put on it ("separatrix, no flip") although it
flips, and a body 3.9e-12 (relative) off had its modulus wrong by 1e-6 relative, while the
accuracy estimate claimed 5e-13 rad. The reference computes the distance exactly from the
doubles it is given and accounts for the rounding of the modulus in its estimate
(:meth:`FreeBody.modulus_error`).

Independent solution: ``_mp_free_body`` of tests/references/exact/test_exact_free_body.py, the
case-A formulas with mpmath's elliptic functions and a quadrature of phi', from the exact binary
values of the inputs (at 30 digits the separatrix distance of these bodies, 1e-17 of L^2, keeps 13
digits). A case-B body is handed to it relabelled: axes (-e3, -e2, -e1), a right-handed frame in
which L circulates about the third axis.
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from references.exact import FreeBody, expected_observables, reference_trajectory
from references.exact._util import EPS, rotation_angle
from references.exact.free_body import MODULUS_RTOL, separatrix_distance
from scenarios.model import Scenario
from tests.references.exact.test_exact_free_body import _mp_free_body

I123 = (1.0, 2.0, 3.0)
#: (inertia, rates, times): W1^2 = 3 W3^2 is the separatrix of I = (1, 2, 3); these rates are
#: the doubles next to it (found by a search over W3 for floating-point distance 0)
FEW_ULP_A = (I123, (0.8668914291882229, 1.0, 0.5005), [10.0, 45.0, 60.0])  # +1.1e-16
FEW_ULP_B = (I123, (-0.8798818102449897, 1.0, 0.508), [10.0, 45.0, 60.0])  # -7.4e-18
REL_39_B = (I123, (-0.8660254038000271, 1.0, 0.5), [10.0, 37.0, 60.0])  # -3.86e-12 of L^2
#: a body of the Gazebo box (moments 97/120, 82/120, 17/120) set 2e-15 of L^2 off its separatrix
GAZEBO = ((0.8083333333333333, 0.6833333333333333, 0.14166666666666666), None, [5.0, 20.0])
TIGHT, FLOOR = 100.0, 16 * EPS  # as tests/references/exact/test_exact_accuracy.py


def _float_distance(I, W) -> float:
    """The floating-point formula the reference used before (to show the defect is real)."""
    lo, mid, hi = np.argsort(I)
    return I[lo] * (I[lo] - I[mid]) * W[lo] ** 2 + I[hi] * (I[hi] - I[mid]) * W[hi] ** 2


def _mp_distance(I, W, dps=60) -> mp.mpf:
    with mp.workdps(dps):
        Im, Wm = [mp.mpf(float(x)) for x in I], [mp.mpf(float(x)) for x in W]
        twoE = sum(i * w * w for i, w in zip(Im, Wm, strict=True))
        L2 = sum((i * w) ** 2 for i, w in zip(Im, Wm, strict=True))
        return L2 - twoE * sorted(Im)[1]


def _gazebo_rates():
    """W = (w1, 5, 0.1) with w1 the double whose separatrix distance is smallest and > 0."""
    I = GAZEBO[0]
    lo, mid, hi = 2, 1, 0  # I[2] < I[1] < I[0]
    w3 = 0.1
    w1 = math.sqrt(I[hi] * (I[hi] - I[mid]) / (I[lo] * (I[mid] - I[lo]))) * w3
    best = None
    for k in range(-40, 41):
        w = w1 + k * math.ulp(w1)
        d = separatrix_distance(I, (w3, 5.0, w))
        if d > 0 and (best is None or d < best[0]):
            best = (d, w)
    return (w3, 5.0, best[1])


def _mp_any_case(I, W, t, dps):
    """(W(t), R(t)) of the body with R0 = 1 from ``_mp_free_body`` in a relabelled frame P
    (columns: signed body axes, right-handed) in which L circulates about the third axis:
    axes by increasing moment for case A, decreasing for case B, signed so that the third
    rate has the sign the helper's parametrisation W3 = +-A3 dn takes (Euler's equations:
    that of I3 - I1)."""
    I, W = np.asarray(I, dtype=float), np.asarray(W, dtype=float)
    order = np.argsort(I)
    if _mp_distance(I, W) < 0:
        order = order[::-1]
    P = np.eye(3)[:, order]
    if np.linalg.det(P) < 0:
        P[:, 0] *= -1.0
    Ir = I[order]
    if np.sign((P.T @ W)[2]) != np.sign(Ir[2] - Ir[0]):
        P[:, 1:] *= -1.0
    Wm, Rm = _mp_free_body(Ir, P.T @ W, t, dps=dps)
    return Wm @ P.T, P @ Rm @ P.T


@pytest.mark.parametrize("body", [FEW_ULP_A, FEW_ULP_B, REL_39_B])
def test_the_separatrix_distance_is_exact(body):
    """The exact distance (rounded once) against mpmath at 60 digits; the floating-point
    formula puts the few-ulp bodies on the separatrix, and misses the third by 1e-6."""
    I, W, _ = body
    exact = _mp_distance(I, W)
    got = separatrix_distance(I, W)
    assert got == float(exact)
    fl = _float_distance(np.array(I), np.array(W))
    assert fl == 0.0 or abs(fl / float(exact) - 1) > 1e-7


@pytest.mark.parametrize(
    "body",
    [FEW_ULP_A, REL_39_B, pytest.param(FEW_ULP_B, marks=pytest.mark.slow)],
    ids=["few_ulp_A", "rel_3.9e-12_B", "few_ulp_B"],
)
def test_near_separatrix_attitude_and_flips_against_mpmath(body):
    """The closed form follows the body through its flips (it was "separatrix, no flip",
    attitude error pi at 60 s, or 1e-5 rad off with an estimate of 5e-13): attitude and rates
    against mpmath, the estimate covering the error and within TIGHT of it, and the flip
    interval 2K/lambda against mpmath's K and lambda."""
    I, W, t = body
    fb = FreeBody(I, W, np.eye(3))
    assert fb.case == ("A" if _mp_distance(I, W) > 0 else "B")
    Wm, Rm = _mp_any_case(I, W, t, dps=30)
    err = rotation_angle(fb.rotation(t), Rm)
    acc = fb.accuracy(t)
    assert err.max() <= acc <= TIGHT * max(err.max(), FLOOR), (err, acc)
    # rates: the phase round-off eps lambda t |W'|, a few 1e-15 over 60 s (measured 2e-16)
    assert np.abs(fb.omega(t) - Wm).max() < 1e-13
    # the flip interval: mpmath's 2 K(m)/lambda from the exact inputs (30 digits)
    with mp.workdps(30):
        Im, Wmp = [mp.mpf(float(x)) for x in I], [mp.mpf(float(x)) for x in W]
        I1, I2, I3 = sorted(Im)
        twoE = sum(i * w * w for i, w in zip(Im, Wmp, strict=True))
        L2 = sum((i * w) ** 2 for i, w in zip(Im, Wmp, strict=True))
        if L2 < twoE * I2:
            I1, I3 = I3, I1  # case B: the same formulas with the extreme axes swapped
        m1 = (I3 - I1) * (L2 - twoE * I2) / ((I3 - I2) * (L2 - twoE * I1))
        lam = mp.sqrt((I3 - I2) * (L2 - twoE * I1) / (I1 * I2 * I3))
        flip = float(2 * mp.ellipk(1 - m1) / lam)
    # 1e-13: K ~ 20 from m1 with a few ulp, lambda a few ulp
    assert fb.flip_interval == pytest.approx(flip, rel=1e-13)
    sc = Scenario(name="s", description="", mass=1.0, inertia=I, rotation=np.eye(3),
                  omega_body=W, t_end=60.0, dt=0.01)  # fmt: skip
    assert expected_observables(sc)["flip_interval"] == pytest.approx(flip, rel=1e-13)
    ref = reference_trajectory(sc, t)
    assert ref.kind == "free_body" and ref.accuracy == pytest.approx(acc)


@pytest.mark.slow
def test_gazebo_box_two_ulp_off_its_separatrix_against_mpmath():
    """A case of our own: the Gazebo box 1e-15 (relative) off its separatrix."""
    I = GAZEBO[0]
    W = _gazebo_rates()
    L2 = sum((i * w) ** 2 for i, w in zip(I, W, strict=True))
    assert 0 < separatrix_distance(I, W) / L2 < 1e-14
    fb = FreeBody(I, W, np.eye(3))
    t = GAZEBO[2]
    Wm, Rm = _mp_any_case(I, W, t, dps=30)
    err = rotation_angle(fb.rotation(t), Rm)
    acc = fb.accuracy(t)
    assert err.max() <= acc <= TIGHT * max(err.max(), FLOOR), (err, acc)


@pytest.mark.parametrize("body", [FEW_ULP_A, REL_39_B])
def test_the_modulus_term_is_the_flip_time_shift_of_a_rounded_modulus(body):
    """The conditioning term against its first-order value derived independently: a
    relative error rho of m1 changes K by dK = (E(m) - m1 K(m))/(2 m) rho (d K/d m1, mpmath
    at 30 digits), the period by 4 dK/lambda, so that after t the motion lags by t dK/K and
    the attitude by up to |W|_max t dK/K. The probe's figure lies within a factor 10 of it
    (the lag of the initial phase and of the precession per period add to it, of the same
    order)."""
    I, W, t = body
    fb = FreeBody(I, W, np.eye(3))
    tmax = 60.0
    with mp.workdps(30):
        m1 = mp.mpf(fb.m1)
        m = 1 - m1
        dK = (mp.ellipe(m) - m1 * mp.ellipk(m)) / (2 * m) * MODULUS_RTOL
        lag = tmax * float(dK / mp.ellipk(m))
    wmax = np.linalg.norm(fb.omega(np.linspace(0, tmax, 2001)), axis=1).max()
    first_order = wmax * lag
    got = fb.modulus_error(tmax)
    assert first_order / 10 <= got <= 10 * first_order, (got, first_order)
    assert fb.accuracy([tmax]) >= got


def test_beyond_the_linear_range_the_closed_form_claims_nothing():
    """Over 1e9 s the probe (S scaled by 1 + 1e-9) moves the attitude by more than 1e-2 rad:
    the modulus term is pi, and a free-body reference asked for explicitly refuses, naming
    its accuracy (``auto`` hands over to the numerical reference). Below that it grows as the
    horizon (a lag proportional to the number of periods)."""
    from references.exact import ReferenceNotApplicable

    I, W, _ = FEW_ULP_A
    fb = FreeBody(I, W, np.eye(3))
    small, large = fb.modulus_error(1e5), fb.modulus_error(1e7)
    assert large / small == pytest.approx(100, rel=0.05)
    assert fb.modulus_error(1e9) == math.pi
    sc = Scenario(name="s", description="", mass=1.0, inertia=I, rotation=np.eye(3),
                  omega_body=W, t_end=1e9, dt=1e3)  # fmt: skip
    with pytest.raises(ReferenceNotApplicable, match="estimated accuracy 3.14 rad exceeds"):
        reference_trajectory(sc, [0.0, 1e9], kind="free_body")
