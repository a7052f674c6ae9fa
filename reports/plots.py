"""Comparison plots, each a pure function of a results folder (results.csv + the per-run
series files written by the runner). Every function returns the written PNG paths.

One figure per scenario and kind:

- ``energy``: relative energy drift against time (log scale), at the scenario's default dt;
- ``momentum``: drift of the conserved angular-momentum components against time;
- ``rates``: body angular velocity on the intermediate axis (shows the Dzhanibekov flips);
- ``attitude``: geodesic attitude error against time (log scale);
- ``convergence``: attitude error against dt, log-log, with the fitted slopes;
- ``work_precision``: attitude error against wall time per engine and integrator.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from reports.results import default_dt, error_series_path, slug

FAMILY_STYLE = {
    "semi-implicit Euler": "-",
    "implicit gyroscopic": "--",
    "4th-order Lie-group": "-.",
    "structure-preserving director": ":",
    "exact": "-",
}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _legend(ax, fig) -> None:
    """Legend to the right of the axes, so it never hides data."""
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()


def _save(fig, path: Path) -> Path:
    """Write the figure as PNG and release it."""
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def _label(r) -> str:
    return f"{r['engine']} {r['integrator']}"


def _default_dt_rows(df, scenario: str, dt: float | None):
    sub = df[(df["scenario"] == scenario) & (df["status"] == "ok")]
    if sub.empty:
        return sub
    h = default_dt(sub) if dt is None else dt
    return sub[np.isclose(sub["dt"], h, rtol=1e-9)]


def _series(root: Path, row):
    import pandas as pd

    if not row["trajectory"]:
        return None
    p = root / error_series_path(Path(row["trajectory"]))
    return pd.read_parquet(p) if p.exists() else None


def _time_plot(df, root, out, scenario, column, ylabel, title, logy, dt=None):
    plt = _plt()
    rows = _default_dt_rows(df, scenario, dt)
    fig, ax = plt.subplots(figsize=(10, 4.2))
    plotted = 0
    for _, r in rows.iterrows():
        s = _series(root, r)
        if s is None or column not in s:
            continue
        y = s[column].to_numpy()
        if r["engine"] == "exact" and column in ("attitude_error", "omega_error"):
            continue
        if logy:
            y = np.maximum(y, 1e-17)  # log axis: show exact zeros at the floor of the plot
        if r["engine"] == "exact":
            # the reference's own drift is the round-off floor of the measurement
            ax.plot(s["t"], y, color="0.6", lw=0.6, label="exact reference (round-off floor)")
        else:
            ax.plot(s["t"], y, FAMILY_STYLE.get(r["family"], "-"), lw=1.1, label=_label(r))
        plotted += 1
    if not plotted:
        plt.close(fig)
        return None
    if logy:
        ax.set_yscale("log")
    dt = rows["dt"].iloc[0]
    ax.set(xlabel="t [s]", ylabel=ylabel, title=f"{scenario}: {title} (dt = {dt:g} s)")
    ax.grid(True, which="both", alpha=0.3)
    _legend(ax, fig)
    return _save(fig, out / f"{slug(scenario)}__{slug(column)}.png")


def rates_plot(df, root, out, scenario, dt=None):
    """Body rates W_1, W_2, W_3 against time, one panel each: the Dzhanibekov flips are the
    sign changes of the intermediate-axis rate, and a stepper that misses or mistimes them
    stands out against the reference (thick line)."""
    plt = _plt()
    rows = _default_dt_rows(df, scenario, dt)
    fig, axes = plt.subplots(3, 1, figsize=(10, 6.0), sharex=True)
    plotted = 0
    for _, r in rows.iterrows():
        s = _series(root, r)
        if s is None:
            continue
        lw = 2.5 if r["engine"] == "exact" else 1.0
        for k, col in enumerate(("wx", "wy", "wz")):
            axes[k].plot(s["t"], s[col], FAMILY_STYLE.get(r["family"], "-"), lw=lw, label=_label(r))
        plotted += 1
    if not plotted:
        plt.close(fig)
        return None
    for k in range(3):
        axes[k].set_ylabel(f"W_{k + 1} [rad/s]")
        axes[k].grid(True, alpha=0.3)
    axes[0].set_title(f"{scenario}: body angular velocity")
    axes[2].set_xlabel("t [s]")
    _legend(axes[0], fig)
    return _save(fig, out / f"{slug(scenario)}__rates.png")


def convergence_plot(df, out, scenario, metric="attitude_error_max"):
    """Error against dt (log-log) per engine and integrator, with the fitted slope."""
    plt = _plt()
    sub = df[(df["scenario"] == scenario) & (df["status"] == "ok") & (df["engine"] != "exact")]
    fig, ax = plt.subplots(figsize=(10, 4.6))
    plotted = 0
    for (eng, integ), g in sub.groupby(["engine", "integrator"]):
        g = g.sort_values("dt")
        if g["dt"].nunique() < 2:
            continue
        slope = g["convergence_order"].iloc[0]
        lab = f"{eng} {integ}" + ("" if math.isnan(slope) else f" (slope {slope:.2f})")
        fam = g["family"].iloc[0]
        ax.loglog(
            g["dt"],
            np.maximum(g[metric], 1e-17),
            FAMILY_STYLE.get(fam, "-"),
            marker="o",
            ms=3,
            lw=1.1,
            label=lab,
        )
        plotted += 1
    if not plotted:
        plt.close(fig)
        return None
    ax.set(xlabel="dt [s]", ylabel=f"{metric}", title=f"{scenario}: error against time step")
    ax.grid(True, which="both", alpha=0.3)
    _legend(ax, fig)
    return _save(fig, out / f"{slug(scenario)}__convergence.png")


def work_precision_plot(df, out, scenario, metric="attitude_error_max"):
    """Error against wall time of the stepping (work-precision diagram)."""
    plt = _plt()
    sub = df[(df["scenario"] == scenario) & (df["status"] == "ok") & (df["engine"] != "exact")]
    sub = sub[np.isfinite(sub[metric]) & (sub["wall_time_s"] > 0)]
    if sub.empty:
        return None
    fig, ax = plt.subplots(figsize=(10, 4.6))
    for (eng, integ), g in sub.groupby(["engine", "integrator"]):
        g = g.sort_values("dt")  # connect the points in step-size order
        fam = g["family"].iloc[0]
        ax.loglog(
            g["wall_time_s"],
            np.maximum(g[metric], 1e-17),
            FAMILY_STYLE.get(fam, "-"),
            marker="o",
            ms=3,
            lw=1.1,
            label=f"{eng} {integ}",
        )
    ax.set(
        xlabel="wall time of the stepping [s]", ylabel=metric, title=f"{scenario}: work-precision"
    )
    ax.grid(True, which="both", alpha=0.3)
    _legend(ax, fig)
    return _save(fig, out / f"{slug(scenario)}__work_precision.png")


def all_plots(df, root: str | Path, out: str | Path | None = None) -> dict[str, list[Path]]:
    """Every plot for every scenario in the results; returns {scenario: [png paths]}."""
    root = Path(root)
    out = Path(out) if out is not None else root / "plots"
    out.mkdir(parents=True, exist_ok=True)
    made: dict[str, list[Path]] = {}
    for scenario in sorted(df["scenario"].unique()):
        paths = [
            _time_plot(
                df, root, out, scenario, "energy_drift", "|E - E0| / E0", "energy drift", True
            ),
            _time_plot(
                df, root, out, scenario, "momentum_drift", "|L - L0| / |L0|", "momentum drift", True
            ),
            rates_plot(df, root, out, scenario),
            _time_plot(
                df,
                root,
                out,
                scenario,
                "attitude_error",
                "angle to reference [rad]",
                "attitude error",
                True,
            ),
            convergence_plot(df, out, scenario),
            work_precision_plot(df, out, scenario),
        ]
        made[scenario] = [p for p in paths if p is not None]
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
    data = [np.maximum(g[metric].astype(float).to_numpy(), 1e-17) for _, g in groups]
    labels = [f"{e} {i}" for (e, i), _ in groups]
    fig, ax = plt.subplots(figsize=(10, 0.35 * len(labels) + 1.5))
    ax.boxplot(data, vert=False, whis=(0, 100))
    ax.set_yticks(range(1, len(labels) + 1), labels, fontsize=7)
    ax.set_xscale("log")
    scen = ok["scenario"].iloc[0]
    n = ok["member"].nunique()
    ax.set(
        xlabel=metric, title=f"{scen}: {metric} over {n} initial conditions (whiskers: min and max)"
    )
    ax.grid(True, which="both", axis="x", alpha=0.3)
    fig.tight_layout()
    return _save(fig, Path(out) / f"{slug(scen)}__ensemble_{slug(metric)}.png")
