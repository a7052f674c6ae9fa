"""The scenario runner: scenarios x engines x integrators x dt -> one row per run.

Data flow: a :class:`~reports.store.runs.RunSpec` names one run; :func:`execute` runs it
(engine adapter -> trajectory in the suite's schema -> metrics against the reference ->
status and verdict) and returns its row, never raising for a failure of the run itself: a
missing engine, a diverged run, an unsupported scenario or a fault of the suite become a row
with a ``status`` and a ``message``. :func:`run_suite` executes many specs and commits each
row to the output folder's results store as soon as it finishes (reports.store.results), so an
interruption loses only the runs in flight, and a rerun skips what is done.
"""

from __future__ import annotations

import collections
import contextlib
import functools
import importlib
import shutil
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from references import cache as reference_cache
from reports.run.body import is_reference
from reports.run.files import kept_less
from reports.run.plan import UNAVAILABLE, offered
from reports.run.system import SHARED, shared_key
from reports.run.timing import BUDGET_FACTOR, TimingResult, TimingUnit, time_unit
from reports.store.exports import export
from reports.store.results import Store, StoreUnwritable, read_results
from reports.store.runs import RunSpec, blank_row, finish_time, trajectory_path

# -- one run -----------------------------------------------------------------------------------

#: the stepper of each scene kind (scenarios.SCENE_KINDS, declared by the scenario as
#: ``sc.kind``), as "module:function": it runs one spec of that kind and fills its row
#: (timings, metrics, status and verdict), with the signature of
#: :func:`reports.run.body.run_body_spec`, and raises for a failure, which :func:`execute`
#: makes the row's status
STEPPERS = {
    "body": "reports.run.body:run_body_spec",
    "system": "reports.run.system:run_system_spec",
    "contact": "reports.run.contact:run_contact_spec",
}


def stepper(kind: str) -> Callable:
    """The stepper of the scene kind ``kind`` (:data:`STEPPERS`), imported on first use."""
    module, name = STEPPERS[kind].split(":")
    return getattr(importlib.import_module(module), name)


def execute(spec: RunSpec, out: Path | None = None, fmt: str = "parquet", progress=None) -> dict:
    """Run one spec and return its result row (see ``reports.store.runs.RESULT_COLUMNS``).

    With ``spec.segment`` the pointwise metrics are streamed over every step
    (:mod:`reports.metrics.streaming`); otherwise they are taken at the saved samples. Writes the
    trajectory and its per-sample series under ``out/trajectories`` when ``out`` is given.
    Never raises for a failure of the run: the row says what happened.
    """
    from references.engines import EngineError

    started = time.perf_counter()
    row = blank_row(spec)
    try:
        integ, sc = _prepare(row, spec)
        stepper(sc.kind)(spec, row, integ, sc, out, fmt, progress)
    except EngineError as exc:
        row["status"] = exc.status
        row["message"] = failure_message(str(exc), "", exc, spec, out)
    except StoreUnwritable:
        raise  # the output folder cannot take the results: the work stops, nothing is lost
    except Exception as exc:  # noqa: BLE001 - a run's failure is a row, never a crash
        row["status"] = "error"
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" (at {Path(tb.filename).name}:{tb.lineno})"
        row["message"] = failure_message(f"{type(exc).__name__}: {exc}", where, exc, spec, out)
    row["finished_at"] = finish_time()
    # the run's seconds in its process, for the progress display's estimate (not a column:
    # the store keeps only RESULT_COLUMNS)
    row[RUN_SECONDS] = time.perf_counter() - started
    row[REFERENCES] = reference_cache.drain()
    return row


#: the key of a row (not a column) holding the seconds :func:`execute` took
RUN_SECONDS = "_run_seconds"
#: the key of a row (not a column) holding what the reference cache did for it in its
#: process (references.cache.drain: keys read, keys computed, lines for the run's log)
REFERENCES = "_references"


