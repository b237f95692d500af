"""Candidates a log cannot tell apart: one finding with several explanations.

Two candidates are look-alikes on a log when either

* their own Jacobian columns, once what the model's own parameters can do is taken out, are
  collinear (:func:`collinearity` above :data:`COLLINEAR`): on this log they are the same term
  of the force balance, whatever ΔBIC or the bootstrap prefer, since between two equal fits
  those only measure which one the noise favours. A spring-preload offset and a pilot-transducer
  offset both act as a constant force; a constant friction and a pilot-pressure friction do when
  each run holds its pilot pressure nearly constant. Or
* they change the model's prediction the same way (cosine of their fitted prediction changes
  above :data:`SAME_DIRECTION`) while the data prefer neither (|ΔBIC between them| below the
  rule's threshold): the test for terms of several parameters.

Look-alikes are reported as one group, with the bench run that would separate them
(:mod:`surrogate.planning.bench_runs`).

Look-alikes of **another kind** are judged differently: a claim of valve physics must predict
the held-out runs clearly better than each shape-free term of another physical kind fitted in
its place (a leak of free shape in place of a force of the opening), and, with the maps' own
error within their σ fitted beside it, clearly better than the maps' error alone
(:func:`declined`). A term of free shape bends to whatever the log holds, so a claim that one
of another kind matches on unseen runs is a claim the log does not make; the loop then adds
nothing and names them.

Every explanation is judged with the maps' error fitted beside it, because every log holds it:
a weak true effect under the CFD's error explains less than the maps' error does (a
pilot-pressure friction at 0.93 of its realistic size predicted the runs left out 19 % worse than
the maps' error within its σ), yet it adds to what the maps' error explains (4.4 % better with
it than the maps' error alone; the stress suite's case 216 on grid maps); and a term of free
shape of another kind takes up the maps' error too (a force of the opening predicted the runs
left out 21 % better than a true pilot-differential friction at 0.61 of its size, case 215).
Judged alone, four of the suite's twenty hidden library effects were withheld.
"""

from __future__ import annotations


import numpy as np

from ..data.loaders import BenchLog
from ..planning.bench_runs import Separation, separating_run
from .result import Candidate, Declined, Diagnosis, Rival
from .rule import RULE, SignificanceRule

SAME_DIRECTION = 0.98  # cosine of two prediction changes above which they act alike
#: the canonical correlation of two candidates' own Jacobian columns (with the model's own
#: parameters' part taken out) above which the log cannot tell them apart. On logs of the
#: shipped test sequence from virtual valves (grid maps, map mismatch; a preload, a
#: pilot-pressure friction or nothing hidden) the look-alike pairs reach 0.97–1.00: spring
#: preload and pilot-transducer offset 0.993–1.000, pilot-pressure and pilot-differential
#: friction 0.991–0.994, flowmeter gain and discharge scale 0.973–0.993; every other pair stays
#: below 0.61
COLLINEAR = 0.95
#: terms of more own parameters than this are compared by their prediction changes only
COLLINEAR_PARAMETERS = 2


def own_directions(candidate: Candidate, own_matrix: np.ndarray) -> np.ndarray | None:
    """An orthonormal basis of ``candidate``'s own Jacobian columns at the model's point
    (:attr:`.result.Candidate.probe`) with the part the model's own parameters' columns
    ``own_matrix`` can produce taken out; None when it has none, more than
    :data:`COLLINEAR_PARAMETERS`, or a parameter per run (a per-run term is a sensor check,
    never a model's explanation)."""
    if candidate.probe is None or candidate.per_run or candidate.shape_free:
        return None
    mine = np.asarray(candidate.probe, float)
    if not 0 < mine.shape[1] <= COLLINEAR_PARAMETERS:
        return None
    if own_matrix.size:
        mine = mine - own_matrix @ np.linalg.lstsq(own_matrix, mine, rcond=None)[0]
    basis, singular, _ = np.linalg.svd(mine, full_matrices=False)
    kept = singular > 1e-9 * max(singular[0], 1e-300)
    return basis[:, kept] if kept.any() else None


