"""Metrics on synthetic trajectories whose answers are known in closed form."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from references.trajectory import OneBody
from reports.metrics import body as metrics
from reports.metrics import catalog
from scenarios.model import Scenario


def spin_scenario(**kw):
    """A symmetric body (I1 = I2) spinning about its axis 3: R(t) = Rz(w t) exactly."""
    base = dict(
        name="spin",
        description="",
        mass=2.0,
        inertia=(1.0, 1.0, 0.5),
        rotation=np.eye(3),
        omega_body=(0.0, 0.0, 3.0),
        t_end=1.0,
        dt=0.1,
    )
    base.update(kw)
    return Scenario(**base)


def rz(a):
    return Rotation.from_rotvec(np.outer(a, [0, 0, 1.0])).as_matrix()


def spin_traj(sc, t, angle_offset=0.0, W=None):
    W = np.tile(sc.omega_body, (len(t), 1)) if W is None else W
    R = rz(sc.omega_body[2] * t + angle_offset)
    x = np.zeros((len(t), 3))
    return OneBody.from_states(sc, t, x, x.copy(), R, W)


def test_exact_spin_has_zero_drifts_and_errors():
    sc = spin_scenario()
    t = np.linspace(0, 1, 11)
    tr = spin_traj(sc, t)
    m = metrics.compute_metrics(sc, tr, ref=spin_traj(sc, t))
    # Rz computed by scipy: orthonormal to a few ulps (4 eps bound on 3x3 products)
    assert m["orthonormality_max"] < 1e-15
    assert m["energy_drift_max"] == 0.0
    assert m["momentum_drift_max"] < 1e-15
    assert m["attitude_error_max"] == 0.0
    assert m["omega_error_max"] == 0.0


@pytest.mark.parametrize("delta", [1e-9, 1e-4, 0.3, 2.5])
def test_attitude_error_is_the_rotation_angle(delta):
    """R = Rz(delta) against R_ref = 1: the geodesic distance is exactly |delta| (delta < pi).
    The Frobenius-norm formula keeps full relative accuracy down to tiny angles (an arccos of
    the trace would return 0 for delta = 1e-9)."""
    sc = spin_scenario(omega_body=(0, 0, 0.0))
    t = np.linspace(0, 1, 5)
    err = metrics.attitude_error(spin_traj(sc, t, delta), spin_traj(sc, t))
    np.testing.assert_allclose(err, delta, rtol=1e-12)


@pytest.mark.parametrize("delta", [1e-6, 0.3])
def test_attitude_error_along_a_moving_reference(delta):
    """Same along R_ref = Rz(3t): the test data itself carries ~1e-16 absolute rounding from
    forming 3t + delta, hence the absolute tolerance of a few ulps of the angle."""
    sc = spin_scenario()
    t = np.linspace(0, 1, 5)
    err = metrics.attitude_error(spin_traj(sc, t, delta), spin_traj(sc, t))
    np.testing.assert_allclose(err, delta, rtol=1e-12, atol=2e-15)


def test_energy_drift_relative_to_scenario_state():
    """W3 wrong by 1 % from the start: T = 1/2 I3 W3^2 changes by (1.01^2 - 1) exactly, and the
    drift is measured against the scenario's state, not the trajectory's first sample. A free
    spinning body without gravity: the energy scale is its kinetic energy T0."""
    sc = spin_scenario()
    t = np.linspace(0, 1, 5)
    W = np.tile([0, 0, 3.0 * 1.01], (5, 1))
    tr = spin_traj(sc, t, W=W)
    assert metrics.energy_drift(sc, tr) == pytest.approx(np.full(5, 1.01**2 - 1), rel=1e-12)
    # L = I3 W3 e_z with |L| = L_c for a spin about the major axis (I3 = 0.5 is the smallest
    # moment here, so L_c = sqrt(2 T0 I_max) = sqrt(2 * 2.25 * 1) = 2.1213): 0.015 / 2.1213
    assert metrics.momentum_drift(sc, tr) == pytest.approx(
        np.full(5, 0.5 * 0.03 / math.sqrt(2 * 2.25 * 1.0)), rel=1e-12
    )


def pendulum(**kw):
    """A physical pendulum released from rest with its axis horizontal: the potential is
    measured from the pivot, so E0 = 0, T0 = 0 and L0 = 0. m = 2 kg, COM 0.25 m from the
    pivot along body axis 3, g = 9.81: m |g| l = 4.905 J."""
    base = dict(
        name="pendulum",
        description="",
        mass=2.0,
        inertia=(0.02, 0.02, 0.01),
        rotation=Rotation.from_rotvec([math.pi / 2, 0, 0]).as_matrix(),
        omega_body=(0.0, 0.0, 0.0),
        gravity=(0.0, 0.0, -9.81),
        pivot=(0.0, 0.0, -0.25),
        t_end=1.0,
        dt=0.1,
    )
    base.update(kw)
    return Scenario(**base)


def test_energy_drift_of_a_pendulum_released_at_rest_uses_m_g_l():
    """E0 = 0 and T0 = 0: the drift is |E - E0| / (m |g| l), written out here: a trajectory
    whose energy is off by 0.049 J reads 0.049 / (2 * 9.81 * 0.25) = 0.0099898. Dividing by
    E0 or T0 (both 0) or by |E0| would give inf or nan."""
    sc = pendulum()
    t = np.linspace(0, 1, 3)
    tr = OneBody.from_states(sc, t, None, None, np.tile(sc.rotation, (3, 1, 1)), np.zeros((3, 3)))
    tr.energy = tr.energy + np.array([0.0, 0.049, -0.049])
    expect = np.array([0.0, 0.049, 0.049]) / (2.0 * 9.81 * 0.25)
    np.testing.assert_allclose(metrics.energy_drift(sc, tr), expect, rtol=1e-12, atol=1e-15)


def test_energy_drift_scale_is_neither_T0_nor_E0():
    """A slow top whose weight term dominates: T0 = 1/2 W.I_p W = 0.0105 J with pivot moments
    I_p = (0.02 + 2 * 0.25^2, ...) = (0.145, 0.145, 0.01) and W = (0.1, 0.2, 0.5):
    T0 = 1/2 (0.145 * 0.01 + 0.145 * 0.04 + 0.01 * 0.25) = 0.0048750; m |g| l = 4.905 J
    > T0, so the scale is 4.905 J; E0 = T0 - m g . x_G is neither."""
    sc = pendulum(omega_body=(0.1, 0.2, 0.5))
    t0 = 0.5 * (0.145 * 0.01 + 0.145 * 0.04 + 0.01 * 0.25)
    assert sc.energy_scale == pytest.approx(4.905, rel=1e-15)
    E0 = float(metrics._initial(sc)[0])
    assert abs(E0 - t0) < 1e-12  # axis horizontal: x_G at the pivot's height, V = 0
    t = np.linspace(0, 1, 2)
    tr = OneBody.from_states(
        sc, t, None, None, np.tile(sc.rotation, (2, 1, 1)), np.tile(sc.omega_body, (2, 1))
    )
    tr.energy = tr.energy + np.array([0.0, 1e-3])
    assert metrics.energy_drift(sc, tr)[1] == pytest.approx(1e-3 / 4.905, rel=1e-10)


def test_momentum_drift_of_a_pendulum_with_zero_initial_momentum():
    """L0 = 0: the drift of L . g_hat is divided by L_c = sqrt(2 E_c I_max), E_c = m|g|l =
    4.905 J, I_max = 0.02 + m l^2 = 0.145 kg m^2 (pivot moments): L_c = 1.1926. A trajectory
    whose vertical momentum is off by 1e-3 reads 1e-3 / 1.1926."""
    sc = pendulum()
    t = np.linspace(0, 1, 2)
    tr = OneBody.from_states(sc, t, None, None, np.tile(sc.rotation, (2, 1, 1)), np.zeros((2, 3)))
    tr.angular_momentum = tr.angular_momentum + np.array([[0, 0, 0], [0, 0, 1e-3]])
    L_c = math.sqrt(2 * 4.905 * 0.145)
    np.testing.assert_allclose(metrics.momentum_drift(sc, tr), [0.0, 1e-3 / L_c], rtol=1e-12)


def test_momentum_drift_of_a_symmetric_top_sees_the_spin():
    """A symmetric top with its axis horizontal: the spin L . d3 = I3 W3 changes by I3 dW3 =
    0.01 * 0.3 = 3e-3 while L . g_hat stays 0; only the spin term can see it. L_c = sqrt(2 E_c
    I_max) with E_c = max(T0, m|g|l) = max(1/2 0.01 5^2, 4.905) = 4.905."""
    sc = pendulum(omega_body=(0.0, 0.0, 5.0))
    assert metrics.conserved_momentum(sc) == "Lg+spin"
    t = np.linspace(0, 1, 2)
    W = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, 5.3]])
    tr = OneBody.from_states(sc, t, None, None, np.tile(sc.rotation, (2, 1, 1)), W)
    assert abs(tr.angular_momentum[1] @ [0, 0, 1.0]) < 1e-15  # d3 horizontal
    L_c = math.sqrt(2 * 4.905 * 0.145)
    np.testing.assert_allclose(metrics.momentum_drift(sc, tr), [0.0, 3e-3 / L_c], rtol=1e-10)


def test_orthonormality_of_a_scaled_rotation():
    """R = (1 + e) Rz: R^T R - 1 = ((1+e)^2 - 1) 1, Frobenius norm sqrt(3) ((1+e)^2 - 1)."""
    sc = spin_scenario()
    t = np.linspace(0, 1, 3)
    e = 1e-6
    tr = spin_traj(sc, t)
    tr.rotation = tr.rotation * (1 + e)
    expect = math.sqrt(3) * ((1 + e) ** 2 - 1)
    np.testing.assert_allclose(metrics.orthonormality(tr), expect, rtol=1e-9)


def test_pivoted_top_conserves_vertical_and_spin_components_only():
    """Tilted symmetric top on a pivot with gravity: the conserved set is L.e_z and L.d3."""
    sc = spin_scenario(
        pivot=(0, 0, -0.5),
        gravity=(0, 0, -9.81),
        rotation=Rotation.from_rotvec([0.3, 0, 0]).as_matrix(),
    )
    assert metrics.conserved_momentum(sc) == "Lg+spin"
    assert metrics.conserved_momentum(spin_scenario()) == "L"
    asym = spin_scenario(inertia=(1.0, 1.2, 0.5), pivot=(0, 0, -0.5), gravity=(0, 0, -9.81))
    assert metrics.conserved_momentum(asym) == "Lg"


def test_nonfinite_samples_are_reported_as_inf():
    sc = spin_scenario()
    t = np.linspace(0, 1, 4)
    tr = spin_traj(sc, t)
    tr.energy[2] = np.nan
    assert metrics.compute_metrics(sc, tr)["energy_drift_max"] == math.inf


def test_reference_on_other_times_is_refused():
    sc = spin_scenario()
    with pytest.raises(ValueError, match="other times"):
        metrics.compute_metrics(
            sc, spin_traj(sc, np.linspace(0, 1, 4)), ref=spin_traj(sc, np.linspace(0, 1, 5))
        )


@pytest.mark.parametrize("p", [1.0, 2.0, 4.0])
def test_convergence_order_recovers_power_law(p):
    dts = np.array([0.04, 0.02, 0.01, 0.005])
    slope, n = metrics.convergence_order(dts, 3e-3 * (dts / 0.04) ** p)
    assert slope == pytest.approx(p, abs=1e-12) and n == 4


def test_convergence_order_recovers_4_from_order_4_plus_a_floor():
    """Exact order-4 errors plus a 2e-11 floor (a reference's accuracy or round-off): fitting
    every point gives a slope below 3.5; the fit stops where the local slope drops (3.93, then
    3.22 as the floor's share grows), drops the point within 10x of the floor value and
    recovers 4 from the two largest steps (the floor's share of 6.3e-9 biases the slope by
    log2(1 + 2e-11/6.3e-9) ~ 0.005)."""
    dts = np.array([0.004, 0.002, 0.001, 0.0005, 0.00025])
    floor = 2e-11
    errors = 1e-7 * (dts / 0.004) ** 4 + floor
    naive = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert naive < 3.5
    slope, n = metrics.convergence_order(dts, errors, floors=floor)
    assert slope == pytest.approx(4.0, abs=0.01) and n == 2


def test_convergence_order_drops_saturated_points():
    """Errors of order 1 rad (the phase is lost) are not in the asymptotic range: with them the
    slope of this order-2 data would be 1.2; without, 2."""
    dts = np.array([0.008, 0.004, 0.002, 0.001])
    errors = np.array([3.1, 1.2, 0.04, 0.01])
    slope, n = metrics.convergence_order(dts, errors)
    assert slope == pytest.approx(2.0, abs=1e-12) and n == 2


def test_convergence_order_is_nan_with_fewer_than_two_points():
    dts = np.array([0.04, 0.02, 0.01])
    slope, n = metrics.convergence_order(dts, [1e-15, 2e-16, 1e-16], floors=1e-16)
    assert math.isnan(slope) and n == 0
    slope, n = metrics.convergence_order(dts, [0.5, 0.04, 0.039])
    assert math.isnan(slope) and n == 0  # 0.04 -> 0.039 stops falling: a floor, both out


def test_convergence_order_stops_at_an_undeclared_floor():
    """4th-order errors that saturate at 5e-11 that no floor estimate covers (round-off
    amplified near a separatrix): the points stop falling and the fit stops there."""
    dts = np.array([0.016, 0.008, 0.004, 0.002, 0.001])
    errors = np.maximum(1e-3 * (dts / 0.016) ** 4, 5e-11)
    errors[-2:] = [4.7e-11, 4.8e-11]  # noisy floor
    slope, n = metrics.convergence_order(dts, errors)
    assert slope == pytest.approx(4.0, abs=1e-9) and n == 3


def test_convergence_order_stops_where_the_slope_drops_sharply():
    """Order-4 errors meeting a floor between the last two steps (local slopes 3.94, then
    1.66, as Pinocchio RKMK4 on gazebo_boxes_complex near its separatrix): the drop marks a
    floor; the point before it is within 10x of the floor value and goes too, leaving one
    point: no order. With the floor further down (local slopes 3.94, 3.75) both stay."""
    dts = np.array([4e-3, 2e-3, 1e-3])
    slope, n = metrics.convergence_order(dts, [1.975e-8, 1.3e-9, 4.1e-10])
    assert math.isnan(slope) and n == 1
    slope, n = metrics.convergence_order(dts, [1.975e-8, 1.3e-9, 9.7e-11])
    assert n == 3 and slope == pytest.approx(3.85, abs=0.05)


# == attitude error of a matrix that is not a rotation ========================================


def _stretched(Q, size, seed=0):
    """Q (I + S) with S symmetric, ||S|| ~ size: its polar factor is Q exactly (I + S is
    symmetric positive definite), so the attitude it stands for is known by construction."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((len(Q), 3, 3))
    S = size * (A + np.swapaxes(A, 1, 2)) / 2
    return Q @ (np.eye(3) + S)


@pytest.mark.parametrize("stretch", [1e-9, 1e-6, 3e-5, 1e-3, 0.05, 0.3])
@pytest.mark.parametrize("delta", [1e-7, 0.3, 2.5])
def test_attitude_error_of_a_stretched_rotation_is_that_of_its_rotation(stretch, delta):
    """R = Rz(delta) (I + S): the attitude error against 1 is delta whatever the stretch
    (both the series and the SVD branch of the polar factor); the stretch shows in
    orthonormality_max only. atol 1e-15: the matrices and the SVD carry a few ulp of absolute
    rounding (measured <= 2.6e-16); rtol 1e-12 for the rest."""
    sc = spin_scenario(omega_body=(0, 0, 0.0))
    t = np.linspace(0, 1, 7)
    ref = spin_traj(sc, t)
    R = _stretched(rz(np.full(len(t), delta)), stretch)
    tr = OneBody.from_states(sc, t, ref.position, ref.velocity, R, ref.omega_body)
    err = metrics.attitude_error(tr, ref)
    np.testing.assert_allclose(err, delta, rtol=1e-12, atol=1e-15)
    assert metrics.orthonormality(tr).max() > stretch  # the norm error is reported there


def test_attitude_error_of_a_non_unit_quaternion_against_scipy():
    """A semi-explicit Euler step on quaternion coordinates leaves |q| != 1, and the matrix of
    the unit-quaternion formula is then no rotation: its attitude error is the angle of the
    rotation it stands for, computed here independently by scipy (polar decomposition by
    scipy.linalg.polar, angle of Q_ref^T Q by scipy's Rotation)."""
    from scipy.linalg import polar

    rng = np.random.default_rng(3)
    n = 40
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    q *= (1.0 + rng.uniform(-0.05, 0.05, n))[:, None]  # norms 0.95 .. 1.05
    w, x, y, z = q.T
    R = np.empty((n, 3, 3))
    R[:, 0] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], 1)
    R[:, 1] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], 1)
    R[:, 2] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], 1)
    Rref = Rotation.random(n, random_state=5).as_matrix()
    sc = spin_scenario(omega_body=(0, 0, 0.0))
    t = np.linspace(0, 1, n)
    ref = OneBody.from_states(sc, t, np.zeros((n, 3)), np.zeros((n, 3)), Rref, np.zeros((n, 3)))
    tr = OneBody.from_states(sc, t, np.zeros((n, 3)), np.zeros((n, 3)), R, np.zeros((n, 3)))
    Q = np.array([polar(r)[0] for r in R])
    want = Rotation.from_matrix(np.einsum("nji,njk->nik", Rref, Q)).magnitude()
    # 1e-12: angles of order 1, computed by two formulas (Frobenius distance vs quaternion)
    np.testing.assert_allclose(metrics.attitude_error(tr, ref), want, rtol=0, atol=1e-12)
    # the old measure, the distance of R itself, counted the norm error as attitude
    raw = 2 * np.arcsin(np.minimum(np.linalg.norm(R - Rref, axis=(1, 2)) / (2 * math.sqrt(2)), 1))
    assert np.max(np.abs(raw - want)) > 1e-3


