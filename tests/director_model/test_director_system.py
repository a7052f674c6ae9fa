"""director_model.system: the API, RATTLE on a system, conservation, restart, bad input.

Expected values come from the single-body integrator (a different formulation: the pivot
eliminated, Moser-Veselov on the pivot inertia), from exact conservation laws and from the
closed-form input rules; no value is copied from the code under test.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import director_model as dm
from director_model.system import (
    Body,
    InvalidJointError,
    InvalidMechanismError,
    Joint,
    SystemStepper,
    project_velocities,
    simulate_system,
)
from director_model.system.examples import rod_chain

EPS = np.finfo(float).eps


def heavy_top_both_ways(scheme):
    c = np.array([0.0, 0.0, -0.5])
    R0 = dm.rotation_from_quat_wxyz([np.cos(0.025), np.sin(0.025), 0, 0])
    W0 = np.array([0.3, -0.2, 50.0])
    g = (0.0, 0.0, -40.0)
    ref = dm.simulate(
        1.0, (4.75, 4.75, 1.0), rotation=R0, omega_body=W0, gravity=g, pivot=c, dt=2e-3,
        t_end=0.4, save_every=20, scheme=scheme,
    )  # fmt: skip
    body = Body("top", 1.0, (4.75, 4.75, 1.0), position=-R0 @ c, rotation=R0,
                velocity=-R0 @ np.cross(W0, c), omega_body=W0)  # fmt: skip
    j = Joint("fixed_point", "top", None, anchor_a=c, anchor_b=(0, 0, 0))
    tr = simulate_system([body], [j], gravity=g, dt=2e-3, t_end=0.4, save_every=20, scheme=scheme)
    return ref, tr


@pytest.mark.parametrize("scheme", ["rattle", "rattle4", "rattle6"])
def test_one_body_with_a_fixed_point_is_the_single_body_pivoted_run(scheme):
    # the single-body code eliminates the pivot (Moser-Veselov on the pivot inertia), the
    # system code keeps it as 3 multipliers: the same RATTLE map, so they agree to the
    # round-off of 200 steps of |W| = 50 (a few hundred ulps of the O(50) momentum)
    ref, tr = heavy_top_both_ways(scheme)
    assert np.abs(tr.rotation[:, 0] - ref.rotation).max() < 1e-12
    assert np.abs(tr.omega_body[:, 0] - ref.omega_body).max() < 1e-11
    assert np.abs(tr.position[:, 0] - ref.position).max() < 1e-12
    assert np.abs(tr.energy - ref.energy).max() < 1e-9  # E ~ 1300 J: a few ulps
    assert tr.constraint_position.max() < 16 * EPS and tr.constraint_velocity.max() < 1e-13


@pytest.mark.parametrize("hang", [True, False])
def test_chain_keeps_constraints_and_momentum_maps(hang):
    bodies, joints = rod_chain(5, hang)
    g = (0.0, 0.0, -9.81) if hang else (0.0, 0.0, 0.0)
    tr = simulate_system(bodies, joints, gravity=g, dt=1e-3, t_end=2.0, save_every=100)
    # RATTLE keeps every joint row to the Newton tolerance (16 eps x length scale ~ 1e-14)
    assert tr.constraint_position.max() < 1e-13
    assert tr.constraint_velocity.max() < 1e-13
    assert tr.orthonormality.max() < 1e-14
    L = tr.angular_momentum
    if hang:  # only the vertical angular momentum about the pivot is a momentum map
        assert np.ptp(L[:, 2]) < 1e-13 * max(1.0, np.abs(L).max())
    else:  # free floating: linear and angular momentum
        assert np.ptp(tr.linear_momentum, axis=0).max() < 1e-13
        assert np.ptp(L, axis=0).max() < 1e-13 * max(1.0, np.abs(L).max())
    # energy bounded: RATTLE's O(h^2) error at h = 1e-3 on an O(10 J) system
    assert np.ptp(tr.energy) < 1e-3 * max(1.0, np.abs(tr.energy).max())


def test_lamina_chain_integrates_and_conserves():
    # I = (0.05, 0.08, 0.13): J_3 = (0.05 + 0.08 - 0.13)/2 = 0, a flat body; the director
    # mass matrix is singular, the scheme never inverts it
    bodies, joints = rod_chain(3, False, inertia=(0.05, 0.08, 0.13))
    assert any(b.J[2] == 0.0 for b in bodies)
    tr = simulate_system(bodies, joints, dt=1e-3, t_end=1.0, save_every=100, scheme="rattle4")
    assert np.all(np.isfinite(tr.rotation))
    assert np.ptp(tr.angular_momentum, axis=0).max() < 1e-13
    assert tr.constraint_position.max() < 1e-13


@pytest.mark.parametrize("scheme", ["rattle", "rattle6"])
def test_stepper_chunks_equal_one_run_bit_for_bit(scheme):
    bodies, joints = rod_chain(4, True, seed=3)
    kw = dict(gravity=(0.0, 0.0, -9.81), scheme=scheme, dt=2e-3)
    one = SystemStepper(bodies, joints, **kw).advance(50, save_every=5, include_start=True)
    st = SystemStepper(bodies, joints, **kw)
    a = st.advance(20, save_every=5, include_start=True)
    b = st.advance(30, save_every=5)
    for f in ("position", "velocity", "rotation", "omega_body"):
        both = np.concatenate([getattr(a, f), getattr(b, f)])
        assert np.array_equal(both, getattr(one, f)), f
    assert np.array_equal(np.concatenate([a.t, b.t]), one.t)
    assert st.nstep_done == 50


def test_gap_velocity_and_name_errors():
    bodies, joints = rod_chain(2, True, spin=False)
    moved = [bodies[0], Body("b1", 1.0, bodies[1].inertia, bodies[1].position + [0, 0.002, 0],
                             bodies[1].rotation)]  # fmt: skip
    with pytest.raises(InvalidJointError, match=r"joint 'joint1'.*gap .* = 0.002 m"):
        SystemStepper(moved, joints, dt=1e-3)
    fast = [bodies[0], Body("b1", 1.0, bodies[1].inertia, bodies[1].position,
                            bodies[1].rotation, velocity=(0.5, 0, 0))]  # fmt: skip
    with pytest.raises(dm.InvalidStateError, match=r"joint 'joint1'.*0\.5.*project_velocities"):
        SystemStepper(fast, joints, dt=1e-3)
    # the explicit projection makes them consistent (and keeps the total momentum here:
    # the joint forces are internal)
    fixed = project_velocities(fast, joints[1:])
    assert np.allclose(sum(b.mass * b.velocity for b in fixed), (0.5, 0, 0), atol=1e-14)
    SystemStepper(fixed, joints[1:], dt=1e-3)
    with pytest.raises(InvalidJointError, match=r"body_b = 'b7': unknown body"):
        SystemStepper(bodies, [Joint("spherical", "b0", "b7")], dt=1e-3)
    with pytest.raises(InvalidJointError, match=r"kind = 'ball': unknown"):
        SystemStepper(bodies, [Joint("ball", "b0", "b1")], dt=1e-3)


def test_body_errors():
    with pytest.raises(dm.InvalidBodyError, match=r"body 'x': mass = 0.0: must be positive"):
        Body("x", 0.0, (1, 1, 1))
    with pytest.raises(dm.InvalidBodyError, match=r"body 'x': mass = -1.0"):
        Body("x", -1.0, (1, 1, 1))
    with pytest.raises(dm.InvalidBodyError, match=r"body 'x'.*triangle inequality"):
        Body("x", 1.0, (2.0, 1.0, 2.0 / 3.0))
    with pytest.raises(dm.InvalidBodyError, match=r"body 'rod'.*thin rod"):
        Body("rod", 1.0, (0.0, 1.0, 1.0))
    with pytest.raises(dm.InvalidBodyError, match=r"used twice"):
        SystemStepper([Body("a", 1.0), Body("a", 1.0)], [], dt=1e-3)


def test_locked_mechanism_is_refused():
    # a body held at two points and by an axis lock: no degree of freedom left
    b = Body("b", 1.0, (1.0, 2.0, 2.5), position=(0, 0, -1))
    j = [Joint("revolute", "b", None, (0, 0, 1), (0, 0, 0), (1, 0, 0), (1, 0, 0)),
         Joint("spherical", "b", None, (0, 0, -1), (0, 0, -2))]  # fmt: skip
    with pytest.raises(InvalidMechanismError, match="locked"):
        SystemStepper([b], j, dt=1e-3)


def test_misaligned_revolute_axes_are_refused():
    b = Body("b", 1.0, (1.0, 2.0, 2.5), position=(0, 0, -1))
    j = [Joint("revolute", "b", None, (0, 0, 1), (0, 0, 0), (1, 0, 0), (0, 1, 0))]
    with pytest.raises(InvalidJointError, match=r"dot product .* axes is -1 where it must be 0"):
        SystemStepper([b], j, dt=1e-3)


def test_an_anchor_off_a_cylindrical_axis_is_refused_with_its_distance():
    """A cylindrical joint lets anchor_b slide along the axis line through anchor_a (0.7 m
    along x: accepted) but not leave it: 0.3 m along y and 0.4 m along z is 0.5 m off."""
    b = Body("b", 1.0, (1.0, 2.0, 2.5), position=(0, 0, -1))

    def joint(anchor_b):
        return [Joint("cylindrical", "b", None, (0, 0, 1), anchor_b, (1, 0, 0), (1, 0, 0))]

    SystemStepper([b], joint((0.7, 0.0, 0.0)), dt=1e-3)
    with pytest.raises(InvalidJointError, match=r"not on the axis line .* distance 0\.5 m"):
        SystemStepper([b], joint((0.0, 0.3, 0.4)), dt=1e-3)


def test_step_beyond_solvability_raises_with_time_and_step():
    # a free spinning body in a chain: h |W| >= 1 has no solution of the rotation equation
    bodies, joints = rod_chain(2, False, spin=False)
    b1 = bodies[1]
    spin = [bodies[0], Body("b1", 1.0, b1.inertia, b1.position, b1.rotation,
                            omega_body=b1.rotation.T @ (b1.rotation @ [0, 0, 400.0]))]  # fmt: skip
    st = SystemStepper(spin, joints, dt=0.01)
    with pytest.raises(dm.StepSizeError, match=r"step 1 starting at t = 0 s") as err:
        st.advance(5)
    assert err.value.time == 0.0 and err.value.step == 1


def test_closed_loop_chunks_equal_one_run_bit_for_bit():
    # the minimum-norm path (a planar four-bar of revolutes: 20 rows of rank 17) restarts
    # bitwise too: its state is the director state and the last multipliers
    from director_model.system.examples import parallelogram_four_bar

    b, j, _, _ = parallelogram_four_bar()
    kw = dict(gravity=(0.0, 0.0, -9.81), scheme="rattle4", dt=2e-3)
    one = SystemStepper(b, j, **kw).advance(40, save_every=10)
    st = SystemStepper(b, j, **kw)
    parts = [st.advance(10, save_every=10), st.advance(30, save_every=10)]
    assert np.array_equal(np.concatenate([p.rotation for p in parts]), one.rotation)
    assert np.array_equal(np.concatenate([p.velocity for p in parts]), one.velocity)


@pytest.mark.slow
def test_million_steps_conservation():
    # benchmarks/system_conservation.py measured on this chain: joints within the Newton
    # tolerance (16 eps x the largest coordinate), p drift 4.4e-16, L drift 1.4e-13 .. 3.0e-13
    # (at |x| = 418 m), energy error 4.7e-7 J in the first tenth, 4.8e-7 .. 5.9e-7 in the last
    b, j = rod_chain(5, False, seed=11)
    tr = SystemStepper(b, j, dt=1e-3).advance(1_000_000, save_every=1000, include_start=True)
    xmax = np.abs(tr.position).max(axis=(1, 2))
    # the kernel's tolerance, doubled for the rounding of the numpy evaluation of the rows
    assert np.all(tr.constraint_position <= 32 * EPS * np.maximum(xmax, 1.0))
    assert tr.constraint_velocity.max() < 1e-13
    assert np.abs(tr.linear_momentum - tr.linear_momentum[0]).max() < 1e-14
    assert np.abs(tr.angular_momentum - tr.angular_momentum[0]).max() < 3e-12
    dE = np.abs(tr.energy - tr.energy[0])
    k = len(tr) // 10
    assert dE[-k:].max() < 2 * dE[:k].max()  # bounded, no drift


def test_block_solver_equals_banded_to_round_off():
    # the same equations solved by block-tridiagonal elimination (3x3 blocks, the default
    # for ball-joint chains) and by the generic banded LU: equal to round-off amplified by
    # 200 steps of a tumbling hanging chain (measured 6.7e-16 .. 1.5e-14 over 3000 steps)
    bodies, joints = rod_chain(5, True, seed=2)
    runs = {}
    for solver in ("block", "banded"):
        st = SystemStepper(bodies, joints, gravity=(0, 0, -9.81), dt=1e-3, solver=solver)
        runs[solver] = st.advance(200, save_every=200)
        assert runs[solver].solver == solver
    assert np.abs(runs["block"].rotation - runs["banded"].rotation).max() < 1e-13
    assert np.abs(runs["block"].velocity - runs["banded"].velocity).max() < 1e-12
    with pytest.raises(dm.InvalidRunError, match="solver = 'block': needs spherical"):
        b = Body("b", 1.0, (1.0, 2.0, 2.5), position=(0, 0, -1))
        j = [Joint("revolute", "b", None, (0, 0, 1), (0, 0, 0), (1, 0, 0), (1, 0, 0))]
        SystemStepper([b], j, dt=1e-3, solver="block")


def test_kernels_one_signature_each():
    """Each numba function of the system kernels is compiled for one signature whatever the
    solver (a constant flag or index, a non-contiguous view or another integer width would
    add a specialisation, and with it compile time), except the step itself, once per
    entry (the banded solver's and the others'). A kernel loaded from numba's cache
    compiles no helper at all, which also passes."""
    from director_model.system import _kernels as K

    bodies, joints = rod_chain(3, hang=True, seed=1)
    for solver in ("block", "banded", "minnorm"):
        simulate_system(bodies, joints, gravity=(0, 0, -9.81), dt=1e-3, t_end=3e-3,
                        solver=solver)  # fmt: skip
    counts = {name: len(f.overloads) for name, f in vars(K).items() if hasattr(f, "overloads")}
    assert counts["run_system"] == 1 and counts["run_system_banded"] == 1
    assert counts["_run_system"] <= 2
    assert all(n <= 1 for name, n in counts.items() if name != "_run_system"), counts


def test_block_and_minnorm_runs_leave_the_banded_entry_alone():
    """Runs with the block and the minnorm solvers compile (or load) run_system only, not the
    banded solver's entry (a fresh process: the other tests here run the banded solver)."""
    code = (
        "from director_model.system import _kernels as K, simulate_system\n"
        "from director_model.system.examples import rod_chain\n"
        "from director_model.system.examples import parallelogram_four_bar\n"
        "b, j = rod_chain(3, hang=True, seed=1)\n"
        "assert simulate_system(b, j, dt=1e-3, t_end=3e-3).solver == 'block'\n"
        "b, j, _, _ = parallelogram_four_bar()\n"
        "assert simulate_system(b, j, dt=1e-3, t_end=3e-3).solver == 'minnorm'\n"
        "print(len(K.run_system.overloads), len(K.run_system_banded.overloads))\n"
    )
    root = Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True,
                         text=True, check=True, timeout=600)  # fmt: skip
    assert out.stdout.split() == ["1", "0"], out.stdout + out.stderr


