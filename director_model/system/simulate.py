"""Entry points for systems: :func:`simulate_system` and :class:`SystemStepper`."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from director_model.errors import InvalidRunError, InvalidStateError, StepSizeError
from director_model.schemes.composition import Rattle4, Rattle6
from director_model.schemes.rattle import Rattle
from director_model.simulate import saved_steps, step_plan
from director_model.system import _kernels as K
from director_model.system.model import Assembly, assemble, assemble_forces, band_order
from director_model.system.states import (
    check_initial,
    energy_momentum,
    force_potential,
    rows_numpy,
)

#: scheme name -> (order, sub-step coefficients); the coefficients are those of the
#: single-body compositions (Yoshida 1990 triple jump; Kahan & Li 1997 s9odr6a)
SYSTEM_SCHEMES = {
    "rattle": (2, tuple(Rattle.coefficients)),
    "rattle4": (4, tuple(Rattle4.coefficients)),
    "rattle6": (6, tuple(Rattle6.coefficients)),
}

#: the joint rows are solved to TOL_EPS * eps * max(length scale, largest |x_i|)
TOL_EPS = 16.0
#: relative singular value below which the minimum-norm solver drops a direction
RANK_TOL = 1e-10
#: the kernel's ``minnorm`` mode of each rank-revealing solver
_MODES = {"minnorm": K.MODE_PIVOTED, "svd": K.MODE_SVD}


@dataclass(eq=False)
class SystemTrajectory:
    """Saved states of a system run (n saved times, nb bodies in the order given), SI units,
    world axes unless said.

    =======================  ===============  ===============================================
    field                    shape            meaning
    =======================  ===============  ===============================================
    ``t``                    (n,)             time, s
    ``position``             (n, nb, 3)       centre of mass x, m
    ``velocity``             (n, nb, 3)       v, m/s
    ``rotation``             (n, nb, 3, 3)    R body-to-world (columns: directors)
    ``omega_body``           (n, nb, 3)       W, body axes, rad/s
    ``energy``               (n,)             sum 1/2 m|v|^2 + 1/2 W.I W - m g.x, J, plus the
                                              force elements' potential
    ``linear_momentum``      (n, 3)           sum m v, kg m/s
    ``angular_momentum``     (n, 3)           about the world origin: sum x x m v + R I W
    ``constraint_position``  (n,)             max |g_r| over the joint rows (m; axis rows:
                                              dot products)
    ``constraint_velocity``  (n,)             max |dg_r/dt| (m/s; axis rows 1/s)
    ``orthonormality``       (n,)             max over bodies of max |R^T R - 1|
    =======================  ===============  ===============================================

    Scalars: ``body_names``, ``joint_names`` (tuples), ``nstep`` (steps of this run or
    chunk), ``dt``, ``scheme``, ``wall_time_s``/``cpu_time_s`` (the compiled stepping
    alone), ``solver`` ("block": 3x3-block tridiagonal elimination, "banded": banded LU and
    L D L^T, "minnorm": rank-revealing banded factorisations with the SVD near singular
    configurations, or "svd": the SVD throughout),
    ``newton_iterations`` (chord-Newton iterations of the position multipliers over all
    sub-steps), ``max_iterations`` (most in one sub-step),
    ``rank_nominal`` (rank of the constraint Jacobian at t = 0), ``rank_drop_steps``
    (RATTLE sub-steps at which the velocity-stage matrix had a numerical rank, singular
    values above RANK_TOL sigma_1, below the nominal rank: a singular configuration),
    ``min_singular_value``
    (smallest sigma_rank_nominal / sigma_1 of that matrix over the steps where its singular
    values were computed: by the SVD, or without vectors where the loop solver's L D L^T
    kept a pivot below PIVOT_CHECK = 1e-8 of the largest diagonal entry on a single loop of
    5-row joints; on the others, the loop solver's smallest kept pivot over that entry, at
    least PIVOT_CHECK; NaN for the banded and block solvers,
    which do not compute it),
    ``min_singular_step`` (the absolute step index where it occurred; -1 for the banded
    solver), ``svd_factorisations`` (multiplier matrices decomposed by SVD: every one with
    "svd", near singular configurations with "minnorm") and ``split_steps`` (loop solvers:
    steps done again from their start as 2, 3, ... steps of dt/2, dt/3, ..., because a
    sub-step inside them landed where the velocity stage's solve dropped a direction of the
    joint rows, _common.MAXSPLIT; the singularity diagnostics count the landings kept) and
    ``kept_singular_steps`` (steps taken as they came after every split up to MAXSPLIT had
    such a landing too).
    The invariants and residuals are computed from the saved states in numpy, independently
    of the compiled step.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    energy: np.ndarray
    linear_momentum: np.ndarray
    angular_momentum: np.ndarray
    constraint_position: np.ndarray
    constraint_velocity: np.ndarray
    orthonormality: np.ndarray
    body_names: tuple
    joint_names: tuple
    nstep: int
    dt: float
    scheme: str
    wall_time_s: float
    cpu_time_s: float
    solver: str
    newton_iterations: int
    max_iterations: int
    rank_nominal: int
    rank_drop_steps: int
    min_singular_value: float
    min_singular_step: int
    svd_factorisations: int
    split_steps: int = 0
    kept_singular_steps: int = 0

    def __len__(self) -> int:
        return self.t.shape[0]

    def body_index(self, name: str) -> int:
        """Index of the body ``name`` in the arrays' body axis."""
        try:
            return self.body_names.index(name)
        except ValueError:
            raise KeyError(
                f"body {name!r}: unknown; the bodies are {list(self.body_names)}"
            ) from None


