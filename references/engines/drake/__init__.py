"""The Drake adapter (:class:`DrakeEngine`), by job:

- :mod:`.integrators`: Drake's integrators as the adapter offers them, and their families;
- :mod:`.charts`: the roll-pitch-yaw charts of a pivoted body on the BallRpyJoint;
- :mod:`.plant`: the MultibodyPlant, its Simulator and integrator, and their read-back;
- :mod:`.adapter`: the adapter (state, stepping, chart switches, the evaluation budget).
"""

from __future__ import annotations

from references.engines.drake.adapter import EVAL_BUDGET, MIN_FIXED_STEPS, DrakeEngine
from references.engines.drake.charts import (
    CHART_SWITCH_COS,
    centred_chart,
    lagrange_tilt_band,
    rpy_chart,
)
from references.engines.drake.integrators import INTEGRATORS

__all__ = [
    "CHART_SWITCH_COS",
    "EVAL_BUDGET",
    "INTEGRATORS",
    "MIN_FIXED_STEPS",
    "DrakeEngine",
    "centred_chart",
    "lagrange_tilt_band",
    "rpy_chart",
]
