"""Force elements on the engines that apply them step by step (PyBullet, DART, Pinocchio,
Drake): the spatial arm with two joint torques and a spring-damper to a world point
(tests/references/exact/test_multibody_forces.py's arm_file) against the reduced-coordinate
reference (references/exact/multibody: it shares nothing with the engines), at two steps to
show each integrator's order, and planted mistakes (a spring 1 % too stiff, attached 1 cm off,
a torque of the wrong sign) that must show. The tolerances are the measured errors with a
margin; each plant moves the arm by far more than them."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios.force_elements as fe
from references.engines.exact.system import reference
from references.engines.system import builder, run_system
from scenarios.system_file import validate_system
from tests.references.exact.test_multibody_forces import arm_file


def _run(engine, integrator, sc, dt, t_end):
    n = int(round(t_end / dt))
    return builder(engine)(sc, integrator, dt, n, max(n // 10, 1))


def _err(engine, integrator, c=0.4, dt=1e-3, t_end=0.5, sc=None, extrapolate=False):
    """Largest position (m) or rotation-entry error of the arm against the reference; with
    ``extrapolate`` (an order-1 integrator), of 2 x(dt/2) - x(dt), which cancels the
    integrator's first-order error (Richardson) and leaves what the loads get wrong."""
    sc = sc or validate_system(arm_file(c, t_end=t_end))
    res = _run(engine, integrator, sc, dt, t_end)
    x, R = res.x, res.R
    if extrapolate:
        half = _run(engine, integrator, sc, dt / 2, t_end)
        x, R = 2 * half.x - x, 2 * half.R - R
    ref = reference(sc, res.t)
    return max(np.abs(x - ref.trajectory.position).max(),
               np.abs(R - ref.trajectory.rotation).max())  # fmt: skip


def _plant(monkeypatch, plant):
    """A mistake in the loads every engine applies (scenarios.force_elements.body_loads)."""
    orig = fe.body_loads

    def planted(scenario, x, R, v, W, index=None):
        if plant == "stiffness +1 %":
            s = scenario.springs[0]
            scenario = _with_spring(scenario, stiffness=s.stiffness * 1.01)
        elif plant == "anchor 1 cm off":
            s = scenario.springs[0]
            scenario = _with_spring(scenario, anchor_a=s.anchor_a + [0.01, 0.0, 0.0])
        F, T = orig(scenario, x, R, v, W, index)
        if plant == "torque sign":
            F2, T2 = orig(_no_torques(scenario), x, R, v, W, index)
            T = 2 * T2 - T  # every torque's couple reversed
        return F, T

    monkeypatch.setattr(fe, "body_loads", planted)


def _with_spring(scenario, **kw):
    import dataclasses

    s = dataclasses.replace(scenario.springs[0], **kw)
    return dataclasses.replace(scenario, springs=(s, *scenario.springs[1:]))


def _no_torques(scenario):
    import dataclasses

    return dataclasses.replace(scenario, torques=())


PLANTS = ("stiffness +1 %", "anchor 1 cm off", "torque sign")

# -- PyBullet --------------------------------------------------------------------------------


def test_pybullet_applies_the_arms_elements_at_eulers_order():
    """PyBullet's multibody semi-implicit Euler with the loads applied before each step,
    0.5 s: 1.85e-3 / 9.23e-4 at dt 1e-3 / 5e-4 (measured; order 1), and the Richardson
    combination of the two 6.5e-6: the first-order error cancels, so the loads are the
    elements'."""
    pytest.importorskip("pybullet")
    e1 = _err("pybullet", "multibody", dt=1e-3)
    e2 = _err("pybullet", "multibody", dt=5e-4)
    ex = _err("pybullet", "multibody", dt=1e-3, extrapolate=True)
    print("pybullet", e1, e2, ex)
    assert e1 < 5e-3
    assert 1.7 < e1 / e2 < 2.3
    assert ex < 3e-5


