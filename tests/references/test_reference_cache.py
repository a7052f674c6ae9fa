"""The reference cache (references.cache): a reference kept by one run is read by the next,
bit for bit; anything it depends on (scenario, times, tolerances, code, library versions)
is in its key, so a change misses; a damaged entry is computed again with one line for the
run's log; it can be switched off; it stays within its size bound. Two planted mistakes (a
key that ignores the times, one that ignores the code's digest) are shown to be caught by
the tests' own checks."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import references.exact as exact_body
import scenarios
from references import cache
from references.engines.exact import system as exact_system

T_END = 0.4  # s: a short run of the spinning chain (a closed form with a Floquet analysis)


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    """An empty cache folder for each test, switched on, and no reference in this process's
    memory."""
    monkeypatch.setenv(cache.ROOT_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(cache.SWITCH_ENV, raising=False)
    exact_system._cached.cache_clear()
    cache.drain()
    yield
    exact_system._cached.cache_clear()


@pytest.fixture(scope="module")
def chain():
    sc = scenarios.load("spinning_chain").replace(t_end=T_END)
    return sc, np.linspace(0.0, T_END, 21)


def computed_count(monkeypatch) -> list:
    """A list that grows by one each time a system reference is computed (not read)."""
    calls = []
    real = exact_system._compute

    def counting(sc, t):
        calls.append(sc.name)
        return real(sc, t)

    monkeypatch.setattr(exact_system, "_compute", counting)
    return calls


def system_ref(sc, t):
    """The system reference as a fresh process would get it (its per-process memory
    emptied first)."""
    exact_system._cached.cache_clear()
    return exact_system.reference(sc, t)


def same_system_reference(a, b, costs: bool = True) -> None:
    """``a`` and ``b`` are the same reference, bit for bit (``costs``: and what computing
    it took)."""
    for f in dataclasses.fields(a):
        timing = ("cpu_time_s", "wall_time_s", "shared_cpu_s")
        if f.name == "trajectory" or (not costs and f.name in timing):
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        assert type(x) is type(y) and x == y, f.name
    for f in ("t", "position", "velocity", "rotation", "omega_body"):
        x, y = getattr(a.trajectory, f), getattr(b.trajectory, f)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), f
    assert a.trajectory.body_names == b.trajectory.body_names


def test_a_kept_reference_is_read_bit_for_bit_and_not_computed_again(chain, monkeypatch):
    sc, t = chain
    calls = computed_count(monkeypatch)
    first = system_ref(sc, t)
    assert calls == [sc.name] and cache.drain()["computed"]
    second = system_ref(sc, t)
    assert calls == [sc.name], "read from the cache, not computed again"
    assert list(cache.drain()) == ["read"]
    same_system_reference(first, second)
    # what computing it took is kept with it: the exact rows' cost (below) is the same
    assert second.cpu_time_s == first.cpu_time_s > 0
    # and the reference read is the reference computed without any cache
    monkeypatch.setenv(cache.SWITCH_ENV, "off")
    same_system_reference(system_ref(sc, t), second, costs=False)


def misses(sc, t, change, monkeypatch) -> bool:
    """Whether the reference of ``sc`` at ``t``, kept by a first call, is computed again
    once ``change(sc, t)`` -> (scenario, times) is applied (``change`` may also patch)."""
    calls = computed_count(monkeypatch)
    system_ref(sc, t)
    sc2, t2 = change(sc, t)
    system_ref(sc2, t2)
    return len(calls) == 2


def other_times(sc, t):
    return sc, np.linspace(0.0, T_END, 41)  # the same span on a finer save grid


def other_scenario(sc, t):
    b0 = sc.bodies[0]
    bodies = (dataclasses.replace(b0, mass=b0.mass * (1 + 1e-15)), *sc.bodies[1:])
    return sc.replace(bodies=bodies), t


def test_the_same_inputs_hit(chain, monkeypatch):
    sc, t = chain
    assert not misses(sc, t, lambda sc, t: (scenarios.load("spinning_chain").replace(
        t_end=T_END), t.copy()), monkeypatch)  # fmt: skip


def test_other_times_miss(chain, monkeypatch):
    assert misses(*chain, other_times, monkeypatch)


def test_another_scenario_misses(chain, monkeypatch):
    sc, _ = chain
    assert other_scenario(sc, None)[0].scenario_hash != sc.scenario_hash
    assert misses(*chain, other_scenario, monkeypatch)


def test_another_tolerance_misses(chain, monkeypatch):
    def tighter(sc, t):
        monkeypatch.setattr(exact_system, "HORIZON_ATTITUDE", exact_system.HORIZON_ATTITUDE / 2)
        return sc, t

    assert misses(*chain, tighter, monkeypatch)


def test_other_code_misses(chain, monkeypatch):
    """An edit of any file of the reference's code is a new digest (checked on a copy of
    the files), and a new digest misses."""
    sc, t = chain

    def edited(sc, t):
        monkeypatch.setattr(cache, "code_version", lambda code=cache.CODE: "edited")
        return sc, t

    assert misses(sc, t, edited, monkeypatch)


def test_an_edit_of_any_reference_source_file_changes_the_code_digest(tmp_path, monkeypatch):
    import shutil

    root = tmp_path / "repo"
    for rel in cache.CODE:
        src = cache._ROOT / rel
        dst = root / rel
        if src.is_dir():
            shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__", "*.toml"))
        else:
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(src, dst)
    monkeypatch.setattr(cache, "_ROOT", root)
    cache.code_version.cache_clear()
    try:
        before = cache.code_version()
        edited = root / "references/exact/multibody/integrate.py"
        edited.write_text(edited.read_text().replace("RTOL = 1e-13", "RTOL = 1e-12"))
        cache.code_version.cache_clear()
        assert cache.code_version() != before
    finally:
        cache.code_version.cache_clear()


def test_other_library_versions_miss(chain, monkeypatch):
    real = cache.versions()

    def newer_numpy(sc, t):
        monkeypatch.setattr(cache, "versions", lambda: {**real, "numpy": "99.0"})
        return sc, t

    assert misses(*chain, newer_numpy, monkeypatch)


@pytest.mark.parametrize("planted", ["times", "code"])
def test_a_key_that_ignores_the_times_or_the_code_is_caught(chain, monkeypatch, planted):
    """The planted mistake: a key that leaves out the times (or the code's digest) hits
    where it must miss, so the checks above (``misses``) would fail."""
    real = cache.key

    def careless(what, scenario_hash, t, tolerances):
        if planted == "times":
            return real(what, scenario_hash, np.zeros(1), tolerances)
        saved = cache.code_version
        cache.code_version = lambda code=cache.CODE: "fixed"
        try:
            return real(what, scenario_hash, t, tolerances)
        finally:
            cache.code_version = saved

    def edited(sc, t):
        monkeypatch.setattr(cache, "code_version", lambda code=cache.CODE: "edited")
        return sc, t

    monkeypatch.setattr(cache, "key", careless)
    assert not misses(*chain, other_times if planted == "times" else edited, monkeypatch)


@pytest.mark.parametrize(
    "damage",
    ["garbage", "truncated", "empty", "another key", "fields"],
)
def test_a_damaged_entry_is_computed_again_with_one_line(chain, monkeypatch, damage):
    sc, t = chain
    good = system_ref(sc, t)
    (k,) = cache.drain()["computed"]
    path = cache._path(k)
    data = path.read_bytes()
    if damage == "garbage":
        path.write_bytes(b"not an npz file" * 10)
    elif damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "empty":
        path.write_bytes(b"")
    elif damage == "another key":  # a file renamed, or a key's name reused
        arrays, fields, cpu, wall = cache.decode(k, data)
        path.write_bytes(cache.encode("0" * 32, arrays, fields, cpu, wall))
    else:  # a field of another type
        arrays, fields, cpu, wall = cache.decode(k, data)
        path.write_bytes(cache.encode(k, arrays, {**fields, "notes": [1, 2]}, cpu, wall))
    calls = computed_count(monkeypatch)
    again = system_ref(sc, t)
    assert calls == [sc.name]
    notes = cache.drain()
    (line,) = notes["lines"]
    assert str(path) in line and "computed again" in line and sc.name in line
    assert notes["computed"] == [k]
    same_system_reference(good, again, costs=False)
    cache.decode(k, path.read_bytes())  # written anew, whole


def test_a_flipped_bit_in_an_array_is_not_trusted(chain):
    """The entry's arrays are checked (the zip's CRC-32): one bit changed in the middle of
    the rotations is an unreadable entry, not a wrong reference."""
    sc, t = chain
    system_ref(sc, t)
    (k,) = cache.drain()["computed"]
    path = cache._path(k)
    data = bytearray(path.read_bytes())
    at = data.find(b"a_R.npy") + 400  # inside the rotations' data
    data[at] ^= 0x01
    path.write_bytes(bytes(data))
    system_ref(sc, t)
    assert len(cache.drain()["lines"]) == 1


def test_switched_off_it_neither_reads_nor_keeps(chain, monkeypatch):
    sc, t = chain
    monkeypatch.setenv(cache.SWITCH_ENV, "off")
    calls = computed_count(monkeypatch)
    system_ref(sc, t)
    system_ref(sc, t)
    assert len(calls) == 2 and not cache.drain()
    assert not cache.folder().exists()


def test_an_unwritable_folder_is_no_error(chain, tmp_path, monkeypatch):
    sc, t = chain
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(cache.ROOT_ENV, str(blocker))  # its "references" folder cannot exist
    ref = system_ref(sc, t)
    assert ref.kind == "spinning_chain"


def test_the_folder_keeps_within_its_bound_the_least_recently_used_removed_first(
    chain, monkeypatch
):
    import os

    sc, t = chain
    keys = []
    for n in (11, 21, 31):
        system_ref(sc, np.linspace(0.0, T_END, n))
        keys += cache.drain()["computed"]
    paths = [cache._path(k) for k in keys]
    for i, p in enumerate(paths):  # written in this order, a second apart
        os.utime(p, (1000.0 + i, 1000.0 + i))
    system_ref(sc, np.linspace(0.0, T_END, 11))  # the oldest, read: used now
    sizes = [p.stat().st_size for p in paths]
    cache.prune(sizes[0] + sizes[2])
    assert paths[0].exists() and not paths[1].exists() and paths[2].exists()
    cache.prune(0)
    assert not any(p.exists() for p in paths)


def test_a_single_bodys_reference_is_kept_bit_for_bit():
    sc = scenarios.load("heavy_top")
    t = np.linspace(0.0, sc.t_end, 101)
    direct = exact_body.reference_trajectory(sc, t)
    first, a = exact_body.reference_kept(sc, t)
    second, b = exact_body.reference_kept(sc, t)
    assert (a["source"], b["source"]) == ("computed", "cache")
    assert a["cpu_s"] == b["cpu_s"] > 0
    for f in dataclasses.fields(direct):
        x, y, z = (getattr(r, f.name) for r in (direct, first, second))
        if isinstance(x, np.ndarray):
            assert x.tobytes() == y.tobytes() == z.tobytes(), f.name
            assert not z.flags.writeable
        else:
            assert x == y == z, f.name


def test_the_exact_rows_cost_is_what_computing_the_reference_took(chain):
    """A system's exact row costs what its reference's computation took (its CPU time),
    the same whether the run computed it or read it from the cache."""
    from references.engines.system import run_system

    sc, _ = chain
    exact_system._cached.cache_clear()
    computed = run_system("exact", sc, "reference", 0.02)
    exact_system._cached.cache_clear()
    read = run_system("exact", sc, "reference", 0.02)
    assert cache.drain().keys() == {"computed", "read"}
    ref = exact_system.reference(sc, computed.trajectory.t)
    assert computed.timing.engine == read.timing.engine == ref.cpu_time_s > 0
    assert computed.timing.wall == read.timing.wall == ref.wall_time_s


def test_each_grids_cost_includes_the_floquet_analysis_its_process_did_for_another(chain):
    """The spinning chain's Floquet analysis is done once per process and scenario, for
    whichever grid comes first; each grid's reference costs it all the same (else the exact
    rows' cost would depend on the order the grids came in: 0.0015 s against 0.38 s)."""
    sc, t = chain
    exact_system._stability.cache_clear()
    first = exact_system.reference(sc, t)
    second = exact_system.reference(sc, np.linspace(0.0, T_END, 41))
    stab_cpu = exact_system._stability(sc.scenario_hash)[1]
    assert stab_cpu > 0
    assert first.cpu_time_s >= stab_cpu and second.cpu_time_s >= stab_cpu
    assert first.shared_cpu_s == 0.0 and second.shared_cpu_s > 0.9 * stab_cpu


