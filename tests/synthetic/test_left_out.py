"""Maps that never saw one opening (surrogate/synthetic/left_out.py): the samples left, the learned
kind retrained on them with its committed calibration, and a virtual valve on other maps than the
model under test's (eval/weak_leakages.py)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from surrogate.data import load_cfd_samples
from surrogate.core.errors import InputError
from surrogate.maps.learned import load_learned_maps, trained_folder
from surrogate.maps.registry import build_maps
from surrogate.core.paths import SHIPPED_CFD_SAMPLES
from surrogate.description.presets import maps
from surrogate.synthetic.left_out import maps_without_opening
from surrogate.synthetic.mismatch import MapMismatch, PerturbedForceMap
from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence
from surrogate.core.units import to_si

LEFT_OUT = to_si(0.13, "mm")


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def gp_without(tmp_path_factory):
    return maps_without_opening("gp", LEFT_OUT, tmp_path_factory.mktemp("left_out"))


def test_grid_is_built_from_every_sample_but_the_opening_and_the_shipped_file_is_untouched(
        tmp_path, cfd_samples):
    before = _sha(SHIPPED_CFD_SAMPLES)
    spec = maps_without_opening("grid", LEFT_OUT, tmp_path)
    assert _sha(SHIPPED_CFD_SAMPLES) == before
    left = load_cfd_samples(dict(spec.flow.options)["cfd"])
    at = np.isclose(cfd_samples.frame["u"], LEFT_OUT)
    assert 0 < at.sum() and len(left) == len(cfd_samples) - at.sum()
    assert not np.isclose(left.frame["u"], LEFT_OUT).any()


@pytest.mark.parametrize("opening_mm, says", [(0.12, "no sample at u = 0.12 mm"),
                                              (0.05, "inner opening"), (0.63, "inner opening")])
def test_an_opening_that_cannot_be_left_out_is_refused(tmp_path, opening_mm, says):
    with pytest.raises(InputError, match=says):
        maps_without_opening("grid", to_si(opening_mm, "mm"), tmp_path)


def test_maps_without_samples_have_no_opening_to_leave_out(tmp_path):
    with pytest.raises(InputError, match="not built from CFD samples"):
        maps_without_opening("orifice", LEFT_OUT, tmp_path)


def test_learned_maps_without_an_opening_err_most_there_and_keep_the_committed_calibration(
        gp_without, cfd_samples, valve):
    flow, force = build_maps(gp_without, valve)
    committed_flow, committed_force = load_learned_maps(trained_folder("gp"))
    assert flow.calibration.to_dict() == committed_flow.calibration.to_dict()
    assert force.calibration.to_dict() == committed_force.calibration.to_dict()
    assert not np.isclose(flow.coverage.openings, LEFT_OUT).any()
    frame, fluid = cfd_samples.frame, cfd_samples.fluid_state()
    p_L, p_B, u = (frame[c].to_numpy() for c in ("p_L", "p_B", "u"))
    error = np.abs(force.flow_force(p_L, p_B, u, fluid)
                   / committed_force.flow_force(p_L, p_B, u, fluid) - 1)
    at = np.isclose(u, LEFT_OUT)
    # retrained on the rest, the maps still agree where they saw the samples and part where
    # they did not (a map that saw the opening would agree everywhere)
    assert np.sqrt(np.mean(error[at] ** 2)) > 3 * np.sqrt(np.mean(error[~at] ** 2))


def test_the_virtual_valve_can_stand_on_other_maps_than_the_model_under_test(gp_without,
                                                                              bench_log):
    sequence = noise_free_sequence(bench_log, every=40)
    case = hidden_effect_case(None, sequence=sequence, seed=3, mismatch=MapMismatch(),
                              maps_under_test=gp_without, valve_maps=maps("gp"))
    assert isinstance(case.truth.force_map, PerturbedForceMap)
    assert np.isclose(case.truth.force_map.base.coverage.openings, LEFT_OUT).any()
    assert not np.isclose(case.start.force_map.coverage.openings, LEFT_OUT).any()


def test_written_cfd_samples_read_back_as_they_were(tmp_path, cfd_samples):
    from surrogate.data.writer import write_cfd_samples

    again = load_cfd_samples(write_cfd_samples(cfd_samples, tmp_path / "again.csv"))
    for column in ("u", "q", "p_B", "p_L", "f_sim", "nu", "rho", "temperature"):
        assert np.allclose(again.frame[column], cfd_samples.frame[column], rtol=1e-5), column
    assert list(again.frame["case"]) == list(cfd_samples.frame["case"])
