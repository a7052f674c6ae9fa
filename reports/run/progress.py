"""Progress of a batch of runs on standard error, for a terminal and for a log.

In a terminal, one line redrawn in place: the count, a bar, the time so far (redrawn every
second by a clock thread, so it never stands still while a worker compiles), an estimate of
the time left and what finished last or what is compiling. Anywhere else (CI, a pipe, a file)
plain lines, never a carriage return: one when the work starts (what loads or compiles
first), one per finished group of work (a scenario, when the runner names them; else a tenth
of the work), and one at the end, so that a log of the default suite holds about a dozen lines.

The first run of some engines in a process loads compiled code first, or compiles it where
the compiler's on-disk cache does not hold it (the director model's and the suite's RKMK4
numba kernels, MJX's step with JAX); compiling, such a run takes seconds where the others
take milliseconds. The runner names these warm-ups (``warming``: key -> what compiles) and
says which key each finished run belongs to; until the first run of every key has finished,
the display says what loads or compiles (which of the two, a run only knows once it has
done it) and gives no estimate. A warm-up at the start of a bundle
of runs that finish together (MJX's) is only named at the start (``bundled``): its end is not
seen before the whole bundle's.

The estimate (:class:`Estimate`): runs differ in cost by three orders of magnitude (a
thousand steps of MuJoCo against thirty thousand of a Runge-Kutta in Drake), so counting runs
misleads. Each unit of work has a size (its number of steps) and a configuration (engine,
integrator, body or system); the seconds each finished run took in its worker give a rate per
configuration (seconds per step), the runs not finished are priced at their configuration's
rate (the median rate of the configurations seen for one not seen yet: the rates span orders
of magnitude, and a mean is one expensive configuration's), and the time left is that price
over the throughput since the warm-ups ended (seconds of runs finished per second, about the
number of busy workers). Runs that compiled are left out of both. A unit of work that costs a
share of its group's runs (a scenario's timing pass, reports.run.timing: a budget in
proportion to the CPU time its runs spent) is priced as that share of the group's runs, those
finished at what they took; once such units have finished, at the share they actually took
(a budget is a bound: a pass spends less).
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import threading
import time
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass

#: what a warm-up does, as the display says it: numba and JAX load what their on-disk cache
#: holds (filled by ``director-bench compile``, or by an earlier run) and compile the rest,
#: and which of the two a run will do is not known before it does it
LOADED_OR_COMPILED = "loaded from the compiler's cache or compiled"
LOADING_OR_COMPILING = "loading or compiling"
#: a terminal line is redrawn at most this often (s) for a running run's own progress, and
#: at least this often by the clock thread
REDRAW_S = 0.2
#: the clock thread's period in a terminal (s)
TICK_S = 1.0
#: outside a terminal and without groups, a line every this fraction of the work
LOG_STEP = 0.1
#: no estimate before this many runs have finished since the warm-ups ended, nor before
#: this many seconds have passed since: a rate from one run is a guess
ETA_MIN_RUNS = 3
ETA_MIN_S = 2.0


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


@dataclass(frozen=True)
class Item:
    """One unit of the work as the estimate sees it: its ``group`` (a scenario: a log line
    when the last of its items finishes), its ``config`` (items of one config cost alike per
    unit of size) and its ``size`` (e.g. its number of steps, > 0). ``share`` > 0: the item
    costs that share of the seconds of its group's other items (a timing pass), not a rate of
    its config."""

    group: str
    config: Hashable
    size: float
    share: float = 0.0


class Estimate:
    """The time left from the items finished so far (see the module docstring)."""

    def __init__(self, items: Mapping[Hashable, Item]):
        self.items = dict(items)
        self.left = set(self.items)
        self.seconds: dict[Hashable, float] = {}  # config -> seconds of its measured runs
        self.sizes: dict[Hashable, float] = {}  # config -> size of its measured runs
        self.took: dict[Hashable, float] = {}  # item -> its seconds, when measured
        self.shares: dict[Hashable, float] = {}  # share item -> its seconds, when measured
        self.since = 0.0  # seconds of the runs measured since the origin
        self.n_since = 0
        self.members: dict[str, list] = {}  # group -> its items that are not a share
        for key, it in self.items.items():
            if not it.share:
                self.members.setdefault(it.group, []).append(key)

    def finished(self, item, seconds: float | None, measured: bool, counts: bool) -> None:
        """``item`` finished after ``seconds`` in its worker; ``measured``: its time is a
        run's (it compiled nothing); ``counts``: it finished after the origin."""
        self.left.discard(item)
        it = self.items.get(item)
        if it is None or seconds is None or not measured or not seconds >= 0:
            return
        if it.share:
            self.shares[item] = seconds
        else:  # a share is priced from its group, not as a rate of its config
            self.took[item] = seconds
            self.seconds[it.config] = self.seconds.get(it.config, 0.0) + seconds
            self.sizes[it.config] = self.sizes.get(it.config, 0.0) + it.size
        if counts:
            self.since += seconds
            self.n_since += 1

    def left_s(self, elapsed: float) -> float | None:
        """Seconds left, ``elapsed`` seconds after the origin; None when too little is known."""
        if self.n_since < ETA_MIN_RUNS or elapsed < ETA_MIN_S or not self.took:
            return None
        # what every run pays whatever its size (building the model, the reference, the
        # metrics, the files): about the quickest run measured
        fixed = min(self.took.values())
        extra: dict[Hashable, float] = {}
        for key, secs in self.took.items():
            c = self.items[key].config
            extra[c] = extra.get(c, 0.0) + secs - fixed
        rates = {c: extra[c] / self.sizes[c] for c in extra if self.sizes[c] > 0}
        if not rates:
            return None
        ordered = sorted(rates.values())
        mid = len(ordered) // 2
        unseen = ordered[mid] if len(ordered) % 2 else (ordered[mid - 1] + ordered[mid]) / 2

        def price(key) -> float:
            it = self.items[key]
            return fixed + it.size * rates.get(it.config, unseen)

        def group_seconds(group: str) -> float:
            return sum(self.took.get(k, price(k)) for k in self.members.get(group, ()))

        # the share the finished share items took of their groups, once there are some
        spent = sum(self.shares.values())
        of = sum(group_seconds(self.items[k].group) for k in self.shares)
        taken = spent / of if of > 0 else None
        total = 0.0
        for k in self.left:
            it = self.items[k]
            if it.share:
                total += (it.share if taken is None else taken) * group_seconds(it.group)
            else:
                total += price(k)
        throughput = self.since / elapsed  # seconds of runs per second: the busy workers
        return total / throughput if throughput > 0 else None


