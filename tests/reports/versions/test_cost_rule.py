"""The rule that confirms a cost change between two engine versions (reports/versions/cost.py):
medians more than the factor apart AND ranges that do not overlap, decided from probes timed
side by side, recorded in the folder and reused.

Each expected verdict and figure is worked out by hand in the test from the probe times it
hands over (medians, ratio, ranges); the probes themselves (which need one environment per
version) are replaced by fixed times, so what is tested is the rule and its bookkeeping.
"""

from __future__ import annotations

import json
import time
import types

import pytest

from reports.versions import cost


def _cand(**kw):
    base = dict(kind="cost", scenario="free", engine="eng", integrator="RK4",
                from_version="1.0", to_version="1.1", a=1.0, b=3.0, ratio=3.0)  # fmt: skip
    return types.SimpleNamespace(**{**base, **kw})


def _rec(a, b, rounds=True):
    rec = {"dt": 0.001, "a": list(a), "b": list(b)}
    if rounds:
        rec["rounds"] = len(a)
    return rec


def test_a_slowdown_beyond_the_factor_with_apart_ranges_is_confirmed_with_its_text():
    """Medians 105 and 305 ns (x2.9 > 2), ranges 100-110 and 300-310 apart."""
    lines = []
    ok, values, why = cost._decide(_cand(), _rec((100, 110, 105), (300, 310, 305)), 2.0,
                                   "side by side", lines.append)  # fmt: skip
    assert ok and values == (105, 305, 305 / 105)
    text = "side by side at dt=0.001, 3 rounds: 105 vs 305 ns (x2.9; 100-110 vs 300-310)"
    assert why == text
    assert lines == [f"[cost] free eng RK4 1.0 -> 1.1: {text}"]


def test_the_number_of_rounds_defaults_to_the_probes():
    ok, _, why = cost._decide(_cand(), _rec((100, 110, 105), (300, 310, 305), rounds=False),
                              2.0, "w", None)  # fmt: skip
    assert ok and ", 3 rounds:" in why


def test_a_speedup_beyond_the_factor_is_confirmed():
    """Medians 305 -> 105 ns (x0.34 < 1/2), ranges apart (110 < 300)."""
    ok, values, _ = cost._decide(_cand(), _rec((300, 310, 305), (100, 110, 105)), 2.0, "w", None)
    assert ok and values == (305, 105, 105 / 305)


@pytest.mark.parametrize(
    "a, b, factor",
    [
        ((300, 310, 305), (100, 110, 300), 2.0),  # a speedup whose ranges touch at 300
        ((100, 110, 105), (110, 310, 305), 2.0),  # a slowdown whose ranges touch at 110
        ((100, 100, 100), (200, 200, 200), 2.0),  # exactly the factor: not more than it
        ((200, 200, 200), (100, 100, 100), 2.0),  # exactly 1 / factor
        ((100, 101, 102), (120, 121, 122), 2.0),  # x1.2, apart: within the factor
        ((100, 101, 102), (80, 81, 82), 2.0),  # x0.8, apart: within the factor
    ],
)
def test_not_confirmed(a, b, factor):
    ok, values, why = cost._decide(_cand(), _rec(a, b), factor, "w", None)
    assert not ok and values is None and why.startswith("not confirmed w at dt=0.001")


def test_a_slowdown_below_2x_beyond_a_smaller_factor_is_confirmed():
    """x1.8 (medians 101 -> 181.8) at factor 1.5, ranges apart."""
    ok, _, _ = cost._decide(_cand(), _rec((100, 101, 102), (180, 181.8, 183)), 1.5, "w", None)
    assert ok


def test_a_candidate_without_probes_says_why():
    assert cost._decide(_cand(), {"why": "no environment"}, 2.0, "w", None) == (
        False, None, "no environment")  # fmt: skip
    assert cost._decide(_cand(), {}, 2.0, "w", None) == (False, None, "not timed")


