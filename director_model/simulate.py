"""Entry points: :func:`simulate` (one body), :class:`Stepper` (one body in chunks) and
:func:`simulate_batch` (N bodies).

All validate every input before any stepping, run the compiled time loop of
:mod:`director_model._kernels` (saved states only, memory O(nsave)), and compute the
invariants from the saved director states with :mod:`director_model.invariants`.
:func:`simulate` is one chunk of a :class:`Stepper`.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numba
import numpy as np

from director_model import _kernels as K
from director_model.body import Body
from director_model.errors import (
    InvalidBodyError,
    InvalidRunError,
    InvalidStateError,
    StepSizeError,
)
from director_model.schemes import SCHEMES
from director_model.schemes.base import Scheme
from director_model.state import check_rotation, hat, omega_body_from_directors
from director_model.trajectory import BatchTrajectory, Trajectory

# --------------------------------------------------------------------------------------------
# validation helpers (every message: argument, value, rule)
# --------------------------------------------------------------------------------------------


def step_plan(dt: float, t_end: float, save_every: int) -> tuple[int, np.ndarray]:
    """Number of steps and the saved step indices (0, s, 2s, ... and always nstep).

    nstep = round(t_end/dt); an error unless |nstep - t_end/dt| <= 1e-9 max(t_end/dt, 1)
    and nstep >= 1 (the suite-wide rule: no silently shortened or lengthened horizon).
    """
    try:
        dt = float(dt)
        t_end = float(t_end)
    except (TypeError, ValueError):
        raise InvalidRunError(f"dt = {dt!r}, t_end = {t_end!r}: must be real numbers") from None
    if not (dt > 0 and math.isfinite(dt)):
        raise InvalidRunError(f"dt = {dt!r}: the time step must be positive and finite")
    if not (t_end > 0 and math.isfinite(t_end)):
        raise InvalidRunError(f"t_end = {t_end!r}: the horizon must be positive and finite")
    if isinstance(save_every, bool) or not isinstance(save_every, int | np.integer):
        raise InvalidRunError(f"save_every = {save_every!r}: must be a whole number >= 1")
    if save_every < 1:
        raise InvalidRunError(f"save_every = {save_every!r}: must be a whole number >= 1")
    ratio = t_end / dt
    nstep = int(round(ratio))
    if nstep < 1 or abs(nstep - ratio) > 1e-9 * max(ratio, 1.0):
        raise InvalidRunError(
            f"t_end = {t_end!r} is not a whole number of steps of dt = {dt!r} "
            f"(t_end/dt = {ratio!r}); choose dt dividing t_end"
        )
    return nstep, saved_steps(nstep, int(save_every))


def saved_steps(nstep: int, save_every: int, include_start: bool = True) -> np.ndarray:
    """The step indices saved of a run (or a chunk) of ``nstep`` steps: s, 2s, ... and always
    ``nstep``, after 0 with ``include_start`` (int64). The suite's one definition: the step
    plan, the director steppers, the system batch and the builders of systems save these."""
    saves = np.arange(0 if include_start else save_every, nstep + 1, save_every, dtype=np.int64)
    if saves.size == 0 or saves[-1] != nstep:
        saves = np.append(saves, np.int64(nstep))
    return saves


def _scheme(name) -> type[Scheme]:
    if name not in SCHEMES:
        raise InvalidRunError(f"scheme = {name!r}: unknown; available: {', '.join(SCHEMES)}")
    return SCHEMES[name]


def _vec(name: str, value, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a new writable float array of ``shape``, every entry finite. Always a copy:
    numba compiles a read-only array (a scenario's frozen gravity) as another type, a second
    compilation of every kernel it reaches."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidStateError(f"{name} = {value!r}: expected real numbers ({exc})") from None
    if a.shape != shape:
        raise InvalidStateError(f"{name}: expected shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        idx = ", ".join(str(i) for i in bad)
        raise InvalidStateError(f"{name}[{idx}] = {float(a[bad])!r}: every entry must be finite")
    return a


def _params(body: Body) -> np.ndarray:
    P = np.zeros(K.NP)
    P[0] = body.mass
    P[1:10] = body.Jbar.ravel()
    P[10:19] = body.Ibar.ravel()
    P[19:28] = np.linalg.inv(body.Ibar).ravel()  # Ibar is positive definite (all I_k > 0)
    if body.pivot is not None:
        P[28:31] = body.pivot
        P[31] = 1.0
    if not np.any(body.Ibar - np.diag(np.diag(body.Ibar))):
        P[32] = 1.0
        I = np.diag(body.Ibar)
        e = np.array([I[2] - I[1], I[0] - I[2], I[1] - I[0]])
        P[33:36] = P[[19, 23, 27]] * e
    return P


def _pivot_state(name_x, name_v, x, v, R, W, c, where=""):
    """With a pivot the COM state follows from the rotation: accept x, v only if zero (the
    defaults) or equal to -R c and -R (W x c) to 1e-12 relative; else an error."""
    x_p = -R @ c
    v_p = -R @ np.cross(W, c)
    for name, given, implied in ((name_x, x, x_p), (name_v, v, v_p)):
        if not np.any(given):
            continue
        tol = 1e-12 * max(1.0, float(np.max(np.abs(implied))))
        if float(np.max(np.abs(given - implied))) > tol:
            raise InvalidStateError(
                f"{name}{where} = {given.tolist()} given with a pivot: with a fixed point the "
                f"centre of mass follows from the rotation (x_G = -R pivot, v_G = -R (W x "
                f"pivot), here {implied.tolist()}); leave {name} at its default (zeros)"
            )
    return x_p, v_p


def _state(x, v, R, W) -> np.ndarray:
    S = np.zeros(K.NS)
    S[0:3] = x
    S[3:6] = v
    S[6:15] = R.ravel()
    S[15:24] = (R @ hat(W)).ravel()
    return S


def _step_error(scheme: type[Scheme], status: int, info, dt: float, body=None, step0: int = 0):
    """StepSizeError for a failure reported by a kernel; ``step0`` steps were done before
    the kernel call (a stepper's earlier chunks)."""
    done = step0 + int(info[0])
    wnorm = float(info[1])
    t = done * dt
    h_max = scheme.h_max(wnorm, float(info[2]))
    who = "" if body is None else f"body {body}: "
    msg = (
        f"{who}{scheme.name}: step {done + 1} starting at t = {t:.9g} s could not be solved: "
        f"{K.STATUS_TEXT.get(status, 'unknown failure')}. dt = {dt:.6g} s, |W| = "
        f"{wnorm:.6g} rad/s, estimated step-size limit h_max ~ {h_max:.3g} s "
        f"({scheme.limit_rule}); reduce dt below h_max."
    )
    return StepSizeError(msg, time=t, step=done + 1, dt=dt, h_max=h_max, body=body)


_COMPILED: set[tuple] = set()


def _ensure_compiled(kind: str, method: int | None = None) -> None:
    """Compile (or load from the on-disk cache) a kernel with a harmless 1-step run of a unit
    sphere at rest, so that the timed call measures stepping only. ``kind``: "single" (the
    kernel of ``method`` with compensated sums, ``K.kernel(method)``), "plain" (plain sums),
    "parallel" or "serial" (the batch loops, both methods; ``method`` unused). A single-body
    run compiles only its own method's kernel."""
    key = (kind, method if kind in ("single", "plain") else None)
    if key in _COMPILED:
        return
    P = _params(Body.make(1.0, (1.0, 1.0, 1.0)))
    S = _state(np.zeros(3), np.zeros(3), np.eye(3), np.zeros(3))
    saves = np.array([0, 1], dtype=np.int64)
    g = np.zeros(3)
    coef = np.ones(1)
    if kind in ("single", "plain"):
        fn = K.kernel(method, compensated=kind == "single")
        fn(
            coef, P, g, S.copy(), 0.1, 1, saves, np.empty((2, 3)), np.empty((2, 3)),
            np.empty((2, 3, 3)), np.empty((2, 3, 3)), np.zeros(3), True, 0,
        )  # fmt: skip
        K.init_state(method, P, g, S.copy())
    else:
        fn = K.run_batch_parallel if kind == "parallel" else K.run_batch_serial
        for m in (K.RATTLE_FAMILY, K.ENERGY_MOMENTUM):
            fn(
                m, coef, P[None], g, S[None], 0.1, 1, saves, np.empty((1, 2, 3)),
                np.empty((1, 2, 3)), np.empty((1, 2, 3, 3)), np.empty((1, 2, 3, 3)),
                np.zeros(1, dtype=np.int64), np.zeros((1, 3)), np.zeros(1, dtype=np.int64), 1,
            )  # fmt: skip
    _COMPILED.add(key)


def _finish(cls, scheme, t, X, V, D, Dp, mass, Jbar, pivoted, g, nstep, wall, cpu, dt):
    return cls(
        t=t,
        position=X,
        velocity=V,
        rotation=D,
        director_velocity=Dp,
        nstep=nstep,
        wall_time_s=wall,
        cpu_time_s=cpu,
        dt=dt,
        scheme=scheme.name,
        _mass=mass,
        _Jbar=Jbar,
        _pivoted=pivoted,
        _gravity=g,
    )


# --------------------------------------------------------------------------------------------
# public entry points
# --------------------------------------------------------------------------------------------


class StepperState(NamedTuple):
    """The state of a :class:`Stepper`, SI units: ``position`` x_G (3,), m, and ``velocity``
    v_G (3,), m/s, world axes (x_G = -R c, v_G = -R (W x c) with a pivot); ``rotation`` R
    (3, 3), body-to-world, columns are the directors; ``omega_body`` W (3,), rad/s, body
    axes (= vee of the skew part of R^T R', as :attr:`Trajectory.omega_body`)."""

    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray


def _check_count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidRunError(f"{name} = {value!r}: must be a whole number >= 1")
    return int(value)


class Stepper:
    """One rigid body advanced in chunks of steps, the integrator state kept between chunks.

    The state is the scheme's own (directors, momentum and their compensations, cached
    torque, multipliers), not the (R, W) it is reported in, so that ``advance(n1)`` then
    ``advance(n2)`` gives, bit for bit, the states of one ``simulate`` run of n1 + n2 steps
    (restarting from converted (R, W) states would not).

    Parameters (SI units) as in :func:`simulate`: ``mass`` (kg), ``inertia`` (3,) principal
    moments (kg m^2), ``rotation`` (3, 3) initial R (body-to-world), ``omega_body`` (3,)
    initial W (rad/s, body axes), ``position``/``velocity`` (3,) initial x_G, v_G (m, m/s,
    world; zeros with a pivot), ``gravity`` (3,) (m/s^2, world), ``pivot`` (3,) or None (m,
    body axes rel. to the COM; the fixed point is the world origin), ``scheme`` (a key of
    :data:`director_model.SCHEMES`), ``dt`` (s, the step of every chunk). ``compensated``
    (default True): sums into the state with Kahan compensation (see the package README);
    False gives the plain floating-point sums, for round-off studies only.

    Attributes: ``dt`` (s), ``scheme`` (name), ``compensated``, ``nstep_done`` (steps
    completed since construction), ``time`` (= nstep_done * dt, s).

    Raises InvalidBodyError, InvalidStateError, InvalidRunError at construction (as
    :func:`simulate`), StepSizeError from :meth:`advance`.
    """

    def __init__(
        self,
        mass: float,
        inertia,
        *,
        rotation,
        omega_body,
        position=(0.0, 0.0, 0.0),
        velocity=(0.0, 0.0, 0.0),
        gravity=(0.0, 0.0, 0.0),
        pivot=None,
        scheme: str = "rattle",
        dt: float,
        compensated: bool = True,
    ):
        body = Body.make(mass, inertia, pivot)
        R = check_rotation(rotation, "rotation")
        W = _vec("omega_body", omega_body, (3,))
        x = _vec("position", position, (3,))
        v = _vec("velocity", velocity, (3,))
        g = _vec("gravity", gravity, (3,))
        sch = _scheme(scheme)
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise InvalidRunError(f"dt = {dt!r}: must be a real number") from None
        if not (dt > 0 and math.isfinite(dt)):
            raise InvalidRunError(f"dt = {dt!r}: the time step must be positive and finite")
        if not isinstance(compensated, bool | np.bool_):
            raise InvalidRunError(f"compensated = {compensated!r}: must be True or False")
        if body.pivoted:
            x, v = _pivot_state("position", "velocity", x, v, R, W, body.pivot)
        self._body = body
        self._scheme_cls = sch
        self._coef = sch.coefficient_array()
        self._P = _params(body)
        self._g = g
        self._S = _state(x, v, R, W)
        self.dt = dt
        self.scheme = sch.name
        self.compensated = bool(compensated)
        self.nstep_done = 0
        self._kernel = K.kernel(sch.method, compensated=self.compensated)
        _ensure_compiled("single" if self.compensated else "plain", sch.method)
        K.init_state(sch.method, self._P, g, self._S)

    @property
    def time(self) -> float:
        """Time reached, s (nstep_done * dt)."""
        return self.nstep_done * self.dt

    def state(self) -> StepperState:
        """The current state as (position, velocity, rotation, omega_body), new arrays."""
        X, V = np.empty((1, 3)), np.empty((1, 3))
        D, Dp = np.empty((1, 3, 3)), np.empty((1, 3, 3))
        K.store_state(self._scheme_cls.method, self._P, self._S, self._g, self.time, X, V, D, Dp)
        return StepperState(X[0], V[0], D[0], omega_body_from_directors(D, Dp)[0])

    def advance(self, nstep: int, save_every: int = 1, include_start: bool = False, *,
                stepped=None) -> Trajectory:  # fmt: skip
        """Advance by ``nstep`` steps of ``dt`` and return the states saved in this chunk.

        Saved: the steps j * save_every (j = 1, 2, ...) of the chunk and always its last
        step, counted from the chunk's start; the start state itself only with
        ``include_start`` (it is the previous chunk's last state). ``Trajectory.t`` is the
        absolute time (nstep_done + j) * dt, ``Trajectory.nstep`` the steps of this chunk.
        ``simulate(..., dt, t_end, save_every)`` equals
        ``Stepper(..., dt).advance(round(t_end/dt), save_every, include_start=True)``.

        Raises StepSizeError (``time``: the absolute time of the failing step's start) if a
        step cannot be solved; the stepper then stays at the last completed step
        (``nstep_done`` counts it) and the chunk's states are not returned.

        ``stepped``: called with no argument as soon as the compiled stepping has returned,
        before the invariants are computed from the saved states (where a caller timing the
        stepping stops its clock).
        """
        nstep = _check_count("nstep", nstep)
        save_every = _check_count("save_every", save_every)
        saves = saved_steps(nstep, save_every, include_start)
        nsave = saves.shape[0]
        X = np.empty((nsave, 3))
        V = np.empty((nsave, 3))
        D = np.empty((nsave, 3, 3))
        Dp = np.empty((nsave, 3, 3))
        info = np.zeros(3)
        sch = self._scheme_cls
        step0 = self.nstep_done
        c0 = time.thread_time()
        t0 = time.perf_counter()
        status = self._kernel(
            self._coef, self._P, self._g, self._S, self.dt, nstep, saves, X, V, D,
            Dp, info, False, step0,
        )  # fmt: skip
        wall = time.perf_counter() - t0
        cpu = time.thread_time() - c0
        if stepped is not None:
            stepped()
        if status != K.OK:
            self.nstep_done = step0 + int(info[0])
            raise _step_error(sch, int(status), info, self.dt, step0=step0)
        self.nstep_done = step0 + nstep
        t = (step0 + saves) * self.dt
        b = self._body
        return _finish(
            Trajectory, sch, t, X, V, D, Dp, b.mass, b.Jbar, b.pivoted, self._g, nstep, wall, cpu,
            self.dt,
        )  # fmt: skip


def simulate(
    mass: float,
    inertia,
    *,
    rotation,
    omega_body,
    position=(0.0, 0.0, 0.0),
    velocity=(0.0, 0.0, 0.0),
    gravity=(0.0, 0.0, 0.0),
    pivot=None,
    scheme: str = "rattle",
    dt: float,
    t_end: float,
    save_every: int = 1,
    compensated: bool = True,
) -> Trajectory:
    """Integrate one rigid body in director form and return its saved states.

    Parameters (SI units)
    ---------------------
    mass : float
        m > 0, kg.
    inertia : array_like (3,)
        Principal moments (I_1, I_2, I_3) about the centre of mass, kg m^2, in body axes;
        must satisfy the triangle inequality; a flat body (I_i = I_j + I_k) is fine, a thin
        rod is rejected.
    rotation : array_like (3, 3)
        Initial body-to-world rotation R (columns: directors d1, d2, d3); orthonormal to 1e-12
        with det +1, never repaired. From a quaternion: :func:`rotation_from_quat_wxyz`.
    omega_body : array_like (3,)
        Initial angular velocity W in body axes, rad/s.
    position, velocity : array_like (3,)
        Initial centre of mass x_G and v_G, world axes, m and m/s. With a pivot they follow
        from the rotation; leave them at zero (values equal to -R c and -R (W x c) to 1e-12
        are accepted, anything else is an error).
    gravity : array_like (3,)
        Uniform gravity g, world axes, m/s^2; V = -m g . x_G.
    pivot : array_like (3,) or None
        Fixed point in body axes relative to the centre of mass, m; the fixed point is the
        world origin.
    scheme : str
        A key of :data:`director_model.SCHEMES`: "rattle" (order 2), "rattle4", "rattle6",
        "energy_momentum".
    dt, t_end : float
        Step and horizon, s; t_end must be a whole number of steps (see :func:`step_plan`).
    save_every : int
        Save every ``save_every``-th step; step 0 and the last step are always saved.
    compensated : bool
        Sums into the state with Kahan compensation (default); False gives the plain
        floating-point sums, whose round-off grows with the number of steps (for round-off
        studies only).

    Returns
    -------
    Trajectory
        Arrays of shape (nsave, ...); see :class:`Trajectory`.

    Raises
    ------
    InvalidBodyError, InvalidStateError, InvalidRunError
        Before any stepping, naming argument, value and rule.
    StepSizeError
        If a step cannot be solved; names the time reached and a step-size limit estimate.

    Runs :class:`Stepper` for the whole horizon. The time loop runs in numba-compiled code
    (cached on disk). For debugging as plain Python set ``NUMBA_DISABLE_JIT=1`` before
    importing director_model.
    """
    stepper = Stepper(
        mass, inertia, rotation=rotation, omega_body=omega_body, position=position,
        velocity=velocity, gravity=gravity, pivot=pivot, scheme=scheme, dt=dt,
        compensated=compensated,
    )  # fmt: skip
    nstep, _ = step_plan(dt, t_end, save_every)
    return stepper.advance(nstep, int(save_every), include_start=True)


def _batch_vec(name: str, value, n: int) -> np.ndarray:
    """None -> zeros; (3,) shared -> broadcast; else must be (n, 3)."""
    if value is None:
        return np.zeros((n, 3))
    if np.shape(value) == (3,):
        value = np.broadcast_to(np.asarray(value, dtype=float), (n, 3))
    return _vec(name, value, (n, 3))


def _per_body(name: str, value, nbody: int, width: int | None) -> np.ndarray:
    """Broadcast a shared or per-body parameter to (nbody,) or (nbody, width)."""
    a = np.asarray(value, dtype=float)
    shared = () if width is None else (width,)
    if a.shape == shared:
        return np.broadcast_to(a, (nbody,) + shared)
    if a.shape == (nbody,) + shared:
        return a
    raise InvalidBodyError(
        f"{name}: expected shape {shared} (shared) or {(nbody,) + shared} (per body), got {a.shape}"
    )


def _batch_bodies(mass, inertia, rotation, omega_body, position, velocity, pivot):
    """(n, P, S0, Jbar, masses, pivots or None): the bodies of :func:`simulate_batch` checked
    one by one (an error names the body) and packed as the kernels' parameter and state rows."""
    try:
        R_all = np.asarray(rotation, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidStateError(f"rotation: expected an (N, 3, 3) array ({exc})") from None
    if R_all.ndim != 3 or R_all.shape[1:] != (3, 3) or R_all.shape[0] < 1:
        raise InvalidStateError(f"rotation: expected shape (N, 3, 3), N >= 1, got {R_all.shape}")
    n = R_all.shape[0]
    W_all = _vec("omega_body", omega_body, (n, 3))
    x_all = _batch_vec("position", position, n)
    v_all = _batch_vec("velocity", velocity, n)
    m_all = _per_body("mass", mass, n, None)
    I_all = _per_body("inertia", inertia, n, 3)
    c_all = None if pivot is None else _per_body("pivot", pivot, n, 3)
    P = np.empty((n, K.NP))
    S0 = np.empty((n, K.NS))
    Jbar = np.empty((n, 3, 3))
    for i in range(n):
        where = f"[{i}]"
        try:
            body = Body.make(m_all[i], I_all[i], None if c_all is None else c_all[i])
        except InvalidBodyError as exc:
            raise InvalidBodyError(f"body {i}: {exc}") from None
        R = check_rotation(R_all[i], f"rotation{where}")
        x, v = x_all[i], v_all[i]
        if body.pivoted:
            x, v = _pivot_state("position", "velocity", x, v, R, W_all[i], body.pivot, where)
        P[i] = _params(body)
        S0[i] = _state(x, v, R, W_all[i])
        Jbar[i] = body.Jbar
    return n, P, S0, Jbar, m_all, c_all


def simulate_batch(
    mass,
    inertia,
    *,
    rotation,
    omega_body,
    position=None,
    velocity=None,
    gravity=(0.0, 0.0, 0.0),
    pivot=None,
    scheme: str = "rattle",
    dt: float,
    t_end: float,
    save_every: int = 1,
    parallel: bool = True,
) -> BatchTrajectory:
    """Integrate N bodies with different initial conditions (and optionally different mass
    and inertia) with the same step plan, in parallel over bodies (numba prange).

    Shapes: ``rotation`` (N, 3, 3), ``omega_body`` (N, 3); ``position``/``velocity`` None
    (zeros), (3,) shared or (N, 3); ``mass`` scalar or (N,); ``inertia`` (3,) or (N, 3);
    ``pivot`` None, (3,) or (N, 3) (all bodies pivoted or none); ``gravity`` (3,) shared.
    Other arguments and units as in :func:`simulate`.

    Returns a :class:`BatchTrajectory`, arrays ``nbody x nsave x ...``. RATTLE-family schemes
    advance blocks of up to 32 bodies together, one SIMD lane per body, with the operations
    of the single-body code in the same order (a lane the vector code cannot finish goes
    through the single-body code), so body i equals ``simulate(...)`` of body i bit for bit.
    Always with compensated sums (``compensated=True`` of :func:`simulate`).
    ``parallel=False`` runs on one thread.
    Every body is validated before any stepping (messages prefixed with the body index);
    if any body fails a step, StepSizeError names the first failing body.
    """
    n, P, S0, Jbar, m_all, c_all = _batch_bodies(
        mass, inertia, rotation, omega_body, position, velocity, pivot
    )
    g = _vec("gravity", gravity, (3,))
    sch = _scheme(scheme)
    nstep, saves = step_plan(dt, t_end, save_every)
    dt = float(dt)
    nsave = saves.shape[0]
    X = np.empty((n, nsave, 3))
    V = np.empty((n, nsave, 3))
    D = np.empty((n, nsave, 3, 3))
    Dp = np.empty((n, nsave, 3, 3))
    status = np.zeros(n, dtype=np.int64)
    info = np.zeros((n, 3))
    vec = np.zeros(n, dtype=np.int64)
    kind = "parallel" if parallel else "serial"
    _ensure_compiled(kind)
    fn = K.run_batch_parallel if parallel else K.run_batch_serial
    coef = sch.coefficient_array()
    nblock = K.block_count(n, numba.get_num_threads() if parallel else 1)
    c0 = time.process_time()
    t0 = time.perf_counter()
    fn(sch.method, coef, P, g, S0, dt, nstep, saves, X, V, D, Dp, status, info, vec, nblock)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    bad = np.flatnonzero(status != K.OK)
    if bad.size:
        i = int(bad[0])
        err = _step_error(sch, int(status[i]), info[i], dt, body=i)
        if bad.size > 1:
            err.args = (f"{err.args[0]} ({bad.size} of {n} bodies failed)",)
        raise err
    t = saves * dt
    bt = _finish(
        BatchTrajectory,
        sch,
        t,
        X,
        V,
        D,
        Dp,
        np.asarray(m_all)[:, None],
        Jbar[:, None],
        c_all is not None,
        g,
        nstep,
        wall,
        cpu,
        dt,
    )
    bt.vector_substeps = vec
    return bt
