"""Each engine's own importer on a model file, read back and compared with our reading
(issue 36): :mod:`.readback` (the read-back and the differences), :mod:`.ours` (our reading
as a read-back), :mod:`.engines` (each engine's importer, two configurations),
:func:`importer_table` (every engine and configuration against ours)."""

from __future__ import annotations

from references.importers.readback import Difference, Readback, compare

__all__ = ["Difference", "Readback", "compare", "importer_table"]

#: the known cause of a difference, by engine and quantity, printed beside it
HINTS = {
    ("pybullet", "as-loaded", "inertia"): "loadURDF without URDF_USE_INERTIA_FROM_FILE "
    "recomputes the inertia from the collision shapes: pass that flag",
    ("pybullet", "as-loaded", "com"): "loadURDF without URDF_USE_INERTIA_FROM_FILE",
}


def importer_table(model, engines=None, configs=None, fixed_base=None) -> list:
    """Difference rows (:class:`Difference`) of every engine and configuration against our
    reading, and one row per engine not installed; an importer that refuses the file is one
    row with its message."""
    from references.importers import engines as E
    from references.importers.ours import readback as ours_readback

    ours = ours_readback(model)
    if fixed_base is None:
        fixed_base = model.format == "urdf"
    rows = []
    for e in engines or E.ENGINES:
        for c in configs or E.CONFIGS:
            try:
                rb = E.READERS[e](model, c)
            except ImportError as exc:
                rows.append(Difference(e, c, "engine", "not installed", "-", str(exc),
                                       float("nan"), ""))  # fmt: skip
                break
            hints = {q: h for (he, hc, q), h in HINTS.items() if he == e and hc == c}
            diff = compare(model, ours, rb, hints, fixed_base)
            if not diff:
                diff = [Difference(e, c, "all", "agree", "-", "-", float("nan"), "",
                                   f"{len(rb.bodies)} bodies, {len(rb.joints)} revolute "
                                   "joints read back")]  # fmt: skip
            rows.extend(diff)
    return rows
