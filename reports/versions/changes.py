"""What changed between engine releases: every configuration's metrics against the version.

Input: a results folder holding rows of several versions of an engine (``director-bench
versions`` writes one). For each configuration (scenario, engine, integrator, dt, target
accuracy) and each pair of consecutive versions of that engine, a :class:`Change` is recorded
for:

- ``metric``: an error metric that moved by more than ``factor`` above its round-off floor, or
  a fitted order that moved by more than the gate's slack (:func:`reports.gate.rule.classify`,
  the comparison rule of ``check`` and ``compare``): ``worse`` or ``better``;
- ``status`` (ok, diverged, error ... ranked as in :data:`reports.gate.rule.STATUS_RANK`) and
  ``verdict`` (pass <-> fail);
- ``behaviour``: the class of the signed energy error over time changed between decisive
  classes (:func:`energy_behaviour`: conserved, gaining, losing);
- ``integrator``: a configuration ``unsupported`` in one version and run in the next (new) or
  the reverse (vanished);
- ``cost``: the median engine time per step of (scenario, engine, integrator) over its dt
  sweep moved by more than ``factor`` AND by more than the product of the spreads measured
  across that sweep in both versions (per-step cost does not depend on dt for a fixed-step
  method, so the sweep's spread is the measurement's noise), AND the cost moved beyond the
  factor, the same way, at every dt of the sweep (:func:`reports.gate.rule.at_every_dt`, the
  rule ``compare`` applies to its cost changes; the machine's load changes between the
  times two versions run, which no spread within one version shows; a real change of the
  engine moves every step size); without a sweep no cost change is claimed.

A pair in which one side is ``unavailable`` is not compared (its reason is listed). A
configuration with no change between a pair counts as ``identical`` (every metric bit for bit)
or ``within`` (some metric differs, by less than the factor above its floor).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from reports.gate.rule import at_every_dt, classify, ratio_change, status_change
from reports.metrics.catalog import FLOORS, HIGHER_IS_BETTER, METRIC_COLUMNS
from reports.store.format import num
from reports.store.results import read_results
from reports.store.runs import CONFIG_KEY, config_key
from scenarios.schema import InputError

#: the cost column compared (time inside the engine's own calls, per step)
COST_COLUMN = "engine_ns_per_step"
#: energy-behaviour classes; only changes between decisive ones are flagged
DECISIVE = ("conserved", "gaining", "losing")


def version_key(v: str):
    """Sort key of an engine version: PEP 440 order, unparsable ones last by text."""
    from packaging.version import InvalidVersion, Version

    try:
        return (0, Version(v), "")
    except InvalidVersion:
        return (1, None, v)


def sort_versions(versions) -> list[str]:
    vs = list(dict.fromkeys(versions))
    parsed = [v for v in vs if version_key(v)[0] == 0]
    other = sorted(v for v in vs if version_key(v)[0] == 1)
    return sorted(parsed, key=lambda v: version_key(v)[1]) + other


# -- energy behaviour ---------------------------------------------------------------------------


def energy_behaviour(t, e, floor: float = FLOORS["energy_drift_max"]) -> dict:
    """The class of a signed energy error e(t) (units of E_c), shapes (n,):

    - ``round-off`` (counted as ``conserved``): max |e| <= floor;
    - the least-squares line through e(t) gives the secular change over the horizon
      ``trend`` = slope * (t_end - t_0); the residual ``wobble`` = max |e - line|;
    - ``conserved`` when |trend| < wobble / 2 (a bounded oscillation, no secular drift),
      ``gaining`` / ``losing`` when |trend| > 2 wobble, by the sign of the trend;
    - ``mixed`` in between (not decisive: a class change to or from it is not flagged), and
      ``diverged`` when e is not finite.

    Returns the class and the figures it was read from."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if len(e) == 0 or not np.all(np.isfinite(e)):
        return {"class": "diverged", "max": math.inf, "trend": math.nan, "wobble": math.nan}
    m = float(np.max(np.abs(e)))
    if m <= floor or len(e) < 3 or t[-1] <= t[0]:
        return {"class": "conserved", "max": m, "trend": 0.0, "wobble": m, "round_off": True}
    slope, icpt = np.polyfit(t, e, 1)
    trend = float(slope * (t[-1] - t[0]))
    wobble = float(np.max(np.abs(e - (slope * t + icpt))))
    if abs(trend) > 2.0 * wobble:
        cls = "gaining" if trend > 0 else "losing"
    elif abs(trend) < 0.5 * wobble:
        cls = "conserved"
    else:
        cls = "mixed"
    return {"class": cls, "max": m, "trend": trend, "wobble": wobble}


