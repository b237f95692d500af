"""Progress lines for long work: what is being done, how far it got and how long it will take.

Lines go to stderr, so that stdout stays for results and --json.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable


class Progress:
    """Print ``[  12.3 s] message`` lines on stderr.

    Call it with a message; ``quiet=True`` keeps it silent. Anything that does long work takes a
    ``progress`` callable, so a program can pass its own (a logger, a progress bar) instead.
    Work counted in steps reports through :meth:`stage`. ``clock`` (seconds, monotonic) is for
    tests.
    """

    def __init__(self, quiet: bool = False, stream=None,
                 clock: Callable[[], float] = time.perf_counter):
        self.quiet = quiet
        self.stream = stream
        self.clock = clock
        self.started = clock()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{self.elapsed:6.1f} s] {message}", file=self.stream or sys.stderr,
                  flush=True)

    @property
    def elapsed(self) -> float:
        """Seconds since the reporter was made [s]."""
        return self.clock() - self.started

    def stage(self, what: str, total: float, unit: str = "") -> "Stage":
        """A stage of ``total`` steps (``unit``: what a step is, e.g. "rows"), reported as it
        advances (:class:`Stage`)."""
        return Stage(self, what, total, unit)


class Stage:
    """One stage of long work: ``stage(done)`` reports how far it got, with the rate and the
    time left, at most once every :attr:`INTERVAL` seconds (and always at the start and the
    end), so a loop may call it as often as it likes."""

    #: [s] between two lines of one stage
    INTERVAL = 2.0

    def __init__(self, progress: Callable[[str], None], what: str, total: float,
                 unit: str = ""):
        self.progress = progress
        self.what, self.total, self.unit = what, float(total), unit
        self.clock = getattr(progress, "clock", time.perf_counter)
        self.began = self.clock()
        self.last = None
        self(0)

    def __call__(self, done: float) -> None:
        now = self.clock()
        final = done >= self.total
        if self.last is not None and not final and now - self.last < self.INTERVAL:
            return
        self.last = now
        unit = f" {self.unit}" if self.unit else ""
        line = f"{self.what}: {done:,.0f} of {self.total:,.0f}{unit}"
        if self.total > 0:
            line += f" ({100 * done / self.total:.0f} %)"
        spent = now - self.began
        if final:
            line += f", done in {duration(spent) if spent >= 90 else f'{spent:.1f} s'}"
        elif done > 0 and spent > 0:
            left = spent * (self.total - done) / done
            line += f", {rate(done / spent, self.unit)}, about {duration(left)} left"
        self.progress(line)


def rate(per_second: float, unit: str = "") -> str:
    """``"12/s"``, or for slow work ``"4 s each"``: never ``"0/s"``."""
    if per_second >= 1.0:
        return f"{per_second:,.0f}{' ' + unit if unit else ''}/s"
    return f"{duration(1.0 / per_second) if per_second > 0 else 'no'} each"


def duration(seconds: float) -> str:
    """``"45 s"``, ``"3 min 20 s"``, ``"1 h 2 min"``: a time [s] as people read it."""
    whole = int(round(seconds))
    if whole < 90:
        return f"{whole} s"
    if whole < 3600:
        return f"{whole // 60} min {whole % 60} s"
    return f"{whole // 3600} h {whole % 3600 // 60} min"
