"""Evaluation: off-the-shelf surrogates ("peers") beside the project's map kinds, by the
project's own cross-validation.

    python eval/peers.py [--out results/peers] [--peers NAME ...] [--quick]

Each peer is a regressor of ln C_d (flow map) and of the flow-force fraction α (force map),
wrapped as maps by :mod:`surrogate.maps.peer` and trained on the training samples of every fold
of the four schemes of :mod:`surrogate.maps.crossval` (k-fold by sweep, leave one opening out,
leave one temperature out, back-pressure set out), then asked about the fold's left-out samples
exactly as the project's kinds are (:func:`~surrogate.maps.crossval.errors_on`).

Each peer has a short list of candidate settings (kernel family, smoothing, network size,
regularisation), each cross-validated whole; a peer on the project's features tries each with
the project's three force features and with the four the project's GP reads (the pressure level
ln(Δp/p_atm) added). The peer's force map takes the candidate with the lowest mean flow-force
error over the schemes (:func:`~surrogate.maps.crossval.flow_force_score`, by which the project
ranks its kinds); its flow map, whose settings do not enter the flow-force error at all, the
candidate with the lowest mean q error. The settings are chosen on the same folds that score
them, so a peer's row is slightly optimistic (the best of three to ten candidates). ``--quick``
runs the first candidate of each peer only (a smoke test, nothing chosen).

The project's kinds are read as ``eval/surrogates.py`` reads them, nothing retrained: the grid's
cross-validation computed now (a second), the learned kinds' from the committed
``surrogate/trained/<kind>/surrogate.json``. Peers have no calibrated uncertainty, so the ±2σ
coverage is the project's kinds' only.

Writes ``peers.md`` (the tables) and ``peers.json`` into ``--out``. GPyTorch and SMT are the
optional extra ``peers`` (``pip install -e ".[peers]" -c constraints.txt``); without them those
two peers are skipped with a note.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.maps.sigma import SigmaCalibration
from surrogate.maps.crossval import SCHEMES, cross_validate, flow_force_score, summary
from surrogate.maps.learned import trained_folder
from surrogate.maps.peer import fit_peer_maps
from surrogate.maps.registry import build_maps, cross_validation_summary, map_kind
from surrogate.core.errors import InputError
from surrogate.core.outputs import Output, atomic_directory, check_outputs
from surrogate.core.paths import SHIPPED_CFD_SAMPLES

KINDS = ("grid", "nn", "gp")
LABELS = {"grid": "grid", "nn": "NN", "gp": "GP"}
#: input columns of the (flow, force) regressors (surrogate.maps.peer): the project's three
#: features, the force's with the pressure level the project's GP reads, or raw ones
INPUT_COUNT = {"dimensionless": (3, 3), "dimensionless+level": (3, 4), "raw": (4, 4)}
#: the force features a peer on the project's features may read, a setting chosen by the folds
#: like the others: the three, or the four the project's GP reads
FORCE_FEATURES = (3, 4)
SEED = 0  # every random start of every peer: the run is repeatable


# --- building blocks the peers share ----------------------------------------------------------


class StandardisedInputs:
    """A regressor fitted on inputs shifted and scaled to zero mean and unit variance (per
    column, from the training inputs), so that length scales, smoothing and weight decay mean the
    same for every input whatever its units."""

    def __init__(self, regressor):
        self.regressor = regressor

    def fit(self, X, y):
        self.centre, spread = X.mean(axis=0), X.std(axis=0)
        # an input constant in training (p_B when trained on the reference back pressure alone)
        # says nothing about how the target varies with it: it is standardised to zero at every
        # query, so the regressor ignores it instead of reading its units as a distance
        self.scale = np.where(spread > 0, spread, np.inf)
        self.regressor.fit((X - self.centre) / self.scale, np.asarray(y, float))
        return self

    def predict(self, X):
        return np.asarray(self.regressor.predict((X - self.centre) / self.scale), float).ravel()


class LinearTrendPlusResidual:
    """A least-squares linear trend in the inputs, and ``residual`` fitted to what it leaves: a
    stationary kernel then reverts to the trend, not to a constant, away from the data."""

    def __init__(self, residual):
        self.residual = residual

    def fit(self, X, y):
        from sklearn.linear_model import LinearRegression

        self.trend = LinearRegression().fit(X, y)
        self.residual.fit(X, y - self.trend.predict(X))
        return self

    def predict(self, X):
        return self.trend.predict(X) + np.asarray(self.residual.predict(X), float).ravel()


def stationary_kernel(family: str, input_count: int):
    """An amplitude times an anisotropic RBF or Matérn kernel (one length scale per standardised
    input), ``family`` one of "RBF", "Matern 3/2", "Matern 5/2"."""
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern

    length_scales = np.ones(input_count)
    bounds = (1e-2, 1e3)  # standardised inputs: from a hundredth of their spread to flat
    if family == "RBF":
        shape = RBF(length_scales, bounds)
    else:
        shape = Matern(length_scales, bounds, nu={"Matern 3/2": 1.5, "Matern 5/2": 2.5}[family])
    return ConstantKernel(1.0, (1e-3, 1e3)) * shape


def white_noise():
    """The nugget: CFD samples carry a per-mesh scatter of about ±3 % in the flow force (GUIDE
    section 8), which an interpolating GP would chase."""
    from sklearn.gaussian_process.kernels import WhiteKernel

    return WhiteKernel(1e-4, (1e-9, 1e-1))


def sklearn_gp(kernel):
    from sklearn.gaussian_process import GaussianProcessRegressor

    return GaussianProcessRegressor(kernel, normalize_y=True, n_restarts_optimizer=2,
                                    random_state=SEED)


# --- the peers ---------------------------------------------------------------------------------


def build_sklearn_gp(settings: dict, input_count: int):
    """scikit-learn GP, constant mean (normalize_y), stationary kernel plus white noise."""
    return StandardisedInputs(sklearn_gp(stationary_kernel(settings["kernel"], input_count)
                                         + white_noise()))


def build_sklearn_gp_with_trend(settings: dict, input_count: int):
    """scikit-learn GP with a linear trend: either a DotProduct kernel beside the stationary one,
    or a least-squares linear fit first and the GP on its residual."""
    from sklearn.gaussian_process.kernels import ConstantKernel, DotProduct

    stationary = stationary_kernel(settings["kernel"], input_count)
    if settings["trend"] == "DotProduct kernel":
        linear = ConstantKernel(1.0, (1e-3, 1e3)) * DotProduct(1.0, (1e-3, 1e3))
        return StandardisedInputs(sklearn_gp(linear + stationary + white_noise()))
    return StandardisedInputs(LinearTrendPlusResidual(sklearn_gp(stationary + white_noise())))


class GPyTorchExactGP:
    """A GPyTorch exact GP: constant or linear mean, a scaled anisotropic Matérn or RBF kernel,
    Gaussian likelihood; hyperparameters by Adam on the exact marginal likelihood, targets
    standardised, float64."""

    def __init__(self, kernel: str = "Matern 5/2", mean: str = "constant",
                 iterations: int = 200, learning_rate: float = 0.1):
        self.kernel, self.mean = kernel, mean
        self.iterations, self.learning_rate = iterations, learning_rate

    def fit(self, X, y):
        import gpytorch
        import torch

        torch.manual_seed(SEED)
        self.y_centre, self.y_scale = float(np.mean(y)), float(np.std(y)) or 1.0
        inputs = torch.as_tensor(X, dtype=torch.float64)
        targets = torch.as_tensor((np.asarray(y) - self.y_centre) / self.y_scale,
                                  dtype=torch.float64)
        likelihood = gpytorch.likelihoods.GaussianLikelihood(
            noise_constraint=gpytorch.constraints.GreaterThan(1e-6)).double()
        model = _exact_gp_class()(inputs, targets, likelihood, self.kernel, self.mean).double()
        model.train()
        likelihood.train()
        optimizer = torch.optim.Adam(model.parameters(), lr=self.learning_rate)
        likelihood_of = gpytorch.mlls.ExactMarginalLogLikelihood(likelihood, model)
        for _ in range(self.iterations):
            optimizer.zero_grad()
            loss = -likelihood_of(model(inputs), targets)
            loss.backward()
            optimizer.step()
        model.eval()
        likelihood.eval()
        self.model = model
        return self

    def predict(self, X):
        import gpytorch
        import torch

        with torch.no_grad(), gpytorch.settings.fast_pred_var():
            mean = self.model(torch.as_tensor(X, dtype=torch.float64)).mean.numpy()
        return mean * self.y_scale + self.y_centre


_EXACT_GP = None


def _exact_gp_class():
    """The ExactGP subclass, defined on first use so that the script runs without GPyTorch."""
    global _EXACT_GP
    if _EXACT_GP is None:
        import gpytorch

        class ExactGP(gpytorch.models.ExactGP):
            def __init__(self, inputs, targets, likelihood, kernel, mean):
                super().__init__(inputs, targets, likelihood)
                count = inputs.shape[1]
                self.mean_module = (gpytorch.means.LinearMean(count) if mean == "linear"
                                    else gpytorch.means.ConstantMean())
                shape = (gpytorch.kernels.RBFKernel(ard_num_dims=count) if kernel == "RBF"
                         else gpytorch.kernels.MaternKernel(
                             nu={"Matern 3/2": 1.5, "Matern 5/2": 2.5}[kernel],
                             ard_num_dims=count))
                self.covar_module = gpytorch.kernels.ScaleKernel(shape)

            def forward(self, x):
                return gpytorch.distributions.MultivariateNormal(self.mean_module(x),
                                                                 self.covar_module(x))

        _EXACT_GP = ExactGP
    return _EXACT_GP


def build_gpytorch(settings: dict, input_count: int):
    return StandardisedInputs(GPyTorchExactGP(settings["kernel"], settings["mean"]))


class SmtKriging:
    """SMT's KRG: universal kriging with a polynomial trend, its noise estimated."""

    def __init__(self, corr: str = "squar_exp", poly: str = "linear"):
        self.corr, self.poly = corr, poly

    def fit(self, X, y):
        from smt.surrogate_models import KRG

        # COBYLA: what KRG switches to anyway when it estimates the noise (with a warning)
        self.model = KRG(poly=self.poly, corr=self.corr, eval_noise=True, hyper_opt="Cobyla",
                         print_global=False, seed=SEED)
        self.model.set_training_values(np.asarray(X, float), np.asarray(y, float))
        self.model.train()
        return self

    def predict(self, X):
        return self.model.predict_values(np.asarray(X, float)).ravel()


