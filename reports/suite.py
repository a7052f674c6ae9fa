"""The suite's top-level operations, one function per CLI subcommand (the CLI is a thin layer)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

DEFAULT_BASELINE = Path(__file__).resolve().parent / "baselines" / "default.json"


@dataclass
class RunSummary:
    out: Path
    n_run: int
    n_skipped: int
    results: object  # pandas DataFrame
    report: dict
    junit: Path | None
    comparison: object | None


def resolve_scenarios(names, all_: bool = False) -> list:
    """Scenario objects for names or paths; none given: the default suite."""
    import scenarios

    if all_:
        names = scenarios.list_scenarios()
    elif not names:
        names = scenarios.default_suite()
    return [scenarios.load(n) for n in names]


def run(
    names=(),
    *,
    all_scenarios: bool = False,
    engines=None,
    integrators=None,
    dts=None,
    t_end=None,
    sweep: bool = True,
    out="results",
    redo: bool = False,
    fmt: str = "parquet",
    baseline: str | Path | None = None,
    report: bool = True,
    progress: bool = True,
    jobs: int | None = None,
    scheduler: str | None = None,
    save_every: int | None = None,
    segment: int | None = None,
) -> RunSummary:
    """Run scenarios x engines x integrators x dt into ``out`` and write the report.

    ``baseline``: the tolerances for ``junit.xml`` (default: the committed baseline of the
    default suite, where it exists); runs absent from it get no test case. ``jobs``: local
    worker processes (default: one per core); ``scheduler``: a Dask scheduler address.
    """
    from reports import gate
    from reports.parallel import make_mapper
    from reports.report import build_report, write_provenance
    from reports.runner import plan, run_suite

    out = Path(out)
    scs = resolve_scenarios(names, all_scenarios)
    specs = plan(
        scs, engines, integrators, dts, t_end, sweep=sweep, save_every=save_every, segment=segment
    )
    out.mkdir(parents=True, exist_ok=True)
    write_provenance(out)
    df, n_run = run_suite(
        specs,
        out,
        redo=redo,
        fmt=fmt,
        progress=progress,
        mapper=make_mapper(jobs, scheduler),
    )
    rep = build_report(out) if report else {}
    baseline = (
        Path(baseline) if baseline else (DEFAULT_BASELINE if DEFAULT_BASELINE.exists() else None)
    )
    junit = cmp = None
    if baseline is not None:
        cmp = gate.compare(out, baseline, only_present=True)
        junit = gate.write_junit(cmp, out / "junit.xml")
    return RunSummary(out, n_run, len(specs) - n_run, df, rep, junit, cmp)


def ensemble(
    name,
    n: int,
    *,
    seed: int = 0,
    engines=None,
    integrators=None,
    dt=None,
    t_end=None,
    out="results",
    jobs=None,
    scheduler=None,
    progress=True,
    report: bool = True,
):
    """Run ``n`` members of one scenario on every engine/integrator into ``out/ensemble.csv``
    (see :mod:`reports.ensemble`), and refresh the report of ``out``."""
    from reports.ensemble import run_ensemble
    from reports.parallel import make_mapper
    from reports.report import build_report, write_provenance

    (sc,) = resolve_scenarios([name])
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if not (out / "provenance.json").exists():
        write_provenance(out)
    df = run_ensemble(
        sc,
        n,
        out,
        seed=seed,
        engines=engines,
        integrators=integrators,
        dt=dt,
        t_end=t_end,
        mapper=make_mapper(jobs, scheduler),
        progress=progress,
    )
    rep = build_report(out) if report else {}
    return df, rep


def catalog() -> dict:
    """Scenarios, engines (with version or why unavailable) and their integrators."""
    import scenarios
    from references.engines import engine_names, get_engine

    scs = []
    default = set(scenarios.default_suite())
    for name in scenarios.list_scenarios():
        sc = scenarios.load(name)
        scs.append(
            {
                "name": name,
                "description": sc.description,
                "default": name in default,
                "pivoted": sc.pivoted,
                "t_end": sc.t_end,
                "dt": sc.dt,
            }
        )
    engs = []
    for name in engine_names():
        cls = get_engine(name)
        why = cls.availability()
        engs.append(
            {
                "name": name,
                "available": why is None,
                "version": cls.version() if why is None else None,
                "why": why,
                "integrators": [
                    {
                        "name": i.name,
                        "family": i.family,
                        "order": i.order,
                        "description": i.description,
                    }
                    for i in cls.integrators
                ],
            }
        )
    return {"scenarios": scs, "engines": engs}
