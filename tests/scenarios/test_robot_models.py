"""Our URDF and MJCF readers (scenarios.models) against hand-computed cases, against engines'
importers read back (an independent computation), planted reader mistakes caught, bad input
refused with the file, element and rule, and the reference's accuracy on a model with an
exact answer."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import scenarios
from scenarios.models import ModelError, read_model, to_system
from scenarios.models import geoms as G
from scenarios.models import urdf as U

MODELS = Path(scenarios.__file__).parent / "robots" / "models"
ARM3 = MODELS / "arm3.urdf"
CRAWLER = MODELS / "crawler.xml"


def write(tmp_path, name, text) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def link(name, mass=1.0, xyz="0 0 0", rpy="0 0 0", I=(1, 2, 3), extra=""):
    return (
        f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="{rpy}"/>'
        f'<mass value="{mass}"/><inertia ixx="{I[0]}" ixy="0" ixz="0" iyy="{I[1]}" iyz="0" '
        f'izz="{I[2]}"/></inertial>{extra}</link>'
    )


def revolute(name, parent, child, xyz="0 0 0", rpy="0 0 0", axis="0 1 0", kind="revolute"):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/></joint>'
    )


def robot(*parts) -> str:
    return '<robot name="t">' + "".join(parts) + "</robot>"


# -- hand-computed cases --------------------------------------------------------------------------


def test_inertial_rpy_rotates_the_inertia_into_the_link_frame(tmp_path):
    # principal moments (1, 2, 3) about axes turned 90 degrees about z: in the link frame the
    # x and y moments swap (by hand: R = Rz(90) maps x -> y)
    p = write(tmp_path, "a.urdf", robot(link("a", rpy=f"0 0 {math.pi / 2}", xyz="0.1 0.2 0.3")))
    ine = read_model(p).link("a").inertial
    np.testing.assert_allclose(ine.inertia, np.diag([2.0, 1.0, 3.0]), atol=1e-15)
    np.testing.assert_allclose(ine.com, [0.1, 0.2, 0.3])


def test_rpy_is_fixed_axes_x_then_y_then_z():
    # roll 90 about x then yaw 90 about the fixed z: e_y -> e_z (roll) -> e_z (yaw), and
    # e_x -> e_x (roll) -> e_y (yaw); a moving-axes (intrinsic x-y-z) reading would send
    # e_x -> e_z instead
    from scenarios.models.model import rpy_matrix

    R = rpy_matrix([math.pi / 2, 0.0, math.pi / 2])
    np.testing.assert_allclose(R @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_pendulum_pose_from_the_joint_angle(tmp_path):
    # a link hanging from a y-hinge at height 1, centre of mass 0.5 below the hinge: at angle
    # t the centre of mass is at (-0.5 sin t, 0, 1 - 0.5 cos t) (a rotation about +y turns
    # -z towards -x), its speed 0.5 w; by hand
    arm = link("arm", xyz="0 0 -0.5", I=(0.1, 0.1, 0.01))
    p = write(
        tmp_path, "p.urdf", robot(link("base"), arm, revolute("j", "base", "arm", xyz="0 0 1"))
    )
    t, w = 0.7, 1.3
    conv = to_system(read_model(p), {"j": t}, {"j": w})
    (b,) = conv.bodies
    np.testing.assert_allclose(
        b.position, [-0.5 * math.sin(t), 0, 1 - 0.5 * math.cos(t)], atol=1e-15
    )
    np.testing.assert_allclose(
        b.velocity, [-0.5 * w * math.cos(t), 0, 0.5 * w * math.sin(t)], atol=1e-15
    )
    np.testing.assert_allclose(sorted(b.inertia), [0.01, 0.1, 0.1])
    (j,) = conv.joints
    assert j.body_b is None and j.kind == "revolute"
    np.testing.assert_allclose(j.anchor_b, [0, 0, 1])


def test_fixed_joint_fuses_links_by_the_parallel_axis_theorem(tmp_path):
    # two 1 kg links with moments (1, 1, 1) 0.2 m apart along x: one body of 2 kg with its
    # centre midway, moments 2 + (0, 2 * 1 * 0.1^2, 2 * 1 * 0.1^2) = (2, 2.02, 2.02)
    p = write(tmp_path, "f.urdf", robot(
        link("base"), link("a", I=(1, 1, 1)), link("b", I=(1, 1, 1)),
        revolute("j", "base", "a"),
        '<joint name="w" type="fixed"><parent link="a"/><child link="b"/>'
        '<origin xyz="0.2 0 0"/></joint>'))  # fmt: skip
    conv = to_system(read_model(p))
    (b,) = conv.bodies
    assert conv.groups == {"a": ["a", "b"]}
    assert b.mass == 2.0
    np.testing.assert_allclose(b.position, [0.1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(sorted(b.inertia), [2.0, 2.02, 2.02], rtol=1e-14)


def test_geom_mass_properties_by_hand():
    # a capsule with no cylinder is a sphere; a long cylinder's moments are m (3r^2 + h^2)/12
    v, k = G.capsule(0.3, 0.0)
    vs, ks = G.sphere(0.3)
    assert v == pytest.approx(vs, rel=1e-15)
    np.testing.assert_allclose(k, ks, rtol=1e-14)
    v, k = G.cylinder(0.1, 0.5)
    assert v == pytest.approx(math.pi * 0.01 * 1.0)
    np.testing.assert_allclose(k, [(0.03 + 1.0) / 12, (0.03 + 1.0) / 12, 0.005])
    v, k = G.box(0.1, 0.2, 0.3)
    assert v == pytest.approx(0.048)
    np.testing.assert_allclose(k, [(0.04 + 0.09) / 3, (0.01 + 0.09) / 3, (0.01 + 0.04) / 3])


def test_mjcf_angles_eulerseq_and_defaults(tmp_path):
    xml = """<mujoco><compiler angle="degree" eulerseq="XYZ"/>
      <default><geom density="500"/>
      <default class="c"><joint axis="1 0 0" range="-30 30"/></default></default>
      <worldbody><body name="b" euler="90 0 0" childclass="c"><joint name="j" ref="10"/>
      <geom type="sphere" size="0.1"/></body></worldbody></mujoco>"""
    m = read_model(write(tmp_path, "m.xml", xml))
    j = m.joint("j")
    np.testing.assert_allclose(j.origin[:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(j.axis, [1, 0, 0])
    assert (j.lower, j.upper) == pytest.approx((-math.pi / 6, math.pi / 6))
    assert j.ref == pytest.approx(math.pi / 18)
    ine = m.link("b").inertial
    assert ine.mass == pytest.approx(500 * 4 / 3 * math.pi * 1e-3)


# -- against engines' importers (independent computations) ----------------------------------------


@pytest.mark.parametrize("engine", ["mujoco", "drake"])
def test_arm3_reading_agrees_with_engine_importers(engine):
    pytest.importorskip({"mujoco": "mujoco", "drake": "pydrake"}[engine])
    from references.engines.importers import importer_table

    rows = importer_table(read_model(ARM3), engines=[engine], configs=["faithful"])
    assert [r.quantity for r in rows] == ["agree"], "\n".join(r.line() for r in rows)


def test_mjcf_reading_agrees_with_mujoco_compiler():
    # every body's mass, centre of mass and inertia (from geoms, defaults, degrees, five
    # orientation forms) and every hinge's axis, point, limits, damping, armature
    pytest.importorskip("mujoco")
    from references.engines.importers import importer_table

    rows = importer_table(read_model(CRAWLER), engines=["mujoco"], configs=["as-loaded"])
    assert [r.quantity for r in rows] == ["agree"], "\n".join(r.line() for r in rows)


def test_pybullet_as_loaded_reports_recomputed_inertia():
    pytest.importorskip("pybullet")
    from references.engines.importers import importer_table

    rows = importer_table(read_model(ARM3), engines=["pybullet"])
    inertia = [r for r in rows if r.quantity == "inertia"]
    assert {r.config for r in inertia} == {"as-loaded"}
    assert all(r.size > 40 for r in inertia)  # percent
    assert "URDF_USE_INERTIA_FROM_FILE" in inertia[0].remark


# -- planted reader mistakes, caught ---------------------------------------------------------------


def test_planted_inertial_rotated_twice_is_caught(monkeypatch, tmp_path):
    pytest.importorskip("mujoco")
    from references.engines.importers import importer_table

    monkeypatch.setattr(U, "rotate_inertia", lambda I, R: (R @ R) @ I @ (R @ R).T)
    rows = importer_table(read_model(ARM3), engines=["mujoco"], configs=["faithful"])
    bad = {r.item for r in rows if r.quantity == "inertia"}
    assert bad == {"body 'upper'", "body 'fore'", "body 'hand'"}, [r.line() for r in rows]
    with pytest.raises(AssertionError):
        test_inertial_rpy_rotates_the_inertia_into_the_link_frame(tmp_path)


def test_planted_axis_in_parent_frame_is_caught(monkeypatch):
    pytest.importorskip("mujoco")
    from references.engines.importers import importer_table

    monkeypatch.setattr(U, "axis_in_child", lambda a, T: T[:3, :3].T @ a)
    rows = importer_table(read_model(ARM3), engines=["mujoco"], configs=["faithful"])
    bad = {r.item for r in rows if r.quantity == "axis"}
    # every joint's origin is rotated (rpy), so every axis moves
    assert bad == {"joint 'shoulder'", "joint 'elbow'", "joint 'wrist'"}


# -- bad input -------------------------------------------------------------------------------------


def test_missing_mesh_names_file_element_and_rule(tmp_path):
    geo = '<collision><geometry><mesh filename="package://nowhere/m.stl"/></geometry></collision>'
    p = write(tmp_path, "m.urdf", robot(link("a", extra=geo)))
    with pytest.raises(ModelError) as e:
        read_model(p)
    msg = str(e.value)
    assert str(p) in msg and "<mesh>" in msg and "line 1" in msg and "not found" in msg
    assert "URDF_USE_INERTIA_FROM_FILE" in msg
    read_model(p, meshes="ignore")  # the reading itself does not need it


@pytest.mark.parametrize(
    "I, rule",
    [((1, 1, 3), "triangle inequality"), ((1, -2, 1), "not positive semi-definite")],
)
def test_bad_inertia_refused(tmp_path, I, rule):
    p = write(tmp_path, "i.urdf", robot(link("base"), link("a", I=I), revolute("j", "base", "a")))
    with pytest.raises(ModelError, match=rule) as e:
        to_system(read_model(p))
    assert "link 'a'" in str(e.value) and str(p) in str(e.value)


def test_massless_moving_link_refused(tmp_path):
    p = write(
        tmp_path, "z.urdf", robot(link("base"), '<link name="a"/>', revolute("j", "base", "a"))
    )
    with pytest.raises(ModelError, match="needs a mass > 0"):
        to_system(read_model(p))


def test_unknown_joint_kind_and_bad_xml(tmp_path):
    p = write(
        tmp_path, "k.urdf", robot(link("base"), link("a"), revolute("j", "base", "a", kind="hinge"))
    )
    with pytest.raises(ModelError, match=r"<joint name='j'> \(line 1\): type='hinge'"):
        read_model(p)
    p = write(tmp_path, "x.urdf", "<robot><link name='a'></robot>")
    with pytest.raises(ModelError, match="not well-formed XML at line 1"):
        read_model(p)


def test_prismatic_must_be_held(tmp_path):
    p = write(
        tmp_path,
        "s.urdf",
        robot(link("base"), link("a"), revolute("j", "base", "a", kind="prismatic")),
    )
    with pytest.raises(ModelError, match=r"lock = \['j'\]"):
        to_system(read_model(p))
    assert to_system(read_model(p), lock=["j"]).bodies == []


def test_mjcf_mesh_inertia_refused(tmp_path):
    xml = """<mujoco><asset><mesh name="m" file="m.stl"/></asset><worldbody><body name="b">
      <joint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>"""
    with pytest.raises(ModelError, match="mesh's mass properties need its volume integrals"):
        read_model(write(tmp_path, "m.xml", xml))


# -- the scenario and the reference on an exact answer -------------------------------------------


def test_show_prints_what_was_read(capsys):
    from reports.cli import main

    assert main(["show", "arm3_swing"]) == 0
    out = capsys.readouterr().out
    assert "link upper: mass 1.2 kg" in out and "joint elbow: revolute upper -> fore" in out
    assert "switched off: damping on 3 joints" in out


def test_reference_on_a_compound_pendulum_period(tmp_path):
    # one link on a hinge from rest at 2.5 rad: it returns to its start after the exact period
    # T = 4 K(k) sqrt(I_p / (m g l)), k = sin(theta0 / 2) (Landau & Lifshitz, Mechanics, 11)
    from scipy.special import ellipk

    from references.exact.multibody import solve, tree_from_world

    m, l, Ic = 1.3, 0.4, 0.02
    arm = link("arm", mass=m, xyz=f"0 0 {-l}", I=(Ic, Ic, 0.005))
    p = write(tmp_path, "p.urdf", robot(link("base"), arm, revolute("j", "base", "arm")))
    th0 = 2.5
    conv = to_system(read_model(p), {"j": th0})
    tree, q0, u0 = tree_from_world(conv.bodies, conv.joints, (0.0, 0.0, -9.81))
    T = 4 * ellipk(math.sin(th0 / 2) ** 2) * math.sqrt((Ic + m * l * l) / (m * 9.81 * l))
    sol = solve(tree, q0, u0, [0.5 * T, T])
    x = sol.x[-1, 0]
    err = float(np.linalg.norm(x - conv.bodies[0].position))
    assert err < 1e-9 * l
    assert err <= sol.accuracy["position"]  # the estimate covers the true error
    # half a period: mirrored about the vertical
    np.testing.assert_allclose(sol.x[0, 0, 0], -conv.bodies[0].position[0], atol=1e-9)


# -- the joint coordinate error, per joint ------------------------------------------------------


def test_joint_coordinate_error_recovers_a_joint_turned_by_a_known_angle():
    """Two states of arm3 placed by our conversion from joint coordinates (an independent
    path: forward kinematics), one with the elbow turned 0.05 rad further: the metric, from
    the bodies' attitudes alone, finds 0.05 rad on the elbow and nothing on the others."""
    from references.trajectory import Trajectory
    from reports.metrics.system import joint_coordinate_error_by_joint, joint_coordinate_errors

    sc = scenarios.load("arm3_swing")
    q0 = {"shoulder": 0.9, "elbow": -1.1, "wrist": 0.7}

    def traj(q):
        conv = to_system(sc.model, q)
        bs = conv.bodies
        return Trajectory([0.0], [[b.position for b in bs]], [[b.velocity for b in bs]],
                                [[b.rotation for b in bs]], [[b.omega_body for b in bs]],
                                [b.name for b in bs])  # fmt: skip

    ref = traj(q0)
    turned = traj({**q0, "elbow": -1.05})
    per = joint_coordinate_error_by_joint(sc, turned, ref)
    assert per["elbow"][0] == pytest.approx(0.05, abs=1e-12)
    assert per["shoulder"][0] < 1e-12 and per["wrist"][0] < 1e-12
    assert joint_coordinate_errors(sc, turned, ref)[0] == pytest.approx(0.05, abs=1e-12)


