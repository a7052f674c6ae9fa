"""Markdown and self-contained HTML reports, pure functions of a results folder.

A results folder holds ``results.csv`` (one row per run), ``provenance.json`` (written when the
runs were made: suite version, git commit, date, machine, engine versions), ``trajectories/``
and, once a report is made, ``plots/``, ``report.md`` and ``report.html``. Every table is
preceded by a one-line title (``### ...``) so that two reports diff cleanly.
"""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path

import numpy as np

from reports.provenance import read_provenance
from reports.results import METRIC_COLUMNS, default_dt

FAMILY_ORDER = [
    "structure-preserving director",
    "4th-order Lie-group",
    "implicit gyroscopic",
    "semi-implicit Euler",
    "exact",
]

SUMMARY_COLUMNS = ["engine", "integrator", "order", *METRIC_COLUMNS, "ns_per_step"]

SHORT = {
    "energy_drift_max": "energy drift",
    "momentum_drift_max": "momentum drift",
    "orthonormality_max": "|R^T R - 1|",
    "attitude_error_max": "attitude err [rad]",
    "omega_error_max": "W err [rad/s]",
    "position_error_max": "x_G err [m]",
    "flip_interval_error": "flip interval err",
    "nutation_period_error": "nutation period err",
    "convergence_order": "order (fit)",
    "ns_per_step": "ns/step",
    "order": "order",
}


# -- tables ------------------------------------------------------------------------------------
def fmt(v) -> str:
    if isinstance(v, str):
        return v
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    v = float(v)
    if math.isinf(v):
        return "inf"
    if v == 0:
        return "0"
    if 1e-3 <= abs(v) < 1e5:
        return f"{v:.4g}"
    return f"{v:.2e}"


def _family_key(fam: str) -> int:
    return FAMILY_ORDER.index(fam) if fam in FAMILY_ORDER else len(FAMILY_ORDER)


def table_rows(df, columns) -> tuple[list[str], list[list[str]]]:
    header = [SHORT.get(c, c) for c in columns]
    rows = [[fmt(r[c]) for c in columns] for _, r in df.iterrows()]
    return header, rows


def markdown_table(title: str, header, rows) -> str:
    lines = [
        f"### {title}",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" for _ in header) + "|",
    ]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def html_table(title: str, header, rows) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows
    )
    return (
        f"<h3>{html.escape(title)}</h3>\n<table><thead><tr>{head}</tr></thead>"
        f"<tbody>{body}</tbody></table>\n"
    )


def sections(df) -> list[tuple[str, str, list, list]]:
    """The report's sections as (kind, title, header, rows); kind is 'table' or 'text' (a
    line of prose in ``title``)."""
    out = []
    if df.empty:
        return out
    counts = df["status"].value_counts().to_dict()
    summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    out.append(("text", f"{len(df)} runs: {summary}.", [], []))
    for scenario in sorted(df["scenario"].unique()):
        sub = df[df["scenario"] == scenario]
        ok = sub[sub["status"] == "ok"]
        if not ok.empty:
            h = default_dt(ok)
            at = ok[np.isclose(ok["dt"], h, rtol=1e-9)]
            for fam, g in sorted(at.groupby("family"), key=lambda kv: _family_key(kv[0])):
                g = g.sort_values(["engine", "integrator"])
                cols = [
                    c for c in SUMMARY_COLUMNS if not (c in METRIC_COLUMNS and g[c].isna().all())
                ]
                header, rows = table_rows(g, cols)
                out.append(("table", f"{scenario}, dt = {h:g} s: {fam}", header, rows))
        conv = ok[ok["engine"] != "exact"].groupby(["engine", "integrator"])
        conv_rows = []
        for (eng, integ), g in conv:
            if g["dt"].nunique() < 2:
                continue
            conv_rows.append(
                [
                    eng,
                    integ,
                    fmt(g["order"].iloc[0]),
                    fmt(g["convergence_order"].iloc[0]),
                    ", ".join(f"{d:g}" for d in sorted(g["dt"])),
                ]
            )
        if conv_rows:
            out.append(
                (
                    "table",
                    f"{scenario}: convergence order over the dt sweep",
                    ["engine", "integrator", "declared", "fitted", "dt values"],
                    conv_rows,
                )
            )
    for scenario in sorted(df["scenario"].unique()):
        wp = work_precision_table(df[df["scenario"] == scenario])
        if wp:
            out.append(("table", f"{scenario}: cheapest configuration reaching each accuracy", *wp))
    bad = df[df["status"] != "ok"].sort_values(["scenario", "engine", "integrator", "dt"])
    if not bad.empty:
        header = ["scenario", "engine", "integrator", "dt", "status", "message"]
        rows = [
            [r["scenario"], r["engine"], r["integrator"], fmt(r["dt"]), r["status"], r["message"]]
            for _, r in bad.iterrows()
        ]
        out.append(("table", "Runs that did not complete", header, rows))
    settings = {}
    for _, r in df[df["settings"] != ""].iterrows():
        try:
            s = json.loads(r["settings"])
        except ValueError:
            continue
        for k, v in s.items():
            settings.setdefault((r["engine"], r["integrator"], k), v)
    if settings:
        rows = [
            [e, i, k, fmt(v) if not isinstance(v, (list, dict)) else json.dumps(v)]
            for (e, i, k), v in sorted(settings.items(), key=lambda kv: kv[0])
        ]
        out.append(
            (
                "table",
                "Settings changed from the engines' defaults",
                ["engine", "integrator", "setting", "value"],
                rows,
            )
        )
    return out


