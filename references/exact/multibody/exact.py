"""Exact motions of systems of rigid bodies (closed forms), each giving every body's x, R, v, W
over time, with the state to start a simulation from and a round-off accuracy estimate.

1. :class:`SpinningChain`: a straight chain (every centre of mass and joint point on one line,
   every body with a principal axis along it) rotating rigidly at rate Omega about a principal
   axis through the system's centre of mass, perpendicular to the line or along it. The
   centripetal forces and the joint forces all lie on the line through the centres of mass,
   so no body feels a torque about its centre of mass and each keeps a steady rotation about
   its own principal axis: R_b(t) = Rot(a, Omega t) R_b(0),
   x_b(t) = x_c(t) + Rot(a, Omega t)(x_b(0) - x_c(0)), with the centre of mass in free fall,
   x_c(t) = x_c(0) + v_c t + g t^2/2 (uniform gravity does not act on the relative motion).
2. :class:`DoubleConicalPendulum`: two links on spherical joints hanging from a fixed point,
   rotating steadily about the vertical at rate Omega in one vertical plane (angles phi_1,
   phi_2 from the downward vertical; each link's principal axes: e1 along the link, e2 in the
   plane, e3 normal to it). A motion locked to a rotation is a relative equilibrium: a
   critical point of the augmented potential V - Omega^2 I_zz(phi)/2 (Marsden & Ratiu,
   *Introduction to Mechanics and Symmetry*, 1999, on relative equilibria; derived here for
   this system), with I_zz the system's moment about the vertical through the pivot:

       V = -|g| (m1 l1 c1 + m2 (L1 c1 + l2 c2)),
       I_zz = m1 l1^2 s1^2 + m2 (L1 s1 + l2 s2)^2 + sum_i (Ja_i c_i^2 + Jb_i s_i^2),

   (c_i, s_i = cos, sin phi_i; l_i: joint to the link's centre of mass, L1: link 1's joint
   to joint length; Ja_i, Jb_i the moments about e1 and e2). Setting both derivatives to zero:

       |g| (m1 l1 + m2 L1) s1 = Omega^2 ((m1 l1^2 + Jb1 - Ja1) s1 c1 + m2 L1 c1 (L1 s1 + l2 s2))
       |g| m2 l2 s2          = Omega^2 ((Jb2 - Ja2) s2 c2 + m2 l2 c2 (L1 s1 + l2 s2)).

   (For one link this is the physical conical pendulum Omega^2 cos phi = m g l/(I_perp - Ja), I_perp
   = m l^2 + Jb about the pivot.) The angles are solved for the given rate on the branch with both
   links tilted to one side, 0 < phi_i < pi/2 (bracketed: see :meth:`DoubleConicalPendulum._solve`).
   Motion: R_i(t) = Rot(e_z, Omega t) R_i(0), x_i(t) = Rot(e_z, Omega t) x_i(0). tests/
   test_multibody_exact.py checks that the reduced-coordinate dynamics keeps this state with zero
   joint accelerations, tests/director_model/test_system_agreement.py that the angles equal those of
   the Newton-Euler balance of each link written independently in director_model.system.
3. :class:`ParallelogramFourBar`: crank A (ground pivot at the origin) and rocker B (ground
   pivot at (D, 0, 0)) of equal joint-to-joint length L, joined by a coupler C as long as the
   ground link D: the coupler translates without rotating, crank and rocker turn by the same
   angle theta (from the downward vertical, in the x-z plane, gravity along -z), and
   T = (I_A + I_B + m_C L^2) theta'^2/2, V = -|g| cos(theta) (m_A L_A + m_B L_B + m_C L)
   (I_A, I_B about the ground pivots; L_A, L_B pivot to centre of mass): a planar pendulum
   with w_p^2 = |g| (m_A L_A + m_B L_B + m_C L)/(I_A + I_B + m_C L^2), solved by the suite's
   closed form of the planar pendulum (:class:`references.exact.pendulum.PlanarPendulum`:
   Jacobi functions with accurate argument reduction, oscillating and rotating through the
   vertical). Bodies: crank and rocker have e1 along the link (pivot to tip), e3 = -e_y (the
   rotation axis, so that theta > 0 moves the tip towards +x), e2 = e3 x e1; the coupler has
   e1 = e_x, e2 = e_z, e3 = -e_y and its centre of mass at ``coupler_com`` along e1 from the
   crank's tip.

4. :class:`NFourBar`: IFToMM benchmark A02, N parallelogram four-bars side by side in the
   x-y plane under gravity along -y: N + 1 cranks of length L pivoting on the ground at
   (i L, 0, 0), i = 0..N, and N couplers of length L, coupler j joining the tips of cranks
   j - 1 and j. Every crank turns by the same angle theta (from the upward vertical, positive
   towards +x: the crank tip at L (sin theta, cos theta, 0)) and the couplers translate, so
   the mechanism is a planar pendulum about the cranks' pivots with
   T = 1/2 ((N + 1)(J + m L^2/4) + N m L^2) theta'^2 and
   V = |g| m L ((N + 1)/2 + N) cos theta (J: each link's moment about its hinge axis through
   its centre of mass, m its mass), solved by the same closed form. Bodies ``crank0`` ..
   ``crankN`` (e1 from pivot to tip, e3 = -e_z, the hinge axis, so that theta' > 0 is
   W = (0, 0, theta')), then ``coupler1`` .. ``couplerN`` (e1 = e_x, e2 = -e_y, e3 = -e_z).
   It passes through its singular configuration (all links on the x axis) twice per turn.

Accuracy: the closed forms are exact; their evaluation errs by the rounding of the phase,
estimated as 16 eps (1 + |Omega| t) rad (as for the single-body closed forms), and positions by
that times the largest distance from the rotation axis plus 16 eps |x|.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from references.conventions import matrix_to_quat_wxyz
from references.exact._util import EPS, ReferenceNotApplicable, rot_axis
from references.exact.multibody.dynamics import body_states
from references.exact.multibody.tree import Body, Joint, Tree
from references.exact.pendulum import PlanarPendulum


class ExactMotion:
    """Common output of the closed forms. ``names`` (nb,) body names;
    ``motion(t)`` -> (x (n, nb, 3), R (n, nb, 3, 3), v (n, nb, 3), W (n, nb, 3)) in world
    axes (W in body axes); ``accuracy(t)`` -> {"position": m, "attitude": rad} round-off
    estimates of the evaluation over [0, max t]; ``initial`` = motion(0) per body."""

    names: list

    def motion(self, t):  # pragma: no cover - interface
        raise NotImplementedError

    @property
    def initial(self):
        x, R, v, W = self.motion(np.zeros(1))
        return x[0], R[0], v[0], W[0]

    #: the distance (rad) of an engine's initial state from this motion: the file's rounding
    #: to 17 digits, a few eps (the conical pendulum adds its balance's residual)
    @property
    def delta0(self) -> float:
        return 16.0 * EPS

    def stability(self):
        """The motion's :class:`~.stability.Floquet` multipliers, or None where errors grow
        at most linearly (a motion with one degree of freedom: a periodic orbit of a
        conservative system in the plane has the multipliers 1, 1)."""
        return None

    def _floquet_rotating(self, tree, rate: float):
        """Floquet multipliers of a relative equilibrium rotating at ``rate`` (rad/s), over
        two turns: after one turn a quaternion of the world attitude has changed sign (the
        chart, not the motion), after two it is back."""
        from references.exact.multibody.stability import floquet

        if rate == 0:
            return None
        q0, u0 = tree.to_joint(*self.initial)
        return floquet(tree, q0, u0, 4.0 * math.pi / abs(rate))


def _rate_accuracy(rate: float, t, radius: float, xmax: float) -> dict:
    tmax = float(np.max(np.abs(t)))
    att = 16.0 * EPS * (1.0 + abs(rate) * tmax)
    return {"attitude": att, "position": att * radius + 16.0 * EPS * xmax}


class SpinningChain(ExactMotion):
    """A straight chain spinning rigidly (module docstring, item 1).

    ``tree``: a chain whose root is ``free`` and whose other joints are spherical or revolute,
    with every anchor on the bodies' e1 axes and every revolute offset the identity, so that
    with all joint coordinates zero (identity quaternions, theta = 0) the bodies share the
    root's attitude ``R0`` and lie on the line R0 e1. ``rate`` Omega (rad/s), ``axis``: the
    body axis (0, 1 or 2; 0 is the line itself) that is the spin axis, ``x_c``, ``v_c``:
    the system's centre of mass and its velocity at t = 0 (world). Raises
    :class:`ReferenceNotApplicable` if the chain is not straight.
    """

    def __init__(
        self, tree: Tree, rate: float, axis: int = 2, R0=None, x_c=(0, 0, 0), v_c=(0, 0, 0)
    ):
        if tree.kinds[0] != "free":
            raise ReferenceNotApplicable("spinning chain: the root's joint must be free")
        if axis not in (0, 1, 2):
            raise ValueError(f"spinning chain: axis {axis!r} must be 0, 1 or 2")
        if np.any(tree.X[1:, 1:] != 0) or np.any(tree.Y[1:, 1:] != 0):
            raise ReferenceNotApplicable(
                "spinning chain: every anchor must lie on the bodies' e1 axes (the line)"
            )
        for b in range(1, tree.nb):
            if tree.kinds[b] == "revolute" and not np.array_equal(tree.offset[b], np.eye(3)):
                raise ReferenceNotApplicable(
                    f"spinning chain: revolute joint of {tree.names[b]!r} has an offset; "
                    "the bodies must share one attitude at theta = 0"
                )
        self.tree = tree
        self.names = list(tree.names)
        self.rate = float(rate)
        self.R0 = np.eye(3) if R0 is None else np.asarray(R0, dtype=float)
        self.a = self.R0[:, axis]
        self.axis = axis
        q = np.zeros(tree.nq)
        for b in range(tree.nb):
            if tree.kinds[b] == "free":
                q[tree.qofs[b] + 3 : tree.qofs[b] + 7] = matrix_to_quat_wxyz(self.R0)
            elif tree.kinds[b] == "spherical":
                q[tree.qofs[b]] = 1.0
        x, _, _, _, _, _ = body_states(tree, q, np.zeros(tree.nu))
        m = tree.mass
        self.x_c = np.asarray(x_c, dtype=float)
        self.v_c = np.asarray(v_c, dtype=float)
        self.r0 = x - (m @ x) / m.sum()  # positions relative to the system's centre of mass
        self.g = tree.gravity

    def motion(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        Q = rot_axis(self.a, self.rate * t)  # (n, 3, 3)
        xc = self.x_c + np.outer(t, self.v_c) + 0.5 * np.outer(t * t, self.g)
        vc = self.v_c + np.outer(t, self.g)
        rel = np.einsum("nij,bj->nbi", Q, self.r0)
        x = xc[:, None, :] + rel
        v = vc[:, None, :] + self.rate * np.cross(self.a, rel)
        R = np.einsum("nij,jk->nik", Q, self.R0)[:, None, :, :].repeat(self.tree.nb, axis=1)
        W = np.zeros((len(t), self.tree.nb, 3))
        W[:, :, self.axis] = self.rate
        return x, R, v, W

    def stability(self):
        return self._floquet_rotating(self.tree, self.rate)

    def accuracy(self, t) -> dict:
        x, *_ = self.motion(np.atleast_1d(t)[-1:])
        radius = float(np.max(np.linalg.norm(self.r0, axis=1)))
        return _rate_accuracy(self.rate, t, radius, float(np.max(np.abs(x))))


def straight_chain(
    masses, inertias, anchors, joint: str = "spherical", gravity=(0, 0, 0), names=None
) -> Tree:
    """A chain of len(masses) bodies along their e1 axes: body i's back joint point at
    -anchors[i][0] and its front one at +anchors[i][1] along e1 (m); the root is free;
    ``joint`` ("spherical" or "revolute", a revolute about e3) between consecutive bodies."""
    n = len(masses)
    names = names or [f"link{i}" for i in range(n)]
    bodies = [Body(names[i], float(masses[i]), tuple(inertias[i])) for i in range(n)]
    joints = [Joint("free", names[0])]
    for i in range(1, n):
        joints.append(
            Joint(
                joint,
                names[i],
                names[i - 1],
                parent_anchor=(float(anchors[i - 1][1]), 0.0, 0.0),
                child_anchor=(-float(anchors[i][0]), 0.0, 0.0),
                axis=(0.0, 0.0, 1.0),
            )
        )
    return Tree(bodies, joints, gravity)


class DoubleConicalPendulum(ExactMotion):
    """Two links on spherical joints hanging from the origin, in steady rotation about the
    vertical e_z (module docstring, item 2). Link i: mass ``m[i]``, principal moments
    ``J[i]`` = (Ja about the link, Jb in the plane, J3 normal to it), ``l[i]`` from its upper
    joint to its centre of mass; ``L1`` link 1's joint-to-joint length; ``g`` = |g| (gravity
    along -e_z); ``rate`` Omega (rad/s). Attributes: ``phi`` (2,) the angles from the
    downward vertical (rad), ``residual`` (the balance equations' residual relative to their
    largest term), ``tree`` (the system as a :class:`Tree`), ``q0``, ``u0`` (its joint state).
    ``branch`` +1: both links tilted to one side (0 < phi_i < pi/2); -1: link 2 tilted to the
    other side of the vertical (phi_2 in (-pi/2, 0), its centre of mass across the axis).
    Raises :class:`ReferenceNotApplicable` when the rate is too slow for that branch."""

    def __init__(self, m, J, l, L1, g, rate, branch: int = 1):
        if branch not in (1, -1):
            raise ValueError(f"double conical pendulum: branch {branch!r} must be 1 or -1")
        self.branch = int(branch)
        self.m = np.asarray(m, dtype=float)
        self.J = np.asarray(J, dtype=float)
        self.l = np.asarray(l, dtype=float)
        self.L1, self.g, self.rate = float(L1), float(g), float(rate)
        phi = self._solve()
        F = self._balance(phi)
        scale = self.g * (self.m[0] * self.l[0] + self.m[1] * self.L1)
        self.residual = float(np.max(np.abs(F)) / scale)
        if not self.residual <= 1e-13:
            raise ReferenceNotApplicable(
                f"double conical pendulum: the balance at rate {rate} rad/s is solved only to "
                f"a relative residual {self.residual:.3g}"
            )
        self.phi = phi
        self.names = ["link1", "link2"]
        self.tree = Tree(
            [Body(f"link{i + 1}", self.m[i], tuple(self.J[i])) for i in range(2)],
            [
                Joint("spherical", "link1", None, (0, 0, 0), (-self.l[0], 0, 0)),
                Joint(
                    "spherical", "link2", "link1", (self.L1 - self.l[0], 0, 0), (-self.l[1], 0, 0)
                ),
            ],
            (0.0, 0.0, -self.g),
        )
        R = np.empty((2, 3, 3))
        x = np.empty((2, 3))
        for i in range(2):
            s, c = math.sin(phi[i]), math.cos(phi[i])
            R[i] = np.column_stack([(s, 0.0, -c), (-c, 0.0, -s), (0.0, 1.0, 0.0)])
        x[0] = self.l[0] * R[0][:, 0]
        x[1] = self.L1 * R[0][:, 0] + self.l[1] * R[1][:, 0]
        self.R0, self.x0 = R, x
        ez = np.array([0.0, 0.0, 1.0])
        v = self.rate * np.cross(ez, x)
        W = self.rate * np.einsum("bji,j->bi", R, ez)
        self.q0, self.u0 = self.tree.to_joint(x, R, v, W)

    def _phi2(self, phi1: float) -> float:
        """Link 2's angle balancing it for link 1's angle phi1 in (0, pi/2): the second balance
        equation is -Omega^2 m2 l2 L1 s1 < 0 at phi2 = 0 and |g| m2 l2 > 0 at pi/2."""
        return brentq(
            lambda p2: self._balance((phi1, p2))[1], 0.0, 0.5 * math.pi, xtol=1e-16, rtol=4 * EPS
        )

    def _solve_opposite(self) -> np.ndarray:
        """Branch -1: phi1 in (0, pi/2), phi2 in (-pi/2, 0). It exists above the frequency of
        the double pendulum's second mode of small swings (8 rad/s on the library's links,
        not 7): Newton (scipy's fsolve) from a grid over the quadrant, the root whose
        balance residual is smallest."""
        from scipy.optimize import fsolve

        best, best_res = None, math.inf
        for a in np.linspace(0.05, 1.5, 15):
            for b in np.linspace(-1.5, -0.05, 15):
                r, _, ier, _ = fsolve(self._balance, [a, b], full_output=True, xtol=1e-15)
                if ier != 1 or not (0 < r[0] < 0.5 * math.pi and -0.5 * math.pi < r[1] < 0):
                    continue
                res = float(np.max(np.abs(self._balance(r))))
                if res < best_res:
                    best, best_res = r, res
        if best is None:
            raise ReferenceNotApplicable(
                f"double conical pendulum: at rate {self.rate} rad/s there is no steady "
                "rotation with the links on opposite sides of the vertical (it exists above "
                "the frequency of the second mode of small swings)"
            )
        return np.asarray(best, dtype=float)

    def _solve(self) -> np.ndarray:
        """Both angles in (0, pi/2): the first balance equation with phi2 = phi2(phi1) is
        > 0 at phi1 = pi/2 (|g| (m1 l1 + m2 L1)) and < 0 just above 0 when the rate exceeds
        the lowest frequency of small swings; bracketed and solved by Brent's method."""
        if self.branch == -1:
            return self._solve_opposite()
        lo, hi = 1e-6, 0.5 * math.pi - 1e-9
        if self._balance((lo, self._phi2(lo)))[0] >= 0:
            raise ReferenceNotApplicable(
                f"double conical pendulum: at rate {self.rate} rad/s (below the lowest "
                "frequency of small swings) there is no steady rotation with both links "
                "tilted to one side"
            )
        p1 = brentq(
            lambda p: self._balance((p, self._phi2(p)))[0], lo, hi, xtol=1e-16, rtol=4 * EPS
        )
        return np.array([p1, self._phi2(p1)])

    def _balance(self, phi):
        (m1, m2), (l1, l2), L1, g, w2 = self.m, self.l, self.L1, self.g, self.rate**2
        s1, c1, s2, c2 = math.sin(phi[0]), math.cos(phi[0]), math.sin(phi[1]), math.cos(phi[1])
        d1 = self.J[0, 1] - self.J[0, 0]
        d2 = self.J[1, 1] - self.J[1, 0]
        r2 = L1 * s1 + l2 * s2  # distance of link 2's centre of mass from the axis
        return np.array(
            [
                g * (m1 * l1 + m2 * L1) * s1
                - w2 * ((m1 * l1 * l1 + d1) * s1 * c1 + m2 * L1 * c1 * r2),
                g * m2 * l2 * s2 - w2 * (d2 * s2 * c2 + m2 * l2 * c2 * r2),
            ]
        )

    def motion(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ez = np.array([0.0, 0.0, 1.0])
        Q = rot_axis(ez, self.rate * t)
        x = np.einsum("nij,bj->nbi", Q, self.x0)
        R = np.einsum("nij,bjk->nbik", Q, self.R0)
        v = self.rate * np.cross(ez, x)
        W = np.broadcast_to(self.rate * np.einsum("bji,j->bi", self.R0, ez), x.shape).copy()
        return x, R, v, W

    @property
    def delta0(self) -> float:
        return 16.0 * EPS + self.residual

    def stability(self):
        return self._floquet_rotating(self.tree, self.rate)

    def accuracy(self, t) -> dict:
        radius = float(np.max(np.linalg.norm(self.x0[:, :2], axis=1)))
        acc = _rate_accuracy(self.rate, t, radius, float(np.max(np.abs(self.x0))))
        # the angles solve the balance to `residual`; their error moves the state by about
        # residual/(d balance/d phi) ~ residual rad (the balance is scaled by its largest term)
        acc["attitude"] += self.residual
        acc["position"] += self.residual * (self.L1 + self.l[1])
        return acc


class ParallelogramFourBar(ExactMotion):
    """The parallelogram four-bar as a planar pendulum (module docstring, item 3).

    ``L`` crank and rocker joint-to-joint length, ``D`` ground link = coupler length (m);
    ``crank``, ``rocker``, ``coupler``: (mass, (J1, J2, J3) principal moments); ``LA``, ``LB``
    pivot to centre of mass along crank and rocker; ``coupler_com`` the coupler's centre of
    mass from the crank tip along e_x; ``g`` = |g|; ``theta0``, ``thetadot0`` the initial
    angle (from the downward vertical) and rate. Attributes: ``wp2`` = w_p^2, ``inertia``
    (I_A + I_B + m_C L^2), ``pendulum`` (the :class:`PlanarPendulum`), ``case``. Bodies in the
    order crank, rocker, coupler.
    """

    def __init__(self, L, D, crank, rocker, coupler, LA, LB, coupler_com, g, theta0, thetadot0):
        self.L, self.D, self.LA, self.LB = float(L), float(D), float(LA), float(LB)
        self.coupler_com = float(coupler_com)
        self.bodies = [crank, rocker, coupler]
        self.names = ["crank", "rocker", "coupler"]
        (mA, JA), (mB, JB), (mC, _) = crank, rocker, coupler
        self.g = float(g)
        IA = JA[2] + mA * self.LA**2
        IB = JB[2] + mB * self.LB**2
        self.inertia = IA + IB + mC * self.L**2
        self.moment = self.g * (mA * self.LA + mB * self.LB + mC * self.L)
        self.wp2 = self.moment / self.inertia
        self.n = np.array([0.0, -1.0, 0.0])  # rotation axis: theta > 0 swings the tips to +x
        down = np.array([0.0, 0.0, -1.0])
        self.Rref = np.column_stack([down, [1.0, 0.0, 0.0], self.n])  # crank/rocker at theta=0
        self.Rc = np.column_stack([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], self.n])
        self.theta0, self.thetadot0 = float(theta0), float(thetadot0)
        R0 = rot_axis(self.n, self.theta0)[0] @ self.Rref
        W0 = self.thetadot0 * (R0.T @ self.n)
        self.pendulum = PlanarPendulum(R0, W0, -down, R0[:, 0], self.wp2)
        self.case = self.pendulum.case
        if self.case != "at rest" and np.dot(self.pendulum.n, self.n) < 0:
            self._sign = -1.0  # PlanarPendulum's axis is -n when theta' < 0
        else:
            self._sign = 1.0

    def theta(self, t):
        """theta(t) and theta'(t) (rad, rad/s)."""
        dth, thd = self.pendulum.theta(t)
        return self.theta0 + self._sign * dth, self._sign * thd

    def motion(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        th, thd = self.theta(t)
        Q = rot_axis(self.n, th)
        RA = Q @ self.Rref
        u = RA[:, :, 0]  # unit vector pivot -> tip
        du = thd[:, None] * np.cross(self.n, u)
        OB = np.array([self.D, 0.0, 0.0])
        x = np.empty((len(t), 3, 3))
        v = np.empty((len(t), 3, 3))
        x[:, 0] = self.LA * u
        x[:, 1] = OB + self.LB * u
        x[:, 2] = self.L * u + np.array([self.coupler_com, 0.0, 0.0])
        v[:, 0], v[:, 1], v[:, 2] = self.LA * du, self.LB * du, self.L * du
        R = np.stack([RA, RA, np.broadcast_to(self.Rc, RA.shape)], axis=1)
        W = np.zeros((len(t), 3, 3))
        W[:, 0] = W[:, 1] = thd[:, None] * np.array([0.0, 0.0, 1.0])  # n = e3 of crank, rocker
        return x, R, v, W

    def accuracy(self, t) -> dict:
        thd = 2.0 * math.sqrt(self.pendulum.k2 * self.wp2) if self.case != "at rest" else 0.0
        return _rate_accuracy(thd, t, self.L, self.D + self.L)


class NFourBar(ExactMotion):
    """IFToMM A02, the N-four-bar (module docstring, item 4): ``N`` loops, links of length
    ``L`` (m) and mass ``m`` (kg), ``J`` each link's moment about its hinge axis through its
    centre of mass (kg m^2), ``g`` = |g| (gravity along -y), ``theta0`` (rad from the upward
    vertical, positive towards +x) and ``thetadot0`` (rad/s; the benchmark: the crank tip B0
    moving at 1 m/s along +x, theta' = 1/L). Bodies: cranks then couplers (``names``)."""

    def __init__(self, N: int, L: float, m: float, J: float, g: float, theta0: float,
                 thetadot0: float):  # fmt: skip
        if int(N) != N or N < 1:
            raise ValueError(f"N-four-bar: N = {N!r} must be an integer >= 1")
        self.N, self.L, self.m, self.J, self.g = int(N), float(L), float(m), float(J), float(g)
        n = self.N
        self.names = [f"crank{i}" for i in range(n + 1)] + [f"coupler{j}" for j in range(1, n + 1)]
        self.inertia = (n + 1) * (self.J + self.m * self.L**2 / 4) + n * self.m * self.L**2
        self.moment = self.g * self.m * self.L * ((n + 1) / 2 + n)
        self.wp2 = self.moment / self.inertia
        self.axis = np.array([0.0, 0.0, -1.0])  # theta > 0 turns the tips towards +x
        up = np.array([0.0, 1.0, 0.0])
        self.Rref = np.column_stack([up, [1.0, 0.0, 0.0], self.axis])  # a crank at theta = 0
        self.Rc = np.column_stack([[1.0, 0.0, 0.0], -up, self.axis])
        self.theta0, self.thetadot0 = float(theta0), float(thetadot0)
        R0 = rot_axis(self.axis, self.theta0)[0] @ self.Rref
        W0 = self.thetadot0 * (R0.T @ self.axis)
        self.pendulum = PlanarPendulum(R0, W0, up, R0[:, 0], self.wp2)
        self.case = self.pendulum.case
        if self.case != "at rest" and np.dot(self.pendulum.n, self.axis) < 0:
            self._sign = -1.0
        else:
            self._sign = 1.0

    def theta(self, t):
        """theta(t) and theta'(t) (rad, rad/s)."""
        dth, thd = self.pendulum.theta(t)
        return self.theta0 + self._sign * dth, self._sign * thd

    def tip(self, t, i: int = 0):
        """The tip of crank ``i`` (B_i of the benchmark), position and velocity (n, 3)."""
        th, thd = self.theta(np.atleast_1d(np.asarray(t, dtype=float)))
        u = np.stack([np.sin(th), np.cos(th), np.zeros_like(th)], axis=1)
        du = thd[:, None] * np.stack([np.cos(th), -np.sin(th), np.zeros_like(th)], axis=1)
        return np.array([i * self.L, 0.0, 0.0]) + self.L * u, self.L * du

    def motion(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        th, thd = self.theta(t)
        Q = rot_axis(self.axis, th)
        Rk = Q @ self.Rref
        u = Rk[:, :, 0]  # pivot -> tip
        du = thd[:, None] * np.cross(self.axis, u)
        n, L = self.N, self.L
        nb = 2 * n + 1
        x = np.empty((len(t), nb, 3))
        v = np.empty((len(t), nb, 3))
        R = np.empty((len(t), nb, 3, 3))
        W = np.zeros((len(t), nb, 3))
        ex = np.array([1.0, 0.0, 0.0])
        for i in range(n + 1):
            x[:, i] = i * L * ex + 0.5 * L * u
            v[:, i] = 0.5 * L * du
            R[:, i] = Rk
            W[:, i, 2] = thd  # e3 is the axis
        for j in range(1, n + 1):
            x[:, n + j] = ((j - 1) * L + 0.5 * L) * ex + L * u
            v[:, n + j] = L * du
            R[:, n + j] = self.Rc
        return x, R, v, W

    def accuracy(self, t) -> dict:
        thd = 2.0 * math.sqrt(self.pendulum.k2 * self.wp2) if self.case != "at rest" else 0.0
        return _rate_accuracy(thd, t, self.L, (self.N + 1) * self.L)
