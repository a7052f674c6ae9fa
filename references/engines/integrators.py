"""Integrators and their families: what an engine offers, each declared with what it costs
(dynamics evaluations per step) and what it promises (verdict bounds beyond its family's).

A :class:`Family` groups integrators that share an algorithm (so engines running it should
agree) with the default bounds its members are held to; :data:`FAMILIES` is the registry,
which other packages extend with :func:`register_family`. An :class:`Integrator` is one
configuration an adapter offers, named for what it is; :func:`slug` is the one rule for the
form of its name a shell types.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

# -- integrator families ----------------------------------------------------------------------


@dataclass(frozen=True)
class Family:
    """A class of integrators that share an algorithm (so engines running it should agree),
    with the default verdict tolerances its members are held to (metric -> bound; see
    :mod:`reports.metrics.verdicts` for the defaults every family shares)."""

    name: str
    description: str
    tolerances: Mapping[str, float] = field(default_factory=dict)


#: Integrator families, name -> :class:`Family`. Engines from other packages may add their own
#: with :func:`register_family` (families are data, not code).
FAMILIES: dict[str, Family] = {}


def register_family(family: Family) -> Family:
    """Add ``family`` to :data:`FAMILIES` (idempotent for an equal family; a different family
    under a taken name is an error)."""
    old = FAMILIES.get(family.name)
    if old is not None and old != family:
        raise ValueError(f"integrator family {family.name!r} is already registered differently")
    FAMILIES[family.name] = family
    return family


for _fam in (
    Family("semi-implicit Euler", "first order, gyroscopic term explicit"),
    Family("implicit gyroscopic", "first order, gyroscopic term linearised implicitly"),
    Family("4th-order Lie-group", "explicit Runge-Kutta(-Munthe-Kaas) class, order 4 on SO(3)"),
    Family(
        "structure-preserving director",
        "symplectic / energy-momentum schemes of the director model; they keep the directors "
        "orthonormal to round-off",
        # every scheme of the family enforces the position constraints at the nodes (docs
        # docs/numerics.md section 3): 1e-10 is round-off accumulated over ~1e5 steps with margin
        {"orthonormality_max": 1e-10},
    ),
    Family(
        "exact",
        "closed-form or high-accuracy reference solution",
        {"energy_drift_max": 1e-9, "momentum_drift_max": 1e-9, "orthonormality_max": 1e-12},
    ),
):
    register_family(_fam)


def slug(name: str) -> str:
    """The form of an integrator's name a shell can type, the one rule for every engine: lower
    case, and every run of characters other than letters, digits, ``_`` and ``.`` one ``-``,
    none at either end ("semi-implicit Euler" -> ``semi-implicit-euler``, "runge_kutta5
    (error-controlled)" -> ``runge_kutta5-error-controlled``, "RK4 (float32)" ->
    ``rk4-float32``). The command line matches a name given in either form through it, so
    matching ignores case; an engine's integrators have distinct slugs (checked when the
    adapter class is defined)."""
    return re.sub(r"[^a-z0-9_.]+", "-", name.lower()).strip("-")


@dataclass(frozen=True)
class Integrator:
    """An integrator an engine offers, named for what it is.

    ``stepping``: "native" (the engine's own time stepping, :meth:`Engine.advance`) or "rkmk4"
    (the suite's Runge-Kutta-Munthe-Kaas around :meth:`Engine.forward_dynamics`).
    ``evals_per_step``: dynamics evaluations per step (forward dynamics, or torque evaluations
    of the director schemes), None if it varies (error-controlled integrators report theirs).
    ``options``: engine-specific settings of this integrator (recorded with the run).
    ``ours``: the time loop is the suite's code around the engine's dynamics even though the
    adapter runs it (Pinocchio has no integrator of its own); cost tables label such
    configurations, since their cost includes our Python.
    ``tolerances``: verdict bounds this integrator promises beyond its family's (metric ->
    bound), e.g. RATTLE's conservation of angular momentum to round-off.
    ``adaptive``: an error-controlled integrator, run at target accuracies (``accuracy`` of
    :meth:`Engine.run`); ``dt`` is then the interval of the checkpoints, not a step, and the
    adapter reports the steps it took (``ctx.stats``, ``ctx.nevals``).
    ``default``: part of the default suite; an engine with many configurations keeps the
    ones that answer the suite's questions at a cost that fits, the rest run on request
    (``director-bench run --full`` or ``--integrators``).
    ``family_on_a_ball``: the family of the algorithm the engine actually runs on a pivoted
    body (a ball joint), where it differs from ``family`` (MuJoCo's implicitfast drops the
    gyroscopic derivative on a ball joint, which leaves its Euler step); the run records it
    (``RunContext.family``) and its verdicts follow it.
    """

    name: str
    family: str
    order: int
    description: str
    stepping: str = "native"
    evals_per_step: float | None = 1.0
    options: Mapping[str, Any] = field(default_factory=dict)
    ours: bool = False
    tolerances: Mapping[str, float] = field(default_factory=dict)
    adaptive: bool = False
    default: bool = True
    family_on_a_ball: str | None = None

    def __post_init__(self):
        for fam in (self.family, self.family_on_a_ball):
            if fam is not None and fam not in FAMILIES:
                raise ValueError(
                    f"integrator {self.name!r}: unknown family {fam!r}; register it with "
                    "references.engines.register_family"
                )
        if self.stepping not in ("native", "rkmk4"):
            raise ValueError(f"integrator {self.name!r}: stepping must be 'native' or 'rkmk4'")

    @property
    def suite_integrated(self) -> bool:
        """True when the time integration is the suite's code around the engine's dynamics."""
        return self.ours or self.stepping != "native"

    @property
    def slug(self) -> str:
        """The name as a shell types it (:func:`slug`); ``name`` is the display name."""
        return slug(self.name)
