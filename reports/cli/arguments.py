"""The command line's parser: every subcommand, its options and their argument types (lists of
numbers, counts, seeds, factors), each refused with argparse's message naming the option, the
value and the rule. Each subcommand's ``func`` is its :mod:`reports.cli.commands` function."""

from __future__ import annotations

import argparse
import math

from reports.cli.commands import (
    cmd_baseline,
    cmd_check,
    cmd_compare,
    cmd_compile,
    cmd_ensemble,
    cmd_list,
    cmd_report,
    cmd_run,
    cmd_show,
)
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
    s.add_argument(
        "--no-reference-cache",
        action="store_true",
        help="compute every reference, neither reading nor keeping any in the reference "
        "cache ($DIRECTOR_BENCH_CACHE/references; also DIRECTOR_BENCH_REFERENCE_CACHE=off)",
    )
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
    s = sub.add_parser(
        "compile",
        help="compile the default suite's numba kernels into numba's cache (after installing)",
        description="Compile the numba kernels the default suite's runs go through (the "
        "director's, the multibody reference's, the suite's RKMK4) into numba's on-disk "
        "cache beside the sources, in parallel, naming each kernel as it compiles; every "
        "later run loads them. With the cache current it compiles nothing. Run it once after "
        "installing (the README's first command does); `run` compiles whatever is missing.",
    )
    s.add_argument(
        "--jobs", type=_whole, default=None, help="worker processes (default: one per core)"
    )
    s.set_defaults(func=cmd_compile)
    _add_ensemble(sub)
    _add_folder_commands(sub)
    _add_compare(sub)
    from reports.versions.cli import add_subcommands  # versions, history

    types = dict(csv=_csv_list, whole=_whole, factor=_factor, overrides=_add_overrides)
    add_subcommands(sub, types)
    return p