def build_smt(settings: dict, input_count: int):
    return StandardisedInputs(SmtKriging(settings["corr"], settings["poly"]))


class ThinPlateSpline:
    """scipy's RBFInterpolator with a thin-plate-spline kernel and a linear polynomial tail;
    ``smoothing`` 0 interpolates."""

    def __init__(self, smoothing: float):
        self.smoothing = smoothing

    def fit(self, X, y):
        from scipy.interpolate import RBFInterpolator

        self.interpolant = RBFInterpolator(X, y, kernel="thin_plate_spline",
                                           smoothing=self.smoothing, degree=1)
        return self

    def predict(self, X):
        return self.interpolant(X)


def build_thin_plate_spline(settings: dict, input_count: int):
    return StandardisedInputs(ThinPlateSpline(settings["smoothing"]))


def build_mlp(settings: dict, input_count: int):
    """scikit-learn MLPRegressor, tanh, L-BFGS (a few hundred samples: full-batch second-order
    steps converge where Adam wanders), targets standardised."""
    from sklearn.compose import TransformedTargetRegressor
    from sklearn.neural_network import MLPRegressor
    from sklearn.preprocessing import StandardScaler

    network = MLPRegressor(hidden_layer_sizes=settings["hidden"], alpha=settings["alpha"],
                           activation="tanh", solver="lbfgs", max_iter=5000, random_state=SEED)
    return StandardisedInputs(TransformedTargetRegressor(network, transformer=StandardScaler()))