def _tell_references(kept: dict, rows: list) -> None:
    """Add what the reference cache did for ``rows`` to ``kept`` ({"read", "computed":
    sets of keys, "lines": list})."""
    for row in rows:
        got = row.get(REFERENCES) or {}
        kept["read"].update(got.get("read", ()))
        kept["computed"].update(got.get("computed", ()))
        kept["lines"] += got.get("lines", ())


def _say_references(kept: dict, summary: bool) -> None:
    """Print (stderr) each line of ``kept`` (an entry of the reference cache that could not
    be read) and, with ``summary``, one line with the counts."""
    import sys

    for line in kept["lines"]:
        print(f"director-bench: {line}", file=sys.stderr)
    if summary and (kept["read"] or kept["computed"]):
        print(
            f"director-bench: references: {len(kept['read'])} read from the reference cache "
            f"{reference_cache.folder()}, {len(kept['computed'])} computed and kept there "
            f"(--no-reference-cache or {reference_cache.SWITCH_ENV}=off computes every one)",
            file=sys.stderr,
        )


#: longest failure message a result row holds whole (characters; the suite's own messages
#: stay below 400, measured on the default suite: at most 323)
MESSAGE_MAX = 600


def failure_message(text: str, where: str, exc: BaseException, spec: RunSpec, out) -> str:
    """The message of a failed run's row: ``text + where`` when ``text`` has at most
    :data:`MESSAGE_MAX` characters. A longer one (a compiler's dump runs to thousands of
    characters) keeps its first line, cut to that length, and ``where``, and names the file of
    the output folder (``logs/errors/<scenario>/<run>.error.txt``) that holds the whole text
    and the traceback; without an output folder, or when that file cannot be written, the
    row keeps the whole text."""
    if len(text) <= MESSAGE_MAX:
        return text + where
    if out is not None:
        rel = Path("logs", "errors", *trajectory_path(spec, "error.txt").parts[1:])
        full = "".join(traceback.format_exception(exc))
        try:
            (Path(out) / rel).parent.mkdir(parents=True, exist_ok=True)
            (Path(out) / rel).write_text(f"{text}{where}\n\n{full}", encoding="utf-8")
        except OSError:
            return text + where
        first = text.strip().splitlines()[0]
        cut = first if len(first) <= MESSAGE_MAX else first[: MESSAGE_MAX - 3] + "..."
        return f"{cut}{where} [{len(text)} characters; the whole message: {rel.as_posix()}]"
    return text + where


def _prepare(row: dict, spec: RunSpec):
    """(integrator, scenario at the run's horizon) of ``spec``, with the row's
    engine version, integrator facts and, for a horizon other than the file's, its scales.

    The version is the engine's own (``version()``, which imports it): a spec planned under
    another (the installed package's metadata, :func:`plan`) is refused with both, since its
    run_id and row name a version that does not run here."""
    from references.engines import EngineError, get_engine

    cls = get_engine(spec.engine)
    if not row["engine_version"]:
        row["engine_version"] = _running_version(spec.engine)
    integ = offered(spec.engine, spec.scenario).get(spec.integrator) or cls.integrator(
        spec.integrator
    )
    row.update(family=integ.family, order=integ.order, suite_integrated=integ.suite_integrated)
    row["reference"] = float(cls.is_reference)
    if row["engine_version"] != UNAVAILABLE:  # else the run says why (EngineUnavailable)
        running = _running_version(spec.engine)
        if row["engine_version"] != running:
            raise EngineError(
                f"engine {spec.engine!r} reports version {running!r} here, but the run was "
                f"planned for {row['engine_version']!r} (its installed package's metadata, "
                "read where the runs were planned): the package imported is not the one "
                "installed (a source build on the path?), or another version runs on this "
                "worker; install one version of the engine"
            )
    sc = spec.scenario
    if spec.t_end is not None and spec.horizon != sc.t_end:
        sc = sc.replace(t_end=spec.horizon)
        # the scales of the horizon run (a free fall's energy in play grows with it)
        row.update(energy_scale=sc.energy_scale, momentum_scale=sc.momentum_scale)
    return integ, sc


