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


_KEY_STRIDE = 1e4  # curves' knot ranges are laid side by side at this spacing for one search
_KEY_RANGE = 4e3  # |x| is clipped below this for the search only (x are logarithms)
#: curves with at most this many inner knots (all but the first and the last) find a query's
#: segment by comparing its key with each of them; curves with more, by a binary search
COMPARED_KNOTS = 8


class CurveSet:
    """A set of PCHIP curves y_c(x).

    Parameters
    ----------
    curves : sequence of (x, y)
        Knots of each curve; x strictly increasing, at least two knots per curve.
    outside : {"tangent", "hold"}
        Beyond its knots a curve continues along its end tangent (linear, C¹) or holds its end
        value.

    Notes
    -----
    All knots are stored flat, curve after curve, with a search key ``c·stride + x`` that is
    increasing over the whole set; one :func:`numpy.searchsorted` then finds the segment of every
    (curve, x) query at once.
    """

    def __init__(self, curves, outside: Outside):
        if outside not in ("tangent", "hold"):
            raise ValueError(f"outside must be 'tangent' or 'hold', got {outside!r}")
        self.outside = outside
        xs, ys, slopes, counts = [], [], [], []
        for c, (x, y) in enumerate(curves):
            x, y = np.asarray(x, float), np.asarray(y, float)
            if len(x) < 2 or np.any(np.diff(x) <= 0):
                raise ValueError(f"curve {c}: need at least two strictly increasing knots")
            if np.any(np.abs(x) >= _KEY_RANGE):
                raise ValueError(f"curve {c}: knots must lie within ±{_KEY_RANGE:g}")
            xs.append(x)
            ys.append(y)
            slopes.append(PchipInterpolator(x, y).derivative()(x))
            counts.append(len(x))
        self.n = np.asarray(counts, dtype=np.intp)
        self.start = np.concatenate([[0], np.cumsum(self.n)[:-1]]).astype(np.intp)
        self.x = np.concatenate(xs)
        self.y = np.concatenate(ys)
        self.slope = np.concatenate(slopes)
        self._keys = np.repeat(np.arange(len(self.n)) * _KEY_STRIDE, self.n) + self.x
        self.lower = self.x[self.start]
        self.upper = self.x[self.start + self.n - 1]
        # row j: each curve's key of its inner knot j + 1, +inf where the curve has none. A
        # query's segment is how many of its curve's inner keys lie at or below the query's
        # key: the binary search's answer clipped to the curve's segments, without a search
        # through the whole set for a curve of a few knots
        inner = int(self.n.max()) - 2
        self._inner_keys = None
        if inner <= COMPARED_KNOTS:
            self._inner_keys = np.full((inner, len(self.n)), np.inf)
            for j in range(inner):
                has = self.n > j + 2
                self._inner_keys[j, has] = self._keys[self.start[has] + j + 1]
        # each segment as a cubic in s = x − x0: y = c0 + c1·s + c2·s² + c3·s³ (the last knot of
        # each curve gets a dummy segment that is never selected)
        h = np.append(np.diff(self.x), 1.0)
        h[self.start + self.n - 1] = 1.0
        dy = np.append(np.diff(self.y), 0.0)
        d0, d1 = self.slope, np.append(self.slope[1:], 0.0)
        secant = dy / h
        self._c = np.stack([self.y, d0, (3 * secant - 2 * d0 - d1) / h,
                            (d0 + d1 - 2 * secant) / h**2])

    def __len__(self) -> int:
        return len(self.n)

    def __call__(self, curve: np.ndarray, x: np.ndarray) -> np.ndarray:
        """y of curve ``curve[i]`` at ``x[i]`` for every i."""
        # np.take and minimum/maximum rather than fancy indexing and np.clip: the same values
        # at a fraction of the overhead, which the grid maps pay at every solver iteration
        curve = np.asarray(curve, dtype=np.intp)
        x = np.asarray(x, float)
        start = self.start.take(curve)
        keys = curve * _KEY_STRIDE + np.minimum(np.maximum(x, -_KEY_RANGE), _KEY_RANGE)
        # flat index of the segment's left knot
        if self._inner_keys is None:
            segment = np.searchsorted(self._keys, keys, side="right") - 1 - start
            first = start + np.minimum(np.maximum(segment, 0), self.n.take(curve) - 2)
        else:  # a NaN x lands on the first segment instead of the last: its y is NaN on either
            first = start
            for inner in self._inner_keys:
                first += inner.take(curve) <= keys
        x0, x1 = self.x.take(first), self.x.take(first + 1)
        offset = np.minimum(np.maximum(x, x0), x1) - x0
        c0, c1, c2, c3 = (row.take(first) for row in self._c)
        y = c0 + offset * (c1 + offset * (c2 + offset * c3))
        if self.outside == "tangent":
            # the tangents add exact zeros within the knots, which leave y as it is but for a
            # zero's sign: they are added where a query lies outside, or y is zero
            beyond = np.flatnonzero((x < x0) | (x > x1) | (y == 0.0))
            if beyond.size:
                at, left, right = x[beyond], x0[beyond], x1[beyond]
                below, above = np.minimum(at - left, 0.0), np.maximum(at - right, 0.0)
                y[beyond] = (y[beyond] + self.slope.take(first[beyond]) * below
                             + self.slope.take(first[beyond] + 1) * above)
        return y

    def inside(self, curve: np.ndarray, x: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
        """True where ``x[i]`` lies within the knots of curve ``curve[i]``."""
        curve = np.asarray(curve, dtype=np.intp)
        lower, upper = self.lower[curve], self.upper[curve]
        slack = rtol * np.maximum(np.abs(lower), np.abs(upper)) + 1e-12
        return (x >= lower - slack) & (x <= upper + slack)
