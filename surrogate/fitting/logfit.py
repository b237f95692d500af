"""Fitting a model's free parameters to every sample of a bench log."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..data.loaders import BenchLog
from ..effects import Effect
from .leastsquares import Evaluation, FitProblem, FitResult, Minimizer, free_parameters, split_key
from ..model import ValveModel
from ..core.parallel import blas_limited, map_threads, single_threaded
from ..parameters import Parameter
from ..core.progress import Stage
from ..core.units import from_si
from ..points import OperatingPoints
from ..solver.sensitivities import pressure_drop_changes
from .residuals import (LogReplay, effective_samples, replay_log, run_rows,
                        state_smoothing_samples)


class LogProblem(FitProblem):
    """The residual of a replay of every run of a log, warm-started from the fit's last step.

    Each evaluation starts the solver from the fit's previous one (a warm start halves the cost
    of a replay); extrapolation flags are skipped. A parameter of one run is differentiated by
    replaying that run alone. The residuals, correlated in time, are worth
    :func:`.residuals.effective_samples` independent ones.
    """

    def __init__(self, log: BenchLog, start: LogReplay | None = None):
        self.log = log
        self.source = log.source
        self.last = start

    def evaluate(self, model: ValveModel, fit_step: bool = True) -> Evaluation:
        log_replay = replay_log(model, self.log, guess=self.last, diagnostics=False)
        # only the fit's own steps move the warm start: the Jacobian's columns, on threads,
        # start from the point they differentiate at, so the result does not depend on timing
        if fit_step:
            self.last = log_replay
        return Evaluation(log_replay.residual, log_replay)

    def column(self, model: ValveModel, parameter: Parameter):
        if parameter.scope is None:
            return super().column(model, parameter)
        rows = run_rows(self.log, parameter.scope)
        start = self.last
        log_replay = replay_log(model, self.log.take(rows), diagnostics=False,
                                guess=None if start is None else start.take(rows))
        return rows, log_replay.residual

    def effective_samples(self, evaluation: Evaluation) -> float:
        log_replay = evaluation.payload
        return effective_samples(log_replay.residual, log_replay.runs)

    def changes(self, model: ValveModel, trials, evaluation: Evaluation) -> np.ndarray:
        """The Jacobian's changes from the replay's sensitivities
        (:func:`surrogate.solver.sensitivities.pressure_drop_changes`): one replay's balance
        states instead of a replay per parameter."""
        log_replay = evaluation.payload
        return pressure_drop_changes(model, self._points, self.log.frame["run"].to_numpy(),
                                     log_replay.replay, trials, smoothing=self._smoothing)

    @cached_property
    def _points(self) -> OperatingPoints:
        return OperatingPoints.from_bench(self.log.frame)

    @cached_property
    def _smoothing(self) -> int:
        return state_smoothing_samples(self.log)


@blas_limited()
@single_threaded
def fit_to_log(model: ValveModel, log: BenchLog, names: Sequence[str] | None = None, *,
               start: LogReplay | None = None, max_evaluations: int = 60,
               tolerance: float = 1e-4, progress=None) -> FitResult:
    """Least-squares fit of the free parameters (or ``names``) by replaying the whole log.

    ``start``: a replay of ``log`` near the model's, to warm-start from. A parameter of one run
    that the run's samples do not feel (a run's pilot offset while its piston sits on the stop)
    keeps its value: with a column of zeros in the Jacobian it would only stall the trust region.
    The default ``tolerance`` stops once a step lowers the sum of squares by less than 10⁻⁴ of
    itself: the RMS is then settled to 5·10⁻⁵ of itself, below the four digits the workbench
    prints, and the parameters to far less than their standard errors. A friction play's
    residual is not smooth in the parameters at finer scales (samples switch between sticking
    and sliding), so a tighter tolerance mostly buys rejected trust-region steps. Standard errors
    are widened for the residuals' correlation in time. ``progress``: called with a line of
    text every few seconds while the fit runs (its evaluations and RMS so far).
    """
    names = _felt(model, log, names, start)
    minimiser_progress = None
    if progress is not None:
        # a fit's length is not known ahead (it stops when it settles): its evaluations and the
        # best RMS so far, every few seconds, against the most it may take
        clock = getattr(progress, "clock", time.perf_counter)
        state = {"best": np.inf, "said": clock()}

        def minimiser_progress(evaluations: int, rss: float) -> None:
            state["best"] = min(state["best"], rss)
            if clock() - state["said"] >= Stage.INTERVAL:
                state["said"] = clock()
                rms = from_si(np.sqrt(state["best"] / max(len(log), 1)), "bar")
                progress(f"fitting {model.name}: {evaluations} evaluations (at most "
                         f"{max_evaluations}), rms so far {rms:.3f} bar")
    result = Minimizer(model, LogProblem(log, start), names).least_squares(
        max_evaluations=max_evaluations, tolerance=tolerance, progress=minimiser_progress)
    if progress is not None:
        progress(f"fitted {model.name} in {result.evaluations} evaluations: rms "
                 f"{from_si(result.rms, 'bar'):.3f} bar")
    return result


#: [Pa] a change of the predicted Δp smaller than this is not felt
FELT = 1.0
#: probe step of a parameter: 2 % of its range (or of its value, if unbounded)
PROBE_FRACTION = 0.02
#: a parameter of one run is fitted only if its :func:`probe_step` moves at least this share
#: of the run's samples by more than :data:`FELT`: a pilot offset of a run whose piston sits on
#: its stop moves only the few samples before the piston gets there, and fitting it to those
#: would only fit their noise
FELT_SHARE = 0.05


def probe_step(parameter) -> float:
    """A step [SI] that shows how the prediction depends on ``parameter``: :data:`PROBE_FRACTION`
    of its range, downwards where a step up would cross the upper bound."""
    span = parameter.max - parameter.min
    step = PROBE_FRACTION * (span if np.isfinite(span) else max(abs(parameter.value), 1.0))
    return step if parameter.value + step <= parameter.max else -step


def probe_change(model: ValveModel, effect_name: str, parameter_name: str, log: BenchLog,
                 base: LogReplay, alike: ReadAlike | None = None) -> tuple[float, np.ndarray]:
    """The parameter's :func:`probe_step` [SI] and the change of the predicted Δp [Pa] it makes
    on ``log``, replayed from ``base``, the model's own replay of ``log``. ``alike``:
    ``model``'s replay of ``log`` read as the trial's is (:class:`ReadAlike`), when the probes
    of several parameters of one model share it."""
    trial = model.copy()
    parameter = trial.effect(effect_name).params[parameter_name]
    step = probe_step(parameter)
    parameter.value += step
    log_replay = replay_log(trial, log, guess=base, diagnostics=False)
    # the difference of two replays read alike: a replay that asked the maps is replayed as the
    # trial is, from the fit's tables (surrogate.solver.map_tables), so that their small
    # difference from the maps does not enter the column
    if base.replay.tables is None and log_replay.replay.tables is not None:
        base = (alike or ReadAlike(model, log, base))()
    return step, log_replay.replay.dp - base.replay.dp


class ReadAlike:
    """``model``'s replay of ``log`` from ``base`` (its replay that asked the maps) as a probe's
    trial replay reads them, from the fit's tables: made when a probe first needs it, then
    shared. Every probe of one model differences its trial against this same replay (the
    tables' rows are those of ``base``'s band throughout), so the probes of a model's free
    parameters replay it once instead of once each."""

    def __init__(self, model: ValveModel, log: BenchLog, base: LogReplay):
        self.model, self.log, self.base = model, log, base
        self._lock = threading.Lock()
        self._played: LogReplay | None = None

    def __call__(self) -> LogReplay:
        with self._lock:  # probes on other threads wait for the one replay
            if self._played is None:
                self._played = replay_log(self.model, self.log, guess=self.base,
                                          diagnostics=False)
            return self._played

    def extended_by(self, effect: Effect) -> "ReadAlike | None":
        """This replay when it is also that of the model with ``effect`` added at its off
        values (its defaults), else None. An effect that only adds a force, or a friction to a
        model that has one already, adds exact zeros to the balance's sums when off, so the
        two replays are the same to the bit, and a diagnosis' candidates of that kind share
        one; an input correction or a change of the flow takes other paths through the maps
        (a leak's shared pressure drop), and a first friction makes the replay a play."""
        alone = self.model.with_effects([effect])
        if alone.may_change_the_flow or (alone.has_friction and not self.model.has_friction):
            return None
        return self


@dataclass(frozen=True)
class Column:
    """One parameter's column of a replay's Jacobian: the Δp change [Pa] at the solved samples
    for a step [SI]."""

    key: str
    step: float
    change: np.ndarray
    felt: bool = True  # whether the data determine the parameter (:func:`felt`)


def probe_column(model: ValveModel, key: str, log: BenchLog, base: LogReplay,
                 ok: np.ndarray, alike: ReadAlike | None = None) -> Column:
    """∂Δp/∂parameter · step of parameter ``key`` (``"effect.parameter"``) by a forward
    difference of :func:`probe_step`, at the samples ``ok``, warm-started from ``base``, the
    model's replay of ``log``; a parameter scoped to one run replays that run only. A step of a
    fiftieth of a range, not a hair: a friction play's Δp is not smooth in the parameters at
    fine scales (samples switch between sticking and sliding), and a tiny step's column is that
    noise (a constant friction's column, differenced by 6·10⁻⁴ N, had a run held out move K1 by
    20 N). ``alike``: ``model``'s replay of ``log`` read as the trial's is, shared with the
    probes of its other parameters (:class:`ReadAlike`; a run's parameter replays its run
    alone, and reads its own)."""
    effect_name, parameter_name = split_key(key)
    scope = model.effect(effect_name).params[parameter_name].scope
    if scope is None:
        step, change = probe_change(model, effect_name, parameter_name, log, base, alike)
        determined = felt(change[ok], scoped=False)
    else:
        rows = run_rows(log, scope)
        step, in_run = probe_change(model, effect_name, parameter_name, log.take(rows),
                                    base.take(rows))
        determined = felt(in_run, scoped=True)
        change = np.zeros(len(ok))
        change[rows] = in_run
    return Column(key, step, np.where(np.isfinite(change), change, 0.0)[ok], determined)


def probe_columns(model: ValveModel, keys, base: LogReplay, workers: int | None = None,
                  alike: ReadAlike | None = None) -> list[Column]:
    """The :func:`probe_column` of every parameter of ``keys`` at the samples ``base`` (the
    model's replay of its log) solves, side by side on threads: one replay each, and one of the
    model read from the tables that they share (:class:`ReadAlike`; ``alike``, when the caller
    shares it further); the parameters of one run each share one replay of the log
    (:func:`probe_runs`)."""
    ok = np.isfinite(base.residual)
    alike = alike or ReadAlike(model, base.log, base)
    keys = list(keys)
    shared = probe_runs(model, keys, base.log, base, ok)
    alone = [key for key in keys if key not in shared]
    found = list(map_threads(lambda key: probe_column(model, key, base.log, base, ok, alike),
                             alone, workers=workers))
    columns = {**shared, **dict(zip(alone, found))}
    return [columns[key] for key in keys]


def _scope(model: ValveModel, key: str) -> str | None:
    """The run parameter ``key`` (``"effect.parameter"``) belongs to, or None."""
    effect_name, parameter_name = split_key(key)
    return model.effect(effect_name).params[parameter_name].scope


def probe_runs(model: ValveModel, keys, log: BenchLog, base: LogReplay, ok: np.ndarray
               ) -> dict[str, Column]:
    """The :func:`probe_column` of the parameters of ``keys`` each scoped to a run of its own (a
    run's pilot offset), from one replay of the whole log with every one of them stepped, where
    :func:`probe_column` replays each run alone, twice (the trial, and the model read alike).

    A run's parameter moves its run's samples only, and a replay solves each sample on its own
    and plays each run from its own start, so the log's replay holds every run's probe: twelve
    runs' probes of a pilot's zero cost two replays of the log instead of 24 of a run, whose cost
    is mostly the solver's calls, not their samples. Empty where the keys cannot share it (fewer
    than two, two on one run, or a run whose friction state the log alone smooths over another
    number of samples, :func:`state_smoothing_samples`)."""
    keys = [key for key in keys if _scope(model, key) is not None]
    scopes = [_scope(model, key) for key in keys]
    rows = [run_rows(log, scope) for scope in scopes]
    smoothing = state_smoothing_samples(log)
    if (len(keys) < 2 or len(set(scopes)) < len(scopes) or any(not r.size for r in rows)
            or any(state_smoothing_samples(log.take(r)) != smoothing for r in rows)):
        return {}
    trial = model.copy()
    steps = []
    for key in keys:
        parameter = trial.effect(split_key(key)[0]).params[split_key(key)[1]]
        steps.append(probe_step(parameter))
        parameter.value += steps[-1]
    played = replay_log(trial, log, guess=base, diagnostics=False)
    reference = base
    if base.replay.tables is None and played.replay.tables is not None:
        reference = ReadAlike(model, log, base)()  # the difference of two replays read alike
    change = played.replay.dp - reference.replay.dp
    columns = {}
    for key, step, run in zip(keys, steps, rows):
        in_run = np.zeros(len(ok))
        in_run[run] = change[run]
        columns[key] = Column(key, step, np.where(np.isfinite(in_run), in_run, 0.0)[ok],
                              felt(change[run], scoped=True))
    return columns


def felt(change: np.ndarray, scoped: bool) -> bool:
    """Whether a parameter step that changed the predicted Δp by ``change`` [Pa] (over its run's
    samples if ``scoped``, else over the whole log) is determined by the data."""
    moved = np.abs(np.where(np.isfinite(change), change, 0.0)) > FELT
    return bool(np.mean(moved) >= FELT_SHARE) if scoped else bool(np.any(moved))


def _felt(model: ValveModel, log: BenchLog, names: Sequence[str] | None,
          start: LogReplay | None) -> list[str] | None:
    """``names`` (default: every free parameter) without the run-scoped ones the data ignore;
    ``start``, a replay of ``log`` near ``model``'s, warm-starts the runs' replays."""
    chosen = free_parameters(model, names)
    scoped = [(name, p) for name, p in chosen if p.scope is not None]
    if not scoped:
        return names

    def ignored(entry) -> bool:
        name, parameter = entry
        rows = run_rows(log, parameter.scope)
        if rows.size == 0:
            return True
        run = log.take(rows)
        base = replay_log(model, run, diagnostics=False,
                          guess=None if start is None else start.take(rows))
        _, change = probe_change(model, *split_key(name), run, base)
        return not felt(change, scoped=True)

    dropped = {entry[0] for entry, drop in zip(scoped, map_threads(ignored, scoped)) if drop}
    return [name for name, _ in chosen if name not in dropped]