def signed_energy_error(folder: Path, row: dict):
    """(t, (E(t) - E(0)) / E_c) of a run from its trajectory file, or None without one (a
    run that kept only the series the report draws, reports.run.files, has no energy).
    E(0) is the first saved sample, the initial state as the suite computes its energy."""
    import pyarrow.parquet as pq

    rel = row.get("trajectory") or ""
    path = Path(folder) / rel
    if not rel or path.suffix != ".parquet" or not path.exists():
        return None
    if "energy" not in pq.read_schema(path).names:
        return None
    tab = pq.read_table(path, columns=["t", "energy"])
    t = tab.column("t").to_numpy()
    en = tab.column("energy").to_numpy()
    scale = float(row.get("energy_scale") or math.nan)
    if not len(en) or not scale > 0:
        return None
    return t, (en - en[0]) / scale


# -- the table of versions ----------------------------------------------------------------------


@dataclass
class Change:
    scenario: str
    engine: str
    integrator: str
    dt: float | None
    target_accuracy: float | None
    from_version: str
    to_version: str
    kind: str  # metric, status, verdict, behaviour, integrator, cost
    column: str
    a: object
    b: object
    ratio: float | None
    direction: str  # worse, better, changed, new, vanished

    @property
    def key(self) -> tuple:
        return (self.scenario, self.engine, self.integrator, self.dt, self.target_accuracy)

    @property
    def gates(self) -> bool:
        """Whether an upgrade with this change fails the gate (cost: only with cost_factor,
        decided by :func:`check`)."""
        return self.direction in ("worse", "vanished") and self.kind != "cost"


@dataclass
class PairSummary:
    engine: str
    from_version: str
    to_version: str
    compared: int = 0
    identical: int = 0
    within: int = 0
    changed: int = 0
    not_compared: list = field(default_factory=list)  # (configuration, reason)


@dataclass
class VersionTable:
    folder: Path
    factor: float
    versions: dict  # engine -> sorted versions
    rows: dict  # (config key, version) -> row dict
    behaviour: dict = field(default_factory=dict)  # (config key, version) -> energy_behaviour
    changes: list = field(default_factory=list)
    pairs: list = field(default_factory=list)
    #: cost differences found in the rows that timing side by side did not confirm
    #: (reports.versions.cost): (Change, reason)
    cost_candidates: list = field(default_factory=list)

    def configs(self, engine: str | None = None) -> list[tuple]:
        keys = {k for k, _ in self.rows if engine is None or k[1] == engine}
        return sorted(keys, key=_sort_key)

    def row(self, key, version):
        return self.rows.get((key, version))


def _sort_key(key):
    sc, eng, integ, dt, acc = key
    return (sc, eng, integ, -1.0 if dt is None else dt, -1.0 if acc is None else acc)


def _records(df) -> list[dict]:
    out = []
    for rec in df.to_dict("records"):
        out.append(
            {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in rec.items()}
        )
    return out


def _newest(rows):
    """The newest row of each configuration among the rows of ONE engine version (the
    identity of a run already fixes everything else), with the convergence orders of its dt
    sweeps fitted (reports.metrics.body)."""
    from reports.metrics.body import add_convergence_orders

    rows = rows.sort_values("finished_at", kind="stable")
    rows = rows.drop_duplicates(subset=list(CONFIG_KEY), keep="last")  # NaN accuracies match
    return add_convergence_orders(rows.sort_values(list(CONFIG_KEY), ignore_index=True))


