"""Robot models run through each engine's own importer (references.engines.importers.simulate):
the faithful configuration against the engine's run on our reading of the file (an
independent path: the system builder never reads the file), the importer's effect in the as
loaded configuration, an importer that cannot load the file named in its row, a planted
frame mistake of the run caught, and the importer table written into a results folder and
shown in the report."""

from __future__ import annotations

import numpy as np
import pytest

import scenarios
from references.engines import importers as imp
from scenarios.models.configurations import split_variant


def _run(engine, sc, integrator, config=None, nstep=300):
    from references.engines.system import run_system

    name = integrator if config is None else imp.variant(integrator, config)
    return run_system(engine, sc, name, 1e-3, t_end=nstep * 1e-3, save_every=10).trajectory


def _attitude(a, b) -> float:
    """The largest rotation angle between the bodies' attitudes of two runs (atan2 form:
    accurate down to round-off)."""
    E = np.einsum("nbji,nbjk->nbik", a.rotation, b.rotation)
    c = 0.5 * (np.trace(E, axis1=2, axis2=3) - 1.0)
    s = 0.5 * np.linalg.norm(
        np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0],
                  E[..., 1, 0] - E[..., 0, 1]], axis=-1), axis=-1)  # fmt: skip
    return float(np.max(np.arctan2(s, c)))


def test_names_of_the_configurations_round_trip():
    assert imp.variant("RK4", "as-loaded") == "RK4 (as loaded)"
    assert imp.variant("Euler (float64)", "faithful") == "Euler (float64, faithful)"
    for name in ("RK4 (as loaded)", "Euler (float64, faithful)", "semi-implicit Euler"):
        base, config = split_variant(name)
        assert (imp.variant(base, config) if config else base) == name
    assert imp.variants("mujoco", ["RK4", "Euler"]) == ["RK4 (as loaded)", "RK4 (faithful)"]
    assert imp.variants("director", ["rattle"]) == []


@pytest.mark.parametrize(
    "engine,integrator",
    [("mujoco", "RK4"), ("pinocchio", "RKMK4"), ("drake", "runge_kutta5"),
     ("dart", "semi-implicit Euler")],
)  # fmt: skip
def test_faithful_import_moves_as_our_reading_does(engine, integrator):
    """arm3.urdf loaded by the engine's importer (faithful) and the same engine on our
    reading (the builder) give the same motion to well below the integrator's error: the
    two paths share no code but the engine's stepping."""
    pytest.importorskip({"mujoco": "mujoco", "pinocchio": "pinocchio", "drake": "pydrake",
                         "dart": "dartpy"}[engine])  # fmt: skip
    sc = scenarios.load("arm3_swing")
    ours = _run(engine, sc, integrator)
    theirs = _run(engine, sc, integrator, "faithful")
    # measured: <= 3e-14 rad (mujoco, pinocchio, dart), 2.6e-14 (drake) over 0.3 s; the
    # integrator's own error there is 1e-9 .. 1e-2 rad
    assert _attitude(ours, theirs) < 1e-9
    np.testing.assert_allclose(theirs.position, ours.position, rtol=0, atol=1e-10)


def test_a_planted_frame_mistake_of_the_run_is_caught(monkeypatch):
    """Each body read at its link's frame instead of its principal frame (the offsets
    dropped): the faithful run no longer moves as our reading does."""
    pytest.importorskip("mujoco")
    sc = scenarios.load("arm3_swing")
    links, off = imp.body_offsets(sc)
    monkeypatch.setattr(
        imp, "body_offsets", lambda s: (links, np.tile(np.eye(4), (len(off), 1, 1)))
    )
    ours = _run("mujoco", sc, "RK4")
    theirs = _run("mujoco", sc, "RK4", "faithful")
    assert _attitude(ours, theirs) > 0.1


