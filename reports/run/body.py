"""One run of a single body, from its spec to its result row: the stepper of the ``body``
scene kind (:data:`reports.run.runner.STEPPERS`), called by :func:`reports.run.runner.execute`,
which prepares the row and turns a failure into the row's status.

Flow: the engine adapter's compiled or library stepping (``EngineBase.run``) -> the trajectory
(:class:`references.trajectory.Trajectory`) -> the reference (:func:`reference_for`, cached per
process) -> the metrics and their series (:func:`reports.metrics.body.metrics_and_series`, or
streamed over every step with ``--segment``) -> status and verdict
(:mod:`reports.metrics.verdicts`) -> the trajectory file. The timing pass
(:mod:`reports.run.timing`) times the run again.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import numpy as np

from reports.metrics import verdicts
from reports.metrics.body import metrics_and_series, roundoff_floor
from reports.run.files import SERIES_FORMAT, SERIES_NOTE, run_identity, series_table
from reports.store.atomic import replacing
from reports.store.results import StoreUnwritable, write_parquet_table
from reports.store.runs import RunSpec, output_columns, trajectory_path

# -- references, cached per process ------------------------------------------------------------


class _Content:
    """A scenario as a cache key: equal to any scenario of the same content
    (``scenario_hash``: every field a reference depends on), since a worker process receives
    a new copy of the scenario with each unit of work and a scenario object compares by
    identity."""

    __slots__ = ("hash", "scenario")

    def __init__(self, scenario):
        self.scenario = scenario
        self.hash = scenario.scenario_hash

    def __hash__(self) -> int:
        return hash(self.hash)

    def __eq__(self, other) -> bool:
        return isinstance(other, _Content) and other.hash == self.hash


@functools.lru_cache(maxsize=64)
def _reference_cached(key: _Content, t_bytes: bytes):
    from references.exact import reference_kept

    return reference_kept(key.scenario, np.frombuffer(t_bytes, dtype=float))[0]


def reference_for(scenario, t):
    """The scenario's reference at times ``t``, cached per process by the scenario's content
    and the times (the engines of a scenario share a grid) and kept across runs in the
    reference cache (references.cache); its arrays are read-only."""
    t_bytes = np.ascontiguousarray(t, dtype=float).tobytes()
    return _reference_cached(_Content(scenario), t_bytes)


@functools.lru_cache(maxsize=64)
def _expected_cached(key: _Content) -> dict:
    from references.exact import expected_observables

    return dict(expected_observables(key.scenario))


def expected_for(scenario) -> dict:
    """The scenario's exact observables (references.exact.expected_observables), cached per
    process by the scenario's content."""
    return _expected_cached(_Content(scenario))


def write_run_files(
    traj,
    series: dict,
    path: Path,
    fmt: str,
    identity: dict,
    body: dict | None = None,
    keep: str = "full",
) -> None:
    """Write a run's trajectory, atomically: Parquet with the per-sample error series as
    extra columns and units, frames, the run's identity and the scenario's ``body``
    (:func:`body_of`, what the report's scenario picture draws) in the schema metadata; or
    CSV with the series, and the body in its metadata, in a Parquet file beside it. With
    ``keep == "series"``: the series file the report draws (reports.run.files) at ``path``."""
    import pyarrow as pa

    from references.trajectory import COLUMNS, UNITS

    path.parent.mkdir(parents=True, exist_ok=True)
    if keep == "series":
        cols = dict(zip(COLUMNS, _columns_of(traj).T, strict=True)) | series
        table = series_table(cols, bool(identity.get("reference")))
        meta = {
            "director_bench.units": {
                c: UNITS.get(c, "1 (see docs/results.md)") for c in table.column_names
            },  # fmt: skip
            "director_bench.kept": SERIES_NOTE,
            "director_bench.run": {k: v for k, v in identity.items() if k != "reference"},
        }
        if body:
            meta["director_bench.body"] = body
        write_parquet_table(table, path, meta)
        return
    if fmt != "parquet":
        with replacing(path) as tmp:
            traj.write(tmp, "csv")
        series = {"t": traj.t, "wx": traj.omega_body[:, 0], "wy": traj.omega_body[:, 1],
                  "wz": traj.omega_body[:, 2], **series}  # fmt: skip
        meta = {"director_bench.body": body} if body else {}
        write_parquet_table(pa.table(series), path.with_name(path.stem + ".series.parquet"), meta)
        return
    data = _columns_of(traj)
    table = pa.table({c: data[:, i] for i, c in enumerate(COLUMNS)} | series)
    meta = {
        "director_bench.units": {**UNITS, **dict.fromkeys(series, "1 (see docs/results.md)")},
        "director_bench.frames": {
            "position, velocity, angular momentum": "world axes",
            "R": "body-to-world rotation, row-major R00..R22; columns are the directors",
            "wx, wy, wz": "body axes",
            "angular momentum about": "the centre of mass (free body) or the pivot",
        },
        "director_bench.run": identity,
    }
    if body:
        meta["director_bench.body"] = body
    write_parquet_table(table, path, meta)


