"""Long horizons with streaming metrics: the running maxima over every step equal the metrics of
one run that saves every step (the engine runs once, without restarts: the same discrete
trajectory), while only every save_every-th state is kept."""

import numpy as np
import pytest

import scenarios
from reports.cli import main
from reports.metrics.catalog import STREAMED
from reports.run.runner import execute
from reports.store.results import read_results
from reports.store.runs import RunSpec

#: every metric the recorder streams: the catalog's pointwise single-body metrics
POINTWISE = list(STREAMED)


@pytest.fixture(scope="module")
def dzh():
    return scenarios.load("dzhanibekov").replace(t_end=2.0, dt_sweep=(), save_every=1)


@pytest.mark.parametrize(
    "engine, integrator",
    [("mujoco", "Euler"), ("director", "rattle4"), ("pybullet", "multibody"), ("dart", "RKMK4")],
)
def test_segmented_maxima_equal_every_step_metrics(dzh, engine, integrator):
    full = execute(RunSpec(dzh, engine, integrator, 1e-3))  # saves all 2001 states
    seg = execute(RunSpec(dzh, engine, integrator, 1e-3, save_every=100, segment=300))
    assert full["status"] == seg["status"] == "ok", (full["message"], seg["message"])
    assert seg["nstep"] == full["nstep"] == 2000
    for c in POINTWISE:
        # the same states; the reference is evaluated on other time grids (chunks of 300
        # against one grid), which moves its last digits: 1e-13 relative, 1e-15 absolute
        assert seg[c] == pytest.approx(full[c], rel=1e-13, abs=1e-15), c


def test_energy_parts_of_a_pivoted_body_stay_empty_when_streamed():
    """A pivoted body has only the total energy: the streamed parts are NaN as the saved
    ones are, not 0 (a maximum over nothing) nor inf."""
    top = scenarios.load("heavy_top").replace(t_end=0.2, dt_sweep=(), save_every=1)
    full = execute(RunSpec(top, "director", "rattle4", 1e-3))
    seg = execute(RunSpec(top, "director", "rattle4", 1e-3, save_every=50, segment=60))
    for row in (full, seg):
        assert row["status"] == "ok", row["message"]
        assert np.isnan(row["energy_drift_rot_max"]) and np.isnan(row["energy_drift_trans_max"])
    assert seg["energy_drift_max"] == pytest.approx(full["energy_drift_max"], rel=1e-13)


def test_kept_samples_and_file(tmp_path, dzh):
    row = execute(
        RunSpec(dzh, "director", "rattle", 1e-3, save_every=100, segment=300), out=tmp_path
    )
    from references.trajectory import Trajectory

    tr = Trajectory.read(tmp_path / row["trajectory"])
    np.testing.assert_allclose(tr.t, np.arange(21) * 0.1, atol=1e-12)


def test_cli_segment_option(tmp_path):
    out = tmp_path / "o"
    assert (
        main(
            [
                "run",
                "major_axis_spin",
                "--engines",
                "director",
                "--integrators",
                "rattle",
                "--t-end",
                "2",
                "--no-sweep",
                "--save-every",
                "100",
                "--segment",
                "500",
                "--out",
                str(out),
                "--quiet",
                "--jobs",
                "1",
                "--no-report",
            ]
        )
        == 0
    )
    df = read_results(out)
    assert list(df["status"]) == ["ok"] and df["segment"].iloc[0] == 500
