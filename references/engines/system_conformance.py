"""The conformance kit for system builders: planted joint mistakes that every builder of
systems of bodies must catch, and the kit's systems (shared by the builders' tests).

:func:`check_mistakes` runs one of the kit's systems (:func:`hinge_chain`: four links on
revolute joints with random attitudes, so that no relative rotation is the identity and an
axis written in the wrong body's frame points elsewhere) through an engine's builder
(``references.engines.<engine>.system``), first as built (it must run), then with each
mistake of :data:`MISTAKES` planted at the builder's boundary with the engine, and returns a
:class:`~references.engines.conformance.Check` per mistake: ``ok`` when the run refuses with
:class:`~references.errors.EngineError` naming the planted joint (``'h1'``) or its child body
(``'link1'``). :func:`assert_conforms` raises with every failed item::

    from references.engines.system_conformance import assert_conforms
    assert_conforms("pinocchio")

The mistakes, planted on the joint ``h1`` that attaches ``link1`` to ``link0``:

- ``axis in the parent's frame``: the hinge axis handed to the engine is the components of
  the axis in the parent's principal frame where the engine takes the child's;
- ``anchor from the body origin``: an anchor measured from the body's origin where the engine
  takes it from the centre of mass (or the reverse, where the engine's body frame is not at
  the COM): each builder's form is in :data:`PLANTS`;
- ``parent and child swapped``: the joint's two sides exchanged, the child's anchor (and
  frame) taken from the parent's side and the parent's from the child's.

Where each mistake is planted (the builder's boundary, :data:`PLANTS`):

==================  ==========================================================================
builder             boundary
==================  ==========================================================================
pinocchio, dart,    ``engine_frames(pl, c)`` -> ``EngineFrames`` (joint placement (R, p) in the
pybullet            parent's joint frame, axis, body offset); the body origin is the joint frame
drake               ``engine_frames(pl, c)`` -> ``DrakeFrames`` (frame F on the parent at p_F,
                    frame M on the child at p_M, axis); the body origin of the other builders is
                    the joint point
mujoco, mjx         ``model_xml(scenario, plan, ...)``: the MJCF is written from a copy of the
                    plan with the mistake (the read-back compares with the true plan); the body
                    origin of a link frame at its joint puts the joint at 0
director            ``model(scenario)`` -> ``director_model.system`` Body and Joint; the
                    director checks every joint at t = 0
==================  ==========================================================================
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import importlib
import types

import numpy as np

from references import conventions as cv
from references.engines.conformance import Check
from references.errors import EngineError

#: gravity of the kit's systems, m/s^2
G = np.array([0.0, 0.0, -9.81])

MISTAKES = ("axis in the parent's frame", "anchor from the body origin", "parent and child swapped")

#: the builders of systems and the integrator, dt (s) and steps of the kit's short runs
RUNS = {
    "director": ("rattle", 1e-2, 2),
    "mujoco": ("RK4", 1e-2, 2),
    "mjx": ("Euler (float64)", 1e-2, 2),
    "pinocchio": ("RKMK4", 1e-2, 2),
    "dart": ("RKMK4", 1e-2, 2),
    "pybullet": ("multibody", 1e-3, 2),
    "drake": ("runge_kutta5", 1e-2, 2),
}

#: the joint the mistakes are planted on, and its child body
PLANTED_JOINT, PLANTED_BODY = "h1", "link1"


# -- the kit's systems ------------------------------------------------------------------------


def scenario(name: str, bodies, joints, gravity=G):
    """A system scenario with the builders' contract fields (name, gravity, bodies, joints,
    body_names) from ``director_model.system`` Body and Joint lists."""
    return types.SimpleNamespace(
        name=name, gravity=np.asarray(gravity, float), bodies=tuple(bodies),
        joints=tuple(joints), body_names=tuple(b.name for b in bodies),
    )  # fmt: skip


def hinge_chain(n: int = 4, seed: int = 3):
    """(bodies, joints): n links (joint to joint 1 m along body axis 3, masses 1 + 0.3 i kg)
    hanging from the origin by revolute joints ``h0``.. with random world axes, random
    attitudes (so that no relative rotation is the identity) and random hinge rates; the
    velocities follow the joints. Joint ``h<i>`` has ``body_a`` = link i-1 (the parent)."""
    from director_model.system import Body, Joint

    rng = np.random.default_rng(seed)
    bodies, joints = [], []
    p, vp, wp, Rp = np.zeros(3), np.zeros(3), np.zeros(3), np.eye(3)
    Y = np.array([0.0, 0.0, 0.5])
    for i in range(n):
        R = cv.rotvec_to_matrix(0.8 * rng.normal(size=3))
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        x = p - R @ Y
        w = wp + 1.5 * rng.normal() * u
        v = vp + np.cross(w, x - p)
        m = 1.0 + 0.3 * i
        bodies.append(Body(f"link{i}", m, (m / 12 + 0.01 + 0.002 * i, m / 12 + 0.015, 0.02),
                           x, R, v, R.T @ w))  # fmt: skip
        if i == 0:
            joints.append(Joint("revolute", "link0", None, Y, p, R.T @ u, u, name="h0"))
        else:
            joints.append(Joint("revolute", f"link{i - 1}", f"link{i}", -Y, Y, Rp.T @ u,
                                R.T @ u, name=f"h{i}"))  # fmt: skip
        tip = x - R @ Y
        p, vp, wp, Rp = tip, v + np.cross(w, tip - x), w, R
    return bodies, joints


def universal_chain(n: int = 3, seed: int = 5):
    """(bodies, joints): n links hanging from the origin, joined by universal joints ``u0``..
    (the first to the ground) with random perpendicular axis pairs and random attitudes; each
    joint's relative rate lies on its two axes. Joint ``u<i>`` has ``body_a`` = link i-1 (the
    parent); the same names of planted joint and body as :func:`hinge_chain` (``h1`` ..)
    when ``names="h"``."""
    from director_model.system import Body, Joint

    rng = np.random.default_rng(seed)
    bodies, joints = [], []
    p, vp, wp, Rp = np.zeros(3), np.zeros(3), np.zeros(3), np.eye(3)
    Y = np.array([0.0, 0.0, 0.5])
    for i in range(n):
        R = cv.rotvec_to_matrix(0.8 * rng.normal(size=3))
        u1 = rng.normal(size=3)
        u1 /= np.linalg.norm(u1)
        u2 = np.cross(u1, rng.normal(size=3))
        u2 /= np.linalg.norm(u2)  # perpendicular to u1 in the world at t = 0
        x = p - R @ Y
        w = wp + 1.3 * rng.normal() * u1 + 0.9 * rng.normal() * u2
        v = vp + np.cross(w, x - p)
        m = 1.0 + 0.2 * i
        bodies.append(Body(f"link{i}", m, (m / 12 + 0.01, m / 12 + 0.012 + 0.001 * i, 0.02),
                           x, R, v, R.T @ w))  # fmt: skip
        # the parent's axis u1 (world) in the parent's frame, the child's u2 in the child's
        if i == 0:
            joints.append(Joint("universal", "link0", None, Y, p, R.T @ u2, u1, name="h0"))
        else:
            joints.append(Joint("universal", f"link{i - 1}", f"link{i}", -Y, Y, Rp.T @ u1,
                                R.T @ u2, name=f"h{i}"))  # fmt: skip
        tip = x - R @ Y
        p, vp, wp, Rp = tip, v + np.cross(w, tip - x), w, R
    return bodies, joints


def rot_y(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def slider():
    """(bodies, joints): a rod hinged at the origin (axis world y, joint ``pivot``) and a
    collar sliding along it (prismatic joint ``slide``, the collar's principal axes permuted
    against the rod's, so that an axis in the wrong frame points elsewhere), swinging at
    1.2 rad/s and sliding at 0.4 m/s at t = 0, the collar 0.3 m below the rod's centre."""
    from director_model.system import Body, Joint

    Rw = rot_y(0.5)
    turned = np.array([[0.0, 1, 0], [0, 0, 1], [1, 0, 0]])
    y = np.array([0, 1.0, 0])
    w = 1.2 * y
    xa = Rw @ np.array([0, 0, -0.5])
    va = np.cross(w, xa)
    u = Rw @ np.array([0, 0, -1.0])
    xb, vb = xa + 0.3 * u, va + np.cross(w, 0.3 * u) - 0.4 * u
    Rb = Rw @ turned
    bodies = [
        Body("rod", 1.0, (0.1, 0.1, 0.02), xa, Rw, va, Rw.T @ w),
        Body("collar", 0.5, (0.01, 0.012, 0.015), xb, Rb, vb, Rb.T @ w),
    ]
    joints = [
        Joint("revolute", "rod", None, (0, 0, 0.5), (0, 0, 0), (0, 1, 0), y, name="pivot"),
        Joint("prismatic", "rod", "collar", (0, 0, 0), (0, 0, 0), (0, 0, -1),
              turned.T @ np.array([0, 0, -1.0]), name="slide"),
    ]  # fmt: skip
    return bodies, joints


def inclined_slide(spin: float = 0.0):
    """(bodies, joints, exact): a 2 kg body on a 45-degree slide through the world origin
    (a prismatic joint to the ground along n = (1, 0, 1)/sqrt 2, its principal axis 3 along
    n), starting 0.2 sqrt 2 m up the slide at 0.7 m/s along it; ``exact(t)`` -> (x (n, 3),
    R (n, 3, 3)): the closed form x0 + v0 t + (g . n) n t^2 / 2, R = R0 (no torque)."""
    from director_model.system import Body, Joint

    n = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    # principal axis 3 along n: a rotation about y by 45 degrees
    R0 = rot_y(np.pi / 4)
    x0, v0 = np.array([0.2, 0.0, 0.2]), 0.7 * n
    body = Body("s", 2.0, (0.3, 0.4, 0.5), position=x0, rotation=R0, velocity=v0)
    joint = Joint("prismatic", "s", None, anchor_a=(0, 0, 0), anchor_b=(0, 0, 0),
                  axis_a=(0, 0, 1), axis_b=n, name="rail")  # fmt: skip

    def exact(t):
        t = np.asarray(t, float)
        x = x0 + np.outer(t, v0) + 0.5 * np.outer(t**2, (G @ n) * n)
        return x, np.broadcast_to(R0, (len(t), 3, 3))

    return [body], [joint], exact


def closure_loop(kind: str = "universal", seed: int = 7):
    """(bodies, joints): two links hanging at rest from two ground points by spherical joints
    ``s0``, ``s1`` and joined to each other by a joint ``h1`` of ``kind`` (``link0`` its
    ``body_a``, ``link1`` its ``body_b``), which closes the loop (the joints to the ground come
    first in the spanning tree): random attitudes, the closure's point off both links, its
    axes random (a universal's perpendicular, the others' parallel). At rest, so every initial
    state satisfies the closure."""
    from director_model.system import Body, Joint

    rng = np.random.default_rng(seed)
    Y = np.array([0.0, 0.0, 0.5])
    pivots = (np.zeros(3), np.array([1.0, 0.2, 0.0]))
    W = np.array([0.5, 0.1, -0.7])  # the closure's point
    ua = rng.normal(size=3)
    ua /= np.linalg.norm(ua)
    ub = ua if kind != "universal" else np.cross(ua, rng.normal(size=3))
    ub = ub / np.linalg.norm(ub)
    bodies, joints, frames = [], [], []
    for i, P in enumerate(pivots):
        R = cv.rotvec_to_matrix(0.6 * rng.normal(size=3))
        x = P - R @ Y
        m = 1.0 + 0.4 * i
        bodies.append(Body(f"link{i}", m, (m / 12 + 0.01, m / 12 + 0.014, 0.02), x, R))
        joints.append(Joint("spherical", f"link{i}", None, Y, P, name=f"s{i}"))
        frames.append((x, R))
    (x0, R0), (x1, R1) = frames
    axes = (R0.T @ ua, R1.T @ ub) if kind != "spherical" else (None, None)
    joints.append(Joint(kind, "link0", "link1", R0.T @ (W - x0), R1.T @ (W - x1), *axes,
                        name=PLANTED_JOINT))  # fmt: skip
    return bodies, joints


# -- the planted mistakes -----------------------------------------------------------------------


def _tree_joint(pl, c):
    """(the plan's tree joint of body c, its scenario joint, whether the child is body_a)."""
    tj = pl.tree[c]
    j = next(j for j in pl.joints if j.name == tj.name)
    return tj, j, j.body_a == pl.names[c]


def _plant_frames(mistake, from_origin, swapped):
    """The mistake in a builder's frames of the planted joint (``engine_frames(pl, c)``, a
    dataclass with an ``axis``): the axis in the parent's frame, or the fields
    ``from_origin(pl, tj)`` or ``swapped(pl, tj)`` give (a dict of changed fields)."""

    def change(orig):
        def planted(pl, c):
            f = orig(pl, c)
            if pl.names[c] != PLANTED_BODY:
                return f
            tj, j, child_is_a = _tree_joint(pl, c)
            if mistake == MISTAKES[0]:
                return dataclasses.replace(f, axis=_unit(j.axis_b if child_is_a else j.axis_a))
            fields = from_origin if mistake == MISTAKES[1] else swapped
            return dataclasses.replace(f, **fields(pl, tj))

        return planted

    return "engine_frames", change


def _plant_engine_frames(mistake):
    """The mistake in Pinocchio's, DART's and PyBullet's ``EngineFrames`` of a non-root joint:
    placement (R, p = X - Y_p) in the parent's joint frame, axis, body offset -Y."""
    return _plant_frames(
        mistake,
        # the parent's anchor X (from its COM) taken as if from its body origin (the parent's
        # joint frame, at Y_p): not moved by -Y_p
        lambda pl, tj: {"p": tj.X},
        lambda pl, tj: {"p": tj.Y - pl.tree[tj.parent].Y, "body_offset": -tj.X},
    )


def _plant_drake_frames(mistake):
    """The mistake in Drake's ``DrakeFrames``: F on the parent at p_F = X, M on the child at
    p_M = Y, axis."""
    return _plant_frames(
        mistake,
        # the parent's anchor measured from its joint point (the body origin of the other
        # builders) instead of its COM
        lambda pl, tj: {"p_F": tj.X - pl.tree[tj.parent].Y},
        lambda pl, tj: {"p_F": tj.Y, "p_M": tj.X},
    )


def _plant_mjcf(mistake):
    """The mistake in the MJCF: ``model_xml`` writes it from a copy of the plan with the
    mistake, while the read-back compares the compiled model with the true plan."""

    def change(orig):
        def planted(scenario, pl, *args, **kw):
            pl = copy.deepcopy(pl)
            c = pl.names.index(PLANTED_BODY)
            tj = pl.tree[c]
            if mistake == MISTAKES[0]:
                tj.axis_c = tj.axis_p
            elif mistake == MISTAKES[1]:
                # the child's anchor measured from a link frame at the joint (URDF's body
                # origin) instead of from its COM, where MuJoCo's body frame is
                tj.Y = np.zeros(3)
            else:
                tj.X, tj.Y = tj.Y, tj.X
            return orig(scenario, pl, *args, **kw)

        return planted

    return "model_xml", change


def _plant_director(mistake):
    """The mistake in the director's Body and Joint lists (``director.system.model``)."""

    def change(orig):
        def planted(scenario):
            bodies, joints = orig(scenario)
            k = next(i for i, j in enumerate(joints) if j.name == PLANTED_JOINT)
            j = joints[k]
            if mistake == MISTAKES[0]:
                j = dataclasses.replace(j, axis_b=j.axis_a)  # link1's axis in link0's frame
            elif mistake == MISTAKES[1]:
                # link1's anchor from a link frame at the joint (URDF's body origin)
                j = dataclasses.replace(j, anchor_b=(0.0, 0.0, 0.0))
            else:
                j = dataclasses.replace(j, body_a=j.body_b, body_b=j.body_a)
            return bodies, [*joints[:k], j, *joints[k + 1 :]]

        return planted

    return "model", change


#: the mistakes planted on the closure ``h1`` of :func:`closure_loop`, in the plan's loop (the
#: builders' boundary for closures: :func:`references.engines.reduced.plan`'s ``loops``)
CLOSURE_MISTAKES = (
    "closure axis in the other body's frame",
    "closure anchor from the body origin",
    "closure sides swapped",
)


def _plant_closure(mistake):
    """The mistake in the plan's closure ``h1``: its points along the axis on body a taken
    with b's axis components; a's points measured from a's joint point (its tree anchor)
    instead of its COM; or each point put on the other body."""

    def wrong(pl, lp):
        pairs, dists = list(lp.pairs), list(lp.distances)
        Xa, Xb = pairs[0]
        if mistake == CLOSURE_MISTAKES[0]:
            pairs = [pairs[0], *((Xa + (pb - Xb), pb) for _, pb in pairs[1:])]
            dists = [(Xa + (pb - Xb), pb, d) for _, pb, d in dists]
        elif mistake == CLOSURE_MISTAKES[1]:
            Ya = pl.tree[lp.a].Y
            pairs = [(pa - Ya, pb) for pa, pb in pairs]
            dists = [(pa - Ya, pb, d) for pa, pb, d in dists]
        else:
            pairs = [(pb, pa) for pa, pb in pairs]
            dists = [(pb, pa, d) for pa, pb, d in dists]
        return dataclasses.replace(lp, pairs=pairs, distances=dists)

    def change(orig):
        def planted(*args, **kw):
            pl = orig(*args, **kw)
            pl.loops = [wrong(pl, lp) if lp.joint == PLANTED_JOINT else lp for lp in pl.loops]
            return pl

        return planted

    return "plan", change


def _unit(a) -> np.ndarray:
    a = np.asarray(a, float)
    return a / np.linalg.norm(a)


#: per builder: where and how each mistake is planted (module docstring)
PLANTS = {
    "director": ("director.system", _plant_director),
    "mujoco": ("mujoco.system", _plant_mjcf),
    "mjx": ("mujoco.system", _plant_mjcf),  # MJX steps the C builder's checked model
    "pinocchio": ("pinocchio.system", _plant_engine_frames),
    "dart": ("dart.system", _plant_engine_frames),
    "pybullet": ("pybullet.system", _plant_engine_frames),
    "drake": ("drake.system", _plant_drake_frames),
}


@contextlib.contextmanager
def planted(engine: str, mistake: str):
    """Within the block, ``engine``'s builder makes ``mistake`` (:data:`MISTAKES`,
    :data:`CLOSURE_MISTAKES`) on joint ``h1`` of the kit's chain or loop; the builder is
    restored on exit."""
    if mistake in CLOSURE_MISTAKES:
        module, make = "reduced", _plant_closure
    elif mistake not in MISTAKES:
        raise ValueError(f"mistake {mistake!r} unknown; known: {[*MISTAKES, *CLOSURE_MISTAKES]}")
    elif engine not in PLANTS:
        raise ValueError(f"engine {engine!r} has no system plants; known: {list(PLANTS)}")
    else:
        module, make = PLANTS[engine]
    mod = importlib.import_module(f"references.engines.{module}")
    attr, change = make(mistake)
    orig = getattr(mod, attr)
    setattr(mod, attr, change(orig))
    try:
        yield
    finally:
        setattr(mod, attr, orig)


#: the integrator of the kit's short runs of a loop, where it is not :data:`RUNS`' (the only
#: ones that close loops: Drake's discrete plant, DART's World.step)
LOOP_RUNS = {"drake": "discrete SAP", "dart": "semi-implicit Euler"}


def run(engine: str, sc=None, loop: bool = False):
    """A short run of ``sc`` (default: the kit's hinge chain) on ``engine``'s builder, with
    the integrator of :data:`LOOP_RUNS` when ``loop``."""
    from references.engines.system import builder

    sc = sc if sc is not None else scenario("kit-hinge4", *hinge_chain())
    integrator, dt, nstep = RUNS[engine]
    if loop:
        integrator = LOOP_RUNS.get(engine, integrator)
    return builder(engine)(sc, integrator, dt, nstep, 1)


def check_mistakes(engine: str, baseline: bool = True, sc=None, mistakes=MISTAKES) -> list[Check]:
    """One :class:`Check` per mistake (and one for the true builder when ``baseline``): the
    planted run must raise :class:`EngineError` naming joint 'h1' or body 'link1'. ``sc``:
    the system (default the hinge chain; :func:`universal_chain` for the universal joints,
    :func:`closure_loop` with ``mistakes=CLOSURE_MISTAKES`` for a closure)."""
    checks = []
    loop = any(m in CLOSURE_MISTAKES for m in mistakes)
    if baseline:
        try:
            run(engine, sc, loop)
            checks.append(Check("runs as built", True))
        except Exception as exc:  # noqa: BLE001 - reported, never raised
            checks.append(Check("runs as built", False, f"{type(exc).__name__}: {exc}"))
    for mistake in mistakes:
        name = f"catches {mistake}"
        try:
            with planted(engine, mistake):
                run(engine, sc, loop)
        except EngineError as exc:
            msg = str(exc)
            named = f"'{PLANTED_JOINT}'" in msg or f"'{PLANTED_BODY}'" in msg
            checks.append(Check(name, named, msg if named else f"not named: {msg}"))
        except Exception as exc:  # noqa: BLE001 - the wrong kind of failure
            checks.append(Check(name, False, f"{type(exc).__name__} instead of EngineError: "
                                              f"{exc}"))  # fmt: skip
        else:
            checks.append(Check(name, False, "the planted mistake ran without complaint"))
    return checks


def assert_conforms(engine: str, baseline: bool = True, sc=None, mistakes=MISTAKES) -> None:
    """Raise ``AssertionError`` listing every failed item of :func:`check_mistakes`."""
    checks = check_mistakes(engine, baseline, sc, mistakes)
    failed = [f"{c.name}: {c.message}" for c in checks if not c.ok]
    if failed:
        raise AssertionError(f"{engine} system builder: " + "; ".join(failed))
