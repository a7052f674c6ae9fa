"""Initial states of a tree given by joint coordinates (scenarios/system.py, _tree_states).

Expected states are computed here by hand with scipy's Rotation (not through the code under
test); the anchors' positions and velocities are checked by their own formulas here too.
"""

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from scenarios.schema import ScenarioError
from scenarios.system_file import load_file, validate_system

ROOT = Path(__file__).resolve().parents[2]
SYSTEMS = ROOT / "scenarios" / "systems"

# Round-off bound: states of order 1 (m, rad/s, m/s) built by two or three rotations and
# cross products of order-1 numbers; a few ulps (2.2e-16 each) per step.
TOL = 1e-14

PIVOT = np.array([0.1, -0.2, 0.3])
S1_TOP, S1_BOT = np.array([0.0, 0.0, 0.5]), np.array([0.02, 0.0, -0.5])
S2_TOP = np.array([0.0, 0.01, 0.45])
AX1 = np.array([0.0, 1.0, 0.0])  # hinge axis in body 1's frame
AX2 = np.array([1.0, 2.0, 0.5]) / math.sqrt(5.25)  # the same hinge in body 2's frame
PHI = np.array([0.4, -0.3, 0.2])  # spherical joint: body 1 relative to the ground
OMEGA = np.array([0.7, 0.1, -0.5])  # rad/s, world (the ground's axes)
ANGLE, RATE = 0.8, -1.3


def _base() -> dict:
    """A 3-D double pendulum: body 1 on a spherical joint to the ground, body 2 on a
    revolute joint whose axis differs in the two bodies' frames; no body state."""
    return {
        "name": "jc_double",
        "description": "double pendulum given by joint coordinates",
        "bodies": [
            {"name": "upper", "mass": 1.0, "inertia": [0.09, 0.09, 0.02]},
            {"name": "lower", "mass": 0.8, "inertia": [0.06, 0.07, 0.02]},
        ],
        "joints": [
            {"name": "shoulder", "kind": "spherical", "body_a": "upper", "body_b": "ground",
             "anchor_a": S1_TOP.tolist(), "anchor_b": PIVOT.tolist(),
             "rotation_vector": PHI.tolist(), "omega": OMEGA.tolist()},
            {"name": "elbow", "kind": "revolute", "body_a": "upper", "body_b": "lower",
             "anchor_a": S1_BOT.tolist(), "anchor_b": S2_TOP.tolist(),
             "axis_a": AX1.tolist(), "axis_b": AX2.tolist(), "angle": ANGLE, "rate": RATE},
        ],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        "run": {"t_end": 0.1, "dt": 1e-3},
    }  # fmt: skip


def _by_hand():
    """World x, R, v, w (world) of both bodies, by hand."""
    R1 = Rotation.from_rotvec(PHI).as_matrix()
    w1 = OMEGA
    x1 = PIVOT - R1 @ S1_TOP
    v1 = -np.cross(w1, R1 @ S1_TOP)
    # angle 0: the smallest rotation taking body 2's axis onto body 1's (scipy's own)
    Q0 = Rotation.align_vectors([AX1], [AX2])[0].as_matrix()
    R2 = R1 @ Rotation.from_rotvec(ANGLE * AX1).as_matrix() @ Q0
    w2 = w1 + RATE * (R1 @ AX1)
    elbow = x1 + R1 @ S1_BOT
    x2 = elbow - R2 @ S2_TOP
    v_elbow = v1 + np.cross(w1, R1 @ S1_BOT)
    v2 = v_elbow - np.cross(w2, R2 @ S2_TOP)
    return [(x1, R1, v1, w1), (x2, R2, v2, w2)]


def _per_body(states) -> dict:
    d = _base()
    for tab in d["joints"]:
        for k in ("angle", "rate", "rotation_vector", "omega"):
            tab.pop(k, None)
    for tab, (x, R, v, w) in zip(d["bodies"], states, strict=True):
        tab.update(position=x.tolist(), rotation=R.tolist(), velocity=v.tolist(),
                   omega_body=(R.T @ w).tolist())  # fmt: skip
    return d


def test_hand_q0_is_the_smallest_rotation():
    # the hand computation's zero: aligns the axes, by the angle between them
    Q0 = Rotation.align_vectors([AX1], [AX2])[0]
    assert np.allclose(Q0.apply(AX2), AX1, atol=1e-15)
    assert math.isclose(Q0.magnitude(), math.acos(float(AX1 @ AX2)), abs_tol=1e-12)


