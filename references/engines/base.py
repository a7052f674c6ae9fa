"""Re-exports of the engine interface's names for an importer that still uses this path
(tests/test_engine_mjx.py); new code imports from :mod:`references.engines` or from the module
that defines a name:

- :mod:`references.engines.integrators`: ``Family``, ``FAMILIES``, ``register_family``,
  ``Integrator``, ``slug``
- :mod:`references.engines.context`: ``BodyModel``, ``ModelReadback``, ``Clock``,
  ``RunContext``, ``RunOutput``
- :mod:`references.engines.interface`: ``EngineBase``, ``Engine``
- :mod:`references.engines.stepping`: the run loop, ``step_plan``, ``check_readback``,
  ``check_initial``, ``initial_state``, ``DIVERGENCE_ENERGY``, ``CHUNK``, ``READBACK_RTOL``
- :mod:`references.engines.recording`: ``Recorder``, ``block_trajectory``
- :mod:`references.engines.native`: ``NativeStderr``, ``import_engine``
"""

from __future__ import annotations

from references.engines.context import BodyModel, Clock, ModelReadback, RunContext, RunOutput
from references.engines.integrators import (
    FAMILIES,
    Family,
    Integrator,
    register_family,
    slug,
)
from references.engines.interface import Engine, EngineBase
from references.engines.native import NativeStderr, import_engine
from references.engines.recording import Recorder, block_trajectory
from references.engines.stepping import (
    CHUNK,
    DIVERGENCE_ENERGY,
    READBACK_RTOL,
    check_initial,
    check_readback,
    initial_state,
    step_plan,
)
from references.errors import Diverged, EngineError, EngineUnavailable, StepFailure, Unsupported

__all__ = [
    "CHUNK",
    "DIVERGENCE_ENERGY",
    "FAMILIES",
    "READBACK_RTOL",
    "BodyModel",
    "Clock",
    "Diverged",
    "Engine",
    "EngineBase",
    "EngineError",
    "EngineUnavailable",
    "Family",
    "Integrator",
    "ModelReadback",
    "NativeStderr",
    "Recorder",
    "RunContext",
    "RunOutput",
    "StepFailure",
    "Unsupported",
    "block_trajectory",
    "check_initial",
    "check_readback",
    "import_engine",
    "initial_state",
    "register_family",
    "slug",
    "step_plan",
]
