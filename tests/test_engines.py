"""Engine adapters (MuJoCo, Pinocchio, DART, PyBullet), tests generated from the registry.

Layers: the initial state read back (non-identity R0, generic W), frame mistakes caught by the
adapters' own checks, the traps of docs/engines.md neutralised, exact-solution oracles, the
declared order of every integrator, order 4 against the numerics.md section 5 test vector,
agreement between engines where the algorithm is the same, failures reported as statuses.

A missing engine is skipped with the reason its adapter gives (never faked).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import scenarios
from references import conventions as cv
from references.engines import (
    FAMILIES,
    EngineError,
    EngineUnavailable,
    Unsupported,
    engine_names,
    get_engine,
)
from scenarios.model import Scenario

#: the third-party engines' adapters (the suite's own "director" and "exact" are tested with
#: their packages); every one must be in the registry
ENGINES = ("mujoco", "pinocchio", "dart", "pybullet")


def engine_or_skip(name):
    cls = get_engine(name)
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine {name!r} is not available here: {why}")
    return cls()


def pairs(families=None):
    """(engine, integrator) for every registered integrator, optionally of some families.
    The adapters' class attributes are readable without the engines installed."""
    out = []
    for e in ENGINES:
        for integ in get_engine(e).integrators:
            if families is None or integ.family in families:
                out.append(pytest.param(e, integ.name, id=f"{e}-{integ.name}"))
    return out


FOURTH_ORDER = {"4th-order Lie-group"}

# -- scenarios: non-identity R0, generic W, generic gravity ---------------------------------
R_GEN = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()
G_GEN = np.array([0.3, -0.2, -9.81])


def free_body(**kw):
    d = dict(
        name="free generic",
        description="free body, generic state",
        mass=1.5,
        inertia=[2.0, 3.0, 4.0],
        rotation=R_GEN,
        omega_body=[0.4, -1.3, 2.1],
        position=[0.1, 0.2, -0.3],
        velocity=[1.0, -2.0, 0.5],
        gravity=G_GEN,
        t_end=1.0,
        dt=1e-3,
    )
    d.update(kw)
    return Scenario(**d)


def tilted_top(**kw):
    d = dict(
        name="tilted top",
        description="symmetric heavy top, COM 0.5 m above the pivot on the symmetry axis",
        mass=1.0,
        inertia=[4.75, 4.75, 1.0],
        rotation=Rotation.from_rotvec([0.3, 0.1, 0.0]).as_matrix(),
        omega_body=[0.1, 0.2, 30.0],
        gravity=[0.0, 0.0, -9.81],
        pivot=[0.0, 0.0, -0.5],
        t_end=1.0,
        dt=1e-3,
    )
    d.update(kw)
    return Scenario(**d)


def pivoted_generic(**kw):
    d = dict(
        name="pivoted generic",
        description="asymmetric body on a pivot off every principal axis",
        mass=1.5,
        inertia=[2.0, 3.0, 4.0],
        rotation=R_GEN,
        omega_body=[0.4, -1.3, 2.1],
        gravity=G_GEN,
        pivot=[0.05, -0.1, 0.3],
        t_end=1.0,
        dt=1e-3,
    )
    d.update(kw)
    return Scenario(**d)


SCENARIOS = {
    "free": free_body,
    "top": tilted_top,
    "pivoted": pivoted_generic,
    # decimal numbers that engines store through arithmetic (0.9 reads back 1 ulp off)
    "free decimals": lambda: free_body(mass=0.7, inertia=[0.9, 1.4, 2.0]),
}


def run(engine, integrator, scenario, dt, t_end=None, save_every=None):
    t_end = scenario.t_end if t_end is None else t_end
    if save_every is None:
        save_every = int(round(t_end / dt))
    return engine.run(scenario, integrator, dt, t_end=t_end, save_every=save_every)


