"""The one trajectory schema every engine's output is mapped into.

A :class:`Trajectory` holds the saved states of a scene of ``nb`` bodies at ``n`` times, on a
bodies axis (bodies in the scenario's order; a single body's scenario is a scene of one body,
named ``"body"``), each body's frame its principal frame at its centre of mass:

=======================  ==============  ===================================================
field                    shape           meaning
=======================  ==============  ===================================================
``t``                    (n,)            time, s
``position``             (n, nb, 3)      centres of mass x_G, world axes, m
``velocity``             (n, nb, 3)      centre-of-mass velocities v_G, world axes, m/s
``rotation``             (n, nb, 3, 3)   body-to-world rotations R (columns: the directors)
``omega_body``           (n, nb, 3)      angular velocities W in body axes, rad/s
``body_names``           (nb,)           names of the bodies
``energy``               (n,)            one body: E = T + V, J (computed by the suite)
``angular_momentum``     (n, 3)          one body: L in world axes, about the centre of mass
                                         for a free body and about the pivot (world origin)
                                         for a pivoted one, kg m^2/s
``constraint_velocity``  (n,)            one body: velocity-constraint residual
                                         ||D^T D' + D'^T D||_F, 1/s (see below)
=======================  ==============  ===================================================

A scene of one body carries its per-sample energy, angular momentum and velocity-constraint
residual (:meth:`Trajectory.from_states` computes them); for a system of bodies they are None:
its energy, momenta and joint residuals are computed from its states
(:func:`system_energy`, :func:`system_momenta`, ``reports.metrics.system``).

The single-body metrics read a scene of one body through :func:`one_body`: a :class:`OneBody`,
the same states without the bodies axis ((n, 3), (n, 3, 3) arrays, views of the
trajectory's: no copy), which is also what a single body's file holds.

The velocity constraint of the director form (D^T D' skew) holds by construction for an
engine whose state is (R, W): there D' = R hat(W) and the residual is R^T R hat(W) -
hat(W) R^T R, of the size of the orthonormality error times |W|, which is what is computed
when an adapter gives nothing else. The director model's energy-momentum scheme updates D'
itself and violates the constraint at O(h^2); its adapter records the residual of its own D'.

Energy and angular momentum are never taken from an engine: :meth:`Trajectory.from_states`
computes them from pose, velocity and the scenario's mass and inertia, identically for every
engine (``E = 1/2 m |v_G|^2 + 1/2 W . I W - m g . x_G``; ``L = R I W`` about the centre of
mass, plus ``x_G x m v_G`` about the pivot).

On disk (Parquet, or CSV on request) a single body's columns are
``t, x, y, z, vx, vy, vz, R00 ... R22 (row-major), wx, wy, wz, energy, Lx, Ly, Lz,
constraint_velocity`` (:data:`COLUMNS`, :meth:`OneBody.write`); a system's are ``t`` and, per
body ``<name>``, ``<name>.x ... <name>.R22 ... <name>.wz`` (:meth:`Trajectory.columns`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

COLUMNS = (
    ["t", "x", "y", "z", "vx", "vy", "vz"]
    + [f"R{i}{j}" for i in range(3) for j in range(3)]
    + ["wx", "wy", "wz", "energy", "Lx", "Ly", "Lz", "constraint_velocity"]
)

#: unit of each column of the on-disk table
UNITS = {
    "t": "s",
    **dict.fromkeys(["x", "y", "z"], "m"),
    **dict.fromkeys(["vx", "vy", "vz"], "m/s"),
    **{f"R{i}{j}": "1" for i in range(3) for j in range(3)},
    **dict.fromkeys(["wx", "wy", "wz"], "rad/s"),
    "energy": "J",
    **dict.fromkeys(["Lx", "Ly", "Lz"], "kg m^2/s"),
    "constraint_velocity": "1/s",
}


def _shaped(kind: str, name: str, value, shape: tuple, where: str) -> np.ndarray:
    """``value`` as a float array of ``shape``, else a ValueError naming the ``kind`` of
    trajectory, the field, its shape and the expected one (``where``: the sizes that set it)."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{kind} field {name!r} has shape {arr.shape}, expected {shape} ({where})")
    return arr


