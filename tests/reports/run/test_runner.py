"""The runner, end to end with real engines: rows, files, failures as rows, interruption and
resume, the CLI on a user's file, and the report rendered in a real browser."""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import scenarios
from reports.cli import main
from reports.run.parallel import Mapper
from reports.run.plan import plan
from reports.run.runner import execute, run_suite
from reports.store.results import read_results
from reports.store.runs import RunSpec

ROOT = Path(__file__).resolve().parents[3]
SHORT = 1.0  # s: long enough for every metric, short enough for a unit test


@pytest.fixture(scope="module")
def dzh():
    return scenarios.load("dzhanibekov").replace(t_end=SHORT, dt_sweep=(4e-3, 2e-3))


def specs_for(
    sc, engines=("director", "exact", "mujoco"), integrators=("rattle", "reference", "Euler")
):
    return plan([sc], engines, integrators)


def test_rows_files_and_report(tmp_path, dzh):
    df, n = run_suite(specs_for(dzh), tmp_path, progress=False)
    # director rattle and mujoco Euler at 3 dt each, exact once
    assert n == 7 and len(df) == 7
    assert set(df["status"]) == {"ok"}
    # the engine's is_reference flag, recorded for the report to tell the reference by
    assert dict(zip(df["engine"], df["reference"], strict=True)) == {
        "director": 0.0,
        "exact": 1.0,
        "mujoco": 0.0,
    }
    for _, r in df.iterrows():
        assert (tmp_path / r["trajectory"]).exists()
        assert r["scenario_hash"] == dzh.scenario_hash and r["engine_version"]
    # the fitted order of RATTLE on the sweep is its declared 2 (tolerance 0.15 as issue 2)
    rattle = df[df["integrator"] == "rattle"]
    assert rattle["convergence_order"].iloc[0] == pytest.approx(2.0, abs=0.15)
    euler = df[df["integrator"] == "Euler"]
    assert euler["convergence_order"].iloc[0] == pytest.approx(1.0, abs=0.15)
    from reports.report.build import build_report

    rep = build_report(tmp_path)
    md = rep["markdown"].read_text()
    # the verdict first, then the details of the scenario at its own dt
    assert md.index("## Scorecard") < md.index("## Details")
    assert "**dzhanibekov at dt = 0.001 s**" in md and "rattle" in md.split("## Details")[0]
    html = rep["html"].read_text()
    # five figures (the scorecard, the scenario, errors, convergence, work-precision),
    # embedded; over this short horizon every configuration's W error stays within 1 % of
    # the reference's max |W|, so the rates figure is a sentence instead
    assert html.count("data:image/png;base64,") == 5 and "src='plots/" not in html
    assert "No rates figure" in md
    assert (tmp_path / "summary.json").exists()


def test_every_configuration_of_a_scenario_runs_the_same_steps(dzh):
    def steps(specs, integrator):
        return sorted(s.dt for s in specs if s.integrator == integrator)

    names = ("rattle", "rattle4", "rattle6", "Euler")
    specs = plan([dzh], ("director", "mujoco"), names)
    for name in names:  # the scenario's sweep, the high orders included
        assert steps(specs, name) == [1e-3, 2e-3, 4e-3]
    # explicit steps and --no-sweep are what the user asked for, for every integrator
    explicit = plan([dzh], ("director", "mujoco"), names, dts=[1e-3, 5e-4])
    single = plan([dzh], ("director", "mujoco"), names, sweep=False)
    for name in names:
        assert steps(explicit, name) == [5e-4, 1e-3]
        assert steps(single, name) == [1e-3]


def test_failing_run_is_a_row_and_the_rest_go_on(tmp_path):
    """h |W| = 0.5 * 2.0 = 1.0: RATTLE has no solution (docs/numerics.md, h|W| < 1); the row says
    diverged at the first step, with the step-size limit, and MuJoCo's run still happens."""
    sc = scenarios.load("major_axis_spin").replace(t_end=2.0, dt_sweep=())
    specs = [RunSpec(sc, "director", "rattle", 0.5), RunSpec(sc, "mujoco", "Euler", 0.5)]
    df, _ = run_suite(specs, tmp_path, progress=False)
    bad = df[df["engine"] == "director"].iloc[0]
    assert bad["status"] == "diverged" and bad["verdict"] == "fail"
    assert bad["t_diverged"] == 0.0  # the step from t = 0 has no solution
    assert "could not be taken" in bad["message"] and "h_max" in bad["message"]
    assert df[df["engine"] == "mujoco"]["status"].iloc[0] == "ok"


