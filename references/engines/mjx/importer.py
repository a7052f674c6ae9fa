"""MJX's importer: MuJoCo's (:mod:`references.engines.mujoco.importer`), its model put on
the device by ``mjx.put_model`` (64-bit), read back from the MJX model's own arrays."""

from __future__ import annotations

import contextlib
import io

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
