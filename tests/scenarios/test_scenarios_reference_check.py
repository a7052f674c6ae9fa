"""A user's file that asks for a closed-form reference by name must describe that motion:
refused before any run (exit 2, the file, ``reference.kind``, the value and why), never
found by each run (single bodies: rows of status error; systems: rows without a reference
that pass)."""

from __future__ import annotations

import re

import pytest

import scenarios
from references.exact import CLOSED_FORMS
from reports import cli
from reports.suite import reference_problem, resolve_scenarios
from scenarios import ScenarioError
from scenarios.system import SYSTEM_CLOSED_FORMS

ASYMMETRIC_TOP = """\
name = "my_asym_top"
description = "An asymmetric heavy top."

[body]
mass = 2.0
inertia = [0.04, 0.055, 0.07]

[initial]
rotation_vector = [0.3, -0.2, 0.1]
omega_body = [1.0, -3.0, 15.0]

[environment]
gravity = [0.0, 0.0, -9.81]
pivot = [0.0, 0.0, -0.08]

[run]
t_end = 1.0
dt = 1e-3

[reference]
kind = "{kind}"
"""


def _asking(kind: str):
    """The edit adding ``[reference] kind = kind`` before a file's ``[run]`` table."""
    return ("[run]", f'[reference]\nkind = "{kind}"\n\n[run]')


def _copy(tmp_path, name: str, new_name: str, edit=None):
    """The library file ``name`` copied to ``tmp_path`` as ``new_name`` (a user's file), with
    ``edit`` (old, new) applied to its text."""
    sc = scenarios.load(name)
    text = open(sc.path).read().replace(f'name = "{name}"', f'name = "{new_name}"', 1)
    if edit is not None:
        old, new = edit
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / f"{new_name}.toml"
    path.write_text(text)
    return path


def _refused(path, kind: str, why: str):
    with pytest.raises(ScenarioError) as err:
        resolve_scenarios([str(path)])
    e = err.value
    assert e.path == str(path)
    assert len(e.problems) == 1
    field, value, rule = e.problems[0]
    assert (field, value) == ("reference.kind", kind)
    assert re.search(why, rule), rule
    assert str(path) in str(e) and f"reference.kind = {kind!r}" in str(e)


def test_lagrange_top_asked_for_an_asymmetric_body_is_refused(tmp_path):
    path = tmp_path / "asym.toml"
    path.write_text(ASYMMETRIC_TOP.format(kind="lagrange_top"))
    _refused(path, "lagrange_top", "not symmetric")


def test_free_body_asked_for_a_heavy_top_is_refused(tmp_path):
    path = tmp_path / "asym.toml"
    path.write_text(ASYMMETRIC_TOP.format(kind="free_body"))
    _refused(path, "free_body", "gravity torques the body")


def test_steady_precession_asked_for_a_nutating_top_is_refused(tmp_path):
    # heavy_top nutates (tilt 0.489 .. 0.512 rad): not a steady precession
    path = _copy(tmp_path, "heavy_top", "my_top", _asking("steady_precession"))
    _refused(path, "steady_precession", "not a steady precession")


def test_numerical_and_auto_are_never_refused(tmp_path):
    for kind in ("numerical", "auto"):
        path = tmp_path / f"{kind}.toml"
        path.write_text(ASYMMETRIC_TOP.format(kind=kind).replace("my_asym_top", f"top_{kind}"))
        (sc,) = resolve_scenarios([str(path)])
        assert sc.reference == kind


def test_a_closed_form_that_applies_is_accepted(tmp_path):
    path = _copy(tmp_path, "heavy_top", "my_top", _asking("lagrange_top"))
    (sc,) = resolve_scenarios([str(path)])
    assert sc.reference == "lagrange_top"
    # the library's four-bar, as a user's file: its state is the closed form's
    path = _copy(tmp_path, "four_bar", "my_four_bar")
    (sc,) = resolve_scenarios([str(path)])
    assert sc.reference == "four_bar" and not scenarios.is_library_file(sc)


def test_four_bar_whose_state_is_another_motion_is_refused(tmp_path):
    # the file's state starts at theta = 0, its [reference] at 0.1 rad: another motion
    path = _copy(tmp_path, "four_bar", "my_four_bar", ("theta0 = 0.0", "theta0 = 0.1"))
    _refused(path, "four_bar", "initial .* of body 'crank' differs")


def test_four_bar_asked_for_bodies_of_other_names_is_refused(tmp_path):
    path = _copy(tmp_path, "four_bar", "my_four_bar")
    text = path.read_text().replace('"crank"', '"link1"')
    path.write_text(text)
    _refused(path, "four_bar", r"needs bodies named \['crank'\]")


def test_spinning_chain_with_a_wrong_rate_is_refused(tmp_path):
    path = _copy(tmp_path, "spinning_chain", "my_chain", ("rate = 2.0", "rate = 2.5"))
    _refused(path, "spinning_chain", "differs from the scenario's")


def test_cli_exits_2_before_any_run(tmp_path, capsys):
    path = tmp_path / "asym.toml"
    path.write_text(ASYMMETRIC_TOP.format(kind="lagrange_top"))
    out = tmp_path / "out"
    rc = cli.main(["run", str(path), "--engines", "director", "--no-report", "--quiet",
                   "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2
    assert str(path) in err and "reference.kind = 'lagrange_top'" in err
    assert "Traceback" not in err
    assert not out.exists()  # nothing written


def test_every_library_file_passes_the_check_it_skips():
    """The check skips the library's files (the set-up costs seconds in the main process):
    each of them must pass it."""
    checked = 0
    for name in scenarios.list_scenarios() + scenarios.list_systems():
        sc = scenarios.load(name)
        assert scenarios.is_library_file(sc)
        kinds = SYSTEM_CLOSED_FORMS if sc.kind != "body" else CLOSED_FORMS
        if sc.reference in kinds:
            assert reference_problem(sc) is None, name
            checked += 1
    assert checked >= 4  # cone_top, conical_pendulum, four_bar(2), spinning_chain
