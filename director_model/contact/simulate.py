"""Entry points of the contact integrator: :func:`simulate_contact`, :class:`ContactStepper`,
:func:`simulate_contact_batch`."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from director_model.contact import _kernels as K
from director_model.contact import _parts as P
from director_model.contact.scene import ContactScene
from director_model.errors import InvalidRunError
from director_model.simulate import step_plan
from director_model.system.states import energy_momentum


class ContactSolveError(RuntimeError):
    """A step of a contact run failed: the contact problem or the position stage did not
    converge within their caps, a configuration the scheme does not treat exactly arose (an
    edge-edge box contact, a cylinder on its flat face), a contact was missed, or a rotation
    step had no solution. Attributes: ``time`` (s, start of the failing step), ``step``
    (1-based), ``status`` (the kernel's code), ``pair`` (names of the pair involved, or
    None), ``member`` (index in a batch, or None). The run's completed steps are kept."""

    def __init__(self, message, *, time, step, status, pair=None, member=None):
        super().__init__(message)
        self.time = time
        self.step = step
        self.status = status
        self.pair = pair
        self.member = member


@dataclass(eq=False)
class ContactTrajectory:
    """Saved states of a contact run (n saved times, nb bodies, npair pairs), SI units, world
    axes unless said.

    ==================  ===============  ======================================================
    field               shape            meaning
    ==================  ===============  ======================================================
    ``t``               (n,)             time, s
    ``position``        (n, nb, 3)       centre of mass x, m
    ``velocity``        (n, nb, 3)       v, m/s
    ``rotation``        (n, nb, 3, 3)    R body-to-world (columns: directors)
    ``omega_body``      (n, nb, 3)       W, body axes, rad/s
    ``energy``          (n,)             sum 1/2 m|v|^2 + 1/2 W.I W - m g.x (J); the
                                         potential of point forces is not included
    ``pair_force``      (n, npair, 3)    contact force on the pair's first body (``pairs[k].a``
                                         if a body, else ``b``) in the step ending at t: the
                                         step's contact impulses / dt, N
    ``penetration``     (n,)             largest overlap max(-gap) of a closed contact over the
                                         steps since the previous save, m
    ``signorini``       (n,)             largest Signorini residual since the previous save
    ``coulomb``         (n,)             largest Coulomb-cone residual
    ``dissipation``     (n,)             largest maximum-dissipation residual
    ``contact_work``    (n,)             largest work of the contact impulses in one step, J
                                         (<= round-off: contact never adds energy)
    ``iterations``      (n,)             most Newton iterations of one contact problem
    ``residual``        (n,)             largest certified residual of a contact problem
                                         (Alart-Curnier function / impulse scale)
    ``contacts``        (n,)             contacts closed at the saved step
    ``passes``          (n,)             most position-stage passes of one step
    ==================  ===============  ======================================================

    The residuals are dimensionless, per contact k with impulse (z_n, z_t), rates (u_n,
    u_t) including the stage's targets (the gap at the step's end / dt, the restitution
    target), rho_k = 3 / trace of the contact's Delassus block, Z the stage's largest contact
    impulse: Signorini |min(z_n, rho_k u_n)| / Z; Coulomb (|z_t| - mu z_n)+ / (mu z_n);
    maximum dissipation rho_k |z_t . u_t + mu z_n |u_t|| / Z^2. Zero for an exact solution.
    Scalars: ``body_names``, ``pair_names``, ``nstep``, ``dt``, ``wall_time_s``,
    ``cpu_time_s`` (the compiled stepping alone).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    energy: np.ndarray
    pair_force: np.ndarray
    penetration: np.ndarray
    signorini: np.ndarray
    coulomb: np.ndarray
    dissipation: np.ndarray
    contact_work: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    contacts: np.ndarray
    passes: np.ndarray
    body_names: tuple
    pair_names: tuple
    nstep: int
    dt: float
    wall_time_s: float
    cpu_time_s: float

    def __len__(self) -> int:
        return self.t.shape[0]

    def body_index(self, name: str) -> int:
        try:
            return self.body_names.index(name)
        except ValueError:
            raise KeyError(
                f"body {name!r}: unknown; the bodies are {list(self.body_names)}"
            ) from None


def _count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidRunError(f"{name} = {value!r}: must be a whole number >= 1")
    return int(value)


def _dt(dt) -> float:
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise InvalidRunError(f"dt = {dt!r}: must be a real number") from None
    if not (dt > 0 and math.isfinite(dt)):
        raise InvalidRunError(f"dt = {dt!r}: the time step must be positive and finite")
    return dt


def _initial_state(scene: ContactScene):
    nb = len(scene.bodies)
    S = np.zeros((nb, P.NS))
    for i, b in enumerate(scene.bodies):
        S[i, 0:3] = b.position
        S[i, 6:9] = b.velocity
        S[i, 12] = 1.0
        S[i, 20:23] = b.inertia * b.omega_body
    D0 = np.array([b.rotation.ravel() for b in scene.bodies])
    return D0, S


def _saves(nstep: int, save_every: int, include_start: bool) -> np.ndarray:
    saves = np.arange(save_every, nstep + 1, save_every, dtype=np.int64)
    if saves.size == 0 or saves[-1] != nstep:
        saves = np.append(saves, np.int64(nstep))
    if include_start:
        saves = np.insert(saves, 0, np.int64(0))
    return saves


def _failure(scene, status, info, done, dt, member=None) -> ContactSolveError:
    t = done * dt
    p = int(info[P.I_PAIR])
    f = int(info[P.I_FEATURE])
    pair = None
    what = P.STATUS_TEXT.get(int(status), "unknown failure")
    if 0 <= p < len(scene.pair_names):
        pair = scene.pair_names[p]
        what += f" (pair {pair[0]!r}-{pair[1]!r}"
        what += f": {scene.feature_text[f]})" if 0 <= f < len(scene.feature_text) else ")"
    elif 0 <= f < len(scene.feature_text):
        pair = scene.pair_names[int(scene.FI[f, 3])]
        what += f" ({scene.feature_text[f]})"
    if status == P.FAIL_SOLVE:
        what += f"; residual reached {info[P.I_RES]:.3g} of the impulse scale"
    who = "" if member is None else f"member {member}: "
    return ContactSolveError(
        f"{who}contact step {done + 1} starting at t = {t:.9g} s failed: {what}",
        time=t, step=done + 1, status=int(status), pair=pair, member=member,
    )  # fmt: skip


def _trajectory(scene, t, X, V, D, W, Q, PF, nstep, dt, wall, cpu):
    E, _, _ = energy_momentum(scene.asm.bodies, scene.gravity, X, V, D, W)
    return ContactTrajectory(
        t=t, position=X, velocity=V, rotation=D, omega_body=W, energy=E,
        pair_force=PF * np.asarray(scene.pair_sign)[None, :, None],
        penetration=Q[:, P.Q_PEN], signorini=Q[:, P.Q_SIG], coulomb=Q[:, P.Q_COUL],
        dissipation=Q[:, P.Q_DISS], contact_work=Q[:, P.Q_WORK],
        iterations=Q[:, P.Q_ITER].astype(np.int64), residual=Q[:, P.Q_RES],
        contacts=Q[:, P.Q_NCON].astype(np.int64), passes=Q[:, P.Q_OUTER].astype(np.int64),
        body_names=scene.asm.names, pair_names=tuple(scene.pair_names), nstep=nstep, dt=dt,
        wall_time_s=wall, cpu_time_s=cpu,
    )  # fmt: skip


_COMPILED = False


def _ensure_compiled() -> None:
    """Compile or load the kernel with a 1-step run of a small scene (a box on a plane), so
    that a run's timing (``cpu_time_s``) measures stepping only."""
    global _COMPILED
    if _COMPILED:
        return
    from director_model.contact.scene import Pair
    from director_model.contact.shapes import Box, Plane
    from director_model.system.model import Body

    box = Box((0.1, 0.1, 0.1))
    sc = ContactScene([Body("b", 1.0, box.inertia(1.0), position=(0, 0, 0.1))], {"b": box},
                      {"g": Plane()}, [Pair("b", "g", mu=0.5)], gravity=(0, 0, -9.81))  # fmt: skip
    ContactStepper(sc, dt=1e-3, _warm=False).advance(1)
    _COMPILED = True