def load_table(folder, factor: float = 2.0, behaviour: bool = True) -> VersionTable:
    """Every engine version's current rows of ``folder`` (the newest row of each configuration
    within each version, convergence orders fitted per version), and the energy behaviour of
    each run from its trajectory."""
    if not factor >= 1.0:
        raise InputError(f"--factor {factor!r}: must be a number >= 1")
    folder = Path(folder)
    df = read_results(folder, all_rows=True)
    versions, rows, beh = {}, {}, {}
    for (eng, ver), grp in df.groupby(["engine", "engine_version"], sort=False):
        versions.setdefault(eng, []).append(ver)
        for r in _records(_newest(grp)):
            key = config_key(*(r[c] for c in CONFIG_KEY))
            rows[(key, ver)] = r
            if behaviour and r["status"] in ("ok", "diverged"):
                series = signed_energy_error(folder, r)
                if series is not None:
                    beh[(key, ver)] = energy_behaviour(*series)
    versions = {e: sort_versions(v) for e, v in versions.items()}
    tab = VersionTable(folder, factor, versions, rows, beh)
    for eng, vs in versions.items():
        for a, b in zip(vs, vs[1:], strict=False):
            summary, changes = compare_versions(tab, eng, a, b)
            tab.pairs.append(summary)
            tab.changes += changes
    return tab


def compare_versions(tab: VersionTable, engine: str, va: str, vb: str):
    """(PairSummary, changes) from version ``va`` to ``vb`` of ``engine`` (any two versions:
    consecutive ones for the table, the two of an upgrade for the gate)."""
    summary = PairSummary(engine, va, vb)
    changes: list[Change] = []
    for key in tab.configs(engine):
        a, b = tab.row(key, va), tab.row(key, vb)
        if a is None or b is None:
            continue
        if "unavailable" in (a["status"], b["status"]):
            which = a if a["status"] == "unavailable" else b
            summary.not_compared.append(
                (_name(key), f"{which['engine_version']}: {which['message']}")
            )
            continue
        summary.compared += 1
        found = _config_changes(tab, key, va, vb, a, b)
        changes += found
        if found:
            summary.changed += 1
        elif _identical(a, b):
            summary.identical += 1
        else:
            summary.within += 1
    changes += _cost_changes(tab, engine, va, vb)
    return summary, changes


def _identical(a: dict, b: dict) -> bool:
    for col in METRIC_COLUMNS:
        x, y = num(a.get(col)), num(b.get(col))
        if not (x == y or (math.isnan(x) and math.isnan(y))):
            return False
    return a["status"] == b["status"] and a["verdict"] == b["verdict"]


def _config_changes(tab, key, va, vb, a, b) -> list[Change]:
    def mk(kind, column, x, y, ratio, direction):
        return Change(*key, va, vb, kind, column, x, y, ratio, direction)

    sa, sb = a["status"], b["status"]
    if sa == "unsupported" or sb == "unsupported":
        if sa == sb:
            return []
        if sa == "unsupported":
            return [mk("integrator", "status", sa, sb, None, "new")]
        return [mk("integrator", "status", sa, f"{sb}: {b['message']}", None, "vanished")]
    out = []
    if sa != sb:
        out.append(mk("status", "status", sa, sb, None, status_change(sa, sb)))
    if sa == sb == "ok" and a["verdict"] != b["verdict"]:
        word = "worse" if b["verdict"] == "fail" else "better"
        detail_b = f"fail ({b['verdict_detail']})" if b["verdict"] == "fail" else b["verdict"]
        detail_a = f"fail ({a['verdict_detail']})" if a["verdict"] == "fail" else a["verdict"]
        out.append(mk("verdict", "verdict", detail_a, detail_b, None, word))
    if sa == sb == "ok":
        for col in METRIC_COLUMNS:
            na, nb = math.isnan(num(a.get(col))), math.isnan(num(b.get(col)))
            if col in HIGHER_IS_BETTER and (na or nb):
                # no fitted order on one side: its errors left the asymptotic range (e.g. fell
                # to the round-off floor), which the error metrics themselves show
                continue
            got = classify(col, a.get(col), b.get(col), tab.factor)
            if got is None or got[1] == "same":
                continue
            ratio, word = got
            out.append(mk("metric", col, num(a.get(col)), num(b.get(col)), _finite(ratio), word))
    ba, bb = tab.behaviour.get((key, va)), tab.behaviour.get((key, vb))
    if ba and bb and ba["class"] != bb["class"]:
        ca, cb = ba["class"], bb["class"]
        if ca in DECISIVE and cb in DECISIVE:
            word = "worse" if ca == "conserved" else "better" if cb == "conserved" else "changed"
            out.append(mk("behaviour", "energy error", ca, cb, None, word))
    return out