def test_double_pendulum_equals_per_body_file():
    sc = validate_system(_base())
    ref = validate_system(_per_body(_by_hand()))
    assert sc.body_names == ref.body_names
    for b, r in zip(sc.bodies, ref.bodies, strict=True):
        for k in ("position", "rotation", "velocity", "omega_body", "inertia"):
            assert np.max(np.abs(getattr(b, k) - getattr(r, k))) < TOL, (b.name, k)
        assert b.mass == r.mass
    # same form: the same fields, joints, tree
    assert sc.to_dict().keys() == ref.to_dict().keys()
    assert sc.tree_joints == ref.tree_joints and sc.loop_joints == ()
    assert [j.name for j in sc.joints] == [j.name for j in ref.joints]


def test_joints_hold_in_position_and_velocity():
    sc = validate_system(_base())
    up, lo = sc.bodies
    w = {b.name: b.rotation @ b.omega_body for b in sc.bodies}
    # shoulder: anchor at the pivot, at rest
    assert np.max(np.abs(up.position + up.rotation @ S1_TOP - PIVOT)) < TOL
    assert np.max(np.abs(up.velocity + np.cross(w["upper"], up.rotation @ S1_TOP))) < TOL
    # elbow: the anchor points coincide and move together
    pa, pb = up.position + up.rotation @ S1_BOT, lo.position + lo.rotation @ S2_TOP
    va = up.velocity + np.cross(w["upper"], up.rotation @ S1_BOT)
    vb = lo.velocity + np.cross(w["lower"], lo.rotation @ S2_TOP)
    assert np.max(np.abs(pa - pb)) < TOL
    assert np.max(np.abs(va - vb)) < TOL
    # hinge: axes aligned, relative angular velocity along the axis with the given rate
    ua, ub = up.rotation @ AX1, lo.rotation @ AX2
    assert np.max(np.abs(ua - ub)) < TOL
    assert np.max(np.abs(w["lower"] - w["upper"] - RATE * ua)) < TOL
    # the given angle: body 2 turned by ANGLE about the hinge from its angle-0 attitude
    Q0 = Rotation.align_vectors([AX1], [AX2])[0].as_matrix()
    rel = Rotation.from_matrix(up.rotation.T @ lo.rotation @ Q0.T).as_rotvec()
    assert np.max(np.abs(rel - ANGLE * AX1)) < TOL


def test_floating_root_takes_its_world_state():
    d = _base()
    d["joints"].pop(0)
    d["bodies"][0].update(position=[1.0, 2.0, 3.0], rotation_vector=[0.1, 0.2, -0.3],
                          velocity=[0.5, 0.0, -0.2], omega_body=[0.3, -0.4, 0.9])  # fmt: skip
    sc = validate_system(d)
    R1 = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()
    w1 = R1 @ np.array([0.3, -0.4, 0.9])
    v1 = np.array([0.5, 0.0, -0.2])
    up, lo = sc.bodies
    assert np.max(np.abs(up.rotation - R1)) < TOL
    assert np.max(np.abs(up.position - [1.0, 2.0, 3.0])) == 0.0
    Q0 = Rotation.align_vectors([AX1], [AX2])[0].as_matrix()
    R2 = R1 @ Rotation.from_rotvec(ANGLE * AX1).as_matrix() @ Q0
    w2 = w1 + RATE * (R1 @ AX1)
    x2 = up.position + R1 @ S1_BOT - R2 @ S2_TOP
    v2 = v1 + np.cross(w1, R1 @ S1_BOT) - np.cross(w2, R2 @ S2_TOP)
    assert np.max(np.abs(lo.rotation - R2)) < TOL
    assert np.max(np.abs(lo.position - x2)) < TOL
    assert np.max(np.abs(lo.velocity - v2)) < TOL
    assert np.max(np.abs(lo.rotation @ lo.omega_body - w2)) < TOL
    assert sc.floating


def test_planar_chain_4_by_joint_angles_matches_the_library_file():
    # the library file's states were written from the links' absolute angles 0.9, 0.4,
    # -0.3, 0.6 rad; relative hinge angles are their differences
    path = SYSTEMS / "planar_chain_4.toml"
    ref = load_file(path)
    d = tomllib.loads(path.read_text())
    for b in d["bodies"]:
        for k in ("position", "rotation", "velocity", "omega_body"):
            b.pop(k)
    for j, a in zip(d["joints"], [0.9, 0.4 - 0.9, -0.3 - 0.4, 0.6 + 0.3], strict=True):
        j["angle"] = a
    sc = validate_system(d)
    for b, r in zip(sc.bodies, ref.bodies, strict=True):
        assert np.max(np.abs(b.position - r.position)) < 1e-15
        assert np.max(np.abs(b.rotation - r.rotation)) < 1e-15
        assert np.max(np.abs(b.velocity)) == 0.0 and np.max(np.abs(b.omega_body)) == 0.0


