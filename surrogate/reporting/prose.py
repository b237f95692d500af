"""The diagnosis in words: what the numbers of :mod:`surrogate.diagnosis` say, for people.

:func:`summarise` writes the summary the workflow, the command line and the report show;
:func:`diagnosis_document` is the diagnosis as JSON, numbers and words together.
"""

from __future__ import annotations

import re

import numpy as np

from ..diagnosis.lookalikes import MAPS_ERROR
from .display import in_bar
from .naming import WITHIN, library_matches, shape_features
from ..diagnosis.result import Candidate, Diagnosis, SensorCheck, rounded_bar
from ..fitting.heldout import HEADLINE
from ..fitting.leastsquares import split_key
from ..planning.bench_runs import Separation, search_range

# a residual within 1.3x the noise floor counts as noise in the summary: the floor estimate runs
# ~10 % low when friction holds the piston (input noise then reaches Δp in bursts, not white)
NOISE_LEVEL = 1.3
#: share of a candidate's gain (in sum of squares) that must lie in the view its physics acts on
#: before the summary stops warning: friction on the half-width, the rest on the median line
OWN_VIEW_SHARE = 0.25


def sensor_check_text(check: SensorCheck) -> str:
    """``run R03: the pilot-pressure transducer zero reads +0.40 bar off (± 0.05)``: the
    sensor of one run, so its title without the per-run qualifier."""
    sensor = check.title.removesuffix(", different in each run")
    return (f"run {check.run}: the {sensor} reads {check.value:+.2f} {check.unit} off "
            f"(± {check.stderr:.2f})")


def map_limit_texts(diagnosis: Diagnosis) -> list[str]:
    """Where the maps' error shows most, e.g. ``force map near 0.16 mm (1.34 bar RMS)``."""
    return [f"{limit.where} ({in_bar(limit.rms):.2f} bar RMS)"
            for limit in diagnosis.map_limits]


def diagnosis_document(diagnosis: Diagnosis) -> dict:
    """The diagnosis as plain JSON data: numbers in bar, NaN as null, with its summary."""
    return {"model": diagnosis.model.name,
            "rms_before_bar": rounded_bar(diagnosis.rms_before),
            "noise_floor_bar": rounded_bar(diagnosis.noise_floor),
            "effective_samples": round(diagnosis.effective_samples, 1),
            "heldout_rms_bar": rounded_bar(diagnosis.heldout_before),
            "heldout_rms_by_scheme_bar": {k: rounded_bar(v) for k, v
                                          in diagnosis.heldout_by_scheme.items()
                                          if k != "pooled"},
            "expected_rms_bar": rounded_bar(diagnosis.expected_rms),
            "median_line_rms_bar": rounded_bar(diagnosis.median_before),
            "half_width_rms_bar": rounded_bar(diagnosis.half_width_before),
            "map_limits": map_limit_texts(diagnosis),
            "sensor_checks": [{"effect": check.effect, "run": check.run,
                               "value": round(check.value, 4),
                               "stderr": round(check.stderr, 4), "unit": check.unit,
                               "text": sensor_check_text(check)}
                              for check in diagnosis.sensor_checks],
            "separating_run": (diagnosis.separation.to_json()
                               if diagnosis.separation is not None else None),
            "declined": (diagnosis.declined.to_json()
                         if diagnosis.declined is not None else None),
            "finding": finding_document(diagnosis),
            "absorbed": {name: {"parameter": key, "cosine": round(cosine, 4)}
                         for name, (key, cosine) in diagnosis.absorbed.items()},
            "summary": summarise(diagnosis),
            "candidates": [c.to_json() for c in diagnosis.candidates],
            "residual_correlations": {k: round(v, 3)
                                      for k, v in diagnosis.correlations.items()}}


def finding_document(diagnosis: Diagnosis) -> dict | None:
    """The finding as JSON: every explanation the log cannot tell apart, with its category and
    fitted parameters (display units), none preferred; None without a finding."""
    best = diagnosis.best
    if best is None:
        return None
    members = diagnosis.explanations
    return {"look_alikes": len(members) > 1,
            "chosen_in": round(diagnosis.group_inclusion(best), 3),
            "explanations": [{"name": c.name, "title": c.title, "category": c.category,
                              "shape_free": c.shape_free, "text": explanation(c),
                              "params": {p.name: p.to_record() for p in c.params if p.vary}}
                             for c in members]}