@functools.cache
def _running_version(engine: str) -> str:
    """The version of ``engine`` in this process (its ``version()``, read once per process:
    some read package metadata, milliseconds a call); raises EngineUnavailable if it does not
    import (not kept: the next run tries again)."""
    from references.engines import get_engine

    return get_engine(engine).version()


# -- many runs ---------------------------------------------------------------------------------


def run_suite(
    specs: Iterable[RunSpec],
    out: str | Path,
    redo: bool = False,
    fmt: str = "parquet",
    progress: bool = True,
    mapper: Callable | None = None,
    extra: Iterable[Callable] = (),
) -> tuple:
    """Execute ``specs``, committing each row to ``out``'s results store as it finishes;
    returns (the current results DataFrame, number of runs executed).

    ``extra``: other work of the command, each a picklable callable taking no argument (e.g.
    reports.run.importers.TablesUnit), handed to the mapper after the runs, so that a worker
    does it while the last runs finish (in this process with the serial mapper); what it
    returns is not kept, what it raises stops the work as a run's fault of the suite would.

    Runs whose identity is already in the store are skipped unless ``redo`` (except those
    whose status is in ``RETRY_STATUSES``). ``mapper`` (a :class:`reports.run.parallel.Mapper`)
    may run specs elsewhere (a process pool, a Dask cluster) and yields rows as they finish;
    the default runs them here in order. ``results.csv`` and ``results.parquet`` are exported
    at the end (also after an interruption).
    """
    out = Path(out)
    specs = list(specs)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise StoreUnwritable(f"{out}: cannot create the output folder ({exc})") from None
    with Store(out, create=True) as store:
        done = set() if redo else store.done_ids()
        if any(s.keep != "none" for s in specs) and done:
            # a run kept with less than it is asked to keep now (reports.run.files) runs again
            stored = {r["run_id"]: r for r in store.rows()}
            done -= {s.run_id for s in specs if kept_less(stored.get(s.run_id, {}), s.keep)}
        todo = [s for s in specs if s.run_id not in done]
        # the runs asked for again are this invocation's too: newest in the store's order,
        # which decides what the tables show (reports.store.results.current)
        store.touch(s.run_id for s in specs if s.run_id in done)
        n_run = 0
        shutil.rmtree(out / SHARED, ignore_errors=True)  # an interrupted run's (reports.run.system)
        if mapper is None:
            from reports.run.parallel import serial

            mapper = serial(out)
        units = bundles(todo)
        passes = {}  # scenario -> its timing pass (a mapper that lets a unit wait for others)
        if mapper.waits:
            units, passes = with_timing_passes(units)
        units += [Extra(job) for job in extra]
        bar = _bar(todo, passes) if progress and todo else None
        if mapper.in_process:
            # in this process: a long run shows its own progress in the bar

            def fn(unit):
                if isinstance(unit, TimingUnit | Extra):
                    return execute_unit(unit)
                return [execute(s, out, fmt, progress=_inner(bar, s)) for s in unit]
        else:
            fn = functools.partial(execute_unit, out=out, fmt=fmt)
        refs = {"read": set(), "computed": set(), "lines": []}  # the reference cache's
        try:
            if passes:
                rows_of = mapper(fn, units, unit_keys, _needs, _provides)
            else:
                rows_of = mapper(fn, units, keys=unit_keys)
            spec_of = {s.run_id: s for s in todo}
            stored = {}  # run_id -> its row, until its scenario's timing pass is back
            for rows in rows_of:
                if isinstance(rows, Extra):  # other work of the command, done
                    continue
                if isinstance(rows, TimingResult):  # a scenario's timing pass is back
                    for run_id, cols in rows.columns.items():
                        store.put({**stored.pop(run_id), **cols})
                    if bar is not None:
                        key = ("timing", rows.scenario)
                        bar.update(0, item=key, seconds=rows.seconds, label="timing")
                    continue
                _tell_references(refs, rows)
                for row in rows:
                    store.put(row)
                    n_run += 1
                    unit = passes.get(row["scenario"])
                    if unit is not None and row["run_id"] in unit.needs:
                        stored[row["run_id"]] = row
                        unit.rows[row["run_id"]] = row  # what the pass sees when handed out
                    if bar is not None:
                        label = f"{row['scenario']}/{row['engine']}/{row['integrator']}"
                        spec = spec_of.get(row["run_id"])
                        bar.update(
                            1,
                            key=tuple(warm_ups(spec)) if spec else None,
                            label=label,
                            item=row["run_id"],
                            seconds=row.get(RUN_SECONDS),
                            outcome=row["verdict"] or row["status"],
                        )
        finally:
            if bar is not None:
                bar.close()
            if refs["read"] or refs["computed"] or refs["lines"]:
                _say_references(refs, progress)
            shutil.rmtree(out / SHARED, ignore_errors=True)
            df = _export_quietly(out)
    return df, n_run