class Clock:
    """A step that counts nothing, shown with a running clock (planning the runs, which loads
    the scenarios and, for a system of bodies, times a pilot run of its reference: from a
    fresh clone that compiles the multibody reference first).

    In a terminal, ``text [m:ss]`` redrawn every :data:`TICK_S` by a thread until the block
    ends, then erased (the progress display of the work takes the line); :meth:`note` prints
    a line above it. Anywhere else nothing but the notes (a log needs no clock: its next line
    says when the work starts). ``disable``: notes only."""

    def __init__(self, text: str, stream=None, terminal: bool | None = None, disable=False):
        self.text = text
        self.stream = sys.stderr if stream is None else stream
        if terminal is None:
            isatty = getattr(self.stream, "isatty", None)
            terminal = bool(isatty and isatty())
        self.terminal = terminal and not disable
        self.t0 = time.monotonic()
        self._width = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker = None

    def __enter__(self) -> Clock:
        if self.terminal:
            self._draw()
            self._ticker = threading.Thread(target=self._tick, daemon=True, name="clock")
            self._ticker.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
            self._ticker = None
        if self.terminal:
            with self._lock:
                self._erase()
                self.stream.flush()

    def note(self, text: str) -> None:
        """A line of its own (above the clock in a terminal)."""
        with self._lock:
            if self.terminal:
                self._erase()
            self.stream.write(text + "\n")
            if self.terminal and not self._stop.is_set():
                self._draw()
            self.stream.flush()

    def _tick(self) -> None:
        while not self._stop.wait(TICK_S):
            with self._lock:
                self._draw()

    def _draw(self) -> None:
        width = shutil.get_terminal_size((80, 24)).columns - 1
        line = f"{self.text} [{_clock(time.monotonic() - self.t0)}]"[:width]
        self.stream.write("\r" + line.ljust(self._width))
        self.stream.flush()
        self._width = len(line)

    def _erase(self) -> None:
        self.stream.write("\r" + " " * self._width + "\r")
        self._width = 0


