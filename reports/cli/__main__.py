"""``python -m reports.cli``: the ``director-bench`` command."""

from reports.cli import program

program()
