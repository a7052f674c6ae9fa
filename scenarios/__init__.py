"""Scenarios: declarative descriptions of the standard cases, validated into typed objects.

The library is one TOML file per scenario in this package's directory (see
``docs/scenarios.md`` for the schema)::

    import scenarios
    scenarios.list_scenarios()          # ['cone_top', 'dzhanibekov', ...]
    sc = scenarios.load("dzhanibekov")  # a library name ...
    sc = scenarios.load("my_body.toml") # ... or the path of a user's file
    scenarios.default_suite()           # names of the files tagged "default"
    scenarios.list_systems()            # systems of bodies (files in systems/)
    scenarios.list_contact()            # bodies in contact (files in contact/)
    scenarios.list_robots()             # robot models (files in robots/, ``[model]``)

Invalid files raise :class:`ScenarioError` (a ``ValueError``) naming the file, the field, the
value and the rule.
"""

from __future__ import annotations

from pathlib import Path

from scenarios.model import REFERENCE_KINDS, SCENE_KINDS, Scenario
from scenarios.schema import ScenarioError, did_you_mean
from scenarios.system import SystemBody, SystemJoint, SystemScenario
from scenarios.system_file import validate as _validate_body_or_system


def validate(data: dict, path: str | None = None):
    """A scenario of one body, of a system (``[[bodies]]``) or of a robot model (``[model]``,
    :mod:`scenarios.models.scenario`), validated from parsed TOML ``data``."""
    if isinstance(data, dict) and "model" in data and "bodies" not in data:
        from scenarios.models.scenario import validate_model

        return validate_model(data, path)
    return _validate_body_or_system(data, path)


def load_file(path):
    """Read and validate one scenario file (one body, a system, or a robot model)."""
    from scenarios.schema import read_file

    return validate(read_file(path), path=str(path))


__all__ = [
    "REFERENCE_KINDS",
    "SCENE_KINDS",
    "Scenario",
    "ScenarioError",
    "SystemBody",
    "SystemJoint",
    "SystemScenario",
    "contact_path",
    "default_contact",
    "default_robots",
    "default_suite",
    "default_systems",
    "is_library_file",
    "library_path",
    "list_contact",
    "list_robots",
    "list_scenarios",
    "list_systems",
    "load",
    "robots_path",
    "systems_path",
    "validate",
]


def library_path() -> Path:
    """The directory holding the library's scenario files."""
    return Path(__file__).resolve().parent


def is_library_file(sc) -> bool:
    """Whether the scenario ``sc`` was read from one of the library's files (this package's
    directory or its ``systems/``), which the tests hold to every rule, rather than a user's."""
    if not getattr(sc, "path", None):
        return False
    folder = Path(sc.path).resolve().parent
    return folder in (library_path(), systems_path(), robots_path(), contact_path())


def list_scenarios() -> list[str]:
    """Names of the library's scenarios (file stems), sorted."""
    return sorted(p.stem for p in library_path().glob("*.toml"))


def default_suite() -> list[str]:
    """Names of the library scenarios tagged ``"default"``, sorted."""
    return [name for name in list_scenarios() if "default" in load(name).tags]


def systems_path() -> Path:
    """The directory holding the library's files of systems of bodies (``[[bodies]]``)."""
    return library_path() / "systems"


def list_systems() -> list[str]:
    """Names of the library's systems of bodies (file stems), sorted."""
    return sorted(p.stem for p in systems_path().glob("*.toml"))


def robots_path() -> Path:
    """The directory holding the library's robot-model scenarios (``[model]`` files)."""
    return library_path() / "robots"


def list_robots() -> list[str]:
    """Names of the library's robot-model scenarios (file stems), sorted."""
    return sorted(p.stem for p in robots_path().glob("*.toml"))


def default_robots() -> list[str]:
    """Names of the library's robot-model scenarios tagged ``"default"`` (those whose model
    ships with the suite), sorted. The tags are read from each file as written, without
    reading its model: a model from an optional package that is not installed (the
    ``robots`` extra) keeps neither the default suite nor the catalog from loading."""
    return [
        name for name in list_robots() if "default" in _written_tags(robots_path() / f"{name}.toml")
    ]


def _written_tags(path: Path) -> list:
    """The ``tags`` a scenario file declares, read from the TOML alone; a file that cannot
    be read that way is loaded in full, so that its error is the loader's."""
    import tomllib

    try:
        tags = tomllib.loads(path.read_text(encoding="utf-8-sig")).get("tags", [])
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return list(load_file(path).tags)
    return tags if isinstance(tags, list) else list(load_file(path).tags)


def default_systems() -> list[str]:
    """Names of the library's systems tagged ``"default"``, sorted."""
    return [name for name in list_systems() if "default" in load(name).tags]


def contact_path() -> Path:
    """The directory holding the library's contact scenes (bodies, planes and the pairs that
    touch; docs/scenarios.md, "Contact")."""
    return library_path() / "contact"


def list_contact() -> list[str]:
    """Names of the library's contact scenes (file stems), sorted."""
    return sorted(p.stem for p in contact_path().glob("*.toml"))


def default_contact() -> list[str]:
    """Names of the library's contact scenes tagged ``"default"``, sorted."""
    return [name for name in list_contact() if "default" in load(name).tags]


def load(name_or_path: str | Path) -> Scenario | SystemScenario:
    """Load a scenario: a library name (e.g. ``"dzhanibekov"``) or the path of a ``.toml`` file.

    A string is taken as a path if it ends in ``.toml`` or contains a path separator; otherwise
    as a library name. An unknown name raises :class:`ScenarioError` listing the names
    available.
    """
    if isinstance(name_or_path, Path):
        return load_file(name_or_path)
    s = str(name_or_path)
    if s.endswith(".toml") or "/" in s or "\\" in s:
        return load_file(s)
    path = library_path() / f"{s}.toml"
    if not path.is_file():
        path = systems_path() / f"{s}.toml"
    if not path.is_file():
        path = robots_path() / f"{s}.toml"
    if not path.is_file():
        path = contact_path() / f"{s}.toml"
    if not path.is_file():
        known = list_scenarios() + list_systems() + list_robots() + list_contact()
        raise ScenarioError(
            f"no scenario named {s!r} in the library{did_you_mean(s, known)}; available: "
            f"{', '.join(known)} ({library_path()}). To load a file of your own, pass its path "
            "(ending in .toml)."
        )
    sc = load_file(path)
    if sc.name != s:
        raise ScenarioError(
            f"invalid scenario file {path}: name = {sc.name!r}: a library file's name must "
            f"equal its file name ({s!r})",
            path=str(path),
            problems=[("name", sc.name, "must equal the file name")],
        )
    return sc
