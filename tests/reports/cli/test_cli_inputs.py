"""Bad input never ends in a traceback: every case exits 2 (bad input) or 1 (a failure of the
work) with a message naming the argument or file, the value and the rule, and no run starts.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import scenarios
from reports.cli import main

FREE = Path(scenarios.library_path()) / "free_tumbling.toml"


def run_main(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses a malformed option itself
        code = exc.code
    err = capsys.readouterr().err
    return code, err


def user_file(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def cases(tmp_path):
    """(argv, exit code, words the message must contain)."""
    out = str(tmp_path / "out")
    a_file = user_file(tmp_path, "a_file.txt", "x")
    twin = user_file(
        tmp_path, "twin.toml", FREE.read_text().replace("[0.9, 1.4, 2.0]", "[1.0, 1.4, 2.0]")
    )
    unknown_family = user_file(
        tmp_path, "fam.toml", FREE.read_text() + '\n[tolerances."RK9000"]\nattitude_error_max = 1\n'
    )
    four_bar = (Path(scenarios.library_path()) / "systems" / "four_bar.toml").read_text()
    settings_engine = user_file(
        tmp_path, "set_engine.toml", four_bar + "\n[engine_settings.mujocoo]\nsolref = [0.004, 1]\n"
    )
    settings_name = user_file(
        tmp_path, "set_name.toml", four_bar + "\n[engine_settings.mujoco]\nsolreff = [0.004, 1]\n"
    )
    settings_director = user_file(
        tmp_path, "set_dir.toml", four_bar + '\n[engine_settings.director]\nsolvr = "auto"\n'
    )
    settings_exact = user_file(
        tmp_path, "set_exact.toml", four_bar + "\n[engine_settings.exact]\nsteps = 10\n"
    )
    settings_mjx = user_file(
        tmp_path, "set_mjx.toml", four_bar + "\n[engine_settings.mjx]\nsolrf = [0.004, 1]\n"
    )
    exact = ["--engines", "exact", "--out", out]
    list_json = user_file(tmp_path, "list.json", "[1, 2, 3]")
    digits = "1" + "0" * 5000  # an integer beyond Python's 4300-digit conversion limit
    big_dt = user_file(tmp_path, "big_dt.json", '{"format": 3, "runs": [{"dt": ' + digits + "}]}")
    empty_dir = tmp_path / "empty"
    empty_dir.mkdir()
    return [
        *hostile_files(tmp_path, out),
        *hostile_options(out),
        (["run", "dzhanibekov", "--t-end", "1e9", "--out", out], 2, ["GiB", "--save-every"]),
        (["run", "free_tumbling", "--out", a_file], 2, ["a_file.txt", "not a folder"]),
        (["run", "/dev/zero", "--out", out], 2, ["/dev/zero", "not a regular file"]),
        (["run", str(tmp_path), "--out", out], 2, ["not a regular file"]),
        (["run", "--engines", "", "--out", out], 2, ["--engines", "empty", "mujoco"]),
        (["run", "--engines", "mujoco,bulletz", "--out", out], 2, ["bulletz", "known"]),
        (["run", "--integrators", "rattle,RK44", "--out", out], 2, ["RK44", "rattle4"]),
        (["run", "--integrators", "rattel", "--out", out], 2, ["rattel", "offer"]),
        (["run", "--engines", "mujoco", "--integrators", "rattle", "--out", out], 2, ["rattle"]),
        # an engine named in --engines that offers none of --integrators would run nothing
        (
            ["run", "--engines", "mujoco,pinocchio", "--integrators", "rk4", "--out", out],
            2,
            ["--engines pinocchio", "offers none", "rkmk4", "did you mean 'rkmk4'?"],
        ),
        (
            [
                "ensemble",
                "dzhanibekov",
                "--engines",
                "mujoco,director",
                "--integrators",
                "rk4",
                "--out",
                out,
            ],
            2,
            ["--engines director", "rattle4"],
        ),
        (["run", "dzhanibekow", "--out", out], 2, ["did you mean 'dzhanibekov'?"]),
        (["run", "--jobs", "0", "--out", out], 2, ["--jobs", ">= 1"]),
        (["run", "--segment", "0", "--out", out], 2, ["--segment", ">= 1"]),
        (["run", "--save-every", "-3", "--out", out], 2, ["--save-every", ">= 1"]),
        (["run", "--dt", "-1", "--out", out], 2, ["--dt", "> 0"]),
        (["run", "--dt", "abc", "--out", out], 2, ["--dt", "numbers"]),
        (["run", "dzhanibekov", "--dt", "7e-3", "--out", out], 2, ["whole number of steps"]),
        (["run", "--t-end", "nan", "--out", out], 2, ["--t-end", "finite"]),
        (["run", "--t-end", "inf", "--out", out], 2, ["--t-end", "finite"]),
        (["run", "--accuracy", "2", "--out", out], 2, ["--accuracy", "(0, 1)"]),
        (["run", "--format", "xml", "--out", out], 2, ["--format", "xml"]),
        (["run", "no_such_scenario", "--out", out], 2, ["no_such_scenario", "dzhanibekov"]),
        (["run", str(FREE), twin, "--out", out], 2, ["free_tumbling", "twin.toml", "are named"]),
        (["run", unknown_family, "--out", out], 2, ["RK9000", "families"]),
        (["run", settings_engine, *exact], 2, ["set_engine.toml", "mujocoo = {", "'mujoco'?"]),
        (["run", settings_name, *exact], 2, ["set_name.toml", "solreff = [0.004", "builder"]),
        (["run", settings_director, *exact], 2, ["set_dir.toml", "solvr = 'auto'", "'solver'?"]),
        (["run", settings_exact, *exact], 2, ["set_exact.toml", "steps = 10", "known: none"]),
        (["run", settings_mjx, *exact], 2, ["set_mjx.toml", "mjx.solrf", "'solref'?"]),
        (["report", str(tmp_path / "nowhere")], 2, ["nowhere", "no results store"]),
        (["report", str(empty_dir)], 2, ["empty", "no results store"]),
        (["check", str(empty_dir), "--baseline", list_json], 2, ["list.json", "baseline"]),
        (["check", str(empty_dir), "--baseline", str(tmp_path / "no.json")], 2, ["no.json"]),
        (["check", str(empty_dir), "--baseline", list_json, "--factor", "0.5"], 2, [">= 1"]),
        (["check", str(empty_dir), "--baseline", str(FREE)], 2, ["free_tumbling.toml", "JSON"]),
        (["check", str(empty_dir), "--baseline", "/dev/zero"], 2, ["/dev/zero", "not a regular"]),
        (["check", str(empty_dir), "--baseline", big_dt], 2, ["big_dt.json", "4300 digits"]),
        (["ensemble", "dzhanibekov", "--n", "0", "--out", out], 2, ["--n", ">= 1"]),
        (["run", "--out", out, "--scheduler", "tcp://127.0.0.1:9"], 2, ["scheduler"]),
    ]


def edited(tmp_path, name: str, old: str, new: str) -> str:
    """free_tumbling.toml with ``old`` replaced by ``new``, as a user's file."""
    text = FREE.read_text()
    assert old in text
    return user_file(tmp_path, name, text.replace(old, new))


