"""director_model batched path: bit-for-bit equal to the single-body path; validation; the
pure-Python debugging mode (NUMBA_DISABLE_JIT=1) gives the same numbers."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import director_model as dm

FIELDS = ("position", "velocity", "rotation", "director_velocity", "omega_body", "energy",
          "angular_momentum", "constraint_position", "constraint_velocity")  # fmt: skip

N = 7
RNG = np.random.default_rng(11)
ROT = Rotation.random(N, random_state=12).as_matrix()
W = RNG.normal(scale=2.0, size=(N, 3))
MASS = RNG.uniform(0.5, 2.0, size=N)
# per-body inertia, including a flat body (1, 2, 3) and a thin disk (J_3 = 0)
INERTIA = np.array([[2, 3, 4], [1, 2, 3], [0.25, 0.25, 0.5], [3, 3, 1], [1, 1, 1], [2, 2.5, 4],
                    [4, 2, 3]], dtype=float)  # fmt: skip


def _single(i, scheme, pivot, gravity, position, velocity):
    kw = dict(rotation=ROT[i], omega_body=W[i], gravity=gravity, pivot=pivot, scheme=scheme,
              dt=0.01, t_end=0.5, save_every=7)  # fmt: skip
    if pivot is None:
        kw.update(position=position[i], velocity=velocity[i])
    return dm.simulate(MASS[i], INERTIA[i], **kw)


@pytest.mark.parametrize("parallel", [True, False])
@pytest.mark.parametrize("scheme", list(dm.SCHEMES))
@pytest.mark.parametrize("pivoted", [False, True])
def test_batch_equals_single_bit_for_bit(scheme, pivoted, parallel):
    pivot = (0.1, -0.3, 0.2) if pivoted else None
    gravity = (0.0, 0.5, -9.81)
    pos = RNG.normal(size=(N, 3))
    vel = RNG.normal(size=(N, 3))
    bt = dm.simulate_batch(MASS, INERTIA, rotation=ROT, omega_body=W, gravity=gravity,
                           pivot=pivot, position=None if pivoted else pos,
                           velocity=None if pivoted else vel, scheme=scheme, dt=0.01,
                           t_end=0.5, save_every=7, parallel=parallel)  # fmt: skip
    assert bt.nbody == N and bt.position.shape == (N, len(bt.t), 3)
    assert bt.rotation.shape == (N, len(bt.t), 3, 3) and bt.energy.shape == (N, len(bt.t))
    for i in range(N):
        tr = _single(i, scheme, pivot, gravity, pos, vel)
        assert np.array_equal(tr.t, bt.t)
        for f in FIELDS:
            assert np.array_equal(getattr(tr, f), getattr(bt, f)[i]), (i, f)


def test_batch_shared_parameters_and_shapes():
    bt = dm.simulate_batch(1.0, (2, 3, 4), rotation=ROT, omega_body=W, dt=0.01, t_end=0.1)
    assert bt.omega_body.shape == (N, 11, 3) and bt.nstep == 10
    for i in range(N):
        tr = dm.simulate(1.0, (2, 3, 4), rotation=ROT[i], omega_body=W[i], dt=0.01, t_end=0.1)
        assert np.array_equal(tr.rotation, bt.rotation[i])


def test_batch_validation_names_body():
    R = ROT.copy()
    R[3, 0, 0] += 1e-6
    with pytest.raises(dm.InvalidStateError, match=r"rotation\[3\] is not orthonormal"):
        dm.simulate_batch(1.0, (2, 3, 4), rotation=R, omega_body=W, dt=0.01, t_end=0.1)
    I = INERTIA.copy()
    I[5] = (2, 1, 2 / 3)
    with pytest.raises(dm.InvalidBodyError, match=r"body 5: inertia = .*triangle"):
        dm.simulate_batch(1.0, I, rotation=ROT, omega_body=W, dt=0.01, t_end=0.1)
    with pytest.raises(dm.InvalidBodyError, match=r"mass: expected shape \(\) .* got \(3,\)"):
        dm.simulate_batch(np.ones(3), (2, 3, 4), rotation=ROT, omega_body=W, dt=0.01, t_end=0.1)
    with pytest.raises(dm.InvalidStateError, match=r"omega_body: expected shape \(7, 3\)"):
        dm.simulate_batch(1.0, (2, 3, 4), rotation=ROT, omega_body=W[:2], dt=0.01, t_end=0.1)


def test_batch_step_failure_names_body():
    Wb = np.zeros((N, 3))
    Wb[4] = (0, 0, 12.0)  # h |W| = 1.2 about a principal axis: unsolvable
    with pytest.raises(dm.StepSizeError, match=r"body 4: rattle: step 1 starting at t = 0 s") as e:
        dm.simulate_batch(1.0, (2, 3, 4), rotation=np.broadcast_to(np.eye(3), (N, 3, 3)),
                          omega_body=Wb, dt=0.1, t_end=1.0)  # fmt: skip
    assert e.value.body == 4


SCRIPT = """
import json, numpy as np, director_model as dm
from scipy.spatial.transform import Rotation
out = {}
R0 = Rotation.from_rotvec([0.3, -0.5, 0.7]).as_matrix()
for scheme in ("rattle", "energy_momentum"):
    tr = dm.simulate(1.5, (1.0, 2.0, 3.0), rotation=R0,
                     omega_body=(1.0, -0.7, 0.5), gravity=(0, 0, -9.81), pivot=(0.1, 0.2, -0.3),
                     scheme=scheme, dt=0.01, t_end=0.05)
    out[scheme] = [tr.rotation.tolist(), tr.director_velocity.tolist()]
