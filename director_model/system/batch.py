"""Batches of systems of the same topology stepped in parallel: :func:`simulate_system_batch`.

N systems with the same bodies (names, masses, principal moments) and the same joints, each
with its own initial state, are advanced by the compiled single-system step
(:func:`director_model.system._kernels.run_system`, or ``run_system_banded`` for the banded
solver) called once per member inside a numba ``prange`` loop, so the members run on the
threads of numba's pool. Every member owns its state, multipliers, diagnostics and output
slices and no sum runs across members, so each member's saved states are bit for bit those
of its own :func:`simulate_system` run, whatever the number of threads.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

from director_model import _cache
from director_model.errors import InvalidRunError, StepSizeError
from director_model.simulate import saved_steps, step_plan
from director_model.system import _kernels as K
from director_model.system.simulate import (
    _MODES,
    RANK_TOL,
    TOL_EPS,
    SystemStepper,
    SystemTrajectory,
    _ensure_compiled,
)


@njit(parallel=True, cache=True)
def run_batch(
    B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X, V, D, W, minnorm,
    bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr, jidx, jside, fint, fvec, status,
):  # fmt: skip
    """:func:`run_system` (the block or minnorm solver) for each member k of a batch (leading
    axis of D0, S, mu, X, V, D, W, diag, info; status (nbatch,) receives each member's
    return value), members spread over numba's threads."""
    for k in prange(S.shape[0]):
        status[k] = K.run_system(
            B, D0[k], rint, rvec, ptr, idx, side, g, S[k], mu[k], coef, dt, nstep, saves,
            X[k], V[k], D[k], W[k], minnorm, bw, rank_nom, rank_tol, tol_rel, Lsc, diag[k],
            info[k], jptr, jidx, jside, fint, fvec,
        )  # fmt: skip


@njit(parallel=True, cache=True)
def run_batch_banded(
    B, D0, rint, rvec, ptr, idx, side, g, S, mu, coef, dt, nstep, saves, X, V, D, W,
    bw, rank_nom, rank_tol, tol_rel, Lsc, diag, info, jptr, jidx, jside, fint, fvec, status,
):  # fmt: skip
    """:func:`run_batch` with the banded solver (:func:`run_system_banded`)."""
    for k in prange(S.shape[0]):
        status[k] = K.run_system_banded(
            B, D0[k], rint, rvec, ptr, idx, side, g, S[k], mu[k], coef, dt, nstep, saves,
            X[k], V[k], D[k], W[k], bw, rank_nom, rank_tol, tol_rel, Lsc, diag[k], info[k],
            jptr, jidx, jside, fint, fvec,
        )  # fmt: skip


@dataclass(eq=False)
class SystemBatchTrajectory:
    """Saved states of a batch (nbatch members, n saved times, nb bodies), SI units, world
    axes unless said; the fields of :class:`SystemTrajectory` with a leading member axis.

    ``t`` (n,) s; ``position`` (nbatch, n, nb, 3) m; ``velocity`` (nbatch, n, nb, 3) m/s;
    ``rotation`` (nbatch, n, nb, 3, 3) body-to-world; ``omega_body`` (nbatch, n, nb, 3) rad/s,
    body axes. ``ok`` (nbatch,) bool; ``steps_done`` (nbatch,) int; ``messages`` (nbatch,)
    tuple: None for a member that completed, else the reason it stopped (its states after
    the last completed save are NaN; the other members are unaffected). ``wall_time_s`` and
    ``cpu_time_s`` (process CPU time over all threads) of the compiled stepping alone;
    ``threads`` the number of numba threads used. :meth:`member` gives one member as a
    :class:`SystemTrajectory` (energy, momenta, joint residuals, solver diagnostics).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    ok: np.ndarray
    steps_done: np.ndarray
    messages: tuple
    body_names: tuple
    joint_names: tuple
    nstep: int
    dt: float
    scheme: str
    solver: str
    threads: int
    wall_time_s: float
    cpu_time_s: float
    _steppers: list
    _diag: np.ndarray

    def __len__(self) -> int:
        return self.position.shape[0]

    def member(self, k: int) -> SystemTrajectory:
        """Member k as a :class:`SystemTrajectory` (invariants computed in numpy from its
        saved states; wall and CPU time those of the whole batch). Raises StepSizeError with
        the member's message if it stopped early."""
        if not self.ok[k]:
            done = int(self.steps_done[k])
            raise StepSizeError(
                f"member {k}: {self.messages[k]}", time=done * self.dt, step=done + 1,
                dt=self.dt, h_max=None,
            )  # fmt: skip
        st = self._steppers[k]
        st.nstep_done = self.nstep
        return st._trajectory(
            self.t, self.position[k], self.velocity[k], self.rotation[k], self.omega_body[k],
            self.nstep, self.wall_time_s, self.cpu_time_s, self._diag[k],
        )  # fmt: skip


