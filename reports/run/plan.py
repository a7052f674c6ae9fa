"""The plan of a command's runs: scenarios x engines x integrators x step sizes (the
scenario's dt and its sweep, a target-accuracy sweep for error-controlled integrators, a robot
model's importer configurations) -> one :class:`~reports.store.runs.RunSpec` per run, every
input checked before anything runs (engines and integrators known, ``[tolerances]`` families
registered, horizons a whole number of steps, no run holding more saved states than memory
allows: :func:`max_states`). Planning never imports an engine: each adapter's version is read
from its package metadata where it says it
(:meth:`~references.engines.interface.EngineBase.planned_version`).
"""

from __future__ import annotations

from collections.abc import Sequence

from reports.metrics import verdicts
from reports.store.runs import RunSpec
from scenarios.schema import InputError, magnitude_problems, step_count_problem

#: target accuracies of error-controlled integrators when neither the command line nor the
#: scenario names any: one in the default suite, a sweep with --full
DEFAULT_ACCURACIES = (1e-8,)
FULL_ACCURACIES = (1e-6, 1e-8, 1e-10)


#: an error-controlled run is checked about this many times over its horizon (a checkpoint
#: is a point the integrator must stop at, so checkpoints every dt would make it a fixed-step
#: run at loose targets)
ADAPTIVE_CHECKPOINTS = 100


