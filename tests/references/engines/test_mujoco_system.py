"""The MuJoCo builder for systems of bodies (references/engines/mujoco/system.py).

Expected values come from formulations that share nothing with MuJoCo: the reduced-coordinate
reference (references/exact/multibody: its own recursive dynamics, DOP853 at rtol 1e-13),
director_model.system's RATTLE6 (director form, constraints as equations), the planar pendulum
of the parallelogram four-bar (scipy DOP853 on one ODE), and the conservation of momentum.
The system scenarios are stand-ins with exactly the contract's fields (name, gravity, bodies,
joints), built from director_model.system's Body and Joint.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp

pytest.importorskip("mujoco")

from director_model.system import Body, Joint  # noqa: E402
from director_model.system import simulate_system as director_simulate  # noqa: E402
from director_model.system.examples import (  # noqa: E402
    parallelogram_four_bar,
    rod_chain,
    rot_y,
)
from references.engines.mujoco import system as ms  # noqa: E402
from references.engines.system_conformance import scenario, slider  # noqa: E402
from references.errors import EngineError, Unsupported  # noqa: E402
from references.exact.multibody import solve, tree_from_world  # noqa: E402

G = np.array([0.0, 0.0, -9.81])


def revolute_chain():
    """Four links hanging from a hinge at the origin, hinge axes along world y, links 1 and 3
    with principal frames turned by 90 degrees about their x axis (the rod along body e2, the
    hinge along body -e3), so that an axis given in the parent's frame differs from the
    child's. Unequal lengths, masses, initial angles and rates."""
    turned = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    th, om = [0.4, -0.3, 0.9, 0.2], [1.0, -2.0, 0.5, 1.5]
    L, m = [1.0, 0.7, 0.9, 0.5], [1.0, 0.6, 0.8, 0.4]
    y = np.array([0.0, 1.0, 0.0])
    bodies, joints = [], []
    top, vtop = np.zeros(3), np.zeros(3)
    prev = None
    for i in range(4):
        B = np.eye(3) if i % 2 == 0 else turned
        R = rot_y(th[i]) @ B
        It, Ia = m[i] * L[i] ** 2 / 12 + 0.01, 0.02
        inertia = (It, It, Ia) if i % 2 == 0 else (It, Ia, It)
        half = rot_y(th[i]) @ np.array([0.0, 0.0, -L[i] / 2])
        w = om[i] * y
        bodies.append(
            Body(f"l{i}", m[i], inertia, top + half, R, vtop + np.cross(w, half), R.T @ w)
        )
        up, ax = B.T @ np.array([0.0, 0.0, L[i] / 2]), B.T @ y
        if prev is None:
            joints.append(Joint("revolute", "l0", None, up, (0, 0, 0), ax, y, name="h0"))
        else:
            joints.append(
                Joint("revolute", f"l{i - 1}", f"l{i}", -prev[0], up, prev[1], ax, name=f"h{i}")
            )
        prev = (up, ax)
        top, vtop = top + 2 * half, vtop + np.cross(w, 2 * half)
    return bodies, joints


def reference(bodies, joints, t, gravity=G):
    tree, q0, u0 = tree_from_world(bodies, joints, gravity)
    sol = solve(tree, q0, u0, t)
    perm = [tree.names.index(b.name) for b in bodies]
    return sol, perm


def max_err(out, sol_x, sol_R):
    return max(np.abs(out.x - sol_x).max(), np.abs(out.R - sol_R).max())


CASES = {
    "3-body spherical chain": lambda: rod_chain(3, hang=True),
    "4-link revolute chain": revolute_chain,
}


