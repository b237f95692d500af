"""A workflow as a JSON document: its numbers, and the words that explain them.

The workflow (:mod:`surrogate.workbench.workflow`) keeps numbers; here each step gets its reason
in words (a diagnosed step's is its diagnosis' summary, :func:`.prose.summarise`) and the
workflow its verdict (:mod:`.verdict`).
"""

from __future__ import annotations

from ..workbench.workflow import Step, Workflow
from .display import in_bar
from .prose import summarise
from .verdict import summary_text, verdict


def step_reason(step: Step) -> str:
    """Why the step was taken: the diagnosis' summary for a step a diagnosis chose, else what
    the step is."""
    return step.reason if step.diagnosis is None else summarise(step.diagnosis)


def step_document(step: Step) -> dict:
    """One step of the staircase: its model, what it added, its RMS [bar] and held-out RMS, the
    parameters it fitted, and why it was taken."""
    parameters = step.model.parameters().to_records(free_only=True)
    return {"model": step.model.name, "added": step.added, "category": step.category,
            "shape_free": step.shape_free,
            "rms_bar": _bar(step.rms),
            "heldout_rms_bar": _bar(step.heldout_rms),
            "heldout_check_bar": _bar(step.heldout_check),
            "entangled": [pair.to_json() for pair in step.entangled],
            "pushed_to_bounds": [pushed.to_json() for pushed in step.pushed],
            "reason": step_reason(step), "parameters": parameters}


def workflow_document(workflow: Workflow) -> dict:
    """The workflow: its data, noise floor [bar], verdict and summary, and every step
    (:func:`step_document`)."""
    return {"data": workflow.log.source, "samples": len(workflow.log), "maps": workflow.maps,
            "noise_floor_bar": _bar(workflow.noise_floor),
            "final_rms_over_noise": round(workflow.final.rms / workflow.noise_floor, 3),
            "verdict": verdict(workflow).to_json(), "summary": summary_text(workflow),
            "dropped_step": workflow.dropped or None,
            "steps": [step_document(step) for step in workflow.steps],
            "seconds": round(workflow.seconds, 1)}


def _bar(value: float) -> float:
    """[Pa] -> bar, to 4 decimals."""
    return round(float(in_bar(value)), 4)
