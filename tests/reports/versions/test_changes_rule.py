"""``director-bench versions``' decisions (reports/versions/changes.py) on version tables written
by hand (no store, no engine): which configurations are compared between two releases, what
changed and in which direction, when a cost change is real, which release a text names, what
the upgrade gate fails on. Every expected value is the module's rule applied by hand (factor
2: 10x is worse, 1.5x is within it)."""

from __future__ import annotations

import math

import pytest

from reports.store.runs import config_key
from reports.versions.changes import (
    COST_COLUMN,
    VersionTable,
    check,
    compare_versions,
    resolve_version,
)
from scenarios.schema import InputError

M = "attitude_error_max"


def _row(version, status="ok", verdict="pass", **values):
    r = {"status": status, "verdict": verdict, "verdict_detail": "", "message": "",
         "engine_version": version}  # fmt: skip
    if status == "ok":
        r[M] = 1e-3
    r.update(values)
    return r


def _key(integ, dt=1e-3, sc="top", acc=None):
    return config_key(sc, "mujoco", integ, dt, acc)


def _table(rows, factor=2.0, behaviour=None, versions=("1.0", "1.1")):
    return VersionTable("folder", factor, {"mujoco": list(versions)}, rows, behaviour or {})


def test_what_changes_between_two_releases():
    k = {n: _key(n) for n in ("Euler", "RK4", "implicit", "disc", "fast", "gone", "new", "v",
                              "same", "fail2", "lost")}  # fmt: skip
    rows = {
        (k["Euler"], "1.0"): _row("1.0"),
        (k["Euler"], "1.1"): _row("1.1", **{M: 1e-2}),
        (k["RK4"], "1.0"): _row("1.0"),
        (k["RK4"], "1.1"): _row("1.1", **{M: 1.5e-3}),
        (k["implicit"], "1.0"): _row("1.0"),
        (k["implicit"], "1.1"): _row("1.1", **{M: 1e-4}),
        (k["disc"], "1.0"): _row("1.0"),
        (k["disc"], "1.1"): _row("1.1", status="diverged", verdict="fail"),
        (k["gone"], "1.0"): _row("1.0"),
        (k["gone"], "1.1"): _row("1.1", status="unsupported", message="removed in 1.1"),
        (k["new"], "1.0"): _row("1.0", status="unsupported"),
        (k["new"], "1.1"): _row("1.1"),
        (k["v"], "1.0"): _row("1.0"),
        (k["v"], "1.1"): _row("1.1", verdict="fail", verdict_detail="attitude_error_max 1 > 0.1"),
        (k["same"], "1.0"): _row("1.0"),
        (k["same"], "1.1"): _row("1.1"),
        (k["fast"], "1.0"): _row("1.0", status="unsupported"),
        (k["fast"], "1.1"): _row("1.1", status="unsupported"),
        (k["fail2"], "1.0"): _row("1.0", verdict="fail", verdict_detail="x 2 > 1"),
        (k["fail2"], "1.1"): _row("1.1"),
        (k["lost"], "1.0"): _row("1.0"),
        (k["lost"], "1.1"): _row("1.1", status="unavailable", message="no wheel for 1.1"),
    }
    # another engine's runs under the same release labels are not this engine's
    dk = config_key("top", "drake", "Euler", 1e-3, None)
    rows[(dk, "1.0")], rows[(dk, "1.1")] = _row("1.0"), _row("1.1", **{M: 1.0})
    # a configuration of one release only, sorted first: the others are still compared
    rows[(_key("A0"), "1.1")] = _row("1.1")
    summary, changes = compare_versions(_table(rows), "mujoco", "1.0", "1.1")
    assert all(c.engine == "mujoco" for c in changes)
    by = {(c.integrator, c.column): c for c in changes}
    e = by["Euler", M]
    assert (e.kind, e.a, e.b, e.direction, e.from_version, e.to_version) == (
        "metric", 1e-3, 1e-2, "worse", "1.0", "1.1")  # fmt: skip
    assert e.ratio == pytest.approx(10.0) and e.gates and e.key == k["Euler"]
    assert ("RK4", M) not in by  # within the factor: not a change
    assert by["implicit", M].direction == "better" and not by["implicit", M].gates
    d = by["disc", "status"]
    assert (d.kind, d.a, d.b, d.ratio, d.direction, d.gates) == (
        "status", "ok", "diverged", None, "worse", True)  # fmt: skip
    back = {(c.integrator, c.column): c for c in compare_versions(_table(rows), "mujoco", "1.1",
                                                                  "1.0")[1]}  # fmt: skip
    assert back["disc", "status"].direction == "better"
    g = by["gone", "status"]
    assert (g.kind, g.a, g.b, g.direction, g.gates) == (
        "integrator", "ok", "unsupported: removed in 1.1", "vanished", True)  # fmt: skip
    n = by["new", "status"]
    assert (n.kind, n.a, n.b, n.direction, n.gates) == (
        "integrator", "unsupported", "ok", "new", False)  # fmt: skip
    v = by["v", "verdict"]
    assert (v.kind, v.a, v.b, v.direction) == (
        "verdict", "pass", "fail (attitude_error_max 1 > 0.1)", "worse")  # fmt: skip
    assert (by["fail2", "verdict"].a, by["fail2", "verdict"].b) == ("fail (x 2 > 1)", "pass")
    assert by["fail2", "verdict"].direction == "better"
    assert not any(c.integrator in ("same", "fast") for c in changes)
    # compared: all but the unavailable one; changed: Euler, implicit, disc, gone, new, v,
    # fail2; identical: same, fast (both unsupported); within: RK4
    assert (summary.compared, summary.changed, summary.identical, summary.within) == (10, 7, 2, 1)
    rows[(_key("R2"), "1.0")], rows[(_key("R2"), "1.1")] = _row("1.0"), _row("1.1", **{M: 1.4e-3})
    assert compare_versions(_table(rows), "mujoco", "1.0", "1.1")[0].within == 2
    assert summary.not_compared == [("top mujoco lost dt=0.001", "1.1: no wheel for 1.1")]
    assert (summary.engine, summary.from_version, summary.to_version) == ("mujoco", "1.0", "1.1")


