"""Time the README's first run: the install-time compilation, the default suite and its
report from a fresh clone (cold: nothing cached but what the compilation wrote), and again with
every cache warm.

Each round clones the repository afresh (``git clone``: no ``__pycache__``, so no numba cache
either), points JAX's persistent compilation cache and the suite's own cache (figures reused
across results folders, reports.report.figure_cache) at new empty folders (the user's own
caches under ``~/.cache/director-bench`` are left alone), and runs inside the clone the
README's commands after ``pip install``: ``director-bench compile`` (the numba kernels into
numba's cache beside the sources) as ``python -m reports.cli compile``, then ``director-bench
run --out results`` as ``python -m reports.cli run --out results`` (cold: the figure cache
empty, the results folder new), so that the clone's code is the code run (checked: the
script asks the clone which ``reports`` it imports). Then the run again in the same clone
into a new output folder (warm): the figures whose inputs do not change from run to run are
cached now (all but the work-precision figures and the scorecard picture, which show the
timings); the results are not. ``pip install`` itself is not timed (the engines are
installed already); ``--no-compile``: no compile step (the cold run compiles). The commands
run with the caches where a user's shell has them (:data:`UNSET`): numba's beside the clone's
sources, and Python's bytecode too (``__pycache__``, written by the cold run and read by the
warm one; without it every process compiles the suite's modules it imports again: 0.25 s of
CPU for the 127 that the workers' fork server and the start of a run import, measured at load
14).

Each command runs with a probe (a ``sitecustomize`` on ``PYTHONPATH``, in every process of
the command) that counts numba's top-level compilations (numba's ``numba:compile`` event; a
kernel loaded from the cache fires none): after ``compile``, the runs should compile nothing.

Printed per run: wall time, CPU time (user + sys of the whole process tree: the command, its
worker processes, their fork server and the report's drawing processes, from the operating
system's accounting of waited-for children: this script adopts and reaps the command's orphaned
descendants), the 1-minute load average before and after, and the *yardstick*: the
CPU time of a fixed pure-Python loop (:data:`YARDSTICK`) run in a fresh process just before and
just after the command, averaged. On a virtual machine whose host is shared, the speed of a
core changes from minute to minute (here the same loop has taken from 1.0x to 1.9x its fastest
time within ten minutes) and the guest's CPU accounting inflates with it, so neither wall nor
CPU time compares across days; the yardstick says how fast the machine was while the command
ran. And how far the progress display's estimate of the time left was off: the largest
factor between its estimate and the time actually left, over its lines from 10 % of the runs
on (:func:`eta_errors`; the command's progress goes to its log, one line per finished
scenario). Then the median of each.

``--beside N``: then N more rounds while a second suite runs beside them (the README's
command again and again, warm, from the first round's clone into a scratch folder, until the
round ends): the first run on a machine busy with another suite run.

Usage: python benchmarks/bench_first_run.py [--rounds 3] [--beside 0] [--repo PATH] [--keep DIR]
[--no-compile] (a few minutes per round on 2 cores).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
COMMAND = [sys.executable, "-m", "reports.cli", "run", "--out"]
COMPILE = [sys.executable, "-m", "reports.cli", "compile"]

#: the probe: in every Python process of a command, a listener on numba's compile event
#: appending each top-level compilation (name, thread CPU s) to $NB_PROBE_DIR/<pid>.jsonl
PROBE = """\
import os, sys
_dir = os.environ.get("NB_PROBE_DIR")
if _dir:
    import importlib.abc, importlib.util, json, time

    def _install():
        import numba.core.event as ev
        stack = []

        class _L(ev.Listener):
            def on_start(self, event):
                f = getattr((event.data or {}).get("dispatcher"), "py_func", None)
                stack.append((f"{getattr(f, '__module__', '?')}.{getattr(f, '__qualname__', '?')}",
                              time.thread_time()))

            def on_end(self, event):
                if not stack:
                    return
                name, c0 = stack.pop()
                if not stack:
                    with open(os.path.join(_dir, f"{os.getpid()}.jsonl"), "a") as fh:
                        fh.write(json.dumps({"name": name, "cpu": time.thread_time() - c0}) + "\\n")

        ev.register("numba:compile", _L())

    class _Hook(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            if name != "numba":
                return None
            sys.meta_path.remove(self)
            spec = importlib.util.find_spec("numba")
            run = spec.loader.exec_module

            def exec_module(module):
                run(module)
                _install()

            spec.loader.exec_module = exec_module
            return spec

    sys.meta_path.insert(0, _Hook())
"""


def compilations(probe_dir: Path) -> list[dict]:
    """The top-level numba compilations the probe recorded in ``probe_dir``."""
    out = []
    for f in sorted(probe_dir.glob("*.jsonl")):
        out += [json.loads(line) for line in f.read_text().splitlines() if line.strip()]
    return out


def _become_subreaper(on: bool = True) -> None:
    """Adopt the command's orphaned descendants (Linux ``PR_SET_CHILD_SUBREAPER``): the local
    workers' fork server is not waited for by the command, so without this its CPU time and
    its workers' would be missing from this process's accounting of waited-for children.
    ``on`` False: no longer (beside a second suite run, whose processes are not the
    command's: CPU times are not measured then)."""
    import ctypes

    if ctypes.CDLL("libc.so.6", use_errno=True).prctl(36, int(on)) != 0:  # PR_SET_CHILD_SUBREAPER
        sys.exit("cannot become a subreaper (prctl PR_SET_CHILD_SUBREAPER): CPU times would miss "
                 "the workers'")  # fmt: skip


def _reap_orphans(timeout: float = 60.0) -> None:
    """Wait for every adopted descendant to end (each ends with the command: see
    reports.run.parallel), so that their CPU time is counted; bounded by ``timeout``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            time.sleep(0.05)
    sys.exit(f"descendants of the timed command still running {timeout:g} s after it ended")


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


#: variables of this process's environment that the commands run without, as in a user's
#: shell: numba's cache beside the clone's sources and its compiler on; Python's bytecode
#: written beside the sources (``__pycache__``: a warm run reads it, as a user's does)
UNSET = ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT", "PYTHONDONTWRITEBYTECODE")


def command_env(**extra: str) -> dict:
    """The environment of the timed commands: this one without :data:`UNSET`, plus
    ``extra``."""
    env = dict(os.environ, **extra)
    for name in UNSET:
        env.pop(name, None)
    return env


def timed(cmd: list[str], cwd: Path, env: dict, log: Path, cpu_too=True) -> tuple[float, ...]:
    """(wall s, CPU s of the process tree, load before, load after, yardstick s) of ``cmd``
    (the yardstick's own processes are not counted in its CPU time); ``cpu_too`` False: CPU
    not measured (NaN), nothing reaped (a second suite runs beside, from this process)."""
    load0 = os.getloadavg()[0]
    stick0 = yardstick()
    cpu0, t0 = _children_cpu(), time.perf_counter()
    with log.open("w") as fh:
        proc = subprocess.run(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    wall = time.perf_counter() - t0
    if cpu_too:
        _reap_orphans()
    cpu = _children_cpu() - cpu0 if cpu_too else float("nan")
    stick = (stick0 + yardstick()) / 2
    if proc.returncode not in (0, 1):  # 1: some runs failed their verdict (the suite has some)
        sys.exit(f"{' '.join(cmd)} exited with {proc.returncode}; see {log}")
    return wall, cpu, load0, os.getloadavg()[0], stick


#: the yardstick's work: a fixed pure-Python loop (0.7 s of CPU on a quiet core of the 2-core
#: machine the README quotes, 1.1 to 1.4 s at busy moments)
YARDSTICK = "s = 0\nfor i in range(5_000_000):\n    s += i * i\n"


def yardstick() -> float:
    """CPU seconds of :data:`YARDSTICK` in a fresh interpreter (start-up excluded)."""
    code = (
        "import time\nt = time.process_time()\n" + YARDSTICK
        + "print(time.process_time() - t)"
    )  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout)


#: a progress line of the run (reports.run.progress, outside a terminal): runs done, their
#: percentage, the time so far and the estimate of the time left; and its closing line
_PROGRESS = re.compile(
    r"director-bench: .*?(\d+)/(\d+) runs \((\d+) %\), ([\d:]+)(?:, about ([\d:]+) left)?"
)
_CLOSING = re.compile(r"director-bench: (\d+)/\1 runs in ([\d:]+)")


def _seconds(clock: str) -> int:
    s = 0
    for part in clock.split(":"):
        s = 60 * s + int(part)
    return s


def eta_errors(log: str, start: float = 10.0) -> list[tuple[int, float]]:
    """(percentage done, estimated over actual time left) of each progress line of ``log``
    from ``start`` % of the runs on that gives an estimate (the actual time left: the
    closing line's time minus the line's; lines 3 s or less before the end are left out,
    a second's rounding being a factor there)."""
    end = _CLOSING.search(log)
    if end is None:
        return []
    total_s = _seconds(end.group(2))
    out = []
    for m in _PROGRESS.finditer(log):
        pct, now, left = int(m.group(3)), _seconds(m.group(4)), m.group(5)
        actual = total_s - now
        if pct >= start and left is not None and actual > 3:
            out.append((pct, _seconds(left) / actual))
    return out


def fresh_clone(repo: Path, where: Path) -> Path:
    clone = where / "clone"
    subprocess.run(["git", "clone", "--quiet", str(repo), str(clone)], check=True)
    caches = [p for p in clone.rglob("*") if p.suffix in (".nbi", ".nbc")]
    if caches:
        sys.exit(f"{clone}: a fresh clone holds numba cache files ({caches[0]})")
    return clone


def check_imports(clone: Path, env: dict) -> None:
    out = subprocess.run(
        [sys.executable, "-c", "import reports, director_model; print(reports.__file__)"],
        cwd=clone, env=env, capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    if not Path(out).resolve().is_relative_to(clone.resolve()):
        sys.exit(f"the clone imports reports from {out}, not from {clone}")


class Beside:
    """A second suite run beside the measurements: the README's command, warm, from
    ``clone`` into a scratch folder, started again each time it ends, until stopped."""

    def __init__(self, clone: Path, env: dict, where: Path):
        import threading

        self.clone, self.env, self.where = clone, env, where
        self.stop = threading.Event()
        self.lock = threading.Lock()  # no run starts once stopped
        self.proc = None
        self.runs = 0
        self.thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while True:
            out = self.where / f"beside-{self.runs}"
            with self.lock:
                if self.stop.is_set():
                    return
                self.proc = subprocess.Popen(
                    [*COMMAND, str(out), "--quiet"], cwd=self.clone, env=self.env,
                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                )  # fmt: skip
            self.proc.wait()
            self.runs += 1
            shutil.rmtree(out, ignore_errors=True)

    def __enter__(self):
        _become_subreaper(False)  # its processes are not the measured command's
        self.thread.start()
        time.sleep(5.0)  # under way (its workers started) before the measurement starts
        return self

    def __exit__(self, *exc):
        with self.lock:
            self.stop.set()
            if self.proc is not None and self.proc.poll() is None:
                self.proc.terminate()
        self.thread.join()
        _become_subreaper(True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="cold + warm pairs (default 3)")
    ap.add_argument("--beside", type=int, default=0,
                    help="then this many rounds beside a second suite run (default 0)")  # fmt: skip
    ap.add_argument("--beside-clone", type=Path,
                    help="a clone whose caches are warm (an earlier round's, kept with --keep) "
                         "for the suite run beside the rounds")  # fmt: skip
    ap.add_argument("--repo", type=Path, default=REPO, help="repository to clone")
    ap.add_argument("--keep", type=Path, help="keep the clones and logs under this folder")
    ap.add_argument(
        "--no-compile",
        action="store_true",
        help="no `director-bench compile` before the cold run (it compiles)",
    )
    args = ap.parse_args(argv)
    _become_subreaper()
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)  # the folder the user named to keep in
    base = Path(tempfile.mkdtemp(prefix="first-run-", dir=args.keep))
    rows = []
    first = None  # the first round's clone and environment (warm): the suite run beside
    try:
        commit = subprocess.run(
            ["git", "-C", str(args.repo), "rev-parse", "--short", "HEAD"],
            capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
        print(f"repository {args.repo} at {commit}; {os.cpu_count()} cores; logs in {base}")
        first_cmd = "" if args.no_compile else f"{' '.join(COMPILE)}, then "
        print(f"commands: {first_cmd}{' '.join(COMMAND)} DIR, in a fresh clone (cold), then "
              "the run again (warm)")  # fmt: skip
        unset = [v for v in UNSET if v in os.environ]
        if unset:
            print(f"run without {', '.join(unset)} (set here; a user's shell has none)")
        probe = base / "probe"
        probe.mkdir()
        (probe / "sitecustomize.py").write_text(PROBE)
        print(f"{'round':>5} {'step':>7} {'wall s':>8} {'CPU s':>8} {'load before':>12} "
              f"{'load after':>11} {'yardstick s':>12} {'ETA off by':>12} "
              f"{'numba compiles':>15}")  # fmt: skip
        if args.beside and args.beside_clone is not None:
            env = command_env(JAX_COMPILATION_CACHE_DIR=str(base / "beside-jax-cache"),
                              DIRECTOR_BENCH_CACHE=str(base / "beside-suite-cache"))  # fmt: skip
            first = (args.beside_clone.resolve(), env)
        elif args.beside and not args.rounds:  # the suite beside runs warm: warm a clone first
            where = base / "beside"
            where.mkdir()
            env = command_env(JAX_COMPILATION_CACHE_DIR=str(where / "jax-cache"),
                              DIRECTOR_BENCH_CACHE=str(where / "suite-cache"))  # fmt: skip
            first = (fresh_clone(args.repo, where), env)
            subprocess.run([*COMMAND, str(where / "results"), "--quiet"], cwd=first[0], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
            print(f"warmed {first[0]} for the suite run beside the rounds", flush=True)
        for k in range(1, args.rounds + args.beside + 1):
            beside = k > args.rounds
            where = base / f"round{k}"
            where.mkdir()
            # JAX's compilation cache and the suite's (reused figures) start empty
            env = command_env(
                JAX_COMPILATION_CACHE_DIR=str(where / "jax-cache"),
                DIRECTOR_BENCH_CACHE=str(where / "suite-cache"),
            )
            clone = fresh_clone(args.repo, where)
            check_imports(clone, env)
            if first is None:
                first = (clone, env)
            steps = ("cold", "warm") if args.no_compile else ("compile", "cold", "warm")
            with Beside(*first, where) if beside else contextlib.nullcontext():
                for kind in steps:
                    out = where / f"results-{kind}"
                    cmd = COMPILE if kind == "compile" else [*COMMAND, str(out)]
                    seen = where / f"probe-{kind}"
                    seen.mkdir()
                    env_k = dict(env, NB_PROBE_DIR=str(seen), PYTHONPATH=str(probe))
                    row = timed(cmd, clone, env_k, where / f"{kind}.log", cpu_too=not beside)
                    label = f"{kind}+" if beside else kind
                    rows.append((label, *row))
                    errs = eta_errors((where / f"{kind}.log").read_text(errors="replace"))
                    worst = max((max(r, 1 / r) for _, r in errs if r > 0), default=float("nan"))
                    got = compilations(seen)
                    print(f"{k:>5} {label:>7} {row[0]:8.1f} {row[1]:8.1f} {row[2]:12.2f} "
                          f"{row[3]:11.2f} {row[4]:12.2f} {worst:12.2f} {len(got):>15}",
                          flush=True)  # fmt: skip
                    if got and kind != "compile":
                        names = ", ".join(sorted({c["name"] for c in got}))
                        print(f"      numba compiled in that run: {names}", flush=True)
        for kind in ("compile", "cold", "warm", "compile+", "cold+", "warm+"):
            sel = [r for r in rows if r[0] == kind]
            if not sel:
                continue
            wall = statistics.median(r[1] for r in sel)
            cpu = statistics.median(r[2] for r in sel)
            loads = [x for r in sel for x in r[3:5]]
            sticks = [r[5] for r in sel]
            what = kind.replace("+", " beside a second suite run")
            cpu_text = f"CPU {cpu:.1f} s" if cpu == cpu else "CPU not measured"
            print(f"median {what}: wall {wall:.1f} s, {cpu_text} over {len(sel)} runs "
                  f"(load average {min(loads):.2f} to {max(loads):.2f}, yardstick "
                  f"{min(sticks):.2f} to {max(sticks):.2f} s)")  # fmt: skip
        for tail in ("", "+"):  # a user's first time after pip install: compile, then run
            comp = [r[1] for r in rows if r[0] == f"compile{tail}"]
            cold = [r[1] for r in rows if r[0] == f"cold{tail}"]
            if comp and len(comp) == len(cold):
                where = " beside a second suite run" if tail else ""
                total = statistics.median(a + b for a, b in zip(comp, cold, strict=True))
                print(f"median compile + cold run{where}: wall {total:.1f} s")
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