def test_pybullet_as_loaded_recomputes_the_inertias_and_it_shows_in_the_motion():
    """PyBullet's loadURDF without URDF_USE_INERTIA_FROM_FILE takes arm3's inertias from its
    collision shapes (59.7-100 % off, read back), and keeps two axes unnormalised (2.5 and
    4.4 % long, which scales those joints' coordinates and rates): as loaded, the arm leaves
    our reading's motion by 0.3 rad and more within 0.3 s. Faithful (the flag, a copy with
    unit axes) it moves as PyBullet on our reading, to PyBullet's single precision: measured
    3.8e-8 m after 0.3 s; with the axes as written it was 5.8e-3 m off (bound 1e-6 m)."""
    pytest.importorskip("pybullet")
    sc = scenarios.load("arm3_swing")
    ref = _run("pybullet", sc, "multibody")
    loaded = _attitude(ref, _run("pybullet", sc, "multibody", "as-loaded"))
    faithful = _run("pybullet", sc, "multibody", "faithful")
    assert loaded > 0.3, loaded
    assert abs(faithful.position - ref.position).max() < 1e-6
    rows = [r for r in imp.importer_table(sc.model, ["pybullet"]) if r.quantity == "axis length"]
    assert {r.config for r in rows} == {"as-loaded"} and len(rows) == 2


def test_an_importer_that_cannot_load_the_file_is_an_unsupported_row_with_its_reason(tmp_path):
    """MuJoCo's importer on a URDF whose collision mesh it cannot open (a ``package://``
    name it does not resolve): the row says so (never a silent fallback to the builder)."""
    pytest.importorskip("mujoco")
    from references.errors import Unsupported

    urdf = scenarios.load("arm3_swing").model.path
    text = (
        open(urdf)
        .read()
        .replace(
            '<link name="base">',
            '<link name="base"><collision><geometry><mesh filename="package://nowhere/m.stl"/>'
            "</geometry></collision>",
            1,
        )
    )
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "arm3.urdf").write_text(text)
    toml = (
        open(scenarios.load("arm3_swing").path)
        .read()
        .replace(
            '[model]\nfile = "models/arm3.urdf"',
            '[model]\nfile = "models/arm3.urdf"\nmeshes = "ignore"',
        )
    )
    (tmp_path / "arm.toml").write_text(toml)
    sc = scenarios.load(str(tmp_path / "arm.toml"))
    with pytest.raises(
        Unsupported, match=r"mujoco: its importer cannot load .*arm3.urdf \(as-loaded\)"
    ):
        _run("mujoco", sc, "RK4", "as-loaded")


def test_a_run_writes_the_importer_table_and_the_report_shows_it(tmp_path):
    """director-bench run on a robot model: the importer configurations are rows of the
    results, each engine's importer table is in the folder (importers/<scenario>.json) and in
    report.md with the command that prints it, and the model's two figures are drawn."""
    pytest.importorskip("mujoco")
    pytest.importorskip("pybullet")
    from reports.suite import run

    out = tmp_path / "res"
    s = run(["arm3_swing"], engines=["mujoco", "pybullet", "exact"],
            integrators=["RK4", "multibody", "reference"], t_end=0.1, out=out,
            progress=False)  # fmt: skip
    got = set(zip(s.results["engine"], s.results["integrator"], strict=True))
    assert {
        ("mujoco", "RK4 (as loaded)"),
        ("mujoco", "RK4 (faithful)"),
        ("pybullet", "multibody (as loaded)"),
        ("pybullet", "multibody (faithful)"),
    } <= got
    import json

    table = json.loads((out / "importers" / "arm3-swing.json").read_text())
    assert table["engines"] == ["mujoco", "pybullet"]
    inertia = [r for r in table["rows"] if r["engine"] == "pybullet" and r["quantity"] ==
               "inertia" and r["config"] == "as-loaded"]  # fmt: skip
    assert len(inertia) == 3 and min(r["size"] for r in inertia) > 50
    md = (out / "report.md").read_text()
    assert "**arm3_swing: what each importer does to the model**" in md
    assert "| mujoco | faithful | agrees with our reading |" in md
    assert "| pybullet | as loaded | inertia: 3 x, up to 100 %;" in md
    assert "director-bench show --importers arm3_swing --engines mujoco,pybullet" in md
    assert (out / "plots" / "arm3-swing__importers.png").is_file()
    assert (out / "plots" / "arm3-swing__joint_angles.png").is_file()
    # the short verdict table (report.md) and the scorecard (report.html) show each
    # configuration's joint angle error beside its attitude error
    from reports.store.format import fmt

    r = s.results
    loaded = r[(r["engine"] == "mujoco") & (r["integrator"] == "RK4 (as loaded)")].iloc[0]
    q, att = fmt(loaded["joint_coordinate_error_max"]), fmt(loaded["attitude_error_max"])
    assert q != att  # the two metrics differ on this run, so the column is told apart
    section = md.split("**arm3_swing: verdicts at")[1].split("\n\n", 2)[1]
    head, _, *rows = section.splitlines()
    assert head.split(" | ")[3:5] == ["joint angle [rad]", "attitude [rad]"]
    row = next(ln for ln in rows if "mujoco RK4 (as loaded)" in ln)
    assert row.split(" | ")[3:5] == [q, att], row
    page = (out / "report.html").read_text()
    assert f"</abbr> {q} rad</span>" in page


