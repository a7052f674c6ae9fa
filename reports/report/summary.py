"""The command line of a results folder's summary:

    python -m reports.report.summary RESULTS_DIR [--readme] [--level 1e-8]

writes ``summary.json`` into the folder (reports.report.summary_json), or with ``--readme``
prints the Markdown block of the README's "What it shows" (reports.report.readme) from the same
scorecard, so that no figure there is copied by hand.
"""

from __future__ import annotations

from pathlib import Path

from reports.report.readme import readme_block
from reports.report.summary_json import write_summary


def main(argv=None) -> int:
    import argparse
    import sys

    from reports.store.provenance import read_provenance
    from reports.store.results import read_results

    p = argparse.ArgumentParser(
        prog="python -m reports.report.summary",
        description="Write summary.json of a results folder, or print the README block.",
    )
    p.add_argument("dir")
    p.add_argument("--readme", action="store_true", help="print the README's Markdown block")
    p.add_argument(
        "--level", type=float, default=1e-8, help="work-precision level of the README block"
    )
    p.add_argument("--scenarios", help="README block: comma-separated scenarios (default all)")
    p.add_argument("--families", help="README block: comma-separated families (default all)")
    args = p.parse_args(argv)

    def names(text):
        return [t.strip() for t in text.split(",") if t.strip()] if text else None

    try:
        df = read_results(args.dir)
        if args.readme:
            cmd = "python -m reports.report.summary results --readme" + "".join(
                f' --{k} "{v}"'
                for k, v in (("scenarios", args.scenarios), ("families", args.families))
                if v
            )
            block = readme_block(
                df, args.level, names(args.scenarios), names(args.families), command=cmd
            )
    except (FileNotFoundError, ValueError) as exc:
        print(f"python -m reports.report.summary: error: {exc}", file=sys.stderr)
        return 2
    if args.readme:
        sys.stdout.write(block)
    else:
        print(write_summary(args.dir, df, read_provenance(Path(args.dir))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