def _finite(x):
    return None if x is None or not math.isfinite(x) else float(x)


def _cost_stats(tab, engine, integ_key, version):
    """(median, spread max/min) of the engine time per step over the dt sweep of one
    (scenario, engine, integrator, accuracy) in one version; spread None with one point."""
    sc, integ, acc = integ_key
    vals = [
        num(r.get(COST_COLUMN))
        for (k, v), r in tab.rows.items()
        if v == version
        and k[0] == sc
        and k[1] == engine
        and k[2] == integ
        and k[4] == acc
        and r["status"] in ("ok", "diverged")
    ]
    vals = [x for x in vals if x > 0 and math.isfinite(x)]
    if not vals:
        return None, None
    spread = max(vals) / min(vals) if len(vals) >= 2 else None
    return float(np.median(vals)), spread


def _paired_cost_ratios(tab, engine, sc, integ, va, vb) -> list[float]:
    """The cost ratio b/a at each dt both versions ran (fixed-step, ok or diverged)."""
    out = []
    for k in tab.configs(engine):
        if (k[0], k[2], k[4]) != (sc, integ, None):
            continue
        a, b = tab.row(k, va), tab.row(k, vb)
        if a is None or b is None:
            continue
        x, y = num(a.get(COST_COLUMN)), num(b.get(COST_COLUMN))
        if x > 0 and y > 0 and math.isfinite(x) and math.isfinite(y):
            out.append(y / x)
    return out


def _cost_changes(tab, engine, va, vb) -> list[Change]:
    out = []
    ikeys = sorted(
        {(k[0], k[2], k[4]) for k in tab.configs(engine)}, key=lambda x: (x[0], x[1], x[2] or -1)
    )
    for sc, integ, acc in ikeys:
        if acc is not None:
            continue  # an error-controlled method's cost per step depends on its step choice
        ma, sa = _cost_stats(tab, engine, (sc, integ, acc), va)
        mb, sb = _cost_stats(tab, engine, (sc, integ, acc), vb)
        if ma is None or mb is None or sa is None or sb is None:
            continue
        ratio = mb / ma
        noise = max(tab.factor, sa * sb)
        paired = _paired_cost_ratios(tab, engine, sc, integ, va, vb)
        word = "worse" if ratio > 1 else "better"
        consistent = at_every_dt(ratio_change(p, tab.factor) for p in paired) == word
        if (ratio > noise or ratio < 1.0 / noise) and consistent:
            out.append(
                Change(
                    sc,
                    engine,
                    integ,
                    None,
                    acc,
                    va,
                    vb,
                    "cost",
                    COST_COLUMN,
                    ma,
                    mb,
                    ratio,
                    word,
                )
            )
    return out


def _name(key) -> str:
    sc, eng, integ, dt, acc = key
    s = f"{sc} {eng} {integ}" + ("" if dt is None else f" dt={dt:g}")
    return s + ("" if acc is None else f" accuracy {acc:g}")


# -- the gate -----------------------------------------------------------------------------------


