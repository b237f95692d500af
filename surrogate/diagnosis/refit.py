"""Refitting every candidate effect with the model's own free parameters, cheaply.

1. *Linearise*: one finite-difference replay per free parameter of the model (shared by every
   candidate) and per parameter of each candidate effect.
2. *Refit* every candidate together with the model's free parameters: bounded linear least
   squares on the linearisation, then up to four Gauss–Newton steps in which every new point is
   replayed for real and the Jacobian is corrected by Broyden's update (one replay per step
   instead of one per parameter); a step that lowers the RSS by less than
   :data:`surrogate.fitting.leastsquares.SETTLED_GAIN` of it ends the refit. Only the four front
   runners after the first real replay (and any as good as the last of them) take those steps; the
   others keep the RMS of that first replay, an upper bound, as they are far behind. The
   reported RMS is that of a real replay at the reported parameters, never a linear estimate.
   Standard errors come from the final Jacobian, inflated by √(n/n_eff) because the samples are
   not independent. The candidates are independent of each other and are refitted side by side
   on threads (:mod:`surrogate.core.parallel`).
"""

from __future__ import annotations


import numpy as np

from ..data.loaders import BenchLog
from ..effects import Effect, PerRunEffect
from ..fitting.heldout import Linearised
from ..fitting.logfit import Column, ReadAlike, probe_column, probe_runs
from ..fitting.residuals import LogReplay, effective_samples, noise_floor, replay_log
from ..fitting.leastsquares import Evaluation, FitProblem, Minimizer
from ..model import ValveModel
from ..core.parallel import map_threads
from ..core.progress import Stage
from .result import Candidate, Label, Score
from .rule import BIC_THRESHOLD, delta_bic

REFINE_STEPS = 4  # Gauss–Newton steps per front-running candidate after the linear solution
REFINED = 4  # candidates refined by those steps (with any as good as the last of them)


def refit_candidates(model: ValveModel, classes: list[type[Effect]],
                     problem: "DiagnosisProblem", own_columns: list["Column"], steps: int,
                     workers: int | None, progress=None) -> tuple[list[Candidate], set[int]]:
    """Every candidate refitted with the model's free parameters (module docstring, step 2):
    the candidates are independent, so they are linearised and refitted side by side. Each gets
    its linear solution evaluated for real; only the front runners are refined further, the
    others keep that first real RMS (an upper bound: refining only lowers it)."""

    def linearise(cls: type[Effect]) -> tuple[Minimizer, list[Column]]:
        trial = model.copy()
        trial.effects.append(cls.for_runs(problem.log.run_ids))
        # the model's own replay read from the tables, where it is also the trial's off
        alike = problem.alike and problem.alike.extended_by(trial.effect(cls.name))
        columns = problem.columns_of(trial, [f"{cls.name}.{name}" for name, parameter
                                             in trial.effect(cls.name).params.items()
                                             if parameter.vary], alike)
        # a parameter the data do not feel (a run's pilot offset while its piston sits on the
        # stop) stays where it is: an empty column leaves the linear step undetermined
        columns = [c for c in columns if c.felt]
        every = own_columns + columns
        minimizer = Minimizer(trial, problem, [c.key for c in every])
        minimizer.linearise([c.change for c in every], [c.step for c in every],
                            problem.base_evaluation).refine(1)
        return minimizer, columns

    linearised = Stage(progress or (lambda message: None), "linearising the candidates",
                       len(classes))
    refits = []
    for refit in map_threads(linearise, classes, workers=workers):
        refits.append(refit)
        linearised(len(refits))
    probes = [np.column_stack([c.change / c.step for c in columns]) if columns else None
              for _, columns in refits]
    first = [candidate_of(cls, minimizer, len(columns), problem, probe)
             for cls, (minimizer, columns), probe in zip(classes, refits, probes)]
    chosen = front_runners(first)
    refining = Stage(progress or (lambda message: None), "refitting the front runners", len(chosen))
    refined = {}
    for i, candidate in zip(chosen, map_threads(
            lambda i: candidate_of(classes[i], refits[i][0].refine(steps), len(refits[i][1]),
                                   problem, probes[i]), chosen, workers=workers)):
        refined[i] = candidate
        refining(len(refined))
    return [refined.get(i, candidate) for i, candidate in enumerate(first)], set(refined)


