"""The DART builder for systems of bodies (references/engines/dart/system.py).

Expected values come from formulations that share nothing with DART: the reduced-coordinate
reference (references/exact/multibody, DOP853 at rtol 1e-13), the planar pendulum of the
parallelogram four-bar (scipy DOP853 on one ODE) and the conservation of momentum. Tolerances
come from the integrators' orders (halving dt divides the error by about 2^p, accepted within a
factor 1.6; the stand-in systems and checks shared with the other builders' tests:
tests/references/engines/system_builders.py).
"""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("dartpy")

from director_model.system.examples import parallelogram_four_bar, rod_chain  # noqa: E402
from references.engines.dart import system as ds  # noqa: E402
from references.engines.system_conformance import hinge_chain, scenario  # noqa: E402
from references.errors import Diverged, EngineError, Unsupported  # noqa: E402
from tests.references.engines import system_builders as sb  # noqa: E402

EULER, RK = "semi-implicit Euler", "RKMK4"


@pytest.mark.parametrize("system", sb.CHAINS, ids=sb.CHAIN_IDS)
@pytest.mark.parametrize("integrator, dt, p", [(EULER, 1e-3, 1), (RK, 1e-2, 4)])
def test_chains_agree_with_the_reduced_reference_at_the_integrators_order(system, integrator,
                                                                          dt, p):  # fmt: skip
    ex2 = sb.assert_chain_order(ds, system, integrator, dt, p)
    # measured (DART 6.20): World.step at 5e-4: 6e-4 m (spherical), 6e-3 m (hinge);
    # RKMK4 at 5e-3: 1.2e-8 m, 1.3e-7 m
    assert ex2 < (1e-2 if integrator == EULER else 1e-6)


@pytest.mark.parametrize("integrator, dt, p", [(EULER, 1e-3, 1), (RK, 1e-2, 4)])
def test_a_floating_chain_keeps_its_momentum_to_the_integrators_order(integrator, dt, p):
    sb.assert_momentum_order(ds, integrator, dt, p)


def test_four_bar_closed_by_dart_joint_constraints():
    """World.step at dt = 1e-3 over 2 s (four singular passages). DART's RevoluteJointConstraint
    at its default ERP 0.01 keeps the gap at 1.4e-8 m (measured) and follows the pendulum to
    the accuracy of the step (9e-6 rad, the same as Pinocchio's semi-implicit Euler);
    a BallJointConstraint at the anchor (3 of the hinge's 5 equations, enough for this planar
    loop) keeps 6e-12 m. The RevoluteJointConstraint of this rank-deficient loop blows up at
    ERP 0.1, which DART hides by replacing non-finite values: the builder reports it."""
    bodies, joints, I_eff, k = parallelogram_four_bar()
    sc = scenario("four_bar", bodies, joints)
    out = ds.simulate_system(sc, EULER, 1e-3, 2000, 50)
    gap, axis = sb.four_bar_gap(sc, out)
    assert gap.max() < 1e-7 and axis.max() < 1e-12
    assert sb.four_bar_theta_error(out, I_eff, k) < 1e-4
    s = out.settings
    assert s["constraint solver"]["error reduction parameter (ERP)"] == ds.DEFAULT_ERP
    assert "RevoluteJointConstraint" in s["loop closures"][0]
    ball = ds.simulate_system(sc, EULER, 1e-3, 2000, 50, revolute_closure="ball")
    assert sb.four_bar_gap(sc, ball)[0].max() < 1e-10
    assert "BallJointConstraint at the anchor" in ball.settings["loop closures"][0]
    with pytest.raises(Diverged, match="non-finite"):
        ds.simulate_system(sc, EULER, 1e-3, 2000, 50, erp=0.1)
    with pytest.raises(Unsupported, match="World.step"):
        ds.simulate_system(sc, RK, 1e-3, 10, 1)


def test_a_loop_through_the_ground_is_the_hinge_it_makes():
    """World.step with a BallJointConstraint to the world follows the reduced reference of the
    hinge at order 1 (measured 3.9e-4 and 2.0e-4 m at dt 1 and 0.5 ms), anchors within 1.3e-12 m."""
    g1, e1 = sb.two_ball_hinge_errors(ds, EULER, 1e-3)
    g2, e2 = sb.two_ball_hinge_errors(ds, EULER, 5e-4)
    sb.assert_order(e1, e2, 1)
    assert max(g1, g2) < 1e-10 and e2 < 1e-3


