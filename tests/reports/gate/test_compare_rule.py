"""``director-bench compare``'s decisions (reports/gate/compare.py) on results folders written
row by row for the purpose (no engine runs): which runs are compared, which change, how the
counts and the verdict come out. Each folder holds rows of the library's free_tumbling at
chosen steps with planted values; every expected word is the rule of reports/gate/rule.py
applied by hand (a factor 2: 10x worse is ``worse``, 1.5x is ``same``)."""

from __future__ import annotations

import math
import re

import pytest

import scenarios
from reports.gate.compare import _counts, _shown, _verdict, compare_folders
from reports.gate.rule import NothingComparable
from reports.store.results import Store
from reports.store.runs import RunSpec, blank_row, finish_time
from scenarios.schema import InputError

M = "attitude_error_max"


@pytest.fixture(scope="module")
def sc():
    return scenarios.load("free_tumbling")


def _row(sc, integ, dt=1e-3, status="ok", verdict="pass", version="1.0", t_end=None,
         accuracy=None, **values):  # fmt: skip
    row = blank_row(RunSpec(sc, "mujoco", integ, dt, t_end=t_end, engine_version=version,
                            accuracy=accuracy))  # fmt: skip
    row.update(status=status, verdict=verdict if status in ("ok", "diverged") else "",
               finished_at=finish_time(), nstep=1000)  # fmt: skip
    if status == "ok":
        row.update({M: 1e-3, "energy_drift_max": 1e-3})
    row.update(values)
    return row


def _folder(path, rows):
    path.mkdir(parents=True, exist_ok=True)
    with Store(path, create=True) as st:
        for r in rows:
            st.put(r)
    return path


def _key(c):
    return c.key[2], c.key[3], c.column


def test_each_kind_of_change_between_two_folders(tmp_path, sc):
    # a folder holds one horizon per scenario: the mismatched run is another scenario's, one
    # that sorts first (every run after it is still compared)
    heavy = scenarios.load("dzhanibekov")
    a = _folder(tmp_path / "a", [
        _row(sc, "Euler"),                                    # 10x worse in B
        _row(sc, "RK4"),                                      # 1.5x: the same
        _row(sc, "implicit"),                                 # 10x better in B
        _row(sc, "discrete", status="ok"),                    # diverges in B
        _row(sc, "implicitfast", status="unsupported"),       # the environment in B
        _row(sc, "Euler", dt=5e-4),                           # only in A
        _row(heavy, "RK4", t_end=2.0, save_every=10),         # another run in B: mismatch
    ])  # fmt: skip
    b = _folder(tmp_path / "b", [
        _row(sc, "Euler", **{M: 1e-2}),
        _row(sc, "RK4", **{M: 1.5e-3}),
        _row(sc, "implicit", **{M: 1e-4}),
        _row(sc, "discrete", status="diverged", verdict="fail"),
        _row(sc, "implicitfast", status="ok"),
        _row(heavy, "RK4", t_end=3.0, save_every=20),
        _row(sc, "Euler", dt=2.5e-4),                         # only in B
    ])  # fmt: skip
    cmp = compare_folders(a, b)
    assert [k[0::2][:2] + (k[3],) for k in cmp.compared] == [
        ("dzhanibekov", "RK4", 1e-3), ("free_tumbling", "Euler", 1e-3),
        ("free_tumbling", "RK4", 1e-3), ("free_tumbling", "discrete", 1e-3),
        ("free_tumbling", "implicit", 1e-3), ("free_tumbling", "implicitfast", 1e-3)]  # fmt: skip
    assert (cmp.a, cmp.b, cmp.factor, cmp.cost_factor, cmp.vary) == (a, b, 2.0, None, ())
    assert [(k[2], k[3], s) for k, s in cmp.only_a] == [("Euler", 5e-4, "ok")]
    assert [(k[2], k[3], s) for k, s in cmp.only_b] == [("Euler", 2.5e-4, "ok")]
    by = {_key(c): c for c in cmp.changes}
    euler = by["Euler", 1e-3, M]
    assert (euler.change, euler.gates, euler.a, euler.b) == ("worse", True, 1e-3, 1e-2)
    assert euler.ratio == pytest.approx(10.0)
    assert by["RK4", 1e-3, M].change == "same"
    assert by["implicit", 1e-3, M].change == "better"
    st = by["discrete", 1e-3, "status"]
    assert (st.a, st.b, st.change, st.gates) == ("ok", "diverged", "worse", True)
    assert not any(c.key[2] == "discrete" and c.column == M for c in cmp.changes)
    assert math.isnan(st.ratio)
    env = by["implicitfast", 1e-3, "status"]
    # unsupported -> ok: the environment, reported, never gating
    assert (env.a, env.b, env.change, env.gates) == ("unsupported", "ok", "same", False)
    assert math.isnan(env.ratio)
    (mis,) = [c for c in cmp.changes if c.column == "identity"]
    assert mis.key[0] == "dzhanibekov" and math.isnan(mis.ratio)
    assert (mis.change, mis.gates, mis.a) == ("mismatch", True, "A")
    assert mis.b == "t_end 2 vs 3; save_every 10 vs 20"
    regressed = sorted((c.key[0], c.key[2]) for c in cmp.regressions)
    assert regressed == [("dzhanibekov", "RK4"), ("free_tumbling", "Euler"),
                         ("free_tumbling", "discrete")]  # fmt: skip
    n = _counts(cmp)
    want = {"in_both": 6, "worse": 2, "mismatch": 1, "better": 1, "same": 2,
            "cost_not_significant": 0, "cost_starved": 0, "only_a": 1, "only_b": 1}  # fmt: skip
    assert n == want
    assert _verdict(cmp) == ("FAIL: 1 run(s) are not the same run in A and B (identity "
                             "mismatch), 2 got worse beyond a factor 2.")  # fmt: skip
    # a vary'd identity column makes the mismatch a comparison
    varied = compare_folders(a, b, vary=("t_end", "save_every"))
    assert varied.vary == ("t_end", "save_every")
    assert not any(c.change == "mismatch" for c in varied.changes)
    # a larger factor: 10x is within it (same), the verdict names the rest
    wide = compare_folders(a, b, factor=20.0)
    assert {_key(c): c.change for c in wide.changes}["Euler", 1e-3, M] == "same"
    assert _verdict(wide).startswith("FAIL: 1 run(s) are not the same run")


