"""Contact scenes through the suite: planned with each engine's contact configurations, run by
the runner into rows with verdicts, drawn and tabled by the report (the creep table and the
stick/slide matrix), refused when a file asks for what no builder takes; the docs' example."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import scenarios
from reports.run.plan import plan
from reports.run.runner import execute
from reports.store.runs import RunSpec
from scenarios.schema import InputError

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"


def test_plan_offers_the_contact_configurations():
    sc = scenarios.load("block_incline_stick")
    specs = plan([sc], ["mujoco", "pinocchio", "director"], sweep=False)
    mj = sorted(s.integrator for s in specs if s.engine == "mujoco")
    assert mj == ["elliptic impratio 10", "elliptic noslip 10", "pyramidal"]
    assert sorted(s.integrator for s in specs if s.engine == "pinocchio") == ["ADMM + suite"]
    full = plan([sc], ["pinocchio"], sweep=False, full=True)
    assert sorted(s.integrator for s in full) == ["ADMM + suite", "PGS + suite"]
    # the director's contact scheme runs through its builder (director_model.contact) and
    # holds the block exactly
    (d,) = [s for s in specs if s.engine == "director"]
    row = execute(d)
    assert row["status"] == "ok", row["message"]
    assert "nonsmooth" in row["integrator"] and row["verdict"] == "pass"


def test_a_contact_scene_runs_end_to_end(tmp_path):
    sc = scenarios.load("block_incline_stick")
    rows = [execute(RunSpec(sc, e, i, 1e-3, t_end=0.5), tmp_path)
            for e, i in (("mujoco", "pyramidal"), ("mujoco", "elliptic noslip 10"),
                         ("exact", "closed form"))]  # fmt: skip
    pyr, noslip, exact = rows
    for r in rows:
        assert r["status"] == "ok", r["message"]
    # MuJoCo's default creeps at ~1.2 mm/s on the 15 degree ramp: above the 1e-4 m/s bound
    assert pyr["creep_speed"] > 5e-4 and pyr["verdict"] == "fail"
    assert "creep_speed" in pyr["verdict_detail"]
    assert noslip["creep_speed"] < 1e-6 and noslip["stick_slide_mismatch"] == 0.0
    assert exact["verdict"] == "pass" and exact["creep_speed"] == 0.0
    assert exact["reference_kind"] == "sliding_block"
    traj = pd.read_parquet(tmp_path / pyr["trajectory"])
    assert {"moved", "penetration", "moved_exact"} <= set(traj.columns)
    assert np.all(traj["moved_exact"] == 0.0)
    # the report's tables
    from reports.report.contact import creep_table, stick_slide_matrix

    df = pd.DataFrame(rows)
    head, body = creep_table(df)
    assert head == ["configuration", "block_incline_stick [um/s]"]
    cells = {r[0]: r[1] for r in body}
    assert float(cells["mujoco pyramidal"]) == pytest.approx(pyr["creep_speed"] * 1e6, rel=1e-2)
    assert cells["exact closed form"] == "0"
    head, body = stick_slide_matrix(df)
    assert head[1] == "block_incline_stick (Coulomb: sticks)"
    assert {r[0]: r[1] for r in body}["mujoco pyramidal"] == "sticks"


def test_the_diagonal_push_separates_the_friction_cones(tmp_path):
    """MuJoCo's pyramid holds only mu N/sqrt 2 on the diagonal: at 0.8 mu m g it slides where
    Coulomb sticks; the matrix says so."""
    sc = scenarios.load("push_diagonal_stick")
    rows = [execute(RunSpec(sc, "mujoco", c, 1e-3, t_end=0.5), tmp_path)
            for c in ("pyramidal", "elliptic impratio 10")]  # fmt: skip
    assert rows[0]["stick_slide_mismatch"] == 1.0 and rows[1]["stick_slide_mismatch"] == 0.0
    from reports.report.contact import stick_slide_matrix

    _, body = stick_slide_matrix(pd.DataFrame(rows))
    assert {r[0]: r[1] for r in body}["mujoco pyramidal"] == "slides (wrong)"


def test_contact_settings_checked_before_any_run(tmp_path):
    from reports.suite import check_engine_settings

    data = tomllib.loads((scenarios.contact_path() / "box_resting.toml").read_text())
    data["name"] = "mine"
    data["engine_settings"] = {"mujoco": {"cone": "elliptic"}}
    sc = scenarios.validate(data, path="mine.toml")
    with pytest.raises(InputError, match=r"engine_settings\.mujoco\.cone = 'elliptic': not a "
                       r"setting of mujoco's contact builder.*known: solver"):  # fmt: skip
        check_engine_settings([sc])
    # what a configuration chooses is named as such, with the configurations that choose it
    data["engine_settings"] = {"mujoco": {"noslip": 10}}
    with pytest.raises(InputError, match=r"noslip_iterations is chosen by the contact "
                       r"configuration.*'elliptic noslip 10'"):  # fmt: skip
        check_engine_settings([scenarios.validate(data, path="mine.toml")])
    data["engine_settings"] = {"mujoco": {"solver": "CG"}}
    check_engine_settings([scenarios.validate(data, path="mine.toml")])


def _docs_example() -> dict:
    text = DOCS.read_text()
    section = text[text.index("## Contact") :]
    return tomllib.loads(re.search(r"```toml\n(.*?)```", section, re.S).group(1))


def test_the_docs_example_is_a_valid_scene_that_slides():
    sc = scenarios.validate(_docs_example(), path="my_ramp.toml")
    from references.exact.contact_scene import contact_motion

    facts = contact_motion(sc, [0.0, sc.t_end]).facts
    assert not facts["sticks"]
    # tan(20 deg) = 0.364 > mu = 0.3, as the description says
    th = math.radians(20.0)
    assert facts["acceleration"] == pytest.approx(9.81 * (math.sin(th) - 0.3 * math.cos(th)))


def test_the_docs_refusal_text_is_the_suites():
    data = _docs_example()
    data["bodies"][0]["position"] = [0.0, 0.0, 0.0]
    with pytest.raises(InputError) as err:
        scenarios.validate(data, path="my_ramp.toml")
    said = "penetrates plane 'ramp' by"
    assert said in str(err.value)
    page = " ".join(DOCS.read_text().split())
    assert "body 'block' penetrates plane 'ground' by 0.003 m at t = 0" in page


def test_a_contact_run_is_timed_in_cpu_time_and_again_by_its_builder(monkeypatch):
    """A contact builder times its engine calls on the run's stopwatch (the engine's CPU
    time and its spread, as systems), and the timing pass runs a contact spec again through
    the contact builder: a system builder would step the bodies without their contacts,
    with the same number of steps, and its time would be taken for the contact run's."""
    from references.engines import contact, get_engine
    from reports.run import timing

    sc = scenarios.load("block_incline_stick").replace(t_end=0.05)
    spec = RunSpec(sc, "mujoco", "pyramidal", 1e-3)
    r = execute(spec)
    assert r["status"] == "ok", r["message"]
    assert 0 < r["engine_time_s"] <= r["cpu_time_s"] <= r["wall_time_s"] + 1e-9, r
    assert r["engine_time_spread_s"] >= 0 and 0 < r["cpu_share"] <= 1
    calls = []
    real = contact.run_contact
    monkeypatch.setattr(contact, "run_contact", lambda *a, **k: calls.append(a) or real(*a, **k))
    got = timing._run_again(get_engine("mujoco"), spec, int(r["nstep"]))
    assert got is not None and got.engine > 0
    assert [c[:3] for c in calls] == [("mujoco", sc, "pyramidal")]


