"""The progress display: a log gets plain lines (no carriage return), a tenth of the work at a
time; compilation is named while it lasts and kept out of the estimate; the first runs of
each warm-up are handed out first."""

from __future__ import annotations

import io
import re

from reports.run.progress import Progress


def test_outside_a_terminal_one_line_per_tenth_and_no_carriage_return():
    log = io.StringIO()
    bar = Progress(441, warming={"director": "the director kernels (numba)"}, stream=log)
    for i in range(441):
        bar.update(1, key="director" if i == 0 else None, label=f"run {i}")
        bar.set_postfix_str("a running run at 50%")
    bar.close()
    text = log.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    # a first line naming what compiles, one per tenth reached before the end (10 % .. 90 %),
    # and the last line
    assert len(lines) == 1 + 9 + 1, lines
    assert (
        "first, loaded from the compiler's cache or compiled: the director kernels (numba)"
        in lines[0]
    )
    assert re.match(r"director-bench: 441/441 runs in \d+:\d\d$", lines[-1])
    percents = [int(m) for m in re.findall(r"\((\d+) %\)", text)]
    assert percents == sorted(percents) and len(percents) == 9


def test_compiling_is_named_until_the_first_run_of_each_warm_up_and_has_no_estimate(monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # a line is cut to the terminal's width
    log = io.StringIO()
    warming = {"mjx/Euler": "MJX's step (JAX) for mjx Euler", "rkmk4": "the RKMK4 stages"}
    bar = Progress(100, warming=warming, stream=log, terminal=True)
    for _ in range(10):
        bar.update(1)
    frame = log.getvalue().split("\r")[-1]
    assert "loading or compiling MJX's step (JAX) for mjx Euler, the RKMK4 stages" in frame
    assert bar.eta() is None
    bar.update(1, key="mjx/Euler")
    assert "loading or compiling the RKMK4 stages" in log.getvalue().split("\r")[-1]
    assert bar.eta() is None
    bar.update(1, key="rkmk4")  # the warm-ups are over: the estimate starts from here
    assert bar.n_warm == 12 and bar.eta() is None
    bar.update(1)
    assert bar.eta() is not None and "left" in log.getvalue().split("\r")[-1]
    bar.close()
    assert log.getvalue().endswith("\n")


def test_the_first_run_of_each_warm_up_goes_first():
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import bundles, warm_up

    specs = plan([scenarios.load("dzhanibekov")], ["director", "mujoco", "pinocchio", "mjx"])
    order = bundles(specs)
    keys = [warm_up(b[0].engine, b[0].integrator) for b in order]
    firsts = [k[0] for k in keys if k is not None]
    distinct = list(dict.fromkeys(firsts))
    # every warm-up key opens with its first bundle, before any second run of any key
    assert firsts[: len(distinct)] == distinct
    assert {"director", "rkmk4", "mjx/Euler (float64)", "mjx/RK4 (float32)"} <= set(distinct)
    # the compilations holding back the most runs start first (the process pool never runs
    # two of one key at once, so these are the chains that would otherwise run last)
    held = [sum(1 for s in specs if (warm_up(s.engine, s.integrator) or ("",))[0] == k)
            for k in distinct]  # fmt: skip
    assert held == sorted(held, reverse=True) and distinct[0] == "director", (distinct, held)
    assert sorted(map(id, (s for b in order for s in b))) == sorted(map(id, specs))


def test_nothing_to_show_shows_nothing_and_a_terminal_line_fits(monkeypatch):
    for kwargs in ({"total": 0}, {"total": 5, "disable": True}):
        for terminal in (False, True):
            log = io.StringIO()
            bar = Progress(**kwargs, stream=log, terminal=terminal)
            bar.update(1)
            bar.set_postfix_str("x")
            bar.close()
            assert log.getvalue() == ""
    monkeypatch.setenv("COLUMNS", "60")
    log = io.StringIO()
    bar = Progress(1000, warming={"a": "a very long description of what compiles " * 3})
    bar.stream, bar.terminal = log, True
    for i in range(1000):
        bar.update(1, key="a" if i == 500 else None, label="scenario/engine/integrator " * 4)
    frames = log.getvalue().split("\r")
    assert max(len(f.rstrip()) for f in frames) <= 59


def test_warm_ups_of_bundled_runs_are_named_at_the_start_and_do_not_hold_the_estimate(capsys):
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import _bar

    bar = _bar(plan([scenarios.load("dzhanibekov")], ["director", "mjx"]))
    assert list(bar.warming) == ["director"]  # MJX's rows arrive with their bundle's end
    first = capsys.readouterr().err  # standard error is no terminal here: the first line
    assert (
        "first, loaded from the compiler's cache or compiled: the director kernels (numba)" in first
    )
    assert "at the start of their bundles: MJX's step (JAX) for mjx Euler (float64)" in first
    bar.update(1, key="director")
    assert bar.t_warm is not None


def test_a_system_of_bodies_names_its_kernels_and_its_reference():
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import _bar, bundles, unit_warm_ups, warm_ups

    specs = plan([scenarios.load("four_bar"), scenarios.load("dzhanibekov")], ["director"])
    system = next(s for s in specs if s.scenario.name == "four_bar")
    body = next(s for s in specs if s.scenario.name == "dzhanibekov")
    assert warm_ups(system) == {
        "director/system": "the system kernels (numba)",
        "multibody": "the multibody reference (numba)",
    }
    assert warm_ups(body) == {"director": "the director kernels (numba)"}
    bar = _bar(specs)
    assert set(bar.warming) == {"director", "director/system", "multibody"}
    bar.update(1, key=("director/system", "multibody"))  # one run ends two warm-ups
    assert set(bar.warming) == {"director"} and bar.t_warm is None
    bar.update(1, key=("director",))
    assert bar.t_warm is not None
    order = bundles(specs)
    leads = [unit_warm_ups(b) for b in order[:2]]
    assert {"director"} in leads and {"director/system", "multibody"} in leads
    assert sorted(map(id, (s for b in order for s in b))) == sorted(map(id, specs))


def test_a_contact_scene_names_its_own_kernels_apart_from_the_systems():
    # the director's contact kernels compile apart from its system kernels: under the
    # systems' key, a contact run would start in a second worker while the first compiles
    # the same kernels (both paying the whole compilation), and the display would name no
    # compilation while it lasted
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import _bar, warm_ups

    specs = plan([scenarios.load("sphere_backspin"), scenarios.load("four_bar")], ["director"])
    contact = next(s for s in specs if s.scenario.name == "sphere_backspin")
    system = next(s for s in specs if s.scenario.name == "four_bar")
    assert warm_ups(contact) == {"director/contact": "the contact kernels (numba)"}
    assert "director/contact" not in warm_ups(system)
    bar = _bar(specs)
    assert bar.warming["director/contact"] == "the contact kernels (numba)"


def test_the_pool_hands_out_no_unit_whose_compilation_is_under_way():
    from reports.run.parallel import _Gate

    keys = {"a1": {"a"}, "a2": {"a"}, "b1": {"b"}, "ab": {"a", "b"}, "x": set(), "y": set()}
    gate = _Gate(list(keys), keys.get)
    first, second, third = gate.next(), gate.next(), gate.next()
    # a1 compiles a, b1 compiles b; a2 and ab must wait; x needs nothing
    assert [first[0], second[0], third[0]] == ["a1", "b1", "x"]
    assert first[1] == {"a"} and second[1] == {"b"} and third[1] == set()
    assert gate.next()[0] == "y"
    assert gate.next() == (None, set())  # everything left waits for a or b
    gate.compiled(first[1])
    unit, compiling = gate.next()
    assert unit == "a2" and compiling == set()  # a is compiled: its cache is loaded
    assert gate.next() == (None, set())  # ab still waits for b
    gate.compiled(second[1])
    assert gate.next() == ("ab", set()) and not gate.pending


def test_a_bundle_holds_only_its_engines_warm_up_and_runs_its_systems_last():
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import bundles, unit_warm_ups

    scs = [scenarios.load("four_bar"), scenarios.load("dzhanibekov")]
    specs = plan(scs, ["mjx", "mujoco"])
    order = bundles(specs)
    mjx = [b for b in order if len(b) > 1]
    assert mjx and all(b[0].engine == "mjx" for b in mjx)
    for b in mjx:
        kinds = [s.scenario.kind != "body" for s in b]
        assert kinds == sorted(kinds) and kinds[-1] and not kinds[0]  # bodies, then systems
        assert unit_warm_ups(b) == {f"mjx/{b[0].integrator}"}  # not the systems' reference
    # the reference's leader is a single run, which holds it only while it runs
    lead = next(b for b in order if "multibody" in unit_warm_ups(b))
    assert len(lead) == 1 and lead[0].scenario.name == "four_bar"


def test_the_clock_of_a_terminal_display_runs_while_nothing_finishes(monkeypatch):
    import time

    from reports.run import progress

    monkeypatch.setattr(progress, "TICK_S", 0.05)
    log = io.StringIO()
    bar = Progress(10, warming={"a": "the kernels"}, stream=log, terminal=True)
    t = time.monotonic()
    monkeypatch.setattr(progress.time, "monotonic", lambda: t + 61.0)  # a minute later
    time.sleep(0.3)  # no update: the clock thread alone redraws
    frame = log.getvalue().split("\r")[-1]
    bar.close()
    assert "[1:01]" in frame and "loading or compiling the kernels" in frame, frame


def test_outside_a_terminal_one_line_per_finished_group_with_its_outcomes():
    from reports.run.progress import Item

    items = {f"{g}{k}": Item(g, "c", 100.0) for g in "ab" for k in range(3)}
    log = io.StringIO()
    bar = Progress(len(items), stream=log, items=items)
    for i, key in enumerate(sorted(items)):
        bar.update(1, item=key, seconds=0.1, outcome="pass" if i % 3 else "fail")
    bar.close()
    lines = log.getvalue().splitlines()
    assert len(lines) == 1 + 2 + 1, lines
    assert lines[1].startswith("director-bench: a done (1 fail, 2 pass); 3/6 runs (50 %)")
    assert lines[2].startswith("director-bench: b done (1 fail, 2 pass); 6/6 runs (100 %)")


def test_the_estimate_prices_what_is_left_per_configuration():
    from reports.run.progress import Estimate, Item

    # config "slow" costs 1 s per 100 steps, "fast" 0.1 s; none compiled
    items = {f"s{k}": Item("g", "slow", 100.0) for k in range(4)}
    items |= {f"f{k}": Item("g", "fast", 100.0) for k in range(10)}
    items["new"] = Item("g", "unseen", 300.0)
    est = Estimate(items)
    for key, secs in (("s0", 1.0), ("f0", 0.1), ("f1", 0.1), ("f2", 0.1)):
        est.finished(key, secs, measured=True, counts=True)
    # every run pays the quickest run's 0.1 s, plus its steps at its configuration's rate of
    # the rest: slow 0.9 s / 100 steps, fast 0; an unseen configuration at the median rate,
    # 0.0045 s per step. Left: 3 slow (3 s), 7 fast (0.7 s), the new one 0.1 + 1.35 s:
    # 5.15 s of runs; measured 1.3 s of runs in 2.6 s: one busy worker in two (throughput
    # 0.5): 10.3 s of time
    assert abs(est.left_s(2.6) - 10.3) < 1e-9
    # a run that compiled is not a rate
    est.finished("s1", 100.0, measured=False, counts=True)
    assert abs(est.left_s(2.6) - (2.0 + 0.7 + 1.45) / 0.5) < 1e-9
    assert Estimate(items).left_s(10.0) is None  # nothing measured yet


def test_an_expensive_configuration_does_not_price_the_unseen_ones():
    # the default suite's rates span three orders of magnitude (a contact scene's steps
    # against MuJoCo's): the mean rate priced every configuration not seen yet like the
    # expensive one, the estimate of a warm default run 4.6 times the time left at 20 %
    from reports.run.progress import Estimate, Item

    items = {f"{c}{k}": Item("g", c, 1000.0) for c in "abcd" for k in range(2)}
    items["new"] = Item("g", "unseen", 1000.0)
    est = Estimate(items)
    for c, secs in (("a", 0.01), ("b", 0.02), ("c", 0.03), ("d", 10.0)):
        est.finished(f"{c}0", secs, measured=True, counts=True)
    # fixed 0.01 s; rates per step 0, 1e-5, 2e-5, 9.99e-3: the median 1.5e-5 prices "new"
    left = 0.01 + 0.02 + 0.03 + 10.0 + (0.01 + 1000 * 1.5e-5)
    assert abs(est.left_s(4.0) - left / (10.06 / 4.0)) < 1e-9


def test_a_timing_pass_is_priced_as_a_share_of_its_scenarios_runs():
    # a scenario's timing pass spends at most a share of what its runs spent stepping
    # (reports.run.timing.BUDGET_FACTOR): priced so, never per step like a run
    from reports.run import runner
    from reports.run.progress import Estimate, Item
    from reports.run.timing import BUDGET_FACTOR

    items = {f"r{k}": Item("g", "c", 100.0) for k in range(4)}
    items["pass"] = Item("g", ("timing",), 400.0, share=0.5)
    est = Estimate(items)
    for k in range(3):
        est.finished(f"r{k}", 1.0, measured=True, counts=True)
    # r3 priced at 1.0 s (every run took 1 s: all of it fixed); the pass half of 4 s
    assert abs(est.left_s(3.0) - (1.0 + 0.5 * 4.0) / 1.0) < 1e-9
    est.finished("pass", 2.0, measured=True, counts=True)  # not a rate of ("timing",)
    assert ("timing",) not in est.seconds
    # once a pass has finished, the others are priced at the share the finished ones took
    # (a budget is a bound: the passes of a warm default run took about a fifth of it)
    items = {f"{g}{k}": Item(g, "c", 100.0) for g in "ab" for k in range(2)}
    items |= {f"pass-{g}": Item(g, ("timing",), 200.0, share=0.5) for g in "ab"}
    est = Estimate(items)
    for key in ("a0", "a1", "b0"):
        est.finished(key, 1.0, measured=True, counts=True)
    est.finished("pass-a", 0.2, measured=True, counts=True)  # 10 % of a's 2 s
    # left: b1 (1 s) and b's pass at 10 % of 2 s; throughput 3.2 s of runs in 3.2 s
    assert abs(est.left_s(3.2) - (1.0 + 0.1 * 2.0)) < 1e-9
    import scenarios
    from reports.run.plan import plan

    specs = plan([scenarios.load("dzhanibekov")], ["mujoco"])
    units, passes = runner.with_timing_passes(runner.bundles(specs))
    bar = runner._bar(specs, passes)
    assert bar.items["timing", "dzhanibekov"].share == BUDGET_FACTOR
    bar.close()


def test_a_unit_that_needs_other_work_waits_until_it_is_back():
    from reports.run.parallel import _Gate

    units = ["r1", "r2", "t", "r3"]
    needs = {"t": {"r1", "r2"}}
    gate = _Gate(units, None, lambda u: needs.get(u, ()), lambda u: {u})
    assert [gate.next()[0] for _ in range(3)] == ["r1", "r2", "r3"]
    assert gate.next() == (None, set())  # t waits for r1 and r2
    gate.compiled(set(), "r1")
    assert gate.next() == (None, set())
    gate.compiled(set(), "r2")
    assert gate.next()[0] == "t" and not gate.pending


def test_each_scenarios_timing_pass_follows_its_last_run():
    import scenarios
    from reports.run.plan import plan
    from reports.run.runner import bundles, with_timing_passes
    from reports.run.timing import TimingUnit

    specs = plan([scenarios.load("cone_top"), scenarios.load("four_bar")], ["mujoco", "exact"])
    units, passes = with_timing_passes(bundles(specs))
    assert sorted(passes) == ["cone_top", "four_bar"]  # bodies and systems alike
    for name, unit in passes.items():
        (i,) = [k for k, u in enumerate(units) if u is unit]
        before = {s.run_id for u in units[:i] if not isinstance(u, TimingUnit) for s in u}
        # the scenario's runs but the exact reference's, every one handed out before it
        timed = {s.run_id for s in specs if s.scenario.name == name and s.engine == "mujoco"}
        assert unit.needs == timed <= before
        after = [s for u in units[i + 1 :] if not isinstance(u, TimingUnit) for s in u]
        assert not any(s.scenario.name == name and s.engine != "exact" for s in after)


def test_planning_shows_a_running_clock_in_a_terminal_and_nothing_in_a_log(monkeypatch):
    # planning compiles the multibody reference from a fresh clone (the systems' pilot
    # runs): a terminal must see a clock that moves meanwhile, a log only the notes
    import io
    import time

    from reports.run import progress

    monkeypatch.setattr(progress, "TICK_S", 0.05)
    t = [0.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: t[0])
    tty = io.StringIO()
    with progress.Clock("director-bench: planning the runs", stream=tty, terminal=True) as c:
        for k in range(1, 4):  # the block holds the main thread; the clock's thread redraws
            t[0] = 60.0 * k
            time.sleep(0.3)
        c.note("director-bench: note: a pilot")
    shown = tty.getvalue()
    for clock in ("0:00", "1:00", "2:00", "3:00"):
        assert f"director-bench: planning the runs [{clock}]" in shown
    assert "\rdirector-bench: note: a pilot\n" in shown  # the clock's line erased first
    assert shown.endswith("\r")  # erased: the progress display takes the line
    log = io.StringIO()
    with progress.Clock("director-bench: planning the runs", stream=log, terminal=False) as c:
        c.note("director-bench: note: a pilot")
    assert log.getvalue() == "director-bench: note: a pilot\n"
