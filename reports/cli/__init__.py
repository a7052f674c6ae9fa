"""Command-line interface ``director-bench``: a thin layer, one library call per subcommand.

    director-bench list
    director-bench compile [--jobs N]
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

Modules: :mod:`.arguments` (the parser: every subcommand, option and argument type),
:mod:`.commands` (what each subcommand does, one library call each); this module runs a
command line and turns its failure into the exit code and message above.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from reports.cli.arguments import build_parser


def _quiet_exit() -> int:
    """The reader of our output went away (`director-bench list | head`): stop quietly, with
    standard output pointed at /dev/null so that the interpreter's final flush stays quiet."""
    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    return 0


def program() -> None:
    """The ``director-bench`` program (its console script, and ``python -m reports.cli``):
    :func:`main`, then the process ends at once with its exit code, its output flushed.

    The interpreter's orderly end would then spend 1.2 to 1.4 s of wall time and 0.3 to 0.5 s
    of CPU (measured after a default run's report, on 2 cores at load 9 to 16) taking apart
    what the command imported (pandas, Arrow, numba, matplotlib, the engines); nothing of
    ours needs it: every file is written and closed when :func:`main` returns, the worker
    processes have ended and the workers' fork server ends with this process
    (reports.run.server_guard). It is kept where something still runs at exit: a tracer or
    profiler (coverage, cProfile, a debugger: they write their results then) or a thread
    that is not a daemon (joined at exit)."""
    code = main()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except BrokenPipeError:
        code = _quiet_exit()
    except (OSError, ValueError):  # a closed stream: the orderly end reports it as it may
        sys.exit(code)
    if _nothing_at_exit():
        os._exit(code)
    sys.exit(code)


def _nothing_at_exit() -> bool:
    """Whether this process may end without the interpreter's orderly end (:func:`program`):
    no tracer or profiler set, and every thread but this one a daemon."""
    import threading

    if sys.gettrace() is not None or sys.getprofile() is not None:
        return False
    main_thread = threading.main_thread()
    return all(t is main_thread or t.daemon for t in threading.enumerate())


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


__all__ = ["build_parser", "main"]
