"""Systems with known motions (multibody exact references) and the benchmark chains.

Each constructor returns the bodies and joints ready for :func:`simulate_system`, and, where
one exists, the exact motion computed from a formulation that shares nothing with the
integrator (rigid rotation and free fall; the Newton-Euler balance of a relative equilibrium
solved for its angles; the one-degree-of-freedom pendulum of a parallelogram linkage).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from director_model.system.model import Body, Joint
from director_model.system.states import project_velocities

RTOL = 4 * np.finfo(float).eps  # relative tolerance of the Brent solves (round-off)


def rot_y(t: float) -> np.ndarray:
    """Rotation by t about the world y axis: maps e_z to (sin t, 0, cos t)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(t: float) -> np.ndarray:
    """Rotation by t about the world z axis."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rod_chain(n: int, hang: bool, *, tilt: float = 0.3, seed: int = 0, spin: bool = True,
              length: float = 1.0, mass: float = 1.0, inertia=None):  # fmt: skip
    """n rods (length 1 m, mass 1 kg, moments (m L^2/12 + 0.01, same, 0.02), body axis 3
    along the rod) joined end to end by spherical joints; the first hangs from the world
    origin if ``hang`` (else the chain floats free). Random tilts (rotation vectors of
    standard deviation ``tilt`` rad) and, with ``spin``, random velocities projected on the
    joints (:func:`project_velocities`). Returns (bodies, joints)."""
    rng = np.random.default_rng(seed)
    L, m = length, mass
    I = inertia or (m * L**2 / 12 + 0.01, m * L**2 / 12 + 0.01, 0.02)
    bodies, joints = [], []
    top = np.zeros(3)
    for i in range(n):
        R = Rotation.from_rotvec(rng.normal(size=3) * tilt).as_matrix()
        a = R @ np.array([0.0, 0.0, L / 2])
        x = top - a
        v = rng.normal(size=3) if spin else np.zeros(3)
        W = rng.normal(size=3) if spin else np.zeros(3)
        bodies.append(Body(f"b{i}", m, I, position=x, rotation=R, velocity=v, omega_body=W))
        if i == 0 and hang:
            joints.append(Joint("spherical", "b0", None, (0, 0, L / 2), (0, 0, 0)))
        elif i > 0:
            joints.append(Joint("spherical", f"b{i - 1}", f"b{i}", (0, 0, -L / 2), (0, 0, L / 2)))
        top = x - a
    return project_velocities(bodies, joints), joints


def straight_chain(omega: float = 2.0, gravity=(0.0, 0.0, -9.81), v_com=(0.3, -0.2, 1.0)):
    """Three unequal rods on the x axis (lengths 1, 0.6, 1.4 m; masses 1, 0.5, 2 kg; body axes
    = world axes, axis 1 along the chain) joined by spherical joints, spinning at ``omega``
    about the z axis through the system's centre of mass while it moves with ``v_com`` under
    ``gravity`` (multibody.md section 5: a relative equilibrium; every joint force lies on the
    line of the centres, no body feels a torque). Returns (bodies, joints, exact) with
    exact(t) -> (X (3, 3) positions, R (3, 3) the common rotation) = rigid rotation about the
    centre of mass plus its free fall."""
    Ls = [1.0, 0.6, 1.4]
    ms = [1.0, 0.5, 2.0]
    Is = [(0.02, 0.1, 0.11), (0.01, 0.03, 0.035), (0.05, 0.4, 0.42)]
    xs = np.array([[0.5, 0, 0], [1.3, 0, 0], [2.3, 0, 0]])
    xc = sum(m * x for m, x in zip(ms, xs, strict=True)) / sum(ms)
    w = np.array([0.0, 0.0, omega])
    vc = np.asarray(v_com, dtype=float)
    g = np.asarray(gravity, dtype=float)
    bodies = [
        Body(f"b{i}", ms[i], Is[i], xs[i], np.eye(3), np.cross(w, xs[i] - xc) + vc, w)
        for i in range(3)
    ]
    joints = [
        Joint("spherical", "b0", "b1", (Ls[0] / 2, 0, 0), (-Ls[1] / 2, 0, 0)),
        Joint("spherical", "b1", "b2", (Ls[1] / 2, 0, 0), (-Ls[2] / 2, 0, 0)),
    ]

    def exact(t: float):
        R = rot_z(omega * t)
        c = xc + vc * t + 0.5 * g * t * t
        return np.array([c + R @ (x - xc) for x in xs]), R

    return bodies, joints, exact


def double_conical_pendulum(omega: float = 3.0, g: float = 9.81):
    """Two rods (1 m, 1 kg and 0.8 m, 0.7 kg; transverse moments m L^2/12 + 0.005, axial
    0.01) hanging from a spherical joint at the origin, joined by a spherical joint, in
    steady rotation at ``omega`` (rad/s) about the vertical (gravity -z, ``g`` = |g| m/s^2).
    The angles (theta_1, theta_2) from the downward vertical solve the Newton-Euler balance
    of each link in the rotating plane: m a = m g + joint forces with a the centripetal
    acceleration, and the torque of the joint forces about each centre of mass equal to
    omega e_z x L_k (the gyroscopic torque of a link spinning about a non-principal axis).

    The branch solved for is the in-phase cone: both links below the pivot and tilted to the
    same side, 0 < theta_k < pi/2, which exists for |omega| above the lowest frequency of
    small swings (2.86093 rad/s with g = 9.81) and tends to pi/2 as |omega| grows. It is
    bracketed, not guessed: for theta_1 in (0, pi/2) link 2's balance has exactly one root
    theta_2 in (0, pi/2) (its residual over cos theta_2 is concave in theta_2, positive at 0,
    negative towards pi/2); link 1's balance with that theta_2 is negative at theta_1 = pi/2
    and positive just above 0 when |omega| exceeds the lowest frequency. Both are solved by
    Brent's method to round-off. A rate with no such solution (at or below the lowest
    frequency, or not finite) raises ValueError naming the rate and that frequency.

    Returns (bodies, joints, exact, angles) with exact(t) -> (X (2, 3), [R_1, R_2]) =
    rotation of the initial state by omega t about e_z, and angles (2,) rad."""
    if not (np.isfinite(omega) and np.isfinite(g) and g > 0):
        raise ValueError(
            f"double_conical_pendulum: omega = {omega!r} rad/s and g = {g!r} m/s^2 must be "
            "finite, with g > 0"
        )
    m = (1.0, 0.7)
    L = (1.0, 0.8)
    It = tuple(mm * LL**2 / 12 + 0.005 for mm, LL in zip(m, L, strict=True))
    Ia = (0.01, 0.01)
    w = np.array([0.0, 0.0, omega])
    gv = np.array([0.0, 0.0, -g])

    def geometry(th):
        R = [rot_y(t) for t in th]  # body e3 = (sin, 0, cos): from the link's bottom to top
        top = np.zeros(3)
        xs, tops = [], []
        for k in range(2):
            x = top - R[k] @ np.array([0.0, 0.0, L[k] / 2])
            xs.append(x)
            tops.append(top)
            top = x - R[k] @ np.array([0.0, 0.0, L[k] / 2])
        return R, xs, tops

    def balance(th, w=w):
        R, xs, tops = geometry(th)
        acc = [np.cross(w, np.cross(w, x)) for x in xs]
        F1 = m[1] * (acc[1] - gv)  # on link 2 at its top, from link 1
        F0 = m[0] * (acc[0] - gv) + F1  # on link 1 at the pivot
        res = []
        for k, (Fin, Fbot) in enumerate(((F0, -F1), (F1, None))):
            Lk = R[k] @ np.diag((It[k], It[k], Ia[k])) @ R[k].T @ w
            tau = np.cross(tops[k] - xs[k], Fin)
            if Fbot is not None:
                tau = tau + np.cross(tops[1] - xs[k], Fbot)
            res.append((tau - np.cross(w, Lk))[1])
        return np.array(res)

    def theta2(th1):
        return brentq(lambda t2: balance((th1, t2))[1], 0.0, np.pi / 2, xtol=1e-16, rtol=RTOL)

    def link1(th1):
        return balance((th1, theta2(th1)))[0]

    lo, hi = 1e-6, np.pi / 2 - 1e-9
    if np.sign(link1(lo)) == np.sign(link1(hi)):
        # the linearised balance at theta = 0 is (K - omega^2 M) theta: K from the Jacobian
        # at rest, M from its change per unit omega^2 (central differences, error ~1e-10)
        def jac(rate):
            e = 1e-6 * np.eye(2)
            wr = np.array([0.0, 0.0, rate])
            return np.column_stack([(balance(e[i], wr) - balance(-e[i], wr)) / 2e-6
                                    for i in range(2)])  # fmt: skip

        K, M = jac(0.0), jac(0.0) - jac(1.0)
        w_low = np.sqrt(np.min(np.linalg.eigvals(np.linalg.solve(M, K)).real))
        raise ValueError(
            f"double_conical_pendulum: at omega = {omega!r} rad/s there is no steady rotation "
            "with both links below the pivot on one side (0 < theta < pi/2): |omega| must "
            f"exceed the lowest frequency of small swings, {w_low:.6g} rad/s"
        )
    th1 = brentq(link1, lo, hi, xtol=1e-16, rtol=RTOL)
    th = np.array([th1, theta2(th1)])
    R, xs, tops = geometry(th)
    bodies = [
        Body(f"l{k}", m[k], (It[k], It[k], Ia[k]), xs[k], R[k], np.cross(w, xs[k]), R[k].T @ w)
        for k in range(2)
    ]
    joints = [
        Joint("spherical", "l0", None, (0, 0, L[0] / 2), (0, 0, 0)),
        Joint("spherical", "l0", "l1", (0, 0, -L[0] / 2), (0, 0, L[1] / 2)),
    ]

    def exact(t: float):
        Q = rot_z(omega * t)
        return np.array([Q @ x for x in xs]), [Q @ r for r in R]

    return bodies, joints, exact, th


def parallelogram_four_bar(theta0: float = 0.0, theta_dot0: float = 7.0):
    """A planar parallelogram four-bar of revolute joints (axes along y) in the x-z plane:
    crank (0.5 m, 1 kg) pivoting at the origin, rocker (0.5 m, 1.5 kg) at (1, 0, 0), coupler
    (1 m, 2 kg) joining their tips; uniform rods with the centres of mass at mid-length.
    theta is the crank and rocker angle from the downward vertical: both are turned by
    rot_y(theta) about their ground pivots (a turn about +y, so the tips sit at
    L (-sin theta, 0, -cos theta) from the pivots and theta' > 0 moves them towards -x), with
    angular velocity theta' e_y; the coupler translates with the tips. Any theta0, theta_dot0
    gives a state on the joints (positions and velocities), the collinear theta0 = pi/2 too.
    Twenty joint rows of rank 17 (three redundant: a planar loop of revolutes in space). With
    theta_dot0 = 7 rad/s from theta0 = 0 it swings to 1.666 rad, through the singular
    configuration theta = pi/2 (all links collinear) twice per swing.

    Returns (bodies, joints, I_eff, k): the exact motion is the planar pendulum
    I_eff theta'' = -|g| k sin(theta) (multibody.md section 5) with I_eff = I_A + I_B +
    m_c L^2 (I_A, I_B about the ground pivots) and k = m_A L_A + m_B L_B + m_c L."""
    if not (np.isfinite(theta0) and np.isfinite(theta_dot0)):
        raise ValueError(
            f"parallelogram_four_bar: theta0 = {theta0!r} rad and theta_dot0 = {theta_dot0!r} "
            "rad/s must be finite"
        )
    L, d = 0.5, 1.0
    mA, mB, mC = 1.0, 1.5, 2.0
    IA = (mA * L**2 / 12 + 0.001, mA * L**2 / 12 + 0.002, 0.002)
    IB = (mB * L**2 / 12 + 0.001, mB * L**2 / 12 + 0.002, 0.002)
    IC = (0.003, mC * d**2 / 12 + 0.001, mC * d**2 / 12 + 0.002)
    R = rot_y(theta0)
    tip = R @ np.array([0.0, 0.0, -L])  # crank tip from its pivot (rocker's likewise)
    vtip = np.cross([0.0, theta_dot0, 0.0], tip)
    W = (0.0, theta_dot0, 0.0)
    bodies = [
        Body("crank", mA, IA, tip / 2, R, vtip / 2, W),
        Body("rocker", mB, IB, np.array([d, 0, 0]) + tip / 2, R, vtip / 2, W),
        Body("coupler", mC, IC, np.array([d / 2, 0, 0]) + tip, np.eye(3), vtip, (0, 0, 0)),
    ]
    y = (0, 1, 0)
    joints = [
        Joint("revolute", "crank", None, (0, 0, L / 2), (0, 0, 0), y, y, name="A0"),
        Joint("revolute", "rocker", None, (0, 0, L / 2), (d, 0, 0), y, y, name="B0"),
        Joint("revolute", "crank", "coupler", (0, 0, -L / 2), (-d / 2, 0, 0), y, y, name="A1"),
        Joint("revolute", "rocker", "coupler", (0, 0, -L / 2), (d / 2, 0, 0), y, y, name="B1"),
    ]
    I_eff = (IA[1] + mA * (L / 2) ** 2) + (IB[1] + mB * (L / 2) ** 2) + mC * L**2
    k = mA * L / 2 + mB * L / 2 + mC * L
    return bodies, joints, I_eff, k


def bricard(radius: float = 0.01):
    """Bricard's mechanism as in the IFToMM benchmark A04 (Gonzalez et al., Multibody Syst.
    Dyn. 2006): five rods of 1 m and 1 kg between the points (0,0,0), (1,0,0), (1,-1,0),
    (1,-1,1), (0,-1,1), (0,0,1), the last two points and the first tied to the ground by
    revolute joints, six revolute joints whose axes are perpendicular to the two links they
    join; gravity along -y (give ``gravity=(0, -9.81, 0)``), from rest. Thirty joint rows of
    rank 29 (one redundant), one degree of freedom. The rods get a radius (axial moment
    m r^2/2, transverse m L^2/12 + m r^2/4) because the integrator refuses thin rods; their
    axial spin is locked by the joints anyway. Returns (bodies, joints)."""
    P = np.array([(0, 0, 0), (1, 0, 0), (1, -1, 0), (1, -1, 1), (0, -1, 1), (0, 0, 1)], float)
    m, L, r = 1.0, 1.0, radius
    It, Ia = m * L**2 / 12 + m * r**2 / 4, m * r**2 / 2
    bodies = []
    for k in range(5):
        e3 = (P[k + 1] - P[k]) / L
        a = np.array([1.0, 0, 0]) if abs(e3[0]) < 0.9 else np.array([0, 1.0, 0])
        e1 = np.cross(a, e3)
        e1 /= np.linalg.norm(e1)
        R = np.column_stack([e1, np.cross(e3, e1), e3])
        bodies.append(Body(f"rod{k + 1}", m, (It, It, Ia), (P[k] + P[k + 1]) / 2, R))
    down, up = (0, 0, -L / 2), (0, 0, L / 2)
    ax = np.cross(P[0] - P[5], P[1] - P[0])
    joints = [Joint("revolute", "rod1", None, down, P[0], bodies[0].rotation.T @ ax, ax)]
    for k in range(1, 5):
        ax = np.cross(P[k] - P[k - 1], P[k + 1] - P[k])
        joints.append(
            Joint("revolute", f"rod{k}", f"rod{k + 1}", up, down,
                  bodies[k - 1].rotation.T @ ax, bodies[k].rotation.T @ ax)
        )  # fmt: skip
    ax = np.cross(P[5] - P[4], P[0] - P[5])
    joints.append(Joint("revolute", "rod5", None, up, P[5], bodies[4].rotation.T @ ax, ax))
    return bodies, joints
