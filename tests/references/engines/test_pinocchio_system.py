"""The Pinocchio builder for systems of bodies (references/engines/pinocchio/system.py).

Expected values come from formulations that share nothing with Pinocchio: the reduced-coordinate
reference (references/exact/multibody: its own recursive dynamics, DOP853 at rtol 1e-13, far
below every error judged here), the planar pendulum of the parallelogram four-bar (scipy DOP853
on one ODE) and the conservation of momentum. Tolerances come from the integrators' orders:
halving dt must divide the error by about 2^p (p = 1 for semi-implicit Euler, 4 for RKMK4),
accepted within a factor 1.6 of that (the error constants of a short run move a little with
dt). The stand-in systems and the solutions they are measured against are shared with the
other builders' tests: tests/references/engines/system_builders.py.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pinocchio")

from director_model.system.examples import parallelogram_four_bar, rod_chain  # noqa: E402
from references.engines import reduced  # noqa: E402
from references.engines import system_conformance as kit  # noqa: E402
from references.engines.pinocchio import system as ps  # noqa: E402
from references.engines.system_conformance import scenario  # noqa: E402
from references.errors import EngineError  # noqa: E402
from tests.references.engines import system_builders as sb  # noqa: E402

EULER, RK = "semi-implicit Euler", "RKMK4"


@pytest.mark.parametrize("system", sb.CHAINS, ids=sb.CHAIN_IDS)
@pytest.mark.parametrize("integrator, dt, p", [(EULER, 1e-3, 1), (RK, 1e-2, 4)])
def test_chains_agree_with_the_reduced_reference_at_the_integrators_order(system, integrator,
                                                                          dt, p):  # fmt: skip
    ex2 = sb.assert_chain_order(ps, system, integrator, dt, p)
    # measured (Pinocchio 4.1): Euler at 5e-4: 6e-4 m (spherical), 6e-3 m (hinge);
    # RKMK4 at 5e-3: 1e-8 m, 1.3e-7 m: the errors are small, not merely converging
    assert ex2 < (1e-2 if integrator == EULER else 1e-6)


@pytest.mark.parametrize("integrator, dt, p", [(EULER, 1e-3, 1), (RK, 1e-2, 4)])
def test_a_floating_chain_keeps_its_momentum_to_the_integrators_order(integrator, dt, p):
    """Zero gravity, no joint to the ground: linear and angular momentum are invariants of the
    exact motion; a reduced-coordinate integrator keeps them up to its truncation error, which
    must shrink at its order (RKMK4 at dt = 5e-3: 3e-7 of |P0| = 4.9 kg m/s)."""
    (dP, dL), P, L = sb.assert_momentum_order(ps, integrator, dt, p)
    if integrator == RK:
        assert dP < 1e-6 * np.abs(P[0]).max() + 1e-12
        assert dL < 1e-4 * np.abs(L[0]).max()


def test_four_bar_closed_by_constraint_dynamics_with_baumgarte():
    """The parallelogram four-bar (B1 closes the loop) over 2 s, through its singular
    configuration four times. The default Baumgarte gains are critical at omega = 10 x 7 rad/s
    (7 rad/s: the initial crank rate, the system's fastest rate at its length scale of 1 m), so
    Kp = 4900, Kd = 140, the same at every dt. RKMK4 at dt = 1e-3 keeps the gap at round-off
    (measured 3.1e-15 m) and follows the planar pendulum (1.7e-11 rad) at order 4 (2.9e-10 rad
    at 2e-3); with Pinocchio's default gains (0) the loop drifts open (2e-4 m) and the
    mechanism leaves the parallelogram branch at a singular passage."""
    bodies, joints, I_eff, k = parallelogram_four_bar()
    sc = scenario("four_bar", bodies, joints)
    out = ps.simulate_system(sc, RK, 1e-3, 2000, 50)
    gap, axis = sb.four_bar_gap(sc, out)
    assert gap.max() < 1e-12 and axis.max() < 1e-12
    e1 = sb.four_bar_theta_error(out, I_eff, k)
    assert e1 < 1e-9
    e2 = sb.four_bar_theta_error(ps.simulate_system(sc, RK, 2e-3, 1000, 25), I_eff, k)
    sb.assert_order(e2, e1, 4)
    s = out.settings
    assert s["Baumgarte (Kp, Kd)"] == pytest.approx([4900.0, 140.0], rel=1e-12)
    assert s["forward dynamics"] == "constraintDynamics"
    assert "two CONTACT_3D" in s["loop closures"][0]
    off = ps.simulate_system(sc, RK, 1e-3, 2000, 50, baumgarte=(0.0, 0.0))
    assert sb.four_bar_gap(sc, off)[0].max() > 1e-6
    assert sb.four_bar_theta_error(off, I_eff, k) > 1.0
    eul = ps.simulate_system(sc, EULER, 1e-3, 2000, 50)
    assert sb.four_bar_gap(sc, eul)[0].max() < 1e-12
    # semi-implicit Euler's positions are those of Stoermer-Verlet: second order in theta
    assert sb.four_bar_theta_error(eul, I_eff, k) < 1e-4


def test_a_loop_through_the_ground_is_the_hinge_it_makes():
    """RKMK4 with the closure's CONTACT_3D follows the reduced reference of the hinge at order
    4 (measured 9.3e-12 and 6.0e-13 m at dt 1 and 0.5 ms) with the anchors held to round-off."""
    g1, e1 = sb.two_ball_hinge_errors(ps, RK, 1e-3)
    g2, e2 = sb.two_ball_hinge_errors(ps, RK, 5e-4)
    sb.assert_order(e1, e2, 4)
    assert max(g1, g2) < 1e-12 and e2 < 1e-10


def test_joints_are_added_depth_first():
    """A breadth-first joint order (crank, rocker, coupler under the crank) makes Pinocchio's
    crba and constraintDynamics wrong silently (aba is not affected): the plan is depth first."""
    bodies, joints, _, _ = parallelogram_four_bar()
    sc = scenario("four_bar", bodies, joints)
    pl = reduced.plan(sc, "pinocchio")
    assert [pl.names[c] for c in pl.order] == ["crank", "coupler", "rocker"]


def test_a_breadth_first_joint_order_is_caught(monkeypatch):
    bodies, joints, _, _ = parallelogram_four_bar()
    orig = reduced.plan

    def breadth_first(*a, **k):
        pl = orig(*a, **k)
        pl.order = sorted(pl.order, key=lambda c: (pl.tree[c].parent >= 0, c))
        return pl

    monkeypatch.setattr(reduced, "plan", breadth_first)
    with pytest.raises(EngineError, match="joint 'crank_joint'.*not contiguous"):
        ps.simulate_system(scenario("four_bar", bodies, joints), RK, 1e-3, 1, 1)


# The planted joint mistakes (axis in the parent's frame, anchor from the body origin, parent
# and child swapped) of every builder: tests/references/engines/test_system_conformance.py.


# -- prismatic joints ------------------------------------------------------------------------


def test_prismatic_joint_on_an_inclined_slide_follows_the_closed_form():
    """A body on a 45-degree prismatic rail to the ground (kit.inclined_slide): the COM
    moves with the constant acceleration (g . n) n. RKMK4 integrates a constant acceleration
    exactly (measured 1.1e-15 m over 1 s); semi-implicit Euler's positions are
    q0 + n h v0 + a h^2 n (n + 1) / 2, off the closed form by exactly a h t / 2 (0.0245 m at
    t = 1 s, h = 0.01 s), which the run reproduces to round-off (measured 1.2e-15 m); the
    attitude stays R0 and the body does not turn. Bounds: 1e-13 m, a hundred ulps of 1 m."""
    b, j, _ = kit.inclined_slide()
    sc = scenario("incline", b, j)
    out, e_rk, _ = sb.slide_errors(ps, sc, RK, 1e-2, 100)
    assert e_rk < 1e-13
    assert out.settings["tree"] == {"s": "prismatic to ground"}
    _, e_eu, e_eu_known = sb.slide_errors(ps, sc, EULER, 1e-2, 100)
    assert e_eu > 0.02 and e_eu_known < 1e-13


def test_prismatic_joint_in_a_chain_agrees_with_rattle6_at_order_4():
    """The rod hinged to the ground with a collar sliding along it (kit.slider: the collar's
    principal axes permuted against the rod's): RKMK4 against director_model.system's
    RATTLE6 (dt 1 ms; its own error measured by halving dt: 9e-16) at dt 2 and 1 ms:
    order 4 within the factor 1.6 of :func:`sb.assert_order` (measured 4.0: 1.5e-11, 9.6e-13),
    and small (below 1e-11 at 1 ms)."""
    e, out = sb.slider_errors_vs_rattle6(ps, RK, (2e-3, 1e-3))
    sb.assert_order(e[0], e[1], 4)
    assert e[1] < 1e-11
    assert out.settings["tree"] == {"rod": "revolute to ground", "collar": "prismatic to 'rod'"}


@pytest.mark.parametrize("mistake", ["axis in the parent's frame", "offset along the axis lost"])
def test_planted_prismatic_mistakes_are_caught(monkeypatch, mistake):
    """The slide axis handed to Pinocchio in the rod's frame instead of the collar's, or the
    initial slide coordinate left at 0 (the collar starts 0.3 m from the rod's anchor along
    the axis): the kinematics of the initial state differ from the scenario, the body named."""
    sb.assert_prismatic_mistake_caught(monkeypatch, ps, mistake, RK)


def test_bad_arguments_are_named():
    sc = scenario("s", *rod_chain(2, True, seed=0))
    with pytest.raises(ValueError, match="integrator 'RK4' unknown"):
        ps.simulate_system(sc, "RK4", 1e-3, 1, 1)
    with pytest.raises(ValueError, match="unknown settings"):
        ps.simulate_system(sc, RK, 1e-3, 1, 1, solref=(0.02, 1))
    sb.assert_saved_steps(ps, sc, EULER)


@pytest.mark.parametrize("integrator", [EULER, RK])
def test_library_four_bar_runs_through_the_suite(integrator):
    """The library's four-bar file, loaded and run by the suite's system path
    (references.engines.system.run_system), comes back with every body and the loop held."""
    import scenarios
    from references.engines.system import run_system

    sc = scenarios.load("four_bar")
    out = run_system("pinocchio", sc, integrator, 2e-3, t_end=0.2, save_every=10)
    tr = out.trajectory
    assert tr.position.shape == (11, len(sc.bodies), 3)
    assert out.settings["forward dynamics"] == "constraintDynamics"
    assert np.all(np.isfinite(tr.position)) and out.engine_time_s > 0
