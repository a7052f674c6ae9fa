"""Systems of rigid bodies joined by joints (chains, trees, closed loops): the scenario
(:class:`SystemScenario`: its bodies, joints, environment, run, reference and tolerances), its
scales (length, energy, momentum, rate) and the joints' residuals (:func:`joint_residuals`,
the rule every check of a joint uses: the file's at t = 0, the metrics over a run).

The joint kinds (:data:`JOINT_KINDS`) have the names and meanings of
``director_model.system.Joint``; the reference kinds are :data:`SYSTEM_REFERENCE_KINDS`. The
spanning tree (:func:`scenarios.tree.spanning_tree`: from the ground outwards, breadth first;
a floating system from its first body) and the loop closures (every joint the tree does not
need) are kept with the scenario: :attr:`SystemScenario.tree_joints`,
:attr:`SystemScenario.loop_joints`. A system file is read by :mod:`scenarios.system_file`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from scenarios.model import RunFields, frozen
from scenarios.tree import spanning_tree

#: joint kinds (the same names and meanings as ``director_model.system.Joint``)
JOINT_KINDS = ("spherical", "fixed_point", "revolute", "universal", "cylindrical", "prismatic")
#: the kinds with a point constraint (anchor_a and anchor_b coincide)
POINT_KINDS = ("spherical", "fixed_point", "revolute", "universal")
#: kinds that need axes
AXIS_KINDS = ("revolute", "universal", "cylindrical", "prismatic")

#: reference kinds of a system: "auto" (numerical), the exact motions of
#: references.exact.multibody.exact, the reduced-coordinate DOP853 reference ("numerical":
#: the spanning tree's spherical and revolute joints, the loop closures and other joints as
#: constraint rows) and "none" (no independent reference: trajectory errors are not
#: measured, invariants and joint gaps are)
SYSTEM_CLOSED_FORMS = ("spinning_chain", "conical_pendulum", "four_bar", "n_four_bar")
#: the closed forms of bodies in contact (references.exact.contact); a scene with
#: ``[[contacts]]`` takes one of these or "none"
CONTACT_CLOSED_FORMS = (
    "sliding_block", "tipping_block", "rolling", "bounce", "resting", "hinged_strike",
)  # fmt: skip
SYSTEM_REFERENCE_KINDS = ("auto", *SYSTEM_CLOSED_FORMS, *CONTACT_CLOSED_FORMS, "numerical", "none")

#: a joint must hold at t = 0 to this, m for points and rad for axes: the tolerance of
#: director_model.system (INIT_TOL), so that a file accepted here runs there (files give
#: their numbers with 17 significant digits, whose rounding is ~1e-16 m)
JOINT_TOL = 1e-10


@dataclass(frozen=True, eq=False)
class SystemBody:
    """One body of a system, with exactly the fields of ``director_model.system.Body``."""

    name: str
    mass: float
    inertia: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray
    omega_body: np.ndarray
    #: the body's collision shape (:class:`scenarios.contact.Shape`), or None
    shape: object = None

    def __post_init__(self):
        for k in ("inertia", "position", "rotation", "velocity", "omega_body"):
            object.__setattr__(self, k, frozen(getattr(self, k)))
        object.__setattr__(self, "mass", float(self.mass))


@dataclass(frozen=True, eq=False)
class SystemJoint:
    """One joint, with exactly the fields of ``director_model.system.Joint``; ``body_b`` None
    is the ground (then ``anchor_b`` and ``axis_b`` are world coordinates)."""

    name: str
    kind: str
    body_a: str
    body_b: str | None
    anchor_a: np.ndarray
    anchor_b: np.ndarray
    axis_a: np.ndarray | None = None
    axis_b: np.ndarray | None = None

    def __post_init__(self):
        for k in ("anchor_a", "anchor_b", "axis_a", "axis_b"):
            v = getattr(self, k)
            if v is not None:
                object.__setattr__(self, k, frozen(v))


def system_inertia(bodies, about) -> np.ndarray:
    """3x3 inertia tensor of the bodies about the world point ``about`` in their initial
    configuration, kg m^2."""
    J = np.zeros((3, 3))
    for b in bodies:
        r = b.position - np.asarray(about, dtype=float)
        J += b.rotation @ np.diag(b.inertia) @ b.rotation.T
        J += b.mass * (float(r @ r) * np.eye(3) - np.outer(r, r))
    return J


@dataclass(frozen=True, eq=False)
class SystemScenario(RunFields):
    """A validated system scenario (build it with :func:`scenarios.load`).

    ``bodies`` and ``joints`` are tuples of :class:`SystemBody` and :class:`SystemJoint`;
    ``gravity`` (3,) m/s^2; run settings, ``reference``, ``tolerances``, ``source``, ``tags``
    and ``path`` as for one body (:class:`scenarios.model.Scenario`); ``reference_params``:
    the ``[reference]`` table's parameters of an exact motion (name -> number).
    ``tree_joints`` and ``loop_joints``: joint names of the spanning tree and of the loop
    closures (:func:`spanning_tree`)."""

    name: str
    description: str
    bodies: tuple
    joints: tuple
    t_end: float
    dt: float
    gravity: np.ndarray = field(default_factory=lambda: frozen(np.zeros(3)))
    dt_sweep: tuple[float, ...] = ()
    save_every: int = 1
    accuracies: tuple[float, ...] = ()
    reference: str = "auto"
    reference_params: dict = field(default_factory=dict)
    tolerances: dict = field(default_factory=dict)
    #: settings handed to one engine's builder, {engine: {name: value}} (``[engine_settings]``)
    engine_settings: dict = field(default_factory=dict)
    #: contact (:mod:`scenarios.contact`): static planes, the pairs that touch, constant forces
    planes: tuple = ()
    contacts: tuple = ()
    forces: tuple = ()
    #: force elements (:mod:`scenarios.force_elements`): constant joint torques, springs
    torques: tuple = ()
    springs: tuple = ()
    source: str = ""
    tags: tuple[str, ...] = ()
    path: str | None = None

    #: the single-body field (a system is tied to the ground by joints instead)
    pivot = None
    pivoted = False

    def __post_init__(self):
        object.__setattr__(self, "bodies", tuple(self.bodies))
        object.__setattr__(self, "joints", tuple(self.joints))
        object.__setattr__(self, "gravity", frozen(self.gravity))
        object.__setattr__(self, "reference_params", dict(self.reference_params))
        for k in ("planes", "contacts", "forces", "torques", "springs"):
            object.__setattr__(self, k, tuple(getattr(self, k)))
        self._normalise_run()
        st = spanning_tree(self.bodies, self.joints)
        object.__setattr__(self, "tree_joints", tuple(self.joints[k].name for k in st.tree))
        object.__setattr__(self, "loop_joints", tuple(self.joints[k].name for k in st.loops))

    # -- structure ------------------------------------------------------------------------
    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bodies)

    @property
    def n_bodies(self) -> int:
        return len(self.bodies)

    @property
    def has_contact(self) -> bool:
        """The scene lists pairs that may touch (``[[contacts]]``)."""
        return bool(self.contacts)

    @property
    def kind(self) -> str:
        """The scene's kind (:data:`scenarios.model.SCENE_KINDS`): ``contact`` when pairs may
        touch, else ``system``."""
        return "contact" if self.contacts else "system"

    @property
    def is_tree(self) -> bool:
        """No loop closure (every joint is in the spanning tree)."""
        return not self.loop_joints

    @property
    def floating(self) -> bool:
        """No joint to the ground: the total angular momentum about the centre of mass and
        the linear momentum less m_tot g t are conserved."""
        return all(j.body_b is not None for j in self.joints)

    @property
    def ground_point(self) -> np.ndarray | None:
        """The world point of the only joint to the ground when it is a point joint
        (spherical, fixed_point, revolute, universal), else None."""
        ground = [j for j in self.joints if j.body_b is None]
        if len(ground) == 1 and ground[0].kind in POINT_KINDS:
            return ground[0].anchor_b
        return None

    @property
    def has_gravity(self) -> bool:
        return bool(np.any(self.gravity != 0.0))

    @property
    def total_mass(self) -> float:
        return float(sum(b.mass for b in self.bodies))

    @property
    def centre_of_mass(self) -> np.ndarray:
        """The system's centre of mass at t = 0, world, m."""
        return sum(b.mass * b.position for b in self.bodies) / self.total_mass

    @property
    def length_scale(self) -> float:
        """The system's size (m): the largest distance between two of its centres of mass
        and joint points at t = 0 (a one-point system: its heaviest body's radius of
        gyration), never 0."""
        pts = [b.position for b in self.bodies]
        by = {b.name: b for b in self.bodies}
        for j in self.joints:
            a = by[j.body_a]
            pts.append(a.position + a.rotation @ j.anchor_a)
        P = np.array(pts)
        d = float(np.max(np.linalg.norm(P[:, None, :] - P[None, :, :], axis=2)))
        if d > 0:
            return d
        b = max(self.bodies, key=lambda b: b.mass)
        return math.sqrt(float(np.max(b.inertia)) / b.mass)

    # -- physical scales of the metrics ---------------------------------------------------
    def kinetic_energy0(self) -> float:
        """The initial kinetic energy, J."""
        return float(
            sum(
                0.5 * b.mass * float(b.velocity @ b.velocity)
                + 0.5 * float(b.omega_body @ (b.inertia * b.omega_body))
                for b in self.bodies
            )
        )

    @property
    def energy_scale(self) -> float:
        """E_c (J), never E0 (its zero is arbitrary): the energy in play, the largest kinetic
        energy the motion can reach, T0 + V0 - V_low, V_low bounded below over the
        configurations the joints allow; a part the joints do not hold up adds what gravity
        can give its centre of mass over the horizon (:func:`scenarios.energy.energy_in_play`).
        1 J if all of it is 0."""
        from scenarios.energy import energy_in_play

        return energy_in_play(self)

    @property
    def energy_scales(self) -> dict[str, float]:
        return {"total": self.energy_scale}

    @property
    def momentum_point(self) -> np.ndarray:
        """The point angular momentum is measured about: the ground's joint point (a single
        point joint to the ground), the centre of mass (floating), else the world origin."""
        p = self.ground_point
        if p is not None:
            return np.asarray(p, dtype=float)
        if self.floating:
            return self.centre_of_mass
        return np.zeros(3)

    @property
    def momentum_scale(self) -> float:
        """L_c = sqrt(2 E_c J_max) (kg m^2/s), J_max the largest principal moment of the
        system about :attr:`momentum_point` at t = 0: the largest angular momentum the
        system can have with the energy in play (never 0 when L0 is)."""
        J = system_inertia(self.bodies, self.momentum_point)
        return math.sqrt(2.0 * self.energy_scale * float(np.max(np.linalg.eigvalsh(J))))

    @property
    def linear_momentum_scale(self) -> float:
        """p_c = sqrt(2 m_tot E_c) (kg m/s): the largest linear momentum with that energy."""
        return math.sqrt(2.0 * self.total_mass * self.energy_scale)

    @property
    def rate_scale(self) -> float:
        """w_c = sqrt(2 E_c / I_min), I_min the smallest moment of any body (rad/s)."""
        imin = min(float(np.min(b.inertia)) for b in self.bodies)
        return math.sqrt(2.0 * self.energy_scale / imin)

    # -- identity -------------------------------------------------------------------------
    def to_dict(self) -> dict:
        def v(a):
            return None if a is None else np.asarray(a).tolist()

        bodies = [
            {k: (getattr(b, k) if k in ("name", "mass") else v(getattr(b, k)))
             for k in ("name", "mass", "inertia", "position", "rotation", "velocity",
                       "omega_body")}
            for b in self.bodies
        ]  # fmt: skip
        joints = [
            {"name": j.name, "kind": j.kind, "body_a": j.body_a, "body_b": j.body_b,
             "anchor_a": v(j.anchor_a), "anchor_b": v(j.anchor_b), "axis_a": v(j.axis_a),
             "axis_b": v(j.axis_b)}
            for j in self.joints
        ]  # fmt: skip
        for d, b in zip(bodies, self.bodies, strict=True):
            if b.shape is not None:  # only then: the hashes of scenes without contact stay
                d["shape"] = b.shape.to_dict()
        out = {
            "name": self.name,
            "description": self.description,
            "bodies": bodies,
            "joints": joints,
            "environment": {"gravity": v(self.gravity)},
            "run": self._run_dict(),
            "reference": self.reference,
            "reference_params": dict(self.reference_params),
            "tolerances": self.tolerances,
            "engine_settings": self.engine_settings,
        }
        if self.planes or self.contacts or self.forces:
            out["planes"] = [p.to_dict() for p in self.planes]
            out["contacts"] = [c.to_dict() for c in self.contacts]
            out["forces"] = [f.to_dict() for f in self.forces]
        if self.torques or self.springs:  # only then: the hashes of other scenes stay
            out["torques"] = [t.to_dict() for t in self.torques]
            out["springs"] = [s.to_dict() for s in self.springs]
        return out

    def magnitude_problems(self, t_end: float | None = None) -> list[tuple]:
        """See :func:`magnitude_problems`."""
        return magnitude_problems(self, t_end)


