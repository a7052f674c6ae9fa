"""The scorecard as one picture (:func:`scorecard_figure`: ``scorecard.png`` and
``scorecard.svg`` in the results folder; the outcome of every configuration of every scenario,
in the scorecard's rows and columns) and the ensemble's figure (:func:`ensemble_plot`).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from reports.report.canvas import (
    AXES_WIDTH,
    DPI,
    FLOOR,
    _hash_code,
    _plt,
    _save,
    _write_png,
    name_list,
)
from reports.report.labels import NOT_RUN, config_label, engine_key
from reports.report.tables import at_scenario_dt
from reports.store.format import fmt, fmt_cost
from reports.store.results import records, reference_rows
from reports.store.runs import slug

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


def scorecard_cells(df) -> tuple[list, list, dict]:
    """The scorecard figure's content: scenarios (columns), configurations (rows: (engine,
    integrator, label)) and {(row, scenario): (outcome, lines of text)}; each scenario at its
    own dt (an error-controlled integrator at its tightest target accuracy)."""
    from reports.report.labels import (
        METRIC_SHORT,
        failed_metrics,
        fmt_headline,
        headline,
        outcome,
    )
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
                    f"{OUTCOME_MARKS.get(out, '')} {fmt_headline(r)} {headline(r)[1]}",
                    fmt_cost(r["engine_ns_per_step"]),
                ]
                if out == "fail":
                    names = failed_metrics(r["verdict_detail"])
                    text.append(", ".join(METRIC_SHORT.get(m, m) for m in names))
            cells[(key, sc)] = (out, text)
    engine = engine_key(df)
    order = sorted(labels, key=lambda k: (engine(k[0]), k[1]))
    return scens, [(e, i, labels[(e, i)]) for e, i in order], cells


#: the scorecard figure's title (wrapped to the figure's width)
SCORECARD_TITLE = (
    "director-bench scorecard, each scenario at its own dt: verdict, max attitude error [rad] "
    "(a contact scene's position error against its closed form [m]; < x: below the "
    "reference's accuracy x), time inside the engine per step, and the metrics that failed"
)


def scorecard_figure(df, out: Path) -> list[Path]:
    """The scorecard as one picture for a README or a pull request, ``scorecard.png`` and
    ``scorecard.svg`` in ``out``: a row per configuration, a column per scenario at its own
    dt; each cell coloured by the verdict, with the error its run is summed up by
    (:func:`reports.report.labels.headline`: the max attitude error in rad, a contact scene's
    position error in m; ``< x``: below the reference's accuracy), the time inside the
    engine per step and the failing metrics.
    Returns the paths written ([] for an empty table)."""
    import matplotlib
    from matplotlib.collections import PatchCollection
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
        cells_drawn = []
        for i, (eng, integ, label) in enumerate(configs):
            y, h = ys[i], heights[i]
            if prev is not None and eng != prev:
                ax.axhline(y, color="0.35", lw=1.0)
            prev = eng
            ax.text(-0.06, y + h / 2, label, ha="right", va="center", fontsize=8.5)
            for j, sc in enumerate(scens):
                out_, text = texts.get(((eng, integ), sc), ("", ["-"]))
                face = OUTCOME_COLOURS.get(out_, "white")
                cells_drawn.append(Rectangle((j, y), 1, h, fc=face, ec="white", lw=1.5))
                # two texts per cell (drawing text is most of the figure's time): the
                # verdict and error, then the cost and failing metrics in smaller type
                mid = y + h / 2 - 0.1 * (len(text) - 1)
                ax.text(j + 0.5, mid, text[0], ha="center", va="center", fontsize=8)
                if len(text) > 1:
                    ax.text(
                        j + 0.5, mid + 0.13, "\n".join(text[1:]), ha="center",
                        va="top", fontsize=6.6, color="0.3", linespacing=1.05,
                    )  # fmt: skip
        # the cells as one artist, under the texts: one clip path and one draw call for
        # hundreds of rectangles (the limits are set: no data limits to update)
        ax.add_collection(PatchCollection(cells_drawn, match_original=True),
                          autolim=False)  # fmt: skip
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
