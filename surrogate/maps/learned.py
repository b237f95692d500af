"""Learned flow and force maps: a physical baseline corrected by a predictor of a dimensionless target.

* :class:`LearnedFlowMap`: Δp(q, p_B, u, fluid) = ½ρ·(q/(C_d·w·u))², ln C_d predicted from the
  flow features of :mod:`surrogate.features`. The pressure drop is explicit, which is what the
  solver needs; the flow at a given p_L is found by the base class's monotone inversion.
* :class:`LearnedForceMap`: f_sim = p_L·A_L + p_B·(A_s3 − A_B) + α·A_L·Δp, α predicted from the
  force features.

The predictor is a neural network (:mod:`.nn`) or a Gaussian process (:mod:`.gp`); both expose
``predict(features, return_std)``. A query is *extrapolating* when its features lie outside the
training data (:class:`~surrogate.learn.domain.FeatureDomain`).

Every learned map is saved as a folder holding ``surrogate.json`` (features, scalers,
constraints, the hash of the training data, held-out metrics) next to plain weight files;
:func:`load_learned_maps` reads it back without executing any code (no pickle).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..features import FeatureSpec
from ..fluid import FluidState
from ..learn.domain import FeatureDomain
from .base import FlowMap, ForceMap, broadcast_query

MANIFEST = "surrogate.json"
FORMAT_VERSION = 2  # 2: network weights as .npz (1: PyTorch state_dicts, still read)
_READABLE = (1, 2)


class LearnedFlowMap(FlowMap):
    """Flow map whose discharge coefficient comes from a learned predictor of ln C_d."""

    def __init__(self, spec: FeatureSpec, predictor, domain: FeatureDomain, kind: str):
        self.spec = spec
        self.predictor = predictor
        self.domain = domain
        self.kind = kind

    def __repr__(self) -> str:
        return f"LearnedFlowMap({self.kind})"

    def log_discharge(self, q, p_B, u, fluid: FluidState, return_std: bool = False):
        """ln C_d at flow ``q`` [m^3/s] (and its standard deviation, if the predictor has one)."""
        return self.predictor.predict(self.spec.flow_features(q, p_B, u, fluid), return_std)

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        shape = q.shape
        q, u, rho = q.ravel(), u.ravel(), fluid.rho.ravel()
        log_cd = self.log_discharge(q, p_B, u, fluid)
        with np.errstate(divide="ignore", invalid="ignore"):
            dp = self.spec.orifice_pressure_drop(q, u, rho) * np.exp(-2.0 * log_cd)
        dp = np.where(q > 0, np.where(u > 0, dp, np.inf), 0.0)
        return dp.reshape(shape)

    def extrapolating_at_flow(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        inside = self.domain.contains(self.spec.flow_features(q, p_B, u, fluid))
        return (~inside | (q.ravel() <= 0)).reshape(q.shape)

    def extrapolating(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        return self.extrapolating_at_flow(self.flow(p_L, p_B, u, fluid), p_B, u, fluid)

    def flow_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of q [m^3/s] at a given p_L, from that of ln C_d.

        At fixed Δp, ln q = ln C_d(q) + const, so δln q = δln C_d / (1 − ∂ln C_d/∂ln q); the slope
        is taken from the predictor's mean by a central difference.
        """
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        q = self.flow(p_L, p_B, u, fluid)
        _, std = self.log_discharge(q, p_B, u, fluid, return_std=True)
        if std is None:
            return None
        step = 1e-4
        up = self.log_discharge(q * np.exp(step), p_B, u, fluid)
        down = self.log_discharge(q * np.exp(-step), p_B, u, fluid)
        feedback = 1.0 - (up - down) / (2 * step)
        return (q.ravel() * std / np.maximum(feedback, 0.05)).reshape(q.shape)


class LearnedForceMap(ForceMap):
    """Force map whose flow-force fraction α comes from a learned predictor."""

    def __init__(self, spec: FeatureSpec, predictor, domain: FeatureDomain, kind: str):
        self.spec = spec
        self.predictor = predictor
        self.domain = domain
        self.kind = kind

    def __repr__(self) -> str:
        return f"LearnedForceMap({self.kind})"

    def _fraction(self, p_L, p_B, u, fluid, return_std):
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        features = self.spec.force_features(p_L, p_B, u, fluid)
        return p_L, p_B, features, self.predictor.predict(features, return_std)

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, _, fraction = self._fraction(p_L, p_B, u, fluid, False)
        dp = np.maximum(p_L - p_B, 0.0).ravel()
        force = self.spec.uniform_force(p_L, p_B) + fraction * self.spec.A_L * dp
        return force.reshape(p_L.shape)

    def extrapolating(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, features, _ = self._fraction(p_L, p_B, u, fluid, False)
        return (~self.domain.contains(features) | (p_L <= p_B).ravel()).reshape(p_L.shape)

    def force_std(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray | None:
        """Standard deviation of f_sim [N]: that of α times A_L·Δp."""
        p_L, p_B, _, (_, std) = self._fraction(p_L, p_B, u, fluid, True)
        if std is None:
            return None
        dp = np.maximum(p_L - p_B, 0.0).ravel()
        return (std * self.spec.A_L * dp).reshape(p_L.shape)


def write_manifest(folder: Path, manifest: dict) -> None:
    manifest = {"format_version": FORMAT_VERSION, **manifest}
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")


def read_manifest(folder: str | Path) -> dict:
    """The ``surrogate.json`` of a surrogate folder, checked for its format."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise InputError(f"{folder}: not a surrogate folder (no {MANIFEST}); train one with "
                         "`python training/train.py`")
    try:
        manifest = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise InputError(f"{path}: not valid JSON ({error})") from None
    from .registry import MAP_KINDS

    learned = [name for name, kind in MAP_KINDS.items() if kind.learned]
    if manifest.get("format_version") not in _READABLE or manifest.get("kind") not in learned:
        raise InputError(f"{path}: unknown surrogate format (need format_version "
                         f"{FORMAT_VERSION} and a learned kind: {', '.join(learned)})")
    return manifest


def load_learned_maps(folder: str | Path) -> tuple[LearnedFlowMap, LearnedForceMap]:
    """The flow and force map of a saved surrogate folder (NN or GP)."""
    from .registry import map_kind

    manifest = read_manifest(folder)
    load = map_kind(manifest["kind"]).load_predictor
    spec = FeatureSpec.from_dict(manifest["features"])
    flow_predictor = load(Path(folder), manifest["flow"]["predictor"])
    force_predictor = load(Path(folder), manifest["force"]["predictor"])
    return (LearnedFlowMap(spec, flow_predictor,
                           FeatureDomain.from_dict(manifest["flow"]["domain"]), manifest["kind"]),
            LearnedForceMap(spec, force_predictor,
                            FeatureDomain.from_dict(manifest["force"]["domain"]),
                            manifest["kind"]))
