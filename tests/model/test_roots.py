"""The vectorised root finder: known bracket-end values save evaluations, not accuracy."""

import numpy as np

from surrogate.roots import find_roots


def test_known_end_values_stand_in_for_the_first_two_evaluations():
    targets = np.linspace(0.5, 30.0, 50)
    lower, upper = np.zeros(50), np.full(50, 10.0)
    calls = []

    def cube_minus_target(x, index):
        calls.append(np.array(x))
        return x**3 - targets[index]

    plain = find_roots(cube_minus_target, lower, upper, xatol=1e-14, xrtol=1e-14)
    plain_calls, calls[:] = len(calls), []
    known = find_roots(cube_minus_target, lower, upper, xatol=1e-14, xrtol=1e-14,
                       f_lower=-targets, f_upper=1000.0 - targets)
    assert len(calls) == plain_calls - 2
    assert not any(np.array_equal(x, lower) or np.array_equal(x, upper) for x in calls)
    np.testing.assert_array_equal(known.x, plain.x)
    np.testing.assert_allclose(known.x, np.cbrt(targets), rtol=1e-13)
