"""The command line's lists of numbers (--dt, --accuracy) and negative numbers: an empty item
or a number given twice is refused naming the option, the value and the rule (a scenario
file's dt_sweep refuses repeated steps too), never skipped or merged; a negative number in
exponent notation reaches the option's own rule instead of argparse's "expected one
argument"."""

from __future__ import annotations

import pytest

from reports.cli import main


def _exit(argv, capsys):
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse refuses a malformed option itself
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    "option, value, words",
    [
        ("--dt", "1e-3,", ["--dt '1e-3,'", "an empty item"]),
        ("--dt", "1e-3,,5e-4", ["--dt '1e-3,,5e-4'", "an empty item"]),
        ("--dt", ",", ["an empty item"]),
        ("--dt", "1e-3,1e-3", ["--dt '1e-3,1e-3'", "0.001 given twice"]),
        ("--dt", "0.001,1e-3,5e-4", ["0.001 given twice"]),
        ("--accuracy", "1e-8,1e-8", ["--accuracy '1e-8,1e-8'", "1e-08 given twice"]),
        ("--dt", "-1e-3", ["--dt '-1e-3'", "every step must be > 0"]),
        ("--dt", "-2.5E+1", ["--dt '-2.5E+1'", "every step must be > 0"]),
        ("--t-end", "-1e3", ["'-1e3' must be a finite number > 0"]),
    ],
)
def test_refused_with_the_option_value_and_rule(tmp_path, capsys, option, value, words):
    out = tmp_path / "out"
    code, err = _exit(["run", "free_tumbling", option, value, "--out", str(out)], capsys)
    assert code == 2
    assert "expected one argument" not in err
    for w in words:
        assert w in err, err
    assert not out.exists()


def test_ensemble_dt_negative_in_exponent_notation(tmp_path, capsys):
    code, err = _exit(["ensemble", "free_tumbling", "--dt", "-1e-3", "--out", str(tmp_path)],
                      capsys)  # fmt: skip
    assert code == 2 and "'-1e-3' must be a finite number > 0" in err


def test_an_unknown_option_is_still_an_option(capsys):
    """Only numbers changed meaning: "-x" and "--nope" stay unknown options."""
    for bad in ("-x", "--nope"):
        code, err = _exit(["run", bad], capsys)
        assert code == 2 and f"unrecognized arguments: {bad}" in err


def test_distinct_steps_with_spaces_are_accepted():
    from reports.cli import build_parser

    args = build_parser().parse_args(["run", "--dt", "1e-3, 5e-4", "--accuracy", "1e-6,1e-8"])
    assert args.dt == [1e-3, 5e-4] and args.accuracy == [1e-6, 1e-8]