def resolve_version(tab: VersionTable, text: str) -> tuple[str, str]:
    """(engine, version) named by ``ENGINE==VERSION``, a bare version held by one engine, or
    ``ENGINE==oldest``/``newest`` (a bare ``oldest``/``newest`` when one engine is held);
    InputError naming what the folder holds otherwise."""
    held = "; ".join(f"{e}: {', '.join(vs)}" for e, vs in tab.versions.items()) or "nothing"
    if "==" in text:
        eng, ver = (s.strip() for s in text.split("==", 1))
        engines = [eng] if eng in tab.versions else []
    else:
        eng, ver = None, text.strip()
        engines = list(tab.versions)
    found = []
    for e in engines:
        vs = tab.versions[e]
        if ver in ("oldest", "newest") and vs:
            found.append((e, vs[0] if ver == "oldest" else vs[-1]))
        elif ver in vs:
            found.append((e, ver))
    if len(found) != 1:
        why = "is held by several engines; write ENGINE==VERSION" if found else "is not held"
        raise InputError(f"--check {text!r}: {why} (the folder holds {held})")
    return found[0]


@dataclass
class CheckResult:
    engine: str
    from_version: str
    to_version: str
    summary: PairSummary
    changes: list
    factor: float = 2.0
    cost_factor: float | None = None
    cost_candidates: list = field(default_factory=list)

    @property
    def failures(self) -> list[Change]:
        out = [c for c in self.changes if c.gates]
        if self.cost_factor is not None:
            out += [
                c
                for c in self.changes
                if c.kind == "cost" and c.ratio and c.ratio > self.cost_factor
            ]
        return out

    @property
    def ok(self) -> bool:
        return not self.failures and not self.summary.not_compared


def check(tab: VersionTable, a: str, b: str, cost_factor: float | None = None) -> CheckResult:
    """The upgrade gate: every change from ``a`` to ``b`` (see :func:`resolve_version`);
    ``ok`` when nothing got worse (status, verdict, a metric beyond its factor and floor, energy
    behaviour from conserved to drifting, a vanished integrator; cost only with
    ``cost_factor``) and every configuration could be compared."""
    ea, va = resolve_version(tab, a)
    eb, vb = resolve_version(tab, b)
    if ea != eb:
        raise InputError(f"--check {a} {b}: two different engines ({ea}, {eb})")
    summary, changes = compare_versions(tab, ea, va, vb)
    return CheckResult(ea, va, vb, summary, changes, tab.factor, cost_factor)


