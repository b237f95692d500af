"""Neural-network predictors for the learned maps: an ensemble of monotone networks.

Each member is a :class:`~surrogate.learn.monotone_nn.SignConstrainedNet`, saved as its
``state_dict`` (``flow_0.pt``, ...) and read back with ``torch.load(weights_only=True)``, so
loading never executes code. Inference runs in numpy. The ensemble averages the members'
corrections R; each member obeys the slope bounds that make the maps monotone, and so does any
average of them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..learn.monotone_nn import Architecture, NumpyNet

#: what the network's output R means, and how the map's target follows from it
OUTPUTS = {"log_discharge": lambda r: r,  # flow: R = ln C_d
           "fraction": np.expm1,  # force: R = ln(1 + α)
           "closing_fraction": lambda r: np.expm1(-np.logaddexp(0.0, -r))}  # α in (−1, 0)


class NetworkEnsemble:
    """Mean correction of several networks, turned into the map's target."""

    def __init__(self, architecture: Architecture, states: list[dict[str, np.ndarray]],
                 feature_mean: np.ndarray, feature_std: np.ndarray, output: str):
        if output not in OUTPUTS:
            raise ValueError(f"unknown network output {output!r}")
        self.architecture = architecture
        self.states = states
        self.members = [NumpyNet(architecture, state) for state in states]
        self.feature_mean = np.asarray(feature_mean, float)
        self.feature_std = np.asarray(feature_std, float)
        self.output = output

    def correction(self, features: np.ndarray) -> np.ndarray:
        """R averaged over the members."""
        z = (features - self.feature_mean) / self.feature_std
        return np.mean([member(z) for member in self.members], axis=0)

    def predict(self, features: np.ndarray, return_std: bool = False):
        value = OUTPUTS[self.output](self.correction(features))
        return (value, None) if return_std else value

    def describe(self) -> dict:
        return {"architecture": self.architecture.to_dict(), "members": len(self.members),
                "parameters": self.architecture.parameter_count * len(self.members),
                "output": self.output, "feature_mean": self.feature_mean.tolist(),
                "feature_std": self.feature_std.tolist()}


def save_ensemble(folder: Path, name: str, ensemble: NetworkEnsemble) -> dict:
    """Write the members' state_dicts; return the manifest entry describing them."""
    import torch

    files = []
    for index, state in enumerate(ensemble.states):
        path = folder / f"{name}_{index}.pt"
        torch.save({key: torch.as_tensor(value) for key, value in state.items()}, path)
        files.append(path.name)
    return {**ensemble.describe(), "files": files}


def _load_ensemble(folder: Path, entry: dict) -> NetworkEnsemble:
    import torch

    states = []
    for name in entry["files"]:
        path = folder / name
        try:
            state = torch.load(path, weights_only=True, map_location="cpu")
        except Exception as error:  # missing, truncated, or not plain tensors (pickled code)
            first_line = str(error).strip().splitlines()[0] if str(error).strip() else ""
            raise InputError(f"{path}: cannot load network weights as plain tensors "
                             f"({type(error).__name__}: {first_line})") from None
        states.append({key: value.numpy() for key, value in state.items()})
    return NetworkEnsemble(Architecture.from_dict(entry["architecture"]), states,
                           entry["feature_mean"], entry["feature_std"], entry["output"])


def load_predictors(folder: Path, manifest: dict) -> tuple[NetworkEnsemble, NetworkEnsemble]:
    """The flow and force ensembles of a saved NN surrogate."""
    return (_load_ensemble(folder, manifest["flow"]["predictor"]),
            _load_ensemble(folder, manifest["force"]["predictor"]))