@dataclass(frozen=True)
class Peer:
    """An off-the-shelf surrogate: its inputs (``"raw"`` or ``"dimensionless"``, see
    :mod:`surrogate.maps.peer`), candidate settings (the first is ``--quick``'s), and
    ``build(settings, input_count)`` returning one fresh unfitted regressor (called once per map
    and fold)."""

    name: str
    description: str
    inputs: str
    build: Callable
    candidates: tuple[dict, ...]
    requires: tuple[str, ...] = field(default=())

    @property
    def key(self) -> str:
        """The name on the command line: lower case, words joined by hyphens."""
        return "-".join("".join(c if c.isalnum() else " " for c in self.name).lower().split())

    def missing(self) -> list[str]:
        """The modules it needs that are not installed."""
        return [module for module in self.requires if importlib.util.find_spec(module) is None]


GP_KERNELS = ({"kernel": "Matern 5/2"}, {"kernel": "Matern 3/2"}, {"kernel": "RBF"})
PEERS = {peer.key: peer for peer in (
    Peer("sklearn GP, raw", "scikit-learn GP on (ln u, ln q or ln Δp, ln ν, p_B)", "raw",
         build_sklearn_gp, GP_KERNELS),
    Peer("sklearn GP", "scikit-learn GP on the project's features", "dimensionless",
         build_sklearn_gp, GP_KERNELS),
    Peer("sklearn GP + trend", "scikit-learn GP with a linear trend, project's features",
         "dimensionless", build_sklearn_gp_with_trend,
         ({"trend": "linear fit", "kernel": "Matern 5/2"},
          {"trend": "linear fit", "kernel": "RBF"},
          {"trend": "DotProduct kernel", "kernel": "Matern 5/2"})),
    Peer("GPyTorch GP", "GPyTorch exact GP, project's features", "dimensionless",
         build_gpytorch,
         ({"mean": "linear", "kernel": "Matern 5/2"}, {"mean": "constant", "kernel": "Matern 5/2"},
          {"mean": "linear", "kernel": "RBF"}), requires=("gpytorch",)),
    Peer("SMT kriging", "SMT KRG, linear trend, project's features", "dimensionless", build_smt,
         ({"poly": "linear", "corr": "squar_exp"}, {"poly": "linear", "corr": "matern52"},
          {"poly": "linear", "corr": "matern32"}), requires=("smt",)),
    Peer("thin-plate RBF", "scipy RBFInterpolator, thin-plate spline, project's features",
         "dimensionless", build_thin_plate_spline,
         tuple({"smoothing": value} for value in (1e-1, 0.0, 1e-2, 1.0, 10.0))),
    Peer("MLP", "scikit-learn MLPRegressor, project's features", "dimensionless", build_mlp,
         ({"hidden": (32, 32), "alpha": 1e-1}, {"hidden": (32, 32), "alpha": 1e-2},
          {"hidden": (32, 32), "alpha": 1.0}, {"hidden": (16, 16), "alpha": 1e-1},
          {"hidden": (64, 64), "alpha": 1e-1})),
)}


