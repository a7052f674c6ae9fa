"""Command-line interface ``director-bench``: a thin layer, one library call per subcommand.

    director-bench list
    director-bench run [SCENARIO_OR_FILE ...] [--engines a,b] [--integrators x,y]
                       [--dt 1e-3,5e-4] [--t-end T] [--out DIR] [--redo] [--no-sweep]
    director-bench ensemble SCENARIO_OR_FILE [--n 64] [--seed 0] [--engines a,b] ...
    director-bench report DIR
    director-bench baseline DIR --write FILE
    director-bench check DIR --baseline FILE [--factor F]

Exit codes: 0 success; 1 the check found regressions (or a run had failures with --strict);
2 bad input (unknown scenario, malformed file, bad option), with a message naming it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _csv_list(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _float_list(text: str) -> list[float]:
    try:
        vals = [float(t) for t in _csv_list(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--dt {text!r}: expected comma-separated numbers, e.g. 1e-3,5e-4"
        ) from None
    if not vals or any(not (v > 0) for v in vals):
        raise argparse.ArgumentTypeError(f"--dt {text!r}: every step must be > 0")
    return vals


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return v


def cmd_list(args) -> int:
    from reports.suite import catalog

    cat = catalog()
    if args.json:
        print(json.dumps(cat, indent=1))
        return 0
    print("Scenarios (* = default suite):")
    for s in cat["scenarios"]:
        mark = "*" if s["default"] else " "
        print(
            f" {mark} {s['name']:<24} t_end={s['t_end']:g} s dt={s['dt']:g} s  "
            f"{s['description'].splitlines()[0][:70]}"
        )
    print("\nEngines and integrators:")
    for e in cat["engines"]:
        state = e["version"] if e["available"] else f"NOT AVAILABLE: {e['why']}"
        print(f"  {e['name']:<10} {state}")
        for i in e["integrators"]:
            print(f"      {i['name']:<22} order {i['order']}  [{i['family']}]")
    return 0


def cmd_run(args) -> int:
    from reports.suite import run

    summary = run(
        args.scenarios,
        all_scenarios=args.all,
        engines=args.engines,
        integrators=args.integrators,
        dts=args.dt,
        t_end=args.t_end,
        sweep=not args.no_sweep,
        out=args.out,
        redo=args.redo,
        fmt=args.format,
        baseline=args.baseline,
        report=not args.no_report,
        progress=not args.quiet,
        jobs=args.jobs,
        scheduler=args.scheduler,
        save_every=args.save_every,
        segment=args.segment,
    )
    df = summary.results
    counts = df["status"].value_counts().to_dict()
    print(
        f"{summary.n_run} runs executed, {summary.n_skipped} already done "
        f"(use --redo to run them again). Status: "
        + ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    )
    out = summary.out
    print(f"results:      {out / 'results.csv'}")
    if summary.report:
        print(f"report:       {summary.report['html']}\n              {summary.report['markdown']}")
    if summary.junit:
        print(f"junit:        {summary.junit}")
    failed = df[~df["status"].isin(["ok", "unavailable", "unsupported"])]
    if len(failed):
        print(f"{len(failed)} run(s) failed; see the 'Runs that did not complete' table.")
    return 1 if (args.strict and len(failed)) else 0


def cmd_ensemble(args) -> int:
    from reports.ensemble import summary
    from reports.suite import ensemble

    df, rep = ensemble(
        args.scenario,
        args.n,
        seed=args.seed,
        engines=args.engines,
        integrators=args.integrators,
        dt=args.dt,
        t_end=args.t_end,
        out=args.out,
        jobs=args.jobs,
        scheduler=args.scheduler,
        progress=not args.quiet,
        report=not args.no_report,
    )
    for r in summary(df):
        print(
            f"{r['engine']:>9} {r['integrator']:<22} members {r['members']:>7}  attitude "
            f"error median {r['attitude_error_max median']:.2e} max "
            f"{r['attitude_error_max max']:.2e}"
        )
    print(f"ensemble:     {Path(args.out) / 'ensemble.csv'}")
    if rep:
        print(f"report:       {rep['html']}")
    return 0


def cmd_report(args) -> int:
    from reports.report import build_report

    rep = build_report(args.dir)
    print(f"report: {rep['html']}\n        {rep['markdown']}")
    return 0


def cmd_baseline(args) -> int:
    from reports.gate import write_baseline

    path = write_baseline(args.dir, args.write)
    print(f"baseline written: {path}")
    return 0


def cmd_check(args) -> int:
    from reports.gate import compare, format_comparison, write_junit

    cmp = compare(args.dir, args.baseline, factor=args.factor, timing_factor=args.timing_factor)
    print(format_comparison(cmp))
    write_junit(cmp, Path(args.dir) / "junit.xml")
    return 0 if cmp.ok else 1


def build_parser() -> argparse.ArgumentParser:
    from reports import __version__

    p = argparse.ArgumentParser(
        prog="director-bench",
        description="Validation and benchmark suite for rigid-body dynamics.",
    )
    p.add_argument("--version", action="version", version=f"director-bench {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("list", help="scenarios, engines and integrators with availability")
    s.add_argument("--json", action="store_true", help="machine-readable output")
    s.set_defaults(func=cmd_list)

    s = sub.add_parser("run", help="run scenarios on engines and write the report")
    s.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO_OR_FILE",
        help="library names or paths to TOML files (none: the default suite)",
    )
    s.add_argument("--all", action="store_true", help="every library scenario")
    s.add_argument("--engines", type=_csv_list, help="comma-separated engine names")
    s.add_argument("--integrators", type=_csv_list, help="comma-separated integrator names")
    s.add_argument("--dt", type=_float_list, help="comma-separated step sizes (overrides files)")
    s.add_argument("--t-end", type=_positive, help="horizon in s (overrides files)")
    s.add_argument("--no-sweep", action="store_true", help="only each scenario's default dt")
    s.add_argument("--save-every", type=int, help="keep every N-th state (overrides files)")
    s.add_argument(
        "--segment",
        type=int,
        metavar="N",
        help="long horizons: run in segments of N steps, metrics over every step, memory O(N)",
    )
    s.add_argument("--out", default="results", help="output folder (default: results)")
    s.add_argument("--redo", action="store_true", help="run again runs already in the results")
    s.add_argument(
        "--format", choices=["parquet", "csv"], default="parquet", help="trajectory file format"
    )
    s.add_argument("--baseline", help="baseline JSON giving the tolerances of junit.xml")
    s.add_argument("--no-report", action="store_true", help="skip plots and reports")
    s.add_argument("--strict", action="store_true", help="exit 1 if any run failed")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="local worker processes (default: one per core; 1 = serial, best for timings)",
    )
    s.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask cluster instead of locally"
    )
    s.set_defaults(func=cmd_run)

    s = sub.add_parser(
        "ensemble",
        help="one scenario over N initial conditions (random "
        "directions of W at the scenario's rotational energy)",
    )
    s.add_argument("scenario", metavar="SCENARIO_OR_FILE")
    s.add_argument("--n", type=int, default=64, help="number of members (default 64)")
    s.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    s.add_argument("--engines", type=_csv_list, help="comma-separated engine names")
    s.add_argument("--integrators", type=_csv_list, help="comma-separated integrator names")
    s.add_argument("--dt", type=_positive, help="step size (default: the scenario's)")
    s.add_argument("--t-end", type=_positive, help="horizon in s (overrides the file)")
    s.add_argument("--out", default="results", help="output folder (default: results)")
    s.add_argument("--jobs", type=int, default=None, help="local worker processes")
    s.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="Dask scheduler")
    s.add_argument("--no-report", action="store_true", help="skip the report")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_ensemble)

    s = sub.add_parser("report", help="regenerate plots and reports from a results folder")
    s.add_argument("dir")
    s.set_defaults(func=cmd_report)

    s = sub.add_parser("baseline", help="write a baseline from a results folder")
    s.add_argument("dir")
    s.add_argument("--write", required=True, metavar="FILE")
    s.set_defaults(func=cmd_baseline)

    s = sub.add_parser("check", help="compare a results folder with a baseline (CI gate)")
    s.add_argument("dir")
    s.add_argument("--baseline", required=True, metavar="FILE")
    s.add_argument(
        "--factor",
        type=_positive,
        default=2.0,
        help="allowed worsening factor of each metric (default 2)",
    )
    s.add_argument(
        "--timing-factor",
        type=_positive,
        default=None,
        help="also gate ns_per_step by this factor (off by default: noisy)",
    )
    s.set_defaults(func=cmd_check)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        # Input errors (malformed scenario file, unknown name, bad baseline) are the user's to
        # fix: print the message that names file, field and rule, not a traceback.
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"director-bench: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            "\ndirector-bench: interrupted; finished runs are kept in results.csv, "
            "rerun the same command to continue.",
            file=sys.stderr,
        )
        return 130


if __name__ == "__main__":
    sys.exit(main())
