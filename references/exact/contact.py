"""Exact motions of rigid bodies in frictional contact with a plane (closed forms), each giving
the bodies' x, R, v, W over time, the facts a contact metric compares with (sticks or slides,
the rolling onset, rebound heights, the force through each support) and a round-off accuracy.

Model: rigid bodies, a static plane n . x = c (n the unit outward normal), uniform gravity g,
isotropic Coulomb friction mu, Newton restitution e, no rolling or torsional resistance. The
laws are the classical ones (e.g. Pfeiffer and Glocker, *Multibody Dynamics with Unilateral
Contacts*, 1996; the rolling sphere in Routh, *Dynamics of a System of Rigid Bodies*, 1905,
ch. on friction); each formula below was derived here for the stated set-up.

1. :class:`SlidingBlock`: a box resting flat on the plane, loaded by gravity and constant
   forces. With P = m g + sum F the applied resultant, N = -P . n > 0 the normal load and
   P_t = P + N n its tangential part: the block sticks iff |P_t| <= mu N (motion 0, friction
   -P_t); else it slides along P_t with a = (|P_t| - mu N)/m, s(t) = a t^2/2, friction
   -mu N P_t/|P_t|. Valid while the block does not tip: the contact resultant C = -P (stick)
   or N n - mu N p (slide) passes through the base at delta = n x b / N from the base centre,
   b = h (n x f) - tau_t (h the centre of mass's height above the base, f the friction, tau
   the applied torque about the centre of mass, tau_t its tangential part); the block is
   refused if delta leaves the base or if tau has a component along n (it would turn).
2. :class:`TippingBlock`: a box on the plane whose downhill bottom edge carries it: released at
   rest with tan(th) > w/h (w the base half-width along the slope, h the half-height), it turns
   about that edge, axis u = n x d (d the downhill unit vector), by phi(t) with
   I_P phi'' = u . (r(phi) x m g), r(phi) = Rot(u, phi) r0, r0 = G - P (P on the edge),
   I_P = u.I_G u + m |r0|^2. phi(t) is integrated by DOP853 at rtol 1e-12 (an error estimate from
   a second run at rtol 1e-10). Valid while the edge neither lifts nor slips: the edge's reaction
   C = m a_G - m g has C . n > 0 and |C_t| <= mu C . n (checked over the horizon; refused beyond).
3. :class:`Rolling`: a sphere or a cylinder lying on its side (radius r, I = k m r^2 about the
   rolling axis) on the plane, its centre moving along the in-plane unit vector e, spinning about
   a = n x e at w (u = v - r w is the slip speed of the contact point along e). With
   g_t = g . e and g_n = -g . n > 0: while u != 0, v' = g_t - mu g_n s, r w' = mu g_n s / k,
   s = sign(u); rolling (u = 0) holds iff mu g_n >= k |g_t| / (1 + k), with v' = r w' =
   g_t/(1 + k); a body that cannot roll slides with s = sign(g_t). Flat ground, v0 = V, r w0 = Q:
   rolling from t* = k (V - Q)/(mu g (1 + k)) (for V > Q) at v* = (V + k Q)/(1 + k).
4. :class:`Bounce`: a body dropped with its lowest point at height z0 above the plane, velocity
   w0 along n (gravity along -n): flights are parabolas; impact j rebounds at e^j V1
   (V1 = sqrt(w0^2 + 2 g z0)), reaching heights e^(2j) V1^2/(2g); the bounces end at
   t_inf = t1 + 2 e V1 / (g (1 - e)) (t1: the first impact; e = 0: t_inf = t1), then rest.
   A spin is kept (frictionless, or about n).
5. :class:`Resting`: bodies released at rest in a configuration of static equilibrium (a box on
   the ground, a stack): the motion is 0; the force through each support (a body on the body or
   plane below it) is the weight of everything it carries.

Accuracy: the closed forms are exact; their evaluation errs by round-off, estimated as 16 eps
times the size of each quantity (positions: |x| + the distance travelled; attitudes: 16 eps
(1 + |angle turned|) rad). The tipping block's: its DOP853 error estimate plus that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from references.exact._util import EPS, ReferenceNotApplicable, rot_axis

#: a vector is taken as lying in the plane, or a force as not turning a body, below this
#: relative size (the files print 17 digits; their rounding is ~1e-16)
GEOMETRY_TOL = 1e-9
#: the tipping block's integration tolerance and that of its error-estimating second run
TIP_RTOL = 1e-12
TIP_RTOL_CHECK = 1e-10


@dataclass
class ContactMotion:
    """Every body's state at the times ``t``: ``x`` (n, nb, 3) world, ``R`` (n, nb, 3, 3)
    body to world, ``v`` (n, nb, 3) world, ``W`` (n, nb, 3) body axes; ``facts`` (the
    quantities contact metrics compare with, documented per kind), ``accuracy``
    {"position": m, "attitude": rad, "velocity": m/s} and ``method``."""

    t: np.ndarray
    x: np.ndarray
    R: np.ndarray
    v: np.ndarray
    W: np.ndarray
    facts: dict = field(default_factory=dict)
    accuracy: dict = field(default_factory=dict)
    method: str = ""


def _unit(a, what: str) -> np.ndarray:
    a = np.asarray(a, dtype=float).reshape(3)
    n = float(np.linalg.norm(a))
    if not n > 0 or not math.isfinite(n):
        raise ReferenceNotApplicable(f"{what}: {a.tolist()} is not a direction")
    return a / n


def _times(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1 or not np.all(np.isfinite(t)) or np.any(t < 0) or np.any(np.diff(t) < 0):
        raise ValueError("times must be a 1-D sorted array of finite values >= 0")
    return t


def _pivot_accuracy(err, phi, r0, x0, t_end) -> dict:
    """Accuracy of a motion integrated as a rotation phi(t) about a fixed axis (a box tipping
    about its edge, a body on a hinge): the angle's error ``err`` (the DOP853 estimate) plus
    round-off on the angle swept; positions at the reach ``|r0|`` of the centre from the axis,
    plus round-off of the position ``x0``; velocities that angle error over the run."""
    att = 2.0 * err + 16 * EPS * (1.0 + float(np.max(np.abs(phi))))
    reach = float(np.linalg.norm(r0))
    return {
        "position": att * reach + 16 * EPS * float(np.linalg.norm(x0)),
        "attitude": att,
        "velocity": att * reach / max(t_end, 1e-300),
    }


def _stack(t, x, R, v, W) -> ContactMotion:
    """One body's (n, ...) arrays as a motion of one body."""
    return ContactMotion(t, x[:, None], R[:, None], v[:, None], W[:, None])


