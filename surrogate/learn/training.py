"""Training the learned maps (NN and GP) from CFD samples, and saving them as folders."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.loaders import CfdSamples
from ..features import ADDITIVE_GROUPS, FEATURE_NAMES, FeatureSpec, Targets, targets
from ..maps.gp import GaussianProcessPredictor
from ..maps.learned import LearnedFlowMap, LearnedForceMap, write_manifest
from ..maps.nn import NetworkEnsemble
from ..maps.registry import MAP_KINDS, map_kind
from ..outputs import atomic_directory
from ..valve import ValveParameters
from .domain import FeatureDomain
from .gaussian_process import fit_gp

#: the map kinds that are trained (the registry's learned kinds)
KINDS = tuple(name for name, kind in MAP_KINDS.items() if kind.learned)

# Network settings: small (a few hundred weights per member), three members averaged.
NN_WIDTH = 16
NN_MEMBERS = 3
NN_EPOCHS = 2500
FLOW_SIGNS, FLOW_BOUNDS = (0, 0, 1), (0.8, 0.98, None)  # see surrogate/learn/monotone_nn.py
# Flow networks are trained in two stages. First the physics: C_d = C_inf(u, sigma_q) *
# (1 + Re_t(u)/Re_q)^(-1/2), the Reynolds number entering only through the laminar-turbulent
# blend whose knee Re_t moves with the opening. Then, starting from that solution, the first part
# also sees the Reynolds number and learns what the blend misses.
FLOW_PHYSICS_GROUPS = ((1,), (1, 2))
FLOW_GROUPS = ((0, 1), (1, 2))
FLOW_TRANSITION = 0
FLOW_KNEE_FEATURES = (1,)
FORCE_SIGNS, FORCE_BOUNDS = (1, 0, -1), (None, None, None)
GP_RESTARTS = 10

@dataclass
class TrainedSurrogate:
    """A flow map and a force map learned together, with what describes them."""

    kind: str
    flow_map: LearnedFlowMap
    force_map: LearnedForceMap
    seconds: float
    details: dict = field(default_factory=dict)

    def save(self, folder: str | Path, training: dict, metrics: dict) -> None:
        """Write the folder (weights plus ``surrogate.json``), all at once or not at all."""
        kind = map_kind(self.kind)
        with atomic_directory(folder) as staging:
            flow_entry = kind.save_predictor(staging, "flow", self.flow_map.predictor)
            force_entry = kind.save_predictor(staging, "force", self.force_map.predictor)
            write_manifest(staging, {
                "kind": self.kind,
                "feature_names": list(FEATURE_NAMES),
                "features": self.flow_map.spec.to_dict(),
                "flow": {"target": "ln C_d from (ln Re_q, ln(u/U), ln sigma_q)",
                         "constraints": kind.constraints["flow"],
                         "predictor": flow_entry, "domain": self.flow_map.domain.to_dict()},
                "force": {"target": "alpha = f_ff/(A_L*dp) from (ln Re, ln(u/U), ln sigma)",
                          "constraints": kind.constraints["force"],
                          "predictor": force_entry, "domain": self.force_map.domain.to_dict()},
                "training": {**training, "seconds": round(self.seconds, 2), **self.details},
                "metrics": metrics,
            })


def train_surrogate(kind: str, samples: CfdSamples, valve: ValveParameters,
                    train: np.ndarray | None = None,
                    progress: Callable[[str], None] = lambda message: None, *,
                    constrained: bool = True) -> TrainedSurrogate:
    """Train the flow and force map of a learned ``kind`` on the ``train`` samples, with the
    kind's registered trainer.

    ``constrained=False`` drops the network's sign and slope constraints (same architecture
    otherwise): an ablation that shows what the constraints buy; never used for shipped maps.
    """
    trainer = map_kind(kind).trainer_function()
    frame = samples.frame if train is None else samples.frame[np.asarray(train, bool)]
    spec = FeatureSpec.for_valve(valve)
    data = targets(spec, frame)
    started = time.perf_counter()
    options = {} if constrained else {"constrained": False}
    flow_predictor, force_predictor = trainer(data, progress, **options)
    seconds = time.perf_counter() - started
    flow_map = LearnedFlowMap(spec, flow_predictor, FeatureDomain.fit(data.flow_features), kind)
    force_map = LearnedForceMap(spec, force_predictor, FeatureDomain.fit(data.force_features),
                                kind)
    return TrainedSurrogate(kind, flow_map, force_map, seconds,
                            {"training_samples": int(len(frame))})


def train_networks(data: Targets, progress, constrained: bool = True
                   ) -> tuple[NetworkEnsemble, NetworkEnsemble]:
    """The monotone network ensembles of the ``nn`` kind (flow: ln C_d; force: α)."""
    import torch
    from torch.nn.functional import softplus

    from .monotone_nn import Architecture, SignConstrainedNet, state_arrays, train, widen

    def ensemble(features, signs, bounds, loss, offset, output, name, groups=ADDITIVE_GROUPS,
                 transition=None, knee_features=(), physics_groups=None):
        if not constrained:
            signs, bounds = (0,) * len(signs), (None,) * len(bounds)
        mean, std = features.mean(axis=0), features.std(axis=0)
        z = (features - mean) / std

        # the tanh parts hold their Reynolds correction beyond the data (the transition and
        # linear terms carry the trend there)
        held = {} if transition is None else {transition: (float(z[:, transition].min()),
                                                           float(z[:, transition].max()))}

        def architecture(parts):
            return Architecture(parts, NN_WIDTH, signs, bounds, tuple(std), transition,
                                knee_features=knee_features, held=held)

        states = []
        for member in range(NN_MEMBERS):
            if physics_groups is None:
                network = SignConstrainedNet(architecture(groups))
                final = train(network, z, loss, offset=offset, seed=member, epochs=NN_EPOCHS)
            else:
                physics = SignConstrainedNet(architecture(physics_groups))
                train(physics, z, loss, offset=offset, seed=member, epochs=NN_EPOCHS)
                network = widen(physics, architecture(groups), seed=member)
                final = train(network, z, loss, offset=offset, epochs=NN_EPOCHS // 2,
                              learning_rate=2e-3, initialise=False)
            progress(f"NN {name}: member {member + 1}/{NN_MEMBERS} trained, loss {final:.3e}")
            states.append(state_arrays(network))
        return NetworkEnsemble(architecture(groups), states, mean, std, output)

    log_cd = torch.as_tensor(data.log_discharge)
    flow = ensemble(data.flow_features, FLOW_SIGNS, FLOW_BOUNDS,
                    lambda r: torch.mean((r - log_cd) ** 2), float(log_cd.mean()),
                    "log_discharge", "flow (ln C_d)", FLOW_GROUPS, FLOW_TRANSITION,
                    FLOW_KNEE_FEATURES, FLOW_PHYSICS_GROUPS)
    alpha = torch.as_tensor(data.flow_force_fraction)
    if bool(torch.all(alpha < 0)):
        # every sample's flow force closes the valve, so the map's does too: 1 + α = e^(−softplus(−R))
        # keeps α in (−1, 0) however far it extrapolates (softplus rises, so the signs still hold)
        output, to_fraction = "closing_fraction", lambda r: torch.expm1(-softplus(-r))
        offset = float(-torch.log(torch.expm1(-torch.log1p(alpha))).mean())
    else:
        output, to_fraction = "fraction", torch.expm1
        offset = float(torch.log1p(alpha).mean())
    # relative error of the flow force itself, the quantity that is evaluated
    force = ensemble(data.force_features, FORCE_SIGNS, FORCE_BOUNDS,
                     lambda r: torch.mean((to_fraction(r) / alpha - 1.0) ** 2), offset, output,
                     f"force ({output.replace('_', ' ')})")
    return flow, force


def train_processes(data: Targets, progress) -> tuple[GaussianProcessPredictor, ...]:
    """The additive Gaussian processes of the ``gp`` kind (flow: ln C_d; force: α or ln(−α))."""
    flow = GaussianProcessPredictor(
        fit_gp(data.flow_features, data.log_discharge, ADDITIVE_GROUPS, linear_mean=False,
               restarts=GP_RESTARTS), "log_discharge")
    progress(f"GP flow (ln C_d): fitted, condition number {flow.arrays.condition_number:.1e}")
    alpha = data.flow_force_fraction
    if np.all(alpha < 0):  # flow forces that close the valve: model ln(−α), relative errors
        force = GaussianProcessPredictor(
            fit_gp(data.force_features, np.log(-alpha), ADDITIVE_GROUPS, linear_mean=False,
                   restarts=GP_RESTARTS), "log_negative_fraction")
    else:
        force = GaussianProcessPredictor(
            fit_gp(data.force_features, alpha, ADDITIVE_GROUPS, linear_mean=True,
                   restarts=GP_RESTARTS), "fraction")
    progress(f"GP force ({force.target}): fitted, condition number "
             f"{force.arrays.condition_number:.1e}")
    return flow, force
