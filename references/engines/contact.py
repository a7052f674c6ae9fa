"""Runs of bodies in contact: the suite's side of the contract with each engine's contact
builder ``references/engines/<engine>/contact.py``, which provides::

    CONFIGURATIONS: tuple[Integrator, ...]   # the contact configurations it offers
    SETTINGS: tuple[str, ...]                # the [engine_settings.<engine>] names it takes
    def simulate_contact(scenario, configuration: str, dt: float, nstep: int,
                         save_every: int, **settings) -> dict

returning what a system builder returns (``t``, ``x``, ``R``, ``v``, ``W``,
``engine_time_s``, ``settings``: :mod:`references.engines.system`) plus ``contacts``: the
engine's own contact points and forces at the saved steps (the step that ended there), as
arrays of shape (n, K) padded with NaN (``pair`` -1), K the most contacts seen at a step:

=============  ============  =====================================================================
``pair``       (n, K) int    index of the scene's contact pair (``scenario.contacts``), -1: none
``point``      (n, K, 3)     the contact point, world, m
``normal``     (n, K, 3)     unit normal pointing from the pair's ``b`` into its body ``a``
``force``      (n, K, 3)     the force on body ``a`` at the point, world, N (the engine's own:
                             a mean over the step, impulse / dt, for impulse-based engines)
``depth``      (n, K)        the engine's penetration depth (> 0 overlapping), m; NaN if not given
=============  ============  =====================================================================

and ``readback``: the model as the engine holds it, {pair index: {"mu": .., "e": ..}} and
{body name: {"shape": kind, "size": (..), "offset": (3,)}}, which :func:`check_readback`
compares with the scene. The suite computes every law residual from these forces and the saved
states (the contact points' velocities v + w x (p - x)), the same way for every engine
(:mod:`reports.metrics.contact`).

:class:`ContactLog` collects the rows step by step for a builder; :func:`pair_coefficients`
solves for per-body friction and restitution coefficients where an engine combines two
bodies' values into a pair's (DART: min and product; PyBullet: products; Drake: 2 a b/(a + b)).
"""

from __future__ import annotations

import importlib
import math
import time
from dataclasses import dataclass, field

import numpy as np

from references.engines import timing
from references.engines.integrators import Family, register_family
from references.engines.stepping import step_plan
from references.engines.system import _threaded
from references.errors import Diverged, EngineError, Unsupported
from references.trajectory import Trajectory

#: families of contact configurations: what the engines' contact solvers are (docs/engines.md)
CONTACT_FAMILIES = {
    "soft convex contact": "MuJoCo's and MJX's regularised convex contact (soft constraints)",
    "boxed LCP": "a linear complementarity problem with friction per tangent direction (DART)",
    "sequential impulses": "projected Gauss-Seidel on velocity impulses (Bullet)",
    "convex compliant contact": "Drake's discrete SAP, TAMSI and their variants",
    "Delassus NCP + suite": (
        "Pinocchio's ADMM and PGS on its Delassus operator, in the suite's Moreau-Jean loop"
    ),
    "exact-cone hard contact": "the director model's nonsmooth RATTLE with the exact Coulomb cone",
    "exact contact": "the closed form of the scene",
}
for _name, _text in CONTACT_FAMILIES.items():
    register_family(Family(_name, _text))

#: a run has diverged when a body has moved further from its start than this times the most
#: any motion of the scene could take it (its size, its initial speed times t, free fall and
#: the external forces' acceleration over t): a body thrown out of the scene by the solver
REACH_FACTOR = 2.0
#: the keys of a builder's ``contacts``
CONTACT_KEYS = ("pair", "point", "normal", "force", "depth")
#: the model read back must equal the scene's to this, relative to each quantity's size
READBACK_RTOL = 1e-9


