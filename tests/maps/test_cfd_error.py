"""The CFD's own error in Δp: the mesh study and the samples' scatter, pooled by their degrees of
freedom (surrogate/maps/cfd_error.py)."""

import numpy as np
import pandas as pd
import pytest

from surrogate.maps.cfd_error import (CFD_ERROR, FLOW_CFD_ERROR, MESH_STUDY_DP_CHANGE,
                                      SHIPPED_CFD_ERROR, TREND_DEGREE, dp_error_estimates,
                                      mesh_study_variance, opening_scatter, pooled_dp_error,
                                      shipped_dp_error, write_dp_error)

OPENINGS = np.array([0.05, 0.08, 0.10, 0.13, 0.16, 0.20]) * 1e-3  # [m]


def samples_with_biases(biases, openings=OPENINGS, jitter=0.0, seed=0) -> pd.DataFrame:
    """An SI frame of sweeps at three temperatures and five flows whose ln Δp is a quadratic in
    ln u (other at each temperature and flow) plus one bias per opening, shared by all its
    sweeps, and ``jitter`` of independent scatter."""
    rng = np.random.default_rng(seed)
    rows = []
    for temperature in (293.15, 313.15, 333.15):
        for q in np.array([1.0, 3.0, 6.0, 9.0, 12.0]) / 6e4:
            log_u = np.log(openings)
            trend = 16.0 - 1.7 * log_u + 0.02 * log_u ** 2 + 0.3 * np.log(q * 6e4)
            log_dp = trend + np.asarray(biases) + jitter * rng.standard_normal(len(openings))
            rows.append(pd.DataFrame({"temperature": temperature, "u": openings, "q": q,
                                      "nu": 4.6e-5, "p_B": 5e5,
                                      "p_L": 5e5 + np.exp(log_dp) / 1e4}))
    return pd.concat(rows, ignore_index=True)


def test_a_smooth_characteristic_has_no_mesh_scatter():
    """No bias, no scatter: the quadratic in ln u takes the whole characteristic."""
    squares, freedom = opening_scatter(samples_with_biases(np.zeros(len(OPENINGS))))
    assert squares == pytest.approx(0.0, abs=1e-20)
    assert freedom == len(OPENINGS) - (TREND_DEGREE + 1)


def test_the_openings_biases_are_found_with_the_trend_taking_three_of_them():
    """Biases drawn per opening (one mesh each) are estimated without bias over many draws: the
    mean of s² matches their variance, the trend's three parameters counted out."""
    rng = np.random.default_rng(1)
    estimates = [opening_scatter(samples_with_biases(0.01 * rng.standard_normal(6)))[0]
                 for _ in range(400)]
    assert np.mean(estimates) == pytest.approx(0.01 ** 2, rel=0.12)


def test_an_unsampled_gap_parts_the_runs_and_a_short_run_counts_nothing():
    """An opening far above the others (0.63 mm beyond 0.20) is no part of their trend: adding
    it, with any bias, changes neither s² nor ν."""
    biases = 0.01 * np.random.default_rng(2).standard_normal(6)
    alone = opening_scatter(samples_with_biases(biases))
    with_far = opening_scatter(samples_with_biases(np.r_[biases, 0.2],
                                                   np.r_[OPENINGS, 0.63e-3]))
    assert with_far == pytest.approx(alone)


def test_the_pooled_error_weighs_each_estimate_by_its_degrees_of_freedom():
    """√((ν₁s₁² + ν₂s₂²)/(ν₁ + ν₂)), the mesh study's on one degree per change."""
    frame = samples_with_biases(0.004 * np.random.default_rng(3).standard_normal(6))
    study, study_freedom = mesh_study_variance()
    assert study_freedom == len(MESH_STUDY_DP_CHANGE)
    assert study == pytest.approx(np.mean(np.square(MESH_STUDY_DP_CHANGE)) / 1e4)
    squares, freedom = opening_scatter(frame)
    expected = np.sqrt((study_freedom * study + freedom * squares) / (study_freedom + freedom))
    assert pooled_dp_error(frame) == pytest.approx(expected)