def plan(
    scenarios: Sequence,
    engines: Sequence[str] | None = None,
    integrators: Sequence[str] | None = None,
    dts: Sequence[float] | None = None,
    t_end: float | None = None,
    sweep: bool = True,
    save_every: int | None = None,
    segment: int | None = None,
    accuracies: Sequence[float] | None = None,
    max_states: int | None = None,
    full: bool = False,
) -> list[RunSpec]:
    """The specs of a suite: every scenario x engine x integrator x dt (x target accuracy,
    for error-controlled integrators: ``accuracies``, else the scenario's ``run.accuracies``,
    else :data:`DEFAULT_ACCURACIES` (:data:`FULL_ACCURACIES` with ``full``); they run at the
    scenario's own ``dt`` with about :data:`ADAPTIVE_CHECKPOINTS` checkpoints).

    ``dts`` None: each scenario's ``dt`` plus, with ``sweep``, its ``dt_sweep``: the same
    steps for every configuration.
    ``integrators`` None: each engine's default-suite integrators (every one with ``full``);
    else only those named (an engine offering none of them contributes nothing).
    ``save_every`` overrides the scenarios' decimation; ``segment`` streams the metrics over
    every step. Engines that are not installed still get specs, so that their absence is
    recorded as rows. Input that cannot run (a step that does not divide the horizon, a
    tolerance for an unknown family, more kept states than ``max_states``) is a ``ValueError``
    naming the scenario, before any run.
    """
    from references.engines import engine_names, get_engine, importers, step_plan
    from scenarios.models.configurations import split_variant

    engines = list(engines) if engines else engine_names()
    versions = {name: _version(get_engine(name)) for name in engines}
    specs = []
    for sc in scenarios:
        check_families(sc)
        steps = [float(h) for h in dts] if dts else [sc.dt, *(sc.dt_sweep if sweep else ())]
        steps = sorted(set(steps), reverse=True)
        horizon = sc.t_end if t_end is None else t_end
        keep = sc.save_every if save_every is None else save_every
        _check_input(sc, steps, horizon)
        for h in steps:
            _check_states(sc, h, horizon, keep, segment, max_states)
            try:
                step_plan(h, horizon, keep)
            except ValueError as exc:
                raise InputError(f"scenario {sc.name!r}: {exc}") from None
        for name in engines:
            offers = offered(name, sc)
            if integrators:
                names = [i.name for i in offers.values() if i.name in integrators]
            else:
                names = [i.name for i in offers.values() if full or i.default]
            if getattr(sc, "model", None) is not None:
                # a robot model also runs through the engine's importer: the configurations
                # of the integrators selected, or those asked for by name
                every = importers.variants(name, list(offers))
                names += [v for v in every if split_variant(v)[0] in names
                          or (integrators and v in integrators)]  # fmt: skip
            cls = get_engine(name)
            steps_e = [sc.dt if not dts else steps[-1]] if cls.is_reference else steps
            for integ in names:
                common = (t_end, save_every, segment, versions[name])
                if (offers.get(integ) or cls.integrator(integ)).adaptive:
                    accs = (
                        accuracies
                        or sc.accuracies
                        or (FULL_ACCURACIES if full else DEFAULT_ACCURACIES)
                    )
                    h = sc.dt if not dts else steps[-1]
                    every = save_every or max(keep, round(horizon / h) // ADAPTIVE_CHECKPOINTS)
                    common = (t_end, every, segment, versions[name])
                    specs += [RunSpec(sc, name, integ, h, *common, float(a)) for a in accs]
                else:  # every configuration of a scenario runs the same steps
                    specs += [RunSpec(sc, name, integ, h, *common) for h in steps_e]
    return specs


def offered(engine: str, sc) -> dict:
    """{name: Integrator} of what ``engine`` runs ``sc`` with: its integrators, or for a
    contact scene its contact configurations (:mod:`references.engines.contact`; an engine
    without a contact builder offers its first integrator, whose run then says that the
    engine has no contact builder)."""
    from references.engines import get_engine

    if sc.kind == "contact":
        from references.engines.contact import configurations

        confs = configurations(engine)
        if confs:
            return {c.name: c for c in confs}
        first = get_engine(engine).integrators[:1]
        return {i.name: i for i in first}
    return {i.name: i for i in get_engine(engine).integrators}


def check_families(sc) -> None:
    """Refuse a scenario whose [tolerances] name an integrator family no engine registers,
    naming the file and the known families (``plan`` and the CLI's ``show`` ask it)."""
    unknown = verdicts.unknown_families(sc)
    if unknown:
        from references.engines import FAMILIES

        raise InputError(
            f"scenario {sc.name!r} ({sc.path}): [tolerances] names unknown integrator "
            f"families {unknown}; known: {', '.join(FAMILIES)}"
        )


def _check_input(sc, steps: list[float], horizon: float) -> None:
    """The scenario's rules on step counts and magnitudes (scenarios.schema), applied again
    with the steps and horizon of the command line."""
    problems = [p for p in (step_count_problem(horizon, h) for h in steps) if p]
    problems += [f"{f} = {v:.3g}: {rule}" for f, v, rule in magnitude_problems(sc, horizon)]
    if problems:
        raise InputError(f"scenario {sc.name!r}: {problems[0]}")


#: bytes of memory a run needs per state it keeps (the trajectory, its reference and the
#: metric series; ~1.3 kB measured with tracemalloc on the library's scenarios, rounded up)
BYTES_PER_STATE = 2000


def max_states(jobs: int) -> int:
    """The most states one run may keep: a quarter of this machine's memory per worker."""
    import os

    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        total = 8 << 30
    return int(total / (4 * max(jobs, 1)) / BYTES_PER_STATE)


def _check_states(sc, dt, horizon, save_every, segment, max_states) -> None:
    """Refuse, before any run, a horizon whose kept states would not fit in memory."""
    if max_states is None:
        return
    # a system keeps every body's state: count them as states of one body
    kept = (round(horizon / dt) // save_every + 2 + (segment or 0)) * sc.n_bodies
    if kept > max_states:
        need = kept * BYTES_PER_STATE / 2**30
        have = max_states * BYTES_PER_STATE / 2**30
        raise InputError(
            f"scenario {sc.name!r} at dt = {dt:g} s to t_end = {horizon:g} s keeps {kept:.3g} "
            f"body states (~{need:.3g} GiB), more than a quarter of this machine's memory per "
            f"worker ({have:.3g} GiB): keep fewer with --save-every N (one state in N), and add "
            "--segment M to still measure every step (memory O(M))"
        )


#: the engine version of the specs of an engine that is not available where they are planned
UNAVAILABLE = "unavailable"


def _version(cls) -> str:
    """The version runs of ``cls`` are planned under (``planned_version``: its installed
    package's metadata, so that this process need not import every engine; each run's
    process checks it against the engine's own, :func:`_prepare`), or :data:`UNAVAILABLE`."""
    from references.engines import EngineUnavailable

    try:
        return cls.planned_version()
    except EngineUnavailable:
        return UNAVAILABLE
