"""Exact torque-free motion of a rigid body: body rates by Jacobi elliptic functions and the
attitude by Euler angles aligned with the (constant) angular momentum.

Notation (docs/numerics.md section 4): principal moments I, body rates W, 2E = sum I_i W_i^2,
L^2 = sum (I_i W_i)^2. The solution is computed in a relabelled body frame (a, b, c), where c
is the axis the angular momentum circulates around (the largest moment in case A,
L^2 > 2 E I_mid; the smallest in case B, L^2 < 2 E I_mid), b the intermediate axis and a the
other. The relabelling is a permutation of the axes; when it is odd the relabelled axes are
all negated so that the frame stays right-handed (an odd permutation alone would flip the
sign of W in Euler's equations). In that frame, with u = lambda t + u0 and parameter m = k^2,

    W_a = sa A_a cn(u | m),  W_b = sb A_b sn(u | m),  W_c = sc A_c dn(u | m),

    A_a^2 = P/(I_a |I_c - I_a|),  A_b^2 = P/(I_b |I_c - I_b|),  A_c^2 = Q/(I_c |I_c - I_a|),
    lambda^2 = |I_c - I_b| Q/(I_a I_b I_c),  m = |I_b - I_a| P/(|I_c - I_b| Q),
    1 - m = |I_c - I_a| S/(|I_c - I_b| Q),

with the cancellation-free forms (exact identities, docs/numerics.md section 4)

    P = |2E I_c - L^2| = I_a |I_c - I_a| W_a^2 + I_b |I_c - I_b| W_b^2,
    Q = |L^2 - 2E I_a| = I_b |I_b - I_a| W_b^2 + I_c |I_c - I_a| W_c^2,
    S = |L^2 - 2E I_b| = I_c |I_c - I_b| W_c^2 - I_a |I_a - I_b| W_a^2   (the separatrix distance),

and K(m) from ``ellipkm1(1 - m)``, so that nothing is lost near the separatrix. Period of W:
T = 4K/lambda; W_b changes sign every T/2 (the flip interval). On the separatrix (S = 0) the
hyperbolic limit sn = tanh, cn = dn = sech is used.

Attitude: R = R_L Rz(phi) Rx(theta) Rz(psi) (relabelled frame), with the z axis of R_L along L.
I W = |L| (sin th sin psi, sin th cos psi, cos th) gives theta and psi algebraically;
phi' = |L| (I_a W_a^2 + I_b W_b^2)/((I_a W_a)^2 + (I_b W_b)^2) is periodic with period 2K in u
and is integrated by :class:`references.exact._util.Antiderivative` (spectrally accurate
trapezoid over a period + composite Gauss-Legendre). After one period R(T) = Rot(L, dphi) R_0.

Symmetric bodies (two equal moments, including the sphere) use the closed form
R(t) = Rot(L, |L| t/I_perp) R_0 Rot(e_c, psi' t), psi' = W_c (I_perp - I_c)/I_perp, and a spin
about a principal axis (at most one non-zero W_i) is R(t) = R_0 Rot(e_i, W_i t).

References: Celledoni, Fasso, Safstrom, Zanna, SIAM J. Sci. Comput. 30 (2008); van Zon and
Schofield, J. Comput. Phys. 225 (2007); Landau and Lifshitz, Mechanics, section 37.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ellipkm1

from references.exact._util import (
    EPS,
    Antiderivative,
    jacobi,
    jacobi_inverse,
    rot_axis,
    rot_x,
    rot_z,
    rotation_angle,
)

_PARITY = {(0, 1, 2): 1, (1, 2, 0): 1, (2, 0, 1): 1, (0, 2, 1): -1, (2, 1, 0): -1, (1, 0, 2): -1}


class FreeBody:
    """The exact motion of a torque-free rigid body.

    Parameters: ``inertia`` (3,) principal moments (any order, > 0), ``omega0`` (3,) body rates
    at t = 0, ``rotation0`` (3, 3) body-to-world rotation at t = 0.

    Attributes: ``case`` ("A", "B", "separatrix", "symmetric", "spherical", "principal spin"),
    ``energy`` (rotational, 1/2 W.I W), ``L`` (|L|), ``period`` (period of W, s; inf if W is
    constant or never repeats), ``flip_interval`` (time between sign changes of the
    intermediate-axis rate, T/2; None unless asymmetric and periodic), ``phi_per_period``
    (increment of the precession angle about L over one period T), ``k2``, ``m1`` (= 1 - k^2),
    ``K``, ``lam``, ``dominant_axis`` (index of the body axis with the largest mean |W_i|),
    ``intermediate_axis`` (index of the intermediate moment, None if two are equal).
    """

    def __init__(self, inertia, omega0, rotation0, _s_factor: float = 1.0):
        # _s_factor scales the separatrix distance S (a probe of the conditioning, see
        # :meth:`accuracy`); 1 for the body itself
        self._s_factor = float(_s_factor)
        I = np.array(inertia, dtype=float)
        W0 = np.array(omega0, dtype=float)
        R0 = np.array(rotation0, dtype=float)
        if I.shape != (3,) or W0.shape != (3,) or R0.shape != (3, 3):
            raise ValueError("FreeBody needs inertia (3,), omega0 (3,) and rotation0 (3, 3)")
        if np.any(I <= 0) or not np.all(np.isfinite(np.concatenate([I, W0, R0.ravel()]))):
            raise ValueError(f"FreeBody: moments must be > 0 and data finite (I = {I.tolist()})")
        self.inertia, self.omega0, self.rotation0 = I, W0, R0
        self.energy = 0.5 * float(np.sum(I * W0 * W0))
        self.L = float(np.linalg.norm(I * W0))
        self.k2 = self.m1 = self.K = self.lam = math.nan
        self.flip_interval = None
        self.phi_per_period = math.nan
        self.quadrature_error = 0.0
        order = np.argsort(I, kind="stable")
        distinct = I[order[0]] < I[order[1]] < I[order[2]]
        self.intermediate_axis = int(order[1]) if distinct else None
        if np.count_nonzero(W0) <= 1:
            self.case = "principal spin"
            i = int(np.argmax(np.abs(W0)))
            self._spin_axis, self._spin_rate = np.eye(3)[i], float(W0[i])
            self.period = math.inf
            self.dominant_axis = i
        elif not distinct:
            self._init_symmetric(I, W0, order)
        else:
            self._init_asymmetric(I, W0, R0, order)

    # -- symmetric and spherical bodies --------------------------------------------------
    def _init_symmetric(self, I, W0, order):
        if I[order[0]] == I[order[2]]:
            self.case = "spherical"
            c = 2
        else:
            self.case = "symmetric"
            c = int(order[2]) if I[order[0]] == I[order[1]] else int(order[0])
        i_perp = float(I[(c + 1) % 3])
        self._c = c
        self._ec = np.eye(3)[c]
        self._psidot = float(W0[c]) * (i_perp - float(I[c])) / i_perp
        self._i_perp = i_perp
        self.period = 2.0 * math.pi / abs(self._psidot) if self._psidot != 0 else math.inf
        # mean |W_i|: the transverse part rotates with constant magnitude
        w_perp = math.hypot(*[W0[j] for j in range(3) if j != c])
        self.dominant_axis = c if abs(W0[c]) >= (2 / math.pi) * w_perp else (c + 1) % 3

    # -- asymmetric bodies ---------------------------------------------------------------
    def _init_asymmetric(self, I, W0, R0, order):
        lo, mid, hi = (int(i) for i in order)
        D = separatrix_distance(I, W0) * self._s_factor
        if D >= 0:
            perm, self.case = (lo, mid, hi), ("A" if D > 0 else "separatrix")
        else:
            perm, self.case = (hi, mid, lo), "B"
        sigma = _PARITY[perm]
        B = np.zeros((3, 3))
        for j, pj in enumerate(perm):
            B[pj, j] = sigma  # columns: the relabelled axes sigma * e_perm[j]
        self._B = B
        Ir = I[list(perm)]
        Wr = B.T @ W0
        Ia, Ib, Ic = Ir
        Wa, Wb, Wc = Wr
        dca, dcb, dba = abs(Ic - Ia), abs(Ic - Ib), abs(Ib - Ia)
        P = Ia * dca * Wa**2 + Ib * dcb * Wb**2
        Q = Ib * dba * Wb**2 + Ic * dca * Wc**2
        S = abs(D)
        self.k2 = dba * P / (dcb * Q)
        self.m1 = dca * S / (dcb * Q)
        self.lam = math.sqrt(dcb * Q / (Ia * Ib * Ic))
        Aa, Ab, Ac = (
            math.sqrt(P / (Ia * dca)),
            math.sqrt(P / (Ib * dcb)),
            math.sqrt(Q / (Ic * dca)),
        )
        s_ord = 1.0 if Ic > Ia else -1.0
        sc = 1.0 if Wc > 0 else -1.0  # W_c never vanishes off a principal spin
        sa = 1.0 if Wa >= 0 else -1.0
        sb = s_ord * sa * sc  # from Euler's equations (sn' = cn dn, ...)
        self._amp = np.array([sa * Aa, sb * Ab, sc * Ac])
        if self.case == "separatrix":
            self.K = math.inf
            self.period = math.inf
        else:
            self.K = float(ellipkm1(self.m1))
            self.period = 4.0 * self.K / self.lam
            self.flip_interval = 2.0 * self.K / self.lam
        self._u0 = jacobi_inverse(Wb / (sb * Ab), Wa / (sa * Aa), self.k2, self.m1, self.K)
        self._Ir = Ir
        # dominant axis: largest mean |W_i| over a period (integrals of |cn|, |sn|, dn)
        if self.case == "separatrix":
            self.dominant_axis = perm[1]
        else:
            k = math.sqrt(self.k2)
            kp = math.sqrt(self.m1)
            if k > 0:
                mcn = math.atan2(k, kp) / k
                msn = (math.log1p(k) - 0.5 * math.log(self.m1)) / k  # atanh(k)/k
            else:
                mcn = msn = 1.0
            means = [Aa * mcn, Ab * msn, Ac * 0.5 * math.pi]
            self.dominant_axis = perm[int(np.argmax(means))]
        # Euler angles about L and the phi' antiderivative
        Pi0 = Ir * Wr
        th0 = math.atan2(math.hypot(Pi0[0], Pi0[1]), Pi0[2])
        psi0 = math.atan2(Pi0[0], Pi0[1])
        Rr0 = R0 @ B
        self._RL = Rr0 @ rot_z(psi0)[0].T @ rot_x(th0)[0].T
        L = self.L
        m, m1, K = self.k2, self.m1, self.K
        A2a, A2b = Aa * Aa, Ab * Ab

        def phidot(u):
            sn, cn, _ = jacobi(u, m, m1, K)
            wa2, wb2 = A2a * cn * cn, A2b * sn * sn
            return L * (Ia * wa2 + Ib * wb2) / (Ia * Ia * wa2 + Ib * Ib * wb2)

        self._phidot = phidot
        self._G = Antiderivative(phidot, None if self.case == "separatrix" else 2.0 * K, 1.0)
        self._G0 = float(self._G(np.array([self._u0]))[0])
        if self.case != "separatrix":
            self.phi_per_period = 2.0 * self._G.total / self.lam
            self.quadrature_error = self._G.error / self.lam
        self._probe = None  # the body with S perturbed, built when accuracy() first needs it

    # -- evaluation ----------------------------------------------------------------------
    def omega(self, t) -> np.ndarray:
        """Body rates W(t), shape (n, 3), rad/s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.case == "principal spin":
            return np.tile(self.omega0, (len(t), 1))
        if self.case in ("symmetric", "spherical"):
            Pi0 = self.inertia * self.omega0 / self._i_perp
            Rc = rot_axis(self._ec, -self._psidot * t)
            return Rc @ Pi0 + self._psidot * self._ec
        sn, cn, dn = jacobi(self._u0 + self.lam * t, self.k2, self.m1, self.K)
        Wr = np.stack([cn, sn, dn], axis=1) * self._amp
        return Wr @ self._B.T

    def rotation(self, t) -> np.ndarray:
        """Body-to-world rotation R(t), shape (n, 3, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        R0 = self.rotation0
        if self.case == "principal spin":
            return R0 @ rot_axis(self._spin_axis, self._spin_rate * t)
        if self.case in ("symmetric", "spherical"):
            Lw = R0 @ (self.inertia * self.omega0)
            Lhat = Lw / self.L
            return (
                rot_axis(Lhat, self.L / self._i_perp * t)
                @ R0
                @ rot_axis(self._ec, self._psidot * t)
            )
        u = self._u0 + self.lam * t
        sn, cn, dn = jacobi(u, self.k2, self.m1, self.K)
        Pi = np.stack([cn, sn, dn], axis=1) * self._amp * self._Ir
        th = np.arctan2(np.hypot(Pi[:, 0], Pi[:, 1]), Pi[:, 2])
        psi = np.arctan2(Pi[:, 0], Pi[:, 1])
        phi = (self._G(u) - self._G0) / self.lam
        Rr = self._RL @ rot_z(phi) @ rot_x(th) @ rot_z(psi)
        return Rr @ self._B.T

    def phi(self, t) -> np.ndarray:
        """Precession angle about L, phi(t) - phi(0), rad (asymmetric bodies only)."""
        if self.case not in ("A", "B", "separatrix"):
            raise ValueError(f"phi(t) is defined here for asymmetric bodies, not {self.case!r}")
        u = self._u0 + self.lam * np.atleast_1d(np.asarray(t, dtype=float))
        return (self._G(u) - self._G0) / self.lam

    def accuracy(self, t) -> float:
        """Estimated maximum attitude error (rad) over the times ``t``: round-off of the phase
        arguments, which grows with the accumulated rotation angle (~ 16 eps per radian of
        rotation), plus the estimated quadrature error of phi per period times the number of
        periods, plus the conditioning term :meth:`modulus_error` of an asymmetric body."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tmax = float(np.max(np.abs(t))) if len(t) else 0.0
        wmax = float(np.max(np.linalg.norm(self.omega(np.linspace(0, tmax, 65)), axis=1)))
        err = 16.0 * EPS * (1.0 + wmax * tmax)
        if math.isfinite(self.period) and self.case in ("A", "B"):
            err += self.quadrature_error * (1.0 + tmax / self.period)
        elif self.case == "separatrix":
            err += self._G.error / self.lam  # panel estimate of the last evaluation
        return err + self.modulus_error(tmax)

    def modulus_error(self, tmax: float) -> float:
        """The attitude error (rad) over [0, tmax] that the rounding of the modulus causes.

        The separatrix distance S = |L^2 - 2 E I_mid| is exact to its last rounding
        (:func:`separatrix_distance`), but m1 = 1 - k^2 = |I_c - I_a| S/(|I_c - I_b| Q) is
        formed with a few more roundings: a relative error up to :data:`MODULUS_RTOL`. Near the
        separatrix K(m) ~ ln(4/sqrt(m1)), the flip time and the precession per period all
        depend on m1, and their errors grow with the number of periods. The effect is measured
        by a probe, the same body with S scaled by 1 + :data:`PROBE_RTOL` (far above
        round-off, in the linear range), evaluated at 1025 times over [0, tmax]: the largest
        angle between the two attitudes, times MODULUS_RTOL/PROBE_RTOL; pi (nothing can be
        said) if that angle exceeds :data:`PROBE_LINEAR` or the probe changes the case. If
        S = 0 exactly (the separatrix itself), or the body is not asymmetric, there is no
        modulus to round: 0.
        """
        if self.case not in ("A", "B") or tmax <= 0.0:
            return 0.0
        if self._probe is None:
            self._probe = FreeBody(
                self.inertia, self.omega0, self.rotation0, self._s_factor * (1.0 + PROBE_RTOL)
            )
        tt = np.linspace(0.0, tmax, 1025)
        diff = rotation_angle(self.rotation(tt), self._probe.rotation(tt))
        worst = float(np.max(diff)) if np.all(np.isfinite(diff)) else math.inf
        if self._probe.case != self.case or not worst <= PROBE_LINEAR:
            return math.pi  # the probe crossed the separatrix or left the linear range
        return worst * MODULUS_RTOL / PROBE_RTOL


