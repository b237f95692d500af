"""One valve of a fleet: its log read, the model fitted, judged on held-out runs and (optionally)
diagnosed; the result as plain JSON data in display units, as ``fit`` and ``diagnose`` report.

This runs on a worker (a process of the local pool or of a Dask cluster): it reads the valve's
own log and builds the model from the task's text, so that nothing but the small task and its
small result ever travels.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..data import load_bench_log
from ..effects import KNOWN, EffectLibrary, load_effects_file
from ..fitting.heldout import run_groups
from ..fitting.logfit import fit_to_log
from ..fitting.residuals import noise_floor, replay_log
from ..model import ValveModel
from ..description.spec import ModelSpec
from ..core.units import from_si
from ..workbench.workflow import heldout_rms
from .tasks import ValveTask

#: digits kept of a result in bar (the workbench prints 3; a tenth of a millibar is far below any
#: noise floor)
BAR_DIGITS = 5


def valve_result(task: ValveTask, progress=None) -> dict:
    """Fit ``task``'s model to its valve's log; the result as JSON data (see docs/fleet.md).

    Holds: the fitted free parameters (display units, with standard errors, and whether a fit
    left one on a bound), the RMS, the held-out RMS (each run predicted by a refit to the
    others, :func:`~surrogate.workbench.workflow.heldout_rms`), the noise floor, the log's size
    and typical conditions, and with ``task.diagnose`` the diagnosis' top candidate and finding.

    Raises
    ------
    InputError
        For a log the loaders refuse (naming the file, line and column), or a model that cannot
        be fitted to it: the caller records it as the valve's failure.
    """
    progress = progress or (lambda message: None)
    log = load_bench_log(task.log)
    model = _model(task.model_toml, task.model_label, task.effects_files,
                   task.model_sha256).copy()
    fitted = None
    if model.parameters().free():
        fitted = fit_to_log(model, log)
        model = fitted.model
    log_replay = replay_log(model, log).require_solved(model.name)
    floor = noise_floor(log_replay.residual, log_replay.runs, source=log.source)
    # a log of one run has no other run to predict it from
    heldout = (heldout_rms(fitted, log_replay, run_groups(log)) if len(log.run_ids) > 1
               else float("nan"))
    result = {"model": model.name, "samples": len(log), "runs": len(log.run_ids),
              "converged": None if fitted is None else bool(fitted.success),
              "evaluations": 0 if fitted is None else int(fitted.evaluations),
              "rms_bar": _bar(log_replay.rms()), "heldout_rms_bar": _bar(heldout),
              "noise_floor_bar": _bar(floor), "conditions": conditions(log),
              "parameters": parameter_records(model)}
    if task.diagnose:
        progress(f"{task.serial}: diagnosing")
        result["diagnosis"] = diagnosis_record(model, log, log_replay,
                                               _library(task.effects_files, task.model_sha256))
    return result


def parameter_records(model: ValveModel) -> dict[str, dict]:
    """Every free parameter, keyed ``"effect.parameter"``: value and standard error in its
    display unit, the unit, whether it sits on a bound, and the run of a per-run parameter."""
    records = {}
    for key, parameter in model.parameters().items():
        if not parameter.vary:
            continue
        stderr = parameter.display_stderr
        records[key] = {"value": parameter.display_value, "unit": parameter.unit,
                        "stderr": None if stderr is None or not np.isfinite(stderr) else stderr,
                        "at_bound": bool(parameter.at_bound)}
        if parameter.scope is not None:
            records[key]["run"] = parameter.scope
    return records


def conditions(log) -> dict[str, float]:
    """The log's typical conditions (medians over its samples, the largest flow), for drawing a
    valve's steady Δp(q) where its bench tested it."""
    frame = log.frame
    return {"p_Pe_bar": _bar(float(np.median(frame["p_P"] - frame["p_B"]))),
            "p_B_bar": _bar(float(np.median(frame["p_B"]))),
            "temperature_C": round(float(from_si(np.median(frame["temperature"]), "degC")), 3),
            "q_max_lpm": round(float(from_si(frame["q"].max(), "L/min")), 4)}


def diagnosis_record(model: ValveModel, log, log_replay, library: EffectLibrary) -> dict:
    """The diagnosis of the fitted ``model`` on ``log`` in brief: its top-ranked candidate
    (name, category, ΔBIC, whether significant, one line on it) and its finding, if any."""
    from ..diagnosis.diagnose import diagnose
    from ..reporting.prose import explanation, summarise

    diagnosis = diagnose(model, log, library, base=log_replay)
    top = diagnosis.candidates[0] if diagnosis.candidates else None
    best = diagnosis.best
    return {
        "top_candidate": None if top is None else {
            "name": top.name, "category": top.category, "kind": top.kind,
            "delta_bic": round(float(top.delta_bic), 2) if np.isfinite(top.delta_bic) else None,
            "significant": bool(top.significant), "summary": explanation(top)},
        "finding": None if best is None else {
            "name": best.name, "category": best.category, "kind": best.kind,
            "explanations": [c.name for c in diagnosis.explanations]},
        "summary": summarise(diagnosis)}


@lru_cache(maxsize=4)
def _library(effects_files: tuple[str, ...], model_sha256: str) -> EffectLibrary:
    """The built-in effects and the files', loaded once per worker process for a model
    (``model_sha256`` covers the files' content: a file changed between two fleets on one
    cluster is loaded again)."""
    library = KNOWN
    for path in effects_files:
        library = library + load_effects_file(path)
    return library


@lru_cache(maxsize=4)
def _model(model_toml: str, label: str, effects_files: tuple[str, ...],
           model_sha256: str) -> ValveModel:
    """The model a task names, built once per worker process (maps take a while to build; a
    worker fits many valves); callers fit a copy."""
    spec = ModelSpec.from_toml(model_toml, label)
    return spec.build(_library(effects_files, model_sha256), label)


def _bar(value: float) -> float | None:
    """Pa as bar, rounded; None for NaN (JSON has no NaN)."""
    return round(float(from_si(value, "bar")), BAR_DIGITS) if np.isfinite(value) else None
