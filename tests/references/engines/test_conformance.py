"""The conformance kit (references.engines.conformance) on every registered engine adapter, and
the kit's own checks shown to fail on adapters that break them.

Every adapter is held to the same items: model read back, initial state through the engine's
own quantities, every planted mistake caught (free and pivoted), declared orders measured,
units. An adapter that is not installed is skipped with its reason.
"""

from __future__ import annotations

import numpy as np
import pytest

from references.engines import conformance as kit
from references.engines import get_engine

# MJX passes the same kit in tests/references/engines/test_engine_mjx.py (test_assert_conforms),
# which shares its compiled steppers with the MJX tests instead of compiling them a second time
# here.
ADAPTERS = ("mujoco", "pinocchio", "dart", "pybullet", "director", "drake")


def adapter_or_skip(name):
    cls = get_engine(name)
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine {name!r} is not available here: {why}")
    return cls


@pytest.mark.parametrize("name", ADAPTERS)
def test_adapter_passes_the_kit(name):
    cls = adapter_or_skip(name)
    checks = kit.check_adapter(cls)
    failed = [f"{c.name}: {c.message}" for c in checks if not c.ok]
    assert not failed, "\n".join(failed)
    names = {c.name for c in checks}
    # every planted mistake was tried on a free body (and on a pivoted one where supported)
    for mistake in (*kit.STATE_MISTAKES, *kit.MODEL_MISTAKES):
        assert f"catches {mistake} (free)" in names
        assert f"catches {mistake} (pivoted)" in names
    for integ in cls.integrators:
        if integ.order >= 1 and not integ.adaptive:  # a fixed step has an order to measure
            assert f"declared order of {integ.name!r}" in names


def test_pybullet_defaults_planted_back_are_caught_at_run_time():
    """PyBullet lets nothing of its damping, velocity clamp or joint motor be read back; the
    probe step of its read-back must catch each when planted back on a built model."""
    cls = adapter_or_skip("pybullet")
    checks = {c.name: c for c in kit.check_mistakes(cls)}
    for name in cls.plantable:
        kinds = cls.plantable[name][1]
        for kind in kinds:
            c = checks[f"catches {name} ({kind})"]
            assert c.ok and "probe step" in c.message, c.message


# -- the kit's checks can fail ------------------------------------------------------------------


def _blind(cls):
    """An adapter whose "own" quantities are computed from the state the suite reads back
    through its conversions: a consistent mistake then passes every check but the kit's."""
    from references.engines.stepping import check_readback  # noqa: F401 - the path under test
    from references.trajectory import OneBody

    def native_quantities(self, ctx):
        st = self.read_state(ctx)
        tr = OneBody.from_states(ctx.scenario, [0.0], *(np.asarray(a)[None] for a in st))
        return {
            "energy": float(tr.energy[0]),
            "angular momentum": tr.angular_momentum[0],
            "rotation": st.rotation,
        }

    return type(f"Blind{cls.__name__}", (cls,), {"native_quantities": native_quantities})


def test_the_kit_fails_an_adapter_whose_own_quantities_are_not_its_own():
    cls = _blind(adapter_or_skip("mujoco"))
    failed = [c.name for c in kit.check_mistakes(cls) if not c.ok]
    # the rotation and rate mistakes round-trip unseen; only the model mistake is still caught
    # (by the read-back of the model, which does not rely on the state)
    assert "catches quaternion order (w last read as w first) (free)" in failed
    assert "catches body rates written as world rates (free)" in failed
    assert "catches rates in degrees per second (free)" in failed
    assert not any("centre of mass" in n for n in failed)


def test_the_kit_fails_a_wrong_declared_order():
    from dataclasses import replace

    cls = adapter_or_skip("mujoco")
    wrong = tuple(replace(i, order=2) if i.name == "Euler" else i for i in cls.integrators)
    bad = type("WrongOrderMujoco", (cls,), {"integrators": wrong})
    checks = {c.name: c for c in kit.check_orders(bad)}
    assert not checks["declared order of 'Euler'"].ok
    assert checks["declared order of 'RK4'"].ok


def test_the_kit_fails_an_adapter_that_ignores_the_model():
    """An adapter that builds a body of the wrong mass (the model read back says so)."""
    import dataclasses

    cls = adapter_or_skip("mujoco")

    def build(self, ctx):
        true = ctx.model
        ctx.model = dataclasses.replace(true, mass=2 * true.mass)
        try:
            cls.build(self, ctx)
        finally:
            ctx.model = true

    bad = type("HeavyMujoco", (cls,), {"build": build})
    failed = [c for c in kit.check_runs(bad) if not c.ok]
    assert failed and all("mass" in c.message for c in failed)
