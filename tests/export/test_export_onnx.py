"""The learned maps as ONNX graphs: onnxruntime reproduces the package to 1e-6 relative on
10,000 random states inside the CFD samples' domain (about 12 s for both kinds)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surrogate.cli import main
from surrogate.export.onnx_maps import parity, random_states
from surrogate.fluid import FluidState
from surrogate.maps.learned import load_learned_maps, trained_folder

ort = pytest.importorskip("onnxruntime")  # the test extra installs it


@pytest.mark.parametrize("kind", ["nn", "gp"])
def test_onnx_maps_reproduce_the_package(kind):
    flow, force = load_learned_maps(trained_folder(kind))
    compared = parity(flow, force, random_states(flow.coverage))
    for name, (found, value) in compared.items():
        assert np.all(np.isfinite(found)), name
        relative = np.abs(found - value) / np.abs(value)
        print(f"{kind} {name}: largest relative difference {relative.max():.2e}")
        assert relative.max() < 1e-6, name


def test_the_gp_graph_holds_its_inputs_beyond_the_data_as_the_package_does():
    """Far below the sampled pressure drops and viscosities the force GP holds Re, σ and the
    pressure level at the edge of its data: the graph clamps the same columns to the same
    range (what it would not if it clamped none, or others)."""
    flow, force = load_learned_maps(trained_folder("gp"))
    states = random_states(flow.coverage, count=2_000, seed=1)
    states["p_L"] = states["p_B"] + (states["p_L"] - states["p_B"]) * 1e-3  # mbar drops
    states["nu"] = states["nu"] * 0.2  # a thin oil the CFD never ran
    scaling = force.predictor.gp.arrays.features
    standardised = (force.features(states["p_L"], states["p_B"], states["u"],
                                   FluidState(states["nu"], states["rho"])) - scaling.mean
                    ) / scaling.std
    low, high = force.predictor.gp.held
    assert np.mean((standardised < low) | (standardised > high)) > 0.2  # the clamp is at work
    compared = parity(flow, force, states)
    for name in ("f_sim", "f_sim_std"):
        found, value = compared[name]
        assert np.all(np.isfinite(found)), name
        assert np.max(np.abs(found - value) / np.abs(value)) < 1e-6, name


@pytest.mark.parametrize("kind", ["nn", "gp"])
def test_below_the_smallest_opening_the_graphs_are_the_package(kind):
    """Toward the seat σ never falls below what no mesh says there
    (:func:`surrogate.maps.cfd_error.seat_error`) and a network's flow force goes on as the power
    of u its two smallest openings give (:meth:`LearnedForceMap.toward_seat`), and the GP's
    flow trend goes on as its tangent in the opening (:func:`surrogate.maps.gp.
    opening_polynomial`): the graphs' q, f_sim and their σ are the package's, down to a fifth
    of the smallest opening."""
    flow, force = load_learned_maps(trained_folder(kind))
    states = random_states(flow.coverage, count=2_000, seed=3)
    shares = np.exp(np.random.default_rng(3).uniform(np.log(0.2), 0.0, 2_000))
    states["u"] = flow.coverage.openings[0] * shares
    compared = parity(flow, force, states)
    for name in ("q", "q_std", "f_sim", "f_sim_std"):
        found, value = compared[name]
        assert np.max(np.abs(found - value) / np.abs(value)) < 1e-6, name


@pytest.mark.pipeline
def test_export_writes_the_onnx_files(tmp_path):
    out = tmp_path / "onnx"
    assert main(["export", "--model", "cfda-nn", "--format", "onnx", "--out", str(out),
                 "--quiet"]) == 0
    document = json.loads((out / "onnx.json").read_text())
    assert document["kind"] == "nn" and set(document["inputs"]) == {"u", "p_L", "p_B", "nu",
                                                                    "rho"}
    session = ort.InferenceSession(str(out / "force.onnx"), providers=["CPUExecutionProvider"])
    assert [o.name for o in session.get_outputs()] == ["f_sim", "f_sim_std"]
    summary = json.loads((out / "export.json").read_text())
    assert set(summary["files"]) == {"flow.onnx", "force.onnx", "onnx.json"}


def test_a_gp_with_a_matern_part_exports_as_the_package_evaluates_it():
    """A Matérn 3/2 part in the opening (surrogate.maps.gp.MATERN): the graph's mean and σ of C_d
    are the package's to 1e-6 relative."""
    from surrogate.data import load_cfd_samples
    from surrogate.features import targets
    from surrogate.learn.gaussian_process import fit_gp
    from surrogate.maps.gp import MATERN, GaussianProcessPredictor
    from surrogate.maps.learned import LearnedFlowMap
    from surrogate.core.paths import SHIPPED_CFD_SAMPLES

    flow, force = load_learned_maps(trained_folder("gp"))
    data = targets(flow.spec, load_cfd_samples(SHIPPED_CFD_SAMPLES).frame)
    arrays = fit_gp(data.flow_features, data.log_discharge, (("matern", (1, 0)), ("rbf", (1, 2))),
                    linear_mean=False, restarts=0)
    assert MATERN in arrays.kernel.kinds
    matern = LearnedFlowMap(flow.spec, GaussianProcessPredictor(arrays, "log_discharge"),
                            flow.domain, "gp", flow.calibration, flow.coverage)
    compared = parity(matern, force, random_states(flow.coverage, count=2_000, seed=2))
    for name in ("q", "q_std"):
        found, value = compared[name]
        assert np.all(np.isfinite(found)), name
        assert np.max(np.abs(found - value) / np.abs(value)) < 1e-6, name


def test_a_force_network_with_a_trend_exports_as_the_package_evaluates_it():
    """The bridged network's trend in (opening, Re) with its own holds
    (BridgedArchitecture.trend_width): the committed NN force members given a random trend, the
    graph's flow force and its σ are the package's to 1e-6 relative."""
    from dataclasses import replace

    from surrogate.maps.learned import LearnedForceMap
    from surrogate.maps.nn import NetworkEnsemble

    flow, force = load_learned_maps(trained_folder("nn"))
    ensemble = force.predictor
    knots = ensemble.architecture.knots
    architecture = replace(ensemble.architecture, trend_width=3,
                           trend_held={1: (knots[0], knots[-1]), 0: (-1.0, 1.0)})
    rng = np.random.default_rng(4)
    states = [{**state, **{name: 0.2 * rng.normal(size=shape) for name, shape in
                           architecture.parameter_shapes().items() if name.startswith("trend")}}
              for state in ensemble.states]
    trended = NetworkEnsemble(architecture, states, ensemble.feature_mean, ensemble.feature_std,
                              ensemble.output)
    trended_map = LearnedForceMap(force.spec, trended, force.domain, "nn", force.calibration,
                                  force.coverage)
    states_drawn = random_states(flow.coverage, count=2_000, seed=5)
    compared = parity(flow, trended_map, states_drawn)
    untrended = parity(flow, force, states_drawn)
    for name in ("f_sim", "f_sim_std"):
        found, value = compared[name]
        assert np.all(np.isfinite(found)), name
        assert np.max(np.abs(found - value) / np.abs(value)) < 1e-6, name
    # the trend is there: without it the flow force differs
    assert np.max(np.abs(untrended["f_sim"][1] / compared["f_sim"][1] - 1.0)) > 1e-3
