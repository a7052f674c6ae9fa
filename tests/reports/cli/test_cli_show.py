"""``director-bench show``: checks files as ``run`` does and prints what they hold, running
and writing nothing; an invalid file exits 2 with the file, field, value and rule."""

from __future__ import annotations

import os

from reports.cli import main

BOX = """\
name = "my_box"
description = "A thrown box."

[body]
mass = 3.0
inertia = [0.0125, 0.025, 0.0325]

[initial]
quaternion_wxyz = [0.9, 0.3, 0.1, 0.3]
omega_body = [0.2, 5.0, 0.3]
velocity = [1.0, 0.0, 4.0]

[environment]
gravity = [0.0, 0.0, -9.81]

[run]
t_end = 1.0
dt = 2e-3
"""


def _run(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_show_a_user_file_and_a_library_system(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "box.toml"
    path.write_text(BOX)
    code, out, err = _run(["show", str(path), "four_bar"], capsys)
    assert code == 0, err
    assert f"my_box ({path}): valid" in out
    assert "one free body: mass 3 kg" in out
    assert "(500 steps)" in out  # 1.0 / 2e-3
    assert "reference: free_body (asked: auto)" in out
    # the four-bar: every joint, the ground named, the loop closure, its exact reference
    assert "loop closures: B1" in out and "joint A0: revolute crank - ground" in out
    assert "reference: four_bar" in out
    assert sorted(os.listdir(tmp_path)) == ["box.toml"]  # nothing written


def test_show_refuses_an_invalid_file(tmp_path, capsys):
    path = tmp_path / "box.toml"
    path.write_text(BOX.replace("mass = 3.0", "mass = -3.0"))
    code, out, err = _run(["show", str(path)], capsys)
    assert code == 2 and out == ""
    assert str(path) in err and "body.mass = -3.0: the mass must be > 0 kg" in err


def test_show_refuses_a_reference_that_does_not_apply(tmp_path, capsys):
    path = tmp_path / "box.toml"
    path.write_text(BOX + '\n[reference]\nkind = "lagrange_top"\n')
    code, _, err = _run(["show", str(path)], capsys)
    assert code == 2 and "reference.kind = 'lagrange_top'" in err


def test_show_refuses_what_run_refuses_before_planning(tmp_path, capsys):
    """A tolerance for a family no engine registers, an engine setting no builder takes."""
    path = tmp_path / "box.toml"
    path.write_text(BOX + '\n[tolerances."4th order"]\nattitude_error_max = 1e-6\n')
    code, _, err = _run(["show", str(path)], capsys)
    assert code == 2 and "unknown integrator families ['4th order']" in err
    system = tmp_path / "four_bar.toml"
    import scenarios

    text = open(scenarios.load("four_bar").path).read().replace('"four_bar"', '"my_bar"', 1)
    system.write_text(text + "\n[engine_settings.mujoco]\nsolreff = [0.004, 1.0]\n")
    code, _, err = _run(["show", str(system)], capsys)
    assert code == 2 and "engine_settings.mujoco.solreff" in err


def test_show_lists_a_systems_force_elements(capsys):
    """Andrews' squeezer (IFToMM A03): its motor torque of 0.033 N m on joint O and its spring
    of c0 = 4530 N/m, l0 = 0.07785 m, undamped, from the triangle to the ground (the
    benchmark's parameters, as its file states them)."""
    code, out, err = _run(["show", "iftomm_a03"], capsys)
    assert code == 0, err
    assert "    torque 0.033 N m on joint O" in out
    assert (
        "    spring spring: triangle - ground, stiffness 4530 N/m, damping 0 N s/m, "
        "rest length 0.07785 m" in out
    )
