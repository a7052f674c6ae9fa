"""A body on a hinge striking a plane: the contact reference of a system of bodies (kind
``hinged_strike``, :mod:`references.exact.contact_scene`), written for the suite.

Set-up: one rigid body (mass m, principal inertia I, attitude R0, centre of mass x0) on a
revolute joint to the ground (the hinge: world point H, world unit axis u), carrying a sphere
of radius r centred at its centre of mass, above a static plane n . x = c; uniform gravity g;
frictionless contact (mu = 0) with Newton restitution e in [0, 1); gravity along -n; released
at rest.

The body turns about the hinge by phi(t): x(phi) = H + Rot(u, phi) r0 (r0 = x0 - H), with

    I_H phi'' = u . (r(phi) x m g),   I_H = u . R0 I R0^T u + m |u x r0|^2,

(the moment balance about the fixed axis; the hinge's reaction has no moment about it). The
sphere's gap is s(phi) = n . x(phi) - c - r; its rate s' = J(phi) phi' with
J = n . (u x r(phi)). A frictionless impulse along n at the sphere's lowest point has the
moment J P about the axis, so Newton's law (s'+ = -e s'-) gives phi'+ = -e phi'-: each impact
turns the angular rate back, e times smaller. Flights between impacts are integrated by DOP853
at rtol 1e-12 with the impact found as an event (the error estimate: twice the gap to a run at
rtol 1e-10). With gravity along -n the gap is the centre's height less a constant, so energy
conservation in flight (I_H phi'^2/2 + m |g| height) lifts the sphere, after impact k, to
e^(2k) times its drop height h0 (the initial gap): the same law as a ball's bounce, and the
rebound metric reads the same facts. After the last flight whose apex is above 1e-12 h0
(e > 0), or at the first impact (e = 0), the body rests on the sphere if gravity presses it
on the plane (u . (r x m g) J < 0); the normal force is then N = -u . (r x m g)/J (the hinge
carries the rest of the weight).
"""

from __future__ import annotations

import numpy as np

from references.exact._util import ReferenceNotApplicable, rot_axis
from references.exact.contact import ContactMotion, _pivot_accuracy, _times, _unit

#: the flights are integrated at this rtol, and again at the check's to estimate the error
RTOL = 1e-12
RTOL_CHECK = 1e-10
#: impacts followed at most (each flight's apex gap is e^2 times the last's)
MAX_IMPACTS = 60
#: the bounces are taken as ended once a flight's apex gap is below this fraction of the drop
APEX_FLOOR = 1e-12


