"""The thread map that refits diagnosis candidates side by side."""

from __future__ import annotations

import threading

import pytest

from surrogate.parallel import map_threads


@pytest.mark.parametrize("workers", [1, 2, 4])
def test_results_keep_the_items_order(workers):
    assert list(map_threads(lambda x: x * x, range(20), workers=workers)) == [
        x * x for x in range(20)]


def test_work_runs_on_several_threads():
    both_running = threading.Barrier(2, timeout=10)

    def wait_for_the_other(item):
        both_running.wait()  # raises BrokenBarrierError if the items ran one after the other
        return item

    assert list(map_threads(wait_for_the_other, [1, 2], workers=2)) == [1, 2]


def test_an_items_exception_reaches_the_caller():
    def fail_on_three(item):
        if item == 3:
            raise ValueError("three")
        return item

    with pytest.raises(ValueError, match="three"):
        list(map_threads(fail_on_three, range(6), workers=2))


def _blas_threads() -> set[int]:
    from threadpoolctl import threadpool_info

    return {pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"}


def test_the_blas_keeps_to_one_thread_while_pools_run_and_is_restored_after():
    """The replays fill the cores; BLAS threads beside them only contend (the module docstring).
    Pools nest (a refit on a worker differentiates on a pool of its own): the limit holds until
    the outermost ends, then the BLAS has the threads it had."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(2, user_api="blas"):  # a BLAS free to use two threads
        before = _blas_threads()
        if not before:
            pytest.skip("NumPy's BLAS is not one threadpoolctl can see")

        def inner(item):
            return item, _blas_threads()

        def outer(item):
            nested = list(map_threads(inner, range(2), workers=2))
            return _blas_threads(), nested

        seen = list(map_threads(outer, range(3), workers=2))
        assert all(during == {1} and all(threads == {1} for _, threads in nested)
                   for during, nested in seen), seen
        assert _blas_threads() == before == {2}



def test_every_command_and_the_loops_entry_points_keep_the_blas_to_one_thread(monkeypatch):
    """A command (here check-data, its work replaced by a probe) and a function decorated as a
    fit, a diagnosis and a workflow are run with one BLAS thread: between their small products
    the idle threads only spin (surrogate.parallel's docstring). The BLAS is restored after."""
    from threadpoolctl import threadpool_limits

    from surrogate import cli
    from surrogate.commands import check_data
    from surrogate.diagnosis.diagnose import diagnose
    from surrogate.fitting.logfit import fit_to_log
    from surrogate.parallel import blas_limited
    from surrogate.workbench.workflow import run_workflow

    with threadpool_limits(2, user_api="blas"):
        if not _blas_threads():
            pytest.skip("NumPy's BLAS is not one threadpoolctl can see")
        seen = []
        monkeypatch.setattr(check_data, "run", lambda args: seen.append(_blas_threads()))
        assert cli.main(["check-data", "any.csv"]) == 0

        @blas_limited()
        def decorated():
            seen.append(_blas_threads())

        decorated()
        assert seen == [{1}, {1}]
        assert _blas_threads() == {2}
    # the loop's entry points carry that decorator (functools.wraps leaves the original behind)
    assert all(hasattr(entry, "__wrapped__") for entry in (run_workflow, diagnose, fit_to_log))


def test_a_small_log_runs_on_one_thread_a_large_one_on_several(monkeypatch):
    """Below THREADED_SAMPLES a job's pools use one thread (its arrays are too small for the
    threads to gain anything; surrogate.parallel), from the call on the main thread down; a
    call from a worker thread, on part of its caller's log, decides nothing."""
    from surrogate import parallel

    monkeypatch.setattr(parallel, "available_cores", lambda: 2)
    monkeypatch.setattr(parallel, "THREAD_LIMIT", None)

    @parallel.threads_sized_by("log")
    def job(log):
        return parallel.default_workers()

    assert job(range(parallel.THREADED_SAMPLES - 1)) == 1
    assert job(log=range(parallel.THREADED_SAMPLES)) == 2
    assert parallel.default_workers() == 2  # restored after the job
    assert list(map_threads(lambda n: job(range(n)), [10, 10], workers=2)) == [2, 2]
