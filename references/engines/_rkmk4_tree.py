"""Compiled stages of the RKMK4 on a tree of joints in DART's coordinates
(:mod:`references.engines.dart_system`): the arithmetic of ``_Model.step_rkmk4`` with the state
in arrays and the per-joint loops compiled, so that a stage costs DART's calls and one small
compiled call instead of a Python loop over the joints.

It computes, operation for operation, what the Python methods it stands for compute (the
formulas of :func:`scenarios.schema.rotation_from_vector`,
:func:`references.conventions.matrix_to_rotvec` and
:func:`references.engines.liegroup.so3_right_jacobian_inverse`, in the same order), so that the
trajectories are bit-identical with ``_Model.step_rkmk4`` (a test holds the two to equality).
Two details make that so:

- the 3x3 products are the fused multiply-adds, in the order, of numpy's BLAS kernels (OpenBLAS
  on x86-64: A @ B and A^T @ v accumulate k = 0, 1, 2; A @ v adds k = 0, then k = 2, to the
  middle product): :func:`_mm`, :func:`_mv`, :func:`_mtv`; the test fails where a BLAS
  computes otherwise;
- ``s ** 2`` of the Python formula calls the C library's ``pow``, which differs from ``s * s`` in
  the last bit for about one argument in a thousand: the exponent ``two`` (2.0) is an argument
  of the compiled entries, so that the compiler cannot replace the call by a product.

The tree is ``blocks`` (nb, 5) int64, one row per joint in DART's dof order: (kind, offset of
its velocities in u, index of its rotation in R or -1, offset of its angle or position in L,
index of its first dof in the skeleton), kind REVOLUTE, SPHERICAL or FREE.

The state: rotations ``R`` (2, nr, 3, 3), hinge angles and free-root positions ``L`` (2, nl),
velocities ``U`` (2, n) (a free root's angular part in body axes), row 0 the step's start and
row 1 the stage's. ``K`` (2, 4, n) holds the four stages' slopes of theta (K[0]) and of u
(K[1]), ``PV`` (2, n) DART's positions and velocities of the stage, ``a`` (n,) the accelerations
DART returned for the previous stage.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

REVOLUTE, SPHERICAL, FREE = 0, 1, 2

#: the bound of a stage's squared rotation angle, as liegroup.check_stage_rotation computes it
_PI2 = math.pi**2


@intrinsic
def _fma(typingctx, a, b, c):
    """a * b + c rounded once (LLVM's llvm.fma.f64: the CPU's instruction, or an exact
    software fallback)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64"
        )
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True)
def _mm(A, B, out):
    """out = A @ B (3x3) as numpy's BLAS computes it."""
    for i in range(3):
        for j in range(3):
            out[i, j] = _fma(A[i, 2], B[2, j], _fma(A[i, 1], B[1, j], A[i, 0] * B[0, j]))


@njit(cache=True)
def _mv(A, v0, v1, v2, out, o):
    """out[o:o+3] = A @ v (3x3, 3) as numpy's BLAS computes it."""
    for i in range(3):
        out[o + i] = _fma(A[i, 2], v2, _fma(A[i, 0], v0, A[i, 1] * v1))


@njit(cache=True)
def _mtv(A, v0, v1, v2, out, o):
    """out[o:o+3] = A^T @ v (3x3, 3) as numpy's BLAS computes it."""
    for i in range(3):
        out[o + i] = _fma(A[2, i], v2, _fma(A[1, i], v1, A[0, i] * v0))


