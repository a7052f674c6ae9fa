"""Reports: metrics computed from trajectories, the runner, results tables, plots, reports,
the regression gate and the command-line interface."""

__version__ = "0.1.0"


def cache_root():
    """The suite's cache folder: ``$DIRECTOR_BENCH_CACHE`` or ``~/.cache/director-bench``
    (engine environments of ``versions``, figures reused across results folders, references
    kept across runs), declared once in :func:`references.cache.cache_root`."""
    from references.cache import cache_root as root

    return root()
