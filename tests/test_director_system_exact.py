"""director_model.system against exact motions, measured orders, closed loops.

References (none from the integrator): rigid rotation plus free fall of a straight chain
(a relative equilibrium); the steady rotation of a double conical pendulum whose angles come
from the Newton-Euler balance of its links (scipy fsolve); the planar pendulum of a
parallelogram four-bar integrated by scipy's DOP853 at rtol 1e-13; self-convergence on a
chaotic double pendulum. Error bounds are about 3x the errors measured when the tests were
written (the README table), so that a lost order or a wrong term fails them; the orders
themselves are checked from error ratios.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from director_model.system import simulate_system
from director_model.system.examples import (
    bricard,
    double_conical_pendulum,
    parallelogram_four_bar,
    rod_chain,
    straight_chain,
)

ORDERS = {"rattle": 2, "rattle4": 4, "rattle6": 6}


def _straight_chain_error(scheme, dt, t_end=4.0):
    b, j, exact = straight_chain()
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=dt, t_end=t_end, scheme=scheme,
                         save_every=int(round(t_end / dt)))  # fmt: skip
    X, R = exact(t_end)
    eR = max(np.abs(tr.rotation[-1, i] - R).max() for i in range(3))
    eX = np.abs(tr.position[-1] - X).max()
    return eR, eX, tr


@pytest.mark.parametrize("scheme", list(ORDERS))
def test_straight_chain_uniform_rotation_and_free_fall_orders(scheme):
    e1, x1, tr = _straight_chain_error(scheme, 0.02)
    e2, x2, _ = _straight_chain_error(scheme, 0.01)
    p = ORDERS[scheme]
    # measured 2.00, 4.00, 6.00 (asymptotic regime at these steps): within 0.1
    assert abs(np.log2(e1 / e2) - p) < 0.1
    assert abs(np.log2(x1 / x2) - p) < 0.1
    # measured at dt = 0.01: 5.3e-4, 5.0e-7, 8.1e-13 rad
    assert e2 < {2: 1.6e-3, 4: 1.5e-6, 6: 2.5e-12}[p]
    assert np.ptp(tr.linear_momentum[:, :2], axis=0).max() < 1e-13  # horizontal: no force


@pytest.mark.parametrize("scheme, bound", [("rattle", 3e-5), ("rattle4", 6e-10),
                                           ("rattle6", 3e-13)])  # fmt: skip
def test_double_conical_pendulum_steady_rotation(scheme, bound):
    b, j, exact, th = double_conical_pendulum()
    assert 0.3 < th[0] < th[1] < 0.6  # the in-phase cone, outer link steeper
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=1e-3, t_end=2.0, scheme=scheme,
                         save_every=100)  # fmt: skip
    err = 0.0
    for k, t in enumerate(tr.t):
        X, R = exact(t)
        err = max(err, max(np.abs(tr.rotation[k, i] - R[i]).max() for i in range(2)))
        err = max(err, np.abs(tr.position[k] - X).max())
    # measured 8.6e-6, 1.8e-10, 8.7e-15 over 2 s (the rotation is uniform, 3 rad/s)
    assert err < bound


def _pendulum(I_eff, k, t, theta_dot0=7.0, g=9.81):
    sol = solve_ivp(lambda _, y: (y[1], -g * k / I_eff * np.sin(y[0])), (0, t[-1]),
                    (0.0, theta_dot0), method="DOP853", rtol=1e-13, atol=1e-13,
                    dense_output=True)  # fmt: skip
    return sol.sol(t)[0]


@pytest.mark.parametrize("scheme, dt, t_end, bound", [("rattle", 1e-3, 3.0, 7e-5),
                                                     ("rattle4", 1e-3, 3.0, 1.3e-8),
                                                     ("rattle6", 2e-3, 2.0, 5e-12)])  # fmt: skip
def test_parallelogram_four_bar_through_its_singular_configuration(scheme, dt, t_end, bound):
    b, j, I_eff, k = parallelogram_four_bar()
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=dt, t_end=t_end, scheme=scheme,
                         save_every=10)  # fmt: skip
    th = np.unwrap(np.arctan2(tr.rotation[:, 0, 0, 2], tr.rotation[:, 0, 2, 2]))
    # measured 2.3e-5, 4.1e-9 rad over 3 s at dt = 1e-3, 1.6e-12 over 2 s at dt = 2e-3
    # against DOP853 (rtol 1e-13: about 1e-13 over these few periods)
    assert np.abs(th - _pendulum(I_eff, k, tr.t)).max() < bound
    assert th.max() > np.pi / 2 + 0.09  # it swings through the collinear configuration
    # the rocker stays parallel to the crank (no jump to the crossed branch), the coupler
    # translates, every joint row holds
    assert np.abs(tr.rotation[:, 1] - tr.rotation[:, 0]).max() < 1e-12
    assert np.abs(tr.rotation[:, 2] - np.eye(3)).max() < 1e-12
    assert tr.constraint_position.max() < 1e-14 and tr.constraint_velocity.max() < 1e-12
    # 20 rows of rank 17 -> the minimum-norm solver, and the singular steps are reported
    assert tr.solver == "minnorm" and tr.rank_nominal == 17
    assert tr.rank_drop_steps >= 2 and tr.min_singular_value < 1e-10


@pytest.mark.parametrize("scheme, dts", [("rattle", (0.004, 0.002, 0.001)),
                                         ("rattle4", (0.008, 0.004, 0.002)),
                                         ("rattle6", (0.02, 0.01, 0.005))])  # fmt: skip
def test_orders_by_self_convergence_on_a_chaotic_double_pendulum(scheme, dts):
    # two rods on spherical joints, tilted by up to ~1 rad and tumbling: chaotic; over 2 s
    # the errors are still in the asymptotic regime
    b, j = rod_chain(2, True, seed=5, tilt=1.0)
    R = []
    for dt in dts:
        tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=dt, t_end=2.0, scheme=scheme,
                             save_every=int(round(2.0 / dt)))  # fmt: skip
        R.append(tr.rotation[-1])
    slope = np.log2(np.abs(R[0] - R[1]).max() / np.abs(R[1] - R[2]).max())
    assert abs(slope - ORDERS[scheme]) < 0.1  # measured 2.00, 4.04, 6.03


def test_bricard_redundant_loop():
    b, j = bricard()
    tr = simulate_system(b, j, gravity=(0, -9.81, 0), dt=1e-3, t_end=2.0, scheme="rattle4",
                         save_every=100)  # fmt: skip
    assert tr.solver == "minnorm" and tr.rank_nominal == 29  # 30 rows, one redundant
    assert tr.constraint_position.max() < 1e-14 and tr.constraint_velocity.max() < 1e-12
    # energy: bounded O(h^4) error, measured 1.4e-11 J on an O(10 J) potential
    assert np.ptp(tr.energy) < 1e-9
    tip = tr.position[:, 2] + np.einsum("nij,j->ni", tr.rotation[:, 2], (0, 0, 0.5))
    assert np.ptp(tip[:, 0]) > 0.5  # it moves (point 3 swings in x)


@pytest.mark.parametrize("kind", ["prismatic", "cylindrical"])
def test_slider_joints_exact_sliding_and_spin(kind):
    # a body on a 45-degree slide through the origin (its principal axis 3 along the slide):
    # the COM slides with the acceleration (g . n) n, and on a cylindrical joint it also
    # spins steadily about the axis (a principal axis: no torque); exact in closed form
    from scipy.spatial.transform import Rotation

    from director_model.system import Body, Joint

    n = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    g = np.array([0.0, 0.0, -9.81])
    R0 = Rotation.align_vectors([n], [[0.0, 0.0, 1.0]])[0].as_matrix()
    x0, v0 = np.array([0.2, 0.0, 0.2]), 0.7 * n
    spin = 3.0 if kind == "cylindrical" else 0.0
    b = Body("s", 2.0, (0.3, 0.4, 0.5), position=x0, rotation=R0, velocity=v0,
             omega_body=(0.0, 0.0, spin))  # fmt: skip
    j = Joint(kind, "s", None, anchor_a=(0, 0, 0), anchor_b=(0, 0, 0), axis_a=(0, 0, 1), axis_b=n)
    tr = simulate_system([b], [j], gravity=g, dt=1e-3, t_end=1.0, scheme="rattle6",
                         save_every=100)  # fmt: skip
    X = x0 + np.outer(tr.t, v0) + 0.5 * np.outer(tr.t**2, (g @ n) * n)
    R = np.array([Rotation.from_rotvec(n * spin * t).as_matrix() @ R0 for t in tr.t])
    # measured 1.3e-15 .. 2.2e-15 m and 1.2e-15: round-off (the slide is integrated exactly
    # by every scheme, the spin by rattle6 to O(h^6) = 1e-18 here)
    assert np.abs(tr.position[:, 0] - X).max() < 1e-14
    assert np.abs(tr.rotation[:, 0] - R).max() < 1e-14
    assert tr.constraint_position.max() < 1e-15


def test_universal_joint_keeps_its_rows_and_energy():
    from scipy.spatial.transform import Rotation

    from director_model.system import Body, Joint, project_velocities

    R1 = Rotation.from_rotvec([0.3, 0.0, 0.0]).as_matrix()
    b = Body("u", 1.0, (0.1, 0.12, 0.05), position=R1 @ [0, 0, -0.5], rotation=R1,
             omega_body=(0.0, 2.0, 0.0))  # fmt: skip
    j = Joint("universal", "u", None, anchor_a=(0, 0, 0.5), anchor_b=(0, 0, 0),
              axis_a=(0, 1, 0), axis_b=(1, 0, 0))  # fmt: skip
    tr = simulate_system(project_velocities([b], [j]), [j], gravity=(0, 0, -9.81), dt=1e-3,
                         t_end=3.0, scheme="rattle4", save_every=100)  # fmt: skip
    assert tr.constraint_position.max() < 1e-15 and tr.constraint_velocity.max() < 1e-14
    assert np.ptp(tr.energy) < 1e-10  # measured 3.3e-12 J: bounded O(h^4)