@pytest.mark.parametrize("plant", PLANTS)
def test_pybullet_a_planted_mistake_shows(monkeypatch, plant):
    """Each plant moves the extrapolated arm by more than 40x the measured 6.5e-6 (measured:
    3.5e-3 with the stiffness 1 % high, 1.1e-2 with the anchor 1 cm off, 0.17 with the torques
    reversed)."""
    pytest.importorskip("pybullet")
    _plant(monkeypatch, plant)
    bad = _err("pybullet", "multibody", dt=1e-3, extrapolate=True)
    print(plant, bad)
    assert bad > 3e-4


def test_pybullet_records_the_elements():
    pytest.importorskip("pybullet")
    sc = validate_system(arm_file(0.4, t_end=0.01))
    out = run_system("pybullet", sc, "multibody", 1e-3)
    assert len(out.settings["force elements"]) == 3


# -- DART ------------------------------------------------------------------------------------


def test_dart_rkmk4_applies_the_arms_elements_at_order_four():
    """The suite's RKMK4 around computeForwardDynamics with the loads set at every stage,
    0.5 s: 1.57e-10 / 9.8e-12 at dt 1e-3 / 5e-4 (measured; order 4)."""
    pytest.importorskip("dartpy")
    e1 = _err("dart", "RKMK4", dt=1e-3)
    e2 = _err("dart", "RKMK4", dt=5e-4)
    print("dart rkmk4", e1, e2)
    assert e1 < 1e-8
    assert 12 < e1 / e2 < 20


def test_dart_world_step_applies_the_arms_elements_at_eulers_order():
    """World.step with the loads set before each step, 0.5 s: 1.85e-3 / 9.23e-4 at dt 1e-3 /
    5e-4 (order 1), Richardson 6.5e-6 (measured; PyBullet's numbers to 1e-16: the same
    semi-implicit Euler with the loads of each step's start)."""
    pytest.importorskip("dartpy")
    e1 = _err("dart", "semi-implicit Euler", dt=1e-3)
    e2 = _err("dart", "semi-implicit Euler", dt=5e-4)
    ex = _err("dart", "semi-implicit Euler", dt=1e-3, extrapolate=True)
    print("dart euler", e1, e2, ex)
    assert e1 < 5e-3
    assert 1.7 < e1 / e2 < 2.3
    assert ex < 3e-5


@pytest.mark.parametrize("plant", PLANTS)
def test_dart_a_planted_mistake_shows(monkeypatch, plant):
    """Each plant moves RKMK4's arm by far more than its 1.6e-10 (measured: 3.5e-3, 1.1e-2,
    0.17)."""
    pytest.importorskip("dartpy")
    _plant(monkeypatch, plant)
    bad = _err("dart", "RKMK4", dt=1e-3)
    print(plant, bad)
    assert bad > 1e-4


def test_dart_reads_its_external_forces_back(monkeypatch):
    """Forces put at the body frame's origin (the joint point) instead of the centre of mass
    are refused before any step, naming the body."""
    pytest.importorskip("dartpy")
    from references.engines.dart import forces
    from references.errors import EngineError

    def at_the_joint(dm, scenario, states=None):
        x, R, v, W = dm.states() if states is None else states
        F, T = fe.body_loads(scenario, x, R, v, W)
        dm.skel.clearExternalForces()
        for c, body in dm.body.items():
            body.addExtForce(F[c], np.zeros(3), False, True)
            body.addExtTorque(T[c], False)
        return F, T

    monkeypatch.setattr(forces, "apply", at_the_joint)
    sc = validate_system(arm_file(0.4, t_end=0.01))
    with pytest.raises(EngineError, match="external forces differ: body 'rod'"):
        run_system("dart", sc, "RKMK4", 1e-3)


# -- Pinocchio -------------------------------------------------------------------------------


def test_pinocchio_rkmk4_applies_the_arms_elements_at_order_four():
    """The suite's RKMK4 on Pinocchio's group with the elements' generalised force at every
    stage, 0.5 s: 1.57e-10 / 9.8e-12 at dt 1e-3 / 5e-4 (measured; order 4; DART's RKMK4 gives
    the same digits)."""
    pytest.importorskip("pinocchio")
    e1 = _err("pinocchio", "RKMK4", dt=1e-3)
    e2 = _err("pinocchio", "RKMK4", dt=5e-4)
    print("pinocchio rkmk4", e1, e2)
    assert e1 < 1e-8
    assert 12 < e1 / e2 < 20


