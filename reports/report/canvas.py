"""The drawing kit of the report's figures: how every figure looks, is laid out and is saved,
whatever it shows.

Styles: a colour and a marker per configuration (:data:`PALETTE`, :data:`MARKERS`), a line
style per integrator family (:data:`FAMILY_STYLE`; the reference's :data:`REFERENCE_STYLE`),
the same in every figure of a results folder (:class:`Styles`). Every figure is as wide as its
legend needs (:func:`_fit`: the legend sits beside the axes and is never cut); a curve that
leaves the plot (a diverged run, an error beyond :data:`CAPS`) is cut where it leaves and
marked there (:func:`_clip_at`, :func:`_diverged_mark`). :func:`_save` writes the PNG and,
beside it, a ``.json`` file with its alt text and its lines as polylines, which the HTML
report uses to name the line under the pointer (:func:`figure_meta` reads it back).
:class:`SeriesCache` reads the per-sample series files the runner writes beside each
trajectory, once per file; :func:`_hash_code` hashes the code that decides what a figure shows
(:data:`_FIGURE_CODE`), the key of every reuse of a figure.
"""

from __future__ import annotations

import importlib.util
import io
import json
import math
import re
import textwrap
from pathlib import Path

import numpy as np

from reports.metrics import catalog
from reports.report.labels import config_label, engine_key, family_key
from reports.report.tables import at_scenario_dt, scenario_dt
from reports.store.format import fmt
from reports.store.results import reference_rows
from reports.store.runs import error_series_path
from scenarios.model import SCENE_KINDS

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
        engine = engine_key(df)
        pairs = sorted(
            set(
                zip(
                    *(df.loc[~reference_rows(df), c] for c in ("engine", "integrator")), strict=True
                )
            ),
            key=lambda p: (engine(p[0]), p[1]),
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
    in between. With ``kw``, savefig's pixels are taken as they are written
    (:class:`_Pixels`), also without a full-colour PNG."""
    from PIL import Image

    if kw:
        sink = _Pixels(fig)
        fig.savefig(sink, format="rgba", dpi=DPI, **kw)
        im = Image.frombuffer("RGBA", sink.size, sink.getbuffer(), "raw", "RGBA", 0, 1)
    else:
        fig.set_dpi(DPI)  # what savefig(dpi=DPI) draws at
        fig.canvas.draw()
        im = Image.frombuffer("RGBA", fig.canvas.get_width_height(physical=True),
                              fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)  # fmt: skip
    with im:
        im.convert("RGB").quantize(colors=256, method=Image.Quantize.FASTOCTREE).save(
            path, format="PNG"
        )


class _Pixels(io.BytesIO):
    """A file for ``savefig(format="rgba")`` that also keeps the size in pixels of the canvas
    writing into it (``savefig``'s, e.g. cropped to ``bbox_inches``, which the figure loses
    once savefig returns)."""

    def __init__(self, fig):
        super().__init__()
        self.fig, self.size = fig, (0, 0)

    def write(self, data) -> int:
        self.size = self.fig.canvas.get_width_height(physical=True)
        return super().write(data)


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
        """The scenario's body stored beside the run's series (reports.run.body.body_of):
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


#: the figures of one scenario, in report order, each with the scene kinds it draws
#: (:data:`scenarios.SCENE_KINDS`, recorded in each run's row as ``scene_kind``): ``scenario``
#: and ``rates`` show one body's motion and body rates; ``system`` the joints and invariants of
#: a scene of bodies (a contact scene's: distance moved and penetration,
#: :data:`BODIES_FIGURE`); ``joint_angles`` and ``importers`` a robot model's
#: (:mod:`reports.report.model_plots`); the others any scene's
FIGURES = {
    "scenario": ("body",),
    "errors": SCENE_KINDS,
    "rates": ("body",),
    "system": ("system", "contact"),
    "joint_angles": ("system", "contact"),
    "importers": ("system", "contact"),
    "convergence": SCENE_KINDS,
    "work_precision": SCENE_KINDS,
}

#: the function drawing the ``system`` figure of each kind of scene of bodies (module:name)
BODIES_FIGURE = {
    "system": "reports.report.system_plots:system_plot",
    "contact": "reports.report.contact:contact_plot",
}


def scene_kind(df, scenario: str) -> str:
    """The kind of scene ``scenario`` is (:data:`scenarios.SCENE_KINDS`), as the runner
    recorded it in its rows (``scene_kind``; a store of an older format has it filled when
    read, :func:`reports.store.results.upgrade_rows`); '' when the results hold no run of it."""
    kinds = df.loc[df["scenario"] == scenario, "scene_kind"]
    return str(kinds.iloc[-1]) if len(kinds) else ""


def draws(figure: str, df, scenario: str) -> bool:
    """Whether the figure kind ``figure`` (:data:`FIGURES`) is drawn for ``scenario``: its
    scene kind is one of those the figure declares."""
    return scene_kind(df, scenario) in FIGURES[figure]


def _hash_code(h) -> None:
    """Add to the hash ``h`` the code that decides what a figure shows: this module, the
    system figure's, the drawing backend's, the report's labels, groups and tables, the
    metric catalog (panel labels and tops) and the number formatting."""
    for mod in _FIGURE_CODE:  # found, not imported (the backend would import matplotlib)
        h.update(Path(importlib.util.find_spec(mod).origin).read_bytes())


#: the modules whose code decides what a figure shows (:func:`_hash_code`)
_FIGURE_CODE = (
    "reports.report.figures",
    "reports.report.canvas",
    "reports.report.plots",
    "reports.report.pictures",
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