def _face_on_plane(R, half, n, what: str) -> tuple[int, float]:
    """(k, sign): the body axis k with R e_k = sign n (the face -sign k of the box lies on the
    plane); refused if no body axis is normal to the plane."""
    dots = R.T @ n
    k = int(np.argmax(np.abs(dots)))
    if abs(abs(dots[k]) - 1.0) > GEOMETRY_TOL:
        raise ReferenceNotApplicable(
            f"{what}: no face of the box lies flat on the plane (the body axes make angles "
            f"with the normal of cosines {np.round(dots, 12).tolist()})"
        )
    return k, float(np.sign(dots[k]))


# -- 1. a block that sticks or slides ------------------------------------------------------


class SlidingBlock:
    """A box (``half_extents`` along its principal axes) resting flat on the plane with unit
    normal ``normal``, centre of mass at ``x0`` (its base on the plane), attitude ``R0``,
    mass ``mass``, Coulomb ``mu``, gravity ``gravity`` and constant ``forces`` [(force (3,)
    world, point (3,) in the body frame relative to the centre of mass), ...]. Module
    docstring, item 1.

    ``facts``: ``sticks`` (bool), ``acceleration`` (m/s^2, 0 when it sticks), ``direction``
    (unit (3,), the sliding direction; zeros when it sticks), ``normal_force`` N (N),
    ``friction_force`` (3,) N world, ``friction_ratio`` |f|/(mu N) (<= 1; NaN when mu N = 0),
    ``pressure_offset`` delta (3,) m."""

    def __init__(self, mass, half_extents, x0, R0, normal, mu, gravity, forces=()):
        self.m = float(mass)
        self.half = np.asarray(half_extents, dtype=float)
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.n = _unit(normal, "the plane's normal")
        self.mu = float(mu)
        g = np.asarray(gravity, dtype=float)
        what = "sliding_block"
        k, _ = _face_on_plane(self.R0, self.half, self.n, what)
        self.h = float(self.half[k])
        P = self.m * g
        tau = np.zeros(3)
        for F, p in forces:
            F = np.asarray(F, dtype=float)
            P = P + F
            tau = tau + np.cross(self.R0 @ np.asarray(p, dtype=float), F)
        N = -float(P @ self.n)
        if not N > 0:
            raise ReferenceNotApplicable(
                f"{what}: the applied forces do not press the block on the plane (normal load "
                f"{N:.6g} N): it lifts off"
            )
        Pt = P + N * self.n
        pt = float(np.linalg.norm(Pt))
        scale = float(np.linalg.norm(P)) + N
        self.sticks = pt <= self.mu * N
        if self.sticks:
            f = -Pt
            self.a = 0.0
            self.d = np.zeros(3)
        else:
            self.d = Pt / pt
            f = -self.mu * N * self.d
            self.a = (pt - self.mu * N) / self.m
        tau_n = float(tau @ self.n)
        lever = float(np.max(self.half))
        if abs(tau_n) > GEOMETRY_TOL * scale * lever:
            raise ReferenceNotApplicable(
                f"{what}: the applied forces turn the block about the normal (torque "
                f"{tau_n:.3g} N m): no closed form here"
            )
        b = self.h * np.cross(self.n, f) - (tau - tau_n * self.n)
        delta = np.cross(self.n, b) / N
        tw = float(np.linalg.norm(np.cross(delta, f)))
        if tw > GEOMETRY_TOL * scale * lever:
            raise ReferenceNotApplicable(
                f"{what}: the applied torque and the friction cannot be balanced by a pressure "
                "centre in the base: the block would turn"
            )
        offs = np.abs(self.R0.T @ delta)
        base = [i for i in range(3) if i != k]
        if any(offs[i] > self.half[i] for i in base):
            raise ReferenceNotApplicable(
                f"{what}: the block tips: the contact force would pass {offs[base].tolist()} m "
                f"from the base centre, outside the half extents {self.half[base].tolist()} m"
            )
        self.N = N
        self.f = f
        self.facts = {
            "sticks": bool(self.sticks),
            "acceleration": float(self.a),
            "direction": self.d.copy(),
            "normal_force": float(N),
            "friction_force": f.copy(),
            "friction_ratio": float(np.linalg.norm(f)) / (self.mu * N) if self.mu > 0 else math.nan,
            "pressure_offset": delta,
        }

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        s = 0.5 * self.a * t * t
        x = self.x0 + s[:, None] * self.d
        v = (self.a * t)[:, None] * self.d
        R = np.broadcast_to(self.R0, (len(t), 3, 3)).copy()
        W = np.zeros((len(t), 3))
        out = _stack(t, x, R, v, W)
        out.facts = dict(self.facts, slide_distance=float(0.5 * self.a * t[-1] ** 2))
        size = float(np.linalg.norm(self.x0)) + float(s[-1])
        out.accuracy = {
            "position": 16 * EPS * size,
            "attitude": 16 * EPS,
            "velocity": 16 * EPS * self.a * float(t[-1]),
        }
        out.method = (
            "closed form: sticks (motion 0)"
            if self.sticks
            else f"closed form: slides, s = a t^2/2 with a = {self.a:.15g} m/s^2"
        )
        return out


