"""The ``versions`` and ``history`` subcommands (registered by :func:`add_subcommands` from
``reports.cli``; one library call each: :func:`reports.versions.run_versions`,
:func:`reports.versions.history.write_history`)."""

from __future__ import annotations


def cmd_versions(args) -> int:
    from reports.gate.format import text_table
    from reports.versions import run_versions
    from reports.versions.changes import SUMMARY_HEAD, format_check, summary_rows
    from scenarios.schema import InputError

    def log(line: str) -> None:
        print(line, flush=True)

    opts = {}
    if args.engines:
        opts = dict(
            integrators=args.integrators, dts=args.dt, t_end=args.t_end, sweep=not args.no_sweep,
            full=not args.default_integrators, accuracies=args.accuracy, jobs=args.jobs,
            parallel=args.parallel, redo=args.redo,
        )  # fmt: skip
    elif args.scenarios:
        raise InputError("versions: scenarios given without --engines; nothing would run them")
    s = run_versions(
        args.engines,
        args.scenarios,
        out=args.out,
        check=args.check,
        factor=args.factor,
        cost_factor=args.cost_factor,
        figures=not args.no_figures,
        retime=args.retime,
        log=log,
        **opts,
    )
    failed = s.matrix.failed if s.matrix else []
    if s.matrix:
        print(f"{s.matrix.rows} rows in {s.out / 'results.sqlite'} ({s.matrix.seconds:.1f} s)")
    for p in s.table.pairs:
        na = f", {len(p.not_compared)} not compared" if p.not_compared else ""
        print(
            f"{p.engine} {p.from_version} -> {p.to_version}: {p.compared} compared, "
            f"{p.identical} identical, {p.within} within the factor, {p.changed} changed{na}"
        )
    if s.table.changes and not s.check:
        print("\n".join(text_table(SUMMARY_HEAD, summary_rows(s.table.changes))))
    for k, path in s.paths.items():
        print(f"{k + ':':<10} {path}")
    if s.check and not args.engines:
        print(
            f"{s.out / 'versions.md'} left as it is: a --check of a folder reads it (without "
            "--check, `versions --out` writes the report again)"
        )
    code = 0
    if failed:
        print(f"{len(failed)} environment(s) could not be made or their runs failed:")
        for r in failed:
            print(f"  {r.env.target.source} -> {r.env.target.label}: {r.error or r.env.reason}")
        code = 1
    if s.check:
        print("\n" + format_check(s.check))
        code = code or (0 if s.check.ok else 1)
    return code


def cmd_history(args) -> int:
    from reports.versions.history import write_history

    path = write_history(args.dirs, args.out, args.factor)
    print(f"history: {path}")
    return 0


def add_subcommands(sub, types: dict) -> None:
    """Add ``versions`` and ``history`` to ``sub`` (argparse subparsers). ``types``: the
    command line's argument checkers (``csv``, ``whole``, ``factor``) and ``overrides``, which
    adds run's options over the scenario files (``--dt``, ``--t-end``, ``--no-sweep``,
    ``--accuracy``), passed in by ``reports.cli`` so that both subcommands check their
    arguments as ``run`` does."""
    _csv_list, _whole, _factor = types["csv"], types["whole"], types["factor"]
    _add_overrides = types["overrides"]

    s = sub.add_parser(
        "versions",
        help="run the suite on several versions of engines, each in its own environment, and "
        "report what changed between them",
        description="Make one uv environment per engine version (cached in "
        "~/.cache/director-bench/envs or $DIRECTOR_BENCH_CACHE), run the scenarios in each, "
        "collect every row in OUT/results.sqlite and write OUT/versions.md, versions.json and "
        "history.html. Without --engines: the report (and --check) of OUT's store again. "
        "Exit 1 when an environment could not be made or a --check found something worse.",
    )
    s.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO_OR_FILE",
        help="library names or TOML files (none: the default suite); give them before --engines",
    )
    s.add_argument(
        "--engines",
        nargs="+",
        metavar="REQ",
        help="ENGINE==V1,V2,... (released versions) or ENGINE@PATH_OR_URL (a wheel), "
        "several at once, e.g. --engines mujoco==3.3.0,4.0.0 drake==1.40.0,1.51.1",
    )
    s.add_argument("--integrators", type=_csv_list, help="comma-separated integrator names")
    s.add_argument(
        "--default-integrators",
        action="store_true",
        help="only the default suite's integrators (default: every integrator, as run --full)",
    )
    _add_overrides(s)
    s.add_argument("--out", default="results-versions", help="output folder")
    s.add_argument("--jobs", type=_whole, default=1, help="worker processes per environment")
    s.add_argument(
        "--parallel", type=_whole, default=2, help="environments made and run at a time (2)"
    )
    s.add_argument("--redo", action="store_true", help="run again runs already in the store")
    s.add_argument(
        "--check",
        nargs=2,
        metavar=("FROM", "TO"),
        help="gate an upgrade: exit 1 if anything got worse from FROM to TO (each "
        "ENGINE==VERSION, a version, or oldest/newest)",
    )
    s.add_argument("--factor", type=_factor, default=2.0, help="metric factor (default 2)")
    s.add_argument(
        "--cost-factor",
        type=_factor,
        default=None,
        help="--check also fails when the cost per step grew by more than this factor",
    )
    s.add_argument("--no-figures", action="store_true", help="no figures in versions.md")
    s.add_argument(
        "--retime",
        action="store_true",
        help="time the cost candidates side by side again (default: the times recorded in "
        "OUT/versions-timings.json by an earlier call, so that two calls give one verdict)",
    )
    s.set_defaults(func=cmd_versions)

    s = sub.add_parser(
        "history",
        help="a self-contained HTML page of every metric over versions and result folders",
    )
    s.add_argument("dirs", nargs="+", metavar="DIR", help="results folders, oldest first")
    s.add_argument("--out", default="history.html", help="the page (default: history.html)")
    s.add_argument("--factor", type=_factor, default=2.0, help="metric factor (default 2)")
    s.set_defaults(func=cmd_history)
