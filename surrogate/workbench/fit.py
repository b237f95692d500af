"""Fitting a model's free parameters to every sample of a bench log."""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from ..data.loaders import BenchLog
from ..fitting import FitResult, fit
from ..model import ValveModel
from .residuals import LogReplay, effective_samples, replay_log


def fit_to_log(model: ValveModel, log: BenchLog, names: Sequence[str] | None = None, *,
               start: LogReplay | None = None, max_evaluations: int = 60,
               tolerance: float = 1e-5) -> FitResult:
    """Least-squares fit of the free parameters (or ``names``) by replaying the whole log.

    Each evaluation starts the solver from the previous one (warm start), which halves the cost
    of a replay; extrapolation flags are skipped inside the fit. The default ``tolerance`` stops
    once the sum of squares falls by less than 10⁻⁵ of itself per step: the RMS is then settled to
    a few parts per million, far below anything the workbench compares. Standard errors are
    widened for the residuals' correlation in time (:func:`.residuals.effective_samples`).
    """
    last = {"replay": start}
    caller = threading.get_ident()

    def residuals(candidate: ValveModel):
        played = replay_log(candidate, log, guess=last["replay"], extrapolation=False)
        # only the fit's own steps move the warm start: the Jacobian's columns, on other threads,
        # start from the point they differentiate at, so the result does not depend on timing
        if threading.get_ident() == caller:
            last["replay"] = played
        return played.residual

    result = fit(model, residuals, names, max_evaluations=max_evaluations, tolerance=tolerance)
    # fit() evaluates the optimum last; its standard errors count every sample as independent,
    # but bench residuals are correlated in time: widen them by sqrt(n / n_eff)
    final = last["replay"]
    if final is not None:
        inflation = np.sqrt(final.ok.sum() / effective_samples(final.residual, final.runs))
        for parameter in result.parameters:
            if parameter.stderr is not None:
                parameter.stderr *= float(inflation)
    return result
