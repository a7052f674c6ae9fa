"""The ensemble store of an output folder: reading its rows back and their statistics per
configuration (written by :mod:`reports.run.ensemble`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from reports.store.results import Store, frame

#: the file of the ensemble store inside the output folder
ENSEMBLE_STORE = "ensemble.sqlite"


def ensemble_frame(rows):
    """Ensemble rows as a DataFrame with a ``member`` column (members are stored as
    scenarios named ``<scenario>#<k>``)."""
    df = frame(rows)
    parts = df["scenario"].str.rpartition("#")
    df.insert(0, "member", parts[2].astype(int) if len(df) else [])
    df["scenario"] = parts[0]
    return df.sort_values(["scenario", "engine", "integrator", "dt", "member"], ignore_index=True)


def read_ensemble(folder):
    """The ensemble rows of an output folder, or None if it has none."""
    if not (Path(folder) / ENSEMBLE_STORE).exists():
        return None
    with Store(folder, name=ENSEMBLE_STORE) as st:
        return ensemble_frame(st.rows())


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
