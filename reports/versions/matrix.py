"""The version matrix: the suite run in one environment per engine version, one store.

Each environment runs ``python -m reports.cli run`` of this checkout (``reports.versions.envs``
puts the checkout on its path) into a folder of its own, ``OUT/versions/<engine>-<label>``,
whose store skips the runs it holds (so an interrupted matrix resumes where it stopped); the
rows are then copied into ``OUT/results.sqlite`` with their trajectory paths made relative to
``OUT``. A run's identity includes the engine version, so the rows of all versions coexist in
the one store. A version whose environment could not be made gets one ``unavailable`` row per
configuration it would have run, with the reason; a rerun tries it again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from reports.versions.envs import Env, checkout_env, make_env
from reports.versions.requirements import Target, parse_requirements

#: longest one environment's runs may take
RUN_TIMEOUT_S = 6 * 3600


@dataclass
class EnvRun:
    """What the runs in one environment gave."""

    env: Env
    folder: Path
    rows: int = 0
    seconds: float = 0.0
    returncode: int | None = None
    error: str = ""
    crashed: int = 0  # runs whose own process ended without a result (error rows)
    skipped: bool = False  # every run was in the store already: nothing started


@dataclass
class MatrixResult:
    out: Path
    runs: list = field(default_factory=list)  # EnvRun, in the order of the targets
    rows: int = 0
    seconds: float = 0.0

    @property
    def failed(self) -> list[EnvRun]:
        return [r for r in self.runs if not r.env.ok or r.error]


def sub_folder(out: Path, target: Target) -> Path:
    return out / "versions" / f"{target.engine}-{target.label}"


def _run_args(scenarios, target, folder, opts: dict) -> list[str]:
    args = ["-m", "reports.cli", "run", *[str(s.path) for s in scenarios]]
    args += ["--engines", target.engine, "--out", str(folder), "--no-report", "--quiet"]
    args += ["--trajectories", "full"]  # the versions figures read each run's energy
    if opts.get("integrators"):
        args += ["--integrators", ",".join(opts["integrators"])]
    if opts.get("dts"):
        args += ["--dt", ",".join(repr(float(h)) for h in opts["dts"])]
    if opts.get("t_end") is not None:
        args += ["--t-end", repr(float(opts["t_end"]))]
    if opts.get("accuracies"):
        args += ["--accuracy", ",".join(repr(float(a)) for a in opts["accuracies"])]
    if not opts.get("sweep", True):
        args.append("--no-sweep")
    if opts.get("full", True):
        args.append("--full")
    if opts.get("redo"):
        args.append("--redo")
    args += ["--jobs", str(opts.get("jobs") or 1)]
    return args


def _relabel(row: dict, target: Target) -> dict:
    """A row of a sub-folder as the matrix store holds it: the trajectory path relative to the
    matrix folder and, for a wheel, the version labelled with the wheel's digest (a developer's
    build may report the same version as a release; the identity then differs as well)."""
    row = dict(row)
    if row.get("trajectory"):
        row["trajectory"] = str(
            Path("versions") / f"{target.engine}-{target.label}" / row["trajectory"]
        )
    if target.wheel:
        local = target.label.split("+", 1)[1]
        if "+" not in row["engine_version"]:
            row["engine_version"] = f"{row['engine_version']}+{local}"
        row["run_id"] = hashlib.sha256(f"{row['run_id']}{local}".encode()).hexdigest()[:20]
    return row


def _unavailable_rows(scenarios, target: Target, reason: str, opts: dict) -> list[dict]:
    from reports.store.runs import blank_row, finish_time

    specs = _specs(scenarios, target, opts, target.label)
    rows = []
    for spec in specs:
        row = blank_row(spec)
        row.update(
            status="unavailable",
            message=f"{target.source}: {target.engine} {target.label}: {reason}",
            finished_at=finish_time(),
        )
        rows.append(row)
    return rows


def _run_in_env(env: Env, scenarios, opts: dict, out: Path) -> EnvRun:
    folder = sub_folder(out, env.target)
    res = EnvRun(env, folder)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    log = folder / "run.log"
    cmd = [str(env.python), *_run_args(scenarios, env.target, folder, opts)]
    try:
        with log.open("w") as fh:
            p = subprocess.run(
                cmd, stdout=fh, stderr=subprocess.STDOUT, cwd=folder, timeout=RUN_TIMEOUT_S,
                check=False, env=checkout_env(),
            )  # fmt: skip
        res.returncode = p.returncode
        if p.returncode not in (0,):
            tail = log.read_text(errors="replace").strip().splitlines()[-3:]
            res.error = f"the run exited {p.returncode}: {' | '.join(tail)} (log: {log})"
    except subprocess.TimeoutExpired:
        res.error = f"the runs took longer than {RUN_TIMEOUT_S} s and were stopped (log: {log})"
    res.seconds = time.perf_counter() - t0
    return res


def _specs(scenarios, target: Target, opts: dict, engine_version: str) -> list:
    """The runs one environment is asked for, with the identities they have there."""
    from reports.run.plan import plan

    specs = plan(
        scenarios, [target.engine], opts.get("integrators"), opts.get("dts"), opts.get("t_end"),
        opts.get("sweep", True), None, None, opts.get("accuracies"), 10**12, opts.get("full", True),
    )  # fmt: skip
    return [dataclasses.replace(s, engine_version=engine_version) for s in specs]


def _missing(env: Env, scenarios, opts: dict, out: Path) -> list:
    """The runs of an environment its folder's store does not hold (yet)."""
    from reports.store.results import Store

    folder = sub_folder(out, env.target)
    if not (folder / "results.sqlite").exists():
        return _specs(scenarios, env.target, opts, env.engine_version)
    with Store(folder) as st:
        done = st.done_ids()
    return [s for s in _specs(scenarios, env.target, opts, env.engine_version)
            if s.run_id not in done]  # fmt: skip


