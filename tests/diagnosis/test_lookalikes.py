"""Look-alikes from the Jacobian, entangled parameters and parameters pushed to a bound."""

from __future__ import annotations

import numpy as np

from surrogate.diagnosis.lookalikes import (COLLINEAR, MAPS_ERROR, collinearity, declined, grouped,
                                           maps_error_rival, own_directions)
from surrogate.diagnosis.result import Candidate, Label, Rival, Score
from surrogate.diagnosis.rule import RULE
from surrogate.fitting.identifiability import ENTANGLED, entangled_pairs, pushed_to_bounds
from surrogate.fitting.leastsquares import FitResult
from surrogate.description.presets import cfda

RNG = np.random.default_rng(7)
SAMPLES = 400


def candidate(name, probe, delta_bic=-50.0, change=None, **fields):
    change = RNG.normal(size=SAMPLES) if change is None else change
    per_run = fields.pop("per_run", False)
    return Candidate(Label(name, name, "", "force", "physics", per_run=per_run),
                     Score(1e5, delta_bic, **fields), probe=probe, change=change)


def test_terms_that_differ_only_by_what_the_model_already_does_are_look_alikes():
    """Two columns that differ by a multiple of the model's own column are one finding,
    whatever their ΔBICs, and the bootstrap's preference plays no part."""
    own_matrix = RNG.normal(size=(SAMPLES, 2))
    shared = RNG.normal(size=SAMPLES)
    a = candidate("preload", (shared + 3 * own_matrix[:, 0])[:, None], delta_bic=-500)
    b = candidate("transducer", (2 * shared - own_matrix[:, 1])[:, None], delta_bic=-450)
    c = candidate("other", RNG.normal(size=(SAMPLES, 1)), delta_bic=-40)
    assert collinearity(own_directions(a, own_matrix), own_directions(b, own_matrix)) > 0.999
    assert collinearity(own_directions(a, own_matrix), own_directions(c, own_matrix)) < 0.3
    # without the model's columns taken out, they are not collinear: the test sees the model
    assert collinearity(own_directions(a, np.zeros((SAMPLES, 0))),
                        own_directions(b, np.zeros((SAMPLES, 0)))) < COLLINEAR
    groups = {g.name: g.group for g in grouped([a, b, c], own_matrix=own_matrix)}
    assert set(groups["preload"]) == {"preload", "transducer"} == set(groups["transducer"])
    assert groups["other"] == ("other",)


def test_per_run_and_wide_terms_are_left_to_their_prediction_changes():
    own_matrix = np.zeros((SAMPLES, 0))
    column = RNG.normal(size=(SAMPLES, 1))
    per_run = candidate("drift", np.hstack([column] * 2), per_run=True)
    wide = candidate("wide", RNG.normal(size=(SAMPLES, 3)))
    assert own_directions(per_run, own_matrix) is None and own_directions(wide, own_matrix) is None
    assert collinearity(own_directions(candidate("a", column), own_matrix), None) == 0.0


#: the model's held-out RMS per scheme before any candidate [Pa]
BEFORE = {"run": 2.0e5, "temperature": 2.0e5, "pilot pressure": 2.0e5}


def _scores(run, temperature=1.0e5, pilot=1.0e5):
    return {"run": run, "temperature": temperature, "pilot pressure": pilot}


def _rival(name, run, kind="leakage", category="physics", temperature=1.0e5):
    return Rival(name, name, kind, category, _scores(run, temperature))


