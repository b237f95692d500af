"""The workbench tells missing physics from map error on a valve that differs from its CFD.

Each log comes from a virtual valve (:mod:`surrogate.synthetic.mismatch`): the shipped CFD
samples perturbed per opening (Δp 1.5 %, flow force 2.5 %, one draw per opening and case), its
own curve across the unsampled gap and below the smallest opening, and a cavitation-driven
back-pressure dependence of the flow force, plus one hidden effect (or none) and the shipped
bench's sensor noise. The model under test runs on the shipped grid maps, or on GP maps (the
workflow's default), then meeting a virtual valve built around them, and never sees the virtual
valve. The workflow must add the hidden effect (or one the data cannot tell from it) and no
other physics or sensor effect; corrections of the maps are allowed and labelled as such.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from surrogate import load_valve
from surrogate.data import load_cfd_samples
from surrogate.diagnosis.diagnose import diagnose
from surrogate.diagnosis.result import Baseline, Candidate, Diagnosis, Label, Score
from surrogate.diagnosis.rule import BIC_THRESHOLD, INCLUSION_MIN
from surrogate.effects.shapes import FlowForceFactor, OpeningForce
from surrogate.fitting.logfit import fit_to_log
from surrogate.fluid import FluidState
from surrogate.core.paths import SHIPPED_CFD_SAMPLES
from surrogate.model import ValveModel
from surrogate.description.presets import cfda, maps
from surrogate.reporting.prose import finding_document, sensor_check_text, summarise
from surrogate.synthetic.mismatch import (CavitationFlowForce, MapMismatch, PerturbedFlowMap,
                                          PerturbedForceMap, mismatched_samples)
from surrogate.synthetic.simulate import (hidden_effect_case, noise_free_sequence,
                                          run_stress_case, stress_suite, unexplained_additions)
from surrogate.testing import check_effect

EVERY = 8
#: the first settings seed of the stress suite (:func:`.simulate.stress_suite`): 20 randomised
#: cases and 5 nothing-hidden logs, on grid maps and on GP maps (`pytest -m stress`; a GP case
#: takes 20 s, so CI runs a slice; `python eval/workbench.py --only-mismatch [--mismatch-maps
#: gp]` runs both settings)
SETTINGS = (2026,)
CASES = 20
CONTROLS = 5
#: share of the randomised cases that must be clean (the issue's target): found cleanly, or
#: with nothing to find (:mod:`surrogate.synthetic.visibility`: nothing added or withheld, and
#: the log ends as its twin with nothing hidden does; case 209, a laminar leak of its realistic
#: size whose fit predicts the runs left out 0.2 % better). The version before the map-aware
#: diagnosis invented effects in every log, the control included.
CLEAN_SHARE = 0.9
#: at most this many effects added per case: a clean run adds one or two (the hidden effect
#: and perhaps a map correction); more would only cost time
ADDITIONS = 3
#: the hidden-effect cases of CI's slice (`pytest -m stress` runs the whole suite)
SLICE_CASES = 2


@pytest.fixture(scope="module")
def sequence(bench_log):
    return noise_free_sequence(bench_log, every=EVERY)


def run_case(case, sequence, kind="grid"):
    return run_stress_case(case, sequence, maps(kind), max_additions=ADDITIONS)


def test_the_virtual_valve_differs_from_its_cfd_like_a_real_one():
    """Per-opening errors of the set size, extra sweeps where the CFD has none, a fresh draw per
    seed and none with a zero mismatch."""
    samples, valve = load_cfd_samples(SHIPPED_CFD_SAMPLES), load_valve()
    perturbed, draw = mismatched_samples(samples, valve, seed=3)
    original = samples.frame
    same = perturbed.frame.iloc[:len(original)]
    dp_ratio = ((same["p_L"] - same["p_B"]) / (original["p_L"] - original["p_B"])).to_numpy()
    assert 0.002 < np.std(np.unique(np.round(dp_ratio, 9))) < 0.04
    assert len(perturbed) > len(original)
    new_openings = set(perturbed.frame["u"]) - set(original["u"])
    assert any(u < original["u"].min() for u in new_openings)
    assert any(0.2e-3 < u < 0.63e-3 for u in new_openings)
    assert mismatched_samples(samples, valve, seed=4)[1].dp_error != draw.dp_error
    still, _ = mismatched_samples(samples, valve, seed=3, mismatch=MapMismatch().scaled(0.0))
    assert np.allclose(still.frame["p_L"].iloc[:len(original)], original["p_L"])


def test_a_learned_map_under_test_meets_its_own_maps_wrapped_with_the_draws(bench_log):
    """For maps other than the reference's grid the virtual valve is those maps, wrong by the
    draws: Δp scaled at a given flow (and flow consistent with it), the flow force scaled, each
    sampled opening by its own draw."""
    case = hidden_effect_case(None, None, sequence=noise_free_sequence(bench_log, every=64),
                              seed=3, mismatch=MapMismatch(), maps_under_test=maps("gp"))
    flow, force = case.truth.flow_map, case.truth.force_map
    assert isinstance(flow, PerturbedFlowMap) and isinstance(force, PerturbedForceMap)
    samples = load_cfd_samples(SHIPPED_CFD_SAMPLES)
    _, draw = mismatched_samples(samples, load_valve(), seed=3)
    u = np.array(sorted(draw.dp_error))
    assert np.allclose(flow.factor(u), 1.0 + np.array([draw.dp_error[x] for x in u]))
    assert np.allclose(force.factor(u), 1.0 + np.array([draw.force_error[x] for x in u]))
    fluid = FluidState(np.full(3, 4.6e-5), np.full(3, 870.0))
    q, p_B, at = np.full(3, 10 / 6e4), np.full(3, 5e5), u[[2, 5, -1]]
    dp = flow.pressure_drop(q, p_B, at, fluid)
    assert np.allclose(dp, flow.base.pressure_drop(q, p_B, at, fluid) * flow.factor(at))
    assert np.allclose(flow.flow(p_B + dp, p_B, at, fluid), q, rtol=1e-4)
    p_L = p_B + dp
    assert np.allclose(force.force(p_L, p_B, at, fluid) - force.base.force(p_L, p_B, at, fluid),
                       (force.factor(at) - 1) * force.base.flow_force(p_L, p_B, at, fluid))


def test_the_cavitation_term_keeps_the_effect_contract():
    check_effect(CavitationFlowForce)


def test_a_shape_free_map_correction_is_not_counted_as_invented_physics():
    # a shape-free term is in no library: its category is the model's effect's own (a flow
    # force scaled by a factor of the opening patches the maps; a force of the opening is physics)
    model = cfda().build()
    shaped = ValveModel(model.valve, model.flow_map, model.force_map,
                        [*model.effects, FlowForceFactor(), OpeningForce()], "shaped")

    def step(name):
        return SimpleNamespace(diagnosis=SimpleNamespace(best=SimpleNamespace(group=[name])),
                               added=[name], model=shaped)

    paper = SimpleNamespace(diagnosis=None, added=[], model=model)
    workflow = SimpleNamespace(steps=[paper, step("shape_flow_force_of_opening"),
                                      step("shape_force_of_opening"), step("laminar_leakage")])
    assert unexplained_additions(workflow, "laminar_leakage") == ["shape_force_of_opening"]
    assert unexplained_additions(workflow, None) == ["shape_force_of_opening", "laminar_leakage"]


@pytest.mark.slow
def test_a_slice_of_the_stress_suite_is_found_cleanly(sequence):
    """CI's slice of the suite below: its first hidden-effect cases (a spring, a flow-force
    scale) and its first control, on grid maps."""
    suite = stress_suite(CASES, CONTROLS, settings=SETTINGS)
    cases = ([case for case in suite if case.hidden][:SLICE_CASES]
             + [case for case in suite if case.hidden is None][:1])
    outcomes = [run_case(case, sequence) for case in cases]
    assert all(outcome.clean for outcome in outcomes), [
        (outcome.case.hidden, outcome.added) for outcome in outcomes]


@pytest.mark.slow
@pytest.mark.stress
@pytest.mark.parametrize("kind", ["grid", "gp"])  # gp: the workflow's default maps
def test_nothing_hidden_adds_no_physics_or_sensor_effect(sequence, kind):
    invented = {}
    controls = [case for case in stress_suite(CASES, CONTROLS, settings=SETTINGS)
                if case.hidden is None]
    for case in controls:
        outcome = run_case(case, sequence, kind=kind)
        flagged = [sensor_check_text(check)
                   for check in outcome.workflow.final_diagnosis.sensor_checks]
        if outcome.invented or flagged:
            invented[case.seed] = outcome.invented + flagged
    assert not invented, invented


@pytest.mark.slow
@pytest.mark.stress
@pytest.mark.parametrize("kind", ["grid", "gp"])
def test_hidden_effects_are_found_cleanly_under_map_mismatch(sequence, kind):
    outcomes = []
    cases = [case for case in stress_suite(CASES, CONTROLS, settings=SETTINGS)
             if case.hidden is not None]
    for case in cases:
        outcome = run_case(case, sequence, kind=kind)
        outcomes.append((case.seed, case.hidden, outcome.added, outcome.clean))
    clean = sum(ok for *_, ok in outcomes)
    assert len(cases) >= 20
    assert clean >= CLEAN_SHARE * len(cases), [o for o in outcomes if not o[2]]


@pytest.mark.slow
def test_a_nothing_hidden_log_whose_maps_err_with_the_back_pressure_gains_nothing(sequence):
    """Stress seed 1104 (nothing hidden, GP maps): a progressive spring stood in for that
    virtual valve's map error (ΔBIC below the threshold, chosen in fewer than half the
    resamples over runs) until the maps' discrepancy could change with the back pressure; now
    it explains nothing the maps' error does not. Nothing is added or withheld."""
    case = hidden_effect_case(None, sequence=sequence, seed=1104, mismatch=MapMismatch(),
                              maps_under_test=maps("gp"))
    diagnosis = diagnose(fit_to_log(case.start, case.log).model, case.log)
    assert diagnosis.best is None and diagnosis.declined is None
    spring = next(c for c in diagnosis.candidates if c.name == "progressive_spring")
    assert spring.delta_bic > BIC_THRESHOLD