def builder(engine: str):
    """The contact builder of ``engine`` (``references.engines.<engine>.contact``), or
    :class:`Unsupported` saying that the engine has none."""
    name = f"references.engines.{engine}.contact"
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name:
            raise
        raise Unsupported(
            f"{engine}: this engine has no contact builder (references/engines/{engine}/"
            "contact.py), so it runs no contact scene yet"
        ) from None


def configurations(engine: str) -> tuple:
    """The contact configurations ``engine`` offers (empty without a builder)."""
    try:
        return tuple(builder(engine).CONFIGURATIONS)
    except Unsupported:
        return ()


def builder_settings(engine: str) -> tuple[str, ...] | None:
    """The ``[engine_settings.<engine>]`` names ``engine``'s contact builder takes, or None."""
    try:
        return tuple(builder(engine).SETTINGS)
    except Unsupported:
        return None


def configuration(engine: str, name: str):
    """The configuration called ``name`` (display name or slug) of ``engine``."""
    from references.engines.integrators import slug

    for c in configurations(engine):
        if c.slug == slug(name):
            return c
    names = ", ".join(c.slug for c in configurations(engine)) or "none"
    raise Unsupported(f"{engine} has no contact configuration {name!r}; it offers: {names}")


def check_settings(engine: str, settings: dict, known) -> None:
    """Refuse a setting the builder does not take, naming it and the ones it takes."""
    bad = sorted(set(settings) - set(known))
    if bad:
        raise Unsupported(
            f"{engine} contact builder: no setting {', '.join(map(repr, bad))}; it takes: "
            f"{', '.join(known) or 'none'}"
        )


@dataclass
class ContactRunOutput:
    """A contact run's states, contacts and costs (``SystemRunOutput`` plus ``contacts``)."""

    trajectory: Trajectory
    contacts: dict
    nstep: int
    wall_time_s: float
    engine_time_s: float
    settings: dict
    readback: dict = field(default_factory=dict)
    evals_per_step: float = math.nan
    stats: dict = field(default_factory=dict)
    family: str = ""
    #: the stepping's timing (references.engines.timing), when the builder timed its engine
    #: calls on the run's stopwatch; None: its wall time stands
    timing: object = None

    @property
    def glue_time_s(self) -> float:
        return max(self.wall_time_s - self.engine_time_s, 0.0)


#: How far from 1 a logged normal's length may be: the engines give unit normals to rounding
#: (a few 1e-16); 1e-9 leaves room for a normal averaged over a surface and renormalised, and
#: catches a zero, NaN or unnormalised normal (an error of order 1).
NORMAL_UNIT_TOL = 1e-9


class ContactLog:
    """The contact rows of a run, one list per saved step (:meth:`add` then :meth:`save`),
    turned into the padded arrays of the module docstring by :meth:`arrays`."""

    def __init__(self):
        self.steps: list[list[tuple]] = []
        self.current: list[tuple] = []

    def add(self, pair: int, point, normal, force, depth=math.nan) -> None:
        """One contact of the current step: ``normal`` into the pair's body a, ``force`` on a.
        Copies: an engine's arrays (MuJoCo's contact frames) are views of memory it reuses.
        A row that is not finite, or whose normal is not a unit vector (to
        :data:`NORMAL_UNIT_TOL`), is refused naming the pair and the value: the law residuals
        are computed from these rows, and a NaN among them would pass silently."""
        row = (
            int(pair),
            np.array(point, dtype=float),
            np.array(normal, dtype=float),
            np.array(force, dtype=float),
            float(depth),
        )
        for name, value in zip(("point", "normal", "force"), row[1:4], strict=True):
            if value.shape != (3,) or not np.all(np.isfinite(value)):
                raise ValueError(
                    f"contact row of pair {row[0]}: {name} {value.tolist()} (rule: 3 finite values)"
                )
        if abs(float(np.linalg.norm(row[2])) - 1.0) > NORMAL_UNIT_TOL:
            raise ValueError(
                f"contact row of pair {row[0]}: normal {row[2].tolist()} has length "
                f"{float(np.linalg.norm(row[2])):.3g} (rule: a unit vector to {NORMAL_UNIT_TOL:g})"
            )
        self.current.append(row)

    def clear(self) -> None:
        """Forget the current step's rows (the engine's contacts are read after each step; only
        a saved step's are kept)."""
        self.current = []

    def save(self) -> None:
        self.steps.append(self.current)
        self.current = []

    def arrays(self) -> dict:
        n = len(self.steps)
        k = max([len(s) for s in self.steps] + [1])
        out = {
            "pair": np.full((n, k), -1, dtype=np.int64),
            "point": np.full((n, k, 3), np.nan),
            "normal": np.full((n, k, 3), np.nan),
            "force": np.full((n, k, 3), np.nan),
            "depth": np.full((n, k), np.nan),
        }
        for i, rows in enumerate(self.steps):
            for j, (p, x, nrm, f, d) in enumerate(rows):
                out["pair"][i, j] = p
                out["point"][i, j] = x
                out["normal"][i, j] = nrm
                out["force"][i, j] = f
                out["depth"][i, j] = d
        return out


