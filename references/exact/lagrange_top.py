"""The Lagrange top (symmetric heavy top on a fixed point of its symmetry axis): nutation by
the cubic f(u) and Jacobi functions, precession and spin by quadrature, and the closed-form
steady precession.

Notation (numerics.md section 4): k is the body symmetry axis, "up" = -g/|g|, u = cos(theta) =
up . d_k the cosine of the tilt of the symmetry axis, A the transverse moment about the pivot,
C the axial moment, l the signed distance pivot -> centre of mass along d_k (l > 0: the centre
of mass above the pivot when the axis is up), a = L_up/A, b = L . d_k/A = C W_k/A,
beta = 2 m |g| l/A, alpha = (2E - C W_k^2)/A. Then

    u'^2 = f(u) = (1 - u^2)(alpha - beta u) - (a - b u)^2 = beta (u - u1)(u - u2)(u - u3).

The cubic is solved in delta = u - u0 (u0 the initial value), where its coefficients follow
from the initial state without cancellation:

    f = (N - 2 u0 delta - delta^2)(w2 - beta delta) - (p - b delta)^2,
    N = 1 - u0^2 = |n_perp|^2,  w2 = |W_perp|^2,  p = W_perp . n_perp,  f(0) = (W_perp x n_perp)^2,

with n = R^T up in body axes (N is a sum of squares, not 1 - u0^2). The roots of the expanded
cubic are polished by Newton on the unexpanded f (numerics.md: the expanded cubic in u loses
~5 digits for fast tops); when f(0) = 0 (the top starts at a turning point, as in Simo-Wong)
delta = 0 is an exact root and the quadratic factor is solved by the stable formula.

Motion between the two roots of [-1, 1]: u = u_far + (u_near - u_far) sn^2(tau), with u_far
the turning point farther from u3, tau' = sqrt(|beta| |u3 - u_far|)/2,
m = |u_near - u_far|/|u3 - u_far|; nutation period T = 4 K(m)/sqrt(|beta| |u3 - u_far|).
Euler angles about up (z-x-z, as for the free body): phi' = (a - b u)/(1 - u^2),
psi' = W_k - u phi', integrated by the periodic quadrature of :mod:`references.exact._util`;
R = F Rz(phi) Rx(theta) Rz(psi) C^T.

Steady precession (double root u1 = u2 = u0, checked to a relative residual of 1e-12 of the
torque balance m g l = phi' (C W_k - A phi' cos theta)): the closed form
R(t) = Rot(up, w_p t) R_0 Rot(e_k, w_s t), W(t) = w_p R(t)^T up + w_s e_k, with
w_p = phi', w_s = psi' (numerics.md section 7).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ellipkinc, ellipkm1

from references.exact._util import EPS, Antiderivative, jacobi, rot_axis, rot_x, rot_z

#: Relative residual of the steady-precession condition (torque balance) accepted as steady.
STEADY_RTOL = 1e-12


class NotALagrangeTop(ValueError):
    """The scenario is not a symmetric heavy top pivoted on its symmetry axis."""


class LagrangeTop:
    """The exact motion of a Lagrange top given by a pivoted scenario.

    Attributes: ``axis`` (body symmetry axis k), ``roots`` (u1 <= u2 the turning points,
    u3 the third root), ``nutation_period`` (s; None for a steady precession), ``dphi``,
    ``dpsi`` (increments of the precession and spin angles over one nutation period),
    ``precession_rate`` (mean phi', rad/s), ``steady`` (True for a steady precession, then
    ``w_p``, ``w_s`` are its rates), ``tilt_range`` (min, max tilt of d_k from up, rad),
    ``residual`` (relative residual of the steady-precession condition), ``cond`` (conditioning
    of the Euler angles, large when a turning point comes close to the vertical).
    """

    def __init__(self, scenario):
        self.scenario = scenario
        sc = scenario
        if sc.pivot is None:
            raise NotALagrangeTop("not pivoted: a Lagrange top turns about a fixed point")
        g = np.asarray(sc.gravity, dtype=float)
        gn = float(np.linalg.norm(g))
        if gn == 0.0:
            raise NotALagrangeTop("no gravity: the motion is torque-free (use free_body)")
        k = sc.symmetric_axis
        I = np.asarray(sc.inertia, dtype=float)
        if k is None and I[0] == I[1] == I[2]:
            nz = np.flatnonzero(sc.pivot)
            k = int(nz[0]) if len(nz) == 1 else None
        if k is None:
            raise NotALagrangeTop(f"the body is not symmetric (inertia {I.tolist()})")
        c = np.asarray(sc.pivot, dtype=float)
        i, j = (k + 1) % 3, (k + 2) % 3
        if c[i] != 0.0 or c[j] != 0.0:
            raise NotALagrangeTop(
                f"the pivot {c.tolist()} is not on the symmetry axis (body axis {k + 1})"
            )
        if c[k] == 0.0:
            raise NotALagrangeTop("the pivot is at the centre of mass: no gravity torque")
        self.axis = k
        self.up = -g / gn
        m = sc.mass
        l = -float(c[k])  # centre of mass relative to the pivot: -c = l e_k
        A = float(I[i]) + m * l * l
        Cm = float(I[k])
        self.A, self.C, self.l = A, Cm, l
        self._Cb = np.eye(3)[:, [i, j, k]]  # relabelled body axes (cyclic: right-handed)
        R0 = np.asarray(sc.rotation, dtype=float)
        W0 = np.asarray(sc.omega_body, dtype=float)
        n = self._Cb.T @ (R0.T @ self.up)
        Wr = self._Cb.T @ W0
        self.omega3 = float(Wr[2])
        u0 = float(n[2])
        N = float(n[0] ** 2 + n[1] ** 2)
        w2 = float(Wr[0] ** 2 + Wr[1] ** 2)
        p = float(Wr[0] * n[0] + Wr[1] * n[1])
        q = float(Wr[0] * n[1] - Wr[1] * n[0])  # f(u0) = q^2 = u'(0)^2
        b = Cm * self.omega3 / A
        beta = 2.0 * m * gn * l / A
        self.beta, self.b = beta, b
        self.a = p + b * u0
        self.alpha = w2 + beta * u0
        self.u0 = u0
        if N == 0.0:
            raise NotALagrangeTop(
                "the symmetry axis starts vertical (sleeping top): Euler angles about the "
                "vertical are singular; use the numerical reference"
            )

        def f(d):
            return (N - 2.0 * u0 * d - d * d) * (w2 - beta * d) - (p - b * d) ** 2

        def fp(d):
            return (
                -2.0 * (u0 + d) * (w2 - beta * d)
                - beta * (N - 2.0 * u0 * d - d * d)
                + 2.0 * b * (p - b * d)
            )

        c3, c2, c1, c0 = (
            beta,
            2 * u0 * beta - w2 - b * b,
            -beta * N - 2 * u0 * w2 + 2 * p * b,
            q * q,
        )
        scale1 = abs(beta) * N + 2 * abs(u0) * w2 + 2 * abs(p * b)
        self.residual = abs(c1) / scale1 if scale1 > 0 else 0.0
        if q == 0.0:
            # delta = 0 is a root; the quadratic factor c3 d^2 + c2 d + c1 by the stable formula
            disc = c2 * c2 - 4.0 * c3 * c1
            if disc < 0:
                raise NotALagrangeTop(f"no real turning points (discriminant {disc!r})")
            sq = math.sqrt(disc)
            qq = -0.5 * (c2 + math.copysign(sq, c2))
            others = [qq / c3, c1 / qq if qq != 0 else 0.0]
            deltas = sorted([0.0, *others])
        else:
            rr = np.roots([c3, c2, c1, c0])
            deltas = sorted(float(r.real) for r in rr)
            polished = []
            for d in deltas:
                for _ in range(8):
                    fd = fp(d)
                    if fd == 0:
                        break
                    step = f(d) / fd
                    d -= step
                    if abs(step) <= 4 * EPS * max(abs(d), 1e-300):
                        break
                polished.append(d)
            deltas = sorted(polished)
        # the turning points straddle delta = 0; the third root lies beyond |u| = 1
        if beta > 0:
            d1, d2, d3 = deltas
        else:
            d3, d1, d2 = deltas
        d1, d2 = min(d1, 0.0), max(d2, 0.0)
        self.roots = (u0 + d1, u0 + d2, u0 + d3)
        self._deltas = (d1, d2, d3)
        # tilt = atan2(sin, cos) with sin^2 = N - 2 u0 d - d^2 (accurate near u = 1, where acos
        # loses digits)
        self.tilt_range = tuple(
            math.atan2(math.sqrt(max(N - 2.0 * u0 * d - d * d, 0.0)), u0 + d) for d in (d2, d1)
        )
        self._N, self._p = N, p
        span = d2 - d1
        self.steady = q * q <= (STEADY_RTOL * math.sqrt(w2 + 1e-300)) ** 2 and (
            self.residual <= STEADY_RTOL
        )
        if self.steady:
            self.w_p = p / N
            self.w_s = self.omega3 - u0 * self.w_p
            self.precession_rate = self.w_p
            th0 = math.atan2(math.sqrt(N), u0)
            self.roots = (u0, u0, u0 + d3)
            self.tilt_range = (th0, th0)
            self.nutation_period = None
            self.dphi = self.dpsi = math.nan
            self.quadrature_error = 0.0
            return
        # nutation: u = u_far + (u_near - u_far) sn^2(tau)
        if beta > 0:
            dfar, dnear = d1, d2
        else:
            dfar, dnear = d2, d1
        self._dfar, self._dspan = dfar, dnear - dfar
        self.m1 = abs(d3 - dnear) / abs(d3 - dfar)
        self.k2 = span / abs(d3 - dfar)
        self.K = float(ellipkm1(self.m1))
        self.taudot = 0.5 * math.sqrt(abs(beta) * abs(d3 - dfar))
        self.nutation_period = 2.0 * self.K / self.taudot
        ratio = min(1.0, max(0.0, -dfar / (dnear - dfar)))
        tau0 = float(ellipkinc(math.asin(math.sqrt(ratio)), self.k2))
        udot0 = -q  # u'(0) = W . (e_k x n) = -(W_i n_j - W_j n_i)
        if udot0 * (dnear - dfar) < 0:
            tau0 = -tau0
        self.tau0 = tau0
        K, m, m1 = self.K, self.k2, self.m1
        td = self.taudot

        def delta_of_tau(tau):
            sn, _, _ = jacobi(tau, m, m1, K)
            return dfar + (dnear - dfar) * sn * sn

        def phidot(tau):
            d = delta_of_tau(tau)
            return (p - b * d) / (N - 2.0 * u0 * d - d * d)

        def uphidot(tau):
            d = delta_of_tau(tau)
            return (u0 + d) * (p - b * d) / (N - 2.0 * u0 * d - d * d)

        self._delta = delta_of_tau
        self._Gphi = Antiderivative(phidot, 2.0 * K, 1.0)
        self._Gu = Antiderivative(uphidot, 2.0 * K, 1.0)
        self._Gphi0 = float(self._Gphi(np.array([tau0]))[0])
        self._Gu0 = float(self._Gu(np.array([tau0]))[0])
        self.dphi = self._Gphi.total / td
        self.dpsi = self.omega3 * self.nutation_period - self._Gu.total / td
        self.precession_rate = self.dphi / self.nutation_period
        self.quadrature_error = (self._Gphi.error + self._Gu.error) / td
        # conditioning of the Euler angles about up: near a turning point close to u = +-1,
        # 1 - u^2 = (1 -+ u0 -+ delta)(...) is a difference of O(|delta|) numbers, relative
        # error ~ eps |delta|/(1 - |u|), and phi, psi swing fast there
        self.cond = max(1.0 + abs(d) / max(1.0 - abs(u0 + d), 1e-300) for d in (d1, d2))
        # Euler frame F with phi(0) = 0 (third column up)
        th0 = math.atan2(math.sqrt(N), u0)
        psi0 = math.atan2(n[0], n[1])
        self._psi0 = psi0
        self._F = R0 @ self._Cb @ rot_z(psi0)[0].T @ rot_x(th0)[0].T

    # -- evaluation ----------------------------------------------------------------------
    def u(self, t) -> np.ndarray:
        """cos(tilt) of the symmetry axis, u(t) = up . d_k."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.steady:
            return np.full(len(t), self.u0)
        return self.u0 + self._delta(self.tau0 + self.taudot * t)

    def rotation_and_omega(self, t) -> tuple[np.ndarray, np.ndarray]:
        """R(t) (n, 3, 3) and W(t) (n, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sc = self.scenario
        R0 = np.asarray(sc.rotation, dtype=float)
        ek = np.eye(3)[self.axis]
        if self.steady:
            R = rot_axis(self.up, self.w_p * t) @ R0 @ rot_axis(ek, self.w_s * t)
            W = self.w_p * np.einsum("nji,j->ni", R, self.up) + self.w_s * ek
            return R, W
        tau = self.tau0 + self.taudot * t
        d = self._delta(tau)
        u0, N, p, b = self.u0, self._N, self._p, self.b
        s2 = N - 2.0 * u0 * d - d * d  # sin^2 theta
        sth = np.sqrt(s2)
        th = np.arctan2(sth, u0 + d)
        phi = (self._Gphi(tau) - self._Gphi0) / self.taudot
        psi = self._psi0 + self.omega3 * t - (self._Gu(tau) - self._Gu0) / self.taudot
        R = self._F @ rot_z(phi) @ rot_x(th) @ rot_z(psi) @ self._Cb.T
        # body rates from the Euler-angle rates: theta' = -u'/sin(theta)
        sn, cn, dn = jacobi(tau, self.k2, self.m1, self.K)
        udot = 2.0 * self._dspan * sn * cn * dn * self.taudot
        phid = (p - b * d) / s2
        thd = -udot / sth
        Wr = np.stack(
            [
                phid * sth * np.sin(psi) + thd * np.cos(psi),
                phid * sth * np.cos(psi) - thd * np.sin(psi),
                np.full(len(t), self.omega3),
            ],
            axis=1,
        )
        return R, Wr @ self._Cb.T

    def accuracy(self, t) -> float:
        """Estimated maximum attitude error (rad) over the times ``t`` (see
        :meth:`references.exact.free_body.FreeBody.accuracy`)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tmax = float(np.max(np.abs(t))) if len(t) else 0.0
        _, W = self.rotation_and_omega(np.linspace(0.0, tmax, 65))
        err = 16.0 * EPS * (1.0 + float(np.max(np.linalg.norm(W, axis=1))) * tmax)
        if not self.steady:
            periods = 1.0 + tmax / self.nutation_period
            err += self.quadrature_error * periods
            # each passage of a turning point near the vertical turns phi and psi by up to
            # 2 pi with relative error ~ eps * cond (measured on random tops: covers the
            # actual error with a margin of 10 .. 100 where cond is large)
            err += 8.0 * EPS * self.cond * 2.0 * math.pi * periods
        return err