def velocity_constraint(rotation, omega_body) -> np.ndarray:
    """||R^T R hat(W) - hat(W) R^T R||_F for stacks (n, 3, 3), (n, 3): the director-form
    velocity-constraint residual of D' = R hat(W), shape (n,)."""
    R = np.asarray(rotation, dtype=float)
    W = np.asarray(omega_body, dtype=float)
    Wh = np.zeros(W.shape[:-1] + (3, 3))
    Wh[..., 0, 1], Wh[..., 0, 2], Wh[..., 1, 2] = -W[..., 2], W[..., 1], -W[..., 0]
    Wh[..., 1, 0], Wh[..., 2, 0], Wh[..., 2, 1] = W[..., 2], -W[..., 1], W[..., 0]
    M = np.einsum("...ki,...kj->...ij", R, R)
    return np.linalg.norm(M @ Wh - Wh @ M, axis=(-2, -1))


def _energy_terms(scenario, position, velocity, omega_body):
    """(1/2 m |v_G|^2, 1/2 W.I W, V = -m g.x_G), each (n,), J."""
    I = np.asarray(scenario.inertia)
    t_trans = 0.5 * scenario.mass * np.einsum("ni,ni->n", velocity, velocity)
    t_rot = 0.5 * np.einsum("ni,i,ni->n", omega_body, I, omega_body)
    return t_trans, t_rot, -scenario.mass * position @ np.asarray(scenario.gravity)


def energy(scenario, position, velocity, rotation, omega_body) -> np.ndarray:
    """Total energy E = T + V from states, shape (n,). Arrays as in :class:`OneBody`."""
    del rotation  # the rotational energy needs only body rates and principal moments
    t_trans, t_rot, V = _energy_terms(scenario, position, velocity, omega_body)
    return (t_trans + t_rot) + V


def energy_parts(scenario, position, velocity, rotation, omega_body) -> dict[str, np.ndarray]:
    """The energy and the parts of it that are conserved on their own, J, each shape (n,):
    ``"total"``, E = T + V (:func:`energy`); for a free body also ``"rot"``, 1/2 W.I W (uniform
    gravity exerts no torque about the centre of mass), and ``"trans"``, 1/2 m |v_G|^2 -
    m g.x_G. A pivoted body's rotation and translation are one motion about the pivot and
    exchange energy: it has only ``"total"``."""
    del rotation
    t_trans, t_rot, V = _energy_terms(scenario, position, velocity, omega_body)
    parts = {"total": (t_trans + t_rot) + V}
    if scenario.pivot is None:
        parts["rot"], parts["trans"] = t_rot, t_trans + V
    return parts


def angular_momentum(scenario, position, velocity, rotation, omega_body) -> np.ndarray:
    """World-axes angular momentum, shape (n, 3): about the centre of mass for a free body,
    about the pivot (the world origin) for a pivoted one."""
    L = np.einsum("nij,nj->ni", rotation, omega_body * np.asarray(scenario.inertia))
    if scenario.pivot is not None:
        L = L + scenario.mass * np.cross(position, velocity)
    return L


