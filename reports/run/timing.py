"""The timing pass: once every run of a scenario is stored, its configurations are run again
in one process, in alternation (A B C, then B C A, ...), each over a bounded *window* of its
first steps, and each run keeps the best of its timings (references.engines.timing.best: the
least engine CPU time among those that ran clean, per step). Timing a configuration right
after itself would favour it (its code and data still in the caches) and a burst of load on
the machine would hit it alone; alternating, each configuration meets the others' traces and
every burst is spread over them.

A repeat steps the run's first :func:`window` steps: as many as its own run stepped in about
:data:`WINDOW_S` of CPU time (at least :data:`WINDOW_MIN_STEPS`; the whole run when it is
shorter, when its steps are chosen by an error control, or for bodies in contact), and its
timing is priced per step over the whole run (:func:`scaled`). The run's own timing covers
every step; a repeat takes its place only when it was cheaper per step, so a window whose
steps cost less than the run's later ones prices the run low. Measured on the default suite
(benchmarks/bench_timing_window.py --bias: a window's engine time per step over a whole
run's, the least of two each, alternating): within 10 % on 291 of the 302 runs a window
shortens, 0.74 at the lowest (dzhanibekov, the director's energy_momentum at dt 1 ms, whose
later steps cost more), 0.80-0.90 on three. ``WINDOW_S = math.inf`` repeats whole runs.

What is timed again (:func:`wanted`): every run that finished ok, up to :data:`TIMINGS`
timings in all (its own included), unless its own timing ran clean (:func:`ran_clean`: not
starved, and its stepping hardly waited for a CPU); a run whose every timing was starved up to
:data:`STARVED_TIMINGS`; in each round the starved runs first, then the cheapest. A repeat of a
run that ran clean measures what its own timing measured: on the default suite
(benchmarks/bench_timing_window.py --clean, one window each, load ~10), a repeat's engine time
per step over the run's own was 0.91-1.08 (5-95 %, median 1.00, 0.89-1.10 at the extremes)
for the 59 of 454 runs that ran clean, 0.93-1.11 (0.75-1.35) for the others. On a quiet
machine most runs run clean and are not timed again; on a busy one most are. The pass
stops at its budget: :data:`BUDGET_FACTOR` times the CPU time the scenario's runs spent
stepping, plus :data:`BUDGET_FLOOR_S`. A run whose every timing was starved keeps its best
and is starved (reports.gate.rule.starved), marked in the report and in ``compare``.

The rows are updated in the results store by the runner (reports.run.runner.run_suite),
which builds one :class:`TimingUnit` per scenario and hands it out once the scenario's runs
are all back (reports.run.parallel: a unit's ``needs``).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field

from reports.store.runs import RunSpec, timing_columns

#: a repeat steps about this much of its run's stepping CPU time (s): long enough for
#: thousands of timing slices' worth of steps (references.engines.timing.SLICE_S), short
#: enough that a repeat costs little beside the call that builds the engine's model
WINDOW_S = 0.005
#: ... and at least this many steps (the whole run when it has fewer)
WINDOW_MIN_STEPS = 100
#: every run is timed up to this many times in all (its own run included)
TIMINGS = 2
#: a run whose every timing was starved is timed up to this many times in all
STARVED_TIMINGS = 3
#: the pass spends at most this many times the CPU time its runs spent stepping, plus the
#: floor (s)
BUDGET_FACTOR = 0.5
BUDGET_FLOOR_S = 0.05
#: a repeat costs its window's stepping plus about this much (s: the model's construction)
CALL_OVERHEAD_S = 0.003


@dataclass
class TimingResult:
    """What a timing pass gives back: its ``scenario``, ``columns`` (run_id -> the row's new
    cost columns) and the ``seconds`` it took."""

    scenario: str
    columns: dict
    seconds: float


@dataclass
class TimingUnit:
    """The timing pass of one scenario: its ``specs``, and (filled by the runner as the rows
    arrive, before the unit is handed out) ``rows``: run_id -> the row's timing columns."""

    scenario: str
    specs: list[RunSpec]
    rows: dict = field(default_factory=dict)

    @functools.cached_property
    def needs(self) -> set[str]:
        """The runs that must be back before this unit is handed out (its specs are fixed
        when it is made; asked for each row that comes back)."""
        return {s.run_id for s in self.specs}


def timed(row) -> bool:
    """Whether a stored row is timed in the pass: a run that finished ok with a measured
    engine CPU time (the exact reference, a system of bodies' builder without a CPU
    timing, and failed runs are not)."""
    spread = row.get("engine_time_spread_s")
    return (
        row.get("status") in ("ok", "reference-inaccurate")
        and not row.get("reference")
        and spread is not None
        and isinstance(spread, float)
        and not math.isnan(spread)
    )


def _from_row(row):
    """The kept timing of a stored row as a Timing (its slowest repeats apart)."""
    from references.engines.timing import Timing

    return Timing(
        float(row["engine_time_s"]),
        float(row["engine_time_spread_s"]),
        float(row["cpu_time_s"]),
        float(row["wall_time_s"]),
        math.nan,
    )


def ran_clean(t) -> bool:
    """Whether the Timing ``t`` ran clean: not starved, and its stepping's CPU time at least
    :data:`references.engines.timing.CLEAN` of its wall time (the thread hardly waited for a
    CPU: its engine time is the engine's CPU time, however the machine was loaded)."""
    from references.engines.timing import CLEAN

    return not t.starved and t.wall > 0 and t.cpu >= CLEAN * t.wall


