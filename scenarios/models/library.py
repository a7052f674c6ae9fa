"""Model names to files: ``<source>:<model>``.

- ``suite:<name>``: the models shipped with the suite (``scenarios/robots/models/<name>.urdf``
  or ``.xml``), small enough for the default suite;
- ``gymnasium:<name>``: gymnasium's MuJoCo assets (``gymnasium/envs/mujoco/assets/<name>.xml``,
  e.g. ``ant``, ``pusher_v5``, ``reacher``), when gymnasium is installed;
- ``example-robot-data:<name>``: example-robot-data's URDFs (:data:`EXAMPLE_ROBOT_DATA`
  names, or a path below its ``robots`` folder), from the installed package's share folder
  (``cmeel.prefix/share`` in the wheel the package index serves) or a checkout named by the
  environment variable ``EXAMPLE_ROBOT_DATA_DIR`` (the folder holding ``robots/``).

The optional extra ``pip install director-bench[robots]`` installs both packages.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import sys
from pathlib import Path

from scenarios.models.xml import ModelError

SOURCES = ("suite", "gymnasium", "example-robot-data")

#: short names of example-robot-data models: path below its ``robots`` folder
EXAMPLE_ROBOT_DATA = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
    "solo12": "solo_description/robots/solo12.urdf",
    "solo8": "solo_description/robots/solo.urdf",
    "go2": "go2_description/urdf/go2.urdf",
    "double_pendulum": "double_pendulum_description/urdf/double_pendulum.urdf",
}


def shipped_models() -> Path:
    return Path(__file__).resolve().parents[1] / "robots" / "models"


def _erd_roots() -> list[Path]:
    roots = []
    env = os.environ.get("EXAMPLE_ROBOT_DATA_DIR")
    if env:
        roots.append(Path(env) / "robots")
    roots.append(Path(sys.prefix) / "share" / "example-robot-data" / "robots")
    try:  # the wheel on the package index (a cmeel wheel) keeps it under cmeel.prefix
        dist = importlib.metadata.distribution("example-robot-data")
        roots.append(Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    except importlib.metadata.PackageNotFoundError:
        pass
    spec = importlib.util.find_spec("example_robot_data")
    if spec is not None and spec.origin:
        for a in Path(spec.origin).resolve().parents:
            roots.append(a / "share" / "example-robot-data" / "robots")
    return roots


def resolve(name: str) -> tuple[Path, dict]:
    """(file, package folders for ``package://`` names) of the model ``name``; a
    :class:`ModelError` saying what is available, or what to install, otherwise."""
    source, sep, model = name.partition(":")
    if not sep or source not in SOURCES or not model:
        raise ModelError(
            f"model name {name!r}: expected <source>:<model>, source one of "
            f"{', '.join(SOURCES)} (e.g. gymnasium:ant, example-robot-data:ur5, "
            "suite:arm3), or give the file's path as model.file"
        )
    if source == "suite":
        for ext in (".urdf", ".xml"):
            p = shipped_models() / f"{model}{ext}"
            if p.is_file():
                return p, {}
        have = sorted(p.stem for p in shipped_models().glob("*") if p.suffix in (".urdf", ".xml"))
        raise ModelError(
            f"model name {name!r}: no shipped model {model!r}; shipped: {', '.join(have)}"
        )
    if source == "gymnasium":
        spec = importlib.util.find_spec("gymnasium")
        if spec is None or not spec.origin:
            raise ModelError(
                f"model name {name!r}: gymnasium is not installed (pip install "
                "'director-bench[robots]'), or give the file's path"
            )
        folder = Path(spec.origin).parent / "envs" / "mujoco" / "assets"
        p = folder / f"{model}.xml"
        if not p.is_file():
            have = sorted(q.stem for q in folder.glob("*.xml"))
            raise ModelError(
                f"model name {name!r}: no {p.name} in gymnasium's assets; "
                f"available: {', '.join(have)}"
            )
        return p, {}
    sub = EXAMPLE_ROBOT_DATA.get(model, model)
    for r in _erd_roots():
        if (r / sub).is_file():
            return r / sub, {"example-robot-data": r.parent, "example_robot_data": r.parent}
    raise ModelError(
        f"model name {name!r}: {sub} not found in example-robot-data (looked in "
        f"{', '.join(str(r) for r in _erd_roots())}); pip install "
        "'director-bench[robots]', set EXAMPLE_ROBOT_DATA_DIR to a checkout, or "
        f"give the file's path. Short names: {', '.join(EXAMPLE_ROBOT_DATA)}"
    )