def test_a_physics_claim_is_withheld_when_a_look_alike_of_another_kind_predicts_as_well():
    """The claim must predict the held-out runs better than each rival of another kind by the
    rule's margin, on the runs left out in turn or a condition left out; rivals of its own kind
    are the diagnosis' own choice, not look-alikes."""
    claim = candidate("detent", None, heldout_rms=1.00e5, heldout=_scores(1.00e5))
    just_behind = 1.00e5 / (1.0 - RULE.other_kind_gain) * 0.999
    clearly_behind = 1.00e5 / (1.0 - RULE.other_kind_gain) * 1.001
    maps = maps_error_rival(_scores(0.99e5))
    assert declined(claim, [_rival("leak", clearly_behind)], BEFORE, None, 1e4) is None
    found = declined(claim, [_rival("leak", just_behind), _rival("force shape", 0.9e5, "force"),
                             maps], BEFORE, None, 1e4)
    assert [r.name for r in found.rivals] == [MAPS_ERROR, "leak"]  # closest first
    assert found.claim is claim and found.separation is None  # no model to replay here
    # a correction of the maps of free shape is no rival: the maps' error within σ stands for it
    assert declined(claim, [_rival("flow-force factor", 0.5e5, "force", "map correction")],
                    BEFORE, None, 1e4) is None
    # a rival as good on each run left out but clearly worse on the pilot pressures left out
    # is told apart by them
    worse = Rival("leak", "leak", "leakage", "physics", _scores(0.9e5, pilot=1.2e5))
    assert declined(claim, [worse], BEFORE, None, 1e4) is None


def test_a_rival_that_cannot_predict_a_left_out_condition_is_no_explanation():
    """A rival must itself predict runs it was not fitted to, as a discovery must: one that
    does no better on a whole temperature or pilot pressure left out than the model explains
    nothing, however close it comes to the claim."""
    claim = candidate("detent", None, heldout_rms=1.0e5, heldout=_scores(1.0e5, 1.9e5, 1.95e5))
    blind = Rival("leak", "leak", "leakage", "physics", _scores(0.98e5, 1.95e5, 1.95e5))
    assert declined(claim, [blind], BEFORE, None, 1e4) is None
    seeing = Rival("leak", "leak", "leakage", "physics", _scores(0.98e5, 1.9e5, 1.95e5))
    assert declined(claim, [seeing], BEFORE, None, 1e4) is not None


def test_only_physics_claims_face_look_alikes_of_other_kinds():
    close = [_rival("leak", 1.0e5), maps_error_rival(_scores(1.0e5))]
    for category in ("sensor", "map correction"):
        claim = Candidate(Label("c", "c", "", "sensor", category),
                          Score(1e5, -50.0, heldout_rms=1.0e5, heldout=_scores(1.0e5)))
        assert declined(claim, close, BEFORE, None, 1e4) is None
    assert declined(None, close, BEFORE, None, 1e4) is None


def _fit(names, correlation):
    return FitResult(None, names, 1.0, 10, np.asarray(correlation), True, "", 1)


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


def test_the_advice_on_a_withheld_claim_names_the_run_the_cfd_and_how_to_test_it():
    from surrogate.diagnosis.result import Declined
    from surrogate.planning.bench_runs import Separation
    from surrogate.reporting.prose import withheld_advice

    claim = candidate("progressive_spring", None, heldout_rms=1.0e5, heldout=_scores(1.0e5))
    run = Separation(283.15, 65e5, 10e5, 1.2e5, 0.8e5, ("progressive_spring", "shape_leakage"))
    advice = withheld_advice(Declined(claim, (_rival("shape_leakage", 1.0e5),
                                              maps_error_rival(_scores(1.0e5))), run))
    assert "progressive_spring and shape_leakage, the CFD maps' own error" in advice
    assert "Measure a bench run at 10 °C and p_Pe = 65 bar" in advice and "1.5×" in advice
    assert "suggest-cfd" in advice and "fit --add progressive_spring on a log with that run" \
        in advice
    undecided = Separation(283.15, 65e5, 0.0, 0.5e5, 0.8e5, run.between)
    advice = withheld_advice(Declined(claim, (_rival("shape_leakage", 1.0e5),), undecided))
    assert "Measure" not in advice and "suggest-cfd" not in advice and "a new log" in advice


