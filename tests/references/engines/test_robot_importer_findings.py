"""What three engines' importers do to an MJCF file, each read back and run (issue 36): DART's
MjcfParser keeps no rotational inertia, Pinocchio's MJCF parser gives a visual geom no mass
and builds the first body tree only, Drake's MJCF parser drops the armature of a joint no
actuator drives (and the as-loaded crawler then diverges at an explicit fixed step). Each
finding is a row of the importer table with its cause beside it; the faithful configuration's
workaround removes the mass-property rows. The expected sizes are computed here by hand from
the file's numbers."""

from __future__ import annotations

import math

import pytest

import scenarios
from references.engines import importers as imp
from scenarios.models import read_model

# one hinged body with two geoms (a box of density 1000, a visual-only sphere of 0.2 kg), an
# unnamed child on a hinge holding only an <inertial>, a floor geom of the world, and a
# second body tree (a slider)
MJCF = """<mujoco model="t">
  <compiler angle="radian"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="base" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.05 0.02" density="1000"/>
      <geom type="sphere" pos="0.1 0 0" size="0.03" mass="0.2" contype="0" conaffinity="0"/>
      <body pos="0.2 0 0">
        <joint name="j2" type="hinge" axis="1 0 0"/>
        <inertial pos="0.05 0 0" mass="0.3" diaginertia="0.001 0.002 0.0025"/>
      </body>
    </body>
    <body name="other" pos="1 0 0">
      <joint name="s" type="slide" axis="1 0 0"/>
      <geom type="sphere" size="0.05"/>
    </body>
  </worldbody>
</mujoco>
"""
BOX = 1000 * 0.2 * 0.1 * 0.04  # kg: density times the box's full extents


@pytest.fixture
def model(tmp_path):
    p = tmp_path / "t.xml"
    p.write_text(MJCF)
    return read_model(p)


def _rows(model, engine, config):
    return [r for r in imp.importer_table(model, [engine], [config]) if r.config == config]


def test_dart_reads_mass_from_the_first_geom_and_no_rotational_inertia(model):
    pytest.importorskip("dartpy")
    rows = {(r.item, r.quantity): r for r in _rows(model, "dart", "as-loaded")}
    # the sphere's 0.2 kg is lost: 0.2 / (0.8 + 0.2) of the mass
    assert rows[("body 'base'", "mass")].size == pytest.approx(100 * 0.2 / (BOX + 0.2))
    assert "never its rotational inertia" in rows[("body 'base'", "inertia")].remark
    # the child holding only an <inertial> gets DART's default 1 kg: (1 - 0.3) / 0.3
    assert rows[("body 'body2'", "mass")].size == pytest.approx(100 * 0.7 / 0.3)


def test_dart_faithful_takes_the_inertias_from_mujocos_model_and_agrees(model):
    pytest.importorskip("dartpy")
    pytest.importorskip("mujoco")
    rows = [r for r in _rows(model, "dart", "faithful")
            if r.quantity in ("mass", "com", "inertia", "unknown body", "missing")]  # fmt: skip
    assert not rows, [r.line() for r in rows]


def test_dart_read_back_pairs_an_unnamed_body_by_its_joint_and_skips_the_floor(model):
    """Our adapter's read-back: DART names an unnamed MJCF body 'Nonamed (k)' and makes the
    world's floor geom an immobile skeleton of 1 kg; neither is a difference of the model."""
    pytest.importorskip("dartpy")
    for config in ("as-loaded", "faithful"):
        bad = [r.line() for r in _rows(model, "dart", config)
               if r.quantity in ("unknown body", "missing")]  # fmt: skip
        assert not bad, bad


def test_pinocchio_gives_a_visual_geom_no_mass_and_builds_the_first_tree_only(model):
    pytest.importorskip("pinocchio")
    rows = {(r.item, r.quantity): r for r in _rows(model, "pinocchio", "as-loaded")}
    assert rows[("body 'base'", "mass")].size == pytest.approx(100 * 0.2 / (BOX + 0.2))
    assert "contype=0 and conaffinity=0" in rows[("body 'base'", "mass")].remark
    assert "first <body>" in rows[("body 'other'", "missing")].remark
    # faithful: every geom collidable in a copy, so the masses agree; the second tree is
    # still dropped (no setting brings it back)
    faithful = [(r.item, r.quantity) for r in _rows(model, "pinocchio", "faithful")]
    assert faithful == [("body 'other'", "missing")]


def test_drake_drops_the_armature_of_a_joint_without_an_actuator():
    pytest.importorskip("pydrake")
    sc = scenarios.load("crawler_float")
    rows = {r.item: r for r in _rows(sc.model, "drake", "as-loaded") if r.quantity == "armature"}
    # crawler.xml: armature 0.01 on every hinge, a motor on the neck only
    assert sorted(rows) == ["joint 'hip_left'", "joint 'hip_right'", "joint 'knee_left'",
                            "joint 'wrist'"]  # fmt: skip
    assert all(r.size == pytest.approx(0.01) for r in rows.values())


