"""The layer contract: data flows one way, director_model -> scenarios -> references -> reports.

Every import of the suite's packages, at module level or inside a function, is read from the
source (ast) and checked: no package imports one above it, and no two modules import each
other, directly or through others. The checker is shown to fail on a planted upward import and
a planted cycle, so the contract cannot pass by accident.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: the layers, lowest first; a package may import only its own layer and those below
LAYERS = ("director_model", "scenarios", "references", "reports")

#: the stages inside ``reports``, lowest first, under the same rule: metrics, then the results
#: store, then the runner, the report, the gate (check and compare), the suite that strings
#: them together, the engine-version matrix, and the command line on top. ``reports`` itself
#: (the package's face: its version) sits below them all.
STAGES = (
    "reports.metrics",
    "reports.store",
    "reports.run",
    "reports.report",
    "reports.gate",
    "reports.suite",
    "reports.versions",
    "reports.cli",
)


def module_name(path: Path, root: Path) -> str:
    rel = path.relative_to(root).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path, root: Path, modules: set[str]) -> set[str]:
    """The suite modules ``path`` imports (absolute and relative imports, at any depth):
    ``from pkg import name`` imports the module ``pkg.name`` when there is one, else ``pkg``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    here = module_name(path, root).split(".")
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here if is_pkg else here[:-1]
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                sub = f"{mod}.{a.name}"
                out.add(sub if sub in modules else mod)
    return {m for m in out if m.split(".")[0] in LAYERS}


def graph(root: Path) -> dict[str, set[str]]:
    """module -> the suite modules it imports (a name that is not a module is mapped to the
    package or module that defines it)."""
    files = {module_name(p, root): p for pkg in LAYERS for p in (root / pkg).rglob("*.py")}
    g = {}
    for mod, path in files.items():
        deps = set()
        for name in imports_of(path, root, set(files)):
            while name and name not in files:
                name = name.rpartition(".")[0]
            if name and name != mod:
                deps.add(name)
        g[mod] = deps
    return g


def upward_imports(g: dict[str, set[str]]) -> list[str]:
    out = []
    for mod, deps in g.items():
        rank = LAYERS.index(mod.split(".")[0])
        for d in deps:
            if LAYERS.index(d.split(".")[0]) > rank:
                out.append(f"{mod} imports {d} (a layer above it)")
    return sorted(out)


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(g):
        if v not in index:
            visit(v)
    return out


# -- the contract on the suite ------------------------------------------------------------------


def test_no_package_imports_a_layer_above_it():
    assert upward_imports(graph(ROOT)) == []


def stage_of(mod: str) -> int | None:
    """The rank of the ``reports`` stage ``mod`` belongs to (-1 for ``reports`` itself), or None
    outside ``reports``."""
    if mod == "reports":
        return -1
    for i, stage in enumerate(STAGES):
        if mod == stage or mod.startswith(stage + "."):
            return i
    return None


def upward_stage_imports(g: dict[str, set[str]]) -> list[str]:
    out = []
    for mod, deps in g.items():
        rank = stage_of(mod)
        if rank is None:
            continue
        for d in deps:
            other = stage_of(d)
            if other is not None and other > rank:
                out.append(f"{mod} imports {d} (a stage above it)")
    return sorted(out)


def test_every_reports_module_belongs_to_a_stage():
    g = graph(ROOT)
    assert [m for m in g if m.startswith("reports") and stage_of(m) is None] == []


def test_no_reports_stage_imports_a_stage_above_it():
    assert upward_stage_imports(graph(ROOT)) == []


def test_no_import_cycles():
    assert cycles(graph(ROOT)) == []


def test_director_model_imports_nothing_of_the_suite():
    g = graph(ROOT)
    outside = {d for m, deps in g.items() if m.startswith("director_model") for d in deps}
    assert all(d.startswith("director_model") for d in outside), outside


# -- the checker fails when it should -----------------------------------------------------------


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for pkg in LAYERS:
        (tmp_path / pkg).mkdir()
        (tmp_path / pkg / "__init__.py").write_text("")
    for rel, text in files.items():
        (tmp_path / rel).write_text(text)
    return tmp_path


def test_an_upward_import_is_caught(tmp_path):
    root = _tree(
        tmp_path,
        {
            "scenarios/model.py": "def f():\n    from reports.metrics import energy\n",
            "reports/metrics.py": "energy = 1\n",
        },
    )
    assert upward_imports(graph(root)) == [
        "scenarios.model imports reports.metrics (a layer above it)"
    ]


def test_an_upward_stage_import_is_caught(tmp_path):
    root = _tree(
        tmp_path,
        {
            "reports/metrics.py": "def f():\n    from reports.store import rows\n",
            "reports/store.py": "rows = 1\n",
        },
    )
    assert upward_stage_imports(graph(root)) == [
        "reports.metrics imports reports.store (a stage above it)"
    ]


def test_a_cycle_is_caught(tmp_path):
    root = _tree(
        tmp_path,
        {
            "reports/runner.py": "from reports.streaming import run\n",
            "reports/streaming.py": "from . import runner\nrun = 1\n",
        },
    )
    assert cycles(graph(root)) == [["reports.runner", "reports.streaming"]]


@pytest.mark.parametrize("layer", LAYERS)
def test_every_layer_has_modules(layer):
    assert any(m.startswith(layer) for m in graph(ROOT))
