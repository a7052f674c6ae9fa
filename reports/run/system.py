"""One run of a system of bodies, from its spec to its result row: the stepper of the
``system`` scene kind (:data:`reports.run.runner.STEPPERS`), called by
:func:`reports.run.runner.execute`, which prepares the row and turns a failure into the row's
status.

Flow: the engine's system builder (:func:`references.engines.system.run_system`) -> the
states (:class:`references.trajectory.Trajectory`) -> the reference
(:func:`references.engines.exact.system.reference`) -> the metrics
(:mod:`reports.metrics.system`) -> status and verdict (:mod:`reports.metrics.verdicts`) -> the
trajectory file (Parquet, per-body columns and the error series).
"""

from __future__ import annotations

import math
from pathlib import Path

from reports.metrics import verdicts
from reports.metrics.body import roundoff_floor
from reports.store.results import StoreUnwritable, write_parquet_table
from reports.store.runs import output_columns, trajectory_path


def run_system_spec(spec, row: dict, integ, sc, out: Path | None, fmt: str, progress=None) -> None:
    """Run the system spec ``spec`` (its integrator ``integ``, its scenario at the run's
    horizon ``sc``) and fill ``row``: timings, metrics, status and verdict (``progress`` is
    not told: a builder steps the whole run in one call). A failure raises;
    :func:`reports.run.runner.execute`, which prepared the row, makes it the row's status."""
    from references.engines.system import run_system

    output, diverged = step_built(spec, integ, sc, run_system, "systems of bodies")
    _measure(row, spec, sc, output, out, fmt)
    verdicts.judge(row, sc, integ, diverged)


def step_built(spec, integ, sc, run, what: str):
    """(output, the divergence or None) of a scene an engine's builder steps in one call
    (``run``: :func:`references.engines.system.run_system` or
    :func:`references.engines.contact.run_contact`), at the spec's fixed step; such scenes
    (``what``, for the message) have no target accuracy and no --segment streaming:
    :class:`references.engines.Unsupported` when the spec asks for either."""
    from references.engines import Diverged, Unsupported

    if spec.accuracy is not None or spec.segment:
        raise Unsupported(
            f"{spec.engine} {integ.name}: {what} run at fixed steps with the metrics at the "
            "saved states (no target accuracy, no --segment streaming)"
        )
    try:
        return run(spec.engine, sc, integ.name, spec.dt, spec.horizon, spec.saving), None
    except Diverged as exc:
        return exc.output, exc


def _measure(row, spec, sc, output, out, fmt):
    """Timings, settings, metrics and the trajectory file of a run's output; returns the
    reference used (None: none)."""
    from references.engines import Unsupported, get_engine
    from references.engines.exact.system import reference
    from reports.metrics.system import compute_system_metrics, error_series

    if output is None:
        return None
    traj = output.trajectory
    row.update(
        output_columns(output),
        roundoff_floor=roundoff_floor(sc, output.nstep),
    )
    ref = None
    if get_engine(spec.engine).is_reference:
        row["reference_kind"] = output.settings.get("reference kind", "")
        row["reference_accuracy"] = float(output.settings.get("accuracy", math.nan))
    elif len(traj):
        try:
            ref = reference(sc, traj.t)
            row["reference_kind"] = ref.kind
            row["reference_accuracy"] = ref.accuracy
            if ref.horizon < traj.t[-1]:
                why = ref.notes.get("horizon reason") or "chaotic motion"
                rate = ref.notes.get("growth rate 1/s", math.nan)
                row["message"] = (
                    f"trajectory errors judged up to the reference's trusted horizon "
                    f"t = {ref.horizon:.4g} s ({why}, growth rate {rate:.4g} 1/s); "
                    "invariants and joints over the whole run"
                )
        except Unsupported as exc:
            row["reference_kind"] = "none"
            row["message"] = f"no reference, trajectory errors not measured: {exc}"
    kept = {}  # the metrics' series, reused by the file's series
    if len(traj):
        row.update(compute_system_metrics(sc, traj, ref, keep=kept))
    if out is not None and len(traj) and spec.keep != "none":
        _write(row, spec, traj, error_series(sc, traj, ref, kept), Path(out), fmt)
    return ref


def _write(row, spec, traj, series, out: Path, fmt: str) -> None:
    """The run's trajectory: Parquet with per-body columns, the error series and the run's
    identity (CSV is not offered for systems: the file is written as Parquet)."""
    import numpy as np
    import pyarrow as pa

    from reports.run.files import SERIES_FORMAT, SERIES_NOTE, bodies_file, series_table

    rel = trajectory_path(spec, SERIES_FORMAT if spec.keep == "series" else "parquet")
    path = out / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    units = {"energy_change": "J", "joint_gap": "m", "loop_gap": "m", "attitude_error": "rad"}
    cols, meta = bodies_file(row, traj, units)
    table = pa.table({**cols, **{k: np.asarray(v, dtype=float) for k, v in series.items()}})
    if spec.keep == "series":  # the series the system figure draws (reports.run.files)
        table = series_table({c: table.column(c).to_numpy() for c in table.column_names}, False)
        meta = {
            "director_bench.units": {
                c: meta["director_bench.units"].get(c, "1") for c in table.column_names
            },  # fmt: skip
            "director_bench.kept": SERIES_NOTE,
            "director_bench.bodies": meta["director_bench.bodies"],
            "director_bench.run": meta["director_bench.run"],
        }
    try:
        write_parquet_table(table, path, meta)
    except OSError as exc:
        raise StoreUnwritable(f"{path}: cannot write the run's trajectory ({exc})") from exc
    row["trajectory"] = rel.as_posix()