def test_engines_running_the_same_algorithm_get_the_same_status():
    """cone_top at dt = 1e-3 under semi-implicit Euler blows up (energy error beyond 100 % of
    the scenario's energy scale): every engine running that algorithm is diverged, at the same
    time (the algorithm is the same to round-off), and fails its verdict."""
    sc = scenarios.load("cone_top")
    pairs = [
        ("mujoco", "Euler"),
        ("pinocchio", "semi-implicit Euler"),
        ("dart", "semi-implicit Euler"),
        ("pybullet", "multibody"),
    ]
    rows = [execute(RunSpec(sc, e, i, 1e-3)) for e, i in pairs]
    rows = [r for r in rows if r["status"] != "unavailable"]
    assert len(rows) >= 2
    assert {r["status"] for r in rows} == {"diverged"}, [r["message"] for r in rows]
    assert {r["verdict"] for r in rows} == {"fail"}
    assert len({r["t_diverged"] for r in rows}) == 1
    # the energy error of the part before the divergence is recorded, and exceeds the limit
    # only at the divergence: the last good sample is within it
    assert all(r["energy_drift_max"] <= 1.0 for r in rows)


def test_a_long_native_error_keeps_its_first_line_and_points_to_the_whole_text(
    tmp_path, monkeypatch
):
    """A run that fails with a compiler's dump (thousands of characters over many lines, as
    JAX's "Cannot lower jaxpr" for MJX) is an 'error' row whose message is the first line,
    where it was raised and the file holding the whole text and the traceback; without an
    output folder the row keeps the whole text; a short message stays whole."""
    from references.engines.mujoco.adapter import MujocoEngine

    dump = "Cannot lower jaxpr with verifier errors:\n" + "\tat loc(jit(step)/tril)\n" * 150

    def fails(*args, **kwargs):
        raise ValueError(dump)

    monkeypatch.setattr(MujocoEngine, "run", fails)
    spec = RunSpec(scenarios.load("free_tumbling").replace(t_end=0.01), "mujoco", "Euler", 1e-3)
    row = execute(spec, tmp_path)
    assert row["status"] == "error"
    msg = row["message"]
    first = "ValueError: Cannot lower jaxpr with verifier errors: (at test_runner.py:"
    assert msg.startswith(first), msg
    assert len(msg) < 300 and "\n" not in msg, msg
    rel = re.search(r"the whole message: (\S+)\]$", msg).group(1)
    assert rel.startswith("logs/errors/free-tumbling/mujoco__")
    text = (tmp_path / rel).read_text()
    assert dump in text and "Traceback" in text
    whole = execute(spec)["message"]
    assert whole.startswith(f"ValueError: {dump} (at test_runner.py:"), whole[-80:]

    def short(*args, **kwargs):
        raise ValueError("bad")

    monkeypatch.setattr(MujocoEngine, "run", short)
    assert re.fullmatch(r"ValueError: bad \(at test_runner.py:\d+\)", execute(spec)["message"])


def test_a_reference_too_coarse_for_the_tolerance_says_so():
    """A [tolerances] bound on the attitude error below 10x the reference's accuracy cannot be
    judged: the run is reference-inaccurate, with the figure, and gets no verdict."""
    sc = scenarios.load("free_tumbling").replace(
        t_end=0.1, dt_sweep=(), tolerances={"*": {"attitude_error_max": 1e-14}}
    )
    row = execute(RunSpec(sc, "mujoco", "RK4", 1e-3))
    assert row["status"] == "reference-inaccurate" and row["verdict"] == ""
    assert "accuracy estimate" in row["message"] and "1e-14" in row["message"]
    ok = execute(RunSpec(sc.replace(tolerances={}), "mujoco", "RK4", 1e-3))
    assert ok["status"] == "ok" and ok["verdict"] == "pass"


