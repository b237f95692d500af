"""Flow and force maps around any regressor, to judge off-the-shelf surrogates by the project's
own cross-validation (:mod:`.crossval`, ``eval/peers.py``).

A *peer* is anything with ``fit(X, y)`` and ``predict(X)`` (scikit-learn's convention). The flow
map's regressor predicts ln C_d and the force map's the flow-force fraction α = f_ff/(A_L·Δp), the
project's targets (:mod:`surrogate.features`), from one of two sets of inputs:

* ``"dimensionless"``: the project's features, (ln Re_q, ln u/U, ln σ_q) for the flow map and
  (ln Re, ln u/U, ln σ) built from Δp for the force map;
* ``"raw"``: (ln u, ln q, ln ν, p_B) for the flow map and (ln u, ln Δp, ln ν, p_B) for the force
  map, with u [m], q [m^3/s], Δp [Pa], ν [m^2/s], p_B [Pa]: what a surrogate sees without the
  physics.

The maps turn the predictions back into Δp, q and the flow force exactly as the learned maps do
(:mod:`.learned`): Δp = ½ρ·(q/(C_d·w·u))², f_ff = α·A_L·Δp. They have no uncertainty and no
coverage: ``calibration_inputs`` gives no spread and no distances, so a peer is judged on its
error alone.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import pandas as pd

from ..features import FeatureSpec, targets
from ..fluid import FluidState, broadcast_query
from ..valve import ValveParameters
from .base import FlowMap, ForceMap

#: the inputs a peer may read: the project's three features; the same with the force map's
#: pressure level, ln(Δp/p_atm), as the project's GP reads it; or raw ones
INPUTS = ("dimensionless", "dimensionless+level", "raw")
# floors under quantities that go into a logarithm of the raw inputs, far below anything physical
_SMALLEST = 1e-30


class Regressor(Protocol):
    """What a peer must offer: scikit-learn's ``fit`` and ``predict`` on 2-D inputs."""

    def fit(self, X: np.ndarray, y: np.ndarray): ...

    def predict(self, X: np.ndarray) -> np.ndarray: ...


def _check_inputs(inputs: str) -> None:
    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, not {inputs!r}")


def flow_inputs(spec: FeatureSpec, inputs: str, q, p_B, u, fluid: FluidState) -> np.ndarray:
    """The flow regressor's inputs at flow ``q`` [m^3/s], back pressure ``p_B`` [Pa] and opening
    ``u`` [m], flattened, shape (n, 3) (``"dimensionless"``) or (n, 4) (``"raw"``)."""
    _check_inputs(inputs)
    if inputs.startswith("dimensionless"):  # the flow map has no fourth feature
        return spec.flow_features(q, p_B, u, fluid)
    q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
    return np.column_stack([np.log(np.maximum(u.ravel(), _SMALLEST)),
                            np.log(np.maximum(q.ravel(), _SMALLEST)),
                            np.log(fluid.nu.ravel()), p_B.ravel()])


def force_inputs(spec: FeatureSpec, inputs: str, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
    """The force regressor's inputs at load pressure ``p_L`` [Pa], back pressure ``p_B`` [Pa] and
    opening ``u`` [m], flattened: the project's three force features (``"dimensionless"``, shape
    (n, 3)), with the pressure level as the GP reads them (``"dimensionless+level"``, (n, 4),
    :data:`~surrogate.features.FORCE_FEATURE_NAMES`), or raw ones ((n, 4))."""
    _check_inputs(inputs)
    if inputs.startswith("dimensionless"):
        return spec.force_features(p_L, p_B, u, fluid,
                                   count=4 if inputs == "dimensionless+level" else 3)
    p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
    return np.column_stack([np.log(np.maximum(u.ravel(), _SMALLEST)),
                            np.log(np.maximum((p_L - p_B).ravel(), _SMALLEST)),
                            np.log(fluid.nu.ravel()), p_B.ravel()])


class _Peer:
    """What a peer's flow and force maps share: the regressor, its inputs, and no uncertainty."""

    def __init__(self, spec: FeatureSpec, regressor: Regressor, inputs: str = "dimensionless",
                 kind: str = "peer"):
        _check_inputs(inputs)
        self.spec = spec
        self.regressor = regressor
        self.inputs = inputs
        self.kind = kind

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.kind}, {self.inputs})"

    def calibration_inputs(self, *query):
        """No spread and no distances: a peer is judged on its error, not its uncertainty."""
        return None, {}