@pytest.mark.parametrize("n", [1, 2, 5, 9])
def test_svd_factor_against_numpy(n):
    """The kernels' SVD (dgesdd called directly, A overwritten): the singular values of
    numpy's SVD, orthogonal U and Vt, U diag(s) Vt = A, the rank count; -1 for a non-finite
    A."""
    from director_model.system import _solvers as SV

    rng = np.random.default_rng(n)
    A = rng.standard_normal((n, n))
    if n > 2:
        A[-1] = A[0] + A[1]  # rank n - 1
    U, s, Vt = np.zeros((n, n)), np.zeros(n), np.zeros((n, n))
    rank = SV._svd_factor(A.copy(), 1e-12, U, s, Vt)
    s_ref = np.linalg.svd(A, compute_uv=False)
    np.testing.assert_allclose(s, s_ref, rtol=1e-13, atol=1e-14 * s_ref[0])
    np.testing.assert_allclose(U @ U.T, np.eye(n), atol=1e-14 * n)
    np.testing.assert_allclose(Vt @ Vt.T, np.eye(n), atol=1e-14 * n)
    np.testing.assert_allclose((U * s) @ Vt, A, atol=1e-14 * n * s_ref[0])
    assert rank == (n - 1 if n > 2 else n)
    A[0, 0] = np.nan
    assert SV._svd_factor(A, 1e-12, U, s, Vt) == -1