def _check_count(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidRunError(f"{name} = {value!r}: must be a whole number >= 1")
    return int(value)


_COMPILED: set[bool] = set()


def _ensure_compiled(banded: bool) -> None:
    """Compile or load the kernel of a solver (``banded``: :func:`K.run_system_banded`, else
    :func:`K.run_system`, the block and minnorm solvers) with a 1-step run of a small
    system, so that the timed call measures stepping only."""
    if banded in _COMPILED:
        return
    from director_model.system.model import Body, Joint

    bodies = [Body("a", 1.0, (1.0, 1.0, 1.0), position=(0, 0, -1)),
              Body("b", 1.0, (1.0, 1.0, 1.0), position=(0, 0, -3))]  # fmt: skip
    joints = [Joint("spherical", "a", None, (0, 0, 1), (0, 0, 0)),
              Joint("spherical", "a", "b", (0, 0, -1), (0, 0, 1))]  # fmt: skip
    st = SystemStepper(bodies, joints, gravity=(0, 0, -1), dt=0.01,
                       solver="banded" if banded else "block", _warm=False)  # fmt: skip
    st.advance(1)
    _COMPILED.add(banded)


class SystemStepper:
    """A system of rigid bodies and joints advanced in chunks, the integrator state (the
    director state, its compensations and the last multipliers) kept between chunks, so
    that ``advance(n1)`` then ``advance(n2)`` saves bit for bit the states of one run of
    n1 + n2 steps.

    Parameters
    ----------
    bodies : list of :class:`Body`
        The bodies and their initial states.
    joints : list of :class:`Joint`
        The joints (bodies named by ``Body.name``; ``body_b=None`` is the ground).
    gravity : (3,)
        Uniform gravity, m/s^2, world axes.
    scheme : str
        "rattle" (order 2), "rattle4" (Yoshida triple jump, order 4), "rattle6" (Kahan-Li
        9-stage composition, order 6).
    dt : float
        Step, s.
    solver : str
        "auto" (default): "minnorm" if the joint rows are redundant at t = 0 (rank of the
        Jacobian below the number of rows: closed loops such as a planar four-bar of
        revolute joints, or Bricard's mechanism), else "block" where it applies, else
        "banded". "block": chains of spherical (and fixed-point) joints listed along the
        chain; the matrices are block tridiagonal with 3x3 blocks, assembled and eliminated
        block by block in straight-line code (same equations as "banded", to round-off).
        "banded": block-banded LU
        without pivoting of the multiplier matrices (rows ordered as the joints are given;
        bandwidth = the largest row distance between rows sharing a body, so a chain whose
        joints are listed along it has cost linear in its length); a singular configuration
        stops it with StepSizeError. "minnorm" (the loop solver): the joints reordered along
        the loops (model.band_order) and the multiplier matrices factorised in their band,
        rank-revealing in the row order: the velocity stage's L D L^T drops every row
        dependent on the rows before it (pivot below DROP_TOL = 1e-10 of its diagonal entry:
        a redundant row), the Newton matrix's LU the same rows, a basic solution over the
        rest (correct for rank-deficient Jacobians: the joint forces are those of the
        minimum-norm solution); where a kept pivot falls below PIVOT_CHECK = 1e-8 of the
        largest diagonal entry (near a singular configuration) the matrix goes to the SVD
        and the minimum-norm solution instead (the singularity diagnostics of
        :class:`SystemTrajectory` then come from it), except on a single loop of 5-row
        joints (the four-bar, Bricard's linkage): there the velocity stage's singular values
        are computed without vectors (the diagnostics come from them) and its L D L^T
        stands where they show the nominal rank, the one it kept, and sigma_rank /
        sigma_1 >= 1e-12, and the Newton matrix's LU stands down to pivots of 1e-12; cost
        linear in the number of rows for
        loops of bounded size. "svd": the SVD at every solve, with the minimum-norm
        multipliers (kept to compare; about 10x the cost of "minnorm" on the four-bar).

    Raises InvalidBodyError, InvalidStateError, InvalidJointError, InvalidMechanismError,
    InvalidRunError at construction; StepSizeError from :meth:`advance` (a step whose
    equations have no solution: too large a step, or a singular configuration for the
    banded solver), after which the stepper stays at the last completed step.
    """

    def __init__(self, bodies, joints, *, gravity=(0.0, 0.0, 0.0), scheme: str = "rattle",
                 dt: float, solver: str = "auto", springs=(), torques=(),
                 _warm: bool = True):  # fmt: skip
        bodies = list(bodies)
        joints = list(joints)
        asm = assemble(bodies, joints)
        rank, dof = check_initial(asm, bodies)
        self._fint, self._fvec = assemble_forces(bodies, joints, list(springs), list(torques))
        self._theta = np.zeros(self._fint.shape[0])
        if scheme not in SYSTEM_SCHEMES:
            raise InvalidRunError(
                f"scheme = {scheme!r}: unknown; available: {', '.join(SYSTEM_SCHEMES)}"
            )
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise InvalidRunError(f"dt = {dt!r}: must be a real number") from None
        if not (dt > 0 and math.isfinite(dt)):
            raise InvalidRunError(f"dt = {dt!r}: the time step must be positive and finite")
        try:
            g = np.array(gravity, dtype=float)  # a writable copy: see _vec3 in model.py
        except (TypeError, ValueError):
            raise InvalidStateError(f"gravity = {gravity!r}: expected 3 real numbers") from None
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise InvalidStateError(f"gravity = {gravity!r}: expected 3 finite real numbers")
        nrow = asm.rint.shape[0]
        if solver == "auto":
            solver = "minnorm" if rank < nrow else ("block" if asm.block3 else "banded")
        if solver not in ("banded", "block", "minnorm", "svd"):
            raise InvalidRunError(
                f"solver = {solver!r}: expected 'auto', 'block', 'banded', 'minnorm' or 'svd'"
            )
        if solver == "block" and not asm.block3:
            raise InvalidRunError(
                "solver = 'block': needs spherical or fixed-point joints only, listed along a "
                "chain (joints sharing a body adjacent in the list); use 'banded' or 'auto'"
            )
        if solver in ("banded", "block") and rank < nrow:
            raise InvalidRunError(
                f"solver = 'banded': the {nrow} joint rows have rank {rank} at t = 0 "
                "(redundant constraints, e.g. a closed loop): use solver='minnorm' or 'auto'"
            )
        self._asm: Assembly = asm
        # the rows as the kernel sees them: for the loop solver the joints in an order that
        # keeps the rows sharing a body close (the factorisations are banded); the other
        # solvers and every result keep the given order
        self._kasm: Assembly = asm
        if solver == "minnorm":
            order = band_order(joints, {n: i for i, n in enumerate(asm.names)})
            if order != list(range(len(joints))):
                self._kasm = assemble(bodies, [joints[k] for k in order])
        self._g = g
        self._coef = np.array(SYSTEM_SCHEMES[scheme][1], dtype=float)
        self.scheme = scheme
        self.dt = dt
        self.solver = solver
        self.rank_nominal = rank
        self.dof = dof
        self.nstep_done = 0
        nb = len(bodies)
        self._D0 = np.array([b.rotation.ravel() for b in bodies])
        S = np.zeros((nb, K.NS))
        for i, b in enumerate(bodies):
            S[i, 0:3] = b.position
            S[i, 6:9] = b.velocity
            S[i, 12] = 1.0
            S[i, 20:23] = b.inertia * b.omega_body
        self._S = S
        self._mu = np.zeros(max(nrow, 1) * (2 + 3 * len(self._coef)) + 2)  # see _run_system
        self._bodies = bodies
        if _warm:
            _ensure_compiled(solver == "banded")

    @property
    def time(self) -> float:
        """Time reached, s (nstep_done * dt)."""
        return self.nstep_done * self.dt

    def advance(self, nstep: int, save_every: int = 1, include_start: bool = False, *,
                stepped=None):  # fmt: skip
        """Advance ``nstep`` steps; save the steps j * save_every of the chunk and its last
        step (and its start with ``include_start``). Returns a :class:`SystemTrajectory`
        with absolute times. Raises StepSizeError naming the time and the step.
        ``stepped``: called with no argument as soon as the compiled stepping has returned,
        before the invariants and residuals are computed from the saved states (where a
        caller timing the stepping stops its clock)."""
        nstep = _check_count("nstep", nstep)
        save_every = _check_count("save_every", save_every)
        saves = saved_steps(nstep, save_every, include_start)
        asm = self._kasm
        nb = len(self._bodies)
        ns = saves.shape[0]
        X = np.empty((ns, nb, 3))
        V = np.empty((ns, nb, 3))
        D = np.empty((ns, nb, 3, 3))
        W = np.empty((ns, nb, 3))
        diag = np.zeros(K.NDIAG)
        diag[K.D_SMIN] = np.inf
        info = np.zeros(2)
        minnorm = _MODES.get(self.solver, 0)
        rint = asm.rint if asm.rint.shape[0] else np.zeros((0, 4), dtype=np.int64)
        c0 = time.thread_time()
        t0 = time.perf_counter()
        args = (
            asm.bodies, self._D0, rint, asm.rvec, asm.brow_ptr, asm.brow_idx, asm.brow_side,
            self._g, self._S, self._mu, self._coef, self.dt, nstep, saves, X, V, D, W,
        )  # fmt: skip
        rest = (
            asm.bandwidth, self.rank_nominal, RANK_TOL, TOL_EPS * K.EPS, asm.length_scale, diag,
            info, asm.jptr, asm.jidx, asm.jside, self._fint, self._fvec,
        )  # fmt: skip
        if self.solver == "banded":
            status = K.run_system_banded(*args, *rest)
        else:
            status = K.run_system(*args, minnorm, *rest)
        wall = time.perf_counter() - t0
        cpu = time.thread_time() - c0
        if stepped is not None:
            stepped()
        step0 = self.nstep_done
        if status != K.OK:
            done = step0 + int(info[0])
            self.nstep_done = done
            t = done * self.dt
            raise StepSizeError(
                f"{self.scheme}: step {done + 1} starting at t = {t:.9g} s could not be "
                f"solved: {K.STATUS_TEXT.get(int(status), 'unknown failure')} (sub-step "
                f"h = {info[1]:.6g} s of dt = {self.dt:.6g} s); reduce dt",
                time=t,
                step=done + 1,
                dt=self.dt,
                h_max=None,
            )
        self.nstep_done = step0 + nstep
        return self._trajectory((step0 + saves) * self.dt, X, V, D, W, nstep, wall, cpu, diag)

    def _trajectory(self, t, X, V, D, W, nstep, wall, cpu, diag):
        asm = self._asm
        E, p, L = energy_momentum(asm.bodies, self._g, X, V, D, W)
        if self._fint.shape[0]:
            R0 = self._D0.reshape(-1, 3, 3)
            Vf, self._theta = force_potential(self._fint, self._fvec, X, D, R0, self._theta)
            E = E + Vf
        if asm.rint.shape[0]:
            gp, gv = rows_numpy(asm, X, D, V, W)
            cp = np.max(np.abs(gp), axis=-1)
            cv = np.max(np.abs(gv), axis=-1)
        else:
            cp = np.zeros(t.shape)
            cv = np.zeros(t.shape)
        RtR = np.einsum("...ki,...kj->...ij", D, D) - np.eye(3)
        orth = np.max(np.abs(RtR), axis=(-3, -2, -1))
        smin = float(diag[K.D_SMIN])
        return SystemTrajectory(
            t=t, position=X, velocity=V, rotation=D, omega_body=W, energy=E,
            linear_momentum=p, angular_momentum=L, constraint_position=cp,
            constraint_velocity=cv, orthonormality=orth, body_names=asm.names,
            joint_names=asm.joint_names, nstep=nstep, dt=self.dt, scheme=self.scheme,
            wall_time_s=wall, cpu_time_s=cpu, solver=self.solver,
            newton_iterations=int(diag[K.D_ITER]), max_iterations=int(diag[K.D_MAXIT]),
            rank_nominal=self.rank_nominal, rank_drop_steps=int(diag[K.D_RANKDROP]),
            min_singular_value=smin if math.isfinite(smin) else math.nan,
            min_singular_step=(
                int(diag[K.D_TSMIN]) + self.nstep_done - nstep if math.isfinite(smin) else -1
            ),
            svd_factorisations=int(diag[K.D_SVD]),
            split_steps=int(diag[K.D_SPLIT]),
            kept_singular_steps=int(diag[K.D_KEPT]),
        )  # fmt: skip


def simulate_system(bodies, joints, *, gravity=(0.0, 0.0, 0.0), scheme: str = "rattle",
                    dt: float, t_end: float, save_every: int = 1, solver: str = "auto",
                    springs=(), torques=()) -> SystemTrajectory:  # fmt: skip
    """Integrate a system of rigid bodies connected by joints and return the saved states.

    ``bodies`` (list of :class:`Body`), ``joints`` (list of :class:`Joint`), ``springs``
    and ``torques`` (lists of :class:`Spring`, :class:`Torque`: force elements), ``gravity``
    (3,) m/s^2, ``scheme`` ("rattle", "rattle4", "rattle6"), ``solver`` as in
    :class:`SystemStepper`; ``dt``, ``t_end`` (s) and ``save_every`` follow the step plan of
    :func:`director_model.step_plan` (t_end a whole number of steps; steps 0, s, 2s, ... and
    the last saved). Memory O(saved states). Equals
    ``SystemStepper(...).advance(round(t_end/dt), save_every, include_start=True)``.
    """
    st = SystemStepper(bodies, joints, gravity=gravity, scheme=scheme, dt=dt, solver=solver,
                       springs=springs, torques=torques)  # fmt: skip
    nstep, _ = step_plan(dt, t_end, save_every)
    return st.advance(nstep, int(save_every), include_start=True)
