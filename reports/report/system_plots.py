"""Figures of systems of bodies, drawn from the per-sample series written beside each run's
trajectory (:func:`reports.metrics.system.error_series`): pure functions of the results
folder, like every figure of :mod:`reports.report.figures`, and drawn with the helpers it passes
(the same colour per configuration, the legend beside the axes, hover text, alt text).

:func:`system_plot`: per group of coinciding configurations at the scenario's own dt, over
time, (1) the largest gap of the loop closures (m; of every joint for a tree), (2) the energy
drift |E - E0| / E_c and (3) the drift of the conserved momenta (when the system has one),
each on a log axis (round-off, 1e-16, and a joint open by a millimetre on one figure). A
value of exactly 0 (a joint a reduced-coordinate engine holds by construction) is drawn at
the axis floor :data:`FLOOR`. The drifts' axes are labelled as in the errors figure, with the
value of the scale each is divided by (``E_c = 66.8 J``). Each configuration has its colour,
line style and marker of every figure (the marker tells apart colours that look alike); the
reference is drawn last, in grey. A configuration that closes a loop with settings of its own
(MuJoCo's ``solref``, Pinocchio's Baumgarte gains, DART's ERP, PyBullet's ``erp``:
:func:`reports.report.tables.closure_settings`) carries the stiffness among them in its
legend entry.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from reports.metrics.catalog import ERROR_PANELS
from reports.store.results import is_reference_record

#: the smallest value shown on the log axes (exact zeros are drawn here)
FLOOR = 1e-17

_DRIFT = {p[0]: p for p in ERROR_PANELS}  # (series, y label, scale column, unit)

#: the panels: (series column, fallback column, y label, scale column, unit, what the title
#: calls it); the drifts labelled as the metric catalog labels them in the errors figure
PANELS = (
    ("loop_gap", "joint_gap", "gap [m]", None, "", "joints"),
    ("energy_drift", None, *_DRIFT["energy_drift"][1:], "energy"),
    ("momentum_drift", None, *_DRIFT["momentum_drift"][1:], "momentum"),
)

#: markers per line over the time axis, every line's first placed a little later than the
#: one before, so that lines lying on one another still show each marker
MARKERS_PER_LINE = 6


def system_plot(
    rows, h: float, cache, out: Path, scenario: str, plt, save, styles=None, new_figure=None,
    legend=None,
):  # fmt: skip
    """The figure of a system scenario (module docstring) as ``<slug>__system.png`` in
    ``out``, or None when no run has samples. ``rows``: the results to draw (the scenario
    at its dt ``h``); ``cache``: a :class:`reports.report.canvas.SeriesCache` of the folder;
    ``plt``: matplotlib's pyplot; ``save(fig, path, alt=...)`` writes the figure. The
    caller's helpers, so that every figure of a report looks alike (this module imports
    nothing of :mod:`reports.report.figures`, which calls it): ``styles``, an object whose
    ``of(row, always_marker=True)`` gives a configuration's colour, line style and marker
    (default: a colour per line);
    ``new_figure(n)``, (figure, n axes sharing t); ``legend(ax)``, the legend of the figure
    beside the axes (default: matplotlib's, inside the first axes)."""
    import textwrap

    from reports.report.groups import group_rows
    from reports.report.labels import config_label, scaled_label
    from reports.report.tables import closure_settings
    from reports.store.runs import slug

    runs = []
    for g in group_rows(rows):
        s = cache.get(g.first)
        if s is not None and "t" in s:
            names = ", ".join(config_label(r) for r in g.rows)
            label = "\n".join(textwrap.wrap(names, 34, break_on_hyphens=False)) or names
            knobs = closure_settings(g.first, short=True)
            if knobs and all(closure_settings(r, short=True) == knobs for r in g.rows):
                label += f"\n({knobs})"
            runs.append((g.first, label, s))
    if not runs:
        return None
    runs.sort(key=lambda run: is_reference_record(run[0]))  # the reference last
    panels = [p for p in PANELS if any(p[0] in s or (p[1] and p[1] in s) for *_, s in runs)]
    if new_figure is not None:
        fig, axes = new_figure(len(panels))
    else:
        fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 2.3 * len(panels)), sharex=True)
        axes = list(np.atleast_1d(axes))
    colours = plt.get_cmap("tab10").colors
    loops = any("loop_gap" in s for *_, s in runs)
    for ax, (col, alt_col, label, scale_col, unit, _) in zip(axes, panels, strict=True):
        for k, (row, name, s) in enumerate(runs):
            key = col if col in s else alt_col if alt_col and alt_col in s else None
            if key is None:
                continue
            y = np.maximum(np.abs(np.asarray(s[key], dtype=float)), FLOOR)
            if is_reference_record(row):
                st = {"color": "0.55", "linestyle": "-", "lw": 2.4, "alpha": 0.6}
            elif styles is not None:
                st = styles.of(row, always_marker=True)
                every = max(1, len(y) // MARKERS_PER_LINE)
                st.update(markevery=(k * max(1, every // len(runs)) % every, every), ms=5)
            else:
                st = {"color": colours[k % len(colours)]}
            (line,) = ax.plot(s["t"], y, lw=st.pop("lw", 1.3), label=name, **st)
            line.set_gid(" ".join(name.split()))
        ax.set_yscale("log")
        if col == "loop_gap":
            label = f"{'loop closure' if loops else 'largest joint'} {label}"
        ax.set_ylabel(scaled_label(label, rows, scale_col, unit))
        ax.grid(True, which="major", alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(0, max(float(s["t"][-1]) for *_, s in runs))
    dt = "" if math.isnan(h) else f" at dt = {h:g} s"
    axes[0].set_title(f"{scenario}: {_and([p[-1] for p in panels])} over time{dt}", fontsize=10)
    if legend is not None:
        legend(axes[0])
    else:
        axes[0].legend(fontsize=7, ncol=2, loc="best")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    said = {
        "joints": f"the largest {'loop closure' if loops else 'joint'} gap in m",
        "energy": "the energy drift",
        "momentum": "the momentum drift",
    }
    n_ref = sum(1 for row, *_ in runs if is_reference_record(row))
    alt = (
        f"{scenario}: per engine and integrator{dt}, {_and([said[p[-1]] for p in panels])} "
        f"over time, log axes, {len(runs) - n_ref} line(s) of configurations"
        + (" and the reference" if n_ref else "")
    )
    return save(fig, out / f"{slug(scenario)}__system.png", alt=alt)


def _and(words: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return ", ".join(words[:-1]) + " and " + words[-1] if len(words) > 1 else words[0]
