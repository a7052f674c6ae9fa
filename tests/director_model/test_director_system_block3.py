"""The block solver's joint kernels (director_model/system/_block3.py: chains of spherical
joints, three POINT rows each) against the general kernels of director_model/system/
(_rows.py, _solvers.py), bit for bit: they leave out only terms with a factor 0 and factors 1,
so every row value, Jacobian entry, joint force, rate and 3x3 block must be the same float. The
reference for the blocks is the general 3x3 products (``_mm``, ``_mmt``) on the full blocks
of the Jacobian, zeros included, summed as the assembly sums them; a chain hanging from the
ground (a joint to body -1) and a free one, random poses, velocities and multipliers."""

from __future__ import annotations

import numpy as np
import pytest

from director_model.system import SystemStepper
from director_model.system import _block3 as B3
from director_model.system import _common as C
from director_model.system import _rows as R
from director_model.system import _solvers as SV
from director_model.system.examples import rod_chain
from director_model.system.model import assemble


def _state(n, hang, seed):
    """(assembly, X, D): the rod chain's assembly at random positions and rotations."""
    bodies, joints = rod_chain(n, hang, seed=seed)
    asm = assemble(bodies, joints)
    assert asm.block3
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 3))
    D = np.array([np.linalg.qr(rng.standard_normal((3, 3)))[0].ravel() for _ in range(n)])
    return asm, X, D, rng


def _blocks_reference(asm, JL, JR, Mx, Mth):
    """Dg, Up, Lo by the general products on the full 3x3 blocks (the assembly before the
    zeros were left out)."""
    nK = asm.rint.shape[0] // 3
    Dg, Up, Lo = np.zeros((nK, 9)), np.zeros((nK, 9)), np.zeros((nK, 9))

    def blk(J, r, o):
        return tuple(float(J[r + i, o + j]) for i in range(3) for j in range(3))

    for i in range(len(asm.jptr) - 1):
        M = tuple(float(v) for v in Mth[i])
        for e1 in range(asm.jptr[i], asm.jptr[i + 1]):
            k, o1 = asm.jidx[e1], 6 * asm.jside[e1]
            CLM = C._mm(blk(JL, 3 * k, o1 + 3), M)
            sl = JL[3 * k, o1] * Mx[i]
            for e2 in range(asm.jptr[i], asm.jptr[i + 1]):
                m, o2 = asm.jidx[e2], 6 * asm.jside[e2]
                Bk = C._mmt(CLM, blk(JR, 3 * m, o2 + 3))
                d = sl * JR[3 * m, o2]
                out, row = (Dg, k) if m == k else ((Up, k) if m == k + 1 else (Lo, m))
                for c in range(9):
                    out[row, c] += Bk[c]
                for c in (0, 4, 8):
                    out[row, c] += d
    return Dg, Up, Lo


@pytest.mark.parametrize("hang", [True, False])
def test_block3_kernels_equal_the_general_ones_bit_for_bit(hang):
    n = 7
    asm, X, D, rng = _state(n, hang, seed=3 if hang else 4)
    nr = asm.rint.shape[0]
    gv, J = np.zeros(nr), np.zeros((nr, 12))
    R._rows(asm.rint, asm.rvec, X, D, gv, J)
    gv3, J3 = np.zeros(nr), np.zeros((nr, 12))
    B3._rows3(asm.rint, asm.rvec, X, D, gv3, J3)
    assert np.array_equal(gv3, gv) and np.array_equal(J3, J)

    lam = rng.standard_normal(nr)
    F, T, F3, T3 = (np.full((n, 3), np.nan) for _ in range(4))
    R._forces(asm.rint, J, lam, F, T)
    B3._forces3(asm.rint, J, lam, F3, T3)
    assert np.array_equal(F3, F) and np.array_equal(T3, T)

    vel, om = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    r, r3 = np.zeros(nr), np.zeros(nr)
    R._vres(asm.rint, J, vel, om, r)
    B3._vres3(asm.rint, J, vel, om, r3)
    assert np.array_equal(r3, r)

    # the Newton matrix's blocks (Jacobians at two poses, Mth not symmetric)
    J2 = np.zeros((nr, 12))
    B3._rows3(asm.rint, asm.rvec, X + 0.1, D, gv3, J2)
    Mx = rng.uniform(0.5, 2.0, n)
    Mth = rng.standard_normal((n, 9))
    nK = nr // 3
    Dg, Up, Lo = np.zeros((nK, 9)), np.zeros((nK, 9)), np.zeros((nK, 9))
    SV._blk_assemble(asm.jptr, asm.jidx, asm.jside, J2, J, Mx, Mth, Dg, Up, Lo)
    for got, want in zip((Dg, Up, Lo), _blocks_reference(asm, J2, J, Mx, Mth), strict=True):
        assert np.array_equal(got, want)
    assert np.count_nonzero(Up) > 0 and np.count_nonzero(Lo) > 0


