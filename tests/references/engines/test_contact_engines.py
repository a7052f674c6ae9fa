"""The conformance kit of every engine's contact builder (references/engines/<engine>/contact.py):
its model read back against the scene (shapes, mu, e), its contact forces read back on cases
with known forces (a resting box: the normal forces carry m g; a held push: the friction
balances the push; a stack: each support carries the weight above it), and each mistake it
declares (mu not applied, a shape offset) caught by the read-back. An engine that is not
installed is skipped with the reason."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from references.engines import EngineError
from references.engines.contact import builder, configurations, run_contact

#: a numerical warning in a builder (a 0/0 normal, an overflow) is a failure here: its NaN or
#: inf would reach the law residuals computed from the rows it logs
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

G = 9.81
#: engines with a contact builder tested here (MJX: its compile takes ~10 s per configuration,
#: so one configuration; the director where director_model.contact, issue 34, is installed)
ENGINES = ("mujoco", "pinocchio", "dart", "pybullet", "drake", "mjx", "director")
#: the mean normal force over the second half of a 0.3 s rest must carry the weight to this:
#: soft contacts settle within ~0.05 s (MuJoCo's time constant 0.02 s, Drake's penetration
#: allowance 1e-3 m at sqrt(g/1e-3) ~ 100 rad/s), and the static balance is then exact
FORCE_RTOL = 1e-2


def _available(engine):
    from references.engines import get_engine

    why = get_engine(engine).availability()
    if why:
        pytest.skip(why)
    if engine == "director":
        pytest.importorskip("director_model.contact", reason="director_model.contact not here")


def _confs(engine):
    confs = [c.name for c in configurations(engine)]
    return confs[:1] if engine == "mjx" else confs


def _mark(engine, *values):
    """A parameter set; MJX's are slow (a compilation of ~10 s each), run with -m slow."""
    marks = [pytest.mark.slow] if engine == "mjx" else []
    return pytest.param(*values, marks=marks)


def _cases():
    return [_mark(e, e, c) for e in ENGINES for c in _confs(e)]


def _engines():
    return [_mark(e, e) for e in ENGINES]


