"""Candidates a log cannot tell apart: one finding with several explanations.

Candidates that change the model's prediction the same way (cosine of their prediction changes
above :data:`SAME_DIRECTION`) while the data prefer neither (|ΔBIC between them| below the
rule's threshold) cannot be told apart on these data — a spring preload offset and a
pilot-transducer offset both act as a constant force — and are reported as one group, with the
bench run that would separate them (:mod:`surrogate.planning.bench_runs`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..data.loaders import BenchLog
from ..planning.bench_runs import Separation, separating_run
from .result import Candidate, Diagnosis
from .rule import RULE, SignificanceRule

SAME_DIRECTION = 0.98  # cosine of two prediction changes above which they act alike


def grouped(candidates: list[Candidate], rule: SignificanceRule = RULE) -> list[Candidate]:
    """The candidates with their groups: each with the names of those it cannot be told from.

    Two candidates are one group when they change the prediction the same way (the cosine of
    their prediction changes exceeds :data:`SAME_DIRECTION`) and the data do not prefer either
    (their BICs differ by less than the rule's threshold in size).
    """
    groups = [[candidate.name] for candidate in candidates]
    for i, a in enumerate(candidates):
        for j in range(i + 1, len(candidates)):
            b = candidates[j]
            size = np.linalg.norm(a.change) * np.linalg.norm(b.change)
            if size == 0:
                continue
            cosine = float(a.change @ b.change) / size
            if cosine > SAME_DIRECTION and abs(a.delta_bic - b.delta_bic) < -rule.bic:
                groups[i].append(b.name)
                groups[j].append(a.name)
    return [replace(candidate, group=tuple(group))
            for candidate, group in zip(candidates, groups)]


def look_alike_separation(diagnosis: Diagnosis, log: BenchLog) -> Separation | None:
    """The bench run that would tell the best candidate from its first look-alike, or None
    without a best candidate or a look-alike."""
    best = diagnosis.best
    if best is None or len(best.group) < 2:
        return None
    other = next(c for c in diagnosis.candidates if c.name in best.group and c is not best)
    return separating_run(best.model, other.model, log, diagnosis.noise_floor, (best.name,
                                                                                other.name))
