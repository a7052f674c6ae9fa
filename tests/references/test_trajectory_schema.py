"""The one trajectory schema: columns, round trip through Parquet and CSV, suite-computed
energy and momentum against hand computations."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from references.trajectory import COLUMNS, OneBody, Trajectory, one_body
from scenarios.model import Scenario


def scenario(**kw):
    base = dict(
        name="s",
        description="",
        mass=3.0,
        inertia=(1.0, 2.0, 2.5),
        rotation=Rotation.from_rotvec([0.2, -0.4, 0.9]).as_matrix(),
        omega_body=(0.3, -1.1, 0.7),
        position=(1.0, 2.0, 3.0),
        velocity=(0.1, 0.2, -0.3),
        gravity=(0, 0, -9.81),
        t_end=1.0,
        dt=0.1,
    )
    base.update(kw)
    return Scenario(**base)


def test_columns_are_the_documented_schema():
    assert COLUMNS[:7] == ["t", "x", "y", "z", "vx", "vy", "vz"]
    assert COLUMNS[7:16] == ["R00", "R01", "R02", "R10", "R11", "R12", "R20", "R21", "R22"]
    assert COLUMNS[16:] == ["wx", "wy", "wz", "energy", "Lx", "Ly", "Lz", "constraint_velocity"]


def test_velocity_constraint_residual_by_hand():
    """D' = R hat(W): with R orthonormal the residual R^T R hat(W) - hat(W) R^T R vanishes (to
    round-off); with R^T R = diag(1 + e, 1, 1) it is e |hat(W) entries of row/column 1|:
    for W = (0, 0, w) the nonzero entries are M hat(W) - hat(W) M at (0, 1) and (1, 0), each
    -e w, so the Frobenius norm is sqrt(2) e w."""
    from references.trajectory import velocity_constraint

    R = Rotation.from_rotvec([0.2, -0.4, 0.9]).as_matrix()
    W = np.array([0.3, -1.1, 0.7])
    assert velocity_constraint(R[None], W[None])[0] < 1e-15
    e, w = 1e-6, 2.0
    S = np.diag([np.sqrt(1 + e), 1.0, 1.0])  # R^T R = S^2 = diag(1 + e, 1, 1)
    got = velocity_constraint((R @ S)[None], np.array([[0.0, 0.0, w]]))[0]
    assert got == pytest.approx(np.sqrt(2) * e * w, rel=1e-9)


def test_energy_and_momentum_by_hand():
    sc = scenario()
    tr = OneBody.from_states(
        sc, [0.0], [sc.position], [sc.velocity], [sc.rotation], [sc.omega_body]
    )
    W, I = sc.omega_body, np.array([1.0, 2.0, 2.5])
    E = 0.5 * 3.0 * (0.01 + 0.04 + 0.09) + 0.5 * (I * W * W).sum() + 3.0 * 9.81 * 3.0
    assert tr.energy[0] == pytest.approx(E, rel=1e-15)
    np.testing.assert_allclose(tr.angular_momentum[0], sc.rotation @ (I * W), rtol=1e-14)


def test_pivot_momentum_equals_pivot_inertia_form():
    """About the pivot, x_G x m v_G + R I W must equal R I_pivot W (parallel-axis theorem)."""
    sc = scenario(pivot=(0.1, -0.2, -0.5))
    tr = OneBody.from_states(sc, [0.0], None, None, [sc.rotation], [sc.omega_body])
    expect = sc.rotation @ (sc.pivot_inertia @ sc.omega_body)
    np.testing.assert_allclose(tr.angular_momentum[0], expect, rtol=1e-13)
    np.testing.assert_allclose(tr.position[0], -sc.rotation @ sc.pivot, rtol=1e-15)


@pytest.mark.parametrize("fmt", ["parquet", "csv"])
def test_round_trip(tmp_path, fmt):
    sc = scenario()
    n = 4
    R = Rotation.random(n, random_state=1).as_matrix()
    rng = np.random.default_rng(0)
    tr = OneBody.from_states(
        sc,
        np.arange(n) * 0.1,
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 3)),
        R,
        rng.normal(size=(n, 3)),
    )
    path = tr.write(tmp_path / f"a.{fmt}", fmt)
    back = OneBody.read(path)
    # the one reader of trajectory files: a single body's file is a scene of one body
    bodies = Trajectory.read(path)
    assert bodies.body_names == ("body",) and bodies.rotation.shape == (n, 1, 3, 3)
    for f in ("t", "position", "velocity", "rotation", "omega_body", "energy", "angular_momentum",
              "constraint_velocity"):  # fmt: skip
        np.testing.assert_array_equal(getattr(back, f), getattr(tr, f))
        np.testing.assert_array_equal(getattr(one_body(bodies), f), getattr(tr, f))


def test_wrong_shape_names_the_field():
    with pytest.raises(ValueError, match="OneBody field 'rotation' has shape"):
        OneBody(
            t=np.zeros(2),
            position=np.zeros((2, 3)),
            velocity=np.zeros((2, 3)),
            rotation=np.zeros((2, 9)),
            omega_body=np.zeros((2, 3)),
            energy=np.zeros(2),
            angular_momentum=np.zeros((2, 3)),
        )


def test_a_single_body_on_a_bodies_axis_is_the_same_memory_both_ways():
    """OneBody.as_bodies gives (n, 1, ...) views carrying energy, momentum and the
    velocity-constraint residual; one_body gives them back as the single body's (n, ...)
    arrays: the same memory, C-contiguous as before (numpy's arithmetic may depend on the
    layout, and the metrics must stay bit for bit). Trajectory.from_states is that trajectory
    of the same states."""
    sc = scenario()
    t = np.linspace(0.0, 1.0, 5)
    R = Rotation.from_rotvec(np.outer(t, [0.2, -0.4, 0.9])).as_matrix()
    W = np.tile(sc.omega_body, (5, 1))
    x = np.outer(t, [1.0, 2.0, 3.0])
    tr = OneBody.from_states(sc, t, x, x + 1.0, R, W)
    bodies = tr.as_bodies("ball")
    assert isinstance(bodies, Trajectory) and bodies.body_names == ("ball",)
    assert bodies.position.shape == (5, 1, 3) and bodies.rotation.shape == (5, 1, 3, 3)
    back = one_body(bodies)
    for name in ("t", "position", "velocity", "rotation", "omega_body", "energy",
                 "angular_momentum", "constraint_velocity"):  # fmt: skip
        a, b = getattr(tr, name), getattr(back, name)
        assert np.shares_memory(a, b) and a.shape == b.shape, name
        assert b.flags.c_contiguous, name
        np.testing.assert_array_equal(a, b)
    assert one_body(tr) is tr and one_body(None) is None
    head = bodies.head(2)
    assert head.energy.shape == (2,) and head.angular_momentum.shape == (2, 3)
    made = Trajectory.from_states(sc, t, x, x + 1.0, R, W)
    assert made.body_names == ("body",)
    for name in ("position", "velocity", "rotation", "omega_body", "energy", "angular_momentum",
                 "constraint_velocity"):  # fmt: skip
        np.testing.assert_array_equal(getattr(one_body(made), name), getattr(tr, name))


def test_one_body_refuses_a_system_and_a_body_without_its_energy():
    z = np.zeros((1, 2, 3))
    R = np.tile(np.eye(3), (1, 2, 1, 1))
    two = Trajectory([0.0], z, z, R, z, ("a", "b"))
    with pytest.raises(ValueError, match=r"2 bodies \(a, b\)"):
        one_body(two)
    bare = Trajectory([0.0], z[:, :1], z[:, :1], R[:, :1], z[:, :1], ("a",))
    with pytest.raises(ValueError, match="without its energy and angular momentum"):
        one_body(bare)
    with pytest.raises(ValueError, match="'energy'.*nb = 2 bodies"):
        Trajectory([0.0], z, z, R, z, ("a", "b"), energy=[1.0])
    with pytest.raises(ValueError, match="'angular_momentum'"):
        Trajectory([0.0], z[:, :1], z[:, :1], R[:, :1], z[:, :1], ("a",),
                   energy=[1.0], angular_momentum=[1.0, 2.0])  # fmt: skip