def hostile_files(tmp_path, out) -> list:
    """(argv, exit code, words): scenario files at the limits of the schema, each refused
    before any work."""
    sweep = "dt_sweep = [4e-3, 2e-3, 1e-3]"
    tiny = FREE.read_text().replace(sweep, "").replace("dt = 1e-3", "dt = 5e-324")
    deep = FREE.read_text() + "\n[tolerances]\nx = " + "[" * 100_000 + "]" * 100_000 + "\n"
    files = [
        (edited(tmp_path, "m400.toml", "mass = 2.0", "mass = " + "9" * 400),
         ["body.mass", "finite"]),
        (edited(tmp_path, "m308.toml", "mass = 2.0", "mass = 1e308"), ["body.mass", "1e+150"]),
        (edited(tmp_path, "i320.toml", "[0.9, 1.4, 2.0]", "[1e-320, 1e-320, 1e-320]"),
         ["body.inertia", "at least 1e-150"]),
        (edited(tmp_path, "v.toml", "[0.5, -0.3, 0.2]", "[1e200, 0, 0]"),
         ["speed of the centre of mass", "1e+200"]),
        (edited(tmp_path, "g.toml", "[run]", "[environment]\ngravity = [0, 0, -1e308]\n[run]"),
         ["potential energy", "inf"]),
        (user_file(tmp_path, "dt.toml", tiny), ["run.dt", "5e-324", "2^53"]),
        (edited(tmp_path, "s400.toml", "save_every = 10", "save_every = " + "9" * 400),
         ["run.save_every", "18 digits"]),
        (edited(tmp_path, "big.toml", "mass = 2.0", "mass = " + "9" * 5000), ["not valid TOML"]),
        (user_file(tmp_path, "deep.toml", deep), ["deep.toml", "nested more than 8 levels"]),
        (edited(tmp_path, "n250.toml", '"free_tumbling"', '"' + "a" * 250 + '"'),
         ["name", "at most 128", "255 bytes"]),
        (edited(tmp_path, "n500.toml", '"free_tumbling"', '"' + "a" * 500 + '"'),
         ["name", "at most 128"]),
        (edited(tmp_path, "r.toml", "[0.4, -0.9, 1.3]", "[1e300, 0, 0]"),
         ["initial.rotation_vector", "modulo 2 pi"]),
    ]  # fmt: skip
    return [(["run", f, "--engines", "exact", "--out", out], 2, w) for f, w in files]