def execute_bundle(specs, out: Path | None = None, fmt: str = "parquet") -> list[dict]:
    """The rows of a bundle of specs executed one after another (see :func:`bundles`)."""
    return [execute(s, out, fmt) for s in specs]


@dataclass
class Extra:
    """Other work of a command handed out with its runs (:func:`run_suite` ``extra``): a
    picklable callable ``job``; the unit comes back (without its job) when done."""

    job: Callable | None


def execute_unit(unit, out: Path | None = None, fmt: str = "parquet"):
    """A unit of work of :func:`run_suite`: a bundle's rows, a timing pass's new cost
    columns ({run_id: columns}, :func:`reports.run.timing.time_unit`), or an :class:`Extra`
    done (given back empty)."""
    if isinstance(unit, TimingUnit):
        return time_unit(unit)
    if isinstance(unit, Extra):
        unit.job()
        return Extra(None)
    return execute_bundle(unit, out, fmt)


def with_timing_passes(units: list) -> tuple[list, dict]:
    """(``units`` with the timing pass of each scenario right after the last unit holding
    one of its runs, {scenario: its :class:`TimingUnit`}); the exact reference's runs are
    not timed again."""
    last, specs = {}, {}
    for i, unit in enumerate(units):
        for s in unit:
            if is_reference(s.engine):
                continue
            last[s.scenario.name] = i
            specs.setdefault(s.scenario.name, []).append(s)
    passes = {name: TimingUnit(name, specs[name]) for name in specs}
    after: dict[int, list] = {}
    for name, i in last.items():
        after.setdefault(i, []).append(passes[name])
    out = []
    for i, unit in enumerate(units):
        out += [unit, *after.get(i, ())]
    return out, passes


def _needs(unit) -> set[str]:
    return unit.needs if isinstance(unit, TimingUnit) else set()


def _provides(unit) -> set[str]:
    return set() if isinstance(unit, TimingUnit | Extra) else {s.run_id for s in unit}


@functools.cache
def warm_up(engine: str, integrator: str, kind: str = "body") -> tuple[str, str] | None:
    """(key, what it compiles) of the warm-up that the first run of this configuration in a
    process goes through, or None: the engine's own (``EngineBase.warm_up``; one per
    integrator when the engine bundles its runs; for a system of bodies the engine's
    ``system_warm_up``, for a contact scene its ``contact_warm_up``, when it declares one,
    under a key of its own) or the suite's compiled RKMK4. ``kind``: the scene kind
    (scenarios.SCENE_KINDS)."""
    from references.engines import EngineError, get_engine
    from references.engines.liegroup import RKMK4_WARM_UP

    try:
        cls = get_engine(engine)
        if cls.warm_up:
            if cls.bundle_runs:
                return f"{engine}/{integrator}", f"{cls.warm_up} for {engine} {integrator}"
            if kind != "body":
                what = cls.contact_warm_up if kind == "contact" else cls.system_warm_up
                return (f"{engine}/{kind}", what) if what else None
            return engine, cls.warm_up
        if cls.integrator(integrator).stepping == "rkmk4":
            return "rkmk4", RKMK4_WARM_UP
    except EngineError:
        pass  # an engine that does not load runs nothing to warm up: its rows say why
    return None


