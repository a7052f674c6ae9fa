"""Every figure of a results folder, drawn once: which kinds a scenario gets (:data:`KINDS`,
each drawn for the scene kinds it declares, :data:`reports.report.canvas.FIGURES`), the drawing
of each scenario's figures (beside a worker process from :data:`PARALLEL_FROM` scenarios) and
the record of what each was made from (:data:`CACHE_FILE`: a scenario whose rows, series and
figure code are unchanged keeps its figures; :mod:`reports.report.figure_cache` reuses them
across folders).

The kinds: ``scenario`` (:mod:`reports.report.pictures`), ``errors``, ``rates``,
``convergence`` and ``work_precision`` (:mod:`reports.report.plots`), ``system``
(:mod:`reports.report.system_plots`, or :mod:`reports.report.contact` for a contact
scenario); the scorecard is drawn apart (:mod:`reports.report.scorecard_plot`).
"""

from __future__ import annotations

import importlib
from pathlib import Path

from reports.report import figure_cache
from reports.report.canvas import (
    BODIES_FIGURE,
    FIGURES,
    SeriesCache,
    Styles,
    _hash_code,
    _legend,
    _new_figure,
    _plot_rows,
    _plt,
    _save,
    draws,
    scene_kind,
)
from reports.report.labels import ENGINE_RANK, with_engine_order
from reports.report.pictures import scenario_plot_from_results
from reports.report.plots import convergence_plot, errors_plot, rates_plot, work_precision_plot
from reports.report.scorecard_plot import scorecard_figure_cached
from reports.store.atomic import write_text
from reports.store.provenance import read_provenance
from reports.store.results import records
from reports.store.runs import error_series_path, slug

#: the figures of one scenario, in report order (the scene kinds each draws:
#: :data:`reports.report.canvas.FIGURES`)
KINDS = tuple(FIGURES)


def scenario_plot(kind: str, df, cache, out: Path, scenario: str, styles: Styles, failed=None):
    """One figure of a scenario, or None. A figure that cannot be drawn (data a log axis
    cannot show, a library failure) is said on the standard error and left out (its kind
    appended to ``failed`` when given): a figure never costs the report, junit.xml or the
    results."""
    try:
        return _scenario_plot(kind, df, cache, out, scenario, styles)
    except Exception as exc:  # noqa: BLE001 - any failure of one figure
        import sys

        if failed is not None:
            failed.append(kind)
        _plt().close("all")
        print(
            f"director-bench: the {kind} figure of {scenario} was not drawn "
            f"({type(exc).__name__}: {exc}); the report goes on without it",
            file=sys.stderr,
        )
        return None


def _scenario_plot(kind: str, df, cache, out: Path, scenario: str, styles: Styles):
    if kind not in KINDS:
        raise ValueError(f"unknown plot kind {kind!r}; known: {', '.join(KINDS)}")
    if not draws(kind, df, scenario):
        return None  # a figure's code sees only the scenes it declares
    if kind == "scenario":
        return scenario_plot_from_results(df, cache, out, scenario)
    if kind == "errors":
        return errors_plot(df, cache, out, scenario, styles)
    if kind == "system":  # joints and invariants over time; a contact scene's distance
        module, name = BODIES_FIGURE[scene_kind(df, scenario)].split(":")
        draw = getattr(importlib.import_module(module), name)
        rows, h = _plot_rows(df, scenario)
        return draw(rows, h, cache, out, scenario, _plt(), _save, styles, _new_figure, _legend)
    if kind in ("joint_angles", "importers"):  # a robot model's, with its importer table
        from reports.report import model_plots
        from reports.run.importers import read_table

        table = read_table(cache.root, scenario)
        if table is None:
            return None
        if kind == "importers":
            return model_plots.importer_plot(table, out, _plt(), _save, _new_figure)
        rows, h = _plot_rows(df, scenario)
        return model_plots.joint_angle_plot(
            rows, h, cache, out, scenario, _plt(), _save, _new_figure, _legend
        )
    if kind == "rates":
        return rates_plot(df, cache, out, scenario, styles)
    if kind == "convergence":
        return convergence_plot(df, out, scenario, styles)
    return work_precision_plot(df, out, scenario, styles)


#: the file in the plots folder that remembers what each scenario's figures were made from
CACHE_FILE = ".made-from.json"


def _scenario_key(df, scenario: str, styles: Styles, root: Path) -> str:
    """A hash of everything a scenario's figures depend on: the code drawing them, the
    scenario's rows, their styles and the series files (size and modification time)."""
    import hashlib
    import json

    h = hashlib.sha256()
    _hash_code(h)
    sub = df[df["scenario"] == scenario].sort_values("run_id")
    h.update(sub.to_json(orient="values", double_precision=15).encode())
    for r in records(sub[["engine", "integrator", "family", "trajectory"]]):
        h.update(json.dumps(styles.of(r), default=str).encode())
        if r["trajectory"]:
            rel = error_series_path(Path(r["trajectory"]))  # relative: a folder named
            p = root / rel  # once relative and once absolute is the same folder
            st = p.stat() if p.exists() else None
            h.update(repr((rel.as_posix(), st and (st.st_size, st.st_mtime_ns))).encode())
    from reports.run.importers import FOLDER  # a robot model's importer table

    table = root / FOLDER / f"{slug(scenario)}.json"
    if table.is_file():
        h.update(table.read_bytes())
    return h.hexdigest()


