"""MJX adapter: MuJoCo's JAX implementation (``mujoco-mjx``), free joint or ball joint.

Model: the MJCF of the C MuJoCo adapter (:meth:`MujocoEngine.model_xml`), compiled by MuJoCo
and put on the JAX device with ``mjx.put_model(impl="jax")``, so the layout is MuJoCo's
(docs/engines.md, section 2) and the conversions are :mod:`references.conventions`' MuJoCo
ones. The only change to the MJCF is its model name, always :data:`MODEL_NAME`: MJX keeps the
names in the static part of ``mjx.Model``, which is part of JAX's compilation key, so a
scenario's name would otherwise force a new compilation per scenario. The model's numbers
(mass, inertia, centre of mass, gravity, step) are array leaves and do not: one compilation
serves every scenario with the same joint, integrator and precision.

Precision. JAX computes in float32 unless 64-bit mode is on (JAX documentation, "The Sharp
Bits: double (64-bit) precision"). Every integrator is offered twice, as named configurations
"... (float64)" and "... (float32)"; every JAX call of a run (putting the model and data on
the device, compiling, stepping, the engine's own quantities) runs inside
``jax.enable_x64(True)`` or ``jax.enable_x64(False)``, a thread-local setting that overrides
the process's ``jax_enable_x64`` for that call only. JAX compiles a function separately for
each setting, but some of its in-memory staging caches ignore it, so a switch of the mode
between runs first drops them (:func:`.compile.x64_mode`); the two precisions then coexist in
one process, after systems of bodies too, whatever the user's global setting.
The read-back checks the width of the model's and the state's floats (8 or 4 bytes):
a float32 run labelled float64 cannot pass.

The initial state of a float32 run. The suite checks the state an engine holds before its
first step against the scenario to 1e-12 (:func:`references.engines.stepping.check_initial`),
which a float32 state cannot meet (its rounding alone is ~6e-8 relative). The float32
configurations therefore hand the scenario's state over in float64: before the first step the
state read back, and the engine's own quantities (C MuJoCo's, as in the C adapter, on the
``MjData`` from which MJX takes the state), are those of the float64 state handed over, which
checks the conversions to 1e-12 like every adapter. ``mjx.put_data`` in float32 mode then
rounds it; that rounded state, which MJX steps from, is checked at once through MJX's own
float32 quantities against the state handed over, to :data:`FLOAT32_INITIAL_RTOL`, and the
errors are recorded in the settings. From the first step on, everything read is MJX's float32
state.

Integrators (MJX's JAX backend, ``mujoco.mjx._src.forward.step``; MuJoCo documentation, "MJX:
Feature Parity"):

- ``Euler``: MuJoCo's semi-implicit Euler; reproduces C MuJoCo's ``Euler`` (float64: to
  round-off, tests/references/engines/test_engine_mjx.py).
- ``RK4``: the classical four stages in the velocities, but the positions are advanced once,
  by the exponential map of the stage-weighted mean velocity, without the dexp correction: order
  2 in the attitude (*measured*). That is C MuJoCo 3.17.0's RK4 (*measured*: equal to 1e-15
  after 160 steps), not 4.0.0's, whose RK4 is order 4 in the attitude; the family
  :data:`RK4_MEAN_EXP` says so.
- ``implicitfast``: MJX's implicit-in-velocity step without the derivative of the bias
  (Coriolis, centripetal, gyroscopic) forces; with no damping and no actuators it is the Euler
  step (*measured*: bit-identical to MJX ``Euler`` on free and ball joints), unlike C MuJoCo's
  ``implicitfast``, which keeps the gyroscopic derivative of a free body.
- ``implicit`` and ``discrete``: not implemented by MJX's JAX backend; declared so that the
  results show the gap. The adapter asks MJX (``put_model`` and a trace of ``step``) and
  reports MJX's own ``NotImplementedError`` as the reason of an ``unsupported`` row.

Modules: :mod:`.compile` (importing MJX, JAX's persistent cache, the compiled stepping and
own-quantities functions), :mod:`.adapter` (the engine: model, read-back, state, stepping)
and :mod:`.batch` (ensembles in one vmapped call).
"""

from references.engines.mjx.adapter import FLOAT32_INITIAL_RTOL, RK4_MEAN_EXP, MjxEngine
from references.engines.mjx.compile import CHECKPOINTS, MODEL_NAME

__all__ = [
    "CHECKPOINTS",
    "FLOAT32_INITIAL_RTOL",
    "MODEL_NAME",
    "RK4_MEAN_EXP",
    "MjxEngine",
]