def test_the_shipped_error_is_the_pooled_estimate_of_the_shipped_samples(cfd_samples):
    """The constant every map adds is what the shipped samples give, kept in the package (a
    wheel carries no samples) for exactly the shipped sample file: about 1.3 % of Δp (0.53 % on
    3 degrees of freedom from the samples, 1.59 % on 5 from the mesh study). Recomputed here, so
    the kept file cannot drift from the samples (``python training/train.py --kinds grid``
    writes it)."""
    import json

    from surrogate.core.paths import SHIPPED_CFD_SAMPLES
    from surrogate.maps.package import file_hash

    stored = json.loads(SHIPPED_CFD_ERROR.read_text())
    assert stored["cfd_sha256"] == file_hash(SHIPPED_CFD_SAMPLES)
    recomputed = dp_error_estimates(cfd_samples.frame)  # to rounding: another BLAS may differ
    for name in ("mesh study", "samples"):
        assert stored["dp"][name]["freedom"] == recomputed[name]["freedom"]
        assert stored["dp"][name]["sigma"] == pytest.approx(recomputed[name]["sigma"], rel=1e-9)
    assert CFD_ERROR["dp"] == stored["dp"]["pooled"]
    assert CFD_ERROR["dp"] == pytest.approx(pooled_dp_error(cfd_samples.frame), rel=1e-9)
    assert FLOW_CFD_ERROR == pytest.approx(CFD_ERROR["dp"] / 2)
    squares, freedom = opening_scatter(cfd_samples.frame)
    assert freedom == 3 and 0.004 < np.sqrt(squares) < 0.007
    assert np.sqrt(squares) < CFD_ERROR["dp"] < np.sqrt(mesh_study_variance()[0])


def test_without_the_kept_file_the_error_is_computed_from_the_samples(tmp_path, cfd_samples):
    """A checkout before the file was first written still imports, with the same σ."""
    assert shipped_dp_error(tmp_path / "absent.json") == pytest.approx(CFD_ERROR["dp"], rel=1e-9)
    written = write_dp_error(tmp_path / "cfd" / "cfd_error.json", cfd_samples.frame, "0" * 64)
    assert shipped_dp_error(tmp_path / "cfd" / "cfd_error.json") == written["dp"]["pooled"]


def test_grid_maps_of_other_samples_carry_their_own_meshes_error(cfd_samples, valve,
                                                                 meshes_of_their_own):
    """A user's CFD whose openings scatter three times as much (±3 % in Δp, opening by opening):
    the grid built on it says so in σ, where the shipped samples' 0.65 % would call it
    certain."""
    from surrogate.maps.cfd_error import flow_cfd_error
    from surrogate.maps.grid import grid_maps_on

    shipped_flow, _ = grid_maps_on(cfd_samples, valve)
    assert shipped_flow.cfd_error == FLOW_CFD_ERROR
    theirs = meshes_of_their_own
    flow, _ = grid_maps_on(theirs, valve)
    assert flow.cfd_error == flow_cfd_error(theirs.frame)
    assert flow.cfd_error > 1.2 * FLOW_CFD_ERROR
    openings = np.unique(theirs.frame["u"])
    assert np.all(flow.mesh_error_at(openings) >= flow.cfd_error * (1 - 1e-12))


