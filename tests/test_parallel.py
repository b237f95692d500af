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
