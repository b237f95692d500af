"""The significance rule: when a candidate effect is a discovery the workflow adds.

A candidate is **significant** when all of these hold (:meth:`SignificanceRule.passes`, then
:meth:`SignificanceRule.stable`):

* ΔBIC < −10 against the maps' discrepancy (very strong evidence, Kass & Raftery), counted with
  n_eff so that residuals correlated in time do not pass as thousands of independent samples
  (:func:`delta_bic`); a shape-free term (:mod:`surrogate.effects.shapes`) must pass it by its
  handicap too, ΔBIC < −20 (:meth:`SignificanceRule.handicap`);
* it lowers the RMS on held-out runs by more than :data:`HELDOUT_GAIN` of it, each run left out
  in turn, and one temperature or one pilot pressure left out
  (:meth:`SignificanceRule.gains_on_unseen`): an effect that describes the valve helps
  on runs it was not fitted to, one that patches this log does not;
* the residual before is not already noise: RMS_before > 1.1·σ (:data:`NOISE_MARGIN`);
* the gain is more than a sliver of noise: RMS_before − RMS_after > 0.02·σ
  (:data:`GAIN_FRACTION`);
* it has no parameter per run: such a parameter cannot predict another run, so per-run
  candidates are reported as sensor checks, never added;
* it narrows the view of the hysteresis its physics acts on (:func:`gains_in_own_view`): a
  friction term the runs' half-width, any other term their median line;
* it, or the group it cannot be told from, is the one added in the majority of bootstrap
  resamples over runs (:data:`INCLUSION_MIN`);
* a claim of valve physics predicts held-out runs better by :data:`OTHER_KIND_GAIN` than every
  look-alike of another kind, each run left out in turn, or each temperature, or each pilot
  pressure (:meth:`SignificanceRule.beats`; :mod:`.lookalikes`): each shape-free term of
  another physical kind fitted in its place, and the maps' own error within their σ fitted
  beside it (the claim with the maps' error against the maps' error alone). A term of free
  shape bends to fit whatever the log holds; if one of another kind predicts every kind of
  unseen run about as well, or the claim adds nothing the maps' error does not, the log does
  not say which physics it holds.

Candidates are ranked by ΔBIC, a shape-free term (:mod:`surrogate.effects.shapes`) with a
handicap of |:data:`BIC_THRESHOLD`|: a library term that fits about as well comes first, having
fewer parameters and a name (:meth:`SignificanceRule.rank`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fitting.heldout import CONDITIONS, HEADLINE

BIC_THRESHOLD = -10.0
NOISE_MARGIN = 1.1  # the residual must exceed the noise floor by 10 %
#: and a candidate must remove at least this share of the noise floor of in-sample RMS: a guard
#: against slivers that a huge effective sample count would call significant. Small, as the
#: held-out gain is the real test: a true sensor offset under map error may lower the in-sample
#: RMS by a few hundredths of the floor once the model's own parameters have taken their share
#: (docs/workbench.md, "Why these thresholds")
GAIN_FRACTION = 0.02
#: a discovery must lower the RMS on held-out runs by at least this share of it: real effects
#: lower it by tens of per cent, terms patching the maps' error by a few (docs/workbench.md)
HELDOUT_GAIN = 0.03
#: a discovery (or the group it cannot be told from) must be the one added in at least this
#: share of those resamples: the majority. A finding that depends on which runs happen to be in
#: the log is not one (docs/workbench.md)
INCLUSION_MIN = 0.5
#: a physics claim must predict the held-out runs better than each look-alike of another kind
#: by at least this share of the look-alike's held-out RMS (the gain asked of any discovery)
OTHER_KIND_GAIN = HELDOUT_GAIN
#: beside a library finding, a shape-free term is refitted for real only when its linear fit's
#: ΔBIC comes within this many thresholds of the finding's: the linear fit, made at the model
#: without the shape, understates a large shape's gain (a detent's linear ΔBIC was less than half
#: its refitted one, docs/validation.md), and each real refit costs a dozen replays
SHAPE_REFIT_REACH = 4


@dataclass(frozen=True)
class SignificanceRule:
    """The thresholds of the rule (module docstring), as one object."""

    bic: float = BIC_THRESHOLD
    noise_margin: float = NOISE_MARGIN
    gain_fraction: float = GAIN_FRACTION
    heldout_gain: float = HELDOUT_GAIN
    inclusion_min: float = INCLUSION_MIN
    other_kind_gain: float = OTHER_KIND_GAIN

    def passes(self, candidate, rms_before: float, floor: float,
               heldout_before: dict[str, float]) -> bool:
        """Whether ``candidate`` passes every test but the last, its inclusion frequency; RMS
        values [Pa], ``heldout_before`` per scheme."""
        return (not candidate.per_run
                and candidate.delta_bic + self.handicap(candidate) < self.bic
                and rms_before > self.noise_margin * floor
                and rms_before - candidate.rms_after > self.gain_fraction * floor
                and self.predicts_unseen(candidate, heldout_before)
                and candidate.own_view)

    def predicts_unseen(self, candidate, heldout_before: dict[str, float]) -> bool:
        """Whether the candidate predicts held-out runs better by :attr:`heldout_gain`
        (:meth:`gains_on_unseen`)."""
        return self.gains_on_unseen(candidate.heldout, heldout_before)

    def gains_on_unseen(self, after: dict[str, float], before: dict[str, float]) -> bool:
        """Whether a model whose held-out RMS per scheme is ``after`` [Pa] predicts runs it was
        not fitted to better than one with ``before`` by more than the share
        :attr:`heldout_gain`: every run left out one at a time, and one temperature or one pilot
        pressure left out (either; a log with neither condition varied is judged on its runs
        alone)."""
        def better(scheme: str) -> bool:
            return (scheme in after and scheme in before
                    and after[scheme] < (1.0 - self.heldout_gain) * before[scheme])

        conditions = [scheme for scheme in CONDITIONS if scheme in before]
        return better(HEADLINE) and (not conditions or any(map(better, conditions)))

    def handicap(self, candidate) -> float:
        """What a candidate's ΔBIC is raised by for ranking and for the threshold: |:attr:`bic`|
        for a shape-free term, nothing for a library effect.

        A shape-free term is chosen from a dozen families, its roughness from a grid, and its
        effective parameter count does not see either choice: the handicap is that search's
        price. Without it, shapes of free form stood in for a pilot transducer drifting from
        run to run, and for the maps' error beside hidden library terms (docs/workbench.md, "Why
        these thresholds")."""
        return -self.bic if getattr(candidate, "shape_free", False) else 0.0

    def rank(self, candidate) -> tuple[float, float]:
        """The sort key of the candidates, best first: ΔBIC with the shape-free handicap, then
        the RMS after."""
        return (candidate.delta_bic + self.handicap(candidate), candidate.rms_after)

    def replaces(self, shape, finding) -> bool:
        """Whether shape-free term ``shape`` replaces the library ``finding``: both are judged
        against the same model, so their ΔBICs compare directly, and the shape must beat it by the
        threshold on top of its handicap, and predict the held-out runs better too (a friction of
        free shape of ν beat the library's viscous friction by ΔBIC on the shipped log, GP maps,
        yet predicted the held-out runs worse: 1.79 against 1.78 bar). A detent at 0.23 mm taken
        for a progressive spring (grid maps, map mismatch; eval/offlibrary.py case 4243): the
        force of free shape beat the spring by ΔBIC 23; a hidden pilot-differential friction under
        GP maps (stress case 215): a friction of free shape of the flow beat it by 12, not
        decisively."""
        return (shape.delta_bic + self.handicap(shape) - finding.delta_bic < self.bic
                and shape.heldout_rms < finding.heldout_rms)

    def ties(self, shape, finding) -> bool:
        """Whether shape-free term ``shape`` and the library ``finding`` fit the log equally
        well: their ΔBICs within the threshold of each other. Neither is then the better
        explanation (:func:`.lookalikes.alike_shapes`). The shape's handicap, the price of
        choosing it from many families, decides which of two is added (:meth:`rank`), not
        whether the log can tell them apart: a friction of p_L of free shape fitted a seal
        friction setting in above a load pressure as well as the library's friction of
        |p_L − p_P| did, and fell outside the tie by its handicap alone."""
        return abs(shape.delta_bic - finding.delta_bic) < -self.bic

    def beats(self, mine: dict, theirs: dict) -> bool:
        """Whether held-out RMS ``mine`` [Pa per scheme] is clearly below a look-alike's
        ``theirs``: by :attr:`other_kind_gain` of it, on the runs left out in turn or on one
        of the conditions left out (a temperature, a pilot pressure). A look-alike within the
        margin on every one leaves the log no kind of unseen run that tells them apart. One is
        enough, as with :meth:`gains_on_unseen`: leaving out the only pilot pressure that
        reaches the largest openings leaves a force acting there undetermined, true or not."""
        return any(mine[scheme] < (1.0 - self.other_kind_gain) * theirs[scheme]
                   for scheme in (HEADLINE, *CONDITIONS) if scheme in mine and scheme in theirs)

    def stable(self, group_share: float) -> bool:
        """Whether a candidate whose group is chosen in ``group_share`` of the resamples over
        runs is a finding (the last test)."""
        return group_share >= self.inclusion_min


