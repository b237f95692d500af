"""Fitting a model's free parameters to every sample of a bench log."""

from __future__ import annotations

from collections.abc import Sequence

from ..data.loaders import BenchLog
from ..fitting import FitResult, fit
from ..model import ValveModel
from .residuals import LogReplay, replay_log


def fit_to_log(model: ValveModel, log: BenchLog, names: Sequence[str] | None = None, *,
               start: LogReplay | None = None, max_evaluations: int = 120) -> FitResult:
    """Least-squares fit of the free parameters (or ``names``) by replaying the whole log.

    Each evaluation starts the solver from the previous one (warm start), which halves the cost
    of a replay; extrapolation flags are skipped inside the fit.
    """
    last = {"replay": start}

    def residuals(candidate: ValveModel):
        played = replay_log(candidate, log, guess=last["replay"], extrapolation=False)
        last["replay"] = played
        return played.residual

    return fit(model, residuals, names, max_evaluations=max_evaluations)