def _normal_sums(sc, out):
    """Per pair, the mean over the second half of the normal forces through it (N)."""
    C = out.contacts
    n = len(out.trajectory)
    half = slice(n // 2, n)
    ln = np.einsum("nki,nki->nk", np.nan_to_num(C["force"][half]), np.nan_to_num(C["normal"][half]))
    pair = C["pair"][half]
    return [float(np.sum(ln[pair == i])) / (n - n // 2) for i in range(len(sc.contacts))]


@pytest.mark.parametrize("engine, conf", _cases())
def test_resting_box_forces_and_readback(engine, conf):
    _available(engine)
    sc = scenarios.load("box_resting")
    out = run_contact(engine, sc, conf, 1e-3, t_end=0.3, save_every=10)
    rb = out.readback
    assert rb["pairs"][0]["mu"] == pytest.approx(0.5, rel=1e-12)
    assert rb["shapes"]["block"]["kind"] == "box"
    assert np.allclose(rb["shapes"]["block"]["size"], [0.1, 0.1, 0.1], rtol=1e-12)
    (fn,) = _normal_sums(sc, out)
    assert fn == pytest.approx(1.0 * G, rel=FORCE_RTOL), (engine, conf, fn)
    # the normal points out of the ground into the box, the force pushes it up
    C = out.contacts
    rows = C["pair"][-1] >= 0
    assert np.allclose(C["normal"][-1][rows], [0.0, 0.0, 1.0], atol=1e-9)


#: Newton's law on each step: the contact forces read back times h equal the impulse that
#: changed the momentum (m dv - h (F + m g)), to this fraction of m g h: the forces are the
#: ones the engine applied, in world axes, on the right body. 1e-6 holds for Pinocchio + suite,
#: DART, PyBullet and Drake SAP (measured: < 1e-9 .. 1e-7); MuJoCo's sliding ball (7e-6 and
#: 1e-5, pyramidal and elliptic) and Drake's TAMSI and Lagged (6e-5, 1.3e-4) differ by more, a
#: gap between the force their results report and the impulse their step applied (measured
#: when this test was written; it is 1e-8 .. 1e-4 of the friction, not a frame or sign error,
#: which would be O(1))
BALANCE_RTOL = {"default": 1e-6, "mujoco": 3e-5, "mjx": 3e-5, "drake": 3e-4}


@pytest.mark.parametrize("engine, conf", _cases())
@pytest.mark.parametrize("scene", ["push_axis_stick", "sphere_topspin"])
def test_contact_forces_are_the_applied_impulses(engine, conf, scene):
    """Every step of 0.05 s of a held push (4 corners, friction against the push) and of a
    ball sliding into rolling (one point, friction along the slip), saved at every step: the
    forces the builder reads back, summed over the rows of the body, times h, are the change
    of its linear momentum less the external forces' and gravity's impulse."""
    _available(engine)
    sc = scenarios.load(scene)
    h = 1e-3
    out = run_contact(engine, sc, conf, h, t_end=0.05, save_every=1)
    tr, C = out.trajectory, out.contacts
    m = sc.bodies[0].mass
    F = sum((f.force for f in sc.forces), np.zeros(3)) + m * np.asarray(sc.gravity)
    impulse = m * np.diff(tr.velocity[:, 0], axis=0) - h * F  # (n-1, 3)
    f = np.where((C["pair"] >= 0)[..., None], np.nan_to_num(C["force"]), 0.0).sum(axis=1)
    read = h * f[1:]
    err = np.max(np.abs(read - impulse)) / (m * G * h)
    tol = BALANCE_RTOL.get(engine, BALANCE_RTOL["default"])
    assert err < tol, (engine, conf, scene, err)


@pytest.mark.parametrize("engine, conf", _cases())
def test_every_row_is_a_unit_normal_on_the_ground(engine, conf):
    """A box pushed along the ground (0.5 s, saved every 10 steps): every contact row of every
    saved step has the ground's normal, as a unit vector (a builder that keeps a view of the
    engine's reused memory logs stale or zero normals: MuJoCo's contact frames were so)."""
    _available(engine)
    sc = scenarios.load("push_axis_slide")
    out = run_contact(engine, sc, conf, 1e-3, t_end=0.5, save_every=10)
    C = out.contacts
    rows = C["pair"] >= 0
    assert rows.sum() > 0
    assert np.allclose(C["normal"][rows], [0.0, 0.0, 1.0], atol=1e-6), engine


@pytest.mark.parametrize("engine", _engines())
@pytest.mark.parametrize("flip", [False, True])
def test_stack_support_forces(engine, flip):
    """Each support carries the weight above it; ``flip`` lists the box-box pairs the other
    way round (a the lower box), so that a builder turns the engine's force and normal to the
    pair's side whichever way the engine orders the two bodies."""
    import dataclasses

    _available(engine)
    sc = scenarios.load("box_stack")
    if flip:
        pairs = [c if c.b_is_plane else dataclasses.replace(c, a=c.b, b=c.a) for c in sc.contacts]
        sc = sc.replace(contacts=tuple(pairs))
    conf = _confs(engine)[0]
    out = run_contact(engine, sc, conf, 1e-3, t_end=0.3, save_every=10)
    sums = _normal_sums(sc, out)
    # each body's momentum over every saved step against the forces on it: +f on the pair's
    # a, -f on its b (a builder that hands the engine's force to the wrong body fails here)
    tr, C = out.trajectory, out.contacts
    idx = {b.name: i for i, b in enumerate(sc.bodies)}
    on = np.zeros((len(tr), len(sc.bodies), 3))
    for k in range(len(tr)):
        for j in np.nonzero(C["pair"][k] >= 0)[0]:
            c = sc.contacts[C["pair"][k, j]]
            on[k, idx[c.a]] += C["force"][k, j]
            if not c.b_is_plane:
                on[k, idx[c.b]] -= C["force"][k, j]
    out1 = run_contact(engine, sc, conf, 1e-3, t_end=0.02, save_every=1)
    tr1, C1 = out1.trajectory, out1.contacts
    for b, i in idx.items():
        on1 = np.zeros((len(tr1), 3))
        for k in range(len(tr1)):
            for j in np.nonzero(C1["pair"][k] >= 0)[0]:
                c = sc.contacts[C1["pair"][k, j]]
                sign = 1.0 if c.a == b else -1.0 if c.b == b else 0.0
                on1[k] += sign * C1["force"][k, j]
        impulse = np.diff(tr1.velocity[:, i], axis=0) - 1e-3 * np.asarray(sc.gravity)
        err = np.max(np.abs(1e-3 * on1[1:] - impulse)) / (G * 1e-3)
        if engine != "drake":
            assert err < BALANCE_RTOL.get(engine, BALANCE_RTOL["default"]), (engine, b, err)
    # pairs: cube0-ground carries 3 m g, cube1-cube0 2 m g, cube2-cube1 m g
    want = [3 * G, 2 * G, G]
    if engine == "drake":  # point contact: each box touches at one vertex and rocks
        pytest.xfail(f"Drake point contact on box-box and box-plane: sums {sums}")
    assert sums == pytest.approx(want, rel=FORCE_RTOL), (engine, sums)


@pytest.mark.parametrize("engine", _engines())
@pytest.mark.parametrize("mistake", ["mu not applied", "shape offset"])
def test_planted_mistakes_caught(engine, mistake):
    _available(engine)
    mod = builder(engine)
    assert mistake in mod.PLANTABLE
    sc = scenarios.load("box_resting")
    conf = _confs(engine)[0]
    with pytest.raises(EngineError, match="mu =|shape offset|offset is"):
        run_contact(engine, sc, conf, 1e-3, t_end=0.01, save_every=10, _plant=mistake)


def test_restitution_read_back_where_modelled():
    """Engines that model e hold the scene's: DART (product of the shapes'), PyBullet
    (product of the bodies'), Pinocchio + suite (Newton's law in the loop)."""
    sc = scenarios.load("drop_e05")
    for engine in ("dart", "pybullet", "pinocchio"):
        from references.engines import get_engine

        if get_engine(engine).availability():
            continue
        out = run_contact(engine, sc, _confs(engine)[0], 1e-3, t_end=0.01, save_every=10)
        assert out.readback["pairs"][0]["e"] == pytest.approx(0.5, rel=1e-12), engine


def test_unsupported_says_why():
    """Drake's discrete contact has no restitution coefficient: a scene with e > 0 is
    unsupported, with that reason (never run with e silently dropped)."""
    from references.engines import Unsupported, get_engine

    if get_engine("drake").availability():
        pytest.skip("Drake is not installed")
    with pytest.raises(Unsupported, match="no restitution coefficient"):
        run_contact("drake", scenarios.load("drop_e05"), "SAP, point contact", 1e-3,
                    t_end=0.01, save_every=10)  # fmt: skip


def test_director_contact_through_its_api():
    """The director's contact scheme (director_model.contact, issue 34), where installed: its
    scene read back (mu, e, shapes), a block below the friction angle held to round-off."""
    pytest.importorskip("director_model.contact", reason="director_model.contact not here yet")
    sc = scenarios.load("block_incline_stick")
    out = run_contact("director", sc, "nonsmooth RATTLE", 1e-3, t_end=0.5, save_every=10)
    assert out.readback["pairs"][0] == {"mu": 0.4, "e": 0.0}
    moved = np.max(np.linalg.norm(out.trajectory.position - out.trajectory.position[0], axis=2))
    assert moved < 1e-12


@pytest.mark.parametrize("engine", _engines())
def test_a_hinged_body_swings_on_its_hinge_and_rests_on_the_ground(engine):
    """A system in contact (hinged_strike: a ball on a hinge to the ground, striking it):
    the joint holds (the ball's centre stays 0.3 m from the hinge point), the model reads
    back (shapes in their bodies: a link's shape placed in the wrong frame shows here; the
    hinge's kind, anchor and axis), and once it rests the ground carries the weight, m g,
    by the moment balance about the hinge (the hinge is at the ball centre's height: it
    carries none)."""
    _available(engine)
    sc = scenarios.load("hinged_strike")
    # 1 s: the forces are averaged over its second half, when MuJoCo's soft contact has
    # settled from the 12 mm it sinks at the impact (within 1e-5 m from 0.45 s)
    out = run_contact(engine, sc, _confs(engine)[0], 1e-3, t_end=1.0, save_every=10)
    x = out.trajectory.position[:, 0]
    hinge = sc.joints[0].anchor_b
    # reduced coordinates hold the joint exactly; the director's constraint rows to its
    # solver's tolerance (1e-12 m): 1e-9 m leaves room for rounding over 1000 steps
    assert np.max(np.abs(np.linalg.norm(x - hinge, axis=1) - 0.3)) < 1e-9
    assert out.readback["shapes"]["ball"]["offset"] == pytest.approx((0, 0, 0), abs=1e-12)
    assert out.readback["joints"]["hinge"]["kind"] == "revolute"
    (support,) = _normal_sums(sc, out)
    if engine == "mjx" and support != pytest.approx(G, rel=FORCE_RTOL):
        # measured 2026-12-05 (pyramidal, 2 s): means over 0.25 s windows 9.81, 9.89, 9.81,
        # 10.04 N from 0.5 s on and the centre 9e-5 m low at 2 s, where C MuJoCo's is 9.81 N
        # and 0.05 m to 1e-14 from 0.5 s on; 9.63 N over 0.5-1 s in one run of this test
        pytest.xfail(f"MJX's resting hinged ball does not settle: mean support {support} N")
    assert support == pytest.approx(G, rel=FORCE_RTOL)


@pytest.mark.parametrize("engine", _engines())
def test_a_body_on_a_slider_drops_along_it(engine):
    """A system in contact with a prismatic joint (slider_drop: the ball of drop_e05 on a
    vertical slider to the ground, e = 0.5): the joint holds (the ball neither moves across
    the axis nor turns: to 1e-9, the reduced coordinates' and the director's constraint
    rows' rounding over 2000 steps), its kind, anchor line and axis read back, and the ball
    ends resting on the ground (its centre within 1 mm of r = 0.1 m after the bounces have
    ended at 0.96 s: MuJoCo's soft contact sinks or hops by up to 0.2 mm, 1e-3 leaves room).
    Drake's discrete contact has no restitution coefficient: unsupported, saying so."""
    from references.engines import Unsupported

    _available(engine)
    sc = scenarios.load("slider_drop")
    if engine == "drake":
        with pytest.raises(Unsupported, match="no restitution coefficient"):
            run_contact(engine, sc, _confs(engine)[0], 1e-3, t_end=0.01, save_every=10)
        return
    out = run_contact(engine, sc, _confs(engine)[0], 1e-3, t_end=2.0, save_every=10)
    x, R = out.trajectory.position[:, 0], out.trajectory.rotation[:, 0]
    assert np.max(np.abs(x[:, :2])) < 1e-9
    assert np.max(np.abs(R - np.eye(3))) < 1e-9
    assert out.readback["joints"]["slider"]["kind"] == "prismatic"
    assert x[-1, 2] == pytest.approx(0.1, abs=1e-3)


@pytest.mark.parametrize("engine", _engines())
def test_a_planted_joint_axis_is_caught(engine):
    """Every joint of hinged_strike built with its axis tilted by 0.01 rad (in the engine's
    model after it is built, or in the scene the builder is handed): the joint read-back
    names the joint and both axes."""
    _available(engine)
    assert "joint axis" in builder(engine).PLANTABLE
    with pytest.raises(EngineError, match="joint 'hinge': the engine's axis"):
        run_contact(engine, scenarios.load("hinged_strike"), _confs(engine)[0], 1e-3,
                    t_end=0.01, save_every=10, _plant="joint axis")  # fmt: skip


def test_joints_with_contact_unsupported_says_why():
    """A joint a contact builder does not make (here a spherical joint to the ground) is
    refused before anything runs, naming the joint and what the builder makes."""
    import dataclasses

    from references.engines import Unsupported

    sc = scenarios.load("hinged_strike")
    ball = dataclasses.replace(sc.joints[0], kind="spherical", axis_a=None, axis_b=None)
    with pytest.raises(Unsupported, match="joint 'hinge' \\(spherical .*revolute or prismatic"):
        run_contact("mujoco", sc.replace(joints=(ball,)), "pyramidal", 1e-3, t_end=0.01,
                    save_every=10)  # fmt: skip


@pytest.mark.parametrize("conf", ["pyramidal", "elliptic"])
def test_mjx_decodes_contact_rows_as_mujoco_does(conf):
    """MJX's builder decodes each contact's force from its constraint rows (C MuJoCo's
    mj_contactForce on the MjData mjx.get_data fills returned 1e160-1e260 on some contacts);
    the decoding against mj_contactForce itself on C MuJoCo's data: a box sliding under an
    axis push (friction at its bound, so every tangential row counts), to 1e-12 N."""
    _available("mujoco")
    import mujoco

    from references.engines.contact import configuration
    from references.engines.mjx.contact import contact_frame_force
    from references.engines.mujoco import contact as mjc

    sc = scenarios.load("push_axis_slide")
    m = mujoco.MjModel.from_xml_string(mjc.mjcf(sc, configuration("mujoco", conf), 1e-3, {}))
    d = mujoco.MjData(m)
    bid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b.name) for b in sc.bodies]
    mjc.set_initial_state(mujoco, m, d, sc, bid)
    (push,) = sc.forces
    d.xfrc_applied[bid[0], :3] = push.force
    f6, seen = np.zeros(6), 0
    for _ in range(200):
        mujoco.mj_step(m, d)
        for c in range(d.ncon):
            if d.contact[c].efc_address < 0:  # found, not in the problem (the builder skips it)
                continue
            mujoco.mj_contactForce(m, d, c, f6)
            got = contact_frame_force(int(m.opt.cone), d.contact[c], d.efc_force)
            assert got == pytest.approx(f6[:3], abs=1e-12)
            seen += max(abs(f6[1]), abs(f6[2])) > 0.1 * abs(f6[0])
    assert seen > 0, "no contact carried friction: the tangential decoding was not checked"


def test_drakes_log_of_a_run_does_not_depend_on_what_ran_before_in_its_process():
    """Drake says some things once per process (a half space registered: "not supported for
    deformable contact"): the same run twice in a fresh process has the same log, so a
    run's settings do not depend on which worker built a scene first."""
    import subprocess
    import sys

    _available("drake")
    code = (
        "import json, scenarios\n"
        "from references.engines.contact import run_contact\n"
        "sc = scenarios.load('block_incline_stick').replace(t_end=0.01)\n"
        "logs = [run_contact('drake', sc, 'SAP, point contact', 1e-3, 0.01, 5)"
        '.settings["Drake\'s log"] for _ in range(2)]\n'
        "print(json.dumps(logs))\n"
    )
    got = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert got.returncode == 0, got.stderr
    first, second = __import__("json").loads(got.stdout.splitlines()[-1])
    assert first == second