def test_confirm_records_the_probes_reuses_them_and_retimes_on_request(tmp_path, monkeypatch):
    """The first call probes (once per candidate, whatever the memo sees) and records the
    times in the folder; a second call decides from the record without probing and says so;
    --retime probes again. A confirmed candidate takes the probes' medians."""
    calls = []

    def probes(tab, c, root, rounds):
        calls.append((c.engine, root, rounds))
        return _rec((100, 110, 105), (300, 310, 305))

    monkeypatch.setattr(cost, "_probes", probes)
    other = types.SimpleNamespace(kind="metric")
    memo = {}
    kept, cands = cost.confirm(None, [_cand(), other, _cand()], 2.0, root="envs", rounds=3,
                               memo=memo, folder=tmp_path)  # fmt: skip
    assert calls == [("eng", "envs", 3)]  # the second, same candidate from the memo
    assert cands == [] and kept[1] is other
    assert (kept[0].a, kept[0].b, kept[0].ratio) == (105, 305, 305 / 105)
    key = "free|eng|RK4|1.0|1.1"
    assert json.loads((tmp_path / cost.TIMINGS_FILE).read_text()) == {
        key: _rec((100, 110, 105), (300, 310, 305))}  # fmt: skip
    assert list(memo) == [("free", "eng", "RK4", "1.0", "1.1")]
    # a second call (a new memo) reads the record: no probe, the record named in the log
    lines = []
    kept, _ = cost.confirm(None, [_cand()], 2.0, folder=tmp_path, log=lines.append)
    assert len(calls) == 1 and kept[0].ratio == 305 / 105
    assert f"(recorded in {cost.TIMINGS_FILE}; --retime times it again)" in lines[0]
    cost.confirm(None, [_cand()], 2.0, folder=tmp_path, retime=True)
    assert len(calls) == 2


def test_confirm_keeps_an_unconfirmed_candidate_with_its_reason(tmp_path, monkeypatch):
    monkeypatch.setattr(cost, "_probes", lambda *a: _rec((100, 101, 102), (120, 121, 122)))
    c = _cand()
    kept, cands = cost.confirm(None, [c], 2.0, folder=tmp_path)
    assert kept == [] and cands == [(c, cands[0][1])]
    assert cands[0][1].startswith("not confirmed side by side at dt=0.001, 3 rounds:")
    # probes that could not be taken are not recorded (tried again next time)
    monkeypatch.setattr(cost, "_probes", lambda *a: {"why": "a timing probe failed"})
    kept, cands = cost.confirm(None, [_cand(to_version="1.2")], 2.0, folder=tmp_path)
    assert cands[0][1] == "a timing probe failed"
    assert "free|eng|RK4|1.0|1.2" not in json.loads((tmp_path / cost.TIMINGS_FILE).read_text())


def test_confirm_without_a_folder_records_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(cost, "_probes", lambda *a: _rec((100, 110, 105), (300, 310, 305)))
    kept, _ = cost.confirm(None, [_cand()], 2.0)
    assert kept[0].ratio == 305 / 105 and not (tmp_path / cost.TIMINGS_FILE).exists()


def test_two_candidates_are_both_recorded(tmp_path, monkeypatch):
    """Each probe's record is added to the file's, never replacing the others; the file is
    JSON with sorted keys and one-space indents, ending in a newline (stable diffs)."""
    monkeypatch.setattr(cost, "_probes", lambda *a: _rec((100, 110, 105), (300, 310, 305)))
    cost.confirm(None, [_cand(), _cand(to_version="1.2")], 2.0, folder=tmp_path)
    text = (tmp_path / cost.TIMINGS_FILE).read_text()
    assert list(json.loads(text)) == ["free|eng|RK4|1.0|1.1", "free|eng|RK4|1.0|1.2"]
    assert text.startswith('{\n "free|eng|RK4|1.0|1.1": {\n  "a": [\n   100,') and text.endswith(
        "}\n")  # fmt: skip


@pytest.mark.parametrize(
    "content",
    ["[1, 2]", '{"k": 5}', '{"k": {"a": [1], "b": 3}}', '{"k": {"a": 1, "b": [3]}}', "{bad"],
)
def test_a_malformed_timings_file_is_ignored(tmp_path, content):
    (tmp_path / cost.TIMINGS_FILE).write_text(content)
    assert cost.read_timings(tmp_path) == {}


def test_a_well_formed_timings_file_is_read(tmp_path):
    data = {"k": {"dt": 0.001, "a": [1.0], "b": [2.0]}}
    (tmp_path / cost.TIMINGS_FILE).write_text(json.dumps(data))
    assert cost.read_timings(tmp_path) == data
    assert cost.read_timings(None) == {} and cost.read_timings(tmp_path / "none") == {}


def _tab(*configs):
    return types.SimpleNamespace(configs=lambda engine: list(configs) if engine == "eng" else [])


def test_probes_time_the_two_versions_interleaved_at_the_median_step(monkeypatch):
    """The candidate's step sizes (its scenario and integrator, no segment) are 8e-3 .. 5e-4:
    the median is 2e-3 (the third of five; others ignored); rounds A, B, A, B, each in its
    version's environment under ``root``."""
    seen = []
    monkeypatch.setattr(cost, "_python", lambda engine, version, root: (engine, version, root))

    def probe(python, c, dt):
        seen.append((python, c.scenario, dt))
        return 100.0 if python[1] == "1.0" else 300.0

    monkeypatch.setattr(cost, "_probe", probe)
    tab = _tab(("free", "x", "RK4", 4e-3, None), ("free", "x", "RK4", 1e-3, None),
               ("free", "x", "RK4", 2e-3, None), ("free", "x", "RK4", 8e-3, None),
               ("free", "x", "RK4", 5e-4, None), ("free", "x", "RK4", 2.5e-4, 3),
               ("other", "x", "RK4", 1e-4, None), ("free", "x", "Euler", 1e-4, None))  # fmt: skip
    rec = cost._probes(tab, _cand(), "root", 2)
    assert rec == {"dt": 2e-3, "rounds": 2, "a": [100.0, 100.0], "b": [300.0, 300.0]}
    a, b = ("eng", "1.0", "root"), ("eng", "1.1", "root")
    assert seen == [(a, "free", 2e-3), (b, "free", 2e-3)] * 2


