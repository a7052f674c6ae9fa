"""Imported first by the local workers' fork server (reports.run.parallel): the server ends
when the main process that started it dies, also while it is still importing the modules it
preloads (it checks for its parent's death only between requests).

The main process starts the server directly, with its own process id in the environment
variable :data:`PARENT_VARIABLE`. Importing this module where that variable is set (the
server alone) asks the kernel for SIGKILL on the parent's death (Linux ``PR_SET_PDEATHSIG``),
and a server whose parent is another process by then (the main process died before the
request) ends at once; anywhere else the import does nothing.
The server's children, the workers, do not inherit the request: each makes its own
(reports.run.parallel._die_with_parent).
"""

from __future__ import annotations

import contextlib
import os
import signal

#: the environment variable in which the main process gives the server its process id
PARENT_VARIABLE = "DIRECTOR_BENCH_SERVER_PARENT"


def kill_on_parent_death() -> None:
    """Ask the kernel for SIGKILL when this process's parent dies (Linux
    ``PR_SET_PDEATHSIG``); elsewhere nothing (callers also watch their parent)."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def _guard(parent: str) -> None:
    kill_on_parent_death()
    if os.getppid() != int(parent):
        os._exit(1)


# only in the server (the variable is set for its start alone): another process importing
# this module, the main process included, is left as it is
if os.environ.get(PARENT_VARIABLE, "").isdigit():
    _guard(os.environ.pop(PARENT_VARIABLE))
