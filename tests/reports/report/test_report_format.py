"""The report's text, one way everywhere: numbers, steps, hover texts, notes under figures,
settings, the reasons a configuration did not run."""

import json
import math

from reports.store.format import fmt


def test_numbers_are_formatted_one_way():
    """Three significant digits; scientific notation outside [1e-3, 1e4), short exponent."""
    cases = {
        0.0037: "0.00370",
        8.5e-4: "8.50e-4",
        1e-3: "0.00100",
        0.1: "0.100",
        3.14159: "3.14",
        1234.5: "1230",
        9999.6: "1.00e4",  # rounds into the scientific range
        158000.0: "1.58e5",
        -2.5e-12: "-2.50e-12",
        0.0: "0",
        math.nan: "-",
        math.inf: "inf",
        4: "4",
    }
    assert {v: fmt(v) for v in cases} == cases


def test_steps_are_written_with_the_short_exponent_of_every_other_number():
    """A step size is written as given, with its exponent as fmt writes one (``6.25e-5``
    beside ``1.00e-12``, never ``6.25e-05``), in tables, titles and a dt axis' ticks."""
    from reports.store.format import fmt_step

    cases = {0.002: "0.002", 0.000125: "0.000125", 6.25e-5: "6.25e-5", 1e-5: "1e-5", 2.0: "2"}
    assert {v: fmt_step(v) for v in cases} == cases


def test_an_error_controlled_line_says_so_once_on_hover():
    """The hover text of an error-controlled work-precision line names it error-controlled
    once (Drake's integrator is called ``runge_kutta5 (error-controlled)`` already)."""
    from reports.report import plots

    said = plots._adaptive_gid("drake runge_kutta5 (error-controlled)")
    assert said.count("error-controlled") == 1 and "target accuracies" in said
    assert plots._adaptive_gid("x rk45").startswith("x rk45, error-controlled, ")


def test_a_note_under_a_figure_keeps_a_number_with_its_unit():
    """Wherever the wrap of a note under a figure falls, ``0.107 s`` and ``dt 0.001`` stay
    on one line (a line once ended in ``diverged at 0.107`` with ``s)`` alone below)."""
    from reports.report import canvas

    plt = canvas._plt()
    for k in range(90):
        fig, _ = canvas._new_figure(1)
        note = "x" * k + " semi_explicit_euler (dt 0.001: diverged at 0.107 s) " + "y " * 60
        canvas._fit(fig, note)
        lines = fig.texts[-1].get_text().split("\n")
        plt.close(fig)
        assert not any(ln.rstrip().endswith(("0.107", " dt")) for ln in lines), (k, lines)
        assert not any(ln.lstrip().startswith(("s)", "0.001:")) for ln in lines), (k, lines)


def test_settings_print_a_negative_zero_as_zero():
    """An engine records a centre of mass at [-0.0, -0.0, 0.1] (a negated zero coordinate):
    the report shows 0 there, keeps every other number as recorded, and the stored value is
    left as it is."""
    import pandas as pd

    from reports.report.tables import _setting, settings_table

    stored = json.dumps(
        {
            "local COM": [-0.0, -0.0, 0.1],
            "inertial frame": "diaginertia at [-0.0, -0, 0.075], tilt -0.05, -1.0e-0, x-0",
            "timestep": -0.0,
        }
    )
    df = pd.DataFrame(
        [{"engine": "mjx", "integrator": "Euler", "scenario": "heavy_top", "settings": stored}]
    )
    shown = {e["setting"]: e["values"] for e in settings_table(df)}
    assert shown == {
        "local COM": ["[0.0, 0.0, 0.1]"],
        "inertial frame": ["diaginertia at [0.0, 0, 0.075], tilt -0.05, -1.0e-0, x-0"],
        "timestep": ["0.0"],
    }
    assert (_setting(-0.0), _setting(-0.5), _setting("(-0.0, 1)")) == ("0", "-0.5", "(0.0, 1)")
    assert json.loads(df["settings"][0])["local COM"][0] == 0.0  # still stored as recorded
    assert str(json.loads(df["settings"][0])["local COM"][0]) == "-0.0"


def test_did_not_run_reasons_are_whole():
    """A long reason is given in full (it ends with what to do), never cut."""
    import pandas as pd

    from reports.report.tables import not_run

    reason = "PyBullet cannot hold this body: " + "a long explanation, " * 20 + "use X instead"
    df = pd.DataFrame(
        [
            {"engine": "pybullet", "integrator": "multibody", "status": "unsupported",
             "message": reason, "scenario": s}
            for s in ("a", "b")
        ]
    )  # fmt: skip
    (entry,) = not_run(df)
    assert entry["message"] == " ".join(reason.split()) and entry["scenarios"] == ["a", "b"]
