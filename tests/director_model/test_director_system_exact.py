"""director_model.system against exact motions, measured orders, closed loops.

References (none from the integrator): rigid rotation plus free fall of a straight chain
(a relative equilibrium); the steady rotation of a double conical pendulum whose angles come
from the Newton-Euler balance of its links (Brent's method); the planar pendulum of a
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


def _conical_error(tr, exact) -> float:
    """Largest rotation-matrix entry (either link) or position (m) error of a run of the double
    conical pendulum against its steady rotation ``exact(t) -> (X, R)``."""
    err = 0.0
    for k, t in enumerate(tr.t):
        X, R = exact(t)
        err = max(err, max(np.abs(tr.rotation[k, i] - R[i]).max() for i in range(2)))
        err = max(err, np.abs(tr.position[k] - X).max())
    return err


@pytest.mark.parametrize("scheme, bound", [("rattle", 3e-5), ("rattle4", 6e-10),
                                           ("rattle6", 3e-13)])  # fmt: skip
def test_double_conical_pendulum_steady_rotation(scheme, bound):
    b, j, exact, th = double_conical_pendulum()
    assert 0.3 < th[0] < th[1] < 0.6  # the in-phase cone, outer link steeper
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=1e-3, t_end=2.0, scheme=scheme,
                         save_every=100)  # fmt: skip
    err = _conical_error(tr, exact)
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


def _four_bar_gaps(bodies, joints):
    """Largest anchor gap (m), axis misalignment |u_a x u_b|, relative velocity of the anchors
    (m/s) and relative angular velocity off the hinge axis (rad/s) over the joints, from the
    bodies' own fields (w = R W; ground: at rest)."""
    by = {b.name: b for b in bodies}

    def frame(name, anchor, axis):
        if name is None:
            return np.asarray(anchor, float), np.zeros(3), np.zeros(3), np.asarray(axis, float)
        b = by[name]
        R = np.asarray(b.rotation)
        r, w = R @ anchor, R @ b.omega_body
        return np.asarray(b.position) + r, np.asarray(b.velocity) + np.cross(w, r), w, R @ axis

    gap = mis = vgap = wgap = 0.0
    for j in joints:
        pa, va, wa, ua = frame(j.body_a, np.asarray(j.anchor_a, float), np.asarray(j.axis_a))
        pb, vb, wb, ub = frame(j.body_b, np.asarray(j.anchor_b, float), np.asarray(j.axis_b))
        ua, ub = ua / np.linalg.norm(ua), ub / np.linalg.norm(ub)
        gap = max(gap, np.abs(pa - pb).max())
        mis = max(mis, np.abs(np.cross(ua, ub)).max())
        vgap = max(vgap, np.abs(va - vb).max())
        wgap = max(wgap, np.abs(np.cross(wa - wb, ua)).max())
    return gap, mis, vgap, wgap


@pytest.mark.parametrize("theta0", [0.4, -1.1, np.pi / 2 - 1e-3, np.pi / 2, 2.5, -3.0])
def test_parallelogram_four_bar_any_initial_angle_is_on_the_joints(theta0):
    from scipy.spatial.transform import Rotation

    thd0 = 1.3
    b, j, _, _ = parallelogram_four_bar(theta0, thd0)
    crank, rocker, coupler = b
    # the pose follows from theta0: crank and rocker turned by theta0 about +y (rot_y), the
    # coupler translated; the crank's and rocker's pivots on the ground pivots
    R = Rotation.from_rotvec([0.0, theta0, 0.0]).as_matrix()
    assert np.abs(crank.rotation - R).max() < 1e-15 and np.abs(rocker.rotation - R).max() < 1e-15
    assert np.array_equal(coupler.rotation, np.eye(3))
    assert np.abs(crank.position + R @ [0, 0, 0.25]).max() < 1e-15  # pivot at the origin
    assert np.abs(rocker.position + R @ [0, 0, 0.25] - [1, 0, 0]).max() < 1e-15
    assert np.array_equal(crank.omega_body, (0, thd0, 0))
    # every joint holds, positions and velocities (round-off: ~1e-16 m on 1 m)
    gap, mis, vgap, wgap = _four_bar_gaps(b, j)
    assert max(gap, mis) < 1e-12 and max(vgap, wgap) < 1e-12


