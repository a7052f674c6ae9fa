"""Universal joints in the trees of the reduced-coordinate builders (issue 32, item 4):
Pinocchio's ``JointModelUniversal``, Drake's and DART's ``UniversalJoint``, and PyBullet's
composition of two hinges through a massless cross link (PyBullet has no universal joint).

The kit's universal chain (three links on universal joints with random perpendicular axis
pairs, random attitudes and rates; references.engines.system_conformance.universal_chain)
against the loop reference (references.exact.multibody.loops: the tree has no universal joint,
so each is four constraint rows, a formulation that shares nothing with the engines), and the
kit's three planted mistakes on joint ``h1`` each caught by name.
"""

from __future__ import annotations

import numpy as np
import pytest

from references.engines import system_conformance as kit
from references.engines.system import builder
from references.exact.multibody import solve
from references.exact.multibody.loops import system_from_world

#: (engine, integrator, bound on the largest position and rotation-entry error over 0.5 s at
#: dt = 1e-3): RKMK4 of order 4 (Pinocchio's and DART's, measured 6e-10), Drake's
#: error-controlled RK5 at its default accuracy stepped at 1e-3 (measured 5e-13)
CASES = [("pinocchio", "RKMK4", 1e-8), ("drake", "runge_kutta5", 1e-10), ("dart", "RKMK4", 1e-8)]


def _available(engine):
    from references.engines import get_engine

    why = get_engine(engine).broken
    if why:
        pytest.skip(f"{engine}: {why}")


@pytest.mark.parametrize("engine, integrator, bound", CASES)
def test_universal_chain_against_the_loop_reference(engine, integrator, bound):
    _available(engine)
    sc = kit.scenario("kit-universal3", *kit.universal_chain())
    out = builder(engine)(sc, integrator, 1e-3, 500, 50)
    system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity)
    assert sorted(system.closure_joints) == ["h0", "h1", "h2"]  # every universal a closure
    sol = solve(system.tree, q0, u0, out.t, estimate=False, system=system)
    order = [sol.names.index(b.name) for b in sc.bodies]
    assert np.max(np.abs(out.x - sol.x[:, order])) < bound
    assert np.max(np.abs(out.R - sol.R[:, order])) < bound


def test_pybullets_two_hinge_universal_converges_to_the_loop_reference_at_order_one():
    """PyBullet steps semi-implicit Euler (order 1): its errors against the loop reference
    halve with the step (measured 1.61e-2, 8.05e-3, 4.02e-3 m at dt 1e-3, 5e-4, 2.5e-4 over
    0.5 s; ratios 2.005, 2.003), so the motion it converges to is the universal joint's: a
    cross with mass, a swapped hinge order or a wrong axis would converge elsewhere."""
    _available("pybullet")
    sc = kit.scenario("kit-universal3", *kit.universal_chain())
    system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity)
    errs = []
    for dt, n in ((1e-3, 500), (5e-4, 1000)):
        out = builder("pybullet")(sc, "multibody", dt, n, n // 10)
        sol = solve(system.tree, q0, u0, out.t, estimate=False, system=system)
        order = [sol.names.index(b.name) for b in sc.bodies]
        errs.append(max(np.max(np.abs(out.x - sol.x[:, order])),
                        np.max(np.abs(out.R - sol.R[:, order]))))  # fmt: skip
    assert errs[1] < 2.5e-2
    assert abs(errs[0] / errs[1] - 2.0) < 0.1
    names = out.settings["universal joints"]
    assert len(names) == 3 and "'h1_cross' (mass 0, moments 0)" in names[1]


@pytest.mark.parametrize("engine", ["pinocchio", "drake", "dart", "pybullet"])
def test_planted_mistakes_on_a_universal_joint_are_caught(engine):
    _available(engine)
    sc = kit.scenario("kit-universal3", *kit.universal_chain())
    checks = kit.check_mistakes(engine, sc=sc)
    assert [c.name for c in checks if not c.ok] == [], [c for c in checks if not c.ok]
    assert len(checks) == 1 + len(kit.MISTAKES)


def test_a_cross_with_mass_is_refused_by_pybullets_read_back(monkeypatch):
    """PyBullet's two-hinge universal joint is the joint only while its cross has no mass: a
    cross of 0.1 kg (moments 0.1 kg m^2) handed to PyBullet is refused, the cross named."""
    from references.engines import reduced
    from references.errors import EngineError

    _available("pybullet")
    monkeypatch.setattr(reduced, "COMPOSED_MASS", 0.1)
    sc = kit.scenario("kit-universal3", *kit.universal_chain())
    with pytest.raises(EngineError, match=r"h1_cross: mass"):
        builder("pybullet")(sc, "multibody", 1e-3, 2, 1)
