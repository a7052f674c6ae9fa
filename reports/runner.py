"""The scenario runner: scenarios x engines x integrators x dt -> one row per run.

Data flow: a :class:`RunSpec` names one run; :func:`execute` runs it (engine adapter ->
trajectory in the suite's schema -> metrics against the reference) and returns a row, never
raising for a failure of the run itself: a missing engine, a step that cannot be solved, a
diverged state or an unsupported scenario become a row with a ``status`` and a ``message``.
:func:`run_suite` executes many specs, appending each row to ``results.csv`` as soon as it
finishes, so an interruption loses only the run in flight, and a rerun skips what is done.
"""

from __future__ import annotations

import csv
import datetime as _dt
import functools
import json
import math
import os
import re
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from reports.metrics import METRIC_COLUMNS, compute_metrics, convergence_order

RESULT_COLUMNS = (
    "scenario",
    "scenario_hash",
    "engine",
    "engine_version",
    "integrator",
    "family",
    "order",
    "dt",
    "t_end",
    "status",
    "message",
    "nstep",
    "wall_time_s",
    "ns_per_step",
    *METRIC_COLUMNS,
    "settings",
    "trajectory",
    "finished_at",
)

#: Statuses a rerun tries again: the engine may have been installed since, or the run was cut.
RETRY_STATUSES = frozenset({"unavailable"})


@dataclass(frozen=True)
class RunSpec:
    """One run: a scenario, an engine, one of its integrators and a step size."""

    scenario: object  # scenarios.Scenario
    engine: str
    integrator: str
    dt: float
    t_end: float | None = None
    save_every: int | None = None
    #: run in segments of this many steps with streaming metrics over every step
    #: (see :mod:`reports.streaming`); None: one run, metrics at the saved samples
    segment: int | None = None

    @property
    def horizon(self) -> float:
        return self.scenario.t_end if self.t_end is None else self.t_end

    @property
    def key(self) -> tuple:
        """Identity of a run in a results table (used to resume and to compare baselines)."""
        return run_key(self.scenario.name, self.engine, self.integrator, self.dt)


def run_key(scenario: str, engine: str, integrator: str, dt: float) -> tuple:
    return (str(scenario), str(engine), str(integrator), float(f"{float(dt):.12g}"))


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.]+", "-", str(text)).strip("-")


def trajectory_path(spec: RunSpec, fmt: str = "parquet") -> Path:
    """Relative path of a run's trajectory file inside the output folder."""
    name = f"{slug(spec.engine)}__{slug(spec.integrator)}__dt{spec.dt:.6g}.{fmt}"
    return Path("trajectories") / slug(spec.scenario.name) / name


def error_series_path(traj_rel: Path) -> Path:
    """The per-sample metric series stored beside a trajectory (for the time plots)."""
    return traj_rel.with_name(traj_rel.stem + ".series.parquet")


def write_error_series(scenario, traj, ref, path: Path) -> None:
    """Per-sample drifts and errors of one run, so that plots are pure functions of files."""
    import pandas as pd

    from reports import metrics

    cols = {
        "t": traj.t,
        "energy_drift": metrics.energy_drift(scenario, traj),
        "momentum_drift": metrics.momentum_drift(scenario, traj),
        "orthonormality": metrics.orthonormality(traj),
        "wx": traj.omega_body[:, 0],
        "wy": traj.omega_body[:, 1],
        "wz": traj.omega_body[:, 2],
    }
    if ref is not None:
        cols["attitude_error"] = metrics.attitude_error(traj, ref)
        cols["omega_error"] = metrics.omega_error(traj, ref)
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(cols).to_parquet(path, index=False)


# -- references, cached per process ------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def _reference_cached(scenario, t_bytes: bytes):
    from references.exact import reference_trajectory

    return reference_trajectory(scenario, np.frombuffer(t_bytes, dtype=float))


def reference_for(scenario, t):
    """The scenario's reference at times ``t`` (cached: several engines share one grid)."""
    return _reference_cached(scenario, np.ascontiguousarray(t, dtype=float).tobytes())


@functools.lru_cache(maxsize=64)
def expected_for(scenario) -> dict:
    from references.exact import expected_observables

    return dict(expected_observables(scenario))


