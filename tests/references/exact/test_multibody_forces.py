"""Force elements in the reduced-coordinate reference (references/exact/multibody/loops.py)
and in a system file, checked against values the reference does not compute itself:
(a) the damped slider's closed form and the torqued hinge's tau t^2 / (2 I), with the
    reference's own error estimate above the error;
(b) a spatial arm (a hinge to the ground, a hinge between two bodies: torques on both, one
    of them internal; a spring from the tip to the ground) against director_model.system's
    RATTLE6, a formulation that shares nothing with it;
(c) energy: conserved without a damper, and with one the loss equals the dissipated work
    integral of c l'^2 along the reference's own motion (a quadrature of its output);
(d) the suite's treatment: the energy drift is not measured with a damper, the momenta not
    with an element to the ground, engines that do not apply force elements answer
    unsupported, a file's bad elements are refused by field.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from references.engines.director.system import force_elements, model
from references.engines.exact.system import reference
from references.engines.system import run_system
from references.errors import Unsupported
from references.trajectory import system_energy
from scenarios import force_elements as fe
from scenarios.schema import ScenarioError
from scenarios.system_file import validate_system


def slider_file(c: float = 0.6) -> dict:
    return {
        "name": "spring_slider",
        "description": "a slider on a level rail pulled by a spring-damper to a fixed point",
        "bodies": [{"name": "slider", "mass": 1.5, "inertia": [0.1, 0.1, 0.1],
                    "position": [1.0, 0.0, 0.0]}],
        "joints": [{"name": "rail", "kind": "prismatic", "body_a": "slider",
                    "body_b": "ground", "anchor_a": [0.0, 0.0, 0.0],
                    "anchor_b": [1.0, 0.0, 0.0], "axis_a": [1.0, 0.0, 0.0],
                    "axis_b": [1.0, 0.0, 0.0]}],
        "springs": [{"body_a": "slider", "body_b": "ground", "anchor_a": [0.0, 0.0, 0.0],
                     "anchor_b": [-2.0, 0.0, 0.0], "stiffness": 40.0, "damping": c,
                     "rest_length": 2.7}],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        "run": {"t_end": 3.0, "dt": 1e-3, "dt_sweep": [1e-3], "save_every": 10},
    }  # fmt: skip


def arm_file(c: float = 0.0, t_end: float = 2.0) -> dict:
    """An arm hinged to the ground about z (torque 0.2 N m), a rod hanging from its end on a
    hinge along (1, 0, 1) (torque -0.1 N m between the two: its reaction on the arm has a
    part along z that the arm's hinge does not hold), a spring from the rod's lower end to a
    world point; every initial velocity consistent with the joints by construction."""
    return {
        "name": "torqued_arm",
        "description": "an arm and a hanging rod with joint torques and a spring",
        "bodies": [
            {"name": "arm", "mass": 1.0, "inertia": [0.002, 0.0533, 0.0533],
             "position": [0.4, 0.0, 0.0], "velocity": [0.0, 0.8, 0.0],
             "omega_body": [0.0, 0.0, 2.0]},
            {"name": "rod", "mass": 0.5, "inertia": [0.015, 0.015, 0.001],
             "position": [0.8, 0.0, -0.3], "velocity": [0.0, 1.75, 0.0],
             "omega_body": [0.5, 0.0, 2.5]},
        ],
        "joints": [
            {"name": "h", "kind": "revolute", "body_a": "arm", "body_b": "ground",
             "anchor_a": [-0.4, 0.0, 0.0], "anchor_b": [0.0, 0.0, 0.0],
             "axis_a": [0.0, 0.0, 1.0], "axis_b": [0.0, 0.0, 1.0]},
            {"name": "k", "kind": "revolute", "body_a": "rod", "body_b": "arm",
             "anchor_a": [0.0, 0.0, 0.3], "anchor_b": [0.4, 0.0, 0.0],
             "axis_a": [1.0, 0.0, 1.0], "axis_b": [1.0, 0.0, 1.0]},
        ],
        "torques": [{"joint": "h", "torque": 0.2}, {"joint": "k", "torque": -0.1}],
        "springs": [{"name": "pull", "body_a": "rod", "body_b": "ground",
                     "anchor_a": [0.0, 0.0, -0.3], "anchor_b": [1.0, 0.5, -1.0],
                     "stiffness": 30.0, "damping": c, "rest_length": 0.5}],
        "environment": {"gravity": [0.0, 0.0, -9.81]},
        "run": {"t_end": t_end, "dt": 1e-3, "dt_sweep": [1e-3], "save_every": 10},
    }  # fmt: skip


def test_the_reference_follows_the_damped_slider_and_knows_its_error():
    sc = validate_system(slider_file())
    t = np.linspace(0.0, sc.t_end, 301)
    ref = reference(sc, t)
    m, k, c, l0 = 1.5, 40.0, 0.6, 2.7
    w, z = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)
    u = np.exp(-z * w * t) * (0.3 * np.cos(wd * t) + z * w * 0.3 / wd * np.sin(wd * t))
    err = np.abs(ref.trajectory.position[:, 0, 0] - (u - 2.0 + l0)).max()
    # measured 3.2e-13 m, estimate 6.4e-12 m
    assert err < 1e-11
    assert err <= ref.accuracy_position


def _director(sc, scheme="rattle6", dt=1e-3):
    from director_model.system import simulate_system

    bodies, joints = model(sc)
    springs, torques = force_elements(sc)
    return simulate_system(bodies, joints, gravity=tuple(sc.gravity), scheme=scheme, dt=dt,
                           t_end=sc.t_end, save_every=sc.save_every, springs=springs,
                           torques=torques)  # fmt: skip


@pytest.mark.parametrize("c", [0.0, 0.4])
def test_the_reference_and_rattle6_agree_on_a_spatial_arm_with_torques_and_a_spring(c):
    sc = validate_system(arm_file(c))
    tr = _director(sc)
    ref = reference(sc, tr.t)
    dx = np.abs(tr.position - ref.trajectory.position).max()
    dR = np.abs(tr.rotation - ref.trajectory.rotation).max()
    # measured 6.7e-14 m / 4.8e-13 (c = 0), 5.3e-14 m / 3.3e-13 (c = 0.4); the reference
    # estimates 8e-12 and 7.5e-12 of its own
    assert dx < 2e-13 and dR < 1.5e-12
    assert ref.accuracy < 1e-9


def test_energy_is_conserved_without_a_damper_and_its_loss_is_the_dampers_work():
    sc0 = validate_system(arm_file(0.0))
    t = np.linspace(0.0, sc0.t_end, 2001)
    E0 = system_energy(sc0, reference(sc0, t).trajectory)
    assert np.ptp(E0) < 1e-10 * sc0.energy_scale
    c = 0.4
    sc = validate_system(arm_file(c))
    traj = reference(sc, t).trajectory
    E = system_energy(sc, traj)
    spring = sc.springs[0]
    _, rate = fe.spring_length(sc.bodies, spring, traj.position, traj.rotation,
                               traj.velocity, traj.omega_body)  # fmt: skip
    p = c * rate**2
    work = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))])
    assert np.all(np.diff(E) <= 1e-12)
    loss = E[0] - E
    # the trapezoidal rule at 1 ms on a smooth power: 1e-6 relative (measured 2e-7)
    assert loss[-1] > 0.05
    assert np.abs(loss - work).max() < 1e-5 * loss[-1]


def test_energy_and_momentum_metrics_say_what_they_cannot_measure():
    from reports.metrics.system import energy_drift, momentum_drift

    sc = validate_system(arm_file(0.4))
    traj = reference(sc, np.linspace(0, 0.1, 11)).trajectory
    assert energy_drift(sc, traj) is None  # a damper: no conserved energy
    assert momentum_drift(sc, traj) is None  # elements to the ground
    sc0 = validate_system(arm_file(0.0))
    assert energy_drift(sc0, reference(sc0, np.linspace(0, 0.1, 11)).trajectory) is not None


def test_an_engine_that_does_not_apply_force_elements_is_unsupported(monkeypatch):
    """A builder that does not declare force_elements (PyBullet's, with the declaration taken
    away) is refused before it runs, naming the elements and the builders that apply them."""
    import dataclasses

    from references.engines import get_engine

    pytest.importorskip("pybullet")
    cls = get_engine("pybullet")
    monkeypatch.setattr(cls, "scene_builder",
                        dataclasses.replace(cls.scene_builder, force_elements=False))  # fmt: skip
    sc = validate_system(arm_file(0.0, t_end=0.01))
    with pytest.raises(Unsupported, match="force elements.*torque on 'h'.*spring 'pull'.*"
                       "builders that apply them: .*director.*mujoco"):  # fmt: skip
        run_system("pybullet", sc, "multibody", 1e-3)


def test_the_energy_scale_counts_the_springs_and_the_torques_work():
    sc = validate_system(slider_file(0.0))
    # a level rail: nothing but the spring's 1/2 k (l - l0)^2 = 1/2 40 0.3^2 J is in play
    assert sc.energy_scale == pytest.approx(1.8, rel=1e-12)
    arm = validate_system(arm_file(0.0))
    without = validate_system({k: v for k, v in arm_file(0.0).items()
                               if k not in ("torques", "springs")})  # fmt: skip
    assert arm.energy_scale > without.energy_scale
    # the bound holds along the reference: the kinetic energy never exceeds it
    traj = reference(arm, np.linspace(0, arm.t_end, 201)).trajectory
    m = np.array([b.mass for b in arm.bodies])
    inertia = np.array([b.inertia for b in arm.bodies])
    T = 0.5 * np.einsum("b,nbi,nbi->n", m, traj.velocity, traj.velocity) + 0.5 * np.einsum(
        "nbi,bi,nbi->n", traj.omega_body, inertia, traj.omega_body
    )
    assert T.max() <= arm.energy_scale


@pytest.mark.parametrize(
    "change, field, words",
    [
        (lambda d: d["torques"][0].update(joint="zz"), "torques[0].joint", "not a joint"),
        (lambda d: d["torques"][0].update(torque=0.0), "torques[0].torque", "does nothing"),
        (lambda d: d["springs"][0].update(body_b="rod"), "springs[0].body_b", "two different"),
        (lambda d: d["springs"][0].update(rest_length=-1.0), "springs[0].rest_length", "> 0"),
        (lambda d: d["springs"][0].update(stiffness=0.0), "springs[0].stiffness", "both 0"),
        (lambda d: d["springs"][0].update(damping=-0.1), "springs[0].damping", ">= 0"),
        (lambda d: d["springs"][0].update(anchor_b=[0.8, 0.0, -0.6]), "springs[0].anchor_b",
         "length"),
        (lambda d: d.update(reference={"kind": "conical_pendulum"}), "reference.kind",
         "numerical"),
    ],
)  # fmt: skip
def test_a_files_bad_force_element_is_refused_naming_field_value_and_rule(change, field, words):
    d = copy.deepcopy(arm_file())
    change(d)
    with pytest.raises(ScenarioError) as exc:
        validate_system(d)
    text = str(exc.value)
    assert field in text and words in text


def test_a_torque_on_a_spherical_joint_is_refused():
    d = copy.deepcopy(arm_file())
    d["joints"][1]["kind"] = "spherical"
    del d["joints"][1]["axis_a"], d["joints"][1]["axis_b"]
    with pytest.raises(ScenarioError, match="spherical: a torque acts about a revolute"):
        validate_system(d)