def _dense_g(asm, J, n):
    """G (nrow, 6 n): each row's translation and rotation entries in its bodies' columns."""
    G = np.zeros((J.shape[0], 6 * n))
    for r, (_, a, b, _) in enumerate(asm.rint):
        G[r, 6 * a : 6 * a + 6] = J[r, 0:6]
        if b >= 0:
            G[r, 6 * b : 6 * b + 6] = J[r, 6:12]
    return G


@pytest.mark.parametrize("hang, reverse", [(True, False), (False, False), (True, True)])
def test_symmetric_factor_solves_the_velocity_stage_matrix(hang, reverse):
    # the velocity stage's A = G blockdiag(Mx 1, Mth) G^T (Mth symmetric positive definite)
    # factorised joint by joint (_sym_factor) and solved (_sym_solve), against numpy's dense
    # solve of the same A formed from the Jacobian rows; bodies listed along the chain or
    # against it (the joints' order is the chain's either way)
    n = 8
    asm, X, D, rng = _state(n, hang, seed=5 if hang else 6)
    if reverse:
        bodies, joints = rod_chain(n, hang, seed=5)
        asm = assemble(bodies[::-1], joints)
        assert asm.block3 and asm.rint[0, 1] == n - 1
    nr = asm.rint.shape[0]
    gv, J = np.zeros(nr), np.zeros((nr, 12))
    B3._rows3(asm.rint, asm.rvec, X, D, gv, J)
    Mx = rng.uniform(0.5, 2.0, n)
    Mth = np.empty((n, 9))
    Minv = np.zeros((6 * n, 6 * n))
    for i in range(n):
        Q = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        S = Q @ np.diag(rng.uniform(0.2, 5.0, 3)) @ Q.T
        Mth[i] = S.ravel()
        Minv[6 * i : 6 * i + 3, 6 * i : 6 * i + 3] = Mx[i] * np.eye(3)
        Minv[6 * i + 3 : 6 * i + 6, 6 * i + 3 : 6 * i + 6] = S
    G = _dense_g(asm, J, n)
    A = G @ Minv @ G.T
    b = rng.standard_normal(nr)
    want = np.linalg.solve(A, b)
    nK = nr // 3
    Pi, Y = np.zeros((nK, 9)), np.zeros((nK, 9))
    assert B3._sym_factor(asm.rint, J, Mx, Mth, Pi, Y)
    x = np.zeros(nr)
    B3._sym_solve(Pi, Y, b, x)
    # a backward-stable solve: error <= a few eps x condition number (cond ~ 1e2 .. 1e4 here)
    bound = 64 * np.finfo(float).eps * np.linalg.cond(A) * np.abs(want).max()
    assert np.abs(x - want).max() <= bound
    # the pivots' inverses are symmetric; a zero matrix is refused as singular
    assert np.allclose(
        Pi.reshape(nK, 3, 3),
        Pi.reshape(nK, 3, 3).transpose(0, 2, 1),
        rtol=0,
        atol=1e-9 * np.abs(Pi).max(),
    )
    assert not B3._sym_factor(asm.rint, J, 0 * Mx, 0 * Mth, Pi, Y)


@pytest.mark.parametrize("scheme, steps, bound", [("rattle", 1000, 1.2), ("rattle4", 600, 1.1)])
def test_hanging_chain_takes_about_one_newton_update_per_sub_step(scheme, steps, bound):
    # the start value of the position multipliers (the last velocity multipliers plus their
    # difference to the position multipliers, extrapolated quadratically over the last three
    # steps: error O(h^4)) closes a hanging chain of 50 rods to the Newton tolerance in one
    # update in most sub-steps. Newton updates per sub-step over these steps: 1.11 (rattle)
    # and 1.02 (rattle4); the multipliers themselves extrapolated quadratically (O(h^3))
    # took 1.41 and 1.35
    bodies, joints = rod_chain(50, True, seed=1)
    st = SystemStepper(bodies, joints, gravity=(0.0, 0.0, -9.81), scheme=scheme, dt=1e-3)
    tr = st.advance(steps, save_every=steps)
    assert tr.solver == "block"
    nsub = {"rattle": 1, "rattle4": 3}[scheme]
    assert tr.newton_iterations / (steps * nsub) <= bound
