"""What a run of the director model returns: the saved states of one body
(:class:`Trajectory`) or of N bodies stepped together (:class:`BatchTrajectory`), with the
invariants computed from the saved director states (:mod:`director_model.invariants`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from director_model import invariants as inv
from director_model.state import omega_body_from_directors


@dataclass(eq=False)
class Trajectory:
    """Saved states of one run (n = number of saved times), SI units, world axes unless said.

    =======================  =========  =====================================================
    field                    shape      meaning
    =======================  =========  =====================================================
    ``t``                    (n,)       time, s
    ``position``             (n, 3)     centre of mass x_G, m (x_G = -R c with a pivot)
    ``velocity``             (n, 3)     v_G, m/s
    ``rotation``             (n, 3, 3)  D = R, body-to-world; columns are the directors
    ``director_velocity``    (n, 3, 3)  D'
    ``omega_body``           (n, 3)     W = vee(skew(D^T D')), body axes, rad/s
    ``energy``               (n,)       E = T + V in director form (seed eq. 11), J
    ``angular_momentum``     (n, 3)     L about the world origin (= the pivot), kg m^2/s
    ``linear_momentum``      (n, 3)     m v_G, kg m/s
    ``constraint_position``  (n,)       max|D^T D - I|
    ``constraint_velocity``  (n,)       max|D^T D' + D'^T D|
    =======================  =========  =====================================================

    The fields from ``omega_body`` to ``constraint_velocity`` are derived from the saved
    states, each computed when it is first read (and kept): change no saved array before
    reading them.

    Scalars: ``nstep`` (steps taken), ``wall_time_s`` (wall time of the compiled stepping
    alone; compilation and the invariants excluded), ``cpu_time_s`` (CPU time of the
    calling thread over the same stepping: unlike the wall time it leaves out the time
    other processes held the core), ``dt``, ``scheme`` (name).

    Note: ``angular_momentum`` is about the world origin, as the director model defines it
    (L = x_G x m v_G + sum Jbar_ij d_i x d_j'); the spin about the centre of mass alone is
    ``angular_momentum - np.cross(position, linear_momentum)`` for a free body.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    director_velocity: np.ndarray
    nstep: int
    wall_time_s: float
    cpu_time_s: float
    dt: float
    scheme: str
    #: the body (mass, director mass matrix Jbar, pivoted) and the gravity the derived
    #: quantities below are computed with
    _mass: np.ndarray | float = field(repr=False)
    _Jbar: np.ndarray = field(repr=False)
    _pivoted: bool = field(repr=False)
    _gravity: np.ndarray = field(repr=False)

    # The quantities derived from the saved states are computed on first access (and kept):
    # a caller that reads only the states (the suite's adapter reads a chunk's states and
    # its own residuals) does not pay for the others.
    @cached_property
    def omega_body(self) -> np.ndarray:
        return omega_body_from_directors(self.rotation, self.director_velocity)

    @cached_property
    def energy(self) -> np.ndarray:
        return inv.energy(
            self._mass, self._Jbar, self._pivoted, self._gravity, self.position, self.velocity,
            self.director_velocity,
        )  # fmt: skip

    @cached_property
    def angular_momentum(self) -> np.ndarray:
        return inv.angular_momentum(
            self._mass, self._Jbar, self._pivoted, self.position, self.velocity, self.rotation,
            self.director_velocity,
        )  # fmt: skip

    @cached_property
    def linear_momentum(self) -> np.ndarray:
        return inv.linear_momentum(self._mass, self.velocity)

    @cached_property
    def constraint_position(self) -> np.ndarray:
        return inv.constraint_position(self.rotation)

    @cached_property
    def constraint_velocity(self) -> np.ndarray:
        return inv.constraint_velocity(self.rotation, self.director_velocity)

    def __len__(self) -> int:
        return self.t.shape[-1]

    @property
    def quat_wxyz(self) -> np.ndarray:
        """Attitude as unit quaternions (w, x, y, z), w >= 0, shape (..., n, 4)."""
        from director_model.state import quat_wxyz_from_rotation

        return quat_wxyz_from_rotation(self.rotation)


@dataclass(eq=False)
class BatchTrajectory(Trajectory):
    """Saved states of N bodies, MuJoCo-rollout style: every array of :class:`Trajectory`
    gains a leading body axis, ``nbody x nsave x ...``:

    ``t`` (nsave,) is shared; ``position``, ``velocity``, ``omega_body``,
    ``angular_momentum``, ``linear_momentum`` (nbody, nsave, 3); ``rotation``,
    ``director_velocity`` (nbody, nsave, 3, 3); ``energy``, ``constraint_position``,
    ``constraint_velocity`` (nbody, nsave). ``nstep`` is per body; ``wall_time_s`` is the
    wall time of the whole compiled batch loop and ``cpu_time_s`` the CPU time the process
    spent in it (all threads). ``nbody`` is the number of bodies.

    ``vector_substeps`` (nbody,): how many RATTLE substeps of each body the vector code of
    the batched loop took (the rest went through the scalar code, with the same result);
    0 for energy-momentum, which has no vector code.
    """

    vector_substeps: np.ndarray | None = None

    @property
    def nbody(self) -> int:
        return self.position.shape[0]

    def __len__(self) -> int:
        return self.t.shape[0]
