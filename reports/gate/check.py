"""The CI regression gate: baselines of a run's metrics and the comparison against them.

A baseline is a JSON file with one entry per run holding its configuration (scenario, engine,
integrator, dt, target accuracy), its identity (:data:`reports.store.runs.IDENTITY_COLUMNS`:
scenario content hash, horizon, save_every, segmenting, engine and suite versions), its
status, verdict and reason, and its metrics. :func:`compare` matches the runs of a results
folder to the baseline on the configuration and reports, by the comparison rule of
:mod:`reports.gate.rule` (the one ``compare`` applies to two folders):

- a run whose identity differs (``t_end 30 vs 10``, a changed scenario file): a mismatch, never
  a pass, since the two runs did not do the same thing; a run on another release of its engine
  (``engine_version``, e.g. a patch release installed since the baseline was written) is the
  same run, compared as usual, and each release change is reported with how many runs it
  changed (:class:`reports.gate.rule.VersionChange`);
- each metric worse than the baseline by more than a factor, a status that got worse, a
  verdict that went from pass to fail, a failing run that fails a check it passed before;
- runs missing from or new to the results.

Every one of these is a regression (the gate fails, JUnit shows a ``<failure>``). A run that
fails exactly as in the baseline is a *known failure*: listed with its reason, never a
failure. Timing metrics are not gated unless a timing factor is given: shared CI machines
vary by far more than the accuracy metrics do.

Round-off floors: a metric at round-off level (e.g. an energy drift of 3e-15) may double from
one platform or library build to another without meaning anything, so a value is compared
against ``factor * max(baseline, floor)``; the floors are a few orders of magnitude above
double-precision round-off accumulated over the suite's ~1e4-1e5 steps (eps * nstep ~ 1e-11).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

from reports.gate.format import json_number, md_escape, md_table, text_table
from reports.gate.rule import (
    Change,
    Comparison,
    NothingComparable,
    classify,
    count_version_change,
    failed_checks,
    failing,
    status_change,
    verdict_change,
)
from reports.metrics.catalog import HIGHER_IS_BETTER, METRIC_COLUMNS, ORDER_SLACK
from reports.report.junit import SKIPPED, case_name
from reports.store.atomic import write_text
from reports.store.runs import IDENTITY_COLUMNS, STATUSES, config_key, identity_differences
from scenarios.model import RELATIVE_EQUILIBRIA
from scenarios.schema import InputError

TIMING_METRICS = ("ns_per_step",)
#: version of the baseline file layout (3: with each run's identity and failure reason)
BASELINE_FORMAT = 3
_ENTRY_KEYS = ("scenario", "engine", "integrator", "dt", "status", *IDENTITY_COLUMNS)
#: a baseline file larger than this is refused before it is read (the default suite's is
#: about 0.5 MB)
MAX_BASELINE_BYTES = 64 * 2**20
#: a failure reason is cut to this many characters in baselines and reports
REASON_CHARS = 400


def _reason(r) -> str:
    """Why a run fails: its verdict detail, or its status and message."""
    status = str(r.get("status", ""))
    detail = str(r.get("verdict_detail", "") or "")
    if status == "ok":
        text = f"fail: {detail}"
    else:
        text = f"{status}: {r.get('message', '') or detail}"
    return text if len(text) <= REASON_CHARS else text[: REASON_CHARS - 3] + "..."


def write_baseline(results_dir: str | Path, path: str | Path) -> Path:
    """Write the baseline of the run in ``results_dir`` to ``path`` (JSON)."""
    from reports.store.provenance import read_provenance
    from reports.store.results import read_results

    df = read_results(results_dir)
    runs = []
    for _, r in df.sort_values(["scenario", "engine", "integrator", "dt"]).iterrows():
        entry = {k: r[k] for k in ("scenario", "engine", "integrator", "status", "verdict")}
        entry["dt"] = float(r["dt"])
        acc = float(r["target_accuracy"])
        entry["target_accuracy"] = None if math.isnan(acc) else acc
        for col in IDENTITY_COLUMNS:
            v = r[col]
            entry[col] = (None if math.isnan(v) else v) if isinstance(v, float) else v
        entry["reason"] = _reason(r) if failing(r) or r["status"] != "ok" else ""
        entry["failed_checks"] = sorted(failed_checks(r))
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
    objects with the configuration, identity and status of a run and numbers (or null) as
    metrics (ValueError naming the file, the entry, the field and the rule otherwise)."""
    path = Path(path)
    if path.exists() and not path.is_file():
        raise InputError(f"{path}: not a baseline file (not a regular file)")
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_BASELINE_BYTES + 1)
        if len(data) > MAX_BASELINE_BYTES:
            raise InputError(
                f"{path}: not a baseline file (larger than {MAX_BASELINE_BYTES} bytes)"
            )
        doc = json.loads(data.decode("utf-8-sig"))  # a leading byte-order mark is no JSON
    except InputError:  # too large: already says so (it is a ValueError, as JSON's are)
        raise
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: baseline file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read the baseline file ({exc})") from None
    except ValueError as exc:  # invalid JSON, or an integer of more than 4300 digits
        raise InputError(f"{path}: not a baseline file (invalid JSON: {exc})") from None
    except RecursionError:
        raise InputError(f"{path}: not a baseline file (JSON nested too deeply)") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("runs"), list):
        raise InputError(f"{path}: not a baseline file (expected an object with a 'runs' list)")
    if doc.get("format") != BASELINE_FORMAT:
        raise InputError(
            f"{path}: baseline format {doc.get('format')!r}, this suite reads format "
            f"{BASELINE_FORMAT} (with each run's identity: scenario content, horizon, "
            "save_every, segmenting, engine and suite versions); write it again with "
            "`director-bench baseline DIR --write FILE`"
        )
    seen: dict[tuple, int] = {}
    for i, run in enumerate(doc["runs"]):
        missing = [k for k in _ENTRY_KEYS if not isinstance(run, dict) or k not in run]
        if missing:
            raise InputError(f"{path}: runs[{i}] lacks {', '.join(missing)}")
        for k in ("dt", "target_accuracy", *METRIC_COLUMNS, *TIMING_METRICS):
            v = run.get(k)
            if (v is not None or k == "dt") and (
                not isinstance(v, int | float) or isinstance(v, bool)
            ):
                raise InputError(f"{path}: runs[{i}].{k} = {v!r} is not a number")
            rule = _number_rule(k, v)
            if rule:
                raise InputError(f"{path}: runs[{i}].{k} = {_json_text(v)}: {rule}")
        for k, allowed in (("status", STATUSES), ("verdict", VERDICTS)):
            if run.get(k, "") not in allowed:
                raise InputError(
                    f"{path}: runs[{i}].{k} = {run.get(k)!r}: must be one of "
                    f"{', '.join(repr(a) for a in allowed)}"
                )
        key = entry_key(run)
        if key in seen:
            raise InputError(
                f"{path}: runs[{i}] repeats the configuration of runs[{seen[key]}] "
                f"({run_name(key)}): each run is in a baseline once (which of the two would "
                "count is not for the order of the file to decide); remove one, or write "
                "the baseline again with `director-bench baseline DIR --write FILE`"
            )
        seen[key] = i
    return doc