def wanted(timings: list) -> bool:
    """Whether a run with these ``timings`` (its own first) is timed once more: up to
    :data:`STARVED_TIMINGS` in all while every one was starved; not when its own timing ran
    clean (:func:`ran_clean`); else up to :data:`TIMINGS` in all."""
    if not any(not t.starved for t in timings):
        return len(timings) < STARVED_TIMINGS
    if len(timings) == 1 and ran_clean(timings[0]):
        return False
    return len(timings) < TIMINGS


def window(spec: RunSpec, nstep: int, cpu_s: float) -> int:
    """How many of its first steps a repeat of ``spec`` steps: what its own run of ``nstep``
    steps stepped in :data:`WINDOW_S` of its ``cpu_s`` CPU time, at least
    :data:`WINDOW_MIN_STEPS`, at most ``nstep``. The whole run for an error-controlled run
    (its steps are its error control's: a shorter horizon is another run) and for bodies in
    contact (a step's cost follows the contacts: Drake's SAP stepped sphere_backspin's first
    100 of 300 steps at 0.37x the whole run's cost per step, bench_timing_window.py)."""
    if spec.accuracy is not None or spec.scenario.kind == "contact":
        return nstep
    if not (cpu_s > 0 and math.isfinite(cpu_s)):
        return nstep
    steps = WINDOW_S * nstep / cpu_s
    return nstep if steps >= nstep else min(nstep, max(WINDOW_MIN_STEPS, math.ceil(steps)))


def scaled(t, factor: float):
    """The Timing ``t`` of a window priced over ``factor`` times as many steps."""
    from references.engines.timing import Timing

    return Timing(
        t.engine * factor, t.spread * factor, t.cpu * factor, t.wall * factor,
        t.engine_wall * factor,
    )  # fmt: skip


def time_unit(unit: TimingUnit) -> TimingResult:
    """Run the timing pass of ``unit`` here."""
    t0 = time.perf_counter()
    cols = _time(unit)
    return TimingResult(unit.scenario, cols, time.perf_counter() - t0)


def _time(unit: TimingUnit) -> dict[str, dict]:
    from references.engines import get_engine

    specs = [s for s in unit.specs if s.run_id in unit.rows and timed(unit.rows[s.run_id])]
    if not specs:
        return {}
    rows = unit.rows
    timings = {s.run_id: [_from_row(rows[s.run_id])] for s in specs}
    extra = {s.run_id: [] for s in specs}
    stepping = sum(float(rows[s.run_id]["cpu_time_s"]) for s in specs)
    budget = BUDGET_FACTOR * stepping + BUDGET_FLOOR_S
    spent, failed = 0.0, set()
    while True:  # each round times a run at most once; wanted() bounds each run's timings
        # the starved first, then the cheapest: the budget goes where a timing tells most
        order = sorted(
            specs,
            key=lambda s: (
                any(not t.starved for t in timings[s.run_id]),
                float(rows[s.run_id]["cpu_time_s"]),
            ),
        )
        ran = False
        for s in order:
            row = rows[s.run_id]
            nstep, cpu = int(row["nstep"]), float(row["cpu_time_s"])
            steps = window(s, nstep, cpu)
            cost = cpu * steps / nstep + CALL_OVERHEAD_S
            if s.run_id in failed or spent + cost > budget or not wanted(timings[s.run_id]):
                continue
            c0 = time.process_time()
            got = _run_again(get_engine(s.engine), s, nstep, steps)
            spent += time.process_time() - c0
            if got is None:  # it failed or took another number of steps: no timing
                failed.add(s.run_id)
                continue
            got = scaled(got, nstep / steps) if steps != nstep else got
            timings[s.run_id].append(got)
            extra[s.run_id].append(got)
            ran = True
        if not ran:
            break
    out = {}
    for s in specs:
        if not extra[s.run_id]:
            continue
        row = rows[s.run_id]
        cols = timing_columns(int(row["nstep"]), timings[s.run_id])
        for col in ("wall_time_max_s", "engine_time_max_s", "cpu_time_max_s"):
            cols[col] = max(cols[col], float(row.get(col, 0.0) or 0.0))
        cols["timing_repeats"] = int(row.get("timing_repeats") or 1) + len(extra[s.run_id])
        out[s.run_id] = cols
    return out


def _run_again(cls, spec: RunSpec, nstep: int, steps: int | None = None):
    """The timing of a fresh engine's run of ``spec`` (of ``nstep`` steps), or of its first
    ``steps`` steps, or None when it fails or takes another number of steps."""
    sc = spec.scenario
    horizon = spec.horizon
    if steps is not None and steps != nstep:  # a window: the run's first steps
        horizon, nstep = steps * spec.dt, steps
    if horizon != sc.t_end:
        sc = sc.replace(t_end=horizon)
    try:
        if sc.kind == "contact":  # bodies in contact: the engine's contact builder
            from references.engines.contact import run_contact

            out = run_contact(spec.engine, sc, spec.integrator, spec.dt, horizon, spec.saving)
        elif sc.kind == "system":  # a system of bodies: the engine's system builder
            from references.engines.system import run_system

            out = run_system(spec.engine, sc, spec.integrator, spec.dt, horizon, spec.saving)
        else:
            out = cls().run(
                sc, spec.integrator, spec.dt, horizon, spec.saving, accuracy=spec.accuracy
            )
    except Exception:  # noqa: BLE001 - a repeat that fails is no timing; the run stands
        return None
    return out.timing if out.nstep == nstep else None