def test_nearest_rotation_of_a_reflection_and_of_non_finite_matrices():
    """A reflection diag(1, 1, -1) R: the nearest rotation with det +1 (the SVD branch with
    the sign), and NaN for a non-finite matrix, which the maximum reports as inf."""
    Q = rz(np.array([0.4]))
    bad = np.array([Q[0] @ np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan)])
    out = metrics.nearest_rotation(bad)
    assert np.linalg.det(out[0]) == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(out[0].T @ out[0], np.eye(3), atol=1e-14)
    assert np.all(np.isnan(out[1]))
    assert catalog.largest([0.1, math.nan]) == math.inf


def test_a_read_only_reference_keeps_its_nearest_rotation_and_a_writable_one_does_not():
    """The reference the runner shares among runs has read-only arrays: its polar factor is
    computed once and reused while its rotation is the same array; a writable trajectory is
    projected anew at each call (it may be changed in place), with the same errors."""
    sc = spin_scenario(omega_body=(0, 0, 0.0))
    t = np.linspace(0, 1, 9)
    ref = spin_traj(sc, t)
    tr = spin_traj(sc, t, angle_offset=1e-3)
    want = metrics.attitude_error(tr, ref)
    assert not hasattr(ref, "_nearest_rotation")  # writable: nothing kept
    ref.rotation.setflags(write=False)
    np.testing.assert_array_equal(metrics.attitude_error(tr, ref), want)
    R, Q = ref._nearest_rotation
    assert R is ref.rotation and not Q.flags.writeable
    np.testing.assert_array_equal(Q, metrics.nearest_rotation(ref.rotation))
    np.testing.assert_array_equal(metrics.attitude_error(tr, ref), want)
    assert ref._nearest_rotation[1] is Q  # reused
    ref.rotation = rz(sc.omega_body[2] * t + 2e-3)  # another array: projected anew
    np.testing.assert_allclose(metrics.attitude_error(tr, ref), 1e-3, rtol=1e-9)