class HingedStrike:
    """A body on a hinge (world point ``hinge``, world ``axis``) carrying a sphere of
    ``radius`` at its centre of mass, above a plane (unit ``normal``, a ``point`` on it),
    frictionless, restitution ``e``, released at rest (module docstring).

    ``facts``: ``impact_times`` (s), ``rebound_heights`` (m: the sphere's greatest gap after
    each impact), ``drop_height`` (m: the initial gap), ``rest_time`` (s), ``sticks``
    (False), and, when the body rests from before half the horizon on, ``support_forces``
    ([N]: the plane's normal force at rest)."""

    def __init__(self, mass, inertia, x0, R0, hinge, axis, radius, normal, point, e, gravity):
        self.m = float(mass)
        self.u = _unit(axis, "the hinge's axis")
        self.n = _unit(normal, "the plane's normal")
        self.c = float(self.n @ np.asarray(point, dtype=float))
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.H = np.asarray(hinge, dtype=float)
        self.r0 = self.x0 - self.H
        self.radius, self.e = float(radius), float(e)
        self.g = np.asarray(gravity, dtype=float)
        if not 0.0 <= self.e < 1.0:
            raise ReferenceNotApplicable(f"hinged_strike: e = {self.e:g}; it follows 0 <= e < 1")
        Ig = self.R0 @ np.diag(np.asarray(inertia, dtype=float)) @ self.R0.T
        arm = np.cross(self.u, self.r0)
        if not float(np.linalg.norm(arm)) > 0:
            raise ReferenceNotApplicable("hinged_strike: the centre of mass is on the hinge axis")
        self.Ih = float(self.u @ Ig @ self.u) + self.m * float(arm @ arm)
        gn = -float(self.g @ self.n)
        if not gn > 0 or float(np.linalg.norm(self.g + gn * self.n)) > 1e-12 * gn:
            raise ReferenceNotApplicable("hinged_strike: gravity is not along the plane's -normal")
        self.drop = self.gap(0.0)
        if self.drop < -1e-12:
            raise ReferenceNotApplicable("hinged_strike: the sphere starts below the plane")

    def r(self, phi: float) -> np.ndarray:
        return rot_axis(self.u, np.array([phi]))[0] @ self.r0

    def gap(self, phi: float) -> float:
        return float(self.n @ (self.H + self.r(phi))) - self.c - self.radius

    def torque(self, phi: float) -> float:
        """u . (r(phi) x m g): gravity's moment about the hinge axis (N m)."""
        return float(self.u @ np.cross(self.r(phi), self.m * self.g))

    def jac(self, phi: float) -> float:
        """J(phi) = d gap / d phi."""
        return float(self.n @ np.cross(self.u, self.r(phi)))

    def _rhs(self, t, y):
        return [y[1], self.torque(y[0]) / self.Ih]

    def _flights(self, t_end: float, rtol: float):
        """[(t0, t1, dense solution)] of the flights up to ``t_end``, the impact times, and
        (rest time, rest angle) or None."""
        from scipy.integrate import solve_ivp

        def hit(t, y):
            return self.gap(y[0])

        hit.terminal, hit.direction = True, -1.0
        flights, impacts = [], []
        t0, y0 = 0.0, np.array([0.0, 0.0])
        for k in range(1, MAX_IMPACTS + 2):
            sol = solve_ivp(self._rhs, (t0, t_end), y0, method="DOP853", rtol=rtol,
                            atol=rtol * 1e-6, events=hit, dense_output=True)  # fmt: skip
            if not sol.success:
                raise ReferenceNotApplicable(f"hinged_strike: integration failed ({sol.message})")
            t1 = float(sol.t[-1])
            flights.append((t0, t1, sol.sol))
            if not len(sol.t_events[0]):  # no impact before t_end
                return flights, impacts, None
            impacts.append(t1)
            phi1, rate1 = (float(v) for v in sol.y_events[0][0])
            if self.e == 0 or self.e ** (2 * k) < APEX_FLOOR:  # the next apex: e^2k h0
                return flights, impacts, (t1, phi1)
            t0, y0 = t1, np.array([phi1, -self.e * rate1])
        raise ReferenceNotApplicable(f"hinged_strike: more than {MAX_IMPACTS} impacts")

    def _angles(self, t, rtol):
        flights, impacts, rest = self._flights(float(t[-1]), rtol)
        phi, rate = np.zeros_like(t), np.zeros_like(t)
        for t0, t1, f in flights:
            sel = (t >= t0) & (t <= t1)
            if sel.any():
                y = f(t[sel])
                phi[sel], rate[sel] = y[0], y[1]
        if rest is not None:
            sel = t > rest[0]
            phi[sel], rate[sel] = rest[1], 0.0
        return phi, rate, impacts, rest

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        phi, rate, impacts, rest = self._angles(t, RTOL)
        phi2, _, _, _ = self._angles(t, RTOL_CHECK)
        err = float(np.max(np.abs(phi2 - phi))) if len(t) > 1 else 0.0
        Q = rot_axis(self.u, phi)
        r = Q @ self.r0
        x = self.H + r
        w = rate[:, None] * self.u
        v = np.cross(w, r)
        R = Q @ self.R0
        W = np.einsum("nji,nj->ni", R, w)
        out = ContactMotion(t, x[:, None], R[:, None], v[:, None], W[:, None])
        drop = max(self.drop, 0.0)
        heights = [drop * self.e ** (2 * j) for j in range(1, len(impacts) + 1)] or [0.0]
        facts = {
            "sticks": False,
            "impact_times": [float(s) for s in impacts],
            "rebound_heights": heights if self.e > 0 else [0.0],
            "drop_height": float(drop),
        }
        if rest is not None:
            facts["rest_time"] = float(rest[0])
            J, tau = self.jac(rest[1]), self.torque(rest[1])
            if tau * J >= 0:
                raise ReferenceNotApplicable(
                    "hinged_strike: gravity lifts the sphere off the plane after the impact"
                )
            if rest[0] < 0.5 * float(t[-1]):
                facts["support_forces"] = np.array([-tau / J])
        if not len(impacts):
            facts.pop("rebound_heights")
        out.facts = facts
        out.accuracy = _pivot_accuracy(err, phi, self.r0, self.x0, float(t[-1]))
        out.method = (
            "rotation about the hinge, flights by DOP853 at rtol 1e-12 with the impacts as "
            "events, phi' -> -e phi' at each (error: twice the gap to a run at rtol 1e-10)"
        )
        return out
