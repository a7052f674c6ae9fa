"""The importer-difference table of each robot-model scenario of a run, written into the results
folder (``importers/<scenario>.json``) so that the report draws it as a pure function of the
folder, as every figure.

Each engine's own importer loads the scenario's model file in every configuration
(:func:`references.engines.importers.importer_table`) and its model is read back against our
reading; one row per difference (engine, configuration, item, quantity, ours, theirs, size,
unit, remark), one row per engine whose importer refuses the file or that is not installed.
Only the engines of the run that have an importer are asked. A failure of one engine's
read-back is a row with its message; the others go on.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

#: the folder of the tables inside a results folder
FOLDER = "importers"


def table_of(sc, engines) -> dict:
    """The importer-difference table of the model scenario ``sc`` for ``engines`` (those
    with an importer; module docstring), as the JSON written for the report."""
    from references.engines import importers as imp
    from references.engines.importers import Difference

    asked = [e for e in imp.ENGINES if e in set(engines)]
    rows = []
    for e in asked:
        try:
            diffs = imp.importer_table(sc.model, engines=[e], fixed_base=not sc.floating)
        except Exception as exc:  # noqa: BLE001 - one engine's failure is its row
            diffs = [Difference(e, c, "model", "read-back", "-", f"{type(exc).__name__}: {exc}",
                                math.nan, "") for c in imp.CONFIGS]  # fmt: skip
        rows += [
            {
                "engine": d.engine,
                "config": d.config,
                "item": d.item,
                "quantity": d.quantity,
                "ours": d.ours,
                "theirs": d.theirs,
                "size": None if math.isnan(d.size) else float(d.size),
                "unit": d.unit,
                "remark": d.remark,
            }
            for d in diffs
        ]
    return {
        "scenario": sc.name,
        "file": sc.model_spec.get("file", ""),
        "sha256": sc.model_spec.get("sha256", ""),
        "format": sc.model.format,
        "floating": bool(sc.floating),
        "length_scale": float(sc.length_scale),
        "engines": asked,
        "configs": list(imp.CONFIGS),
        "command": f"director-bench show --importers {sc.name} --engines {','.join(asked)}",
        "rows": rows,
    }


def write_tables(scenarios, engines, out: Path) -> list[Path]:
    """Write the table of every robot-model scenario among ``scenarios`` into
    ``out/importers/``; returns the paths written."""
    paths = []
    for sc in scenarios:
        if getattr(sc, "model", None) is None:
            continue
        from reports.store.runs import slug

        path = Path(out) / FOLDER / f"{slug(sc.name)}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(table_of(sc, engines), indent=1, sort_keys=True))
        tmp.replace(path)
        paths.append(path)
    return paths


@dataclass(frozen=True)
class TablesUnit:
    """The writing of the importer tables (:func:`write_tables`) as a unit of work a runner
    hands a worker beside the runs (reports.run.runner.run_suite ``extra``): each engine's
    importer loads the model files in a process that has the engines imported already,
    while the main process stores rows, instead of importing them all into the main process
    after the runs. Calling it writes the tables; it gives back the paths written."""

    scenarios: tuple
    engines: tuple[str, ...]
    out: str

    def __call__(self) -> list[Path]:
        return write_tables(self.scenarios, self.engines, Path(self.out))


def tables_unit(scenarios, engines, out: Path) -> TablesUnit | None:
    """The :class:`TablesUnit` of the robot-model scenarios among ``scenarios``, or None when
    there is none."""
    models = tuple(sc for sc in scenarios if getattr(sc, "model", None) is not None)
    return TablesUnit(models, tuple(engines), str(out)) if models else None


def read_table(root: Path, scenario: str) -> dict | None:
    """The table of ``scenario`` written into the results folder ``root``, or None."""
    from reports.store.runs import slug

    path = Path(root) / FOLDER / f"{slug(scenario)}.json"
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None
