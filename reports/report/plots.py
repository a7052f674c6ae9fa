"""The figures of a scenario's runs over time and over step sizes, pure functions of a results
folder (the results table and the per-run series files the runner writes beside each
trajectory). Each returns the PNG path it wrote, or None when there is nothing to draw:

- ``errors`` (:func:`errors_plot`): running maxima of the attitude, energy and momentum errors
  against time at the scenario's own dt (log scale), the quantities the metrics report, as
  they grow; the band below the reference's accuracy, where attitude errors are not
  measurements, is shaded;
- ``rates`` (:func:`rates_plot`): body angular velocity against the reference, with only the
  configurations that visibly leave it drawn; a fast oscillation is shown over its last
  periods;
- ``convergence`` (:func:`convergence_plot`): attitude error against dt (log-log), with the
  fitted orders;
- ``work_precision`` (:func:`work_precision_plot`): attitude error against the time spent
  inside the engine's calls.

Configurations whose results coincide (reports.report.groups) are one line labelled with all
of them; a diverged run's end is marked with a cross, and its legend entry says when it
diverged (``... (diverged at 1.64 s)``); every configuration cut, left out or not drawn is
named under the figure. How they look and are saved: :mod:`reports.report.canvas`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reports.metrics import catalog
from reports.metrics.body import SATURATION
from reports.report.canvas import (
    CAPS,
    FLOOR,
    SeriesCache,
    Styles,
    _clip_at,
    _diverged_mark,
    _flat,
    _legend,
    _line_label,
    _log_axes,
    _new_figure,
    _plot_rows,
    _running_max,
    _save,
    _thin,
    draws,
    name_list,
    plot_label,
    scene_kind,
)
from reports.report.groups import group_rows, sweep_groups
from reports.report.labels import (
    NOT_RUN,
    config_label,
    engine_key,
    family_key,
    on_cpu_alone,
    reference_label,
    scaled_label,
    suite_sep,
)
from reports.report.precision import cost_of, measure_of, outlook
from reports.store.format import fmt, fmt_step, num
from reports.store.results import records, reference_rows
from reports.store.runs import slug

#: the rates plot shows a configuration only if its W error exceeds this fraction of max |W|
RATES_VISIBLE = 0.01

#: the rates plot's panels widen to show a drawn run up to this many times max |W| of the
#: reference (a run beyond is cut where it leaves)
RATES_REACH = 2.0

#: a fast oscillation in the rates plot is shown over its last RATES_PERIODS periods
RATES_PERIODS = 12


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
    bodies = scene_kind(df, scenario) != "body"
    for ax, (column, ylabel, scale_col, unit) in zip(axes, panels, strict=True):
        if bodies and column == "attitude_error":
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
    if not draws("rates", df, scenario):
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


#: the work-precision plot leaves out configurations never within this error (rad, or m for a
#: contact scene's position error)
WP_RELEVANT = 0.1


def work_precision_plot(df, out: Path, scenario: str, styles: Styles):
    """Max attitude error (a contact scene: its position error against the closed form,
    reports.report.precision.measure_of) against the cost a user pays
    (reports.report.precision.cost_of: the CPU time inside the engine's calls, the suite's
    glue left out; for a ``+ suite``
    configuration the whole step's CPU time), one line per configuration in dt order (every
    configuration ran the scenario's sweep); error-controlled runs in target-accuracy order,
    open markers. Configurations never within WP_RELEVANT (rad or m), or with no finished run, are
    named under the figure, not drawn; those still converging at the smallest step are named
    too (a smaller step was not tried)."""
    every = df[(df["scenario"] == scenario) & ~reference_rows(df)]
    every = every[~every["status"].isin(NOT_RUN)]
    sub = every[(every["status"] == "ok")]
    if sub.empty:
        return None
    col, unit = measure_of(sub.iloc[0])
    sub = sub[np.isfinite(sub[col])]
    rows = records(sub)  # converted once: a configuration's rows are a few of them
    cost = [cost_of(r) for r in rows]
    sub = sub.assign(cost=cost)
    keep = [c > 0 for c in cost]
    sub = sub[keep]
    if sub.empty:
        return None
    fig, (ax,) = _new_figure(height=4.4)
    left_out = []
    engine = engine_key(sub)
    by_config: dict[tuple, list] = {}  # (engine, integrator) -> [(row, cost)], in table order
    for r, c, k in zip(rows, cost, keep, strict=True):
        if k:
            by_config.setdefault((r["engine"], r["integrator"]), []).append((r, c))
    configs = sorted(
        by_config.items(),
        key=lambda kv: (family_key(kv[1][0][0]["family"]), engine(kv[0][0]), kv[0][1]),
    )
    bottom = max(FLOOR, float(sub[col].clip(lower=FLOOR).min()) / 3.0)
    drawn = []
    for _config, g in configs:
        first = g[0][0]
        name = _wp_name(first)
        if not any(r[col] <= WP_RELEVANT for r, _ in g):
            left_out.append(f"{name} (best {fmt(min(r[col] for r, _ in g))} {unit})")
            continue
        st = styles.of(first, always_marker=True)
        adaptive = any(not np.isnan(num(r["target_accuracy"])) for r, _ in g)
        by = "target_accuracy" if adaptive else "dt"
        g = sorted(g, key=lambda rc, by=by: rc[0][by])  # noqa: B023 - used here only
        (line,) = ax.loglog(
            np.array([c for _, c in g]),
            np.maximum(np.array([r[col] for r, _ in g], dtype=float), bottom),
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
    # the attitude panel's cap (about pi rad); a position error up to 1 m (the library's
    # scenes are 0.1 m in size; a body thrown further is drawn at three times its error)
    top = CAPS["attitude_error"] if unit == "rad" else max(1.0, 3.0 * float(sub[col].max()))
    ax.set_ylim(bottom, top)
    _log_axes(ax, x=True)
    ax.set(
        xlabel="CPU time inside the engine's calls [s] (+ suite: of the whole step)",
        ylabel="max attitude error [rad]" if unit == "rad" else "max position error [m]",
        title=f"{scenario}: work-precision (points: the dt sweep, the same for all)",
    )
    ax.grid(True, which="major", alpha=0.3)
    _legend(ax)
    parts = []
    if sub["target_accuracy"].notna().any():
        parts.append("Open markers: an error-controlled integrator at its target accuracies.")
    if left_out:
        parts.append(f"Not drawn, never within {WP_RELEVANT:g} {unit}: " + name_list(left_out))
    if unfinished:
        parts.append("Not drawn, no run finished: " + name_list(unfinished))
    falling = _still_falling(every, drawn)
    if falling:
        parts.append(
            "Still converging at the sweep's smallest step (a smaller one not tried): "
            + name_list(falling)
        )
    alt = (
        f"{scenario}: max {'attitude' if unit == 'rad' else 'position'} error against the "
        "time spent inside the engine, log-log, "
        f"for {len(drawn)} configuration(s)"
        + (f"; not drawn: {name_list([*left_out, *unfinished])}" if left_out or unfinished else "")
        + "."
    )
    return _save(
        fig, out / f"{slug(scenario)}__work_precision.png", alt=alt, notes="\n".join(parts)
    )


def _wp_name(row) -> str:
    """A configuration's name in the work-precision figure: ``engine [+ suite] integrator``,
    and MJX stepped alone on a CPU says so (reports.report.labels.on_cpu_alone)."""
    alone = " (one instance, CPU)" if on_cpu_alone(row) else ""
    return f"{row['engine']}{suite_sep(row)}{row['integrator']}{alone}"


def _still_falling(every, drawn: list[str]) -> list[str]:
    """The drawn fixed-step configurations whose error was still falling at the smallest
    step they ran (reports.report.precision.outlook at a level below all their errors)."""
    out = []
    by_config: dict[tuple, list] = {}
    for r in records(every):
        by_config.setdefault((r["engine"], r["integrator"]), []).append(r)
    for _config, rows in sorted(by_config.items(), key=lambda kv: kv[0]):
        if rows[0]["target_accuracy"] == rows[0]["target_accuracy"]:  # error-controlled
            continue
        name = _wp_name(rows[0])
        if name in drawn and outlook(rows, 0.0)[0] == "not tried":
            out.append(name)
    return out


def _adaptive_gid(name: str) -> str:
    """The hover text of an error-controlled configuration's work-precision line: its name,
    that it is error-controlled (unless the name says so) and what its points are."""
    said = "error-controlled" in name
    return f"{name}, {'' if said else 'error-controlled, '}points: its target accuracies"


__all__ = [
    "ERROR_PANELS",
    "convergence_plot",
    "errors_plot",
    "rates_left_out",
    "rates_plot",
    "work_precision_plot",
]
