"""The conformance kit: what every engine adapter must pass, ours and a user's.

:func:`check_adapter` runs the checks below on an adapter class and returns one :class:`Check` per
item (``ok`` and a message); :func:`assert_conforms` raises with every failed item.
``tests/references/engines/test_conformance.py`` runs the kit on every registered adapter, and an
adapter in another package can do the same in its own tests::

    from references.engines.conformance import assert_conforms
    assert_conforms(MyEngine)

The checks:

- **identity**: a name, integrators with a registered family and a description, a version;
- **model read back**: the built model holds the scenario's mass, inertia, centre of mass,
  joint, gravity and step (free and pivoted bodies);
- **initial state through the engine's own quantities**: one step runs and passes the
  initial check (the engine's own energy, momentum and rotation equal the scenario's);
- **planted mistakes caught**: a mistake planted at the adapter's boundary, made the same way
  in both directions so that the round trip through the conversions still agrees, must make
  the run refuse (status ``error``), never run ``ok``: the quaternion stored in the other
  order, body rates written as world rates, rates in degrees per second, and the centre of
  mass (inertial frame) built off the body frame. Adapters may declare engine-specific
  mistakes of their own (``Engine.plantable``: {name: (plant(ctx) applied right after
  building, the kinds of body it applies to: "free", "pivoted")}, e.g. a default that
  distorts the experiment left on), which must be caught the same way;
- **declared order measured**: the slope of the attitude error over a dt sweep on a smooth
  free body is within :data:`ORDER_SLACK` of each fixed-step integrator's declared order
  (error-controlled integrators run the other checks at the target accuracy
  :data:`KIT_ACCURACY`);
- **units**: times in seconds (the last saved time is the horizon), energy in joules (the
  first saved energy is the scenario's E0 to round-off).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from references import conventions as cv
from references.errors import EngineError, Unsupported
from references.trajectory import one_body
from scenarios.metric_catalog import METRICS

#: a measured order may differ from the declared one by this much: the convergence order's
#: slack in the metric catalog, the gate's too
ORDER_SLACK = next(m.slack for m in METRICS if m.name == "convergence_order")


@dataclass
class Check:
    name: str
    ok: bool
    message: str = ""


# -- the kit's scenarios: non-identity rotation, generic rates, generic gravity ----------------


def free_scenario(**kw):
    from scenarios.model import Scenario

    d = dict(
        name="conformance-free",
        description="free body, generic state (the conformance kit)",
        mass=1.5,
        inertia=[2.0, 3.0, 4.0],
        rotation=cv.rotvec_to_matrix([0.3, -1.1, 0.7]),
        omega_body=[0.4, -1.3, 2.1],
        position=[0.1, 0.2, -0.3],
        velocity=[1.0, -2.0, 0.5],
        gravity=[0.3, -0.2, -9.81],
        t_end=1.0,
        dt=1e-3,
    )
    d.update(kw)
    return Scenario(**d)


def pivoted_scenario(**kw):
    from scenarios.model import Scenario

    d = dict(
        name="conformance-pivoted",
        description="body on a pivot off every principal axis (the conformance kit)",
        mass=1.5,
        inertia=[2.0, 3.0, 4.0],
        rotation=cv.rotvec_to_matrix([0.3, -1.1, 0.7]),
        omega_body=[0.4, -1.3, 2.1],
        gravity=[0.3, -0.2, -9.81],
        pivot=[0.05, -0.1, 0.3],
        t_end=1.0,
        dt=1e-3,
    )
    d.update(kw)
    return Scenario(**d)


# -- mistakes planted at the adapter's boundary -------------------------------------------------


def _swap_quaternion(R, inverse=False):
    """The rotation whose (w, x, y, z) quaternion is R's read in the other order."""
    q = cv.matrix_to_quat_wxyz(R)
    q = np.roll(q, 1) if inverse else np.roll(q, -1)
    return cv.quat_wxyz_to_matrix(q)


def _state_mistake(to_engine, from_engine):
    """A mixin planting a state mistake the same way in set_state and read_state."""

    def set_state(self, ctx, state):
        type(self).__mro__[1].set_state(self, ctx, to_engine(state))

    def read_state(self, ctx):
        return from_engine(type(self).__mro__[1].read_state(self, ctx))

    return {"set_state": set_state, "read_state": read_state}


