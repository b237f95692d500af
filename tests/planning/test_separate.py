"""Which bench run would tell two look-alike candidates apart."""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.diagnosis.diagnose import diagnose
from surrogate.effects import LIBRARY
from surrogate.fitting.logfit import fit_to_log
from surrogate.planning.bench_runs import candidate_runs, separating_run
from surrogate.description.presets import cfda
from surrogate.reporting.prose import diagnosis_document, summarise
from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence
from surrogate.core.units import from_si

FLOOR = 0.8e5  # [Pa] a noise floor of the shipped log's size


@pytest.fixture(scope="module")
def sequence(bench_log):
    return noise_free_sequence(bench_log, every=8)


@pytest.fixture(scope="module")
def model():
    return cfda().build()


def test_the_runs_to_make_leave_out_what_the_log_already_holds(sequence):
    runs, settings = candidate_runs(sequence)
    frame = sequence.frame
    held = {(round(from_si(t, "degC")), s) for t, s in
            frame.groupby("run")[["temperature", "p_Pe_nominal"]].median().itertuples(index=False)}
    assert not any((round(from_si(t, "degC")), s) in held for t, s, r in
                   settings[["temperature", "set_point", "rise"]].itertuples(index=False) if r == 0)
    # beyond the log's range on every axis, and every run carries its own settings
    assert from_si(settings["temperature"].min(), "degC") == pytest.approx(10.0)
    assert from_si(settings["temperature"].max(), "degC") == pytest.approx(70.0)
    assert settings["set_point"].max() == frame["p_Pe_nominal"].max() + 20e5
    for run, setting in settings.set_index("run").iterrows():
        rows = runs.frame[runs.frame["run"] == run]
        assert (rows["temperature"] == setting["temperature"]).all()
        assert (rows["p_Pe_nominal"] == setting["set_point"]).all()


def test_identical_models_are_separated_by_no_run(model, sequence):
    separation = separating_run(model, model.copy(), sequence, FLOOR)
    assert separation.difference == 0.0 and not separation.decides


def test_friction_growing_with_viscosity_is_told_apart_in_the_coldest_oil(model, sequence):
    """Viscous friction grows as the oil cools: the run that shows it best is the coldest."""
    viscous = LIBRARY.effect("friction_viscous")(K_nu=4.0)
    separation = separating_run(model, model.with_effects([*model.effects, viscous]), sequence,
                                FLOOR, ("cfda", "cfda + friction_viscous"))
    assert from_si(separation.temperature, "degC") == pytest.approx(10.0)
    assert separation.decides
    assert separation.to_json()["between"] == ["cfda", "cfda + friction_viscous"]
    assert "10 °C" in str(separation)


def test_a_parameter_per_run_cannot_be_carried_to_a_new_run(model, sequence):
    drift = LIBRARY.effect("pilot_zero_drift").for_runs(sequence.run_ids)
    assert separating_run(model, model.with_effects([*model.effects, drift]), sequence,
                          FLOOR) is None


@pytest.mark.slow
def test_diagnose_says_which_run_would_decide_between_look_alikes(sequence):
    """A pilot-transducer offset and a spring-preload offset both act as a constant force: no run
    within reach separates them, and the summary says so instead of naming one."""
    case = hidden_effect_case("pilot_transducer_offset", sequence=sequence, seed=3)
    diagnosis = diagnose(fit_to_log(case.start, case.log).model, case.log)
    assert set(diagnosis.best.group) >= {"pilot_transducer_offset", "spring_preload_offset"}
    separation = diagnosis.separation
    assert separation is not None and not separation.decides
    assert np.isfinite(separation.difference)
    assert "no bench run" in summarise(diagnosis) and "dedicated test" in summarise(diagnosis)
    assert diagnosis_document(diagnosis)["separating_run"]["decides"] is False
