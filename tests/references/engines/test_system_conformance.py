"""The system conformance kit (references/engines/system_conformance.py): each of the three
planted joint mistakes (an axis in the parent's frame, an anchor from the body origin, a
swapped parent and child) is caught by every builder of systems of bodies, with the specific
error its check gives. A builder whose engine is not installed is skipped with its reason.
"""

from __future__ import annotations

import importlib.util
import re

import pytest

from references.engines import system_conformance as kit
from references.errors import EngineError

#: the Python module each builder needs
NEEDS = {
    "director": "director_model",
    "mujoco": "mujoco",
    "mjx": "mujoco.mjx",
    "pinocchio": "pinocchio",
    "dart": "dartpy",
    "pybullet": "pybullet",
    "drake": "pydrake",
}

_INITIAL = r"kinematics of the initial state differ from the scenario.*"
#: the specific error of each builder for each mistake (the check that catches it)
EXPECTED = {
    "director": (
        r"refused the system: joint 'h1': the axes violate the joint at t = 0",
        r"refused the system: joint 'h1': the anchors do not coincide at t = 0: .* = 0\.5 m",
        r"refused the system: joint 'h1': the anchors do not coincide at t = 0",
    ),
    "mujoco": (
        r"compiled model differs .*'h1'.*jnt_axis \(the child's axis",
        r"compiled model differs .*'h1'.*jnt_pos \(the child's anchor",
        r"compiled model differs .*'h1'.*jnt_pos \(the child's anchor",
    ),
    "pinocchio": (
        _INITIAL + r"body 'link1': COM velocity",
        _INITIAL + r"body 'link1': COM position",
        r"model differs from the scenario: body 'link1' .*COM in the joint frame",
    ),
    "dart": (
        _INITIAL + r"body 'link1': COM velocity",
        _INITIAL + r"body 'link1': COM position",
        r"model differs from the scenario: body 'link1' .*local COM",
    ),
    "pybullet": (
        _INITIAL + r"body 'link1': COM velocity",
        _INITIAL + r"body 'link1': COM position",
        r"model differs from the scenario: body 'link1' .*inertial frame position",
    ),
    "drake": (
        _INITIAL + r"body 'link1': COM velocity",
        _INITIAL + r"body 'link1': COM position",
        _INITIAL + r"body 'link1': COM position",
    ),
}
EXPECTED["mjx"] = EXPECTED["mujoco"]  # MJX steps the C builder's checked model


def _need(engine):
    mod = NEEDS[engine]
    try:
        found = importlib.util.find_spec(mod) is not None
    except ModuleNotFoundError:
        found = False
    if not found:
        pytest.skip(f"{engine}: {mod} is not installed")


@pytest.mark.parametrize("mistake", kit.MISTAKES)
@pytest.mark.parametrize("engine", list(kit.PLANTS))
def test_planted_joint_mistake_is_caught(engine, mistake):
    _need(engine)
    with kit.planted(engine, mistake), pytest.raises(EngineError) as exc:
        kit.run(engine)
    pattern = EXPECTED[engine][kit.MISTAKES.index(mistake)]
    assert re.search(pattern, str(exc.value), flags=re.S), (pattern, str(exc.value))


@pytest.mark.parametrize("engine", [e for e in kit.PLANTS if e != "mjx"])
def test_the_kit_passes_every_builder_as_built(engine):
    """Every item of the kit on the true builder (the chain runs) and with each mistake
    (caught, naming the joint or its child body). MJX's as-built run compiles JAX steps
    (tests/references/engines/test_mjx_system.py runs MJX); its mistakes are caught before any
    compilation."""
    _need(engine)
    checks = kit.check_mistakes(engine)
    assert [c.name for c in checks] == ["runs as built"] + [f"catches {m}" for m in kit.MISTAKES]
    failed = [f"{c.name}: {c.message}" for c in checks if not c.ok]
    assert not failed, failed


def test_the_plant_is_restored_and_the_kit_reports_an_uncaught_mistake(monkeypatch):
    """The kit fails a builder that lets a mistake through: with the director's joint check
    switched off (its refusal becomes a silent run), the kit reports each mistake uncaught;
    and a plant never outlives its block."""
    from references.engines.director import system as director_system

    orig = director_system.model
    with kit.planted("director", kit.MISTAKES[0]):
        assert director_system.model is not orig
    assert director_system.model is orig

    def lenient(scenario, integrator, dt, nstep, save_every, **kw):
        return {"t": [0.0]}  # a builder with no check at all

    monkeypatch.setattr(director_system, "simulate_system", lenient)
    checks = kit.check_mistakes("director", baseline=False)
    assert [c.ok for c in checks] == [False, False, False]
    assert all("ran without complaint" in c.message for c in checks)
    with pytest.raises(AssertionError, match="catches axis in the parent's frame"):
        kit.assert_conforms("director", baseline=False)


def test_unknown_names_are_refused():
    with pytest.raises(ValueError, match="mistake 'typo' unknown"), kit.planted("mujoco", "typo"):
        pass
    with pytest.raises(ValueError, match="engine 'bullet' has no system plants"):
        with kit.planted("bullet", kit.MISTAKES[0]):
            pass
