"""Scaling of the flow force that the force map predicts."""

from __future__ import annotations

import numpy as np

from .base import BalanceState, Effect, Parameter


class FlowForceScale(Effect):
    """f_ff → scale·f_ff: the map's flow force, made stronger (scale > 1) or weaker (< 1).

    The flow force f_ff is the part of the fluid force a uniform pressure would not give (paper
    eq. 10). The paper's CFD-assisted model needed it reduced by 10 % (scale 0.9) to fit the
    40 °C, p_Pe = 65 bar data.
    """

    name = "flow_force_scale"
    title = "flow-force scale"
    parameter_specs = (
        Parameter("scale", 1.0, "1", min=0.0, max=3.0,
                  description="factor on the map's flow force"),
    )
    validity = "Acts only on what the force map calls flow force; zero with a uniform-pressure map."

    def force(self, state: BalanceState) -> np.ndarray:
        return (self["scale"] - 1.0) * state.flow_force