def test_a_director_contact_row_costs_its_stepping_not_its_kernels_loading(monkeypatch):
    """The director's contact kernel is compiled, or loaded from numba's cache, when its
    stepper is built (1.6 ms a step of a 1000-step run was such a load, ~3 us a warm step):
    the builder builds it before the stepping is timed. Planted here: building the stepper
    burns 0.3 s of CPU; the row's whole-step CPU time must not hold it."""
    import time

    dc = pytest.importorskip("director_model.contact")
    real = dc.ContactStepper.__init__

    def slow_init(self, *a, **k):
        real(self, *a, **k)
        c0 = time.thread_time()
        while time.thread_time() - c0 < 0.3:
            pass

    monkeypatch.setattr(dc.ContactStepper, "__init__", slow_init)
    sc = scenarios.load("block_incline_stick").replace(t_end=0.05)
    r = execute(RunSpec(sc, "director", "nonsmooth RATTLE", 1e-3))
    assert r["status"] == "ok", r["message"]
    # 50 steps of ~3-10 us each and the suite's checks between them: far below the 0.3 s
    assert r["cpu_time_s"] < 0.1, r["cpu_time_s"]
    assert 0 < r["engine_time_s"] <= r["cpu_time_s"]


def test_the_closed_forms_contact_row_has_a_cpu_cost_too():
    """The exact engine's contact rows are timed like an engine's (the closed form's
    evaluation on the run's stopwatch): every contact row has a CPU cost."""
    sc = scenarios.load("tall_box_tips").replace(t_end=0.05)  # the DOP853 reference
    r = execute(RunSpec(sc, "exact", "closed form", 1e-3))
    assert r["status"] == "ok", r["message"]
    assert 0 < r["engine_time_s"] <= r["cpu_time_s"], r
    assert math.isfinite(r["ns_per_step"]) and math.isfinite(r["engine_time_spread_s"])