@pytest.mark.parametrize("theta0, bound", [(0.4, 1.5e-12), (-1.1, 5e-13),
                                           (np.pi / 2 - 1e-3, 4e-9), (2.5, 1e-13)])  # fmt: skip
def test_parallelogram_four_bar_from_any_angle_is_the_planar_pendulum(theta0, bound):
    # the planar pendulum written here from the bodies' data:
    # T = 1/2 (I_A + I_B + m_c L^2) theta'^2, V = -|g| cos(theta) (m_A L_A + m_B L_B + m_c L)
    # (I_A, I_B about the pivots: I_yy + m L_k^2 with L_k = 0.25 m pivot to COM; L = 0.5 m
    # pivot to tip), integrated by DOP853 at rtol 1e-13. (Exactly at the collinear
    # configuration theta0 = pi/2 the integrator's first step does not converge: the joint
    # Jacobian is singular at t = 0; only the state is checked there, above.)
    thd0, g, L, Lk = 1.3, 9.81, 0.5, 0.25
    b, j, _, _ = parallelogram_four_bar(theta0, thd0)
    crank, rocker, coupler = b
    I = crank.inertia[1] + crank.mass * Lk**2 + rocker.inertia[1] + rocker.mass * Lk**2
    I += coupler.mass * L**2
    k = crank.mass * Lk + rocker.mass * Lk + coupler.mass * L
    tr = simulate_system(b, j, gravity=(0, 0, -g), dt=2e-3, t_end=0.4, scheme="rattle6",
                         save_every=10)  # fmt: skip
    sol = solve_ivp(lambda _, y: (y[1], -g * k / I * np.sin(y[0])), (0, 0.4), (theta0, thd0),
                    method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True)  # fmt: skip
    th = np.unwrap(np.arctan2(tr.rotation[:, 0, 0, 2], tr.rotation[:, 0, 2, 2]))
    # measured 4.5e-13, 1.5e-13, 1.2e-9 (five minimum-norm steps at the collinear
    # configuration, crossed slowly), 3.3e-14 rad over 0.4 s
    assert np.abs(th - sol.sol(tr.t)[0]).max() < bound
    assert tr.constraint_position.max() < 1e-14 and tr.constraint_velocity.max() < 1e-12


def _reference_conical_angles(rate):
    """The angles of the independent closed form (augmented potential, Brent's method):
    references/exact/multibody/exact.py with the example's rods."""
    from references.exact.multibody.exact import DoubleConicalPendulum

    It = [m * L**2 / 12 + 0.005 for m, L in ((1.0, 1.0), (0.7, 0.8))]
    J = ((0.01, It[0], It[0]), (0.01, It[1], It[1]))
    return DoubleConicalPendulum((1.0, 0.7), J, (0.5, 0.4), 1.0, 9.81, rate).phi


@pytest.mark.parametrize("rate", [2.87, 3.0, 4.0, 5.0, -5.0, 8.0, 30.0])
def test_double_conical_pendulum_angles_are_the_in_phase_cone(rate):
    _, _, _, th = double_conical_pendulum(rate)
    assert 0.0 < th[0] < th[1] < np.pi / 2  # both links below the pivot, on one side
    # both solved to round-off by Brent's method on two formulations (Newton-Euler balance,
    # augmented potential): measured at most 2.2e-16 rad apart
    assert np.abs(th - _reference_conical_angles(abs(rate))).max() < 1e-14


@pytest.mark.parametrize("rate", [2.86, 1.0, 0.0, float("nan")])
def test_double_conical_pendulum_refuses_rates_without_the_cone(rate):
    # the lowest frequency of small swings: 2.86093 rad/s (the reference refuses 2.8609 and
    # solves 2.861)
    with pytest.raises(ValueError, match="lowest frequency of small swings, 2.8609|finite"):
        double_conical_pendulum(rate)


def test_double_conical_pendulum_at_5_rad_s_keeps_its_steady_rotation():
    b, j, exact, th = double_conical_pendulum(5.0)
    tr = simulate_system(b, j, gravity=(0, 0, -9.81), dt=1e-3, t_end=0.5, scheme="rattle6",
                         save_every=50)  # fmt: skip
    err = _conical_error(tr, exact)
    # measured 6.1e-16 over 0.5 s: round-off (at 3 rad/s the O(h^6) error was 8.7e-15 in 2 s)
    assert err < 5e-15