# --- cross-validating them ---------------------------------------------------------------------


def settings_label(settings: dict) -> str:
    return ", ".join(f"{key} {value}" for key, value in settings.items())


def error_summary(errors) -> dict:
    """Per scheme: relative RMS error of q and of the flow force (``summary`` without the
    coverage, which needs a calibrated σ a peer does not have)."""
    result = summary(errors, SigmaCalibration(), SigmaCalibration())
    for row in result.values():
        for key in ("q_coverage_2sigma", "flow_force_coverage_2sigma"):
            row.pop(key)
    return result


def per_fold(errors) -> dict:
    """Per scheme and fold: the left-out samples and the relative RMS errors of q and of the
    flow force."""
    result = {}
    for (scheme, fold), part in errors.groupby(["scheme", "fold"], sort=False):
        result.setdefault(scheme, {})[fold] = {
            "samples": len(part),
            "q_rel_rmse": float(np.sqrt(np.mean(part["q_error"] ** 2))),
            "flow_force_rel_rmse": float(np.sqrt(np.mean(part["force_error"] ** 2)))}
    return result


def q_score(summary_of_kind: dict | None) -> float:
    """The q relative RMS error averaged over the schemes (nan without a summary)."""
    if not summary_of_kind:
        return float("nan")
    return float(np.mean([row["q_rel_rmse"] for row in summary_of_kind.values()]))


def cross_validate_candidate(peer: Peer, settings: dict, samples, valve) -> dict:
    """One candidate's cross-validated errors per scheme and per fold, with its seconds and the
    warnings its fits raised, counted per distinct message (a GP at a bound of its
    hyperparameters, an MLP stopped at its iteration limit)."""
    inputs = ("dimensionless+level" if settings.get("force features") == 4 else peer.inputs)
    flow_count, force_count = INPUT_COUNT[inputs]

    def fit_maps(train):
        return fit_peer_maps(samples.frame[train], valve, peer.build(settings, flow_count),
                             peer.build(settings, force_count), inputs, peer.name)

    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            errors = cross_validate(samples, valve, fit_maps)
            result = {"summary": error_summary(errors), "per_fold": per_fold(errors)}
        # a peer whose fit breaks (a singular matrix, a kernel that is not positive definite,
        # NaN from a diverged optimiser) is reported and the others still run; SMT raises a
        # bare Exception for a trend it cannot fit (ln σ and ln Δp are one column at a fixed
        # back pressure)
        except Exception as error:  # noqa: BLE001
            result = {"summary": None, "per_fold": None,
                      "failed": f"{type(error).__name__}: {error}"}
    kinds = {}
    for warning in caught:
        # the first line of each distinct message is enough to tell a bound from a non-start
        text = f"{warning.category.__name__}: {str(warning.message).splitlines()[0][:160]}"
        kinds[text] = kinds.get(text, 0) + 1
    return {"settings": settings, "label": settings_label(settings), **result,
            "flow_force_score": flow_force_score(result["summary"]),
            "q_score": q_score(result["summary"]),
            "seconds": time.perf_counter() - started, "warnings": kinds}