def _launch(env: Env, specs: list, folder: Path, opts: dict, log: Path):
    """Run exactly ``specs`` in the environment (:mod:`reports.versions.worker`); returns the
    process's exit code (or why it was stopped)."""
    import json

    items = [
        {"scenario": str(s.scenario.path), "engine": s.engine, "integrator": s.integrator,
         "dt": s.dt, "accuracy": s.accuracy, "t_end": s.t_end, "save_every": s.save_every,
         "segment": s.segment}
        for s in specs
    ]  # fmt: skip
    spec_file = folder / "isolated-specs.json"
    spec_file.write_text(json.dumps(items))
    with log.open("a") as fh:
        names = ", ".join(f"{s.scenario.name} {s.integrator} dt={s.dt:g}" for s in specs[:3])
        fh.write(f"\n== {len(specs)} run(s): {names}{' ...' if len(specs) > 3 else ''}\n")
        fh.flush()
        try:
            p = subprocess.run(
                [str(env.python), "-m", "reports.versions.worker", str(folder), str(spec_file)],
                stdout=fh, stderr=subprocess.STDOUT, cwd=folder, timeout=RUN_TIMEOUT_S,
                check=False, env=checkout_env(),
            )  # fmt: skip
            return p.returncode
        except subprocess.TimeoutExpired:
            return f"timeout after {RUN_TIMEOUT_S} s"


def _isolate(env: Env, scenarios, opts: dict, run: EnvRun) -> int:
    """After an environment's run process ended early (an engine that aborts the process, a
    failed assertion in native code), go on without losing a row: the unfinished runs one per
    process until one takes its process down too (it becomes an ``error`` row with the end of
    its output), then the rest together in one process, and so on until every run has a row.
    Each round records at least one row, so it ends. Returns the number of error rows."""
    from reports.store.results import Store
    from reports.store.runs import blank_row, finish_time

    out = run.folder.parent.parent
    log = run.folder / "isolated.log"
    crashed: set[str] = set()
    singles = True
    todo = _missing(env, scenarios, opts, out)
    # each round records a row or finds a culprit; the bound guards against a worker that
    # records nothing (its runs then stay missing, as after any interrupted run)
    for _ in range(2 * len(todo) + 2):
        todo = [s for s in _missing(env, scenarios, opts, out) if s.run_id not in crashed]
        if not todo:
            return len(crashed)
        batch = todo[:1] if singles else todo
        code = _launch(env, batch, run.folder, opts, log)
        if code == 0:
            continue  # all of the batch recorded: singles go on until the culprit is found
        with Store(run.folder, create=True) as st:
            done = st.done_ids()
        if singles and batch[0].run_id not in done:
            tail = [ln for ln in log.read_text(errors="replace").splitlines() if ln.strip()]
            row = blank_row(batch[0])
            row.update(
                status="error",
                message=f"the run's process ended ({code}) without a result: "
                f"{' | '.join(tail[-2:])[-500:]}",
                finished_at=finish_time(),
            )
            with Store(run.folder, create=True) as st:
                st.put(row)
            crashed.add(batch[0].run_id)
            singles = False  # the culprit is recorded: the rest together
        else:
            singles = True  # the batch crashed: find its culprit one run at a time
    return len(crashed)


def merge(out: Path, target: Target, folder: Path) -> int:
    """Copy the rows of one environment's folder into the matrix store; returns their number.
    Rows already there with the same content are written again (idempotent)."""
    from reports.store.results import Store

    if not (folder / "results.sqlite").exists():
        return 0
    with Store(folder) as src:
        rows = [_relabel(r, target) for r in src.rows()]
    with Store(out, create=True) as dst:
        for r in rows:
            dst.put(r)
    return len(rows)


