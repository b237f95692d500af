"""The vectorised root finder: known bracket-end values save evaluations, not accuracy."""

import numpy as np

from surrogate.numerics.roots import find_roots


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


def test_known_middle_values_stand_in_for_the_first_step():
    """The solver finds h at a bracket's middle, where Chandrupatla's first step (a bisection)
    lands, beside its ends: where known, those values are the first step's, one call of the
    function fewer, the same roots to the bit; the others are asked for."""
    targets = np.linspace(0.5, 30.0, 50)
    lower, upper = np.zeros(50), np.full(50, 10.0)
    lower[0] = upper[0] = 2.0  # converged before the first step: its middle is not asked
    calls = []

    def cube_minus_target(x, index):
        calls.append(np.array(index))
        return x**3 - targets[index]

    ends = {"f_lower": lower**3 - targets, "f_upper": upper**3 - targets}
    plain = find_roots(cube_minus_target, lower, upper, xatol=1e-14, xrtol=1e-14, **ends)
    plain_calls, calls[:] = len(calls), []
    middle = lower + 0.5 * (upper - lower)
    known = np.arange(50) % 7 != 3  # some middles unknown: asked in the first step
    found = find_roots(cube_minus_target, lower, upper, xatol=1e-14, xrtol=1e-14,
                       f_middle=(middle**3 - targets, known), **ends)
    assert len(calls) == plain_calls
    np.testing.assert_array_equal(np.sort(calls[0]), np.flatnonzero(~known))
    np.testing.assert_array_equal(found.x, plain.x)
    np.testing.assert_array_equal(found.status, plain.status)
    calls[:] = []
    every = find_roots(cube_minus_target, lower, upper, xatol=1e-14, xrtol=1e-14,
                       f_middle=(middle**3 - targets, np.ones(50, bool)), **ends)
    assert len(calls) == plain_calls - 1
    np.testing.assert_array_equal(every.x, plain.x)


def test_roots_are_scipys_to_the_bit():
    """The port of Chandrupatla's method (surrogate.numerics.chandrupatla) returns what
    scipy.optimize.elementwise.find_root returns: the same roots, convergence and status, for
    good brackets, brackets without a sign change, non-finite ends and the iteration limit."""
    from scipy.optimize.elementwise import find_root

    rng = np.random.default_rng(1)
    n = 5000
    a, c, p = rng.uniform(0.1, 3, n), rng.uniform(-5, 5, n), rng.uniform(1, 5, n)

    def fn(x, i):
        return np.sign(x - a[i]) * np.abs(x - a[i]) ** p[i] + 1e-3 * np.tanh(c[i] * x) - 1e-4

    lower, upper = np.zeros(n), np.full(n, 4.0)
    upper[:50] = 0.05  # no sign change
    lower[50:60] = np.nan  # not finite
    for tolerances, maxiter in (({"xatol": 1e-30, "xrtol": 1e-14}, 200),
                                ({"xatol": 1e-12, "xrtol": 1e-8}, 3)):
        mine = find_roots(fn, lower, upper, maxiter=maxiter, **tolerances)
        theirs = find_root(lambda x, k: fn(x, k.astype(np.intp)), (lower, upper),
                           args=(np.arange(n, dtype=float),), maxiter=maxiter,
                           tolerances={**tolerances, "fatol": 0.0, "frtol": 0.0})
        success = np.asarray(theirs.success)
        np.testing.assert_array_equal(mine.converged, success)
        np.testing.assert_array_equal(mine.status, theirs.status)
        np.testing.assert_array_equal(mine.x, np.where(success, theirs.x, np.nan))
