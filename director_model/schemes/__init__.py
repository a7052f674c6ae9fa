"""Registry of integration schemes by name (``SCHEMES``): adding a scheme is one new module
and one line here."""

from __future__ import annotations

from director_model.schemes.base import Scheme
from director_model.schemes.composition import Rattle4, Rattle6
from director_model.schemes.energy_momentum import EnergyMomentum
from director_model.schemes.rattle import Rattle

SCHEMES: dict[str, type[Scheme]] = {
    cls.name: cls for cls in (Rattle, Rattle4, Rattle6, EnergyMomentum)
}

__all__ = ["SCHEMES", "Scheme", "Rattle", "Rattle4", "Rattle6", "EnergyMomentum"]