@dataclass
class OneBody:
    """The states of a scene of one body without the bodies axis, (n, ...) arrays: what the
    single-body metrics read (:func:`one_body` of a :class:`Trajectory`) and what a single
    body's file holds (:meth:`write`, :meth:`read`). Fields as in :class:`Trajectory` with
    ``nb`` left out; ``energy`` and ``angular_momentum`` are required."""

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    energy: np.ndarray
    angular_momentum: np.ndarray
    constraint_velocity: np.ndarray | None = None

    def __post_init__(self):
        n = len(self.t)
        shapes = {
            "t": (n,),
            "position": (n, 3),
            "velocity": (n, 3),
            "rotation": (n, 3, 3),
            "omega_body": (n, 3),
            "energy": (n,),
            "angular_momentum": (n, 3),
            "constraint_velocity": (n,),
        }
        where = f"n = {n} saved times"
        for name, shape in shapes.items():
            if name == "constraint_velocity" and self.constraint_velocity is None:
                self.constraint_velocity = velocity_constraint(self.rotation, self.omega_body)
            setattr(self, name, _shaped("OneBody", name, getattr(self, name), shape, where))

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def from_states(
        cls, scenario, t, position, velocity, rotation, omega_body, constraint_velocity=None
    ) -> OneBody:
        """One body's states, computing energy and momentum the suite's way
        (:meth:`Trajectory.from_states` puts them on the bodies axis).

        For a pivoted scenario ``position`` and ``velocity`` may be None: they follow from the
        rotation and body rates (x_G = -R c, v_G = -R (W x c) with c the pivot in body axes).
        """
        t = np.asarray(t, dtype=float)
        R = np.asarray(rotation, dtype=float)
        W = np.asarray(omega_body, dtype=float)
        if scenario.pivot is not None and position is None:
            c = np.asarray(scenario.pivot)
            position = -R @ c
            velocity = -np.einsum("nij,nj->ni", R, np.cross(W, c))
        x = np.asarray(position, dtype=float)
        v = np.asarray(velocity, dtype=float)
        return cls(
            t=t,
            position=x,
            velocity=v,
            rotation=R,
            omega_body=W,
            energy=energy(scenario, x, v, R, W),
            angular_momentum=angular_momentum(scenario, x, v, R, W),
            constraint_velocity=constraint_velocity,
        )

    # -- tabular form --------------------------------------------------------------------
    def to_frame(self):
        """A pandas DataFrame with the schema's columns (see the module docstring)."""
        import pandas as pd

        n = len(self)
        data = np.column_stack(
            [
                self.t,
                self.position,
                self.velocity,
                self.rotation.reshape(n, 9),
                self.omega_body,
                self.energy,
                self.angular_momentum,
                self.constraint_velocity,
            ]
        )
        return pd.DataFrame(data, columns=COLUMNS)

    @classmethod
    def from_frame(cls, df) -> OneBody:
        missing = [c for c in COLUMNS if c not in df.columns]
        if missing:
            raise ValueError(f"trajectory table lacks columns {missing}")
        a = df[COLUMNS].to_numpy(dtype=float)
        n = len(a)
        return cls(
            t=a[:, 0],
            position=a[:, 1:4],
            velocity=a[:, 4:7],
            rotation=a[:, 7:16].reshape(n, 3, 3),
            omega_body=a[:, 16:19],
            energy=a[:, 19],
            angular_momentum=a[:, 20:23],
            constraint_velocity=a[:, 23],
        )

    def write(self, path: str | Path, fmt: str = "parquet") -> Path:
        """Write to ``path`` as Parquet (default) or CSV; returns the path written."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        df = self.to_frame()
        if fmt == "parquet":
            df.to_parquet(path, index=False)
        elif fmt == "csv":
            df.to_csv(path, index=False, float_format="%.17g")
        else:
            raise ValueError(f"unknown trajectory format {fmt!r}: expected 'parquet' or 'csv'")
        return path

    @classmethod
    def read(cls, path: str | Path) -> OneBody:
        """Read a single body's file written by the suite (Parquet or CSV)."""
        import pandas as pd

        path = Path(path)
        df = pd.read_csv(path) if path.suffix == ".csv" else pd.read_parquet(path)
        return cls.from_frame(df)

    def as_bodies(self, name: str = "body") -> Trajectory:
        """The same states on the bodies axis: a :class:`Trajectory` of one body named
        ``name`` carrying these energy, angular momentum and velocity-constraint residual;
        its arrays are views of these (no copy)."""
        return Trajectory(
            self.t, self.position[:, None], self.velocity[:, None], self.rotation[:, None],
            self.omega_body[:, None], (name,), energy=self.energy,
            angular_momentum=self.angular_momentum, constraint_velocity=self.constraint_velocity,
        )  # fmt: skip


