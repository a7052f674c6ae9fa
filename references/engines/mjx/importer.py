"""MJX's importer: MuJoCo's (:mod:`references.engines.mujoco.importer`), its model put on
the device by ``mjx.put_model`` (64-bit), read back from the MJX model's own arrays."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from references.engines.importers import Readback
from references.engines.mujoco.importer import mujoco_model, mujoco_readback


def readback(model, config: str, floating: bool = False) -> Readback:
    """MuJoCo's model put on the device by ``mjx.put_model``, read from the MJX model's own
    arrays (float64)."""
    try:
        m = mujoco_model(model, config, floating)
    except Exception as exc:
        return Readback("mjx", config, error=f"{type(exc).__name__}: {exc}".strip())
    import jax

    jax.config.update("jax_enable_x64", True)
    from mujoco import mjx as _mjx

    if config == "faithful":
        import mujoco as _mj

        # a contact-free test: MJX lacks some geom-pair collisions and refuses the model
        m.geom_contype[:] = 0
        m.geom_conaffinity[:] = 0
        m.opt.disableflags |= int(_mj.mjtDisableBit.mjDSBL_CONTACT)
    try:
        with contextlib.redirect_stderr(io.StringIO()):
            mx = _mjx.put_model(m)
    except Exception as exc:
        return Readback("mjx", config, error=f"put_model: {type(exc).__name__}: {exc}".strip())
    return mujoco_readback(m, model, "mjx", config, fields=mx)


# -- runs through the importer ---------------------------------------------------------------------

#: the integrators an importer run takes (:func:`references.engines.importers.variants`)
INTEGRATORS = ("Euler (float64)",)


def load(scenario, config: str, integrator: str, dt: float):
    """The scenario's model file loaded by MuJoCo's importer in ``config`` (MJX has no
    importer of its own: :class:`references.engines.mujoco.importer._Sim` sets the state),
    put on the device in float64 and stepped by ``mjx.step`` (``lax.fori_loop`` between
    saves, compiled as the MJX system builder's); the links read by C MuJoCo's kinematics on
    MJX's state. MJX lacks some geom-pair collisions: the faithful configuration switches
    contact off anyway, and a model MJX refuses as loaded is an unsupported row."""
    from references.engines.mujoco.importer import _Sim

    base = integrator.partition(" (")[0]

    class _MjxSim(_Sim):
        def __init__(self):
            super().__init__(scenario, config, base, dt)
            from references.engines.mjx.compile import _compiled, x64_mode
            from references.engines.mjx.system import _step_fn
            from references.errors import Unsupported

            jax, mjx, step = _step_fn()
            try:
                with x64_mode(True), contextlib.redirect_stderr(io.StringIO()):
                    mx = mjx.put_model(self.m, impl="jax")
                    dx = mjx.put_data(self.m, self.d, impl="jax")
                    # put_data's integer fields (the contact's geom ids) are int32, step's
                    # int64 under x64: the loop's carry keeps the types step gives (a model
                    # loaded with its contacts: ant, pusher as loaded)
                    shapes = jax.eval_shape(mjx.step, mx, dx)
                    dx = jax.tree_util.tree_map(lambda a, s: a.astype(s.dtype), dx, shapes)
            except Exception as exc:  # MJX's refusal of the loaded model is the finding
                raise Unsupported(
                    f"mjx: put_model or mjx.step refuses the model MuJoCo's importer loaded "
                    f"({config}): {type(exc).__name__}: {str(exc).strip()[:300]}"
                ) from None
            comp, secs, _ = _compiled(f"importer-step-{base}", step, (mx, dx),
                                      (np.int32(1),), True)  # fmt: skip
            self.jax, self.comp, self.x64 = jax, comp, x64_mode
            self.mxl, self.dxl = comp.leaves(0, mx), comp.leaves(1, dx)
            self.at = jax.tree_util.tree_unflatten(comp.defs[1], list(range(len(self.dxl))))
            self.settings = {**self.settings, "engine": "mjx.step (float64)",
                             "compile time s": round(secs, 3)}  # fmt: skip

        def advance(self, n: int) -> None:
            import time

            from references.engines import timing

            t0 = time.perf_counter()
            with self.x64(True):
                self.dxl = self.comp(self.mxl, self.dxl, np.int32(n))
                self.jax.block_until_ready(self.dxl[self.at.qvel])
            self.clock += timing.lap(t0)  # on the run's stopwatch: CPU slices
            self.d.qpos[:] = np.asarray(self.dxl[self.at.qpos])
            self.d.qvel[:] = np.asarray(self.dxl[self.at.qvel])

    return _MjxSim()