def _draw_scenario(scenario, kinds, df, root, out) -> tuple[str, dict]:
    """The figures ``kinds`` of one scenario (a worker's task: styles and series are rebuilt
    here from the same inputs, so they are the ones a serial draw would use)."""
    styles, cache = Styles(df), SeriesCache(Path(root))
    return scenario, _figures_of(scenario, kinds, df, cache, Path(out), styles)


def _figures_of(scenario, kinds, df, cache, out: Path, styles) -> dict[str, str | None]:
    """Draw the figures ``kinds`` of ``scenario`` into ``out``: {kind: file name, or None
    when the scenario has no such figure}; a kind whose figure failed is left out."""
    failed: list[str] = []
    paths = {k: scenario_plot(k, df, cache, out, scenario, styles, failed) for k in kinds}
    return {k: None if p is None else p.name for k, p in paths.items() if k not in failed}


def _code_digest() -> str:
    """The digest of the code that decides what a figure shows (:func:`_hash_code`)."""
    import hashlib

    h = hashlib.sha256()
    _hash_code(h)
    return h.hexdigest()


#: draw in parallel processes from this many scenarios to draw on (a process costs ~1 s to
#: start, a scenario's figures ~1-2.5 s to draw)
PARALLEL_FROM = 3


def _cpus() -> int:
    """The cores this process may run on."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def _warm_matplotlib() -> None:
    """Import pyplot and load the fonts (a figure with text drawn once), so that processes
    forked from this one start with them."""
    plt = _plt()
    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, "µ 1e-3")
    fig.canvas.draw()
    plt.close(fig)


def _pool_context():
    """The multiprocessing context of the drawing workers: a fork of this process where that
    is safe (Linux, and no other thread of this interpreter: the caller pauses its own), so
    that a worker starts with the modules and data already here (a spawned one imports
    matplotlib, pandas and the suite again: ~2 s of CPU, as much as drawing two scenarios);
    elsewhere spawn."""
    import multiprocessing as mp
    import sys
    import threading

    safe = sys.platform.startswith("linux") and threading.active_count() == 1
    return mp.get_context("fork" if safe else "spawn")


def _draw_all(todo, df, cache, root, out, styles, bar, alongside=None):
    """Yield (scenario, figure file names) for the scenarios in ``todo`` (scenario, kind)
    pairs. With several scenarios and cores, this process draws alongside a pool of one
    worker process fewer than the cores: it first calls ``alongside`` (another figure, while
    the workers start), then both take the scenarios with the most runs first (the longest
    to draw, so that the last ones to finish are short), a worker being handed its next
    scenario as soon as it returns one. Without a pool ``alongside`` is called first too."""
    import itertools
    import threading
    from collections import deque

    kinds_of: dict[str, list[str]] = {}
    for sc, kind in todo:
        kinds_of.setdefault(sc, []).append(kind)
    scenarios = list(kinds_of)
    workers = min(_cpus() - 1, len(scenarios) - 1)
    if len(scenarios) < PARALLEL_FROM or workers < 1:
        if alongside is not None:
            alongside()
        for sc in scenarios:
            names = _figures_of(sc, kinds_of[sc], df, cache, out, styles)
            bar.update(len(kinds_of[sc]))
            yield sc, names
        return
    from concurrent.futures import ProcessPoolExecutor

    runs = df["scenario"].value_counts()
    pending = deque(sorted(scenarios, key=lambda sc: (-int(runs.get(sc, 0)), sc)))
    lock = threading.Lock()
    jobs = []  # a scenario leaves ``pending`` and its job enters ``jobs`` under one lock

    def take():
        with lock:
            return pending.popleft() if pending else None

    def hand_out(done=None):
        # called here and, as each job finishes, from the pool's thread: a job per worker;
        # none after a failed job (a broken pool: its error is raised where it is collected)
        with lock:
            if not pending or (done is not None and done.exception() is not None):
                return
            sc = pending.popleft()
            job = pool.submit(_draw_scenario, sc, kinds_of[sc], df, str(root), str(out))
            jobs.append(job)
        job.add_done_callback(hand_out)

    ctx = _pool_context()
    if ctx.get_start_method() == "fork":
        _warm_matplotlib()  # once here, not again in each forked worker
    with bar.paused():  # no thread of ours across a fork
        pool = ProcessPoolExecutor(workers, mp_context=ctx)
        for _ in range(workers):  # a forking pool starts its workers at the first job
            hand_out()
    with pool:
        try:
            if alongside is not None:
                alongside()
            returned = 0  # the workers' scenarios yielded so far, in the order handed out
            while (sc := take()) is not None:
                names = _figures_of(sc, kinds_of[sc], df, cache, out, styles)
                bar.update(len(kinds_of[sc]))
                yield sc, names
                with lock:  # those returned, up to the first still drawing
                    ready = list(itertools.takewhile(lambda j: j.done(), jobs[returned:]))
                for job in ready:
                    returned += 1
                    sc, names = job.result()
                    bar.update(len(kinds_of[sc]))
                    yield sc, names
            # ``pending`` is empty: no job is handed out any more, ``jobs`` is complete
            for job in jobs[returned:]:
                sc, names = job.result()
                bar.update(len(kinds_of[sc]))
                yield sc, names
        finally:  # on an error, hand out nothing more while the pool shuts down
            with lock:
                pending.clear()


def all_plots(
    df,
    root: str | Path,
    out: str | Path | None = None,
    progress: bool = False,
    alongside=None,
    reuse_figures: bool = True,
) -> dict[str, list[Path]]:
    """Every figure of every scenario (:data:`KINDS`); returns {scenario: [png paths]}.

    A scenario whose figures exist and were made from the same inputs (rows, series files,
    styles and this code: :data:`CACHE_FILE` in the plots folder) is not drawn again, so a
    report regenerated from an unchanged store draws nothing. ``progress``: the progress of
    the figures (:class:`reports.run.progress.Progress`; nothing when none is drawn).
    ``alongside``: a callable this process calls while worker processes start drawing
    (:func:`report_figures`: the scorecard picture); called once, also when nothing else is
    drawn (not for an empty table). ``reuse_figures``: copy a figure whose inputs are those
    of one drawn before in any folder from the user's cache (:mod:`figure_cache`)."""
    import json

    from reports.run.progress import Progress

    root = Path(root)
    out = Path(out) if out is not None else root / "plots"
    out.mkdir(parents=True, exist_ok=True)
    if df.empty:
        return {}
    df = _in_folder_order(df, root)
    styles = Styles(df)
    cache = SeriesCache(root)
    try:
        made_from = json.loads((out / CACHE_FILE).read_text())
    except (OSError, ValueError):
        made_from = {}
    made: dict[str, list[Path]] = {}
    todo = []
    names: dict[str, dict[str, str]] = {}  # scenario -> {kind: file name}
    reuse: dict[tuple[str, str], str] = {}  # (scenario, kind) -> its key in the user's cache
    code = _code_digest() if reuse_figures else ""
    for scenario in sorted(df["scenario"].unique()):
        key = _scenario_key(df, scenario, styles, root)
        old = made_from.get(scenario, {})
        files = [out / f for f in old.get("files", [])]
        if old.get("key") == key and all(
            f.exists() and f.with_suffix(".json").exists() for f in files
        ):
            made[scenario] = [out / f for f in old["files"]]
            continue
        made_from[scenario] = {"key": key, "files": []}
        names[scenario] = {}
        digest = None  # of the scenario's inputs, once (figure_cache.inputs)
        for kind in KINDS:
            if reuse_figures and kind in figure_cache.REUSED:
                if digest is None:
                    sub = df[df["scenario"] == scenario]
                    digest = figure_cache.inputs(scenario, sub, styles, root)
                k = figure_cache.key(kind, digest, code)
                got = figure_cache.fetch(k, out)
                if got is not None:  # "" : the scenario has no such figure
                    names[scenario][kind] = got or None
                    continue
                reuse[scenario, kind] = k
            todo.append((scenario, kind))
    bar = Progress(len(todo), desc="plots", unit="figure", disable=not progress)
    for scenario, drawn in _draw_all(todo, df, cache, root, out, styles, bar, alongside):
        names[scenario].update(drawn)
        for kind, name in drawn.items():
            if (scenario, kind) in reuse:
                figure_cache.put(reuse[scenario, kind], None if name is None else out / name)
    bar.close()
    if reuse:
        figure_cache.prune()
    for scenario, by_kind in names.items():
        ordered = [by_kind[k] for k in KINDS if by_kind.get(k)]
        made[scenario] = [out / n for n in ordered]
        made_from[scenario]["files"] = ordered
    made = {sc: made[sc] for sc in sorted(made)}
    write_text(out / CACHE_FILE, json.dumps(made_from, indent=1))
    return made


def _in_folder_order(df, root):
    """``df`` with its engines' places in the folder's order (:data:`labels.ENGINE_RANK`,
    from its provenance.json), unless it has them already (:func:`build_report` adds them)."""
    if ENGINE_RANK in df:
        return df
    return with_engine_order(df, read_provenance(Path(root)))


def report_figures(df, root: str | Path, progress: bool = False):
    """The report's figures: every scenario's (:func:`all_plots`, {scenario: [png paths]})
    and the scorecard picture's paths (:func:`scorecard_figure_cached`), the latter drawn in
    this process while the worker processes start and draw scenarios. ({}, []) for an empty
    table."""
    if df.empty:
        return {}, []
    df = _in_folder_order(df, root)
    card: list[Path] = []

    def scorecard():
        card.extend(scorecard_figure_cached(df, root))

    return all_plots(df, root, progress=progress, alongside=scorecard), card
