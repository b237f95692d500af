"""Handing freed memory back to the system after the big steps of a big log.

NumPy's temporaries of a few hundred kilobytes come from the C library's heap, one arena per
thread, and glibc keeps what is freed there for reuse instead of returning it. After replaying a
log of millions of samples that is a few hundred megabytes the process holds but no longer uses,
on top of which the next step allocates its own. :func:`release_freed` asks glibc to return it
(``malloc_trim``, as Dask's workers do); elsewhere it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools

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
