"""An engine from another package: the example adapter in examples/solve_ivp_engine, installed
with pip into a separate folder, is found through its entry point, listed and run by the CLI,
and passes the conformance kit, with no change to this repository."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "solve_ivp_engine"


@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory):
    """An environment in which the example package is installed (pip --target a folder on
    PYTHONPATH: its entry point is visible to importlib.metadata there only)."""
    target = tmp_path_factory.mktemp("site")
    proc = subprocess.run(
        [
            sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
            "--no-build-isolation", "--disable-pip-version-check", "--target", str(target),
            str(EXAMPLE),
        ],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    if proc.returncode != 0:
        pytest.fail(f"pip could not install the example adapter:\n{proc.stderr[-2000:]}")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(target), env.get("PYTHONPATH")]))
    return env


def cli(env, *args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "reports.cli", *args],
        capture_output=True, text=True, env=env, timeout=600, cwd=cwd,
    )  # fmt: skip


def test_the_plugin_is_listed(plugin_env):
    proc = cli(plugin_env, "list", "--json")
    assert proc.returncode == 0, proc.stderr
    engines = {e["name"]: e for e in json.loads(proc.stdout)["engines"]}
    assert engines["solve_ivp"]["available"]
    names = [i["name"] for i in engines["solve_ivp"]["integrators"]]
    assert names == ["RK45 fixed step", "RK23 fixed step", "RKMK4"]


def test_the_plugin_runs_a_library_scenario(plugin_env, tmp_path):
    out = tmp_path / "out"
    proc = cli(
        plugin_env, "run", "free_tumbling", "--engines", "solve_ivp,exact", "--t-end", "1",
        "--no-sweep", "--out", str(out), "--quiet", "--jobs", "1", "--no-report",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    import pandas as pd

    df = pd.read_csv(out / "results.csv")
    mine = df[df["engine"] == "solve_ivp"]
    assert sorted(mine["integrator"]) == ["RK23 fixed step", "RK45 fixed step", "RKMK4"]
    assert set(mine["status"]) == {"ok"} and set(mine["verdict"]) == {"pass"}
    # RK45 at dt = 1e-3 on a smooth free body: far below the 0.1 rad tolerance (order 5 on
    # h |W| = 2.6e-3: the measured error is ~1e-13, the reference's accuracy ~1e-13)
    assert mine["attitude_error_max"].max() < 1e-9


def test_the_plugin_runs_systems_of_bodies(plugin_env, tmp_path):
    """The plug-in's adapter declares a system builder (examples/solve_ivp_engine/
    solve_ivp_system.py): a spherical double pendulum (a tree, measured against the suite's
    reduced-coordinate DOP853 reference) and a four-bar (a closed loop of revolute joints,
    measured against its closed form) run through the entry point like a built-in engine's
    systems, and agree with those references to the order of their methods."""
    out = tmp_path / "out"
    proc = cli(
        plugin_env, "run", "double_pendulum_3d", "four_bar", "--engines", "solve_ivp,exact",
        "--t-end", "0.2", "--no-sweep", "--out", str(out), "--quiet", "--jobs", "1",
        "--no-report",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    import pandas as pd

    df = pd.read_csv(out / "results.csv")
    mine = df[df["engine"] == "solve_ivp"].set_index(["scenario", "integrator"])
    for scenario in ("double_pendulum_3d", "four_bar"):
        for method in ("RK45 fixed step", "RK23 fixed step"):
            row = mine.loc[(scenario, method)]
            assert row["status"] == "ok" and row["verdict"] == "pass", row["message"]
            assert row["reference_kind"] in ("numerical", "four_bar")
        rk45, rk23 = (
            mine.loc[(scenario, "RK45 fixed step")],
            mine.loc[(scenario, "RK23 fixed step")],
        )
        # a 5th-order method at h |W| ~ 3e-3 over 200 steps: errors ~ (3e-3)^5 x 200 ~ 1e-10 at
        # most, measured 2e-13 (the pendulum) and 5e-14 (the four-bar); the 3rd-order method
        # (3e-3)^3 x 200 ~ 5e-6 at most, measured 2e-9 and 5e-8: 100x above RK45 at least
        assert rk45["attitude_error_max"] < 1e-10
        assert 100 * rk45["attitude_error_max"] < rk23["attitude_error_max"] < 5e-6
        # nothing but the equations holds the joints: their gaps are the integration error
        assert rk45["joint_gap_max"] < 1e-10 and rk23["joint_gap_max"] < 5e-6
        # the suite's RKMK4 is a single-body integrator: refused for systems, with the reason
        rkmk4 = mine.loc[(scenario, "RKMK4")]
        assert rkmk4["status"] == "unsupported" and "RK45 fixed step" in rkmk4["message"]


def test_the_plugin_passes_the_conformance_kit(plugin_env):
    code = (
        "from references.engines import get_engine\n"
        "from references.engines.conformance import assert_conforms\n"
        "assert_conforms(get_engine('solve_ivp'))\n"
        "print('conforms')\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=plugin_env, timeout=600
    )
    assert proc.returncode == 0 and "conforms" in proc.stdout, proc.stderr[-3000:]


def test_a_plugin_cannot_take_a_builtin_name(plugin_env, tmp_path):
    """A package registering an entry point named like a built-in engine does not replace
    it: the registry keeps the built-in."""
    code = (
        "from importlib.metadata import EntryPoint\n"
        "import references.engines as e\n"
        "import importlib.metadata as md\n"
        "orig = md.entry_points\n"
        "def fake(group=None):\n"
        "    return [EntryPoint('mujoco', 'solve_ivp_engine:SolveIvpEngine', group)]\n"
        "md.entry_points = fake\n"
        "e._registry.cache_clear()\n"
        "print(e.get_engine('mujoco').__name__)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=plugin_env, timeout=120
    )
    assert proc.stdout.strip() == "MujocoEngine", proc.stderr
