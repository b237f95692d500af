"""The learned maps as ONNX graphs: onnxruntime reproduces the package to 1e-6 relative on
10,000 random states inside the CFD samples' domain (about 12 s for both kinds)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from surrogate.cli import main
from surrogate.export.onnx_maps import flow_graph, force_graph
from surrogate.fluid import FluidState
from surrogate.maps.learned import load_learned_maps, trained_folder

ort = pytest.importorskip("onnxruntime")  # the test extra installs it


def random_states(coverage, count=10_000, seed=0):
    """States spread over the samples' openings, pressure drops, back pressures and
    viscosities (log-uniform where the samples span decades)."""
    rng = np.random.default_rng(seed)
    u = np.exp(rng.uniform(*np.log(coverage.openings[[0, -1]]), count))
    dp = np.exp(rng.uniform(np.log(coverage.dp_low.min()), np.log(coverage.dp_high.max()),
                            count))
    p_B = rng.uniform(*coverage.p_B_range, count)
    nu = np.exp(rng.uniform(*np.log(coverage.nu_range), count))
    rho = rng.uniform(840.0, 880.0, count)
    return {"u": u, "p_L": p_B + dp, "p_B": p_B, "nu": nu, "rho": rho}


@pytest.mark.parametrize("kind", ["nn", "gp"])
def test_onnx_maps_reproduce_the_package(kind):
    flow, force = load_learned_maps(trained_folder(kind))
    states = random_states(flow.coverage)
    query = (states["p_L"], states["p_B"], states["u"], FluidState(states["nu"], states["rho"]))
    expected = {"q": flow.flow(*query), "q_std": flow.flow_std(*query),
                "f_sim": force.force(*query), "f_sim_std": force.force_std(*query)}
    found = {}
    for graph in (flow_graph(flow), force_graph(force)):
        session = ort.InferenceSession(graph.SerializeToString(),
                                       providers=["CPUExecutionProvider"])
        names = [output.name for output in session.get_outputs()]
        found.update(zip(names, session.run(None, states)))
    for name, value in expected.items():
        assert np.all(np.isfinite(found[name])), name
        relative = np.abs(found[name] - value) / np.abs(value)
        print(f"{kind} {name}: largest relative difference {relative.max():.2e}")
        assert relative.max() < 1e-6, name


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
