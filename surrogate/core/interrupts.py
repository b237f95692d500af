"""Stopping cleanly on Ctrl-C (SIGINT) and on ``kill`` (SIGTERM).

Python turns SIGINT into :class:`KeyboardInterrupt` but lets SIGTERM end the process at once,
without unwinding: the ``finally`` clauses that remove a command's staging folder never run, and a
hidden half-written folder stays next to ``--out``. While :func:`handling_interrupts` is active,
both signals raise :class:`Interrupted` instead (a :class:`KeyboardInterrupt`, so code that lets
Ctrl-C through lets SIGTERM through too), the stack unwinds, and the command line exits with the
shell's convention, 128 + the signal's number: 130 for SIGINT, 143 for SIGTERM.

The few steps that must not be cut in half (moving finished files into place, removing a staging
folder) run inside :func:`deferred`: a signal that arrives there is held and raised when the step
is done, so an output is either wholly written or not at all.
"""

from __future__ import annotations

import contextlib
import signal
import threading

#: the signals a command stops on
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupted(KeyboardInterrupt):
    """The user (Ctrl-C) or the system (``kill``) asked the command to stop."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        """The shell's convention: 128 + the signal's number (130 SIGINT, 143 SIGTERM)."""
        return 128 + int(self.signum)


_deferring = 0
_pending: list[int] = []


def _raise_interrupted(signum, frame) -> None:
    if _deferring:  # inside a step that must finish: hold the signal until it has
        _pending.append(signum)
        return
    raise Interrupted(signum)


@contextlib.contextmanager
def handling_interrupts():
    """Turn SIGINT and SIGTERM into :class:`Interrupted` while the block runs.

    Does nothing outside the main thread (only the main thread may set signal handlers; Python
    runs them there). The previous handlers are restored afterwards.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.signal(number, _raise_interrupted) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


@contextlib.contextmanager
def deferred():
    """Hold SIGINT and SIGTERM until the block is done, then raise :class:`Interrupted` for the
    first that arrived (if none arrived, nothing happens)."""
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if not _deferring and _pending:
            signum = _pending[0]
            _pending.clear()
            raise Interrupted(signum)


def exit_code(interruption: KeyboardInterrupt) -> int:
    """Exit code for an interruption: 130 for Ctrl-C, 143 for SIGTERM."""
    return interruption.exit_code if isinstance(interruption, Interrupted) else 128 + signal.SIGINT