def test_library_file_by_joint_coordinates():
    sc = load_file(SYSTEMS / "planar_chain_3_rates.toml")
    assert sc.is_tree and not sc.floating and "default" not in sc.tags
    # the link hinged to the ground: angle 1.0 from the downward vertical, rate 0.5 rad/s
    b = sc.bodies[0]
    R = Rotation.from_rotvec([0.0, 1.0, 0.0]).as_matrix()
    assert np.max(np.abs(b.rotation - R)) < TOL
    assert np.max(np.abs(b.position + R @ [0.0, 0.0, 0.25])) < TOL
    assert np.max(np.abs(b.omega_body - R.T @ [0.0, 0.5, 0.0])) < TOL


# -- refusals -------------------------------------------------------------------------------


def _problems(d, path="x.toml"):
    with pytest.raises(ScenarioError) as e:
        validate_system(d, path)
    assert path in str(e.value)
    return {f: (v, rule) for f, v, rule in e.value.problems}, str(e.value)


def test_both_forms_refused_naming_the_fields():
    d = _base()
    d["bodies"][1]["position"] = [0.0, 0.0, -1.0]
    d["bodies"][1]["omega_body"] = [0.0, 0.0, 1.0]
    probs, msg = _problems(d)
    assert set(probs) == {"bodies[1].position", "bodies[1].omega_body"}
    assert probs["bodies[1].position"][0] == [0.0, 0.0, -1.0]
    assert "never both" in probs["bodies[1].position"][1]
    assert "'elbow'" in probs["bodies[1].position"][1]


def test_grounded_root_takes_no_state():
    d = _base()
    d["bodies"][0]["rotation_vector"] = [0.1, 0.0, 0.0]
    probs, _ = _problems(d)
    assert set(probs) == {"bodies[0].rotation_vector"}


def test_loop_refused():
    d = tomllib.loads((SYSTEMS / "four_bar.toml").read_text())
    for b in d["bodies"]:
        for k in ("position", "rotation", "rotation_vector", "quaternion_wxyz", "velocity",
                  "omega_body"):  # fmt: skip
            b.pop(k, None)
    assert d["joints"][3]["name"] == "B1"  # the loop closure (test_system_suite)
    d["joints"][0]["angle"] = 0.3
    probs, _ = _problems(d)
    assert set(probs) == {"joints[3]"} and probs["joints[3]"][0] == "B1"
    assert "closes a loop" in probs["joints[3]"][1]
    # a coordinate on the loop-closing joint itself is named by its field
    d["joints"][3]["angle"] = 0.1
    probs, _ = _problems(d)
    assert set(probs) == {"joints[3].angle"} and probs["joints[3].angle"][0] == 0.1


def test_wrong_coordinates_kind_and_axes_refused_together():
    d = _base()
    d["joints"][1]["rotation_vector"] = [0.0, 0.1, 0.0]  # a revolute joint's are angle, rate
    d["joints"][0]["angle"] = 0.2  # a spherical joint's are rotation_vector, omega
    probs, _ = _problems(d)
    assert set(probs) == {"joints[1].rotation_vector", "joints[0].angle"}
    assert "angle and rate" in probs["joints[1].rotation_vector"][1]

    d = _base()
    d["joints"][1]["axis_b"] = (-AX1).tolist()
    d["joints"][1]["axis_a"] = AX1.tolist()
    probs, _ = _problems(d)
    assert set(probs) == {"joints[1].axis_b"} and "opposite" in probs["joints[1].axis_b"][1]

    d = _base()
    d["joints"][1]["kind"] = "universal"
    d["joints"][1].pop("angle")
    d["joints"][1].pop("rate")
    probs, _ = _problems(d)
    assert set(probs) == {"joints[1].kind"}


def test_floating_root_needs_its_position():
    d = _base()
    d["joints"].pop(0)
    probs, _ = _problems(d)
    assert probs == {"bodies[0].position": ("<missing>", probs["bodies[0].position"][1])}


def test_per_body_files_unchanged():
    # a per-body file still requires position (the joint-coordinate form alone relaxes it)
    d = _per_body(_by_hand())
    del d["bodies"][1]["position"]
    probs, _ = _problems(copy.deepcopy(d))
    assert "bodies[1].position" in probs
