"""Judging every candidate's refit against the maps' own error and on runs it was not fitted to.

Each candidate's residual and the model's, each with smooth map-discrepancy terms of the maps'
calibrated size (:mod:`surrogate.fitting.discrepancy`) fitted as penalised nuisances together
with the model's (and the candidate's) parameters (:mod:`surrogate.fitting.heldout`), give
ΔBIC = n_eff·ln(S_after/S_before) + k·ln(n_eff), with S the sum of squares left once the
discrepancy and the parameters have explained what they can, plus the discrepancy prior's
penalty, and k the candidate's parameters the data inform. Each candidate is refitted without one
run, one temperature, one pilot pressure at a time (linearised at its optimum): its RMS on the
runs left out, per scheme. A bootstrap over runs gives its inclusion frequency: the share of
resamples in which it would be added.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..fitting.discrepancy import Discrepancy, map_discrepancy, map_error_with_cfd
from ..fitting.heldout import (HEADLINE, Linearised, RunBlocks, RunIndex, bootstrap_weights,
                               held_at_bounds, run_groups)
from ..fitting.residuals import LogReplay
from ..model import ValveModel
from .refit import Column, DiagnosisProblem
from .result import Candidate, MapLimit
from .rule import RULE, SignificanceRule, delta_bic

RESAMPLES = 200  # bootstrap resamples over runs for the inclusion frequencies


def own_roughness(model: ValveModel, own_columns: list[Column], samples: int
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """The model's penalty (:meth:`~surrogate.model.ValveModel.penalty`, a shape's roughness) on
    its own parameters over ``samples`` residuals, per step of each column, and its residual
    [Pa] at the model's values; None without one."""
    keys = [c.key for c in own_columns]
    penalty = model.penalty(keys, samples)
    if penalty is None:
        return None
    matrix, offset = penalty
    parameters = model.parameters()
    values = np.array([parameters[key].value for key in keys])
    return matrix * np.array([c.step for c in own_columns]), matrix @ values + offset