def _best(results: list[dict], score: str) -> dict | None:
    scored = [result for result in results if np.isfinite(result[score])]
    return min(scored, key=lambda result: result[score]) if scored else None


def _combined(flow: dict, force: dict, table: str) -> dict:
    """Per scheme (and fold), the q columns of ``flow``'s candidate and the flow-force columns
    of ``force``'s (same folds, same left-out samples)."""
    if table == "summary":
        return {scheme: {"samples": row["samples"], "q_rel_rmse": row["q_rel_rmse"],
                         "flow_force_rel_rmse": force["summary"][scheme]["flow_force_rel_rmse"]}
                for scheme, row in flow["summary"].items()}
    return {scheme: {fold: {**row, "flow_force_rel_rmse":
                            force["per_fold"][scheme][fold]["flow_force_rel_rmse"]}
                     for fold, row in rows.items()}
            for scheme, rows in flow["per_fold"].items()}


def evaluate_peer(peer: Peer, samples, valve, quick: bool, log: Callable[[str], None]) -> dict:
    """Every candidate of a peer (the first only with ``quick``) and the chosen settings: for
    the force map the candidate with the lowest mean flow-force error over the schemes
    (:func:`~surrogate.maps.crossval.flow_force_score`, as the project's kinds are ranked); for
    the flow map, whose settings do not enter the flow-force error at all (each fold fits the
    two maps apart, and ``errors_on`` takes the force at the sample's p_L), the candidate with
    the lowest mean q error."""
    candidates = peer.candidates[:1] if quick else peer.candidates
    if peer.inputs == "dimensionless" and not quick:  # each with three and four force features
        candidates = tuple({**settings, "force features": count}
                           for count in FORCE_FEATURES for settings in candidates)
    results = []
    for index, settings in enumerate(candidates, start=1):
        result = cross_validate_candidate(peer, settings, samples, valve)
        results.append(result)
        log(f"{peer.name} [{index}/{len(candidates)}] {result['label']}: "
            + (f"q {100 * result['q_score']:.2f} %, flow force "
               f"{100 * result['flow_force_score']:.2f} %" if result["summary"]
               else result["failed"]) + f" ({result['seconds']:.0f} s)")
    flow, force = _best(results, "q_score"), _best(results, "flow_force_score")
    chosen = flow is not None and force is not None
    return {"description": peer.description, "inputs": peer.inputs,
            "flow_map_settings": flow["label"] if flow else None,
            "force_map_settings": force["label"] if force else None,
            "summary": _combined(flow, force, "summary") if chosen else None,
            "per_fold": _combined(flow, force, "per_fold") if chosen else None,
            "candidates": results, "seconds": sum(r["seconds"] for r in results)}


# --- the tables ---------------------------------------------------------------------------------


def _percent(value, digits: int) -> str:
    return "–" if value is None or not np.isfinite(value) else f"{100 * value:.{digits}f}"