def test_a_config_in_one_release_only_is_not_compared():
    rows = {(_key("Euler"), "1.0"): _row("1.0"), (_key("RK4"), "1.1"): _row("1.1")}
    summary, changes = compare_versions(_table(rows), "mujoco", "1.0", "1.1")
    assert (summary.compared, changes) == (0, [])
    unavailable_a = {(_key("E"), "1.0"): _row("1.0", status="unavailable", message="no wheel"),
                     (_key("E"), "1.1"): _row("1.1")}  # fmt: skip
    s2, _ = compare_versions(_table(unavailable_a), "mujoco", "1.0", "1.1")
    assert s2.not_compared == [("top mujoco E dt=0.001", "1.0: no wheel")]


def test_identical_needs_every_metric_status_and_verdict():
    def pair(a, b):
        rows = {(_key("E"), "1.0"): a, (_key("E"), "1.1"): b}
        s, ch = compare_versions(_table(rows, factor=1e9), "mujoco", "1.0", "1.1")
        return s.identical, s.within

    assert pair(_row("1.0"), _row("1.1")) == (1, 0)
    assert pair(_row("1.0"), _row("1.1", **{M: 2e-3})) == (0, 1)  # within a huge factor
    assert pair(_row("1.0", **{M: None}), _row("1.1", **{M: None})) == (1, 0)
    assert pair(_row("1.0", **{M: None}), _row("1.1")) == (0, 1)  # gained: the same, not identical
    assert pair(_row("1.0", status="error", verdict="fail"), _row("1.1", status="error")) == (0, 1)
    drift = "energy_drift_max"
    assert pair(_row("1.0", **{drift: 1e-3}), _row("1.1", **{drift: 1.5e-3})) == (0, 1)


def test_a_missing_order_is_not_a_change_and_behaviour_classes_are():
    k = _key("E")
    rows = {(k, "1.0"): _row("1.0", convergence_order=2.0), (k, "1.1"): _row("1.1")}
    _, ch = compare_versions(_table(rows), "mujoco", "1.0", "1.1")
    assert ch == []
    rows = {(k, "1.0"): _row("1.0", convergence_order=4.0),
            (k, "1.1"): _row("1.1", convergence_order=2.0)}  # fmt: skip
    (c,) = compare_versions(_table(rows), "mujoco", "1.0", "1.1")[1]
    assert (c.column, c.direction, c.ratio) == ("convergence_order", "worse", 0.5)

    def beh(ca, cb):
        b = {(k, "1.0"): {"class": ca}, (k, "1.1"): {"class": cb}}
        rows = {(k, "1.0"): _row("1.0"), (k, "1.1"): _row("1.1")}
        found = compare_versions(_table(rows, behaviour=b), "mujoco", "1.0", "1.1")[1]
        return [(c.kind, c.column, c.a, c.b, c.direction) for c in found]

    assert beh("conserved", "gaining") == [("behaviour", "energy error", "conserved", "gaining",
                                            "worse")]  # fmt: skip
    assert beh("losing", "conserved")[0][-1] == "better"
    assert beh("gaining", "losing")[0][-1] == "changed"
    assert beh("conserved", "noisy") == []  # not decisive
    assert beh("conserved", "conserved") == []


