"""The workflow's verdict: three lines that open its report and its summary.

1. **Lacks**: what the final model still misses, with its size in bar, or that nothing more is
   found, and what the loop added on the way (each effect's fall of the residual RMS);
2. **Where**: what the missing term changes with and which view of the hysteresis it acts on,
   or where what is left lies (the maps' least sure regions, else the worst run);
3. **Next**: the one run that would settle most: a bench run that tells look-alikes apart, a fit
   of the finding, CFD runs where the maps are least sure, or a run the log lacks.

Every number comes from the workflow (:class:`~surrogate.workbench.workflow.Workflow`): its
final diagnosis (the final model's), its steps and its noise floor. Effects are named in the
words of their titles and physical family (:func:`~surrogate.reporting.naming.family`); an
effect's name appears only where a command needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..diagnosis.lookalikes import MAPS_ERROR
from .display import in_bar
from .naming import family, shape_features
from .prose import NOISE_LEVEL, hysteresis_share, workflow_summary

#: what each category of effect is, in the verdict's words
CATEGORY_WORDS = {"physics": "valve physics", "map correction": "a correction of the CFD maps",
                  "sensor": "a sensor error"}


@dataclass(frozen=True)
class Verdict:
    """The three lines (plain text; commands in backticks)."""

    lacks: str
    where: str
    next: str

    def lines(self) -> tuple[str, str, str]:
        return (f"Lacks: {self.lacks}", f"Where: {self.where}", f"Next: {self.next}")

    def text(self) -> str:
        return "\n".join(self.lines())

    def to_json(self) -> dict:
        return {"lacks": self.lacks, "where": self.where, "next": self.next}


def _bar(value: float) -> str:
    """[Pa] as "0.85 bar"."""
    return f"{in_bar(value):.2f} bar"


def explained(before: float, after: float) -> float:
    """The RMS of the part of Δp a term explains [Pa]: what the residual's mean square loses
    when it is added, from ``before`` to ``after`` RMS [Pa]."""
    return float(np.sqrt(max(before**2 - after**2, 0.0)))


def what(item) -> str:
    """An effect, a candidate or a rival in an engineer's words: its title, a term of free shape
    said as such."""
    return item.title.replace(", of free shape", ", in a shape the data drew")


def category_words(category: str) -> str:
    """A category ("physics or sensor" for look-alikes of two) in the verdict's words."""
    return " or ".join(CATEGORY_WORDS.get(part, part) for part in category.split(" or "))


def added_words(workflow) -> str:
    """What the loop added after its start (the paper's CFDA, or the given model), each with its
    category and the fall of the residual RMS it brought ("" when it added nothing)."""
    steps = workflow.steps
    first = 3 if workflow.maps and len(steps) > 3 else 0  # CFDA, the paper's last step
    start = "the paper's CFDA" if first else "the starting model"
    parts = []
    for before, step in zip(steps[first:], steps[first + 1:]):
        if step.diagnosis is not None:
            effects = [step.model.effect(name) for name in step.added]
            words = " and ".join(map(what, effects))
        else:  # a step that followed the loop: the maps calibrated to the bench
            words = "the CFD maps calibrated within their uncertainty"
        parts.append(f"{words}: {category_words(step.category)}, "
                     f"{in_bar(before.rms):.2f} → {in_bar(step.rms):.2f} bar")
    if not parts:
        return ""
    return (f"Beyond {start} ({_bar(steps[first].rms)} RMS) the loop added "
            + "; ".join(parts) + ".")


def _finding(diagnosis) -> str:
    """The final diagnosis' finding: what it is, its size, what adding it would gain, and its
    look-alikes."""
    best = diagnosis.best
    others = [c for c in diagnosis.explanations if c is not best]
    text = (f"{what(best)} ({category_words(best.category)}), about "
            f"{_bar(explained(diagnosis.rms_before, best.rms_after))} RMS of Δp: adding it "
            f"lowers the residual from {_bar(diagnosis.rms_before)} to {_bar(best.rms_after)} "
            f"RMS (noise floor {_bar(diagnosis.noise_floor)}).")
    if others:
        text += (" This log cannot tell it from " + ", or ".join(
            f"{what(c)} ({category_words(c.category)})" for c in others) + ".")
    return text


def _withheld(diagnosis) -> str:
    """A physics claim the final diagnosis withheld for its look-alikes of other kinds."""
    declined = diagnosis.declined
    claim = declined.claim
    rivals = ", ".join("the CFD maps' own error" if rival.name == MAPS_ERROR else what(rival)
                       for rival in declined.rivals)
    return (f"perhaps {what(claim)}, about "
            f"{_bar(explained(diagnosis.rms_before, claim.rms_after))} RMS of Δp, but {rivals} "
            "predict the runs left out about as well, so nothing was added; the model leaves "
            f"{_bar(diagnosis.rms_before)} RMS, {diagnosis.rms_before / diagnosis.noise_floor:.2f}"
            f"× the noise floor of {_bar(diagnosis.noise_floor)}.")


