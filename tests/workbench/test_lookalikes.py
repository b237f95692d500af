"""Look-alikes from the Jacobian, entangled parameters and parameters pushed to a bound."""

from __future__ import annotations

import numpy as np

from surrogate.diagnosis.lookalikes import COLLINEAR, collinearity, grouped, own_directions
from surrogate.diagnosis.result import Candidate
from surrogate.fitting.identifiability import ENTANGLED, entangled_pairs, pushed_to_bounds
from surrogate.leastsquares import FitResult
from surrogate.presets import cfda

RNG = np.random.default_rng(7)
SAMPLES = 400


def candidate(name, probe, delta_bic=-50.0, change=None, **fields):
    change = RNG.normal(size=SAMPLES) if change is None else change
    return Candidate(name, name, "", "force", "physics", 1e5, delta_bic, probe=probe,
                     change=change, **fields)


def test_terms_that_differ_only_by_what_the_model_already_does_are_look_alikes():
    """Two columns that differ by a multiple of the model's own column are one finding,
    whatever their ΔBICs, and the bootstrap's preference plays no part."""
    own = RNG.normal(size=(SAMPLES, 2))
    shared = RNG.normal(size=SAMPLES)
    a = candidate("preload", (shared + 3 * own[:, 0])[:, None], delta_bic=-500)
    b = candidate("transducer", (2 * shared - own[:, 1])[:, None], delta_bic=-450)
    c = candidate("other", RNG.normal(size=(SAMPLES, 1)), delta_bic=-40)
    assert collinearity(own_directions(a, own), own_directions(b, own)) > 0.999
    assert collinearity(own_directions(a, own), own_directions(c, own)) < 0.3
    # without the model's columns taken out, they are not collinear: the test sees the model
    assert collinearity(own_directions(a, np.zeros((SAMPLES, 0))),
                        own_directions(b, np.zeros((SAMPLES, 0)))) < COLLINEAR
    groups = {g.name: g.group for g in grouped([a, b, c], own=own)}
    assert set(groups["preload"]) == {"preload", "transducer"} == set(groups["transducer"])
    assert groups["other"] == ("other",)


def test_per_run_and_wide_terms_are_left_to_their_prediction_changes():
    own = np.zeros((SAMPLES, 0))
    column = RNG.normal(size=(SAMPLES, 1))
    per_run = candidate("drift", np.hstack([column] * 2), per_run=True)
    wide = candidate("wide", RNG.normal(size=(SAMPLES, 3)))
    assert own_directions(per_run, own) is None and own_directions(wide, own) is None
    assert collinearity(own_directions(candidate("a", column), own), None) == 0.0


def _fit(names, correlation):
    return FitResult(None, names, 1.0, 10, 0.0, 0.0, np.asarray(correlation), True, "", 1)


def test_entangled_pairs_are_those_beyond_the_threshold_most_entangled_first():
    names = ["a.x", "b.y", "c.z"]
    correlation = [[1, -0.99, 0.2], [-0.99, 1, ENTANGLED + 0.01], [0.2, ENTANGLED + 0.01, 1]]
    pairs = entangled_pairs(_fit(names, correlation))
    assert [(p.first, p.second) for p in pairs] == [("a.x", "b.y"), ("b.y", "c.z")]
    assert entangled_pairs(_fit(names[:1], [[1.0]])) == [] and entangled_pairs(None) == []


def test_a_parameter_a_step_drives_to_its_bound_is_named_with_the_term_that_did_it():
    before = cfda().build()
    after = before.copy()
    after.parameters()["friction_constant.K1"].value = 0.0  # its lower bound
    (pushed,) = pushed_to_bounds(before, after, ["friction_pilot_pressure"])
    assert pushed.parameter == "friction_constant.K1" and pushed.by == ("friction_pilot_pressure",)
    assert pushed.before == 6.5 and pushed.after == 0.0 and pushed.unit == "N"
    # one that already sat on its bound before is no news
    assert pushed_to_bounds(after, after.copy(), ["x"]) == []