@njit(cache=True)
def _exp(x, y, z, two, E):
    """E = exp(hat(x, y, z)): scenarios.schema.rotation_from_vector."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        s = 1.0 - a2 / 6.0 + a2 * a2 / 120.0
        c = 0.5 - a2 / 24.0 + a2 * a2 / 720.0
    else:
        a = math.sqrt(a2)
        s = math.sin(a) / a
        c = 2.0 * math.sin(0.5 * a) ** two / a2
    E[0, 0] = 1.0 - c * (y * y + z * z)
    E[0, 1] = c * x * y - s * z
    E[0, 2] = c * x * z + s * y
    E[1, 0] = c * x * y + s * z
    E[1, 1] = 1.0 - c * (x * x + z * z)
    E[1, 2] = c * y * z - s * x
    E[2, 0] = c * x * z - s * y
    E[2, 1] = c * y * z + s * x
    E[2, 2] = 1.0 - c * (x * x + y * y)


@njit(cache=True)
def _rotvec(R, out, o):
    """out[o:o+3] = the rotation vector of R: conventions.matrix_to_rotvec (through
    matrix_to_quat_wxyz, Shepperd's pivot the first largest as Python's max picks it)."""
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    tr = r00 + r11 + r22
    k, best = 0, tr
    if r00 > best:
        k, best = 1, r00
    if r11 > best:
        k, best = 2, r11
    if r22 > best:
        k, best = 3, r22
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q0, q1, q2, q3 = 0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + r00 - r11 - r22)
        q0, q1, q2, q3 = (r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + r11 - r00 - r22)
        q0, q1, q2, q3 = (r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + r22 - r00 - r11)
        q0, q1, q2, q3 = (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    sign = -1.0 if q0 < 0 else 1.0
    w, x, y, z = sign * q0 / n, sign * q1 / n, sign * q2 / n, sign * q3 / n
    m = math.sqrt(x * x + y * y + z * z)
    f = 2.0 / w if m < 1e-8 else 2.0 * math.atan2(m, w) / m
    out[o], out[o + 1], out[o + 2] = f * x, f * y, f * z


@njit(cache=True)
def _dexpinv(x, y, z, u, o):
    """u[o:o+3] = J_r(x, y, z)^{-1} u[o:o+3] (liegroup.so3_right_jacobian_inverse, then the
    product); returns the squared angle, or -1.0 when it is below pi^2 (no failure)."""
    a2 = x * x + y * y + z * z
    if not a2 < _PI2:
        return a2
    if a2 < 1e-6:
        c = 1.0 / 12.0 + a2 / 720.0 + a2 * a2 / 30240.0
    else:
        a = math.sqrt(a2)
        c = 1.0 / a2 - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    j00 = 1.0 - c * (y * y + z * z)
    j01 = c * x * y - 0.5 * z
    j02 = c * x * z + 0.5 * y
    j10 = c * x * y + 0.5 * z
    j11 = 1.0 - c * (x * x + z * z)
    j12 = c * y * z - 0.5 * x
    j20 = c * x * z - 0.5 * y
    j21 = c * y * z + 0.5 * x
    j22 = 1.0 - c * (x * x + y * y)
    u0, u1, u2 = u[o], u[o + 1], u[o + 2]
    # J @ u as numpy's BLAS computes it (_mv)
    u[o] = _fma(j02, u2, _fma(j00, u0, j01 * u1))
    u[o + 1] = _fma(j12, u2, _fma(j10, u0, j11 * u1))
    u[o + 2] = _fma(j22, u2, _fma(j20, u0, j21 * u1))
    return -1.0


@njit(cache=True)
def _integrate(blocks, R0, L0, th, R1, L1, two):
    """(R1, L1) = (R0, L0) exp(th): R0 @ exp(hat th) per rotation, L0 + th otherwise."""
    E = np.empty((3, 3))
    for b in range(blocks.shape[0]):
        kind, uo, ri, lo = blocks[b, 0], blocks[b, 1], blocks[b, 2], blocks[b, 3]
        if kind == REVOLUTE:
            L1[lo] = L0[lo] + th[uo]
            continue
        _exp(th[uo], th[uo + 1], th[uo + 2], two, E)
        _mm(R0[ri], E, R1[ri])
        if kind == FREE:
            for k in range(3):
                L1[lo + k] = L0[lo + k] + th[uo + 3 + k]


@njit(cache=True)
def pack(blocks, R, L, u, PV):
    """DART's positions PV[0] and velocities PV[1] of the state (R, L, u) (one row of the
    state's arrays): a FreeJoint's [rotation vector, x], [R W (world), v]; a BallJoint's
    rotation vector and W; a hinge's angle and rate (conventions.dart_free_from_state,
    dart_ball_from_state)."""
    pos, vel = PV[0], PV[1]
    for b in range(blocks.shape[0]):
        kind, uo, ri, lo, di = blocks[b, 0], blocks[b, 1], blocks[b, 2], blocks[b, 3], blocks[b, 4]
        if kind == REVOLUTE:
            pos[di] = L[lo]
            vel[di] = u[uo]
        elif kind == SPHERICAL:
            _rotvec(R[ri], pos, di)
            for k in range(3):
                vel[di + k] = u[uo + k]
        else:
            _rotvec(R[ri], pos, di)
            _mv(R[ri], u[uo], u[uo + 1], u[uo + 2], vel, di)
            for k in range(3):
                pos[di + 3 + k] = L[lo + k]
                vel[di + 3 + k] = u[uo + 3 + k]


@njit(cache=True)
def _unpack(blocks, R, a, out):
    """out = u' of DART's accelerations a at the stage (rotations R): a FreeJoint's world
    angular acceleration to body axes, R^T dw/dt; the others as they are."""
    for b in range(blocks.shape[0]):
        kind, uo, ri, di = blocks[b, 0], blocks[b, 1], blocks[b, 2], blocks[b, 4]
        if kind == FREE:
            _mtv(R[ri], a[di], a[di + 1], a[di + 2], out, uo)
            for k in range(3):
                out[uo + 3 + k] = a[di + 3 + k]
        else:
            for k in range(1 if kind == REVOLUTE else 3):
                out[uo + k] = a[di + k]


@njit(cache=True)
def _copy(R, L, U, src, dst):
    """Row ``dst`` of R and L (and of U when dst is the stage's row 1) = row ``src``."""
    for r in range(R.shape[1]):
        for i in range(3):
            for j in range(3):
                R[dst, r, i, j] = R[src, r, i, j]
    for k in range(L.shape[1]):
        L[dst, k] = L[src, k]
    if dst == 1:
        for k in range(U.shape[1]):
            U[1, k] = U[0, k]


@njit(cache=True)
def stage(i, blocks, R, L, U, K, a, PV, h, two):
    """Store the accelerations ``a`` of stage i - 1 (i > 0), then prepare stage i (0..3): its
    state in row 1 of R, L, U, its theta slope in K[0, i], DART's positions and velocities in
    PV. Returns -1.0, or the squared angle (>= pi^2, or not finite) of the first joint rotation
    whose dexp^{-1} the stage cannot take (nothing prepared then)."""
    n = U.shape[1]
    if i > 0:
        _unpack(blocks, R[1], a, K[1, i - 1])
    if i == 0:
        _copy(R, L, U, 0, 1)
        for k in range(n):
            K[0, 0, k] = U[0, k]
    else:
        ch = 0.5 * h if i < 3 else h
        th = np.empty(n)
        for k in range(n):
            th[k] = ch * K[0, i - 1, k]
            U[1, k] = U[0, k] + ch * K[1, i - 1, k]
        kt = K[0, i]
        for k in range(n):
            kt[k] = U[1, k]
        for b in range(blocks.shape[0]):
            if blocks[b, 0] != REVOLUTE:
                uo = blocks[b, 1]
                bad = _dexpinv(th[uo], th[uo + 1], th[uo + 2], kt, uo)
                if bad >= 0.0:
                    return bad
        _integrate(blocks, R[0], L[0], th, R[1], L[1], two)
    pack(blocks, R[1], L[1], U[1], PV)
    return -1.0


@njit(cache=True)
def finish(blocks, R, L, U, K, a, h, two):
    """Store the accelerations ``a`` of stage 3 and advance row 0 of (R, L, U) by the step."""
    n = U.shape[1]
    _unpack(blocks, R[1], a, K[1, 3])
    w = h / 6.0
    th = np.empty(n)
    for k in range(n):
        th[k] = w * (K[0, 0, k] + 2.0 * K[0, 1, k] + 2.0 * K[0, 2, k] + K[0, 3, k])
        U[0, k] = U[0, k] + w * (K[1, 0, k] + 2.0 * K[1, 1, k] + 2.0 * K[1, 2, k] + K[1, 3, k])
    _integrate(blocks, R[0], L[0], th, R[1], L[1], two)
    _copy(R, L, U, 1, 0)


def warm_up() -> None:
    """Compile (or load from numba's cache) the entries once, outside any timed stage: a tree
    of a free root, a ball joint and a hinge."""
    blocks = np.array(
        [[FREE, 0, 0, 0, 0], [SPHERICAL, 6, 1, -1, 6], [REVOLUTE, 9, -1, 3, 9]], dtype=np.int64
    )
    R = np.zeros((2, 2, 3, 3))
    R[0, :] = np.eye(3)
    L, U = np.zeros((2, 4)), np.zeros((2, 10))
    K, PV, a = np.zeros((2, 4, 10)), np.zeros((2, 10)), np.zeros(10)
    for i in range(4):
        stage(i, blocks, R, L, U, K, a, PV, 1e-3, 2.0)
    finish(blocks, R, L, U, K, a, 1e-3, 2.0)
    pack(blocks, R[0], L[0], U[0], PV)