#: the rule the package uses
RULE = SignificanceRule()


def delta_bic(rss_after: float, rss_before: float, n_eff: float, extra: float) -> float:
    """n_eff·ln(S_after/S_before) + k·ln(n_eff): the gain in fit against the ``extra``
    parameters it took (a shape-free term's effective number, a fraction)."""
    return float(n_eff * np.log(max(rss_after, 1e-300) / rss_before) + extra * np.log(n_eff))


def gains_in_own_view(candidate, median_before: float, half_before: float) -> bool:
    """Whether ``candidate`` narrows the view its physics acts on (RMS [Pa] before it given):
    a friction term the half-width of the runs' hysteresis, any other term their median line.

    Friction splits the up and down ramps; a friction term that leaves that split no closer to
    the data is soaking up something else (the maps' error moves both ramps alike). A term
    that moves both ramps alike must bring their median line closer. A necessary condition,
    not a sufficient one: how much of the gain lies in each view is only reported
    (:func:`surrogate.reporting.prose.hysteresis_sentence`), since a weak friction can gain more
    on the median line than on the half-width where the piston sticks at the ramps' ends.
    """
    after, before = ((candidate.half_width_rms, half_before) if candidate.kind == "friction"
                     else (candidate.median_rms, median_before))
    if not (np.isfinite(after) and np.isfinite(before)):
        return True  # a log without both ramps at equal flow has no such view to judge by
    return after < before
