"""Adapter for the suite's own integrator, :mod:`director_model` (each scheme an integrator).

The director model is an engine like the others here: the model is its :class:`Body`
(convected moments J, pivot inertia), its state the directors D and their velocities D', its
own energy and momentum those of the director form (:mod:`director_model.invariants`).
"""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback
from references.engines.integrators import Integrator
from references.engines.interface import Engine
from references.errors import EngineError, EngineUnavailable, StepFailure, Unsupported

#: dynamics (torque) evaluations per step of each scheme: one per RATTLE sub-step (Yoshida's
#: composition has 3, Kahan and Li's 9)
_EVALS = {"rattle": 1.0, "rattle4": 3.0, "rattle6": 9.0, "energy_momentum": 1.0}

#: what each scheme promises beyond its family: RATTLE and its compositions conserve the
#: angular momentum to round-off (docs/numerics.md section 3); 1e-10 of the momentum scale is
#: round-off over ~1e5 steps with margin. The energy-momentum scheme conserves momentum in
#: director form, but its director velocities leave the tangent space at O(h^2), which the
#: suite's momentum (from W) sees, so it promises nothing more here.
_PROMISES = {
    "rattle": {"momentum_drift_max": 1e-10},
    "rattle4": {"momentum_drift_max": 1e-10},
    "rattle6": {"momentum_drift_max": 1e-10},
}


def _dm():
    try:
        import director_model
    except ImportError as exc:  # pragma: no cover - director_model ships with the suite
        raise EngineUnavailable(f"director_model does not import: {exc}") from exc
    return director_model


def _integrators() -> tuple[Integrator, ...]:
    dm = _dm()
    return tuple(
        Integrator(
            name=name,
            family="structure-preserving director",
            order=int(scheme.order),
            description=(scheme.__doc__ or "").strip().splitlines()[0],
            evals_per_step=_EVALS.get(name),
            tolerances=_PROMISES.get(name, {}),
            # two halvings below a scenario's smallest swept step for the compositions of
            # order 4 and 6: milliseconds of stepping, and rattle6 then reaches 1e-10 rad on
            # the library's fast tops (cone_top, heavy_top, simo_wong_top)
            sweep_halvings=2 if scheme.order >= 4 else 0,
        )
        for name, scheme in dm.SCHEMES.items()
    )


class DirectorEngine(Engine):
    """The director formulation integrated by director_model's compiled schemes."""

    name = "director"
    warm_up = "the director kernels (numba)"
    description = "director_model: RATTLE, energy-momentum and compositions in director form"
    integrators = _integrators()

    @classmethod
    def version(cls) -> str:
        _dm()
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("director-bench")
        except PackageNotFoundError:  # a source tree that was never installed
            return "0+unknown"

    # -- model -------------------------------------------------------------------------
    def build(self, ctx) -> None:
        dm = _dm()
        mdl = ctx.model
        if not mdl.pivoted and np.any(mdl.com != 0.0):
            # the director model places a free body's centre of mass at its body-frame origin
            raise EngineError(
                f"director_model: a free body's centre of mass is its body-frame origin; a "
                f"model with the centre of mass at {mdl.com.tolist()} cannot be built"
            )
        pivot = -mdl.com if mdl.pivoted else None
        try:
            body = dm.Body.make(mdl.mass, mdl.inertia, pivot)
        except dm.InvalidBodyError as exc:
            raise Unsupported(f"director_model refuses the body: {exc}") from exc
        ctx.handle = _Handle(dm, body)

    def read_model(self, ctx) -> ModelReadback:
        body = ctx.handle.body
        com = -body.pivot if body.pivoted else np.zeros(3)
        return ModelReadback(
            mass=body.mass,
            inertia=np.diag(body.inertia),  # the moments the Body holds (its J follow from them)
            com=com,
            joint="ball" if body.pivoted else "free",
            gravity=ctx.model.gravity,
            dt=ctx.dt,
        )

    def settings(self, ctx) -> dict:
        return {
            "scheme": ctx.integrator.name,
            "gravity": ctx.model.gravity.tolist(),
            "sums": "compensated (Kahan) in the attitude quaternion and momentum updates",
        }

    # -- state -------------------------------------------------------------------------
    def set_state(self, ctx, state) -> None:
        """Start the scheme from ``state``: a new director_model.Stepper, whose own state
        (directors, momentum, compensations) is then kept between blocks of steps."""
        h = ctx.handle
        x, v, R, W = (np.array(a, dtype=float) for a in state)
        kw = {} if h.body.pivoted else {"position": x, "velocity": v}
        h.stepper = h.dm.Stepper(
            h.body.mass,
            ctx.model.inertia,
            rotation=R,
            omega_body=W,
            gravity=ctx.model.gravity,
            pivot=h.body.pivot,
            scheme=ctx.integrator.name,
            dt=ctx.dt,
            **kw,
        )

    def read_state(self, ctx) -> cv.BodyState:
        return cv.BodyState(*ctx.handle.stepper.state())

    def native_quantities(self, ctx) -> dict:
        """Energy and angular momentum in director form (director_model.invariants) from the
        stepper's directors D and their velocities D' = D hat(W)."""
        h = ctx.handle
        dm, body = h.dm, h.body
        x, v, D, W = h.stepper.state()
        Dp = dm.director_velocity(D, W)
        g = ctx.model.gravity
        L = dm.invariants.angular_momentum(body.mass, body.Jbar, body.pivoted, x, v, D, Dp)
        if not body.pivoted:
            L = L - body.mass * np.cross(x, v)  # the suite's L is about the centre of mass
        E = dm.invariants.energy(body.mass, body.Jbar, body.pivoted, g, x, v, Dp)
        return {"energy": float(E), "angular momentum": L, "rotation": D}

    # -- stepping ----------------------------------------------------------------------
    def advance(self, ctx, k: int) -> None:
        self.advance_saving(ctx, [k])

    def advance_saving(self, ctx, steps: list[int]) -> cv.BodyState:
        """One compiled run for a block of equally spaced checkpoints (else one per
        checkpoint), saving the state at each, with the velocity-constraint residual of the
        scheme's own director velocities (ctx.residuals)."""
        if len(set(steps)) == 1:
            return self._chunk(ctx, steps[0], len(steps))
        parts = [self._chunk(ctx, k, 1) for k in steps]
        return cv.BodyState(*(np.concatenate(p) for p in zip(*parts, strict=True)))

    def _chunk(self, ctx, every: int, count: int) -> cv.BodyState:
        h = ctx.handle
        start = h.stepper.nstep_done
        try:
            tr = h.stepper.advance(every * count, save_every=every)
        except h.dm.StepSizeError as exc:
            err = StepFailure(str(exc))
            err.time = float(exc.time)
            raise err from exc
        ctx.clock.elapsed += float(tr.wall_time_s)
        A = np.einsum("nki,nkj->nij", tr.rotation, tr.director_velocity)
        res = np.linalg.norm(A + np.swapaxes(A, 1, 2), axis=(1, 2))
        steps = start + every * np.arange(1, len(tr.t) + 1)
        ctx.residuals.update(zip(steps.tolist(), res.tolist(), strict=True))
        return cv.BodyState(tr.position, tr.velocity, tr.rotation, tr.omega_body)


class _Handle:
    def __init__(self, dm, body):
        self.dm, self.body = dm, body
        self.stepper = None
