"""The order the report lists and colours engines in: the results folder's own (its
provenance.json, written in the registry's order), else this installation's registry; names
neither knows after them, alphabetically; the reference engines last. The same order in the
tables, the figures' colours, a worker's figures and the figures' reuse keys."""

import json
import re
import shutil

import pandas as pd

from reports.report import labels
from reports.report.labels import ENGINE_RANK, engine_key, engine_order, with_engine_order


def _table(engines, reference=()):
    return pd.DataFrame(
        {
            "engine": list(engines),
            "integrator": "x",
            "family": "f",
            "reference": [1.0 if e in reference else 0.0 for e in engines],
        }
    )


def test_the_folder_s_provenance_gives_the_order_when_it_names_every_engine():
    prov = {"engines": {"pybullet": "3", "exact": "0", "director": "0", "mujoco": "4"}}
    assert engine_order(prov, {"director", "mujoco"}) == ["pybullet", "exact", "director", "mujoco"]


def test_without_a_provenance_naming_every_engine_the_registry_s_order_is_taken():
    from references.engines import BUILTIN, engine_names

    registry = engine_names()
    assert registry[: len(BUILTIN)] == list(BUILTIN)  # built-ins first, in their order
    assert engine_order({}, {"director"}) == registry
    assert engine_order({"note": "unreadable"}, {"director"}) == registry
    # a provenance of the last run only (another run added engines to the folder since):
    # the registry, then the provenance's names the registry does not know, in its order
    prov = {"engines": {"zz_plugin": "1", "drake": "1.5", "aa_plugin": "2"}}
    assert engine_order(prov, {"drake", "mujoco"}) == [*registry, "zz_plugin", "aa_plugin"]


def test_engines_under_test_in_order_then_unknown_names_sorted_then_the_references():
    df = _table(
        ["exact", "zz_plugin", "mujoco", "drake", "aa_plugin", "director", "my_reference"],
        reference=("exact", "my_reference"),
    )
    prov = {"engines": {e: "1" for e in ("director", "exact", "my_reference", "mujoco", "drake")}}
    ordered = sorted(set(df["engine"]), key=engine_key(with_engine_order(df, prov)))
    assert ordered == [
        "director",
        "mujoco",
        "drake",
        "aa_plugin",
        "zz_plugin",
        "exact",
        "my_reference",
    ]
    # in the folder's order, not the registry's; the same table without the column: the
    # registry's (built-in order: drake before mjx, both before the reference)
    prov = {"engines": {e: "1" for e in ("mjx", "drake", "director", "exact")}}
    df = _table(["director", "drake", "mjx", "exact"], reference=("exact",))
    assert sorted(df["engine"], key=engine_key(with_engine_order(df, prov))) == [
        "mjx",
        "drake",
        "director",
        "exact",
    ]
    assert sorted(df["engine"], key=engine_key(df)) == ["director", "drake", "mjx", "exact"]


def test_colours_and_figure_keys_follow_the_order(folder, tmp_path):
    """The configurations' colours are given out in the folder's order, and a figure's reuse
    key (its rows: figure_cache.inputs; the plots folder's record: figures._scenario_key)
    changes with the order, so that no figure drawn in another order is reused."""
    from reports.report import canvas, figure_cache, figures
    from reports.store.results import read_results

    df = read_results(folder)
    engines = ["director", "exact", "mujoco", "pinocchio"]
    first = with_engine_order(df, {"engines": dict.fromkeys(engines, "1")})
    flipped = with_engine_order(df, {"engines": dict.fromkeys(engines[::-1], "1")})

    def colours(table):
        styles = canvas.Styles(table)
        rows = table[table["engine"] != "exact"].drop_duplicates(["engine", "integrator"])
        return {
            (r["engine"], r["integrator"]): styles.of(r)["color"] for r in rows.to_dict("records")
        }

    def engines_by_colour(given):  # the engines in the order the palette's colours went out
        pairs = sorted(given, key=lambda p: canvas.PALETTE.index(given[p]))
        return list(dict.fromkeys(e for e, _ in pairs))

    a, b = colours(first), colours(flipped)
    assert engines_by_colour(a) == ["director", "mujoco", "pinocchio"]
    assert engines_by_colour(b) == ["pinocchio", "mujoco", "director"]
    assert sorted(a.values()) == sorted(b.values()) and a != b  # the same colours, moved
    for table in (first, flipped):  # the scenario's rows, as the cache reads them
        assert ENGINE_RANK in table[table["scenario"] == "cone_top"]
    sub = {k: t[t["scenario"] == "cone_top"] for k, t in (("a", first), ("b", flipped))}
    assert figure_cache.inputs("cone_top", sub["a"], canvas.Styles(first), folder) != (
        figure_cache.inputs("cone_top", sub["b"], canvas.Styles(flipped), folder)
    )
    assert figures._scenario_key(first, "cone_top", canvas.Styles(first), folder) != (
        figures._scenario_key(flipped, "cone_top", canvas.Styles(flipped), folder)
    )
    # the place of an engine is data of its rows: a worker process receives it with them
    assert set(first.loc[first["engine"] == "pinocchio", ENGINE_RANK]) == {3}