#: the verdicts a baseline entry may hold ("" for a run with nothing to judge)
VERDICTS = ("pass", "fail", "")


def _number_rule(column: str, v) -> str:
    """The rule a number of a baseline entry breaks, or "": no NaN anywhere (the baseline's
    writer writes a value that was not measured as null, and NaN compares as nothing, so a
    baseline of NaN would pass any results); a step is finite and > 0; a metric of error,
    drift or cost is >= 0 (infinite for a run that blew up), a fitted order finite."""
    if v is None or isinstance(v, bool) or not isinstance(v, int | float):
        return ""
    if math.isnan(v):
        return "not a number (a value that was not measured is null)"
    if column == "dt":
        return "" if 0 < v < math.inf else "a step must be finite and > 0"
    if column == "target_accuracy":
        return "" if 0 < v < 1 else "a target accuracy is in (0, 1), or null for a fixed step"
    if column in HIGHER_IS_BETTER:
        return "" if math.isfinite(v) else "a fitted order must be finite"
    return "" if v >= 0 else "must be >= 0 (an error, a drift or a cost; Infinity for a blow-up)"


def _json_text(v) -> str:
    """A number as the JSON file spells it (NaN, Infinity)."""
    if isinstance(v, float) and not math.isfinite(v):
        return "NaN" if math.isnan(v) else ("Infinity" if v > 0 else "-Infinity")
    return repr(v)


