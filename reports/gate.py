"""The CI regression gate: baselines of a run's metrics and the comparison against them.

A baseline is a JSON file with one entry per run (scenario, engine, integrator, dt) holding its
status and metrics. :func:`compare` reports, for every run, each metric that got worse than the
baseline by more than a factor, every run whose status got worse, and runs missing from or new
to the results. Timing metrics are not gated unless a timing factor is given: shared CI
machines vary by far more than the accuracy metrics do.

Round-off floors: a metric at round-off level (e.g. an energy drift of 3e-15) may double from
one platform or library build to another without meaning anything, so a value is compared
against ``factor * max(baseline, floor)``; the floors are a few orders of magnitude above
double-precision round-off accumulated over the suite's ~1e4-1e5 steps (eps * nstep ~ 1e-11).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from reports.metrics import HIGHER_IS_BETTER
from reports.results import METRIC_COLUMNS, config_key, read_results

FLOORS = {
    "energy_drift_max": 1e-11,
    "energy_drift_rot_max": 1e-11,
    "energy_drift_trans_max": 1e-11,
    "momentum_drift_max": 1e-11,
    "orthonormality_max": 1e-11,
    "constraint_velocity_max": 1e-11,
    "attitude_error_max": 1e-10,
    "omega_error_max": 1e-10,
    "position_error_max": 1e-10,
    "flip_interval_error": 1e-9,
    "nutation_period_error": 1e-9,
}
#: A fitted convergence order may fall by this much before it counts as a regression.
ORDER_SLACK = 0.3
TIMING_METRICS = ("ns_per_step",)
#: version of the baseline file layout
BASELINE_FORMAT = 2
_ENTRY_KEYS = ("scenario", "engine", "integrator", "dt", "status")


def write_baseline(results_dir: str | Path, path: str | Path) -> Path:
    """Write the baseline of the run in ``results_dir`` to ``path`` (JSON)."""
    from reports.provenance import read_provenance

    df = read_results(results_dir)
    runs = []
    for _, r in df.sort_values(["scenario", "engine", "integrator", "dt"]).iterrows():
        entry = {
            k: r[k]
            for k in ("scenario", "engine", "integrator", "engine_version", "status", "verdict")
        }
        entry["dt"] = float(r["dt"])
        acc = float(r["target_accuracy"])
        entry["target_accuracy"] = None if math.isnan(acc) else acc
        for m in (*METRIC_COLUMNS, *TIMING_METRICS):
            v = float(r[m]) if r[m] == r[m] else None  # NaN -> null
            entry[m] = v
        runs.append(entry)
    prov = read_provenance(results_dir)
    doc = {"format": BASELINE_FORMAT, "provenance": prov, "runs": runs}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return path


def read_baseline(path: str | Path) -> dict:
    """A baseline file, checked: a JSON object of format BASELINE_FORMAT whose ``runs`` are
    objects with scenario, engine, integrator, dt and status (ValueError naming the file and
    the first problem otherwise)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: baseline file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read the baseline file ({exc})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not a baseline file (invalid JSON: {exc})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("runs"), list):
        raise ValueError(f"{path}: not a baseline file (expected an object with a 'runs' list)")
    if doc.get("format") != BASELINE_FORMAT:
        raise ValueError(
            f"{path}: baseline format {doc.get('format')!r}, this suite reads format "
            f"{BASELINE_FORMAT}; write it again with `director-bench baseline DIR --write FILE`"
        )
    for i, run in enumerate(doc["runs"]):
        missing = [k for k in _ENTRY_KEYS if not isinstance(run, dict) or k not in run]
        if missing:
            raise ValueError(f"{path}: runs[{i}] lacks {', '.join(missing)}")
        if not isinstance(run["dt"], int | float) or isinstance(run["dt"], bool):
            raise ValueError(f"{path}: runs[{i}].dt = {run['dt']!r} is not a number")
    return doc


@dataclass
class Finding:
    key: tuple
    what: str  # "metric", "status", "verdict", "missing", "new"
    metric: str = ""
    baseline: object = None
    current: object = None

    @property
    def ratio(self) -> float:
        try:
            return float(self.current) / float(self.baseline)
        except (TypeError, ValueError, ZeroDivisionError):
            return math.nan


