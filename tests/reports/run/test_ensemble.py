"""Ensembles: members at the scenario's rotational energy, director members through the
batched path giving the same metrics as single runs, every engine's members as rows."""

import numpy as np
import pytest

import scenarios
from reports.run.ensemble import members, run_ensemble
from reports.run.runner import RunSpec, execute
from reports.store.ensemble import summary


@pytest.fixture(scope="module")
def dzh():
    return scenarios.load("dzhanibekov").replace(t_end=1.0)


def test_members_keep_rotational_energy_and_are_seeded(dzh):
    I, W0 = dzh.inertia, dzh.omega_body
    T0 = 0.5 * W0 @ (I * W0)  # 6.0003 for docs/numerics.md's Dzhanibekov body
    assert T0 == pytest.approx(6.0003, rel=1e-15)
    ms = members(dzh, 50, seed=3)
    T = [0.5 * m.omega_body @ (I * m.omega_body) for m in ms]
    np.testing.assert_allclose(T, T0, rtol=1e-14)
    dirs = np.array([m.omega_body / np.linalg.norm(m.omega_body) for m in ms])
    # uniform directions: the mean of 50 unit vectors is far from any pole (|mean| ~ 1/sqrt(50))
    assert np.linalg.norm(dirs.mean(axis=0)) < 0.5
    again = members(dzh, 50, seed=3)
    assert all(np.array_equal(a.omega_body, b.omega_body) for a, b in zip(ms, again, strict=True))
    assert not np.array_equal(members(dzh, 2, seed=4)[0].omega_body, ms[0].omega_body)


def test_bad_ensemble_size(dzh):
    with pytest.raises(ValueError, match="n = 0"):
        members(dzh, 0)


def test_batched_members_equal_single_runs(tmp_path, dzh):
    df = run_ensemble(
        dzh,
        4,
        tmp_path,
        engines=["director", "mujoco"],
        integrators=["rattle4", "RK4"],
        progress=False,
    )
    assert (tmp_path / "ensemble.csv").exists()
    assert len(df) == 8 and set(df["status"]) == {"ok"}
    cols = ["energy_drift_max", "momentum_drift_max", "attitude_error_max", "omega_error_max"]
    for k, m in enumerate(members(dzh, 4)):
        single = execute(RunSpec(m, "director", "rattle4", dzh.dt))
        row = df[(df["engine"] == "director") & (df["member"] == k)].iloc[0]
        # the batched path is bit-for-bit the single path (director_model's own test), so the
        # suite's metrics of both are identical
        for c in cols:
            assert row[c] == single[c], c
    (s_dir, s_mj) = summary(df)
    assert s_dir["members"] == "4/4" and s_mj["members"] == "4/4"
    # RK4 and the Yoshida composition at dt = 1e-3 over 1 s: both far below 1e-6 rad
    assert s_dir["attitude_error_max max"] < 1e-6 and s_mj["attitude_error_max max"] < 1e-6


def test_an_ensemble_in_a_fresh_folder_writes_its_report(tmp_path):
    """``director-bench ensemble`` into a new folder draws its figures into plots/, which
    nothing else made there: the report is written, with the two ensemble figures, instead
    of the run failing on 'plots/<figure>.png: No such file or directory'."""
    from reports.cli import main

    out = tmp_path / "ens"
    code = main(["ensemble", "dzhanibekov", "--n", "2", "--engines", "mujoco", "--integrators",
                 "rk4", "--t-end", "0.2", "--quiet", "--jobs", "1", "--out", str(out)])  # fmt: skip
    assert code == 0
    figures = sorted(p.name for p in (out / "plots").glob("*.png"))
    assert figures == [
        "dzhanibekov__ensemble_attitude-error-max.png",
        "dzhanibekov__ensemble_energy-drift-max.png",
    ]
    page = (out / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 2 and "ensemble of 2 initial" in page
