"""Each sampled opening's own bias (surrogate/maps/opening_offsets.py): known where sampled,
faded to nothing between openings, saved and read back checked."""

import numpy as np
import pytest

from surrogate.core.errors import InputError
from surrogate.maps.opening_offsets import OpeningOffsets


def three_openings():
    """Samples at three openings (column 1, in ln u) whose residuals average 0.01, -0.02, 0.005."""
    x = np.repeat(np.log([0.1, 0.2, 0.6]), 4)
    residuals = np.array([0.0, 0.02, 0.01, 0.01, -0.03, -0.01, -0.02, -0.02,
                          0.005, 0.005, 0.0, 0.01])
    features = np.column_stack([np.linspace(0, 1, 12), x, np.zeros(12)])
    return features, residuals


def test_each_opening_gets_its_mean_residual_and_nothing_halfway_to_the_next():
    features, residuals = three_openings()
    offsets = OpeningOffsets.fit(features, residuals, column=1)
    at = offsets(features)
    assert np.allclose(at, np.repeat([0.01, -0.02, 0.005], 4))
    # half the closest spacing (0.1 to 0.2 mm): the bumps meet nowhere
    assert offsets.half_width == pytest.approx(np.log(2.0) / 2)
    between = np.column_stack([np.zeros(3), np.log([np.sqrt(0.02), 0.35, 0.9]), np.zeros(3)])
    assert np.allclose(offsets(between), 0.0)
    # a quarter of the way: half the nearer opening's offset
    quarter = np.array([[0.0, np.log(0.1) + np.log(2.0) / 4, 0.0]])
    assert offsets(quarter)[0] == pytest.approx(0.005)


def test_a_single_opening_gets_no_offset():
    features, residuals = three_openings()
    offsets = OpeningOffsets.fit(features[:4], residuals[:4], column=1)
    assert np.all(offsets(features) == 0.0)


def test_offsets_read_back_as_written_and_a_bad_entry_is_refused():
    features, residuals = three_openings()
    offsets = OpeningOffsets.fit(features, residuals, column=1)
    again = OpeningOffsets.from_dict(offsets.to_dict(), "surrogate.json: flow:", 3)
    assert np.array_equal(again(features), offsets(features))
    for change, words in ((dict(column=3), "column"), (dict(knots=[0.0, -1.0, 2.0]), "increasing"),
                          (dict(offsets=[0.0, 2.0, 0.0]), "offsets"),
                          (dict(half_width=0.0), "half_width"),
                          (dict(offsets=[0.0, 0.1]), "offsets")):
        with pytest.raises(InputError, match=words):
            OpeningOffsets.from_dict({**offsets.to_dict(), **change}, "surrogate.json: flow:", 3)


def test_the_committed_nn_flow_map_carries_them():
    """The shipped NN flow map reads each opening's bias (0 mid-gap); the NumPy map with the
    offsets removed differs by exactly them at the sampled openings."""
    from surrogate.maps.learned import load_learned_maps, trained_folder

    flow_map, _ = load_learned_maps(trained_folder("nn"))
    ensemble = flow_map.predictor
    offsets = ensemble.opening_offsets
    assert offsets is not None and np.max(np.abs(offsets.offsets)) > 1e-4
    rows = np.column_stack([np.full(len(offsets.knots), 8.0), offsets.knots,
                            np.full(len(offsets.knots), 1.0)])
    with_them = ensemble.latent(rows)
    ensemble.opening_offsets = None
    try:
        without = ensemble.latent(rows)
    finally:
        ensemble.opening_offsets = offsets
    assert np.allclose(with_them - without, offsets.offsets)