#: Accuracy levels of the work-precision table (max attitude error, rad).
ACCURACY_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)


def work_precision_table(sub, metric: str = "attitude_error_max", levels=ACCURACY_LEVELS):
    """For each accuracy level: the cheapest run (engine, integrator, dt) whose ``metric`` is
    at or below it, by wall time of the stepping, and how many times more the cheapest run of
    every other engine/integrator that reaches it costs. Returns (header, rows) or None."""
    ok = sub[(sub["status"] == "ok") & (sub["engine"] != "exact")]
    ok = ok[np.isfinite(ok[metric]) & (ok["wall_time_s"] > 0)]
    if ok.empty:
        return None
    rows = []
    for level in levels:
        hit = ok[ok[metric] <= level]
        if hit.empty:
            rows.append([f"{level:.0e}", "none of the runs", "-", "-", "-"])
            continue
        best = hit.loc[hit.groupby(["engine", "integrator"])["wall_time_s"].idxmin()]
        best = best.sort_values("wall_time_s")
        first = best.iloc[0]
        others = (
            ", ".join(
                f"{r['engine']} {r['integrator']} x{r['wall_time_s'] / first['wall_time_s']:.3g}"
                for _, r in best.iloc[1:4].iterrows()
            )
            or "-"
        )
        rows.append(
            [
                f"{level:.0e}",
                f"{first['engine']} {first['integrator']}",
                f"{first['dt']:g}",
                fmt(first["wall_time_s"]),
                others,
            ]
        )
    header = ["attitude error <=", "cheapest", "dt", "wall time [s]", "next cheapest (cost ratio)"]
    return header, rows


def _provenance_lines(prov: dict) -> list[tuple[str, str]]:
    m = prov.get("machine", {})
    lines = [
        ("suite version", prov.get("suite_version", "?")),
        ("git commit", prov.get("git_commit", "?")),
        ("date (UTC)", prov.get("date", "?")),
        (
            "machine",
            f"{m.get('cpu', '?')}, {m.get('cores', '?')} cores, {m.get('platform', '?')},"
            f" Python {m.get('python', '?')}",
        ),
    ]
    for eng, ver in prov.get("engines", {}).items():
        lines.append((f"engine {eng}", str(ver)))
    return lines


# -- documents ---------------------------------------------------------------------------------
def build_report(root: str | Path, progress: bool = False) -> dict[str, Path]:
    """Write plots, report.md and report.html for the results folder ``root``."""
    from reports.ensemble import read_ensemble, summary
    from reports.plots import all_plots, ensemble_plot
    from reports.results import STORE_NAME, frame, read_results

    root = Path(root)
    edf = read_ensemble(root)
    if (root / STORE_NAME).exists() or edf is None:
        df = read_results(root)
    else:  # a folder holding only an ensemble
        df = frame([])
    prov = read_provenance(root)
    plots = all_plots(df, root)
    secs = sections(df)
    if edf is not None:
        for scenario, g in edf.groupby("scenario"):
            rows = summary(g)
            cols = [c for c in rows[0] if c != "scenario"]
            title = (
                f"{scenario}: ensemble of {g['member'].nunique()} initial conditions "
                "(median, 90th percentile, max)"
            )
            secs.append(("table", title, cols, [[fmt(r[c]) for c in cols] for r in rows]))
            paths = [
                ensemble_plot(g, root / "plots", m)
                for m in ("attitude_error_max", "energy_drift_max")
            ]
            plots.setdefault(f"{scenario} ensemble", []).extend(p for p in paths if p)

    md = ["# director-bench report", ""]
    md += [f"- {k}: {v}" for k, v in _provenance_lines(prov)]
    md.append("")
    for kind, title, header, rows in secs:
        md.append(title + "\n" if kind == "text" else markdown_table(title, header, rows))
    for scenario, paths in plots.items():
        if paths:
            md.append(f"### {scenario}: plots\n")
            md += [f"![{p.stem}](plots/{p.name})" for p in paths]
            md.append("")
    (root / "report.md").write_text("\n".join(md))

    css = (
        "body{font-family:system-ui,sans-serif;margin:2em;max-width:1200px}"
        "table{border-collapse:collapse;font-size:12px;margin-bottom:1em}"
        "td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}"
        "td:first-child,th:first-child,td:nth-child(2){text-align:left}"
        "img{max-width:48%;margin:4px;border:1px solid #eee}"
    )
    h = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>director-bench report"
        f"</title><style>{css}</style></head><body><h1>director-bench report</h1><ul>"
    ]
    h += [
        f"<li><b>{html.escape(k)}</b>: {html.escape(str(v))}</li>"
        for k, v in _provenance_lines(prov)
    ]
    h.append("</ul>")
    for kind, title, header, rows in secs:
        h.append(
            f"<p>{html.escape(title)}</p>" if kind == "text" else html_table(title, header, rows)
        )
    for scenario, paths in plots.items():
        if not paths:
            continue
        h.append(f"<h3>{html.escape(scenario)}: plots</h3><div>")
        for p in paths:
            data = base64.b64encode(p.read_bytes()).decode()
            h.append(f"<img alt='{html.escape(p.stem)}' src='data:image/png;base64,{data}'>")
        h.append("</div>")
    h.append("</body></html>")
    (root / "report.html").write_text("\n".join(h))
    return {"markdown": root / "report.md", "html": root / "report.html", "plots": root / "plots"}
