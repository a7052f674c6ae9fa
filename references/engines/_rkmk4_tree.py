"""Compiled stages of the suite's RKMK4 on a tree's product group (DART's system builder,
:mod:`references.engines.dart.system`), the method of :func:`references.engines.liegroup.
rkmk4_step` on the product of the tree joints' groups: SO(3) x R^3 for a free root (body-axes
W, world v_G), SO(3) for a ball joint (body-axes relative rate), R^n for the others.

The state: positions ``y`` and velocities ``u``, flat, each joint at its offsets (``J``, one
row per tree joint: kind, offset in y, offset in u, velocity dofs, index of its first dof in
the engine's vectors). A free root's positions are a unit quaternion (w, x, y, z) and x_G
(7), a ball joint's a unit quaternion (4), the others' the joint coordinates; so a stage
rotation R0 exp(theta) is a quaternion product, as in :mod:`references.engines._rkmk4`. The
stage state is (``zy``, ``zu``), the slopes ``K`` (4 stages x [theta' (nu), u' (nu)]).

A step is four calls of :func:`stage` and one of :func:`finish`; each stage call first takes
the previous stage's accelerations from the engine's vector ``a`` (a free root's angular one
is world-axes: dW/dt = R^T dw/dt because R'^T w = -(W x W) = 0) and, after computing its
state, packs it into the engine's positions and velocities (DART's: a rotation vector and x,
[w WORLD, v WORLD] for a free root; a rotation vector and the body rate for a ball joint).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from references.engines import _rkmk4 as _rkmk4_module
from references.engines._rkmk4 import (
    FORWARD,
    INVERSE,
    OK,
    TOO_LARGE,
    _dexpinv,
    _qexp_mul,
    half_angle,
    rotate,
    rotvec,
)

FREE, BALL, VECTOR = 0, 1, 2
#: the columns of the joint table ``J``
KIND, YOFF, UOFF, NDOF, DOF = range(5)
#: Runge-Kutta nodes of the classical tableau (stage i uses c_i h and the slope of stage i-1)
_C = np.array([0.0, 0.5, 0.5, 1.0])


@njit(cache=True)
def quat_of_rotvec(r, out):
    """out[0:4] = the unit quaternion (w, x, y, z) of the rotation vector r (3,)."""
    t0, t1, t2 = r[0], r[1], r[2]
    w, s = half_angle(t0, t1, t2)
    out[0], out[1], out[2], out[3] = w, s * t0, s * t1, s * t2


@njit(cache=True)
def pack(J, zy, zu, pos, vel):
    """The engine's positions and velocities of the state (zy, zu)."""
    for j in range(J.shape[0]):
        kind, yo, uo, n, d = J[j, KIND], J[j, YOFF], J[j, UOFF], J[j, NDOF], J[j, DOF]
        if kind == VECTOR:
            for k in range(n):
                pos[d + k] = zy[yo + k]
                vel[d + k] = zu[uo + k]
            continue
        q = zy[yo : yo + 4]
        rotvec(q, pos[d : d + 3])
        if kind == BALL:
            for k in range(3):
                vel[d + k] = zu[uo + k]
        else:
            rotate(q, zu[uo : uo + 3], vel[d : d + 3], FORWARD)
            for k in range(3):
                pos[d + 3 + k] = zy[yo + 4 + k]
                vel[d + 3 + k] = zu[uo + 3 + k]


@njit(cache=True)
def unpack(J, zy, a, out):
    """The accelerations u' (nu,) at the stage state zy from the engine's vector ``a``."""
    for j in range(J.shape[0]):
        kind, yo, uo, n, d = J[j, KIND], J[j, YOFF], J[j, UOFF], J[j, NDOF], J[j, DOF]
        if kind == FREE:
            rotate(zy[yo : yo + 4], a[d : d + 3], out[uo : uo + 3], INVERSE)
            for k in range(3, 6):
                out[uo + k] = a[d + k]
        else:
            for k in range(n):
                out[uo + k] = a[d + k]