class ContactStepper:
    """A contact scene advanced in chunks; ``advance(n1)`` then ``advance(n2)`` continues
    the run of n1 + n2 steps from where it stopped (the state, its compensations and the last
    contact impulses, the start values of the next step's solves, are kept), equal to one
    run to the contact solver's tolerance, not bit for bit: what a chunk builds for its
    solves (the rows, the kept Jacobian factors of the chord steps) starts afresh in the
    next, which can round differently (a resting stack of 3 boxes: 1.5e-20 m after 500 + 500
    steps; a box pushed into sliding: 3.6e-15 m).

    ``scene`` a :class:`ContactScene`; ``dt`` the step (s). The scheme is the nonsmooth
    RATTLE of director_model.contact._kernels (order 2 away from events, 1 through them).
    :meth:`advance` raises ContactSolveError on a failed step; the stepper then stays at the
    last completed step (``nstep_done``)."""

    def __init__(self, scene: ContactScene, *, dt: float, _warm: bool = True):
        if not isinstance(scene, ContactScene):
            raise InvalidRunError(f"scene = {scene!r}: expected a ContactScene")
        self.scene = scene
        self.dt = _dt(dt)
        self._D0, self._S = _initial_state(scene)
        self._WS = np.zeros((max(scene.FI.shape[0], 1), 6))
        self._WJ = np.zeros((max(scene.asm.rint.shape[0], 1), 2))
        self.nstep_done = 0
        if _warm:
            _ensure_compiled()

    @property
    def time(self) -> float:
        return self.nstep_done * self.dt

    def state(self):
        """(position (nb, 3), velocity (nb, 3), rotation (nb, 3, 3), omega_body (nb, 3)) now,
        stored by the kernel itself (a run of no steps saving its start): the numbers a
        trajectory saving this step holds, bit for bit."""
        _, X, V, D, W, *_ = self._run(0, np.zeros(1, dtype=np.int64))
        return X[0], V[0], D[0], W[0]

    def _run(self, nstep: int, saves: np.ndarray):
        """Run the kernel ``nstep`` steps saving the steps ``saves`` (0 = now). Returns
        (status, X, V, D, W, Q, PF, info, wall time, thread CPU time)."""
        sc = self.scene
        nb, ns, npair = len(sc.bodies), saves.shape[0], sc.PI.shape[0]
        X = np.zeros((ns, nb, 3))
        V = np.zeros((ns, nb, 3))
        D = np.zeros((ns, nb, 3, 3))
        W = np.zeros((ns, nb, 3))
        Q = np.zeros((ns, P.NQ))
        PF = np.zeros((ns, npair, 3))
        info = np.full(P.NINFO, -1.0)
        rint = sc.asm.rint if sc.asm.rint.shape[0] else np.zeros((0, 4), dtype=np.int64)
        c0 = time.thread_time()
        t0 = time.perf_counter()
        status = K.run_contact(
            sc.asm.bodies, sc.SH, self._D0, self._S, self._WS, self._WJ, sc.FI, sc.FV, sc.PI,
            sc.PV, rint, sc.asm.rvec, sc.fb, sc.fv, sc.gravity, self.dt, nstep, saves,
            X, V, D, W, Q, PF, info,
        )  # fmt: skip
        wall = time.perf_counter() - t0
        cpu = time.thread_time() - c0
        return status, X, V, D, W, Q, PF, info, wall, cpu

    def advance(self, nstep: int, save_every: int = 1, include_start: bool = False):
        """Advance ``nstep`` steps; save the steps j * save_every of the chunk, its last step
        and, with ``include_start``, its start. Returns a :class:`ContactTrajectory`."""
        nstep = _count("nstep", nstep)
        save_every = _count("save_every", save_every)
        saves = _saves(nstep, save_every, include_start)
        sc = self.scene
        status, X, V, D, W, Q, PF, info, wall, cpu = self._run(nstep, saves)
        step0 = self.nstep_done
        if status != P.OK:
            self.nstep_done = step0 + int(info[P.I_STEPS])
            raise _failure(sc, status, info, self.nstep_done, self.dt)
        self.nstep_done = step0 + nstep
        return _trajectory(sc, (step0 + saves) * self.dt, X, V, D, W, Q, PF, nstep, self.dt,
                           wall, cpu)  # fmt: skip