# -- validation ---------------------------------------------------------------------------------


def joint_residuals(bodies, joint, x, R, v=None, W=None, index=None) -> dict[str, np.ndarray]:
    """Violations of one joint at a stack of states, each (n,):

    ``"gap"`` (m): for a point joint |x_a + R_a anchor_a - x_b - R_b anchor_b|; for a
    cylindrical or prismatic joint the distance of point b from the line through point a
    along u_a; ``"angle"`` (rad): the angle between the axes u_a = R_a axis_a and
    u_b = R_b axis_b (revolute, cylindrical, prismatic; a prismatic joint's locked rotation
    about the axis is not measured), a universal joint's departure from perpendicular axes,
    0 for spherical joints; atan2 of cross and dot, accurate when small. With ``v``, ``W``
    also ``"gap_rate"`` (m/s): the relative velocity of the two anchor points (across the
    line for cylindrical and prismatic joints).

    ``x`` (n, nb, 3), ``R`` (n, nb, 3, 3), ``v`` (n, nb, 3), ``W`` (n, nb, 3, body axes) in
    the order of ``bodies``; the ground is x = 0, R = 1. The one implementation of the
    joints' rules: the file check and the metrics use it. ``index``: {body name: position in
    ``bodies``}, when the caller has it (one dict for all the joints of a large system).
    """
    idx = index if index is not None else {b.name: i for i, b in enumerate(bodies)}
    x = np.asarray(x, dtype=float)
    R = np.asarray(R, dtype=float)
    n = x.shape[0]
    ia = idx[joint.body_a]
    ra = R[:, ia] @ joint.anchor_a
    pa = x[:, ia] + ra
    if joint.body_b is None:
        rb = np.zeros_like(pa)
        pb = np.broadcast_to(joint.anchor_b, pa.shape)
        Rb = np.broadcast_to(np.eye(3), (n, 3, 3))
    else:
        ib = idx[joint.body_b]
        Rb = R[:, ib]
        rb = Rb @ joint.anchor_b
        pb = x[:, ib] + rb
    d = pb - pa
    out: dict[str, np.ndarray] = {}
    ua = R[:, ia] @ joint.axis_a if joint.axis_a is not None else None
    if joint.kind in POINT_KINDS:
        out["gap"] = np.linalg.norm(d, axis=1)
    else:
        out["gap"] = np.linalg.norm(d - np.einsum("ni,ni->n", d, ua)[:, None] * ua, axis=1)
    if joint.kind in AXIS_KINDS:
        ub = Rb @ joint.axis_b
        c = np.einsum("ni,ni->n", ua, ub)
        s = np.linalg.norm(np.cross(ua, ub), axis=1)
        out["angle"] = np.abs(np.arctan2(c, s)) if joint.kind == "universal" else np.arctan2(s, c)
    else:
        out["angle"] = np.zeros(n)
    if v is not None and W is not None:
        v = np.asarray(v, dtype=float)
        W = np.asarray(W, dtype=float)
        va = v[:, ia] + np.cross(np.einsum("nij,nj->ni", R[:, ia], W[:, ia]), ra)
        if joint.body_b is None:
            vb = np.zeros_like(va)
        else:
            vb = v[:, ib] + np.cross(np.einsum("nij,nj->ni", Rb, W[:, ib]), rb)
        rel = vb - va
        if ua is not None and joint.kind not in POINT_KINDS:
            rel = rel - np.einsum("ni,ni->n", rel, ua)[:, None] * ua
        out["gap_rate"] = np.linalg.norm(rel, axis=1)
    return out

    # fmt: skip


def magnitude_problems(sc: SystemScenario, t_end: float | None = None) -> list[tuple]:
    """Masses and moments within [1/MAX_MAGNITUDE, MAX_MAGNITUDE] and the energy scale over
    the horizon ``t_end`` below MAX_MAGNITUDE (as :func:`scenarios.schema.magnitude_problems`
    for one body)."""
    from scenarios.schema import MAX_MAGNITUDE as lim

    probs = []
    for i, b in enumerate(sc.bodies):
        for f, value in ((f"bodies[{i}].mass", b.mass),
                         (f"bodies[{i}].inertia", float(np.min(b.inertia)))):  # fmt: skip
            if not 1.0 / lim <= value <= lim:
                probs.append((f, value, f"must be in [{1 / lim:g}, {lim:g}] (SI units)"))
    sc2 = sc if t_end is None else sc.replace(t_end=float(t_end))
    with np.errstate(over="ignore", invalid="ignore"):
        e = sc2.energy_scale
    if not e <= lim:
        probs.append(("energy scale", e, f"above {lim:g} J: state the system in moderate units"))
    return probs
