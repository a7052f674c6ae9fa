"""The comparison rule (reports/gate/rule.py) at its edges, function by function: each expected
value is the rule as its docstring states it, worked by hand (a ratio at exactly the factor,
a range end at exactly the factor times the other, a status of unknown rank, a legacy row's
wall-clock range). check and compare exercise the rule through whole folders
(test_gate.py, test_compare.py); these pin the boundaries those cannot reach cheaply."""

from __future__ import annotations

import math

import pytest

from reports.gate import rule
from reports.gate.rule import (
    Change,
    Comparison,
    classify,
    classify_cost,
    corroborate_costs,
    cost_range,
    count_version_change,
    failed_checks,
    failing,
    identical_metrics,
    ratio_change,
    status_change,
    verdict_change,
)
from reports.metrics.catalog import ORDER_SLACK

NAN = math.nan


# -- a metric ------------------------------------------------------------------------------


def test_ratio_change_is_strict_at_the_factor_and_its_inverse():
    assert ratio_change(2.0, 2.0) == "same"  # exactly the factor: not beyond it
    assert ratio_change(2.0000001, 2.0) == "worse"
    assert ratio_change(0.5, 2.0) == "same"  # exactly 1 / factor
    assert ratio_change(0.4999999, 2.0) == "better"
    assert ratio_change(0.75, 2.0) == "same"
    assert ratio_change(1.5, 2.0) == "same"


def test_the_convergence_order_is_compared_by_difference():
    """Higher is better, by ORDER_SLACK (0.3): 4.0 -> 4.0 - 0.3 exactly is the same, 4.0 ->
    4.0 + 0.3 exactly the same; the ratio B/A is reported (1.5 for 2 -> 3), NaN from 0."""
    a = 4.0
    assert classify("convergence_order", a, a - ORDER_SLACK, 2.0)[1] == "same"
    assert classify("convergence_order", a, a + ORDER_SLACK, 2.0)[1] == "same"
    assert classify("convergence_order", a, a - 0.31, 2.0)[1] == "worse"
    assert classify("convergence_order", 2.0, 3.0, 2.0) == (1.5, "better")
    r, word = classify("convergence_order", 0.0, 1.0, 2.0)
    assert math.isnan(r) and word == "better"


def test_an_error_metric_without_a_floor_is_compared_from_zero():
    """A column without a round-off floor (FLOORS' default 0): 1e-3 -> 3e-3 is 3x worse;
    equal values are ratio 1 exactly; from 0 the ratio is infinite."""
    assert classify("a column with no floor", 1e-3, 3e-3, 2.0) == pytest.approx((3.0, "worse"))
    assert classify("a column with no floor", 1e-3, 1e-3, 2.0) == (1.0, "same")
    assert classify("a column with no floor", 0.0, 1.0, 2.0) == (math.inf, "worse")


def test_both_values_below_the_floor_are_the_same_at_ratio_one():
    assert classify("energy_drift_max", 3e-16, 9e-15, 2.0) == (1.0, "same")


# -- a status and a verdict ----------------------------------------------------------------


@pytest.mark.parametrize(
    "a, b, word",
    [("ok", "ok", "same"), ("ok", "diverged", "worse"), ("diverged", "ok", "better"),
     ("unsupported", "unavailable", "changed"),  # the same rank, 4
     ("a status of no rank", "ok", "better"), ("ok", "a status of no rank", "worse"),
     ("error", "a status of no rank", "worse"), ("no rank", "another of no rank", "changed")],
)  # fmt: skip
def test_status_change_by_rank(a, b, word):
    assert status_change(a, b) == word


def test_failing_and_the_failed_checks():
    assert failing({"status": "error"}) and failing({"verdict": "fail"})
    assert not failing({"status": "diverged", "verdict": "pass"})
    assert failed_checks({"status": "error"}) == {"error"}
    assert failed_checks({"status": "diverged", "verdict": "fail"}) == {"diverged"}
    assert failed_checks({"status": "unsupported"}) == set()
    assert failed_checks({"status": "ok"}) == set()  # no detail at all
    assert failed_checks({"status": "ok", "verdict_detail": None}) == set()
    assert failed_checks({"status": "ok", "verdict_detail": "x 1 > 0; y 2 > 1"}) == {"x", "y"}