class PeerFlowMap(_Peer, FlowMap):
    """Flow map whose ln C_d comes from a fitted regressor of :func:`flow_inputs`."""

    def log_discharge(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        """ln C_d [-] at flow ``q`` [m^3/s], flattened."""
        features = flow_inputs(self.spec, self.inputs, q, p_B, u, fluid)
        return np.asarray(self.regressor.predict(features), float).ravel()

    def pressure_drop(self, q, p_B, u, fluid: FluidState) -> np.ndarray:
        q, p_B, u, fluid = broadcast_query(q, p_B, u, fluid)
        shape = q.shape
        log_cd = self.log_discharge(q, p_B, u, fluid)
        q, u, rho = q.ravel(), u.ravel(), fluid.rho.ravel()
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            dp = self.spec.orifice_pressure_drop(q, u, rho) * np.exp(-2.0 * log_cd)
        # as the learned maps: no flow needs no pressure, a closed valve passes none
        dp = np.where(q > 0, np.where(u > 0, dp, np.inf), 0.0)
        return dp.reshape(shape)


class PeerForceMap(_Peer, ForceMap):
    """Force map whose flow-force fraction α comes from a fitted regressor of
    :func:`force_inputs`."""

    def flow_force_fraction(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        """α = f_ff/(A_L·Δp) [-] at load pressure ``p_L`` [Pa], flattened."""
        features = force_inputs(self.spec, self.inputs, p_L, p_B, u, fluid)
        return np.asarray(self.regressor.predict(features), float).ravel()

    def flow_force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        dp = np.maximum(p_L - p_B, 0.0).ravel()
        fraction = self.flow_force_fraction(p_L, p_B, u, fluid)
        return (fraction * self.spec.A_L * dp).reshape(p_L.shape)

    def force(self, p_L, p_B, u, fluid: FluidState) -> np.ndarray:
        p_L, p_B, u, fluid = broadcast_query(p_L, p_B, u, fluid)
        return (self.spec.uniform_force(p_L, p_B).reshape(p_L.shape)
                + self.flow_force(p_L, p_B, u, fluid))


def fit_peer_maps(frame: pd.DataFrame, valve: ValveParameters, flow_regressor: Regressor,
                  force_regressor: Regressor, inputs: str = "dimensionless",
                  kind: str = "peer") -> tuple[PeerFlowMap, PeerForceMap]:
    """Fit the two regressors to the CFD samples of ``frame`` (SI, ``CfdSamples.frame``) and
    wrap them as maps. The training inputs come from the same functions the maps query
    with, so a regressor that reproduces its training targets reproduces the samples."""
    spec = FeatureSpec.for_valve(valve)
    fluid = FluidState(frame["nu"].to_numpy(), frame["rho"].to_numpy())
    q, p_L, p_B, u = (frame[name].to_numpy() for name in ("q", "p_L", "p_B", "u"))
    truth = targets(spec, frame)
    flow_regressor.fit(flow_inputs(spec, inputs, q, p_B, u, fluid), truth.log_discharge)
    force_regressor.fit(force_inputs(spec, inputs, p_L, p_B, u, fluid),
                        truth.flow_force_fraction)
    return (PeerFlowMap(spec, flow_regressor, inputs, kind),
            PeerForceMap(spec, force_regressor, inputs, kind))
