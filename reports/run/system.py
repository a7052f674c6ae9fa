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

import contextlib
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
            ref = shared_reference(sc, traj.t, out)
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


#: the folder of a results folder where, while a run is in progress, the worker process that
#: computed a system's reference on a time grid leaves it for the other workers (the process
#: pool lets one unit compute it while the others of that grid wait: :func:`shared_key`);
#: :func:`reports.run.runner.run_suite` removes it when it starts and when it ends
SHARED = ".references"


def shared_key(spec) -> str | None:
    """The key of the reference a system run's metrics need (its scenario's content and
    the time grid of its saves: dt, horizon, decimation), for the process pool's gate
    (reports.run.parallel): the first unit holding the key computes the reference and
    leaves it in :data:`SHARED`; the others are handed out after it and read it. None: the
    run needs no shared reference (a single body's reference is cheap, a contact scene's is
    a closed form, the exact reference's own runs are the reference)."""
    from reports.run.body import is_reference

    if spec.scenario.kind != "system" or is_reference(spec.engine):
        return None
    return f"reference {spec.scenario.scenario_hash} {spec.dt!r} {spec.horizon!r} {spec.saving}"


def shared_reference(sc, t, out: Path | None):
    """:func:`references.engines.exact.system.reference` of ``sc`` at the times ``t``, which
    each worker process would otherwise compute for itself (a numerical reference or a
    Floquet analysis takes 0.1-0.4 s of CPU per scenario and grid): read from the run's
    :data:`SHARED` folder when another process left it there, else computed and left there
    (written whole or not at all). Without an output folder, or when the folder cannot be
    read or written, computed here. A refusal (Unsupported) is not kept: it is raised.
    "Computed" includes read from the reference cache, where an earlier run kept it
    (:mod:`references.cache`); this folder shares it within the run when that cache is off."""
    import hashlib

    import numpy as np

    from references.engines.exact.system import reference

    if out is None:
        return reference(sc, t)
    key = (sc.scenario_hash, np.ascontiguousarray(t, dtype=float).tobytes())
    ref = _SEEN.get(key)
    if ref is not None:
        return ref
    grid = hashlib.sha256(key[1]).hexdigest()[:20]
    path = Path(out) / SHARED / f"{key[0]}-{grid}.pickle"
    ref = _read_shared(path, key)
    if ref is None:
        ref = reference(sc, t)
        _leave(path, key, ref)
    while len(_SEEN) >= _SEEN_MAX:  # bounded like the reference's own cache
        _SEEN.pop(next(iter(_SEEN)))
    _SEEN[key] = ref
    return ref


#: the shared references this process has used ((scenario hash, times) -> reference): the
#: runs of a grid share one, as they share the reference's own per-process cache
_SEEN: dict = {}
_SEEN_MAX = 16


def _read_shared(path: Path, key: tuple):
    """The reference another process left at ``path`` for ``key``, or None (absent,
    unreadable, or left for another key)."""
    import pickle

    try:
        with open(path, "rb") as fh:
            got, ref = pickle.load(fh)
    except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError):
        return None
    return ref if got == key else None


def _leave(path: Path, key: tuple, ref) -> None:
    """Leave ``ref`` at ``path`` for the other processes (a temporary file renamed: whole or
    absent); nothing when the folder cannot be written."""
    import os
    import pickle

    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as fh:
            pickle.dump((key, ref), fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            tmp.unlink()


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
