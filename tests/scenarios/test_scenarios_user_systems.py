"""A new user's own system files (a three-link chain given by joint coordinates, a
parallelogram loop given by body states): each mistake is refused by ``scenarios.load`` with
the file, the dotted field, the value and the rule, and nothing is repaired."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenarios
from scenarios import ScenarioError

CHAIN = """\
name = "my_chain3"
description = "Three links: revolute, spherical, revolute, under gravity."

[[bodies]]
name = "l1"
mass = 1.2
inertia = [0.03, 0.031, 0.003]

[[bodies]]
name = "l2"
mass = 0.8
inertia = [0.02, 0.022, 0.002]

[[bodies]]
name = "l3"
mass = 0.5
inertia = [0.01, 0.012, 0.0025]

[[joints]]
name = "hip"
kind = "revolute"
body_a = "l1"
body_b = "ground"
anchor_a = [0.0, 0.0, 0.3]
anchor_b = [0.0, 0.0, 0.0]
axis_a = [0.0, 1.0, 0.0]
axis_b = [0.0, 1.0, 0.0]
angle = 0.7
rate = 0.3

[[joints]]
name = "knee"
kind = "spherical"
body_a = "l1"
body_b = "l2"
anchor_a = [0.0, 0.0, -0.3]
anchor_b = [0.0, 0.0, 0.25]
rotation_vector = [0.2, -0.4, 0.1]
omega = [0.5, 1.0, -2.0]

[[joints]]
name = "ankle"
kind = "revolute"
body_a = "l2"
body_b = "l3"
anchor_a = [0.0, 0.0, -0.25]
anchor_b = [0.0, 0.0, 0.2]
axis_a = [1.0, 0.0, 0.0]
axis_b = [1.0, 0.0, 0.0]
angle = -0.5
rate = 1.5

[environment]
gravity = [0.0, 0.0, -9.81]

[run]
t_end = 1.0
dt = 1e-3
"""


def _load(tmp_path, text):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    return path, scenarios.load(str(path))


def _problems(tmp_path, text):
    path = tmp_path / "mine.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as err:
        scenarios.load(str(path))
    assert str(path) in str(err.value)
    return err.value.problems


def _edit(old, new, text=CHAIN):
    assert old in text
    return text.replace(old, new, 1)


def test_the_chain_loads_with_its_joints_holding(tmp_path):
    _, sc = _load(tmp_path, CHAIN)
    assert list(sc.body_names) == ["l1", "l2", "l3"]
    # independent forward kinematics of the first hinge: l1 turned by 0.7 rad about world y
    # from hanging straight down, its pivot at the origin 0.3 m above its centre of mass
    c, s = math.cos(0.7), math.sin(0.7)
    Ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    b1 = sc.bodies[0]
    np.testing.assert_allclose(b1.rotation, Ry, atol=1e-15)
    np.testing.assert_allclose(b1.position, -Ry @ [0, 0, 0.3], atol=1e-15)
    np.testing.assert_allclose(b1.omega_body, [0, 0.3, 0], atol=1e-15)


def test_the_ground_on_side_a_is_refused_with_the_way_out(tmp_path):
    text = _edit('body_a = "l1"\nbody_b = "ground"', 'body_a = "ground"\nbody_b = "l1"')
    probs = _problems(tmp_path, text)
    assert len(probs) == 1
    field, value, rule = probs[0]
    assert (field, value) == ("joints[0].body_a", "ground")
    assert "always body_b" in rule and "swap" in rule


@pytest.mark.parametrize(
    "old, new, field, value, words",
    [
        ('kind = "spherical"', 'kind = "ball"', "joints[1].kind", "ball", "must be one of"),
        ('body_b = "l3"', 'body_b = "l4"', "joints[2].body_b", "l4", "not a body of this file"),
        ("mass = 0.8", "mass = -0.8", "bodies[1].mass", -0.8, "> 0"),
        ("[0.02, 0.022, 0.002]", "[0.02, 0.022, 0.0]", "bodies[1].inertia", [0.02, 0.022, 0.0],
         "> 0"),
        ("axis_a = [1.0, 0.0, 0.0]\n", "", "joints[2].axis_a", "<missing>", "required"),
        ("axis_a = [1.0, 0.0, 0.0]", "axis_a = [0.0, 0.0, 0.0]", "joints[2].axis_a",
         [0.0, 0.0, 0.0], "non-zero"),
        ("rotation_vector = [0.2, -0.4, 0.1]", "angle = 0.3", "joints[1].angle", 0.3,
         "rotation_vector and omega"),
        ("dt = 1e-3", "dt = 7e-3", "run.dt", 7e-3, "whole number of steps"),
        ('name = "l3"', 'name = "l2"', "bodies[2].name", "l2", "unique"),
    ],
)  # fmt: skip
def test_each_mistake_names_its_field_value_and_rule(tmp_path, old, new, field, value, words):
    probs = _problems(tmp_path, _edit(old, new))
    hit = [p for p in probs if p[0] == field]
    assert hit, probs
    assert hit[0][1] == value and words in hit[0][2]