def comparison_table(project: dict, peers: dict) -> str:
    """One row per map (the project's kinds, then the peers), per scheme the q and flow-force
    relative RMS errors [%]; in brackets, for the project's kinds, the share of left-out samples
    inside the calibrated ±2σ band [%]; in bold the best peer per scheme and column."""
    schemes = [s for s in SCHEMES if any(s in (summary_ or {}) for summary_ in project.values())]
    columns = [(scheme, key) for scheme in schemes
               for key in ("q_rel_rmse", "flow_force_rel_rmse")]
    best = {}
    for column in columns:
        values = {name: result["summary"][column[0]][column[1]] for name, result in peers.items()
                  if result["summary"] and column[0] in result["summary"]}
        if values:
            best[column] = min(values, key=values.get)
    samples = {scheme: next(s[scheme]["samples"] for s in project.values() if s and scheme in s)
               for scheme in schemes}
    header = ["map"] + [f"{scheme} ({samples[scheme]}): {'q' if key == 'q_rel_rmse' else 'flow force'}"
                        for scheme, key in columns] + ["mean flow force"]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    coverage_key = {"q_rel_rmse": "q_coverage_2sigma",
                    "flow_force_rel_rmse": "flow_force_coverage_2sigma"}
    for kind, summary_of_kind in project.items():
        cells = [LABELS[kind]]
        for scheme, key in columns:
            row = summary_of_kind[scheme]
            cells.append(f"{_percent(row[key], 2 if key == 'q_rel_rmse' else 1)} "
                         f"[{_percent(row[coverage_key[key]], 0)}]")
        cells.append(_percent(flow_force_score(summary_of_kind), 2))
        lines.append("| " + " | ".join(cells) + " |")
    for name, result in peers.items():
        cells = [name]
        for scheme, key in columns:
            value = (result["summary"] or {}).get(scheme, {}).get(key)
            text = _percent(value, 2 if key == "q_rel_rmse" else 1)
            cells.append(f"**{text}**" if best.get((scheme, key)) == name else text)
        cells.append(_percent(flow_force_score(result["summary"]), 2))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def candidates_table(peers: dict) -> str:
    """Every candidate of every peer: mean q and flow-force errors over the schemes [%], seconds
    for all its folds, and for which map it was chosen."""
    lines = ["| peer | inputs | settings | mean q error | mean flow-force error | seconds | chosen |",
             "|---|---|---|---|---|---|---|"]
    for name, result in peers.items():
        for candidate in result["candidates"]:
            note = " and ".join(name for name, key in (("flow map", "flow_map_settings"),
                                                        ("force map", "force_map_settings"))
                                if candidate["label"] == result[key]) or candidate.get("failed", "")
            lines.append(f"| {name} | {result['inputs']} | {candidate['label']} | "
                         f"{_percent(candidate['q_score'], 2)} | "
                         f"{_percent(candidate['flow_force_score'], 2)} | "
                         f"{candidate['seconds']:.0f} | {note} |")
    return "\n".join(lines)


def fold_table(project_folds: dict, peers: dict, scheme: str, key: str, digits: int) -> str:
    """One row per map, one column per fold of ``scheme``: relative RMS error ``key`` [%], in bold
    the best peer per fold."""
    folds = list(next(iter(project_folds.values()))[scheme])
    rows = {LABELS[kind]: per_fold_of_kind[scheme] for kind, per_fold_of_kind in
            project_folds.items()}
    peer_rows = {name: result["per_fold"][scheme] for name, result in peers.items()
                 if result["per_fold"] and scheme in result["per_fold"]}
    best = {fold: min(peer_rows, key=lambda name: peer_rows[name][fold][key])
            for fold in folds if peer_rows}
    lines = ["| map | " + " | ".join(f"{fold} ({rows[LABELS[KINDS[0]]][fold]['samples']})"
                                     for fold in folds) + " |", "|---" * (len(folds) + 1) + "|"]
    for name, row in {**rows, **peer_rows}.items():
        cells = []
        for fold in folds:
            text = _percent(row[fold][key], digits)
            cells.append(f"**{text}**" if name in peer_rows and best.get(fold) == name else text)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def project_errors(kind: str, valve):
    """The cross-validated errors of one of the project's kinds, one row per (fold, sample), as
    ``eval/surrogates.py`` reads them: the grid's computed now, the learned kinds' from their
    committed ``cross_validation.csv``."""
    if kind == "grid":
        return build_maps("grid", valve)[0].uncertainty.errors
    # imports PyTorch: only here
    from surrogate.learn.training import CROSS_VALIDATION_FILE

    return pd.read_csv(trained_folder(kind) / CROSS_VALIDATION_FILE)