def test_learned_maps_read_the_meshes_error_their_training_recorded(tmp_path):
    """A learned surrogate records σ_CFD of its training samples in its manifest; one written
    before it did (trained on the shipped samples) has theirs; an absurd one is refused."""
    import json

    from surrogate.core.errors import InputError
    from surrogate.maps.learned import load_learned_maps, trained_folder

    folder = tmp_path / "gp"
    folder.mkdir()
    for path in trained_folder("gp").iterdir():
        (folder / path.name).write_bytes(path.read_bytes())
    manifest = json.loads((folder / "surrogate.json").read_text())
    assert manifest["flow"]["cfd_error"] == pytest.approx(FLOW_CFD_ERROR, rel=1e-12)
    for recorded, expected in ((0.02, 0.02), (None, FLOW_CFD_ERROR)):
        if recorded is None:
            del manifest["flow"]["cfd_error"]
        else:
            manifest["flow"]["cfd_error"] = recorded
        (folder / "surrogate.json").write_text(json.dumps(manifest))
        flow, force = load_learned_maps(folder)
        assert flow.cfd_error == expected
        assert force.cfd_error == force.__class__.cfd_error
    manifest["flow"]["cfd_error"] = 5.0
    (folder / "surrogate.json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match=r"flow.*cfd_error.*must lie in \[0, 1\]"):
        load_learned_maps(folder)


def test_the_gaps_prior_is_a_floor_under_a_calibration_that_bridged_such_spans():
    """Two estimates of one error (the grid's own, from openings left out of its bridge, and the
    prior of what no mesh says) do not add; a calibration that never bridged a gap gets the
    prior beside it."""
    from surrogate.maps.cfd_error import valve_sigma

    calibrated, meshes, gap = np.array([0.06, 0.01, 0.0]), 0.02, np.array([0.05, 0.05, 0.0])
    assert np.allclose(valve_sigma(calibrated, meshes, gap, gap_is_floor=True),
                       [np.hypot(0.06, 0.02), 0.05, 0.02])
    assert np.allclose(valve_sigma(calibrated, meshes, gap),
                       [np.hypot(0.06, 0.05), np.hypot(0.01, 0.05), 0.02])


def test_grid_maps_take_the_gaps_prior_as_a_floor_and_learned_ones_beside_their_own(
        cfd_samples, valve):
    """At the middle of the shipped 0.20–0.63 mm gap: the grid's σ is the larger of its own
    (with its meshes') and the gap's prior; the GP's its own and the prior in quadrature."""
    from surrogate.fluid import FluidState
    from surrogate.maps.cfd_error import GAP_FLOW_ERROR, GAP_FORCE_ERROR
    from surrogate.maps.grid import grid_maps_on
    from surrogate.maps.registry import build_maps

    u = np.full(3, np.sqrt(0.20 * 0.63) * 1e-3)
    p_B, p_L = np.full(3, 5e5), np.array([40e5, 100e5, 200e5])
    fluid = FluidState(np.full(3, 4.6e-5), np.full(3, 870.0))
    grid_flow, grid_force = grid_maps_on(cfd_samples, valve)
    gp_flow, gp_force = build_maps("gp", valve)
    for flow, floor in ((grid_flow, True), (gp_flow, False)):
        q = flow.flow(p_L, p_B, u, fluid)
        own = flow.calibration.std(*flow.calibration_inputs(q, p_B, u, fluid))
        meshes = flow.mesh_error_at(u)
        expected = (np.maximum(np.hypot(own, meshes), GAP_FLOW_ERROR) if floor
                    else np.hypot(own, np.maximum(meshes, GAP_FLOW_ERROR)))
        assert np.allclose(flow.log_discharge_std(q, p_B, u, fluid), expected, rtol=1e-9)
    for force, floor in ((grid_force, True), (gp_force, False)):
        own = force.calibration.std(*force.calibration_inputs(p_L, p_B, u, fluid))
        meshes = force.mesh_error_at(p_B, u)
        expected = (np.maximum(np.hypot(own, meshes), GAP_FORCE_ERROR) if floor
                    else np.hypot(own, np.maximum(meshes, GAP_FORCE_ERROR)))
        assert np.allclose(force.relative_force_std(p_L, p_B, u, fluid), expected, rtol=1e-9)