def one_body(traj):
    """The states of a scene of one body as the single-body metrics read them, (n, ...) arrays
    without the bodies axis: of a :class:`Trajectory` of one body that carries its energy and
    angular momentum (:meth:`Trajectory.from_states`), a :class:`OneBody` over views of its
    arrays (no copy: the values, and the memory layout numpy's arithmetic may depend on, are
    the same), of a read-only one the same view object at every call; a :class:`OneBody` as
    it is, None as None."""
    if traj is None or isinstance(traj, OneBody):
        return traj
    nb = len(traj.body_names)
    if nb != 1 or traj.energy is None or traj.angular_momentum is None:
        raise ValueError(
            f"one_body: a trajectory of {nb} bodies ({', '.join(traj.body_names)})"
            + ("" if nb != 1 else " without its energy and angular momentum")
            + " is not the trajectory of a scene of one body (see Trajectory.from_states)"
        )
    arrays = (traj.t, traj.position, traj.velocity, traj.rotation, traj.omega_body,
              traj.energy, traj.angular_momentum, traj.constraint_velocity)  # fmt: skip
    kept = traj.__dict__.get("_one_body")
    if kept is not None and all(a is b for a, b in zip(kept[0], arrays, strict=True)):
        return kept[1]
    view = OneBody(
        traj.t, traj.position[:, 0], traj.velocity[:, 0], traj.rotation[:, 0],
        traj.omega_body[:, 0], traj.energy, traj.angular_momentum, traj.constraint_velocity,
    )  # fmt: skip
    if not traj.rotation.flags.writeable:
        # a trajectory nobody may change (a reference the runner shares among the runs on its
        # grid): the same view each time, so that what a metric keeps on it
        # (reports.metrics.body._nearest_kept) is computed once per reference, not per run
        traj._one_body = (arrays, view)
    return view


# -- the trajectory: bodies on an axis --------------------------------------------------------


@dataclass
class Trajectory:
    """Saved states of one run of a scene of ``nb`` bodies at ``n`` times, in the suite's
    schema (the fields and their shapes: the module docstring). A scene of one body also
    carries its ``energy``, ``angular_momentum`` and ``constraint_velocity``
    (:meth:`from_states`), read by its metrics through :func:`one_body`; for a system they are
    None."""

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    omega_body: np.ndarray
    body_names: tuple = ()
    energy: np.ndarray | None = None
    angular_momentum: np.ndarray | None = None
    constraint_velocity: np.ndarray | None = None

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float)
        n = len(self.t)
        nb = len(self.body_names)
        shapes = {
            "position": (n, nb, 3),
            "velocity": (n, nb, 3),
            "rotation": (n, nb, 3, 3),
            "omega_body": (n, nb, 3),
        }
        where = f"n = {n} saved times, nb = {nb} bodies"
        for name, shape in shapes.items():
            setattr(self, name, _shaped("Trajectory", name, getattr(self, name), shape, where))
        self.body_names = tuple(self.body_names)
        one_body_shapes = {"energy": (n,), "angular_momentum": (n, 3), "constraint_velocity": (n,)}
        for name, shape in one_body_shapes.items():
            value = getattr(self, name)
            if value is None:
                continue
            if nb != 1:
                raise ValueError(
                    f"Trajectory field {name!r} belongs to a scene of one body, not of "
                    f"nb = {nb} bodies"
                )
            setattr(self, name, _shaped("Trajectory", name, value, shape, where))

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def from_states(
        cls, scenario, t, position, velocity, rotation, omega_body, constraint_velocity=None
    ) -> Trajectory:
        """The trajectory of a scene of one body from its states, (n, ...) arrays as in
        :class:`OneBody`, energy and momentum computed the suite's way
        (:meth:`OneBody.from_states`; ``constraint_velocity`` None: computed from R and W).
        For a pivoted scenario ``position`` and ``velocity`` may be None."""
        one = OneBody.from_states(
            scenario, t, position, velocity, rotation, omega_body, constraint_velocity
        )
        return one.as_bodies()

    def head(self, k: int) -> Trajectory:
        """The first ``k`` saved states."""

        def first(a):
            return None if a is None else a[:k]

        return Trajectory(
            self.t[:k], self.position[:k], self.velocity[:k], self.rotation[:k],
            self.omega_body[:k], self.body_names, first(self.energy),
            first(self.angular_momentum), first(self.constraint_velocity),
        )  # fmt: skip

    #: per-body columns on disk, in order
    BODY_COLUMNS = COLUMNS[1:19]

    def columns(self) -> dict[str, np.ndarray]:
        """A system's on-disk columns, name -> (n,) array (see the module docstring)."""
        n = len(self)
        cols = {"t": self.t}
        for b, name in enumerate(self.body_names):
            block = np.column_stack(
                [
                    self.position[:, b],
                    self.velocity[:, b],
                    self.rotation[:, b].reshape(n, 9),
                    self.omega_body[:, b],
                ]
            )
            for i, c in enumerate(self.BODY_COLUMNS):
                cols[f"{name}.{c}"] = block[:, i]
        return cols

    @classmethod
    def from_columns(cls, cols, body_names) -> Trajectory:
        """The inverse of :meth:`columns` (``cols``: a mapping or a DataFrame)."""
        t = np.asarray(cols["t"], dtype=float)
        n, nb = len(t), len(body_names)
        block = np.empty((n, nb, len(cls.BODY_COLUMNS)))
        for b, name in enumerate(body_names):
            for i, c in enumerate(cls.BODY_COLUMNS):
                block[:, b, i] = np.asarray(cols[f"{name}.{c}"], dtype=float)
        return cls(
            t, block[:, :, 0:3], block[:, :, 3:6], block[:, :, 6:15].reshape(n, nb, 3, 3),
            block[:, :, 15:18], tuple(body_names),
        )  # fmt: skip

    @classmethod
    def read(cls, path: str | Path) -> Trajectory:
        """Read a trajectory file written by the suite: a system's (Parquet; the body names are
        the column prefixes, in order) or a single body's (Parquet or CSV,
        :meth:`OneBody.read`: one body with its energy and momentum)."""
        import pandas as pd

        path = Path(path)
        df = pd.read_csv(path) if path.suffix == ".csv" else pd.read_parquet(path)
        names = list(dict.fromkeys(c.rsplit(".", 1)[0] for c in df.columns if c.endswith(".x")))
        if not names and "x" in df.columns:
            return OneBody.from_frame(df).as_bodies()
        return cls.from_columns(df, names)


