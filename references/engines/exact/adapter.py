"""The scenario's reference solution (closed form or high-accuracy numerical) presented as an
engine, so that it appears in every table and plot beside the others: its energy and momentum
drifts are the round-off floor of the measurement."""

from __future__ import annotations

from references.engines.context import RunOutput
from references.engines.integrators import Integrator
from references.engines.interface import EngineBase, SceneBuilder
from references.engines.stepping import step_plan
from references.engines.timing import Timing


class ExactEngine(EngineBase):
    """The scenario's reference: closed form where one exists, else a tight DOP853 solution."""

    name = "exact"
    is_reference = True
    description = "closed-form solutions (Jacobi elliptic, Lagrange top) or DOP853 at rtol 1e-13"
    scene_builder = SceneBuilder(
        "references.engines.exact.system:simulate_system", force_elements=True
    )
    integrators = (
        Integrator(
            name="reference",
            family="exact",
            order=0,
            description="the scenario's reference solution, evaluated at the saved times",
            evals_per_step=None,
        ),
    )

    @classmethod
    def version(cls) -> str:
        from references.engines.director.adapter import DirectorEngine

        return DirectorEngine.version()

    @classmethod
    def installed_version(cls) -> str | None:
        from references.engines.director.adapter import DirectorEngine

        return DirectorEngine.installed_version()

    def run(
        self,
        scenario,
        integrator,
        dt,
        t_end=None,
        save_every=None,
        progress=None,
        recorder=None,
        accuracy=None,
    ) -> RunOutput:
        from references.exact import reference_kept

        self.integrator(integrator)
        t_end = scenario.t_end if t_end is None else t_end
        save_every = scenario.save_every if save_every is None else save_every
        nstep, saves = step_plan(dt, t_end, save_every)
        # its cost: what computing the reference took, on the calling thread's CPU clock as
        # every engine's (references.engines.timing), whether this run computed it or read
        # it from the reference cache (references.cache), where it is kept with it
        ref, kept = reference_kept(scenario, saves * dt)
        wall, cpu = kept["wall_s"], kept["cpu_s"]
        settings = {
            "reference kind": ref.kind,
            "accuracy": ref.accuracy,
            "method": ref.method,
            "reason": getattr(ref, "reason", ""),
        }
        if progress is not None:
            progress(1.0)
        # one computation: its CPU time read around it is its cost
        timing = Timing(cpu, 0.0, cpu, wall, wall)
        return RunOutput(ref, nstep, wall, wall, 0.0, settings, cpu_time_s=cpu, timing=timing)