def simulate_system_batch(bodies_batch, joints, *, gravity=(0.0, 0.0, 0.0),
                          scheme: str = "rattle", dt: float, t_end: float,
                          save_every: int = 1, solver: str = "auto",
                          threads: int | None = None) -> SystemBatchTrajectory:  # fmt: skip
    """Integrate a batch of systems of the same topology and return their saved states.

    ``bodies_batch``: a sequence of nbatch lists of :class:`Body`, one per member, every list
    with the same names, masses and principal moments in the same order (initial poses and
    velocities free; each member is checked against the joints as by
    :class:`SystemStepper`). ``joints``, ``gravity``, ``scheme``, ``solver``, ``dt``,
    ``t_end``, ``save_every``: as :func:`simulate_system`, common to all members.
    ``threads``: numba threads to use (default: numba's current setting), at most
    ``numba.config.NUMBA_NUM_THREADS``. Memory O(nbatch x saved states).

    Each member equals its own ``simulate_system`` run bit for bit. A member whose step
    cannot be solved stops there (``ok`` False, its message in ``messages``); the others go
    on. Raises InvalidRunError for an empty batch, members of different topology (naming the
    member and what differs), or a bad ``threads``; the errors of :class:`SystemStepper` for
    a bad member, its index in the message.
    """
    try:
        members = [list(b) for b in bodies_batch]
    except TypeError:
        raise InvalidRunError(
            f"bodies_batch = {type(bodies_batch).__name__}: expected a sequence of body lists"
        ) from None
    if not members:
        raise InvalidRunError("bodies_batch: empty; expected at least one list of bodies")
    nthread_max = numba.config.NUMBA_NUM_THREADS
    if threads is not None and (
        isinstance(threads, bool) or not isinstance(threads, int | np.integer)
        or not 1 <= threads <= nthread_max
    ):  # fmt: skip
        raise InvalidRunError(f"threads = {threads!r}: must be a whole number in 1..{nthread_max}")
    joints = list(joints)
    steppers = []
    for k, bodies in enumerate(members):
        try:
            st = SystemStepper(bodies, joints, gravity=gravity, scheme=scheme, dt=dt,
                               solver=solver, _warm=False)  # fmt: skip
        except ValueError as e:  # the stepper's errors are ValueError subclasses
            raise type(e)(f"bodies_batch[{k}]: {e}") from None
        steppers.append(st)
    ref = steppers[0]
    for k, st in enumerate(steppers[1:], start=1):
        a, b = ref._asm, st._asm
        if a.names != b.names:
            what = f"body names {list(b.names)} (member 0: {list(a.names)})"
        elif not np.array_equal(a.bodies, b.bodies):
            i = int(np.flatnonzero(np.any(a.bodies != b.bodies, axis=1))[0])
            what = f"body {a.names[i]!r}: mass or principal moments differ from member 0's"
        elif st.solver != ref.solver or st.rank_nominal != ref.rank_nominal:
            what = (
                f"solver {st.solver!r} / Jacobian rank {st.rank_nominal} at t = 0 (member 0: "
                f"{ref.solver!r} / {ref.rank_nominal}): a singular initial configuration"
            )
        else:
            continue
        raise InvalidRunError(f"bodies_batch[{k}]: {what}; a batch needs one topology")
    nstep, _ = step_plan(ref.dt, t_end, save_every)
    saves = saved_steps(nstep, int(save_every))
    asm = ref._asm
    nbatch, nb, ns = len(steppers), len(asm.names), saves.shape[0]
    X = np.full((nbatch, ns, nb, 3), np.nan)
    V = np.full((nbatch, ns, nb, 3), np.nan)
    D = np.full((nbatch, ns, nb, 3, 3), np.nan)
    W = np.full((nbatch, ns, nb, 3), np.nan)
    diag = np.zeros((nbatch, K.NDIAG))
    diag[:, K.D_SMIN] = np.inf
    info = np.zeros((nbatch, 2))
    status = np.zeros(nbatch, dtype=np.int64)
    D0 = np.ascontiguousarray([st._D0 for st in steppers])
    S = np.ascontiguousarray([st._S for st in steppers])
    mu = np.ascontiguousarray([st._mu for st in steppers])
    kasm = ref._kasm  # the rows in the kernel's order (SystemStepper)
    rint = kasm.rint if kasm.rint.shape[0] else np.zeros((0, 4), dtype=np.int64)
    banded = ref.solver == "banded"
    _ensure_compiled(banded)
    old = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(int(threads))
    used = numba.get_num_threads()
    try:
        c0 = time.process_time()
        t0 = time.perf_counter()
        args = (
            kasm.bodies, D0, rint, kasm.rvec, kasm.brow_ptr, kasm.brow_idx, kasm.brow_side, ref._g,
            S, mu, ref._coef, ref.dt, nstep, saves, X, V, D, W,
        )  # fmt: skip
        rest = (
            kasm.bandwidth, ref.rank_nominal, RANK_TOL, TOL_EPS * K.EPS, kasm.length_scale,
            diag, info, kasm.jptr, kasm.jidx, kasm.jside, ref._fint, ref._fvec, status,
        )  # fmt: skip
        if banded:
            run_batch_banded(*args, *rest)
        else:
            run_batch(*args, _MODES.get(ref.solver, 0), *rest)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - c0
    finally:
        numba.set_num_threads(old)
    ok = status == K.OK
    done = np.where(ok, nstep, info[:, 0].astype(np.int64))
    messages = tuple(
        None
        if ok[k]
        else (
            f"{scheme}: step {done[k] + 1} starting at t = {done[k] * ref.dt:.9g} s could not "
            f"be solved: {K.STATUS_TEXT.get(int(status[k]), 'unknown failure')} (sub-step "
            f"h = {info[k, 1]:.6g} s of dt = {ref.dt:.6g} s); reduce dt"
        )
        for k in range(nbatch)
    )
    return SystemBatchTrajectory(
        t=saves * ref.dt, position=X, velocity=V, rotation=D, omega_body=W, ok=ok,
        steps_done=done, messages=messages, body_names=asm.names,
        joint_names=asm.joint_names, nstep=nstep, dt=ref.dt, scheme=scheme,
        solver=ref.solver, threads=used, wall_time_s=wall, cpu_time_s=cpu,
        _steppers=steppers, _diag=diag,
    )  # fmt: skip


__all__ = ["SystemBatchTrajectory", "run_batch", "simulate_system_batch"]

# the batch kernels compile the system kernel into their own cached code: their cache is tied
# to the files it is compiled from (an edit of _kernels.py left them running the old step)
_cache.tie(
    {"run_batch": run_batch, "run_batch_banded": run_batch_banded},
    Path(K.__file__),
    *K.SOURCES,
)