def system_energy(scenario, traj: Trajectory) -> np.ndarray:
    """E = sum_b 1/2 m_b |v_b|^2 + 1/2 W_b . I_b W_b - m_b g . x_b of a system's states, (n,),
    J (the bodies' masses and principal moments from ``scenario.bodies``), plus the force
    elements' potential (:func:`scenarios.force_elements.potential`: the springs' 1/2 k
    (l - l0)^2 less the torques' work, the states in time order from t = 0)."""
    from scenarios.force_elements import potential

    m = np.array([b.mass for b in scenario.bodies])
    inertia = np.array([b.inertia for b in scenario.bodies])
    v, W, x = traj.velocity, traj.omega_body, traj.position
    t_trans = 0.5 * np.einsum("b,nbi,nbi->n", m, v, v)
    t_rot = 0.5 * np.einsum("nbi,bi,nbi->n", W, inertia, W)
    V = -np.einsum("b,nbi,i->n", m, x, np.asarray(scenario.gravity))
    return (t_trans + t_rot) + V + potential(scenario, x, traj.rotation)


def system_momenta(scenario, traj: Trajectory, about) -> tuple[np.ndarray, np.ndarray]:
    """(linear momentum (n, 3) kg m/s, angular momentum about the world point ``about``
    (n, 3) kg m^2/s) of a system's states: sum m_b v_b and
    sum (x_b - about) x m_b v_b + R_b I_b W_b."""
    m = np.array([b.mass for b in scenario.bodies])
    inertia = np.array([b.inertia for b in scenario.bodies])
    p_b = m[None, :, None] * traj.velocity
    spin = np.einsum("nbij,nbj->nbi", traj.rotation, inertia[None] * traj.omega_body)
    r = traj.position - np.asarray(about, dtype=float)
    L = np.sum(np.cross(r, p_b) + spin, axis=1)
    return p_b.sum(axis=1), L
