"""Gaussian-process maps: an additive anisotropic kernel fitted with scikit-learn, evaluated in numpy.

The kernel mirrors the additive structure of :mod:`surrogate.features`,

    k(x, x') = c1·RBF_(Re, u)(x, x') + c2·RBF_(u, σ)(x, x') + noise·δ(x, x'),

each RBF anisotropic over its two standardised features, with a learned noise term (the CFD's mesh
error is about 1 %). Targets are standardised (``normalize_y``); optionally a linear mean in the
features is fitted first by least squares and the GP models the residual (a physics trend that
the GP reverts to far from the data). Inputs are standardised and everything is float64; the
condition number of the training covariance is recorded, because GPs on gridded data are prone
to ill-conditioning.

For export only arrays are kept (training inputs, dual coefficients, Cholesky factor, kernel
hyperparameters): :class:`NumpyGP` predicts from them with no scikit-learn object and no pickle.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Hyperparameter, Kernel, WhiteKernel

LENGTH_SCALE_BOUNDS = (0.3, 100.0)  # standardised units: smooth on the scale of the data
NOISE_BOUNDS = (1e-8, 1e-2)


class ProjectedRBF(Kernel):
    """An anisotropic RBF kernel on a subset ``dims`` of the input columns."""

    def __init__(self, dims=(0, 1), length_scale=(1.0, 1.0),
                 length_scale_bounds=LENGTH_SCALE_BOUNDS):
        self.dims = dims
        self.length_scale = length_scale
        self.length_scale_bounds = length_scale_bounds

    @property
    def hyperparameter_length_scale(self):
        return Hyperparameter("length_scale", "numeric", self.length_scale_bounds, len(self.dims))

    def __call__(self, X, Y=None, eval_gradient=False):
        rbf = RBF(np.asarray(self.length_scale, float))
        X = np.asarray(X)[:, list(self.dims)]
        Y = None if Y is None else np.asarray(Y)[:, list(self.dims)]
        return rbf(X, Y, eval_gradient=eval_gradient)

    def diag(self, X):
        return np.ones(len(X))

    def is_stationary(self):
        return True


@dataclass(frozen=True)
class GPArrays:
    """Everything a fitted GP needs to predict, as plain arrays and numbers."""

    groups: tuple[tuple[int, ...], ...]
    feature_mean: np.ndarray
    feature_std: np.ndarray
    trend: np.ndarray  # linear mean: intercept then one coefficient per standardised feature
    inputs: np.ndarray  # standardised training features
    dual: np.ndarray  # α = K⁻¹·y (normalised y)
    cholesky: np.ndarray  # lower Cholesky factor of K + noise
    amplitudes: np.ndarray  # c per group
    length_scales: np.ndarray  # (groups, widest group), padded with ones
    noise: float
    y_mean: float
    y_std: float
    condition_number: float

    def to_npz(self) -> dict[str, np.ndarray]:
        return {"groups": np.asarray(self.groups), "feature_mean": self.feature_mean,
                "feature_std": self.feature_std, "trend": self.trend, "inputs": self.inputs,
                "dual": self.dual, "cholesky": self.cholesky, "amplitudes": self.amplitudes,
                "length_scales": self.length_scales, "noise": np.asarray(self.noise),
                "y_mean": np.asarray(self.y_mean), "y_std": np.asarray(self.y_std),
                "condition_number": np.asarray(self.condition_number)}

    @classmethod
    def from_npz(cls, data) -> "GPArrays":
        return cls(tuple(tuple(int(i) for i in g) for g in data["groups"]),
                   *(np.asarray(data[key], float) for key in (
                       "feature_mean", "feature_std", "trend", "inputs", "dual", "cholesky",
                       "amplitudes", "length_scales")),
                   *(float(data[key]) for key in ("noise", "y_mean", "y_std",
                                                  "condition_number")))


def fit_gp(features: np.ndarray, target: np.ndarray, groups, *, linear_mean: bool,
           restarts: int = 3, seed: int = 0) -> GPArrays:
    """Fit the additive GP to ``target`` and return its arrays."""
    feature_mean = features.mean(axis=0)
    feature_std = np.where(features.std(axis=0) > 0, features.std(axis=0), 1.0)
    z = (features - feature_mean) / feature_std
    design = np.column_stack([np.ones(len(z)), z])
    if linear_mean:
        trend = np.linalg.lstsq(design, target, rcond=None)[0]
    else:
        trend = np.zeros(design.shape[1])
    residual = target - design @ trend
    kernel = None
    for group in groups:
        part = ConstantKernel(1.0, (1e-4, 1e3)) * ProjectedRBF(tuple(group), (1.0,) * len(group))
        kernel = part if kernel is None else kernel + part
    kernel = kernel + WhiteKernel(1e-4, NOISE_BOUNDS)
    regressor = GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=restarts,
                                         random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # a bound reached is reported below
        regressor.fit(z, residual)
    fitted = regressor.kernel_
    parts = _parts(fitted, len(groups))
    covariance = fitted(z)
    widest = max(len(g) for g in groups)
    scales = np.ones((len(groups), widest))
    for row, (_, ell) in enumerate(parts):
        scales[row, : len(ell)] = ell
    return GPArrays(
        tuple(tuple(g) for g in groups), feature_mean, feature_std, trend, z,
        np.asarray(regressor.alpha_, float).ravel(), np.asarray(regressor.L_, float),
        np.array([c for c, _ in parts]), scales,
        float(fitted.k2.noise_level), float(regressor._y_train_mean),
        float(regressor._y_train_std), float(np.linalg.cond(covariance)))


def _parts(kernel, count: int):
    """[(amplitude, length scales)] of the additive parts of a fitted kernel, in order."""
    sums = kernel.k1  # the kernel is ((part1 + part2) + ...) + white
    parts = []
    for _ in range(count - 1):
        parts.append(sums.k2)
        sums = sums.k1
    parts.append(sums)
    parts.reverse()
    return [(float(p.k1.constant_value), np.atleast_1d(np.asarray(p.k2.length_scale, float)))
            for p in parts]


class NumpyGP:
    """Mean and latent standard deviation of a fitted GP from its :class:`GPArrays`."""

    def __init__(self, arrays: GPArrays):
        self.arrays = arrays
        # training side of each part, scaled by its length scales, with squared norms
        self._parts = []
        for group, amplitude, scales in zip(arrays.groups, arrays.amplitudes,
                                            arrays.length_scales):
            cols = list(group)
            scaled = arrays.inputs[:, cols] / scales[: len(cols)]
            self._parts.append((cols, scales[: len(cols)], amplitude, scaled,
                                np.sum(scaled**2, axis=1)))

    def _cross(self, z: np.ndarray) -> np.ndarray:
        """k(z, training inputs), using |a − b|² = |a|² + |b|² − 2·a·b (a matrix product)."""
        total = np.zeros((len(z), len(self.arrays.inputs)))
        for cols, scales, amplitude, scaled, norms in self._parts:
            query = z[:, cols] / scales
            squared = np.sum(query**2, axis=1)[:, None] + norms[None, :] - 2.0 * query @ scaled.T
            total += amplitude * np.exp(-0.5 * np.maximum(squared, 0.0))
        return total

    def predict(self, features: np.ndarray, return_std: bool = False):
        """Mean (and latent standard deviation) of the target at each row of ``features``."""
        a = self.arrays
        z = (features - a.feature_mean) / a.feature_std
        cross = self._cross(z)
        mean = a.y_mean + a.y_std * (cross @ a.dual) + np.column_stack([np.ones(len(z)), z]) @ a.trend
        if not return_std:
            return mean
        v = solve_triangular(a.cholesky, cross.T, lower=True, check_finite=False)
        variance = np.sum(a.amplitudes) - np.sum(v**2, axis=0)
        return mean, a.y_std * np.sqrt(np.clip(variance, 0.0, None))