@dataclass
class Comparison:
    factor: float
    findings: list[Finding] = field(default_factory=list)
    checked: list[tuple] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.findings

    def for_key(self, key) -> list[Finding]:
        return [f for f in self.findings if f.key == key]


def _worse(metric, base, cur, factor, timing_factor) -> bool:
    if base is None or (isinstance(base, float) and math.isnan(base)):
        return False  # nothing to compare against
    if cur is None or math.isnan(cur):
        return True  # a metric that existed is gone
    if metric in HIGHER_IS_BETTER:
        return cur < base - ORDER_SLACK
    if metric in TIMING_METRICS:
        return timing_factor is not None and cur > timing_factor * base
    return cur > factor * max(base, FLOORS.get(metric, 0.0))


def compare(
    results_dir,
    baseline_path,
    factor: float = 2.0,
    timing_factor: float | None = None,
    only_present: bool = False,
) -> Comparison:
    """Compare the run in ``results_dir`` against the baseline file.

    ``only_present``: compare only the runs present in both (a partial run, e.g. one
    scenario); by default missing and new runs are findings too."""
    if not factor >= 1.0:
        raise ValueError(f"--factor {factor!r}: must be a number >= 1")
    base = read_baseline(baseline_path)
    df = read_results(results_dir)
    current = {
        config_key(r["scenario"], r["engine"], r["integrator"], r["dt"], r["target_accuracy"]): r
        for _, r in df.iterrows()
    }
    expected = {
        config_key(
            b["scenario"], b["engine"], b["integrator"], b["dt"], b.get("target_accuracy")
        ): b
        for b in base["runs"]
    }
    cmp = Comparison(factor)
    for key, b in expected.items():
        r = current.get(key)
        if r is None and only_present:
            continue
        cmp.checked.append(key)
        if r is None:
            cmp.findings.append(Finding(key, "missing", baseline=b["status"]))
            continue
        if b["status"] == "ok" and r["status"] != "ok":
            cmp.findings.append(
                Finding(key, "status", "status", b["status"], f"{r['status']}: {r['message']}")
            )
            continue
        if r["status"] != "ok":
            continue
        if b.get("verdict") == "pass" and r["verdict"] == "fail":
            cmp.findings.append(
                Finding(key, "verdict", "verdict", "pass", f"fail: {r['verdict_detail']}")
            )
        for m in (*METRIC_COLUMNS, *TIMING_METRICS):
            cur = float(r[m])
            if _worse(m, b.get(m), cur, factor, timing_factor):
                cmp.findings.append(Finding(key, "metric", m, b.get(m), cur))
    for key in current:
        if key not in expected and not only_present:
            cmp.findings.append(Finding(key, "new", current=current[key]["status"]))
    return cmp


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3e}"
    return str(v)


def format_comparison(cmp: Comparison) -> str:
    """A readable plain-text table of the findings (empty findings: a one-line summary)."""
    if cmp.ok:
        return f"OK: {len(cmp.checked)} runs match the baseline (factor {cmp.factor:g})."
    head = ["scenario", "engine", "integrator", "dt", "problem", "baseline", "current", "ratio"]
    rows = []
    for f in cmp.findings:
        sc, eng, integ, dt, acc = f.key
        problem = {
            "metric": f.metric,
            "status": "status got worse",
            "verdict": "verdict got worse",
            "missing": "missing run",
            "new": "new run (not in baseline)",
        }[f.what]
        ratio = f"{f.ratio:.3g}" if f.what == "metric" and not math.isnan(f.ratio) else ""
        integ = integ if acc is None else f"{integ} (accuracy {acc:g})"
        rows.append([sc, eng, integ, f"{dt:g}", problem, _fmt(f.baseline), _fmt(f.current), ratio])
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=False)]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))
    out = [
        f"FAIL: {len(cmp.findings)} finding(s) against the baseline (factor {cmp.factor:g}):",
        line,
        "-" * len(line),
    ]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(out)