def test_pinocchio_euler_applies_the_arms_elements_at_order_one():
    """The suite's semi-implicit Euler around aba, 0.5 s: 1.85e-3 / 9.23e-4 (order 1),
    Richardson 6.5e-6 (measured)."""
    pytest.importorskip("pinocchio")
    e1 = _err("pinocchio", "semi-implicit Euler", dt=1e-3)
    e2 = _err("pinocchio", "semi-implicit Euler", dt=5e-4)
    ex = _err("pinocchio", "semi-implicit Euler", dt=1e-3, extrapolate=True)
    print("pinocchio euler", e1, e2, ex)
    assert e1 < 5e-3
    assert 1.7 < e1 / e2 < 2.3
    assert ex < 3e-5


@pytest.mark.parametrize("plant", PLANTS)
def test_pinocchio_a_planted_mistake_shows(monkeypatch, plant):
    """Each plant moves RKMK4's arm by far more than its 1.6e-10 (measured: 3.5e-3, 1.1e-2,
    0.17)."""
    pytest.importorskip("pinocchio")
    _plant(monkeypatch, plant)
    bad = _err("pinocchio", "RKMK4", dt=1e-3)
    print(plant, bad)
    assert bad > 1e-4


def test_pinocchio_checks_its_generalised_force_against_rnea(monkeypatch):
    """The Jacobians taken in the joints' LOCAL frame instead of WORLD (a frame mistake) are
    refused before any step by the comparison with rnea's fext."""
    pytest.importorskip("pinocchio")
    from references.engines.pinocchio import forces
    from references.errors import EngineError

    orig = forces.generalized

    def local(pm, q, v):
        world = pm.pin.ReferenceFrame.WORLD
        monkeypatch.setattr(pm.pin.ReferenceFrame, "WORLD", pm.pin.ReferenceFrame.LOCAL)
        try:
            return orig(pm, q, v)
        finally:
            monkeypatch.setattr(pm.pin.ReferenceFrame, "WORLD", world)

    monkeypatch.setattr(forces, "generalized", local)
    sc = validate_system(arm_file(0.4, t_end=0.01))
    with pytest.raises(EngineError, match="differs from Pinocchio's rnea with fext"):
        run_system("pinocchio", sc, "RKMK4", 1e-3)


# -- Drake -----------------------------------------------------------------------------------


def test_drake_applies_the_arms_elements_at_runge_kutta3s_order():
    """LinearSpringDamper and the applied generalised force, runge_kutta3 at fixed step,
    0.5 s: 8.7e-8 / 1.08e-8 at dt 1e-3 / 5e-4 (measured; order 3)."""
    pytest.importorskip("pydrake")
    e1 = _err("drake", "runge_kutta3", dt=1e-3)
    e2 = _err("drake", "runge_kutta3", dt=5e-4)
    print("drake rk3", e1, e2)
    assert e1 < 1e-6
    assert 6 < e1 / e2 < 10


@pytest.mark.parametrize("plant", ["stiffness +1 %", "anchor 1 cm off", "torque sign"])
def test_drake_a_planted_mistake_is_refused_by_the_read_back(monkeypatch, plant):
    """What Drake is handed (forces.spring_parameters, forces.torque_forces) planted wrong:
    the read-back refuses it before any step, naming the element."""
    pytest.importorskip("pydrake")
    from references.engines.drake import forces
    from references.errors import EngineError

    if plant == "torque sign":
        orig = forces.torque_forces
        monkeypatch.setattr(forces, "torque_forces", lambda *a: [
            (iv, -q, lab) for iv, q, lab in orig(*a)])  # fmt: skip
        words = "applied generalised force"
    else:
        orig = forces.spring_parameters

        def planted(scenario):
            a, P, b, Q, l0, k, c = orig(scenario)[0]
            if plant == "stiffness +1 %":
                k = 1.01 * k
            else:
                P = P + [0.01, 0.0, 0.0]
            return [(a, P, b, Q, l0, k, c)]

        monkeypatch.setattr(forces, "spring_parameters", planted)
        words = "spring 'pull': " + ("stiffness" if plant == "stiffness +1 %" else "p_AP")
    sc = validate_system(arm_file(0.4, t_end=0.01))
    with pytest.raises(EngineError, match=words):
        run_system("drake", sc, "runge_kutta3", 1e-3)


