"""Test-session settings shared by every test file.

The default run uses two pytest-xdist worker processes with ``--dist loadfile`` (addopts in
pyproject.toml): each test file runs whole on one worker, which takes the next file when it is
done. The files are handed out in collection order, so the order below puts the files that take
longest first (longest-first keeps one long file from running alone at the end while the
other worker idles); every other file follows in its usual order. The order is also the order
of a run in one process (``-n 0``), where it changes nothing but the order of the output.
"""

from __future__ import annotations

import os
import tempfile

#: the suite's user cache (reports.cache_root: figures reused across results folders, engine
#: environments) is a fresh folder for the tests, never the user's own
os.environ["DIRECTOR_BENCH_CACHE"] = tempfile.mkdtemp(prefix="director-bench-test-cache-")

#: test files that take longest (seconds of one worker, measured in a two-worker run of the
#: default tests: the fault injection ~100 s, the contact integrator's first compilation on a
#: fresh clone ~120 s of CPU, the report folders, the CLI's subprocess runs, the Dask clusters,
#: the import-layering check, the plug-in's pip install, then the runner's)
LONGEST_FIRST = (
    "test_faults.py",
    "test_contact.py",
    "test_report_figures.py",
    "test_report_documents.py",
    "test_cli_inputs.py",
    "test_distributed.py",
    "test_layers.py",
    "test_plugin.py",
    "test_runner.py",
    "test_engine_drake.py",
)


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    # sorted() is stable: tests keep their order within a file, other files theirs
    items[:] = sorted(items, key=lambda item: rank.get(item.path.name, len(rank)))