class SavedStates:
    """The body states a contact builder saves: every ``save_every``-th step and the last,
    plus the initial state (``t``, centres ``x``, attitudes ``R``, centre velocities ``v``,
    body-frame angular velocities ``W``; one row per saved step, one column per body).
    The builders fill rows ``0..k-1`` and return :meth:`fields` of the rows filled (a run
    that stops early returns the rows it reached)."""

    def __init__(self, nstep: int, save_every: int, nbodies: int):
        n = nstep // save_every + (1 if nstep % save_every else 0) + 1
        self.t = np.zeros(n)
        self.x = np.zeros((n, nbodies, 3))
        self.R = np.zeros((n, nbodies, 3, 3))
        self.v = np.zeros((n, nbodies, 3))
        self.W = np.zeros((n, nbodies, 3))

    def fields(self, k: int) -> dict:
        """The first ``k`` rows, under the keys a builder's result carries."""
        return {"t": self.t[:k], "x": self.x[:k], "R": self.R[:k], "v": self.v[:k], "W": self.W[:k]}


def forced_bodies(scenario) -> list[int]:
    """Indices of the bodies a force element acts on (the builders apply their loads before
    every step)."""
    return [
        i for i, b in enumerate(scenario.bodies) if any(f.body == b.name for f in scenario.forces)
    ]


def pair_index(scenario) -> dict:
    """{frozenset((a, b)): index} of the scene's contact pairs."""
    return {frozenset((c.a, c.b)): i for i, c in enumerate(scenario.contacts)}


