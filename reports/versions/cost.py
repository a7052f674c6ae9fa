"""Cost changes confirmed by timing the two versions side by side.

The runs of two engine versions happen at different times, and a shared machine's load moves
a run's time per step by a factor of two or more between them, which no spread within one
version's runs shows. A cost difference between two versions found in the stored rows
(:func:`reports.versions.changes._cost_changes`) is therefore only a candidate; it becomes a
change when timing probes of the two versions, interleaved (A, B, A, B, ...: each round sees
about the same load), give medians more than the factor apart AND ranges that do not overlap.
A candidate that cannot be timed (its environment is gone) stays a candidate, never a change.

The probes' times are recorded in the folder (:data:`TIMINGS_FILE`) and reused by every later
call on it: timing again would give other times, so two calls on one store could give two
verdicts (and rewrite versions.md with the other). Only ``--retime`` times them again; the
decision (the factor, whether the ranges overlap) is made from the recorded times each call.
"""

from __future__ import annotations

import json
import statistics
import subprocess
from pathlib import Path

#: interleaved rounds per candidate (each times both versions once)
ROUNDS = 3
PROBE_TIMEOUT_S = 600
#: the probes' times of a versions folder, reused by later calls (see the module docstring)
TIMINGS_FILE = "versions-timings.json"


def _timing_key(c) -> str:
    return "|".join((c.scenario, c.engine, c.integrator, c.from_version, c.to_version))


def read_timings(folder: Path | None) -> dict:
    """{candidate key: {"dt", "a", "b", "rounds"}} recorded in ``folder`` (empty without one,
    or when the file is not a JSON object of such records: they are timed again)."""
    path = None if folder is None else Path(folder) / TIMINGS_FILE
    if path is None or not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    ok = isinstance(data, dict) and all(
        isinstance(v, dict) and isinstance(v.get("a"), list) and isinstance(v.get("b"), list)
        for v in data.values()
    )
    return data if ok else {}


def _write_timings(folder: Path, data: dict) -> None:
    from reports.store.atomic import write_text

    write_text(Path(folder) / TIMINGS_FILE, json.dumps(data, indent=1, sort_keys=True) + "\n")


def _python(engine: str, version: str, root: Path | None) -> Path | None:
    from reports.versions.envs import MARKER, env_path
    from reports.versions.requirements import Target, engine_package

    pkg = engine_package(engine) or engine
    target = Target(engine, pkg, f"{pkg}=={version}", version, version)
    path = env_path(target, root)
    return path / "bin" / "python" if (path / MARKER).exists() else None


def _probe(python: Path, change, dt: float) -> float | None:
    from reports.versions.envs import checkout_env

    args = [str(python), "-m", "reports.versions.worker", "--time", change.scenario,
            change.engine, change.integrator, repr(dt)]  # fmt: skip
    try:
        p = subprocess.run(args, capture_output=True, text=True, timeout=PROBE_TIMEOUT_S,
                           check=False, env=checkout_env())  # fmt: skip
        out = json.loads(p.stdout.strip().splitlines()[-1])
        return float(out["engine_ns_per_step"]) if out["status"] in ("ok", "diverged") else None
    except (subprocess.TimeoutExpired, ValueError, IndexError, KeyError, TypeError):
        return None


def confirm(
    tab,
    changes: list,
    factor: float,
    root: Path | None = None,
    rounds: int = ROUNDS,
    log=None,
    memo: dict | None = None,
    folder: Path | None = None,
    retime: bool = False,
) -> tuple[list, list]:
    """(changes with the cost changes that timing side by side confirmed, their values replaced
    by the probes' medians; the cost candidates it did not confirm, each with the reason).
    ``memo`` keeps the verdicts of candidates already timed (the table and the gate share
    them); ``folder``: where the probes' times are recorded and read back
    (:data:`TIMINGS_FILE`), unless ``retime``."""
    memo = {} if memo is None else memo
    recorded = {} if retime else read_timings(folder)
    kept, cands = [], []
    for c in changes:
        if c.kind != "cost":
            kept.append(c)
            continue
        key = (c.scenario, c.engine, c.integrator, c.from_version, c.to_version)
        if key not in memo:
            rec = recorded.get(_timing_key(c))
            if rec is None:
                rec = _probes(tab, c, root, rounds)
                if "a" in rec and folder is not None:
                    recorded[_timing_key(c)] = rec
                    _write_timings(folder, {**read_timings(folder), _timing_key(c): rec})
                when = "side by side"
            else:
                when = f"side by side (recorded in {TIMINGS_FILE}; --retime times it again)"
            memo[key] = _decide(c, rec, factor, when, log)
        ok, values, why = memo[key]
        if ok:
            c.a, c.b, c.ratio = values
            kept.append(c)
        else:
            cands.append((c, why))
    return kept, cands


def _probes(tab, c, root, rounds) -> dict:
    """The probes of one cost candidate, interleaved: ``{"dt", "rounds", "a": [ns...],
    "b": [ns...]}``, or ``{"why": ...}`` when they could not be taken (recorded only when
    taken: an environment made later, or a probe that fails once, is tried again)."""
    pa, pb = _python(c.engine, c.from_version, root), _python(c.engine, c.to_version, root)
    if pa is None or pb is None:
        return {"why": "no environment to time it in"}
    dts = sorted(k[3] for k in tab.configs(c.engine)
                 if (k[0], k[2], k[4]) == (c.scenario, c.integrator, None))  # fmt: skip
    dt = dts[len(dts) // 2]
    ta, tb = [], []
    for _ in range(rounds):
        ta.append(_probe(pa, c, dt))
        tb.append(_probe(pb, c, dt))
    if None in ta or None in tb:
        return {"why": "a timing probe failed"}
    return {"dt": dt, "rounds": rounds, "a": ta, "b": tb}


def _decide(c, rec: dict, factor: float, when: str, log):
    """(confirmed?, (median a, median b, ratio), why) of one cost candidate from its probes
    ``rec`` (:func:`_probes`)."""
    if "a" not in rec:
        return False, None, rec.get("why", "not timed")
    ta, tb, dt, rounds = rec["a"], rec["b"], rec["dt"], rec.get("rounds", len(rec["a"]))
    ma, mb = statistics.median(ta), statistics.median(tb)
    ratio = mb / ma
    apart = max(tb) < min(ta) if ratio < 1 else min(tb) > max(ta)
    ranges = f"{min(ta):.3g}-{max(ta):.3g} vs {min(tb):.3g}-{max(tb):.3g}"
    text = f"{when} at dt={dt:g}, {rounds} rounds: {ma:.3g} vs {mb:.3g} ns"
    text += f" (x{ratio:.2g}; {ranges})"
    if log:
        log(f"[cost] {c.scenario} {c.engine} {c.integrator} {c.from_version} -> "
            f"{c.to_version}: {text}")  # fmt: skip
    if (ratio > factor or ratio < 1.0 / factor) and apart:
        return True, (ma, mb, ratio), text
    return False, None, f"not confirmed {text}"
