"""The exports of the results store (results.csv, results.parquet): an export changed by hand
is named by every command that reads the folder, with the first cell that differs from the
store, and moved aside by the next run, never silently overwritten nor silently ignored."""

import csv

import pytest

import scenarios
from reports.cli import main
from reports.gate.check import write_baseline
from reports.run.runner import run_suite
from reports.store.exports import csv_text, edited
from reports.store.results import read_results
from reports.store.runs import RunSpec

RUN = ["free_tumbling", "--engines", "director", "--integrators", "rattle", "--dt", "1e-3",
       "--t-end", "0.01", "--no-sweep", "--quiet", "--jobs", "1"]  # fmt: skip


@pytest.fixture
def folder(tmp_path):
    sc = scenarios.load("free_tumbling").replace(t_end=0.01, dt_sweep=())
    run_suite([RunSpec(sc, "director", "rattle", 1e-3)], tmp_path / "res", progress=False)
    return tmp_path / "res"


def _edit_verdict(path, new: str) -> str:
    rows = list(csv.reader(path.open(newline="")))
    k = rows[0].index("verdict")
    old, rows[1][k] = rows[1][k], new
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    return old


def test_exports_as_written_are_not_edited(folder, capsys):
    assert edited(folder) == {}
    assert (folder / "results.csv").read_bytes() == csv_text(read_results(folder)).encode()
    assert (
        main(["check", str(folder), "--baseline", str(write_baseline(folder, folder / "b.json"))])
        == 0
    )
    assert "warning" not in capsys.readouterr().err


def test_an_edited_csv_is_named_by_every_reader_and_moved_aside_by_a_run(folder, capsys):
    old = _edit_verdict(folder / "results.csv", "fail")
    assert old == "pass"
    found = edited(folder)
    assert list(found) == ["results.csv"]
    run_id = read_results(folder)["run_id"].iloc[0]
    want = f"(line 2, run {run_id}, column verdict: 'fail', the store says 'pass')"
    assert want in found["results.csv"]
    base = write_baseline(folder, folder.parent / "b.json")
    for argv in (["check", str(folder), "--baseline", str(base)],
                 ["compare", str(folder), str(folder)], ["report", str(folder)]):  # fmt: skip
        assert main(argv) == 0, argv  # the store is unchanged: the verdicts stand
        err = capsys.readouterr().err
        assert f"warning: {folder / 'results.csv'} was changed after director-bench" in err, argv
        assert want in err and "the change has no effect" in err
    # the next run moves the edited file aside and writes the export again from the store
    assert main(["run", *RUN, "--out", str(folder), "--no-report"]) == 0
    out = capsys.readouterr().out
    assert f"moved aside:  {folder / 'results.csv.edited'}" in out
    assert (folder / "results.csv.edited").read_text().count(",fail,") == 1
    assert (folder / "results.csv").read_bytes() == csv_text(read_results(folder)).encode()
    assert edited(folder) == {}


def test_an_edited_parquet_export_is_named(folder, capsys):
    import pandas as pd

    df = pd.read_parquet(folder / "results.parquet")
    df.loc[0, "attitude_error_max"] = 0.0
    df.to_parquet(folder / "results.parquet", index=False)
    assert list(edited(folder)) == ["results.parquet"]
    assert main(["compare", str(folder), str(folder)]) == 0
    assert "results.parquet was changed after director-bench wrote it" in capsys.readouterr().err
