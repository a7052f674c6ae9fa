"""The dense solvers of director_model.system: the pivoted factorisations ("minnorm": LU with
complete pivoting, L D L^T with diagonal pivoting, the SVD where a kept pivot falls below
PIVOT_CHECK) against numpy's SVD and against the SVD solver ("svd") they replace.

- On random matrices G W G^T and G1 W G0^T of a given rank (redundant rows), the basic
  solutions solve every consistent system to round-off and give the joint forces G^T x of the
  minimum-norm solution (numpy.linalg.lstsq), and the factorisations find the rank;
- on the four-bar (through its singular configuration) and Bricard's loop the two solvers
  give the same motion to 1e-10 and the same singularity diagnostics where they matter.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from director_model.system import Body, Joint, simulate_system
from director_model.system import _kernels as K


def _problem(rng, n=20, rank=17, sym=True):
    G0 = rng.standard_normal((n, 30))
    # rank-deficient rows: the last n - rank rows combinations of the others
    C = rng.standard_normal((n - rank, rank))
    G0[rank:] = C @ G0[:rank]
    G1 = G0 if sym else G0 + 1e-3 * rng.standard_normal(G0.shape)
    if not sym:
        G1[rank:] = C @ G1[:rank]
    W = np.diag(rng.uniform(0.5, 2.0, 30))
    A = G1 @ W @ G0.T
    b = A @ rng.standard_normal(n)  # consistent
    return A, b, G0, W


@pytest.mark.parametrize("seed", range(5))
def test_ldl_with_diagonal_pivoting(seed):
    rng = np.random.default_rng(seed)
    A, b, G, W = _problem(rng)
    F = A.copy()
    pr = np.zeros(20, dtype=np.int64)
    pv = np.zeros(1)
    rank = K._ldlp_factor(F, pr, K.SOLVE_TOL, pv)
    assert rank == 17 and pv[0] > K.PIVOT_CHECK
    x = np.zeros(20)
    K._ldlp_solve(F, pr, rank, b, x, np.zeros(20))
    assert np.max(np.abs(A @ x - b)) < 1e-11 * np.max(np.abs(b))
    xm = np.linalg.lstsq(A, b, rcond=None)[0]
    # the joint forces G^T x are those of the minimum-norm solution
    assert np.max(np.abs(G.T @ (x - xm))) < 1e-9 * np.max(np.abs(G.T @ xm))


@pytest.mark.parametrize("seed", range(5))
def test_lu_with_complete_pivoting(seed):
    rng = np.random.default_rng(seed)
    A, b, G, W = _problem(rng, sym=False)
    F = A.copy()
    pr = np.zeros(20, dtype=np.int64)
    pc = np.zeros(20, dtype=np.int64)
    pv = np.zeros(1)
    rank = K._lucp_factor(F, pr, pc, K.SOLVE_TOL, pv)
    assert rank == 17
    x = np.zeros(20)
    K._lucp_solve(F, pr, pc, rank, b, x, np.zeros(20))
    assert np.max(np.abs(A @ x - b)) < 1e-10 * np.max(np.abs(b))


def _system(name):
    sc = scenarios.load(name)
    bodies = [Body(b.name, b.mass, b.inertia, b.position, b.rotation, b.velocity,
                   b.omega_body) for b in sc.bodies]  # fmt: skip
    joints = [Joint(j.kind, j.body_a, j.body_b, j.anchor_a, j.anchor_b, j.axis_a, j.axis_b,
                    name=j.name) for j in sc.joints]  # fmt: skip
    return bodies, joints, tuple(sc.gravity)


@pytest.mark.parametrize("name, t_end", [("four_bar", 0.6), ("bricard", 0.5)])
def test_pivoted_and_svd_solvers_agree(name, t_end):
    bodies, joints, g = _system(name)
    runs = {s: simulate_system(bodies, joints, gravity=g, scheme="rattle4", dt=1e-3,
                               t_end=t_end, save_every=50, solver=s)
            for s in ("minnorm", "svd")}  # fmt: skip
    a, b = runs["minnorm"], runs["svd"]
    assert np.max(np.abs(a.position - b.position)) < 1e-10
    assert np.max(np.abs(a.rotation - b.rotation)) < 1e-10
    assert a.rank_nominal == b.rank_nominal
    if name == "four_bar":  # the collinear passage: both see the rank drop, from the SVD
        assert a.rank_drop_steps >= 2 and b.rank_drop_steps >= 2
        assert a.min_singular_value < 1e-10 and b.min_singular_value < 1e-10
    else:
        assert a.rank_drop_steps == b.rank_drop_steps == 0