def pair_coefficients(scenario, values: str, rule: str, plane_value: float | None = None):
    """Per-body (and per-plane) coefficients whose pairwise combination by ``rule`` gives
    each pair's ``values`` ("mu" or "e"), for engines that store them per body:

    - ``"min"`` (DART's friction): pair = min(a, b); planes get ``plane_value`` (large), each
      body the least of its pairs' values;
    - ``"product"`` (PyBullet's friction and restitution, DART's restitution): pair = a b;
      planes get ``plane_value`` (1), bodies solved outward from the planes along the pairs;
    - ``"harmonic"`` (Drake's friction): pair = 2 a b/(a + b); planes get each pair's value
      (one plane per value), bodies solved outward.

    Returns {name: value}; raises :class:`Unsupported` when no per-body values give every
    pair its value (e.g. one body on two planes of different mu under the min rule with a
    third pair), naming the pair."""
    want = {(c.a, c.b): float(getattr(c, values)) for c in scenario.contacts}
    names = [b.name for b in scenario.bodies]
    val: dict[str, float] = {}
    if rule == "min":
        for p in scenario.planes:
            val[p.name] = plane_value if plane_value is not None else 1e6
        for n in names:
            mine = [v for (a, b), v in want.items() if n in (a, b)]
            val[n] = min(mine) if mine else 1.0
    else:
        pending = dict(want)
        for (_a, b), v in want.items():
            if b in {p.name for p in scenario.planes}:
                val.setdefault(b, plane_value if plane_value is not None else v)
        for _ in range(len(want) + 1):
            for (a, b), v in list(pending.items()):
                known = [x for x in (a, b) if x in val]
                if len(known) == 1:
                    k = known[0]
                    other = b if k == a else a
                    val[other] = _solve(rule, val[k], v, (a, b), values)
                    pending.pop((a, b))
                elif len(known) == 2:
                    pending.pop((a, b))
            if not pending:
                break
            if all(not ({a, b} & set(val)) for a, b in pending):
                a, b = next(iter(pending))
                val[a] = v if rule == "harmonic" else math.sqrt(pending[(a, b)])
        for n in names:
            val.setdefault(n, 1.0 if rule == "product" else 0.5)
    for (a, b), v in want.items():
        got = _combine(rule, val[a], val[b])
        if not math.isclose(got, v, rel_tol=1e-12, abs_tol=1e-15):
            raise Unsupported(
                f"the engine stores {values} per body and combines two bodies' values by "
                f"{rule}: no per-body values give pair {a!r}-{b!r} its {values} = {v:g} (it "
                f"would get {got:g})"
            )
    return val


def _combine(rule, a, b):
    if rule == "min":
        return min(a, b)
    if rule == "product":
        return a * b
    return 2.0 * a * b / (a + b) if a + b > 0 else 0.0


def _solve(rule, known, want, pair, what):
    """The other body's value so that combine(known, x) = want."""
    if rule == "product":
        if known == 0:
            if want == 0:
                return 1.0
            raise Unsupported(f"pair {pair}: {what} = {want:g} against a value of 0")
        x = want / known
    else:  # harmonic: 2 k x/(k + x) = w -> x = w k/(2 k - w)
        if want == 0:
            return 0.0
        if not 2 * known > want:
            raise Unsupported(
                f"pair {pair}: {what} = {want:g} needs the other side above {want / 2:g}, and "
                f"it is {known:g}"
            )
        x = want * known / (2.0 * known - want)
    return x


def check_readback(scenario, readback: dict, engine: str) -> None:
    """Compare what the engine holds with the scene: every pair's mu (and e where the engine
    models it: the key is present), every body's shape kind, sizes and offset, and where the
    builder reads them back (``joints``) every joint (:func:`check_joints`). Raises
    :class:`EngineError` naming the pair, body or joint and both values."""
    if "joints" in readback:
        check_joints(scenario, readback["joints"], engine)
    pairs = readback.get("pairs", {})
    for i, c in enumerate(scenario.contacts):
        got = pairs.get(i)
        if got is None:
            raise EngineError(f"{engine}: pair {c.a!r}-{c.b!r} is not in the engine's model")
        for key in ("mu", "e"):
            if key in got and not math.isclose(
                got[key], getattr(c, key), rel_tol=READBACK_RTOL, abs_tol=1e-12
            ):
                raise EngineError(
                    f"{engine}: pair {c.a!r}-{c.b!r}: the engine holds {key} = {got[key]!r}, "
                    f"the scene {getattr(c, key)!r}"
                )
    shapes = readback.get("shapes", {})
    for b in scenario.bodies:
        if b.shape is None:
            continue
        got = shapes.get(b.name)
        if got is None:
            raise EngineError(f"{engine}: body {b.name!r}'s shape is not in the engine's model")
        s = b.shape
        want = {
            "kind": s.kind,
            "size": tuple(s.half_extents)
            if s.kind == "box"
            else (s.radius,) + ((s.half_length,) if s.kind in ("capsule", "cylinder") else ()),
            "offset": tuple(s.position),
        }
        if got["kind"] != want["kind"]:
            raise EngineError(
                f"{engine}: body {b.name!r}: shape {got['kind']} (scene: {want['kind']})"
            )
        scale = s.extent
        for key in ("size", "offset"):
            a, w = np.asarray(got[key], dtype=float), np.asarray(want[key], dtype=float)
            if a.shape != w.shape or np.max(np.abs(a - w), initial=0.0) > READBACK_RTOL * scale:
                raise EngineError(
                    f"{engine}: body {b.name!r}: the engine's shape {key} is {a.tolist()} m, "
                    f"the scene's {w.tolist()} m"
                )
        if "rotation" in got:
            err = float(np.max(np.abs(np.asarray(got["rotation"]) - s.rotation)))
            if err > READBACK_RTOL:
                raise EngineError(
                    f"{engine}: body {b.name!r}: the shape's axes differ from "
                    f"the scene's by {err:.3g}"
                )


