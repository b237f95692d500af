"""The maps' discrepancy: its basis."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.fitting.discrepancy import hat_weights, knots
from surrogate.description.presets import cfda

KNOTS = np.array([0.05, 0.1, 0.2, 0.63]) * 1e-3


def test_hat_weights_square_sum_to_one_and_are_local():
    u = np.array([0.01, 0.05, 0.07, 0.2, 0.4, 0.63, 2.0]) * 1e-3
    weights = hat_weights(u, KNOTS)
    np.testing.assert_allclose((weights**2).sum(axis=1), 1.0)
    # at a knot only its own hat; between two knots only those two; beyond the ends held
    assert np.count_nonzero(weights[1]) == 1 and weights[1, 0] == pytest.approx(1.0)
    assert set(np.flatnonzero(weights[2])) == {0, 1}
    np.testing.assert_allclose(weights[0], weights[1])
    np.testing.assert_allclose(weights[-1], weights[-2])


def test_knots_sit_at_the_samples_inside_the_gap_and_below_the_smallest_opening():
    """A map's error is shared by nearby openings: the knots are the sampled openings, points
    inside the unsampled 0.20–0.63 mm gap and one below the smallest opening."""
    at = knots(cfda().build()) * 1e3  # [mm]
    sampled = [0.05, 0.08, 0.1, 0.13, 0.16, 0.2, 0.63]
    assert all(np.isclose(at, opening).any() for opening in sampled)
    inside = at[(at > 0.2 + 1e-9) & (at < 0.63 - 1e-9)]
    assert len(inside) == 2
    np.testing.assert_allclose(np.log(inside / 0.2) / np.log(0.63 / 0.2), [1 / 3, 2 / 3])
    assert at.min() == pytest.approx(0.05 * 0.3)