#: relative error bound of m1 = |I_c - I_a| S/(|I_c - I_b| Q): S correctly rounded (1/2 ulp),
#: the two differences (1/2 ulp each), Q a sum of two products of three factors (4 ulp), the
#: product and quotient (3/2 ulp): 7 ulp, rounded up to 8 ulp = 4 eps
MODULUS_RTOL = 4.0 * EPS
#: relative perturbation of S by the conditioning probe of :meth:`FreeBody.modulus_error`,
#: and the largest attitude difference (rad) it may cause for the response to count as linear
PROBE_RTOL = 1e-9
PROBE_LINEAR = 1e-2


def separatrix_distance(inertia, omega) -> float:
    """L^2 - 2 E I_mid = I_lo (I_lo - I_mid) W_lo^2 + I_hi (I_hi - I_mid) W_hi^2, kg^2 m^4/s^2,
    computed exactly from the doubles given (rational arithmetic) and rounded once.

    Its sign decides the case (A: > 0, B: < 0, the separatrix: 0) and its relative value sets
    m1 = 1 - k^2, on which the flip time depends logarithmically. In floating point the two
    terms, each of size ~L^2, cancel near the separatrix, and the rounding of each, a few
    ulp of L^2, becomes the whole result: a body 1e-16 off the separatrix (relative) would be
    put on it, or on the wrong side, and a body 4e-12 off would have m1 wrong by 1e-4
    relative. The exact value leaves only its final rounding, 1/2 ulp of itself.
    """
    from fractions import Fraction

    I = [Fraction(float(x)) for x in inertia]
    W = [Fraction(float(x)) for x in omega]
    lo, mid, hi = (int(i) for i in np.argsort(np.asarray(inertia, dtype=float), kind="stable"))
    D = I[lo] * (I[lo] - I[mid]) * W[lo] ** 2 + I[hi] * (I[hi] - I[mid]) * W[hi] ** 2
    return float(D)


def free_flight(x0, v0, g, t) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass under uniform gravity: x = x0 + v0 t + g t^2/2, v = v0 + g t."""
    t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
    x0, v0, g = (np.asarray(a, dtype=float) for a in (x0, v0, g))
    return x0 + v0 * t + 0.5 * g * t * t, v0 + g * t