def _val(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return "-" if math.isnan(v) else f"{v:.3g}"
    return str(v)


def change_rows(changes) -> list[list[str]]:
    rows = []
    for c in changes:
        cfg = f"{c.scenario} {c.engine} {c.integrator}"
        if c.dt is not None:
            cfg += f" dt={c.dt:g}"
        if c.target_accuracy is not None:
            cfg += f" acc={c.target_accuracy:g}"
        what = c.column if c.kind in ("metric", "cost") else c.kind
        ratio = "" if c.ratio is None else f"{c.ratio:.3g}"
        rows.append(
            [
                f"{c.from_version} -> {c.to_version}",
                cfg,
                what,
                _short(c.a),
                _short(c.b),
                ratio,
                c.direction,
            ]
        )
    return rows


def _short(v, n: int = 48) -> str:
    text = _val(v)
    return text if len(text) <= n else text[: n - 1] + "…"


SUMMARY_HEAD = ["versions", "configuration", "worse", "better", "changed"]


def summary_rows(changes) -> list[list[str]]:
    """One row per (pair of versions, configuration): what got worse, better or changed
    (metrics by name and ratio, verdict, status, energy behaviour, integrator)."""
    groups: dict = {}
    for c, r in zip(changes, change_rows(changes), strict=True):
        g = groups.setdefault((r[0], r[1]), {"worse": [], "better": [], "changed": []})
        if c.kind in ("metric", "cost"):
            item = c.column + (f" x{c.ratio:.2g}" if c.ratio is not None else " (gone)")
        elif c.kind == "integrator":  # unsupported on one side: absent, or refused the run
            item = ("runs now" if c.direction == "new" else "no longer runs") + (
                f" ({_short(c.b, 30)})" if c.direction == "new" else f" ({_short(c.b, 60)})"
            )
        else:
            item = f"{c.kind} {_short(c.a, 30)} -> {_short(c.b, 30)}"
        word = {"new": "better", "vanished": "worse"}.get(c.direction, c.direction)
        if c.direction == "new" and c.b != "ok":
            word = "changed"  # it runs now, but does not end ok
        g[word].append(item)
    return [[k[0], k[1], "; ".join(v["worse"]), "; ".join(v["better"]), "; ".join(v["changed"])]
            for k, v in groups.items()]  # fmt: skip


CHANGE_HEAD = ["versions", "configuration", "what", "before", "after", "ratio", "change"]


def format_check(res: CheckResult) -> str:
    from reports.gate.format import text_table

    s = res.summary
    lines = [
        f"{res.engine} {res.from_version} -> {res.to_version}: {s.compared} configurations "
        f"compared: {s.identical} identical, {s.within} within a factor {res.factor:g} above "
        f"their floors, {s.changed} changed."
    ]
    shown = sorted(
        res.changes,
        key=lambda c: (
            c not in res.failures,
            _sort_key(c.key) if c.dt is not None else _sort_key((*c.key[:3], -1.0, c.key[4])),
        ),
    )
    if shown:
        lines += ["", *text_table(CHANGE_HEAD, change_rows(shown))]
    if s.not_compared:
        lines += ["", f"Not compared ({len(s.not_compared)}): one side unavailable"]
        lines += [f"  {n}: {why}" for n, why in s.not_compared[:20]]
    fails = res.failures
    lines.append("")
    if fails:
        lines.append(
            f"FAIL: upgrading {res.engine} {res.from_version} -> {res.to_version} makes "
            f"{len(fails)} thing(s) worse."
        )
    elif s.not_compared:
        lines.append("FAIL: some configurations could not be compared (see above).")
    else:
        lines.append(
            f"OK: upgrading {res.engine} {res.from_version} -> {res.to_version} makes "
            "nothing worse."
        )
    return "\n".join(lines)


# -- JSON ---------------------------------------------------------------------------------------


def to_json(tab: VersionTable, environments: list | None = None) -> dict:
    """The document written as ``versions.json`` (NaN -> null)."""
    series = {}
    for (key, ver), r in tab.rows.items():
        ent = series.setdefault(
            _name(key), {"configuration": dict(zip(CONFIG_KEY, key, strict=True)), "versions": {}}
        )
        vals = {c: _json_num(r.get(c)) for c in (*METRIC_COLUMNS, COST_COLUMN)}
        vals.update(
            status=r["status"],
            verdict=r["verdict"],
            message=r["message"] if r["status"] != "ok" else "",
        )
        beh = tab.behaviour.get((key, ver))
        vals["energy_behaviour"] = beh["class"] if beh else None
        ent["versions"][ver] = vals
    return {
        "format": 1,
        "factor": tab.factor,
        "floors": FLOORS,
        "higher_is_better": sorted(HIGHER_IS_BETTER),
        "engines": tab.versions,
        "environments": environments or [],
        "pairs": [asdict(p) for p in tab.pairs],
        "changes": [_json_obj(asdict(c)) for c in tab.changes],
        "cost_candidates": [
            {**_json_obj(asdict(c)), "reason": why} for c, why in tab.cost_candidates
        ],
        "series": series,
    }


def _json_num(v):
    x = num(v)
    if math.isnan(x):
        return None
    return "inf" if math.isinf(x) else x


def _json_obj(d: dict) -> dict:
    return {k: (_json_num(v) if isinstance(v, float) else v) for k, v in d.items()}


def write_json(tab: VersionTable, path: Path, environments=None) -> Path:
    path = Path(path)
    path.write_text(json.dumps(to_json(tab, environments), indent=1, sort_keys=False) + "\n")
    return path
