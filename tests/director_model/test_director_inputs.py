"""director_model: body/state/run validation, conversions and invariant formulas.

Expected values come from closed-form facts (J_i = (I_j + I_k - I_i)/2, textbook energy and
angular momentum) and from scipy as an independent implementation of the conversions.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import director_model as dm
from director_model import invariants as inv

EPS = np.finfo(float).eps
R0 = Rotation.from_rotvec([0.3, -0.5, 0.7]).as_matrix()
W0 = np.array([0.4, -1.3, 2.1])


def run(**kw):
    args = dict(rotation=R0, omega_body=W0, dt=0.01, t_end=0.1)
    args.update(kw)
    mass = args.pop("mass", 1.0)
    inertia = args.pop("inertia", (2.0, 3.0, 4.0))
    return dm.simulate(mass, inertia, **args)


# --- body ----------------------------------------------------------------------------------
def test_convected_moments_exact():
    # J_i = (I_j + I_k - I_i)/2; these small integers/halves are exact in binary
    assert np.array_equal(dm.validate_body(1.0, (2.0, 3.0, 4.0)), [2.5, 1.5, 0.5])
    assert np.array_equal(dm.validate_body(1.0, (1.0, 2.0, 3.0)), [2.0, 1.0, 0.0])  # flat
    assert np.array_equal(dm.validate_body(1.0, (0.25, 0.25, 0.5)), [0.25, 0.25, 0.0])  # disk


def test_flat_tolerance_is_rounding_only():
    # 0.1 + 0.2 - 0.3 is 5.6e-17, not 0: a lamina up to rounding, not a triangle violation
    J = dm.validate_body(1.0, (0.3, 0.1, 0.2))
    assert J[0] == 0.0 and J[1] > 0 and J[2] > 0


@pytest.mark.parametrize(
    "mass, inertia, pivot, match",
    [
        (0.0, (2, 3, 4), None, r"mass = 0\.0: must be positive and finite"),
        (-1.0, (2, 3, 4), None, r"mass = -1\.0: must be positive and finite"),
        (float("nan"), (2, 3, 4), None, r"mass = nan: must be positive and finite"),
        (float("inf"), (2, 3, 4), None, r"mass = inf"),
        (1.0, (2, float("nan"), 4), None, r"inertia = .*nan.*must be finite"),
        (1.0, (2, -3, 4), None, r"inertia = .*must be positive"),
        (1.0, (2, 1, 2 / 3), None, r"triangle inequality I_1 <= I_2 \+ I_3.*J_1 .* negative"),
        (1.0, (0, 1, 1), None, r"thin rod .*two zeros"),
        (1.0, (1, 0, 1), None, r"thin rod"),
        (1.0, (1, 2), None, r"inertia = .*expected 3 real numbers, got shape \(2,\)"),
        (1.0, (2, 3, 4), (0, float("nan"), 0), r"pivot = .*must be finite"),
    ],
)
def test_bad_body_raises_before_stepping(mass, inertia, pivot, match):
    with pytest.raises(dm.InvalidBodyError, match=match):
        dm.validate_body(mass, inertia, pivot)
    with pytest.raises(dm.InvalidBodyError, match=match):
        run(mass=mass, inertia=inertia, pivot=pivot)


# --- state ---------------------------------------------------------------------------------
def test_non_orthonormal_rotation_names_deviation():
    R = R0.copy()
    R[0, 0] += 1e-9
    with pytest.raises(
        dm.InvalidStateError, match=r"not orthonormal: max\|R\^T R - I\| = 1\.\d+e-09"
    ):
        run(rotation=R)


def test_tiny_deviation_accepted_not_repaired():
    # a rotation off by 1e-14 (below the 1e-12 rule) is used as given
    R = R0 + 1e-14 * np.eye(3)
    tr = run(rotation=R)
    assert np.array_equal(tr.rotation[0], R)


def test_reflection_rejected():
    with pytest.raises(dm.InvalidStateError, match=r"det = -1.*reflection"):
        run(rotation=-R0)


@pytest.mark.parametrize(
    "kw, match",
    [
        (
            dict(omega_body=(0.0, float("nan"), 0.0)),
            r"omega_body\[1\] = nan: every entry must be finite",
        ),
        (dict(position=(0.0, 0.0, float("inf"))), r"position\[2\] = inf"),
        (dict(gravity=(0.0, 0.0)), r"gravity: expected shape \(3,\), got \(2,\)"),
        (dict(rotation=np.eye(4)), r"rotation: expected a 3x3 rotation matrix, got shape \(4, 4\)"),
        (
            dict(pivot=(0, 0, 1), position=(1.0, 0.0, 0.0)),
            r"position = \[1\.0, 0\.0, 0\.0\] given with a pivot",
        ),
    ],
)
def test_bad_state_raises(kw, match):
    with pytest.raises(dm.InvalidStateError, match=match):
        run(**kw)


def test_pivot_accepts_consistent_com_state():
    # the suite's Scenario stores x_G = -R c and v_G = -R (W x c) for pivoted bodies
    c = np.array([0.1, -0.2, 0.3])
    a = run(pivot=c)
    b = run(pivot=c, position=-R0 @ c, velocity=-R0 @ np.cross(W0, c))
    assert np.array_equal(a.rotation, b.rotation)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(dt=0.03, t_end=0.1), r"not a whole number of steps"),
        (dict(dt=0.0), r"dt = 0\.0: the time step must be positive"),
        (dict(dt=float("nan")), r"dt = nan"),
        (dict(t_end=-1.0), r"t_end = -1\.0"),
        (dict(save_every=0), r"save_every = 0"),
        (dict(save_every=1.5), r"save_every = 1\.5"),
        (dict(scheme="verlet"), r"scheme = 'verlet': unknown; available: rattle"),
    ],
)
def test_bad_run_settings(kw, match):
    with pytest.raises(dm.InvalidRunError, match=match):
        run(**kw)


def test_step_plan_rule():
    nstep, saves = dm.step_plan(0.1, 1.0, 3)  # 1.0/0.1 = 9.999999999999998, rounds to 10
    assert nstep == 10 and saves.tolist() == [0, 3, 6, 9, 10]
    tr = run(dt=0.01, t_end=0.1, save_every=4)
    assert tr.nstep == 10 and np.allclose(tr.t, [0.0, 0.04, 0.08, 0.1], rtol=0, atol=1e-15)


# --- conversions ---------------------------------------------------------------------------
def test_quaternion_round_trip_against_scipy():
    rot = Rotation.random(50, random_state=3)
    R = rot.as_matrix()
    q = dm.quat_wxyz_from_rotation(R)
    q_sp = rot.as_quat()  # scipy: scalar last (x, y, z, w)
    q_sp = np.where(q_sp[:, 3:] < 0, -q_sp, q_sp)
    # rounding of scipy's own conversion: a few ulps
    assert np.max(np.abs(q - np.roll(q_sp, 1, axis=1))) < 8 * EPS
    assert np.all(q[:, 0] >= 0)
    assert np.max(np.abs(dm.rotation_from_quat_wxyz(q) - R)) < 8 * EPS
    # hand case: 90 degrees about z, q = (cos 45, 0, 0, sin 45)
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    assert np.allclose(dm.quat_wxyz_from_rotation(Rz), [2**-0.5, 0, 0, 2**-0.5], atol=4 * EPS)


def test_unnormalised_quaternion_rejected():
    with pytest.raises(dm.InvalidStateError, match="not a unit quaternion"):
        dm.rotation_from_quat_wxyz([1.0, 1e-5, 0, 0])  # |q| - 1 = 5e-11


def test_angular_velocity_conversions():
    rng = np.random.default_rng(5)
    R = Rotation.random(20, random_state=6).as_matrix()
    W = rng.normal(size=(20, 3))
    w = dm.omega_world_from_body(R, W)
    assert np.allclose(w, Rotation.from_matrix(R).apply(W), rtol=0, atol=1e-15)
    assert np.allclose(dm.omega_body_from_world(R, w), W, rtol=0, atol=1e-14)
    Dp = dm.director_velocity(R, W)
    # d_i' = w x d_i (columns), the defining property of the director velocities
    assert np.allclose(Dp, np.cross(w[:, None, :], np.swapaxes(R, 1, 2)).swapaxes(1, 2), atol=1e-14)
    assert np.allclose(dm.omega_body_from_directors(R, Dp), W, rtol=0, atol=1e-14)
    a = rng.normal(size=3)
    b = rng.normal(size=3)
    assert np.allclose(dm.hat(a) @ b, np.cross(a, b), atol=1e-15)
    assert np.array_equal(dm.vee(dm.hat(a)), a)


# --- invariants ----------------------------------------------------------------------------
def test_director_invariants_equal_textbook_forms():
    rng = np.random.default_rng(7)
    I = np.array([1.0, 2.0, 3.0])  # flat body: J_3 = 0 must not matter
    m = 2.5
    body = dm.Body.make(m, I)
    R = Rotation.random(10, random_state=8).as_matrix()
    W = rng.normal(size=(10, 3))
    x = rng.normal(size=(10, 3))
    v = rng.normal(size=(10, 3))
    g = np.array([0.1, -0.2, -9.81])
    Dp = dm.director_velocity(R, W)
    E = inv.energy(m, body.Jbar, False, g, x, v, Dp)
    E_text = 0.5 * m * np.sum(v * v, 1) + 0.5 * np.sum(W * I * W, 1) - m * x @ g
    assert np.allclose(E, E_text, rtol=1e-14, atol=0)
    L = inv.angular_momentum(m, body.Jbar, False, x, v, R, Dp)
    L_text = m * np.cross(x, v) + np.einsum("nij,nj->ni", R, I * W)
    assert np.allclose(L, L_text, rtol=0, atol=1e-13)
    # pivoted: L about the pivot = R Ibar W, T = 1/2 W . Ibar W
    c = np.array([0.3, -0.1, 0.2])
    pb = dm.Body.make(m, I, c)
    Ibar = np.diag(I) + m * (c @ c * np.eye(3) - np.outer(c, c))  # parallel-axis theorem
    assert np.allclose(pb.Ibar, Ibar, atol=1e-15)
    Lp = inv.angular_momentum(m, pb.Jbar, True, None, None, R, Dp)
    assert np.allclose(Lp, np.einsum("nij,jk,nk->ni", R, Ibar, W), atol=1e-13)
    T = inv.kinetic_energy(m, pb.Jbar, True, None, Dp)
    assert np.allclose(T, 0.5 * np.einsum("ni,ij,nj->n", W, Ibar, W), rtol=1e-14)