@pytest.mark.parametrize("case", CASES)
def test_rk4_agrees_with_the_reduced_reference_and_rattle6(case):
    """MuJoCo RK4 at dt = 2 ms and 1 ms over 2 s against the reduced-coordinate reference.

    Tolerance: RK4 is order 4, so its error at dt is e(dt) ~ C dt^4, and the difference of
    its two runs estimates it (Richardson): e(1 ms) ~ |y(1 ms) - y(2 ms)| / 15. Asserted: the
    observed order log2(e(2 ms) / e(1 ms)) within 3.5 .. 4.5 (measured 3.9 and 4.0), and
    e(1 ms) within 2 x the Richardson estimate plus the reference's own error estimate. A
    frame, anchor or axis mistake gives an O(1) error that shrinks at no order.
    director_model.system's RATTLE6 (order 6, dt 1 ms) must agree with MuJoCo to the same
    bound plus RATTLE6's own measured error against the reference."""
    bodies, joints = CASES[case]()
    sc = scenario(case, bodies, joints)
    out2 = ms.simulate_system(sc, "RK4", 2e-3, 1000, 50)
    out1 = ms.simulate_system(sc, "RK4", 1e-3, 2000, 100)
    np.testing.assert_array_equal(out1.t, out2.t)
    sol, perm = reference(bodies, joints, out1.t)
    sx, sR = sol.x[:, perm], sol.R[:, perm]
    e2, e1 = max_err(out2, sx, sR), max_err(out1, sx, sR)
    order = np.log2(e2 / e1)
    assert 3.5 <= order <= 4.5, (e2, e1, order)
    rich = max(np.abs(out1.x - out2.x).max(), np.abs(out1.R - out2.R).max()) / 15
    ref_err = max(sol.accuracy["position"], sol.accuracy["attitude"])
    assert e1 <= 2 * rich + ref_err, (e1, rich, ref_err)
    assert (
        np.abs(out1.W - sol.W[:, perm]).max()
        <= 2 * np.abs(out1.W - out2.W).max() / 15 + sol.accuracy["omega"]
    )
    tr = director_simulate(
        bodies, joints, gravity=G, scheme="rattle6", dt=1e-3, t_end=2.0, save_every=100
    )
    r6 = max(np.abs(tr.position - sx).max(), np.abs(tr.rotation - sR).max())
    assert r6 < 1e-11  # RATTLE6 is two orders more accurate than RK4 here (measured 3e-13)
    d = max(np.abs(out1.x - tr.position).max(), np.abs(out1.R - tr.rotation).max())
    assert d <= 2 * rich + r6, (d, rich, r6)