def hand_energy_momentum(sc):
    """E and L of the scenario's initial state, written out independently of the suite:
    E = 1/2 m |v|^2 + 1/2 sum I_i W_i^2 - m g . x, L = R (I W) (+ x x m v about the pivot)."""
    R, W, I, m = sc.rotation, np.asarray(sc.omega_body), np.asarray(sc.inertia), sc.mass
    if sc.pivot is not None:
        c = np.asarray(sc.pivot)
        x = -R @ c
        v = np.cross(R @ W, x)  # v_G = w x x_G for a point of the body relative to the pivot
    else:
        x, v = np.asarray(sc.position), np.asarray(sc.velocity)
    E = 0.5 * m * v @ v + 0.5 * np.sum(I * W * W) - m * np.asarray(sc.gravity) @ x
    L = R @ (I * W)
    if sc.pivot is not None:
        L = L + m * np.cross(x, v)
    return x, v, E, L


# == interface ===============================================================================
def test_engines_are_registered():
    assert set(ENGINES) <= set(engine_names())
    for name in ENGINES:
        assert get_engine(name).name == name


@pytest.mark.parametrize("name", ENGINES)
def test_version_and_integrators_are_documented(name):
    engine = engine_or_skip(name)
    assert isinstance(engine.version(), str) and engine.version()
    assert engine.integrators, f"{name} offers no integrator"
    for integ in engine.integrators:
        assert integ.family in FAMILIES
        assert integ.order == (4 if integ.family in FOURTH_ORDER else 1)
        assert len(integ.description) > 60, f"{name} {integ.name}: describe what it is"


# == initial state: read back from the engine before the first step ========================
@pytest.mark.parametrize("kind", list(SCENARIOS))
@pytest.mark.parametrize("name,integrator", pairs())
def test_initial_state_read_back(name, integrator, kind):
    engine = engine_or_skip(name)
    sc = SCENARIOS[kind]()
    dt = 1e-3
    if name == "pybullet" and integrator == "maximal coordinates" and sc.pivoted:
        with pytest.raises(Unsupported, match="pivoted"):
            engine.run(sc, integrator, dt, t_end=dt)
        return
    out = engine.run(sc, integrator, dt, t_end=dt, save_every=1)
    tr = out.trajectory
    x, v, E, L = hand_energy_momentum(sc)
    # 1e-12 relative: the brief's bound; conversions cost a few ulp (measured <= 1e-15)
    assert abs(tr.energy[0] - E) <= 1e-12 * abs(E)
    assert np.linalg.norm(tr.angular_momentum[0] - L) <= 1e-12 * np.linalg.norm(L)
    # the state itself, to a few ulp of O(1) numbers (quaternion / rotation-vector round trip)
    assert np.allclose(tr.rotation[0], sc.rotation, rtol=0, atol=1e-15 * 4)
    assert np.allclose(tr.omega_body[0], sc.omega_body, rtol=0, atol=1e-14)
    assert np.allclose(tr.position[0], x, rtol=0, atol=1e-15 * 4)
    assert np.allclose(tr.velocity[0], v, rtol=0, atol=1e-14)
    assert tr.t[0] == 0.0 and tr.t[1] == dt and out.nstep == 1
    # settings are recorded: gravity and the time step at least
    s = out.settings
    assert s["gravity"] == list(sc.gravity)
    assert s["timestep"] == dt
    assert s["integrator"] == integrator


def _swap_rates(orig_from, orig_to):
    """A consistent frame mistake: the from-conversion puts R W where W belongs and the
    to-conversion undoes it, so the round trip alone cannot see it."""

    def bad_from(*args):
        *head, R, W = args
        return orig_from(*head, R, np.asarray(R) @ np.asarray(W))

    def bad_to(*args):
        st = orig_to(*args)
        if isinstance(st, cv.BodyState):
            return st._replace(omega_body=st.rotation.T @ st.omega_body)
        R, W = st
        return R, R.T @ W

    return bad_from, bad_to


FRAME_MISTAKES = {
    # engine: (scenario kind, conversion pair whose angular rates get the wrong frame)
    "mujoco": ("free", "mujoco_free_from_state", "mujoco_free_to_state"),
    "pinocchio": ("free", "pinocchio_freeflyer_from_state", "pinocchio_freeflyer_to_state"),
    "dart": ("pivoted", "dart_ball_from_state", "dart_ball_to_state"),
    "pybullet": ("pivoted", "pybullet_spherical_from_state", "pybullet_spherical_to_state"),
}


