"""Independent replays side by side, on threads.

A replay of a bench log spends most of its time inside NumPy on arrays of tens of thousands of
samples, where the interpreter lock is released, so threads overlap most of the work without the
cost and fragility of processes (no pickling of maps, no forking a process that holds PyTorch).
Measured once by hand on a 2-core machine: two replays on two threads took 0.68 of the time they
take one after the other; eval/workbench.py reports the diagnosis' speed that results.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")


def default_workers() -> int:
    """Threads to use: the cores this process may run on, at most 4 (beyond that the
    interpreter lock leaves little to gain)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, 4))


def map_threads(function: Callable[[Item], Result], items: Iterable[Item], *,
                workers: int | None = None) -> Iterator[Result]:
    """``function(item)`` for every item, evaluated on up to ``workers`` threads.

    Yields the results in the items' order, each as soon as it and those before it are done (so
    a caller can report progress). ``function`` must not mutate state shared between items; an
    exception raised by any item is raised here.
    """
    items = list(items)
    workers = default_workers() if workers is None else workers
    if workers <= 1 or len(items) <= 1:
        yield from map(function, items)
        return
    with ThreadPoolExecutor(max_workers=min(workers, len(items))) as pool:
        yield from pool.map(function, items)
