"""The significance rule's pure pieces: ranking, the shape-free handicap, when a shape-free
term replaces a library finding, and what it asks of a candidate on runs it was not fitted to."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from surrogate.diagnosis.rule import RULE, delta_bic
from surrogate.fitting.heldout import HEADLINE


@dataclass
class Scored:
    """What the rule reads off a candidate."""

    delta_bic: float
    heldout_rms: float
    shape_free: bool = False
    rms_after: float = 1.0


def test_a_shape_free_term_ranks_behind_a_library_term_that_fits_about_as_well():
    library, shape = Scored(-100.0, 1.0), Scored(-105.0, 1.0, shape_free=True)
    assert RULE.rank(library) < RULE.rank(shape)
    assert RULE.rank(Scored(-115.0, 1.0, shape_free=True)) < RULE.rank(library)


@pytest.mark.parametrize("shape_bic, shape_heldout, replaces", [
    (-121.0, 0.95, True),    # decisively better in ΔBIC and better on held-out runs
    (-121.0, 1.01, False),   # better in ΔBIC, worse on held-out runs: the named term stays
    (-115.0, 0.90, False),   # better on held-out runs, but not by the handicap and threshold
    (-119.9, 0.95, False),   # just short of them
])
def test_a_shape_replaces_a_finding_only_when_it_fits_decisively_better_and_predicts_better(
        shape_bic, shape_heldout, replaces):
    finding = Scored(-100.0, 1.0)
    shape = Scored(shape_bic, shape_heldout, shape_free=True)
    assert RULE.replaces(shape, finding) is replaces


def test_delta_bic_weighs_the_gain_against_the_parameters_it_took():
    assert delta_bic(100.0, 100.0, 1000.0, 0.0) == 0.0
    assert delta_bic(100.0, 100.0, 1000.0, 2.0) == pytest.approx(2.0 * 6.907755, rel=1e-6)
    assert delta_bic(90.0, 100.0, 1000.0, 1.0) < 0.0


@pytest.mark.parametrize("after, expected", [
    ({"run": 0.90, "temperature": 0.90, "pilot pressure": 0.90}, True),
    ({"run": 0.90, "temperature": 0.90, "pilot pressure": 1.50}, True),  # one condition is enough
    ({"run": 0.90, "temperature": 1.20, "pilot pressure": 0.90}, True),
    ({"run": 0.90, "temperature": 1.00, "pilot pressure": 1.00}, False),  # no condition
    ({"run": 0.99, "temperature": 0.80, "pilot pressure": 0.80}, False),  # not the runs (3 %)
    ({"temperature": 0.80, "pilot pressure": 0.80}, False),  # no run scheme: nothing to judge
])
def test_a_candidate_must_predict_unseen_runs_and_one_unseen_condition(after, expected):
    before = {HEADLINE: 1.0, "temperature": 1.0, "pilot pressure": 1.0}
    assert RULE.gains_on_unseen(after, before) is expected


def test_a_log_without_conditions_is_judged_on_its_runs():
    assert RULE.gains_on_unseen({"run": 0.9}, {"run": 1.0})
    assert not RULE.gains_on_unseen({"run": 0.99}, {"run": 1.0})