def test_default_erp_is_dart_s():
    """The default recorded as DART's is DART's (read in a fresh process: the ERP is a global
    that the builder sets on every build)."""
    code = (
        "import dartpy; "
        "print(dartpy.constraint.DynamicJointConstraint.getErrorReductionParameter())"
    )
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert float(got.stdout.split()[-1]) == ds.DEFAULT_ERP


# The planted joint mistakes of every builder: tests/references/engines/test_system_conformance.py.


def test_planted_default_is_caught(monkeypatch):
    """Joint damping left on (a distorting default) is read back and named."""
    orig = ds._Model.__init__

    def damped(self, *a):
        orig(self, *a)
        self.joint[1].setDampingCoefficient(0, 0.01)

    monkeypatch.setattr(ds._Model, "__init__", damped)
    with pytest.raises(EngineError, match="body 'link1'.*joint damping"):
        ds.simulate_system(scenario("hinge4", *hinge_chain()), EULER, 1e-3, 1, 1)


# -- prismatic joints (DART's PrismaticJoint) --------------------------------------------------


def test_prismatic_joint_on_an_inclined_slide_follows_the_closed_form():
    """kit.inclined_slide as for Pinocchio (tests/references/engines/test_pinocchio_system.py):
    RKMK4 integrates
    the constant acceleration (g . n) n exactly (measured 1.1e-15 m over 1 s), semi-implicit
    Euler is off by exactly a h t / 2 (0.0245 m; after it, measured 1.2e-15 m)."""
    from references.engines.system_conformance import inclined_slide

    b, j, _ = inclined_slide()
    sc = scenario("incline", b, j)
    out, e_rk, _ = sb.slide_errors(ds, sc, RK, 1e-2, 100)
    assert e_rk < 1e-13
    assert out.settings["tree"] == {"s": "prismatic to ground"}
    _, e_eu, e_eu_known = sb.slide_errors(ds, sc, EULER, 1e-2, 100)
    assert e_eu > 0.02 and e_eu_known < 1e-13


def test_prismatic_joint_in_a_chain_agrees_with_rattle6_at_order_4():
    """kit.slider: RKMK4 against RATTLE6 at dt 2 and 1 ms, order 4 (measured 1.5e-11,
    9.6e-13: ratio 16.1) and below 1e-11 at 1 ms."""
    e, out = sb.slider_errors_vs_rattle6(ds, RK, (2e-3, 1e-3))
    sb.assert_order(e[0], e[1], 4)
    assert e[1] < 1e-11
    assert out.settings["tree"] == {"rod": "revolute to ground", "collar": "prismatic to 'rod'"}


@pytest.mark.parametrize("mistake", ["axis in the parent's frame", "offset along the axis lost"])
def test_planted_prismatic_mistakes_are_caught(monkeypatch, mistake):
    sb.assert_prismatic_mistake_caught(monkeypatch, ds, mistake, RK)


def test_unsupported_and_bad_arguments():
    sc = scenario("s", *rod_chain(2, True, seed=0))
    with pytest.raises(ValueError, match="unknown settings"):
        ds.simulate_system(sc, EULER, 1e-3, 1, 1, baumgarte=(1, 1))
    with pytest.raises(ValueError, match="erp"):
        ds.simulate_system(sc, EULER, 1e-3, 1, 1, erp=2.0)
    sb.assert_saved_steps(ds, sc, EULER)


def test_library_four_bar_runs_through_the_suite():
    """The library's four-bar file through the suite's system path: World.step runs it, the
    suite's RKMK4 is unsupported with the reason."""
    import scenarios
    from references.engines.system import run_system

    sc = scenarios.load("four_bar")
    out = run_system("dart", sc, EULER, 2e-3, t_end=0.2, save_every=10)
    assert out.trajectory.position.shape == (11, len(sc.bodies), 3)
    assert "constraint solver" in out.settings
    with pytest.raises(Unsupported, match="World.step"):
        run_system("dart", sc, RK, 2e-3, t_end=0.2, save_every=10)