def _costs(per_version):
    """rows of one configuration swept over dts 1e-3, 5e-4, 2.5e-4 with the given cost per
    step (ns) per version and dt."""
    rows = {}
    for ver, costs in per_version.items():
        for dt, ns in zip((1e-3, 5e-4, 2.5e-4), costs, strict=True):
            rows[(_key("E", dt), ver)] = _row(ver, **{COST_COLUMN: ns})
    return rows


def test_a_cost_change_is_beyond_the_factor_the_sweeps_spread_and_at_every_dt():
    # 1000 ns at every dt -> 5000: 5x, spread 1 on both sides: worse, ratio 5, median values
    (c,) = [c for c in compare_versions(_table(_costs({"1.0": (1000, 1000, 1000),
            "1.1": (5000, 5000, 5000)})), "mujoco", "1.0", "1.1")[1]]  # fmt: skip
    assert (c.kind, c.column, c.a, c.b, c.ratio, c.direction, c.dt) == (
        "cost", COST_COLUMN, 1000.0, 5000.0, 5.0, "worse", None)  # fmt: skip
    assert not c.gates  # a cost gates only through check's cost_factor
    assert (c.scenario, c.engine, c.integrator, c.from_version, c.to_version) == (
        "top", "mujoco", "E", "1.0", "1.1")  # fmt: skip
    # 5x faster: better
    (c,) = compare_versions(_table(_costs({"1.0": (5000, 5000, 5000), "1.1": (1000, 1000, 1000)})),
                            "mujoco", "1.0", "1.1")[1]  # fmt: skip
    assert (c.ratio, c.direction) == (0.2, "better")
    # within the factor: nothing
    assert compare_versions(_table(_costs({"1.0": (1000,) * 3, "1.1": (1900,) * 3})), "mujoco",
                            "1.0", "1.1")[1] == []  # fmt: skip
    # a sweep spread of 2 on each side: noise 4; 3x is within it
    noisy = _costs({"1.0": (500, 1000, 1000), "1.1": (1500, 3000, 3000)})
    assert compare_versions(_table(noisy), "mujoco", "1.0", "1.1")[1] == []
    # median 5x, but one dt the same: not at every dt
    mixed = _costs({"1.0": (1000, 1000, 1000), "1.1": (1000, 5000, 5000)})
    assert compare_versions(_table(mixed), "mujoco", "1.0", "1.1")[1] == []
    # a single dt gives no spread: no cost change either way
    single = {
        (_key("E"), v): _row(v, **{COST_COLUMN: ns}) for v, ns in (("1.0", 1e3), ("1.1", 1e5))
    }
    assert compare_versions(_table(single), "mujoco", "1.0", "1.1")[1] == []
    # failed or zero costs are left out of the median and the ratios
    holes = _costs({"1.0": (1000, 1000, 0), "1.1": (5000, 5000, math.nan)})
    (c,) = compare_versions(_table(holes), "mujoco", "1.0", "1.1")[1]
    assert (c.a, c.b, c.ratio) == (1000.0, 5000.0, 5.0)


def _sweep(rows, ver, sc, integ, costs, dts=(1e-3, 5e-4, 2.5e-4), eng="mujoco"):
    for dt, ns in zip(dts, costs, strict=True):
        rows[(config_key(sc, eng, integ, dt, None), ver)] = _row(ver, **{COST_COLUMN: ns})
    return rows


def _cost_words(rows, factor=2.0):
    found = compare_versions(_table(rows, factor), "mujoco", "1.0", "1.1")[1]
    return [(c.scenario, c.integrator, c.direction) for c in found if c.kind == "cost"]


