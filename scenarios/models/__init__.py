"""Robot models from URDF and MJCF files, read by our own readers into the suite's system of
bodies (docs/scenarios.md, "Robot models").

- :mod:`.xml`: the XML tree with line numbers, :class:`ModelError`;
- :mod:`.urdf`, :mod:`.mjcf`: the readers (what enters the dynamics, and what is refused);
- :mod:`.geoms`: mass properties of MJCF's primitive geoms;
- :mod:`.model`: the reading (:class:`RobotModel`) and its conversion to bodies and joints;
- :mod:`.library`: model names (``gymnasium:ant``, ``example-robot-data:ur5``, the models
  shipped here) to files;
- :mod:`.scenario`: the ``[model]`` scenario file, validated into a system scenario.
"""

from __future__ import annotations

from pathlib import Path

from scenarios.models.model import RobotModel, to_system
from scenarios.models.xml import ModelError

__all__ = ["ModelError", "RobotModel", "read_model", "to_system"]


def model_format(path) -> str:
    """ "urdf" or "mjcf" from the file's extension (.urdf; .xml or .mjcf), else from its
    root element."""
    p = Path(path)
    if p.suffix.lower() == ".urdf":
        return "urdf"
    if p.suffix.lower() in (".mjcf",):
        return "mjcf"
    from scenarios.models.xml import parse

    tag = parse(p).tag
    if tag == "robot":
        return "urdf"
    if tag == "mujoco":
        return "mjcf"
    raise ModelError(
        f"model file {p}: root element <{tag}>: neither URDF (<robot>) nor MJCF (<mujoco>)",
        path=str(p),
    )


def read_model(path, packages=None, meshes: str = "require") -> RobotModel:
    """Read a URDF or MJCF file (:func:`model_format` decides which)."""
    from scenarios.models import mjcf, urdf

    if model_format(path) == "urdf":
        return urdf.read(path, packages=packages, meshes=meshes)
    return mjcf.read(path)
