"""Chandrupatla's bracketing root finder for many functions at once, without SciPy's framework.

:func:`.roots.find_roots` solves thousands of one-dimensional roots together, a fit
some twenty thousand per replay. SciPy's :func:`scipy.optimize.elementwise.find_root` runs
Chandrupatla's method [1] inside a general framework (array-API dispatch, result objects,
callbacks) whose bookkeeping cost about a fifth of a replay on the shipped log: more than the
arithmetic. This is the same method with the same arithmetic in the same order (SciPy 1.17's
``scipy/optimize/_chandrupatla.py`` and ``scipy/_lib/_elementwise_iterative_method.py``: its
tolerances, termination tests, status codes and compression of finished points), so that it
returns SciPy's roots to the bit (tests/numerics/test_roots.py compares them). Ported under
SciPy's BSD 3-Clause license (Copyright (c) 2001-2002 Enthought, Inc., 2003 SciPy Developers).

[1] Chandrupatla, T. R. "A new hybrid quadratic/bisection algorithm for finding the zero of a
nonlinear function without using derivatives". Advances in Engineering Software 28(3),
145–149 (1997).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: SciPy's status codes (``scipy._lib._elementwise_iterative_method``)
CONVERGED, SIGN_ERROR, NOT_CONVERGED, VALUE_ERROR, IN_PROGRESS = 0, -1, -2, -3, 1


def chandrupatla(fn: Callable[[np.ndarray, np.ndarray], np.ndarray], x1: np.ndarray,
                 x2: np.ndarray, f1: np.ndarray, f2: np.ndarray, *, xatol: float,
                 xrtol: float, fatol: float, maxiter: int,
                 f_first: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(x, status) of the roots of ``fn(x, index)`` (the points ``index``, integer positions
    into ``x1``) in the brackets [x1, x2], whose ``fn`` values f1 and f2 are known; status as
    SciPy's (:data:`CONVERGED` ...). The relative tolerance on ``fn`` is SciPy's default, 0.
    ``f_first``: (values, known), ``fn`` at the first step's point x1 + 0.5·(x2 − x1) (a
    bisection) where ``known``, which the caller found with the ends' values; the same
    iterations follow, one call of ``fn`` fewer."""
    n = x1.size
    x1, x2 = np.array(x1, float), np.array(x2, float)
    f1, f2 = np.array(f1, float), np.array(f2, float)
    x_out = np.zeros(n)
    status_out = np.full(n, IN_PROGRESS, dtype=np.int32)
    active = np.arange(n)
    status = np.full(n, IN_PROGRESS, dtype=np.int32)
    frtol = 0.0 * np.minimum(np.abs(f1), np.abs(f2))  # SciPy scales frtol = 0 by the ends
    x3 = f3 = None
    t = 0.5
    nit = 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        stop, xmin, dx, tol = _check(x1, f1, x2, f2, status, frtol, fatol, xatol, xrtol)
        while True:
            if stop.any():  # record the finished points and drop them from the work
                done, keep = active[stop], ~stop
                x_out[done], status_out[done] = xmin[stop], status[stop]
                active = active[keep]
                x1, f1, x2, f2 = x1[keep], f1[keep], x2[keep], f2[keep]
                status, frtol, xmin, dx, tol = (status[keep], frtol[keep], xmin[keep],
                                                dx[keep], tol[keep])
                if x3 is not None:
                    x3, f3 = x3[keep], f3[keep]
                if np.ndim(t):
                    t = t[keep]
            if not active.size:
                break
            if nit:  # the next step, as SciPy's post_termination_check
                t = _step_fraction(x1, f1, x2, f2, x3, f3, dx, tol)
            if nit >= maxiter:
                break
            x = x1 + t * (x2 - x1)
            f = (np.asarray(fn(x, active), dtype=float) if nit or f_first is None
                 else _first_values(fn, x, active, *f_first))
            x3, f3 = x2.copy(), f2.copy()
            j = np.sign(f) == np.sign(f1)
            nj = ~j
            x3[j], f3[j] = x1[j], f1[j]
            x2[nj], f2[nj] = x1[nj], f1[nj]
            x1, f1 = x, f
            nit += 1
            stop, xmin, dx, tol = _check(x1, f1, x2, f2, status, frtol, fatol, xatol,
                                         xrtol)
    # those still running at the iteration limit
    x_out[active], status_out[active] = xmin, NOT_CONVERGED
    return x_out, status_out


def _first_values(fn, x: np.ndarray, active: np.ndarray, values: np.ndarray,
                  known: np.ndarray) -> np.ndarray:
    """``fn`` at the first step's points ``x`` of the points ``active``: the caller's
    ``values`` where it ``known`` them (by position among all points), ``fn`` asked for the
    rest."""
    f = np.asarray(values, float)[active]
    ask = ~np.asarray(known, bool)[active]
    if ask.any():
        f[ask] = np.asarray(fn(x[ask], active[ask]), dtype=float)
    return f


def _check(x1, f1, x2, f2, status, frtol, fatol: float, xatol: float, xrtol: float):
    """SciPy's termination tests: (stop, xmin, dx, tol), ``status`` set in place."""
    i = np.abs(f1) < np.abs(f2)
    xmin = np.where(i, x1, x2)
    fmin = np.where(i, f1, f2)
    stop = np.zeros(x1.shape, dtype=bool)
    i = np.abs(fmin) <= fatol + frtol
    status[i] = CONVERGED
    stop[i] = True
    i = (np.sign(f1) == np.sign(f2)) & ~stop
    xmin[i], fmin[i], status[i] = np.nan, np.nan, SIGN_ERROR
    stop[i] = True
    x_nonfinite = ~(np.isfinite(x1) & np.isfinite(x2))
    f_nan = np.isnan(f1) & np.isnan(f2)
    i = (x_nonfinite | f_nan) & ~stop
    xmin[i], fmin[i], status[i] = np.nan, np.nan, VALUE_ERROR
    stop[i] = True
    dx = np.abs(x2 - x1)
    tol = np.abs(xmin) * xrtol + xatol
    i = dx < tol
    status[i] = CONVERGED
    stop[i] = True
    return stop, xmin, dx, tol


def _step_fraction(x1, f1, x2, f2, x3, f3, dx, tol) -> np.ndarray:
    """Where in [x1, x2] the next point lies, as a fraction of the bracket: inverse quadratic
    interpolation through the three last points where it is safe (Chandrupatla's test), the
    bisection's 0.5 elsewhere, kept a half tolerance inside the bracket's ends."""
    xi1 = (x1 - x2) / (x3 - x2)
    phi1 = (f1 - f2) / (f3 - f2)
    alpha = (x3 - x1) / (x2 - x1)
    j = ((1 - np.sqrt(1 - xi1)) < phi1) & (phi1 < np.sqrt(xi1))
    f1j, f2j, f3j, alphaj = f1[j], f2[j], f3[j], alpha[j]
    t = np.full_like(alpha, 0.5)
    t[j] = (f1j / (f1j - f2j) * f3j / (f3j - f2j)
            - alphaj * f1j / (f3j - f1j) * f2j / (f2j - f3j))
    tl = 0.5 * tol / dx
    return np.clip(t, tl, 1 - tl)