def test_gram_is_einsums_product_bit_for_bit():
    """gram(R) = R^T R with the products and sums einsum forms, in its order: equal to
    np.einsum's bit for bit on stretched rotations, on matrices of any scale and with
    non-finite entries (quietly, as einsum), and exactly 1 for rotations by quarter turns."""
    import warnings

    rng = np.random.default_rng(7)
    for trial in range(40):
        n = int(rng.integers(1, 500))
        R = Rotation.random(n, random_state=trial).as_matrix()
        R = R * (1 + 10 ** rng.uniform(-16, -1) * rng.standard_normal((n, 3, 3)))
        if trial % 2:
            R = rng.standard_normal((n, 3, 3)) * 10 ** rng.uniform(-150, 150)
        if trial % 5 == 0:
            R.flat[rng.integers(0, R.size, 4)] = [np.nan, np.inf, -np.inf, -0.0]
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            G = metrics.gram(R)
        assert G.flags.c_contiguous
        np.testing.assert_array_equal(G, np.einsum("nki,nkj->nij", R, R))
    quarter = Rotation.from_rotvec(np.pi / 2 * np.eye(3)).as_matrix().round()
    np.testing.assert_array_equal(metrics.gram(quarter), np.broadcast_to(np.eye(3), (3, 3, 3)))