def test_drake_as_loaded_crawler_diverges_by_its_step_not_by_its_model():
    """The armature lost, knee_left's damping 0.3 N m s acts on 2.8e-5 kg m^2: a rate of
    1.1e4 1/s. Times 1e-3 s that is 10.8, outside runge_kutta5's real stability interval
    (about 3.3); at 2.5e-4 s it is 2.7, inside, and the same import runs."""
    pytest.importorskip("pydrake")
    from references.errors import Diverged

    sc = scenarios.load("crawler_float")
    with pytest.raises(Diverged):
        imp.simulate("drake", sc, "as-loaded", "runge_kutta5", 1e-3, 50, 10)
    out = imp.simulate("drake", sc, "as-loaded", "runge_kutta5", 2.5e-4, 200, 50)
    assert all(math.isfinite(float(a)) for a in out.x.ravel())
    assert "knee_left" in out.settings["armature lost"]


def _run(engine, sc, integrator, config=None, nstep=300):
    from references.engines.system import run_system

    name = integrator if config is None else imp.variant(integrator, config)
    return run_system(engine, sc, name, 1e-3, t_end=nstep * 1e-3, save_every=10).trajectory


def test_dart_faithful_crawler_moves_as_dart_on_our_reading():
    """crawler.xml through MjcfParser, faithful (a <joint type='free'> for its <freejoint>,
    inertias from MuJoCo's model, the wrist's ref of 20 deg taken off the scenario's start
    since DART's coordinate ignores ref) against DART stepping our reading: the same
    semi-implicit Euler on the same system. The two put the free joint at different points
    of the torso (the link origin, the centre of mass), which changes the scheme's O(dt)
    error by a uniform drift: measured 4.6e-6 m after 0.3 s, where the scheme's own error is
    2.5e-3 rad; started at the file's wrist angle plus its ref they part by 5.8e-3 m, and
    welded by the importer (its <freejoint> unread) the torso does not move at all."""
    pytest.importorskip("dartpy")
    pytest.importorskip("mujoco")
    sc = scenarios.load("crawler_float")
    ours = _run("dart", sc, "semi-implicit Euler")
    theirs = _run("dart", sc, "semi-implicit Euler", "faithful")
    assert abs(theirs.position - ours.position).max() < 1e-4


def test_dart_faithful_runs_contact_free(tmp_path):
    """A pendulum whose box starts inside the world's floor: DART's importer run as loaded
    collides (its parser gives every geom a collision shape, the floor one too); the faithful
    configuration, contact-free as the scenario is, has no contact at all."""
    pytest.importorskip("dartpy")
    pytest.importorskip("mujoco")
    from references.engines.dart import importer as di

    (tmp_path / "p.xml").write_text("""<mujoco model="p">
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="bob" pos="0 0 0.01">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.05 0.02" density="1000"/>
    </body>
  </worldbody>
</mujoco>
""")
    (tmp_path / "p.toml").write_text("""name = "p_swing"
description = "a pendulum touching the floor"
[model]
file = "p.xml"
[model.initial]
joints = { hinge = 0.3 }
[environment]
gravity = [0.0, 0.0, -9.81]
[run]
t_end = 0.01
dt = 1e-3
""")
    sc = scenarios.load(tmp_path / "p.toml")
    counts = {}
    for config in ("as-loaded", "faithful"):
        sim = di.load(sc, config, "semi-implicit Euler", 1e-3)
        n = 0
        for _ in range(10):
            sim.advance(1)
            n += sim.world.getLastCollisionResult().getNumContacts()
        counts[config] = n
    assert counts["as-loaded"] > 0 and counts["faithful"] == 0, counts


def test_dart_welds_a_freejoint_body_and_the_faithful_copy_frees_it():
    """crawler.xml's torso has a <freejoint>, which MjcfParser does not read: the as-loaded
    read-back says the root is attached to the world; the faithful copy (<joint
    type='free'>) floats it."""
    pytest.importorskip("dartpy")
    sc = scenarios.load("crawler_float")
    rows = {c: [(r.ours, r.theirs) for r in _rows(sc.model, "dart", c)
                if r.quantity == "root joint"] for c in ("as-loaded", "faithful")}  # fmt: skip
    assert rows == {"as-loaded": [("free", "attached")], "faithful": []}


