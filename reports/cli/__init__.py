"""Command-line interface ``director-bench``: a thin layer, one library call per subcommand.

    director-bench list
    director-bench run [SCENARIO_OR_FILE ...] [--engines a,b] [--integrators x,y]
                       [--dt 1e-3,5e-4] [--t-end T] [--out DIR] [--redo] [--no-sweep]
    director-bench ensemble SCENARIO_OR_FILE [--n 64] [--seed 0] [--engines a,b] ...
    director-bench report DIR
    director-bench baseline DIR --write FILE
    director-bench check DIR --baseline FILE [--factor F]

Exit codes: 0 success; 1 a failure of the work (the check found regressions, the results
store is damaged, locked or cannot be written, a figure failed, a fault of the suite, or
--strict and a run failed), with a message fitting the cause; 2 bad input (unknown scenario,
engine or integrator, malformed file, bad option: an :class:`scenarios.schema.InputError` or
argparse's refusal), with a message naming it. Never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
from pathlib import Path

from reports.suite import ENSEMBLE_OUT, RUN_OUT


def _csv_list(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def _number_list(text: str, option: str, example: str, ok, rule: str) -> list[float]:
    """The comma-separated numbers of ``option``'s value ``text``, each passing ``ok`` and
    each given once; else an argparse error naming the option, the value and the rule. An
    empty item ("1e-3,,5e-4", "1e-3,") is refused, not skipped: it is a number left out."""
    items = [t.strip() for t in text.split(",")]
    try:
        vals = [float(t) for t in items]
    except ValueError:
        what = "an empty item: expected" if "" in items else "expected"
        what += " comma-separated numbers"
        raise argparse.ArgumentTypeError(f"{option} {text!r}: {what}, e.g. {example}") from None
    if any(not ok(v) for v in vals):
        raise argparse.ArgumentTypeError(f"{option} {text!r}: {rule}")
    twice = sorted({v for v in vals if vals.count(v) > 1})
    if twice:
        raise argparse.ArgumentTypeError(
            f"{option} {text!r}: {', '.join(f'{v:g}' for v in twice)} given twice; give each once"
        )
    return vals


def _float_list(text: str) -> list[float]:
    return _number_list(
        text, "--dt", "1e-3,5e-4", lambda v: v > 0 and math.isfinite(v), "every step must be > 0"
    )


def _accuracy_list(text: str) -> list[float]:
    return _number_list(
        text, "--accuracy", "1e-6,1e-9", lambda v: 0 < v < 1, "every accuracy must be in (0, 1)"
    )


#: the largest count an option takes (steps, states, members are indexed by 64-bit integers)
MAX_COUNT = 10**18


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a whole number") from None


def _whole(text: str) -> int:
    v = _integer(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 1")
    if v > MAX_COUNT:
        raise argparse.ArgumentTypeError(
            f"{text[:40]!r} ({len(text)} digits) must be at most {MAX_COUNT:.0e}"
        )
    return v


def _seed(text: str) -> int:
    v = _integer(text)
    if not 0 <= v < 2**64:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} must be in 0 .. 2^64 - 1")
    return v


def _factor(text: str) -> float:
    v = _positive(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 1 (a factor of worsening)")
    return v


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (v > 0 and math.isfinite(v)):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return v


#: the widths `list` lays its text out in: the terminal's, within these bounds
LIST_WIDTH = (60, 100)
#: the column where the text beside a scenario's or an integrator's name begins
LIST_COLUMN = 28


def _columns(left: str, text: str, width: int) -> list[str]:
    """``left`` then ``text`` wrapped at word boundaries from column LIST_COLUMN to ``width``
    (a word is never cut, not even at a hyphen; a NUL in ``text`` is a space that does not
    break); a ``left`` too wide for its column gets a line of its own."""
    import textwrap

    pad = " " * LIST_COLUMN
    lines = textwrap.wrap(
        text, width - LIST_COLUMN, break_long_words=False, break_on_hyphens=False
    ) or [""]
    lines = [line.replace("\0", " ") for line in lines]
    if len(left) < LIST_COLUMN:
        first = [f"{left:<{LIST_COLUMN}}{lines[0]}".rstrip()]
        return first + [pad + line for line in lines[1:]]
    return [left] + [pad + line for line in lines]


def _first_sentence(text: str) -> str:
    import re

    text = " ".join(text.split())
    return re.split(r"(?<=[.!?])\s+(?=[A-Z])", text, maxsplit=1)[0]


def cmd_list(args) -> int:
    import shutil
    import textwrap

    from reports.suite import catalog

    cat = catalog()
    if args.json:
        print(json.dumps(cat, indent=1))
        return 0
    lo, hi = LIST_WIDTH
    width = min(max(shutil.get_terminal_size((80, 24)).columns, lo), hi)
    out = ["Scenarios (* = in the default suite):"]
    for s in cat["scenarios"]:
        mark = "*" if s["default"] else " "
        text = f"{s['t_end']:g} s at dt {s['dt']:g} s. {_first_sentence(s['description'])}"
        out += _columns(f"{mark} {s['name']}", text, width)
    out += [""] + textwrap.wrap(
        "Engines and integrators (* = in the default suite). Give an integrator by the name on "
        "the left (--integrators semi-implicit-euler); case does not matter, and the display "
        'name, quoted, works too ("semi-implicit Euler").',
        width,
        break_on_hyphens=False,
    )
    for e in cat["engines"]:
        state = e["version"] if e["available"] else f"NOT AVAILABLE: {e['why']}"
        out += textwrap.wrap(
            f"{e['name']} {state}", width, subsequent_indent="    ", break_on_hyphens=False
        )
        for i in e["integrators"]:
            mark = "*" if i["default"] else " "
            text = f"order {i['order']}, {i['family']}"
            if i["name"] != i["slug"]:
                shown = i["name"].replace(" ", "\0")  # a display name stays on one line
                text += f'; shown as "{shown}"'
            out += _columns(f"  {mark} {i['slug']}", text, width)
    print("\n".join(out))
    return 0


def _show_lines(sc) -> list[str]:
    """What ``show`` prints of one checked scenario: its bodies and joints, run, reference
    and the scales its metrics are divided by."""
    from references.engines.exact.system import reference_kind as system_reference_kind

    def vec(a) -> str:
        return "[" + ", ".join(f"{float(x):.6g}" for x in a) + "]"

    lines = [f"{sc.name} ({sc.path}): valid"]
    if getattr(sc, "is_system", False):
        loops = sc.loop_joints
        lines.append(
            f"  a system of {len(sc.bodies)} bodies, {len(sc.joints)} joints"
            + (f"; loop closures: {', '.join(sorted(loops))}" if loops else "; a tree")
            + ("; floating" if sc.floating else "")
        )
        for b in sc.bodies:
            lines.append(
                f"    body {b.name}: mass {b.mass:.6g} kg, moments {vec(b.inertia)} kg m^2, "
                f"x_G {vec(b.position)} m"
            )
        for j in sc.joints:
            lines.append(f"    joint {j.name}: {j.kind} {j.body_a} - {j.body_b or 'ground'}")
        if getattr(sc, "has_contact", False):
            lines += _contact_lines(sc, vec)
        if getattr(sc, "model", None) is not None:
            from scenarios.models.scenario import describe

            lines += describe(sc)
        kind = system_reference_kind(sc)
    else:
        from references.exact import resolve_kind

        where = "pivoted" if sc.pivoted else "free"
        lines.append(
            f"  one {where} body: mass {sc.mass:.6g} kg, moments {vec(sc.inertia)} kg m^2, "
            f"W0 {vec(sc.omega_body)} rad/s"
        )
        kind = resolve_kind(sc)
    lines.append(f"  gravity {vec(sc.gravity)} m/s^2")
    sweep = ", ".join(f"{h:g}" for h in sc.dt_sweep) or "-"
    lines.append(
        f"  run: t_end {sc.t_end:g} s, dt {sc.dt:g} s ({round(sc.t_end / sc.dt)} steps), "
        f"dt_sweep {sweep}, save_every {sc.save_every}"
    )
    asked = "" if sc.reference == kind else f" (asked: {sc.reference})"
    lines.append(f"  reference: {kind}{asked}")
    if getattr(sc, "has_contact", False):
        from reports.metrics import contact as mc

        lines.append(
            f"  contact scales: L {mc.size(sc):.4g} m (slides beyond L/10), F_c "
            f"{mc.force_scale(sc):.4g} N, V_c {mc.speed_scale(sc):.4g} m/s"
        )
    else:
        scales = ", ".join(f"{k} {v:.4g}" for k, v in sc.energy_scales.items())
        lines.append(f"  scales: energy ({scales}) J, momentum {sc.momentum_scale:.4g} kg m^2/s")
    if sc.tolerances:
        lines.append(f"  tolerances: {sc.tolerances}")
    return lines


def _contact_lines(sc, vec) -> list[str]:
    """The shapes, planes, touching pairs, forces and closed form of a contact scene."""
    out = []
    for b in sc.bodies:
        s = b.shape
        if s is None:
            continue
        size = (
            f"half extents {vec(s.half_extents)}"
            if s.kind == "box"
            else f"radius {s.radius:g}"
            + (f", half length {s.half_length:g}" if s.kind in ("capsule", "cylinder") else "")
        )
        out.append(f"    shape of {b.name}: {s.kind}, {size} m, offset {vec(s.position)} m")
    for p in sc.planes:
        out.append(f"    plane {p.name}: normal {vec(p.normal)}, through {vec(p.point)} m")
    for c in sc.contacts:
        out.append(f"    contact {c.a} - {c.b}: mu {c.mu:g}, e {c.e:g}")
    for f in sc.forces:
        out.append(f"    force on {f.body}: {vec(f.force)} N at {vec(f.point)} m (body axes)")
    if sc.reference not in ("auto", "none"):
        import numpy as np

        from references.exact.contact_scene import contact_motion

        facts = contact_motion(sc, np.array([0.0, sc.t_end])).facts
        shown = {
            k: v
            for k, v in facts.items()
            if isinstance(v, bool | float) and k not in ("friction_ratio",)
        }
        out.append(
            "    closed form: "
            + ", ".join(
                f"{k} {v:.6g}" if isinstance(v, float) else f"{k} {v}" for k, v in shown.items()
            )
        )
    return out  # fmt: skip


def cmd_show(args) -> int:
    from reports.run.plan import check_families
    from reports.suite import check_engine_settings, resolve_scenarios

    scs = resolve_scenarios(args.scenarios)
    check_engine_settings(scs)
    out = []
    for sc in scs:
        check_families(sc)
        out += _show_lines(sc)
        if args.importers and getattr(sc, "model", None) is not None:
            out += _importer_lines(sc, args.engines)
    print("\n".join(out))
    return 0


def _importer_lines(sc, engines) -> list[str]:
    """The importer-difference table of a robot-model scenario (``show --importers``)."""
    from references.engines.importers import importer_table

    rows = importer_table(sc.model, engines=engines, fixed_base=not sc.floating)
    lines = ["  importers (each engine's own loader, read back at the zero configuration, "
             "root-link frame; differences from our reading):"]  # fmt: skip
    lines += [f"    {r.line()}" for r in rows]
    return lines


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
        report=not args.no_report,
        progress=not args.quiet,
        jobs=args.jobs,
        scheduler=args.scheduler,
        save_every=args.save_every,
        segment=args.segment,
        accuracies=args.accuracy,
        full=args.full,
        trajectories=args.trajectories,
    )
    df = summary.results
    print(
        f"{summary.n_run} runs executed, {summary.n_skipped} already done "
        f"(use --redo to run them again). The folder holds {len(df)} runs."
    )
    print("Status:  " + _counts(df["status"]))
    print("Verdict: " + _counts(df["verdict"].replace("", "none")))
    out = summary.out
    print(f"results:      {out / 'results.sqlite'} (exported: results.csv, results.parquet)")
    if args.trajectories == "report":
        print(
            f"trajectories: {out / 'trajectories'}: the series the report draws, at each "
            "scenario's own step (--trajectories full keeps every run's whole trajectory)"
        )
    if summary.report:
        print(f"report:       {summary.report['html']}\n              {summary.report['markdown']}")
    print(f"junit:        {summary.junit}")
    for why in summary.unloadable.values():
        print(f"not run:      {why}")
    for engine, why in summary.left_out.items():
        print(f"not run:      {engine}, left out of the default suite here: {why}; "
              "--engines all adds it")  # fmt: skip
    for path in summary.moved:
        print(
            f"moved aside:  {path} (it was changed by hand after director-bench wrote it; the "
            f"commands read the store, and {path.stem} was written again from it)"
        )
    if summary.removed:
        names = ", ".join(p.name for p in summary.removed)
        print(
            f"removed:      {names} (the verdict of an earlier `check` or `compare` on the "
            "results before this run; run it again)"
        )
    failed = df[(df["verdict"] == "fail") | (df["status"] == "error")]
    if len(failed):
        print(f"{len(failed)} run(s) failed their verdict or errored{_known(out, df)}; see the "
              "report's failures.")  # fmt: skip
    return 1 if (args.strict and len(failed)) else 0


def _known(out, df) -> str:
    """How many of the failures of the results ``df`` the committed baseline expects: ``: all
    190 fail as in the committed baseline (FILE), known failures`` or ``: 185 fail as in ...,
    5 do not (`director-bench check` lists them)``."""
    from reports.gate.check import failures_in_baseline
    from reports.suite import DEFAULT_BASELINE

    if not DEFAULT_BASELINE.is_file():
        return ""
    known, other = failures_in_baseline(out, df, DEFAULT_BASELINE)
    where = f"the committed baseline ({DEFAULT_BASELINE})"
    if not known:
        return f": none of them fails as in {where}"
    if not other:
        return f": all {known} fail as in {where}, known failures, not regressions"
    return (
        f": {known} fail as in {where}, {other} do not (`director-bench check {out} "
        f"--baseline {DEFAULT_BASELINE}` lists them)"
    )


def _counts(series) -> str:
    counts = series.value_counts().to_dict()
    return ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "none"


def cmd_ensemble(args) -> int:
    from reports.store.ensemble import summary
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


def _warn_edited(folder) -> None:
    """Say so when an export of ``folder`` (results.csv, results.parquet) was changed by
    hand (reports.store.exports): the commands read the store, so the change is not read."""
    from reports.store.exports import edited

    for sentence in edited(folder).values():
        print(f"director-bench: warning: {sentence}", file=sys.stderr)
        if os.environ.get("GITHUB_ACTIONS"):
            print(f"::warning title=director-bench: an export was edited::{sentence}")


def cmd_report(args) -> int:
    from reports.report.build import build_report

    folder = Path(args.dir)
    if (folder / "results.sqlite").is_file():
        _warn_edited(folder)
    if (folder / "results.sqlite").is_file() and not os.access(folder, os.W_OK):
        # the store reads fine (compare and check work here); the report is written beside it
        print(
            f"director-bench: error: {folder} is read-only and the report is written into the "
            f"results folder: copy it somewhere writable (`cp -r {folder} COPY`) and run "
            "`director-bench report COPY`",
            file=sys.stderr,
        )
        return 1
    rep = build_report(args.dir, progress=True)
    print(f"report: {rep['html']}\n        {rep['markdown']}")
    return 0


def cmd_baseline(args) -> int:
    from reports.gate.check import write_baseline
    from scenarios.schema import InputError

    if Path(args.write).is_dir():
        raise InputError(f"--write {args.write}: is a folder; give the baseline file's name")
    path = write_baseline(args.dir, args.write)
    print(f"baseline written: {path}")
    return 0


def cmd_check(args) -> int:
    from reports.gate.check import check

    if (Path(args.dir) / "results.sqlite").is_file():
        _warn_edited(args.dir)
    return check(
        args.dir,
        args.baseline,
        factor=args.factor,
        timing_factor=args.timing_factor,
        markdown=args.markdown,
        json_path=args.json,
    )


def cmd_compare(args) -> int:
    from reports.gate.compare import run_compare

    for folder in (args.a, args.b):
        if (Path(folder) / "results.sqlite").is_file():
            _warn_edited(folder)
    return run_compare(
        args.a,
        args.b,
        factor=args.factor,
        cost_factor=args.cost_factor,
        vary=tuple(args.vary or ()),
        show_all=args.all,
        markdown=args.markdown,
        json_path=args.json,
    )


def _add_compare(sub) -> None:
    s = sub.add_parser(
        "compare",
        help="compare two results folders run by run (e.g. two engine versions)",
        description="Match the runs of two results folders on scenario, engine, integrator, "
        "dt and target accuracy and give, per metric and cost, the ratio B/A: worse, better or "
        "the same within --factor (above round-off floors; a cost only beyond its measured "
        "spread). Runs whose identity differs (horizon, scenario content, versions...) are a "
        "mismatch. Exit 1 when a run got worse in a metric, its status or its verdict, on a "
        "mismatch, or when nothing is comparable; 2 for bad input.",
    )
    s.add_argument("a", metavar="A", help="the reference results folder")
    s.add_argument("b", metavar="B", help="the results folder compared with it")
    s.add_argument(
        "--factor",
        type=_factor,
        default=2.0,
        help="a metric changed by less than this factor is the same (default 2)",
    )
    s.add_argument(
        "--cost-factor",
        type=_factor,
        default=None,
        help="also exit 1 when the cost per step grew by more than this factor (off by "
        "default: timings follow the machine's load)",
    )
    s.add_argument("--all", action="store_true", help="list unchanged metrics too")
    s.add_argument(
        "--vary",
        type=_csv_list,
        default=(),
        metavar="FIELD[,FIELD]",
        help="identity fields allowed to differ between A and B, e.g. suite_version "
        "(by default any difference is a mismatch; engine releases may always differ and "
        "are reported)",
    )
    s.add_argument("--markdown", metavar="FILE", help="the Markdown summary (default B/compare.md)")
    s.add_argument("--json", metavar="FILE", help="the JSON summary (default B/compare.json)")
    s.set_defaults(func=cmd_compare)


RUN_EXAMPLES = """\
examples:
  director-bench run                          the default suite into results/
  director-bench run dzhanibekov heavy_top --engines mujoco,director
  director-bench run --engines mujoco --integrators rk4 --dt 1e-3,5e-4
  director-bench run --integrators semi-implicit-euler,runge_kutta5-error-controlled
  director-bench run my_top.toml --out /tmp/mine --jobs 1
  director-bench run --full --engines drake     every Drake integrator

