"""Which physical effect is the model missing? Refit with each candidate and judge the gain.

Procedure
---------
1. Replay the model over the log: residual r0, its noise floor σ
   (:func:`~surrogate.fitting.residuals.noise_floor`) and its effective number of independent
   samples n_eff (:func:`~surrogate.fitting.residuals.effective_samples`).
2. *Linearise* and *refit* every candidate together with the model's free parameters
   (:mod:`.refit`).
3. Judge each candidate against the maps' own error and on runs it was not fitted to: ΔBIC
   against the maps' discrepancy, held-out RMS per scheme, inclusion frequency over bootstrap
   resamples of runs (:mod:`.judge`). Rank the candidates by ΔBIC, best (most negative) first.
4. Split each run's residual, before and after each candidate, into its median line and its
   half-width (:mod:`~surrogate.fitting.hysteresis`): a map error moves both ramps alike,
   friction changes their split. A friction term must narrow the half-width, any other term the
   median line.
5. Group the candidates the data cannot tell apart (:mod:`.lookalikes`), apply the significance
   rule (:mod:`.rule`), and flag per-run readings that look like a sensor fault (:mod:`.sensors`).
6. Fit the shape-free terms (:mod:`.shapes`), judge them the same way, and rank and group them
   with the library's, the bootstrap over runs choosing among all of them. When a library term
   is significant, a shape replaces it only when it fits decisively better.
7. When the best candidate has a look-alike, replay both over the runs the bench could make
   next and name the one where they differ most, or say that none within reach decides
   (:mod:`~surrogate.planning.bench_runs`).

The result is numbers only (:class:`~.result.Diagnosis`); :mod:`surrogate.reporting.prose` puts
them into words.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from ..data.loaders import BenchLog
from ..effects import LIBRARY, Effect, EffectLibrary
from ..effects.shapes import SHAPE_FREE
from ..fitting.hysteresis import hysteresis_split
from ..fitting.logfit import probe_columns
from ..fitting.residuals import LogReplay, noise_floor, replay_log
from ..fitting.leastsquares import free_parameters
from ..model import ValveModel
from ..core.parallel import blas_limited, single_threaded
from ..core.units import from_si
from .judge import Judge
from .lookalikes import (absorbed, alike_shapes, declined, grouped, joined,
                         look_alike_separation, maps_error_rival, rival_of)
from .refit import REFINE_STEPS, DiagnosisProblem, refit_candidates
from .result import Baseline, Candidate, Declined, Diagnosis, Rival
from .rule import RULE, SHAPE_REFIT_REACH, SignificanceRule, gains_in_own_view
from .sensors import sensor_checks
from .shapes import shape_free_candidates


def candidate_effects(model: ValveModel, library: EffectLibrary = LIBRARY,
                      names: Iterable[str] | None = None) -> list[type[Effect]]:
    """The effects of ``library`` the model does not have (or those of them named), shape-free
    ones included only when named (by default the diagnosis tries every shape-free term on its
    own, :func:`shape_candidates`), and no effect that is no candidate by default
    (:attr:`~surrogate.effects.Effect.candidate`: the maps' calibration) unless named.

    Raises
    ------
    InputError
        For a name the library (or the shape-free terms) does not hold.
    """
    known = library + EffectLibrary(cls for cls in SHAPE_FREE if cls.name not in library)
    chosen = ({name: cls for name, cls in library.items()
               if not getattr(cls, "shape_free", False) and cls.candidate} if names is None
              else {name: known.effect(name) for name in names})
    return [cls for name, cls in chosen.items() if not model.has_effect(name)]


def shape_candidates(model: ValveModel, names: Iterable[str] | None = None,
                     library: EffectLibrary = LIBRARY) -> list[type[Effect]]:
    """The shape-free terms a diagnosis tries: every one the model lacks, or those named."""
    if names is None:
        return [cls for cls in SHAPE_FREE if not model.has_effect(cls.name)]
    return [cls for cls in candidate_effects(model, library, names)
            if getattr(cls, "shape_free", False)]


@dataclass(frozen=True)
class Diagnoser:
    """Diagnoses a fitted model's log (the module docstring's procedure), its settings held once.

    Parameters
    ----------
    library : EffectLibrary
        The effects to choose from (default: the built-in ones).
    rule : SignificanceRule
        When a candidate is a discovery (default: the package's :data:`.rule.RULE`).
    candidates : tuple of str, optional
        Names of the library's effects (or shape-free terms) to try; default every one the
        model lacks.
    steps : int
        Gauss–Newton steps (one replay each) per candidate after the linear solution.
    shapes : bool
        Whether to try the shape-free terms (:mod:`.shapes`; those named in ``candidates``, or
        all of :data:`surrogate.effects.shapes.SHAPE_FREE`) when no library term is
        significant. They then compete with the library's, ranked behind a library term that
        fits about as well (:meth:`.rule.SignificanceRule.rank`).
    workers : int, optional
        Threads refitting candidates side by side (default one,
        :func:`surrogate.core.parallel.single_threaded`); on GP and NN maps more threads may
        move the result's last digits, with the order the threads renew the maps' tables in.
    progress : callable, optional
        Called with a line of text as the work proceeds.
    """

    library: EffectLibrary = field(default_factory=lambda: LIBRARY)
    rule: SignificanceRule = RULE
    candidates: tuple[str, ...] | None = None
    steps: int = REFINE_STEPS
    shapes: bool = True
    workers: int | None = None
    progress: Callable[[str], None] | None = None

    def note_progress(self, message: str) -> None:
        """Tell the progress callback, if there is one."""
        if self.progress is not None:
            self.progress(message)

    @blas_limited()
    @single_threaded
    def diagnose(self, model: ValveModel, log: BenchLog, *, base: LogReplay | None = None,
                 exclude: Iterable[str] = (), own_columns: list | None = None) -> Diagnosis:
        """Rank the candidate effects by how much of the residual they explain.

        Parameters
        ----------
        model : ValveModel
            The current model, with its free parameters already fitted to ``log``.
        log : BenchLog
        base : LogReplay, optional
            The model's replay of ``log``, if already computed.
        exclude : iterable of str
            Names not to try (a workflow's step that a full refit refused).
        own_columns : list of Column, optional
            The probe columns of every free parameter of ``model`` at ``base``
            (:func:`~surrogate.fitting.logfit.probe_columns`), if already made; else made here.
        """
        exclude = set(exclude)
        base = base or replay_log(model, log)
        problem = DiagnosisProblem(log, base, model)
        own_columns = self._own_columns(model, base, problem, own_columns)
        classes = [cls for cls in candidate_effects(model, self.library, self.candidates)
                   if not getattr(cls, "shape_free", False) and cls.name not in exclude]
        results, refined = refit_candidates(model, classes, problem, own_columns, self.steps,
                                            self.workers, self.note_progress)
        ground = _Ground.of(model, log, problem, own_columns, self.rule)
        results = ground.with_views([ground.judge.judge(candidate) for candidate in results])
        _say_scores(self.note_progress, results, refined)
        results = ground.ranked(results)
        rivals = [maps_error_rival(ground.judge.maps_error_heldout())]
        beside_maps: dict[str, dict] = {}  # a shape's held-out RMS with the maps' error beside it
        shaped = [cls for cls in (shape_candidates(model, self.candidates, self.library)
                                  if self.shapes else []) if cls.name not in exclude]
        if shaped:
            results, shape_rivals, beside_maps = self._with_shapes(model, ground, results, shaped)
            rivals += shape_rivals
        results, withheld = self._withheld(ground, log, results, rivals, beside_maps)
        return ground.diagnosis(model, log, results, withheld)

    def _own_columns(self, model: ValveModel, base: LogReplay, problem: DiagnosisProblem,
                     own_columns: list | None) -> list:
        """The probe columns of the model's free parameters the data feel: those given, if they
        are every free parameter's, else made here."""
        free = free_parameters(model)
        if own_columns is None or [c.key for c in own_columns] != [key for key, _ in free]:
            self.note_progress(f"linearising the replay in the model's {len(free)} free "
                               "parameter(s)")
            own_columns = probe_columns(model, [key for key, _ in free], base,
                                        workers=self.workers, alike=problem.alike)
        return [column for column in own_columns if column.felt]

    def _with_shapes(self, model: ValveModel, ground: "_Ground", results: list[Candidate],
                     shaped: list) -> tuple[list[Candidate], list[Rival], dict[str, dict]]:
        """The candidates with the shape-free terms judged beside the library's; the rivals
        they bring (their linear fits, and each refitted shape); each shape's held-out RMS with
        the maps' error beside it.

        Shape-free terms only after the library: a library term that explains the log says it
        with fewer parameters and a name (and shapes, which soak up part of any effect, would
        split the bootstrap's votes with it). A shape replaces a library finding only when it
        fits decisively better (:meth:`.rule.SignificanceRule.replaces`): a detent taken for a
        progressive spring, a friction rising with the flow taken for a pilot-pressure friction.
        """
        rule, judge = self.rule, ground.judge
        finding = next((c for c in results if c.significant), None)
        # beside a finding, only the shapes whose linear fit comes within reach of it are
        # refitted (:data:`.rule.SHAPE_REFIT_REACH`), and those whose linear fit predicts the
        # held-out runs nearly as well as the finding: a look-alike that may withhold it
        # (:func:`.lookalikes.declined`) is refitted as it was
        must_beat = heldout_to_beat = None
        if finding is not None:
            must_beat = finding.delta_bic - SHAPE_REFIT_REACH * rule.bic
            heldout_to_beat = finding.heldout_rms / (1.0 - rule.other_kind_gain)
        found, linear_rivals = shape_free_candidates(
            model, ground.problem, ground.own_columns, judge, shaped, steps=self.steps,
            workers=self.workers, progress=self.note_progress, must_beat=must_beat,
            heldout_to_beat=heldout_to_beat, finding_kind=finding and finding.kind)
        found = ground.with_views(found)
        # a shape refitted for real stands as its refit, not its linear fit
        rivals = [r for r in linear_rivals if r.name not in {c.name for c in found}]
        _say_scores(self.note_progress, found, set(range(len(found))))
        together = ground.ranked(results + found)
        challenger = next((c for c in together if c.significant), None)
        if finding is None or (challenger is not None and challenger.shape_free
                               and rule.replaces(challenger, finding)):
            results = together
        else:  # reported, behind the library's finding, never added
            behind = [c.scored(significant=False) for c in together if c.shape_free]
            # every share shown comes from the one bootstrap competition all of them were in,
            # so that a group's share counts each resample once: the finding's from the
            # library's alone beside a shape's from both summed to 102-107 % of resamples
            # where a look-alike shape joined its group (stress cases 216-218)
            shares = {c.name: c.inclusion for c in together}
            results = joined([c.scored(inclusion=shares[c.name]) for c in results] + behind,
                             finding.name, alike_shapes(finding, behind,
                                                        ground.problem.rms_before, ground.floor,
                                                        judge.heldout, rule))
        beside_maps = {c.name: judge.maps_error_heldout(c.linearised)
                       for c in results if c.shape_free}
        rivals += [rival_of(c, beside_maps[c.name]) for c in results if c.shape_free]
        return results, rivals, beside_maps

    def _withheld(self, ground: "_Ground", log: BenchLog, results: list[Candidate],
                  rivals: list[Rival], beside_maps: dict[str, dict]
                  ) -> tuple[list[Candidate], Declined | None]:
        """The candidates, none significant when the physics claim among them is withheld for
        its look-alikes of other kinds (:func:`.lookalikes.declined`), and the withholding."""
        claim = next((c for c in results if c.significant), None)
        withheld = declined(claim, rivals, ground.judge.heldout, log, ground.floor, self.rule,
                            beside_maps=(None if claim is None else beside_maps.get(claim.name)
                                         or ground.judge.maps_error_heldout(claim.linearised)))
        if withheld is None:
            return results, None
        self.note_progress(f"{claim.name} withheld: " + ", ".join(
            f"{r.name} {from_si(r.heldout_rms, 'bar'):.3f} bar" for r in withheld.rivals)
            + f" on held-out runs against its {from_si(claim.heldout_rms, 'bar'):.3f} bar, and"
              " as close on each condition left out")
        return [c.scored(significant=False) for c in results], withheld


@dataclass(frozen=True)
class _Ground:
    """What one diagnosis judges every candidate against: the replay's problem and noise floor,
    the model's own columns (as probe columns and as a matrix), the judge, and the runs'
    hysteresis views before any candidate."""

    rule: SignificanceRule
    problem: DiagnosisProblem
    floor: float  # [Pa]
    own_columns: list
    own_matrix: np.ndarray  # samples × the model's free parameters
    judge: Judge
    split: object  # the runs' hysteresis split (surrogate.fitting.hysteresis)
    median_before: float  # [Pa]
    half_before: float  # [Pa]

    @classmethod
    def of(cls, model: ValveModel, log: BenchLog, problem: DiagnosisProblem, own_columns: list,
           rule: SignificanceRule) -> "_Ground":
        """The ground of a diagnosis of ``model`` on ``log``."""
        base = problem.base
        floor = noise_floor(base.residual, base.runs, source=base.log.source)
        judge = Judge(model, problem, own_columns, floor, rule)
        split = hysteresis_split(log.frame.loc[problem.ok])
        median_before, half_before = split.rms(problem.base_evaluation.residual)
        own_matrix = (np.column_stack([c.change / c.step for c in own_columns]) if own_columns
                      else np.zeros((int(problem.ok.sum()), 0)))
        return cls(rule, problem, floor, own_columns, own_matrix, judge, split, median_before,
                   half_before)

    def with_views(self, found: list[Candidate]) -> list[Candidate]:
        """The candidates with the RMS of the runs' median line and half-width after each."""
        return [c.scored(**dict(zip(("median_rms", "half_width_rms"),
                                      self.split.rms(c.linearised.residual)))) for c in found]

    def ranked(self, found: list[Candidate]) -> list[Candidate]:
        """The candidates best first, grouped with their look-alikes, and the significance rule
        applied, its last test (the bootstrap over runs) among these candidates."""
        rule, problem = self.rule, self.problem
        # best first by ΔBIC, which weighs the gain against the parameters it took (an offset
        # per run always fits a little better than one offset; it must fit better by enough)
        found = sorted(found, key=rule.rank)
        found = [c.scored(own_view=gains_in_own_view(c, self.median_before, self.half_before),
                         significant=False, stable=True, inclusion=0.0) for c in found]
        found = [c.scored(significant=rule.passes(c, problem.rms_before, self.floor,
                                                    self.judge.heldout)) for c in found]
        found = grouped(found, rule, self.own_matrix)
        shares = self.judge.inclusion(found)
        # the last test needs every candidate's share
        found = [c.scored(inclusion=shares[c.name],
                         stable=rule.stable(sum(shares[name] for name in c.group)))
                 for c in found]
        return [c.scored(significant=c.significant and c.stable) for c in found]

    def diagnosis(self, model: ValveModel, log: BenchLog, results: list[Candidate],
                  withheld: Declined | None) -> Diagnosis:
        """The diagnosis of ``results``: settled, with the sensor checks, the terms the model's
        own parameters mimic and the bench run that would separate the best from its first
        look-alike."""
        judge, problem = self.judge, self.problem
        mimicked = absorbed(results, self.own_matrix, [c.key for c in self.own_columns])
        checks = sensor_checks(results, judge.schemes)
        baseline = Baseline(
            rms_before=problem.rms_before, noise_floor=self.floor,
            effective_samples=problem.n_eff, correlations=residual_correlations(problem.base),
            heldout_by_scheme=judge.heldout, expected_rms=judge.expected_rms(problem.base),
            map_limits=judge.map_limits(), median_before=self.median_before,
            half_width_before=self.half_before)
        diagnosis = Diagnosis(model=model, base=problem.base, baseline=baseline,
                              candidates=tuple(candidate.settled() for candidate in results),
                              sensor_checks=checks, absorbed=mimicked, declined=withheld,
                              rule=self.rule)
        return replace(diagnosis, separation=look_alike_separation(diagnosis, log))


def diagnose(model: ValveModel, log: BenchLog, library: EffectLibrary = LIBRARY, *,
             base: LogReplay | None = None, exclude: Iterable[str] = (),
             own_columns: list | None = None, **settings) -> Diagnosis:
    """``Diagnoser(library, **settings).diagnose(model, log, ...)``: one diagnosis with the
    settings of :class:`Diagnoser` (``candidates``, ``rule``, ``shapes``, ``steps``,
    ``workers``, ``progress``) and the arguments of :meth:`Diagnoser.diagnose`."""
    if settings.get("candidates") is not None:
        settings["candidates"] = tuple(settings["candidates"])
    return Diagnoser(library, **settings).diagnose(model, log, base=base, exclude=exclude,
                                                   own_columns=own_columns)


def _say_scores(progress, candidates: list[Candidate], refined: set[int]) -> None:
    """One progress line per candidate: its RMS, held-out RMS and ΔBIC."""
    for number, candidate in enumerate(candidates, start=1):
        progress(f"  [{number}/{len(candidates)}] {candidate.name}: rms "
                 f"{from_si(candidate.rms_after, 'bar'):.3f} bar, "
                 + (f"held out {from_si(candidate.heldout_rms, 'bar'):.3f} bar"
               if np.isfinite(candidate.heldout_rms) else "not judged on held-out runs (per run)")
                 + f", ΔBIC {candidate.delta_bic:.1f}"
                 + ("" if number - 1 in refined else " (not refined)"))


def residual_correlations(base: LogReplay) -> dict[str, float]:
    """Pearson correlation of the residual with candidate variables, and of the residual signed
    by the ramp direction (a hysteresis misfit) with the same variables."""
    frame = base.log.frame
    values = {"q": frame["q"], "p_L": frame["p_L"], "p_P": frame["p_P"], "p_B": frame["p_B"],
              "p_Pe": frame["p_P"] - frame["p_B"], "temperature": frame["temperature"],
              "|p_L - p_P|": (frame["p_L"] - frame["p_P"]).abs()}
    ok = np.isfinite(base.residual)
    signed = base.residual * np.where(frame["direction"].to_numpy() == "up", 1.0, -1.0)
    result = {}
    for name, series in values.items():
        x = np.asarray(series, float)[ok]
        if np.std(x) == 0:
            continue
        result[f"residual~{name}"] = float(np.corrcoef(base.residual[ok], x)[0, 1])
        result[f"hysteresis~{name}"] = float(np.corrcoef(signed[ok], x)[0, 1])
    return result