def hostile_options(out) -> list:
    """(argv, exit code, words): options at their limits."""
    ex = ["--engines", "exact", "--out", out]
    many, too_long = "9" * 400, "o" * 300  # a file name holds 255 bytes
    return [
        (["run", "free_tumbling", "--dt", "5e-324", *ex], 2, ["2^53", "inf steps"]),
        (["run", "free_tumbling", "--t-end", "1e300", "--dt", "1e297", *ex], 2,
         ["distance travelled by the centre of mass", "1e+150"]),
        (["run", "free_tumbling", "--save-every", many, *ex], 2, ["--save-every", "at most"]),
        (["run", "free_tumbling", "--segment", many, *ex], 2, ["--segment", "at most"]),
        (["run", "free_tumbling", "--jobs", "100000", *ex], 2, ["--jobs", "4 per core"]),
        (["ensemble", "free_tumbling", "--n", many, *ex], 2, ["--n", "at most"]),
        (["ensemble", "free_tumbling", "--n", "1000000000", *ex], 2, ["members", "memory"]),
        (["ensemble", "free_tumbling", "--seed", "-1", *ex], 2, ["--seed", "2^64"]),
        (["ensemble", "free_tumbling", "--dt", "5e-324", *ex], 2, ["2^53"]),
        (["ensemble", "free_tumbling", "--dt", "7e-3", *ex], 2, ["whole number of steps"]),
        (["run", "free_tumbling", "--scheduler", "nonsense://x", *ex], 2,
         ["--scheduler nonsense://x", "address scheme"]),
        (["run", "free_tumbling", "--engines", "exact", "--out", str(Path(out).parent / too_long)],
         2, ["--out", "File name too long"]),
        (["baseline", out, "--write", str(Path(out).parent)], 2, ["--write", "is a folder"]),
    ]  # fmt: skip


def test_every_bad_input_exits_with_a_message(tmp_path, capsys):
    failures = []
    for argv, want, words in cases(tmp_path):
        code, err = run_main(argv, capsys)
        problems = []
        if code != want:
            problems.append(f"exit {code}, expected {want}")
        if "Traceback" in err:
            problems.append("a traceback")
        missing = [w for w in words if w not in err]
        if missing:
            problems.append(f"message lacks {missing}")
        if problems:
            failures.append(f"{argv}: {'; '.join(problems)}\n    {err.strip()[:300]}")
    assert not failures, "\n".join(failures)
    # nothing ran: no refused command wrote anything, not even the output folder
    assert not (tmp_path / "out").exists()