def test_a_held_prismatic_joint_slides_its_link(tmp_path):
    """A prismatic joint held at 0.05 m moves its child 0.05 m along its axis (by hand: the
    origin's offset plus 0.05 times the axis), never turns it by 0.05 rad (which the panda's
    fingers were, caught by the importer runs: the hand's inertia 7.4e-4 off Pinocchio's and
    MuJoCo's)."""
    p = write(tmp_path, "s.urdf", robot(
        link("a"), link("b", mass=0.5, xyz="0 0 0.1", I=(1, 2, 3)),
        revolute("hinge", "a", "b", xyz="0 0 0.3", axis="0 1 0", kind="prismatic")
        .replace("<axis", '<limit lower="-1" upper="1" effort="1" velocity="1"/><axis'),
    ))  # fmt: skip
    conv = to_system(read_model(p), {"hinge": 0.05}, lock=["hinge"])
    T = conv.link_pose["b"]
    np.testing.assert_allclose(T[:3, 3], [0.0, 0.05, 0.3], atol=1e-15)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-15)


# -- the default suite --------------------------------------------------------------------------


def test_the_default_suite_and_catalog_load_without_the_robots_extra(monkeypatch):
    """No model package installed (the README's quickstart installs the engines only): the
    default suite, --all and the catalog still load; the library's scenarios of optional
    models are not read for them."""
    from reports.suite import catalog, resolve_scenarios
    from scenarios.models import library

    monkeypatch.delenv("EXAMPLE_ROBOT_DATA_DIR", raising=False)
    monkeypatch.setattr(library, "_erd_roots", lambda: [])
    with pytest.raises(Exception, match="not found in example-robot-data"):
        scenarios.load("go2_float")  # the package is out of reach
    assert "arm3_swing" in [s.name for s in resolve_scenarios([])]
    assert "arm3_swing" in [s.name for s in resolve_scenarios([], all_=True)]
    assert any(s["name"] == "arm3_swing" for s in catalog()["scenarios"])


