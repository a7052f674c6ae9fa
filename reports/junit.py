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
"""

from __future__ import annotations

import math
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

SKIPPED = frozenset({"unsupported", "unavailable", "reference-inaccurate"})


def _case(r) -> tuple[str, str]:
    """(kind, XML of one test case); kind is "pass", "failure", "error" or "skipped"."""
    name = f"{r['engine']}/{r['integrator']}/dt={float(r['dt']):g}"
    if not math.isnan(float(r["target_accuracy"])):
        name += f"/accuracy={float(r['target_accuracy']):g}"
    wall = float(r["wall_time_s"]) if not math.isnan(float(r["wall_time_s"])) else 0.0
    head = (
        f"  <testcase classname={quoteattr('director_bench.' + str(r['scenario']))} "
        f'name={quoteattr(name)} time="{wall:.6f}">'
    )
    status, verdict = r["status"], r["verdict"]
    if status == "error":
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
    body = f"<{kind} message={quoteattr(str(msg))}>{escape(str(msg))}</{kind}>"
    return kind, head + body + "</testcase>"


def write(df, path: str | Path) -> Path:
    """Write the JUnit XML of the results ``df`` (one row per run) to ``path``."""
    cases, counts = [], {"failure": 0, "error": 0, "skipped": 0, "pass": 0}
    for _, r in df.iterrows():
        kind, xml = _case(r)
        counts[kind] += 1
        cases.append(xml)
    total = float(df["wall_time_s"].fillna(0.0).sum()) if len(df) else 0.0
    doc = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f'<testsuite name="director-bench" tests="{len(cases)}" failures="{counts["failure"]}" '
        f'errors="{counts["error"]}" skipped="{counts["skipped"]}" time="{total:.6f}">',
        *cases,
        "</testsuite>",
    ]
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text("\n".join(doc) + "\n")
    tmp.replace(path)
    return path
