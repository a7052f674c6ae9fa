"""The loop reference (references/exact/multibody/loops.py): closed loops and the joints the
reduced tree does not have, as constraint rows on the tree.

Checked against values it does not compute itself:
(a) the rows' rates and accelerations (J u and J u' + b) against finite differences of the
    rows' residuals along a motion of the tree with every closure left open (every row kind:
    point, axis, line; a universal, a prismatic and a cylindrical joint);
(b) the parallelogram four-bar away from its singular configuration against its closed form
    (the planar pendulum), the error estimate between the actual error and 1000 times it;
(c) through the singular configuration it stops with the time and the reason;
(d) Bricard's redundant loop and the spatial slider-crank (slider, universal, spherical) against
    director_model.system's RATTLE6, a formulation that shares nothing with it, and energy.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from references.engines.exact.system import reference
from references.errors import Unsupported
from references.exact._util import rotation_angle
from references.exact.multibody import loops, solve
from references.exact.multibody.integrate import _run


def four_bar_at(thetadot0: float, t_end: float):
    """The library four-bar started at ``thetadot0`` (rad/s) instead of 7: every velocity of
    its initial state scales with theta'."""
    sc = scenarios.load("four_bar")
    k = thetadot0 / float(sc.reference_params["thetadot0"])
    bodies = tuple(
        dataclasses.replace(b, velocity=b.velocity * k, omega_body=b.omega_body * k)
        for b in sc.bodies
    )
    params = {**sc.reference_params, "thetadot0": thetadot0}
    return sc.replace(bodies=bodies, reference_params=params, t_end=t_end)


# -- (a) the rows against finite differences ------------------------------------------------


def _open_motion(sc, t):
    """The tree of ``sc``'s loop system moving with its closures left open, and the rows'
    residuals along it (its joint states at the times t)."""
    system, q0, u0 = loops.system_from_world(sc.bodies, sc.joints, sc.gravity)
    tree = system.tree
    # a kick that opens every closure: the tree's own rates, perturbed
    rng = np.random.default_rng(3)
    u0 = u0 + rng.standard_normal(tree.nu)
    sol = solve(tree, q0, u0, t, estimate=False)
    return system, sol


@pytest.mark.parametrize("name", ["slider_crank_spatial", "bricard"])
def test_rows_rates_and_accelerations_match_finite_differences(name):
    """phi' = J u and phi'' = J u' + b at every row kind, against central differences of phi
    along an open motion (h = 1e-4 s: truncation ~h^2 phi'''' ~ 1e-7, round-off
    eps/h^2 ~ 1e-8 relative)."""
    sc = scenarios.load(name)
    h = 1e-4
    tc = np.array([0.05, 0.17, 0.31])
    t = np.sort(np.concatenate([tc - h, tc, tc + h]))
    system, sol = _open_motion(sc, t)
    tree = system.tree
    phi = np.array([loops.residuals(system, q) for q in sol.q])
    assert np.max(np.abs(phi)) > 1e-2  # the closures are open: the rows move
    for k in range(len(tc)):
        i = 3 * k + 1
        q, u = sol.q[i], sol.u[i]
        d1 = (phi[i + 1] - phi[i - 1]) / (2 * h)
        d2 = (phi[i + 1] - 2 * phi[i] + phi[i - 1]) / h**2
        Ju = loops.velocity_residuals(system, q, u)
        # J u' + b with u' the tree's own (unconstrained) accelerations: the rows' system at
        # alpha = 0 with every closure dropped gives them
        free = loops.LoopSystem(tree, [], [], [], system.chains)
        ud = loops.accelerations(free, q, u)[0]
        _, J, b = loops._rows(system, *_kin(system, q, u))
        scale1 = max(1.0, float(np.max(np.abs(d1))))
        scale2 = max(1.0, float(np.max(np.abs(d2))))
        assert np.max(np.abs(Ju - d1)) < 1e-6 * scale1, (Ju, d1)
        assert np.max(np.abs(J @ ud + b - d2)) < 1e-5 * scale2, (J @ ud + b, d2)


def _kin(system, q, u):
    _, _, R, x, v, S, a = loops._kin(system, q, u)
    return R, x, v, S, a, system.tree.gravity


# -- (b), (c) the parallelogram four-bar ------------------------------------------------------


