"""What the tests of the system builders (tests/test_<engine>_system.py) share: the stand-in
systems they run, the independent solutions they are measured against and the order rule.

Expected values come from formulations that share nothing with the builders: the
reduced-coordinate reference (references/exact/multibody: its own recursive dynamics, DOP853 at
rtol 1e-13, far below every error judged here), the planar pendulum of the parallelogram
four-bar (scipy DOP853 on one ODE), the inclined slide's closed form, director_model.system's
RATTLE6 and the conservation of momentum. Tolerances come from the integrators' orders: halving
dt must divide the error by about 2^p, accepted within a factor 1.6 of that
(:func:`assert_order`: the error constants of a short run move a little with dt). The scenarios
are stand-ins with exactly the contract's fields (name, gravity, bodies, joints), built from
director_model.system's Body and Joint (references.engines.system_conformance.scenario).

The functions take the builder module (``references.engines.<engine>_system``) and its
integrator's name; those named ``assert_...`` assert what every builder must do and return
what the calling test bounds with its own measured figures.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from director_model.system import Body, Joint
from director_model.system.examples import rod_chain
from references.conventions import rotvec_to_matrix
from references.engines import reduced
from references.engines import system_conformance as kit
from references.engines.system_conformance import hinge_chain, scenario
from references.errors import EngineError
from references.exact.multibody import solve, tree_from_world

#: the stand-in chains of the builders' order tests (:func:`chain`), and the names pytest shows
CHAINS = ("spherical3", "hinge4")
CHAIN_IDS = ("3-body spherical chain", "4-link revolute chain")


def assert_order(e_coarse, e_fine, p):
    ratio = e_coarse / e_fine
    assert 2**p / 1.6 < ratio < 2**p * 1.6, (e_coarse, e_fine, ratio)


def chain(system: str):
    """The stand-in chain ``system``: "spherical3" (three rods on spherical joints, the first
    to the ground, random attitudes and rates) or "hinge4" (the kit's four-link revolute
    chain)."""
    if system == "spherical3":
        return scenario(system, *rod_chain(3, True, seed=1))
    return scenario(system, *hinge_chain())


def errors_vs_reference(mod, sc, integrator, dt, t_end=1.0):
    """Largest COM position (m) and attitude (|R - R_ref|, max entry) errors over a run of the
    builder module ``mod`` against the reduced-coordinate reference."""
    n = int(round(t_end / dt))
    out = mod.simulate_system(sc, integrator, dt, n, n // 10)
    tree, q0, u0 = tree_from_world(sc.bodies, sc.joints, sc.gravity)
    ref = solve(tree, q0, u0, out.t, estimate=False)
    order = [ref.names.index(b.name) for b in sc.bodies]
    return (float(np.max(np.abs(out.x - ref.x[:, order]))),
            float(np.max(np.abs(out.R - ref.R[:, order]))))  # fmt: skip


def assert_chain_order(mod, system, integrator, dt, p) -> float:
    """The chain ``system`` (:func:`chain`) at dt and dt / 2 against the reduced reference:
    position and attitude errors converge at order ``p``; returns the position error (m) at
    dt / 2."""
    sc = chain(system)
    ex1, eR1 = errors_vs_reference(mod, sc, integrator, dt)
    ex2, eR2 = errors_vs_reference(mod, sc, integrator, dt / 2)
    assert_order(ex1, ex2, p)
    assert_order(eR1, eR2, p)
    return ex2


def momentum(sc, out):
    """Linear (kg m/s) and angular (about the world origin, kg m^2/s) momentum over a run."""
    m = np.array([b.mass for b in sc.bodies])
    P = np.einsum("b,nbi->ni", m, out.v)
    L = np.zeros_like(P)
    for k, b in enumerate(sc.bodies):
        L += np.cross(out.x[:, k], m[k] * out.v[:, k])
        L += np.einsum("nij,j,nj->ni", out.R[:, k], np.asarray(b.inertia), out.W[:, k])
    return P, L


def assert_momentum_order(mod, integrator, dt, p):
    """A floating 5-body chain (no joint to the ground) in zero gravity over 1 s at dt and
    dt / 2: linear and angular momentum are invariants of the exact motion, and their drifts
    must shrink at order ``p``. Returns the drifts (P, L) at dt / 2 and that run's P and L."""
    sc = scenario("float5", *rod_chain(5, False, seed=2), gravity=(0, 0, 0))
    drifts = []
    for h in (dt, dt / 2):
        out = mod.simulate_system(sc, integrator, h, int(round(1.0 / h)), 10)
        P, L = momentum(sc, out)
        drifts.append((np.max(np.abs(P - P[0])), np.max(np.abs(L - L[0]))))
    assert_order(drifts[0][0], drifts[1][0], p)
    assert_order(drifts[0][1], drifts[1][1], p)
    return drifts[1], P, L