def test_convergence_orders_fill_each_configuration_from_its_ok_runs():
    """Per (scenario, engine, integrator): the slope of its ok runs' attitude errors over dt
    (errors 3e-3 (dt/0.04)^p, so the slope is p) on each of those rows; NaN on a failed run
    and for a configuration with one dt, whatever the table's index."""
    import pandas as pd

    dts = [0.04, 0.02, 0.01]
    rows = []
    for engine, p in (("a", 2.0), ("b", 4.0)):
        for h in dts:
            rows.append(dict(scenario="s", engine=engine, integrator="i", dt=h, status="ok",
                             attitude_error_max=3e-3 * (h / 0.04) ** p))  # fmt: skip
    rows.append(dict(scenario="s", engine="b", integrator="i", dt=0.005, status="diverged",
                     attitude_error_max=math.inf))  # fmt: skip
    rows.append(dict(scenario="s", engine="c", integrator="i", dt=0.01, status="ok",
                     attitude_error_max=1e-6))  # fmt: skip
    df = pd.DataFrame(rows, index=np.arange(len(rows)) * 3 + 5)  # not 0..n-1
    df["reference_accuracy"], df["roundoff_floor"] = 1e-14, math.nan
    out = metrics.add_convergence_orders(df)
    assert list(out.index) == list(df.index) and "convergence_order" not in df
    order = dict(zip(out["engine"] + out["status"], out["convergence_order"], strict=True))
    assert order["aok"] == pytest.approx(2.0, rel=1e-12)
    assert order["bok"] == pytest.approx(4.0, rel=1e-12)
    assert math.isnan(order["bdiverged"])
    assert math.isnan(order["cok"])
    assert list(out["convergence_points"].fillna(-1)) == [3, 3, 3, 3, 3, 3, -1, -1]


