"""Comparison plots, pure functions of a results folder (the results table and the per-run
series files the runner writes beside each trajectory). Every function returns the PNG path
it wrote, or None when there is nothing to draw.

One figure per scenario and kind (:data:`KINDS`):

- ``scenario``: the body (the uniform box with its principal moments) and its motion, a
  strip of poses and the trace of one body axis, from the exact reference's run
  (:func:`scenario_picture`; ``python -m reports.report.plots --scenario-figures docs/figures``
  draws the same pictures for the documentation);
- ``errors``: running maxima of the attitude, energy and momentum errors against time at the
  scenario's own dt (log scale), the quantities the metrics report, as they grow; the band
  below the reference's accuracy, where attitude errors are not measurements, is shaded;
- ``rates``: body angular velocity against the reference, with only the configurations that
  visibly leave it drawn; a fast oscillation is shown over its last periods;
- ``system`` (a system of bodies, in the place of ``scenario`` and ``rates``): the loop
  closure's (or largest joint's) gap, the energy and the momentum drift over time per
  configuration (:mod:`reports.report.system_plots`);
- ``convergence``: attitude error against dt (log-log), with the fitted orders;
- ``work_precision``: attitude error against the time spent inside the engine's calls.

and the scorecard as one picture (:func:`scorecard_figure`, ``scorecard.png`` and
``scorecard.svg`` in the results folder).

Styles: a colour and a marker per configuration (:data:`PALETTE`, :data:`MARKERS`), a line
style per integrator family (:data:`FAMILY_STYLE`). Configurations whose results coincide
(reports.report.groups) are one line labelled with all of them. Every figure is as wide
as its legend needs (:func:`_fit`: the legend sits beside the axes and is never cut). A
curve that leaves the plot (a diverged run, an error beyond :data:`CAPS`) is cut where it
leaves and marked there; a diverged run's end is marked with a cross, and its legend entry
says when it diverged (``... (diverged at 1.64 s)``: several crosses close together are told
apart by their lines and entries, not by texts that could overlap); every configuration
cut, left out or not drawn is named under the figure. Beside each PNG a ``.json`` file holds
its alt text and its lines as polylines, which the HTML report uses to name the line under
the pointer.
"""

from __future__ import annotations

import importlib.util
import json
import math
import re
import textwrap
from pathlib import Path

import numpy as np

from reports.metrics import catalog
from reports.metrics.body import SATURATION
from reports.report import figure_cache
from reports.report.groups import group_rows, sweep_groups
from reports.report.labels import (
    ENGINE_ORDER,
    FAMILY_ORDER,
    NOT_RUN,
    config_label,
    engine_key,
    family_key,
    reference_label,
    scaled_label,
)
from reports.report.tables import at_scenario_dt, scenario_dt
from reports.store.atomic import write_text
from reports.store.format import fmt, fmt_step, truthy
from reports.store.results import error_series_path, records, reference_rows, slug

#: colours of the configurations, given out in engine and integrator order so that every
#: configuration of a results folder has its own (tab10, then darker tones of tab20b/c); a
#: line standing for several configurations that coincide takes its first member's colour
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
    "#393b79",
    "#e6550d",
    "#31a354",
    "#843c39",
    "#7b4173",
    "#3182bd",
    "#637939",
    "#8c6d31",
    "#756bb1",
    "#636363",
)

#: the exact reference's colour
REFERENCE_COLOUR = "#555555"

#: one line style per family (families not listed take the next of EXTRA_STYLES)
FAMILY_STYLE = {
    "structure-preserving director": "-",
    "4th-order Lie-group": "--",
    "implicit gyroscopic": "-.",
    "semi-implicit Euler": ":",
}
#: the reference's line style
REFERENCE_STYLE = "-"
EXTRA_STYLES = (
    (0, (6, 1.5, 1, 1.5, 1, 1.5)),
    (0, (10, 3)),
    (0, (1, 3)),
    (0, (4, 1.5, 1, 1.5)),
    (0, (8, 2, 2, 2)),
    (0, (2, 1)),
)

#: markers, given out with the colours (a second cue where two colours look alike: the second
#: half of :data:`PALETTE` repeats the hues of the first, so the markers shift by one each time
#: the colours wrap past ten, :meth:`Styles.__init__`)
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h")

#: the top of the log axes, per series column: beyond it a run has blown up (the metric
#: catalog's panel tops, :data:`reports.metrics.catalog.PANEL_TOPS`)
CAPS = catalog.PANEL_TOPS

#: log axes stop at this floor (exact zeros are drawn there)
FLOOR = 1e-17

#: the rates plot shows a configuration only if its W error exceeds this fraction of max |W|
RATES_VISIBLE = 0.01

#: the rates plot's panels widen to show a drawn run up to this many times max |W| of the
#: reference (a run beyond is cut where it leaves)
RATES_REACH = 2.0

#: a fast oscillation in the rates plot is shown over its last RATES_PERIODS periods
RATES_PERIODS = 12

DPI = 100
#: the width of the axes, inches; a figure is as wide as its axes, tick labels and legend
#: need (:func:`_fit`), so a legend is never cut and every axes has the same width
AXES_WIDTH = 5.6
#: the height of one panel, inches (a figure of three panels, one axes each)
PANEL_HEIGHT = 1.9
#: white space around everything a figure holds, inches
PAD = 0.08


def _plt():
    import matplotlib

    # Agg with text laid out and glyphs rendered once per process: the same pixels
    matplotlib.use("module://reports.report.agg_text")
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "font.size": 10,
            "axes.titlesize": 10.5,
            "axes.labelsize": 10,
            "legend.fontsize": 9,
            "xtick.labelsize": 9,
            "ytick.labelsize": 9,
        }
    )
    return plt


# -- styles -------------------------------------------------------------------------------------