Integrators are named as `director-bench list` shows them on the left
(semi-implicit-euler, rk4-float32, ...), in any case; the display names work
too when quoted ("semi-implicit Euler").
"""


def _add_overrides(s) -> None:
    """The options that override the scenario files' steps, horizon and target accuracies
    (``run`` and ``versions``, which runs the suite as ``run`` does)."""
    s.add_argument("--dt", type=_float_list, help="comma-separated step sizes (overrides files)")
    s.add_argument("--t-end", type=_positive, help="horizon in s (overrides files)")
    s.add_argument("--no-sweep", action="store_true", help="only each scenario's default dt")
    s.add_argument(
        "--accuracy",
        type=_accuracy_list,
        metavar="A,B",
        help="target accuracies of error-controlled integrators (overrides files)",
    )


def _add_run(sub) -> None:
    s = sub.add_parser(
        "run",
        help="run scenarios on engines and write the report",
        description="Run scenarios x engines x integrators x steps into a results folder and "
        "write its report (report.html, report.md), junit.xml and the results store.",
        epilog=RUN_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    s.add_argument(
        "scenarios",
        nargs="*",
        metavar="SCENARIO_OR_FILE",
        help="library names or paths to TOML files (none: the default suite)",
    )
    s.add_argument("--all", action="store_true", help="every library scenario")
    s.add_argument(
        "--full",
        action="store_true",
        help="every integrator of every engine (not only the default suite's) and the full "
        "sweep of target accuracies",
    )
    s.add_argument(
        "--engines",
        type=_csv_list,
        metavar="A,B",
        help="comma-separated engine names, or all (default: every engine but those left "
        "out of the default suite on this machine: MJX where JAX sees no accelerator)",
    )
    s.add_argument(
        "--integrators",
        type=_csv_list,
        metavar="X,Y",
        help="comma-separated integrator names, as `list` shows them (e.g. rk4,rattle4)",
    )
    _add_overrides(s)
    s.add_argument("--save-every", type=_whole, help="keep every N-th state (overrides files)")
    s.add_argument(
        "--segment",
        type=_whole,
        metavar="N",
        help="long horizons: metrics over every step, updated every N steps, memory O(N)",
    )
    s.add_argument("--out", default=RUN_OUT, help=f"output folder (default: {RUN_OUT})")
    s.add_argument("--redo", action="store_true", help="run again runs already in the results")
    s.add_argument(
        "--format",
        choices=["parquet", "csv"],
        default="parquet",
        help="file format of full trajectories (with --trajectories full)",
    )
    s.add_argument(
        "--trajectories",
        choices=["report", "full"],
        default="report",
        help="what each run keeps beside its row: report (default), the series the report "
        "draws, at each scenario's own step, a few MB for the default suite; full, every "
        "run's whole trajectory (about 200 MB for the default suite). The metrics are "
        "computed from the full run either way",
    )
    s.add_argument("--no-report", action="store_true", help="skip plots and reports")
    s.add_argument("--strict", action="store_true", help="exit 1 if any run failed or errored")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.add_argument(
        "--jobs",
        type=_whole,
        default=None,
        help="local worker processes (default: one per core; 1 = serial, best for timings)",
    )
    s.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask cluster instead of locally"
    )
    s.set_defaults(func=cmd_run)


def _add_ensemble(sub) -> None:
    s = sub.add_parser(
        "ensemble",
        help="one scenario over N initial conditions (random "
        "directions of W at the scenario's rotational energy)",
    )
    s.add_argument(
        "scenario", metavar="SCENARIO_OR_FILE", help="a library name or a path to a TOML file"
    )
    s.add_argument("--n", type=_whole, default=64, help="number of members (default 64)")
    s.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    s.add_argument("--engines", type=_csv_list, metavar="A,B", help="comma-separated engine names")
    s.add_argument(
        "--integrators",
        type=_csv_list,
        metavar="X,Y",
        help="comma-separated integrator names, as `list` shows them",
    )
    s.add_argument("--dt", type=_positive, help="step size (default: the scenario's)")
    s.add_argument("--t-end", type=_positive, help="horizon in s (overrides the file)")
    s.add_argument(
        "--out",
        default=ENSEMBLE_OUT,
        help=f"output folder (default: {ENSEMBLE_OUT}, apart from run's {RUN_OUT})",
    )
    s.add_argument("--jobs", type=_whole, default=None, help="local worker processes")
    s.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="Dask scheduler")
    s.add_argument("--no-report", action="store_true", help="skip the report")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_ensemble)


def _add_folder_commands(sub) -> None:
    s = sub.add_parser("report", help="regenerate plots and reports from a results folder")
    s.add_argument("dir", metavar="DIR", help="a results folder (run's or ensemble's --out)")
    s.set_defaults(func=cmd_report)

    s = sub.add_parser("baseline", help="write a baseline from a results folder")
    s.add_argument("dir", metavar="DIR", help="the results folder the baseline is taken from")
    s.add_argument(
        "--write", required=True, metavar="FILE", help="the baseline file to write (JSON)"
    )
    s.set_defaults(func=cmd_baseline)

    s = sub.add_parser("check", help="compare a results folder with a baseline (CI gate)")
    s.add_argument("dir", metavar="DIR", help="the results folder to check")
    s.add_argument(
        "--baseline",
        required=True,
        metavar="FILE",
        help="the baseline to compare with (written by `baseline`)",
    )
    s.add_argument(
        "--factor",
        type=_factor,
        default=2.0,
        help="allowed worsening factor of each metric (default 2)",
    )
    s.add_argument(
        "--timing-factor",
        type=_factor,
        default=None,
        help="also gate ns_per_step by this factor (off by default: noisy)",
    )
    s.add_argument(
        "--markdown",
        metavar="FILE",
        help="write the Markdown summary here (default DIR/check.md; also appended to "
        "$GITHUB_STEP_SUMMARY when set)",
    )
    s.add_argument(
        "--json", metavar="FILE", help="write the JSON summary here (default DIR/check.json)"
    )
    s.set_defaults(func=cmd_check)


class _Parser(argparse.ArgumentParser):
    """argparse's parser, taking a negative number in exponent notation ("--dt -1e-3") as
    an option's value like "-0.001", so that the option's own check refuses it by its rule
    instead of argparse saying the option "expected one argument". (Python 3.11's argparse
    recognises only "-1" and "-.5" forms; the parser has no option that looks like a
    negative number, so nothing else changes meaning.)"""

    def __init__(self, *args, **kwargs):
        import re

        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def build_parser() -> argparse.ArgumentParser:
    from reports import __version__

    p = _Parser(
        prog="director-bench",
        description="Validation and benchmark suite for rigid-body dynamics.",
    )
    p.add_argument("-V", "--version", action="version", version=f"director-bench {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("list", help="scenarios, engines and integrators with availability")
    s.add_argument(
        "--json",
        action="store_true",
        help="machine-readable output (each integrator with its slug and default flag)",
    )
    s.set_defaults(func=cmd_list)
    s = sub.add_parser(
        "show",
        help="check scenario files (or library names) as run does, and show what they hold, "
        "without running anything",
        description="Check each scenario as `run` checks it (every field, the joints at t = 0, "
        "the reference asked for) and print its bodies, joints, run, reference and metric "
        "scales; nothing is run or written. Exit 2 with the file, field, value and rule when "
        "a file is invalid.",
    )
    s.add_argument(
        "scenarios", nargs="+", metavar="SCENARIO_OR_FILE", help="library names or TOML files"
    )
    s.add_argument(
        "--importers",
        action="store_true",
        help="robot-model scenarios: load the model file with every engine's own importer "
        "(as loaded, and with the settings that make it faithful), read each model back and "
        "print every difference from our reading by name and size",
    )
    s.add_argument(
        "--engines", type=_csv_list, default=None, metavar="A,B",
        help="with --importers: these engines only",
    )  # fmt: skip
    s.set_defaults(func=cmd_show)
    _add_run(sub)
    _add_ensemble(sub)
    _add_folder_commands(sub)
    _add_compare(sub)
    from reports.versions.cli import add_subcommands  # versions, history

    types = dict(csv=_csv_list, whole=_whole, factor=_factor, overrides=_add_overrides)
    add_subcommands(sub, types)
    return p


def _quiet_exit() -> int:
    """The reader of our output went away (`director-bench list | head`): stop quietly, with
    standard output pointed at /dev/null so that the interpreter's final flush stays quiet."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    return 0


