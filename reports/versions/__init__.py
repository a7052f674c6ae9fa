"""Engine releases side by side: ``director-bench versions`` (see docs/versions.md).

- :mod:`reports.versions.requirements`: the requirement syntax (``mujoco==3.3.0,4.0.0``,
  ``mujoco@path/to.whl``);
- :mod:`reports.versions.envs`: one cached ``uv`` environment per engine version;
- :mod:`reports.versions.matrix`: the suite run in each environment, every row in one store;
- :mod:`reports.versions.changes`: what changed between consecutive versions, the gate;
- :mod:`reports.versions.history`: the self-contained history page.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

#: the environments of the last matrix run into a folder (read back by a later report)
ENVIRONMENTS_FILE = "versions-environments.json"


@dataclass
class VersionsSummary:
    out: Path
    matrix: object  # MatrixResult, or None when only the folder was analysed
    table: object  # changes.VersionTable
    paths: dict
    check: object  # changes.CheckResult, or None


def run_versions(
    requirements=None,
    scenarios=(),
    *,
    out,
    check=None,
    factor: float = 2.0,
    cost_factor: float | None = None,
    figures: bool = True,
    retime: bool = False,
    log=print,
    **run_options,
) -> VersionsSummary:
    """``director-bench versions``: with ``requirements``, run the matrix into ``out``
    (:func:`reports.versions.matrix.run_matrix`, ``run_options`` passed on); then, from the
    folder's store, write ``versions.md``, ``versions.json``, the figures and ``history.html``
    and, with ``check = (FROM, TO)``, decide the upgrade gate
    (:func:`reports.versions.changes.check`). A check of a folder without ``requirements``
    reads it and writes nothing but the timings it had to take: versions.md stays the report
    of the matrix run (``paths`` is empty). Cost candidates are timed once per folder, their
    times recorded and reused (:data:`reports.versions.cost.TIMINGS_FILE`), unless
    ``retime``, so that two calls on one store give one verdict."""
    from reports.versions.changes import check as check_upgrade
    from reports.versions.changes import load_table
    from reports.versions.cost import confirm
    from reports.versions.history import write_history
    from reports.versions.matrix import environments_record, run_matrix
    from reports.versions.report import write_report
    from scenarios.schema import InputError

    if not factor >= 1.0:
        raise InputError(f"--factor {factor!r}: must be a number >= 1")
    out = Path(out)
    matrix = None
    envs = None
    if requirements:
        matrix = run_matrix(requirements, scenarios, out=out, log=log, **run_options)
        envs = environments_record(matrix)
        (out / ENVIRONMENTS_FILE).write_text(json.dumps(envs, indent=1) + "\n")
    elif not (out / "results.sqlite").exists():
        raise FileNotFoundError(
            f"{out}: no results store here; give --engines to run a matrix into it"
        )
    elif (out / ENVIRONMENTS_FILE).exists():
        envs = json.loads((out / ENVIRONMENTS_FILE).read_text())
    tab = load_table(out, factor)
    res = check_upgrade(tab, *check, cost_factor=cost_factor) if check else None
    memo: dict = {}  # cost candidates timed side by side once, for the table and the gate
    cache = run_options.get("cache")
    timed = dict(log=log, memo=memo, folder=out, retime=retime)
    if res is not None:
        res.changes, res.cost_candidates = confirm(tab, res.changes, factor, cache, **timed)
    if res is not None and not requirements:
        return VersionsSummary(out, matrix, tab, {}, res)  # the gate alone: the report stays
    tab.changes, tab.cost_candidates = confirm(tab, tab.changes, factor, cache, **timed)
    paths = write_report(tab, out, envs, figures=figures)
    paths["history"] = write_history([out], out / "history.html", factor)
    return VersionsSummary(out, matrix, tab, paths, res)