def collinearity(a: np.ndarray | None, b: np.ndarray | None) -> float:
    """The smallest canonical correlation between two bases of equal size (0 if either is
    missing or their sizes differ): 1 when the two terms can do exactly the same on this log."""
    if a is None or b is None or a.shape[1] != b.shape[1]:
        return 0.0
    return float(np.linalg.svd(a.T @ b, compute_uv=False).min())


def grouped(candidates: list[Candidate], rule: SignificanceRule = RULE,
            own_matrix: np.ndarray | None = None) -> list[Candidate]:
    """The candidates with their groups: each with the names of those it cannot be told from
    (module docstring); ``own_matrix`` holds the columns of the model's own free parameters
    (samples × parameters)."""
    own_matrix = np.zeros((0, 0)) if own_matrix is None else own_matrix
    groups = [[candidate.name] for candidate in candidates]
    directions = [own_directions(candidate, own_matrix) for candidate in candidates]
    for i, a in enumerate(candidates):
        for j in range(i + 1, len(candidates)):
            b = candidates[j]
            if collinearity(directions[i], directions[j]) > COLLINEAR:
                groups[i].append(b.name)
                groups[j].append(a.name)
                continue
            size = np.linalg.norm(a.change) * np.linalg.norm(b.change)
            if size == 0:
                continue
            cosine = float(a.change @ b.change) / size
            if cosine > SAME_DIRECTION and abs(a.delta_bic - b.delta_bic) < -rule.bic:
                groups[i].append(b.name)
                groups[j].append(a.name)
    return [candidate.scored(group=tuple(group))
            for candidate, group in zip(candidates, groups)]


def alike_shapes(finding: Candidate, shapes: list[Candidate], rms_before: float,
                 floor: float, heldout_before: dict, rule: SignificanceRule = RULE
                 ) -> list[str]:
    """The shape-free terms of ``finding``'s kind that the log cannot tell from it: each passes
    the rule on its own (:meth:`.rule.SignificanceRule.passes`) and ties with it
    (:meth:`.rule.SignificanceRule.ties`), neither replacing it nor clearly behind it. The
    library term is added, having a name and fewer parameters; the shape is named beside it as
    another explanation of the same finding. A seal friction setting in above a load pressure
    was taken for the library's friction of |p_L − p_P|; a friction of p_L of free shape fitted
    as well (ΔBIC −423 with its handicap against −430) and predicted the runs and the
    temperatures left out 3–5 % better, the pilot pressures left out far worse
    (eval/offlibrary.py case 4245, grid maps)."""
    return [shape.name for shape in shapes
            if shape.shape_free and shape.kind == finding.kind and shape.category == "physics"
            and rule.passes(shape, rms_before, floor, heldout_before)
            and rule.ties(shape, finding)]


def joined(candidates: list[Candidate], name: str, others: list[str]) -> list[Candidate]:
    """The candidates with ``name`` and ``others`` in one another's groups."""
    members = {name, *others}
    return [c.scored(group=tuple(dict.fromkeys([*c.group, *sorted(members - {c.name})])))
            if c.name in members else c for c in candidates]


def absorbed(candidates: list[Candidate], own_matrix: np.ndarray, own_keys: list[str]
             ) -> dict[str, tuple[str, float]]:
    """The candidates of one parameter whose column at the model's point is collinear with one
    of the model's own parameters' (|cosine| above :data:`COLLINEAR`): on this log that
    parameter already does what the candidate would, and carries it if it acts (a pilot-pressure
    friction in K1 when each run holds its pilot pressure nearly constant). {candidate name:
    (own parameter, cosine)}."""
    found = {}
    norms = np.linalg.norm(own_matrix, axis=0)
    for candidate in candidates:
        if candidate.probe is None or candidate.per_run or candidate.probe.shape[1] != 1:
            continue
        column = candidate.probe[:, 0]
        size = np.linalg.norm(column) * norms
        cosines = np.divide(own_matrix.T @ column, size, out=np.zeros(len(norms)), where=size > 0)
        if cosines.size and np.max(np.abs(cosines)) > COLLINEAR:
            best = int(np.argmax(np.abs(cosines)))
            found[candidate.name] = (own_keys[best], float(cosines[best]))
    return found


