"""Ensembles: one scenario over many initial conditions, with distributions of the metrics.

The members keep the scenario's body, initial attitude and kinetic energy of rotation and draw
the direction of the body angular velocity uniformly on the sphere (seeded, so an ensemble is
reproducible): ``W_k = s_k u_k`` with ``u_k`` uniform on S^2 and ``s_k`` chosen so that
``1/2 W_k . I W_k`` equals the scenario's rotational kinetic energy. Such members cross every
regime of the free body: rotations about the major and minor axes and near-separatrix tumbling.

director_model runs all members in one call of its batched path; every other engine runs each
member through its adapter (distributable like any sweep). Metrics are the suite's, member by
member, against each member's own reference. Output: ``ensemble.csv`` in the output folder,
one row per member and configuration.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from reports.metrics import compute_metrics
from reports.runner import RESULT_COLUMNS, RunSpec, execute, expected_for, reference_for

ENSEMBLE_COLUMNS = ("member", *RESULT_COLUMNS)


def members(scenario, n: int, seed: int = 0) -> list:
    """``n`` variants of ``scenario`` with random directions of W at the scenario's rotational
    kinetic energy. Member k is named ``<name>#k``."""
    if n < 1:
        raise ValueError(f"ensemble size n = {n}: must be >= 1")
    I = np.asarray(scenario.inertia)
    W0 = np.asarray(scenario.omega_body)
    T_rot = 0.5 * W0 @ (I * W0)
    if T_rot == 0:
        raise ValueError(f"scenario {scenario.name!r}: W = 0, no rotational energy to keep")
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    s = np.sqrt(2 * T_rot / np.einsum("ni,i,ni->n", u, I, u))
    return [
        scenario.replace(name=f"{scenario.name}#{k}", omega_body=s[k] * u[k], dt_sweep=())
        for k in range(n)
    ]


def _director_batch(base, mems, scheme, dt, t_end) -> list[dict]:
    """All members in one call of director_model's batched path; rows per member."""
    import director_model as dm
    from references.trajectory import Trajectory

    rows = []
    R = np.stack([m.rotation for m in mems])
    W = np.stack([m.omega_body for m in mems])
    kwargs = {}
    if base.pivot is None:
        kwargs = dict(
            position=np.stack([m.position for m in mems]),
            velocity=np.stack([m.velocity for m in mems]),
        )
    t0 = time.perf_counter()
    try:
        out = dm.simulate_batch(
            base.mass,
            base.inertia,
            rotation=R,
            omega_body=W,
            gravity=base.gravity,
            pivot=base.pivot,
            scheme=scheme,
            dt=dt,
            t_end=t_end,
            save_every=base.save_every,
            **kwargs,
        )
    except dm.StepSizeError as exc:
        # The batch stops at its first member that cannot be stepped: record the message
        # for every member rather than guess which ones would have succeeded.
        for k, m in enumerate(mems):
            row = _row(m, "director", scheme, dt, t_end, k)
            row.update(status="failed", message=str(exc))
            rows.append(row)
        return rows
    wall = float(getattr(out, "wall_time_s", time.perf_counter() - t0))
    nbody = len(mems)
    for k, m in enumerate(mems):
        traj = Trajectory.from_states(
            m, out.t, out.position[k], out.velocity[k], out.rotation[k], out.omega_body[k]
        )
        row = _row(m, "director", scheme, dt, t_end, k)
        row.update(compute_metrics(m, traj, reference_for(m, traj.t), expected_for(m)))
        row.update(
            status="ok",
            nstep=int(out.nstep),
            wall_time_s=wall / nbody,
            ns_per_step=1e9 * wall / nbody / max(int(out.nstep), 1),
        )
        rows.append(row)
    return rows


def _row(member, engine, integrator, dt, t_end, k) -> dict:
    from references.engines import get_engine

    row = dict.fromkeys(ENSEMBLE_COLUMNS, "")
    cls = get_engine(engine)
    integ = cls.integrator(integrator)
    row.update(
        member=k,
        scenario=member.name.split("#")[0],
        scenario_hash=member.scenario_hash,
        engine=engine,
        engine_version=cls.version(),
        integrator=integrator,
        family=integ.family,
        order=integ.order,
        dt=dt,
        t_end=t_end,
    )
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
    """Run ``n`` members of ``scenario`` on every engine/integrator; write ``ensemble.csv``.

    Returns the DataFrame of rows (member x configuration)."""
    import pandas as pd

    from references.engines import engine_names, get_engine

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    dt = scenario.dt if dt is None else float(dt)
    t_end = scenario.t_end if t_end is None else float(t_end)
    mems = members(scenario, n, seed)
    rows = []
    specs = []
    for name in engines or engine_names():
        if name == "exact":
            continue
        cls = get_engine(name)
        names = [i.name for i in cls.integrators if not integrators or i.name in integrators]
        if name == "director" and cls.availability() is None:
            for scheme in names:
                rows += _director_batch(scenario, mems, scheme, dt, t_end)
            continue
        for integ in names:
            specs += [(k, RunSpec(m, name, integ, dt, t_end)) for k, m in enumerate(mems)]

    bar = None
    if progress and specs:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(specs), unit="run", desc=f"ensemble {scenario.name}")
    todo = [s for _, s in specs]
    for row in (mapper or map)(execute, todo):
        # members are named "<scenario>#<k>"
        name, _, k = row["scenario"].rpartition("#")
        row["member"] = int(k)
        row["scenario"] = name
        rows.append(row)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    df = pd.DataFrame(rows, columns=list(ENSEMBLE_COLUMNS))
    df = df.sort_values(["engine", "integrator", "member"], ignore_index=True)
    df.to_csv(out / "ensemble.csv", index=False)
    return df


def summary(df, metrics=("attitude_error_max", "energy_drift_max", "momentum_drift_max")):
    """Median, 90th percentile and maximum of each metric per configuration, and how many
    members completed."""
    rows = []
    for (sc, eng, integ, dt), g in df.groupby(["scenario", "engine", "integrator", "dt"]):
        ok = g[g["status"] == "ok"]
        r = {
            "scenario": sc,
            "engine": eng,
            "integrator": integ,
            "dt": dt,
            "members": f"{len(ok)}/{len(g)}",
        }
        for m in metrics:
            v = ok[m].astype(float).to_numpy()
            v = v[np.isfinite(v)]
            r[f"{m} median"] = float(np.median(v)) if v.size else math.nan
            r[f"{m} p90"] = float(np.quantile(v, 0.9)) if v.size else math.nan
            r[f"{m} max"] = float(v.max()) if v.size else math.nan
        rows.append(r)
    return rows
