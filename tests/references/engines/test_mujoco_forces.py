"""MuJoCo's force elements (references/engines/mujoco/forces.py): springs as spatial tendons,
joint torques as qfrc_applied, against the reduced-coordinate reference (which shares nothing
with MuJoCo: references/exact/multibody/forces.py) and with planted mistakes that must show."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

import scenarios
from references.engines.exact.system import reference
from references.engines.mujoco import forces, mjcf
from references.engines.system import builder
from references.errors import EngineError, Unsupported
from references.exact.multibody import solve
from references.exact.multibody.loops import system_from_world
from scenarios.system_file import validate_system
from tests.references.exact.test_multibody_forces import arm_file

pytest.importorskip("mujoco")


def _arm_errors(c, integrator="RK4", dts=(1e-3, 5e-4)):
    sc = validate_system(arm_file(c, t_end=1.0))
    out = []
    for dt in dts:
        n = int(round(1.0 / dt))
        res = builder("mujoco")(sc, integrator, dt, n, n // 10)
        ref = reference(sc, res.t)
        out.append(max(np.abs(res.x - ref.trajectory.position).max(),
                       np.abs(res.R - ref.trajectory.rotation).max()))  # fmt: skip
    return out


@pytest.mark.parametrize("c", [0.0, 0.4])
def test_torques_and_a_spring_follow_the_reference_at_rk4s_order(c):
    """The spatial arm (a grounded torque, an internal torque on a tilted hinge, a
    spring-damper to a world point), 1 s: MuJoCo RK4 4.5e-10 / 2.8e-11 (c = 0) and 3.8e-10 /
    2.3e-11 (c = 0.4) at dt 1e-3 / 5e-4 (largest position or rotation-entry error, measured):
    order 4, so every element acts as the scenario says."""
    e1, e2 = _arm_errors(c)
    assert e1 < 2e-9
    assert 12 < e1 / e2 < 20  # measured 16.1 and 16.1


def test_eulers_damper_converges_at_order_one():
    """MuJoCo's Euler (damping implicit): 2.1e-3 and 1.06e-3 at dt 1e-3, 5e-4 (measured)."""
    e1, e2 = _arm_errors(0.4, "Euler")
    assert e1 < 5e-3 and abs(e1 / e2 - 2.0) < 0.1


@pytest.mark.parametrize("plant", ["torque sign", "spring on the other body", "no damping"])
def test_a_planted_mistake_shows(monkeypatch, plant):
    """Each is refused by the read-back or moves the arm off the reference by far more than
    RK4's 4.5e-10."""
    if plant == "torque sign":
        orig = forces.torque_forces
        monkeypatch.setattr(forces, "torque_forces", lambda *a: [
            (dof, -Q, s) for dof, Q, s in orig(*a)])  # fmt: skip
    elif plant == "spring on the other body":
        orig = mjcf.spring_parts

        def swapped(sc, pl):
            sites, tendons = orig(sc, pl)
            a = pl.names.index("rod")
            arm = pl.names.index("arm")
            sites[arm] = sites.pop(a)  # the rod's site put on the arm
            return sites, tendons

        monkeypatch.setattr(mjcf, "spring_parts", swapped)
    else:
        orig = mjcf.spring_parts
        monkeypatch.setattr(mjcf, "spring_parts", lambda sc, pl: (
            orig(sc, pl)[0], [t.replace('damping="0.4"', 'damping="0.0"')
                              for t in orig(sc, pl)[1]]))  # fmt: skip
    try:
        e1 = _arm_errors(0.4, dts=(1e-3,))[0]
    except EngineError as exc:
        assert "spring 'pull'" in str(exc)
        return
    assert e1 > 1e-4


def test_the_flyball_governor_follows_the_reference():
    """IFToMM A05 (stiff springs and dampers between the slider and the rods), 0.05 s: MuJoCo
    RK4 6.8e-13 m and 1.5e-13 (rotation entries) off the reference at dt 5e-5 and 2.5e-5
    alike, measured: the reference's own error (the director model's RATTLE6 agrees with it
    to the same 6.8e-13 m, tests/references/exact/test_iftomm_a05.py)."""
    sc = scenarios.load("iftomm_a05")
    system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity, sc.springs,
                                       sc.torques)  # fmt: skip
    res = builder("mujoco")(sc, "RK4", 5e-5, 1000, 100)
    sol = solve(system.tree, q0, u0, res.t, estimate=False, system=system)
    order = [sol.names.index(b.name) for b in sc.bodies]
    assert np.abs(res.x - sol.x[:, order]).max() < 1e-11
    assert np.abs(res.R - sol.R[:, order]).max() < 1e-11
    assert len(res.settings["force elements"]) == 2


def test_a_torque_on_a_loop_closure_is_unsupported_with_the_reason():
    """The four-bar with a torque on B1, the joint that closes its loop (an equality connect
    in MuJoCo, no degree of freedom to act on)."""
    data = tomllib.loads((scenarios.systems_path() / "four_bar.toml").read_text())
    data["torques"] = [{"joint": "B1", "torque": 0.1}]
    data["reference"] = {"kind": "auto"}  # the closed form knows no torque
    sc = validate_system(data)
    with pytest.raises(Unsupported, match="'B1': that joint closes a loop.*qfrc_applied"):
        builder("mujoco")(sc, "RK4", 1e-3, 10, 10)