# -- 2. a tall block that tips about its downhill edge ------------------------------------


class TippingBlock:
    """A box (``half_extents``, principal ``inertia`` (3,)) at rest flat on the plane, centre
    of mass ``x0``, attitude ``R0``, on Coulomb ``mu`` and ``gravity`` (module docstring,
    item 2). The downhill direction must lie along a body axis of the base.

    ``facts``: ``tips`` (True), ``edge_point`` (3,) P, ``axis`` (3,) u, ``inertia_edge`` I_P,
    ``angle_end`` phi(t_end), ``valid_until`` (s: the edge holds up to there),
    ``min_normal`` (N) and ``max_friction_ratio`` over the asked times."""

    def __init__(self, mass, inertia, half_extents, x0, R0, normal, mu, gravity):
        what = "tipping_block"
        self.m = float(mass)
        self.I = np.asarray(inertia, dtype=float)
        self.half = np.asarray(half_extents, dtype=float)
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.n = _unit(normal, "the plane's normal")
        self.mu = float(mu)
        self.g = np.asarray(gravity, dtype=float)
        k, _ = _face_on_plane(self.R0, self.half, self.n, what)
        gt = self.g - float(self.g @ self.n) * self.n
        if not float(np.linalg.norm(gt)) > GEOMETRY_TOL * float(np.linalg.norm(self.g)):
            raise ReferenceNotApplicable(f"{what}: the plane is level: nothing tips the block")
        d = gt / float(np.linalg.norm(gt))
        along = self.R0.T @ d
        j = int(np.argmax(np.abs(along)))
        if j == k or abs(abs(along[j]) - 1.0) > GEOMETRY_TOL:
            raise ReferenceNotApplicable(
                f"{what}: the downhill direction is not along an edge of the base (body-axis "
                f"cosines {np.round(along, 12).tolist()})"
            )
        w, h = float(self.half[j]), float(self.half[k])
        g_n = -float(self.g @ self.n)
        g_t = float(np.linalg.norm(gt))
        if not g_t * h > g_n * w:
            raise ReferenceNotApplicable(
                f"{what}: tan(th) = {g_t / g_n:.6g} <= w/h = {w / h:.6g}: the block does not tip"
            )
        self.u = np.cross(self.n, d)
        self.P = self.x0 - h * self.n + w * d
        self.r0 = self.x0 - self.P
        Ig = self.R0 @ np.diag(self.I) @ self.R0.T
        self.Ip = float(self.u @ Ig @ self.u) + self.m * float(self.r0 @ self.r0)
        self.d = d

    def _rhs(self, t, y):
        phi, om = y
        r = rot_axis(self.u, phi)[0] @ self.r0
        return [om, float(self.u @ np.cross(r, self.m * self.g)) / self.Ip]

    def _solve(self, t, rtol):
        from scipy.integrate import solve_ivp

        sol = solve_ivp(
            self._rhs,
            (0.0, float(t[-1])),
            [0.0, 0.0],
            method="DOP853",
            t_eval=t,
            rtol=rtol,
            atol=rtol * 1e-6,
            dense_output=False,
        )
        if not sol.success:
            raise ReferenceNotApplicable(f"tipping_block: the integration failed ({sol.message})")
        return sol.y[0], sol.y[1]

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        phi, om = self._solve(t, TIP_RTOL)
        phi2, _ = self._solve(t, TIP_RTOL_CHECK)
        err = float(np.max(np.abs(phi2 - phi))) if len(t) > 1 else 0.0
        Q = rot_axis(self.u, phi)
        r = Q @ self.r0
        x = self.P + r
        w = om[:, None] * self.u
        v = np.cross(w, r)
        R = Q @ self.R0
        W = np.einsum("nji,nj->ni", R, w)
        alpha = np.array([self._rhs(0.0, (p, 0.0))[1] for p in phi])
        aG = alpha[:, None] * np.cross(self.u, r) - (om * om)[:, None] * r
        C = self.m * aG - self.m * self.g
        Cn = C @ self.n
        Ct = np.linalg.norm(C - Cn[:, None] * self.n, axis=1)
        ok = (Cn > 0) & (Ct <= self.mu * Cn)
        if not np.all(ok):
            bad = int(np.argmin(ok))
            why = "lifts off" if Cn[bad] <= 0 else "slips"
            raise ReferenceNotApplicable(
                f"tipping_block: the edge {why} at t = {t[bad]:.6g} s (normal {Cn[bad]:.6g} N, "
                f"friction {Ct[bad]:.6g} N, mu = {self.mu:g}): shorten the horizon"
            )
        out = _stack(t, x, R, v, W)
        out.facts = {
            "tips": True,
            "edge_point": self.P.copy(),
            "axis": self.u.copy(),
            "inertia_edge": self.Ip,
            "angle_end": float(phi[-1]),
            "valid_until": float(t[-1]),
            "min_normal": float(np.min(Cn)),
            "max_friction_ratio": float(np.max(Ct / (self.mu * Cn))),
        }
        out.accuracy = _pivot_accuracy(err, phi, self.r0, self.x0, float(t[-1]))
        out.method = (
            "rotation about the downhill edge, DOP853 at rtol 1e-12 (error: twice the gap to a "
            "run at rtol 1e-10)"
        )
        return out


