"""The workbench finds what is hidden: synthetic logs with one effect switched on (or none).

Each log is the shipped test sequence (every 8th sample, for speed) replayed by a reference valve
with the hidden effect, plus sensor noise like the shipped bench's. The model under test starts
from the reference without the effect and its presets' starting values.
"""

from __future__ import annotations

import numpy as np
import pytest

from surrogate.diagnosis.diagnose import diagnose
from surrogate.effects import LIBRARY, load_effects_file
from surrogate.fitting.logfit import fit_to_log
from surrogate.reporting.prose import diagnosis_document, summarise
from surrogate.synthetic.simulate import (REALISTIC_MAGNITUDES, hidden_effect_case, identified,
                                          noise_free_sequence, random_settings)
from surrogate.testing import check_effect

pytestmark = pytest.mark.slow  # each case fits and diagnoses a synthetic log: seconds each

RATIO = 1.3  # the RMS after adding the effect must be within 1.3x the noise floor
EVERY = 8


@pytest.fixture(scope="module")
def sequence(bench_log):
    return noise_free_sequence(bench_log, every=EVERY)


def find(case, library=LIBRARY, shapes=True):
    """Fit the starting model, diagnose it over ``library`` (and the shape-free terms, unless
    ``shapes`` is false); return the diagnosis."""
    fitted = fit_to_log(case.start, case.log).model
    return diagnose(fitted, case.log, library, shapes=shapes)


#: the effects CI tries (one of each category and a per-run one); `pytest -m stress` tries all
CI_SLICE = {"friction_pilot_pressure", "spring_preload_offset", "pilot_zero_drift",
            "flow_force_scale", "laminar_leakage"}


@pytest.mark.parametrize("hidden", [
    name if name in CI_SLICE else pytest.param(name, marks=pytest.mark.stress)
    for name in sorted(REALISTIC_MAGNITUDES)])
def test_every_library_effect_is_found_at_a_realistic_magnitude(sequence, hidden):
    case = hidden_effect_case(hidden, sequence=sequence, seed=sorted(REALISTIC_MAGNITUDES)
                              .index(hidden))
    diagnosis = find(case)
    assert identified(diagnosis, hidden), (hidden, summarise(diagnosis))
    best = next(c for c in diagnosis.candidates if hidden in c.group)
    assert best.rms_after <= RATIO * diagnosis.noise_floor, (best.rms_after, diagnosis.noise_floor)
    # the hidden effect's group (one name, or the indistinguishable ones) reaches the floor too
    assert diagnosis.rms_before > 1.1 * diagnosis.noise_floor


def test_every_library_effect_has_a_realistic_magnitude():
    assert set(LIBRARY) <= set(REALISTIC_MAGNITUDES)


def test_indistinguishable_candidates_are_reported_as_one_group(sequence):
    case = hidden_effect_case("pilot_transducer_offset", sequence=sequence, seed=21)
    diagnosis = find(case)
    best = diagnosis.candidates[0]
    assert set(best.group) >= {"pilot_transducer_offset", "spring_preload_offset"}
    summary = summarise(diagnosis)
    assert "cannot tell apart" in summary
    # both explanations, with their categories and sizes, and neither preferred
    assert "(spring_preload_offset, physics: delta_F = " in summary
    assert "(pilot_transducer_offset, sensor: delta = " in summary
    assert "most likely" not in summary
    finding = diagnosis_document(diagnosis)["finding"]
    assert finding["look_alikes"] and {e["category"] for e in finding["explanations"]} == {
        "physics", "sensor"}


def test_nothing_is_discovered_when_nothing_is_hidden(sequence):
    for seed in (0, 1):
        case = hidden_effect_case(None, sequence=sequence, seed=seed)
        diagnosis = find(case)
        assert diagnosis.best is None, summarise(diagnosis)
        assert not any(c.significant for c in diagnosis.candidates)
        assert summarise(diagnosis).startswith("Nothing beyond noise is left")
        assert not diagnosis.sensor_checks, diagnosis.sensor_checks  # no run's sensor flagged


CUSTOM = '''
import numpy as np
from surrogate.effects import custom_effect

@custom_effect("friction", units={"k": "N"}, bounds={"k": (0.0, 50.0)},
               title="friction from the jet's side load, growing with flow")
def jet_side_load_friction(state, k=0.0):
    """Friction from the flow jet pressing the piston against its bore: k per 10 L/min."""
    return k * state.q / 1.6667e-4
'''


@pytest.fixture
def custom_library(tmp_path):
    path = tmp_path / "my_effects.py"
    path.write_text(CUSTOM)
    library = load_effects_file(path)
    for cls in library.values():
        check_effect(cls)  # the contract the built-in effects pass
    return library


def test_a_custom_effect_explains_what_the_library_cannot(sequence, custom_library):
    (name,) = custom_library
    library = LIBRARY + custom_library
    case = hidden_effect_case(name, {"k": 8.0}, sequence=sequence, seed=5, library=library)
    without = find(case, LIBRARY, shapes=False)
    assert without.candidates[0].rms_after > RATIO * without.noise_floor

    # beside the library, the friction of free shape in the flow finds it without being told
    shaped = find(case, LIBRARY)
    assert shaped.best is not None and shaped.best.name == "shape_friction_of_q", \
        summarise(shaped)
    assert shaped.best.rms_after < without.candidates[0].rms_after

    with_custom = find(case, library)
    assert identified(with_custom, name), summarise(with_custom)
    assert with_custom.candidates[0].rms_after <= RATIO * with_custom.noise_floor
    assert with_custom.candidates[0].rms_after < without.candidates[0].rms_after


@pytest.mark.stress
def test_identification_rate_over_randomised_cases(sequence, capsys):
    """Random effect, magnitude (0.6–1.5x realistic) and noise seed; at least 90 % found."""
    outcomes = []
    for case_number, (hidden, factor, values) in enumerate(random_settings(20, seed=2026)):
        case = hidden_effect_case(hidden, values, sequence=sequence, seed=100 + case_number)
        diagnosis = find(case)
        outcomes.append((hidden, round(factor, 2), identified(diagnosis, hidden)))
    rate = np.mean([found for *_, found in outcomes])
    with capsys.disabled():
        print(f"\nidentification rate over {len(outcomes)} randomised cases: {rate:.0%}; "
              f"missed: {[o for o in outcomes if not o[2]]}")
    assert rate >= 0.9, outcomes