def test_linear_momentum_drift_in_closed_form():
    """A free body thrown with v0 = (1, 0, 0) m/s under g = (0, 0, -9.81) m/s^2 for 1 s: the
    largest speed is the final one, |v1| = sqrt(1 + 9.81^2), so p_c = sqrt(2 m E_tr,c) =
    m |v1|. v_G = v0 + g t exactly conserves m v_G - m g t (0 up to the rounding of g t); an
    extra velocity (0, 1e-3 t, 0) m/s gives 1e-3 / |v1| at t = 1 s. A pivoted body: NaN."""
    v0, g = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, -9.81])
    sc = spin_scenario(velocity=v0, gravity=g)
    t = np.linspace(0, 1, 11)
    R, W = rz(3.0 * t), np.tile(sc.omega_body, (len(t), 1))
    x = v0 * t[:, None] + 0.5 * g * t[:, None] ** 2
    v = v0 + g * t[:, None]
    exact = metrics.compute_metrics(sc, OneBody.from_states(sc, t, x, v, R, W))
    assert exact["linear_momentum_drift_max"] < 1e-15  # a few ulp of g t over |v1| ~ 10
    kick = np.outer(t, [0.0, 1e-3, 0.0])
    off = metrics.compute_metrics(sc, OneBody.from_states(sc, t, x, v + kick, R, W))
    assert off["linear_momentum_drift_max"] == pytest.approx(1e-3 / math.hypot(1.0, 9.81))
    top = spin_scenario(pivot=(0.0, 0.0, -0.2), gravity=g)
    assert math.isnan(metrics.compute_metrics(top, spin_traj(top, t))["linear_momentum_drift_max"])