def external_wrench(scenario, body_index: int, R) -> tuple[np.ndarray, np.ndarray]:
    """The scene's constant forces on one body: (force (3,), torque about the centre of mass
    (3,)), world axes, for the body's attitude ``R`` (the points turn with the body)."""
    b = scenario.bodies[body_index]
    F = np.zeros(3)
    tau = np.zeros(3)
    for f in scenario.forces:
        if f.body == b.name:
            F += f.force
            tau += np.cross(np.asarray(R) @ f.point, f.force)
    return F, tau


def ground_hinges(scenario, engine: str) -> dict:
    """{body name: its joint} of a scene whose joints are each a revolute joint tying one
    body to the ground (at most one per body); any other joint is refused with the reason."""
    return ground_joints(scenario, engine, ("revolute",))


def ground_joints(scenario, engine: str, kinds=("revolute", "prismatic")) -> dict:
    """{body name: its joint} of a scene whose joints each tie one body to the ground (at
    most one per body) and are of one of ``kinds`` (those the engine's builder makes with
    contact); any other joint is refused, naming it and what the builder makes."""
    out = {}
    for j in scenario.joints:
        if j.kind not in kinds or j.body_b is not None or j.body_a in out:
            raise Unsupported(
                f"{engine} contact builder: joint {j.name!r} ({j.kind} between {j.body_a!r} and "
                f"{j.body_b or 'the ground'!r}): with contact, this builder makes one "
                f"{' or '.join(kinds)} joint from a body to the ground, no other"
            )
        out[j.body_a] = j
    return out


def hinge_rate(b, j) -> float:
    """The initial rate (rad/s) of body ``b`` about its hinge ``j``'s axis (the scene's
    checks have made its velocity that of a rotation about the hinge)."""
    return float(np.asarray(b.omega_body) @ (np.asarray(j.axis_a) / np.linalg.norm(j.axis_a)))


def joint_rate(b, j) -> float:
    """The initial rate of body ``b``'s ground joint ``j``: about a hinge's axis (rad/s,
    :func:`hinge_rate`), along a slider's (m/s: the centre of mass's velocity along the
    axis, world; the scene's checks have made its velocity a slide along the axis)."""
    if j.kind == "prismatic":
        return float(np.asarray(b.velocity) @ joint_axis_world(b, j))
    return hinge_rate(b, j)


def joint_axis_world(b, j) -> np.ndarray:
    """The unit axis of body ``b``'s joint ``j`` in world axes at t = 0."""
    a = np.asarray(b.rotation) @ np.asarray(j.axis_a, dtype=float)
    return a / np.linalg.norm(a)


def joint_anchor_world(b, j) -> np.ndarray:
    """The anchor of body ``b``'s joint ``j`` (on body a) in world coordinates at t = 0."""
    return np.asarray(b.position) + np.asarray(b.rotation) @ np.asarray(j.anchor_a, float)