@pytest.mark.parametrize("name", ENGINES)
def test_adapter_catches_a_consistent_frame_mistake(name, monkeypatch):
    engine = engine_or_skip(name)
    kind, f_from, f_to = FRAME_MISTAKES[name]
    bad_from, bad_to = _swap_rates(getattr(cv, f_from), getattr(cv, f_to))
    monkeypatch.setattr(cv, f_from, bad_from)
    monkeypatch.setattr(cv, f_to, bad_to)
    integrator = engine.integrators[0].name
    with pytest.raises(EngineError, match="engine's own"):
        engine.run(SCENARIOS[kind](), integrator, 1e-3, t_end=1e-3)


def test_pinocchio_catches_a_world_frame_linear_velocity(monkeypatch):
    # The FreeFlyer linear velocity is LOCAL. Passing v_G (world) and reading it back the
    # same way keeps |v| and hence E and L: only Pinocchio's own COM velocity can catch it.
    engine = engine_or_skip("pinocchio")
    orig_from, orig_to = cv.pinocchio_freeflyer_from_state, cv.pinocchio_freeflyer_to_state

    def bad_from(x, v, R, W):
        q, vel = orig_from(x, v, R, W)
        vel[:3] = v
        return q, vel

    def bad_to(q, v):
        return orig_to(q, v)._replace(velocity=np.array(v[:3]))

    monkeypatch.setattr(cv, "pinocchio_freeflyer_from_state", bad_from)
    monkeypatch.setattr(cv, "pinocchio_freeflyer_to_state", bad_to)
    with pytest.raises(EngineError, match="engine's own COM velocity"):
        engine.run(free_body(), "semi-implicit Euler", 1e-3, t_end=1e-3)


# == model read-back: a model that differs from the scenario is refused =====================
def _readback_mujoco(sc, other):
    engine = MUJOCO_CLS()
    mujoco, m, _ = engine._build(sc, "Euler", 1e-3)
    engine._check_model(mujoco, m, other, "Euler", 1e-3)


def _readback_pinocchio(sc, other):
    engine = get_engine("pinocchio")()
    pin, model, _ = engine._build(sc)
    engine._check_model(pin, model, other, np.zeros(3))


def _readback_dart(sc, other):
    engine = get_engine("dart")()
    world, skel, joint, body, _ = engine._build(sc, 1e-3)
    engine._check_model(world, skel, joint, body, other, np.zeros(3), 1e-3)


def _readback_pybullet(sc, other):
    import pybullet as p

    engine = get_engine("pybullet")()
    cid = p.connect(p.DIRECT)
    try:
        body, link, _ = engine._build(p, cid, sc, "multibody", 1e-3)
        engine._check_model(p, cid, body, link, other, False, 1e-3)
    finally:
        p.disconnect(physicsClientId=cid)


MUJOCO_CLS = get_engine("mujoco")
READBACK = {
    "mujoco": _readback_mujoco,
    "pinocchio": _readback_pinocchio,
    "dart": _readback_dart,
    "pybullet": _readback_pybullet,
}


@pytest.mark.parametrize("name", ENGINES)
def test_model_read_back_names_a_wrong_quantity(name):
    engine_or_skip(name)
    sc = free_body()
    READBACK[name](sc, sc)  # the model built from a scenario matches it
    with pytest.raises(EngineError, match="inertia"):
        READBACK[name](sc, free_body(inertia=[2.0, 3.0, 4.5]))
    with pytest.raises(EngineError, match="mass"):
        READBACK[name](sc, free_body(mass=1.25))
    with pytest.raises(EngineError, match="gravity"):
        READBACK[name](sc, free_body(gravity=[0.0, 0.0, -9.80665]))


# == traps of docs/engines.md ==============================================================
def _energy_ratio(tr):
    return tr.energy[-1] / tr.energy[0]


