"""The bridged flow-force network: its NumPy evaluation is the trained PyTorch module, networks
saved before the pressure-level slope still load, and the slope does not run off where a sweep
is missing."""

import numpy as np
import pytest
import torch

from surrogate.features import FeatureSpec, targets
from surrogate.learn.bridged_nn import TorchBridgedNet
from surrogate.learn.training import _bridged_ensemble
from surrogate.maps.crossval import folds
from surrogate.maps.network import BridgedArchitecture, BridgedNet, hat_weights, hold


@pytest.mark.parametrize("level_column, trend_width", ((None, 0), (3, 0), (3, 4)))
def test_the_numpy_network_is_the_torch_module(level_column, trend_width):
    """Random parameters, queries inside and beyond the knots and the held ranges."""
    trend_held = {1: (-1.2, 1.5), 0: (-1.0, 1.0)} if trend_width else {}
    architecture = BridgedArchitecture((-1.2, -0.3, 0.4, 1.5), 5,
                                       held={0: (-2.0, 2.0), 3: (-1.5, 1.5)},
                                       level_column=level_column, trend_width=trend_width,
                                       trend_held=trend_held)
    module = TorchBridgedNet(architecture, seed=3, offset=0.2)
    with torch.no_grad():
        for parameter in module.parameters():
            parameter.add_(torch.randn(parameter.shape, dtype=torch.float64) * 0.3)
    state = {key: value.detach().numpy() for key, value in module.state_dict().items()}
    assert set(state) == set(architecture.parameter_shapes())
    z = np.random.default_rng(0).normal(0.0, 2.0, (400, 4))
    held = hold(z, architecture.held)
    expected = module(torch.as_tensor(hat_weights(z[:, 1], architecture.knots)),
                      torch.as_tensor(held[:, 0]), torch.as_tensor(held[:, 2]),
                      None if level_column is None else torch.as_tensor(held[:, 3]),
                      torch.as_tensor(hold(z, trend_held)[:, [1, 0]]))
    np.testing.assert_allclose(BridgedNet(architecture, state)(z), expected.detach().numpy(),
                               rtol=1e-12, atol=1e-12)


def test_an_architecture_saved_without_the_level_slope_reads_three_columns():
    saved = {"type": "bridged", "knots": [-1.0, 1.0], "width": 4, "bridge_column": 1,
             "local_column": 0, "shared_column": 2, "held": {"0": [-2.0, 2.0]}}
    architecture = BridgedArchitecture.from_dict(saved)
    assert architecture.level_column is None
    assert "local_m" not in architecture.parameter_shapes()
    assert architecture.problem(3) is None
    assert architecture.to_dict() == saved
    with_level = BridgedArchitecture.from_dict({**saved, "level_column": 3})
    assert with_level.problem(3) is not None and with_level.problem(4) is None
    assert with_level.parameter_count == architecture.parameter_count + 2


def test_an_architecture_with_a_trend_round_trips_and_one_without_reads_as_before():
    plain = BridgedArchitecture((-1.0, 1.0), 4, held={0: (-2.0, 2.0)}, level_column=3)
    trended = BridgedArchitecture((-1.0, 1.0), 4, held={0: (-2.0, 2.0)}, level_column=3,
                                  trend_width=6, trend_held={1: (-1.0, 1.0), 0: (-1.5, 1.5)})
    assert "trend_width" not in plain.to_dict()
    assert BridgedArchitecture.from_dict(trended.to_dict()) == trended
    assert trended.parameter_count == plain.parameter_count + 6 * 4 + 2
    assert BridgedArchitecture((-1.0, 1.0), 4, trend_width=-1).problem(3) is not None
    assert BridgedArchitecture((-1.0, 1.0), 4, trend_width=2,
                               trend_held={2: (0.0, 1.0)}).problem(3) is not None


def test_the_level_slopes_hold_where_a_left_out_sweep_leaves_a_hole(cfd_samples, valve):
    """The fold of the k-fold scheme where one free slope per opening missed the left-out
    sweeps by 40 % (neighbouring slopes kept close: 2.6 %; the three-feature network 3.0 %)."""
    fold = [f for f in folds(cfd_samples.frame) if f.label == "fold 4"][0]
    spec = FeatureSpec.for_valve(valve)
    train = targets(spec, cfd_samples.frame[fold.train])
    test = targets(spec, cfd_samples.frame[fold.test])
    import surrogate.learn.training as training

    members, training.NN_MEMBERS = training.NN_MEMBERS, 2
    try:
        ensemble = _bridged_ensemble(train, lambda message: None)
    finally:
        training.NN_MEMBERS = members
    assert ensemble.architecture.level_column == 3
    alpha = ensemble.predict(test.force_features)
    error = np.sqrt(np.mean((alpha / test.flow_force_fraction - 1.0) ** 2))
    assert error < 0.06, error


def test_the_smoothed_bridge_is_each_opening_on_it_and_a_polynomial_across_them_between():
    """BridgedArchitecture.smoothing_degree: on a knot the weights pick that opening's network
    alone; halfway between knots values lying on a cubic are interpolated as the cubic's
    straight chord, and one opening's outlier (its mesh's bias) moves the mid-gap value less
    than the straight bridge lets it."""
    from surrogate.maps.network import bridge_weights, hat_weights

    knots = np.log([0.05, 0.08, 0.10, 0.13, 0.16, 0.20, 0.63])
    assert np.allclose(bridge_weights(knots, knots, 3), np.eye(len(knots)))
    middle = (knots[5] + knots[6]) / 2
    x = np.array([middle, knots[2] + 0.01, knots[0] - 1.0])
    weights = bridge_weights(x, knots, 3)
    assert np.allclose(weights.sum(axis=1), 1.0)
    cubic = 0.3 * knots**3 - knots**2 + 0.5
    chord = hat_weights(x[:1], knots) @ cubic  # the straight line between the cubic's values
    assert weights[0] @ cubic == pytest.approx(chord[0])
    outlier = cubic + np.eye(len(knots))[5] * 0.05  # 0.20 mm off by 5 %
    moved_smoothed = weights[0] @ (outlier - cubic)
    moved_straight = hat_weights(x[:1], knots)[0] @ (outlier - cubic)
    assert abs(moved_smoothed) < 0.7 * abs(moved_straight)  # 0.65 with these knots
    assert np.allclose(bridge_weights(x, knots, 0), hat_weights(x, knots))
