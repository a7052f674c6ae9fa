"""Hostile system inputs end in a clear error naming the field, the value and the rule, or in
the right result (issue 32, item 8): a joint angle of 1e300, a joint rate of 1e8 rad/s, a
four-bar with all links on one line at rest at t = 0, a body joined to nothing, chains of
hundreds and thousands of bodies (their cost and memory announced before any run, MuJoCo's
model built without recursion)."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

import scenarios
from references.exact.multibody import ReferenceCostExceeded, solve
from references.exact.multibody.loops import system_from_world
from reports.suite import check_singular, warn_costs
from scenarios.schema import ScenarioError
from scenarios.system_file import validate_system


def chain(n: int, angle: float = 1.0, rate: float = 0.5, t_end: float = 1.0) -> dict:
    """A planar chain of n 0.5 m links hanging from a hinge, by joint coordinates."""
    inertia = [0.021833333333333333, 0.02283333333333333, 0.002]
    bodies = [{"name": f"link{i}", "mass": 1.0, "inertia": inertia} for i in range(n)]
    joints = []
    for i in range(n):
        j = {"name": f"hinge{i}", "kind": "revolute", "axis_a": [0.0, 1.0, 0.0],
             "axis_b": [0.0, 1.0, 0.0], "angle": angle if i == 0 else 0.1,
             "rate": rate if i == 0 else 0.0}  # fmt: skip
        if i == 0:
            j |= {"body_a": "link0", "body_b": "ground", "anchor_a": [0.0, 0.0, 0.25],
                  "anchor_b": [0.0, 0.0, 0.0]}  # fmt: skip
        else:
            j |= {"body_a": f"link{i - 1}", "body_b": f"link{i}",
                  "anchor_a": [0.0, 0.0, -0.25], "anchor_b": [0.0, 0.0, 0.25]}  # fmt: skip
        joints.append(j)
    return {"name": f"chain{n}", "description": "hostile", "bodies": bodies, "joints": joints,
            "environment": {"gravity": [0.0, 0.0, -9.81]},
            "run": {"t_end": t_end, "dt": 1e-3, "save_every": 10}}  # fmt: skip


def problems(data) -> dict:
    with pytest.raises(ScenarioError) as err:
        validate_system(data)
    return {f: (v, rule) for f, v, rule in err.value.problems}


def test_a_joint_angle_of_1e300_is_refused_with_its_field():
    p = problems(chain(3, angle=1e300))
    value, rule = p["joints[0].angle"]
    assert value == 1e300 and "at most 1000 rad" in rule and "1e+300 rad" in rule
    # and a body's rotation vector likewise
    d = tomllib.loads((scenarios.systems_path() / "four_bar.toml").read_text())
    body = d["bodies"][0]
    del body["rotation"]
    body["rotation_vector"] = [0.0, 1e300, 0.0]
    assert "bodies[0].rotation_vector" in problems(d)


def test_a_joint_rate_of_1e8_is_refused_before_any_run():
    value, rule = problems(chain(3, rate=1e8))["run.dt"]
    assert value == 1e-3 and "1e+05 rad in one step" in rule and "at most pi" in rule


def test_a_body_joined_to_nothing_is_refused():
    d = chain(2)
    d["bodies"].append({"name": "stray", "mass": 1.0, "inertia": [0.1, 0.1, 0.1],
                        "position": [5.0, 0.0, 0.0]})  # fmt: skip
    # per-body states are needed for a body no joint places
    with pytest.raises(ScenarioError) as err:
        validate_system(d)
    assert any(f == "bodies[2].name" and "joined to nothing" in r
               for f, _, r in err.value.problems)  # fmt: skip


def _flat_four_bar():
    """The library four-bar turned to theta = pi/2, all links on the x axis, at rest."""
    from references.exact.multibody.exact import ParallelogramFourBar

    d = tomllib.loads((scenarios.systems_path() / "four_bar.toml").read_text())
    P, by = d["reference"], {b["name"]: b for b in d["bodies"]}
    parts = [(by[n]["mass"], by[n]["inertia"]) for n in ("crank", "rocker", "coupler")]
    m = ParallelogramFourBar(P["L"], P["D"], *parts, P["LA"], P["LB"], P["coupler_com"],
                             9.81, 0.5 * math.pi, 0.0)  # fmt: skip
    x, R, _, _ = m.initial
    for i, n in enumerate(m.names):
        by[n]["position"], by[n]["rotation"] = x[i].tolist(), R[i].tolist()
        by[n]["velocity"], by[n]["omega_body"] = [0.0] * 3, [0.0] * 3
    d["reference"] = {"kind": "numerical"}
    d["tags"] = []
    return validate_system(d)


def test_a_four_bar_with_all_links_on_one_line_at_t0_is_refused():
    """It was "Newton did not converge; reduce dt" (dt/20 too); the truth is a singular
    configuration at t = 0: the closure joint named, the rule stated."""
    sc = _flat_four_bar()
    with pytest.raises(ScenarioError) as err:
        check_singular([sc])
    ((field, value, rule),) = err.value.problems
    assert field == "joints[3]" and value == "B1"
    assert "singular configuration at t = 0" in rule


def test_regular_loops_are_not_singular():
    for name in ("four_bar", "bricard", "slider_crank_spatial", "iftomm_a02_n2"):
        check_singular([scenarios.load(name)])


def test_the_reference_refuses_at_once_beyond_its_bound():
    sc = validate_system(chain(30, t_end=5.0))
    system, q0, u0 = system_from_world(sc.bodies, sc.joints, sc.gravity)
    t = np.linspace(0.0, 5.0, 11)
    with pytest.raises(ReferenceCostExceeded, match=r"estimated .* s \(.*\), beyond its bound"):
        solve(system.tree, q0, u0, t, system=system, max_wall=0.01)


def test_costly_references_are_announced_with_the_number(monkeypatch, capsys):
    import reports.suite as suite

    monkeypatch.setattr(suite, "COST_WARNING_S", 0.0)
    lines = warn_costs([validate_system(chain(20, t_end=2.0)), scenarios.load("four_bar")])
    assert len(lines) == 1  # the four-bar has a closed form: nothing to announce
    assert "chain20" in lines[0] and "will take about" in lines[0]
    assert "note:" in capsys.readouterr().err


@pytest.mark.parametrize("n", [300, 2000])
def test_mujoco_builds_a_300_body_chain_and_names_its_limit_at_2000(n):
    """The MJCF nests a chain's bodies: written leaves first, not by recursion (2000 deep
    raised RecursionError). MuJoCo compiles 300; its MJCF reader refuses nesting beyond about
    500 elements, so 2000 is unsupported with that reason."""
    mujoco = pytest.importorskip("mujoco")
    from references.engines.mujoco import mjcf
    from references.engines.mujoco import system as ms
    from references.errors import Unsupported

    sc = validate_system(chain(n))
    pl = ms.plan(sc)
    args = (sc, pl, "RK4", 1e-3, (0.02, 1.0), (0.9, 0.95, 0.001, 0.5, 2.0))
    if n > mjcf.MJCF_MAX_DEPTH:
        with pytest.raises(Unsupported, match="nests 2000 bodies deep.*XML_ELEMENT_DEPTH"):
            ms.model_xml(*args)
        return
    m = mujoco.MjModel.from_xml_string(ms.model_xml(*args))
    assert m.nbody == n + 1 and m.njnt == n