def test_free_floating_chain_keeps_its_momentum():
    """Five rods joined by spherical joints, floating in zero gravity (free root): total
    linear momentum sum m v and angular momentum about the origin sum (x x m v + R I W) are
    invariants of the motion. RK4 keeps them to its discretisation error: the drift shrinks
    at order 4 (measured ratio 16.0 from 2 ms to 1 ms) and at 1 ms stays below 1e-9 of the
    momenta's scale (measured 6e-11 and 2e-11 relative)."""
    bodies, joints = rod_chain(5, hang=False)
    sc = scenario("free chain", bodies, joints, gravity=np.zeros(3))
    m = np.array([b.mass for b in bodies])
    inertia = np.array([b.inertia for b in bodies])
    drift = {}
    for dt in (2e-3, 1e-3):
        n = round(2.0 / dt)
        out = ms.simulate_system(sc, "RK4", dt, n, n // 20)
        assert out.settings["tree"]["b0"] == "free to ground"
        p = np.einsum("b,nbi->ni", m, out.v)
        L = np.einsum("b,nbi->ni", m, np.cross(out.x, out.v))
        L += np.einsum("nbij,nbj->ni", out.R, inertia * out.W)
        drift[dt] = (
            np.abs(p - p[0]).max() / np.linalg.norm(p[0]),
            np.abs(L - L[0]).max() / np.linalg.norm(L[0]),
        )
    for k in range(2):
        assert 3.5 <= np.log2(drift[2e-3][k] / drift[1e-3][k]) <= 4.5, drift
        assert drift[1e-3][k] < 1e-9, drift


def loop_gap(out, bodies, joint):
    """The gap of a joint's anchors (m) over time from the returned states."""
    names = [b.name for b in bodies]
    a, b = names.index(joint.body_a), names.index(joint.body_b)
    pa = out.x[:, a] + np.einsum("nij,j->ni", out.R[:, a], joint.anchor_a)
    pb = out.x[:, b] + np.einsum("nij,j->ni", out.R[:, b], joint.anchor_b)
    return np.linalg.norm(pa - pb, axis=1)


def test_four_bar_loop_closure_gap_default_and_stiff_solref():
    """The parallelogram four-bar over 2 s (theta' = 7 rad/s from the bottom: it passes the
    singular, collinear configuration twice per swing), closed by two connects on the hinge
    axis of joint B1, with MuJoCo's default solref (0.02, 1) and a stiffer (0.002, 1).

    Expected: the gap of a soft constraint scales with the square of its time constant (the
    constraint's reference stiffness is 1/(d_max tc dr)^2): ten times shorter, ~100 times
    smaller (measured 51: max 2.9e-4 m and 5.7e-6 m); asserted: more than 10 times smaller.
    The crank angle follows the exact planar pendulum I_eff theta'' = -|g| k sin(theta)
    (multibody.md section 5; scipy DOP853 at rtol 1e-12) to an error set by the softness
    (measured 1.1e-2 and 2.4e-4 rad); asserted below 0.05 and 1e-3 rad: the linkage stays on
    its branch (the crossed branch would be off by O(1))."""
    theta_err = four_bar_solref_errors(ms, "RK4", 2.0)
    assert theta_err[(0.02, 1.0)] < 0.05 and theta_err[(0.002, 1.0)] < 1e-3, theta_err


def four_bar_solref_errors(mod, integrator, t_end):
    """The parallelogram four-bar from the bottom at theta' = 7 rad/s over ``t_end`` s at dt
    1 ms on the builder ``mod`` (mujoco_system or mjx_system) with solref (0.02, 1) and
    (0.002, 1): each run's settings are those given (two site-to-site connects on B1), the
    loop gap is 0 at t = 0, between 1e-6 and 1e-3 m with the default solref and more than 10
    times smaller with the stiffer one. Returns the crank angle's largest error (rad) against
    the exact planar pendulum, by solref."""
    bodies, joints, I_eff, k = parallelogram_four_bar()
    sc = scenario("parallelogram four-bar", bodies, joints)
    n = int(round(t_end / 1e-3))
    t = np.linspace(0.0, t_end, n // 10 + 1)
    rhs = lambda _, y: [y[1], -9.81 * k / I_eff * np.sin(y[0])]  # noqa: E731
    exact = solve_ivp(rhs, (0, t_end), [0.0, 7.0], t_eval=t, rtol=1e-12, atol=1e-12,
                      method="DOP853").y[0]  # fmt: skip
    gaps, theta_err = {}, {}
    for solref in ((0.02, 1.0), (0.002, 1.0)):
        out = mod.simulate_system(sc, integrator, 1e-3, n, 10, solref=solref)
        s = out.settings
        assert s["solref"] == list(solref) and s["solref effective"] == list(solref)
        assert s["solimp"] == list(ms.DEFAULT_SOLIMP)
        assert (
            "two site-to-site connects" in s["loop closures"][0] and "'B1'" in s["loop closures"][0]
        )
        gaps[solref] = loop_gap(out, bodies, joints[3])
        # with theta' > 0 about +y the crank's tip swings to -x
        theta = np.arctan2(-out.x[:, 0, 0], -out.x[:, 0, 2])
        theta_err[solref] = np.abs(theta - exact).max()
    g_def, g_stiff = gaps[(0.02, 1.0)].max(), gaps[(0.002, 1.0)].max()
    assert gaps[(0.02, 1.0)][0] < 1e-12 and 1e-6 < g_def < 1e-3, g_def
    assert g_stiff < g_def / 10, (g_def, g_stiff)
    return theta_err


def test_refsafe_raises_a_short_time_constant_and_says_so():
    bodies, joints, _, _ = parallelogram_four_bar()
    out = ms.simulate_system(scenario("fb", bodies, joints), "Euler", 2e-3, 5, 5, solref=(0.002, 1))
    assert out.settings["solref effective"] == [0.004, 1.0]
    assert "refsafe" in out.settings["solref note"]


@pytest.mark.parametrize("integrator", ["Euler", "implicit", "implicitfast", "RK4"])
def test_every_integrator_runs_the_closed_loop(integrator):
    """Each integrator builds and steps the four-bar; the first saved state is the scenario's."""
    bodies, joints, _, _ = parallelogram_four_bar()
    out = ms.simulate_system(scenario("fb", bodies, joints), integrator, 1e-3, 200, 50)
    assert out.x.shape == (5, 3, 3) and out.R.shape == (5, 3, 3, 3)
    np.testing.assert_allclose(out.t, [0, 0.05, 0.1, 0.15, 0.2])
    np.testing.assert_allclose(out.x[0], [b.position for b in bodies], atol=1e-14)
    np.testing.assert_allclose(out.W[0], [b.omega_body for b in bodies], atol=1e-13)
    assert out.settings["integrator"] == integrator and out.engine_time_s > 0
    assert loop_gap(out, bodies, joints[3]).max() < 1e-3


# -- planted mistakes at the builder's boundary ----------------------------------------------


def _replace(joints, i, **kw):
    joints = list(joints)
    joints[i] = dataclasses.replace(joints[i], **kw)
    return joints


def test_planted_axis_in_the_parents_frame_is_refused():
    bodies, joints = revolute_chain()
    bad = _replace(joints, 1, axis_b=joints[1].axis_a)  # l0's frame instead of l1's
    with pytest.raises(ms.InconsistentSystem, match=r"'h1'.*axis misalignment .*\) 1 rad"):
        ms.simulate_system(scenario("rev", bodies, bad), "RK4", 1e-3, 10, 10)


def test_planted_anchor_from_the_body_origin_is_refused():
    """Rod b1's anchor given from its end (a link frame at the joint) instead of its COM."""
    bodies, joints = rod_chain(3, hang=True)
    bad = _replace(joints, 1, anchor_b=(0.0, 0.0, 0.0))
    with pytest.raises(ms.InconsistentSystem, match=r"joint1.*anchor gap .* 0\.5 m"):
        ms.simulate_system(scenario("sph", bodies, bad), "RK4", 1e-3, 10, 10)


def test_planted_swapped_parent_and_child_is_refused():
    bodies, joints = rod_chain(3, hang=True)
    j = joints[2]
    bad = _replace(joints, 2, body_a=j.body_b, body_b=j.body_a)
    with pytest.raises(ms.InconsistentSystem, match=r"joint2' \(spherical 'b2'-'b1'\).*anchor gap"):
        ms.simulate_system(scenario("sph", bodies, bad), "RK4", 1e-3, 10, 10)


def test_planted_loop_closure_violation_is_refused():
    bodies, joints, _, _ = parallelogram_four_bar()
    bad = _replace(joints, 3, anchor_b=(0.5 + 1e-6, 0.0, 0.0))
    with pytest.raises(ms.InconsistentSystem, match=r"'B1'.*anchor gap .*1e-06 m"):
        ms.simulate_system(scenario("fb", bodies, bad), "RK4", 1e-3, 10, 10)


# The planted joint mistakes (axis in the parent's frame, anchor from the body origin, parent and
# child swapped) of every builder, MuJoCo's included:
# tests/references/engines/test_system_conformance.py.
PLANTS = {
    "COM off the body frame": (
        lambda x: x.replace('<inertial pos="0 0 0"', '<inertial pos="0 0 0.01"', 1),
        r"body 'l0': body_ipos",
    ),
    "joint damping": (lambda x: x.replace('damping="0"', 'damping="0.01"', 1), "dof_damping"),
    "joint limits": (
        lambda x: x.replace('limited="false"', 'limited="true" range="-1 1"', 1),
        "jnt_limited",
    ),
    "contacts on": (lambda x: x.replace('contact="disable" ', ""), "mjDSBL_CONTACT"),
    "sleeping on": (
        lambda x: x.replace('contact="disable"', 'contact="disable" sleep="enable"'),
        "mjENBL_SLEEP",
    ),
    "solver override on": (
        lambda x: x.replace('contact="disable"', 'contact="disable" override="enable"'),
        "mjENBL_OVERRIDE",
    ),
    "gravity compensation": (
        lambda x: x.replace('gravcomp="0"', 'gravcomp="1"', 1),
        "body_gravcomp",
    ),
}


@pytest.mark.parametrize("plant", PLANTS)
def test_planted_model_mistakes_are_caught_by_the_read_back(plant, monkeypatch):
    """A mistake written into the MJCF (the builder's boundary with MuJoCo) is caught when the
    compiled model is read back and compared with the scenario."""
    change, pattern = PLANTS[plant]
    real = ms.model_xml
    seen = []

    def planted(*a, **kw):
        xml = real(*a, **kw)
        out = change(xml)
        seen.append(out != xml)
        return out

    monkeypatch.setattr(ms, "model_xml", planted)
    bodies, joints = revolute_chain()
    with pytest.raises(EngineError, match=pattern):
        ms.simulate_system(scenario("rev", bodies, joints), "RK4", 1e-3, 10, 10)
    assert seen == [True]  # the plant took effect


def test_swapped_nesting_is_caught_by_the_read_back(monkeypatch):
    """The tree's parent and child swapped inside the builder (l1 attached as l0's parent):
    the read-back's expectations come from the same (wrong) plan, so MuJoCo's kinematics of
    the initial state, compared with the scenario's world states, catch it."""
    real = ms.plan

    def planted(sc):
        pl = real(sc)
        pl.tree[1].parent, pl.tree[0].parent = -1, 1
        pl.order = [1, 0, 2, 3]
        return pl

    monkeypatch.setattr(ms, "plan", planted)
    bodies, joints = revolute_chain()
    with pytest.raises(
        EngineError, match=r"kinematics of the initial state differ.*body 'l0': COM position"
    ):
        ms.simulate_system(scenario("rev", bodies, joints), "RK4", 1e-3, 10, 10)


def test_unsupported_joints_and_bad_settings():
    fb, fj, _, _ = parallelogram_four_bar()
    cyl = _replace(fj, 3, kind="cylindrical")
    with pytest.raises(Unsupported, match=r"'B1'.*cylindrical closure"):
        ms.simulate_system(scenario("c", fb, cyl), "RK4", 1e-3, 10, 10)
    pri = _replace(fj, 3, kind="prismatic")
    with pytest.raises(Unsupported, match=r"'B1'.*prismatic closure"):
        ms.simulate_system(scenario("p", fb, pri), "RK4", 1e-3, 10, 10)
    with pytest.raises(ValueError, match="unknown settings"):
        ms.simulate_system(scenario("fb", fb, fj), "RK4", 1e-3, 10, 10, solrf=(0.02, 1))
    with pytest.raises(ValueError, match="integrator 'RK45' unknown"):
        ms.simulate_system(scenario("fb", fb, fj), "RK45", 1e-3, 10, 10)


def test_default_solref_and_solimp_are_mujocos():
    """DEFAULT_SOLREF/SOLIMP are what MuJoCo compiles for a connect with none given."""
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="a"><freejoint/><inertial pos="0 0 0" mass="1" '
        'diaginertia="1 1 1"/></body></worldbody><equality><connect body1="a" '
        'anchor="0 0 0"/></equality></mujoco>'
    )
    np.testing.assert_array_equal(m.eq_solref[0], ms.DEFAULT_SOLREF)
    np.testing.assert_array_equal(m.eq_solimp[0], ms.DEFAULT_SOLIMP)


def rope(w0=2.0):
    """Three rods hanging like a trapezoid between the ground points (0, 0, 0) and (2.2, 0, 0),
    spherical joints throughout (a closed loop through the ground), swinging rigidly about the
    x axis at ``w0`` rad/s at t = 0; rod axis e3 along the rod."""
    P = np.array([(0, 0, 0), (0.6, 0, -0.8), (1.6, 0, -0.8), (2.2, 0, 0)], float)
    w = np.array([w0, 0.0, 0.0])
    bodies = []
    for k in range(3):
        e3 = (P[k + 1] - P[k]) / np.linalg.norm(P[k + 1] - P[k])
        e2 = np.array([0.0, 1.0, 0.0])
        R = np.column_stack([np.cross(e2, e3), e2, e3])
        x = (P[k] + P[k + 1]) / 2
        bodies.append(Body(f"r{k}", 1.0, (1 / 12 + 0.01, 1 / 12 + 0.01, 0.02), x, R,
                           np.cross(w, x), R.T @ w))  # fmt: skip
    joints = [
        Joint("spherical", "r0", None, (0, 0, -0.5), P[0], name="A"),
        Joint("spherical", "r0", "r1", (0, 0, 0.5), (0, 0, -0.5), name="B"),
        Joint("spherical", "r1", "r2", (0, 0, 0.5), (0, 0, -0.5), name="C"),
        Joint("fixed_point", "r2", None, (0, 0, 0.5), P[3], name="D"),
    ]
    return bodies, joints


def test_spherical_loop_closures_follow_rattle6():
    """Spherical loop closures: the rope (closed through the ground; the tree takes A, D and
    B, so C closes the loop between two bodies) and a rod held at both ends by spherical
    joints to the ground (one becomes a connect to a world site). RATTLE6 (dt 1 ms, exact
    constraints, error ~1e-12) is the reference; MuJoCo's difference from it is the soft
    constraints' give, which scales with the time constant squared: with (0.002, 1), asserted
    below 5e-5 m and rad (measured 5.2e-6 on the rope), with the loop gap below 1e-4 m."""
    rod_I = (0.1, 0.1, 0.02)
    R = np.column_stack([[0, 1.0, 0], [0, 0, 1.0], [1.0, 0, 0]])  # rod axis e3 along x
    x = np.array([0.5, 0.0, -0.3])
    w = np.array([3.0, 0.0, 0.0])
    gate = (
        [Body("gate", 2.0, rod_I, x, R, np.cross(w, x), R.T @ w)],
        [
            Joint("spherical", "gate", None, R.T @ (np.zeros(3) - x), (0, 0, 0), name="G0"),
            Joint("spherical", "gate", None, R.T @ (np.array([1.0, 0, 0]) - x), (1, 0, 0),
                  name="G1"),
        ],
    )  # fmt: skip
    for (bodies, joints), closing in ((rope(), "'C'"), (gate, "'G1'")):
        sc = scenario("loop", bodies, joints)
        out = ms.simulate_system(sc, "RK4", 1e-3, 2000, 100, solref=(0.002, 1))
        (closure,) = out.settings["loop closures"]
        assert closing in closure and "one site-to-site connect" in closure
        tr = director_simulate(bodies, joints, gravity=G, scheme="rattle6", dt=1e-3, t_end=2.0,
                               save_every=100)  # fmt: skip
        assert tr.constraint_position.max() < 1e-12
        d = max(np.abs(out.x - tr.position).max(), np.abs(out.R - tr.rotation).max())
        assert d < 5e-5, d
        j = joints[2] if closing == "'C'" else joints[1]
        names = [b.name for b in bodies]
        a = names.index(j.body_a)
        pa = out.x[:, a] + np.einsum("nij,j->ni", out.R[:, a], j.anchor_a)
        if j.body_b is None:
            pb = np.asarray(j.anchor_b, float)
        else:
            b = names.index(j.body_b)
            pb = out.x[:, b] + np.einsum("nij,j->ni", out.R[:, b], j.anchor_b)
        assert np.linalg.norm(pa - pb, axis=1).max() < 1e-4


def test_slide_joint_agrees_with_rattle6():
    """A hinge and a slide joint in a tree: MuJoCo RK4 against RATTLE6 (dt 1 ms; its own
    error measured by halving dt: 9e-16). Tolerance: 2 x RK4's Richardson estimate
    |y(1 ms) - y(2 ms)| / 15 plus 1e-13 for RATTLE6 (measured difference 9.6e-13, estimate
    9.6e-13)."""
    bodies, joints = slider()
    sc = scenario("slider", bodies, joints)
    o2 = ms.simulate_system(sc, "RK4", 2e-3, 500, 50)
    o1 = ms.simulate_system(sc, "RK4", 1e-3, 1000, 100)
    assert o1.settings["tree"] == {"rod": "hinge to ground", "collar": "slide to 'rod'"}
    tr = director_simulate(bodies, joints, gravity=G, scheme="rattle6", dt=1e-3, t_end=1.0,
                           save_every=100)  # fmt: skip
    rich = max(np.abs(o1.x - o2.x).max(), np.abs(o1.R - o2.R).max()) / 15
    d = max(np.abs(o1.x - tr.position).max(), np.abs(o1.R - tr.rotation).max())
    assert d <= 2 * rich + 1e-13, (d, rich)


# MJX (float64, trees and loops): tests/references/engines/test_mjx_system.py.


def rot_x(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def cardan():
    """A rod hung from the origin by a universal joint (the ground's axis world x, the rod's
    its body axis 2) and a sleeve on the rod joined by a cylindrical joint along the rod's
    axis 3 (the sleeve's principal axes permuted against the rod's), swinging about both
    universal axes, sliding and spinning at t = 0."""
    RA = rot_x(0.4)
    e3 = RA[:, 2]
    wA = 1.3 * np.array([1.0, 0, 0]) - 0.7 * RA[:, 1]
    xA = -0.5 * e3
    vA = np.cross(wA, xA)
    turned = np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]])
    RB = RA @ turned
    xB = xA - 0.2 * e3
    wB = wA + 2.5 * e3
    vB = vA + np.cross(wA, xB - xA) + 0.3 * e3
    bodies = [
        Body("rod", 1.0, (0.1, 0.1, 0.02), xA, RA, vA, RA.T @ wA),
        Body("sleeve", 0.4, (0.011, 0.013, 0.016), xB, RB, vB, RB.T @ wB),
    ]
    joints = [
        Joint("universal", "rod", None, (0, 0, 0.5), (0, 0, 0), (0, 1, 0), (1, 0, 0), name="U"),
        Joint("cylindrical", "rod", "sleeve", (0, 0, 0), (0, 0, 0), (0, 0, 1),
              turned.T @ np.array([0, 0, 1.0]), name="C"),
    ]  # fmt: skip
    return bodies, joints