def entry_key(b: dict) -> tuple:
    return config_key(
        b["scenario"], b["engine"], b["integrator"], b["dt"], b.get("target_accuracy")
    )


def row_key(r) -> tuple:
    return config_key(r["scenario"], r["engine"], r["integrator"], r["dt"], r["target_accuracy"])


def compare(
    results_dir,
    baseline_path,
    factor: float = 2.0,
    timing_factor: float | None = None,
    only_present: bool = False,
    df=None,
) -> Comparison:
    """Compare the run in ``results_dir`` (or the current rows ``df``) against the baseline.

    ``only_present``: compare only the runs present in both (a partial run, e.g. one
    scenario); by default missing and new runs are findings too. Raises
    :class:`NothingComparable` when the results hold no run or share none with the
    baseline."""
    from reports.store.results import current as current_view
    from reports.store.results import read_results

    if not factor >= 1.0:
        raise InputError(f"--factor {factor!r}: must be a number >= 1")
    base = read_baseline(baseline_path)
    stored = read_results(results_dir, all_rows=True) if df is None else df
    df = current_view(stored) if df is None else df
    current = {row_key(r): r for _, r in df.iterrows()}
    history = {row_key(r): r for _, r in stored.iterrows()}  # newest stored row per key
    expected = {entry_key(b): b for b in base["runs"]}
    if not current:
        raise NothingComparable(
            f"{results_dir}: the results store holds no run, so nothing was checked against "
            f"{baseline_path}; run the suite first (`director-bench run --out {results_dir}`)"
        )
    if not set(current) & set(expected):
        raise NothingComparable(
            f"{results_dir}: none of its {len(current)} run(s) is in the baseline "
            f"{baseline_path} ({len(expected)} runs): nothing was compared (another suite, "
            "or another baseline?)"
        )
    cmp = Comparison(str(baseline_path), str(results_dir), factor)
    cmp.provenance_a = base.get("provenance") or {}
    for key, b in expected.items():
        r = current.get(key)
        if r is None and only_present:
            continue
        cmp.compared.append(key)
        if r is None:
            old = history.get(key)
            why = None
            if old is not None:
                diff = identity_differences(b, old)
                why = (
                    f"history only: {'; '.join(diff)}"
                    if diff
                    else "history only: its scenario's newest runs have another identity"
                )
            cmp.changes.append(Change(key, "", b["status"], why, change="missing", gates=True))
            continue
        found = _run_findings(key, b, r, factor, timing_factor)
        cmp.changes += found
        count_version_change(cmp, key, b, r, found)
        if not found and failing(r):
            cmp.known[key] = (_reason(r), b.get("reason", ""))
    for key in current:
        if key not in expected and not only_present:
            cmp.changes.append(
                Change(key, "", None, current[key]["status"], change="new", gates=True)
            )
    return cmp


def failures_in_baseline(results_dir, df, baseline_path) -> tuple[int, int, int]:
    """(failing as in the baseline, failing otherwise, not in the baseline) of the failing
    runs of ``df`` (a failed verdict or an error, :func:`reports.gate.rule.failing`) against
    the baseline ``baseline_path``: the first are its known failures, the second fail
    differently or anew, the third are runs the baseline does not hold (another scenario,
    engine, integrator or dt). For the closing line of ``run``: the committed baseline says
    which of a suite's failures are expected."""
    failed = {row_key(r) for _, r in df.iterrows() if failing(r)}
    if not failed:
        return 0, 0, 0
    absent = len(failed - {entry_key(b) for b in read_baseline(baseline_path)["runs"]})
    try:
        cmp = compare(results_dir, baseline_path, only_present=True, df=df)
    except NothingComparable:
        return 0, 0, absent
    known = len(failed & set(cmp.known))
    return known, len(failed) - known - absent, absent


