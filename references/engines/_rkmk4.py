"""Compiled pieces of the suite's RKMK4 (see :mod:`references.engines.liegroup` for the method).

The state is a flat float64 vector ``y`` of 13 entries, ``[q (4, w x y z), x_G (3), W (3),
v_G (3)]``: the rotation as a unit quaternion, so a stage rotation R0 exp(theta) is the
quaternion product q0 (x) exp(theta) and costs a few dozen flops instead of a 3x3 matrix
exponential. Slopes are kept in ``K`` (4 stages x 12: the algebra-valued theta' (6) and the
acceleration (6)). A step is four calls of :func:`stage` (each preparing the state ``z`` at
which the engine is asked for accelerations) and one of :func:`finish`; between them the engine
fills ``acc`` = [dW/dt (3) body axes, dv_G/dt (3) world axes]. y, z and acc are slices of one
workspace array (:data:`WORKSPACE`).

The arithmetic is the readable :func:`references.engines.liegroup.rkmk4_step` on SO(3) x R^3
in another parametrisation; a test holds the two to round-off. ``TOO_LARGE`` is returned when
a stage asks for a rotation of half a turn or more (exp is not one-to-one there).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

OK = 0
TOO_LARGE = 1

#: Runge-Kutta nodes of the classical tableau (stage i uses c_i h and the slope of stage i-1)
_C = np.array([0.0, 0.5, 0.5, 1.0])

#: the workspace of :func:`stage` and :func:`finish`: one array of WORKSPACE entries holding the
#: state y, the stage state z and the engine's accelerations acc at these slices (one array to
#: hand over instead of three: each array argument costs the call ~0.15 us of unboxing)
Y, Z, ACC = slice(0, 13), slice(13, 26), slice(26, 32)
WORKSPACE = 32


@njit(cache=True, inline="always")
def _dexpinv(t0, t1, t2, u0, u1, u2):
    """J_r(theta)^{-1} u on SO(3): u + theta x u / 2 + c theta x (theta x u)."""
    a2 = t0 * t0 + t1 * t1 + t2 * t2
    if a2 < 1e-6:
        c = 1.0 / 12.0 + a2 / 720.0 + a2 * a2 / 30240.0
    else:
        a = math.sqrt(a2)
        c = 1.0 / a2 - (1.0 + math.cos(a)) / (2.0 * a * math.sin(a))
    x0 = t1 * u2 - t2 * u1
    x1 = t2 * u0 - t0 * u2
    x2 = t0 * u1 - t1 * u0
    y0 = t1 * x2 - t2 * x1
    y1 = t2 * x0 - t0 * x2
    y2 = t0 * x1 - t1 * x0
    return u0 + 0.5 * x0 + c * y0, u1 + 0.5 * x1 + c * y1, u2 + 0.5 * x2 + c * y2


@njit(cache=True, inline="always")
def half_angle(t0, t1, t2):
    """(cos(a/2), sin(a/2)/a) of the rotation vector theta = (t0, t1, t2), a = |theta|: the
    unit quaternion of theta is (w, s theta)."""
    a2 = t0 * t0 + t1 * t1 + t2 * t2
    if a2 < 1e-8:
        # sin(a/2)/a and cos(a/2) by their series, exact to double precision below 1e-4 rad
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
        w = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
    else:
        a = math.sqrt(a2)
        s = math.sin(0.5 * a) / a
        w = math.cos(0.5 * a)
    return w, s


@njit(cache=True, inline="always")
def _qexp_mul(q, t0, t1, t2, out):
    """out[0:4] = q (x) exp(theta) (right multiplication: body-frame increment)."""
    w, s = half_angle(t0, t1, t2)
    e1, e2, e3 = s * t0, s * t1, s * t2
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    out[0] = q0 * w - q1 * e1 - q2 * e2 - q3 * e3
    out[1] = q0 * e1 + q1 * w + q2 * e3 - q3 * e2
    out[2] = q0 * e2 - q1 * e3 + q2 * w + q3 * e1
    out[3] = q0 * e3 + q1 * e2 - q2 * e1 + q3 * w


@njit(cache=True)
def stage(i, w, K, h, pivoted):
    """Store the previous stage's acceleration ``acc`` (i > 0) in K, then write into ``z`` the
    state of stage i (0..3) at which the engine is asked for accelerations. Returns OK or
    TOO_LARGE. ``w`` is the workspace (:data:`WORKSPACE`) holding y, z and acc."""
    y, z, acc = w[Y], w[Z], w[ACC]
    if i > 0:
        for k in range(6):
            K[i - 1, 6 + k] = acc[k]
    if i == 0:
        for k in range(13):
            z[k] = y[k]
        K[0, 0], K[0, 1], K[0, 2] = y[7], y[8], y[9]
        K[0, 3], K[0, 4], K[0, 5] = y[10], y[11], y[12]
        return OK
    ch = _C[i] * h
    t0 = ch * K[i - 1, 0]
    t1 = ch * K[i - 1, 1]
    t2 = ch * K[i - 1, 2]
    if not t0 * t0 + t1 * t1 + t2 * t2 < math.pi * math.pi:
        return TOO_LARGE
    _qexp_mul(y, t0, t1, t2, z)
    for k in range(3):
        z[4 + k] = y[4 + k] + ch * K[i - 1, 3 + k]  # x_i = x0 + c h (theta'_x)
        z[7 + k] = y[7 + k] + ch * K[i - 1, 6 + k]  # W_i
        z[10 + k] = y[10 + k] + ch * K[i - 1, 9 + k]  # v_i
    d0, d1, d2 = _dexpinv(t0, t1, t2, z[7], z[8], z[9])
    K[i, 0], K[i, 1], K[i, 2] = d0, d1, d2
    K[i, 3], K[i, 4], K[i, 5] = z[10], z[11], z[12]
    if pivoted:
        for k in range(3):
            z[4 + k] = 0.0
            z[10 + k] = 0.0
    return OK


@njit(cache=True)
def finish(w, K, h, pivoted):
    """Store the last stage's acceleration and advance ``y`` by one step (in place, with the
    quaternion renormalised). Returns OK or TOO_LARGE. ``w`` as for :func:`stage`."""
    y, z, acc = w[Y], w[Z], w[ACC]
    for k in range(6):
        K[3, 6 + k] = acc[k]
    w1, w2 = h / 6.0, h / 3.0
    th = np.empty(12)
    for k in range(12):
        th[k] = w1 * (K[0, k] + K[3, k]) + w2 * (K[1, k] + K[2, k])
    if not th[0] * th[0] + th[1] * th[1] + th[2] * th[2] < math.pi * math.pi:
        return TOO_LARGE
    _qexp_mul(y, th[0], th[1], th[2], z)
    n = math.sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2] + z[3] * z[3])
    for k in range(4):
        y[k] = z[k] / n
    for k in range(3):
        y[4 + k] = 0.0 if pivoted else y[4 + k] + th[3 + k]
        y[7 + k] += th[6 + k]
        y[10 + k] = 0.0 if pivoted else y[10 + k] + th[9 + k]
    return OK


# -- packing for the engines --------------------------------------------------------------------


#: the ``sign`` argument of :func:`rotate`
FORWARD = 1.0
INVERSE = -1.0


@njit(cache=True)
def rotate(q, v, out, sign):
    """out = R(q) v (``sign`` FORWARD, 1.0) or R(q)^T v (INVERSE, -1.0: the vector part of q
    negated, exactly) for a unit quaternion q (w, x, y, z). The sign is a float, not a bool:
    numba would compile a version for each of the literals True and False."""
    w, x, y, z = q[0], sign * q[1], sign * q[2], sign * q[3]
    # v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
    c0 = y * v[2] - z * v[1]
    c1 = z * v[0] - x * v[2]
    c2 = x * v[1] - y * v[0]
    out[0] = v[0] + 2.0 * (w * c0 + y * c2 - z * c1)
    out[1] = v[1] + 2.0 * (w * c1 + z * c0 - x * c2)
    out[2] = v[2] + 2.0 * (w * c2 + x * c1 - y * c0)


@njit(cache=True)
def rotvec(q, out):
    """The rotation vector (|theta| <= pi) of a unit quaternion q (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    n = math.sqrt(x * x + y * y + z * z)
    f = 2.0 / w if n < 1e-8 else 2.0 * math.atan2(n, w) / n
    out[0], out[1], out[2] = f * x, f * y, f * z


@njit(cache=True)
def pack_pinocchio(z, pivoted, qp, vp):
    """Pinocchio's (q, v) of the stage state z: FreeFlyer q = [x, qx, qy, qz, qw], v = [R^T v_G,
    W] (LOCAL); Spherical q = [qx, qy, qz, qw], v = W."""
    if pivoted:
        qp[0], qp[1], qp[2], qp[3] = z[1], z[2], z[3], z[0]
        vp[0], vp[1], vp[2] = z[7], z[8], z[9]
        return
    qp[0], qp[1], qp[2] = z[4], z[5], z[6]
    qp[3], qp[4], qp[5], qp[6] = z[1], z[2], z[3], z[0]
    rotate(z[0:4], z[10:13], vp[0:3], INVERSE)
    vp[3], vp[4], vp[5] = z[7], z[8], z[9]


@njit(cache=True)
def unpack_pinocchio(z, pivoted, a, acc):
    """(dW/dt, a_G) from Pinocchio's joint acceleration: the FreeFlyer's is the derivative of
    its LOCAL velocity, so a_G = R (dv_local/dt + W x R^T v_G)."""
    if pivoted:
        acc[0], acc[1], acc[2] = a[0], a[1], a[2]
        acc[3] = acc[4] = acc[5] = 0.0
        return
    vl = np.empty(3)
    rotate(z[0:4], z[10:13], vl, INVERSE)
    W0, W1, W2 = z[7], z[8], z[9]
    t = np.empty(3)
    t[0] = a[0] + W1 * vl[2] - W2 * vl[1]
    t[1] = a[1] + W2 * vl[0] - W0 * vl[2]
    t[2] = a[2] + W0 * vl[1] - W1 * vl[0]
    rotate(z[0:4], t, acc[3:6], FORWARD)
    acc[0], acc[1], acc[2] = a[3], a[4], a[5]


@njit(cache=True)
def pack_dart(z, pivoted, pos, vel):
    """DART's positions and velocities of the stage state z: FreeJoint [rotation vector, x],
    [w = R W (world), v_G]; BallJoint: rotation vector, W (body)."""
    if pivoted:
        rotvec(z[0:4], pos)
        vel[0], vel[1], vel[2] = z[7], z[8], z[9]
        return
    rotvec(z[0:4], pos[0:3])
    pos[3], pos[4], pos[5] = z[4], z[5], z[6]
    rotate(z[0:4], z[7:10], vel[0:3], FORWARD)
    vel[3], vel[4], vel[5] = z[10], z[11], z[12]


@njit(cache=True)
def unpack_dart(z, pivoted, a, acc):
    """(dW/dt, a_G) from DART's accelerations: a FreeJoint's angular one is world-frame, and
    dW/dt = R^T dw/dt (R'^T w = -(W x W) = 0)."""
    if pivoted:
        acc[0], acc[1], acc[2] = a[0], a[1], a[2]
        acc[3] = acc[4] = acc[5] = 0.0
        return
    rotate(z[0:4], a[0:3], acc[0:3], INVERSE)
    acc[3], acc[4], acc[5] = a[3], a[4], a[5]


# -- a stage and the engine's packing in one call ------------------------------------------------
# Per stage the stepper makes one compiled call before the engine's (the previous stage's
# accelerations unpacked from the engine's vector ``a``, this stage's state, packed into the
# engine's buffers) instead of three, and the step's end and the next step's stage 0 are one
# call: each call from Python costs ~0.2 us, a tenth of an engine's call, and each array
# argument ~0.04 us of it, so the slopes K and the engine's buffers live in the workspace too
# (:data:`STAGED_WORKSPACE`). The same functions in the same order as the separate calls.

#: the staged workspace: y, z, acc (:data:`WORKSPACE`), then K (4 x 12, row-major) at KS, then
#: the engine's two buffers from BUF (:func:`pinocchio_buffers`, :func:`dart_buffers`)
KS = slice(32, 80)
BUF = 80
STAGED_WORKSPACE = BUF + 13


def pinocchio_buffers(w, pivoted: bool):
    """Pinocchio's (q, v) buffers in the staged workspace ``w``: views, (4, 3) entries for a
    Spherical joint, (7, 6) for a FreeFlyer."""
    nq, nv = (4, 3) if pivoted else (7, 6)
    return w[BUF : BUF + nq], w[BUF + nq : BUF + nq + nv]


def dart_buffers(w, pivoted: bool):
    """DART's (positions, velocities) buffers in the staged workspace ``w``: views, 3 entries
    each for a BallJoint, 6 for a FreeJoint."""
    n = 3 if pivoted else 6
    return w[BUF : BUF + n], w[BUF + n : BUF + 2 * n]


@njit(cache=True)
def _pinocchio_stage(i, w, K, h, pivoted, a, qp, vp):
    if i > 0:
        unpack_pinocchio(w[Z], pivoted, a, w[ACC])
    r = stage(i, w, K, h, pivoted)
    if r == OK:
        pack_pinocchio(w[Z], pivoted, qp, vp)
    return r


@njit(cache=True)
def pinocchio_stage(i, w, h, pivoted, a):
    """:func:`unpack_pinocchio` of ``a`` (i > 0), :func:`stage` i, :func:`pack_pinocchio`
    of its state into the buffers when it succeeded; ``w`` the staged workspace. Returns what
    :func:`stage` returns."""
    nq, nv = (4, 3) if pivoted else (7, 6)
    K = w[KS].reshape((4, 12))
    return _pinocchio_stage(i, w, K, h, pivoted, a, w[BUF : BUF + nq], w[BUF + nq : BUF + nq + nv])


@njit(cache=True)
def pinocchio_finish(w, h, pivoted, a):
    """:func:`unpack_pinocchio` of the last stage's ``a``, :func:`finish`, then, when it
    succeeded, the next step's stage 0 (:func:`pinocchio_stage`). Returns what :func:`finish`
    returns."""
    K = w[KS].reshape((4, 12))
    unpack_pinocchio(w[Z], pivoted, a, w[ACC])
    r = finish(w, K, h, pivoted)
    if r == OK:
        pinocchio_stage(0, w, h, pivoted, a)
    return r


@njit(cache=True)
def _dart_stage(i, w, K, h, pivoted, a, pos, vel):
    if i > 0:
        unpack_dart(w[Z], pivoted, a, w[ACC])
    r = stage(i, w, K, h, pivoted)
    if r == OK:
        pack_dart(w[Z], pivoted, pos, vel)
    return r


@njit(cache=True)
def dart_stage(i, w, h, pivoted, a):
    """:func:`unpack_dart` of ``a`` (i > 0), :func:`stage` i, :func:`pack_dart` of its state
    into the buffers when it succeeded; ``w`` the staged workspace. Returns what :func:`stage`
    returns."""
    n = 3 if pivoted else 6
    K = w[KS].reshape((4, 12))
    return _dart_stage(i, w, K, h, pivoted, a, w[BUF : BUF + n], w[BUF + n : BUF + 2 * n])


@njit(cache=True)
def dart_finish(w, h, pivoted, a):
    """:func:`unpack_dart` of the last stage's ``a``, :func:`finish`, then, when it
    succeeded, the next step's stage 0 (:func:`dart_stage`). Returns what :func:`finish`
    returns."""
    K = w[KS].reshape((4, 12))
    unpack_dart(w[Z], pivoted, a, w[ACC])
    r = finish(w, K, h, pivoted)
    if r == OK:
        dart_stage(0, w, h, pivoted, a)
    return r


def warm_up() -> None:
    """Compile (or load from numba's cache) every function once, outside any timed region."""
    w = np.zeros(WORKSPACE)
    w[0] = 1.0
    z, acc = w[Z], w[ACC]
    K = np.zeros((4, 12))
    for i in range(4):
        stage(i, w, K, 1e-3, False)
    finish(w, K, 1e-3, False)
    for pivoted in (False, True):
        n = 4 if pivoted else 7
        m = 3 if pivoted else 6
        pack_pinocchio(z, pivoted, np.zeros(n), np.zeros(m))
        unpack_pinocchio(z, pivoted, np.zeros(m), acc)
        pack_dart(z, pivoted, np.zeros(m), np.zeros(m))
        unpack_dart(z, pivoted, np.zeros(m), acc)
        ws = np.zeros(STAGED_WORKSPACE)
        ws[0] = 1.0
        for staged in (pinocchio_stage, dart_stage):
            staged(1, ws, 1e-3, pivoted, np.zeros(m))
        pinocchio_finish(ws, 1e-3, pivoted, np.zeros(m))
        dart_finish(ws, 1e-3, pivoted, np.zeros(m))
