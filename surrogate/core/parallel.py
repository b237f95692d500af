"""Independent replays side by side, on threads.

A replay of a bench log spends most of its time inside NumPy on arrays of tens of thousands of
samples, where the interpreter lock is released, so threads overlap most of the work without the
cost and fragility of processes (no pickling of maps, no forking a process that holds PyTorch).
Measured once by hand on a 2-core machine: two replays on two threads took 0.68 of the time they
take one after the other. A fit, a diagnosis or a workflow, though, runs its refits on one
thread, its replays' batches too (:func:`single_threaded`: on two, its result depended on
which thread came first); a replay outside them (``predict``, ``simulate``, ``compare``) still
runs its batches side by side.

While a pool runs, the BLAS that NumPy calls keeps to one thread. The replays already fill the
cores; OpenBLAS's own threads on top of them (it starts one per core for each matrix product of a
GP map's kernel) only contend with them: a diagnose on GP maps took 1.79 times as long with them
(``python eval/workbench.py`` measures the diagnosis both ways).

Every command, and a fit, a diagnosis or a workflow called from Python, keeps the BLAS to one
thread throughout (:func:`blas_limited`, also a decorator), pool or not: the package's matrices
are small (products and QR factors of 11,000 × 20 Jacobians), and between them OpenBLAS's idle
threads spin. On 2 cores that other work shared, ``diagnose --model cfda`` on the shipped log
took 13.3, 18.5 and 23.2 CPU s with two BLAS threads and 11.1, 11.4 and 12.5 s with one
(``OPENBLAS_NUM_THREADS``, runs alternating), its wall time alike; a workflow on an off-library
log (eval/profile_loop.py offlibrary --case 4243) 25.2 against 11.3 CPU s, 7.4 s of the
difference in QR factors of 1,380 × 11 Jacobians that take milliseconds on one thread.
"""

from __future__ import annotations

import functools
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")

#: BLAS threads while a pool runs (None: leave the BLAS as it is, the baseline the eval times)
BLAS_THREADS_IN_POOL: int | None = 1
#: most threads :func:`default_workers` hands out in this process (None: as many as the cores).
#: A fleet's worker processes set 1 (:mod:`surrogate.fleet.runner`): there the processes are the
#: parallelism, one valve each, and threads inside each would only contend for the same cores
THREAD_LIMIT: int | None = None


#: how many fits, diagnoses or workflows are running, each on one thread
#: (:func:`single_threaded`)
_single_jobs = 0


def default_workers() -> int:
    """Threads to use: the cores this process may run on, at most 4 (beyond that the
    interpreter lock leaves little to gain) and at most :data:`THREAD_LIMIT`; one while a fit,
    a diagnosis or a workflow runs (:func:`single_threaded`)."""
    if _single_jobs:
        return 1
    cores = available_cores()
    return max(1, min(cores, 4, THREAD_LIMIT or cores))


def single_threaded(function):
    """Decorator: while the function (a fit, a diagnosis, a workflow) runs, pools use one thread.

    Why one: its refits replay the log on maps whose tables (:mod:`.solver.map_tables`) a
    replay on another thread may renew meanwhile, and a renewed row of a GP or NN map differs
    in its last digits from the row it replaces (their predictions depend on the batch they are
    made in), so that on two threads the result depended on which thread came first (``diagnose
    --model cfda-gp`` gave four different JSON files in four runs). On one thread it is the same
    every run, and costs less CPU: on the shipped log 13-17 % less for ``diagnose`` and the
    workflow, for 5-14 % more wall time; on an off-library log of 1,380 samples 17.0-17.5 CPU s
    and 15.9-16.4 s of wall time against 22.0-23.6 and 18.0-19.3 s on two (2 quiet cores).
    """
    @functools.wraps(function)
    def single(*args, **kwargs):
        global _single_jobs
        with _limit_lock:
            _single_jobs += 1
        try:
            return function(*args, **kwargs)
        finally:
            with _limit_lock:
                _single_jobs -= 1
    return single


def available_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


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
    with blas_limited():
        pool = ThreadPoolExecutor(max_workers=min(workers, len(items)))
        try:
            yield from pool.map(function, items)
        except BaseException:  # an item failed, or Ctrl-C/SIGTERM: start none of the rest
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)


_limit_lock = threading.Lock()
_pools_running = 0
_blas_limit = None


@contextmanager
def blas_limited():
    """BLAS kept to :data:`BLAS_THREADS_IN_POOL` threads from the first pool (or command, module
    docstring) that starts to the last that ends (pools nest: a refit on a worker thread
    differentiates on a pool of its own), then restored to what it was."""
    global _pools_running, _blas_limit
    with _limit_lock:
        if _pools_running == 0 and BLAS_THREADS_IN_POOL is not None:
            from threadpoolctl import threadpool_limits  # scikit-learn's own dependency

            _blas_limit = threadpool_limits(BLAS_THREADS_IN_POOL, user_api="blas")
        _pools_running += 1
    try:
        yield
    finally:
        with _limit_lock:
            _pools_running -= 1
            if _pools_running == 0 and _blas_limit is not None:
                _blas_limit.restore_original_limits()
                _blas_limit = None