def _run_findings(key, b, r, factor, timing_factor) -> list[Change]:
    """The regressions of run ``r`` against its baseline entry ``b`` (:mod:`reports.gate.rule`:
    a status ranked worse, a verdict from pass to fail or failing one more check, a metric
    worse beyond ``factor`` above its floor; timing only with ``timing_factor``)."""

    def regression(column, base, now, ratio=math.nan, change="worse"):
        return Change(key, column, base, now, ratio, change, gates=True)

    diff = identity_differences(b, r)
    if diff:
        return [regression("identity", "baseline", "; ".join(diff), change="mismatch")]
    bs, rs = b["status"], r["status"]
    if status_change(bs, rs) == "worse":
        return [regression("status", bs, f"{rs}: {r['message']}")]
    out = []
    if rs != "ok" or bs != "ok":
        if failing(r) and not failing(b):
            out.append(regression("verdict", "pass", _reason(r)))
        return out
    column, change, new = verdict_change(b, r)
    if change == "worse" and column == "verdict":
        out.append(regression("verdict", "pass", _reason(r)))
    elif change == "worse":
        out.append(regression(column, b.get("reason", ""), f"also fails {new}: {_reason(r)}"))
    for m in (*METRIC_COLUMNS, *TIMING_METRICS):
        cur = float(r[m])
        f = factor if m not in TIMING_METRICS else timing_factor or math.inf
        got = classify(m, b.get(m), cur, f)
        if got is not None and got[1] == "worse":
            out.append(regression(m, b.get(m), cur, _ratio(b.get(m), cur)))
    return out


def _ratio(base, now) -> float:
    """now / base as the message gives it (raw values, not above the floors)."""
    try:
        return float(now) / float(base)
    except (TypeError, ValueError, ZeroDivisionError):
        return math.nan


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3e}"
    return str(v)


def message(c: Change) -> str:
    """A regression as one line of text."""
    if c.what == "mismatch":
        return f"not the baseline's run: {c.b}"
    if c.what == "missing":
        if c.b:  # the store holds the run as history (see results.current)
            return f"missing run (in the baseline with status {c.a}); the store holds it as {c.b}"
        return f"missing run (in the baseline with status {c.a})"
    if c.what == "new":
        return (
            f"new run, not in the baseline (status {c.b}); write the baseline "
            "again if it belongs to the suite"
        )
    if c.what == "metric":
        ratio = "" if math.isnan(c.ratio) else f" ({c.ratio:.3g}x)"
        return f"{c.column}: baseline {_fmt(c.a)}, now {_fmt(c.b)}{ratio}"
    return f"{c.column or c.what}: baseline {_fmt(c.a)}, now {_fmt(c.b)}"


def run_name(key) -> str:
    """``dzhanibekov mujoco/RK4/dt=0.001``: the scenario and the run's JUnit case name."""
    sc, eng, integ, dt, acc = key
    return f"{sc} {case_name(eng, integ, dt, acc)}"


_PROBLEM = {
    "metric": "",
    "status": "status got worse",
    "verdict": "verdict got worse",
    "mismatch": "identity mismatch",
    "missing": "missing run",
    "new": "new run (not in baseline)",
}


def format_comparison(cmp: Comparison) -> str:
    """A readable plain-text summary and table of the findings and the known failures."""
    head_line = (
        f"{len(cmp.compared)} runs checked against the baseline (factor {cmp.factor:g}): "
        f"{len(cmp.regressed)} regressed, {len(cmp.known)} known failure(s) failing as in the "
        "baseline (expected, not regressions)"
    )
    versions = [f"engine release {line}" for line in cmp.version_lines()]
    if cmp.ok:
        return "\n".join([*versions, f"OK: {head_line}."])
    head = ["scenario", "engine", "integrator", "dt", "problem", "baseline", "current", "ratio"]
    rows = []
    for c in cmp.regressions:
        sc, eng, integ, dt, acc = c.key
        integ = integ if acc is None else f"{integ} (accuracy {acc:g})"
        rows.append([sc, eng, integ, f"{dt:g}", _problem(c), _fmt(c.a), _fmt(c.b), _ratio_text(c)])
    n = len(cmp.regressions)
    out = [*versions, f"FAIL: {n} finding(s) in {len(cmp.regressed)} run(s); {head_line}:"]
    return "\n".join(out + text_table(head, rows))


def _problem(c: Change) -> str:
    return _PROBLEM[c.what] or c.column


def _ratio_text(c: Change) -> str:
    return f"{c.ratio:.3g}" if c.what == "metric" and not math.isnan(c.ratio) else ""


def junit_notes(cmp: Comparison) -> tuple[dict, list]:
    """What a baseline says about each run, for :func:`reports.report.junit.write`: a dict
    key -> ("known", reason) | ("regression", message), and the missing runs as
    (key, message)."""
    notes = {key: ("known", reason) for key, (reason, _) in cmp.known.items()}
    missing = []
    for key in cmp.regressed:
        msg = "; ".join(message(c) for c in cmp.for_key(key))
        if any(f.what == "missing" for f in cmp.for_key(key)):
            missing.append((key, msg))
        else:
            notes[key] = ("regression", msg)
    return notes, missing