def hysteresis_share(diagnosis: Diagnosis, candidate: Candidate) -> float:
    """The share of ``candidate``'s gain, in the sum of squares of the two views, that lies in
    the half-width (NaN when it gains in neither)."""
    median = diagnosis.median_before**2 - candidate.median_rms**2
    half = diagnosis.half_width_before**2 - candidate.half_width_rms**2
    gain = max(median, 0.0) + max(half, 0.0)
    return max(half, 0.0) / gain if gain > 0 else float("nan")


def hysteresis_sentence(diagnosis: Diagnosis, candidate: Candidate) -> str:
    """Where the candidate's gain lies: the runs' median line or their half-width."""
    share = hysteresis_share(diagnosis, candidate)
    if not np.isfinite(share):
        return ""
    views = (f" Of its gain, {100 * share:.0f} % lies in the runs' hysteresis half-width "
             f"({in_bar(diagnosis.half_width_before):.2f} → "
             f"{in_bar(candidate.half_width_rms):.2f} bar RMS) and "
             f"{100 * (1 - share):.0f} % in their median line "
             f"({in_bar(diagnosis.median_before):.2f} → "
             f"{in_bar(candidate.median_rms):.2f} bar).")
    friction = candidate.kind == "friction"
    own_view_share = share if friction else 1.0 - share
    if own_view_share < OWN_VIEW_SHARE:
        views += (" Friction splits the ramps, so a friction term that gains mostly on the "
                  "median line, where the maps' error acts too, is provisional: refit it to the "
                  "hysteresis alone before trusting it." if friction else
                  " A term that moves both ramps alike but gains mostly on the half-width acts "
                  "like friction here: a friction candidate may be the better explanation.")
    return views


def separation_advice(separation: Separation | None) -> str:
    """What would decide between the best candidate and its look-alike."""
    if separation is None:
        return "pick by physical knowledge or a dedicated test."
    if separation.decides:
        return f"{separation} would tell them apart: their Δp differ there by {separation.gap()}."
    return (f"no bench run {search_range()} separates them by the noise floor (at best by "
            f"{separation.gap()}, {separation.where()}): pick by "
            "physical knowledge or a dedicated test (a transducer calibration, a spring measured "
            "on its own).")