def test_linear_momentum_drift_sees_a_velocity_in_body_axes():
    """v_G reported in body axes, R^T v0, on a body spinning at 3 rad/s about z without gravity:
    its length, hence the translational energy, is right, but the momentum turns: |Rz(-3t) v0 -
    v0| / |v0| = 2 sin(3t/2), largest at t = 1 s: 2 sin(1.5). The default tolerance fails it."""
    from reports.metrics.verdicts import DEFAULT_TOLERANCES, verdict

    v0 = np.array([1.0, 0.0, 0.0])
    sc = spin_scenario(velocity=v0)
    t = np.linspace(0, 1, 11)
    R, W = rz(3.0 * t), np.tile(sc.omega_body, (len(t), 1))
    x = v0 * t[:, None]
    wrong = np.einsum("nji,j->ni", R, v0)  # R^T v0
    m = metrics.compute_metrics(sc, OneBody.from_states(sc, t, x, wrong, R, W))
    assert m["energy_drift_trans_max"] < 1e-15
    assert m["linear_momentum_drift_max"] == pytest.approx(2.0 * math.sin(1.5), rel=1e-14)
    v, detail = verdict({"status": "ok", **m}, DEFAULT_TOLERANCES)
    assert v == "fail" and detail == "linear_momentum_drift_max 1.99 > 0.01", detail