def annotation(title: str, message: str, level: str = "error") -> str:
    """A GitHub Actions workflow command (``::error title=...::message``), escaped as the
    runner requires (%, CR and LF in the message; also ':' and ',' in the title)."""

    def data(s: str) -> str:
        return s.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")

    def prop(s: str) -> str:
        return data(s).replace(":", "%3A").replace(",", "%2C")

    return f"::{level} title={prop(title)}::{data(message)}"


def annotations(cmp: Comparison) -> list[str]:
    """One GitHub error annotation per regressed run."""
    return [
        annotation(
            f"director-bench regression: {run_name(key)}",
            "; ".join(message(c) for c in cmp.for_key(key)),
        )
        for key in cmp.regressed
    ]


def _run_dict(key) -> dict:
    sc, eng, integ, dt, acc = key
    return {"scenario": sc, "engine": eng, "integrator": integ, "dt": dt, "target_accuracy": acc}


def as_json(cmp: Comparison, problems: list[str]) -> dict:
    """The comparison as a JSON-ready dict (NaN written as null)."""
    return {
        "ok": cmp.ok and not problems,
        "results": cmp.b,
        "baseline": cmp.a,
        "baseline_git_commit": cmp.provenance_a.get("git_commit"),
        "factor": cmp.factor,
        "counts": {
            "checked": len(cmp.compared),
            "regressed": len(cmp.regressed),
            "known_failures": len(cmp.known),
            "passed": len(cmp.compared)
            - len(set(cmp.regressed) & set(cmp.compared))
            - len(cmp.known),
            "findings": len(cmp.regressions),
            "invariant_problems": len(problems),
        },
        "findings": [
            {
                "run": _run_dict(c.key),
                "what": c.what,
                "metric": c.column,
                "baseline": json_number(c.a),
                "current": json_number(c.b),
                "ratio": json_number(c.ratio) if c.what == "metric" else None,
                "message": message(c),
            }
            for c in cmp.regressions
        ],
        "known_failures": [
            {"run": _run_dict(k), "reason": reason, "baseline_reason": was}
            for k, (reason, was) in cmp.known.items()
        ],
        "engine_releases": [dataclasses.asdict(v) for v in cmp.versions.values()],
        "invariant_problems": list(problems),
    }


def as_markdown(cmp: Comparison, problems: list[str]) -> str:
    """The comparison as Markdown, for a job summary or a pull-request comment."""
    doc = as_json(cmp, problems)
    c = doc["counts"]
    verdict = "OK" if doc["ok"] else "FAIL"
    commit = doc["baseline_git_commit"] or "unknown commit"
    out = [
        f"## director-bench check: {verdict}",
        "",
        f"Results `{md_escape(cmp.b)}` against the baseline "
        f"`{md_escape(cmp.a)}` ({md_escape(commit)}), factor {cmp.factor:g}.",
        "",
        *md_table(
            ["runs checked", "passed", "known failures (as in the baseline)", "regressed",
             "invariant problems"],
            [[c["checked"], c["passed"], c["known_failures"], c["regressed"],
              c["invariant_problems"]]],
            "rrrrr",
        ),
    ]  # fmt: skip
    if cmp.versions:
        out += [
            "",
            "Engine releases other than the baseline's (the same runs, compared as usual):",
            "",
        ]
        out += [f"- {md_escape(line)}" for line in cmp.version_lines()]
    if cmp.regressions:
        rows = [
            [run_name(c.key), _problem(c), _fmt(c.a), _fmt(c.b), _ratio_text(c)]
            for c in cmp.regressions
        ]
        out += ["", "### Regressions", ""]
        out += md_table(["run", "problem", "baseline", "now", "ratio"], rows, "llllr")
    if problems:
        out += ["", "### Invariants that do not hold", ""]
        out += [f"- {md_escape(p)}" for p in problems]
    if cmp.known:
        out += [
            "",
            f"<details><summary>{len(cmp.known)} known failure(s), failing as in the "
            "baseline</summary>",
            "",
        ]
        out += md_table(["run", "reason"], [[run_name(k), r] for k, (r, _) in cmp.known.items()])
        out += ["", "</details>"]
    return "\n".join(out) + "\n"


