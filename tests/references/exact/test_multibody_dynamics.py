"""The compiled right-hand side of the multibody reference against the same equations assembled
in NumPy from its mass matrix and bias forces: u' = solve(M, -C) (np.linalg.solve), and the
joint kinematics q' (quaternion rates q (0, w)/2, revolute theta' = u) written out in
tests/system_builders.joint_rates."""

import numpy as np
import pytest

import scenarios
from references.exact.multibody import tree_from_world
from references.exact.multibody.dynamics import mass_matrix_and_bias, rhs
from tests.references.engines import system_builders as sb


@pytest.mark.parametrize("name", ["double_pendulum_3d", "free_chain_5", "planar_chain_4"])
def test_rhs_is_the_solve_of_the_mass_matrix_and_bias(name):
    sc = scenarios.load(name)
    tree, q0, u0 = tree_from_world(sc.bodies, sc.joints, sc.gravity)
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = q0 + 0.3 * rng.standard_normal(tree.nq)
        u = u0 + rng.standard_normal(tree.nu)
        M, C = mass_matrix_and_bias(tree, q, u)
        assert np.array_equal(M, M.T)
        assert np.all(np.linalg.eigvalsh(M) > 0)
        f = rhs(tree, np.concatenate([q, u]))
        np.testing.assert_allclose(f[: tree.nq], sb.joint_rates(tree, q, u), rtol=1e-14, atol=1e-14)
        ud = np.linalg.solve(M, -C)
        scale = np.max(np.abs(ud)) * np.linalg.cond(M)
        np.testing.assert_allclose(f[tree.nq :], ud, rtol=0, atol=1e-13 * scale)


def test_non_finite_state_is_an_error():
    sc = scenarios.load("double_pendulum_3d")
    tree, q0, u0 = tree_from_world(sc.bodies, sc.joints, sc.gravity)
    y = np.concatenate([q0, u0])
    y[0] = np.nan
    with pytest.raises(FloatingPointError, match="non-finite"):
        rhs(tree, y)
