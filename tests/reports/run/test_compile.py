"""``director-bench compile`` (reports.run.compile): which short runs it makes of the default
suite, and what its listener says numba compiled.

That a run after ``compile`` compiles nothing is shown by benchmarks/bench_first_run.py (its
probe counts numba's compilations in every process of the run: 0 after compile), a whole
default suite from a fresh clone, too long for a test."""

from __future__ import annotations

import os

import pytest

from reports.cli import main
from reports.run import compile as ahead
from reports.run.runner import warm_ups


@pytest.fixture(scope="module")
def default_specs():
    from reports.run.plan import max_states, plan
    from reports.suite import check_engines, check_integrators, default_engines, resolve_scenarios

    engines, _ = default_engines()
    engines = check_engines(engines)
    integrators = check_integrators(None, engines, False)
    scs = resolve_scenarios(())
    return plan(scs, engines, integrators, None, None, False, None, None, None, max_states(2))


def test_every_configuration_that_compiles_gets_one_short_run(default_specs):
    work = ahead.units(default_specs)
    got = [(s.scenario.name, s.engine, s.integrator) for u in work for s in u]
    assert len(got) == len(set(got)), "a configuration compiled twice"
    # what the runs of the default suite compile: every configuration with a warm-up of
    # its own (the director's kernels, the multibody reference, the suite's RKMK4), MJX
    # (JAX, cached by JAX itself) and error-controlled runs (no numba) apart
    wanted = {
        (s.scenario.name, s.engine, s.integrator)
        for s in default_specs
        if warm_ups(s) and s.engine != "mjx" and s.accuracy is None
    }
    assert set(got) == wanted
    kinds = {s.scenario.kind for u in work for s in u}
    assert kinds == {"body", "system", "contact"}
    for unit in work:
        assert len({frozenset(warm_ups(s)) for s in unit}) == 1, "a unit mixes warm-ups"
        for s in unit:
            assert s.keep == "none" and s.segment is None
            steps = s.horizon / s.dt
            assert steps == pytest.approx(s.saving * ahead.SHORT_SAVES)
            assert s.horizon < s.scenario.t_end
    # the longest compilations start first: the contact kernels, then the systems'
    order = [min(ahead.KIND_ORDER[s.scenario.kind] for s in u) for u in work]
    assert order == sorted(order) and order[0] == ahead.KIND_ORDER["contact"]


def test_the_listener_names_each_compilation_once(capsys):
    from numba import njit

    @njit
    def twice(x):
        return 2.0 * x

    ahead.listen()
    try:
        ahead.drain()
        assert twice(1.5) == 3.0
        got = ahead.drain()
        assert [name.rsplit(".", 1)[-1] for name, _ in got] == ["twice"]
        assert got[0][1] >= 0.0
        assert twice(2.5) == 5.0  # compiled already: no event
        assert twice(3) == 6.0  # another signature: compiled again
        assert len(ahead.drain()) == 1
        err = capsys.readouterr().err
        assert "compiling " in err and "twice" in err and "s CPU)" in err
    finally:
        ahead.stop()  # the other tests of this process print nothing of numba's
    assert twice(4 + 1j) == 8 + 2j  # compiled with no listener: no record, no line
    assert ahead.drain() == [] and "twice" not in capsys.readouterr().err


def test_bad_jobs_is_a_clear_error(capsys):
    assert main(["compile", "--jobs", str(4 * (os.cpu_count() or 1) + 1)]) == 2
    assert "--jobs" in capsys.readouterr().err