def summarise(diagnosis: Diagnosis) -> str:
    """Plain sentences: the most likely missing effect (with its category, held-out gain and
    inclusion frequency), or why none is named, where the maps limit the diagnosis, and what
    the per-run readings say about the sensors."""
    before = in_bar(diagnosis.rms_before)
    floor = in_bar(diagnosis.noise_floor)
    expected = in_bar(diagnosis.expected_rms)
    best = diagnosis.best
    if best is None:
        unstable = next((c for c in diagnosis.candidates if not c.stable
                         and diagnosis.rule.passes(c, diagnosis.rms_before,
                                                   diagnosis.noise_floor,
                                                   diagnosis.heldout_by_scheme)), None)
        if diagnosis.declined is not None:
            sentence = (f"The residual ({before:.2f} bar RMS) is {before / floor:.1f}x the "
                        f"noise floor ({floor:.2f} bar).")
        elif diagnosis.rms_before <= NOISE_LEVEL * diagnosis.noise_floor:
            sentence = (f"Nothing beyond noise is left: the residual RMS ({before:.2f} bar) is "
                        f"within {NOISE_LEVEL:.1f}x the noise floor ({floor:.2f} bar) and no "
                        "candidate improves the model significantly.")
        elif np.isfinite(expected) and before <= expected:
            sentence = (f"The residual ({before:.2f} bar RMS) is within what the noise "
                        f"({floor:.2f} bar) and the maps' uncertainty allow together "
                        f"({expected:.2f} bar), and no candidate explains more than the maps' "
                        "own error could: nothing can be concluded beyond the maps.")
        else:
            sentence = (f"No candidate in the library explains the residual significantly on "
                        f"runs it was not fitted to, but it ({before:.2f} bar) is still "
                        f"{before / floor:.1f}x the noise floor ({floor:.2f} bar): the missing "
                        "physics may lie outside the library, or in the maps; a custom effect "
                        "(--effects-file) can test a hypothesis.")
        if diagnosis.declined is not None:
            sentence += declined_sentence(diagnosis)
        elif unstable is not None:
            share = diagnosis.group_inclusion(unstable)
            sentence += (f" {unstable.title[0].upper()}{unstable.title[1:]} ({unstable.name}) "
                         f"would explain part of this log (ΔBIC {unstable.delta_bic:.0f}), but "
                         f"it is chosen in only {100 * share:.0f} % of resamples "
                         "over runs: which runs the log holds decides it, so it is not a "
                         "finding; more runs where it acts would settle it.")
        else:
            sentence += maps_or_shape_sentence(diagnosis)
    elif best.shape_free:
        sentence = shape_sentence(diagnosis, best)
    elif len(best.group) > 1:
        sentence = look_alike_sentence(diagnosis, best)
    else:
        params = ", ".join(str(p) for p in best.params if p.vary)
        sentence = (f"The most likely missing effect is {best.title} ({best.name}, "
                    f"{best.category}): adding it lowers the residual RMS from {before:.2f} to "
                    f"{in_bar(best.rms_after):.2f} bar and the RMS on held-out runs from "
                    f"{in_bar(diagnosis.heldout_before):.2f} to "
                    f"{in_bar(best.heldout_rms):.2f} bar (noise floor {floor:.2f} bar, "
                    f"ΔBIC {best.delta_bic:.0f} against the maps' own error, chosen in "
                    f"{100 * best.inclusion:.0f} % of resamples over runs) with {params}.")
        sentence += hysteresis_sentence(diagnosis, best)
        if best.category == "map correction":
            sentence += (" It patches the CFD maps rather than adding valve physics: "
                         "more CFD where the bench operates would replace it.")
    sentence += absorbed_sentence(diagnosis)
    if diagnosis.map_limits:
        sentence += (" The maps' error shows most " + "; ".join(map_limit_texts(diagnosis))
                     + ": `suggest-cfd` lists the CFD runs that would settle it.")
    if diagnosis.sensor_checks:
        sentence += (" Sensor check (never part of the model): "
                     + "; ".join(map(sensor_check_text, diagnosis.sensor_checks[:3])) + ".")
    return sentence


def declined_sentence(diagnosis: Diagnosis) -> str:
    """A physics claim withheld (:class:`~surrogate.diagnosis.result.Declined`): what it would
    gain, the look-alikes of other kinds that predict unseen runs about as well, and what would
    tell them apart."""
    declined = diagnosis.declined
    claim = declined.claim

    def held(value: float) -> str:
        return f"{in_bar(value):.2f} bar"

    others = [rival for rival in declined.rivals if rival.name != MAPS_ERROR]
    maps = next((rival for rival in declined.rivals if rival.name == MAPS_ERROR), None)
    reasons = []
    if others:
        one = len(others) == 1
        reasons.append(f"{'a term' if one else 'terms'} of another kind fitted in its place "
                       f"predict{'s' if one else ''} the runs left out about as well ("
                       + "; ".join(f"{rival.title} ({rival.name}) {held(rival.heldout_rms)}"
                                   for rival in others)
                       + "), and the temperatures and pilot pressures left out too")
    if maps is not None:
        with_maps = declined.beside_maps.get(HEADLINE, claim.heldout_rms)
        reasons.append("the CFD maps' own error, within their uncertainty, explains as much "
                       f"({MAPS_ERROR}): fitted beside it, the claim predicts the runs left out "
                       f"at {held(with_maps)} against {held(maps.heldout_rms)} with the maps' "
                       "error alone, and the conditions left out no better")
    sentence = (f" The log does not say which physics is missing: {claim.title} "
                f"({claim.name}) would lower the RMS on held-out runs from "
                f"{held(diagnosis.heldout_before)} to {held(claim.heldout_rms)}, but "
                + "; and ".join(reasons)
                + f". A claim must do {100 * diagnosis.rule.other_kind_gain:.0f} % better than "
                  "each, on the runs or on a condition left out; nothing is added.")
    separation = declined.separation
    if separation is not None:
        run = str(separation)
        sentence += (f" {run[0].upper()}{run[1:]} would tell {claim.name} from "
                     f"{separation.between[1]}: "
                     f"their Δp differ there by {separation.gap()}."
                     if separation.decides else
                     f" No bench run {search_range()} tells {claim.name} from "
                     f"{separation.between[1]} by the noise floor (at best by "
                     f"{separation.gap()}, {separation.where()}).")
    if any(rival.name == MAPS_ERROR or rival.category == "map correction"
           for rival in declined.rivals):
        sentence += (" CFD runs where the maps are least sure (`suggest-cfd`) would tell the "
                     "maps' error from it.")
    return sentence


