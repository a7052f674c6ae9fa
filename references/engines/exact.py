"""Adapter presenting the scenario's reference solution (closed form or high-accuracy
numerical) as an engine, so it appears in every table and plot beside the others."""

from __future__ import annotations

import time

from references.engines.base import Engine, Integrator, RunOutput


class ExactEngine(Engine):
    """The scenario's reference: closed form where one exists, else a tight DOP853 solution."""

    name = "exact"
    description = "closed-form solutions (Jacobi elliptic, Lagrange top) or DOP853 at rtol 1e-13"
    integrators = (
        Integrator(
            name="reference",
            family="exact",
            order=0,
            description="the scenario's reference solution, evaluated at the saved times",
        ),
    )

    @classmethod
    def version(cls) -> str:
        from references.engines.director import DirectorEngine

        return DirectorEngine.version()

    def _run(self, scenario, integrator, dt, nstep, saves, progress) -> RunOutput:
        from references.exact import reference_trajectory

        t = saves * dt
        t0 = time.perf_counter()
        ref = reference_trajectory(scenario, t)
        wall = time.perf_counter() - t0
        settings = {"reference kind": ref.kind, "accuracy": ref.accuracy, "method": ref.method}
        return RunOutput(ref, nstep, wall, settings)
