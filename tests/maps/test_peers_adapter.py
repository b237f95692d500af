"""The peer adapter (surrogate/maps/peer.py): a regressor that knows the training targets
reproduces the CFD samples through the adapter's feature and target transforms, and a known error
in α comes out as that error in the flow force."""

import numpy as np
import pytest

from surrogate.fluid import FluidState
from surrogate.maps.crossval import errors_on
from surrogate.maps.peer import INPUTS, fit_peer_maps


class NearestSample:
    """An oracle: the training target of the nearest training input (inputs standardised), times
    ``factor``."""

    def __init__(self, factor: float = 1.0):
        self.factor = factor

    def fit(self, X, y):
        self.centre, self.scale = X.mean(axis=0), X.std(axis=0)
        self.inputs, self.targets = (X - self.centre) / self.scale, np.asarray(y, float)
        return self

    def predict(self, X):
        standardised = (X - self.centre) / self.scale
        squared = ((standardised[:, None, :] - self.inputs[None, :, :]) ** 2).sum(axis=-1)
        return self.factor * self.targets[np.argmin(squared, axis=1)]


@pytest.mark.parametrize("inputs", INPUTS)
def test_an_oracle_reproduces_the_samples_through_the_adapter(inputs, cfd_samples, valve):
    frame = cfd_samples.frame
    flow_map, force_map = fit_peer_maps(frame, valve, NearestSample(), NearestSample(), inputs)
    errors = errors_on(flow_map, force_map, frame, valve)
    assert np.abs(errors["discharge_error"]).max() < 1e-9
    assert np.abs(errors["force_error"]).max() < 1e-9
    # q from p_L goes through the base class's inversion of Δp(q): its tolerance, not exactness
    assert np.abs(errors["q_error"]).max() < 1e-6
    assert (errors["flow_spread"] == 0).all() and (errors["force_spread"] == 0).all()


def test_five_percent_too_much_alpha_is_five_percent_too_much_flow_force(cfd_samples, valve):
    frame = cfd_samples.frame
    flow_map, force_map = fit_peer_maps(frame, valve, NearestSample(), NearestSample(1.05))
    errors = errors_on(flow_map, force_map, frame, valve)
    np.testing.assert_allclose(errors["force_error"], 0.05, atol=1e-9)
    assert np.sqrt(np.mean(errors["force_error"] ** 2)) == pytest.approx(0.05, abs=1e-9)
    assert np.abs(errors["q_error"]).max() < 1e-6  # the flow map is untouched


def test_the_force_is_the_uniform_pressure_force_plus_the_flow_force(cfd_samples, valve):
    frame = cfd_samples.frame
    _, force_map = fit_peer_maps(frame, valve, NearestSample(), NearestSample())
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    args = (frame["p_L"].to_numpy(), frame["p_B"].to_numpy(), frame["u"].to_numpy(), fluid)
    np.testing.assert_allclose(force_map.force(*args), frame["f_sim"], rtol=1e-12)


def test_unknown_inputs_are_refused(cfd_samples, valve):
    with pytest.raises(ValueError, match="inputs must be one of"):
        fit_peer_maps(cfd_samples.frame, valve, NearestSample(), NearestSample(), "kelvin")
