"""Contact in scenario files: the library's contact scenes load and their closed forms say what
their descriptions say; the suite's contact geometry against brute force (vertices, sampled
surfaces); every bad input named by file, field, value and rule."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

import scenarios
from references.exact.contact_scene import contact_motion
from scenarios.contact import Plane, Shape, body_distance, lowest_point, plane_distance
from scenarios.schema import ScenarioError, rotation_from_vector
from scenarios.system_file import validate

RNG = np.random.default_rng(35)


def _rot():
    return rotation_from_vector(RNG.normal(size=3))


# -- geometry against brute force --------------------------------------------------------------


def _box_vertices(h, c, A):
    s = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    return c + (s * h) @ A.T


def test_plane_distance_box_is_its_lowest_vertex():
    h = np.array([0.1, 0.25, 0.05])
    shape = Shape(
        "box",
        half_extents=h,
        position=[0.01, -0.02, 0.03],
        rotation=rotation_from_vector([0.2, 0.1, -0.3]),
    )
    n = np.array([0.3, -0.2, 0.9])
    n /= np.linalg.norm(n)
    plane = Plane("p", n, [0.1, 0.2, -0.05])
    for _ in range(20):
        x, R = RNG.normal(size=3), _rot()
        c, A = x + R @ shape.position, R @ shape.rotation
        brute = np.min(_box_vertices(h, c, A) @ n) - n @ plane.point
        assert plane_distance(shape, plane, x, R)[0] == pytest.approx(brute, abs=1e-14)
        low = lowest_point(shape, plane, x, R)[0]
        assert low @ n - n @ plane.point == pytest.approx(brute, abs=1e-14)


@pytest.mark.parametrize("kind", ["capsule", "cylinder", "sphere"])
def test_plane_distance_round_shapes_against_sampled_surfaces(kind):
    shape = Shape(kind, radius=0.07, half_length=0.12 if kind != "sphere" else 0.0)
    plane = Plane("p", np.array([0.0, 0.0, 1.0]), np.zeros(3))
    u = np.linspace(0, 2 * np.pi, 4001)
    circle = np.stack([np.cos(u), np.sin(u), 0 * u], axis=1) * 0.07
    for _ in range(10):
        x, R = RNG.normal(size=3), _rot()
        if kind == "cylinder":  # rim circles at both ends
            pts = np.concatenate([circle + [0, 0, s * 0.12] for s in (-1, 1)]) @ R.T + x
            brute = pts[:, 2].min()
            tol = 0.07 * (1 - math.cos(np.pi / 4000)) + 1e-14  # the sampling's sag
        else:  # a sphere (of radius r) swept along the segment: lowest end minus r
            ends = [x + R @ [0, 0, s * shape.half_length] for s in (-1, 1)]
            brute = min(e[2] for e in ends) - 0.07
            tol = 1e-14
        assert plane_distance(shape, plane, x, R)[0] == pytest.approx(brute, abs=tol)


def test_box_box_distance_by_separating_axes():
    """Overlapping boxes: the SAT depth is the smallest translation along the 15 axes that
    separates them; checked on axis-aligned cases by hand and on random ones by moving the
    second box along the reported axis... here: the depth of a box sunk into another, and the
    gap of two apart along an axis."""
    h = np.array([0.1, 0.1, 0.1])
    s = Shape("box", half_extents=h)
    I = np.eye(3)[None]
    for dz in (0.25, 0.2, 0.19, 0.15):
        d = body_distance(s, [[0, 0, 0]], I, s, [[0.03, -0.02, dz]], I)[0]
        assert d == pytest.approx(dz - 0.2, abs=1e-15)
    # a box turned 45 degrees about z on top of another: edge-face, gap along z
    R45 = rotation_from_vector([0, 0, math.pi / 4])[None]
    d = body_distance(s, [[0, 0, 0]], I, s, [[0, 0, 0.21]], R45)[0]
    assert d == pytest.approx(0.01, abs=1e-15)
    # edge on edge: the lower box's top edge along y, the upper box's bottom edge along x;
    # the separating axis is their cross product (z)
    Ra = rotation_from_vector([0, math.pi / 4, 0])[None]
    Rb = rotation_from_vector([math.pi / 4, 0, 0])[None]
    for gap in (0.01, -0.004):
        top = [[0.0, 0.0, 0.2 * math.sqrt(2) + gap]]
        assert body_distance(s, [[0, 0, 0]], Ra, s, top, Rb)[0] == pytest.approx(gap, abs=1e-14)
    # a box standing on a corner: its lowest vertex sqrt(3) h below its centre
    tilt = math.acos(1 / math.sqrt(3))
    Rc = rotation_from_vector(np.array([1.0, -1.0, 0.0]) / math.sqrt(2) * tilt)
    top = np.array([[0, 0, 0.1 + 0.1 * math.sqrt(3) - 0.004]])
    d = body_distance(s, [[0, 0, 0]], I, s, top, Rc[None])[0]
    assert d == pytest.approx(-0.004, abs=1e-12)


def test_sphere_box_distance():
    b = Shape("box", half_extents=np.array([0.1, 0.2, 0.3]))
    sp = Shape("sphere", radius=0.05)
    I = np.eye(3)[None]
    for p, want in (
        ([0, 0, 0.36], 0.01),
        ([0.15, 0.25, 0.0], math.hypot(0.05, 0.05) - 0.05),
        ([0.0, 0.0, 0.28], -0.07),
    ):
        assert body_distance(b, [[0, 0, 0]], I, sp, [p], I)[0] == pytest.approx(want, abs=1e-15)
        assert body_distance(sp, [p], I, b, [[0, 0, 0]], I)[0] == pytest.approx(want, abs=1e-15)


# -- the library ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", scenarios.list_contact())
def test_library_contact_scenes(name):
    sc = scenarios.load(name)
    assert sc.has_contact and scenarios.is_library_file(sc)
    t = np.linspace(0.0, sc.t_end, 11)
    m = contact_motion(sc, t)
    # the reference starts at the file's state
    assert np.allclose(m.x[0], [b.position for b in sc.bodies], atol=1e-15)
    assert np.allclose(m.R[0], [b.rotation for b in sc.bodies], atol=1e-15)
    assert np.allclose(m.v[0], [b.velocity for b in sc.bodies], atol=1e-15)
    tags = set(sc.tags)
    if "stick" in tags:
        assert m.facts["sticks"] and np.all(m.x == m.x[0])
    if "slide" in tags and "sticks" in m.facts:
        assert not m.facts["sticks"] and m.facts["slide_distance"] > 0.1
    if "roll" in tags:
        assert m.facts["rolls"]
    if "slide" in tags and "rolls" in m.facts:
        assert not m.facts["rolls"]
    # the touching pairs stay in contact (or above) along the closed form
    from scenarios.contact import pair_distance

    for pair in sc.contacts:
        gap = pair_distance(sc, pair, m.x, m.R)
        assert np.all(gap >= -1e-12), (pair.a, pair.b, gap.min())


def test_hashes_of_scenes_without_contact_unchanged():
    """Adding contact fields to the system schema leaves the other scenarios' identity alone:
    their to_dict has no contact key."""
    sc = scenarios.load("four_bar")
    d = sc.to_dict()
    assert not {"planes", "contacts", "forces"} & set(d)
    assert all("shape" not in b for b in d["bodies"])


# -- bad input -------------------------------------------------------------------------------------


def _data(name="box_resting"):
    with open(scenarios.contact_path() / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def _problems(data):
    with pytest.raises(ScenarioError) as err:
        validate(data, path="my_scene.toml")
    msg = str(err.value)
    assert msg.startswith("invalid scenario file my_scene.toml")
    return {f: (v, rule) for f, v, rule in err.value.problems}, msg


def test_penetration_at_start_named():
    d = _data()
    d["bodies"][0]["position"] = [0.0, 0.0, 0.097]
    probs, msg = _problems(d)
    v, rule = probs["contacts[0].pair"]
    assert v == ["block", "ground"]
    assert "penetrates plane 'ground' by 0.003 m at t = 0" in rule and "1e-09" in rule
    d = _data("box_stack")
    d["bodies"][2]["position"] = [0.05, 0.0, 0.45]
    probs, _ = _problems(d)
    assert "penetrates body 'cube1' by 0.05 m" in probs["contacts[2].pair"][1]


@pytest.mark.parametrize(
    "edit, field, value, words",
    [
        (lambda d: d["contacts"][0].update(mu=-0.1), "contacts[0].mu", -0.1, ">= 0"),
        (lambda d: d["contacts"][0].update(e=1.5), "contacts[0].e", 1.5, "in [0, 1]"),
        (lambda d: d["contacts"][0].update(e=-0.2), "contacts[0].e", -0.2, "in [0, 1]"),
        (
            lambda d: d["contacts"][0].update(pair=["block", "floor"]),
            "contacts[0].pair",
            ["block", "floor"],
            "neither a body nor a plane",
        ),
        (
            lambda d: d["contacts"][0].update(pair=["ground", "ground"]),
            "contacts[0].pair",
            ["ground", "ground"],
            "two planes never touch",
        ),
        (
            lambda d: d["planes"][0].update(normal=[0.0, 0.0, 2.0]),
            "planes[0].normal",
            [0.0, 0.0, 2.0],
            "unit vector",
        ),
        (
            lambda d: d["bodies"][0]["shape"].update(kind="cone"),
            "bodies[0].shape.kind",
            "cone",
            "sphere, box, capsule, cylinder",
        ),
        (
            lambda d: d["bodies"][0]["shape"].update(half_extents=[0.1, 0.0, 0.1]),
            "bodies[0].shape.half_extents",
            [0.1, 0.0, 0.1],
            "> 0",
        ),
        (
            lambda d: d["bodies"][0]["shape"].update(radius=0.1),
            "bodies[0].shape.radius",
            0.1,
            "a box takes only half_extents",
        ),
        (
            lambda d: d.update(forces=[{"body": "ghost", "force": [1.0, 0.0, 0.0]}]),
            "forces[0].body",
            "ghost",
            "not a body",
        ),
        (
            lambda d: d["contacts"].append({"pair": ["ground", "block"], "mu": 0.2}),
            "contacts[1].pair",
            ["ground", "block"],
            "listed twice",
        ),
        (
            lambda d: d["reference"].update(kind="numerical"),
            "reference.kind",
            "numerical",
            "contact closed form",
        ),
        (  # a misspelt body: the hint, and its body not also "joined to nothing"
            lambda d: d["contacts"][0].update(pair=["blok", "ground"]),
            "contacts[0].pair",
            ["blok", "ground"],
            "(did you mean 'block'?)",
        ),
        (  # a misspelt kind: the hint, and not also "takes a contact closed form"
            lambda d: d["reference"].update(kind="slidng_block"),
            "reference.kind",
            "slidng_block",
            "(did you mean 'sliding_block'",
        ),
        (
            lambda d: d["contacts"][0].update(friction=0.3),
            "contacts[0].friction",
            0.3,
            "unknown key",
        ),
    ],
)
def test_bad_contact_input(edit, field, value, words):
    d = _data()
    edit(d)
    probs, msg = _problems(d)
    assert field in probs, msg
    v, rule = probs[field]
    assert v == value and words in rule, (v, rule)
    assert f"{field} = {value!r}" in msg
    # that problem alone: a refused pair, plane or shape does not also make its body 'joined
    # to nothing', the file one 'without [[contacts]]' (both were reported with mu < 0), a
    # pair's plane 'neither a body nor a plane' or its body one 'without [bodies.shape]';
    # a pair of two planes names no body, whose block then touches nothing indeed
    others = sorted(set(probs) - {field})
    assert others == (["bodies[0].name"] if value == ["ground", "ground"] else []), msg


def test_contact_kind_without_contacts_refused():
    d = _data()
    d.pop("contacts")
    probs, _ = _problems(d)
    assert "needs [[contacts]]" in probs["reference.kind"][1]


def test_body_body_pair_geometry_refused():
    d = _data("box_stack")
    d["bodies"][2]["shape"] = {"kind": "capsule", "radius": 0.1, "half_length": 0.05}
    probs, _ = _problems(d)
    assert "box-capsule pair is not measured" in probs["contacts[2].pair"][1]
