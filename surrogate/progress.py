"""Progress lines for long work: what is being done and how long it has taken so far."""

from __future__ import annotations

import sys
import time


class Progress:
    """Print ``[  12.3 s] message`` lines on stderr, so that stdout stays for results and --json.

    Call it with a message; ``quiet=True`` keeps it silent. Anything that does long work takes a
    ``progress`` callable, so a program can pass its own (a logger, a progress bar) instead.
    """

    def __init__(self, quiet: bool = False, stream=None):
        self.quiet = quiet
        self.stream = stream
        self.started = time.perf_counter()

    def __call__(self, message: str) -> None:
        if not self.quiet:
            print(f"[{self.elapsed:6.1f} s] {message}", file=self.stream or sys.stderr,
                  flush=True)

    @property
    def elapsed(self) -> float:
        """Seconds since the reporter was made [s]."""
        return time.perf_counter() - self.started