def test_drake_discrete_sap_applies_the_arms_elements_at_order_one():
    """The discrete SAP plant (the one that closes loops), 0.5 s: 1.85e-3 / 9.23e-4 at dt 1e-3
    / 5e-4 (measured; order 1; without contact or constraints SAP's step is the semi-implicit
    Euler step, the digits of PyBullet's, DART's and Pinocchio's)."""
    pytest.importorskip("pydrake")
    e1 = _err("drake", "discrete SAP", dt=1e-3)
    e2 = _err("drake", "discrete SAP", dt=5e-4)
    print("drake sap", e1, e2)
    assert e1 < 1e-2
    assert 1.7 < e1 / e2 < 2.3


# -- MJX -------------------------------------------------------------------------------------


def test_mjx_euler_applies_the_arms_elements_as_c_mujocos_euler():
    """MJX steps the C builder's model (springs as spatial tendons, torques in qfrc_applied):
    its Euler equals C MuJoCo's Euler on the arm to 5.6e-16 over 0.5 s at dt 1e-3 (measured;
    C's is tested against the reference in test_mujoco_forces.py) and is 1.85e-3 off the
    reference, the semi-implicit Euler's error of the other engines."""
    pytest.importorskip("mujoco.mjx")
    sc = validate_system(arm_file(0.4, t_end=0.5))
    a = _run("mjx", "Euler (float64)", sc, 1e-3, 0.5)
    c = _run("mujoco", "Euler", sc, 1e-3, 0.5)
    same = max(np.abs(a.x - c.x).max(), np.abs(a.R - c.R).max())
    ref = reference(sc, a.t)
    off = max(np.abs(a.x - ref.trajectory.position).max(),
              np.abs(a.R - ref.trajectory.rotation).max())  # fmt: skip
    print("mjx", same, off)
    assert same < 1e-12
    assert off < 5e-3
    assert len(a.settings["force elements"]) == 3


@pytest.mark.parametrize("plant", ["torques not handed over", "spring 1 % stiffer"])
def test_mjx_a_planted_mistake_is_refused_by_the_read_back(monkeypatch, plant):
    """What MJX holds is compared with the scenario, not with the C model: a C model or data
    changed after the C builder's own read-back is refused before any step."""
    pytest.importorskip("mujoco.mjx")
    from references.engines.mujoco import system as ms
    from references.errors import EngineError

    orig = ms.build

    def planted(*a, **k):
        mujoco, m, d, pl, bid, rec = orig(*a, **k)
        if plant == "torques not handed over":
            d.qfrc_applied[:] = 0.0
        else:
            m.tendon_stiffness[0] *= 1.01
        return mujoco, m, d, pl, bid, rec

    monkeypatch.setattr(ms, "build", planted)
    sc = validate_system(arm_file(0.4, t_end=0.01))
    words = "qfrc_applied" if plant == "torques not handed over" else "tendon_stiffness"
    with pytest.raises(EngineError, match=f"force elements MJX holds differ.*{words}"):
        run_system("mjx", sc, "Euler (float64)", 1e-3)


@pytest.mark.parametrize("engine, integrator", [("pinocchio", "RKMK4"), ("dart", "RKMK4")])
def test_the_read_back_accepts_springs_at_their_rest_length(engine, integrator):
    """IFToMM A05 starts with both springs at their rest length: loads of rounding size
    (~1e-10 N of k = 8e5 N/m), which the checks compare to the elements' load scale, not to
    themselves (they refused it before). 0.01 s against the reference: measured 7.9e-14 m
    (Pinocchio)."""
    pytest.importorskip({"dart": "dartpy"}.get(engine, engine))
    import scenarios

    sc = scenarios.load("iftomm_a05")
    res = _run(engine, integrator, sc, 2.5e-5, 0.01)
    ref = reference(sc, res.t)
    assert np.abs(res.x - ref.trajectory.position).max() < 1e-11
