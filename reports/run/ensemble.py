"""Ensembles: one scenario over many initial conditions, with distributions of the metrics.

The members keep the scenario's body, initial attitude and kinetic energy of rotation and draw
the direction of the body angular velocity uniformly on the sphere (seeded, so an ensemble is
reproducible): ``W_k = s_k u_k`` with ``u_k`` uniform on S^2 and ``s_k`` chosen so that
``1/2 W_k . I W_k`` equals the scenario's rotational kinetic energy. Such members cross every
regime of the free body: rotations about the major and minor axes and near-separatrix tumbling.

An engine that steps many bodies together (``batched``: director_model in one call of its
batched path, MJX in one vmapped, compiled call) runs all members of a configuration through its
``run_batch``; every other engine runs each member through its adapter (distributable like any
sweep). Metrics, statuses and verdicts are
the suite's, member by member, against each member's own reference. Output: the ensemble
store ``ensemble.sqlite`` in the output folder (the same transactional store as the results,
reports.store.results), exported as ``ensemble.csv``, one row per member and configuration.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reports.run.runner import execute
from reports.store.ensemble import ENSEMBLE_STORE, ensemble_frame
from reports.store.runs import RunSpec
from scenarios.schema import InputError


def members(scenario, n: int, seed: int = 0) -> list:
    """``n`` variants of ``scenario`` with random directions of W at the scenario's rotational
    kinetic energy. Member k is named ``<name>#k``."""
    if n < 1:
        raise InputError(f"ensemble size n = {n}: must be >= 1")
    I = np.asarray(scenario.inertia)
    W0 = np.asarray(scenario.omega_body)
    T_rot = 0.5 * W0 @ (I * W0)
    if T_rot == 0:
        raise InputError(f"scenario {scenario.name!r}: W = 0, no rotational energy to keep")
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    s = np.sqrt(2 * T_rot / np.einsum("ni,i,ni->n", u, I, u))
    return [
        scenario.replace(name=f"{scenario.name}#{k}", omega_body=s[k] * u[k], dt_sweep=())
        for k in range(n)
    ]