def test_computing_a_reference_runs_no_suite_code_outside_the_digest():
    """Every function of the suite that runs while references are computed (every kind: a
    single body's closed forms and numerical reference, a system's closed forms with their
    Floquet analysis and its numerical reference), seen by a profiler hook, is in a file
    whose digest the key holds (cache.CODE): an edit of the code that computes a reference
    can never be forgotten. (What imports run is not counted: a package's ``__init__``
    imports modules whose functions the references never call.)"""
    script = textwrap.dedent(
        """
        import sys, numpy as np
        from pathlib import Path
        import scenarios
        from references.engines.exact import system as ex
        import references.exact as rx
        from references import cache
        ran = set()

        def hook(frame, event, arg):
            code = frame.f_code
            if event == "call" and code.co_name != "<module>":
                ran.add(code.co_filename)

        bodies = [scenarios.load(name) for name in
                  ("heavy_top", "dzhanibekov", "cone_top", "pendulum_through_vertical")]
        systems = [scenarios.load(name).replace(t_end=0.05) for name in
                   ("spinning_chain", "four_bar", "double_pendulum_3d")]

        def compute(n):
            for sc in bodies:
                rx.reference_trajectory(sc, np.linspace(0, min(sc.t_end, 0.2), n))
                rx.reference_trajectory(sc, np.linspace(0, 0.05, n), kind="numerical")
            for sc in systems:
                ex.reference(sc, np.linspace(0, 0.05, n))
            ex._cached.cache_clear()
            ex._stability.cache_clear()

        compute(3)  # the imports (their module and class bodies, decorators) done here
        sys.setprofile(hook)
        compute(5)
        sys.setprofile(None)
        root = cache._ROOT
        suite = {f for f in ran if f.startswith(str(root) + "/") and "/tests/" not in f}
        files = {str(p) for p in cache._files()}
        print("outside:", sorted(Path(f).relative_to(root).as_posix() for f in suite - files))
        print("ran:", len(suite))
        """
    )
    env = {**os.environ, cache.SWITCH_ENV: "off"}  # computed, never read
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True, env=env).stdout  # fmt: skip
    assert "outside: []" in out, out
    assert int(out.split("ran:")[1]) > 10, out  # the hook saw the reference modules


