"""Engine registry: name -> adapter class, imported lazily so a missing engine never breaks
the suite.

The built-in adapters are listed here; installed packages add their own through the entry-point
group ``director_bench.engines`` (``name = "package.module:AdapterClass"``), so a user's engine
appears in ``director-bench list`` and runs every scenario with no change to this repository
(docs/engines.md, "Writing an adapter").
"""

from __future__ import annotations

import functools
import importlib

from references.engines.context import BodyModel, ModelReadback, RunContext, RunOutput
from references.engines.integrators import FAMILIES, Family, Integrator, register_family, slug
from references.engines.interface import Engine, EngineBase, SceneBuilder
from references.engines.native import import_engine
from references.engines.recording import Recorder, block_trajectory
from references.engines.stepping import CHUNK, DIVERGENCE_ENERGY, check_readback, step_plan
from references.errors import Diverged, EngineError, EngineUnavailable, StepFailure, Unsupported

#: the entry-point group through which other packages register engine adapters
ENTRY_POINT_GROUP = "director_bench.engines"

BUILTIN = {
    "director": "references.engines.director.adapter:DirectorEngine",
    "exact": "references.engines.exact.adapter:ExactEngine",
    "mujoco": "references.engines.mujoco.adapter:MujocoEngine",
    "pinocchio": "references.engines.pinocchio.adapter:PinocchioEngine",
    "dart": "references.engines.dart.adapter:DartEngine",
    "pybullet": "references.engines.pybullet.adapter:PybulletEngine",
    "drake": "references.engines.drake:DrakeEngine",
    "mjx": "references.engines.mjx:MjxEngine",
}


@functools.cache
def _registry() -> dict[str, str]:
    """Built-in adapters plus those registered by installed packages (entry points). A
    plug-in may not take a built-in name."""
    from importlib.metadata import entry_points

    reg = dict(BUILTIN)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in BUILTIN:
            continue  # a built-in name cannot be shadowed by a plug-in
        reg.setdefault(ep.name, ep.value)
    return reg


def engine_names() -> list[str]:
    """Every registered engine name, installed or not."""
    return list(_registry())


def reference_engine_names() -> list[str]:
    """The registered engines whose rows are the reference the others are measured against
    (:attr:`EngineBase.is_reference`: the exact reference), read from their adapter classes
    (importing an adapter never imports its engine)."""
    return [name for name in engine_names() if get_engine(name).is_reference]


class UnknownEngine(EngineUnavailable, KeyError):
    """No adapter is registered under this name here (e.g. rows of a plug-in that is not
    installed on this machine): an :class:`EngineUnavailable`, and a ``KeyError``."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


def get_engine(name: str) -> type[EngineBase]:
    """The adapter class registered as ``name`` (its import never needs the engine itself).

    An adapter whose module fails to import (any exception: a plug-in with a bug, a broken
    install) is replaced by a stand-in with no integrators whose :meth:`availability` gives
    the reason, so that one broken adapter never stops ``list`` or the other engines' runs.
    A name nobody registered raises :class:`UnknownEngine`."""
    try:
        target = _registry()[name]
    except KeyError:
        known = ", ".join(_registry())
        raise UnknownEngine(f"unknown engine {name!r}; known engines here: {known}") from None
    return _load(name, target)


@functools.cache
def _load(name: str, target: str) -> type[EngineBase]:
    module, cls = target.split(":")
    try:
        return getattr(importlib.import_module(module), cls)
    except Exception as exc:  # noqa: BLE001 - any failure of an adapter's import
        why = (
            f"engine {name!r}: its adapter {target} does not load ({type(exc).__name__}: "
            f"{exc}); reinstall the package that provides it, or uninstall it"
        )
        return _stand_in(name, why)


def _stand_in(name: str, why: str) -> type[EngineBase]:
    """An engine that is unavailable for the reason ``why`` and offers no integrator."""

    def version(cls) -> str:
        raise EngineUnavailable(why)

    def run(self, *args, **kwargs):
        raise EngineUnavailable(why)

    body = {"name": name, "description": why, "integrators": (), "broken": why}
    return type(f"Unloadable_{name}", (EngineBase,), body | {
        "version": classmethod(version), "run": run,
    })  # fmt: skip


__all__ = [
    "BUILTIN",
    "CHUNK",
    "DIVERGENCE_ENERGY",
    "ENTRY_POINT_GROUP",
    "FAMILIES",
    "BodyModel",
    "Diverged",
    "Engine",
    "EngineBase",
    "EngineError",
    "EngineUnavailable",
    "Family",
    "Integrator",
    "ModelReadback",
    "Recorder",
    "RunContext",
    "RunOutput",
    "SceneBuilder",
    "StepFailure",
    "UnknownEngine",
    "Unsupported",
    "block_trajectory",
    "check_readback",
    "engine_names",
    "get_engine",
    "import_engine",
    "reference_engine_names",
    "register_family",
    "slug",
    "step_plan",
]
