"""Many monotone 1-D curves, each through its own knots, evaluated for many points at once.

Each curve is a piecewise-cubic Hermite interpolant with PCHIP slopes (Fritsch–Carlson, as
:class:`scipy.interpolate.PchipInterpolator`): C¹, and monotone wherever the data are, so a solver
iterating on it meets neither kinks nor spurious wiggles. The grid maps keep one curve per CFD
sweep (one opening, one fluid state) in a single :class:`CurveSet` and evaluate a whole batch of
(curve, x) pairs with array operations only.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.interpolate import PchipInterpolator

Outside = Literal["tangent", "hold"]


class CurveSet:
    """A set of PCHIP curves y_c(x).

    Parameters
    ----------
    curves : sequence of (x, y)
        Knots of each curve; x strictly increasing, at least two knots per curve.
    outside : {"tangent", "hold"}
        Beyond its knots a curve continues along its end tangent (linear, C¹) or holds its end
        value.
    """

    def __init__(self, curves, outside: Outside):
        if outside not in ("tangent", "hold"):
            raise ValueError(f"outside must be 'tangent' or 'hold', got {outside!r}")
        self.outside = outside
        n_max = max(len(x) for x, _ in curves)
        count = len(curves)
        self.x = np.full((count, n_max), np.inf)
        self.y = np.zeros((count, n_max))
        self.slope = np.zeros((count, n_max))
        self.n = np.empty(count, dtype=np.intp)
        for c, (x, y) in enumerate(curves):
            x, y = np.asarray(x, float), np.asarray(y, float)
            if len(x) < 2 or np.any(np.diff(x) <= 0):
                raise ValueError(f"curve {c}: need at least two strictly increasing knots")
            self.x[c, : len(x)] = x
            self.y[c, : len(x)] = y
            self.slope[c, : len(x)] = PchipInterpolator(x, y).derivative()(x)
            self.n[c] = len(x)
        rows = np.arange(count)
        self.lower = self.x[:, 0].copy()
        self.upper = self.x[rows, self.n - 1]

    def __len__(self) -> int:
        return len(self.n)

    def __call__(self, curve: np.ndarray, x: np.ndarray) -> np.ndarray:
        """y of curve ``curve[i]`` at ``x[i]`` for every i."""
        curve = np.asarray(curve, dtype=np.intp)
        x = np.asarray(x, float)
        knots = self.x[curve]
        n = self.n[curve]
        # segment i has knots i and i+1; padding knots are +inf and never counted
        segment = np.clip(np.sum(x[:, None] >= knots[:, 1:], axis=1), 0, n - 2)
        x0, x1 = knots[np.arange(len(x)), segment], knots[np.arange(len(x)), segment + 1]
        rows = (curve, segment)
        y0, y1 = self.y[rows], self.y[curve, segment + 1]
        d0, d1 = self.slope[rows], self.slope[curve, segment + 1]
        inside_x = np.clip(x, x0, x1)
        h = x1 - x0
        t = (inside_x - x0) / h
        t2, t3 = t * t, t * t * t
        y = ((2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * h * d0
             + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * h * d1)
        if self.outside == "tangent":
            y = y + np.where(x < x0, d0 * (x - x0), 0.0) + np.where(x > x1, d1 * (x - x1), 0.0)
        return y

    def inside(self, curve: np.ndarray, x: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
        """True where ``x[i]`` lies within the knots of curve ``curve[i]``."""
        curve = np.asarray(curve, dtype=np.intp)
        lower, upper = self.lower[curve], self.upper[curve]
        slack = rtol * np.maximum(np.abs(lower), np.abs(upper)) + 1e-12
        return (x >= lower - slack) & (x <= upper + slack)
