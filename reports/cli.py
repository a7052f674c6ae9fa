"""Command-line interface ``director-bench``."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    from reports import __version__

    print(f"director-bench {__version__}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
