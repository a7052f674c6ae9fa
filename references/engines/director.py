"""Adapter for the suite's own integrator, :mod:`director_model` (each scheme an integrator)."""

from __future__ import annotations

from references.engines.base import (
    Engine,
    EngineUnavailable,
    Integrator,
    RunOutput,
    StepFailure,
)
from references.trajectory import Trajectory


def _schemes():
    try:
        import director_model
    except ImportError as exc:  # pragma: no cover - director_model ships with the suite
        raise EngineUnavailable(f"director_model does not import: {exc}") from exc
    return director_model


def _integrators() -> tuple[Integrator, ...]:
    dm = _schemes()
    return tuple(
        Integrator(
            name=name,
            family="structure-preserving director",
            order=int(scheme.order),
            description=(scheme.__doc__ or "").strip().splitlines()[0],
        )
        for name, scheme in dm.SCHEMES.items()
    )


class DirectorEngine(Engine):
    """The director formulation integrated by director_model's compiled schemes."""

    name = "director"
    description = "director_model: RATTLE, energy-momentum and compositions in director form"
    integrators = _integrators()

    @classmethod
    def version(cls) -> str:
        from importlib.metadata import PackageNotFoundError, version

        _schemes()
        try:
            return version("director-bench")
        except PackageNotFoundError:  # running from a source tree
            from reports import __version__

            return __version__

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        dm = _schemes()
        save_every = int(saves[1] - saves[0]) if len(saves) > 1 else nstep
        kwargs = {}
        if scenario.pivot is None:
            kwargs = {"position": scenario.position, "velocity": scenario.velocity}
        try:
            out = dm.simulate(
                scenario.mass,
                scenario.inertia,
                rotation=scenario.rotation,
                omega_body=scenario.omega_body,
                gravity=scenario.gravity,
                pivot=scenario.pivot,
                scheme=integrator,
                dt=dt,
                t_end=nstep * dt,
                save_every=save_every,
                **kwargs,
            )
        except dm.StepSizeError as exc:
            raise StepFailure(str(exc)) from exc
        traj = Trajectory.from_states(
            scenario, out.t, out.position, out.velocity, out.rotation, out.omega_body
        )
        if progress is not None:
            progress(1.0)
        return RunOutput(traj, int(out.nstep), float(out.wall_time_s), settings={})