def test_four_bar_away_from_its_singular_configuration_matches_the_closed_form():
    """At 5 rad/s the four-bar swings to 1.24 rad and back, never near its collinear
    configuration (pi/2): the loop reference (kind numerical) against the planar pendulum,
    and its error estimate between the actual error and 1000 times it."""
    sc = four_bar_at(5.0, 2.0)
    t = np.linspace(0.0, 2.0, 201)
    exact = reference(sc, t)
    num = reference(sc.replace(reference="numerical"), t)
    assert exact.kind == "four_bar" and num.kind == "numerical"
    err = float(np.max(rotation_angle(num.trajectory.rotation.reshape(-1, 3, 3),
                                      exact.trajectory.rotation.reshape(-1, 3, 3))))  # fmt: skip
    perr = float(np.max(np.abs(num.trajectory.position - exact.trajectory.position)))
    assert err < 1e-11 and perr < 1e-11
    assert err <= num.accuracy <= 1e3 * max(err, 1e-15), (err, num.accuracy)
    assert perr <= num.accuracy_position <= 1e3 * max(perr, 1e-15), (perr, num.accuracy_position)


def test_four_bar_through_its_singular_configuration_stops_there():
    """At 7 rad/s (the library file) the four-bar reaches its collinear configuration at
    t = 0.3086 s (closed form): the loop reference refuses, naming the time, rather than
    follow either branch."""
    sc = scenarios.load("four_bar").replace(reference="numerical")
    with pytest.raises(Unsupported, match=r"singular configuration near t = 0\.30"):
        reference(sc, np.linspace(0.0, 0.6, 61))


def test_loop_singular_is_raised_by_the_right_hand_side():
    sc = scenarios.load("four_bar")
    system, q0, u0 = loops.system_from_world(sc.bodies, sc.joints, sc.gravity)
    f = loops.rhs_function(system, alpha=1.0)
    y0 = np.concatenate([q0, u0])
    t = np.linspace(0.0, 0.6, 7)
    with pytest.raises(loops.LoopSingular, match="rank drops from 2"):
        _run(f, y0, t, 1e-13, np.ones(len(y0)), np.inf, 10**6, 1e300, "test")


# -- (d) agreement with the director model ----------------------------------------------------


@pytest.mark.parametrize("name, t_end", [("bricard", 0.5), ("slider_crank_spatial", 0.5)])
def test_loop_reference_agrees_with_director_rattle6(name, t_end):
    """The loop reference (one run, rtol 1e-13) and director_model.system's RATTLE6 at
    dt = 1e-3 (its error over 0.5 s ~1e-9 rad: docs/numerics.md) agree to 1e-7 rad and m,
    and the reference holds its rows and its energy to 1e-10 of the energy in play."""
    from references.engines.system import run_system
    from references.trajectory import Trajectory, system_energy

    sc = scenarios.load(name).replace(t_end=t_end)
    out = run_system("director", sc, "rattle6", 1e-3, t_end, 10)
    tr = out.trajectory
    system, q0, u0 = loops.system_from_world(sc.bodies, sc.joints, sc.gravity)
    tree = system.tree
    sol = solve(tree, q0, u0, tr.t, estimate=False, system=system)
    order = [sol.names.index(n) for n in sc.body_names]
    ang = rotation_angle(tr.rotation.reshape(-1, 3, 3), sol.R[:, order].reshape(-1, 3, 3))
    assert float(np.max(ang)) < 1e-7
    assert float(np.max(np.abs(tr.position - sol.x[:, order]))) < 1e-7
    assert sol.constraint_residual < 1e-10
    ref_tr = Trajectory(tr.t, sol.x[:, order], sol.v[:, order], sol.R[:, order],
                              sol.W[:, order], sc.body_names)  # fmt: skip
    E = system_energy(sc, ref_tr)
    assert float(np.max(np.abs(E - E[0]))) < 1e-10 * sc.energy_scale


def test_closures_and_tree_joints():
    """The spanning tree takes the spherical and revolute joints; a universal or prismatic
    joint is a closure even where it joins the tree for the first time (the slider becomes
    a free root held by two closures: 9 rows on 10 rates, one degree of freedom)."""
    sc = scenarios.load("slider_crank_spatial")
    system, _, _ = loops.system_from_world(sc.bodies, sc.joints, sc.gravity)
    assert system.tree_joints == ["hinge", "ball"]
    assert sorted(system.closure_joints) == ["cross", "slide"]
    assert system.tree.kinds[system.tree.index["slider"]] == "free"
    assert system.nc == 9 and system.tree.nu == 10 and system.rank0 == 9


def test_an_open_closure_at_t0_is_refused():
    sc = scenarios.load("bricard")
    bodies = list(sc.bodies)
    bodies[2] = dataclasses.replace(bodies[2], position=bodies[2].position + [0, 0, 1e-6])
    with pytest.raises(ValueError, match=r"apart|violated by"):
        loops.system_from_world(bodies, sc.joints, sc.gravity)
