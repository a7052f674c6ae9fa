"""The validated, typed form of a scenario file.

A :class:`Scenario` is what every later stage receives: engines build their models from it,
references compute exact solutions from it, metrics read its inertia and conserved quantities.
It is immutable and carries a content hash (``scenario_hash``) that travels with every result.

Conventions (SI units throughout):

- ``inertia``: principal moments of inertia about the centre of mass, kg m^2, in body axes
  (body axes are the principal axes).
- ``rotation``: body-to-world rotation matrix R at t = 0, so a body vector b has world
  coordinates R b. Its columns are the directors d1, d2, d3.
- ``omega_body``: angular velocity W in body axes, rad/s. The world angular velocity is w = R W.
- ``position``/``velocity``: centre of mass x_G and its velocity v_G in world axes, m and m/s.
- ``pivot``: for a pivoted body, the fixed point's position in body axes relative to the centre
  of mass, m. The fixed point is the world origin, so x_G = -R pivot at all times.
- ``gravity``: uniform gravitational acceleration g in world axes, m/s^2; V = -m g . x_G.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field

import numpy as np

from scenarios.metric_catalog import BOUNDED

#: The kinds of scene, each declared by its scenario as ``sc.kind``: what steps a run of it,
#: which references measure it, which metrics and figures it has. ``body``: one rigid body
#: (:class:`Scenario`); ``system``: bodies tied by joints; ``contact``: bodies whose listed
#: pairs may touch (both :class:`scenarios.system.SystemScenario`).
SCENE_KINDS = ("body", "system", "contact")

#: Reference kinds a scenario may request; "auto" lets the suite pick (see references).
REFERENCE_KINDS = ("auto", "free_body", "lagrange_top", "steady_precession", "numerical")

#: Reference kinds whose motion is a relative equilibrium: a steady rotation (a top in steady
#: precession, a straight chain spinning about a principal axis, a conical pendulum). On such
#: a motion the leading term of an integrator's error may vanish (joint rates are constant,
#: so a reduced-coordinate Euler step is exact up to its attitude update), and an order fitted
#: there may exceed the integrator's generic one without anything being wrong.
RELATIVE_EQUILIBRIA = ("steady_precession", "spinning_chain", "conical_pendulum")

#: Metrics a ``[tolerances]`` table may bound: every error (lower is better) of the metric
#: catalog (:mod:`scenarios.metric_catalog`; docs/results.md)
TOLERANCE_METRICS = BOUNDED


def frozen(a) -> np.ndarray:
    """``a`` as a read-only float array (a copy)."""
    arr = np.array(a, dtype=float)
    arr.setflags(write=False)
    return arr


class RunFields:
    """What a scenario of one body (:class:`Scenario`) and of a system
    (:class:`scenarios.system.SystemScenario`) share: the run settings (``t_end``, ``dt``,
    ``dt_sweep``, ``save_every``, ``accuracies``), ``tags`` and ``tolerances`` held as plain
    values, their part of the identity, the hash of that identity and copies with fields
    changed. A subclass provides :meth:`to_dict`."""

    def _normalise_run(self) -> None:
        """The run settings, tags and tolerances as floats, tuples and plain dicts, so that code
        building a scenario by hand gets the same object a file would give."""
        object.__setattr__(self, "dt_sweep", tuple(float(h) for h in self.dt_sweep))
        object.__setattr__(self, "accuracies", tuple(float(a) for a in self.accuracies))
        object.__setattr__(self, "tags", tuple(self.tags))
        object.__setattr__(self, "t_end", float(self.t_end))
        object.__setattr__(self, "dt", float(self.dt))
        object.__setattr__(
            self,
            "tolerances",
            {str(f): {str(k): float(v) for k, v in b.items()} for f, b in self.tolerances.items()},
        )

    def _run_dict(self) -> dict:
        """The ``run`` part of :meth:`to_dict`."""
        return {
            "t_end": self.t_end,
            "dt": self.dt,
            "dt_sweep": list(self.dt_sweep),
            "save_every": self.save_every,
            "accuracies": list(self.accuracies),
        }

    @property
    def scenario_hash(self) -> str:
        """First 12 hex digits of the SHA-256 of the content that determines a result: every
        field of :meth:`to_dict` but the description (for one body: name, body, initial state,
        environment, run settings, reference kind, tolerances; a system adds its joints, the
        reference's parameters and the engine settings; a robot model its file's content,
        ``model.sha256``, not where the file lies). Text fields other than the name do not
        count: the same scenario has the same hash in every checkout and on every machine."""
        d = self.to_dict()
        d.pop("description")
        if isinstance(d.get("model"), dict):
            d["model"] = {k: v for k, v in d["model"].items() if k != "file"}
        blob = json.dumps(d, sort_keys=True, separators=(",", ":")).encode()
        return hashlib.sha256(blob).hexdigest()[:12]

    def replace(self, **changes):
        """A copy with some fields changed (e.g. ``t_end`` from the command line)."""
        import dataclasses

        return dataclasses.replace(self, **changes)


@dataclass(frozen=True, eq=False)
class Scenario(RunFields):
    """One validated scenario. Build it with :func:`scenarios.load` or directly in code.

    Array fields are read-only float arrays: ``inertia`` (3,), ``rotation`` (3, 3),
    ``omega_body`` (3,), ``position`` (3,), ``velocity`` (3,), ``gravity`` (3,),
    ``pivot`` (3,) or None. ``dt_sweep`` is a tuple of step sizes (may be empty).
    """

    name: str
    description: str
    mass: float
    inertia: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    t_end: float
    dt: float
    position: np.ndarray = field(default_factory=lambda: frozen(np.zeros(3)))
    velocity: np.ndarray = field(default_factory=lambda: frozen(np.zeros(3)))
    gravity: np.ndarray = field(default_factory=lambda: frozen(np.zeros(3)))
    pivot: np.ndarray | None = None
    dt_sweep: tuple[float, ...] = ()
    save_every: int = 1
    #: target accuracies of error-controlled integrators (empty: the suite's default)
    accuracies: tuple[float, ...] = ()
    reference: str = "auto"
    #: verdict bounds from the file's ``[tolerances]`` table: {"*" or family: {metric: bound}}
    tolerances: dict = field(default_factory=dict)
    source: str = ""
    tags: tuple[str, ...] = ()
    path: str | None = None

    #: the scene's kind (:data:`SCENE_KINDS`)
    kind = "body"
    #: a single body has no joints, so no loop closures
    loop_joints = ()
    #: the scene's number of bodies
    n_bodies = 1

    def __post_init__(self):
        # Normalise containers so that code building a Scenario by hand gets the same object a
        # file would give; physical validation lives in scenarios.schema.
        for name in ("inertia", "rotation", "omega_body", "position", "velocity", "gravity"):
            object.__setattr__(self, name, frozen(getattr(self, name)))
        if self.pivot is not None:
            object.__setattr__(self, "pivot", frozen(self.pivot))
            # With a pivot the centre of mass is not free: it follows from the rotation.
            R = self.rotation
            W = self.omega_body
            x = -R @ self.pivot
            v = -R @ np.cross(W, self.pivot)
            object.__setattr__(self, "position", frozen(x))
            object.__setattr__(self, "velocity", frozen(v))
        object.__setattr__(self, "mass", float(self.mass))
        self._normalise_run()

    # -- derived facts used by references and metrics --------------------------------------
    @property
    def pivoted(self) -> bool:
        return self.pivot is not None

    @property
    def has_gravity(self) -> bool:
        return bool(np.any(self.gravity != 0.0))

    @property
    def vertical(self) -> np.ndarray | None:
        """The scenario's own vertical, up = -g/|g| (world axes, unit), or None without
        gravity. Observables of tops (tilt, nutation, precession) are measured about it."""
        gn = float(np.linalg.norm(self.gravity))
        if gn == 0.0:
            return None
        return frozen(-self.gravity / gn)

    @property
    def symmetric_axis(self) -> int | None:
        """Index of the body axis of symmetry, or None
        (:func:`director_model.body.symmetric_axis`)."""
        from director_model.body import symmetric_axis

        return symmetric_axis(self.inertia)

    @property
    def top_axis(self) -> int | None:
        """For a pivoted body: the body axis through the pivot and the centre of mass about
        which the moments about the pivot are symmetric (the spin axis of a Lagrange top), or
        None. A body with equal moments about its centre of mass (the library's cone top) has
        one all the same: the line from the pivot to its centre of mass."""
        if self.pivot is None:
            return None
        on_axis = [k for k in range(3) if self.pivot[k] != 0.0]
        if len(on_axis) != 1:
            return None  # pivot at the centre of mass or off the principal axes
        k = on_axis[0]
        i, j = [a for a in range(3) if a != k]
        I = np.diag(self.pivot_inertia)
        return k if I[i] == I[j] else None

    @property
    def pivot_inertia(self) -> np.ndarray:
        """3x3 inertia tensor about the fixed point in body axes: I + m(|c|^2 1 - c c^T)."""
        c = self.pivot if self.pivot is not None else np.zeros(3)
        return np.diag(self.inertia) + self.mass * (c @ c * np.eye(3) - np.outer(c, c))

    # -- physical scales of the metrics -----------------------------------------------------
    @property
    def energy_scale(self) -> float:
        """Characteristic energy E_c (J) that energy drifts are divided by: the energy in play
        over the horizon.

        - pivoted body: max(T0, m |g| l), the larger of the initial kinetic energy and the
          weight times the pivot to centre-of-mass distance l (the potential ranges over
          [-m|g|l, m|g|l]);
        - free body: the rotational energy 1/2 W.IW (conserved) plus
          :attr:`translational_energy_scale`, the largest translational kinetic energy over
          the horizon (the initial one plus what gravity hands over: a body falling from rest
          for t_end has m |g|^2 t_end^2/2 in play).

        Never the initial total energy E0, which depends on where the potential's zero is and
        is 0 for a pendulum released from rest with its axis horizontal. 1 J if it is 0 (a
        body at rest with no force on it).
        """
        W = self.omega_body
        t0 = 0.5 * float(W @ (self.pivot_inertia @ W))
        if self.pivot is None:
            e = t0 + self._translational_in_play()
        else:
            length = float(np.linalg.norm(self.pivot))
            e = max(t0, self.mass * float(np.linalg.norm(self.gravity)) * length)
        return e if e > 0 else 1.0

    def _translational_in_play(self) -> float:
        """1/2 m max_t |v_G(t)|^2 over [0, t_end] on the parabola v_G = v0 + g t (|v_G|^2 is
        convex in t: the larger of its end values), J."""
        v1 = self.velocity + self.gravity * self.t_end
        return 0.5 * self.mass * max(float(self.velocity @ self.velocity), float(v1 @ v1))

    @property
    def rotational_energy_scale(self) -> float:
        """The part of :attr:`energy_scale` that can be in rotation (J), the scale of
        ``energy_drift_rot_max``: the rotational energy 1/2 W.IW for a free body (it is
        conserved; :attr:`energy_scale` if it is 0), all of :attr:`energy_scale` for a
        pivoted one."""
        if self.pivot is None:
            W = self.omega_body
            e = 0.5 * float(W @ (self.inertia * W))
            if e > 0:
                return e
        return self.energy_scale

    @property
    def translational_energy_scale(self) -> float:
        """The part of :attr:`energy_scale` in the motion of the centre of mass (J), the scale
        of ``energy_drift_trans_max``: for a free body the largest translational kinetic
        energy over the horizon, 1/2 m max(|v0|^2, |v0 + g t_end|^2) (:attr:`energy_scale`
        if it is 0); all of :attr:`energy_scale` for a pivoted one."""
        if self.pivot is None:
            e = self._translational_in_play()
            if e > 0:
                return e
        return self.energy_scale

    @property
    def energy_scales(self) -> dict[str, float]:
        """The scale of each separately conserved part of the energy
        (:func:`references.trajectory.energy_parts`): ``"total"`` always, ``"rot"`` and
        ``"trans"`` for a free body."""
        scales = {"total": self.energy_scale}
        if self.pivot is None:
            scales["rot"] = self.rotational_energy_scale
            scales["trans"] = self.translational_energy_scale
        return scales

    @property
    def momentum_scale(self) -> float:
        """Characteristic angular momentum L_c = sqrt(2 E_rot I_max) (kg m^2/s) that momentum
        drifts are divided by: the largest |L| a body with the rotational energy scale can
        have (|L|^2 = |I W|^2 <= I_max W.IW). Equals |L0| for a spin about the major axis and
        is never 0 when |L0| is (a pendulum released from rest has L0 = 0)."""
        lam = float(np.max(np.linalg.eigvalsh(self.pivot_inertia)))
        return math.sqrt(2.0 * self.rotational_energy_scale * lam)

    @property
    def rate_scale(self) -> float:
        """Characteristic angular rate w_c = sqrt(2 E_rot / I_min) (rad/s): the largest |W|
        a body with the rotational energy scale can reach."""
        lam = float(np.min(np.linalg.eigvalsh(self.pivot_inertia)))
        return math.sqrt(2.0 * self.rotational_energy_scale / lam)

    def to_dict(self) -> dict:
        """A plain-data description (lists and numbers), the basis of the hash."""
        d = {
            "name": self.name,
            "description": self.description,
            "body": {"mass": self.mass, "inertia": self.inertia.tolist()},
            "initial": {
                "rotation": self.rotation.tolist(),
                "omega_body": self.omega_body.tolist(),
            },
            "environment": {"gravity": self.gravity.tolist()},
            "run": self._run_dict(),
            "reference": self.reference,
            "tolerances": self.tolerances,
        }
        if self.pivot is None:
            d["initial"]["position"] = self.position.tolist()
            d["initial"]["velocity"] = self.velocity.tolist()
        else:
            d["environment"]["pivot"] = self.pivot.tolist()
        return d
