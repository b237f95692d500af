"""Departures of the main spring from the datasheet's linear characteristic."""

from __future__ import annotations

import numpy as np

from .base import BalanceState, Effect, Parameter


class SpringPreloadOffset(Effect):
    """A spring preload different from the nominal crack force: F_cr → F_cr + ΔF.

    Tolerances of the spring, its seat and the adjustment set the preload; a preload ΔF higher
    than nominal raises the crack pressure by ΔF/A_L at every flow.
    """

    name = "spring_preload_offset"
    kind = "force"
    category = "physics"
    title = "spring preload offset"
    parameter_specs = (
        Parameter("delta_F", 0.0, "N", min=-150.0, max=150.0,
                  description="preload above the nominal crack force"),
    )
    validity = "A constant force: indistinguishable from anything else that acts as one."

    def force(self, state: BalanceState) -> np.ndarray:
        return np.broadcast_to(-self["delta_F"], state.u.shape)


class ProgressiveSpring(Effect):
    """A progressive (β > 0) or degressive (β < 0) spring: K_f·u → K_f·u·(1 + β·u/U_max).

    Coil springs stiffen as coils touch and nest; the rate then grows with the stroke, which
    shows at large openings (high pilot pressure, high flow).
    """

    name = "progressive_spring"
    kind = "force"
    category = "physics"
    title = "progressive spring"
    parameter_specs = (
        Parameter("beta", 0.0, "1", min=-0.9, max=3.0,
                  description="relative increase of the spring force at full stroke"),
    )
    validity = "Quadratic in u; a spring with a kinked characteristic needs its own term."

    def force(self, state: BalanceState) -> np.ndarray:
        valve = state.valve
        return -valve.K_f * self["beta"] * state.u**2 / valve.U_max
