"""Where a learned map has data: the region of feature space its training samples cover.

A query is inside when each feature lies within the training range (plus 2 % of it) *and* the
query is no farther from its nearest training sample than the training samples are from each other
at most (distances in standardised features). The second test catches the holes of a
non-rectangular grid, e.g. high flows at small openings that the CFD never ran.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_RANGE_SLACK = 0.02
_CHUNK = 4096


@dataclass(frozen=True)
class FeatureDomain:
    """Bounding box and sample cloud of the training features."""

    lower: np.ndarray
    upper: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    points: np.ndarray  # standardised training features
    reach: float  # largest distance from a training sample to its nearest neighbour

    @classmethod
    def fit(cls, features: np.ndarray) -> "FeatureDomain":
        mean, std = features.mean(axis=0), features.std(axis=0)
        std = np.where(std > 0, std, 1.0)
        points = (features - mean) / std
        distances = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
        np.fill_diagonal(distances, np.inf)
        reach = float(np.max(np.min(distances, axis=1))) if len(points) > 1 else 0.0
        return cls(features.min(axis=0), features.max(axis=0), mean, std, points, reach)

    def distance(self, features: np.ndarray) -> np.ndarray:
        """Distance from each query (row of ``features``) to the nearest training sample, in
        standardised features."""
        nearest = np.empty(len(features))
        scaled = (features - self.mean) / self.std
        for start in range(0, len(features), _CHUNK):
            block = scaled[start:start + _CHUNK]
            nearest[start:start + _CHUNK] = np.sqrt(np.maximum(np.min(
                np.sum(block**2, axis=1)[:, None] + np.sum(self.points**2, axis=1)[None, :]
                - 2.0 * block @ self.points.T, axis=1), 0.0))
        return nearest

    def contains(self, features: np.ndarray) -> np.ndarray:
        """True where a query (row of ``features``) lies inside the data."""
        slack = _RANGE_SLACK * (self.upper - self.lower)
        inside = np.all((features >= self.lower - slack) & (features <= self.upper + slack), axis=1)
        return inside & (self.distance(features) <= self.reach * (1 + 1e-9))

    def to_dict(self) -> dict:
        return {"lower": self.lower.tolist(), "upper": self.upper.tolist(),
                "mean": self.mean.tolist(), "std": self.std.tolist(),
                "points": self.points.tolist(), "reach": self.reach}

    @classmethod
    def from_dict(cls, data: dict) -> "FeatureDomain":
        return cls(*(np.asarray(data[key], float) for key in ("lower", "upper", "mean", "std",
                                                               "points")), float(data["reach"]))
