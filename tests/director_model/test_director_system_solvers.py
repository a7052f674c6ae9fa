"""The loop solver of director_model.system ("minnorm": banded LU and L D L^T in the row
order that drop the rows dependent on the rows before them; where a kept pivot falls below
PIVOT_CHECK the SVD, or on a single loop of 5-row joints first the velocity stage's singular
values) against numpy and against the SVD solver ("svd").

- On random matrices G W G^T and G1 W G0^T whose dependent rows are known (redundant rows at
  the end and in the middle), the factorisations drop exactly those rows, their basic
  solutions solve every consistent system to round-off and give the joint forces G^T x of the
  minimum-norm solution (numpy.linalg.lstsq); a nearly dependent row is reported (the
  kernel then asks the singular values, computed without vectors as numpy's SVD gives them);
- the joints are factorised in an order that keeps the rows sharing a body close (the
  four-bar listed A0, B0, A1, B1 is solved as A0, A1, B1, B0), and the motion does not depend
  on the order the joints are listed in;
- on the four-bar (through its singular configuration) and Bricard's loop the two solvers
  give the same motion to 1e-10 and the same singularity diagnostics where they matter.
"""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from director_model.system import Body, Joint, SystemStepper, simulate_system
from director_model.system import _common as C
from director_model.system import _solvers as SV

N = 20


def _problem(rng, dep=(17, 18, 19), sym=True, near=0.0):
    """(A, b, G0): A = G1 W G0^T (N x N, G0 N x 30) whose rows ``dep`` are combinations of
    the rows before them (plus ``near`` times a random row: nearly dependent), b consistent."""
    G0 = rng.standard_normal((N, 30))
    G1 = G0 + (0.0 if sym else 1e-3) * rng.standard_normal(G0.shape)
    for k in dep:
        c = rng.standard_normal(k)
        G0[k] = c @ G0[:k] + near * rng.standard_normal(30)
        G1[k] = c @ G1[:k] + near * rng.standard_normal(30) if not sym else G0[k]
    W = np.diag(rng.uniform(0.5, 2.0, 30))
    A = G1 @ W @ G0.T
    b = A @ rng.standard_normal(N)  # consistent
    return A, b, G0


def _band(A, upper):
    """A in the kernels' band storage with bw = N - 1 and its envelope (a dense matrix is a
    full band)."""
    bw = N - 1
    Ab = np.zeros((N, 2 * bw + 1))
    for r in range(N):
        for s in range(r if upper else 0, N):
            Ab[r, bw + s - r] = A[r, s]
    return Ab, bw, np.full(N, N - 1, dtype=np.int64)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dep", [(17, 18, 19), (4, 11, 19)])
def test_band_ldl_drops_the_dependent_rows(seed, dep):
    rng = np.random.default_rng(seed)
    A, b, G = _problem(rng, dep)
    Ab, bw, ext = _band(A, upper=True)
    keep = np.zeros(N, dtype=np.int64)
    out = np.zeros(2)
    assert SV._band_ldl_rr(Ab, bw, ext, keep, np.zeros(N), out, C.PIVOT_CHECK) == 0
    assert [k for k in range(N) if not keep[k]] == list(dep) and out[1] == N - len(dep)
    assert out[0] >= C.PIVOT_CHECK
    x = np.zeros(N)
    SV._band_ldl_solve_rr(Ab, bw, ext, keep, b, x)
    assert np.all(x[list(dep)] == 0.0)
    assert np.max(np.abs(A @ x - b)) < 1e-11 * np.max(np.abs(b))
    xm = np.linalg.lstsq(A, b, rcond=None)[0]
    # the joint forces G^T x are those of the minimum-norm solution
    assert np.max(np.abs(G.T @ (x - xm))) < 1e-9 * np.max(np.abs(G.T @ xm))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dep", [(17, 18, 19), (4, 11, 19)])
def test_band_lu_solves_over_the_kept_rows(seed, dep):
    rng = np.random.default_rng(seed)
    A, b, G = _problem(rng, dep, sym=False)
    Ab, bw, ext = _band(A, upper=False)
    keep = np.ones(N, dtype=np.int64)
    keep[list(dep)] = 0
    out = np.zeros(2)
    assert SV._band_lu_rr(Ab, bw, ext, keep, out, C.PIVOT_CHECK) == 0 and out[1] == N - len(dep)
    x = np.zeros(N)
    SV._band_solve_rr(Ab, bw, ext, keep, b, x)
    assert np.all(x[list(dep)] == 0.0)
    assert np.max(np.abs(A @ x - b)) < 1e-10 * np.max(np.abs(b))


