"""Vectorised root finding for monotone functions of one variable, one root per point.

Both the valve solver (u for each operating point) and the maps (Δp for a flow, or the flow for a
Δp) need thousands of independent one-dimensional roots. They are found together with Chandrupatla's
bracketing method, :func:`scipy.optimize.elementwise.find_root`'s to the bit without its framework
(:mod:`.chandrupatla`), which keeps the guarantee of bisection and converges superlinearly, and
only evaluates the points that are still iterating.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .chandrupatla import CONVERGED, chandrupatla

@dataclass(frozen=True)
class Roots:
    """Roots of many functions. ``x`` is NaN where ``converged`` is False; ``status`` is
    find_root's code (-1 no sign change, -2 iteration limit, -3 non-finite function value)."""

    x: np.ndarray
    converged: np.ndarray
    status: np.ndarray


def find_roots(fn: Callable[[np.ndarray, np.ndarray], np.ndarray], lower, upper, *,
               xatol: float, xrtol: float = 1e-13, fatol: float = 0.0,
               maxiter: int = 200, f_lower=None, f_upper=None, f_middle=None) -> Roots:
    """Solve ``fn(x, index) = 0`` for every point, with the root bracketed by [lower, upper].

    Parameters
    ----------
    fn : callable
        ``fn(x, index)`` returns the function values at ``x`` for the points ``index`` (an integer
        array into the caller's per-point data); ``x`` and ``index`` have the same length.
    lower, upper : numpy.ndarray
        Bracket ends, one per point, with ``fn`` of opposite signs at them.
    xatol, xrtol, fatol : float
        Absolute and relative tolerance on the root, absolute tolerance on the function value.
    maxiter : int
        Iteration limit; points that reach it are reported as not converged.
    f_lower, f_upper : numpy.ndarray, optional
        ``fn`` at the bracket ends, if the caller has them already (having checked the bracket):
        they then stand in for the method's first two evaluations.
    f_middle : tuple of numpy.ndarray, optional
        (values, known): ``fn`` at each bracket's middle, lower + 0.5·(upper − lower), where
        the method's first step lands, for the points ``known`` (found beside the ends' values,
        in the same call); the method asks ``fn`` for the others.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    if lower.ndim != 1 or lower.shape != upper.shape:
        raise ValueError("find_roots needs one-dimensional brackets of equal length, one per point")
    if lower.size == 0:
        empty = np.empty(0)
        return Roots(empty, empty.astype(bool), empty.astype(int))
    index = np.arange(lower.size)
    # the ends' values: the caller's (having checked the bracket), or one evaluation each
    if f_lower is None or f_upper is None:
        f_lower, f_upper = fn(lower, index), fn(upper, index)
    x, status = chandrupatla(fn, lower, upper, f_lower, f_upper, xatol=xatol, xrtol=xrtol,
                             fatol=fatol, maxiter=maxiter, f_first=f_middle)
    converged = status == CONVERGED
    return Roots(np.where(converged, x, np.nan), converged, status)


def invert_increasing(fn: Callable[[np.ndarray, np.ndarray], np.ndarray], target: np.ndarray,
                      start: np.ndarray, *, xatol: float, xrtol: float = 1e-12,
                      growth: float = 4.0, max_growths: int = 60) -> Roots:
    """Solve ``fn(x, index) = target`` for x >= 0, ``fn`` non-decreasing in x with fn(0) <= target.

    The upper bracket end starts at ``start`` and grows geometrically until it passes the target,
    so no a-priori bound on x is needed (used to turn a flow into a pressure drop and back).
    """
    target = np.asarray(target, float)
    upper = np.broadcast_to(np.asarray(start, float), target.shape).copy()
    pending = np.arange(target.size)
    for _ in range(max_growths):
        below = fn(upper[pending], pending) < target[pending]
        pending = pending[below]
        if pending.size == 0:
            break
        upper[pending] *= growth
    lower = np.zeros_like(upper)
    return find_roots(lambda x, i: fn(x, i) - target[i], lower, upper, xatol=xatol, xrtol=xrtol)
