"""The importer-difference table of a robot-model scenario in the report, read from the results
folder (``importers/<scenario>.json``, written by :mod:`reports.run.importers`).

Two tables: per engine and configuration, what its importer did to the model (refused it, or
per kind of difference - mass, centre of mass, inertia, joint axis and its line, limits,
damping, friction, armature, a body or joint missing - how many items differ and the largest);
then every difference, by name and size, collapsed in HTML. The runs of the importer
configurations themselves are rows of the scenario's tables ("RK4 (as loaded)").
"""

from __future__ import annotations

import html
import math

#: the summary's columns: (header, quantities of the rows it gathers)
COLUMNS = (
    ("mass", ("mass",)),
    ("centre of mass", ("com",)),
    ("inertia", ("inertia",)),
    ("joint axis", ("axis", "axis length")),
    ("axis line", ("axis offset",)),
    ("limits", ("lower", "upper")),
    ("damping, friction, armature", ("damping", "friction", "armature")),
    ("missing or extra", ("missing", "unknown body")),
)

#: the configurations as the run names them (references.engines.importers.CONFIG_WORDS)
CONFIG_WORDS = {"as-loaded": "as loaded", "faithful": "faithful"}


def _size(v, unit: str) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "yes"
    if unit == "%":
        return f"{v:.3g} %"
    return f"{v:.2g} {unit}" if unit else f"{v:.2g} (relative)"


def summary(table: dict) -> list[list[str]]:
    """The rows of the summary table (module docstring): engine, configuration and what its
    importer did ("agrees", "refuses the file: ...", or per kind of difference "inertia: 3 x,
    up to 42 %", kinds in :data:`COLUMNS` order)."""
    by: dict = {}
    for r in table["rows"]:
        by.setdefault((r["engine"], r["config"]), []).append(r)
    out = []
    for e in table["engines"]:
        for c in table["configs"]:
            rows = by.get((e, c), [])
            if not rows:
                continue
            first = rows[0]
            word = CONFIG_WORDS.get(c, c)
            if first["quantity"] == "not installed":
                out.append([e, word, "not installed"])
                continue
            if first["item"] == "model":
                out.append([e, word, f"refuses the file: {first['theirs']}"])
                continue
            if first["item"] == "all":
                out.append([e, word, "agrees with our reading"])
                continue
            parts = []
            for head, qs in COLUMNS:
                hit = [r for r in rows if r["quantity"] in qs]
                if not hit:
                    continue
                sized = [r for r in hit if r["size"] is not None]
                top = max(sized, key=lambda r: r["size"]) if sized else hit[0]
                parts.append(f"{head}: {len(hit)} x, up to {_size(top['size'], top['unit'])}")
            out.append([e, word, "; ".join(parts)])
    return out


def importer_section(doc, table: dict, cell) -> None:
    """The importer tables of one scenario into ``doc`` (the report's Markdown and HTML
    document); ``cell``: its cell class (text, md=, html_=)."""
    name = table["scenario"]
    cmd = table["command"]
    doc.para(
        f"Each engine's importer on {table['file']} ({table['format']}"
        f"{', floating base' if table['floating'] else ''}), read back at the zero "
        f"configuration against our own reading of the file; printed by `{cmd}`.",
        f"Each engine's importer on <code>{html.escape(table['file'])}</code> "
        f"({html.escape(table['format'])}{', floating base' if table['floating'] else ''}), "
        "read back at the zero configuration against our own reading of the file; printed by "
        f"<code>{html.escape(cmd)}</code>.",
    )
    doc.table(f"{name}: what each importer does to the model",
              ["engine", "configuration", "what differs from our reading"], summary(table),
              cls="narrow-stack")  # fmt: skip
    diff = [r for r in table["rows"] if r["item"] not in ("all",)]
    if not diff:
        return
    doc.open_details(f"Every importer difference of {html.escape(name)} ({len(diff)})")
    rows = [
        [r["engine"], CONFIG_WORDS.get(r["config"], r["config"]), r["item"], r["quantity"],
         cell("" if r["size"] is None else _size(r["size"], r["unit"]), num=True),
         r["ours"], r["theirs"], r["remark"]]
        for r in diff
    ]  # fmt: skip
    doc.table(
        f"{name}: importer differences",
        ["engine", "configuration", "item", "quantity", "size", "ours", "theirs", "remark"],
        rows,
        cls="stack",
    )
    doc.close_details()
