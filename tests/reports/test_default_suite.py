"""What the default suite runs on this machine: MJX only where JAX sees an accelerator (the
product decision of issue 31: on a CPU it runs one instance at a time at hundreds of times
MuJoCo's cost, after tens of seconds of compilation), listed with the reason and the flag
that adds it."""

from __future__ import annotations

import json
import subprocess
import sys

from references.engines import engine_names
from references.engines.mjx import adapter as mjx_adapter
from reports.suite import check_engines, default_engines, run


def test_mjx_is_left_out_where_jax_sees_no_accelerator_and_in_where_it_sees_one(monkeypatch):
    monkeypatch.setattr(mjx_adapter, "accelerator", lambda: None)
    engines, left_out = default_engines()
    assert "mjx" not in engines and list(left_out) == ["mjx"]
    assert "no accelerator" in left_out["mjx"]
    assert engines == [e for e in engine_names() if e != "mjx"]
    assert default_engines(every=True) == (engine_names(), {})  # --full
    assert check_engines(["all"]) == engine_names() == check_engines(["ALL"])
    monkeypatch.setattr(mjx_adapter, "accelerator", lambda: "gpu")
    assert default_engines() == (engine_names(), {})


def test_no_accelerator_plugin_means_no_accelerator_without_importing_jax():
    code = (
        "import sys\nfrom references.engines.mjx.adapter import accelerator, ACCELERATOR_PLUGINS\n"
        "from importlib.metadata import version, PackageNotFoundError\n"
        "def has(n):\n    try:\n        version(n); return True\n"
        "    except PackageNotFoundError:\n        return False\n"
        "print(accelerator(), any(map(has, ACCELERATOR_PLUGINS)), 'jax' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    got, plugin, imported = out.stdout.split()
    if plugin == "True":  # a machine with a GPU or TPU plugin: JAX is asked
        return
    assert (got, imported) == ("None", "False")


def test_jax_platforms_cpu_means_no_accelerator(monkeypatch):
    monkeypatch.setenv("JAX_PLATFORMS", "cpu")
    monkeypatch.setattr(mjx_adapter, "ACCELERATOR_PLUGINS", ("numpy",))  # "installed"
    assert mjx_adapter.accelerator() is None


def test_a_default_run_says_what_it_left_out_and_why(tmp_path, monkeypatch):
    monkeypatch.setattr(mjx_adapter, "accelerator", lambda: None)
    summary = run(
        ["cone_top"], integrators=["Euler"], dts=[1e-3], t_end=0.01, out=tmp_path,
        report=False, progress=False, jobs=1,
    )  # fmt: skip
    assert set(summary.results["engine"]) == {"mujoco"}  # not MJX's Euler
    assert list(summary.left_out) == ["mjx"]
    prov = json.loads((tmp_path / "provenance.json").read_text())
    assert list(prov["left_out"]) == ["mjx"] and "mjx" not in prov["engines"]