def simulate_contact(scene: ContactScene, *, dt: float, t_end: float,
                     save_every: int = 1) -> ContactTrajectory:  # fmt: skip
    """Integrate a contact scene; ``dt``, ``t_end`` (s) and ``save_every`` follow
    :func:`director_model.step_plan` (t_end a whole number of steps; the steps 0, s, 2s, ...
    and the last are saved). Equals ``ContactStepper(scene, dt=dt).advance(nstep,
    save_every, include_start=True)``.

    Example: a ball dropped from 1 m on the ground with restitution 0.5

    >>> import numpy as np
    >>> from director_model.contact import Body, ContactScene, Pair, Plane, Sphere
    >>> from director_model.contact import simulate_contact
    >>> ball = Sphere(0.1)
    >>> scene = ContactScene(
    ...     [Body("ball", 1.0, ball.inertia(1.0), position=(0, 0, 1.1))],
    ...     shapes={"ball": ball},
    ...     planes={"ground": Plane((0, 0, 1), 0.0)},
    ...     pairs=[Pair("ball", "ground", mu=0.5, e=0.5)],
    ...     gravity=(0, 0, -9.81),
    ... )
    >>> tr = simulate_contact(scene, dt=1e-3, t_end=1.2, save_every=10)
    >>> round(float(tr.position[:, 0, 2].min() - 0.1), 12)  # lowest point never below ground
    0.0
    >>> bool(tr.position[-1, 0, 2] > 0.3)  # it rebounded towards e^2 h0 = 0.25 m above it
    True
    """
    nstep, _ = step_plan(dt, t_end, save_every)
    return ContactStepper(scene, dt=dt).advance(nstep, int(save_every), include_start=True)