def test_contact_tables_are_at_the_scenes_own_dt_when_a_sweep_ran(tmp_path):
    """A run with the dt sweep holds each configuration at several steps: the creep table,
    the matrix and the per-scene tables show the scene's own dt (the exact reference's),
    not the sweep's largest (4e-3 s for most library scenes, their files' dt being 1e-3 s)."""
    from reports.report.contact import creep_table, scene_tables

    sc = scenarios.load("block_incline_stick").replace(t_end=0.2)
    rows = [execute(RunSpec(sc, e, i, h), tmp_path)
            for e, i, h in (("pybullet", "default friction", 1e-3),
                            ("pybullet", "default friction", 4e-3),
                            ("exact", "closed form", 1e-3))]  # fmt: skip
    assert all(r["status"] == "ok" for r in rows), [r["message"] for r in rows]
    fine, coarse, _ = rows
    assert coarse["creep_speed"] > 5 * fine["creep_speed"]  # 138 and 7 um/s: they differ
    df = pd.DataFrame(rows)
    cells = {r[0]: r[1] for r in creep_table(df)[1]}
    assert float(cells["pybullet default friction"]) == pytest.approx(
        fine["creep_speed"] * 1e6, rel=1e-2
    )
    ((scene, h, head, body),) = scene_tables(df)
    assert (scene, h) == ("block_incline_stick", 1e-3)
    creep = head.index("creep [um/s]")
    row = next(b for b in body if b[0] == "pybullet default friction")
    assert float(row[creep]) == pytest.approx(fine["creep_speed"] * 1e6, rel=1e-2)


def test_work_precision_of_a_contact_scene_is_its_position_error(tmp_path):
    """MuJoCo's pyramidal cone creeps ~1.2 mm/s on the 15 degree ramp: 0.6 mm in 0.5 s, with
    its attitude hardly turned. Ranked by attitude error it would reach 1e-4; by the
    position error against the closed form (the contact scenes' measure) it does not."""
    from reports.report.tables import work_precision

    sc = scenarios.load("block_incline_stick")
    rows = [execute(RunSpec(sc, e, i, 1e-3), tmp_path)
            for e, i in (("mujoco", "pyramidal"), ("exact", "closed form"))]  # fmt: skip
    pyr = rows[0]
    assert pyr["attitude_error_max"] < 1e-4 < pyr["position_error_max"], pyr
    (level,) = work_precision(pd.DataFrame(rows), levels=(1e-4,))
    assert level["ranked"] == []
    (miss,) = level["not_reached"]
    assert miss["configuration"] == "mujoco pyramidal" and " m at dt" in miss["why"]
    (level,) = work_precision(pd.DataFrame(rows), levels=(1e-2,))
    (entry,) = level["ranked"]
    assert entry["error_measure"] == "position_error_max"
    assert entry["error"] == pytest.approx(pyr["position_error_max"])


