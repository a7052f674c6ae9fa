"""The planar physical pendulum: a body on a fixed point swinging in a vertical plane.

Planar pendulum (no spin, W_k = 0, and no angular momentum about the vertical, a = 0: the
case where the Euler angles about the vertical reflect the motion at the pole instead of
passing through it, since phi' = 0 there except at the pole itself): the axis swings in the
vertical plane normal to the horizontal axis n, R(t) = Rot(n, theta(t) - theta0) R0, with theta
the angle from the downward vertical to the line pivot -> centre of mass, A theta'' =
-m |g| |l| sin(theta), and with w_p^2 = m |g| |l|/A, k^2 = theta'(0)^2/(4 w_p^2) +
sin^2(theta0/2): sin(theta/2) = k sn(w_p t + v0 | k^2) when it oscillates (k < 1),
theta/2 = am(k w_p t + w0 | 1/k^2) when it goes over the top (k > 1) (Lawden, Elliptic
Functions and Applications, 1989, section 5.2; Whittaker, Analytical Dynamics, section 44).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ellipkm1

from references.exact._util import jacobi, jacobi_inverse, rot_axis


class PlanarPendulum:
    """Exact motion of a physical pendulum swinging in a vertical plane (module docstring).

    Parameters: ``R0`` body-to-world rotation at t = 0, ``W0`` body rates at t = 0 (their world
    form R0 W0 must be normal to the swing plane), ``up`` (unit), ``eG`` the unit vector from
    the pivot to the centre of mass at t = 0 (world), ``wp2`` = m |g| |l|/A.

    Attributes: ``n`` (world axis of the swing), ``theta0``, ``thetadot0``, ``k2`` (k^2),
    ``case`` ("oscillating", "rotating", "separatrix" or "at rest"), ``period`` (period of
    cos(theta), s; inf if at rest or on the separatrix), ``theta_max`` (largest |theta|, pi
    when it goes over the top), ``thetadot_max``.
    """

    def __init__(self, R0, W0, up, eG, wp2: float):
        self.R0 = np.asarray(R0, dtype=float)
        self.W0 = np.asarray(W0, dtype=float)
        up = np.asarray(up, dtype=float)
        eG = np.asarray(eG, dtype=float)
        down = -up
        omega = self.R0 @ self.W0
        wn = float(np.linalg.norm(omega))
        cross = np.cross(down, eG)
        cn = float(np.linalg.norm(cross))
        if wn > 0.0:
            n = omega / wn  # normal to the swing plane: the rotation axis
        elif cn > 0.0:
            n = cross / cn  # released from rest: the plane of the axis and the vertical
        else:
            n = None
        self.wp = math.sqrt(wp2)
        self.case = "at rest" if n is None else ""
        if n is None:
            self.n, self.theta0, self.thetadot0, self.k2 = np.zeros(3), 0.0, 0.0, 0.0
            self.period = math.inf
            self.theta_max = math.atan2(cn, float(down @ eG))
            self.thetadot_max = 0.0
            return
        self.n = n
        th0 = math.atan2(float(cross @ n), float(down @ eG))  # signed angle about n, (-pi, pi]
        thd0 = float(omega @ n)
        self.theta0, self.thetadot0 = th0, thd0
        s0, c0 = math.sin(0.5 * th0), math.cos(0.5 * th0)
        e = thd0 / (2.0 * self.wp)  # theta'/(2 w_p)
        k2 = e * e + s0 * s0
        self.k2 = k2
        if thd0 == 0.0 and s0 == 0.0:  # resting at the bottom
            self.case, self.period, self.theta_max, self.thetadot_max = "at rest", math.inf, 0, 0
            return
        if thd0 == 0.0 and c0 == 0.0:  # balanced exactly over the pivot: stays there
            self.case, self.period = "at rest", math.inf
            self.theta_max, self.thetadot_max = abs(th0), 0.0
            return
        m1 = (c0 - e) * (c0 + e)  # 1 - k^2 = cos^2(theta0/2) - (theta'/(2 w_p))^2
        if m1 >= 0.0:
            self.case = "oscillating" if m1 > 0 else "separatrix"
            self._m, self._m1 = k2, m1
            self._K = float(ellipkm1(m1)) if m1 > 0 else math.inf
            self._k = math.sqrt(k2)
            # sin(theta/2) = k sn(v), theta' = 2 k w_p cn(v): sn(v0) : cn(v0) = s0 : e
            self._v0 = jacobi_inverse(s0, e, k2, m1, self._K)
            self.period = 2.0 * self._K / self.wp
            self.theta_max = 2.0 * math.asin(min(1.0, self._k))
            self.thetadot_max = 2.0 * self._k * self.wp
        else:
            self.case = "rotating"
            self._sign = 1.0 if thd0 > 0 else -1.0
            self._k = math.sqrt(k2)
            self._m, self._m1 = 1.0 / k2, -m1 / k2
            self._K = float(ellipkm1(self._m1))
            # theta/2 = sign am(w), w = k w_p t + w0: sn(w0) = sign sin(theta0/2), cn(w0) = cos
            self._w0 = jacobi_inverse(self._sign * s0, c0, self._m, self._m1, self._K)
            self._am0 = self._am(np.array([self._w0]))[0]
            self.period = 2.0 * self._K / (self._k * self.wp)
            self.theta_max = math.pi
            self.thetadot_max = 2.0 * self._k * self.wp

    def _am(self, w: np.ndarray) -> np.ndarray:
        """Jacobi amplitude am(w | 1/k^2), continuous (increases by pi per 2K)."""
        j = np.round(w / (2.0 * self._K))
        r = w - 2.0 * self._K * j
        sn, cn, _ = jacobi(r, self._m, self._m1, self._K)
        return math.pi * j + np.arctan2(sn, cn)

    def theta(self, t) -> tuple[np.ndarray, np.ndarray]:
        """theta(t) - theta0 and theta'(t)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.case == "at rest":
            return np.zeros(len(t)), np.zeros(len(t))
        if self.case == "rotating":
            w = self._k * self.wp * t + self._w0
            _, _, dn = jacobi(w, self._m, self._m1, self._K)
            dth = 2.0 * self._sign * (self._am(w) - self._am0)
            return dth, 2.0 * self._sign * self._k * self.wp * dn
        v = self.wp * t + self._v0
        sn, cn, dn = jacobi(v, self._m, self._m1, self._K)
        th = 2.0 * np.arctan2(self._k * sn, dn)
        return th - self.theta0, 2.0 * self._k * self.wp * cn

    def rotation_and_omega(self, t) -> tuple[np.ndarray, np.ndarray]:
        dth, thd = self.theta(t)
        R = rot_axis(self.n, dth) @ self.R0
        W = thd[:, None] * np.einsum("nji,j->ni", R, self.n)
        return R, W
