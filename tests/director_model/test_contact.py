"""director_model.contact against the closed forms of rigid frictional contact, its law
residuals and its refusals.

Expected values are the classical closed forms (Coulomb friction mu, Newton restitution e,
no rolling resistance; e.g. Pfeiffer and Glocker, *Multibody Dynamics with Unilateral
Contacts*, 1996), written out here, never read from the integrator. The tolerances:

- ROUND: the scheme's position update is exact for a constant acceleration (a kick-drift-kick
  step integrates a parabola without truncation error), so a body that sticks, slides or
  rolls at constant acceleration must match the closed form to round-off: 1e-12 m on
  displacements of order 1 m (a few thousand steps, each adding a few ulps of 1 m), and the
  contact impulses equal the exact ones to the solver's certified residual (RES_TOL = 256 eps
  of the impulse scale, director_model/contact/_solver.py) -> 1e-11 relative on forces.
- EVENT: a quantity measured through an event (an impact, the rolling onset) inside a step is
  first order in dt: the event time is resolved to one step (t* within dt), and a rebound
  height errs by at most the impact speed times dt (each test says why).

benchmarks/contact_closed_forms.py prints the errors of every case and their convergence in dt.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from director_model.contact import (
    Body,
    Box,
    Capsule,
    ContactScene,
    ContactStepper,
    Cylinder,
    InvalidContactError,
    Joint,
    Pair,
    Plane,
    Sphere,
    incline_frame,
    simulate_contact,
)
from director_model.contact import examples as ex

G = ex.G
EPS = np.finfo(float).eps
#: the contact solver's certified residual, relative to the impulse scale (see the docstring)
RES_TOL = 256 * EPS


def _run(scene, dt=1e-3, t_end=1.0, save_every=1):
    return simulate_contact(scene, dt=dt, t_end=t_end, save_every=save_every)


def _no_energy_gained(tr, scale):
    """Contact never adds energy: the work of each step's contact impulses <= round-off of
    the energy scale, and the energy (kinetic + gravity) never above its start."""
    assert tr.contact_work.max() <= 64 * EPS * scale
    assert tr.energy.max() <= tr.energy[0] + 64 * EPS * scale


# ---- exact stick ---------------------------------------------------------------------------


def test_block_below_friction_angle_does_not_move_in_10_s():
    # mu = 0.4, 15 deg: tan 15 deg = 0.268 <= 0.4, the block stays; normal force m g cos th
    th = math.radians(15.0)
    tr = _run(ex.block_on_incline(th, 0.4), dt=1e-3, t_end=10.0, save_every=100)
    disp = np.abs(tr.position[:, 0] - tr.position[0, 0]).max()
    assert disp < 1e-12, disp
    assert np.abs(tr.velocity).max() < 1e-12
    _, n = incline_frame(th)
    force = tr.pair_force[-1, 0]
    np.testing.assert_allclose(force, -G * np.array([0.0, 0.0, -1.0]), rtol=0, atol=1e-11 * G)
    assert abs(force @ n - G * math.cos(th)) <= 1e-11 * G
    assert tr.penetration.max() <= 1e-12 * 0.1
    assert tr.signorini.max() <= 1e-9 and tr.coulomb.max() <= 1e-9
    _no_energy_gained(tr, G * 0.1)


@pytest.mark.parametrize("direction", [0.0, math.pi / 4], ids=["axis", "diagonal"])
def test_push_below_mu_m_g_does_not_move(direction):
    # isotropic Coulomb: F = 0.95 mu m g holds in every direction (a pyramid would let the
    # diagonal push slide: it holds only mu m g / sqrt 2 there)
    mu = 0.5
    tr = _run(ex.pushed_box(0.95 * mu * G, direction, mu), dt=1e-3, t_end=10.0, save_every=100)
    disp = np.abs(tr.position[:, 0] - tr.position[0, 0]).max()
    assert disp < 1e-12, disp


# ---- sliding at constant acceleration ------------------------------------------------------


def test_block_above_friction_angle_slides_at_g_sin_minus_mu_cos():
    th = math.radians(30.0)
    mu = 0.4
    s, n = incline_frame(th)
    tr = _run(ex.block_on_incline(th, mu), dt=1e-3, t_end=1.0)
    a = G * (math.sin(th) - mu * math.cos(th))  # 1.5067 m/s^2
    d = (tr.position[:, 0] - tr.position[0, 0]) @ s
    np.testing.assert_allclose(d, 0.5 * a * tr.t**2, rtol=0, atol=1e-12)
    # it slides straight down the slope, on the plane
    off = (tr.position[:, 0] - tr.position[0, 0]) @ n
    assert np.abs(off).max() < 1e-12
    f = tr.pair_force[-1, 0]
    assert abs(f @ n - G * math.cos(th)) <= 1e-11 * G
    assert abs(f @ s + mu * G * math.cos(th)) <= 1e-11 * G
    _no_energy_gained(tr, G)


@pytest.mark.parametrize("direction", [0.0, math.pi / 4], ids=["axis", "diagonal"])
def test_push_above_mu_m_g_slides_along_the_force(direction):
    mu = 0.5
    F = 1.1 * mu * G
    tr = _run(ex.pushed_box(F, direction, mu), dt=1e-3, t_end=1.0)
    a = F - mu * G  # m = 1
    u = np.array([math.cos(direction), math.sin(direction), 0.0])
    dx = tr.position[:, 0] - tr.position[0, 0]
    np.testing.assert_allclose(dx @ u, 0.5 * a * tr.t**2, rtol=0, atol=1e-12)
    across = dx - np.outer(dx @ u, u)
    assert np.abs(across).max() < 1e-12


# ---- rolling -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("v0", "w0"), [(2.0, 5.0), (1.0, -40.0)], ids=["topspin", "backspin_returns"]
)
def test_sphere_slides_into_rolling(v0, w0):
    # solid sphere r = 0.1, mu = 0.2: t* = 2 (v0 - r w0) / (7 mu g), v* = (5 v0 + 2 r w0) / 7;
    # the backspin case (r w0 = -4 < -5 v0 / 2) comes back: v* < 0
    mu, r, m, dt = 0.2, 0.1, 1.0, 1e-3
    tstar = 2 * (v0 - r * w0) / (7 * mu * G)
    vstar = (5 * v0 + 2 * r * w0) / 7
    lost = 0.5 * m * v0**2 + 0.2 * m * r**2 * w0**2 - 0.7 * m * vstar**2
    T = dt * math.ceil((tstar + 0.5) / dt)
    tr = _run(ex.sphere_on_ground(v0, w0, mu, radius=r, mass=m), dt=dt, t_end=T)
    slip = tr.velocity[:, 0, 0] - r * tr.omega_body[:, 0, 1]
    rolling = np.abs(slip) <= 1e-12 * (abs(v0) + abs(r * w0))
    k = int(np.argmax(rolling))
    assert rolling[k:].all()  # once rolling, it rolls
    # the onset lies in the step ending at t[k] (the event is resolved to one step)
    assert tr.t[k] - dt <= tstar <= tr.t[k] + 1e-12
    # while sliding, v = v0 - mu g t exactly (constant friction mu m g); the momentum lost by
    # the end of the sliding phase fixes v* to the solver's residual
    np.testing.assert_allclose(tr.velocity[:k, 0, 0], v0 - mu * G * tr.t[:k], rtol=0, atol=1e-12)
    assert abs(tr.velocity[-1, 0, 0] - vstar) <= 1e-12 * abs(v0)
    assert abs(tr.velocity[k:, 0, 0] - vstar).max() <= 1e-12 * abs(v0)
    assert abs((tr.energy[0] - tr.energy[-1]) - lost) <= 1e-11 * lost
    _no_energy_gained(tr, 0.5 * m * v0**2 + 0.2 * m * r**2 * w0**2)


@pytest.mark.parametrize("kind", ["sphere", "cylinder"])
@pytest.mark.parametrize("side", [1.2, 0.8], ids=["rolls", "slides"])
def test_roller_on_incline_both_sides_of_the_threshold(kind, side):
    # I = k m r^2 (sphere 2/5, cylinder 1/2): rolls iff mu >= k tan th / (1 + k), then
    # a = g sin th / (1 + k); else a = g (sin th - mu cos th), spin rate mu g cos th / (k r)
    th = math.radians(30.0)
    k = 0.4 if kind == "sphere" else 0.5
    r = 0.1
    mu = side * k * math.tan(th) / (1 + k)
    s, _ = incline_frame(th)
    tr = _run(ex.roller_on_incline(kind, th, mu, radius=r), dt=1e-3, t_end=1.0)
    d = (tr.position[:, 0] - tr.position[0, 0]) @ s
    w = tr.rotation[:, 0] @ tr.omega_body[:, 0][..., None]  # world angular velocity
    wy = w[:, 1, 0]
    if side > 1:
        a = G * math.sin(th) / (1 + k)
        np.testing.assert_allclose(wy * r, a * tr.t, rtol=0, atol=1e-12)
    else:
        a = G * (math.sin(th) - mu * math.cos(th))
        np.testing.assert_allclose(wy, mu * G * math.cos(th) / (k * r) * tr.t, rtol=0, atol=1e-10)
    np.testing.assert_allclose(d, 0.5 * a * tr.t**2, rtol=0, atol=1e-12)


# ---- rest and stacks -----------------------------------------------------------------------


@pytest.mark.parametrize("n_boxes", [1, 3])
def test_resting_boxes_do_not_move_and_supports_carry_the_weight_above(n_boxes):
    tr = _run(ex.box_stack(n_boxes), dt=1e-3, t_end=2.0, save_every=50)
    disp = np.abs(tr.position - tr.position[0]).max()
    assert disp < 1e-12, disp
    # pair 0: the ground under box 0 (carries n_boxes m g), pair p: box p on box p - 1
    for p in range(n_boxes):
        np.testing.assert_allclose(
            tr.pair_force[1:, p], np.tile([0.0, 0.0, (n_boxes - p) * G], (len(tr.t) - 1, 1)),
            rtol=0, atol=1e-11 * n_boxes * G,
        )  # fmt: skip
    assert tr.penetration.max() <= 1e-12


# ---- impacts -------------------------------------------------------------------------------


def test_drop_with_e_zero_stays_down():
    h0, dt = 1.0, 1e-3
    tr = _run(ex.dropped_sphere(h0, 0.0), dt=dt, t_end=1.0)
    z = tr.position[:, 0, 2] - 0.1
    k = int(np.argmax(z <= 1e-12))
    assert k > 0 and tr.t[k] - dt <= math.sqrt(2 * h0 / G) <= tr.t[k]
    assert np.abs(z[k:]).max() <= 1e-12
    assert np.abs(tr.velocity[k:]).max() <= 1e-12
    _no_energy_gained(tr, G * h0)


def test_drop_with_e_half_rebounds_to_e_2n_h0():
    # rebound heights e^(2n) h0. The impact happens inside a step, so the ball's flight time
    # is shifted by up to dt and the restitution applies to the speed at the step's end:
    # the apex errs by O(g h dt) ~ |v| dt (first order, <= 2 v_impact dt here)
    h0, e, dt = 1.0, 0.5, 1e-4
    apex, _, tr = _bounce(h0, e, dt)
    v1 = math.sqrt(2 * G * h0)
    for j, a in enumerate(apex[:3], start=1):
        assert abs(a - e ** (2 * j) * h0) <= 2 * v1 * dt, (j, a)
    assert tr.penetration.max() <= 1e-12
    _no_energy_gained(tr, G * h0)


def _bounce(h0, e, dt, n=3):
    """Apex heights of the ball's lowest point after each impact: on each rising flight, the
    last saved state before the velocity turns, continued as a free parabola."""
    t_end = math.sqrt(2 * h0 / G) * (1 + 2 * sum(e**j for j in range(1, n + 1))) + 0.05
    tr = _run(ex.dropped_sphere(h0, e), dt=dt, t_end=dt * math.ceil(t_end / dt))
    z = tr.position[:, 0, 2] - 0.1
    vz = tr.velocity[:, 0, 2]
    turn = np.nonzero((vz[:-1] > 0.0) & (vz[1:] <= 0.0))[0]
    return [float(z[k] + vz[k] ** 2 / (2 * G)) for k in turn], z, tr


# ---- law residuals, energy -------------------------------------------------------------------


# ---- refusals ------------------------------------------------------------------------------


def _ball_scene(z=0.1, mu=0.5, e=0.0, shape=None):
    sph = shape or Sphere(0.1)
    return ContactScene(
        [Body("ball", 1.0, (0.004, 0.004, 0.004), position=(0, 0, z))], {"ball": sph},
        {"ground": Plane((0, 0, 1), 0.0)}, [Pair("ball", "ground", mu=mu, e=e)],
    )  # fmt: skip


def test_overlap_at_t0_is_refused_naming_the_pair_and_depth():
    with pytest.raises(InvalidContactError, match=r"'ball'-'ground'.*penetrates by 0\.01"):
        _ball_scene(z=0.09)


@pytest.mark.parametrize(("mu", "e", "rule"), [(-0.1, 0.0, "mu"), (0.5, 1.5, "e"),
                                               (0.5, -0.1, "e")])  # fmt: skip
def test_bad_coefficients_are_refused(mu, e, rule):
    with pytest.raises(InvalidContactError, match=rf"{rule} = "):
        _ball_scene(mu=mu, e=e)


@pytest.mark.parametrize("make", [lambda: Sphere(0.0), lambda: Box((0.1, -1.0, 0.1)),
                                  lambda: Capsule(float("nan"), 0.1)])  # fmt: skip
def test_degenerate_shapes_are_refused(make):
    with pytest.raises(InvalidContactError, match="must be finite and > 0"):
        make()


def test_pair_not_treated_exactly_is_refused_with_the_reason():
    cyl = Cylinder(0.1, 0.1)
    sph = Sphere(0.1)
    with pytest.raises(InvalidContactError, match="cylinder-sphere contact is not implemented"):
        ContactScene(
            [Body("c", 1.0, cyl.inertia(1.0), position=(0, 0, 0)),
             Body("s", 1.0, sph.inertia(1.0), position=(1, 0, 0))],
            {"c": cyl, "s": sph}, pairs=[Pair("c", "s")],
        )  # fmt: skip


# ---- tipping, spin, long runs --------------------------------------------------------------


def _tip_reference(t, th, w, h):
    """Angle turned about the downhill bottom edge: the edge's pendulum, with psi the angle of
    the centre of mass seen from the edge (from the normal towards uphill, psi(0) = atan(w/h))
    and I_edge = 4/3 m L^2 (a box about an edge, L = |G - edge|): psi'' = 3 g / (4 L)
    sin(psi - th); DOP853 at rtol 1e-12 (an independent integration, not the scheme)."""
    from scipy.integrate import solve_ivp

    L = math.hypot(w, h)
    psi0 = math.atan2(w, h)
    sol = solve_ivp(lambda _, y: (y[1], 3 * G / (4 * L) * math.sin(y[0] - th)),
                    (0.0, float(t[-1])), (psi0, 0.0), method="DOP853", rtol=1e-12, atol=1e-14,
                    t_eval=t)  # fmt: skip
    return psi0 - sol.y[0]


def test_tall_box_tips_about_its_edge_rather_than_sliding():
    # tan 30 deg = 0.577 > w/h = 1/3 (it tips) and < mu = 1 (it does not slide)
    th, w, h, dt = math.radians(30.0), 0.05, 0.15, 1e-3
    tr = _run(ex.block_on_incline(th, 1.0, half=(w, 0.05, h)), dt=dt, t_end=0.3)
    R = tr.rotation[:, 0]
    rel = np.einsum("kji,jl->kil", R, R[0])  # R_k^T R_0: rotation about y by minus the angle
    angle = -np.arctan2(rel[:, 0, 2] - rel[:, 2, 0], rel[:, 0, 0] + rel[:, 2, 2])
    ref = _tip_reference(tr.t, th, w, h)
    assert ref[-1] > 0.3  # it turned well over (rad)
    # second order (benchmarks/contact_closed_forms.py: the error at 0.3 s falls 4x per
    # halving of dt, 1.52e-6 rad at dt = 1e-3, also its largest over [0, 0.3] s): the bound
    # 5e-6 rad is 3x that; stick rows that hold only the contact points' linear rate (planted)
    # give 3.3e-5 rad and a pivot creeping 6e-6 m, and a wrong pivot, a slipping edge or a
    # wrong moment of inertia errs by > 1e-3 rad
    assert np.abs(angle - ref).max() <= 5e-6
    # the downhill bottom edge carries it, neither lifting nor slipping: to round-off (the
    # stick rows hold the displacement of the vertices over each step, rotation included)
    s, n = incline_frame(th)
    edge = tr.position[:, 0] + np.einsum("kij,j->ki", R, [w, 0.0, -h])
    assert np.abs((edge - edge[0]) @ n).max() <= 1e-12
    assert np.abs((edge - edge[0]) @ s).max() <= 1e-12
    assert tr.contact_work.max() <= 0.0 and tr.penetration.max() <= 1e-12


def test_frictionless_drop_keeps_its_spin():
    spin = (3.0, -2.0, 5.0)
    tr = _run(ex.dropped_sphere(0.5, 0.5, mu=0.0, spin=spin), dt=1e-3, t_end=1.0)
    assert np.abs(tr.omega_body[:, 0] - spin).max() <= 1e-13 * 5.0


def _tumbling_box():
    """A box thrown with spin onto the ground: it slides, tumbles, bounces (e = 0.3) and comes
    to rest on a face."""
    box = Box((0.1, 0.08, 0.05))
    body = Body("box", 1.0, box.inertia(1.0), position=(0.0, 0.0, 0.3), velocity=(2.0, 0.5, 0.0),
                omega_body=(3.0, 5.0, 1.0))  # fmt: skip
    return ContactScene([body], {"box": box}, {"ground": Plane((0.0, 0.0, 1.0), 0.0)},
                        [Pair("box", "ground", mu=0.5, e=0.3)], gravity=(0.0, 0.0, -G))  # fmt: skip


def _check_long_run(tr):
    # energy (kinetic + gravity) never above its start, nor rising between saves beyond the
    # round-off of the energy scale (m g z ~ 3 J); the work of the contact impulses <= 0
    scale = G * 0.3
    assert tr.energy.max() <= tr.energy[0] + 64 * EPS * scale
    assert tr.contact_work.max() <= 64 * EPS * scale
    # the law residuals at the solver's tolerance (dimensionless, see ContactTrajectory)
    assert tr.signorini.max() <= 1e-9 and tr.coulomb.max() <= 1e-9
    assert tr.dissipation.max() <= 1e-9
    assert tr.penetration.max() <= 1e-12
    # it comes to rest: no motion over the last saves
    assert np.abs(tr.velocity[-1]).max() <= 1e-12


def test_tumbling_box_1e5_steps_within_the_laws():
    # 100 s at dt = 1e-3 (about 4 s here): sliding, tumbling, bouncing, then at rest from
    # ~0.9 s on a face; measured: energy rise <= 8.9e-16 J, penetration 1.8e-15 m, Signorini
    # 1.5e-13, Coulomb 3.8e-11, dissipation 4.1e-13, contact work 0
    tr = _run(_tumbling_box(), dt=1e-3, t_end=100.0, save_every=100)
    _check_long_run(tr)
    disp = np.abs(tr.position[-1] - tr.position[len(tr.t) // 2]).max()
    assert disp <= 1e-12  # at rest for the second half: exact stick, no drift


def test_stepper_state_is_what_a_trajectory_saves_at_that_step():
    # ContactStepper.state() is the kernel's own store of the state: equal bit for bit to the
    # saved step of a trajectory (a tumbling box: a general rotation, spin about every axis)
    st = ContactStepper(_tumbling_box(), dt=1e-3)
    start = st.state()
    tr = st.advance(250, save_every=250, include_start=True)
    end = st.state()
    for k, name in enumerate(("position", "velocity", "rotation", "omega_body")):
        assert np.array_equal(start[k], getattr(tr, name)[0])
        assert np.array_equal(end[k], getattr(tr, name)[-1])
    R = end[2]
    assert abs(np.linalg.det(R[0]) - 1.0) <= 4 * EPS and st.time == 0.25


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_hinged_body_resting_on_the_ground_obeys_the_moment_balance(mu):
    # a sphere (r 0.1, 1 kg) hinged (revolute about y) to the ground at its centre's height,
    # 0.5 m from its centre, resting on the ground under its centre: no motion; the ground's
    # force (f_x, 0, N) at (0.5, 0, 0) and gravity at the centre balance about the hinge's
    # axis: 0.5 m g - 0.1 f_x - 0.5 N = 0, i.e. N + f_x / 5 = m g (f_x, shared with the
    # hinge, is statically indeterminate when mu > 0; without friction N = m g)
    sph = Sphere(0.1)
    ball = Body("ball", 1.0, sph.inertia(1.0), position=(0.5, 0.0, 0.1))
    hinge = Joint("revolute", "ball", None, anchor_a=(-0.5, 0.0, 0.0), anchor_b=(0.0, 0.0, 0.1),
                  axis_a=(0.0, 1.0, 0.0), axis_b=(0.0, 1.0, 0.0))  # fmt: skip
    scene = ContactScene([ball], {"ball": sph}, {"ground": Plane((0.0, 0.0, 1.0), 0.0)},
                         [Pair("ball", "ground", mu=mu)], joints=[hinge],
                         gravity=(0.0, 0.0, -G))  # fmt: skip
    tr = _run(scene, dt=1e-3, t_end=2.0, save_every=100)
    assert np.abs(tr.position - tr.position[0]).max() <= 1e-12
    f = tr.pair_force[1:, 0]
    np.testing.assert_allclose(f[:, 2] + f[:, 0] / 5, G, rtol=0, atol=1e-11 * G)
    assert np.abs(f[:, 1]).max() <= 1e-11 * G
    assert np.all(np.hypot(f[:, 0], f[:, 1]) <= mu * f[:, 2] + 1e-11 * G)  # inside the cone
    if mu == 0.0:
        np.testing.assert_allclose(f[:, 2], G, rtol=0, atol=1e-11 * G)
    assert tr.penetration.max() <= 1e-12