def main(argv: list[str] | None = None) -> int:
    from reports.store.results import StoreDamaged, StoreUnwritable
    from scenarios.schema import InputError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        # input errors (malformed scenario file, unknown name, bad baseline, bad option) are
        # the user's to fix: the message names the file or argument, the value and the rule
        print(f"director-bench: error: {exc}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        if exc.errno is None:  # ours, naming a folder or file given as an argument
            print(f"director-bench: error: {exc}", file=sys.stderr)
            return 2
        return _work_failed(exc, args.command)
    except (StoreDamaged, StoreUnwritable) as exc:
        print(f"director-bench: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        return _quiet_exit()
    except KeyboardInterrupt:
        print(
            "\ndirector-bench: interrupted; finished runs are kept in the results store, "
            "rerun the same command to continue.",
            file=sys.stderr,
        )
        return 130
    except Exception as exc:  # noqa: BLE001 - the work failed: a message, never a traceback
        return _work_failed(exc, args.command)


def _work_failed(exc: BaseException, command: str = "") -> int:
    """Exit 1 for a failure of the work, with a message that fits its cause: a file that
    cannot be written (disk full, a file-size limit, a read-only folder), memory, or a fault
    of the suite, located (file:line) so that it can be reported."""
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        advice = "; the results store is unchanged"
        if command in ("run", "ensemble", "report"):
            advice = (
                "; finished runs are kept in the results store, rerun (or `director-bench "
                "report DIR`) when the cause is fixed"
            )
        print(f"director-bench: error: {where}{exc.strerror or exc}{advice}", file=sys.stderr)
        return 1
    from reports.run.parallel import ClusterLost

    if isinstance(exc, ClusterLost):
        print(f"director-bench: error: {exc}", file=sys.stderr)
        return 1
    if isinstance(exc, MemoryError):
        print(
            "director-bench: error: out of memory; finished runs are kept in the results "
            "store: run fewer or shorter runs at once (--jobs, --save-every)",
            file=sys.stderr,
        )
        return 1
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    at = f" (at {Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""
    print(
        f"director-bench: error: the work failed: {type(exc).__name__}: {exc}{at}. This is a "
        "fault of director-bench, not of the input: finished runs are kept in the results "
        "store; please report it with the command (set DIRECTOR_BENCH_TRACEBACK=1 for the "
        "traceback)",
        file=sys.stderr,
    )
    if os.environ.get("DIRECTOR_BENCH_TRACEBACK"):
        traceback.print_exception(exc, file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
