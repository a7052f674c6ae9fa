"""The mutation run over the system, gate and versions code (issue 32, item 7): how many of
mutmut's mutants of each module its tests kill, and every survivor's diff.

    pip install -e ".[mutation]"          # mutmut, pinned in pyproject.toml
    python benchmarks/mutation_run.py     # every module of MODULES
    python benchmarks/mutation_run.py --modules energy,gate --max-children 2

Each module of :data:`MODULES` is mutated on its own, in a copy of this checkout's tracked files
under a temporary folder (``--keep`` keeps it), with only the test files that exercise it
selected (so that one run takes minutes, not days: mutmut forks each mutant from a process
that has imported the tests once, and runs only the selected tests that reach the mutated
function). The score is killed / (killed + survived); a mutant whose tests time out counts as
killed (mutmut's rule: the change made the tests hang), one that no selected test reaches
("no tests") is listed apart. It prints a Markdown table per module and each survivor's diff
(``mutmut show``); ``--json FILE`` writes the counts and the survivors' names.

It is not part of the default tests (minutes per module on two cores). Each run's score and
its survivors, each killed by a test or explained as equivalent, are in the message of the
commit that added those tests (``git log -- benchmarks/mutation_run.py``).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> (the module mutated, the test files selected for it[, pytest -k expression]); the
#: expression leaves out the few slow end-to-end tests (a run through the engines takes 30-100 s,
#: and mutmut would rerun it for each of hundreds of mutants), so each module's run takes minutes
MODULES = {
    "energy": (
        "scenarios/energy.py",
        ["tests/scenarios/test_energy_in_play.py", "tests/reports/metrics/test_energy_scales.py"],
    ),
    "system metrics": (
        "reports/metrics/system.py",
        ["tests/reports/test_system_suite.py", "tests/reports/metrics/test_system_metrics.py"],
        "not end_to_end and not spinning_chain",
    ),
    "gate rule": (
        "reports/gate/rule.py",
        [
            "tests/reports/gate/test_gate.py",
            "tests/reports/gate/test_compare.py",
            "tests/reports/gate/test_rule.py",
        ],  # fmt: skip
    ),
    "gate check": (
        "reports/gate/check.py",
        ["tests/reports/gate/test_gate.py", "tests/reports/gate/test_check_output.py"],
    ),
    # test_compare.py is left out: its folders come from MuJoCo runs (a module fixture, ~3 s
    # rebuilt for every mutant); the two files below write their folders row by row
    "gate compare": (
        "reports/gate/compare.py",
        ["tests/reports/gate/test_compare_rule.py", "tests/reports/gate/test_compare_output.py"],
    ),
    "versions changes": (
        "reports/versions/changes.py",
        [
            "tests/reports/versions/test_versions.py",
            "tests/reports/versions/test_versions_history.py",
            "tests/reports/versions/test_changes_rule.py",
            "tests/reports/versions/test_changes_output.py",
            "tests/reports/versions/test_changes_reading.py",
        ],  # fmt: skip
        # two tests build a release's environment (14 s each, rerun for every mutant they reach)
        "not worker_records_the_planned_identity and not unreachable_index",
    ),
    "versions cost": (
        "reports/versions/cost.py",
        ["tests/reports/versions/test_versions.py", "tests/reports/versions/test_cost_rule.py"],
    ),
}

#: the packages copied into mutmut's ``mutants/`` (the tests import them from there)
PACKAGES = ["director_model", "scenarios", "references", "reports"]
#: other tracked folders the tests read
ALSO = ["docs", "benchmarks", "examples"]


def _copy_checkout(dest: Path) -> None:
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, check=True, capture_output=True,
                           text=True).stdout.split()  # fmt: skip
    for f in files:
        src = ROOT / f
        if src.is_file():
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / f)


def _setup_cfg(module: str, tests: list[str], keyword: str | None = None) -> str:
    def lines(xs):
        return "\n".join(f"    {x}" for x in xs)

    selection = tests + (["-k", keyword] if keyword else [])
    return (
        "[mutmut]\n"
        f"source_paths =\n{lines(PACKAGES)}\n"
        f"only_mutate =\n    {module}\n"
        f"also_copy =\n{lines(ALSO)}\n"
        f"pytest_add_cli_args_test_selection =\n{lines(selection)}\n"
        # one process per mutant (mutmut forks), no xdist workers, the default suite's marks
        "pytest_add_cli_args =\n    -n\n    0\n    -p\n    no:cacheprovider\n"
    )


def _results(cwd: Path, env) -> dict[str, str]:
    out = subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"],
                         cwd=cwd, env=env, capture_output=True, text=True).stdout  # fmt: skip
    status = {}
    for line in out.splitlines():
        if ":" in line and "__mutmut_" in line:
            name, st = line.rsplit(":", 1)
            status[name.strip()] = st.strip()
    return status


def run_module(name: str, max_children: int, keep: bool, only: list[str] | None = None) -> dict:
    module, tests, *keyword = MODULES[name]
    work = Path(tempfile.mkdtemp(prefix=f"mutation-{name.replace(' ', '-')}-"))
    _copy_checkout(work)
    (work / "setup.cfg").write_text(_setup_cfg(module, tests, *keyword))
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    t0 = time.monotonic()
    # mutmut names a mutant <module>.x_<function>__mutmut_<n>, or x\u01c1Class\u01c1method
    names = [f"{module[:-3].replace('/', '.')}.x{'' if chr(0x1C1) in f else '_'}{f}__mutmut_*"
             for f in only or ()]  # fmt: skip
    proc = subprocess.run([sys.executable, "-m", "mutmut", "run", "--max-children",
                           str(max_children), *names], cwd=work, env=env, capture_output=True,
                          text=True)  # fmt: skip
    wall = time.monotonic() - t0
    status = _results(work, env)
    if only:  # the other functions' mutants were not run ("not checked")
        status = {n: st for n, st in status.items() if st != "not checked"}
    counts: dict[str, int] = {}
    for st in status.values():
        counts[st] = counts.get(st, 0) + 1
    killed = counts.get("killed", 0) + counts.get("timeout", 0)
    survived = counts.get("survived", 0)
    survivors = sorted(n for n, st in status.items() if st == "survived")
    diffs = {}
    for n in survivors:
        diffs[n] = subprocess.run([sys.executable, "-m", "mutmut", "show", n], cwd=work,
                                  env=env, capture_output=True, text=True).stdout  # fmt: skip
    if not keep:
        shutil.rmtree(work, ignore_errors=True)
    return {
        "module": module,
        "tests": tests,
        "counts": counts,
        "score": killed / (killed + survived) if killed + survived else float("nan"),
        "survivors": survivors,
        "diffs": diffs,
        "wall_s": round(wall, 1),
        "returncode": proc.returncode,
        "log_tail": (proc.stdout + proc.stderr)[-2000:] if not status else "",
        "folder": str(work) if keep else None,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--modules", default=",".join(MODULES),
                    help=f"comma-separated, of: {', '.join(MODULES)}")  # fmt: skip
    ap.add_argument("--max-children", type=int, default=2, help="mutants run at once")
    ap.add_argument("--keep", action="store_true", help="keep each module's work folder")
    ap.add_argument("--only", default="",
                    help="comma-separated function names (e.g. _fmt,as_json; a method as "
                         "Class\u01c1method): mutate only these (one module)")  # fmt: skip
    ap.add_argument("--json", help="write the results to this file")
    args = ap.parse_args(argv)
    names = [m.strip() for m in args.modules.split(",") if m.strip()]
    unknown = [m for m in names if m not in MODULES]
    if unknown:
        ap.error(f"--modules: unknown {unknown}; known: {list(MODULES)}")
    results = {}
    for name in names:
        print(f"mutating {MODULES[name][0]} ...", file=sys.stderr, flush=True)
        only = [f.strip() for f in args.only.split(",") if f.strip()]
        results[name] = r = run_module(name, args.max_children, args.keep, only)
        if not r["counts"]:
            print(f"{name}: mutmut produced no results (exit {r['returncode']}):\n"
                  f"{r['log_tail']}", file=sys.stderr)  # fmt: skip
    print("| module | mutants | killed | timeout | survived | no tests | score | wall s |")
    print("|---|--:|--:|--:|--:|--:|--:|--:|")
    tot_k = tot_s = 0
    for r in results.values():
        c = r["counts"]
        k, s = c.get("killed", 0) + c.get("timeout", 0), c.get("survived", 0)
        tot_k, tot_s = tot_k + k, tot_s + s
        print(f"| {r['module']} | {sum(c.values())} | {c.get('killed', 0)} | "
              f"{c.get('timeout', 0)} | {s} | {c.get('no tests', 0)} | {r['score']:.1%} | "
              f"{r['wall_s']} |")  # fmt: skip
    if tot_k + tot_s:
        print(f"\nall: {tot_k} killed of {tot_k + tot_s}: {tot_k / (tot_k + tot_s):.1%}")
    for r in results.values():
        for n in r["survivors"]:
            print(f"\n### survivor {n}\n```diff\n{r['diffs'][n].strip()}\n```")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