def _columns_of(traj):
    """The trajectory as an (n, len(COLUMNS)) array, columns in references.trajectory's
    order."""
    n = len(traj)
    return np.column_stack(
        [
            traj.t, traj.position, traj.velocity, traj.rotation.reshape(n, 9),
            traj.omega_body, traj.energy, traj.angular_momentum, traj.constraint_velocity,
        ]
    )  # fmt: skip


def body_of(sc) -> dict:
    """A single body's scenario as the results folder keeps it beside its trajectories (the
    report draws the body from it, never from the scenario library): name, mass [kg],
    principal moments [kg m^2], pivot in body axes [m] (None: a free body) and initial
    angular velocity W in body axes [rad/s]."""
    return {
        "name": sc.name,
        "mass": float(sc.mass),
        "inertia": [float(v) for v in sc.inertia],
        "pivot": None if sc.pivot is None else [float(v) for v in sc.pivot],
        "omega_body": [float(v) for v in sc.omega_body],
    }


def run_body_spec(spec: RunSpec, row: dict, integ, sc, out, fmt: str, progress=None) -> None:
    """Run the single-body spec ``spec`` (its integrator ``integ``, its scenario at the run's
    horizon ``sc``) through its engine and fill ``row``: timings, metrics, status and verdict.
    ``progress``: a callback told the fraction of the run done. A failure raises;
    :func:`reports.run.runner.execute`, which prepared the row, makes it the row's status."""
    from references.engines import Diverged, get_engine

    cls = get_engine(spec.engine)
    recorder = _recorder(spec, sc)
    try:
        output = cls().run(
            sc,
            integ.name,
            spec.dt,
            spec.horizon,
            spec.saving,
            progress,
            recorder,
            accuracy=spec.accuracy,
        )
        diverged = None
    except Diverged as exc:
        output, diverged = exc.output, exc
    if output is not None and output.family and output.family != integ.family:
        row["family"] = output.family  # the algorithm this model ran (see RunOutput)
        integ = dataclasses.replace(integ, family=output.family)
    _measure(row, spec, sc, output, recorder, out, fmt)
    verdicts.judge(row, sc, integ, diverged)


def is_reference(engine: str) -> bool:
    """Whether ``engine``'s rows are the reference the others are measured against (its
    adapter's ``is_reference``: the exact reference), not a configuration under test."""
    from references.engines import get_engine

    return get_engine(engine).is_reference


def _recorder(spec: RunSpec, sc):
    if not spec.segment:
        return None
    from references.engines import step_plan
    from reports.metrics.streaming import StreamingRecorder

    _, saves = step_plan(spec.dt, spec.horizon, spec.saving)
    ref = None if is_reference(spec.engine) else functools.partial(reference_for, sc)
    return StreamingRecorder(saves, sc, spec.dt, spec.segment, ref)


def _measure(row, spec, sc, output, recorder, out, fmt) -> None:
    """Timings, settings and metrics of a run's output (also of a diverged run's part); the
    timing pass (reports.run.timing) times it again."""
    if output is None:
        return
    from references.trajectory import one_body

    traj = one_body(output.trajectory)  # a bodies axis of one body: the single body's file
    row.update(
        output_columns(output),
        roundoff_floor=roundoff_floor(sc, output.nstep),
        steps_taken=output.stats.get("steps taken", math.nan),
        steps_rejected=output.stats.get("steps rejected", math.nan),
    )
    if is_reference(spec.engine):
        ref = None
        row["reference_kind"] = output.settings.get("reference kind", "")
        row["reference_accuracy"] = float(output.settings.get("accuracy", math.nan))
    elif len(traj):
        from references.exact.numerical import ReferenceCostExceeded

        try:
            ref = reference_for(sc, traj.t)
            row["reference_kind"] = ref.kind
            row["reference_accuracy"] = float(ref.accuracy)
        except ReferenceCostExceeded as exc:  # the metrics without a reference; the judge says why
            ref = None
            row["reference_kind"] = "numerical"
            row["message"] = str(exc)
    else:
        ref = None
    series = None
    if len(traj):
        metrics, series = metrics_and_series(sc, traj, ref, expected_for(sc))
        row.update(metrics)
    if spec.accuracy is not None:
        row["accuracy_ratio"] = row["attitude_error_max"] / spec.accuracy
    if recorder is not None:
        row.update(recorder.maxima)
        if not math.isnan(recorder.reference_accuracy):
            row["reference_accuracy"] = max(row["reference_accuracy"], recorder.reference_accuracy)
    if out is not None and len(traj) and spec.keep != "none":
        rel = trajectory_path(spec, SERIES_FORMAT if spec.keep == "series" else fmt)
        identity = run_identity(row)
        if spec.keep == "series":
            identity["reference"] = is_reference(spec.engine)
        try:
            write_run_files(traj, series, Path(out) / rel, fmt, identity, body_of(sc), spec.keep)
        except OSError as exc:
            raise StoreUnwritable(
                f"{Path(out) / rel}: cannot write the run's trajectory ({exc.strerror or exc}; "
                "disk full or a file-size limit?); finished runs are kept, rerun to continue"
            ) from exc
        row["trajectory"] = rel.as_posix()
