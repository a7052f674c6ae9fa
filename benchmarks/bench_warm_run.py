"""The CPU a warm default-suite run spends outside the engines' stepping, before and after a
change, measured side by side: two checkouts of director-bench (``--before DIR``, e.g. a
``git archive`` of main, and this one), each step timed on both in alternation (B A, A B,
...), CPU time, so that a busy machine slows both alike.

Steps (each a median over ``--rounds`` rounds, the two checkouts in alternating order):

- ``run``: the default suite and its report, warm (numba's cache current, the figure cache
  filled by a first run of each checkout), ``python -m reports.cli run --out DIR`` in the
  checkout: wall time and CPU time of the whole process tree (its workers and their fork
  server adopted and reaped, as benchmarks/bench_first_run.py does);
- ``references``: every closed-form and numerical reference the default suite's systems of
  bodies and single bodies ask for, on every time grid their runs save on, in one process
  with its per-process caches emptied (what each worker process gets for itself: computed,
  or read from the checkout's reference cache, references.cache, when it keeps one; each
  checkout has its own cache folder under ``--keep``, filled by a first call not counted):
  CPU s of the systems', the single bodies' and both;
- ``scorecard``: the scorecard picture (PNG and SVG) of the results folder ``--results``;
- ``work-precision``: every scenario's work-precision figure of ``--results`` (the figures a
  warm run draws again besides the scorecard: they show the run's timings);
- ``report``: the report of a copy of ``--results`` whose figures are all current (the
  documents, summary.json and the scorecard's check);
- ``drake-contact``: the first Drake contact scene a process builds (its imports), in a fresh
  process each time.

Usage: python benchmarks/bench_warm_run.py --before DIR --results RESULTS [--rounds 3]
[--steps run references scorecard work-precision report drake-contact] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

STEPS = ("run", "references", "scorecard", "work-precision", "report", "drake-contact")


# -- the steps measured inside a checkout's own process ----------------------------------------


def _grids(sc):
    """The time grids the default suite's runs of the scenario ``sc`` save on."""
    import numpy as np

    from reports.run.plan import plan
    from reports.suite import check_engines, default_engines

    engines = check_engines(default_engines()[0])
    grids = {}
    for s in plan([sc], engines, None, None, None, True, None, None, None, 10**9, False):
        from references.engines import step_plan

        _, saves = step_plan(s.dt, s.horizon, s.saving)
        t = np.asarray(saves, dtype=float) * s.dt
        grids.setdefault(t.tobytes(), t)
    return list(grids.values())


def _references() -> list[float]:
    """CPU s of [the systems' references, the single bodies', both] as a worker process gets
    them, its per-process caches emptied (each checkout's own way: computed, or read from
    its reference cache when it keeps one)."""
    import scenarios
    from references.engines.exact import system as ex
    from references.errors import Unsupported
    from reports.run import body

    names = scenarios.default_suite() + scenarios.default_systems() + scenarios.default_robots()
    scs = [scenarios.load(n) for n in names]
    work = [(sc, t) for sc in scs for t in _grids(sc)]
    for f in (getattr(ex, "_cached", None), getattr(ex, "_stability", None),
              body._reference_cached):  # fmt: skip
        if f is not None:
            f.cache_clear()
    got = {"system": 0.0, "body": 0.0}
    for sc, t in work:
        c0 = time.process_time()
        try:
            if sc.kind == "system":
                ex.reference(sc, t)
            else:
                body.reference_for(sc, t)
        except Unsupported:
            pass
        got[sc.kind] += time.process_time() - c0
    return [got["system"], got["body"], got["system"] + got["body"]]


def _frame(results: str):
    from reports.report.build import python_strings
    from reports.report.labels import with_engine_order
    from reports.store.provenance import read_provenance
    from reports.store.results import read_results

    return with_engine_order(python_strings(read_results(results)), read_provenance(results))


def _scorecard(results: str) -> float:
    from reports.report.scorecard_plot import scorecard_figure

    df = _frame(results)
    with tempfile.TemporaryDirectory() as tmp:
        c0 = time.process_time()
        scorecard_figure(df, Path(tmp))
        return time.process_time() - c0


def _work_precision(results: str) -> float:
    from reports.report import figures
    from reports.report.canvas import Styles
    from reports.report.plots import work_precision_plot

    df = _frame(results)
    styles = Styles(df)
    figures._warm_matplotlib()  # as the report's drawing process has it
    names = [sc for sc in sorted(df["scenario"].unique())
             if figures.draws("work_precision", df, sc)]  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        c0 = time.process_time()
        for sc in names:
            work_precision_plot(df, Path(tmp), sc, styles)
        return time.process_time() - c0


def _report(results: str) -> float:
    from reports.report.build import build_report

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "r"
        shutil.copytree(results, copy)  # modification times kept: every figure current
        build_report(copy)  # the scorecard's and the figures' marks written for this copy
        c0 = time.process_time()
        build_report(copy)
        return time.process_time() - c0


def worker() -> None:
    """Answer {"step": ..., "results": ...} requests with {"cpu": s} (run by CheckoutWorker)."""
    import reports

    for line in sys.stdin:
        req = json.loads(line)
        step = req["step"]
        if step == "where":
            out = {"where": reports.__file__}
        elif step == "references":
            out = {"cpu": _references()}
        elif step == "scorecard":
            out = {"cpu": _scorecard(req["results"])}
        elif step == "work-precision":
            out = {"cpu": _work_precision(req["results"])}
        else:
            out = {"cpu": _report(req["results"])}
        print(json.dumps(out), flush=True)


