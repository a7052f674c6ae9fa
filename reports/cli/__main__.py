"""``python -m reports.cli``: the ``director-bench`` command."""

import sys

from reports.cli import main

sys.exit(main())