def run_matrix(
    requirements,
    scenario_names=(),
    *,
    out,
    integrators=None,
    dts=None,
    t_end=None,
    sweep: bool = True,
    full: bool = True,
    accuracies=None,
    jobs: int = 1,
    parallel: int = 2,
    redo: bool = False,
    cache: Path | None = None,
    log=print,
) -> MatrixResult:
    """Run the scenarios (default: the default suite) on every target of ``requirements`` in
    its own environment and collect every row in ``out/results.sqlite``.

    ``parallel`` environments are made and run at a time, each run with ``jobs`` worker
    processes; one progress line per environment made and per environment run. Every input
    is checked first (InputError naming it). Never raises for a version that cannot be
    installed or whose runs fail: the result lists them, and the store keeps every finished
    row."""
    from reports.store.results import Store
    from reports.suite import check_count, check_integrators, check_out, resolve_scenarios

    t0 = time.perf_counter()
    targets = parse_requirements(requirements)
    for name, value in (("--jobs", jobs), ("--parallel", parallel)):
        check_count(name, value)
    scenarios = resolve_scenarios(scenario_names)
    engines = list(dict.fromkeys(t.engine for t in targets))
    integrators = check_integrators(integrators, engines, named=True)
    opts = dict(
        integrators=integrators, dts=dts, t_end=t_end, sweep=sweep, full=full,
        accuracies=accuracies, jobs=jobs, redo=redo,
    )  # fmt: skip
    out = check_out(out)
    result = MatrixResult(out)
    n = len(targets)
    done = {"envs": 0, "runs": 0}

    def one(target: Target) -> EnvRun:
        env = make_env(target, cache)
        done["envs"] += 1
        k = done["envs"]
        if not env.ok:
            log(f"[env {k}/{n}] {target.engine} {target.label}: UNAVAILABLE: {env.reason}")
            rows = _unavailable_rows(scenarios, target, env.reason, opts)
            with Store(out, create=True) as st:
                for r in rows:
                    st.put(r)
            return EnvRun(env, sub_folder(out, target), len(rows), 0.0, None, env.reason)
        how = "reused" if env.reused else f"created in {env.seconds:.1f} s"
        log(f"[env {k}/{n}] {target.engine} {target.label}: {how} ({env.path})")
        t_run = time.perf_counter()
        if not opts.get("redo") and not _missing(env, scenarios, opts, out):
            run = EnvRun(env, sub_folder(out, target), returncode=0, skipped=True)
        else:
            run = _run_in_env(env, scenarios, opts, out)
        if run.returncode not in (0, None):
            n_err = _isolate(env, scenarios, opts, run)
            log(
                f"[run] {target.engine} {target.label}: the run process ended early "
                f"({run.error}); the unfinished runs went on in processes of their own, "
                f"{n_err} of them ended their process too (error rows)"
            )
            run.error = ""
            run.crashed = n_err
            run.seconds = time.perf_counter() - t_run
        run.rows = merge(out, target, run.folder)
        done["runs"] += 1
        state = f"FAILED: {run.error}" if run.error else "done"
        if run.skipped:
            state = "every run already in the store"
        log(
            f"[run {done['runs']}/{n}] {target.engine} {target.label}: {run.rows} rows in "
            f"{run.seconds:.1f} s, {state}"
        )
        return run

    runs: dict[int, EnvRun] = {}
    with ThreadPoolExecutor(max_workers=parallel) as pool:
        futs = {pool.submit(one, t): i for i, t in enumerate(targets)}
        for fut in as_completed(futs):
            runs[futs[fut]] = fut.result()
    result.runs = [runs[i] for i in range(n)]
    from reports.store.exports import export
    from reports.store.results import read_results

    df = read_results(out, all_rows=True)
    export(out, df)
    result.rows = len(df)
    result.seconds = time.perf_counter() - t0
    return result


def environments_record(result: MatrixResult) -> list[dict]:
    """Per environment: what was asked, what was installed, how long it took."""
    recs = []
    for r in result.runs:
        e = r.env
        recs.append(
            {
                "engine": e.target.engine,
                "label": e.target.label,
                "requirement": e.target.source,
                "available": e.ok,
                "reason": e.reason,
                "engine_version": e.engine_version,
                "reused": e.reused,
                "create_seconds": round(e.seconds, 2),
                "run_seconds": round(r.seconds, 2),
                "rows": r.rows,
                "run_error": r.error if e.ok else "",
                "crashed_runs": r.crashed,
                "path": str(e.path),
                "python": os.path.basename(str(e.python)),
            }
        )
    return recs
