"""N contact scenes of one structure in parallel: :func:`simulate_contact_batch`."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from director_model.contact import _kernels as K
from director_model.contact import _parts as P
from director_model.contact.scene import ContactScene
from director_model.contact.simulate import (
    ContactTrajectory,
    _dt,
    _failure,
    _initial_state,
    _trajectory,
)
from director_model.errors import InvalidRunError
from director_model.simulate import step_plan


@dataclass(eq=False)
class ContactBatchTrajectory:
    """The saved states of N runs: ``member(k)`` gives run k as a ContactTrajectory (its
    states up to its failure, if it failed); ``ok`` (N,) and ``messages`` (N,) say which
    failed and why; ``wall_time_s`` and ``cpu_time_s`` of the whole batch (cpu: process)."""

    scenes: list
    arrays: tuple
    saves: np.ndarray
    dt: float
    nstep: int
    ok: np.ndarray
    messages: list
    wall_time_s: float
    cpu_time_s: float

    def __len__(self) -> int:
        return len(self.scenes)

    def member(self, k: int) -> ContactTrajectory:
        X, V, D, W, Q, PF = (a[k] for a in self.arrays)
        return _trajectory(self.scenes[k], self.saves * self.dt, X, V, D, W, Q, PF, self.nstep,
                           self.dt, self.wall_time_s, self.cpu_time_s)  # fmt: skip


def simulate_contact_batch(scenes, *, dt: float, t_end: float,
                           save_every: int = 1) -> ContactBatchTrajectory:  # fmt: skip
    """Run N scenes that differ only in their initial states (same bodies, shapes, planes,
    pairs, joints, forces and gravity) in parallel over numba's threads; each member equals
    its own :func:`simulate_contact` bit for bit. A member whose step fails is reported in
    ``ok``/``messages`` (its saved states stop there) while the others go on."""
    scenes = list(scenes)
    if not scenes or not all(isinstance(s, ContactScene) for s in scenes):
        raise InvalidRunError("scenes: expected a non-empty list of ContactScene")
    ref = scenes[0]
    for k, s in enumerate(scenes[1:], 1):
        same = (
            s.asm.names == ref.asm.names
            and np.array_equal(s.asm.bodies, ref.asm.bodies)
            and np.array_equal(s.SH, ref.SH)
            and np.array_equal(s.FI, ref.FI)
            and np.array_equal(s.FV, ref.FV)
            and np.array_equal(s.PV, ref.PV)
            and np.array_equal(s.asm.rint, ref.asm.rint)
            and np.array_equal(s.asm.rvec, ref.asm.rvec)
            and np.array_equal(s.fb, ref.fb)
            and np.array_equal(s.fv, ref.fv)
            and np.array_equal(s.gravity, ref.gravity)
        )
        if not same:
            raise InvalidRunError(
                f"scenes[{k}]: differs from scenes[0] in more than the initial state (bodies, "
                "shapes, planes, pairs, joints, forces or gravity); a batch shares them"
            )
    dt = _dt(dt)
    nstep, saves = step_plan(dt, t_end, save_every)
    nbt, nb, ns, npair = len(scenes), len(ref.bodies), saves.shape[0], ref.PI.shape[0]
    D0 = np.empty((nbt, nb, 9))
    S = np.empty((nbt, nb, P.NS))
    for k, s in enumerate(scenes):
        D0[k], S[k] = _initial_state(s)
    WS = np.zeros((nbt, max(ref.FI.shape[0], 1), 6))
    WJ = np.zeros((nbt, max(ref.asm.rint.shape[0], 1), 2))
    X = np.zeros((nbt, ns, nb, 3))
    V = np.zeros((nbt, ns, nb, 3))
    D = np.zeros((nbt, ns, nb, 3, 3))
    W = np.zeros((nbt, ns, nb, 3))
    Q = np.zeros((nbt, ns, P.NQ))
    PF = np.zeros((nbt, ns, npair, 3))
    info = np.full((nbt, P.NINFO), -1.0)
    status = np.zeros(nbt, dtype=np.int64)
    rint = ref.asm.rint if ref.asm.rint.shape[0] else np.zeros((0, 4), dtype=np.int64)
    c0 = time.process_time()
    t0 = time.perf_counter()
    K.run_contact_batch(
        ref.asm.bodies, ref.SH, D0, S, WS, WJ, ref.FI, ref.FV, ref.PI, ref.PV, rint,
        ref.asm.rvec, ref.fb, ref.fv, ref.gravity, dt, nstep, saves, X, V, D, W, Q, PF, info,
        status,
    )  # fmt: skip
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    ok = status == P.OK
    msgs = [
        ""
        if ok[k]
        else str(_failure(scenes[k], status[k], info[k], int(info[k, P.I_STEPS]), dt, k))
        for k in range(nbt)
    ]
    return ContactBatchTrajectory(
        scenes=scenes, arrays=(X, V, D, W, Q, PF), saves=saves, dt=dt, nstep=nstep, ok=ok,
        messages=msgs, wall_time_s=wall, cpu_time_s=cpu,
    )  # fmt: skip