def test_an_importers_own_initial_joint_values_never_set_the_zero_configuration(tmp_path):
    """DART's URDF loader starts a joint whose limits exclude 0 inside them: arm3 with its
    elbow limited to [0.5, 1.0] rad still reads back as our reading at the zero
    configuration, and its importer run starts where the scenario says (the elbow at the
    scenario's -1.1, outside the limits DART would clamp it into)."""
    pytest.importorskip("dartpy")
    from scenarios.models import read_model

    sc = scenarios.load("arm3_swing")
    text = (
        open(sc.model.path)
        .read()
        .replace('<limit lower="-2.8" upper="2.8"', '<limit lower="0.5" upper="1.0"')
    )
    assert 'lower="0.5"' in text
    (tmp_path / "arm3.urdf").write_text(text)
    rows = imp.importer_table(read_model(tmp_path / "arm3.urdf"), engines=["dart"])
    assert {r.quantity for r in rows} == {"agree"}, [r.line() for r in rows]
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "arm3.urdf").write_text(text)
    toml = open(sc.path).read()
    (tmp_path / "arm.toml").write_text(toml)
    limited = scenarios.load(str(tmp_path / "arm.toml"))
    first = imp.simulate("dart", limited, "faithful", "semi-implicit Euler", 1e-3, 10, 10)
    np.testing.assert_allclose(first.x[0], [b.position for b in limited.bodies], atol=1e-12)


PENDULUM_WITH_FLOOR = """<mujoco model="pend">
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0"/>
      <geom name="rod" type="capsule" fromto="0 0 0 0.3 0 -0.3" size="0.03" density="800"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_mjx_runs_a_model_loaded_with_its_contacts(tmp_path):
    """MJX as loaded keeps the file's contacts (a capsule above a floor): put_data gives the
    contact's geom ids as int32, mjx.step as int64 under x64, and the run's loop needs one
    type (it was a TypeError row on ant and pusher as loaded). Its motion is MuJoCo's on our
    reading of the file stepped by MuJoCo's Euler (no contact is reached: the rod swings
    0.3 m above the floor; an independent path: the system builder never reads the file)."""
    pytest.importorskip("mujoco.mjx")
    (tmp_path / "pend.xml").write_text(PENDULUM_WITH_FLOOR)
    (tmp_path / "pend.toml").write_text(
        'name = "pend_floor"\ndescription = "a hinged capsule above a floor, as loaded by '
        'MJX and MuJoCo, for a test of the importer runs"\nsource = "test"\n'
        '[model]\nfile = "pend.xml"\n[model.initial]\njoints = { hinge = 0.5 }\n'
        "[environment]\ngravity = [0.0, 0.0, -9.81]\n"
        '[run]\nt_end = 0.02\ndt = 1e-3\nsave_every = 10\n[reference]\nkind = "numerical"\n'
    )
    sc = scenarios.load(str(tmp_path / "pend.toml"))
    mjx = _run("mjx", sc, "Euler (float64)", "as-loaded", nstep=20)
    c = _run("mujoco", sc, "Euler", nstep=20)
    assert mjx.position.shape == c.position.shape
    # measured: 6.9e-17 m, 2.8e-16 rad: one Euler step in float64 on the same mass properties
    # (our reading of the capsule equals MuJoCo's compiler's); 1e-12 leaves round-off room
    np.testing.assert_allclose(mjx.position, c.position, rtol=0, atol=1e-12)
    assert _attitude(mjx, c) < 1e-12


def test_a_diverged_importer_run_is_named_in_its_panel(tmp_path):
    """Drake's as-loaded crawler diverges in its first steps (its MJCF parser drops the
    armature of unactuated joints): the joint angle figure has no line for it, so its panel
    says so, and so does the figure's text."""
    pytest.importorskip("pydrake")
    from reports.suite import run

    out = tmp_path / "res"
    s = run(["crawler_float"], engines=["drake", "exact"],
            integrators=["runge_kutta5", "reference"], t_end=0.05, out=out,
            progress=False)  # fmt: skip
    r = s.results
    assert "diverged" in set(r[r["integrator"] == "runge_kutta5 (as loaded)"]["status"])
    md = (out / "report.md").read_text()
    alt = next(ln for ln in md.splitlines() if "crawler-float__joint_angles.png" in ln)
    assert "no line for drake runge_kutta5 as loaded: diverged at t = 0 s" in alt, alt