def four_bar_gap(sc, out):
    """(point gap m, axis misalignment rad) of the closing joint B1 over time."""
    j = sc.joints[3]
    names = [b.name for b in sc.bodies]
    a, b = names.index(j.body_a), names.index(j.body_b)
    pa = out.x[:, a] + np.einsum("nij,j->ni", out.R[:, a], j.anchor_a)
    pb = out.x[:, b] + np.einsum("nij,j->ni", out.R[:, b], j.anchor_b)
    ua = np.einsum("nij,j->ni", out.R[:, a], j.axis_a)
    ub = np.einsum("nij,j->ni", out.R[:, b], j.axis_b)
    return np.linalg.norm(pa - pb, axis=1), np.linalg.norm(np.cross(ua, ub), axis=1)


def four_bar_theta_error(out, I_eff, k):
    R = out.R[:, 0]
    th = np.arctan2(R[:, 0, 2], R[:, 2, 2])
    rhs = lambda t, y: [y[1], -9.81 * k / I_eff * np.sin(y[0])]  # noqa: E731
    sol = solve_ivp(rhs, (0, out.t[-1]), [0.0, 7.0], t_eval=out.t, rtol=1e-12,
                    atol=1e-12, method="DOP853")  # fmt: skip
    return float(np.max(np.abs(np.angle(np.exp(1j * (th - sol.y[0]))))))


def two_ball_hinge():
    """A plate (COM 0.3 m below the line through its two anchors, tilted 0.4 rad, swinging at
    3 rad/s) hung from the ground by two spherical joints 0.4 m apart on the x axis: the second
    closes a loop through the ground (six equations for the hinge's five). Returns (the loop
    system, the same plate on one revolute joint along x for the reduced reference, the two
    anchors in the plate's frame with their world points)."""
    R0 = rotvec_to_matrix([0.4, 0.0, 0.0])
    x0 = R0 @ np.array([0.0, 0.0, -0.3])
    w = np.array([3.0, 0.0, 0.0])
    b = [Body("plate", 1.0, (0.02, 0.03, 0.04), x0, R0, np.cross(w, x0), R0.T @ w)]
    ends = [(X, R0 @ X + x0) for X in (np.array([-0.2, 0, 0.3]), np.array([0.2, 0, 0.3]))]
    balls = [Joint("spherical", "plate", None, X, P, name=n)
             for (X, P), n in zip(ends, ("left", "right"), strict=True)]  # fmt: skip
    hinge = [Joint("revolute", "plate", None, (0, 0, 0.3), (0, 0, 0), (1, 0, 0), (1, 0, 0))]
    return scenario("two_ball_hinge", b, balls), scenario("hinge", b, hinge), ends