def tilted_joints(scenario, angle: float = 0.01):
    """The scene with every joint's axis turned by ``angle`` rad about a world axis across
    it, on both sides (``axis_a`` in its body, ``axis_b`` in the world), so that the joint
    still holds at t = 0: the conformance kit's planted 'joint axis' mistake for builders
    that build their model from a scene."""
    import dataclasses

    bodies = {b.name: b for b in scenario.bodies}
    out = []
    for j in scenario.joints:
        b = bodies[j.body_a]
        a = joint_axis_world(b, j)
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        across /= np.linalg.norm(across)
        t = math.cos(angle) * a + math.sin(angle) * np.cross(across, a)
        fields = {"axis_a": np.asarray(b.rotation).T @ t}
        if j.body_b is None and j.axis_b is not None:
            fields["axis_b"] = t
        out.append(dataclasses.replace(j, **fields))
    return scenario.replace(joints=tuple(out))


def check_joints(scenario, joints: dict, engine: str) -> None:
    """Compare the joints an engine holds (``{name: {"kind", "axis", "anchor"}}``, world
    axes at t = 0, read from its model) with the scene's: the kind, the axis's direction
    (either sense), and for a hinge its anchor (a slider's anchor may sit anywhere on its
    line: the line through the anchor along the axis is compared). Raises
    :class:`EngineError` naming the joint and both values."""
    bodies = {b.name: b for b in scenario.bodies}
    for j in scenario.joints:
        got = joints.get(j.name)
        if got is None:
            raise EngineError(f"{engine}: joint {j.name!r} is not in the engine's model")
        if got["kind"] != j.kind:
            raise EngineError(f"{engine}: joint {j.name!r} is {got['kind']} (scene: {j.kind})")
        b = bodies[j.body_a]
        axis, anchor = joint_axis_world(b, j), joint_anchor_world(b, j)
        ga = np.asarray(got["axis"], dtype=float)
        ga = ga / np.linalg.norm(ga)
        if float(np.linalg.norm(np.cross(ga, axis))) > READBACK_RTOL:
            raise EngineError(
                f"{engine}: joint {j.name!r}: the engine's axis is {ga.tolist()}, the "
                f"scene's {axis.tolist()} (world, t = 0)"
            )
        gap = np.asarray(got["anchor"], dtype=float) - anchor
        if j.kind == "prismatic":
            gap = gap - (gap @ axis) * axis
        scale = max(b.shape.extent if b.shape is not None else 0.0, 1.0)
        if float(np.linalg.norm(gap)) > READBACK_RTOL * scale:
            raise EngineError(
                f"{engine}: joint {j.name!r}: the engine's anchor is "
                f"{np.asarray(got['anchor']).tolist()} m, the scene's {anchor.tolist()} m "
                "(world, t = 0)"
            )