# -- one run -----------------------------------------------------------------------------------
def _blank_row(spec: RunSpec) -> dict:
    row = dict.fromkeys(RESULT_COLUMNS, "")
    row.update(
        scenario=spec.scenario.name,
        scenario_hash=spec.scenario.scenario_hash,
        engine=spec.engine,
        integrator=spec.integrator,
        dt=float(spec.dt),
        t_end=float(spec.horizon),
    )
    for col in METRIC_COLUMNS:
        row[col] = math.nan
    return row


def execute(spec: RunSpec, out: Path | None = None, fmt: str = "parquet") -> dict:
    """Run one spec and return its result row (see ``RESULT_COLUMNS``).

    Writes the trajectory (and, once per grid, the reference) under ``out/trajectories`` when
    ``out`` is given. Never raises for a failure of the run: the row says what happened.
    """
    from references.engines import EngineError, get_engine

    if spec.segment:
        from reports.streaming import execute_segmented

        return execute_segmented(spec, spec.segment, out, fmt)
    row = _blank_row(spec)
    try:
        engine_cls = get_engine(spec.engine)
        row["engine_version"] = engine_cls.version()
        integ = engine_cls.integrator(spec.integrator)
        row["family"], row["order"] = integ.family, integ.order
        engine = engine_cls()
        output = engine.run(spec.scenario, spec.integrator, spec.dt, spec.t_end, spec.save_every)
        traj = output.trajectory
        row["nstep"] = output.nstep
        row["wall_time_s"] = output.wall_time_s
        row["ns_per_step"] = 1e9 * output.wall_time_s / max(output.nstep, 1)
        row["settings"] = json.dumps(output.settings, sort_keys=True, default=str)
        ref = None if spec.engine == "exact" else reference_for(spec.scenario, traj.t)
        row.update(compute_metrics(spec.scenario, traj, ref, expected_for(spec.scenario)))
        if out is not None:
            rel = trajectory_path(spec, fmt)
            traj.write(Path(out) / rel, fmt)
            write_error_series(spec.scenario, traj, ref, Path(out) / error_series_path(rel))
            row["trajectory"] = rel.as_posix()
        bad = [c for c in METRIC_COLUMNS if row[c] == math.inf]
        if bad:
            row["status"] = "diverged"
            row["message"] = f"non-finite state during the run (metrics {', '.join(bad)})"
        else:
            row["status"] = "ok"
    except EngineError as exc:
        row["status"] = exc.status
        row["message"] = str(exc)
    except Exception as exc:  # noqa: BLE001 - a run's failure is a row, never a crash
        row["status"] = "error"
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        where = f"{Path(tb.filename).name}:{tb.lineno}"
        row["message"] = f"{type(exc).__name__}: {exc} (at {where})"
    row["finished_at"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    return row


# -- many runs ---------------------------------------------------------------------------------
def plan(
    scenarios: Sequence,
    engines: Sequence[str] | None = None,
    integrators: Sequence[str] | None = None,
    dts: Sequence[float] | None = None,
    t_end: float | None = None,
    sweep: bool = True,
    save_every: int | None = None,
    segment: int | None = None,
) -> list[RunSpec]:
    """The specs of a suite: every scenario x engine x integrator x dt.

    ``dts`` None: each scenario's ``dt`` plus, with ``sweep``, its ``dt_sweep``. ``integrators``
    None: every integrator of each engine; else only those named (an engine offering none of
    them contributes nothing). ``save_every`` overrides the scenarios' decimation;
    ``segment`` runs long horizons in segments with streaming metrics over every step.
    Engines that are not installed still get specs, so that their
    absence is recorded as rows.
    """
    from references.engines import engine_names, get_engine, step_plan

    engines = list(engines) if engines else engine_names()
    specs = []
    for sc in scenarios:
        if dts:
            steps = [float(h) for h in dts]
        else:
            steps = [sc.dt, *(sc.dt_sweep if sweep else ())]
        steps = sorted(set(steps), reverse=True)
        horizon = sc.t_end if t_end is None else t_end
        for h in steps:
            # A step or horizon from the command line that does not fit the scenario is the
            # user's input to fix, said once, not a failed row per engine and integrator.
            try:
                step_plan(h, horizon, sc.save_every if save_every is None else save_every)
            except ValueError as exc:
                raise ValueError(f"scenario {sc.name!r}: {exc}") from None
        for name in engines:
            cls = get_engine(name)
            names = [i.name for i in cls.integrators]
            if integrators:
                names = [n for n in names if n in integrators]
            if name == "exact":
                steps_e = [sc.dt if not dts else steps[-1]]
            else:
                steps_e = steps
            for integ in names:
                for h in steps_e:
                    specs.append(RunSpec(sc, name, integ, h, t_end, save_every, segment))
    return specs


def default_dt(rows) -> float:
    """The step shown in per-dt tables and time plots: the scenario's own ``dt``, which is
    the step of the exact reference's run (:func:`plan` runs it there only); without such a
    row, the dt with the most runs, ties broken by the smaller step."""
    exact = rows[rows["engine"] == "exact"]
    if len(exact):
        return float(exact["dt"].iloc[0])
    counts = rows.groupby("dt").size()
    return max(counts.index, key=lambda h: (counts[h], -h))


def read_results(path: Path):
    """The results table at ``path`` (a results.csv or its folder) as a pandas DataFrame."""
    import pandas as pd

    path = Path(path)
    if path.is_dir():
        path = path / "results.csv"
    if not path.exists():
        raise FileNotFoundError(f"{path}: no results table here (run `director-bench run` first)")
    df = pd.read_csv(path, keep_default_na=True)
    for col in ("message", "settings", "trajectory", "engine_version", "family"):
        if col in df:
            df[col] = df[col].astype(object).where(df[col].notna(), "").astype(str)
    return df


def _append_row(path: Path, row: dict) -> None:
    new = not path.exists()
    with path.open("a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=RESULT_COLUMNS)
        if new:
            writer.writeheader()
        writer.writerow({k: row.get(k, "") for k in RESULT_COLUMNS})
        fh.flush()
        os.fsync(fh.fileno())


def add_convergence_orders(df):
    """Fill ``convergence_order`` per (scenario, engine, integrator) from the attitude error
    over the dt values present (NaN where fewer than two usable points)."""
    df = df.copy()
    df["convergence_order"] = math.nan
    ok = df["status"] == "ok"
    for _, grp in df[ok].groupby(["scenario", "engine", "integrator"]):
        if grp["dt"].nunique() < 2:
            continue
        slope = convergence_order(grp["dt"], grp["attitude_error_max"])
        df.loc[grp.index, "convergence_order"] = slope
    return df


def run_suite(
    specs: Iterable[RunSpec],
    out: str | Path,
    redo: bool = False,
    fmt: str = "parquet",
    progress: bool = True,
    mapper: Callable | None = None,
) -> tuple:
    """Execute ``specs``, writing ``out/results.csv`` row by row; returns (DataFrame, n_run).

    Runs already in ``out/results.csv`` are skipped unless ``redo`` (except those whose status
    is in ``RETRY_STATUSES``). ``mapper(fn, specs)`` may run specs elsewhere (a process pool,
    a Dask cluster) and must yield rows as they finish; the default runs them here in order.
    """
    import pandas as pd

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results = out / "results.csv"
    specs = list(specs)
    done = {}
    if results.exists() and not redo:
        old = read_results(results)
        for _, r in old.iterrows():
            if r["status"] not in RETRY_STATUSES:
                done[run_key(r["scenario"], r["engine"], r["integrator"], r["dt"])] = True
    elif results.exists() and redo:
        old = read_results(results)
        keys = {s.key for s in specs}
        keep = [
            run_key(r["scenario"], r["engine"], r["integrator"], r["dt"]) not in keys
            for _, r in old.iterrows()
        ]
        old[keep].to_csv(results, index=False)
    todo = [s for s in specs if s.key not in done]

    bar = None
    if progress and todo:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(todo), unit="run", desc="director-bench", dynamic_ncols=True)
    fn = functools.partial(execute, out=out, fmt=fmt)
    rows_iter = mapper(fn, todo) if mapper is not None else map(fn, todo)
    n_run = 0
    try:
        for row in rows_iter:
            _append_row(results, row)
            n_run += 1
            if bar is not None:
                bar.set_postfix_str(f"{row['scenario']}/{row['engine']}/{row['integrator']}")
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    df = read_results(results)
    df = df.drop_duplicates(subset=["scenario", "engine", "integrator", "dt"], keep="last")
    # Rows arrive in completion order when runs execute in parallel: sort so that the table
    # is the same whatever executed it.
    df = df.sort_values(["scenario", "engine", "integrator", "dt"], ignore_index=True)
    df = add_convergence_orders(df)
    tmp = results.with_suffix(".csv.tmp")
    df.to_csv(tmp, index=False)
    tmp.replace(results)
    return pd.DataFrame(df), n_run