@pytest.mark.parametrize("seed", range(3))
def test_a_nearly_dependent_row_is_reported(seed):
    # row 12 dependent up to 1e-4 of a row's size: pivot ratio ~1e-9 of its diagonal entry
    # and of the largest, above DROP_TOL and below PIVOT_CHECK: kept, and reported
    rng = np.random.default_rng(seed)
    A, b, G = _problem(rng, (12,), near=1e-4)
    z = np.zeros(N, dtype=np.int64)
    for upper in (True, False):
        Ab, bw, ext = _band(A, upper=upper)
        if upper:
            assert SV._band_ldl_rr(Ab, bw, ext, z, np.zeros(N), np.zeros(2), C.PIVOT_CHECK) == 1
        else:
            assert SV._band_lu_rr(Ab, bw, ext, z + 1, np.zeros(2), C.PIVOT_CHECK) == 1
        # above PIVOT_FLOOR the factorisation is completed, its smallest pivot ratio in out[0]
        Ab, bw, ext = _band(A, upper=upper)
        out = np.zeros(2)
        keep = z + (0 if upper else 1)
        if upper:
            assert SV._band_ldl_rr(Ab, bw, ext, keep, np.zeros(N), out, C.PIVOT_FLOOR) == 0
            x = np.zeros(N)
            SV._band_ldl_solve_rr(Ab, bw, ext, keep, b, x)
        else:
            assert SV._band_lu_rr(Ab, bw, ext, keep, out, C.PIVOT_FLOOR) == 0
            x = np.zeros(N)
            SV._band_solve_rr(Ab, bw, ext, keep, b, x)
        assert C.PIVOT_FLOOR <= out[0] < C.PIVOT_CHECK and out[1] == N
        # still a solution, to the rounding the small pivot amplifies (1e-9: 1e-16 / 1e-9)
        assert np.max(np.abs(A @ x - b)) < 1e-6 * np.max(np.abs(b))
    # a non-finite entry is refused
    A[3, 7] = np.nan
    Ab, bw, ext = _band(A, upper=True)
    assert SV._band_ldl_rr(Ab, bw, ext, z, np.zeros(N), np.zeros(2), C.PIVOT_FLOOR) == -1


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("dep", [(), (17, 18, 19), (4, 11, 19)])
def test_symmetric_singular_values_are_numpys(seed, dep):
    # the singular values without vectors (_sigma._sym_sigma: |eigenvalues| of the symmetric
    # matrix, dsyevd) against numpy's SVD (dgesdd): both backward stable, so they agree to a
    # few eps sigma_1 (bound 64 eps sigma_1), the redundant rows' zeros included
    from director_model.system._sigma import _sym_sigma

    rng = np.random.default_rng(seed)
    A, b, G = _problem(rng, dep)
    ref = np.linalg.svd(A, compute_uv=False)
    s = np.zeros(N)
    assert _sym_sigma(A.copy(), s) == 0
    assert np.all(np.diff(s) <= 0.0)
    assert np.max(np.abs(s - ref)) < 64 * np.finfo(float).eps * ref[0]
    assert np.sum(s > C.SOLVE_TOL * s[0]) == N - len(dep)
    A[2, 5] = np.inf
    assert _sym_sigma(A, s) == -1


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
    if name == "four_bar":  # the collinear passage: both see the rank drop, from the
        # singular values (minnorm: without their vectors where the rank they show is the
        # one the factorisations kept and sigma_17 / sigma_1 >= SIGMA_LDL; one landing here,
        # at 6.6e-13, goes to the SVD; with the SVD wherever a pivot ratio is below
        # PIVOT_CHECK: 5)
        assert a.rank_drop_steps >= 2 and b.rank_drop_steps >= 2
        assert a.min_singular_value < 1e-10 and b.min_singular_value < 1e-10
        assert a.svd_factorisations <= 1 < b.svd_factorisations
    else:
        assert a.rank_drop_steps == b.rank_drop_steps == 0


def test_joints_are_factorised_along_the_loop_and_their_listed_order_does_not_matter():
    bodies, joints, g = _system("four_bar")  # listed A0, B0, A1, B1
    st = SystemStepper(bodies, joints, gravity=g, dt=1e-3)
    assert st.solver == "minnorm"
    assert st._kasm.joint_names == ("A0", "A1", "B1", "B0")
    assert st._asm.bandwidth == 14 and st._kasm.bandwidth == 9  # rows of two adjacent joints
    # the envelope: each row reaches to the end of the next joint's rows (the last to its own)
    a = st._kasm
    ext = np.zeros(20, dtype=np.int64)
    SV._envelope(a.brow_ptr, a.brow_idx, 20, ext)
    assert ext.tolist() == [9] * 5 + [14] * 5 + [19] * 10
    runs = [simulate_system(bodies, js, gravity=g, scheme="rattle4", dt=1e-3, t_end=0.6,
                            save_every=50)
            for js in (joints, joints[::-1], [joints[k] for k in (2, 0, 3, 1)])]  # fmt: skip
    for tr in runs[1:]:
        assert tr.joint_names != runs[0].joint_names  # reported in the order given
        assert np.max(np.abs(tr.position - runs[0].position)) < 1e-10
        assert np.max(np.abs(tr.rotation - runs[0].rotation)) < 1e-10