def test_a_metric_below_its_round_off_floor_is_the_same(tmp_path, sc):
    """energy_drift_max 3e-16 -> 9e-15 (30x) is below its floor (1e-11) on both sides."""
    a = _folder(tmp_path / "a", [_row(sc, "Euler", energy_drift_max=3e-16)])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", energy_drift_max=9e-15)])
    (c,) = [c for c in compare_folders(a, b).changes if c.column == "energy_drift_max"]
    assert (c.change, c.ratio) == ("same", 1.0)


def test_the_verdict_and_the_shown_changes(tmp_path, sc):
    a = _folder(tmp_path / "a", [_row(sc, "Euler"), _row(sc, "RK4")])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", **{M: 1e-2}), _row(sc, "RK4")])
    cmp = compare_folders(a, b)
    assert _verdict(cmp) == "FAIL: 1 run(s) got worse beyond a factor 2."
    shown = _shown(cmp, False)
    assert [(c.key[2], c.column, c.change) for c in shown] == [("Euler", M, "worse")]
    every = _shown(cmp, True)
    assert every[0].change == "worse" and {c.change for c in every[1:]} == {"same"}
    assert len(every) == len(cmp.changes)
    ok = compare_folders(a, a)
    assert _verdict(ok) == "OK: no run got worse."
    assert _counts(ok)["same"] == 2 and _counts(ok)["worse"] == 0


def test_verdicts_and_failed_checks_of_runs_that_ran(tmp_path, sc):
    a = _folder(tmp_path / "a", [
        _row(sc, "Euler"),
        _row(sc, "RK4", verdict="fail", verdict_detail="energy_drift_max 1 > 0.01"),
        _row(sc, "implicit", status="error"),
    ])  # fmt: skip
    b = _folder(tmp_path / "b", [
        _row(sc, "Euler", verdict="fail", verdict_detail="attitude_error_max 1 > 0.1"),
        _row(sc, "RK4", verdict="fail",
             verdict_detail="energy_drift_max 1 > 0.01; attitude_error_max 1 > 0.1"),
        _row(sc, "implicit", status="error"),  # the same status: nothing compared
    ])  # fmt: skip
    by = {(c.key[2], c.column): c for c in compare_folders(a, b).changes}
    v = by["Euler", "verdict"]
    assert (v.a, v.b, v.change, v.gates) == ("pass", "fail", "worse", True)
    f = by["RK4", "failed checks"]
    assert (f.a, f.b, f.change, f.gates) == ("", "also fails attitude_error_max", "worse", True)
    assert math.isnan(v.ratio) and math.isnan(f.ratio)
    back = {(c.key[2], c.column): c for c in compare_folders(b, a).changes}
    assert back["Euler", "verdict"].change == "better"
    d = _folder(tmp_path / "d", [_row(sc, "Euler", status="diverged", verdict="fail")])
    e = _folder(tmp_path / "e", [_row(sc, "Euler")])
    (st,) = [c for c in compare_folders(d, e).changes if c.column == "status"]
    assert (st.a, st.b, st.change, st.gates) == ("diverged", "ok", "better", True)
    assert not any(k[0] == "implicit" for k in by)


