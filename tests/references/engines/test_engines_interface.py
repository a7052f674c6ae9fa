"""The engine interface declares every hook (references/engines/interface.py), docs/engines.md
lists each one with the engines that override it, and the declared defaults do what they say:
batching, the reference flag, the packed forward dynamics and the scheme facts the director
adapter reads from director_model's declarations.

A missing engine is skipped with the reason its adapter gives (never faked).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import scenarios
from references.engines import (
    BUILTIN,
    BodyModel,
    Diverged,
    EngineError,
    RunContext,
    RunOutput,
    StepFailure,
    Unsupported,
    get_engine,
    reference_engine_names,
)
from references.engines.interface import Engine, EngineBase

DOC = Path(__file__).resolve().parents[3] / "docs" / "engines.md"


def engine_or_skip(name: str):
    cls = get_engine(name)
    why = cls.availability()
    if why is not None:
        pytest.skip(f"engine {name!r} is not available here: {why}")
    return cls()


def interface_hooks() -> list[str]:
    """The public members of EngineBase and Engine, declared or annotated, in order."""
    out: list[str] = []
    for cls in (EngineBase, Engine):
        for n in [*cls.__annotations__, *vars(cls)]:
            if not n.startswith("_") and n not in out:
                out.append(n)
    return out


def documented_hooks() -> dict[str, list[str]]:
    """hook -> the engines the table of docs/engines.md ("The interface's hooks") says
    override it."""
    text = DOC.read_text()
    section = text.split("### The interface's hooks", 1)[1]
    rows = {}
    for line in section.splitlines():
        if not line.startswith("| `"):
            if rows:
                break  # the end of the table
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        name = re.match(r"`([A-Za-z_]+)", cells[0]).group(1)
        who = cells[-1]
        rows[name] = [] if who == "none" else [w.strip() for w in who.split(",")]
    return rows


def overriders(hook: str) -> list[str]:
    """The built-in engines whose adapter class (or a class between it and the interface)
    defines ``hook``."""
    out = []
    for name in BUILTIN:
        for k in get_engine(name).__mro__:
            if k in (Engine, EngineBase):
                break
            if hook in vars(k):
                out.append(name)
                break
    return out


def test_the_documented_hooks_are_the_interface():
    documented = documented_hooks()
    assert sorted(documented) == sorted(interface_hooks())


@pytest.mark.parametrize("hook", interface_hooks())
def test_the_documented_overrides_are_the_adapters(hook):
    if any(get_engine(n).__name__.startswith("Unloadable_") for n in BUILTIN):
        pytest.skip("an adapter does not load here; its overrides cannot be read")
    assert sorted(documented_hooks()[hook]) == sorted(overriders(hook))


def test_the_table_parser_sees_a_drifted_table(tmp_path, monkeypatch):
    """The comparison can fail: a hook missing from the table, and a wrong override list."""
    text = DOC.read_text()
    missing = text.replace("| `batched` |", "| `batching` |")
    monkeypatch.setitem(globals(), "DOC", tmp_path / "engines.md")
    (tmp_path / "engines.md").write_text(missing)
    assert sorted(documented_hooks()) != sorted(interface_hooks())
    wrong = re.sub(r"(\| `guard\(ctx, state\)` .*\| )mujoco, pybullet \|", r"\1mujoco |", text)
    (tmp_path / "engines.md").write_text(wrong)
    assert documented_hooks()["guard"] == ["mujoco"] != sorted(overriders("guard"))


def test_step_failure_declares_where_it_happened():
    exc = StepFailure("no step")
    assert (exc.time, exc.steps_taken, exc.states) == (None, None, None)
    exc = StepFailure("no step", time=0.25, steps_taken=3)
    assert (exc.time, exc.steps_taken) == (0.25, 3) and str(exc) == "no step"


def test_the_reference_is_declared_by_its_adapter():
    assert reference_engine_names() == [n for n in BUILTIN if get_engine(n).is_reference]
    assert get_engine("exact").is_reference
    assert not any(get_engine(n).is_reference for n in BUILTIN if n != "exact")


def _members():
    """Two heavy tops of one body: a calm one, and the library's, on which semi-implicit
    Euler at dt = 0.004 s diverges (its energy error passes the scenario's scale)."""
    sc = scenarios.load("heavy_top")
    calm = sc.replace(name="calm", omega_body=np.array(sc.omega_body) * 0.01)
    return sc, [calm, sc]


def test_default_run_batch_is_a_loop_that_keeps_every_member():
    engine = engine_or_skip("pinocchio")
    assert not type(engine).batched
    sc, members = _members()
    outs = engine.run_batch(members, "semi-implicit Euler", 0.004, sc.t_end, sc.save_every)
    assert isinstance(outs[0], RunOutput) and isinstance(outs[1], Diverged)
    alone = engine.run(members[0], "semi-implicit Euler", 0.004, sc.t_end, sc.save_every)
    assert np.array_equal(alone.trajectory.rotation, outs[0].trajectory.rotation)
    with pytest.raises(Diverged) as info:
        engine.run(members[1], "semi-implicit Euler", 0.004, sc.t_end, sc.save_every)
    assert str(info.value) == str(outs[1])
    with pytest.raises(Unsupported, match="no integrator"):
        engine.run_batch(members, "leapfrog", 0.004, sc.t_end, sc.save_every)


def test_director_run_batch_is_each_member_s_own_run():
    """director_model's batched path, each member bit for bit its single run (the same
    compiled step, director_model's claim for simulate_batch, checked here through the
    adapter); members of different bodies are refused, naming the field."""
    engine = engine_or_skip("director")
    assert type(engine).batched
    sc = scenarios.load("dzhanibekov").replace(t_end=0.5)
    members = [
        sc.replace(name=f"m{k}", omega_body=np.array(sc.omega_body) * (1 + 0.1 * k))
        for k in range(3)
    ]
    outs = engine.run_batch(members, "rattle4", sc.dt, 0.5, 5)
    for m, out in zip(members, outs, strict=True):
        alone = engine.run(m, "rattle4", sc.dt, t_end=0.5, save_every=5)
        assert np.array_equal(alone.trajectory.rotation, out.trajectory.rotation)
        assert np.array_equal(alone.trajectory.omega_body, out.trajectory.omega_body)
        assert (out.nstep, out.evals_per_step) == (alone.nstep, alone.evals_per_step)
    heavier = members[1].replace(mass=2 * sc.mass)
    with pytest.raises(EngineError, match="member 1 .* in mass"):
        engine.run_batch([members[0], heavier], "rattle4", sc.dt, 0.5, 5)


def test_director_batch_refused_when_a_member_cannot_be_stepped():
    """RATTLE has no step for h |W| >= 1 (a principal-axis spin): director_model stops the
    whole batched call, which is the batch's EngineError."""
    engine = engine_or_skip("director")
    sc = scenarios.load("dzhanibekov").replace(t_end=0.5)
    fast = sc.replace(name="fast", omega_body=[0.0, 0.0, 2.0 / sc.dt])
    with pytest.raises(EngineError) as info:
        engine.run_batch([sc, fast], "rattle", sc.dt, 0.5, 5)
    assert type(info.value) is EngineError and info.value.status == "error"


@pytest.mark.parametrize("pivoted", [False, True])
def test_default_packed_dynamics_is_the_engine_s_forward_dynamics(pivoted):
    """The interface's default packed_dynamics (a BodyState from the flat stage state, then
    forward_dynamics) agrees with Pinocchio's staged call (the compiled packing of its
    stages, aba, the compiled unpacking) to round-off: 1e-12 of the accelerations' size, a
    few ulps of the two conversions (rotation matrix against the compiled packing). Both
    time the engine's call on the run's clock."""
    from references.engines import _rkmk4

    engine = engine_or_skip("pinocchio")
    sc = scenarios.load("heavy_top" if pivoted else "dzhanibekov")
    integ = engine.integrator("RKMK4")
    ctx = RunContext(sc, BodyModel.of(sc, sc.dt), integ, sc.dt, sc.t_end)
    engine.build(ctx)
    rng = np.random.default_rng(1)
    q = rng.normal(size=4)
    z = np.concatenate([q / np.linalg.norm(q), rng.normal(size=9)])
    sd, default_fd = engine.staged_dynamics(ctx), Engine.packed_dynamics(engine, ctx)
    assert engine.packed_dynamics(ctx) is not None and sd is not None

    def own_fd(z, acc):
        _rkmk4.pack_pinocchio(z, pivoted, *_rkmk4.pinocchio_buffers(sd.workspace, pivoted))
        _rkmk4.unpack_pinocchio(z, pivoted, sd.call(), acc)

    own, default = np.full(6, np.nan), np.full(6, np.nan)
    own_fd(z, own)
    assert ctx.clock.elapsed > 0
    timed = ctx.clock.elapsed
    default_fd(z, default)
    assert ctx.clock.elapsed > timed
    assert np.all(np.isfinite(own)) and np.abs(own).max() > 0
    assert np.abs(own - default).max() <= 1e-12 * np.abs(own).max()
    if pivoted:
        assert np.array_equal(default[3:], np.zeros(3))
    # and a planted mistake is seen: the body rates read in another order
    z_bad = z.copy()
    z_bad[7:10] = z[[8, 9, 7]]
    wrong = np.zeros(6)
    default_fd(z_bad, wrong)
    assert np.abs(own - wrong).max() > 1e-6 * np.abs(own).max()


def test_director_schemes_declare_their_cost_and_promises():
    """Evaluations per step from the schemes' own declarations against the literature's
    stage counts: RATTLE 1, Yoshida's triple jump 3 (Yoshida 1990), Kahan and Li's s9odr6a 9
    (Kahan & Li 1997), the energy-momentum midpoint 1; the momentum promise on the RATTLE
    compositions only (docs/numerics.md section 3)."""
    integs = {i.name: i for i in get_engine("director").integrators}
    evals = {n: i.evals_per_step for n, i in integs.items()}
    assert evals == {"rattle": 1.0, "rattle4": 3.0, "rattle6": 9.0, "energy_momentum": 1.0}
    for n in ("rattle", "rattle4", "rattle6"):
        assert dict(integs[n].tolerances) == {"momentum_drift_max": 1e-10}
    assert dict(integs["energy_momentum"].tolerances) == {}


def test_an_integrator_s_family_on_a_ball_is_declared_and_true():
    """MuJoCo declares that implicitfast runs its Euler step on a ball joint: the run records
    that family for a pivoted body (and its own for a free one), and the declaration holds,
    the trajectories are bit for bit Euler's on the heavy top."""
    from references.engines import Integrator

    engine = engine_or_skip("mujoco")
    top = scenarios.load("heavy_top").replace(t_end=0.2)
    fast = engine.run(top, "implicitfast", top.dt)
    euler = engine.run(top, "Euler", top.dt)
    assert fast.family == "semi-implicit Euler"
    assert fast.settings["family of the algorithm run"] == "semi-implicit Euler"
    assert np.array_equal(fast.trajectory.rotation, euler.trajectory.rotation)
    free = scenarios.load("dzhanibekov").replace(t_end=0.2)
    assert engine.run(free, "implicitfast", free.dt).family == "implicit gyroscopic"
    with pytest.raises(ValueError, match="unknown family 'leapfrog'"):
        Integrator("x", "semi-implicit Euler", 1, "x", family_on_a_ball="leapfrog")