def test_linear_momentum_drift_of_a_run_saved_and_streamed():
    """The director model's RATTLE4 on a box thrown under gravity keeps m v_G - m g t to
    round-off (its translation is exact: v += g h), and the streamed maximum over every step
    equals the one at the saved samples (the same states: every step is saved)."""
    import scenarios
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    box = scenarios.load("gazebo_boxes_simple").replace(
        gravity=(0.0, 0.0, -9.81), t_end=1.0, dt_sweep=(), save_every=1
    )
    full = execute(RunSpec(box, "director", "rattle4", 1e-3))
    seg = execute(RunSpec(box, "director", "rattle4", 1e-3, segment=300))
    assert full["status"] == seg["status"] == "ok", (full["message"], seg["message"])
    # 1000 steps of v += g h round at most 1000 ulp of |v| <= 10 m/s (1.8e-12 m/s) over
    # p_c / m = |v1| = 9.76 m/s: 2e-13 (measured 6e-18)
    assert full["linear_momentum_drift_max"] < 2e-13
    assert seg["linear_momentum_drift_max"] == pytest.approx(full["linear_momentum_drift_max"])


@pytest.mark.parametrize(
    "name, engine, integrator",
    [("dzhanibekov", "mujoco", "RK4"), ("heavy_top", "director", "rattle4")],
)
def test_a_run_on_a_bodies_axis_gives_the_same_row_and_file(
    tmp_path, monkeypatch, name, engine, integrator
):
    """A single body's run (its output on the bodies axis, Trajectory.from_states) gives the row
    and the trajectory file of the same run handed over without the bodies axis
    (references.trajectory.one_body of it: the single body's (n, ...) arrays), bit for bit:
    every column but the timings, and every column of the file."""
    import dataclasses

    import pandas as pd

    import scenarios
    from references.engines import get_engine
    from references.trajectory import one_body
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    sc = scenarios.load(name).replace(t_end=0.5, dt_sweep=())
    spec = RunSpec(sc, engine, integrator, 1e-3)
    plain = execute(spec, out=tmp_path / "plain")
    cls = get_engine(engine)
    run = cls.run

    def one(self, *args, **kw):
        out = run(self, *args, **kw)
        assert out.trajectory.position.shape[1:] == (1, 3)
        return dataclasses.replace(out, trajectory=one_body(out.trajectory))

    monkeypatch.setattr(cls, "run", one)
    bodies = execute(spec, out=tmp_path / "bodies")
    assert plain["status"] == "ok", plain["message"]
    timing = {"wall_time_s", "engine_time_s", "glue_time_s", "cpu_time_s", "ns_per_step",
              "engine_ns_per_step", "finished_at", "wall_time_max_s", "engine_time_max_s",
              "cpu_time_max_s", "cpu_share", "timing_repeats", "_run_seconds",
              "_references"}  # fmt: skip
    assert plain.keys() == bodies.keys()
    for c in plain.keys() - timing:
        a, b = plain[c], bodies[c]
        same = (a == b) or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
        assert same, (c, a, b)
    fa = pd.read_parquet(tmp_path / "plain" / plain["trajectory"])
    fb = pd.read_parquet(tmp_path / "bodies" / bodies["trajectory"])
    pd.testing.assert_frame_equal(fa, fb, check_exact=True)


def test_one_body_of_a_shared_reference_is_one_view_and_its_polar_factor_is_kept():
    """The runner shares a scenario's reference among the runs on its grid, read-only
    (reports.run.body.reference_for): one_body gives the same view of it at every call, so
    that its nearest rotation (reports.metrics.body._nearest_kept) is computed once per
    reference, not once per run; a trajectory that may change gets a new view each time."""
    import scenarios
    from references.trajectory import one_body
    from reports.metrics.body import _nearest_kept
    from reports.run.body import reference_for

    sc = scenarios.load("dzhanibekov")
    t = np.linspace(0.0, 0.5, 6)
    ref = reference_for(sc, t)
    assert reference_for(sc, t) is ref and ref.rotation.shape == (6, 1, 3, 3)
    view = one_body(ref)
    assert one_body(ref) is view and not view.rotation.flags.writeable
    assert _nearest_kept(one_body(ref)) is _nearest_kept(view)
    tr = OneBody.from_states(
        sc,
        ref.t,
        *(np.array(getattr(view, f)) for f in ("position", "velocity", "rotation", "omega_body")),
    ).as_bodies()
    assert one_body(tr) is not one_body(tr)
    np.testing.assert_array_equal(one_body(tr).rotation, view.rotation)