class Judge:
    """Every candidate's refit, judged against what the maps' uncertainty allows and on runs it
    was not fitted to, linearised at its optimum.

    The penalty on the discrepancy's coefficients is s² = σ²·n/n_eff: the noise of one
    effective sample, as the residuals are correlated in time."""

    def __init__(self, model: ValveModel, problem: DiagnosisProblem, own_columns: list[Column],
                 floor: float, rule: SignificanceRule = RULE):
        self.problem = problem
        self.rule = rule
        ok = problem.ok
        self.runs = problem.base.runs[ok]
        self.run_index = RunIndex.of(self.runs)  # for every refit's RunBlocks
        self.discrepancy: Discrepancy | None = map_discrepancy(model, problem.base, ok)
        self.penalty = floor**2 * ok.sum() / problem.n_eff
        self.schemes = run_groups(problem.log)
        parameters = model.parameters()
        held = [parameters[c.key] for c in own_columns]
        own_matrix = held_at_bounds(
            np.column_stack([c.change for c in own_columns]) if own_columns
            else np.zeros((int(ok.sum()), 0)), held)
        self.own_matrix = own_matrix  # the model's own columns, at the samples the model solves
        #: the model's own penalty (a shape's roughness) in those columns, and its residual
        self.own_roughness = own_roughness(model, own_columns, int(ok.sum()))
        #: the model's linearisation at its optimum, parameters on a bound held
        self.fit = Linearised(problem.base_evaluation.residual, own_matrix, self.own_roughness
                              ).held(held)
        self.base = RunBlocks(self.fit, self.discrepancy, self.run_index, self.penalty)
        self.ones = np.ones(len(self.base.labels))
        self.objective_before = self.base.objective(self.ones)
        self.heldout = self.base.heldout_rms(self.schemes)  # per scheme [Pa]
        self.blocks: dict[str, tuple[RunBlocks, float]] = {}
        # each judged refit's objective on every bootstrap resample, by its blocks: a diagnosis
        # asks for the inclusion twice (the library, then the library with the shapes)
        self._resampled: dict[int, tuple[RunBlocks, np.ndarray, list[float]]] = {}

    def judge(self, candidate: Candidate, shape: list[int] | None = None) -> Candidate:
        """The candidate with its held-out RMS and its ΔBIC against the maps' discrepancy.

        Its linearisation brings the fit's roughness penalty, if any (:class:`~surrogate.
        fitting.heldout.RunBlocks`); a shape-free term brings the columns of its coefficients
        (``shape``), and the parameters it counts in ΔBIC are then their effective number (the
        trace of their block of the hat matrix, the discrepancy refitted with them), not their
        count."""
        blocks = RunBlocks(candidate.linearised, self.discrepancy, self.run_index, self.penalty)
        if shape is not None:
            candidate = replace(candidate, extra=blocks.effective_parameters(shape))
        self.blocks[candidate.name] = (blocks, candidate.extra)
        scores = {}
        if not candidate.per_run:  # a run's own parameter is off for a run it never saw
            heldout = blocks.heldout_rms(self.schemes)
            scores = {"heldout": heldout, "heldout_rms": heldout.get(HEADLINE, float("nan"))}
        return candidate.scored(**scores, delta_bic=delta_bic(
            blocks.objective(self.ones), self.objective_before, self.problem.n_eff,
            candidate.extra))

    def inclusion(self, candidates: list[Candidate]) -> dict[str, float]:
        """Each candidate's share of bootstrap resamples over runs in which it would be added:
        the best by ΔBIC against the discrepancy (with a shape-free term's handicap), and below
        the threshold, among those that predict held-out runs better and narrow their own view
        of the hysteresis (a candidate that fails either test is never added)."""
        weights = bootstrap_weights(len(self.base.labels), RESAMPLES)
        chosen = [c for c in candidates if not c.per_run and c.own_view
                  and self.rule.predicts_unseen(c, self.heldout)]
        counts = dict.fromkeys((c.name for c in chosen), 0)
        befores = self._objectives(self.base, weights)
        afters = [self._objectives(self.blocks[c.name][0], weights) for c in chosen]
        for i, w in enumerate(weights):
            n_eff = self.problem.n_eff * w.sum() / len(w)
            before = befores[i]
            scores = [delta_bic(after[i], before, n_eff, self.blocks[c.name][1])
                      for c, after in zip(chosen, afters)]
            ranks = [score + self.rule.handicap(c) for score, c in zip(scores, chosen)]
            if ranks and min(ranks) < self.rule.bic:
                counts[chosen[int(np.argmin(ranks))].name] += 1
        return {c.name: counts.get(c.name, 0) / len(weights) for c in candidates}

    def _objectives(self, blocks: RunBlocks, weights: np.ndarray) -> list[float]:
        """``blocks.objective`` at each row of ``weights``, formed once per blocks and
        weights."""
        found = self._resampled.get(id(blocks))
        if found is None or not np.array_equal(found[1], weights):
            found = (blocks, weights, [blocks.objective(w) for w in weights])
            self._resampled[id(blocks)] = found  # keeps blocks, so that its id stays its own
        return found[2]

    def maps_error_heldout(self, fit: Linearised | None = None) -> dict[str, float]:
        """RMS on held-out runs [Pa] per scheme of the model (or of a candidate's refit: its
        linearisation ``fit``) with the maps' own error fitted beside it: the discrepancy's
        coefficients refitted with the parameters under their prior (s²·‖a‖², as in the
        judgement), so that it stays within the maps' σ. Empty without a discrepancy."""
        if self.discrepancy is None:
            return {}
        size = self.discrepancy.size
        fit = (self.fit if fit is None else fit).beside(
            self.discrepancy.columns, np.sqrt(self.penalty) * np.eye(size), np.zeros(size))
        blocks = RunBlocks(fit, None, self.run_index, 0.0)
        # about the whole log's optimum, as a candidate's refit is
        return blocks.moved(blocks.step(self.ones)).heldout_rms(self.schemes)

    def expected_rms(self, base: LogReplay) -> float:
        """The RMS that noise and the maps' uncertainty (with the CFD's own error) allow
        together [Pa]."""
        effects = map_error_with_cfd(base.replay)
        spread = 0.0 if effects is None else float(
            np.nanmean(np.sum(effects[:, self.problem.ok] ** 2, axis=0)))
        return float(np.sqrt(self.problem.noise_floor**2 + spread))

    def map_limits(self, count: int = 3) -> tuple[MapLimit, ...]:
        """Where the fitted discrepancy is largest: the maps' error the residual shows most."""
        if self.discrepancy is None:
            return ()
        theta = self.base.nuisance()
        share = np.sqrt(np.mean((self.discrepancy.columns * theta) ** 2, axis=0))
        order = [i for i in np.argsort(share)[::-1] if share[i] > 0][:count]
        return tuple(MapLimit(self.discrepancy.names[i], float(share[i])) for i in order)
