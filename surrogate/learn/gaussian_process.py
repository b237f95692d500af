"""Gaussian-process maps: an additive anisotropic kernel fitted with scikit-learn, evaluated in numpy.

The kernel mirrors the additive structure of :mod:`surrogate.features`,

    k(x, x') = c1·RBF_(Re, u)(x, x') + c2·RBF_(u, σ)(x, x') + noise·δ(x, x'),

each RBF anisotropic over its two standardised features, with a learned noise term (the CFD's mesh
error is about 1 %). Targets are standardised (``normalize_y``); optionally a linear mean in the
features (optionally a polynomial in the opening) is fitted first by least squares and the GP
models the residual (a physics trend that the GP reverts to far from the data, and between
distant openings). Inputs are standardised and everything is float64; the
condition number of the training covariance is recorded, because GPs on gridded data are prone
to ill-conditioning.

For export only arrays are kept (training inputs, dual coefficients, Cholesky factor, kernel
hyperparameters): :class:`surrogate.maps.gp.NumpyGP` predicts from them with no scikit-learn
object and no pickle. Besides RBF parts a part may *bridge* the opening linearly (a Brownian-motion
kernel, :class:`BridgeKernel`), as the grid maps do between sampled openings, or be a Matérn 3/2 in
the opening times an RBF of other columns (:class:`ProjectedMatern`).
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import (RBF, ConstantKernel, Hyperparameter, Kernel, Matern,
                                              WhiteKernel)

from ..maps.gp import (PART_KINDS, FeatureScaling, GPArrays, KernelParts, OutputScaling,
                       TrainingFit, bridge_coordinate)

LENGTH_SCALE_BOUNDS = (0.3, 100.0)  # standardised units: smooth on the scale of the data
NOISE_BOUNDS = (1e-8, 1e-2)


class _Projected(Kernel):
    """A stationary anisotropic kernel (:meth:`_kernel`) on a subset ``dims`` of the input
    columns."""

    def __init__(self, dims=(0, 1), length_scale=(1.0, 1.0),
                 length_scale_bounds=LENGTH_SCALE_BOUNDS):
        self.dims = dims
        self.length_scale = length_scale
        self.length_scale_bounds = length_scale_bounds

    @property
    def hyperparameter_length_scale(self):
        return Hyperparameter("length_scale", "numeric", self.length_scale_bounds, len(self.dims))

    def _kernel(self, length_scale: np.ndarray) -> Kernel:
        raise NotImplementedError

    def __call__(self, X, Y=None, eval_gradient=False):
        kernel = self._kernel(np.asarray(self.length_scale, float))
        X = np.asarray(X)[:, list(self.dims)]
        Y = None if Y is None else np.asarray(Y)[:, list(self.dims)]
        return kernel(X, Y, eval_gradient=eval_gradient)

    def diag(self, X):
        return np.ones(len(X))

    def is_stationary(self):
        return True


class ProjectedRBF(_Projected):
    """An anisotropic RBF kernel on a subset ``dims`` of the input columns."""

    def _kernel(self, length_scale):
        return RBF(length_scale)


class ProjectedMatern(_Projected):
    """A Matérn 3/2 kernel on a subset ``dims`` of the input columns (:data:`surrogate.maps.gp.
    MATERN` parts use it on the opening)."""

    def _kernel(self, length_scale):
        return Matern(length_scale, nu=1.5)


class BridgeKernel(Kernel):
    """min(b(x), b(x')) on one column, b clamped to ``span`` and shifted by ``origin``: Brownian
    motion, whose posterior mean interpolates linearly between the data (see
    :mod:`surrogate.maps.gp`). No hyperparameters: its amplitude is a ConstantKernel's."""

    def __init__(self, dim=1, span=(0.0, 1.0), origin=-1.0):
        self.dim = dim
        self.span = span
        self.origin = origin

    def _coordinate(self, X):
        return bridge_coordinate(np.asarray(X)[:, self.dim], np.asarray(self.span), self.origin)

    def __call__(self, X, Y=None, eval_gradient=False):
        a = self._coordinate(X)
        b = a if Y is None else self._coordinate(Y)
        K = np.minimum(a[:, None], b[None, :])
        return (K, np.empty((len(a), len(a), 0))) if eval_gradient else K

    def diag(self, X):
        return self._coordinate(X)

    def is_stationary(self):
        return False


def fit_gp(features: np.ndarray, target: np.ndarray, parts, *, linear_mean: bool,
           opening_degree: int = 1, opening_column: int = 1, restarts: int = 3, seed: int = 0,
           held: tuple[int, ...] = (), held_margin: float = 0.0) -> GPArrays:
    """Fit an additive GP to ``target`` and return its arrays.

    ``parts``: the kernel's additive parts, each ``("rbf", columns)`` or ``("bridge", columns)``
    (the first column the opening, linearly bridged; the others in an RBF factor); a bare tuple of
    columns is an RBF part. Each part has its own amplitude; a white-noise term is learned too.
    ``linear_mean``: fit a trend linear in the features first, by least squares, and the GP to
    what it leaves; with ``opening_degree`` above 1 the trend is a polynomial of that degree in
    column ``opening_column`` (the opening), carried on beyond the training range as its tangent
    (:func:`surrogate.maps.gp.opening_polynomial`).
    ``held``: feature columns clamped to their training range, widened by ``held_margin``
    standard deviations, when predicting (:mod:`surrogate.maps.gp`).
    """
    parts = [("rbf", tuple(p)) if not isinstance(p[0], str) else (p[0], tuple(p[1]))
             for p in parts]
    feature_mean = features.mean(axis=0)
    feature_std = np.where(features.std(axis=0) > 0, features.std(axis=0), 1.0)
    z = (features - feature_mean) / feature_std
    powers = np.arange(2, opening_degree + 1) if linear_mean else np.zeros(0, int)
    opening = z[:, opening_column] if len(powers) else np.zeros(len(z))
    design = np.column_stack([np.ones(len(z)), z, np.power.outer(opening, powers)])
    if linear_mean:
        coefficients = np.linalg.lstsq(design, target, rcond=None)[0]
    else:
        coefficients = np.zeros(design.shape[1])
    residual = target - design @ coefficients
    trend, higher = coefficients[: z.shape[1] + 1], coefficients[z.shape[1] + 1:]
    kernel, span, origin = additive_kernel(parts, z)
    regressor = GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=restarts,
                                         random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # a bound reached is reported below
        regressor.fit(z, residual)
    fitted = regressor.kernel_
    amplitudes, scales = _fitted_parts(fitted, len(parts))
    widest = max(len(dims) for _, dims in parts)
    length_scales = np.ones((len(parts), widest))
    part_dims = np.full((len(parts), widest), -1)
    for row, ((_, dims), ell) in enumerate(zip(parts, scales)):
        length_scales[row, : len(ell)] = ell
        part_dims[row, : len(dims)] = dims
    kernel_parts = KernelParts(np.array([PART_KINDS[kind] for kind, _ in parts]), part_dims,
                               np.asarray(amplitudes), length_scales,
                               float(fitted.k2.noise_level), span, origin)
    training = TrainingFit(z, np.asarray(regressor.alpha_, float).ravel(),
                           np.asarray(regressor.L_, float), float(np.linalg.cond(fitted(z))))
    held_range = np.array([[z[:, c].min() - held_margin, z[:, c].max() + held_margin]
                           for c in held], float).reshape(-1, 2)
    return GPArrays(FeatureScaling(feature_mean, feature_std, np.asarray(held, int), held_range),
                    kernel_parts, training,
                    OutputScaling(trend, float(regressor._y_train_mean),
                                  float(regressor._y_train_std), higher, opening_column,
                                  np.array([opening.min(), opening.max()])))


def additive_kernel(parts, z: np.ndarray) -> tuple[Kernel, np.ndarray, float]:
    """The unfitted kernel of ``parts`` (``(kind, columns)`` pairs, as :func:`fit_gp` takes
    them) over standardised inputs ``z``, each part with its own amplitude, plus white noise;
    with the bridge's span (the training range of its opening column) and origin."""
    bridge_column = next((dims[0] for kind, dims in parts if kind == "bridge"), None)
    span = (np.array([z[:, bridge_column].min(), z[:, bridge_column].max()])
            if bridge_column is not None else np.array([0.0, 0.0]))
    origin = float(span[0] - 1.0)
    kernel = None
    for kind, dims in parts:
        rbf = dims if kind == "rbf" else dims[1:]
        factor = ProjectedRBF(rbf, (1.0,) * len(rbf)) if rbf else None
        if kind != "rbf":  # the opening's own kernel, first in the product
            opening = (BridgeKernel(dims[0], tuple(span), origin) if kind == "bridge"
                       else ProjectedMatern((dims[0],), (1.0,)))
            factor = opening if factor is None else opening * factor
        part = ConstantKernel(1.0, (1e-4, 1e3)) * factor
        kernel = part if kernel is None else kernel + part
    return kernel + WhiteKernel(1e-4, NOISE_BOUNDS), span, origin


def _fitted_parts(kernel, count: int):
    """(amplitudes, RBF length scales) of the additive parts of a fitted kernel, in order."""
    sums = kernel.k1  # the kernel is ((part1 + part2) + ...) + white
    parts = []
    for _ in range(count - 1):
        parts.append(sums.k2)
        sums = sums.k1
    parts.append(sums)
    parts.reverse()
    amplitudes, scales = [], []
    for part in parts:
        amplitudes.append(float(part.k1.constant_value))
        # a part's factor: an RBF, the opening's kernel alone, or the opening's times an RBF
        factors = [part.k2] if isinstance(part.k2, (_Projected, BridgeKernel)) else [
            part.k2.k1, part.k2.k2]
        scales.append(np.concatenate(
            [np.atleast_1d(np.asarray(f.length_scale, float)) for f in factors
             if not isinstance(f, BridgeKernel)] or [np.zeros(0)]))
    return amplitudes, scales