def write_junit(cmp: Comparison, path: str | Path) -> Path:
    """JUnit XML of a comparison with a baseline: one test case per run compared, failing
    when the run regressed (``director-bench check`` writes it as ``check-junit.xml``)."""
    keys = list(cmp.checked) + [f.key for f in cmp.findings if f.what == "new"]
    cases = []
    nfail = 0
    for key in keys:
        sc, eng, integ, dt, acc = key
        name = f"{eng}/{integ}/dt={dt:g}" + ("" if acc is None else f"/accuracy={acc:g}")
        fails = cmp.for_key(key)
        body = ""
        if fails:
            nfail += 1
            msg = "; ".join(
                f"{f.metric or f.what}: baseline {_fmt(f.baseline)}, current {_fmt(f.current)}"
                for f in fails
            )
            body = f"<failure message={quoteattr(msg)}>{escape(msg)}</failure>"
        cases.append(
            f"  <testcase classname={quoteattr('director_bench.' + sc)} "
            f"name={quoteattr(name)}>{body}</testcase>"
        )
    xml = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f'<testsuite name="director-bench check" tests="{len(keys)}" failures="{nfail}">',
        *cases,
        "</testsuite>",
    ]
    path = Path(path)
    path.write_text("\n".join(xml) + "\n")
    return path


# -- invariants of a suite: statements the results must make true ------------------------------

#: a fitted convergence order may differ from the declared one by this much, where at least
#: two points are in the asymptotic range
ORDER_TOLERANCE = 0.3


def invariants(df, junit_path: str | Path | None = None) -> list[str]:
    """What must hold of any results, whatever the engines: every problem found, as a line.

    - no run whose energy error exceeds 100 % of its scale (the divergence limit) is ``ok``;
    - a diverged run fails its verdict; an ``ok`` run has one; error, unsupported,
      unavailable and reference-inaccurate runs have none;
    - a fixed-step integrator's fitted order is within :data:`ORDER_TOLERANCE` of its
      declared order wherever at least two points are in the asymptotic range;
    - ``junit.xml`` (if given) counts the same failures, errors and skips as the results.
    """
    from references.engines.base import DIVERGENCE_ENERGY

    out = []
    ok = df[df["status"] == "ok"]
    for metric in ("energy_drift_max", "energy_drift_rot_max", "energy_drift_trans_max"):
        if metric not in ok:
            continue  # a store written before the energy parts were measured
        for _, r in ok[ok[metric] > DIVERGENCE_ENERGY].iterrows():  # NaN (pivoted): not over
            what = metric.removesuffix("_max").replace("_", " ")
            out.append(f"{_name(r)}: status ok with {what} {r[metric]:.3g}")
    rules = {"diverged": {"fail"}, "ok": {"pass", "fail"}}
    for _, r in df.iterrows():
        allowed = rules.get(r["status"], {""})
        if r["verdict"] not in allowed:
            out.append(f"{_name(r)}: status {r['status']} with verdict {r['verdict']!r}")
    fits = df[(df["convergence_points"] >= 2) & df["target_accuracy"].isna() & (df["order"] >= 1)]
    for (sc, eng, integ), g in fits.groupby(["scenario", "engine", "integrator"]):
        declared, fitted = float(g["order"].iloc[0]), float(g["convergence_order"].iloc[0])
        if not abs(fitted - declared) <= ORDER_TOLERANCE:
            out.append(
                f"{sc} {eng} {integ}: fitted order {fitted:.3f} from "
                f"{int(g['convergence_points'].iloc[0])} points, declared {declared:g}"
            )
    if junit_path is not None:
        out += _junit_agrees(df, Path(junit_path))
    return out


def _name(r) -> str:
    return f"{r['scenario']} {r['engine']} {r['integrator']} dt={float(r['dt']):g}"


def _junit_agrees(df, path: Path) -> list[str]:
    import xml.etree.ElementTree as ET

    from reports.junit import SKIPPED

    try:
        suite = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        return [f"{path}: not readable JUnit XML ({exc})"]
    want = {
        "tests": len(df),
        "failures": int(((df["verdict"] == "fail") & (df["status"] != "error")).sum()),
        "errors": int((df["status"] == "error").sum()),
        "skipped": int(df["status"].isin(SKIPPED).sum()),
    }
    return [
        f"{path}: {key} = {suite.get(key)}, the results say {n}"
        for key, n in want.items()
        if suite.get(key) != str(n)
    ]