def test_pybullet_default_damping_is_neutralised():
    engine = engine_or_skip("pybullet")
    import pybullet as p

    W0 = np.array([0.4, 2.0, 0.3])
    sc = free_body(omega_body=W0, velocity=[0, 0, 0], gravity=[0, 0, 0], t_end=2.0)
    # PyBullet's default law w' = -0.04 (1 + |w|) w (docs/engines.md) removes rotational
    # energy at the rate 2 * 0.04 (1 + |w|): about 39 % over 2 s for |w| = 2.06.
    damped = math.exp(-2 * 0.04 * (1 + np.linalg.norm(W0)) * sc.t_end)
    assert damped < 0.65
    for integrator in ("multibody", "maximal coordinates"):
        tr = run(engine, integrator, sc, 1e-3).trajectory
        # 1e-4: five times the energy error of the (semi-)implicit Euler algorithm itself on
        # this run (1.9e-5, the same for MuJoCo Euler); damping would lose 0.39
        assert abs(_energy_ratio(tr) - 1) < 1e-4, integrator

    # the trap is real in this PyBullet: same body, inertia set, damping left at its default
    cid = p.connect(p.DIRECT)
    try:
        b = p.createMultiBody(baseMass=1.5, physicsClientId=cid)
        p.changeDynamics(b, -1, localInertiaDiagonal=[2.0, 3.0, 4.0], physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=1e-3, numSubSteps=0, physicsClientId=cid)
        p.resetBaseVelocity(b, [0, 0, 0], (R_GEN @ W0).tolist(), physicsClientId=cid)
        for _ in range(2000):
            p.stepSimulation(physicsClientId=cid)
        w = np.array(p.getBaseVelocity(b, physicsClientId=cid)[1])
    finally:
        p.disconnect(physicsClientId=cid)
    # the law d|w|/dt = -0.04 (1 + |w|) |w| gives |w|/|w0| = e/(1 + |w0| (1 - e)),
    # e = exp(-0.04 t): 0.80 after 2 s (measured 0.82: |w| of an asymmetric body also varies
    # without damping, by 1e-2 here, while the energy is kept to 1e-4 above)
    e = math.exp(-0.04 * sc.t_end)
    u0 = np.linalg.norm(W0)
    assert np.linalg.norm(w) / u0 == pytest.approx(e / (1 + u0 * (1 - e)), abs=0.05)


def test_pybullet_velocity_clamp_is_raised():
    engine = engine_or_skip("pybullet")
    # steady spin about the principal axis of largest moment: W x I W = 0, so every
    # integrator keeps W exactly (round-off only); the default clamp would cut it to 100
    sc = free_body(omega_body=[0.0, 0.0, 150.0], velocity=[0, 0, 0], gravity=[0, 0, 0])
    for integrator in ("multibody", "maximal coordinates"):
        tr = run(engine, integrator, sc, 1e-3, t_end=0.05).trajectory
        # 1e-12 relative: round-off of 50 steps
        assert np.allclose(tr.omega_body[-1], [0, 0, 150.0], rtol=0, atol=150 * 1e-12)


def test_pybullet_spherical_motor_is_off_and_its_default_is_real():
    engine = engine_or_skip("pybullet")
    import pybullet as p

    # steady spin of a pivoted body about its (principal) pivot axis, no gravity: exact
    # solution R(t) = R0 exp(t hat W), W constant; a motor pulling to identity breaks it
    sc = pivoted_generic(omega_body=[0.0, 0.0, 5.0], pivot=[0, 0, -0.5], gravity=[0, 0, 0])
    tr = run(engine, "multibody", sc, 1e-3).trajectory
    R_exact = sc.rotation @ Rotation.from_rotvec([0, 0, 5.0 * sc.t_end]).as_matrix()
    # 1e-12: round-off of 1000 steps (measured 1.4e-15)
    assert np.allclose(tr.rotation[-1], R_exact, rtol=0, atol=1e-12)

    # with the default motor left on, the same joint does not follow the free motion
    cid = p.connect(p.DIRECT)
    try:
        body, _, _ = engine._build(p, cid, sc, "multibody", 1e-3)
        p.setJointMotorControlMultiDof(
            body, 0, p.POSITION_CONTROL, targetPosition=[0, 0, 0, 1], physicsClientId=cid
        )  # restores a motor with pybullet's default force
        q, W = cv.pybullet_spherical_from_state(sc.rotation, sc.omega_body)
        p.resetJointStateMultiDof(body, 0, q, W, physicsClientId=cid)
        for _ in range(1000):
            p.stepSimulation(physicsClientId=cid)
        R_motor, _ = cv.pybullet_spherical_to_state(
            *p.getJointStateMultiDof(body, 0, physicsClientId=cid)[:2]
        )
    finally:
        p.disconnect(physicsClientId=cid)
    assert np.abs(R_motor - R_exact).max() > 1e-3