def check_ensemble(scenario, n: int, dt: float, t_end: float, jobs: int | None = None) -> None:
    """Every input of an ensemble, checked before anything runs or is written
    (:class:`~scenarios.schema.InputError` naming the value and the rule): the size, the step
    (a whole number of steps, at most 2^53), the magnitudes over the horizon, and memory by
    run's rule (:func:`reports.run.plan.max_states`), here for the ``n`` members a batched
    engine (director_model, MJX) holds at once in one process."""
    import os

    from references.engines import step_plan
    from reports.run.plan import BYTES_PER_STATE, max_states
    from scenarios.schema import magnitude_problems, step_count_problem

    members(scenario, 1)  # the size and the rotational energy the members keep
    if n < 1:
        raise InputError(f"ensemble size n = {n}: must be >= 1")
    problem = step_count_problem(t_end, dt)
    problems = [problem] if problem else []
    problems += [f"{f} = {v:.3g}: {rule}" for f, v, rule in magnitude_problems(scenario, t_end)]
    if not problems:
        try:
            nstep, _ = step_plan(dt, t_end, scenario.save_every)
        except ValueError as exc:
            problems.append(str(exc))
    if problems:
        raise InputError(f"ensemble of {scenario.name!r}: {problems[0]}")
    kept = n * (nstep // scenario.save_every + 2)
    limit = min(max_states(1), n * max_states(jobs or os.cpu_count() or 1))
    if kept > limit:
        raise InputError(
            f"ensemble of {n} members of {scenario.name!r} at dt = {dt:g} s to t_end = "
            f"{t_end:g} s keeps {kept:.3g} states at once (~{kept * BYTES_PER_STATE / 2**30:.3g} "
            f"GiB), more than a quarter of this machine's memory "
            f"({limit * BYTES_PER_STATE / 2**30:.3g} GiB): fewer members (--n), a shorter "
            "horizon (--t-end) or a larger step (--dt)"
        )


def _batch(cls, specs) -> list[dict]:
    """All members of one configuration in one call of the engine's ``run_batch`` (an engine
    that steps many bodies together, ``batched``: director_model's batched path, MJX's
    vmapped, compiled call); the rows are built like every other run's (reports.run.runner),
    a diverged member's from its output up to the divergence."""
    from references.engines import Diverged, EngineError, Unsupported
    from reports.metrics.verdicts import judge
    from reports.run.body import _measure

    spec0 = specs[0]
    integ = cls.integrator(spec0.integrator)
    rows = [_start_row(sp, integ) for sp in specs]
    mems = [sp.scenario for sp in specs]
    try:
        results = cls().run_batch(mems, spec0.integrator, spec0.dt, spec0.horizon, spec0.saving)
    except EngineError as exc:
        # the model, an initial state or the configuration was refused for the whole batch
        why = str(exc) if isinstance(exc, Unsupported) else f"the batched run stopped: {exc}"
        for row in rows:
            row.update(status=exc.status, message=why)
        return rows
    for m, sp, row, res in zip(mems, specs, rows, results, strict=True):
        diverged = res if isinstance(res, Diverged) else None
        output = res.output if diverged else res
        if isinstance(res, EngineError) and output is None:
            row.update(status=res.status, message=str(res))
            continue
        _measure(row, sp, m, output, None, None, "parquet")
        judge(row, m, integ, diverged)
    return rows


def _start_row(spec, integ) -> dict:
    from reports.store.runs import blank_row, finish_time

    row = blank_row(spec)
    row.update(family=integ.family, order=integ.order, suite_integrated=integ.suite_integrated)
    row["finished_at"] = finish_time()
    return row


def run_ensemble(
    scenario,
    n: int,
    out,
    *,
    seed: int = 0,
    engines=None,
    integrators=None,
    dt: float | None = None,
    t_end: float | None = None,
    mapper=None,
    progress: bool = True,
):
    """Run ``n`` members of ``scenario`` on every engine/integrator into the output folder's
    ensemble store (``ensemble.sqlite``, exported as ``ensemble.csv``); members already in it
    are skipped. Returns the DataFrame of rows (member x configuration)."""
    from references.engines import engine_names, get_engine
    from reports.run.parallel import log_dir, working_directory
    from reports.store.results import Store

    out = Path(out).resolve()
    dt = scenario.dt if dt is None else float(dt)
    t_end = scenario.t_end if t_end is None else float(t_end)
    check_ensemble(scenario, n, dt, t_end)
    mems = members(scenario, n, seed)
    # engines write their logs (MUJOCO_LOG.TXT) into the working directory: out/logs
    with Store(out, create=True, name=ENSEMBLE_STORE) as store, working_directory(log_dir(out)):
        done = store.done_ids()
        specs = []
        for name in engines or engine_names():
            cls = get_engine(name)
            if cls.is_reference:
                continue
            why = cls.availability()
            version = cls.version() if why is None else "unavailable"
            for integ in cls.integrators:
                if integrators and integ.name not in integrators:
                    continue
                group = [
                    RunSpec(m, name, integ.name, dt, t_end, engine_version=version) for m in mems
                ]
                group = [sp for sp in group if sp.run_id not in done]
                if cls.batched and why is None and group:
                    for row in _batch(cls, group):
                        store.put(row)
                else:
                    specs += group
        from reports.run.progress import Progress

        bar = Progress(len(specs), desc=f"ensemble {scenario.name}", disable=not progress)
        try:
            for row in (mapper or _serial)(execute, specs):
                store.put(row)
                bar.update(1)
        finally:
            bar.close()
        df = ensemble_frame(store.rows())
    df.to_csv(out / "ensemble.csv", index=False)
    return df


def _serial(fn, specs):
    return map(fn, specs)