# the batched RATTLE loop (vector block code): a free body, a large step that falls back to
# the scalar solver, and a symmetric top pivoted on its axis
bt = dm.simulate_batch(1.0, (2.0, 3.0, 4.0), rotation=np.stack([R0, R0.T, np.eye(3)]),
                       omega_body=[(1.0, -0.7, 0.5), (0.0, 30.0, 20.0), (0.5, 0.1, 3.0)],
                       scheme="rattle", dt=0.01, t_end=0.05)
out["batch"] = [bt.rotation.tolist(), bt.director_velocity.tolist()]
print(json.dumps(out))
"""


def test_pure_python_debug_mode_same_numbers():
    """NUMBA_DISABLE_JIT=1 runs the kernels as Python: same IEEE operations, same numbers."""
    runs = {}
    for flag in ("1", "0"):
        env = dict(os.environ, NUMBA_DISABLE_JIT=flag)
        res = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                             text=True, timeout=300)  # fmt: skip
        assert res.returncode == 0, res.stderr
        runs[flag] = json.loads(res.stdout.strip().splitlines()[-1])
    for scheme in ("rattle", "energy_momentum", "batch"):
        a = np.array(runs["1"][scheme])
        b = np.array(runs["0"][scheme])
        # no fastmath: LLVM keeps the order of operations and does not fuse multiply-adds,
        # so the compiled numbers equal the interpreted ones (observed: identical); 4 ulps
        # leaves room for a different libm or BLAS summation order in the 3x3 products
        assert np.max(np.abs(a - b)) <= 4 * np.finfo(float).eps * max(1.0, np.abs(b).max())


# --------------------------------------------------------------------------------------------
# the vector block code of the batched RATTLE loop against the scalar loop, kernel level
# --------------------------------------------------------------------------------------------


def _kernel_inputs():
    """75 bodies in three blocks, mixing every way a lane can leave the vector code: free
    bodies with small steps (vector code throughout), large steps h|W| = 0.6 (beyond the
    straight-line solve, h|W| ~ 0.05: scalar Newton loop), pendulums under gravity
    8000 m/s^2 (h|W| grows as they swing: some steps each way, and some fail mid-run),
    pivots off the principal axes (non-diagonal Ibar: scalar only) and a spin with
    h|W| = 1.2 (fails at the first step)."""
    import importlib

    from director_model import _kernels as K
    from director_model.body import Body

    sm = importlib.import_module("director_model.simulate")
    rng = np.random.default_rng(5)
    n = 75
    R = Rotation.random(n, random_state=6).as_matrix()
    P = np.empty((n, K.NP))
    S0 = np.empty((n, K.NS))
    kinds = []
    for i in range(n):
        kind = "fail" if i == 40 else ("small", "small", "large", "pendulum", "offaxis")[i % 5]
        inertia = np.sort(rng.uniform(1, 2, 3))
        W = rng.normal(size=3)
        pivot = None
        if kind == "large":
            W *= 60.0 / np.linalg.norm(W)
        elif kind == "fail":
            inertia, W, R[i] = np.array([2.0, 3.0, 4.0]), np.array([0.0, 0.0, 120.0]), np.eye(3)
        elif kind == "pendulum":
            pivot, W = (0.0, 0.0, 1.0), 0.1 * W
        elif kind == "offaxis":
            pivot = (0.1, -0.3, 0.2)
        body = Body.make(rng.uniform(0.5, 2.0), inertia, pivot)
        x, v = rng.normal(size=3), rng.normal(size=3)
        if pivot is not None:
            x, v = sm._pivot_state("x", "v", np.zeros(3), np.zeros(3), R[i], W, body.pivot)
        P[i] = sm._params(body)
        S0[i] = sm._state(x, v, R[i], W)
        kinds.append(kind)
    return K, P, S0, np.array(kinds)


@pytest.mark.parametrize("parallel", [False, True])
@pytest.mark.parametrize("scheme", ["rattle", "rattle4"])
def test_vector_block_equals_scalar_loop_bit_for_bit(scheme, parallel):
    K, P, S0, kinds = _kernel_inputs()
    n = P.shape[0]
    g = np.array([0.3, -0.2, -8000.0])
    h, nstep = 0.01, 60
    saves = np.append(np.arange(0, nstep + 1, 7, dtype=np.int64), nstep)
    coef = dm.SCHEMES[scheme].coefficient_array()
    ns = saves.size
    X, V = np.full((n, ns, 3), np.nan), np.full((n, ns, 3), np.nan)
    D, Dp = np.full((n, ns, 3, 3), np.nan), np.full((n, ns, 3, 3), np.nan)
    status, info, vec = np.zeros(n, np.int64), np.zeros((n, 3)), np.zeros(n, np.int64)
    fn = K.run_batch_parallel if parallel else K.run_batch_serial
    nblock = K.block_count(n, 2 if parallel else 1)
    fn(K.RATTLE_FAMILY, coef, P, g, S0, h, nstep, saves, X, V, D, Dp, status, info, vec, nblock)
    for i in range(n):
        x, v = np.full((ns, 3), np.nan), np.full((ns, 3), np.nan)
        d, dp = np.full((ns, 3, 3), np.nan), np.full((ns, 3, 3), np.nan)
        inf1 = np.zeros(3)
        st = K.run_one(K.RATTLE_FAMILY, coef, P[i], g, S0[i].copy(), h, nstep, saves, x, v, d,
                       dp, inf1, True, 0)  # fmt: skip
        assert st == status[i] and np.array_equal(inf1, info[i]), (i, kinds[i])
        for a, b in ((x, X), (v, V), (d, D), (dp, Dp)):
            assert np.array_equal(a, b[i], equal_nan=True), (i, kinds[i])
    # the comparison covered every path: vector code throughout, scalar fallback, a mix of
    # both in one body, a failure at the first step and failures mid-run inside a block
    total = nstep * coef.size
    assert np.all(vec[kinds == "small"] == total)
    assert np.all(vec[kinds == "offaxis"] == 0) and np.all(vec[kinds == "large"] == 0)
    pend = kinds == "pendulum"
    assert np.any((vec[pend] > 0) & (vec[pend] < total))
    assert status[kinds == "fail"][0] == K.FAIL_BRANCH and info[kinds == "fail"][0, 0] == 0
    assert np.any((status[pend] != K.OK) & (info[pend, 0] > 0))


def test_batch_reports_vector_substeps():
    # |W| = 1 rad/s, dt = 0.01 (h|W|/2 <= 0.0085 in rattle4's largest substep): within the
    # straight-line solve, every substep by the vector code
    Ws = W / np.linalg.norm(W, axis=1, keepdims=True)
    bt = dm.simulate_batch(1.0, (2, 3, 4), rotation=ROT, omega_body=Ws, dt=0.01, t_end=0.1,
                           scheme="rattle4")  # fmt: skip
    assert np.array_equal(bt.vector_substeps, np.full(N, 3 * 10))
    # |W| = 60 rad/s (h|W|/2 = 0.3): beyond the straight-line solve, every substep by the
    # scalar Newton loop
    big = dm.simulate_batch(1.0, (2, 3, 4), rotation=ROT, omega_body=60 * Ws, dt=0.01,
                            t_end=0.1)  # fmt: skip
    assert np.array_equal(big.vector_substeps, np.zeros(N))
    em = dm.simulate_batch(1.0, (2, 3, 4), rotation=ROT, omega_body=W, dt=0.01, t_end=0.1,
                           scheme="energy_momentum")  # fmt: skip
    assert np.array_equal(em.vector_substeps, np.zeros(N))
