"""Coulomb friction of the piston, load-pressure corrected (paper eq. 8)."""

from __future__ import annotations

import numpy as np

from ..units import BAR
from .base import BalanceState, Effect, Parameter


class CoulombFriction(Effect):
    """Coulomb friction f_μ = s·(K1 + K2·p_L) (paper eq. 8, after Handroos & Halme).

    The seals press harder on the piston as the load pressure rises, hence K2. Quasi-statically
    this is a play: the piston stays put while the net force lies inside ±(K1 + K2·p_L) and moves
    to the band's edge when it leaves it, which is what separates up- and down-ramps.
    """

    name = "coulomb_friction"
    title = "Coulomb friction K1 + K2·p_L"
    parameter_specs = (
        Parameter("K1", 0.0, "N", min=0.0, max=200.0, description="constant friction force"),
        Parameter("K2", 0.0, "N/bar", min=0.0, max=2.0 / BAR,
                  description="friction force per load pressure"),
    )
    validity = ("Quasi-static (no velocity dependence); one pair of coefficients per temperature "
                "in the paper, which could not fit two pilot pressures at once.")

    def friction(self, state: BalanceState) -> np.ndarray:
        return np.maximum(self["K1"] + self["K2"] * np.maximum(state.p_L, 0.0), 0.0)