# -- 3. a sphere or cylinder sliding into rolling -----------------------------------------


class Rolling:
    """A round body (radius ``radius``, ``k`` = I_axis/(m r^2): 2/5 for a solid sphere, 1/2 for
    a solid cylinder) touching the plane at its lowest point, centre ``x0``, attitude ``R0``,
    moving along the in-plane unit vector ``direction`` e at speed ``v0`` and spinning about
    a = n x e at ``w0`` (rad/s); Coulomb ``mu``, ``gravity`` (module docstring, item 3).

    ``facts``: ``t_roll`` (s: the slip ends; 0 if it rolls from the start, inf if never),
    ``v_roll`` (m/s: the speed then; NaN if never), ``rolls`` (rolling can hold),
    ``slip0`` u(0), ``energy_lost`` (J, by friction up to t_roll; NaN if never)."""

    def __init__(self, mass, radius, k, x0, R0, normal, direction, v0, w0, mu, gravity):
        self.m, self.r, self.k = float(mass), float(radius), float(k)
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.n = _unit(normal, "the plane's normal")
        e = np.asarray(direction, dtype=float)
        if abs(float(e @ self.n)) > GEOMETRY_TOL * float(np.linalg.norm(e)):
            raise ReferenceNotApplicable("rolling: the direction of motion leaves the plane")
        self.e = _unit(e, "the direction of motion")
        self.a = np.cross(self.n, self.e)
        self.v0, self.w0, self.mu = float(v0), float(w0), float(mu)
        g = np.asarray(gravity, dtype=float)
        self.gn = -float(g @ self.n)
        self.gt = float(g @ self.e)
        side = g - float(g @ self.n) * self.n - self.gt * self.e
        if float(np.linalg.norm(side)) > GEOMETRY_TOL * float(np.linalg.norm(g)):
            raise ReferenceNotApplicable("rolling: gravity pulls across the direction of motion")
        if not self.gn > 0:
            raise ReferenceNotApplicable("rolling: gravity does not press the body on the plane")
        self.can_roll = self.mu * self.gn * (1.0 + self.k) >= self.k * abs(self.gt)
        u0 = self.v0 - self.r * self.w0
        self.u0 = u0
        # phases: (t_start, v, rw, slide sign s (0: rolling)) with v' = gt - mu gn s,
        # rw' = mu gn s / k while sliding, v' = rw' = gt/(1+k) rolling
        if u0 == 0.0:
            s0 = 0 if self.can_roll else (1 if self.gt > 0 else -1 if self.gt < 0 else 0)
        else:
            s0 = 1 if u0 > 0 else -1
        self.phases = [(0.0, self.v0, self.r * self.w0, s0)]
        self.t_roll = 0.0 if s0 == 0 else math.inf
        if s0 != 0:
            du = self.gt - self.mu * self.gn * s0 - self.mu * self.gn * s0 / self.k  # u'
            if du * s0 < 0:  # the slip decreases in size: it ends at t1
                t1 = -u0 / du
                v1 = self.v0 + (self.gt - self.mu * self.gn * s0) * t1
                rw1 = self.r * self.w0 + self.mu * self.gn * s0 / self.k * t1
                if self.can_roll:
                    s1 = 0
                else:  # the slip reverses: friction cannot hold it
                    s1 = 1 if self.gt > 0 else -1
                self.phases.append((t1, v1, rw1, s1))
                self.t_roll = t1 if s1 == 0 else math.inf
        self.v_roll = math.nan
        if math.isfinite(self.t_roll):
            self.v_roll = self.phases[-1][1]

    def _accel(self, s):
        if s == 0:
            a = self.gt / (1.0 + self.k)
            return a, a
        return self.gt - self.mu * self.gn * s, self.mu * self.gn * s / self.k

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        s = np.zeros_like(t)
        v = np.zeros_like(t)
        th = np.zeros_like(t)  # angle turned about a
        rw = np.zeros_like(t)
        s_acc = th_acc = 0.0
        for i, (t0, v0, rw0, sg) in enumerate(self.phases):
            t1 = self.phases[i + 1][0] if i + 1 < len(self.phases) else math.inf
            av, arw = self._accel(sg)
            sel = (t >= t0) & (t < t1)
            tau = t[sel] - t0
            s[sel] = s_acc + v0 * tau + 0.5 * av * tau * tau
            v[sel] = v0 + av * tau
            rw[sel] = rw0 + arw * tau
            th[sel] = th_acc + (rw0 * tau + 0.5 * arw * tau * tau) / self.r
            if math.isfinite(t1):
                dt1 = t1 - t0
                s_acc += v0 * dt1 + 0.5 * av * dt1 * dt1
                th_acc += (rw0 * dt1 + 0.5 * arw * dt1 * dt1) / self.r
        x = self.x0 + s[:, None] * self.e
        vel = v[:, None] * self.e
        Q = rot_axis(self.a, th)
        R = Q @ self.R0
        w = (rw / self.r)[:, None] * self.a
        W = np.einsum("nji,nj->ni", R, w)
        out = _stack(t, x, R, vel, W)
        I = self.k * self.m * self.r * self.r
        lost = math.nan
        if math.isfinite(self.t_roll) and self.gt == 0.0:
            lost = 0.5 * self.m * (self.v0**2 - self.v_roll**2) + 0.5 * I * (
                self.w0**2 - (self.v_roll / self.r) ** 2
            )
        out.facts = {
            "t_roll": float(self.t_roll),
            "v_roll": float(self.v_roll),
            "rolls": bool(self.can_roll),
            "slip0": float(self.u0),
            "energy_lost": float(lost),
            "distance": float(s[-1]),
        }
        size = float(np.linalg.norm(self.x0)) + float(np.max(np.abs(s)))
        turned = float(np.max(np.abs(th)))
        out.accuracy = {
            "position": 16 * EPS * size,
            "attitude": 16 * EPS * (1.0 + turned),
            "velocity": 16 * EPS * (abs(self.v0) + float(np.max(np.abs(v)))),
        }
        out.method = "closed form: sliding phase then rolling (piecewise uniform acceleration)"
        return out