def look_alike_separation(diagnosis: Diagnosis, log: BenchLog) -> Separation | None:
    """The bench run that would tell the best candidate from its first look-alike, or None
    without a best candidate or a look-alike."""
    best = diagnosis.best
    if best is None or len(best.group) < 2:
        return None
    other = next(c for c in diagnosis.explanations if c is not best)
    return separating_run(best.model, other.model, log, diagnosis.noise_floor, (best.name,
                                                                                other.name))


#: the name of the rival that is the maps' own error, fitted within their σ
MAPS_ERROR = "maps_error"


def maps_error_rival(heldout: dict) -> Rival:
    """The maps' own error within their σ (:func:`~surrogate.fitting.discrepancy.
    map_discrepancy`) as a rival, with its held-out RMS [Pa] per scheme."""
    return Rival(MAPS_ERROR, "the CFD maps' own error, within their uncertainty", "maps",
                 "map correction", heldout, heldout)


def rival_of(candidate: Candidate, beside_maps: dict) -> Rival:
    """A judged candidate as a rival, with its held-out RMS beside the maps' error."""
    return Rival(candidate.name, candidate.title, candidate.kind, candidate.category,
                 candidate.heldout, beside_maps, candidate.model)


def other_kinds(claim: Candidate, rivals: list[Rival], heldout_before: dict,
                rule: SignificanceRule = RULE) -> list[Rival]:
    """The rivals a physics claim must beat: the maps' own error within their σ, always, and
    physics of another kind (:attr:`~surrogate.effects.Effect.kind`), each one that would itself
    predict runs it was not fitted to better than the model (``heldout_before`` [Pa] per
    scheme), as the rule asks of a discovery (:meth:`.rule.SignificanceRule.predicts_unseen`):
    a term that fails that is no explanation of the log.

    The maps' error needs no such gain: the maps do err, within their σ, whatever the log shows,
    so a claim fitted beside it must predict the runs left out clearly better than it alone.
    Asked to gain by itself first, it dropped out where it gained 1-3 %, and a claim that gained
    a few per cent beside it stood though it was no better than the maps' error (off-library
    case 4260 on GP maps: a leak of free shape beside a true friction of p_L).

    A correction of the maps of free shape is no rival: unbounded, it is no longer the maps'
    error but a force or a flow of its own, and it mimics every term of its hook, true or not:
    on a log with a progressive spring hidden, a flow force of free shape took the spring's
    place by scaling the CFD's flow force by 0.50 to 0.83 (the CFD errs by 2.5 %; the stress
    suite's first case, grid maps). The maps' error stands in for it within the size the maps'
    σ allows."""
    return [r for r in rivals if r.name != claim.name and np.isfinite(r.heldout_rms)
            and (r.name == MAPS_ERROR or (r.category == "physics" and r.kind != claim.kind
                                          and rule.predicts_unseen(r, heldout_before)))]


def declined(claim: Candidate | None, rivals: list[Rival], heldout_before: dict,
             log: BenchLog, noise_floor: float, rule: SignificanceRule = RULE,
             beside_maps: dict | None = None) -> Declined | None:
    """The physics ``claim`` withheld, with the look-alikes of other kinds among ``rivals`` that
    it does not beat on held-out runs (:meth:`.rule.SignificanceRule.beats`), closest first,
    and the bench run that would tell it from the closest one with a model; None when it beats
    them all (or is no physics claim). ``heldout_before``: the model's held-out RMS [Pa] per
    scheme, which a rival must beat to count (:func:`other_kinds`); ``beside_maps``: the
    claim's with the maps' error fitted beside it, judged against each rival's beside it
    (:attr:`~.result.Rival.beside_maps`; without them, their own)."""
    if claim is None or claim.category != "physics":
        return None
    mine = beside_maps or claim.heldout
    close = sorted((r for r in other_kinds(claim, rivals, heldout_before, rule)
                    if not rule.beats(mine, r.beside_maps or r.heldout)),
                   key=lambda r: r.heldout_rms)
    if not close:
        return None
    modelled = next((r for r in close if r.model is not None), None)
    separation = None if modelled is None or claim.model is None else separating_run(
        claim.model, modelled.model, log, noise_floor, (claim.name, modelled.name))
    return Declined(claim, tuple(close), separation, beside_maps or {})