def test_a_shape_of_the_findings_kind_that_fits_as_well_is_named_beside_it():
    """A library finding and a shape-free term of its kind that tie on ΔBIC (the shape with its
    handicap) and pass the rule on their own are one finding with two explanations; a shape
    clearly behind, of another kind, or failing the rule is not."""
    from surrogate.diagnosis.lookalikes import alike_shapes, joined
    from surrogate.diagnosis.result import ShapeCurve

    curve = ShapeCurve("p_L", "the load pressure", "bar", "N", np.zeros(2), np.zeros(2),
                       np.zeros(2), 0.01)
    scores = _scores(1.0e5)

    def term(name, delta_bic, kind="friction", shape=True, heldout=scores):
        return Candidate(Label(name, name, "", kind, "physics"),
                         Score(1.0e5, delta_bic, heldout=heldout, heldout_rms=heldout["run"],
                               own_view=True), curve=curve if shape else None)

    finding = term("friction_seal_pressure", -430.0, shape=False)
    tied = term("shape_friction_of_p_L", -433.0)  # -423 with its handicap: within 10
    behind = term("shape_friction_of_q", -415.0)  # -405: clearly behind
    other_kind = term("shape_leakage", -433.0, kind="leakage")
    blind = term("shape_friction_of_nu", -433.0, heldout=_scores(1.99e5, 1.99e5, 1.99e5))
    alike = alike_shapes(finding, [tied, behind, other_kind, blind], 1.5e5, 1.0e5, BEFORE)
    assert alike == ["shape_friction_of_p_L"]
    groups = {c.name: c.group for c in joined([finding, tied, behind], finding.name, alike)}
    assert groups == {"friction_seal_pressure": ("shape_friction_of_p_L",),
                      "shape_friction_of_p_L": ("friction_seal_pressure",),
                      "shape_friction_of_q": ()}


def test_the_maps_error_is_judged_beside_the_claim_not_in_its_place():
    """Every log holds the maps' error: a weak true effect may explain less than it does, yet
    add to it. The claim stands when, with the maps' error fitted beside it, it predicts the
    runs left out clearly better than the maps' error alone; it is withheld when it adds
    nothing the maps' error does not."""
    claim = candidate("friction_pilot_pressure", None, heldout_rms=1.2e5,
                      heldout=_scores(1.2e5, 1.2e5, 1.2e5))
    maps = maps_error_rival(_scores(1.0e5, 1.0e5, 1.0e5))  # better than the claim alone
    adds = _scores(0.95e5, 1.0e5, 1.0e5)  # 5 % better on the runs left out beside it
    assert declined(claim, [maps], BEFORE, None, 1e4, beside_maps=adds) is None
    nothing = _scores(0.99e5, 0.99e5, 0.99e5)
    withheld = declined(claim, [maps], BEFORE, None, 1e4, beside_maps=nothing)
    assert [r.name for r in withheld.rivals] == [MAPS_ERROR]
    assert withheld.beside_maps == nothing


def test_the_maps_error_is_a_rival_even_where_it_gains_little_by_itself():
    """The maps do err within their σ whatever a log shows: a claim must predict the runs left
    out clearly better beside the maps' error than the maps' error alone, even where the maps'
    error alone gains less than a discovery must (off-library case 4260 on GP maps: a leak of
    free shape beside a true friction of p_L gained 3.4 % on the runs left out beside it, and
    stood while the maps' error, which gained 2 % alone, was not asked). A physics rival of
    another kind that gains too little is still no explanation
    (:func:`test_a_rival_that_cannot_predict_a_left_out_condition_is_no_explanation`)."""
    before = _scores(1.174e5, 1.171e5, 1.749e5)
    claim = candidate("shape_leakage", None, heldout_rms=1.10e5,
                      heldout=_scores(1.10e5, 1.10e5, 1.60e5))
    maps = maps_error_rival(_scores(1.15e5, 1.17e5, 1.70e5))  # 2 % better: no discovery
    assert not RULE.predicts_unseen(maps, before)
    beside = _scores(1.133e5, 1.22e5, 1.672e5)  # within 3 % of it on every scheme
    withheld = declined(claim, [maps], before, None, 1e4, beside_maps=beside)
    assert [r.name for r in withheld.rivals] == [MAPS_ERROR]
    # where the claim beside the maps' error is clearly better than they are alone, it stands
    clearly = _scores(1.05e5, 1.10e5, 1.60e5)
    assert declined(claim, [maps], before, None, 1e4, beside_maps=clearly) is None