# PyBullet's loadMJCF: a <default> density of 5 kg/m^3, a sphere off its body's origin, an
# unnamed body whose capsule (fromto) has a mass of its own, hinges written in full (Bullet
# reads a joint's type and axis from the joint element only)
PB_MJCF = """<mujoco model="pb">
  <compiler angle="radian"/>
  <default><geom density="5"/></default>
  <worldbody>
    <body name="base" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0"/>
      <geom type="sphere" pos="0.1 0 0" size="0.1"/>
      <body pos="0.2 0 0">
        <joint name="j2" type="hinge" axis="1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.05" mass="0.3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
SPHERE = 4 / 3 * math.pi * 0.1**3  # m^3
CAPSULE = 4 / 3 * math.pi * 0.05**3 + math.pi * 0.05**2 * 0.3  # m^3: two half-spheres, a cylinder


@pytest.fixture
def pb_model(tmp_path):
    p = tmp_path / "pb.xml"
    p.write_text(PB_MJCF)
    return read_model(p)


def test_pybullet_load_mjcf_takes_1000_kg_per_m3_and_no_density_or_mass(pb_model):
    """BulletMJCFImporter.cpp (parseBody): a body without <inertial> weighs 1000 kg/m^3 times
    its geoms' volume, whatever density or mass the file gives, and its centre of mass is at
    its last fromto capsule's midpoint, else at the body origin. Expected sizes by hand: the
    sphere's 5 kg/m^3 read as 1000 (199 times too heavy: 19900 %), the capsule's 0.3 kg read
    as 1000 kg/m^3 times its volume, the sphere's centre 0.1 m off the origin."""
    pytest.importorskip("pybullet")
    rows = {(r.item, r.quantity): r for r in _rows(pb_model, "pybullet", "as-loaded")}
    assert rows[("body 'base'", "mass")].size == pytest.approx(100 * (1000 / 5 - 1), rel=1e-6)
    assert "1000 kg/m^3" in rows[("body 'base'", "mass")].remark
    assert rows[("body 'base'", "com")].size == pytest.approx(0.1, rel=1e-6)
    # the unnamed body (ours 'body2', PyBullet's a "link..." fixed to its joint's link) is
    # paired by its joint: a mass row, no unknown or missing body
    got = rows[("body 'body2'", "mass")].size
    assert got == pytest.approx(100 * abs(1000 * CAPSULE - 0.3) / 0.3, rel=1e-6)
    assert not [k for k in rows if k[1] in ("unknown body", "missing")], sorted(rows)


def test_pybullet_faithful_mjcf_copy_agrees_with_our_reading(pb_model):
    """The faithful copy (every body's <inertial>, pose and joints written from MuJoCo's
    compiled model, URDF_USE_INERTIA_FROM_FILE): no mass-property row beyond PyBullet's
    single-precision storage of the file's numbers (float32's unit round-off 6e-8 relative:
    measured 1e-8 relative and 1e-8 m on the library's models; bounds 1e-7 relative, 1e-7 m)."""
    pytest.importorskip("pybullet")
    pytest.importorskip("mujoco")
    rows = _rows(pb_model, "pybullet", "faithful")
    bad = [r.line() for r in rows
           if r.quantity in ("unknown body", "missing", "load", "axis length")
           or (r.quantity in ("mass", "inertia") and r.size > 1e-5)
           or (r.quantity in ("com", "axis offset") and r.size > 1e-7)]  # fmt: skip
    assert not bad, bad


def test_pybullet_faithful_crawler_moves_as_pybullet_on_our_reading():
    """crawler.xml through loadMJCF: as loaded its limbs are lost (their joints' type comes
    from a default class, which Bullet does not read: an unsupported row naming the arm);
    faithful (the copy written from MuJoCo's model, the wrist's ref of 20 deg taken off the
    start since PyBullet's coordinate 0 is the file's pose) it moves as PyBullet stepping our
    reading: measured 1.1e-6 m apart after 0.3 s, where the scheme's own error is 2.5e-3
    rad; the bound 1e-4 m is far below what the ref alone moves (5.8e-3 m in DART's test)."""
    pytest.importorskip("pybullet")
    pytest.importorskip("mujoco")
    from references.errors import Unsupported

    sc = scenarios.load("crawler_float")
    with pytest.raises(Unsupported, match="'arm'"):
        imp.simulate("pybullet", sc, "as-loaded", "multibody", 1e-3, 10, 10)
    ours = _run("pybullet", sc, "multibody")
    theirs = _run("pybullet", sc, "multibody", "faithful")
    assert abs(theirs.position - ours.position).max() < 1e-4


def test_pybullet_reads_a_second_body_tree_in_the_root_frame(model):
    """loadMJCF returns one PyBullet body per tree of the world body; every tree is read back
    in the frame of the root link's tree (else 'other', 1 m beside the root, would read as
    1.4 m off: its own base frame taken for the root's)."""
    pytest.importorskip("pybullet")
    pytest.importorskip("mujoco")
    rows = [r for r in _rows(model, "pybullet", "faithful") if r.item == "body 'other'"]
    bad = [r.line() for r in rows if r.size > (1e-7 if r.quantity == "com" else 1e-5)]
    assert not bad, bad
