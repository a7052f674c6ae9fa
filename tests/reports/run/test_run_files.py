"""What a run keeps on disk (reports.run.files): by default the series the report draws for the
runs it draws, nothing for the others; in full on request. The results are the same bit for
bit either way (the metrics come from the full run, before anything is kept), and the figures
are drawn from what was kept."""

import math

import numpy as np
import pyarrow.parquet as pq
import pytest

from reports.cli import main
from reports.run.files import POSE, RATES, SERIES
from reports.store.results import read_results
from reports.store.runs import RESULT_COLUMNS, TIMING_COLUMNS

#: two steps of free_tumbling (the scenario's own, 1e-3 s, and 2e-3 s) on the director's RATTLE
#: and MuJoCo's RK4, over 0.2 s, and the exact reference at the smaller: 5 runs
RUN = ["run", "free_tumbling", "--engines", "exact,director,mujoco", "--integrators",
       "reference,rattle,rk4", "--dt", "1e-3,2e-3", "--t-end", "0.2", "--quiet",
       "--jobs", "1"]  # fmt: skip
TIMES = TIMING_COLUMNS | {"trajectory"}


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    base = tmp_path_factory.mktemp("files")
    assert main([*RUN, "--out", str(base / "default")]) == 0
    assert main([*RUN, "--out", str(base / "full"), "--trajectories", "full"]) == 0
    return base / "default", base / "full"


def test_the_default_keeps_the_drawn_runs_series_and_nothing_else(folders):
    default, _ = folders
    df = read_results(default)
    drawn = df[df["dt"] == 1e-3]
    assert set(df.loc[df["dt"] == 2e-3, "trajectory"]) == {""}  # not drawn: no file
    for _, r in drawn.iterrows():
        assert r["trajectory"].endswith(".series.parquet"), r["trajectory"]
        t = pq.read_table(default / r["trajectory"])
        pose = POSE if r["engine"] == "exact" else ()
        series = [c for c in SERIES if c in t.column_names]
        assert t.column_names == [*RATES, *pose, *series]
        assert {"energy_drift", "attitude_error"} <= set(series) or r["engine"] == "exact"
        assert t.schema.field("t").type == "double"
        assert all(t.schema.field(c).type == "float" for c in t.column_names if c != "t")
        meta = t.schema.metadata
        assert b"director_bench.kept" in meta and b"director_bench.run" in meta
        assert len(t) == 21  # every saved time: 0.2 s at 1e-3 s, one in 10 saved


def test_what_is_kept_changes_no_result(folders):
    default, full = folders
    a, b = read_results(default), read_results(full)
    cols = [c for c in RESULT_COLUMNS if c not in TIMES]
    assert len(a) == len(b) == 5
    for c in cols:
        for x, y in zip(a[c], b[c], strict=True):
            assert x == y or (isinstance(x, float) and math.isnan(x) and math.isnan(y)), c
    # the full folder keeps every run's whole trajectory, and the series file holds its
    # values to single precision
    for (_, ra), (_, rb) in zip(a.iterrows(), b.iterrows(), strict=True):
        tb = pq.read_table(full / rb["trajectory"])
        assert "R00" in tb.column_names and "energy" in tb.column_names
        if ra["trajectory"]:
            ta = pq.read_table(default / ra["trajectory"])
            for c in ta.column_names:
                x, y = ta.column(c).to_numpy(), tb.column(c).to_numpy()
                np.testing.assert_array_equal(x, y.astype(x.dtype), err_msg=c)


def test_the_figures_are_drawn_from_the_series(folders):
    default, full = folders
    for folder in folders:
        names = {p.name for p in (folder / "plots").glob("free-tumbling__*.png")}
        assert {"free-tumbling__errors.png", "free-tumbling__scenario.png"} <= names, names


def test_full_trajectories_asked_for_later_run_the_compact_runs_again(folders, tmp_path, capsys):
    import shutil

    default, _ = folders
    folder = tmp_path / "again"
    shutil.copytree(default, folder)
    assert main([*RUN, "--out", str(folder), "--trajectories", "full", "--no-report"]) == 0
    assert "5 runs executed, 0 already done" in capsys.readouterr().out
    df = read_results(folder)
    assert not any(t.endswith(".series.parquet") or not t for t in df["trajectory"])
    # and the default asked for again finds them done: more than it needs
    assert main([*RUN, "--out", str(folder), "--no-report"]) == 0
    assert "0 runs executed, 5 already done" in capsys.readouterr().out


def test_a_format_without_full_trajectories_is_refused(tmp_path, capsys):
    assert main([*RUN, "--out", str(tmp_path / "x"), "--format", "csv"]) == 2
    err = capsys.readouterr().err
    assert "--format csv" in err and "--trajectories full" in err
    assert not (tmp_path / "x").exists()
