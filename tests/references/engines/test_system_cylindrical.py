"""Cylindrical joints in the trees of the reduced-coordinate builders (issue 32, item 4): none
of Pinocchio, DART, PyBullet and Drake has a cylindrical joint, and each builder writes the
composition its engine offers: Pinocchio a ``JointModelComposite`` (a prismatic and a revolute
on one axis), DART, PyBullet and Drake a prismatic joint to a massless sleeve (``<joint>_sleeve``)
and a revolute joint from it.

The system: the coverage table's cylindrical tree probe (references.engines.joint_coverage.
tree_probe: a link on a spherical joint to the ground, a second on a cylindrical joint to it,
random attitudes and axis, sliding at 0.4 m/s and turning at t = 0), against the loop reference
(references.exact.multibody.loops: the reduced tree has no cylindrical joint, so it is four
constraint rows there, a formulation that shares nothing with the engines); and the kit's
three planted mistakes on joint ``h1`` each caught by name.
"""

from __future__ import annotations

import numpy as np
import pytest

from references.engines import reduced
from references.engines import system_conformance as kit
from references.engines.joint_coverage import tree_probe
from references.engines.system import builder
from references.errors import EngineError, Unsupported
from references.exact.multibody import solve
from references.exact.multibody.loops import system_from_world

#: (engine, integrator, bound on the largest position and rotation-entry error over 0.5 s at
#: dt = 1e-3): RKMK4 of order 4 (Pinocchio's and DART's, measured 6.2e-12; MuJoCo's RK4 on its
#: own cylindrical joint gives the same 6.2e-12), Drake's RK5 (measured 4.7e-13)
CASES = [("pinocchio", "RKMK4", 1e-10), ("dart", "RKMK4", 1e-10),
         ("drake", "runge_kutta5", 1e-11)]  # fmt: skip
#: the first-order steppers (engine, integrator): measured errors 3.9e-3 and 1.95e-3 at dt 1e-3
#: and 5e-4 (Pinocchio, DART, PyBullet), 4.1e-3 and 2.1e-3 (Drake's SAP)
EULERS = [("pinocchio", "semi-implicit Euler"), ("dart", "semi-implicit Euler"),
          ("pybullet", "multibody"), ("drake", "discrete SAP")]  # fmt: skip
#: what each builder's settings record says the joint became (the massless link named)
RECORDS = {
    "pinocchio": "h1: JointModelComposite (PrismaticUnaligned, then RevoluteUnaligned",
    "dart": "through the massless body node 'h1_sleeve' (mass 0, moments 0",
    "pybullet": "through the massless link 'h1_sleeve' (mass 0, moments 0)",
    "drake": "through the massless body 'h1_sleeve' (SpatialInertia.Zero())",
}


def _available(engine):
    from references.engines import get_engine

    why = get_engine(engine).broken
    if why:
        pytest.skip(f"{engine}: {why}")


def _errors(engine, integrator, dt, t_end=0.5):
    """(largest position or rotation-entry error against the loop reference, the run)."""
    sc = kit.scenario("kit-cylindrical", *tree_probe("cylindrical"))
    n = round(t_end / dt)
    out = builder(engine)(sc, integrator, dt, n, n // 10)
    system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity)
    assert system.closure_joints == ["h1"]  # the cylindrical joint is a closure there
    sol = solve(system.tree, q0, u0, out.t, estimate=False, system=system)
    order = [sol.names.index(b.name) for b in sc.bodies]
    err = max(np.max(np.abs(out.x - sol.x[:, order])), np.max(np.abs(out.R - sol.R[:, order])))
    return float(err), out


@pytest.mark.parametrize("engine, integrator, bound", CASES)
def test_cylindrical_tree_against_the_loop_reference(engine, integrator, bound):
    _available(engine)
    err, out = _errors(engine, integrator, 1e-3)
    assert err < bound
    assert out.settings["tree"]["link1"] == "cylindrical to 'link0'"
    assert RECORDS[engine] in out.settings["cylindrical joints"][0]


@pytest.mark.parametrize("engine, integrator", EULERS)
def test_first_order_steppers_converge_to_the_cylindrical_motion(engine, integrator):
    """Each first-order stepper's error against the loop reference halves with the step, so
    the motion it converges to is the cylindrical joint's: a sleeve with mass, a wrong axis
    or a slide left out would converge elsewhere."""
    _available(engine)
    e1, _ = _errors(engine, integrator, 1e-3)
    e2, out = _errors(engine, integrator, 5e-4)
    assert e2 < 2.5e-3
    assert abs(e1 / e2 - 2.0) < 0.1, (e1, e2)
    if engine in RECORDS:
        assert RECORDS[engine] in out.settings["cylindrical joints"][0]


@pytest.mark.parametrize("engine", ["pinocchio", "dart", "pybullet", "drake"])
def test_planted_mistakes_on_a_cylindrical_joint_are_caught(engine):
    _available(engine)
    sc = kit.scenario("kit-cylindrical", *tree_probe("cylindrical"))
    checks = kit.check_mistakes(engine, sc=sc)
    assert [c for c in checks if not c.ok] == []
    assert len(checks) == 1 + len(kit.MISTAKES)


def test_a_tree_kind_a_builder_does_not_build_is_refused_with_its_reason():
    """reduced.plan, for a builder (or plug-in) without a kind: the joint named, the
    builder's reason and what it builds."""
    sc = kit.scenario("kit-cylindrical", *tree_probe("cylindrical"))
    with pytest.raises(
        Unsupported,
        match=r"eng: joint 'h1' \(cylindrical 'link0'-'link1'\): "
        r"a cylindrical joint in a tree: no such joint \(built: spherical",
    ):
        reduced.plan(sc, "eng", ("spherical",), tree_refused={"cylindrical": "no such joint"})


@pytest.mark.parametrize("engine", ["dart", "pybullet", "drake"])
def test_a_sleeve_with_mass_is_refused_by_the_read_back(monkeypatch, engine):
    """The composition is the cylindrical joint only while its sleeve has no mass: a sleeve
    of 0.1 kg (moments 0.1 kg m^2) handed to the engine is refused, the sleeve named."""
    _available(engine)
    monkeypatch.setattr(reduced, "COMPOSED_MASS", 0.1)
    sc = kit.scenario("kit-cylindrical", *tree_probe("cylindrical"))
    with pytest.raises(EngineError, match=r"h1_sleeve: mass"):
        builder(engine)(sc, kit.RUNS[engine][0], 1e-3, 2, 1)


@pytest.mark.parametrize("engine", ["dart", "pybullet", "drake"])
def test_a_body_named_as_the_sleeve_is_refused_naming_the_joint(engine):
    """The sleeve is named '<joint>_sleeve'; a scenario body of that name (which Drake would
    refuse deep inside AddRigidBody and DART rename) is refused before the engine is asked."""
    import dataclasses

    _available(engine)
    bodies, joints = tree_probe("cylindrical")
    bodies = [bodies[0], dataclasses.replace(bodies[1], name="h1_sleeve")]
    joints = [joints[0], dataclasses.replace(joints[1], body_b="h1_sleeve")]
    sc = kit.scenario("kit-cylindrical", bodies, joints)
    with pytest.raises(ValueError, match=r"joint 'h1' .*its massless sleeve is named 'h1_sleeve'"):
        builder(engine)(sc, kit.RUNS[engine][0], 1e-3, 2, 1)
