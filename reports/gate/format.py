"""The tables of the gate's outputs (``check``, ``compare``, ``versions``): plain text for the
terminal, Markdown for a job summary or a pull-request comment. Numbers are formatted by
:mod:`reports.store.format`.
"""

from __future__ import annotations

import math


def json_number(v):
    """A value for the gate's JSON outputs: a NaN or infinite float as null, else as it is."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def md_escape(text) -> str:
    """Text safe inside a Markdown table cell (pipes, HTML, line breaks)."""
    s = str(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return s.replace("|", "\\|").replace("\n", " ").replace("`", "'")


def md_table(head, rows, align: str = "") -> list[str]:
    """A Markdown table, every cell escaped (:func:`md_escape`); ``align``: one letter per
    column, ``r`` for a right-aligned one (default left)."""
    align = align.ljust(len(head), "l")
    out = ["| " + " | ".join(md_escape(h) for h in head) + " |"]
    out.append("|" + "|".join("---:" if a == "r" else "---" for a in align) + "|")
    out += ["| " + " | ".join(md_escape(c) for c in r) + " |" for r in rows]
    return out


def text_table(head, rows) -> list[str]:
    """A plain-text table: columns padded to their widest cell, a rule under the header."""
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows, strict=True)]
    line = "  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return out
