"""The compiled right-hand side of the multibody reference against the same equations assembled
in NumPy from its mass matrix and bias forces: u' = solve(M, -C) (np.linalg.solve), and the
joint kinematics q' (quaternion rates q (0, w)/2, revolute theta' = u) written out here."""

import numpy as np
import pytest

import scenarios
from references.exact.multibody import tree_from_world
from references.exact.multibody.dynamics import mass_matrix_and_bias, rhs


def _qdot(tree, q, u):
    out = np.empty(tree.nq)
    for b in range(tree.nb):
        qo, uo = tree.qofs[b], tree.uofs[b]
        if tree.kinds[b] == "revolute":
            out[qo] = u[uo]
            continue
        if tree.kinds[b] == "free":
            out[qo : qo + 3] = u[uo : uo + 3]
            qo, uo = qo + 3, uo + 3
        w = np.concatenate([[0.0], u[uo : uo + 3]])
        a, b_ = q[qo : qo + 4], w  # Hamilton product q w / 2
        out[qo : qo + 4] = 0.5 * np.array([
            a[0] * b_[0] - a[1] * b_[1] - a[2] * b_[2] - a[3] * b_[3],
            a[0] * b_[1] + a[1] * b_[0] + a[2] * b_[3] - a[3] * b_[2],
            a[0] * b_[2] - a[1] * b_[3] + a[2] * b_[0] + a[3] * b_[1],
            a[0] * b_[3] + a[1] * b_[2] - a[2] * b_[1] + a[3] * b_[0],
        ])  # fmt: skip
    return out


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
        np.testing.assert_allclose(f[: tree.nq], _qdot(tree, q, u), rtol=1e-14, atol=1e-14)
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
