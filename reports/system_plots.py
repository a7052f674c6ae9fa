"""Figures of systems of bodies, drawn from the per-sample series written beside each run's
trajectory (:func:`reports.system_metrics.error_series`): pure functions of the results
folder, like every figure of :mod:`reports.plots`.

:func:`system_plot`: per configuration at the scenario's own dt, over time, (1) the largest
gap of the loop closures (m; of every joint for a tree), (2) the energy drift |E - E0| / E_c
and (3) the drift of the conserved momenta (when the system has one), each on a log axis
(round-off, 1e-16, and a joint open by a millimetre on one figure). A value of exactly 0 (a
joint a reduced-coordinate engine holds by construction) is drawn at the axis floor
:data:`FLOOR`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: the smallest value shown on the log axes (exact zeros are drawn here)
FLOOR = 1e-17

#: the panels: (series column, fallback column, y label)
PANELS = (
    ("loop_gap", "joint_gap", "gap [m]"),
    ("energy_drift", None, "|E − E₀| / E_c [1]"),
    ("momentum_drift", None, "momentum drift / scale [1]"),
)


def system_plot(rows, h: float, cache, out: Path, scenario: str, plt, save):
    """The figure of a system scenario (module docstring) as ``<scenario>__system.png`` in
    ``out``, or None when no run has samples. ``rows``: the results to draw (the scenario
    at its dt ``h``); ``cache``: a :class:`reports.plots.SeriesCache` of the folder;
    ``plt``: matplotlib's pyplot; ``save(fig, path, alt=...)`` writes the figure (the
    caller's, so that every figure of a report is written alike)."""
    runs = []
    for _, row in rows.iterrows():
        s = cache.get(row)
        if s is not None and "t" in s:
            runs.append((f"{row['engine']} {row['integrator']}", s))
    if not runs:
        return None
    panels = [p for p in PANELS if any(p[0] in s or (p[1] and p[1] in s) for _, s in runs)]
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 2.3 * len(panels)), sharex=True)
    axes = np.atleast_1d(axes)
    loops = any("loop_gap" in s for _, s in runs)
    colours = plt.get_cmap("tab20").colors
    for ax, (col, alt_col, label) in zip(axes, panels, strict=True):
        for k, (name, s) in enumerate(runs):
            key = col if col in s else alt_col if alt_col and alt_col in s else None
            if key is None:
                continue
            y = np.maximum(np.abs(np.asarray(s[key], dtype=float)), FLOOR)
            style = ("-", "--", ":")[(k // len(colours)) % 3]
            (line,) = ax.plot(s["t"], y, lw=1.2, ls=style, color=colours[k % len(colours)],
                              label=name)  # fmt: skip
            line.set_gid(name)
        ax.set_yscale("log")
        what = "loop closure" if (col == "loop_gap" and loops) else None
        ax.set_ylabel(label if what is None else f"loop closure {label}")
        ax.grid(True, which="major", alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[0].legend(fontsize=7, ncol=2, loc="best")
    dt = "" if math.isnan(h) else f" at dt = {h:g} s"
    axes[0].set_title(f"{scenario}: joints, energy and momentum over time{dt}", fontsize=10)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    alt = (
        f"{scenario}: per engine and integrator{dt}, the "
        + ("loop closure's gap" if loops else "largest joint gap")
        + " in m, the energy drift and the momentum drift over time, log axes"
    )
    return save(fig, out / f"{scenario}__system.png", alt=alt)