def test_unknown_integrator_is_a_row(tmp_path, dzh):
    df, _ = run_suite([RunSpec(dzh, "mujoco", "RK45", 1e-3)], tmp_path, progress=False)
    assert df["status"].iloc[0] == "unsupported"
    assert "RK4" in df["message"].iloc[0]  # lists what the engine does offer


def test_interruption_keeps_finished_runs_and_resume_skips_them(tmp_path, dzh):
    specs = specs_for(dzh)

    def interrupted(fn, todo, keys=None):
        for i, spec in enumerate(todo):
            if i == 3:
                raise KeyboardInterrupt
            yield fn(spec)

    with pytest.raises(KeyboardInterrupt):
        run_suite(specs, tmp_path, progress=False, mapper=Mapper(interrupted))
    assert len(read_results(tmp_path)) == 3
    seen = []

    def recording(fn, todo, keys=None):
        for spec in todo:
            seen.extend(s.key for s in spec)
            yield fn(spec)

    df, n = run_suite(specs, tmp_path, progress=False, mapper=Mapper(recording))
    assert n == len(specs) - 3 and len(seen) == n and len(df) == len(specs)
    # --redo runs everything again
    df, n = run_suite(specs, tmp_path, progress=False, redo=True)
    assert n == len(specs) and len(df) == len(specs)


def test_cli_run_on_a_user_file(tmp_path, capsys):
    src = Path(scenarios.library_path()) / "free_tumbling.toml"
    user = tmp_path / "my_body.toml"
    text = src.read_text().replace('name = "free_tumbling"', 'name = "my_body"')
    user.write_text(text)
    out = tmp_path / "out"
    code = main(
        [
            "run",
            str(user),
            "--engines",
            "director",
            "--integrators",
            "rattle4",
            "--t-end",
            "1",
            "--no-sweep",
            "--out",
            str(out),
            "--quiet",
            "--jobs",
            "1",
        ]
    )
    assert code == 0
    df = read_results(out)
    assert list(df["scenario"]) == ["my_body"] and df["status"].iloc[0] == "ok"
    assert (out / "provenance.json").exists()
    prov = json.loads((out / "provenance.json").read_text())
    assert prov["engines"]["director"]


