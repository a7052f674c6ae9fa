"""The comparison rule: when a run of one configuration is worse, better or the same as another
run of it (A and B: the committed baseline and the current results for ``director-bench
check``, two results folders for ``director-bench compare``, two engine releases for
``director-bench versions``). Each rule is written here once; the callers decide only what
gates.

- **A metric** (:func:`classify`): an error metric is compared above its round-off floor
  (:data:`reports.metrics.body.FLOORS`: ``max(value, floor)`` on both sides), so that 3e-16
  against 9e-15 is ``same``: ``worse`` when B is more than ``factor`` times A, ``better`` when
  less than A / ``factor``. The fitted convergence order (higher is better) is compared by
  difference, :data:`reports.metrics.body.ORDER_SLACK`. A value B lost is ``worse``; one it
  gained is ``same``.
- **A status** (:func:`status_change`): ranked by :data:`STATUS_RANK`; ``unsupported`` and
  ``unavailable`` rank below every run that ran (for the gate, an engine the baseline ran and
  this machine cannot is a regression; ``compare`` treats them as the environment).
- **A cost** (:func:`cost_range`, :func:`classify_cost`, :func:`at_every_dt`): a range
  measured with the run, significant only beyond the factor AND beyond the measured spread
  (after airspeed velocity's ``asv compare``), and only when every dt of the configuration's
  sweep moved the same way (the engine's own change moves every step size; a burst of load on
  the machine single runs).

- **An engine release** (:class:`VersionChange`): a run of the same configuration and run
  identity on another release of the engine is the same run on a new release, compared by
  the rules above; the pairs are counted per release change, so that a patch release shows
  as ``mujoco 4.0.0 -> 4.0.1: 196 runs compared, 0 changed``.

The outcome of a comparison of one configuration is a :class:`Change`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from reports.metrics.catalog import FLOORS, HIGHER_IS_BETTER, METRIC_COLUMNS, ORDER_SLACK
from reports.store.format import num

#: statuses in order of how bad they are for a run that should have run; a status not listed
#: ranks as :data:`UNKNOWN_RANK`
STATUS_RANK = {
    "ok": 0,
    "reference-inaccurate": 1,
    "diverged": 2,
    "error": 3,
    "unsupported": 4,
    "unavailable": 4,
}
UNKNOWN_RANK = 5

#: the statuses of a run that ran (the others say what the environment could not do)
RAN = ("ok", "reference-inaccurate", "diverged", "error")

#: cost columns compared (ns per step: the CPU time inside the engine's calls, and of the
#: whole step), each with the column of the slowest repeat's time that bounds its range
COST_COLUMNS = ("engine_ns_per_step", "ns_per_step")
COST_MAX = {"engine_ns_per_step": "engine_time_max_s", "ns_per_step": "cpu_time_max_s"}
#: the same for rows written before the costs were CPU times (ns_per_step was the wall's)
COST_MAX_WALL = {"engine_ns_per_step": "engine_time_max_s", "ns_per_step": "wall_time_max_s"}

#: words of a change that count against B (with ``worse``: a run that is not the same run, a
#: run of A that B lacks, a run of B the baseline lacks)
AGAINST = ("worse", "mismatch", "missing", "new")


class NothingComparable(RuntimeError):
    """The two sides share no run (an empty folder, disjoint runs): nothing was compared,
    which is never a pass."""


@dataclass
class Change:
    """One comparison of a configuration ``key`` (:func:`reports.store.runs.config_key`)
    between A and B.

    ``column``: the metric or cost column, ``status``, ``verdict``, ``failed checks``,
    ``identity`` (a mismatch: ``b`` names the fields that differ) or ``""`` (a run found on
    one side only); ``a``, ``b``: the two values (text for a status or a reason); ``ratio``:
    B/A (NaN where it means nothing); ``change``: ``better``, ``worse``, ``same``, ``not
    significant`` (a cost change within the measured noise), ``mismatch``, ``missing`` (in A
    only) or ``new`` (in B only); ``gates``: whether it makes the command fail."""

    key: tuple
    column: str
    a: object
    b: object
    ratio: float = math.nan
    change: str = "same"
    gates: bool = False

    @property
    def worse(self) -> bool:
        return self.change in AGAINST

    @property
    def what(self) -> str:
        """The kind of change: metric, status, verdict, mismatch, missing or new."""
        if self.change in ("mismatch", "missing", "new"):
            return self.change
        if self.column == "status":
            return "status"
        if self.column in ("verdict", "failed checks"):
            return "verdict"
        return "metric"


@dataclass
class VersionChange:
    """The runs of one engine compared across a release change (``a`` -> ``b``): a new patch
    release is not a new run, so the pairs are compared as usual and counted here.
    ``identical``: runs whose status, verdict and every metric are bit for bit the same;
    ``regressed`` / ``better``: runs with a regression / an improvement beyond the rule."""

    engine: str
    a: str
    b: str
    compared: int = 0
    identical: int = 0
    regressed: int = 0
    better: int = 0

    @property
    def changed(self) -> int:
        return self.regressed + self.better

    def line(self) -> str:
        """``mujoco 4.0.0 -> 4.0.1: 196 runs compared, 0 changed (196 identical in every
        metric, 0 regressed, 0 better)``."""
        return (
            f"{self.engine} {self.a} -> {self.b}: {self.compared} runs compared, "
            f"{self.changed} changed ({self.identical} identical in every metric, "
            f"{self.regressed} regressed, {self.better} better)"
        )


def identical_metrics(a, b) -> bool:
    """Whether two rows (or baseline entries) have the same status, verdict and every metric
    (:data:`reports.metrics.catalog.METRIC_COLUMNS`) bit for bit, missing values alike."""
    if a.get("status") != b.get("status") or a.get("verdict") != b.get("verdict"):
        return False
    for m in METRIC_COLUMNS:
        x, y = num(a.get(m)), num(b.get(m))
        if not (x == y or (math.isnan(x) and math.isnan(y))):
            return False
    return True


def count_version_change(cmp: Comparison, key, a, b, changes: list[Change]) -> None:
    """Count the pair (``a``, ``b``) of configuration ``key`` in ``cmp.versions`` when the two
    ran on different releases of the engine (``engine_version``); ``changes``: what the
    comparison found for the pair."""
    va, vb = str(a.get("engine_version") or "none"), str(b.get("engine_version") or "none")
    if va == vb:
        return
    vc = cmp.versions.setdefault((key[1], va, vb), VersionChange(key[1], va, vb))
    vc.compared += 1
    if any(c.worse and c.gates for c in changes):
        vc.regressed += 1
    elif any(c.change == "better" for c in changes):
        vc.better += 1
    if identical_metrics(a, b):
        vc.identical += 1


@dataclass
class Comparison:
    """The comparison of results B against A: ``check``'s against a baseline file (A), or
    ``compare``'s of two folders.

    ``compared``: the configurations compared, in order; ``changes``: every :class:`Change`
    found (``check`` records only the regressions); ``only_a``, ``only_b``: (key, status) of
    the runs in one folder only (``compare``; the gate records them as changes ``missing``
    and ``new``); ``known``: the runs failing as in the baseline, key -> (reason now, reason
    in the baseline); ``cost_factor``: the factor a cost is gated at (None: not gated);
    ``vary``: identity columns allowed to differ; ``provenance_a``: the baseline's;
    ``versions``: the release changes of the engines, (engine, a, b) -> :class:`VersionChange`."""

    a: str
    b: str
    factor: float
    cost_factor: float | None = None
    vary: tuple = ()
    compared: list = field(default_factory=list)
    changes: list = field(default_factory=list)
    only_a: list = field(default_factory=list)
    only_b: list = field(default_factory=list)
    known: dict = field(default_factory=dict)
    provenance_a: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)

    def version_lines(self) -> list[str]:
        """One line per engine release change (:meth:`VersionChange.line`)."""
        return [v.line() for v in self.versions.values()]

    @property
    def regressions(self) -> list[Change]:
        return [c for c in self.changes if c.worse and c.gates]

    @property
    def ok(self) -> bool:
        return not self.regressions

    @property
    def regressed(self) -> list[tuple]:
        """The configurations with at least one regression, in order of the first."""
        return list(dict.fromkeys(c.key for c in self.regressions))

    def for_key(self, key) -> list[Change]:
        return [c for c in self.regressions if c.key == key]


def ratio_change(ratio: float, factor: float) -> str:
    """``worse`` above ``factor``, ``better`` below 1 / ``factor``, else ``same``."""
    if ratio > factor:
        return "worse"
    return "better" if ratio < 1.0 / factor else "same"


def classify(column: str, a, b, factor: float) -> tuple[float, str] | None:
    """(ratio B/A, better/worse/same) of one metric or cost, or None when neither side has a
    value (see the module docstring). ``factor`` may be ``math.inf``: then only a lost value
    is ``worse``."""
    a, b = num(a), num(b)
    if math.isnan(a) and math.isnan(b):
        return None
    if math.isnan(b):
        return math.nan, "worse"
    if math.isnan(a):
        return math.nan, "same"
    if column in HIGHER_IS_BETTER:
        ratio = b / a if a else math.nan
        if b < a - ORDER_SLACK:
            return ratio, "worse"
        return ratio, ("better" if b > a + ORDER_SLACK else "same")
    floor = FLOORS.get(column, 0.0)
    ea, eb = max(a, floor), max(b, floor)
    if ea == eb:
        return 1.0, "same"
    ratio = eb / ea if ea else math.inf
    return ratio, ratio_change(ratio, factor)


def status_change(a: str, b: str) -> str:
    """From status ``a`` to ``b``: ``worse`` or ``better`` by :data:`STATUS_RANK`, ``same``
    when equal, ``changed`` when different at the same rank."""
    if a == b:
        return "same"
    ra, rb = STATUS_RANK.get(a, UNKNOWN_RANK), STATUS_RANK.get(b, UNKNOWN_RANK)
    return "worse" if rb > ra else "better" if rb < ra else "changed"


def starved(row) -> bool:
    """Whether a run's engine time was measured starved (:func:`reports.store.runs.starved`):
    its cost changes are ``starved``, never worse."""
    from reports.store.runs import starved as measured_starved

    return measured_starved(row)


def cost_range(row, column: str) -> tuple[float, float, float, bool]:
    """The cost of a run in ``column`` (ns per step): (kept timing, the range's low end,
    its high end, whether it was measured starved). The kept timing is the least engine time
    among the repeats that ran clean (reports.store.results.timing_columns); the range runs
    from it less its uncertainty (``engine_time_spread_s``, the engine's CPU time only) to
    the slowest repeat. Rows written before the costs were CPU times: the low end is the
    fastest repeat scaled by the process's CPU time over its wall time (the engine's own
    cost may be that much lower than the clock says). Without a CPU time and with a single
    timing the spread is unknown: low and high are NaN."""
    fastest = num(row.get(column))
    n = num(row.get("nstep"))
    per = 1e9 / n if n and n > 0 else math.nan
    spread = num(row.get("engine_time_spread_s"))
    if not math.isnan(spread):  # CPU times (references.engines.timing)
        width = spread * per if column == "engine_ns_per_step" else 0.0
        hi = num(row.get(COST_MAX[column])) * per
        hi = max(fastest + width, fastest if math.isnan(hi) else hi)
        return fastest, max(fastest - width, 0.0), hi, starved(row)
    wall, cpu = num(row.get("wall_time_s")), num(row.get("cpu_time_s"))
    repeats = num(row.get("timing_repeats"))
    if math.isnan(cpu) and not repeats >= 2:
        return fastest, math.nan, math.nan, False
    hi = num(row.get(COST_MAX_WALL[column])) * per
    hi = fastest if math.isnan(hi) else max(hi, fastest)
    share = cpu / wall if wall > 0 else math.nan
    lo = fastest * share if 0.0 <= share < 1.0 else fastest
    return fastest, lo, hi, False


def classify_cost(a, b, factor: float) -> tuple[float, str] | None:
    """(ratio of the kept timings B/A, word) of a cost measured on each side as (kept, low,
    high[, starved]) (:func:`cost_range`; low and high NaN: the spread was not measured).
    After asv's rule (a change beyond the factor whose ranges do not overlap), taken at the
    ranges' nearest ends: ``worse`` only when the ratio exceeds ``factor`` AND so does B's
    low end over A's high end (``better``: B's high end below A's low end over the factor);
    ``starved`` when the ratio is beyond the factor and a side was measured starved (its
    engine time is not known well enough to tell); ``not significant`` when the ratio is
    beyond the factor but the ranges allow less, or a side's spread was not measured (a
    change cannot be told from noise that was not measured); ``same`` within the factor."""
    a_starved = bool(a[3]) if len(a) > 3 else False
    b_starved = bool(b[3]) if len(b) > 3 else False
    (a_fast, a_lo, a_hi), (b_fast, b_lo, b_hi) = (
        tuple(num(v) for v in side[:3]) for side in (a, b)
    )
    if math.isnan(a_fast) and math.isnan(b_fast):
        return None
    if math.isnan(a_fast) or math.isnan(b_fast) or a_fast <= 0:
        return math.nan, "same"
    ratio = b_fast / a_fast
    if 1.0 / factor <= ratio <= factor:
        return ratio, "same"
    if a_starved or b_starved:
        return ratio, "starved"
    if any(math.isnan(v) for v in (a_lo, a_hi, b_lo, b_hi)):
        return ratio, "not significant"
    if ratio > factor:
        return ratio, ("worse" if b_lo > factor * a_hi else "not significant")
    return ratio, ("better" if factor * b_hi < a_lo else "not significant")


def at_every_dt(words) -> str | None:
    """The one word every dt of a sweep gives a cost (``worse``, ``better``, ``same`` ...),
    or None when they differ or there are none. A cost change of a configuration counts only
    where this is ``worse`` or ``better``: the engine's own change moves the cost per step at
    every step size; a burst of load on the machine hits single runs, and a run's measured
    spread cannot show load that came and went between two of its repeats."""
    words = set(words)
    return words.pop() if len(words) == 1 else None


def corroborate_costs(changes: list[Change]) -> None:
    """Keep a cost change only where every step size of its sweep moved the same way
    (:func:`at_every_dt`): a ``worse`` (``better``) cost at one dt stays so only when that
    cost column is ``worse`` (``better``) at every dt of the configuration (scenario, engine,
    integrator) the two sides share; otherwise it is ``not significant``. A configuration run
    at one dt only is judged on that run."""
    groups: dict = {}
    for c in changes:
        if c.column in COST_COLUMNS:
            groups.setdefault((c.key[:3], c.column), []).append(c)
    for group in groups.values():
        if at_every_dt(c.change for c in group) is None:
            for c in group:
                if c.change in ("worse", "better"):
                    c.change = "not significant"


def failing(r) -> bool:
    """True when a row is a failing test case (a failed verdict or a fault of the suite)."""
    return r.get("verdict") == "fail" or r.get("status") == "error"


def failed_checks(r) -> set[str]:
    """The checks a row fails: the metric names of its verdict detail (``"attitude_error_max
    0.5 > 0.1; ..."``), or its status when it did not run to the end."""
    if r.get("status") != "ok":
        return {str(r.get("status"))} if failing(r) else set()
    detail = str(r.get("verdict_detail", "") or "")
    return {part.split()[0] for part in detail.split("; ") if part.strip()}


def verdict_change(a, b) -> tuple[str, str, str]:
    """How run ``b``'s verdict compares with run ``a``'s when both ran to the end: ``("verdict",
    "worse" | "better", "")`` when it went from pass to fail or back; ``("failed checks",
    "worse", names)`` when a failing run fails checks it did not fail before (``a`` may be a
    baseline entry, which keeps its failed checks as a list); ``("", "same", "")`` otherwise.
    The one rule for ``check`` and ``compare``."""
    va, vb = a.get("verdict"), b.get("verdict")
    if {va, vb} == {"pass", "fail"}:
        return "verdict", ("worse" if vb == "fail" else "better"), ""
    if va == vb == "fail":
        before = a.get("failed_checks")
        before = set(before) if isinstance(before, (list, tuple, set)) else failed_checks(a)
        new = failed_checks(b) - before
        if new:
            return "failed checks", "worse", ", ".join(sorted(new))
    return "", "same", ""
