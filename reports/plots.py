"""Comparison plots, pure functions of a results folder (the results table and the per-run
series files the runner writes beside each trajectory). Every function returns the PNG path
it wrote, or None when there is nothing to draw.

One figure per scenario and kind (:data:`KINDS`):

- ``errors``: running maxima of the attitude, energy and momentum errors against time at the
  scenario's own dt (log scale), the quantities the metrics report, as they grow; the band
  below the reference's accuracy, where attitude errors are not measurements, is shaded;
- ``rates``: body angular velocity against the reference, with only the configurations that
  visibly leave it drawn; a fast oscillation is shown over its last periods;
- ``convergence``: attitude error against dt (log-log), with the fitted orders;
- ``work_precision``: attitude error against the time spent inside the engine's calls.

Styles: one colour per engine (:data:`ENGINE_COLOURS`), one line style per integrator family
(:data:`FAMILY_STYLE`), a marker per integrator where an engine has several in one family.
Configurations whose results coincide (reports.summary's groups) are one line labelled with
all of them, in near-black when they are several engines' (:data:`SHARED_COLOUR`). A curve
that leaves the plot (a diverged run, an error beyond :data:`CAPS`) is cut where it leaves
and marked there; a diverged run's end is marked with its time.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

from reports.metrics import SATURATION
from reports.results import error_series_path, slug
from reports.summary import (
    ENGINE_ORDER,
    FAMILY_ORDER,
    NOT_RUN,
    at_scenario_dt,
    engine_key,
    family_key,
    fmt,
    fmt_step,
    group_rows,
    records,
    scenario_dt,
    sweep_groups,
    truthy,
)

#: one colour per engine (engines not listed take the next of EXTRA_COLOURS)
ENGINE_COLOURS = {
    "director": "#1f77b4",
    "mujoco": "#ff7f0e",
    "pinocchio": "#2ca02c",
    "dart": "#d62728",
    "pybullet": "#9467bd",
    "exact": "#555555",
}
EXTRA_COLOURS = ("#8c564b", "#e377c2", "#bcbd22", "#17becf", "#7f7f7f")

#: the colour of one line standing for several engines that coincide
SHARED_COLOUR = "#222222"

#: one line style per family (families not listed take the next of EXTRA_STYLES)
FAMILY_STYLE = {
    "structure-preserving director": "-",
    "4th-order Lie-group": "--",
    "implicit gyroscopic": "-.",
    "semi-implicit Euler": ":",
    "exact": "-",
}
EXTRA_STYLES = (
    (0, (6, 1.5, 1, 1.5, 1, 1.5)),
    (0, (10, 3)),
    (0, (1, 3)),
    (0, (4, 1.5, 1, 1.5)),
    (0, (8, 2, 2, 2)),
    (0, (2, 1)),
)

#: markers telling apart the integrators of one engine within one family
MARKERS = ("o", "s", "^", "D", "v", "P", "X")

#: the top of the log axes, per series column: beyond it a run has blown up (the runner
#: declares divergence at an energy error of 1 scale; attitude errors end at pi)
CAPS = {"energy_drift": 10.0, "momentum_drift": 10.0, "attitude_error": 4.0}

#: log axes stop at this floor (exact zeros are drawn there)
FLOOR = 1e-17

#: the rates plot shows a configuration only if its W error exceeds this fraction of max |W|
RATES_VISIBLE = 0.01

#: a fast oscillation in the rates plot is shown over its last RATES_PERIODS periods
RATES_PERIODS = 12

FIGSIZE = (9.0, 4.2)
DPI = 100
#: axes box in figure fractions: the legend takes the right part
AXES_BOX = {"left": 0.09, "right": 0.62, "bottom": 0.13, "top": 0.88}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
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
    configuration looks the same in every figure."""

    def __init__(self, df):
        engines = sorted(set(df["engine"]), key=engine_key)
        extra = iter(EXTRA_COLOURS * 4)
        self.colour = {e: ENGINE_COLOURS.get(e) or next(extra) for e in engines}
        fams = sorted({f for f in df["family"] if f}, key=family_key)
        extra_s = iter(EXTRA_STYLES * 4)
        self.style = {f: FAMILY_STYLE.get(f) or next(extra_s) for f in fams}
        self.marker = {}
        pairs = df[["engine", "family", "integrator"]].drop_duplicates()
        for (_, _), g in pairs.groupby(["engine", "family"]):
            integs = sorted(g["integrator"])
            if len(integs) > 1:
                for k, integ in enumerate(integs):
                    self.marker[(g["engine"].iloc[0], integ)] = MARKERS[k % len(MARKERS)]

    def of(self, row, always_marker: bool = False, engines=None) -> dict:
        """Style of a configuration's line; ``engines``: the engines of a group of coinciding
        configurations drawn as one line (several engines: :data:`SHARED_COLOUR`)."""
        marker = self.marker.get((row["engine"], row["integrator"]))
        if marker is None and always_marker:
            marker = "o"
        several = engines is not None and len(set(engines)) > 1
        return {
            "color": SHARED_COLOUR if several else self.colour.get(row["engine"], "k"),
            "linestyle": self.style.get(row["family"], "-"),
            "marker": marker,
        }