def test_the_default_suite_runs_a_shipped_robot_model():
    # a robot scenario in the default suite needs no optional package: its model ships with the
    # suite (scenarios/robots/models), and its runs fit the default suite's budget (test_scenarios:
    # each run <= ~3e4 steps)
    from reports.suite import catalog, resolve_scenarios

    assert scenarios.default_robots() == ["arm3_swing"]
    sc = scenarios.load("arm3_swing")
    assert Path(sc.model.path).resolve().parent == MODELS.resolve()
    assert round(sc.t_end / sc.dt) <= 30_000 and not sc.dt_sweep
    assert "arm3_swing" in [s.name for s in resolve_scenarios([])]
    entry = next(s for s in catalog()["scenarios"] if s["name"] == "arm3_swing")
    assert entry["default"]


def test_a_robot_scenario_has_one_hash_wherever_its_files_lie(tmp_path):
    """The same robot scenario read from another checkout (a CI machine's fresh clone) has
    the baseline's identity: its hash counts the model file's content, not its path; a
    changed model file changes it."""
    import shutil

    here = scenarios.load("arm3_swing")
    (tmp_path / "models").mkdir()
    shutil.copy(scenarios.robots_path() / "arm3_swing.toml", tmp_path)
    shutil.copy(MODELS / "arm3.urdf", tmp_path / "models")
    there = scenarios.load(tmp_path / "arm3_swing.toml")
    assert there.model.path != here.model.path
    assert there.scenario_hash == here.scenario_hash
    urdf = tmp_path / "models" / "arm3.urdf"
    urdf.write_text(urdf.read_text().replace('mass value="', 'mass value="1', 1))
    assert scenarios.load(tmp_path / "arm3_swing.toml").scenario_hash != here.scenario_hash
