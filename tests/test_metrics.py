"""Metrics on synthetic trajectories whose answers are known in closed form."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from references.trajectory import Trajectory
from reports import metrics
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
    return Trajectory.from_states(sc, t, x, x.copy(), R, W)


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
    drift is measured against the scenario's state, not the trajectory's first sample."""
    sc = spin_scenario()
    t = np.linspace(0, 1, 5)
    W = np.tile([0, 0, 3.0 * 1.01], (5, 1))
    tr = spin_traj(sc, t, W=W)
    assert metrics.energy_drift(sc, tr) == pytest.approx(np.full(5, 1.01**2 - 1), rel=1e-12)
    # L = I3 W3 e_z: relative drift 1 %
    assert metrics.momentum_drift(sc, tr) == pytest.approx(np.full(5, 0.01), rel=1e-12)


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
    assert metrics.convergence_order(dts, 3.0 * dts**p) == pytest.approx(p, abs=1e-12)


def test_convergence_order_ignores_roundoff_points():
    dts = np.array([0.04, 0.02, 0.01])
    assert math.isnan(metrics.convergence_order(dts, [1e-15, 2e-16, 1e-16]))
    # two informative points and one at round-off: the slope of the two
    assert metrics.convergence_order(dts, [1.6e-5, 1e-6, 1e-16]) == pytest.approx(4.0)


def test_convergence_order_stops_at_the_error_floor():
    """4th-order errors that saturate at 5e-11 (round-off amplified near a separatrix): the fit
    uses only the points before the floor."""
    dts = np.array([0.016, 0.008, 0.004, 0.002, 0.001])
    errors = np.maximum(1e-3 * (dts / 0.016) ** 4, 5e-11)
    errors[-2:] = [4.7e-11, 4.8e-11]  # noisy floor
    assert metrics.convergence_order(dts, errors) == pytest.approx(4.0, abs=1e-9)
