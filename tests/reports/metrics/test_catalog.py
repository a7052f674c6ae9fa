"""The metric catalog: every metric declared once, every table derived from it, and the catalog's
own checks able to fail (a metric declared without its function, a function of an undeclared
metric, a function taking an argument the catalog does not pass)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from reports.metrics import catalog as C
from reports.metrics import (
    contact,  # noqa: F401  (attaches the contact functions)
    system,  # noqa: F401  (attaches the system functions)
)
from scenarios.metric_catalog import METRICS, OBSERVABLE, POINTWISE, SWEEP, Metric


def test_names_are_unique_and_every_metric_is_well_formed():
    names = [m.name for m in METRICS]
    assert len(names) == len(set(names))
    for m in METRICS:
        assert m.body or m.system or m.contact, m.name
        assert m.kind in (POINTWISE, OBSERVABLE, SWEEP), m.name
        assert m.floor is None or m.floor > 0, m.name
        assert m.tolerance is None or m.tolerance > 0, m.name
        # a higher-is-better metric has a slack instead of a floor and no upper bound
        assert (m.slack is not None) == m.higher_is_better, m.name
        assert not (m.higher_is_better and (m.tolerance is not None or m.floor is not None))
        assert m.panel is None or (m.series is not None and m.panel_top), m.name
        assert m.scale, m.name


def test_every_declared_metric_has_its_function_and_only_those():
    for on in C.TARGETS:
        C.check_attached(on)
        attached = {m.name for m, _ in C.computed(on)}
        declared = {m.name for m in METRICS if getattr(m, on) and m.kind in (POINTWISE, OBSERVABLE)}
        assert attached == declared


def test_derived_tables_follow_the_declarations():
    assert C.METRIC_COLUMNS == tuple(m.name for m in METRICS)
    assert C.METRIC_COLUMNS[-1] == "convergence_order"
    from scenarios.model import TOLERANCE_METRICS

    assert TOLERANCE_METRICS == tuple(m for m in C.METRIC_COLUMNS if m not in C.HIGHER_IS_BETTER)
    assert C.HIGHER_IS_BETTER == {"convergence_order"}
    assert C.ORDER_SLACK == 0.3
    assert set(C.DEFAULT_TOLERANCES) == {m.name for m in METRICS if m.tolerance is not None}
    # a verdict's detail lists the errors against the reference trajectory first
    assert next(iter(C.DEFAULT_TOLERANCES)) == "attitude_error_max"
    # the report shows what is compared with an exact solution first
    shown = list(C.METRIC_TITLES)
    assert shown[:5] == [
        "attitude_error_max",
        "omega_error_max",
        "position_error_max",
        "flip_interval_error",
        "nutation_period_error",
    ]
    assert [p[0] for p in C.ERROR_PANELS] == ["attitude_error", "energy_drift", "momentum_drift"]
    assert set(C.SYSTEM_METRICS) == {
        "joint_gap_max",
        "joint_angle_gap_max",
        "branch_error",
        "joint_coordinate_error_max",
    }


def test_the_consumers_read_the_catalog():
    """The store, the verdicts, the streaming recorder, the report and the figures hold the
    catalog's tables, not copies."""
    from reports.metrics import streaming, verdicts
    from reports.report import canvas, labels, plots, sections
    from reports.store import runs

    assert runs.METRIC_COLUMNS is C.METRIC_COLUMNS
    assert verdicts.DEFAULT_TOLERANCES is C.DEFAULT_TOLERANCES
    assert labels.METRIC_SHORT is C.METRIC_SHORT
    assert sections.METRIC_TITLES is C.METRIC_TITLES
    assert plots.ERROR_PANELS is C.ERROR_PANELS
    assert canvas.CAPS == {"energy_drift": 10.0, "momentum_drift": 10.0, "attitude_error": 4.0}
    assert [m.name for m, _ in streaming.streamed()] == list(C.STREAMED)
    assert system.SYSTEM_METRICS is C.SYSTEM_METRICS


def test_measures_refuses_what_the_catalog_does_not_declare():
    with pytest.raises(ValueError, match="not declared in scenarios.metric_catalog"):
        C.measures("no_such_metric")(lambda traj: traj)
    with pytest.raises(ValueError, match="not declared as applying to on='body'"):
        C.measures("joint_gap_max")(lambda traj: traj)
    with pytest.raises(ValueError, match="sweep metric"):
        C.measures("convergence_order", on="system")(lambda traj: traj)
    with pytest.raises(ValueError, match="already has a function"):
        C.measures("energy_drift_max")(lambda scenario, traj: traj)
    with pytest.raises(ValueError, match=r"parameters \['dt'\]"):
        C.measures("energy_drift_max")(lambda traj, dt: traj)


def test_a_declared_metric_without_a_function_fails_on_import():
    """Plant an undeclared-function metric in a fresh interpreter: importing the single-body
    metrics refuses it, naming the metric."""
    code = textwrap.dedent(
        """
        import scenarios.metric_catalog as mc
        mc.METRICS = mc.METRICS + (mc.Metric("planted_drift_max", "1", "a planted scale"),)
        try:
            import reports.metrics.body
        except ImportError as e:
            print("refused:", e)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "refused:" in out.stdout and "planted_drift_max" in out.stdout, out.stdout + out.stderr


def test_a_function_is_called_with_the_arguments_it_names():
    """``measures`` binds by parameter name and passes fixed keywords; the attached callable
    ignores what the function does not take."""
    seen = {}
    planted = Metric("planted_error_max", "1", "a planted scale", reference=True)
    C._BY_NAME[planted.name] = planted
    try:

        def fn(ref, traj, part):
            seen.update(ref=ref, traj=traj, part=part)
            return [1.0]

        C.measures(planted.name, part="rot")(fn)
        call = C._FUNCTIONS[(planted.name, "body")]
        assert call("scenario", "traj", "ref", "expected") == [1.0]
        assert seen == {"ref": "ref", "traj": "traj", "part": "rot"}
    finally:
        del C._BY_NAME[planted.name]
        C._FUNCTIONS.pop((planted.name, "body"), None)
