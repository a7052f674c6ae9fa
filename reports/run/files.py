"""What a run keeps on disk beside its row: its full trajectory, the series the report draws,
or nothing.

A run's metrics are computed from its full-resolution trajectory in double precision, in the
process that ran it, before anything is written (the steppers: reports.run.body, .system,
.contact); what is kept afterwards decides only what can be drawn or read again. Kept in full, every
saved state of every run of the default suite is about 200 MB, too heavy for a CI artifact or
a pull request. So by default (``run --trajectories report``, :func:`assign`):

- a run the report draws (each scenario's own step, :func:`drawn_steps`) keeps a *series
  file*, ``<run>.series.parquet``: every saved time, the body rates ``wx, wy, wz`` and the
  per-sample error series (:data:`SERIES`), plus, for the reference run, the centre of mass
  and the rotation the scenario picture draws; single precision (seven digits, far more than
  a figure shows) except the time;
- a run the report does not draw (the other steps of a dt sweep) keeps no file: its metrics
  are in the store, and no figure reads its samples.

``run --trajectories full`` keeps every run's full trajectory (every column of
:mod:`references.trajectory`, double precision), as described in docs/results.md; a run
already in the store with less than that is run again.
"""

from __future__ import annotations

from dataclasses import replace

#: what a run keeps, from least to most (a stored run with less than its spec asks for is run
#: again: :func:`kept_less`)
KEEP = ("none", "series", "full")
#: the choices of ``run --trajectories``
MODES = ("report", "full")

#: the per-sample series the figures draw, single bodies and systems
SERIES = (
    "energy_drift",
    "momentum_drift",
    "orthonormality",
    "attitude_error",
    "omega_error",
    "energy_change",
    "joint_gap",
    "loop_gap",
    "joint_coordinate_error",
)
#: series kept under a name of their own per item (a robot model's per-joint errors)
SERIES_PREFIXES = ("joint_coordinate_error.",)
#: the columns of a single body's series file beside the series; the reference run adds
#: :data:`POSE` (the scenario picture draws its motion)
RATES = ("t", "wx", "wy", "wz")
POSE = ("x", "y", "z", "R00", "R01", "R02", "R10", "R11", "R12", "R20", "R21", "R22")
#: the file name's ending of a series file (its trajectory_path format)
SERIES_FORMAT = "series.parquet"


def drawn_steps(specs) -> dict[str, float]:
    """{scenario: the step its figures are drawn at}: the reference's step where the plan has
    a reference run, else the step most runs of the scenario use, the smaller on a tie (the
    rule of :func:`reports.store.results.default_dt`, applied to the plan)."""
    from collections import Counter

    from references.engines import EngineError, get_engine

    def is_reference(engine: str) -> bool:
        try:
            return bool(get_engine(engine).is_reference)
        except EngineError:
            return False

    out, counts = {}, {}
    for s in specs:
        name = s.scenario.name
        if is_reference(s.engine):
            out.setdefault(name, float(s.dt))
        counts.setdefault(name, Counter())[float(s.dt)] += 1
    for name, c in counts.items():
        out.setdefault(name, max(c, key=lambda h: (c[h], -h)))
    return out


def assign(specs, mode: str) -> list:
    """The specs with what each keeps (``RunSpec.keep``) for ``run --trajectories mode``
    (:data:`MODES`; see the module docstring)."""
    if mode == "full":
        return [replace(s, keep="full") for s in specs]
    steps = drawn_steps(specs)
    return [
        replace(s, keep="series" if float(s.dt) == steps[s.scenario.name] else "none")
        for s in specs
    ]


def stored_keep(trajectory: str) -> str:
    """What a stored row's file keeps, from its ``trajectory`` path."""
    if not trajectory:
        return "none"
    return "series" if trajectory.endswith("." + SERIES_FORMAT) else "full"


def kept_less(row: dict, keep: str) -> bool:
    """Whether the stored ``row`` kept less than ``keep`` asks for, so that its run is done
    again (a run that produced no samples keeps nothing whatever was asked: not again)."""
    if row.get("status") not in ("ok", "diverged", "reference-inaccurate"):
        return False
    return KEEP.index(stored_keep(row.get("trajectory") or "")) < KEEP.index(keep)


def series_table(columns: dict, reference: bool):
    """The Arrow table of a series file from a run's full set of ``columns`` (name -> array):
    :data:`RATES` (and :data:`POSE` for the reference run) and every :data:`SERIES` column
    present (and those named by :data:`SERIES_PREFIXES`), single precision except the time."""
    import numpy as np
    import pyarrow as pa

    names = [*RATES, *(POSE if reference else ()), *SERIES]
    names += [c for c in columns if c.startswith(SERIES_PREFIXES)]
    return pa.table(
        {
            c: np.asarray(columns[c], dtype=float if c == "t" else np.float32)
            for c in names
            if c in columns
        }
    )


#: the schema metadata a series file carries beside the run's identity
SERIES_NOTE = (
    "the series the report draws, at every saved time: body rates, per-sample errors (and, "
    "for the reference run, the centre of mass and rotation), single precision except t; "
    "the run's metrics were computed from its full trajectory in double precision. "
    "`director-bench run --trajectories full` keeps every column in double precision."
)


#: the columns of a run's row that name the run in its trajectory file's metadata
IDENTITY = (
    "run_id", "scenario", "scenario_hash", "engine", "engine_version", "integrator", "dt",
    "target_accuracy", "t_end",
)  # fmt: skip

#: the frames of a scene of bodies' per-body columns (``<body>.<column>``)
BODIES_FRAMES = {
    "<body>.x .. <body>.vz": "world axes, centre of mass of the body",
    "<body>.R00 .. R22": "body-to-world rotation, row-major; columns: principal axes",
    "<body>.wx .. wz": "body axes",
}


def run_identity(row: dict) -> dict:
    """The run's identity kept in its trajectory file's metadata (:data:`IDENTITY`)."""
    return {k: row[k] for k in IDENTITY}


def bodies_file(row: dict, traj, series_units: dict) -> tuple[dict, dict]:
    """(columns, metadata) of the trajectory file of a run of a system or contact scene:
    per-body columns (:meth:`references.trajectory.Trajectory.columns`) with their
    units and frames, the body names and the run's identity; ``series_units``: the units of
    the per-sample series written beside them."""
    from references.trajectory import UNITS

    cols = traj.columns()
    units = {c: UNITS[c.rsplit(".", 1)[1]] for c in cols if c != "t"} | {"t": "s"}
    meta = {
        "director_bench.units": units | series_units,
        "director_bench.frames": BODIES_FRAMES,
        "director_bench.bodies": list(traj.body_names),
        "director_bench.run": run_identity(row),
    }
    return cols, meta
