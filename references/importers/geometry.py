"""A copy of a URDF file without its geometry (``<visual>``, ``<collision>``), for importers
that would otherwise load mesh files or compute inertias from collision shapes; the copy is
written beside nothing of the user's (a temporary folder) and says so in the notes."""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path


def strip_urdf(path, extra: str | None = None) -> Path:
    """The path of a copy of the URDF ``path`` with every link's visual and collision removed
    (and ``extra``, an XML element's text, appended to the robot element)."""
    tree = ET.parse(path)
    root = tree.getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    if extra:
        root.append(ET.fromstring(extra))
    folder = Path(tempfile.mkdtemp(prefix="director-bench-urdf-"))
    out = folder / Path(path).name
    tree.write(out)
    return out
