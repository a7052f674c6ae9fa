"""The engine releases CI installs (reports/baselines/engines.txt, pip constraints) are the
ones the committed baseline was made with: each engine's version in the baseline's
provenance is what its adapter makes of the pinned packages (EngineBase.version_of). Writing
the baseline again with another release and forgetting the pin (or the reverse) fails here."""

import json
import re
from pathlib import Path

from references.engines import get_engine

ROOT = Path(__file__).resolve().parents[3]
PINS = ROOT / "reports" / "baselines" / "engines.txt"
BASELINE = ROOT / "reports" / "baselines" / "default.json"


def read_pins(path: Path) -> dict[str, str]:
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"([A-Za-z0-9_.-]+)==([A-Za-z0-9_.+-]+)", line)
        assert m, f"{path}: {line!r} is not an exact pin 'name==version'"
        assert m[1] not in pins, f"{path}: {m[1]} pinned twice"
        pins[m[1]] = m[2]
    return pins


def test_every_engine_of_the_baseline_is_pinned_at_its_release():
    pins = read_pins(PINS)
    engines = json.loads(BASELINE.read_text())["provenance"]["engines"]
    pinned = set()
    for name, version in engines.items():
        adapter = get_engine(name)
        if not adapter.packages:  # ships with the suite (director, exact)
            continue
        missing = [p for p in adapter.packages if p not in pins]
        assert not missing, f"{name}: {missing} not pinned in {PINS.name}"
        assert adapter.version_of(pins) == version, (name, adapter.version_of(pins), version)
        pinned.update(adapter.packages)
    assert pinned == set(pins), f"pinned but no baseline engine uses them: {set(pins) - pinned}"


def test_a_pin_that_differs_from_the_baseline_is_caught():
    """The check above bites: a patch release in the pins is not the baseline's version."""
    pins = read_pins(PINS) | {"mujoco": "4.0.1"}
    engines = json.loads(BASELINE.read_text())["provenance"]["engines"]
    assert get_engine("mujoco").version_of(pins) != engines["mujoco"]


def test_ci_installs_with_the_pins():
    text = (ROOT / ".ci" / "run").read_text()
    assert "-c reports/baselines/engines.txt" in text