def withheld_advice(declined) -> str:
    """What to do about a claim withheld for its look-alikes of other kinds: the run that tells
    them apart, then how to test the claim by hand."""
    claim, rivals = declined.claim, declined.rivals
    names = ", ".join("the CFD maps' own error" if rival.name == MAPS_ERROR else rival.name
                      for rival in rivals)
    advice = (f"The log fits {claim.name} and {names} about equally well on runs they were not "
              "fitted to, so none was added. ")
    separation = declined.separation
    if separation is not None and separation.decides:
        advice += (f"Measure {separation}: the two differ there by {separation.gap()}. ")
    if any(rival.name == MAPS_ERROR for rival in rivals):
        advice += ("The CFD runs suggest-cfd ranks would shrink the maps' error that stands "
                   "in for it. ")
    where = ("a log with that run" if separation is not None and separation.decides
             else "a new log")
    if claim.shape_free:
        return advice + ("To test the shape by hand, diagnose --out DIR writes it as an effects "
                         f"file; fit it with --effects-file FILE --add NAME on {where}.")
    return advice + f"To test {claim.name} by hand, fit it with fit --add {claim.name} on {where}."


def absorbed_sentence(diagnosis: Diagnosis) -> str:
    """Which candidates the model's own parameters already mimic on this log, by parameter."""
    by_parameter: dict[str, list[str]] = {}
    for name, (key, _) in diagnosis.absorbed.items():
        by_parameter.setdefault(key, []).append(name)
    if not by_parameter:
        return ""
    parameters = diagnosis.model.parameters()
    titles = {c.name: c.title for c in diagnosis.candidates}
    words = []
    for key, names in by_parameter.items():
        parameter = parameters[key]
        alike = max(abs(diagnosis.absorbed[name][1]) for name in names)
        effect_name, parameter_name = split_key(key)
        effect = diagnosis.model.effect(effect_name)
        title = re.sub(r"^(a|an|the) ", "", effect.title)
        said = " and ".join(titles.get(name, name) for name in names)
        # in words first, the names and the value last
        words.append(f" On this log {said} would change the pressure drop almost as the "
                     f"model's {title} does ({100 * alike:.0f} % alike): its value may already "
                     f"carry part of {'them' if len(names) > 1 else 'it'}, and the log cannot "
                     "tell how much; runs that move what sets them apart would ("
                     + ", ".join(names) + f" against {parameter_name} = "
                     f"{parameter.display_value:.3g} {parameter.unit}).")
    return "".join(words)


def explanation(candidate: Candidate) -> str:
    """One explanation of a finding: what it is, its category and its fitted size (a shape's
    effective number of parameters)."""
    if candidate.shape_free:
        return (f"{candidate.title} ({candidate.name}, {candidate.category}, "
                f"{candidate.extra:.1f} effective parameters)")
    params = ", ".join(str(p) for p in candidate.params if p.vary)
    return f"{candidate.title} ({candidate.name}, {candidate.category}: {params})"