def test_two_processes_writing_one_key_while_a_third_reads_never_show_half_an_entry(tmp_path):
    """Two writers keep the same key over and over (as two workers, or two suites, that
    computed the same reference) while a reader reads it: every read is a whole entry (a
    temporary file renamed over it), never a torn one. (Planted by hand: the entry written in
    place, in 4 kB pieces, the reader saw torn entries: WRITER's "in-place".)"""
    torn, whole = _race(tmp_path, "renamed")
    assert torn == 0 and whole > 0


WRITER = """
import sys, numpy as np
from references import cache
if sys.argv[1] == "in-place":
    def careless(k, data):
        cache.folder().mkdir(parents=True, exist_ok=True)
        with open(cache._path(k), "wb") as fh:
            for i in range(0, len(data), 4096):
                fh.write(data[i:i + 4096])
                fh.flush()
    cache._write = careless
data = cache.encode("k" * 32, {"a": np.arange(100_000, dtype=float)}, {"n": 1}, 0.5, 0.5)
for _ in range(40):
    cache._write("k" * 32, data)
"""

READER = """
import sys, time
from references import cache
torn = whole = 0
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    try:
        data = cache._read("k" * 32)
        if data is not None:
            cache.decode("k" * 32, data)
            whole += 1
    except cache.Unreadable:
        torn += 1
print(torn, whole)
"""


def _race(tmp_path, how: str, seconds: float = 2.0) -> tuple[int, int]:
    """(torn reads, whole reads) of a reader racing two writers of one key (``how``:
    "renamed", the cache's own writes, or "in-place")."""
    env = {**os.environ, cache.ROOT_ENV: str(tmp_path / how)}
    writers = [subprocess.Popen([sys.executable, "-c", WRITER, how], env=env) for _ in range(2)]
    out = subprocess.run([sys.executable, "-c", READER, str(seconds)], env=env,
                         capture_output=True, text=True, check=True).stdout  # fmt: skip
    for w in writers:
        assert w.wait() == 0
    torn, whole = map(int, out.split())
    return torn, whole