def run_contact(
    engine: str,
    scenario,
    configuration_name: str,
    dt: float,
    t_end: float | None = None,
    save_every: int | None = None,
    **settings,
) -> ContactRunOutput:
    """Run the contact scene ``scenario`` on ``engine``'s contact builder in the configuration
    ``configuration_name`` at step ``dt`` (the file's ``[engine_settings.<engine>]``, then
    ``settings``). Checks the result's shape and times, the engine's model against the scene
    (:func:`check_readback`) and stops at a divergence (a non-finite state). Raises
    :class:`Unsupported`, :class:`Diverged` (with the output up to the last good state) or
    :class:`EngineError`."""
    t_end = scenario.t_end if t_end is None else float(t_end)
    save_every = scenario.save_every if save_every is None else int(save_every)
    nstep, saves = step_plan(dt, t_end, save_every)
    mod = builder(engine)
    conf = configuration(engine, configuration_name)
    settings = {**getattr(scenario, "engine_settings", {}).get(engine, {}), **settings}
    plant = settings.pop("_plant", None)  # the conformance kit's planted mistake (tests)
    check_settings(engine, settings, mod.SETTINGS)
    if plant is not None:
        settings["_plant"] = plant
    watch = timing.Stopwatch(timing.cpu_clock(_threaded(engine)))
    t0 = time.perf_counter()
    with timing.running(watch):  # the builder times its engine calls on it
        res = mod.simulate_contact(
            scenario, conf.name, float(dt), int(nstep), int(save_every), **settings
        )
    wall = time.perf_counter() - t0
    missing = [k for k in ("t", "x", "R", "v", "W", "contacts") if res.get(k) is None]
    if missing:
        raise EngineError(f"{engine} contact builder: its result lacks {missing}")
    try:
        traj = Trajectory(res["t"], res["x"], res["v"], res["R"], res["W"], scenario.body_names)
    except ValueError as exc:
        raise EngineError(f"{engine} contact builder: {exc}") from None
    contacts = res["contacts"]
    n = len(traj)
    for k in CONTACT_KEYS:
        if k not in contacts or len(contacts[k]) != n:
            raise EngineError(
                f"{engine} contact builder: contacts[{k!r}] missing or not one row per saved state"
            )
    want = saves * float(dt)
    if n > len(want) or not np.allclose(traj.t, want[:n], rtol=0, atol=1e-9 * max(t_end, 1)):
        raise EngineError(
            f"{engine} contact builder: saved times are not the steps 0, "
            f"{save_every}, ... of dt = {dt:g} s"
        )
    readback = res.get("readback", {})
    check_readback(scenario, readback, engine)
    out = ContactRunOutput(
        trajectory=traj,
        contacts=contacts,
        nstep=int(saves[n - 1]) if n else 0,
        wall_time_s=wall,
        engine_time_s=float(min(res.get("engine_time_s", wall) or wall, wall)),
        settings={**dict(res.get("settings", {})), "configuration": conf.name, "timestep": dt},
        readback=readback,
        stats=dict(res.get("stats", {}) or {}),
        family=conf.family,
        timing=watch.timing() if watch.elapsed > 0 else None,
    )
    bad = _first_divergence(scenario, traj)
    if bad is not None:
        k, why = bad
        out.trajectory = traj.head(k)
        out.contacts = {key: v[:k] for key, v in contacts.items()}
        out.nstep = int(saves[k - 1]) if k else 0
        raise Diverged(
            f"{conf.name} at dt = {dt:g} s: {why} at t = {traj.t[k]:.6g} s", float(traj.t[k]), out
        )
    if n < len(want):
        raise EngineError(f"{engine} contact builder: {n} saved states, the plan has {len(want)}")
    return out


def _first_divergence(scenario, traj) -> tuple[int, str] | None:
    """(index, why) of the first non-finite state or the first beyond :data:`REACH_FACTOR`
    times the reach of any motion of the scene (a body thrown out of it), or None."""
    arrays = (traj.position, traj.velocity, traj.omega_body)
    finite = np.all([np.isfinite(a).all(axis=(1, 2)) for a in arrays], axis=0)
    finite &= np.isfinite(traj.rotation).all(axis=(1, 2, 3))
    x0 = traj.position[:1]
    size = max(scenario.length_scale, 1e-3)
    reach = np.zeros(len(traj))
    with np.errstate(all="ignore"):
        reach = np.max(np.linalg.norm(traj.position - x0, axis=2), axis=1)
    g = float(np.linalg.norm(scenario.gravity))
    v0 = max([float(np.linalg.norm(b.velocity)) for b in scenario.bodies] + [0.0])
    bound = REACH_FACTOR * (
        size
        + v0 * traj.t
        + 0.5 * g * traj.t**2
        + sum(float(np.linalg.norm(f.force)) for f in scenario.forces)
        / max(scenario.total_mass, 1e-300)
        * traj.t**2
    )
    bad = ~finite | ~(reach <= bound)
    if not bad.any():
        return None
    k = int(np.argmax(bad))
    if not finite[k]:
        return k, "the state became non-finite"
    return k, f"a body moved {reach[k]:.3g} m from its start, beyond any motion of the scene"