def test_dart_deactivation_is_switched_off():
    engine = engine_or_skip("dart")
    import dartpy

    # the trap: DART enables deactivation by default (threshold 0.05 rad/s)
    assert dartpy.simulation.World().getDeactivationOptions().mEnabled
    # a body slower than the threshold for 4 times the 0.5 s dwell keeps its motion.
    # (DART 6.20 only lets bodies in a constraint island sleep, so this isolated body would
    # not sleep even with the default; the read-back below is what guards the setting.)
    W0 = [0.01, 0.02, 0.015]
    sc = free_body(omega_body=W0, velocity=[0.001, 0, 0], gravity=[0, 0, 0], t_end=2.0)
    out = run(engine, "semi-implicit Euler", sc, 1e-3)
    # 1e-6: the algorithm's own energy error here is 7.3e-8 (first order, measured); a
    # sleeping body would have no kinetic energy at all (ratio 0)
    assert abs(_energy_ratio(out.trajectory) - 1) < 1e-6
    assert np.allclose(out.trajectory.position[-1], sc.position + 2.0 * sc.velocity, atol=1e-14)
    assert out.settings["deactivation (sleeping)"] is False
    # the read-back refuses a World with deactivation left on
    world, skel, joint, body, _ = engine._build(sc, 1e-3)
    opts = world.getDeactivationOptions()
    opts.mEnabled = True
    world.setDeactivationOptions(opts)
    with pytest.raises(EngineError, match="deactivation"):
        engine._check_model(world, skel, joint, body, sc, np.zeros(3), 1e-3)


def test_mujoco_state_is_read_from_qpos_not_stale_xmat():
    engine = engine_or_skip("mujoco")
    import mujoco

    sc = free_body(gravity=[0, 0, 0])
    dt = 1e-2
    out = engine.run(sc, "Euler", dt, t_end=dt, save_every=1)
    m = mujoco.MjModel.from_xml_string(engine.model_xml(sc, "Euler", dt))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = cv.mujoco_free_from_state(
        sc.position, sc.velocity, sc.rotation, sc.omega_body
    )
    mujoco.mj_step(m, d)
    stale = d.xmat[1].reshape(3, 3).copy()
    # the trap: after mj_step, xmat still describes the START of the step
    assert np.allclose(stale, sc.rotation, rtol=0, atol=1e-15)
    mujoco.mj_forward(m, d)
    fresh = d.xmat[1].reshape(3, 3).copy()
    # the step turned the body by dt |W| = 0.026 rad
    assert np.abs(fresh - stale).max() > 0.5 * dt * np.linalg.norm(sc.omega_body)
    assert np.allclose(out.trajectory.rotation[1], fresh, rtol=0, atol=1e-15)


def test_mujoco_alignment_trap_is_refused():
    engine = engine_or_skip("mujoco")
    import mujoco

    # an inertial frame offset from, or rotated against, the body frame changes what
    # qpos/qvel refer to (free-joint alignment): the read-back refuses such a model
    sc = free_body()
    xml = engine.model_xml(sc, "Euler", 1e-3)
    shifted = xml.replace(
        '<inertial pos="0.0 0.0 0.0" quat="1 0 0 0"', '<inertial pos="0.0 0.0 0.1" quat="1 0 0 0"'
    )
    rotated = xml.replace(
        '<inertial pos="0.0 0.0 0.0" quat="1 0 0 0"',
        '<inertial pos="0.0 0.0 0.0" quat="0.8 0.6 0 0"',
    )
    assert shifted != xml and rotated != xml
    for bad, what in ((shifted, "body_ipos"), (rotated, "body_iquat")):
        m = mujoco.MjModel.from_xml_string(bad)
        with pytest.raises(EngineError, match=what):
            engine._check_model(mujoco, m, sc, "Euler", 1e-3)


PACKAGES = {"mujoco": "mujoco", "pinocchio": "pinocchio", "dart": "dartpy", "pybullet": "pybullet"}