def test_a_contact_run_is_summed_up_by_its_position_error_everywhere(tmp_path):
    """Wherever a run is one number (the scorecard's entry and picture, report.md's short
    verdict table, summary.json, the dt sweep and work-precision tables), a contact scene's
    is its position error against the closed form in m, the metric catalog's headline for
    the scene kind; a body's stays its attitude error in rad. MuJoCo's pyramidal cone on the
    15 degree ramp: attitude < 1e-4 rad, position 6e-4 m from its 1.2 mm/s creep, so the two
    cannot be mistaken for each other. An unsupported contact row (no metrics at all) counts
    among the contact rows by its recorded scene kind."""
    from reports.metrics.catalog import HEADLINE
    from reports.report.contact import contact_rows
    from reports.report.doc import Doc
    from reports.report.labels import entry_texts, headline
    from reports.report.precision import measure_of
    from reports.report.scorecard_plot import scorecard_cells
    from reports.report.sections import sweep_table, wp_table
    from reports.report.summary_json import summary
    from reports.report.tables import scorecard
    from reports.report.verdict import scenario_verdicts
    from reports.store.format import fmt

    assert HEADLINE == {"body": "attitude_error_max", "system": "attitude_error_max",
                        "contact": "position_error_max"}  # fmt: skip
    sc = scenarios.load("block_incline_stick").replace(t_end=0.5)
    rows = [execute(RunSpec(sc, "mujoco", "pyramidal", h), tmp_path) for h in (2e-3, 1e-3)]
    rows.append(execute(RunSpec(sc, "exact", "closed form", 1e-3), tmp_path))
    pyr = rows[1]
    assert pyr["attitude_error_max"] < 1e-4 < pyr["position_error_max"], pyr
    pos = fmt(pyr["position_error_max"])
    df = pd.DataFrame(rows)
    assert headline(pyr) == ("position_error_max", "m", "position")
    assert measure_of(pyr) == ("position_error_max", "m")
    assert headline({"scene_kind": "body"})[:2] == measure_of({}) == ("attitude_error_max", "rad")

    (s,) = scorecard(df)
    (g,) = [g for gs in s["cells"].values() for g in gs]
    assert entry_texts(g)[2][:2] == [f"{pos} m", f"E {fmt(pyr['energy_gain_max'])}"]
    doc = Doc()
    scenario_verdicts(doc, s)
    table = [ln for ln in "\n".join(doc.md).splitlines() if ln.startswith("| ")]
    assert table[0].split(" | ")[3:5] == ["position [m]", "energy gained"]
    assert table[1].split(" | ")[3] == pos
    _, _, cells = scorecard_cells(df)
    (text,) = [t for (key, _), (_, t) in cells.items() if key[0] == "mujoco"]
    assert text[0].endswith(f"{pos} m"), text
    (grp,) = summary(df)["scorecard"][0]["families"].values()
    assert grp[0]["error_measure"] == "position_error_max"
    assert grp[0]["error"] == pytest.approx(pyr["position_error_max"])
    assert grp[0]["energy_measure"] == "energy_gain_max"
    doc = Doc()
    sweep_table(doc, "block_incline_stick", df)
    wp_table(doc, "block_incline_stick", df)
    md = "\n".join(doc.md)
    assert "max position error [m] over the dt sweep" in md and pos in md
    assert "| position error ≤ | cheapest | its error [m] |" in md
    assert "attitude" not in md
    # a scene whose runs have a fitted order (a sliding one): the order is the attitude
    # error's (reports.metrics.body.add_convergence_orders), and the header says so beside
    # the position errors
    slid = df.assign(convergence_order=1.0, convergence_points=2.0)
    doc = Doc()
    sweep_table(doc, "block_incline_stick", slid)
    header = next(ln for ln in "\n".join(doc.md).splitlines() if ln.startswith("| family"))
    assert header.endswith("| fitted order (attitude error) | declared order |"), header

    bare = {**rows[0], "status": "unsupported", "position_error_max": math.nan,
            "slide_distance": math.nan, "engine": "mjx"}  # fmt: skip
    assert len(contact_rows(pd.DataFrame([*rows, bare]))) == 4


def test_a_configuration_named_with_its_suite_loop_says_so_once():
    """Pinocchio's contact configurations carry '+ suite' in their names: their label does
    not say it twice ('pinocchio + suite ADMM + suite' in the scorecard and the tables)."""
    from reports.report.labels import config_label

    row = {"engine": "pinocchio", "integrator": "ADMM + suite", "suite_integrated": True,
           "reference": False}  # fmt: skip
    assert config_label(row) == "pinocchio ADMM + suite"
    row = {"engine": "pinocchio", "integrator": "RKMK4", "suite_integrated": True,
           "reference": False}  # fmt: skip
    assert config_label(row) == "pinocchio + suite RKMK4"
