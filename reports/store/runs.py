"""A run and its row: the columns of the results table (:data:`RESULT_COLUMNS`, documented
column by column in ``docs/results.md``), what a run is (:class:`RunSpec`) and its identity,
the blank row it starts from and the columns of its output, and where its files go in the
output folder.

A run's identity (:attr:`RunSpec.run_id`) is a hash of everything that determines its
result: the scenario's content hash, the engine and its version, the integrator, dt, the
horizon, save_every, the segmenting and the suite's version. The gate and ``compare`` match
runs on the configuration (:data:`CONFIG_KEY`), refuse a pair that is not the same run
(:data:`RUN_IDENTITY`, every column that differs named by :func:`identity_differences`) and
compare the metrics of a pair that differs only in the engine's release
(:data:`VERSION_COLUMNS`). The rows live in the store of :mod:`reports.store.results`.
"""

from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import json
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from reports.metrics.catalog import METRIC_COLUMNS

#: a run's costs: its wall, engine and CPU times and what is derived from them (the
#: timing pass's repeats, spread and CPU share)
COST_COLUMNS = (
    "wall_time_s",
    "engine_time_s",
    "glue_time_s",
    "wall_time_max_s",
    "engine_time_max_s",
    "timing_repeats",
    "cpu_time_s",
    "cpu_time_max_s",
    "engine_time_spread_s",
    "cpu_share",
    "ns_per_step",
    "engine_ns_per_step",
)

#: every column of a run's row; the metric columns are the catalog's
#: (:data:`reports.metrics.catalog.METRIC_COLUMNS`), in its order
RESULT_COLUMNS = (
    "run_id",
    "scenario",
    "scenario_hash",
    "scene_kind",
    "engine",
    "engine_version",
    "integrator",
    "family",
    "order",
    "suite_integrated",
    "reference",
    "dt",
    "target_accuracy",
    "t_end",
    "save_every",
    "segment",
    "status",
    "verdict",
    "verdict_detail",
    "message",
    "t_diverged",
    "nstep",
    *COST_COLUMNS,
    "evals_per_step",
    "steps_taken",
    "steps_rejected",
    *METRIC_COLUMNS,
    "accuracy_ratio",
    "convergence_points",
    "energy_scale",
    "momentum_scale",
    "reference_kind",
    "reference_accuracy",
    "roundoff_floor",
    "settings",
    "trajectory",
    "suite_version",
    "finished_at",
)


#: the columns that differ between two runs of the same configuration: the costs and the
#: time of day (every other column is deterministic)
TIMING_COLUMNS = frozenset({*COST_COLUMNS, "finished_at"})

#: columns holding text; every other column holds a number
TEXT_COLUMNS = frozenset(
    {
        "run_id",
        "scenario",
        "scenario_hash",
        "scene_kind",
        "engine",
        "engine_version",
        "integrator",
        "family",
        "suite_integrated",
        "status",
        "verdict",
        "verdict_detail",
        "message",
        "reference_kind",
        "settings",
        "trajectory",
        "suite_version",
        "finished_at",
    }
)


NUMERIC_COLUMNS = frozenset(RESULT_COLUMNS) - TEXT_COLUMNS


#: statuses, in the order reports list them
STATUSES = ("ok", "reference-inaccurate", "diverged", "error", "unsupported", "unavailable")


#: statuses a rerun tries again: the engine may have been installed since, or the fault of
#: the suite that made the error may have been fixed
RETRY_STATUSES = frozenset({"unavailable", "error"})


#: the columns that name one configuration in tables (several identities may share them);
#: target_accuracy is NaN for fixed-step integrators
CONFIG_KEY = ("scenario", "engine", "integrator", "dt", "target_accuracy")


#: the columns of a run's identity (:attr:`RunSpec.run_id`) beyond its configuration: two
#: rows of one configuration that differ in any of them are different runs
IDENTITY_COLUMNS = (
    "scenario_hash",
    "t_end",
    "save_every",
    "segment",
    "engine_version",
    "suite_version",
)


#: the identity columns that name an engine's release: two runs of one configuration that
#: differ only in them did the same thing on another release, so the gate and ``compare``
#: compare their metrics and report the release change (:class:`reports.gate.rule.VersionChange`)
#: instead of refusing the pair
VERSION_COLUMNS = ("engine_version",)


#: the identity columns that make two runs of one configuration different runs (another
#: scenario content, horizon, save_every, segmenting or suite version): never compared
RUN_IDENTITY = tuple(c for c in IDENTITY_COLUMNS if c not in VERSION_COLUMNS)


#: the identity columns shared by every run of a scenario in one invocation (the engine's
#: version is per engine, save_every per integrator: an error-controlled one saves at its
#: checkpoints)
SCENARIO_IDENTITY = ("scenario_hash", "t_end", "segment", "suite_version")


