"""The metric catalog: each metric declared once, its computation attached, every table derived.

The declarations (:data:`METRICS`: name, unit, scale, round-off floor, title, short name,
default tolerance, better direction, single bodies and/or systems, kind) are plain data in
:mod:`scenarios.metric_catalog`, the lowest layer of the suite, because scenario validation
checks the names of a ``[tolerances]`` table and ``scenarios`` may not import ``reports``
(``tests/test_layers.py``). This module attaches to each name how it is computed and derives
every table the later stages use:

- :func:`measures`, a decorator on the function that computes a metric on a scene kind
  (``on``: :data:`scenarios.SCENE_KINDS`, the kinds the metric's declaration applies it to),
  in :mod:`reports.metrics.body` (``on="body"``), :mod:`reports.metrics.system`
  (``on="system"``) or :mod:`reports.metrics.contact` (``on="contact"``). A
  :data:`POINTWISE` function returns the per-sample values, shape (n,),
  or None where the metric does not apply to the scenario (NaN in the results); an
  :data:`OBSERVABLE` function returns one number. It names the arguments it takes among
  ``scenario``, ``traj``, ``ref`` and ``expected`` (the exact observables), and is called
  with those; ``measures`` may fix further keyword arguments. Each of those modules calls
  :func:`check_attached` at its end, so a declared metric without its function, or a
  function of an undeclared one, fails on import.
- :func:`computed`: (metric, function) pairs of a scene kind, for :func:`measure` (the one
  loop that takes every metric of a run of any kind), the streamed maxima and the per-sample
  series;
- the tables: :data:`METRIC_COLUMNS` (store), :data:`FLOORS`, :data:`HIGHER_IS_BETTER`,
  :data:`ORDER_SLACK` (gate, compare, report), :data:`DEFAULT_TOLERANCES` (verdicts),
  :data:`METRIC_TITLES`, :data:`METRIC_SHORT`, :data:`METRIC_UNITS` (report, history),
  :data:`HEADLINE`, :data:`HEADLINE_ENERGY` (the errors a run of each scene kind is summed
  up by),
  :data:`ERROR_PANELS` and :data:`PANEL_TOPS` (errors figure), :data:`SYSTEM_METRICS`,
  :data:`STREAMED`.

Adding a metric: its :class:`Metric` entry in :mod:`scenarios.metric_catalog`, its function
with ``@measures(name)`` and its test (docs/extending.md).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import numpy as np

from scenarios.metric_catalog import (
    METRICS,
    OBSERVABLE,
    POINTWISE,
    SWEEP,
    Metric,
    shown_order,
)
from scenarios.model import SCENE_KINDS

__all__ = [
    "DEFAULT_TOLERANCES",
    "ERROR_PANELS",
    "FLOORS",
    "HEADLINE",
    "HEADLINE_ENERGY",
    "HIGHER_IS_BETTER",
    "METRICS",
    "METRIC_COLUMNS",
    "METRIC_SHORT",
    "METRIC_TITLES",
    "METRIC_UNITS",
    "OBSERVABLE",
    "ORDER_SLACK",
    "PANEL_TOPS",
    "POINTWISE",
    "STREAMED",
    "SWEEP",
    "SYSTEM_METRICS",
    "Metric",
    "by_name",
    "check_attached",
    "computed",
    "largest",
    "measure",
    "measures",
]

#: the arguments a metric function may take, by name
ARGUMENTS = ("scenario", "traj", "ref", "expected")
#: what a metric applies to: the scene kinds (scenarios.SCENE_KINDS, ``sc.kind``)
TARGETS = SCENE_KINDS

_BY_NAME = {m.name: m for m in METRICS}
#: (name, target) -> the function, called with keyword arguments among :data:`ARGUMENTS`
_FUNCTIONS: dict[tuple[str, str], Callable] = {}


def by_name(name: str) -> Metric:
    """The catalog entry of ``name`` (KeyError naming the known metrics otherwise)."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(
            f"{name!r} is not a metric of the catalog; known: {', '.join(_BY_NAME)}"
        ) from None