def test_a_tolerance_for_a_family_of_an_engine_not_selected_is_valid(tmp_path):
    """Drake registers its families when its adapter is imported: a file bounding one of them
    is valid however the run selects its engines (here only the exact reference), and a
    family nobody registers is still refused. A fresh process, so that no other test has
    imported Drake's adapter already."""
    drake_family = user_file(
        tmp_path,
        "drake_family.toml",
        FREE.read_text()
        + '\n[tolerances."explicit Runge-Kutta on coordinates"]\nattitude_error_max = 1e-3\n',
    )
    code = (
        "import sys, scenarios\n"
        "from reports.run.plan import plan, InputError\n"
        "sc = scenarios.load(sys.argv[1])\n"
        "assert len(plan([sc], engines=['exact'], sweep=False)) == 1\n"
        "try:\n"
        "    plan([sc.replace(tolerances={'RK9000': {'attitude_error_max': 1.0}})], ['exact'])\n"
        "except InputError as exc:\n"
        "    assert 'RK9000' in str(exc) and 'explicit Runge-Kutta on coordinates' in str(exc)\n"
        "else:\n"
        "    raise AssertionError('an unknown family was accepted')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, drake_family], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]


def test_a_closed_pipe_exits_quietly():
    proc = subprocess.run(
        f"{sys.executable} -m reports.cli list --json | head -c 10",
        shell=True, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.stdout == '{\n "scenar'[:10]
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr


def test_list_json_is_valid_json():
    proc = subprocess.run(
        [sys.executable, "-m", "reports.cli", "list", "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    doc = json.loads(proc.stdout)
    assert {"scenarios", "engines"} <= set(doc)


# -- names a shell can type, `list` at 80 columns, help for every argument ----------------------


def test_the_slug_rule_on_names_written_out_by_hand():
    from references.engines.integrators import slug

    # expected values written from the rule in its docstring, not computed by it
    assert slug("semi-implicit Euler") == "semi-implicit-euler"
    assert slug("runge_kutta5 (error-controlled)") == "runge_kutta5-error-controlled"
    assert slug("RK4 (float32)") == "rk4-float32"
    assert slug("discrete SAP") == "discrete-sap"
    assert slug("RK4") == "rk4"
    assert slug("rattle4") == "rattle4"


def test_every_integrator_has_a_name_a_shell_types_unquoted():
    import re
    import shlex

    from references.engines import engine_names, get_engine

    for e in engine_names():
        slugs = [i.slug for i in get_engine(e).integrators]
        assert len(set(slugs)) == len(slugs), (e, slugs)
        for s in slugs:
            assert re.fullmatch(r"[a-z0-9_.-]+", s) and shlex.split(s) == [s], (e, s)


def test_two_integrators_with_one_slug_are_refused_when_the_adapter_is_defined():
    import pytest

    from references.engines import EngineBase, Integrator

    with pytest.raises(ValueError, match="same typed name 'rk4'"):

        class Twins(EngineBase):  # noqa: F841 - defining it is the test
            name = "twins"
            integrators = (
                Integrator("RK4", "4th-order Lie-group", 4, "one"),
                Integrator("rk4", "4th-order Lie-group", 4, "the other"),
            )


def test_integrators_by_slug_or_display_name_in_any_case():
    from reports.suite import check_integrators

    engines = ["mujoco", "pinocchio", "drake", "mjx"]
    asked = [
        "rk4",
        "RK4",
        "Semi-Implicit-Euler",
        "runge_kutta5 (error-controlled)",
        "EULER-float64",
    ]
    got = check_integrators(asked, engines)
    want = ["RK4", "semi-implicit Euler", "runge_kutta5 (error-controlled)", "Euler (float64)"]
    assert got == want


def test_a_misspelt_name_gets_a_suggestion(tmp_path, capsys):
    out = str(tmp_path / "out")
    argv = ["run", "--engines", "mujoco", "--integrators", "rk5", "--out", out]
    code, err = run_main(argv, capsys)
    assert code == 2 and "did you mean 'rk4'?" in err, err
    code, err = run_main(["run", "--engines", "pinocho", "--out", out], capsys)
    assert code == 2 and "did you mean 'pinocchio'?" in err, err
    assert not (tmp_path / "out").exists()


def test_run_mujoco_rk4_by_its_slug(tmp_path, capsys):
    from reports.store.results import read_results

    out = tmp_path / "out"
    argv = ["run", "free_tumbling", "--engines", "mujoco", "--integrators", "rk4",
            "--no-sweep", "--t-end", "0.1", "--no-report", "--quiet", "--jobs", "1",
            "--out", str(out)]  # fmt: skip
    code, err = run_main(argv, capsys)
    assert code == 0, err
    df = read_results(out)
    assert list(df["integrator"]) == ["RK4"] and list(df["status"]) == ["ok"]


def _list_lines(columns: int) -> list[str]:
    import os

    env = {**os.environ, "COLUMNS": str(columns)}
    proc = subprocess.run(
        [sys.executable, "-m", "reports.cli", "list"],
        capture_output=True, text=True, timeout=120, env=env,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.splitlines()


def test_list_fits_80_columns_cuts_no_word_and_marks_the_defaults():
    import re

    from reports.suite import catalog

    lines = _list_lines(80)
    assert max(map(len, lines)) <= 80, [line for line in lines if len(line) > 80]
    words = set(" ".join(lines).split())
    cat = catalog()
    for s in cat["scenarios"]:
        # the first sentence: up to a full stop before a capital letter ("0.489 .. 0.512"
        # is inside a sentence)
        first = re.split(r"(?<=\.)\s+(?=[A-Z])", " ".join(s["description"].split()))[0]
        assert set(first.split()) <= words, s["name"]  # every word whole, none cut
    marked = {line.split()[1] for line in lines if line.startswith("* ")}
    assert marked == {s["name"] for s in cat["scenarios"] if s["default"]}
    marked = {line.split()[1] for line in lines if line.startswith("  * ")}
    assert marked == {i["slug"] for e in cat["engines"] for i in e["integrators"] if i["default"]}
    unmarked = {line.split()[0] for line in lines if line.startswith("    ") and line[4] != " "}
    assert unmarked == {
        i["slug"] for e in cat["engines"] for i in e["integrators"] if not i["default"]
    }


def test_list_json_has_slugs_and_default_flags():
    proc = subprocess.run(
        [sys.executable, "-m", "reports.cli", "list", "--json"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    doc = json.loads(proc.stdout)
    mujoco = next(e for e in doc["engines"] if e["name"] == "mujoco")
    rk4 = next(i for i in mujoco["integrators"] if i["name"] == "RK4")
    assert rk4["slug"] == "rk4" and rk4["default"] is True
    drake = next(e for e in doc["engines"] if e["name"] == "drake")
    assert {i["default"] for i in drake["integrators"]} == {True, False}


def test_every_argument_has_help_and_run_help_has_examples(capsys):
    import argparse

    from reports.cli import build_parser

    missing = []

    def walk(parser, path):
        for a in parser._actions:
            if isinstance(a, argparse._SubParsersAction):
                for name, sub in a.choices.items():
                    walk(sub, [*path, name])
            elif not a.help:
                missing.append(
                    " ".join([*path, a.option_strings[0] if a.option_strings else a.dest])
                )

    walk(build_parser(), [])
    assert not missing, missing
    code, _ = run_main(["-V"], capsys)  # argparse prints the version to stdout and exits 0
    assert code == 0
    try:
        main(["run", "--help"])
    except SystemExit:
        pass
    text = capsys.readouterr().out
    assert "examples:" in text and "--engines mujoco --integrators rk4" in text


def test_ensemble_writes_apart_from_the_main_results(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    argv = ["ensemble", "free_tumbling", "--n", "2", "--engines", "mujoco", "--integrators",
            "euler", "--t-end", "0.05", "--jobs", "1", "--no-report", "--quiet"]  # fmt: skip
    code, err = run_main(argv, capsys)
    assert code == 0, err
    assert (tmp_path / "results-ensemble" / "ensemble.csv").exists()
    assert not (tmp_path / "results").exists()


# -- the program's end: output flushed, no interpreter teardown unless something needs it ------

PROGRAM = (
    "import atexit, sys, threading\n"
    "atexit.register(lambda: print('teardown ran', file=sys.stderr))\n"
    "if sys.argv[1] == 'thread':\n"
    "    def wait():  # until the main thread has ended (the orderly end marks it so)\n"
    "        while threading.main_thread().is_alive():\n"
    "            threading.Event().wait(0.05)\n"
    "    threading.Thread(target=wait).start()\n"
    "if sys.argv[1] == 'profiler':\n"
    "    sys.setprofile(lambda *a: None)\n"
    "sys.argv = ['director-bench', 'list', '--json']\n"
    "from reports.cli import program\n"
    "program()\n"
)


@pytest.mark.parametrize("case", ["plain", "thread", "profiler"])
def test_the_program_ends_at_once_with_its_output_flushed(case):
    # the whole of `list --json` (tens of kB through a pipe: block-buffered) reaches the
    # reader although the process ends without the interpreter's teardown (its atexit
    # handlers do not run), except where a non-daemon thread or a profiler needs that end
    proc = subprocess.run(
        [sys.executable, "-c", PROGRAM, case], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(proc.stdout) > 16384 and proc.stdout.endswith("}\n")  # print's last write
    assert {"scenarios", "engines"} <= set(json.loads(proc.stdout))
    assert ("teardown ran" in proc.stderr) == (case != "plain")
