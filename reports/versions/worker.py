"""Run a given list of runs into a folder, inside an environment of the matrix.

``python -m reports.versions.worker FOLDER SPECS.json``: SPECS.json is a list of objects
(scenario file, engine, integrator, dt, accuracy, t_end, save_every, segment: the planned
run's own values, so that each row gets the identity the matrix looks for); each run's row is
committed to FOLDER's store as it finishes (:func:`reports.run.runner.run_suite`, here, in order).
The matrix uses it to go on after an engine took its process down (an abort in native code):
unlike ``run``, it runs exactly the runs it is given, so a run already recorded as having
crashed is not tried again within the same matrix.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def time_one(argv: list[str]) -> int:
    """``--time SCENARIO ENGINE INTEGRATOR DT``: run it once, nothing written, and print its
    engine time per step (ns) as JSON: the probe of :func:`reports.versions.cost.confirm`."""
    import scenarios
    from references.engines import get_engine
    from reports.run.runner import execute
    from reports.store.runs import RunSpec

    name, engine, integrator, dt = argv[0], argv[1], argv[2], float(argv[3])
    spec = RunSpec(scenarios.load(name), engine, integrator, dt,
                   engine_version=get_engine(engine).version())  # fmt: skip
    row = execute(spec, None)
    print(json.dumps({"status": row["status"], "engine_ns_per_step": row["engine_ns_per_step"]}))
    return 0


def main(argv: list[str]) -> int:
    if argv and argv[0] == "--time":
        return time_one(argv[1:])
    import scenarios
    from references.engines import get_engine
    from reports.run.parallel import serial
    from reports.run.runner import run_suite
    from reports.store.runs import RunSpec

    folder, spec_file = Path(argv[0]), Path(argv[1])
    items = json.loads(spec_file.read_text())
    loaded: dict = {}
    specs = []
    for it in items:
        sc = loaded.setdefault(it["scenario"], scenarios.load(it["scenario"]))
        version = get_engine(it["engine"]).version()
        specs.append(
            RunSpec(
                sc,
                it["engine"],
                it["integrator"],
                it["dt"],
                t_end=it.get("t_end"),
                save_every=it.get("save_every"),
                segment=it.get("segment"),
                engine_version=version,
                accuracy=it.get("accuracy"),
            )  # fmt: skip
        )
    run_suite(specs, folder, progress=False, mapper=serial(folder))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
