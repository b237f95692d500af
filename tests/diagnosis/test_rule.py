"""The significance rule's pure pieces: ranking, the shape-free handicap, and when a shape-free
term replaces a library finding."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from surrogate.diagnosis.rule import RULE, delta_bic


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