#: the warm-up of every run of a system of bodies: its reference (and the invariants of
#: every engine's states) is the reduced-coordinate multibody code compiled by numba
#: (references.exact.multibody)
SYSTEM_REFERENCE_WARM_UP = ("multibody", "the multibody reference (numba)")


def warm_ups(spec: RunSpec) -> dict[str, str]:
    """{key: what it compiles} of every warm-up the first run of ``spec`` in a process goes
    through (:func:`warm_up`, and for a system of bodies its reference's)."""
    kind = spec.scenario.kind
    out = dict([w]) if (w := warm_up(spec.engine, spec.integrator, kind)) else {}
    if kind == "system":  # a contact scene's reference is a closed form: no numba
        out.setdefault(*SYSTEM_REFERENCE_WARM_UP)
    return out


def unit_warm_ups(unit: list[RunSpec]) -> set[str]:
    """The warm-up keys of a unit of work (a bundle of specs), for the process pool's gate
    (reports.run.parallel.process_pool). A bundle of several runs counts only its engine's
    own warm-ups: it would hold a shared one (a system of bodies' reference) for the whole
    bundle; its systems run last (:func:`bundles`), when that one is cached."""
    if isinstance(unit, TimingUnit | Extra):  # a pass follows its scenario's runs
        return set()
    if len(unit) > 1:
        return {k for s in unit if (w := warm_up(s.engine, s.integrator)) for k in (w[0],)}
    return {k for s in unit for k in warm_ups(s)}


def unit_keys(unit) -> set[str]:
    """The keys the process pool's gate holds a unit of work back by (reports.run.parallel):
    its warm-ups (:func:`unit_warm_ups`) and the system references its runs share with
    other units (:func:`reports.run.system.shared_key`: one unit computes each, the others
    wait for it, while the workers take other units, and read it)."""
    if isinstance(unit, TimingUnit | Extra):
        return set()
    return unit_warm_ups(unit) | {k for s in unit if (k := shared_key(s)) is not None}


def _bundled(engine: str) -> bool:
    """Whether the engine's runs go in bundles (``EngineBase.bundle_runs``)."""
    from references.engines import EngineError, get_engine

    try:
        return get_engine(engine).bundle_runs
    except EngineError:
        return False


