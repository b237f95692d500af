"""Handing freed memory back to the system after the big steps of a big log.

NumPy's temporaries of a few hundred kilobytes come from the C library's heap, one arena per
thread, and glibc keeps what is freed there for reuse instead of returning it. After replaying a
log of millions of samples that is a few hundred megabytes the process holds but no longer uses,
on top of which the next step allocates its own. :func:`release_freed` asks glibc to return it
(``malloc_trim``, as Dask's workers do); elsewhere it does nothing.

A command's long-lived objects are also taken out of the cyclic collector's walks
(:func:`settle_survivors`), and modules load with the collector paused (:func:`loading`).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
from contextlib import contextmanager

#: samples from which the steps of a log are followed by :func:`release_freed`
BIG_LOG = 200_000


@functools.cache
def _trim():
    name = ctypes.util.find_library("c")
    try:
        function = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):  # not glibc: nothing to ask
        return None
    return function


def release_freed(samples: int = BIG_LOG) -> None:
    """Return freed heap memory to the system, after a step over ``samples`` samples that is
    at least :data:`BIG_LOG` (smaller steps leave too little to be worth a call)."""
    trim = _trim()
    if trim is not None and samples >= BIG_LOG:
        trim(0)


def settle_survivors() -> None:
    """Take every object alive now out of the cyclic collector's walks (``gc.freeze``), within
    :func:`settling`: for what a command keeps to its end (its modules and inputs, a finished
    workflow's maps, models and replays).

    The collector walks every container object of a generation each time it collects it, and
    its oldest generation holds all that survived: a workflow's models and replays, and the
    report's artists drawn after them, were walked again at every full collection for nothing,
    since they live until the command ends. What is made afterwards is collected as before.
    """
    gc.freeze()


@contextmanager
def settling():
    """Within: :func:`settle_survivors` may be called; at the end, whatever it took out is
    handed back to the collector (``gc.unfreeze``), so that a process that goes on (a test, a
    notebook running commands) frees a finished command's cycles as before."""
    try:
        yield
    finally:
        gc.unfreeze()


@contextmanager
def loading():
    """Within: modules load with the cyclic collector paused; at the end, every object alive is
    taken out of its walks (``gc.freeze``), and it runs again as it did.

    Modules make thousands of objects (classes, functions, their dictionaries) that live as
    long as the process, none of them garbage, which the collector would otherwise walk in
    some two hundred passes while they load (matplotlib's, for the report, cost 15 ms of
    collection), and again in every full collection after."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if collecting:
            gc.enable()