def test_verdict_change_returns_the_whole_triple():
    assert verdict_change({"verdict": "pass"}, {"verdict": "fail"}) == ("verdict", "worse", "")
    assert verdict_change({"verdict": "fail"}, {"verdict": "pass"}) == ("verdict", "better", "")
    a = {"verdict": "fail", "failed_checks": ["x"]}
    b = {"verdict": "fail", "status": "ok", "verdict_detail": "z 2 > 1; x 1 > 0; y 3 > 1"}
    assert verdict_change(a, b) == ("failed checks", "worse", "y, z")


def test_identical_metrics_needs_status_verdict_and_every_metric():
    m = "attitude_error_max"
    base = {"status": "ok", "verdict": "pass", m: 1e-3}
    assert identical_metrics(base, dict(base))
    assert not identical_metrics(base, {**base, "status": "diverged"})
    assert not identical_metrics(base, {**base, "verdict": "fail"})
    assert not identical_metrics(base, {**base, m: 2e-3})
    assert not identical_metrics(base, {**base, m: NAN})  # a value lost
    assert identical_metrics({**base, m: NAN}, {**base, m: None})  # missing alike


# -- a cost --------------------------------------------------------------------------------


def _cpu_row(fast, nstep, spread, tmax, engine_time=1.0):
    return {"engine_ns_per_step": fast, "nstep": nstep, "engine_time_spread_s": spread,
            "engine_time_max_s": tmax, "engine_time_s": engine_time}  # fmt: skip


def test_cost_range_of_cpu_times():
    """1000 ns/step over 1000 steps (1e6 ns per second of engine time): a spread of 1e-4 s is
    100 ns each way; the slowest repeat (1.05e-3 s: 1050 ns) is inside it, so the high end is
    1100; a spread wider than the cost leaves the low end at 0."""
    assert cost_range(_cpu_row(1000.0, 1000, 1e-4, 1.05e-3), "engine_ns_per_step") == (
        pytest.approx(1000.0), pytest.approx(900.0), pytest.approx(1100.0), False)  # fmt: skip
    lo = cost_range(_cpu_row(100.0, 1000, 1.5e-4, 1e-4), "engine_ns_per_step")[1]
    assert lo == 0.0
    # one step: 1e9 ns per second; a spread of 0.1 s is 1e8 ns
    one = cost_range(_cpu_row(5e8, 1, 0.1, 0.5), "engine_ns_per_step")
    assert one[1:3] == (pytest.approx(4e8), pytest.approx(6e8))
    # no step counted: no per-step range, and no fault
    zero = cost_range(_cpu_row(5e8, 0, 0.1, 0.5), "engine_ns_per_step")
    assert zero[0] == 5e8 and math.isnan(zero[2])


def test_cost_range_of_a_legacy_rows_wall_times():
    """Rows written before the costs were CPU times: the high end is the slowest repeat (or
    the kept timing without one), the low end the kept timing scaled by CPU / wall; without
    a CPU time the spread is known only from two repeats or more."""
    row = {"ns_per_step": 1000.0, "nstep": 1000, "wall_time_s": 2.0, "cpu_time_s": None,
           "timing_repeats": 2, "wall_time_max_s": 1.2e-3}  # fmt: skip
    assert cost_range(row, "ns_per_step") == (1000.0, 1000.0, pytest.approx(1200.0), False)
    one = cost_range({**row, "timing_repeats": 1}, "ns_per_step")
    assert one[0] == 1000.0 and math.isnan(one[1]) and math.isnan(one[2]) and one[3] is False
    no_max = {k: v for k, v in row.items() if k != "wall_time_max_s"}
    assert cost_range(no_max, "ns_per_step")[2] == 1000.0
    cpu = {**row, "cpu_time_s": 1.0}  # half the wall: the engine may have cost half
    assert cost_range(cpu, "ns_per_step")[1] == pytest.approx(500.0)
    assert cost_range({**row, "cpu_time_s": 0.0}, "ns_per_step")[1] == 0.0
    assert cost_range({**row, "cpu_time_s": 1.0, "wall_time_s": 0.0}, "ns_per_step")[1] == 1000.0