def look_alike_sentence(diagnosis: Diagnosis, best: Candidate) -> str:
    """A finding the log cannot attribute: every explanation with its category and size, none
    preferred, and what would decide."""
    members = diagnosis.explanations
    categories = sorted({c.category for c in members})
    why = (f"they fit it about equally well (ΔBIC within {-diagnosis.rule.bic:.0f} of each "
           "other, a term of free shape counted with its handicap)"
           if any(c.shape_free for c in members) else
           "they are the same term of the force balance (their effects are collinear)")
    sentence = (f"The log holds one finding with {len(members)} explanations it cannot tell "
                f"apart: " + ", or ".join(map(explanation, members)) + f". On this log {why}, "
                "so neither is preferred: either lowers the residual RMS from "
                f"{in_bar(diagnosis.rms_before):.2f} to about "
                f"{in_bar(best.rms_after):.2f} bar and the RMS on held-out runs from "
                f"{in_bar(diagnosis.heldout_before):.2f} to about "
                f"{in_bar(best.heldout_rms):.2f} bar (noise floor "
                f"{in_bar(diagnosis.noise_floor):.2f} bar, ΔBIC {best.delta_bic:.0f}, "
                f"one of them chosen in {100 * diagnosis.group_inclusion(best):.0f} % of "
                "resamples over runs).")
    advice = separation_advice(diagnosis.separation)
    if len(categories) > 1:
        sentence += (f" The explanations differ in kind ({' and '.join(categories)}): "
                     f"check the cheaper one before changing the model; {advice}")
    else:
        sentence += f" {advice[0].upper()}{advice[1:]}"
    return sentence + hysteresis_sentence(diagnosis, best)


def maps_or_shape_sentence(diagnosis: Diagnosis) -> str:
    """When a shape-free term would predict held-out runs better but the maps' own error could
    do as much: the log cannot tell that shape from the maps' error (empty otherwise)."""
    shape = next((c for c in diagnosis.candidates if c.shape_free and not c.per_run
                  and diagnosis.rule.predicts_unseen(c, diagnosis.heldout_by_scheme)
                  and diagnosis.rms_before - c.rms_after > diagnosis.rule.gain_fraction
                  * diagnosis.noise_floor), None)
    if shape is None:
        return ""
    return (f" A term of free shape, {shape.title} ({shape.name}), would lower the RMS to "
            f"{in_bar(shape.rms_after):.2f} bar and the held-out RMS to "
            f"{in_bar(shape.heldout_rms):.2f} bar, but the maps' own error could do "
            f"nearly as much there (ΔBIC {shape.delta_bic:.1f} against it): this log cannot "
            f"tell a {shape.effect.quantity} of {shape.curve.label} from the maps' error. "
            "Runs at other pilot pressures and temperatures at the same operating points, or "
            "CFD runs where the maps are least sure (`suggest-cfd`), would.")


def shape_sentence(diagnosis: Diagnosis, best: Candidate) -> str:
    """What a shape-free find says: what it is, what it gains, its shape, whether a library
    term has that shape, and how to take it over (its effects file)."""
    curve = best.curve
    effect = best.effect
    before = in_bar(diagnosis.rms_before)
    sentence = (f"The log holds a {effect.quantity} that depends on {curve.label} with a shape of "
                f"its own ({best.name}, {best.category}): a term of free shape lowers the "
                f"residual RMS from {before:.2f} to {in_bar(best.rms_after):.2f} bar and "
                f"the RMS on held-out runs from {in_bar(diagnosis.heldout_before):.2f} to "
                f"{in_bar(best.heldout_rms):.2f} bar (noise floor "
                f"{in_bar(diagnosis.noise_floor):.2f} bar, ΔBIC {best.delta_bic:.0f} "
                f"against the maps' own error with {best.extra:.1f} effective parameters, chosen "
                f"in {100 * best.inclusion:.0f} % of resamples over runs). ")
    sentence += shape_words(best) + " " + naming_words(best)
    sentence += (" `diagnose --out DIR` writes it as an effects file to read, edit and add with "
                 "--effects-file.")
    return sentence + hysteresis_sentence(diagnosis, best)


def shape_words(candidate: Candidate) -> str:
    """The found shape in a sentence: its range, and where it bends, rises or falls."""
    curve = candidate.curve
    features = shape_features(curve)
    unit, x_unit = curve.value_unit, curve.unit
    words = (f"Its {candidate.effect.quantity} runs from {features.low:+.3g} {unit} (at "
             f"{features.low_at:.3g} {x_unit}) to {features.high:+.3g} {unit} (at "
             f"{features.high_at:.3g} {x_unit})")
    steepest = f", most steeply near {features.steepest_at:.3g} {x_unit}."
    if features.rising:
        return words + ", rising with it" + steepest
    if features.falling:
        return words + ", falling with it" + steepest
    kind = "bump" if features.bend > 0 else "dip"
    return (words + f", with a {kind} of {abs(features.bend):.3g} {unit} at "
                    f"{features.bend_at:.3g} {x_unit} against the line between its ends.")