def plot_label(rows, width: int = 34) -> str:
    """A legend label for configurations that coincide: ``mujoco RK4, pinocchio RKMK4``,
    wrapped."""
    text = ", ".join(f"{r['engine']} {r['integrator']}" for r in rows)
    return "\n".join(textwrap.wrap(text, width, break_long_words=False)) or text


def _new_figure(nrows: int = 1, height: float | None = None):
    plt = _plt()
    fig, axes = plt.subplots(
        nrows, 1, figsize=(FIGSIZE[0], height or FIGSIZE[1]), sharex=True, squeeze=False
    )
    fig.subplots_adjust(**AXES_BOX, hspace=0.12)
    return fig, [a for a in axes[:, 0]]


def _legend(ax, title=None) -> None:
    """Legend to the right of the axes (the figure keeps room for it), never over data; it
    lists the labelled artists of every axes of the figure, each label once."""
    handles, labels = [], []
    for a in ax.figure.axes:
        for hnd, lab in zip(*a.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(hnd)
                labels.append(lab)
    kw = {"loc": "upper left", "bbox_to_anchor": (1.02, 1.0), "frameon": False}
    if title:
        kw["title"] = title
        kw["title_fontsize"] = 9
    ax.legend(handles, labels, borderaxespad=0.0, handlelength=3.2, **kw)


def _save(fig, path: Path) -> Path:
    """Write the figure as PNG and release it."""
    fig.savefig(path, dpi=DPI)
    _plt().close(fig)
    return path


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
        return self._data[rel]


def _running_max(y: np.ndarray) -> np.ndarray:
    """max over samples 0..i of y (NaN samples ignored)."""
    y = np.where(np.isnan(y), -np.inf, y)
    return np.maximum.accumulate(y)


def _clip_at(ax, t, y, top, **style):
    """Plot ``y(t)``, cut where it first exceeds ``top`` (or becomes infinite), with a
    marker on the top edge there. Returns the line and the point where it left, or None."""
    bad = np.isinf(y) | (y > top)  # NaN: a gap (an exact zero on a log axis), not an exit
    exit_pt = None
    if bad.any():
        k = int(np.argmax(bad))
        exit_pt = (t[k], top)
        t, y = t[:k], y[:k]
    (line,) = ax.plot(t, y, **style)
    if exit_pt is not None:
        ax.plot(*exit_pt, marker="^", ms=8, color=style["color"], clip_on=False, zorder=5)
    return line, exit_pt


def _status_note(ax, x, y, text, k: int) -> None:
    """A cross where a diverged run ends, and its text (the k-th such note) beside it, on
    the side of the axes with more room."""
    ax.plot(x, y, marker="x", ms=9, mew=2.2, color="#b00020", clip_on=False, zorder=6)
    if text:
        lo, hi = ax.get_xlim()
        right = (x - lo) < 0.5 * (hi - lo)
        ax.annotate(
            text,
            (x, y),
            xytext=(9 if right else -9, -4 - 11 * k),
            textcoords="offset points",
            ha="left" if right else "right",
            va="top",
            fontsize=8.5,
            color="#b00020",
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
            zorder=7,
        )


def _plot_rows(df, scenario):
    """The rows a time plot shows: the scenario at its own dt, runs that produced samples."""
    sub = df[df["scenario"] == scenario]
    if sub.empty:
        return sub, math.nan
    rows = at_scenario_dt(sub)
    rows = rows[rows["status"].isin(("ok", "diverged", "reference-inaccurate"))]
    return rows, scenario_dt(sub)


# -- time plots ---------------------------------------------------------------------------------

#: the panels of the errors-over-time figure: (series column, y label, scale column, unit)
ERROR_PANELS = (
    ("attitude_error", "attitude error [rad]", None, ""),
    ("energy_drift", "|E − E₀| / E_c [1]", "energy_scale", "J"),
    ("momentum_drift", "|ΔL| / L_c [1]", "momentum_scale", "kg m²/s"),
)


def errors_plot(df, cache: SeriesCache, out: Path, scenario: str, styles: Styles):
    """Running maxima of the attitude, energy and momentum errors against time at the
    scenario's dt (three log panels sharing t), one line per group of coinciding
    configurations; the exact reference's own drift (its round-off) in grey; the band below
    the reference's accuracy shaded; curves beyond :data:`CAPS` cut and marked."""
    rows, h = _plot_rows(df, scenario)
    if rows.empty:
        return None
    groups = []
    for g in group_rows(rows[rows["engine"] != "exact"]):
        s = cache.get(g.first)
        if s is not None:
            groups.append((g, s))
    if not groups:
        return None
    exact = rows[rows["engine"] == "exact"]
    ref = cache.get(exact.iloc[0]) if len(exact) else None
    fig, axes = _new_figure(3, height=7.4)
    fig.subplots_adjust(top=0.93, bottom=0.08)
    axes[-1].set_xlim(0, float(rows["t_end"].max()))
    for ax, (column, ylabel, scale_col, unit) in zip(axes, ERROR_PANELS, strict=True):
        _error_panel(ax, rows, groups, ref, column, styles, show_notes=ax is axes[0])
        if scale_col and rows[scale_col].notna().any():
            scale = float(rows[scale_col].dropna().iloc[0])
            sym = ylabel.split("/")[-1].split("[")[0].strip()
            ylabel = f"{ylabel}\n{sym} = {fmt(scale)} {unit}"
        ax.set_ylabel(ylabel)
        ax.grid(True, which="major", alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(0, float(rows["t_end"].max()))
    fig.suptitle(
        f"{scenario}: errors against time, running max (dt = {fmt_step(h)} s)", fontsize=10.5
    )
    _legend(axes[0])
    return _save(fig, out / f"{slug(scenario)}__errors.png")


def _error_panel(ax, rows, groups, ref, column, styles, show_notes: bool) -> None:
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
    notes = 0
    noted = set()
    for t, y, g in lines:
        st = styles.of(g.first, engines=g.engines)
        y = np.where(y > 0, np.maximum(y, bottom), np.nan)  # log axis: zeros start the curve
        kw = {
            "color": st["color"],
            "linestyle": st["linestyle"],
            "lw": 1.7,
            "label": plot_label(g.rows),
        }
        if st["marker"] and np.isfinite(y).sum() > 1:  # markevery needs a drawn line
            kw.update(marker=st["marker"], markevery=(0.04 + 0.025 * len(ax.lines), 0.2), ms=5)
        _, left = _clip_at(ax, t, y, top, **kw)
        if g.outcome == "diverged" and np.isfinite(y).any():
            x, yy = left if left is not None else (t[-1], min(np.nanmax(y), top))
            text = f"diverged at {fmt(g.value('t_diverged'))} s"
            _status_note(ax, x, yy, "" if text in noted or not show_notes else text, notes)
            noted.add(text)
            notes += 1
    if ref_line is not None:
        t, y = ref_line
        ax.plot(
            t,
            np.where(y > 0, np.maximum(y, bottom), np.nan),
            color="0.55",
            lw=1.0,
            label="exact reference\n(its round-off)" if column == "energy_drift" else None,
        )
    if column == "attitude_error":
        acc = float(np.nanmax(rows["reference_accuracy"]))
        if acc > bottom:
            ax.axhspan(bottom, acc, color="0.88", zorder=0, label="below the reference's\naccuracy")
    ax.set_yscale("log")
    _log_axes(ax)
    ax.set_ylim(bottom, top * 1.05)


def _window(t, w_ref) -> tuple[float, float]:
    """The time window of the rates plot: everything, or the last RATES_PERIODS periods of
    a fast oscillation (counted from the sign changes about the mean)."""
    best = np.array([], dtype=int)
    for k in range(3):
        c = w_ref[:, k] - np.mean(w_ref[:, k])
        idx = np.nonzero(np.diff(np.signbit(c)))[0]
        if idx.size > best.size:
            best = idx
    if best.size > 2 * RATES_PERIODS + 1:
        return float(t[best[-2 * RATES_PERIODS - 1]]), float(t[-1])
    return float(t[0]), float(t[-1])


def _clipped_line(ax, tt, y, lim, st, label):
    """Draw y(tt) in the style ``st`` up to where it first leaves ``lim`` (or stops being
    finite), marking that point on the edge with a triangle."""
    lo, hi = lim
    out_of = ~np.isfinite(y) | (y < lo) | (y > hi)
    if out_of.any():
        j = int(np.argmax(out_of))
        edge = hi if (np.isfinite(y[j]) and y[j] > hi) or not np.isfinite(y[j]) else lo
        ax.plot(tt[j], edge, marker="^" if edge == hi else "v", ms=8, color=st["color"])
        tt, y = tt[:j], y[:j]
    kw = {}
    if st["marker"] and np.isfinite(y).sum() > 1:  # markevery needs a drawn line
        kw = {"marker": st["marker"], "markevery": 0.1, "ms": 5}
    ax.plot(
        tt, y, color=st["color"], linestyle=st["linestyle"], lw=1.5, label=label, zorder=3, **kw
    )


def rates_plot(df, cache: SeriesCache, out: Path, scenario: str, styles: Styles):
    """Body rates W_1, W_2, W_3 against the reference (thick grey), one panel each. Only the
    configurations whose W error exceeds RATES_VISIBLE of max |W| are drawn; y ranges are the
    reference's (a blown-up run is cut where it leaves them)."""
    rows, h = _plot_rows(df, scenario)
    exact = rows[rows["engine"] == "exact"]
    ref = cache.get(exact.iloc[0]) if len(exact) else None
    if ref is None:
        return None
    t_ref = ref["t"]
    w_ref = np.column_stack([ref["wx"], ref["wy"], ref["wz"]])
    wmax = float(np.max(np.abs(w_ref))) or 1.0
    t0, t1 = _window(t_ref, w_ref)
    groups = group_rows(rows[rows["engine"] != "exact"])
    shown, hidden = [], 0
    for g in groups:
        err = g.value("omega_error_max")
        if g.outcome == "diverged" or not (err <= RATES_VISIBLE * wmax):
            shown.append(g)
        else:
            hidden += len(g.rows)
    fig, axes = _new_figure(3, height=6.2)
    fig.subplots_adjust(top=0.93, bottom=0.09)
    axes[-1].set_xlim(t0, t1)
    sel = (t_ref >= t0) & (t_ref <= t1)
    lims = []
    for k, ax in enumerate(axes):
        w = w_ref[sel, k]
        lo, hi = float(w.min()), float(w.max())
        pad = 0.15 * max(hi - lo, 0.05 * wmax)
        lims.append((lo - pad, hi + pad))
        ax.plot(*_thin(t_ref[sel], w), color="0.6", lw=4.0, label="exact reference", zorder=1)
    notes, noted = 0, set()
    for g in shown:
        s = cache.get(g.first)
        if s is None:
            continue
        st = styles.of(g.first, engines=g.engines)
        t = s["t"]
        label = plot_label(g.rows)
        if g.outcome == "diverged" and t[-1] < t0:
            label += f"\n(diverged at {fmt(g.value('t_diverged'))} s,\nbefore this window)"
        m = (t >= t0) & (t <= t1)
        for k, (ax, col) in enumerate(zip(axes, ("wx", "wy", "wz"), strict=True)):
            _clipped_line(ax, *_thin(t[m], s[col][m]), lims[k], st, label if k == 0 else None)
        if g.outcome == "diverged" and t0 <= t[-1] <= t1:
            text = f"diverged at {fmt(g.value('t_diverged'))} s"
            _status_note(axes[0], t[-1], lims[0][1], "" if text in noted else text, notes)
            noted.add(text)
            notes += 1
    for k, ax in enumerate(axes):
        ax.set_ylim(*lims[k])
        ax.set_ylabel(f"W{'₁₂₃'[k]} [rad/s]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    axes[-1].set_xlim(t0, t1)
    window = "" if t0 <= t_ref[0] else f", last {fmt(t1 - t0)} s"
    axes[0].set_title(
        f"{scenario}: body angular velocity, body axes (dt = {fmt_step(h)} s{window})"
    )
    title = None
    if hidden:
        title = f"{hidden} configuration(s) within\n{RATES_VISIBLE:.0%} of max|W| not drawn"
    _legend(axes[0], title=title)
    return _save(fig, out / f"{slug(scenario)}__rates.png")


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
    the declared order; a run that diverged or failed is a cross at the top; saturation (no
    fit above it) and the reference's accuracy shown."""
    sub = df[(df["scenario"] == scenario) & (df["engine"] != "exact")]
    sub = sub[~sub["status"].isin(NOT_RUN)]
    groups = [g for g in sweep_groups(sub) if len(g.dts) >= 2]
    if not groups:
        return None
    fig, (ax,) = _new_figure(height=5.4)
    vals = sub.loc[sub["status"] == "ok", "attitude_error_max"]
    vals = vals[np.isfinite(vals) & (vals > 0)]
    bottom = max(FLOOR, float(vals.min()) / 3.0) if len(vals) else 1e-12
    top = CAPS["attitude_error"]
    crosses = set()
    for g in groups:
        first = g.first
        st = styles.of(first, always_marker=True, engines=[m["engine"] for m in g.members])
        ok = [h for h in g.dts if g.at(h).first["status"] == "ok"]
        crosses.update(h for h in g.dts if g.at(h).first["status"] != "ok")
        if not ok:
            continue
        order, npts = first["convergence_order"], first["convergence_points"]
        fit = "no fit" if order != order else f"fit {order:.2f} ({int(npts)} pts)"
        label = f"{plot_label(g.members, 34)}\n  {fit}, declared {int(first['order'])}"
        y = np.array([g.at(h).value("attitude_error_max") for h in ok], dtype=float)
        ax.loglog(
            ok,
            np.clip(y, bottom, top),
            color=st["color"],
            linestyle=st["linestyle"],
            marker=st["marker"],
            ms=5,
            lw=1.6,
            label=label,
        )
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
            label="some run diverged or\nfailed at this dt",
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
    return _save(fig, out / f"{slug(scenario)}__convergence.png")


#: the work-precision plot leaves out configurations never within this attitude error (rad)
WP_RELEVANT = 0.1


def work_precision_plot(df, out: Path, scenario: str, styles: Styles):
    """Max attitude error against the time spent inside the engine (the suite's glue left out,
    so a suite-integrated configuration's cost is its engine's dynamics), one line per
    configuration in dt order; error-controlled runs in target-accuracy order, open markers.
    Configurations never within WP_RELEVANT rad are listed, not drawn."""
    sub = df[(df["scenario"] == scenario) & (df["status"] == "ok") & (df["engine"] != "exact")]
    sub = sub[np.isfinite(sub["attitude_error_max"])]
    cost = sub["engine_time_s"].where(sub["engine_time_s"] > 0, sub["wall_time_s"])
    sub = sub.assign(cost=cost)
    sub = sub[sub["cost"] > 0]
    if sub.empty:
        return None
    fig, (ax,) = _new_figure(height=5.4)
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
    for (eng, integ), g in configs:
        first = g.iloc[0]
        if not (g["attitude_error_max"] <= WP_RELEVANT).any():
            left_out.append(f"{eng} {integ}")
            continue
        st = styles.of(first, always_marker=True)
        adaptive = g["target_accuracy"].notna().any()
        g = g.sort_values("target_accuracy" if adaptive else "dt")
        sep = " + suite " if truthy(first["suite_integrated"]) else " "
        ax.loglog(
            g["cost"],
            np.maximum(g["attitude_error_max"], bottom),
            color=st["color"],
            linestyle=st["linestyle"],
            marker=st["marker"],
            mfc="none" if adaptive else st["color"],
            ms=5,
            lw=1.6,
            label=f"{eng}{sep}{integ}" + (" (error-controlled)" if adaptive else ""),
        )
    _shade_reference(ax, sub, bottom)
    ax.set_ylim(bottom, CAPS["attitude_error"])
    _log_axes(ax, x=True)
    ax.set(
        xlabel="time inside the engine's calls [s] (suite glue excluded)",
        ylabel="max attitude error [rad]",
        title=f"{scenario}: work-precision (points: the dt sweep)",
    )
    ax.grid(True, which="major", alpha=0.3)
    title = None
    if left_out:
        title = "not drawn (never within\n" + f"{WP_RELEVANT:g} rad): {len(left_out)}"
    _legend(ax, title=title)
    return _save(fig, out / f"{slug(scenario)}__work_precision.png")


# -- all figures --------------------------------------------------------------------------------

#: the figures of one scenario, in report order
KINDS = ("errors", "rates", "convergence", "work_precision")


def scenario_plot(kind: str, df, cache, out: Path, scenario: str, styles: Styles):
    if kind == "errors":
        return errors_plot(df, cache, out, scenario, styles)
    if kind == "rates":
        return rates_plot(df, cache, out, scenario, styles)
    if kind == "convergence":
        return convergence_plot(df, out, scenario, styles)
    if kind == "work_precision":
        return work_precision_plot(df, out, scenario, styles)
    raise ValueError(f"unknown plot kind {kind!r}; known: {', '.join(KINDS)}")


#: the file in the plots folder that remembers what each scenario's figures were made from
CACHE_FILE = ".made-from.json"


def _scenario_key(df, scenario: str, styles: Styles, root: Path) -> str:
    """A hash of everything a scenario's figures depend on: the code drawing them, the
    scenario's rows, their styles and the series files (size and modification time)."""
    import hashlib
    import json

    import reports.summary as summary_mod

    h = hashlib.sha256()
    h.update(Path(__file__).read_bytes())
    h.update(Path(summary_mod.__file__).read_bytes())
    sub = df[df["scenario"] == scenario].sort_values("run_id")
    h.update(sub.to_json(orient="values", double_precision=15).encode())
    for r in records(sub[["engine", "integrator", "family", "trajectory"]]):
        h.update(json.dumps(styles.of(r), default=str).encode())
        if r["trajectory"]:
            p = root / error_series_path(Path(r["trajectory"]))
            st = p.stat() if p.exists() else None
            h.update(repr((str(p), st and (st.st_size, st.st_mtime_ns))).encode())
    return h.hexdigest()


def _draw_scenario(scenario, df, root, out) -> tuple[str, list[str]]:
    """Every figure of one scenario (a worker's task: styles and series are rebuilt here from
    the same inputs, so they are the ones a serial draw would use)."""
    styles, cache = Styles(df), SeriesCache(Path(root))
    paths = [scenario_plot(k, df, cache, Path(out), scenario, styles) for k in KINDS]
    return scenario, [p.name for p in paths if p is not None]


#: draw in parallel processes from this many scenarios to draw on (a process costs ~1 s to
#: start, a scenario's four figures ~2.5 s to draw)
PARALLEL_FROM = 3


def _draw_all(todo, df, cache, root, out, styles, bar):
    """Yield (scenario, figure file names) for the scenarios in ``todo`` (scenario, kind)
    pairs, drawing them in a process pool when there are several."""
    import os

    scenarios = list(dict.fromkeys(sc for sc, _ in todo))
    workers = min(os.cpu_count() or 1, len(scenarios))
    if len(scenarios) < PARALLEL_FROM or workers < 2:
        for sc in scenarios:
            paths = [scenario_plot(k, df, cache, out, sc, styles) for k in KINDS]
            bar.update(len(KINDS))
            yield sc, [p.name for p in paths if p is not None]
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
        jobs = [pool.submit(_draw_scenario, sc, df, str(root), str(out)) for sc in scenarios]
        for job in jobs:
            sc, names = job.result()
            bar.update(len(KINDS))
            yield sc, names


def all_plots(
    df, root: str | Path, out: str | Path | None = None, progress: bool = False
) -> dict[str, list[Path]]:
    """Every figure of every scenario (:data:`KINDS`); returns {scenario: [png paths]}.

    A scenario whose figures exist and were made from the same inputs (rows, series files,
    styles and this code: :data:`CACHE_FILE` in the plots folder) is not drawn again, so a
    report regenerated from an unchanged store draws nothing. ``progress``: a progress bar
    over the figures (shown once drawing takes over a second)."""
    import json

    from tqdm.auto import tqdm

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
    for scenario in sorted(df["scenario"].unique()):
        key = _scenario_key(df, scenario, styles, root)
        old = made_from.get(scenario, {})
        if old.get("key") == key and all((out / f).exists() for f in old.get("files", [])):
            made[scenario] = [out / f for f in old["files"]]
        else:
            made[scenario] = []
            made_from[scenario] = {"key": key, "files": []}
            todo += [(scenario, k) for k in KINDS]
    bar = tqdm(total=len(todo), desc="plots", unit="fig", disable=not progress, delay=1.0)
    for scenario, names in _draw_all(todo, df, cache, root, out, styles, bar):
        made[scenario] = [out / n for n in names]
        made_from[scenario]["files"] = names
    bar.close()
    tmp = out / f"{CACHE_FILE}.tmp"
    tmp.write_text(json.dumps(made_from, indent=1))
    tmp.replace(out / CACHE_FILE)
    return made


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
    fig, ax = plt.subplots(figsize=(FIGSIZE[0], 0.32 * len(labels) + 1.6))
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
    return _save(fig, Path(out) / f"{slug(scen)}__ensemble_{slug(metric)}.png")


__all__ = [
    "CAPS",
    "ENGINE_COLOURS",
    "ENGINE_ORDER",
    "FAMILY_ORDER",
    "FAMILY_STYLE",
    "KINDS",
    "all_plots",
    "convergence_plot",
    "ensemble_plot",
    "rates_plot",
    "errors_plot",
    "work_precision_plot",
]