def test_costs_are_reported_and_gate_only_with_a_cost_factor(tmp_path, sc):
    """engine_ns_per_step 1000 -> 5000 with tight ranges (spread 1e-6 s over 1000 steps:
    +-1 ns) at both steps of the sweep: worse, gating only when --cost-factor is given; at one
    step only (the other the same): not significant."""

    def cost(ns):
        return {"engine_ns_per_step": ns, "engine_time_spread_s": 1e-6,
                "engine_time_max_s": ns * 1e-6, "engine_time_s": ns * 1e-6}  # fmt: skip

    a = _folder(tmp_path / "a", [_row(sc, "Euler", dt=d, **cost(1000.0)) for d in (1e-3, 5e-4)])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", dt=d, **cost(5000.0)) for d in (1e-3, 5e-4)])
    c1 = [c for c in compare_folders(a, b).changes if c.column == "engine_ns_per_step"]
    assert [(c.change, c.gates) for c in c1] == [("worse", False)] * 2
    assert c1[0].ratio == pytest.approx(5.0) and c1[0].a == 1000.0 and c1[0].b == 5000.0
    gated = compare_folders(a, b, cost_factor=2.0)
    assert gated.cost_factor == 2.0
    c2 = [c for c in gated.changes if c.column == "engine_ns_per_step"]
    assert [(c.change, c.gates) for c in c2] == [("worse", True)] * 2
    assert not compare_folders(a, b, cost_factor=10.0).regressions
    worse_too = _folder(tmp_path / "w", [_row(sc, "Euler", dt=d, **{**cost(5000.0), M: 1e-2})
                                         for d in (1e-3, 5e-4)])  # fmt: skip
    shown = _shown(compare_folders(a, worse_too), False)
    ns = "engine_ns_per_step"
    assert [(c.column, c.gates) for c in shown] == [(M, True), (M, True), (ns, False),
                                                    (ns, False)]  # fmt: skip
    # a side timed starved (its spread beyond the share STARVED of its engine time): starved
    loose = {**cost(5000.0), "engine_time_spread_s": 0.5 * 5000.0 * 1e-6}
    starved = _folder(tmp_path / "s", [_row(sc, "Euler", dt=d, **loose) for d in (1e-3, 5e-4)])
    cs = compare_folders(a, starved)
    assert [c.change for c in cs.changes if c.column == "engine_ns_per_step"] == ["starved"] * 2
    assert _counts(cs)["cost_starved"] == 2
    one = _folder(tmp_path / "one", [_row(sc, "Euler", dt=1e-3, **cost(5000.0)),
                                     _row(sc, "Euler", dt=5e-4, **cost(1000.0))])  # fmt: skip
    cmp = compare_folders(a, one, cost_factor=2.0)
    words = sorted(c.change for c in cmp.changes if c.column == "engine_ns_per_step")
    assert words == ["not significant", "same"]
    assert _counts(cmp)["cost_not_significant"] == 1


def test_an_engine_release_change_is_counted(tmp_path, sc):
    a = _folder(tmp_path / "a", [_row(sc, "Euler", version="1.0"), _row(sc, "RK4", version="1.0")])
    b = _folder(tmp_path / "b", [_row(sc, "Euler", version="1.1", **{M: 1e-2}),
                                 _row(sc, "RK4", version="1.1")])  # fmt: skip
    cmp = compare_folders(a, b)
    (vc,) = cmp.versions.values()
    assert (vc.engine, vc.a, vc.b, vc.compared, vc.regressed, vc.identical) == (
        "mujoco", "1.0", "1.1", 2, 1, 1)  # fmt: skip


@pytest.mark.parametrize(
    "kw, words",
    [({"factor": 0.5}, "--factor 0.5: must be a number >= 1"),
     ({"cost_factor": 0.9}, "--cost-factor 0.9: must be a number >= 1"),
     ({"vary": ("colour",)}, "--vary 'colour': not an identity column (one of scenario_hash, "
      "t_end, save_every, segment, engine_version, suite_version)")],
)  # fmt: skip
def test_bad_options_are_refused_naming_them(tmp_path, sc, kw, words):
    a = _folder(tmp_path / "a", [_row(sc, "Euler")])
    with pytest.raises(InputError, match=re.escape(words)):
        compare_folders(a, a, **kw)
    compare_folders(a, a, factor=1.0, cost_factor=1.0, vary=("t_end",))  # the edges are allowed


def test_folders_with_nothing_in_common_are_never_a_pass(tmp_path, sc):
    a = _folder(tmp_path / "a", [_row(sc, "Euler")])
    b = _folder(tmp_path / "b", [_row(sc, "RK4")])
    with pytest.raises(NothingComparable, match=r"\(1 runs\) and .* \(1 runs\) share no run "
                       r"\(scenario, engine, integrator, dt, target accuracy\): nothing was "
                       "compared$"):  # fmt: skip
        compare_folders(a, b)
    empty = _folder(tmp_path / "empty", [])
    with pytest.raises(NothingComparable, match="empty: the results store holds no run"):
        compare_folders(empty, a)
    with pytest.raises(NothingComparable, match="empty: the results store holds no run"):
        compare_folders(a, empty)


def test_target_accuracy_runs_are_keyed_and_sorted_apart(tmp_path, sc):
    """An error-controlled run is keyed by its target accuracy (dt is nominal): two targets
    are two runs, sorted after the fixed-step one (no target sorts as -1)."""
    rows = [_row(sc, "RK45", accuracy=1e-6), _row(sc, "RK45", accuracy=1e-8),
            _row(sc, "RK45")]  # fmt: skip
    a = _folder(tmp_path / "a", rows)
    cmp = compare_folders(a, a)
    assert [k[4] for k in cmp.compared] == [None, 1e-8, 1e-6]
    assert not math.isnan(cmp.factor)