class Styles:
    """Colours, line styles and markers of the configurations of one results table, so that a
    configuration looks the same in every figure: a colour and a marker of its own
    (:data:`PALETTE`, :data:`MARKERS`, in engine and integrator order), a line style per
    integrator family."""

    def __init__(self, df):
        under_test = df.loc[~reference_rows(df), "family"]
        fams = sorted({f for f in under_test if f}, key=family_key)
        extra_s = iter(EXTRA_STYLES * 4)
        self.style = {f: FAMILY_STYLE.get(f) or next(extra_s) for f in fams}
        pairs = sorted(
            set(
                zip(
                    *(df.loc[~reference_rows(df), c] for c in ("engine", "integrator")), strict=True
                )
            ),
            key=lambda p: (engine_key(p[0]), p[1]),
        )
        self.colour = {p: PALETTE[k % len(PALETTE)] for k, p in enumerate(pairs)}
        n = len(MARKERS)
        self.marker = {p: MARKERS[(k + k // n) % n] for k, p in enumerate(pairs)}

    def of(self, row, always_marker: bool = False, engines=None) -> dict:
        """Style of a configuration's line (a group of coinciding configurations drawn as one
        line takes its first member's; ``engines`` is accepted for callers that pass it).
        ``always_marker``: a marker even in time plots' dense lines."""
        key = (row["engine"], row["integrator"])
        return {
            "color": self.colour.get(key, REFERENCE_COLOUR),
            "linestyle": self.style.get(row["family"], REFERENCE_STYLE),
            "marker": self.marker.get(key, "o") if always_marker else None,
        }


def plot_label(rows, width: int = 34) -> str:
    """A legend label for configurations that coincide, named as in the tables
    (``mujoco RK4, pinocchio + suite RKMK4``), wrapped."""
    text = ", ".join(config_label(r) for r in rows)
    wrapped = textwrap.wrap(text, width, break_long_words=False, break_on_hyphens=False)
    return "\n".join(wrapped) or text


def _new_figure(nrows: int = 1, height: float | None = None):
    """A figure of ``nrows`` axes sharing x, each AXES_WIDTH wide and ``height`` (default
    PANEL_HEIGHT) high; :func:`_save` fits the figure around them."""
    plt = _plt()
    h = height or PANEL_HEIGHT
    fig, axes = plt.subplots(
        nrows, 1, figsize=(AXES_WIDTH + 4.0, nrows * h + 1.2), dpi=DPI, sharex=True, squeeze=False
    )
    W, H = fig.get_size_inches()
    gap = 0.12
    for k, ax in enumerate(axes[:, 0]):
        top = H - 0.5 - k * (h + gap)
        ax.set_position([1.0 / W, (top - h) / H, AXES_WIDTH / W, h / H])
    return fig, [a for a in axes[:, 0]]


def _legend(ax, title=None):
    """Legend to the right of the axes, never over data (the figure grows to hold it,
    :func:`_fit`); it lists the labelled artists of every axes of the figure, each label once,
    in two columns when one would be more than 1.6 times as tall as the axes."""
    handles, labels = [], []
    for a in ax.figure.axes:
        for hnd, lab in zip(*a.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(hnd)
                labels.append(lab)
    if not handles:
        return None
    kw = {"loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "frameon": False}
    if title:
        kw["title"] = title
        kw["title_fontsize"] = 9
        kw["alignment"] = "left"
    leg = ax.legend(handles, labels, borderaxespad=0.0, handlelength=3.2, **kw)
    r = ax.figure.canvas.get_renderer()
    axes_h = sum(a.get_window_extent(r).height for a in ax.figure.axes)
    if leg.get_window_extent(r).height > 1.6 * axes_h and len(handles) > 4:
        leg.remove()
        leg = ax.legend(handles, labels, borderaxespad=0.0, handlelength=3.2, ncols=2, **kw)
    return leg


def _fit(fig, notes: str = "") -> None:
    """Resize the figure around its axes (kept at their size in inches) so that everything
    it holds (tick labels, axis labels, titles, the legend beside the axes, annotations) lies
    inside it with PAD to spare; ``notes``: text set under it all, wrapped to its width."""
    from matplotlib.transforms import Bbox

    r = fig.canvas.get_renderer()
    dpi = fig.dpi
    axes = fig.axes
    W, H = fig.get_size_inches()
    inner = Bbox.union([a.get_position() for a in axes])  # figure fractions
    x0, x1, y0, y1 = inner.x0 * W, inner.x1 * W, inner.y0 * H, inner.y1 * H
    ext = Bbox.union([a.get_tightbbox(r) for a in axes])  # pixels
    need_l = max(0.0, x0 - ext.x0 / dpi)
    need_r = max(0.0, ext.x1 / dpi - x1)
    need_b = max(0.0, y0 - ext.y0 / dpi)
    need_t = max(0.0, ext.y1 / dpi - y1)
    new_w = 2 * PAD + need_l + (x1 - x0) + need_r
    note_h, text = 0.0, None
    if notes:
        chars = max(40, int((new_w - 2 * PAD) * 72 / (8.0 * 0.56)))
        wrapped = "\n".join(
            "\n".join(
                textwrap.wrap(
                    _unbroken(par),
                    chars,
                    break_long_words=False,
                    break_on_hyphens=False,
                    subsequent_indent="  ",
                )
            )
            for par in notes.split("\n")
        )
        text = fig.text(0, 0, wrapped, fontsize=8.0, color="0.25", ha="left", va="bottom")
        note_h = text.get_window_extent(r).height / dpi + 0.1
    new_h = 2 * PAD + note_h + need_b + (y1 - y0) + need_t
    fig.set_size_inches(new_w, new_h)
    for a in axes:
        p = a.get_position()
        ax0 = PAD + need_l + (p.x0 * W - x0)
        ay0 = PAD + note_h + need_b + (p.y0 * H - y0)
        a.set_position([ax0 / new_w, ay0 / new_h, p.width * W / new_w, p.height * H / new_h])
    if text is not None:
        text.set_position((PAD / new_w, PAD / new_h))


#: a space that a note under a figure never breaks at: between a number and its unit
#: (``0.107 s``) and after ``dt`` (``dt 0.001``); a no-break space in its place
UNBROKEN = re.compile(r"(?<=\d) (?=(?:s|rad|rad/s|J|m|kg)\b)|(?<=\bdt) (?=\d)")


def _unbroken(text: str) -> str:
    """``text`` with the spaces of :data:`UNBROKEN` made no-break spaces (textwrap and
    the figure's text see them as letters; they are drawn as spaces)."""
    return UNBROKEN.sub("\u00a0", text)


def _hover_lines(fig, width_px: float, height_px: float) -> list[dict]:
    """The lines of the figure that stand for configurations (an artist with a ``gid``: the
    label to show), as polylines in fractions of the image (x right, y down), clipped to
    their axes and simplified to within about a pixel (matplotlib's own path cleanup)."""
    import matplotlib
    from matplotlib.path import Path as MPath

    out = {}
    with matplotlib.rc_context({"path.simplify_threshold": 1.0}):
        for ax in fig.axes:
            ax.get_xlim(), ax.get_ylim()  # apply any pending autoscaling to the transforms
            box = ax.get_window_extent()
            for line in ax.get_lines():
                gid = line.get_gid()
                if not gid:
                    continue
                path = line.get_transform().transform_path(line.get_path())
                path = MPath(path.vertices)  # with the threshold above, no codes
                clean = path.cleaned(remove_nans=True, clip=box.extents, simplify=True)
                paths, cur = [], []
                for (x, y), code in zip(clean.vertices, clean.codes, strict=True):
                    if code == MPath.STOP:
                        break
                    if code == MPath.MOVETO and cur:
                        paths.append(cur)
                        cur = []
                    cur.append([round(x / width_px, 4), round(1.0 - y / height_px, 4)])
                if cur:
                    paths.append(cur)
                if paths:
                    out.setdefault(gid, []).extend(paths)
    return [{"label": k, "paths": v} for k, v in out.items()]


def _save(fig, path: Path, alt: str = "", notes: str = "") -> Path:
    """Fit the figure (:func:`_fit`), write it as PNG and, beside it (``.json``), the alt
    text and the lines a reader can hover over in the HTML report; release the figure."""
    import json

    _fit(fig, notes)
    w, h = fig.get_size_inches() * fig.dpi
    meta = {"alt": alt, "lines": _hover_lines(fig, w, h)}
    path.parent.mkdir(parents=True, exist_ok=True)  # a folder holding only an ensemble has none
    _write_png(fig, path)
    _plt().close(fig)
    path.with_suffix(".json").write_text(json.dumps(meta, separators=(",", ":")))
    return path


def _write_png(fig, path: Path, **kw) -> None:
    """Save the figure at DPI as a PNG of at most 256 colours (a third of the size of a
    full-colour one, the same to the eye for line art). Without ``kw`` (savefig's keywords,
    e.g. ``bbox_inches``) the canvas is drawn once and its pixels quantized directly: the
    same pixels ``savefig`` would write, without encoding and decoding a full-colour PNG
    in between."""
    import io

    from PIL import Image

    if kw:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=DPI, **kw)
        buf.seek(0)
        im = Image.open(buf)
    else:
        fig.set_dpi(DPI)  # what savefig(dpi=DPI) draws at
        fig.canvas.draw()
        im = Image.frombuffer("RGBA", fig.canvas.get_width_height(physical=True),
                              fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)  # fmt: skip
    with im:
        im.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(
            path, format="PNG"
        )


def figure_meta(png: Path) -> dict:
    """The alt text and hover lines written beside a figure by :func:`_save` (empty if the
    file is missing or unreadable)."""
    import json

    try:
        meta = json.loads(Path(png).with_suffix(".json").read_text())
    except (OSError, ValueError):
        return {}
    return meta if isinstance(meta, dict) else {}


def name_list(names, limit: int = 0) -> str:
    """``a, b and c``; ``limit``: at most this many names, then ``and N more``."""
    names = list(dict.fromkeys(names))
    if limit and len(names) > limit:
        names = [*names[:limit], f"{len(names) - limit} more"]
    if len(names) < 2:
        return "".join(names)
    return ", ".join(names[:-1]) + " and " + names[-1]


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _decade(v, _pos=None) -> str:
    """A log-axis tick label as plain text, ``10⁻⁵`` (cheaper to lay out than mathtext)."""
    if not v > 0:
        return ""
    e = math.log10(v)
    if abs(e - round(e)) > 1e-9:
        return ""
    e = int(round(e))
    return {0: "1", 1: "10"}.get(e, "10" + str(e).translate(_SUPERSCRIPT))


def _log_axes(ax, x: bool = False) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

    axes = [ax.yaxis, ax.xaxis] if x else [ax.yaxis]
    for a in axes:
        a.set_major_locator(LogLocator(base=10.0, numticks=12))
        a.set_major_formatter(FuncFormatter(_decade))
        # minor ticks on a 17-decade axis are ~150 tick objects: half a figure's drawing time
        a.set_minor_locator(NullLocator())


#: a line is drawn from at most this many points (the figure is 900 px wide)
MAX_POINTS = 2500


def _thin(t, *ys):
    """Every k-th sample (and the last) so that a line has at most MAX_POINTS points: the
    running maxima are monotone, and an oscillation keeps more than 100 points per period
    over the windows the rates plot shows."""
    n = len(t)
    if n <= MAX_POINTS:
        return (t, *ys)
    idx = np.unique(np.append(np.arange(0, n, math.ceil(n / MAX_POINTS)), n - 1))
    return (t[idx], *(y[idx] for y in ys))


# -- data ---------------------------------------------------------------------------------------


class SeriesCache:
    """The per-sample series files of a results folder, each read once."""

    def __init__(self, root: Path):
        self.root = Path(root)
        self._data: dict[str, dict | None] = {}
        self._bodies: dict[str, dict] = {}

    def get(self, row) -> dict | None:
        rel = row.get("trajectory") or ""
        if not rel:
            return None
        if rel not in self._data:
            import pyarrow.parquet as pq

            p = self.root / error_series_path(Path(rel))
            if not p.exists():
                self._data[rel] = None
            else:
                t = pq.read_table(p)
                self._data[rel] = {c: t.column(c).to_numpy() for c in t.column_names}
                body = (t.schema.metadata or {}).get(b"director_bench.body")
                if body is not None:
                    self._bodies[rel] = json.loads(body)
        return self._data[rel]

    def body(self, row):
        """The scenario's body stored beside the run's series (reports.run.runner.body_of):
        an object with ``name``, ``mass``, ``inertia``, ``pivot`` (None: free) and
        ``omega_body``, or None (a folder written before the body was stored)."""
        if self.get(row) is None:
            return None
        b = self._bodies.get(row.get("trajectory") or "")
        if b is None:
            return None
        from types import SimpleNamespace

        def vec(v):
            return None if v is None else np.asarray(v, dtype=float)

        return SimpleNamespace(
            name=str(b["name"]), mass=float(b["mass"]), inertia=vec(b["inertia"]),
            pivot=vec(b["pivot"]), omega_body=vec(b["omega_body"]),
        )  # fmt: skip


def _running_max(y: np.ndarray) -> np.ndarray:
    """max over samples 0..i of y (NaN samples ignored)."""
    y = np.where(np.isnan(y), -np.inf, y)
    return np.maximum.accumulate(y)


def _clip_at(ax, t, y, top, **style):
    """Plot ``y(t)``, cut where it first exceeds ``top`` (or becomes infinite), with a
    marker on the top edge there. Returns the line and the point where it left, or None;
    the line's gid is its label (the name the HTML report shows on hover)."""
    bad = np.isinf(y) | (y > top)  # NaN: a gap (an exact zero on a log axis), not an exit
    exit_pt = None
    if bad.any():
        k = int(np.argmax(bad))
        exit_pt = (t[k], top)
        t, y = t[:k], y[:k]
    (line,) = ax.plot(t, y, **style)
    line.set_gid(_flat(style.get("label")))
    if exit_pt is not None:
        ax.plot(*exit_pt, marker="^", ms=8, color=style["color"], clip_on=False, zorder=5)
    return line, exit_pt


def _flat(label) -> str:
    """A legend label on one line (the hover text)."""
    return " ".join(str(label).split()) if label else ""


def _diverged_mark(ax, x, y) -> None:
    """A cross where a diverged run ends (its time is in its legend entry,
    :func:`_line_label`)."""
    ax.plot(x, y, marker="x", ms=9, mew=2.2, color="#b00020", clip_on=False, zorder=6)


def _line_label(g) -> str:
    """A time plot's legend entry for a group of configurations: :func:`plot_label`, and for
    a diverged group when it diverged, on a line of its own."""
    label = plot_label(g.rows)
    if g.outcome == "diverged":
        label += f"\n(diverged at {fmt(g.value('t_diverged'))} s)"
    return label


def _plot_rows(df, scenario):
    """The rows a time plot shows: the scenario at its own dt, runs that produced samples."""
    sub = df[df["scenario"] == scenario]
    if sub.empty:
        return sub, math.nan
    rows = at_scenario_dt(sub)
    rows = rows[rows["status"].isin(("ok", "diverged", "reference-inaccurate"))]
    return rows, scenario_dt(sub)


# -- time plots ---------------------------------------------------------------------------------

#: the panels of the errors-over-time figure: (series column, y label, scale column, unit), the
#: metric catalog's (:data:`reports.metrics.catalog.ERROR_PANELS`)
ERROR_PANELS = catalog.ERROR_PANELS


def errors_plot(df, cache: SeriesCache, out: Path, scenario: str, styles: Styles):
    """Running maxima of the attitude, energy and momentum errors against time at the
    scenario's dt (three log panels sharing t), one line per group of coinciding
    configurations; the reference's own drift (a closed form's round-off) in grey; the band below
    the reference's accuracy shaded; curves beyond :data:`CAPS` cut and marked, and named
    under the figure."""
    rows, h = _plot_rows(df, scenario)
    if rows.empty:
        return None
    groups = []
    for g in group_rows(rows[~reference_rows(rows)]):
        s = cache.get(g.first)
        if s is not None:
            groups.append((g, s))
    if not groups:
        return None
    exact = rows[reference_rows(rows)]
    ref = cache.get(exact.iloc[0]) if len(exact) else None
    # a panel only for a quantity measured here (the momentum of a pivoted body under
    # gravity is not conserved: no series)
    panels = [
        p
        for p in ERROR_PANELS
        if any(p[0] in s and np.any(np.isfinite(s[p[0]]) & (s[p[0]] > 0)) for _, s in groups)
    ]
    if not panels:
        return None
    fig, axes = _new_figure(len(panels))
    axes[-1].set_xlim(0, float(rows["t_end"].max()))
    off = {}
    system = is_system(df, cache, scenario)
    for ax, (column, ylabel, scale_col, unit) in zip(axes, panels, strict=True):
        if system and column == "attitude_error":
            ylabel = "attitude error [rad]\n(largest over bodies)"
        left = _error_panel(ax, rows, groups, ref, column, styles)
        for name, t_left in left:
            off.setdefault(name, []).append((column, t_left))
        ax.set_ylabel(scaled_label(ylabel, rows, scale_col, unit))
        ax.grid(True, which="major", alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(0, float(rows["t_end"].max()))
    axes[0].set_title(f"{scenario}: errors against time, running max (dt = {fmt_step(h)} s)")
    _legend(axes[0])
    words = {m.series: m.short for m in catalog.METRICS if m.panel}
    notes = ""
    if off:
        notes = "Beyond the top of a panel (cut there, ▲): " + "; ".join(
            f"{name} ({', '.join(f'{words[c]} at t = {fmt(t)} s' for c, t in where)})"
            for name, where in off.items()
        )
    diverged = [g for g, _ in groups if g.outcome == "diverged"]
    alt = (
        f"{scenario}: running maximum of the "
        + name_list(
            [f"{words[p[0]]} {'error' if p[0] == 'attitude_error' else 'drift'}" for p in panels]
        )
        + f" against time at dt = {fmt_step(h)} s for {len(groups)} line(s) of configurations"
        + (f"; diverged: {name_list(g.label for g in diverged)}" if diverged else "; none diverged")
        + "."
    )
    return _save(fig, out / f"{slug(scenario)}__errors.png", alt=alt, notes=notes)


def _reference_drift_label(rows) -> str:
    """The legend of the reference's own drift: a closed form's is its round-off, a numerical
    reference's its integration error as well."""
    exact = rows[reference_rows(rows)]
    name = reference_label(exact.iloc[0]) if len(exact) else "exact reference"
    return f"{name}\n({'its round-off' if name == 'exact reference' else 'its own drift'})"


def _error_panel(ax, rows, groups, ref, column, styles) -> list:
    """One panel of the errors figure; returns (label, t) of the lines cut at its top."""
    lines = []
    for g, s in groups:
        if column in s:
            lines.append((*_thin(s["t"], _running_max(s[column])), g))
    ref_line = None
    if ref is not None and column in ref and column != "attitude_error":
        ref_line = _thin(ref["t"], _running_max(ref[column]))
    vals = [y[np.isfinite(y) & (y > 0)] for _, y, _ in lines]
    vals = np.concatenate([v for v in vals if v.size] or [np.array([1.0])])
    top = min(CAPS[column], 3.0 * float(vals.max()))
    bottom = max(FLOOR, float(vals.min()) / 3.0)
    if ref_line is not None:
        ry = ref_line[1][np.isfinite(ref_line[1]) & (ref_line[1] > 0)]
        if ry.size:
            bottom = min(bottom, max(FLOOR, float(ry.min()) / 3.0))
    left_top = []
    for t, y, g in lines:
        st = styles.of(g.first, engines=g.engines)
        y = np.where(y > 0, np.maximum(y, bottom), np.nan)  # log axis: zeros start the curve
        kw = {
            "color": st["color"],
            "linestyle": st["linestyle"],
            "lw": 1.7,
            "label": _line_label(g),
        }
        if np.isfinite(y).sum() > 1:  # markevery needs a drawn line
            mk = styles.of(g.first, always_marker=True)["marker"]
            kw.update(marker=mk, markevery=(0.04 + 0.025 * len(ax.lines), 0.2), ms=5)
        _, left = _clip_at(ax, t, y, top, **kw)
        if left is not None:
            left_top.append((_flat(plot_label(g.rows)), left[0]))
        if g.outcome == "diverged" and np.isfinite(y).any():
            _diverged_mark(ax, *(left if left is not None else (t[-1], min(np.nanmax(y), top))))
    if ref_line is not None:
        t, y = ref_line
        ax.plot(
            t,
            np.where(y > 0, np.maximum(y, bottom), np.nan),
            color="0.55",
            lw=1.0,
            label=_reference_drift_label(rows) if column == "energy_drift" else None,
        )
    if column == "attitude_error":
        acc = float(np.nanmax(rows["reference_accuracy"]))
        if acc > bottom:
            ax.axhspan(bottom, acc, color="0.88", zorder=0, label="below the reference's\naccuracy")
    ax.set_yscale("log")
    _log_axes(ax)
    ax.set_ylim(bottom, top * 1.05)
    return left_top


def _window(t, w_ref, t_stop: float | None = None) -> tuple[float, float]:
    """The time window of the rates plot, ending at ``t_stop`` (default: the end): all of it,
    or the last RATES_PERIODS periods of a fast oscillation (counted from the sign changes
    about the mean)."""
    if t_stop is not None:
        keep = t <= t_stop
        t, w_ref = t[keep], w_ref[keep]
    best = np.array([], dtype=int)
    for k in range(3):
        c = w_ref[:, k] - np.mean(w_ref[:, k])
        idx = np.nonzero(np.diff(np.signbit(c)))[0]
        if idx.size > best.size:
            best = idx
    if best.size > 2 * RATES_PERIODS + 1:
        return float(t[best[-2 * RATES_PERIODS - 1]]), float(t[-1])
    return float(t[0]), float(t[-1])


def _clipped_line(ax, tt, y, lim, st, label, gid):
    """Draw y(tt) in the style ``st`` up to where it first leaves ``lim`` (or stops being
    finite), marking that point on the edge with a triangle; returns the time it left, or
    None."""
    lo, hi = lim
    out_of = ~np.isfinite(y) | (y < lo) | (y > hi)
    left = None
    if out_of.any():
        j = int(np.argmax(out_of))
        edge = hi if (np.isfinite(y[j]) and y[j] > hi) or not np.isfinite(y[j]) else lo
        ax.plot(tt[j], edge, marker="^" if edge == hi else "v", ms=8, color=st["color"])
        left = float(tt[j])
        tt, y = tt[:j], y[:j]
    kw = {}
    if st["marker"] and np.isfinite(y).sum() > 1:  # markevery needs a drawn line
        kw = {"marker": st["marker"], "markevery": 0.1, "ms": 5}
    (line,) = ax.plot(
        tt, y, color=st["color"], linestyle=st["linestyle"], lw=1.5, label=label, zorder=3, **kw
    )
    line.set_gid(gid)
    return left


def _rates_selection(df, cache: SeriesCache, scenario: str):
    """What the rates figure of a scenario would draw: None without a reference series, else
    (rows, dt, reference name, reference series, max |W| of the reference, the groups drawn
    (diverged, or W error above RATES_VISIBLE max |W|), the labels of those within it)."""
    rows, h = _plot_rows(df, scenario)
    exact = rows[reference_rows(rows)]
    ref = cache.get(exact.iloc[0]) if len(exact) else None
    if ref is None:
        return None
    w_ref = np.column_stack([ref["wx"], ref["wy"], ref["wz"]])
    wmax = float(np.max(np.abs(w_ref))) or 1.0
    shown, hidden = [], []
    for g in group_rows(rows[~reference_rows(rows)]):
        err = g.value("omega_error_max")
        if cache.get(g.first) is None:
            continue
        if g.outcome == "diverged" or not (err <= RATES_VISIBLE * wmax):
            shown.append(g)
        else:
            hidden.append(g.label)
    return rows, h, reference_label(exact.iloc[0]), ref, wmax, shown, hidden


def rates_left_out(df, cache: SeriesCache, scenario: str) -> str:
    """The sentence the report gives in place of a single body's rates figure that is not
    drawn because every configuration stays within RATES_VISIBLE of max |W| of the reference
    (the figure would be the reference alone); '' when the figure is drawn or there is no
    reference to draw it against."""
    if is_system(df, cache, scenario):
        return ""
    sel = _rates_selection(df, cache, scenario)
    if sel is None or sel[5] or not sel[6]:
        return ""
    _, _, ref_name, _, wmax, _, hidden = sel
    who = f"all {len(hidden)} configuration groups" if len(hidden) > 1 else "its one configuration"
    return (
        f"No rates figure: the W error of {who} stays within {RATES_VISIBLE:.0%} of the "
        f"{ref_name}'s max |W| ({fmt(wmax)} rad/s) throughout, so the figure would show the "
        f"{ref_name} alone; the W errors are in the table above."
    )


def rates_plot(df, cache: SeriesCache, out: Path, scenario: str, styles: Styles):
    """Body rates W_1, W_2, W_3 against the reference (thick grey), one panel each. Only the
    configurations whose W error exceeds RATES_VISIBLE of max |W| are drawn (the others are
    named under the figure); y ranges are the reference's widened to the drawn runs up to
    RATES_REACH max |W| (a blown-up run is cut where it leaves them, and named). A fast
    oscillation is shown over its last periods, ending where the last drawn run diverged when
    every drawn run diverged before the end. None when no configuration would be drawn (the
    report says so instead, :func:`rates_left_out`)."""
    sel = _rates_selection(df, cache, scenario)
    if sel is None or not sel[5]:
        return None
    rows, h, ref_name, ref, wmax, shown, hidden = sel
    t_ref = ref["t"]
    w_ref = np.column_stack([ref["wx"], ref["wy"], ref["wz"]])
    ends = [float(cache.get(g.first)["t"][-1]) for g in shown]
    t_stop = None
    if shown and max(ends) < t_ref[-1] - 1e-12:
        t_stop = max(ends)  # every drawn run ended early: show the time before it did
    t0, t1 = _window(t_ref, w_ref, t_stop)
    fig, axes = _new_figure(3)
    axes[-1].set_xlim(t0, t1)
    sel = (t_ref >= t0) & (t_ref <= t1)
    lims = []
    for k, ax in enumerate(axes):
        w = w_ref[sel, k]
        lo, hi = float(w.min()), float(w.max())
        # the drawn runs widen the range up to RATES_REACH max|W| (then they are cut), so
        # that a run leaving the reference is seen leaving it
        for g in shown:
            s = cache.get(g.first)
            y = s[("wx", "wy", "wz")[k]][(s["t"] >= t0) & (s["t"] <= t1)]
            y = y[np.isfinite(y) & (np.abs(y) <= RATES_REACH * wmax)]
            if y.size:
                lo, hi = min(lo, float(y.min())), max(hi, float(y.max()))
        pad = 0.15 * max(hi - lo, 0.05 * wmax)
        lims.append((lo - pad, hi + pad))
        ax.plot(*_thin(t_ref[sel], w), color="0.6", lw=4.0, label=ref_name, zorder=1)
    before, outside = [], {}
    for g in shown:
        s = cache.get(g.first)
        st = styles.of(g.first, always_marker=True)
        t = s["t"]
        label = _line_label(g)
        if t[-1] < t0:
            before.append(_flat(label))
            continue
        m = (t >= t0) & (t <= t1)
        for k, (ax, col) in enumerate(zip(axes, ("wx", "wy", "wz"), strict=True)):
            left = _clipped_line(
                ax, *_thin(t[m], s[col][m]), lims[k], st, label if k == 0 else None, _flat(label)
            )
            if left is not None:
                outside.setdefault(_flat(plot_label(g.rows)), []).append(
                    f"W{'₁₂₃'[k]} at t = {fmt(left)} s"
                )
        if g.outcome == "diverged" and t0 <= t[-1] <= t1:
            _diverged_mark(axes[0], t[-1], lims[0][1])
    for k, ax in enumerate(axes):
        ax.set_ylim(*lims[k])
        ax.set_ylabel(f"W{'₁₂₃'[k]} [rad/s]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(t0, t1)
    window = "" if t0 <= t_ref[0] and t1 >= t_ref[-1] else f", {fmt(t0)} to {fmt(t1)} s"
    axes[0].set_title(
        f"{scenario}: body angular velocity, body axes (dt = {fmt_step(h)} s{window})"
    )
    _legend(axes[0])
    parts = []
    if outside:
        parts.append(
            "Left the plotted range (cut there, ▲▼): "
            + "; ".join(f"{n} ({', '.join(w)})" for n, w in outside.items())
        )
    if before:
        parts.append("Diverged before this window, not drawn: " + "; ".join(before))
    if hidden:
        parts.append(
            f"Within {RATES_VISIBLE:.0%} of max |W| of the reference throughout, not drawn: "
            + name_list(hidden)
        )
    drawn = [g.label for g in shown if cache.get(g.first)["t"][-1] >= t0]
    alt = (
        f"{scenario}: body angular velocity W1, W2, W3 against the {ref_name}"
        + (f", drawn for {name_list(drawn)}" if drawn else ", no configuration drawn")
        + f"; {len(hidden)} configuration group(s) within {RATES_VISIBLE:.0%} not drawn."
    )
    return _save(fig, out / f"{slug(scenario)}__rates.png", alt=alt, notes="\n".join(parts))


# -- dt sweeps and cost -------------------------------------------------------------------------


def _shade_reference(ax, sub, bottom) -> None:
    acc = sub["reference_accuracy"].max()
    if acc == acc and acc > bottom:
        ax.axhspan(bottom, acc, color="0.88", zorder=0, label="below the reference's\naccuracy")


def _dt_ticks(ax, dts) -> None:
    """Tick the dt axis at the steps that ran (a sweep spans less than a decade or two)."""
    from matplotlib.ticker import FixedLocator, NullLocator

    ax.xaxis.set_major_locator(FixedLocator(sorted(dts)))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xticklabels([fmt_step(h) for h in sorted(dts)])
    lo, hi = min(dts), max(dts)
    ax.set_xlim(lo / 1.25, hi * 1.25)


def convergence_plot(df, out: Path, scenario: str, styles: Styles):
    """Max attitude error against dt (log-log), one line per group of configurations with the
    same errors at every dt, labelled with the fitted order (and the points of the fit) and
    the declared order; a run that diverged or failed is a cross at the top, and named under
    the figure with the configurations that have no point at all; saturation (no fit above
    it) and the reference's accuracy shown."""
    sub = df[(df["scenario"] == scenario) & ~reference_rows(df)]
    sub = sub[~sub["status"].isin(NOT_RUN)]
    groups = [g for g in sweep_groups(sub) if len(g.dts) >= 2]
    if not groups:
        return None
    fig, (ax,) = _new_figure(height=4.4)
    vals = sub.loc[sub["status"] == "ok", "attitude_error_max"]
    vals = vals[np.isfinite(vals) & (vals > 0)]
    bottom = max(FLOOR, float(vals.min()) / 3.0) if len(vals) else 1e-12
    top = CAPS["attitude_error"]
    crosses, bad, absent, drawn = set(), {}, [], []
    for g in groups:
        first = g.first
        st = styles.of(first, always_marker=True)
        ok = [h for h in g.dts if g.at(h).first["status"] == "ok"]
        name = _flat(plot_label(g.members))
        for h in g.dts:
            at = g.at(h)
            if at.first["status"] != "ok":
                crosses.add(h)
                word = at.outcome
                if word == "diverged":
                    word += f" at {fmt(at.value('t_diverged'))} s"
                bad.setdefault(name, []).append(f"dt {fmt_step(h)}: {word}")
        if not ok:
            absent.append(f"{name} ({', '.join(bad.pop(name, []))})")
            continue
        order, npts = first["convergence_order"], first["convergence_points"]
        fit = "no fit" if order != order else f"fit {order:.2f} ({int(npts)} pts)"
        label = f"{plot_label(g.members, 34)}\n  {fit}, declared {int(first['order'])}"
        y = np.array([g.at(h).value("attitude_error_max") for h in ok], dtype=float)
        (line,) = ax.loglog(
            ok,
            np.clip(y, bottom, top),
            color=st["color"],
            linestyle=st["linestyle"],
            marker=st["marker"],
            ms=5,
            lw=1.6,
            label=label,
        )
        line.set_gid(f"{name}: {fit}, declared order {int(first['order'])}")
        drawn.append(name)
    if crosses:
        ax.plot(
            sorted(crosses),
            [top] * len(crosses),
            linestyle="none",
            marker="x",
            ms=9,
            mew=2.2,
            color="#b00020",
            clip_on=False,
            label="some run diverged or\nfailed to run at this dt",
        )
    ax.axhline(SATURATION, color="0.4", lw=0.8, ls=(0, (2, 2)))
    ax.text(
        0.01,
        SATURATION,
        f" saturated above {SATURATION:g} rad (not fitted)",
        transform=ax.get_yaxis_transform(),
        va="bottom",
        fontsize=8,
        color="0.3",
    )
    _shade_reference(ax, sub, bottom)
    ax.set_ylim(bottom, top * 1.3)
    _log_axes(ax, x=True)
    _dt_ticks(ax, {h for g in groups for h in g.dts})
    ax.set(
        xlabel="dt [s]",
        ylabel="max attitude error [rad]",
        title=f"{scenario}: error against time step",
    )
    ax.grid(True, which="major", alpha=0.3)
    _legend(ax)
    parts = []
    if bad:
        parts.append(
            "No point at a dt where the run did not finish (× at the top): "
            + "; ".join(f"{n} ({', '.join(w)})" for n, w in bad.items())
        )
    if absent:
        parts.append("Not drawn, no run finished at any dt: " + "; ".join(absent))
    adaptive = df[(df["scenario"] == scenario) & df["target_accuracy"].notna()]
    adaptive = adaptive[~adaptive["status"].isin(NOT_RUN)]
    if len(adaptive):
        names = [config_label(r).split(" tol ")[0] for r in records(adaptive)]
        parts.append(
            "Error-controlled, no fixed dt (see the work-precision figure): " + name_list(names)
        )
    alt = (
        f"{scenario}: max attitude error against the time step (log-log) for "
        f"{len(drawn)} line(s) of configurations with their fitted convergence orders"
        + (f"; {len(absent)} not drawn (no run finished)" if absent else "")
        + "."
    )
    return _save(fig, out / f"{slug(scenario)}__convergence.png", alt=alt, notes="\n".join(parts))


#: the work-precision plot leaves out configurations never within this attitude error (rad)
WP_RELEVANT = 0.1


def work_precision_plot(df, out: Path, scenario: str, styles: Styles):
    """Max attitude error against the time spent inside the engine (the suite's glue left out,
    so a suite-integrated configuration's cost is its engine's dynamics), one line per
    configuration in dt order; error-controlled runs in target-accuracy order, open markers.
    Configurations never within WP_RELEVANT rad, or with no finished run, are named under the
    figure, not drawn."""
    every = df[(df["scenario"] == scenario) & ~reference_rows(df)]
    every = every[~every["status"].isin(NOT_RUN)]
    sub = every[(every["status"] == "ok")]
    sub = sub[np.isfinite(sub["attitude_error_max"])]
    cost = sub["engine_time_s"].where(sub["engine_time_s"] > 0, sub["wall_time_s"])
    sub = sub.assign(cost=cost)
    sub = sub[sub["cost"] > 0]
    if sub.empty:
        return None
    fig, (ax,) = _new_figure(height=4.4)
    left_out = []
    configs = sorted(
        sub.groupby(["engine", "integrator"]),
        key=lambda kv: (
            family_key(kv[1]["family"].iloc[0]),
            engine_key(kv[0][0]),
            kv[0][1],
        ),
    )
    bottom = max(FLOOR, float(sub["attitude_error_max"].clip(lower=FLOOR).min()) / 3.0)
    drawn = []
    for (eng, integ), g in configs:
        first = g.iloc[0]
        sep = " + suite " if truthy(first["suite_integrated"]) else " "
        name = f"{eng}{sep}{integ}"
        if not (g["attitude_error_max"] <= WP_RELEVANT).any():
            left_out.append(f"{name} (best {fmt(g['attitude_error_max'].min())} rad)")
            continue
        st = styles.of(first, always_marker=True)
        adaptive = g["target_accuracy"].notna().any()
        g = g.sort_values("target_accuracy" if adaptive else "dt")
        (line,) = ax.loglog(
            g["cost"],
            np.maximum(g["attitude_error_max"], bottom),
            color=st["color"],
            linestyle=st["linestyle"],
            marker=st["marker"],
            mfc="none" if adaptive else st["color"],
            ms=5,
            lw=1.6,
            label=name,
        )
        line.set_gid(_adaptive_gid(name) if adaptive else name)
        drawn.append(name)
    finished = set(zip(sub["engine"], sub["integrator"], strict=True))
    unfinished = [
        config_label(r)
        for r in records(every.drop_duplicates(["engine", "integrator"]))
        if (r["engine"], r["integrator"]) not in finished
    ]
    _shade_reference(ax, sub, bottom)
    ax.set_ylim(bottom, CAPS["attitude_error"])
    _log_axes(ax, x=True)
    ax.set(
        xlabel="time inside the engine's calls [s] (suite glue excluded)",
        ylabel="max attitude error [rad]",
        title=f"{scenario}: work-precision (points: the dt sweep)",
    )
    ax.grid(True, which="major", alpha=0.3)
    _legend(ax)
    parts = []
    if sub["target_accuracy"].notna().any():
        parts.append("Open markers: an error-controlled integrator at its target accuracies.")
    if left_out:
        parts.append(f"Not drawn, never within {WP_RELEVANT:g} rad: " + name_list(left_out))
    if unfinished:
        parts.append("Not drawn, no run finished: " + name_list(unfinished))
    alt = (
        f"{scenario}: max attitude error against the time spent inside the engine, log-log, "
        f"for {len(drawn)} configuration(s)"
        + (f"; not drawn: {name_list([*left_out, *unfinished])}" if left_out or unfinished else "")
        + "."
    )
    return _save(
        fig, out / f"{slug(scenario)}__work_precision.png", alt=alt, notes="\n".join(parts)
    )


def _adaptive_gid(name: str) -> str:
    """The hover text of an error-controlled configuration's work-precision line: its name,
    that it is error-controlled (unless the name says so) and what its points are."""
    said = "error-controlled" in name
    return f"{name}, {'' if said else 'error-controlled, '}points: its target accuracies"


# -- a picture of each scenario ------------------------------------------------------------------

#: the poses of the strip in a scenario picture (equally spaced over the horizon, both ends)
POSES = 5

#: face colours of the body's box, by the body axis a face is normal to (d1, d2, d3)
AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")


def body_box(sc) -> np.ndarray:
    """Half the side lengths (m) of the uniform box with the scenario's mass and principal
    moments about the centre of mass: a box of sides (a1, a2, a3) has I1 = m (a2^2 + a3^2)/12,
    so a1^2 = 6 (I2 + I3 - I1)/m. A side that comes out 0 or negative (moments on the edge
    of the triangle inequality) is drawn as a thin plate: 2 % of the largest."""
    I, m = np.asarray(sc.inertia, dtype=float), float(sc.mass)
    sq = np.array([6.0 * (I[(k + 1) % 3] + I[(k + 2) % 3] - I[k]) / m for k in range(3)])
    half = 0.5 * np.sqrt(np.clip(sq, 0.0, None))
    return np.maximum(half, 0.02 * half.max())


def tracked_axis(sc) -> tuple[int, np.ndarray]:
    """The body axis a scenario picture traces, as (index, unit vector in body axes): a
    pivoted body's axis from the pivot through the centre of mass; a free body's axis
    carrying the largest share of the initial angular momentum, pointing along it."""
    if sc.pivot is not None and np.linalg.norm(sc.pivot) > 0:
        u = -np.asarray(sc.pivot, dtype=float)
        return int(np.argmax(np.abs(u))), u / np.linalg.norm(u)
    L = np.asarray(sc.inertia) * np.asarray(sc.omega_body)
    k = int(np.argmax(np.abs(L)))
    u = np.zeros(3)
    u[k] = 1.0 if L[k] >= 0 else -1.0
    return k, u


def _box_faces(half, R, c):
    """The six faces of a box (half sides ``half``) turned by R about its centre c, with the
    index of the body axis each is normal to."""
    faces, normals = [], []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for sgn in (-1.0, 1.0):
            corners = []
            for si, sj in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                v = np.zeros(3)
                v[k], v[i], v[j] = sgn * half[k], si * half[i], sj * half[j]
                corners.append(c + R @ v)
            faces.append(corners)
            normals.append(k)
    return faces, normals


def _tip_length(half, u) -> float:
    """How far from the centre of mass the traced axis is drawn: out of the box by half its
    largest side."""
    k = int(np.argmax(np.abs(u)))
    return float(half[k] + 0.6 * np.max(half))


def _draw_pose(ax, sc, R, x, half, u, lim, trace=None) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    faces, normals = _box_faces(half, R, x)
    ax.add_collection3d(
        Poly3DCollection(
            faces,
            facecolors=[AXIS_COLOURS[k] for k in normals],
            edgecolors="0.25",
            linewidths=0.4,
            alpha=0.35,
        )
    )
    tip = x + R @ (u * _tip_length(half, u))
    ax.plot(*np.column_stack([x, tip]), color="k", lw=1.8)
    if sc.pivot is not None:
        ax.plot([0, x[0]], [0, x[1]], [0, x[2]], color="0.2", lw=1.0, ls=(0, (2, 1)))
        ax.scatter([0], [0], [0], color="k", s=14, depthshade=False)
    if trace is not None:
        ax.plot(*trace.T, color="#6a3d9a", lw=1.1)
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-lim, lim)
    ax.set_box_aspect((1, 1, 1), zoom=1.45)
    ax.view_init(elev=18, azim=-58)
    ax.set_axis_off()


def scenario_picture(sc, t, R, x, out_path: Path, note: str = "") -> Path:
    """A picture of a scenario: its body (the uniform box with its mass and principal
    moments, faces coloured by body axis d1 red, d2 green, d3 blue) at t = 0 with the trace of
    one body axis (:func:`tracked_axis`) over the horizon, then a strip of :data:`POSES` poses
    equally spaced in time; a pivot is a black dot with a dashed line to the centre of mass.

    ``t`` (n,), ``R`` (n, 3, 3) body-to-world rotations and ``x`` (n, 3) centre-of-mass
    positions of the motion (the exact reference); a free body's centre of mass is drawn at
    the origin (its flight is not what the picture shows). Writes a small PNG."""
    plt = _plt()
    t, R, x = np.asarray(t, float), np.asarray(R, float), np.asarray(x, float)
    half = body_box(sc)
    k, u = tracked_axis(sc)
    pivoted = sc.pivot is not None
    if not pivoted:
        x = np.zeros_like(x)
    tips = x + np.einsum("nij,j->ni", R, u * _tip_length(half, u))
    reach = np.max(np.linalg.norm(half)) + (np.linalg.norm(sc.pivot) if pivoted else 0.0)
    lim = 1.05 * max(reach, float(np.max(np.abs(tips))))
    fig = plt.figure(figsize=(9.6, 2.4), dpi=80)
    main = fig.add_axes([0.0, 0.07, 0.27, 0.84], projection="3d")
    _draw_pose(main, sc, R[0], x[0], half, u, lim, trace=tips)
    main.set_title(f"{sc.name}: body and the trace of d{k + 1}", fontsize=8.5, pad=0, loc="left")
    idx = np.unique(np.round(np.linspace(0, len(t) - 1, POSES)).astype(int))
    w = 0.71 / len(idx)
    for n, i in enumerate(idx):
        ax = fig.add_axes([0.28 + n * w, 0.07, w, 0.78], projection="3d")
        _draw_pose(ax, sc, R[i], x[i], half, u, lim)
        ax.set_title(f"t = {fmt(float(t[i]))} s", fontsize=8, pad=0)
    side = " x ".join(fmt(2 * h) for h in half)
    text = (
        f"box {side} m (mass {fmt(sc.mass)} kg, the same principal moments), faces normal to "
        f"d1 red, d2 green, d3 blue; black: d{k + 1}; purple: its tip over "
        f"{fmt(float(t[-1]))} s; "
        f"{'pivot: black dot' if pivoted else 'centre of mass held still'}; world z up"
        + (f"; {note}" if note else "")
    )
    fig.text(0.01, 0.01, text, fontsize=7, color="0.3", ha="left", va="bottom")
    _write_png(fig, out_path)
    plt.close(fig)
    return out_path


def library_scenario(row):
    """The library's scenario a run used, or None: the file of the run's scenario name when
    its content hash is the run's, or when its body and initial state give the run's energy
    and momentum scales to 1e-12 (the same body run with another horizon or step). A
    scenario file of one's own gives None: the results folder does not hold its body."""
    import scenarios

    try:
        sc = scenarios.load(str(row["scenario"]))
    except (ValueError, OSError):
        return None
    if sc.scenario_hash == str(row.get("scenario_hash") or ""):
        return sc
    same = [
        abs(float(getattr(sc, col)) - float(row.get(col))) <= 1e-12 * abs(float(row.get(col)))
        for col in ("energy_scale", "momentum_scale")
    ]
    return sc if all(same) else None


def scenario_plot_from_results(df, cache: SeriesCache, out: Path, scenario: str):
    """The scenario picture of a results folder: the body stored beside the exact
    reference's run (:meth:`SeriesCache.body`; in a folder written before it was stored, the
    library's scenario file when the runs used that very file) and that run's motion."""
    rows = df[(df["scenario"] == scenario) & reference_rows(df)]
    rows = rows[rows["status"].isin(("ok", "reference-inaccurate"))]
    if rows.empty:
        return None
    row = rows.sort_values("dt").iloc[0]
    s = cache.get(row)
    sc = cache.body(row) or library_scenario(row)
    if sc is None or s is None or "R00" not in s:
        return None
    R = np.stack([s[f"R{i}{j}"] for i in range(3) for j in range(3)], axis=1).reshape(-1, 3, 3)
    x = np.column_stack([s["x"], s["y"], s["z"]])
    path = scenario_picture(sc, s["t"], R, x, out / f"{slug(scenario)}__scenario.png")
    k, _ = tracked_axis(sc)
    pose = "pivoted on a fixed point" if sc.pivot is not None else "free"
    alt = (
        f"{scenario}: the body as a uniform box ({pose}) with the same principal moments, the "
        f"trace of its body axis d{k + 1} over {fmt(float(s['t'][-1]))} s, and {POSES} poses "
        "equally spaced in time."
    )
    import json

    path.with_suffix(".json").write_text(json.dumps({"alt": alt, "lines": []}))
    return path


def scenario_figures(names, out: Path, samples: int = 401) -> list[Path]:
    """The pictures of library scenarios for the documentation, each from its exact reference
    at ``samples`` times: ``scenario_<name>.png`` in ``out``."""
    import scenarios
    from references.exact import reference_trajectory

    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        sc = scenarios.load(name)
        t = np.linspace(0.0, sc.t_end, samples)
        ref = reference_trajectory(sc, t)
        path = out / f"scenario_{name}.png"
        paths.append(scenario_picture(sc, t, ref.rotation, ref.position, path))
    return paths


# -- all figures --------------------------------------------------------------------------------

#: the figures of one scenario, in report order (``scenario`` and ``rates`` are a single
#: body's, ``system`` a system of bodies': :func:`is_system`)
KINDS = (
    "scenario", "errors", "rates", "system", "joint_angles", "importers", "convergence",
    "work_precision",
)  # fmt: skip

#: the figures only a single body has, and those only a system of bodies has (a robot
#: model's two: :mod:`reports.report.model_plots`)
SINGLE_BODY_KINDS = ("scenario", "rates")
SYSTEM_KINDS = ("system", "joint_angles", "importers")


def scenario_plot(kind: str, df, cache, out: Path, scenario: str, styles: Styles, failed=None):
    """One figure of a scenario, or None. A figure that cannot be drawn (data a log axis
    cannot show, a library failure) is said on the standard error and left out (its kind
    appended to ``failed`` when given): a figure never costs the report, junit.xml or the
    results."""
    try:
        return _scenario_plot(kind, df, cache, out, scenario, styles)
    except Exception as exc:  # noqa: BLE001 - any failure of one figure
        import sys

        if failed is not None:
            failed.append(kind)
        _plt().close("all")
        print(
            f"director-bench: the {kind} figure of {scenario} was not drawn "
            f"({type(exc).__name__}: {exc}); the report goes on without it",
            file=sys.stderr,
        )
        return None


def _scenario_plot(kind: str, df, cache, out: Path, scenario: str, styles: Styles):
    if kind not in KINDS:
        raise ValueError(f"unknown plot kind {kind!r}; known: {', '.join(KINDS)}")
    if kind in (SINGLE_BODY_KINDS if is_system(df, cache, scenario) else SYSTEM_KINDS):
        return None  # a single body's figure code never sees a system, nor the reverse
    if kind == "scenario":
        return scenario_plot_from_results(df, cache, out, scenario)
    if kind == "errors":
        return errors_plot(df, cache, out, scenario, styles)
    if kind == "system":
        from reports.report.system_plots import system_plot  # joints, invariants over time

        rows, h = _plot_rows(df, scenario)
        if "slide_distance" in rows and rows["slide_distance"].notna().any():
            from reports.report.contact import contact_plot  # distance, penetration

            system_plot = contact_plot
        return system_plot(
            rows, h, cache, out, scenario, _plt(), _save, styles, _new_figure, _legend
        )
    if kind in ("joint_angles", "importers"):  # a robot model's, with its importer table
        from reports.report import model_plots
        from reports.run.importers import read_table

        table = read_table(cache.root, scenario)
        if table is None:
            return None
        if kind == "importers":
            return model_plots.importer_plot(table, out, _plt(), _save, _new_figure)
        rows, h = _plot_rows(df, scenario)
        return model_plots.joint_angle_plot(
            rows, h, cache, out, scenario, _plt(), _save, _new_figure, _legend
        )
    if kind == "rates":
        return rates_plot(df, cache, out, scenario, styles)
    if kind == "convergence":
        return convergence_plot(df, out, scenario, styles)
    return work_precision_plot(df, out, scenario, styles)


def is_system(df, cache, scenario: str) -> bool:
    """Whether a scenario of the results is a system of bodies: a run of it has a system
    metric (:data:`reports.metrics.system.SYSTEM_METRICS`), or a series file with per-body
    columns (``<body>.wx``); a single body's runs have neither."""
    from reports.metrics.system import SYSTEM_METRICS

    sub = df[df["scenario"] == scenario]
    if any(m in sub and sub[m].notna().any() for m in SYSTEM_METRICS):
        return True
    for _, row in sub.iterrows():
        s = cache.get(row)
        if s is not None:
            return any("." in c for c in s)
    return False


#: the file in the plots folder that remembers what each scenario's figures were made from
CACHE_FILE = ".made-from.json"


def _hash_code(h) -> None:
    """Add to the hash ``h`` the code that decides what a figure shows: this module, the
    system figure's, the drawing backend's, the report's labels, groups and tables, the
    metric catalog (panel labels and tops) and the number formatting."""
    for mod in _FIGURE_CODE:  # found, not imported (the backend would import matplotlib)
        h.update(Path(importlib.util.find_spec(mod).origin).read_bytes())


#: the modules whose code decides what a figure shows (:func:`_hash_code`)
_FIGURE_CODE = (
    "reports.report.plots",
    "reports.report.system_plots",
    "reports.report.contact",
    "reports.report.model_plots",
    "reports.report.importers",
    "reports.report.agg_text",
    "reports.report.labels",
    "reports.report.groups",
    "reports.report.tables",
    "scenarios.metric_catalog",
    "reports.store.format",
)


def _scenario_key(df, scenario: str, styles: Styles, root: Path) -> str:
    """A hash of everything a scenario's figures depend on: the code drawing them, the
    scenario's rows, their styles and the series files (size and modification time)."""
    import hashlib
    import json

    h = hashlib.sha256()
    _hash_code(h)
    sub = df[df["scenario"] == scenario].sort_values("run_id")
    h.update(sub.to_json(orient="values", double_precision=15).encode())
    for r in records(sub[["engine", "integrator", "family", "trajectory"]]):
        h.update(json.dumps(styles.of(r), default=str).encode())
        if r["trajectory"]:
            rel = error_series_path(Path(r["trajectory"]))  # relative: a folder named
            p = root / rel  # once relative and once absolute is the same folder
            st = p.stat() if p.exists() else None
            h.update(repr((rel.as_posix(), st and (st.st_size, st.st_mtime_ns))).encode())
    from reports.run.importers import FOLDER  # a robot model's importer table

    table = root / FOLDER / f"{slug(scenario)}.json"
    if table.is_file():
        h.update(table.read_bytes())
    return h.hexdigest()


def _draw_scenario(scenario, kinds, df, root, out) -> tuple[str, dict]:
    """The figures ``kinds`` of one scenario (a worker's task: styles and series are rebuilt
    here from the same inputs, so they are the ones a serial draw would use)."""
    styles, cache = Styles(df), SeriesCache(Path(root))
    return scenario, _figures_of(scenario, kinds, df, cache, Path(out), styles)


def _figures_of(scenario, kinds, df, cache, out: Path, styles) -> dict[str, str | None]:
    """Draw the figures ``kinds`` of ``scenario`` into ``out``: {kind: file name, or None
    when the scenario has no such figure}; a kind whose figure failed is left out."""
    failed: list[str] = []
    paths = {k: scenario_plot(k, df, cache, out, scenario, styles, failed) for k in kinds}
    return {k: None if p is None else p.name for k, p in paths.items() if k not in failed}


def _code_digest() -> str:
    """The digest of the code that decides what a figure shows (:func:`_hash_code`)."""
    import hashlib

    h = hashlib.sha256()
    _hash_code(h)
    return h.hexdigest()


#: draw in parallel processes from this many scenarios to draw on (a process costs ~1 s to
#: start, a scenario's figures ~1-2.5 s to draw)
PARALLEL_FROM = 3


def _cpus() -> int:
    """The cores this process may run on."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def _warm_matplotlib() -> None:
    """Import pyplot and load the fonts (a figure with text drawn once), so that processes
    forked from this one start with them."""
    plt = _plt()
    fig = plt.figure(figsize=(1, 1))
    fig.text(0.5, 0.5, "µ 1e-3")
    fig.canvas.draw()
    plt.close(fig)


def _pool_context():
    """The multiprocessing context of the drawing workers: a fork of this process where that
    is safe (Linux, and no other thread of this interpreter: the caller pauses its own), so
    that a worker starts with the modules and data already here (a spawned one imports
    matplotlib, pandas and the suite again: ~2 s of CPU, as much as drawing two scenarios);
    elsewhere spawn."""
    import multiprocessing as mp
    import sys
    import threading

    safe = sys.platform.startswith("linux") and threading.active_count() == 1
    return mp.get_context("fork" if safe else "spawn")


def _draw_all(todo, df, cache, root, out, styles, bar, alongside=None):
    """Yield (scenario, figure file names) for the scenarios in ``todo`` (scenario, kind)
    pairs. With several scenarios and cores, this process draws alongside a pool of one
    worker process fewer than the cores: it first calls ``alongside`` (another figure, while
    the workers start), then both take the scenarios with the most runs first (the longest
    to draw, so that the last ones to finish are short), a worker being handed its next
    scenario as soon as it returns one. Without a pool ``alongside`` is called first too."""
    import itertools
    import threading
    from collections import deque

    kinds_of: dict[str, list[str]] = {}
    for sc, kind in todo:
        kinds_of.setdefault(sc, []).append(kind)
    scenarios = list(kinds_of)
    workers = min(_cpus() - 1, len(scenarios) - 1)
    if len(scenarios) < PARALLEL_FROM or workers < 1:
        if alongside is not None:
            alongside()
        for sc in scenarios:
            names = _figures_of(sc, kinds_of[sc], df, cache, out, styles)
            bar.update(len(kinds_of[sc]))
            yield sc, names
        return
    from concurrent.futures import ProcessPoolExecutor

    runs = df["scenario"].value_counts()
    pending = deque(sorted(scenarios, key=lambda sc: (-int(runs.get(sc, 0)), sc)))
    lock = threading.Lock()
    jobs = []  # a scenario leaves ``pending`` and its job enters ``jobs`` under one lock

    def take():
        with lock:
            return pending.popleft() if pending else None

    def hand_out(done=None):
        # called here and, as each job finishes, from the pool's thread: a job per worker;
        # none after a failed job (a broken pool: its error is raised where it is collected)
        with lock:
            if not pending or (done is not None and done.exception() is not None):
                return
            sc = pending.popleft()
            job = pool.submit(_draw_scenario, sc, kinds_of[sc], df, str(root), str(out))
            jobs.append(job)
        job.add_done_callback(hand_out)

    ctx = _pool_context()
    if ctx.get_start_method() == "fork":
        _warm_matplotlib()  # once here, not again in each forked worker
    with bar.paused():  # no thread of ours across a fork
        pool = ProcessPoolExecutor(workers, mp_context=ctx)
        for _ in range(workers):  # a forking pool starts its workers at the first job
            hand_out()
    with pool:
        try:
            if alongside is not None:
                alongside()
            returned = 0  # the workers' scenarios yielded so far, in the order handed out
            while (sc := take()) is not None:
                names = _figures_of(sc, kinds_of[sc], df, cache, out, styles)
                bar.update(len(kinds_of[sc]))
                yield sc, names
                with lock:  # those returned, up to the first still drawing
                    ready = list(itertools.takewhile(lambda j: j.done(), jobs[returned:]))
                for job in ready:
                    returned += 1
                    sc, names = job.result()
                    bar.update(len(kinds_of[sc]))
                    yield sc, names
            # ``pending`` is empty: no job is handed out any more, ``jobs`` is complete
            for job in jobs[returned:]:
                sc, names = job.result()
                bar.update(len(kinds_of[sc]))
                yield sc, names
        finally:  # on an error, hand out nothing more while the pool shuts down
            with lock:
                pending.clear()


def all_plots(
    df,
    root: str | Path,
    out: str | Path | None = None,
    progress: bool = False,
    alongside=None,
    reuse_figures: bool = True,
) -> dict[str, list[Path]]:
    """Every figure of every scenario (:data:`KINDS`); returns {scenario: [png paths]}.

    A scenario whose figures exist and were made from the same inputs (rows, series files,
    styles and this code: :data:`CACHE_FILE` in the plots folder) is not drawn again, so a
    report regenerated from an unchanged store draws nothing. ``progress``: the progress of
    the figures (:class:`reports.run.progress.Progress`; nothing when none is drawn).
    ``alongside``: a callable this process calls while worker processes start drawing
    (:func:`report_figures`: the scorecard picture); called once, also when nothing else is
    drawn (not for an empty table). ``reuse_figures``: copy a figure whose inputs are those
    of one drawn before in any folder from the user's cache (:mod:`figure_cache`)."""
    import json

    from reports.run.progress import Progress

    root = Path(root)
    out = Path(out) if out is not None else root / "plots"
    out.mkdir(parents=True, exist_ok=True)
    if df.empty:
        return {}
    styles = Styles(df)
    cache = SeriesCache(root)
    try:
        made_from = json.loads((out / CACHE_FILE).read_text())
    except (OSError, ValueError):
        made_from = {}
    made: dict[str, list[Path]] = {}
    todo = []
    names: dict[str, dict[str, str]] = {}  # scenario -> {kind: file name}
    reuse: dict[tuple[str, str], str] = {}  # (scenario, kind) -> its key in the user's cache
    code = _code_digest() if reuse_figures else ""
    for scenario in sorted(df["scenario"].unique()):
        key = _scenario_key(df, scenario, styles, root)
        old = made_from.get(scenario, {})
        files = [out / f for f in old.get("files", [])]
        if old.get("key") == key and all(
            f.exists() and f.with_suffix(".json").exists() for f in files
        ):
            made[scenario] = [out / f for f in old["files"]]
            continue
        made_from[scenario] = {"key": key, "files": []}
        names[scenario] = {}
        sub = df[df["scenario"] == scenario] if reuse_figures else None
        for kind in KINDS:
            if reuse_figures and kind in figure_cache.REUSED:
                k = figure_cache.key(kind, scenario, sub, styles, root, code)
                got = figure_cache.fetch(k, out)
                if got is not None:  # "" : the scenario has no such figure
                    names[scenario][kind] = got or None
                    continue
                reuse[scenario, kind] = k
            todo.append((scenario, kind))
    bar = Progress(len(todo), desc="plots", unit="figure", disable=not progress)
    for scenario, drawn in _draw_all(todo, df, cache, root, out, styles, bar, alongside):
        names[scenario].update(drawn)
        for kind, name in drawn.items():
            if (scenario, kind) in reuse:
                figure_cache.put(reuse[scenario, kind], None if name is None else out / name)
    bar.close()
    if reuse:
        figure_cache.prune()
    for scenario, by_kind in names.items():
        ordered = [by_kind[k] for k in KINDS if by_kind.get(k)]
        made[scenario] = [out / n for n in ordered]
        made_from[scenario]["files"] = ordered
    made = {sc: made[sc] for sc in sorted(made)}
    write_text(out / CACHE_FILE, json.dumps(made_from, indent=1))
    return made


def report_figures(df, root: str | Path, progress: bool = False):
    """The report's figures: every scenario's (:func:`all_plots`, {scenario: [png paths]})
    and the scorecard picture's paths (:func:`scorecard_figure_cached`), the latter drawn in
    this process while the worker processes start and draw scenarios. ({}, []) for an empty
    table."""
    if df.empty:
        return {}, []
    card: list[Path] = []

    def scorecard():
        card.extend(scorecard_figure_cached(df, root))

    return all_plots(df, root, progress=progress, alongside=scorecard), card


# -- the scorecard as one picture --------------------------------------------------------------

#: cell colours of the scorecard figure, per outcome (the HTML report's colours)
OUTCOME_COLOURS = {
    "pass": "#cfe9d6",
    "fail": "#f6c9c4",
    "diverged": "#e8a39b",
    "error": "#fce8b2",
    "reference-inaccurate": "#dde3e6",
    "unsupported": "#f2f2f2",
    "unavailable": "#f2f2f2",
}
#: a mark per outcome in the scorecard figure
OUTCOME_MARKS = {
    "pass": "✓",
    "fail": "✗",
    "diverged": "↯",
    "error": "!",
    "reference-inaccurate": "?",
    "unsupported": "",
    "unavailable": "",
}


def fmt_cost(ns: float) -> str:
    """A cost per step, ``1.23 µs`` (``-`` when unknown)."""
    try:
        v = float(ns)
    except (TypeError, ValueError):
        return "-"
    if not v > 0:
        return "-"
    return f"{fmt(v / 1e3)} µs"


def scorecard_cells(df) -> tuple[list, list, dict]:
    """The scorecard figure's content: scenarios (columns), configurations (rows: (engine,
    integrator, label)) and {(row, scenario): (outcome, lines of text)}; each scenario at its
    own dt (an error-controlled integrator at its tightest target accuracy)."""
    from reports.report.labels import METRIC_SHORT, failed_metrics, fmt_attitude, outcome
    from reports.report.tables import scenarios_of

    scens = scenarios_of(df)
    cells, labels = {}, {}
    for sc in scens:
        rows = at_scenario_dt(df[df["scenario"] == sc])
        for r in records(rows[~reference_rows(rows)]):
            key = (r["engine"], r["integrator"])
            labels.setdefault(key, config_label(r))
            out = outcome(r)
            if out in NOT_RUN:
                text = ["not run", f"({out})"]
            elif out == "diverged":
                text = [f"↯ t = {fmt(r['t_diverged'])} s", fmt_cost(r["engine_ns_per_step"])]
            elif out == "error":
                text = ["! error"]
            else:
                text = [
                    f"{OUTCOME_MARKS.get(out, '')} {fmt_attitude(r)}",
                    fmt_cost(r["engine_ns_per_step"]),
                ]
                if out == "fail":
                    names = failed_metrics(r["verdict_detail"])
                    text.append(", ".join(METRIC_SHORT.get(m, m) for m in names))
            cells[(key, sc)] = (out, text)
    order = sorted(labels, key=lambda k: (engine_key(k[0]), k[1]))
    return scens, [(e, i, labels[(e, i)]) for e, i in order], cells


#: the scorecard figure's title (wrapped to the figure's width)
SCORECARD_TITLE = (
    "director-bench scorecard, each scenario at its own dt: verdict, max attitude error [rad] "
    "(< x: below the reference's accuracy x), time inside the engine per step, and the "
    "metrics that failed"
)


def scorecard_figure(df, out: Path) -> list[Path]:
    """The scorecard as one picture for a README or a pull request, ``scorecard.png`` and
    ``scorecard.svg`` in ``out``: a row per configuration, a column per scenario at its own
    dt; each cell coloured by the verdict, with the max attitude error [rad] (``< x``: below
    the reference's accuracy), the time inside the engine per step and the failing metrics.
    Returns the paths written ([] for an empty table)."""
    import matplotlib
    from matplotlib.patches import Patch, Rectangle

    df = df[~reference_rows(df)]
    if df.empty:
        return []
    scens, configs, cells = scorecard_cells(df)
    plt = _plt()
    cw, ch, lw = 1.3, 0.55, 2.5  # cell width and height, label column, inches
    # sized by its content: the title and the legend wrap to the width of the labels and
    # cells (one scenario makes a narrow figure, not one as wide as a one-line title)
    content = lw + cw * len(scens)
    title = textwrap.wrap(SCORECARD_TITLE, max(48, int(content * 13)))  # ~13 chars/inch at 9 pt
    ncols = max(2, min(6, int(content // 1.45)))  # legend entries are up to ~1.4 in wide
    bottom = 0.53 + 0.22 * -(-6 // ncols)
    top = 1.01 + 0.17 * len(title)
    texts = {}
    for key, (out_, text) in cells.items():  # the failing metrics, on more lines if need be
        texts[key] = (out_, [*text[:2], *textwrap.wrap(text[2], 22)] if len(text) > 2 else text)
    # a row as tall as its longest cell needs (in units of ch): the first line, then 0.21 per
    # line of 6.6 pt, and a margin; at least one unit
    heights, ys = [], [0.0]
    for eng, integ, _ in configs:
        n = max((len(texts.get(((eng, integ), sc), ("", ["-"]))[1]) for sc in scens), default=1)
        heights.append(max(1.0, 0.38 + 0.21 * (n - 1)))
        ys.append(ys[-1] + heights[-1])
    rows = ys[-1]
    width, height = content + 0.2, ch * rows + bottom + top
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig = plt.figure(figsize=(width, height), dpi=DPI)
        ax = fig.add_axes(
            [lw / width, bottom / height, cw * len(scens) / width, ch * rows / height]
        )
        ax.set_xlim(0, len(scens))
        ax.set_ylim(rows, 0)
        ax.axis("off")
        prev = None
        for i, (eng, integ, label) in enumerate(configs):
            y, h = ys[i], heights[i]
            if prev is not None and eng != prev:
                ax.axhline(y, color="0.35", lw=1.0)
            prev = eng
            ax.text(-0.06, y + h / 2, label, ha="right", va="center", fontsize=8.5)
            for j, sc in enumerate(scens):
                out_, text = texts.get(((eng, integ), sc), ("", ["-"]))
                face = OUTCOME_COLOURS.get(out_, "white")
                ax.add_patch(Rectangle((j, y), 1, h, fc=face, ec="white", lw=1.5))
                # two texts per cell (drawing text is most of the figure's time): the
                # verdict and error, then the cost and failing metrics in smaller type
                mid = y + h / 2 - 0.1 * (len(text) - 1)
                ax.text(j + 0.5, mid, text[0], ha="center", va="center", fontsize=8)
                if len(text) > 1:
                    ax.text(
                        j + 0.5, mid + 0.13, "\n".join(text[1:]), ha="center",
                        va="top", fontsize=6.6, color="0.3", linespacing=1.05,
                    )  # fmt: skip
        for j, sc in enumerate(scens):
            ax.text(
                j + 0.5, -0.15, sc, ha="left", va="bottom",
                rotation=25, rotation_mode="anchor", fontsize=8.5,
            )  # fmt: skip
        handles = [
            Patch(fc=OUTCOME_COLOURS[o], ec="0.6", label=f"{OUTCOME_MARKS[o]} {o}".strip())
            for o in ("pass", "fail", "diverged", "error", "reference-inaccurate")
        ]
        handles.append(Patch(fc=OUTCOME_COLOURS["unsupported"], ec="0.6", label="not run"))
        fig.legend(
            handles=handles, loc="lower left", bbox_to_anchor=(0.01, 0.0), ncols=ncols,
            frameon=False, fontsize=8, handlelength=1.4,
        )  # fmt: skip
        fig.text(0.01, 1 - 0.08 / height, "\n".join(title), ha="left", va="top", fontsize=9)
        paths = [out / "scorecard.png", out / "scorecard.svg"]
        box = fig.get_tightbbox().padded(0.1)  # inches; measured once for both files
        _write_png(fig, paths[0], bbox_inches=box)
        fig.savefig(paths[1], bbox_inches=box)
        plt.close(fig)
    return paths


def scorecard_figure_cached(df, root: str | Path) -> list[Path]:
    """:func:`scorecard_figure` into the results folder, drawn again only when the table or
    the code drawing it changed (a hash kept in ``plots/.scorecard-made-from``)."""
    import hashlib

    root = Path(root)
    h = hashlib.sha256()
    _hash_code(h)
    h.update(df.sort_values("run_id").to_json(orient="values", double_precision=15).encode())
    key = h.hexdigest()
    mark = root / "plots" / ".scorecard-made-from"
    paths = [root / "scorecard.png", root / "scorecard.svg"]
    try:
        if mark.read_text() == key and all(p.exists() for p in paths):
            return paths
    except OSError:
        pass
    paths = scorecard_figure(df, root)
    mark.parent.mkdir(parents=True, exist_ok=True)
    mark.write_text(key)
    return paths


def ensemble_plot(df, out, metric: str = "attitude_error_max"):
    """Distribution of ``metric`` over the members of an ensemble, one box per engine and
    integrator (log scale), ordered by median."""
    plt = _plt()
    ok = df[(df["status"] == "ok") & np.isfinite(df[metric].astype(float))]
    if ok.empty:
        return None
    groups = sorted(
        ok.groupby(["engine", "integrator"]), key=lambda kv: float(np.median(kv[1][metric]))
    )
    data = [np.maximum(g[metric].astype(float).to_numpy(), FLOOR) for _, g in groups]
    labels = [f"{e} {i}" for (e, i), _ in groups]
    fig, ax = plt.subplots(figsize=(AXES_WIDTH + 3.0, 0.32 * len(labels) + 1.6), dpi=DPI)
    ax.boxplot(data, orientation="horizontal", whis=(0, 100))
    ax.set_yticks(range(1, len(labels) + 1), labels)
    ax.set_xscale("log")
    scen = ok["scenario"].iloc[0]
    n = ok["member"].nunique()
    unit = {"attitude_error_max": " [rad]"}.get(metric, " [1]")
    ax.set(
        xlabel=metric + unit,
        title=f"{scen}: {metric} over {n} initial conditions (whiskers: min and max)",
    )
    ax.grid(True, which="major", axis="x", alpha=0.3)
    fig.subplots_adjust(left=0.3, right=0.97, bottom=0.5 / (0.32 * len(labels) + 1.6) + 0.1)
    alt = (
        f"{scen}: distribution of {metric} over {n} initial conditions, one box per "
        f"configuration ({name_list(labels)}), ordered by median."
    )
    return _save(fig, Path(out) / f"{slug(scen)}__ensemble_{slug(metric)}.png", alt=alt)


__all__ = [
    "CAPS",
    "ENGINE_ORDER",
    "FAMILY_ORDER",
    "FAMILY_STYLE",
    "KINDS",
    "PALETTE",
    "all_plots",
    "convergence_plot",
    "ensemble_plot",
    "errors_plot",
    "figure_meta",
    "rates_plot",
    "scenario_figures",
    "scenario_picture",
    "scorecard_figure",
    "work_precision_plot",
]


def main(argv=None) -> int:
    """``python -m reports.report.plots --scenario-figures DIR [NAME ...]``: the pictures of the
    default suite's scenarios (or those named) for the documentation."""
    import argparse

    import scenarios

    p = argparse.ArgumentParser(
        prog="python -m reports.report.plots",
        description="Draw the pictures of library scenarios (body and motion) into a folder.",
    )
    p.add_argument(
        "--scenario-figures",
        metavar="DIR",
        required=True,
        help="folder to write scenario_<name>.png into (e.g. docs/figures)",
    )
    p.add_argument("names", nargs="*", help="library scenarios (default: the default suite)")
    args = p.parse_args(argv)
    names = args.names or scenarios.default_suite()
    try:
        for path in scenario_figures(names, Path(args.scenario_figures)):
            print(path)
    except (ValueError, OSError) as exc:
        print(f"python -m reports.report.plots: error: {exc}", file=__import__("sys").stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