def naming_words(candidate: Candidate) -> str:
    """Whether a library term has the found shape, and if not, what tells them apart."""
    matches = library_matches(candidate.name, candidate.curve)
    if not matches:
        return "No library term acts on this variable in this way."
    closest = matches[0]
    if closest.fits:
        return (f"The library's {closest.name} fits this shape within {WITHIN:g} standard "
                "deviations of it: prefer that term, which says the same with a name.")
    return (f"No library term has this shape: the closest, {closest.name}, departs from it by "
            f"{closest.worst:.1f} standard deviations at {closest.worst_at:.3g} "
            f"{candidate.curve.unit}.")


def workflow_summary(workflow) -> str:
    """The final diagnosis' :func:`summarise`: what is left of the final model (the workflow's
    last step, which its final diagnosis diagnosed), said of its RMS and noise floor."""
    return summarise(workflow.final_diagnosis)


def next_steps(workflow) -> list[str]:
    """What to do next, from what the workflow found (a :class:`~surrogate.workbench.workflow.
    Workflow`): each line follows from one of its findings, so that the advice never points
    where the tools found nothing to gain."""
    final, diagnosis = workflow.final, workflow.final_diagnosis
    steps = []
    if diagnosis.best is not None:
        steps.append(f"The final diagnosis still finds {diagnosis.best.title} "
                     f"({diagnosis.best.name}): the loop stopped before adding it (it adds "
                     "--max-additions terms at most, and stops at a term of another kind "
                     "after refusing one on held-out runs); run the workflow again with a larger "
                     "--max-additions, or fit it with fit --model final_model.toml --add "
                     f"{diagnosis.best.name}.")
    if workflow.dropped:
        steps.append(f"{workflow.dropped}: the log does not confirm it on runs it was not "
                     "fitted to. Runs at other temperatures or pilot pressures would.")
    if diagnosis.declined is not None:
        steps.append(withheld_advice(diagnosis.declined))
    elif workflow.loop_end is not None and workflow.loop_end.declined is not None:
        steps.append("Before the maps' calibration the loop withheld a claim: "
                     + withheld_advice(workflow.loop_end.declined))
    for number, step in enumerate(workflow.steps, start=1):
        best = None if step.diagnosis is None else step.diagnosis.best
        if step.diagnosis is not None and best is not None and len(best.group) > 1:
            steps.append(f"Step {number} added {best.name}, one of "
                         f"{len(best.group)} explanations this log cannot tell apart "
                         f"({', '.join(best.group)}): "
                         + separation_advice(step.diagnosis.separation))
        if step.shape_free:
            steps.append(f"Step {number} added a term of free shape ({best.name}): its effects "
                         f"file (found_*.py, in the output folder) holds the shape as a table. "
                         "Read it, replace the table by a formula you believe, and fit again "
                         "with --effects-file FILE --add NAME: the error says whether the "
                         "formula holds.")
        for moved in step.pushed:
            steps.append(f"Step {number} drove {moved.parameter} to its bound: "
                         f"{', '.join(moved.by)} took over what it carried. Check whether "
                         "that is physics or a stand-in before trusting either value.")
    for pair in final.entangled:
        steps.append(f"The log fixes {pair.first} and {pair.second} only together (correlation "
                     f"{pair.correlation:+.2f}): runs that move what sets them apart (another "
                     "pilot pressure at the same load pressure, another temperature) would "
                     "separate them.")
    if diagnosis.map_limits:
        steps.append("What is left is within the maps' own error; it shows most at "
                     + "; ".join(map_limit_texts(diagnosis))
                     + ". suggest-cfd ranks CFD runs by how much of the maps' uncertainty over "
                       "this log each would remove; where that uncertainty is mostly the maps' "
                       "calibrated floor (the learned maps), no single new run removes much, "
                       "and the CFD's own accuracy (its mesh) is what would.")
    if not steps:
        steps.append("Nothing is left to add: the model explains the log to its noise.")
    steps.append("To trust the model beyond this log, compare it with a run at a temperature "
                 "or pilot pressure the log lacks (compare --model final_model.toml --data "
                 "NEW_LOG).")
    return steps