class Progress:
    """Progress of ``total`` units of work (runs) on ``stream`` (default: standard error).

    ``update(n, key, label, item, seconds, outcome)`` counts ``n`` finished units of warm-up
    key(s) ``key`` (or None); ``item``: which one finished (a key of ``items``), ``seconds``
    the time it took, ``outcome`` a word counted in its group's line (e.g. its verdict).
    ``set_postfix_str(text)`` shows what is running (a terminal only); ``close()`` ends the
    display. ``items``: {item: :class:`Item`} of the whole work (the estimate and the
    per-group lines; without them the estimate counts units and a log gets a line per tenth).
    ``terminal``: draw in place (default: whether ``stream`` is a terminal); ``disable``:
    show nothing. No work (``total`` 0) shows nothing either."""

    def __init__(
        self,
        total: int,
        desc: str = "director-bench",
        unit: str = "run",
        warming: Mapping[str, str] | None = None,
        stream=None,
        terminal: bool | None = None,
        disable: bool = False,
        bundled: Mapping[str, str] | Sequence[str] = (),
        items: Mapping[Hashable, Item] | None = None,
    ):
        # nothing to show: no work, or the caller asked for quiet
        self.total = 0 if disable else max(int(total), 0)
        self.desc, self.unit = desc, unit
        self.stream = sys.stderr if stream is None else stream
        if terminal is None:
            isatty = getattr(self.stream, "isatty", None)
            terminal = bool(isatty and isatty())
        self.terminal = terminal
        self.warming = dict(warming or {})
        # warm-ups at the start of bundles: named until a row of their bundle arrives
        self.bundled = dict(bundled) if isinstance(bundled, Mapping) else dict.fromkeys(bundled)
        self.bundled = {k: (v if v is not None else k) for k, v in self.bundled.items()}
        self.n = 0
        self.t0 = time.monotonic()
        # the estimate's origin: the end of the warm-ups (the start if there are none)
        self.t_warm = self.t0 if not self.warming else None
        self.n_warm = 0
        self.items = dict(items or {})
        self.estimate = Estimate(self.items) if self.items else None
        self.groups: dict[str, int] = {}  # group -> items not finished
        for it in self.items.values():
            self.groups[it.group] = self.groups.get(it.group, 0) + 1
        self.outcomes: dict[str, dict[str, int]] = {}
        self.postfix = ""
        self.logged = 0  # tenths of the work reported outside a terminal
        self._drawn = 0.0
        self._width = 0
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._ticker = None
        if not self.total:
            return
        if not self.terminal:
            first = f"{self.desc}: {self.total} {self.unit}s"
            if self.groups:
                first += f" in {len(self.groups)} groups" if len(self.groups) > 1 else ""
            if self.warming:
                first += f"; first, {LOADED_OR_COMPILED}: " + ", ".join(self.warming.values())
            if self.bundled:
                first += "; at the start of their bundles: " + ", ".join(self.bundled.values())
            self._line(first)
        else:
            self._draw()
            self._ticker = threading.Thread(target=self._tick, daemon=True, name="progress")
            self._ticker.start()

    # -- the interface the runner uses ---------------------------------------------------------

    def update(
        self,
        n: int = 1,
        key: str | Sequence[str] | None = None,
        label: str = "",
        item: Hashable | None = None,
        seconds: float | None = None,
        outcome: str = "",
    ) -> None:
        """``n`` more units finished; ``key``: their warm-up key or keys (those compilations
        are over); ``label``: what finished (shown in a terminal); ``item``, ``seconds``,
        ``outcome``: which item of ``items`` finished, how long it took, what came of it."""
        if not self.total:
            return
        with self._lock:
            self.n += n
            keys = (key,) if isinstance(key, str) else tuple(key or ())
            ended = [k for k in keys if self.warming.pop(k, None) is not None]
            compiled = bool(ended) | any([self.bundled.pop(k, None) is not None for k in keys])
            if self.estimate is not None and item is not None:
                # a run that ended a warm-up compiled: its time is not a run's
                self.estimate.finished(item, seconds, not compiled, self.t_warm is not None)
            if ended and not self.warming:
                self.t_warm, self.n_warm = time.monotonic(), self.n
            if label:
                self.postfix = label
            group = self.items[item].group if item in self.items else None
            done_group = None
            if group is not None:
                if outcome:
                    counts = self.outcomes.setdefault(group, {})
                    counts[outcome] = counts.get(outcome, 0) + 1
                self.groups[group] -= 1
                if self.groups[group] == 0:
                    done_group = group
            if self.terminal:
                self._draw()
            elif self.groups:
                if done_group is not None:
                    self._line(self._group_line(done_group))
            else:
                tenth = int(self.n / self.total / LOG_STEP + 1e-9) if self.total else 0
                if tenth > self.logged and self.n < self.total:
                    self.logged = tenth
                    self._line(self._status())

    def set_postfix_str(self, text: str, refresh: bool = True) -> None:
        """What is running now (a run's own progress); a terminal shows it, a log does not."""
        with self._lock:
            self.postfix = text
            now = time.monotonic()
            if self.total and self.terminal and refresh and now - self._drawn >= REDRAW_S:
                self._draw()

    def close(self) -> None:
        """The final state: the count and the time taken."""
        if not self.total:
            return
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
            self._ticker = None
        with self._lock:
            if self.terminal:
                self.postfix = ""
                self._draw(final=True)
                self.stream.write("\n")
                self.stream.flush()
            else:
                self._line(
                    f"{self.desc}: {self.n}/{self.total} {self.unit}s in "
                    f"{_clock(time.monotonic() - self.t0)}"
                )
            self.total = 0  # closed: nothing more is shown

    @contextlib.contextmanager
    def paused(self):
        """The block runs with the clock thread stopped (restarted after): e.g. while the
        process forks, so that no child starts with a lock that thread held."""
        ticking = self._ticker is not None
        if ticking:
            self._stop.set()
            self._ticker.join()
            self._ticker = None
        try:
            yield
        finally:
            if ticking and self.total:
                self._stop = threading.Event()
                self._ticker = threading.Thread(target=self._tick, daemon=True, name="progress")
                self._ticker.start()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- text ----------------------------------------------------------------------------------

    def eta(self) -> float | None:
        """Seconds left: from the items' sizes and the rates measured since the warm-ups
        ended (:class:`Estimate`), or without items from the count of units finished since
        then; None while the warm-ups last or before enough has finished since."""
        if self.t_warm is None:
            return None
        elapsed = time.monotonic() - self.t_warm
        if self.estimate is not None:
            return self.estimate.left_s(elapsed)
        if self.n <= self.n_warm:
            return None
        rate = (self.n - self.n_warm) / max(elapsed, 1e-9)
        return (self.total - self.n) / rate

    def _count(self) -> str:
        pct = 100 * self.n / self.total if self.total else 100.0
        elapsed = _clock(time.monotonic() - self.t0)
        return f"{self.n}/{self.total} {self.unit}s ({pct:.0f} %), {elapsed}"

    def _tail(self) -> str:
        if self.warming:
            return f", {LOADING_OR_COMPILING} " + ", ".join(self.warming.values())
        eta = self.eta()
        return f", about {_clock(eta)} left" if eta is not None else ""

    def _status(self) -> str:
        return f"{self.desc}: {self._count()}{self._tail()}"

    def _group_line(self, group: str) -> str:
        counts = self.outcomes.get(group, {})
        said = ", ".join(f"{n} {w}" for w, n in sorted(counts.items()))
        said = f" ({said})" if said else ""
        return f"{self.desc}: {group} done{said}; {self._count()}{self._tail()}"

    def _tick(self) -> None:
        """The clock thread of a terminal display: a redraw every :data:`TICK_S`."""
        while not self._stop.wait(TICK_S):
            with self._lock:
                if self.total and time.monotonic() - self._drawn >= TICK_S * 0.9:
                    self._draw()

    def _draw(self, final: bool = False) -> None:
        if not self.terminal:
            return
        width = shutil.get_terminal_size((80, 24)).columns - 1
        pct = self.n / self.total if self.total else 1.0
        elapsed = _clock(time.monotonic() - self.t0)
        if self.warming and not final:
            tail = f"{LOADING_OR_COMPILING} " + ", ".join(self.warming.values())
        else:
            eta = self.eta()
            tail = f"{_clock(eta)} left" if eta is not None and not final else ""
            if self.bundled and not final:
                tail += (
                    (" " if tail else "") + "bundles compiling " + ", ".join(self.bundled.values())
                )
            tail += (" " if tail and self.postfix else "") + self.postfix
        head = f"{self.desc} {100 * pct:3.0f}% {self.n}/{self.total} [{elapsed}]"
        nbar = max(min(20, width - len(head) - len(tail) - 4), 0)
        bar = f" |{'#' * int(pct * nbar):<{nbar}}|" if nbar >= 5 else ""
        line = f"{head}{bar} {tail}"[:width]
        self.stream.write("\r" + line.ljust(self._width))
        self.stream.flush()
        self._width = len(line)
        self._drawn = time.monotonic()

    def _line(self, text: str) -> None:
        self.stream.write(text + "\n")
        self.stream.flush()