def bundles(specs) -> list[list[RunSpec]]:
    """The specs as units of work for a mapper: one spec each, except that the runs of an
    engine whose runs share a warm-up (``bundle_runs``, e.g. MJX's compilation) go together,
    one bundle per integrator, so that each compiles once, in one worker.

    Within a bundle, single bodies first, then systems of bodies. Order: first the bundles
    that start a warm-up (:func:`unit_warm_ups`), those whose
    compilation holds back the most runs first (a system of bodies' reference and kernels,
    then the director's, the RKMK4 stages, MJX's bundles), so that the longest chains of
    compilation start at once (the process pool hands out no second run of a key before its
    first has finished, reports.run.parallel); then the longest bundles, so that the single
    runs fill the other workers meanwhile."""
    out, grouped = [], {}
    for s in specs:
        if _bundled(s.engine):
            key = (s.engine, s.integrator)
            if key not in grouped:
                grouped[key] = []
                out.append(grouped[key])
            grouped[key].append(s)
        else:
            out.append([s])
    for b in grouped.values():  # a bundle's systems of bodies last (see unit_warm_ups)
        b.sort(key=lambda s: s.scenario.kind != "body")
    out.sort(key=len, reverse=True)
    firsts: dict[str, list[RunSpec]] = {}  # warm-up key -> the first bundle going through it
    for b in out:
        for key in sorted(unit_warm_ups(b)):
            firsts.setdefault(key, b)
    leaders = list({id(b): b for b in firsts.values()}.values())  # a bundle once
    held = collections.Counter(k for b in out for s in b for k in warm_ups(s))
    leaders.sort(key=lambda b: -max(held[k] for k in unit_warm_ups(b)))
    lead = {id(b) for b in leaders}
    rest = [b for b in out if id(b) not in lead]
    # then one unit of each configuration not yet started, its cheapest: the progress
    # display prices the runs left by their configuration's measured rate, known early so
    probes: dict[tuple, list[RunSpec]] = {}
    seen = {_config(b[0]) for b in leaders}
    for b in rest:
        key = _config(b[0])
        if key not in seen and (key not in probes or _steps(b) < _steps(probes[key])):
            probes[key] = b
    probe = {id(b) for b in probes.values()}
    return leaders + list(probes.values()) + [b for b in rest if id(b) not in probe]


def _config(spec: RunSpec) -> tuple:
    """(engine, integrator, scene kind): runs of one configuration cost alike per step."""
    return spec.engine, spec.integrator, spec.scenario.kind


def _steps(unit: list[RunSpec]) -> float:
    """The steps of a unit's runs (bodies times steps for a system of bodies)."""
    return sum(_size(s) for s in unit)


def _size(s: RunSpec) -> float:
    """A run's size for the progress display's estimate: its steps, times its bodies for a
    system of bodies."""
    steps = max(s.horizon / s.dt, 1.0) if s.dt > 0 else 1.0
    return steps * s.scenario.n_bodies


def _export_quietly(out: Path):
    """Export the store (also after an interruption); an export that cannot be written
    (disk full) must not hide the error that stopped the run, and loses nothing: the store
    holds every row and the next run or report exports again."""
    df = read_results(out)
    with contextlib.suppress(OSError):
        export(out, df)
    return df


def _bar(todo: list[RunSpec], passes=None):
    """The progress display of ``todo`` (reports.run.progress), told which warm-ups its first
    runs go through (those of bundled runs apart: their rows arrive with the bundle's end)
    and the timing ``passes`` ({scenario: TimingUnit}) that end their scenarios."""
    from reports.run.progress import Item, Progress

    warming, bundled = {}, {}
    for s in todo:
        for key, what in warm_ups(s).items():
            bundle_key = _bundled(s.engine) and key.startswith(f"{s.engine}/")
            (bundled if bundle_key else warming)[key] = what
    items = progress_items(todo)
    for name, unit in (passes or {}).items():
        # a pass spends at most BUDGET_FACTOR times its runs' stepping (reports.run.timing)
        items["timing", name] = Item(
            name, ("timing",), sum(_size(s) for s in unit.specs), share=BUDGET_FACTOR
        )
    return Progress(len(todo), warming=warming, bundled=bundled, items=items)


def progress_items(todo: list[RunSpec]) -> dict:
    """{run_id: :class:`reports.run.progress.Item`} of ``todo``: grouped by scenario, priced
    per configuration (:func:`_config`) by their size (:func:`_size`)."""
    from reports.run.progress import Item

    return {s.run_id: Item(s.scenario.name, _config(s), _size(s)) for s in todo}


def _inner(bar, spec):
    """A per-run progress callback that shows the fraction of a long run in the bar."""
    if bar is None:
        return None
    label = f"{spec.scenario.name}/{spec.engine}/{spec.integrator}"

    def show(frac: float) -> None:
        bar.set_postfix_str(f"{label} {100 * frac:.0f}%", refresh=True)

    return show