def suite_version() -> str:
    from reports import __version__

    return __version__


@dataclass(frozen=True)
class RunSpec:
    """One run: a scenario, an engine, one of its integrators and a step size, with the
    horizon and decimation (None: the scenario's) and, for long horizons, ``segment``: the
    number of steps between streaming-metric updates (None: metrics at the saved samples).
    ``keep``: what the run keeps on disk beside its row (reports.run.files: ``full``, its
    trajectory; ``series``, the series the report draws; ``none``), no part of its identity:
    the metrics are computed before anything is kept."""

    scenario: object  # scenarios.Scenario
    engine: str
    integrator: str
    dt: float
    t_end: float | None = None
    save_every: int | None = None
    segment: int | None = None
    engine_version: str = ""
    accuracy: float | None = None
    keep: str = "full"

    @property
    def horizon(self) -> float:
        return self.scenario.t_end if self.t_end is None else float(self.t_end)

    @property
    def saving(self) -> int:
        return self.scenario.save_every if self.save_every is None else int(self.save_every)

    @functools.cached_property
    def run_id(self) -> str:
        """Identity of the run: a hash of everything that determines its result (computed
        once per spec: the runner and the timing passes ask for it per row; the spec is
        frozen and so is its scenario)."""
        ident = {
            "scenario_hash": self.scenario.scenario_hash,
            "engine": self.engine,
            "engine_version": self.engine_version,
            "integrator": self.integrator,
            "dt": repr(float(self.dt)),
            "t_end": repr(self.horizon),
            "save_every": self.saving,
            "segment": self.segment,
            "accuracy": None if self.accuracy is None else repr(float(self.accuracy)),
            "suite_version": suite_version(),
        }
        blob = json.dumps(ident, sort_keys=True, separators=(",", ":")).encode()
        return hashlib.sha256(blob).hexdigest()[:20]

    @property
    def key(self) -> tuple:
        """The configuration this run belongs to (see :data:`CONFIG_KEY`)."""
        return config_key(self.scenario.name, self.engine, self.integrator, self.dt, self.accuracy)


def config_key(scenario: str, engine: str, integrator: str, dt: float, accuracy=None) -> tuple:
    """A hashable configuration key; an absent or NaN target accuracy is None."""
    acc = None if accuracy is None or accuracy != accuracy else float(f"{float(accuracy):.12g}")
    return (str(scenario), str(engine), str(integrator), float(f"{float(dt):.12g}"), acc)


def _ident_value(col: str, v):
    """An identity value in comparable form: numbers as floats (NaN and empty: None), text
    as text."""
    if col in NUMERIC_COLUMNS:
        try:
            f = float(v)
        except (TypeError, ValueError):
            return None
        return None if math.isnan(f) else float(f"{f:.12g}")
    return "" if v is None else str(v)


def _show(col: str, v) -> str:
    if v is None or v == "":
        return "none"
    if col == "scenario_hash":
        return str(v)[:12]
    return f"{v:g}" if isinstance(v, float) else str(v)


def identity_differences(a, b, vary: Iterable[str] = ()) -> list[str]:
    """The run-identity columns (:data:`RUN_IDENTITY`) in which rows ``a`` and ``b`` (of one
    configuration) differ, each as ``"<column> <a> vs <b>"`` (e.g. ``"t_end 30 vs 10"``);
    columns named in ``vary`` are allowed to differ. An empty list: the same run, possibly on
    another engine release (:data:`VERSION_COLUMNS`, compared by :func:`same_version`)."""
    out = []
    for col in RUN_IDENTITY:
        if col in vary:
            continue
        x, y = _ident_value(col, a.get(col)), _ident_value(col, b.get(col))
        if x != y:
            what = "scenario content (scenario_hash)" if col == "scenario_hash" else col
            out.append(f"{what} {_show(col, x)} vs {_show(col, y)}")
    return out


def same_version(a, b) -> bool:
    """Whether rows ``a`` and ``b`` ran on the same engine release (:data:`VERSION_COLUMNS`)."""
    return all(_ident_value(c, a.get(c)) == _ident_value(c, b.get(c)) for c in VERSION_COLUMNS)


def blank_row(spec: RunSpec) -> dict:
    """The row of ``spec`` before it runs: identity filled, every result empty (NaN)."""
    row = dict.fromkeys(RESULT_COLUMNS, "")
    for col in NUMERIC_COLUMNS:
        row[col] = math.nan
    row.update(
        run_id=spec.run_id,
        scenario=spec.scenario.name,
        scenario_hash=spec.scenario.scenario_hash,
        scene_kind=spec.scenario.kind,
        engine=spec.engine,
        engine_version=spec.engine_version,
        integrator=spec.integrator,
        dt=float(spec.dt),
        target_accuracy=math.nan if spec.accuracy is None else float(spec.accuracy),
        t_end=spec.horizon,
        save_every=spec.saving,
        segment=math.nan if spec.segment is None else int(spec.segment),
        energy_scale=spec.scenario.energy_scale,
        momentum_scale=spec.scenario.momentum_scale,
        suite_version=suite_version(),
    )
    return row