def _rotation_map(f, finv):
    return _state_mistake(
        lambda s: s._replace(rotation=f(s.rotation)),
        lambda s: s._replace(rotation=finv(s.rotation)),
    )


DEG = 180.0 / math.pi

#: name -> methods overriding the adapter's (each a consistent mistake, see the module text)
STATE_MISTAKES = {
    "quaternion order (w last read as w first)": _rotation_map(
        _swap_quaternion, lambda R: _swap_quaternion(R, inverse=True)
    ),
    "body rates written as world rates": _state_mistake(
        lambda s: s._replace(omega_body=s.rotation @ s.omega_body),
        lambda s: s._replace(omega_body=s.rotation.T @ s.omega_body),
    ),
    "rates in degrees per second": _state_mistake(
        lambda s: s._replace(omega_body=DEG * np.asarray(s.omega_body)),
        lambda s: s._replace(omega_body=np.asarray(s.omega_body) / DEG),
    ),
}


def _com_offset():
    """Build the model with its centre of mass 5 % of the body's size off the body frame."""

    def build(self, ctx):
        true = ctx.model
        size = float(np.linalg.norm(true.com)) or math.sqrt(float(np.max(true.inertia)) / true.mass)
        ctx.model = dataclasses.replace(true, com=true.com + 0.05 * size * np.array([1.0, -1, 1]))
        try:
            type(self).__mro__[1].build(self, ctx)
        finally:
            ctx.model = true

    return {"build": build}


MODEL_MISTAKES = {"centre of mass (inertial frame) off the body frame": _com_offset()}


def _planted(cls, name: str, methods: dict):
    return type(f"{cls.__name__}Planted", (cls,), {**methods, "__doc__": f"planted: {name}"})


def _engine_mistake(cls, name: str, plant):
    """An adapter that applies the engine-specific ``plant(ctx)`` right after building."""

    def build(self, ctx):
        cls.build(self, ctx)
        plant(ctx)

    return type(f"{cls.__name__}Planted", (cls,), {"build": build})


# -- the checks -----------------------------------------------------------------------------


#: the target accuracy the kit gives an error-controlled integrator
KIT_ACCURACY = 1e-8


def _short_run(engine, sc, integrator):
    acc = KIT_ACCURACY if engine.integrator(integrator).adaptive else None
    return engine.run(sc, integrator, sc.dt, t_end=2 * sc.dt, save_every=1, accuracy=acc)


def _scenarios(cls, integrator):
    out = []
    for make in (free_scenario, pivoted_scenario):
        sc = make()
        try:
            cls().check_supported(sc, cls.integrator(integrator))
        except Unsupported:
            continue
        out.append(sc)
    return out


def check_identity(cls) -> list[Check]:
    from references.engines.integrators import FAMILIES

    out = [Check("has a name", bool(getattr(cls, "name", "")), "")]
    integs = getattr(cls, "integrators", ())
    out.append(Check("offers integrators", len(integs) > 0, f"{len(integs)} integrators"))
    for i in integs:
        ok = i.family in FAMILIES and len(i.description) > 20 and i.order >= 0
        out.append(Check(f"integrator {i.name!r} is documented", ok, i.family))
    try:
        v = cls.version()
        out.append(Check("reports its version", bool(v), v))
    except EngineError as exc:
        out.append(Check("reports its version", False, str(exc)))
    return out


def check_runs(cls) -> list[Check]:
    """Model read back and the initial check pass, free and pivoted, for every integrator;
    units of the output."""
    out = []
    for integ in cls.integrators:
        for sc in _scenarios(cls, integ.name):
            what = f"{integ.name} on a {'pivoted' if sc.pivot is not None else 'free'} body"
            try:
                res = _short_run(cls(), sc, integ.name)
            except EngineError as exc:
                out.append(Check(f"runs and passes the read-back: {what}", False, str(exc)))
                continue
            tr = one_body(res.trajectory)
            units = (
                abs(tr.t[-1] - 2 * sc.dt) <= 1e-15
                and abs(tr.energy[0] - _energy0(sc)) <= 1e-12 * sc.energy_scale
            )
            out.append(Check(f"runs and passes the read-back: {what}", True))
            out.append(Check(f"units (s, J): {what}", units, f"t_end {tr.t[-1]!r}"))
    return out


