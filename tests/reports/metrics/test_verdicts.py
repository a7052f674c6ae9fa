"""The one judge (reports.metrics.verdicts.judge) of every scene kind's runs."""

import math

import pytest

import scenarios
from references.engines import Diverged, get_engine
from reports.metrics import verdicts


def _row(**kw):
    row = {"status": "", "message": "", "reference_kind": "", "reference_accuracy": math.nan}
    row.update(kw)
    return row


@pytest.mark.parametrize("name", ["heavy_top", "four_bar", "block_incline_stick"])
def test_one_judge_for_every_scene_kind(name):
    sc = scenarios.load(name)
    integ = get_engine("mujoco").integrator("rk4")
    tol = verdicts.tolerances(sc, integ)["attitude_error_max"]
    # a reference the row names must be REFERENCE_MARGIN x below the attitude tolerance
    fine = tol / verdicts.REFERENCE_MARGIN
    ok = _row(reference_kind="numerical", reference_accuracy=fine, attitude_error_max=tol / 2)
    verdicts.judge(ok, sc, integ)
    assert (ok["status"], ok["verdict"]) == ("ok", "pass")
    coarse = _row(reference_kind="numerical", reference_accuracy=fine * 1.01)
    verdicts.judge(coarse, sc, integ)
    assert coarse["status"] == "reference-inaccurate" and coarse["verdict"] == ""
    assert "not 10x below the attitude tolerance" in coarse["message"]
    # no reference: judged on what is measured without one, its own message kept
    none = _row(reference_kind="none", message="no reference: why", energy_drift_max=0.5)
    verdicts.judge(none, sc, integ)
    assert none["status"] == "ok" and none["message"] == "no reference: why"
    assert none["verdict"] == "fail" and none["verdict_detail"].startswith("energy_drift_max")
    # a divergence fails, whatever was measured before it
    div = _row(reference_kind="numerical", reference_accuracy=fine)
    verdicts.judge(div, sc, integ, Diverged("blew up", t_diverged=0.25))
    assert (div["status"], div["verdict"], div["t_diverged"]) == ("diverged", "fail", 0.25)
