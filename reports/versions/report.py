"""``versions.md`` and ``versions.json``: the report section of a version matrix.

One table of the environments (what was asked, installed, how long it took), one summary line
per pair of consecutive versions (configurations compared, identical, within the factor,
changed, not compared), the table of every change (:mod:`reports.versions.changes`), and per
changed configuration one figure: left, each metric that changed against the version (log
scale, the changed pairs marked); right, the signed energy error over time of every version.
"""

from __future__ import annotations

import math
from pathlib import Path

from reports.metrics.catalog import HIGHER_IS_BETTER, ORDER_SLACK
from reports.versions.changes import (
    CHANGE_HEAD,
    SUMMARY_HEAD,
    VersionTable,
    _name,
    change_rows,
    signed_energy_error,
    summary_rows,
    write_json,
)

_COLOURS = {"worse": "#d00", "vanished": "#d00", "better": "#0a0", "new": "#0a0"}


def _md_table(head, rows) -> list[str]:
    esc = [[str(c).replace("|", "\\|") for c in r] for r in rows]
    return ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)] + [
        "| " + " | ".join(r) + " |" for r in esc
    ]


def _slug(text: str) -> str:
    import re

    return re.sub(r"[^A-Za-z0-9.]+", "-", text).strip("-")


def figure(tab: VersionTable, key: tuple, changes: list, path: Path) -> Path:
    """The figure of one changed configuration (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eng = key[1]
    versions = tab.versions[eng]
    cols = sorted({c.column for c in changes if c.kind in ("metric", "cost")})
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.6))
    xs = range(len(versions))
    for col in cols or ["energy_drift_max", "attitude_error_max"]:
        ys = []
        for v in versions:
            if key[3] is None:  # a cost change: the median over the dt sweep
                from reports.versions.changes import _cost_stats

                ys.append(_cost_stats(tab, eng, (key[0], key[2], key[4]), v)[0] or math.nan)
                continue
            r = tab.row(key, v)
            ok = r is not None and r["status"] == "ok"
            ys.append(float(r[col]) if ok and r.get(col) is not None else math.nan)
        if col in HIGHER_IS_BETTER:  # an order, not an error: its own linear axis
            twin = ax1.twinx()
            twin.plot(xs, ys, "s--", color="k", label=col)
            twin.set_ylabel(col, fontsize=8)
            continue
        ax1.plot(xs, ys, "o-", label=col)
    for c in changes:
        i = versions.index(c.to_version)
        ax1.axvspan(i - 1, i, color=_COLOURS.get(c.direction, "#e90"), alpha=0.08)
    ax1.set_yscale("log")
    ax1.set_xticks(list(xs), versions, rotation=30, fontsize=8)
    ax1.set_title("metrics that changed, per version", fontsize=9)
    ax1.legend(fontsize=7)
    drawn = False
    if key[3] is not None:
        for v in versions:
            r = tab.row(key, v)
            s = signed_energy_error(tab.folder, r) if r else None
            if s is not None:
                step = max(1, len(s[0]) // 1500)  # a figure's width holds no more points
                ax2.plot(s[0][::step], s[1][::step], lw=1, label=v)
                drawn = True
    if drawn:
        ax2.set_yscale("symlog", linthresh=1e-12)
        ax2.set_xlabel("t [s]", fontsize=8)
        ax2.legend(fontsize=7, ncol=2)
    ax2.set_title("signed energy error (E - E0) / E_c", fontsize=9)
    fig.suptitle(_name(key), fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def write_report(tab: VersionTable, out: Path, environments=None, figures: bool = True) -> dict:
    """Write ``versions.md``, ``versions.json`` and the figures (``versions-figures/``) into
    ``out``; returns their paths."""
    out = Path(out)
    lines = [
        "# Engine versions side by side",
        "",
        f"Folder `{out}`. A change is flagged between consecutive versions when an error "
        f"metric moved by more than a factor {tab.factor:g} above its round-off floor "
        f"(the CI gate's floors), a fitted order by more than {ORDER_SLACK:g}, the status or the "
        "verdict changed, the signed energy error changed class (conserved, gaining, losing), an "
        "integrator appeared or vanished, or the cost per step moved beyond both the factor "
        "and its measured spread over the dt sweep.",
        "",
    ]
    if environments:
        lines += ["## Environments", ""]
        head = ["engine", "version", "requirement", "environment", "made [s]", "runs [s]", "rows"]
        rows = []
        for e in environments:
            made = (
                "reused"
                if e["reused"]
                else (f"{e['create_seconds']:.1f}" if e["available"] else "unavailable")
            )
            rows.append(
                [e["engine"], e["label"], e["requirement"], e["path"] if e["available"] else
                 e["reason"][:200], made, f"{e['run_seconds']:.1f}", str(e["rows"])]
            )  # fmt: skip
        lines += _md_table(head, rows) + [""]
    lines += ["## Consecutive versions", ""]
    head = ["engine", "from", "to", "compared", "identical", "within factor", "changed", "n/a"]
    rows = [
        [p.engine, p.from_version, p.to_version, p.compared, p.identical, p.within, p.changed,
         len(p.not_compared)]
        for p in tab.pairs
    ]  # fmt: skip
    lines += _md_table(head, rows) + [""]
    lines += [f"## Changes ({len(tab.changes)})", ""]
    if tab.changes:
        lines += ["One row per pair of versions and configuration (ratios after/before):", ""]
        lines += _md_table(SUMMARY_HEAD, summary_rows(tab.changes)) + [""]
        lines += ["<details><summary>every change, value by value</summary>", ""]
        lines += _md_table(CHANGE_HEAD, change_rows(tab.changes)) + ["", "</details>", ""]
    else:
        lines += ["None: every configuration is the same within its factor and floor.", ""]
    if tab.cost_candidates:
        lines += [
            f"Cost differences seen in the stored rows but not confirmed by timing the two "
            f"versions side by side ({len(tab.cost_candidates)}; not changes):",
            "",
        ]
        lines += [f"- {_name(c.key)} {c.from_version} -> {c.to_version}: {why}"
                  for c, why in tab.cost_candidates]  # fmt: skip
        lines.append("")
    paths = {}
    by_key: dict = {}
    for c in tab.changes:
        by_key.setdefault(c.key, []).append(c)
    figdir = out / "versions-figures"
    if figures and figdir.is_dir():
        for old in figdir.glob("*.png"):  # the figures of an earlier report
            old.unlink()
    if by_key:
        lines += ["## Changed configurations", ""]
    for key, cs in by_key.items():
        lines += [f"### {_name(key)}", ""]
        lines += [f"- {r[0]}: {r[2]} {r[3]} -> {r[4]} ({r[6]})" for r in change_rows(cs)]
        if figures:
            rel = Path("versions-figures") / f"{_slug(_name(key))}.png"
            figure(tab, key, cs, out / rel)
            lines += ["", f"![{_name(key)}]({rel.as_posix()})"]
        lines.append("")
    md = out / "versions.md"
    md.write_text("\n".join(lines))
    paths["markdown"] = md
    paths["json"] = write_json(tab, out / "versions.json", environments)
    return paths