def candidate_of(cls: type[Effect], minimizer: Minimizer, extra: int,
                 problem: "DiagnosisProblem", probe: np.ndarray | None = None) -> Candidate:
    """The candidate at its refinement's best point, with standard errors; ``extra`` of its
    parameters are the candidate's own (the data inform them), ``probe`` their columns at the
    model's point (:attr:`.result.Candidate.probe`)."""
    evaluation, rss = minimizer.refined
    minimizer.refinement_errors()
    linearised = Linearised(evaluation.residual, minimizer.refined_jacobian,
                            minimizer.refined_penalty).held(minimizer.parameters)
    change = np.zeros(len(problem.ok))
    change[problem.ok] = evaluation.residual - problem.base_evaluation.residual
    trial = minimizer.model
    label = Label(cls.name, cls.title, cls.describe(), cls.kind, cls.category,
                  per_run=issubclass(cls, PerRunEffect),
                  check_threshold=getattr(cls, "check_threshold", 0.0))
    score = Score(float(np.sqrt(rss / problem.ok.sum())),
                  delta_bic(rss, problem.rss_before, problem.n_eff, extra))
    return Candidate(label, score, params=tuple(trial.effect(cls.name).params.values()),
                     extra=extra, model=trial, replay=evaluation.payload, change=change,
                     linearised=linearised, probe=probe)


class DiagnosisProblem(FitProblem):
    """The log's residual on the samples the model solves, every replay warm-started from the
    model's own (the candidates' refits never move it, so they do not depend on each other).
    With ``model`` (the model ``base`` replays), its replay read from the fit's tables is made
    once for the probes that difference against it (:class:`~surrogate.fitting.logfit.
    ReadAlike`)."""

    def __init__(self, log: BenchLog, base: LogReplay, model: ValveModel | None = None):
        self.log, self.base = log, base
        self.alike = None if model is None else ReadAlike(model, log, base)
        self.ok = np.isfinite(base.residual)
        self.rss_before = float(np.sum(base.residual[self.ok] ** 2))
        self.rms_before = float(np.sqrt(self.rss_before / self.ok.sum()))
        self.n_eff = effective_samples(base.residual, base.runs)
        self.noise_floor = noise_floor(base.residual, base.runs, source=base.log.source)
        self.base_evaluation = Evaluation(base.residual[self.ok], base)

    def evaluate(self, model: ValveModel, fit_step: bool = True) -> Evaluation:
        log_replay = replay_log(model, self.log, guess=self.base, diagnostics=False)
        return Evaluation(log_replay.residual[self.ok], log_replay)

    def effective_samples(self, evaluation: Evaluation) -> float:
        return self.n_eff

    def column_of(self, model: ValveModel, key: str, alike: ReadAlike | None = None
                  ) -> Column:
        """∂Δp/∂parameter · step by a forward difference, warm-started from the base replay
        (:func:`~surrogate.fitting.logfit.probe_column`; ``alike``: ``model``'s replay read
        from the tables, if shared)."""
        return probe_column(model, key, self.log, self.base, self.ok, alike)

    def columns_of(self, model: ValveModel, keys: list[str], alike: ReadAlike | None = None
                   ) -> list[Column]:
        """:meth:`column_of` of every parameter of ``keys``, those of one run each from one
        replay of the log (:func:`~surrogate.fitting.logfit.probe_runs`)."""
        shared = probe_runs(model, keys, self.log, self.base, self.ok)
        return [shared[key] if key in shared else self.column_of(model, key, alike)
                for key in keys]


def front_runners(candidates: list[Candidate]) -> list[int]:
    """Indices of the candidates worth refining: the :data:`REFINED` best by ΔBIC after their
    first real replay, and any within 2·|:data:`.rule.BIC_THRESHOLD`| of the last of those (so
    that two candidates the data may not tell apart are refined alike)."""
    order = sorted(range(len(candidates)), key=lambda i: candidates[i].delta_bic)
    if len(order) <= REFINED:
        return order
    cut = candidates[order[REFINED - 1]].delta_bic - 2.0 * BIC_THRESHOLD
    return [i for i in order if candidates[i].delta_bic <= cut]