def _energy0(sc) -> float:
    from references.trajectory import energy

    return float(
        energy(sc, sc.position[None], sc.velocity[None], sc.rotation[None], sc.omega_body[None])[0]
    )


def check_mistakes(cls) -> list[Check]:
    """Every planted mistake makes a short run refuse (EngineError with status error)."""
    kinds = ("free", "pivoted")
    plants = {n: (_planted, m, kinds) for n, m in {**STATE_MISTAKES, **MODEL_MISTAKES}.items()}
    for n, (plant, where) in cls.plantable.items():
        plants[n] = (_engine_mistake, plant, where)
    integ = cls.integrators[0].name
    out = []
    for name, (make, what, where) in plants.items():
        bad_cls = make(cls, name, what)
        for sc in _scenarios(cls, integ):
            kind = "pivoted" if sc.pivot is not None else "free"
            if kind not in where:
                continue
            try:
                _short_run(bad_cls(), sc, integ)
            except EngineError as exc:
                ok = exc.status == "error"
                out.append(Check(f"catches {name} ({kind})", ok, str(exc)[:200]))
            else:
                out.append(Check(f"catches {name} ({kind})", False, "the run completed ok"))
    return out


def measured_order(cls, integrator: str, dts=(0.04, 0.02, 0.01)) -> float:
    """Slope of the attitude error at t = 2 s over ``dts`` on a smooth free body (no
    separatrix: case A, k^2 = 0.16), against the closed-form reference."""
    from references.exact import reference_trajectory

    sc = free_scenario(
        inertia=[0.9, 1.4, 2.0], omega_body=[1.2, -0.8, 2.1], gravity=[0, 0, 0], t_end=2.0
    )
    ref = one_body(reference_trajectory(sc, [sc.t_end]))
    errs = []
    for h in dts:
        out = cls().run(sc, integrator, h, t_end=sc.t_end, save_every=round(sc.t_end / h))
        tr = one_body(out.trajectory)
        d = np.linalg.norm(tr.rotation[-1] - ref.rotation[0]) / (2 * math.sqrt(2))
        errs.append(2 * math.asin(min(d, 1.0)))
    return float(np.polyfit(np.log(dts), np.log(errs), 1)[0])


def check_orders(cls) -> list[Check]:
    out = []
    for integ in cls.integrators:
        if integ.order < 1 or integ.adaptive:
            continue  # an error-controlled integrator's step is not the dt of a sweep
        dts = (0.04, 0.02, 0.01) if integ.order <= 2 else (0.05, 0.025, 0.0125)
        try:
            cls().check_supported(free_scenario(), integ)
        except Unsupported:
            continue  # an integrator the engine refuses (with its reason) has no order to show
        try:
            p = measured_order(cls, integ.name, dts)
        except EngineError as exc:
            out.append(Check(f"declared order of {integ.name!r}", False, str(exc)))
            continue
        ok = abs(p - integ.order) <= ORDER_SLACK
        out.append(
            Check(
                f"declared order of {integ.name!r}", ok, f"declared {integ.order}, measured {p:.3f}"
            )
        )
    return out


def check_adapter(cls, orders: bool = True) -> list[Check]:
    """Every check of the kit on the adapter class ``cls`` (see the module docstring)."""
    checks = check_identity(cls)
    if cls.availability() is not None:
        return checks
    checks += check_runs(cls) + check_mistakes(cls)
    if orders:
        checks += check_orders(cls)
    return checks


def assert_conforms(cls, orders: bool = True) -> None:
    """Raise AssertionError listing every failed check of the kit."""
    failed = [c for c in check_adapter(cls, orders) if not c.ok]
    if failed:
        lines = "\n".join(f"  {c.name}: {c.message}" for c in failed)
        raise AssertionError(f"adapter {cls.__name__} fails {len(failed)} check(s):\n{lines}")