def reused_peers(path: Path) -> dict:
    """An earlier run's peers.json, checked to hold this script's schemes (exit 2 if not)."""
    try:
        document = json.loads(path.read_text())
        if document["schemes"] != list(SCHEMES):
            raise ValueError(f"its schemes {document['schemes']} are not {list(SCHEMES)}")
        if not document["peers"]:
            raise ValueError("it holds no peer")
        return document
    except (OSError, ValueError, KeyError, TypeError) as error:
        detail = f"key {error} missing" if isinstance(error, KeyError) else str(error)
        print(f"error: --reuse-peers {path}: not a peers.json of this script ({detail})",
              file=sys.stderr)
        raise SystemExit(2) from None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("results/peers"))
    parser.add_argument("--peers", nargs="+", metavar="NAME", choices=list(PEERS),
                        help="peers to run (default: all); names: " + "; ".join(PEERS))
    parser.add_argument("--quick", action="store_true",
                        help="the first candidate setting of each peer only (a smoke test)")
    parser.add_argument("--reuse-peers", type=Path, metavar="PEERS_JSON",
                        help="the peers' results of an earlier run (its peers.json), for when "
                             "only the project's maps changed: the peers are fitted to the same "
                             "samples and folds whatever the project trains, so only the "
                             "project's rows are read again")
    args = parser.parse_args()
    if args.reuse_peers is not None and (args.peers or args.quick):
        parser.error("--reuse-peers takes the earlier run's peers as they are: not with "
                     "--peers or --quick")
    try:  # the output folder replaces what it holds: never an input
        check_outputs([Output("--out", args.out, "folder")],
                      [(args.reuse_peers, "the reused peers"),
                       (SHIPPED_CFD_SAMPLES, "the CFD samples"),
                       *((trained_folder(kind), f"the {kind} maps")
                         for kind in KINDS if map_kind(kind).learned)])
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    started = time.perf_counter()

    def log(message: str) -> None:
        print(f"[{time.perf_counter() - started:6.0f} s] {message}", file=sys.stderr, flush=True)

    valve = load_valve()
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    project = {kind: cross_validation_summary(map_kind(kind).source(), valve) for kind in KINDS}
    project_folds = {kind: per_fold(project_errors(kind, valve)) for kind in KINDS}
    peers, skipped = {}, {}
    if args.reuse_peers is not None:
        earlier = reused_peers(args.reuse_peers)
        peers, skipped, args.quick = earlier["peers"], earlier["skipped"], earlier["quick"]
        log(f"peers reused from {args.reuse_peers}: {', '.join(peers)}")
    for key in [] if args.reuse_peers is not None else args.peers or list(PEERS):
        peer, name = PEERS[key], PEERS[key].name
        if missing := peer.missing():
            skipped[name] = (f"not installed: {', '.join(missing)} (the optional extra `peers`: "
                             "pip install -e \".[peers]\" -c constraints.txt)")
            log(f"{name}: skipped, {skipped[name]}")
            continue
        peers[name] = evaluate_peer(peer, samples, valve, args.quick, log)
    seconds = time.perf_counter() - started

    lines = ["Cross-validated relative RMS error [%] of q (from p_L) and of the flow force, per "
             "scheme (left-out samples in brackets in the header); for the project's kinds, in "
             "square brackets, the share of left-out samples inside the calibrated ±2σ band "
             "[%]; in bold the best peer per scheme and column. Peers: "
             + ("the first candidate (--quick, nothing chosen)" if args.quick else
                "the flow map with the settings of lowest mean q error, the force map with "
                "those of lowest mean flow-force error") + ".", "",
             comparison_table(project, peers), "",
             ("Leave one opening out, per left-out opening: flow-force relative RMS error [%] "
              "(0.20 mm is the opening below the 0.20–0.63 mm gap; bold: best peer):"), "",
             fold_table(project_folds, peers, SCHEMES[1], "flow_force_rel_rmse", 1), "",
             ("Candidates (mean over the schemes [%]); the flow map's settings are chosen by "
              "the mean q error, the force map's by the mean flow-force error:"), "",
             candidates_table(peers)]
    if skipped:
        lines += [""] + [f"Skipped {name}: {reason}" for name, reason in skipped.items()]
    reused = "" if args.reuse_peers is None else f"; peers reused from {args.reuse_peers}"
    lines += ["", f"Runtime: {seconds:.0f} s{reused} (" + ", ".join(
        f"{name} {result['seconds']:.0f} s" for name, result in peers.items()) + ")."]
    table = "\n".join(lines)
    print(table)
    document = {"schemes": list(SCHEMES), "quick": args.quick, "seconds": seconds,
                "project": project, "project_per_fold": project_folds, "peers": peers,
                "skipped": skipped}
    with atomic_directory(args.out) as staging:
        (staging / "peers.md").write_text(table + "\n")
        (staging / "peers.json").write_text(json.dumps(document, indent=2, default=list) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