@pytest.mark.parametrize("name", ENGINES)
def test_missing_engine_is_reported_unavailable(name, monkeypatch):
    import sys

    # a package that does not import (sys.modules entry None makes `import` raise)
    monkeypatch.setitem(sys.modules, PACKAGES[name], None)
    cls = get_engine(name)
    why = cls.availability()
    assert why is not None and "pip install" in why
    with pytest.raises(EngineUnavailable):
        cls.version()


@pytest.mark.parametrize("scenario_name", scenarios.list_scenarios())
@pytest.mark.parametrize("name,integrator", pairs())
def test_library_scenarios_are_accepted(name, integrator, scenario_name):
    # every scenario of the library builds, passes the adapter's read-back and initial-state
    # checks, and takes a step; the only refusal is the documented Unsupported one
    engine = engine_or_skip(name)
    sc = scenarios.load(scenario_name)
    if name == "pybullet" and integrator == "maximal coordinates" and sc.pivoted:
        with pytest.raises(Unsupported):
            engine.run(sc, integrator, sc.dt, t_end=sc.dt)
        return
    tr = engine.run(sc, integrator, sc.dt, t_end=sc.dt, save_every=1).trajectory
    _, _, E, _ = hand_energy_momentum(sc)
    # 1e-12 relative, as in test_initial_state_read_back
    assert abs(tr.energy[0] - E) <= 1e-12 * abs(E)
    assert np.all(np.isfinite(tr.rotation[-1]))


@pytest.mark.parametrize("name,integrator", pairs())
def test_flat_body_runs_and_a_non_physical_inertia_is_refused_by_mujoco(name, integrator):
    engine = engine_or_skip(name)
    # a lamina, I_3 = I_1 + I_2 (numerics.md section 1: physical, J_3 = 0): every engine runs it
    tr = run(engine, integrator, free_body(inertia=[1.0, 2.0, 3.0]), 1e-3, t_end=0.01).trajectory
    assert np.all(np.isfinite(tr.omega_body))
    if name == "mujoco":
        # violating the triangle inequality: MuJoCo's compiler rejects it (docs/engines.md)
        with pytest.raises(Unsupported, match="triangle inequality"):
            engine.run(free_body(inertia=[1.0, 1.0, 2.5]), integrator, 1e-3, t_end=1e-3)


def test_pybullet_inertia_quirks_are_caught_by_the_read_back():
    engine = engine_or_skip("pybullet")
    import pybullet as p

    sc = free_body()
    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(*sc.gravity, physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=1e-3, numSubSteps=0, physicsClientId=cid)
        # maximal coordinates: setting the inertia without the mass makes the body static
        b = p.createMultiBody(baseMass=sc.mass, useMaximalCoordinates=True, physicsClientId=cid)
        p.changeDynamics(b, -1, localInertiaDiagonal=list(sc.inertia), physicsClientId=cid)
        assert p.getDynamicsInfo(b, -1, physicsClientId=cid)[0] == 0.0  # the quirk (3.2.7)
        with pytest.raises(EngineError, match="mass"):
            engine._check_model(p, cid, b, -1, sc, True, 1e-3)
        # a link: body-wide options in the same call as the inertia leave the inertia at 0
        top = tilted_top()
        b = p.createMultiBody(
            baseMass=0.0,
            linkMasses=[top.mass],
            linkCollisionShapeIndices=[-1],
            linkVisualShapeIndices=[-1],
            linkPositions=[[0, 0, 0]],
            linkOrientations=[[0, 0, 0, 1]],
            linkInertialFramePositions=[[0, 0, 0.5]],
            linkInertialFrameOrientations=[[0, 0, 0, 1]],
            linkParentIndices=[0],
            linkJointTypes=[p.JOINT_SPHERICAL],
            linkJointAxis=[[0, 0, 1]],
            physicsClientId=cid,
        )
        p.changeDynamics(
            b, 0, localInertiaDiagonal=list(top.inertia), linearDamping=0.0, physicsClientId=cid
        )
        assert p.getDynamicsInfo(b, 0, physicsClientId=cid)[2] == (0.0, 0.0, 0.0)  # the quirk
        with pytest.raises(EngineError, match="inertia"):
            engine._check_model(p, cid, b, 0, top, False, 1e-3)
    finally:
        p.disconnect(physicsClientId=cid)
