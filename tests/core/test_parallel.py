"""The thread map that refits diagnosis candidates side by side."""

from __future__ import annotations

import threading

import pytest

from surrogate.core.parallel import map_threads


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
    the idle threads only spin (surrogate.core.parallel's docstring). The BLAS is restored after."""
    from threadpoolctl import threadpool_limits

    from surrogate import cli
    from surrogate.commands import check_data
    from surrogate.diagnosis.diagnose import Diagnoser
    from surrogate.fitting.logfit import fit_to_log
    from surrogate.core.parallel import blas_limited
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
    assert all(hasattr(entry, "__wrapped__")
               for entry in (run_workflow, Diagnoser.diagnose, fit_to_log))


def test_a_fit_a_diagnosis_and_a_workflow_run_on_one_thread(monkeypatch):
    """While a decorated job runs, pools use one thread, from its call down (on two, a GP
    map's tables renewed by one refit while another read them made the result depend on which
    thread came first: surrogate.core.parallel.single_threaded); after it, as many as before. The
    loop's entry points carry the decorator."""
    from surrogate.core import parallel
    from surrogate.diagnosis.diagnose import Diagnoser
    from surrogate.fitting.logfit import fit_to_log
    from surrogate.workbench.workflow import run_workflow

    monkeypatch.setattr(parallel, "available_cores", lambda: 2)
    monkeypatch.setattr(parallel, "THREAD_LIMIT", None)

    @parallel.single_threaded
    def job():
        return parallel.default_workers()

    assert parallel.default_workers() == 2
    assert job() == 1
    assert parallel.default_workers() == 2  # restored after the job
    assert list(map_threads(lambda _: job(), [1, 2], workers=2)) == [1, 1]

    def wrappers(entry):
        names = []
        while hasattr(entry, "__wrapped__"):
            names.append(entry.__code__.co_name)
            entry = entry.__wrapped__
        return names

    assert all("single" in wrappers(entry)
               for entry in (run_workflow, Diagnoser.diagnose, fit_to_log))