def test_universal_and_cylindrical_joints_agree_with_rattle6():
    """A universal joint (two hinges in one body: about the parent-fixed axis, then the
    child-fixed one) and a cylindrical joint (a hinge and a slide on one axis) under gravity:
    MuJoCo RK4 against RATTLE6 (dt 1 ms); tolerance as for the slide joint: 2 x RK4's
    Richardson estimate plus 1e-13 for RATTLE6 (measured 4e-16 between dt 1 ms and 0.5 ms;
    MuJoCo's difference from it 5.9e-13, its Richardson estimate 5.8e-13)."""
    bodies, joints = cardan()
    sc = scenario("cardan", bodies, joints)
    o2 = ms.simulate_system(sc, "RK4", 2e-3, 500, 50)
    o1 = ms.simulate_system(sc, "RK4", 1e-3, 1000, 100)
    assert o1.settings["tree"] == {
        "rod": "universal to ground",
        "sleeve": "cylindrical to 'rod'",
    }
    tr = director_simulate(bodies, joints, gravity=G, scheme="rattle6", dt=1e-3, t_end=1.0,
                           save_every=100)  # fmt: skip
    rich = max(np.abs(o1.x - o2.x).max(), np.abs(o1.R - o2.R).max()) / 15
    d = max(np.abs(o1.x - tr.position).max(), np.abs(o1.R - tr.rotation).max())
    assert d <= 2 * rich + 1e-13, (d, rich)
    # a universal's axes must be perpendicular and turn so at t = 0: a rate along u_a x u_b
    bad = list(bodies)
    bad[0] = dataclasses.replace(bodies[0], omega_body=bodies[0].omega_body + (0, 0, 0.1))
    with pytest.raises(ms.InconsistentSystem, match=r"'U'.*d/dt \(u_a \. u_b\)"):
        ms.simulate_system(scenario("cardan", bad, joints), "RK4", 1e-3, 10, 10)


def test_a_blow_up_is_reported_with_the_states_before_it():
    """Euler at dt = 0.2 s on the spinning 3-rod chain (rates of a few rad/s: h w ~ 1) blows
    up; MuJoCo flags it and the run ends as Diverged carrying the saved states before it."""
    from references.errors import Diverged

    bodies, joints = rod_chain(3, hang=True)
    with pytest.raises(Diverged, match="MuJoCo flagged an unstable state") as info:
        ms.simulate_system(scenario("c", bodies, joints), "Euler", 0.2, 2000, 10)
    out = info.value.output
    assert 0 < info.value.t_diverged <= 400 and out.t[0] == 0.0
    assert np.all(np.isfinite(out.x)) and out.x.shape[0] == len(out.t)
