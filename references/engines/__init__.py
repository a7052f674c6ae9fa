"""Engine registry: name -> adapter class, imported lazily so a missing engine never breaks
the suite. Adding an engine is one new module and one line here."""

from __future__ import annotations

import importlib

from references.engines.base import (
    FAMILIES,
    Engine,
    EngineError,
    EngineUnavailable,
    Integrator,
    RunOutput,
    StepFailure,
    Unsupported,
    step_plan,
)

_REGISTRY = {
    "director": "references.engines.director:DirectorEngine",
    "exact": "references.engines.exact:ExactEngine",
    "mujoco": "references.engines.mujoco_engine:MujocoEngine",
    "pinocchio": "references.engines.pinocchio_engine:PinocchioEngine",
    "dart": "references.engines.dart_engine:DartEngine",
    "pybullet": "references.engines.pybullet_engine:PybulletEngine",
}


def engine_names() -> list[str]:
    """Every registered engine name, installed or not."""
    return list(_REGISTRY)


def get_engine(name: str) -> type[Engine]:
    """The adapter class registered as ``name`` (its import never needs the engine itself)."""
    try:
        target = _REGISTRY[name]
    except KeyError:
        raise KeyError(f"unknown engine {name!r}; known engines: {', '.join(_REGISTRY)}") from None
    module, cls = target.split(":")
    return getattr(importlib.import_module(module), cls)


__all__ = [
    "FAMILIES",
    "Engine",
    "EngineError",
    "EngineUnavailable",
    "Integrator",
    "RunOutput",
    "StepFailure",
    "Unsupported",
    "engine_names",
    "get_engine",
    "step_plan",
]
