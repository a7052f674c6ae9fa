"""Reports: metrics computed from trajectories, the runner, results tables, plots, reports,
the regression gate and the command-line interface."""

__version__ = "0.1.0"
