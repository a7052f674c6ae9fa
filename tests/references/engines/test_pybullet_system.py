"""The PyBullet builder for systems of bodies (references/engines/pybullet/system.py).

Expected values come from formulations that share nothing with PyBullet: the reduced-coordinate
reference (references/exact/multibody, DOP853 at rtol 1e-13), the planar pendulum of the
parallelogram four-bar (scipy DOP853 on one ODE) and the conservation of momentum. Bullet's
multibody stepper is first order, so the tolerances are orders (halving dt divides the error by
about 2, accepted within a factor 1.6; the stand-in systems and checks shared with the other
builders' tests: tests/references/engines/system_builders.py).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pybullet")

from director_model.system.examples import parallelogram_four_bar, rod_chain  # noqa: E402
from references.engines.pybullet import system as bs  # noqa: E402
from references.engines.system_conformance import scenario  # noqa: E402
from references.errors import EngineError, Unsupported  # noqa: E402
from tests.references.engines import system_builders as sb  # noqa: E402

MB = "multibody"


@pytest.mark.parametrize("system", sb.CHAINS, ids=sb.CHAIN_IDS)
def test_chains_agree_with_the_reduced_reference_at_first_order(system):
    """Measured (pybullet 3.2.7, dt 1 and 0.5 ms over 1 s): 1.21e-3 / 6.08e-4 m (spherical),
    1.13e-2 / 5.62e-3 m (hinge): order 1, the same errors as Pinocchio's and DART's
    semi-implicit Euler on these systems."""
    assert sb.assert_chain_order(bs, system, MB, 1e-3, 1) < 1e-2


def test_a_floating_chain_keeps_its_momentum_to_first_order():
    """A floating 5-body sb.chain (the base of its own multibody) in zero gravity."""
    sb.assert_momentum_order(bs, MB, 1e-3, 1)


def test_four_bar_closed_by_point_to_point_constraints():
    """Two JOINT_POINT2POINT on the closing hinge, dt = 1 ms over 2 s (four singular passages).
    Measured: at Bullet's default erp 0.2 the gap reaches 1.86e-6 m (4.7e-7 m at 0.5 ms) and
    the crank follows the pendulum to 8.0e-6 rad (the step's accuracy); at erp 0.9 the gap is
    a third of that; with erp 0 the loop drifts open (2.4e-3 m) and the mechanism leaves its branch
    (1.27 rad off the pendulum)."""
    bodies, joints, I_eff, k = parallelogram_four_bar()
    sc = scenario("four_bar", bodies, joints)
    out = bs.simulate_system(sc, MB, 1e-3, 2000, 50)
    gap, axis = sb.four_bar_gap(sc, out)
    assert gap.max() < 3e-6 and axis.max() < 1e-12
    assert sb.four_bar_theta_error(out, I_eff, k) < 1e-4
    half = bs.simulate_system(sc, MB, 5e-4, 4000, 100)
    assert sb.four_bar_gap(sc, half)[0].max() < gap.max() / 2
    s = out.settings
    assert "two JOINT_POINT2POINT" in s["loop closures"][0]
    assert [c["erp"] for c in s["constraints"]] == [bs.DEFAULT_ERP] * 2
    assert [c["maxAppliedForce (N)"] for c in s["constraints"]] == [bs.DEFAULT_MAX_FORCE] * 2
    stiff = bs.simulate_system(sc, MB, 1e-3, 2000, 50, erp=0.9)
    assert sb.four_bar_gap(sc, stiff)[0].max() < gap.max() / 2
    off = bs.simulate_system(sc, MB, 1e-3, 2000, 50, erp=0.0)
    assert sb.four_bar_gap(sc, off)[0].max() > 1e-3
    assert sb.four_bar_theta_error(off, I_eff, k) > 1.0


def test_default_erp_is_bullet_s(monkeypatch):
    """DEFAULT_ERP is Bullet's: a run whose global erp is left at Bullet's default equals the
    run at DEFAULT_ERP bit for bit (the global erp cannot be read back)."""
    sc = scenario("four_bar", *parallelogram_four_bar()[:2])
    out = bs.simulate_system(sc, MB, 1e-3, 300, 300)
    orig = bs._Model.add_loops

    def defaults(self, erp, max_force):
        p = self.p
        real = p.setPhysicsEngineParameter
        monkeypatch.setattr(p, "setPhysicsEngineParameter", lambda **kw: None)
        try:
            orig(self, erp, max_force)
        finally:
            monkeypatch.setattr(p, "setPhysicsEngineParameter", real)

    monkeypatch.setattr(bs._Model, "add_loops", defaults)
    assert np.array_equal(bs.simulate_system(sc, MB, 1e-3, 300, 300).x, out.x)


def test_a_loop_through_the_ground_is_the_hinge_it_makes():
    """A plate on two ground point-to-point constraints follows the reduced reference of the
    hinge at order 1; the anchors stay within 1e-4 m."""
    g1, e1 = sb.two_ball_hinge_errors(bs, MB, 1e-3)
    g2, e2 = sb.two_ball_hinge_errors(bs, MB, 5e-4)
    sb.assert_order(e1, e2, 1)
    assert max(g1, g2) < 1e-4 and e2 < 1e-2


# The planted joint mistakes of every builder: tests/references/engines/test_system_conformance.py.


@pytest.mark.parametrize("system", sb.CHAINS, ids=["spherical joints", "revolute joints"])
def test_default_motors_left_on_are_caught(monkeypatch, system):
    """PyBullet's default joint motors (never switched off) show in the probe step."""
    sc = sb.chain(system)
    monkeypatch.setattr(bs._Model, "motors_off", lambda self, *a: None)
    with pytest.raises(EngineError, match="joint motor, damping or the velocity clamp"):
        bs.simulate_system(sc, MB, 1e-3, 1, 1)


@pytest.mark.parametrize(
    "default",
    [
        {"angularDamping": 0.04, "linearDamping": 0.04},
        {"maxJointVelocity": 100.0},
        {"jointDamping": 0.01},
    ],  # fmt: skip
    ids=["damping", "velocity clamp", "joint damping"],
)
def test_planted_defaults_are_caught(monkeypatch, default):
    orig = bs._Model.motors_off

    def planted(self, mb, links, kinds):
        orig(self, mb, links, kinds)
        self.p.changeDynamics(mb, links[-1], **default, physicsClientId=self.cid)

    monkeypatch.setattr(bs._Model, "motors_off", planted)
    with pytest.raises(EngineError, match="velocity clamp|joint damping"):
        bs.simulate_system(scenario("s", *rod_chain(3, True, seed=1)), MB, 1e-3, 1, 1)


# -- prismatic joints (JOINT_PRISMATIC) ---------------------------------------------------------


def test_prismatic_joint_on_an_inclined_slide_follows_the_closed_form():
    """kit.inclined_slide: PyBullet's multibody step is semi-implicit Euler, off the closed
    form by exactly a h t / 2 (2.45e-3 m at t = 1 s, h = 1 ms); after that term the run is the
    closed form to round-off (measured 7.8e-15 m)."""
    from references.engines.system_conformance import inclined_slide

    b, j, _ = inclined_slide()
    sc = scenario("incline", b, j)
    out, e, e_known = sb.slide_errors(bs, sc, MB, 1e-3, 1000)
    assert e > 2e-3 and e_known < 1e-12
    assert out.settings["tree"] == {"s": "prismatic to ground"}


def test_prismatic_joint_in_a_chain_agrees_with_rattle6_at_order_1():
    """kit.slider against RATTLE6 at dt 2 and 1 ms: order 1 (measured 1.26e-2, 6.28e-3)."""
    e, _ = sb.slider_errors_vs_rattle6(bs, MB, (2e-3, 1e-3))
    sb.assert_order(e[0], e[1], 1)


@pytest.mark.parametrize("mistake", ["axis in the parent's frame", "offset along the axis lost"])
def test_planted_prismatic_mistakes_are_caught(monkeypatch, mistake):
    sb.assert_prismatic_mistake_caught(monkeypatch, bs, mistake, MB)


def test_unsupported_and_bad_arguments():
    sc = scenario("s", *rod_chain(2, True, seed=0))
    with pytest.raises(Unsupported, match="maximal coordinates"):
        bs.simulate_system(sc, "maximal coordinates", 1e-3, 1, 1)
    with pytest.raises(ValueError, match="unknown settings"):
        bs.simulate_system(sc, MB, 1e-3, 1, 1, baumgarte=(1, 1))
    with pytest.raises(ValueError, match="erp"):
        bs.simulate_system(sc, MB, 1e-3, 1, 1, erp=2.0)
    sb.assert_saved_steps(bs, sc, MB)