def test_probes_say_why_they_were_not_taken(monkeypatch):
    tab = _tab(("free", "x", "RK4", 1e-3, None))
    monkeypatch.setattr(cost, "_python", lambda e, v, r: None if v == "1.1" else "py")
    assert cost._probes(tab, _cand(), None, 2) == {"why": "no environment to time it in"}
    monkeypatch.setattr(cost, "_python", lambda e, v, r: None if v == "1.0" else "py")
    assert cost._probes(tab, _cand(), None, 2) == {"why": "no environment to time it in"}
    monkeypatch.setattr(cost, "_python", lambda e, v, r: v)
    monkeypatch.setattr(cost, "_probe", lambda p, c, dt: None if p == "1.1" else 1.0)
    assert cost._probes(tab, _cand(), None, 2) == {"why": "a timing probe failed"}


def _fake_python(tmp_path, lines, code=0):
    """An executable standing in for an environment's python: writes its arguments and
    PYTHONPATH to files beside it, prints ``lines`` and exits with ``code``."""
    p = tmp_path / "python"
    p.write_text("#!/bin/sh\n"
                 f'echo "$@" > {tmp_path}/args\necho "$PYTHONPATH" > {tmp_path}/path\n'
                 + "".join(f"echo '{ln}'\n" for ln in lines) + f"exit {code}\n")  # fmt: skip
    p.chmod(0o755)
    return p


@pytest.mark.parametrize(
    "lines, expected",
    [
        (['{"status": "ok", "engine_ns_per_step": 1234.5}'], 1234.5),
        (["noise", '{"status": "diverged", "engine_ns_per_step": 7}'], 7.0),
        (['{"status": "error", "engine_ns_per_step": 7}'], None),
        (['{"status": "ok"}'], None),
        (["not json"], None),
        ([], None),
    ],
)
def test_a_probe_reads_the_last_line_of_the_worker(tmp_path, lines, expected):
    py = _fake_python(tmp_path, lines)
    assert cost._probe(py, _cand(), 1e-3) == expected


def test_a_probe_runs_the_worker_of_this_checkout(tmp_path):
    """The worker's command line (reports/versions/worker.py --time SCENARIO ENGINE
    INTEGRATOR DT) with this checkout first on PYTHONPATH; its exit code does not matter, its
    last line does."""
    from reports.versions.envs import CHECKOUT

    py = _fake_python(tmp_path, ['{"status": "ok", "engine_ns_per_step": 5}'], code=1)
    assert cost._probe(py, _cand(), 0.001) == 5.0
    args = (tmp_path / "args").read_text().split()
    assert args == ["-m", "reports.versions.worker", "--time", "free", "eng", "RK4", "0.001"]
    assert (tmp_path / "path").read_text().startswith(str(CHECKOUT))


def test_an_environment_counts_once_its_marker_is_written(tmp_path):
    from reports.versions.envs import MARKER, env_path
    from reports.versions.requirements import Target

    assert cost._python("mujoco", "3.1.0", tmp_path) is None
    path = env_path(Target("mujoco", "mujoco", "mujoco==3.1.0", "3.1.0", "3.1.0"), tmp_path)
    path.mkdir(parents=True)
    (path / MARKER).write_text("{}")
    assert cost._python("mujoco", "3.1.0", tmp_path) == path / "bin" / "python"


def test_a_probe_that_hangs_is_stopped_at_its_bound(tmp_path, monkeypatch):
    """A worker that does not answer within PROBE_TIMEOUT_S counts as a failed probe (here the
    bound is 0.5 s and the stand-in sleeps 20 s before it would answer)."""
    p = tmp_path / "python"
    p.write_text('#!/bin/sh\nexec sleep 20\necho \'{"status": "ok", "engine_ns_per_step": 5}\'\n')
    p.chmod(0o755)
    monkeypatch.setattr(cost, "PROBE_TIMEOUT_S", 0.5)
    t0 = time.monotonic()
    assert cost._probe(p, _cand(), 0.001) is None
    assert time.monotonic() - t0 < 10.0