def _nothing(diagnosis) -> str:
    """Nothing found: what is left, against the noise and the maps' uncertainty."""
    rms, floor, expected = diagnosis.rms_before, diagnosis.noise_floor, diagnosis.expected_rms
    left = (f"the final model leaves {_bar(rms)} RMS, {rms / floor:.2f}× the noise floor of "
            f"{_bar(floor)}")
    if rms <= NOISE_LEVEL * floor:
        return f"nothing more that this log can show: {left}."
    if np.isfinite(expected) and rms <= expected:
        return (f"nothing beyond the CFD maps' own error: {left}, within the {_bar(expected)} "
                "that noise and the maps' uncertainty allow together.")
    return (f"nothing the library or a term of free shape names, yet {left}: the missing "
            "physics may lie outside the library, or in the maps.")


def lacks(workflow) -> str:
    """Line 1: what the final model lacks and how large, then what the loop added."""
    diagnosis = workflow.final_diagnosis
    if diagnosis.best is not None:
        text = _finding(diagnosis)
    elif diagnosis.declined is not None:
        text = _withheld(diagnosis)
    else:
        text = _nothing(diagnosis)
    added = added_words(workflow)
    return f"{text} {added}" if added else text


def acts(diagnosis, candidate) -> str:
    """What a candidate changes with, where a shape changes most, and which view of the
    hysteresis holds its gain."""
    text = f"it acts as {family(candidate).words}"
    if candidate.curve is not None:
        features = shape_features(candidate.curve)
        text += f", most steeply near {features.steepest_at:.3g} {candidate.curve.unit}"
    share = hysteresis_share(diagnosis, candidate)
    if np.isfinite(share):
        text += (f"; {100 * share:.0f} % of its gain lies in the split between the up and down "
                 f"ramps (the hysteresis), {100 * (1 - share):.0f} % in both ramps alike")
    return text + "."


def worst_run(log_replay) -> tuple[str, float]:
    """The run of largest residual RMS in a replay, and that RMS [Pa]."""
    residual = pd.Series(np.asarray(log_replay.residual, float))
    rms = np.sqrt((residual**2).groupby(np.asarray(log_replay.runs)).mean().dropna())
    return str(rms.idxmax()), float(rms.max())


def where(workflow) -> str:
    """Line 2: where the finding acts, or where what is left lies."""
    diagnosis = workflow.final_diagnosis
    claim = diagnosis.best or (diagnosis.declined.claim if diagnosis.declined else None)
    if claim is not None:
        return acts(diagnosis, claim)
    if diagnosis.map_limits:
        return ("what is left lies where the CFD maps are least sure: "
                + "; ".join(f"the {limit.where} ({_bar(limit.rms)} RMS)"
                            for limit in diagnosis.map_limits) + ".")
    run, rms = worst_run(diagnosis.base)
    return (f"what is left is spread over the log; it is largest on run {run} ({_bar(rms)} "
            "RMS).")


def _separating(separation, titles: dict[str, str]) -> str:
    """A bench run that tells two look-alikes apart, in words."""
    first, second = (titles.get(name, name) for name in separation.between)
    return (f"{separation}: it tells {first} from {second} (their Δp differ there by "
            f"{separation.gap()}).")


def next_run(workflow) -> str:
    """Line 3: the run that would settle most, from what the workflow found."""
    diagnosis = workflow.final_diagnosis
    titles = {c.name: what(c) for c in diagnosis.candidates}
    best, declined = diagnosis.best, diagnosis.declined
    for separation in (diagnosis.separation if best is not None else None,
                       declined.separation if declined is not None else None):
        if separation is not None and separation.decides:
            return _separating(separation, titles)
    if best is not None:
        return (f"fit {what(best)} to the log: `fit --model final_model.toml --data LOG --add "
                f"{best.name}`.")
    for step in workflow.steps:  # a step that added one of look-alikes a run would tell apart
        found = step.diagnosis
        if found is not None and found.best is not None and len(found.best.group) > 1 \
                and found.separation is not None and found.separation.decides:
            return _separating(found.separation, {c.name: what(c) for c in found.candidates})
    if diagnosis.map_limits:
        return (f"CFD runs where the maps are least sure, first for the "
                f"{diagnosis.map_limits[0].where}: `suggest-cfd --data LOG` ranks them.")
    return ("a bench run at a temperature or pilot pressure the log lacks, compared with the "
            "final model (`compare --model final_model.toml --data NEW_LOG`): the model's test "
            "beyond this log.")


def verdict(workflow) -> Verdict:
    """The workflow's three-line verdict (see the module docstring)."""
    return Verdict(lacks(workflow), where(workflow), next_run(workflow))


def summary_text(workflow) -> str:
    """The workflow's summary: the verdict's three lines, then the final diagnosis in words
    (:func:`.prose.workflow_summary`: the look-alikes, the maps' limits, the sensors)."""
    return f"{verdict(workflow).text()}\n{workflow_summary(workflow)}"


__all__ = ["Verdict", "summary_text", "verdict"]
