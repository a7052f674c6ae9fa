"""The exact torque-free body against docs/numerics.md's 30-digit test vectors, an independent
high-precision mpmath evaluation (20-30 digits), Euler's equations, relabelling symmetry and
the numerical reference."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from references.exact import numerical
from references.exact._util import rotation_angle
from references.exact.free_body import FreeBody, free_flight
from scenarios.model import Scenario

DZ_I, DZ_W = [2.0, 3.0, 4.0], [0.01, 2.0, 0.01]  # docs/numerics.md section 5

# Required by the brief: 1e-12 relative. The computation takes O(10) roundings, so 1e-13 is a
# margin of ~100x over what was measured (<= 2.2e-16 on every quantity below).
REL = 1e-13


@pytest.fixture(scope="module")
def dz():
    return FreeBody(DZ_I, DZ_W, np.eye(3))


def test_dzhanibekov_constants(dz):
    assert dz.case == "A"
    assert dz.energy == pytest.approx(6.0003, rel=REL)
    assert dz.L == pytest.approx(6.0001666643519161500, rel=REL)
    assert dz.k2 == pytest.approx(0.99996666888874075062, rel=REL)
    # 1 - k^2 from the cancellation-free identity: the 20-digit k^2 above fixes it to 3e-16
    # relative, so the same 1e-13 holds (the naive 1 - k^2 would be off by ~1e-12 relative)
    assert dz.m1 == pytest.approx(1.0 - 0.99996666888874075062, rel=1e-11)
    assert dz.m1 == pytest.approx(3.3331111259249380e-5, rel=REL)
    assert dz.K == pytest.approx(6.5408501947927692532, rel=REL)
    assert dz.lam == pytest.approx(0.70713035101976306935, rel=REL)
    assert dz.period == pytest.approx(36.999402926830183884, rel=REL)
    assert dz.flip_interval == pytest.approx(36.999402926830183884 / 2, rel=REL)
    assert dz.phi_per_period == pytest.approx(77.821937985846349919, rel=REL)
    assert dz.intermediate_axis == 1 and dz.dominant_axis == 1


def test_dzhanibekov_state_at_10s(dz):
    W10 = [-1.6306316852386145375, 0.67442845639437637254, 1.153052404035506982]
    # |W| ~ 2: 1e-13 absolute is the same margin as REL
    assert np.abs(dz.omega([10.0])[0] - W10).max() < 1e-13
    R10 = np.array(
        [
            [0.601069719933, -0.479226289446, 0.639575918311],
            [-0.541629680940, 0.344194223927, 0.766920872672],
            [-0.587666980955, -0.807386214720, -0.052678456472],
        ]
    )
    # docs/numerics.md gives R(10) to 12 decimals: rounding up to 5e-13, plus our error
    assert np.abs(dz.rotation([10.0])[0] - R10).max() < 6e-13


def test_dzhanibekov_half_and_full_period(dz):
    T = 36.999402926830183884
    # W(T/2) = (-0.01, -2, 0.01) (docs/numerics.md): the flip
    assert np.abs(dz.omega([T / 2])[0] - [-0.01, -2.0, 0.01]).max() < 1e-13
    assert np.abs(dz.omega([T])[0] - DZ_W).max() < 1e-13
    # after one period R(T) = Rot(L, dphi) R0 (docs/numerics.md section 4), with the 30-digit dphi
    L = np.multiply(DZ_I, DZ_W)
    expect = Rotation.from_rotvec(77.821937985846349919 * L / np.linalg.norm(L)).as_matrix()
    # the rotation angle of 77.8 rad carries eps * 78 of round-off in both evaluations
    assert rotation_angle(dz.rotation([T]), expect[None])[0] < 1e-13


def test_second_test_body():
    fb = FreeBody(DZ_I, [0.2, 0.5, 1.0], np.eye(3))  # docs/numerics.md section 5, case A
    assert fb.case == "A"
    assert fb.energy == pytest.approx(2.415, rel=REL)
    assert fb.L == pytest.approx(4.2906875905849868808, rel=REL)
    assert fb.k2 == pytest.approx(0.104, rel=REL)
    assert fb.period == pytest.approx(10.693567966073623546, rel=REL)


def _mp_free_body(I, W, t_list, dps=20, attitude=True):
    """Independent high-precision evaluation of the case-A formulas of docs/numerics.md section 4
    with mpmath (body rates, and the attitude by mpmath quadrature of phi'), R0 = identity,
    W1 = A1 cn, W2 = A2 sn, W3 = s A3 dn: Euler's equations need s = sign(I3 - I1)."""
    mp = pytest.importorskip("mpmath")
    mp.mp.dps = dps
    # the doubles themselves (mpf of a float is exact), not their shortest decimal forms,
    # which differ by up to 1/2 ulp: near the separatrix that moves m1 (4e-6 relative at a
    # separatrix distance of 4e-12 of L^2)
    I = [mp.mpf(float(x)) for x in I]
    W = [mp.mpf(float(x)) for x in W]
    I1, I2, I3 = I
    W1, W2, W3 = W
    twoE = sum(i * w * w for i, w in zip(I, W, strict=True))
    L2 = sum((i * w) ** 2 for i, w in zip(I, W, strict=True))
    # case A in the order given: L circulates about the third axis (I1 < I2 < I3 and
    # L^2 > 2 E I2, or the reverse order and L^2 < 2 E I2, a case-B body relabelled)
    assert (L2 - twoE * I2) * (I3 - I1) > 0
    m = (I2 - I1) * (twoE * I3 - L2) / ((I3 - I2) * (L2 - twoE * I1))
    lam = mp.sqrt((I3 - I2) * (L2 - twoE * I1) / (I1 * I2 * I3))
    A1 = mp.sqrt((twoE * I3 - L2) / (I1 * (I3 - I1)))
    A2 = mp.sqrt((twoE * I3 - L2) / (I2 * (I3 - I2)))
    A3 = mp.sqrt((L2 - twoE * I1) / (I3 * (I3 - I1)))
    s = mp.sign(W3)
    u0 = mp.ellipf(mp.atan2(W2 / A2, W1 / A1), m)
    L = mp.sqrt(L2)

    def rates(u):
        return (
            A1 * mp.ellipfun("cn", u, m=m),
            A2 * mp.ellipfun("sn", u, m=m),
            s * A3 * mp.ellipfun("dn", u, m=m),
        )

    def phidot(u):
        w1, w2, _ = rates(u)
        return L * (I1 * w1**2 + I2 * w2**2) / ((I1 * w1) ** 2 + (I2 * w2) ** 2)

    def rot_z(a):
        c, s_ = mp.cos(a), mp.sin(a)
        return mp.matrix([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])

    def rot_x(a):
        c, s_ = mp.cos(a), mp.sin(a)
        return mp.matrix([[1, 0, 0], [0, c, -s_], [0, s_, c]])

    def euler(u):
        w = rates(u)
        P = [i * x for i, x in zip(I, w, strict=True)]
        return mp.atan2(mp.sqrt(P[0] ** 2 + P[1] ** 2), P[2]), mp.atan2(P[0], P[1])

    th0, psi0 = euler(u0)
    RL = rot_z(psi0).T  # R0 = identity: R_L = Rz(psi0)^T Rx(th0)^T
    RL = RL * rot_x(th0).T
    out_W, out_R = [], []
    for t in t_list:
        u = u0 + lam * mp.mpf(float(t))
        out_W.append([float(x) for x in rates(u)])
        if not attitude:
            continue
        # quadrature of phi' over u, split at multiples of K for accuracy
        K = mp.ellipk(m)
        nodes = [u0] + [k * K for k in range(int(mp.ceil(u0 / K)), int(mp.floor(u / K)) + 1)]
        nodes.append(u)
        phi = mp.quad(phidot, nodes) / lam
        th, psi = euler(u)
        R = RL * rot_z(phi) * rot_x(th) * rot_z(psi)
        out_R.append(np.array([[float(R[i, j]) for j in range(3)] for i in range(3)]))
    return np.array(out_W), np.array(out_R)


def test_rates_against_independent_high_precision_evaluation(dz):
    # up to t = 1e4 s (270 periods): checks the argument reduction of the Jacobi functions
    # (plain scipy ellipj(u, m) is off by 6e-12 at t = 10 s and 3e-9 at t = 1e4 s here)
    t = [10.0, 250.0, 1000.0, 1e4]
    Wm, _ = _mp_free_body(DZ_I, DZ_W, t, dps=30, attitude=False)
    # phase round-off ~ eps lambda t |W'|: 1e-13 at t = 1e4 s; measured 3e-14
    assert np.abs(dz.omega(t) - Wm).max() < 1e-13


def _check_attitude(dz, t):
    _, Rm = _mp_free_body(DZ_I, DZ_W, t)
    err = rotation_angle(dz.rotation(t), Rm)
    # the reference's own estimate (round-off of the phases ~ 16 eps per radian turned, plus
    # quadrature) must cover the actual error
    assert np.all(err <= dz.accuracy(t)), (err, dz.accuracy(t))
    return err


def test_attitude_against_independent_high_precision_evaluation(dz):
    err = _check_attitude(dz, [10.0, 40.0])
    assert err.max() < 1e-13  # measured 5e-15 at 10 s


@pytest.mark.slow
def test_attitude_against_independent_high_precision_evaluation_long(dz):
    err = _check_attitude(dz, [250.0])  # 7 periods, 500 rad turned
    assert err.max() < 1e-12  # measured 1.5e-13


def _euler_residual(fb, t, h=1e-3):
    """Residuals of Euler's equations I W' = (I W) x W and of R' = R hat(W), derivatives by
    5-point central differences (truncation h^4 |f^(5)|/30 ~ 1e-12 here, round-off eps/h)."""
    c = np.array([1.0, -8.0, 0.0, 8.0, -1.0]) / (12.0 * h)
    ts = np.array([t + k * h for k in (-2, -1, 0, 1, 2)])
    W = fb.omega(ts)
    R = fb.rotation(ts)
    Wd = np.tensordot(c, W, axes=1)
    Rd = np.tensordot(c, R, axes=1)
    I = fb.inertia
    r1 = np.abs(I * Wd - np.cross(I * W[2], W[2])).max()
    w = W[2]
    hat = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    r2 = np.abs(Rd - R[2] @ hat).max()
    return r1, r2


BODIES = {
    # name: (inertia, W0) -> expected case
    "case A, generic": ([0.9, 1.4, 2.0], [1.2, -0.8, 2.1], "A"),
    "case B": ([0.9, 1.4, 2.0], [2.1, -0.8, 0.3], "B"),
    "case B, unsorted moments": ([2.0, 0.9, 1.4], [-0.3, 2.1, 0.8], "B"),
    "near separatrix, W3 < 0": ([2.0, 3.0, 4.0], [0.01, 2.0, -0.01], "A"),
    "separatrix": ([3.0, 4.0, 6.0], [2.0, 1.0, 1.0], "separatrix"),
    "separatrix, signs": ([3.0, 4.0, 6.0], [-2.0, 1.0, -1.0], "separatrix"),
    "symmetric": ([1.0, 1.0, 2.0], [0.3, 0.5, 2.0], "symmetric"),
    "symmetric, axis 1": ([2.0, 1.0, 1.0], [2.0, 0.3, -0.5], "symmetric"),
    "spherical": ([1.5, 1.5, 1.5], [0.3, 0.5, 2.0], "spherical"),
    "principal spin": ([2.0, 3.0, 4.0], [0.0, 2.0, 0.0], "principal spin"),
    "nearly symmetric": ([1.0, 1.0 + 1e-9, 2.0], [0.3, 0.5, 2.0], "A"),
}
R0 = Rotation.from_rotvec([0.4, -0.9, 1.3]).as_matrix()


@pytest.mark.parametrize("name", sorted(BODIES))
def test_closed_form_satisfies_the_equations_of_motion(name):
    I, W0, case = BODIES[name]
    fb = FreeBody(I, W0, R0)
    assert fb.case == case
    for t in (0.7, 5.3, 13.1):
        r1, r2 = _euler_residual(fb, t)
        # finite-difference truncation ~ h^4 |W|^5/30 and round-off ~ eps |W| / h: < 1e-9
        assert r1 < 1e-9 and r2 < 1e-9, (t, r1, r2)


@pytest.mark.parametrize("name", sorted(BODIES))
def test_closed_form_agrees_with_the_numerical_reference(name):
    I, W0, _ = BODIES[name]
    fb = FreeBody(I, W0, R0)
    # 8 s: a few periods; on the separatrix the numerical solution's own error grows like
    # exp(lambda t) from round-off, which its estimate follows
    t = np.linspace(0.0, 8.0, 41)
    sc = Scenario(name="t", description="", mass=1.0, inertia=I, rotation=R0, omega_body=W0,
                  t_end=8.0, dt=0.01)  # fmt: skip
    num = numerical.solve(sc, t)
    err = rotation_angle(fb.rotation(t), num.rotation).max()
    werr = np.abs(fb.omega(t) - num.omega_body).max()
    # agreement within the numerical reference's estimated error (plus the closed form's);
    # measured: 1e-13 .. 3e-11 here
    assert err <= num.accuracy + fb.accuracy(t), (err, num.accuracy)
    assert werr <= num.omega_accuracy + 1e-13, (werr, num.omega_accuracy)
    assert err < 1e-9


def _relabel(I, W, R, perm):
    """The same physical body described with its axes permuted by ``perm``; an odd
    permutation is completed by negating all axes so that the frame stays right-handed."""
    sign = 1.0 if perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0
    p = list(perm)
    return np.asarray(I)[p], sign * np.asarray(W)[p], sign * np.asarray(R)[:, p], sign


@pytest.mark.parametrize("perm", list(itertools.permutations(range(3))))
@pytest.mark.parametrize("name", ["case A, generic", "case B", "near separatrix, W3 < 0"])
def test_any_axis_order_gives_the_same_motion(name, perm):
    I, W0, _ = BODIES[name]
    base = FreeBody(I, W0, R0)
    Ip, Wp, Rp, sign = _relabel(I, W0, R0, perm)
    other = FreeBody(Ip, Wp, Rp)
    t = np.linspace(0.0, 20.0, 11)
    p = list(perm)
    # both are closed forms: they differ by round-off (~16 eps per radian turned)
    assert np.abs(other.omega(t) - sign * base.omega(t)[:, p]).max() < 1e-12
    assert np.abs(other.rotation(t) - sign * base.rotation(t)[:, :, p]).max() < 1e-12
    assert other.period == pytest.approx(base.period, rel=1e-14)


def test_separatrix_approaches_the_intermediate_axis():
    fb = FreeBody([3.0, 4.0, 6.0], [2.0, 1.0, 1.0], R0)
    # on the separatrix L^2 = 2 E I_2, so W tends to +-|L|/I_2 about the intermediate axis
    W = fb.omega([60.0])[0]
    assert abs(abs(W[1]) - fb.L / 4.0) < 1e-12 and np.abs(W[[0, 2]]).max() < 1e-12
    assert math.isinf(fb.period) and fb.flip_interval is None


def test_principal_spin_and_symmetric_closed_forms():
    # a spin about a principal axis: R(t) = R0 Rot(e_2, W_2 t) exactly
    fb = FreeBody([2.0, 3.0, 4.0], [0.0, 2.0, 0.0], R0)
    expect = R0 @ Rotation.from_rotvec([0.0, 2.0 * 3.7, 0.0]).as_matrix()
    assert np.abs(fb.rotation([3.7])[0] - expect).max() < 1e-15
    # symmetric body: W_perp turns about e_3 at psi' = W_3 (I_perp - I_3)/I_perp = -2
    fb = FreeBody([1.0, 1.0, 2.0], [0.3, 0.5, 2.0], R0)
    a = -2.0 * 0.9
    expect = [0.3 * math.cos(a) + 0.5 * math.sin(a), -0.3 * math.sin(a) + 0.5 * math.cos(a), 2.0]
    assert np.abs(fb.omega([0.9])[0] - expect).max() < 1e-15
    assert fb.period == pytest.approx(math.pi, rel=1e-15)


def test_free_flight():
    x, v = free_flight([1.0, 2.0, 3.0], [-2.0, 2.0, 8.0], [0.0, 0.0, -9.8], [0.0, 2.0])
    assert x[1].tolist() == [1.0 - 4.0, 2.0 + 4.0, 3.0 + 16.0 - 19.6]
    assert v[1].tolist() == [-2.0, 2.0, 8.0 - 19.6]
