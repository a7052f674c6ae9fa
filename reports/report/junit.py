"""JUnit XML of a run's verdicts, for CI systems that show test results.

One test case per run (classname ``director_bench.<scenario>``, name
``<engine>/<integrator>/dt=<dt>``, ``time`` the wall time of its stepping):

- verdict ``fail`` (a metric beyond its tolerance, or a diverged run): a ``<failure>`` whose
  message gives the figures;
- status ``error`` (a fault of the suite): an ``<error>`` with the message and its location;
- statuses ``unsupported``, ``unavailable`` and ``reference-inaccurate``: ``<skipped>`` with
  the reason (nothing could be judged);
- otherwise (``pass``) an empty, passing case.

The counts in the ``<testsuite>`` element therefore agree with the report's status and
verdict counts.

With a baseline (``director-bench check DIR --baseline FILE`` rewrites ``DIR/junit.xml``;
the ``<testsuite>`` then names the baseline in its ``baseline`` attribute), a run that fails
as in the baseline is a *known failure*: ``<skipped message="known failure (as in baseline):
<reason>">``, which JUnit reporters show as not failed; a regression (a metric, status or
verdict worse than the baseline, an identity mismatch, a new or a missing run) is a
``<failure>`` naming what changed, even when the run itself passes.
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from reports.store.atomic import write_text

SKIPPED = frozenset({"unsupported", "unavailable", "reference-inaccurate"})


def case_name(engine: str, integrator: str, dt: float, accuracy=None) -> str:
    """A run's test-case name, ``mujoco/RK4/dt=0.001`` (``/accuracy=1e-08`` for an
    error-controlled integrator; ``accuracy`` None or NaN: none); the gate names runs so too."""
    name = f"{engine}/{integrator}/dt={float(dt):g}"
    if accuracy is not None and not math.isnan(float(accuracy)):
        name += f"/accuracy={float(accuracy):g}"
    return name


def _name(r) -> str:
    return case_name(r["engine"], r["integrator"], r["dt"], r["target_accuracy"])


def _head(scenario, name: str, wall: float) -> str:
    return (
        f"  <testcase classname={quoteattr('director_bench.' + str(scenario))} "
        f'name={quoteattr(name)} time="{wall:.6f}">'
    )


def _body(kind: str, msg) -> str:
    return f"<{kind} message={quoteattr(str(msg))}>{escape(str(msg))}</{kind}>"


def _case(r, note: tuple[str, str] | None = None) -> tuple[str, str]:
    """(kind, XML of one test case); kind is "pass", "failure", "error" or "skipped".
    ``note``: what a baseline says of the run, ("known", reason) or ("regression", what)."""
    wall = float(r["wall_time_s"]) if not math.isnan(float(r["wall_time_s"])) else 0.0
    head = _head(r["scenario"], _name(r), wall)
    status, verdict = r["status"], r["verdict"]
    if note is not None and note[0] == "regression":
        kind, msg = "failure", f"regression against the baseline: {note[1]}"
    elif note is not None and note[0] == "known":
        kind, msg = "skipped", f"known failure (as in baseline): {note[1]}"
    elif status == "error":
        kind, msg = "error", r["message"]
    elif status in SKIPPED:
        kind, msg = "skipped", f"{status}: {r['message']}"
    elif verdict == "fail":
        kind = "failure"
        msg = f"{status}: {r['verdict_detail']}"
        if status == "diverged":
            msg += f" ({r['message']})"
    else:
        return "pass", head + "</testcase>"
    return kind, head + _body(kind, msg) + "</testcase>"


def write(
    df,
    path: str | Path,
    notes: dict | None = None,
    missing: list | None = None,
    baseline: str | None = None,
) -> Path:
    """Write the JUnit XML of the results ``df`` (one row per run) to ``path``.

    With a baseline (see the module docstring): ``notes`` maps a run's configuration key
    (:func:`reports.store.runs.config_key`) to ("known", reason) or ("regression", message);
    ``missing`` lists (key, message) of the baseline's runs absent from ``df`` (each a
    failing case); ``baseline`` names the baseline file."""
    from reports.store.runs import config_key

    notes = notes or {}
    cases, counts = [], {"failure": 0, "error": 0, "skipped": 0, "pass": 0}
    for _, r in df.iterrows():
        key = config_key(r["scenario"], r["engine"], r["integrator"], r["dt"], r["target_accuracy"])
        kind, xml = _case(r, notes.get(key))
        counts[kind] += 1
        cases.append(xml)
    for (sc, eng, integ, dt, acc), msg in missing or []:
        counts["failure"] += 1
        head = _head(sc, case_name(eng, integ, dt, acc), 0.0)
        cases.append(head + _body("failure", msg) + "</testcase>")
    total = float(df["wall_time_s"].fillna(0.0).sum()) if len(df) else 0.0
    attr = "" if baseline is None else f" baseline={quoteattr(str(baseline))}"
    doc = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f'<testsuite name="director-bench" tests="{len(cases)}" failures="{counts["failure"]}" '
        f'errors="{counts["error"]}" skipped="{counts["skipped"]}" time="{total:.6f}"{attr}>',
        *cases,
        "</testsuite>",
    ]
    return write_text(path, "\n".join(doc) + "\n")