def test_cost_changes_at_the_edges_of_the_noise():
    """noise = max(factor, spread_a x spread_b): sweeps spread 2 on each side make it 4; a
    ratio of exactly 4 (or 1/4) is within it, 0.4 is not beyond 1/4."""
    r = _sweep(_sweep({}, "1.0", "s", "E", (500, 1000, 1000)), "1.1", "s", "E", (2000, 4000, 4000))
    assert _cost_words(r) == []
    r = _sweep(_sweep({}, "1.0", "s", "E", (2000, 4000, 4000)), "1.1", "s", "E", (500, 1000, 1000))
    assert _cost_words(r) == []
    r = _sweep(_sweep({}, "1.0", "s", "E", (2000, 4000, 4000)), "1.1", "s", "E", (800, 1600, 1600))
    assert _cost_words(r) == []
    # a factor of 1.2: 1.5x slower at every dt is worse
    r = _sweep(_sweep({}, "1.0", "s", "E", (1000,) * 3), "1.1", "s", "E", (1500,) * 3)
    assert _cost_words(r, factor=1.2) == [("s", "E", "worse")]
    # sub-nanosecond costs are costs (every positive finite one counts)
    r = _sweep(_sweep({}, "1.0", "s", "E", (0.05,) * 3), "1.1", "s", "E", (0.5,) * 3)
    assert _cost_words(r) == [("s", "E", "worse")]


def test_cost_changes_of_several_configurations_in_order():
    """Each (scenario, integrator) apart, sorted by scenario then integrator; a target-accuracy
    run, a configuration swept in one release only or timed at one dt are passed over and the
    others still judged."""
    r = {}
    _sweep(r, "1.0", "a", "Z", (1000,) * 3)
    _sweep(r, "1.1", "a", "Z", (5000,) * 3)
    _sweep(r, "1.0", "b", "A", (5000,) * 3)
    _sweep(r, "1.1", "b", "A", (1000,) * 3)
    for ver, ns in (("1.0", 1000), ("1.1", 9000)):  # a target accuracy on 'a' 'B' (skipped)
        r[(config_key("a", "mujoco", "B", 1e-3, 1e-6), ver)] = _row(ver, **{COST_COLUMN: ns})
        r[(config_key("a", "mujoco", "Z", 1e-3, 1e-6), ver)] = _row(ver, **{COST_COLUMN: ns})
    _sweep(r, "1.0", "a", "C", (1000,) * 3)  # swept in 1.0, one dt in 1.1
    _sweep(r, "1.1", "a", "C", (9000,), dts=(1e-3,))
    _sweep(r, "1.0", "a", "D", (1000,), dts=(1e-3,))  # one dt in 1.0
    _sweep(r, "1.1", "a", "D", (9000,) * 3)
    assert _cost_words(r) == [("a", "Z", "worse"), ("b", "A", "better")]


def test_paired_cost_ratios_at_every_dt_both_releases_timed():
    """The ratio at each dt both releases ran with a positive finite cost: a dt of one release
    only (here the smallest, sorted first), another integrator's runs, a zero or NaN cost on
    one side are left out; every ratio left must be beyond the factor the same way."""
    r = _sweep(_sweep({}, "1.0", "s", "E", (1000,) * 3), "1.1", "s", "E", (5000,) * 3)
    _sweep(r, "1.1", "s", "E", (5000,), dts=(1e-4,))  # 1.1 only
    _sweep(r, "1.0", "s", "A", (1000,) * 3)  # another integrator, sorted first
    _sweep(r, "1.1", "s", "A", (1100,) * 3)
    _sweep(r, "1.0", "s", "E", (0.0,), dts=(2e-3,))  # a zero on one side
    _sweep(r, "1.1", "s", "E", (5000.0,), dts=(2e-3,))
    _sweep(r, "1.0", "s", "E", (1000.0,), dts=(4e-3,))  # a NaN on the other
    _sweep(r, "1.1", "s", "E", (math.nan,), dts=(4e-3,))
    _sweep(r, "1.0", "s", "E", (1000.0,), dts=(8e-3,))  # a zero on the other
    _sweep(r, "1.1", "s", "E", (0.0,), dts=(8e-3,))
    assert _cost_words(r) == [("s", "E", "worse")]
    dk = config_key("s", "drake", "E", 1e-3, None)  # another engine, same labels: not paired
    r[(dk, "1.0")], r[(dk, "1.1")] = _row("1.0", **{COST_COLUMN: 5000}), _row("1.1", **{
        COST_COLUMN: 1000})  # fmt: skip
    assert _cost_words(r) == [("s", "E", "worse")]


