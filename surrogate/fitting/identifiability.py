"""What a fit cannot tell apart, and what it pushed to a bound, said after every step.

A log can hold an effect without telling which of two parameters carries it: a pilot-pressure
friction on a log whose runs each hold their pilot pressure nearly constant moves the constant
friction K1 as much as its own coefficient. Two signs show it, both read off the fit:

* **entangled parameters**: their estimates correlate beyond :data:`ENTANGLED` (from the fit's
  Jacobian); the log fixes their combination, not each;
* **a parameter pushed to a bound**: a parameter that was inside its bounds before a term was
  added and sits on a bound after it (K1 = 0 N): the new term took over what it carried, and the
  bound, not the data, now holds it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .leastsquares import FitResult
from ..model import ValveModel

#: |correlation| of two fitted parameters' estimates above which the log fixes only their
#: combination (the standard errors grow by 1/√(1 − ρ²): 3.2× at 0.95)
ENTANGLED = 0.95


@dataclass(frozen=True)
class Entangled:
    """Two fitted parameters (``"effect.parameter"``) whose estimates the log cannot separate."""

    first: str
    second: str
    correlation: float

    def to_json(self) -> dict:
        return {"parameters": [self.first, self.second],
                "correlation": round(self.correlation, 4)}


@dataclass(frozen=True)
class PushedToBound:
    """A parameter a step drove onto a bound, with what it was before (display units) and the
    terms the step added."""

    parameter: str
    before: float
    after: float
    unit: str
    by: tuple[str, ...]

    def to_json(self) -> dict:
        return {"parameter": self.parameter, "before": round(self.before, 6),
                "after": round(self.after, 6), "unit": self.unit, "by": list(self.by)}


def entangled_pairs(fit: FitResult | None, threshold: float = ENTANGLED) -> list[Entangled]:
    """The pairs of ``fit``'s parameters whose estimates correlate beyond ``threshold``, most
    entangled first (none without a fit or with one parameter)."""
    if fit is None or len(fit.names) < 2:
        return []
    correlation = np.asarray(fit.correlation, float)
    pairs = [Entangled(fit.names[i], fit.names[j], float(correlation[i, j]))
             for i in range(len(fit.names)) for j in range(i + 1, len(fit.names))
             if np.isfinite(correlation[i, j]) and abs(correlation[i, j]) > threshold]
    return sorted(pairs, key=lambda pair: -abs(pair.correlation))


def pushed_to_bounds(before: ValveModel, after: ValveModel, added: list[str]
                     ) -> list[PushedToBound]:
    """The free parameters of ``before`` that were inside their bounds there and sit on one in
    ``after``, the model with the terms ``added``."""
    old, new = before.parameters(), after.parameters()
    return [PushedToBound(key, old[key].display_value, new[key].display_value, new[key].unit,
                          tuple(added))
            for key in old.free() if key in new and new[key].vary
            and not old[key].at_bound and new[key].at_bound]


__all__ = ["ENTANGLED", "Entangled", "PushedToBound", "entangled_pairs", "pushed_to_bounds"]