def write_outputs(cmp: Comparison, problems: list[str], markdown: Path, json_path: Path) -> None:
    """Write check.md and check.json, and append the Markdown to ``$GITHUB_STEP_SUMMARY``
    when that variable is set (GitHub Actions' job summary)."""
    md = as_markdown(cmp, problems)
    write_text(markdown, md)
    write_text(json_path, json.dumps(as_json(cmp, problems), indent=1) + "\n")
    summary = os.environ.get("GITHUB_STEP_SUMMARY")
    if summary:
        with open(summary, "a") as fh:
            fh.write(md)


def check(
    results_dir: str | Path,
    baseline_path: str | Path,
    factor: float = 2.0,
    timing_factor: float | None = None,
    markdown: str | Path | None = None,
    json_path: str | Path | None = None,
) -> int:
    """``director-bench check``: compare, check the invariants, rewrite ``junit.xml`` with the
    baseline's expectations, print the table and GitHub annotations of the regressions, write
    the Markdown and JSON summaries (default ``DIR/check.md``, ``DIR/check.json``). Returns
    the exit code: 0 when nothing regressed and every invariant holds, 1 otherwise (also
    when nothing could be compared)."""
    import sys

    from reports.report import junit as junit_xml
    from reports.store.results import read_results

    folder = Path(results_dir)
    markdown = Path(markdown) if markdown else folder / "check.md"
    json_path = Path(json_path) if json_path else folder / "check.json"
    read_baseline(baseline_path)  # a bad baseline is named before the results are read
    df = read_results(folder)
    try:
        cmp = compare(folder, baseline_path, factor, timing_factor)
    except NothingComparable as exc:
        print(f"director-bench: error: {exc}", file=sys.stderr)
        print(annotation("director-bench check: nothing compared", str(exc)))
        return 1
    junit = folder / "junit.xml"
    problems = invariants(df, junit if junit.exists() else None)
    print(format_comparison(cmp))
    if problems:
        print(f"FAIL: {len(problems)} statement(s) the results must make true do not hold:")
        print("\n".join(f"  {p}" for p in problems))
    else:
        print(
            "OK: the results' invariants hold (no blown-up run ok, verdicts match statuses, "
            f"fitted orders within {ORDER_SLACK:g} of declared, junit.xml agrees)."
        )
    for line in annotations(cmp):
        print(line)
    for p in problems:
        print(annotation("director-bench invariant", p))
    notes, missing = junit_notes(cmp)
    written = []
    try:
        written.append(junit_xml.write(df, junit, notes, missing, baseline=str(baseline_path)))
        write_outputs(cmp, problems, markdown, json_path)
        written += [markdown, json_path]
    except OSError as exc:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(
            f"director-bench: warning: {where}{exc.strerror or exc}; the verdict above stands, "
            "but junit.xml and the summaries were not all written",
            file=sys.stderr,
        )
    if written:
        print("written: " + ", ".join(str(p) for p in written))
    return 0 if cmp.ok and not problems else 1


# -- invariants of a suite: statements the results must make true ------------------------------


def invariants(df, junit_path: str | Path | None = None) -> list[str]:
    """What must hold of any results, whatever the engines: every problem found, as a line.

    - no run whose energy error exceeds 100 % of its scale (the divergence limit) is ``ok``;
    - a diverged run fails its verdict; an ``ok`` run has one; error, unsupported,
      unavailable and reference-inaccurate runs have none;
    - a fixed-step integrator's fitted order is within
      :data:`reports.metrics.body.ORDER_SLACK` of its declared order wherever at least two
      points are in the asymptotic range (on a relative equilibrium,
      :data:`scenarios.model.RELATIVE_EQUILIBRIA`, it may exceed it);
    - ``junit.xml`` (if given, as ``run`` wrote it) counts the same failures, errors and skips
      as the results.
    """
    from references.engines.stepping import DIVERGENCE_ENERGY

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
        steady = "reference_kind" in g and g["reference_kind"].iloc[0] in RELATIVE_EQUILIBRIA
        if steady and fitted > declared:
            continue  # above the generic order on a steady motion: not a mislabelled scheme
        if not abs(fitted - declared) <= ORDER_SLACK:
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

    try:
        suite = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        return [f"{path}: not readable JUnit XML ({exc})"]
    if suite.get("baseline") is not None:
        return []  # written by `check` from these results with a baseline's expectations
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
