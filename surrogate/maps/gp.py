"""Gaussian-process predictors for the learned maps, stored as npz arrays.

The GP predicts a transformed target; the predictor turns it into the map's target and carries
the standard deviation along (delta method), so the maps report it in their own units.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError
from ..learn.gaussian_process import GPArrays, NumpyGP

#: target transform -> (value, derivative of value w.r.t. the GP's output)
TARGETS = {
    "log_discharge": (lambda m: m, lambda m: np.ones_like(m)),  # flow: ln C_d
    "fraction": (lambda m: m, lambda m: np.ones_like(m)),  # force: α
    "log_negative_fraction": (lambda m: -np.exp(m), lambda m: np.exp(m)),  # force: ln(−α)
}


class GaussianProcessPredictor:
    """A fitted GP and the transform from its output to the map's target."""

    def __init__(self, arrays: GPArrays, target: str):
        if target not in TARGETS:
            raise ValueError(f"unknown GP target {target!r}")
        self.arrays = arrays
        self.gp = NumpyGP(arrays)
        self.target = target

    def predict(self, features: np.ndarray, return_std: bool = False):
        value, slope = TARGETS[self.target]
        if not return_std:
            return value(self.gp.predict(features))
        mean, std = self.gp.predict(features, return_std=True)
        return value(mean), np.abs(slope(mean)) * std

    def describe(self) -> dict:
        a = self.arrays
        return {"target": self.target, "groups": [list(g) for g in a.groups],
                "amplitudes": a.amplitudes.tolist(), "length_scales": a.length_scales.tolist(),
                "noise": a.noise, "condition_number": a.condition_number,
                "training_points": len(a.inputs), "feature_mean": a.feature_mean.tolist(),
                "feature_std": a.feature_std.tolist(), "trend": a.trend.tolist()}


def save_predictor(folder: Path, name: str, predictor: GaussianProcessPredictor) -> dict:
    path = folder / f"{name}.npz"
    np.savez(path, **predictor.arrays.to_npz())
    return {**predictor.describe(), "file": path.name}


def load_predictor(folder: Path, entry: dict) -> GaussianProcessPredictor:
    """A predictor saved by :func:`save_predictor`."""
    path = folder / entry["file"]
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = GPArrays.from_npz(data)
    except (OSError, ValueError, KeyError) as error:
        raise InputError(f"{path}: cannot load GP arrays ({error})") from None
    return GaussianProcessPredictor(arrays, entry["target"])