def _workflow(rms_over_floor, added=(), declined=()):
    """A stand-in for a finished workflow: a paper step, then one diagnosed step adding
    ``added``, ending at ``rms_over_floor`` times a noise floor of 1."""
    steps = [SimpleNamespace(added=(), diagnosis=None),
             SimpleNamespace(added=("calibrated_flow_force",), diagnosis=None),
             SimpleNamespace(added=tuple(added), diagnosis=SimpleNamespace(best=None),
                             model=SimpleNamespace(has_effect=lambda name: False))]
    return SimpleNamespace(steps=steps, declined=list(declined), noise_floor=1.0,
                           final=SimpleNamespace(rms=rms_over_floor))


def test_a_stress_case_is_clean_for_an_effect_it_cannot_show_only_as_its_twin():
    """A hidden effect that left nothing to find (nothing diagnosed, the log ends as its twin
    with nothing hidden does) is clean, as in the off-library suite; not when the log ends
    further from the floor than its twin, nor when a claim was named and withheld, nor with no
    twin run."""
    from surrogate.synthetic.simulate import StressCase, StressOutcome

    case = StressCase("laminar_leakage", 1.06, {}, 209)
    twin = _workflow(1.10)
    quiet = StressOutcome(case, _workflow(1.12), 1.0, twin)
    assert quiet.invisible and quiet.clean and not quiet.found
    assert not StressOutcome(case, _workflow(1.25), 1.0, _workflow(1.02)).invisible
    assert not StressOutcome(case, _workflow(1.40), 1.0, _workflow(1.35)).invisible  # floor
    withheld = _workflow(1.12, declined=[SimpleNamespace(claim=SimpleNamespace(name="x"))])
    assert not StressOutcome(case, withheld, 1.0, twin).clean
    added = StressOutcome(case, _workflow(1.05, added=("friction_constant",)), 1.0, twin)
    assert not added.invisible
    assert not StressOutcome(case, _workflow(1.12), 1.0).invisible  # no twin run
    nothing = StressCase(None, 0.0, None, 100)
    assert not StressOutcome(nothing, _workflow(1.12), 1.0, twin).invisible