# -- the steps measured from outside ----------------------------------------------------------

DRAKE_CONTACT = """
import time
import scenarios
from references.engines.contact import configurations
from references.engines.drake.contact import Scene
sc = scenarios.load("sphere_backspin")
conf = configurations("drake")[0]
c0 = time.process_time()
Scene(sc, conf, sc.dt, {})
print(time.process_time() - c0)
"""


def _env(root: Path) -> dict:
    """The environment of a command in the checkout ``root``: as the first run's commands
    (bench_first_run.command_env: Python's bytecode and numba's cache beside the sources),
    the checkout first on the path."""
    from bench_first_run import command_env

    path = f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"
    return command_env(PYTHONPATH=path)


def drake_contact(root: Path) -> float:
    out = subprocess.run([sys.executable, "-c", DRAKE_CONTACT], cwd=root, env=_env(root),
                         capture_output=True, text=True, check=True)  # fmt: skip
    return float(out.stdout.split()[-1])


def warm_run(root: Path, out: Path, env: dict) -> tuple[float, float]:
    """(wall s, CPU s of the process tree) of the default suite and its report in ``root``."""
    from bench_first_run import timed

    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "reports.cli", "run", "--out", str(out)]
    wall, cpu, *_ = timed(cmd, root, env, out.with_suffix(".log"))
    return wall, cpu


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", type=Path, required=True, help="a checkout of the code before")
    ap.add_argument("--results", type=Path, help="a default-suite results folder")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", nargs="+", choices=STEPS, default=list(STEPS))
    ap.add_argument("--keep", type=Path, help="the runs' folders (default: a temporary one)")
    args = ap.parse_args(argv)
    if {"scorecard", "work-precision", "report"} & set(args.steps) and args.results is None:
        ap.error("--results is needed for the steps scorecard, work-precision and report")
    if "run" in args.steps and len(args.steps) > 1:
        # its CPU time is that of every child this process waits for, so none other may live
        ap.error("the step run is measured alone (--steps run)")
    from _checkout import CheckoutWorker
    from bench_first_run import _become_subreaper

    roots = {"before": args.before.resolve(), "after": ROOT}
    keep = args.keep or Path(tempfile.mkdtemp(prefix="warm-run-"))
    keep.mkdir(parents=True, exist_ok=True)
    got: dict = {(s, side): [] for s in args.steps for side in roots}
    workers = {}
    if "run" not in args.steps:  # one process per checkout, answering the steps measured in it
        for side, root in roots.items():  # each with its own cache folder (references, figures)
            os.environ["DIRECTOR_BENCH_CACHE"] = str(keep / "cache" / side)
            workers[side] = CheckoutWorker(root, __file__)
    try:
        for side, w in workers.items():  # each imports its own checkout
            print(f"{side}: {w.ask({'step': 'where'}, 'where')['where']}")
            if "references" in args.steps:  # a warm run's: the reference cache filled
                w.ask({"step": "references", "results": ""}, "references")
        if "run" in args.steps:
            _become_subreaper()
            for side, root in roots.items():  # fills the figure cache: the runs below are warm
                cache = keep / "figure-cache" / side
                if cache.is_dir() and any(cache.iterdir()):
                    continue  # filled by an earlier call with this --keep
                warm_run(
                    root, keep / f"{side}-first", dict(_env(root), DIRECTOR_BENCH_CACHE=str(cache))
                )
        for r in range(args.rounds):
            order = list(roots) if r % 2 == 0 else list(reversed(roots))
            for step in args.steps:
                for side in order:
                    if step == "run":
                        cache = str(keep / "figure-cache" / side)
                        env = dict(_env(roots[side]), DIRECTOR_BENCH_CACHE=cache)
                        value = warm_run(roots[side], keep / f"{side}-{r}", env)
                    elif step == "drake-contact":
                        value = (drake_contact(roots[side]),)
                    else:
                        req = {"step": step, "results": str(args.results)}
                        cpu = workers[side].ask(req, step)["cpu"]
                        value = tuple(cpu) if isinstance(cpu, list) else (cpu,)
                    got[step, side].append(value)
                    shown = " ".join(f"{v:.3f}" for v in value)
                    load = os.getloadavg()[0]
                    print(f"round {r + 1} {step} {side} {shown} (load {load:.1f})", flush=True)
    finally:
        for w in workers.values():
            w.close()
    print("\nstep            before (median)   after (median)   after/before (CPU)")
    print(
        "(CPU s; the step run: wall s / CPU s of the process tree; the step references: "
        "systems / single bodies / both)"
    )
    for step in args.steps:
        b = [statistics.median(v) for v in zip(*got[step, "before"], strict=True)]
        a = [statistics.median(v) for v in zip(*got[step, "after"], strict=True)]
        ratio = a[-1] / b[-1] if b[-1] else float("nan")
        bs, as_ = " / ".join(f"{x:.3f}" for x in b), " / ".join(f"{x:.3f}" for x in a)
        print(f"{step:15s} {bs:>16s}  {as_:>16s}   {ratio:.3f}")
    return 0


if __name__ == "__main__":
    if "--worker" in sys.argv:
        worker()
    else:
        sys.exit(main())
