"""Training the learned maps (NN and GP) from CFD samples, and saving them as folders."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.loaders import CfdSamples
from ..features import (ADDITIVE_GROUPS, FEATURE_NAMES, FORCE_FEATURE_NAMES, FeatureSpec,
                        Targets, targets)
from ..maps.gp import GaussianProcessPredictor
from ..maps.learned import LearnedFlowMap, LearnedForceMap
from ..maps.nn import NetworkEnsemble
from ..maps.opening_offsets import OpeningOffsets
from ..maps.sigma import SigmaCalibration
from ..maps.cfd_error import flow_cfd_error
from ..maps.coverage import Coverage
from ..maps.domain import FeatureDomain
from ..maps.package import seal, write_manifest
from ..maps.registry import learned_kinds, map_kind
from ..core.outputs import atomic_directory
from ..valve import ValveParameters
from .gaussian_process import fit_gp

#: the map kinds that are trained (the registry's learned kinds)
KINDS = tuple(learned_kinds())
#: the cross-validated errors behind a folder's calibration, next to its ``surrogate.json``
CROSS_VALIDATION_FILE = "cross_validation.csv"
#: how a folder keeps its cross-validated errors (6 significant digits)
CROSS_VALIDATION_FORMAT = "%.6g"

# Network settings: small (a few hundred weights per member); a deep ensemble of five members,
# whose spread is the networks' own uncertainty.
NN_WIDTH = 16
NN_MEMBERS = 5
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
# A decay on the hidden weights that read the opening (column 1), in both stages, bends the flow
# network between the sampled openings no more than the data ask (docs/maps.md, "How the learned
# maps are built").
FLOW_OPENING_DECAY: dict[int, float] = {1: 1e-6}
# A network that smooth in the opening cannot follow each mesh's own bias at the sampled openings;
# a term of its own gives each its mean residual, fading to 0 halfway to the next opening
# (surrogate.maps.opening_offsets).
FLOW_OPENING_OFFSETS = True
# The flow force: ln(−α) = a(opening, Re) + m(opening)·ln(Δp/p_atm) + b(σ), the opening bridged
# linearly between sampled openings (as the grid maps do) and the cavitation part shared by all
# openings: the samples collapse on σ across openings and back pressures (surrogate/maps/
# network.py, BridgedArchitecture).
FORCE_BRIDGE = dict(bridge_column=1, local_column=0, shared_column=2, level_column=3)
FORCE_WIDTH = 8
# No trend in (opening, Re) shared by all openings (BridgedArchitecture.trend_width): it helped
# a left-out opening but took the back-pressure set beyond 5 %, by an amount that moved with the
# members' initial weights.
FORCE_TREND_WIDTH = 0
# Between openings the bridge interpolates the openings' networks smoothed across all openings
# by a cubic in ln u (BridgedArchitecture.smoothing_degree); on a sampled opening it is that
# opening's own network, so only the left-out opening's error moves, and that error chose it.
FORCE_SMOOTHING_DEGREE = 3
# Beyond the samples' Reynolds number, cavitation number and pressure level (columns 0, 2, 3,
# plus the margin, in standard deviations) both force maps hold their inputs: the flow-force
# fraction stays near its value at the edge of the data instead of following the networks'
# linear terms off (which made f_sim fall with p_L far outside the data), or the GP's parts
# reverting to the mean (which made α < −1 far below the sampled pressure drops).
FORCE_HELD = (0, 2, 3)
FORCE_HOLD_MARGIN = 0.5
# The GP's flow force: ln(−α) from (ln Re, ln(u/U), ln σ, ln(Δp/p_atm)) (columns 0-3): the
# opening bridged linearly between sampled openings, its factor an RBF of Re and the pressure
# level; plus an RBF of (Re, u) and one of σ. Chosen by the four-scheme cross-validation
# (eval/force_gp_structures.py).
FORCE_GP_PARTS = (("bridge", (1, 0, 3)), ("rbf", (0, 1)), ("rbf", (2,)))
# The GP's flow map: ln C_d from (ln Re_q, ln(u/U), ln σ_q) as a trend (below) plus a Matérn 3/2 in
# the opening times an RBF of Re, plus an RBF of (u, σ). The Matérn's rougher correlation in the
# opening predicts a left-out opening from its neighbours instead of reverting toward the mean
# between them; the trend carries the coldest oil. Chosen by the four-scheme cross-validation
# (eval/force_gp_structures.py --flow).
FLOW_GP_PARTS = (("matern", (1, 0)), ("rbf", (1, 2)))
FLOW_GP_TREND = True
# The trend is a quadratic in the opening, ln(u/U), not a line: between distant openings (the
# 0.20-0.63 mm gap) the Matérn reverts to the trend, and a line there bent the flow 3.5 % below
# the NN's. Quadratic, because it predicts a left-out temperature far better than a line for a
# little more error leaving an opening out; a cubic loses a left-out temperature and a quartic
# a left-out opening (eval/force_gp_structures.py --flow; docs/maps.md).
FLOW_GP_TREND_DEGREE = 2
GP_RESTARTS = 10


@dataclass(frozen=True)
class TrainedSurrogate:
    """A flow map and a force map learned together, with what describes them."""

    kind: str
    flow_map: LearnedFlowMap
    force_map: LearnedForceMap
    seconds: float
    details: dict = field(default_factory=dict)

    def calibrate(self, flow: SigmaCalibration, force: SigmaCalibration) -> None:
        """Attach the calibrations found by cross-validation (:mod:`surrogate.maps.crossval`)."""
        self.flow_map.calibration, self.force_map.calibration = flow, force

    def save(self, folder: str | Path, training: dict, metrics: dict,
             cross_validation=None) -> None:
        """Write the folder (weights plus ``surrogate.json``, which records their SHA-256, and
        the cross-validated errors as ``cross_validation.csv`` if given), all at once or not at
        all."""
        kind = map_kind(self.kind)
        with atomic_directory(folder) as staging:
            # each entry records its weight file's SHA-256: loading refuses other bytes
            flow_entry = seal(staging, kind.save_predictor(staging, "flow",
                                                           self.flow_map.predictor))
            force_entry = seal(staging, kind.save_predictor(staging, "force",
                                                            self.force_map.predictor))
            force_names = FORCE_FEATURE_NAMES[:self.force_map.feature_count]
            write_manifest(staging, {
                "kind": self.kind,
                "feature_names": list(FEATURE_NAMES),
                "features": self.flow_map.spec.to_dict(),
                "coverage": self.flow_map.coverage.to_dict(),
                "flow": {"target": "ln C_d from (ln Re_q, ln(u/U), ln sigma_q)",
                         "feature_names": list(FEATURE_NAMES),
                         "constraints": kind.constraints["flow"],
                         "predictor": flow_entry, "domain": self.flow_map.domain.to_dict(),
                         "calibration": self.flow_map.calibration.to_dict(),
                         "cfd_error": self.flow_map.cfd_error},
                "force": {"target": "alpha = f_ff/(A_L*dp) from (ln Re, ln(u/U), ln sigma"
                                    + (", ln(dp/p_atm))" if len(force_names) == 4 else ")"),
                          "feature_names": list(force_names),
                          "constraints": kind.constraints["force"],
                          "predictor": force_entry, "domain": self.force_map.domain.to_dict(),
                          "calibration": self.force_map.calibration.to_dict()},
                "training": {**training, "seconds": round(self.seconds, 2), **self.details},
                "metrics": metrics,
            })
            if cross_validation is not None:
                cross_validation.to_csv(staging / CROSS_VALIDATION_FILE, index=False,
                                        float_format=CROSS_VALIDATION_FORMAT)


def kept_errors(errors):
    """Cross-validated errors (a DataFrame) as a folder keeps them, to the digits of its
    ``cross_validation.csv``: what a calibration is fitted to, so that :func:`recalibrate` on
    the folder fits the same constants. The fit's optimum can move with the errors' last digits
    (the GP's force calibration has two nearly equal optima, and the ones fitted to the errors in
    memory and to the file's differed in their floor, 0 against 1.3 %)."""
    import io

    import pandas as pd

    text = errors.to_csv(index=False, float_format=CROSS_VALIDATION_FORMAT)
    return pd.read_csv(io.StringIO(text))


def recalibrate(folder: str | Path, samples: CfdSamples
                ) -> tuple[SigmaCalibration, SigmaCalibration]:
    """Fit a trained folder's calibrations again from the cross-validated errors it keeps
    (``cross_validation.csv``, made on ``samples``) and write them, with the summary per scheme,
    into its ``surrogate.json``; the weights stay as they are. For a change in how σ is fitted
    (:func:`surrogate.maps.crossval.calibrate`), which needs no retraining. Returns (flow,
    force)."""
    import pandas as pd

    from ..maps.crossval import calibrate, summary
    from ..maps.package import MANIFEST, read_manifest

    folder = Path(folder)
    read_manifest(folder, learned_kinds())  # checked; rewritten below as it was, but for σ
    manifest = json.loads((folder / MANIFEST).read_text())
    errors = pd.read_csv(folder / CROSS_VALIDATION_FILE)
    powers = map_kind(manifest["kind"]).calibration_powers
    flow, force = calibrate(errors, use_spread=True, samples=samples, powers=(powers, powers))
    manifest["flow"]["calibration"] = flow.to_dict()
    manifest["flow"]["cfd_error"] = flow_cfd_error(samples.frame)  # the σ_CFD it was fitted with
    manifest["force"]["calibration"] = force.to_dict()
    manifest["metrics"]["cross_validation"] = summary(errors, flow, force, samples=samples)
    with atomic_directory(folder) as staging:  # replaced whole or not at all, in its own format
        (staging / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return flow, force


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
    coverage = Coverage.of_samples(frame[frame["q"] > 0])
    flow_map = LearnedFlowMap(spec, flow_predictor, FeatureDomain.fit(data.flow_features), kind,
                              coverage=coverage, cfd_error=flow_cfd_error(frame))
    # a predictor reads the first few force features (FORCE_FEATURE_NAMES); its domain the same
    force_features = data.force_features[:, :force_predictor.feature_count]
    force_map = LearnedForceMap(spec, force_predictor, FeatureDomain.fit(force_features),
                                kind, coverage=coverage)
    return TrainedSurrogate(kind, flow_map, force_map, seconds,
                            {"training_samples": int(len(frame))})


def learned_maps_on(kind: str, samples: CfdSamples, valve: ValveParameters,
                    train: np.ndarray) -> tuple[LearnedFlowMap, LearnedForceMap]:
    """The maps of ``kind`` trained on the ``train`` samples (a cross-validation fold; module
    level so that worker processes can run it)."""
    trained = train_surrogate(kind, samples, valve, train)
    return trained.flow_map, trained.force_map


def train_networks(data: Targets, progress, constrained: bool = True
                   ) -> tuple[NetworkEnsemble, NetworkEnsemble]:
    """The network ensembles of the ``nn`` kind: the monotone flow network (ln C_d) and the
    bridged force network (ln(−α))."""
    import torch

    from .monotone_nn import Architecture, SignConstrainedNet, state_arrays, train, widen

    def ensemble(features, signs, bounds, loss, offset, output, name, groups=ADDITIVE_GROUPS,
                 transition=None, knee_features=(), physics_groups=None, feature_decay=None):
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
                final = train(network, z, loss, offset=offset, seed=member, epochs=NN_EPOCHS,
                              feature_decay=feature_decay)
            else:
                physics = SignConstrainedNet(architecture(physics_groups))
                train(physics, z, loss, offset=offset, seed=member, epochs=NN_EPOCHS,
                      feature_decay=feature_decay)
                network = widen(physics, architecture(groups), seed=member)
                final = train(network, z, loss, offset=offset, epochs=NN_EPOCHS // 2,
                              learning_rate=2e-3, initialise=False,
                              feature_decay=feature_decay)
            progress(f"NN {name}: member {member + 1}/{NN_MEMBERS} trained, loss {final:.3e}")
            states.append(state_arrays(network))
        return NetworkEnsemble(architecture(groups), states, mean, std, output)

    log_cd = torch.as_tensor(data.log_discharge)
    flow = ensemble(data.flow_features, FLOW_SIGNS, FLOW_BOUNDS,
                    lambda r: torch.mean((r - log_cd) ** 2), float(log_cd.mean()),
                    "log_discharge", "flow (ln C_d)", FLOW_GROUPS, FLOW_TRANSITION,
                    FLOW_KNEE_FEATURES, FLOW_PHYSICS_GROUPS, FLOW_OPENING_DECAY)
    if FLOW_OPENING_OFFSETS:  # each mesh's own bias, where it is known (the sampled openings)
        residuals = data.log_discharge - flow.predict(data.flow_features)
        flow.opening_offsets = OpeningOffsets.fit(data.flow_features, residuals,
                                                  column=FEATURE_NAMES.index("log_opening"))
    return flow, _bridged_ensemble(data, progress)


def force_target(data: Targets) -> tuple[np.ndarray, str]:
    """The force maps' latent target: ln(−α) when every sample's flow force closes the valve (its
    error is the flow force's relative error), else α itself."""
    alpha = data.flow_force_fraction
    if np.all(alpha < 0):
        return np.log(-alpha), "log_negative_fraction"
    return alpha, "plain_fraction"


def _bridged_ensemble(data: Targets, progress) -> NetworkEnsemble:
    """The force network ensemble of the ``nn`` kind (:mod:`.bridged_nn`)."""
    from ..maps.network import BridgedArchitecture
    from .bridged_nn import train_bridged

    target, output = force_target(data)
    features = data.force_features  # Re, u, σ and the pressure level
    mean, std = features.mean(axis=0), features.std(axis=0)
    z = (features - mean) / std
    knots = tuple(float(k) for k in np.unique(np.round(z[:, FORCE_BRIDGE["bridge_column"]], 9)))
    held = {} if FORCE_HOLD_MARGIN is None else {
        column: (float(z[:, column].min()) - FORCE_HOLD_MARGIN,
                 float(z[:, column].max()) + FORCE_HOLD_MARGIN)
        for column in FORCE_HELD}
    # the trend holds its value beyond the end openings, as the bridge does, and beyond the
    # sampled Reynolds numbers with no margin: the back-pressure set lies at the top of the
    # samples' Re
    bridge, local = FORCE_BRIDGE["bridge_column"], FORCE_BRIDGE["local_column"]
    trend_held = {bridge: (knots[0], knots[-1]),
                  local: (float(z[:, local].min()), float(z[:, local].max()))}
    architecture = BridgedArchitecture(knots, FORCE_WIDTH, **FORCE_BRIDGE, held=held,
                                       trend_width=FORCE_TREND_WIDTH,
                                       trend_held=trend_held if FORCE_TREND_WIDTH else {},
                                       smoothing_degree=FORCE_SMOOTHING_DEGREE)
    states = []
    for member in range(NN_MEMBERS):
        states.append(train_bridged(architecture, z, target, seed=member))
        progress(f"NN force ({output.replace('_', ' ')}): member {member + 1}/{NN_MEMBERS} "
                 "trained")
    return NetworkEnsemble(architecture, states, mean, std, output)


def train_processes(data: Targets, progress) -> tuple[GaussianProcessPredictor, ...]:
    """The additive Gaussian processes of the ``gp`` kind (flow: ln C_d; force: α or ln(−α))."""
    flow = GaussianProcessPredictor(
        fit_gp(data.flow_features, data.log_discharge, FLOW_GP_PARTS, linear_mean=FLOW_GP_TREND,
               opening_degree=FLOW_GP_TREND_DEGREE, restarts=GP_RESTARTS), "log_discharge")
    progress("GP flow (ln C_d): fitted, condition number "
             f"{flow.arrays.training.condition_number:.1e}")
    target, name = force_target(data)
    force = GaussianProcessPredictor(
        fit_gp(data.force_features, target, FORCE_GP_PARTS, linear_mean=name == "plain_fraction",
               restarts=GP_RESTARTS, held=FORCE_HELD, held_margin=FORCE_HOLD_MARGIN),
        "fraction" if name == "plain_fraction" else name)
    progress(f"GP force ({force.target}): fitted, condition number "
             f"{force.arrays.training.condition_number:.1e}")
    return flow, force