def _work_precision_engines(md: str) -> list[str]:
    """The engines of the report's work-precision table, top to bottom."""
    part = md.split("## Work precision")[1].split("## Failures")[0]
    rows = [line.split("|") for line in part.splitlines() if line.startswith("|")]
    return [r[2].strip() for r in rows[2:] if len(r) > 3]


def test_the_report_lists_the_engines_in_the_folder_s_order(folder, tmp_path, monkeypatch):
    """Built from a folder whose provenance.json lists pinocchio before mujoco and director,
    the report's tables list them so; without a provenance.json (the session's folder),
    in the registry's order."""
    from reports.report.build import build_report

    monkeypatch.setenv("DIRECTOR_BENCH_CACHE", str(tmp_path / "cache"))
    dst = tmp_path / "folder"
    shutil.copytree(folder, dst, ignore=shutil.ignore_patterns("plots", "scorecard.*"))
    engines = ["pinocchio", "mujoco", "director", "exact"]
    (dst / "provenance.json").write_text(json.dumps({"engines": dict.fromkeys(engines, "1")}))
    build_report(dst)
    mine = _work_precision_engines((dst / "report.md").read_text())
    assert [e for e in mine if e] == ["pinocchio", "mujoco", "director"] * 2  # two scenarios
    theirs = _work_precision_engines((folder / "report.md").read_text())
    assert [e for e in theirs if e] == ["director", "mujoco", "pinocchio"] * 2
    # the folder's provenance rows list the engines as the file does
    assert re.findall(r"^\| engine (\w+) \|", (dst / "report.md").read_text(), re.M) == engines


def test_provenance_lists_the_engines_in_the_registry_s_order():
    """``--engines pybullet,director`` writes them in the registry's order, which the report
    then lists them in."""
    from references.engines import engine_names
    from reports.store.provenance import engine_versions

    got = list(engine_versions(["pybullet", "director", "mujoco"]))
    assert got == [e for e in engine_names() if e in {"pybullet", "director", "mujoco"}]
    assert got == ["director", "mujoco", "pybullet"]
    assert list(engine_versions()) == engine_names()


def test_no_engine_name_is_written_in_the_report_s_code():
    """The report names no engine in its code (a fact about one engine lives in its home
    under references/engines/): the orders come from the folder or the registry. The one
    quoted name left is a family of an old store format (the reference rows of a folder
    written before the ``reference`` column), declared once."""
    from pathlib import Path

    root = Path(labels.__file__).parents[1]
    from references.engines import BUILTIN

    pattern = re.compile("([\"'])(" + "|".join(BUILTIN) + ")\\1")  # a whole quoted name
    found = [
        f"{p.relative_to(root)}:{n}"
        for p in sorted(root.rglob("*.py"))
        for n, line in enumerate(p.read_text().splitlines(), 1)
        if pattern.search(line) and not line.startswith("LEGACY_REFERENCE_FAMILY = ")
    ]
    assert found == []
