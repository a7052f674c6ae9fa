"""Work-precision answers (reports.report.precision): a level reached, not tried (the error
still falling at the smallest step run) or not reached (nothing finished, a floor), and the
cost a configuration is ranked by."""

from __future__ import annotations

import math

from reports.report.precision import cost_of, outlook


def runs(errors: dict, status=None, **common):
    """Rows of one fixed-step configuration: {dt: max attitude error}."""
    status = status or {}
    return [
        dict(
            dt=dt,
            attitude_error_max=e,
            reference_accuracy=1e-13,
            status=status.get(dt, "ok"),
            target_accuracy=math.nan,
            engine_time_s=1e-3 / dt,
            **common,
        )  # fmt: skip
        for dt, e in errors.items()
    ]


def test_reached_is_the_cheapest_run_within_the_level():
    rows = runs({4e-3: 1e-3, 2e-3: 6e-5, 1e-3: 4e-6})
    word, row = outlook(rows, 1e-4)
    assert word == "reached" and row["dt"] == 2e-3  # 2e-3 is cheaper than 1e-3


def test_still_falling_at_the_smallest_step_is_not_tried_with_the_step_that_would_do():
    # order 4 over the last halving (6.4e-5 -> 4e-6, 16x): 1e-8 needs (1e-8/4e-6)^(1/4) of
    # 1e-3, 2.24e-4
    word, text = outlook(runs({2e-3: 6.4e-5, 1e-3: 4e-6}), 1e-8)
    assert word == "not tried"
    assert text == "4e-6 rad at dt 0.001; about dt 2.2e-4 would", text


def test_a_floor_or_nothing_finished_does_not_reach():
    word, text = outlook(runs({2e-3: 3e-7, 1e-3: 2.9e-7}), 1e-8)  # the error stopped falling
    assert (word, text) == ("does not reach", "stalls at 2.9e-7 rad")
    word, text = outlook(runs({2e-3: 0.5, 1e-3: 0.4}, {2e-3: "diverged", 1e-3: "diverged"}), 1)
    assert (word, text) == ("does not reach", "no run finished")
    # its smallest step diverged where a larger one finished: not a matter of the sweep
    word, text = outlook(runs({2e-3: 1e-3, 1e-3: 9.0}, {1e-3: "diverged"}), 1e-6)
    assert word == "does not reach" and "diverged below dt 0.002" in text


def test_an_error_below_the_references_accuracy_reaches_no_level_below_it():
    rows = runs({1e-3: 1e-15})  # reference accurate to 1e-13
    assert outlook(rows, 1e-12)[0] == "reached"
    assert outlook(rows, 1e-14)[0] != "reached"


def test_a_configuration_whose_time_loop_is_the_suites_is_ranked_by_its_whole_step():
    row = {"engine_time_s": 1e-3, "cpu_time_s": 8e-3, "wall_time_s": 9e-3}
    assert cost_of(row) == 1e-3
    assert cost_of({**row, "suite_integrated": True}) == 8e-3
    assert cost_of({"wall_time_s": 9e-3}) == 9e-3  # a folder written before


def test_a_cost_measured_starved_says_so():
    # an engine time known within 5 % is a measurement; within 30 %, starved (the rule:
    # references.costs.STARVED, 10 %)
    from reports.report.sections import wp_cost
    from reports.store.format import fmt
    from reports.store.runs import starved

    row = {"engine_time_s": 1e-3, "engine_time_spread_s": 5e-5}
    assert not starved(row)
    assert starved({**row, "engine_time_spread_s": 3e-4})
    assert not starved({"engine_time_s": 1e-3})  # a row without a spread: not measured so
    entry = {"suite_integrated": False, "cost_s": 1e-3, "engine_time_s": 1e-3}
    assert wp_cost({**entry, "starved": False}) == f"{fmt(1e-3)} s"
    assert wp_cost({**entry, "starved": True}) == f"{fmt(1e-3)} s (starved)"