def test_classify_cost_at_its_edges():
    """factor 2: a ratio of exactly 2 or 1/2 is the same; beyond it, worse only when B's low
    end is beyond 2 x A's high end (exactly 2 x is not), better only when 2 x B's high end
    is below A's low end (exactly equal is not)."""
    a = (100.0, 90.0, 110.0)
    assert classify_cost(a, (200.0, 190.0, 210.0), 2.0) == (2.0, "same")
    assert classify_cost(a, (50.0, 40.0, 60.0), 2.0) == (0.5, "same")
    assert classify_cost(a, (75.0, 70.0, 80.0), 2.0) == (0.75, "same")
    assert classify_cost(a, (300.0, 220.0, 310.0), 2.0) == (3.0, "not significant")  # 220 = 2 x 110
    assert classify_cost(a, (300.0, 220.1, 310.0), 2.0) == (3.0, "worse")
    assert classify_cost(a, (30.0, 20.0, 45.0), 2.0) == (0.3, "not significant")  # 2 x 45 = 90
    assert classify_cost(a, (30.0, 20.0, 44.9), 2.0) == (0.3, "better")
    assert classify_cost((NAN, NAN, NAN), (NAN, NAN, NAN), 2.0) is None
    for one_sided in (((NAN, NAN, NAN), a), (a, (NAN, NAN, NAN)), ((0.0, 0.0, 0.0), a)):
        r, word = classify_cost(*one_sided, 2.0)
        assert math.isnan(r) and word == "same"


def test_a_cost_change_at_one_dt_only_is_not_significant():
    """corroborate_costs: better at one dt and the same at the other is not a change."""
    k1, k2 = ("s", "e", "i", 1e-3), ("s", "e", "i", 5e-4)
    for word in ("better", "worse"):
        cs = [Change(k1, "engine_ns_per_step", 1, 1, change=word),
              Change(k2, "engine_ns_per_step", 1, 1, change="same")]  # fmt: skip
        corroborate_costs(cs)
        assert [c.change for c in cs] == ["not significant", "same"]
    both = [Change(k, "ns_per_step", 1, 1, change="better") for k in (k1, k2)]
    corroborate_costs(both)
    assert [c.change for c in both] == ["better", "better"]


# -- an engine release ---------------------------------------------------------------------


def test_release_changes_are_counted_per_engine_and_pair():
    cmp = Comparison("a", "b", 2.0)
    key = ("sc", "mujoco", "RK4", 1e-3)
    a, b = {"engine_version": None}, {"engine_version": "4.0.1"}
    worse = [Change(key, "attitude_error_max", 1, 3, change="worse", gates=True)]
    better = [Change(key, "attitude_error_max", 3, 1, change="better")]
    for changes in (worse, worse, better, better, []):
        count_version_change(cmp, key, a, b, changes)
    vc = cmp.versions[("mujoco", "none", "4.0.1")]
    assert (vc.compared, vc.regressed, vc.better) == (5, 2, 2)
    assert vc.line().startswith("mujoco none -> 4.0.1: 5 runs compared, 4 changed")
    count_version_change(cmp, key, b, a, [])
    assert ("mujoco", "4.0.1", "none") in cmp.versions
    count_version_change(cmp, key, b, dict(b), [])  # the same release: not counted
    assert len(cmp.versions) == 2


def test_the_status_ranks_put_unavailable_engines_below_any_run():
    assert all(rule.STATUS_RANK[s] < rule.STATUS_RANK["unsupported"] for s in rule.RAN)
    assert rule.UNKNOWN_RANK > max(rule.STATUS_RANK.values())
