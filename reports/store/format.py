"""How a stored value is written as text and as JSON, one way everywhere (the report, the
gate's check and compare, the engine-version tables).

Numbers (:func:`fmt`): three significant digits, scientific notation outside [1e-3, 1e4).
Missing values (NaN, None, an empty text column) read as NaN (:func:`num`) and print as ``-``.
Boolean columns come back from the store as text (:func:`truthy`). In JSON, NaN is ``null`` and
an infinity the string ``"inf"`` (:func:`json_value`). Markdown cells are escaped so a value is
shown as it is (:func:`md_cell`).
"""

from __future__ import annotations

import math

import numpy as np


def fmt(v) -> str:
    """A number for a table: three significant digits, scientific notation outside
    [1e-3, 1e4) with a short exponent (``8.50e-4``, ``1.58e5``); NaN and None are ``-``,
    integers and text as they are."""
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    v = float(v)
    if math.isnan(v):
        return "-"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == 0:
        return "0"
    r = float(f"{v:.3g}")
    if math.isinf(r):  # v within rounding of the largest double: its 3 digits overflow
        r = v
    if 1e-3 <= abs(r) < 1e4:
        e = math.floor(math.log10(abs(r)))
        return f"{r:.{max(0, 2 - e)}f}"
    mant, exp = f"{r:.2e}".split("e")
    return f"{mant}e{int(exp)}"


def fmt_int(v) -> str:
    """A count or a declared order: a whole number, ``-`` if missing."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return "-" if v in (None, "") else str(v)
    return "-" if math.isnan(f) else str(int(round(f)))


def fmt_level(v: float) -> str:
    """An accuracy level or target accuracy: ``1e-8``."""
    mant, exp = f"{float(v):.0e}".split("e")
    return f"{mant}e{int(exp)}"


def fmt_step(dt: float) -> str:
    """A step size as given, with a short exponent as in :func:`fmt`: ``0.002``, ``1e-5``,
    ``6.25e-5``."""
    mant, e, exp = f"{float(dt):g}".partition("e")
    return f"{mant}e{int(exp)}" if e else mant


def fmt_cost(ns: float) -> str:
    """A cost per step given in ns, as ``1.23 µs`` (``-`` when unknown)."""
    try:
        v = float(ns)
    except (TypeError, ValueError):
        return "-"
    if not v > 0:
        return "-"
    return f"{fmt(v / 1e3)} µs"


def num(v) -> float:
    """A stored value as a float: NaN when it is missing or not a number."""
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def truthy(v) -> bool:
    """A boolean column read back from the store (``"True"``/``"False"``/empty)."""
    return v is True or str(v).strip().lower() in ("true", "1", "yes")


def json_value(v):
    """NaN and None -> null, +-inf -> "inf"/"-inf" (JSON has no infinities), numpy -> Python."""
    if isinstance(v, bool | np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        f = float(v)
        if math.isnan(f):
            return None
        if math.isinf(f):
            return "inf" if f > 0 else "-inf"
        return f
    if v is None:
        return None
    return v


def md_cell(text) -> str:
    """Text safe in a GitHub-flavoured Markdown table cell or paragraph, shown as it is:
    backslashes, pipes and backticks escaped, ``&`` and ``<`` as entities (so ``<1e-12`` is
    not read as a tag, nor ``&lt;`` as a character), one line (newlines would end the row)."""
    text = " ".join(str(text).split())
    text = text.replace("\\", "\\\\").replace("|", "\\|").replace("`", "\\`")
    return text.replace("&", "&amp;").replace("<", "&lt;")


def md_table(header, rows) -> str:
    lines = ["| " + " | ".join(md_cell(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(md_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(lines) + "\n"
