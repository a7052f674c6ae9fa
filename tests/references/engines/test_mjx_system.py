"""The MJX builder for systems of bodies (references/engines/mjx/system.py), float64: trees
and loops closed by MuJoCo's equality connects, stepped by MJX's JAX backend.

Expected values: C MuJoCo (the same model, MJX's Euler is MuJoCo's algorithm), the
reduced-coordinate reference (references/exact/multibody) and the exact planar pendulum of
the parallelogram four-bar (scipy DOP853 on one ODE). JAX compiles MJX's step once per model
and integrator (2 to 45 s on 2 loaded cores, less from JAX's persistent cache): the runs are
``slow``; the read-back and the refusals compile nothing.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco.mjx")

from director_model.system.examples import parallelogram_four_bar, rod_chain  # noqa: E402
from references.engines.mjx import system as mjx_system  # noqa: E402
from references.engines.mujoco import system as ms  # noqa: E402
from references.engines.system_conformance import scenario  # noqa: E402
from references.errors import EngineError, Unsupported  # noqa: E402
from tests.references.engines.test_mujoco_system import four_bar_solref_errors, max_err, reference  # noqa: E402


def test_mjx_refuses_the_integrators_it_lacks_and_float32():
    bodies, joints = rod_chain(3, hang=True)
    for name in ("implicit", "discrete"):
        with pytest.raises(Unsupported, match=f"does not implement MuJoCo's {name}"):
            mjx_system.simulate_system(scenario("c", bodies, joints), name, 1e-3, 10, 10)
    with pytest.raises(Unsupported, match="float64 only"):
        mjx_system.simulate_system(scenario("c", bodies, joints), "Euler (float32)", 1e-3, 1, 1)
    with pytest.raises(ValueError, match=r"mjx simulate_system: unknown settings \['erp'\]"):
        mjx_system.simulate_system(scenario("c", bodies, joints), "Euler", 1e-3, 1, 1, erp=0.2)


def test_mjx_read_back_catches_a_model_that_differs_from_the_c_model():
    """The MJX model of the four-bar holds the C model's connects, solref, solimp and solver
    settings; each planted difference is named."""
    from references.engines.mjx.compile import _import

    _, jax, mjx = _import()
    bodies, joints, _, _ = parallelogram_four_bar()
    sc = scenario("fb", bodies, joints)
    _, m, _, _, _, _ = ms.build(sc, "Euler", 1e-3, solref=(0.004, 1.0))
    with jax.enable_x64(True):
        mx = mjx.put_model(m, impl="jax")
    mjx_system.read_back(m, mx, sc)  # as put: passes
    assert np.asarray(mx.eq_solref).tolist() == [[0.004, 1.0], [0.004, 1.0]]
    plants = {
        "eq_solref": mx.replace(eq_solref=np.asarray(mx.eq_solref) * 2),
        "eq_solimp": mx.replace(eq_solimp=np.asarray(mx.eq_solimp) * 0.9),
        "eq_obj2id": mx.replace(eq_obj2id=np.asarray(mx.eq_obj2id)[::-1]),
        "opt.iterations": mx.replace(opt=mx.opt.replace(iterations=5)),
    }
    for what, bad in plants.items():
        with pytest.raises(EngineError, match=rf"MJX model differs from the C model: {what}"):
            mjx_system.read_back(m, bad, sc)


@pytest.mark.slow
def test_mjx_closes_the_four_bar_with_mujocos_connects():
    """The parallelogram four-bar over 1 s (through its singular configuration twice) on MJX's
    Euler at dt 1 ms with MuJoCo's default solref (0.02, 1) and a stiffer (0.002, 1): the
    settings are the C builder's (two site-to-site connects on B1, solref and solimp as
    given); the loop gap is that of a soft constraint, at most 1e-3 m with the default and
    more than 10 times smaller with the stiffer one (a time constant 10 times shorter;
    measured 2.8e-4 and 5.1e-6 m, C MuJoCo 2.9e-4 and 5.2e-6); the crank follows the exact
    planar pendulum to 0.02 rad and 1e-3 rad (measured 3.1e-3 and 2.4e-4; C MuJoCo 4.9e-3 and
    2.4e-4): the linkage stays on its branch (the crossed branch is off by O(1)).
    MJX and C MuJoCo differ by up to 1.4e-3 m with the default solref: MJX's reference
    acceleration of a connect lacks C MuJoCo's Jdot v term (test below), and the difference
    grows at the singular passages; with the stiffer solref 1.8e-6 m."""
    theta_err = four_bar_solref_errors(mjx_system, "Euler (float64)", 1.0)
    assert theta_err[(0.02, 1.0)] < 0.02 and theta_err[(0.002, 1.0)] < 1e-3, theta_err


@pytest.mark.slow
def test_mjx_float64_tree_euler_equals_c_mujoco_and_rk4_converges():
    """MJX's Euler is MuJoCo's algorithm: on the 3-body spherical chain over 1 s (1000 steps)
    it equals C MuJoCo's Euler to round-off (measured 5e-15 m, 3e-14 rad/s; asserted 1e-12,
    the growth of a few ulps per step over 1000 steps). MJX's RK4 against the reduced
    reference at dt 2 ms and 1 ms: its attitude is order 2 (positions advanced once by the
    exponential map of the mean stage velocity; docs/engines.md, MJX): the observed order
    lies in 1.5 .. 2.5 (measured 2.00: 7.7e-5, 1.9e-5, 4.8e-6 at 2, 1, 0.5 ms) and the error at
    1 ms is far above C MuJoCo's RK4 (1.4e-10).
    JAX compiles the step once per integrator (15 to 45 s on 2 loaded cores)."""
    bodies, joints = rod_chain(3, hang=True)
    sc = scenario("chain", bodies, joints)
    mjx = mjx_system.simulate_system(sc, "Euler", 1e-3, 1000, 100)
    c = ms.simulate_system(sc, "Euler", 1e-3, 1000, 100)
    assert "float64" in mjx.settings["precision"]
    for key in ("x", "R", "v", "W"):
        assert np.abs(getattr(mjx, key) - getattr(c, key)).max() < 1e-12, key
    out = {dt: mjx_system.simulate_system(sc, "RK4", dt, round(1 / dt), round(0.1 / dt))
           for dt in (2e-3, 1e-3)}  # fmt: skip
    sol, perm = reference(bodies, joints, out[1e-3]["t"])
    e = {dt: max_err(o, sol.x[:, perm], sol.R[:, perm]) for dt, o in out.items()}
    assert 1.5 <= np.log2(e[2e-3] / e[1e-3]) <= 2.5, e
    assert e[1e-3] > 1e-8, e


@pytest.mark.slow
def test_mjx_connect_reference_acceleration_lacks_c_mujocos_jdot_v():
    """On the four-bar after 20 Euler steps the connect rows of MJX and C MuJoCo share their
    position error, Jacobian and impedance, and their reference accelerations differ by
    exactly the velocity-product term Jdot v that C MuJoCo subtracts for connect rows
    (mj_referenceConstraint -> mj_Jdotv): C's aref = MJX's aref - Jdot v, with Jdot v computed
    here by central differences of C's efc_J along qvel (step 1e-6: truncation ~1e-12, the
    rows' round-off ~1e-10 over 2e-6; bound 1e-8 of aref's size ~1). Documents where MJX's
    loops part from C MuJoCo's; fails when MJX adds the term."""
    from references.engines.mjx.compile import _import

    _, jax, mjx = _import()
    bodies, joints, _, _ = parallelogram_four_bar()
    mujoco, m, d, _, _, _ = ms.build(scenario("fb", bodies, joints), "Euler", 1e-3)
    mujoco.mj_step(m, d, 20)
    mujoco.mj_forward(m, d)
    with jax.enable_x64(True):
        dx = jax.jit(mjx.forward)(mjx.put_model(m, impl="jax"), mjx.put_data(m, d, impl="jax"))
    im = dx._impl
    n = d.nefc
    np.testing.assert_allclose(np.asarray(im.efc_pos)[:n], d.efc_pos, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(im.efc_J)[:n], d.efc_J.reshape(n, m.nv), atol=1e-14)
    np.testing.assert_allclose(np.asarray(im.efc_D)[:n], d.efc_D, rtol=1e-12)

    def jac(q):
        dd = mujoco.MjData(m)
        dd.qpos[:], dd.qvel[:] = q, d.qvel
        mujoco.mj_forward(m, dd)
        return dd.efc_J.reshape(dd.nefc, m.nv).copy()

    qp, qm = d.qpos.copy(), d.qpos.copy()
    mujoco.mj_integratePos(m, qp, d.qvel, 1e-6)
    mujoco.mj_integratePos(m, qm, d.qvel, -1e-6)
    jdotv = (jac(qp) - jac(qm)) @ d.qvel / 2e-6
    aref_mjx = np.asarray(im.efc_aref)[:n]
    assert np.abs(jdotv).max() > 1e-4  # the term is not negligible here (measured 8.4e-3)
    np.testing.assert_allclose(d.efc_aref, aref_mjx - jdotv, rtol=0, atol=1e-8)