def two_ball_hinge_errors(mod, integrator, dt, t_end=2.0):
    """(largest anchor gap m, COM error m against the reduced reference of the hinge)."""
    sc, hinge, ends = two_ball_hinge()
    n = int(round(t_end / dt))
    out = mod.simulate_system(sc, integrator, dt, n, n // 20)
    tree, q0, u0 = tree_from_world(hinge.bodies, hinge.joints, kit.G)
    ref = solve(tree, q0, u0, out.t, estimate=False)
    gap = max(float(np.max(np.linalg.norm(
        out.x[:, 0] + np.einsum("nij,j->ni", out.R[:, 0], X) - P, axis=1)))
        for X, P in ends)  # fmt: skip
    return gap, float(np.max(np.abs(out.x - ref.x)))


def slide_errors(mod, sc, integrator, h, nstep):
    """(run, largest COM error against the inclined slide's closed form, the same after
    removing semi-implicit Euler's known error (g . n) n h t / 2)."""
    _, _, exact = kit.inclined_slide()
    out = mod.simulate_system(sc, integrator, h, nstep, 10)
    x, R = exact(out.t)
    n = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    err = out.x[:, 0] - x
    euler = np.outer(out.t, (kit.G @ n) * n) * h / 2
    assert np.abs(out.R[:, 0] - R).max() < 1e-14 and np.abs(out.W).max() < 1e-14
    return out, float(np.abs(err).max()), float(np.abs(err - euler).max())


def slider_errors_vs_rattle6(mod, integrator, dts):
    """kit.slider (a collar sliding along a hinged rod) run by ``mod`` at each step of ``dts``
    over 1 s against director_model.system's RATTLE6 at dt 1 ms (its own error measured by
    halving dt: 9e-16): (largest position or rotation error at each step, the last run)."""
    from director_model.system import simulate_system

    bodies, joints = kit.slider()
    sc = scenario("slider", bodies, joints)
    tr = simulate_system(bodies, joints, gravity=kit.G, scheme="rattle6", dt=1e-3, t_end=1.0,
                         save_every=100)  # fmt: skip
    e = []
    for h in dts:
        out = mod.simulate_system(sc, integrator, h, round(1 / h), round(0.1 / h))
        e.append(max(np.abs(out.x - tr.position).max(), np.abs(out.R - tr.rotation).max()))
    return e, out


def assert_prismatic_mistake_caught(monkeypatch, mod, mistake: str, integrator) -> None:
    """Plant on kit.slider's collar either the slide axis handed to the engine in the rod's
    frame instead of the collar's (``mistake`` "axis in the parent's frame"; ``mod.engine_frames``
    returns frames with an ``axis``) or the initial slide coordinate left at 0 (the collar
    starts 0.3 m from the rod's anchor along the axis): the builder's check of the engine's
    kinematics of the initial state refuses the run, naming the collar."""
    bodies, joints = kit.slider()
    if mistake == "axis in the parent's frame":
        orig = mod.engine_frames

        def planted(pl, c):
            f = orig(pl, c)
            if pl.names[c] != "collar":
                return f
            return dataclasses.replace(f, axis=reduced.unit(joints[1].axis_a, ""))

        monkeypatch.setattr(mod, "engine_frames", planted)
    else:
        orig_state = reduced.slide_state
        monkeypatch.setattr(reduced, "slide_state", lambda pl, tj: (0.0, orig_state(pl, tj)[1]))
    with pytest.raises(EngineError, match=r"initial state differ.*body 'collar'"):
        mod.simulate_system(scenario("slider", bodies, joints), integrator, 1e-3, 1, 1)


def assert_saved_steps(mod, sc, integrator) -> None:
    """Five steps of 1 ms saved every second step come back at 0, 2, 4 and 5 ms (the last
    step always saved), with every body's state and time inside the engine."""
    out = mod.simulate_system(sc, integrator, 1e-3, 5, 2)
    assert out.t.tolist() == pytest.approx([0, 2e-3, 4e-3, 5e-3])
    assert out.x.shape == (4, len(sc.bodies), 3) and out.engine_time_s > 0


def joint_rates(tree, q, u):
    """q' of a reduced-coordinate tree (references.exact.multibody) for the velocities u: the
    joints' kinematic equations written out in NumPy (revolute theta' = u, free x' = v, and
    quaternion rates q (0, w) / 2 as a Hamilton product), independent of the compiled ones."""
    dq = np.zeros(tree.nq)
    for b in range(tree.nb):
        qo, uo = tree.qofs[b], tree.uofs[b]
        if tree.kinds[b] == "revolute":
            dq[qo] = u[uo]
            continue
        if tree.kinds[b] == "free":
            dq[qo : qo + 3] = u[uo : uo + 3]
            qo, uo = qo + 3, uo + 3
        w, x, y, z = q[qo : qo + 4]
        a, bb, c = u[uo : uo + 3]
        dq[qo : qo + 4] = 0.5 * np.array(
            [
                -x * a - y * bb - z * c,
                w * a + y * c - z * bb,
                w * bb + z * a - x * c,
                w * c + x * bb - y * a,
            ]
        )
    return dq