@njit(cache=True)
def stage(i, J, y, u, zy, zu, K, h, a, pos, vel):
    """Store the previous stage's accelerations (from ``a``, i > 0) in K, then write stage i's
    state into (zy, zu), its slope theta' into K[i] and the engine's positions and velocities
    of it into (pos, vel). Returns OK, or TOO_LARGE when a rotation of the stage reaches half a
    turn (exp is not one-to-one there)."""
    nu = u.shape[0]
    if i == 0:
        zy[:] = y
        zu[:] = u
        K[0, :nu] = u
        pack(J, zy, zu, pos, vel)
        return OK
    unpack(J, zy, a, K[i - 1, nu:])
    ch = _C[i] * h
    for k in range(nu):
        zu[k] = u[k] + ch * K[i - 1, nu + k]
    for j in range(J.shape[0]):
        kind, yo, uo, n = J[j, KIND], J[j, YOFF], J[j, UOFF], J[j, NDOF]
        if kind == VECTOR:
            for k in range(n):
                zy[yo + k] = y[yo + k] + ch * K[i - 1, uo + k]
                K[i, uo + k] = zu[uo + k]
            continue
        t0 = ch * K[i - 1, uo]
        t1 = ch * K[i - 1, uo + 1]
        t2 = ch * K[i - 1, uo + 2]
        if not t0 * t0 + t1 * t1 + t2 * t2 < math.pi * math.pi:
            return TOO_LARGE
        _qexp_mul(y[yo : yo + 4], t0, t1, t2, zy[yo : yo + 4])
        d0, d1, d2 = _dexpinv(t0, t1, t2, zu[uo], zu[uo + 1], zu[uo + 2])
        K[i, uo], K[i, uo + 1], K[i, uo + 2] = d0, d1, d2
        if kind == FREE:
            for k in range(3):
                zy[yo + 4 + k] = y[yo + 4 + k] + ch * K[i - 1, uo + 3 + k]
                K[i, uo + 3 + k] = zu[uo + 3 + k]
    pack(J, zy, zu, pos, vel)
    return OK


@njit(cache=True)
def finish(J, y, u, zy, K, h, a):
    """Store the last stage's accelerations (from ``a``) and advance (y, u) by one step in
    place, each joint's quaternion renormalised."""
    nu = u.shape[0]
    unpack(J, zy, a, K[3, nu:])
    w1, w2 = h / 6.0, h / 3.0
    for k in range(nu):
        u[k] += w1 * (K[0, nu + k] + K[3, nu + k]) + w2 * (K[1, nu + k] + K[2, nu + k])
    for j in range(J.shape[0]):
        kind, yo, uo, n = J[j, KIND], J[j, YOFF], J[j, UOFF], J[j, NDOF]
        m = n if kind == VECTOR else (3 if kind == FREE else 0)
        first = n - m  # the translational coordinates follow the rotation's three
        for k in range(m):
            c = uo + first + k
            y[yo + (4 if kind == FREE else 0) + k] += w1 * (K[0, c] + K[3, c]) + w2 * (
                K[1, c] + K[2, c]
            )
        if kind == VECTOR:
            continue
        th = np.empty(3)
        for k in range(3):
            c = uo + k
            th[k] = w1 * (K[0, c] + K[3, c]) + w2 * (K[1, c] + K[2, c])
        q = zy[yo : yo + 4]
        _qexp_mul(y[yo : yo + 4], th[0], th[1], th[2], q)
        nq = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        for k in range(4):
            y[yo + k] = q[k] / nq
    return OK


_tied = False


def _tie() -> None:
    """numba keys a function's disk cache on its own file only: the stage arithmetic compiled
    in from _rkmk4.py (the quaternion exponential, dexp^-1, rotations) would stay stale after
    an edit there, so director_model._cache.tie adds that file's content to the key. Done at
    the first warm-up (importing director_model for it costs ~0.35 s, which a module import
    of a DART builder should not pay)."""
    global _tied
    if not _tied:
        from director_model import _cache

        # this module's own functions only: those imported from _rkmk4 (rotate, ...) are
        # dispatchers shared with it, cached under _rkmk4.py's own stamp; tying them here
        # would give them another stamp in a process that built a DART tree than in one
        # that did not, and each would find the other's cache stale and compile them again
        own = {
            k: v
            for k, v in globals().items()
            if getattr(getattr(v, "py_func", None), "__module__", None) == __name__
        }
        _cache.tie({"__name__": __name__, **own}, Path(_rkmk4_module.__file__))
        _tied = True


def warm_up() -> None:
    """Compile (or load from numba's cache) every function once, outside any timed region;
    its cache keyed on _rkmk4.py too (:func:`_tie`)."""
    _tie()
    J = np.array([[FREE, 0, 0, 6, 0], [BALL, 7, 6, 3, 6], [VECTOR, 11, 9, 1, 9]], np.int64)
    y, u = np.zeros(12), np.zeros(10)
    y[0] = y[7] = 1.0
    zy, zu, K = y.copy(), u.copy(), np.zeros((4, 20))
    a, pos, vel = np.zeros(10), np.zeros(10), np.zeros(10)
    for i in range(4):
        stage(i, J, y, u, zy, zu, K, 1e-3, a, pos, vel)
    finish(J, y, u, zy, K, 1e-3, a)
    quat_of_rotvec(np.zeros(3), np.zeros(4))
