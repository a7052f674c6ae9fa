"""Force elements of a system of bodies: a constant torque about a revolute joint's axis and a
linear spring-damper between two body points, read from a system file, and the quantities
every later stage measures them by (the one implementation: the reference, the metrics and
the energy use these functions or their formulas).

A system file may add (docs/scenarios.md, "Force elements")::

    [[torques]]                  # a constant torque about a revolute joint's axis
    joint = "motor"              # a revolute joint of the file (a tree joint or a closure)
    torque = 0.033               # N m: +torque about u = R_a axis_a on body_a, -torque on body_b

    [[springs]]                  # a linear spring-damper between two body points
    name = "spring"              # default "spring<index>"
    body_a = "lever"
    body_b = "ground"            # a body's name, or "ground"
    anchor_a = [0.0, 0.0, 0.0]   # in a's principal frame, relative to its centre of mass
    anchor_b = [0.0, 0.0, 0.0]   # in b's principal frame; for the ground a WORLD point
    stiffness = 4530.0           # k, N/m, >= 0
    damping = 0.0                # c, N s/m, >= 0
    rest_length = 0.07785        # l0, m, > 0

Forces. With p_a, p_b the two world points, l = |p_a - p_b| and e = (p_a - p_b) / l, the
spring pulls point a by F_a = -(k (l - l0) + c l') e and point b by -F_a (l' the rate of l).
A torque acts on body a as tau u and on body b (or the ground) as -tau u, u = R_a axis_a;
it does the work tau theta, theta the rotation of a relative to b about u since t = 0
(:func:`joint_angle`).

Energy. Springs store 1/2 k (l - l0)^2 and a torque's potential is -tau theta, so a system
without dampers conserves T + V_gravity + sum 1/2 k (l - l0)^2 - sum tau theta
(:func:`potential`); a damper (c > 0) dissipates it (:func:`dissipative`). Momentum: forces
between two bodies are internal; one to the ground is not (:func:`grounded`).

Refused: a torque on a joint that is not revolute or does not exist, a spring of rest length
<= 0 or of length 0 at t = 0 (its direction is undefined), negative or non-finite k, c, an
element with nothing to do (k = c = 0, tau = 0), a spring from a body to itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.model import frozen

_TORQUE_KEYS = {"joint": "str", "torque": "number"}
_SPRING_KEYS = {
    "name": "name",
    "body_a": "str",
    "body_b": "str",
    "anchor_a": "vec3",
    "anchor_b": "vec3",
    "stiffness": "number",
    "damping": "number",
    "rest_length": "number",
}
_SPRING_REQUIRED = ("body_a", "body_b", "anchor_a", "anchor_b", "rest_length")
#: a spring's length at t = 0 must exceed this fraction of the system's size (its direction
#: is that of p_a - p_b)
MIN_LENGTH = 1e-9


@dataclass(frozen=True, eq=False)
class JointTorque:
    """A constant torque ``torque`` (N m) about the axis of the revolute joint ``joint``
    (module docstring)."""

    joint: str
    torque: float

    def __post_init__(self):
        object.__setattr__(self, "torque", float(self.torque))

    def to_dict(self) -> dict:
        return {"joint": self.joint, "torque": self.torque}


@dataclass(frozen=True, eq=False)
class Spring:
    """A linear spring-damper between ``anchor_a`` on ``body_a`` and ``anchor_b`` on
    ``body_b`` (None: the ground, ``anchor_b`` a world point): ``stiffness`` k (N/m),
    ``damping`` c (N s/m), ``rest_length`` l0 (m) (module docstring)."""

    name: str
    body_a: str
    body_b: str | None
    anchor_a: np.ndarray
    anchor_b: np.ndarray
    stiffness: float
    damping: float
    rest_length: float

    def __post_init__(self):
        object.__setattr__(self, "anchor_a", frozen(self.anchor_a))
        object.__setattr__(self, "anchor_b", frozen(self.anchor_b))
        for k in ("stiffness", "damping", "rest_length"):
            object.__setattr__(self, k, float(getattr(self, k)))

    def to_dict(self) -> dict:
        return {"name": self.name, "body_a": self.body_a, "body_b": self.body_b,
                "anchor_a": self.anchor_a.tolist(), "anchor_b": self.anchor_b.tolist(),
                "stiffness": self.stiffness, "damping": self.damping,
                "rest_length": self.rest_length}  # fmt: skip


def read_force_elements(data: dict, bodies, joints, bad, typed) -> tuple[tuple, tuple]:
    """``(torques, springs)`` of a system file's ``[[torques]]`` and ``[[springs]]``; every
    problem through ``bad(field, value, rule)``. ``bodies`` and ``joints`` are the file's, read
    already (their states: a spring's length at t = 0 is checked); ``typed(table, keys,
    required, prefix, bad)`` the file reader's check of a table's fields and types."""
    names = {b.name: b for b in bodies}
    by_joint = {j.name: j for j in joints}
    known = ", ".join(sorted(names)[:20]) + (" ..." if len(names) > 20 else "")
    torques = []
    for i, tab in enumerate(_array(data, "torques", bad)):
        p = f"torques[{i}]"
        good = typed(tab, _TORQUE_KEYS, ("joint", "torque"), p, bad)
        jn, tau = good.get("joint"), good.get("torque")
        j = by_joint.get(jn)
        if jn is not None and j is None:
            bad(f"{p}.joint", jn, "not a joint of this file; joints: "
                + ", ".join(sorted(by_joint)[:20]))  # fmt: skip
        elif j is not None and j.kind != "revolute":
            bad(f"{p}.joint", jn, f"joint {jn!r} is {j.kind}: a torque acts about a revolute "
                "joint's axis")  # fmt: skip
        if tau is not None and not tau != 0:
            bad(f"{p}.torque", tau, "a torque of 0 does nothing: leave the element out")
        if j is not None and j.kind == "revolute" and tau is not None and tau != 0:
            torques.append(JointTorque(jn, tau))
    springs = []
    seen = set()
    for i, tab in enumerate(_array(data, "springs", bad)):
        p = f"springs[{i}]"
        good = typed(tab, _SPRING_KEYS, _SPRING_REQUIRED, p, bad)
        name = good.get("name", f"spring{i}")
        if name in seen:
            bad(f"{p}.name", name, "spring names must be unique")
        seen.add(name)
        a, b = good.get("body_a"), good.get("body_b")
        ok = True
        if a is not None and a not in names:
            bad(f"{p}.body_a", a, f"not a body of this file; bodies: {known}")
            ok = False
        if b is not None and b != "ground" and b not in names:
            bad(f"{p}.body_b", b, f"not a body of this file nor 'ground'; bodies: {known}")
            ok = False
        if a is not None and a == b:
            bad(f"{p}.body_b", b, "a spring joins two different bodies (or a body and 'ground')")
            ok = False
        k, c = good.get("stiffness", 0.0), good.get("damping", 0.0)
        l0 = good.get("rest_length")
        for f, v in (("stiffness", k), ("damping", c)):
            if not v >= 0:
                bad(f"{p}.{f}", v, "must be >= 0")
                ok = False
        if ok and k == 0 and c == 0:
            bad(f"{p}.stiffness", k, "stiffness and damping are both 0: the spring does nothing")
            ok = False
        if l0 is not None and not l0 > 0:
            bad(f"{p}.rest_length", l0, "must be > 0")
            ok = False
        if not ok or None in (a, b, l0) or "anchor_a" not in good or "anchor_b" not in good:
            continue
        s = Spring(name, a, None if b == "ground" else b, np.array(good["anchor_a"], float),
                   np.array(good["anchor_b"], float), k, c, l0)  # fmt: skip
        x = np.array([q.position for q in bodies])[None]
        R = np.array([q.rotation for q in bodies])[None]
        length = float(spring_length(bodies, s, x, R)[0][0])
        size = max(1.0, float(np.max(np.abs(x))))
        if not length > MIN_LENGTH * size:
            bad(f"{p}.anchor_b", good["anchor_b"], f"spring {name!r} has length {length:.3g} "
                "m at t = 0: its direction (p_a - p_b) is undefined; its points must "
                "differ")  # fmt: skip
            continue
        springs.append(s)
    return tuple(torques), tuple(springs)


def _array(data, key, bad) -> list:
    v = data.get(key)
    if v is None:
        return []
    if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
        bad(key, v, f"must be an array of [[{key}]] tables")
        return []
    return v


def _points(bodies, spring, x, R, v=None, W=None, index=None):
    idx = index if index is not None else {b.name: i for i, b in enumerate(bodies)}
    x = np.asarray(x, dtype=float)
    R = np.asarray(R, dtype=float)
    ia = idx[spring.body_a]
    ra = R[:, ia] @ spring.anchor_a
    pa = x[:, ia] + ra
    if spring.body_b is None:
        pb = np.broadcast_to(spring.anchor_b, pa.shape)
        rb = None
    else:
        ib = idx[spring.body_b]
        rb = R[:, ib] @ spring.anchor_b
        pb = x[:, ib] + rb
    if v is None:
        return pa, pb, None, None
    v = np.asarray(v, dtype=float)
    W = np.asarray(W, dtype=float)
    va = v[:, ia] + np.cross(np.einsum("nij,nj->ni", R[:, ia], W[:, ia]), ra)
    if rb is None:
        vb = np.zeros_like(va)
    else:
        vb = v[:, ib] + np.cross(np.einsum("nij,nj->ni", R[:, ib], W[:, ib]), rb)
    return pa, pb, va, vb


def spring_length(bodies, spring, x, R, v=None, W=None, index=None):
    """(l (n,), l' (n,) or None): the spring's length (m) and its rate (m/s, with ``v`` and
    ``W``) at a stack of states x (n, nb, 3), R (n, nb, 3, 3), v (n, nb, 3), W (n, nb, 3)
    (body axes), bodies in the order of ``bodies``."""
    pa, pb, va, vb = _points(bodies, spring, x, R, v, W, index)
    d = pa - pb
    length = np.linalg.norm(d, axis=1)
    if va is None:
        return length, None
    return length, np.einsum("ni,ni->n", d, va - vb) / length


def _reference_vectors(bodies, joint, index):
    """(axis in a, m in b, p in a): m a unit vector of b perpendicular to b's axis and p the
    vector of a that coincides with it at t = 0 (both in their body's frame)."""
    ia = index[joint.body_a]
    Ra0 = bodies[ia].rotation
    Rb0 = np.eye(3) if joint.body_b is None else bodies[index[joint.body_b]].rotation
    nb = np.asarray(joint.axis_b, dtype=float) / np.linalg.norm(joint.axis_b)
    k = int(np.argmin(np.abs(nb)))
    e = np.zeros(3)
    e[k] = 1.0
    m = np.cross(nb, e)
    m /= np.linalg.norm(m)
    p = Ra0.T @ (Rb0 @ m)
    na = np.asarray(joint.axis_a, dtype=float) / np.linalg.norm(joint.axis_a)
    return na, m, p


def joint_angle(bodies, joint, R, index=None) -> np.ndarray:
    """theta (n,), rad: the rotation of ``joint``'s body a relative to its body b about the
    axis u = R_a axis_a since the scenario's t = 0, at the stack of attitudes R (n, nb, 3, 3)
    of one run in time order: the angle about u from a vector of b perpendicular to the axis
    to the vector of a that coincided with it at t = 0, unwrapped along the stack (a turn of
    more than pi between two states is miscounted; :func:`angle_steps_ok` tells)."""
    idx = index if index is not None else {b.name: i for i, b in enumerate(bodies)}
    R = np.asarray(R, dtype=float)
    na, m, p = _reference_vectors(bodies, joint, idx)
    Ra = R[:, idx[joint.body_a]]
    Rb = np.broadcast_to(np.eye(3), Ra.shape) if joint.body_b is None else R[:, idx[joint.body_b]]
    u = Ra @ na
    mw = Rb @ m
    pw = Ra @ p
    s = np.einsum("ni,ni->n", u, np.cross(mw, pw))
    c = np.einsum("ni,ni->n", mw, pw)
    return np.unwrap(np.arctan2(s, c))


def angle_steps_ok(theta) -> bool:
    """True when no two consecutive angles of :func:`joint_angle` differ by more than pi/2
    (a count of turns that sampling cannot have confused)."""
    return bool(np.all(np.abs(np.diff(theta)) <= 0.5 * math.pi))


def potential(scenario, x, R) -> np.ndarray:
    """sum 1/2 k (l - l0)^2 - sum tau theta over the force elements, J, (n,), at a stack of
    states of one run in time order (module docstring)."""
    n = np.asarray(x).shape[0]
    V = np.zeros(n)
    if not has_elements(scenario):
        return V
    bodies = scenario.bodies
    idx = {b.name: i for i, b in enumerate(bodies)}
    for s in scenario.springs:
        length, _ = spring_length(bodies, s, x, R, index=idx)
        V += 0.5 * s.stiffness * (length - s.rest_length) ** 2
    by = {j.name: j for j in scenario.joints}
    for t in scenario.torques:
        V -= t.torque * joint_angle(bodies, by[t.joint], R, idx)
    return V


def _mv(R, a):
    """R a for a 3x3 R and a 3-vector a, as plain floats (3-vectors cost more through NumPy
    than through Python's own arithmetic)."""
    return (R[0][0] * a[0] + R[0][1] * a[1] + R[0][2] * a[2],
            R[1][0] * a[0] + R[1][1] * a[1] + R[1][2] * a[2],
            R[2][0] * a[0] + R[2][1] * a[1] + R[2][2] * a[2])  # fmt: skip


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def body_loads(scenario, x, R, v, W, index=None) -> tuple[np.ndarray, np.ndarray]:
    """(F (nb, 3), T (nb, 3)): the force elements' resultant force on each body (world, N,
    acting at its centre of mass) and their moment about its centre of mass (world, N m), at one
    state x (nb, 3), R (nb, 3, 3), v (nb, 3), W (nb, 3) (body axes), bodies in the order of
    ``scenario.bodies``: a spring's F_a at p_a is F_a on a and (p_a - x_a) x F_a about its
    centre, -F_a at p_b on b; a torque is the couple tau u on a and -tau u on b (module
    docstring). What an engine without force elements of its own applies at each evaluation
    (each step or stage, so it is written on plain floats); the ground's share is dropped.
    Only the states of :func:`loaded_bodies` are read (the others' rows may hold anything)."""
    bodies = scenario.bodies
    idx = index if index is not None else {b.name: i for i, b in enumerate(bodies)}
    x, R = np.asarray(x, dtype=float).tolist(), np.asarray(R, dtype=float).tolist()
    v, W = np.asarray(v, dtype=float).tolist(), np.asarray(W, dtype=float).tolist()
    F = [[0.0, 0.0, 0.0] for _ in bodies]
    T = [[0.0, 0.0, 0.0] for _ in bodies]

    def point(i, anchor):  # a body point's position, velocity and arm from the centre
        r = _mv(R[i], anchor)
        w = _mv(R[i], W[i])
        wr = _cross(w, r)
        return ([x[i][k] + r[k] for k in range(3)], [v[i][k] + wr[k] for k in range(3)], r)

    for s in getattr(scenario, "springs", ()):
        ia = idx[s.body_a]
        # the anchors as floats: NumPy's scalars would carry through every product below
        pa, va, ra = point(ia, s.anchor_a.tolist())
        if s.body_b is None:
            pb, vb, rb = s.anchor_b.tolist(), [0.0, 0.0, 0.0], None
        else:
            ib = idx[s.body_b]
            pb, vb, rb = point(ib, s.anchor_b.tolist())
        d = [pa[k] - pb[k] for k in range(3)]
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        e = [c / length for c in d]
        rate = sum(e[k] * (va[k] - vb[k]) for k in range(3))
        f = -(s.stiffness * (length - s.rest_length) + s.damping * rate)
        Fa = (f * e[0], f * e[1], f * e[2])
        _add(F[ia], Fa)
        _add(T[ia], _cross(ra, Fa))
        if rb is not None:
            _sub(F[ib], Fa)
            _sub(T[ib], _cross(rb, Fa))
    by = {j.name: j for j in scenario.joints}
    for t in getattr(scenario, "torques", ()):
        j = by[t.joint]
        ia = idx[j.body_a]
        n = math.sqrt(sum(float(c) * float(c) for c in j.axis_a))
        tu = [t.torque * c for c in _mv(R[ia], [float(c) / n for c in j.axis_a])]
        _add(T[ia], tu)
        if j.body_b is not None:
            _sub(T[idx[j.body_b]], tu)
    return np.array(F), np.array(T)


def _add(acc, a):
    acc[0] += a[0]
    acc[1] += a[1]
    acc[2] += a[2]


def _sub(acc, a):
    acc[0] -= a[0]
    acc[1] -= a[1]
    acc[2] -= a[2]


def loaded_bodies(scenario, index=None) -> tuple[int, ...]:
    """The bodies (indices in the order of ``scenario.bodies``, ascending) the force elements
    act on: a spring's two, a torque's joint's two, the ground left out. :func:`body_loads`
    reads their states alone and gives every other body no load."""
    idx = index if index is not None else {b.name: i for i, b in enumerate(scenario.bodies)}
    by = {j.name: j for j in scenario.joints}
    ends = [(s.body_a, s.body_b) for s in getattr(scenario, "springs", ())]
    ends += [(by[t.joint].body_a, by[t.joint].body_b) for t in getattr(scenario, "torques", ())]
    return tuple(sorted({idx[n] for pair in ends for n in pair if n is not None}))


def load_scale(scenario, length: float, rate: float) -> float:
    """N: the size of the loads the force elements can give in a system of length scale
    ``length`` (m) and rate scale ``rate`` (1/s): sum k L + c L rate over the springs plus
    sum |tau| / L over the torques. A check that compares loads (or their generalised forces)
    computed two ways compares them to a fraction of this, not of the loads themselves, which
    are rounding where a spring sits at its rest length."""
    f = sum(
        s.stiffness * length + s.damping * length * rate for s in getattr(scenario, "springs", ())
    )
    return f + sum(abs(t.torque) / length for t in getattr(scenario, "torques", ()))


def has_elements(scenario) -> bool:
    return bool(getattr(scenario, "torques", ()) or getattr(scenario, "springs", ()))


def dissipative(scenario) -> bool:
    """A damper dissipates the energy: there is no conserved energy to drift."""
    return any(s.damping > 0 for s in getattr(scenario, "springs", ()))


def grounded(scenario) -> bool:
    """Some force element acts between a body and the ground (the momenta are not
    conserved)."""
    by = {j.name: j for j in scenario.joints}
    return any(s.body_b is None for s in getattr(scenario, "springs", ())) or any(
        by[t.joint].body_b is None for t in getattr(scenario, "torques", ())
    )


def axis_inertia(scenario, torque) -> float:
    """I_eff (kg m^2) of a torque's joint: the kinetic energy of the system is at least
    1/2 I_eff theta'^2 (theta' the joint's rate). For a joint to the ground, body a turns
    about the fixed joint point O: T >= 1/2 w . I_O w >= 1/2 theta'^2 / (n . I_O^-1 n); between
    two bodies, each body's rotation alone, T >= 1/2 (w_a . n)^2 / (n . I_a^-1 n) + the same
    of b, smallest over w_a - w_b = theta' n: I_a' I_b' / (I_a' + I_b')."""
    by = {b.name: b for b in scenario.bodies}
    j = next(j for j in scenario.joints if j.name == torque.joint)
    a = by[j.body_a]
    n = a.rotation @ (np.asarray(j.axis_a, dtype=float) / np.linalg.norm(j.axis_a))

    def eff(b, about=None):
        I = b.rotation @ np.diag(b.inertia) @ b.rotation.T
        if about is not None:
            r = b.position - about
            I = I + b.mass * (float(r @ r) * np.eye(3) - np.outer(r, r))
        return 1.0 / float(n @ np.linalg.solve(I, n))

    if j.body_b is None:
        return eff(a, a.position + a.rotation @ np.asarray(j.anchor_a, dtype=float))
    ia, ib = eff(a), eff(by[j.body_b])
    return ia * ib / (ia + ib)


def energy_bound(scenario, e0: float) -> float:
    """The energy in play over the horizon with the force elements (J): e0 (the energy in
    play of the joints and gravity) plus the springs' initial energy (their lowest is 0), and
    with torques the bound sqrt(E) <= sqrt(E0) + sum |tau| t_end / sqrt(2 I_eff): the energy
    E = T + V - V_low grows at the torques' power tau theta' <= |tau| sqrt(2 E / I_eff)
    (:func:`axis_inertia`, T <= E)."""
    if not has_elements(scenario):
        return e0
    bodies = scenario.bodies
    x = np.array([b.position for b in bodies])[None]
    R = np.array([b.rotation for b in bodies])[None]
    e = e0
    for s in scenario.springs:
        length, _ = spring_length(bodies, s, x, R)
        e += 0.5 * s.stiffness * float(length[0] - s.rest_length) ** 2
    if scenario.torques:
        grow = sum(abs(t.torque) * scenario.t_end / math.sqrt(2.0 * axis_inertia(scenario, t))
                   for t in scenario.torques)  # fmt: skip
        e = (math.sqrt(e) + grow) ** 2
    return e


__all__ = [
    "JointTorque",
    "Spring",
    "angle_steps_ok",
    "axis_inertia",
    "body_loads",
    "loaded_bodies",
    "load_scale",
    "dissipative",
    "energy_bound",
    "grounded",
    "has_elements",
    "joint_angle",
    "potential",
    "read_force_elements",
    "spring_length",
]
