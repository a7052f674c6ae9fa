"""The two configurations a robot model runs in through an engine's importer, and how they
read in an integrator's name: "as loaded" (the importer's defaults, as a user would load the
file) and "faithful" (the settings that make the importer read the file as written). Declared
here, in the scenario stage, so that the engines that run them and the report that groups
their rows read one rule."""

from __future__ import annotations

#: the importer configurations, in the order they are planned
CONFIGS = ("as-loaded", "faithful")

#: how a configuration reads in an integrator's name ("RK4 (as loaded)")
CONFIG_WORDS = {"as-loaded": "as loaded", "faithful": "faithful"}


def variant(integrator: str, config: str) -> str:
    """The name of ``integrator`` run through the engine's importer in ``config``: "RK4 (as
    loaded)", "Euler (float64, faithful)"."""
    word = CONFIG_WORDS[config]
    if integrator.endswith(")"):
        return f"{integrator[:-1]}, {word})"
    return f"{integrator} ({word})"


def split_variant(name: str) -> tuple[str, str | None]:
    """(integrator, configuration) of a name made by :func:`variant`; (name, None) for any
    other name."""
    for config, word in CONFIG_WORDS.items():
        for tail in (f" ({word})", f", {word})"):
            if name.endswith(tail):
                base = name[: -len(tail)] + ("" if tail.startswith(" ") else ")")
                return base, config
    return name, None
