"""The per-opening (per-mesh) bias of a learned map, as a term of its own.

Every sampled opening is a CFD mesh of its own, and each mesh errs by a bias of its own (Table 4
of the paper: the flow moves by about 1 % between meshes). A map smooth in the opening cannot
follow those biases, and should not between openings, where they are unknown; at a sampled
opening they are known from the samples there. So the map's latent output gets

    b(x) = Σ_k b_k · max(0, 1 − |x − x_k| / h),

x the opening's feature (ln(u/U) [-]), x_k the sampled openings' values, b_k the mean residual of
the map's training samples at opening k, and h half the closest spacing of two sampled openings:
each bump is b_k on its opening and has faded to 0 halfway to the next, so between openings the
smooth map speaks alone. Fitted after the networks, from their residuals on the training data.

Measured on the NN's flow map (ln C_d, the four cross-validation schemes, 3 members): C_d error
by k-fold / left-out opening / left-out temperature / back-pressure set 0.418 / 0.379 / 0.624 /
0.911 % without, 0.392 / 0.379 / 0.603 / 0.856 % with (the left-out opening, ≥ 0.21 in ln u from
every other, untouched); a shrinkage of b_k toward 0 (n/(n + 5)) did no better.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from . import package
from .network import bump_weights


@dataclass(frozen=True)
class OpeningOffsets:
    """b(x) of the module docstring on feature ``column`` (``knots`` x_k increasing and
    ``offsets`` b_k [latent units], ``half_width`` h [feature units])."""

    column: int
    knots: np.ndarray
    offsets: np.ndarray
    half_width: float

    @classmethod
    def fit(cls, features: np.ndarray, residuals: np.ndarray, column: int) -> "OpeningOffsets":
        """The mean residual (target − map) of the samples at each distinct value of
        ``features[:, column]``; with a single opening, no bump can fade, so none is fitted."""
        x = np.round(np.asarray(features, float)[:, column], 9)
        knots = np.unique(x)
        residuals = np.asarray(residuals, float)
        offsets = np.array([residuals[x == knot].mean() for knot in knots])
        if len(knots) < 2:
            return cls(column, knots, np.zeros_like(offsets), 1.0)
        return cls(column, knots, offsets, float(np.min(np.diff(knots))) / 2)

    def __call__(self, features: np.ndarray) -> np.ndarray:
        """b at each row of ``features`` (n, columns) [latent units]."""
        x = np.asarray(features, float)[:, self.column]
        return bump_weights(x, self.knots, self.half_width) @ self.offsets

    def to_dict(self) -> dict:
        return {"column": self.column, "knots": self.knots.tolist(),
                "offsets": self.offsets.tolist(), "half_width": self.half_width}

    @classmethod
    def from_dict(cls, data, where: str, features: int) -> "OpeningOffsets":
        """Read back from a manifest, checked (``where`` names the place in it)."""
        column = package.number(data, "column", where, low=0, high=features - 1)
        if column != int(column):
            raise InputError(f"{package.place(where, 'column')}: must be a whole number")
        knots = package.numbers(data, "knots", where, (None,))
        offsets = package.numbers(data, "offsets", where, (len(knots),))
        if len(knots) == 0 or np.any(np.diff(knots) <= 0):
            raise InputError(f"{package.place(where, 'knots')}: must be one or more numbers, "
                             "increasing")
        if np.any(np.abs(offsets) > 1.0):
            raise InputError(f"{package.place(where, 'offsets')}: each must lie in [-1, 1] "
                             "(a mesh's bias of ln C_d is a few percent)")
        half_width = package.number(data, "half_width", where, low=0.0, above=True)
        return cls(int(column), knots, offsets, half_width)
