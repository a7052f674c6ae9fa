"""A benchmark's worker process importing another checkout of director-bench, so that two
versions of the same package can be timed side by side in one interleaved run.

The worker is the calling script itself run with ``--worker``, with the checkout first on
PYTHONPATH; it answers one JSON request per line on stdin with one JSON line on stdout.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


class CheckoutWorker:
    """The script ``script`` run as a worker (``--worker``) importing the checkout at ``root``."""

    def __init__(self, root: Path, script: str):
        if not (root / "director_model" / "system").is_dir():
            raise SystemExit(f"--before {root}: not a checkout of director-bench (no "
                             "director_model/system there)")  # fmt: skip
        env = dict(os.environ, PYTHONPATH=f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
        self.p = subprocess.Popen([sys.executable, str(Path(script).resolve()), "--worker"],
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                  env=env, cwd=str(root))  # fmt: skip

    def ask(self, request: dict, what: str) -> dict:
        """The worker's answer to ``request``; ``what`` names the request if the worker
        stopped instead of answering."""
        self.p.stdin.write(json.dumps(request) + "\n")
        self.p.stdin.flush()
        line = self.p.stdout.readline()
        if not line:
            raise SystemExit(f"the worker stopped at {what} (exit {self.p.wait()})")
        return json.loads(line)

    def close(self):
        self.p.stdin.close()
        self.p.wait()