# -- 4. a drop and its bounces --------------------------------------------------------------


class Bounce:
    """A body dropped with its lowest point ``z0`` above the plane (unit ``normal``), centre of
    mass ``x0``, attitude ``R0``, velocity ``w0`` along n, body rates ``W0`` (kept), Newton
    restitution ``e`` and ``gravity`` along -n (module docstring, item 4).

    ``facts``: ``impact_times`` (s), ``rebound_heights`` (m: the lowest point's greatest height
    after each impact, e^(2j) V1^2/(2g)), ``impact_speed`` V1, ``rest_time`` t_inf (s)."""

    #: impacts listed in ``facts`` (the heights shrink by e^2 each)
    MAX_IMPACTS = 12

    def __init__(self, z0, x0, R0, normal, e, gravity, w0=0.0, W0=(0.0, 0.0, 0.0)):
        self.n = _unit(normal, "the plane's normal")
        g = np.asarray(gravity, dtype=float)
        self.g = -float(g @ self.n)
        if float(np.linalg.norm(g + self.g * self.n)) > GEOMETRY_TOL * float(np.linalg.norm(g)):
            raise ReferenceNotApplicable("bounce: gravity is not along the plane's normal")
        if not self.g > 0:
            raise ReferenceNotApplicable("bounce: gravity does not pull the body to the plane")
        self.z0, self.e, self.w0 = float(z0), float(e), float(w0)
        if self.z0 < 0:
            raise ReferenceNotApplicable(f"bounce: starts below the plane (z0 = {self.z0:g} m)")
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.W0 = np.asarray(W0, dtype=float)
        self.V1 = math.sqrt(self.w0 * self.w0 + 2.0 * self.g * self.z0)
        self.t1 = (self.w0 + self.V1) / self.g
        if self.e >= 1.0:
            raise ReferenceNotApplicable("bounce: e = 1 never comes to rest (no closed form here)")
        self.t_inf = self.t1 + 2.0 * self.e * self.V1 / (self.g * (1.0 - self.e))

    def _flight_start(self, j):
        """T_j, the start of the flight after impact j (j >= 1)."""
        return self.t1 + 2.0 * self.V1 * self.e * (1.0 - self.e ** (j - 1)) / (
            self.g * (1.0 - self.e)
        )

    def heights(self, t) -> tuple[np.ndarray, np.ndarray]:
        """(height of the lowest point above the plane, its velocity along n) at ``t``."""
        t = _times(t)
        z = np.zeros_like(t)
        w = np.zeros_like(t)
        first = t < self.t1
        z[first] = self.z0 + self.w0 * t[first] - 0.5 * self.g * t[first] ** 2
        w[first] = self.w0 - self.g * t[first]
        if self.e > 0:
            rest = (t >= self.t1) & (t < self.t_inf)
            # the j-th flight (j >= 1) starts at T_j = t1 + 2 V1 e (1 - e^(j-1))/(g (1 - e))
            tau = t[rest] - self.t1
            q = 1.0 - tau * self.g * (1.0 - self.e) / (2.0 * self.e * self.V1)
            j = np.floor(1.0 + np.log(np.maximum(q, 1e-300)) / math.log(self.e))
            j = np.maximum(j, 1.0)
            for _ in range(2):  # rounding at a flight's boundary: move to the right flight
                start = self._flight_start(j)
                j = j - (start > t[rest]) + (t[rest] >= self._flight_start(j + 1))
                j = np.maximum(j, 1.0)
            start = self._flight_start(j)
            vj = self.V1 * self.e**j
            s = t[rest] - start
            z[rest] = np.maximum(vj * s - 0.5 * self.g * s * s, 0.0)
            w[rest] = vj - self.g * s
        return z, w

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        z, w = self.heights(t)
        x = self.x0 + (z - self.z0)[:, None] * self.n
        v = w[:, None] * self.n
        W = np.broadcast_to(self.W0, (len(t), 3)).copy()
        wv = self.R0 @ self.W0
        wn = float(np.linalg.norm(wv))
        if wn > 0:
            R = rot_axis(wv / wn, wn * t) @ self.R0
        else:
            R = np.broadcast_to(self.R0, (len(t), 3, 3)).copy()
        out = _stack(t, x, R, v, W)
        times, heights = [self.t1], []
        for j in range(1, self.MAX_IMPACTS + 1):
            vj = self.V1 * self.e**j
            heights.append(vj * vj / (2.0 * self.g))
            if self.e == 0:
                break
            times.append(times[-1] + 2.0 * vj / self.g)
        out.facts = {
            "impact_times": [float(x) for x in times],
            "rebound_heights": [float(h) for h in heights],
            "impact_speed": float(self.V1),
            "rest_time": float(self.t_inf),
            "drop_height": float(self.V1 * self.V1 / (2.0 * self.g)),
        }
        out.accuracy = {
            "position": 16 * EPS * (float(np.linalg.norm(self.x0)) + self.z0),
            "attitude": 16 * EPS * (1.0 + wn * float(t[-1])),
            "velocity": 16 * EPS * self.V1,
        }
        out.method = "closed form: parabolic flights, rebound speed e v at each impact"
        return out


