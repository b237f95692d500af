"""Learned flow and force maps: a physical baseline corrected by a predictor of a dimensionless target.

* :class:`LearnedFlowMap`: Δp(q, p_B, u, fluid) = ½ρ·(q/(C_d·w·u))², ln C_d predicted from the
  flow features of :mod:`surrogate.features`. The pressure drop is explicit, which is what the
  solver needs; the flow at a given p_L is found by the base class's monotone inversion.
* :class:`LearnedForceMap`: f_sim = p_L·A_L + p_B·(A_s3 − A_B) + α·A_L·Δp, α predicted from the
  force features.

The predictor is a neural network ensemble (:mod:`.nn`) or a Gaussian process (:mod:`.gp`); both
expose ``predict(features)`` and ``latent(features, return_std=True)``, the spread that, with the
distance to the data, makes the calibrated standard deviation (:mod:`.sigma`). A query is
*extrapolating* for the reasons of :mod:`.coverage`, or when its features lie in a hole of the
training data (:class:`~surrogate.maps.domain.FeatureDomain`).

Every learned map is saved as a folder holding ``surrogate.json`` (features, scalers,
constraints, coverage, calibration, the hash of the training data, cross-validated accuracy) next
to plain weight files (:mod:`.package`); :func:`load_learned_maps` reads it back without
executing any code (no pickle).

What the learned kinds share as map kinds (:mod:`.registry`) is here too: :func:`learned_kind`
makes the kind of a predictor (:mod:`.nn`, :mod:`.gp`), whose maps are loaded from the folder of
a trained surrogate (default: the committed one, :func:`trained_folder`) and record the SHA-256
of its manifest.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..features import FeatureSpec
from ..fluid import FluidState, broadcast_query
from ..core.paths import SHIPPED_SURROGATES
from . import package
from .base import FlowMap, ForceMap
from .sigma import SigmaCalibration
from .coverage import DP_OUTSIDE, FEATURES_SPARSE, Coverage
from .domain import FeatureDomain
from .registry import (SHIPPED, MapKind, Option, learned_kinds, map_kind, resolve_path,
                       sha256_hex)

MANIFEST = package.MANIFEST


#: the force features' column of ln(u/U) (:data:`surrogate.features.FORCE_FEATURE_NAMES`)
_OPENING_COLUMN = 1
#: the range of the power of u by which α goes on below the smallest opening, as the grid's
#: (:data:`.grid._POWER_BELOW`): between holding it and falling in proportion to the opening
_POWER_TOWARD_SEAT = (0.0, 1.0)


class LearnedFlowMap(FlowMap):
    """Flow map whose discharge coefficient comes from a learned predictor of ln C_d.

    ``calibration`` turns the predictor's own spread into a calibrated standard deviation of
    ln C_d (:mod:`.sigma`; none, i.e. the spread itself, before one is fitted);
    ``coverage`` says where the training samples are; ``cfd_error`` [1] is σ of ln C_d that the
    training samples' meshes put on them (:func:`.cfd_error.flow_cfd_error`; default the shipped
    samples', :data:`.cfd_error.FLOW_CFD_ERROR`).
    """

    # tanh networks and RBF kernels are C^∞ in the flow and Δp (but where a GP holds a feature at
    # its training range's edge: a kink there)
    smooth = True

    def __init__(self, spec: FeatureSpec, predictor, domain: FeatureDomain, kind: str,
                 calibration: SigmaCalibration | None = None, coverage: Coverage | None = None,
                 cfd_error: float | None = None):
        self.spec = spec
        self.predictor = predictor
        self.domain = domain
        self.kind = kind
        self.calibration = calibration or SigmaCalibration()
        self.coverage = coverage
        if cfd_error is not None:  # else the class's: the shipped samples'
            self.cfd_error = float(cfd_error)

    def __repr__(self) -> str:
        return f"LearnedFlowMap({self.kind})"

    def log_discharge(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """ln C_d at flow ``q`` [m^3/s]."""
        return self.predictor.predict(self.spec.flow_features(q, p_B, u, fluid))

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        shape = q.shape
        q, u, rho = q.ravel(), u.ravel(), fluid.rho.ravel()
        log_cd = self.log_discharge(q, p_B, u, fluid)
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = self.spec.orifice_pressure_drop(q, u, rho) * np.exp(-2.0 * log_cd)
        dp = np.where(q > 0, np.where(u > 0, dp, np.inf), 0.0)
        return dp.reshape(shape)

    def reasons_at_flow(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        flags = super().reasons_at_flow(q, p_B, u, fluid)
        inside = self.domain.contains(self.spec.flow_features(q, p_B, u, fluid))
        return flags | np.where(inside.reshape(q.shape), 0, FEATURES_SPARSE)

    def calibration_inputs(self, q, p_B, u, fluid: FluidState):
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        features = self.spec.flow_features(q, p_B, u, fluid)
        return _inputs(self, features, p_B, u)[1:]


class LearnedForceMap(ForceMap):
    """Force map whose flow-force fraction α comes from a learned predictor."""

    # tanh networks and RBF kernels are C^∞ in the flow and Δp (but where a GP holds a feature at
    # its training range's edge: a kink there)
    smooth = True

    def __init__(self, spec: FeatureSpec, predictor, domain: FeatureDomain, kind: str,
                 calibration: SigmaCalibration | None = None, coverage: Coverage | None = None):
        self.spec = spec
        self.predictor = predictor
        self.domain = domain
        self.kind = kind
        self.calibration = calibration or SigmaCalibration()
        self.coverage = coverage

    def __repr__(self) -> str:
        return f"LearnedForceMap({self.kind})"

    @property
    def feature_count(self) -> int:
        """How many of :data:`~surrogate.features.FORCE_FEATURE_NAMES` the predictor reads (3 or
        4, as its training data's domain records)."""
        return len(self.domain.lower)

    def features(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """The predictor's force features at flattened queries, shape (n, :attr:`feature_count`)."""
        return self.spec.force_features(p_L, p_B, u, fluid, count=self.feature_count)

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        features = self.features(p_L, p_B, u, fluid)
        fraction = self.toward_seat(self.predictor.predict(features), features, u)
        dp = np.maximum(p_L - p_B, 0.0).ravel()
        force = self.spec.uniform_force(p_L, p_B) + fraction * self.spec.A_L * dp
        return force.reshape(p_L.shape)

    def toward_seat(self, fraction: np.ndarray, features: np.ndarray, u) -> np.ndarray:
        """The flow-force fraction α of flattened queries (the predictor's ``fraction`` at their
        ``features``), below the smallest sampled opening u₀ continued as the power of u the
        two smallest openings give, α(u) = α(u₀)·(u/u₀)^k with 0 ≤ k ≤ 1 at the query's other
        features, as the grid continues it (:mod:`.grid`), for a predictor whose features hold
        their edge value there (networks: :attr:`~.nn.NetworkEnsemble.holds_the_smallest_opening`).
        Such a predictor keeps the smallest opening's flow force down to the seat, where the jet's
        momentum, and with it the flow force at a given Δp, vanishes as the valve closes; a GP's
        kernel follows the CFD's own fall there."""
        if (not getattr(self.predictor, "holds_the_smallest_opening", False)
                or self.coverage is None or len(self.coverage.openings) < 2):
            return fraction
        smallest, next_one = np.sort(self.coverage.openings)[:2]
        u = np.ravel(u)
        below = u < smallest
        if not below.any():
            return fraction
        at_smallest, at_next = features[below].copy(), features[below].copy()
        at_smallest[:, _OPENING_COLUMN] = np.log(smallest / self.spec.length)
        at_next[:, _OPENING_COLUMN] = np.log(next_one / self.spec.length)
        edge, beyond = self.predictor.predict(at_smallest), self.predictor.predict(at_next)
        with np.errstate(divide="ignore", invalid="ignore"):
            power = np.log(beyond / edge) / np.log(next_one / smallest)
        power = np.where((edge * beyond > 0.0) & np.isfinite(power),
                         np.clip(power, *_POWER_TOWARD_SEAT), 0.0)
        continued = np.array(fraction, float, copy=True)
        continued[below] = edge * np.exp(power * np.log(np.maximum(u[below], 1e-300) / smallest))
        return continued

    def extrapolation_reasons(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        flags = super().extrapolation_reasons(p_L, p_B, u, fluid)
        inside = self.domain.contains(self.features(p_L, p_B, u, fluid))
        flags = flags | np.where(inside.reshape(p_L.shape), 0, FEATURES_SPARSE)
        return flags | np.where(p_L <= p_B, DP_OUTSIDE, 0)

    def flow_force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return self.force(p_L, p_B, u, fluid) - self.spec.uniform_force(p_L, p_B)

    def calibration_inputs(self, p_L, p_B, u, fluid: FluidState):
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return _inputs(self, self.features(p_L, p_B, u, fluid), p_B, u)[1:]

    def force_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of f_sim [N] against the valve: as :meth:`ForceMap.force_std`, with
        the predictor asked once for its mean and spread (the kernel or the networks are the
        cost)."""
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        features = self.features(p_L, p_B, u, fluid)
        latent, spread, distances = _inputs(self, features, p_B, u)
        dp = np.maximum(p_L - p_B, 0.0).ravel()
        fraction = self.toward_seat(self.predictor.from_latent(latent), features, u)
        flow_force = fraction * self.spec.A_L * dp
        relative = self.against_valve(self.calibration.std(spread, distances), p_B, u)
        return np.reshape(np.abs(flow_force) * relative, p_L.shape)


def _inputs(learned_map, features: np.ndarray, p_B: np.ndarray, u: np.ndarray):
    """(latent mean, spread, distances) of a learned map at its features (:mod:`.sigma`)."""
    latent, spread = learned_map.predictor.latent(features, return_std=True)
    distances = {"features": learned_map.domain.distance(features)}
    if learned_map.coverage is not None:
        distances["back pressure"] = learned_map.coverage.back_pressure_distance(np.ravel(p_B))
        # a predictor that does not say is taken not to (a plug-in kind's, say)
        if not getattr(learned_map.predictor, "spread_knows_openings", False):
            distances["opening"] = learned_map.coverage.opening_distance(np.ravel(u))
    return latent, spread, distances


def load_learned_maps(folder: str | Path) -> tuple[LearnedFlowMap, LearnedForceMap]:
    """The flow and force map of a saved surrogate folder (NN or GP): its manifest checked, its
    weight files inside it and, when it records them, holding the bytes it records
    (:mod:`.package`); a folder without recorded hashes loads with a warning."""
    folder = Path(folder)
    manifest = package.read_manifest(folder, learned_kinds())
    where = str(folder / MANIFEST)
    load = map_kind(manifest["kind"]).load_predictor
    spec = FeatureSpec.from_dict(manifest["features"])
    coverage = Coverage.from_dict(manifest["coverage"]) if "coverage" in manifest else None
    unsealed = [name for name in ("flow", "force") if not package.verify(
        folder, manifest[name]["predictor"], f"{where}: {name}.predictor")]
    if unsealed:  # before the arrays load: a warning that explains a broken file too
        print(f"warning: {folder}: its weights are not sealed ({MANIFEST} records no SHA-256 of "
              f"the {' and '.join(unsealed)} weights: written by an older version), so a changed "
              "weight file would go unnoticed; retrain it with training/train.py to seal it",
              file=sys.stderr)
    maps = []
    for cls, name in ((LearnedFlowMap, "flow"), (LearnedForceMap, "force")):
        entry = manifest[name]
        count = len(package.feature_names(entry, name, f"{where}: {name}"))
        # the flow's σ_CFD as its training recorded it (a manifest written before it was
        # recorded: trained on the shipped samples, whose σ_CFD is the class's)
        own = {"cfd_error": entry["cfd_error"]} if "cfd_error" in entry else {}
        maps.append(cls(spec, load(folder, entry["predictor"], count),
                        FeatureDomain.from_dict(entry["domain"]), manifest["kind"],
                        SigmaCalibration.from_dict(entry.get("calibration")), coverage, **own))
    return tuple(maps)


# --- the learned kinds ---------------------------------------------------------------------------

def trained_folder(kind: str) -> Path:
    """Folder of the committed surrogate of a learned kind."""
    return SHIPPED_SURROGATES / map_kind(kind).name


def learned_kind(name: str, description: str, *, trainer: str, save_predictor: Callable,
                 load_predictor: Callable, constraints: Mapping[str, str],
                 calibration_powers: Mapping[str, float] | None = None) -> MapKind:
    """The map kind of a learned predictor (:class:`~.registry.MapKind`, to register): maps
    loaded from the folder of a trained surrogate (``folder``, default the committed one), built
    on the manifest whose SHA-256 a model records (``surrogate_sha256``); its calibration given
    ``calibration_powers`` (:attr:`~.registry.MapKind.calibration_powers`)."""
    return MapKind(name, description, _learned_builder(name),
                   (_folder_option(name), _SURROGATE_HASH), trainer=trainer,
                   calibration_powers=dict(calibration_powers or {}),
                   data=_learned_data(name), accuracy=_learned_accuracy(name),
                   save_predictor=save_predictor, load_predictor=load_predictor,
                   constraints=constraints)


def _folder_option(kind: str) -> Option:
    return Option("folder", "the trained surrogate's folder (default: the committed one)",
                  default=SHIPPED, path=True, shipped=SHIPPED_SURROGATES / kind)


_SURROGATE_HASH = Option("surrogate_sha256",
                         "SHA-256 of the surrogate's manifest the model was built on", sha256_hex)


def _learned_folder(kind: str, folder: str, base: Path) -> Path:
    return trained_folder(kind) if folder == SHIPPED else resolve_path(folder, base)


def _learned_builder(kind: str):
    def build(options, valve, base):
        path = _learned_folder(kind, options.get("folder", SHIPPED), base)
        expected = options.get("surrogate_sha256")
        if expected is not None and (path / MANIFEST).is_file() and \
                expected not in package.sealed_hashes(path / MANIFEST):
            raise InputError(f"{path}: this {kind} surrogate is not the one the model was built "
                             f"on (its {MANIFEST} has SHA-256 "
                             f"{package.file_hash(path / MANIFEST)[:12]}…, the model records "
                             f"{expected[:12]}…); refit the model on it, or point folder = ... at "
                             "the original surrogate")
        flow, force = load_learned_maps(path)
        if flow.kind != kind:
            raise InputError(f"{path}: holds a {flow.kind!r} surrogate, not {kind!r}")
        return flow, force
    return build


def _learned_accuracy(kind: str):
    def accuracy(options, valve, base):
        folder = _learned_folder(kind, options.get("folder", SHIPPED), base)
        manifest = package.read_manifest(folder, learned_kinds())
        return manifest.get("metrics", {}).get("cross_validation")
    return accuracy


def _learned_data(kind: str):
    def data(cfd, folder: str = SHIPPED, **options) -> dict:
        if cfd is not None:
            raise InputError(f"{kind} maps are trained from CFD samples beforehand "
                             "(training/train.py --cfd); give their folder with --maps FOLDER")
        path = _learned_folder(kind, folder, Path("."))
        return {"folder": folder if folder == SHIPPED else str(path.resolve()),
                "surrogate_sha256": package.file_hash(path / MANIFEST)}
    return data