def output_columns(output, timings=()) -> dict:
    """The columns a run's output fills (a ``RunOutput`` of references.engines): its steps,
    its timings (:func:`timing_columns` of ``timings``, the timings of the run and its
    repeats; without them the output's own), the evaluations per step and the settings."""
    timings = [t for t in (timings or (getattr(output, "timing", None),)) if t is not None]
    if timings:
        cols = timing_columns(output.nstep, timings)
    else:  # an output that measured no timing (a builder's): its wall and engine times
        n = max(output.nstep, 1)
        cols = dict(
            wall_time_s=output.wall_time_s,
            engine_time_s=output.engine_time_s,
            glue_time_s=output.glue_time_s,
            ns_per_step=1e9 * output.wall_time_s / n,
            engine_ns_per_step=1e9 * output.engine_time_s / n,
            wall_time_max_s=output.wall_time_s,
            engine_time_max_s=output.engine_time_s,
            timing_repeats=1,
        )
    return dict(
        nstep=output.nstep,
        **cols,
        evals_per_step=output.evals_per_step,
        settings=json.dumps(output.settings, sort_keys=True, default=str),
    )


def starved(row) -> bool:
    """Whether a stored run's engine time was measured *starved*: no timing of it ran clean
    enough that the engine's CPU time is known within
    :data:`references.costs.STARVED` of itself (``engine_time_spread_s`` beyond
    that share of ``engine_time_s``; a row without a spread never is)."""
    from references.costs import STARVED

    def value(col):
        try:
            return float(row.get(col))
        except (TypeError, ValueError):
            return math.nan

    spread, engine = value("engine_time_spread_s"), value("engine_time_s")
    return spread > STARVED * engine if not math.isnan(spread) else False


def timing_columns(nstep: int, timings) -> dict:
    """The cost columns of a run from its ``timings`` (references.engines.timing.Timing,
    the run's and its repeats'): the engine time of the one kept
    (:func:`references.engines.timing.best`: the least among those not starved), the least
    CPU and wall time of all (read, not priced), and the largest of each over all.
    ``engine_time_s``: the engine calls' CPU time (``engine_time_spread_s``: its
    uncertainty); ``cpu_time_s``: the whole stepping's CPU time, the suite's glue included
    (``glue_time_s`` the difference); ``wall_time_s``: its wall time; ``cpu_share``: CPU over
    wall (below 1: the run waited for a CPU); per step: ``engine_ns_per_step`` (the
    engine's) and ``ns_per_step`` (the whole step's CPU time)."""
    from references.engines.timing import best

    timings = list(timings)
    kept, _ = best(timings)
    n = max(int(nstep), 1)
    # the whole step's CPU time is read, not priced: the least of all timings (a first run
    # that compiled or loaded code inside its stepping is not the step's cost)
    cpu = max(min(t.cpu for t in timings), kept.engine)
    return dict(
        wall_time_s=min(t.wall for t in timings),
        engine_time_s=kept.engine,
        engine_time_spread_s=kept.spread,
        cpu_time_s=cpu,
        glue_time_s=max(cpu - kept.engine, 0.0),
        cpu_share=kept.share,
        ns_per_step=1e9 * cpu / n,
        engine_ns_per_step=1e9 * kept.engine / n,
        wall_time_max_s=max(t.wall for t in timings),
        engine_time_max_s=max(t.engine for t in timings),
        cpu_time_max_s=max(t.cpu for t in timings),
        timing_repeats=len(timings),
    )


def finish_time() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.]+", "-", str(text)).strip("-")


def trajectory_path(spec: RunSpec, fmt: str = "parquet") -> Path:
    """Relative path of a run's trajectory file inside the output folder."""
    name = f"{slug(spec.engine)}__{slug(spec.integrator)}__dt{spec.dt:.6g}.{fmt}"
    return Path("trajectories") / slug(spec.scenario.name) / name


def error_series_path(traj_rel: Path) -> Path:
    """The file holding a run's per-sample metric series (for the time plots): the
    trajectory's own Parquet file, whose extra columns they are, or a ``.series.parquet``
    file beside a CSV trajectory."""
    traj_rel = Path(traj_rel)
    if traj_rel.suffix == ".parquet":
        return traj_rel
    return traj_rel.with_name(traj_rel.stem + ".series.parquet")