def measures(name: str, on: str = "body", **fixed) -> Callable:
    """Decorator attaching the function to the catalog as how metric ``name`` is computed on
    the scene kind ``on`` (:data:`TARGETS`: "body", "system" or "contact"); ``fixed`` keyword
    arguments are passed on every call. The function is returned unchanged (it stays callable
    as before)."""

    def attach(fn: Callable) -> Callable:
        where = f"{fn.__module__}.{fn.__qualname__}"
        m = _BY_NAME.get(name)
        if m is None:
            raise ValueError(f"{where}: {name!r} is not declared in scenarios.metric_catalog")
        if on not in TARGETS or not getattr(m, on):
            raise ValueError(f"{where}: {name!r} is not declared as applying to on={on!r}")
        if m.kind not in (POINTWISE, OBSERVABLE):
            raise ValueError(f"{where}: {name!r} is a {m.kind} metric, computed over runs")
        if m.kind == OBSERVABLE and on != "body":
            raise ValueError(f"{where}: {name!r}: exact observables are measured on one body")
        params = set(inspect.signature(fn).parameters) - set(fixed)
        extra = params - set(ARGUMENTS)
        if extra:
            raise ValueError(
                f"{where}: parameters {sorted(extra)} are none of {ARGUMENTS} and not fixed"
            )
        takes = tuple(a for a in ARGUMENTS if a in params)
        if (name, on) in _FUNCTIONS:
            raise ValueError(f"{where}: {name!r} on {on} already has a function")

        def call(scenario, traj, ref=None, expected=None):
            given = {"scenario": scenario, "traj": traj, "ref": ref, "expected": expected}
            return fn(**{a: given[a] for a in takes}, **fixed)

        call.__name__ = call.__qualname__ = f"{name}[{on}]"
        _FUNCTIONS[(name, on)] = call
        return fn

    return attach


def computed(on: str) -> list[tuple[Metric, Callable]]:
    """(metric, function) of every pointwise and observable metric applying to ``on``, in
    catalog order; the function is called ``fn(scenario, traj, ref, expected)``."""
    return [
        (m, _FUNCTIONS[(m.name, on)])
        for m in METRICS
        if getattr(m, on) and m.kind in (POINTWISE, OBSERVABLE)
    ]


def largest(a) -> float:
    """The largest value of a per-sample series: NaN for an empty one, inf when a sample is not
    finite (the run blew up: said so rather than hidden)."""
    a = np.asarray(a)
    if a.size == 0:
        return math.nan
    if not np.all(np.isfinite(a)):
        return math.inf
    return float(np.max(a))


def measure(scenario, traj, ref=None, expected=None, window=None, reduce=largest):
    """The metrics of one run of ``scenario``, whatever its kind: every pointwise and
    observable metric declared for ``scenario.kind`` (:func:`computed`), in catalog order, as
    ``(values, series)``.

    - an observable: its function's number, from the run, the reference and ``expected`` (the
      scenario's exact observables);
    - a metric against the reference: NaN without one (``ref`` None), else ``reduce`` of its
      series over ``window(traj, ref)``: the samples the reference is trusted on (default: the
      run and the reference as given);
    - any other: ``reduce`` of its series, NaN where it does not apply (its function returns
      None).

    ``reduce``: a series to one number (default :func:`largest`). ``series``: metric name ->
    the per-sample series of every pointwise metric computed (None where it does not apply),
    for the run's file."""
    if ref is not None and window is not None:
        inside = window(traj, ref)
    else:
        inside = (traj, ref)
    values, series = {}, {}
    for metric, fn in computed(scenario.kind):
        if metric.kind == OBSERVABLE:
            values[metric.name] = fn(scenario, traj, ref, expected)
            continue
        if metric.reference and ref is None:
            values[metric.name] = math.nan
            continue
        v = fn(scenario, *inside) if metric.reference else fn(scenario, traj, ref)
        values[metric.name] = math.nan if v is None else reduce(v)
        series[metric.name] = v
    return values, series


