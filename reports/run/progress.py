"""Progress of a batch of runs on standard error, for a terminal and for a log.

In a terminal, one line redrawn in place: the count, a bar, the time so far, an estimate of
the time left and what finished last or what is compiling. Anywhere else (CI, a pipe, a
file) a plain line at every tenth of the work and at the end, never a carriage return, so a
log of the whole default suite holds about a dozen lines.

The first run of some engines in a process compiles code first (the director model's and the
suite's RKMK4 numba kernels, MJX's step with JAX); such a run takes seconds where the others
take milliseconds. The runner names these warm-ups (``warming``: key -> what compiles) and
says which key each finished run belongs to; until the first run of every key has finished,
the display says what is compiling and gives no estimate, and the estimate afterwards uses
only the runs finished since then, so that compilation does not inflate it. A warm-up at the
start of a bundle of runs that finish together (MJX's) is only named at the start
(``bundled``): its end is not seen before the whole bundle's.
"""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Mapping, Sequence

#: a terminal line is redrawn at most this often (s) for a running run's own progress
REDRAW_S = 0.2
#: outside a terminal, a line every this fraction of the work
LOG_STEP = 0.1


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
    return f"{s // 60}:{s % 60:02d}"


class Progress:
    """Progress of ``total`` units of work (runs) on ``stream`` (default: standard error).

    ``update(n, key)`` counts ``n`` finished units of warm-up key ``key`` (or None);
    ``set_postfix_str(text)`` shows what is running (a terminal only); ``close()`` ends the
    display. ``terminal``: draw in place (default: whether ``stream`` is a terminal);
    ``disable``: show nothing. No work (``total`` 0) shows nothing either."""

    def __init__(
        self,
        total: int,
        desc: str = "director-bench",
        unit: str = "run",
        warming: Mapping[str, str] | None = None,
        stream=None,
        terminal: bool | None = None,
        disable: bool = False,
        bundled: Sequence[str] = (),
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
        self.n = 0
        self.t0 = time.monotonic()
        # the estimate's origin: the end of the warm-ups (the start if there are none)
        self.t_warm = self.t0 if not self.warming else None
        self.n_warm = 0
        self.postfix = ""
        self.logged = 0  # tenths of the work reported outside a terminal
        self._drawn = 0.0
        self._width = 0
        if not self.total:
            return
        if not self.terminal:
            first = f"{self.desc}: {self.total} {self.unit}s"
            if self.warming:
                first += "; compiling first: " + ", ".join(self.warming.values())
            if bundled:
                first += "; at the start of their bundles: " + ", ".join(bundled)
            self._line(first)
        else:
            self._draw()

    # -- the interface the runner uses ---------------------------------------------------------

    def update(self, n: int = 1, key: str | Sequence[str] | None = None, label: str = "") -> None:
        """``n`` more units finished; ``key``: their warm-up key or keys (those compilations
        are over); ``label``: what finished (shown in a terminal)."""
        if not self.total:
            return
        self.n += n
        keys = (key,) if isinstance(key, str) else tuple(key or ())
        ended = [k for k in keys if self.warming.pop(k, None) is not None]
        if ended and not self.warming:
            self.t_warm, self.n_warm = time.monotonic(), self.n
        if label:
            self.postfix = label
        if self.terminal:
            self._draw()
        else:
            tenth = int(self.n / self.total / LOG_STEP + 1e-9) if self.total else 0
            if tenth > self.logged and self.n < self.total:
                self.logged = tenth
                self._line(self._status())

    def set_postfix_str(self, text: str, refresh: bool = True) -> None:
        """What is running now (a run's own progress); a terminal shows it, a log does not."""
        self.postfix = text
        now = time.monotonic()
        if self.total and self.terminal and refresh and now - self._drawn >= REDRAW_S:
            self._draw()

    def close(self) -> None:
        """The final state: the count and the time taken."""
        if not self.total:
            return
        if self.terminal:
            self.postfix = ""
            self._draw(final=True)
            self.stream.write("\n")
            self.stream.flush()
        elif self.total:
            self._line(
                f"{self.desc}: {self.n}/{self.total} {self.unit}s in "
                f"{_clock(time.monotonic() - self.t0)}"
            )

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- text ----------------------------------------------------------------------------------

    def eta(self) -> float | None:
        """Seconds left, from the rate since the warm-ups ended; None while they last or
        before a run has finished since."""
        if self.t_warm is None or self.n <= self.n_warm:
            return None
        rate = (self.n - self.n_warm) / max(time.monotonic() - self.t_warm, 1e-9)
        return (self.total - self.n) / rate

    def _status(self) -> str:
        pct = 100 * self.n / self.total if self.total else 100.0
        text = f"{self.desc}: {self.n}/{self.total} {self.unit}s ({pct:.0f} %), "
        text += _clock(time.monotonic() - self.t0)
        if self.warming:
            return text + ", compiling " + ", ".join(self.warming.values())
        eta = self.eta()
        return text + (f", about {_clock(eta)} left" if eta is not None else "")

    def _draw(self, final: bool = False) -> None:
        if not self.terminal:
            return
        width = shutil.get_terminal_size((80, 24)).columns - 1
        pct = self.n / self.total if self.total else 1.0
        elapsed = _clock(time.monotonic() - self.t0)
        if self.warming and not final:
            tail = "compiling " + ", ".join(self.warming.values())
        else:
            eta = self.eta()
            tail = f"{_clock(eta)} left" if eta is not None and not final else ""
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
