"""docs/scenarios.md's example file loads, and the error messages it shows are the ones the
suite prints for that file with the mistakes the text describes (so the page cannot drift
from the code)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import scenarios
from reports.suite import resolve_scenarios

DOC = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"


def _blocks(text: str) -> list[str]:
    """The code blocks of a Markdown text without a language tag (fences alone on a line)."""
    blocks, current, lang = [], None, None
    for line in text.splitlines():
        if line.startswith("```"):
            if current is None:
                current, lang = [], line[3:].strip()
            else:
                if not lang:
                    blocks.append("\n".join(current))
                current = None
        elif current is not None:
            current.append(line)
    return blocks


def _example() -> str:
    text = DOC.read_text()
    return re.search(r"## Example\n\n```toml\n(.*?)```", text, re.S).group(1)


def _edit(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def _shown(start: str) -> list[str]:
    """The problem lines of the first plain code block of the page that starts with
    ``start``."""
    for block in _blocks(DOC.read_text()):
        if block.startswith(start):
            return [line.strip() for line in block.splitlines()[1:] if line.strip()]
    raise AssertionError(f"no block starting {start!r}")


def test_the_example_loads(tmp_path):
    path = tmp_path / "my_top.toml"
    path.write_text(_example())
    sc = scenarios.load(str(path))
    assert sc.name == "my_top" and sc.pivot is not None


def test_the_validation_message_shown_is_the_suites(tmp_path):
    # the page's box: the example with the moments and the step its message names
    text = _edit(_example(), "inertia = [0.011, 0.011, 0.02]", "inertia = [1.0, 1.0, 2.5]")
    text = _edit(text, "t_end = 4.0", "t_end = 1.0")
    text = _edit(text, "dt = 1e-3\n", "dt = 0.03\n")
    text = _edit(text, "dt_sweep = [4e-3, 2e-3, 1e-3]\n", "")
    path = tmp_path / "box.toml"
    path.write_text(text)
    with pytest.raises(scenarios.ScenarioError) as err:
        scenarios.load(str(path))
    got = [line.strip() for line in str(err.value).splitlines()[1:]]
    assert got == _shown("invalid scenario file /home/me/box.toml")


def test_the_reference_refusal_shown_is_the_suites(tmp_path):
    text = _edit(_example(), "inertia = [0.011, 0.011, 0.02]", "inertia = [0.04, 0.055, 0.07]")
    text = _edit(text, 'kind = "auto"', 'kind = "lagrange_top"')
    path = tmp_path / "my_top.toml"
    path.write_text(text)
    with pytest.raises(scenarios.ScenarioError) as err:
        resolve_scenarios([str(path)])
    got = [line.strip() for line in str(err.value).splitlines()[1:]]
    assert got == _shown("invalid scenario file my_top.toml")