def check_attached(on: str) -> None:
    """Raise if a metric applying to ``on`` has no function (called once every function of
    ``on`` is defined)."""
    missing = [
        m.name
        for m in METRICS
        if getattr(m, on) and m.kind in (POINTWISE, OBSERVABLE) and (m.name, on) not in _FUNCTIONS
    ]
    if missing:
        raise ImportError(
            f"metrics declared for on={on!r} in scenarios.metric_catalog without a function "
            f"(@measures(name, on={on!r})): {', '.join(missing)}"
        )


# -- tables derived from the catalog ----------------------------------------------------------

#: the store's metric columns, in catalog order
METRIC_COLUMNS = tuple(m.name for m in METRICS)

#: round-off floors: values below these are round-off, compared as equal (gate, compare, report)
FLOORS = {m.name: m.floor for m in METRICS if m.floor is not None}

#: metrics where a larger value is better; every other metric is an error (lower is better)
HIGHER_IS_BETTER = frozenset(m.name for m in METRICS if m.higher_is_better)

#: a fitted convergence order may fall by this much before it counts as a regression
ORDER_SLACK = _BY_NAME["convergence_order"].slack

#: default verdict bounds, every family (metric -> largest value that passes), the errors
#: against the reference trajectory first (a verdict's detail lists the failed metrics in
#: this order), then catalog order
DEFAULT_TOLERANCES = {
    m.name: m.tolerance
    for m in sorted(METRICS, key=lambda m: not m.reference)
    if m.tolerance is not None
}

#: column titles of the metrics in the report, with units, in the order shown
METRIC_TITLES = {m.name: m.title for m in shown_order() if m.title is not None}

#: the unit each metric is shown in: its own, or for a ratio the symbol of its scale ("E_c")
METRIC_UNITS = {m.name: m.per or m.unit for m in METRICS}

#: short names of the metrics in verdict texts (a metric without one is shown by its name)
METRIC_SHORT = {m.name: m.short for m in shown_order() if m.short is not None}

#: the panels of the errors-over-time figure: (series column, y label, scale column, unit)
ERROR_PANELS = tuple(
    (m.series, m.panel, m.scale_column, m.scale_unit)
    for m in shown_order()
    if m.panel is not None and m.series is not None
)

#: the top of each panel's log axis, by series column: beyond it a run has blown up (the runner
#: declares divergence at an energy error of 1 scale; attitude errors end at pi)
PANEL_TOPS = {m.series: m.panel_top for m in METRICS if m.panel is not None}


def _per_kind(field: str) -> dict[str, str]:
    """scene kind -> the one metric whose declaration names it in ``field``."""
    out = {kind: m.name for m in METRICS for kind in getattr(m, field)}
    if sorted(out) != sorted(SCENE_KINDS) or sum(len(getattr(m, field)) for m in METRICS) != len(
        SCENE_KINDS
    ):
        raise ImportError(
            f"scenarios.metric_catalog: each scene kind needs exactly one metric with it in "
            f"{field}, have {[(m.name, getattr(m, field)) for m in METRICS if getattr(m, field)]}"
        )
    return out


#: the error each scene kind (:data:`scenarios.SCENE_KINDS`) is summed up by wherever a run is
#: one number (scorecard, short verdict tables, summary.json, work precision): kind -> metric
HEADLINE = _per_kind("headline")
#: the energy error shown beside it: kind -> metric
HEADLINE_ENERGY = _per_kind("headline_energy")

#: the metrics only systems have
SYSTEM_METRICS = tuple(m.name for m in METRICS if m.system and not m.body)

#: the metrics a single body's streaming recorder folds over every step
STREAMED = tuple(m.name for m in METRICS if m.body and m.kind == POINTWISE)