def test_error_controlled_runs_and_unsupported_ones_have_no_cost_change():
    rows = {}
    for ver, ns in (("1.0", 1000), ("1.1", 9000)):
        for acc in (1e-6, 1e-8):
            rows[(_key("RK45", acc=acc), ver)] = _row(ver, **{COST_COLUMN: ns})
        for dt in (1e-3, 5e-4):
            rows[(_key("U", dt), ver)] = _row(ver, status="unsupported", **{COST_COLUMN: ns})
    assert [c for c in compare_versions(_table(rows), "mujoco", "1.0", "1.1")[1]
            if c.kind == "cost"] == []  # fmt: skip
    diverged = _costs({"1.0": (1000,) * 3, "1.1": (5000,) * 3})
    for r in diverged.values():
        r["status"], r["verdict"] = "diverged", "fail"
    (c,) = [c for c in compare_versions(_table(diverged), "mujoco", "1.0", "1.1")[1]
            if c.kind == "cost"]  # fmt: skip
    assert c.ratio == 5.0  # a diverged run's steps were timed too


def test_versions_are_named_by_engine_bare_or_oldest_newest():
    tab = VersionTable("f", 2.0, {"mujoco": ["3.0", "3.1"], "drake": ["1.0", "3.1"]}, {})
    assert resolve_version(tab, "mujoco==3.0") == ("mujoco", "3.0")
    assert resolve_version(tab, " mujoco == newest ") == ("mujoco", "3.1")
    assert resolve_version(tab, "drake==oldest") == ("drake", "1.0")
    assert resolve_version(tab, "1.0") == ("drake", "1.0")
    held = "the folder holds mujoco: 3.0, 3.1; drake: 1.0, 3.1"
    with pytest.raises(InputError, match=rf"^--check '3.1': is held by several engines; write "
                       rf"ENGINE==VERSION \({held}\)$"):  # fmt: skip
        resolve_version(tab, "3.1")
    with pytest.raises(InputError, match=rf"^--check 'mujoco==9': is not held \({held}\)$"):
        resolve_version(tab, "mujoco==9")
    with pytest.raises(InputError, match="is not held"):
        resolve_version(tab, "pinocchio==3.0")
    with pytest.raises(InputError, match="several engines"):
        resolve_version(tab, "newest")
    one = VersionTable("f", 2.0, {"mujoco": ["3.0", "3.1", "3.2"]}, {})
    assert resolve_version(one, "oldest") == ("mujoco", "3.0")
    assert resolve_version(one, "newest") == ("mujoco", "3.2")
    with pytest.raises(InputError, match="is not held"):
        resolve_version(one, "mujoco==3.0==3.1")
    empty = VersionTable("f", 2.0, {}, {})
    with pytest.raises(InputError, match=r"is not held \(the folder holds nothing\)$"):
        resolve_version(empty, "3.0")


def test_the_upgrade_gate():
    k = _key("E")
    worse = {(k, "1.0"): _row("1.0"), (k, "1.1"): _row("1.1", **{M: 1e-2})}
    res = check(_table(worse), "mujoco==1.0", "mujoco==1.1")
    assert (res.engine, res.from_version, res.to_version, res.factor) == ("mujoco", "1.0", "1.1",
                                                                          2.0)  # fmt: skip
    assert not res.ok and [c.column for c in res.failures] == [M]
    better = {(k, "1.0"): _row("1.0", **{M: 1e-2}), (k, "1.1"): _row("1.1")}
    assert check(_table(better), "1.0", "1.1").ok
    slow = _costs({"1.0": (1000,) * 3, "1.1": (5000,) * 3})
    assert check(_table(slow), "1.0", "1.1").ok  # a cost alone does not gate
    gated = check(_table(slow), "1.0", "1.1", cost_factor=4.0)
    assert not gated.ok and gated.cost_factor == 4.0 and gated.failures[0].kind == "cost"
    assert check(_table(slow), "1.0", "1.1", cost_factor=5.0).ok  # 5x is not beyond 5
    lost = {(k, "1.0"): _row("1.0"), (k, "1.1"): _row("1.1", status="unavailable", message="x")}
    assert not check(_table(lost), "1.0", "1.1").ok  # a configuration not compared
    two = VersionTable("f", 2.0, {"mujoco": ["1.0"], "drake": ["2.0"]}, {})
    with pytest.raises(InputError, match=r"^--check 1.0 2.0: two different engines \(mujoco, "
                       r"drake\)$"):  # fmt: skip
        check(two, "1.0", "2.0")