def test_mjx_compilations_are_announced_before_the_runs_with_the_number(capsys):
    """Issue 32 item 8's rule for a first run's compilation: MJX's runs on robot models
    compile mjx.step once per scenario and configuration where JAX's persistent cache does not
    hold it (pusher as loaded, with its contacts, measured minutes of CPU); the planner's note
    names the count, the total, the largest and where compilations are kept, once the total
    passes a minute, and says nothing below it or where nothing compiles."""
    pytest.importorskip("jax")
    from reports.run.plan import plan
    from reports.suite import COST_WARNING_S, check_integrators, warn_compiles

    def specs(scs, engines, slugs):
        return plan(scs, engines, check_integrators(slugs, engines, True))

    scs = [scenarios.load(n) for n in ("arm3_swing", "crawler_float", "pusher_swing")]
    (line,) = warn_compiles(
        specs(scs, ["mjx", "mujoco"], ["euler-float64", "euler-float64-as-loaded", "euler"])
    )
    # three scenarios x (on our reading, as loaded, faithful: a robot model's importer
    # configurations come with the integrator); the sweep's steps share a compilation
    assert line.startswith("mjx: 9 configurations compile before they step, about ")
    total = float(line.split("about ")[1].split(" s")[0])
    assert total > COST_WARNING_S
    # the largest: an as-loaded configuration of a file with collision geometry
    assert "with the file's contacts for " in line and "(float64, as loaded)" in line
    assert "kept in " in line
    assert "note: mjx" in capsys.readouterr().err
    # arm3 on our reading alone: one contact-free compilation, under a minute: no note
    assert warn_compiles(specs(scs[:1], ["mjx"], ["euler-float64"])) == []
    # a single body: MJX's compilation there is not announced by this rule
    assert warn_compiles(specs([scenarios.load("dzhanibekov")], ["mjx"], ["euler-float64"])) == []


def test_pybullets_importer_prints_no_banner():
    """PyBullet's C module prints its build time when first imported; the importer's read-back
    (run in the main process for a run's importer table, reports.run.importers) imports it
    silenced, as the adapter does: before, a rerun's first line of output was the banner."""
    import subprocess
    import sys

    pytest.importorskip("pybullet")
    code = (
        "import scenarios\n"
        "from references.engines import importers as imp\n"
        "from references.engines.pybullet.importer import readback\n"
        "readback(scenarios.load('arm3_swing').model, imp.CONFIGS[0])\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "build time" not in p.stdout + p.stderr, p.stdout + p.stderr


@pytest.mark.parametrize("engine", ["mujoco", "pybullet"])
def test_an_importer_run_is_timed_in_cpu_time_and_again_in_the_timing_pass(engine):
    """An importer's stepping is timed on the run's stopwatch (references.engines.timing.lap)
    as the system builders' is: its row carries the engine's CPU time and its spread, so
    the timing pass times it again (reports.run.timing.timed) and a busy machine does not
    inflate its cost (before: wall time only, no repeat, 1.6x-3.3x apart between a run
    alone and one beside a second suite, bench_cost_agreement.py)."""
    from reports.run import runner, timing
    from reports.store.runs import RunSpec

    sc = scenarios.load("arm3_swing").replace(t_end=0.05, dt_sweep=())
    base = {"mujoco": "RK4", "pybullet": "multibody"}[engine]
    row = runner.execute(RunSpec(sc, engine, imp.variant(base, "faithful"), 1e-3))
    assert row["status"] == "ok", row["message"]
    assert 0 < row["engine_time_s"] <= row["cpu_time_s"] <= row["wall_time_s"] + 1e-9, row
    assert row["engine_time_spread_s"] >= 0 and 0 < row["cpu_share"] <= 1
    assert timing.timed(row)
