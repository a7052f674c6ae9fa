"""Figures of a robot-model scenario (a ``[model]`` file), drawn from the results folder only:
the per-sample series beside each run's trajectory and the importer-difference table
(``importers/<scenario>.json``, :mod:`reports.run.importers`). Drawn only for a scenario
with that table, with the helpers :mod:`reports.report.plots` passes (colours, legend, alt
text), as :mod:`reports.report.system_plots`.

- :func:`joint_angle_plot` (``<slug>__joint_angles.png``): one panel per engine, the largest
  joint angle error against the reference over time (log axis) of the engine on our reading
  and of its importer's configurations ("RK4 (as loaded)", "RK4 (faithful)"), at the
  scenario's dt;
- :func:`importer_plot` (``<slug>__importers.png``): per engine and configuration (rows) and
  kind of difference (columns, :data:`reports.report.importers.COLUMNS`), the largest
  difference of its importer's model from our reading, as a relative size on one colour
  scale (masses and inertias relative, lengths over the system's size, angles in rad, the
  rest relative to the file's value or 1), the value in its own unit written in the cell; an
  importer that refuses the file is a grey row saying so.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from reports.store.results import is_reference_record

#: the smallest value shown on the log axis (exact zeros drawn here)
FLOOR = 1e-17


#: the lines of a panel: (how the run loaded the model, style)
KINDS = (
    ("our reading", {"color": "tab:blue", "linestyle": "-", "marker": "o"}),
    ("as loaded", {"color": "tab:orange", "linestyle": "--", "marker": "s"}),
    ("faithful", {"color": "tab:green", "linestyle": ":", "marker": "^"}),
)


def joint_angle_plot(rows, h, cache, out: Path, scenario, plt, save, new_figure, legend):
    """The joint angle figure (module docstring): one panel per engine that ran the model
    through its importer, three lines: the engine on our reading (the system builder) and its
    importer's two configurations, at the integrator the importer runs; None when no run has
    the series."""
    from reports.store.runs import slug
    from scenarios.models.configurations import split_variant

    panels: dict = {}
    for r in rows.to_dict("records"):
        if is_reference_record(r):
            continue
        base, config = split_variant(str(r["integrator"]))
        panels.setdefault((r["engine"], base), {})[config or "our reading"] = r
    # a panel only where an importer ran: an engine that reads no model file (the suite's
    # own integrator) has our reading alone
    panels = {k: v for k, v in panels.items() if len(v) > 1 or "our reading" not in v}
    runs, missing = [], []
    for (engine, base), by in panels.items():
        lines, notes = [], []
        for word, st in KINDS:
            r = by.get(word if word == "our reading" else word.replace(" ", "-"))
            s = cache.get(r) if r is not None else None
            if r is not None and r.get("status") == "diverged":  # its few states say little
                t = r.get("t_diverged")
                at = "" if t is None or t != t else f" at t = {t:.3g} s"
                notes.append(f"{word}: diverged{at}")
            elif s is not None and "joint_coordinate_error" in s:
                lines.append((word, st, s))
            elif r is not None:
                notes.append(f"{word}: {r.get('status')}")
        if lines or notes:
            runs.append((f"{engine} {base}", lines, notes))
            missing += [f"{engine} {base} {n}" for n in notes]
    if not runs:
        return None
    fig, axes = new_figure(len(runs), 1.3)
    for ax, (title, lines, notes) in zip(axes, runs, strict=True):
        if notes:  # a run the panel has no line for, said in it
            ax.text(0.01, 0.96, "; ".join(notes), transform=ax.transAxes, fontsize=7,
                    va="top", color="tab:red")  # fmt: skip
        for word, st, s in lines:
            y = np.asarray(s["joint_coordinate_error"], dtype=float)
            y = np.where(np.isnan(y), np.nan, np.maximum(np.abs(y), FLOOR))
            every = max(1, len(y) // 6)
            (line,) = ax.plot(s["t"], y, lw=1.4, ms=4, markevery=every, label=word, **st)
            line.set_gid(f"{title} ({word})")
        ax.set_yscale("log")
        ax.set_ylabel(title, fontsize=7)
        ax.grid(True, which="major", alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    dt = "" if math.isnan(h) else f" at dt = {h:g} s"
    axes[0].set_title(f"{scenario}: largest joint angle error [rad] against the reference{dt}",
                      fontsize=10)  # fmt: skip
    legend(axes[0])
    alt = (f"{scenario}: the largest joint angle error against the reference over time{dt}, "
           f"log axes, one panel per engine ({', '.join(t for t, *_ in runs)}), each with the "
           "engine on our reading of the file and its importer as loaded and faithful"
           + (f"; no line for {', '.join(missing)}" if missing else ""))  # fmt: skip
    return save(fig, Path(out) / f"{slug(scenario)}__joint_angles.png", alt=alt)


def _relative(r: dict, length: float) -> float:
    """A difference row's size on the figure's one scale (module docstring)."""
    size, unit = r["size"], r["unit"]
    if r["quantity"] in ("missing", "unknown body") or size is None:
        return 1.0
    if unit == "%":
        return size / 100.0
    if unit == "m":
        return size / length
    if unit == "kg":
        return 1.0
    return float(size)


def _text(r: dict) -> str:
    size, unit = r["size"], r["unit"]
    if r["quantity"] in ("missing", "unknown body"):
        return "missing" if r["quantity"] == "missing" else "extra"
    if size is None:
        return "differs"
    if unit == "%":
        return f"{size:.2g} %"
    if unit == "m":
        return f"{size * 1e3:.2g} mm"
    return f"{size:.2g} {unit}".strip()


def importer_plot(table: dict, out: Path, plt, save, new_figure):
    """The importer-difference figure (module docstring), or None for an empty table."""
    from matplotlib.colors import LogNorm

    from reports.report.importers import COLUMNS, CONFIG_WORDS
    from reports.store.runs import slug

    by: dict = {}
    for r in table["rows"]:
        by.setdefault((r["engine"], r["config"]), []).append(r)
    keys = [(e, c) for e in table["engines"] for c in table["configs"] if (e, c) in by]
    if not keys:
        return None
    length = float(table.get("length_scale") or 1.0)
    n, m = len(keys), len(COLUMNS)
    val = np.full((n, m), np.nan)
    text = [["" for _ in range(m)] for _ in range(n)]
    refused = {}
    for i, key in enumerate(keys):
        rows = by[key]
        if rows[0]["item"] == "model" or rows[0]["quantity"] == "not installed":
            refused[i] = rows[0]["theirs"] if rows[0]["item"] == "model" else "not installed"
            continue
        for j, (_, qs) in enumerate(COLUMNS):
            hit = [r for r in rows if r["quantity"] in qs]
            if not hit:
                text[i][j] = "-"
                continue
            top = max(hit, key=lambda r: _relative(r, length))
            val[i, j] = max(_relative(top, length), 1e-12)
            text[i][j] = _text(top) + (f" ({len(hit)})" if len(hit) > 1 else "")
    fig, axes = new_figure(1, 0.42 * n + 0.6)
    ax = axes[0]
    ax.set_visible(True)
    cmap = plt.get_cmap("YlOrRd").with_extremes(bad="white")
    im = ax.imshow(np.ma.masked_invalid(val), aspect="auto", cmap=cmap,
                   norm=LogNorm(vmin=1e-10, vmax=1e1), interpolation="nearest")  # fmt: skip
    for i in range(n):
        if i in refused:
            ax.axhspan(i - 0.5, i + 0.5, color="0.85")
            ax.text(m / 2 - 0.5, i, "refuses: " + refused[i][:70], ha="center", va="center",
                    fontsize=6.5)  # fmt: skip
            continue
        for j in range(m):
            dark = not np.isnan(val[i, j]) and val[i, j] > 1e-2
            ax.text(j, i, text[i][j], ha="center", va="center", fontsize=6.5,
                    color="white" if dark else "black")  # fmt: skip
    ax.set_xticks(range(m))
    ax.set_xticklabels([h for h, _ in COLUMNS], rotation=30, ha="right", fontsize=7)
    ax.set_yticks(range(n))
    ax.set_yticklabels([f"{e} ({CONFIG_WORDS.get(c, c)})" for e, c in keys], fontsize=7)
    ax.tick_params(axis="x", labelbottom=True)
    ax.set_title(f"{table['scenario']}: each importer's model against our reading "
                 "(largest difference, count)", fontsize=10)  # fmt: skip
    bar = fig.colorbar(im, ax=ax, fraction=0.04, pad=0.02)
    bar.set_label("relative size (lengths over the system's size)", fontsize=7)
    bar.ax.tick_params(labelsize=7)
    agree = [f"{e} ({CONFIG_WORDS.get(c, c)})" for i, (e, c) in enumerate(keys)
             if i not in refused and np.all(np.isnan(val[i]))]  # fmt: skip
    alt = (f"{table['scenario']}: per engine and importer configuration, the largest difference "
           "of its model from our reading of the file, by kind; "
           + (f"{len(refused)} refuse the file; " if refused else "")
           + (f"agree: {', '.join(agree)}" if agree else "none agrees"))  # fmt: skip
    return save(fig, Path(out) / f"{slug(table['scenario'])}__importers.png", alt=alt)