def test_a_term_the_runs_do_not_agree_on_is_named_but_not_added():
    """A candidate that passes every test but the bootstrap over runs is named in the summary
    with the share of resamples that chose it, and not added."""
    top = Candidate(Label("progressive_spring", "progressive spring", "", "force", "physics"),
                    Score(1.0e5, -14.0, group=("progressive_spring",), heldout_rms=1.0e5,
                          heldout={"run": 1.0e5, "temperature": 1.0e5}, inclusion=0.42,
                          stable=False, own_view=True))
    baseline = Baseline(1.2e5, 0.8e5, 500.0, heldout_by_scheme={"run": 1.2e5,
                                                                "temperature": 1.2e5},
                        expected_rms=2.0e5)
    diagnosis = Diagnosis(None, None, baseline, (top,))
    assert diagnosis.best is None
    summary = summarise(diagnosis)
    assert "progressive_spring" in summary and "42 % of resamples over runs" in summary


@pytest.mark.slow
def test_a_weak_true_effect_is_judged_beside_the_maps_error_not_withheld_for_it(sequence):
    """Stress case 216 (grid maps): a pilot-pressure friction at 0.93 of its realistic size
    under the maps' error. Fitted in its place, the maps' error within its σ predicts the runs
    left out better than the friction does; fitted beside it, the friction adds what the maps'
    error cannot. The friction (or its look-alike) is the finding, and the look-alike rule names
    no rival."""
    case = next(c for c in stress_suite(CASES, CONTROLS, settings=SETTINGS) if c.seed == 216)
    made = hidden_effect_case(case.hidden, case.values, sequence=sequence, seed=case.seed,
                              mismatch=MapMismatch(), maps_under_test=maps("grid"))
    diagnosis = diagnose(fit_to_log(made.start, made.log).model, made.log)
    best = diagnosis.best
    assert best is not None and case.hidden in best.group, summarise(diagnosis)
    assert diagnosis.declined is None


@pytest.mark.slow
def test_a_findings_share_of_resamples_counts_each_resample_once(sequence):
    """Stress case 217 (grid maps): a pilot-pressure friction, found as its look-alike the
    pilot-differential friction, with a friction of free shape of p_P named beside them. The
    group's share of resamples over runs is at most all of them, and its members' shares come
    from one competition: the library's finding's share from the library alone beside the
    shape's from the library and the shapes summed to 102 %."""
    case = next(c for c in stress_suite(CASES, CONTROLS, settings=SETTINGS) if c.seed == 217)
    made = hidden_effect_case(case.hidden, case.values, sequence=sequence, seed=case.seed,
                              mismatch=MapMismatch(), maps_under_test=maps("grid"))
    diagnosis = diagnose(fit_to_log(made.start, made.log).model, made.log)
    best = diagnosis.best
    assert best is not None and case.hidden in best.group
    assert any(name.startswith("shape_") for name in best.group), best.group
    assert 0.5 <= diagnosis.group_inclusion(best) <= 1.0
    assert finding_document(diagnosis)["chosen_in"] <= 1.0