# -- 5. bodies at rest ------------------------------------------------------------------------


class Resting:
    """Bodies at rest (``x0`` (nb, 3), ``R0`` (nb, 3, 3)) with masses ``masses``, each carried
    by the support ``supports[i]`` (the index of the body below it, or -1 for a plane),
    ``gravity`` (module docstring, item 5).

    ``facts``: ``sticks`` (True), ``support_forces`` (nb,) N: the force through body i's
    support, |g| times the mass of i and of everything above it."""

    def __init__(self, masses, x0, R0, supports, gravity):
        self.m = np.asarray(masses, dtype=float)
        self.x0 = np.asarray(x0, dtype=float)
        self.R0 = np.asarray(R0, dtype=float)
        self.sup = [int(s) for s in supports]
        nb = len(self.m)
        for i, s in enumerate(self.sup):
            if not -1 <= s < nb or s == i:
                raise ReferenceNotApplicable(f"resting: body {i}'s support {s} is not a body")
        carried = self.m.copy()
        order = self._top_down()
        for i in order:
            if self.sup[i] >= 0:
                carried[self.sup[i]] += carried[i]
        self.load = float(np.linalg.norm(gravity)) * carried

    def _top_down(self) -> list[int]:
        """Bodies ordered so that each comes before its support (refused if they form a cycle)."""
        nb = len(self.m)
        depth = [0] * nb
        for i in range(nb):
            j, steps = i, 0
            while self.sup[j] >= 0:
                j = self.sup[j]
                steps += 1
                if steps > nb:
                    raise ReferenceNotApplicable("resting: the supports form a cycle")
            depth[i] = steps
        return sorted(range(nb), key=lambda i: -depth[i])

    def motion(self, t) -> ContactMotion:
        t = _times(t)
        n, nb = len(t), len(self.m)
        out = ContactMotion(
            t,
            np.broadcast_to(self.x0, (n, nb, 3)).copy(),
            np.broadcast_to(self.R0, (n, nb, 3, 3)).copy(),
            np.zeros((n, nb, 3)),
            np.zeros((n, nb, 3)),
        )
        out.facts = {"sticks": True, "support_forces": self.load.copy()}
        out.accuracy = {
            "position": 16 * EPS * float(np.max(np.linalg.norm(self.x0, axis=1))),
            "attitude": 16 * EPS,
            "velocity": 0.0,
        }
        out.method = "closed form: static equilibrium (motion 0)"
        return out
