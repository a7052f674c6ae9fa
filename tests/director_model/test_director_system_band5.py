"""The loop solver's solves and assembly in 5 x 5 joint blocks (director_model/system/_band5.py)
against the general banded ones of director_model/system/_solvers.py and _rows.py, bit for bit: each
unknown gets the same subtractions in the same order, each matrix entry the same products
(less those by an exact zero) summed in the same order, so every entry must be the same float.

The matrices are the kernel's own: the four-bar's and Bricard's rows (joints in the band
order, five rows each) at their initial configuration (where the four-bar's planar loop has
three redundant rows, dropped by the factorisation) and at random body poses (rows dropped
only beyond the bodies' freedoms), assembled with random positive masses and random rotation
responses (symmetric for the velocity stage's L D L^T, not for the Newton matrix's LU),
factorised by the general ``_band_ldl_rr`` / ``_band_lu_rr``; random right-hand sides."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from director_model.system import Body, Joint, SystemStepper
from director_model.system import _band5 as B5
from director_model.system import _common as C
from director_model.system import _rows as R
from director_model.system import _solvers as SV


def _stepper(name):
    sc = scenarios.load(name)
    bodies = [Body(b.name, b.mass, b.inertia, b.position, b.rotation, b.velocity,
                   b.omega_body) for b in sc.bodies]  # fmt: skip
    joints = [Joint(j.kind, j.body_a, j.body_b, j.anchor_a, j.anchor_b, j.axis_a, j.axis_b,
                    name=j.name) for j in sc.joints]  # fmt: skip
    return SystemStepper(bodies, joints, gravity=tuple(sc.gravity), dt=1e-3)


def _rows(st, rng, posed):
    """The Jacobians (nrow, 12) of the stepper's rows in its kernel order, at the initial
    poses or (``posed``) at random ones."""
    a = st._kasm
    nb = a.bodies.shape[0]
    X = np.array([b.position for b in st._bodies], dtype=float)
    D = np.array([b.rotation.ravel() for b in st._bodies])
    if posed:
        X = X + rng.standard_normal(X.shape)
        D = np.array([np.linalg.qr(rng.standard_normal((3, 3)))[0].ravel() for _ in range(nb)])
    n = a.rint.shape[0]
    J = np.zeros((n, 12))
    R._rows(a.rint, a.rvec, X, D, np.zeros(n), J)
    return a, J


def _matrix(a, JL, JR, rng, upper):
    """The band of sum_i JL_i blockdiag(Mx_i, Mth_i) JR_i^T with random Mx_i > 0 and Mth_i
    (symmetric positive definite if ``upper``)."""
    nb = a.bodies.shape[0]
    Mx = rng.uniform(0.5, 2.0, nb)
    Mth = np.empty((nb, 9))
    for i in range(nb):
        R = rng.standard_normal((3, 3))
        Mth[i] = (R @ R.T + np.eye(3)).ravel() if upper else (R + 2 * np.eye(3)).ravel()
    bw = a.bandwidth
    Ab = np.zeros((a.rint.shape[0], 2 * bw + 1))
    SV._assemble(a.brow_ptr, a.brow_idx, a.brow_side, JL, JR, Mx, Mth, Ab, True, bw, upper)
    return Ab, bw


def _envelope(a):
    n = a.rint.shape[0]
    ext = np.zeros(n, dtype=np.int64)
    SV._envelope(a.brow_ptr, a.brow_idx, n, ext)
    return ext


@pytest.mark.parametrize("name, redundant", [("four_bar", 3), ("bricard", 1)])
@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("posed", [False, True])
def test_block_solves_equal_the_general_ones_bit_for_bit(name, redundant, seed, posed):
    st = _stepper(name)
    rng = np.random.default_rng(seed)
    a, J0 = _rows(st, rng, posed)
    n = J0.shape[0]
    ext = _envelope(a)
    assert B5._is_band5(ext, n)
    # the velocity stage: L D L^T of G W G^T, then both solves of the same factors
    Ab, bw = _matrix(a, J0, J0, rng, upper=True)
    keep = np.zeros(n, dtype=np.int64)
    assert SV._band_ldl_rr(Ab, bw, ext, keep, np.zeros(n), np.zeros(2), C.PIVOT_CHECK) == 0
    # dropped: the loop's redundant rows, or at random poses the rows beyond the bodies' 6 nb
    # freedoms (the four-bar: 20 rows, 18 freedoms)
    assert n - keep.sum() == (max(0, n - 6 * a.bodies.shape[0]) if posed else redundant)
    for _ in range(3):
        b = rng.standard_normal(n)
        x, y = np.full(n, np.nan), np.full(n, np.nan)
        SV._band_ldl_solve_rr(Ab, bw, ext, keep, b, x)
        B5._b5_ldl_solve_rr(Ab, bw, keep, b, y)
        assert np.array_equal(x, y)
    # the Newton matrix: LU of G1 W G0^T (G1 near G0) over the kept rows
    J1 = J0 + 1e-3 * rng.standard_normal(J0.shape) * (J0 != 0.0)
    Ab, bw = _matrix(a, J1, J0, rng, upper=False)
    assert SV._band_lu_rr(Ab, bw, ext, keep, np.zeros(2), C.PIVOT_CHECK) == 0
    for _ in range(3):
        b = rng.standard_normal(n)
        x, y = np.full(n, np.nan), np.full(n, np.nan)
        SV._band_solve_rr(Ab, bw, ext, keep, b, x)
        B5._b5_solve_rr(Ab, bw, keep, b, y)
        assert np.array_equal(x, y)
        assert np.all(y[keep == 0] == 0.0)


def test_block_tridiagonal_envelopes_are_recognised():
    a = _stepper("four_bar")._kasm
    ext = _envelope(a)
    assert B5._is_band5(ext, 20)  # [9] * 5 + [14] * 5 + [19] * 10
    for r, e in ((3, 14), (12, 18), (19, 18)):  # a row reaching too far or not far enough
        bad = ext.copy()
        bad[r] = e
        assert not B5._is_band5(bad, 20)
    assert B5._is_band5(np.full(5, 4, dtype=np.int64), 5)  # one joint
    assert not B5._is_band5(np.zeros(0, dtype=np.int64), 0)
    # joints of three rows (a chain of ball joints) are not blocks of five
    assert not B5._is_band5(np.array([5, 5, 5, 8, 8, 8, 8, 8, 8], dtype=np.int64), 9)
    assert not B5._is_band5(np.array([5, 5, 5, 5, 5, 5], dtype=np.int64), 6)


@pytest.mark.parametrize("name", ["four_bar", "bricard"])
@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("posed", [False, True])
@pytest.mark.parametrize("upper", [False, True])
def test_revolute_assembly_equals_the_general_one_bit_for_bit(name, seed, posed, upper):
    st = _stepper(name)
    rng = np.random.default_rng(seed)
    a, J0 = _rows(st, rng, posed)
    n = J0.shape[0]
    assert B5._is_revolute5(a.rint, n)
    # the Newton matrix G1 W G0^T (G1 near G0, W not symmetric), the velocity stage's G W G^T
    J1 = J0 if upper else J0 + 1e-3 * rng.standard_normal(J0.shape) * (J0 != 0.0)
    Ab, bw = _matrix(a, J1, J0, np.random.default_rng(seed + 10), upper)
    nb = a.bodies.shape[0]
    r2 = np.random.default_rng(seed + 10)  # the same Mx, Mth as _matrix drew
    Mx = r2.uniform(0.5, 2.0, nb)
    Mth = np.empty((nb, 9))
    for i in range(nb):
        R = r2.standard_normal((3, 3))
        Mth[i] = (R @ R.T + np.eye(3)).ravel() if upper else (R + 2 * np.eye(3)).ravel()
    Ar = np.full_like(Ab, np.nan)
    B5._r5_assemble(a.jptr, a.jidx, a.jside, J1, J0, Mx, Mth, Ar, bw, upper)
    c0 = bw if upper else 0  # the upper band: the columns below the diagonal left as they were
    assert np.array_equal(Ab[:, c0:], Ar[:, c0:])
    assert np.all(np.isnan(Ar[:, :c0]))


def test_revolute_rows_are_recognised():
    a = _stepper("four_bar")._kasm
    assert B5._is_revolute5(a.rint, 20)
    for r, c, v in ((3, 0, 0), (1, 3, 0), (4, 0, 2)):  # a DOT row for a POINT one, ...
        bad = a.rint.copy()
        bad[r, c] = v
        assert not B5._is_revolute5(bad, 20)


@pytest.mark.parametrize("name", ["four_bar", "bricard"])
@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("posed", [False, True])
def test_revolute_rows_forces_and_rates_equal_the_general_ones_bit_for_bit(name, seed, posed):
    st = _stepper(name)
    rng = np.random.default_rng(seed)
    a = st._kasm
    n, nb = a.rint.shape[0], a.bodies.shape[0]
    X = np.array([b.position for b in st._bodies], dtype=float)
    D = np.array([b.rotation.ravel() for b in st._bodies])
    if posed:
        X = X + rng.standard_normal(X.shape)
        D = np.array([np.linalg.qr(rng.standard_normal((3, 3)))[0].ravel() for _ in range(nb)])
    g0, J0 = np.zeros(n), np.zeros((n, 12))
    R._rows(a.rint, a.rvec, X, D, g0, J0)
    g1, J1 = np.full(n, np.nan), np.zeros((n, 12))  # the zero entries are never written
    B5._r5_rows(a.rint, a.rvec, X, D, g1, J1)
    assert np.array_equal(g0, g1) and np.array_equal(J0, J1)
    lam = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, 3, n)
    F0, T0 = np.zeros((nb, 3)), np.zeros((nb, 3))
    R._forces(a.rint, J0, lam, F0, T0)
    F1, T1 = np.full((nb, 3), np.nan), np.full((nb, 3), np.nan)
    B5._r5_forces(a.rint, J1, lam, F1, T1)
    assert np.array_equal(F0, F1) and np.array_equal(T0, T1)
    # the rows' rates G u
    vel = rng.standard_normal((nb, 3)) * 10.0 ** rng.uniform(-3, 3, (nb, 3))
    om = rng.standard_normal((nb, 3)) * 10.0 ** rng.uniform(-3, 3, (nb, 3))
    u0, u1 = np.zeros(n), np.full(n, np.nan)
    R._vres(a.rint, J0, vel, om, u0)
    B5._r5_vres(a.rint, J1, vel, om, u1)
    assert np.array_equal(u0, u1)