def c_euler_with_mjx_aref(sc, dt, nstep, **settings):
    """C MuJoCo's Euler with the reference acceleration MJX uses, aref = -B J v - K imp r (C's
    Jdot v term left out): mj_step's stages called one by one, efc_aref replaced between
    mj_fwdVelocity (which computes it) and mj_fwdConstraint (which uses it). Returns (x, R)
    after nstep steps and the largest |C's aref - this aref| met (the Jdot v C subtracts)."""
    mujoco, m, d, _, bid, _ = ms.build(sc, "Euler", dt, **settings)
    largest = 0.0
    for _ in range(nstep):
        mujoco.mj_fwdPosition(m, d)
        mujoco.mj_fwdVelocity(m, d)
        K, B, imp = d.efc_KBIP[:, 0], d.efc_KBIP[:, 1], d.efc_KBIP[:, 2]
        aref = -B * d.efc_vel - K * imp * (d.efc_pos - d.efc_margin)
        largest = max(largest, float(np.abs(aref - d.efc_aref).max(initial=0.0)))
        d.efc_aref[:] = aref
        mujoco.mj_fwdActuation(m, d)
        mujoco.mj_fwdAcceleration(m, d)
        mujoco.mj_fwdConstraint(m, d)
        mujoco.mj_Euler(m, d)
    x, R, _, _ = ms.read_states(mujoco, m, d, bid)
    return x, R, largest


