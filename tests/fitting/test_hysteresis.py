"""The residual's two views: the runs' median line (map error moves it) and their hysteresis
half-width (friction changes it)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from surrogate.diagnosis.diagnose import diagnose
from surrogate.diagnosis.result import Candidate, Label, Score
from surrogate.diagnosis.rule import gains_in_own_view
from surrogate.fitting.hysteresis import hysteresis_split
from surrogate.fitting.logfit import fit_to_log
from surrogate.reporting.prose import hysteresis_share, summarise
from surrogate.synthetic.simulate import hidden_effect_case, noise_free_sequence


def ramps(runs: int = 2, samples: int = 40) -> pd.DataFrame:
    """Runs that ramp the flow up and back down, at slightly different flows each way."""
    rows = []
    for run in range(runs):
        up = np.linspace(1.0, 10.0, samples)
        down = np.linspace(10.0, 1.0, samples) + 0.05
        rows.append(pd.DataFrame({"run": f"R{run}", "q": np.concatenate([up, down]),
                                  "direction": ["up"] * samples + ["down"] * samples}))
    return pd.concat(rows, ignore_index=True)


def test_a_shift_shared_by_both_ramps_is_all_median_line():
    frame = ramps()
    split = hysteresis_split(frame)
    residual = 0.3 + 0.1 * frame["q"].to_numpy()  # the same error at the same flow either way
    median, half = split.rms(residual)
    assert half < 0.01 * median
    assert median == pytest.approx(np.sqrt(np.mean((0.3 + 0.1 * np.linspace(1, 10, 200)) ** 2)),
                                   rel=0.05)


def test_a_split_between_the_ramps_is_all_half_width():
    frame = ramps()
    split = hysteresis_split(frame)
    sign = np.where(frame["direction"] == "up", 1.0, -1.0)
    median, half = split.rms(0.5 * sign)
    assert median == pytest.approx(0.0, abs=1e-12)
    assert half == pytest.approx(0.5)


def test_runs_that_go_one_way_only_have_no_views():
    frame = ramps().query("direction == 'up'")
    split = hysteresis_split(frame)
    assert split.bins == 0
    assert np.isnan(split.rms(np.ones(len(frame)))).all()


def candidate(kind: str, median: float, half: float) -> Candidate:
    return Candidate(Label("trial", "a trial", "", kind, "physics"),
                     Score(rms_after=1.0, delta_bic=-50.0, median_rms=median,
                           half_width_rms=half))


@pytest.mark.parametrize("kind, median, half, passes", [
    ("friction", 1.0, 0.4, True),    # narrows the split it acts on
    ("friction", 0.5, 0.6, False),   # only moves the median line, and widens the split
    ("force", 0.8, 0.6, True),       # moves the median line closer
    ("force", 1.0, 0.4, False),      # only narrows the split: acts like friction, not a force
    ("leakage", 0.9, 0.5, True),
    ("sensor", 1.1, 0.5, False),
])
def test_a_candidate_must_narrow_the_view_its_physics_acts_on(kind, median, half, passes):
    assert gains_in_own_view(candidate(kind, median, half), 1.0, 0.5) is passes


def test_a_log_without_both_ramps_does_not_judge_by_views():
    assert gains_in_own_view(candidate("friction", np.nan, np.nan), np.nan, np.nan)


@pytest.mark.slow
@pytest.mark.parametrize("hidden, friction", [("friction_constant", True),
                                              ("flow_force_scale", False)])
def test_friction_gains_on_the_half_width_and_a_force_on_the_median_line(bench_log, hidden,
                                                                           friction):
    case = hidden_effect_case(hidden, sequence=noise_free_sequence(bench_log, every=8), seed=5)
    diagnosis = diagnose(fit_to_log(case.start, case.log).model, case.log)
    share = hysteresis_share(diagnosis, diagnosis.best)
    assert diagnosis.best.name == hidden and diagnosis.best.own_view
    assert (share > 0.5) if friction else (share < 0.5), share
    assert "half-width" in summarise(diagnosis)
