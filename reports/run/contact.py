"""One run of a contact scene, from its spec to its result row: the stepper of the ``contact``
scene kind (a scene with ``[[contacts]]``; :data:`reports.run.runner.STEPPERS`), called by
:func:`reports.run.runner.execute`, which prepares the row and turns a failure into the row's
status.

Flow: the engine's contact builder (:func:`references.engines.contact.run_contact`) -> the
states and the engine's contact forces -> the scene's closed form at the saved times
(:func:`references.exact.contact_scene.contact_motion`) -> the contact metrics
(:mod:`reports.metrics.contact`) -> status and verdict (:mod:`reports.metrics.verdicts`) -> the
trajectory file (Parquet: per-body columns, and per sample the distance moved, the deepest
penetration and the closed form's distance, for the report's figures).
"""

from __future__ import annotations

import math
from pathlib import Path

from reports.metrics import verdicts
from reports.store.results import StoreUnwritable, write_parquet_table
from reports.store.runs import output_columns, trajectory_path


def run_contact_spec(spec, row: dict, integ, sc, out: Path | None, fmt: str, progress=None) -> None:
    """Run the contact spec ``spec`` (its configuration ``integ``, its scene at the run's
    horizon ``sc``) and fill ``row`` (``progress`` is not told: a builder steps the whole run
    in one call); a failure raises (the caller makes it the row)."""
    from references.engines import get_engine
    from references.engines.contact import run_contact
    from reports.run.system import step_built

    output, diverged = step_built(spec, integ, sc, run_contact, "contact scenes")
    _measure(row, spec, sc, output, out, get_engine(spec.engine).is_reference)
    verdicts.judge(row, sc, integ, diverged)


def _measure(row, spec, sc, output, out, is_reference):
    """Timings, settings, metrics and the trajectory file; returns the closed form (or None)."""
    from references.exact._util import ReferenceNotApplicable
    from references.exact.contact_scene import contact_motion
    from reports.metrics.contact import compute_contact_metrics

    if output is None:
        return None
    traj = output.trajectory
    row.update(output_columns(output))
    ref = None
    if len(traj):
        try:
            ref = contact_motion(sc, traj.t)
            row["reference_kind"] = sc.reference
            row["reference_accuracy"] = float(ref.accuracy["attitude"])
        except ReferenceNotApplicable as exc:
            row["reference_kind"] = "none"
            row["message"] = f"no closed form: {exc}"
        if is_reference:
            row["reference_kind"] = sc.reference
        row.update(compute_contact_metrics(sc, output, ref))
    if out is not None and len(traj):
        _write(row, spec, sc, output, ref, Path(out))
    return ref


def series(sc, output, ref) -> dict:
    """Per-sample series of a contact run (the figures read them): the distance each body's
    centre of mass has moved, the largest over the bodies (m), the deepest penetration over
    the pairs (m), and the closed form's distance moved (m; NaN without one)."""
    import numpy as np

    from reports.metrics.contact import _gaps

    tr = output.trajectory
    moved = np.max(np.linalg.norm(tr.position - tr.position[:1], axis=2), axis=1)
    pen = np.max(np.maximum(-_gaps(sc, output), 0.0), axis=0)
    exact = np.full(len(tr), math.nan)
    if ref is not None:
        exact = np.max(np.linalg.norm(ref.x - ref.x[:1], axis=2), axis=1)
    return {"moved": moved, "penetration": pen, "moved_exact": exact}


def _write(row, spec, sc, output, ref, out: Path) -> None:
    import numpy as np
    import pyarrow as pa

    from reports.run.files import bodies_file

    rel = trajectory_path(spec, "parquet")
    path = out / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    units = {"moved": "m", "penetration": "m", "moved_exact": "m"}
    cols, meta = bodies_file(row, output.trajectory, units)
    extra = {k: np.asarray(v, dtype=float) for k, v in series(sc, output, ref).items()}
    table = pa.table({**cols, **extra})
    try:
        write_parquet_table(table, path, meta)
    except OSError as exc:
        raise StoreUnwritable(f"{path}: cannot write the run's trajectory ({exc})") from exc
    row["trajectory"] = rel.as_posix()