@pytest.mark.slow
def test_the_jdot_v_term_is_the_whole_difference_between_mjx_and_c_mujoco_on_a_loop():
    """four_bar_stiff_loop (solref 0.004), 0.6 s of Euler at dt 2 ms: MJX and C MuJoCo end
    2.8e-5 apart (measured); C MuJoCo with MJX's reference acceleration ends 5.2e-15 from MJX
    (measured): the connect rows' Jdot v (up to 0.14 here) is all that parts them. The same
    comparison over the library's loops (docs/engines.md, MJX): four_bar 1.8e-3 vs 2.3e-15,
    bricard 8.7e-4 vs 3.2e-15, slider_crank_spatial with solref 0.002 2.0e-2 vs 6.0e-13,
    iftomm_a02_n2 1.81 vs 5.2e-12."""
    import scenarios

    sc = scenarios.load("four_bar_stiff_loop")
    settings = dict(sc.engine_settings.get("mujoco", {}))
    n = int(round(sc.t_end / sc.dt))
    mx = mjx_system.simulate_system(sc, "Euler (float64)", sc.dt, n, n, **settings)
    c = ms.simulate_system(sc, "Euler", sc.dt, n, n, **settings)
    xa, Ra, jdv = c_euler_with_mjx_aref(sc, sc.dt, n, **settings)
    apart = max(np.abs(mx.x[-1] - c.x[-1]).max(), np.abs(mx.R[-1] - c.R[-1]).max())
    same = max(np.abs(mx.x[-1] - xa).max(), np.abs(mx.R[-1] - Ra).max())
    assert apart > 1e-6 and jdv > 1e-2
    assert same < 1e-12


@pytest.mark.slow
def test_mjx_slide_universal_and_cylindrical_joints_equal_c_mujoco():
    """The C builder's slide, universal (two hinges) and cylindrical (hinge and slide) joints
    stepped by MJX's Euler equal C MuJoCo's Euler over 500 steps to round-off (measured 2.2e-15
    and 1.2e-15; bound 1e-12 as for the spherical chain)."""
    from references.engines.system_conformance import slider
    from tests.references.engines.test_mujoco_system import cardan

    for name, (bodies, joints) in (("slider", slider()), ("cardan", cardan())):
        sc = scenario(name, bodies, joints)
        out = mjx_system.simulate_system(sc, "Euler", 1e-3, 500, 100)
        c = ms.simulate_system(sc, "Euler", 1e-3, 500, 100)
        assert out.settings["tree"] == c.settings["tree"]
        for key in ("x", "R", "v", "W"):
            assert np.abs(getattr(out, key) - getattr(c, key)).max() < 1e-12, (name, key)


@pytest.mark.slow
def test_a_system_in_float64_leaves_a_single_body_in_float32_runnable():
    """One process steps a system of bodies with MJX's RK4 in float64, then a single body with
    MJX's RK4 in float32 (the order of a suite run). JAX keeps traces of MJX's RK4 (whose
    tableau is a numpy float64 constant) in caches not keyed by the 64-bit mode, so without
    the adapter's precision switch the float32 step was lowered with the float64 tableau and
    refused ("Cannot lower jaxpr ... tensor<3x3xf32> ... tensor<3x3xf64>"). The float32 run
    must complete and hold float32 numbers (its RK4 agrees with MJX's float64 RK4 to float32
    round-off: 1e-4 rad over 100 steps, about 100 * 64 u32 ~ 4e-4 with the margin of the
    adapter's FLOAT32_INITIAL_RTOL per step, measured below 1e-5)."""
    from references.engines import conformance as kit
    from references.engines import get_engine

    bodies, joints = rod_chain(2, hang=True)
    out = mjx_system.simulate_system(scenario("chain", bodies, joints), "RK4", 1e-3, 20, 10)
    assert "float64" in out.settings["precision"]
    sc = kit.free_scenario(t_end=0.1)
    f32 = get_engine("mjx")().run(sc, "RK4 (float32)", sc.dt, save_every=50)
    assert "float32" in str(f32.settings), f32.settings
    f64 = get_engine("mjx")().run(sc, "RK4 (float64)", sc.dt, save_every=50)
    R32, R64 = f32.trajectory.rotation, f64.trajectory.rotation
    gap = np.linalg.norm(R32 - R64, axis=(-2, -1)).max()
    assert 0 < gap < 1e-4, gap
