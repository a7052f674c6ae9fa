"""The director model's schemes for systems of bodies (director_model.system: RATTLE compositions
rattle4 and rattle6, director coordinates, joints as constraints) against the independent
reduced-coordinate reference (references/exact/multibody: joint coordinates, composite-rigid-
body + recursive Newton-Euler, DOP853) and against the exact multibody motions.

Tolerance of each comparison: the reference's own error estimate (``accuracy``, see
references/exact/multibody/integrate.py) plus the director run's own error, estimated from a
run at a finer step: with D(h) the run at step h, p the scheme's order and f the refinement (2,
or 4 for the four-bar), D(h/f) errs by about |D(h) - D(h/f)|/(f^p - 1); a factor 2 is added
on that estimate. The two formulations share
nothing but the physics, so agreement to that sum (itself required to be far below any
physical scale) is evidence that both are right; a planted mistake (one body 1e-6 heavier in
the reference) shows the comparison can fail.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from references.conventions import matrix_to_quat_wxyz
from references.exact._util import rot_axis, rotation_angle
from references.exact.multibody import (
    Body,
    Joint,
    Tree,
    solve,
    trajectory_horizon,
    tree_from_world,
)
from references.exact.multibody.exact import (
    DoubleConicalPendulum,
    ParallelogramFourBar,
    SpinningChain,
    straight_chain,
)
from tests.references.exact.test_multibody_exact import FOURBAR

system = pytest.importorskip(
    "director_model.system", reason="director_model.system (the director multibody API) absent"
)

G = (0.0, 0.0, -9.81)
ORDER = {"rattle4": 4, "rattle6": 6}


def director_model_of(tree: Tree, x, R, v, W):
    """The director-form bodies and joints of ``tree`` in the world state (x, R, v, W)."""
    bodies = [
        system.Body(
            name,
            mass=float(tree.mass[b]),
            inertia=tuple(tree.inertia[b]),
            position=tuple(x[b]),
            rotation=np.asarray(R[b]),
            velocity=tuple(v[b]),
            omega_body=tuple(W[b]),
        )
        for b, name in enumerate(tree.names)
    ]
    joints = []
    for b, name in enumerate(tree.names):
        p = tree.parent[b]
        parent = None if p < 0 else tree.names[p]
        kind = tree.kinds[b]
        if kind == "free":
            continue
        kw = dict(anchor_a=tuple(tree.Y[b]), anchor_b=tuple(tree.X[b]))
        if kind == "revolute":
            # the axis in the child's frame, and the same axis in the parent's (or world) frame
            kw.update(axis_a=tuple(tree.axis[b]), axis_b=tuple(tree.offset[b] @ tree.axis[b]))
        joints.append(system.Joint(kind, name, parent, **kw))
    return bodies, joints


def run(bodies, joints, gravity, scheme, dt, t_end, every):
    return system.simulate_system(
        bodies,
        joints,
        gravity=gravity,
        scheme=scheme,
        dt=dt,
        t_end=t_end,
        save_every=int(round(every / dt)),
    )


def differences(tr, x, R):
    """Largest attitude (rad) and position (m) differences over bodies and saved times."""
    att = rotation_angle(tr.rotation.reshape(-1, 3, 3), np.asarray(R).reshape(-1, 3, 3))
    pos = np.linalg.norm(tr.position - x, axis=-1)
    return float(np.max(att)), float(np.max(pos))


def director_with_error(bodies, joints, gravity, scheme, dt, t_end, every, factor=2):
    """The run at dt/factor and its estimated error (attitude rad, position m): the
    difference from the run at dt over factor^p - 1, times 2."""
    coarse = run(bodies, joints, gravity, scheme, dt, t_end, every)
    fine = run(bodies, joints, gravity, scheme, dt / factor, t_end, every)
    att, pos = differences(fine, coarse.position, coarse.rotation)
    k = 2.0 / (factor ** ORDER[scheme] - 1)
    return fine, k * att, k * pos


def hanging_spherical_chain():
    bodies = [
        Body(f"b{i}", 1.0 + 0.3 * i, (0.02 + 0.01 * i, 0.05, 0.06 + 0.005 * i)) for i in range(3)
    ]
    joints = [Joint("spherical", "b0", None, (0.0, 0.0, 0.0), (0.02, -0.01, 0.25))]
    for i in range(1, 3):
        joints.append(
            Joint("spherical", f"b{i}", f"b{i - 1}", (0.01, 0.03, -0.25), (-0.02, 0.0, 0.22))
        )
    tree = Tree(bodies, joints, G)
    rng = np.random.default_rng(3)
    q0 = np.concatenate([rng.standard_normal(4) for _ in range(3)])
    for b in range(3):
        q0[4 * b : 4 * b + 4] /= np.linalg.norm(q0[4 * b : 4 * b + 4])
    u0 = 3.0 * rng.standard_normal(9)
    return tree, q0, u0


def revolute_chain():
    """Four links hanging from a revolute joint, each hinge axis turned from the last so that
    the chain moves in space; link i: e1 along the link."""
    bodies = [
        Body(f"l{i}", 0.5 + 0.2 * i, (0.002, 0.02 + 0.002 * i, 0.021 + 0.002 * i)) for i in range(4)
    ]
    axes = [(0, 0, 1), (0, 1, 1), (0, 0.3, 1), (0, 1, 0.2)]
    down = np.column_stack([(0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, -1.0, 0.0)])
    joints = [Joint("revolute", "l0", None, (0, 0, 0), (-0.15, 0, 0), axis=axes[0], offset=down)]
    for i in range(1, 4):
        joints.append(
            Joint("revolute", f"l{i}", f"l{i - 1}", (0.15, 0, 0), (-0.12, 0.01, 0), axis=axes[i])
        )
    tree = Tree(bodies, joints, G)
    return tree, np.array([1.0, -0.5, 0.8, 0.3]), np.array([2.0, -3.0, 1.0, 4.0])


CASES = {"3-body spherical chain": hanging_spherical_chain, "4-link revolute chain": revolute_chain}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("scheme, dt", [("rattle4", 2.5e-4), ("rattle6", 1e-3)])
def test_director_schemes_agree_with_the_reduced_reference(case, scheme, dt):
    tree, q0, u0 = CASES[case]()
    t_end, every = 1.0, 0.05
    t = np.linspace(0.0, t_end, int(round(t_end / every)) + 1)
    ref = solve(tree, q0, u0, t)
    bodies, joints = director_model_of(tree, ref.x[0], ref.R[0], ref.v[0], ref.W[0])
    tr, e_att, e_pos = director_with_error(bodies, joints, G, scheme, dt, t_end, every)
    assert np.allclose(tr.t, t, atol=1e-12)
    att, pos = differences(tr, ref.x, ref.R)
    tol_att = ref.accuracy["attitude"] + e_att
    tol_pos = ref.accuracy["position"] + e_pos
    assert att <= tol_att, (att, ref.accuracy["attitude"], e_att)
    assert pos <= tol_pos, (pos, ref.accuracy["position"], e_pos)
    assert tol_att < 1e-8 and tol_pos < 1e-9  # the comparison is sharp (links ~0.3 m)
    # a planted mistake: the reference with one body 1e-6 heavier is told apart
    wrong = Tree(
        [
            Body(n, tree.mass[b] * (1 + 1e-6 * (b == 1)), tuple(tree.inertia[b]))
            for b, n in enumerate(tree.names)
        ],
        _joints_of(tree),
        G,
    )
    bad = solve(wrong, q0, u0, t, estimate=False)
    batt, bpos = differences(tr, bad.x, bad.R)
    assert batt > 10 * tol_att or bpos > 10 * tol_pos


def _joints_of(tree: Tree):
    out = []
    for b, n in enumerate(tree.names):
        p = tree.parent[b]
        out.append(
            Joint(
                tree.kinds[b],
                n,
                None if p < 0 else tree.names[p],
                tuple(tree.X[b]),
                tuple(tree.Y[b]),
                tuple(tree.axis[b]),
                tree.offset[b],
            )
        )
    return out


# -- the exact motions ----------------------------------------------------------------------


def test_director_spinning_chain_is_the_uniform_rotation():
    tree = straight_chain(
        masses=(1.0, 0.6, 1.4),
        inertias=((0.01, 0.05, 0.06), (0.004, 0.02, 0.022), (0.02, 0.1, 0.11)),
        anchors=((0.2, 0.25), (0.15, 0.15), (0.3, 0.2)),
        gravity=G,
    )
    R0 = rot_axis(np.array([0.2, 0.4, 0.8]) / math.sqrt(0.84), 0.9)[0]
    exact = SpinningChain(tree, rate=5.0, axis=2, R0=R0, x_c=(0.1, -0.2, 1.0), v_c=(0.5, 0, 2))
    bodies, joints = director_model_of(tree, *exact.initial)
    t_end, every = 1.0, 0.05
    tr, e_att, e_pos = director_with_error(bodies, joints, G, "rattle6", 2e-3, t_end, every)
    x, R, _, _ = exact.motion(tr.t)
    att, pos = differences(tr, x, R)
    acc = exact.accuracy(tr.t)
    assert att <= acc["attitude"] + e_att + 1e-13  # 1e-13: round-off of ~500 steps
    assert pos <= acc["position"] + e_pos + 1e-13


def test_director_double_conical_pendulum_holds_its_steady_rotation():
    cp = DoubleConicalPendulum(
        m=(1.0, 0.7),
        J=((0.002, 0.03, 0.031), (0.001, 0.02, 0.02)),
        l=(0.3, 0.25),
        L1=0.6,
        g=9.81,
        rate=6.0,
    )
    bodies, joints = director_model_of(cp.tree, *cp.initial)
    t_end = 2 * math.pi / cp.rate  # one turn (the steady state is unstable: errors grow ~4/s)
    dt = t_end / 1000
    tr, e_att, e_pos = director_with_error(bodies, joints, G, "rattle6", dt, t_end, 50 * dt)
    x, R, _, _ = cp.motion(tr.t)
    att, pos = differences(tr, x, R)
    acc = cp.accuracy(tr.t)
    assert att <= acc["attitude"] + e_att + 1e-12
    assert pos <= acc["position"] + e_pos + 1e-12


def four_bar():
    """The parallelogram four-bar in director form: a closed loop (crank and rocker on revolute
    joints to the ground, the coupler on revolute joints to both: 20 constraint rows for 17
    degrees of freedom removed, a redundant loop), started to rotate through the singular
    configurations (all links collinear when the crank is horizontal)."""
    # the rotating four-bar of tests/references/exact/test_multibody_exact.py, whose closed form is
    # checked there
    fb = ParallelogramFourBar(theta0=-0.3, thetadot0=-12.0, **FOURBAR)
    x0, R0, v0, W0 = fb.initial
    e3 = (0.0, 0.0, 1.0)
    bodies = [
        system.Body(
            n,
            mass=m,
            inertia=tuple(J),
            position=tuple(x0[b]),
            rotation=R0[b],
            velocity=tuple(v0[b]),
            omega_body=tuple(W0[b]),
        )
        for b, (n, (m, J)) in enumerate(zip(fb.names, fb.bodies, strict=True))
    ]
    joints = [
        system.Joint(
            "revolute",
            "crank",
            None,
            anchor_a=(-fb.LA, 0, 0),
            anchor_b=(0, 0, 0),
            axis_a=e3,
            axis_b=tuple(fb.n),
        ),
        system.Joint(
            "revolute",
            "rocker",
            None,
            anchor_a=(-fb.LB, 0, 0),
            anchor_b=(fb.D, 0, 0),
            axis_a=e3,
            axis_b=tuple(fb.n),
        ),
        system.Joint(
            "revolute",
            "coupler",
            "crank",
            anchor_a=(-fb.coupler_com, 0, 0),
            anchor_b=(fb.L - fb.LA, 0, 0),
            axis_a=e3,
            axis_b=e3,
        ),
        system.Joint(
            "revolute",
            "coupler",
            "rocker",
            anchor_a=(fb.D - fb.coupler_com, 0, 0),
            anchor_b=(fb.L - fb.LB, 0, 0),
            axis_a=e3,
            axis_b=e3,
        ),
    ]
    return fb, bodies, joints


def test_director_parallelogram_four_bar_is_the_planar_pendulum():
    fb, bodies, joints = four_bar()
    t_end = 0.7  # a turn: 2 passages through the singular configurations (the min-norm
    # multiplier solve of the redundant loop costs ~3 ms a step)
    # steps 2e-3 and 5e-4 s (the next test takes steps that land closer to the singular
    # configuration)
    tr, e_att, e_pos = director_with_error(bodies, joints, G, "rattle6", 2e-3, t_end, 0.05, 4)
    x, R, _, _ = fb.motion(tr.t)
    att, pos = differences(tr, x, R)
    th, _ = fb.theta(np.linspace(0.0, t_end, 1001))
    # it passed the singular configurations (crank horizontal, theta = -pi/2 - k pi) twice
    assert np.count_nonzero(np.diff(np.floor((th + 0.5 * math.pi) / math.pi)) != 0) >= 2
    acc = fb.accuracy(tr.t)
    assert att <= acc["attitude"] + e_att + 1e-12
    assert pos <= acc["position"] + e_pos + 1e-12
    assert e_att < 1e-8


@pytest.mark.parametrize("dt, t_end", [(1e-3, 0.6), (2.5e-4, 0.15)])
def test_director_four_bar_passes_the_singular_configuration_at_these_steps(dt, t_end):
    """Steps that land within a fraction of a degree of the collinear configuration (with the
    API of commit 6cb905a the multiplier iteration failed there: at dt = 1e-3 s on step 546,
    crank 0.4 degrees from horizontal; at 2.5e-4 s on step 463)."""
    fb, bodies, joints = four_bar()
    tr = run(bodies, joints, G, "rattle6", dt, t_end, 0.05)
    x, R, _, _ = fb.motion(tr.t)
    att, pos = differences(tr, x, R)
    assert att < 1e-10 and pos < 1e-10  # measured 4.6e-12 rad at dt 1e-3 s over 1 s


@pytest.mark.slow
def test_chaotic_double_spherical_pendulum_agrees_inside_its_horizon():
    """Two rigid links on spherical joints, the upper one raised 115 degrees: chaotic. The
    trajectory is compared only inside the reference's horizon for 1e-6 rad (7.6 s of 9 s);
    the invariants of the director run over the whole run."""
    tree = Tree(
        [Body("upper", 1.0, (0.02, 0.021, 0.003)), Body("lower", 0.8, (0.015, 0.016, 0.002))],
        [
            Joint("spherical", "upper", None, (0, 0, 0), (0, 0, 0.25)),
            Joint("spherical", "lower", "upper", (0, 0, -0.25), (0, 0, 0.2)),
        ],
        G,
    )
    q0 = np.concatenate(
        [
            matrix_to_quat_wxyz(rot_axis(np.array([1.0, 0, 0]), 2.0)[0]),
            matrix_to_quat_wxyz(rot_axis(np.array([0, 1.0, 0]), 1.0)[0]),
        ]
    )
    u0 = np.array([0.0, 3.0, 1.0, 2.0, 0.0, 0.5])
    t_end, every, tol = 9.0, 0.05, 1e-6
    t = np.linspace(0.0, t_end, 181)
    hz = trajectory_horizon(tree, q0, u0, t, tol_attitude=tol, probes=2)
    assert not hz.within
    ref = hz.reference
    bodies, joints = director_model_of(tree, ref.x[0], ref.R[0], ref.v[0], ref.W[0])
    coarse = run(bodies, joints, G, "rattle6", 1e-3, t_end, every)
    fine = run(bodies, joints, G, "rattle6", 5e-4, t_end, every)
    inside = t <= hz.horizon

    def angles(tr, R):
        ang = rotation_angle(tr.rotation.reshape(-1, 3, 3), np.asarray(R).reshape(-1, 3, 3))
        return ang.reshape(len(t), -1).max(axis=1)

    e_dir = 2.0 / 63.0 * np.max(angles(fine, coarse.rotation)[inside])
    # measured inside the horizon: 4.6e-8 rad apart (at dt 1e-3 s)
    assert np.max(angles(fine, ref.R)[inside]) <= tol + e_dir
    # invariants over the whole run (9 s, 18000 steps): energy to 1e-11 of m g l, L_z to 1e-13
    scale = 1.8 * 9.81 * 0.5
    assert np.ptp(fine.energy) < 1e-11 * scale
    assert np.ptp(fine.angular_momentum[:, 2]) < 1e-13


def test_conical_pendulum_angles_agree_with_the_director_examples_balance():
    """Two derivations of the steady double conical pendulum: the augmented potential here
    (references/exact/multibody/exact.py) and the Newton-Euler balance of each link in
    director_model.system.examples (its rods: 1 m, 1 kg and 0.8 m, 0.7 kg, transverse moments
    m L^2/12 + 0.005, axial 0.01, joints at the rods' ends)."""
    examples = pytest.importorskip("director_model.system.examples")
    _, _, _, angles = examples.double_conical_pendulum(3.0)
    It = [m * L**2 / 12 + 0.005 for m, L in ((1.0, 1.0), (0.7, 0.8))]
    cp = DoubleConicalPendulum(
        m=(1.0, 0.7),
        J=((0.01, It[0], It[0]), (0.01, It[1], It[1])),
        l=(0.5, 0.4),
        L1=1.0,
        g=9.81,
        rate=3.0,
    )
    # both solved to round-off by Brent's method on the two formulations: measured 1.1e-16 apart
    assert np.max(np.abs(np.asarray(angles) - cp.phi)) < 1e-12


@pytest.mark.parametrize("case", list(CASES))
def test_reference_built_from_the_director_description_is_the_same_tree(case):
    """tree_from_world reads director_model.system's Body and Joint objects (anchor_a in
    body_a, anchor_b in body_b or the world): the tree it builds moves as the original."""
    tree, q0, u0 = CASES[case]()
    t = np.linspace(0.0, 0.2, 5)
    ref = solve(tree, q0, u0, t, estimate=False)
    bodies, joints = director_model_of(tree, ref.x[0], ref.R[0], ref.v[0], ref.W[0])
    tree2, q2, u2 = tree_from_world(bodies, joints, G)
    again = solve(tree2, q2, u2, t, estimate=False)
    order = [tree.names.index(n) for n in tree2.names]
    assert np.max(np.abs(again.x - ref.x[:, order])) < 1e-12