def test_cli_malformed_file_names_file_field_and_rule(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    src = Path(scenarios.library_path()) / "free_tumbling.toml"
    bad.write_text(src.read_text().replace("[body]\n", "[body]\ncolour = 3\n"))
    assert main(["run", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "colour" in err
    assert main(["run", "no_such_scenario", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "dzhanibekov" in capsys.readouterr().err  # lists the available names


def test_parallel_pool_gives_the_serial_rows(tmp_path, dzh):
    """Runs are deterministic: a 2-process pool writes the same metrics as a serial run."""
    from reports.run.parallel import process_pool

    specs = specs_for(dzh, engines=("director", "mujoco"))
    a, _ = run_suite(specs, tmp_path / "a", progress=False)
    b, _ = run_suite(specs, tmp_path / "b", progress=False, mapper=process_pool(2))
    cols = [
        "scenario",
        "engine",
        "integrator",
        "dt",
        "status",
        "energy_drift_max",
        "attitude_error_max",
        "omega_error_max",
        "momentum_drift_max",
    ]
    pd.testing.assert_frame_equal(a[cols], b[cols])


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


#: added to a copy of report.html: opens every collapsed section, then writes into the page
#: what it measured (images that did not load, tables wider than their container or the
#: page, a page that scrolls sideways, the name shown when the pointer is on a line of a
#: figure), which --dump-dom prints
LAYOUT_CHECK = """<script>
window.addEventListener('load', function () {
  document.querySelectorAll('details').forEach(function (d) { d.open = true; });
  var vw = document.documentElement.clientWidth, bad = [], broken = 0;
  var imgs = document.images, tables = document.querySelectorAll('table');
  for (var i = 0; i < imgs.length; i++) {
    if (!(imgs[i].complete && imgs[i].naturalWidth > 0)) broken++;
  }
  tables.forEach(function (t, k) {
    var box = t.parentElement, r = box.getBoundingClientRect(), tr = t.getBoundingClientRect();
    if (!box.classList.contains('scroll')) bad.push(k + ': not in a scrolling container');
    if (r.left < -1 || r.right > vw + 1) bad.push(k + ': ' + r.left + '..' + r.right);
    if (vw <= 800 && (t.scrollWidth > box.clientWidth + 1 || tr.right > vw + 1))
      bad.push(k + ': table ' + t.scrollWidth + ' px in ' + box.clientWidth + ' px');
  });
  var fig = document.querySelector('figure[data-lines]'), hover = null;
  if (fig) {
    var lines = JSON.parse(fig.getAttribute('data-lines')), img = fig.querySelector('img');
    var p = lines[0].paths[0][Math.floor(lines[0].paths[0].length / 2)];
    fig.scrollIntoView();
    var r = img.getBoundingClientRect();
    img.dispatchEvent(new MouseEvent('mousemove', {clientX: r.left + p[0] * r.width,
      clientY: r.top + p[1] * r.height, bubbles: true}));
    var tip = fig.querySelector('.tip');
    hover = {line: lines[0].label, shown: tip.hidden ? null : tip.textContent};
  }
  var pre = document.createElement('pre');
  pre.id = 'layout-check';
  pre.textContent = JSON.stringify({width: vw, images: imgs.length, broken: broken,
    tables: tables.length, overflow: bad, hover: hover,
    page_scrolls: document.documentElement.scrollWidth > vw + 1});
  document.body.appendChild(pre);
});
</script>"""


@pytest.mark.skipif(
    CHROMIUM is None,
    reason="Debian's chromium is not installed "
    "(apt-get install chromium) - the report is not rendered in a browser",
)
def test_report_renders_in_headless_chromium(tmp_path, dzh):
    """At 1400 and 800 px wide: every embedded figure loads (the scorecard picture, the
    scenario picture and the three figures), every table sits in a container that scrolls
    instead of widening the page, at 800 px no table is wider than its container (they turn
    into cards), the page itself never scrolls sideways, and the pointer on a line of a figure
    shows that line's configuration; a screenshot of each width is a rendered page (not
    blank)."""
    import html as htmlmod

    run_suite(specs_for(dzh), tmp_path, progress=False)
    from reports.report.build import build_report

    rep = build_report(tmp_path)
    page = rep["html"].read_text()
    n_images = page.count("<img ")
    # the scorecard, the scenario picture and three figures: no rates figure, every
    # configuration staying within 1 % of W over this 1 s (the report says so instead)
    assert n_images == 5 and "No rates figure: the W error of all " in page
    probe = tmp_path / "probe.html"
    probe.write_text(page.replace("</body>", LAYOUT_CHECK + "</body>"))
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
        "--hide-scrollbars",
    ]
    from matplotlib.image import imread

    for width in (1400, 800):
        dom = subprocess.run(
            [CHROMIUM, *flags, f"--window-size={width},1600", "--dump-dom", probe.as_uri()],
            capture_output=True,
            text=True,
            timeout=120,
        ).stdout
        found = re.search(r'<pre id="layout-check">(.*?)</pre>', dom, flags=re.S)
        assert found, f"no layout result in the DOM at {width} px: {dom[-500:]}"
        check = json.loads(htmlmod.unescape(found.group(1)))
        assert check["width"] <= width and check["images"] == n_images, check
        assert check["broken"] == 0, check
        assert check["tables"] >= 5 and check["overflow"] == [], check
        assert not check["page_scrolls"], check
        assert check["hover"] and check["hover"]["shown"] == check["hover"]["line"], check
        shot = tmp_path / f"report_{width}.png"
        subprocess.run(
            [CHROMIUM, *flags, f"--window-size={width},1600", f"--screenshot={shot}",
             rep["html"].as_uri()],
            capture_output=True,
            timeout=120,
        )  # fmt: skip
        img = imread(shot)
        # a rendered page with a coloured scorecard is not a blank (single-colour) image
        assert img.shape[:2] == (1600, width) and img[..., :3].std() > 0.05


def test_dt_that_does_not_divide_the_horizon_is_refused_up_front(tmp_path, capsys):
    """30 s / 7e-3 is not a whole number of steps: exit 2 naming scenario, values and rule,
    and no run starts."""
    out = tmp_path / "o"
    assert main(["run", "dzhanibekov", "--dt", "7e-3", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "dzhanibekov" in err and "dt = 0.007" in err and "whole number of steps" in err
    assert not (out / "results.csv").exists()


@pytest.mark.parametrize("engine,integrator", [("mujoco", "RK4"), ("pinocchio", "RKMK4")])
def test_drifts_of_a_pendulum_released_at_rest_have_their_physical_size(engine, integrator):
    """pendulum_through_vertical starts from rest with its axis horizontal: E0 = 0 (potential
    from the pivot) and L0 = 0. A 4th-order method at dt = 1e-3 keeps energy and momentum to
    far better than 1e-6 of the scenario's scales (measured ~1e-12); a drift divided by E0 or
    |L0| would be inf or nan, one divided by a round-off E0 ~1e4."""
    sc = scenarios.load("pendulum_through_vertical")
    from references.exact import reference_trajectory

    ref = reference_trajectory(sc, [0.0])
    assert ref.energy[0] == 0.0 and np.linalg.norm(ref.angular_momentum[0]) == 0.0
    row = execute(RunSpec(sc, engine, integrator, 1e-3))
    if row["status"] == "unavailable":
        pytest.skip(row["message"])
    assert row["status"] == "ok", row["message"]
    assert 0.0 <= row["energy_drift_max"] < 1e-6
    assert 0.0 <= row["momentum_drift_max"] < 1e-6
    # the exact reference itself: round-off (scale m g l, not E0 = 0)
    exact = execute(RunSpec(sc, "exact", "reference", 1e-3))
    assert exact["energy_drift_max"] < 1e-12 and exact["momentum_drift_max"] < 1e-12


def test_an_error_controlled_run_gets_its_target_accuracy():
    """The planned target accuracy reaches the engine: Drake's runge_kutta5 under error control
    on the Dzhanibekov body over 1 s runs, reads the accuracy back, and lands within 1e3 x the
    target of the exact solution (a local error per unit step of 1e-8 accumulated over 1 s of a
    separatrix-free stretch; without the accuracy the run is refused as 'unsupported')."""
    from references.engines import get_engine

    why = get_engine("drake").availability()
    if why is not None:
        pytest.skip(f"engine 'drake' is not available here: {why}")
    sc = scenarios.load("dzhanibekov").replace(t_end=SHORT, dt_sweep=())
    (spec,) = plan([sc], ["drake"], ["runge_kutta5 (error-controlled)"], accuracies=[1e-8])
    row = execute(spec)
    assert row["status"] == "ok", row["message"]
    assert row["target_accuracy"] == 1e-8
    assert json.loads(row["settings"])["target accuracy"] == 1e-8
    assert row["steps_taken"] > 0
    assert row["attitude_error_max"] < 1e-5


def test_references_are_cached_by_content_not_by_object(dzh):
    """A worker receives a new copy of the scenario with each unit of work: a copy of the same
    content gets the reference already computed, a scenario of other content its own."""
    import pickle

    from reports.run.body import _reference_cached, expected_for, reference_for

    _reference_cached.cache_clear()
    t = np.linspace(0.0, SHORT, 11)
    copy = pickle.loads(pickle.dumps(dzh))
    assert copy is not dzh
    first = reference_for(dzh, t)
    assert reference_for(copy, t) is first
    assert expected_for(copy) is expected_for(dzh)
    other = dzh.replace(omega_body=dzh.omega_body * 1.5)
    ref = reference_for(other, t)
    assert ref is not first and not np.array_equal(ref.omega_body, first.omega_body)
    assert reference_for(dzh, t[:6]) is not first  # other times, another reference
    _reference_cached.cache_clear()


# -- engine versions: planned from package metadata, checked where the runs run -----------------


def _last_json_line_of_fresh_python(code: str):
    """The JSON value on the last line printed by ``code`` run in a new interpreter (so that
    what it imports is not what this test process has imported already)."""
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_planning_imports_no_engine_and_files_each_runs_under_its_own_version():
    """Planning the default suite reads the engines' versions from their packages' metadata
    (no engine imported in the planning process), and each version is the one the engine
    reports once imported (importlib.metadata and the engines' own attributes, read here)."""
    code = (
        "import sys, json\n"
        "from reports.suite import resolve_scenarios\n"
        "from reports.run.plan import plan\n"
        "specs = plan(resolve_scenarios(()), None)\n"
        "versions = {s.engine: s.engine_version for s in specs}\n"
        "engines = ['mujoco', 'pinocchio', 'dartpy', 'pybullet', 'pydrake', 'jax', 'jaxlib']\n"
        "print(json.dumps([versions, [m for m in engines if m in sys.modules]]))\n"
    )
    versions, imported = _last_json_line_of_fresh_python(code)
    assert imported == []
    from importlib.metadata import version

    from references.engines import get_engine

    expected = {"director": version("director-bench"), "exact": version("director-bench")}
    for name, module, attr in (
        ("mujoco", "mujoco", "__version__"),
        ("pinocchio", "pinocchio", "__version__"),
        ("dart", "dartpy", "__version__"),
    ):
        if get_engine(name).availability() is None:
            expected[name] = getattr(__import__(module), attr)
    for name, dist in (("pybullet", "pybullet"), ("drake", "drake")):
        if get_engine(name).availability() is None:
            expected[name] = version(dist)
    for name, v in expected.items():
        assert versions[name] == v, name


def test_a_run_planned_for_another_engine_version_is_an_error_naming_both(tmp_path, dzh):
    from importlib.metadata import version

    spec = RunSpec(dzh, "exact", "reference", dzh.dt, engine_version="0.0.0-planned")
    row = execute(spec, tmp_path)
    assert row["status"] == "error"
    assert "'0.0.0-planned'" in row["message"]
    assert repr(version("director-bench")) in row["message"]
    assert row["engine_version"] == "0.0.0-planned"  # the row keeps its identity


def test_an_engine_missing_from_the_metadata_and_the_path_is_planned_unavailable(monkeypatch, dzh):
    """No metadata (the package is not installed) and no import: the plan's version is
    'unavailable' and the run is an 'unavailable' row saying how to install it."""
    import importlib.metadata as md

    real = md.version

    def version(dist):
        if dist == "mujoco":
            raise md.PackageNotFoundError(dist)
        return real(dist)

    monkeypatch.setattr(md, "version", version)
    monkeypatch.setitem(sys.modules, "mujoco", None)  # `import mujoco` raises
    (spec,) = plan([dzh], ["mujoco"], ["Euler"], dts=[4e-3])
    assert spec.engine_version == "unavailable"
    row = execute(spec, None)
    assert row["status"] == "unavailable" and "pip install mujoco" in row["message"]


def test_the_workers_fork_server_preloads_no_engine():
    """The local workers' fork server imports reports.run.parallel.PRELOAD (and JAX for
    MJX) before it forks them: no engine among them, nor anything they import (an engine
    holds native state that a fork does not carry safely)."""
    code = (
        "import sys, json\n"
        "from reports.run.parallel import PRELOAD\n"
        "for m in (*PRELOAD, 'jax'): __import__(m)\n"
        "engines = ['mujoco', 'pinocchio', 'dartpy', 'pybullet', 'pydrake']\n"
        "print(json.dumps([m for m in engines if m in sys.modules]))\n"
    )
    assert _last_json_line_of_fresh_python(code) == []


def test_what_the_workers_preload_is_known_before_director_model_is_imported():
    """A run starts its workers' fork server once it knows the default engines and what
    their adapters say the workers may preload (reports.suite.run): asking for both imports
    every adapter, and none of them director_model (the director's integrators are made when
    first asked for, references.engines.interface.LazyIntegrators), so that the server's
    imports overlap the main process's own; the director's integrators are still there."""
    code = (
        "import sys, json\n"
        "from reports.suite import default_engines, worker_preload\n"
        "engines, _ = default_engines()\n"
        "worker_preload(engines)\n"
        "before = 'director_model' in sys.modules\n"
        "from references.engines import get_engine\n"
        "names = [i.slug for i in get_engine('director').integrators]\n"
        "print(json.dumps([before, 'director' in engines, names[:2]]))\n"
    )
    assert _last_json_line_of_fresh_python(code) == [False, True, ["rattle", "rattle4"]]


def test_a_lazy_integrator_list_refuses_two_integrators_of_one_typed_name():
    from references.engines.integrators import Integrator
    from references.engines.interface import Engine, LazyIntegrators

    def two():
        fam = "semi-implicit Euler"
        return [Integrator("RK4", fam, 4, "one"), Integrator("rk4", fam, 4, "two")]

    class Twice(Engine):
        name = "twice"
        integrators = LazyIntegrators(two)

    with pytest.raises(ValueError, match="same typed name 'rk4'"):
        Twice.integrators  # noqa: B018 - made on first use, and checked then


def test_each_scene_declares_its_kind_and_every_kind_has_a_stepper():
    """The runner dispatches on the kind a scene declares (``sc.kind``): a single body, a
    system of bodies, bodies in contact; every kind has a stepper that imports."""
    from reports.run.runner import STEPPERS, stepper

    assert set(STEPPERS) == set(scenarios.SCENE_KINDS)
    assert all(callable(stepper(k)) for k in scenarios.SCENE_KINDS)
    kinds = {n: scenarios.load(n).kind for n in ("heavy_top", "four_bar", "block_incline_stick")}
    assert kinds == {"heavy_top": "body", "four_bar": "system", "block_incline_stick": "contact"}
    # a system whose contacts are dropped is a system of bodies again
    sc = scenarios.load("block_incline_stick")
    assert sc.replace(contacts=()).kind == "system" and sc.loop_joints == ()
    heavy_top, four_bar = scenarios.load("heavy_top"), scenarios.load("four_bar")
    assert heavy_top.loop_joints == ()  # one body: no joints, no loops
    assert (heavy_top.n_bodies, four_bar.n_bodies) == (1, 3)


def test_a_scene_stepped_by_a_builder_refuses_a_target_accuracy_and_streaming():
    """Systems of bodies and contact scenes are stepped by an engine's builder at fixed steps,
    with the metrics at the saved states: a spec asking for a target accuracy or for
    --segment streaming is an unsupported row that says so."""
    four_bar, block = scenarios.load("four_bar"), scenarios.load("block_incline_stick")
    rows = [
        execute(RunSpec(four_bar, "mujoco", "rk4", 1e-3, t_end=0.01, accuracy=1e-6)),
        execute(RunSpec(block, "mujoco", "pyramidal", 1e-3, t_end=0.01, segment=5)),
    ]
    for r, what in zip(rows, ("systems of bodies", "contact scenes"), strict=True):
        assert r["status"] == "unsupported", r["message"]
        assert f"{what} run at fixed steps" in r["message"], r["message"]
        assert "no target accuracy, no --segment streaming" in r["message"]


@pytest.mark.parametrize("pool", [False, True])
def test_other_work_is_handed_out_with_the_runs_and_done(tmp_path, dzh, pool):
    """run_suite's ``extra`` (a command's other work, e.g. the importer tables): each job is
    done once, in a worker when there are workers, and gives no row."""
    import functools
    import os

    from reports.run.parallel import process_pool, serial

    specs = specs_for(dzh, engines=("director",))
    made = [tmp_path / "made-1", tmp_path / "made-2"]
    df, n_run = run_suite(
        specs,
        tmp_path / "out",
        progress=False,
        mapper=process_pool(2) if pool else serial(tmp_path / "out"),
        extra=[functools.partial(os.makedirs, p) for p in made],  # a second call would raise
    )
    assert all(p.is_dir() for p in made)
    assert n_run == len(specs) == len(df)
