"""Adapter for the suite's own integrator, :mod:`director_model` (each scheme an integrator).

The director model is an engine like the others here: the model is its :class:`Body`
(convected moments J, pivot inertia), its state the directors D and their velocities D', its
own energy and momentum those of the director form (:mod:`director_model.invariants`).
"""

from __future__ import annotations

import numpy as np

from references import conventions as cv
from references.engines.context import ModelReadback, RunOutput
from references.engines.integrators import Integrator
from references.engines.interface import Engine, LazyIntegrators, SceneBuilder, installed
from references.engines.stepping import check_batch_members
from references.errors import EngineError, EngineUnavailable, StepFailure, Unsupported

#: what a composition of RATTLE steps (a scheme stepped by RATTLE's kernel method) promises beyond
#: its family: it conserves the angular momentum to round-off step by step (docs/numerics.md
#: section 3); 1e-10 of the momentum scale is round-off over ~1e5 steps with margin. The
#: energy-momentum scheme conserves momentum in director form, but its director velocities
#: leave the tangent space at O(h^2), which the suite's momentum (from W) sees, so it promises
#: nothing more here.
RATTLE_PROMISES = {"momentum_drift_max": 1e-10}


def _evals_per_step(scheme) -> float:
    """Dynamics (torque) evaluations per step of a director_model scheme, from its declaration:
    one per RATTLE sub-step, a step being ``len(coefficients)`` of them (Yoshida's composition
    3, Kahan and Li's 9); the energy-momentum step (one coefficient) evaluates the torque once."""
    return float(len(scheme.coefficients))


def _promises(dm, scheme) -> dict:
    """The verdict bounds a scheme promises beyond its family (:data:`RATTLE_PROMISES`)."""
    return dict(RATTLE_PROMISES) if scheme.method == dm.schemes.Rattle.method else {}


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
            evals_per_step=_evals_per_step(scheme),
            tolerances=_promises(dm, scheme),
        )
        for name, scheme in dm.SCHEMES.items()
    )


class DirectorEngine(Engine):
    """The director formulation integrated by director_model's compiled schemes."""

    name = "director"
    batched = True
    warm_up = "the director kernels (numba)"
    #: a system of bodies runs director_model.system's kernels, compiled apart from the
    #: single body's (reports.run.runner.warm_up)
    system_warm_up = "the system kernels (numba)"
    #: a contact scene runs director_model.contact's kernels, compiled apart from both
    contact_warm_up = "the contact kernels (numba)"
    description = "director_model: RATTLE, energy-momentum and compositions in director form"
    scene_builder = SceneBuilder(
        "references.engines.director.system:simulate_system", ("solver",), force_elements=True
    )
    #: made from director_model's schemes when first asked for (its import is the slow part
    #: of importing this adapter)
    integrators = LazyIntegrators(_integrators)

    @classmethod
    def version(cls) -> str:
        _dm()
        # "0+unknown": a source tree that was never installed
        return installed("director-bench") or "0+unknown"

    @classmethod
    def installed_version(cls) -> str | None:
        return installed("director-bench")  # director_model ships in the suite's package

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
        watch = ctx.clock
        if not watch.running:  # a chunk after another in one block (stepped paused it)
            watch.resume()
        try:
            # the stepping ends with the compiled call: the invariants director_model then
            # computes from the saved states, and the residuals below, are checks of the
            # states (as the runner's own, outside the stepping), not the step's cost
            tr = h.stepper.advance(every * count, save_every=every, stepped=watch.pause)
        except h.dm.StepSizeError as exc:
            raise StepFailure(str(exc), time=float(exc.time)) from exc
        ctx.clock.add(float(tr.wall_time_s), float(tr.cpu_time_s))  # the kernel's own
        A = np.einsum("nki,nkj->nij", tr.rotation, tr.director_velocity)
        res = np.linalg.norm(A + np.swapaxes(A, 1, 2), axis=(1, 2))
        steps = start + every * np.arange(1, len(tr.t) + 1)
        ctx.residuals.update(zip(steps.tolist(), res.tolist(), strict=True))
        return cv.BodyState(tr.position, tr.velocity, tr.rotation, tr.omega_body)

    # -- batches -----------------------------------------------------------------------
    def run_batch(self, members, integrator, dt, t_end, save_every) -> list:
        """All members in one call of director_model's batched path (``simulate_batch``, in
        parallel over bodies, each member bit for bit its own single run), times the batch's
        divided by the number of members. A member that cannot be stepped stops the whole
        call (director_model names the first), so that refusal is the batch's
        (:class:`EngineError`); a body director_model refuses is :class:`Unsupported`."""
        from references.trajectory import Trajectory

        dm = _dm()
        integ = self.integrator(integrator)
        check_batch_members(self.name, members)
        base = members[0]
        kwargs = {}
        if base.pivot is None:
            kwargs = dict(
                position=np.stack([m.position for m in members]),
                velocity=np.stack([m.velocity for m in members]),
            )
        try:
            out = dm.simulate_batch(
                base.mass,
                base.inertia,
                rotation=np.stack([m.rotation for m in members]),
                omega_body=np.stack([m.omega_body for m in members]),
                gravity=base.gravity,
                pivot=base.pivot,
                scheme=integ.name,
                dt=dt,
                t_end=t_end,
                save_every=save_every,
                **kwargs,
            )
        except dm.InvalidBodyError as exc:
            raise Unsupported(f"director_model refuses the body: {exc}") from exc
        except dm.StepSizeError as exc:
            raise EngineError(str(exc)) from exc
        wall = float(out.wall_time_s) / len(members)
        return [
            RunOutput(
                Trajectory.from_states(
                    m, out.t, out.position[k], out.velocity[k], out.rotation[k], out.omega_body[k]
                ),
                int(out.nstep),
                wall,
                wall,
                integ.evals_per_step or 0.0,
            )
            for k, m in enumerate(members)
        ]


class _Handle:
    def __init__(self, dm, body):
        self.dm, self.body = dm, body
        self.stepper = None
